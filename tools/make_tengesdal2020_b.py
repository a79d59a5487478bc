"""Write scenarios/tengesdal2020_b.yaml (the package's built-in scenario folder): the congested-traffic
scenario B of Tengesdal, Brekke & Johansen (2020), 13 targets from :func:`psbmpc_jax.traffic.random_targets` (seed 0, the first seed tried; the paper's
own positions are not published).  ``python tools/make_tengesdal2020_b.py [--check]``; ``--check`` exits 1 if
the committed file differs from what this script writes."""

from __future__ import annotations

import argparse
import pathlib
import sys

from psbmpc_jax.traffic import random_targets

ROOT = pathlib.Path(__file__).resolve().parents[1]
N, SEED = 13, 0

HEADER = """name: tengesdal2020_b
description: "Tengesdal, Brekke & Johansen (2020) scenario B, Fig. 5: congested traffic. The own-ship sails north from the origin at 9 m/s among 13 targets drawn by psbmpc_jax.traffic.random_targets(13, seed={seed}) (positions uniform in north 0..1000 m x east -400..400 m, headings uniform, speeds 2-9 m/s, starts >= 80 m = 2 d_safe apart; the paper's positions are not published). Targets keep course and speed (straight lines; the paper's truth adds CV process noise of at most 0.03 m/s^2, not simulated). Tracking as in scenario A. Run it with mpc.method sbmpc and psbmpc_2020. Regenerate: python tools/make_tengesdal2020_b.py"
simulation:
  dt_s: 0.1                  # the paper's Euler step
  duration_s: 150
monte_carlo:
  runs: 20
  seed: 0
mpc:
  preset: tengesdal2020      # T 200 s, dt 0.5 s, 39 behaviours, straight-line tracks
  update_period_s: 5
  method: psbmpc_2020
  sbmpc:
    preset: tengesdal2020
sensor:
  position_std_m: 5
  period_s: 2.5
  filter_R_scale: 25
  sigma_a_mps2: 0.5
  U_max_mps: 9
collision_distance_m: 30
evaluation:
  preset: default            # open-water ranges (r_col 30 m = the collision distance)
own_ship:
  name: OS
  position_m: [0, 0]
  course_deg: 0
  speed_mps: 9
  waypoints_m: [[0, 0], [3000, 0]]
  length_m: 30
  width_m: 6
targets:
"""


def text() -> str:
    rows = [HEADER.format(seed=SEED)]
    for t in random_targets(N, seed=SEED):
        rows.append(f"  - {{name: {t['name']}, position_m: [{t['position_m'][0]:g}, {t['position_m'][1]:g}], "
                    f"course_deg: {t['course_deg']:g}, speed_mps: {t['speed_mps']:g}, length_m: {t['length_m']:g}, "
                    f"width_m: {t['width_m']:g}, colav: none}}\n")
    return "".join(rows)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--check", action="store_true", help="compare with the committed files instead of writing")
    args = ap.parse_args(argv)
    want = text()
    paths = [ROOT / "scenarios" / "tengesdal2020_b.yaml"]
    if args.check:
        bad = [str(p) for p in paths if not p.exists() or p.read_text() != want]
        if bad:
            print("differs from the generator:", *bad, file=sys.stderr)
            return 1
        return 0
    for p in paths:
        p.write_text(want)
        print("wrote", p)
    return 0


if __name__ == "__main__":
    sys.exit(main())
