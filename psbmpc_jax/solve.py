"""One solve step, pure and jitted: search the behaviour table, pick the best, return the next planner state.

>>> plan, state, ev = solve(inputs, state, params, samples, config=config)

:class:`~psbmpc_jax.Planner`, the closed-loop simulator (both batch modes), the benchmark and the
multi-device evaluator all go through :func:`solve` (or, for the sharded search, through :func:`select`).
The planner state is a pytree (optax ``init/update`` style): the offsets applied after the previous solve
and a slot for warm starts; it is returned, never mutated.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .array_types import HostOrDevice, Shape
from .costs.grounding import grounding_g
from .evaluate import DEFAULT_TERMS, Evaluation, evaluate_arrays
from .jitting import canonical_jit
from .packing import ChartArrays, SolveInputs
from .params import Params, PlannerConfig
from .status import STATUS_NAMES, Status

#: ``Plan.status`` values (of the library's one status enum, :class:`psbmpc_jax.status.Status`).
STATUS_OK = int(Status.OK)
STATUS_NO_FINITE_BEHAVIOUR = int(Status.NO_FINITE_BEHAVIOUR)   # every behaviour's total is inf or NaN
STATUS_INVALID_INPUT = int(Status.INVALID_INPUT)     # a non-finite input or a parameter out of its range


@dataclass(frozen=True)
class PlannerState:
    """Planner memory between solves (a pytree): ``last_offsets`` (u, chi) applied after the previous solve,
    and ``warm_start`` (any pytree, or None) for solvers that refine from a previous solution.

    Built on the host it is validated (u in [0, 1], |chi| <= pi); inside jit its leaves are arrays."""

    last_offsets: Any = (1.0, 0.0)
    warm_start: Any = None

    def __post_init__(self) -> None:
        try:
            u, chi = (float(v) for v in np.asarray(self.last_offsets, dtype=float).reshape(-1))
        except (TypeError, ValueError):
            raise ValueError(f"PlannerState.last_offsets must be two numbers (u, chi), got "
                             f"{self.last_offsets!r}") from None
        if not (np.isfinite(u) and np.isfinite(chi)) or not 0 <= u <= 1 or abs(chi) > np.pi + 1e-12:
            raise ValueError(
                f"PlannerState.last_offsets must be (u in [0, 1], chi in [-pi, pi] rad), got {self.last_offsets}"
            )
        object.__setattr__(self, "last_offsets", (u, chi))


def _state_from_leaves(_, leaves):
    state = object.__new__(PlannerState)       # traced leaves: no host validation
    object.__setattr__(state, "last_offsets", leaves[0])
    object.__setattr__(state, "warm_start", leaves[1])
    return state


def _state_leaves(s):
    last = s.last_offsets
    if isinstance(last, tuple):          # host state: one [2] leaf, the same treedef as a traced state
        last = np.asarray(last, dtype=float)
    return (last, s.warm_start), None


jax.tree_util.register_pytree_node(PlannerState, _state_leaves, _state_from_leaves)


class Plan(NamedTuple):
    """The decision of one solve: ``best`` index, its ``offsets [n_M, 2]``, its ``total`` and ``costs``
    (term name -> scalar), and ``status`` (:data:`STATUS_OK`, :data:`STATUS_NO_FINITE_BEHAVIOUR` or, from
    :func:`solve`, :data:`STATUS_INVALID_INPUT`: a non-finite input or a parameter out of range,
    :func:`inputs_valid`; the next state then keeps the previous offsets)."""

    best: Annotated[jax.Array, Shape("")]
    offsets: Annotated[jax.Array, Shape("n_M 2")]
    total: Annotated[jax.Array, Shape("")]
    costs: dict
    status: Annotated[jax.Array, Shape("")]


#: Totals within this many float epsilons (relative) of the minimum are ties (docs/algorithm.md §11).
TIE_EPS = 8
#: A cost that varies by less than this many float epsilons (relative) over the behaviours is "the same for
#: every behaviour": a hazard at the present (docs/algorithm.md §11).
SATURATION_EPS = 64


def _same_for_all(x, valid, rtol):
    """``x [B, ...]`` -> ``[...]``: positive and equal (to ``rtol``) over the valid behaviours."""
    v = valid.reshape(valid.shape + (1,) * (x.ndim - 1))
    hi = jnp.max(jnp.where(v, x, -jnp.inf), axis=0)
    lo = jnp.min(jnp.where(v, x, jnp.inf), axis=0)
    return (hi > 0) & jnp.isfinite(hi) & (hi - lo <= rtol * hi)


def signed_distance(px: Annotated[jax.Array, Shape("B")], py: Annotated[jax.Array, Shape("B")],
                    chart: ChartArrays) -> Annotated[jax.Array, Shape("P B")]:
    """Signed distance of points ``px, py [B]`` to every polygon of a packed chart
    (:class:`~psbmpc_jax.packing.ChartArrays`): ``[P, B]``, negative inside (minus the distance to the
    boundary; even-odd rule over the polygon's rings), +inf for padding polygons."""
    n_v = chart.vertices.shape[1]

    def one(poly):
        verts, nxt, n, real = poly
        ax, ay = verts[:, 0, None], verts[:, 1, None]                          # [V, 1]
        bx, by = verts[nxt, 0][:, None], verts[nxt, 1][:, None]
        edge = (jnp.arange(n_v) < n)[:, None]
        ex, ey = bx - ax, by - ay
        l2 = ex * ex + ey * ey
        t = jnp.where(l2 > 0, jnp.clip(((px - ax) * ex + (py - ay) * ey) / jnp.where(l2 > 0, l2, 1.0), 0.0, 1.0),
                      0.0)
        qx, qy = ax + t * ex - px, ay + t * ey - py
        d = jnp.sqrt(jnp.min(jnp.where(edge, qx * qx + qy * qy, jnp.inf), axis=0))
        dy_ = jnp.where(by != ay, by - ay, 1.0)
        cross = edge & ((ay > py) != (by > py)) & (px < ax + (py - ay) * (bx - ax) / dy_)
        inside = (jnp.sum(cross, axis=0) % 2) == 1
        return jnp.where(real, jnp.where(inside, -d, d), jnp.inf)

    # vmap, not a loop over the polygons: [P, V, B] is small for the one or two points per behaviour asked here
    return jax.vmap(one)((chart.vertices, chart.next, chart.n, chart.mask))


def selection_cost(ev: Evaluation, inputs: SolveInputs, params: Params | None = None,
                   config: PlannerConfig | None = None) -> Annotated[jax.Array, Shape("B")]:
    """The cost :func:`select` ranks the behaviours by (docs/algorithm.md §11): the total, except where a hazard
    is at the present — a cost the same for every behaviour because its maximum over time is at t_0, which
    every behaviour shares.  Such a cost says nothing about which behaviour escapes it, so it is replaced:

    * collision: for every (obstacle, scenario) whose C is the same for every behaviour, C is replaced by its
      maximum over the future steps k >= 1 (detail ``C_future``) and its COLREGS indicator is dropped (the
      encounter classification is meaningless at zero range: the collision is in progress);
    * grounding (needs ``params`` and ``config``): when some polygon's cost is the same for every behaviour
      (own-ship inside land, or within d_safe of it and every behaviour moving away; in grid mode the
      nearest-land cost as a whole), the saturated polygon with the smallest signed distance from the
      own-ship now (the one it is in) is ranked by g at the horizon end with the signed distance to it
      (negative inside land: the linear branch of g continued, so the cost keeps decreasing towards the
      boundary and beyond it); other saturated polygons (within d_safe of two pieces of land at once) are
      left out of the ranking — their cost is the same for every behaviour.

    Terms without their details (custom terms) are left as they are.  Returns ``rank [B]``."""
    total = ev.total
    dtype = total.dtype
    valid = inputs.behaviours.mask & jnp.isfinite(total)
    rtol = SATURATION_EPS * jnp.finfo(dtype).eps
    adj = jnp.zeros_like(total)
    hazard = jnp.asarray(False)
    det, costs = ev.details, ev.costs
    if "C" in det and "C_future" in det and "do" in costs:
        obs = inputs.obstacles
        w = ((obs.weight * obs.mask)[:, None] * obs.probs).astype(dtype)             # [O, S]
        sat = _same_for_all(det["C"], valid, rtol) & (w > 0)
        adj = adj - jnp.sum(jnp.where(sat, w * (det["C"] - det["C_future"]), 0.0), axis=(1, 2))
        if "mu" in det and "colregs" in costs and params is not None:
            adj = adj - params.kappa * jnp.sum(jnp.where(sat, w * det["mu"], 0.0), axis=(1, 2))
        hazard = hazard | jnp.any(sat)
    chart = inputs.world.polygons
    if ("so_j" in det and "so" in costs and params is not None and config is not None
            and chart.mask.shape[0] > 0):
        so_j = det["so_j"]                                                           # [B, P] or [B, 1] (grid)
        grid = config.grounding_mode == "grid"
        sat_j = _same_for_all(so_j, valid, rtol)
        any_sat = jnp.any(sat_j)
        t_end = jnp.asarray(config.n_steps * config.dt, dtype)
        # the saturated polygon the own-ship is in (or nearest to) now gets the escape cost
        s_now = signed_distance(ev.own.x[0, :1], ev.own.y[0, :1], chart)[:, 0]      # [P], one point: cheap
        j = jnp.argmin(jnp.where(chart.mask if grid else sat_j & chart.mask, s_now, jnp.inf))

        def escape(_):
            one = type(chart)(chart.vertices[j][None], chart.next[j][None], chart.n[j][None], chart.mask[j][None])
            s_end = signed_distance(ev.own.x[-1], ev.own.y[-1], one)[0]             # [B] at the horizon end
            return grounding_g(s_end, t_end, 0.0, params).astype(dtype)

        g_end = jax.lax.cond(any_sat, escape, lambda _: jnp.zeros_like(total), None)
        if grid:
            so_sel = jnp.where(sat_j[0], g_end, so_j[:, 0])
        else:
            so_sel = jnp.maximum(jnp.max(jnp.where(sat_j, 0.0, so_j), axis=1, initial=0.0), g_end)
        adj = adj + jnp.where(any_sat, so_sel - costs["so"], 0.0)
        hazard = hazard | any_sat
    rank = jnp.where(hazard, total + adj, total)
    return jnp.where(jnp.isfinite(rank), rank, total)


def break_ties(rank: Annotated[jax.Array, Shape("B")], valid: Annotated[HostOrDevice, Shape("B")],
               offsets: Annotated[HostOrDevice, Shape("B n_M 2")]) -> Annotated[jax.Array, Shape("")]:
    """Index of the smallest ``rank`` among ``valid`` behaviours; ranks within :data:`TIE_EPS` float epsilons
    (relative) of it are ties, broken by the first maneuver: the smallest course offset |chi_1|, then
    starboard (chi_1 >= 0) before port, then the highest speed factor u_1, then the lowest index.  -1 when no
    behaviour is valid."""
    r = jnp.where(valid, rank, jnp.inf)
    m = jnp.min(r)
    tol = TIE_EPS * jnp.finfo(r.dtype).eps * jnp.maximum(jnp.abs(m), jnp.finfo(r.dtype).tiny)
    cand = valid & (r <= m + tol)
    u1, chi1 = offsets[:, 0, 0], offsets[:, 0, 1]
    a = jnp.abs(chi1)
    cand = cand & (a <= jnp.min(jnp.where(cand, a, jnp.inf)))
    stbd = chi1 >= 0
    cand = cand & jnp.where(jnp.any(cand & stbd), stbd, True)
    cand = cand & (u1 >= jnp.max(jnp.where(cand, u1, -jnp.inf)))
    return jnp.where(jnp.any(cand), jnp.argmax(cand), -1).astype(jnp.int32)


def select(ev: Evaluation, state: PlannerState, inputs: SolveInputs | None = None, params: Params | None = None,
           config: PlannerConfig | None = None) -> tuple[Plan, PlannerState]:
    """The chosen behaviour of a search and the next planner state (its first maneuver applied).

    With ``inputs`` (and ``params``, ``config``: :func:`solve` passes them) the choice is the smallest
    :func:`selection_cost` with ties broken by :func:`break_ties` (docs/algorithm.md §11); without, it is
    ``ev.best`` (the plain argmin of the totals, ties to the lowest index)."""
    best, best_offsets = ev.best, ev.best_offsets
    if inputs is not None:
        valid = inputs.behaviours.mask & jnp.isfinite(ev.total)
        pick = break_ties(selection_cost(ev, inputs, params, config), valid, inputs.behaviours.offsets)
        best = jnp.where(pick >= 0, pick, ev.best).astype(jnp.asarray(ev.best).dtype)
        best_offsets = jnp.asarray(inputs.behaviours.offsets)[best]
    total = ev.total[best]
    status = jnp.where(jnp.isfinite(total), STATUS_OK, STATUS_NO_FINITE_BEHAVIOUR).astype(jnp.int32)
    plan = Plan(best, best_offsets, total, {k: v[best] for k, v in ev.costs.items()}, status)
    last = jnp.asarray(state.last_offsets, best_offsets.dtype)
    nxt = _state_from_leaves(None, (jnp.where(status == STATUS_OK, best_offsets[0], last), state.warm_start))
    return plan, nxt


def _finite_where(a, valid):
    """All of ``a`` finite where ``valid`` (broadcast over ``a``'s trailing axes)."""
    a = jnp.asarray(a)
    v = jnp.asarray(valid).reshape(jnp.shape(valid) + (1,) * (a.ndim - jnp.ndim(valid)))
    return jnp.all(jnp.where(v, jnp.isfinite(a), True))


def params_valid(params: Params):
    """Device-side (traceable, no host sync) form of :func:`psbmpc_jax.params.validate_params`'s value checks:
    every leaf finite (``t_ts``: > 0 or NaN), the positive / non-negative / unit-interval groups in range,
    ``|wind_dir| <= 2 pi`` and a PSD OU diffusion.  A scalar bool."""
    from .params import NON_NEGATIVE_FIELDS, POSITIVE_FIELDS, UNIT_INTERVAL_FIELDS

    ok = jnp.asarray(True)
    for name in Params.__dataclass_fields__:
        v = jnp.asarray(getattr(params, name))
        if name == "t_ts":
            ok &= jnp.all(jnp.isnan(v) | (jnp.isfinite(v) & (v > 0)))
            continue
        ok &= jnp.all(jnp.isfinite(v))
        if name in POSITIVE_FIELDS:
            ok &= jnp.all(v > 0)
        elif name in NON_NEGATIVE_FIELDS:
            ok &= jnp.all(v >= 0)
        elif name in UNIT_INTERVAL_FIELDS:
            ok &= jnp.all((v > 0) & (v <= 1))
    ok &= jnp.all(jnp.abs(jnp.asarray(params.wind_dir)) <= 2 * np.pi)
    sx2, sy2 = jnp.asarray(params.sigma_x) ** 2, jnp.asarray(params.sigma_y) ** 2
    return ok & jnp.all(jnp.asarray(params.sigma_xy) ** 2 <= sx2 * sy2 * (1 + 1e-6))


def inputs_valid(inputs: SolveInputs, last_offsets, params: Params, samples, behaviours: bool = True):
    """A scalar bool, computed on the device (traceable; no host sync): every real (unmasked) input finite —
    own-ship state, route, U_d and length; obstacle states, covariances, probabilities, weights; polygon
    vertices; the behaviour offsets (``behaviours``); ``last_offsets``; the sample table — and the parameters
    in range (:func:`params_valid`).  :func:`solve` reports :data:`STATUS_INVALID_INPUT` when it is False; the
    host-side checks (:class:`~psbmpc_jax.situation.Situation`, :func:`~psbmpc_jax.params.validate_params`)
    refuse the same inputs with a message."""
    own, obs = inputs.own, inputs.obstacles
    w_slots = jnp.arange(own.wx.shape[-1]) < jnp.reshape(own.n, (-1, 1))
    ok = (jnp.all(jnp.isfinite(own.state)) & _finite_where(own.wx, w_slots) & _finite_where(own.wy, w_slots)
          & jnp.all(jnp.isfinite(own.U_d)) & jnp.all(jnp.isfinite(own.length)))
    m = obs.mask
    ok &= (_finite_where(obs.state, m) & _finite_where(obs.cov, m) & _finite_where(obs.probs, m)
           & _finite_where(obs.weight, m) & _finite_where(obs.zeta, m) & _finite_where(obs.length, m))
    chart = inputs.world.polygons
    v_slots = (jnp.arange(chart.vertices.shape[1]) < chart.n[:, None]) & chart.mask[:, None]
    ok &= _finite_where(chart.vertices, v_slots)
    if behaviours:
        ok &= _finite_where(inputs.behaviours.offsets, inputs.behaviours.mask)
    ok &= jnp.all(jnp.isfinite(jnp.asarray(last_offsets)))
    if samples is not None:
        ok &= jnp.all(jnp.isfinite(samples))
    return ok & params_valid(params)


def solve_arrays(inputs: SolveInputs, state: PlannerState, params: Params, samples, config: PlannerConfig,
                 terms=DEFAULT_TERMS) -> tuple[Plan, PlannerState, Evaluation]:
    """Un-jitted solve step (vmap it, or jit it through :func:`solve`).  The evaluation returned carries the
    selected behaviour in ``best`` / ``best_offsets``."""
    inputs = jax.tree.map(jnp.asarray, inputs)
    ev = evaluate_arrays(inputs, state.last_offsets, params, samples, config, terms)
    plan, nxt = select(ev, state, inputs, params, config)
    # a non-finite input or a parameter out of range: status STATUS_INVALID_INPUT and the previous offsets
    # kept (computed on the device: no host sync in the hot path)
    ok = inputs_valid(inputs, state.last_offsets, params, samples)
    plan = plan._replace(status=jnp.where(ok, plan.status, STATUS_INVALID_INPUT).astype(jnp.int32))
    last = jnp.asarray(state.last_offsets, nxt.last_offsets.dtype)
    nxt = _state_from_leaves(None, (jnp.where(ok, nxt.last_offsets, last), nxt.warm_start))
    return plan, nxt, ev._replace(best=plan.best, best_offsets=plan.offsets)


@canonical_jit(static_argnames=("config",))
def solve(inputs: SolveInputs, state: PlannerState, params: Params, samples, config: PlannerConfig,
          terms=DEFAULT_TERMS) -> tuple[Plan, PlannerState, Evaluation]:
    """One jitted solve step: grid search, selection, next state.  Returns ``(plan, next_state, evaluation)``;
    one compile per (config, term classes, padded shapes, dtype)."""
    return solve_arrays(inputs, state, params, samples, config, terms)


__all__ = ["PlannerState", "Plan", "select", "selection_cost", "break_ties", "signed_distance", "solve",
           "solve_arrays", "inputs_valid", "params_valid", "STATUS_OK", "STATUS_NO_FINITE_BEHAVIOUR",
           "STATUS_INVALID_INPUT", "STATUS_NAMES", "TIE_EPS", "SATURATION_EPS"]
