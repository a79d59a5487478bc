"""Algorithm 3 of Mahipala & Johansen (2024, Sec. VII): the cross-track-error corridor around a reference trajectory
Ψ, in the cross-track form of choice SM-8 (eq. (28) read as an inequality on the cross-track coordinate, not the
printed per-coordinate box; see ``docs/corridor.md``).

For reference positions ``P [N+1, 2]`` (north, east) and land buffered by the ship-domain radius
(G = ⊕ r_dom of the union of the land polygons), at every step j:

* t̂_j: the unit direction of the segment P_j → P_{j+1} (j < N); the last step reuses t̂_{N−1}.  A segment
  no longer than ``min_segment`` reuses the previous direction; zero-length segments at the start take the
  next non-zero direction; when *every* segment is zero-length the course ``heading`` (rad, from north,
  clockwise) gives t̂ = (cos heading, sin heading).
* n̂_j = (−t̂_y, t̂_x): in NED (x north, y east) the starboard normal of the local track.
* two rays from P_j along ±n̂_j, of length Δd; e⁺_j = the distance along +n̂_j to the nearest point of the
  boundary ∂G on the ray (Δd if none), e⁻_j = −(the same along −n̂_j).  So e⁻_j ≤ 0 ≤ e⁺_j, and the boundary
  points of Algorithm 3 are g^{Δd±}_j = P_j + e^±_j n̂_j.
* Inside convention: when P_j lies in G (closed: interior or boundary, i.e. the reference point is within
  r_dom of land), both bounds collapse to 0 and ``inside[j]`` is True.  The reference itself stays feasible
  (its cross-track error is 0), the optimiser gets no sideways freedom there, and the caller can log /
  handle the flagged steps.

The constraint for the optimiser is on the cross-track coordinate e_j(x) = n̂_j·(x_j − P_j):
e⁻_j ≤ e_j(x_j) ≤ e⁺_j, returned as residuals h ≤ 0 by :func:`cross_track_residuals` (linear in x, exact
gradients ∓n̂_j).

Two implementations that agree to rounding:

* :func:`cross_track_corridor_shapely` — the host oracle: shapely ``unary_union(...).buffer(r_dom)`` and
  ``LineString`` intersections with its boundary (NumPy float64 out);
* :func:`cross_track_corridor` — the device version: buffer once on the host (:func:`buffered_chart`:
  shapely, then packed like :func:`psbmpc_jax.packing.pack_world`), then the jitted ray cast
  :func:`corridor_kernel` — for each of the 2(N+1) rays the smallest non-negative hit parameter over all
  buffered edges, min(·, Δd), plus an even–odd inside test of P_j.
"""

from __future__ import annotations

import math
from types import SimpleNamespace
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import shapely
from jax import lax
from shapely.geometry import LineString, MultiPolygon, Point, Polygon
from shapely.ops import unary_union

from ..array_types import HostOrDevice
from ..packing import Capacities, ChartArrays, pack_world
from .land_hit import (DEFAULT_BLOCK, as_chart, box_near, check_points, check_radius, concrete_float,
                       crossings, cull_tolerance, edge_blocks, may_cross, ray_edge_t)

#: Default ``quad_segs`` of the shapely buffer (segments per quarter circle of the rounded corners).
DEFAULT_QUAD_SEGS = 16

#: Default length [m] at or below which a segment of Ψ counts as zero-length.
DEFAULT_MIN_SEGMENT = 1e-9


class Corridor(NamedTuple):
    """The corridor of a reference trajectory, per step j = 0..N (a pytree; NumPy from the host oracle, JAX
    arrays from the device version).

    Attributes:
        origin: P_j ``[N+1, 2]`` (north, east) [m].
        tangent: t̂_j ``[N+1, 2]``.
        normal: n̂_j = (−t̂_y, t̂_x) ``[N+1, 2]`` (starboard).
        lower: e⁻_j ``[N+1]`` (≤ 0) [m].
        upper: e⁺_j ``[N+1]`` (≥ 0) [m].
        inside: ``bool [N+1]``: P_j lies in the buffered land (then lower = upper = 0).
    """

    origin: HostOrDevice
    tangent: HostOrDevice
    normal: HostOrDevice
    lower: HostOrDevice
    upper: HostOrDevice
    inside: HostOrDevice


# ------------------------------------------------------------------------------------------ validation
def _check_positive(value, name: str):
    if np.ndim(value) != 0:
        raise ValueError(f"{name} must be a scalar [m], got shape {np.shape(value)}")
    v = concrete_float(value)
    if v is not None and (not math.isfinite(v) or v <= 0):
        raise ValueError(f"{name} must be a finite number > 0 [m], got {v}")
    return value


def _check_heading(heading):
    if heading is None:
        return None
    if np.ndim(heading) != 0:
        raise ValueError(f"heading must be a scalar course [rad], got shape {np.shape(heading)}")
    v = concrete_float(heading)
    if v is not None and not math.isfinite(v):
        raise ValueError(f"heading must be finite [rad], got {v}")
    return heading


def _check_min_segment(min_segment):
    v = concrete_float(min_segment)
    if np.ndim(min_segment) != 0 or v is None or not math.isfinite(v) or v < 0:
        raise ValueError(f"min_segment must be a finite number >= 0 [m], got {min_segment!r}")
    return v


def _check_trajectory(positions):
    check_points(positions, "positions")
    if np.ndim(positions) != 2:
        raise ValueError(f"positions must have shape [N+1, 2] (north, east), got {np.shape(positions)}")


# ------------------------------------------------------------------------------------------ host side
def _as_shapely(polygons) -> list:
    """Land polygons as shapely polygons: shapely (Multi)Polygons, rings ``[n, 2]`` or tuples of rings
    (outer ring, holes) as in :class:`psbmpc_jax.Situation`."""
    if isinstance(polygons, (Polygon, MultiPolygon)):
        polygons = [polygons]
    out = []
    for j, p in enumerate(polygons):
        if isinstance(p, (Polygon, MultiPolygon)):
            g = p
        else:
            arrs = ring_arrays(p, j)
            g = Polygon(arrs[0], arrs[1:])
        if not g.is_valid:
            g = shapely.make_valid(g)
        out.append(g)
    return out


def ring_arrays(p, j: int) -> list:
    """One polygon given as a ring ``[n, 2]`` or a sequence of rings (outer ring, then holes) as a list of
    float64 arrays, each checked: finite, ``[n >= 3, 2]`` (north, east); ``ValueError`` naming ``polygons[j]``."""
    rings = p if isinstance(p, (list, tuple)) and len(p) and np.ndim(p[0]) == 2 else (p,)
    arrs = []
    for k, r in enumerate(rings):
        a = np.asarray(r, dtype=float)
        if a.ndim != 2 or a.shape[1] != 2 or a.shape[0] < 3 or not np.all(np.isfinite(a)):
            raise ValueError(f"polygons[{j}] ring {k} must be a finite array [n >= 3, 2] (north, east), got "
                             f"shape {a.shape}")
        arrs.append(a)
    return arrs


def buffer_land(polygons, r_dom, *, quad_segs: int = DEFAULT_QUAD_SEGS):
    """G of Algorithm 3: the union of the land ``polygons`` (rings / tuples of rings / shapely) buffered
    (Minkowski sum with a disc) by ``r_dom`` >= 0 [m]; a shapely geometry (possibly empty)."""
    r = check_radius(r_dom, "r_dom")
    if isinstance(quad_segs, bool) or not isinstance(quad_segs, (int, np.integer)) or quad_segs < 1:
        raise ValueError(f"quad_segs must be an integer >= 1, got {quad_segs!r}")
    polys = _as_shapely(polygons)
    if not polys:
        return Polygon()
    return unary_union(polys).buffer(float(r), quad_segs=int(quad_segs))


def _ring_sets(geom) -> list[tuple[np.ndarray, ...]]:
    out = []
    for g in shapely.get_parts(geom):
        if isinstance(g, MultiPolygon):
            out += _ring_sets(g)
        elif isinstance(g, Polygon) and not g.is_empty:
            rings = [g.exterior, *g.interiors]
            out.append(tuple(np.asarray(r.coords, dtype=float)[:-1, :2] for r in rings))
    return out


def buffered_chart(polygons, r_dom, *, quad_segs: int = DEFAULT_QUAD_SEGS, capacities: Capacities | None = None,
                   dtype="float64") -> ChartArrays:
    """The buffered land G (:func:`buffer_land`) packed for the device exactly as
    :func:`psbmpc_jax.packing.pack_world` packs a chart (``vertices [P, V, 2]``, ``next``, ``n``, ``mask``;
    capacities bucketed unless given).  Do this once per chart and ``r_dom``; the result feeds
    :func:`cross_track_corridor` for every reference trajectory."""
    geom = buffer_land(polygons, r_dom, quad_segs=quad_segs)
    cfg = SimpleNamespace(dtype=np.dtype(dtype).name, grounding_mode="exact", grid_margin=0.0, grid_spacing=1.0)
    return pack_world(_ring_sets(geom), cfg, capacities).polygons


def _tangents_host(P: np.ndarray, heading, min_segment: float) -> np.ndarray:
    """t̂_j by the rules of the module docstring (plain loops: an independent twin of the device version)."""
    n1 = len(P)
    seg = np.diff(P, axis=0)
    length = np.linalg.norm(seg, axis=1)
    valid = length > min_segment
    if not valid.any():
        if heading is None:
            raise ValueError("positions: every segment of the reference trajectory has zero length; pass heading "
                             "(course [rad]) to orient the corridor")
        h = float(heading)
        return np.tile([math.cos(h), math.sin(h)], (n1, 1))
    unit = np.zeros_like(seg)
    unit[valid] = seg[valid] / length[valid, None]
    t = np.zeros((n1, 2))
    first = int(np.argmax(valid))
    cur = unit[first]
    for j in range(n1 - 1):
        if valid[j]:
            cur = unit[j]
        t[j] = cur
    t[n1 - 1] = t[n1 - 2]
    return t


def cross_track_corridor_shapely(positions, polygons, r_dom, delta_d, *, heading=None,
                                 quad_segs: int = DEFAULT_QUAD_SEGS,
                                 min_segment: float = DEFAULT_MIN_SEGMENT) -> Corridor:
    """Host oracle of Algorithm 3 (NumPy float64 :class:`Corridor`): buffer the union of the land ``polygons``
    by ``r_dom`` with shapely, then intersect the segments [P_j, P_j ± Δd n̂_j] with its boundary and keep the
    nearest hit.  ``positions [N+1, 2]``: Ψ's positions (north, east) [m]; ``delta_d`` > 0: the maximum
    half-width Δd [m]; ``heading``: course [rad] used only when every segment has zero length."""
    _check_trajectory(positions)
    _check_positive(delta_d, "delta_d")
    _check_heading(heading)
    min_segment = _check_min_segment(min_segment)
    P = np.asarray(positions, dtype=float)
    G = buffer_land(polygons, r_dom, quad_segs=quad_segs)
    t = _tangents_host(P, heading, min_segment)
    n = np.stack([-t[:, 1], t[:, 0]], axis=1)
    dd = float(delta_d)
    boundary = None if G.is_empty else G.boundary
    upper, lower, inside = np.full(len(P), dd), np.full(len(P), -dd), np.zeros(len(P), bool)
    for j, (p, nj) in enumerate(zip(P, n)):
        if boundary is None:
            continue
        pt = Point(p)
        if G.covers(pt):
            upper[j] = lower[j] = 0.0
            inside[j] = True
            continue
        for sign, out in ((1.0, upper), (-1.0, lower)):
            hit = LineString([p, p + sign * dd * nj]).intersection(boundary)
            if not hit.is_empty:
                out[j] = sign * min(pt.distance(hit), dd)
    return Corridor(P.copy(), t, n, lower, upper, inside)


# ------------------------------------------------------------------------------------------ device side
def _tangents(P, heading, min_segment):
    """t̂_j ``[N+1, 2]`` on the device (same rules as :func:`_tangents_host`)."""
    fallback = jnp.stack([jnp.cos(heading), jnp.sin(heading)]).astype(P.dtype)
    n1 = P.shape[0]
    if n1 == 1:
        return fallback[None]
    seg = P[1:] - P[:-1]                                                         # [N, 2]
    length = jnp.sqrt(jnp.sum(seg * seg, axis=1))
    valid = length > min_segment
    N = n1 - 1
    idx = jnp.arange(N)
    last = lax.cummax(jnp.where(valid, idx, -1), axis=0)                        # last valid k <= j
    nxt = lax.cummin(jnp.where(valid, idx, N), axis=0, reverse=True)            # first valid k >= j
    pick = jnp.where(last >= 0, last, nxt)                                       # N: none at all
    unit = seg / jnp.where(valid, length, 1.0)[:, None]
    t = jnp.concatenate([unit, fallback[None]])[pick]
    return jnp.concatenate([t, t[-1:]])


def corridor_kernel(positions, chart: ChartArrays, delta_d, heading=0.0, min_segment=DEFAULT_MIN_SEGMENT,
                    block: int = DEFAULT_BLOCK) -> Corridor:
    """The device ray cast of Algorithm 3, traceable (no validation, no gradient: every output is
    ``stop_gradient``-ed).  ``chart``: the *buffered* land (:func:`buffered_chart`); its polygons must be
    interior-disjoint (the parts of one union), since every edge counts as boundary and one even–odd parity
    runs over all edges.  ``heading``: the fallback course when every segment is zero-length; ``block``
    (static): edge slots visited at once.  Blocks whose box misses the rays' box skip the ray test, blocks
    that no +x ray from a P_j can cross skip the parity (``lax.cond``; exact, only work is saved).

    The ray/edge test is :func:`psbmpc_jax.smooth.land_hit.ray_edge_t` (from the end points' sides of the ray's
    line, so a ray through a vertex cannot slip between its two edges; a collinear edge hits at
    max(min(t_a, t_b), 0) when max(…) >= 0)."""
    P = lax.stop_gradient(jnp.asarray(positions))
    dtype = P.dtype
    t = _tangents(P, jnp.asarray(heading, dtype), min_segment)
    n = jnp.stack([-t[:, 1], t[:, 0]], axis=1)
    n1 = P.shape[0]
    ox = jnp.concatenate([P[:, 0], P[:, 0]])[:, None]                             # rays [2(N+1), 1]
    oy = jnp.concatenate([P[:, 1], P[:, 1]])[:, None]
    dx = jnp.concatenate([n[:, 0], -n[:, 0]])[:, None]
    dy = jnp.concatenate([n[:, 1], -n[:, 1]])[:, None]
    px, py = P[:, 0:1], P[:, 1:2]
    blocks = edge_blocks(chart, block, per_polygon=False)
    inf = jnp.asarray(jnp.inf, dtype)
    dd = jnp.asarray(delta_d, dtype)
    ends = jnp.concatenate([P + dd * n, P - dd * n])
    rlo, rhi = jnp.minimum(P.min(0), ends.min(0)), jnp.maximum(P.max(0), ends.max(0))   # every ray's box
    plo, phi = P.min(0), P.max(0)
    tol = cull_tolerance(rlo, rhi)

    def ray_hits(e):
        return ray_edge_t(ox, oy, dx, dy, e)

    def per_block(carry, blk):
        tmin, parity = carry
        e, v, lo, hi = blk
        tmin = lax.cond(box_near(lo, hi, rlo, rhi, tol),
                        lambda: jnp.minimum(tmin, jnp.min(jnp.where(v, ray_hits(e), inf), axis=1)), lambda: tmin)
        # one even-odd parity over all edges: the parts of the buffered union are disjoint
        parity = lax.cond(may_cross(lo, hi, plo, phi, tol),
                          lambda: parity ^ (jnp.sum(v & crossings(px, py, e), axis=1) % 2 == 1), lambda: parity)
        return (tmin, parity), None

    (tmin, inside), _ = lax.scan(per_block, (jnp.full(2 * n1, inf), jnp.zeros(n1, bool)),
                                 lax.stop_gradient((blocks.edges, blocks.valid, blocks.lo, blocks.hi)))
    reach = jnp.minimum(tmin, dd)
    upper = jnp.where(inside, 0.0, reach[:n1])
    lower = jnp.where(inside, 0.0, -reach[n1:])
    return Corridor(P, t, n, lower, upper, inside)


_corridor_jit = jax.jit(corridor_kernel, static_argnames=("block",))


def cross_track_corridor(positions, chart, delta_d, *, heading=None, min_segment: float = DEFAULT_MIN_SEGMENT,
                         block: int = DEFAULT_BLOCK) -> Corridor:
    """Device Algorithm 3 (jitted): the :class:`Corridor` of reference positions ``positions [N+1, 2]``
    (north, east) [m] against the *buffered* land ``chart`` (:func:`buffered_chart`, built once per chart and
    r_dom), with maximum half-width ``delta_d`` > 0 [m].  ``heading``: course [rad] orienting the corridor
    when every segment has zero length (required then, when ``positions`` is concrete).

    Raises ``ValueError`` naming the field on a bad shape, a non-finite trajectory, ``delta_d`` <= 0, or an
    all-zero-length trajectory without ``heading``."""
    _check_trajectory(positions)
    _check_positive(delta_d, "delta_d")
    _check_heading(heading)
    min_segment = _check_min_segment(min_segment)
    chart = as_chart(chart)
    if isinstance(block, bool) or not isinstance(block, (int, np.integer)) or block < 1:
        raise ValueError(f"block must be an integer >= 1, got {block!r}")
    P = jnp.asarray(positions)
    if not jnp.issubdtype(P.dtype, jnp.floating):
        P = P.astype(jnp.asarray(chart.vertices).dtype)
    if heading is None:
        if not isinstance(positions, jax.core.Tracer):
            _tangents_host(np.asarray(positions, dtype=float), None, min_segment)   # raises when all zero
        heading = 0.0
    return _corridor_jit(P, chart, delta_d, heading, min_segment, block=int(block))


def boundary_points(corridor: Corridor):
    """The boundary points of Algorithm 3: g^{Δd+}_j = P_j + e⁺_j n̂_j and g^{Δd−}_j = P_j + e⁻_j n̂_j
    (each ``[N+1, 2]``)."""
    o, n = corridor.origin, corridor.normal
    return o + corridor.upper[..., None] * n, o + corridor.lower[..., None] * n


def cross_track_residuals(positions, corridor: Corridor):
    """Corridor constraints as residuals h <= 0 for an optimiser: with e_j = n̂_j·(x_j − P_j),
    ``lower_violation = e⁻_j − e_j`` and ``upper_violation = e_j − e⁺_j`` (each ``[..., N+1]``; feasible
    when both are <= 0).  ``positions [..., N+1, 2]``: the candidate positions x_j, time-aligned with the
    corridor's steps (the DOCP uses j = 1..N_mpc: slice ``[..., 1:]``).  Linear in ``positions``
    (gradient ∓n̂_j, never NaN); the corridor is treated as a constant."""
    shape = np.shape(positions)
    n1 = np.shape(corridor.origin)[-2]
    if len(shape) < 2 or shape[-1] != 2 or shape[-2] != n1:
        raise ValueError(f"positions must have shape [..., {n1}, 2] (the corridor's N+1 steps, north/east), "
                         f"got {shape}")
    c = jax.tree.map(lambda a: lax.stop_gradient(jnp.asarray(a)), corridor)
    x = jnp.asarray(positions)
    e = jnp.sum(c.normal * (x - c.origin), axis=-1)
    return c.lower - e, e - c.upper


__all__ = ["Corridor", "buffer_land", "ring_arrays", "buffered_chart", "cross_track_corridor", "cross_track_corridor_shapely",
           "corridor_kernel", "cross_track_residuals", "boundary_points", "DEFAULT_QUAD_SEGS",
           "DEFAULT_MIN_SEGMENT"]
