#!/usr/bin/env python3
"""The closed-loop experiments of Tengesdal, Brekke & Johansen (2020, Sec. 7): scenario A (head-on, noisy
tracking) and scenario B (13 random obstacles), each with the original SB-MPC (``sbmpc``) and the paper's PSB-MPC
(``psbmpc_2020``) on the same seeds (run r's measurement noise is ``default_rng([seed, r])`` for both methods).

    python experiments/tengesdal2020/run.py --runs 20 --out /tmp/tengesdal2020

Per (scenario, method) it writes the simulator's usual output under ``<out>/<scenario>/<method>/`` and, in
``<out>/comparison.json`` and ``<out>/comparison.md``, per run and aggregated:

* the minimum distance to any target [m] and the runs whose minimum is below d_safe (40 m: a safety-zone
  violation, the paper's Fig. 4b criterion) or below the collision distance;
* the side of the own-ship's first course alteration: the first MPC update whose chosen course offset has
  |χ_m| ≥ ``--alteration-deg`` (default 1°), "starboard" (χ_m > 0) or "port"; "none" if it never alters;
* the mean path deviation [m] (cross-track distance to the planned route), the paper's "on par" criterion;
* the mean solve time.

The paper's findings: in A the SB-MPC dips slightly below d_safe while the PSB-MPC keeps clear
with a larger margin; in B the PSB-MPC turns to starboard and the SB-MPC to port.
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

SCENARIOS = ("tengesdal2020_a", "tengesdal2020_b")
METHODS = ("sbmpc", "psbmpc_2020")


def first_alteration(offsets_chi, threshold_rad: float) -> tuple[str, int | None]:
    """(side, update index) of the first |χ_m| >= threshold in one run's chosen course offsets [M]."""
    for m, chi in enumerate(offsets_chi):
        if chi == chi and abs(chi) >= threshold_rad:          # NaN-safe
            return ("starboard" if chi > 0 else "port"), m
    return "none", None


def run_records(result, d_safe: float, threshold_rad: float) -> list[dict]:
    import numpy as np

    out = []
    for r, m in enumerate(result.metrics):
        dmin = min(t["min_distance_m"] for t in m["targets"])
        side, k = first_alteration(result.offsets[r, 0, :, 1], threshold_rad)
        out.append({
            "run": r,
            "min_distance_m": round(float(dmin), 3),
            "closest_target": min(m["targets"], key=lambda t: t["min_distance_m"])["name"],
            "d_safe_violation": bool(dmin < d_safe),
            "collision": bool(m["collision"]),
            "first_alteration": side,
            "first_alteration_t_s": None if k is None else float(k * result.scenario.mpc.period),
            "first_alteration_deg": None if k is None else round(float(np.degrees(result.offsets[r, 0, k, 1])), 1),
            "path_deviation_mean_m": round(float(m["path_deviation_mean_m"]), 3),
            "solve_time_mean_s": m.get("solve_time_mean_s"),
        })
    return out


def aggregate(rows: list[dict]) -> dict:
    d = [r["min_distance_m"] for r in rows]
    sides = [r["first_alteration"] for r in rows]
    return {
        "runs": len(rows),
        "min_distance_m": {"median": round(statistics.median(d), 2), "min": min(d), "max": max(d),
                           "mean": round(statistics.fmean(d), 2)},
        "d_safe_violations": sum(r["d_safe_violation"] for r in rows),
        "collisions": sum(r["collision"] for r in rows),
        "first_alteration": {s: sides.count(s) for s in ("starboard", "port", "none")},
        "path_deviation_mean_m": round(statistics.fmean(r["path_deviation_mean_m"] for r in rows), 2),
        "solve_time_mean_ms": round(1e3 * statistics.fmean(r["solve_time_mean_s"] for r in rows
                                                           if r["solve_time_mean_s"] is not None), 1),
    }


def markdown(doc: dict) -> str:
    lines = ["| scenario | method | runs | min distance median (min–max) [m] | runs < d_safe 40 m | collisions | "
             "first alteration stbd / port / none | mean path deviation [m] | solve [ms] |",
             "|---|---|---|---|---|---|---|---|---|"]
    for sc, per in doc["results"].items():
        for m, rec in per.items():
            a = rec["aggregate"]
            md, fa = a["min_distance_m"], a["first_alteration"]
            lines.append(f"| {sc} | {m} | {a['runs']} | {md['median']:.1f} ({md['min']:.1f}–{md['max']:.1f}) | "
                         f"{a['d_safe_violations']} | {a['collisions']} | {fa['starboard']} / {fa['port']} / "
                         f"{fa['none']} | {a['path_deviation_mean_m']:.1f} | {a['solve_time_mean_ms']:.0f} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--runs", type=int, default=20, help="Monte Carlo runs per (scenario, method) (default 20)")
    p.add_argument("--seed", type=int, default=None, help="base seed (default: the scenario's)")
    p.add_argument("--out", default=None,
                   help="output folder (default: a new results_<UTC stamp> folder next to this script)")
    p.add_argument("--force", action="store_true", help="write into an --out folder that already holds results")
    p.add_argument("--scenarios", default=",".join(SCENARIOS), help="comma-separated scenario names or paths")
    p.add_argument("--alteration-deg", type=float, default=1.0, help="course offset counted as an alteration")
    p.add_argument("--sbmpc", action="append", default=[], metavar="FIELD=VALUE",
                   help="override a psbmpc_jax.methods.SbmpcSettings field for both methods, e.g. T_c=30 "
                        "(a sensitivity run; repeatable)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    args = p.parse_args(argv)
    if args.runs < 1:
        p.error(f"--runs must be >= 1, got {args.runs}")
    overrides = {}
    for item in args.sbmpc:
        key, sep, value = item.partition("=")
        if not sep:
            p.error(f"--sbmpc expects FIELD=VALUE, got {item!r}")
        try:
            overrides[key.strip()] = int(value) if key.strip() in ("n_mc", "seed") else float(value)
        except ValueError:
            p.error(f"--sbmpc {key}: a number expected, got {value!r}")

    from psbmpc_jax.scenario import load_scenario
    from psbmpc_jax.sim import simulate
    from psbmpc_jax.sim.output import write_outputs

    names = [s.strip() for s in args.scenarios.split(",") if s.strip()]
    loaded = {(n, m): load_scenario(n, method=m) for n in names for m in METHODS}       # file errors first
    if overrides:
        try:
            loaded = {k: dataclasses.replace(sc, mpc=sc.mpc.with_section("sbmpc", **overrides))
                      for k, sc in loaded.items()}
        except (TypeError, ValueError) as exc:
            p.error(f"--sbmpc: {exc}")
    out, doc = start(args.out, STUDY, force=args.force, runs=args.runs, alteration_deg=args.alteration_deg,
                     sbmpc_overrides=overrides)
    for (name, method), sc in loaded.items():
        t0 = time.perf_counter()
        res = simulate(sc, runs=args.runs, seed=args.seed, progress=not args.quiet)
        wall = time.perf_counter() - t0
        write_outputs(res, out / sc.name / method, figures=True, force=args.force)
        rows = run_records(res, sc.mpc.sbmpc.d_safe, math.radians(args.alteration_deg))
        rec = {"aggregate": aggregate(rows), "runs": rows, "wall_s": round(wall, 1), "d_safe_m": sc.mpc.sbmpc.d_safe,
               "collision_distance_m": sc.d_collision, "seed": sc.seed if args.seed is None else args.seed}
        doc["results"].setdefault(sc.name, {})[method] = rec
        a = rec["aggregate"]
        print(f"{sc.name} {method}: {args.runs} runs in {wall:.0f} s; min distance median {a['min_distance_m']['median']} "
              f"m (min {a['min_distance_m']['min']}), < d_safe in {a['d_safe_violations']}, collisions "
              f"{a['collisions']}, first alteration {a['first_alteration']}", flush=True)
    finish(out, doc, markdown(doc))
    return 0


if __name__ == "__main__":
    sys.exit(main())
