"""The parallel PSB-MPC evaluator (paper Algorithm 3) — pure, traceable JAX.

Axes: B behaviours, O obstacles, S scenarios, P polygons, V vertices, T = N+1 time samples.

* **Prediction** (:func:`context`): own-ship rollouts over B (kernel 1), obstacle scenarios and their
  covariances (independent of the behaviour).
* **Cost terms** (:mod:`psbmpc_jax.costs`): each term is a small unit — collision, COLREGS, grounding, path
  by default — returning a cost per behaviour (kernel 2: per (l, i, s) and per (l, j) work items inside).
* **Reduction** on the device: the sum of the terms, then the argmin.

:func:`evaluate_arrays` is the grid search over a behaviour table (compact layouts, the fast path);
:func:`psbmpc_jax.objective.objective` is the same cost of one control input through dense, gradient-safe
layouts.  Both call :func:`cost_terms`.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from .costs.base import Context, check_terms, needs_applied
from .costs.collision import CollisionTerm
from .costs.colregs import ColregsTerm
from .costs.grounding_term import GroundingTerm
from .costs.path import PathTerm
from .layouts import resolve_rollout_kernel, resolve_unroll
from .obstacles import obstacle_covariances, obstacle_scenarios, positional_stats
from .ownship import Trajectory, make_path, ownship_rollouts
from .jitting import canonical_jit
from .packing import SolveInputs
from .params import Params, PlannerConfig

#: The four terms of the paper's cost (eq. 9), in column order.
DEFAULT_TERMS = (CollisionTerm(), ColregsTerm(), GroundingTerm(), PathTerm())


class Evaluation(NamedTuple):
    """Everything one search produces (padded shapes; padded behaviours have cost +inf).

    ``best`` index and ``best_offsets [n_M, 2]``; ``total [B]``; ``costs``: term name -> ``[B]`` (by default
    ``do, colregs, so, path``); ``details``: per-behaviour arrays of the terms (by default ``C, mu [B, O, S]``,
    the collision cost and COLREGS indicator, and ``so_j [B, P]``, ``[B, 1]`` in grid mode); trajectories
    ``own`` (time-major ``[T, B]``) and ``obstacles`` (``[T, O, S]``); ``obs_cov [O, T, 4, 4]``; ``counters``:
    scalars (``n_pc_blocks``: (row, time block) pairs sent to the collision-probability estimator)."""

    best: jax.Array
    best_offsets: jax.Array
    total: jax.Array
    costs: dict
    details: dict
    own: Trajectory
    obstacles: Trajectory
    obs_cov: jax.Array
    counters: dict

    @property
    def C(self):
        return self.details["C"]

    @property
    def mu(self):
        return self.details["mu"]

    @property
    def so_j(self):
        return self.details["so_j"]

    @property
    def n_pc_blocks(self):
        return self.counters.get("n_pc_blocks", jnp.int32(0))


def context(inputs: SolveInputs, last_offsets, params: Params, config: PlannerConfig, *,
            dense: bool = False, applied: bool = False) -> Context:
    """Rollouts and predictions of one solve: what every cost term reads (``applied``: also the own-ship rollout
    of ``last_offsets`` held over the horizon, ``Context.own_applied``)."""
    # packed inputs have NumPy leaves: outside jit, NumPy arithmetic would promote int32/float32 (a no-op on
    # traced values)
    inputs = jax.tree.map(jnp.asarray, inputs)
    n_steps, dt = config.n_steps, config.dt
    own_in, obs_in = inputs.own, inputs.obstacles
    dtype = own_in.state.dtype
    t = jnp.arange(n_steps + 1, dtype=dtype) * dt
    offsets = inputs.behaviours.offsets
    own_path = make_path(own_in.wx, own_in.wy, own_in.n)
    plat = getattr(config, "layout_platform", "auto")
    unroll = resolve_unroll(getattr(config, "rollout_unroll", 1), plat)
    kernel = resolve_rollout_kernel(getattr(config, "rollout_kernel", "scan"), plat)
    own = ownship_rollouts(own_in.state, own_path, own_in.U_d, offsets, params, n_steps, dt, unroll=unroll,
                           kernel=kernel)
    own_applied = None
    if applied:
        held = jnp.broadcast_to(jnp.asarray(last_offsets, dtype), (1, offsets.shape[1], 2))
        own_applied = ownship_rollouts(own_in.state, own_path, own_in.U_d, held, params, n_steps, dt, unroll=unroll,
                                       kernel=kernel)
    n_o, n_s = obs_in.probs.shape
    obs = obstacle_scenarios(obs_in.state, obs_in.wx, obs_in.wy, obs_in.n, obs_in.n_ps, n_s, params, n_steps, dt,
                             leg_u=obs_in.leg_u, unroll=unroll, kernel=kernel)
    cov = obstacle_covariances(obs_in.cov, params, n_steps, dt)
    scen_valid = obs_in.mask[:, None] & (jnp.arange(n_s)[None, :] < obs_in.n_ps[:, None])
    return Context(
        t=t, offsets=offsets, last_offsets=jnp.asarray(last_offsets, dtype), own=own, obstacles=obs, obs_cov=cov,
        cov_stats=positional_stats(cov), scen_valid=scen_valid,
        radius=params.d_safe + 0.5 * (own_in.length + obs_in.length), zeta_k=obs_in.zeta * params.K_coll,
        scen_weight=(obs_in.weight * obs_in.mask)[:, None] * obs_in.probs, world=inputs.world, dense=dense,
        own_applied=own_applied, obstacle_r18=obs_in.r18)


def cost_terms(ctx: Context, params: Params, samples, config: PlannerConfig, terms=DEFAULT_TERMS):
    """``(costs, details, counters)``: every term's ``[B]`` cost by name, their details and counters."""
    costs, details, counters = {}, {}, {}
    for term in terms:
        out = term(ctx, params, config, samples)
        costs[term.name] = out.value
        details.update(out.details)
        counters.update(out.counters)
    return costs, details, counters


def evaluate_arrays(inputs: SolveInputs, last_offsets, params: Params, samples, config: PlannerConfig,
                    terms=DEFAULT_TERMS) -> Evaluation:
    """Un-jitted grid search over ``inputs.behaviours`` (jit it through :func:`evaluate`)."""
    ctx = context(inputs, last_offsets, params, config, applied=needs_applied(terms))
    costs, details, counters = cost_terms(ctx, params, samples, config, terms)
    total = jnp.where(inputs.behaviours.mask, sum(costs.values()), jnp.inf)
    best = jnp.argmin(total)
    return Evaluation(best, inputs.behaviours.offsets[best], total, costs, details, ctx.own, ctx.obstacles,
                      ctx.obs_cov, counters)


@canonical_jit(static_argnames=("config",))
def evaluate(inputs: SolveInputs, last_offsets, params: Params, samples, config: PlannerConfig,
             terms=DEFAULT_TERMS) -> Evaluation:
    """Jitted grid search: one compile per (config, term classes, padded shapes, dtype); values never
    recompile (term parameters are traced leaves)."""
    return evaluate_arrays(inputs, last_offsets, params, samples, config, terms)


__all__ = ["Evaluation", "DEFAULT_TERMS", "context", "cost_terms", "evaluate", "evaluate_arrays", "check_terms"]
