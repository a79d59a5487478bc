#!/usr/bin/env python3
"""PSB-MPC on the ``nidelva`` scenario with the published cost and with the COLREGS stop remedy, same runs:
collisions, groundings, stops, course rate, closest approaches.

    python experiments/stop_remedy/nidelva.py --runs 20 --out /tmp/nidelva.json

Same scenario, seed and settings as ``experiments/compare_methods.py nidelva --methods psbmpc`` (its runs 0 …
R − 1 of seed 1), the only change ``mpc.config.stop_remedy``.  ``--method psbmpc_refine`` for the refined
variant.  Stops are computed here from the true own-ship speed (<= 0.2 m/s).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import pathlib
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))   # experiments/: comparison.py
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from comparison import output_file, utc_stamp  # noqa: E402
from common import course_rate, min_target_distance, stop_stats, write_record  # noqa: E402

STUDY = pathlib.Path(__file__).resolve().parent
VARIANTS = {"paper": "none", "colregs_heading": "colregs_heading"}


def rows_of(res) -> list[dict]:
    rows = []
    for r, m in enumerate(res.metrics):
        own = res.states[r, 0]
        dmin, who = min_target_distance(res.states[r])
        rows.append({"run": r, "collision": bool(m["collision"]), "grounding": bool(m["grounding"]),
                     "closest_target_m": round(dmin, 2), "closest_land_m": m["min_distance_land_m"],
                     "stops": stop_stats(res.t, own[:, 3]),
                     "mean_abs_course_rate_deg_s": round(float(m["mean_abs_course_rate_deg_s"]), 4),
                     "mean_abs_course_rate_here_deg_s": round(course_rate(res.t, own[:, 2]), 4),
                     "path_length_m": m.get("path_length_m")})
    return rows


def decomposition(variant: str, runs: int, method: str) -> dict:
    """Every own-ship solve of ``runs`` runs (loop mode): where the search chose a stop, the stop's cost per term
    against the cheapest moving behaviour (:func:`stop_analysis.why_stop`), split by whether the own-ship was
    already stopped."""
    sys.path.insert(0, str(STUDY.parent / "nidelva_refinement"))
    from common import Recorder
    from stop_analysis import first_maneuver_stops, why_stop

    from psbmpc_jax.scenario import load_scenario
    from psbmpc_jax.sim import simulate

    sc = load_scenario("nidelva", method=method)
    sc = dataclasses.replace(sc, mpc=dataclasses.replace(sc.mpc, config=sc.mpc.config.replace(stop_remedy=VARIANTS[variant])))
    with Recorder() as rec:
        res = simulate(sc, runs=runs, progress=False, batch="loop")
    n_ships = sum(s.colav != "none" for s in sc.ships)
    M = len(res.solve_t)
    if len(rec.seen) != M * runs * n_ships or sc.ships[0].colav == "none":
        raise RuntimeError(f"expected {M * runs * n_ships} solves, recorded {len(rec.seen)}")
    own = [rec.seen[(m * runs + r) * n_ships] for m in range(M) for r in range(runs)]        # ship 0 first per run
    beh = np.asarray(sc.mpc.behaviours)
    best = np.array([int(np.argmin(t[: len(beh)])) for t, _, _ in own]).reshape(M, runs)
    k = np.searchsorted(res.t, res.solve_t)
    stopped = res.states[:, 0, k, 3].T <= 0.2
    return {"runs": runs, "grid_chose_stop_updates": int(first_maneuver_stops(beh)[best].sum()),
            "longest_stop_s": [stop_stats(res.t, res.states[r, 0, :, 3])["longest_s"] for r in range(runs)],
            "why_the_grid_stops": why_stop([(t, c) for t, c, _ in own], beh, best, stopped)}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--runs", type=int, default=20)
    p.add_argument("--method", default="psbmpc", choices=("psbmpc", "psbmpc_refine"))
    p.add_argument("--variants", default="paper,colregs_heading", help=f"comma-separated, of {', '.join(VARIANTS)}")
    p.add_argument("--decompose", type=int, default=0, metavar="R",
                   help="instead: the stop decomposition of the first R runs of each variant (loop mode; "
                        "experiments/nidelva_refinement/stop_analysis.py's why_stop on the grid search)")
    p.add_argument("--out", default=None, help="output JSON (default results/nidelva_<UTC stamp>.json)")
    p.add_argument("--force", action="store_true", help="write over an existing --out file")
    args = p.parse_args(argv)
    variants = [v.strip() for v in args.variants.split(",") if v.strip()]
    if any(v not in VARIANTS for v in variants) or args.runs < 1:
        p.error(f"--variants must be of {list(VARIANTS)}, --runs >= 1")
    out = output_file(args.out, STUDY / "results" / f"nidelva_{utc_stamp()}.json", force=args.force)


    from psbmpc_jax.provenance import commit
    from psbmpc_jax.scenario import load_scenario
    from psbmpc_jax.sim import simulate

    started_at, t_all = commit(), time.perf_counter()
    doc = {"what": __doc__.split("\n\n")[0], "scenario": "nidelva", "method": args.method, "runs": args.runs,
           "stop_speed_m_s": 0.2, "results": {}}
    if args.decompose:
        doc["decomposition"] = {v: decomposition(v, args.decompose, args.method) for v in variants}
        variants = []
    for v in variants:
        sc = load_scenario("nidelva", method=args.method)
        sc = dataclasses.replace(sc, mpc=dataclasses.replace(
            sc.mpc, config=sc.mpc.config.replace(stop_remedy=VARIANTS[v])))
        t0 = time.perf_counter()
        res = simulate(sc, runs=args.runs, progress=False)
        rows = rows_of(res)
        longest = [r["stops"]["longest_s"] for r in rows]
        rates = [r["mean_abs_course_rate_deg_s"] for r in rows]
        doc["results"][v] = {
            "stop_remedy": VARIANTS[v], "seed": sc.seed, "wall_s": round(time.perf_counter() - t0, 1),
            "collisions": sum(r["collision"] for r in rows), "groundings": sum(r["grounding"] for r in rows),
            "longest_stop_s": {"max": max(longest), "median": float(np.median(longest)), "mean": float(np.mean(longest)),
                               "runs_over_30_s": sum(x > 30 for x in longest)},
            "mean_abs_course_rate_deg_s": {"mean": round(float(np.mean(rates)), 4), "max": max(rates)},
            "closest_target_m": min(r["closest_target_m"] for r in rows),
            "closest_land_m": min(r["closest_land_m"] for r in rows), "per_run": rows}
        print(v, json.dumps({k: x for k, x in doc["results"][v].items() if k != "per_run"}), flush=True)
    write_record(out, doc, "nidelva.py", argv, started_at, t_all)
    return 0


if __name__ == "__main__":
    sys.exit(main())
