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

import math
from functools import partial
from typing import Annotated, Any

import jax
import jax.numpy as jnp
import numpy as np

from .array_types import HostOrDevice, Shape
from .costs.base import needs_applied
from .evaluate import DEFAULT_TERMS, context, cost_terms
from .packing import BehaviourArrays, SolveInputs
from .params import Params, PlannerConfig
from .solve import inputs_valid


#: The box the cost is defined on: speed factor u in [0, 1], course offset chi in [-pi, pi] rad (the grid's and
#: the refinement's box; beyond u = 1 the path cost K_u (1 - u) turns into a reward).
U_RANGE = (0.0, 1.0)
CHI_MAX = math.pi


def _check_controls(controls, config: PlannerConfig, per_step: bool):
    if controls.ndim != 2 or controls.shape[-1] != 2:
        raise ValueError(f"controls must be [n_M, 2] (or [N, 2] per step), got shape {controls.shape}")
    if per_step and controls.shape[0] != config.n_steps:
        raise ValueError(f"per-step controls must be [N, 2] with N = T / dt = {config.n_steps}, got "
                         f"{controls.shape[0]} rows")


def _concrete(x) -> np.ndarray | None:
    """``x`` as NumPy when it is a concrete (not traced) array, else None (inside jit, grad, vmap)."""
    if isinstance(x, jax.core.Tracer):
        return None
    return np.asarray(x)


def check_offsets(a: np.ndarray, name: str) -> None:
    """Host check of (u, chi) rows ``[..., 2]``: finite, u in [0, 1], |chi| <= pi; ValueError naming the row."""
    bad = ~np.isfinite(a)
    if np.any(bad):
        row = tuple(int(i) for i in np.argwhere(bad)[0])
        raise ValueError(f"{name}{list(row)} = {a[row]} is not finite (the cost of NaN or inf controls is undefined)")
    for col, ok, what in ((0, (a[..., 0] >= U_RANGE[0]) & (a[..., 0] <= U_RANGE[1]),
                           "speed factor u in [0, 1] (beyond 1 the path cost turns negative)"),
                          (1, np.abs(a[..., 1]) <= CHI_MAX, "course offset chi in [-pi, pi] rad (degrees given?)")):
        if not np.all(ok):
            row = tuple(int(i) for i in np.argwhere(~ok)[0])
            raise ValueError(f"{name}{list(row) + [col]} = {a[row + (col,)]:g}: the cost is defined for {what}")


def _valid_controls(controls):
    """Device form of :func:`check_offsets` (a scalar bool; traceable)."""
    u, chi = controls[..., 0], controls[..., 1]
    return jnp.all(jnp.isfinite(controls)) & jnp.all((u >= U_RANGE[0]) & (u <= U_RANGE[1]) & (jnp.abs(chi) <= CHI_MAX))


def _differentiable_rollouts(config: PlannerConfig) -> PlannerConfig:
    """The objective is differentiated through the own-ship rollout, and the Pallas rollout kernel
    (:mod:`psbmpc_jax.rollout_kernel`) has no derivative rule: ``rollout_kernel="auto"`` (a GPU's default) is
    taken as ``"scan"`` here, an explicit ``"pallas"`` is refused."""
    kernel = getattr(config, "rollout_kernel", "scan")
    if kernel == "pallas":
        raise ValueError("PlannerConfig.rollout_kernel='pallas' cannot serve the objective: it is differentiated "
                         "through the own-ship rollout and the Pallas rollout kernel has no derivative rule; use "
                         "'scan' or 'auto' (the objective takes 'auto' as 'scan')")
    return config if kernel == "scan" else config.replace(rollout_kernel="scan")


def objective(controls: Annotated[HostOrDevice, Shape("K 2")], inputs: SolveInputs, params: Params, samples,
              config: PlannerConfig, terms=DEFAULT_TERMS, *, last_offsets: Annotated[Any, Shape("2")] = None,
              per_step: bool = False,
              smooth: bool = False) -> tuple[Annotated[jax.Array, Shape("")], dict[str, jax.Array]]:
    """Total cost and the cost of each term (dict of scalars) of one control input.

    Args:
        controls: ``[K, 2]``: K = n_M per-maneuver offsets, or K = N per-step controls with ``per_step=True``.
        inputs: packed situation (:func:`psbmpc_jax.packing.pack`); the behaviour table in it is unused.
        params, samples, config, terms: as for :func:`psbmpc_jax.evaluate.evaluate`.
        last_offsets: the planner state's last applied (u, chi); default (1, 0).
        per_step: the rows of ``controls`` are per time step.
        smooth: evaluate the collision term with the quadrature estimator (the smooth form).

    The rollouts are the ``lax.scan`` ones whatever ``config.rollout_kernel`` says for ``"auto"`` (the Pallas
    kernel a GPU's grid search uses has no derivative rule); ``"pallas"`` is refused.

    The cost is defined for finite controls with u in [0, 1] and |chi| <= pi.  Concrete (not traced) controls
    and ``last_offsets`` outside that raise ``ValueError`` naming the entry; traced ones (inside ``jit``,
    ``grad``, ``vmap``) give NaN costs, as do a non-finite input or a parameter out of range
    (:func:`psbmpc_jax.solve.inputs_valid`, checked on the device)."""
    host = _concrete(controls)
    if host is not None and host.dtype.kind in "iuf":       # checked mode: concrete controls are checked here
        check_offsets(host.astype(np.float64).reshape(-1, 2) if host.ndim == 2 and host.shape[-1] == 2 else
                      np.zeros((0, 2)), "controls")
    if last_offsets is not None and (lo := _concrete(last_offsets)) is not None:
        check_offsets(np.asarray(lo, np.float64).reshape(-1, 2), "last_offsets")
    controls = jnp.asarray(controls).astype(inputs.own.state.dtype)     # the inputs' (config's) dtype
    _check_controls(controls, config, per_step)
    config = _differentiable_rollouts(config)
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
    # traced controls outside the box, a non-finite input or a parameter out of range: every cost is NaN
    # (never a finite number such as a collision cost 0 for NaN positions); computed on the device
    ok = _valid_controls(controls) & _valid_controls(jnp.asarray(last_offsets)) & inputs_valid(
        one, last_offsets, params, samples, behaviours=False)
    costs = {k: jnp.where(ok, v[0], jnp.nan) for k, v in costs.items()}
    return sum(costs.values()), costs


@partial(jax.jit, static_argnames=("config", "per_step", "smooth"))
def value_and_grad(controls, inputs: SolveInputs, params: Params, samples, config: PlannerConfig,
                   terms=DEFAULT_TERMS, last_offsets=None, per_step: bool = False, smooth: bool = True):
    """Jitted ``(total, costs), d total / d controls`` (reverse mode) of :func:`objective`."""
    fn = lambda c: objective(c, inputs, params, samples, config, terms, last_offsets=last_offsets,  # noqa: E731
                             per_step=per_step, smooth=smooth)
    return jax.value_and_grad(fn, has_aux=True)(controls)


__all__ = ["objective", "value_and_grad"]
