"""The ``sensor`` and ``chart`` sections of a scenario file: tracking settings, land polygons (built-in, file or
inline; UTM or lat/lon origin) and their clipping around the routes."""

from __future__ import annotations
import numbers
import pathlib
from typing import Any
from functools import lru_cache
import numpy as np
import shapely
import shapely.validation
from shapely.geometry import Polygon
from ..charts import BUILTIN_CHARTS, areal_parts, load_chart, lonlat_to_utm
from ..checks import multiple_of
from ..geo import check_latlon

from ..config import as_mapping, as_number, as_points, check_keys, read_speed
from .schema import CLIP_QUAD_SEGS, SensorSpec
from .ships import route_geometry


_SENSOR_KEYS = ("position_std_m", "period_s", "filter_R_scale", "sigma_a_mps2", "U_max_mps", "U_max_kn",
                "colav_target_cov")


_COV_KEYS = ("position_var_m2", "velocity_var_m2s2")


_CHART_KEYS = ("builtin", "file", "polygons_m", "origin_utm", "rdp_eps_m", "clip_m")


_ORIGIN_KEYS = ("east", "north", "zone")


_LATLON_ORIGIN_KEYS = ("lat", "lon")


def read_sensor(d, dt: float) -> SensorSpec:
    d = as_mapping(d, "sensor")
    check_keys(d, _SENSOR_KEYS, "sensor")
    base = SensorSpec()
    kw: dict[str, Any] = {}
    if "position_std_m" in d:
        kw["position_std"] = as_number(d["position_std_m"], "sensor.position_std_m", gt=0)
    if "period_s" in d:
        kw["period"] = as_number(d["period_s"], "sensor.period_s", gt=0)
    multiple_of(kw.get("period", base.period), dt,
                "sensor.period_s" if "period" in kw else "sensor.period_s (not given: the default)", "simulation.dt_s")
    if "filter_R_scale" in d:
        kw["filter_R_scale"] = as_number(d["filter_R_scale"], "sensor.filter_R_scale", ge=1)
    if "sigma_a_mps2" in d:
        kw["sigma_a"] = as_number(d["sigma_a_mps2"], "sensor.sigma_a_mps2", ge=0)
    u_max = read_speed(d, ("U_max_mps", "U_max_kn"), "sensor", required=False, gt=0)
    if u_max is not None:
        kw["U_max"] = u_max
    if "colav_target_cov" in d:
        c = as_mapping(d["colav_target_cov"], "sensor.colav_target_cov")
        check_keys(c, _COV_KEYS, "sensor.colav_target_cov")
        pv = as_number(c.get("position_var_m2", base.colav_target_cov[0]), "sensor.colav_target_cov.position_var_m2",
                     gt=0)
        vv = as_number(c.get("velocity_var_m2s2", base.colav_target_cov[1]),
                     "sensor.colav_target_cov.velocity_var_m2s2", gt=0)
        kw["colav_target_cov"] = (pv, vv)
    return SensorSpec(**kw)


# ---------------------------------------------------------------------------------------------- charts
@lru_cache(maxsize=8)
def _builtin_chart(name: str, origin, zone):
    return load_chart(name, origin, zone=zone)


def _inline_polygons(v) -> list[Polygon]:
    where = "chart.polygons_m"
    if not isinstance(v, (list, tuple)) or not v:
        raise ValueError(f"{where} must be a non-empty list of polygons, each a list of >= 3 points [north, east]")
    out = []
    for j, ring in enumerate(v):
        w = f"{where}[{j}]"
        pts = as_points(ring, w, min_n=3)
        if len(pts) > 3 and np.array_equal(pts[0], pts[-1]):
            pts = pts[:-1]  # an explicitly closed ring: the closing point repeats the first one
        same = np.flatnonzero(np.all(pts == np.roll(pts, -1, axis=0), axis=1))
        if same.size:
            raise ValueError(f"{w}: vertex {int(same[0])} repeats the next one; a polygon needs distinct "
                             f"consecutive vertices")
        if len(pts) < 3:
            raise ValueError(f"{w}: a polygon needs at least 3 distinct vertices, got {len(pts)}")
        poly = Polygon(pts)
        if not poly.is_valid or poly.area <= 0.0:
            why = shapely.validation.explain_validity(poly) if not poly.is_valid else "zero area"
            raise ValueError(f"{w} is not a valid simple polygon ({why}); give one non-self-intersecting exterior "
                             f"ring with non-zero area")
        out.append(poly)
    return out


def read_origin_latlon(d) -> tuple[float, float]:
    o = as_mapping(d, "origin_latlon")
    check_keys(o, _LATLON_ORIGIN_KEYS, "origin_latlon", required=_LATLON_ORIGIN_KEYS)
    return check_latlon(as_number(o["lat"], "origin_latlon.lat"), as_number(o["lon"], "origin_latlon.lon"),
                        "origin_latlon [lat, lon]")


def chart_source(d, base_dir, origin_ll=None):
    """-> (Chart or None, inline polygons or None, info dict, settings) before ships are known."""
    d = as_mapping(d, "chart")
    check_keys(d, _CHART_KEYS, "chart")
    sources = [k for k in ("builtin", "file", "polygons_m") if k in d]
    if len(sources) != 1:
        raise ValueError(f"chart needs exactly one land source of builtin / file / polygons_m, got "
                         f"{sources or 'none'} (leave the chart section out for open water)")
    src = sources[0]
    rdp_eps = as_number(d["rdp_eps_m"], "chart.rdp_eps_m", gt=0) if "rdp_eps_m" in d else None
    clip = as_number(d["clip_m"], "chart.clip_m", gt=0) if "clip_m" in d else None
    if src == "polygons_m":
        for k in ("origin_utm", "rdp_eps_m"):
            if k in d:
                raise ValueError(f"chart.{k} applies only to builtin / file charts, not to chart.polygons_m "
                                 f"(inline polygons are already in local NED metres)")
        polys = _inline_polygons(d["polygons_m"])
        info = dict(source="inline chart.polygons_m", origin=None, crs=None)
        return None, polys, info, rdp_eps, clip
    origin = zone = None
    if "origin_utm" in d and origin_ll is not None:
        raise ValueError("give the origin once: chart.origin_utm or origin_latlon, not both")
    if "origin_utm" in d:
        o = as_mapping(d["origin_utm"], "chart.origin_utm")
        check_keys(o, _ORIGIN_KEYS, "chart.origin_utm", required=("east", "north"))
        origin = (as_number(o["east"], "chart.origin_utm.east"), as_number(o["north"], "chart.origin_utm.north"))
        if "zone" in o:
            zone = o["zone"]
            if isinstance(zone, bool) or not isinstance(zone, numbers.Integral) or not 1 <= zone <= 60:
                raise ValueError(f"chart.origin_utm.zone must be a UTM zone, an integer in 1..60, got {zone!r}")
            zone = int(zone)
    if src == "builtin":
        name = d["builtin"]
        if not isinstance(name, str) or name.lower() not in BUILTIN_CHARTS:
            raise ValueError(f"chart.builtin must be one of {list(BUILTIN_CHARTS)}, got {name!r}")
        try:
            chart = _builtin_chart(name.lower(), origin, zone)
        except ValueError as exc:
            raise ValueError(f"chart.builtin {name!r}: {exc}") from None
        source = f"builtin:{name.lower()} ({chart.source})"
    else:
        f = d["file"]
        if not isinstance(f, str) or not f.strip():
            raise ValueError(f"chart.file must be a path (relative to the scenario file), got {f!r}")
        p = pathlib.Path(f).expanduser()
        if not p.is_absolute():
            p = pathlib.Path(base_dir if base_dir is not None else ".") / p
        if not p.exists() and not p.with_suffix(".shp").exists():
            raise ValueError(f"chart.file {f!r}: not found ({p}); the path is relative to the scenario file's "
                             f"folder")
        try:
            chart = load_chart(p, origin, zone=zone)
        except (ValueError, FileNotFoundError) as exc:
            raise ValueError(f"chart.file {f!r}: {exc}") from None
        source = str(p)
    if origin_ll is not None:  # the geographic origin, projected to the chart's UTM zone
        info_crs = chart.crs_info
        if src == "file":       # a user's file may be in [lat, lon] order; the built-in charts are not
            _check_chart_order(chart, origin_ll, "origin_latlon")
        e, n = lonlat_to_utm(origin_ll[1], origin_ll[0], chart.zone, south=info_crs.south, datum=info_crs.datum)
        chart = chart.with_origin((float(e), float(n)))
        _check_chart_near_origin(chart, "origin_latlon")
    info = dict(source=source, origin=tuple(chart.origin), crs=chart.crs)
    return chart, None, info, rdp_eps, clip


def _check_chart_order(chart, origin_ll, what: str) -> None:
    """A chart written [lat, lon] (GeoJSON wants [lon, lat]) lies far from the origin as read and near it with
    the coordinates exchanged: refused with that diagnosis (:mod:`psbmpc_jax.chart_order`)."""
    from ..chart_order import check_near
    from ..charts import MAX_ORIGIN_DISTANCE_M, utm_to_lonlat

    if not chart.polygons:
        return
    pts = np.concatenate([np.asarray(p.exterior.coords)[:-1] for p in chart.polygons])     # local (north, east)
    info = chart.crs_info
    lon, lat = utm_to_lonlat(pts[:, 1] + chart.origin[0], pts[:, 0] + chart.origin[1], chart.zone,
                             south=info.south, datum=info.datum)
    check_near(lon, lat, origin_ll[1], origin_ll[0], MAX_ORIGIN_DISTANCE_M, what)


def _check_chart_near_origin(chart, what: str) -> None:
    from ..charts import MAX_ORIGIN_DISTANCE_M

    if not chart.polygons:
        return
    b = np.array(shapely.total_bounds(np.array(chart.polygons, dtype=object)))   # (n_min, e_min, n_max, e_max)
    d = float(np.hypot(*np.maximum(0.0, np.maximum(b[:2], -b[2:]))))
    if d > MAX_ORIGIN_DISTANCE_M:
        raise ValueError(f"{what}: the chart lies {d / 1000:.0f} km from this origin; at most "
                         f"{MAX_ORIGIN_DISTANCE_M / 1000:.0f} km allowed -- origin_latlon is {{lat, lon}} in degrees; "
                         f"check the chart's CRS and coordinate order")


def clip_polygons(polys: list[Polygon], ships, clip_m: float) -> tuple[list[Polygon], dict]:
    """Keep the land within ``clip_m`` of every ship's start and route (shapely buffer, CLIP_QUAD_SEGS)."""
    region = shapely.union_all([route_geometry(s).buffer(clip_m, quad_segs=CLIP_QUAD_SEGS) for s in ships])
    shapely.prepare(region)
    out, removed, clipped, dropped = [], 0, 0, 0
    for p in polys:
        if not region.intersects(p):
            removed += 1
            continue
        if region.contains(p):
            out.append(p)
            continue
        parts, k = areal_parts(p.intersection(region))
        clipped += 1
        dropped += k
        if not parts:
            removed += 1
        out += parts
    return out, dict(clip_removed=removed, clip_clipped=clipped, clip_dropped_parts=dropped)
