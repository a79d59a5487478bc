"""The MPC stage of Smooth-SBMPC (seed 000, SPEC_SEEDS §1.6): the DOCP (27) over per-step offsets, and one
complete Smooth-SBMPC step (initialisation stage → corridor → DOCP → safeguard).

Decision variable: ``u [N_mpc, 2]`` = (U_m, χ_m) per step, single shooting (the states are the rollout of the
kinematic model (13) under route LOS, so the dynamics hold exactly), box −90° ≤ χ_m ≤ 90°, 0.1 ≤ U_m ≤ 1.

    J_d(u) = Σ_i Σ_{k=1..N_mpc} (σ_coll C R + κ μ_FIS)(x_k, target_i,k)  +  Σ_{k=0..N_mpc−1} Γ_smooth(u_k; u_{k−1})

subject to the terminal condition x_{N_mpc} = Ψ_{N_mpc} (``terminal="full"``: x, y, χ (wrapped), U;
``"position"``: x, y; ``"soft"``: a quadratic penalty instead) and the cross-track corridor of Ψ (Alg. 3,
C-000-8) at steps 1..N_mpc.  Solved by :func:`psbmpc_jax.nlp.solve_docp` (augmented Lagrangian, L-BFGS on a box
map), warm-started from the init stage's offsets, with the safeguard: a result worse or less feasible than the
warm start is replaced by the warm start.

**χ_d inside the DOCP (our reading, see docs/smooth_sbmpc.md):** route LOS, the same guidance as the init
stage, rather than LOS on the segment p(τ₀) → p_T (SPEC choice C-000-7).  With the same guidance the warm
start reproduces Ψ exactly, so it satisfies the full terminal equality and the corridor — the safeguard always
has a feasible fallback.  With C-000-7's segment LOS the warm start would not be feasible.
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp

from ..costs.manoeuvring import gamma_sequence
from ..costs.sbmpc import sbmpc_costs
from ..nlp import SolverResult, SolverSettings, safeguard, solve_docp
from ..numerics import wrap_angle
from .corridor import Corridor, cross_track_corridor, cross_track_residuals
from .init_stage import (InitResult, ShipModel, SmoothSettings, SmoothWeights, gamma_weights, init_stage, pair_kwargs,
                         rollout_controls, route_path, target_predictions)

#: Box of the DOCP's offsets: (U_m, χ_m) — the extremes of the behaviour sets (26a), (26b).
LOWER = (0.1, -math.pi / 2)
UPPER = (1.0, math.pi / 2)


class DocpArgs(NamedTuple):
    """Traced data of one DOCP: start state ``[4]``, route ``[W, 2]``, targets ``[I, 4]``, last offsets ``[2]``,
    the terminal state Ψ_{N_mpc} ``[4]``, the corridor of Ψ at steps 0..N_mpc, weights and model."""

    state0: jax.Array
    route: jax.Array
    targets: jax.Array
    last: jax.Array
    terminal: jax.Array
    corridor: Corridor
    weights: SmoothWeights
    model: ShipModel


def _states(u, a: DocpArgs, settings: SmoothSettings):
    return rollout_controls(a.state0, route_path(a.route), u, a.model, settings.dt)


def docp_cost(u, a: DocpArgs, settings: SmoothSettings):
    """J_d of (27) (plus the soft terminal penalty when ``settings.terminal == "soft"``)."""
    states = _states(u, a, settings)
    t = jnp.arange(states.shape[0], dtype=states.dtype) * settings.dt
    w = a.weights
    hazard = 0.0
    if a.targets.shape[0]:
        hazard = sbmpc_costs(states, target_predictions(a.targets, t), t, aggregation="sum", kappa=w.kappa,
                             **pair_kwargs(w, settings))["joint"]
    gamma = gamma_sequence(u, a.last, form="smooth", **gamma_weights(w))
    total = hazard + gamma
    if settings.terminal == "soft":
        r = _terminal_residual(states[-1], a.terminal, full=True)
        total = total + settings.terminal_weight * jnp.sum(r * r)
    return total


def _terminal_residual(x, target, full: bool):
    d = jnp.stack([x[0] - target[0], x[1] - target[1], wrap_angle(x[2] - target[2]), x[3] - target[3]])
    return d if full else d[:2]


def docp_eq(u, a: DocpArgs, settings: SmoothSettings):
    return _terminal_residual(_states(u, a, settings)[-1], a.terminal, full=settings.terminal == "full")


def docp_ineq(u, a: DocpArgs, settings: SmoothSettings):
    lo, hi = cross_track_residuals(_states(u, a, settings)[:, :2], a.corridor)
    return jnp.concatenate([lo[1:], hi[1:]])


@functools.lru_cache(maxsize=None)
def problem(settings: SmoothSettings):
    """``(f, eq, ineq)`` of the DOCP for static ``settings`` (cached: the solver hashes them by identity)."""
    f = functools.partial(docp_cost, settings=settings)
    eq = None if settings.terminal == "soft" else functools.partial(docp_eq, settings=settings)
    ineq = functools.partial(docp_ineq, settings=settings)
    return f, eq, ineq


def bounds(n: int, dtype):
    return (jnp.broadcast_to(jnp.asarray(LOWER, dtype), (n, 2)), jnp.broadcast_to(jnp.asarray(UPPER, dtype), (n, 2)))


class SmoothStep(NamedTuple):
    """One Smooth-SBMPC step: the offsets to apply now ``[2]`` (U_m, χ_m), the refined sequence ``[N_mpc, 2]``,
    its cost and constraint violation, whether the safeguard fell back to the warm start, the solver's result,
    the init stage's result (Ψ, offsets) and the corridor."""

    apply: jax.Array
    controls: jax.Array
    cost: jax.Array
    violation: jax.Array
    used_warm: jax.Array
    solver: SolverResult
    init: InitResult
    corridor: Corridor
    warm_cost: jax.Array


def smooth_sbmpc_step(state0, route, targets, last, land, buffered_land, *, weights: SmoothWeights = SmoothWeights(),
                      model: ShipModel = ShipModel(), settings: SmoothSettings = SmoothSettings(),
                      solver: SolverSettings = SolverSettings()) -> SmoothStep:
    """One control step of Smooth-SBMPC (§1.1): Alg. 1 → Alg. 3 → DOCP (27) → safeguard.

    ``land``: the unbuffered chart (``pack_world(...).polygons``) for N_TP; ``buffered_land``: the chart
    buffered by ``settings.r_dom`` (:func:`psbmpc_jax.smooth.buffered_chart`, built once per chart) for the
    corridor.  Other arguments as :func:`psbmpc_jax.smooth.init_stage.init_stage`."""
    init = init_stage(state0, route, targets, last, land, weights, model, settings)
    n = settings.n_mpc
    dtype = init.psi.dtype
    corridor = cross_track_corridor(init.psi[:n + 2, :2], buffered_land, settings.corridor_half_width)
    corridor = jax.tree.map(lambda a: a[:n + 1], corridor)
    args = DocpArgs(init.psi[0], jnp.asarray(route, dtype), jnp.asarray(targets, dtype), jnp.asarray(last, dtype),
                    init.psi[n], corridor, weights, model)
    f, eq, ineq = problem(settings)
    lower, upper = bounds(n, dtype)
    warm = init.controls[:n]
    result = solve_docp(f, warm, lower=lower, upper=upper, eq=eq, ineq=ineq, settings=solver, args=args)
    kept = safeguard(result, warm, f, lower=lower, upper=upper, eq=eq, ineq=ineq, args=args, tol=solver.tol)
    return SmoothStep(kept.u[0], kept.u, kept.f, kept.max_violation, kept.used_warm, result, init, corridor,
                      f(warm, args))
