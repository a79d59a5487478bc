#!/usr/bin/env python3
"""Reproduce the Smooth-SBMPC study into one new folder: Smooth-SBMPC against its initialisation stage
(``reconstruction/``), the same with the two-level MPC as a third method (``three_way/``), the two-level MPC with
the MPC plan as nominal route (``two_level_nominal_plan/``) and the ablation of the DOCP (``ablation/``).

    python experiments/smooth_sbmpc/run.py --out /tmp/smooth_sbmpc

Each step is the command the README lists for the committed folder of the same name, with ``--out`` inside
this run's folder; ``--runs N`` runs every step with N Monte Carlo runs instead (a quick check, not the
committed results).
"""

from __future__ import annotations

import argparse
import pathlib
import sys

STUDY = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(STUDY.parent))   # experiments/: comparison.py, compare_methods.py
sys.path.insert(0, str(STUDY))          # ablation.py
import ablation  # noqa: E402
import compare_methods  # noqa: E402
from comparison import output_folder, utc_stamp  # noqa: E402

NOMINAL_PLAN = STUDY / "results" / "two_level_nominal_plan" / "smooth_000_reconstruction_nominal_plan.yaml"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default=None,
                   help="output folder (default: a new results_<UTC stamp> folder next to this script)")
    p.add_argument("--force", action="store_true", help="write into an --out folder that already holds results")
    p.add_argument("--runs", type=int, default=None,
                   help="Monte Carlo runs of every step (default: the committed results': 20, the ablation 5)")
    args = p.parse_args(argv)
    if args.runs is not None and args.runs < 1:
        p.error(f"--runs must be >= 1, got {args.runs}")
    out = output_folder(args.out, STUDY / f"results_{utc_stamp()}", force=args.force)
    force = ["--force"] if args.force else []
    runs = str(args.runs or 20)
    steps = [
        lambda: compare_methods.main(["smooth_000_reconstruction", "--methods", "sbmpc_init,smooth_sbmpc",
                                      "--runs", runs, "--out", str(out / "reconstruction"), "--quiet", *force]),
        lambda: compare_methods.main(["smooth_000_reconstruction", "--methods", "sbmpc_init,two_level,smooth_sbmpc",
                                      "--runs", runs, "--out", str(out / "three_way"), "--quiet", *force]),
        lambda: compare_methods.main([str(NOMINAL_PLAN), "--methods", "two_level", "--runs", runs,
                                      "--out", str(out / "two_level_nominal_plan"), "--quiet", *force]),
        # last: the ablation records the DOCP's plans by replacing the simulator's Smooth-SBMPC planner
        lambda: ablation.main(["--runs", str(args.runs or 5), "--out", str(out / "ablation"), *force]),
    ]
    for step in steps:
        rc = step()
        if rc:
            return rc
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
