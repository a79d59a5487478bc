"""What every cost term is: the context it reads, what it returns, and how a new one is declared.

A **cost term** is a small unit that owns

* its name — the column it adds to every evaluation, the CLI tables and the simulator records;
* its parameters — for the four terms of the paper these are fields of :class:`~psbmpc_jax.params.Params`
  (listed in the term's ``PARAMS``); a new term declares its own parameters as the fields of its class
  (a frozen dataclass registered as a pytree with :func:`cost_term`, so the values are traced leaves:
  changing them never recompiles and they can be differentiated);
* a pure function ``term(ctx, params, config, samples) -> TermValue``: the cost of every row of
  ``ctx`` (B behaviours or control sequences) and, optionally, per-row details (``C [B, O, S]`` ...);
* optionally, a ``reference(...)`` counterpart in float64 NumPy (the oracle of
  :func:`psbmpc_jax.reference.evaluate_reference`) and a ``smooth`` flag saying whether its value is a
  smooth function of the controls (the gradient refinement only trusts smooth terms).

The evaluator (:mod:`psbmpc_jax.evaluate`) builds one :class:`Context` per solve and adds the terms it is
given; the total is their sum.  The grid search (``dense=False``) may use a compacted layout; the
objective (``dense=True``, one control input) must be the same numbers through a dense, gradient-safe
layout.

Axes: B rows (behaviours), O obstacles, S scenarios, P polygons, T = N + 1 time samples.
"""

from __future__ import annotations

import dataclasses
from typing import Any, NamedTuple, dataclass_transform

import jax

from ..array_types import HostOrDevice
from ..ownship import Trajectory


class Context(NamedTuple):
    """Everything a cost term may read for one solve.

    ``t [T]`` times; ``offsets [B, n_M, 2]`` the control input of every row (speed factor, course offset;
    per-step controls are ``n_M = N``); ``last_offsets [2]`` the planner state; ``own`` the own-ship
    trajectories (time-major ``[T, B]``); ``obstacles`` the obstacle scenario trajectories (``[T, O, S]``);
    ``obs_cov [O, T, 4, 4]`` and ``cov_stats`` (S_xx, S_xy, S_yy, σ_max, each ``[O, T]``); ``scen_valid
    [O, S]``; ``radius [O]`` = d_safe + (l_0 + l_i)/2; ``zeta_k [O]`` = ζ_i K_coll; ``scen_weight [O, S]`` =
    w_i P_s (0 for padding); ``world`` the device chart (:class:`~psbmpc_jax.packing.WorldArrays`);
    ``dense`` (static) selects the dense, gradient-safe layout; ``own_applied`` the own-ship trajectory of the
    applied offsets ``last_offsets`` held over the horizon (``[T, 1]``), computed only for terms that declare
    ``needs_applied`` (the SB-MPC transitional term), else None; ``obstacle_r18 [O]`` the obstacles' Rule-18
    priority flags (``Obstacle.rule18``; None when the inputs carry none)."""

    t: jax.Array
    offsets: HostOrDevice
    last_offsets: jax.Array
    own: Trajectory
    obstacles: Trajectory
    obs_cov: jax.Array
    cov_stats: tuple
    scen_valid: HostOrDevice
    radius: HostOrDevice
    zeta_k: HostOrDevice
    scen_weight: HostOrDevice
    world: Any
    dense: bool
    own_applied: Any = None
    obstacle_r18: Any = None


def needs_applied(terms) -> bool:
    """Whether any of ``terms`` reads :attr:`Context.own_applied` (a static ``needs_applied`` attribute)."""
    return any(bool(getattr(t, "needs_applied", False)) for t in terms)


class TermValue(NamedTuple):
    """A term's output: ``value [B]`` and per-row ``details`` (a dict of arrays with leading axis B;
    ``counters`` are scalars summed over devices, e.g. the estimator's block count)."""

    value: jax.Array
    details: dict = {}
    counters: dict = {}


@dataclass_transform(frozen_default=True)  # for type checkers: a frozen dataclass (its fields are __init__'s)
def cost_term(cls=None, *, static: tuple[str, ...] = ()):
    """Class decorator: a frozen dataclass whose fields are the term's parameters, registered as a pytree.

    Fields are traced leaves (a new value never recompiles and can be differentiated), except those named in
    ``static`` (strings such as an aggregation mode, integer sizes): static pytree data, so changing one
    recompiles.  Use as ``@cost_term`` or ``@cost_term(static=("aggregation",))``."""

    def deco(cls):
        cls = dataclasses.dataclass(frozen=True)(cls)
        names = tuple(f.name for f in dataclasses.fields(cls))
        unknown = [s for s in static if s not in names]
        if unknown:
            raise ValueError(f"static fields {unknown} are not fields of {cls.__name__}")
        leaves = tuple(n for n in names if n not in static)
        jax.tree_util.register_pytree_node(
            cls, lambda obj: (tuple(getattr(obj, n) for n in leaves), tuple(getattr(obj, n) for n in static)),
            lambda aux, ch: cls(**dict(zip(leaves, ch)), **dict(zip(static, aux))))
        if not isinstance(getattr(cls, "name", None), str) or not cls.name.isidentifier():
            raise ValueError(f"cost term {cls.__name__} must define a class attribute name (an identifier)")
        cls.STATIC = tuple(static)
        return cls

    return deco if cls is None else deco(cls)


RESERVED_NAMES = ("total",)


def check_terms(terms) -> tuple:
    """Validate a sequence of cost terms (instances of :func:`cost_term` classes): returns it as a tuple."""
    try:
        terms = tuple(terms)
    except TypeError:
        raise ValueError(f"terms must be a sequence of cost terms, got {type(terms).__name__}") from None
    if not terms:
        raise ValueError("terms must hold at least one cost term")
    names = []
    for i, term in enumerate(terms):
        if isinstance(term, type) or not callable(term) or not isinstance(getattr(term, "name", None), str):
            raise ValueError(f"terms[{i}] must be a cost-term instance (a @cost_term class, called), got {term!r}")
        if term.name in RESERVED_NAMES:
            raise ValueError(f"terms[{i}].name {term.name!r} is reserved")
        names.append(term.name)
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ValueError(f"cost term names must be unique, got {dup} more than once")
    return terms


def term_names(terms) -> tuple[str, ...]:
    """``("total",) + names``: the cost columns of an evaluation with these terms."""
    return ("total",) + tuple(t.name for t in terms)


__all__ = ["Context", "TermValue", "cost_term", "check_terms", "term_names"]
