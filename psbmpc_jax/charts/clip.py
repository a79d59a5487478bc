"""Clipping: the range filter that keeps the hazards within ``d_so`` of the own-ship (whole polygons, or clipped
to a disc), and :func:`areal_parts`, the polygon parts of a repaired or clipped geometry."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Point, Polygon

from .chart import Chart


def areal_parts(geom) -> tuple[list[Polygon], int]:
    """Polygon parts of a geometry (after repair / intersection) and the number of other parts dropped."""
    parts, dropped = [], 0
    for g in shapely.get_parts(geom):
        if isinstance(g, Polygon) and not g.is_empty and g.area > 0.0:
            parts.append(g)
        elif isinstance(g, (MultiPolygon, shapely.GeometryCollection)):
            p, d = areal_parts(g)
            parts += p
            dropped += d
        else:
            dropped += 1
    return parts, dropped


def range_filter(chart: Chart, position, d_so: float, *, mode: str = "clip", n_arc: int = 128) -> Chart:
    """Keep the grounding hazards within ``d_so`` of the own-ship ``position`` (local north, east) [m].

    ``mode="whole"`` (the authors' C++ behaviour): keep every polygon whose distance to ``position`` is
    ``<= d_so`` (0 if inside), unchanged.  ``mode="clip"`` (default): additionally intersect each kept
    polygon with a clip region ``C`` -- the regular ``n_arc``-gon circumscribing the disc of radius ``d_so``
    (so ``C`` contains the disc and extends at most ``d_so (1/cos(pi/n_arc) - 1)`` beyond it, 0.06 m for
    200 m and 128 sides).  Polygons entirely inside the disc are kept unchanged (no new vertices).

    Why clipping is safe for the grounding cost: a clipped part ``P ∩ C`` is a subset of the hazard ``P``, so
    (i) its new edges along the arc lie inside ``P`` -- no hazard is invented, and no point gets closer to
    land than it really is; (ii) for any point ``q`` the distance to ``P ∩ C`` equals the distance to ``P``
    whenever the nearest point of ``P`` lies in the disc -- in particular at the own-ship position itself and at
    every ``q`` with ``d(q, P) + |q - position| <= d_so``; and inside/outside is exact in the disc.  Distances are
    over-estimated only for predicted positions whose nearest land is beyond ``d_so`` -- hazards the range
    filter declares out of scope anyway, exactly as the whole-polygon filter does for a polygon just beyond
    ``d_so``; the grounding cost there is at most ``exp(-G3 (d_so - |q - position| - d_safe))`` of its peak.  The
    gain: a polygon such as the 21 961-vertex land around Nidelva keeps only its few hundred vertices near
    the ship instead of all of them.  Re-run the filter at every solve (the disc follows the ship).

    Parts that become empty or non-areal are dropped and counted.  ``report`` gains ``range_position``,
    ``range_d_so``, ``range_mode``, ``range_removed`` (polygons beyond ``d_so``), ``range_clipped``
    (polygons cut by the disc) and ``range_dropped_parts``.
    """
    if mode not in ("clip", "whole"):
        raise ValueError(f"mode must be 'clip' or 'whole', got {mode!r}")
    pos = np.asarray(position, float)
    if pos.shape != (2,) or not np.all(np.isfinite(pos)):
        raise ValueError(f"position must be a finite (north, east) pair, got {position!r}")
    d_so = float(d_so)
    if not math.isfinite(d_so) or d_so <= 0.0:
        raise ValueError(f"d_so must be a finite distance > 0 m, got {d_so}")
    if int(n_arc) < 8:
        raise ValueError(f"n_arc must be >= 8, got {n_arc}")
    pt = Point(pos)
    polys = np.array(chart.polygons, dtype=object)
    dist = shapely.distance(polys, pt) if len(polys) else np.zeros(0)
    within = dist <= d_so
    out, ids, layers = [], [], []
    clipped = dropped = 0
    if mode == "clip":
        n = int(n_arc)
        ang = 2.0 * np.pi * np.arange(n) / n
        r = d_so / math.cos(math.pi / n)
        clip = Polygon(np.stack([pos[0] + r * np.cos(ang), pos[1] + r * np.sin(ang)], axis=1))
        shapely.prepare(clip)
    for j in np.flatnonzero(within):
        p = chart.polygons[j]
        if mode == "whole" or shapely.hausdorff_distance(pt, p.exterior) <= d_so:
            parts = [p]
        else:
            parts, d = areal_parts(p.intersection(clip))
            dropped += d
            clipped += 1
        for q in parts:
            out.append(q)
            ids.append(chart.ids[j])
            layers.append(chart.layers[j])
    report = dict(chart.report)
    report.update(range_position=(float(pos[0]), float(pos[1])), range_d_so=d_so, range_mode=mode,
                  range_removed=int((~within).sum()), range_clipped=clipped, range_dropped_parts=dropped)
    return dataclasses.replace(chart, polygons=tuple(out), ids=tuple(ids), layers=tuple(layers), report=report)
