"""True vessel motion for the closed-loop simulator: the kinematic model with LOS guidance and first-order
autopilot lags (Tengesdal et al. 2022, eqs. 3–6 and 19), vectorised over any leading batch axes in NumPy float64.

It is the same model and guidance law that the planner uses for its predictions (``ownship.los_rollout``),
stepped one simulation step at a time, with the MPC's course offset added to the LOS course and the speed
factor applied to the nominal speed.  Routes are padded ``[n_ships, W, 2]`` with their point counts.
"""

from __future__ import annotations

import numpy as np

from ..numerics import wrap_angle_host as wrap

#: How far the simulator extends every route beyond its last waypoint, along the last leg [m]: ships keep
#: the last leg's course after their route ends (docs/algorithm.md §2), and the planner sees the same extended line.
ROUTE_EXTENSION_M = 20_000.0


def extend_route(waypoints: np.ndarray) -> np.ndarray:
    """Append a point :data:`ROUTE_EXTENSION_M` beyond the last waypoint along the last leg."""
    w = np.asarray(waypoints, float)
    d = w[-1] - w[-2]
    n = np.hypot(*d)
    if n == 0.0:
        raise ValueError(f"route's last leg has zero length at {w[-1].tolist()}")
    return np.concatenate([w, (w[-1] + ROUTE_EXTENSION_M * d / n)[None]])


def pad_routes(routes) -> tuple[np.ndarray, np.ndarray]:
    """Routes (list of ``[n_i, 2]``) -> padded ``[n_ships, W, 2]`` (last point repeated) and counts ``[n_ships]``."""
    w = max(len(r) for r in routes)
    out = np.zeros((len(routes), w, 2))
    for i, r in enumerate(routes):
        out[i, : len(r)] = r
        out[i, len(r):] = r[-1]
    return out, np.array([len(r) for r in routes], dtype=np.int64)


def los_course(pos: np.ndarray, seg: np.ndarray, routes: np.ndarray, n_wp: np.ndarray, lookahead, R_a):
    """Advance the active segments and return the LOS course ``[..., n_ships]`` (and the new segments).

    ``pos [..., n_ships, 2]``; ``routes [n_ships, W, 2]``; ``lookahead``, ``R_a`` ``[n_ships]``.
    Same switching rule as the planner: inside the acceptance radius of the next waypoint, or past the end
    of the segment along its direction; at most one switch per step; never beyond the last segment."""
    last = n_wp - 2                                                      # [n]
    ships = np.arange(routes.shape[0])

    def geometry(z):
        zc = np.minimum(z, last)
        a = routes[ships, zc]                                          # [..., n, 2]
        b = routes[ships, zc + 1]
        d = b - a
        return a, b, d, np.hypot(d[..., 0], d[..., 1])

    a, b, d, length = geometry(seg)
    along = np.sum((pos - a) * d, axis=-1) / length
    to_next = b - pos
    switch = (seg < last) & ((np.sum(to_next * to_next, axis=-1) <= R_a * R_a) | (along >= length))
    seg = seg + switch
    a, b, d, length = geometry(seg)
    alpha = np.arctan2(d[..., 1], d[..., 0])
    e = -(pos[..., 0] - a[..., 0]) * np.sin(alpha) + (pos[..., 1] - a[..., 1]) * np.cos(alpha)
    return alpha + np.arctan(-e / lookahead), seg


def kinematic_step(state: np.ndarray, chi_cmd, U_cmd, T_chi, T_U, dt: float) -> np.ndarray:
    """One forward-Euler step of eq. (19) with autopilot lags; ``state [..., 4]`` (x, y, chi, U)."""
    x, y, chi, U = np.moveaxis(state, -1, 0)
    return np.stack([
        x + dt * U * np.cos(chi),
        y + dt * U * np.sin(chi),
        wrap(chi + (dt / T_chi) * wrap(chi_cmd - chi)),
        U + (dt / T_U) * (U_cmd - U),
    ], axis=-1)


def leg_speed(ship, seg):
    """The nominal speed of ``ship`` on its active leg ``seg`` (an index into its extended route; beyond the last
    waypoint the last leg's), for a ship with ``leg_speeds``; ``seg`` may be an array."""
    legs = np.asarray(ship.leg_speeds, float)
    return legs[np.minimum(np.asarray(seg), len(legs) - 1)]


def nominal_speed(ship, t: float) -> float:
    """The ship's nominal speed U_d at time ``t`` (its speed plan, piecewise constant)."""
    u = ship.U_d
    if ship.speed_plan is not None:
        for t_k, u_k in ship.speed_plan:
            if t >= t_k:
                u = float(u_k)
    return float(u)
