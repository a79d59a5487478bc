"""Host-side API: validate, pack into bucketed device arrays, call the jitted evaluator, unpack.

>>> planner = Planner()                                   # paper defaults, 1014 behaviours
>>> result, state = planner.plan(situation, state)        # state carries the last applied offsets

Shapes are bucketed (obstacles, scenarios, waypoints, polygons, vertices, behaviours) so that a stream of
situations with slowly varying sizes compiles a handful of times; values never recompile.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np

from .behaviours import paper_behaviours, validate_behaviours
from .costs.collision import standard_normal_table
from .distance_grid import DistanceGrid, build_distance_grid, polygons_key, reach_region
from .evaluate import Evaluation, SituationArrays, evaluate
from .params import Params, PlannerConfig, params_as_arrays, validate_params
from .problem import Situation, ring_vertices

COST_TERMS = ("total", "do", "colregs", "so", "path")


def bucket(n: int, minimum: int = 1) -> int:
    """Smallest power of two >= max(n, minimum) (0 stays 0 when minimum is 0)."""
    n = max(int(n), minimum)
    return 0 if n == 0 else 1 << (n - 1).bit_length()


def bucket_scenarios(n: int) -> int:
    """Scenario capacity: exact for odd n <= 9 (the common cases), else a multiple of 8."""
    return n if n <= 9 else -(-n // 8) * 8


def bucket_behaviours(n: int) -> int:
    """Behaviour capacity: a multiple of 64 (1014 -> 1024)."""
    return -(-n // 64) * 64


@dataclass(frozen=True)
class PlannerState:
    """Planner memory between solves: the offsets (u, chi) applied after the previous solve."""

    last_offsets: tuple[float, float] = (1.0, 0.0)

    def __post_init__(self) -> None:
        u, chi = (float(v) for v in self.last_offsets)
        if not (np.isfinite(u) and np.isfinite(chi)) or not 0 <= u <= 1 or abs(chi) > np.pi + 1e-12:
            raise ValueError(
                f"PlannerState.last_offsets must be (u in [0, 1], chi in [-pi, pi] rad), got {self.last_offsets}"
            )
        object.__setattr__(self, "last_offsets", (u, chi))


@dataclass
class PlanResult:
    """Result of one solve (NumPy, unpadded).

    Attributes:
        best_index: index of the chosen behaviour in the planner's behaviour table.
        offsets: its maneuver sequence ``[n_M, 2]`` (speed factor, course offset rad).
        u_opt, chi_opt: the first maneuver, to apply as U_c = u_opt U_d, chi_c = chi_opt + chi_d.
        costs: per-behaviour cost terms ``{"total", "do", "colregs", "so", "path"} -> [B]``.
        collision_cost, colregs_indicator: per obstacle ``[B, n_ps_i]`` arrays (C_s^{l,i}, mu_s^{l,i}).
        grounding_per_polygon: ``[B, n_so]`` (``[B, 0]`` in grid mode, which only knows the nearest land).
        own_trajectories: ``[B, N+1, 4]`` (x, y, chi, U); obstacle_trajectories: per obstacle
            ``[n_ps_i, N+1, 4]``.
        n_pc_blocks: (row, time-block) pairs evaluated by the collision-probability estimator.
        solve_time_s: wall time of the device call (including transfer back).
    """

    best_index: int
    offsets: np.ndarray
    costs: dict
    collision_cost: list
    colregs_indicator: list
    grounding_per_polygon: np.ndarray
    own_trajectories: np.ndarray
    obstacle_trajectories: list
    n_pc_blocks: int
    solve_time_s: float
    behaviours: np.ndarray = field(repr=False, default=None)

    @property
    def u_opt(self) -> float:
        return float(self.offsets[0, 0])

    @property
    def chi_opt(self) -> float:
        return float(self.offsets[0, 1])

    def ranking(self, k: int = 5) -> list[dict]:
        """The k cheapest behaviours with their cost breakdown (course offsets in degrees)."""
        order = np.argsort(self.costs["total"], kind="stable")[:k]
        rows = []
        for b in order:
            row = {"index": int(b),
                   "maneuvers": [(float(u), float(np.rad2deg(c))) for u, c in self.behaviours[b]]}
            row.update({term: float(self.costs[term][b]) for term in COST_TERMS})
            rows.append(row)
        return rows


def pack_situation(situation: Situation, behaviours: np.ndarray, state: PlannerState,
                   config: PlannerConfig, grid: DistanceGrid | None = None) -> SituationArrays:
    """Validated host objects -> bucketed, padded device arrays (dtype of ``config``).

    In ``grounding_mode="grid"`` the nearest-land distance grid of ``situation.polygons`` is needed:
    pass it as ``grid`` (built with :func:`~psbmpc_jax.distance_grid.build_distance_grid`; the
    :class:`Planner` builds and caches it), otherwise it is built here."""
    if not isinstance(situation, Situation):
        raise ValueError(f"situation must be a psbmpc_jax.Situation, got {type(situation).__name__}")
    dtype = np.dtype(config.dtype)
    own = situation.own_ship
    w_cap = bucket(len(own.waypoints), 2)
    own_w = np.zeros((1, w_cap, 2))
    own_w[0, : len(own.waypoints)] = own.waypoints

    obstacles = situation.obstacles
    o_cap = bucket(len(obstacles), 1)
    s_cap = bucket_scenarios(max([ob.n_ps for ob in obstacles], default=1))
    routes = []
    for ob in obstacles:
        if ob.waypoints is not None:
            routes.append(ob.waypoints)
        else:
            speed = float(np.hypot(ob.state[2], ob.state[3]))
            course = float(np.arctan2(ob.state[3], ob.state[2]))
            length = max(2.0 * speed * config.T, 1000.0)
            p0 = ob.state[:2]
            routes.append(np.stack([p0, p0 + length * np.array([np.cos(course), np.sin(course)])]))
    wo_cap = bucket(max([len(r) for r in routes], default=2), 2)
    obs_state = np.zeros((o_cap, 4))
    obs_cov = np.tile(np.eye(4), (o_cap, 1, 1))
    obs_length = np.ones(o_cap)
    obs_w = np.zeros((o_cap, wo_cap, 2))
    obs_w[:, 1, 0] = 1.0                                   # harmless default route for padding rows
    obs_n = np.full(o_cap, 2, dtype=np.int32)
    obs_n_ps = np.ones(o_cap, dtype=np.int32)
    obs_probs = np.zeros((o_cap, s_cap))
    obs_weight = np.zeros(o_cap)
    obs_zeta = np.zeros(o_cap)
    obs_mask = np.zeros(o_cap, dtype=bool)
    for i, (ob, route) in enumerate(zip(obstacles, routes)):
        obs_state[i], obs_cov[i], obs_length[i] = ob.state, ob.cov, ob.length
        obs_w[i, : len(route)], obs_n[i] = route, len(route)
        obs_n_ps[i] = ob.n_ps
        obs_probs[i, : ob.n_ps] = ob.probs
        obs_weight[i], obs_zeta[i], obs_mask[i] = ob.weight, ob.zeta, True

    polys = [ring_vertices(poly) for poly in situation.polygons]
    p_cap = bucket(len(polys), 0)
    v_cap = bucket(max([len(v) for v, _ in polys], default=4), 4)
    poly_v = np.zeros((p_cap, v_cap, 2))
    poly_next = np.tile((np.arange(v_cap) + 1) % 3, (p_cap, 1)).astype(np.int32)
    poly_n = np.full(p_cap, 3, dtype=np.int32)
    poly_mask = np.zeros(p_cap, dtype=bool)
    for j, (verts, nxt) in enumerate(polys):   # rings back to back, each closing on itself
        n = len(verts)
        poly_v[j, :n], poly_next[j, :n], poly_next[j, n:] = verts, nxt, 0
        poly_n[j], poly_mask[j] = n, True

    b = len(behaviours)
    b_cap = bucket_behaviours(b)
    beh = np.concatenate([behaviours, np.repeat(behaviours[:1], b_cap - b, axis=0)])
    beh_mask = np.arange(b_cap) < b

    f = lambda a: jnp.asarray(a, dtype)
    i32 = lambda a: jnp.asarray(a, jnp.int32)
    if config.grounding_mode == "grid" and situation.polygons:
        if grid is None:
            grid = build_distance_grid(situation.polygons, config.grid_spacing, config.grid_margin, dtype=dtype)
        grid_fields = dict(grid_values=f(grid.values), grid_origin=f(grid.origin), grid_spacing=f(grid.spacing),
                           grid_margin=f(grid.margin), grid_active=jnp.asarray(True))
    else:  # placeholder (exact mode, or no land at all)
        grid_fields = dict(grid_values=f(np.zeros((2, 2))), grid_origin=f(np.zeros(2)), grid_spacing=f(1.0),
                           grid_margin=f(config.grid_margin), grid_active=jnp.asarray(False))
    return SituationArrays(
        own_state=f(own.state), own_wx=f(own_w[..., 0]), own_wy=f(own_w[..., 1]),
        own_n=i32([len(own.waypoints)]), U_d=f(own.U_d), own_length=f(own.length),
        obs_state=f(obs_state), obs_cov=f(obs_cov), obs_length=f(obs_length), obs_wx=f(obs_w[..., 0]),
        obs_wy=f(obs_w[..., 1]), obs_n=i32(obs_n), obs_n_ps=i32(obs_n_ps), obs_probs=f(obs_probs),
        obs_weight=f(obs_weight), obs_zeta=f(obs_zeta), obs_mask=jnp.asarray(obs_mask),
        poly_vertices=f(poly_v), poly_next=i32(poly_next), poly_n=i32(poly_n), poly_mask=jnp.asarray(poly_mask),
        **grid_fields,
        behaviours=f(beh), beh_mask=jnp.asarray(beh_mask), last_offsets=f(state.last_offsets),
    )


def check_dtype(config: PlannerConfig) -> None:
    if config.dtype == "float64" and not jax.config.jax_enable_x64:
        raise ValueError(
            "PlannerConfig.dtype='float64' needs 64-bit JAX: call jax.config.update('jax_enable_x64', True) "
            "before building arrays (or use dtype='float32')"
        )


def unpack(ev: Evaluation, situation: Situation, behaviours: np.ndarray, solve_time: float,
           per_polygon: bool = True) -> PlanResult:
    """Device output (padded) -> host :class:`PlanResult` (unpadded).  ``per_polygon=False`` (grid mode):
    there are no per-polygon grounding costs, ``costs["so"]`` is the cost of the nearest land."""
    ev = jax.device_get(ev)
    b = len(behaviours)
    obstacles = situation.obstacles
    # device trajectories are time-major ([T, B] and [T, O, S]); results are row-major
    own = np.stack([ev.own.x, ev.own.y, ev.own.chi, ev.own.U], axis=-1).swapaxes(0, 1)[:b].astype(float)
    obs = np.moveaxis(np.stack([ev.obstacles.x, ev.obstacles.y, ev.obstacles.chi, ev.obstacles.U], axis=-1),
                      0, 2).astype(float)
    return PlanResult(
        best_index=int(ev.best),
        offsets=np.array(behaviours[int(ev.best)], dtype=float),   # exact host values, not dtype-rounded
        costs={term: np.asarray(getattr(ev, term), dtype=float)[:b] for term in COST_TERMS},
        collision_cost=[np.asarray(ev.C[:b, i, : ob.n_ps], float) for i, ob in enumerate(obstacles)],
        colregs_indicator=[np.asarray(ev.mu[:b, i, : ob.n_ps], float) for i, ob in enumerate(obstacles)],
        grounding_per_polygon=(np.asarray(ev.so_j[:b, : len(situation.polygons)], float) if per_polygon
                               else np.zeros((b, 0))),
        own_trajectories=own,
        obstacle_trajectories=[obs[i, : ob.n_ps] for i, ob in enumerate(obstacles)],
        n_pc_blocks=int(ev.n_pc_blocks),
        solve_time_s=solve_time,
        behaviours=behaviours,
    )


class Planner:
    """PSB-MPC planner: a behaviour table, static config and parameter values.

    Args:
        config: :class:`PlannerConfig` (static: horizon, estimator, dtype, ...).
        params: :class:`Params` (values; may also be passed per call).
        behaviours: ``[B, n_M, 2]`` table; default the paper's 1014 (n_M = 2).
    """

    def __init__(self, config: PlannerConfig | None = None, params: Params | None = None, behaviours=None):
        self.config = config or PlannerConfig()
        if not isinstance(self.config, PlannerConfig):
            raise ValueError(f"config must be a PlannerConfig, got {type(self.config).__name__}")
        check_dtype(self.config)
        self.params = params or Params()
        validate_params(self.params)
        self.behaviours = validate_behaviours(paper_behaviours(2) if behaviours is None else behaviours)
        self._grids: dict[str, DistanceGrid] = {}

    def distance_grid(self, situation: Situation) -> DistanceGrid:
        """The nearest-land grid for grid mode, covering everywhere the own-ship can reach in one horizon.

        No predicted position is farther than max(U_0, U_d)·T from the own-ship (speed references never
        exceed U_d and the speed lag is monotone), so the grid covers that disc; grids are cached per
        chart and (snapped) region and rebuilt only when the own-ship moves out of them."""
        own = situation.own_ship
        reach = max(float(own.state[3]), float(own.U_d)) * self.config.T + 10.0
        region = reach_region(own.state[:2], reach)
        key = polygons_key(situation.polygons, self.config.grid_spacing, self.config.grid_margin, region)
        if key not in self._grids:
            self._grids[key] = build_distance_grid(situation.polygons, self.config.grid_spacing,
                                                   self.config.grid_margin, dtype=np.dtype(self.config.dtype),
                                                   region=region)
        return self._grids[key]

    def init_state(self) -> PlannerState:
        return PlannerState()

    def prepare(self, situation: Situation, state: PlannerState | None = None, *, key=None,
                params: Params | None = None):
        """Validated, packed device inputs ``(arrays, params, samples)`` for :func:`evaluate`."""
        state = state or self.init_state()
        if not isinstance(state, PlannerState):
            raise ValueError(f"state must be a PlannerState, got {type(state).__name__}")
        params = params or self.params
        validate_params(params)
        dtype = np.dtype(self.config.dtype)
        grid = (self.distance_grid(situation)
                if self.config.grounding_mode == "grid" and situation.polygons else None)
        arrays = pack_situation(situation, self.behaviours, state, self.config, grid)
        samples = standard_normal_table(key, self.config, dtype)
        return arrays, params_as_arrays(params, dtype), samples

    def plan(self, situation: Situation, state: PlannerState | None = None, *, key=None,
             params: Params | None = None) -> tuple[PlanResult, PlannerState]:
        """Solve once; returns the result and the next planner state (the applied first maneuver)."""
        arrays, p, samples = self.prepare(situation, state, key=key, params=params)
        t0 = time.perf_counter()
        ev = evaluate(arrays, p, samples, config=self.config)
        jax.block_until_ready(ev)
        result = unpack(ev, situation, self.behaviours, time.perf_counter() - t0,
                        per_polygon=self.config.grounding_mode == "exact")
        return result, PlannerState((result.u_opt, result.chi_opt))
