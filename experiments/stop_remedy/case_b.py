#!/usr/bin/env python3
"""Congested traffic (Tengesdal, Brekke & Johansen 2020, scenario B) over ten random traffic draws, with the
paper's target process noise, for the 2020 PSB-MPC (``psbmpc_2020``) with its cost as published and with stop
remedies; and the stop decomposition of the published cost on the committed draw.

    python experiments/stop_remedy/case_b.py --out /tmp/case_b.json

Traffic draw d: the 13 targets of :func:`psbmpc_jax.traffic.random_targets` ``(13, seed=d)`` (d = 0 is the
built-in ``tengesdal2020_b``), the own-ship, tracking and MPC settings of ``tengesdal2020_b``.  The targets'
true motion is a constant-velocity model with process noise of strength ``--sigma-a`` (default 0.03 m/s², the
bound the paper gives), drawn per update (:func:`common.cv_noise_method`); the built-in scenario has straight
lines.  ``--runs`` runs per draw (measurement and target-motion noise from ``[seed, run]``).

Variants (``--variants``): ``paper`` (the published cost), ``colregs_heading`` (``mpc.config.stop_remedy:
colregs_heading``), ``free_speed_change`` (the published cost with K_Δu = 0: setting off again costs nothing, a
stand-in for a restart rule) and ``both``; as a sensitivity (not the paper's tuning) ``paper_Tc30`` and
``colregs_heading_Tc30``, the collision discount T_c = 30 s in place of Table 1's 6 s.

Per (variant, draw, run): collision (the simulator's metric: closest approach below the scenario's collision
distance, 30 m), closest approach [m], the stops (speed <= 0.2 m/s: count, longest, first), mean |course rate|.

The decomposition (``--decompose``, variant ``paper``, draw 0, the first run): at every update where the grid
search chose a stop (first maneuver's speed factor < 0.05), the stop's cost split (collision sum, COLREGS sum of
the obstacle that sets the maximum of eq. (20), manoeuvring) against the cheapest behaviour whose first maneuver
moves.
"""

from __future__ import annotations

import argparse
import copy
import json
import pathlib
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))   # experiments/: comparison.py
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from comparison import output_file, utc_stamp  # noqa: E402
from common import STOP_FACTOR, Recorder, course_rate, cv_noise_method, min_target_distance, stop_stats, write_record  # noqa: E402

STUDY = pathlib.Path(__file__).resolve().parent
VARIANTS = {"paper": ("none", {}), "colregs_heading": ("colregs_heading", {}),
            "free_speed_change": ("none", {"Delta_U": 0.0}), "both": ("colregs_heading", {"Delta_U": 0.0}),
            # sensitivity, not the paper's tuning: the collision discount T_c = 30 s instead of Table 1's 6 s
            "paper_Tc30": ("none", {"T_c_s": 30.0}), "colregs_heading_Tc30": ("colregs_heading", {"T_c_s": 30.0})}


def scenario_dict(draw: int, colav: str) -> dict:
    import yaml

    import psbmpc_jax
    from psbmpc_jax.traffic import random_targets

    d = yaml.safe_load((pathlib.Path(psbmpc_jax.__file__).parent / "scenarios" / "tengesdal2020_b.yaml").read_text())
    d["name"] = f"tengesdal2020_b_draw{draw}"
    d["targets"] = [dict(t, colav=colav) for t in random_targets(13, seed=draw)]
    return d


def build(draw: int, variant: str, colav: str):
    from psbmpc_jax.scenario import scenario_from_dict

    remedy, sbmpc = VARIANTS[variant]
    d = copy.deepcopy(scenario_dict(draw, colav))
    d["mpc"]["config"] = {"stop_remedy": remedy}
    d["mpc"]["sbmpc"] = dict(d["mpc"]["sbmpc"], **sbmpc)
    return scenario_from_dict(d)


def run_rows(res) -> list[dict]:
    rows = []
    for r, m in enumerate(res.metrics):
        own = res.states[r, 0]
        dmin, who = min_target_distance(res.states[r])
        rows.append({"run": r, "collision": bool(m["collision"]), "closest_m": round(dmin, 2),
                     "closest_target": res.scenario.ships[who].name, "stops": stop_stats(res.t, own[:, 3]),
                     "mean_abs_course_rate_deg_s": round(course_rate(res.t, own[:, 2]), 4)})
    return rows


def decompose(seen, behaviours, speeds) -> list[dict]:
    """Per update where the grid chose a stop: the stop's and the cheapest moving behaviour's cost split."""
    stops = np.asarray(behaviours)[:, 0, 0] < STOP_FACTOR
    out = []
    for m, (total, costs, det) in enumerate(seen):
        n_b = len(behaviours)
        b = int(np.argmin(total[:n_b]))
        if not stops[b]:
            continue
        alt = np.where(~stops & np.isfinite(total[:n_b]), total[:n_b], np.inf)
        j = int(np.argmin(alt))

        def split(k):
            h = det["psbmpc2020_h"][k]                       # [O]
            i = int(np.argmax(h))
            coll = float(np.sum(det["psbmpc2020_coll_i"][k, i]))
            col = float(np.sum(det["psbmpc2020_colregs_i"][k, i]))
            rest = {name: float(v[k]) for name, v in costs.items() if name != "psbmpc2020"}
            return {"behaviour": np.asarray(behaviours[k]).round(4).tolist(), "total": float(total[k]),
                    "max_obstacle": i, "collision_sum": coll, "colregs_sum": col, "psbmpc2020": float(h[i]), **rest}

        out.append({"update": m, "own_speed_m_s": round(float(speeds[m]), 3), "stop": split(b), "cheapest_moving": split(j)})
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--draws", default="0-9", help="traffic draws, 'a-b' or comma-separated (default 0-9)")
    p.add_argument("--runs", type=int, default=1, help="runs per draw (default 1)")
    p.add_argument("--variants", default="paper,colregs_heading", help=f"comma-separated, of {', '.join(VARIANTS)}")
    p.add_argument("--sigma-a", type=float, default=0.03, help="targets' process-noise strength [m/s^2]")
    p.add_argument("--decompose", action="store_true", help="also the stop decomposition (paper, draw 0, run 0)")
    p.add_argument("--out", default=None, help="output JSON (default results/case_b_<UTC stamp>.json)")
    p.add_argument("--force", action="store_true", help="write over an existing --out file")
    args = p.parse_args(argv)
    a, sep, b = args.draws.partition("-")
    draws = list(range(int(a), int(b) + 1)) if sep else [int(x) for x in args.draws.split(",")]
    variants = [v.strip() for v in args.variants.split(",") if v.strip()]
    bad = [v for v in variants if v not in VARIANTS]
    if bad or args.runs < 1 or not args.sigma_a >= 0:
        p.error(f"--variants must be of {list(VARIANTS)} (got {bad}); --runs >= 1; --sigma-a >= 0")
    out = output_file(args.out, STUDY / "results" / f"case_b_{utc_stamp()}.json", force=args.force)


    from psbmpc_jax.methods import register
    from psbmpc_jax.provenance import commit
    from psbmpc_jax.sim import simulate

    colav = "cv_noise" if args.sigma_a > 0 else "none"
    if args.sigma_a > 0:
        register(cv_noise_method(args.sigma_a), replace=True)
    started_at, t_all = commit(), time.perf_counter()
    doc = {"what": __doc__.split("\n\n")[0], "draws": draws, "runs_per_draw": args.runs, "sigma_a_mps2": args.sigma_a,
           "stop_speed_m_s": 0.2, "results": {}}
    for v in variants:
        rows, t0 = [], time.perf_counter()
        for d in draws:
            sc = build(d, v, colav)
            res = simulate(sc, runs=args.runs, progress=False)
            for row in run_rows(res):
                rows.append({"draw": d, **row})
                print(v, json.dumps(rows[-1]), flush=True)
        longest = [r["stops"]["longest_s"] for r in rows]
        doc["results"][v] = {
            "stop_remedy": VARIANTS[v][0], "sbmpc_overrides": VARIANTS[v][1], "wall_s": round(time.perf_counter() - t0, 1),
            "collisions": sum(r["collision"] for r in rows), "runs": len(rows),
            "longest_stop_s": {"max": max(longest), "median": float(np.median(longest)),
                               "runs_with_a_stop": sum(x > 0 for x in longest)},
            "closest_m": {"min": min(r["closest_m"] for r in rows), "median": float(np.median([r["closest_m"] for r in rows]))},
            "mean_abs_course_rate_deg_s": round(float(np.mean([r["mean_abs_course_rate_deg_s"] for r in rows])), 4),
            "per_run": rows}
        print(v, json.dumps({k: x for k, x in doc["results"][v].items() if k != "per_run"}), flush=True)
    if args.decompose:
        sc = build(0, "paper", colav)
        with Recorder(("psbmpc2020_h", "psbmpc2020_coll_i", "psbmpc2020_colregs_i")) as rec:
            res = simulate(sc, runs=1, progress=False, batch="loop")
        k = np.searchsorted(res.t, res.solve_t)
        rows = decompose(rec.seen, sc.mpc.behaviours, res.states[0, 0, k, 3])
        doc["decomposition"] = {"draw": 0, "run": 0, "variant": "paper", "stop_stats": stop_stats(res.t, res.states[0, 0, :, 3]),
                                "updates": len(rec.seen), "stop_updates": rows}
        print("decomposition", json.dumps(rows[:3], indent=1))
    write_record(out, doc, "case_b.py", argv, started_at, t_all)
    return 0


if __name__ == "__main__":
    sys.exit(main())
