"""Collision probability estimators (the probability P̂_c of Tengesdal et al. 2022, eq. 12; docs/algorithm.md §7).

All estimators take point pairs in *relative* form — ``dx, dy`` = obstacle mean minus own-ship position,
the obstacle positional covariance ``(sxx, sxy, syy)`` and the disc radius ``R`` — as arrays of any common
broadcast shape, and return P̂ of that shape.  The sigma shortcut (P̂ = 0 beyond R + c_σ σ_max) is applied
by the evaluator, which sends only the points that pass it here.

Random numbers are explicit: :func:`standard_normal_table` draws the common-random-number table from a key.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np

from ..layouts import resolve_pc_layout
from ..numerics import normal_cdf, ordered_sum, safe_sqrt
from .base import Context, TermValue, cost_term

LOG_2PI = math.log(2.0 * math.pi)


def standard_normal_table(key, config, dtype=None):
    """Common random numbers for ``mc`` (``[n_samples, 2]``) or ``ce`` (``[ce_max_iter + 1, n_samples, 2]``).

    Returns ``None`` for ``quadrature``.  ``key`` must be a JAX PRNG key (no default key exists)."""
    if config.estimator == "quadrature":
        return None
    if key is None:
        raise ValueError(f"estimator {config.estimator!r} needs an explicit PRNG key (key=jax.random.key(...))")
    dtype = dtype or jnp.dtype(config.dtype)
    if config.estimator == "mc":
        return jax.random.normal(key, (config.n_samples, 2), dtype)
    return jax.random.normal(key, (config.ce_max_iter + 1, config.n_samples, 2), dtype)


def _cholesky2(sxx, sxy, syy):
    l00 = jnp.sqrt(sxx)
    l10 = sxy / l00
    l11 = safe_sqrt(syy - l10 * l10)
    return l00, l10, l11


def pc_quadrature(dx, dy, sxx, sxy, syy, R, n_quad: int = 32, span: float = 6.0):
    """Gauss-Legendre along the line through the obstacle mean, exact (erf) across it."""
    t_np, w_np = np.polynomial.legendre.leggauss(n_quad)
    t, w = jnp.asarray(t_np, dx.dtype), jnp.asarray(w_np, dx.dtype)
    R = jnp.broadcast_to(R, jnp.shape(dx))
    d = safe_sqrt(dx * dx + dy * dy)                                   # finite gradient at d = 0
    pos = d > 0
    d_safe = jnp.where(pos, d, 1.0)
    ux, uy = jnp.where(pos, dx / d_safe, 1.0), jnp.where(pos, dy / d_safe, 0.0)
    vx, vy = -uy, ux
    s_uu = ux * ux * sxx + 2 * ux * uy * sxy + uy * uy * syy
    s_uv = ux * vx * sxx + (ux * vy + uy * vx) * sxy + uy * vy * syy
    s_vv = vx * vx * sxx + 2 * vx * vy * sxy + vy * vy * syy
    sx = jnp.sqrt(s_uu)
    s = safe_sqrt(s_vv - s_uv * s_uv / s_uu)
    a = jnp.maximum(-R, d - span * sx)
    b = jnp.minimum(R, d + span * sx)
    nonempty = a < b
    # half-angle substitution x = 2Ru/(1+u^2): rational (no trig per node) and it removes the square-root
    # end-point behaviour of the chord half-width h = sqrt(R^2 - x^2) = R(1-u^2)/(1+u^2)
    # safe_sqrt: a or b clamped at +-R (or beyond R when the window misses the disc) must not give
    # 0 * inf = NaN gradients
    u_a = a / (R + safe_sqrt(R * R - a * a))
    u_b = b / (R + safe_sqrt(R * R - b * b))
    half = 0.5 * (u_b - u_a)
    mid = 0.5 * (u_b + u_a)
    u = half[..., None] * t + mid[..., None]                         # [..., n_quad]
    q = 1.0 / (1.0 + u * u)
    x = 2.0 * R[..., None] * u * q
    h = R[..., None] * (1.0 - u * u) * q
    m = (s_uv / s_uu)[..., None] * (x - d[..., None])
    dens = jnp.exp(-0.5 * (x - d[..., None]) ** 2 / s_uu[..., None]) / jnp.sqrt(2 * math.pi * s_uu)[..., None]
    s_e = s[..., None]
    if dx.dtype == jnp.float64:
        inner = normal_cdf((h - m) / s_e) - normal_cdf((-h - m) / s_e)
    else:
        # float32: XLA's polynomial erf (no exp) is ~3x cheaper than ndtr; absolute error ~1e-7
        inv = 1.0 / (math.sqrt(2.0) * s_e)
        inner = 0.5 * (jax.lax.erf((h - m) * inv) + jax.lax.erf((h + m) * inv))
    p = half * ordered_sum(w * dens * inner * (2.0 * h * q), first_axis=-1)
    return jnp.where(nonempty, jnp.clip(p, 0.0, 1.0), 0.0)


@jax.custom_jvp
def pc_mc(dx, dy, sxx, sxy, syy, R, z):
    """Plain Monte Carlo with the shared table ``z [N_s, 2]``.

    Derivative: the estimate itself is piecewise constant in ``dx, dy`` (a sample-indicator average); its
    derivative (a custom JVP, :func:`_score_tangent`) is the score-function estimate of the derivative of
    the probability it estimates, from the same samples — unbiased, and equal to the quadrature estimator's
    derivative up to sampling error."""
    return _mc_samples(dx, dy, sxx, sxy, syy, R, z)[0]


def _mc_samples(dx, dy, sxx, sxy, syy, R, z):
    """P̂ and the per-sample indicators and offsets ``(rx, ry) = L z`` from the obstacle mean."""
    l00, l10, l11 = _cholesky2(sxx, sxy, syy)
    rx = l00[..., None] * z[:, 0]
    ry = l10[..., None] * z[:, 0] + l11[..., None] * z[:, 1]
    ex = dx[..., None] + rx
    ey = dy[..., None] + ry
    r2 = jnp.broadcast_to(R * R, jnp.shape(dx))[..., None]
    inside = (ex * ex + ey * ey) <= r2
    return jnp.mean(inside.astype(dx.dtype), axis=-1), inside, rx, ry


@pc_mc.defjvp
def _pc_mc_jvp(primals, tangents):
    dx, dy, sxx, sxy, syy, R, z = primals
    p, inside, rx, ry = _mc_samples(dx, dy, sxx, sxy, syy, R, z)
    return p, _score_tangent(inside.astype(p.dtype), rx, ry, primals[:6], tangents[:6], p.shape)


def _score_tangent(weight, rx, ry, primals, tangents, shape):
    """Score-function (likelihood-ratio) tangent of P = Pr(|mu + e| <= R), e ~ N(0, S), mu = (dx, dy).

    ``weight [..., N_s]``: each sample's term of the estimate (the indicator for mc; indicator times the
    importance weight for ce), ``rx, ry``: the sample minus the obstacle mean.  With s = S⁻¹ r:
    dP/dmu = E[w s], dP/dS = ½ E[w (s sᵀ − S⁻¹)] (S symmetric: the sxy entry counts twice), and R from the
    scale invariance P(a mu, a² S, a R) = P(mu, S, R): dP/dR = −(mu·dP/dmu + 2 S:dP/dS) / R.  The samples
    and everything that only shapes the proposal are constants (their tangent is ignored): the random
    numbers are fixed, and the importance-sampling identity holds for any proposal.  Where S is not
    positive definite or R <= 0 (padding) the tangent is 0."""
    dx, dy, sxx, sxy, syy, R = (jnp.broadcast_to(a, shape) for a in primals)
    det = sxx * syy - sxy * sxy
    ok = (det > 0) & (sxx > 0)
    det_s = jnp.where(ok, det, 1.0)
    ixx, ixy, iyy = syy / det_s, -sxy / det_s, sxx / det_s
    okn = ok[..., None]
    # NaN offsets / weights of a degenerate S: no tangent
    rx, ry, weight = (jnp.where(okn & jnp.isfinite(a), a, 0.0) for a in (rx, ry, weight))
    sx = ixx[..., None] * rx + ixy[..., None] * ry
    sy = ixy[..., None] * rx + iyy[..., None] * ry
    mean = lambda a: jnp.mean(weight * a, axis=-1)                             # noqa: E731
    w0 = jnp.mean(weight, axis=-1)
    g_x, g_y = mean(sx), mean(sy)
    g_xx = 0.5 * (mean(sx * sx) - ixx * w0)
    g_xy = 0.5 * (mean(sx * sy) - ixy * w0)
    g_yy = 0.5 * (mean(sy * sy) - iyy * w0)
    r_ok = R > 0
    g_r = -(dx * g_x + dy * g_y + 2.0 * (sxx * g_xx + 2.0 * sxy * g_xy + syy * g_yy)) / jnp.where(r_ok, R, 1.0)
    # masked coefficients (not a masked result): reverse mode multiplies the cotangent by them
    coefs = (g_x, g_y, g_xx, 2.0 * g_xy, g_yy, jnp.where(r_ok, g_r, 0.0))
    out = sum(jnp.where(ok, c, 0.0) * jnp.broadcast_to(t, shape) for c, t in zip(coefs, tangents))
    return out.astype(w0.dtype)


def _inv_logdet2(sxx, sxy, syy):
    det = sxx * syy - sxy * sxy
    return syy / det, -sxy / det, sxx / det, jnp.log(det)


@jax.custom_jvp
def pc_ce(dx, dy, sxx, sxy, syy, R, z, rho, alpha, chi2):
    """Cross-Entropy importance sampling with the shared table ``z [I+1, N_s, 2]`` (own-ship at origin).

    Derivative: as :func:`pc_mc`, the score-function estimate from the final importance-sampling pass (the
    proposal, fitted from independent samples, is held fixed: the identity holds for any proposal); 0 where
    the estimate is clipped at 1.

    The ``I`` refit iterations are unrolled: a ``while_loop`` that stops once every point is done was measured
    slower on the CPU (C++-test-like situation, 1 014 / 7 098 behaviours: 73 / 583 ms against 52 / 534 ms,
    ``benchmarks/bench_cpu_targets.py``), since in a chunk of thousands of points some point always needs
    every iteration and the loop keeps XLA from fusing across iterations."""
    return _ce_samples(dx, dy, sxx, sxy, syy, R, z, rho, alpha, chi2)[0]


def _ce_samples(dx, dy, sxx, sxy, syy, R, z, rho, alpha, chi2):
    """P̂ (clipped at 1), the unclipped mean, each final sample's weight (0 outside the disc) and its offset
    ``(qx, qy)`` from the obstacle mean.

    Every sample is ``x = m + L z`` (L the proposal's Cholesky factor), so the proposal's Mahalanobis distance of
    a sample is ``|z|^2`` and the elite moments of a refit are those of the table's ``z`` mapped through ``L``
    (:func:`_ce_refit`): per sample only the elite / inside tests and the importance weight are computed."""
    n_iter = z.shape[0] - 1
    R = jnp.broadcast_to(R, dx.shape)
    ixx, ixy, iyy, logdet = _inv_logdet2(sxx, sxy, syy)
    cxx = R * R / 3.0
    prop = (0.5 * dx, 0.5 * dy, cxx, jnp.zeros_like(dx), cxx, jnp.zeros(dx.shape, bool))
    for it in range(n_iter):
        prop = _ce_refit(z[it], dx, dy, R, (ixx, ixy, iyy), prop, rho, alpha, chi2)
    mx, my, cxx, cxy, cyy, _ = prop
    l00, l10, l11 = _cholesky2(cxx, cxy, cyy)
    px, py, qx, qy = _ce_draw(z[n_iter], mx, my, l00, l10, l11, dx, dy)
    maha_o = ixx[..., None] * qx * qx + 2 * ixy[..., None] * qx * qy + iyy[..., None] * qy * qy
    # the proposal's own Mahalanobis distance of x = m + L z is |z|^2; log det of L L^T is 2 log(l00 l11)
    maha_c = z[n_iter, :, 0] * z[n_iter, :, 0] + z[n_iter, :, 1] * z[n_iter, :, 1]
    logdet_c = 2.0 * jnp.log(l00 * l11)
    logw = -0.5 * (maha_o - maha_c) - 0.5 * (logdet - logdet_c)[..., None]
    inside = (px * px + py * py) <= (R * R)[..., None]
    w = jnp.where(inside, jnp.exp(jnp.where(inside, logw, 0.0)), 0.0)
    raw = jnp.mean(w, axis=-1)
    return jnp.minimum(1.0, raw), raw, w, qx, qy


def _ce_draw(zi, mx, my, l00, l10, l11, dx, dy):
    """The samples ``x = m + L z`` of the table ``zi [N_s, 2]`` (``[..., N_s]``) and their offsets from the
    obstacle mean."""
    px = mx[..., None] + l00[..., None] * zi[:, 0]
    py = my[..., None] + l10[..., None] * zi[:, 0] + l11[..., None] * zi[:, 1]
    return px, py, px - dx[..., None], py - dy[..., None]


@pc_ce.defjvp
def _pc_ce_jvp(primals, tangents):
    p, raw, w, qx, qy = _ce_samples(*primals)
    tangent = _score_tangent(w, qx, qy, primals[:6], tangents[:6], p.shape)
    return p, jnp.where(raw < 1.0, tangent, 0.0)


def _ce_refit(zi, dx, dy, R, inv, prop, rho, alpha, chi2):
    """One Cross-Entropy iteration with the samples ``zi [N_s, 2]``: the proposal ``(mx, my, cxx, cxy, cyy,
    done)`` refitted to its elite samples where the point is not done, converged or short of elites.

    The elite samples' mean and covariance come from their moments in ``z`` (count, sums of z and of its
    products: one product of the elite mask with a ``[N_s, 6]`` table, a matrix product) mapped through the
    proposal's ``m + L z``: the same moments as summing the samples themselves, without a second pass over
    them."""
    mx, my, cxx, cxy, cyy, done = prop
    ixx, ixy, iyy = inv
    n_s = zi.shape[0]
    l00, l10, l11 = _cholesky2(cxx, cxy, cyy)
    px, py, qx, qy = _ce_draw(zi, mx, my, l00, l10, l11, dx, dy)
    maha = ixx[..., None] * qx * qx + 2 * ixy[..., None] * qx * qy + iyy[..., None] * qy * qy
    elite = ((px * px + py * py) <= (R * R)[..., None]) & (maha <= chi2)
    z0, z1 = zi[:, 0], zi[:, 1]
    table = jnp.stack([jnp.ones_like(z0), z0, z1, z0 * z0, z0 * z1, z1 * z1], axis=-1)     # [N_s, 6]
    mom = jnp.matmul(elite.astype(dx.dtype), table, precision=jax.lax.Precision.HIGHEST)
    n_e = mom[..., 0]
    converged = n_e >= rho * n_s
    refit = (~done) & (~converged) & (n_e >= 3)
    n_safe = jnp.maximum(n_e, 1.0)
    a0, a1 = mom[..., 1] / n_safe, mom[..., 2] / n_safe                     # elite mean of z
    # elite covariance of z (the variances' rounding may not take them below 0)
    c00 = jnp.maximum(mom[..., 3] / n_safe - a0 * a0, 0.0)
    c01 = mom[..., 4] / n_safe - a0 * a1
    c11 = jnp.maximum(mom[..., 5] / n_safe - a1 * a1, 0.0)
    ex_ = mx + l00 * a0                                                      # ... mapped through m + L z
    ey_ = my + l10 * a0 + l11 * a1
    sxx_e = l00 * l00 * c00
    sxy_e = l00 * (l10 * c00 + l11 * c01)
    syy_e = l10 * l10 * c00 + 2.0 * l10 * l11 * c01 + l11 * l11 * c11
    mx = jnp.where(refit, alpha * ex_ + (1 - alpha) * mx, mx)
    my = jnp.where(refit, alpha * ey_ + (1 - alpha) * my, my)
    cxx = jnp.where(refit, alpha * sxx_e + (1 - alpha) * cxx, cxx)
    cxy = jnp.where(refit, alpha * sxy_e + (1 - alpha) * cxy, cxy)
    cyy = jnp.where(refit, alpha * syy_e + (1 - alpha) * cyy, cyy)
    return mx, my, cxx, cxy, cyy, done | ~refit


def collision_probability(dx, dy, sxx, sxy, syy, R, params, config, samples=None):
    """Dispatch on ``config.estimator`` (no shortcut applied here)."""
    if config.estimator == "quadrature":
        return pc_quadrature(dx, dy, sxx, sxy, syy, R, config.n_quad, config.quad_span)
    if samples is None:
        raise ValueError(f"estimator {config.estimator!r} needs the standard normal table `samples`")
    if config.estimator == "mc":
        return pc_mc(dx, dy, sxx, sxy, syy, R, samples)
    if config.estimator == "ce":
        return pc_ce(dx, dy, sxx, sxy, syy, R, samples, params.ce_rho, params.ce_alpha, params.ce_chi2)
    raise ValueError(f"estimator must be one of ('quadrature', 'mc', 'ce'), got {config.estimator!r}")


# ------------------------------------------------------------------------------------------- the term
def _pad_time(a, t_pad: int):
    """Pad the (leading) time axis at the end by repeating the last sample."""
    if t_pad == 0:
        return a
    return jnp.pad(a, [(0, t_pad)] + [(0, 0)] * (a.ndim - 1), mode="edge")


def pair_geometry(ctx: Context):
    """Time-major relative geometry of every (time, obstacle·scenario, row) point: obstacle minus own-ship
    position ``dx, dy [T, O·S, B]`` and a mask ``live`` of real scenarios.  Shared (through XLA's CSE) by the
    collision and COLREGS terms."""
    n_t = ctx.own.x.shape[0]
    n_os = ctx.obstacles.x.shape[1] * ctx.obstacles.x.shape[2]
    qx, qy = ctx.obstacles.x.reshape(n_t, n_os), ctx.obstacles.y.reshape(n_t, n_os)
    dx = qx[:, :, None] - ctx.own.x[:, None, :]
    dy = qy[:, :, None] - ctx.own.y[:, None, :]
    return dx, dy, ctx.scen_valid.reshape(n_os)


#: Rows per chunk of the tail of the compact collision kernel (see :func:`collision_kernel`).
TAIL_ROWS = 64


def collision_kernel(ctx: Context, params, config, samples):
    """C [B, O·S] = max_k ζ_i K_coll ‖v_0 − v_i‖² P̂ e^{−t_k/T_d} over the points that pass the σ-shortcut
    (distance ≤ R + c_σ σ_max), the same maximum over the future steps k ≥ 1 only (``C_future``: k = 0 is the
    present, the same for every behaviour; used by the selection, docs/algorithm.md §11), and the number of
    (row, time-block) pairs the estimator evaluated.

    Everything is time-major ([T, O·S, B]): reductions over time run over the leading axis, so the inner,
    vectorised axis is always the long behaviour axis (measured 2x faster than [B, O·S, T] on XLA:CPU).

    Layouts (``config.pc_layout``, "auto": :func:`psbmpc_jax.layouts.resolve_pc_layout`): ``ctx.dense`` or
    ``"dense"`` evaluates every point (differentiable; the
    shortcut is a ``where``).  Otherwise ("compact", the grid search's fast path) a cheap dense pass finds
    the points that pass the shortcut, the (row, time-block) pairs holding one are compacted and only those
    are sent through the (expensive) estimator: full chunks of ``chunk_rows`` items while at least that many
    are left, then the rest in chunks of :data:`TAIL_ROWS` (64), so a small problem (77 items, say) pays for
    at most 63 padding items instead of ``chunk_rows - 1``.  Every item's value is the same whichever chunk
    computes it (the maximum into the accumulators does not depend on the order)."""
    own, obs, t = ctx.own, ctx.obstacles, ctx.t
    n_t, n_b = own.x.shape
    n_o, n_s = obs.x.shape[1:]
    n_os = n_o * n_s
    tb = min(config.time_block, n_t)
    n_blk = -(-n_t // tb)
    t_pad = n_blk * tb - n_t
    dtype = own.x.dtype

    t_valid = jnp.arange(n_blk * tb) < n_t
    disc = _pad_time(jnp.exp(-t / params.T_d), t_pad)                          # [Tp]
    px, py = _pad_time(own.x, t_pad), _pad_time(own.y, t_pad)                   # [Tp, B]
    vx, vy = _pad_time(own.vx, t_pad), _pad_time(own.vy, t_pad)
    flat = lambda a: _pad_time(a.reshape(n_t, n_os), t_pad)                     # [Tp, O·S]
    wx, wy = flat(obs.vx), flat(obs.vy)
    sxx, sxy, syy, smax = (_pad_time(c.T, t_pad) for c in ctx.cov_stats)       # [Tp, O]
    rep_s = lambda a: jnp.repeat(a, n_s, axis=-1)                               # [..., O] -> [..., O·S]
    r_os = rep_s(ctx.radius)                                                    # [O·S]
    thr_os = rep_s(ctx.radius[None, :] + params.c_sigma * smax)                 # [Tp, O·S]
    zk_os = rep_s(ctx.zeta_k)

    dx, dy, valid_os = pair_geometry(ctx)
    dx, dy = _pad_time(dx, t_pad), _pad_time(dy, t_pad)
    live = t_valid[:, None, None] & valid_os[None, :, None]
    active = (dx * dx + dy * dy <= (thr_os ** 2)[:, :, None]) & live

    def point_terms(dx, dy, dvx, dvy, s_xx, s_xy, s_yy, rad, zk, dsc, act):
        p = collision_probability(dx, dy, s_xx, s_xy, s_yy, rad, params, config, samples)
        return jnp.where(act, zk * (dvx * dvx + dvy * dvy) * p * dsc, 0.0)

    width = {"quadrature": config.n_quad, "mc": config.n_samples}.get(
        config.estimator, config.n_samples * (config.ce_max_iter + 1))
    layout = resolve_pc_layout(config.pc_layout, n_t * n_os * n_b, width, getattr(config, "layout_platform", None))
    if ctx.dense or layout == "dense":
        o_of = jnp.arange(n_os) // n_s
        terms = point_terms(dx, dy, wx[:, :, None] - vx[:, None], wy[:, :, None] - vy[:, None],
                            sxx[:, o_of, None], sxy[:, o_of, None], syy[:, o_of, None], r_os[None, :, None],
                            zk_os[None, :, None], disc[:, None, None], active)
        n_blocks = jnp.sum(jnp.any(active.reshape(n_blk, tb, n_os, n_b), axis=1))
        return jnp.max(terms, axis=0).T, jnp.max(terms[1:], axis=0).T, n_blocks

    # compact: the (row, time-block) pairs holding an active point, per row (o·s, l) from its first to its
    # last such block (one contiguous run of items per row), enumerated by a cumsum over the rows
    blk_act = jnp.any(active.reshape(n_blk, tb, n_os, n_b), axis=1)             # [nblk, O·S, B]
    b_all = jnp.arange(n_blk, dtype=jnp.int32)[:, None, None]
    b_first = jnp.min(jnp.where(blk_act, b_all, n_blk), axis=0).reshape(-1)     # rows ordered (o·s, l)
    b_last = jnp.max(jnp.where(blk_act, b_all, -1), axis=0).reshape(-1)
    n_items = jnp.maximum(b_last - b_first + 1, 0).astype(jnp.int32)
    ends = jnp.cumsum(n_items)
    total_items = ends[-1]
    blk3 = lambda a: a.reshape((n_blk, tb) + a.shape[1:])                       # [nblk, tb, ...]
    px3, py3, vx3, vy3 = blk3(px), blk3(py), blk3(vx), blk3(vy)
    qx3, qy3 = blk3(flat(obs.x)), blk3(flat(obs.y))
    wx3, wy3, thr3 = blk3(wx), blk3(wy), blk3(thr_os)
    sxx3, sxy3, syy3 = blk3(sxx), blk3(sxy), blk3(syy)
    disc2, tval2 = disc.reshape(n_blk, tb), t_valid.reshape(n_blk, tb)
    future2 = (jnp.arange(n_blk * tb) >= 1).reshape(n_blk, tb)                  # k >= 1

    def run(chunk: int, start, stop, accs):
        """Items ``start .. stop-1`` (``stop - start`` a multiple of ``chunk`` or the last, partial chunk)."""
        def body(state):
            q0, acc, acc_f = state
            q = q0 + jnp.arange(chunk, dtype=jnp.int32)
            ok = q < total_items
            row = jnp.minimum(jnp.searchsorted(ends, q, side="right"), n_b * n_os - 1).astype(jnp.int32)
            blk = jnp.where(ok, b_first[row] + q - (ends[row] - n_items[row]), 0)
            os_, l = row // n_b, row % n_b
            o = os_ // n_s
            g = lambda a3, idx: a3[blk, :, idx]                                 # [chunk, tb] windows
            dx_ = g(qx3, os_) - g(px3, l)
            dy_ = g(qy3, os_) - g(py3, l)
            act = (dx_ * dx_ + dy_ * dy_ <= g(thr3, os_) ** 2) & tval2[blk] & ok[:, None]
            # materialise the gathered windows once: otherwise XLA may fuse the gathers into the estimator's
            # per-sample loop and redo them for every sample (measured 3x slower for mc)
            win = jax.lax.optimization_barrier(
                (dx_, dy_, g(wx3, os_) - g(vx3, l), g(wy3, os_) - g(vy3, l), g(sxx3, o), g(sxy3, o), g(syy3, o),
                 act))
            terms = point_terms(*win[:7], r_os[os_][:, None], zk_os[os_][:, None], disc2[blk], win[7])
            acc = acc.at[row].max(jnp.where(ok, jnp.max(terms, axis=-1), 0.0))
            acc_f = acc_f.at[row].max(jnp.where(ok, jnp.max(jnp.where(future2[blk], terms, 0.0), axis=-1), 0.0))
            return q0 + chunk, acc, acc_f

        state = jax.lax.while_loop(lambda st: st[0] < stop, body, (start, *accs))
        return state[1:]

    acc0 = (jnp.zeros((n_os * n_b,), dtype), jnp.zeros((n_os * n_b,), dtype))
    chunk = config.chunk_rows
    if chunk <= TAIL_ROWS:
        accs = run(chunk, jnp.int32(0), total_items, acc0)
    else:
        bulk = (total_items // chunk) * chunk                                   # full chunks
        accs = run(chunk, jnp.int32(0), bulk, acc0)
        accs = run(TAIL_ROWS, bulk, total_items, accs)                          # the rest, < chunk items
    acc, acc_f = accs
    return acc.reshape(n_os, n_b).T, acc_f.reshape(n_os, n_b).T, total_items


@cost_term
class CollisionTerm:
    """H_do = Σ_i w_i Σ_s P_s C_s^{l,i} (eqs. 10, 14): the collision probability of each (obstacle,
    scenario) times the kinetic-energy factor ζ_i K_coll ‖v_0 − v_i‖² and the discount e^{−t/T_d}, maximised
    over time, with the σ-shortcut.  Details: ``C [B, O, S]`` and ``C_future [B, O, S]`` (the same maximum over
    k >= 1 only; the selection's present-hazard rule, docs/algorithm.md §11); counter ``n_pc_blocks``."""

    name = "do"
    PARAMS = ("d_safe", "K_coll", "T_d", "c_sigma", "ce_rho", "ce_alpha", "ce_chi2")
    smooth = True            # with the quadrature estimator (mc and ce are piecewise constant in the controls;
    #                          their derivative is a score-function estimate: pc_mc, pc_ce)

    def __call__(self, ctx: Context, params, config, samples) -> TermValue:
        n_o, n_s = ctx.scen_weight.shape
        c_flat, cf_flat, n_blocks = collision_kernel(ctx, params, config, samples)
        c = c_flat.reshape(-1, n_o, n_s)
        return TermValue(ordered_sum(ctx.scen_weight[None] * c),
                         {"C": c, "C_future": cf_flat.reshape(-1, n_o, n_s)}, {"n_pc_blocks": n_blocks})
