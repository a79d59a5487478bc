"""Building a :class:`~psbmpc_jax.charts.Chart` from the polygons a loader read: projection to UTM, the local
NED frame, ring cleaning, validity repair, and the plausibility checks (coordinate order, CRS, origin distance)
with the :class:`ChartWarning` that names whatever was dropped."""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Sequence

import numpy as np
import shapely
from shapely.geometry import Polygon

from .chart import Chart
from .clip import areal_parts
from .crs import CRSInfo
from .utm import check_zone, convert_utm, lonlat_to_utm, utm_zone_for


#: Farthest the chart may lie from an origin given explicitly (``origin=``) [m]; farther means the origin or
#: the chart is in the wrong CRS or has its coordinates swapped.
MAX_ORIGIN_DISTANCE_M = 100_000.0

#: Plausible UTM coordinates [m]: eastings (wide enough for Norway's use of zone 33 from 4 deg E to 31 deg E)
#: and northings (0 at the equator in the north, 10 000 km false northing in the south).
UTM_EAST_RANGE = (-1_000_000.0, 2_000_000.0)
UTM_NORTH_RANGE = (-1_000_000.0, 10_500_000.0)

#: Largest longitude difference [deg] from the central meridian of the UTM zone lon/lat data is projected to.
MAX_ZONE_LON_OFFSET_DEG = 20.0

_ORDER_HINT = ("check the coordinate order and the CRS: GeoJSON and lon/lat charts are [lon, lat] (not [lat, lon]); "
               "UTM is (east, north) (the psbmpc CSV: line 2 eastings, line 3 northings); lon/lat degrees need a "
               "lon/lat CRS (EPSG:4326), UTM metres a UTM CRS")


class ChartWarning(UserWarning):
    """A chart loaded, but something was dropped or looks wrong (the counts are also in ``Chart.report``)."""


def _clean_ring(arr: np.ndarray) -> tuple[np.ndarray, int]:
    """Drop consecutive duplicates and repeated closing vertices; return (ring, number removed)."""
    n0 = len(arr)
    if n0 == 0:
        return arr, 0
    keep = np.r_[True, np.any(arr[1:] != arr[:-1], axis=1)]
    arr = arr[keep]
    while len(arr) > 1 and np.array_equal(arr[0], arr[-1]):
        arr = arr[:-1]
    return arr, n0 - len(arr)


def _make_valid(poly: Polygon):
    try:
        return shapely.make_valid(poly, method="structure", keep_collapsed=False)
    except (TypeError, ValueError, shapely.errors.GEOSException):  # pragma: no cover - old GEOS
        fixed = shapely.make_valid(poly)
        return fixed if not fixed.is_empty else poly.buffer(0)


@dataclass
class RawPolygon:
    """One polygon as read: rings in the file's native (x, y) (east, north or lon, lat)."""

    shell: np.ndarray
    holes: list
    fid: int
    layer: str = ""


def _check_finite(raws: Sequence[RawPolygon], where: str) -> None:
    for r in raws:
        for ring in [r.shell, *r.holes]:
            if not np.all(np.isfinite(ring)):
                raise ValueError(f"{where}: polygon {r.fid} has non-finite coordinates (NaN/inf)")


def project_raws(raws: list[RawPolygon], info: CRSInfo, zone: int | None,
                 where: str) -> tuple[list[RawPolygon], CRSInfo]:
    """Bring native coordinates to UTM (east, north) in the target zone (default: native, or auto for lon/lat)."""
    if info.kind == "lonlat":
        allpts = np.vstack([r.shell for r in raws])
        if np.any(np.abs(allpts[:, 0]) > 180.0) or np.any(np.abs(allpts[:, 1]) > 90.0):
            if np.all(np.abs(allpts[:, 0]) <= 90.0) and np.all(np.abs(allpts[:, 1]) <= 180.0):
                raise ValueError(f"{where}: coordinates are outside lon/lat range (latitude up to "
                                 f"{np.abs(allpts[:, 1]).max():g} deg) but the CRS is {info.name}; they look like "
                                 f"[lat, lon] -- lon/lat charts and GeoJSON are [lon, lat]")
            raise ValueError(f"{where}: coordinates are outside lon/lat range but the CRS is {info.name}; "
                             f"projected data needs its CRS (e.g. crs='EPSG:32632')")
        if zone is None:
            c = allpts.mean(axis=0)
            zone = utm_zone_for(c[0], c[1])
        cm = 6.0 * check_zone(zone) - 183.0
        off = np.abs((allpts[:, 0] - cm + 180.0) % 360.0 - 180.0).max()
        if off > MAX_ZONE_LON_OFFSET_DEG:
            raise ValueError(f"{where}: longitudes up to {off:.1f} deg from the central meridian ({cm:g} deg) of UTM "
                             f"zone {zone}; at most {MAX_ZONE_LON_OFFSET_DEG:g} deg allowed -- a wrong zone, or "
                             f"[lat, lon] given where [lon, lat] belongs")
        south = bool(np.mean(allpts[:, 1]) < 0)
        out_info = CRSInfo("utm", info.datum, check_zone(zone), south)

        def tr(a):
            e, n = lonlat_to_utm(a[:, 0], a[:, 1], out_info.zone, south=south, datum=info.datum)
            return np.stack([e, n], axis=1)
    else:
        if zone is None or zone == info.zone:
            return raws, info
        out_info = CRSInfo("utm", info.datum, check_zone(zone), info.south)

        def tr(a):
            e, n = convert_utm(a[:, 0], a[:, 1], info.zone, out_info.zone, from_south=info.south,
                               to_south=info.south, datum=info.datum)
            return np.stack([e, n], axis=1)
    return [RawPolygon(tr(r.shell), [tr(h) for h in r.holes], r.fid, r.layer) for r in raws], out_info


def _default_origin(raws: Sequence[RawPolygon]) -> tuple[float, float]:
    """Centre of the bounding box of all outer-ring vertices, rounded to whole metres."""
    allpts = np.vstack([r.shell for r in raws])
    lo, hi = allpts.min(axis=0), allpts.max(axis=0)
    c = np.round(0.5 * (lo + hi))
    return float(c[0]), float(c[1])


def build_chart(raws: list[RawPolygon], info: CRSInfo, *, origin, zone, source: str, report: dict) -> Chart:
    """Native rings -> UTM (target zone) -> local NED -> cleaned, validated, repaired shapely polygons."""
    where = source
    if not raws:
        raise ValueError(f"{where}: no polygons found (empty chart)")
    _check_finite(raws, where)
    raws, info = project_raws(raws, info, zone, where)
    _check_utm_range(raws, info, where)
    explicit_origin = origin is not None
    if origin is None:
        origin = _default_origin(raws)
    origin = tuple(float(v) for v in origin)
    if len(origin) != 2 or not all(math.isfinite(v) for v in origin):
        raise ValueError(f"origin must be (E0, N0) in metres, got {origin!r}")
    E0, N0 = origin
    polys, ids, layers = [], [], []
    rep = dict(n_features=len({(r.layer, r.fid) for r in raws}), n_duplicate_vertices=0, n_repaired=0,
               n_split_parts=0, n_dropped_parts=0)
    rep.update(report)

    def local(a):
        return np.stack([a[:, 1] - N0, a[:, 0] - E0], axis=1)

    for r in raws:
        label = f"polygon {r.fid}" + (f" of layer {r.layer!r}" if r.layer else "")
        shell, nd = _clean_ring(local(r.shell))
        rep["n_duplicate_vertices"] += nd
        if len(shell) < 3:
            raise ValueError(f"{where}: {label} is degenerate: {len(shell)} distinct vertices (a polygon needs "
                             f"at least 3)")
        holes = []
        for h in r.holes:
            hc, nd = _clean_ring(local(h))
            rep["n_duplicate_vertices"] += nd
            if len(hc) < 3 or Polygon(hc).area == 0.0:
                rep["n_dropped_parts"] += 1
                continue
            holes.append(hc)
        poly = Polygon(shell, holes)
        if poly.is_valid:
            parts = [poly]
        else:
            rep["n_repaired"] += 1
            parts, dropped = areal_parts(_make_valid(poly))
            rep["n_dropped_parts"] += dropped
            if not parts:
                raise ValueError(f"{where}: {label} is degenerate: zero area (collinear or collapsed vertices)")
            rep["n_split_parts"] += len(parts) - 1
        for p in parts:
            polys.append(p)
            ids.append(r.fid)
            layers.append(r.layer)
    _check_not_lonlat(raws, info, where)
    if explicit_origin:
        _check_origin_distance(raws, origin, info, where)
    _warn_dropped(rep, where)
    return Chart(tuple(polys), origin, info.code, source, tuple(ids), tuple(layers), rep)


def _all_points(raws: Sequence[RawPolygon]) -> np.ndarray:
    return np.vstack([r.shell for r in raws] + [h for r in raws for h in r.holes if len(h)])


def _check_not_lonlat(raws: Sequence[RawPolygon], info: CRSInfo, where: str) -> None:
    """Refuse lon/lat degrees declared as UTM: every coordinate within lon/lat range and the whole chart less
    than 5 m wide (checked after the per-polygon checks, so tiny degenerate test polygons say what they are)."""
    allpts = _all_points(raws)
    e, n = allpts[:, 0], allpts[:, 1]
    extent = float(max(np.ptp(e), np.ptp(n)))
    if np.all(np.abs(e) <= 180.0) and np.all(np.abs(n) <= 90.0) and extent < 5.0:
        raise ValueError(f"{where}: the coordinates look like lon/lat degrees (east {e.min():g}..{e.max():g}, north "
                         f"{n.min():g}..{n.max():g}: the whole chart would be {extent:.3g} m wide) but the CRS is "
                         f"{info.name}; give the lon/lat CRS (crs='EPSG:4326') or UTM metres")


def _check_utm_range(raws: Sequence[RawPolygon], info: CRSInfo, where: str) -> None:
    """Refuse UTM data outside the plausible UTM range: (north, east) swapped, or garbage from a corrupt file."""
    allpts = _all_points(raws)
    e, n = allpts[:, 0], allpts[:, 1]
    e_lo, e_hi = UTM_EAST_RANGE
    n_lo, n_hi = UTM_NORTH_RANGE
    bad_e = (e < e_lo) | (e > e_hi)
    bad_n = (n < n_lo) | (n > n_hi)
    if np.any(bad_e) or np.any(bad_n):
        swapped = (np.all((n >= e_lo) & (n <= e_hi)) and np.all((e >= n_lo) & (e <= n_hi)))
        hint = ("; they look like (north, east) -- UTM is (east, north) (the psbmpc CSV: line 2 eastings, line 3 "
                "northings)" if swapped else "; a corrupt file or the wrong CRS?")
        k = int(np.flatnonzero(bad_e | bad_n)[0])
        raise ValueError(f"{where}: coordinate ({e[k]:.6g}, {n[k]:.6g}) is outside the plausible UTM range "
                         f"(east {e_lo:g}..{e_hi:g} m, north {n_lo:g}..{n_hi:g} m) of {info.name}{hint}")


def _check_origin_distance(raws: Sequence[RawPolygon], origin, info: CRSInfo, where: str) -> None:
    allpts = np.vstack([r.shell for r in raws])
    lo, hi = allpts.min(axis=0), allpts.max(axis=0)
    o = np.asarray(origin, float)
    d = float(np.hypot(*np.maximum(0.0, np.maximum(lo - o, o - hi))))
    if d > MAX_ORIGIN_DISTANCE_M:
        raise ValueError(f"{where}: the chart lies {d / 1000:.0f} km from the origin (E0, N0) = ({o[0]:.0f}, "
                         f"{o[1]:.0f}) in {info.name}; at most {MAX_ORIGIN_DISTANCE_M / 1000:.0f} km allowed -- "
                         f"{_ORDER_HINT}; and the origin's zone")


def _warn_dropped(rep: dict, where: str) -> None:
    """One :class:`ChartWarning` naming every count of features or parts that were dropped."""
    what = {"n_empty_features": "empty features (no coordinates)",
            "n_skipped_features": "features without polygon geometry (null, Point, LineString, ...)",
            "n_null_shapes": "null shapes", "n_dropped_parts": "degenerate holes / non-areal parts"}
    dropped = [f"{int(rep[k])} {txt}" for k, txt in what.items() if int(rep.get(k, 0) or 0) > 0]
    if dropped:
        warnings.warn(f"{where}: dropped {', '.join(dropped)}; counted in Chart.report", ChartWarning, stacklevel=4)
