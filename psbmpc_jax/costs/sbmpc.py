"""SB-MPC risk pieces and their smooth forms (Johansen et al. 2016 as restated by Mahipala & Johansen 2024,
eqs. (2)-(10), (16)-(18), (27)); docs/smooth_sbmpc.md "Smooth cost components".

Pure, vectorised, differentiable ``jax.numpy`` functions (NED: x north, y east [m], courses [rad],
clockwise positive):

* :func:`adhoc_risk`: the ad hoc collision risk R, crisp (3) or ungated (17);
* :func:`sigma_coll`: the distance gate σ_coll (16), falling, slope a₂ = −ln 99 / (w_coll d_safe) (our reading, choice
  SM-1 of docs/algorithm.md §12: the paper calls the slope tunable and gives neither its sign nor a value);
* :func:`collision_weight`: C = K_coll ‖v_o − v_i‖² (4)/(18);
* :func:`collision_hazard`: σ_coll·C·R (smooth) or C·R (crisp) of one (target, time) pair;
* :func:`colregs_boolean`: the original Boolean COLREGS indicator μ (5)-(10) (crisp);
* :func:`aggregate`: max over (target, time) (eq. 2, the initialisation stage) or sum over (target, time)
  (eq. 27, the DOCP), over the times τ ≥ τ₀ + T_s only (R is singular at τ₀; choice SM-10);
* :func:`sbmpc_costs`: all of the above on one own-ship trajectory and its targets' trajectories;

and the cost terms that plug them into the evaluator / objective (:mod:`psbmpc_jax.evaluate`,
:mod:`psbmpc_jax.objective`): :class:`SmoothCollisionTerm` (``"sbmpc_coll"``), :class:`FuzzyColregsTerm`
(``"colregs_fis"``) and :class:`SbmpcHazardTerm` (``"sbmpc"``, the joint max of eq. (2)).

Gradient safety: distances go through ``safe_sqrt``; R uses max(d, 10⁻³ d_safe) in place of d (finite at
d = 0, unchanged for d ≥ 10⁻³ d_safe); R is singular at τ = τ₀, so every function that sees a time grid
drops τ₀ *before* evaluating R (slicing afterwards would still poison reverse-mode gradients with 0·∞).
"""

from __future__ import annotations

from typing import dataclass_transform

import jax
import jax.numpy as jnp

from ..array_types import HostOrDevice
from ..numerics import safe_sqrt
from .base import Context, TermValue, cost_term
from .colregs import violation
from .colregs_fuzzy import (COMPLETIONS, DEFAULT_D_CL, DEFAULT_E_CL, DEFAULT_EPS, DEFAULT_N_Y, LN99, check_choice,
                            check_fis_params, check_param, encounter_inputs_xy, fis_colregs, sig)

#: Defaults for a ~5 m inland vessel at ~1 m/s (our proposal: Mahipala & Johansen 2024 give no numbers for these); p,
#: q are the paper's "typical" values.
DEFAULT_D_SAFE = 10.0
DEFAULT_K_COLL = 1.0
DEFAULT_KAPPA = 10.0
DEFAULT_P = 1.0
DEFAULT_Q = 4.0
DEFAULT_W_COLL = 0.1          # SM-1: gate width as a fraction of d_safe (99 % at 0.9 d_safe, 1 % at 1.1 d_safe)
#: Weight λ of the COLREGS-transitional term (used only with ``transitional=True``; the papers give no value; ours).
DEFAULT_LAMBDA_T = 10.0
#: R is evaluated at max(d, RISK_D_FLOOR · d_safe) (finite value and gradient at d = 0).
RISK_D_FLOOR = 1e-3
#: The original SB-MPC's own-ship speed guard of HEAD-ON (and, in the library, CROSSED) [m/s].
V_EPS = 0.05

AGGREGATIONS = ("max", "sum")
RISK_FORMS = ("smooth", "crisp")
COLREGS_FORMS = ("fis", "boolean")


# ------------------------------------------------------------------------------------------ pieces
def coll_slope(d_safe, w_coll=DEFAULT_W_COLL):
    """Slope a₂ of σ_coll: −ln 99 / (w_coll·d_safe) (choice SM-1, docs/algorithm.md §12; negative, a falling curve)."""
    return -LN99 / (w_coll * d_safe)


def sigma_coll(d, d_safe, w_coll=DEFAULT_W_COLL):
    """σ_coll(d) = sig(d; d_safe, −ln 99 / (w_coll d_safe)) (eq. 16 with a₃ = 0, a₄ = 1): 0.5 at d_safe,
    0.99 at (1 − w_coll) d_safe, 0.01 at (1 + w_coll) d_safe."""
    check_param("d_safe", d_safe, lo=0.0, lo_open=True)
    check_param("w_coll", w_coll, lo=0.0, lo_open=True)
    return sig(d, d_safe, coll_slope(d_safe, w_coll))


def adhoc_risk(d, t, d_safe, p=DEFAULT_P, q=DEFAULT_Q, *, crisp: bool = False):
    """R = |t|^(−p)·(d_safe / d)^q; ``crisp=True``: eq. (3), 0 where d > d_safe; else eq. (17), ungated.

    ``t`` = τ − τ₀ must be non-zero (R is singular at τ₀; the aggregations start at τ₀ + T_s).  ``d`` is
    replaced by max(d, 10⁻³ d_safe) (:data:`RISK_D_FLOOR`)."""
    check_param("d_safe", d_safe, lo=0.0, lo_open=True)
    check_param("p", p, lo=0.0)
    check_param("q", q, lo=0.0)
    d_eff = jnp.maximum(d, RISK_D_FLOOR * d_safe)
    # (d_safe / d_eff)^q as exp(q log(.)): the base is > 0, and a float power is a slow scalar call on XLA:CPU
    r = jnp.abs(t) ** (-p) * jnp.exp(q * jnp.log(d_safe / d_eff))
    if crisp:
        return jnp.where(d <= d_safe, r, 0.0)
    return r


def collision_weight(vo_x, vo_y, vi_x, vi_y, K_coll=DEFAULT_K_COLL):
    """C = K_coll ‖v_o − v_i‖² (eqs. 4 and 18)."""
    check_param("K_coll", K_coll, lo=0.0)
    ex, ey = vo_x - vi_x, vo_y - vi_y
    return K_coll * (ex * ex + ey * ey)


def collision_hazard(d, t, vo_x, vo_y, vi_x, vi_y, *, d_safe=DEFAULT_D_SAFE, K_coll=DEFAULT_K_COLL, p=DEFAULT_P,
                     q=DEFAULT_Q, w_coll=DEFAULT_W_COLL, risk: str = "smooth"):
    """The collision part of one (target, time) pair: σ_coll·C·R with R ungated (``risk="smooth"``,
    eqs. 16-18) or C·R with R crisp (``risk="crisp"``, eqs. 3-4).  ``t`` ≠ 0."""
    check_choice("risk", risk, RISK_FORMS)
    c = collision_weight(vo_x, vo_y, vi_x, vi_y, K_coll)
    if risk == "crisp":
        return c * adhoc_risk(d, t, d_safe, p, q, crisp=True)
    return sigma_coll(d, d_safe, w_coll) * c * adhoc_risk(d, t, d_safe, p, q)


def colregs_boolean_xy(own_x, own_y, own_chi, own_U, tgt_x, tgt_y, tgt_chi, tgt_U, d_cl=DEFAULT_D_CL, *,
                       heading: bool = False):
    """The original COLREGS indicator μ ∈ {0, 1} (eqs. 5-10), as the arrays' float dtype:
    μ = CLOSE ∧ STARBOARD ∧ (HEAD-ON ∨ (CROSSED ∧ ¬OVERTAKEN)) with CLOSE: d < d_cl; STARBOARD: RB ∈ (0, π);
    HEAD-ON: ‖v_o‖ > 0.05 m/s ∧ v_o·v_i < −cos 22.5° ‖v_o‖‖v_i‖ ∧ v_o·L > cos 67.5° ‖v_o‖; CROSSED:
    ‖v_o‖ > 0.05 m/s ∧ v_o·v_i < cos 67.5° ‖v_o‖‖v_i‖; OVERTAKEN: v_o·v_i > cos 67.5° ‖v_o‖‖v_i‖ ∧
    ‖v_i‖ > ‖v_o‖ (the library's :func:`psbmpc_jax.costs.colregs.violation`).  Piecewise constant.
    ``heading=True`` (static): the stop remedy ``"colregs_heading"``, the tests on the own-ship's heading χ
    whatever its speed (no speed guard)."""
    check_param("d_cl", d_cl, lo=0.0, lo_open=True)
    c, s = jnp.cos(own_chi), jnp.sin(own_chi)
    ci, si = jnp.cos(tgt_chi), jnp.sin(tgt_chi)
    dtype = jnp.result_type(own_x, tgt_x, float)
    out = violation(tgt_x - own_x, tgt_y - own_y, own_U * c, own_U * s, tgt_U * ci, tgt_U * si, c, s, d_cl,
                    heading=heading)
    return out.astype(dtype)


def colregs_boolean(own_state, target_state, d_cl=DEFAULT_D_CL):
    """:func:`colregs_boolean_xy` for state arrays ``[..., 4]`` = (x, y, χ, U) (broadcast)."""
    o, t = jnp.asarray(own_state), jnp.asarray(target_state)
    if o.shape[-1] != 4 or t.shape[-1] != 4:
        raise ValueError(f"states must be [..., 4] (x, y, chi, U), got shapes {o.shape} and {t.shape}")
    return colregs_boolean_xy(o[..., 0], o[..., 1], o[..., 2], o[..., 3], t[..., 0], t[..., 1], t[..., 2],
                              t[..., 3], d_cl)


#: cos 67.5° and cos 22.5°, the sector limits of the Boolean COLREGS geometry (eqs. 7-10).
_COS_67_5 = 0.38268343236508984
_COS_22_5 = 0.9238795325112867


def transitional_situation(own_x, own_y, own_chi, own_U, tgt_x, tgt_y, tgt_chi, tgt_U, d_cl=DEFAULT_D_CL):
    """Whether a target is in a situation where the COLREGS-transitional term applies (Johansen et al. 2016
    eq. 11 after Hagen et al. 2018): CLOSE (d < d_cl) ∧ (own-ship OVERTAKING ∨ OVERTAKEN ∨ CROSSED), from the
    present states (broadcast).  OVERTAKEN: v_o·v_i > cos 67.5° ‖v_o‖‖v_i‖ ∧ ‖v_i‖ > ‖v_o‖; OVERTAKING: the same
    sector ∧ ‖v_o‖ > ‖v_i‖ ∧ the target ahead (v_o·L > 0); CROSSED: ‖v_o‖ > 0.05 m/s ∧ v_o·v_i < cos 67.5°
    ‖v_o‖‖v_i‖ and not head-on (v_o·v_i ≥ −cos 22.5° ‖v_o‖‖v_i‖).  A target with no speed is in none."""
    c, s_ = jnp.cos(own_chi), jnp.sin(own_chi)
    dot = own_U * tgt_U * (c * jnp.cos(tgt_chi) + s_ * jnp.sin(tgt_chi))
    norms = own_U * tgt_U
    dx, dy = tgt_x - own_x, tgt_y - own_y
    close = dx * dx + dy * dy < d_cl * d_cl
    same = dot > _COS_67_5 * norms
    overtaken = same & (tgt_U > own_U)
    overtaking = same & (own_U > tgt_U) & (c * dx + s_ * dy > 0)
    crossed = (own_U > V_EPS) & (dot < _COS_67_5 * norms) & (dot >= -_COS_22_5 * norms)
    return close & (overtaken | overtaking | crossed)


def passing_side(own_x, own_y, own_chi, tgt_x, tgt_y):
    """The side the target passes on, at the closest point of the predicted trajectories: sign of
    sin(bearing − χ_own) at the time step of the smallest distance (axis 0 is time; +1 starboard, −1 port,
    0 dead ahead/astern); ties in distance take the first step."""
    shape = jnp.broadcast_shapes(own_x.shape, tgt_x.shape)
    ox, oy, oc, tx, ty = (jnp.broadcast_to(a, shape) for a in (own_x, own_y, own_chi, tgt_x, tgt_y))
    dx, dy = tx - ox, ty - oy
    k = jnp.argmin(dx * dx + dy * dy, axis=0)[None]
    take = lambda a: jnp.take_along_axis(a, k, axis=0)[0]                   # noqa: E731
    chi = take(oc)
    return jnp.sign(take(dy) * jnp.cos(chi) - take(dx) * jnp.sin(chi))


def transitional_indicator(ctx: Context, d_cl=DEFAULT_D_CL):
    """T [O·S, B] ∈ {0, 1}: target i is in a transitional situation now (:func:`transitional_situation`) and
    behaviour l makes it pass on the other side than the applied offsets would (:func:`passing_side` of
    ``ctx.own`` against ``ctx.own_applied``, over τ ≥ τ₀ + T_s). Constant over the horizon (choice SB-7,
    docs/algorithm.md §13)."""
    if ctx.own_applied is None:
        raise ValueError("the transitional term needs Context.own_applied (the rollout of the applied offsets): "
                         "evaluate with terms that declare needs_applied, through psbmpc_jax.evaluate.context("
                         "applied=True)")
    o, x, _, _ = context_pairs(ctx)
    a = ctx.own_applied
    ap = tuple(v[1:, None, :] for v in (a.x, a.y, a.chi))                  # [K, 1, 1]
    side = passing_side(o[0], o[1], o[2], x[0], x[1])                      # [O·S, B]
    side0 = passing_side(ap[0], ap[1], ap[2], x[0], x[1])                  # [O·S, 1]
    own0 = [v[0, 0] for v in (ctx.own.x, ctx.own.y, ctx.own.chi, ctx.own.U)]     # present state, row 0
    n_t = ctx.own.x.shape[0]
    n_os = x[0].shape[1]
    tg0 = [v.reshape(n_t, n_os)[0] for v in (ctx.obstacles.x, ctx.obstacles.y, ctx.obstacles.chi, ctx.obstacles.U)]
    situation = transitional_situation(own0[0], own0[1], own0[2], own0[3], tg0[0], tg0[1], tg0[2], tg0[3],
                                       d_cl)                                # [O·S]
    return (situation[:, None] & (side * side0 < 0)).astype(ctx.own.x.dtype)


def aggregate(h, aggregation: str = "max", valid=None):
    """Reduce ``h [K, I, ...]`` (time-major: K times τ₀ + T_s … τ₀ + T, I targets) to ``[...]``:
    ``"max"``: max over (time, target) (eq. 2); ``"sum"``: sum over both (eq. 27).  ``valid [I]`` masks
    targets out (their h counts as 0). No target (I = 0) gives 0. The caller drops τ₀ (R is singular there; choice
    SM-10)."""
    check_choice("aggregation", aggregation, AGGREGATIONS)
    h = jnp.asarray(h)
    if h.ndim < 2:
        raise ValueError(f"h must be [K, I, ...] (time, target, ...), got shape {h.shape}")
    if valid is not None:
        valid = jnp.asarray(valid, bool)
        h = jnp.where(valid.reshape(valid.shape + (1,) * (h.ndim - 2)), h, 0.0)
    if h.shape[0] == 0 or h.shape[1] == 0:
        return jnp.zeros(h.shape[2:], h.dtype)
    return jnp.max(h, axis=(0, 1)) if aggregation == "max" else jnp.sum(h, axis=(0, 1))


def _aggregate_time(h, aggregation: str):
    """Per target: reduce the leading time axis (max or sum)."""
    if h.shape[0] == 0:
        return jnp.zeros(h.shape[1:], h.dtype)
    return jnp.max(h, axis=0) if aggregation == "max" else jnp.sum(h, axis=0)


def pair_components(own_x, own_y, own_chi, own_U, tgt_x, tgt_y, tgt_chi, tgt_U, t, *, d_safe=DEFAULT_D_SAFE,
                    K_coll=DEFAULT_K_COLL, p=DEFAULT_P, q=DEFAULT_Q, w_coll=DEFAULT_W_COLL, d_cl=DEFAULT_D_CL,
                    e_cl=DEFAULT_E_CL, eps=DEFAULT_EPS, n_y: int = DEFAULT_N_Y, completion="default_false",
                    risk: str = "smooth", colregs: str = "fis", need=("coll", "mu")):
    """``(coll, mu)`` of (target, time) pairs, all inputs broadcast: coll = :func:`collision_hazard`,
    mu = FIS_colregs (``colregs="fis"``) or the Boolean original (``"boolean"``); entries not in ``need`` are
    ``None``.  ``t`` ≠ 0."""
    check_choice("colregs", colregs, COLREGS_FORMS)
    coll = mu = None
    if "coll" in need:
        dx, dy = tgt_x - own_x, tgt_y - own_y
        d = safe_sqrt(dx * dx + dy * dy)
        coll = collision_hazard(d, t, own_U * jnp.cos(own_chi), own_U * jnp.sin(own_chi),
                                tgt_U * jnp.cos(tgt_chi), tgt_U * jnp.sin(tgt_chi), d_safe=d_safe, K_coll=K_coll,
                                p=p, q=q, w_coll=w_coll, risk=risk)
    if "mu" in need:
        if colregs == "fis":
            dcog, rb, d = encounter_inputs_xy(own_x, own_y, own_chi, tgt_x, tgt_y, tgt_chi)
            mu = fis_colregs(dcog, rb, d, d_cl=d_cl, e_cl=e_cl, eps=eps, n_y=n_y, completion=completion)
        else:
            mu = colregs_boolean_xy(own_x, own_y, own_chi, own_U, tgt_x, tgt_y, tgt_chi, tgt_U, d_cl)
    return coll, mu


def sbmpc_costs(own_traj, target_trajs, t, *, aggregation: str = "max", kappa=DEFAULT_KAPPA, valid=None,
                **pair_kwargs) -> dict:
    """The SB-MPC hazard costs of ONE own-ship trajectory (vmap it over behaviours).

    Args:
        own_traj: ``[T, 4]`` own-ship states (x, y, χ, U) at times ``t``.
        target_trajs: ``[T, I, 4]`` target states (point targets, one trajectory each).
        t: ``[T]`` times relative to τ₀ (``t[0] = 0`` = τ₀ is skipped: R is singular there, choice SM-10).
        aggregation: ``"max"`` (eq. 2) or ``"sum"`` (eq. 27). kappa: COLREGS weight κ.
        valid: optional ``[I]`` target mask.
        **pair_kwargs: d_safe, K_coll, p, q, w_coll, d_cl, e_cl, eps, n_y, completion, risk, colregs
            (:func:`pair_components`).

    Returns ``{"coll": …, "colregs": …, "joint": …}``: the aggregated σCR (or crisp CR), the aggregated κμ and
    the aggregate of their sum per (target, time) — the faithful eq. (2) for ``"max"`` (for ``"sum"`` it is
    the sum of the other two)."""
    check_choice("aggregation", aggregation, AGGREGATIONS)
    check_param("kappa", kappa, lo=0.0)
    o, x = jnp.asarray(own_traj), jnp.asarray(target_trajs)
    if o.ndim != 2 or o.shape[-1] != 4 or x.ndim != 3 or x.shape[-1] != 4 or x.shape[0] != o.shape[0]:
        raise ValueError(f"own_traj must be [T, 4] and target_trajs [T, I, 4], got {o.shape} and {x.shape}")
    t = jnp.asarray(t)
    if t.shape != (o.shape[0],):
        raise ValueError(f"t must be [T] = [{o.shape[0]}], got shape {t.shape}")
    o, x, tt = o[1:, None, :], x[1:], t[1:, None]
    coll, mu = pair_components(o[..., 0], o[..., 1], o[..., 2], o[..., 3], x[..., 0], x[..., 1], x[..., 2],
                               x[..., 3], tt, **pair_kwargs)
    return {"coll": aggregate(coll, aggregation, valid), "colregs": aggregate(kappa * mu, aggregation, valid),
            "joint": aggregate(coll + kappa * mu, aggregation, valid)}


# ------------------------------------------------------------------------------------------ cost terms
@dataclass_transform()      # for type checkers: see cost_term
def smooth_cost_term(*static: str):
    """``cost_term(static=static)``: the smooth terms keep their mode strings and sizes static."""
    return cost_term(static=static)


#: Four arrays (x, y, χ, U) of the own-ship or the targets, as :func:`context_pairs` returns them.
Quad = tuple[jax.Array, jax.Array, jax.Array, jax.Array]


def context_pairs(ctx: Context) -> tuple[Quad, Quad, jax.Array, HostOrDevice]:
    """Time-major pair arrays of a :class:`Context` for τ ≥ τ₀ + T_s: own-ship ``(x, y, χ, U) [K, 1, B]``,
    targets ``(x, y, χ, U) [K, O·S, 1]`` (every (obstacle, scenario) is a point target; Smooth-SBMPC has one
    scenario per target), ``t [K, 1, 1]`` and the target mask ``valid [O·S]`` (``ctx.scen_valid``)."""
    own, obs = ctx.own, ctx.obstacles
    n_t = own.x.shape[0]
    n_os = obs.x.shape[1] * obs.x.shape[2]
    ox, oy, ochi, ou = (a[1:, None, :] for a in (own.x, own.y, own.chi, own.U))
    tx, ty, tchi, tu = (a.reshape(n_t, n_os)[1:, :, None] for a in (obs.x, obs.y, obs.chi, obs.U))
    return (ox, oy, ochi, ou), (tx, ty, tchi, tu), ctx.t[1:, None, None], ctx.scen_valid.reshape(n_os)


def term_value(ctx: Context, h, aggregation: str, detail: str) -> TermValue:
    """Aggregate ``h [K, O·S, B]`` to the term's ``[B]`` value and per-target details ``[B, O, S]``."""
    n_o, n_s = ctx.scen_valid.shape
    _, _, _, valid = context_pairs(ctx)
    h = jnp.where(valid[None, :, None], h, 0.0)
    per_target = _aggregate_time(h, aggregation)                       # [O·S, B]
    value = aggregate(h, aggregation)
    return TermValue(value, {detail: per_target.T.reshape(-1, n_o, n_s)})


def _check_common(term) -> None:
    check_choice("aggregation", term.aggregation, AGGREGATIONS)


def _check_collision(term) -> None:
    """The collision-risk fields shared by :class:`SmoothCollisionTerm` and :class:`SbmpcHazardTerm`."""
    check_param("d_safe", term.d_safe, lo=0.0, lo_open=True)
    check_param("K_coll", term.K_coll, lo=0.0)
    check_param("p", term.p, lo=0.0)
    check_param("q", term.q, lo=0.0)
    check_param("w_coll", term.w_coll, lo=0.0, lo_open=True)
    _check_common(term)
    check_choice("risk", term.risk, RISK_FORMS)


@smooth_cost_term("aggregation", "risk")
class SmoothCollisionTerm:
    """Collision cost of Smooth-SBMPC: h = σ_coll(d)·K_coll‖v_o − v_i‖²·R(d, τ) per (target, τ) (eqs. 16-18;
    ``risk="crisp"``: the original C·R with R of eq. (3)), aggregated over targets and τ ≥ τ₀ + T_s by
    ``aggregation``: ``"max"`` (initialisation stage, eq. 2) or ``"sum"`` (DOCP, eq. 27).

    Note: eq. (2) maximises the *sum* σCR + κμ jointly; this term plus :class:`FuzzyColregsTerm` with
    ``"max"`` gives max(σCR) + max(κμ) instead — use :class:`SbmpcHazardTerm` for the joint maximum.
    Details: ``sbmpc_coll_i [B, O, S]`` (per target, aggregated over time)."""

    name = "sbmpc_coll"
    PARAMS = ("d_safe", "K_coll", "p", "q", "w_coll")

    d_safe: float = DEFAULT_D_SAFE
    K_coll: float = DEFAULT_K_COLL
    p: float = DEFAULT_P
    q: float = DEFAULT_Q
    w_coll: float = DEFAULT_W_COLL
    aggregation: str = "max"
    risk: str = "smooth"

    def __post_init__(self):
        _check_collision(self)

    @property
    def smooth(self) -> bool:
        return self.risk == "smooth"

    def _kw(self):
        return dict(d_safe=self.d_safe, K_coll=self.K_coll, p=self.p, q=self.q, w_coll=self.w_coll, risk=self.risk)

    def __call__(self, ctx: Context, params, config, samples) -> TermValue:
        o, x, t, _ = context_pairs(ctx)
        coll, _ = pair_components(*o, *x, t, need=("coll",), **self._kw())
        return term_value(ctx, coll, self.aggregation, "sbmpc_coll_i")

    def reference(self, own_traj, behaviour, situation, params, config):
        from .. import reference_smooth as rs

        t = [k * float(config.dt) for k in range(len(own_traj))]
        return rs.sbmpc_cost(own_traj, rs.obstacle_targets(situation, params, config), t, component="coll",
                             aggregation=self.aggregation, **self._kw())


@smooth_cost_term("aggregation", "completion", "n_y")
class FuzzyColregsTerm:
    """COLREGS cost of Smooth-SBMPC: κ·μ per (target, τ) with μ from FIS_colregs (Tables I-IV, rules
    19-21, eq. 22; :func:`psbmpc_jax.costs.colregs_fuzzy.fis_colregs`), aggregated over targets and
    τ ≥ τ₀ + T_s (``"max"`` or ``"sum"``).  μ never reaches 0 (≈ 0.031 with ε = 1e-6), so ``"sum"`` carries a
    control-independent floor κ·0.031 per (target, step).  Details: ``colregs_fis_i [B, O, S]``."""

    name = "colregs_fis"
    PARAMS = ("kappa", "d_cl", "e_cl", "eps")
    smooth = True            # piecewise smooth (crisp clips of the rule strengths, RB jump dead astern)

    kappa: float = DEFAULT_KAPPA
    d_cl: float = DEFAULT_D_CL
    e_cl: float = DEFAULT_E_CL
    eps: float = DEFAULT_EPS
    n_y: int = DEFAULT_N_Y
    aggregation: str = "max"
    completion: str = "default_false"

    def __post_init__(self):
        check_param("kappa", self.kappa, lo=0.0)
        check_fis_params(self.d_cl, self.e_cl, self.eps, self.n_y, self.completion)
        _check_common(self)

    def _kw(self):
        return dict(d_cl=self.d_cl, e_cl=self.e_cl, eps=self.eps, n_y=self.n_y, completion=self.completion)

    def __call__(self, ctx: Context, params, config, samples) -> TermValue:
        o, x, t, _ = context_pairs(ctx)
        _, mu = pair_components(*o, *x, t, need=("mu",), colregs="fis", **self._kw())
        return term_value(ctx, self.kappa * mu, self.aggregation, "colregs_fis_i")

    def reference(self, own_traj, behaviour, situation, params, config):
        from .. import reference_smooth as rs

        t = [k * float(config.dt) for k in range(len(own_traj))]
        return rs.sbmpc_cost(own_traj, rs.obstacle_targets(situation, params, config), t, component="colregs",
                             aggregation=self.aggregation, kappa=self.kappa, colregs="fis", **self._kw())


@smooth_cost_term("aggregation", "risk", "colregs", "completion", "n_y", "transitional")
class SbmpcHazardTerm:
    """The SB-MPC hazard of eq. (2) with one joint aggregation: h = σ_coll·C·R + κ·μ (+ λ·T) per (target, τ),
    ``max`` over (target, τ ≥ τ₀ + T_s) (initialisation stage) or ``sum`` (DOCP, eq. 27; then equal to
    :class:`SmoothCollisionTerm` + :class:`FuzzyColregsTerm`).  ``risk="crisp"`` / ``colregs="boolean"`` give
    the original SB-MPC pieces (3)-(10) (not smooth).  ``transitional=True`` adds the COLREGS-transitional
    term λ·T of eq. (11) (:func:`transitional_indicator`: the behaviour changes the passing side of a target
    in an overtaking / overtaken / crossing situation; it needs the rollout of the applied offsets, so the
    evaluator computes ``Context.own_applied``); off by default (λ = 0, as Mahipala & Johansen 2024 omit it; choice
    SM-9). Details: ``sbmpc_i [B, O, S]``."""

    name = "sbmpc"
    PARAMS = ("d_safe", "K_coll", "p", "q", "w_coll", "kappa", "d_cl", "e_cl", "eps", "lambda_T")

    d_safe: float = DEFAULT_D_SAFE
    K_coll: float = DEFAULT_K_COLL
    p: float = DEFAULT_P
    q: float = DEFAULT_Q
    w_coll: float = DEFAULT_W_COLL
    kappa: float = DEFAULT_KAPPA
    d_cl: float = DEFAULT_D_CL
    e_cl: float = DEFAULT_E_CL
    eps: float = DEFAULT_EPS
    n_y: int = DEFAULT_N_Y
    lambda_T: float = DEFAULT_LAMBDA_T
    aggregation: str = "max"
    risk: str = "smooth"
    colregs: str = "fis"
    completion: str = "default_false"
    transitional: bool = False

    def __post_init__(self):
        _check_collision(self)
        check_param("kappa", self.kappa, lo=0.0)
        check_param("lambda_T", self.lambda_T, lo=0.0)
        check_fis_params(self.d_cl, self.e_cl, self.eps, self.n_y, self.completion)
        check_choice("colregs", self.colregs, COLREGS_FORMS)
        if not isinstance(self.transitional, bool):
            raise ValueError(f"transitional must be True or False, got {self.transitional!r}")

    @property
    def smooth(self) -> bool:
        return self.risk == "smooth" and self.colregs == "fis" and not self.transitional

    @property
    def needs_applied(self) -> bool:
        return self.transitional

    def _kw(self):
        return dict(d_safe=self.d_safe, K_coll=self.K_coll, p=self.p, q=self.q, w_coll=self.w_coll, d_cl=self.d_cl,
                    e_cl=self.e_cl, eps=self.eps, n_y=self.n_y, completion=self.completion, risk=self.risk,
                    colregs=self.colregs)

    def pair_kwargs(self) -> dict:
        """The keyword arguments of :func:`pair_components` (and of the float64 reference) this term uses."""
        return self._kw()

    def pair_hazard(self, ctx: Context):
        """The per-(τ ≥ τ₀ + T_s, target, behaviour) hazard ``h [K, O·S, B]`` before aggregation (C R + κ μ
        [+ λ T]), with the target mask ``valid [O·S]``."""
        o, x, t, valid = context_pairs(ctx)
        coll, mu = pair_components(*o, *x, t, **self._kw())
        h = coll + self.kappa * mu
        if self.transitional:
            h = h + self.lambda_T * transitional_indicator(ctx, self.d_cl)[None]
        return h, valid

    def __call__(self, ctx: Context, params, config, samples) -> TermValue:
        h, _ = self.pair_hazard(ctx)
        return term_value(ctx, h, self.aggregation, "sbmpc_i")

    def reference(self, own_traj, behaviour, situation, params, config, last_offsets=(1.0, 0.0)):
        from .. import reference_smooth as rs

        t = [k * float(config.dt) for k in range(len(own_traj))]
        applied = rs.applied_trajectory(situation, behaviour, last_offsets, params, config) if self.transitional else None
        return rs.sbmpc_cost(own_traj, rs.obstacle_targets(situation, params, config), t, component="joint",
                             aggregation=self.aggregation, kappa=self.kappa,
                             lambda_T=self.lambda_T if self.transitional else 0.0, applied_traj=applied, **self._kw())


__all__ = [
    "DEFAULT_D_SAFE", "DEFAULT_K_COLL", "DEFAULT_KAPPA", "DEFAULT_P", "DEFAULT_Q", "DEFAULT_W_COLL", "RISK_D_FLOOR",
    "AGGREGATIONS", "RISK_FORMS", "COLREGS_FORMS", "COMPLETIONS", "coll_slope", "sigma_coll", "adhoc_risk",
    "collision_weight", "collision_hazard", "colregs_boolean_xy", "colregs_boolean", "aggregate", "pair_components",
    "DEFAULT_LAMBDA_T", "transitional_situation", "passing_side", "transitional_indicator",
    "sbmpc_costs", "smooth_cost_term", "context_pairs", "term_value", "SmoothCollisionTerm", "FuzzyColregsTerm",
    "SbmpcHazardTerm",
]
