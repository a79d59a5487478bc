"""Sequential float64 NumPy reference of the PSB-MPC predictions (``docs/algorithm.md`` §2-6): the own-ship's
LOS path following and kinematic model under one behaviour, the obstacles' prediction scenarios and their
Ornstein-Uhlenbeck covariances.

Part of the test oracle of :mod:`psbmpc_jax.reference` (which evaluates the costs on these trajectories); like it,
float64 throughout and only NumPy and the standard library.  Frame: NED (x north, y east) [m], course from north,
clockwise positive [rad].
"""

from __future__ import annotations

import math

import numpy as np

from .numerics import wrap_angle_host as wrap_angle
from .params import Params, PlannerConfig
from .situation import Obstacle, OwnShip

__all__ = [
    "wrap_angle",
    "as_behaviour",
    "los_rollout",
    "maneuver_start_steps",
    "ownship_trajectory",
    "obstacle_initial_state",
    "obstacle_path",
    "obstacle_scenarios",
    "ou_covariance",
    "obstacle_covariances",
]

# ----------------------------------------------------------------------------------------------------------
# §2-3 path following + kinematic model
# ----------------------------------------------------------------------------------------------------------
def _per_step(values, n_steps: int, name: str) -> np.ndarray:
    arr = np.asarray(values, dtype=float)
    if arr.ndim == 0:
        arr = np.full(n_steps, float(arr))
    arr = arr.reshape(-1)
    if arr.shape != (n_steps,):
        raise ValueError(f"{name} must be a scalar or have length n_steps={n_steps}, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite")
    return arr


def los_rollout(x0, waypoints, chi_offsets, U_cmd, lateral_offset, lookahead, R_a, T_chi, T_U, dt,
                n_steps, leg_speeds=None) -> np.ndarray:
    """Roll out the kinematic model (§3) under LOS path following (§2).

    Args:
        x0: initial state ``[x, y, chi, U]``.
        waypoints: path ``[n >= 2, 2]``.
        chi_offsets: ``[N]`` course offset added to chi_LOS at each step k = 0..N-1 (or a scalar).
        U_cmd: ``[N]`` speed reference at each step (or a scalar).
        lateral_offset: lateral path offset o [m] (positive = starboard of the path).
        lookahead: LOS lookahead distance Delta [m].
        R_a: waypoint acceptance radius [m].
        T_chi, T_U: course and speed time constants [s].
        dt: time step [s].
        n_steps: N.
        leg_speeds: optional ``[n - 1]`` speed per leg: the active leg's replaces ``U_cmd`` (after the last
            waypoint, the last leg's).

    Returns:
        ``[N + 1, 4]`` trajectory ``[x, y, chi, U]``; row 0 is ``x0``.
    """
    n_steps = int(n_steps)
    if n_steps < 0:
        raise ValueError(f"n_steps must be >= 0, got {n_steps}")
    x0 = np.asarray(x0, dtype=float)
    if x0.shape != (4,):
        raise ValueError(f"x0 must be a state [x, y, chi, U] of shape (4,), got {x0.shape}")
    wps = np.asarray(waypoints, dtype=float)
    if wps.ndim != 2 or wps.shape[1] != 2 or wps.shape[0] < 2:
        raise ValueError(f"waypoints must have shape [n >= 2, 2], got {wps.shape}")
    chi_off = _per_step(chi_offsets, n_steps, "chi_offsets")
    u_ref = _per_step(U_cmd, n_steps, "U_cmd")

    n = wps.shape[0]
    wx = [float(v) for v in wps[:, 0]]
    wy = [float(v) for v in wps[:, 1]]
    alpha = [math.atan2(wy[z + 1] - wy[z], wx[z + 1] - wx[z]) for z in range(n - 1)]
    seg_len = [math.hypot(wx[z + 1] - wx[z], wy[z + 1] - wy[z]) for z in range(n - 1)]
    cos_a = [math.cos(a) for a in alpha]
    sin_a = [math.sin(a) for a in alpha]
    o = float(lateral_offset)
    delta = float(lookahead)
    R_a = float(R_a)
    dt = float(dt)
    k_chi = dt / float(T_chi)
    k_u = dt / float(T_U)

    traj = np.empty((n_steps + 1, 4))
    traj[0] = x0
    x, y, chi, U = (float(v) for v in x0)
    z = 0
    for k in range(n_steps):
        # 1. switch (at most once per step)
        if z <= n - 2:
            s = (x - wx[z]) * cos_a[z] + (y - wy[z]) * sin_a[z]
            d_next = math.hypot(x - wx[z + 1], y - wy[z + 1])
            if d_next <= R_a or s >= seg_len[z]:
                z += 1
        # 2. guidance
        if z <= n - 2:
            e = -(x - wx[z]) * sin_a[z] + (y - wy[z]) * cos_a[z]
            chi_los = alpha[z] + math.atan(-(e - o) / delta)
        else:
            chi_los = alpha[n - 2]
        chi_cmd = chi_los + chi_off[k]
        # 3. explicit Euler, old state on the right-hand side
        x_new = x + dt * U * math.cos(chi)
        y_new = y + dt * U * math.sin(chi)
        chi_new = wrap_angle(chi + k_chi * wrap_angle(chi_cmd - chi))
        u_k = u_ref[k] if leg_speeds is None else float(leg_speeds[min(z, n - 2)])
        U_new = U + k_u * (u_k - U)
        x, y, chi, U = x_new, y_new, chi_new, U_new
        traj[k + 1, 0] = x
        traj[k + 1, 1] = y
        traj[k + 1, 2] = chi
        traj[k + 1, 3] = U
    return traj


# ----------------------------------------------------------------------------------------------------------
# §4 own-ship behaviours
# ----------------------------------------------------------------------------------------------------------
def as_behaviour(behaviour) -> np.ndarray:
    arr = np.asarray(behaviour, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != 2 or arr.shape[0] < 1:
        raise ValueError(
            f"behaviour must have shape [n_M >= 1, 2] (speed factor, course offset), got {arr.shape}"
        )
    return arr


def maneuver_start_steps(n_m: int, params: Params, config: PlannerConfig) -> np.ndarray:
    """k_M = round((M - 1) t_ts / dt), M = 1..n_M, with t_ts = T / n_M when ``params.t_ts`` is NaN."""
    t_ts = float(params.t_ts)
    if math.isnan(t_ts):
        t_ts = float(config.T) / n_m
    return np.array([int(round(m * t_ts / float(config.dt))) for m in range(n_m)], dtype=np.int64)


def ownship_trajectory(own_ship: OwnShip, behaviour, params: Params = Params(),
                       config: PlannerConfig = PlannerConfig()) -> np.ndarray:
    """Own-ship trajectory ``[N + 1, 4]`` under one behaviour ``[n_M, 2]`` (§4)."""
    beh = as_behaviour(behaviour)
    n_m = beh.shape[0]
    n_steps = config.n_steps
    k_start = maneuver_start_steps(n_m, params, config)
    # active maneuver at step k: the largest M with k_M <= k
    active = np.searchsorted(k_start, np.arange(n_steps), side="right") - 1
    chi_offsets = beh[active, 1]
    u_cmd = beh[active, 0] * float(own_ship.U_d)
    return los_rollout(own_ship.state, own_ship.waypoints, chi_offsets, u_cmd, 0.0,
                       params.os_lookahead, params.os_R_a, params.os_T_chi, params.os_T_U,
                       config.dt, n_steps)


# ----------------------------------------------------------------------------------------------------------
# §5 obstacle prediction scenarios
# ----------------------------------------------------------------------------------------------------------
def obstacle_initial_state(obstacle: Obstacle) -> np.ndarray:
    """[x, y, atan2(V_y, V_x), |V|] from the estimate [x, y, V_x, V_y]."""
    x, y, vx, vy = (float(v) for v in obstacle.state)
    return np.array([x, y, math.atan2(vy, vx), math.hypot(vx, vy)])


def obstacle_path(obstacle: Obstacle, config: PlannerConfig = PlannerConfig()) -> np.ndarray:
    """The obstacle's nominal path: its waypoints, else a straight line along its velocity (§5)."""
    if obstacle.waypoints is not None:
        return np.asarray(obstacle.waypoints, dtype=float)
    x, y, chi, V = obstacle_initial_state(obstacle)
    length = max(2.0 * V * float(config.T), 1000.0)
    return np.array([[x, y], [x + length * math.cos(chi), y + length * math.sin(chi)]])


def obstacle_scenarios(obstacle: Obstacle, params: Params = Params(),
                       config: PlannerConfig = PlannerConfig()) -> np.ndarray:
    """Prediction scenarios ``[n_ps, N + 1, 4]``; scenario j follows the path offset by (j - m) r_ct."""
    x0 = obstacle_initial_state(obstacle)
    path = obstacle_path(obstacle, config)
    n_ps = int(obstacle.n_ps)
    m = (n_ps - 1) / 2.0
    n_steps = config.n_steps
    out = np.empty((n_ps, n_steps + 1, 4))
    for j in range(n_ps):
        offset = (j - m) * float(params.r_ct)
        out[j] = los_rollout(x0, path, 0.0, x0[3], offset, params.ob_lookahead, params.ob_R_a,
                             params.ob_T_chi, params.ob_T_U, config.dt, n_steps, leg_speeds=obstacle.leg_speeds)
    return out


# ----------------------------------------------------------------------------------------------------------
# §6 obstacle covariance
# ----------------------------------------------------------------------------------------------------------
def ou_covariance(t, params: Params = Params()) -> np.ndarray:
    """Covariance Sigma(t) ``[4, 4]`` of the OU position-velocity process started at zero (§6), order
    [x, y, V_x, V_y]; P_0 is not included."""
    t = float(t)
    gam = (float(params.gamma_x), float(params.gamma_y))
    sxy = float(params.sigma_xy)
    Q = ((float(params.sigma_x) ** 2, sxy), (sxy, float(params.sigma_y) ** 2))

    def one_minus_exp_over(g: float) -> float:  # (1 - e^{-g t}) / g
        return -math.expm1(-g * t) / g

    sig = np.zeros((4, 4))
    for a in range(2):
        for b in range(2):
            ga, gb = gam[a], gam[b]
            ea, eb, eab = one_minus_exp_over(ga), one_minus_exp_over(gb), one_minus_exp_over(ga + gb)
            q = Q[a][b]
            sig[a, b] = q / (ga * gb) * (t - ea - eb + eab)
            sig[a, 2 + b] = q / ga * (eb - eab)
            sig[2 + a, 2 + b] = q * eab
    # exact symmetry: mirror the (p, p) and (v, v) off-diagonals and the (v, p) block
    sig[1, 0] = sig[0, 1]
    sig[3, 2] = sig[2, 3]
    for a in range(2):
        for b in range(2):
            sig[2 + b, a] = sig[a, 2 + b]
    return sig


def obstacle_covariances(obstacle: Obstacle, params: Params = Params(),
                         config: PlannerConfig = PlannerConfig()) -> np.ndarray:
    """P_k = P_0 + Sigma(t_k), ``[N + 1, 4, 4]``."""
    P0 = np.asarray(obstacle.cov, dtype=float)
    n_steps = config.n_steps
    return np.stack([P0 + ou_covariance(k * float(config.dt), params) for k in range(n_steps + 1)])
