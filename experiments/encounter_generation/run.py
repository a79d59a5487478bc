#!/usr/bin/env python3
"""Does the encounter generator give what it is asked for?  For each configuration and encounter type: generate
``--n`` encounters (:mod:`psbmpc_jax.scenario_generation`), write them as scenario files, load every file with
the scenario loader (land checks as errors), sail every ship straight at its initial course and speed (no collision
avoidance) and classify each own-ship/target pair with the evaluation tool (:mod:`psbmpc_jax.evaltool`, the
scenario's own evaluation parameters); on a chart, test every start against the full chart's land.

    python experiments/encounter_generation/run.py --n 1000 --out /tmp/encgen

Configurations: ``harbour_open_water`` (the ``harbour`` preset), ``open_sea_open_water`` (``open_sea``),
``harbour_trondheim`` (``harbour`` placed on the built-in Trondheim chart, own-ship starts drawn in the
Trondheimsfjord box north 300..1900 m, east -1500..7000 m, 20 m land margin), ``harbour_five_targets`` (one
target of each type per encounter, ``--n`` encounters) and ``harbour_open_water_margin0`` (the ablation: no sector
margin).  Writes ``encounter_generation.json`` and ``summary.md``.
"""

from __future__ import annotations

import argparse
import collections
import datetime
import json
import pathlib
import platform
import sys
import tempfile
import time

import numpy as np
import shapely
from shapely.geometry import Point

from psbmpc_jax.charts import load_chart
from psbmpc_jax.provenance import commit
from psbmpc_jax.scenario import load_scenario
from psbmpc_jax.scenario_generation import (ENCOUNTER_TYPES, SITUATION_CODES, classify_straight_line,
                                            generate_encounters, get_settings, write_scenarios)

STUDY = pathlib.Path(__file__).resolve().parent
TRONDHEIM = {"builtin": "trondheim", "clip_m": 1000.0}
FJORD_BOX = dict(own_north_m=(300.0, 1900.0), own_east_m=(-1500.0, 7000.0))

#: name -> (settings, chart section, target types per encounter (None: one target of each type in turn))
CONFIGS = {
    "harbour_open_water": ("harbour", None, None),
    "open_sea_open_water": ("open_sea", None, None),
    "harbour_trondheim": (get_settings("harbour", **FJORD_BOX), TRONDHEIM, None),
    "harbour_five_targets": ("harbour", None, list(ENCOUNTER_TYPES)),
    "harbour_open_water_margin0": (get_settings("harbour", sector_margin_deg=0.0), None, None),
}


def _out_folder(out, force: bool) -> pathlib.Path:
    stamp = datetime.datetime.now(datetime.timezone.utc).strftime("%Y%m%dT%H%M%SZ")
    folder = pathlib.Path(out) if out else STUDY / f"results_{stamp}"
    if folder.exists() and any(folder.iterdir()) and not force:
        sys.exit(f"{folder} already holds files; choose a new --out or pass --force")
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def check_batch(types, paths, land) -> dict:
    """Load each file, classify its straight tracks, test the starts against ``land`` (shapely polygons)."""
    want = tuple(SITUATION_CODES[k] for k in types)
    per_type = {k: collections.Counter() for k in dict.fromkeys(types)}
    on_land, clearance, wrong = 0, np.inf, []
    for p in paths:
        sc = load_scenario(p)
        got = classify_straight_line(sc)
        for k, g in zip(types, got):
            per_type[k][g] += 1
        if got != want:
            wrong.append({"file": p.name, "got": list(got)})
        if land is not None:
            for ship in sc.ships:
                pt = Point(ship.position)
                on_land += int(bool(np.any(shapely.covers(land, pt))))
                clearance = min(clearance, float(np.min(shapely.distance(land, pt))))
    out = {}
    for k, c in per_type.items():
        n = sum(c.values())
        out[k] = {"n": n, "classified_as_requested": c[SITUATION_CODES[k]],
                  "fraction": round(c[SITUATION_CODES[k]] / n, 4), "classes": dict(c)}
    return {"types": out, "files_not_as_requested": wrong[:20], "n_files_not_as_requested": len(wrong),
            "ship_starts_on_land": on_land if land is not None else 0,
            "min_start_clearance_to_land_m": None if land is None else round(clearance, 2)}


def run_config(name: str, n: int, seed: int, work: pathlib.Path) -> dict:
    settings, chart, multi = CONFIGS[name]
    land = None
    if chart is not None:
        land = np.array(load_chart(chart["builtin"]).polygons, dtype=object)
        shapely.prepare(land)
    batches = [multi] if multi is not None else [[k] for k in ENCOUNTER_TYPES]
    res = {"settings": settings if isinstance(settings, str) else settings.as_dict(),
           "chart": chart, "n_encounters_per_batch": n, "seed": seed, "batches": {}}
    for types in batches:
        key = "+".join(types)
        t0 = time.perf_counter()
        batch = generate_encounters(types, n, seed=seed, settings=settings, chart=chart, base_dir=work / name / key,
                                    validate=chart is not None)
        t1 = time.perf_counter()
        paths = write_scenarios(batch, work / name / key, validate=chart is None)
        t2 = time.perf_counter()
        checked = check_batch(types, paths, land)
        t3 = time.perf_counter()
        res["batches"][key] = {**checked, "rejections": batch.rejections,
                               "draws_per_encounter": round(1 + sum(batch.rejections.values()) / n, 3),
                               "generate_s": round(t1 - t0, 2), "write_s": round(t2 - t1, 2),
                               "load_and_classify_s": round(t3 - t2, 2)}
        fr = {k: v["fraction"] for k, v in checked["types"].items()}
        print(f"{name} {key}: classified as requested {fr}; starts on land {checked['ship_starts_on_land']}; "
              f"{t1 - t0:.1f} s generate, {t3 - t2:.1f} s load + classify", flush=True)
    return res


def summary(doc: dict) -> str:
    lines = [f"# Encounter generation check ({doc['created_utc']}, commit {doc['commit'][:12]})", "",
             "| configuration | batch | type | n | classified as requested | ship starts on land | draws / encounter |",
             "|---|---|---|---|---|---|---|"]
    for name, res in doc["results"].items():
        for key, b in res["batches"].items():
            for k, t in b["types"].items():
                lines.append(f"| {name} | {key} | {k} | {t['n']} | {t['classified_as_requested']} "
                             f"({100 * t['fraction']:.1f} %) | {b['ship_starts_on_land']} | "
                             f"{b['draws_per_encounter']} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=1000, help="encounters per batch (default 1000)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--configs", nargs="+", choices=tuple(CONFIGS), default=list(CONFIGS))
    ap.add_argument("--out", help="output folder (default experiments/encounter_generation/results_<UTC stamp>)")
    ap.add_argument("--force", action="store_true", help="write into an --out folder that already holds files")
    args = ap.parse_args(argv)
    folder = _out_folder(args.out, args.force)
    doc = {"created_utc": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
           "commit": commit(), "python": platform.python_version(), "machine": platform.machine(),
           "command": "python experiments/encounter_generation/run.py " + " ".join(argv or sys.argv[1:]),
           "results": {}}
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="encgen_") as work:
        for name in args.configs:
            doc["results"][name] = run_config(name, args.n, args.seed, pathlib.Path(work))
    doc["wall_s"] = round(time.perf_counter() - t0, 1)
    (folder / "encounter_generation.json").write_text(json.dumps(doc, indent=1) + "\n")
    (folder / "summary.md").write_text(summary(doc))
    print(summary(doc))
    print("wrote", folder)
    return 0


if __name__ == "__main__":
    sys.exit(main())
