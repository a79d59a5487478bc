"""The Smooth-SBMPC controllers (``smooth_sbmpc``; ``sbmpc_init``, its initialisation stage alone): the own-ship
planned by :class:`psbmpc_jax.smooth.planner.SmoothSBMPCPlanner`, all runs of an update in one ``plan_batch``
call, per-step controls at ``mpc.smooth.dt_s``.

The planner sees the own-ship's true state and the targets through the own-ship's tracks: the Kalman filter's
position, course ``atan2(V_east, V_north)`` and speed ``|V|`` (the experiment runs with tracking noise; the
Smooth-SBMPC paper gives its planner the true target states).
"""

from __future__ import annotations

import logging
import time
from typing import NamedTuple

import jax
import numpy as np

from .base import COST_NAMES, INFO_NAMES, Decision, Observation, tracked_targets
from .grid import consistent_sequences, plan_now

log = logging.getLogger(__name__)


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
    ``mpc.smooth.k_ntp``; the rest Smooth-SBMPC's defaults), the ship model from the own-ship's spec (nominal
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
                                fis_completion=fis.completion, n_y=fis.n_y, chi_d_mode=sm.chi_d_mode,
                                corridor_land_buffer=sm.corridor_land_buffer, corridor_check=sm.corridor_check),
        solver=SolverSettings(**given) if given else None,
        n_starts=sm.n_starts, init_only=mpc.method == "sbmpc_init", dtype=mpc.config.dtype,
        **({"previous_start": True} if sm.previous_start and mpc.method != "sbmpc_init" else {}))


class SmoothController:
    """The own-ship under ``smooth_sbmpc`` / ``sbmpc_init``: one ``plan_batch`` call per update for all runs.
    With ``mpc.smooth.previous_start`` it keeps each run's last kept sequence and hands it, shifted by the
    steps since that update, to the next update as a DOCP start."""

    ships = (0,)
    uses_grid = False
    snapshots = False

    def __init__(self, scenario, planner_cls=None):
        cls = smooth_planner_class() if planner_cls is None else planner_cls
        self.step = float(scenario.mpc.smooth.dt)
        args = smooth_arguments(scenario)
        self.previous_start = bool(args.get("previous_start", False))
        self.true_targets = scenario.mpc.smooth.targets == "true_states"
        self.planner = cls(scenario.polygons, batch="map", **args)
        self.init_only = bool(args["init_only"])
        self.terminal_los = args["settings"].chi_d_mode == "terminal_los"
        self._previous = None                                                  # (t [s], controls [R, N, 2])

    def _shifted_previous(self, t: float):
        if not self.previous_start or self._previous is None:
            return None
        return plan_now(self._previous, t, self.step)

    def init(self, n_runs: int) -> None:
        """Forget the sequences kept for ``previous_start``."""
        self._previous = None

    def decide(self, obs: Observation) -> Decision:
        R = obs.n_runs
        states = obs.states[:, 0]                                               # [R, 4] true own-ship state
        if self.true_targets:                                                   # the paper's: true states
            targets = np.asarray(obs.states[:, 1:], float)                      # [R, I, 4]
        else:
            targets = tracked_targets(obs.tracks)                               # [R, I, 4]
        last = obs.offsets[:, 0]                                                # [R, 2] applied offsets
        route = obs.route(0)                                                    # the route, extended
        t = obs.t
        extra = {"previous": self._shifted_previous(t)} if self.previous_start else {}
        t0 = time.perf_counter()
        plan = self.planner.plan_batch(states, route, targets, last, np.asarray(obs.segments[:, 0]), **extra)
        plan = jax.device_get(plan)
        wall = time.perf_counter() - t0
        first = np.asarray(plan.apply, float).reshape(R, 2)
        controls = np.asarray(plan.controls, float).reshape(R, -1, 2)
        if self.previous_start:
            self._previous = (t, controls)
        frame = np.asarray(plan.route_frame, bool).reshape(R)
        if not self.init_only and self.terminal_los and frame.any():
            log.info("Smooth-SBMPC at t = %g s: %d of %d runs planned in the route frame (the initialisation "
                     "stage's offsets leave the box in the terminal-LOS frame)", t, int(frame.sum()), R)
        info = {name: np.asarray(getattr(plan, name), float).reshape(R) for name in INFO_NAMES}
        return Decision(jobs=[(r, 0) for r in range(R)], first=first,
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
    route_frame: np.ndarray


class SmoothStepPlanner:
    """A reference planner with ``SmoothSBMPCPlanner``'s interface, built on the existing single-situation
    functions :func:`psbmpc_jax.smooth.docp.smooth_sbmpc_step` (``init_only=False``: init stage, corridor, one
    DOCP solve from the warm start, safeguard) and :func:`psbmpc_jax.smooth.init_stage.init_stage`
    (``init_only=True``: the original SB-MPC; its per-step controls are the init stage's offsets).  One device
    call per run, no multi-start (``n_starts`` and ``batch`` are accepted and ignored).  For tests and
    cross-checks: monkeypatch :func:`smooth_planner_class` to return it."""

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
        self.buffered = None if self.init_only else buffered_chart(tuple(polygons), self.settings.corridor_land_buffer,
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
                            cost, np.asarray(f(0.0)), np.asarray(1, np.int32), np.asarray(0, np.int32),
                            np.asarray(0, np.int32), np.asarray(True))
        st = jax.device_get(smooth_sbmpc_step(state0, route, targets, last, self.land, self.buffered,
                                              weights=self.weights, model=self.model, settings=self.settings,
                                              solver=self.solver))
        return StepPlan(np.asarray(st.apply), np.asarray(st.controls), np.asarray(st.init.psi), np.asarray(st.cost),
                        np.asarray(st.warm_cost), np.asarray(st.violation), np.asarray(st.used_warm, np.int32),
                        np.asarray(st.solver.status), np.asarray(st.solver.inner_iterations),
                        np.asarray(st.route_frame))

    def plan_batch(self, states, route, targets, last, segments) -> StepPlan:
        rows = [self.plan(states[r], route, targets[r], last[r], int(segments[r])) for r in range(len(states))]
        return StepPlan(*(np.stack([np.asarray(getattr(p, name)) for p in rows]) for name in StepPlan._fields))


__all__ = ["SmoothController", "SmoothStepPlanner", "StepPlan", "smooth_arguments", "smooth_planner_class"]
