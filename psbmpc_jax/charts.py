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
"""

from __future__ import annotations

import dataclasses
import importlib.resources
import io
import json
import math
import pathlib
import re
import warnings
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Point, Polygon

__all__ = [
    "Chart", "load_chart", "load_psbmpc_csv", "load_shapefile", "load_geojson", "trondheim_chart",
    "range_filter", "to_rings", "to_ring_sets", "combine_charts", "count_vertices", "BUILTIN_CHARTS",
    "parse_crs", "CRSInfo", "lonlat_to_utm", "utm_to_lonlat", "utm_zone_for", "convert_utm",
    "TABLE2_FILE_INDICES", "PIREN_ORIGIN_LATLON", "NIDELVA_OWN_SHIP_UTM", "nidelva_own_ship_ned",
    "ChartWarning", "MAX_ORIGIN_DISTANCE_M", "tm_coefficients", "UTM_EAST_RANGE", "UTM_NORTH_RANGE",
]

# ================================================================================================ constants
#: File indices (0-based, in file order) of the 13 Nidelva polygons of the paper's Table 2 in the shipped
#: ``piren_frame_psbmpc_polygons_trd.csv``: polygons 1-12 are the consecutive file polygons 21-32, polygon 13
#: (the 21 961-vertex land polygon around the river) is file polygon 42.  Identified by their vertex counts,
#: which are unique in the file and match the table exactly.
TABLE2_FILE_INDICES = (21, 22, 23, 24, 25, 26, 27, 28, 29, 30, 31, 32, 42)

#: Origin (lat, lon) [deg] of the authors' "piren" local frame (psbmpc C++ example
#: ``run_psbmpc_with_grounding_hazards.cpp``); :func:`trondheim_chart` uses it as its default origin.
PIREN_ORIGIN_LATLON = (63.4389029083, 10.39908278)

#: Own-ship position for the Nidelva situation, UTM (east, north, zone) [m, m, -], WGS 84 / UTM 32N.
#: The paper's 13 Table 2 polygons can NOT all be within d_so = 200 m of one point: polygons 2 (file 22, the
#: breakwater in the west) and 11 (file 31, east of the river mouth) are more than 1.4 km apart, and every
#: disc reaching all 13 also reaches the 38 small pier polygons of the file (see docs/charts.md).  The 13
#: are the polygons of the chart the paper used, not a range-filter result.  This point was chosen by a
#: 5 m grid search over the water of the lower Nidelva (east 569 900-570 700, north 7 034 300-7 035 800):
#: the most Table 2 polygons within 200 m (three: polygons 6, 11, 12 = file 27, 31, 32) with *no* other
#: polygon within 200 m, ties broken by the largest distance to land (river centre, 54.5 m clearance).  It
#: lies in the river where the canal (Kanalen) joins it, between Bakke bru and the mouth.
NIDELVA_OWN_SHIP_UTM = (570210.0, 7034815.0, 32)

_SEPARATOR = -1.0

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


# ================================================================================================ UTM
_ELLIPSOIDS = {"WGS84": (6378137.0, 1.0 / 298.257223563), "ETRS89": (6378137.0, 1.0 / 298.257222101)}
_K0, _FALSE_E, _FALSE_N_SOUTH = 0.9996, 500000.0, 10000000.0


def _tm_series(f: float):
    """Krueger series coefficients (Karney 2011, eqs. 35-36) to order n^6."""
    n = f / (2.0 - f)
    n2, n3, n4, n5, n6 = n ** 2, n ** 3, n ** 4, n ** 5, n ** 6
    A = (1.0 + n2 / 4 + n4 / 64 + n6 / 256) / (1.0 + n)
    alpha = (
        n / 2 - 2 * n2 / 3 + 5 * n3 / 16 + 41 * n4 / 180 - 127 * n5 / 288 + 7891 * n6 / 37800,
        13 * n2 / 48 - 3 * n3 / 5 + 557 * n4 / 1440 + 281 * n5 / 630 - 1983433 * n6 / 1935360,
        61 * n3 / 240 - 103 * n4 / 140 + 15061 * n5 / 26880 + 167603 * n6 / 181440,
        49561 * n4 / 161280 - 179 * n5 / 168 + 6601661 * n6 / 7257600,
        34729 * n5 / 80640 - 3418889 * n6 / 1995840,
        212378941 * n6 / 319334400,
    )
    beta = (
        n / 2 - 2 * n2 / 3 + 37 * n3 / 96 - n4 / 360 - 81 * n5 / 512 + 96199 * n6 / 604800,
        n2 / 48 + n3 / 15 - 437 * n4 / 1440 + 46 * n5 / 105 - 1118711 * n6 / 3870720,
        17 * n3 / 480 - 37 * n4 / 840 - 209 * n5 / 4480 + 5569 * n6 / 90720,
        4397 * n4 / 161280 - 11 * n5 / 504 - 830251 * n6 / 7257600,
        4583 * n5 / 161280 - 108847 * n6 / 3991680,
        20648693 * n6 / 638668800,
    )
    return A, alpha, beta


def tm_coefficients(datum: str = "WGS84"):
    """``(a, f, A, alpha, beta)`` of the transverse Mercator series (Krueger n^6) of ``datum``'s ellipsoid:
    semi-major axis [m], flattening, rectifying-radius factor and the forward / inverse coefficients."""
    if datum not in _ELLIPSOIDS:
        raise ValueError(f"datum must be one of {list(_ELLIPSOIDS)}, got {datum!r}")
    a, f = _ELLIPSOIDS[datum]
    A, alpha, beta = _tm_series(f)
    return a, f, A, alpha, beta


def _check_zone(zone) -> int:
    if isinstance(zone, bool) or not isinstance(zone, (int, np.integer)) or not 1 <= zone <= 60:
        raise ValueError(f"UTM zone must be an integer in 1..60, got {zone!r}")
    return int(zone)


def utm_zone_for(lon: float, lat: float) -> int:
    """The standard UTM zone of a lon/lat point [deg], with the Norway (32V) and Svalbard exceptions."""
    lon = (float(lon) + 180.0) % 360.0 - 180.0
    lat = float(lat)
    if 56.0 <= lat < 64.0 and 3.0 <= lon < 12.0:
        return 32
    if 72.0 <= lat < 84.0 and 0.0 <= lon < 42.0:
        return 31 if lon < 9.0 else 33 if lon < 21.0 else 35 if lon < 33.0 else 37
    return int((lon + 180.0) // 6.0) % 60 + 1


def tm_forward(lat, lon, lon0: float, e: float, alpha):
    """Transverse Mercator (Krueger n^6, Karney 2011): lat/lon [deg] -> the normalised (xi, eta) about the
    central meridian ``lon0`` [deg]; multiply by k0 a A for metres."""
    lam = np.radians(np.asarray(lon, float)) - math.radians(lon0)
    lam = (lam + np.pi) % (2 * np.pi) - np.pi
    tau = np.tan(np.radians(np.asarray(lat, float)))
    sig = np.sinh(e * np.arctanh(e * tau / np.sqrt(1.0 + tau ** 2)))
    taup = tau * np.sqrt(1.0 + sig ** 2) - sig * np.sqrt(1.0 + tau ** 2)
    xip = np.arctan2(taup, np.cos(lam))
    etap = np.arcsinh(np.sin(lam) / np.sqrt(taup ** 2 + np.cos(lam) ** 2))
    xi, eta = xip.copy(), etap.copy()
    for j, al in enumerate(alpha, start=1):
        xi = xi + al * np.sin(2 * j * xip) * np.cosh(2 * j * etap)
        eta = eta + al * np.cos(2 * j * xip) * np.sinh(2 * j * etap)
    return xi, eta


def tm_inverse(xi, eta, e: float, beta):
    """Inverse of :func:`tm_forward`: normalised (xi, eta) -> (lat [deg], lon − lon0 [deg])."""
    e2 = e * e
    xip, etap = xi.copy(), eta.copy()
    for j, be in enumerate(beta, start=1):
        xip = xip - be * np.sin(2 * j * xi) * np.cosh(2 * j * eta)
        etap = etap - be * np.cos(2 * j * xi) * np.sinh(2 * j * eta)
    taup = np.sin(xip) / np.sqrt(np.sinh(etap) ** 2 + np.cos(xip) ** 2)
    lam = np.arctan2(np.sinh(etap), np.cos(xip))
    tau = taup.copy()
    for _ in range(6):  # Newton on tau'(tau) = taup (Karney 2011, eqs. 19-21)
        sig = np.sinh(e * np.arctanh(e * tau / np.sqrt(1.0 + tau ** 2)))
        taui = tau * np.sqrt(1.0 + sig ** 2) - sig * np.sqrt(1.0 + tau ** 2)
        tau = tau + (taup - taui) / np.sqrt(1.0 + taui ** 2) * (1.0 + (1.0 - e2) * tau ** 2) / (
            (1.0 - e2) * np.sqrt(1.0 + tau ** 2))
    return np.degrees(np.arctan(tau)), np.degrees(lam)


def lonlat_to_utm(lon, lat, zone: int, *, south: bool = False, datum: str = "WGS84"):
    """Project lon/lat [deg] to UTM (east, north) [m] in ``zone`` (transverse Mercator, Krueger n^6)."""
    zone = _check_zone(zone)
    a, f = _ELLIPSOIDS[datum]
    A, alpha, _ = _tm_series(f)
    xi, eta = tm_forward(lat, lon, 6.0 * zone - 183.0, math.sqrt(f * (2.0 - f)), alpha)
    east = _FALSE_E + _K0 * a * A * eta
    north = _K0 * a * A * xi + (_FALSE_N_SOUTH if south else 0.0)
    return east, north


def utm_to_lonlat(east, north, zone: int, *, south: bool = False, datum: str = "WGS84"):
    """Inverse of :func:`lonlat_to_utm`: UTM (east, north) [m] -> (lon, lat) [deg]."""
    zone = _check_zone(zone)
    a, f = _ELLIPSOIDS[datum]
    A, _, beta = _tm_series(f)
    xi = (np.asarray(north, float) - (_FALSE_N_SOUTH if south else 0.0)) / (_K0 * a * A)
    eta = (np.asarray(east, float) - _FALSE_E) / (_K0 * a * A)
    lat, dlon = tm_inverse(xi, eta, math.sqrt(f * (2.0 - f)), beta)
    lon = dlon + (6.0 * zone - 183.0)
    return (lon + 180.0) % 360.0 - 180.0, lat


def convert_utm(east, north, from_zone: int, to_zone: int, *, from_south: bool = False,
                to_south: bool = False, datum: str = "WGS84"):
    """Exact conversion of UTM coordinates between zones (through lon/lat)."""
    if from_zone == to_zone and from_south == to_south:
        return np.asarray(east, float).copy(), np.asarray(north, float).copy()
    lon, lat = utm_to_lonlat(east, north, from_zone, south=from_south, datum=datum)
    return lonlat_to_utm(lon, lat, to_zone, south=to_south, datum=datum)


# ================================================================================================ CRS
@dataclass(frozen=True)
class CRSInfo:
    """A parsed coordinate reference system: UTM (``zone``, ``south``) or lon/lat, and the datum."""

    kind: str  # "utm" | "lonlat"
    datum: str  # "WGS84" | "ETRS89"
    zone: int | None = None
    south: bool = False

    @property
    def code(self) -> str:
        """Canonical ``"EPSG:nnnn"`` string."""
        if self.kind == "lonlat":
            return "EPSG:4258" if self.datum == "ETRS89" else "EPSG:4326"
        if self.datum == "ETRS89" and not self.south:
            return f"EPSG:{25800 + self.zone}"
        return f"EPSG:{(32700 if self.south else 32600) + self.zone}"

    @property
    def name(self) -> str:
        d = "ETRS89" if self.datum == "ETRS89" else "WGS 84"
        if self.kind == "lonlat":
            return f"{d} lon/lat ({self.code})"
        return f"{d} / UTM zone {self.zone}{'S' if self.south else 'N'} ({self.code})"

    def same_grid(self, other: "CRSInfo") -> bool:
        """Same projection and zone (datum WGS 84 vs ETRS89 ignored, see module docstring)."""
        return (self.kind, self.zone, self.south) == (other.kind, other.zone, other.south)


_ALLOWED_CRS = ("'EPSG:326zz', 'EPSG:327zz', 'EPSG:258zz' (UTM), 'EPSG:4326', 'EPSG:4258' (lon/lat), "
                "'UTM32N'-style names, or a WKT string with a UTM zone or a GEOGCS")


def parse_crs(text) -> CRSInfo:
    """Parse a CRS string (EPSG code, ``"UTM33N"``, OGC URN or WKT of a .prj file); ``ValueError`` if unknown."""
    if isinstance(text, CRSInfo):
        return text
    if not isinstance(text, str) or not text.strip():
        raise ValueError(f"CRS must be a non-empty string: {_ALLOWED_CRS}; got {text!r}")
    s = text.strip()
    up = s.upper()
    m = re.search(r"EPSG(?::|::|:\d*:)(\d+)$", up.replace("URN:OGC:DEF:CRS:", "")) or re.fullmatch(r"(\d{4,5})", up)
    if m:
        code = int(m.group(1))
        if code in (4326, 4258):
            return CRSInfo("lonlat", "ETRS89" if code == 4258 else "WGS84")
        if 32601 <= code <= 32660:
            return CRSInfo("utm", "WGS84", code - 32600, False)
        if 32701 <= code <= 32760:
            return CRSInfo("utm", "WGS84", code - 32700, True)
        if 25801 <= code <= 25860:
            return CRSInfo("utm", "ETRS89", code - 25800, False)
        raise ValueError(f"unsupported CRS {text!r}: allowed {_ALLOWED_CRS}")
    if up in ("CRS84", "OGC:CRS84", "URN:OGC:DEF:CRS:OGC:1.3:CRS84", "WGS84", "WGS 84"):
        return CRSInfo("lonlat", "WGS84")
    datum = "ETRS89" if ("ETRS" in up or "EUREF" in up or "GRS_1980" in up or "GRS 1980" in up) else "WGS84"
    m = re.search(r"UTM[ _]*(?:ZONE[ _]*)?(\d{1,2})\s*([NS])?\b", up)
    if m:
        zone = _check_zone(int(m.group(1)))
        return CRSInfo("utm", datum, zone, m.group(2) == "S")
    if up.startswith("GEOGCS") or up.startswith("GEOGCRS"):
        return CRSInfo("lonlat", datum)
    raise ValueError(f"unsupported CRS {text[:120]!r}: allowed {_ALLOWED_CRS}")


# ================================================================================================ Chart
@dataclass(frozen=True, eq=False)
class Chart:
    """Grounding-hazard polygons in the local NED frame.

    Attributes:
        polygons: shapely ``Polygon`` s, coordinates **(x, y) = (north, east)** [m] relative to ``origin``;
            valid, non-empty, no repeated consecutive vertices.
        origin: ``(E0, N0)`` -- the UTM (east, north) [m] of the local origin, in ``crs``.
        crs: the UTM CRS of ``origin`` as ``"EPSG:nnnn"`` (see :func:`parse_crs`); :attr:`crs_name` spells it.
        source: where the polygons came from (file path, layer names).
        ids: per polygon, the index of the feature it came from in its file/layer (parts of one feature --
            after a validity repair or a range clip -- share the id).
        layers: per polygon, the layer name ("" for single-layer formats).
        report: counts of everything the pipeline changed, never silently: ``n_features`` read,
            ``n_duplicate_vertices`` removed, ``n_repaired`` (invalid polygons repaired by ``make_valid``),
            ``n_split_parts`` (extra parts from repairs), ``n_dropped_parts`` (empty or non-areal parts
            dropped, degenerate holes included), ``skipped_layers``; :func:`range_filter` and
            :func:`psbmpc_jax.rdp.simplify_chart` add their own keys.
    """

    polygons: tuple
    origin: tuple
    crs: str
    source: str
    ids: tuple = ()
    layers: tuple = ()
    report: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        polys = tuple(self.polygons)
        for j, p in enumerate(polys):
            if not isinstance(p, Polygon):
                raise ValueError(f"chart.polygons[{j}] must be a shapely Polygon, got {type(p).__name__}")
        object.__setattr__(self, "polygons", polys)
        ids = tuple(int(i) for i in self.ids) if self.ids else tuple(range(len(polys)))
        layers = tuple(self.layers) if self.layers else ("",) * len(polys)
        if len(ids) != len(polys) or len(layers) != len(polys):
            raise ValueError(f"chart.ids ({len(ids)}) and chart.layers ({len(layers)}) must have one entry per "
                             f"polygon ({len(polys)})")
        object.__setattr__(self, "ids", ids)
        object.__setattr__(self, "layers", layers)
        origin = tuple(float(v) for v in self.origin)
        if len(origin) != 2 or not all(math.isfinite(v) for v in origin):
            raise ValueError(f"chart.origin must be finite (E0, N0), got {self.origin!r}")
        object.__setattr__(self, "origin", origin)
        info = parse_crs(self.crs)
        if info.kind != "utm":
            raise ValueError(f"chart.crs must be a UTM CRS, got {self.crs!r}")
        object.__setattr__(self, "crs", info.code)
        object.__setattr__(self, "report", dict(self.report))

    # ------------------------------------------------------------------ info
    def __len__(self) -> int:
        return len(self.polygons)

    @property
    def crs_info(self) -> CRSInfo:
        return parse_crs(self.crs)

    @property
    def crs_name(self) -> str:
        return self.crs_info.name

    @property
    def zone(self) -> int:
        return self.crs_info.zone

    @property
    def n_vertices(self) -> tuple[int, ...]:
        """Outer-ring vertex count of every polygon (closing vertex not counted)."""
        return tuple(len(p.exterior.coords) - 1 for p in self.polygons)

    @property
    def total_vertices(self) -> int:
        """Vertices of all rings, holes included."""
        return count_vertices(self.polygons)

    # ------------------------------------------------------------------ frames
    def utm_to_local(self, points) -> np.ndarray:
        """UTM (east, north) ``[..., 2]`` in this chart's CRS -> local (north, east)."""
        p = np.asarray(points, float)
        return np.stack([p[..., 1] - self.origin[1], p[..., 0] - self.origin[0]], axis=-1)

    def local_to_utm(self, points) -> np.ndarray:
        """Local (north, east) ``[..., 2]`` -> UTM (east, north) in this chart's CRS."""
        p = np.asarray(points, float)
        return np.stack([p[..., 1] + self.origin[0], p[..., 0] + self.origin[1]], axis=-1)

    def with_origin(self, origin) -> "Chart":
        """The same chart about another origin ``(E0, N0)`` (same CRS): a pure translation."""
        o = tuple(float(v) for v in origin)
        dn, de = self.origin[1] - o[1], self.origin[0] - o[0]
        polys = tuple(shapely.transform(p, lambda c: c + np.array([dn, de])) for p in self.polygons)
        return dataclasses.replace(self, polygons=polys, origin=o)

    def reproject(self, zone: int, *, south: bool = False, origin=None) -> "Chart":
        """The chart in another UTM zone (exact conversion of every vertex), about ``origin`` (E0, N0) in the
        new zone (default: the old origin converted)."""
        info = self.crs_info
        zone = _check_zone(zone)
        new = CRSInfo("utm", info.datum, zone, south)
        if info.same_grid(new) and origin is None:
            return self

        def conv(c):
            e, n = convert_utm(c[:, 1] + self.origin[0], c[:, 0] + self.origin[1], info.zone, zone,
                               from_south=info.south, to_south=south, datum=info.datum)
            return np.stack([n, e], axis=1)

        if origin is None:
            oe, on = convert_utm(self.origin[0], self.origin[1], info.zone, zone, from_south=info.south,
                                 to_south=south, datum=info.datum)
            origin = (float(oe), float(on))
        origin = tuple(float(v) for v in origin)
        polys = []
        for p in self.polygons:
            q = shapely.transform(p, lambda c: conv(c) - np.array([origin[1], origin[0]]))
            polys.append(q)
        return dataclasses.replace(self, polygons=tuple(polys), origin=origin, crs=new.code)


# ================================================================================================ building
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


def _make_valid(poly: Polygon):
    try:
        return shapely.make_valid(poly, method="structure", keep_collapsed=False)
    except (TypeError, ValueError, shapely.errors.GEOSException):  # pragma: no cover - old GEOS
        fixed = shapely.make_valid(poly)
        return fixed if not fixed.is_empty else poly.buffer(0)


@dataclass
class _Raw:
    """One polygon as read: rings in the file's native (x, y) (east, north or lon, lat)."""

    shell: np.ndarray
    holes: list
    fid: int
    layer: str = ""


def _check_finite(raws: Sequence[_Raw], where: str) -> None:
    for r in raws:
        for ring in [r.shell, *r.holes]:
            if not np.all(np.isfinite(ring)):
                raise ValueError(f"{where}: polygon {r.fid} has non-finite coordinates (NaN/inf)")


def _project_raws(raws: list[_Raw], info: CRSInfo, zone: int | None, where: str) -> tuple[list[_Raw], CRSInfo]:
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
        cm = 6.0 * _check_zone(zone) - 183.0
        off = np.abs((allpts[:, 0] - cm + 180.0) % 360.0 - 180.0).max()
        if off > MAX_ZONE_LON_OFFSET_DEG:
            raise ValueError(f"{where}: longitudes up to {off:.1f} deg from the central meridian ({cm:g} deg) of UTM "
                             f"zone {zone}; at most {MAX_ZONE_LON_OFFSET_DEG:g} deg allowed -- a wrong zone, or "
                             f"[lat, lon] given where [lon, lat] belongs")
        south = bool(np.mean(allpts[:, 1]) < 0)
        out_info = CRSInfo("utm", info.datum, _check_zone(zone), south)

        def tr(a):
            e, n = lonlat_to_utm(a[:, 0], a[:, 1], out_info.zone, south=south, datum=info.datum)
            return np.stack([e, n], axis=1)
    else:
        if zone is None or zone == info.zone:
            return raws, info
        out_info = CRSInfo("utm", info.datum, _check_zone(zone), info.south)

        def tr(a):
            e, n = convert_utm(a[:, 0], a[:, 1], info.zone, out_info.zone, from_south=info.south,
                               to_south=info.south, datum=info.datum)
            return np.stack([e, n], axis=1)
    return [_Raw(tr(r.shell), [tr(h) for h in r.holes], r.fid, r.layer) for r in raws], out_info


def _default_origin(raws: Sequence[_Raw]) -> tuple[float, float]:
    """Centre of the bounding box of all outer-ring vertices, rounded to whole metres."""
    allpts = np.vstack([r.shell for r in raws])
    lo, hi = allpts.min(axis=0), allpts.max(axis=0)
    c = np.round(0.5 * (lo + hi))
    return float(c[0]), float(c[1])


def _build_chart(raws: list[_Raw], info: CRSInfo, *, origin, zone, source: str, report: dict) -> Chart:
    """Native rings -> UTM (target zone) -> local NED -> cleaned, validated, repaired shapely polygons."""
    where = source
    if not raws:
        raise ValueError(f"{where}: no polygons found (empty chart)")
    _check_finite(raws, where)
    raws, info = _project_raws(raws, info, zone, where)
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


def _all_points(raws: Sequence[_Raw]) -> np.ndarray:
    return np.vstack([r.shell for r in raws] + [h for r in raws for h in r.holes if len(h)])


def _check_not_lonlat(raws: Sequence[_Raw], info: CRSInfo, where: str) -> None:
    """Refuse lon/lat degrees declared as UTM: every coordinate within lon/lat range and the whole chart less
    than 5 m wide (checked after the per-polygon checks, so tiny degenerate test polygons say what they are)."""
    allpts = _all_points(raws)
    e, n = allpts[:, 0], allpts[:, 1]
    extent = float(max(np.ptp(e), np.ptp(n)))
    if np.all(np.abs(e) <= 180.0) and np.all(np.abs(n) <= 90.0) and extent < 5.0:
        raise ValueError(f"{where}: the coordinates look like lon/lat degrees (east {e.min():g}..{e.max():g}, north "
                         f"{n.min():g}..{n.max():g}: the whole chart would be {extent:.3g} m wide) but the CRS is "
                         f"{info.name}; give the lon/lat CRS (crs='EPSG:4326') or UTM metres")


def _check_utm_range(raws: Sequence[_Raw], info: CRSInfo, where: str) -> None:
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


def _check_origin_distance(raws: Sequence[_Raw], origin, info: CRSInfo, where: str) -> None:
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


# ================================================================================================ loaders
def _read_text(path, what: str) -> str:
    p = pathlib.Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{what} file not found: {p}")
    try:
        return p.read_text(encoding="utf-8-sig")
    except (UnicodeDecodeError, OSError) as exc:
        raise ValueError(f"{p}: cannot read as text ({exc}); expected a {what} file") from None


def _parse_psbmpc_csv(text: str, where: str) -> list[_Raw]:
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    if len(lines) < 3:
        raise ValueError(f"{where}: a psbmpc polygon CSV needs 3 lines ('rows,cols', eastings, northings), got "
                         f"{len(lines)}" + (" (empty file)" if not lines else ""))
    try:
        rows, cols = (int(v) for v in lines[0].split(","))
    except ValueError:
        raise ValueError(f"{where}: line 1 must be 'rows,cols' (two integers, rows = 2), "
                         f"got {lines[0][:60]!r}") from None
    if rows != 2 or len(lines) != 3:
        raise ValueError(f"{where}: expected rows = 2 and exactly 2 data lines (eastings, northings), got rows = "
                         f"{rows} and {len(lines) - 1} data lines")
    data = []
    for k, name in ((1, "eastings"), (2, "northings")):
        try:
            arr = np.array([float(v) for v in lines[k].split(",")])
        except ValueError:
            raise ValueError(f"{where}: line {k + 1} ({name}) must be comma-separated numbers") from None
        if len(arr) != cols:
            raise ValueError(f"{where}: line {k + 1} ({name}) has {len(arr)} values, line 1 says cols = {cols}")
        data.append(arr)
    E, N = data
    sepE, sepN = E == _SEPARATOR, N == _SEPARATOR
    if np.any(sepE != sepN):
        c = int(np.argmax(sepE != sepN))
        raise ValueError(f"{where}: column {c + 1} is -1 in only one row; polygons are separated by a column of -1 "
                         f"in both rows")
    raws, start, fid = [], 0, 0
    for stop in [*np.flatnonzero(sepE), len(E)]:
        if stop > start:
            raws.append(_Raw(np.stack([E[start:stop], N[start:stop]], axis=1), [], fid))
            fid += 1
        start = stop + 1
    if not raws:
        raise ValueError(f"{where}: no polygon vertices (only separators)")
    return raws


def load_psbmpc_csv(path, origin=None, *, crs: str = "EPSG:32632", zone: int | None = None) -> Chart:
    """Load a psbmpc polygon CSV (line 1 ``rows,cols``; line 2 eastings; line 3 northings; polygons separated
    by a column of -1; trailing separator optional).

    Args:
        path: the ``.csv`` file.
        origin: local origin ``(E0, N0)`` in the output CRS; default the centre of the bounding box of all
            vertices, rounded to whole metres.
        crs: the file's CRS (the format has no CRS field); default WGS 84 / UTM zone 32N, as the authors' files.
        zone: convert to this UTM zone (exact); default keep the file's zone.
    Polygon ids are their 0-based positions in the file."""
    where = str(path)
    raws = _parse_psbmpc_csv(_read_text(path, "psbmpc CSV"), where)
    info = parse_crs(crs)
    return _build_chart(raws, info, origin=origin, zone=zone, source=where, report={})


def _geojson_polygons(geom, fid: int, where: str, counts: dict) -> list[_Raw]:
    if not isinstance(geom, dict) or "type" not in geom:
        raise ValueError(f"{where}: feature {fid} has no valid geometry object")
    t = geom["type"]
    try:
        if t == "Polygon":
            rings = [np.asarray(r, float)[:, :2] for r in geom["coordinates"]]
            if not rings:
                counts["n_empty_features"] = counts.get("n_empty_features", 0) + 1
            return [_Raw(rings[0], rings[1:], fid)] if rings else []
        if t == "MultiPolygon":
            out = []
            for poly in geom["coordinates"]:
                rings = [np.asarray(r, float)[:, :2] for r in poly]
                if rings:
                    out.append(_Raw(rings[0], rings[1:], fid))
            if not out:
                counts["n_empty_features"] = counts.get("n_empty_features", 0) + 1
            return out
        if t == "GeometryCollection":
            sub: dict = {}
            out = [r for g in geom.get("geometries", []) for r in _geojson_polygons(g, fid, where, sub)]
            if not out:
                key = "n_empty_features" if not geom.get("geometries") else "n_skipped_features"
                counts[key] = counts.get(key, 0) + 1
            return out
    except (TypeError, ValueError, IndexError, KeyError):
        raise ValueError(f"{where}: feature {fid} has malformed {t} coordinates") from None
    counts["n_skipped_features"] = counts.get("n_skipped_features", 0) + 1
    return []


def load_geojson(path, origin=None, *, crs: str | None = None, zone: int | None = None) -> Chart:
    """Load Polygon and MultiPolygon features (outer rings and holes) from a GeoJSON file.

    Coordinates are lon/lat WGS 84 (RFC 7946) unless ``crs`` or a legacy top-level ``"crs"`` member
    (``{"type": "name", "properties": {"name": "EPSG:32632"}}``) names another CRS.  Lon/lat data is
    projected to UTM ``zone`` (default: the zone of the data's mean position).  Other geometry types are
    skipped and counted in ``report["n_skipped_features"]``.  Polygon ids are feature indices."""
    where = str(path)
    text = _read_text(path, "GeoJSON")
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{where}: not valid JSON ({exc.msg} at line {exc.lineno}); expected a GeoJSON "
                         f"FeatureCollection, Feature or Polygon/MultiPolygon geometry") from None
    if not isinstance(doc, dict) or "type" not in doc:
        raise ValueError(f"{where}: not a GeoJSON object (no 'type'); expected a FeatureCollection, Feature or "
                         f"geometry")
    if crs is None:
        member = doc.get("crs")
        if isinstance(member, dict):
            crs = (member.get("properties") or {}).get("name")
        crs = crs or "EPSG:4326"
    info = parse_crs(crs)
    if doc["type"] == "FeatureCollection":
        feats = doc.get("features")
        if not isinstance(feats, list):
            raise ValueError(f"{where}: FeatureCollection without a 'features' list")
        geoms = [(f.get("geometry") if isinstance(f, dict) else None) for f in feats]
    elif doc["type"] == "Feature":
        geoms = [doc.get("geometry")]
    else:
        geoms = [doc]
    counts: dict = {}
    raws = []
    for fid, g in enumerate(geoms):
        if g is None:
            counts["n_skipped_features"] = counts.get("n_skipped_features", 0) + 1
            continue
        raws += _geojson_polygons(g, fid, where, counts)
    counts.setdefault("n_skipped_features", 0)
    counts.setdefault("n_empty_features", 0)
    if not raws:
        raise ValueError(f"{where}: no Polygon or MultiPolygon features (empty chart; "
                         f"{counts['n_skipped_features']} other features skipped, {counts['n_empty_features']} "
                         f"empty)")
    return _build_chart(raws, info, origin=origin, zone=zone, source=where, report=counts)


# ---------------------------------------------------------------------------------------------- shapefiles
_POLYGON_TYPES = (5, 15, 25)  # POLYGON, POLYGONZ, POLYGONM


def _shapefile_layers(path: pathlib.Path) -> dict[str, pathlib.Path]:
    """Layer name -> .shp path for a .shp file or a folder (its .shp files and those one level down)."""
    if path.is_dir():
        found = sorted(path.glob("*.shp")) + sorted(path.glob("*/*.shp"))
        layers = {}
        for p in found:
            layers.setdefault(p.stem, p)
        if not layers:
            raise ValueError(f"{path}: folder contains no .shp files (expected a shapefile or a folder of "
                             f"shapefile layers)")
        return layers
    if path.suffix.lower() != ".shp":
        path = path.with_suffix(".shp")
    if not path.exists():
        raise FileNotFoundError(f"shapefile not found: {path}")
    return {path.stem: path}


def _read_shapefile_layer(shp, shx, dbf, prj_text: str | None, name: str, where: str, crs_override):
    """-> (list of _Raw, CRSInfo, status) where status is '' or why the layer is unusable."""
    import shapefile  # pyshp

    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            reader = shapefile.Reader(shp=shp, shx=shx, dbf=dbf)
            shapes = reader.shapes()
            shape_type = reader.shapeType
            file_bbox = list(reader.bbox) if len(shapes) else None
    except Exception as exc:  # pyshp raises its own ShapefileException and struct errors
        raise ValueError(f"{where}: cannot read shapefile layer {name!r} ({exc}); expected an ESRI shapefile "
                         f"with Polygon geometry") from None
    corrupt = [str(w.message) for w in caught if "Corrupt" in type(w.message).__name__]
    if corrupt:
        raise ValueError(f"{where}: cannot read shapefile layer {name!r}: corrupt file ({corrupt[0]}); expected an "
                         f"intact ESRI shapefile (.shp, .shx and .dbf written together)")
    for w in caught:  # anything else pyshp said is passed on
        warnings.warn(f"{where}: layer {name!r}: pyshp: {w.message}", ChartWarning, stacklevel=3)
    if crs_override is not None:
        info = parse_crs(crs_override)
    elif prj_text:
        try:
            info = parse_crs(prj_text)
        except ValueError as exc:
            raise ValueError(f"{where}: layer {name!r}: {exc}; pass crs= to override") from None
    else:
        raise ValueError(f"{where}: layer {name!r} has no .prj file, its CRS is unknown; pass crs= "
                         f"(e.g. 'EPSG:32632')")
    if len(shapes) == 0:
        return [], info, "empty"
    if shape_type not in _POLYGON_TYPES:
        return [], info, f"shape type {shapefile.SHAPETYPE_LOOKUP.get(shape_type, shape_type)} is not a polygon type"
    raws, n_null = [], 0
    for fid, shp_obj in enumerate(shapes):
        if shp_obj.shapeType == 0 or not shp_obj.points:
            n_null += 1
            continue
        _check_record_bbox(shp_obj, file_bbox, fid, name, where)
        gi = shp_obj.__geo_interface__
        counts: dict = {}
        for r in _geojson_polygons(gi, fid, where, counts):
            r.layer = name
            raws.append(r)
    return raws, info, (f"{n_null} null shapes" if n_null else "")


def _check_record_bbox(shp_obj, file_bbox, fid: int, name: str, where: str) -> None:
    """Every point of a record must lie in the record's stored bounding box and in the file's: a coordinate
    outside them is garbage read from a corrupt file."""
    pts = np.asarray(shp_obj.points, float)[:, :2]
    for label, bb in (("record", getattr(shp_obj, "bbox", None)), ("file", file_bbox)):
        if bb is None or len(bb) < 4:
            continue
        lo, hi = np.array(bb[:2], float), np.array(bb[2:4], float)
        tol = 1e-6 * np.maximum(1.0, np.maximum(np.abs(lo), np.abs(hi)))
        bad = ~np.all(np.isfinite(pts), axis=1) | np.any((pts < lo - tol) | (pts > hi + tol), axis=1)
        if np.any(bad):
            k = int(np.flatnonzero(bad)[0])
            raise ValueError(f"{where}: cannot read shapefile layer {name!r}: record {fid} point {k} "
                             f"({pts[k, 0]:.6g}, {pts[k, 1]:.6g}) lies outside the {label}'s bounding box "
                             f"({lo[0]:.6g}, {lo[1]:.6g}, {hi[0]:.6g}, {hi[1]:.6g}): a corrupt file")


def _load_shapefile_sources(sources: dict, where: str, origin, layer, crs, zone) -> Chart:
    """sources: layer name -> (open_files() -> (shp, shx, dbf), prj_text or None)."""
    available = list(sources)
    explicit = layer is not None
    if layer is None:
        names = available
    else:
        names = [layer] if isinstance(layer, str) else list(layer)
        unknown = [n for n in names if n not in sources]
        if unknown:
            raise ValueError(f"{where}: unknown layer(s) {unknown}; available layers: {available}")
    raws, infos, skipped, nulls = [], {}, [], 0
    for name in names:
        opener, prj_text = sources[name]
        shp, shx, dbf = opener()
        try:
            r, info, status = _read_shapefile_layer(shp, shx, dbf, prj_text, name, where, crs)
        finally:
            for f in (shp, shx, dbf):
                if f is not None:
                    f.close()
        if status and not r:
            if explicit:
                raise ValueError(f"{where}: layer {name!r} has no polygons ({status}); allowed: non-empty "
                                 f"Polygon/PolygonZ/PolygonM layers")
            skipped.append(f"{name} ({status})")
            continue
        if status:
            nulls += int(status.split()[0])
        raws += r
        infos[name] = info
    if not raws:
        raise ValueError(f"{where}: no polygons in layers {names} (skipped: {skipped}); empty chart")
    first = next(iter(infos.values()))
    mixed = {n: i.name for n, i in infos.items() if not i.same_grid(first)}
    if mixed and zone is None:
        raise ValueError(f"{where}: layers have different CRSs ({ {n: i.name for n, i in infos.items()} }); "
                         f"pass zone= to convert all of them to one UTM zone, or load them separately")
    # convert every layer to one UTM grid (the first layer's, or `zone`) before building one chart
    target_zone = zone if zone is not None else first.zone
    if target_zone is None:  # lon/lat layers and no zone given: the zone of the data's mean position
        c = np.vstack([r.shell for r in raws]).mean(axis=0)
        target_zone = utm_zone_for(c[0], c[1])
    merged, out_info = [], None
    for name, info in infos.items():
        lr, li = _project_raws([r for r in raws if r.layer == name], info, target_zone, where)
        merged += lr
        out_info = out_info or li
    report = dict(skipped_layers=tuple(skipped), n_null_shapes=nulls,
                  layer_crs={n: i.name for n, i in infos.items()})
    src = where + (f" [layers: {', '.join(infos)}]" if len(sources) > 1 or explicit else "")
    return _build_chart(merged, out_info, origin=origin, zone=None, source=src, report=report)


def load_shapefile(path, origin=None, layer=None, *, crs: str | None = None, zone: int | None = None) -> Chart:
    """Load Polygon shapefile(s): outer rings and holes of every record (multi-part records are split into
    polygons sharing the record index as id).

    Args:
        path: a ``.shp`` file (or its path without extension) or a folder of layers (``*.shp`` in it and in
            its sub-folders, e.g. ``charts/land/land.shp``; the layer name is the file stem).
        origin: local origin ``(E0, N0)`` in the output CRS; default the centre of the bounding box of all
            vertices, rounded to whole metres.
        layer: layer name or list of names (folders only); default all layers, where empty and non-polygon
            layers are skipped and listed in ``report["skipped_layers"]`` (named layers must have polygons).
        crs: override the ``.prj`` CRS of every layer (required when a layer has no ``.prj``).
        zone: UTM zone to convert to; required to combine layers in different zones (``ValueError``
            otherwise, naming each layer's CRS).
    """
    p = pathlib.Path(path)
    if not p.exists() and not p.with_suffix(".shp").exists():
        raise FileNotFoundError(f"shapefile or folder not found: {p}")
    layers = _shapefile_layers(p)
    if not p.is_dir() and layer is not None and layer != next(iter(layers)):
        raise ValueError(f"{p}: layer {layer!r} requested from a single-layer shapefile ({next(iter(layers))!r})")

    def make_opener(shp_path: pathlib.Path):
        def opener():
            shx, dbf = shp_path.with_suffix(".shx"), shp_path.with_suffix(".dbf")
            return (open(shp_path, "rb"), open(shx, "rb") if shx.exists() else None,
                    open(dbf, "rb") if dbf.exists() else None)
        return opener

    sources = {}
    for name, shp_path in layers.items():
        prj = shp_path.with_suffix(".prj")
        sources[name] = (make_opener(shp_path), prj.read_text(errors="replace") if prj.exists() else None)
    return _load_shapefile_sources(sources, str(p), origin, layer if p.is_dir() else None, crs, zone)


#: Names of the shipped charts :func:`load_chart` accepts instead of a path.
BUILTIN_CHARTS = ("trondheim", "trondheim-psbmpc", "trondheim-shapefile")
_KNOWN_EXT = (".csv (psbmpc)", ".shp or a folder of shapefile layers", ".geojson/.json",
              "or the names " + ", ".join(f"'{n}'" for n in BUILTIN_CHARTS))


def count_vertices(polygons) -> int:
    """Vertices of all rings of shapely polygons, holes included (closing vertices not counted)."""
    return int(sum(len(p.exterior.coords) - 1 + sum(len(r.coords) - 1 for r in p.interiors) for p in polygons))


def load_chart(path_or_name, origin=None, **kwargs) -> Chart:
    """Load a chart, dispatching on the file extension (see the module docstring), or a shipped chart by name
    (``"trondheim"`` = ``"trondheim-psbmpc"``, ``"trondheim-shapefile"``).  Keyword arguments go to the loader."""
    if isinstance(path_or_name, str) and path_or_name.lower() in BUILTIN_CHARTS:
        kind = "shapefile" if path_or_name.lower().endswith("shapefile") else "psbmpc"
        return trondheim_chart(kind, origin=origin, **kwargs)
    p = pathlib.Path(path_or_name)
    ext = p.suffix.lower()
    if ext == ".csv":
        return load_psbmpc_csv(p, origin, **kwargs)
    if ext == ".shp" or p.is_dir():
        return load_shapefile(p, origin, **kwargs)
    if ext in (".geojson", ".json"):
        return load_geojson(p, origin, **kwargs)
    if not p.exists():
        raise FileNotFoundError(f"chart not found: {p} (allowed: {', '.join(_KNOWN_EXT)})")
    raise ValueError(f"{p}: unknown chart format {ext or '(no extension)'!r}; allowed: {', '.join(_KNOWN_EXT)}")


def combine_charts(charts: Sequence[Chart], *, zone: int | None = None, origin=None) -> Chart:
    """One chart from several.  All charts must share a UTM zone unless ``zone`` is given (then each is
    converted exactly).  ``origin`` defaults to the first chart's origin (converted if needed)."""
    charts = list(charts)
    if not charts:
        raise ValueError("combine_charts needs at least one chart")
    infos = [c.crs_info for c in charts]
    if zone is None:
        if any(not i.same_grid(infos[0]) for i in infos):
            raise ValueError(f"charts have different CRSs ({[i.name for i in infos]}); pass zone= to convert them "
                             f"to one UTM zone")
        zone = infos[0].zone
    first = charts[0].reproject(zone)
    origin = first.origin if origin is None else tuple(float(v) for v in origin)
    polys, ids, layers, reports = [], [], [], []
    for c in charts:
        c = c.reproject(zone, origin=origin) if c.zone != zone else c.with_origin(origin)
        polys += c.polygons
        ids += c.ids
        layers += [lay or c.source for lay in c.layers]
        reports.append(c.report)
    rep = {"combined": tuple(reports)}
    return Chart(tuple(polys), origin, first.crs, " + ".join(c.source for c in charts), tuple(ids), tuple(layers), rep)


# ---------------------------------------------------------------------------------------------- shipped data
def _data_dir():
    return importlib.resources.files("psbmpc_jax") / "data" / "trondheim"


def trondheim_chart(kind: str = "psbmpc", *, origin=None, zone: int | None = None, layer=None) -> Chart:
    """The shipped Trondheim chart (``psbmpc_jax/data/trondheim``, MIT licence, see its README).

    ``kind="psbmpc"``: ``piren_frame_psbmpc_polygons_trd.csv`` -- 61 polygons around Nidelva, WGS 84 / UTM 32N
    (the 13 of the paper's Table 2 are :data:`TABLE2_FILE_INDICES`).  ``kind="shapefile"``: the chart layers
    (``land``, ``rocks``, ``seabed``, ``shallows``, ``shore``) in ETRS89 / UTM 33N; only ``land`` has polygons
    (3 large ones west of Trondheim), the others are empty and skipped unless named in ``layer``.
    ``zone`` converts to another UTM zone; ``origin`` (E0, N0) defaults to the authors' "piren" origin
    :data:`PIREN_ORIGIN_LATLON` projected to the output zone."""
    root = _data_dir()
    if kind == "psbmpc":
        native = CRSInfo("utm", "WGS84", 32)
    elif kind == "shapefile":
        native = CRSInfo("utm", "ETRS89", 33)
    else:
        raise ValueError(f"kind must be 'psbmpc' or 'shapefile', got {kind!r}")
    out_zone = native.zone if zone is None else _check_zone(zone)
    if origin is None:
        e, n = lonlat_to_utm(PIREN_ORIGIN_LATLON[1], PIREN_ORIGIN_LATLON[0], out_zone, datum=native.datum)
        origin = (float(e), float(n))
    if kind == "psbmpc":
        res = root / "piren_frame_psbmpc_polygons_trd.csv"
        where = "psbmpc_jax/data/trondheim/piren_frame_psbmpc_polygons_trd.csv"
        raws = _parse_psbmpc_csv(res.read_text(encoding="utf-8"), where)
        return _build_chart(raws, native, origin=origin, zone=out_zone, source=where, report={})
    charts = root / "charts"
    sources = {}
    for d in sorted((t for t in charts.iterdir() if t.is_dir()), key=lambda t: t.name):
        name = d.name

        def opener(d=d, name=name):
            def rd(ext):
                f = d / f"{name}.{ext}"
                return io.BytesIO(f.read_bytes()) if f.is_file() else None
            return rd("shp"), rd("shx"), rd("dbf")

        prj = d / f"{name}.prj"
        sources[name] = (opener, prj.read_text(encoding="utf-8") if prj.is_file() else None)
    return _load_shapefile_sources(sources, "psbmpc_jax/data/trondheim/charts", origin, layer, None, out_zone)


def nidelva_own_ship_ned(chart: Chart) -> np.ndarray:
    """:data:`NIDELVA_OWN_SHIP_UTM` in ``chart``'s local (north, east) frame (converted if the zone differs)."""
    e, n, z = NIDELVA_OWN_SHIP_UTM
    e, n = convert_utm(e, n, z, chart.zone, datum=chart.crs_info.datum)
    return chart.utm_to_local(np.array([float(e), float(n)]))


# ================================================================================================ range filter
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


# ================================================================================================ to the device
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
