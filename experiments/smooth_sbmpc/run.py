#!/usr/bin/env python3
"""Reproduce the Smooth-SBMPC study into one new folder: Smooth-SBMPC against its initialisation stage
(``reconstruction/``), the same with the two-level MPC as a third method (``three_way/``), the two-level MPC with
the MPC plan as nominal route (``two_level_nominal_plan/``), the DOCP's guidance, terminal LOS against route LOS
(``guidance/``, with tracking noise; ``guidance_true_states/``, the paper's true target states) and the ablation
of the DOCP (``ablation/``); ``--steps`` picks some of them.

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
GUIDANCE = STUDY / "guidance"            # scenario variants: mpc.smooth.chi_d_mode and mpc.smooth.targets
STEPS = ("reconstruction", "three_way", "two_level_nominal_plan", "guidance", "guidance_true_states", "ablation")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default=None,
                   help="output folder (default: a new results_<UTC stamp> folder next to this script)")
    p.add_argument("--force", action="store_true", help="write into an --out folder that already holds results")
    p.add_argument("--runs", type=int, default=None,
                   help="Monte Carlo runs of every step (default: the committed results': 20, the ablation 5; the "
                        "true-state guidance runs are deterministic: 1)")
    p.add_argument("--steps", default=",".join(STEPS),
                   help=f"comma-separated steps to run, in this order: {', '.join(STEPS)} (default: all)")
    args = p.parse_args(argv)
    if args.runs is not None and args.runs < 1:
        p.error(f"--runs must be >= 1, got {args.runs}")
    chosen = [x.strip() for x in args.steps.split(",") if x.strip()]
    bad = [x for x in chosen if x not in STEPS]
    if bad or not chosen:
        p.error(f"--steps must name some of {', '.join(STEPS)}, got {args.steps!r}")
    out = output_folder(args.out, STUDY / f"results_{utc_stamp()}", force=args.force)
    force = ["--force"] if args.force else []
    runs = str(args.runs or 20)
    steps = {
        "reconstruction": lambda: compare_methods.main(["smooth_000_reconstruction", "--methods", "sbmpc_init,smooth_sbmpc",
                                      "--runs", runs, "--out", str(out / "reconstruction"), "--quiet", *force]),
        "three_way": lambda: compare_methods.main(["smooth_000_reconstruction", "--methods",
                                                    "sbmpc_init,two_level,smooth_sbmpc",
                                      "--runs", runs, "--out", str(out / "three_way"), "--quiet", *force]),
        "two_level_nominal_plan": lambda: compare_methods.main([str(NOMINAL_PLAN), "--methods", "two_level",
                                                                 "--runs", runs,
                                      "--out", str(out / "two_level_nominal_plan"), "--quiet", *force]),
        # the DOCP's guidance (mpc.smooth.chi_d_mode): the paper's terminal LOS against the route's LOS, with the
        # tracking noise and with the true target states (deterministic: one run)
        "guidance": lambda: (
            compare_methods.main([str(GUIDANCE / "reconstruction_terminal_los.yaml"), "--methods",
                                  "sbmpc_init,smooth_sbmpc", "--runs", runs, "--out",
                                  str(out / "guidance" / "terminal_los"), "--quiet", *force])
            or compare_methods.main([str(GUIDANCE / "reconstruction_route_los.yaml"), "--methods", "smooth_sbmpc",
                                     "--runs", runs, "--out", str(out / "guidance" / "route_los"), "--quiet",
                                     *force])),
        "guidance_true_states": lambda: (
            compare_methods.main([str(GUIDANCE / "reconstruction_terminal_los_true_targets.yaml"), "--methods",
                                  "sbmpc_init,smooth_sbmpc", "--runs", str(args.runs or 1), "--out",
                                  str(out / "guidance_true_states" / "terminal_los"), "--quiet", *force])
            or compare_methods.main([str(GUIDANCE / "reconstruction_route_los_true_targets.yaml"), "--methods",
                                     "smooth_sbmpc", "--runs", str(args.runs or 1), "--out",
                                     str(out / "guidance_true_states" / "route_los"), "--quiet", *force])),
        # last: the ablation records the DOCP's plans by replacing the simulator's Smooth-SBMPC planner
        "ablation": lambda: ablation.main(["--runs", str(args.runs or 5), "--out", str(out / "ablation"), *force]),
    }
    for name in STEPS:
        if name not in chosen:
            continue
        rc = steps[name]()
        if rc:
            return rc
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
