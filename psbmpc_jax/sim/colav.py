"""Which controller runs which ship in the closed-loop simulator, and one MPC update of all of them.

Every ship with collision avoidance runs the method its ``colav`` names (the own-ship's is ``mpc.method``); the
registry :data:`psbmpc_jax.sim.methods.REGISTRY` maps a method to its group, and the ships of one method form
one group, so their solves batch (one vmapped call per update in ``vmap`` mode):

===================  ==========================================================================================
``psbmpc``           grid search over the behaviour table (:func:`psbmpc_jax.solve.solve`); the first maneuver
                     of the chosen behaviour is held until the next update (the simulator as it always was)
``psbmpc_refine``    the same grid search, then :func:`psbmpc_jax.refine.refine` (gradient refinement): its
                     per-step controls are applied step by step between two updates (row ``j`` from
                     ``t_update + j * config.dt`` on)
``sbmpc``            the same grid search with the original SB-MPC cost (:func:`psbmpc_jax.methods.sbmpc_terms`),
                     straight-line targets
``psbmpc_2020``      the same grid search with seed 004's cost (:func:`psbmpc_jax.methods.psbmpc2020_terms`)
``informed_sbmpc``   the same grid search with seed 002's cost (:func:`psbmpc_jax.methods.informed_terms`):
                     route exchange, Rule 18, bearing-shaped d_safe; planners rest beyond ``d_init``
``smooth_sbmpc``     Smooth-SBMPC of seed 000 (:class:`psbmpc_jax.smooth.planner.SmoothSBMPCPlanner`), all runs
                     of an update in one ``plan_batch`` call; per-step controls at ``mpc.smooth.dt_s`` (own-ship)
``sbmpc_init``       its initialisation stage alone (``init_only=True``): the paper's "original SB-MPC" (Sim 01)
``two_level``        the two-level MPC of seed 001 (:class:`psbmpc_jax.two_level.planner.TwoLevelPlanner`,
                     :mod:`psbmpc_jax.sim.colav_two_level`): absolute course/speed commands
===================  ==========================================================================================

Every controller returns, per (run, ship) job of an update, the offsets (speed factor, course offset [rad])
applied at the update and optionally a per-step sequence with its step; the simulator
(:mod:`psbmpc_jax.sim.simulator`) applies them on top of LOS guidance exactly like PSB-MPC's offsets.  A
sequence is used only when its first row is the offsets to apply now (else those are held for the period).

The smooth planner sees the own-ship's true state and the targets through the own-ship's tracks: the Kalman
filter's position, course ``atan2(V_east, V_north)`` and speed ``|V|`` (the experiment runs with tracking
noise; seed 000 itself gives its planner the true target states).
"""

from __future__ import annotations

import dataclasses
import functools
import time
from dataclasses import dataclass, field
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..costs.base import term_names
from ..evaluate import DEFAULT_TERMS
from ..numerics import shift_controls
from ..packing import SHARED_AXES, pack, stack
from ..solve import Plan, PlannerState, solve, solve_arrays

#: Columns of ``SimulationResult.best_costs`` (the simulator plans with the default cost terms).
COST_NAMES = term_names(DEFAULT_TERMS)
#: Per-update diagnostics of the gradient methods (``SimulationResult.colav_info``; NaN where not applicable).
INFO_NAMES = ("cost", "warm_cost", "violation", "used_warm", "status", "iterations")
#: Size [m] a point target (``length_m: 0``) gets in a PSB-MPC situation, which needs a positive hull.
POINT_HULL_M = 1e-6


@dataclass
class Decisions:
    """What one controller decided at one update, per job ``(run, ship)``.

    Attributes:
        jobs: the ``(run, ship)`` pairs, in the order of the arrays.
        first: offsets ``(u, chi)`` applied at the update ``[n, 2]``.
        sequences: per-step offsets ``[n, N, 2]`` (row ``j`` applies from ``t_update + j * seq_dt`` on, the last
            row to the end of the period), or None: ``first`` is held until the next update.
        seq_dt: the step of ``sequences`` [s].
        costs: the chosen behaviour's cost columns ``[n, len(COST_NAMES)]`` (NaN for the smooth methods).
        info: :data:`INFO_NAMES` -> ``[n]`` (refinement / DOCP diagnostics) or None.
        walls: wall time of each job [s] (amortised over the jobs of one device call).
        device_calls, wall: device calls of this update and their wall time [s].
        kept, kept_job: the snapshot job's full evaluation (PSB-MPC only) or None.
        commands: absolute commands ``(U, chi)`` ``[n, 2]`` [m/s, rad] applied as they are (not on top of LOS
            guidance) until the next update, or None (``two_level``: χ_c = χ_d + χ_m, U_c = U_d·U_m).
    """

    jobs: list
    first: np.ndarray
    costs: np.ndarray
    walls: np.ndarray
    device_calls: int
    wall: float
    sequences: np.ndarray | None = None
    seq_dt: float | None = None
    info: dict | None = None
    kept: object = None
    kept_job: tuple | None = None
    commands: np.ndarray | None = None


def consistent_sequences(first: np.ndarray, controls: np.ndarray, atol: float = 1e-6) -> np.ndarray:
    """``controls [n, N, 2]`` with row 0 set to ``first [n, 2]``; a job whose row 0 differs from ``first`` by more
    than ``atol`` (a fallback that applies something else) holds ``first`` over the whole sequence."""
    first = np.asarray(first, float)
    seq = np.array(controls, dtype=float, copy=True)
    same = np.all(np.abs(seq[:, 0] - first) <= atol, axis=-1)
    seq[~same] = first[~same, None, :]
    seq[:, 0] = first
    return seq


# ------------------------------------------------------------------------------------------------ PSB-MPC
@functools.lru_cache(maxsize=16)
def _batched_solve(config, terms):
    """vmap of the solve step over the solves of one MPC update (chart, grid and behaviours broadcast)."""
    return jax.jit(jax.vmap(functools.partial(solve_arrays, config=config, terms=terms),
                            in_axes=(SHARED_AXES, 0, None, None)))


def _costs_row(plan: Plan):
    """The chosen behaviour's cost columns ``[..., len(COST_NAMES)]`` (total first, then the default terms in
    order; NaN for a column the method's terms do not have)."""
    total = np.asarray(jax.device_get(plan.total), float)
    cols = [total] + [np.asarray(jax.device_get(plan.costs[name]), float) if name in plan.costs
                      else np.full(total.shape, np.nan) for name in COST_NAMES[1:]]
    return np.stack(cols, axis=-1)


def _refine_function():
    """:func:`psbmpc_jax.refine.refine` and its settings class (ImportError with a clear message if missing)."""
    try:
        from ..refine import RefineSettings, refine
    except ImportError as exc:
        raise ImportError(f"mpc.method psbmpc_refine needs psbmpc_jax.refine (refine, RefineSettings), which "
                          f"cannot be imported here: {exc}") from exc
    return refine, RefineSettings


def plan_now(kept, t: float, step: float) -> np.ndarray:
    """A plan kept at an earlier update, ``(t_kept [s], controls [..., N, 2])`` with one control per ``step``
    seconds, as seen at time ``t``: shifted by the steps since (:func:`~psbmpc_jax.numerics.shift_controls`), or
    NaN throughout (no plan) once its whole horizon has passed."""
    t_kept, controls = kept
    steps = int(round((t - t_kept) / step))
    if steps > controls.shape[-2]:
        return np.full_like(controls, np.nan)
    return shift_controls(controls, steps)


class _Solver:
    """Device side of one PSB-MPC update: solve packed situations (one vmapped call or one call each) and return
    the chosen behaviour indices, their cost columns and, on request, one situation's full evaluation; the jobs
    flagged ``refine`` are refined after their solve (:func:`psbmpc_jax.refine.refine`)."""

    def __init__(self, mode: str, config, params, samples, refine=None, terms=DEFAULT_TERMS):
        self.mode, self.config, self.params, self.samples = mode, config, params, samples
        self.refine = refine            # (refine function, settings) or None
        self.terms = tuple(terms)

    def _refine_one(self, inputs, plan, state, evaluation):
        """Refine one solve: ``state`` is the planner state passed TO that solve, ``evaluation`` its third output
        (so the grid is not evaluated twice)."""
        fn, settings = self.refine
        ref = fn(inputs, plan, state, self.params, self.samples, self.config, settings, evaluation=evaluation)
        return jax.device_get(ref)

    def __call__(self, packed: list, states: list, keep: int | None, refine_jobs=()):
        """Returns the chosen indices ``[n]``, their cost rows ``[n, C]``, the kept evaluation (or None), the wall
        time of each solve ``[n]`` [s] (None under vmap, where only the call as a whole is timed) and
        ``{job index: Refinement}`` of the refined jobs (host arrays)."""
        refine_jobs = set(refine_jobs)
        refined = {}
        if self.mode == "vmap":
            batch_state = jax.tree.map(lambda *a: jnp.stack([jnp.asarray(x) for x in a]), *states)
            plan, _, ev = _batched_solve(self.config, self.terms)(stack(packed), batch_state, self.params,
                                                                  self.samples)
            best, costs = jax.device_get(plan.best), _costs_row(plan)
            kept = jax.tree.map(lambda a: a[keep], ev) if keep is not None else None
            for n in sorted(refine_jobs):
                one = functools.partial(lambda n_, a: a[n_], n)
                refined[n] = self._refine_one(packed[n], jax.tree.map(one, plan), states[n], jax.tree.map(one, ev))
            return np.asarray(best), np.asarray(costs), kept, None, refined
        outs, kept, walls = [], None, []
        for n, (inputs, state) in enumerate(zip(packed, states)):
            t0 = time.perf_counter()   # each solve timed up to its decision on the host
            plan, _, ev = solve(inputs, state, self.params, self.samples, config=self.config, terms=self.terms)
            outs.append((jax.device_get(plan.best), _costs_row(plan)))
            if n in refine_jobs:
                refined[n] = self._refine_one(inputs, plan, state, ev)
            walls.append(time.perf_counter() - t0)
            if n == keep:
                kept = ev
        return (np.array([b for b, _ in outs]), np.stack([c for _, c in outs]), kept,
                np.asarray(walls, dtype=float), refined)

    def device_calls(self, n_solves: int, n_refined: int = 0) -> int:
        return (1 if self.mode == "vmap" else n_solves) + n_refined


class GridGroup:
    """The ships of one grid-search method (``psbmpc``, ``psbmpc_refine``, ``sbmpc``, ``psbmpc_2020``; the
    registry :mod:`psbmpc_jax.sim.methods` builds one per method): every run and ship of an update solved
    together with the method's cost ``terms``, obstacles predicted with ``n_ps`` scenarios (None: ``mpc.n_ps``;
    1: straight lines); ``refine_ships`` are refined after the search.  ``samples``: the estimator's table."""

    def __init__(self, ships, mode: str, mpc, params, samples, refine_ships=(), terms=DEFAULT_TERMS,
                 n_ps: int | None = None, method: str = "psbmpc", informed: bool = False,
                 d_init: float | None = None):
        self.ships, self.mpc, self.method = tuple(int(i) for i in ships), mpc, method
        self.refine_ships = tuple(int(i) for i in refine_ships)
        self.n_ps = n_ps
        self.informed, self.d_init = informed, d_init
        self.terms = tuple(terms)
        refine = None
        if self.refine_ships:
            fn, settings_cls = _refine_function()
            refine = (fn, refine_settings(mpc, settings_cls))
        self.solver = _Solver(mode, mpc.config, params, samples, refine, self.terms)
        self.previous_start = bool(refine and getattr(refine[1], "previous_start", False))
        self._previous: dict = {}                  # (run, ship) -> (t [s], refined controls [N, 2])

    def _warm_start(self, loop, r: int, i: int, k: int):
        """The previous refinement of ship ``i`` in run ``r`` shifted to now (NaN: none, or past its horizon);
        None without ``previous_start``."""
        if not self.previous_start:
            return None
        if (r, i) not in self._previous:
            return np.full((self.mpc.config.n_steps, 2), np.nan)
        return plan_now(self._previous[(r, i)], float(loop.t[k]), self.mpc.config.dt)

    @property
    def snapshots(self) -> bool:
        """Whether the own-ship's full evaluation can be kept (the snapshot reads the PSB-MPC terms' details)."""
        return 0 in self.ships and self.terms == tuple(DEFAULT_TERMS)

    def _active(self, loop, r: int, i: int, k: int) -> bool:
        """With ``d_init``: whether another ship is within it (else the planner rests this update)."""
        if self.d_init is None:
            return True
        d = np.hypot(*(loop.states[r, :, k, :2] - loop.states[r, i, k, :2]).T)
        d[i] = np.inf
        return bool(np.min(d) <= self.d_init)

    def update(self, loop, k: int, keep_job) -> Decisions:
        jobs = [(r, i) for r in range(loop.R) for i in self.ships]
        active = [self._active(loop, r, i, k) for r, i in jobs]
        if all(active):
            return self._solve(loop, k, keep_job, jobs)
        # resting planners apply (1, 0) and forget their last offsets (SPEC_SEEDS §3.4)
        first = np.tile([1.0, 0.0], (len(jobs), 1))
        costs = np.full((len(jobs), len(COST_NAMES)), np.nan)
        walls = np.full(len(jobs), np.nan)             # no solve: not a solve time (metrics skip NaN)
        busy = [n for n, a in enumerate(active) if a]
        calls, wall, kept, kept_job = 0, 0.0, None, None
        if busy:
            sub = self._solve(loop, k, keep_job, [jobs[n] for n in busy])
            first[busy], costs[busy], walls[busy] = sub.first, sub.costs, sub.walls
            calls, wall, kept, kept_job = sub.device_calls, sub.wall, sub.kept, sub.kept_job
        return Decisions(jobs=jobs, first=first, costs=costs, walls=walls, device_calls=calls, wall=wall, kept=kept,
                         kept_job=kept_job)

    def _solve(self, loop, k: int, keep_job, jobs) -> Decisions:
        mpc, config = self.mpc, self.mpc.config
        if not self.snapshots:
            keep_job = None
        packed = [pack(loop.situation(r, i, k, n_ps=self.n_ps, informed=self.informed), mpc.behaviours, config,
                       grid=loop.grid) for r, i in jobs]
        states = [PlannerState((loop.u_c[r, i], loop.chi_off[r, i]), self._warm_start(loop, r, i, k)) for r, i in jobs]
        keep = jobs.index(keep_job) if keep_job in jobs else None
        refine_jobs = [n for n, (_, i) in enumerate(jobs) if i in self.refine_ships]
        t0 = time.perf_counter()
        best, costs, kept, walls, refined = self.solver(packed, states, keep, refine_jobs)
        wall = time.perf_counter() - t0
        if walls is None:      # vmap: one call for every solve, amortised
            walls = np.full(len(jobs), wall / len(jobs))
        first = np.array([mpc.behaviours[int(b)][0] for b in best], dtype=float).reshape(len(jobs), 2)
        out = Decisions(jobs=jobs, first=first, costs=np.asarray(costs, float), walls=np.asarray(walls, float),
                        device_calls=self.solver.device_calls(len(jobs), len(refined)), wall=wall, kept=kept,
                        kept_job=keep_job if keep is not None else None)
        if refined:
            out = _with_refinements(out, refined, mpc.config.dt)
            if self.previous_start:
                for n, ref in refined.items():
                    self._previous[jobs[n]] = (float(loop.t[k]), np.asarray(ref.controls, float).reshape(-1, 2))
        return out


def refine_settings(mpc, settings_cls):
    """``RefineSettings`` from the scenario's ``mpc.refine`` and, where the file gives them, ``mpc.solver`` (over
    RefineSettings' default solver) and ``mpc.fis.e_cl_m`` / ``n_y`` (the refinement's FIS edge width and output
    grid).  ``block``: ``mpc.refine.block_s`` in PSB-MPC steps, by default the MPC update period (one refined
    control per re-plan: per-step controls jittered in closed loop, docs/refine.md "Closed loop");
    ``previous_start`` when ``mpc.refine.previous_start`` is on.  The rest (``batch``, ``path_eps``) are
    RefineSettings' defaults."""
    from ..nlp import SolverSettings

    r = mpc.refine
    kw = {k: v for k, v in (("fis_e_cl", r.fis_e_cl), ("fis_n_y", r.fis_n_y)) if v is not None}
    if mpc.solver.given():       # the file's keys over the refinement's own (cheap) default solver
        base = getattr(settings_cls(), "solver", None)
        kw["solver"] = dataclasses.replace(base if isinstance(base, SolverSettings) else SolverSettings(),
                                           **mpc.solver.given())
    hold = r.block if r.block is not None else min(mpc.period, r.horizon or mpc.config.T)
    kw["block"] = max(1, int(round(hold / mpc.config.dt)))
    if r.previous_start:
        kw["previous_start"] = True
    return settings_cls(n_starts=r.n_starts, horizon=r.horizon, colregs=r.colregs, **kw)


def _with_refinements(dec: Decisions, refined: dict, step: float) -> Decisions:
    """Jobs that were refined apply the refinement's per-step controls; the others hold their grid offsets."""
    n_max = max(np.asarray(ref.controls).shape[0] for ref in refined.values())
    first = dec.first.copy()
    seq = np.repeat(first[:, None, :], n_max, axis=1)
    info = {name: np.full(len(dec.jobs), np.nan) for name in INFO_NAMES}
    for n, ref in refined.items():
        apply = np.asarray(ref.apply, float).reshape(2)
        ctrl = np.asarray(ref.controls, float).reshape(-1, 2)
        ctrl = np.concatenate([ctrl, np.repeat(ctrl[-1:], n_max - len(ctrl), axis=0)]) if len(ctrl) < n_max else ctrl
        first[n] = apply
        seq[n] = consistent_sequences(apply[None], ctrl[None])[0]
        for name in INFO_NAMES:
            info[name][n] = float(np.asarray(getattr(ref, name)))
    return dataclasses.replace(dec, first=first, sequences=seq, seq_dt=float(step), info=info)


# ------------------------------------------------------------------------------------------------ smooth
def smooth_planner_class():
    """:class:`psbmpc_jax.smooth.planner.SmoothSBMPCPlanner` (ImportError with a clear message if missing)."""
    try:
        from ..smooth.planner import SmoothSBMPCPlanner
    except ImportError as exc:
        raise ImportError(f"mpc.method smooth_sbmpc / sbmpc_init needs psbmpc_jax.smooth.planner "
                          f"(SmoothSBMPCPlanner), which cannot be imported here: {exc}") from exc
    return SmoothSBMPCPlanner


def smooth_arguments(scenario) -> dict:
    """The keyword arguments of ``SmoothSBMPCPlanner`` for the scenario's own-ship: weights (``mpc.fis``,
    ``mpc.smooth.k_ntp``; the rest SPEC_SEEDS §1.8 defaults), the ship model from the own-ship's spec (nominal
    speed, LOS lookahead, acceptance radius, autopilot time constants), the settings (``mpc.smooth``,
    ``mpc.fis``), the solver (the keys of ``mpc.solver`` over SolverSettings' defaults; None without any: the
    planner's own default), the number of starts, ``init_only`` for ``sbmpc_init``, the dtype of
    ``mpc.config`` and ``previous_start`` (only when ``mpc.smooth.previous_start`` is on, not for ``sbmpc_init``)."""
    from ..nlp import SolverSettings
    from ..smooth.init_stage import ShipModel, SmoothSettings, SmoothWeights

    mpc, own = scenario.mpc, scenario.own_ship
    sm, fis = mpc.smooth, mpc.fis
    given = mpc.solver.given()
    return dict(
        weights=SmoothWeights(d_cl=fis.d_cl, e_cl=fis.e_cl, eps=fis.eps, k_ntp=sm.k_ntp),
        model=ShipModel(U_d=float(own.U_d), lookahead=float(own.lookahead), R_a=float(own.R_a),
                        T_chi=float(own.T_chi), T_U=float(own.T_U)),
        settings=SmoothSettings(T_init=sm.T_init, T_mpc=sm.T_mpc, dt=sm.dt, r_dom=sm.domain_radius,
                                corridor_half_width=sm.corridor_half_width, terminal=sm.terminal,
                                fis_completion=fis.completion, n_y=fis.n_y),
        solver=SolverSettings(**given) if given else None,
        n_starts=sm.n_starts, init_only=mpc.method == "sbmpc_init", dtype=mpc.config.dtype,
        **({"previous_start": True} if sm.previous_start and mpc.method != "sbmpc_init" else {}))


def tracked_targets(track_x: np.ndarray) -> np.ndarray:
    """Tracks ``[..., 4]`` (north, east, V_north, V_east) -> point targets ``[..., 4]`` (north, east, course
    ``atan2(V_east, V_north)`` [rad], speed ``|V|``)."""
    x = np.asarray(track_x, float)
    return np.stack([x[..., 0], x[..., 1], np.arctan2(x[..., 3], x[..., 2]), np.hypot(x[..., 2], x[..., 3])],
                    axis=-1)


class SmoothGroup:
    """The own-ship under ``smooth_sbmpc`` / ``sbmpc_init``: one ``plan_batch`` call per update for all runs.
    With ``mpc.smooth.previous_start`` it keeps each run's last kept sequence and hands it, shifted by the
    steps since that update, to the next update as a DOCP start."""

    ships = (0,)

    def __init__(self, scenario, planner_cls=None):
        cls = smooth_planner_class() if planner_cls is None else planner_cls
        self.step = float(scenario.mpc.smooth.dt)
        args = smooth_arguments(scenario)
        self.previous_start = bool(args.get("previous_start", False))
        self.planner = cls(scenario.polygons, batch="map", **args)
        self._previous = None                                                  # (t [s], controls [R, N, 2])

    def _shifted_previous(self, t: float):
        if not self.previous_start or self._previous is None:
            return None
        return plan_now(self._previous, t, self.step)

    def update(self, loop, k: int, keep_job) -> Decisions:
        R = loop.R
        states = loop.states[:, 0, k]                                           # [R, 4] true own-ship state
        targets = tracked_targets(loop.track_x[:, :, k])                        # [R, I, 4]
        last = np.stack([loop.u_c[:, 0], loop.chi_off[:, 0]], axis=-1)         # [R, 2] applied offsets
        route = loop.routes_ext[0, : loop.n_wp[0]]                              # the route, extended
        t = float(loop.t[k])
        extra = {"previous": self._shifted_previous(t)} if self.previous_start else {}
        t0 = time.perf_counter()
        plan = self.planner.plan_batch(states, route, targets, last, np.asarray(loop.seg[:, 0]), **extra)
        plan = jax.device_get(plan)
        wall = time.perf_counter() - t0
        first = np.asarray(plan.apply, float).reshape(R, 2)
        controls = np.asarray(plan.controls, float).reshape(R, -1, 2)
        if self.previous_start:
            self._previous = (t, controls)
        info = {name: np.asarray(getattr(plan, name), float).reshape(R) for name in INFO_NAMES}
        return Decisions(jobs=[(r, 0) for r in range(R)], first=first,
                         costs=np.full((R, len(COST_NAMES)), np.nan), walls=np.full(R, wall / R), device_calls=1,
                         wall=wall, sequences=consistent_sequences(first, controls), seq_dt=self.step, info=info)


class StepPlan(NamedTuple):
    """What :meth:`SmoothStepPlanner.plan_batch` returns: the fields of ``SmoothPlan`` with a leading run axis."""

    apply: np.ndarray
    controls: np.ndarray
    psi: np.ndarray
    cost: np.ndarray
    warm_cost: np.ndarray
    violation: np.ndarray
    used_warm: np.ndarray
    status: np.ndarray
    iterations: np.ndarray


class SmoothStepPlanner:
    """A reference planner with ``SmoothSBMPCPlanner``'s interface, built on the existing single-situation
    functions :func:`psbmpc_jax.smooth.docp.smooth_sbmpc_step` (``init_only=False``: init stage, corridor, one
    DOCP solve from the warm start, safeguard) and :func:`psbmpc_jax.smooth.init_stage.init_stage`
    (``init_only=True``: the original SB-MPC; its per-step controls are the init stage's offsets).  One device
    call per run, no multi-start (``n_starts`` and ``batch`` are accepted and ignored).  For tests and
    cross-checks: pass it as ``build(..., smooth_planner_cls=SmoothStepPlanner)``."""

    def __init__(self, polygons=(), *, weights=None, model=None, settings=None, solver=None, n_starts=4,
                 batch="map", init_only=False, dtype="float32"):
        from ..nlp import SolverSettings
        from ..packing import pack_world
        from ..params import PlannerConfig
        from ..smooth import buffered_chart
        from ..smooth.init_stage import ShipModel, SmoothSettings, SmoothWeights

        self.weights = SmoothWeights() if weights is None else weights
        self.model = ShipModel() if model is None else model
        self.settings = SmoothSettings() if settings is None else settings
        self.solver = SolverSettings() if solver is None else solver
        self.init_only, self.dtype = bool(init_only), np.dtype(dtype)
        self.land = pack_world(tuple(polygons), PlannerConfig(dtype=str(self.dtype))).polygons
        self.buffered = None if self.init_only else buffered_chart(tuple(polygons), self.settings.r_dom,
                                                                    dtype=str(self.dtype))

    def plan(self, state0, route, targets, last, segment=0) -> StepPlan:
        from ..smooth.docp import smooth_sbmpc_step
        from ..smooth.init_stage import init_stage

        f = self.dtype.type
        state0, targets, last = (np.asarray(a, self.dtype) for a in (state0, targets, last))
        route = np.asarray(route, self.dtype)[int(segment):]
        n = self.settings.n_mpc
        if self.init_only:
            init = jax.device_get(init_stage(state0, route, targets, last, self.land, self.weights, self.model,
                                             self.settings))
            cost = np.asarray(init.cost[0], self.dtype)
            return StepPlan(np.asarray(init.controls[0]), np.asarray(init.controls[:n]), np.asarray(init.psi), cost,
                            cost, f(0.0), np.int32(1), np.int32(0), np.int32(0))
        st = jax.device_get(smooth_sbmpc_step(state0, route, targets, last, self.land, self.buffered,
                                              weights=self.weights, model=self.model, settings=self.settings,
                                              solver=self.solver))
        return StepPlan(np.asarray(st.apply), np.asarray(st.controls), np.asarray(st.init.psi), np.asarray(st.cost),
                        np.asarray(st.warm_cost), np.asarray(st.violation), np.asarray(st.used_warm, np.int32),
                        np.asarray(st.solver.status), np.asarray(st.solver.inner_iterations))

    def plan_batch(self, states, route, targets, last, segments) -> StepPlan:
        rows = [self.plan(states[r], route, targets[r], last[r], int(segments[r])) for r in range(len(states))]
        return StepPlan(*(np.stack([np.asarray(getattr(p, name)) for p in rows]) for name in StepPlan._fields))


# ------------------------------------------------------------------------------------------------ dispatch
@dataclass
class Colav:
    """The controllers of a scenario's ships (:func:`build`): ``groups`` in call order, ``method`` of the
    own-ship (None when it runs no collision avoidance), ``controlled`` ship mask, ``methods`` per ship
    (``"none"`` or a method name)."""

    groups: list
    method: str | None
    controlled: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    methods: tuple = ()

    def update(self, loop, k: int, keep_job) -> list[Decisions]:
        """One MPC update: every group's decisions for every run."""
        return [g.update(loop, k, keep_job) for g in self.groups]

    @property
    def snapshots(self) -> bool:
        """Whether the own-ship's solves can be kept in full (PSB-MPC search of the own-ship)."""
        return any(getattr(g, "snapshots", False) for g in self.groups)

    @property
    def uses_grid(self) -> bool:
        """Whether any ship runs a grid search (which needs the chart's distance grid in ``grid`` mode)."""
        return any(isinstance(g, GridGroup) for g in self.groups)


def build(scenario, mode: str, params, samples, *, smooth_planner_cls=None, key=None) -> Colav:
    """The controllers of ``scenario``: every ship runs the method its ``colav`` names (the own-ship's is
    ``mpc.method``), the ships of one method in one group (:data:`psbmpc_jax.sim.methods.REGISTRY`).
    ``params`` / ``samples``: the PSB-MPC parameters as arrays and the estimator's sample table; ``key``: the
    PRNG key methods with their own sample tables draw from; ``smooth_planner_cls`` replaces
    :class:`~psbmpc_jax.smooth.planner.SmoothSBMPCPlanner` (same interface)."""
    from .methods import build_groups

    ships = scenario.ships
    methods = tuple(s.colav for s in ships)
    groups = build_groups(scenario, mode, params, samples, methods, key=key, smooth_planner_cls=smooth_planner_cls)
    return Colav(groups=groups, method=None if methods[0] == "none" else methods[0],
                 controlled=np.array([m != "none" for m in methods]), methods=methods)


__all__ = ["COST_NAMES", "INFO_NAMES", "POINT_HULL_M", "Decisions", "Colav", "GridGroup", "SmoothGroup",
           "SmoothStepPlanner", "StepPlan", "build", "smooth_arguments", "smooth_planner_class", "refine_settings",
           "tracked_targets", "consistent_sequences"]
