"""``psbmpc-jax bench --depth``: instead of timing, the loop iterations each point's solve step executes
(:func:`psbmpc_jax.depth.sequential_depth_only`, the GPU latency floor), one ``psbmpc-depth/1`` record per point
(docs/bench_schema.md), in a file of its own: ``psbmpc-jax report`` reads timing records only."""

from __future__ import annotations

import datetime as dt
import json
import os
import platform as _platform
import sys
import time

from ..provenance import commit, versions
from .bench_points import behaviours_for, n_vertices, point_config, situation_for
from .bench_timing import default_out, select_devices

DEPTH_SCHEMA = "psbmpc-depth/1"
DEPTH_FIELDS = ("schema", "sweep", "swept", "value", "n_cbs", "n_ps", "n_do", "n_so", "n_vertices", "T", "dt",
                "estimator", "dtype", "grounding_mode", "layout_platform", "grounding_search", "pc_layout",
                "rollout_unroll", "rollout_kernel", "platform", "host", "depth", "loop_executions", "sites", "versions",
                "commit", "timestamp")



def depth_out_problem(path, depth: bool) -> str | None:
    """Why ``--out`` cannot take this run's records: ``psbmpc-jax report`` reads files of ``psbmpc-bench/1``
    records only, so depth records (``depth``) and timing records go to separate files.  None if it can."""
    if not path or not os.path.isfile(path):
        return None
    try:
        with open(path, encoding="utf-8") as fh:
            for lineno, line in enumerate(fh, 1):
                if not line.strip():
                    continue
                try:
                    schema = json.loads(line).get("schema")
                except (ValueError, AttributeError):
                    schema = None
                if depth and schema != DEPTH_SCHEMA:
                    return (f"--depth --out {path}: line {lineno} is not a {DEPTH_SCHEMA} record "
                            f"({schema or 'no schema'}); depth records go to a file of their own, or "
                            f"psbmpc-jax report could no longer read it: give another --out")
                if not depth and schema == DEPTH_SCHEMA:
                    return (f"--out {path}: line {lineno} is a {DEPTH_SCHEMA} record (psbmpc-jax bench --depth); "
                            f"timing records go to another file: give another --out")
    except (OSError, UnicodeDecodeError):
        return None      # unreadable: the CLI's own check of --out reports it
    return None


def run_depth(args, points) -> int:
    """``psbmpc-jax bench --depth``: per point the :func:`psbmpc_jax.depth.sequential_depth_only` of the solve step
    (:func:`psbmpc_jax.solve.solve` on the inputs the timing would use), one ``psbmpc-depth/1`` record each."""
    import functools

    import jax

    from ..depth import sequential_depth_only
    from ..params import Params
    from ..planner import Planner
    from ..solve import solve

    dev = jax.devices()[0] if args.devices == "all" else select_devices(args.devices)[args.devices][0]
    layout_platform = args.layout_platform or ("cpu" if dev.platform == "cpu" else "gpu")
    out = args.out or default_out()
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    meta = {"host": _platform.node(), "versions": versions(), "commit": commit()}
    with open(out, "a", encoding="utf-8") as fh:
        for i, p in enumerate(points, 1):
            behaviours, situation = behaviours_for(p.n_cbs), situation_for(p)
            config = point_config(args, p, layout_platform)
            with jax.default_device(dev):
                planner = Planner(config, params=Params(r_ct=p.r_ct), behaviours=behaviours)
                inputs, state, params, samples = planner.prepare(situation, key=jax.random.key(args.seed))
                t0 = time.perf_counter()
                report = sequential_depth_only(functools.partial(solve, config=config), inputs, state, params,
                                               samples)
            rec = dict.fromkeys(DEPTH_FIELDS)
            rec.update(schema=DEPTH_SCHEMA, sweep=p.sweep, swept=p.swept, value=p.value, n_cbs=len(behaviours),
                       n_ps=int(max([ob.n_ps for ob in situation.obstacles], default=0)),
                       n_do=len(situation.obstacles), n_so=len(situation.polygons),
                       n_vertices=n_vertices(situation), T=float(p.T), dt=float(args.dt), estimator=config.estimator,
                       dtype=config.dtype, grounding_mode=config.grounding_mode, layout_platform=layout_platform,
                       grounding_search=config.grounding_search, pc_layout=config.pc_layout,
                       rollout_unroll=config.rollout_unroll, rollout_kernel=config.rollout_kernel,
                       platform=dev.platform,
                       **meta, **report.to_dict(),
                       timestamp=dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds"))
            assert set(rec) == set(DEPTH_FIELDS), set(rec) ^ set(DEPTH_FIELDS)
            fh.write(json.dumps(rec) + "\n")
            fh.flush()
            if not args.quiet:
                print(f"[{i}/{len(points)}] {p.label()} ({layout_platform} layouts): depth {report.depth}, "
                      f"{report.loop_executions} loop executions ({time.perf_counter() - t0:.1f} s)\n"
                      f"{report.table()}\n", flush=True)
    if not args.quiet:
        print(f"psbmpc-jax bench: {len(points)} depth records appended to {out}", file=sys.stderr)
    return 0
