"""The shipped Trondheim chart (``psbmpc_jax/data/trondheim``) and its constants: the paper's Table 2
polygons, the authors' "piren" origin and the Nidelva own-ship position."""

from __future__ import annotations

import importlib.resources
import io

import numpy as np

from .build import build_chart
from .chart import Chart
from .crs import CRSInfo
from .psbmpc_csv import parse_psbmpc_csv
from .shapefiles import load_shapefile_sources
from .utm import check_zone, convert_utm, lonlat_to_utm


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

#: Names of the shipped charts :func:`load_chart` accepts instead of a path.
BUILTIN_CHARTS = ("trondheim", "trondheim-psbmpc", "trondheim-shapefile")


def data_dir():
    return importlib.resources.files("psbmpc_jax") / "data" / "trondheim"


def trondheim_chart(kind: str = "psbmpc", *, origin=None, zone: int | None = None, layer=None) -> Chart:
    """The shipped Trondheim chart (``psbmpc_jax/data/trondheim``, MIT licence, see its README).

    ``kind="psbmpc"``: ``piren_frame_psbmpc_polygons_trd.csv`` -- 61 polygons around Nidelva, WGS 84 / UTM 32N
    (the 13 of the paper's Table 2 are :data:`TABLE2_FILE_INDICES`).  ``kind="shapefile"``: the chart layers
    (``land``, ``rocks``, ``seabed``, ``shallows``, ``shore``) in ETRS89 / UTM 33N; only ``land`` has polygons
    (3 large ones west of Trondheim), the others are empty and skipped unless named in ``layer``.
    ``zone`` converts to another UTM zone; ``origin`` (E0, N0) defaults to the authors' "piren" origin
    :data:`PIREN_ORIGIN_LATLON` projected to the output zone."""
    root = data_dir()
    if kind == "psbmpc":
        native = CRSInfo("utm", "WGS84", 32)
    elif kind == "shapefile":
        native = CRSInfo("utm", "ETRS89", 33)
    else:
        raise ValueError(f"kind must be 'psbmpc' or 'shapefile', got {kind!r}")
    assert native.zone is not None          # both native frames are UTM
    out_zone = native.zone if zone is None else check_zone(zone)
    if origin is None:
        e, n = lonlat_to_utm(PIREN_ORIGIN_LATLON[1], PIREN_ORIGIN_LATLON[0], out_zone, datum=native.datum)
        origin = (float(e), float(n))
    if kind == "psbmpc":
        res = root / "piren_frame_psbmpc_polygons_trd.csv"
        where = "psbmpc_jax/data/trondheim/piren_frame_psbmpc_polygons_trd.csv"
        raws = parse_psbmpc_csv(res.read_text(encoding="utf-8"), where)
        return build_chart(raws, native, origin=origin, zone=out_zone, source=where, report={})
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
    return load_shapefile_sources(sources, "psbmpc_jax/data/trondheim/charts", origin, layer, None, out_zone)


def nidelva_own_ship_ned(chart: Chart) -> np.ndarray:
    """:data:`NIDELVA_OWN_SHIP_UTM` in ``chart``'s local (north, east) frame (converted if the zone differs)."""
    e, n, z = NIDELVA_OWN_SHIP_UTM
    e, n = convert_utm(e, n, z, chart.zone, datum=chart.crs_info.datum)
    return chart.utm_to_local(np.array([float(e), float(n)]))
