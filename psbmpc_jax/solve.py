"""One solve step, pure and jitted: search the behaviour table, pick the best, return the next planner state.

>>> plan, state, ev = solve(inputs, state, params, samples, config=config)

:class:`~psbmpc_jax.Planner`, the closed-loop simulator (both batch modes), the benchmark and the
multi-device evaluator all go through :func:`solve` (or, for the sharded search, through :func:`select`).
The planner state is a pytree (optax ``init/update`` style): the offsets applied after the previous solve
and a slot for warm starts; it is returned, never mutated.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .evaluate import DEFAULT_TERMS, Evaluation, evaluate_arrays
from .packing import SolveInputs
from .params import Params, PlannerConfig

#: ``Plan.status`` values.
STATUS_OK = 0
STATUS_NO_FINITE_BEHAVIOUR = 1      # every behaviour's total is inf or NaN: the plan is meaningless
STATUS_NAMES = {STATUS_OK: "ok", STATUS_NO_FINITE_BEHAVIOUR: "no finite behaviour"}


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
    (term name -> scalar), and ``status`` (:data:`STATUS_OK` or :data:`STATUS_NO_FINITE_BEHAVIOUR`)."""

    best: jax.Array
    offsets: jax.Array
    total: jax.Array
    costs: dict
    status: jax.Array


def select(ev: Evaluation, state: PlannerState) -> tuple[Plan, PlannerState]:
    """The chosen behaviour of a search and the next planner state (its first maneuver applied)."""
    best = ev.best
    total = ev.total[best]
    status = jnp.where(jnp.isfinite(total), STATUS_OK, STATUS_NO_FINITE_BEHAVIOUR).astype(jnp.int32)
    plan = Plan(best, ev.best_offsets, total, {k: v[best] for k, v in ev.costs.items()}, status)
    last = jnp.asarray(state.last_offsets, ev.best_offsets.dtype)
    nxt = _state_from_leaves(None, (jnp.where(status == STATUS_OK, ev.best_offsets[0], last), state.warm_start))
    return plan, nxt


def solve_arrays(inputs: SolveInputs, state: PlannerState, params: Params, samples, config: PlannerConfig,
                 terms=DEFAULT_TERMS) -> tuple[Plan, PlannerState, Evaluation]:
    """Un-jitted solve step (vmap it, or jit it through :func:`solve`)."""
    ev = evaluate_arrays(inputs, state.last_offsets, params, samples, config, terms)
    plan, nxt = select(ev, state)
    return plan, nxt, ev


@partial(jax.jit, static_argnames=("config",))
def solve(inputs: SolveInputs, state: PlannerState, params: Params, samples, config: PlannerConfig,
          terms=DEFAULT_TERMS) -> tuple[Plan, PlannerState, Evaluation]:
    """One jitted solve step: grid search, selection, next state.  Returns ``(plan, next_state, evaluation)``;
    one compile per (config, term classes, padded shapes, dtype)."""
    return solve_arrays(inputs, state, params, samples, config, terms)


__all__ = ["PlannerState", "Plan", "select", "solve", "solve_arrays", "STATUS_OK", "STATUS_NO_FINITE_BEHAVIOUR",
           "STATUS_NAMES"]
