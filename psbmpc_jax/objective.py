"""The PSB-MPC cost of ONE own-ship control input: dense, gradient-safe, differentiable.

>>> total, costs = objective(controls, inputs, params, samples, config=config)
>>> g = jax.grad(lambda c: objective(c, inputs, params, samples, config=config)[0])(controls)

``controls`` is either a behaviour — per-maneuver offsets ``[n_M, 2]`` (speed factor, course offset [rad]),
maneuver m starting at step round(m t_ts / dt) as in the grid search — or, with ``per_step=True``,
per-step controls ``[N, 2]`` (N = T / dt; step k applies row k, i.e. n_M = N maneuvers with t_ts = dt; the
path cost then averages its per-maneuver terms over the N steps).  Obstacles, scenarios and chart come from
``inputs`` (:func:`psbmpc_jax.packing.pack`; its behaviour table is ignored).

It is the same cost as the grid search, term by term: ``vmap(objective)`` over a behaviour table equals
:func:`psbmpc_jax.evaluate.evaluate` on it (tested in float64 for every estimator and grounding mode).  The
difference is the layout: every (time, obstacle, scenario) point goes through the collision estimator (no
compaction, no ``while_loop``), so forward and reverse mode both work.

Smoothness: the collision term with the ``quadrature`` estimator, the grounding term (exact or grid; on a
grid line the derivative of the + side cell) and the path term are piecewise smooth in the controls; the
COLREGS indicator is piecewise constant (its gradient is 0 — finite, but no descent direction).  The
``mc``/``ce`` estimates are piecewise constant too; their derivative is the score-function estimate of the
collision probability's derivative from the same samples (:func:`psbmpc_jax.costs.collision.pc_mc`):
unbiased, the quadrature's derivative up to sampling error, not the derivative of the sampled value.  With
``smooth=True`` the collision term uses the quadrature estimator whatever ``config.estimator`` says.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp

from .costs.base import needs_applied
from .evaluate import DEFAULT_TERMS, context, cost_terms
from .packing import BehaviourArrays, SolveInputs
from .params import Params, PlannerConfig


def _check_controls(controls, config: PlannerConfig, per_step: bool):
    if controls.ndim != 2 or controls.shape[-1] != 2:
        raise ValueError(f"controls must be [n_M, 2] (or [N, 2] per step), got shape {controls.shape}")
    if per_step and controls.shape[0] != config.n_steps:
        raise ValueError(f"per-step controls must be [N, 2] with N = T / dt = {config.n_steps}, got "
                         f"{controls.shape[0]} rows")


def objective(controls, inputs: SolveInputs, params: Params, samples, config: PlannerConfig,
              terms=DEFAULT_TERMS, *, last_offsets=None, per_step: bool = False, smooth: bool = False):
    """Total cost and the cost of each term (dict of scalars) of one control input.

    Args:
        controls: ``[n_M, 2]`` per-maneuver offsets, or ``[N, 2]`` per-step controls with ``per_step=True``.
        inputs: packed situation (:func:`psbmpc_jax.packing.pack`); the behaviour table in it is unused.
        params, samples, config, terms: as for :func:`psbmpc_jax.evaluate.evaluate`.
        last_offsets: the planner state's last applied (u, chi); default (1, 0).
        per_step: the rows of ``controls`` are per time step.
        smooth: evaluate the collision term with the quadrature estimator (the smooth form).
    """
    controls = jnp.asarray(controls).astype(inputs.own.state.dtype)     # the inputs' (config's) dtype
    _check_controls(controls, config, per_step)
    if per_step:
        params = params.replace(t_ts=jnp.asarray(config.dt, controls.dtype))
    if smooth and config.estimator != "quadrature":
        config = config.replace(estimator="quadrature")
        samples = None
    if last_offsets is None:
        last_offsets = jnp.asarray([1.0, 0.0], controls.dtype)
    one = inputs._replace(behaviours=BehaviourArrays(controls[None], jnp.ones((1,), bool)))
    ctx = context(one, last_offsets, params, config, dense=True, applied=needs_applied(terms))
    costs, _, _ = cost_terms(ctx, params, samples, config, terms)
    costs = {k: v[0] for k, v in costs.items()}
    return sum(costs.values()), costs


@partial(jax.jit, static_argnames=("config", "per_step", "smooth"))
def value_and_grad(controls, inputs: SolveInputs, params: Params, samples, config: PlannerConfig,
                   terms=DEFAULT_TERMS, last_offsets=None, per_step: bool = False, smooth: bool = True):
    """Jitted ``(total, costs), d total / d controls`` (reverse mode) of :func:`objective`."""
    fn = lambda c: objective(c, inputs, params, samples, config, terms, last_offsets=last_offsets,  # noqa: E731
                             per_step=per_step, smooth=smooth)
    return jax.value_and_grad(fn, has_aux=True)(controls)


__all__ = ["objective", "value_and_grad"]
