"""Lat/lon in scenario files (issue 11 item 9): the local transverse Mercator conversion of psbmpc_jax.geo
against known geodesic values (< 1 m over 10 km; in fact millimetres), and the scenario keys origin_latlon,
position_latlon and waypoints_latlon with and without a UTM chart."""

from __future__ import annotations

import math

import numpy as np
import pytest

from psbmpc_jax.charts import lonlat_to_utm, trondheim_chart
from psbmpc_jax.geo import LATLON_MAX_DISTANCE_M, check_latlon, latlon_to_ned, ned_to_latlon
from psbmpc_jax.scenario import scenario_from_dict

A_WGS84, F_WGS84 = 6378137.0, 1 / 298.257223563


def vincenty_inverse(lat1, lon1, lat2, lon2):
    """Geodesic distance [m] and initial azimuth [rad] on WGS 84 (Vincenty 1975), written independently of the
    package; converges to < 1e-12 rad, accurate to 0.1 mm."""
    a, f = A_WGS84, F_WGS84
    b = a * (1 - f)
    L = math.radians(lon2 - lon1)
    U1, U2 = math.atan((1 - f) * math.tan(math.radians(lat1))), math.atan((1 - f) * math.tan(math.radians(lat2)))
    sU1, cU1, sU2, cU2 = math.sin(U1), math.cos(U1), math.sin(U2), math.cos(U2)
    lam = L
    for _ in range(200):
        sl, cl = math.sin(lam), math.cos(lam)
        ss = math.hypot(cU2 * sl, cU1 * sU2 - sU1 * cU2 * cl)
        cs = sU1 * sU2 + cU1 * cU2 * cl
        sig = math.atan2(ss, cs)
        sa = cU1 * cU2 * sl / ss
        c2a = 1 - sa * sa
        c2sm = cs - 2 * sU1 * sU2 / c2a if c2a else 0.0
        C = f / 16 * c2a * (4 + f * (4 - 3 * c2a))
        prev = lam
        lam = L + (1 - C) * f * sa * (sig + C * ss * (c2sm + C * cs * (-1 + 2 * c2sm * c2sm)))
        if abs(lam - prev) < 1e-13:
            break
    u2 = c2a * (a * a - b * b) / (b * b)
    A = 1 + u2 / 16384 * (4096 + u2 * (-768 + u2 * (320 - 175 * u2)))
    B = u2 / 1024 * (256 + u2 * (-128 + u2 * (74 - 47 * u2)))
    ds = B * ss * (c2sm + B / 4 * (cs * (-1 + 2 * c2sm ** 2) - B / 6 * c2sm * (-3 + 4 * ss ** 2) * (-3 + 4 * c2sm ** 2)))
    s = b * A * (sig - ds)
    az = math.atan2(cU2 * math.sin(lam), cU1 * sU2 - sU1 * cU2 * math.cos(lam))
    return s, az


def meridian_arc(lat_deg: float) -> float:
    """Meridian distance from the equator [m] by Gauss-Legendre quadrature of M(phi) = a(1-e^2)/(1-e^2 sin^2)^1.5."""
    e2 = F_WGS84 * (2 - F_WGS84)
    x, w = np.polynomial.legendre.leggauss(64)
    phi = 0.5 * math.radians(lat_deg) * (x + 1)
    M = A_WGS84 * (1 - e2) / (1 - e2 * np.sin(phi) ** 2) ** 1.5
    return float(0.5 * math.radians(lat_deg) * np.sum(w * M))


# ================================================================================================ geo
def test_known_meridian_values():
    # the WGS 84 quarter meridian is 10 001 965.729 m; the arc to 45 deg 4 984 944.378 m
    assert latlon_to_ned(90.0 - 1e-12, 0.0, 0.0, 0.0)[0] == pytest.approx(10_001_965.729, abs=1e-3)
    assert latlon_to_ned(45.0, 0.0, 0.0, 0.0)[0] == pytest.approx(4_984_944.378, abs=1e-3)
    for lat in (10.0, 37.5, 63.43):
        assert latlon_to_ned(lat, 20.0, 0.0, 20.0)[0] == pytest.approx(meridian_arc(lat), abs=1e-4)
    # one minute of longitude on the equator: a * pi / 10800 = 1855.3248 m (scale 1 on the central meridian)
    assert latlon_to_ned(0.0, 1 / 60, 0.0, 0.0)[1] == pytest.approx(1855.3248, abs=1e-3)


@pytest.mark.parametrize("lat0, lon0", [(63.43, 10.39), (0.5, -20.0), (-45.0, 170.0), (78.2, 15.6)])
def test_distances_and_bearings_match_the_geodesic_within_a_metre_over_10_km(lat0, lon0):
    rng = np.random.default_rng(int(abs(lat0 * 100)))
    for az_deg in list(range(0, 360, 30)) + list(rng.uniform(0, 360, 8)):
        # the point 10 km from the origin along azimuth az_deg, by inverting Vincenty with a few Newton steps
        d_target, az = 10_000.0, math.radians(az_deg)
        n, e = d_target * math.cos(az), d_target * math.sin(az)
        lat, lon = (float(v) for v in ned_to_latlon(n, e, lat0, lon0))
        s, az_true = vincenty_inverse(lat0, lon0, lat, lon)
        p = latlon_to_ned(lat, lon, lat0, lon0)
        # the position the geodesic (distance, initial azimuth) gives in a flat NED frame, against ours
        ref = s * np.array([math.cos(az_true), math.sin(az_true)])
        assert np.hypot(*(p - ref)) < 1.0, (lat0, lon0, az_deg, p, ref)
        assert abs(np.hypot(*p) - s) < 0.02                     # distances: centimetres over 10 km


def test_round_trip_and_utm_consistency():
    lat0, lon0 = 63.43, 10.39
    lat = lat0 + np.linspace(-0.4, 0.4, 9)
    lon = lon0 + np.linspace(-0.8, 0.8, 9)
    p = latlon_to_ned(lat, lon, lat0, lon0)
    back = ned_to_latlon(p[:, 0], p[:, 1], lat0, lon0)
    np.testing.assert_allclose(back[0], lat, atol=1e-11)
    np.testing.assert_allclose(back[1], lon, atol=1e-11)
    # a local TM centred on zone 32's central meridian is UTM 32 up to its scale 0.9996 and false easting
    q = latlon_to_ned(lat, lon, 0.0, 9.0) * 0.9996
    e, n = lonlat_to_utm(lon, lat, 32)
    np.testing.assert_allclose(q[:, 0], n, atol=1e-6)
    np.testing.assert_allclose(q[:, 1] + 500_000.0, e, atol=1e-6)


def test_check_latlon():
    assert check_latlon(63.4, 10.4, "p") == (63.4, 10.4)
    with pytest.raises(ValueError, match=r"p = \[10.4, 163.4\]|p = \[163.4, 10.4\] .*looks like \[lon, lat\]"):
        check_latlon(163.4, 10.4, "p")
    with pytest.raises(ValueError, match=r"not \[lat, lon\] in degrees"):
        check_latlon(95.0, 200.0, "p")


# ================================================================================================ scenario keys
def base() -> dict:
    return {
        "name": "ll",
        "simulation": {"dt_s": 0.5, "duration_s": 200},
        "mpc": {"preset": "nidelva", "update_period_s": 5},
        "origin_latlon": {"lat": 63.43, "lon": 10.39},
        "own_ship": {"name": "OS", "position_latlon": [63.43, 10.39], "course_deg": 0, "speed_mps": 2,
                     "waypoints_latlon": [[63.44, 10.39], [63.44, 10.40]]},
        "targets": [{"name": "TS1", "position_latlon": [63.44, 10.40], "course_deg": 180, "speed_mps": 2}],
    }


def test_scenario_latlon_in_open_water():
    s = scenario_from_dict(base())
    np.testing.assert_allclose(s.own_ship.position, [0.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(s.own_ship.waypoints[1], latlon_to_ned(63.44, 10.40, 63.43, 10.39), atol=1e-9)
    assert s.targets[0].position == pytest.approx(latlon_to_ned(63.44, 10.40, 63.43, 10.39))
    # 0.01 deg of latitude north is about 1.115 km
    assert s.own_ship.waypoints[0][0] == pytest.approx(1115.0, abs=1.0)
    assert s.chart_info["origin_latlon"] == (63.43, 10.39)


def test_scenario_latlon_with_a_utm_chart_lands_on_the_chart():
    d = base()
    d["chart"] = {"builtin": "trondheim"}
    d["own_ship"] = {"name": "OS", "position_latlon": [63.4389029083, 10.39908278], "course_deg": 180,
                     "speed_mps": 1, "waypoints_latlon": [[63.4389029083, 10.39908278], [63.4380, 10.3990]]}
    d["targets"] = []
    s = scenario_from_dict(d, land_checks="off")
    chart = trondheim_chart("psbmpc")
    e, n = lonlat_to_utm(10.39, 63.43, 32)
    assert s.chart_info["origin"] == pytest.approx((float(e), float(n)))     # origin_latlon -> the chart's zone
    e1, n1 = lonlat_to_utm(10.39908278, 63.4389029083, 32)
    np.testing.assert_allclose(s.own_ship.position, [n1 - n, e1 - e], atol=1e-6)
    # without origin_latlon, lat/lon positions go through the chart's own origin
    d.pop("origin_latlon")
    s2 = scenario_from_dict(d, land_checks="off")
    np.testing.assert_allclose(s2.own_ship.position, chart.utm_to_local(np.array([e1, n1])), atol=1e-6)


@pytest.mark.parametrize("mutate, match", [
    (lambda d: d["targets"][0].update(position_latlon=[10.40, 63.44]),
     r"targets\[0\].position_latlon: \[10.4, 63.44\] lies [0-9]+ km from origin_latlon; at most 100 km allowed "
     r"\(local projection\) -- positions are \[lat, lon\], not \[lon, lat\]"),
    (lambda d: d["own_ship"].update(waypoints_latlon=[[63.44, 10.39], [95.0, 10.4]]),
     r"own_ship.waypoints_latlon\[1\] = \[95, 10.4\] is not \[lat, lon\] in degrees"),
    (lambda d: d.pop("origin_latlon"), r"own_ship.position_latlon: lat/lon positions need origin_latlon"),
    (lambda d: d.update(origin_latlon={"lat": 63.43}), r"origin_latlon: missing required key 'lon'"),
    (lambda d: d.update(origin_latlon={"lat": 10.39, "lon": 163.43}) or d["own_ship"].update(position_m=[0, 0]),
     r"origin_latlon \[lat, lon\] = \[10.39, 163.43\]|give only one of"),
    (lambda d: d["own_ship"].update(position_m=[0, 0]), r"own_ship: give only one of position_m / position_utm / "
                                                        r"position_latlon"),
    (lambda d: d.update(chart={"builtin": "trondheim", "origin_utm": {"east": 570000, "north": 7034000}}),
     r"give the origin once: chart.origin_utm or origin_latlon, not both"),
    (lambda d: d.update(chart={"builtin": "trondheim"}, origin_latlon={"lat": 10.39, "lon": 63.43}),
     r"origin_latlon: the chart lies [0-9]+ km from this origin; at most 100 km allowed"),
])
def test_scenario_latlon_errors(mutate, match):
    d = base()
    mutate(d)
    with pytest.raises(ValueError, match=match):
        scenario_from_dict(d)


def test_limit_constant():
    assert LATLON_MAX_DISTANCE_M == 100_000.0


def test_documented_latlon_example_loads(tmp_path):
    import pathlib
    import re
    import warnings

    from psbmpc_jax.scenario import load_scenario

    doc = pathlib.Path(__file__).resolve().parents[1] / "docs" / "scenarios.md"
    blocks = [b for b in re.findall(r"```yaml\n(.*?)```", doc.read_text(), flags=re.S)
              if b.startswith("name: latlon_example")]
    assert len(blocks) == 1
    (tmp_path / "ll.yaml").write_text(blocks[0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        s = load_scenario(tmp_path / "ll.yaml")
    np.testing.assert_allclose(s.own_ship.position, [0.0, 0.0], atol=1e-9)
    assert s.own_ship.waypoints[0][0] == pytest.approx(1115.0, abs=1.0)
    assert s.own_ship.waypoints[1][1] == pytest.approx(499.1, abs=0.1)
