"""The :class:`Chart` data class: grounding-hazard polygons in the local NED frame about a UTM origin, with
their ids, layers and the report of everything the pipeline changed."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np
import shapely
from shapely.geometry import Polygon

from .crs import CRSInfo, parse_crs
from .utm import check_zone, convert_utm


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
        zone = self.crs_info.zone
        assert zone is not None                 # the chart's CRS is UTM (checked in __post_init__)
        return zone

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
        zone = check_zone(zone)
        new = CRSInfo("utm", info.datum, zone, south)
        if info.same_grid(new) and origin is None:
            return self

        def conv(c):
            e, n = convert_utm(c[:, 1] + self.origin[0], c[:, 0] + self.origin[1], info.zone, zone,
                               from_south=info.south, to_south=south, datum=info.datum)
            return np.stack([n, e], axis=1)

        if origin is None:
            oe, on = convert_utm(self.origin[0], self.origin[1], self.zone, zone, from_south=info.south,
                                 to_south=south, datum=info.datum)
            origin = (float(oe), float(on))
        origin = tuple(float(v) for v in origin)
        polys = []
        for p in self.polygons:
            q = shapely.transform(p, lambda c: conv(c) - np.array([origin[1], origin[0]]))
            polys.append(q)
        return dataclasses.replace(self, polygons=tuple(polys), origin=origin, crs=new.code)


def count_vertices(polygons) -> int:
    """Vertices of all rings of shapely polygons, holes included (closing vertices not counted)."""
    return int(sum(len(p.exterior.coords) - 1 + sum(len(r.coords) - 1 for r in p.interiors) for p in polygons))
