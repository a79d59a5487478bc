"""Static obstacles of the upper level of the two-level MPC (Mahipala & Johansen 2023, eqs. 10, 12;
``docs/two_level_geometry.md``): circles (centre [north, east], radius) and the per-step constraint

    ||p_k − c_i|| >= L_i = r_i + r_os,

as residuals h = L_i − ||p_k − c_i|| <= 0 (:func:`circle_residuals`).  The radius r_i includes every
margin of the obstacle itself; r_os (the own-ship's radius) is added by the constraint.

Circles come from a scenario file (:func:`from_yaml`: a list of ``{center_m: [n, e], radius_m: r}``) or
from land (:func:`circles_from_land`, :func:`enclosing_circle`: the minimum enclosing circle of a land
piece plus a margin; choice TL-8 (docs/algorithm.md §15; the enclosing circle follows Sec. IX-B of Mahipala & Johansen
2024) uses it for the land that crosses a route leg, see :func:`psbmpc_jax.two_level.riparian.crossing_land_circles`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Polygon
from shapely.ops import unary_union

from ..array_types import HostOrDevice
from ..numerics import safe_sqrt
from ..smooth.corridor import ring_arrays


class StaticCircles(NamedTuple):
    """Circular static obstacles (a pytree: pass it into ``jit``).

    Attributes:
        centres: ``[n, 2]`` (north, east) [m].
        radii: ``[n]`` [m], >= 0, margins included (the constraint adds r_os).

    Build validated instances with :meth:`build` (or :func:`from_yaml`, :func:`circles_from_land`);
    the plain constructor does not check (it is also what JAX's pytree machinery calls).
    """

    centres: HostOrDevice
    radii: HostOrDevice

    @classmethod
    def build(cls, centres, radii) -> "StaticCircles":
        """Validated circles as float64 NumPy: ``centres [n, 2]`` finite, ``radii [n]`` finite >= 0."""
        return check_circles(cls(centres, radii))

    @classmethod
    def empty(cls) -> "StaticCircles":
        """No circles (``centres [0, 2]``, ``radii [0]``)."""
        return cls(np.zeros((0, 2)), np.zeros(0))

    @classmethod
    def from_pairs(cls, pairs) -> "StaticCircles":
        """Circles from ``(centre [2], radius)`` pairs (validated)."""
        pairs = list(pairs)
        if not pairs:
            return cls.empty()
        try:
            centres = np.array([np.asarray(c, dtype=float) for c, _ in pairs], dtype=float)
            radii = np.array([float(r) for _, r in pairs])
        except (TypeError, ValueError):
            raise ValueError("pairs must be (centre [north, east], radius) pairs of numbers") from None
        return cls.build(centres, radii)

    @property
    def n_circles(self) -> int:
        """Number of circles n."""
        return int(np.shape(self.radii)[0])


def check_circles(circles, name: str = "circles") -> StaticCircles:
    """Validate a :class:`StaticCircles`; concrete values come back as float64 NumPy, traced ones unchanged
    (shape-checked only)."""
    if not isinstance(circles, StaticCircles):
        raise ValueError(f"{name} must be a StaticCircles, got {type(circles).__name__}")
    c, r = circles
    cs, rs = np.shape(c), np.shape(r)
    if len(cs) != 2 or cs[1] != 2:
        raise ValueError(f"{name}.centres must have shape [n, 2] (north, east), got {cs}")
    if rs != cs[:1]:
        raise ValueError(f"{name}.radii must have shape [{cs[0]}] (one per centre), got {rs}")
    if isinstance(c, jax.core.Tracer) or isinstance(r, jax.core.Tracer):
        return circles
    try:
        c, r = np.asarray(c, dtype=float), np.asarray(r, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: centres and radii must be numbers") from None
    if not np.all(np.isfinite(c)):
        raise ValueError(f"{name}.centres must be finite (circle {int(np.argwhere(~np.isfinite(c))[0, 0])})")
    bad = np.flatnonzero(~(np.isfinite(r) & (r >= 0)))
    if bad.size:
        raise ValueError(f"{name}.radii must be finite and >= 0 [m], got {r[bad[0]]!r} for circle {int(bad[0])}")
    return StaticCircles(c, r)


def concat_circles(*items: StaticCircles) -> StaticCircles:
    """Concatenate several :class:`StaticCircles` (validated)."""
    checked = [check_circles(c, f"items[{k}]") for k, c in enumerate(items)]
    if not checked:
        return StaticCircles.empty()
    return StaticCircles(np.concatenate([np.asarray(c.centres, float).reshape(-1, 2) for c in checked]),
                         np.concatenate([np.asarray(c.radii, float).reshape(-1) for c in checked]))


# ------------------------------------------------------------------------------------------ from YAML
def _yaml_number(v, where: str, *, ge=None) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
        raise ValueError(f"{where} must be a finite number, got {v!r}"[:300])
    try:
        x = float(v)
    except OverflowError:
        raise ValueError(f"{where} must be a finite number, got an integer that is too large") from None
    if not math.isfinite(x):
        raise ValueError(f"{where} must be a finite number, got {v!r}")
    if ge is not None and x < ge:
        raise ValueError(f"{where} must be >= {ge:g}, got {v!r}")
    return x


def from_yaml(entries, where: str = "static_obstacles") -> StaticCircles:
    """Circles from a scenario list ``[{center_m: [north, east], radius_m: r}, ...]`` (``None`` or ``[]``:
    none).  ``radius_m`` >= 0 [m] includes the obstacle's margins.  ``ValueError`` naming the entry and the
    field (``static_obstacles[2].radius_m ...``) on a missing / unknown key or a bad value."""
    if entries is None:
        return StaticCircles.empty()
    if isinstance(entries, (str, bytes, Mapping)) or not isinstance(entries, Sequence):
        raise ValueError(f"{where} must be a list of {{center_m: [north, east], radius_m: r}}, got "
                         f"{type(entries).__name__}")
    centres, radii = [], []
    for k, e in enumerate(entries):
        w = f"{where}[{k}]"
        if not isinstance(e, Mapping):
            raise ValueError(f"{w} must be a mapping {{center_m: [north, east], radius_m: r}}, got "
                             f"{type(e).__name__}")
        unknown = sorted(set(map(str, e)) - {"center_m", "radius_m"})
        if unknown:
            raise ValueError(f"{w}: unknown key(s) {', '.join(unknown)} (expected center_m, radius_m)")
        for key in ("center_m", "radius_m"):
            if key not in e:
                raise ValueError(f"{w}.{key} is missing")
        c = e["center_m"]
        if isinstance(c, (str, bytes, Mapping)) or not isinstance(c, Sequence) or len(c) != 2:
            raise ValueError(f"{w}.center_m must be a list [north, east] of 2 numbers [m], got {c!r}"[:300])
        centres.append([_yaml_number(v, f"{w}.center_m[{i}]") for i, v in enumerate(c)])
        radii.append(_yaml_number(e["radius_m"], f"{w}.radius_m", ge=0.0))
    if not centres:
        return StaticCircles.empty()
    return StaticCircles(np.array(centres, dtype=float), np.array(radii, dtype=float))


# ------------------------------------------------------------------------------------------ from land
def as_land_polygons(land_polygons, name: str = "land_polygons") -> list:
    """Land as a list of valid shapely polygons: accepts a shapely (Multi)Polygon, or a sequence of shapely
    (Multi)Polygons, rings ``[n, 2]`` (north, east) and tuples of rings (outer ring, holes) as
    :class:`psbmpc_jax.Situation` / the scenario loader hold them.  ``ValueError`` naming the polygon."""
    if land_polygons is None:
        return []
    if isinstance(land_polygons, (Polygon, MultiPolygon)):
        land_polygons = [land_polygons]
    if isinstance(land_polygons, np.ndarray) and land_polygons.ndim == 2:
        land_polygons = [land_polygons]        # one ring given bare
    out: list[Polygon | MultiPolygon] = []
    for j, p in enumerate(land_polygons):
        if isinstance(p, (Polygon, MultiPolygon)):
            g = p
        else:
            try:
                arrs = ring_arrays(p, j)
            except ValueError as e:
                raise ValueError(str(e).replace("polygons[", f"{name}[", 1)) from None
            except TypeError:
                raise ValueError(f"{name}[{j}] must be a shapely polygon, a ring [n >= 3, 2] or a tuple of "
                                 f"rings") from None
            g = Polygon(arrs[0], arrs[1:])
        if not g.is_valid:
            g = shapely.make_valid(g)
        out.extend(q for q in shapely.get_parts(g) if isinstance(q, (Polygon, MultiPolygon)) and not q.is_empty)
    return out


def land_pieces(land_polygons) -> list:
    """The connected land pieces: the polygon parts of the union of the land (overlapping polygons merge
    into one piece), in a deterministic order (by their bounds)."""
    polys = as_land_polygons(land_polygons)
    if not polys:
        return []
    parts = [p for p in shapely.get_parts(unary_union(polys)) if isinstance(p, Polygon) and not p.is_empty]
    return sorted(parts, key=lambda p: p.bounds)


def enclosing_circle(geometry, margin: float = 0.0) -> tuple[np.ndarray, float]:
    """The minimum enclosing circle of a shapely geometry (``shapely.minimum_bounding_circle``), its radius
    raised to the farthest vertex from the centre (guards the rounding of the centre), plus ``margin`` >= 0.
    Returns ``(centre [2], radius)``."""
    margin = float(margin)
    if not math.isfinite(margin) or margin < 0:
        raise ValueError(f"margin must be a finite number >= 0 [m], got {margin!r}")
    if geometry.is_empty:
        raise ValueError("enclosing_circle: the geometry is empty")
    circle = shapely.minimum_bounding_circle(geometry)
    if isinstance(circle, Polygon) and not circle.is_empty:
        centre = np.asarray(circle.centroid.coords[0], dtype=float)
    else:                                              # a point (or a degenerate circle): its own centre
        centre = np.asarray(geometry.centroid.coords[0], dtype=float)
    vertices = shapely.get_coordinates(geometry)
    r = max(float(shapely.minimum_bounding_radius(geometry)),
            float(np.max(np.linalg.norm(vertices - centre, axis=1))) if len(vertices) else 0.0)
    return centre, r + margin


def circles_from_land(land_polygons, margin: float = 0.0) -> StaticCircles:
    """One circle per land piece (:func:`land_pieces`): its minimum enclosing circle plus ``margin`` >= 0 [m]."""
    pairs = [enclosing_circle(p, margin) for p in land_pieces(land_polygons)]
    return StaticCircles.from_pairs(pairs) if pairs else StaticCircles.empty()


# ------------------------------------------------------------------------------------------ constraint
def circle_residuals(positions, circles: StaticCircles, r_os):
    """Residuals h = L_i − ||p_k − c_i|| with L_i = r_i + r_os: ``positions [..., K, 2]`` (north, east),
    ``circles`` (:class:`StaticCircles`, n circles), ``r_os`` >= 0 [m] -> ``[..., K, n]``; feasible when
    <= 0.  jax.numpy, smooth away from the centres; the distance uses :func:`psbmpc_jax.numerics.safe_sqrt`
    so the gradient at zero distance is finite (0), never NaN."""
    shape = np.shape(positions)
    if len(shape) < 2 or shape[-1] != 2:
        raise ValueError(f"positions must have shape [..., K, 2] (north, east), got {shape}")
    circles = check_circles(circles)
    if np.ndim(r_os) != 0:
        raise ValueError(f"r_os must be a scalar [m], got shape {np.shape(r_os)}")
    if not isinstance(r_os, jax.core.Tracer):
        if isinstance(r_os, (bool, np.bool_)):
            raise ValueError(f"r_os must be a number [m], got {r_os!r}")
        v = float(r_os)
        if not math.isfinite(v) or v < 0:
            raise ValueError(f"r_os must be a finite number >= 0 [m], got {r_os!r}")
    p = jnp.asarray(positions)
    if not jnp.issubdtype(p.dtype, jnp.floating):
        p = p.astype(jnp.result_type(float))
    c = jnp.asarray(circles.centres, p.dtype)
    r = jnp.asarray(circles.radii, p.dtype)
    d = p[..., :, None, :] - c                                          # [..., K, n, 2]
    dist = safe_sqrt(jnp.sum(d * d, axis=-1))
    return r + jnp.asarray(r_os, p.dtype) - dist


__all__ = ["StaticCircles", "check_circles", "concat_circles", "from_yaml", "as_land_polygons", "land_pieces",
           "enclosing_circle", "circles_from_land", "circle_residuals"]
