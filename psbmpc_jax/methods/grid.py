"""The grid-search controller: every method that searches the PSB-MPC behaviour table with
:func:`psbmpc_jax.solve.solve` (``psbmpc``, ``psbmpc_refine``, ``sbmpc``, ``psbmpc_2020``, ``informed_sbmpc``).

The methods differ in their cost terms and in how they predict the obstacles (``n_ps``; ``informed``: along the
routes the ships shared); ``psbmpc_refine`` adds the gradient refinement (:func:`psbmpc_jax.refine.refine`) after
the search, whose per-step controls are applied step by step between two updates (row ``j`` from
``t_update + j * config.dt`` on).  All solves of one update -- every run and every ship of the controller -- go
to the device together, as one ``vmap``-ed call (``mode="vmap"``) or one call each (``mode="loop"``).
"""

from __future__ import annotations

import dataclasses
import functools
import time

import jax
import jax.numpy as jnp
import numpy as np

from ..evaluate import DEFAULT_TERMS
from ..numerics import shift_controls, wrap_angle_host
from ..packing import pack, stack, unpack
from ..sharding import solve_batch
from ..solve import Plan, PlannerState, solve
from .base import COST_NAMES, INFO_NAMES, Decision, Observation


def consistent_sequences(first: np.ndarray, controls: np.ndarray, atol: float = 1e-6) -> np.ndarray:
    """``controls [n, N, 2]`` with row 0 set to ``first [n, 2]``; a job whose row 0 differs from ``first`` by more
    than ``atol`` (a fallback that applies something else) holds ``first`` over the whole sequence."""
    first = np.asarray(first, float)
    seq = np.array(controls, dtype=float, copy=True)
    same = np.all(np.abs(seq[:, 0] - first) <= atol, axis=-1)
    seq[~same] = first[~same, None, :]
    seq[:, 0] = first
    return seq


def _costs_row(plan: Plan):
    """The chosen behaviour's cost columns ``[..., len(COST_NAMES)]`` (total first, then the default terms in
    order; NaN for a column the method's terms do not have)."""
    total = np.asarray(jax.device_get(plan.total), float)
    cols = [total] + [np.asarray(jax.device_get(plan.costs[name]), float) if name in plan.costs
                      else np.full(total.shape, np.nan) for name in COST_NAMES[1:]]
    return np.stack(cols, axis=-1)


def refine_function():
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
    """Device side of one PSB-MPC update: solve packed situations (one vmapped call, its batch split over
    ``devices`` when there are several, or one call each) and return the chosen behaviour indices, their cost
    columns and, on request, one situation's full evaluation; the jobs flagged ``refine`` are refined after their
    solve (:func:`psbmpc_jax.refine.refine`)."""

    def __init__(self, mode: str, config, params, samples, refine=None, terms=DEFAULT_TERMS, devices=None):
        self.mode, self.config, self.params, self.samples = mode, config, params, samples
        self.refine = refine            # (refine function, settings) or None
        self.terms = tuple(terms)
        self.devices = None if devices is None else tuple(devices)    # None: the default device, unsplit
        if self.devices is not None and len(self.devices) > 1 and mode != "vmap":
            raise ValueError(f"{len(self.devices)} devices split the vmapped batch of an update; batch mode "
                             f"{mode!r} makes one call per solve (use batch 'vmap' or 'auto')")

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
            plan, _, ev = solve_batch(stack(packed), batch_state, self.params, self.samples, self.config,
                                      self.terms, self.devices)
            best, costs = jax.device_get(plan.best), _costs_row(plan)
            kept = jax.tree.map(functools.partial(self._row, keep), ev) if keep is not None else None
            for n in sorted(refine_jobs):
                one = functools.partial(self._row, n)
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

    def _row(self, n: int, a):
        """Solve ``n``'s row of a batched output, on one device (rows of a batch split over several devices
        live on theirs; the refinement then runs where a single-device solve would)."""
        row = a[n]
        return jax.device_put(row, self.devices[0]) if self.devices is not None and len(self.devices) > 1 else row

    def device_calls(self, n_solves: int, n_refined: int = 0) -> int:
        return (1 if self.mode == "vmap" else n_solves) + n_refined


class GridController:
    """The controller of one grid-search method for all its ships (built by the method, see
    :mod:`psbmpc_jax.methods.builtin`): every run and ship of an update solved together with the method's cost
    ``terms``, obstacles predicted with ``n_ps`` scenarios (None: ``mpc.n_ps``; 1: straight lines); ``refine_ships``
    are refined after the search.  ``samples``: the estimator's table.  ``informed``: obstacles along the routes
    they shared (Informed SB-MPC); ``d_init``: the planner rests, applying (1, 0), while no other ship is within
    it.  ``freeze``: the COLREGS option (a ``ColregsOptionSpec``) whose held course reference applies
    (:mod:`psbmpc_jax.methods.colregs_hold`; None: offsets over LOS guidance throughout)."""

    uses_grid = True                 # packs the chart's distance grid in grounding_mode "grid"
    splits_runs = True               # its vmapped batch is split over BuildContext.devices

    def __init__(self, ships, mode: str, mpc, params, samples, refine_ships=(), terms=DEFAULT_TERMS,
                 n_ps: int | None = None, method: str = "psbmpc", informed: bool = False,
                 d_init: float | None = None, devices=None, freeze=None):
        self.ships, self.mpc, self.method = tuple(int(i) for i in ships), mpc, method
        self.freeze = freeze
        # the held-course option's engagement radii (only read when the option freezes a course)
        self.d_safe = float("nan") if freeze is None else float(params.d_safe)
        self.refine_ships = tuple(int(i) for i in refine_ships)
        self.n_ps = n_ps
        self.informed, self.d_init = informed, d_init
        self.terms = tuple(terms)
        self.solver = _Solver(mode, mpc.config, params, samples, None, self.terms, devices)
        self.previous_start = False
        self._previous: dict = {}                  # (run, ship) -> (t [s], refined controls [N, 2])
        if self.refine_ships:
            self.enable_refinement(self.refine_ships)

    def enable_refinement(self, ships=None) -> None:
        """Refine the solves of ``ships`` (default: all of this controller's) after the grid search
        (:func:`psbmpc_jax.refine.refine` with :func:`refine_settings` of the scenario's ``mpc``)."""
        self.refine_ships = self.ships if ships is None else tuple(int(i) for i in ships)
        fn, settings_cls = refine_function()
        self.solver.refine = (fn, refine_settings(self.mpc, settings_cls))
        self.previous_start = bool(getattr(self.solver.refine[1], "previous_start", False))

    def _warm_start(self, obs: Observation, r: int, i: int):
        """The previous refinement of ship ``i`` in run ``r`` shifted to now (NaN: none, or past its horizon);
        None without ``previous_start``."""
        if not self.previous_start:
            return None
        if (r, i) not in self._previous:
            return np.full((self.mpc.config.n_steps, 2), np.nan)
        return plan_now(self._previous[(r, i)], obs.t, self.mpc.config.dt)

    @property
    def snapshots(self) -> bool:
        """Whether the own-ship's full evaluation can be kept (the snapshot reads the PSB-MPC terms' details)."""
        return 0 in self.ships and self.terms == tuple(DEFAULT_TERMS)

    def _active(self, obs: Observation, r: int, i: int) -> bool:
        """With ``d_init``: whether another ship is within it (else the planner rests this update)."""
        if self.d_init is None:
            return True
        d = np.hypot(*(obs.states[r, :, :2] - obs.states[r, i, :2]).T)
        d[i] = np.inf
        return bool(np.min(d) <= self.d_init)

    def init(self, n_runs: int) -> None:
        """Forget the refinements kept for ``previous_start``."""
        self._previous = {}

    def decide(self, obs: Observation) -> Decision:
        jobs = [(r, i) for r in range(obs.n_runs) for i in self.ships]
        active = [self._active(obs, r, i) for r, i in jobs]
        if all(active):
            return self._solve(obs, jobs)
        # resting planners apply (1, 0) and forget their last offsets (Informed SB-MPC's d_init rule)
        first = np.tile([1.0, 0.0], (len(jobs), 1))
        costs = np.full((len(jobs), len(COST_NAMES)), np.nan)
        walls = np.full(len(jobs), np.nan)             # no solve: not a solve time (metrics skip NaN)
        busy = [n for n, a in enumerate(active) if a]
        calls, wall, snapshot = 0, 0.0, None
        if busy:
            sub = self._solve(obs, [jobs[n] for n in busy])
            first[busy], costs[busy], walls[busy] = sub.first, sub.costs, sub.walls
            calls, wall, snapshot = sub.device_calls, sub.wall, sub.snapshot
        return Decision(jobs=jobs, first=first, costs=costs, walls=walls, device_calls=calls, wall=wall,
                        snapshot=snapshot)

    def _solve(self, obs: Observation, jobs) -> Decision:
        mpc, config = self.mpc, self.mpc.config
        keep_job = obs.keep if self.snapshots else None
        situations = [obs.situation(r, i, n_ps=self.n_ps, informed=self.informed) for r, i in jobs]
        refs = np.full(len(jobs), np.nan)            # the frozen course reference of a held job [rad]
        if self.freeze is not None:
            from .colregs_hold import engaged_now, frozen_reference

            for n, s in enumerate(situations):
                if engaged_now(s, self.d_safe, self.freeze):
                    situations[n], refs[n] = frozen_reference(s)
        packed = [pack(s, mpc.behaviours, config, grid=obs.grid) for s in situations]
        states = [PlannerState((obs.offsets[r, i, 0], obs.offsets[r, i, 1]), self._warm_start(obs, r, i))
                  for r, i in jobs]
        keep = jobs.index(keep_job) if keep_job in jobs else None
        refine_jobs = [n for n, (_, i) in enumerate(jobs) if i in self.refine_ships]
        t0 = time.perf_counter()
        best, costs, kept, walls, refined = self.solver(packed, states, keep, refine_jobs)
        wall = time.perf_counter() - t0
        if walls is None:      # vmap: one call for every solve, amortised
            walls = np.full(len(jobs), wall / len(jobs))
        first = np.array([mpc.behaviours[int(b)][0] for b in best], dtype=float).reshape(len(jobs), 2)
        snapshot = None
        if kept is not None and keep is not None:      # kept: the keep job's arrays
            snapshot = unpack(kept, situations[keep], mpc.behaviours, wall,
                              per_polygon=config.grounding_mode == "exact", names=COST_NAMES)
        commands = None
        if np.any(np.isfinite(refs)):                # held jobs: absolute (u U_d, α + χ); the others NaN (LOS + χ)
            u_d = np.array([s.own_ship.U_d for s in situations])
            commands = np.column_stack([first[:, 0] * u_d, wrap_angle_host(refs + first[:, 1], include_pi=True)])
        out = Decision(jobs=jobs, first=first, costs=np.asarray(costs, float), walls=np.asarray(walls, float),
                       device_calls=self.solver.device_calls(len(jobs), len(refined)), wall=wall, snapshot=snapshot,
                       commands=commands)
        if refined:
            out = _with_refinements(out, refined, mpc.config.dt)
            if self.previous_start:
                for n, ref in refined.items():
                    self._previous[jobs[n]] = (obs.t, np.asarray(ref.controls, float).reshape(-1, 2))
        return out


class GroupedController:
    """One grid-search method whose ships plan with different cost terms (a ship's own ``colregs_option``): one
    :class:`GridController` per group of ships with the same terms, called in turn at each update; their
    decisions are returned as one (every job of every group, the device calls and wall times added up)."""

    uses_grid = True
    splits_runs = True

    def __init__(self, groups):
        self.groups = tuple(groups)
        if len(self.groups) < 2:
            raise ValueError(f"GroupedController needs at least two groups of ships, got {len(self.groups)}")
        self.ships = tuple(sorted(i for g in self.groups for i in g.ships))
        self.method = self.groups[0].method

    @property
    def snapshots(self) -> bool:
        return any(g.snapshots for g in self.groups)

    def init(self, n_runs: int) -> None:
        for g in self.groups:
            g.init(n_runs)

    def decide(self, obs: Observation) -> Decision:
        parts = [g.decide(obs) for g in self.groups]
        if any(p.sequences is not None or p.info is not None for p in parts):
            # the refinement, the only source of per-step sequences here, takes no COLREGS option, so a method
            # whose ships differ in their option is never refined
            raise ValueError("GroupedController: a refined group cannot be combined with others")
        commands = None
        if any(p.commands is not None for p in parts):
            commands = np.concatenate([p.commands if p.commands is not None else np.full((len(p.jobs), 2), np.nan)
                                       for p in parts])
        return Decision(jobs=[j for p in parts for j in p.jobs], first=np.concatenate([p.first for p in parts]),
                        costs=np.concatenate([p.costs for p in parts]),
                        walls=np.concatenate([p.walls for p in parts]),
                        device_calls=sum(p.device_calls for p in parts), wall=sum(p.wall for p in parts),
                        snapshot=next((p.snapshot for p in parts if p.snapshot is not None), None),
                        commands=commands)


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


def _with_refinements(dec: Decision, refined: dict, step: float) -> Decision:
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


__all__ = ["GridController", "GroupedController", "consistent_sequences", "plan_now", "refine_settings"]
