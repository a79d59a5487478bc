"""The ``two_level`` controller (Mahipala & Johansen 2023's two-level MPC): one
:class:`~psbmpc_jax.two_level.planner.TwoLevelPlanner` for the scenario, one planner memory per run.

The planner sees the own-ship's true state and the targets through the own-ship's tracks (as the smooth
methods: position, course ``atan2(V_east, V_north)``, speed ``|V|``).  It commands an absolute course and
speed (χ_c = χ_d + χ_m, U_c = U_d·U_m), applied as they are instead of on top of LOS guidance
(``Decision.commands``); the recorded offsets are the SB-MPC's (U_m, χ_m), the per-update diagnostics the
upper level's (cost, violation, status, inner iterations).
"""

from __future__ import annotations

import time

import numpy as np

from ..params import PlannerConfig
from .base import COST_NAMES, INFO_NAMES, Decision, Observation, tracked_targets


def two_level_settings(scenario):
    """:class:`~psbmpc_jax.two_level.planner.TwoLevelSettings` from ``mpc.two_level`` and ``mpc.sbmpc``, and the
    lower level's :class:`~psbmpc_jax.params.PlannerConfig` (``mpc.config`` with ``sbmpc_T_s`` /
    ``sbmpc_dt_s``)."""
    from ..two_level.path_mpc import PathMpcSettings
    from ..two_level.planner import TwoLevelSettings

    spec, own = scenario.mpc.two_level, scenario.own_ship
    path = PathMpcSettings(N_p=spec.N_p, dt=spec.dt, Q=spec.Q, M=spec.M, chi_span=spec.chi_span,
                           U_max=spec.U_max, T_chi=float(own.T_chi), T_U=float(own.T_U), r_os=spec.r_os)
    settings = TwoLevelSettings(
        path=path, corridor_half_width=spec.corridor_half_width, corridor_sample=spec.corridor_sample,
        corridor_radius=spec.corridor_radius, corridor_margin=spec.corridor_margin, circle_margin=spec.circle_margin,
        r_accept=spec.r_accept, beta=spec.beta, d_critical=spec.d_critical, prediction_compare=spec.compare,
        eta1=spec.eta1, eta2=spec.eta2, d_close=spec.d_close, zeta_d_safe=spec.zeta_d_safe,
        zeta_shape=spec.zeta_shape, sbmpc=scenario.mpc.sbmpc, nominal=spec.nominal, plan_stride=spec.plan_stride,
        sbmpc_every=spec.sbmpc_every)
    config: PlannerConfig = scenario.mpc.config
    if spec.sbmpc_T is not None:
        config = config.replace(T=spec.sbmpc_T, dt=spec.sbmpc_dt)
    return settings, config


class TwoLevelController:
    """The own-ship under ``two_level``: every run planned in turn (host loop; each update is one upper-level
    solve and one 39-behaviour grid search)."""

    ships = (0,)
    uses_grid = False
    snapshots = False

    def __init__(self, scenario):
        from ..two_level.planner import TwoLevelPlanner
        from ..two_level.static_obstacles import StaticCircles

        settings, config = two_level_settings(scenario)
        own = scenario.own_ship
        circles = scenario.mpc.two_level.static_obstacles
        self.planner = TwoLevelPlanner(
            np.asarray(own.waypoints, float), scenario.polygons,
            circles=StaticCircles.from_pairs(circles) if circles else None, U_ref=float(own.U_d),
            settings=settings, config=config, length=max(float(own.length), 1e-6), width=max(float(own.width), 1e-6))
        self.states: dict[int, object] = {}

    def init(self, n_runs: int) -> None:
        """Forget every run's planner memory."""
        self.states = {}

    def decide(self, obs: Observation) -> Decision:
        R = obs.n_runs
        states = obs.states[:, 0]                                               # [R, 4] true own-ship state
        targets = tracked_targets(obs.tracks)                                   # [R, I, 4]
        first, commands, walls = np.zeros((R, 2)), np.zeros((R, 2)), np.zeros(R)
        info = {name: np.full(R, np.nan) for name in INFO_NAMES}
        t_all, calls = time.perf_counter(), 0
        for r in range(R):
            t0 = time.perf_counter()
            plan, self.states[r] = self.planner.plan(states[r], targets[r], self.states.get(r))
            calls += 1 if plan.sbmpc is None else 2
            walls[r] = time.perf_counter() - t0
            first[r] = (plan.U_m, plan.chi_m)
            commands[r] = (plan.U_c, plan.chi_c)
            info["cost"][r] = float(plan.path.cost)
            info["violation"][r] = float(plan.path.violation)
            info["status"][r] = float(plan.path.status)
            info["iterations"][r] = float(plan.path.inner)
        wall = time.perf_counter() - t_all
        return Decision(jobs=[(r, 0) for r in range(R)], first=first, costs=np.full((R, len(COST_NAMES)), np.nan),
                        walls=walls, device_calls=calls, wall=wall, info=info, commands=commands)


__all__ = ["TwoLevelController", "two_level_settings"]
