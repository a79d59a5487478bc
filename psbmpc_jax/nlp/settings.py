"""Settings, result containers and status codes of the generic constrained solver (:mod:`psbmpc_jax.nlp`).

:class:`SolverSettings` is a frozen dataclass registered as a pytree with two kinds of fields:

* **static** (pytree metadata, part of the jit cache key; changing one recompiles): loop bounds and the
  choice of algorithm -- ``max_outer``, ``max_inner``, ``method``, ``box_map``, ``memory_size``,
  ``max_linesearch_steps``;
* **numeric** (pytree leaves, traced; changing one does NOT recompile, and they can be vmapped over):
  tolerances, penalty parameters, step sizes -- ``tol``, ``rel_tol``, ``grad_tol``, ``mu0``, ``growth``,
  ``mu_max``, ``decrease``, ``learning_rate``, ``start_margin``, ``multiplier_max``.

Every field is validated on the host when the settings are built (``ValueError`` naming the field, what is
allowed and what was given).  Numeric fields that are tracers (settings rebuilt inside a transformation)
are not validated.
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import jax
import numpy as np

from ..status import STATUS_NAMES, Status

#: Status codes of :class:`SolverResult` (``result.status``), from the library's one status enum
#: (:class:`psbmpc_jax.status.Status`; :data:`STATUS_NAMES` names every code).
#: max violation <= tol and relative change of f between outer iterations <= rel_tol
CONVERGED = int(Status.OK)
#: outer budget spent; the final iterate is feasible (violation <= tol) but not converged
MAX_ITER = int(Status.MAX_ITER)
#: outer budget spent with violation > tol (or an empty box, some lower > upper)
INFEASIBLE = int(Status.INFEASIBLE)
#: f, a constraint or a gradient became NaN/inf; u is the last iterate with finite values
NON_FINITE = int(Status.NON_FINITE)

METHODS = ("lbfgs", "adam")
BOX_MAPS = ("sin", "tanh")

_STATIC = ("max_outer", "max_inner", "method", "box_map", "memory_size", "max_linesearch_steps")
_NUMERIC = ("tol", "rel_tol", "grad_tol", "mu0", "growth", "mu_max", "decrease", "learning_rate",
            "start_margin", "multiplier_max")


@dataclasses.dataclass(frozen=True, eq=False)
class SolverSettings:
    """Settings of :func:`psbmpc_jax.nlp.solve_docp` (defaults: our proposal, since Mahipala & Johansen 2024 name no
    solver; ``docs/solver.md``).

    Static (recompile when changed):
        max_outer: augmented-Lagrangian (outer) iterations, >= 1.  Default 20.
        max_inner: inner iterations per outer iteration, >= 1.  Default 50.
        method: inner method, ``"lbfgs"`` (optax L-BFGS with zoom line search on a box reparametrisation;
            the default) or ``"adam"`` (optax Adam followed by projection onto the box).
        box_map: reparametrisation of components with two finite bounds used by ``"lbfgs"``: ``"sin"``
            (u = l + (h - l)(1 + sin z)/2, the MINUIT map; default) or ``"tanh"``.
        memory_size: L-BFGS memory, >= 1.  Default 10.
        max_linesearch_steps: zoom (strong Wolfe) line-search steps per L-BFGS iteration, >= 1.  Default 20.

    Numeric (pytree leaves, no recompilation):
        tol: feasibility tolerance on the max constraint violation, > 0.  Default 1e-3.
        rel_tol: relative change of f between outer iterations that counts as converged, >= 0.  The test is
            ``|f_k - f_{k-1}| <= rel_tol * max(|f_k|, |f_{k-1}|, 1)``.  Default 1e-6.
        grad_tol: inner early stop on the infinity norm of the gradient of the augmented Lagrangian in
            the inner variable (projected gradient for ``"adam"``), >= 0.  Default 1e-6.
        mu0: initial penalty, > 0.  Default 1.
        growth: penalty growth factor, > 1.  Default 5.
        mu_max: penalty cap, >= mu0.  Default 1e8.
        decrease: the penalty grows when the constraint measure did not shrink below ``decrease`` times its
            previous value, in (0, 1).  Default 0.5.
        learning_rate: Adam step size (``"adam"`` only), > 0.  Default 1e-2.
        start_margin: the start is moved into the box interior by this fraction of the box width (two
            finite bounds) or this absolute distance (one finite bound) before the reparametrisation
            (``"lbfgs"`` only), in (0, 0.5).  Default 1e-3.
        multiplier_max: multipliers are clipped to [-multiplier_max, multiplier_max], > 0.  Default 1e8.
    """

    max_outer: int = 20
    max_inner: int = 50
    method: str = "lbfgs"
    box_map: str = "sin"
    memory_size: int = 10
    max_linesearch_steps: int = 20
    tol: float = 1e-3
    rel_tol: float = 1e-6
    grad_tol: float = 1e-6
    mu0: float = 1.0
    growth: float = 5.0
    mu_max: float = 1e8
    decrease: float = 0.5
    learning_rate: float = 1e-2
    start_margin: float = 1e-3
    multiplier_max: float = 1e8

    def __post_init__(self):
        _validate(self)

    def replace(self, **changes) -> "SolverSettings":
        """A copy with ``changes`` applied (validated)."""
        return dataclasses.replace(self, **changes)

    @property
    def static(self) -> tuple:
        """The static fields as a hashable tuple."""
        return tuple(getattr(self, n) for n in _STATIC)

    def __repr__(self):
        items = ", ".join(f"{n}={getattr(self, n)!r}" for n in _STATIC + _NUMERIC)
        return f"SolverSettings({items})"


def _int_field(name, value, minimum):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"SolverSettings.{name} must be an integer >= {minimum}, got {value!r}")
    if value < minimum:
        raise ValueError(f"SolverSettings.{name} must be an integer >= {minimum}, got {value}")


def _concrete(value):
    """``float(value)`` or None for a tracer / an abstract placeholder."""
    if isinstance(value, jax.core.Tracer):
        return None
    if isinstance(value, bool):
        raise TypeError
    arr = np.asarray(value)
    if arr.shape != () or not np.issubdtype(arr.dtype, np.number):
        raise TypeError
    return float(arr)


def _validate(s: SolverSettings):
    _int_field("max_outer", s.max_outer, 1)
    _int_field("max_inner", s.max_inner, 1)
    _int_field("memory_size", s.memory_size, 1)
    _int_field("max_linesearch_steps", s.max_linesearch_steps, 1)
    if s.method not in METHODS:
        raise ValueError(f"SolverSettings.method must be one of {METHODS}, got {s.method!r}")
    if s.box_map not in BOX_MAPS:
        raise ValueError(f"SolverSettings.box_map must be one of {BOX_MAPS}, got {s.box_map!r}")
    rules = {   # name: (test, description of what is allowed)
        "tol": (lambda v: v > 0, "> 0"),
        "rel_tol": (lambda v: v >= 0, ">= 0"),
        "grad_tol": (lambda v: v >= 0, ">= 0"),
        "mu0": (lambda v: v > 0, "> 0"),
        "growth": (lambda v: v > 1, "> 1"),
        "mu_max": (lambda v: v > 0, ">= mu0"),
        "decrease": (lambda v: 0 < v < 1, "in (0, 1)"),
        "learning_rate": (lambda v: v > 0, "> 0"),
        "start_margin": (lambda v: 0 < v < 0.5, "in (0, 0.5)"),
        "multiplier_max": (lambda v: v > 0, "> 0"),
    }
    values = {}
    for name, (ok, allowed) in rules.items():
        raw = getattr(s, name)
        try:
            v = _concrete(raw)
        except (TypeError, ValueError):
            raise ValueError(f"SolverSettings.{name} must be a real scalar {allowed}, got {raw!r}") from None
        if v is None:
            continue
        if not math.isfinite(v) or not ok(v):
            raise ValueError(f"SolverSettings.{name} must be finite and {allowed}, got {raw!r}")
        values[name] = v
        object.__setattr__(s, name, v)      # a Python float: np.float64(1e-3) and 1e-3 share a jit cache key
    if "mu_max" in values and "mu0" in values and values["mu_max"] < values["mu0"]:
        raise ValueError(f"SolverSettings.mu_max must be >= mu0 = {s.mu0!r}, got {s.mu_max!r}")


def _flatten(s: SolverSettings):
    return tuple(getattr(s, n) for n in _NUMERIC), tuple(getattr(s, n) for n in _STATIC)


def _unflatten(static, numeric):
    obj = object.__new__(SolverSettings)     # no validation: leaves may be tracers or placeholders
    for n, v in zip(_STATIC, static):
        object.__setattr__(obj, n, v)
    for n, v in zip(_NUMERIC, numeric):
        object.__setattr__(obj, n, v)
    return obj


jax.tree_util.register_pytree_node(SolverSettings, _flatten, _unflatten)


class SolverResult(NamedTuple):
    """Result of :func:`psbmpc_jax.nlp.solve_docp` (a pytree; batched with a leading [S] axis by
    :func:`psbmpc_jax.nlp.solve_multistart`).

    Attributes:
        u: the solution, u0's shape, inside the box.
        f: f(u, args).
        max_violation: max(|eq(u)|, max(ineq(u), 0), box violation of u) (0-d).
        status: int32 code -- 0 ok (converged), 3 max-iter (feasible, not converged), 4 infeasible,
            5 non-finite (:class:`psbmpc_jax.status.Status`).
        outer_iterations: augmented-Lagrangian iterations used (int32).
        inner_iterations: inner iterations used, summed over outer iterations (int32).
        lam_eq: multipliers of the equalities ``[m_e]`` (after the last update).
        lam_ineq: multipliers of the inequalities ``[m_i]`` (>= 0).
        mu: the final penalty.
        grad_norm: infinity norm of the inner gradient at the end of the last inner loop (in the inner
            variable: z of the box map for ``"lbfgs"``, the projected gradient for ``"adam"``).
        stalled: the last inner loop ended on a line-search failure with grad_norm above
            max(grad_tol, sqrt(eps) * max(|L|, 1)) -- the final point is not a stationary point of the
            augmented Lagrangian to tolerance (a kink, the edge of a NaN region, or ill-conditioning at a large
            penalty).  An outer iteration whose inner loop stalled without accepting a step never counts as
            converged.
    """

    u: jax.Array
    f: jax.Array
    max_violation: jax.Array
    status: jax.Array
    outer_iterations: jax.Array
    inner_iterations: jax.Array
    lam_eq: jax.Array
    lam_ineq: jax.Array
    mu: jax.Array
    grad_norm: jax.Array
    stalled: jax.Array


class MultistartResult(NamedTuple):
    """Result of :func:`psbmpc_jax.nlp.solve_multistart`.

    Attributes:
        results: :class:`SolverResult` with a leading ``[S]`` axis (one per start).
        best: index of the best start: lowest f among those with finite f and max_violation <= tol; if none
            is feasible, the least (finite) violation; 0 when nothing is finite.
    """

    results: SolverResult
    best: jax.Array

    def best_result(self) -> SolverResult:
        """The :class:`SolverResult` of start ``best``."""
        return jax.tree_util.tree_map(lambda x: x[self.best], self.results)


class Safeguarded(NamedTuple):
    """Result of :func:`psbmpc_jax.nlp.safeguard`: the kept control sequence, its cost and violation,
    ``used_warm`` (True when the warm start replaced the solver's result), ``warm_index`` (int32: which of a
    stack of warm starts was the reference; 0 for a single warm start), and ``warm_f`` / ``warm_violation``:
    f and the max violation of every warm start (``[W]`` for a stack, scalars for one), so a caller that
    reports a warm start's cost need not evaluate f again."""

    u: jax.Array
    f: jax.Array
    max_violation: jax.Array
    used_warm: jax.Array
    warm_index: jax.Array
    warm_f: jax.Array
    warm_violation: jax.Array


__all__ = ["SolverSettings", "SolverResult", "MultistartResult", "Safeguarded", "STATUS_NAMES", "CONVERGED",
           "MAX_ITER", "INFEASIBLE", "NON_FINITE", "METHODS", "BOX_MAPS"]
