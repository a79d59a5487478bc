"""Scripted trajectories for checks and examples: vessels that follow piecewise-linear course profiles at constant
(or piecewise-linear) speed, integrated exactly enough (trapezoidal rule on a fine grid) for the geometric
numbers of the scripted test cases T1–T7 (``docs/evaltool.md``, "Scripted scenarios") to hold to about 0.01 m."""

from __future__ import annotations

import numpy as np

from .tracks import Tracks

__all__ = ["profile", "scripted_vessel", "scripted_tracks"]


def profile(t, knots, default: float) -> np.ndarray:
    """Piecewise-linear profile through ``knots`` = [(t_s, value), ...] (sorted by time), held constant before
    the first and after the last knot; ``default`` everywhere when there are no knots."""
    t = np.asarray(t, float)
    if not knots:
        return np.full(t.shape, float(default))
    kt, kv = zip(*knots)
    return np.interp(t, np.asarray(kt, float), np.asarray(kv, float))


def scripted_vessel(t, start_ne, course_deg, speed_mps, course_knots=(), speed_knots=()):
    """(north, east, course [rad], speed) ``[n]`` of a vessel starting at ``start_ne`` [m] with course
    ``course_deg`` and speed ``speed_mps``; ``course_knots`` / ``speed_knots`` [(t_s, deg or m/s), ...] script
    changes (a constant-rate turn from 0° at 60 s to 30° at 70 s: ``[(60, 0), (70, 30)]``)."""
    t = np.asarray(t, float)
    chi = np.radians(profile(t, list(course_knots), course_deg))
    u = profile(t, list(speed_knots), speed_mps)
    vn, ve = u * np.cos(chi), u * np.sin(chi)
    dt = np.diff(t)
    north = start_ne[0] + np.concatenate([[0.0], np.cumsum(0.5 * (vn[1:] + vn[:-1]) * dt)])
    east = start_ne[1] + np.concatenate([[0.0], np.cumsum(0.5 * (ve[1:] + ve[:-1]) * dt)])
    return north, east, chi, u


def scripted_tracks(vessels: dict, duration_s: float, step_s: float = 0.05, own=0) -> Tracks:
    """:class:`Tracks` of scripted vessels from t = 0 to ``duration_s`` on a grid of ``step_s``.

    ``vessels`` maps a name to the keyword arguments of :func:`scripted_vessel` (``start_ne``, ``course_deg``,
    ``speed_mps``, optional ``course_knots``, ``speed_knots``)."""
    t = np.arange(0.0, duration_s + 0.5 * step_s, step_s)
    cols = [scripted_vessel(t, **kw) for kw in vessels.values()]
    north, east, course, speed = (np.stack(c) for c in zip(*cols))
    return Tracks.from_arrays(t, north, east, course, speed, names=list(vessels), own=own, source="scripted")
