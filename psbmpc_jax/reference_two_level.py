"""Float64 NumPy/shapely oracle of the ground-avoiding constant-velocity target prediction of Mahipala & Johansen
(2023; eq. 2; :mod:`psbmpc_jax.two_level.prediction`, docs/two_level_prediction.md). Used only by the tests.

Written independently of the JAX kernel: plain Python loops over targets, steps, polygons and edges; the ray
distance by segment intersection per edge in Python floats, with every near-tie hit/miss decision redone in
exact rational arithmetic (so a ray through a vertex hits it), the inside test by shapely
(``Polygon(outer, holes).covers``, i.e. the boundary counts as land; any polygon).  Same conventions as the
kernel: NED (x north, y east [m]), course χ [rad] clockwise from north; p_{k+1} = p_k + dt U (cos χ_k, sin χ_k)
and χ_{k+1} decided from p_k and χ_k; β per step, ties → +β; courses not wrapped.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
from shapely.geometry import Point, Polygon


def _rings(polygon) -> list[np.ndarray]:
    """A ring ``[n, 2]`` or a sequence of rings (outer, then holes) as a list of float64 arrays."""
    if isinstance(polygon, (list, tuple)) and len(polygon) and np.ndim(polygon[0]) == 2:
        return [np.asarray(r, dtype=float) for r in polygon]
    return [np.asarray(polygon, dtype=float)]


def _cross(ax: float, ay: float, bx: float, by: float) -> float:
    return ax * by - ay * bx


def _ray_segment_t_exact(o, dx: float, dy: float, a, b) -> float:
    """:func:`ray_segment_t` in exact rational arithmetic on the float inputs (``fractions.Fraction``)."""
    ox, oy, ax, ay, bx, by = (Fraction(float(v)) for v in (o[0], o[1], a[0], a[1], b[0], b[1]))
    fdx, fdy = Fraction(dx), Fraction(dy)
    ex, ey, wx, wy = bx - ax, by - ay, ax - ox, ay - oy
    den = fdx * ey - fdy * ex
    if den == 0:
        if wx * fdy - wy * fdx != 0:
            return math.inf
        ta, tb = wx * fdx + wy * fdy, (wx + ex) * fdx + (wy + ey) * fdy
        return float(max(min(ta, tb), Fraction(0))) if max(ta, tb) >= 0 else math.inf
    t = (wx * ey - wy * ex) / den
    s = (wx * fdy - wy * fdx) / den
    return float(t) if (t >= 0 and 0 <= s <= 1) else math.inf


def ray_segment_t(o, chi: float, a, b) -> float:
    """Smallest t >= 0 with o + t (cos χ, sin χ) on the closed segment a-b (math.inf when none): Cramer's rule
    in floats, redone exactly (:func:`_ray_segment_t_exact`) whenever a decision is within 1e-9 of its
    threshold (s near 0 or 1, t near 0, a nearly parallel edge), so that every hit/miss decision is exact for
    the float ray and a ray through a vertex hits it."""
    dx, dy = math.cos(chi), math.sin(chi)
    ex, ey = float(b[0]) - float(a[0]), float(b[1]) - float(a[1])
    wx, wy = float(a[0]) - float(o[0]), float(a[1]) - float(o[1])
    den = _cross(dx, dy, ex, ey)
    if abs(den) > 1e-9 * math.hypot(ex, ey):
        t = _cross(wx, wy, ex, ey) / den
        s = _cross(wx, wy, dx, dy) / den
        if min(abs(s), abs(s - 1.0), abs(t)) > 1e-9:
            return t if (t > 0.0 and 0.0 < s < 1.0) else math.inf
    return _ray_segment_t_exact(o, dx, dy, a, b)


def inside_land(p, polygons) -> bool:
    """Whether ``p`` lies in (or on the boundary of) any polygon (shapely)."""
    pt = Point(float(p[0]), float(p[1]))
    for poly in polygons:
        rings = _rings(poly)
        if Polygon(rings[0], rings[1:]).covers(pt):
            return True
    return False


def ray_land_distance_reference(origin, chi: float, polygons, max_range: float) -> float:
    """d_LOSg: 0 inside land, else the first hit over every edge of every ring, math.inf beyond ``max_range``."""
    if inside_land(origin, polygons):
        return 0.0
    best = math.inf
    for poly in polygons:
        for ring in _rings(poly):
            n = len(ring)
            for i in range(n):
                best = min(best, ray_segment_t(origin, chi, ring[i], ring[(i + 1) % n]))
    return best if best <= max_range else math.inf


def ground_avoiding_cv_reference(state, polygons, n_steps: int, dt: float, *, beta, d_critical,
                                 max_range=None, compare: str = "plus"):
    """Eq. (2) step by step for ``state [n_targets, 4]`` (x, y, χ, U) against land ``polygons`` (rings or
    tuples of rings).  ``beta``, ``d_critical``, ``max_range`` (None: 2 d_critical): scalars or per target.
    Returns ``(positions [n, n_steps+1, 2], courses [n, n_steps+1], d_los [n, n_steps])`` (float64)."""
    if compare not in ("plus", "both"):
        raise ValueError(f"compare must be 'plus' or 'both', got {compare!r}")
    S = np.atleast_2d(np.asarray(state, dtype=float))
    n = len(S)
    betas = np.broadcast_to(np.asarray(beta, dtype=float), (n,))
    dcs = np.broadcast_to(np.asarray(d_critical, dtype=float), (n,))
    rngs = 2.0 * dcs if max_range is None else np.broadcast_to(np.asarray(max_range, dtype=float), (n,))
    positions = np.zeros((n, n_steps + 1, 2))
    courses = np.zeros((n, n_steps + 1))
    d_los = np.zeros((n, n_steps))
    for i in range(n):
        x, y, chi, U = (float(v) for v in S[i])
        b, dc, R = float(betas[i]), float(dcs[i]), float(rngs[i])
        positions[i, 0], courses[i, 0] = (x, y), chi
        for k in range(n_steps):
            d0 = ray_land_distance_reference((x, y), chi, polygons, R)
            d_los[i, k] = d0
            if d0 >= dc:
                chi_next = chi
            else:
                dp = ray_land_distance_reference((x, y), chi + b, polygons, R)
                if compare == "plus":
                    chi_next = chi + b if dp >= d0 else chi - b
                else:
                    dm = ray_land_distance_reference((x, y), chi - b, polygons, R)
                    chi_next = chi + b if dp >= dm else chi - b
            x, y = x + dt * U * math.cos(chi), y + dt * U * math.sin(chi)
            chi = chi_next
            positions[i, k + 1], courses[i, k + 1] = (x, y), chi
    return positions, courses, d_los


__all__ = ["ray_segment_t", "inside_land", "ray_land_distance_reference", "ground_avoiding_cv_reference"]
