"""One entry to every chart: :func:`load_chart` (dispatch on the file extension, or a shipped chart by name) and
:func:`combine_charts` (one chart from several, converted to one UTM zone)."""

from __future__ import annotations

import pathlib
from typing import Sequence

from .builtin import BUILTIN_CHARTS, trondheim_chart
from .chart import Chart
from .geojson import load_geojson
from .psbmpc_csv import load_psbmpc_csv
from .shapefiles import load_shapefile


_KNOWN_EXT = (".csv (psbmpc)", ".shp or a folder of shapefile layers", ".geojson/.json",
              "or the names " + ", ".join(f"'{n}'" for n in BUILTIN_CHARTS))


def load_chart(path_or_name, origin=None, **kwargs) -> Chart:
    """Load a chart, dispatching on the file extension (see :mod:`psbmpc_jax.charts`), or a shipped chart by name
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
        zone = charts[0].zone
    first = charts[0].reproject(zone)
    origin = first.origin if origin is None else tuple(float(v) for v in origin)
    polys: list = []
    ids: list = []
    layers: list[str] = []
    reports: list[dict] = []
    for c in charts:
        c = c.reproject(zone, origin=origin) if c.zone != zone else c.with_origin(origin)
        polys += c.polygons
        ids += c.ids
        layers += [lay or c.source for lay in c.layers]
        reports.append(c.report)
    rep = {"combined": tuple(reports)}
    return Chart(tuple(polys), origin, first.crs, " + ".join(c.source for c in charts), tuple(ids), tuple(layers), rep)
