"""Host API of Smooth-SBMPC (Mahipala & Johansen 2024) for the closed-loop simulator: :class:`SmoothSBMPCPlanner`.

>>> planner = SmoothSBMPCPlanner(polygons)                       # packs the land chart and its buffer once
>>> plan = planner.plan(state0, route, targets, last, segment=0)  # one ship
>>> plans = planner.plan_batch(states, route, targets, last, segments)   # R runs, one device call

Frame: NED, positions (north, east) [m], courses from north, clockwise positive [rad].  States and targets are
``(north, east, course, speed)``; controls and ``last`` are the offsets ``(U_m, χ_m)`` (speed factor, course
offset [rad]).  ``route [W, 2]`` is the whole route; ``segment`` the active segment (from waypoint ``segment``
to the next) — a value, so runs on different segments share one compilation and one ``vmap``.

**Local origin** (as :class:`psbmpc_jax.Planner`, docs/algorithm.md §11): the device works relative to
:attr:`SmoothSBMPCPlanner.origin`, a multiple of 1 km (the centre of the chart's bounding box, else the first
planned own-ship position), subtracted in float64 on the host before the cast to the device dtype, so float32
keeps millimetre resolution with UTM-sized coordinates.  It is re-chosen (and the chart re-packed, cached per
origin) when an own-ship is more than 10 km from it.  Everything returned is in the user's frame.

One step (``init_only=False``): the initialisation stage (Alg. 1–2), the corridor of Ψ (Alg. 3), the DOCP (27)
from ``n_starts`` starts (Ψ and the best constant behaviours at τ₀), the best feasible result and the safeguard
against Ψ (:mod:`psbmpc_jax.smooth.docp`).  ``init_only=True`` is the "original SB-MPC" of the paper's
Simulation 01: the init stage alone, whose first offsets are applied.
"""

from __future__ import annotations

import math

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from ..array_types import HostOrDevice
from ..methods.smooth_settings import SmoothSpec
from ..nlp import SolverSettings
from ..packing import pack_world, snap_origin
from ..params import PlannerConfig
from .corridor import buffered_chart, ring_arrays
from ..checks import MAX_ANGLE_RAD, MAX_SPEED_MPS
from .docp import DOCP_SOLVER, LOWER, UPPER, Previous, cast_tree, check_previous, check_step_options, step_traced
from .init_stage import ShipModel, SmoothSettings, SmoothWeights, init_stage_traced

#: The planner re-chooses its local origin when an own-ship is farther than this from it in north or east [m]
#: (float32 spacing stays <= 1 mm out to 10 km).
RECENTRE_DISTANCE = 10_000.0

DTYPES = ("float32", "float64")


class SmoothPlan(NamedTuple):
    """The result of :meth:`SmoothSBMPCPlanner.plan` (host NumPy arrays; :meth:`~SmoothSBMPCPlanner.plan_batch`
    adds a leading run axis ``[R]`` to every field; JAX arrays inside the jitted plan, before they come back).

    Attributes:
        apply: the offsets to apply now ``[2]`` (U_m, χ_m).
        controls: the kept sequence ``[N_mpc, 2]`` (``init_only``: the init stage's first N_mpc offsets).
        psi: the init stage's trajectory Ψ ``[N_init + 1, 4]`` (north, east, course, speed), user's frame
            (float64).
        cost: J_d of the kept sequence (``init_only``: the chosen behaviour's total cost at τ₀).
        warm_cost: J_d of the warm start Ψ (``init_only``: = cost).
        violation: max constraint violation of the kept sequence [m, rad] (``init_only``: 0).
        used_warm: the safeguard kept the warm start (``init_only``: True).
        status: solver status of the best start (0 ok/converged, 3 max-iter, 4 infeasible, 5 non-finite;
            ``init_only``: 0).
        iterations: inner solver iterations summed over the starts (``init_only``: 0).
        route_frame: the DOCP ran in the route frame (``chi_d_mode="route_los"``, or Ψ did not fit the box in the
            terminal-LOS frame; ``init_only``: True).  ``apply`` and ``controls`` are route-frame offsets always.
    """

    apply: HostOrDevice
    controls: HostOrDevice
    psi: HostOrDevice
    cost: HostOrDevice
    warm_cost: HostOrDevice
    violation: HostOrDevice
    used_warm: HostOrDevice
    status: HostOrDevice
    iterations: HostOrDevice
    route_frame: HostOrDevice


# ------------------------------------------------------------------------------------------ device side
def _plan_core(state0, route, targets, last, segment, land, buffered, weights, model, solver, previous=None, *,
               settings: SmoothSettings, n_starts: int, batch: str, init_only: bool) -> SmoothPlan:
    """One ship, traceable; positions in the local frame; ``previous``: a :class:`Previous` or None."""
    n = settings.n_mpc
    if init_only:
        init = init_stage_traced(state0, route, targets, last, land, weights, model, settings, segment)
        cost = init.cost[0]
        return SmoothPlan(init.controls[0], init.controls[:n], init.psi, cost, cost, jnp.zeros_like(cost),
                          jnp.asarray(True), jnp.asarray(0, jnp.int32), jnp.asarray(0, jnp.int32), jnp.asarray(True))
    st = step_traced(state0, route, targets, last, segment, land, buffered, weights, model, solver, settings=settings,
                     n_starts=n_starts, batch=batch, previous=previous)
    return _from_step(st)


def _from_step(st) -> SmoothPlan:
    return SmoothPlan(st.apply, st.controls, st.init.psi, st.cost, st.warm_cost, st.violation, st.used_warm,
                      st.solver.status, st.iterations, st.route_frame)


def _plan_batch_core(states, route, targets, last, segments, land, buffered, weights, model, solver, previous=None, *,
                     settings: SmoothSettings, n_starts: int, batch: str, init_only: bool) -> SmoothPlan:
    """R ships in one computation: the whole step ``lax.map``-ed over the runs (``batch="map"``) or ``vmap``-ed
    (``batch="vmap"``).  On a CPU ``map`` is the faster: the init stage is compute-bound (``vmap`` over 8 runs
    measured no faster than 8 single steps), its ``lax.cond`` culling and fast paths turn into ``select`` (both
    branches) under ``vmap`` with per-run predicates, and vectorised solver loops run in lockstep
    (docs/solver.md)."""
    one = lambda s, t, l, z, p: _plan_core(s, route, t, l, z, land, buffered, weights, model, solver,  # noqa: E731
                                           p, settings=settings, n_starts=n_starts, batch=batch, init_only=init_only)
    if batch == "map":
        return lax.map(lambda a: one(*a), (states, targets, last, segments, previous))
    return jax.vmap(one)(states, targets, last, segments, previous)


_STATIC = ("settings", "n_starts", "batch", "init_only")
_plan_jit = jax.jit(_plan_core, static_argnames=_STATIC)
_plan_batch_jit = jax.jit(_plan_batch_core, static_argnames=_STATIC)


# ------------------------------------------------------------------------------------------ host side
def polygon_rings(polygons) -> tuple:
    """Land polygons (shapely (Multi)Polygons, rings ``[n, 2]``, or tuples of rings: outer ring then holes) as
    a tuple of float64 ring tuples in the NED frame (``ValueError`` naming the polygon on a bad ring)."""
    from shapely.geometry import MultiPolygon, Polygon

    if isinstance(polygons, (Polygon, MultiPolygon)):
        polygons = [polygons]
    out = []
    for j, p in enumerate(polygons):
        if isinstance(p, (Polygon, MultiPolygon)):
            parts = [p] if isinstance(p, Polygon) else list(p.geoms)
            for g in parts:
                if not g.is_empty:
                    out.append(tuple(np.asarray(r.coords, float)[:-1, :2] for r in (g.exterior, *g.interiors)))
            continue
        out.append(tuple(ring_arrays(p, j)))
    return tuple(out)


def _array(value, name: str, shape_ok, shape_text: str) -> np.ndarray:
    a = np.asarray(value)
    if a.dtype.kind not in "iuf":
        raise ValueError(f"{name} must be numeric, got dtype {a.dtype}")
    a = a.astype(np.float64)
    if not shape_ok(a.shape):
        raise ValueError(f"{name} must be {shape_text}, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be finite (no NaN/inf)")
    return a


def _ship_states(a: np.ndarray, name: str) -> None:
    """Plausible (north, east, course, speed) rows: course in radians (|course| <= 2 pi: a larger value is
    probably degrees), speed in [0, MAX_SPEED_MPS] m/s (a larger one is probably knots or km/h)."""
    course, speed = a[..., 2], a[..., 3]
    bad = np.abs(course) > MAX_ANGLE_RAD
    if np.any(bad):
        v = float(course[bad].flat[0])
        raise ValueError(f"{name}: course (column 2) = {v:g} is not in radians (|course| <= 2 pi allowed); "
                         f"degrees? np.deg2rad({v:g}) = {np.deg2rad(v):.6g}")
    bad = (speed < 0) | (speed > MAX_SPEED_MPS)
    if np.any(bad):
        raise ValueError(f"{name}: speed (column 3) = {float(speed[bad].flat[0]):g} m/s is not a plausible ship "
                         f"speed (0 to {MAX_SPEED_MPS:g} m/s allowed); knots or km/h given as m/s?")


def _offsets(a: np.ndarray, name: str, tol: float = 1e-6, frames: bool = False) -> None:
    """Applied offsets (U_m, χ_m) inside the DOCP's box (the extremes of the behaviour sets).  ``frames``
    (``chi_d_mode="terminal_los"``): the offsets applied last are the DOCP's, converted to the route frame
    (:func:`psbmpc_jax.smooth.docp.to_route_frame`: a box offset plus the wrapped difference of the two LOS
    courses), so χ_m may be up to π beyond the box, |χ_m| <= 3π/2."""
    lo, hi = np.asarray(LOWER, float), np.asarray(UPPER, float)
    if frames:
        lo[1], hi[1] = lo[1] - math.pi, hi[1] + math.pi
    bad = (a < lo - tol) | (a > hi + tol)
    if np.any(bad):
        col = int(np.argwhere(bad)[0][-1])
        v = float(a[..., col][bad[..., col]].flat[0])
        if col == 0:
            what = f"the speed factor U_m must be in [{LOWER[0]:g}, {UPPER[0]:g}] (the DOCP's box)"
        elif frames:
            what = ("the course offset chi_m must be in [-3pi/2, 3pi/2] rad (the DOCP's box [-pi/2, pi/2] plus "
                    "at most pi between the terminal-LOS and the route frame)")
        else:
            what = "the course offset chi_m must be in [-pi/2, pi/2] rad (the DOCP's box)"
        raise ValueError(f"{name}: {what}, got {v:g}")


def _route_legs(route: np.ndarray, name: str = "route") -> None:
    """No zero-length leg (the LOS guidance divides by the leg's length)."""
    legs = np.linalg.norm(np.diff(route, axis=0), axis=1)
    if np.any(legs == 0):
        k = int(np.argmax(legs == 0))
        raise ValueError(f"{name}: leg {k} has zero length (waypoints {k} and {k + 1} coincide at "
                         f"{route[k].tolist()}); remove the repeated waypoint")


def _ship_model(model) -> None:
    """The own-ship model's values: U_d a plausible speed > 0, lookahead and time constants > 0, R_a >= 0."""
    for name, lo, hi in (("U_d", 0.0, MAX_SPEED_MPS), ("lookahead", 0.0, None), ("T_chi", 0.0, None),
                         ("T_U", 0.0, None)):
        v = getattr(model, name)
        if not (np.ndim(v) == 0 and np.isfinite(v) and v > lo and (hi is None or v <= hi)):
            rng = f"(0, {hi:g}] m/s" if hi is not None else "> 0"
            raise ValueError(f"model.{name} must be a finite number {rng}, got {v!r}")
    if not (np.ndim(model.R_a) == 0 and np.isfinite(model.R_a) and model.R_a >= 0):
        raise ValueError(f"model.R_a must be a finite number >= 0 m, got {model.R_a!r}")


def _segments(value, n_runs: int | None, n_waypoints: int, name: str) -> np.ndarray:
    a = np.asarray(value)
    shape = () if n_runs is None else (n_runs,)
    if a.shape != shape or a.dtype.kind not in "iu":
        raise ValueError(f"{name} must be {'an integer' if n_runs is None else f'integers [{n_runs}]'} (active "
                         f"route segment), got {a.dtype} of shape {a.shape}")
    if np.any(a < 0) or np.any(a > n_waypoints - 2):
        raise ValueError(f"{name} must be in [0, {n_waypoints - 2}] (segment z runs from waypoint z to z + 1 of the "
                         f"{n_waypoints} waypoints), got {a.tolist()}")
    return a.astype(np.int32)


class SmoothSBMPCPlanner:
    """Smooth-SBMPC for one ship (:meth:`plan`) or R independent runs sharing a chart and a route
    (:meth:`plan_batch`, one jitted device call).

    Args:
        polygons: land polygons in the NED frame [m] (shapely Polygons, rings ``[n, 2]`` or tuples of rings,
            as :class:`psbmpc_jax.Situation` polygons); the land chart (N_TP, clearance) and the chart buffered by
            ``settings.corridor_land_buffer`` (corridor) are packed once per local origin.
        weights, model, settings: :class:`SmoothWeights` (numeric, traced), :class:`ShipModel`,
            :class:`SmoothSettings` (static); None gives the defaults.
        solver: the DOCP's :class:`~psbmpc_jax.nlp.SolverSettings`; None: :data:`psbmpc_jax.smooth.docp.DOCP_SOLVER`.
        n_starts: DOCP starts, 1 (Ψ only) … 40 (Ψ and the n_starts − 1 best constant behaviours at τ₀).
        previous_start: start 1 of the DOCP is the previous update's kept sequence, shifted to begin now (the
            ``previous`` argument of :meth:`plan` / :meth:`plan_batch`; a behaviour while there is none), the
            receding-horizon warm start; needs ``n_starts >= 2`` and the DOCP (not ``init_only``).
        batch: ``"map"`` (default; independent solves — starts, and runs in :meth:`plan_batch` — one after
            another in one compiled call, the faster on a CPU) or ``"vmap"`` (vectorised).
        init_only: the "original SB-MPC" (the paper's Simulation 01): apply the init stage's first offsets; no
            corridor, no DOCP.
        dtype: device float type, ``"float32"`` (default) or ``"float64"`` (needs ``jax_enable_x64``).
    """

    def __init__(self, polygons=(), *, weights: SmoothWeights | None = None, model: ShipModel | None = None,
                 settings: SmoothSettings | None = None, solver: SolverSettings | None = None,
                 n_starts: int = SmoothSpec.n_starts, batch: str = "map", init_only: bool = False,
                 dtype: str = "float32", previous_start: bool = SmoothSpec.previous_start):
        self.weights = SmoothWeights() if weights is None else weights
        self.model = ShipModel() if model is None else model
        self.settings = SmoothSettings() if settings is None else settings
        # offsets applied last come back from the terminal-LOS frame (wider than the box in the route frame)
        self._frames = not init_only and self.settings.chi_d_mode == "terminal_los"
        self.solver = DOCP_SOLVER if solver is None else solver
        if not isinstance(self.weights, SmoothWeights):
            raise ValueError(f"weights must be a SmoothWeights, got {type(self.weights).__name__}")
        if not isinstance(self.model, ShipModel):
            raise ValueError(f"model must be a ShipModel, got {type(self.model).__name__}")
        _ship_model(self.model)
        check_step_options(self.settings, self.solver, n_starts, batch)
        if not isinstance(init_only, (bool, np.bool_)):
            raise ValueError(f"init_only must be a bool, got {init_only!r}")
        if not isinstance(previous_start, (bool, np.bool_)):
            raise ValueError(f"previous_start must be a bool, got {previous_start!r}")
        if previous_start and (init_only or n_starts < 2):
            raise ValueError(f"previous_start needs the DOCP with n_starts >= 2 (it is start 1, after Ψ), got "
                             f"init_only={init_only}, n_starts={n_starts!r}")
        self.previous_start = bool(previous_start)
        if str(dtype) not in DTYPES:
            raise ValueError(f"dtype must be one of {DTYPES}, got {dtype!r}")
        if str(dtype) == "float64" and not jax.config.jax_enable_x64:  # type: ignore[attr-defined]  # jax's Config stub lacks its flags
            raise ValueError("dtype 'float64' needs 64-bit JAX (jax.config.update('jax_enable_x64', True))")
        self.n_starts, self.batch, self.init_only, self.dtype = int(n_starts), batch, bool(init_only), np.dtype(dtype)
        self.polygons = polygon_rings(polygons)
        self.origin: np.ndarray | None = None
        if self.polygons:
            pts = np.concatenate([r for poly in self.polygons for r in poly])
            self.origin = snap_origin(0.5 * (pts.min(axis=0) + pts.max(axis=0)))
        self._charts: dict = {}
        self._time_checked: set = set()
        self._w = cast_tree(self.weights, self.dtype)
        self._m = cast_tree(self.model, self.dtype)

    # -------------------------------------------------------------------------------------- helpers
    def _origin_for(self, positions: np.ndarray) -> np.ndarray:
        """The local origin for own-ship ``positions [..., 2]`` (float64, user's frame)."""
        pos = positions.reshape(-1, 2)
        if self.origin is None or (len(pos) and np.max(np.abs(pos - self.origin)) > RECENTRE_DISTANCE):
            self.origin = snap_origin(pos[0])
        return self.origin

    def charts(self, origin=None):
        """``(land, buffered)`` packed about ``origin`` (default: :attr:`origin`, or (0, 0) before the first
        plan), cached per origin."""
        o = np.zeros(2) if origin is None and self.origin is None else np.asarray(
            self.origin if origin is None else origin, float)
        key = (float(o[0]), float(o[1]))
        if key not in self._charts:
            shifted = tuple(tuple(r - o for r in poly) for poly in self.polygons)
            land = pack_world(shifted, PlannerConfig(dtype=self.dtype.name)).polygons
            buf = land if self.init_only else buffered_chart(shifted, self.settings.corridor_land_buffer,
                                                             dtype=self.dtype.name)
            self._charts[key] = (land, buf)
        return self._charts[key]

    def _local(self, states, route, targets, origin):
        f = self.dtype.type
        states, targets = states.copy(), targets.copy()
        states[..., :2] -= origin
        targets[..., :2] -= origin
        return (np.asarray(states, f), np.asarray(route - origin, f), np.asarray(targets, f))

    def _finish(self, plan, origin) -> SmoothPlan:
        plan = jax.device_get(plan)
        psi = np.asarray(plan.psi, np.float64).copy()
        psi[..., :2] += origin
        host = {k: np.asarray(getattr(plan, k)) for k in SmoothPlan._fields}
        return SmoothPlan(**{**host, "psi": psi})

    def _previous(self, previous, lead: tuple):
        """``previous`` (None, or ``lead + [N_mpc, 2]`` with NaN rows for runs without one) as a
        :class:`Previous` of device arrays (not valid where there is none), or None with one start or
        ``init_only``."""
        n = self.settings.n_mpc
        if not self.previous_start and previous is not None:
            raise ValueError("previous is only used with previous_start=True")
        if self.init_only or self.n_starts < 2:
            return None
        if previous is None:     # none: a row the starts ignore (with 2+ starts always passed: no recompile)
            return Previous(np.zeros((*lead, n, 2), self.dtype), np.zeros(lead, bool))
        a = check_previous(previous, n, "previous", lead)
        valid = ~np.all(np.isnan(a), axis=(-2, -1))
        return Previous(np.asarray(np.nan_to_num(a), self.dtype), np.asarray(valid))

    def _check_time(self, n_targets: int) -> None:
        """Refuse an update whose estimated time (one run) exceeds the limit (:mod:`psbmpc_jax.update_time`),
        before anything is compiled; once per number of targets."""
        if n_targets in self._time_checked:
            return
        from ..update_time import check_smooth

        st = self.settings
        check_smooth(st.n_init, st.n_mpc, n_targets, self.n_starts, self.solver.max_outer, self.solver.max_inner,
                     init_only=self.init_only, names={"T_init": "settings.T_init / dt", "T_mpc": "settings.T_mpc / dt",
                                                      "starts": "n_starts",
                                                      "iterations": "solver.max_outer x max_inner"})
        self._time_checked.add(n_targets)

    def _statics(self):
        return dict(settings=self.settings, n_starts=self.n_starts, batch=self.batch, init_only=self.init_only)

    # -------------------------------------------------------------------------------------- API
    def plan(self, state0, route, targets, last, segment=0, previous=None) -> SmoothPlan:
        """One ship: ``state0 [4]`` (north, east, course, speed), ``route [W >= 2, 2]``, ``targets [I, 4]``
        (north, east, course, speed; I may be 0), ``last [2]`` the offsets applied last (U_m, χ_m),
        ``segment`` the active route segment, ``previous`` (``previous_start`` only) the previous plan's
        ``controls [N_mpc, 2]`` shifted to begin now (:func:`psbmpc_jax.smooth.docp.shift_controls`) or None.
        Returns :class:`SmoothPlan` (host arrays, user's frame).

        Raises ``ValueError`` naming the input for a wrong shape, a non-finite value, a course outside
        ``|course| <= 2 pi`` (degrees?), a speed outside 0 to 30 m/s, ``last`` outside the DOCP's box
        (U_m in [0.1, 1], χ_m in [-pi/2, pi/2]; with ``chi_d_mode="terminal_los"`` χ_m in [-3pi/2, 3pi/2], the
        DOCP's offsets converted back to the route frame) or a zero-length route leg; ``ResourceError`` (a ValueError)
        before anything is compiled when the update's estimated time exceeds the limit
        (:mod:`psbmpc_jax.update_time`, naming the setting)."""
        state0 = _array(state0, "state0", lambda s: s == (4,), "[4] (north, east, course, speed)")
        route = _array(route, "route", lambda s: len(s) == 2 and s[1] == 2 and s[0] >= 2, "[W >= 2, 2] waypoints")
        targets = _array(targets, "targets", lambda s: len(s) == 2 and s[1] == 4, "[I, 4] (north, east, course, "
                         "speed)")
        last = _array(last, "last", lambda s: s == (2,), "[2] (U_m, chi_m)")
        z = _segments(segment, None, route.shape[0], "segment")
        _ship_states(state0, "state0")
        _ship_states(targets, "targets")
        _offsets(last, "last", frames=self._frames)
        _route_legs(route)
        prev = self._previous(previous, ())
        self._check_time(targets.shape[0])
        origin = self._origin_for(state0[:2])
        land, buf = self.charts(origin)
        s, r, t = self._local(state0, route, targets, origin)
        plan = _plan_jit(s, r, t, np.asarray(last, self.dtype), jnp.asarray(z), land, buf, self._w, self._m,
                         self.solver, prev, **self._statics())
        return self._finish(plan, origin)

    def plan_batch(self, states, route, targets, last, segments, previous=None) -> SmoothPlan:
        """R runs in one jitted call: ``states [R, 4]``, ``targets [R, I, 4]``, ``last [R, 2]``, ``segments [R]``
        (integers), ``previous`` (``previous_start`` only; None or ``[R, N_mpc, 2]``, a run's rows NaN throughout
        when it has no previous plan); ``route [W, 2]`` shared.  Returns :class:`SmoothPlan` with a leading ``[R]`` axis; row r equals
        ``plan(states[r], route, targets[r], last[r], segments[r])`` up to rounding."""
        states = _array(states, "states", lambda s: len(s) == 2 and s[1] == 4 and s[0] >= 1,
                        "[R >= 1, 4] (north, east, course, speed)")
        R = states.shape[0]
        route = _array(route, "route", lambda s: len(s) == 2 and s[1] == 2 and s[0] >= 2, "[W >= 2, 2] waypoints")
        targets = _array(targets, "targets", lambda s: len(s) == 3 and s[0] == R and s[2] == 4,
                         f"[R = {R}, I, 4] (north, east, course, speed)")
        last = _array(last, "last", lambda s: s == (R, 2), f"[R = {R}, 2] (U_m, chi_m)")
        z = _segments(segments, R, route.shape[0], "segments")
        _ship_states(states, "states")
        _ship_states(targets, "targets")
        _offsets(last, "last", frames=self._frames)
        _route_legs(route)
        prev = self._previous(previous, (R,))
        self._check_time(targets.shape[1])
        origin = self._origin_for(states[:, :2])
        land, buf = self.charts(origin)
        s, r, t = self._local(states, route, targets, origin)
        plan = _plan_batch_jit(s, r, t, np.asarray(last, self.dtype), jnp.asarray(z), land, buf, self._w, self._m,
                               self.solver, prev, **self._statics())
        return self._finish(plan, origin)


__all__ = ["SmoothSBMPCPlanner", "SmoothPlan", "RECENTRE_DISTANCE", "polygon_rings"]
