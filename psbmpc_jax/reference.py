"""Sequential float64 NumPy reference of the PSB-MPC cost (the paper's Algorithm 2).

This module is the test oracle of the JAX evaluator and the "CPU sequential" baseline of the benchmark.
It implements ``docs/algorithm.md`` literally, one behaviour at a time (the trajectories come from
:mod:`psbmpc_jax.reference_prediction`):

* obstacle prediction scenarios and their covariances are generated once (§5-6);
* ``for l in behaviours``: own-ship rollout (§2-4), path cost, ``for j in polygons``: grounding cost,
  ``for i in obstacles: for s in scenarios``: collision cost ``C_s^{l,i}`` and COLREGS indicator
  ``mu_s^{l,i}`` (§7-8).

Inside one (l, i, s) the per-step geometry (distances, the sigma shortcut mask, COLREGS flags) is vectorised
over the time steps k with NumPy; the collision probability is then evaluated point by point for the steps
that pass the shortcut.  Everything is float64; only NumPy and the standard library are used.

Axis names: B behaviours, M maneuvers, S scenarios, T = N + 1 time samples.
Frame: NED (x north, y east) [m], course from north, clockwise positive [rad].
"""

from __future__ import annotations

import inspect
import math
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from .behaviours import validate_behaviours
from .params import ESTIMATORS, STOP_REMEDIES, Params, PlannerConfig, validate_params
from .reference_prediction import (
    as_behaviour,
    obstacle_covariances,
    obstacle_scenarios,
    ownship_trajectory,
    wrap_angle,
)
from .situation import Situation

__all__ = [
    "ReferenceResult",
    "evaluate_reference",
    "sigma_max",
    "collision_probability",
    "collision_cost",
    "colregs_violation",
    "colregs_violation_heading",
    "polygon_distance",
    "polygon_distances",
    "grounding_cost",
    "path_cost",
    "normal_cdf",
]

_SQRT2 = math.sqrt(2.0)
COS_67_5 = math.cos(math.radians(67.5))
COS_22_5 = math.cos(math.radians(22.5))


# ----------------------------------------------------------------------------------------------------------
# small helpers
# ----------------------------------------------------------------------------------------------------------
def normal_cdf(x: float) -> float:
    """Standard normal CDF, float64: ``0.5 * erfc(-x / sqrt(2))``."""
    return 0.5 * math.erfc(-x / _SQRT2)


def _phi_ratio(num: float, s: float) -> float:
    """Phi(num / s), with its s -> 0+ limit (step function, 1/2 at num = 0) for a degenerate chord spread."""
    if s > 0.0:
        return 0.5 * math.erfc(-(num / s) / _SQRT2)
    if num > 0.0:
        return 1.0
    if num < 0.0:
        return 0.0
    return 0.5


@lru_cache(maxsize=16)
def _leggauss(n: int) -> tuple[np.ndarray, np.ndarray]:
    t, w = np.polynomial.legendre.leggauss(int(n))
    t.setflags(write=False)
    w.setflags(write=False)
    return t, w


def _chol2(S) -> tuple[float, float, float]:
    """Lower Cholesky factor [[l00, 0], [l10, l11]] of a 2x2 covariance, as in algorithm.md §7 (mc).

    Degenerate inputs (S_xx = 0, or a rounding-negative Schur complement) give zero entries instead of NaN.
    """
    l00 = math.sqrt(max(float(S[0][0]), 0.0))
    l10 = float(S[0][1]) / l00 if l00 > 0.0 else 0.0
    l11 = math.sqrt(max(float(S[1][1]) - l10 * l10, 0.0))
    return l00, l10, l11


def sigma_max(S) -> float:
    """Largest positional standard deviation sqrt(lambda_max(S)) of a 2x2 covariance (closed form, §6)."""
    a, b, c = float(S[0][0]), float(S[0][1]), float(S[1][1])
    lam = 0.5 * (a + c) + math.sqrt((0.5 * (a - c)) ** 2 + b * b)
    return math.sqrt(max(lam, 0.0))


# ----------------------------------------------------------------------------------------------------------
# §7 collision probability
# ----------------------------------------------------------------------------------------------------------
def _check_estimator(estimator: str) -> None:
    if estimator not in ESTIMATORS:
        raise ValueError(f"estimator must be one of {ESTIMATORS}, got {estimator!r}")


def _check_samples(samples, estimator: str, config: PlannerConfig):
    """The standard-normal table the estimator needs, as float64 (None for quadrature)."""
    _check_estimator(estimator)
    if estimator == "quadrature":
        return None
    shape: tuple[int, ...]
    if estimator == "mc":
        shape = (config.n_samples, 2)
        what = "(config.n_samples, 2)"
    else:
        shape = (config.ce_max_iter + 1, config.n_samples, 2)
        what = "(config.ce_max_iter + 1, config.n_samples, 2)"
    if samples is None:
        raise ValueError(
            f"samples (a standard normal table of shape {what} = {shape}) is required for estimator "
            f"{estimator!r}, got None"
        )
    arr = np.asarray(samples, dtype=float)
    if arr.shape != shape:
        raise ValueError(f"samples must have shape {what} = {shape} for estimator {estimator!r}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError("samples must be finite")
    return arr


def _pc_quadrature(p, mu, S, R: float, n_quad: int, quad_span: float) -> float:
    dx = float(mu[0]) - float(p[0])
    dy = float(mu[1]) - float(p[1])
    d = math.hypot(dx, dy)
    if d == 0.0:
        ux, uy = 1.0, 0.0
    else:
        ux, uy = dx / d, dy / d
    vx, vy = -uy, ux
    s00, s01, s10, s11 = float(S[0][0]), float(S[0][1]), float(S[1][0]), float(S[1][1])
    Suu = ux * (s00 * ux + s01 * uy) + uy * (s10 * ux + s11 * uy)
    Suv = ux * (s00 * vx + s01 * vy) + uy * (s10 * vx + s11 * vy)
    Svv = vx * (s00 * vx + s01 * vy) + vy * (s10 * vx + s11 * vy)
    s_x = math.sqrt(max(Suu, 0.0))
    a = max(-R, d - quad_span * s_x)
    b = min(R, d + quad_span * s_x)
    if a >= b:
        return 0.0
    # Suu > 0 here (otherwise a = b = d, or a > b)
    s = math.sqrt(max(Svv - Suv * Suv / Suu, 0.0))
    # half-angle substitution x = 2Ru/(1+u^2), u = x / (R + sqrt(R^2 - x^2))
    u_a = a / (R + math.sqrt(max(R * R - a * a, 0.0)))
    u_b = b / (R + math.sqrt(max(R * R - b * b, 0.0)))
    t_n, w_n = _leggauss(n_quad)
    half = 0.5 * (u_b - u_a)
    un = half * t_n + 0.5 * (u_b + u_a)
    qn = 1.0 / (1.0 + un * un)
    xn = 2.0 * R * un * qn
    rc = R * (1.0 - un * un) * qn  # h_n, the chord half-width
    jac = 2.0 * rc * qn            # dx/du
    mn = (Suv / Suu) * (xn - d)
    gauss = np.exp(-0.5 * (xn - d) ** 2 / Suu) / math.sqrt(2.0 * math.pi * Suu)
    chord = np.array([_phi_ratio(h - m, s) - _phi_ratio(-h - m, s) for h, m in zip(rc.tolist(), mn.tolist())])
    f = gauss * chord * jac
    val = half * float(np.dot(w_n, f))
    return min(max(val, 0.0), 1.0)


def _pc_mc(p, mu, S, R: float, Z: np.ndarray) -> float:
    l00, l10, l11 = _chol2(S)
    xs = float(mu[0]) + l00 * Z[:, 0]
    ys = float(mu[1]) + l10 * Z[:, 0] + l11 * Z[:, 1]
    inside = (xs - float(p[0])) ** 2 + (ys - float(p[1])) ** 2 <= R * R
    return int(np.count_nonzero(inside)) / Z.shape[0]


def _inv2(S) -> tuple[float, float, float, float]:
    """(inverse entries i00, i01, i11, determinant) of a symmetric 2x2 matrix."""
    a, b, c = float(S[0][0]), float(S[0][1]), float(S[1][1])
    det = a * c - b * b
    return c / det, -b / det, a / det, det


def _pc_ce(p, mu, S, R: float, Z: np.ndarray, params: Params) -> float:
    n_iter = Z.shape[0] - 1
    n_s = Z.shape[1]
    px, py = float(p[0]), float(p[1])
    mx, my = float(mu[0]), float(mu[1])
    R2 = R * R
    a, b, c = float(S[0][0]), float(S[0][1]), float(S[1][1])
    det_s = a * c - b * b
    if not det_s > 0.0:
        # [degenerate positional covariance: N(x; mu, S) has no density; algorithm.md is silent] -> 0
        return 0.0
    i00, i01, i11 = c / det_s, -b / det_s, a / det_s
    rho, alpha, chi2 = float(params.ce_rho), float(params.ce_alpha), float(params.ce_chi2)

    mu_c = np.array([0.5 * (px + mx), 0.5 * (py + my)])
    sig_c = np.array([[R2 / 3.0, 0.0], [0.0, R2 / 3.0]])

    def draw(z):
        l00, l10, l11 = _chol2(sig_c)
        xs = mu_c[0] + l00 * z[:, 0]
        ys = mu_c[1] + l10 * z[:, 0] + l11 * z[:, 1]
        return xs, ys

    for it in range(n_iter):
        xs, ys = draw(Z[it])
        in_disc = (xs - px) ** 2 + (ys - py) ** 2 <= R2
        ex, ey = xs - mx, ys - my
        maha = ex * ex * i00 + 2.0 * ex * ey * i01 + ey * ey * i11
        elite = in_disc & (maha <= chi2)
        n_e = int(np.count_nonzero(elite))
        if n_e >= rho * n_s:
            break
        if n_e < 3:
            break
        ex_e, ey_e = xs[elite], ys[elite]
        me = np.array([ex_e.mean(), ey_e.mean()])
        cx, cy = ex_e - me[0], ey_e - me[1]
        sig_e = np.array([[np.dot(cx, cx), np.dot(cx, cy)], [np.dot(cy, cx), np.dot(cy, cy)]]) / n_e
        mu_c = alpha * me + (1.0 - alpha) * mu_c
        sig_c = alpha * sig_e + (1.0 - alpha) * sig_c

    xs, ys = draw(Z[n_iter])
    in_disc = (xs - px) ** 2 + (ys - py) ** 2 <= R2
    # N(x; mu, S) / N(x; mu_c, Sigma_c) = sqrt(det Sigma_c / det S) exp(-(q_S - q_c) / 2)
    j00, j01, j11, det_c = _inv2(sig_c)
    ex, ey = xs - mx, ys - my
    q_s = ex * ex * i00 + 2.0 * ex * ey * i01 + ey * ey * i11
    fx, fy = xs - mu_c[0], ys - mu_c[1]
    q_c = fx * fx * j00 + 2.0 * fx * fy * j01 + fy * fy * j11
    w = np.where(in_disc, math.sqrt(det_c / det_s) * np.exp(-0.5 * (q_s - q_c)), 0.0)
    return min(1.0, float(np.sum(w)) / n_s)


def _pc_no_shortcut(p, mu, S, R: float, estimator: str, params: Params, config: PlannerConfig,
                    samples) -> float:
    if estimator == "quadrature":
        return _pc_quadrature(p, mu, S, R, config.n_quad, float(config.quad_span))
    if estimator == "mc":
        return _pc_mc(p, mu, S, R, samples)
    return _pc_ce(p, mu, S, R, samples, params)


def collision_probability(p, mu, S, R, estimator: str = "quadrature", params: Params = Params(),
                          config: PlannerConfig = PlannerConfig(), samples=None) -> float:
    """Probability that N(mu, S) lies in the disc of radius R around p (§7), including the shortcut.

    Args:
        p: own-ship position (2,).  mu: obstacle mean position (2,).  S: 2x2 positional covariance.
        R: disc radius d_safe + (l_os + l_i) / 2.
        estimator: ``"quadrature"``, ``"mc"`` or ``"ce"``.
        samples: standard normal table, ``(n_samples, 2)`` for mc, ``(ce_max_iter + 1, n_samples, 2)``
            for ce; ignored for quadrature.
    """
    Z = _check_samples(samples, estimator, config)
    p = np.asarray(p, dtype=float).reshape(2)
    mu = np.asarray(mu, dtype=float).reshape(2)
    S = np.asarray(S, dtype=float).reshape(2, 2)
    R = float(R)
    d = math.hypot(float(mu[0] - p[0]), float(mu[1] - p[1]))
    if d > R + float(params.c_sigma) * sigma_max(S):
        return 0.0
    return _pc_no_shortcut(p, mu, S, R, estimator, params, config, Z)


# ----------------------------------------------------------------------------------------------------------
# §8 cost terms
# ----------------------------------------------------------------------------------------------------------
def _velocities(traj: np.ndarray) -> np.ndarray:
    return traj[:, 3:4] * np.stack([np.cos(traj[:, 2]), np.sin(traj[:, 2])], axis=1)


def collision_cost(own_traj, obs_traj, S_seq, R, zeta, params: Params = Params(),
                   config: PlannerConfig = PlannerConfig(), samples=None) -> float:
    """C_s^{l,i} = max_k zeta K_coll |v_obs - v_own|^2 P_k exp(-t_k / T_d) for one (l, i, s) (§8).

    The shortcut mask is computed for all k at once; the probability is then evaluated point by point for
    the steps that pass it.  ``samples`` must already be validated (see ``evaluate_reference``).
    """
    estimator = config.estimator
    own_traj = np.asarray(own_traj, dtype=float)
    obs_traj = np.asarray(obs_traj, dtype=float)
    S_seq = np.asarray(S_seq, dtype=float)
    R = float(R)
    dp = obs_traj[:, :2] - own_traj[:, :2]
    dist = np.sqrt(dp[:, 0] ** 2 + dp[:, 1] ** 2)
    a, b, c = S_seq[:, 0, 0], S_seq[:, 0, 1], S_seq[:, 1, 1]
    lam = 0.5 * (a + c) + np.sqrt((0.5 * (a - c)) ** 2 + b * b)
    smax = np.sqrt(np.maximum(lam, 0.0))
    passing = np.flatnonzero(dist <= R + float(params.c_sigma) * smax)
    if passing.size == 0:
        return 0.0
    dv = _velocities(obs_traj) - _velocities(own_traj)
    dv2 = dv[:, 0] ** 2 + dv[:, 1] ** 2
    scale = float(zeta) * float(params.K_coll)
    dt, T_d = float(config.dt), float(params.T_d)
    best = 0.0
    for k in passing.tolist():
        pk = _pc_no_shortcut(own_traj[k, :2], obs_traj[k, :2], S_seq[k], R, estimator, params, config,
                             samples)
        if pk > 0.0:
            cost = scale * dv2[k] * pk * math.exp(-(k * dt) / T_d)
            if cost > best:
                best = cost
    return best


def colregs_violation(own_traj, obs_traj, params: Params = Params(), stop_remedy: str = "none") -> np.ndarray:
    """Per-step COLREGS (rules 14/15) violation flags ``[N + 1]`` bool for one (l, i, s) (§8).

    mu_s^{l,i} = ``colregs_violation(...).any()``.  ``stop_remedy="colregs_heading"``: every step through
    :func:`colregs_violation_heading` (the test on the own-ship's heading whatever its speed).
    """
    own_traj = np.asarray(own_traj, dtype=float)
    obs_traj = np.asarray(obs_traj, dtype=float)
    if stop_remedy not in STOP_REMEDIES:
        raise ValueError(f"stop_remedy must be one of {STOP_REMEDIES}, got {stop_remedy!r}")
    if stop_remedy == "colregs_heading":
        return np.array([colregs_violation_heading(o, b, float(params.d_close)) for o, b in zip(own_traj, obs_traj)],
                        dtype=bool)
    v0 = _velocities(own_traj)
    vi = _velocities(obs_traj)
    dp = obs_traj[:, :2] - own_traj[:, :2]
    d = np.sqrt(dp[:, 0] ** 2 + dp[:, 1] ** 2)
    safe_d = np.where(d > 0.0, d, 1.0)
    L = np.where((d > 0.0)[:, None], dp / safe_d[:, None], 0.0)
    n0 = np.sqrt(v0[:, 0] ** 2 + v0[:, 1] ** 2)
    ni = np.sqrt(vi[:, 0] ** 2 + vi[:, 1] ** 2)
    dot = v0[:, 0] * vi[:, 0] + v0[:, 1] * vi[:, 1]
    close = d < float(params.d_close)
    overtaken = (dot > COS_67_5 * n0 * ni) & (ni > n0)
    chi0 = own_traj[:, 2]
    starboard = np.cos(chi0) * dp[:, 1] - np.sin(chi0) * dp[:, 0] > 0.0
    head_on = ((n0 > 0.05) & (dot < -COS_22_5 * n0 * ni)
               & (v0[:, 0] * L[:, 0] + v0[:, 1] * L[:, 1] > COS_67_5 * n0))
    crossed = (n0 > 0.05) & (dot < COS_67_5 * n0 * ni)   # [choice] moving own-ship, as HEAD-ON
    return close & starboard & (head_on | (crossed & ~overtaken))


def colregs_violation_heading(own, obs, d_close: float) -> bool:
    """The stop remedy's COLREGS test of one time step, in angles (own-ship and obstacle states (x, y, χ, U)):
    with the own-ship's heading χ₀ standing for its direction whatever its speed U₀, the bearing β of the
    obstacle and Δχ = χ_i − χ₀:  CLOSE d < d_close; STARBOARD sin(β − χ₀) > 0; AHEAD d > 0 ∧ cos(β − χ₀) >
    cos 67.5°; HEAD-ON U_i > 0 ∧ cos Δχ < −cos 22.5° ∧ AHEAD; CROSSED U_i > 0 ∧ cos Δχ < cos 67.5°; OVERTAKEN
    U_i > 0 ∧ cos Δχ > cos 67.5° ∧ U_i > U₀.  Violation: CLOSE ∧ STARBOARD ∧ (HEAD-ON ∨ (CROSSED ∧ ¬OVERTAKEN)).
    (Negative speeds do not occur in the trajectories.)"""
    x0, y0, chi0, u0 = (float(v) for v in own[:4])
    xi, yi, chii, ui = (float(v) for v in obs[:4])
    dx, dy = xi - x0, yi - y0
    d = math.hypot(dx, dy)
    if not d < d_close or d == 0.0:
        return False
    beta = math.atan2(dy, dx)
    if not math.sin(beta - chi0) > 0.0:
        return False
    c = math.cos(chii - chi0)
    ahead = math.cos(beta - chi0) > COS_67_5
    head_on = ui > 0.0 and c < -COS_22_5 and ahead
    crossed = ui > 0.0 and c < COS_67_5
    overtaken = ui > 0.0 and c > COS_67_5 and ui > u0
    return bool(head_on or (crossed and not overtaken))


def polygon_distances(points, ring) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Distance from each point ``[K, 2]`` to a polygon — a ring ``[n, 2]`` or a tuple of rings (outer ring and
    holes) — (0 inside, even-odd rule over all rings), the unit
    vector to the nearest boundary point (zeros inside or at distance 0), and the inside flags."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    rings = ring if isinstance(ring, (list, tuple)) and len(ring) and np.ndim(ring[0]) == 2 else (ring,)
    As = []
    for r in rings:
        R_ = np.asarray(r, dtype=float)
        if R_.ndim != 2 or R_.shape[1] != 2 or R_.shape[0] < 3:
            raise ValueError(f"polygon ring must have shape [n >= 3, 2], got {R_.shape}")
        As.append(R_)
    # every ring is closed on itself; the even-odd rule over all rings' edges handles holes
    A = np.concatenate(As)
    B = np.concatenate([np.roll(R_, -1, axis=0) for R_ in As])
    E = B - A                                            # edge vectors b - a
    L2 = E[:, 0] ** 2 + E[:, 1] ** 2
    L2_safe = np.where(L2 > 0.0, L2, 1.0)                # zero-length edge: dot = 0 -> t = 0
    dy_safe = np.where(E[:, 1] != 0.0, E[:, 1], 1.0)     # only used where the edge straddles p_y
    Ax, Ay, Ex, Ey, By = A[:, 0], A[:, 1], E[:, 0], E[:, 1], B[:, 1]

    n_pts = pts.shape[0]
    dist = np.empty(n_pts)
    unit = np.zeros((n_pts, 2))
    inside = np.empty(n_pts, dtype=bool)
    block = max(1, 65536 // max(1, A.shape[0]))  # cache-sized blocks of points
    for start in range(0, n_pts, block):
        P = pts[start:start + block]
        px, py = P[:, 0:1], P[:, 1:2]                    # [K, 1]
        rows = np.arange(P.shape[0])
        rx = px - Ax                                     # [K, n]  p - a
        ry = py - Ay
        # nearest point on each edge: a + t (b - a), t = clip((p - a).(b - a) / |b - a|^2, 0, 1)
        t = rx * Ex
        t += ry * Ey
        t /= L2_safe
        np.clip(t, 0.0, 1.0, out=t)
        ddx = t * Ex
        ddx += Ax
        ddx -= px                                        # nearest - p
        ddy = t * Ey
        ddy += Ay
        ddy -= py
        d2 = ddx * ddx
        d2 += ddy * ddy
        jmin = np.argmin(d2, axis=1)
        dmin = np.sqrt(d2[rows, jmin])
        # even-odd ray crossing: (a_y > p_y) != (b_y > p_y) and p_x < a_x + (p_y - a_y)(b_x - a_x)/(b_y - a_y)
        straddle = (Ay > py) != (By > py)
        x_cross = ry * Ex
        x_cross /= dy_safe
        x_cross += Ax
        straddle &= px < x_cross
        ins = (np.count_nonzero(straddle, axis=1) % 2) == 1
        has_dir = (~ins) & (dmin > 0.0)
        safe = np.where(has_dir, dmin, 1.0)
        dist[start:start + block] = np.where(ins, 0.0, dmin)
        unit[start:start + block, 0] = np.where(has_dir, ddx[rows, jmin] / safe, 0.0)
        unit[start:start + block, 1] = np.where(has_dir, ddy[rows, jmin] / safe, 0.0)
        inside[start:start + block] = ins
    return dist, unit, inside


def polygon_distance(point, ring) -> tuple[float, np.ndarray]:
    """(distance, unit vector to the nearest boundary point) from one point to a polygon ring (§8).

    The distance is 0 inside (even-odd rule); the unit vector is zeros inside or at distance 0.
    """
    d, u, _ = polygon_distances(np.asarray(point, dtype=float).reshape(1, 2), ring)
    return float(d[0]), u[0].copy()


def grounding_cost(traj, ring, params: Params = Params(), config: PlannerConfig = PlannerConfig(),
                   d_safe=None) -> float:
    """H_so^{l,j} = max_k g(d_{j,k}, t_k) of one own-ship trajectory ``[N + 1, >= 2]`` and one polygon (§8).

    ``d_safe`` defaults to ``params.d_safe``.
    """
    traj = np.asarray(traj, dtype=float)
    d_safe = float(params.d_safe) if d_safe is None else float(d_safe)
    d, L, _ = polygon_distances(traj[:, :2], ring)
    t = np.arange(traj.shape[0]) * float(config.dt)
    wd = float(params.wind_dir)
    phi = np.maximum(0.0, math.cos(wd) * L[:, 0] + math.sin(wd) * L[:, 1])
    A = float(params.G1) + float(params.G2) * phi * float(params.V_w) ** 2
    G3, G4 = float(params.G3), float(params.G4)
    g = np.where(d >= d_safe,
                 A * np.exp(-(G3 * (d - d_safe) + G4 * t)),
                 A * np.exp(-G4 * t) * (1.0 + G3 * (d_safe - d)))
    return float(np.max(g))


def path_cost(behaviour, last_offsets=(1.0, 0.0), params: Params = Params()) -> float:
    """H_p of one behaviour ``[n_M, 2]`` given the previously applied offsets (u_last, chi_last) (§8)."""
    beh = as_behaviour(behaviour)
    last = np.asarray(last_offsets, dtype=float).reshape(-1)
    if last.shape != (2,):
        raise ValueError(f"last_offsets must be (speed factor, course offset), got shape {last.shape}")
    K_u, K_du = float(params.K_u), float(params.K_du)
    K_cp, K_cs = float(params.K_chi_port), float(params.K_chi_stbd)
    K_dp, K_ds = float(params.K_dchi_port), float(params.K_dchi_stbd)

    def f(u: float, chi: float) -> float:
        return K_u * (1.0 - u) + (K_cp if chi < 0.0 else K_cs) * chi * chi

    def h(u: float, chi: float, u_prev: float, chi_prev: float) -> float:
        delta = wrap_angle(chi - chi_prev)
        return K_du * abs(u - u_prev) + (K_dp if delta < 0.0 else K_ds) * delta * delta

    n_m = beh.shape[0]
    us = [float(v) for v in beh[:, 0]]
    cs = [float(v) for v in beh[:, 1]]
    first = sum(f(us[m], cs[m]) for m in range(n_m)) + h(us[0], cs[0], float(last[0]), float(last[1]))
    cost = first / n_m
    if n_m >= 2:
        cost += sum(h(us[m], cs[m], us[m - 1], cs[m - 1]) for m in range(1, n_m)) / (n_m - 1)
    return cost


# ----------------------------------------------------------------------------------------------------------
# Algorithm 2
# ----------------------------------------------------------------------------------------------------------
@dataclass
class ReferenceResult:
    """Cost breakdown of every behaviour (B behaviours, n_ps_i scenarios of obstacle i, T = N + 1)."""

    total: np.ndarray      # (B,) H^l
    do: np.ndarray         # (B,) H_do
    colregs: np.ndarray    # (B,) H_colregs
    so: np.ndarray         # (B,) H_so
    path: np.ndarray       # (B,) H_p
    best: int              # argmin (first index on ties)
    own_traj: np.ndarray   # (B, N+1, 4) [x, y, chi, U]
    obs_traj: list         # per obstacle i: (n_ps_i, N+1, 4)
    obs_cov: list          # per obstacle i: (N+1, 4, 4)
    C: list                # per obstacle i: (B, n_ps_i) collision cost C_s^{l,i}
    mu: list               # per obstacle i: (B, n_ps_i) COLREGS indicator (0.0/1.0)
    so_j: np.ndarray       # (B, n_so) per-polygon grounding cost H_so^{l,j}
    extra: dict = field(default_factory=dict)   # name -> (B,) costs of extra terms


def evaluate_reference(situation: Situation, behaviours, params: Params = Params(),
                       config: PlannerConfig = PlannerConfig(), last_offsets=(1.0, 0.0),
                       samples=None, extra_terms=()) -> ReferenceResult:
    """Evaluate the PSB-MPC cost of every behaviour sequentially in float64 (Algorithm 2).

    Args:
        situation: own-ship, obstacles and grounding polygons.
        behaviours: ``[B, n_M, 2]`` (speed factor, course offset [rad]).
        params, config: planner parameters; ``config.dtype`` is ignored (always float64).
        last_offsets: previously applied (speed factor, course offset), planner state.
        samples: standard normal table, ``(n_samples, 2)`` for ``mc``, ``(ce_max_iter + 1, n_samples, 2)``
            for ``ce``; ignored for ``quadrature``.
        extra_terms: cost terms beyond the paper's four (:func:`psbmpc_jax.costs.base.cost_term` instances),
            each evaluated through its ``reference(own_traj [N+1, 4], behaviour [n_M, 2], situation, params,
            config[, last_offsets])`` method (``last_offsets`` passed when the method takes it); their costs are in
            ``ReferenceResult.extra`` and added to the total.
    """
    if not isinstance(situation, Situation):
        raise ValueError(f"situation must be a psbmpc_jax.Situation, got {type(situation).__name__}")
    if not isinstance(config, PlannerConfig):
        raise ValueError(f"config must be a psbmpc_jax.PlannerConfig, got {type(config).__name__}")
    validate_params(params)
    beh = validate_behaviours(behaviours)
    last = np.asarray(last_offsets, dtype=float).reshape(-1)
    if last.shape != (2,) or not np.all(np.isfinite(last)):
        raise ValueError(
            f"last_offsets must be two finite numbers (speed factor, course offset), got {last_offsets!r}"
        )
    Z = _check_samples(samples, config.estimator, config)

    own = situation.own_ship
    obstacles = situation.obstacles
    polygons = situation.polygons
    n_b = beh.shape[0]
    n_steps = config.n_steps

    # obstacle prediction scenarios and covariances, once per solve
    obs_traj = [obstacle_scenarios(ob, params, config) for ob in obstacles]
    obs_cov = [obstacle_covariances(ob, params, config) for ob in obstacles]
    S_pos = [cov[:, 0:2, 0:2].copy() for cov in obs_cov]
    radii = [float(params.d_safe) + 0.5 * (float(own.length) + float(ob.length)) for ob in obstacles]

    own_traj = np.empty((n_b, n_steps + 1, 4))
    H_do = np.zeros(n_b)
    H_col = np.zeros(n_b)
    H_so = np.zeros(n_b)
    H_p = np.zeros(n_b)
    so_j = np.zeros((n_b, len(polygons)))
    C = [np.zeros((n_b, ob.n_ps)) for ob in obstacles]
    mu = [np.zeros((n_b, ob.n_ps)) for ob in obstacles]
    kappa = float(params.kappa)
    remedy = getattr(config, "stop_remedy", "none")

    for l in range(n_b):
        traj = ownship_trajectory(own, beh[l], params, config)
        own_traj[l] = traj
        H_p[l] = path_cost(beh[l], last, params)
        for j, ring in enumerate(polygons):
            so_j[l, j] = grounding_cost(traj, ring, params, config, params.d_safe)
        H_so[l] = float(np.max(so_j[l])) if len(polygons) else 0.0
        h_do = 0.0
        h_col = 0.0
        for i, ob in enumerate(obstacles):
            sum_c = 0.0
            sum_mu = 0.0
            assert ob.probs is not None          # Obstacle.__post_init__ sets the uniform default
            for s in range(ob.n_ps):
                c_s = collision_cost(traj, obs_traj[i][s], S_pos[i], radii[i], ob.zeta, params, config, Z)
                mu_s = 1.0 if bool(np.any(colregs_violation(traj, obs_traj[i][s], params, remedy))) else 0.0
                C[i][l, s] = c_s
                mu[i][l, s] = mu_s
                sum_c += float(ob.probs[s]) * c_s
                sum_mu += float(ob.probs[s]) * mu_s
            h_do += float(ob.weight) * sum_c
            h_col += float(ob.weight) * sum_mu
        H_do[l] = h_do
        H_col[l] = kappa * h_col

    total = H_do + H_col + H_so + H_p
    extra = {}
    for term in extra_terms:
        ref = getattr(term, "reference", None)
        if not callable(ref):
            raise ValueError(f"cost term {term.name!r} has no reference(...) counterpart")
        # a term that depends on the planner state (e.g. a manoeuvring cost) gets the same last offsets
        kw = {"last_offsets": tuple(last)} if "last_offsets" in inspect.signature(ref).parameters else {}
        extra[term.name] = np.array([float(ref(own_traj[l], beh[l], situation, params, config, **kw))
                                     for l in range(n_b)])
        total = total + extra[term.name]
    return ReferenceResult(
        total=total, do=H_do, colregs=H_col, so=H_so, path=H_p, best=int(np.argmin(total)),
        own_traj=own_traj, obs_traj=obs_traj, obs_cov=obs_cov, C=C, mu=mu, so_j=so_j, extra=extra,
    )
