"""The scenario schema: frozen dataclasses in SI units and radians (ships, sensor, MPC settings, the scenario),
and the names and limits the loader checks against."""

from __future__ import annotations
import dataclasses
import pathlib
from dataclasses import dataclass, field
from typing import Any
import numpy as np
from ..evaltool.params import EvalParams
from ..methods.registry import REGISTRY, SECTIONS
from ..params import Params, PlannerConfig

#: The built-in controllers (``mpc.method`` for the own-ship, ``colav`` per ship), as registered in
#: :data:`psbmpc_jax.methods.REGISTRY` (:mod:`psbmpc_jax.methods.builtin`).  A scenario may also name a method
#: registered later, one published through the ``psbmpc_jax.methods`` entry point group, or an import path
#: ``package.module:Name`` (:func:`psbmpc_jax.methods.get_method`).
METHODS = tuple(REGISTRY)


#: Values of a ship's ``colav`` among the built-in ones: no collision avoidance, or a method.
COLAV_MODES = ("none",) + METHODS




#: Built-in methods only the own-ship may run (the Smooth-SBMPC and two-level planners plan ship 0).
OWN_SHIP_ONLY_METHODS = tuple(n for n, m in REGISTRY.items() if m.own_ship_only)


#: The preset a smooth-method file without ``mpc.preset`` gets its defaults from (5 m river vessels).
SMOOTH_DEFAULT_PRESET = "nidelva"


@dataclass(frozen=True)
class ShipSpec:
    """One vessel of a scenario (own-ship or target), SI units, NED frame.

    Attributes:
        name: unique name within the scenario.
        position: initial ``[north, east]`` [m].
        course: initial course over ground [rad].
        speed: initial speed over ground [m/s].
        waypoints: route ``[n >= 2, 2]`` [m] (LOS guidance follows it; after the last waypoint the ship holds
            the last leg's course).
        U_d: nominal (cruise) speed [m/s].
        speed_plan: optional ``[m, 2]`` rows ``(t [s], U_d [m/s])``: from time t on, the nominal speed is U_d
            (piecewise constant; before the first row the nominal speed is ``U_d``).  ``None``: constant.
        length, width: hull size [m].
        T_chi, T_U: autopilot time constants of the true motion [s].
        lookahead, R_a: LOS lookahead distance and waypoint acceptance radius [m].
        colav: ``"none"`` (follows its route) or the method of its collision avoidance (one of :data:`METHODS`;
            the own-ship's is always ``mpc.method``: in the file ``colav: psbmpc`` or no key means "on, with
            ``mpc.method``"; a target runs the method it names, the smooth ones excepted).
        allow_route_over_land: the own-ship's route may cross land on purpose (its controller must avoid it;
            the loader then warns about such legs instead of refusing them).  Targets: always False.
        shares_route: the ship publishes its route and its Rule-18 role to the others every MPC update (route
            exchange, Akdağ, Fossen & Johansen 2022; only ``informed_sbmpc`` planners use it).
        leg_speeds: optional nominal speed per leg of ``waypoints`` [m/s] (``leg_speeds_mps``; after the last
            waypoint the last leg's); shared with the route.  None: ``U_d`` / ``speed_plan``.
        rule18_role: its COLREGS Rule-18 role, one of :data:`RULE18_ROLES` (``pdv``: power-driven, no priority).
        colregs_option: the ship's own COLREGS option (a
            :class:`~psbmpc_jax.methods.colregs_option_settings.ColregsOptionSpec`: its ``colregs_option`` section
            over ``mpc.colregs_option``), or None: ``mpc.colregs_option`` (docs/colregs_option.md).
        stop_remedy: the ship's own stop remedy (its ``stop_remedy`` key, one of
            :data:`~psbmpc_jax.params.STOP_REMEDIES`), or None: ``mpc.config.stop_remedy``
            (:mod:`psbmpc_jax.methods.stop_remedy_settings`).
        motion_model: ``"kinematic"`` (the planner's model with autopilot lags ``T_chi``, ``T_U``) or ``"3dof"``
            (Fossen's manoeuvring model, :mod:`psbmpc_jax.sim.vessel3dof`, preset ``vessel_model``).

    A target with ``length == width == 0`` is a point object (as in the Smooth-SBMPC paper); the own-ship has a hull.
    """

    name: str
    position: np.ndarray
    course: float
    speed: float
    waypoints: np.ndarray
    U_d: float
    speed_plan: np.ndarray | None = None
    length: float = 5.0
    width: float = 3.0
    T_chi: float = 0.92
    T_U: float = 1.44
    lookahead: float = 66.0
    R_a: float = 5.0
    colav: str = "none"
    allow_route_over_land: bool = False
    shares_route: bool = False
    leg_speeds: np.ndarray | None = None
    rule18_role: str = "pdv"
    motion_model: str = "kinematic"
    vessel_model: str | None = None
    colregs_option: Any = None
    stop_remedy: str | None = None

    @property
    def is_point(self) -> bool:
        """A point object (no hull: ``length_m: 0`` and ``width_m: 0``)."""
        return self.length == 0.0 and self.width == 0.0


@dataclass(frozen=True)
class SensorSpec:
    """The own-ship's target tracking (as in Tengesdal, Brekke & Johansen 2020): position measurements and a constant-velocity Kalman filter.

    Attributes:
        position_std: true measurement noise standard deviation per axis [m].
        period: time between measurements [s].
        filter_R_scale: the filter's measurement covariance is ``filter_R_scale * position_std**2 * I``
            (Tengesdal, Brekke & Johansen 2020 use 25: a deliberately conservative tracker).
        sigma_a: process-noise strength of the filter's constant-velocity model [m/s^2].
        U_max: maximum target speed [m/s], sets the initial velocity variance of single-point initiation.
        colav_target_cov: ``[pos_var m^2, vel_var (m/s)^2]`` of the (noise-free) estimates that ships running
            their own PSB-MPC get of the others.
    """

    position_std: float = 5.0
    period: float = 2.5
    filter_R_scale: float = 25.0
    sigma_a: float = 0.5
    U_max: float = 10.0
    colav_target_cov: tuple[float, float] = (1.0, 0.01)


@dataclass(frozen=True)
class MPCSpec:
    """The own-ship's controller and the PSB-MPC tuning every psbmpc ship uses.

    Attributes:
        preset: name in :data:`psbmpc_jax.presets.PRESETS` (for the smooth methods optional in the file:
            :data:`SMOOTH_DEFAULT_PRESET`, used only for defaults and for targets that run PSB-MPC).
        config, params, behaviours: the preset with the file's overrides applied.
        n_ps: prediction scenarios per obstacle (odd).
        period: MPC update period [s] (a multiple of the simulation step).
        method: the own-ship's controller, one of :data:`METHODS` (targets with ``colav: psbmpc`` always run
            plain PSB-MPC).
        sections: the methods' own sections of ``mpc``, key -> settings, each parsed by the method's settings
            module (:data:`psbmpc_jax.methods.registry.SECTIONS`; defaults when not in the file; each is used only
            by the methods it belongs to).  They read as attributes: ``mpc.smooth``, ``mpc.fis``, ``mpc.solver``,
            ``mpc.refine``, ``mpc.sbmpc`` (``sbmpc``, ``psbmpc_2020`` and the lower level of ``two_level``),
            ``mpc.informed``, ``mpc.two_level``.
        given: the keys of the sections the file gives, and ``"params"`` when it gives ``mpc.params`` (the
            others are defaults; a method whose tuning sections are all defaults is checked against the ship it was tuned for,
            :meth:`psbmpc_jax.methods.Method.check_fit`).
        given_params: the ``mpc.params`` keys the file gives (as written; the grid search is checked against its
            preset's design ship unless they include every scale-dependent parameter,
            :data:`psbmpc_jax.design_ship.SCALE_PARAMS`).
    """

    preset: str
    config: PlannerConfig
    params: Params
    behaviours: np.ndarray
    n_ps: int = 5
    period: float = 5.0
    method: str = "psbmpc"
    sections: dict = field(default_factory=dict)
    given: tuple = ()
    given_params: tuple = ()

    def __getattr__(self, name: str):
        """A method's section by its key (the file's, else the section's default)."""
        if name.startswith("__"):
            raise AttributeError(name)
        sections = self.__dict__.get("sections", {})
        if name in sections:
            return sections[name]
        if name in SECTIONS:
            return SECTIONS[name].default()
        raise AttributeError(f"MPCSpec has no attribute or section {name!r} (sections: {', '.join(SECTIONS)})")

    def with_section(self, name: str, **changes) -> "MPCSpec":
        """A copy with the fields ``changes`` of section ``name`` replaced (the section's own validation runs;
        ``ValueError`` for an unknown section, ``TypeError`` for an unknown field)."""
        if name not in SECTIONS:
            raise ValueError(f"MPCSpec has no section {name!r} (sections: {', '.join(SECTIONS)})")
        section = dataclasses.replace(getattr(self, name), **changes)
        return dataclasses.replace(self, sections={**self.sections, name: section})


@dataclass(frozen=True)
class Scenario:
    """A closed-loop scenario, validated.

    Attributes:
        name, description: identification.
        own_ship: the own-ship (index 0 in simulation arrays).
        targets: target ships (indices 1..n).
        polygons: land as ring sets in the scenario's NED frame (``()`` for open water).
        chart_info: where the land came from (source, origin, CRS, RDP epsilon) for reports.
        sensor, mpc: tracking and planner settings.
        dt, duration: simulation step and length [s].
        runs, seed: Monte Carlo runs and the base seed.
        collision_distance: centre-to-centre distance below which two ships collide [m] (default: the
            planner's d_safe).
        source: the file it was loaded from (``None`` if built in code).
        evaluation: the parameters of the COLREGS evaluation of the runs (:mod:`psbmpc_jax.evaltool`; the file's
            ``evaluation`` section: a preset and overrides of :class:`~psbmpc_jax.evaltool.EvalParams` fields).
        overrides: the file's settings its loader replaced, by key: ``{"simulation.duration_s": {"file": 300.0,
            "used": 60.0, "by": "campaign field 'duration_s'"}}`` (``load_scenario(..., duration_s=)``); empty
            when the file's own settings are used.  Recorded in the run's ``metrics.json``.
    """

    name: str
    description: str
    own_ship: ShipSpec
    targets: tuple[ShipSpec, ...]
    sensor: SensorSpec
    mpc: MPCSpec
    polygons: tuple = ()
    chart_info: dict = field(default_factory=dict)
    dt: float = 0.5
    duration: float = 300.0
    runs: int = 20
    seed: int = 0
    collision_distance: float | None = None
    source: str | None = None
    evaluation: EvalParams = field(default_factory=EvalParams)
    overrides: dict = field(default_factory=dict)

    @property
    def ships(self) -> tuple[ShipSpec, ...]:
        return (self.own_ship,) + tuple(self.targets)

    @property
    def d_collision(self) -> float:
        return float(self.mpc.params.d_safe if self.collision_distance is None else self.collision_distance)


#: One knot in m/s (exact: 1 international nautical mile = 1852 m).
KNOT = 1852.0 / 3600.0


#: The folder of the built-in scenario files (package data).
SCENARIO_DIR = pathlib.Path(__file__).resolve().parent.parent / "scenarios"


#: Minimum length of a default (straight) route [m].
DEFAULT_ROUTE_MIN_M = 1000.0


#: Quarter-circle segments of the buffer that ``chart.clip_m`` intersects the land with.
CLIP_QUAD_SEGS = 16


#: Rule-18 roles a ship may declare (``rule18_role``): power-driven (no priority), not under command, restricted
#: in its ability to manoeuvre, constrained by its draught, engaged in fishing, sailing.
RULE18_ROLES = ("pdv", "nuc", "ram", "cbd", "fishing", "sailing")


MOTION_MODELS = ("kinematic", "3dof")


#: The presets of :mod:`psbmpc_jax.sim.vessel3dof` (named here: loading a scenario must not import JAX).
VESSEL_MODELS = ("psv_116m", "small_5m")
