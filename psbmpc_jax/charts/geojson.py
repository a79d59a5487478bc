"""GeoJSON charts: Polygon and MultiPolygon features (outer rings and holes), lon/lat WGS 84 as RFC 7946 says or
the CRS a legacy ``"crs"`` member or ``crs=`` names."""

from __future__ import annotations

import json

import numpy as np

from .build import RawPolygon, build_chart
from .chart import Chart
from .crs import parse_crs
from .psbmpc_csv import read_text


def geojson_polygons(geom, fid: int, where: str, counts: dict) -> list[RawPolygon]:
    if not isinstance(geom, dict) or "type" not in geom:
        raise ValueError(f"{where}: feature {fid} has no valid geometry object")
    t = geom["type"]
    try:
        if t == "Polygon":
            rings = [np.asarray(r, float)[:, :2] for r in geom["coordinates"]]
            if not rings:
                counts["n_empty_features"] = counts.get("n_empty_features", 0) + 1
            return [RawPolygon(rings[0], rings[1:], fid)] if rings else []
        if t == "MultiPolygon":
            out = []
            for poly in geom["coordinates"]:
                rings = [np.asarray(r, float)[:, :2] for r in poly]
                if rings:
                    out.append(RawPolygon(rings[0], rings[1:], fid))
            if not out:
                counts["n_empty_features"] = counts.get("n_empty_features", 0) + 1
            return out
        if t == "GeometryCollection":
            sub: dict = {}
            out = [r for g in geom.get("geometries", []) for r in geojson_polygons(g, fid, where, sub)]
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
    text = read_text(path, "GeoJSON")
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
        raws += geojson_polygons(g, fid, where, counts)
    counts.setdefault("n_skipped_features", 0)
    counts.setdefault("n_empty_features", 0)
    if not raws:
        raise ValueError(f"{where}: no Polygon or MultiPolygon features (empty chart; "
                         f"{counts['n_skipped_features']} other features skipped, {counts['n_empty_features']} "
                         f"empty)")
    return build_chart(raws, info, origin=origin, zone=zone, source=where, report=counts)
