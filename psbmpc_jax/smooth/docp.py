"""The MPC stage of Smooth-SBMPC (Mahipala & Johansen 2024, Sec. VII): the DOCP (27) over per-step offsets, and one
complete Smooth-SBMPC step (initialisation stage → corridor → DOCP from several starts → safeguard), jitted as
one computation.

Decision variable: ``u [N_mpc, 2]`` = (U_m, χ_m) per step, single shooting (the states are the rollout of the
kinematic model (13) under route LOS, so the dynamics hold exactly), box −90° ≤ χ_m ≤ 90°, 0.1 ≤ U_m ≤ 1.

    J_d(u) = Σ_i Σ_{k=1..N_mpc} (σ_coll C R + κ μ_FIS)(x_k, target_i,k)  +  Σ_{k=0..N_mpc−1} Γ_smooth(u_k; u_{k−1})

subject to the terminal condition x_{N_mpc} = Ψ_{N_mpc} (``terminal="full"``: x, y, χ (wrapped), U;
``"position"``: x, y; ``"soft"``: a quadratic penalty instead) and the cross-track corridor of Ψ (Alg. 3,
read as a cross-track inequality: choice SM-8, docs/algorithm.md §12) at steps 1..N_mpc. Solved by
:func:`psbmpc_jax.nlp.solve_docp` (augmented Lagrangian, L-BFGS on a box map, settings :data:`DOCP_SOLVER` unless
given) from the warm start Ψ (the init stage's offsets) and, with ``n_starts > 1``, also from the ``n_starts − 1``
best constant behaviours of the init stage's first inner step (:func:`psbmpc_jax.nlp.solve_multistart`,
``batch="map"`` or ``"vmap"``); the best feasible result (:func:`psbmpc_jax.nlp.best_index`) then passes the
safeguard: a result worse or less feasible than the best of the starts themselves (Ψ, or the previous plan when that
is feasible and cheaper) is replaced by that start.

**χ_d inside the DOCP** (``settings.chi_d_mode``, :mod:`psbmpc_jax.smooth.guidance`): ``"terminal_los"`` (the
paper's, the default) takes LOS on the line from the ship through Ψ_N; Ψ's offsets are re-expressed against
it along Ψ, so the warm start still reproduces Ψ (to rounding) and satisfies the terminal equality and the
corridor; the applied offset ``last`` is carried into that frame at τ₀, and the kept sequence is converted back
to the route frame (the frame the simulator and the init stage apply offsets in) along the plan's own
trajectory.  Where a re-expressed offset of Ψ would leave the box (±90°), that update runs in the route frame
(``SmoothStep.route_frame``).  ``"route_los"``: the route's LOS, as the init stage.

**Land between samples** (``settings.corridor_check="continuous"``, the default): besides the corridor at the
samples, every segment x_k → x_{k+1} of the plan keeps the corridor's land buffer b by a proven sample bound
(:mod:`psbmpc_jax.smooth.clearance`).
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..array_types import HostOrDevice
from ..checks import control_plan
from ..costs.manoeuvring import gamma_sequence
from ..costs.sbmpc import sbmpc_costs
from ..nlp import BATCH_MODES, SolverResult, SolverSettings, safeguard, solve_docp, solve_multistart
from ..numerics import shift_controls, wrap_angle  # noqa: F401  (shift_controls: re-exported, docs name docp.shift_controls)
from ..ownship import Path
from .clearance import Clearance, make_clearance, segment_residuals
from .corridor import Corridor, corridor_kernel, cross_track_residuals
from .guidance import line_path, reexpress, select_path
from .init_stage import (InitResult, ShipModel, SmoothSettings, SmoothWeights, init_stage_traced, behaviour_table,
                         check_segment, gamma_weights, pair_kwargs, rollout_controls, route_path, target_predictions)
from .land_hit import as_chart

#: Box of the DOCP's offsets: (U_m, χ_m) — the extremes of the behaviour sets (26a), (26b).
LOWER = (0.1, -math.pi / 2)
UPPER = (1.0, math.pi / 2)

#: Solver settings of the DOCP when none are given: the library defaults (max_outer 20, max_inner 50, L-BFGS on
#: the sin box map, tol 1e-3, rel_tol 1e-6, mu0 1, growth 5).  Measured against alternatives on 12 situations of
#: the paper-scale channel (``benchmarks/bench_smooth.py``'s geometry, float32, 4 starts each; docs/smooth_sbmpc.md
#: "Solver settings"): every faster variant found (mu0 = 100, max_outer 10-12, max_inner 25-30, growth 10) saved
#: 10-30 % of the solve time but ended 3-12x farther above the best cost found (mean relative gap of the
#: Ψ start 4e-2 … 1.2e-1 against 1.1e-2 … 1.5e-2); rel_tol 1e-4 … 1e-5 and grad_tol 1e-4 … 1e-3 change
#: nothing in float32 (the inner loops end on the line search, not on the gradient).
DOCP_SOLVER = SolverSettings()

#: The most starts of the multi-start: Ψ plus every one of the 39 behaviours.
MAX_STARTS = 40

#: Ψ's offsets re-expressed in the terminal-LOS frame may exceed the box by this much [rad] (rounding; they are
#: then moved onto it); farther out, the update runs in the route frame.
FRAME_TOL = 1e-6


class DocpArgs(NamedTuple):
    """Traced data of one DOCP: start state ``[4]``, route ``[W, 2]``, targets ``[I, 4]``, last offsets ``[2]``
    (in the DOCP's frame), the terminal state Ψ_{N_mpc} ``[4]``, the corridor of Ψ at steps 0..N_mpc, weights,
    model and the active segment of the guidance path at τ₀ (int32 scalar).  ``path``: the guidance path
    (:mod:`psbmpc_jax.smooth.guidance`; None: the route's); ``clearance``: the land clearance between samples
    (:mod:`psbmpc_jax.smooth.clearance`; None: not checked)."""

    state0: jax.Array
    route: jax.Array
    targets: jax.Array
    last: jax.Array
    terminal: jax.Array
    corridor: Corridor
    weights: SmoothWeights
    model: ShipModel
    segment: jax.Array | int = 0
    path: Path | None = None
    clearance: Clearance | None = None


def _path(a: DocpArgs) -> Path:
    return route_path(a.route) if a.path is None else a.path


def _states(u, a: DocpArgs, settings: SmoothSettings):
    return rollout_controls(a.state0, _path(a), _as_state_dtype(u, a), a.model, settings.dt, z0=a.segment)


def _as_state_dtype(u, a: DocpArgs):
    """``u`` in the problem's dtype (that of ``a.state0``): with 64-bit JAX on, the solver's line search can
    hand a float32 problem float64 iterates, which a float32 rollout's scan carry would refuse."""
    return jnp.asarray(u).astype(jnp.asarray(a.state0).dtype)


def docp_cost(u, a: DocpArgs, settings: SmoothSettings):
    """J_d of (27) (plus the soft terminal penalty when ``settings.terminal == "soft"``)."""
    u = _as_state_dtype(u, a)
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
    states = _states(u, a, settings)
    lo, hi = cross_track_residuals(states[:, :2], a.corridor)
    parts = [lo[1:], hi[1:]]
    if a.clearance is not None:
        parts.append(segment_residuals(states, a.clearance, settings.dt))
    return jnp.concatenate(parts)


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
    """One Smooth-SBMPC step.

    Attributes:
        apply: the offsets to apply now ``[2]`` (U_m, χ_m).
        controls: the kept sequence ``[N_mpc, 2]`` (refined, or the start ``warm_index`` when ``used_warm``).
        cost: its J_d.  violation: its max constraint violation (terminal, corridor, box).
        used_warm: the safeguard kept an unrefined start (``warm_index``) instead of the solver's best result.
        solver: the :class:`~psbmpc_jax.nlp.SolverResult` of the best start.
        init: the init stage's :class:`InitResult` (Ψ, offsets, …).  corridor: the corridor of Ψ, steps 0..N_mpc.
        warm_cost: J_d of the warm start Ψ.
        starts: the starts ``[S, N_mpc, 2]`` (S = n_starts; row 0 is Ψ's offsets, then the previous plan when
            given and valid, then constant behaviours).
        start_cost, start_violation: J_d and violation of each start's result ``[S]``.
        best: index of the start whose result went into the safeguard (int32).
        iterations: inner solver iterations summed over the starts (int32).
        warm_index: the start the safeguard compared with (int32): the best of the starts themselves by
            :func:`psbmpc_jax.nlp.best_index` (feasible first, then the lowest J_d, ties to the lower index), so 0
            (Ψ, feasible by construction) unless another start -- in practice the previous plan -- is feasible
            and cheaper.
        docp_controls: the kept sequence ``[N_mpc, 2]`` in the DOCP's frame (``apply`` and ``controls`` are in the
            route frame; equal with ``chi_d_mode="route_los"``).  ``starts`` are in the DOCP's frame too.
        route_frame: bool, the DOCP ran in the route frame (``"route_los"``, or Ψ's offsets did not fit the box in
            the terminal-LOS frame).
    """

    apply: jax.Array
    controls: jax.Array
    cost: jax.Array
    violation: jax.Array
    used_warm: jax.Array
    solver: SolverResult
    init: InitResult
    corridor: Corridor
    warm_cost: jax.Array
    starts: jax.Array
    start_cost: jax.Array
    start_violation: jax.Array
    best: jax.Array
    iterations: jax.Array
    warm_index: jax.Array
    docp_controls: jax.Array
    route_frame: jax.Array


class Previous(NamedTuple):
    """The previous update's kept sequence as a start of this update's DOCP (``previous_start``).

    Attributes:
        controls: ``[N_mpc, 2]`` (U_m, χ_m), already shifted to begin now (:func:`shift_controls`).
        valid: bool scalar; False (no previous plan, e.g. at the first update): the start is a behaviour instead.
    """

    controls: HostOrDevice
    valid: HostOrDevice


def warm_starts(init: InitResult, n_starts: int, n: int, previous: Previous | None = None, warm=None):
    """The starts ``[n_starts, n, 2]`` of the multi-start: Ψ's first ``n`` offsets, then the constant sequences
    of the ``n_starts − 1`` behaviours with the lowest total cost at τ₀ (``init.first_cost``; ties: enumeration
    order).  A behaviour whose constant sequence equals Ψ's (Ψ held it throughout) is ranked last, so it does
    not duplicate start 0.

    With ``previous`` (needs ``n_starts >= 2``): row 1 is the previous update's sequence when
    ``previous.valid``, and the behaviours fill rows 2…; when not valid the rows are those without it.
    ``warm``: row 0 (Ψ's offsets in the DOCP's frame; default: ``init.controls[:n]``, the route frame)."""
    warm = init.controls[:n] if warm is None else warm
    if n_starts == 1:
        if previous is not None:
            raise ValueError("a previous-plan start needs n_starts >= 2 (row 0 is always Ψ)")
        return warm[None]
    table = behaviour_table(warm.dtype)
    same = jnp.all(table[:, None, :] == warm[None], axis=(1, 2))
    key = jnp.where(same, jnp.inf, init.first_cost)
    order = jnp.argsort(key, stable=True)[: n_starts - 1]
    const = jnp.broadcast_to(table[order][:, None, :], (n_starts - 1, n, 2))
    starts = jnp.concatenate([warm[None], const], axis=0)
    if previous is None:
        return starts
    with_previous = jnp.concatenate([warm[None], previous.controls.astype(warm.dtype)[None], const[:-1]], axis=0)
    return jnp.where(previous.valid, with_previous, starts)


def cast_tree(tree, dtype):
    """Every floating leaf (Python numbers included) as a strongly typed array of ``dtype``."""
    def one(v):
        v = jnp.asarray(v)
        return v.astype(dtype) if jnp.issubdtype(v.dtype, jnp.floating) else v
    return jax.tree.map(one, tree)


class Frame(NamedTuple):
    """The DOCP's guidance frame of one step (:func:`docp_frame`): its path and segment at τ₀, Ψ's first N_mpc
    offsets and the applied offsets ``last`` in it, whether it is the route's (bool), and the route path and
    segment (to convert back)."""

    path: Path
    segment: jax.Array
    warm: jax.Array
    last: jax.Array
    route_frame: jax.Array
    route: Path
    route_segment: jax.Array


def docp_frame(init: InitResult, state0, last, route, segment, model: ShipModel, settings: SmoothSettings) -> Frame:
    """The DOCP's frame (``settings.chi_d_mode``): the route's, or the line from the ship through Ψ_N with Ψ's
    offsets and ``last`` re-expressed against it (the route's when a re-expressed offset of Ψ leaves the box by
    more than :data:`FRAME_TOL`)."""
    n = settings.n_mpc
    rpath = route_path(route)
    z = jnp.asarray(segment, jnp.int32)
    warm_r = init.controls[:n]
    if settings.chi_d_mode == "route_los":
        return Frame(rpath, z, warm_r, last, jnp.asarray(True), rpath, z)
    lpath = line_path(state0[:2], init.psi[n, :2], state0[2], route.shape[0])
    zero = jnp.asarray(0, jnp.int32)
    chi = reexpress(warm_r[:, 1], init.psi[:n, :2], rpath, z, lpath, zero, model.lookahead, model.R_a)
    use_route = ~jnp.all(jnp.abs(chi) <= UPPER[1] + FRAME_TOL)
    chi = jnp.clip(chi, LOWER[1], UPPER[1])
    last_l = reexpress(last[1:2], state0[None, :2], rpath, z, lpath, zero, model.lookahead, model.R_a)[0]
    warm = jnp.where(use_route, warm_r, jnp.stack([warm_r[:, 0], chi], axis=-1))
    last_f = jnp.where(use_route, last, jnp.stack([last[0], last_l]))
    return Frame(select_path(use_route, rpath, lpath), jnp.where(use_route, z, zero), warm, last_f, use_route,
                 rpath, z)


def to_route_frame(u, state0, frame: Frame, model: ShipModel, settings: SmoothSettings):
    """A sequence ``u [N, 2]`` in the DOCP's frame as route-frame offsets, along the trajectory it produces (the
    same commands: rolled out on the route's LOS it gives the same states, to rounding)."""
    states = rollout_controls(state0, frame.path, u, model, settings.dt, z0=frame.segment)
    n = u.shape[0]
    chi = reexpress(u[:, 1], states[:n, :2], frame.path, frame.segment, frame.route, frame.route_segment,
                    model.lookahead, model.R_a)
    return jnp.stack([u[:, 0], chi], axis=-1)


def _previous_in_frame(previous: Previous | None, state0, frame: Frame, model: ShipModel,
                       settings: SmoothSettings) -> Previous | None:
    """The previous plan (route-frame offsets, as :class:`SmoothStep` returns them) in the DOCP's frame, along
    the trajectory it produces from now, moved onto the box (a start only)."""
    if previous is None:
        return None
    u = previous.controls.astype(state0.dtype)
    states = rollout_controls(state0, frame.route, u, model, settings.dt, z0=frame.route_segment)
    n = u.shape[0]
    chi = reexpress(u[:, 1], states[:n, :2], frame.route, frame.route_segment, frame.path, frame.segment,
                    model.lookahead, model.R_a)
    lo, hi = (jnp.asarray(b, u.dtype) for b in (LOWER, UPPER))
    return previous._replace(controls=jnp.clip(jnp.stack([u[:, 0], chi], axis=-1), lo, hi))


class Prepared(NamedTuple):
    """The first part of a step (:func:`prepare_step`): the init stage's result, the corridor of Ψ, the DOCP's
    data, its starts ``[S, N_mpc, 2]`` (in the DOCP's frame) and the :class:`Frame`."""

    init: InitResult
    corridor: Corridor
    args: DocpArgs
    starts: jax.Array
    frame: Frame


def prepare_step(state0, route, targets, last, segment, land, buffered_land, weights, model, *,
                 settings: SmoothSettings, n_starts: int, previous: Previous | None = None) -> Prepared:
    """Traceable first part of a step: Alg. 1 (init stage), Alg. 3 (corridor of Ψ), the DOCP's frame, data and
    starts (no validation; every array already of one float dtype; ``previous``: see :func:`warm_starts`, in
    the route frame).  ``land``: the unbuffered chart (N_TP, and the clearance between samples);
    ``buffered_land``: the chart buffered by ``settings.corridor_land_buffer`` (the corridor's ray cast)."""
    init = init_stage_traced(state0, route, targets, last, land, weights, model, settings, segment)
    n = settings.n_mpc
    dtype = init.psi.dtype
    corridor = corridor_kernel(init.psi[:n + 2, :2], buffered_land, jnp.asarray(settings.corridor_half_width, dtype),
                               heading=state0[2])
    corridor = jax.tree.map(lambda a: a[:n + 1], corridor)
    frame = docp_frame(init, state0, last, route, segment, model, settings)
    clearance = None
    if settings.corridor_check == "continuous":
        clearance = make_clearance(land, init.psi[:n + 1], state0, model.U_d, settings.corridor_land_buffer,
                                   settings.dt)
    args = DocpArgs(init.psi[0], route, targets, frame.last, init.psi[n], corridor, weights, model, frame.segment,
                    frame.path, clearance)
    prev = _previous_in_frame(previous, state0, frame, model, settings)
    return Prepared(init, corridor, args, warm_starts(init, n_starts, n, prev, warm=frame.warm), frame)


def solve_step(prep: Prepared, solver: SolverSettings, *, settings: SmoothSettings, batch: str) -> SmoothStep:
    """Traceable second part of a step: the DOCP from every start (one start: :func:`solve_docp`; several:
    :func:`solve_multistart` with ``batch``), the best start (:func:`psbmpc_jax.nlp.best_index`), the safeguard
    against the best of the starts themselves (Ψ, row 0, unless another start is feasible and cheaper)."""
    f, eq, ineq = problem(settings)
    args, starts = prep.args, prep.starts
    n_starts, n = starts.shape[0], starts.shape[1]
    lower, upper = bounds(n, starts.dtype)
    warm = starts[0]                                                    # Ψ
    if n_starts == 1:
        result = solve_docp(f, warm, lower=lower, upper=upper, eq=eq, ineq=ineq, settings=solver, args=args)
        best = jnp.asarray(0, jnp.int32)
        all_f, all_v, iters = result.f[None], result.max_violation[None], result.inner_iterations
    else:
        multi = solve_multistart(f, starts, lower=lower, upper=upper, eq=eq, ineq=ineq, settings=solver, args=args,
                                 batch=batch)
        best = multi.best
        result = multi.best_result()
        all_f, all_v = multi.results.f, multi.results.max_violation
        iters = jnp.sum(multi.results.inner_iterations).astype(jnp.int32)
    # the reference of the safeguard: the best of the starts themselves (feasible first, then J_d; ties keep
    # Ψ), so the kept sequence is never worse than Ψ nor than any other start, the previous plan included
    kept = safeguard(result, starts, f, lower=lower, upper=upper, eq=eq, ineq=ineq, args=args, tol=solver.tol)
    applied = to_route_frame(kept.u, args.state0, prep.frame, args.model, settings)
    return SmoothStep(applied[0], applied, kept.f, kept.max_violation, kept.used_warm, result, prep.init,
                      prep.corridor, kept.warm_f[0], starts, all_f, all_v, best, iters, kept.warm_index, kept.u,
                      prep.frame.route_frame)


def step_traced(state0, route, targets, last, segment, land, buffered_land, weights, model, solver, *,
                settings: SmoothSettings, n_starts: int, batch: str, previous: Previous | None = None) -> SmoothStep:
    """Traceable Smooth-SBMPC step (no validation; every array already of one float dtype)."""
    prep = prepare_step(state0, route, targets, last, segment, land, buffered_land, weights, model,
                        settings=settings, n_starts=n_starts, previous=previous)
    return solve_step(prep, solver, settings=settings, batch=batch)


_step_jit = jax.jit(step_traced, static_argnames=("settings", "n_starts", "batch"))


def check_step_options(settings, solver, n_starts, batch):
    """Validate the static options of a step (``ValueError`` naming the field)."""
    if not isinstance(settings, SmoothSettings):
        raise ValueError(f"settings must be a SmoothSettings, got {type(settings).__name__}")
    if not isinstance(solver, SolverSettings):
        raise ValueError(f"solver must be a psbmpc_jax.nlp.SolverSettings, got {type(solver).__name__}")
    if isinstance(n_starts, bool) or not isinstance(n_starts, int) or not 1 <= n_starts <= MAX_STARTS:
        raise ValueError(f"n_starts must be an integer in [1, {MAX_STARTS}] (Ψ plus up to 39 behaviours), "
                         f"got {n_starts!r}")
    if batch not in BATCH_MODES:
        raise ValueError(f"batch must be one of {BATCH_MODES}, got {batch!r}")


def check_previous(previous, n: int, name: str = "previous", lead: tuple = ()) -> np.ndarray:
    """A previous-plan start ``lead + [n, 2]`` (U_m, χ_m; route-frame offsets, as :class:`SmoothStep` returns
    them) as float64 NumPy: finite, U_m in the DOCP's box, χ_m in [−π, π] (a route-frame offset may exceed ±90°
    where the DOCP's frame is the terminal-LOS line; :func:`psbmpc_jax.checks.control_plan`, ``ValueError``
    naming ``name`` otherwise).  With ``lead`` (runs), a row that is NaN throughout means "no previous plan for
    this run"; a partly NaN row is an error, and so is a single plan that is NaN throughout (pass None
    instead)."""
    a, _ = control_plan(previous, name, n=n, lower=(LOWER[0], -math.pi), upper=(UPPER[0], math.pi),
                        what="U_m, chi_m", lead=lead, missing_ok=False,
                        box=f"the route frame's box: U_m in [{LOWER[0]}, {UPPER[0]}], chi_m in [-pi, pi] rad")
    return a


def check_step_inputs(state0, route, targets, last, dtype=None):
    """``(state0 [4], route [W, 2], targets [I, 4], last [2])`` as arrays of one float dtype (``dtype``, else
    that of ``state0``, float32 for integers), shapes and finiteness checked (``ValueError`` naming the field)."""
    if dtype is None:
        s = jnp.asarray(state0)
        dtype = s.dtype if jnp.issubdtype(s.dtype, jnp.floating) else jnp.float32
    out = []
    for name, value, shape, ok in (("state0", state0, "[4] (x, y, chi, U)", lambda s: s == (4,)),
                                   ("route", route, "[W >= 2, 2] waypoints", lambda s: len(s) == 2 and s[1] == 2
                                    and s[0] >= 2),
                                   ("targets", targets, "[I, 4] (x, y, chi, U)", lambda s: len(s) == 2 and s[1] == 4),
                                   ("last", last, "[2] (U_m, chi_m)", lambda s: s == (2,))):
        a = jnp.asarray(value, dtype)
        if not ok(a.shape):
            raise ValueError(f"{name} must be {shape}, got shape {a.shape}")
        if not isinstance(a, jax.core.Tracer) and not bool(jnp.all(jnp.isfinite(a))):
            raise ValueError(f"{name} must be finite (no NaN/inf)")
        out.append(a)
    return tuple(out)


def smooth_sbmpc_step(state0, route, targets, last, land, buffered_land, *, weights: SmoothWeights = SmoothWeights(),
                      model: ShipModel = ShipModel(), settings: SmoothSettings = SmoothSettings(),
                      solver: SolverSettings | None = None, n_starts: int = 1, batch: str = "map",
                      segment: int = 0, previous=None) -> SmoothStep:
    """One control step of Smooth-SBMPC (§1.1): Alg. 1 → Alg. 3 → DOCP (27) from ``n_starts`` starts →
    safeguard, as one jitted computation (values never recompile; ``settings``, ``n_starts``, ``batch``, the
    static fields of ``solver`` and the array shapes do).

    ``land``: the unbuffered chart (``pack_world(...).polygons``) for N_TP and the clearance between samples;
    ``buffered_land``: the chart buffered by ``settings.corridor_land_buffer``
    (:func:`psbmpc_jax.smooth.buffered_chart`, built once per chart) for the corridor.  ``solver``: :data:`DOCP_SOLVER` when None.  ``n_starts``: 1 (Ψ only) … 40; ``batch``: how the
    starts run, ``"map"`` (one after another, the faster on a CPU) or ``"vmap"``.  ``segment``: the active route
    segment at τ₀.  ``previous``: the previous update's kept sequence ``[N_mpc, 2]``, shifted to begin now
    (:func:`shift_controls`), as start 1 (needs ``n_starts >= 2``); None: not used.  Other arguments as
    :func:`psbmpc_jax.smooth.init_stage.init_stage`; every float input is cast to ``state0``'s dtype (weights and
    model included)."""
    solver = DOCP_SOLVER if solver is None else solver
    check_step_options(settings, solver, n_starts, batch)
    state0, route, targets, last = check_step_inputs(state0, route, targets, last)
    dtype = state0.dtype
    prev = None                          # with 2+ starts always a Previous: its presence is a value (no recompile)
    if previous is not None:
        if n_starts < 2:
            raise ValueError(f"previous needs n_starts >= 2 (row 0 is always Ψ), got n_starts {n_starts}")
        prev = Previous(jnp.asarray(check_previous(previous, settings.n_mpc), dtype), jnp.asarray(True))
    elif n_starts >= 2:
        prev = Previous(jnp.zeros((settings.n_mpc, 2), dtype), jnp.asarray(False))
    z = check_segment(segment, route.shape[0])
    land, buffered_land = (cast_tree(as_chart(c, name), dtype) for c, name in ((land, "land"),
                                                                            (buffered_land, "buffered_land")))
    return _step_jit(state0, route, targets, last, jnp.asarray(z, jnp.int32), land, buffered_land,
                     cast_tree(weights, dtype), cast_tree(model, dtype), solver, settings=settings, n_starts=n_starts,
                     batch=batch, previous=prev)
