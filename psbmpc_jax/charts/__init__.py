"""Host-side chart pipeline: read grounding hazards, convert them to the local NED frame, repair, range-filter
and hand them to :class:`psbmpc_jax.Situation` as rings.  NumPy + shapely + pyshp; nothing here is traced.

Frames and conventions
----------------------
* Input charts are in UTM (east, north) [m] -- or lon/lat degrees, which are projected to UTM first.
* Everything a :class:`Chart` holds is in the **local NED frame** about an origin ``(E0, N0)`` of its UTM
  CRS: a UTM point ``(E, N)`` becomes ``(north, east) = (N - N0, E - E0)``.  The conversion happens once,
  at load time.
* The polygons are shapely geometries in that frame, so **shapely's x is north and y is east** (as
  ``x = north`` in the rest of the package).  Swapping the axes mirrors the plane: a ring that is
  counter-clockwise in a map (east right, north up) is clockwise in shapely's (x, y).  Orientation is
  irrelevant to the grounding cost (even-odd inside test, distances) and is never changed here.
* Ring vertex order is kept as read; repeated consecutive vertices (e.g. the closing point of a shapefile
  ring, or the two repeated closing points of the psbmpc CSV) are removed at load and counted.

Formats (:func:`load_chart` dispatches on the extension)
-------------------------------------------------------
* ``.csv`` -- the psbmpc format (:func:`load_psbmpc_csv`): line 1 ``rows,cols`` (rows = 2), line 2 the
  eastings, line 3 the northings; polygons separated by a column of ``-1``.  CRS: UTM zone 32N by default.
* ``.shp`` or a folder of layers (:func:`load_shapefile`): Polygon/PolygonZ/PolygonM shapefiles, outer rings
  and holes; the CRS comes from the ``.prj`` file of each layer.
* ``.geojson`` / ``.json`` (:func:`load_geojson`): Polygon and MultiPolygon features (outer rings and
  holes); lon/lat WGS 84 as RFC 7946 says, or UTM when a legacy ``"crs"`` member or ``crs=`` names it.

CRSs are identified by strings ``"EPSG:326zz"`` (WGS 84 / UTM zz N), ``"EPSG:327zz"`` (south),
``"EPSG:258zz"`` (ETRS89 / UTM zz N), ``"EPSG:4326"`` / ``"EPSG:4258"`` (lon/lat), or WKT.  Charts in
different UTM zones are never mixed silently: combining them raises unless a target ``zone`` is given, in
which case every chart is converted exactly (transverse Mercator, Krueger series to n^6 -- sub-millimetre
inside a zone and its neighbours).  WGS 84 and ETRS89 are treated as the same datum (they differ by < 1 m
in Europe, below chart accuracy; EPSG's default transformation between them is the null transformation).

Pipeline: ``load_* -> rdp.simplify_chart -> range_filter (per solve) -> to_rings / to_ring_sets ->
Situation(polygons=...)``.

Modules (each owns one thing; every public name is importable from ``psbmpc_jax.charts``):
``utm`` (transverse Mercator, UTM zones), ``crs`` (:class:`CRSInfo`, :func:`parse_crs`), ``chart`` (the
:class:`Chart` data class), ``build`` (native rings -> cleaned, repaired local-frame polygons, the plausibility
checks, :class:`ChartWarning`), ``psbmpc_csv`` / ``geojson`` / ``shapefiles`` (the formats), ``builtin`` (the
shipped Trondheim chart and its constants), ``load`` (:func:`load_chart`, :func:`combine_charts`), ``clip``
(:func:`range_filter`) and ``rings`` (:func:`to_rings`, :func:`to_ring_sets`).
"""

from __future__ import annotations

from .build import MAX_ORIGIN_DISTANCE_M, MAX_ZONE_LON_OFFSET_DEG, UTM_EAST_RANGE, UTM_NORTH_RANGE, ChartWarning
from .builtin import (BUILTIN_CHARTS, NIDELVA_OWN_SHIP_UTM, PIREN_ORIGIN_LATLON, TABLE2_FILE_INDICES, data_dir,
                      nidelva_own_ship_ned, trondheim_chart)
from .chart import Chart, count_vertices
from .clip import areal_parts, range_filter
from .crs import CRSInfo, parse_crs
from .geojson import load_geojson
from .load import combine_charts, load_chart
from .psbmpc_csv import load_psbmpc_csv
from .rings import to_ring_sets, to_rings
from .shapefiles import load_shapefile
from .utm import convert_utm, lonlat_to_utm, tm_coefficients, tm_forward, tm_inverse, utm_to_lonlat, utm_zone_for

__all__ = [
    "Chart", "load_chart", "load_psbmpc_csv", "load_shapefile", "load_geojson", "trondheim_chart",
    "range_filter", "to_rings", "to_ring_sets", "combine_charts", "count_vertices", "BUILTIN_CHARTS",
    "parse_crs", "CRSInfo", "lonlat_to_utm", "utm_to_lonlat", "utm_zone_for", "convert_utm",
    "TABLE2_FILE_INDICES", "PIREN_ORIGIN_LATLON", "NIDELVA_OWN_SHIP_UTM", "nidelva_own_ship_ned",
    "ChartWarning", "MAX_ORIGIN_DISTANCE_M", "tm_coefficients", "UTM_EAST_RANGE", "UTM_NORTH_RANGE",
    # public before the split too, used by other modules of the package (geo, scenario.world)
    "tm_forward", "tm_inverse", "areal_parts", "MAX_ZONE_LON_OFFSET_DEG", "data_dir",
]

#: The former module's name for :func:`~psbmpc_jax.charts.builtin.data_dir` (the shipped data folder), kept for
#: existing callers.
_data_dir = data_dir
