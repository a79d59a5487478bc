"""N_TP of the initialisation stage (Mahipala & Johansen 2024, Sec. VI, Fig. 5): the index of the first trajectory
point that collides with land.

A collision occurs at point j of a trajectory ``Ψ̄ [N+1, 2]`` (north, east) if

(a) the disc of radius ``r_dom`` around Ψ̄_j meets land: the exact distance to some polygon is ≤ r_dom
    (a point inside a polygon, even–odd rule over its rings, has distance 0), or
(b) j ≥ 1 and the closed segment Ψ̄_{j−1} → Ψ̄_j meets a polygon edge (crossing or touching).  A segment that
    lies wholly inside a polygon has both end points inside, so (a) has already fired; (b) catches the
    segments that jump over a thin polygon without any sample point within ``r_dom`` of it.

N_TP = the first colliding index j* (= the number of points before it), or N when no point collides.

:func:`first_land_hit` (jitted, vectorised over any leading behaviour axes) works on the padded chart of
:func:`psbmpc_jax.packing.pack_world` (:class:`~psbmpc_jax.packing.ChartArrays`): for every polygon the edge
slots ``i < n`` (edge i runs from vertex i to vertex ``next[i]``) of the polygons with ``mask`` set.  The
edge slots are visited in blocks of ``block`` slots of one polygon each (one ``lax.scan``; the even–odd
parity is closed per polygon, so overlapping polygons stay land), so memory stays at ``points × block``
whatever the chart size.  Blocks whose bounding box is out of reach of every point (farther than r_dom
from the trajectories' box) skip the distance and segment tests, and blocks that no point's +x ray can cross
skip the parity (``lax.cond``; exact, only work is saved).  Integer output, no gradient.
"""

from __future__ import annotations

import math
from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from ..geometry import edge_table
from ..packing import ChartArrays, WorldArrays

#: Default number of edge slots visited at once (memory ~ points × block per intermediate).
DEFAULT_BLOCK = 256


# --------------------------------------------------------------------------------------------- helpers
def as_chart(chart, name: str = "chart") -> ChartArrays:
    """``chart`` as :class:`ChartArrays` (a :class:`WorldArrays` gives its polygons), shapes checked."""
    if isinstance(chart, WorldArrays):
        chart = chart.polygons
    if not isinstance(chart, ChartArrays):
        raise ValueError(f"{name} must be a psbmpc_jax.packing.ChartArrays (or WorldArrays), got "
                         f"{type(chart).__name__}")
    v, nx, n, m = (np.shape(a) for a in (chart.vertices, chart.next, chart.n, chart.mask))
    if len(v) != 3 or v[2] != 2 or nx != v[:2] or n != v[:1] or m != v[:1]:
        raise ValueError(f"{name} must hold vertices [P, V, 2], next [P, V], n [P], mask [P], got shapes "
                         f"{v}, {nx}, {n}, {m}")
    return chart


def concrete_float(x):
    """``float(x)`` when ``x`` is a concrete scalar, ``None`` when it is traced (checked inside a caller's jit
    only by shape)."""
    if isinstance(x, jax.core.Tracer):
        return None
    try:
        return float(np.asarray(x))
    except (TypeError, ValueError):
        return None


def check_radius(value, name: str):
    """A finite radius ``>= 0`` (a traced value passes unchecked); returns ``value``."""
    if np.ndim(value) != 0:
        raise ValueError(f"{name} must be a scalar [m], got shape {np.shape(value)}")
    v = concrete_float(value)
    if v is not None and (not math.isfinite(v) or v < 0):
        raise ValueError(f"{name} must be a finite number >= 0 [m], got {v}")
    return value


def check_points(value, name: str, min_points: int = 1):
    """A trajectory ``[..., N+1 >= min_points, 2]`` of floats (finite when concrete)."""
    shape = np.shape(value)
    if len(shape) < 2 or shape[-1] != 2 or shape[-2] < min_points:
        raise ValueError(f"{name} must have shape [..., N+1 >= {min_points}, 2] (north, east), got {shape}"
                         + (" (pass traj[..., :2] for full states)" if len(shape) >= 2 and shape[-1] > 2 else ""))
    if not isinstance(value, jax.core.Tracer):
        arr = np.asarray(value)
        if arr.dtype.kind not in "iuf":
            raise ValueError(f"{name} must be numeric, got dtype {arr.dtype}")
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{name} must be finite (no NaN/inf)")
    return value


class EdgeBlocks(NamedTuple):
    """A chart's edge slots in blocks (see :func:`edge_blocks`)."""

    edges: jax.Array     # [C, M, 8]  columns of psbmpc_jax.geometry.EDGE_COLUMNS
    valid: jax.Array     # [C, M]     slot < n of a masked-in polygon
    first: jax.Array     # [C]        the block starts a polygon
    lo: jax.Array        # [C, 2]     box of the block's valid edges (+inf when it has none)
    hi: jax.Array        # [C, 2]     (-inf when it has none)


def edge_blocks(chart: ChartArrays, block: int = DEFAULT_BLOCK, per_polygon: bool = True) -> EdgeBlocks:
    """Every edge slot of the chart in blocks of M slots, with each block's bounding box (for culling).

    ``per_polygon`` (for per-polygon even–odd parity): blocks never straddle two polygons, M = min(block, V)
    and each polygon's V slots are padded to ceil(V / M) blocks.  Otherwise the P V slots are cut into
    blocks of M = min(block, P V) (``first`` then only marks block 0).  At least one block: an empty chart
    gives one invalid block."""
    verts, nxt = jnp.asarray(chart.vertices), jnp.asarray(chart.next)
    P, V = nxt.shape
    edges = edge_table(verts, nxt)                                                   # [P, V, 8]
    valid = (jnp.arange(V)[None, :] < jnp.asarray(chart.n)[:, None]) & jnp.asarray(chart.mask)[:, None]
    if not per_polygon:
        P, V = 1, P * V
        edges, valid = edges.reshape(1, V, 8), valid.reshape(1, V)
    M = max(1, min(int(block), V))
    if P * V == 0:
        inf = jnp.full((1, 2), jnp.inf, edges.dtype)
        return EdgeBlocks(jnp.zeros((1, M, 8), edges.dtype), jnp.zeros((1, M), bool), jnp.ones(1, bool), inf, -inf)
    Cp = -(-V // M)
    pad = Cp * M - V
    edges = jnp.pad(edges, ((0, 0), (0, pad), (0, 0))).reshape(P * Cp, M, 8)
    valid = jnp.pad(valid, ((0, 0), (0, pad))).reshape(P * Cp, M)
    inf = jnp.asarray(jnp.inf, edges.dtype)
    lo = jnp.stack([jnp.where(valid, jnp.minimum(edges[..., 0], edges[..., 5]), inf).min(1),
                    jnp.where(valid, jnp.minimum(edges[..., 1], edges[..., 6]), inf).min(1)], -1)
    hi = jnp.stack([jnp.where(valid, jnp.maximum(edges[..., 0], edges[..., 5]), -inf).max(1),
                    jnp.where(valid, jnp.maximum(edges[..., 1], edges[..., 6]), -inf).max(1)], -1)
    return EdgeBlocks(edges, valid, jnp.arange(P * Cp) % Cp == 0, lo, hi)


def cull_tolerance(qlo, qhi):
    """Slack of the culling tests against rounding: 1e-9 relative to the coordinates' magnitude."""
    return 1e-9 * (1.0 + jnp.maximum(jnp.max(jnp.abs(qlo)), jnp.max(jnp.abs(qhi))))


def box_near(lo, hi, qlo, qhi, margin):
    """Whether the box [lo, hi] comes within ``margin`` of the box [qlo, qhi] (per axis; an empty box never)."""
    return jnp.all((lo <= qhi + margin) & (hi >= qlo - margin))


def may_cross(lo, hi, qlo, qhi, tol):
    """Whether some edge of a block with box [lo, hi] can cross the +x ray of a point in the box [qlo, qhi]:
    the y ranges overlap and the block reaches right of the leftmost point (``tol``: slack)."""
    return (lo[1] <= qhi[1] + tol) & (hi[1] >= qlo[1] - tol) & (hi[0] >= qlo[0] - tol)


def crossings(px, py, e):
    """Whether each edge (columns ``e [..., 8]`` broadcast against the points) crosses the ray from
    ``(px, py)`` towards +x: the half-open even–odd rule of :mod:`psbmpc_jax.geometry`."""
    ax, ay, by, slope = e[..., 0], e[..., 1], e[..., 6], e[..., 7]
    return ((ay > py) != (by > py)) & (px < ax + (py - ay) * slope)


def ray_edge_t(ox, oy, dx, dy, e):
    """Hit parameter t >= 0 of the rays o + t d (``|d| = 1``; broadcast against the edges ``e [..., 8]``, columns
    of :data:`psbmpc_jax.geometry.EDGE_COLUMNS`), +inf when a ray misses the closed edge a-b.

    Robust at vertices: with the orientations σ(v) = d × (v − o) of the end points (× the 2-d cross product;
    computed from the vertex alone, so a vertex shared by two edges gets the same σ in both), the ray's line
    meets the edge iff σ(a) and σ(b) do not have strictly equal signs, at s = σ(a)/(σ(a) − σ(b)) ∈ [0, 1] along
    it and t = d·(a − o) + s d·(b − a) along the ray; a hit needs t >= 0.  A ray through a vertex where the
    boundary crosses its line therefore never slips between the two edges, whatever the rounding (a plain
    Cramer solve for s per edge can put s just below 0 on one edge and just above 1 on the other).
    Collinear edge (σ(a) = σ(b) = 0): the hit is at max(min(t_a, t_b), 0) when max(t_a, t_b) >= 0."""
    ax, ay, bx, by = e[..., 0], e[..., 1], e[..., 5], e[..., 6]
    sa = dx * (ay - oy) - dy * (ax - ox)
    sb = dx * (by - oy) - dy * (bx - ox)
    ta = dx * (ax - ox) + dy * (ay - oy)
    tb = dx * (bx - ox) + dy * (by - oy)
    col = (sa == 0) & (sb == 0)
    meets = ((sa <= 0) & (sb >= 0)) | ((sa >= 0) & (sb <= 0))
    den = sa - sb                                    # |den| = |σ(a)| + |σ(b)| > 0 where it meets, not collinear
    s = jnp.clip(sa / jnp.where(den == 0, 1.0, den), 0.0, 1.0)
    t = ta + s * (tb - ta)
    inf = jnp.asarray(jnp.inf, t.dtype)
    t_col = jnp.where(jnp.maximum(ta, tb) >= 0, jnp.maximum(jnp.minimum(ta, tb), 0.0), inf)
    return jnp.where(col, t_col, jnp.where(meets & (t >= 0), t, inf))


def point_edge_d2(px, py, e):
    """Squared distance from the points to each edge (broadcast)."""
    ax, ay, abx, aby, inv_l2 = e[..., 0], e[..., 1], e[..., 2], e[..., 3], e[..., 4]
    apx, apy = px - ax, py - ay
    t = jnp.clip((apx * abx + apy * aby) * inv_l2, 0.0, 1.0)
    qx, qy = apx - t * abx, apy - t * aby
    return qx * qx + qy * qy


def segment_hits_edge(p0x, p0y, p1x, p1y, e):
    """Whether the closed segment p0 → p1 meets each closed edge (broadcast): orientation signs, with the
    collinear case (every orientation zero) decided by overlap of the boxes."""
    ax, ay, abx, aby, bx, by = e[..., 0], e[..., 1], e[..., 2], e[..., 3], e[..., 5], e[..., 6]
    sx, sy = p1x - p0x, p1y - p0y
    o1 = jnp.sign(abx * (p0y - ay) - aby * (p0x - ax))      # p0 against the edge line
    o2 = jnp.sign(abx * (p1y - ay) - aby * (p1x - ax))      # p1
    o3 = jnp.sign(sx * (ay - p0y) - sy * (ax - p0x))        # a against the segment line
    o4 = jnp.sign(sx * (by - p0y) - sy * (bx - p0x))        # b
    collinear = (o1 == 0) & (o2 == 0) & (o3 == 0) & (o4 == 0)
    proper = (o1 * o2 <= 0) & (o3 * o4 <= 0) & ~collinear
    overlap = ((jnp.maximum(ax, bx) >= jnp.minimum(p0x, p1x)) & (jnp.minimum(ax, bx) <= jnp.maximum(p0x, p1x))
               & (jnp.maximum(ay, by) >= jnp.minimum(p0y, p1y)) & (jnp.minimum(ay, by) <= jnp.maximum(p0y, p1y)))
    return proper | (collinear & overlap)


# --------------------------------------------------------------------------------------------- kernel
def _flags_kernel(pts, chart: ChartArrays, r_dom, block: int):
    """Collision flags ``[K, T]`` of trajectories ``pts [K, T, 2]`` (rule (a) or (b) of the module
    docstring at each j)."""
    point_hit, seg_hit, _, _ = _scan_chart(pts, chart, r_dom, block)
    return point_hit | seg_hit


def _scan_chart(pts, chart: ChartArrays, r_dom, block: int):
    """``(point_hit [K, T], seg_hit [K, T], d2 [K T], inside [K T])``: d2 is exact only within ``r_dom`` of a
    point (farther blocks are culled) and ``big`` where nothing is that near."""
    K, T, _ = pts.shape
    pts = lax.stop_gradient(pts)
    px, py = pts[..., 0].reshape(-1, 1), pts[..., 1].reshape(-1, 1)                 # [K T, 1]
    p0, p1 = pts[:, :-1].reshape(-1, 2), pts[:, 1:].reshape(-1, 2)                  # [K (T-1), 2]
    s0x, s0y, s1x, s1y = (a[:, None] for a in (p0[:, 0], p0[:, 1], p1[:, 0], p1[:, 1]))
    blocks = edge_blocks(chart, block)
    dtype = pts.dtype
    big = jnp.asarray(jnp.finfo(dtype).max, dtype)
    r = jnp.asarray(r_dom, dtype)
    flat = pts.reshape(-1, 2)
    qlo, qhi = flat.min(0), flat.max(0)                      # every point and segment lies in this box
    tol = cull_tolerance(qlo, qhi)

    def per_block(carry, blk):
        d2, parity, inside, seg_hit = carry
        e, v, start, lo, hi = blk                                                    # [M, 8], [M], [], [2], [2]
        # even-odd per polygon (overlapping polygons stay land): a new polygon closes the previous one's parity
        inside = inside | (start & parity)
        parity = jnp.where(start, False, parity)
        # culling (exact): blocks out of reach of every point / segment skip the distance and segment tests,
        # blocks that no +x ray can cross skip the parity
        parity = lax.cond(may_cross(lo, hi, qlo, qhi, tol),
                          lambda: parity ^ (jnp.sum(v & crossings(px, py, e), axis=1) % 2 == 1), lambda: parity)

        def near():
            return (jnp.minimum(d2, jnp.min(jnp.where(v, point_edge_d2(px, py, e), big), axis=1)),
                    seg_hit | jnp.any(v & segment_hits_edge(s0x, s0y, s1x, s1y, e), axis=1))

        d2, seg_hit = lax.cond(box_near(lo, hi, qlo, qhi, r + tol), near, lambda: (d2, seg_hit))
        return (d2, parity, inside, seg_hit), None

    zeros = jnp.zeros(K * T, bool)
    init = (jnp.full((K * T,), big, dtype), zeros, zeros, jnp.zeros(K * (T - 1), bool))
    (d2, parity, inside, seg_hit), _ = lax.scan(per_block, init, tuple(blocks[:3]) + (blocks.lo, blocks.hi))
    inside = inside | parity
    point_hit = (inside | (d2 <= r * r)).reshape(K, T)
    seg_hit = jnp.concatenate([jnp.zeros((K, 1), bool), seg_hit.reshape(K, T - 1)], axis=1)
    return point_hit, seg_hit, d2, inside


def land_clearance(point, chart, reach) -> jax.Array:
    """Distance [m] from ``point [2]`` (north, east) to the land of ``chart`` (0 inside land), capped at
    ``reach``: polygons farther than ``reach`` are not visited, and ``reach`` is returned when none is nearer.
    Traceable (no validation; used inside the init stage's jit), no gradient."""
    pts = jnp.reshape(jnp.asarray(point), (1, 1, 2))
    reach = jnp.asarray(reach, pts.dtype)
    _, _, d2, inside = _scan_chart(pts, as_chart(chart), reach, DEFAULT_BLOCK)
    d = jnp.sqrt(jnp.minimum(d2[0], reach * reach))
    return jnp.where(inside[0], jnp.zeros_like(d), d)


@partial(jax.jit, static_argnames=("block",))
def _hits_jit(pts, chart, r_dom, block):
    """Flags ``[K, T]`` and N_TP ``[K]`` of trajectories ``pts [K, T, 2]`` (one compilation serves both)."""
    flags = _flags_kernel(pts, chart, r_dom, block)
    n_tp = jnp.where(jnp.any(flags, axis=-1), jnp.argmax(flags, axis=-1), pts.shape[1] - 1).astype(jnp.int32)
    return flags, n_tp


def _hits(traj_xy, chart, r_dom, block):
    """Validate, flatten the leading axes, run :func:`_hits_jit`, restore the leading axes."""
    check_points(traj_xy, "traj_xy")
    check_radius(r_dom, "r_dom")
    chart = as_chart(chart)
    if isinstance(block, bool) or not isinstance(block, (int, np.integer)) or block < 1:
        raise ValueError(f"block must be an integer >= 1, got {block!r}")
    traj = jnp.asarray(traj_xy)
    if not jnp.issubdtype(traj.dtype, jnp.floating):
        traj = traj.astype(jnp.asarray(chart.vertices).dtype)
    lead, T = traj.shape[:-2], traj.shape[-2]
    flags, n_tp = _hits_jit(traj.reshape(-1, T, 2), chart, r_dom, int(block))
    return flags.reshape(lead + (T,)), n_tp.reshape(lead)


# --------------------------------------------------------------------------------------------- public
def land_collision_flags(traj_xy, chart, r_dom, *, block: int = DEFAULT_BLOCK) -> jax.Array:
    """Per-point collision flags ``bool [..., N+1]`` of trajectories ``traj_xy [..., N+1, 2]`` (north, east)
    against the land polygons ``chart`` (:class:`~psbmpc_jax.packing.ChartArrays`, unbuffered): flag j is
    rule (a) (polygon distance ≤ ``r_dom``, inside = 0) or rule (b) (segment j−1 → j meets an edge) of the
    module docstring.  Jitted; traceable inside a caller's jit (then only shapes are validated)."""
    return _hits(traj_xy, chart, r_dom, block)[0]


def first_land_hit(traj_xy, chart, r_dom, *, block: int = DEFAULT_BLOCK) -> jax.Array:
    """N_TP of Mahipala & Johansen (2024, Sec. VI): the index of the first colliding point of each trajectory
    ``traj_xy [..., N+1, 2]`` (int32 ``[...]``; a single trajectory ``[N+1, 2]`` gives a scalar), N when none
    collides.  ``chart``: the *unbuffered* land polygons as packed by :func:`~psbmpc_jax.packing.pack_world`
    (``ChartArrays`` or the ``WorldArrays`` holding them); ``r_dom``: ship-domain radius [m] (>= 0).

    Leading axes are behaviours (``[B, N+1, 2]`` → ``[B]``), evaluated in one vectorised call.  Jitted; no
    gradient (integer output).  Raises ``ValueError`` naming the field on a bad shape, a negative or
    non-finite ``r_dom``, or a non-finite trajectory."""
    return _hits(traj_xy, chart, r_dom, block)[1]


__all__ = ["first_land_hit", "land_collision_flags", "land_clearance", "edge_blocks", "EdgeBlocks", "DEFAULT_BLOCK",
           "ray_edge_t"]
