"""Kernel-level profile of one paper-scale solve on this device: how many kernels one solve launches, and where
the time goes by kernel group.

The situation is fig5's 1 014-behaviour point (the Nidelva head-on, 13 Table-2 polygons, exact grounding,
quadrature, float32, T = 150 s; ``--n-ps``/``--n-do`` as in ``psbmpc-jax bench``).  The solve is compiled, run
``--warmup`` times, then ``--repeats`` solves are traced with ``jax.profiler`` (a Perfetto trace).  The trace's
device events are counted per solve and grouped by the name of the XLA fusion or kernel (its prefix before the
first ``.`` or digit), with their total device time; on a CPU the trace holds host threads only, so the counts
are of XLA:CPU thunks and are not a GPU's.  Also written: the sequential depth of the same program
(:mod:`psbmpc_jax.depth`), so the launches can be set against the loop steps.

Usage: python benchmarks/profile_solve.py [--n-cbs 1014] [--n-ps 1] [--n-do 2] [--repeats 5] [--out DIR]
Writes DIR/profile_<platform>_<UTC stamp>.json (default benchmarks/results/) and keeps the raw trace in
DIR/profile_trace/.
"""

from __future__ import annotations

import argparse
import collections
import glob
import gzip
import json
import os
import re
import sys
import time

import jax

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import environment_meta, write_results  # noqa: E402


def group_of(name: str) -> str:
    """A kernel's group: its name up to the first '.', '_<digits>' or digit run (``loop_add_fusion.12`` ->
    ``loop_add_fusion``)."""
    return re.split(r"[.]|_\d|\d", name, maxsplit=1)[0] or name


def summarise(trace_dir: str, n_solves: int) -> dict:
    files = sorted(glob.glob(os.path.join(trace_dir, "**", "*.trace.json.gz"), recursive=True))
    if not files:
        return {"error": f"no Perfetto trace found under {trace_dir}"}
    with gzip.open(files[-1], "rt") as fh:
        trace = json.load(fh)
    events = trace.get("traceEvents", trace if isinstance(trace, list) else [])
    pnames = {e.get("pid"): e.get("args", {}).get("name", "")
              for e in events if e.get("ph") == "M" and e.get("name") == "process_name"}
    groups = collections.defaultdict(lambda: [0, 0.0])
    total = 0
    device_events = 0
    for e in events:
        if e.get("ph") != "X":
            continue
        proc = pnames.get(e.get("pid"), "")
        on_device = "/device:" in proc and "host" not in proc.lower()
        if not on_device:
            continue
        device_events += 1
        g = groups[group_of(e.get("name", ""))]
        g[0] += 1
        g[1] += float(e.get("dur", 0.0))
        total += 1
    rows = sorted(({"group": k, "kernels_per_solve": v[0] / n_solves, "device_us_per_solve": v[1] / n_solves}
                   for k, v in groups.items()), key=lambda r: -r["device_us_per_solve"])
    return {"trace_file": files[-1], "kernels_per_solve": total / n_solves, "groups": rows[:40],
            "device_events": device_events}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n-cbs", type=int, default=1014)
    ap.add_argument("--n-ps", type=int, default=1)
    ap.add_argument("--n-do", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--warmup", type=int, default=3)
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "results"))
    args = ap.parse_args(argv)
    from functools import partial

    from psbmpc_jax import Params, Planner, PlannerConfig
    from psbmpc_jax.apps.bench_points import Point, behaviours_for, situation_for
    from psbmpc_jax.depth import sequential_depth
    from psbmpc_jax.solve import solve

    platform = jax.devices()[0].platform
    p = Point(sweep="profile", swept="n_cbs", value=args.n_cbs, n_cbs=args.n_cbs, n_ps=args.n_ps, n_do=args.n_do)
    config = PlannerConfig(T=p.T).for_platform(platform)
    planner = Planner(config, params=Params(r_ct=p.r_ct), behaviours=behaviours_for(p.n_cbs))
    prepared = jax.device_put(planner.prepare(situation_for(p)))
    t0 = time.perf_counter()
    compiled = solve.lower(*prepared, config=config).compile()
    compile_s = time.perf_counter() - t0
    for _ in range(args.warmup):
        jax.block_until_ready(compiled(*prepared))
    trace_dir = os.path.join(args.out, "profile_trace")
    times = []
    with jax.profiler.trace(trace_dir, create_perfetto_trace=True):
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            jax.block_until_ready(compiled(*prepared))
            times.append(time.perf_counter() - t0)
    summary = summarise(trace_dir, args.repeats)
    depth = sequential_depth(partial(solve, config=config), *prepared)
    meta = environment_meta("one solve's kernels (jax.profiler)", n_cbs=p.n_cbs, n_ps=p.n_ps, n_do=p.n_do,
                            layouts={"grounding_search": config.grounding_search, "pc_layout": config.pc_layout,
                                     "rollout_unroll": config.rollout_unroll, "rollout_kernel": config.rollout_kernel,
                                     "layout_platform": platform},
                            compile_s=round(compile_s, 3))
    point = {"times_ms": [round(t * 1e3, 4) for t in times], **summary, "depth": depth.to_dict()}
    print(f"{platform} (rollouts: {config.rollout_kernel}): {summary.get('kernels_per_solve')} kernels per solve, "
          f"median "
          f"{sorted(times)[len(times) // 2] * 1e3:.2f} ms, depth {depth.depth}")
    write_results(args.out, "profile", meta, [point])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
