"""The CPU paths the authors' C++ nearly matches: the cross-entropy estimator and a few small polygons, against the
quadrature solve without polygons, one interleaved run on this device.

Situation (modelled on the authors' C++ PSB-MPC test: own-ship from the origin along a 7-waypoint route at
9 m/s, one target from 1 km ahead coming head-on at 5 m/s with P_0 = diag(25, 25, 0.025, 0.025), T 120 s,
dt 0.5 s, n_ps 5): the paper's n_M = 2 behaviour tables of 1 014 and 7 098 behaviours (``psbmpc-jax bench``'s
``behaviours_for``), float32.  Slots per table: ``quadrature`` (no polygons), ``quadrature+polygons`` (three small
islands beside the route, 176 vertices in all, exact grounding) and ``ce`` (no polygons; its random table is
drawn once, as ``Planner`` does for one key).  Reported: each slot's median and the ratios ce / quadrature and
(quadrature+polygons) / quadrature, the goals being <= 4 and <= 1.2.

``--baseline DIR`` adds the same slots for another copy of the package (a directory holding it renamed
``psbmpc_old``, as for ``bench_ab_points.py``), timed in the same rounds: a before/after in one interleaved run.

Usage: PYTHONPATH=. python benchmarks/bench_cpu_targets.py [--repeats 20] [--tables 1014,7098] [--baseline DIR]
[--out DIR] (from the repository root: ``PYTHONPATH=.`` makes ``new`` this checkout's package, not an installed
copy; the script's own directory comes first on ``sys.path``).
"""

from __future__ import annotations

import argparse
import importlib
import math
import os
import sys

import jax
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import environment_meta, time_interleaved, write_results  # noqa: E402

ROUTE = np.array([[0.0, 0.0], [200.0, 0.0], [200.0, 200.0], [400.0, 200.0], [600.0, 0.0], [300.0, -300.0],
                  [1000.0, -300.0]])


def islands() -> list[np.ndarray]:
    """Three small star-shaped islands beside the route: 58 + 59 + 59 = 176 vertices."""
    out = []
    for (cx, cy, r, n) in ((100.0, 60.0, 25.0, 58), (300.0, 120.0, 30.0, 59), (520.0, -40.0, 20.0, 59)):
        a = 2 * math.pi * np.arange(n) / n
        rad = r * (1.0 + 0.25 * np.sin(5 * a))
        out.append(np.stack([cx + rad * np.cos(a), cy + rad * np.sin(a)], axis=-1))
    return out


def situation(with_polygons: bool, pkg_name: str = "psbmpc_jax"):
    pkg = importlib.import_module(pkg_name)
    Obstacle, OwnShip, Situation = pkg.Obstacle, pkg.OwnShip, pkg.Situation

    own = OwnShip(state=[0.0, 0.0, 0.0, 4.0], waypoints=ROUTE, U_d=9.0, length=5.0, width=3.0)
    target = Obstacle(state=[1000.0, 0.0, -5.0, 0.0], cov=np.diag([25.0, 25.0, 0.025, 0.025]), length=5.0,
                      width=3.0, n_ps=5)
    return Situation(own, (target,), tuple(islands()) if with_polygons else ())


def slot(label: str, n_cbs: int, estimator: str, with_polygons: bool, pkg_name: str = "psbmpc_jax",
         version: str = "new"):
    pkg = importlib.import_module(pkg_name)
    behaviours_for = importlib.import_module(f"{pkg_name}.apps.bench_points").behaviours_for
    solve = importlib.import_module(f"{pkg_name}.solve").solve

    config = pkg.PlannerConfig(T=120.0, dt=0.5, estimator=estimator)
    planner = pkg.Planner(config, behaviours=behaviours_for(n_cbs))
    prepared = jax.device_put(planner.prepare(situation(with_polygons, pkg_name), key=jax.random.key(0)))
    compiled = solve.lower(*prepared, config=config).compile()
    ev = jax.block_until_ready(compiled(*prepared))[2]
    return {"point": {"version": version, "slot": label, "n_cbs": n_cbs, "estimator": estimator,
                      "polygons": with_polygons,
                      "n_vertices": 176 if with_polygons else 0, "best": int(ev.best),
                      "n_pc_blocks": int(ev.n_pc_blocks)},
            "call": lambda: compiled(*prepared)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--tables", default="1014,7098")
    ap.add_argument("--baseline", default=None, help="directory holding the package psbmpc_old (before/after)")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "results"))
    args = ap.parse_args(argv)
    tables = [int(v) for v in args.tables.split(",") if v]
    versions = [("psbmpc_jax", "new")]
    if args.baseline:
        sys.path.insert(0, os.path.abspath(args.baseline))
        versions.append(("psbmpc_old", "old"))
    slots = []
    for n in tables:
        for pkg_name, version in versions:
            slots += [slot("quadrature", n, "quadrature", False, pkg_name, version),
                      slot("quadrature+polygons", n, "quadrature", True, pkg_name, version),
                      slot("ce", n, "ce", False, pkg_name, version)]
        print(f"compiled the slots of {n} behaviours", file=sys.stderr, flush=True)
    points = time_interleaved(slots, args.repeats)
    ratios = []
    for n in tables:
        for _, version in versions:
            m = {p["slot"]: p["median_ms"] for p in points if p["n_cbs"] == n and p["version"] == version}
            r = {"version": version, "n_cbs": n, "ce_over_quadrature": round(m["ce"] / m["quadrature"], 3),
                 "polygons_over_quadrature": round(m["quadrature+polygons"] / m["quadrature"], 3)}
            ratios.append(r)
            print(f"{version} {n} behaviours: quadrature {m['quadrature']:.1f} ms, +polygons "
                  f"{m['quadrature+polygons']:.1f} ms (x{r['polygons_over_quadrature']}), ce {m['ce']:.1f} ms "
                  f"(x{r['ce_over_quadrature']})")
    meta = environment_meta("ce and small polygons against the quadrature solve (C++-test-like situation)",
                            repeats=args.repeats, schedule="interleaved", ratios=ratios,
                            goals={"ce_over_quadrature": 4.0, "polygons_over_quadrature": 1.2})
    write_results(args.out, "cpu_targets", meta, points)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
