"""Smooth-SBMPC step benchmark at the Smooth-SBMPC paper's scale (SmoothSettings defaults: T_init 60 s, T_mpc 20 s, dt
1 s, n_y 201; 39 behaviours; 4 point targets; the reconstruction channel of scenarios/smooth_000_reconstruction.yaml:
banks, a crossing channel, a peninsula across the route and an island, 10 polygons), float32, this device.

Slots (each compiled first, compile time recorded separately, then timed round-robin, one repeat of every
slot per round, so that a slow spell of this shared machine lands on every slot alike):

* ``init``: the initialisation stage (Alg. 1-2, ``init_stage``);
* ``corridor``: Alg. 3 on Ψ (``cross_track_corridor``);
* ``docp``: the DOCP from Ψ with ``DOCP_SOLVER`` and the safeguard (the situation's Ψ and corridor prepared once);
* ``step1``: one whole step, one start (``smooth_sbmpc_step``, one jitted call);
* ``step4map`` / ``step4vmap``: one whole step, 4 starts, ``batch="map"`` / ``"vmap"``;
* ``batch20``: ``SmoothSBMPCPlanner.plan_batch`` over R = 20 runs (perturbed states and targets; 4 starts, map);
* ``plan``: ``SmoothSBMPCPlanner.plan`` (host validation, local origin, transfer; 4 starts).

``--baseline DIR`` adds ``old/init`` and ``old/step`` for another copy of the package (a directory holding a
package ``psbmpc_old`` with that version's ``init_stage`` and ``smooth_sbmpc_step``), for a before/after
comparison in one interleaved run.  ``--vmap-repeats`` bounds the slow ``step4vmap`` slot separately.

Usage: python benchmarks/bench_smooth.py [--repeats 10] [--vmap-repeats 10] [--baseline DIR]
Writes benchmarks/results/smooth_step_cpu_<UTC stamp>.json.
"""

from __future__ import annotations

import argparse
import importlib
import math
import os
import sys
import time

import jax
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import environment_meta, stats, write_results  # noqa: E402

CHI0 = math.radians(105.0)          # as in the reconstruction scenario: route frame rotated to the mean course


def rot(s, e):
    """Route frame (s along, e cross, starboard positive) -> NED (north, east)."""
    s, e = np.asarray(s, float), np.asarray(e, float)
    return np.stack([s * math.cos(CHI0) - e * math.sin(CHI0), s * math.sin(CHI0) + e * math.cos(CHI0)], -1)


def box(s0, s1, e0, e1):
    return rot([s0, s1, s1, s0], [e0, e0, e1, e1])


def channel_polygons():
    """The reconstruction channel (our proposed geometry, not the paper's): banks at |e| = 30..60 m for s in [-50, 80]
    and [135, 230], a port-side peninsula across the route (s 15..28 m, up to e = +3 m), the crossing channel's sides
    and an island in it: 10 polygons."""
    return [box(-50, 80, 30, 60), box(135, 230, 30, 60), box(-50, 80, -60, -30), box(135, 230, -60, -30),
            box(15, 28, -30, 3), box(50, 80, 60, 150), box(135, 165, 60, 150), box(50, 80, -150, -60),
            box(135, 165, -150, -60), rot([100, 110, 105], [100, 100, 110])]


def situation(t: float, rng=None):
    """The own-ship on the route at s ~ t (1 m/s) and the four §1.9 targets advanced t seconds; with ``rng``,
    small perturbations (one run of a batch)."""
    rng = rng or np.random.default_rng(0)
    jit = lambda scale: rng.normal(0.0, scale) if scale else 0.0  # noqa: E731
    p = rot(0.95 * t + jit(1.0), jit(0.5))
    own = np.array([p[0], p[1], CHI0 + jit(0.05), 0.9 + jit(0.05)])

    def target(s, e, dc, U):
        q = rot(s, e)
        c = CHI0 + math.radians(dc)
        return [q[0] + U * math.cos(c) * t + jit(0.5), q[1] + U * math.sin(c) * t + jit(0.5), c + jit(0.02), U]

    targets = np.array([target(35, -6, 0, 0.4), target(95, 70, -90, 0.7), target(125, -75, 90, 0.7),
                        target(230, 2, 180, 0.6)])
    return own, rot([0.0, 160.0], [0.0, 0.0]), targets, np.array([1.0, 0.0])


def new_slots(t_sit: float, batch_runs: int):
    import jax.numpy as jnp

    from psbmpc_jax.nlp import safeguard, solve_docp
    from psbmpc_jax.packing import pack_world
    from psbmpc_jax.params import PlannerConfig
    from psbmpc_jax.smooth import SmoothSBMPCPlanner, buffered_chart, cross_track_corridor, smooth_sbmpc_step
    from psbmpc_jax.smooth.docp import DOCP_SOLVER, _cast, bounds, prepare_step, problem
    from psbmpc_jax.smooth.init_stage import ShipModel, SmoothSettings, SmoothWeights, init_stage

    settings = SmoothSettings()
    polys = channel_polygons()
    land = pack_world(polys, PlannerConfig(dtype="float32")).polygons
    buf = buffered_chart(polys, settings.r_dom, dtype="float32")
    own, route, targets, last = (np.asarray(a, np.float32) for a in situation(t_sit))
    w, m = _cast(SmoothWeights(), np.float32), _cast(ShipModel(), np.float32)
    prep = jax.jit(prepare_step, static_argnames=("settings", "n_starts"))(
        jnp.asarray(own), jnp.asarray(route), jnp.asarray(targets), jnp.asarray(last), jnp.asarray(0, jnp.int32),
        land, buf, w, m, settings=settings, n_starts=1)
    f, eq, ineq = problem(settings)
    lo, hi = bounds(settings.n_mpc, np.float32)

    def docp():
        r = solve_docp(f, prep.starts[0], lower=lo, upper=hi, eq=eq, ineq=ineq, settings=DOCP_SOLVER, args=prep.args)
        return safeguard(r, prep.starts[0], f, lower=lo, upper=hi, eq=eq, ineq=ineq, args=prep.args,
                         tol=DOCP_SOLVER.tol), r

    psi_xy = prep.init.psi[:settings.n_mpc + 2, :2]
    planner = SmoothSBMPCPlanner(polys, n_starts=4, batch="map", dtype="float32")
    rng = np.random.default_rng(1)
    runs = [situation(t_sit, rng) for _ in range(batch_runs)]
    states = np.stack([r[0] for r in runs])
    tgts = np.stack([r[2] for r in runs])
    lasts = np.stack([r[3] for r in runs])
    slots = {
        "new/init": lambda: init_stage(own, route, targets, last, land),
        "new/corridor": lambda: cross_track_corridor(psi_xy, buf, settings.corridor_half_width),
        "new/docp": docp,
        "new/step1": lambda: smooth_sbmpc_step(own, route, targets, last, land, buf, n_starts=1),
        "new/step4map": lambda: smooth_sbmpc_step(own, route, targets, last, land, buf, n_starts=4, batch="map"),
        "new/step4vmap": lambda: smooth_sbmpc_step(own, route, targets, last, land, buf, n_starts=4, batch="vmap"),
        f"new/batch{batch_runs}": lambda: planner.plan_batch(states, route, tgts, lasts, np.zeros(batch_runs, int)),
        "new/plan": lambda: planner.plan(own, route, targets, last, 0),
    }
    info = {}
    for name, fn in slots.items():
        t0 = time.perf_counter()
        out = jax.block_until_ready(fn())
        first = time.perf_counter() - t0
        t0 = time.perf_counter()
        jax.block_until_ready(fn())
        info[name] = {"first_call_s": round(first, 2), "compile_s_est": round(first - (time.perf_counter() - t0), 2)}
        if name == "new/docp":
            kept, r = out
            info[name].update(cost=float(kept.f), warm_cost=float(f(prep.starts[0], prep.args)),
                              violation=float(kept.max_violation), used_warm=bool(kept.used_warm),
                              status=int(r.status), outer=int(r.outer_iterations), inner=int(r.inner_iterations))
        elif name.startswith("new/step"):
            info[name].update(cost=float(out.cost), warm_cost=float(out.warm_cost), violation=float(out.violation),
                              used_warm=bool(out.used_warm), best=int(out.best), iterations=int(out.iterations),
                              start_cost=[round(float(c), 5) for c in np.asarray(out.start_cost)],
                              apply=[round(float(c), 5) for c in np.asarray(out.apply)])
        elif name.startswith("new/batch"):
            info[name].update(used_warm=int(np.sum(out.used_warm)), mean_cost=float(np.mean(out.cost)),
                              mean_warm_cost=float(np.mean(out.warm_cost)), iterations=int(np.sum(out.iterations)))
        print(f"compiled {name}: {info[name]}", flush=True)
    return slots, info


def old_slots(t_sit: float):
    old_pack = importlib.import_module("psbmpc_old.packing")
    old_params = importlib.import_module("psbmpc_old.params")
    old_smooth = importlib.import_module("psbmpc_old.smooth")
    old_init = importlib.import_module("psbmpc_old.smooth.init_stage")
    old_docp = importlib.import_module("psbmpc_old.smooth.docp")
    settings = old_init.SmoothSettings()
    polys = channel_polygons()
    land = old_pack.pack_world(polys, old_params.PlannerConfig(dtype="float32")).polygons
    buf = old_smooth.buffered_chart(polys, settings.r_dom, dtype="float32")
    own, route, targets, last = (np.asarray(a, np.float32) for a in situation(t_sit))
    slots = {"old/init": lambda: old_init.init_stage(own, route, targets, last, land),
             "old/step": lambda: old_docp.smooth_sbmpc_step(own, route, targets, last, land, buf)}
    info = {}
    for name, fn in slots.items():
        t0 = time.perf_counter()
        out = jax.block_until_ready(fn())
        first = time.perf_counter() - t0
        t0 = time.perf_counter()
        jax.block_until_ready(fn())
        info[name] = {"first_call_s": round(first, 2), "compile_s_est": round(first - (time.perf_counter() - t0), 2)}
        if name == "old/step":
            info[name].update(cost=float(out.cost), warm_cost=float(out.warm_cost), violation=float(out.violation),
                              used_warm=bool(out.used_warm), iterations=int(out.solver.inner_iterations),
                              apply=[round(float(c), 5) for c in np.asarray(out.apply)])
        print(f"compiled {name}: {info[name]}", flush=True)
    return slots, info


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=10)
    ap.add_argument("--vmap-repeats", type=int, default=10, help="repeats of the (slow on a CPU) step4vmap slot")
    ap.add_argument("--batch-runs", type=int, default=20)
    ap.add_argument("--time", type=float, default=50.0, help="situation time [s] along the reconstruction run")
    ap.add_argument("--baseline", default=None, help="directory holding the package psbmpc_old (before/after)")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "results"))
    args = ap.parse_args(argv)
    if args.repeats < 2 or args.vmap_repeats < 2 or args.batch_runs < 1:
        ap.error("--repeats and --vmap-repeats >= 2, --batch-runs >= 1")
    slots, info = new_slots(args.time, args.batch_runs)
    if args.baseline:
        sys.path.insert(0, os.path.abspath(args.baseline))
        s, i = old_slots(args.time)
        slots.update(s)
        info.update(i)
    times = {k: [] for k in slots}
    for rnd in range(args.repeats):
        for name, fn in slots.items():
            if name == "new/step4vmap" and rnd >= args.vmap_repeats:
                continue
            t0 = time.perf_counter()
            jax.block_until_ready(fn())
            times[name].append(time.perf_counter() - t0)
    points = []
    for name, ts in times.items():
        version, what = name.split("/")
        points.append({"version": version, "what": what, **info[name], "timing": stats(ts)})
        print(f"{name:>16}: median {stats(ts)['median_ms']:9.2f} ms  (q1 {stats(ts)['q1_ms']:.1f}, "
              f"q3 {stats(ts)['q3_ms']:.1f}, n {len(ts)})", flush=True)
    meta = environment_meta("Smooth-SBMPC step at the Smooth-SBMPC paper's scale (reconstruction channel, "
                            "10 polygons, 4 targets, "
                            "T_init 60 s, T_mpc 20 s, dt 1 s, n_y 201, float32)", repeats=args.repeats,
                            vmap_repeats=args.vmap_repeats, batch_runs=args.batch_runs, situation_time_s=args.time,
                            schedule="interleaved", baseline=args.baseline, load_average=os.getloadavg())
    write_results(args.out, "smooth_step", meta, points)
    return 0


if __name__ == "__main__":
    sys.exit(main())
