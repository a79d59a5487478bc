"""Time of one MPC update of the refinement and of Smooth-SBMPC at small sizes: the measurements behind the time
model of :mod:`psbmpc_jax.update_time` (docs/limits.md, "Time of an update").

Each case is one host call as the simulator makes it, compiled first (compile time recorded), then timed
``--repeats`` times (median):

* ``refine``: ``Planner.plan(situation, refine=RefineSettings(n_starts=1, solver=...))`` on the Nidelva head-on
  (``examples.nidelva_head_on``: 2 obstacles x n_ps scenarios, 13 Table-2 polygons, grid grounding, the Nidelva
  preset's 1014 behaviours, dt 0.5 s, float32); the time is ``result.refine_time_s`` (the refinement alone, not
  the grid search) with the iterations of the kept start (``result.refined.iterations``).
* ``smooth_init``: ``SmoothSBMPCPlanner(init_only=True).plan`` (the initialisation stage) on the reconstruction
  channel of ``bench_smooth.py`` (10 polygons) with the first I of its 4 targets.
* ``smooth_step``: ``SmoothSBMPCPlanner(n_starts=1).plan`` (init stage, corridor, DOCP, safeguard) on the same
  situation, timed round-robin with the ``init_only`` planner of the same T_init and targets; the DOCP's time
  per inner iteration (``plan.iterations``) is the difference of the medians over the iterations.

Usage: python benchmarks/bench_update_time.py --cases refine:150:5:8,refine:150:5:24 [--repeats 5]
       python benchmarks/bench_update_time.py --fit benchmarks/results/update_time_cpu_*.json
  case syntax: refine:T:n_ps:max_inner | smooth_init:T_init:targets | smooth_step:T_init:T_mpc:targets:max_outer:max_inner
Writes benchmarks/results/update_time_cpu_<UTC stamp>.json, one per case.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import environment_meta, write_results  # noqa: E402


def refine_case(T: float, n_ps: int, max_inner: int, repeats: int) -> dict:
    from psbmpc_jax.examples import nidelva_head_on
    from psbmpc_jax.planner import Planner
    from psbmpc_jax.presets import build_mpc
    from psbmpc_jax.refine import DEFAULT_SOLVER, RefineSettings

    sit = nidelva_head_on(n_ps=n_ps)
    config, params, beh = build_mpc("nidelva", {"T": T, "dtype": "float32"})
    planner = Planner(config, params, beh)
    settings = RefineSettings(n_starts=1, previous_start=False,
                              solver=dataclasses.replace(DEFAULT_SOLVER, max_inner=max_inner))
    t0 = time.perf_counter()
    res, _ = planner.plan(sit, refine=settings)
    first = time.perf_counter() - t0
    times, its = [], []
    for _ in range(repeats):
        res, _ = planner.plan(sit, refine=settings)
        times.append(res.refine_time_s)
        its.append(int(res.refined.iterations))
    return dict(kind="refine", T=T, dt=config.dt, n_steps=config.n_steps, n_obstacles=len(sit.obstacles), n_ps=n_ps,
                n_obstacle_scenarios=len(sit.obstacles) * n_ps, n_polygons=len(sit.polygons), n_behaviours=len(beh),
                max_outer=1, max_inner=max_inner, n_starts=1, first_call_s=round(first, 2),
                median_s=statistics.median(times), times_s=[round(t, 5) for t in times], iterations=its)


def smooth_case(T_init: float, T_mpc: float | None, n_targets: int, max_outer: int, max_inner: int,
                repeats: int) -> dict:
    """``T_mpc`` None: the initialisation stage alone (an ``init_only`` planner); else the whole step, timed
    round-robin with the ``init_only`` planner of the same T_init and targets (so a slow spell of the shared
    machine falls on both), and the DOCP's time per inner iteration = (step - init) / iterations."""
    from bench_smooth import channel_polygons, situation
    from psbmpc_jax.smooth import SmoothSBMPCPlanner
    from psbmpc_jax.smooth.docp import DOCP_SOLVER
    from psbmpc_jax.smooth.init_stage import SmoothSettings

    init_only = T_mpc is None
    settings = SmoothSettings(T_init=T_init, T_mpc=20.0 if init_only else T_mpc)
    own, route, targets, last = situation(50.0)
    targets = targets[:n_targets]
    planners = {"init": SmoothSBMPCPlanner(channel_polygons(), settings=settings, n_starts=1, init_only=True,
                                           dtype="float32")}
    if not init_only:
        solver = dataclasses.replace(DOCP_SOLVER, max_outer=max_outer, max_inner=max_inner)
        planners["step"] = SmoothSBMPCPlanner(channel_polygons(), settings=settings, solver=solver, n_starts=1,
                                              dtype="float32")
    first = {}
    for k, pl in planners.items():
        t0 = time.perf_counter()
        pl.plan(own, route, targets, last, 0)
        first[k] = round(time.perf_counter() - t0, 2)
    times = {k: [] for k in planners}
    its = []
    for _ in range(repeats):
        for k, pl in planners.items():
            t0 = time.perf_counter()
            p = pl.plan(own, route, targets, last, 0)
            times[k].append(time.perf_counter() - t0)
            if k == "step":
                its.append(int(p.iterations))
    key = "init" if init_only else "step"
    out = dict(kind="smooth_init" if init_only else "smooth_step", T_init=T_init,
               T_mpc=None if init_only else T_mpc, dt=settings.dt, n_init=settings.n_init,
               n_mpc=None if init_only else settings.n_mpc, n_targets=n_targets, n_polygons=len(channel_polygons()),
               max_outer=None if init_only else max_outer, max_inner=None if init_only else max_inner, n_starts=1,
               first_call_s=first[key], median_s=statistics.median(times[key]),
               times_s=[round(t, 5) for t in times[key]], iterations=its or [0])
    if not init_only:
        out.update(init_median_s=statistics.median(times["init"]), init_times_s=[round(t, 5) for t in times["init"]],
                   docp_per_iteration_s=(statistics.median(times["step"]) - statistics.median(times["init"]))
                   / statistics.median(its))
    return out


def run_case(spec: str, repeats: int) -> dict:
    kind, *a = spec.split(":")
    if kind == "refine":
        return refine_case(float(a[0]), int(a[1]), int(a[2]), repeats)
    if kind == "smooth_init":
        return smooth_case(float(a[0]), None, int(a[1]), 0, 0, repeats)
    if kind == "smooth_step":
        return smooth_case(float(a[0]), float(a[1]), int(a[2]), int(a[3]), int(a[4]), repeats)
    raise SystemExit(f"unknown case {spec!r} (refine:..., smooth_init:..., smooth_step:...)")


def fit(points: list) -> dict:
    """The coefficients of :mod:`psbmpc_jax.update_time` from the measured cases, and each case's estimate
    against its measurement (model in the module; least squares on the relative error where there are more
    cases than coefficients).  Uses refine:150:5:8, refine:150:5:24, refine:60:5:8 (refine:150:1:8 is
    checked, not fitted), smooth_init cases, and smooth_step:*:20:4 / :20:1 (T_mpc 40 checked); fits what the
    files hold."""
    by = {p["case"]: p for p in points}
    out: dict = {"checks": []}
    it = lambda p: statistics.median(p["iterations"])  # noqa: E731
    if {"refine:150:5:8", "refine:150:5:24", "refine:60:5:8"} <= set(by):
        _fit_refine(points, by, out, it)
    init = [p for p in points if p["kind"] == "smooth_init"]
    if init:
        _fit_init(init, out)
    steps = {(p["n_mpc"], p["n_targets"]): p for p in points if p["kind"] == "smooth_step"}
    if (20, 4) in steps and (20, 1) in steps:
        _fit_docp(steps, out)
    return out


def _fit_refine(points, by, out, it):
    """update_time's model: one iteration (alpha + beta (N + 1)) x max(1, OS / 10), plus k iterations once."""
    r8, r24, r60 = by["refine:150:5:8"], by["refine:150:5:24"], by["refine:60:5:8"]
    t300 = (r24["median_s"] - r8["median_s"]) / (it(r24) - it(r8))
    k = r8["median_s"] / t300 - it(r8)
    t120 = r60["median_s"] / (it(r60) + k)
    beta = (t300 - t120) / (r8["n_steps"] - r60["n_steps"])
    alpha = t300 - beta * (r8["n_steps"] + 1)
    out["REFINE_ITER"], out["REFINE_FIXED_ITERATIONS"] = (alpha, beta), k
    for p in (p for p in points if p["kind"] == "refine"):
        t_it = (alpha + beta * (p["n_steps"] + 1)) * max(1.0, p["n_obstacle_scenarios"] / 10.0)
        out["checks"].append((p["case"], p["median_s"], (it(p) + k) * t_it))


def _fit_init(init, out):
    A = np.array([[p["n_init"] * (p["n_init"] + 1) / p["median_s"],
                   p["n_init"] * (p["n_init"] + 1) * p["n_targets"] / p["median_s"]] for p in init])
    a, b = np.linalg.lstsq(A, np.ones(len(init)), rcond=None)[0]
    # an upper bound: scaled so that no measured case is above the model (the stage's time depends on how much
    # land the predictions reach, not only on the shapes)
    scale = max(p["median_s"] / (p["n_init"] * (p["n_init"] + 1) * (a + b * p["n_targets"])) for p in init)
    a, b = a * scale, b * scale
    out["SMOOTH_INIT"] = (float(a), float(b))
    for p in init:
        out["checks"].append((p["case"], p["median_s"], p["n_init"] * (p["n_init"] + 1) * (a + b * p["n_targets"])))


def _fit_docp(steps, out):
    """update_time's model: one inner iteration = s0 + c x N_mpc x (1 + targets)."""
    d4, d1 = steps[(20, 4)]["docp_per_iteration_s"], steps[(20, 1)]["docp_per_iteration_s"]
    c = (d4 - d1) / (20 * 3)
    out["SMOOTH_ITER"] = (d4 - c * 20 * 5, c)
    for p in steps.values():
        out["checks"].append((p["case"] + " (per iteration)", p["docp_per_iteration_s"],
                              d4 - c * 100 + c * p["n_mpc"] * (1 + p["n_targets"])))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", help="comma-separated cases (see the usage line)")
    ap.add_argument("--fit", nargs="+", metavar="JSON", help="print the coefficients fitted to these result files")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "results"))
    args = ap.parse_args(argv)
    if args.fit:
        pts = [p for f in args.fit for p in json.load(open(f))["points"]]
        res = fit(pts)
        for case, meas, est in res.pop("checks"):
            print(f"{case:>32}: measured {meas * 1e3:9.2f} ms, model {est * 1e3:9.2f} ms ({est / meas:.2f}x)")
        print(json.dumps(res))
        return 0
    if args.repeats < 1 or not args.cases:
        ap.error("--cases and --repeats >= 1")
    for spec in [c for c in args.cases.split(",") if c]:     # one file per case: a long compile loses nothing
        p = run_case(spec, args.repeats)
        p["case"] = spec
        print(f"{spec}: first call {p['first_call_s']} s, median {p['median_s'] * 1e3:.1f} ms, iterations "
              f"{sorted(set(p['iterations']))}", flush=True)
        meta = environment_meta("time of one MPC update (refinement, Smooth-SBMPC) at small sizes, float32",
                                repeats=args.repeats, load_average=os.getloadavg())
        write_results(args.out, "update_time", meta, [p])
    return 0


if __name__ == "__main__":
    sys.exit(main())
