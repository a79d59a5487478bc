"""Closed-loop scenario files: schema (frozen dataclasses, SI units and radians inside), YAML loading and
validation.

The YAML format is documented in ``docs/scenarios.md``; degrees and knots appear only in the file (with the
unit in the field name) and are converted exactly once, here.

API: :func:`load_scenario` (a ``.yaml``/``.yml`` path or a built-in name), :func:`scenario_from_dict` (a
parsed mapping), :func:`builtin_scenarios` (the names of the files in ``psbmpc_jax/scenarios/``).  Every
problem in a file raises ``ValueError`` naming the key and what is allowed; nothing is clamped or dropped.
"""

from __future__ import annotations

import copy
import dataclasses
import difflib
import math
import numbers
import os
import pathlib
import re
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
import shapely
import shapely.validation
import yaml
from shapely.geometry import LineString, Point, Polygon

from . import scenario_checks as limits
from .charts import BUILTIN_CHARTS, areal_parts, count_vertices, load_chart, lonlat_to_utm, to_ring_sets
from .checks import MAX_SPEED_MPS, integer, multiple_of, show
from .geo import LATLON_MAX_DISTANCE_M, check_latlon, latlon_to_ned
from .evaltool.params import PRESETS as EVAL_PRESETS
from .evaltool.params import EvalParams
from .evaltool.params import scaled_params
from .methods.registry import REGISTRY, get_method
from .methods.sbmpc_family import SBMPC_PRESETS, SbmpcSettings
from .params import Params, PlannerConfig, validate_params
from .situation import MAX_N_PS

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


def _method_name(value, where: str, *, none_ok: bool = False) -> str:
    """``value`` if it names a method (:func:`psbmpc_jax.methods.get_method`; ``"none"`` too when ``none_ok``),
    else ValueError naming ``where`` and what is allowed."""
    if none_ok and value == "none":
        return value
    try:
        get_method(value, where, none_ok=none_ok)
    except (ImportError, TypeError) as exc:
        raise ValueError(str(exc)) from exc
    return value
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


# ====================================================================================================== loading
__all__ = [
    "ShipSpec", "SensorSpec", "MPCSpec", "InformedSpec", "RULE18_ROLES", "MOTION_MODELS", "VESSEL_MODELS",
    "INFORMED_TERM_FIELDS", "TwoLevelSpec", "SmoothSpec", "FisSpec", "SolverSpec", "RefineSpec", "Scenario",
    "COLAV_MODES", "METHODS", "SMOOTH_METHODS", "OWN_SHIP_ONLY_METHODS", "KNOT", "SCENARIO_DIR",
    "scenario_from_dict", "load_scenario", "builtin_scenarios", "estimator_key",
]

#: One knot in m/s (exact: 1 international nautical mile = 1852 m).
KNOT = 1852.0 / 3600.0

#: The folder of the built-in scenario files (package data).
SCENARIO_DIR = pathlib.Path(__file__).resolve().parent / "scenarios"

#: Minimum length of a default (straight) route [m].
DEFAULT_ROUTE_MIN_M = 1000.0

#: Quarter-circle segments of the buffer that ``chart.clip_m`` intersects the land with.
CLIP_QUAD_SEGS = 16


_TOP_KEYS = ("name", "description", "simulation", "monte_carlo", "collision_distance_m", "evaluation", "mpc", "sensor",
             "chart",
             "origin_latlon", "own_ship", "targets")
_TOP_REQUIRED = ("name", "simulation", "mpc", "own_ship")
_SIM_KEYS = ("dt_s", "duration_s")
_MC_KEYS = ("runs", "seed")
_MPC_KEYS = ("preset", "update_period_s", "n_ps", "config", "params", "speed_factors", "course_offsets_deg",
             "method", "smooth", "fis", "solver", "refine", "sbmpc", "informed", "two_level")
_SMOOTH_KEYS = ("T_init_s", "T_mpc_s", "dt_s", "corridor_half_width_m", "domain_radius_m", "k_ntp", "terminal",
                "n_starts", "previous_start")
_FIS_KEYS = ("d_cl_m", "e_cl_m", "eps", "n_y", "completion")
_SOLVER_KEYS = ("max_outer", "max_inner", "tol", "method")
_REFINE_KEYS = ("n_starts", "horizon_s", "colregs", "block_s", "previous_start")
_TERMINALS = ("full", "position", "soft")
_COMPLETIONS = ("default_false", "literal")
_SOLVER_METHODS = ("lbfgs", "adam")
_REFINE_COLREGS = ("fis", "none")
#: Upper limits of the method settings (plausibility, like the rest of the file).
MAX_METHOD_STEPS = 10_000      # T_init_s / dt_s, T_mpc_s / dt_s
MAX_STARTS = 64
MAX_SOLVER_ITERATIONS = 100_000
MAX_FIS_NY = 100_001
MAX_SBMPC_INT = 1_000_000      # mpc.sbmpc.n_mc, seed
_SENSOR_KEYS = ("position_std_m", "period_s", "filter_R_scale", "sigma_a_mps2", "U_max_mps", "U_max_kn",
                "colav_target_cov")
_COV_KEYS = ("position_var_m2", "velocity_var_m2s2")
_CHART_KEYS = ("builtin", "file", "polygons_m", "origin_utm", "rdp_eps_m", "clip_m")
_ORIGIN_KEYS = ("east", "north", "zone")
_LATLON_ORIGIN_KEYS = ("lat", "lon")
_SHIP_KEYS = ("name", "position_m", "position_utm", "position_latlon", "course_deg", "speed_mps", "speed_kn",
              "nominal_speed_mps", "nominal_speed_kn", "waypoints_m", "waypoints_utm", "waypoints_latlon", "speed_plan", "length_m", "width_m", "T_chi_s",
              "T_U_s", "lookahead_m", "R_a_m", "colav", "allow_route_over_land", "shares_route", "rule18_role",
              "motion_model", "vessel_model", "leg_speeds_mps")
_PLAN_KEYS = ("t_s", "speed_mps", "speed_kn")


# ---------------------------------------------------------------------------------------------- primitives
def _mapping(value, where: str) -> dict:
    if not isinstance(value, dict):
        raise ValueError(f"{where} must be a mapping (key: value), got {type(value).__name__} {value!r}"[:300])
    return value


def _check_keys(d: dict, allowed, where: str, required=()) -> None:
    for k in d:
        if k not in allowed:
            close = difflib.get_close_matches(str(k), [str(a) for a in allowed], n=1, cutoff=0.6)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise ValueError(f"unknown key {k!r} in {where}{hint}; allowed keys: {', '.join(allowed)}")
    for k in required:
        if k not in d:
            raise ValueError(f"{where}: missing required key {k!r}")


def _path(where: str, key: str) -> str:
    return f"{where}.{key}" if where else key


def _is_number(v) -> bool:
    return isinstance(v, numbers.Real) and not isinstance(v, bool)


def _number(v, where: str, *, gt=None, ge=None, le=None) -> float:
    """A finite real number (int or float, not bool), optionally bounded; returned as float."""
    if not _is_number(v):
        raise ValueError(f"{where} must be a finite number, got {v!r}"[:300])
    try:
        x = float(v)
    except OverflowError:
        raise ValueError(f"{where} must be a finite number, got an integer with {len(str(abs(int(v))))} digits "
                         f"(too large)") from None
    if not math.isfinite(x):
        raise ValueError(f"{where} must be a finite number, got {v!r}")
    if gt is not None and not x > gt:
        raise ValueError(f"{where} must be > {gt:g}, got {v!r}")
    if ge is not None and not x >= ge:
        raise ValueError(f"{where} must be >= {ge:g}, got {v!r}")
    if le is not None and not x <= le:
        raise ValueError(f"{where} must be <= {le:g}, got {v!r}")
    return x


def _string(v, where: str) -> str:
    if not isinstance(v, str) or not v.strip():
        raise ValueError(f"{where} must be a non-empty string, got {v!r}")
    return v


def _one_of(d: dict, keys, where: str, *, required: bool) -> str | None:
    """The one key of ``keys`` present in ``d`` (unit alternatives such as speed_mps / speed_kn)."""
    present = [k for k in keys if k in d]
    if len(present) > 1:
        raise ValueError(f"{where}: give only one of {' / '.join(keys)}, got {' and '.join(present)}")
    if not present:
        if required:
            raise ValueError(f"{where}: missing required key, one of {' / '.join(keys)}")
        return None
    return present[0]


def _point(v, where: str) -> np.ndarray:
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if not isinstance(v, (list, tuple)) or len(v) != 2:
        raise ValueError(f"{where} must be a pair of numbers [a, b], got {v!r}")
    return np.array([_number(v[0], f"{where}[0]"), _number(v[1], f"{where}[1]")], dtype=float)


def _points(v, where: str, *, min_n: int) -> np.ndarray:
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if not isinstance(v, (list, tuple)) or len(v) < min_n:
        n = len(v) if isinstance(v, (list, tuple)) else type(v).__name__
        raise ValueError(f"{where} must be a list of at least {min_n} points [a, b] (shape [n >= {min_n}, 2]), "
                         f"got {n if isinstance(n, str) else f'{n} points'}: {v!r}"[:300])
    return np.stack([_point(p, f"{where}[{i}]") for i, p in enumerate(v)]).reshape(-1, 2)


def _wrap_deg(deg: float) -> float:
    return (deg + 180.0) % 360.0 - 180.0


def _course_rad(deg: float) -> float:
    """Degrees -> radians in [-pi, pi): wrapped in degrees first (exact for whole degrees), converted once."""
    return math.radians(_wrap_deg(deg))


_AXIS_DIRECTIONS = {0.0: (1.0, 0.0), 90.0: (0.0, 1.0), -90.0: (0.0, -1.0), -180.0: (-1.0, 0.0)}


def _direction(deg: float) -> np.ndarray:
    """Unit vector (north, east) of a course in degrees; exact along the axes (no 1e-16 sine residue)."""
    w = _wrap_deg(deg)
    if w in _AXIS_DIRECTIONS:
        return np.array(_AXIS_DIRECTIONS[w])
    r = math.radians(w)
    return np.array([math.cos(r), math.sin(r)])


def _speed(d: dict, keys, where: str, *, required: bool, gt=None, ge=None):
    """m/s from one of (``*_mps``, ``*_kn``); knots converted exactly once (1 kn = 1852/3600 m/s)."""
    key = _one_of(d, keys, where, required=required)
    if key is None:
        return None
    x = _number(d[key], _path(where, key), gt=gt, ge=ge)
    # x * 1852 is exact for any speed a file holds, so the result is 1852 x / 3600 correctly rounded
    mps = x * 1852.0 / 3600.0 if key.endswith("_kn") else x
    if mps > MAX_SPEED_MPS:
        raise ValueError(f"{_path(where, key)} ({x:g}) is {mps:g} m/s; at most {MAX_SPEED_MPS:g} m/s "
                         f"({MAX_SPEED_MPS * 3600 / 1852:.1f} kn) allowed -- knots given as m/s (use the _kn key), "
                         f"or km/h?")
    return mps


# ---------------------------------------------------------------------------------------------- YAML
_YAML12_FLOAT = re.compile(r"""^(?:[-+]?[0-9][0-9_]*(?:\.[0-9_]*)?[eE][-+]?[0-9]+
                              |[-+]?\.[0-9_]+[eE][-+]?[0-9]+)$""", re.X)


class _Loader(yaml.SafeLoader):
    """Safe YAML loader that refuses duplicate keys (PyYAML keeps the last one silently) and reads YAML 1.2
    floats such as ``1e3`` (YAML 1.1, and so PyYAML, would read them as strings)."""

    def construct_mapping(self, node, deep=False):
        if isinstance(node, yaml.MappingNode):
            self.flatten_mapping(node)
            seen = set()
            for key_node, _ in node.value:
                key = self.construct_object(key_node, deep=deep)
                try:
                    dup = key in seen
                except TypeError:  # unhashable key: let PyYAML report it
                    continue
                if dup:
                    raise ValueError(f"duplicate key {key!r} at line {key_node.start_mark.line + 1}: every key "
                                     f"may appear only once in a mapping")
                seen.add(key)
        return super().construct_mapping(node, deep=deep)


_Loader.add_implicit_resolver("tag:yaml.org,2002:float", _YAML12_FLOAT, list("-+0123456789."))


def _yaml_load(text: str, where: str):
    try:
        return yaml.load(text, Loader=_Loader)  # noqa: S506 -- a SafeLoader subclass
    except yaml.YAMLError as exc:
        raise ValueError(f"{where}: not valid YAML ({exc})") from None
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None


# ---------------------------------------------------------------------------------------------- sections
def _simulation(d) -> tuple[float, float]:
    d = _mapping(d, "simulation")
    _check_keys(d, _SIM_KEYS, "simulation", required=_SIM_KEYS)
    dt = _number(d["dt_s"], "simulation.dt_s", gt=0)
    duration = _number(d["duration_s"], "simulation.duration_s", gt=0, le=limits.MAX_DURATION_S)
    if dt > duration:
        raise ValueError(f"simulation.dt_s ({dt:g}) must be <= simulation.duration_s ({duration:g})")
    if duration / dt > limits.MAX_STEPS * (1 + 1e-9):
        raise ValueError(f"simulation.duration_s / simulation.dt_s = {duration / dt:.6g} steps; at most "
                         f"{limits.MAX_STEPS} allowed (a larger dt_s or a shorter duration_s)")
    multiple_of(duration, dt, "simulation.duration_s", "simulation.dt_s")
    return dt, duration


def _monte_carlo(d) -> tuple[int, int]:
    d = _mapping(d, "monte_carlo")
    _check_keys(d, _MC_KEYS, "monte_carlo")
    runs = integer(d.get("runs", 20), "monte_carlo.runs", ge=1, le=limits.MAX_RUNS)
    seed = integer(d.get("seed", 0), "monte_carlo.seed", ge=0, le=limits.MAX_SEED)
    return runs, seed


def _value_sets(v, where: str, *, lo: float, hi: float) -> tuple[tuple[float, ...], ...]:
    if not isinstance(v, (list, tuple)) or not v:
        raise ValueError(f"{where} must be a non-empty list with one list of values per maneuver, got {v!r}")
    out = []
    for m, s in enumerate(v):
        w = f"{where}[{m}]"
        if not isinstance(s, (list, tuple)) or not s:
            raise ValueError(f"{w} must be a non-empty list of numbers, got {s!r}")
        out.append(tuple(_number(x, f"{w}[{i}]", ge=lo, le=hi) for i, x in enumerate(s)))
    return tuple(out)


def _mpc(d, dt: float) -> MPCSpec:
    from .presets import PRESETS, build_mpc

    d = _mapping(d, "mpc")
    _check_keys(d, _MPC_KEYS, "mpc", required=("update_period_s",))
    method = d.get("method", "psbmpc")
    _method_name(method, "mpc.method")
    if "preset" not in d and method not in SMOOTH_METHODS:
        raise ValueError(f"mpc: missing required key 'preset' (required for mpc.method {method}; optional only "
                         f"for {' / '.join(SMOOTH_METHODS)}, which then take their defaults from "
                         f"{SMOOTH_DEFAULT_PRESET!r})")
    preset = d.get("preset", SMOOTH_DEFAULT_PRESET)
    if not isinstance(preset, str) or preset not in PRESETS:
        raise ValueError(f"mpc.preset must be one of {sorted(PRESETS)}, got {preset!r}")
    period = _number(d["update_period_s"], "mpc.update_period_s", gt=0)
    multiple_of(period, dt, "mpc.update_period_s", "simulation.dt_s")
    smooth = _smooth_spec(d.get("smooth", {}) or {})
    fis = _fis_spec(d.get("fis", {}) or {})
    solver = _solver_spec(d.get("solver", {}) or {})
    if method in SMOOTH_METHODS:
        multiple_of(period, smooth.dt, "mpc.update_period_s",
                    "mpc.smooth.dt_s" if "dt_s" in (d.get("smooth") or {}) else "mpc.smooth.dt_s (default)")
    n_ps = d.get("n_ps", PRESETS[preset].n_ps)
    if isinstance(n_ps, bool) or not isinstance(n_ps, numbers.Integral) or n_ps < 1 or n_ps % 2 == 0:
        raise ValueError(f"mpc.n_ps must be an odd integer >= 1, got {n_ps!r}"[:300])
    if n_ps > MAX_N_PS:
        raise ValueError(f"mpc.n_ps must be an odd integer <= {MAX_N_PS}, got {show(n_ps)}")

    config = dict(_mapping(d.get("config", {}) or {}, "mpc.config"))
    params_in = dict(_mapping(d.get("params", {}) or {}, "mpc.params"))
    params = {}
    for k, v in params_in.items():
        if k == "wind_dir":
            raise ValueError("mpc.params.wind_dir: angles in scenario files are in degrees; use wind_dir_deg "
                             "(direction the wind blows towards, from north, clockwise)")
        if k == "wind_dir_deg":
            params["wind_dir"] = _course_rad(_number(v, "mpc.params.wind_dir_deg"))
        elif k == "t_ts" and _is_number(v) and math.isnan(float(v)):
            params[k] = float("nan")  # nan = T / n_M, the documented default
        else:
            params[k] = _number(v, f"mpc.params.{k}")
    has_s, has_c = "speed_factors" in d, "course_offsets_deg" in d
    if has_s != has_c:
        raise ValueError("mpc.speed_factors and mpc.course_offsets_deg must be given together (one set of each "
                         "per maneuver)")
    speeds = courses = None
    if has_s:
        speeds = _value_sets(d["speed_factors"], "mpc.speed_factors", lo=0.0, hi=1.0)
        courses = _value_sets(d["course_offsets_deg"], "mpc.course_offsets_deg", lo=-180.0, hi=180.0)
        if len(speeds) != len(courses):
            raise ValueError(f"mpc.speed_factors and mpc.course_offsets_deg need one set per maneuver, got "
                             f"{len(speeds)} and {len(courses)} sets")
        if len(speeds) > limits.MAX_MANEUVERS:
            raise ValueError(f"mpc.speed_factors: {len(speeds)} maneuvers; at most {limits.MAX_MANEUVERS} allowed")
        n_b = math.prod(len(a) * len(b) for a, b in zip(speeds, courses))
        if n_b > limits.MAX_BEHAVIOURS:
            raise ValueError(f"mpc.speed_factors x mpc.course_offsets_deg make {n_b} control behaviours (the product "
                             f"of all set sizes); at most {limits.MAX_BEHAVIOURS} allowed")
    for k, v in config.items():
        if isinstance(v, bool) or (isinstance(v, numbers.Integral) and abs(v) > 10 ** 15):
            raise ValueError(f"mpc.config.{k} must be a number or a name, got {v!r}"[:200])
    try:
        cfg, prm, behaviours = build_mpc(preset, config, params, speeds, courses)
        validate_params(prm, cfg, np.shape(behaviours)[1])
    except (ValueError, TypeError, OverflowError) as exc:
        raise ValueError(f"mpc ({preset!r} with the file's overrides): {exc}") from None
    if cfg.dtype == "float64":
        _enable_x64()
    refine = _refine_spec(d.get("refine", {}) or {}, cfg)
    given = d.get("fis") or {}
    refine = dataclasses.replace(refine, fis_e_cl=fis.e_cl if "e_cl_m" in given else None,
                                 fis_n_y=fis.n_y if "n_y" in given else None)
    return MPCSpec(preset=preset, config=cfg, params=prm, behaviours=np.asarray(behaviours, dtype=float),
                   n_ps=int(n_ps), period=period, method=method, smooth=smooth, fis=fis, solver=solver,
                   refine=refine, sbmpc=_sbmpc_spec(d.get("sbmpc", {}) or {}),
                   informed=_informed_spec(d.get("informed", {}) or {}),
                   two_level=_two_level_spec(d.get("two_level", {}) or {}))


_TWO_LEVEL_KEYS = ("N_p", "dt_s", "Q_diag", "M_diag", "chi_span_deg", "U_max_mps", "r_os_m", "corridor", "r_accept_m",
                   "prediction", "zeta", "nominal", "plan_stride", "static_obstacles", "sbmpc_T_s", "sbmpc_dt_s",
                   "sbmpc_every")
_TL_CORRIDOR_KEYS = ("half_width_m", "sample_m", "radius_m", "margin_m", "circle_margin_m")
_TL_PREDICTION_KEYS = ("beta_deg", "d_critical_m", "compare")
_TL_ZETA_KEYS = ("eta1", "eta2", "d_close_m", "d_safe_m", "shape")


def _two_level_spec(d) -> TwoLevelSpec:
    w = "mpc.two_level"
    d = _mapping(d, w)
    _check_keys(d, _TWO_LEVEL_KEYS, w)
    kw: dict = {}
    if "N_p" in d:
        kw["N_p"] = integer(d["N_p"], f"{w}.N_p", ge=1, le=MAX_METHOD_STEPS)
    for key in ("plan_stride", "sbmpc_every"):
        if key in d:
            kw[key] = integer(d[key], f"{w}.{key}", ge=1, le=MAX_METHOD_STEPS)
    for key, name in (("dt_s", "dt"), ("U_max_mps", "U_max"), ("r_accept_m", "r_accept"), ("sbmpc_T_s", "sbmpc_T"),
                      ("sbmpc_dt_s", "sbmpc_dt")):
        if key in d:
            kw[name] = _number(d[key], f"{w}.{key}", gt=0)
    if ("sbmpc_T_s" in d) != ("sbmpc_dt_s" in d):
        raise ValueError(f"{w}.sbmpc_T_s and {w}.sbmpc_dt_s must be given together")
    if "sbmpc_T" in kw:
        multiple_of(kw["sbmpc_T"], kw["sbmpc_dt"], f"{w}.sbmpc_T_s", f"{w}.sbmpc_dt_s")
    if "U_max_mps" in kw and kw["U_max"] > MAX_SPEED_MPS:
        raise ValueError(f"{w}.U_max_mps must be <= {MAX_SPEED_MPS} m/s, got {kw['U_max']}")
    if "r_os_m" in d:
        kw["r_os"] = _number(d["r_os_m"], f"{w}.r_os_m", ge=0)
    if "chi_span_deg" in d:
        v = _number(d["chi_span_deg"], f"{w}.chi_span_deg", gt=0)
        if v >= 180:
            raise ValueError(f"{w}.chi_span_deg must be in (0, 180), got {v:g}")
        kw["chi_span"] = math.radians(v)
    for key, name, n in (("Q_diag", "Q", 4), ("M_diag", "M", 2)):
        if key in d:
            v = d[key]
            if not isinstance(v, (list, tuple)) or len(v) != n:
                raise ValueError(f"{w}.{key} must be a list of {n} weights >= 0, got {v!r}"[:300])
            kw[name] = tuple(_number(x, f"{w}.{key}[{i}]", ge=0) for i, x in enumerate(v))
    if "nominal" in d:
        kw["nominal"] = _choice(d["nominal"], ("plan", "hold"), f"{w}.nominal")
    sub = _mapping(d.get("corridor", {}) or {}, f"{w}.corridor")
    _check_keys(sub, _TL_CORRIDOR_KEYS, f"{w}.corridor")
    for key, name, lo in (("half_width_m", "corridor_half_width", "gt"), ("sample_m", "corridor_sample", "gt"),
                          ("radius_m", "corridor_radius", "gt"), ("margin_m", "corridor_margin", "ge"),
                          ("circle_margin_m", "circle_margin", "ge")):
        if key in sub:
            kw[name] = _number(sub[key], f"{w}.corridor.{key}", **{lo: 0})
    sub = _mapping(d.get("prediction", {}) or {}, f"{w}.prediction")
    _check_keys(sub, _TL_PREDICTION_KEYS, f"{w}.prediction")
    if "beta_deg" in sub:
        v = _number(sub["beta_deg"], f"{w}.prediction.beta_deg", gt=0)
        if v >= 180:
            raise ValueError(f"{w}.prediction.beta_deg must be in (0, 180) degrees per step, got {v:g}")
        kw["beta"] = math.radians(v)
    if "d_critical_m" in sub:
        kw["d_critical"] = _number(sub["d_critical_m"], f"{w}.prediction.d_critical_m", gt=0)
    if "compare" in sub:
        kw["compare"] = _choice(sub["compare"], ("plus", "both"), f"{w}.prediction.compare")
    sub = _mapping(d.get("zeta", {}) or {}, f"{w}.zeta")
    _check_keys(sub, _TL_ZETA_KEYS, f"{w}.zeta")
    for key, name in (("eta1", "eta1"), ("eta2", "eta2"), ("d_safe_m", "zeta_d_safe")):
        if key in sub:
            kw[name] = _number(sub[key], f"{w}.zeta.{key}", ge=0)
    if "d_close_m" in sub:
        kw["d_close"] = _number(sub["d_close_m"], f"{w}.zeta.d_close_m", gt=0)
    if "shape" in sub:
        kw["zeta_shape"] = _choice(sub["shape"], ("printed", "psbmpc"), f"{w}.zeta.shape")
    circles = d.get("static_obstacles", []) or []
    if not isinstance(circles, (list, tuple)):
        raise ValueError(f"{w}.static_obstacles must be a list of {{center_m: [north, east], radius_m: r}}, got "
                         f"{circles!r}"[:300])
    out = []
    for i, c in enumerate(circles):
        where = f"{w}.static_obstacles[{i}]"
        c = _mapping(c, where)
        _check_keys(c, ("center_m", "radius_m"), where, required=("center_m", "radius_m"))
        ctr = c["center_m"]
        if not isinstance(ctr, (list, tuple)) or len(ctr) != 2:
            raise ValueError(f"{where}.center_m must be [north, east] in metres, got {ctr!r}"[:300])
        out.append(((_number(ctr[0], f"{where}.center_m[0]"), _number(ctr[1], f"{where}.center_m[1]")),
                    _number(c["radius_m"], f"{where}.radius_m", gt=0)))
    kw["static_obstacles"] = tuple(out)
    return TwoLevelSpec(**kw)


_INFORMED_KEYS = ("route_exchange", "xtd_threshold_m", "d_init_m", "exchange_delay_s", "exchange_dropout", "classify",
                  "circular", "term")


def _informed_spec(d) -> InformedSpec:
    w = "mpc.informed"
    d = _mapping(d, w)
    _check_keys(d, _INFORMED_KEYS, w)
    kw = {}
    for key in ("route_exchange", "circular"):
        if key in d:
            kw[key] = _bool(d[key], f"{w}.{key}")
    for key, name in (("xtd_threshold_m", "xtd_threshold"), ("d_init_m", "d_init")):
        if key in d:
            kw[name] = _number(d[key], f"{w}.{key}", gt=0)
    if "exchange_delay_s" in d:
        kw["exchange_delay"] = _number(d["exchange_delay_s"], f"{w}.exchange_delay_s", ge=0)
    if "exchange_dropout" in d:
        kw["exchange_dropout"] = _number(d["exchange_dropout"], f"{w}.exchange_dropout", ge=0, le=1)
    if "classify" in d:
        kw["classify"] = _choice(d["classify"], INFORMED_CLASSIFY, f"{w}.classify")
    if "term" in d:
        t = _mapping(d["term"] or {}, f"{w}.term")
        _check_keys(t, INFORMED_TERM_FIELDS, f"{w}.term")
        kw["term"] = {k: _number(v, f"{w}.term.{k}", ge=0) for k, v in t.items()}
    return InformedSpec(**kw)


#: ``mpc.sbmpc`` keys -> :class:`~psbmpc_jax.methods.SbmpcSettings` fields (units in the key where there is one).
_SBMPC_KEYS = {"d_safe_m": "d_safe", "K_coll": "K_coll", "p": "p", "q": "q", "kappa": "kappa", "lambda_T": "lambda_T",
               "d_cl_m": "d_cl",
               "k_U": "k_U", "Delta_U": "Delta_U", "k_chi_port": "k_chi_port", "k_chi_stbd": "k_chi_stbd",
               "Delta_chi_port": "Delta_chi_port", "Delta_chi_stbd": "Delta_chi_stbd", "T_c_s": "T_c",
               "n_mc": "n_mc", "q_P": "q_P", "r_P": "r_P", "V0": "V0", "seed": "seed", "grounding": "grounding"}
_SBMPC_POSITIVE = ("d_safe_m", "d_cl_m", "T_c_s", "r_P", "V0")


def _sbmpc_spec(d) -> SbmpcSettings:
    w = "mpc.sbmpc"
    d = _mapping(d, w)
    _check_keys(d, ("preset",) + tuple(_SBMPC_KEYS), w)
    preset = d.get("preset", "tengesdal2020")
    base = SBMPC_PRESETS.get(preset) if isinstance(preset, str) else None
    if base is None:
        raise ValueError(f"{w}.preset must be one of {', '.join(SBMPC_PRESETS)}, got {show(preset)}")
    kw = {}
    for key, name in _SBMPC_KEYS.items():
        if key not in d or key == "preset":
            continue
        v = d[key]
        if key == "grounding":
            kw[name] = _bool(v, f"{w}.grounding")
        elif key in ("n_mc", "seed"):
            lo = 1 if key == "n_mc" else 0
            kw[name] = integer(v, f"{w}.{key}", ge=lo, le=MAX_SBMPC_INT)
        elif key in _SBMPC_POSITIVE:
            kw[name] = _number(v, f"{w}.{key}", gt=0)
        else:
            kw[name] = _number(v, f"{w}.{key}", ge=0)
    return dataclasses.replace(base, **kw)


def _bool(v, where: str) -> bool:
    """A YAML ``true`` / ``false`` (not 0/1, not a string)."""
    if not isinstance(v, bool):
        raise ValueError(f"{where} must be true or false, got {show(v)}")
    return v


def _choice(v, allowed, where: str) -> str:
    if not isinstance(v, str) or v not in allowed:
        raise ValueError(f"{where} must be one of {', '.join(allowed)}, got {show(v)}")
    return v


def _evaluation(d) -> EvalParams:
    """The ``evaluation`` section: ``preset`` (default ``default``), ``range_scale`` (> 0, multiplies the
    preset's stage radii and CPA ranges, :data:`psbmpc_jax.evaltool.params.RANGE_FIELDS`; default 1) and any
    :class:`EvalParams` field (applied after the scaling)."""
    d = dict(_mapping(d, "evaluation"))
    preset = d.pop("preset", "default")
    if not isinstance(preset, str) or preset not in EVAL_PRESETS:
        raise ValueError(f"evaluation.preset must be one of {', '.join(EVAL_PRESETS)}, got {show(preset)}")
    scale = _number(d.pop("range_scale"), "evaluation.range_scale", gt=0, le=1000) if "range_scale" in d else 1.0
    names = [f.name for f in dataclasses.fields(EvalParams)]
    for k in d:
        if k not in names:
            raise ValueError(f"unknown key {k!r} in evaluation; allowed: preset, range_scale, {', '.join(names)}")
    try:
        return scaled_params(preset, scale, **d)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"evaluation: {exc}") from None


def _colav(value, own: bool, method: str, where: str) -> str:
    """A ship's method: ``"none"`` or a method name (:func:`_method_name`).  The own-ship's is ``mpc.method``
    (``psbmpc``, the historic "on", or the same name as ``mpc.method``); a target's is the name it gives (not a
    method that plans the own-ship only)."""
    _method_name(value, f"{where}.colav", none_ok=True)
    if value == "none":
        return value
    if own:
        if value not in ("psbmpc", method):
            raise ValueError(f"{where}.colav: the own-ship runs mpc.method ({method}), got colav {value!r}; set "
                             f"mpc.method: {value} (or colav: psbmpc, which means 'on, with mpc.method')")
        return method
    if get_method(value).own_ship_only:
        targets_ok = [n for n, m in REGISTRY.items() if not m.own_ship_only]
        raise ValueError(f"{where}.colav: {value} plans the own-ship only; a target may run "
                         f"{', '.join(targets_ok)}, another method that plans targets, or none")
    return value


def _smooth_spec(d) -> SmoothSpec:
    w = "mpc.smooth"
    d = _mapping(d, w)
    _check_keys(d, _SMOOTH_KEYS, w)
    kw = {}
    for key, name in (("T_init_s", "T_init"), ("T_mpc_s", "T_mpc"), ("dt_s", "dt"),
                      ("corridor_half_width_m", "corridor_half_width")):
        if key in d:
            kw[name] = _number(d[key], f"{w}.{key}", gt=0)
    if "domain_radius_m" in d:
        kw["domain_radius"] = _number(d["domain_radius_m"], f"{w}.domain_radius_m", ge=0)
    if "k_ntp" in d:
        kw["k_ntp"] = _number(d["k_ntp"], f"{w}.k_ntp", ge=0)
    if "terminal" in d:
        kw["terminal"] = _choice(d["terminal"], _TERMINALS, f"{w}.terminal")
    if "n_starts" in d:
        kw["n_starts"] = integer(d["n_starts"], f"{w}.n_starts", ge=1, le=MAX_STARTS)
    if "previous_start" in d:
        kw["previous_start"] = _bool(d["previous_start"], f"{w}.previous_start")
    spec = SmoothSpec(**kw)
    if spec.previous_start and spec.n_starts < 2:
        raise ValueError(f"{w}.previous_start needs {w}.n_starts >= 2 (start 0 is always the trajectory Ψ), "
                         f"got n_starts {spec.n_starts}")
    for key, name in (("T_init_s", "T_init"), ("T_mpc_s", "T_mpc")):
        given = f"{w}.{key}" + ("" if key in d else " (default)")
        n = multiple_of(getattr(spec, name), spec.dt, given, f"{w}.dt_s" + ("" if "dt_s" in d else " (default)"))
        if n > MAX_METHOD_STEPS:
            raise ValueError(f"{given} / {w}.dt_s = {n} steps; at most {MAX_METHOD_STEPS} allowed")
    if not spec.T_init > spec.T_mpc:
        raise ValueError(f"{w}.T_init_s ({spec.T_init:g}) must be > {w}.T_mpc_s ({spec.T_mpc:g}): the DOCP's "
                         f"terminal state is taken from the initialisation stage's trajectory")
    return spec


def _fis_spec(d) -> FisSpec:
    w = "mpc.fis"
    d = _mapping(d, w)
    _check_keys(d, _FIS_KEYS, w)
    kw = {}
    if "d_cl_m" in d:
        kw["d_cl"] = _number(d["d_cl_m"], f"{w}.d_cl_m", gt=0)
    if "e_cl_m" in d:
        kw["e_cl"] = _number(d["e_cl_m"], f"{w}.e_cl_m", gt=0)
    if "eps" in d:
        kw["eps"] = _number(d["eps"], f"{w}.eps", gt=0)
    if "n_y" in d:
        kw["n_y"] = integer(d["n_y"], f"{w}.n_y", ge=2, le=MAX_FIS_NY)
    if "completion" in d:
        kw["completion"] = _choice(d["completion"], _COMPLETIONS, f"{w}.completion")
    return FisSpec(**kw)


def _solver_spec(d) -> SolverSpec:
    w = "mpc.solver"
    d = _mapping(d, w)
    _check_keys(d, _SOLVER_KEYS, w)
    kw = {}
    for key in ("max_outer", "max_inner"):
        if key in d:
            kw[key] = integer(d[key], f"{w}.{key}", ge=1, le=MAX_SOLVER_ITERATIONS)
    if "tol" in d:
        kw["tol"] = _number(d["tol"], f"{w}.tol", gt=0)
    if "method" in d:
        kw["method"] = _choice(d["method"], _SOLVER_METHODS, f"{w}.method")
    return SolverSpec(**kw)


def _refine_spec(d, config: PlannerConfig) -> RefineSpec:
    w = "mpc.refine"
    d = _mapping(d, w)
    _check_keys(d, _REFINE_KEYS, w)
    kw = {}
    if "n_starts" in d:
        kw["n_starts"] = integer(d["n_starts"], f"{w}.n_starts", ge=1, le=MAX_STARTS)
    if "horizon_s" in d:
        h = _number(d["horizon_s"], f"{w}.horizon_s", gt=0)
        if h > config.T * (1 + 1e-9):
            raise ValueError(f"{w}.horizon_s ({h:g}) must be <= the PSB-MPC horizon mpc.config T ({config.T:g}); "
                             f"leave it out for the whole horizon")
        multiple_of(h, config.dt, f"{w}.horizon_s", "the PSB-MPC step mpc.config dt")
        kw["horizon"] = h
    if "colregs" in d:
        kw["colregs"] = _choice(d["colregs"], _REFINE_COLREGS, f"{w}.colregs")
    if "block_s" in d:
        b = _number(d["block_s"], f"{w}.block_s", gt=0)
        limit = kw.get("horizon", config.T)
        if b > limit * (1 + 1e-9):
            raise ValueError(f"{w}.block_s ({b:g}) must be <= the refined horizon ({limit:g} s)")
        multiple_of(b, config.dt, f"{w}.block_s", "the PSB-MPC step mpc.config dt")
        kw["block"] = b
    n_starts = kw.get("n_starts", RefineSpec.n_starts)
    if "previous_start" in d:
        kw["previous_start"] = _bool(d["previous_start"], f"{w}.previous_start")
        if kw["previous_start"] and n_starts < 2:
            raise ValueError(f"{w}.previous_start needs {w}.n_starts >= 2 (start 0 is the grid's choice), got "
                             f"n_starts {n_starts}")
    else:
        kw["previous_start"] = n_starts >= 2          # the default: on whenever there is a second start
    return RefineSpec(**kw)


def _enable_x64() -> None:
    """``mpc.config.dtype: float64`` needs 64-bit JAX: switch it on now, before any array is built (a process-wide
    JAX setting; arrays created before keep their dtype)."""
    import jax

    if not jax.config.jax_enable_x64:
        jax.config.update("jax_enable_x64", True)


def _sensor(d, dt: float) -> SensorSpec:
    d = _mapping(d, "sensor")
    _check_keys(d, _SENSOR_KEYS, "sensor")
    base = SensorSpec()
    kw = {}
    if "position_std_m" in d:
        kw["position_std"] = _number(d["position_std_m"], "sensor.position_std_m", gt=0)
    if "period_s" in d:
        kw["period"] = _number(d["period_s"], "sensor.period_s", gt=0)
    multiple_of(kw.get("period", base.period), dt,
                "sensor.period_s" if "period" in kw else "sensor.period_s (not given: the default)", "simulation.dt_s")
    if "filter_R_scale" in d:
        kw["filter_R_scale"] = _number(d["filter_R_scale"], "sensor.filter_R_scale", ge=1)
    if "sigma_a_mps2" in d:
        kw["sigma_a"] = _number(d["sigma_a_mps2"], "sensor.sigma_a_mps2", ge=0)
    u_max = _speed(d, ("U_max_mps", "U_max_kn"), "sensor", required=False, gt=0)
    if u_max is not None:
        kw["U_max"] = u_max
    if "colav_target_cov" in d:
        c = _mapping(d["colav_target_cov"], "sensor.colav_target_cov")
        _check_keys(c, _COV_KEYS, "sensor.colav_target_cov")
        pv = _number(c.get("position_var_m2", base.colav_target_cov[0]), "sensor.colav_target_cov.position_var_m2",
                     gt=0)
        vv = _number(c.get("velocity_var_m2s2", base.colav_target_cov[1]),
                     "sensor.colav_target_cov.velocity_var_m2s2", gt=0)
        kw["colav_target_cov"] = (pv, vv)
    return SensorSpec(**kw)


# ---------------------------------------------------------------------------------------------- charts
@lru_cache(maxsize=8)
def _builtin_chart(name: str, origin, zone):
    return load_chart(name, origin, zone=zone)


def _inline_polygons(v) -> list[Polygon]:
    where = "chart.polygons_m"
    if not isinstance(v, (list, tuple)) or not v:
        raise ValueError(f"{where} must be a non-empty list of polygons, each a list of >= 3 points [north, east]")
    out = []
    for j, ring in enumerate(v):
        w = f"{where}[{j}]"
        pts = _points(ring, w, min_n=3)
        if len(pts) > 3 and np.array_equal(pts[0], pts[-1]):
            pts = pts[:-1]  # an explicitly closed ring: the closing point repeats the first one
        same = np.flatnonzero(np.all(pts == np.roll(pts, -1, axis=0), axis=1))
        if same.size:
            raise ValueError(f"{w}: vertex {int(same[0])} repeats the next one; a polygon needs distinct "
                             f"consecutive vertices")
        if len(pts) < 3:
            raise ValueError(f"{w}: a polygon needs at least 3 distinct vertices, got {len(pts)}")
        poly = Polygon(pts)
        if not poly.is_valid or poly.area <= 0.0:
            why = shapely.validation.explain_validity(poly) if not poly.is_valid else "zero area"
            raise ValueError(f"{w} is not a valid simple polygon ({why}); give one non-self-intersecting exterior "
                             f"ring with non-zero area")
        out.append(poly)
    return out


def _origin_latlon(d) -> tuple[float, float]:
    o = _mapping(d, "origin_latlon")
    _check_keys(o, _LATLON_ORIGIN_KEYS, "origin_latlon", required=_LATLON_ORIGIN_KEYS)
    return check_latlon(_number(o["lat"], "origin_latlon.lat"), _number(o["lon"], "origin_latlon.lon"),
                        "origin_latlon [lat, lon]")


def _chart_source(d, base_dir, origin_ll=None):
    """-> (Chart or None, inline polygons or None, info dict, settings) before ships are known."""
    d = _mapping(d, "chart")
    _check_keys(d, _CHART_KEYS, "chart")
    sources = [k for k in ("builtin", "file", "polygons_m") if k in d]
    if len(sources) != 1:
        raise ValueError(f"chart needs exactly one land source of builtin / file / polygons_m, got "
                         f"{sources or 'none'} (leave the chart section out for open water)")
    src = sources[0]
    rdp_eps = _number(d["rdp_eps_m"], "chart.rdp_eps_m", gt=0) if "rdp_eps_m" in d else None
    clip = _number(d["clip_m"], "chart.clip_m", gt=0) if "clip_m" in d else None
    if src == "polygons_m":
        for k in ("origin_utm", "rdp_eps_m"):
            if k in d:
                raise ValueError(f"chart.{k} applies only to builtin / file charts, not to chart.polygons_m "
                                 f"(inline polygons are already in local NED metres)")
        polys = _inline_polygons(d["polygons_m"])
        info = dict(source="inline chart.polygons_m", origin=None, crs=None)
        return None, polys, info, rdp_eps, clip
    origin = zone = None
    if "origin_utm" in d and origin_ll is not None:
        raise ValueError("give the origin once: chart.origin_utm or origin_latlon, not both")
    if "origin_utm" in d:
        o = _mapping(d["origin_utm"], "chart.origin_utm")
        _check_keys(o, _ORIGIN_KEYS, "chart.origin_utm", required=("east", "north"))
        origin = (_number(o["east"], "chart.origin_utm.east"), _number(o["north"], "chart.origin_utm.north"))
        if "zone" in o:
            zone = o["zone"]
            if isinstance(zone, bool) or not isinstance(zone, numbers.Integral) or not 1 <= zone <= 60:
                raise ValueError(f"chart.origin_utm.zone must be a UTM zone, an integer in 1..60, got {zone!r}")
            zone = int(zone)
    if src == "builtin":
        name = d["builtin"]
        if not isinstance(name, str) or name.lower() not in BUILTIN_CHARTS:
            raise ValueError(f"chart.builtin must be one of {list(BUILTIN_CHARTS)}, got {name!r}")
        try:
            chart = _builtin_chart(name.lower(), origin, zone)
        except ValueError as exc:
            raise ValueError(f"chart.builtin {name!r}: {exc}") from None
        source = f"builtin:{name.lower()} ({chart.source})"
    else:
        f = d["file"]
        if not isinstance(f, str) or not f.strip():
            raise ValueError(f"chart.file must be a path (relative to the scenario file), got {f!r}")
        p = pathlib.Path(f).expanduser()
        if not p.is_absolute():
            p = pathlib.Path(base_dir if base_dir is not None else ".") / p
        if not p.exists() and not p.with_suffix(".shp").exists():
            raise ValueError(f"chart.file {f!r}: not found ({p}); the path is relative to the scenario file's "
                             f"folder")
        try:
            chart = load_chart(p, origin, zone=zone)
        except (ValueError, FileNotFoundError) as exc:
            raise ValueError(f"chart.file {f!r}: {exc}") from None
        source = str(p)
    if origin_ll is not None:  # the geographic origin, projected to the chart's UTM zone
        info_crs = chart.crs_info
        e, n = lonlat_to_utm(origin_ll[1], origin_ll[0], chart.zone, south=info_crs.south, datum=info_crs.datum)
        chart = chart.with_origin((float(e), float(n)))
        _check_chart_near_origin(chart, "origin_latlon")
    info = dict(source=source, origin=tuple(chart.origin), crs=chart.crs)
    return chart, None, info, rdp_eps, clip


def _check_chart_near_origin(chart, what: str) -> None:
    from .charts import MAX_ORIGIN_DISTANCE_M

    if not chart.polygons:
        return
    b = np.array(shapely.total_bounds(np.array(chart.polygons, dtype=object)))   # (n_min, e_min, n_max, e_max)
    d = float(np.hypot(*np.maximum(0.0, np.maximum(b[:2], -b[2:]))))
    if d > MAX_ORIGIN_DISTANCE_M:
        raise ValueError(f"{what}: the chart lies {d / 1000:.0f} km from this origin; at most "
                         f"{MAX_ORIGIN_DISTANCE_M / 1000:.0f} km allowed -- origin_latlon is {{lat, lon}} in degrees; "
                         f"check the chart's CRS and coordinate order")


def route_geometry(ship: ShipSpec):
    """The ship's start and route as one shapely geometry (what ``chart.clip_m`` buffers)."""
    pts = np.vstack([ship.position[None, :], ship.waypoints])
    keep = np.r_[True, np.any(pts[1:] != pts[:-1], axis=1)]
    pts = pts[keep]
    return Point(pts[0]) if len(pts) == 1 else LineString(pts)


def _clip(polys: list[Polygon], ships, clip_m: float) -> tuple[list[Polygon], dict]:
    """Keep the land within ``clip_m`` of every ship's start and route (shapely buffer, CLIP_QUAD_SEGS)."""
    region = shapely.union_all([route_geometry(s).buffer(clip_m, quad_segs=CLIP_QUAD_SEGS) for s in ships])
    shapely.prepare(region)
    out, removed, clipped, dropped = [], 0, 0, 0
    for p in polys:
        if not region.intersects(p):
            removed += 1
            continue
        if region.contains(p):
            out.append(p)
            continue
        parts, k = areal_parts(p.intersection(region))
        clipped += 1
        dropped += k
        if not parts:
            removed += 1
        out += parts
    return out, dict(clip_removed=removed, clip_clipped=clipped, clip_dropped_parts=dropped)


# ---------------------------------------------------------------------------------------------- ships
def _ship(d, where: str, *, own: bool, ctx: dict) -> ShipSpec:
    d = _mapping(d, where)
    _check_keys(d, _SHIP_KEYS, where, required=("name", "course_deg"))
    name = _string(d["name"], f"{where}.name")
    chart = ctx["chart"]

    def utm_allowed(key):
        if chart is None:
            raise ValueError(f"{where}.{key}: UTM coordinates need a builtin or file chart (its origin converts "
                             f"them to local NED); use {key.replace('_utm', '_m')} [north, east] instead")

    def from_latlon(ll: np.ndarray, key: str) -> np.ndarray:
        """[n, 2] (lat, lon) degrees -> [n, 2] NED (the chart's UTM zone, or the local TM about origin_latlon)."""
        for k, (la, lo) in enumerate(ll):
            check_latlon(la, lo, f"{where}.{key}" + (f"[{k}]" if key.startswith("waypoints") else ""))
        if chart is not None:
            ci = chart.crs_info
            e, n = lonlat_to_utm(ll[:, 1], ll[:, 0], chart.zone, south=ci.south, datum=ci.datum)
            return chart.utm_to_local(np.stack([e, n], axis=-1))
        o = ctx["origin_latlon"]
        if o is None:
            raise ValueError(f"{where}.{key}: lat/lon positions need origin_latlon {{lat, lon}} (the geographic "
                             f"position of the NED origin) or a builtin / file chart")
        ned = latlon_to_ned(ll[:, 0], ll[:, 1], o[0], o[1])
        far = np.hypot(ned[:, 0], ned[:, 1])
        if far.max() > LATLON_MAX_DISTANCE_M:
            k = int(np.argmax(far))
            raise ValueError(f"{where}.{key}: [{ll[k, 0]:g}, {ll[k, 1]:g}] lies {far[k] / 1000:.0f} km from "
                             f"origin_latlon; at most {LATLON_MAX_DISTANCE_M / 1000:.0f} km allowed (local projection) "
                             f"-- positions are [lat, lon], not [lon, lat]")
        return ned

    def near_origin(pts: np.ndarray, key: str) -> None:
        dist = np.hypot(pts[..., 0], pts[..., 1]).reshape(-1)
        if dist.max() > limits.MAX_POSITION_M:
            k = int(np.argmax(dist))
            hint = {"_utm": "UTM is [east, north] in the chart's zone", "_latlon": "positions are [lat, lon]",
                    "_m": "local metres [north, east] about the origin"}[key[key.rindex("_"):]]
            raise ValueError(f"{where}.{key}" + (f"[{k}]" if pts.ndim == 2 else "") + f" lies {dist[k] / 1000:.0f} "
                             f"km from the scenario's origin; at most {limits.MAX_POSITION_M / 1000:.0f} km allowed -- "
                             f"{hint}")

    pkey = _one_of(d, ("position_m", "position_utm", "position_latlon"), where, required=True)
    pos = _point(d[pkey], f"{where}.{pkey}")
    if pkey == "position_utm":
        utm_allowed(pkey)
        pos = chart.utm_to_local(pos)
    elif pkey == "position_latlon":
        pos = from_latlon(pos[None, :], pkey)[0]
    near_origin(pos, pkey)
    course_deg = _number(d["course_deg"], f"{where}.course_deg")
    course = _course_rad(course_deg)
    speed = _speed(d, ("speed_mps", "speed_kn"), where, required=True, ge=0)
    U_d = _speed(d, ("nominal_speed_mps", "nominal_speed_kn"), where, required=False, ge=0)
    U_d = speed if U_d is None else U_d

    colav = _colav(d.get("colav", "psbmpc" if own else "none"), own, ctx.get("method", "psbmpc"), where)
    if colav != "none" and not U_d > 0:
        raise ValueError(f"{where}: a ship with colav {colav} needs a nominal speed > 0 (nominal_speed_mps, "
                         f"default the initial speed), got {U_d:g} m/s")
    over_land = _bool(d.get("allow_route_over_land", False), f"{where}.allow_route_over_land")
    if over_land and not own:
        raise ValueError(f"{where}.allow_route_over_land: allowed only for the own-ship (its controller avoids the "
                         f"land; a target follows its route and would sail through it)")
    method = ctx.get("method", "psbmpc")
    if own and colav in SMOOTH_METHODS and "speed_plan" in d:
        raise ValueError(f"{where}.speed_plan: not supported with mpc.method {method} (the Smooth-SBMPC model has "
                         f"one nominal speed, nominal_speed_mps); leave it out or use another method")

    plan = None
    if "speed_plan" in d:
        sp = d["speed_plan"]
        if isinstance(sp, (list, tuple)) and len(sp) > limits.MAX_WAYPOINTS:
            raise ValueError(f"{where}.speed_plan: {len(sp)} entries; at most {limits.MAX_WAYPOINTS} allowed")
        if not isinstance(sp, (list, tuple)) or not sp:
            raise ValueError(f"{where}.speed_plan must be a non-empty list of {{t_s, speed_mps | speed_kn}} "
                             f"(leave it out for a constant nominal speed), got {sp!r}")
        rows = []
        for i, e in enumerate(sp):
            w = f"{where}.speed_plan[{i}]"
            e = _mapping(e, w)
            _check_keys(e, _PLAN_KEYS, w, required=("t_s",))
            t = _number(e["t_s"], f"{w}.t_s", ge=0)
            if t >= ctx["duration"]:
                raise ValueError(f"{w}.t_s ({t:g}) must be < simulation.duration_s ({ctx['duration']:g}); a "
                                 f"later entry would never apply")
            if rows and not t > rows[-1][0]:
                raise ValueError(f"{w}.t_s ({t:g}) must be greater than the previous entry's ({rows[-1][0]:g}); "
                                 f"speed_plan times must increase strictly")
            rows.append((t, _speed(e, ("speed_mps", "speed_kn"), w, required=True, ge=0)))
        plan = np.array(rows, dtype=float)

    wkey = _one_of(d, ("waypoints_m", "waypoints_utm", "waypoints_latlon"), where, required=False)
    if wkey is None:
        U_max = max([speed, U_d] + ([] if plan is None else list(plan[:, 1])))
        length = max(2.0 * U_max * ctx["duration"], DEFAULT_ROUTE_MIN_M)
        wps = np.stack([pos, pos + length * _direction(course_deg)])
    else:
        if isinstance(d[wkey], (list, tuple)) and len(d[wkey]) > limits.MAX_WAYPOINTS:
            raise ValueError(f"{where}.{wkey}: {len(d[wkey])} waypoints; at most {limits.MAX_WAYPOINTS} allowed")
        wps = _points(d[wkey], f"{where}.{wkey}", min_n=1)
        if wkey == "waypoints_utm":
            utm_allowed(wkey)
            wps = chart.utm_to_local(wps)
        elif wkey == "waypoints_latlon":
            wps = from_latlon(wps, wkey)
        near_origin(wps, wkey)
        if len(wps) == 1:
            wps = np.vstack([pos[None, :], wps])
        same = np.flatnonzero(np.all(wps[1:] == wps[:-1], axis=1))
        if same.size:
            k = int(same[0])
            raise ValueError(f"{where}.{wkey}: route points {k} and {k + 1} coincide ({wps[k].tolist()}); a route "
                             f"needs distinct consecutive points (with one point given, the start position is "
                             f"prepended)")

    prm = ctx["params"]
    pre = "os_" if own else "ob_"

    def opt(key, default, **bounds):
        return _number(d[key], f"{where}.{key}", **bounds) if key in d else float(default)

    def size(key, default, le):
        if own or key not in d:       # the own-ship has a hull; a target may be a point object (0 and 0)
            return opt(key, default, gt=0, le=le)
        x = _number(d[key], f"{where}.{key}", ge=0, le=le)
        return x

    spec = ShipSpec(
        name=name, position=pos, course=course, speed=speed, waypoints=np.asarray(wps, dtype=float), U_d=U_d,
        speed_plan=plan,
        length=size("length_m", 5.0, limits.MAX_SHIP_LENGTH_M),
        width=size("width_m", 3.0, limits.MAX_SHIP_WIDTH_M),
        T_chi=opt("T_chi_s", getattr(prm, pre + "T_chi"), gt=0), T_U=opt("T_U_s", getattr(prm, pre + "T_U"), gt=0),
        lookahead=opt("lookahead_m", getattr(prm, pre + "lookahead"), gt=0),
        R_a=opt("R_a_m", getattr(prm, pre + "R_a"), ge=0),
        colav=colav, allow_route_over_land=over_land,
    )
    if not own and (spec.length == 0.0) != (spec.width == 0.0):
        raise ValueError(f"{where}: length_m and width_m must both be 0 (a point object) or both > 0, got "
                         f"{spec.length:g} and {spec.width:g}")
    ctx.setdefault("default_routes", []).append(wkey is None)
    out = _exchange_and_motion(d, where)
    if "leg_speeds_mps" in d:
        ls = d["leg_speeds_mps"]
        if wkey is None:
            raise ValueError(f"{where}.leg_speeds_mps needs the ship's waypoints (one speed per leg)")
        if plan is not None:
            raise ValueError(f"{where}: leg_speeds_mps and speed_plan are exclusive (speeds per leg or over time)")
        n_legs = len(spec.waypoints) - 1
        if not isinstance(ls, (list, tuple)) or len(ls) != n_legs:
            raise ValueError(f"{where}.leg_speeds_mps must be a list of {n_legs} speeds (one per leg of the route), "
                             f"got {show(ls)}")
        out["leg_speeds"] = np.array([_number(v, f"{where}.leg_speeds_mps[{i}]", ge=0, le=MAX_SPEED_MPS)
                                      for i, v in enumerate(ls)])
        if colav != "none" and not np.all(out["leg_speeds"] > 0):
            raise ValueError(f"{where}.leg_speeds_mps: every leg speed must be > 0 for a ship that runs a method "
                             f"(its planner needs a nominal speed), got {out['leg_speeds'].tolist()}")
    return dataclasses.replace(spec, **out)


#: Rule-18 roles a ship may declare (``rule18_role``): power-driven (no priority), not under command, restricted
#: in its ability to manoeuvre, constrained by its draught, engaged in fishing, sailing.
RULE18_ROLES = ("pdv", "nuc", "ram", "cbd", "fishing", "sailing")
MOTION_MODELS = ("kinematic", "3dof")
#: The presets of :mod:`psbmpc_jax.sim.vessel3dof` (named here: loading a scenario must not import JAX).
VESSEL_MODELS = ("psv_116m", "small_5m")


def _exchange_and_motion(d, where: str) -> dict:
    """``shares_route``, ``rule18_role``, ``motion_model`` and ``vessel_model`` of one ship."""
    out = {}
    if "shares_route" in d:
        out["shares_route"] = _bool(d["shares_route"], f"{where}.shares_route")
    if "rule18_role" in d:
        out["rule18_role"] = _choice(d["rule18_role"], RULE18_ROLES, f"{where}.rule18_role")
    if "motion_model" in d:
        out["motion_model"] = _choice(d["motion_model"], MOTION_MODELS, f"{where}.motion_model")
    if "vessel_model" in d:
        if out.get("motion_model") != "3dof":
            raise ValueError(f"{where}.vessel_model: only with motion_model: 3dof")
        out["vessel_model"] = _choice(d["vessel_model"], VESSEL_MODELS, f"{where}.vessel_model")
    elif out.get("motion_model") == "3dof":
        raise ValueError(f"{where}: motion_model 3dof needs vessel_model (one of {', '.join(VESSEL_MODELS)})")
    return out


# ---------------------------------------------------------------------------------------------- public API
def scenario_from_dict(data: dict, base_dir=None, source: str | None = None, *, land_checks: str = "warn",
                       method: str | None = None) -> Scenario:
    """Validate a scenario mapping (the parsed YAML, schema in ``docs/scenarios.md``) and build a
    :class:`Scenario` in SI units, radians and the local NED frame.

    Args:
        data: the mapping; not modified.
        base_dir: folder that ``chart.file`` is relative to (default: the current directory).
        source: recorded in ``Scenario.source`` (the file path).
        land_checks: what to do with the geometry problems of
            :func:`psbmpc_jax.scenario_checks.land_issues` (a ship starting on land, a waypoint on land, a route
            leg through land, two ships starting closer than the collision distance): ``"error"`` raises
            ``ValueError`` (what :func:`load_scenario` does), ``"warn"`` (default here) issues a
            :class:`~psbmpc_jax.scenario_checks.ScenarioWarning` per problem, ``"off"`` skips the checks.
        method: overrides ``mpc.method`` (one of :data:`METHODS`; ``psbmpc-jax run --method``) before the
            mapping is validated, so the file is checked as if it said so.

    Raises:
        ValueError: unknown or missing keys, wrong types, non-finite numbers, values out of range, unit
            alternatives given twice, times that are not multiples of ``simulation.dt_s``, bad overrides, bad
            charts, sizes above the limits of :mod:`psbmpc_jax.scenario_checks` -- the message names the key and
            says what is allowed.
    """
    if land_checks not in ("error", "warn", "off"):
        raise ValueError(f"land_checks must be 'error', 'warn' or 'off', got {land_checks!r}")
    data = copy.deepcopy(_mapping(data, "the scenario"))
    _check_keys(data, _TOP_KEYS, "the scenario (top level)", required=_TOP_REQUIRED)
    if method is not None:
        _method_name(method, "method (the override of mpc.method)")
        data["mpc"] = {**_mapping(data["mpc"], "mpc"), "method": method}
    name = _string(data["name"], "name")
    description = data.get("description", "")
    if not isinstance(description, str):
        raise ValueError(f"description must be a string, got {description!r}")
    dt, duration = _simulation(data["simulation"])
    runs, seed = _monte_carlo(data.get("monte_carlo", {}) or {})
    mpc = _mpc(data["mpc"], dt)
    sensor = _sensor(data.get("sensor", {}) or {}, dt)
    coll = None
    if "collision_distance_m" in data:
        coll = _number(data["collision_distance_m"], "collision_distance_m", gt=0)
    origin_ll = _origin_latlon(data["origin_latlon"]) if "origin_latlon" in data else None
    evaluation = _evaluation(data.get("evaluation", {}) or {})

    chart = inline = None
    info = dict(source=None, origin=None, crs=None)
    rdp_eps = clip = None
    if "chart" in data:
        chart, inline, info, rdp_eps, clip = _chart_source(data["chart"], base_dir, origin_ll)
    info["origin_latlon"] = origin_ll

    tl = data.get("targets", [])
    if tl is None:
        tl = []
    if not isinstance(tl, (list, tuple)):
        raise ValueError(f"targets must be a list of ships, got {type(tl).__name__}")
    if len(tl) + 1 > limits.MAX_SHIPS:
        raise ValueError(f"targets: {len(tl)} target ships; at most {limits.MAX_SHIPS - 1} allowed (plus the "
                         f"own-ship)")
    n_steps = int(round(duration / dt))
    mem = limits.simulation_memory_bytes(n_steps, runs, len(tl) + 1)
    if mem > limits.MAX_SIM_MEMORY_BYTES:
        raise ValueError(f"monte_carlo.runs ({runs}) x {n_steps + 1} steps (simulation.duration_s / dt_s) x "
                         f"{len(tl) + 1} ships need about {mem / 1024 ** 3:.1f} GiB of simulator memory; at most "
                         f"{limits.MAX_SIM_MEMORY_BYTES / 1024 ** 3:.0f} GiB allowed -- fewer runs, a shorter "
                         f"duration_s or a larger dt_s")

    ctx = dict(chart=chart, duration=duration, params=mpc.params, origin_latlon=origin_ll, method=mpc.method)
    own = _ship(data["own_ship"], "own_ship", own=True, ctx=ctx)
    targets = tuple(_ship(t, f"targets[{i}]", own=False, ctx=ctx) for i, t in enumerate(tl))
    seen = {own.name: "own_ship"}
    for i, t in enumerate(targets):
        if t.name in seen:
            raise ValueError(f"duplicate ship name {t.name!r} ({seen[t.name]} and targets[{i}]); ship names must "
                             f"be unique")
        seen[t.name] = f"targets[{i}]"

    # land: loaded -> RDP (builtin / file charts) -> clip about the routes -> ring sets
    polys: list[Polygon] = list(chart.polygons) if chart is not None else list(inline or ())
    info.update(n_polygons_loaded=len(polys), n_vertices_loaded=count_vertices(polys))
    if chart is not None:
        labels = [f"chart polygon {j}, feature {fid}" + (f" of layer {lay!r}" if lay else "")
                  for j, (fid, lay) in enumerate(zip(chart.ids, chart.layers))]
    else:
        labels = [f"chart.polygons_m[{j}]" for j in range(len(polys))]
    roles = [f"own-ship {own.name!r}"] + [f"target {t.name!r} (targets[{i}])" for i, t in enumerate(targets)]
    d_coll = float(mpc.params.d_safe if coll is None else coll)

    close = limits.start_distance_errors((own,) + targets, roles, d_coll)
    if close:
        raise ValueError(close[0] if len(close) == 1 else f"{len(close)} pairs of ships start too close: "
                         + "; ".join(close[:5]))
    reported: set = set()

    def land_check(variant, first):
        if land_checks == "off":
            return
        errors, warns = limits.land_issues((own,) + targets, roles, [variant], duration=duration,
                                           default_routes=ctx.get("default_routes", ()), ship_pairs=first)
        if own.allow_route_over_land:   # the file says so: the own-ship's legs over land are warned about
            leg = f"{roles[0]}: route leg "
            warns = warns + [m + " (allowed by own_ship.allow_route_over_land)" for m in errors if m.startswith(leg)]
            errors = [m for m in errors if not m.startswith(leg)]
        fresh = [m for m in errors + warns if not any(m.startswith(r) for r in reported)]
        errors, warns = [m for m in errors if m in fresh], [m for m in warns if m in fresh]
        reported.update(r for r in roles for m in errors + warns if m.startswith(r))
        limits.report_land_issues(errors, warns, land_checks)

    land_check(limits.LandVariant(polys, labels), True)       # before RDP: a start on land fails fast
    if chart is not None and rdp_eps is not None:
        from .rdp import simplify_chart

        loaded_chart = chart
        chart = simplify_chart(chart, rdp_eps)
        polys = list(chart.polygons)
        info.update(n_vertices_rdp=count_vertices(polys),
                    rdp_degenerate_kept=int(chart.report.get("rdp_degenerate_kept", 0)),
                    rdp_holes_dropped=int(chart.report.get("rdp_holes_dropped", 0)))
        same = len(polys) == len(loaded_chart.polygons)
        land_check(limits.LandVariant(polys, labels if same else [f"simplified chart polygon {j}"
                                                                  for j in range(len(polys))],
                                      f", as simplified with rdp_eps_m = {rdp_eps:g}"), False)
    if clip is not None:
        polys, clip_info = _clip(polys, (own,) + targets, clip)
        info.update(clip_info)

    for j, q in enumerate(polys):   # what Situation (the planner) will accept: RDP can make rings self-intersect
        if not q.is_valid:
            raise ValueError(f"chart: polygon {j} of the land as simplified (rdp_eps_m = {rdp_eps}) and clipped is not "
                             f"a valid simple polygon ({shapely.validation.explain_validity(q)}); the planner refuses "
                             f"it -- use a smaller chart.rdp_eps_m")
    rings = tuple(tuple(np.asarray(r, dtype=float) for r in rs) for rs in to_ring_sets(polys)) if polys else ()
    info.update(rdp_eps_m=rdp_eps, clip_m=clip, n_polygons=len(rings),
                n_vertices=int(sum(len(r) for rs in rings for r in rs)))
    return Scenario(name=name, description=description, own_ship=own, targets=targets, sensor=sensor, mpc=mpc,
                    polygons=rings, chart_info=info, dt=dt, duration=duration, runs=runs, seed=seed,
                    collision_distance=coll, source=source, evaluation=evaluation)


def estimator_key(scenario: Scenario, seed: int | None = None):
    """The PRNG key of the ``mc`` / ``ce`` estimators for a scenario run: ``jax.random.key(seed)`` with the
    scenario's ``monte_carlo.seed`` (or ``seed``); ``None`` for the ``quadrature`` estimator (it draws nothing)."""
    if scenario.mpc.config.estimator == "quadrature":
        return None
    import jax

    seed = integer(scenario.seed if seed is None else seed, "seed", ge=0, le=limits.MAX_SEED)
    return jax.random.key(seed)


def builtin_scenarios() -> list[str]:
    """Sorted names of the scenario files shipped in ``psbmpc_jax/scenarios/`` (``*.yaml``, ``*.yml``)."""
    if not SCENARIO_DIR.is_dir():
        return []
    return sorted({p.stem for p in SCENARIO_DIR.iterdir() if p.suffix in (".yaml", ".yml") and p.is_file()})


def _builtin_path(name: str) -> pathlib.Path:
    for ext in (".yaml", ".yml"):
        p = SCENARIO_DIR / f"{name}{ext}"
        if p.is_file():
            return p
    raise ValueError(f"unknown built-in scenario {name!r}; built-in scenarios: {', '.join(builtin_scenarios())} "
                     f"(or give the path of a .yaml / .yml file)")


def load_scenario(path_or_name, *, land_checks: str = "error", method: str | None = None) -> Scenario:
    """Load and validate a scenario: a path to a ``.yaml`` / ``.yml`` file, or the name of a built-in scenario
    (:func:`builtin_scenarios`, e.g. ``"head_on"``, ``"imazu_01"``).

    Everything is checked before anything is simulated or compiled, the land geometry included
    (``land_checks="error"``: a ship starting on land, a waypoint or route leg on or through land, two ships
    starting closer than the collision distance raise; see :func:`scenario_from_dict`).  ``method`` overrides
    the file's ``mpc.method`` (validated as if the file said so).

    Raises:
        ValueError: unknown built-in name (the message lists them), invalid YAML or an invalid scenario.
        FileNotFoundError: a ``.yaml`` / ``.yml`` path that does not exist.
    """
    if isinstance(path_or_name, os.PathLike):
        s = os.fspath(path_or_name)
        path_like = True
    elif isinstance(path_or_name, str) and path_or_name.strip():
        s = path_or_name
        path_like = s.lower().endswith((".yaml", ".yml")) or "/" in s or os.sep in s
    else:
        raise ValueError(f"load_scenario needs a .yaml/.yml path or a built-in scenario name "
                         f"({', '.join(builtin_scenarios())}), got {path_or_name!r}")
    if path_like:
        path = pathlib.Path(s).expanduser()
        if path.suffix.lower() not in (".yaml", ".yml"):
            raise ValueError(f"scenario files must end in .yaml or .yml, got {s!r}")
        if not path.is_file():
            raise FileNotFoundError(f"scenario file not found: {path}")
    else:
        path = _builtin_path(s)
    where = str(path)
    data = _yaml_load(path.read_text(encoding="utf-8"), where)
    if not isinstance(data, dict):
        raise ValueError(f"{where}: a scenario file must hold a mapping at the top level, got "
                         f"{type(data).__name__}")
    try:
        return scenario_from_dict(data, base_dir=path.parent, source=where, land_checks=land_checks, method=method)
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None
