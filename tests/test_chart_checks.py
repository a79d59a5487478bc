"""Chart input checks (issue 11 item 6): swapped coordinate orders, lon/lat declared as UTM, UTM (north, east)
swapped, swapped CSV rows, charts far from their origin, corrupt shapefiles, and empty features counted and
reported with a ChartWarning."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
import shapefile

from psbmpc_jax.charts import ChartWarning, load_chart, load_geojson, load_psbmpc_csv, load_shapefile, lonlat_to_utm

WGS84_UTM32_PRJ = ('PROJCS["WGS_1984_UTM_Zone_32N",GEOGCS["GCS_WGS_1984",DATUM["D_WGS_1984",SPHEROID["WGS_1984",'
                   '6378137.0,298.257223563]],PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]],'
                   'PROJECTION["Transverse_Mercator"],PARAMETER["False_Easting",500000.0],PARAMETER["False_Northing",'
                   '0.0],PARAMETER["Central_Meridian",9.0],PARAMETER["Scale_Factor",0.9996],PARAMETER['
                   '"Latitude_Of_Origin",0.0],UNIT["Meter",1.0]]')
E0, N0 = 569000.0, 7035000.0
SQUARE = np.array([[E0, N0], [E0, N0 + 100], [E0 + 100, N0 + 100], [E0 + 100, N0], [E0, N0]])   # (east, north)
LAT, LON = 63.43, 10.40
LL_RING = [[LON, LAT], [LON + 0.002, LAT], [LON + 0.002, LAT + 0.001], [LON, LAT + 0.001], [LON, LAT]]


def csv_text(rows_e, rows_n) -> str:
    rows_e, rows_n = [repr(float(v)) for v in rows_e], [repr(float(v)) for v in rows_n]
    return f"2,{len(rows_e)}\n" + ",".join(rows_e) + "\n" + ",".join(rows_n) + "\n"


def geojson(path, coords, crs=None, extra=()):
    doc = {"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {}, "geometry": {"type": "Polygon", "coordinates": [coords]}}, *extra]}
    if crs:
        doc["crs"] = {"type": "name", "properties": {"name": crs}}
    path.write_text(json.dumps(doc))
    return path


# ------------------------------------------------------------------------------------------ coordinate order
def test_swapped_csv_rows_are_refused(tmp_path):
    p = tmp_path / "swapped.csv"
    p.write_text(csv_text(list(SQUARE[:-1, 1]), list(SQUARE[:-1, 0])))        # line 2 northings, line 3 eastings
    with pytest.raises(ValueError, match=r"swapped.csv: coordinate \(7.035e\+06, 569000\) is outside the plausible UTM "
                                         r"range .* they look like \(north, east\) -- UTM is \(east, north\) \(the "
                                         r"psbmpc CSV: line 2 eastings, line 3 northings\)"):
        load_psbmpc_csv(p)
    p.write_text(csv_text(list(SQUARE[:-1, 0]), list(SQUARE[:-1, 1])))
    assert len(load_psbmpc_csv(p)) == 1


def test_utm_north_east_swapped_in_geojson(tmp_path):
    p = geojson(tmp_path / "ne.geojson", SQUARE[:, ::-1].tolist(), crs="EPSG:32632")
    with pytest.raises(ValueError, match=r"look like \(north, east\)"):
        load_geojson(p)


def test_lonlat_declared_as_utm(tmp_path):
    p = geojson(tmp_path / "ll.geojson", LL_RING, crs="EPSG:32632")
    with pytest.raises(ValueError, match=r"look like lon/lat degrees .* but the CRS is WGS 84 / UTM zone 32N .*"
                                         r"crs='EPSG:4326'"):
        load_geojson(p)
    p = tmp_path / "ll.csv"
    p.write_text(csv_text([r[0] for r in LL_RING[:-1]], [r[1] for r in LL_RING[:-1]]))
    with pytest.raises(ValueError, match=r"look like lon/lat degrees"):
        load_psbmpc_csv(p)


def test_latlon_given_where_lonlat_belongs(tmp_path):
    # swapped into range: lat 63 as "lon", lon 10 as "lat"; the auto zone would be 41 -- refused with a zone
    p = geojson(tmp_path / "swap.geojson", [[b, a] for a, b in LL_RING])
    with pytest.raises(ValueError, match=r"longitudes up to 54.4 deg from the central meridian \(9 deg\) of UTM zone 32;"
                                         r" at most 20 deg allowed -- a wrong zone, or \[lat, lon\] given where "
                                         r"\[lon, lat\] belongs"):
        load_geojson(p, zone=32)
    # ... and with an origin near the real place the chart is far away from it
    e, n = lonlat_to_utm(LON, LAT, 32)
    with pytest.raises(ValueError, match=r"the chart lies [0-9]+ km from the origin .* at most 100 km allowed -- check "
                                         r"the coordinate order and the CRS: GeoJSON and lon/lat charts are \[lon, lat\]"):
        load_geojson(p, origin=(float(e), float(n)))
    # latitudes beyond 90 that fit as longitudes: the message says [lat, lon]
    p = geojson(tmp_path / "swap2.geojson", [[45.0, 120.0], [45.1, 120.0], [45.1, 120.1], [45.0, 120.0]])
    with pytest.raises(ValueError, match=r"outside lon/lat range .* they look like \[lat, lon\]"):
        load_geojson(p)
    assert len(load_geojson(geojson(tmp_path / "ok.geojson", LL_RING))) == 1


def test_chart_far_from_the_given_origin(tmp_path):
    p = tmp_path / "c.csv"
    p.write_text(csv_text(list(SQUARE[:-1, 0]), list(SQUARE[:-1, 1])))
    assert load_psbmpc_csv(p, origin=(E0 + 50_000, N0)).origin == (E0 + 50_000, N0)
    with pytest.raises(ValueError, match=r"the chart lies 150 km from the origin \(E0, N0\) = \(719100, 7035000\)"):
        load_psbmpc_csv(p, origin=(E0 + 150_100, N0))


def test_garbage_coordinates_are_refused(tmp_path):
    p = tmp_path / "g.csv"
    p.write_text(csv_text([E0, E0 + 100, 1e300], [N0, N0, N0 + 100]))
    with pytest.raises(ValueError, match=r"outside the plausible UTM range .* a corrupt file or the wrong CRS"):
        load_psbmpc_csv(p)


# ------------------------------------------------------------------------------------------ shapefiles
def write_shapefile(base, rings):
    w = shapefile.Writer(str(base), shapeType=shapefile.POLYGON)
    w.field("name", "C")
    for k, r in enumerate(rings):
        if r is None:
            w.null()
        else:
            w.poly([[tuple(v) for v in r]])
        w.record(f"p{k}")
    w.close()
    base.with_suffix(".prj").write_text(WGS84_UTM32_PRJ)
    return base.with_suffix(".shp")


def test_corrupt_coordinate_in_a_shapefile(tmp_path):
    shp = write_shapefile(tmp_path / "land", [SQUARE, SQUARE + [300, 0]])
    assert len(load_shapefile(shp)) == 2
    b = bytearray(shp.read_bytes())
    first_point = 100 + 8 + 4 + 32 + 4 + 4 + 4                  # file header, record header, type, bbox, counts, part
    b[first_point + 8 * 3: first_point + 8 * 4] = b"\xff\x13\x00\x7f\x01\x02\x03\x04"   # y of point 1: garbage
    shp.write_bytes(bytes(b))
    with pytest.raises(ValueError, match=r"cannot read shapefile layer 'land': record 0 point 1 .* lies outside the "
                                         r"record's bounding box .*: a corrupt file"):
        load_shapefile(shp)


def test_truncated_or_padded_shapefile_is_refused(tmp_path):
    shp = write_shapefile(tmp_path / "land", [SQUARE, SQUARE + [300, 0]])
    data = shp.read_bytes()
    shp.write_bytes(data + b"\x00" * 8)                         # size no longer matches the header
    with pytest.raises(ValueError, match=r"cannot read shapefile layer 'land'"):
        load_shapefile(shp)
    shp.write_bytes(data[:-40])
    with pytest.raises(ValueError, match=r"cannot read shapefile layer 'land'"):
        load_shapefile(shp)


def test_null_shapes_are_counted_and_reported(tmp_path):
    shp = write_shapefile(tmp_path / "land", [SQUARE, None, SQUARE + [300, 0], None])
    with pytest.warns(ChartWarning, match=r"dropped 2 null shapes; counted in Chart.report"):
        c = load_shapefile(shp)
    assert len(c) == 2 and c.report["n_null_shapes"] == 2 and c.ids == (0, 2)


# ------------------------------------------------------------------------------------------ empty features
def test_empty_geojson_features_are_counted_and_reported(tmp_path):
    extra = [{"type": "Feature", "properties": {}, "geometry": {"type": "Polygon", "coordinates": []}},
             {"type": "Feature", "properties": {}, "geometry": {"type": "MultiPolygon", "coordinates": []}},
             {"type": "Feature", "properties": {}, "geometry": {"type": "GeometryCollection", "geometries": []}},
             {"type": "Feature", "properties": {}, "geometry": None},
             {"type": "Feature", "properties": {}, "geometry": {"type": "Point", "coordinates": [E0, N0]}}]
    p = geojson(tmp_path / "e.geojson", SQUARE.tolist(), crs="EPSG:32632", extra=extra)
    with pytest.warns(ChartWarning, match=r"dropped 3 empty features \(no coordinates\), 2 features without polygon "
                                          r"geometry"):
        c = load_chart(p)
    assert len(c) == 1 and c.report["n_empty_features"] == 3 and c.report["n_skipped_features"] == 2
    # nothing dropped: no warning
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        c = load_chart(geojson(tmp_path / "ok.geojson", SQUARE.tolist(), crs="EPSG:32632"))
    assert c.report["n_empty_features"] == 0


def test_all_features_empty_is_an_error_that_counts_them(tmp_path):
    p = tmp_path / "none.geojson"
    p.write_text(json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {}, "geometry": {"type": "Polygon", "coordinates": []}}]}))
    with pytest.raises(ValueError, match=r"no Polygon or MultiPolygon features \(empty chart; 0 other features skipped, "
                                         r"1 empty\)"):
        load_geojson(p)


def test_shipped_charts_load_without_warnings():
    from psbmpc_jax.charts import trondheim_chart

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        trondheim_chart("psbmpc")
        trondheim_chart("shapefile")
