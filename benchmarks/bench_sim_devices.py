"""Closed-loop runs split over local devices: ``simulate(devices=1)`` against ``devices=N`` (both the vmapped call
of every MPC update; the loop, the CPU's default, as a third slot for context).

Usage:  python benchmarks/bench_sim_devices.py [--devices 2] [--runs 8] [--duration 30] [--repeats 3]

On the CPU the host is split into ``--devices`` XLA devices (``--xla_force_host_platform_device_count``, set
here before JAX starts unless XLA_FLAGS already sets it); on a machine with several accelerators their real
devices are used.  Each slot is simulated once untimed (compiles), then the slots are timed round-robin
(``--repeats`` rounds), so slow and fast spells of a shared machine fall on every slot alike.  Each point
records the whole simulation's wall time and the MPC updates' call times, and whether its trajectories, offsets
and best costs equal the one-device vmapped call's bit for bit (``equal_to_vmap_one_device``; the loop's best
costs differ from vmap's in the last bits, docs/simulation.md).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import sys
import time


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--devices", type=int, default=2, help="devices to split the runs over (default 2)")
    ap.add_argument("--runs", type=int, default=8)
    ap.add_argument("--duration", type=float, default=30.0, help="simulated seconds (default 30)")
    ap.add_argument("--scenario", default="head_on")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "results"))
    args = ap.parse_args(argv)
    flags = os.environ.get("XLA_FLAGS", "")
    if "xla_force_host_platform_device_count" not in flags:    # before JAX starts: host devices on the CPU
        os.environ["XLA_FLAGS"] = f"{flags} --xla_force_host_platform_device_count={args.devices}".strip()

    import jax
    import numpy as np

    from psbmpc_jax.scenario import load_scenario
    from psbmpc_jax.sim import simulate

    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from _common import environment_meta, write_results

    sc = dataclasses.replace(load_scenario(args.scenario), duration=args.duration)
    slots = [("vmap", 1), ("vmap", args.devices), ("loop", 1)]
    first = {s: simulate(sc, runs=args.runs, seed=0, batch=s[0], devices=s[1]) for s in slots}   # compiles
    ref = first[("vmap", 1)]
    walls = {s: [] for s in slots}
    calls = {s: [] for s in slots}
    same = {}
    for _ in range(args.repeats):
        for s in slots:
            t0 = time.perf_counter()
            res = simulate(sc, runs=args.runs, seed=0, batch=s[0], devices=s[1])
            walls[s].append(time.perf_counter() - t0)
            calls[s] += [c["wall_s"] for c in res.calls]
            same[s] = {f: bool(np.array_equal(getattr(res, f), getattr(ref, f), equal_nan=True))
                       for f in ("states", "offsets", "best_costs")}
    points = []
    for s in slots:
        mode, n_dev = s
        point = {"scenario": sc.name, "runs": args.runs, "simulated_s": sc.duration, "mode": mode, "devices": n_dev,
                 "mpc_updates": len(ref.calls), "solves_per_update": ref.calls[0]["solves"],
                 "wall_s": [round(w, 3) for w in walls[s]], "wall_s_median": round(statistics.median(walls[s]), 3),
                 "ms_per_update_median": round(1e3 * statistics.median(calls[s]), 2),
                 "equal_to_vmap_one_device": same[s]}
        points.append(point)
        print(point, flush=True)
    meta = environment_meta("sim_devices", scenario=sc.name, n_cbs=int(len(sc.mpc.behaviours)), T=sc.mpc.config.T,
                            dt=sc.mpc.config.dt, dtype=sc.mpc.config.dtype, repeats=args.repeats,
                            schedule="interleaved", load_avg=os.getloadavg(), xla_flags=os.environ.get("XLA_FLAGS"),
                            local_devices=[str(d) for d in jax.local_devices()])
    write_results(args.out, "sim_devices", meta, points)
    return 0


if __name__ == "__main__":
    sys.exit(main())
