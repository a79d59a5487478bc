"""Closed-loop simulation of a :class:`~psbmpc_jax.scenario.Scenario`, Monte Carlo runs batched.

Per simulation step (``scenario.dt``), for all runs at once (NumPy arrays ``[R, n_ships, ...]``):

1. every ``sensor.period``: noisy position measurements of the targets update the own-ship's Kalman-filter
   tracks (constant-velocity model, single-point initiation; :mod:`psbmpc_jax.sim.tracker`);
2. every ``mpc.period``: every ship with collision avoidance plans once.  Each ship runs the method its
   ``colav`` names (the own-ship the one of ``mpc.method``), looked up in :mod:`psbmpc_jax.methods.registry`;
   one controller per method serves all its ships and runs.  The simulator hands every controller an
   :class:`~psbmpc_jax.methods.base.Observation` (true states, the own-ship's tracks, applied offsets, routes,
   shared routes) and applies the :class:`~psbmpc_jax.methods.base.Decision` it returns -- nothing else passes
   between them, and the simulator knows no method by name.  The built-in grid-search controllers send all
   solves of one update to the device together, as one ``vmap``-ed call (``batch="vmap"``) or one call each
   (``batch="loop"``); with ``devices`` > 1 the vmapped call's batch (runs x ships) is split over that many
   local devices (:func:`psbmpc_jax.sharding.solve_batch`), with the same results;
3. the true vessels move one step: LOS guidance on their routes with the controller's course offset and speed
   factor (the row of a per-step sequence that is due, for the gradient methods), kinematic model with
   autopilot lags (:mod:`psbmpc_jax.sim.vessel`).

Randomness: run ``r`` draws its measurement noise from ``numpy.random.default_rng([seed, r])`` (and its
route-exchange dropouts from ``default_rng([seed, r, 2002])``), where ``r`` is the run's index in the whole
Monte Carlo set: ``run_start`` plus its position in the call.  So a run replays identically whatever the number
of runs simulated with it, and runs ``[a, b)`` simulated alone (``run_start=a, runs=b - a``) equal the same runs
of one call of ``b`` runs bit for bit -- which lets a campaign cut its runs into tasks
(:mod:`psbmpc_jax.campaign`).

"""

from __future__ import annotations

import dataclasses
import logging
import sys
import time
from dataclasses import dataclass, field

import jax
import numpy as np

from ..checks import integer, multiple_of
from ..costs.collision import standard_normal_table
from ..distance_grid import build_distance_grid
from ..params import params_as_arrays
from .. import checks
from ..methods.base import COST_NAMES, INFO_NAMES, BuildContext, Observation
from ..methods.registry import build_controllers
from ..planner import check_dtype
from ..scenario_checks import check_run_size
from .. import simulation_time
from ..sharding import local_devices
from ..scenario import Scenario, route_geometry
from . import metrics as metrics_mod
from .tracker import TrackerBank
from . import vessel3dof
from .vessel import extend_route, kinematic_step, leg_speed, los_course, nominal_speed, pad_routes

BATCH_MODES = ("auto", "vmap", "loop")


@dataclass
class SimulationResult:
    """Everything a closed-loop simulation produced (NumPy, host).

    Attributes:
        scenario: the scenario simulated (with ``runs``/``seed`` as used).
        t: times ``[K+1]`` [s].
        states: true states ``[R, n_ships, K+1, 4]`` (north, east, course, speed); ship 0 is the own-ship.
        track_x, track_P: the own-ship's target estimates ``[R, n_targets, K+1, 4]`` and covariances
            ``[..., 4, 4]`` (after the measurement update of that step, if any).
        solve_t: MPC update times ``[M]``.
        offsets: (speed factor, course offset [rad]) applied at each update ``[R, n_ships, M, 2]`` (nan for
            ships without collision avoidance); the gradient methods then follow their per-step sequences
            until the next update.
        best_costs: cost columns of the chosen behaviour ``[R, n_ships, M, len(COST_NAMES)]`` (total, then
            the terms: do, colregs, so, path; nan for the smooth methods, which have no behaviour table).
        calls: one dict per MPC update: time, number of solves, number of device calls (1 with vmap, one per
            solve in the loop), wall time of all of them [s].
        solve_wall: wall time of each solve ``[R, n_ships, M]`` [s] (nan for ships without PSB-MPC): measured
            per solve in the loop (dispatch to the chosen behaviour on the host), the update's call time divided
            by its number of solves under vmap; the first update includes compiling the solver.
        snapshot: one solve of run ``snapshot_run``'s own-ship kept in full (all candidate trajectories and
            their costs) for the paper-Fig.-1-style plot: the first solve that chose to manoeuvre.
        metrics: per-run metrics (:func:`psbmpc_jax.sim.metrics.run_metrics` plus per-ship land distances
            and the minimum distance between every pair of ships).
        summary: :func:`psbmpc_jax.sim.metrics.aggregate` of ``metrics`` plus run information.
        method: the own-ship's controller (``mpc.method``; None when it runs no collision avoidance).
        colav_info: the own-ship's per-update diagnostics of the gradient methods, :data:`INFO_NAMES` ->
            ``[R, M]`` (refined / DOCP cost, warm-start cost, constraint violation, whether the warm start was
            kept, status, iterations; nan for ``psbmpc``).
        run_start: the Monte Carlo index of the first run (row 0 of every ``[R, ...]`` array); ``metrics[i]["run"]``
            is ``run_start + i``.
    """

    scenario: Scenario
    t: np.ndarray
    states: np.ndarray
    track_x: np.ndarray
    track_P: np.ndarray
    solve_t: np.ndarray
    offsets: np.ndarray
    best_costs: np.ndarray
    calls: list
    snapshot: dict | None
    metrics: list
    summary: dict = field(default_factory=dict)
    solve_wall: np.ndarray | None = None
    method: str | None = "psbmpc"
    colav_info: dict | None = None
    run_start: int = 0

    @property
    def ship_names(self) -> list[str]:
        """Ship names in the order of the ship axis (own-ship first)."""
        return [s.name for s in self.scenario.ships]


def resolve_batch_mode(batch: str, n_devices: int = 1) -> str:
    """``auto`` -> ``vmap`` on an accelerator, ``loop`` on the CPU (where one call per solve measured faster:
    see ``benchmarks/results``); ``vmap`` whenever the batch is split over ``n_devices`` > 1 devices, which
    ``loop`` (one call per solve) cannot be."""
    if batch not in BATCH_MODES:
        raise ValueError(f"batch must be one of {BATCH_MODES}, got {batch!r}")
    if n_devices > 1:
        if batch == "loop":
            raise ValueError(f"devices={n_devices} splits the vmapped call of each MPC update over the devices; "
                             f"batch 'loop' makes one call per solve: use batch 'vmap' or 'auto' with several "
                             f"devices, or devices=1 with 'loop'")
        return "vmap"
    if batch == "auto":
        return "loop" if jax.default_backend() == "cpu" else "vmap"
    return batch


# ------------------------------------------------------------------------------------------- helpers
def _refuse_unsplit(scenario: Scenario, colav, n_devices: int) -> None:
    """ValueError when ``n_devices`` > 1 were asked for but no controller of ``scenario`` splits its batch."""
    if n_devices > 1 and not colav.splits_runs:
        methods = sorted({m for m in colav.methods if m != "none"}) or ["none"]
        raise ValueError(f"devices={n_devices}: no controller of scenario {scenario.name!r} splits its solves over "
                         f"devices (methods: {', '.join(methods)}); only the grid-search methods' vmapped batch is "
                         f"split (psbmpc, psbmpc_refine, sbmpc, psbmpc_2020, informed_sbmpc): use devices=1")


def check_devices_split(scenario: Scenario, devices: int | str = 1, batch: str = "auto") -> tuple:
    """The devices :func:`simulate` would split ``scenario``'s runs over (``devices``, ``batch`` as there),
    checked without simulating (the controllers are built, nothing is compiled): ValueError for too many devices,
    ``batch="loop"`` with several, or several for a scenario none of whose controllers splits its batch.  The
    command line checks every scenario with it before the first simulation."""
    devs = local_devices(devices)
    resolve_batch_mode(batch, len(devs))
    if len(devs) > 1:
        _refuse_unsplit(scenario, build_controllers(scenario, BuildContext(mode="vmap", devices=devs)), len(devs))
    return devs


def grid_region(scenario: Scenario, routes) -> tuple:
    """The area the distance grid must cover: every route and start, plus the farthest a ship can travel
    in one horizon, plus a 25 % allowance for avoidance manoeuvres off the routes.  Returns (region, reach):
    predictions stay on the grid as long as every ship stays ``reach`` inside the region (checked after the
    run and reported as ``grid_region_exceeded``)."""
    pts = np.concatenate([np.asarray(r, float) for r in routes] + [s.position[None] for s in scenario.ships])
    fastest = max(max(s.speed, s.U_d, *(s.speed_plan[:, 1] if s.speed_plan is not None else [0.0]))
                  for s in scenario.ships)
    reach = fastest * scenario.mpc.config.T
    pad = reach + 0.25 * float(np.max(np.ptp(pts, axis=0))) + 50.0
    return (tuple(pts.min(axis=0) - pad), tuple(pts.max(axis=0) + pad)), reach


log = logging.getLogger(__name__)


class _Progress:
    """Progress of one simulation on stderr: one tick per MPC update (per simulation step when no ship runs
    PSB-MPC), with an ETA taken from the ticks after the first -- the first update compiles the solver, so its
    time says nothing about the rest.  Uses ``tqdm`` when it is installed, else a plain bar: a live line on a
    terminal, four lines (25 %, 50 %, ...) in a log file.  The start, the end of the compiling first update and
    the end go to the module's logger too (INFO), with the bar or without it."""

    def __init__(self, total: int, label: str, enabled: bool, *, unit: str = "MPC updates",
                 first_compiles: bool = True):
        self.total, self.label, self.enabled, self.unit = max(int(total), 1), label, enabled, unit
        self.first_compiles = first_compiles
        self.t0 = time.perf_counter()
        self.t_first: float | None = None  # when the first tick came (the rate is measured from there)
        self.done, self.last_pct, self.last_draw = 0, -1, 0.0
        self.tty = sys.stderr.isatty()
        self.bar = None
        log.info("%s: %d %s%s", label, self.total, unit, "; the first compiles the solver" if first_compiles else "")
        if not enabled:
            return
        try:
            from tqdm import tqdm
        except ImportError:
            tqdm = None
        if tqdm is not None:
            # smoothing 0: the mean rate since the (re)start, as eta(); into a log file (no terminal) a line at
            # most every 10 s instead of ten a second
            self.bar = tqdm(total=self.total, desc=label, unit=unit.split()[-1].rstrip("s") or "it",
                            file=sys.stderr, dynamic_ncols=True, leave=True, smoothing=0.0,
                            mininterval=0.1 if self.tty else 10.0)
            if first_compiles:
                self.bar.set_postfix_str("first update compiles the solver")
        else:
            self._draw(force=True)

    def eta(self) -> float | None:
        """Seconds left, from the mean time per tick after the first (None before two ticks)."""
        if self.done >= self.total:
            return 0.0
        start = 1 if self.first_compiles else 0
        if self.t_first is None or self.done <= start:
            return None
        since = time.perf_counter() - (self.t_first if self.first_compiles else self.t0)
        return since / (self.done - start) * (self.total - self.done)

    def update(self, done: int) -> None:
        """``done`` ticks of ``total`` finished."""
        if done <= self.done:
            return
        if self.t_first is None:
            self.t_first = time.perf_counter()
            if self.first_compiles:
                log.info("%s: first update (compiling) took %.1f s", self.label, self.t_first - self.t0)
        if not self.enabled:
            self.done = min(int(done), self.total)
            return
        prev, self.done = self.done, min(int(done), self.total)
        if self.bar is not None:
            if self.first_compiles and prev == 0:
                # restart tqdm's clock after the compiling update: its rate and ETA cover the later updates
                self.bar.reset(total=self.total)
                self.bar.initial = self.bar.n = self.bar.last_print_n = self.done
                self.bar.set_postfix_str(f"first update {self.t_first - self.t0:.1f} s (compile)", refresh=False)
                self.bar.refresh()
            else:
                self.bar.update(self.done - self.bar.n)
            return
        self._draw()

    def _draw(self, force: bool = False) -> None:
        pct = int(100 * self.done / self.total)
        now = time.perf_counter()
        final = self.done >= self.total
        if self.tty:
            if not (force or final or now - self.last_draw >= 0.1):
                return
        else:
            step = pct // 25 * 25
            if not (force or final) and (step == self.last_pct or step == 0):
                return
            pct = step if not final else 100
        self.last_pct, self.last_draw = (pct // 25 * 25 if not self.tty else pct), now
        bar = "#" * (pct // 4) + "." * (25 - pct // 4)
        el = now - self.t0
        eta = self.eta()
        if self.done == 0 and self.first_compiles:
            tail = "first update compiles the solver"
        elif eta is None:
            tail = "ETA after the next update"
        else:
            tail = f"~{eta:.0f} s left"
        line = f"{self.label} [{bar}] {self.done}/{self.total} {self.unit}  {el:.1f} s elapsed, {tail}"
        sys.stderr.write(("\r" + line + "\x1b[K") if self.tty else line + "\n")
        if self.tty and final:
            sys.stderr.write("\n")
        sys.stderr.flush()

    def close(self) -> None:
        log.info("%s: %d of %d %s in %.1f s", self.label, self.done, self.total, self.unit,
                 time.perf_counter() - self.t0)
        if self.bar is not None:
            self.bar.close()
        elif self.enabled and self.tty and self.done < self.total:
            sys.stderr.write("\n")
            sys.stderr.flush()


# ------------------------------------------------------------------------------------------- simulation
class _ClosedLoop:
    """The state of one :func:`simulate` call, arrays ``[runs, ships, ...]``, and one method per phase of a step
    (measure, plan, move).  Ship 0 is the own-ship."""

    def __init__(self, scenario: Scenario, runs: int, seed: int, mode: str, key, snapshot_run: int,
                 run_start: int = 0, devices: tuple = ()):
        self.sc, self.R, self.snapshot_run = scenario, runs, snapshot_run
        mpc, sensor, config = scenario.mpc, scenario.sensor, scenario.mpc.config
        dt = scenario.dt
        # scenarios built in code skip the loader's checks: the same check again, by the loader's helper
        self.K = multiple_of(scenario.duration, dt, "duration", "the simulation step dt")
        self.mpc_every = multiple_of(mpc.period, dt, "mpc.period", "the simulation step dt")
        self.meas_every = multiple_of(sensor.period, dt, "sensor.period", "the simulation step dt")
        ships = self.ships = scenario.ships
        n, self.n_tg = len(ships), len(ships) - 1
        self.routes_ext, self.n_wp = pad_routes([extend_route(s.waypoints) for s in ships])
        self.lookahead, self.R_a = np.array([s.lookahead for s in ships]), np.array([s.R_a for s in ships])
        self.T_chi, self.T_U = np.array([s.T_chi for s in ships]), np.array([s.T_U for s in ships])
        # ships whose true motion is the 3-DOF manoeuvring model (their full state [R, m, 6] is kept here)
        self.motion3 = [i for i, s in enumerate(ships) if s.motion_model == "3dof"]
        self.params3 = (vessel3dof.stack_params([vessel3dof.preset(ships[i].vessel_model) for i in self.motion3])
                        if self.motion3 else None)

        dtype = np.dtype(config.dtype)
        # which controller runs which ship (the registry); the grid-search methods get the solver's inputs
        split = tuple(devices) if len(devices) > 1 else None        # None: the default device, unsplit
        context = BuildContext(mode=mode, params=params_as_arrays(mpc.params, dtype),
                               samples=standard_normal_table(key, config, dtype), key=key, devices=split)
        self.colav = build_controllers(scenario, context)
        if split is not None:
            _refuse_unsplit(scenario, self.colav, len(split))
        self.colav.init(runs)
        self.controlled = self.colav.controlled
        self.grid, self.grid_bounds = None, None
        region, self.reach = grid_region(scenario, [s.waypoints for s in ships])
        uses_grid = self.colav.uses_grid
        if config.grounding_mode == "grid" and scenario.polygons and uses_grid:
            reach = self.reach
            self.grid = build_distance_grid(scenario.polygons, config.grid_spacing, config.grid_margin, dtype=dtype,
                                            region=region)
            self.grid_bounds = (np.asarray(region[0]) + reach, np.asarray(region[1]) - reach)

        K, R = self.K, runs
        self.t = np.arange(K + 1) * dt
        self.states = np.empty((R, n, K + 1, 4))
        self.states[:, :, 0] = np.array([[s.position[0], s.position[1], s.course, s.speed] for s in ships])
        self.full3 = vessel3dof.from_sim_state(self.states[:, self.motion3, 0]) if self.motion3 else None
        self.seg = np.zeros((R, n), dtype=np.int64)
        self.u_c, self.chi_off = np.ones((R, n)), np.zeros((R, n))
        self.absolute = np.zeros((R, n), bool)          # ships commanded by absolute (U, chi) (two_level)
        self.cmd_U, self.cmd_chi = np.zeros((R, n)), np.zeros((R, n))
        self.run_start = int(run_start)
        self.rngs = [np.random.default_rng([int(seed), run_start + r]) for r in range(R)]
        # route exchange (Akdağ, Fossen & Johansen 2022): the segment of the last plan each run received from each
        # ship (-1: none), the plans published but not yet due (delay), and the dropout draws (their own streams)
        self.received_seg = np.full((R, n), -1, dtype=np.int64)
        self.plan_queue: list[tuple[float, np.ndarray, np.ndarray]] = []
        self.exchange_rngs = [np.random.default_rng([int(seed), run_start + r, 2002]) for r in range(R)]
        R_filter = sensor.filter_R_scale * sensor.position_std ** 2 * np.eye(2)
        self.tracker = TrackerBank((R, self.n_tg), R_filter, sensor.sigma_a, sensor.U_max) if self.n_tg else None
        self.track_x = np.full((R, self.n_tg, K + 1, 4), np.nan)
        self.track_P = np.full((R, self.n_tg, K + 1, 4, 4), np.nan)
        self.solve_steps = list(range(0, K, self.mpc_every))
        M = len(self.solve_steps)
        self.offsets = np.full((R, n, M, 2), np.nan)
        self.best_costs = np.full((R, n, M, len(COST_NAMES)), np.nan)
        self.solve_wall = np.full((R, n, M), np.nan)
        self.colav_info = {name: np.full((R, M), np.nan) for name in INFO_NAMES}
        # per ship: the per-step sequence being followed [R, N, 2], its step [s] and the time of its update
        self.sequences: dict[int, tuple[np.ndarray, float, float]] = {}
        self.calls: list[dict] = []
        self.snapshot: dict | None = None
        self.snap_pending = bool(self.controlled[0]) and self.colav.snapshots
        pos_var, vel_var = sensor.colav_target_cov
        self.true_cov = np.diag([pos_var, pos_var, vel_var, vel_var])

    def observe(self, k: int, keep=None) -> Observation:
        """What the controllers see at step ``k`` (copies: a controller cannot change the simulation); ``keep``:
        the ``(run, ship)`` whose full evaluation is wanted for the snapshot plot."""
        sharing = any(s.shares_route for s in self.ships)
        shared = tuple(tuple((self.shared_route(r, j), self.shared_leg_speeds(r, j))
                             if sharing and self.received_seg[r, j] >= 0 else None
                             for j in range(len(self.ships))) for r in range(self.R))
        return Observation(
            scenario=self.sc, t=float(self.t[k]), states=self.states[:, :, k].copy(),
            tracks=self.track_x[:, :, k].copy(), track_covs=self.track_P[:, :, k].copy(),
            offsets=np.stack([self.u_c, self.chi_off], axis=-1), segments=self.seg.copy(),
            routes=self.routes_ext, route_len=self.n_wp, speeds=self.nominal(k), shared=shared,
            target_cov=self.true_cov, grid=self.grid, keep=keep)

    def measure(self, k: int) -> None:
        """Noisy target positions into the tracks (every sensor period); record the tracks of step ``k``."""
        if self.tracker is None:
            return
        if k % self.meas_every == 0:
            noise = np.stack([g.normal(size=(self.n_tg, 2)) for g in self.rngs])
            self.tracker.measure(self.states[:, 1:, k, :2] + self.sc.sensor.position_std * noise)
        self.track_x[:, :, k], self.track_P[:, :, k] = self.tracker.x, self.tracker.P

    def nominal(self, k: int) -> np.ndarray:
        """Nominal speeds ``[R, n]`` at step ``k``: per active leg for ships with ``leg_speeds``, else the speed
        plan's."""
        out = np.tile(np.array([nominal_speed(s, self.t[k]) for s in self.ships]), (self.R, 1))
        for i, s in enumerate(self.ships):
            if s.leg_speeds is not None:
                out[:, i] = leg_speed(s, self.seg[:, i])
        return out

    def exchange(self, k: int) -> None:
        """Route exchange at an MPC update: every ship with ``shares_route`` publishes its remaining route (its
        active segment) and role; a message is lost with ``mpc.informed.exchange_dropout``; the plans published
        at or before ``t - exchange_delay`` are delivered (the receiver keeps the last one it got)."""
        sharing = np.array([s.shares_route for s in self.ships])
        if not sharing.any():
            return
        inf = self.sc.mpc.informed
        lost = np.stack([g.random(len(self.ships)) < inf.exchange_dropout for g in self.exchange_rngs])
        self.plan_queue.append((float(self.t[k]), self.seg.copy(), sharing[None, :] & ~lost))
        due = float(self.t[k]) - inf.exchange_delay + 1e-9
        while self.plan_queue and self.plan_queue[0][0] <= due:
            _, seg, delivered = self.plan_queue.pop(0)
            self.received_seg = np.where(delivered, seg, self.received_seg)

    def shared_route(self, r: int, j: int):
        """The route ship ``j`` shared with run ``r``'s planners (``[m, 2]`` from its active segment at the time
        of the plan), or None if none was received."""
        z = int(self.received_seg[r, j])
        if z < 0:
            return None
        return self.routes_ext[j, z: max(self.n_wp[j], z + 2)]

    def shared_leg_speeds(self, r: int, j: int):
        """The leg speeds of :meth:`shared_route` (``[m - 1]``), or None (no plan, or no leg speeds)."""
        route, ship = self.shared_route(r, j), self.ships[j]
        if route is None or ship.leg_speeds is None:
            return None
        z = int(self.received_seg[r, j])
        return leg_speed(ship, np.arange(z, z + len(route) - 1))

    def plan(self, k: int) -> None:
        """One MPC update of every ship with collision avoidance in every run (every controller decides on the
        same observation); apply what is due now."""
        self.exchange(k)
        m = k // self.mpc_every
        keep_job = (self.snapshot_run, 0) if self.snap_pending else None
        obs = self.observe(k, keep_job)
        t0 = time.perf_counter()
        decisions = self.colav.decide(obs)
        wall = time.perf_counter() - t0
        n_jobs = sum(len(d.jobs) for d in decisions)
        self.calls.append({"t_s": float(self.t[k]), "solves": n_jobs,
                           "device_calls": int(sum(d.device_calls for d in decisions)), "wall_s": wall})
        kept = None
        for d in decisions:
            for n, (r, i) in enumerate(d.jobs):
                u, c = d.first[n]
                self.u_c[r, i], self.chi_off[r, i] = u, c
                self.offsets[r, i, m] = (u, c)
                self.best_costs[r, i, m] = d.costs[n]
                self.solve_wall[r, i, m] = d.walls[n]
                if i == 0 and d.info is not None:
                    for name in INFO_NAMES:
                        self.colav_info[name][r, m] = d.info[name][n]
            for n, (r, i) in enumerate(d.jobs):        # a NaN row (or no commands): offsets over LOS guidance
                if d.commands is None or not np.all(np.isfinite(d.commands[n])):
                    self.absolute[r, i] = False
                else:
                    self.absolute[r, i] = True
                    self.cmd_U[r, i], self.cmd_chi[r, i] = d.commands[n]
            ships = sorted({i for _, i in d.jobs})
            for i in ships:
                rows = [n for n, (_, s) in enumerate(d.jobs) if s == i]     # one per run, runs in order
                if d.sequences is None:
                    self.sequences.pop(i, None)
                else:
                    assert d.seq_dt is not None     # Decision: sequences come with their step
                    self.sequences[i] = (d.sequences[rows], float(d.seq_dt), float(self.t[k]))
            if d.snapshot is not None:
                kept = d.snapshot
        if kept is not None:
            self._keep_snapshot(kept, k)

    def _apply_sequences(self, k: int) -> None:
        """The row of each ship's per-step sequence that is due at step ``k`` (the last row after its end)."""
        for i, (seq, step, t_update) in self.sequences.items():
            j = min(int(np.floor((self.t[k] - t_update) / step + 1e-9)), seq.shape[1] - 1)
            self.u_c[:, i], self.chi_off[:, i] = seq[:, j, 0], seq[:, j, 1]

    def _keep_snapshot(self, res, k: int) -> None:
        """Keep the snapshot run's own-ship solve in full (``res``: a :class:`~psbmpc_jax.packing.PlanResult`):
        the first one, replaced by the first that manoeuvres."""
        r = self.snapshot_run
        manoeuvring = bool(self.u_c[r, 0] != 1.0 or self.chi_off[r, 0] != 0.0)
        if self.snapshot is None or manoeuvring:
            self.snapshot = {"t_s": float(self.t[k]), "run": r, "best_index": res.best_index,
                             "own_trajectories": res.own_trajectories, "total_cost": res.costs["total"],
                             "obstacle_trajectories": res.obstacle_trajectories, "manoeuvring": manoeuvring}
        self.snap_pending = not manoeuvring

    def move(self, k: int) -> None:
        """True motion from step ``k`` to ``k + 1`` (LOS + offsets; the kinematic model, or the 3-DOF model for
        ships with ``motion_model: 3dof``); tracks predicted along."""
        self._apply_sequences(k)
        chi_los, self.seg = los_course(self.states[:, :, k, :2], self.seg, self.routes_ext, self.n_wp,
                                       self.lookahead, self.R_a)
        U_cmd = np.where(self.absolute, self.cmd_U, self.u_c * self.nominal(k))
        chi_cmd = np.where(self.absolute, self.cmd_chi, chi_los + self.chi_off)
        self.states[:, :, k + 1] = kinematic_step(self.states[:, :, k], chi_cmd, U_cmd, self.T_chi, self.T_U,
                                                  self.sc.dt)
        if self.motion3:
            m = self.motion3
            self.full3 = vessel3dof.step(self.full3, chi_cmd[:, m], U_cmd[:, m], self.sc.dt, self.params3)
            self.states[:, m, k + 1] = vessel3dof.sim_view(self.full3)
        if self.tracker is not None:
            self.tracker.step(self.sc.dt)

    def run(self, progress: bool) -> SimulationResult:
        label = f"{self.sc.name} ({self.R} run{'s' if self.R != 1 else ''})"
        planning = bool(self.colav.controllers)
        bar = (_Progress(len(self.solve_steps), label, progress) if planning
               else _Progress(self.K, label, progress, unit="steps", first_compiles=False))
        try:
            for k in range(self.K + 1):
                self.measure(k)
                if k == self.K:
                    break
                if k % self.mpc_every == 0 and planning:
                    self.plan(k)
                    bar.update(len(self.calls))
                self.move(k)
                if not planning:
                    bar.update(k + 1)
        finally:
            bar.close()
        return SimulationResult(
            scenario=self.sc, t=self.t, states=self.states, track_x=self.track_x, track_P=self.track_P,
            solve_t=self.t[self.solve_steps], offsets=self.offsets, best_costs=self.best_costs, calls=self.calls,
            snapshot=self.snapshot, metrics=[], solve_wall=self.solve_wall, method=self.colav.method,
            colav_info=self.colav_info if self.colav.own is not None and self.colav.own.diagnostics else None,
            run_start=self.run_start)

    def clip_exceeded(self) -> bool | None:
        """Whether a prediction can have reached beyond the land kept by ``chart.clip_m``: true when a ship came
        farther than ``clip_m`` minus one horizon's reach from every route (None without clipping)."""
        clip = self.sc.chart_info.get("clip_m")
        if not clip or not self.sc.polygons:
            return None
        import shapely

        routes = shapely.union_all([route_geometry(s) for s in self.ships])
        xy = self.states[..., :2].reshape(-1, 2)
        far = float(np.max(shapely.distance(routes, shapely.points(xy))))
        return bool(far + self.reach > clip)

    def grid_exceeded(self) -> bool | None:
        """Whether any ship came closer to the grid's edge than one horizon's reach (None without a grid)."""
        if self.grid_bounds is None:
            return None
        xy = self.states[..., :2]
        return bool(np.any(xy < self.grid_bounds[0]) or np.any(xy > self.grid_bounds[1]))


def simulate(scenario: Scenario, *, runs: int | None = None, seed: int | None = None, batch: str = "auto",
             progress: bool = False, snapshot_run: int = 0, key=None, run_start: int = 0,
             devices: int | str = 1) -> SimulationResult:
    """Run ``runs`` Monte Carlo closed-loop simulations of ``scenario`` (default: the scenario's).

    Args:
        runs, seed: override the scenario's Monte Carlo settings.
        batch: ``"vmap"`` (all solves of one MPC update in one device call), ``"loop"`` (one call per solve)
            or ``"auto"`` (``"vmap"`` when ``devices`` > 1).
        devices: local devices to split the vmapped call's batch (every run and ship of an update) over: an
            integer >= 1 (the first that many of ``jax.local_devices()``) or ``"all"``; default 1 (unsplit, the
            default device).  The results equal one device's (:func:`psbmpc_jax.sharding.solve_batch`); only the
            grid-search methods split (ValueError for a scenario with none, or with ``batch="loop"``).
        progress: draw a progress bar on stderr, one tick per MPC update (``tqdm`` if installed).
        snapshot_run: the run whose first manoeuvring own-ship solve is kept in full for plotting.
        key: PRNG key for the ``mc``/``ce`` estimators' samples (required for those; unused by ``quadrature``).
        run_start: the Monte Carlo index of the first run (>= 0, default 0): the call simulates runs
            ``run_start .. run_start + runs - 1`` of the seed, each identical to the same run of one bigger call
            (module docstring); ``snapshot_run`` counts from the first run of the call.
    """
    if not isinstance(scenario, Scenario):
        raise ValueError(f"scenario must be a psbmpc_jax.scenario.Scenario, got {type(scenario).__name__}")
    runs = integer(scenario.runs if runs is None else runs, "runs", ge=1)
    seed = integer(scenario.seed if seed is None else seed, "seed", ge=0)
    run_start = integer(run_start, "run_start", ge=0)
    check_run_size(scenario, runs)                 # a --runs override is held to the memory limit too
    simulation_time.check(scenario, runs, runs_setting="runs")           # ... and to the time limit
    if not 0 <= snapshot_run < runs:
        raise ValueError(f"snapshot_run must be in [0, {runs}), got {snapshot_run}")
    devs = local_devices(devices)
    mode = resolve_batch_mode(batch, len(devs))
    check_dtype(scenario.mpc.config)
    if (runs, seed) != (scenario.runs, scenario.seed):   # the result records the settings as used
        scenario = dataclasses.replace(scenario, runs=runs, seed=seed)
    if scenario.mpc.config.estimator != "quadrature" and key is None:
        raise ValueError(f"estimator {scenario.mpc.config.estimator!r} draws samples: pass key=jax.random.key(...) "
                         "(psbmpc_jax.scenario.estimator_key(scenario) gives the scenario seed's key)")
    if key is not None:
        checks.prng_key(key, "key")
    loop = _ClosedLoop(scenario, runs, seed, mode, key, snapshot_run, run_start, devs)
    result = loop.run(progress)
    result.metrics = [run_metrics(result, r) for r in range(runs)]
    result.summary = summarize(result, mode=mode, grid_exceeded=loop.grid_exceeded(),
                               clip_exceeded=loop.clip_exceeded(), devices=len(devs))
    return result


# ------------------------------------------------------------------------------------------- metrics
def run_metrics(result: SimulationResult, r: int) -> dict:
    """Metrics of run ``r``: :func:`psbmpc_jax.sim.metrics.run_metrics` for the own-ship, plus the minimum
    distance to land of every ship and the minimum distance between every pair of ships (targets that run
    their own PSB-MPC must not collide with each other either)."""
    sc = result.scenario
    states = result.states[r]
    if sc.own_ship.colav == "none":
        own_solves = []
    elif result.solve_wall is not None:      # this run's own-ship solves (measured one by one in the loop)
        own_solves = [float(w) for w in result.solve_wall[r, 0] if np.isfinite(w)]
    else:                                    # a result built without per-solve times: amortised call times
        own_solves = [c["wall_s"] / c["solves"] for c in result.calls]
    out = metrics_mod.run_metrics(
        result.t, states[0], states[1:], sc.own_ship.waypoints, sc.polygons, d_collision=sc.d_collision,
        ground_clearance=0.5 * sc.own_ship.width, solve_times=own_solves or None,
        target_names=[s.name for s in sc.targets], arrival_radius=sc.own_ship.R_a, evaluation=sc.evaluation,
        own_name=sc.own_ship.name, target_routes=[s.waypoints for s in sc.targets],
        target_arrival_radii=[s.R_a for s in sc.targets])
    out["run"] = result.run_start + r
    out["solve_times_s"] = own_solves
    ships = sc.ships
    if sc.polygons:
        # the own-ship's distance is in the metrics already; the targets' are computed here
        land = [out["min_distance_land_m"]] + [float(np.min(metrics_mod.distance_to_land(states[i, :, :2],
                                                                                         sc.polygons)))
                                               for i in range(1, len(ships))]
        out["ships_min_distance_land_m"] = {s.name: d for s, d in zip(ships, land)}
        # a point target (width 0) grounds when it is on land (distance 0)
        out["ships_grounded"] = [s.name for s, d in zip(ships, land) if d < 0.5 * s.width or d <= 0.0]
    pairs, controlled = {}, []
    for i in range(len(ships)):
        for j in range(i + 1, len(ships)):
            d = np.hypot(*(states[i, :, :2] - states[j, :, :2]).T)
            name = f"{ships[i].name}-{ships[j].name}"
            pairs[name] = float(d.min())
            if ships[i].colav != "none" or ships[j].colav != "none":
                controlled.append(name)
    out["pair_min_distance_m"] = pairs
    # a collision counts against the method only if one of the two ships plans; two route-following
    # targets meeting each other is part of the scenario (reported, not counted)
    out["pair_collisions"] = [k for k in controlled if pairs[k] < sc.d_collision]
    out["uncontrolled_pair_collisions"] = [k for k in pairs if k not in controlled and pairs[k] < sc.d_collision]
    return out


def summarize(result: SimulationResult, *, mode: str, grid_exceeded: bool | None,
              clip_exceeded: bool | None = None, devices: int = 1) -> dict:
    """Aggregate over runs (:func:`psbmpc_jax.sim.metrics.aggregate`, less its own-ship ``n_solves``), plus how
    the simulation ran: ``mpc_updates`` (MPC update instants), ``mpc_solves_total`` (solves of every PSB-MPC
    ship in every run: the one count of solves), ``device_calls``, batch mode, device, ``devices`` (how many the
    vmapped batch was split over; 1: unsplit) and timing.  ``solves``
    repeats ``mpc_solves_total`` under its older name (in memory only; metrics.json has the new name)."""
    sc = result.scenario
    summary = metrics_mod.aggregate(result.metrics)
    summary.pop("n_solves", None)       # the own-ship's solves only: the per-run n_solves add up to it
    walls = np.array([c["wall_s"] for c in result.calls]) if result.calls else np.zeros(0)
    per_solve = np.array([c["wall_s"] / c["solves"] for c in result.calls]) if result.calls else np.zeros(0)
    summary.update({
        "scenario": sc.name,
        "method": result.method,
        "runs": len(result.metrics),
        "seed": sc.seed,
        "any_ship_groundings": sum(1 for m in result.metrics if m.get("ships_grounded")),
        "pair_collision_runs": sum(1 for m in result.metrics if m["pair_collisions"]),
        "pair_min_distance_m": {k: float(min(m["pair_min_distance_m"][k] for m in result.metrics))
                                for k in (result.metrics[0]["pair_min_distance_m"] if result.metrics else {})},
        "batch_mode": mode,
        "device": str(jax.devices()[0].device_kind),
        "platform": jax.default_backend(),
        "devices": int(devices),
        "mpc_updates": len(result.calls),
        "device_calls": int(sum(c["device_calls"] for c in result.calls)),
        "mpc_solves_total": int(sum(c["solves"] for c in result.calls)),
        "call_wall_s_median": float(np.median(walls)) if walls.size else None,
        "solve_wall_s_amortised_median": float(np.median(per_solve)) if per_solve.size else None,
        "grid_region_exceeded": grid_exceeded,
        "chart_clip_exceeded": clip_exceeded,
    })
    summary["colav_diagnostics"] = colav_diagnostics(result.colav_info)
    summary["solves"] = summary["mpc_solves_total"]   # older name, kept in memory only (not in metrics.json)
    return summary


def colav_diagnostics(info: dict | None) -> dict | None:
    """Summary of the own-ship's gradient-method diagnostics over all runs and updates (None for ``psbmpc``):
    ``updates`` (own-ship plans), ``used_warm_fraction`` (a warm start was kept instead of the solver's result -- the
    best of the starts: Ψ, a grid behaviour or the previous plan -- because the result was not better or was
    infeasible), ``nonzero_status`` (plans whose status was not 0), ``violation_max``,
    ``iterations_median`` and ``cost_improvement_median`` (warm-start cost minus final cost)."""
    if info is None:
        return None
    used = np.asarray(info["used_warm"], float)
    done = np.isfinite(used)
    if not done.any():
        return {"updates": 0}

    def pick(name):
        return np.asarray(info[name], float)[done]

    improvement = pick("warm_cost") - pick("cost")
    improvement = improvement[np.isfinite(improvement)]
    viol = pick("violation")
    viol = viol[np.isfinite(viol)]
    iters = pick("iterations")
    iters = iters[np.isfinite(iters)]
    return {"updates": int(done.sum()), "used_warm_fraction": float(np.mean(pick("used_warm") > 0)),
            "nonzero_status": int(np.sum(pick("status") != 0)),
            "violation_max": float(viol.max()) if viol.size else None,
            "iterations_median": float(np.median(iters)) if iters.size else None,
            "cost_improvement_median": float(np.median(improvement)) if improvement.size else None}
