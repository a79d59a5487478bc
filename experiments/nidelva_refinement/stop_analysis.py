#!/usr/bin/env python3
"""Where PSB-MPC + refinement's stops on Nidelva come from: at every MPC update of the own-ship, the grid
search's choice (is its first maneuver a stop, speed factor < 0.05?) against the refined control applied
(speed factor < 0.05?), per run, with the runs' longest stops.

    python experiments/nidelva_refinement/stop_analysis.py --runs 15 --out /tmp/stop_analysis.json

Same scenario, seeds and settings as ``experiments/compare_methods.py nidelva --methods psbmpc,psbmpc_refine``
(runs 0 … R − 1 of seed 1 are the same runs there).  A stopped update: own-ship speed <= 0.2 m/s at the update
(the metrics' stop threshold).  ``--start-margin`` overrides the solver's ``start_margin`` (how far into the box
the starts are moved; a start on the speed bound 0, the stop behaviour, sits where the sin box map's slope
vanishes): a check whether the stops are an artefact of that map.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import pathlib
import platform
import sys

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))   # experiments/: comparison.py
from comparison import output_file, utc_stamp  # noqa: E402

STUDY = pathlib.Path(__file__).resolve().parent
STOP_FACTOR = 0.05
STOP_SPEED = 0.2


def first_maneuver_stops(behaviours) -> np.ndarray:
    """Per behaviour ``[B, n_M, 2]``: does its first maneuver stop (speed factor < STOP_FACTOR)?"""
    return np.asarray(behaviours)[..., 0, 0] < STOP_FACTOR


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--runs", type=int, default=15)
    p.add_argument("--out", default=None, help="output JSON file (default: a new results/stop_analysis_<UTC "
                   "stamp>.json next to this script); an existing file is refused unless --force")
    p.add_argument("--force", action="store_true", help="write over an existing --out file")
    p.add_argument("--start-margin", type=float, default=None,
                   help="the refinement solver's start_margin (default: the library's, 1e-3)")
    args = p.parse_args(argv)
    out = output_file(args.out, STUDY / "results" / f"stop_analysis_{utc_stamp()}.json", force=args.force)

    import jax

    from psbmpc_jax.provenance import commit
    from psbmpc_jax.scenario import load_scenario
    from psbmpc_jax.methods import grid
    from psbmpc_jax.sim import simulate

    started_at = commit()
    seen, terms_seen = [], []
    original = grid._Solver._refine_one

    def recording(self, inputs, plan, state, evaluation):
        ref = original(self, inputs, plan, state, evaluation)
        seen.append((int(np.asarray(plan.best)), float(np.asarray(ref.apply)[0]), int(ref.behaviour)))
        terms_seen.append((np.asarray(evaluation.total, np.float64),
                           {k: np.asarray(v, np.float64) for k, v in evaluation.costs.items()}))
        return ref

    grid._Solver._refine_one = recording
    if args.start_margin is not None:
        settings_of = grid.refine_settings

        def with_margin(mpc, cls):
            s = settings_of(mpc, cls)
            return s.replace(solver=s.solver.replace(start_margin=args.start_margin))

        grid.refine_settings = with_margin
    sc = load_scenario("nidelva", method="psbmpc_refine")
    res = simulate(sc, runs=args.runs, progress=False)
    behaviours = np.asarray(sc.mpc.behaviours)
    M, R = len(res.solve_t), args.runs
    if len(seen) != M * R:
        raise RuntimeError(f"expected {M * R} refinements (updates x runs), recorded {len(seen)}")
    best = np.array([s[0] for s in seen]).reshape(M, R)
    applied_u = np.array([s[1] for s in seen]).reshape(M, R)
    from_previous = np.array([s[2] == -1 for s in seen]).reshape(M, R)
    k = np.searchsorted(res.t, res.solve_t)
    stopped = res.states[:, 0, k, 3].T <= STOP_SPEED                                   # [M, R]
    grid_stop = first_maneuver_stops(behaviours)[best]                                   # [M, R]
    refined_stop = applied_u < STOP_FACTOR
    runs = []
    for r in range(R):
        s, g, f = stopped[:, r], grid_stop[:, r], refined_stop[:, r]
        runs.append({"run": r, "longest_stop_s": res.metrics[r]["longest_stop_s"], "stopped_updates": int(s.sum()),
                     "grid_chose_stop_at_stopped_updates": int((g & s).sum()),
                     "refined_stop_at_stopped_updates": int((f & s).sum()),
                     "grid_chose_stop_updates": int(g.sum()), "refined_stop_updates": int(f.sum()),
                     "refined_stop_while_grid_moves": int((f & ~g).sum()),
                     "kept_previous_plan_start": int(from_previous[:, r].sum())})
    total = {key: int(sum(x[key] for x in runs)) for key in runs[0] if key not in ("run", "longest_stop_s")}
    why = why_stop(terms_seen, behaviours, best, stopped)
    doc = {"scenario": "nidelva", "method": "psbmpc_refine", "runs": R, "seed": sc.seed, "updates_per_run": M,
           "start_margin": args.start_margin,
           "mean_abs_course_rate_deg_s": float(np.mean([x["mean_abs_course_rate_deg_s"] for x in res.metrics])),
           "collisions": res.summary["collisions"], "groundings": res.summary["groundings"],
           "stop_speed_factor_below": STOP_FACTOR, "stopped_speed_m_s_at_most": STOP_SPEED, "per_run": runs,
           "total": total, "why_the_grid_stops": why, "commit": started_at, "device": str(jax.devices()[0]),
           "platform": platform.platform(),
           "versions": {"python": sys.version.split()[0], "jax": jax.__version__, "numpy": np.__version__},
           "command": "python experiments/nidelva_refinement/stop_analysis.py "
                      + " ".join(argv if argv is not None else sys.argv[1:]),
           "utc": dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")}
    out.write_text(json.dumps(doc, indent=1) + "\n")
    for x in runs:
        print(json.dumps(x))
    print("total", json.dumps(total))
    print("why_the_grid_stops", json.dumps(why, indent=1))
    return 0


def why_stop(terms_seen, behaviours, best, stopped) -> dict:
    """At every update where the grid search chose a stop (first maneuver's speed factor < STOP_FACTOR): the
    chosen behaviour's cost per term against the cheapest behaviour whose first maneuver moves, and which term
    decides (the largest positive share of the gap cost(moving) - cost(stop)).  Split by whether the own-ship
    was already stopped at the update (then the path term's speed-change cost to set off counts against
    moving).  ``terms_seen`` holds one (total, {term: cost}) per (update, run) in the order of ``best`` and
    ``stopped`` ``[M, R]``."""
    stops = first_maneuver_stops(behaviours)                          # [B]
    n_b = len(behaviours)
    names = sorted(terms_seen[0][1])
    rows = {"already_stopped": [], "moving": []}
    for (total, costs), b, was_stopped in zip(terms_seen, np.ravel(best), np.ravel(stopped)):
        if not stops[b]:
            continue
        parts = np.stack([costs[k][:n_b] for k in names])             # [K, B]
        if not np.allclose(parts.sum(0), total[:n_b], rtol=1e-4, atol=1e-6):
            raise RuntimeError("the evaluation's total is not the sum of its terms; the decomposition needs it")
        alt = np.where(~stops & np.isfinite(total[:n_b]), total[:n_b], np.inf)
        j = int(np.argmin(alt))
        gap = parts[:, j] - parts[:, b]                               # > 0: the term favours the stop
        rows["already_stopped" if was_stopped else "moving"].append(
            {"gap": float(total[j] - total[b]), "terms": dict(zip(names, gap.tolist())),
             "decides": names[int(np.argmax(gap))]})

    def summary(rs):
        if not rs:
            return {"updates": 0}
        return {"updates": len(rs), "median_gap": float(np.median([x["gap"] for x in rs])),
                "decided_by": {k: sum(x["decides"] == k for x in rs) for k in names},
                "median_term_gap": {k: float(np.median([x["terms"][k] for x in rs])) for k in names},
                "updates_where_term_favours_stop": {k: sum(x["terms"][k] > 0 for x in rs) for k in names}}

    return {"what": "grid search's stop choice vs the cheapest behaviour whose first maneuver moves: per-term "
                    "cost(moving) - cost(stop) (> 0 favours the stop); 'decides' = the term with the largest "
                    "positive share", "terms": names,
            "already_stopped": summary(rows["already_stopped"]), "moving": summary(rows["moving"])}


if __name__ == "__main__":
    sys.exit(main())
