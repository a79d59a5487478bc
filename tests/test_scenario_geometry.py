"""Geometry of the shipped Nidelva and Sakshaug scenario files (tools/check_scenario_geometry.py): routes
clear of land, starts in water, and nominal CPAs that make the scenarios real avoidance tests.  Reads the
YAML directly (independent of the loader in psbmpc_jax.scenario)."""

from __future__ import annotations

import importlib.util
import math
import pathlib

import pytest
import yaml

REPO = pathlib.Path(__file__).resolve().parents[1]
SCENARIOS = REPO / "psbmpc_jax" / "scenarios"

_spec = importlib.util.spec_from_file_location("check_scenario_geometry",
                                               REPO / "tools" / "check_scenario_geometry.py")
geo = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(geo)
route_clearances = geo.route_clearances

#: minimum distance [m] of every route leg to land, per file
MIN_CLEARANCE_M = {"nidelva": 10.0, "sakshaug": 20.0}


def _load(name: str) -> dict:
    with open(SCENARIOS / f"{name}.yaml", encoding="utf-8") as f:
        return yaml.safe_load(f)


@pytest.fixture(scope="module")
def results() -> dict:
    return {name: route_clearances(_load(name), base_dir=SCENARIOS) for name in MIN_CLEARANCE_M}


@pytest.mark.parametrize("name", sorted(MIN_CLEARANCE_M))
def test_routes_clear_of_land(results, name):
    res = results[name]
    for ship, sh in res["ships"].items():
        assert sh["start_in_water"], f"{name}: {ship} starts on land"
        assert sh["start_clearance_m"] >= MIN_CLEARANCE_M[name], (name, ship, sh["start_clearance_m"])
        for j, leg in enumerate(sh["legs"]):
            assert leg["clearance_m"] >= MIN_CLEARANCE_M[name], f"{name}: {ship} leg {j} {leg}"
        # the ships stay on their listed routes for the whole run (no unchecked extension beyond the end)
        assert sh["beyond_route_m"] == 0.0, (name, ship, sh["beyond_route_m"])
        assert sh["min_clearance_m"] >= MIN_CLEARANCE_M[name]


@pytest.mark.parametrize("name", sorted(MIN_CLEARANCE_M))
def test_initial_course_is_first_leg_bearing(results, name):
    data = _load(name)
    for ship in [data["own_ship"]] + data["targets"]:
        first = results[name]["ships"][ship["name"]]["legs"][0]["course_deg"]
        diff = (float(ship["course_deg"]) - first + 180.0) % 360.0 - 180.0
        assert abs(diff) < 0.5, (name, ship["name"], ship["course_deg"], first)


@pytest.mark.parametrize("name", sorted(MIN_CLEARANCE_M))
def test_every_target_conflicts_with_own_ship(results, name):
    res = results[name]
    own = _load(name)["own_ship"]["name"]
    d2 = 2.0 * res["d_safe_m"]
    with_os = [p for p in res["pairs"] if p["a"] == own]
    assert len(with_os) == len(res["ships"]) - 1
    for p in with_os:
        assert p["cpa_m"] < d2, p
        assert 0.0 < p["t_cpa_s"] < res["duration_s"], p


def test_sakshaug_targets_do_not_meet_each_other(results):
    res = results["sakshaug"]
    d2 = 2.0 * res["d_safe_m"]
    assert res["d_safe_m"] == 10.0
    tt = [p for p in res["pairs"] if p["a"] != "OS"]
    assert len(tt) == 6
    for p in tt:
        assert p["cpa_m"] >= d2, p


def test_nidelva_meets_targets_one_after_the_other(results):
    res = results["nidelva"]
    assert res["d_safe_m"] == 5.0
    t = sorted(p["t_cpa_s"] for p in res["pairs"] if p["a"] == "OS")
    assert len(t) == 2 and t[1] - t[0] >= 30.0
    tt = [p for p in res["pairs"] if p["a"] != "OS"]
    assert all(p["cpa_m"] >= 2.0 * res["d_safe_m"] for p in tt)


# ------------------------------------------------------------------------------------ the checker itself
def _toy(**over) -> dict:
    data = {
        "name": "toy",
        "simulation": {"dt_s": 0.5, "duration_s": 100},
        "mpc": {"preset": "sakshaug"},
        "chart": {"polygons_m": [[[10, 30], [10, 40], [-10, 40], [-10, 30]]]},   # square 20 m east of x-axis
        "own_ship": {"name": "A", "position_m": [-100, 0], "course_deg": 0, "speed_mps": 2,
                     "waypoints_m": [[100, 0]]},
        "targets": [{"name": "B", "position_m": [100, 5], "course_deg": 180, "speed_kn": 2 * 3600 / 1852}],
    }
    data.update(over)
    return data


def test_checker_on_a_toy_case():
    res = route_clearances(_toy())
    a, b = res["ships"]["A"], res["ships"]["B"]
    assert res["d_safe_m"] == 10.0 and res["collision_distance_m"] == 10.0
    assert len(a["legs"]) == 1 and a["legs"][0]["from"] == [-100.0, 0.0]          # start prepended
    assert a["legs"][0]["clearance_m"] == pytest.approx(30.0)
    assert a["beyond_route_m"] == pytest.approx(0.0)
    # B has no waypoints: a straight line along its course, >= 1000 m long
    assert b["legs"][0]["length_m"] == pytest.approx(1000.0)
    assert b["legs"][0]["clearance_m"] == pytest.approx(25.0)
    (p,) = res["pairs"]
    assert p["cpa_m"] == pytest.approx(5.0, abs=1e-9) and p["t_cpa_s"] == pytest.approx(50.0, abs=1e-6)


def test_checker_counts_the_route_extension_and_land_starts():
    data = _toy(own_ship={"name": "A", "position_m": [-100, 0], "course_deg": 0, "speed_mps": 2,
                          "waypoints_m": [[-100, 0], [-50, 0], [-50, 10]]})   # ends after 60 m, 200 m covered
    data["targets"][0]["position_m"] = [0, 35]                                  # inside the square
    res = route_clearances(data)
    a, b = res["ships"]["A"], res["ships"]["B"]
    assert a["beyond_route_m"] == pytest.approx(140.0)
    # the extension runs east along n = -50 up to e = 150: nearest land corner (-10, 30) is 40 m away
    assert a["extension_clearance_m"] == pytest.approx(40.0)
    assert not b["start_in_water"] and b["start_clearance_m"] == 0.0
    assert math.isfinite(res["pairs"][0]["cpa_m"])
