"""To the device: polygons as float64 (north, east) rings for ``Situation.polygons`` -- outer rings only
(:func:`to_rings`) or outer ring and holes (:func:`to_ring_sets`, the even-odd multi-ring form)."""

from __future__ import annotations

import numpy as np
from shapely.geometry import MultiPolygon, Polygon

from .chart import Chart


def _polygon_list(polygons) -> list[Polygon]:
    if isinstance(polygons, Chart):
        return list(polygons.polygons)
    if isinstance(polygons, Polygon):
        return [polygons]
    out = []
    for j, p in enumerate(polygons):
        if isinstance(p, MultiPolygon):
            out += list(p.geoms)
        elif isinstance(p, Polygon):
            out.append(p)
        else:
            raise ValueError(f"polygons[{j}] must be a shapely Polygon, got {type(p).__name__}")
    return out


def _ring_array(ring) -> np.ndarray:
    return np.array(ring.coords, dtype=float)[:-1, :2]


def to_rings(polygons, *, holes: str = "error") -> list[np.ndarray]:
    """Outer rings as float64 ``[n, 2]`` (north, east) arrays for ``Situation.polygons``: vertex order as
    stored, closing vertex dropped.

    ``holes="error"`` (default) raises if a polygon has holes (use :func:`to_ring_sets` for the even-odd
    multi-ring form); ``holes="fill"`` drops the holes -- the hole then counts as land (conservative)."""
    if holes not in ("error", "fill"):
        raise ValueError(f"holes must be 'error' or 'fill', got {holes!r}")
    out = []
    for j, p in enumerate(_polygon_list(polygons)):
        if p.is_empty:
            raise ValueError(f"polygons[{j}] is empty")
        if len(p.interiors) and holes == "error":
            raise ValueError(f"polygons[{j}] has {len(p.interiors)} hole(s); use to_ring_sets() for outer ring + "
                             f"holes (even-odd rule), or to_rings(..., holes='fill') to treat holes as land")
        out.append(_ring_array(p.exterior))
    return out


def to_ring_sets(polygons) -> list[tuple[np.ndarray, ...]]:
    """Every polygon as a tuple of rings ``(outer, hole1, ...)`` (north, east; closing vertices dropped; order
    as stored) -- the multi-ring form of ``Situation.polygons`` (inside = odd number of ring crossings)."""
    out = []
    for j, p in enumerate(_polygon_list(polygons)):
        if p.is_empty:
            raise ValueError(f"polygons[{j}] is empty")
        out.append(tuple([_ring_array(p.exterior)] + [_ring_array(r) for r in p.interiors]))
    return out
