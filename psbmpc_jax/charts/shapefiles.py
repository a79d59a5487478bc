"""Shapefile charts (pyshp): Polygon/PolygonZ/PolygonM layers, one file or a folder of layers, each with the
CRS of its ``.prj``; layers in different UTM zones are combined only when a target zone is given."""

from __future__ import annotations

import pathlib
import warnings

import numpy as np

from .build import ChartWarning, build_chart, project_raws
from .chart import Chart
from .crs import parse_crs
from .geojson import geojson_polygons
from .utm import utm_zone_for


_POLYGON_TYPES = (5, 15, 25)  # POLYGON, POLYGONZ, POLYGONM


def _shapefile_layers(path: pathlib.Path) -> dict[str, pathlib.Path]:
    """Layer name -> .shp path for a .shp file or a folder (its .shp files and those one level down)."""
    if path.is_dir():
        found = sorted(path.glob("*.shp")) + sorted(path.glob("*/*.shp"))
        layers: dict[str, pathlib.Path] = {}
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
    """-> (list of RawPolygon, CRSInfo, status) where status is '' or why the layer is unusable."""
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
        for r in geojson_polygons(gi, fid, where, counts):
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


def load_shapefile_sources(sources: dict, where: str, origin, layer, crs, zone) -> Chart:
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
        lr, li = project_raws([r for r in raws if r.layer == name], info, target_zone, where)
        merged += lr
        out_info = out_info or li
    report = dict(skipped_layers=tuple(skipped), n_null_shapes=nulls,
                  layer_crs={n: i.name for n, i in infos.items()})
    src = where + (f" [layers: {', '.join(infos)}]" if len(sources) > 1 or explicit else "")
    assert out_info is not None             # raws is not empty: at least one layer was projected
    return build_chart(merged, out_info, origin=origin, zone=None, source=src, report=report)


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
    return load_shapefile_sources(sources, str(p), origin, layer if p.is_dir() else None, crs, zone)
