#!/usr/bin/env python3
"""Reproduce the Nidelva refinement study into one new folder: the comparison of PSB-MPC with and without the
refinement (``compare/``), the same without the stop behaviour (``no_stop/``) and the stop analysis with the
solver's default and a 0.05 start margin (``stop_analysis.json``, ``stop_analysis_margin_0.05.json``).

    python experiments/nidelva_refinement/run.py --out /tmp/nidelva_refinement

Each step is the command the README lists for the committed folder of the same name, with ``--out`` inside
this run's folder; ``--runs N`` runs every step with N Monte Carlo runs instead (a quick check, not the
committed results).  ``results/compare_refine_block1/`` comes from an earlier setting of the refinement and is
not re-made here.
"""

from __future__ import annotations

import argparse
import pathlib
import sys

STUDY = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(STUDY.parent))   # experiments/: comparison.py, compare_methods.py
sys.path.insert(0, str(STUDY))          # stop_analysis.py
import compare_methods  # noqa: E402
import stop_analysis  # noqa: E402
from comparison import output_folder, utc_stamp  # noqa: E402


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default=None,
                   help="output folder (default: a new results_<UTC stamp> folder next to this script)")
    p.add_argument("--force", action="store_true", help="write into an --out folder that already holds results")
    p.add_argument("--runs", type=int, default=None,
                   help="Monte Carlo runs of every step (default: the committed results': 20 and 15)")
    args = p.parse_args(argv)
    if args.runs is not None and args.runs < 1:
        p.error(f"--runs must be >= 1, got {args.runs}")
    out = output_folder(args.out, STUDY / f"results_{utc_stamp()}", force=args.force)
    force = ["--force"] if args.force else []
    compare_runs = str(args.runs or 20)
    stop_runs = str(args.runs or 15)
    steps = [
        lambda: compare_methods.main(["nidelva", "--methods", "psbmpc,psbmpc_refine", "--runs", compare_runs,
                                      "--out", str(out / "compare"), "--quiet", *force]),
        lambda: compare_methods.main([str(STUDY / "results" / "no_stop" / "scenario.yaml"), "--methods",
                                      "psbmpc,psbmpc_refine", "--runs", compare_runs, "--out", str(out / "no_stop"),
                                      "--quiet", *force]),
        # last: the stop analysis records the refinement's calls by patching the simulator's solver
        lambda: stop_analysis.main(["--runs", stop_runs, "--out", str(out / "stop_analysis.json"), *force]),
        lambda: stop_analysis.main(["--runs", stop_runs, "--start-margin", "0.05",
                                    "--out", str(out / "stop_analysis_margin_0.05.json"), *force]),
    ]
    for step in steps:
        rc = step()
        if rc:
            return rc
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
