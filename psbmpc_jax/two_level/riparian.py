"""Riparian-land corridor of the upper level of the two-level MPC (Mahipala & Johansen 2023,
Algorithm 1; ``docs/two_level_geometry.md``): per route leg, the cross-track bounds g_lh(s) <= y_p <= g_rh(s)
left by the land, computed once per leg from the chart and cached.

For leg j (WP_j -> WP_{j+1}, course ψ_j, length l_j; path frame of :mod:`.path_frame`):

1. **Crossing land (choice TL-8, docs/algorithm.md §15).** A land piece (a connected part of the union of the land,
   :func:`~.static_obstacles.land_pieces`) that meets the closed leg segment is split
   (:func:`split_crossing`): its part within ``margin`` of the segment becomes a static obstacle, the minimum
   enclosing circle of that part plus ``circle_margin``; the rest of the piece outside the circle stays land
   (in RG).  So a peninsula of a bank that crosses the route becomes a circle while the bank still bounds
   the corridor; a whole bank polygon would otherwise become one circle that closes the channel.
2. **RG** = the other land pieces within ``radius`` (R_RG) of the leg *segment* (not of the own-ship: the
   corridor is computed once per leg).  Before buffering, RG is clipped to the leg's rectangle
   [−h, l_j + h] × [−h, h] (path frame), h = half_width + margin + 1 m: this only drops land that no ray can
   reach, so the result equals the corridor of the unclipped RG (tested).  RG is then buffered outward by
   ``margin`` (proposed r_os + 2 m) with shapely (``quad_segs`` segments per quarter circle).
3. **Samples** S_i at s_i = i · l_j / (N_s − 1), N_s = ceil(l_j / ds) + 1: uniform spacing <= ds, both ends
   included.
4. **Ray cast** from every S_i along ±n̂ (n̂ = (−sin ψ_j, cos ψ_j), starboard, = the +y_p axis) up to Δd
   = ``half_width``: g_rh(s_i) = the distance to the first hit of the buffered RG along +n̂ (Δd if none, so
   >= 0), g_lh(s_i) = −(the same along −n̂) (<= 0).  A sample inside the buffered RG gets g_lh = g_rh = 0 and
   ``inside`` True.  ``device=True`` runs the jitted ray cast
   :func:`psbmpc_jax.smooth.corridor.cross_track_corridor` against :func:`~psbmpc_jax.smooth.corridor.buffered_chart`;
   ``device=False`` the shapely oracle :func:`~psbmpc_jax.smooth.corridor.cross_track_corridor_shapely`.
   Both work in leg-local coordinates (origin WP_j) for precision.
5. **Bounds (choice TL-4)**: piecewise-linear in the along-track coordinate s through the samples
   (:func:`corridor_bounds`, clamped at the ends), evaluated at a predicted x_p.

Results are cached (:func:`leg_corridor`): the key is the content hash of the chart (:func:`land_key`), the
leg's two waypoints and the parameters (and JAX's x64 flag for the device version), so a repeated call, or a
new route sharing a leg, costs one hash of the chart.
"""

from __future__ import annotations

import hashlib
import math
from collections import OrderedDict
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import shapely
from shapely.geometry import LineString, MultiPolygon, Polygon

from ..packing import bucket
from ..smooth.corridor import (DEFAULT_QUAD_SEGS, buffered_chart, cross_track_corridor,
                               cross_track_corridor_shapely, ring_arrays)
from .path_frame import check_leg_index, check_waypoints, to_leg_frame
from .static_obstacles import StaticCircles, enclosing_circle, land_pieces

#: Default maximum half-width Δd [m] (the fjord value; 20 m is proposed for small-scale scenes).
DEFAULT_HALF_WIDTH = 50.0
#: Default sample spacing ds [m] along the leg (or U·dt of the upper MPC).
DEFAULT_SAMPLE = 5.0
#: Default margin [m] added to the enclosing circle of land crossing a leg (the constraint adds r_os).
DEFAULT_CIRCLE_MARGIN = 2.0
#: The device ray cast pads the sample count to a power of two at least this large (fewer compilations).
MIN_SAMPLE_BUCKET = 16
#: Most samples per leg (length / ds + 1).
MAX_SAMPLES = 1_000_000
#: Entries kept by the corridor cache (least recently used dropped first).
CACHE_SIZE = 256
#: Extra half-width [m] of the clipping rectangle beyond half_width + margin.
CLIP_PAD = 1.0


class LegCorridor(NamedTuple):
    """The corridor of one leg (NumPy, read-only; a pytree, so it can be passed into ``jit``).

    Attributes:
        s: along-track abscissae s_i ``[S]`` [m], 0 .. length (x_p of the samples).
        lower: g_lh(s_i) ``[S]`` [m], <= 0 (port bound on y_p).
        upper: g_rh(s_i) ``[S]`` [m], >= 0 (starboard bound on y_p).
        inside: ``bool [S]``: S_i lies in the buffered land (both bounds 0 there).
        start: WP_j ``[2]`` (north, east) [m].
        psi: ψ_j [rad] (0-d).
        length: l_j [m] (0-d).
    """

    s: jax.Array
    lower: jax.Array
    upper: jax.Array
    inside: jax.Array
    start: jax.Array
    psi: jax.Array
    length: jax.Array


# ------------------------------------------------------------------------------------------ validation
def _positive(v, name: str, *, allow_zero: bool = False) -> float:
    if isinstance(v, (bool, np.bool_)) or np.ndim(v) != 0:
        raise ValueError(f"{name} must be a number [m], got {v!r}")
    try:
        x = float(v)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number [m], got {v!r}") from None
    if not math.isfinite(x) or (x < 0 if allow_zero else x <= 0):
        raise ValueError(f"{name} must be a finite number {'>= 0' if allow_zero else '> 0'} [m], got {v!r}")
    return x


def _quad_segs(q) -> int:
    if isinstance(q, bool) or not isinstance(q, (int, np.integer)) or q < 1:
        raise ValueError(f"quad_segs must be an integer >= 1, got {q!r}")
    return int(q)


def _seg_items(land_polygons) -> list:
    if land_polygons is None:
        return []
    if isinstance(land_polygons, (Polygon, MultiPolygon)):
        return [land_polygons]
    if isinstance(land_polygons, np.ndarray) and land_polygons.ndim == 2:
        return [land_polygons]
    return list(land_polygons)


def land_key(land_polygons) -> str:
    """Content hash (sha1 hex) of a chart given as shapely polygons and/or rings / tuples of rings: WKB of
    the shapely geometries, the float64 bytes of the rings.  Equal charts given the same way hash equal."""
    h = hashlib.sha1()
    for j, p in enumerate(_seg_items(land_polygons)):
        if isinstance(p, (Polygon, MultiPolygon)):
            h.update(b"G")
            h.update(shapely.to_wkb(p))
        else:
            try:
                rings = ring_arrays(p, j)
            except ValueError as e:
                raise ValueError(str(e).replace("polygons[", "land_polygons[", 1)) from None
            except TypeError:
                raise ValueError(f"land_polygons[{j}] must be a shapely polygon, a ring [n >= 3, 2] or a tuple "
                                 f"of rings") from None
            for r in rings:
                h.update(b"R")
                h.update(np.asarray(r.shape, np.int64).tobytes())
                h.update(np.ascontiguousarray(r, np.float64).tobytes())
        h.update(b"|")
    return h.hexdigest()


# ------------------------------------------------------------------------------------------ caches
_PIECES: OrderedDict = OrderedDict()
_CORRIDORS: OrderedDict = OrderedDict()
_STATS = {"hits": 0, "misses": 0}


def _pieces(key: str, land_polygons) -> list:
    if key in _PIECES:
        _PIECES.move_to_end(key)
        return _PIECES[key]
    pieces = land_pieces(land_polygons)
    _PIECES[key] = pieces
    while len(_PIECES) > 8:
        _PIECES.popitem(last=False)
    return pieces


def clear_corridor_cache() -> None:
    """Empty the corridor cache (and the cached land pieces)."""
    _PIECES.clear()
    _CORRIDORS.clear()
    _STATS.update(hits=0, misses=0)


def corridor_cache_info() -> dict:
    """``{"hits", "misses", "size", "maxsize"}`` of the corridor cache."""
    return dict(_STATS, size=len(_CORRIDORS), maxsize=CACHE_SIZE)


# ------------------------------------------------------------------------------------------ crossing land
def _segments(w: np.ndarray, legs) -> list:
    return [LineString([w[j], w[j + 1]]) for j in legs]


def split_crossing(piece, segments, reach: float | None, circle_margin: float):
    """Choice TL-8 for one land ``piece`` that meets the leg ``segments``: the circle ``(centre, radius)``
    enclosing the part of the piece within ``reach`` [m] of them (None: the whole piece) (+ ``circle_margin``),
    and the rest of the piece outside that circle (a list of polygons, possibly empty).  The rest lies at
    least ``reach`` from the segments.  The corridor uses ``reach`` = 2 × its buffer margin, so the buffered
    rest stays a margin away from the leg."""
    if reach is None:
        return enclosing_circle(piece, circle_margin), []
    band = shapely.union_all([sg.buffer(max(reach, 1e-9)) for sg in segments])
    near = piece.intersection(band)
    if near.is_empty:                              # touching at a point (reach 0): the point itself
        near = piece.intersection(shapely.union_all(list(segments)))
    centre, r = enclosing_circle(near, 0.0)
    q = 64
    disk = shapely.Point(centre).buffer(r / math.cos(math.pi / (4 * q)) + 1e-9, quad_segs=q)   # covers the circle
    rest = [g for g in shapely.get_parts(piece.difference(disk)) if isinstance(g, Polygon) and g.area > 0]
    return (centre, r + circle_margin), rest


def crossing_land_circles(waypoints, land_polygons, margin: float = DEFAULT_CIRCLE_MARGIN, *, legs=None,
                          reach: float | None = None):
    """Choice TL-8: the land pieces (:func:`~.static_obstacles.land_pieces`) that meet a leg segment (closed:
    touching counts) of ``legs`` (default: every leg), as static circles (minimum enclosing circle +
    ``margin`` >= 0 [m], one per piece, in piece order), and the other pieces.

    Returns ``(circles: StaticCircles, remaining: list[shapely.Polygon])``; ``remaining`` is the land left
    for RG."""
    w = check_waypoints(waypoints)
    margin = _positive(margin, "margin", allow_zero=True)
    n_legs = len(w) - 1
    legs = range(n_legs) if legs is None else [check_leg_index(j, len(w), "legs[]") for j in legs]
    segs = _segments(w, legs)
    pairs, remaining = [], []
    for p in land_pieces(land_polygons):
        if any(p.intersects(sg) for sg in segs):
            pair, rest = split_crossing(p, [sg for sg in segs if p.intersects(sg)], reach, margin)
            pairs.append(pair)
            remaining.extend(rest)
        else:
            remaining.append(p)
    return StaticCircles.from_pairs(pairs), remaining


# ------------------------------------------------------------------------------------------ one leg
def _readonly(a):
    a = np.array(a)
    a.flags.writeable = False
    return a


def _compute_leg(a, b, pieces, half_width, sample, radius, margin, circle_margin, quad_segs, device):
    d = b - a
    length = float(np.hypot(d[0], d[1]))
    t = d / length
    n = np.array([-t[1], t[0]])
    psi = math.atan2(d[1], d[0])
    seg = LineString([a, b])
    circles, rg = [], []
    for p in pieces:
        if p.intersects(seg):
            pair, rest = split_crossing(p, [seg], 2.0 * margin, circle_margin)
            circles.append(pair)
            rg.extend(q for q in rest if q.distance(seg) <= radius)
        elif p.distance(seg) <= radius:
            rg.append(p)

    # leg-local coordinates (origin WP_j), clipped to the rectangle no ray can see past
    h = half_width + margin + CLIP_PAD
    rect = Polygon([-h * t - h * n, (length + h) * t - h * n, (length + h) * t + h * n, -h * t + h * n])
    local = []
    for p in rg:
        q = shapely.transform(p, lambda c: c - a).intersection(rect)
        local.extend(g for g in shapely.get_parts(q) if isinstance(g, Polygon) and not g.is_empty and g.area > 0)

    n_s = int(math.ceil(length / sample - 1e-9)) + 1
    n_s = max(n_s, 2)
    if n_s > MAX_SAMPLES:
        raise ValueError(f"sample = {sample:g} m gives {n_s} samples on leg of {length:g} m (more than "
                         f"{MAX_SAMPLES}); use a larger spacing")
    s = np.linspace(0.0, length, n_s)
    pos = s[:, None] * t[None, :]
    if device:
        dtype = "float64" if jax.config.jax_enable_x64 else "float32"
        chart = buffered_chart(local, margin, quad_segs=quad_segs, dtype=dtype)
        cap = bucket(n_s, MIN_SAMPLE_BUCKET)
        padded = np.concatenate([pos, np.repeat(pos[-1:], cap - n_s, axis=0)])
        c = cross_track_corridor(padded, chart, half_width, heading=psi)
        lower, upper, inside = (np.asarray(x)[:n_s] for x in (c.lower, c.upper, c.inside))
    else:
        c = cross_track_corridor_shapely(pos, local, margin, half_width, heading=psi, quad_segs=quad_segs)
        lower, upper, inside = c.lower, c.upper, c.inside
    corridor = LegCorridor(_readonly(s), _readonly(np.asarray(lower, float)), _readonly(np.asarray(upper, float)),
                           _readonly(np.asarray(inside, bool)), _readonly(a), _readonly(np.float64(psi)),
                           _readonly(np.float64(length)))
    return corridor, tuple(circles)


def _add_circles(out, circles) -> None:
    if out is None:
        return
    if not hasattr(out, "append"):
        raise ValueError(f"static_circles_out must be a list (circles are appended), got {type(out).__name__}")
    for c, r in circles:
        if not any(np.array_equal(c, c2) and r == r2 for c2, r2 in out):
            out.append((np.array(c), float(r)))


def leg_corridor(waypoints, j, land_polygons, *, margin, half_width: float = DEFAULT_HALF_WIDTH,
                 sample: float = DEFAULT_SAMPLE, radius: float | None = None,
                 circle_margin: float = DEFAULT_CIRCLE_MARGIN, quad_segs: int = DEFAULT_QUAD_SEGS,
                 static_circles_out: list | None = None, device: bool = True) -> LegCorridor:
    """Algorithm 1 for leg ``j`` of the route ``waypoints [n >= 2, 2]`` (north, east) [m]: the
    :class:`LegCorridor` (cached; see the module docstring).

    Args:
        land_polygons: the chart: shapely (Multi)Polygons, rings ``[n, 2]`` or tuples of rings (outer, holes).
        margin: buffer of the land >= 0 [m] (proposed r_os + 2 m).
        half_width: Δd > 0 [m], the half-width where no land is near.
        sample: ds > 0 [m], the largest sample spacing (e.g. U·dt of the upper MPC).
        radius: R_RG [m] >= 0: only land pieces within this distance of the leg segment form RG.  Default
            (``None``): half_width + margin, i.e. all land a ray can reach; a smaller value ignores farther land.
        circle_margin: >= 0 [m] added to the enclosing circle of land crossing the leg (choice TL-8).
        quad_segs: shapely buffer segments per quarter circle.
        static_circles_out: a list that receives ``(centre [2], radius)`` of each land piece crossing the leg
            (not already in it); :meth:`StaticCircles.from_pairs` turns it into circles.
        device: the jitted ray cast (True) or the shapely oracle (False).

    Raises ``ValueError`` naming the field on bad input."""
    w = check_waypoints(waypoints)
    j = check_leg_index(j, len(w))
    margin = _positive(margin, "margin", allow_zero=True)
    half_width = _positive(half_width, "half_width")
    sample = _positive(sample, "sample")
    radius = half_width + margin if radius is None else _positive(radius, "radius", allow_zero=True)
    circle_margin = _positive(circle_margin, "circle_margin", allow_zero=True)
    quad_segs = _quad_segs(quad_segs)
    if not isinstance(device, (bool, np.bool_)):
        raise ValueError(f"device must be True or False, got {device!r}")
    if static_circles_out is not None and not hasattr(static_circles_out, "append"):
        raise ValueError(f"static_circles_out must be a list (circles are appended), got "
                         f"{type(static_circles_out).__name__}")
    lk = land_key(land_polygons)
    a, b = w[j].copy(), w[j + 1].copy()
    key = (lk, a.tobytes(), b.tobytes(), half_width, sample, radius, margin, circle_margin, quad_segs, bool(device),
           bool(jax.config.jax_enable_x64) if device else None)  # type: ignore[attr-defined]  # jax's Config stub lacks its flags
    if key in _CORRIDORS:
        _CORRIDORS.move_to_end(key)
        _STATS["hits"] += 1
        corridor, circles = _CORRIDORS[key]
    else:
        _STATS["misses"] += 1
        corridor, circles = _compute_leg(a, b, _pieces(lk, land_polygons), half_width, sample, radius, margin,
                                         circle_margin, quad_segs, bool(device))
        _CORRIDORS[key] = (corridor, circles)
        while len(_CORRIDORS) > CACHE_SIZE:
            _CORRIDORS.popitem(last=False)
    _add_circles(static_circles_out, circles)
    return corridor


def leg_corridors(waypoints, land_polygons, **kwargs) -> tuple:
    """:func:`leg_corridor` for every leg 0 .. n − 2 (same keyword arguments); a tuple of
    :class:`LegCorridor`.  ``static_circles_out`` receives each crossing land piece once."""
    w = check_waypoints(waypoints)
    return tuple(leg_corridor(w, j, land_polygons, **kwargs) for j in range(len(w) - 1))


# ------------------------------------------------------------------------------------------ evaluation
def _check_corridor(corridor) -> None:
    if not isinstance(corridor, LegCorridor):
        raise ValueError(f"corridor must be a LegCorridor, got {type(corridor).__name__}")
    s = np.shape(corridor.s)
    if len(s) != 1 or s[0] < 2 or np.shape(corridor.lower) != s or np.shape(corridor.upper) != s:
        raise ValueError(f"corridor.s, .lower, .upper must have one shape [S >= 2], got {s}, "
                         f"{np.shape(corridor.lower)}, {np.shape(corridor.upper)}")


def _float(x):
    a = jnp.asarray(x)
    return a if jnp.issubdtype(a.dtype, jnp.floating) else a.astype(jnp.result_type(float))


def corridor_bounds(corridor: LegCorridor, s_query):
    """Choice TL-4: the bounds (g_lh, g_rh) at along-track positions ``s_query`` (any shape) [m]: linear
    interpolation through the samples, clamped to the end values outside [0, l_j].  jax.numpy, traceable,
    differentiable w.r.t. ``s_query`` (slope of the segment; 0 outside the leg).  Returns ``(lower, upper)``
    shaped like ``s_query``."""
    _check_corridor(corridor)
    q = _float(s_query)
    s = jnp.asarray(corridor.s, q.dtype)
    return (jnp.interp(q, s, jnp.asarray(corridor.lower, q.dtype)),
            jnp.interp(q, s, jnp.asarray(corridor.upper, q.dtype)))


def corridor_residuals(positions, corridor: LegCorridor):
    """Corridor constraints for NED ``positions [..., 2]`` (north, east) on this leg: with (x_p, y_p) the
    path-frame coordinates (eq. 3, from ``corridor.start`` and ``corridor.psi``), returns
    ``(g_lh(x_p) − y_p, y_p − g_rh(x_p))`` (each ``[...]``; feasible when both <= 0).  jax.numpy,
    differentiable w.r.t. ``positions``."""
    _check_corridor(corridor)
    if np.ndim(positions) < 1 or np.shape(positions)[-1] != 2:
        raise ValueError(f"positions must have shape [..., 2] (north, east), got {np.shape(positions)}")
    q = to_leg_frame(positions, corridor.start, corridor.psi)
    xp, yp = q[..., 0], q[..., 1]
    lo, up = corridor_bounds(corridor, xp)
    return lo - yp, yp - up


__all__ = ["LegCorridor", "DEFAULT_HALF_WIDTH", "DEFAULT_SAMPLE", "DEFAULT_CIRCLE_MARGIN", "CACHE_SIZE",
           "land_key", "crossing_land_circles", "split_crossing", "leg_corridor", "leg_corridors", "corridor_bounds",
           "corridor_residuals", "clear_corridor_cache", "corridor_cache_info"]
