#!/usr/bin/env python3
"""Combine folders of ``experiments/compare_methods.py`` that hold disjoint runs of one Monte Carlo set (the same
scenario, seed and methods; ``--first-run`` picks the runs) into the figures of the whole set: per method the
collisions, groundings, closest approach to land and to each target, the mean |course rate| per run and over
the runs, and each method's change against the first method (ratio of the means, per run, bootstrap 95 %
interval over the runs).  Nothing is simulated.

    python experiments/smooth_sbmpc/combine_sets.py experiments/smooth_sbmpc/results/guidance_12runs/terminal_los \\
        experiments/smooth_sbmpc/results/guidance_runs12to19/terminal_los \\
        --out experiments/smooth_sbmpc/results/guidance_20runs_terminal_los.json

Refused (naming the folder): a missing ``comparison.json`` or method folder, folders of another scenario, seed or
method list, a run that appears twice, or runs that do not make up 0 … N − 1.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))   # experiments/: comparison.py
from comparison import output_file  # noqa: E402


def read_set(folder: pathlib.Path) -> dict:
    comp = folder / "comparison.json"
    if not comp.is_file():
        raise SystemExit(f"{folder}: no comparison.json (not a compare_methods.py folder)")
    doc = json.loads(comp.read_text())
    runs = {}
    for m in doc["methods"]:
        metrics = folder / m / "metrics.json"
        if not metrics.is_file():
            raise SystemExit(f"{folder}: no {m}/metrics.json")
        runs[m] = json.loads(metrics.read_text())["runs"]
    return {"scenario": doc["scenario"], "seed": doc["seed"], "methods": list(doc["methods"]), "runs": runs,
            "commit": doc.get("commit"), "command": doc.get("command")}


def combine(folders) -> dict:
    sets = [read_set(pathlib.Path(f)) for f in folders]
    first = sets[0]
    for f, s in zip(folders, sets):
        for key in ("scenario", "seed", "methods"):
            if s[key] != first[key]:
                raise SystemExit(f"{f}: {key} {s[key]!r} differs from {folders[0]}'s {first[key]!r}")
    methods = first["methods"]
    per = {m: {} for m in methods}
    for f, s in zip(folders, sets):
        for m in methods:
            for r in s["runs"][m]:
                if r["run"] in per[m]:
                    raise SystemExit(f"{f}: run {r['run']} of {m} is also in an earlier folder")
                per[m][r["run"]] = r
    ids = sorted(per[methods[0]])
    if ids != list(range(len(ids))) or any(sorted(per[m]) != ids for m in methods):
        raise SystemExit(f"the folders' runs are not 0 … N − 1 for every method: {ids}")
    out = {"scenario": first["scenario"], "seed": first["seed"], "runs": len(ids), "methods": {},
           "sources": [{"folder": str(f), "commit": s["commit"], "command": s["command"]}
                       for f, s in zip(folders, sets)]}
    rates = {}
    for m in methods:
        rs = [per[m][i] for i in ids]
        cr = np.array([r["mean_abs_course_rate_deg_s"] for r in rs], float)
        rates[m] = cr
        names = [t["name"] for t in rs[0]["targets"]]
        out["methods"][m] = {
            "collisions": int(sum(bool(r["collision"]) for r in rs)),
            "groundings": int(sum(bool(r["grounding"]) for r in rs)),
            "min_distance_land_m": min(r["min_distance_land_m"] for r in rs),
            "min_distance_targets_m": {n: min(t["min_distance_m"] for r in rs for t in r["targets"] if t["name"] == n)
                                       for n in names},
            "longest_stop_s": max(r["longest_stop_s"] for r in rs),
            "path_length_m_mean": float(np.mean([r["path_length_m"] for r in rs])),
            "mean_abs_course_rate_deg_s": {"mean": float(cr.mean()), "median": float(np.median(cr)),
                                           "per_run": cr.tolist()},
        }
    base = rates[methods[0]]
    rng = np.random.default_rng(0)
    boot = rng.integers(0, len(ids), (10000, len(ids)))
    for m in methods[1:]:
        change = rates[m] / base - 1.0
        b = rates[m][boot].mean(axis=1) / base[boot].mean(axis=1) - 1.0
        out["methods"][m]["course_rate_change"] = {
            "ratio_of_means": float(rates[m].mean() / base.mean() - 1.0), "per_run": change.tolist(),
            "per_run_median": float(np.median(change)), "runs_at_least_25_percent_below": int(np.sum(change <= -0.25)),
            "bootstrap_95": [float(np.percentile(b, 2.5)), float(np.percentile(b, 97.5))],
            "relative_to": methods[0]}
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("folders", nargs="+", help="compare_methods.py output folders of disjoint runs")
    p.add_argument("--out", required=True, help="the combined JSON (new; an existing file is refused unless --force)")
    p.add_argument("--force", action="store_true")
    args = p.parse_args(argv)
    doc = combine(args.folders)
    from psbmpc_jax.safe_io import atomic_write_text

    path = output_file(args.out, pathlib.Path(args.out), force=args.force)
    atomic_write_text(path, json.dumps(doc, indent=1) + "\n")
    for m, r in doc["methods"].items():
        ch = r.get("course_rate_change")
        print(f"{m}: {doc['runs']} runs, collisions {r['collisions']}, groundings {r['groundings']}, mean |course "
              f"rate| {r['mean_abs_course_rate_deg_s']['mean']:.3f} deg/s"
              + (f", {100 * ch['ratio_of_means']:+.1f} % vs {ch['relative_to']}" if ch else ""))
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
