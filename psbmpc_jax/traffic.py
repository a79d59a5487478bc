"""Seeded random traffic: target ships scattered in a rectangle, for congested-traffic scenarios (Tengesdal, Brekke &
Johansen 2020, Sec. 7, scenario B: 13 obstacles "randomly initialised inside a 1000 m × 800 m grid", speeds 2-9 m/s).

:func:`random_targets` returns target entries in the scenario-file format (``targets:`` of a YAML scenario,
:mod:`psbmpc_jax.scenario`), so a generated traffic picture can be written once, committed and read back like
any other scenario; ``scenarios/tengesdal2020_b.yaml`` was made by :func:`random_targets` with the arguments
its description names (a test regenerates it).

Rules (our proposal, where the paper gives none): positions uniform in the rectangle, headings uniform in
[0°, 360°), speeds uniform in the range; a start closer than ``min_separation`` to a point of ``keep_clear``
(the own-ship's start) or to an earlier target is redrawn.  Targets follow straight routes (no ``waypoints_m``:
the loader's default straight route along the initial course).
"""

from __future__ import annotations

import math

import numpy as np

#: Most draws of one target before :func:`random_targets` gives up.
MAX_TRIES = 10_000


def _range(v, name: str, *, lo: float = -math.inf) -> tuple[float, float]:
    try:
        a, b = (float(x) for x in v)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be two numbers (low, high), got {v!r}") from None
    if not (math.isfinite(a) and math.isfinite(b)) or not lo <= a <= b:
        raise ValueError(f"{name} must be finite with {lo:g} <= low <= high, got {v!r}")
    return a, b


def random_targets(n: int, *, seed: int, north_range_m=(0.0, 1000.0), east_range_m=(-400.0, 400.0),
                   speed_range_mps=(2.0, 9.0), min_separation_m: float = 80.0, keep_clear=((0.0, 0.0),),
                   length_m: float = 30.0, width_m: float = 6.0, name_prefix: str = "TS",
                   decimals: int = 1) -> list[dict]:
    """``n`` targets as scenario-file entries (``name``, ``position_m``, ``course_deg``, ``speed_mps``,
    ``length_m``, ``width_m``, ``colav: none``), drawn from ``numpy.random.default_rng(seed)``; values rounded
    to ``decimals`` (the separation rule holds for the rounded values).  Raises ValueError naming the argument
    for bad input, or when ``MAX_TRIES`` draws cannot place a target."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 0 <= n <= 1000:
        raise ValueError(f"n must be an integer in [0, 1000], got {n!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    north, east = _range(north_range_m, "north_range_m"), _range(east_range_m, "east_range_m")
    speeds = _range(speed_range_mps, "speed_range_mps", lo=0.0)
    for name, v in (("min_separation_m", min_separation_m), ("length_m", length_m), ("width_m", width_m)):
        if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not (
                math.isfinite(v) and v >= 0):
            raise ValueError(f"{name} must be a finite number >= 0, got {v!r}")
    clear = np.asarray(keep_clear, float).reshape(-1, 2) if len(keep_clear) else np.zeros((0, 2))
    rng = np.random.default_rng(int(seed))
    placed: list[np.ndarray] = []
    out = []
    for i in range(int(n)):
        for _ in range(MAX_TRIES):
            pos = np.round([rng.uniform(*north), rng.uniform(*east)], decimals)
            course = round(float(rng.uniform(0.0, 360.0)), decimals) % 360.0
            speed = round(float(rng.uniform(*speeds)), decimals)
            others = np.concatenate([clear, np.asarray(placed, float).reshape(-1, 2)])
            if not len(others) or np.min(np.hypot(*(others - pos).T)) >= min_separation_m:
                break
        else:
            raise ValueError(f"cannot place target {i + 1} of {n} at least {min_separation_m:g} m from the others in "
                             f"{MAX_TRIES} draws; use a larger area, fewer targets or a smaller min_separation_m")
        placed.append(pos)
        out.append({"name": f"{name_prefix}{i + 1}", "position_m": [float(pos[0]), float(pos[1])],
                    "course_deg": float(course), "speed_mps": float(speed), "length_m": float(length_m),
                    "width_m": float(width_m), "colav": "none"})
    return out


__all__ = ["MAX_TRIES", "random_targets"]
