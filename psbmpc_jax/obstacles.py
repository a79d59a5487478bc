"""Obstacle prediction: LOS scenarios and OU covariance (Tengesdal et al. 2022, Sec. II-A and eqs. 7–8;
docs/algorithm.md §5-6).

Axes: O obstacles (padded), S scenarios (padded to the largest n_ps), W waypoints, T = N+1 time samples.
"""

from __future__ import annotations

import jax.numpy as jnp

from .ownship import Path, Trajectory, los_rollout, make_path


def scenario_offsets(n_ps, s_cap: int, r_ct):
    """Lateral offsets ``[O, S]``: (j - m) r_ct for j < n_ps, m = (n_ps - 1) / 2; 0 in padding."""
    j = jnp.arange(s_cap)
    m = (n_ps[:, None] - 1) / 2
    return jnp.where(j[None, :] < n_ps[:, None], (j[None, :] - m) * r_ct, 0.0)


def obstacle_scenarios(obs_state, wx, wy, n_wps, n_ps, s_cap: int, params, n_steps: int, dt,
                       unroll: int = 1, leg_u=None, kernel: str = "scan") -> Trajectory:
    """Predicted trajectories of every (obstacle, scenario), time-major components ``[N+1, O, S]``.

    Args:
        obs_state: ``[O, 4]`` estimates ``[x, y, V_x, V_y]``.
        wx, wy: ``[O, W]`` padded routes (already including the straight-line default route).
        n_wps: ``[O]`` valid waypoints (>= 2); n_ps: ``[O]`` scenario counts.
        leg_u: optional ``[O, W]`` leg speeds of shared plans (< 0: none; the present speed is held).
    """
    n_o = obs_state.shape[0]
    speed = jnp.sqrt(obs_state[:, 2] ** 2 + obs_state[:, 3] ** 2)
    course = jnp.arctan2(obs_state[:, 3], obs_state[:, 2])
    x0 = jnp.stack([obs_state[:, 0], obs_state[:, 1], course, speed], axis=-1)          # [O, 4]
    rows = n_o * s_cap
    rep = lambda a: jnp.repeat(a, s_cap, axis=0)
    path = make_path(rep(wx), rep(wy), rep(n_wps))
    offsets = scenario_offsets(n_ps, s_cap, params.r_ct).reshape(rows)
    u_ref = jnp.broadcast_to(rep(speed), (n_steps, rows))
    chi_off = jnp.zeros((n_steps, rows), obs_state.dtype)
    traj = los_rollout(rep(x0), path, chi_off, u_ref, offsets, params.ob_lookahead, params.ob_R_a,
                       params.ob_T_chi, params.ob_T_U, dt, unroll=unroll,
                       seg_speed=None if leg_u is None else rep(leg_u), kernel=kernel)
    return Trajectory(*(c.reshape(n_steps + 1, n_o, s_cap) for c in traj))


def ou_covariance(t, params):
    """Σ(t) of the OU position-velocity process started at zero, ``[..., 4, 4]`` in order [x, y, Vx, Vy].

    Q = [[σx², σxy], [σxy, σy²]], γ = (γx, γy) (docs/algorithm.md §6); ``t`` may be any shape."""
    t = jnp.asarray(t)[..., None, None]
    g = jnp.stack([params.gamma_x, params.gamma_y])
    q = jnp.array([[params.sigma_x ** 2, params.sigma_xy], [params.sigma_xy, params.sigma_y ** 2]])
    ga, gb = g[:, None], g[None, :]
    gab = ga + gb
    ea, eb, eab = -jnp.expm1(-ga * t), -jnp.expm1(-gb * t), -jnp.expm1(-gab * t)   # 1 - e^{-γ t}
    pp = q / (ga * gb) * (t - ea / ga - eb / gb + eab / gab)
    pv = q / ga * (eb / gb - eab / gab)          # cov(p_a, v_b)
    vv = q * eab / gab
    top = jnp.concatenate([pp, pv], axis=-1)
    bottom = jnp.concatenate([jnp.swapaxes(pv, -1, -2), vv], axis=-1)
    return jnp.concatenate([top, bottom], axis=-2)


def obstacle_covariances(P0, params, n_steps: int, dt):
    """P_k = P_0 + Σ(t_k) for k = 0..N: ``[O, N+1, 4, 4]``."""
    t = jnp.arange(n_steps + 1, dtype=P0.dtype) * dt
    return P0[:, None] + ou_covariance(t, params)[None]


def positional_stats(P):
    """From covariances ``[..., 4, 4]``: (S_xx, S_xy, S_yy, σ_max) of the positional block."""
    a, b, c = P[..., 0, 0], P[..., 0, 1], P[..., 1, 1]
    lam = 0.5 * (a + c) + jnp.sqrt(0.25 * (a - c) ** 2 + b * b)
    return a, b, c, jnp.sqrt(lam)


__all__ = ["scenario_offsets", "obstacle_scenarios", "ou_covariance", "obstacle_covariances",
           "positional_stats", "Path"]
