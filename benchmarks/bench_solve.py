"""Solve-step benchmark at paper scale (Nidelva head-on: 1014 behaviours, T = 150 s, dt = 0.5 s, 2 obstacles x 5
scenarios, the 13 Table-2 polygons after RDP 2 m), float32, this device:

* ``search``: the compiled solve step (grid search + selection) on device-resident inputs;
* ``plan``: ``Planner.plan`` wall time (validation, packing, transfer, solve, cost-table fetch); the host
  overhead is ``plan - search``;
* ``grad``: reverse-mode gradient of the objective for ONE per-step control sequence ``[N, 2]``.

Points are compiled first, then timed round-robin (one repeat of each slot per round), so that a slow spell of
this shared machine lands on every slot alike.  ``--baseline DIR`` adds the same ``search`` and ``plan`` slots
for another copy of the package (a directory holding a package ``psbmpc_old``: e.g.
``git worktree add /tmp/old <commit>; cp -r /tmp/old/psbmpc_jax /tmp/oldpkg/psbmpc_old``) with its own API of
that commit (``evaluate(arrays, params, samples)``), for a before/after comparison in one interleaved run.

Usage: python benchmarks/bench_solve.py [--repeats 30] [--modes exact,grid] [--baseline /tmp/oldpkg]
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import environment_meta, stats, write_results  # noqa: E402


def new_slots(mode: str, with_grad: bool):
    from psbmpc_jax import Planner, PlannerConfig
    from psbmpc_jax.examples import nidelva_head_on
    from psbmpc_jax.objective import value_and_grad
    from psbmpc_jax.solve import solve

    sit = nidelva_head_on()
    config = PlannerConfig(grounding_mode=mode)
    planner = Planner(config)
    prepared = planner.prepare(sit)
    compiled = solve.lower(*prepared, config=config).compile()
    search = lambda: jax.block_until_ready(compiled(*prepared))  # noqa: E731
    plan = lambda: planner.plan(sit)  # noqa: E731
    search()
    res, _ = plan()
    slots = {f"new/{mode}/search": search, f"new/{mode}/plan": plan}
    info = {"best": res.best_index, "n_edges": int(sum(len(r) for p in sit.polygons for r in p))}
    if with_grad:
        inputs, state, params, samples = prepared
        controls = jnp.tile(jnp.asarray([[0.8, 0.1]], jnp.float32), (config.n_steps, 1))
        grad = lambda: jax.block_until_ready(  # noqa: E731
            value_and_grad(controls, inputs, params, samples, config, per_step=True))
        t0 = time.perf_counter()
        (val, _), g = grad()
        info["grad_compile_s"] = round(time.perf_counter() - t0, 2)
        info["grad_finite"] = bool(np.all(np.isfinite(np.asarray(g)))) and bool(np.isfinite(float(val)))
        info["grad_norm"] = float(jnp.linalg.norm(g))
        slots[f"new/{mode}/grad"] = grad
    return slots, info


def old_slots(mode: str):
    old = importlib.import_module("psbmpc_old")
    examples = importlib.import_module("psbmpc_old.examples")
    evaluate = importlib.import_module("psbmpc_old.evaluate").evaluate
    sit = examples.nidelva_head_on()
    config = old.PlannerConfig(grounding_mode=mode)
    planner = old.Planner(config)
    arrays, params, samples = planner.prepare(sit)
    compiled = evaluate.lower(arrays, params, samples, config=config).compile()
    search = lambda: jax.block_until_ready(compiled(arrays, params, samples))  # noqa: E731
    plan = lambda: planner.plan(sit)  # noqa: E731
    search()
    res, _ = plan()
    return {f"old/{mode}/search": search, f"old/{mode}/plan": plan}, {"best": res.best_index}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=30)
    ap.add_argument("--modes", default="exact,grid", help="grounding modes, comma-separated")
    ap.add_argument("--baseline", default=None, help="directory holding the package psbmpc_old (before/after)")
    ap.add_argument("--no-grad", action="store_true", help="skip the gradient slots")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "results"))
    args = ap.parse_args(argv)
    modes = [m for m in args.modes.split(",") if m]
    if args.repeats < 2 or not modes or any(m not in ("exact", "grid") for m in modes):
        ap.error("--repeats >= 2 and --modes from exact,grid")
    if args.baseline:
        sys.path.insert(0, os.path.abspath(args.baseline))
    slots, infos = {}, {}
    for mode in modes:
        s, info = new_slots(mode, not args.no_grad)
        slots.update(s)
        infos[f"new/{mode}"] = info
        if args.baseline:
            s, info = old_slots(mode)
            slots.update(s)
            infos[f"old/{mode}"] = info
        print(f"compiled {mode}: {infos}", flush=True)
    times = {k: [] for k in slots}
    for _ in range(args.repeats):
        for name, fn in slots.items():
            t0 = time.perf_counter()
            fn()
            times[name].append(time.perf_counter() - t0)
    points = []
    for name, ts in times.items():
        version, mode, what = name.split("/")
        points.append({"version": version, "grounding_mode": mode, "what": what, **infos[f"{version}/{mode}"],
                       "timing": stats(ts)})
        print(f"{name:>20}: median {stats(ts)['median_ms']:.2f} ms", flush=True)
    for version in ("new", "old"):
        for mode in modes:
            key = {p["what"]: p["timing"]["median_ms"] for p in points
                   if p["version"] == version and p["grounding_mode"] == mode}
            if "plan" in key:
                overhead = key["plan"] - key["search"]
                points.append({"version": version, "grounding_mode": mode, "what": "host_overhead",
                               "median_ms": round(overhead, 3)})
                print(f"{version}/{mode}: plan - search = {overhead:.2f} ms", flush=True)
    meta = environment_meta("solve step at paper scale (Nidelva head-on, 13 Table-2 polygons, float32)",
                            repeats=args.repeats, schedule="interleaved", baseline=args.baseline)
    write_results(args.out, "solve", meta, points)
    return 0


if __name__ == "__main__":
    sys.exit(main())
