"""Make ``crossing_trondheimsfjord.csv``: a simulated crossing encounter written as AIS-style reports.

The own-ship (MMSI 257000001) gives way to a target crossing from starboard (MMSI 257000002): run 0 of the
built-in ``crossing_give_way`` scenario (5 m vessels at 2 m/s, PSB-MPC), placed in the Trondheimsfjord north of
Munkholmen (63.47 N, 10.38 E), reporting like AIS transponders do: each vessel at its own irregular times (3 to
12 s apart), with about one report in ten lost and a 40 s hole in the target's track; positions rounded to 1e-6
deg, SOG to 0.1 kn and COG to 0.1 deg.

    psbmpc-jax run crossing_give_way --runs 1 --save-trajectories --no-figures --out /tmp/ais_src
    python examples/ais/make_crossing_csv.py /tmp/ais_src/crossing_give_way/trajectories.npz \\
        examples/ais/crossing_trondheimsfjord.csv
"""

import pathlib
import sys

import numpy as np

from psbmpc_jax.evaltool.ais import ais_frame
from psbmpc_jax.evaltool.tracks import tracks_from_simulation
from psbmpc_jax.safe_io import atomic_write_text
from psbmpc_jax.sim.output import load_trajectories

ORIGIN = (63.47, 10.38)                 # Trondheimsfjord, north of Munkholmen
MMSI = {"OS": "257000001", "TS1": "257000002"}


def report_times(t_end: float, rng: np.random.Generator, hole=None) -> np.ndarray:
    t = np.cumsum(rng.uniform(3.0, 12.0, int(t_end / 3) + 2)) - rng.uniform(0.0, 3.0)
    t = t[(t >= 0) & (t <= t_end)]
    t = t[rng.random(t.size) > 0.1]                     # lost reports
    if hole is not None:
        t = t[(t < hole[0]) | (t > hole[1])]
    return t


def main(src: str, out: str) -> None:
    tracks = tracks_from_simulation(load_trajectories(src))[0]
    rng = np.random.default_rng(2024)
    times = {"OS": report_times(tracks.t[-1], rng), "TS1": report_times(tracks.t[-1], rng, hole=(200.0, 240.0))}
    df = ais_frame(tracks, *ORIGIN, start="2024-05-02T10:00:00Z", report_times=times, mmsi=MMSI)
    atomic_write_text(pathlib.Path(out), df.to_csv(index=False))
    print(f"wrote {out}: {len(df)} reports of {df['MMSI'].nunique()} vessels")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: python examples/ais/make_crossing_csv.py TRAJECTORIES.npz OUT.csv")
    main(sys.argv[1], sys.argv[2])
