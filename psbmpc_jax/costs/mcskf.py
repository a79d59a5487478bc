"""The collision-risk method of Tengesdal, Brekke & Johansen (2020, Secs. 4–6, eqs. 14–20;
docs/mcskf.md): a Monte-Carlo estimate of a 4-D straight-line CPA collision probability at every prediction
step, filtered along the horizon by a scalar Kalman filter (MCS + KF), and the PSB-MPC cost of eq. (20).

Pure, vectorised ``jax.numpy`` (jit / vmap friendly, float32 and float64); NED: x north, y east [m],
courses [rad] clockwise from north, velocities (V_x, V_y) = U (cos χ, sin χ) [m/s].

Pieces:

* :func:`kf_gains`, :func:`kf_weights`, :func:`kf_filter`: the scalar KF of eq. (18) (random-walk model,
  prior ℙ⁻₀ = P0 with variance V0).  The gains do not depend on the data, so the filtered sequence is a fixed
  linear map, ℙ̂ = W·y + b·P0, W lower-triangular with W[k, j] = K_j Π_{m=j+1}^{k} (1 − K_m) and
  b[k] = Π_{m=0}^{k} (1 − K_m) (the clip at 1 of the recursive form never binds for y, P0 ∈ [0, 1]).
* :func:`normal_table`: the common-random-number table Z [T, N_MC, 4] (independent across steps, shared by
  every behaviour and obstacle).
* :func:`cholesky4`: a semi-definite-safe Cholesky factor (a zero pivot gives a zero column, no NaN).
* :func:`cpa_time`: the CPA time of the straight-line means, with the relative-speed floor ε_v.
* :func:`mcs_estimates`: y = the fraction of samples x̄ + L z inside the safety zone, for the two readings of
  the event (``event="mean_cpa"``: at the CPA time of the means, our reading, the one that reproduces the paper's Fig.
  3; ``"sample_cpa"``: each sample's own CPA distance, the alternative reading).
* :class:`Psbmpc2020Term` (``"psbmpc2020"``): eq. (20) on the evaluator's :class:`~.base.Context`.

The float64 oracle is :mod:`psbmpc_jax.reference_mcskf`.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .base import Context, TermValue, cost_term
from .colregs_fuzzy import check_choice, check_param
from .colregs import stop_remedy
from .sbmpc import colregs_boolean_xy

#: Readings of the collision event 𝒮 (eq. 19; docs/mcskf.md): ``"mean_cpa"`` (our choice) and ``"sample_cpa"`` (the
#: alternative).
EVENTS = ("mean_cpa", "sample_cpa")

# Table 1 of the paper where it gives a value, otherwise our proposal (docs/mcskf.md).
DEFAULT_N_MC = 100
DEFAULT_Q_P = 5e-5
DEFAULT_R_P = 1e-3
DEFAULT_V0 = 0.3
DEFAULT_P0 = 0.0
DEFAULT_T_C = 6.0
DEFAULT_D_SAFE = 40.0
DEFAULT_K_COLL = 1.0          # not in the paper: our proposal
DEFAULT_KAPPA = 10.0
DEFAULT_D_CL = 200.0          # not in the paper: our proposal
DEFAULT_EPS_V = 0.25          # our proposal: the authors' calculate_cpa relative-speed floor [m/s]

#: Relative pivot threshold of :func:`cholesky4` (times the machine epsilon and the largest diagonal entry).
CHOL_TOL = 64.0


# ------------------------------------------------------------------------------------------ the scalar KF
def kf_gains(n: int, q_P=DEFAULT_Q_P, r_P=DEFAULT_R_P, V0=DEFAULT_V0, dtype=None):
    """Kalman gains K [n] of the scalar random-walk filter (18): V⁻₀ = V0, K_k = V⁻_k / (V⁻_k + r_P),
    V_k = (1 − K_k) V⁻_k, V⁻_{k+1} = V_k + q_P.  Data-independent.  With the paper's q_P = 5e-5,
    r_P = 1e-3, V0 = 0.3: 0.9967, 0.5114, 0.3596, 0.2906, … → 0.200."""
    if isinstance(n, bool) or not isinstance(n, int) or n < 0:
        raise ValueError(f"n must be a non-negative integer (number of steps), got {n!r}")
    check_param("q_P", q_P, lo=0.0)
    check_param("r_P", r_P, lo=0.0, lo_open=True)
    check_param("V0", V0, lo=0.0)
    dtype = dtype or jnp.result_type(q_P, r_P, V0, float)
    q, r, v0 = (jnp.asarray(a, dtype) for a in (q_P, r_P, V0))

    def step(v_prior, _):
        k = v_prior / (v_prior + r)
        # V_k = (1 − K_k) V⁻_k written as K_k r_P (the same number): 1 − K_0 ≈ 0.003 cancels about 2.5 digits,
        # which cost float32 up to 1e-5 relative error on a GPU (2e-6 on the CPU); K r_P has no cancellation
        return k * r + q, k

    _, K = jax.lax.scan(step, v0, None, length=n)
    return K


def kf_weights(K):
    """``(W [n, n], b [n])`` with ℙ̂ = W·y + b·P0 equal to the recursive filter: W[k, j] = K_j Π_{m=j+1}^{k}
    (1 − K_m) for j ≤ k (0 above the diagonal), b[k] = Π_{m=0}^{k} (1 − K_m).  Computed from one cumulative
    sum of log(1 − K) (the products of a row are differences of it)."""
    K = jnp.asarray(K)
    n = K.shape[0]
    c = jnp.cumsum(jnp.log1p(-K))                                   # c[k] = Σ_{m<=k} log(1 - K_m)
    k, j = jnp.arange(n)[:, None], jnp.arange(n)[None, :]
    low = j <= k
    W = jnp.where(low, K[None, :] * jnp.exp(jnp.where(low, c[:, None] - c[None, :], 0.0)), 0.0)
    return W, jnp.exp(c)


def smoothing_matrix(n: int, q_P=DEFAULT_Q_P, r_P=DEFAULT_R_P, V0=DEFAULT_V0, dtype=None):
    """The fixed lower-triangular W [n, n] of :func:`kf_weights` for these filter parameters."""
    return kf_weights(kf_gains(n, q_P, r_P, V0, dtype))[0]


def kf_filter(y, K, P0=DEFAULT_P0):
    """The recursive form along the leading axis of ``y [n, ...]``: ℙ⁻₀ = P0; ℙ̂_k = min(ℙ⁻_k + K_k (y_k − ℙ⁻_k),
    1); ℙ⁻_{k+1} = ℙ̂_k.  Equal to ``W·y + b·P0`` (:func:`kf_weights`) for y, P0 ∈ [0, 1]."""
    y = jnp.asarray(y)
    K = jnp.asarray(K, y.dtype)

    def step(p_prior, inp):
        k, yk = inp
        p = jnp.minimum(p_prior + k * (yk - p_prior), 1.0)
        return p, p

    _, out = jax.lax.scan(step, jnp.broadcast_to(jnp.asarray(P0, y.dtype), y.shape[1:]), (K, y))
    return out


def kf_apply(y, K, P0=DEFAULT_P0):
    """ℙ̂ = min(W·y + b·P0, 1) along the leading axis of ``y [n, ...]`` (one matrix product)."""
    y = jnp.asarray(y)
    W, b = kf_weights(jnp.asarray(K, y.dtype))
    p = jnp.tensordot(W, y, axes=(1, 0)) + (b * P0).reshape((-1,) + (1,) * (y.ndim - 1))
    return jnp.minimum(p, 1.0)


# ------------------------------------------------------------------------------------------ sampling
def normal_table(key, n_steps_plus_1: int, n_mc: int = DEFAULT_N_MC, dtype=None):
    """The standard-normal table Z [T, N_MC, 4] (independent samples per step k, shared by every behaviour
    and obstacle: common random numbers).  ``key``: a JAX PRNG key."""
    for name, v, lo in (("n_steps_plus_1", n_steps_plus_1, 1), ("n_mc", n_mc, 1)):
        if isinstance(v, bool) or not isinstance(v, int) or v < lo:
            raise ValueError(f"{name} must be an integer >= {lo}, got {v!r}")
    return jax.random.normal(key, (n_steps_plus_1, n_mc, 4), dtype or jnp.result_type(float))


def cholesky4(S):
    """Lower-triangular L [..., 4, 4] with L Lᵀ = S for symmetric positive semi-definite S [..., 4, 4].

    Plain column Cholesky, except that a pivot ≤ CHOL_TOL·eps·max(diag S) gives a zero column (a degenerate
    direction, e.g. an exactly known velocity, is sampled as a constant) instead of NaN."""
    S = jnp.asarray(S)
    if S.shape[-2:] != (4, 4):
        raise ValueError(f"S must be [..., 4, 4], got shape {S.shape}")
    eps = jnp.finfo(S.dtype).eps if jnp.issubdtype(S.dtype, jnp.floating) else jnp.finfo(float).eps
    tol = CHOL_TOL * eps * jnp.max(jnp.diagonal(S, axis1=-2, axis2=-1), axis=-1)
    L = [[jnp.zeros(S.shape[:-2], S.dtype) for _ in range(4)] for _ in range(4)]
    for j in range(4):
        s = S[..., j, j] - sum(L[j][m] * L[j][m] for m in range(j))
        pos = s > tol
        d = jnp.where(pos, jnp.sqrt(jnp.where(pos, s, 1.0)), 0.0)
        inv = jnp.where(pos, 1.0 / jnp.where(pos, d, 1.0), 0.0)
        L[j][j] = d
        for i in range(j + 1, 4):
            L[i][j] = (S[..., i, j] - sum(L[i][m] * L[j][m] for m in range(j))) * inv
    return jnp.stack([jnp.stack(row, axis=-1) for row in L], axis=-2)


# ------------------------------------------------------------------------------------------ the event
def cpa_time(dpx, dpy, dvx, dvy, eps_v=DEFAULT_EPS_V):
    """t_cpa = −(Δp·Δv)/‖Δv‖² when ‖Δv‖ ≥ ε_v (and ‖Δv‖ > 0) and the vessels are closing (Δp·Δv < 0), else 0
    (Δp = obstacle − own-ship position, Δv = obstacle − own-ship velocity; straight lines from now)."""
    dot = dpx * dvx + dpy * dvy
    v2 = dvx * dvx + dvy * dvy
    ok = (v2 >= eps_v * eps_v) & (v2 > 0) & (dot < 0)
    return jnp.where(ok, -dot / jnp.where(ok, v2, 1.0), 0.0)


def _inside_fraction(dpx, dpy, dvx, dvy, e, d_safe, eps_v, event: str):
    """y and the mean CPA time for relative means ``[...]`` and sample perturbations ``e = L z [..., N, 4]``
    (order [x, y, V_x, V_y]; broadcast against ``[..., N]``)."""
    check_choice("event", event, EVENTS)
    tc = cpa_time(dpx, dpy, dvx, dvy, eps_v)
    r2 = d_safe * d_safe
    ex, ey, evx, evy = e[..., 0], e[..., 1], e[..., 2], e[..., 3]
    if event == "mean_cpa":
        t = tc[..., None]
        # sample position minus own-ship position at the CPA time of the means
        qx = dpx[..., None] + dvx[..., None] * t + ex + evx * t
        qy = dpy[..., None] + dvy[..., None] * t + ey + evy * t
    else:
        spx, spy = dpx[..., None] + ex, dpy[..., None] + ey
        svx, svy = dvx[..., None] + evx, dvy[..., None] + evy
        ts = cpa_time(spx, spy, svx, svy, eps_v)
        qx, qy = spx + svx * ts, spy + svy * ts
    inside = (qx * qx + qy * qy) <= r2
    return jnp.mean(inside.astype(tc.dtype), axis=-1), tc


def mcs_estimates(dpx, dpy, dvx, dvy, L, z, d_safe=DEFAULT_D_SAFE, *, eps_v=DEFAULT_EPS_V, event: str = "mean_cpa"):
    """The Monte-Carlo measurements y (eq. 19, read as the fraction of samples in 𝒮) and the CPA time of the
    means, for every pair.

    Args:
        dpx, dpy, dvx, dvy: obstacle-mean minus own-ship position and velocity, any common shape ``[...]``
            (e.g. ``[T, P]``: every prediction step of P pairs).
        L: Cholesky factors ``[..., 4, 4]`` of the obstacle covariance (order [x, y, V_x, V_y]), broadcast
            against ``[...]`` (e.g. ``[P, 4, 4]``).
        z: standard normals ``[..., N_MC, 4]`` broadcast against ``[...]`` (e.g. ``[T, 1, N_MC, 4]``: the
            table of :func:`normal_table` with an axis for the pairs, independent across steps).
        d_safe: safety-zone radius [m]. eps_v: relative-speed floor of :func:`cpa_time` [m/s].
        event: ``"mean_cpa"`` (the sample x̄ + Lz, moved on a straight line, is inside the zone around the
            own-ship at the CPA time of the means) or ``"sample_cpa"`` (the sample's own CPA distance ≤ d_safe).

    Returns ``(y, t_cpa)``, both ``[...]``."""
    check_param("d_safe", d_safe, lo=0.0, lo_open=True)
    check_param("eps_v", eps_v, lo=0.0)
    L, z = jnp.asarray(L), jnp.asarray(z)
    e = jnp.matmul(z, jnp.swapaxes(L, -1, -2))                          # (L z)ᵀ per sample: [..., N, 4]
    return _inside_fraction(jnp.asarray(dpx), jnp.asarray(dpy), jnp.asarray(dvx), jnp.asarray(dvy), e, d_safe,
                            eps_v, event)


# ------------------------------------------------------------------------------------------ the cost term
def _check_static_int(name: str, v, lo: int) -> None:
    if isinstance(v, bool) or not isinstance(v, int) or v < lo:
        raise ValueError(f"{name} must be an integer >= {lo}, got {v!r}")


@cost_term(static=("n_mc", "seed", "event", "include_t0"))
class Psbmpc2020Term:
    """The PSB-MPC cost of Tengesdal, Brekke & Johansen (2020), eq. (20), for every behaviour l:

        H^l = max_i Σ_s π_{i,s} ( Σ_k C(t_k) ℙ̂_{i,s}(t_k) e^{−(t_k + t_cpa(t_k) − t₀)/T_c} + Σ_k κ μ(t_k) ),
        C(t_k) = K_coll ‖v_o(t_k) − v_{i,s}(t_k)‖²,

    where ℙ̂ is the KF-filtered (:func:`kf_apply`) Monte-Carlo probability y (:func:`mcs_estimates`) of the
    straight-line CPA event at every step, t_cpa the CPA time of the means (ε_v), μ Johansen's Boolean COLREGS
    indicator (:func:`psbmpc_jax.costs.sbmpc.colregs_boolean_xy`, close range ``d_cl``).

    Choices (docs/mcskf.md):

    * covariance: the track covariance at t₀, ``ctx.obs_cov[:, 0]``, held constant over the horizon (§4.2/§7
      of the paper), the full 4×4 (position and velocity);
    * samples: Z [T, N_MC, 4] from ``jax.random.key(seed)`` in the context's dtype (:func:`normal_table`),
      independent across steps, shared by every behaviour and obstacle; the evaluator's ``samples`` argument
      (the library estimator's table) is not used;
    * the filter runs over every step k = 0…N (prior P0, variance V0, re-initialised at every solve); the
      sums of eq. (20) run over k = 0…N (``include_t0=True``, the default: D(t₀) holds t₀, and the present
      risk differs between obstacles though not between behaviours) or k = 1…N (``include_t0=False``);
    * scenarios: π_{i,s} = scen_weight[i, s]·scen_valid[i, s] / Σ_s (…) — the scenario probabilities P_s
      (w_i cancels; an obstacle with w_i = 0 or no valid scenario counts 0).  With n_ps = 1 (the paper's one
      straight CV line) this is scenario 0 exactly.  A context without ``scen_weight`` (None) weighs the valid
      scenarios uniformly;
    * d_safe is the term's own radius (Table 1: 40 m), not ``ctx.radius`` (no ship lengths added);
    * the maximum over obstacles of an empty mask (or O = 0) is 0;
    * ``config.stop_remedy`` (:class:`~psbmpc_jax.params.PlannerConfig`; ``"none"`` when ``config`` is None):
      ``"colregs_heading"`` evaluates μ on the own-ship's heading whatever its speed, so a stopped own-ship is
      no longer exempt (docs/methods/psbmpc.md "The stop loophole").

    Not smooth: y is a sample count (piecewise constant in the trajectories) and μ is Boolean; the other
    factors (C, the discount) are smooth, so gradients exist almost everywhere but ignore the jumps.

    Details (``[B, O, S]`` per (obstacle, scenario), 0 where invalid): ``psbmpc2020_i`` (the bracket of
    eq. (20)), ``psbmpc2020_coll_i`` (its collision sum), ``psbmpc2020_colregs_i`` (κ·number of violating
    steps), ``psbmpc2020_pmax`` (max over the summed steps of ℙ̂); ``psbmpc2020_h [B, O]`` the π-weighted
    bracket per obstacle (the value is its maximum over O)."""

    name = "psbmpc2020"
    PARAMS = ("d_safe", "eps_v", "q_P", "r_P", "V0", "P0", "T_c", "K_coll", "kappa", "d_cl")
    smooth = False

    n_mc: int = DEFAULT_N_MC
    seed: int = 0
    event: str = "mean_cpa"
    include_t0: bool = True
    d_safe: float = DEFAULT_D_SAFE
    eps_v: float = DEFAULT_EPS_V
    q_P: float = DEFAULT_Q_P
    r_P: float = DEFAULT_R_P
    V0: float = DEFAULT_V0
    P0: float = DEFAULT_P0
    T_c: float = DEFAULT_T_C
    K_coll: float = DEFAULT_K_COLL
    kappa: float = DEFAULT_KAPPA
    d_cl: float = DEFAULT_D_CL

    def __post_init__(self):
        _check_static_int("n_mc", self.n_mc, 1)
        _check_static_int("seed", self.seed, 0)
        check_choice("event", self.event, EVENTS)
        if not isinstance(self.include_t0, bool):
            raise ValueError(f"include_t0 must be True or False, got {self.include_t0!r}")
        check_param("d_safe", self.d_safe, lo=0.0, lo_open=True)
        check_param("eps_v", self.eps_v, lo=0.0)
        check_param("q_P", self.q_P, lo=0.0)
        check_param("r_P", self.r_P, lo=0.0, lo_open=True)
        check_param("V0", self.V0, lo=0.0)
        check_param("P0", self.P0, lo=0.0, hi=1.0)
        check_param("T_c", self.T_c, lo=0.0, lo_open=True)
        check_param("K_coll", self.K_coll, lo=0.0)
        check_param("kappa", self.kappa, lo=0.0)
        check_param("d_cl", self.d_cl, lo=0.0, lo_open=True)

    # -------------------------------------------------------------------------------- pieces
    def table(self, n_t: int, dtype):
        """This term's standard-normal table Z [n_t, N_MC, 4] (from ``jax.random.key(seed)``)."""
        return normal_table(jax.random.key(self.seed), n_t, self.n_mc, dtype)

    def series(self, ctx: Context, z=None, heading: bool = False) -> dict:
        """Per (step, obstacle·scenario, behaviour) arrays ``[T, O·S, B]``: ``y`` (MC measurement), ``P``
        (filtered ℙ̂), ``t_cpa``, ``coll`` (C·ℙ̂·discount), ``mu`` (0/1), and ``step [T]`` (1 where the step
        enters the sums).  ``z``: an explicit table [T, N_MC, 4] (default: :meth:`table`).  ``heading``: μ on
        the own-ship's heading whatever its speed (the stop remedy ``"colregs_heading"``)."""
        own, obs = ctx.own, ctx.obstacles
        n_t = own.x.shape[0]
        n_o, n_s = obs.x.shape[1], obs.x.shape[2]
        n_os = n_o * n_s
        dtype = own.x.dtype
        flat = lambda a: a.reshape(n_t, n_os)[:, :, None]                       # noqa: E731  [T, O·S, 1]
        ox, oy, ochi, oU = (a[:, None, :] for a in (own.x, own.y, own.chi, own.U))  # [T, 1, B]
        ovx, ovy = oU * jnp.cos(ochi), oU * jnp.sin(ochi)
        tx, ty, tchi, tU = (flat(a) for a in (obs.x, obs.y, obs.chi, obs.U))
        tvx, tvy = tU * jnp.cos(tchi), tU * jnp.sin(tchi)
        dpx, dpy, dvx, dvy = tx - ox, ty - oy, tvx - ovx, tvy - ovy               # [T, O·S, B]

        L = jnp.repeat(cholesky4(jnp.asarray(ctx.obs_cov, dtype)[:, 0]), n_s, axis=0)     # [O·S, 4, 4]
        z = self.table(n_t, dtype) if z is None else jnp.asarray(z, dtype)
        if z.shape != (n_t, self.n_mc, 4):
            raise ValueError(f"z must be [T, n_mc, 4] = [{n_t}, {self.n_mc}, 4], got shape {z.shape}")
        # L z once per (step, obstacle·scenario): it does not depend on the behaviour
        e = jnp.einsum("knj,pij->kpni", z, L)[:, :, None]                         # [T, O·S, 1, N, 4]
        y, tc = _inside_fraction(dpx, dpy, dvx, dvy, e, self.d_safe, self.eps_v, self.event)
        K = kf_gains(n_t, self.q_P, self.r_P, self.V0, dtype)
        P = kf_apply(y, K, jnp.asarray(self.P0, dtype))
        t = jnp.asarray(ctx.t, dtype)
        disc = jnp.exp(-((t - t[0])[:, None, None] + tc) / self.T_c)
        C = self.K_coll * (dvx * dvx + dvy * dvy)
        mu = colregs_boolean_xy(ox, oy, ochi, oU, tx, ty, tchi, tU, self.d_cl, heading=heading)
        step = (jnp.arange(n_t) >= (0 if self.include_t0 else 1)).astype(dtype)
        return {"y": y, "P": P, "t_cpa": tc, "coll": C * P * disc, "mu": mu, "step": step}

    def scenario_weights(self, ctx: Context):
        """π [O, S]: the normalised scenario weights of every obstacle (0 rows for dropped obstacles)."""
        valid = jnp.asarray(ctx.scen_valid, bool)
        dtype = ctx.own.x.dtype
        w = jnp.ones(valid.shape, dtype) if ctx.scen_weight is None else jnp.asarray(ctx.scen_weight, dtype)
        w = jnp.where(valid, w, 0.0)
        tot = jnp.sum(w, axis=1, keepdims=True)
        return jnp.where(tot > 0, w / jnp.where(tot > 0, tot, 1.0), 0.0)

    def __call__(self, ctx: Context, params=None, config=None, samples=None) -> TermValue:
        n_o, n_s = ctx.scen_valid.shape
        n_b = ctx.own.x.shape[1]
        dtype = ctx.own.x.dtype
        if n_o * n_s == 0:
            z = jnp.zeros((n_b, n_o, n_s), dtype)
            return TermValue(jnp.zeros((n_b,), dtype), {"psbmpc2020_i": z, "psbmpc2020_coll_i": z,
                                                        "psbmpc2020_colregs_i": z, "psbmpc2020_pmax": z,
                                                        "psbmpc2020_h": jnp.zeros((n_b, n_o), dtype)})
        sr = self.series(ctx, heading=stop_remedy(config) == "colregs_heading")
        step = sr["step"][:, None, None]
        valid = jnp.asarray(ctx.scen_valid, bool).reshape(-1)[:, None]           # [O·S, 1]
        coll = jnp.where(valid, jnp.sum(step * sr["coll"], axis=0), 0.0)         # [O·S, B]
        col = jnp.where(valid, self.kappa * jnp.sum(step * sr["mu"], axis=0), 0.0)
        pmax = jnp.where(valid, jnp.max(jnp.where(step > 0, sr["P"], 0.0), axis=0), 0.0)
        h = coll + col
        per = lambda a: a.T.reshape(n_b, n_o, n_s)                               # noqa: E731
        h_i = jnp.sum(self.scenario_weights(ctx)[None] * per(h), axis=2)         # [B, O]
        return TermValue(jnp.max(h_i, axis=1), {"psbmpc2020_i": per(h), "psbmpc2020_coll_i": per(coll),
                                                "psbmpc2020_colregs_i": per(col), "psbmpc2020_pmax": per(pmax),
                                                "psbmpc2020_h": h_i})

    def _kw(self) -> dict:
        return dict(d_safe=self.d_safe, eps_v=self.eps_v, q_P=self.q_P, r_P=self.r_P, V0=self.V0, P0=self.P0,
                    T_c=self.T_c, K_coll=self.K_coll, kappa=self.kappa, d_cl=self.d_cl, event=self.event,
                    include_t0=self.include_t0)

    def reference(self, own_traj, behaviour, situation, params, config):
        """The float64 oracle (:func:`psbmpc_jax.reference_mcskf.psbmpc2020_cost`) of one own-ship trajectory
        ``[N+1, 4]`` against the situation's obstacles (the reference's scenario rollouts, each obstacle's
        ``cov`` and scenario probabilities), with this term's table Z built in ``config.dtype``."""
        import numpy as np

        from .. import reference_mcskf as rm

        n_t = len(own_traj)
        Z = np.asarray(self.table(n_t, jnp.dtype(config.dtype)), dtype=float)
        t = [k * float(config.dt) for k in range(n_t)]
        return rm.psbmpc2020_cost(own_traj, rm.situation_obstacles(situation, params, config), t, Z,
                                  stop_remedy=stop_remedy(config), **self._kw())["value"]


__all__ = [
    "EVENTS", "DEFAULT_N_MC", "DEFAULT_Q_P", "DEFAULT_R_P", "DEFAULT_V0", "DEFAULT_P0", "DEFAULT_T_C",
    "DEFAULT_D_SAFE", "DEFAULT_K_COLL", "DEFAULT_KAPPA", "DEFAULT_D_CL", "DEFAULT_EPS_V", "kf_gains", "kf_weights",
    "smoothing_matrix", "kf_filter", "kf_apply", "normal_table", "cholesky4", "cpa_time", "mcs_estimates",
    "Psbmpc2020Term",
]
