"""Stops and arrival of every ship of a run, and their aggregation over runs (NumPy; plain JSON out).

Definitions (the module constants):

* a ship is **stopped** at a sample while its speed over ground is at or below :data:`STOP_SPEED_MPS`;
* a **stop** is a stretch of consecutive stopped samples lasting at least :data:`STOP_MIN_DURATION_S` (from its
  first sample to its last; a stretch still going at the end of the run counts with the time it lasted);
* a ship **arrives** at the first sample within its waypoint acceptance radius ``R_a`` of its last waypoint;
  the arrival time is that sample's time.
"""

from __future__ import annotations

import numpy as np

from ..checks import positive, waypoints

__all__ = ["STOP_SPEED_MPS", "STOP_MIN_DURATION_S", "longest_stop", "stop_intervals", "stop_metrics", "arrival", "ship_metrics",
           "aggregate_ships"]

#: A ship is stopped while its speed over ground is at or below this [m/s] (the EvalTool's ε_U, "not moving").
STOP_SPEED_MPS = 0.2
#: ... and such a stretch is a stop when it lasts at least this long [s].
STOP_MIN_DURATION_S = 5.0


def _check(t, speed) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(t, dtype=float)
    speed = np.asarray(speed, dtype=float)
    if t.ndim != 1 or t.size < 1 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise ValueError("t must be a finite, strictly increasing [K] array with at least one sample")
    if speed.shape != t.shape:
        raise ValueError(f"speed must have the shape of t {t.shape}, got {speed.shape}")
    if not np.all(np.isfinite(speed)):
        raise ValueError("speed must be finite (no NaN/inf)")
    return t, speed


def longest_stop(t, speed, threshold=STOP_SPEED_MPS) -> float:
    """The longest stretch of time [s] during which ``speed`` stays at or below ``threshold``: from the first
    sample of a run of such samples to its last (0 when no sample, or one isolated sample, is that slow).  No
    minimum duration: :func:`psbmpc_jax.sim.stops.stop_metrics` counts the stops of the metrics."""
    return max((b - a for a, b in stop_intervals(t, speed, threshold, 0.0)), default=0.0)


def stop_intervals(t, speed, threshold: float = STOP_SPEED_MPS,
                   min_duration: float = STOP_MIN_DURATION_S) -> list[tuple[float, float]]:
    """``[(t_start, t_end), ...]``: the stretches of samples with ``speed <= threshold`` that last at least
    ``min_duration`` [s] (``t_end - t_start``, first to last sample of the stretch), in time order."""
    t, speed = _check(t, speed)
    threshold = positive(threshold, "threshold", allow_zero=True)
    min_duration = positive(min_duration, "min_duration", allow_zero=True)
    slow = speed <= threshold
    edges = np.diff(np.concatenate([[0], slow.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    return [(float(t[a]), float(t[b])) for a, b in zip(starts, ends) if t[b] - t[a] >= min_duration]


def stop_metrics(t, speed, threshold: float = STOP_SPEED_MPS, min_duration: float = STOP_MIN_DURATION_S) -> dict:
    """``{"stops": n, "longest_stop_s", "longest_stop_start_s", "stopped_time_s"}`` of one ship: the number
    of stops (:func:`stop_intervals`), the longest one and its start time (0.0 and None when there is none;
    the first of equal ones), and the time spent in stops."""
    iv = stop_intervals(t, speed, threshold, min_duration)
    if not iv:
        return {"stops": 0, "longest_stop_s": 0.0, "longest_stop_start_s": None, "stopped_time_s": 0.0}
    dur = [b - a for a, b in iv]
    k = int(np.argmax(dur))
    return {"stops": len(iv), "longest_stop_s": float(dur[k]), "longest_stop_start_s": iv[k][0],
            "stopped_time_s": float(sum(dur))}


def arrival(t, positions, route, radius) -> dict:
    """``{"arrived", "arrival_time_s"}``: whether the ship came within ``radius`` [m] of the last waypoint of
    ``route [m, 2]`` and the time of the first such sample (None if never).  ``positions [K, 2]``
    (north, east); ``radius=None``: no arrival is judged (``arrived`` None)."""
    t = np.asarray(t, dtype=float)
    pos = np.asarray(positions, dtype=float)
    if pos.shape != (t.size, 2):
        raise ValueError(f"positions must have shape [K={t.size}, 2], got {pos.shape}")
    if radius is None:
        return {"arrived": None, "arrival_time_s": None}
    radius = positive(radius, "radius", allow_zero=True)
    route = waypoints(route, "route", 2)
    hit = np.flatnonzero(np.hypot(pos[:, 0] - route[-1, 0], pos[:, 1] - route[-1, 1]) <= radius)
    return {"arrived": bool(hit.size), "arrival_time_s": float(t[hit[0]]) if hit.size else None}


def ship_metrics(t, states, names, routes, radii) -> list[dict]:
    """Per ship of one run: ``{"name"}`` + :func:`stop_metrics` + :func:`arrival`.

    Args:
        t: ``[K]`` sample times [s]; states: ``[n_ships, K, 4]`` rows (north, east, chi, U).
        names: n_ships names; routes: n_ships ``[m, 2]`` routes (None: no arrival judged for that ship);
        radii: n_ships acceptance radii [m] (None: the same).
    """
    states = np.asarray(states, dtype=float)
    n = len(names)
    if states.ndim != 3 or states.shape[0] != n or states.shape[2] != 4:
        raise ValueError(f"states must have shape [n_ships={n}, K, 4], got {states.shape}")
    if len(routes) != n or len(radii) != n:
        raise ValueError(f"routes and radii need one entry per ship ({n}), got {len(routes)} and {len(radii)}")
    out = []
    for i in range(n):
        arr = arrival(t, states[i, :, :2], routes[i], radii[i]) if routes[i] is not None \
            else {"arrived": None, "arrival_time_s": None}
        out.append({"name": str(names[i]), **stop_metrics(t, states[i, :, 3]), **arr})
    return out


def _stats(values) -> dict:
    v = np.asarray([x for x in values if x is not None], dtype=float)
    if v.size == 0:
        return {"min": None, "mean": None, "median": None, "max": None, "n": 0}
    return {"min": float(v.min()), "mean": float(v.mean()), "median": float(np.median(v)),
            "max": float(v.max()), "n": int(v.size)}


def aggregate_ships(per_run: list[list[dict]]) -> list[dict]:
    """Aggregate :func:`ship_metrics` over runs, per ship name (first-seen order): ``runs``, ``stops_total``,
    ``runs_with_stops``, ``longest_stop_s`` (stats over runs: every run counts, 0 for a run without a stop),
    ``longest_stop`` (``{"s", "run", "start_s"}`` of the longest stop of any run; None when no run has one),
    ``arrived_runs`` (None when arrival is not judged for the ship) and ``arrival_time_s`` stats over the runs
    that arrived."""
    groups: dict[str, list[tuple[int, dict]]] = {}
    for r, ships in enumerate(per_run):
        for s in ships:
            groups.setdefault(s["name"], []).append((r, s))
    out = []
    for name, entries in groups.items():
        best = max(entries, key=lambda e: (e[1]["longest_stop_s"], -e[0]))
        judged = [s["arrived"] for _, s in entries if s["arrived"] is not None]
        out.append({
            "name": name, "runs": len(entries),
            "stops_total": int(sum(s["stops"] for _, s in entries)),
            "runs_with_stops": int(sum(1 for _, s in entries if s["stops"])),
            "longest_stop_s": _stats(s["longest_stop_s"] for _, s in entries),
            "longest_stop": (None if best[1]["stops"] == 0 else
                             {"s": best[1]["longest_stop_s"], "run": best[0],
                              "start_s": best[1]["longest_stop_start_s"]}),
            "arrived_runs": int(sum(judged)) if judged else None,
            "arrival_time_s": _stats(s["arrival_time_s"] for _, s in entries),
        })
    return out
