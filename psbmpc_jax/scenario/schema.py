"""The scenario schema: frozen dataclasses in SI units and radians (ships, sensor, MPC settings, the scenario),
and the names and limits the loader checks against."""

from __future__ import annotations
import math
import pathlib
from dataclasses import dataclass, field
import numpy as np
from ..evaltool.params import EvalParams
from ..methods.registry import REGISTRY
from ..methods.sbmpc_family import SbmpcSettings
from ..params import Params, PlannerConfig

#: The built-in controllers (``mpc.method`` for the own-ship, ``colav`` per ship), as registered in
#: :data:`psbmpc_jax.methods.REGISTRY` (:mod:`psbmpc_jax.methods.builtin`).  A scenario may also name a method
#: registered later, one published through the ``psbmpc_jax.methods`` entry point group, or an import path
#: ``package.module:Name`` (:func:`psbmpc_jax.methods.get_method`).
METHODS = tuple(REGISTRY)


#: Values of a ship's ``colav`` among the built-in ones: no collision avoidance, or a method.
COLAV_MODES = ("none",) + METHODS


#: The methods of seed 000 (their own model and tuning; the PSB-MPC preset only supplies defaults).
SMOOTH_METHODS = ("smooth_sbmpc", "sbmpc_init")


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
            exchange, seed 002; only ``informed_sbmpc`` planners use it).
        leg_speeds: optional nominal speed per leg of ``waypoints`` [m/s] (``leg_speeds_mps``; after the last
            waypoint the last leg's); shared with the route.  None: ``U_d`` / ``speed_plan``.
        rule18_role: its COLREGS Rule-18 role, one of :data:`RULE18_ROLES` (``pdv``: power-driven, no priority).
        motion_model: ``"kinematic"`` (the planner's model with autopilot lags ``T_chi``, ``T_U``) or ``"3dof"``
            (Fossen's manoeuvring model, :mod:`psbmpc_jax.sim.vessel3dof`, preset ``vessel_model``).

    A target with ``length == width == 0`` is a point object (seed 000); the own-ship has a hull.
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

    @property
    def is_point(self) -> bool:
        """A point object (no hull: ``length_m: 0`` and ``width_m: 0``)."""
        return self.length == 0.0 and self.width == 0.0


@dataclass(frozen=True)
class SensorSpec:
    """The own-ship's target tracking (seed 004): position measurements and a constant-velocity Kalman filter.

    Attributes:
        position_std: true measurement noise standard deviation per axis [m].
        period: time between measurements [s].
        filter_R_scale: the filter's measurement covariance is ``filter_R_scale * position_std**2 * I``
            (seed 004 uses 25: a deliberately conservative tracker).
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
class SmoothSpec:
    """``mpc.smooth``: Smooth-SBMPC's horizons and corridor (seed 000; defaults SPEC_SEEDS §1.8, the values of
    :class:`psbmpc_jax.smooth.init_stage.SmoothSettings`).  Seconds and metres.

    Attributes:
        T_init, T_mpc: horizons of the initialisation stage and of the DOCP (T_init > T_mpc, multiples of dt).
        dt: T_s, the discretisation step of both stages.
        corridor_half_width: Δd.  domain_radius: r_dom, the ship-domain radius (N_TP and the corridor buffer).
        k_ntp: grounding-penalty weight per lost trajectory point.
        terminal: ``"full"``, ``"position"`` or ``"soft"`` terminal condition of the DOCP.
        n_starts: starts of the DOCP solve (multi-start).
        previous_start: start 1 of the DOCP is the previous update's kept sequence, shifted (needs
            n_starts >= 2; ignored by ``sbmpc_init``, which has no DOCP).
    """

    T_init: float = 60.0
    T_mpc: float = 20.0
    dt: float = 1.0
    corridor_half_width: float = 20.0
    domain_radius: float = 4.0
    k_ntp: float = 1.0
    terminal: str = "full"
    n_starts: int = 4
    previous_start: bool = False


@dataclass(frozen=True)
class FisSpec:
    """``mpc.fis``: the fuzzy COLREGS inference of seed 000 (d_cl, e_cl [m], smooth-max ε, output grid n_y,
    rule-table completion ``"default_false"`` or ``"literal"``)."""

    d_cl: float = 40.0
    e_cl: float = 5.0
    eps: float = 1e-6
    n_y: int = 201
    completion: str = "default_false"


@dataclass(frozen=True)
class SolverSpec:
    """``mpc.solver``: overrides of the gradient solver of the smooth DOCP and of the PSB-MPC refinement
    (:class:`psbmpc_jax.nlp.SolverSettings`: outer / inner iterations, feasibility tolerance, inner method).
    None: the method's own default (the refinement's is deliberately cheap, ``psbmpc_jax.refine.DEFAULT_SOLVER``)."""

    max_outer: int | None = None
    max_inner: int | None = None
    tol: float | None = None
    method: str | None = None

    def given(self) -> dict:
        """The fields the file sets (SolverSettings field name -> value)."""
        return {k: v for k, v in vars(self).items() if v is not None}


@dataclass(frozen=True)
class RefineSpec:
    """``mpc.refine``: the gradient refinement after the PSB-MPC grid search (``psbmpc_refine``): starts,
    horizon [s] (None: the PSB-MPC horizon ``config.T``), the COLREGS term (``"fis"`` or ``"none"``), ``block``:
    how long each refined control is held [s] (``mpc.refine.block_s``, a multiple of ``config.dt``; None: the
    MPC update period, so the refined controls change no faster than the planner re-plans);
    ``fis_e_cl`` / ``fis_n_y``: ``mpc.fis.e_cl_m`` / ``n_y`` when the file gives them (None: the refinement's
    own defaults); ``previous_start``: start 1 is the previous refinement, shifted to now (needs n_starts >= 2;
    default: on whenever n_starts >= 2, docs/refine.md "Closed loop")."""

    n_starts: int = 4
    horizon: float | None = None
    colregs: str = "fis"
    block: float | None = None
    fis_e_cl: float | None = None
    fis_n_y: int | None = None
    previous_start: bool = True


#: Numeric fields of :class:`psbmpc_jax.costs.informed.InformedSbmpcTerm` that ``mpc.informed.term`` may set
#: (listed here: loading a scenario must not import JAX; a test keeps the two in step).
INFORMED_TERM_FIELDS = ("K_coll", "kappa", "rho", "c_dist", "p", "q", "d_close", "K_coll_r18", "kappa_r18", "rho_r18",
                        "c_dist_r18", "p_r18", "q_r18", "d_close_r18", "k", "l", "m", "n", "gamma", "p_g", "q_g",
                        "d_static_safe")


INFORMED_CLASSIFY = ("velocity", "sectors_t0")


@dataclass(frozen=True)
class InformedSpec:
    """``mpc.informed``: Informed SB-MPC (seed 002; ``informed_sbmpc``).

    Attributes:
        route_exchange: planners predict a target that shares its route along that route (False: straight lines
            for every target, the paper's "without route exchange").
        xtd_threshold: the supervisor falls back to a straight line for a target farther than this from its
            shared route [m] (STM 2019: 100 m).
        d_init: the planner is active only while some target is within this range [m]; else it applies (1, 0)
            and forgets its last offsets (SPEC §3.4).
        exchange_delay: age of the plans a planner uses [s] (the latest plan published at or before t − delay).
        exchange_dropout: probability that a published plan is lost (the receiver keeps the last one it got).
        classify: how the COLREGS situations are found: ``"velocity"`` (per predicted time, C-002-3) or
            ``"sectors_t0"`` (Woerner sectors at t₀).
        circular: a circular safety region of radius c_dist instead of the bearing-shaped one (eq. 10).
        term: overrides of the term's numbers (:data:`INFORMED_TERM_FIELDS`, e.g. ``c_dist``, ``rho_r18``).
    """

    route_exchange: bool = True
    xtd_threshold: float = 100.0
    d_init: float = 2000.0
    exchange_delay: float = 0.0
    exchange_dropout: float = 0.0
    classify: str = "velocity"
    circular: bool = False
    term: dict = field(default_factory=dict)


@dataclass(frozen=True)
class TwoLevelSpec:
    """``mpc.two_level``: the two-level MPC of seed 001 (docs/two_level.md; defaults SPEC_SEEDS §2.3-2.4 at
    fjord scale).  SI units and radians inside (the file gives degrees where a key ends in ``_deg``).

    Attributes:
        N_p, dt: the upper level's steps and step [s].  Q, M: its weights of (x, y, χ, U) errors and of the
            (χ_d, U_d) moves.  chi_span: the course box around the leg angle [rad].  U_max: speed bound [m/s].
            r_os: own-ship circle radius [m] (added to every static circle).
        corridor_half_width, corridor_sample, corridor_radius, corridor_margin, circle_margin: Algorithm 1 and
            C-001-8 [m].  r_accept: leg switching radius [m].
        beta, d_critical, compare: the targets' ground-avoiding prediction (eq. 2; β [rad per step]).
        eta1, eta2, d_close, zeta_d_safe, zeta_shape: ζ of eq. (15).
        nominal, plan_stride: the SB-MPC's nominal references (``plan`` / ``hold``).
        sbmpc_every: the SB-MPC solves every this many updates (SPEC §2.4: MPC every 1 s, SB-MPC every 5 s).
        static_obstacles: circles ``((north, east), radius)`` [m].
        sbmpc_T, sbmpc_dt: the lower level's horizon and step [s] (None: ``mpc.config``'s T and dt).
    """

    N_p: int = 30
    dt: float = 1.0
    Q: tuple = (1e-3, 1e-3, 1.0, 1.0)
    M: tuple = (10.0, 1.0)
    chi_span: float = math.pi / 2
    U_max: float = 5.0
    r_os: float = 5.0
    corridor_half_width: float = 50.0
    corridor_sample: float = 5.0
    corridor_radius: float = 500.0
    corridor_margin: float = 7.0
    circle_margin: float = 2.0
    r_accept: float = 20.0
    beta: float = math.radians(5.0)
    d_critical: float = 50.0
    compare: str = "plus"
    eta1: float = 0.25
    eta2: float = 0.01
    d_close: float = 50.0
    zeta_d_safe: float = 50.0
    zeta_shape: str = "printed"
    nominal: str = "hold"
    plan_stride: int = 5
    sbmpc_every: int = 5
    static_obstacles: tuple = ()
    sbmpc_T: float | None = None
    sbmpc_dt: float | None = None


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
        smooth, fis, solver, refine: the settings of the other methods (defaults when not in the file; each
            is used only by the methods it belongs to).
        sbmpc: the settings of ``sbmpc`` and ``psbmpc_2020`` (``mpc.sbmpc``: a preset of
            :data:`psbmpc_jax.methods.SBMPC_PRESETS` with the file's overrides), used by every ship running one
            (and by the lower level of ``two_level``).
        two_level: the settings of ``two_level`` (``mpc.two_level``, :class:`TwoLevelSpec`).
    """

    preset: str
    config: PlannerConfig
    params: Params
    behaviours: np.ndarray
    n_ps: int = 5
    period: float = 5.0
    method: str = "psbmpc"
    smooth: SmoothSpec = field(default_factory=SmoothSpec)
    fis: FisSpec = field(default_factory=FisSpec)
    solver: SolverSpec = field(default_factory=SolverSpec)
    refine: RefineSpec = field(default_factory=RefineSpec)
    sbmpc: SbmpcSettings = field(default_factory=SbmpcSettings)
    informed: InformedSpec = field(default_factory=InformedSpec)
    two_level: TwoLevelSpec = field(default_factory=TwoLevelSpec)


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


#: Upper limits of the method settings (plausibility, like the rest of the file).
MAX_METHOD_STEPS = 10_000      # T_init_s / dt_s, T_mpc_s / dt_s


MAX_STARTS = 64


MAX_SOLVER_ITERATIONS = 100_000


MAX_FIS_NY = 100_001


MAX_SBMPC_INT = 1_000_000      # mpc.sbmpc.n_mc, seed


#: Rule-18 roles a ship may declare (``rule18_role``): power-driven (no priority), not under command, restricted
#: in its ability to manoeuvre, constrained by its draught, engaged in fishing, sailing.
RULE18_ROLES = ("pdv", "nuc", "ram", "cbd", "fishing", "sailing")


MOTION_MODELS = ("kinematic", "3dof")


#: The presets of :mod:`psbmpc_jax.sim.vessel3dof` (named here: loading a scenario must not import JAX).
VESSEL_MODELS = ("psv_116m", "small_5m")
