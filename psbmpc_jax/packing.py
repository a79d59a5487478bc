"""Host objects <-> device arrays, in one place: capacities, padding, stacking for vmap, and unpacking.

Device inputs of one solve are nested by what they describe (every leaf padded to a capacity, masks mark
the real rows):

* :class:`OwnShipArrays` — state ``[4]``, route ``wx, wy [1, W]`` with ``n [1]`` valid points, ``U_d``,
  ``length``;
* :class:`ObstacleArrays` — ``state [O, 4]``, ``cov [O, 4, 4]``, ``length [O]``, routes ``wx, wy [O, Wo]``
  with ``n [O]``, ``n_ps [O]``, ``probs [O, S]`` (0 in padding), ``weight [O]``, ``zeta [O]``, ``mask [O]``;
* :class:`WorldArrays` — the chart as polygons (:class:`ChartArrays`: ``vertices [P, V, 2]``, ``next [P, V]``
  — the next vertex of the same ring, a polygon holding its outer ring and holes back to back, even-odd
  rule —, ``n [P]`` valid vertex slots = edges, ``mask [P]``) and as a distance grid (:class:`GridArrays`,
  ``active`` False when there is none);
* :class:`BehaviourArrays` — ``offsets [B, n_M, 2]``, ``mask [B]``;

bundled as :class:`SolveInputs`.  Capacities are an argument (:class:`Capacities`); by default they are
bucketed so that a stream of situations with slowly varying sizes compiles a handful of times.

**Local origin** (docs/algorithm.md §11).  Device positions are relative to a local origin ``o`` (north, east
[m], float64 on the host): every position — own-ship state and route, obstacle states and routes, polygon
vertices, the distance grid's corner — is shifted by ``-o`` in float64 *before* the cast to the device dtype,
so float32 keeps millimetre resolution whatever the user's frame (UTM northings are ~7e6 m, where float32
spacing is 0.5 m).  Courses, the wind direction and velocities are unchanged by a translation.
:class:`PlanResult` shifts its trajectories back: everything it returns is in the user's frame.  The origin
is a multiple of :data:`ORIGIN_SNAP` (1 km), so it is exact in both dtypes and nearby situations share it.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .array_types import HostOrDevice
from .distance_grid import DistanceGrid, build_distance_grid
from .edge_blocks import host_blocks, padded_blocks
from .situation import Situation, ring_vertices


# ------------------------------------------------------------------------------------------- device types
class OwnShipArrays(NamedTuple):
    state: HostOrDevice
    wx: HostOrDevice
    wy: HostOrDevice
    n: HostOrDevice
    U_d: HostOrDevice
    length: HostOrDevice


class ObstacleArrays(NamedTuple):
    state: HostOrDevice
    cov: HostOrDevice
    length: HostOrDevice
    wx: HostOrDevice
    wy: HostOrDevice
    n: HostOrDevice
    n_ps: HostOrDevice
    probs: HostOrDevice
    weight: HostOrDevice
    zeta: HostOrDevice
    mask: HostOrDevice
    r18: Any = None             # [O] bool: Rule-18 priority (Obstacle.rule18); None in hand-built inputs
    leg_u: Any = None           # [O, Wo] leg speeds of shared plans (Obstacle.leg_speeds; -1: none)


class ChartArrays(NamedTuple):
    vertices: HostOrDevice
    next: HostOrDevice
    n: HostOrDevice
    mask: HostOrDevice
    #: ``[K, 2]`` int32 (polygon, first edge slot) of the chart's blocks of 32 edges, back to back
    #: (:func:`psbmpc_jax.edge_blocks.host_blocks`); the ``flat`` grounding search reads them.  None: the
    #: content-independent layout (:func:`psbmpc_jax.edge_blocks.padded_blocks`), correct but more work.
    blocks: HostOrDevice | None = None


class GridArrays(NamedTuple):
    values: HostOrDevice
    origin: HostOrDevice
    spacing: HostOrDevice
    margin: HostOrDevice
    active: HostOrDevice

    def distance_grid(self) -> DistanceGrid:
        return DistanceGrid(self.values, self.origin, self.spacing, self.margin)


class WorldArrays(NamedTuple):
    polygons: ChartArrays
    grid: GridArrays


class BehaviourArrays(NamedTuple):
    offsets: HostOrDevice
    mask: HostOrDevice


class SolveInputs(NamedTuple):
    """Padded device inputs of one solve (see the module docstring for every field)."""

    own: OwnShipArrays
    obstacles: ObstacleArrays
    world: WorldArrays
    behaviours: BehaviourArrays


# ------------------------------------------------------------------------------------------- capacities
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
class Capacities:
    """Padded sizes of the device inputs: obstacles O, scenarios S, own-route waypoints W, obstacle-route
    waypoints Wo, polygons P, vertices per polygon V, behaviours B.  ``None`` = bucketed from the data."""

    obstacles: int | None = None
    scenarios: int | None = None
    waypoints: int | None = None
    obstacle_waypoints: int | None = None
    polygons: int | None = None
    vertices: int | None = None
    behaviours: int | None = None

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if v is not None and (isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0):
                raise ValueError(f"Capacities.{f.name} must be an integer >= 0 or None, got {v!r}")


def _capacity(given, needed: int, default: int, what: str) -> int:
    if given is None:
        return default
    if given < needed:
        raise ValueError(f"Capacities.{what} = {given} is too small: this situation needs {needed}")
    return int(given)


# ------------------------------------------------------------------------------------------- local origin
#: Local origins are multiples of this [m]: exact in float32 and float64, and shared by nearby situations.
ORIGIN_SNAP = 1000.0


def snap_origin(position) -> np.ndarray:
    """The multiple of :data:`ORIGIN_SNAP` nearest to ``position`` (north, east) [m], float64 ``[2]``."""
    p = np.asarray(position, dtype=np.float64).reshape(2)
    if not np.all(np.isfinite(p)):
        raise ValueError(f"origin position must be two finite numbers (north, east), got {position!r}")
    return np.round(p / ORIGIN_SNAP) * ORIGIN_SNAP


def default_origin(situation: Situation) -> np.ndarray:
    """The local origin :func:`pack` and :func:`unpack` use when none is given: the centre of the polygons'
    bounding box when the situation has polygons, else the own-ship position, snapped to :data:`ORIGIN_SNAP`.

    Chart first: every solve over one chart then shares one origin and so one packed world, which
    :func:`stack` (``vmap`` over solves, the simulator's batch mode) requires; without polygons the packed world
    holds no positions and per-solve origins are harmless."""
    if situation.polygons:
        pts = np.concatenate([ring_vertices(poly)[0] for poly in situation.polygons])
        return snap_origin(0.5 * (pts.min(axis=0) + pts.max(axis=0)))
    return snap_origin(situation.own_ship.state[:2])


def _origin(origin) -> np.ndarray:
    """A validated origin: ``None`` -> (0, 0), else two finite numbers as float64 ``[2]``."""
    if origin is None:
        return np.zeros(2)
    o = np.asarray(origin, dtype=np.float64)
    if o.shape != (2,) or not np.all(np.isfinite(o)):
        raise ValueError(f"origin must be two finite numbers (north, east) [m], got {origin!r}")
    return o


def _obstacle_route(ob, horizon: float) -> np.ndarray:
    """The route an obstacle is predicted along: its waypoints, or a straight line along its velocity."""
    if ob.waypoints is not None:
        return ob.waypoints
    speed = float(np.hypot(ob.state[2], ob.state[3]))
    course = float(np.arctan2(ob.state[3], ob.state[2]))
    length = max(2.0 * speed * horizon, 1000.0)
    p0 = ob.state[:2]
    return np.stack([p0, p0 + length * np.array([np.cos(course), np.sin(course)])])


def shift_polygons(polygons, origin) -> tuple:
    """``polygons`` (rings or ring tuples) with ``origin`` subtracted from every vertex, in float64."""
    o = _origin(origin)
    out = []
    for poly in polygons:
        if isinstance(poly, tuple):
            out.append(tuple(np.asarray(r, dtype=np.float64) - o for r in poly))
        else:
            out.append(np.asarray(poly, dtype=np.float64) - o)
    return tuple(out)


def pack_world(polygons, config, capacities: Capacities | None = None,
               grid: DistanceGrid | None = None, origin=None) -> WorldArrays:
    """The chart part of the inputs: padded polygons and, in grid mode, the distance grid (built here from
    ``polygons`` unless given).

    ``polygons`` and ``grid`` are in the user's frame; the packed world is relative to ``origin`` (default
    (0, 0): no shift), subtracted in float64 before the cast to ``config.dtype``.  A grid built here is built
    from the shifted polygons (its distances are computed near the origin, at full precision)."""
    caps = capacities or Capacities()
    dtype = np.dtype(config.dtype)
    o = _origin(origin)
    polygons = shift_polygons(polygons, o) if np.any(o != 0) else tuple(polygons)
    polys = [ring_vertices(poly) for poly in polygons]
    p_cap = _capacity(caps.polygons, len(polys), bucket(len(polys), 0), "polygons")
    n_v = max([len(v) for v, _ in polys], default=4)
    v_cap = max(_capacity(caps.vertices, n_v, bucket(n_v, 4), "vertices"), 3)
    poly_v = np.zeros((p_cap, v_cap, 2))
    poly_next = np.tile((np.arange(v_cap) + 1) % 3, (p_cap, 1)).astype(np.int32)
    poly_n = np.full(p_cap, 3, dtype=np.int32)
    poly_mask = np.zeros(p_cap, dtype=bool)
    for j, (verts, nxt) in enumerate(polys):   # rings back to back, each closing on itself
        n = len(verts)
        poly_v[j, :n], poly_next[j, :n], poly_next[j, n:] = verts, nxt, 0
        poly_n[j], poly_mask[j] = n, True
    if config.grounding_mode == "grid" and polys:
        if grid is None:
            grid = build_distance_grid(polygons, config.grid_spacing, config.grid_margin, dtype=dtype)
            grid_origin = np.asarray(grid.origin, np.float64)            # built in the local frame
        else:
            grid_origin = np.asarray(grid.origin, np.float64) - o        # the user's grid: shift its corner
        grid_arrays = GridArrays(grid.values, np.asarray(grid_origin, dtype), np.asarray(grid.spacing, dtype),
                                 np.asarray(grid.margin, dtype), np.asarray(True))
    else:  # placeholder (exact mode, or no land at all)
        grid_arrays = GridArrays(np.zeros((2, 2), dtype), np.zeros(2, dtype), np.asarray(1.0, dtype),
                                 np.asarray(config.grid_margin, dtype), np.asarray(False))
    if caps.polygons is not None and caps.vertices is not None:   # fixed capacities: a content-free block count
        blocks = padded_blocks(p_cap, v_cap)
    else:
        blocks = host_blocks([len(v) for v, _ in polys], p_cap, v_cap)
    return WorldArrays(ChartArrays(poly_v.astype(dtype), poly_next, poly_n, poly_mask, blocks), grid_arrays)


def pack_behaviours(behaviours, config, capacities: Capacities | None = None) -> BehaviourArrays:
    """The behaviour table padded to its capacity with masked copies of behaviour 0."""
    caps = capacities or Capacities()
    behaviours = np.asarray(behaviours, dtype=float)
    b = len(behaviours)
    b_cap = _capacity(caps.behaviours, b, bucket_behaviours(b), "behaviours")
    beh = np.concatenate([behaviours, np.repeat(behaviours[:1], b_cap - b, axis=0)])
    return BehaviourArrays(beh.astype(np.dtype(config.dtype)), np.arange(b_cap) < b)


def pack(situation: Situation, behaviours: np.ndarray, config, *, capacities: Capacities | None = None,
         grid: DistanceGrid | None = None, world: WorldArrays | None = None,
         behaviour_arrays: BehaviourArrays | None = None, origin=None) -> SolveInputs:
    """Validated host objects -> padded inputs (NumPy leaves of the dtype of ``config``; the distance grid stays
    on the device), ready for the jitted :func:`~psbmpc_jax.solve.solve`.

    In ``grounding_mode="grid"`` the nearest-land distance grid of ``situation.polygons`` is used: pass it as
    ``grid`` (in the user's frame; :class:`~psbmpc_jax.planner.Planner` builds and caches it), otherwise it is
    built here.  ``world`` / ``behaviour_arrays``: already packed chart and table (:func:`pack_world`,
    :func:`pack_behaviours`) to reuse — the planner caches them, they rarely change between solves.

    ``origin``: the local origin (north, east) [m] of the device frame (module docstring); default
    :func:`default_origin`.  Pass the same origin to :func:`unpack`.  With ``world`` the origin that world was
    packed with is required."""
    if not isinstance(situation, Situation):
        raise ValueError(f"situation must be a psbmpc_jax.Situation, got {type(situation).__name__}")
    caps = capacities or Capacities()
    if not isinstance(caps, Capacities):
        raise ValueError(f"capacities must be a psbmpc_jax.Capacities, got {type(caps).__name__}")
    if world is not None and origin is None:
        raise ValueError("pack(world=...) needs the origin that world was packed with (origin=...)")
    o = default_origin(situation) if origin is None else _origin(origin)
    dtype = np.dtype(config.dtype)
    own = situation.own_ship
    own_state = np.array(own.state, dtype=np.float64)
    own_state[:2] -= o
    n_w = len(own.waypoints)
    w_cap = _capacity(caps.waypoints, n_w, bucket(n_w, 2), "waypoints")
    own_w = np.zeros((1, w_cap, 2))
    own_w[0, :n_w] = own.waypoints - o

    obstacles = situation.obstacles
    o_cap = max(_capacity(caps.obstacles, len(obstacles), bucket(len(obstacles), 1), "obstacles"), 1)
    n_s = max([ob.n_ps for ob in obstacles], default=1)
    s_cap = _capacity(caps.scenarios, n_s, bucket_scenarios(n_s), "scenarios")
    routes = [_obstacle_route(ob, config.T) for ob in obstacles]
    n_wo = max([len(r) for r in routes], default=2)
    wo_cap = _capacity(caps.obstacle_waypoints, n_wo, bucket(n_wo, 2), "obstacle_waypoints")
    obs_state = np.zeros((o_cap, 4))
    obs_cov = np.tile(np.eye(4), (o_cap, 1, 1))
    obs_length = np.ones(o_cap)
    obs_w = np.zeros((o_cap, wo_cap, 2))
    obs_w[:, 1, 0] = 1.0                                   # harmless default route for padding rows
    obs_n = np.full(o_cap, 2, dtype=np.int32)
    obs_n_ps = np.ones(o_cap, dtype=np.int32)
    obs_probs = np.zeros((o_cap, s_cap))
    obs_weight, obs_zeta = np.zeros(o_cap), np.zeros(o_cap)
    obs_mask = np.zeros(o_cap, dtype=bool)
    obs_r18 = np.zeros(o_cap, dtype=bool)
    obs_leg = np.full((o_cap, wo_cap), -1.0)
    for i, (ob, route) in enumerate(zip(obstacles, routes)):
        obs_r18[i] = ob.rule18
        if ob.leg_speeds is not None:
            obs_leg[i, : len(ob.leg_speeds)] = ob.leg_speeds
        obs_state[i], obs_cov[i], obs_length[i] = ob.state, ob.cov, ob.length
        obs_state[i, :2] -= o
        obs_w[i, : len(route)], obs_n[i] = route - o, len(route)
        obs_n_ps[i] = ob.n_ps
        obs_probs[i, : ob.n_ps] = ob.probs
        obs_weight[i], obs_zeta[i], obs_mask[i] = ob.weight, ob.zeta, True

    f = lambda a: np.asarray(a, dtype)
    i32 = lambda a: np.asarray(a, np.int32)
    # host (NumPy) leaves: the jitted solve transfers them in its C++ dispatch path, much cheaper per array
    # than a Python-side jax.device_put (measured in benchmarks/bench_solve.py)
    return SolveInputs(
        own=OwnShipArrays(f(own_state), f(own_w[..., 0]), f(own_w[..., 1]), i32([n_w]), f(own.U_d),
                          f(own.length)),
        obstacles=ObstacleArrays(f(obs_state), f(obs_cov), f(obs_length), f(obs_w[..., 0]), f(obs_w[..., 1]),
                                 i32(obs_n), i32(obs_n_ps), f(obs_probs), f(obs_weight), f(obs_zeta), obs_mask,
                                 obs_r18, f(obs_leg)),
        world=world if world is not None else pack_world(situation.polygons, config, caps, grid, origin=o),
        behaviours=(behaviour_arrays if behaviour_arrays is not None
                    else pack_behaviours(behaviours, config, caps)),
    )


# ------------------------------------------------------------------------------------------- batching
#: Inputs every solve of one batch shares (one chart, one grid, one behaviour table): vmap broadcasts them
#: (``in_axes=None``) instead of stacking a copy per solve (the Nidelva grid alone is ~16 MB).
SHARED_AXES = SolveInputs._make((0, 0, None, None))      # (own, obstacles, world, behaviours): an axes spec


def stack(items) -> SolveInputs:
    """Stack packed inputs along a new leading axis for ``vmap(..., in_axes=SHARED_AXES)``: waypoint
    capacities are padded to the largest (padding waypoints never enter the guidance); the world and the
    behaviour table are taken from the first item (their shapes must agree, as they do for all solves of
    one MPC update)."""
    items = list(items)
    if not items:
        raise ValueError("stack needs at least one packed input")
    for part in ("world", "behaviours"):
        shapes = {tuple(a.shape for a in jax.tree.leaves(getattr(x, part))) for x in items}
        if len(shapes) > 1:
            raise ValueError(f"stack: the inputs must share their {part} (chart, grid, behaviours), got "
                             f"different shapes")
    w_own = max(x.own.wx.shape[-1] for x in items)
    w_obs = max(x.obstacles.wx.shape[-1] for x in items)

    def widen(a, w):
        return a if a.shape[-1] == w else jnp.pad(a, [(0, 0)] * (a.ndim - 1) + [(0, w - a.shape[-1])],
                                                  mode="edge")

    own = [x.own._replace(wx=widen(x.own.wx, w_own), wy=widen(x.own.wy, w_own)) for x in items]
    obs = [x.obstacles._replace(wx=widen(x.obstacles.wx, w_obs), wy=widen(x.obstacles.wy, w_obs),
                                leg_u=None if x.obstacles.leg_u is None else widen(x.obstacles.leg_u, w_obs))
           for x in items]
    stack_ = lambda trees: jax.tree.map(lambda *a: jnp.stack(a), *trees)
    return SolveInputs(stack_(own), stack_(obs), items[0].world, items[0].behaviours)


def pad_behaviours(inputs: SolveInputs, multiple: int) -> SolveInputs:
    """Pad the behaviour axis to a multiple of ``multiple`` with masked copies of behaviour 0."""
    beh = np.asarray(inputs.behaviours.offsets)
    mask = np.asarray(inputs.behaviours.mask)
    n_pad = -beh.shape[0] % multiple
    if n_pad:
        beh = np.concatenate([beh, np.repeat(beh[:1], n_pad, axis=0)])
        mask = np.concatenate([mask, np.zeros(n_pad, dtype=mask.dtype)])
    return inputs._replace(behaviours=BehaviourArrays(jnp.asarray(beh, inputs.behaviours.offsets.dtype),
                                                      jnp.asarray(mask)))




# ------------------------------------------------------------------------------------------- unpacking
class PlanResult:
    """Result of one solve (NumPy, unpadded), fetched from the device lazily: the decision on construction,
    the cost table, trajectories and per-scenario details on first access (then kept).

    Attributes:
        best_index: index of the chosen behaviour in the planner's behaviour table.
        offsets: its maneuver sequence ``[n_M, 2]`` (speed factor, course offset rad).
        u_opt, chi_opt: the first maneuver, to apply as U_c = u_opt U_d, chi_c = chi_opt + chi_d.
        status: ``"ok"`` or why the plan is meaningless (``"no finite behaviour"``).
        costs: per-behaviour cost terms ``{"total", <term names>} -> [B]`` (default terms: do, colregs, so,
            path).
        collision_cost, colregs_indicator: per obstacle ``[B, n_ps_i]`` arrays (C_s^{l,i}, mu_s^{l,i}).
        grounding_per_polygon: ``[B, n_so]`` (``[B, 0]`` in grid mode, which only knows the nearest land).
        own_trajectories: ``[B, N+1, 4]`` (x, y, chi, U); obstacle_trajectories: per obstacle
            ``[n_ps_i, N+1, 4]``; both in the user's frame (the device's local frame shifted back by
            ``origin``).
        origin: the local origin (north, east) [m] the solve ran about (module docstring).
        n_pc_blocks: (row, time-block) pairs evaluated by the collision-probability estimator.
        solve_time_s: wall time of the device call (including the transfer of the cost table).
        behaviours: the behaviour table ``[B, n_M, 2]``.
        refined, refine_time_s: the gradient refinement's result (:class:`psbmpc_jax.refine.Refinement`,
            host arrays in the user's frame) and its wall time [s] when :meth:`psbmpc_jax.Planner.plan` ran it
            (``refine=...``), else None.
    """

    def __init__(self, ev, situation: Situation, behaviours: np.ndarray, solve_time: float, *,
                 per_polygon: bool = True, status: str = "ok", names=None, origin=None):
        self.best_index = int(ev.best)
        self.origin = default_origin(situation) if origin is None else _origin(origin)
        self.offsets = np.array(behaviours[self.best_index], dtype=float)   # exact host values
        self._names = names
        self.behaviours = behaviours
        self.solve_time_s = solve_time
        self.status = status
        self._ev, self._situation, self._per_polygon = ev, situation, per_polygon
        self._cache: dict = {}
        self.refined: Any = None                   # a Refinement (refine.py imports this module, not back)
        self.refine_time_s: float | None = None

    def __repr__(self) -> str:
        return (f"PlanResult(best_index={self.best_index}, offsets={self.offsets.tolist()}, status={self.status!r}, "
                f"solve_time_s={self.solve_time_s:.4f})")

    def _get(self, name, build):
        if name not in self._cache:
            self._cache[name] = build()
        return self._cache[name]

    @property
    def costs(self) -> dict:
        """Per-behaviour cost columns ``{"total", <term names>} -> [B]``, in the terms' order."""
        def build():
            b = len(self.behaviours)
            total, costs = jax.device_get((self._ev.total, self._ev.costs))
            # pytrees sort dict keys: restore the terms' order ("total" first)
            order = [n for n in (self._names or ("total", *costs)) if n != "total"]
            out = {"total": np.asarray(total, float)[:b]}
            out.update({k: np.asarray(costs[k], float)[:b] for k in order})
            return out
        return self._get("costs", build)

    @property
    def u_opt(self) -> float:
        return float(self.offsets[0, 0])

    @property
    def chi_opt(self) -> float:
        return float(self.offsets[0, 1])

    @property
    def n_pc_blocks(self) -> int:
        return self._get("n_pc_blocks", lambda: int(self._ev.n_pc_blocks))

    @property
    def collision_cost(self) -> list:
        b, obs = len(self.behaviours), self._situation.obstacles
        return self._get("C", lambda: [np.asarray(self._ev.C[:b, i, : ob.n_ps], float) for i, ob in enumerate(obs)])

    @property
    def colregs_indicator(self) -> list:
        b, obs = len(self.behaviours), self._situation.obstacles
        return self._get("mu", lambda: [np.asarray(self._ev.mu[:b, i, : ob.n_ps], float) for i, ob in enumerate(obs)])

    @property
    def grounding_per_polygon(self) -> np.ndarray:
        b, n_so = len(self.behaviours), len(self._situation.polygons)
        return self._get("so_j", lambda: np.asarray(self._ev.so_j[:b, :n_so], float) if self._per_polygon
                         else np.zeros((b, 0)))

    @property
    def own_trajectories(self) -> np.ndarray:
        # device trajectories are time-major ([T, B]); results are row-major
        def build():
            own = jax.device_get(self._ev.own)
            out = np.stack([own.x, own.y, own.chi, own.U], axis=-1).swapaxes(0, 1)[: len(self.behaviours)] \
                .astype(float)
            out[..., :2] += self.origin
            return out
        return self._get("own", build)

    @property
    def obstacle_trajectories(self) -> list:
        def build():
            o = jax.device_get(self._ev.obstacles)
            obs = np.moveaxis(np.stack([o.x, o.y, o.chi, o.U], axis=-1), 0, 2).astype(float)
            obs[..., :2] += self.origin
            return [obs[i, : ob.n_ps] for i, ob in enumerate(self._situation.obstacles)]
        return self._get("obs", build)

    def ranking(self, k: int = 5) -> list[dict]:
        """The k cheapest behaviours with their cost breakdown (course offsets in degrees)."""
        order = np.argsort(self.costs["total"], kind="stable")[:k]
        rows = []
        for b in order:
            row = {"index": int(b),
                   "maneuvers": [(float(u), float(np.rad2deg(c))) for u, c in self.behaviours[b]]}
            row.update({term: float(v[b]) for term, v in self.costs.items()})
            rows.append(row)
        return rows


def unpack(ev, situation: Situation, behaviours: np.ndarray, solve_time: float, per_polygon: bool = True,
           status: str = "ok", names=None, origin=None) -> PlanResult:
    """Device output (padded :class:`~psbmpc_jax.evaluate.Evaluation`) -> host :class:`PlanResult`
    (unpadded).  ``per_polygon=False`` (grid mode): there are no per-polygon grounding costs, ``costs["so"]``
    is the cost of the nearest land.  ``names``: the cost columns in order (``("total",) + term names``).
    ``origin``: the one the inputs were packed with (default :func:`default_origin`, as :func:`pack`)."""
    return PlanResult(ev, situation, behaviours, solve_time, per_polygon=per_polygon, status=status, names=names,
                      origin=origin)


__all__ = ["SolveInputs", "OwnShipArrays", "ObstacleArrays", "WorldArrays", "ChartArrays", "GridArrays",
           "BehaviourArrays", "Capacities", "pack", "pack_world", "shift_polygons", "default_origin", "snap_origin",
           "ORIGIN_SNAP", "pack_behaviours", "stack", "pad_behaviours", "SHARED_AXES", "bucket",
           "bucket_scenarios", "bucket_behaviours", "PlanResult", "unpack"]
