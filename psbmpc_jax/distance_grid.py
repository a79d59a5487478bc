"""Precomputed nearest-land distance grid for the fast grounding mode.

The exact grounding kernel visits every polygon edge for every (time, behaviour) point.  The fast mode
instead samples the distance to the nearest polygon (0 inside, even-odd rule) once, on a regular grid over
the polygons' bounding box plus a margin, and the device bilinearly interpolates it.

Error bound (documented in docs/algorithm.md §9): the distance function is 1-Lipschitz, so the bilinear
interpolant is within h/√2 of it (h = grid spacing); g(d, t) is log-Lipschitz in d with constant G3, so
every grounding cost is within a factor exp(±G3·h/√2) of the exact one when V_w = 0.  Points outside the
grid are at least ``margin`` from every polygon and use d = margin (an absolute error below
g(margin, 0) = G1·exp(-G3 (margin − d_safe))).

The grid is built once per chart (not per solve): pass the whole chart — range filtering is unnecessary
in this mode, land beyond d_so costs exp(-G3·d_so) ≈ 0 anyway.
"""

from __future__ import annotations

import hashlib
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .array_types import HostOrDevice
from .geometry import edge_table, polygon_distance
from .situation import polygon_rings, ring_vertices


class DistanceGrid(NamedTuple):
    """``values [Gx, Gy]`` = distance to the nearest polygon at (x0 + i h, y0 + j h); ``origin`` = (x0, y0),
    ``spacing`` = h, ``margin`` = distance assigned outside the grid."""

    values: HostOrDevice
    origin: HostOrDevice
    spacing: HostOrDevice
    margin: HostOrDevice


def _edge_tables(polygons, dtype):
    """One padded edge table per polygon ``[P, V, 7]`` and the edge counts ``[P]``."""
    rows = [ring_vertices(poly) for poly in polygons]
    v_cap = max(len(v) for v, _ in rows)
    verts = np.zeros((len(rows), v_cap, 2))
    nxt = np.zeros((len(rows), v_cap), np.int32)
    for k, (v, nx) in enumerate(rows):
        verts[k, : len(v)], nxt[k, : len(v)] = v, nx
    counts = np.array([len(v) for v, _ in rows], np.int32)
    return edge_table(jnp.asarray(verts, dtype), jnp.asarray(nxt)), jnp.asarray(counts), \
        np.concatenate([v for v, _ in rows])


@jax.jit
def _tile_distance(px, py, tables, counts):
    """Distance to the nearest polygon, each polygon with its own even-odd rule (overlaps are fine)."""
    def one(dmin, tc):
        d, _, _ = polygon_distance(px, py, tc[0], tc[1], with_direction=False)
        return jnp.minimum(dmin, d), None
    big = jnp.full(px.shape, jnp.finfo(px.dtype).max, px.dtype)
    return jax.lax.scan(one, big, (tables, counts))[0]


def build_distance_grid(polygons, spacing: float = 0.5, margin: float = 100.0,
                        max_cells: int = 40_000_000, dtype=np.float32, region=None) -> DistanceGrid:
    """Sample the nearest-polygon distance of ``polygons`` (rings or ring tuples, NED) on a grid.

    ``region``: ``((x_lo, y_lo), (x_hi, y_hi))`` in NED, the area to cover (e.g. everywhere the own-ship can
    reach within one horizon); default: the polygons' bounding box plus ``margin`` — then every point
    outside the grid is at least ``margin`` from land and gets d = ``margin``.  With an explicit region the
    caller guarantees that no evaluated point leaves it (:class:`~psbmpc_jax.planner.Planner` does).

    The value at a node is the minimum over polygons of the exact distance (0 inside a polygon, even-odd
    rule over that polygon's rings), so overlapping polygons are handled.

    Raises:
        ValueError: no polygons, non-positive spacing/margin, or a grid larger than ``max_cells``.
    """
    if not (isinstance(spacing, (int, float)) and math.isfinite(spacing) and spacing > 0):
        raise ValueError(f"grid spacing must be a finite number > 0 m, got {spacing!r}")
    if not (isinstance(margin, (int, float)) and math.isfinite(margin) and margin > 0):
        raise ValueError(f"grid margin must be a finite number > 0 m, got {margin!r}")
    polygons = list(polygons)
    if not polygons:
        raise ValueError("build_distance_grid needs at least one polygon")
    tables, counts, verts = _edge_tables(polygons, dtype)
    if region is None:
        lo = verts.min(axis=0) - margin
        hi = verts.max(axis=0) + margin
    else:
        lo, hi = (np.asarray(v, dtype=float).reshape(2) for v in region)
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(hi > lo)):
            raise ValueError(f"grid region must be finite ((x_lo, y_lo), (x_hi, y_hi)) with hi > lo, got {region!r}")
    shape = tuple(int(math.ceil((h - l) / spacing)) + 1 for l, h in zip(lo, hi))
    cells = shape[0] * shape[1]
    if cells > max_cells:
        raise ValueError(
            f"distance grid of {shape[0]} x {shape[1]} = {cells} cells exceeds max_cells={max_cells}; use a larger "
            f"grid spacing (now {spacing} m), fewer/smaller polygons, or raise max_cells"
        )
    xs = lo[0] + spacing * np.arange(shape[0])
    ys = lo[1] + spacing * np.arange(shape[1])
    rows = max(1, 262_144 // shape[1])                       # fixed tile shape: one compile
    out = np.empty(shape, dtype)
    for r0 in range(0, shape[0], rows):
        xr = np.full(rows, xs[-1])
        xr[: min(rows, shape[0] - r0)] = xs[r0:r0 + rows]
        px = jnp.asarray(np.repeat(xr, shape[1]).reshape(rows, shape[1]), dtype)
        py = jnp.asarray(np.tile(ys, (rows, 1)), dtype)
        d = np.asarray(_tile_distance(px, py, tables, counts))
        out[r0:r0 + rows] = d[: min(rows, shape[0] - r0)]
    return DistanceGrid(jnp.asarray(out), jnp.asarray(lo, dtype), jnp.asarray(spacing, dtype),
                        jnp.asarray(margin, dtype))


def reach_region(position, reach: float, snap: float = 100.0):
    """A grid region containing the disc of radius ``reach`` around ``position``, with its centre snapped
    to multiples of ``snap`` so that nearby positions share one grid."""
    c = np.round(np.asarray(position, dtype=float) / snap) * snap
    half = reach + snap
    return (tuple(c - half), tuple(c + half))


def polygons_key(polygons, spacing, margin, region=None) -> str:
    """Content hash of polygons + grid settings (the planner caches grids by it)."""
    h = hashlib.sha1()
    for poly in polygons:
        for ring in polygon_rings(poly):
            h.update(np.ascontiguousarray(ring, dtype=np.float64).tobytes())
            h.update(b"|")
        h.update(b"#")
    h.update(f"{spacing}/{margin}/{region}".encode())
    return h.hexdigest()


def interpolate(grid: DistanceGrid, px, py):
    """Bilinear interpolation of the grid at points ``px, py`` (any shape); ``margin`` outside the grid.

    Returns (d, gx, gy): the distance and its (bilinear) gradient, whose negative points towards land.

    Derivatives: a point exactly on a grid line belongs to the cell on its + side (the cell ``floor``
    picks), so there the derivative (automatic, and ``gx, gy``) is the one-sided derivative from the +
    side, the derivative of that cell's bilinear patch — the whole derivative, not half of it (the
    interpolant is continuous, and where it is smooth across the line, e.g. a straight coast, this is
    the derivative).  On the last grid line (the + edge of the grid) it is the derivative from the −
    side; beyond it the distance is the constant ``margin``."""
    h = grid.spacing
    nx, ny = grid.values.shape
    fx = (px - grid.origin[0]) / h
    fy = (py - grid.origin[1]) / h
    inside = (fx >= 0) & (fx <= nx - 1) & (fy >= 0) & (fy <= ny - 1)
    i = jnp.clip(jnp.floor(fx), 0, nx - 2).astype(jnp.int32)
    j = jnp.clip(jnp.floor(fy), 0, ny - 2).astype(jnp.int32)
    # no clip on the weights: inside the grid 0 <= fx - i <= 1 already (fx - floor(fx) is exact), and a
    # clip would give the derivative a factor 1/2 at its bounds, i.e. exactly on every grid line
    # (jnp.clip's tie rule).  Outside the grid the weights are out of [0, 1], but the result is masked.
    a = fx - i
    b = fy - j
    v = grid.values
    v00, v10, v01, v11 = v[i, j], v[i + 1, j], v[i, j + 1], v[i + 1, j + 1]
    d = (1 - a) * (1 - b) * v00 + a * (1 - b) * v10 + (1 - a) * b * v01 + a * b * v11
    gx = ((1 - b) * (v10 - v00) + b * (v11 - v01)) / h
    gy = ((1 - a) * (v01 - v00) + a * (v11 - v10)) / h
    return (jnp.where(inside, d, grid.margin), jnp.where(inside, gx, 0.0), jnp.where(inside, gy, 0.0))


def relative_error_bound(spacing: float, G3: float) -> float:
    """Bound on |g_grid / g_exact − 1| for points inside the grid when V_w = 0: exp(G3·h/√2) − 1."""
    return math.expm1(G3 * spacing / math.sqrt(2.0))
