"""Closed-loop batching benchmark: one device call per MPC update for all runs (vmap) against one call per
solve (loop), for the shipped head-on scenario (1014 behaviours, T = 150 s, dt = 0.5 s, 80 MPC updates).

Usage:  python benchmarks/bench_sim_batch.py [--runs 1,4,16] [--duration 400] [--out benchmarks/results]

Each point simulates the scenario end to end twice (the first pass compiles; the second is timed) and
records the wall time of the whole simulation and of the device calls, and the solve time per solve
(device-call wall time / solves).  Both modes must choose the same manoeuvres (checked).  This is what
``psbmpc-jax run --batch auto`` is based on: loop on the CPU, vmap on an accelerator.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time

import numpy as np

from psbmpc_jax.scenario import load_scenario
from psbmpc_jax.sim import simulate

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import environment_meta, write_results  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", default="1,4,16", help="comma-separated Monte Carlo run counts")
    ap.add_argument("--duration", type=float, default=400.0, help="simulated seconds (default: the file's 400)")
    ap.add_argument("--scenario", default="head_on")
    ap.add_argument("--out", default="benchmarks/results")
    args = ap.parse_args(argv)
    sc = dataclasses.replace(load_scenario(args.scenario), duration=args.duration)
    points = []
    for runs in (int(v) for v in args.runs.split(",")):
        chosen, states = {}, {}
        for mode in ("loop", "vmap"):
            simulate(dataclasses.replace(sc, duration=4 * sc.mpc.period), runs=runs, batch=mode)   # compile
            t0 = time.perf_counter()
            res = simulate(sc, runs=runs, batch=mode)
            wall = time.perf_counter() - t0
            calls = np.array([c["wall_s"] for c in res.calls])
            solves = int(sum(c["solves"] for c in res.calls))
            chosen[mode] = res.offsets
            states[mode] = res.states
            point = {"scenario": sc.name, "runs": runs, "mode": mode, "simulated_s": sc.duration,
                     "mpc_updates": len(res.calls), "solves": solves,
                     "device_calls": int(sum(c["device_calls"] for c in res.calls)),
                     "wall_s": round(wall, 3), "device_wall_s": round(float(calls.sum()), 3),
                     "ms_per_solve": round(1e3 * float(calls.sum()) / solves, 3),
                     "ms_per_update_median": round(1e3 * float(np.median(calls)), 3)}
            points.append(point)
            print(point, flush=True)
        # offsets hold nan for ships without PSB-MPC: compare with equal_nan
        same = bool(np.array_equal(chosen["loop"], chosen["vmap"], equal_nan=True))
        same_states = bool(np.array_equal(states["loop"], states["vmap"]))
        for p in points[-2:]:
            p["same_manoeuvres_as_other_mode"] = same
            p["same_trajectories_as_other_mode"] = same_states
    meta = environment_meta("sim_batch", scenario=sc.name, n_cbs=int(len(sc.mpc.behaviours)),
                            T=sc.mpc.config.T, dt=sc.mpc.config.dt)
    write_results(args.out, "sim_batch", meta, points)
    return 0


if __name__ == "__main__":
    sys.exit(main())
