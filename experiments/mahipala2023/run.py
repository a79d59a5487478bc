#!/usr/bin/env python3
"""Simulation 2 of Mahipala & Johansen (2023) with the ``two_level`` method on the seven reconstructed Trondheim
scenarios (``tools/make_mahipala2023.py``), and the checks of what the paper reports:

* no collision, no grounding (the simulator's metrics);
* the riparian corridor never violated: every true own-ship position, in the frame of the leg nearest to it,
  within that leg's corridor bounds (Algorithm 1, the planner's own corridors) + ``--corridor-tol``;
* the static circles kept: distance to every circle centre >= its radius (r_os not included: the hull);
* the first manoeuvre of the SB-MPC (the first update with a target within its d_cl whose χ_m ≠ 0 or U_m < 1)
  to starboard in the head-on and give-way crossing scenarios (2, 3, 4, 7);
* the deviation from scenario 1's path (mean distance of each run's track to run 0 of scenario 1) larger in 3,
  6 and 7 than in the others.

    python experiments/mahipala2023/run.py --runs 10 --out /tmp/mahipala2023
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))   # experiments/: comparison.py
from comparison import finish, start  # noqa: E402

STUDY = pathlib.Path(__file__).resolve().parent

CASES = ("1_reference", "2_head_on", "3_crossing", "4_head_on_crossing", "5_overtaking", "6_overtaking_crossing",
         "7_combined")
STARBOARD_FIRST = ("2_head_on", "3_crossing", "4_head_on_crossing", "7_combined")


def first_manoeuvre(offsets, near):
    """(update index, side) of the first update with a target within the SB-MPC's d_cl (``near [M]``) whose
    SB-MPC modification is not (1, 0) (modifications away from targets answer land, ζ); (None, "none")."""
    for m, (u, chi) in enumerate(offsets):
        if near[m] and u == u and (abs(chi) > 1e-6 or u < 1.0 - 1e-9):
            return m, ("starboard" if chi > 1e-6 else "port" if chi < -1e-6 else "speed only")
    return None, "none"


def corridor_excess(planner, xy) -> np.ndarray:
    """Per position: how far [m] it lies outside the corridor of the leg nearest to it (0 inside)."""
    from psbmpc_jax.two_level.path_mpc import path_coordinates

    legs = planner.legs
    wp, psi, length = (np.asarray(a) for a in (legs.wp, legs.psi, legs.length))
    s, lo, hi = (np.asarray(a) for a in (legs.s, legs.lower, legs.upper))
    out = np.zeros(len(xy))
    for i, p in enumerate(xy):
        best = None
        for j in range(len(psi)):
            xp, yp = (float(v) for v in path_coordinates(p, wp[j], psi[j]))
            along = max(0.0, -xp, xp - float(length[j]))
            d = (along, abs(yp))
            if best is None or d < best[0]:
                best = (d, xp, yp, j)
        _, xp, yp, j = best
        lower, upper = np.interp(xp, s[j], lo[j]), np.interp(xp, s[j], hi[j])
        out[i] = max(0.0, yp - upper, lower - yp)
    return out


def records(result, planner, ref_xy, d_cl):
    rows = []
    steps = np.searchsorted(result.t, result.solve_t)
    centres = np.asarray(planner.circles.centres).reshape(-1, 2)
    radii = np.asarray(planner.circles.radii).reshape(-1)
    for r, m in enumerate(result.metrics):
        own = result.states[r, 0]
        xy = own[:, :2]
        tg = result.states[r, 1:, :, :2]                                   # [I, K+1, 2]
        near = (np.min(np.hypot(*(tg - xy[None]).transpose(2, 0, 1)), axis=0) < d_cl if len(tg)
                else np.zeros(len(xy), bool))[steps]
        k, side = first_manoeuvre(result.offsets[r, 0], near)
        excess = corridor_excess(planner, xy[::2])
        d_circ = (np.min(np.hypot(*(xy[:, None, :] - centres[None]).transpose(2, 0, 1)) - radii[None], axis=0)
                  if len(radii) else np.array([np.inf]))
        dev = float(np.mean([np.min(np.hypot(*(ref_xy - p).T)) for p in xy])) if ref_xy is not None else 0.0
        rows.append({"run": r, "collision": bool(m["collision"]), "grounding": bool(m["grounding"]),
                     "min_distance_land_m": m["min_distance_land_m"],
                     "min_distance_targets_m": {t["name"]: t["min_distance_m"] for t in m.get("targets", [])},
                     "corridor_excess_max_m": float(excess.max()),
                     "circle_clearance_min_m": float(np.min(d_circ)),
                     "first_manoeuvre_update": k, "first_manoeuvre_side": side,
                     "mean_deviation_from_reference_m": dev})
    return rows


def aggregate(rows) -> dict:
    sides = [r["first_manoeuvre_side"] for r in rows]
    return {"runs": len(rows), "collisions": sum(r["collision"] for r in rows),
            "groundings": sum(r["grounding"] for r in rows),
            "corridor_excess_max_m": max(r["corridor_excess_max_m"] for r in rows),
            "circle_clearance_min_m": min(r["circle_clearance_min_m"] for r in rows),
            "min_distance_land_m": min(r["min_distance_land_m"] for r in rows
                                       if r["min_distance_land_m"] is not None),
            "min_distance_targets_m": min([d for r in rows for d in r["min_distance_targets_m"].values()],
                                          default=None),
            "first_manoeuvre": {s: sides.count(s) for s in sorted(set(sides))},
            "mean_deviation_from_reference_m": float(np.mean([r["mean_deviation_from_reference_m"] for r in rows]))}


def markdown(doc) -> str:
    lines = ["| scenario | collisions | groundings | corridor excess max [m] | circle clearance min [m] | "
             "closest target [m] | closest land [m] | first manoeuvre | mean deviation from 1 [m] |",
             "|---|---|---|---|---|---|---|---|---|"]
    for name, res in doc["results"].items():
        a = res["aggregate"]
        tgt = "—" if a["min_distance_targets_m"] is None else f"{a['min_distance_targets_m']:.1f}"
        first = ", ".join(f"{k} {v}" for k, v in a["first_manoeuvre"].items())
        lines.append(f"| {name} | {a['collisions']}/{a['runs']} | {a['groundings']}/{a['runs']} | "
                     f"{a['corridor_excess_max_m']:.2f} | {a['circle_clearance_min_m']:.1f} | {tgt} | "
                     f"{a['min_distance_land_m']:.1f} | {first} | {a['mean_deviation_from_reference_m']:.1f} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--runs", type=int, default=10)
    p.add_argument("--out", default=None,
                   help="output folder (default: a new results_<UTC stamp> folder next to this script)")
    p.add_argument("--force", action="store_true", help="write into an --out folder that already holds results")
    p.add_argument("--scenarios", default=",".join(CASES))
    p.add_argument("--quiet", action="store_true")
    args = p.parse_args(argv)
    names = [s.strip() for s in args.scenarios.split(",") if s.strip()]
    if any(n not in CASES for n in names) or args.runs < 1 or names[:1] != ["1_reference"]:
        p.error(f"--scenarios: a subset of {', '.join(CASES)} starting with 1_reference; --runs >= 1")

    from psbmpc_jax.scenario import load_scenario
    from psbmpc_jax.sim import simulate
    from psbmpc_jax.methods.two_level import TwoLevelController
    from psbmpc_jax.sim.output import write_outputs

    out, doc = start(args.out, STUDY, force=args.force, runs=args.runs, method="two_level")
    ref_xy = None
    for name in names:
        sc = load_scenario(f"mahipala2023_{name}")
        t0 = time.perf_counter()
        res = simulate(sc, runs=args.runs, progress=not args.quiet)
        wall = time.perf_counter() - t0
        planner = TwoLevelController(sc).planner                  # the same corridors and circles (cached)
        write_outputs(res, out / name, figures=True, force=args.force)
        if ref_xy is None:
            ref_xy = res.states[0, 0, :, :2]
        rows = records(res, planner, ref_xy, sc.mpc.sbmpc.d_cl)
        doc["results"][name] = {"aggregate": aggregate(rows), "runs": rows, "wall_s": round(wall, 1),
                                "solve_time_mean_s": float(np.nanmean(res.solve_wall[:, 0]))}
        a = doc["results"][name]["aggregate"]
        print(f"{name}: collisions {a['collisions']}, groundings {a['groundings']}, corridor excess "
              f"{a['corridor_excess_max_m']:.2f} m, first {a['first_manoeuvre']} ({wall:.0f} s)", flush=True)
    finish(out, doc, markdown(doc))
    return 0


if __name__ == "__main__":
    sys.exit(main())
