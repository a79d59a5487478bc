"""Float64 NumPy/``math`` oracle of the MCS + KF collision risk of Tengesdal, Brekke & Johansen (2020) and of
its PSB-MPC cost, eq. (20) (docs/mcskf.md; the JAX code is :mod:`psbmpc_jax.costs.mcskf`).

Written independently of the JAX code, as plain loops: the scalar Kalman filter in its recursive form (and
the smoothing matrix W by explicit products), a column Cholesky, the CPA time, the Monte-Carlo indicator
sample by sample, and the cost summed step by step.  Also the exact probability of the ``"mean_cpa"`` event
(a 2-D Gaussian disc probability by quadrature, and the Marcum-Q series for an isotropic covariance), the
reference values of the Fig. 3 unit case.

States: own-ship and targets (x, y, χ, U) in NED (x north, y east [m], χ [rad] clockwise from north,
U [m/s]); obstacle covariances 4×4 in the order [x, y, V_x, V_y].
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .reference import colregs_violation_heading
from .reference_smooth import colregs_boolean

CHOL_TOL = 64.0          # the pivot threshold of cholesky4, times eps and the largest diagonal entry


# ------------------------------------------------------------------------------------------ the scalar KF
def kf_gains(n: int, q_P: float = 5e-5, r_P: float = 1e-3, V0: float = 0.3) -> np.ndarray:
    """K_0 … K_{n−1} of the scalar random-walk KF (prior variance V0)."""
    K = np.empty(n)
    v_prior = float(V0)
    for k in range(n):
        K[k] = v_prior / (v_prior + r_P)
        v_post = (1.0 - K[k]) * v_prior
        v_prior = v_post + q_P
    return K


def kf_filter(y, q_P: float = 5e-5, r_P: float = 1e-3, V0: float = 0.3, P0: float = 0.0) -> np.ndarray:
    """The recursive filter: ℙ⁻₀ = P0, V⁻₀ = V0; K = V⁻/(V⁻ + r_P); ℙ̂ = min(ℙ⁻ + K (y − ℙ⁻), 1);
    V = (1 − K) V⁻; ℙ⁻ ← ℙ̂; V⁻ ← V + q_P."""
    out = np.empty(len(y))
    p_prior, v_prior = float(P0), float(V0)
    for k, yk in enumerate(y):
        gain = v_prior / (v_prior + r_P)
        p = p_prior + gain * (float(yk) - p_prior)
        p = min(p, 1.0)
        out[k] = p
        p_prior, v_prior = p, (1.0 - gain) * v_prior + q_P
    return out


def kf_matrix(n: int, q_P: float = 5e-5, r_P: float = 1e-3, V0: float = 0.3) -> np.ndarray:
    """W[k, j] = K_j Π_{m=j+1}^{k} (1 − K_m) (j ≤ k), by explicit products."""
    K = kf_gains(n, q_P, r_P, V0)
    W = np.zeros((n, n))
    for k in range(n):
        for j in range(k + 1):
            w = K[j]
            for m in range(j + 1, k + 1):
                w *= 1.0 - K[m]
            W[k, j] = w
    return W


# ------------------------------------------------------------------------------------------ sampling pieces
def cholesky4(S) -> np.ndarray:
    """Column Cholesky of a PSD 4×4; a pivot ≤ CHOL_TOL·eps·max(diag) gives a zero column."""
    S = np.asarray(S, dtype=float)
    tol = CHOL_TOL * np.finfo(float).eps * max(S[i, i] for i in range(4))
    L = np.zeros((4, 4))
    for j in range(4):
        s = S[j, j] - sum(L[j, m] ** 2 for m in range(j))
        if s > tol:
            L[j, j] = math.sqrt(s)
            for i in range(j + 1, 4):
                L[i, j] = (S[i, j] - sum(L[i, m] * L[j, m] for m in range(j))) / L[j, j]
    return L


def cpa_time(dp, dv, eps_v: float = 0.25) -> float:
    """Time to the CPA of two straight lines (relative position dp, velocity dv); 0 unless ‖dv‖ ≥ ε_v and
    closing."""
    dot = dp[0] * dv[0] + dp[1] * dv[1]
    v2 = dv[0] * dv[0] + dv[1] * dv[1]
    if v2 > 0 and v2 >= eps_v * eps_v and dot < 0:
        return -dot / v2
    return 0.0


def velocity(state) -> tuple[float, float]:
    return state[3] * math.cos(state[2]), state[3] * math.sin(state[2])


def mcs_estimate(dp, dv, L, Zk, d_safe: float = 40.0, eps_v: float = 0.25,
                 event: str = "mean_cpa") -> tuple[float, float]:
    """(y, t_cpa of the means) at one step: the fraction of the samples x̄ + L z (z the rows of ``Zk [N, 4]``)
    in the event, sample by sample."""
    if event not in ("mean_cpa", "sample_cpa"):
        raise ValueError(f"event must be 'mean_cpa' or 'sample_cpa', got {event!r}")
    tc = cpa_time(dp, dv, eps_v)
    hits = 0
    for z in np.asarray(Zk, dtype=float):
        e = [sum(L[i, j] * z[j] for j in range(4)) for i in range(4)]
        sp = (dp[0] + e[0], dp[1] + e[1])
        sv = (dv[0] + e[2], dv[1] + e[3])
        t = tc if event == "mean_cpa" else cpa_time(sp, sv, eps_v)
        qx, qy = sp[0] + sv[0] * t, sp[1] + sv[1] * t
        hits += (qx * qx + qy * qy) <= d_safe * d_safe
    return hits / len(Zk), tc


# ------------------------------------------------------------------------------------------ exact values
def _phi(x: float) -> float:
    return 0.5 * math.erfc(-x / math.sqrt(2.0))


def disc_probability(mean, cov, R: float, n_panels: int = 400, n_gauss: int = 8) -> float:
    """P(‖X‖ ≤ R) for X ~ N(mean, cov) in 2-D: the covariance's eigen-frame, composite Gauss-Legendre over
    x = R sin θ along the wider axis, the normal CDF exactly across it (accurate to ~1e-10 for
    σ_max ≳ R/100)."""
    m, S = np.asarray(mean, float), np.asarray(cov, float)
    lam, V = np.linalg.eigh(S)
    s1, s2 = math.sqrt(max(lam[1], 0.0)), math.sqrt(max(lam[0], 0.0))
    m1, m2 = float(V[:, 1] @ m), float(V[:, 0] @ m)
    if s1 == 0.0:
        return 1.0 if m1 * m1 + m2 * m2 <= R * R else 0.0
    nodes, weights = np.polynomial.legendre.leggauss(n_gauss)
    total = 0.0
    edges = np.linspace(-0.5 * math.pi, 0.5 * math.pi, n_panels + 1)
    for a, b in zip(edges[:-1], edges[1:]):
        for u, w in zip(nodes, weights):
            th = 0.5 * (b - a) * u + 0.5 * (a + b)
            x, h = R * math.sin(th), R * math.cos(th)
            dens = math.exp(-0.5 * ((x - m1) / s1) ** 2) / (s1 * math.sqrt(2.0 * math.pi))
            if s2 > 0:
                across = _phi((h - m2) / s2) - _phi((-h - m2) / s2)
            else:
                across = 1.0 if -h <= m2 <= h else 0.0
            total += 0.5 * (b - a) * w * dens * across * R * math.cos(th)
    return min(max(total, 0.0), 1.0)


def disc_probability_isotropic(dist: float, sigma: float, R: float, tol: float = 1e-16) -> float:
    """P(‖X‖ ≤ R) for X ~ N(μ, σ² I₂), ‖μ‖ = dist: 1 − Q₁(dist/σ, R/σ) by the Poisson mixture of central χ²
    distributions, Σ_j Pois(j; λ/2) P(χ²_{2j+2} ≤ R²/σ²), λ = dist²/σ²."""
    half_lam, half_x = 0.5 * (dist / sigma) ** 2, 0.5 * (R / sigma) ** 2
    total, j = 0.0, 0
    # P(χ²_{2m} ≤ x) = 1 − e^{−x/2} Σ_{i<m} (x/2)^i / i!
    partial = 0.0                      # Σ_{i<=j} (x/2)^i/i! e^{-x/2}
    term_i = math.exp(-half_x)
    while True:
        partial += term_i
        cdf = max(1.0 - partial, 0.0)
        pois = math.exp(-half_lam + j * math.log(half_lam) - math.lgamma(j + 1)) if half_lam > 0 else float(j == 0)
        total += pois * cdf
        j += 1
        term_i *= half_x / j
        if j > half_lam + 10 and (pois < tol or cdf < tol) or j > 10000:
            break
    return total


def exact_probability(dp, dv, Sigma, d_safe: float = 40.0, eps_v: float = 0.25) -> float:
    """The exact probability of the ``"mean_cpa"`` event: with t = t_cpa of the means, the sample's relative
    position at t is Gaussian, mean dp + dv t, covariance A Σ Aᵀ with A = [I₂, t I₂]."""
    t = cpa_time(dp, dv, eps_v)
    S = np.asarray(Sigma, float)
    A = np.hstack([np.eye(2), t * np.eye(2)])
    return disc_probability(np.asarray(dp, float) + t * np.asarray(dv, float), A @ S @ A.T, d_safe)


# ------------------------------------------------------------------------------------------ eq. (20)
def pair_series(own_traj, tgt_traj, t, Sigma, Z, *, d_safe: float = 40.0, eps_v: float = 0.25,
                q_P: float = 5e-5, r_P: float = 1e-3, V0: float = 0.3, P0: float = 0.0, T_c: float = 6.0,
                K_coll: float = 1.0, d_cl: float = 200.0, event: str = "mean_cpa", stop_remedy: str = "none") -> dict:
    """Per step k = 0…N of one (own-ship trajectory, target trajectory) pair: ``y``, ``P`` (filtered),
    ``t_cpa``, ``coll`` (C ℙ̂ e^{−(t_k + t_cpa − t₀)/T_c}) and ``mu`` (Johansen's Boolean indicator; with
    ``stop_remedy="colregs_heading"`` the test on the heading, :func:`psbmpc_jax.reference.colregs_violation_heading`)."""
    own_traj, tgt_traj = np.asarray(own_traj, float), np.asarray(tgt_traj, float)
    L = cholesky4(Sigma)
    n = len(own_traj)
    y, tcs, C, mu = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    for k in range(n):
        own, tgt = own_traj[k], tgt_traj[k]
        vo, vi = velocity(own), velocity(tgt)
        dp = (tgt[0] - own[0], tgt[1] - own[1])
        dv = (vi[0] - vo[0], vi[1] - vo[1])
        y[k], tcs[k] = mcs_estimate(dp, dv, L, Z[k], d_safe, eps_v, event)
        C[k] = K_coll * (dv[0] ** 2 + dv[1] ** 2)
        if stop_remedy == "colregs_heading":
            mu[k] = 1.0 if colregs_violation_heading(own, tgt, d_cl) else 0.0
        else:
            mu[k] = colregs_boolean(own, tgt, d_cl)
    P = kf_filter(y, q_P, r_P, V0, P0)
    coll = np.array([C[k] * P[k] * math.exp(-(t[k] + tcs[k] - t[0]) / T_c) for k in range(n)])
    return {"y": y, "P": P, "t_cpa": tcs, "coll": coll, "mu": mu}


def situation_obstacles(situation, params, config) -> list:
    """``[(scenario trajectories [S, N+1, 4], probabilities [S], covariance [4, 4]), ...]`` of a situation's
    obstacles (the sequential reference's scenario rollouts; an obstacle with weight 0 gets probability 0)."""
    from .reference_prediction import obstacle_scenarios

    out = []
    for ob in situation.obstacles:
        probs = np.asarray(ob.probs, float) * (1.0 if float(ob.weight) > 0 else 0.0)
        out.append((obstacle_scenarios(ob, params, config), probs, np.asarray(ob.cov, float)))
    return out


def psbmpc2020_cost(own_traj, obstacles, t, Z, *, kappa: float = 10.0, include_t0: bool = True,
                    **pair_kw) -> dict:
    """Eq. (20) without f and g for one own-ship trajectory ``[T, 4]``.

    ``obstacles``: a list of ``(scenario_trajs [n_ps, T, 4], probs [n_ps], Sigma [4, 4])``; probabilities are
    normalised per obstacle (an obstacle whose probabilities sum to 0 counts 0).  ``Z [T, N_MC, 4]`` the
    standard normals.  The sums run over k = 0…N (``include_t0``) or k = 1…N.

    Returns ``{"value": max_i h_i (0 without obstacles), "h": [h_i], "bracket": [[h_is]], "coll": [[…]],
    "colregs": [[…]]}``."""
    k0 = 0 if include_t0 else 1
    out: dict[str, Any] = {"h": [], "bracket": [], "coll": [], "colregs": []}
    for trajs, probs, Sigma in obstacles:
        probs = np.asarray(probs, float)
        tot = float(np.sum(probs))
        brackets, colls, cols = [], [], []
        h = 0.0
        for s, traj in enumerate(trajs):
            ser = pair_series(own_traj, traj, t, Sigma, Z, **pair_kw)
            coll = sum(ser["coll"][k] for k in range(k0, len(t)))
            col = kappa * sum(ser["mu"][k] for k in range(k0, len(t)))
            brackets.append(coll + col)
            colls.append(coll)
            cols.append(col)
            if tot > 0:
                h += probs[s] / tot * (coll + col)
        out["h"].append(h)
        out["bracket"].append(brackets)
        out["coll"].append(colls)
        out["colregs"].append(cols)
    out["value"] = max(out["h"]) if out["h"] else 0.0
    return out


__all__ = ["kf_gains", "kf_filter", "kf_matrix", "cholesky4", "cpa_time", "velocity", "mcs_estimate",
           "disc_probability", "disc_probability_isotropic", "exact_probability", "pair_series",
           "psbmpc2020_cost"]
