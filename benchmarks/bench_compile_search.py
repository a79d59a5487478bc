"""Compile time of one solve with three small islands, by grounding search and by XLA flags: what the bounded
search costs the first solve, and what the test suite's compile flags change.

Each measurement runs in a fresh process (XLA reads ``XLA_FLAGS`` once, and no compiled program or cache is
shared): the situation of ``bench_cpu_targets.py`` with polygons (3 islands, 176 vertices, one head-on target,
n_ps 5, T 120 s, float32) at ``--n-cbs`` behaviours, ``solve`` lowered and compiled once with
``grounding_search`` ``culled`` or ``bounded``.  Flag sets: ``default`` (what a user compiles), ``o0`` (the
tests' ``--xla_backend_optimization_level=0``) and ``o0_legacy`` (also ``--xla_cpu_use_fusion_emitters=false``).
Rounds are interleaved: every (flags, search) pair once per round.  Recorded per point: median / min / max of
the trace+lower seconds and of the compile seconds, and the StableHLO line count.

``--baseline DIR`` (a checkout of another commit, e.g. ``git worktree add /tmp/old COMMIT``) measures every
point with that tree's package too, in the same rounds (``tree``: ``new`` / ``old``): a before/after in one
interleaved run.  ``--flags`` and ``--searches`` pick a subset (comma-separated).

``--program suite_solve`` / ``suite_refine`` compiles the test suite's shared solve / refinement instead
(tests/conftest.py's configuration, float64; run with ``--flags o0``, the suite's flag).

Usage: PYTHONPATH=. python benchmarks/bench_compile_search.py [--rounds 2] [--n-cbs 1014] [--baseline DIR]
[--flags default,o0] [--searches culled,bounded] [--program solve] [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time

FLAGS = {"default": "", "o0": "--xla_backend_optimization_level=0",
         "o0_legacy": "--xla_backend_optimization_level=0 --xla_cpu_use_fusion_emitters=false"}
SEARCHES = ("culled", "bounded")
#: ``solve``: the islands situation above; ``suite_solve`` / ``suite_refine``: the test suite's shared solve and
#: refinement programs (what most of its compile time goes to).
PROGRAMS = ("solve", "suite_solve", "suite_refine")


def suite_child(program: str, search: str) -> None:
    """The test suite's shared configuration (tests/conftest.py: the 30-behaviour table padded to 64, ``CAPS``,
    T 20 s, dt 0.5 s, float64): its ``solve``, or the refinement of test_refine.py (2 starts, 10 s horizon)."""
    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp
    import numpy as np

    sys.path.insert(0, os.path.join(os.getcwd(), "tests"))
    from conftest import CAPS, SMALL_BEHAVIOURS, pad_arrays, random_situation
    from psbmpc_jax import Planner, PlannerConfig
    from psbmpc_jax.evaluate import DEFAULT_TERMS
    from psbmpc_jax.refine import RefineSettings, _refine_jit, previous_plan
    from psbmpc_jax.solve import solve

    config = PlannerConfig(T=20.0, dt=0.5, dtype="float64", grounding_search=search)
    planner = Planner(config, behaviours=SMALL_BEHAVIOURS)
    inputs, state, params, samples = planner.prepare(random_situation(3, T=20.0), None)
    inputs = pad_arrays(inputs, **CAPS, junk=False)
    t0 = time.perf_counter()
    if program == "suite_solve":
        lowered = solve.lower(inputs, state, params, samples, config=config)
    else:
        plan, _, ev = solve(inputs, state, params, samples, config=config)
        s = RefineSettings(n_starts=2, horizon=10.0)
        f64 = np.float64
        args = (inputs, jnp.asarray(plan.best, jnp.int32), jnp.asarray(state.last_offsets, f64), params, samples,
                ev, s.solver, jnp.asarray(s.path_eps, f64), jnp.asarray(s.fis_e_cl, f64), DEFAULT_TERMS,
                previous_plan(None, config.n_steps, f64))
        t0 = time.perf_counter()
        lowered = _refine_jit.lower(*args, config=config, static=s.static(config))
    t1 = time.perf_counter()
    lowered.compile()
    t2 = time.perf_counter()
    print(json.dumps({"lower_s": t1 - t0, "compile_s": t2 - t1, "hlo_lines": lowered.as_text().count("\n"),
                      "best": -1}))


def child(search: str, n_cbs: int, program: str = "solve") -> None:
    if program != "solve":
        return suite_child(program, search)
    import jax

    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import bench_cpu_targets as bct
    from psbmpc_jax import Planner, PlannerConfig
    from psbmpc_jax.apps.bench_points import behaviours_for
    from psbmpc_jax.solve import solve

    config = PlannerConfig(T=120.0, dt=0.5, grounding_search=search)
    planner = Planner(config, behaviours=behaviours_for(n_cbs))
    prepared = jax.device_put(planner.prepare(bct.situation(True), key=jax.random.key(0)))
    t0 = time.perf_counter()
    lowered = solve.lower(*prepared, config=config)
    t1 = time.perf_counter()
    compiled = lowered.compile()
    t2 = time.perf_counter()
    best = int(jax.block_until_ready(compiled(*prepared))[2].best)
    print(json.dumps({"lower_s": t1 - t0, "compile_s": t2 - t1, "hlo_lines": lowered.as_text().count("\n"),
                      "best": best}))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--n-cbs", type=int, default=1014)
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "results"))
    ap.add_argument("--baseline", default=None, help="checkout of another commit, measured in the same rounds")
    ap.add_argument("--flags", default=",".join(FLAGS), help="comma-separated subset of " + ", ".join(FLAGS))
    ap.add_argument("--searches", default=",".join(SEARCHES), help="comma-separated subset of " + ", ".join(SEARCHES))
    ap.add_argument("--program", default="solve", choices=PROGRAMS, help="the program compiled (PROGRAMS)")
    ap.add_argument("--child", choices=SEARCHES, help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.rounds < 1:
        ap.error("--rounds must be >= 1")
    if a.child:
        child(a.child, a.n_cbs, a.program)
        return 0
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from _common import environment_meta, write_results

    flag_sets, searches = a.flags.split(","), a.searches.split(",")
    for name, value, allowed in (("--flags", flag_sets, FLAGS), ("--searches", searches, SEARCHES)):
        bad = [v for v in value if v not in allowed]
        if bad:
            ap.error(f"{name}: unknown {bad}, allowed: {', '.join(allowed)}")
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    trees = {"new": here}
    if a.baseline:
        if not os.path.isfile(os.path.join(a.baseline, "psbmpc_jax", "__init__.py")):
            ap.error(f"--baseline: {a.baseline} holds no psbmpc_jax package")
        trees["old"] = os.path.abspath(a.baseline)
    runs: dict = {(t, f, s): [] for t in trees for f in flag_sets for s in searches}
    for r in range(a.rounds):
        for (tree, flags, search), out in runs.items():
            env = dict(os.environ, XLA_FLAGS=FLAGS[flags], PYTHONPATH=trees[tree])
            p = subprocess.run([sys.executable, os.path.abspath(__file__), "--child", search, "--n-cbs",
                                str(a.n_cbs), "--program", a.program], env=env, capture_output=True, text=True, timeout=900,
                               cwd=trees[tree])
            if p.returncode != 0:
                raise SystemExit(f"{tree}/{flags}/{search}: child failed ({p.returncode}): {p.stderr[-2000:]}")
            rec = json.loads(p.stdout.strip().splitlines()[-1])
            out.append(rec)
            print(f"round {r} {tree} {flags:10s} {search:8s} lower {rec['lower_s']:6.1f} s  compile "
                  f"{rec['compile_s']:6.1f} s  best {rec['best']}  lines {rec['hlo_lines']}", flush=True)
    points = []
    for (tree, flags, search), recs in runs.items():
        lo, co = [x["lower_s"] for x in recs], [x["compile_s"] for x in recs]
        points.append({"tree": tree, "tree_path": trees[tree], "flags": flags, "xla_flags": FLAGS[flags],
                       "grounding_search": search, "n_cbs": a.n_cbs, "program": a.program,
                       "hlo_lines": recs[0]["hlo_lines"], "best": sorted({x["best"] for x in recs}),
                       "lower_median_s": statistics.median(lo), "lower_min_s": min(lo), "lower_max_s": max(lo),
                       "compile_median_s": statistics.median(co), "compile_min_s": min(co),
                       "compile_max_s": max(co), "n": len(recs)})
    meta = environment_meta("compile time of one solve by grounding search and XLA flags", rounds=a.rounds,
                            schedule="interleaved, one fresh process per measurement", load_avg=os.getloadavg())
    write_results(a.out, "compile_search" if a.program == "solve" else f"compile_{a.program}", meta, points)
    return 0


if __name__ == "__main__":
    sys.exit(main())
