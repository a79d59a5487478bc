#!/usr/bin/env python3
"""The experiments of Akdağ, Fossen & Johansen (2022, Figs. 4-8), reconstructed (the paper gives no
coordinates): each scenario with the two variants the paper compares, Informed SB-MPC on the own-ship, 3-DOF
PSV motion, the same seeds for both variants (run r's tracking noise is ``default_rng([seed, r])``).

    python experiments/akdag2022/run.py --runs 20 --out /tmp/akdag2022

=================================  =======================================  ===================================
scenario                           variants                                 the paper's finding
=================================  =======================================  ===================================
``akdag2022_head_on``              route exchange off / on                  off: starboard turn; on: port turn
``akdag2022_crossing_give_way``    route exchange off / on                  off: starboard turn; on: keeps on
``akdag2022_stand_on_rule18``      target role ``pdv`` / ``ram`` (P_R18)    pdv: crosses ahead, close; ram:
                                                                            slows down, keeps out of the way
``akdag2022_overtaken``            circular / bearing-shaped (k = 2) d_safe circular: earlier first manoeuvre
``akdag2022_three_ships``          one variant                              no collision; the power-driven
                                                                            ships keep out of the Rule-18 ship
=================================  =======================================  ===================================

Per (scenario, variant) it writes the simulator's output under ``<out>/<scenario>/<variant>/`` and, in
``<out>/comparison.json`` / ``comparison.md``, per run and aggregated: the own-ship's first manoeuvre (the first MPC
update whose chosen offsets differ from (1, 0): its time, side and speed factor), the minimum distance to the
target, the smallest speed factor chosen, and whether the own-ship passed ahead of or astern of the target.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import statistics
import pathlib
import sys
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))   # experiments/: comparison.py
from comparison import finish, start  # noqa: E402

STUDY = pathlib.Path(__file__).resolve().parent


def _informed(sc, **kw):
    """``sc`` with its ``mpc.informed`` section's fields replaced by ``kw``."""
    return dataclasses.replace(sc, mpc=sc.mpc.with_section("informed", **kw))


def _role(sc, role):
    return dataclasses.replace(sc, targets=tuple(dataclasses.replace(t, rule18_role=role) for t in sc.targets))


#: scenario -> (variant name -> function of the loaded scenario)
VARIANTS = {
    "akdag2022_head_on": {"no_route_exchange": lambda sc: _informed(sc, route_exchange=False),
                          "route_exchange": lambda sc: _informed(sc, route_exchange=True)},
    "akdag2022_crossing_give_way": {"no_route_exchange": lambda sc: _informed(sc, route_exchange=False),
                                    "route_exchange": lambda sc: _informed(sc, route_exchange=True)},
    "akdag2022_stand_on_rule18": {"P_default (role pdv)": lambda sc: _role(sc, "pdv"),
                                  "P_R18 (role ram)": lambda sc: _role(sc, "ram")},
    "akdag2022_overtaken": {"circular": lambda sc: _informed(sc, circular=True),
                            "bearing_shaped_k2": lambda sc: _informed(sc, circular=False)},
    "akdag2022_three_ships": {"default": lambda sc: sc},
}


def first_manoeuvre(offsets, period: float):
    """(t [s], side, speed factor) of the first update whose offsets differ from (1, 0); (None, "none", None)."""
    for m, (u, chi) in enumerate(offsets):
        if u == u and (abs(chi) > 1e-6 or u < 1.0 - 1e-9):
            side = "starboard" if chi > 1e-6 else "port" if chi < -1e-6 else "speed only"
            return m * period, side, float(u)
    return None, "none", None


def passed_ahead(own, tgt) -> bool | None:
    """Whether the own-ship crossed the target's track ahead of it: at the closest approach, the own-ship lies
    in front of the target (positive projection on the target's velocity)."""
    import numpy as np

    d = np.hypot(*(own[:, :2] - tgt[:, :2]).T)
    k = int(np.argmin(d))
    rel = own[k, :2] - tgt[k, :2]
    v = np.array([np.cos(tgt[k, 2]), np.sin(tgt[k, 2])])
    return bool(rel @ v > 0)


def records(result) -> list[dict]:
    import numpy as np

    out = []
    period = result.scenario.mpc.period
    for r in range(result.states.shape[0]):
        t0, side, u0 = first_manoeuvre(result.offsets[r, 0], period)
        d = np.hypot(*(result.states[r, 1:, :, :2] - result.states[r, :1, :, :2]).transpose(2, 0, 1))
        ships = result.scenario.ships
        r18 = [j for j, s in enumerate(ships) if s.rule18_role != "pdv"]
        astern = {ships[i].name: not passed_ahead(result.states[r, i], result.states[r, j])
                  for j in r18 for i, s in enumerate(ships) if s.colav != "none" and i != j}
        pair_min = {f"{ships[i].name}-{ships[j].name}": round(float(np.min(np.hypot(
            *(result.states[r, i, :, :2] - result.states[r, j, :, :2]).T))), 1)
            for i in range(len(ships)) for j in range(i + 1, len(ships))}
        out.append({"run": r, "first_manoeuvre_t_s": t0, "first_manoeuvre_side": side,
                    "passed_astern_of_rule18_ship": astern, "pair_min_distance_m": pair_min,
                    "first_manoeuvre_speed_factor": u0,
                    "first_manoeuvre_course_deg": None if t0 is None else
                    round(math.degrees(float(result.offsets[r, 0, int(round(t0 / period)), 1])), 1),
                    "min_distance_m": round(float(d.min()), 2),
                    "min_speed_factor": float(np.nanmin(result.offsets[r, 0, :, 0])),
                    "max_abs_course_offset_deg": round(math.degrees(float(np.nanmax(np.abs(result.offsets[r, 0, :, 1])))), 1),
                    "passed_ahead_of_target": passed_ahead(result.states[r, 0], result.states[r, 1]),
                    "collision": bool(result.metrics[r]["collision"])})
    return out


def aggregate(rows) -> dict:
    def stat(key):
        v = [r[key] for r in rows if r[key] is not None]
        return None if not v else {"median": statistics.median(v), "min": min(v), "max": max(v)}

    sides = [r["first_manoeuvre_side"] for r in rows]
    return {"runs": len(rows), "first_manoeuvre_side": {s: sides.count(s) for s in sorted(set(sides))},
            "first_manoeuvre_t_s": stat("first_manoeuvre_t_s"), "min_distance_m": stat("min_distance_m"),
            "min_speed_factor": stat("min_speed_factor"), "max_abs_course_offset_deg": stat("max_abs_course_offset_deg"),
            "passed_ahead_runs": sum(bool(r["passed_ahead_of_target"]) for r in rows),
            "all_planners_astern_of_rule18_runs": sum(bool(r["passed_astern_of_rule18_ship"]) and
                                                      all(r["passed_astern_of_rule18_ship"].values()) for r in rows),
            "collisions": sum(r["collision"] for r in rows)}


def markdown(doc) -> str:
    lines = ["| scenario | variant | runs | first manoeuvre (side: runs) | at t [s] median | min distance median "
             "(min–max) [m] | smallest speed factor (median) | largest course offset (median) [deg] | passed ahead "
             "| collisions |", "|---|---|---|---|---|---|---|---|---|---|"]
    for sc, per in doc["results"].items():
        for v, rec in per.items():
            a = rec["aggregate"]
            fm = ", ".join(f"{k}: {n}" for k, n in a["first_manoeuvre_side"].items())
            t = a["first_manoeuvre_t_s"]
            md = a["min_distance_m"]
            t_txt = "—" if t is None else f"{t['median']:.0f}"
            lines.append(f"| {sc} | {v} | {a['runs']} | {fm} | {t_txt} | "
                         f"{md['median']:.0f} ({md['min']:.0f}–{md['max']:.0f}) | {a['min_speed_factor']['median']:g} | "
                         f"{a['max_abs_course_offset_deg']['median']:g} | {a['passed_ahead_runs']} | {a['collisions']} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--runs", type=int, default=20)
    p.add_argument("--out", default=None,
                   help="output folder (default: a new results_<UTC stamp> folder next to this script)")
    p.add_argument("--force", action="store_true", help="write into an --out folder that already holds results")
    p.add_argument("--scenarios", default=",".join(VARIANTS), help="comma-separated subset of " + ", ".join(VARIANTS))
    p.add_argument("--quiet", action="store_true")
    args = p.parse_args(argv)
    names = [s.strip() for s in args.scenarios.split(",") if s.strip()]
    bad = [n for n in names if n not in VARIANTS]
    if bad or args.runs < 1:
        p.error(f"--scenarios from {', '.join(VARIANTS)} and --runs >= 1 expected, got {bad or args.runs}")

    from psbmpc_jax.scenario import load_scenario
    from psbmpc_jax.sim import simulate
    from psbmpc_jax.sim.output import write_outputs

    out, doc = start(args.out, STUDY, force=args.force, runs=args.runs)
    for name in names:
        base = load_scenario(name)
        for variant, make in VARIANTS[name].items():
            sc = make(base)
            t0 = time.perf_counter()
            res = simulate(sc, runs=args.runs, progress=not args.quiet)
            wall = time.perf_counter() - t0
            folder = variant.split(" ")[0].replace("(", "").replace(")", "")
            write_outputs(res, out / name / folder, figures=True, force=args.force)
            rows = records(res)
            doc["results"].setdefault(name, {})[variant] = {"aggregate": aggregate(rows), "runs": rows,
                                                           "wall_s": round(wall, 1)}
            a = doc["results"][name][variant]["aggregate"]
            print(f"{name} / {variant}: first manoeuvre {a['first_manoeuvre_side']}, min distance "
                  f"{a['min_distance_m']}, collisions {a['collisions']} ({wall:.0f} s)", flush=True)
    finish(out, doc, markdown(doc))
    return 0


if __name__ == "__main__":
    sys.exit(main())
