"""Paper-faithful vs COLREGS option on a few shipped scenarios: runs ``psbmpc-jax run`` on each scenario and on
its option copy (:mod:`make_variants`), then collects S_sit, S_safety, situations, collisions and groundings
from the two ``metrics.json`` into one JSON with the exact commands.

    PYTHONPATH=. python experiments/colregs_option/measure.py OUT SCENARIO... [--runs 3] [--timeout 600]
        [--set key=value ...] [--no-paper]

OUT must not exist yet (nothing is overwritten); OUT/measurement.md (the table) and OUT/measurement.json are
written last, atomically.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import shlex
import subprocess
import sys
import time

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(ROOT))

from psbmpc_jax.safe_io import atomic_write_text  # noqa: E402

KEYS = ("S_sit", "S_safety", "P_delay", "P_na_delta", "P_2", "P_3", "P_pt", "P_nsb", "P_sts")


def summary(folder: pathlib.Path) -> dict:
    m = json.loads((folder / "metrics.json").read_text())
    agg = m["colregs_evaluation"]["aggregate"]
    s = m["summary"]
    return {"runs": s["runs"], "collisions": s["collisions"], "groundings": s["groundings"],
            "min_distance_m": s["min_distance_m"]["min"], "situations": agg["situations"],
            "statuses": agg["statuses"],
            "scores": {k: agg["scores"][k] for k in KEYS if k in agg["scores"]}}


def _score(r: dict, key: str) -> str:
    v = r.get("scores", {}).get(key)
    return "—" if not v or v.get("n", 0) == 0 else f"{v['mean']:.2f} ({v['min']:.2f})"


def table(doc: dict) -> str:
    """The measurement as a Markdown table (S_sit and S_safety: mean (min) over the scored encounters)."""
    labels = [k for k in ("paper", "option") if any(k in r for r in doc["results"])]
    head = ["scenario"] + [f"{k} {c}" for k in labels for c in ("S_sit", "S_safety", "coll./gr.", "min dist. [m]",
                                                               "situations")]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in doc["results"]:
        cells = [r["scenario"]]
        for k in labels:
            x = r.get(k, {})
            if "error" in x or not x:
                cells += ["error"] * 5
                continue
            sit = ", ".join(f"{a} {b}" for a, b in x["situations"].items())
            cells += [_score(x, "S_sit"), _score(x, "S_safety"), f"{x['collisions']}/{x['groundings']}",
                      f"{x['min_distance_m']:.1f}", sit]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def run(cmd: list, timeout: float) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, cwd=ROOT, check=False, timeout=timeout)
    return time.perf_counter() - t0


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("scenarios", nargs="+")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--timeout", type=float, default=600.0)
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--no-paper", action="store_true",
                    help="run the option copies only (term-by-term and sensitivity runs; the paper-faithful "
                         "numbers are those of a full measurement)")
    a = ap.parse_args(argv)
    out = pathlib.Path(a.out)
    if out.exists():
        raise SystemExit(f"{out} exists; give a new folder (nothing is overwritten)")
    variants = out / "scenarios"
    sets = [x for kv in a.set for x in ("--set", kv)]
    make = [sys.executable, str(HERE / "make_variants.py"), str(variants), *a.scenarios, *sets]
    subprocess.run(make, cwd=ROOT, check=True, env={**os.environ, "PYTHONPATH": str(ROOT)})
    cli = [sys.executable, "-m", "psbmpc_jax.apps.cli", "run", "--runs", str(a.runs), "--no-figures", "--quiet"]
    rows, commands = [], [" ".join(shlex.quote(c) for c in make)]
    for name in a.scenarios:
        row = {"scenario": name}
        pairs = (("paper", name), ("option", str(variants / f"{name}_colregs.yaml")))
        for label, target in pairs[1:] if a.no_paper else pairs:
            cmd = cli + [target, "--out", str(out / label)]
            commands.append(" ".join(shlex.quote(c) for c in cmd))
            wall = run(cmd, a.timeout)
            folder = out / label / (name if label == "paper" else f"{name}_colregs")
            row[label] = summary(folder) if (folder / "metrics.json").is_file() else {"error": "no metrics.json"}
            row[label]["wall_s"] = round(wall, 1)
        rows.append(row)
        print(name, {k: row[k].get("scores", {}).get("S_sit") for k in ("paper", "option") if k in row}, flush=True)
    doc = {"what": "paper-faithful PSB-MPC vs the COLREGS option (mpc.colregs_option), docs/colregs_option.md",
           "runs_each": a.runs, "option_overrides": a.set, "commands": commands, "results": rows}
    atomic_write_text(out / "measurement.md", table(doc))
    atomic_write_text(out / "measurement.json", json.dumps(doc, indent=1) + "\n")
    print(out / "measurement.json")


if __name__ == "__main__":
    main()
