"""The two-level MPC of Mahipala & Johansen (2023, Secs. II, IV, V, Fig. 1) as one planner (docs/two_level.md):
per update

1. the active leg (switch past the leg's end or within R_a of its waypoint);
2. the upper level, :func:`~psbmpc_jax.two_level.path_mpc.solve_path_mpc`: absolute commands (χ_d, U_d) over
   N_p steps against the static circles and the riparian corridor of the route (built once per leg);
3. the lower level, the original SB-MPC (39 behaviours) with ζ (eq. 15) on the grid evaluator: the own-ship's
   nominal course follows the upper level's plan (choice TL-7, docs/algorithm.md §15: LOS through the planned
   positions, then straight on along the last planned course; ``nominal="hold"``: straight on along χ_d,0 from the
   start), the targets predicted by the ground-avoiding CV model (eq. 2) and handed to the evaluator as routes;
4. the command χ_c = χ_d,0 + χ_m, U_c = U_d,0 · U_m.
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..behaviours import enumerate_behaviours_deg
from ..costs.sbmpc import SbmpcHazardTerm
from ..costs.zeta import ZETA_SHAPES, SbmpcZetaTerm
from ..methods.sbmpc_family import SbmpcSettings, manoeuvring_term
from ..methods.two_level_settings import TwoLevelSpec
from ..numerics import wrap_angle_host
from ..packing import Capacities, pack_world
from ..params import PlannerConfig
from ..planner import Planner
from ..situation import Obstacle, OwnShip, Situation
from ..solve import PlannerState
from .path_frame import active_leg
from .path_mpc import Legs, PathMpcData, PathMpcSettings, make_circles, make_legs, solve_path_mpc
from .prediction import DEFAULT_BETA, DEFAULT_D_CRITICAL, predict_targets
from .riparian import leg_corridors
from .static_obstacles import StaticCircles, concat_circles

#: The 39 behaviours of the original SB-MPC as Mahipala & Johansen (2023, 2024) restate it: speed factors {1, 0.5, 0}
#: × course offsets −90 … 90° in 15° steps.
SBMPC_BEHAVIOURS = enumerate_behaviours_deg(((1.0, 0.5, 0.0),), (tuple(range(-90, 91, 15)),))
NOMINALS = ("plan", "hold")


@dataclasses.dataclass(frozen=True)
class TwoLevelSettings:
    """Tuning of the two-level method (defaults: our proposals where Mahipala & Johansen 2023 give no values; fjord
    scale).

    Attributes:
        path: the upper level (:class:`PathMpcSettings`).
        corridor_half_width, corridor_sample, corridor_radius, corridor_margin: Algorithm 1's Δd, Δs, R_RG and
            the buffer of the land [m] (proposed r_os + 2 m).
        circle_margin: added to the enclosing circle of land that crosses a leg (choice TL-8) [m]; the circle
            constraint adds r_os on top.
        r_accept: leg switching radius R_a [m].
        beta, d_critical, prediction_compare: the targets' ground-avoiding prediction (eq. 2).
        eta1, eta2, d_close, zeta_d_safe, zeta_shape: ζ of eq. (15) (``zeta_shape`` "printed" or "psbmpc").
        sbmpc: the SB-MPC's collision/COLREGS/Γ tuning (:class:`~psbmpc_jax.methods.sbmpc_family.SbmpcSettings`).
        nominal: the SB-MPC's nominal references: ``"plan"`` (choice TL-7) or ``"hold"`` (the flag).
        plan_stride: every how many MPC steps a planned position becomes a nominal waypoint.
        sbmpc_every: the SB-MPC solves at every ``sbmpc_every``-th update (the first included) and its
            (χ_m, U_m) is held in between (our proposal: the MPC every 1 s, the SB-MPC every 5 s).

    The defaults shared with scenario files are defined once, by the ``mpc.two_level`` section
    (:class:`~psbmpc_jax.methods.two_level_settings.TwoLevelSpec`), except ``sbmpc_every``: 1 here, 5 there.
    """

    path: PathMpcSettings = PathMpcSettings()
    corridor_half_width: float = TwoLevelSpec.corridor_half_width
    corridor_sample: float = TwoLevelSpec.corridor_sample
    corridor_radius: float = TwoLevelSpec.corridor_radius
    corridor_margin: float = TwoLevelSpec.corridor_margin
    circle_margin: float = TwoLevelSpec.circle_margin
    r_accept: float = TwoLevelSpec.r_accept
    beta: float = DEFAULT_BETA
    d_critical: float = DEFAULT_D_CRITICAL
    prediction_compare: str = TwoLevelSpec.compare
    eta1: float = TwoLevelSpec.eta1
    eta2: float = TwoLevelSpec.eta2
    d_close: float = TwoLevelSpec.d_close
    zeta_d_safe: float = TwoLevelSpec.zeta_d_safe
    zeta_shape: str = TwoLevelSpec.zeta_shape
    sbmpc: SbmpcSettings = SbmpcSettings()
    nominal: str = TwoLevelSpec.nominal
    plan_stride: int = TwoLevelSpec.plan_stride
    sbmpc_every: int = 1

    def __post_init__(self):
        if not isinstance(self.path, PathMpcSettings):
            raise ValueError(f"TwoLevelSettings.path must be a PathMpcSettings, got {type(self.path).__name__}")
        if not isinstance(self.sbmpc, SbmpcSettings):
            raise ValueError(f"TwoLevelSettings.sbmpc must be an SbmpcSettings, got {type(self.sbmpc).__name__}")
        for name in ("corridor_half_width", "corridor_sample", "corridor_radius", "r_accept", "d_critical",
                     "d_close"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
                raise ValueError(f"TwoLevelSettings.{name} must be a finite number > 0, got {v!r}")
        for name in ("corridor_margin", "circle_margin", "eta1", "eta2", "zeta_d_safe"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ValueError(f"TwoLevelSettings.{name} must be a finite number >= 0, got {v!r}")
        if not (isinstance(self.beta, (int, float)) and 0 < self.beta < math.pi):
            raise ValueError(f"TwoLevelSettings.beta must be in (0, pi) rad per step, got {self.beta!r}")
        if self.prediction_compare not in ("plus", "both"):
            raise ValueError(f"TwoLevelSettings.prediction_compare must be 'plus' or 'both', got "
                             f"{self.prediction_compare!r}")
        if self.zeta_shape not in ZETA_SHAPES:
            raise ValueError(f"TwoLevelSettings.zeta_shape must be one of {ZETA_SHAPES}, got {self.zeta_shape!r}")
        if self.nominal not in NOMINALS:
            raise ValueError(f"TwoLevelSettings.nominal must be one of {NOMINALS}, got {self.nominal!r}")
        for name in ("plan_stride", "sbmpc_every"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"TwoLevelSettings.{name} must be an integer >= 1, got {v!r}")

    def terms(self) -> tuple:
        """The lower level's cost terms: the SB-MPC hazard with ζ joined inside the max, and Γ."""
        s = self.sbmpc
        hazard = SbmpcHazardTerm(d_safe=s.d_safe, K_coll=s.K_coll, p=s.p, q=s.q, kappa=s.kappa, d_cl=s.d_cl,
                                 aggregation="max", risk="crisp", colregs="boolean")
        zeta = SbmpcZetaTerm(hazard=hazard, eta1=self.eta1, eta2=self.eta2, d_safe_g=self.zeta_d_safe,
                             d_close=self.d_close, shape=self.zeta_shape)
        return (zeta, manoeuvring_term(s))


class TwoLevelState(NamedTuple):
    """Memory between updates: active leg ``j``, the applied command ``u_prev = (χ, U)``, the last upper-level
    plan ``u_plan [N_p, 2]`` (warm start; None at first), the SB-MPC's planner state (its last offsets) and the
    updates since its last solve."""

    j: int
    u_prev: np.ndarray
    u_plan: np.ndarray | None
    sbmpc: PlannerState
    since: int = 0


class TwoLevelPlan(NamedTuple):
    """One update: the command ``(chi_c, U_c)``, the upper level's ``(chi_d, U_d)`` and plan
    (:class:`~psbmpc_jax.two_level.path_mpc.PathMpcResult`, NumPy), the SB-MPC modification ``(chi_m, U_m)``
    and its :class:`~psbmpc_jax.packing.PlanResult`, the targets' predicted positions ``[I, N+1, 2]``, the
    active leg and the nominal route the SB-MPC followed.  At an update that holds the last modification
    (``sbmpc_every`` > 1) ``sbmpc`` is None and ``target_paths`` / ``nominal_route`` are empty."""

    chi_c: float
    U_c: float
    chi_d: float
    U_d: float
    chi_m: float
    U_m: float
    path: object
    sbmpc: object
    target_paths: np.ndarray
    leg: int
    nominal_route: np.ndarray


def _circles_from_spec(circles) -> StaticCircles:
    if circles is None:
        return StaticCircles.empty()
    if isinstance(circles, StaticCircles):
        return circles
    from .static_obstacles import from_yaml

    return from_yaml(circles)


class TwoLevelPlanner:
    """The two-level method for one own-ship on a route through a chart (module docstring).

    Args:
        waypoints: the route ``[n >= 2, 2]`` (north, east) [m].
        polygons: the chart (land) as the situation takes it (rings ``[n, 2]`` or tuples of rings).
        circles: static obstacles: a :class:`~psbmpc_jax.two_level.static_obstacles.StaticCircles`, the YAML
            list ``[{center_m: [n, e], radius_m: r}, ...]``, or None; land that crosses a leg is added as a
            circle (choice TL-8) and left out of the corridors.
        U_ref: cruise speed [m/s] (the upper level's reference and the SB-MPC's nominal speed scale).
        settings: :class:`TwoLevelSettings`.
        config: the SB-MPC's horizon and step (its :class:`~psbmpc_jax.params.PlannerConfig`; ``grid`` grounding
            recommended on real charts).
        length, width: the own-ship's size [m] (for the SB-MPC situation).
    """

    def __init__(self, waypoints, polygons=(), *, circles=None, U_ref: float, settings: TwoLevelSettings =
                 TwoLevelSettings(), config: PlannerConfig | None = None, length: float = 5.0, width: float = 3.0):
        if not isinstance(settings, TwoLevelSettings):
            raise ValueError(f"settings must be a TwoLevelSettings, got {type(settings).__name__}")
        if isinstance(U_ref, bool) or not isinstance(U_ref, (int, float)) or not (0 < U_ref <= settings.path.U_max):
            raise ValueError(f"U_ref must be a number in (0, path.U_max = {settings.path.U_max}] m/s, got {U_ref!r}")
        self.settings, self.U_ref = settings, float(U_ref)
        self.route = np.asarray(waypoints, dtype=float)
        if self.route.ndim != 2 or self.route.shape[1:] != (2,) or len(self.route) < 2:
            raise ValueError(f"waypoints must be [n >= 2, 2] (north, east) [m], got shape {self.route.shape}")
        # the route runs on past its last waypoint (as LOS guidance does in the simulator): one more leg
        d = self.route[-1] - self.route[-2]
        ext = 2.0 * settings.path.U_max * settings.path.N_p * settings.path.dt + (config.T if config else 300.0) \
            * settings.path.U_max
        self.waypoints = np.vstack([self.route, self.route[-1] + ext * d / np.hypot(*d)])
        self.polygons = tuple(polygons)
        self.config = PlannerConfig(T=300.0, dt=2.0) if config is None else config
        self.length, self.width = float(length), float(width)
        crossing: list = []
        corridors = leg_corridors(self.waypoints, self.polygons, half_width=settings.corridor_half_width,
                                  sample=settings.corridor_sample, radius=settings.corridor_radius,
                                  margin=settings.corridor_margin, circle_margin=settings.circle_margin,
                                  static_circles_out=crossing) if self.polygons else None
        self.circles = concat_circles(_circles_from_spec(circles), StaticCircles.from_pairs(crossing))
        self.legs: Legs = make_legs(self.waypoints, None if corridors is None else
                                    [(c.s, c.lower, c.upper) for c in corridors],
                                    half_width=settings.corridor_half_width)
        self.circle_arrays = make_circles(self.circles.centres, self.circles.radii)
        # the route and circles on the device in the solve's dtype, once (not at every update)
        dtype = jnp.float64 if self.config.dtype == "float64" else jnp.float32
        self.device_legs, self.device_circles = (jax.tree.map(lambda a: jnp.asarray(a, dtype), t)
                                                 for t in (self.legs, self.circle_arrays))
        self.chart = pack_world(self.polygons, PlannerConfig(dtype=self.config.dtype)).polygons
        # fixed route capacities: the nominal route and the targets' predicted routes change length from one
        # update to the next, which would otherwise recompile the grid search
        caps = Capacities(waypoints=settings.path.N_p // settings.plan_stride + 3,
                          obstacle_waypoints=self.config.n_steps // settings.plan_stride + 3)
        self.grid_planner = Planner(self.config, behaviours=SBMPC_BEHAVIOURS, terms=settings.terms(),
                                    capacities=caps)

    def initial_state(self, own_state) -> TwoLevelState:
        s = np.asarray(own_state, dtype=float)
        return TwoLevelState(0, np.array([s[2], s[3]]), None, PlannerState(), 0)

    def nominal_route(self, own_state, path) -> np.ndarray:
        """The SB-MPC's nominal route: LOS through the upper level's planned positions (every ``plan_stride``-th)
        and on along its last planned course to beyond the SB-MPC horizon (``nominal="plan"``), or straight on
        along χ_d,0 (``"hold"``)."""
        p0 = np.asarray(own_state[:2], dtype=float)
        reach = self.config.T * max(self.U_ref, float(own_state[3])) + 10.0
        if self.settings.nominal == "hold":
            chi = float(path.u[0, 0])
            return np.stack([p0, p0 + reach * np.array([math.cos(chi), math.sin(chi)])])
        pts = np.asarray(path.x[:, :2], dtype=float)[:: self.settings.plan_stride][1:]
        chi = float(path.u[-1, 0])
        end = (pts[-1] if len(pts) else p0) + reach * np.array([math.cos(chi), math.sin(chi)])
        route = np.vstack([p0[None], pts, end[None]])
        keep = np.concatenate([[True], np.hypot(*np.diff(route, axis=0).T) > 1e-6])   # no zero-length legs
        return route[keep]

    def plan(self, own_state, targets, state: TwoLevelState | None = None) -> tuple[TwoLevelPlan, TwoLevelState]:
        """One update from the own-ship state ``(x, y, χ, U)`` and the targets ``[I, 4]`` as (x, y, χ, U)."""
        s = self.settings
        own = np.asarray(own_state, dtype=float).reshape(-1)
        if own.shape != (4,) or not np.all(np.isfinite(own)):
            raise ValueError(f"own_state must be 4 finite numbers (x, y, chi, U), got {np.asarray(own_state)!r}")
        tg = np.asarray(targets, dtype=float) if np.size(targets) else np.zeros((0, 4))
        if tg.ndim != 2 or tg.shape[1] != 4 or not np.all(np.isfinite(tg)):
            raise ValueError(f"targets must be a finite [I, 4] array of (x, y, chi, U) rows, got shape "
                             f"{np.shape(targets)}")
        state = self.initial_state(own) if state is None else state
        j = int(active_leg(own[:2], self.waypoints, state.j, s.r_accept))
        j = min(j, len(self.waypoints) - 2)
        dtype = self.device_legs.wp.dtype
        data = PathMpcData(jnp.asarray(own, dtype), jnp.asarray(state.u_prev, dtype), jnp.asarray(j, jnp.int32),
                           jnp.asarray(self.U_ref, dtype), self.device_legs, self.device_circles)
        path = jax.device_get(solve_path_mpc(data, s.path, previous=state.u_plan))
        chi_d, U_d = float(path.u[0, 0]), float(path.u[0, 1])
        fresh = state.u_plan is None or state.since + 1 >= s.sbmpc_every
        if not fresh:                                  # hold the SB-MPC's last modification
            U_m, chi_m = (float(v) for v in np.asarray(state.sbmpc.last_offsets, dtype=float))
            plan = TwoLevelPlan(float(wrap_angle_host(chi_d + chi_m)), U_d * U_m, chi_d, U_d, chi_m, U_m, path, None,
                                np.zeros((0, self.config.n_steps + 1, 2)), j, np.zeros((0, 2)))
            return plan, TwoLevelState(j, np.array([chi_d, U_d]), np.asarray(path.u), state.sbmpc, state.since + 1)
        n_steps = self.config.n_steps
        if len(tg):
            pred = jax.device_get(predict_targets(tg, self.chart, n_steps, self.config.dt, beta=s.beta,
                                                  d_critical=s.d_critical, compare=s.prediction_compare))
            paths = np.asarray(pred.positions, dtype=float)
        else:
            paths = np.zeros((0, n_steps + 1, 2))
        obstacles = tuple(self._obstacle(tg[i], paths[i]) for i in range(len(tg)))
        route = self.nominal_route(own, path)
        U_nom = max(U_d, 1e-3)
        sit = Situation(OwnShip(state=own, waypoints=route, U_d=U_nom, length=self.length, width=self.width),
                        obstacles, self.polygons)
        res, sb_state = self.grid_planner.plan(sit, state.sbmpc)
        U_m, chi_m = float(res.u_opt), float(res.chi_opt)
        chi_c = float(wrap_angle_host(chi_d + chi_m))
        U_c = U_d * U_m
        plan = TwoLevelPlan(chi_c, U_c, chi_d, U_d, chi_m, U_m, path, res, paths, j, route)
        return plan, TwoLevelState(j, np.array([chi_d, U_d]), np.asarray(path.u), sb_state, 0)

    def _obstacle(self, target, path) -> Obstacle:
        """A target for the SB-MPC: its predicted ground-avoiding path as its route (every ``plan_stride``-th
        point; LOS along it at the target's speed), straight-line-like covariance, one scenario."""
        chi, U = float(target[2]), float(target[3])
        pts = path[:: self.settings.plan_stride]
        if np.hypot(*(pts[-1] - path[-1])) > 1e-9:
            pts = np.vstack([pts, path[-1:]])
        moving = U > 1e-6 and np.all(np.hypot(*np.diff(pts, axis=0).T) > 1e-6)
        return Obstacle(np.array([target[0], target[1], U * math.cos(chi), U * math.sin(chi)]),
                        np.diag([1.0, 1.0, 0.01, 0.01]), length=self.length, width=self.width,
                        waypoints=pts if moving else None, n_ps=1)


__all__ = ["TwoLevelSettings", "TwoLevelState", "TwoLevelPlan", "TwoLevelPlanner", "SBMPC_BEHAVIOURS", "NOMINALS"]
