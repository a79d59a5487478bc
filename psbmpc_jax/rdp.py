"""Ramer-Douglas-Peucker simplification (the paper's Algorithm 1), host side, NumPy.

Algorithm 1 on an open polyline ``P[0..n-1]``: find the vertex ``P[j]`` (0 < j < n-1) farthest from the
segment ``P[0]-P[n-1]``; if that distance is ``> eps`` keep ``P[j]`` and recurse on ``P[0..j]`` and
``P[j..n-1]``, otherwise keep only the two end points.  Details fixed here:

* **Distance.** The distance from a vertex to the *segment* first-last (the perpendicular distance when the
  foot of the perpendicular falls inside the segment, otherwise the distance to the nearer end point).
  When first == last -- as in the first step on a closed ring -- the segment is a point and the distance is
  the distance to that point.  This is what the authors' C++ implementation
  (``distance_to_line_segment`` in ``grounding_hazard_manager.hpp``) and GEOS/shapely both compute.
* **Ties.** A vertex is kept only if its distance is strictly greater than ``eps``; among equal maxima the
  first (lowest index) wins.  The result does not depend on the order in which sub-segments are processed.
* **No recursion.** An explicit stack of index pairs; each step evaluates all interior vertices of one
  segment in one vectorised NumPy call, so a 22 000-vertex ring costs a few milliseconds and no recursion
  limit applies.

Closed rings (:func:`simplify_ring`) need an anchor, because RDP always keeps its two end points.  Two
conventions are implemented (``anchor=``):

* ``"closing"`` (default, GEOS/shapely): run RDP on the closed polyline ``v0, v1, ..., v_{n-1}, v0`` (first ==
  last, so the first split is at the vertex farthest from ``v0``), then -- like GEOS >= 3.12 for polygon
  rings -- drop the anchor ``v0`` itself if it lies within ``eps`` of the segment joining its two
  neighbours in the result (the ring then starts at the next kept vertex).  This reproduces
  ``shapely.simplify(Polygon(ring), eps, preserve_topology=False)`` vertex for vertex, whenever that result
  is a valid polygon (shapely repairs an invalid, self-intersecting result with ``buffer(0)``, which we
  do not do) and is not collapsed (shapely returns an empty polygon, we raise).
* ``"open"`` (the authors' C++ code, used for the paper's Table 2): drop the closing vertex and run RDP on
  the open polyline ``v0, ..., v_{n-1}``; ``v0`` and ``v_{n-1}`` are always kept, so the closing edge
  ``v_{n-1} -> v0`` is never simplified away.

RDP guarantees that every removed vertex lies within ``eps`` of the simplified segment that replaces it
(one-sided Hausdorff distance <= eps).  The GEOS anchor step (``drop_anchor=True``) re-tests only ``v0``
itself, so the vertices next to it may end up up to ``2 eps`` away (distance to a segment is convex along the
old edge ``v_{m-1} -> v0``); ``"open"`` and ``"closing"`` with ``drop_anchor=False`` keep the ``eps`` bound
everywhere.  That is why :func:`simplify_chart` -- the chart pipeline -- defaults to ``"open"`` (also the
paper's convention, reproducing its Table 2) while :func:`simplify_ring` defaults to the shapely-identical
convention.  No convention guarantees a simple (non-self-intersecting) result; no topology repair is applied.

A simplified ring with fewer than 3 vertices is never returned: :func:`simplify_ring` raises
:class:`DegenerateRingError`, and :func:`simplify_chart` applies an explicit policy (keep the original
ring, drop it, or raise) and reports the counts in the chart's ``report``.
"""

from __future__ import annotations

import argparse
import dataclasses
from typing import Iterable, Sequence

import numpy as np

__all__ = [
    "DegenerateRingError", "segment_distance", "rdp_mask", "rdp", "simplify_ring", "simplify_chart",
    "TABLE2_PAPER_BEFORE", "TABLE2_PAPER_AFTER", "table2", "format_table2", "main",
]

ANCHORS = ("closing", "open")
ON_DEGENERATE = ("keep", "drop", "raise")

#: The paper's Table 2 (Nidelva polygons 1..13): vertices before and after RDP with eps = 2 m.
TABLE2_PAPER_BEFORE = (8, 207, 649, 322, 140, 890, 207, 8, 8, 1633, 2110, 2483, 21961)
TABLE2_PAPER_AFTER = (3, 27, 95, 33, 18, 53, 48, 3, 5, 187, 162, 143, 1734)


class DegenerateRingError(ValueError):
    """The simplified ring has fewer than 3 vertices (the whole ring lies within eps of a segment)."""


# --------------------------------------------------------------------------------------------- core
def segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Euclidean distances from ``points`` [m, 2] to the closed segment ``a``-``b``.

    ``a == b`` gives the distance to the point ``a``."""
    points = np.asarray(points, float)
    a = np.asarray(a, float)
    ab = np.asarray(b, float) - a
    ap = points - a
    L2 = float(ab @ ab)
    if L2 == 0.0:
        return np.hypot(ap[:, 0], ap[:, 1])
    t = np.clip((ap @ ab) / L2, 0.0, 1.0)
    d = ap - t[:, None] * ab
    return np.hypot(d[:, 0], d[:, 1])


def _as_points(points, name: str = "points") -> np.ndarray:
    arr = np.asarray(points, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ValueError(f"{name} must have shape [n, 2], got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} contains non-finite coordinates")
    return arr


def _check_eps(eps: float) -> float:
    eps = float(eps)
    if not np.isfinite(eps) or eps < 0.0:
        raise ValueError(f"eps must be a finite distance >= 0, got {eps}")
    return eps


def rdp_mask(points, eps: float) -> np.ndarray:
    """Algorithm 1 on the open polyline ``points`` [n, 2]: boolean mask of the kept vertices.

    The first and last vertices are always kept.  A vertex is kept when it is the farthest vertex (first
    one on ties) from the current segment and its distance is ``> eps``.  Iterative, one vectorised
    distance evaluation per visited segment."""
    pts = _as_points(points)
    eps = _check_eps(eps)
    n = len(pts)
    keep = np.zeros(n, dtype=bool)
    if n == 0:
        return keep
    keep[0] = keep[-1] = True
    stack = [(0, n - 1)]
    while stack:
        i, j = stack.pop()
        if j - i < 2:
            continue
        d = segment_distance(pts[i + 1:j], pts[i], pts[j])
        k = int(np.argmax(d))
        if d[k] > eps:
            k += i + 1
            keep[k] = True
            stack.append((k, j))
            stack.append((i, k))
    return keep


def rdp(points, eps: float) -> np.ndarray:
    """Algorithm 1: the simplified open polyline (kept vertices of ``points`` in their order)."""
    pts = _as_points(points)
    return pts[rdp_mask(pts, eps)]


def _clean_ring(ring, name: str = "ring") -> np.ndarray:
    """Drop consecutive duplicate vertices and a repeated closing vertex."""
    pts = _as_points(ring, name)
    if len(pts) == 0:
        return pts
    keep = np.r_[True, np.any(pts[1:] != pts[:-1], axis=1)]
    pts = pts[keep]
    while len(pts) > 1 and np.array_equal(pts[0], pts[-1]):
        pts = pts[:-1]
    return pts


def simplify_ring(ring, eps: float, *, anchor: str = "closing", drop_anchor: bool = True) -> np.ndarray:
    """Simplify a closed ring ``[n, 2]`` (closing vertex optional; consecutive duplicates are ignored).

    Returns the kept vertices ``[m, 2]``, ``m >= 3``, in the input order and without a closing vertex.
    ``anchor="closing"`` (default) runs RDP on ``v0..v_{n-1}, v0`` and, with ``drop_anchor=True``, then
    removes ``v0`` if it is within ``eps`` of the segment between its kept neighbours -- the GEOS/shapely
    convention; ``anchor="open"`` runs RDP on ``v0..v_{n-1}`` (the authors' C++ convention, closing edge
    always kept).  See the module docstring.  Raises :class:`DegenerateRingError` when fewer than 3
    vertices would remain, ``ValueError`` for bad input."""
    if anchor not in ANCHORS:
        raise ValueError(f"anchor must be one of {ANCHORS}, got {anchor!r}")
    pts = _clean_ring(ring)
    if len(pts) < 3:
        raise ValueError(f"ring must have at least 3 distinct vertices, got {len(pts)}")
    if anchor == "open":
        out = pts[rdp_mask(pts, eps)]
    else:
        closed = np.vstack([pts, pts[:1]])
        out = closed[rdp_mask(closed, eps)][:-1]
        if drop_anchor and len(out) >= 3:
            if segment_distance(out[:1], out[1], out[-1])[0] <= float(eps):
                out = out[1:]
    if len(out) < 3:
        raise DegenerateRingError(
            f"RDP with eps={float(eps)} m reduces a {len(pts)}-vertex ring to {len(out)} vertices "
            f"(every vertex lies within eps of one segment)")
    return out


# --------------------------------------------------------------------------------------------- charts
def simplify_chart(chart, eps: float, *, anchor: str = "open", drop_anchor: bool = True,
                   on_degenerate: str = "keep"):
    """RDP-simplify every ring (outer and holes) of a :class:`psbmpc_jax.charts.Chart`.

    ``anchor`` defaults to ``"open"``: the paper's (and the authors' C++) convention, which keeps every
    removed vertex within ``eps`` of the result; ``anchor="closing"`` gives shapely's output (see
    :func:`simplify_ring`).

    ``on_degenerate`` says what happens to an *outer* ring that would collapse below 3 vertices:
    ``"keep"`` (default) keeps the original, unsimplified polygon -- never lose an obstacle;
    ``"drop"`` removes the polygon; ``"raise"`` raises :class:`DegenerateRingError`.  A collapsing *hole*
    is always removed (the polygon then covers it: conservative for grounding).  The returned chart's
    ``report`` gains ``rdp_eps``, ``rdp_anchor``, ``rdp_vertices_before``/``_after`` (all rings),
    ``rdp_degenerate_kept``, ``rdp_degenerate_dropped`` and ``rdp_holes_dropped``."""
    from shapely.geometry import Polygon

    eps = _check_eps(eps)
    if on_degenerate not in ON_DEGENERATE:
        raise ValueError(f"on_degenerate must be one of {ON_DEGENERATE}, got {on_degenerate!r}")
    polys, ids, layers = [], [], []
    before = after = kept = dropped = holes_dropped = 0
    for j, poly in enumerate(chart.polygons):
        shell = np.asarray(poly.exterior.coords)[:-1]
        before += len(shell)
        try:
            new_shell = simplify_ring(shell, eps, anchor=anchor, drop_anchor=drop_anchor)
        except DegenerateRingError as err:
            if on_degenerate == "raise":
                raise DegenerateRingError(f"polygon {j} (id {chart.ids[j]}) of {chart.source}: {err}") from None
            if on_degenerate == "drop":
                dropped += 1
                before += sum(len(r.coords) - 1 for r in poly.interiors)
                continue
            kept += 1
            new_shell = shell
        holes = []
        for ring in poly.interiors:
            h = np.asarray(ring.coords)[:-1]
            before += len(h)
            try:
                holes.append(simplify_ring(h, eps, anchor=anchor, drop_anchor=drop_anchor))
            except DegenerateRingError:
                holes_dropped += 1
        after += len(new_shell) + sum(len(h) for h in holes)
        polys.append(Polygon(new_shell, holes))
        ids.append(chart.ids[j])
        layers.append(chart.layers[j])
    report = dict(chart.report)
    report.update(rdp_eps=eps, rdp_anchor=anchor, rdp_vertices_before=before, rdp_vertices_after=after,
                  rdp_degenerate_kept=kept, rdp_degenerate_dropped=dropped, rdp_holes_dropped=holes_dropped)
    return dataclasses.replace(chart, polygons=tuple(polys), ids=tuple(ids), layers=tuple(layers),
                               report=report)


# --------------------------------------------------------------------------------------------- Table 2
def table2(chart, eps: float = 2.0, *, anchor: str = "open") -> list[dict]:
    """The paper's Table 2 measured on ``chart`` (the shipped Trondheim CSV chart, unclipped).

    The 13 Nidelva polygons are the CSV's polygons with file indices
    :data:`psbmpc_jax.charts.TABLE2_FILE_INDICES` (their vertex counts identify them uniquely: a mismatch
    raises).  ``before`` counts distinct ring vertices (repeated closing points removed at load), ``after``
    the vertices of ``simplify_ring(ring, eps, anchor=anchor)`` -- by default the authors' ``"open"``
    convention.  Each row also has ``after_closing`` (the GEOS/shapely convention, 0 if collapsed),
    ``polygon`` (1..13) and ``file_index``."""
    from .charts import TABLE2_FILE_INDICES

    rows = []
    for k, (fid, pb, pa) in enumerate(zip(TABLE2_FILE_INDICES, TABLE2_PAPER_BEFORE, TABLE2_PAPER_AFTER)):
        matches = [p for p, i in zip(chart.polygons, chart.ids) if i == fid]
        if len(matches) != 1:
            raise ValueError(f"Table 2 polygon {k + 1} (file index {fid}) must appear exactly once in the "
                             f"chart, found {len(matches)}; pass the unclipped chart from trondheim_chart()")
        ring = np.asarray(matches[0].exterior.coords)[:-1]
        if len(ring) != pb:
            raise ValueError(f"Table 2 polygon {k + 1} (file index {fid}) has {len(ring)} vertices, "
                             f"the paper lists {pb}: not the Nidelva chart")
        after = len(simplify_ring(ring, eps, anchor=anchor))
        try:
            after_closing = len(simplify_ring(ring, eps, anchor="closing"))
        except DegenerateRingError:
            after_closing = 0
        rows.append(dict(polygon=k + 1, file_index=fid, before=len(ring), after=after, paper_before=pb,
                         paper_after=pa, after_closing=after_closing))
    return rows


def format_table2(rows: Sequence[dict], title: str = "") -> str:
    """Markdown table of :func:`table2` rows."""
    lines = [title] if title else []
    lines += ["| Polygon | file index | before | paper before | after | paper after | diff | after (closing) |",
              "|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['polygon']} | {r['file_index']} | {r['before']} | {r['paper_before']} | {r['after']} | "
                     f"{r['paper_after']} | {r['after'] - r['paper_after']:+d} | {r['after_closing']} |")
    tb, ta = sum(r["before"] for r in rows), sum(r["after"] for r in rows)
    lines.append(f"| total | | {tb} | {sum(TABLE2_PAPER_BEFORE)} | {ta} | {sum(TABLE2_PAPER_AFTER)} | "
                 f"{ta - sum(TABLE2_PAPER_AFTER):+d} | {sum(r['after_closing'] for r in rows)} |")
    return "\n".join(lines)


def main(argv: Iterable[str] | None = None) -> int:
    """``python -m psbmpc_jax.rdp [--eps 2] [--zone 32 33] [--anchor open]``: print Table 2."""
    from .charts import trondheim_chart

    ap = argparse.ArgumentParser(prog="python -m psbmpc_jax.rdp", description="Reproduce the paper's Table 2 "
                                 "(RDP on the shipped Nidelva/Trondheim chart).")
    ap.add_argument("--eps", type=float, default=2.0, help="RDP tolerance in metres (default 2)")
    ap.add_argument("--zone", type=int, nargs="+", default=[32, 33],
                    help="UTM zone(s) to project the chart to before simplifying (default: 32 33)")
    ap.add_argument("--anchor", choices=ANCHORS, default="open", help="ring anchoring (default: open, as the paper)")
    args = ap.parse_args(None if argv is None else list(argv))
    for zone in args.zone:
        rows = table2(trondheim_chart("psbmpc", zone=zone), args.eps, anchor=args.anchor)
        print(format_table2(rows, f"Table 2, eps = {args.eps} m, UTM zone {zone}N, anchor = {args.anchor}"))
        print()
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
