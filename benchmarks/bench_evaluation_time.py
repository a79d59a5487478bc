"""The time of scoring tracks (``evaluate_tracks``) by samples, vessels and scored pairs (docs/limits.md, "Time
of an evaluation"; the coefficients of ``psbmpc_jax.limits.EVAL_TIME_S``).

Each case builds synthetic tracks of ``vessels`` vessels x ``samples`` samples 1 s apart (the own-ship heading
north at 0.5 m/s; the k-th other vessel head-on at 0.5 m/s, 100·k km ahead and 30·k m to the side, so only
the nearest ones meet it within the tracks: 1 to 4 encounters), or
``circling``: one vessel circling the own-ship at 10 m/s on a 3 km circle whose centre is 2.9 km away, so it
enters and leaves the 2.5 km stage-2 range about once every 31 min: an encounter-rich track), then times
``evaluate_tracks(tracks, pairs=...)`` alone (the tracks' construction and validation are not timed): the median
of ``--repeats`` calls, round-robin over the cases.  Only NumPy: no JAX work is timed.

Usage: python benchmarks/bench_evaluation_time.py [--repeats 3] [--large]
    --large adds 2 vessels x 2 000 000 and 10 000 000 samples (as the tested-limits cases ``track`` and
    ``track_1e7``, one call each).
Writes benchmarks/results/evaluation_time_<platform>_<UTC stamp>.json.
"""

from __future__ import annotations

import os
import statistics
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path[:0] = [os.path.dirname(os.path.abspath(__file__)), ROOT]    # this checkout's psbmpc_jax: its commit is recorded
from _common import environment_meta, interleaved_parser, write_results  # noqa: E402

from psbmpc_jax.evaltool import evaluate_tracks  # noqa: E402
from psbmpc_jax.evaltool.tracks import Tracks  # noqa: E402

#: (samples, vessels, pairs mode, layout)
CASES = [(200_000, 2, "own", "head_on"), (200_000, 3, "own", "head_on"), (200_000, 5, "own", "head_on"),
         (200_000, 8, "own", "head_on"), (200_000, 3, "all", "head_on"), (200_000, 5, "all", "head_on"),
         (200_000, 2, "own", "circling"), (1_000_000, 2, "own", "head_on")]
LARGE = [(2_000_000, 2, "own", "head_on"), (10_000_000, 2, "own", "head_on")]


def make_tracks(n: int, vessels: int, layout: str) -> Tracks:
    t = np.arange(n, dtype=float)
    north, east, course, speed = [t * 0.5], [np.zeros(n)], [np.zeros(n)], [np.full(n, 0.5)]
    if layout == "circling":
        w = 10.0 / 3000.0                         # 10 m/s on a 3 km circle
        north.append(t * 0.5 + 2900.0 + 3000.0 * np.cos(w * t))
        east.append(3000.0 * np.sin(w * t))
        vn, ve = 0.5 - 10.0 * np.sin(w * t), 10.0 * np.cos(w * t)
        course.append(np.arctan2(ve, vn))
        speed.append(np.hypot(vn, ve))
    else:
        for k in range(1, vessels):
            north.append(1.0e5 * k - t * 0.5)
            east.append(np.full(n, 30.0 * k))
            course.append(np.full(n, np.pi))
            speed.append(np.full(n, 0.5))
    return Tracks(t=t, north=np.stack(north), east=np.stack(east), course=np.stack(course), speed=np.stack(speed),
                  names=tuple(f"v{k}" for k in range(len(north))))


def main(argv=None) -> int:
    ap = interleaved_parser(__doc__, repeats=3)
    ap.add_argument("--large", action="store_true")
    args = ap.parse_args(argv)
    tracks = [make_tracks(n, v, lay) for n, v, _, lay in CASES]
    times: list[list[float]] = [[] for _ in CASES]
    enc = [0] * len(CASES)
    for _ in range(args.repeats):
        for i, ((n, v, pairs, lay), tr) in enumerate(zip(CASES, tracks)):
            t0 = time.perf_counter()
            ev = evaluate_tracks(tr, pairs=pairs)
            times[i].append(time.perf_counter() - t0)
            enc[i] = len(ev.encounters)
    points = []
    for (n, v, pairs, lay), ts, e in zip(CASES, times, enc):
        points.append(dict(samples=n, vessels=v, pairs=pairs, layout=lay, encounters=e, repeats=len(ts),
                           median_s=round(statistics.median(ts), 4), min_s=round(min(ts), 4)))
        print(points[-1], flush=True)
    del tracks
    for n, v, pairs, lay in (LARGE if args.large else []):
        tr = make_tracks(n, v, lay)
        t0 = time.perf_counter()
        ev = evaluate_tracks(tr, pairs=pairs)
        w = time.perf_counter() - t0
        points.append(dict(samples=n, vessels=v, pairs=pairs, layout=lay, encounters=len(ev.encounters), repeats=1,
                           median_s=round(w, 4), min_s=round(w, 4)))
        print(points[-1], flush=True)
        del tr, ev
    meta = environment_meta("evaluate_tracks wall time by samples, vessels and pairs (median of repeats, "
                            "round-robin)", repeats=args.repeats, load_avg=os.getloadavg())
    write_results(args.out, "evaluation_time", meta, points)
    return 0


if __name__ == "__main__":
    sys.exit(main())
