"""Chart pipeline (psbmpc_jax.charts): loaders (shipped data and small files written here), UTM <-> local NED,
CRS handling and zone conversion, validity repair, bad input, the range filter, rings for Situation."""

from __future__ import annotations

import functools
import json
import math

import numpy as np
import pytest
import shapefile  # pyshp
import shapely
from hypothesis import given, settings, strategies as st
from shapely.geometry import Point, Polygon

from psbmpc_jax import charts
from psbmpc_jax.charts import (NIDELVA_OWN_SHIP_UTM, TABLE2_FILE_INDICES, Chart, combine_charts, convert_utm,
                               load_chart, load_geojson, load_psbmpc_csv, load_shapefile, lonlat_to_utm,
                               nidelva_own_ship_ned, parse_crs, range_filter, to_ring_sets, to_rings,
                               trondheim_chart, utm_to_lonlat, utm_zone_for)
from psbmpc_jax.rdp import TABLE2_PAPER_BEFORE

WGS84_UTM32_PRJ = ('PROJCS["WGS_1984_UTM_Zone_32N",GEOGCS["GCS_WGS_1984",DATUM["D_WGS_1984",SPHEROID["WGS_1984",'
                   '6378137.0,298.257223563]],PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]],'
                   'PROJECTION["Transverse_Mercator"],PARAMETER["False_Easting",500000.0],PARAMETER["False_Northing",'
                   '0.0],PARAMETER["Central_Meridian",9.0],PARAMETER["Scale_Factor",0.9996],PARAMETER['
                   '"Latitude_Of_Origin",0.0],UNIT["Meter",1.0]]')


@functools.lru_cache(maxsize=None)
def shipped_chart() -> Chart:
    return trondheim_chart("psbmpc")


@pytest.fixture(scope="module")
def chart():
    return shipped_chart()


def raw_csv_polygons():
    """The shipped CSV parsed independently: list of [n, 2] (east, north) arrays in file order."""
    path = charts._data_dir() / "piren_frame_psbmpc_polygons_trd.csv"
    lines = path.read_text().splitlines()
    E = np.array(lines[1].split(","), float)
    N = np.array(lines[2].split(","), float)
    cuts = np.flatnonzero(E == -1)
    chunks = [np.stack([e, n], 1) for e, n in zip(np.split(E, cuts), np.split(N, cuts))]
    return [chunks[0]] + [c[1:] for c in chunks[1:]], len(E), len(cuts)


def write_csv(path, polys, trailing=True):
    cols_e, cols_n = [], []
    for k, p in enumerate(polys):
        cols_e += [repr(float(v)) for v in p[:, 0]]
        cols_n += [repr(float(v)) for v in p[:, 1]]
        if trailing or k < len(polys) - 1:
            cols_e.append("-1")
            cols_n.append("-1")
    path.write_text(f"2,{len(cols_e)}\n" + ",".join(cols_e) + "\n" + ",".join(cols_n) + "\n")
    return path


def write_shapefile(base, polygons, prj=WGS84_UTM32_PRJ):
    """polygons: list of lists of rings (east, north); outer rings clockwise, holes counter-clockwise as the
    shapefile spec says (pyshp's geo-interface relies on it)."""
    w = shapefile.Writer(str(base), shapeType=shapefile.POLYGON)
    w.field("name", "C")
    for k, rings in enumerate(polygons):
        w.poly([[tuple(v) for v in r] for r in rings])
        w.record(f"p{k}")
    w.close()
    if prj is not None:
        base.with_suffix(".prj").write_text(prj)
    return base.with_suffix(".shp")


E0, N0 = 569000.0, 7035000.0
SQUARE_CW = np.array([[E0, N0], [E0, N0 + 100], [E0 + 100, N0 + 100], [E0 + 100, N0], [E0, N0]])  # clockwise (E,N)
HOLE_CCW = np.array([[E0 + 40, N0 + 40], [E0 + 60, N0 + 40], [E0 + 60, N0 + 60], [E0 + 40, N0 + 60],
                     [E0 + 40, N0 + 40]])


# ------------------------------------------------------------------------------------------ shipped CSV
def test_shipped_csv_loads_with_ids_crs_and_report(chart):
    polys, n_cols, n_sep = raw_csv_polygons()
    assert len(chart) == 61 == len(polys) and chart.ids == tuple(range(61))
    assert chart.crs == "EPSG:32632" and chart.zone == 32 and "UTM zone 32N" in chart.crs_name
    rep = chart.report
    assert rep["n_features"] == 61 and rep["n_repaired"] == 0 and rep["n_dropped_parts"] == 0
    # nothing lost but repeated vertices: every raw vertex is either kept or counted as a duplicate
    assert chart.total_vertices + rep["n_duplicate_vertices"] == n_cols - n_sep
    assert all(p.is_valid for p in chart.polygons)


def test_table2_before_counts_and_ring_order(chart):
    assert tuple(chart.n_vertices[i] for i in TABLE2_FILE_INDICES) == TABLE2_PAPER_BEFORE
    raw, _, _ = raw_csv_polygons()
    for i in TABLE2_FILE_INDICES:
        assert len(raw[i]) == chart.n_vertices[i] + 2  # the CSV repeats each closing vertex twice
    # counts identify the 13 uniquely in the file
    counts = [len(p) - 2 for p in raw]
    assert all(counts.count(c) == TABLE2_PAPER_BEFORE.count(c) for c in set(TABLE2_PAPER_BEFORE) - {8})


def test_utm_to_ned_known_point(chart):
    raw, _, _ = raw_csv_polygons()
    E, N = raw[22][0]
    np.testing.assert_allclose(np.asarray(chart.polygons[22].exterior.coords)[0],
                               [N - chart.origin[1], E - chart.origin[0]], atol=1e-9)
    ring = to_rings(chart)[22]
    np.testing.assert_allclose(ring, raw[22][:-2, ::-1] - [chart.origin[1], chart.origin[0]], atol=1e-9)
    np.testing.assert_allclose(chart.local_to_utm(ring), raw[22][:-2], atol=1e-9)
    np.testing.assert_allclose(chart.utm_to_local(raw[22][:-2]), ring, atol=1e-9)
    # explicit origin
    c2 = trondheim_chart("psbmpc", origin=(E0, N0))
    assert c2.origin == (E0, N0)
    np.testing.assert_allclose(np.asarray(c2.polygons[22].exterior.coords)[0], [N - N0, E - E0], atol=1e-9)
    np.testing.assert_allclose(np.asarray(chart.with_origin((E0, N0)).polygons[22].exterior.coords),
                               np.asarray(c2.polygons[22].exterior.coords), atol=1e-8)


def test_default_origin_is_piren(chart):
    lat, lon = charts.PIREN_ORIGIN_LATLON
    e, n = lonlat_to_utm(lon, lat, 32)
    assert chart.origin == pytest.approx((e, n), abs=1e-6)


# ------------------------------------------------------------------------------------------ UTM / CRS
def test_utm_reference_values():
    # meridian arc to 45 deg on WGS 84 is 4 984 944.378 m; on the central meridian N = k0 * arc
    e, n = lonlat_to_utm(9.0, 45.0, 32)
    assert e == pytest.approx(500000.0, abs=1e-6) and n == pytest.approx(0.9996 * 4984944.378, abs=2e-3)
    # values from PROJ 9.5 (pyproj 3.7): the piren origin in zones 32/33, ETRS89 33N, and Sydney (56S)
    lat, lon = charts.PIREN_ORIGIN_LATLON
    assert lonlat_to_utm(lon, lat, 32) == pytest.approx((569796.9051786549, 7035254.301548563), abs=1e-5)
    assert lonlat_to_utm(lon, lat, 33) == pytest.approx((270605.66066646634, 7042736.466780299), abs=1e-5)
    assert lonlat_to_utm(lon, lat, 33, datum="ETRS89") == pytest.approx((270605.6606634436, 7042736.466659428),
                                                                         abs=1e-5)
    assert lonlat_to_utm(151.2093, -33.8688, 56, south=True) == pytest.approx((334368.633648097, 6250948.345385009),
                                                                               abs=1e-5)


@settings(max_examples=50, deadline=None)
@given(st.floats(-79.0, 83.0), st.floats(-8.0, 8.0), st.integers(1, 60))
def test_utm_round_trip(lat, dlon, zone):
    lon = (6.0 * zone - 183.0 + dlon + 180.0) % 360.0 - 180.0
    e, n = lonlat_to_utm(lon, lat, zone, south=lat < 0)
    lo, la = utm_to_lonlat(e, n, zone, south=lat < 0)
    assert la == pytest.approx(lat, abs=1e-10)
    assert ((lo - lon + 180.0) % 360.0 - 180.0) == pytest.approx(0.0, abs=1e-10)


def test_zone_rules_and_crs_parsing():
    assert utm_zone_for(10.4, 63.4) == 32 and utm_zone_for(15.0, 60.0) == 33
    assert utm_zone_for(5.0, 60.0) == 32  # Norway exception (normally 31)
    assert utm_zone_for(15.0, 78.0) == 33 and utm_zone_for(8.0, 78.0) == 31  # Svalbard
    assert parse_crs("EPSG:32632") == charts.CRSInfo("utm", "WGS84", 32, False)
    assert parse_crs("urn:ogc:def:crs:EPSG::25833").code == "EPSG:25833"
    assert parse_crs("EPSG:32756").south and parse_crs("utm 33n").zone == 33
    prj = (charts._data_dir() / "charts" / "land" / "land.prj").read_text()
    assert parse_crs(prj) == charts.CRSInfo("utm", "ETRS89", 33, False)
    assert parse_crs(WGS84_UTM32_PRJ).code == "EPSG:32632"
    assert parse_crs("EPSG:4326").kind == "lonlat"
    for bad in ("EPSG:3857", "mercator", "", None):
        with pytest.raises(ValueError, match="CRS"):
            parse_crs(bad)


def test_reproject_is_exact_and_scales_distances(chart):
    c33 = chart.reproject(33)
    assert c33.crs == "EPSG:32633"
    p32 = chart.local_to_utm(np.asarray(chart.polygons[30].exterior.coords))
    p33 = c33.local_to_utm(np.asarray(c33.polygons[30].exterior.coords))
    e, n = convert_utm(p32[:, 0], p32[:, 1], 32, 33)
    np.testing.assert_allclose(p33, np.stack([e, n], 1), atol=1e-6)
    back = c33.reproject(32, origin=chart.origin)
    np.testing.assert_allclose(np.asarray(back.polygons[30].exterior.coords),
                               np.asarray(chart.polygons[30].exterior.coords), atol=1e-6)
    # scale factor at Trondheim: k(33)/k(32) = 1.0006 (4.6 deg vs 1.4 deg from the central meridian)
    ratio = c33.polygons[42].length / chart.polygons[42].length
    assert 1.0005 < ratio < 1.0007
    assert chart.reproject(32) is chart


# ------------------------------------------------------------------------------------------ shipped shapefiles
def test_shipped_shapefiles_and_zone_mixing(chart):
    land = trondheim_chart("shapefile")
    assert len(land) == 3 and land.crs == "EPSG:25833" and set(land.layers) == {"land"}
    assert land.n_vertices == (2431, 4454, 3392)
    assert len(land.report["skipped_layers"]) == 4 and "rocks (empty)" in land.report["skipped_layers"]
    assert land.report["layer_crs"] == {"land": "ETRS89 / UTM zone 33N (EPSG:25833)"}
    with pytest.raises(ValueError, match="'rocks' has no polygons"):
        trondheim_chart("shapefile", layer="rocks")
    with pytest.raises(ValueError, match="unknown layer"):
        trondheim_chart("shapefile", layer="buoys")
    # the CSV (32N) and the shapefile (33N) are never mixed silently
    with pytest.raises(ValueError, match="different CRSs"):
        combine_charts([chart, land])
    both = combine_charts([chart, land], zone=33)
    assert len(both) == 64 and both.crs == "EPSG:32633"
    ref = chart.reproject(33, origin=both.origin)
    np.testing.assert_allclose(np.asarray(both.polygons[42].exterior.coords),
                               np.asarray(ref.polygons[42].exterior.coords), atol=1e-6)
    np.testing.assert_allclose(np.asarray(both.polygons[62].exterior.coords),
                               np.asarray(land.with_origin(both.origin).polygons[1].exterior.coords), atol=1e-6)
    assert charts.trondheim_chart("shapefile", zone=32).crs == "EPSG:25832"


# ------------------------------------------------------------------------------------------ files written here
def test_csv_roundtrip_with_and_without_trailing_separator(tmp_path):
    a = SQUARE_CW[:-1]
    b = np.array([[E0 + 200, N0], [E0 + 260, N0], [E0 + 230, N0 + 50]])
    for trailing in (True, False):
        path = write_csv(tmp_path / f"p{trailing}.csv", [np.vstack([a, a[:1], a[:1]]), b], trailing)
        c = load_psbmpc_csv(path, origin=(E0, N0))
        assert len(c) == 2 and c.n_vertices == (4, 3) and c.report["n_duplicate_vertices"] == 2
        np.testing.assert_allclose(to_rings(c)[1], np.stack([b[:, 1] - N0, b[:, 0] - E0], 1))
        assert load_chart(path).origin == (E0 + 130, N0 + 50)  # bbox centre
    c33 = load_psbmpc_csv(path, zone=33)
    assert c33.crs == "EPSG:32633"


@pytest.mark.parametrize("content,match", [
    ("", "empty file"),
    ("2,3\n1,2,3\n", "needs 3 lines"),
    ("two,three\n1,2,3\n4,5,6\n", "line 1 must be 'rows,cols'"),
    ("3,3\n1,2,3\n4,5,6\n", "rows = 2"),
    ("2,4\n1,2,3\n4,5,6\n", "has 3 values, line 1 says cols = 4"),
    ("2,3\n1,x,3\n4,5,6\n", "line 2 .eastings. must be comma-separated numbers"),
    ("2,5\n0,10,-1,0,5\n0,0,0,10,3\n", "column 3 is -1 in only one row"),
    ("2,2\n-1,-1\n-1,-1\n", "only separators"),
    ("2,3\n0,1,0\n0,0,0\n", "degenerate: zero area|degenerate"),
    ("2,4\n0,1,1,0\n0,0,0,0\n", r"polygon 0 is degenerate: 2 distinct vertices"),
    ("2,4\n0,1,nan,0\n0,0,1,0\n", "non-finite"),
])
def test_csv_bad_input(tmp_path, content, match):
    path = tmp_path / "bad.csv"
    path.write_text(content)
    with pytest.raises(ValueError, match=match) as err:
        load_psbmpc_csv(path)
    assert "bad.csv" in str(err.value)


def test_bowtie_is_repaired_and_reported(tmp_path):
    bow = np.array([[E0, N0], [E0 + 10, N0 + 10], [E0 + 10, N0], [E0, N0 + 10]])
    c = load_psbmpc_csv(write_csv(tmp_path / "bow.csv", [bow]))
    assert c.report["n_repaired"] == 1 and c.report["n_split_parts"] == 1
    assert len(c) == 2 and c.ids == (0, 0) and all(p.is_valid for p in c.polygons)
    assert sum(p.area for p in c.polygons) == pytest.approx(50.0)


def test_geojson_with_hole_multipolygon_and_crs(tmp_path):
    doc = {"type": "FeatureCollection",
           "crs": {"type": "name", "properties": {"name": "urn:ogc:def:crs:EPSG::32632"}},
           "features": [
               {"type": "Feature", "properties": {}, "geometry": {"type": "Polygon", "coordinates": [
                   SQUARE_CW.tolist(), HOLE_CCW.tolist()]}},
               {"type": "Feature", "properties": {}, "geometry": {"type": "Point", "coordinates": [E0, N0]}},
               {"type": "Feature", "properties": {}, "geometry": {"type": "MultiPolygon", "coordinates": [
                   [(SQUARE_CW + [300, 0]).tolist()], [(SQUARE_CW + [600, 0]).tolist()]]}},
           ]}
    path = tmp_path / "c.geojson"
    path.write_text(json.dumps(doc))
    c = load_chart(path, origin=(E0, N0))
    assert c.crs == "EPSG:32632" and len(c) == 3 and c.ids == (0, 2, 2)
    assert c.report["n_skipped_features"] == 1
    assert c.polygons[0].area == pytest.approx(100 * 100 - 20 * 20) and len(c.polygons[0].interiors) == 1
    assert Point(50, 50).within(c.polygons[0]) is False and Point(10, 10).within(c.polygons[0])
    sets = to_ring_sets(c)
    assert [len(s) for s in sets] == [2, 1, 1]
    np.testing.assert_allclose(sets[0][1], HOLE_CCW[:-1, ::-1] - [N0, E0])  # hole kept, order as given
    with pytest.raises(ValueError, match="hole"):
        to_rings(c)
    filled = to_rings(c, holes="fill")
    assert len(filled) == 3 and Polygon(filled[0]).area == pytest.approx(100 * 100)


def test_geojson_lonlat_is_projected(tmp_path):
    lat, lon = 63.43, 10.40
    ring = [[lon, lat], [lon + 0.002, lat], [lon + 0.002, lat + 0.001], [lon, lat + 0.001], [lon, lat]]
    path = tmp_path / "ll.json"
    path.write_text(json.dumps({"type": "Feature", "geometry": {"type": "Polygon", "coordinates": [ring]}}))
    c = load_geojson(path)
    assert c.crs == "EPSG:32632"
    e, n = lonlat_to_utm(lon, lat, 32)
    np.testing.assert_allclose(c.local_to_utm(np.asarray(c.polygons[0].exterior.coords)[0]), [e, n], atol=1e-6)
    assert load_geojson(path, zone=33).crs == "EPSG:32633"
    # projected coordinates without a CRS are refused, not taken as degrees
    path.write_text(json.dumps({"type": "Polygon", "coordinates": [SQUARE_CW.tolist()]}))
    with pytest.raises(ValueError, match="outside lon/lat range"):
        load_geojson(path)
    assert len(load_geojson(path, crs="EPSG:32632")) == 1


@pytest.mark.parametrize("content,match", [
    ("{not json", "not valid JSON"),
    ("[1, 2]", "not a GeoJSON object"),
    ('{"type": "FeatureCollection", "features": []}', "no Polygon or MultiPolygon"),
    ('{"type": "Point", "coordinates": [0, 0]}', "no Polygon or MultiPolygon"),
    ('{"type": "Polygon", "coordinates": [[[0, 0], [1]]]}', "malformed Polygon"),
    ('{"type": "Polygon", "coordinates": [[[0, 0], [1, 1], [0, 0]]]}', "degenerate"),
])
def test_geojson_bad_input(tmp_path, content, match):
    path = tmp_path / "bad.geojson"
    path.write_text(content)
    with pytest.raises(ValueError, match=match) as err:
        load_geojson(path, crs="EPSG:32632")
    assert "bad.geojson" in str(err.value)


def test_shapefile_written_with_pyshp(tmp_path):
    shp = write_shapefile(tmp_path / "land", [[SQUARE_CW, HOLE_CCW], [SQUARE_CW + [500, 0]]])
    c = load_shapefile(shp, origin=(E0, N0))
    assert c.crs == "EPSG:32632" and len(c) == 2 and c.ids == (0, 1) and c.layers == ("land", "land")
    assert len(c.polygons[0].interiors) == 1 and c.polygons[0].area == pytest.approx(9600.0)
    np.testing.assert_allclose(to_ring_sets(c)[0][0], SQUARE_CW[:-1, ::-1] - [N0, E0])  # order kept, NED
    assert load_chart(tmp_path / "land.shp").n_vertices == (4, 4)
    # no .prj: refused unless crs= is given
    shp2 = write_shapefile(tmp_path / "noprj", [[SQUARE_CW]], prj=None)
    with pytest.raises(ValueError, match="no .prj"):
        load_shapefile(shp2)
    assert load_shapefile(shp2, crs="EPSG:25832").crs == "EPSG:25832"


def test_shapefile_folder_layers_with_different_zones(tmp_path):
    """Layer a in 32N, layer b the same square converted to 33N: mixing is refused unless a zone is given,
    and the conversion brings b back onto a exactly."""
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    write_shapefile(tmp_path / "a" / "a", [[SQUARE_CW]])
    prj33 = (charts._data_dir() / "charts" / "land" / "land.prj").read_text()
    e33, n33 = convert_utm(SQUARE_CW[:, 0], SQUARE_CW[:, 1], 32, 33, datum="ETRS89")  # b's .prj says ETRS89
    write_shapefile(tmp_path / "b" / "b", [[np.stack([e33, n33], 1)]], prj=prj33)
    with pytest.raises(ValueError, match="different CRSs.*EPSG:32632.*EPSG:25833"):
        load_shapefile(tmp_path)
    c = load_shapefile(tmp_path, zone=32, origin=(E0, N0))
    assert c.layers == ("a", "b") and c.crs == "EPSG:32632"
    assert c.report["layer_crs"]["b"] == "ETRS89 / UTM zone 33N (EPSG:25833)"
    np.testing.assert_allclose(np.asarray(c.polygons[1].exterior.coords), np.asarray(c.polygons[0].exterior.coords),
                               atol=1e-6)
    c33 = load_shapefile(tmp_path, zone=33)
    assert c33.crs == "EPSG:32633"
    np.testing.assert_allclose(c33.local_to_utm(np.asarray(c33.polygons[1].exterior.coords)[:-1]),
                               np.stack([e33, n33], 1)[:-1], atol=1e-6)
    assert load_shapefile(tmp_path, layer="a").n_vertices == (4,)


@pytest.mark.filterwarnings("ignore")  # pyshp warns about the corrupt header before failing
def test_shapefile_and_dispatch_errors(tmp_path):
    with pytest.raises(FileNotFoundError):
        load_shapefile(tmp_path / "nothing.shp")
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="no .shp files"):
        load_shapefile(tmp_path / "empty")
    garbage = tmp_path / "g.shp"
    garbage.write_bytes(b"this is not a shapefile at all" * 10)
    (tmp_path / "g.prj").write_text(WGS84_UTM32_PRJ)
    with pytest.raises(ValueError, match="cannot read shapefile layer 'g'"):
        load_shapefile(garbage)
    w = shapefile.Writer(str(tmp_path / "pts"), shapeType=shapefile.POINT)
    w.field("n", "N")
    w.point(1.0, 2.0)
    w.record(1)
    w.close()
    (tmp_path / "pts.prj").write_text(WGS84_UTM32_PRJ)
    with pytest.raises(ValueError, match="not a polygon type"):
        load_shapefile(tmp_path / "pts.shp")
    txt = tmp_path / "chart.txt"
    txt.write_text("hello")
    with pytest.raises(ValueError, match=r"unknown chart format '.txt'; allowed: .csv"):
        load_chart(txt)
    with pytest.raises(FileNotFoundError, match="allowed"):
        load_chart(tmp_path / "missing.xyz")
    with pytest.raises(FileNotFoundError):
        load_psbmpc_csv(tmp_path / "missing.csv")
    assert len(load_chart("trondheim")) == 61
    with pytest.raises(ValueError, match="kind must be"):
        trondheim_chart("s57")


def test_chart_validation():
    with pytest.raises(ValueError, match="must be a shapely Polygon"):
        Chart((np.zeros((3, 2)),), (0.0, 0.0), "EPSG:32632", "x")
    with pytest.raises(ValueError, match="UTM CRS"):
        Chart((), (0.0, 0.0), "EPSG:4326", "x")
    with pytest.raises(ValueError, match="one entry per"):
        Chart((Polygon([(0, 0), (1, 0), (0, 1)]),), (0.0, 0.0), "EPSG:32632", "x", ids=(1, 2))


# ------------------------------------------------------------------------------------------ range filter
def _check_range_filter(chart, pos, d_so, n_arc=128):
    out = range_filter(chart, pos, d_so, n_arc=n_arc)
    pt = Point(pos)
    dist = np.array([p.distance(pt) for p in chart.polygons])
    # polygons beyond d_so are removed, all others kept (as one or more parts)
    assert set(out.ids) == {chart.ids[j] for j in np.flatnonzero(dist <= d_so)}
    assert out.report["range_removed"] == int((dist > d_so).sum())
    # kept geometry is inside the clip polygon (circumscribing the disc)
    r_max = d_so / math.cos(math.pi / n_arc) + 1e-6
    for p in out.polygons:
        assert shapely.hausdorff_distance(pt, p.exterior) <= r_max
        assert p.is_valid and p.area > 0
    # distance from the own-ship to every kept polygon is the original one
    for fid in set(out.ids):
        orig = chart.polygons[chart.ids.index(fid)]
        kept = shapely.union_all([p for p, i in zip(out.polygons, out.ids) if i == fid])
        assert kept.distance(pt) == pytest.approx(orig.distance(pt), abs=1e-6)
    # within the disc the kept geometry IS the original geometry
    disc = pt.buffer(d_so * 0.999, quad_segs=64)
    a = shapely.union_all(chart.polygons).intersection(disc)
    b = shapely.union_all(out.polygons).intersection(disc)
    assert a.symmetric_difference(b).area <= 1e-6 * max(1.0, a.area)
    return out


def test_range_filter_at_nidelva(chart):
    pos = nidelva_own_ship_ned(chart)
    out = _check_range_filter(chart, pos, 200.0)
    assert sorted(set(out.ids)) == [27, 31, 32]  # the documented choice
    assert out.report["range_clipped"] >= 2 and out.report["range_mode"] == "clip"
    whole = range_filter(chart, pos, 200.0, mode="whole")
    assert sorted(whole.ids) == [27, 31, 32] and whole.polygons[0] is chart.polygons[27]
    assert out.total_vertices < whole.total_vertices / 5
    # points in the disc whose nearest land is also in the disc see exactly the original distances
    rng = np.random.default_rng(0)
    land, kept = shapely.union_all(chart.polygons), shapely.union_all(out.polygons)
    n_checked = 0
    for _ in range(200):
        q = pos + rng.uniform(-200, 200, 2)
        r = np.hypot(*(q - pos))
        d = land.distance(Point(q))
        if d + r <= 200.0:
            assert kept.distance(Point(q)) == pytest.approx(d, abs=1e-6)
            n_checked += 1
        assert kept.distance(Point(q)) >= d - 1e-9  # clipping never brings land closer
    assert n_checked > 20


@settings(max_examples=25, deadline=None)
@given(st.floats(-2500.0, 1500.0), st.floats(-3000.0, 2000.0), st.floats(20.0, 600.0))
def test_range_filter_properties_random_positions(pos_n, pos_e, d_so):
    _check_range_filter(shipped_chart(), np.array([pos_n, pos_e]), d_so)


def test_range_filter_inside_polygon_and_errors(chart):
    # own-ship on land (inside the big polygon): distance 0 kept, and the disc is all land
    pos = np.array([-5000.0, 0.0])
    assert chart.polygons[42].contains(Point(pos))
    out = range_filter(chart, pos, 100.0)
    assert out.ids == (42,) and out.polygons[0].contains(Point(pos))
    assert out.polygons[0].area == pytest.approx(math.pi * 100.0 ** 2, rel=1e-3)
    with pytest.raises(ValueError, match="d_so"):
        range_filter(chart, pos, -1.0)
    with pytest.raises(ValueError, match="position"):
        range_filter(chart, [1.0, 2.0, 3.0], 100.0)
    with pytest.raises(ValueError, match="mode"):
        range_filter(chart, pos, 100.0, mode="bbox")


# ------------------------------------------------------------------------------------------ Nidelva / Situation
def test_nidelva_position_and_why_13_cannot_be_in_range(chart):
    e, n, zone = NIDELVA_OWN_SHIP_UTM
    assert zone == 32
    pos = nidelva_own_ship_ned(chart)
    np.testing.assert_allclose(pos, [n - chart.origin[1], e - chart.origin[0]])
    pt = Point(pos)
    dist = np.array([p.distance(pt) for p in chart.polygons])
    assert dist.min() > 50.0  # in water, river centre
    within = set(np.flatnonzero(dist <= 200.0))
    assert within == {27, 31, 32} and within <= set(TABLE2_FILE_INDICES)
    # polygons 2 and 11 of Table 2 (file 22 and 31) are > 2 d_so apart: no disc of 200 m reaches both
    assert chart.polygons[22].distance(chart.polygons[31]) > 400.0
    # the same point in zone 33 coordinates
    c33 = trondheim_chart("psbmpc", zone=33)
    p33 = nidelva_own_ship_ned(c33)
    assert c33.polygons[27].distance(Point(p33)) == pytest.approx(dist[27], rel=1e-3)


def test_rings_feed_situation(chart):
    from psbmpc_jax import OwnShip, Situation

    pos = nidelva_own_ship_ned(chart)
    local = range_filter(chart, pos, 200.0)
    rings = to_rings(local)
    assert all(r.dtype == np.float64 and r.shape[1] == 2 and len(r) >= 3 for r in rings)
    assert all(not np.array_equal(r[0], r[-1]) for r in rings)  # closing vertex dropped
    own = OwnShip(state=[pos[0], pos[1], math.pi, 2.0], waypoints=[pos, pos + [-300.0, -100.0]], U_d=2.0)
    sit = Situation(own, (), tuple(rings))
    assert len(sit.polygons) == len(local)
    sets = to_ring_sets(local)
    assert all(isinstance(s, tuple) and len(s) == 1 for s in sets)
    np.testing.assert_array_equal(sets[0][0], rings[0])
    assert len(Situation(own, (), tuple(sets)).polygons) == len(local)
