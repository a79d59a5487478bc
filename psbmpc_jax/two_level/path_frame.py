"""Path frames {P_j} of the upper level of the two-level MPC (Mahipala & Johansen 2023, eqs. 3-4;
``docs/two_level_geometry.md``).

Frame: NED (x north, y east) [m].  The route is ``waypoints [n >= 2, 2]``; leg j runs WP_j -> WP_{j+1}
(j = 0 .. n-2) with course ψ_j = α_j = atan2(Δy, Δx) (from north, clockwise) and length l_j.  The path frame
P_j has its origin at WP_j, x_p along the leg and y_p to starboard:

    [x_pj; y_pj] = R(ψ_j) ([x; y] − WP_j),   R(ψ) = [[cos ψ, sin ψ], [−sin ψ, cos ψ]]        (3)

so x_p is the along-track distance from WP_j and y_p the cross-track error, **positive to starboard** (for
a north-bound leg y_p = east offset).  The y_p axis is n̂ = (−sin ψ, cos ψ), the starboard normal that the
corridor code (:mod:`psbmpc_jax.smooth.corridor`) uses.  Switching to P_{j+1} (eq. 4):

    [x_p(j+1); y_p(j+1)] = R(ψ_{j+1} − ψ_j) [x_pj − l_j; y_pj]                               (4)

which equals transforming the NED point again with (3) for leg j+1.

Leg switching (:func:`active_leg`): from the current leg j, advance to j+1 while x_pj >= l_j (past the end
of the leg) or ||p − WP_{j+1}|| <= R_a (inside the radius of acceptance), never beyond the last leg n−2.
The test repeats, so one call may skip several short legs.

Host-facing functions validate their inputs (``ValueError`` naming the field); the transforms are written
in ``jax.numpy`` and are traceable and differentiable (w.r.t. the points and the waypoints) with a fixed or a
traced leg index; value checks are skipped for traced inputs (shapes are still checked).  cos ψ, sin ψ are
taken from the unit leg vector (no trigonometric round trip).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

#: A leg no longer than this [m] is rejected as zero-length.
MIN_LEG_LENGTH = 1e-9


class PathLegs(NamedTuple):
    """Per-leg data of a route (NumPy float64 from :func:`path_legs`; a pytree, so it can be passed into a
    jitted function and indexed with a traced leg index).

    Attributes:
        start: WP_j ``[L, 2]`` (north, east) [m], L = n − 1 legs.
        tangent: (cos ψ_j, sin ψ_j) ``[L, 2]``.
        psi: ψ_j = atan2(Δy, Δx) ``[L]`` [rad] in (−π, π].
        length: l_j ``[L]`` [m].
    """

    start: jax.Array
    tangent: jax.Array
    psi: jax.Array
    length: jax.Array


# ------------------------------------------------------------------------------------------ validation
def _is_traced(x) -> bool:
    return isinstance(x, jax.core.Tracer)


def check_waypoints(waypoints, name: str = "waypoints"):
    """Check a route ``[n >= 2, 2]`` (north, east): finite, no leg of length <= :data:`MIN_LEG_LENGTH`.
    Traced values are checked by shape only.  Returns the waypoints (float64 NumPy when concrete)."""
    shape = np.shape(waypoints)
    if len(shape) != 2 or shape[1] != 2 or shape[0] < 2:
        raise ValueError(f"{name} must have shape [n >= 2, 2] (north, east), got {shape}")
    if _is_traced(waypoints):
        return waypoints
    try:
        w = np.asarray(waypoints, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an array of numbers [n >= 2, 2] (north, east)") from None
    if not np.all(np.isfinite(w)):
        bad = int(np.argwhere(~np.all(np.isfinite(w), axis=1))[0, 0])
        raise ValueError(f"{name} must be finite, got {w[bad].tolist()} at row {bad}")
    length = np.linalg.norm(np.diff(w, axis=0), axis=1)
    short = np.flatnonzero(length <= MIN_LEG_LENGTH)
    if short.size:
        k = int(short[0])
        raise ValueError(f"{name}: leg {k} (waypoint {k} -> {k + 1}) has zero length ({length[k]:g} m); "
                         f"remove the repeated waypoint")
    return w


def check_leg_index(j, n_waypoints: int, name: str = "j", *, last: int | None = None):
    """Check a leg index: an integer in [0, last] (default last = n − 2); a traced integer passes unchecked.
    Returns ``j`` (a Python int when concrete)."""
    last = n_waypoints - 2 if last is None else last
    if _is_traced(j):
        if np.ndim(j) != 0 or not jnp.issubdtype(j.dtype, jnp.integer):
            raise ValueError(f"{name} must be a scalar integer leg index, got {j.dtype} of shape {np.shape(j)}")
        return j
    if isinstance(j, (bool, np.bool_)) or np.ndim(j) != 0 or not np.issubdtype(np.asarray(j).dtype, np.integer):
        raise ValueError(f"{name} must be an integer leg index, got {j!r}")
    j = int(j)
    if not 0 <= j <= last:
        raise ValueError(f"{name} = {j} is out of range: the route has legs 0..{n_waypoints - 2}"
                         + (f" and leg {j} needs a next leg (j <= {last})" if last != n_waypoints - 2 else ""))
    return j


def _check_points(points, name: str):
    shape = np.shape(points)
    if len(shape) < 1 or shape[-1] != 2:
        raise ValueError(f"{name} must have shape [..., 2], got {shape}")
    if not _is_traced(points):
        try:
            a = np.asarray(points, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"{name} must be an array of numbers [..., 2]") from None
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{name} must be finite")
    return points


def _check_scalar(value, name: str):
    if np.ndim(value) != 0:
        raise ValueError(f"{name} must be a scalar [m], got shape {np.shape(value)}")
    if _is_traced(value):
        return value
    if isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be a number [m], got {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number [m], got {value!r}") from None
    if not math.isfinite(v) or v < 0:
        raise ValueError(f"{name} must be a finite number >= 0 [m], got {value!r}")
    return v


def _float_array(x):
    a = jnp.asarray(x)
    return a if jnp.issubdtype(a.dtype, jnp.floating) else a.astype(jnp.result_type(float))


# ------------------------------------------------------------------------------------------ legs
def leg_angles(waypoints):
    """ψ_j = α_j = atan2(Δy_j, Δx_j) of every leg, ``[n − 1]`` [rad] in (−π, π]: NumPy float64 for concrete
    waypoints (validated), a JAX array for traced ones."""
    w = check_waypoints(waypoints)
    if _is_traced(w):
        d = w[1:] - w[:-1]
        return jnp.arctan2(d[:, 1], d[:, 0])
    d = np.diff(w, axis=0)
    return np.arctan2(d[:, 1], d[:, 0])


def path_legs(waypoints) -> PathLegs:
    """:class:`PathLegs` of a route (validated; NumPy float64)."""
    w = check_waypoints(waypoints)
    if _is_traced(w):
        raise ValueError("waypoints: path_legs needs concrete waypoints (host data); inside jit index the "
                         "waypoints directly or pass a PathLegs built outside")
    d = np.diff(w, axis=0)
    length = np.linalg.norm(d, axis=1)
    return PathLegs(w[:-1].copy(), d / length[:, None], np.arctan2(d[:, 1], d[:, 0]), length)


def _leg(waypoints, j):
    """(WP_j, t̂_j, l_j) with a static or traced j (jax.numpy)."""
    w = _float_array(waypoints)
    a = lax.dynamic_index_in_dim(w, j, axis=0, keepdims=False)
    b = lax.dynamic_index_in_dim(w, j + 1, axis=0, keepdims=False)
    d = b - a
    length = jnp.sqrt(jnp.sum(d * d))
    return a, d / length, length


def _rotate(c, s, x, y):
    """R(ψ) [x; y] with c = cos ψ, s = sin ψ."""
    return c * x + s * y, -s * x + c * y


def to_path_frame(points, waypoints, j):
    """Eq. (3): NED ``points [..., 2]`` -> (x_p, y_p) ``[..., 2]`` in the frame of leg ``j`` (x_p along the
    leg from WP_j, y_p cross-track, positive to starboard).  jax.numpy, traceable and differentiable; ``j`` a
    Python int or a traced integer scalar."""
    _check_points(points, "points")
    check_waypoints(waypoints)
    j = check_leg_index(j, np.shape(waypoints)[0])
    a, t, _ = _leg(waypoints, j)
    p = _float_array(points)
    xp, yp = _rotate(t[0], t[1], p[..., 0] - a[0], p[..., 1] - a[1])
    return jnp.stack([xp, yp], axis=-1)


def from_path_frame(points_p, waypoints, j):
    """Inverse of :func:`to_path_frame`: (x_p, y_p) ``[..., 2]`` in the frame of leg ``j`` -> NED
    ``[..., 2]`` (WP_j + R(ψ_j)ᵀ [x_p; y_p]).  jax.numpy, traceable and differentiable."""
    _check_points(points_p, "points_p")
    check_waypoints(waypoints)
    j = check_leg_index(j, np.shape(waypoints)[0])
    a, t, _ = _leg(waypoints, j)
    q = _float_array(points_p)
    x, y = _rotate(t[0], -t[1], q[..., 0], q[..., 1])
    return jnp.stack([x + a[0], y + a[1]], axis=-1)


def _check_leg_data(start, psi) -> None:
    if np.shape(start) != (2,) or np.ndim(psi) != 0:
        raise ValueError(f"start must have shape [2] and psi be a scalar, got {np.shape(start)} and "
                         f"{np.shape(psi)}")


def to_leg_frame(points, start, psi):
    """Eq. (3) from leg data: NED ``points [..., 2]`` -> (x_p, y_p) ``[..., 2]`` = R(ψ)(p − start), for a leg
    given by its start ``[2]`` and course ``psi`` (e.g. ``PathLegs`` rows or a ``LegCorridor``, possibly
    traced).  jax.numpy, no value checks (for use inside ``jit``)."""
    _check_points(points, "points")
    _check_leg_data(start, psi)
    p = _float_array(points)
    a = jnp.asarray(start, p.dtype)
    ang = jnp.asarray(psi, p.dtype)
    xp, yp = _rotate(jnp.cos(ang), jnp.sin(ang), p[..., 0] - a[0], p[..., 1] - a[1])
    return jnp.stack([xp, yp], axis=-1)


def from_leg_frame(points_p, start, psi):
    """Inverse of :func:`to_leg_frame`: start + R(ψ)ᵀ [x_p; y_p]."""
    _check_points(points_p, "points_p")
    _check_leg_data(start, psi)
    q = _float_array(points_p)
    a = jnp.asarray(start, q.dtype)
    ang = jnp.asarray(psi, q.dtype)
    x, y = _rotate(jnp.cos(ang), -jnp.sin(ang), q[..., 0], q[..., 1])
    return jnp.stack([x + a[0], y + a[1]], axis=-1)


def switch_frame(xp, yp, waypoints, j):
    """Eq. (4): coordinates ``(xp, yp)`` (any matching shapes) in the frame of leg ``j`` -> the same point in
    the frame of leg ``j + 1``: R(ψ_{j+1} − ψ_j) [xp − l_j; yp].  Returns ``(xp_next, yp_next)``.  Needs a
    next leg (j <= n − 3).  jax.numpy, traceable and differentiable."""
    check_waypoints(waypoints)
    n = np.shape(waypoints)[0]
    if n < 3:
        raise ValueError(f"waypoints: switch_frame needs a next leg, but the route has {n} waypoints (one leg)")
    j = check_leg_index(j, n, last=n - 3)
    for v, name in ((xp, "xp"), (yp, "yp")):
        if not _is_traced(v) and not np.all(np.isfinite(np.asarray(v, dtype=float))):
            raise ValueError(f"{name} must be finite")
    _, t0, l0 = _leg(waypoints, j)
    _, t1, _ = _leg(waypoints, j + 1)
    c = t0[0] * t1[0] + t0[1] * t1[1]                 # cos(ψ_{j+1} − ψ_j)
    s = t0[0] * t1[1] - t0[1] * t1[0]                 # sin(ψ_{j+1} − ψ_j)
    x_new, y_new = _rotate(c, s, _float_array(xp) - l0, _float_array(yp))
    return x_new, y_new


# ------------------------------------------------------------------------------------------ switching
def _active_leg_host(p: np.ndarray, w: np.ndarray, j: int, r_accept: float) -> int:
    last = len(w) - 2
    while j < last:
        d = w[j + 1] - w[j]
        length = math.hypot(d[0], d[1])
        xp = float(np.dot(p - w[j], d)) / length
        if xp >= length or math.hypot(*(p - w[j + 1])) <= r_accept:
            j += 1
        else:
            break
    return j


def _active_leg_traced(p, w, j, r_accept):
    w = _float_array(w)
    p = _float_array(p)
    last = w.shape[0] - 2

    def step(_, j):
        a, t, length = _leg(w, j)
        b = lax.dynamic_index_in_dim(w, j + 1, axis=0, keepdims=False)
        xp = jnp.sum(t * (p - a))
        dist = jnp.sqrt(jnp.sum((p - b) ** 2))
        advance = (j < last) & ((xp >= length) | (dist <= r_accept))
        return jnp.where(advance, j + 1, j)

    return lax.fori_loop(0, max(last, 0), step, jnp.asarray(j, jnp.int32))


def active_leg(position, waypoints, j, r_accept):
    """The leg switching rule: starting at leg ``j``, advance while the own-ship ``position [2]`` (north,
    east) is past the end of the leg (x_pj >= l_j) or within ``r_accept`` (R_a >= 0 [m]) of WP_{j+1}, never
    beyond the last leg n − 2.  Returns the new leg index: a Python ``int`` for concrete inputs, a traced
    ``int32`` scalar under ``jit`` (``lax.fori_loop``, same rule)."""
    if np.shape(position) != (2,):
        raise ValueError(f"position must have shape [2] (north, east), got {np.shape(position)}")
    _check_points(position, "position")
    w = check_waypoints(waypoints)
    j = check_leg_index(j, np.shape(waypoints)[0])
    r = _check_scalar(r_accept, "r_accept")
    if any(_is_traced(v) for v in (position, w, j, r)):
        return _active_leg_traced(position, w, j, r)
    return _active_leg_host(np.asarray(position, dtype=float), w, j, r)


__all__ = ["PathLegs", "MIN_LEG_LENGTH", "check_waypoints", "check_leg_index", "leg_angles", "path_legs",
           "to_path_frame", "from_path_frame", "to_leg_frame", "from_leg_frame", "switch_frame", "active_leg"]
