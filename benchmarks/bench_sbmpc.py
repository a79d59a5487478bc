#!/usr/bin/env python3
"""Solve time of the SB-MPC family on the situations of Tengesdal, Brekke & Johansen (2020) (39 behaviours, T 200 s,
dt 0.5 s, 401 steps).

    python benchmarks/bench_sbmpc.py [--repeats 30] [--out benchmarks/results]

For each scenario (``tengesdal2020_a``: 1 target, ``tengesdal2020_b``: 13 targets) the situation of the first
MPC update (the own-ship's start and the targets' true states with the tracker's initial covariance
diag(625, 625, 20.25, 20.25)) is solved by the jitted grid search (:func:`psbmpc_jax.solve.solve`) with the cost
terms of ``sbmpc``, ``psbmpc_2020`` and ``psbmpc`` (the library's PSB-MPC, quadrature estimator, n_ps = 1, for
scale).  The methods are timed interleaved, round by round, so machine noise hits them alike; each point records
the median and quartiles of ``--repeats`` warm calls and the compile time.  Writes
``<out>/sbmpc_<platform>_<UTC stamp>.json`` (device, versions, commit).
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import time

import jax
import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from _common import environment_meta, stats, write_results  # noqa: E402

from psbmpc_jax.evaluate import DEFAULT_TERMS  # noqa: E402
from psbmpc_jax.methods import psbmpc2020_terms, sbmpc_terms  # noqa: E402
from psbmpc_jax.packing import pack  # noqa: E402
from psbmpc_jax.params import params_as_arrays  # noqa: E402
from psbmpc_jax.scenario import load_scenario  # noqa: E402
from psbmpc_jax.situation import Obstacle, OwnShip, Situation  # noqa: E402
from psbmpc_jax.solve import PlannerState, solve  # noqa: E402

#: The tracker's covariance right after single-point initiation in these scenarios: 25 x R, (U_max / 2)^2.
P_INIT = np.diag([625.0, 625.0, 20.25, 20.25])


def first_situation(sc, n_ps: int) -> Situation:
    o = sc.own_ship
    own = OwnShip(state=[*o.position, o.course, o.speed], waypoints=o.waypoints, U_d=o.U_d, length=o.length,
                  width=o.width)
    obs = tuple(Obstacle([*t.position, t.speed * np.cos(t.course), t.speed * np.sin(t.course)], P_INIT,
                         length=t.length, width=t.width, n_ps=n_ps) for t in sc.targets)
    return Situation(own, obs, sc.polygons)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=30)
    ap.add_argument("--out", default=str(pathlib.Path(__file__).resolve().parent / "results"))
    args = ap.parse_args(argv)

    points = []
    for name in ("tengesdal2020_a", "tengesdal2020_b"):
        sc = load_scenario(name)
        cfg, s = sc.mpc.config, sc.mpc.sbmpc
        params = params_as_arrays(sc.mpc.params, np.dtype(cfg.dtype))
        inputs = pack(first_situation(sc, 1), sc.mpc.behaviours, cfg)
        state = PlannerState((1.0, 0.0))
        methods = {"sbmpc": sbmpc_terms(s, with_grounding=False), "psbmpc_2020": psbmpc2020_terms(s, with_grounding=False),
                   "psbmpc": DEFAULT_TERMS}
        compiled, compile_s, times, best = {}, {}, {m: [] for m in methods}, {}
        for m, terms in methods.items():
            t0 = time.perf_counter()
            compiled[m] = solve.lower(inputs, state, params, None, config=cfg, terms=terms).compile()
            compile_s[m] = time.perf_counter() - t0
            plan = jax.block_until_ready(compiled[m](inputs, state, params, None, terms=methods[m]))[0]
            best[m] = [float(v) for v in np.asarray(plan.offsets)[0]]
        for _ in range(args.repeats):                      # interleaved rounds
            for m in methods:
                t0 = time.perf_counter()
                jax.block_until_ready(compiled[m](inputs, state, params, None, terms=methods[m]))
                times[m].append(time.perf_counter() - t0)
        for m in methods:
            st = stats(times[m])
            points.append({"scenario": name, "method": m, "n_behaviours": int(len(sc.mpc.behaviours)),
                           "n_obstacles": len(sc.targets), "n_steps": int(cfg.n_steps), "n_mc": s.n_mc,
                           "compile_s": round(compile_s[m], 2), "chosen_offsets": best[m], **st})
            print(f"{name:16s} {m:12s} median {st['median_ms']:8.2f} ms (q1 {st['q1_ms']}, q3 {st['q3_ms']}), "
                  f"compile {compile_s[m]:.1f} s, chosen {best[m]}")
    write_results(args.out, "sbmpc", environment_meta("bench_sbmpc", repeats=args.repeats), points)
    return 0


if __name__ == "__main__":
    sys.exit(main())
