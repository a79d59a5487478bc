#!/usr/bin/env python3
"""Which of Akdağ, Fossen & Johansen's (2022) four head-on / give-way findings hold, over the COLREGS weight κ,
the way the encounter is classified and the collision weight K_coll: one table per finding.

    python experiments/akdag2022/kappa_table.py --out experiments/akdag2022/results/kappa_table --force

===============================  ======================  =================================================
finding (scenario / variant)     the paper's finding     holds in a run when
===============================  ======================  =================================================
``head_on`` / no route exchange  starboard turn          the first manoeuvre is to starboard
``head_on`` / route exchange     port turn               the first manoeuvre is to port, or there is none
``give_way`` / no route exch.    starboard turn          the first manoeuvre is to starboard
``give_way`` / route exchange    keeps on, regulates     no course offset above 15° and the closest
                                 its distance            approach at least 500 m (d_safe)
===============================  ======================  =================================================

The grid: κ (``mpc.informed.term.kappa``, P_default; the scenarios' targets are power-driven), the
classification (``mpc.informed.classify``: ``velocity`` = the situation found at every predicted time from
the predicted velocities, ``sectors_t0`` = Woerner's sectors once at the start of each update, kept over the
horizon) and K_coll (``mpc.informed.term.K_coll``).  Every other number is the scenario's.  The runs and the
per-run numbers are those of ``run.py`` (:func:`run.records`; the same seeds); the simulator's per-run output
folders are not written (only the table).  It writes ``comparison.json`` (per cell: the aggregate, the runs for
which the finding holds, the per-run records) and ``comparison.md`` (the tables and the cells in which all four
findings hold) into a new folder.  ``comparison.json`` is written (atomically) after every cell with
``"complete": false``; ``--resume`` continues such an interrupted run in its folder, at the same commit.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import pathlib
import sys
import time

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))   # experiments/: comparison.py
from comparison import finish, start, utc_stamp  # noqa: E402

from psbmpc_jax.safe_io import atomic_write_text  # noqa: E402


def _study_runner():
    """This study's ``run.py`` (its records, aggregate and scenario variants), imported by path."""
    spec = importlib.util.spec_from_file_location("akdag2022_run", HERE / "run.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


_run = _study_runner()
_informed, aggregate, records = _run._informed, _run.aggregate, _run.records

#: finding key -> (scenario, route exchange, the paper's finding, the rule that decides a run)
FINDINGS = {
    "head_on_no_re": ("akdag2022_head_on", False, "starboard turn", "first manoeuvre to starboard"),
    "head_on_re": ("akdag2022_head_on", True, "port turn", "first manoeuvre to port, or none"),
    "give_way_no_re": ("akdag2022_crossing_give_way", False, "starboard turn", "first manoeuvre to starboard"),
    "give_way_re": ("akdag2022_crossing_give_way", True, "keeps on, regulates its distance",
                    "no course offset above 15° and closest approach ≥ 500 m"),
}
CLASSIFY = ("velocity", "sectors_t0")
DEFAULT_KAPPA = (0.0, 1.0, 2.0, 3.0)
DEFAULT_K_COLL = (0.25, 0.5, 2.0)
#: the give-way-with-route-exchange rule: largest course offset [deg], closest approach [m]
KEEPS_ON_MAX_OFFSET_DEG = 15.0
KEEPS_ON_MIN_DISTANCE_M = 500.0


def holds(finding: str, rec: dict) -> bool:
    """Whether ``finding`` holds in one run's record (:func:`run.records`)."""
    side = rec["first_manoeuvre_side"]
    if finding in ("head_on_no_re", "give_way_no_re"):
        return side == "starboard"
    if finding == "head_on_re":
        return side in ("port", "none")
    if finding == "give_way_re":
        return (rec["max_abs_course_offset_deg"] <= KEEPS_ON_MAX_OFFSET_DEG
                and rec["min_distance_m"] >= KEEPS_ON_MIN_DISTANCE_M)
    raise ValueError(f"finding must be one of {', '.join(FINDINGS)}, got {finding!r}")


def cell(finding: str, rows: list[dict]) -> dict:
    """One table cell: the runs in which ``finding`` holds, and the aggregate of :func:`run.aggregate`."""
    if not rows:
        raise ValueError(f"{finding}: a cell needs at least one run")
    return {"holds_runs": sum(holds(finding, r) for r in rows), "aggregate": aggregate(rows), "runs": rows}


def _fmt(x: float) -> str:
    return f"{x:g}"


def cell_text(c: dict) -> str:
    """``yes 3/3 · stb · 30° · 611 m``: verdict (all runs / none / some), runs, the first manoeuvre's side (the
    most frequent), the median largest course offset and the median closest approach."""
    a = c["aggregate"]
    n, h = a["runs"], c["holds_runs"]
    verdict = "**yes**" if h == n else "no" if h == 0 else "partly"
    sides = a["first_manoeuvre_side"]
    side = max(sides, key=sides.get)
    short = {"starboard": "stb", "port": "port", "none": "none", "speed only": "speed"}[side]
    return (f"{verdict} {h}/{n} · {short} · {a['max_abs_course_offset_deg']['median']:.0f}° · "
            f"{a['min_distance_m']['median']:.0f} m")


def markdown(doc: dict) -> str:
    """The tables of :func:`main`'s document: one per finding (rows: classification × κ, columns: K_coll), then
    the grid points at which every finding run holds in every run."""
    grid = doc["grid"]
    res = doc["results"]
    lines = ["Cell: whether the finding holds (yes = in every run), runs in which it holds, the first manoeuvre's "
             "side (most frequent), the median largest course offset and the median closest approach.", ""]
    for f in grid["findings"]:
        scenario, re_on, paper, rule = FINDINGS[f]
        lines += [f"### {scenario}, route exchange {'on' if re_on else 'off'}: the paper reports \"{paper}\"",
                  "", f"Holds in a run when: {rule}.", "",
                  "| classification | κ | " + " | ".join(f"K_coll {_fmt(k)}" for k in grid["K_coll"]) + " |",
                  "|---|---|" + "---|" * len(grid["K_coll"])]
        for cl in grid["classify"]:
            for kappa in grid["kappa"]:
                row = [cell_text(res[f][cl][_fmt(kappa)][_fmt(kc)]) for kc in grid["K_coll"]]
                lines.append(f"| {cl} | {_fmt(kappa)} | " + " | ".join(row) + " |")
        lines.append("")
    every = [(cl, k, kc) for cl in grid["classify"] for k in grid["kappa"] for kc in grid["K_coll"]
             if all(res[f][cl][_fmt(k)][_fmt(kc)]["holds_runs"] == res[f][cl][_fmt(k)][_fmt(kc)]["aggregate"]["runs"]
                    for f in grid["findings"])]
    lines.append(f"**Grid points where all {len(grid['findings'])} findings hold in every run:** "
                 + (", ".join(f"{cl}, κ {_fmt(k)}, K_coll {_fmt(kc)}" for cl, k, kc in every) or "none") + ".")
    return "\n".join(lines) + "\n"


def _numbers(text: str, name: str) -> tuple[float, ...]:
    try:
        vals = tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise SystemExit(f"--{name}: comma-separated numbers expected, got {text!r}") from None
    if not vals or any(v < 0 for v in vals):
        raise SystemExit(f"--{name}: at least one number, all >= 0, expected, got {text!r}")
    return vals


def _choices(text: str, allowed, name: str) -> tuple[str, ...]:
    vals = tuple(v.strip() for v in text.split(",") if v.strip())
    bad = [v for v in vals if v not in allowed]
    if bad or not vals:
        raise SystemExit(f"--{name}: comma-separated subset of {', '.join(allowed)} expected, got {text!r}")
    return vals


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--runs", type=int, default=3, help="Monte Carlo runs per cell (default 3)")
    p.add_argument("--kappa", default=",".join(map(_fmt, DEFAULT_KAPPA)))
    p.add_argument("--K-coll", dest="K_coll", default=",".join(map(_fmt, DEFAULT_K_COLL)))
    p.add_argument("--classify", default=",".join(CLASSIFY))
    p.add_argument("--findings", default=",".join(FINDINGS))
    p.add_argument("--out", default=None,
                   help="output folder (default: a new results_kappa_<UTC stamp> folder next to this script)")
    p.add_argument("--force", action="store_true", help="write into an --out folder that already holds results")
    p.add_argument("--resume", action="store_true",
                   help="reuse the cells of an interrupted run in --out (same commit, runs and grid)")
    args = p.parse_args(argv)
    if args.runs < 1:
        p.error(f"--runs >= 1 expected, got {args.runs}")
    kappas, kcolls = _numbers(args.kappa, "kappa"), _numbers(args.K_coll, "K-coll")
    classify = _choices(args.classify, CLASSIFY, "classify")
    findings = _choices(args.findings, tuple(FINDINGS), "findings")

    from psbmpc_jax.scenario import load_scenario
    from psbmpc_jax.sim import simulate

    grid = {"findings": list(findings), "classify": list(classify), "kappa": list(kappas), "K_coll": list(kcolls)}
    done = resumable(args.out, args.runs, grid) if args.resume else {}
    out, doc = start(args.out or HERE / f"results_kappa_{utc_stamp()}", HERE,
                     force=args.force or args.resume, runs=args.runs, grid=grid)
    doc["complete"] = False
    t_all = time.perf_counter()
    for f in findings:
        scenario, re_on, _, _ = FINDINGS[f]
        base = load_scenario(scenario)
        for cl in classify:
            for kappa in kappas:
                for kc in kcolls:
                    c = done.get(f, {}).get(cl, {}).get(_fmt(kappa), {}).get(_fmt(kc))
                    if c is None:
                        sc = _informed(base, route_exchange=re_on, classify=cl,
                                       term={**base.mpc.informed.term, "kappa": kappa, "K_coll": kc})
                        c = cell(f, records(simulate(sc, runs=args.runs)))
                    doc["results"].setdefault(f, {}).setdefault(cl, {}).setdefault(_fmt(kappa), {})[_fmt(kc)] = c
                    print(f"{f} {cl} κ {_fmt(kappa)} K_coll {_fmt(kc)}: {cell_text(c)}", flush=True)
                    atomic_write_text(out / "comparison.json", json.dumps(doc, indent=2) + "\n")   # checkpoint
    doc["complete"] = True
    doc["wall_s"] = round(time.perf_counter() - t_all, 1)
    finish(out, doc, markdown(doc))
    return 0


def resumable(out, runs: int, grid: dict) -> dict:
    """The cells of an interrupted run in ``out`` (its checkpointed ``comparison.json``) to reuse: only when it
    was made at this commit, with these runs and this grid and is marked incomplete; else ``SystemExit`` saying
    why (cells of another commit or grid are never mixed into a table)."""
    from psbmpc_jax.provenance import commit

    if out is None:
        raise SystemExit("--resume needs --out: the folder of the interrupted run")
    path = pathlib.Path(out) / "comparison.json"
    if not path.is_file():
        return {}
    try:
        doc = json.loads(path.read_text())
    except ValueError as exc:
        raise SystemExit(f"--resume: {path} is not JSON ({exc}); give a new --out") from None
    now = commit()
    if doc.get("complete") is not False:
        raise SystemExit(f"--resume: {path} is a finished table, not an interrupted one; give a new --out")
    for key, want in (("commit", now), ("runs", runs), ("grid", grid)):
        if doc.get(key) != want:
            raise SystemExit(f"--resume: {path} has {key} {doc.get(key)!r}, this run {want!r}; cells of another "
                             f"{key} are not mixed in: give a new --out")
    if now == "unknown" or now.endswith("-dirty"):
        raise SystemExit(f"--resume: the checkout is {now!r}; commit first so that the cells' source is known")
    return doc.get("results", {})


if __name__ == "__main__":
    sys.exit(main())
