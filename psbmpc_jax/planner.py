"""Host-side API: validate, pack into bucketed device arrays, call the jitted solve step, unpack.

>>> planner = Planner()                                   # paper defaults, 1014 behaviours
>>> result, state = planner.plan(situation, state)        # state carries the last applied offsets

Shapes are bucketed (obstacles, scenarios, waypoints, polygons, vertices, behaviours) so that a stream of
situations with slowly varying sizes compiles a handful of times; values never recompile.

Local origin (docs/algorithm.md §11): the device works relative to :attr:`Planner.origin`, chosen at the first
solve as the own-ship position snapped to 1 km and kept (so the packed chart and the distance grid, cached by
content and origin, stay valid from solve to solve) until the own-ship is more than
:data:`RECENTRE_DISTANCE` (10 km) from it in either axis.  Results are in the user's frame.
"""

from __future__ import annotations

import time

import jax
import numpy as np

from .behaviours import paper_behaviours, validate_behaviours
from .costs.base import check_terms, term_names
from .costs.collision import standard_normal_table
from . import checks
from .distance_grid import DistanceGrid, build_distance_grid, polygons_key, reach_region
from .evaluate import DEFAULT_TERMS
from .packing import (Capacities, PlanResult, SolveInputs, WorldArrays, pack, pack_behaviours, pack_world,
                      shift_polygons, snap_origin, unpack)
from .params import Params, PlannerConfig, params_as_arrays, validate_params
from .situation import Situation
from .solve import PlannerState, solve
from .status import status_name

#: Cost columns of the default terms.
COST_TERMS = term_names(DEFAULT_TERMS)

#: A planner re-chooses its local origin when the own-ship is farther than this from it in north or east [m]:
#: float32 spacing stays <= 1 mm out to 10 km (and the origin, cached world and grid rarely change).
RECENTRE_DISTANCE = 10_000.0


def check_dtype(config: PlannerConfig) -> None:
    if config.dtype == "float64" and not jax.config.jax_enable_x64:  # type: ignore[attr-defined]  # jax's Config stub lacks its flags
        raise ValueError(
            "PlannerConfig.dtype='float64' needs 64-bit JAX: call jax.config.update('jax_enable_x64', True) "
            "before building arrays (or use dtype='float32')"
        )


class Planner:
    """PSB-MPC planner: a behaviour table, static config, parameter values and cost terms.

    Args:
        config: :class:`PlannerConfig` (static: horizon, estimator, dtype, ...).
        params: :class:`Params` (values; may also be passed per call).
        behaviours: ``[B, n_M, 2]`` table; default the paper's 1014 (n_M = 2).
        terms: the cost terms (default :data:`psbmpc_jax.evaluate.DEFAULT_TERMS`: collision, COLREGS,
            grounding, path); add your own with :func:`psbmpc_jax.costs.base.cost_term`.
        capacities: fixed padded sizes (:class:`~psbmpc_jax.packing.Capacities`); default bucketed.

    Attributes:
        origin: the local origin (north, east) [m] of the device frame of the latest :meth:`prepare` (``None``
            before the first); device arrays from :meth:`prepare` / :func:`~psbmpc_jax.solve.solve` are relative
            to it (pass it to :func:`~psbmpc_jax.packing.unpack`).
    """

    def __init__(self, config: PlannerConfig | None = None, params: Params | None = None, behaviours=None,
                 terms=None, capacities: Capacities | None = None):
        self.config = config or PlannerConfig()
        if not isinstance(self.config, PlannerConfig):
            raise ValueError(f"config must be a PlannerConfig, got {type(self.config).__name__}")
        check_dtype(self.config)
        self.params = params or Params()
        self.behaviours = validate_behaviours(paper_behaviours(2) if behaviours is None else behaviours)
        validate_params(self.params, self.config, self.behaviours.shape[1])   # t_ts inside the horizon too
        self.terms = check_terms(DEFAULT_TERMS if terms is None else terms)
        self.capacities = capacities
        self._grids: dict[str, DistanceGrid] = {}
        self._grid_regions: list = []          # (chart+origin key, region, key of _grids)
        self._device_params: tuple | None = None      # (params object, its device arrays)
        self._world: tuple | None = None              # (polygons content key, origin, grid, packed world)
        self._memory_checked: tuple | None = None     # the padded shapes whose memory estimate passed
        self.origin: np.ndarray | None = None
        self._behaviour_arrays = pack_behaviours(self.behaviours, self.config, capacities)

    @property
    def cost_names(self) -> tuple[str, ...]:
        """``("total",) + term names``: the keys of :attr:`PlanResult.costs`."""
        return term_names(self.terms)

    def _origin_for(self, situation: Situation) -> np.ndarray:
        """The planner's local origin, (re-)chosen at the first solve and when the own-ship is more than
        :data:`RECENTRE_DISTANCE` from it (module docstring)."""
        pos = np.asarray(situation.own_ship.state[:2], dtype=float)
        if self.origin is None or np.max(np.abs(pos - self.origin)) > RECENTRE_DISTANCE:
            self.origin = snap_origin(pos)
        return self.origin

    def distance_grid(self, situation: Situation) -> DistanceGrid:
        """The nearest-land grid for grid mode, covering everywhere the own-ship can reach in one horizon.

        No predicted position is farther than max(U_0, U_d)·T from the own-ship (speed references never
        exceed U_d and the speed lag is monotone), so the grid covers that disc; grids are cached per
        chart, origin and (snapped) region and rebuilt only when the own-ship moves out of them.  The distances
        are computed about the planner's local origin (full precision in float32 with UTM coordinates); the
        grid returned is in the user's frame (its ``origin`` corner is float64 NumPy)."""
        own = situation.own_ship
        o = self._origin_for(situation)
        reach = max(float(own.state[3]), float(own.U_d)) * self.config.T + 10.0
        region = reach_region(own.state[:2], reach)
        key = polygons_key(situation.polygons, self.config.grid_spacing, self.config.grid_margin, region) \
            + f"@{o[0]!r},{o[1]!r}"
        if key not in self._grids:
            # a cached grid of the same chart and origin that covers the region serves as well (a reach that
            # shrinks with the speed would otherwise rebuild - and recompile - the grid at every solve)
            base = polygons_key(situation.polygons, self.config.grid_spacing, self.config.grid_margin) \
                + f"@{o[0]!r},{o[1]!r}"
            for b, reg, k in self._grid_regions:
                if b == base and all(reg[0][i] <= region[0][i] and reg[1][i] >= region[1][i] for i in (0, 1)):
                    return self._grids[k]
            lo, hi = (np.asarray(c, dtype=float) - o for c in region)
            grid = build_distance_grid(shift_polygons(situation.polygons, o), self.config.grid_spacing,
                                       self.config.grid_margin, dtype=np.dtype(self.config.dtype),
                                       region=(tuple(lo), tuple(hi)))
            self._grids[key] = grid._replace(origin=lo + o)
            self._grid_regions.append((base, region, key))
        return self._grids[key]

    def _packed_world(self, situation: Situation) -> WorldArrays:
        """The packed chart about the planner's origin, reused while the situation carries the same polygons
        (content hash), the origin is the same and, in grid mode, so is the distance grid."""
        o = self._origin_for(situation)
        grid = (self.distance_grid(situation)
                if self.config.grounding_mode == "grid" and situation.polygons else None)
        key = polygons_key(situation.polygons, 0.0, 0.0)
        cached = self._world
        if cached is None or cached[0] != key or not np.array_equal(cached[1], o) or cached[2] is not grid:
            cached = (key, o.copy(), grid, pack_world(situation.polygons, self.config, self.capacities, grid,
                                                       origin=o))
            self._world = cached
        return cached[3]

    def init_state(self) -> PlannerState:
        return PlannerState()

    def _params(self, params: Params | None) -> Params:
        """Validated device copy of ``params`` (cached for the planner's own and the last one passed)."""
        params = params or self.params
        if self._device_params is None or self._device_params[0] is not params:
            validate_params(params, self.config, self.behaviours.shape[1])
            self._device_params = (params, jax.device_put(params_as_arrays(params, np.dtype(self.config.dtype))))
        return self._device_params[1]

    def prepare(self, situation: Situation, state: PlannerState | None = None, *, key=None,
                params: Params | None = None) -> tuple[SolveInputs, PlannerState, Params, object]:
        """Validated device inputs ``(inputs, state, params, samples)`` for :func:`psbmpc_jax.solve.solve`,
        positions relative to :attr:`origin` (set here)."""
        if not isinstance(situation, Situation):
            raise ValueError(f"situation must be a psbmpc_jax.Situation, got {type(situation).__name__}")
        state = state or self.init_state()
        if not isinstance(state, PlannerState):
            raise ValueError(f"state must be a PlannerState, got {type(state).__name__}")
        p = self._params(params)
        origin = self._origin_for(situation)
        inputs = pack(situation, self.behaviours, self.config, capacities=self.capacities,
                      world=self._packed_world(situation), behaviour_arrays=self._behaviour_arrays, origin=origin)
        if self.config.estimator != "quadrature" and key is not None:
            checks.prng_key(key, "key")
        self._check_memory(inputs)
        samples = standard_normal_table(key, self.config, np.dtype(self.config.dtype))
        return inputs, state, p, samples

    def _check_memory(self, inputs: SolveInputs) -> None:
        """Refuse a solve whose estimated memory exceeds the limit (:func:`psbmpc_jax.limits.check_solve`), before
        the samples are drawn or anything is compiled; checked once per padded shape."""
        from . import limits

        n_b = int(inputs.behaviours.offsets.shape[0])
        n_os = int(np.prod(np.shape(inputs.obstacles.probs)))
        land = bool(np.shape(inputs.world.polygons.mask)[0]) or bool(np.asarray(inputs.world.grid.active))
        n_mc = max([int(getattr(t, "n_mc", 0) or 0) for t in self.terms] + [0])
        key = (n_b, n_os, land, n_mc)
        if key == self._memory_checked:
            return
        platform = None if self.config.layout_platform == "auto" else self.config.layout_platform
        limits.check_solve(self.config, n_b, n_os, land, n_mc=n_mc, platform=platform,
                           settings={"n_mc": "the Psbmpc2020Term's n_mc"})
        self._memory_checked = key

    def plan(self, situation: Situation, state: PlannerState | None = None, *, refine=None, key=None,
             params: Params | None = None) -> tuple[PlanResult, PlannerState]:
        """Solve once; returns the result and the next planner state (the applied first maneuver).

        ``refine``: a :class:`~psbmpc_jax.refine.RefineSettings` to refine the grid search's plan with the
        smooth DOCP (docs/refine.md); ``result.refined`` is then the :class:`~psbmpc_jax.refine.Refinement`
        (NumPy, trajectory in the user's frame; ``result.refine_time_s`` its wall time) and the next state holds its
        first control (``result.refined.apply``); with ``refine.previous_start`` it also holds the refined
        controls as ``warm_start``, the next refinement's start 1: shift them by the steps that pass before the
        next plan (:func:`psbmpc_jax.numerics.shift_controls`; unshifted they are taken as planned now).
        ``None`` (default): the grid search alone, ``result.refined`` is None.  A refinement whose estimated
        time exceeds the limit (:func:`psbmpc_jax.update_time.check_refine`) is refused with ``ResourceError``
        before the grid search runs."""
        if refine is not None:
            from .refine import RefineSettings

            if not isinstance(refine, RefineSettings):
                raise ValueError(f"refine must be a psbmpc_jax.refine.RefineSettings or None, got "
                                 f"{type(refine).__name__}")
            refine.n_refine(self.config)           # a horizon that does not fit the config: ValueError now
        inputs, state, p, samples = self.prepare(situation, state, key=key, params=params)
        if refine is not None:                     # its time, from the padded shapes, before anything compiles
            from .update_time import check_refine

            check_refine(self.config.n_steps, int(np.prod(np.shape(inputs.obstacles.probs))), refine.n_starts,
                         refine.solver.max_outer, refine.solver.max_inner)
        origin = self.origin
        t0 = time.perf_counter()
        plan, _, ev = solve(inputs, state, p, samples, config=self.config, terms=self.terms)
        status = int(plan.status)                  # waits for the device
        result = unpack(ev, situation, self.behaviours, time.perf_counter() - t0,
                        per_polygon=self.config.grounding_mode == "exact", status=status_name(status),
                        names=self.cost_names, origin=origin)
        if status:                                 # nothing to apply: keep the previous offsets
            return result, state
        if refine is None:
            return result, PlannerState((result.u_opt, result.chi_opt))
        from .refine import refine as run_refine

        t0 = time.perf_counter()
        ref = jax.device_get(run_refine(inputs, plan, state, p, samples, self.config, refine, self.terms,
                                        evaluation=ev))
        result.refine_time_s = time.perf_counter() - t0
        ref = ref._replace(trajectory=np.asarray(ref.trajectory, float) + np.r_[origin, 0.0, 0.0],
                           costs={k: float(v) for k, v in ref.costs.items()})
        result.refined = ref
        u, chi = (float(v) for v in np.asarray(ref.apply, float))
        warm = np.asarray(ref.controls, float) if refine.previous_start else None
        return result, PlannerState((min(max(u, 0.0), 1.0), min(max(chi, -np.pi), np.pi)), warm)


__all__ = ["Planner", "PlannerState", "PlanResult", "COST_TERMS", "RECENTRE_DISTANCE", "check_dtype"]
