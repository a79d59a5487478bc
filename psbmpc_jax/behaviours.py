"""Control-behaviour grid (Tengesdal et al. 2022, Sec. II and Table 1; docs/algorithm.md §4).

A behaviour is a sequence of ``n_M`` maneuvers ``(u_M, chi_M)``: a speed factor in [0, 1] and a course
offset [rad].  The set of behaviours is the Cartesian product of per-maneuver speed and course sets,
enumerated with the LAST maneuver's course index varying fastest, then its speed index, then the previous
maneuver's course index, and so on (``itertools.product(u_1, chi_1, u_2, chi_2, ...)`` order).

Axis names: B behaviours, M maneuvers.  The table is ``offsets[B, M, 2]`` with ``[..., 0] = u`` and
``[..., 1] = chi``.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

import numpy as np

#: Paper Table 1 (Nidelva) sets.
PAPER_SPEEDS = ((1.0, 0.5, 0.0), (1.0, 0.5))
PAPER_COURSES_DEG = (-60.0, -45.0, -30.0, -15.0, -10.0, -5.0, 0.0, 5.0, 10.0, 15.0, 30.0, 45.0, 60.0)
#: Paper Table 3 (Sakshaug) course set.
SAKSHAUG_COURSES_DEG = tuple(float(v) for v in range(-90, 91, 15))


def _as_set(values, what: str, m: int) -> np.ndarray:
    try:
        arr = np.asarray(values, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{what} of maneuver {m + 1} must be a sequence of numbers, got {values!r}") from exc
    if arr.size == 0:
        raise ValueError(f"{what} of maneuver {m + 1} is empty; each maneuver needs at least one value")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{what} of maneuver {m + 1} must be finite, got {arr.tolist()}")
    return arr


def enumerate_behaviours(
    speed_sets: Sequence[Sequence[float]],
    course_sets_rad: Sequence[Sequence[float]],
) -> np.ndarray:
    """All control behaviours as an array ``[B, n_M, 2]`` (speed factor, course offset in radians).

    Args:
        speed_sets: one sequence of speed factors in [0, 1] per maneuver.
        course_sets_rad: one sequence of course offsets in radians, each in [-pi, pi], per maneuver.

    Raises:
        ValueError: empty sets, mismatched numbers of maneuvers, non-finite values, speed factors outside
            [0, 1] or course offsets outside [-pi, pi].
    """
    if isinstance(speed_sets, np.ndarray) or isinstance(course_sets_rad, np.ndarray):
        speed_sets, course_sets_rad = list(speed_sets), list(course_sets_rad)
    n_m = len(speed_sets)
    if n_m == 0:
        raise ValueError("speed_sets is empty; n_M (the number of maneuvers) must be >= 1")
    if len(course_sets_rad) != n_m:
        raise ValueError(
            f"speed_sets and course_sets must have one entry per maneuver; got {n_m} speed sets and "
            f"{len(course_sets_rad)} course sets"
        )
    axes = []
    for m in range(n_m):
        u = _as_set(speed_sets[m], "speed factor set", m)
        if np.any((u < 0) | (u > 1)):
            bad = u[(u < 0) | (u > 1)][0]
            raise ValueError(f"speed factor must be in [0, 1], got {bad} in maneuver {m + 1}")
        c = _as_set(course_sets_rad[m], "course offset set", m)
        if np.any(np.abs(c) > math.pi + 1e-12):
            bad = c[np.abs(c) > math.pi + 1e-12][0]
            raise ValueError(f"course offset must be in [-pi, pi] rad, got {bad} in maneuver {m + 1}")
        axes += [u, c]
    grid = np.array(list(itertools.product(*axes)), dtype=float)  # [B, 2 n_M], last axis fastest
    return grid.reshape(grid.shape[0], n_m, 2)


def enumerate_behaviours_deg(speed_sets, course_sets_deg) -> np.ndarray:
    """:func:`enumerate_behaviours` with course offsets given in degrees (converted once, here)."""
    return enumerate_behaviours(speed_sets, [np.deg2rad(np.asarray(c, dtype=float)) for c in course_sets_deg])


def paper_behaviours(n_m: int = 2) -> np.ndarray:
    """The paper's Nidelva sets: 1014 behaviours for ``n_m = 2``; 39 for ``n_m = 1`` (first-maneuver sets)."""
    if n_m not in (1, 2):
        raise ValueError(f"paper_behaviours supports n_m in (1, 2), got {n_m}")
    return enumerate_behaviours_deg(PAPER_SPEEDS[:n_m], [PAPER_COURSES_DEG] * n_m)


def validate_behaviours(offsets) -> np.ndarray:
    """Check a user-supplied behaviour table ``[B, n_M, 2]``; returns it as float64."""
    arr = np.asarray(offsets, dtype=float)
    if arr.ndim != 3 or arr.shape[-1] != 2 or arr.shape[0] < 1 or arr.shape[1] < 1:
        raise ValueError(
            f"behaviours must have shape [B >= 1, n_M >= 1, 2] (speed factor, course offset), got {arr.shape}"
        )
    if not np.all(np.isfinite(arr)):
        raise ValueError("behaviours must be finite")
    u, c = arr[..., 0], arr[..., 1]
    if np.any((u < 0) | (u > 1)):
        raise ValueError(f"behaviour speed factor must be in [0, 1], got {u[(u < 0) | (u > 1)][0]}")
    if np.any(np.abs(c) > math.pi + 1e-12):
        raise ValueError(f"behaviour course offset must be in [-pi, pi] rad, got {c[np.abs(c) > math.pi + 1e-12][0]}")
    return arr
