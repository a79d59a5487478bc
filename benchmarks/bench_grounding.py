"""Grounding benchmark on the Trondheim chart: paper-scale Nidelva solve, Fig. 9 and Fig. 10 runtimes.

Usage:  python benchmarks/bench_grounding.py [--repeats 10] [--out benchmarks/results] [--skip-fig9-raw]

Points (all float32, 1014 behaviours, T = 150 s, dt = 0.5 s, jitted evaluator timed on the device with
warm-up and ``block_until_ready``; compile time recorded separately):
* ``nidelva``: 2 obstacles x 5 scenarios + the 13 Table 2 polygons after RDP at 2 m, for the exact and the
  grid grounding mode and the quadrature and mc estimators (targets: grid <= 100 ms, exact <= 400 ms);
* ``fig9``: the largest polygon alone (21 961 vertices; 1 734 after RDP), own-ship standing still, no
  obstacles, exact mode, with and without RDP;
* ``fig10``: n_so = 1..13 (Table 2 order, after RDP), own-ship standing still, no obstacles, exact and grid.
The grid build time (once per chart) is recorded with each grid point.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import jax

from psbmpc_jax import OwnShip, Planner, PlannerConfig, Situation, paper_behaviours
from psbmpc_jax.examples import nidelva_head_on, nidelva_polygons
from psbmpc_jax.situation import polygon_rings

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import environment_meta, stats, time_compiled, write_results  # noqa: E402


def time_solve(situation, config: PlannerConfig, repeats: int, seed: int = 0) -> dict:
    planner = Planner(config, behaviours=paper_behaviours(2))
    t0 = time.perf_counter()
    prepared = planner.prepare(situation, key=jax.random.key(seed))
    prepare_s = time.perf_counter() - t0            # includes the grid build in grid mode
    compile_s, times, ev = time_compiled(prepared, config, repeats, warmup=1)
    n_edges = int(sum(len(r) for p in situation.polygons for r in polygon_rings(p)))
    return {"estimator": config.estimator, "grounding_mode": config.grounding_mode, "n_cbs": 1014,
            "n_do": len(situation.obstacles), "n_so": len(situation.polygons), "n_edges": n_edges,
            "n_ct": 1014 * (len(situation.polygons) + sum(o.n_ps for o in situation.obstacles)),
            "prepare_s": round(prepare_s, 3), "compile_s": round(compile_s, 3), "jax": stats(times),
            "best": int(ev.best)}


def nidelva_range_filtered(nid: Situation) -> Situation:
    """The Nidelva situation with the whole Trondheim chart, RDP at 2 m, clipped to d_so = 200 m."""
    from psbmpc_jax.charts import range_filter, to_ring_sets, trondheim_chart
    from psbmpc_jax.rdp import simplify_chart

    chart = simplify_chart(trondheim_chart("psbmpc"), 2.0)
    near = range_filter(chart, nid.own_ship.state[:2], 200.0)
    return Situation(nid.own_ship, nid.obstacles, tuple(to_ring_sets(near.polygons)))


def standing_still(polygons) -> Situation:
    base = nidelva_head_on()
    p = base.own_ship.state[:2]
    own = OwnShip(state=[p[0], p[1], base.own_ship.state[2], 0.0], waypoints=base.own_ship.waypoints, U_d=0.0)
    return Situation(own, (), tuple(polygons))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=10)
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "results"))
    ap.add_argument("--skip-fig9-raw", action="store_true", help="skip the 21 961-vertex exact point (slow)")
    args = ap.parse_args(argv)
    if args.repeats < 2:
        ap.error("--repeats must be >= 2")
    points = []

    def record(kind, point, **extra):
        point = {"kind": kind, **extra, **point}
        points.append(point)
        print(f"{kind:>8} {json.dumps({k: point[k] for k in point if k not in ('jax',)})} "
              f"median {point['jax']['median_ms']:.1f} ms", flush=True)

    nid = nidelva_head_on()
    for mode in ("grid", "exact"):
        for est in ("quadrature", "mc"):
            record("nidelva", time_solve(nid, PlannerConfig(estimator=est, grounding_mode=mode), args.repeats),
                   polygons="13 Table 2 polygons after RDP 2 m, unclipped (worst case)")
    # what a planner actually evaluates: the chart range-filtered to d_so = 200 m around the own-ship
    filtered = nidelva_range_filtered(nid)
    for est in ("quadrature", "mc"):
        record("nidelva", time_solve(filtered, PlannerConfig(estimator=est), args.repeats),
               polygons="whole chart after RDP 2 m, range_filter(clip, d_so = 200 m)")

    rings_rdp, _ = nidelva_polygons(2.0, 13, rdp=True)
    rings_raw, _ = nidelva_polygons(2.0, 13, rdp=False)
    record("fig9", time_solve(standing_still(rings_rdp[12:13]), PlannerConfig(), args.repeats), rdp=True)
    if not args.skip_fig9_raw:
        record("fig9", time_solve(standing_still(rings_raw[12:13]), PlannerConfig(), max(2, args.repeats // 3)),
               rdp=False)
    for n_so in range(1, 14):
        for mode in ("exact", "grid"):
            record("fig10", time_solve(standing_still(rings_rdp[:n_so]), PlannerConfig(grounding_mode=mode),
                                       args.repeats))

    meta = environment_meta("grounding on the Trondheim chart (issue: charts and anti-grounding)",
                            dtype="float32", T=150.0, dt=0.5)
    write_results(args.out, "grounding", meta, points)
    return 0


if __name__ == "__main__":
    sys.exit(main())
