"""Input-validation helpers shared by several modules (host side, NumPy float64).

Each check returns the validated value (converted) or raises ``ValueError`` naming the input and what is
allowed:

* :func:`finite_array` — a finite float array, optionally of an exact shape or number of dimensions
  (the situation types, the simulator's metrics and tracker);
* :func:`positive` — a finite scalar ``> 0`` (or ``>= 0``);
* :func:`waypoints` — a route ``[n, 2]`` (north, east) without zero-length segments;
* :func:`integer` — an integer (not bool) with a lower bound (scenario files, ``simulate``);
* :func:`multiple_of` — the number of steps a duration holds, which must be a whole multiple of the step.
"""

from __future__ import annotations

import numbers

import numpy as np

#: Tolerance of the "is a multiple of the simulation step" checks (relative to the number of steps).
MULTIPLE_TOL = 1e-9


def finite_array(value, name: str, shape: tuple | None = None, *, ndim: int | None = None) -> np.ndarray:
    """``value`` as a finite float array (a copy), of shape ``shape`` and/or ``ndim`` dimensions if given."""
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be numeric, got {value!r}") from exc
    if shape is not None and arr.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
    if ndim is not None and arr.ndim != ndim:
        raise ValueError(f"{name} must be a {ndim}-d array, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite (no NaN/inf), got {arr.tolist()}")
    return arr


def positive(value, name: str, *, allow_zero: bool = False) -> float:
    """A finite scalar ``> 0`` (``>= 0`` with ``allow_zero``), as float."""
    v = finite_array(value, name, ())
    if v < 0 or (v == 0 and not allow_zero):
        raise ValueError(f"{name} must be {'>= 0' if allow_zero else '> 0'}, got {float(v)}")
    return float(v)


def waypoints(value, name: str, min_points: int) -> np.ndarray:
    """A route ``[n >= min_points, 2]`` (north, east) with no repeated consecutive waypoint."""
    wps = finite_array(value, name)
    if wps.ndim != 2 or wps.shape[1] != 2:
        raise ValueError(f"{name} must have shape [n, 2] (north, east), got {wps.shape}")
    if wps.shape[0] < min_points:
        raise ValueError(f"{name} needs at least {min_points} waypoints, got {wps.shape[0]}")
    if wps.shape[0] >= 2 and np.any(np.linalg.norm(np.diff(wps, axis=0), axis=1) == 0):
        raise ValueError(f"{name} has repeated consecutive waypoints (zero-length segment)")
    return wps


def integer(v, where: str, *, ge: int) -> int:
    """An integer (not bool) ``>= ge``, as int."""
    if isinstance(v, bool) or not isinstance(v, numbers.Integral) or v < ge:
        raise ValueError(f"{where} must be an integer >= {ge}, got {v!r}")
    return int(v)


def multiple_of(value: float, step: float, what: str, step_what: str) -> int:
    """``value / step`` as an int >= 1; ``value`` must be a whole multiple of ``step`` (to :data:`MULTIPLE_TOL`)."""
    n = value / step
    k = round(n)
    if k < 1 or abs(n - k) > MULTIPLE_TOL * max(1.0, abs(n)):
        raise ValueError(f"{what} ({value:g}) must be a multiple of {step_what} ({step:g})")
    return int(k)
