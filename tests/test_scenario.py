"""Scenario files (psbmpc_jax.scenario): schema validation and its error messages, unit conversions, default
routes, speed plans, charts (inline, file, built-in with RDP and route clipping), the shipped scenarios, and
the Imazu files against their CSV and their generator script."""

from __future__ import annotations

import copy
import csv
import functools
import importlib.util
import json
import re
import math
import pathlib

import numpy as np
import pytest
import shapely
from shapely.geometry import LineString, Point, Polygon

from psbmpc_jax.charts import NIDELVA_OWN_SHIP_UTM, trondheim_chart
from psbmpc_jax.presets import PRESETS
from psbmpc_jax.rdp import simplify_chart
from psbmpc_jax.scenario import (KNOT, SCENARIO_DIR, Scenario, builtin_scenarios, load_scenario,
                                 scenario_from_dict)

REPO = pathlib.Path(__file__).resolve().parents[1]
BASIC = ("head_on", "crossing_give_way", "crossing_stand_on", "overtaking", "overtaken")
IMAZU = tuple(f"imazu_{k:02d}" for k in range(1, 23))


def base() -> dict:
    """A small valid scenario; every test mutates its own copy."""
    return {
        "name": "t",
        "simulation": {"dt_s": 0.5, "duration_s": 400},
        "mpc": {"preset": "nidelva", "update_period_s": 5},
        "own_ship": {"name": "OS", "position_m": [0, 0], "course_deg": 0, "speed_mps": 2},
        "targets": [{"name": "TS1", "position_m": [600, 0], "course_deg": 180, "speed_mps": 2}],
    }


def build(mutate=None) -> Scenario:
    d = base()
    if mutate is not None:
        mutate(d)
    return scenario_from_dict(d)


def own(d):
    return d["own_ship"]


def tgt(d):
    return d["targets"][0]


def _set(getter, key, value):
    def m(d):
        getter(d)[key] = value
    return m


def _del(getter, key):
    def m(d):
        del getter(d)[key]
    return m


def _top(key, value):
    return _set(lambda d: d, key, value)


# ============================================================================================ minimal and defaults
def test_minimal_scenario_and_defaults():
    s = build()
    assert s.name == "t" and s.description == "" and s.source is None
    assert (s.dt, s.duration, s.runs, s.seed) == (0.5, 400.0, 20, 0)
    o, t = s.own_ship, s.targets[0]
    assert o.colav == "psbmpc" and t.colav == "none"
    assert o.U_d == 2.0 and t.U_d == 2.0 and o.speed_plan is None
    assert (o.length, o.width) == (5.0, 3.0)
    p = PRESETS["nidelva"].params
    assert (o.T_chi, o.T_U, o.lookahead, o.R_a) == (p.os_T_chi, p.os_T_U, p.os_lookahead, p.os_R_a)
    assert (t.T_chi, t.T_U, t.lookahead, t.R_a) == (p.ob_T_chi, p.ob_T_U, p.ob_lookahead, p.ob_R_a)
    assert s.polygons == () and s.chart_info["n_polygons"] == 0 and s.chart_info["source"] is None
    assert s.mpc.preset == "nidelva" and s.mpc.n_ps == PRESETS["nidelva"].n_ps and s.mpc.period == 5.0
    assert s.mpc.behaviours.shape == PRESETS["nidelva"].behaviours().shape
    assert s.collision_distance is None and s.d_collision == p.d_safe
    sensor = s.sensor
    assert (sensor.position_std, sensor.period, sensor.filter_R_scale, sensor.U_max) == (5.0, 2.5, 25.0, 10.0)
    assert [sh.name for sh in s.ships] == ["OS", "TS1"]


def test_input_is_not_modified():
    d = base()
    d["own_ship"]["speed_kn"] = d["own_ship"].pop("speed_mps")
    before = copy.deepcopy(d)
    scenario_from_dict(d)
    assert d == before


# ============================================================================================ validation errors
ERRORS = [
    # unknown keys, at every level
    ("unknown_top", _top("simulaton", {}), r"unknown key 'simulaton' in the scenario \(top level\) \(did you mean "
                                           r"'simulation'\?\); allowed keys: name, description, simulation"),
    ("unknown_own", _set(own, "heading_deg", 0), r"unknown key 'heading_deg' in own_ship; allowed keys: .*course_deg"),
    ("unknown_target", _set(tgt, "speed", 2), r"unknown key 'speed' in targets\[0\].*; allowed keys: .*speed_mps"),
    ("unknown_sim", _set(lambda d: d["simulation"], "steps", 3), r"unknown key 'steps' in simulation"),
    ("unknown_mpc", _set(lambda d: d["mpc"], "period_s", 3), r"unknown key 'period_s' in mpc"),
    ("unknown_sensor", _top("sensor", {"position_std": 3}), r"unknown key 'position_std' in sensor"),
    ("unknown_cov", _top("sensor", {"colav_target_cov": {"pos_var": 1}}),
     r"unknown key 'pos_var' in sensor.colav_target_cov"),
    ("unknown_mc", _top("monte_carlo", {"n_runs": 3}), r"unknown key 'n_runs' in monte_carlo"),
    ("unknown_chart", _top("chart", {"polygons_m": [[[0, 0], [0, 1], [1, 0]]], "simplify": 1}),
     r"unknown key 'simplify' in chart"),
    ("unknown_plan", _set(own, "speed_plan", [{"t_s": 1, "speed_mps": 1, "speed": 2}]),
     r"unknown key 'speed' in own_ship.speed_plan\[0\]"),
    # missing required keys
    ("missing_name", _del(lambda d: d, "name"), r"missing required key 'name'"),
    ("missing_simulation", _del(lambda d: d, "simulation"), r"missing required key 'simulation'"),
    ("missing_mpc", _del(lambda d: d, "mpc"), r"missing required key 'mpc'"),
    ("missing_own_ship", _del(lambda d: d, "own_ship"), r"missing required key 'own_ship'"),
    ("missing_dt", _del(lambda d: d["simulation"], "dt_s"), r"simulation: missing required key 'dt_s'"),
    ("missing_preset", _del(lambda d: d["mpc"], "preset"), r"mpc: missing required key 'preset'"),
    ("missing_period", _del(lambda d: d["mpc"], "update_period_s"), r"mpc: missing required key 'update_period_s'"),
    ("missing_course", _del(own, "course_deg"), r"own_ship: missing required key 'course_deg'"),
    ("missing_target_name", _del(tgt, "name"), r"targets\[0\]: missing required key 'name'"),
    ("missing_position", _del(own, "position_m"), r"own_ship: missing required key, one of position_m / position_utm"),
    ("missing_speed", _del(tgt, "speed_mps"), r"targets\[0\]: missing required key, one of speed_mps / speed_kn"),
    # unit alternatives given twice
    ("speed_twice", _set(own, "speed_kn", 4), r"own_ship: give only one of speed_mps / speed_kn"),
    ("nominal_twice", lambda d: own(d).update(nominal_speed_mps=2, nominal_speed_kn=4),
     r"give only one of nominal_speed_mps / nominal_speed_kn"),
    ("umax_twice", _top("sensor", {"U_max_mps": 4, "U_max_kn": 8}), r"sensor: give only one of U_max_mps / U_max_kn"),
    ("position_twice", _set(own, "position_utm", [570000, 7034000]), r"give only one of position_m / position_utm"),
    ("waypoints_twice", lambda d: own(d).update(waypoints_m=[[10, 0]], waypoints_utm=[[1, 2]]),
     r"give only one of waypoints_m / waypoints_utm"),
    ("plan_speed_twice", _set(own, "speed_plan", [{"t_s": 1, "speed_mps": 1, "speed_kn": 2}]),
     r"own_ship.speed_plan\[0\]: give only one of speed_mps / speed_kn"),
    # multiples of the simulation step
    ("duration_multiple", _set(lambda d: d["simulation"], "duration_s", 400.25),
     r"simulation.duration_s \(400.25\) must be a multiple of simulation.dt_s \(0.5\)"),
    ("period_multiple", _set(lambda d: d["mpc"], "update_period_s", 5.2),
     r"mpc.update_period_s \(5.2\) must be a multiple of simulation.dt_s \(0.5\)"),
    ("period_below_dt", _set(lambda d: d["mpc"], "update_period_s", 0.25),
     r"mpc.update_period_s \(0.25\) must be a multiple of simulation.dt_s"),
    ("sensor_period_multiple", _top("sensor", {"period_s": 2.7}),
     r"sensor.period_s \(2.7\) must be a multiple of simulation.dt_s \(0.5\)"),
    ("sensor_default_period", lambda d: d["simulation"].update(dt_s=1.0),
     r"sensor.period_s \(not given: the default\) \(2.5\) must be a multiple of simulation.dt_s \(1\)"),
    # MPC
    ("n_ps_even", _set(lambda d: d["mpc"], "n_ps", 4), r"mpc.n_ps must be an odd integer from 1 to 99, got 4"),
    ("n_ps_zero", _set(lambda d: d["mpc"], "n_ps", 0), r"mpc.n_ps must be an odd integer from 1 to 99"),
    ("n_ps_float", _set(lambda d: d["mpc"], "n_ps", 5.0), r"mpc.n_ps must be an odd integer from 1 to 99, got 5.0"),
    ("n_ps_bool", _set(lambda d: d["mpc"], "n_ps", True), r"mpc.n_ps must be an odd integer"),
    ("preset_unknown", _set(lambda d: d["mpc"], "preset", "river"),
     r"mpc.preset must be one of \['akdag2022', 'nidelva', 'open_sea', 'sakshaug', 'tengesdal2020'\], got 'river'"),
    ("config_name", _set(lambda d: d["mpc"], "config", {"horizon": 100}),
     r"unknown PlannerConfig field\(s\) \['horizon'\]; allowed: .*'T'"),
    ("params_name", _set(lambda d: d["mpc"], "params", {"dsafe": 5}),
     r"unknown Params field\(s\) \['dsafe'\] \(did you mean 'd_safe' for 'dsafe'\?\); allowed: .*'d_safe'"),
    ("params_wind_dir_rad", _set(lambda d: d["mpc"], "params", {"wind_dir": 1.0}), r"use wind_dir_deg"),
    ("config_value", _set(lambda d: d["mpc"], "config", {"estimator": "magic"}),
     r"PlannerConfig.estimator must be one of"),
    ("config_steps", _set(lambda d: d["mpc"], "config", {"T": 100.3}), r"PlannerConfig.T / PlannerConfig.dt"),
    ("params_value", _set(lambda d: d["mpc"], "params", {"d_safe": -1}), r"Params.d_safe must be >= 0"),
    ("params_string", _set(lambda d: d["mpc"], "params", {"d_safe": "5 m"}),
     r"mpc.params.d_safe must be a finite number, got '5 m'"),
    ("params_nan", _set(lambda d: d["mpc"], "params", {"K_coll": float("nan")}),
     r"mpc.params.K_coll must be a finite number, got nan"),
    ("config_not_mapping", _set(lambda d: d["mpc"], "config", [1]), r"mpc.config must be a mapping"),
    ("speeds_alone", _set(lambda d: d["mpc"], "speed_factors", [[1, 0.5]]),
     r"mpc.speed_factors and mpc.course_offsets_deg must be given together"),
    ("sets_mismatch", lambda d: d["mpc"].update(speed_factors=[[1], [1]], course_offsets_deg=[[0]]),
     r"one set per maneuver, got 2 and 1"),
    ("speed_factor_range", lambda d: d["mpc"].update(speed_factors=[[1.5]], course_offsets_deg=[[0]]),
     r"mpc.speed_factors\[0\]\[0\] must be <= 1, got 1.5"),
    ("course_offset_range", lambda d: d["mpc"].update(speed_factors=[[1]], course_offsets_deg=[[0, 200]]),
     r"mpc.course_offsets_deg\[0\]\[1\] must be <= 180, got 200"),
    ("empty_set", lambda d: d["mpc"].update(speed_factors=[[]], course_offsets_deg=[[0]]),
     r"mpc.speed_factors\[0\] must be a non-empty list"),
    # non-finite numbers, wrong types, out of range
    ("course_string", _set(own, "course_deg", "north"), r"own_ship.course_deg must be a finite number, got 'north'"),
    ("course_nan", _set(own, "course_deg", float("nan")), r"own_ship.course_deg must be a finite number, got nan"),
    ("course_inf", _set(tgt, "course_deg", float("inf")), r"targets\[0\].course_deg must be a finite number, got inf"),
    ("course_bool", _set(own, "course_deg", True), r"own_ship.course_deg must be a finite number, got True"),
    ("position_nan", _set(own, "position_m", [0, float("nan")]), r"own_ship.position_m\[1\] must be a finite number"),
    ("speed_negative", _set(tgt, "speed_mps", -1), r"targets\[0\].speed_mps must be >= 0, got -1"),
    ("dt_zero", _set(lambda d: d["simulation"], "dt_s", 0), r"simulation.dt_s must be > 0, got 0"),
    ("duration_inf", _set(lambda d: d["simulation"], "duration_s", float("inf")),
     r"simulation.duration_s must be a finite number, got inf"),
    ("collision_zero", _top("collision_distance_m", 0), r"collision_distance_m must be > 0"),
    ("runs_zero", _top("monte_carlo", {"runs": 0}), r"monte_carlo.runs must be an integer >= 1, got 0"),
    ("runs_float", _top("monte_carlo", {"runs": 2.5}), r"monte_carlo.runs must be an integer >= 1, got 2.5"),
    ("seed_negative", _top("monte_carlo", {"seed": -1}), r"monte_carlo.seed must be an integer >= 0, got -1"),
    ("R_scale", _top("sensor", {"filter_R_scale": 0.5}), r"sensor.filter_R_scale must be >= 1, got 0.5"),
    ("std_zero", _top("sensor", {"position_std_m": 0}), r"sensor.position_std_m must be > 0"),
    ("cov_negative", _top("sensor", {"colav_target_cov": {"position_var_m2": -1}}),
     r"sensor.colav_target_cov.position_var_m2 must be > 0"),
    # a target may be a point object (length_m and width_m both 0, tests/test_sim_methods.py); not half of one
    ("length_zero", _set(tgt, "length_m", 0), r"targets\[0\]: length_m and width_m must both be 0 \(a point "
                                               r"object\) or both > 0, got 0 and 3"),
    ("own_length_zero", _set(lambda d: d["own_ship"], "length_m", 0), r"own_ship.length_m must be > 0, got 0"),
    ("R_a_negative", _set(own, "R_a_m", -1), r"own_ship.R_a_m must be >= 0"),
    ("name_empty", _top("name", ""), r"name must be a non-empty string"),
    ("description_type", _top("description", 3), r"description must be a string, got 3"),
    ("targets_not_list", _top("targets", {"name": "TS1"}), r"targets must be a list of ships, got dict"),
    ("own_not_mapping", _top("own_ship", [1, 2]), r"own_ship must be a mapping"),
    ("colav_bad", _set(tgt, "colav", "mpc"), r"targets\[0\].colav must be 'none', a known method \(psbmpc, .*\) or an import path .*got 'mpc'"),
    ("psbmpc_not_moving", lambda d: own(d).update(speed_mps=0), r"own_ship: a ship with colav psbmpc needs a nominal "
                                                                 r"speed > 0"),
    # waypoints of the wrong shape
    ("waypoints_3d", _set(own, "waypoints_m", [[1, 2, 3]]), r"own_ship.waypoints_m\[0\] must be a pair of numbers"),
    ("waypoints_flat", _set(own, "waypoints_m", [100, 0]), r"own_ship.waypoints_m\[0\] must be a pair of numbers"),
    ("waypoints_empty", _set(own, "waypoints_m", []), r"own_ship.waypoints_m must be a list of at least 1 point"),
    ("waypoints_string", _set(own, "waypoints_m", "north"), r"own_ship.waypoints_m must be a list of at least 1"),
    ("waypoints_repeat", _set(own, "waypoints_m", [[0, 0], [100, 0], [100, 0]]),
     r"own_ship.waypoints_m: route points 1 and 2 coincide"),
    ("waypoint_at_start", _set(tgt, "waypoints_m", [[600, 0]]), r"targets\[0\].waypoints_m: route points 0 and 1 "
                                                                 r"coincide"),
    ("position_shape", _set(own, "position_m", [0, 0, 0]), r"own_ship.position_m must be a pair of numbers"),
    # duplicate ship names
    ("duplicate_own", _set(tgt, "name", "OS"), r"duplicate ship name 'OS' \(own_ship and targets\[0\]\)"),
    ("duplicate_targets", lambda d: d["targets"].append(dict(tgt(d))),
     r"duplicate ship name 'TS1' \(targets\[0\] and targets\[1\]\)"),
    # speed plans
    ("plan_not_increasing", _set(own, "speed_plan", [{"t_s": 10, "speed_mps": 1}, {"t_s": 10, "speed_mps": 2}]),
     r"own_ship.speed_plan\[1\].t_s \(10\) must be greater than the previous entry's \(10\)"),
    ("plan_after_end", _set(own, "speed_plan", [{"t_s": 400, "speed_mps": 1}]),
     r"own_ship.speed_plan\[0\].t_s \(400\) must be < simulation.duration_s \(400\)"),
    ("plan_empty", _set(own, "speed_plan", []), r"own_ship.speed_plan must be a non-empty list"),
    ("plan_negative_speed", _set(own, "speed_plan", [{"t_s": 5, "speed_mps": -1}]),
     r"own_ship.speed_plan\[0\].speed_mps must be >= 0"),
    ("plan_no_speed", _set(own, "speed_plan", [{"t_s": 5}]),
     r"own_ship.speed_plan\[0\]: missing required key, one of speed_mps / speed_kn"),
    # charts
    ("two_chart_sources", _top("chart", {"builtin": "trondheim", "polygons_m": [[[0, 0], [0, 1], [1, 0]]]}),
     r"chart needs exactly one land source of builtin / file / polygons_m, got \['builtin', 'polygons_m'\]"),
    ("no_chart_source", _top("chart", {"clip_m": 100}), r"chart needs exactly one land source .* got none"),
    ("chart_builtin_unknown", _top("chart", {"builtin": "oslo"}), r"chart.builtin must be one of \['trondheim'"),
    ("utm_without_chart", lambda d: own(d).update(position_utm=own(d).pop("position_m")),
     r"own_ship.position_utm: UTM coordinates need a builtin or file chart"),
    ("utm_with_inline", lambda d: (own(d).update(waypoints_utm=[[1, 2]]),
                                   d.update(chart={"polygons_m": [[[0, 50], [0, 60], [10, 50]]]})),
     r"own_ship.waypoints_utm: UTM coordinates need a builtin or file chart"),
    ("inline_rdp", _top("chart", {"polygons_m": [[[0, 50], [0, 60], [10, 50]]], "rdp_eps_m": 1}),
     r"chart.rdp_eps_m applies only to builtin / file charts"),
    ("inline_origin", _top("chart", {"polygons_m": [[[0, 50], [0, 60], [10, 50]]],
                                     "origin_utm": {"east": 1, "north": 2}}),
     r"chart.origin_utm applies only to builtin / file charts"),
    ("inline_two_points", _top("chart", {"polygons_m": [[[0, 50], [0, 60]]]}),
     r"chart.polygons_m\[0\] must be a list of at least 3 points"),
    ("inline_bowtie", _top("chart", {"polygons_m": [[[0, 0], [10, 10], [10, 0], [0, 10]]]}),
     r"chart.polygons_m\[0\] is not a valid simple polygon \(Self-intersection"),
    ("inline_collinear", _top("chart", {"polygons_m": [[[0, 0], [1, 1], [2, 2]]]}),
     r"chart.polygons_m\[0\] is not a valid simple polygon"),
    ("inline_repeat", _top("chart", {"polygons_m": [[[0, 0], [0, 0], [0, 5], [5, 0]]]}),
     r"chart.polygons_m\[0\]: vertex 0 repeats the next one"),
    ("clip_negative", _top("chart", {"polygons_m": [[[0, 50], [0, 60], [10, 50]]], "clip_m": -5}),
     r"chart.clip_m must be > 0"),
    ("origin_zone", _top("chart", {"builtin": "trondheim", "origin_utm": {"east": 1, "north": 2, "zone": 61}}),
     r"chart.origin_utm.zone must be a UTM zone, an integer in 1..60, got 61"),
    ("origin_missing_north", _top("chart", {"builtin": "trondheim", "origin_utm": {"east": 1}}),
     r"chart.origin_utm: missing required key 'north'"),
    ("chart_file_missing", _top("chart", {"file": "no_such_chart.geojson"}),
     r"chart.file 'no_such_chart.geojson': not found"),
]


@pytest.mark.parametrize("mutate, match", [e[1:] for e in ERRORS], ids=[e[0] for e in ERRORS])
def test_validation_errors(mutate, match):
    with pytest.raises(ValueError, match=match):
        build(mutate)


def test_error_ids_are_unique():
    ids = [e[0] for e in ERRORS]
    assert len(ids) == len(set(ids))


def test_top_level_must_be_mapping():
    with pytest.raises(ValueError, match=r"the scenario must be a mapping"):
        scenario_from_dict([base()])


# ============================================================================================ units and angles
def test_knots_are_converted_exactly_once():
    def m(d):
        o = own(d)
        o.pop("speed_mps")
        o.update(speed_kn=10, nominal_speed_kn=7.5, speed_plan=[{"t_s": 50, "speed_kn": 3}, {"t_s": 60, "speed_mps": 1}])
        d["sensor"] = {"U_max_kn": 20}
    s = build(m)
    assert KNOT == 1852.0 / 3600.0
    assert s.own_ship.speed == 10 * 1852 / 3600
    assert s.own_ship.U_d == 7.5 * 1852 / 3600
    assert s.sensor.U_max == 20 * 1852 / 3600
    np.testing.assert_array_equal(s.own_ship.speed_plan, [[50.0, 3 * 1852 / 3600], [60.0, 1.0]])


@pytest.mark.parametrize("deg, rad", [(0, 0.0), (30, math.radians(30)), (90, math.pi / 2), (270, -math.pi / 2),
                                      (180, -math.pi), (-180, -math.pi), (405, math.radians(45)),
                                      (-90.5, math.radians(-90.5)), (359, math.radians(-1))])
def test_degrees_are_converted_exactly_and_wrapped(deg, rad):
    s = build(lambda d: (own(d).update(course_deg=deg), d["mpc"].update(params={"wind_dir_deg": deg})))
    assert s.own_ship.course == rad
    assert s.mpc.params.wind_dir == rad
    assert -math.pi <= s.own_ship.course < math.pi


def test_course_offsets_in_degrees():
    s = build(lambda d: d["mpc"].update(speed_factors=[[1, 0.5]], course_offsets_deg=[[-30, 0, 30]]))
    b = s.mpc.behaviours
    assert b.shape == (6, 1, 2)
    np.testing.assert_array_equal(np.unique(b[:, 0, 1]), np.radians([-30.0, 0.0, 30.0]))
    np.testing.assert_array_equal(np.unique(b[:, 0, 0]), [0.5, 1.0])


# ============================================================================================ routes
def test_default_route_along_course():
    s = build(lambda d: own(d).update(course_deg=30))
    w = s.own_ship.waypoints
    assert w.shape == (2, 2)
    np.testing.assert_array_equal(w[0], [0.0, 0.0])
    L = 2 * 2.0 * 400.0
    np.testing.assert_allclose(w[1], L * np.array([math.cos(math.radians(30)), math.sin(math.radians(30))]),
                               rtol=1e-15)
    # along the axes the route is exact (no 1e-13 m sine residue)
    np.testing.assert_array_equal(s.targets[0].waypoints, [[600.0, 0.0], [600.0 - L, 0.0]])


def test_default_route_minimum_length_and_fastest_speed():
    s = build(lambda d: (own(d).update(speed_mps=0.5, course_deg=90),
                         tgt(d).update(speed_mps=0.0, speed_plan=[{"t_s": 100, "speed_mps": 3.0}])))
    np.testing.assert_array_equal(s.own_ship.waypoints, [[0.0, 0.0], [0.0, 1000.0]])  # 2*0.5*400 < 1000 m
    np.testing.assert_array_equal(s.targets[0].waypoints, [[600.0, 0.0], [600.0 - 2 * 3.0 * 400, 0.0]])
    assert s.targets[0].U_d == 0.0  # a stationary target (colav none) is allowed


def test_route_with_one_point_gets_the_start_prepended():
    s = build(lambda d: own(d).update(position_m=[10, -5], waypoints_m=[[500, 20]]))
    np.testing.assert_array_equal(s.own_ship.waypoints, [[10.0, -5.0], [500.0, 20.0]])
    s = build(lambda d: own(d).update(waypoints_m=[[5, 5], [500, 20], [900, 0]]))
    np.testing.assert_array_equal(s.own_ship.waypoints, [[5.0, 5.0], [500.0, 20.0], [900.0, 0.0]])


def test_speed_plan_parsing_and_nominal_speed():
    s = build(lambda d: own(d).update(nominal_speed_mps=1.5,
                                      speed_plan=[{"t_s": 0, "speed_mps": 1.0}, {"t_s": 120.5, "speed_mps": 0}]))
    assert s.own_ship.speed == 2.0 and s.own_ship.U_d == 1.5
    assert s.own_ship.speed_plan.shape == (2, 2) and s.own_ship.speed_plan.dtype == np.float64
    np.testing.assert_array_equal(s.own_ship.speed_plan, [[0.0, 1.0], [120.5, 0.0]])


# ============================================================================================ overrides
def test_overrides_are_applied():
    def m(d):
        d["mpc"].update(n_ps=3, config={"T": 60.0, "estimator": "mc"}, params={"d_safe": 8.0, "os_T_chi": 2.0})
        own(d)["T_U_s"] = 3.0
        tgt(d).update(colav="psbmpc", lookahead_m=40)
        d["monte_carlo"] = {"runs": 3, "seed": 7}
        d["sensor"] = {"colav_target_cov": {"velocity_var_m2s2": 0.04}}
    s = build(m)
    assert s.mpc.n_ps == 3 and s.mpc.config.T == 60.0 and s.mpc.config.estimator == "mc"
    assert s.mpc.params.d_safe == 8.0 and s.d_collision == 8.0
    assert s.own_ship.T_chi == 2.0 and s.own_ship.T_U == 3.0  # preset default after override, then own value
    assert s.targets[0].colav == "psbmpc" and s.targets[0].lookahead == 40.0
    assert s.targets[0].T_chi == PRESETS["nidelva"].params.ob_T_chi
    assert (s.runs, s.seed) == (3, 7) and s.sensor.colav_target_cov == (1.0, 0.04)
    assert build(_top("collision_distance_m", 12)).d_collision == 12.0
    # t_ts = nan (T / n_M) is the one non-finite value a parameter may take
    assert math.isnan(build(lambda d: d["mpc"].update(params={"t_ts": float("nan")})).mpc.params.t_ts)


# ============================================================================================ charts
def test_inline_polygons_as_ring_sets_and_clip():
    near = [[100, 20], [100, 60], [140, 60], [140, 20], [100, 20]]  # closed explicitly; 20-60 m east of the route
    far = [[100, 500], [100, 520], [120, 520]]                        # 500 m east: beyond clip_m
    across = [[300, -200], [300, 200], [310, 200], [310, -200]]       # crosses the route
    s = build(lambda d: d.update(chart={"polygons_m": [near, far, across]}))
    assert len(s.polygons) == 3 and all(isinstance(rs, tuple) and len(rs) == 1 for rs in s.polygons)
    np.testing.assert_array_equal(s.polygons[0][0], np.array(near[:-1], float))  # closing point dropped
    assert s.polygons[0][0].dtype == np.float64 and s.polygons[1][0].shape == (3, 2)
    assert s.chart_info["source"] == "inline chart.polygons_m" and s.chart_info["n_vertices"] == 4 + 3 + 4

    s = build(lambda d: d.update(chart={"polygons_m": [near, far, across], "clip_m": 100}))
    info = s.chart_info
    assert info["clip_m"] == 100.0 and info["clip_removed"] == 1 and info["clip_clipped"] == 1
    assert info["n_polygons"] == len(s.polygons) == 2 and info["n_polygons_loaded"] == 3
    np.testing.assert_array_equal(s.polygons[0][0], np.array(near[:-1], float))  # inside: untouched
    clipped = Polygon(s.polygons[1][0])
    assert clipped.bounds[1] == pytest.approx(-100.0, abs=0.5) and clipped.bounds[3] == pytest.approx(100.0, abs=0.5)
    assert clipped.area == pytest.approx(10 * 200, rel=1e-3)


def test_clip_keeps_parts_near_every_route_and_counts_splits():
    # a long wall east of both ships: the own-ship's route (north) and a target's route (far east) each keep a part
    wall = [[-2000, 300], [-2000, 310], [2000, 310], [2000, 300]]

    def m(d):
        d["chart"] = {"polygons_m": [wall], "clip_m": 50}
        own(d).update(waypoints_m=[[0, 0], [0, 260]])  # route turns east, ends 40 m from the wall
        tgt(d).update(position_m=[-1500, 330], waypoints_m=[[-1500, 330], [-1000, 330]])
    s = build(m)
    assert len(s.polygons) == 2 and s.chart_info["clip_clipped"] == 1 and s.chart_info["clip_removed"] == 0
    route = shapely.union_all([LineString([(0, 0), (0, 260)]), LineString([(-1500, 330), (-1000, 330)])])
    for rs in s.polygons:
        assert max(route.distance(Point(v)) for v in rs[0]) <= 50.0 + 1e-6


@functools.lru_cache(maxsize=None)
def simplified_trondheim():
    return simplify_chart(trondheim_chart("psbmpc"), 2.0)


@pytest.fixture(scope="module")
def trondheim_scenario():
    e, n, _ = NIDELVA_OWN_SHIP_UTM

    def m(d):
        d["chart"] = {"builtin": "trondheim", "rdp_eps_m": 2, "clip_m": 300}
        own(d).pop("position_m")
        own(d).update(position_utm=[e, n], waypoints_utm=[[e, n + 400]], speed_mps=1.0)
        d["targets"] = []
        d["simulation"]["duration_s"] = 100
    return build(m)


def test_builtin_chart_utm_conversion_rdp_and_route_clip(trondheim_scenario):
    s = trondheim_scenario
    full = trondheim_chart("psbmpc")
    e, n, _ = NIDELVA_OWN_SHIP_UTM
    np.testing.assert_array_equal(s.own_ship.position, full.utm_to_local(np.array([e, n])))
    np.testing.assert_array_equal(s.own_ship.waypoints[1], full.utm_to_local(np.array([e, n + 400])))
    info = s.chart_info
    assert info["crs"] == "EPSG:32632" and info["origin"] == full.origin and info["source"].startswith("builtin:")
    assert info["rdp_eps_m"] == 2.0 and info["clip_m"] == 300.0
    assert info["n_polygons_loaded"] == len(full) and info["n_vertices_loaded"] == full.total_vertices
    assert info["n_vertices_rdp"] == simplified_trondheim().total_vertices
    assert 0 < info["n_polygons"] == len(s.polygons) < len(full)
    assert info["n_vertices"] == sum(len(r) for rs in s.polygons for r in rs)
    assert info["clip_removed"] > 0
    # every vertex lies within clip_m of the route, and the kept land is the simplified land in the buffer
    route = LineString(s.own_ship.waypoints)
    verts = np.vstack([r for rs in s.polygons for r in rs])
    assert shapely.distance(shapely.points(verts), route).max() <= 300.0 + 1e-6
    region = route.buffer(300.0, quad_segs=16)
    expected = sum(p.intersection(region).area for p in simplified_trondheim().polygons)
    got = sum(Polygon(rs[0], rs[1:]).area for rs in s.polygons)
    assert got == pytest.approx(expected, rel=1e-9) and got > 0


def test_builtin_chart_origin_utm():
    e, n, _ = NIDELVA_OWN_SHIP_UTM

    def m(d):
        d["chart"] = {"builtin": "trondheim", "origin_utm": {"east": e, "north": n, "zone": 32}, "clip_m": 200}
        own(d).pop("position_m")
        own(d)["position_utm"] = [e, n]
        d["targets"] = []
    s = build(m)
    np.testing.assert_array_equal(s.own_ship.position, [0.0, 0.0])
    assert s.chart_info["origin"] == (e, n) and s.chart_info["rdp_eps_m"] is None
    verts = np.vstack([r for rs in s.polygons for r in rs])
    assert np.hypot(verts[:, 0], verts[:, 1]).min() < 200.0


def test_chart_file_relative_to_the_scenario_file(tmp_path):
    E0, N0 = 570000.0, 7034000.0
    square = [[E0 + 100, N0 + 200], [E0 + 150, N0 + 200], [E0 + 150, N0 + 260], [E0 + 100, N0 + 260],
              [E0 + 100, N0 + 200]]
    (tmp_path / "charts").mkdir()
    (tmp_path / "charts" / "land.geojson").write_text(json.dumps({
        "type": "FeatureCollection", "crs": {"type": "name", "properties": {"name": "EPSG:32632"}},
        "features": [{"type": "Feature", "properties": {}, "geometry": {"type": "Polygon", "coordinates": [square]}}],
    }))
    (tmp_path / "s.yaml").write_text(f"""
name: file_chart
simulation: {{dt_s: 0.5, duration_s: 100}}
mpc: {{preset: open_sea, update_period_s: 5}}
chart:
  file: charts/land.geojson
  origin_utm: {{east: {E0}, north: {N0}}}
own_ship:
  name: OS
  position_utm: [{E0 + 10}, {N0 + 20}]
  course_deg: 0
  speed_mps: 5
""")
    s = load_scenario(tmp_path / "s.yaml")
    np.testing.assert_array_equal(s.own_ship.position, [20.0, 10.0])
    ring = s.polygons[0][0]
    assert Polygon(ring).equals(Polygon([(200, 100), (200, 150), (260, 150), (260, 100)]))
    assert s.chart_info["origin"] == (E0, N0) and s.chart_info["crs"] == "EPSG:32632"
    assert s.source == str(tmp_path / "s.yaml")


# ============================================================================================ YAML files
def write(tmp_path, text, name="s.yaml"):
    p = tmp_path / name
    p.write_text(text)
    return p


MINIMAL_YAML = """
name: y
simulation: {dt_s: 0.5, duration_s: 1e2}
mpc: {preset: nidelva, update_period_s: 5}
own_ship: {name: OS, position_m: [0, 0], course_deg: 0, speed_mps: 2}
"""


def test_yaml_12_floats_and_path_loading(tmp_path):
    s = load_scenario(write(tmp_path, MINIMAL_YAML))
    assert s.duration == 100.0 and s.targets == ()
    assert load_scenario(str(write(tmp_path, MINIMAL_YAML, "other.yml"))).name == "y"


def test_yaml_duplicate_keys_are_refused(tmp_path):
    p = write(tmp_path, MINIMAL_YAML + "name: z\n")
    with pytest.raises(ValueError, match=r"duplicate key 'name' at line \d+"):
        load_scenario(p)


def test_yaml_errors_name_the_file(tmp_path):
    p = write(tmp_path, MINIMAL_YAML.replace("course_deg: 0", "course_deg: .inf"))
    with pytest.raises(ValueError, match=r"s\.yaml: own_ship.course_deg must be a finite number, got inf"):
        load_scenario(p)
    with pytest.raises(ValueError, match=r"not valid YAML"):
        load_scenario(write(tmp_path, "name: [unclosed\n", "bad.yaml"))
    with pytest.raises(ValueError, match=r"must hold a mapping at the top level, got list"):
        load_scenario(write(tmp_path, "- 1\n- 2\n", "list.yaml"))


def test_load_scenario_bad_names_and_paths(tmp_path):
    with pytest.raises(ValueError, match=r"unknown built-in scenario 'no_such'; built-in scenarios: .*head_on"):
        load_scenario("no_such")
    with pytest.raises(FileNotFoundError, match=r"scenario file not found"):
        load_scenario(tmp_path / "missing.yaml")
    with pytest.raises(ValueError, match=r"must end in .yaml or .yml"):
        load_scenario(write(tmp_path, MINIMAL_YAML, "s.txt"))
    with pytest.raises(ValueError, match=r"needs a .yaml/.yml path or a built-in scenario name"):
        load_scenario(3)


# ============================================================================================ shipped scenarios
def test_builtin_scenario_names():
    names = builtin_scenarios()
    assert names == sorted(names)
    assert set(BASIC) | set(IMAZU) <= set(names)
    assert "imazu_cases" not in names  # the CSV is data, not a scenario


@pytest.mark.parametrize("name", builtin_scenarios())
def test_every_shipped_scenario_loads(name):
    s = load_scenario(name)
    assert s.name == name and s.source.endswith((f"{name}.yaml", f"{name}.yml"))
    assert s.own_ship.colav == s.mpc.method and s.own_ship.U_d > 0
    assert s.description and s.d_collision > 0
    for ship in s.ships:
        assert ship.waypoints.shape[0] >= 2 and np.all(np.isfinite(ship.waypoints))
        assert -math.pi <= ship.course < math.pi


def cpa(s: Scenario):
    """(time, distance) of the closest approach of own-ship and target 0 at their initial velocities."""
    o, t = s.own_ship, s.targets[0]
    v = lambda sh: sh.speed * np.array([math.cos(sh.course), math.sin(sh.course)])
    dp, dv = t.position - o.position, v(t) - v(o)
    tc = -float(dp @ dv) / float(dv @ dv)
    return tc, float(np.linalg.norm(dp + tc * dv)), float(np.linalg.norm(dp + s.duration * dv))


@pytest.mark.parametrize("name, t_cpa", [("head_on", 150.0), ("crossing_give_way", 150.0),
                                         ("crossing_stand_on", 150.0), ("overtaking", 125.0), ("overtaken", 75.0)])
def test_basic_encounters(name, t_cpa):
    s = load_scenario(name)
    assert s.mpc.preset == "nidelva" and s.d_collision == 5.0 and s.polygons == ()
    assert (s.dt, s.mpc.period, s.runs) == (0.5, 5.0, 20) and 400 <= s.duration <= 600
    assert (s.sensor.position_std, s.sensor.period, s.sensor.filter_R_scale, s.sensor.sigma_a, s.sensor.U_max) == \
        (2.0, 2.5, 25.0, 0.5, 4.0)
    o, t = s.own_ship, s.targets[0]
    assert len(s.targets) == 1 and t.colav == "none" and o.colav == "psbmpc"
    np.testing.assert_array_equal(o.position, [0.0, 0.0])
    assert o.course == 0.0 and o.waypoints.shape == (2, 2) and o.waypoints[1][1] == 0.0
    tc, d_cpa, d_end = cpa(s)
    assert tc == pytest.approx(t_cpa, abs=1e-9) and d_cpa == pytest.approx(0.0, abs=1e-9)  # collision course
    assert d_end >= 300.0  # passed and separated by the end
    for ship in (o, t):  # routes straight, along the initial course, long enough for the whole run
        leg = ship.waypoints[1] - ship.waypoints[0]
        np.testing.assert_array_equal(ship.waypoints[0], ship.position)
        assert math.atan2(leg[1], leg[0]) == pytest.approx(ship.course, abs=1e-12) or abs(ship.course) == math.pi
        assert np.linalg.norm(leg) >= ship.speed * s.duration
    expected = {
        "head_on": dict(speed=(2.0, 2.0), target_course=180, side=0),
        "crossing_give_way": dict(speed=(2.0, 2.0), target_course=270, side=+1),
        "crossing_stand_on": dict(speed=(2.0, 2.0), target_course=90, side=-1),
        "overtaking": dict(speed=(2.0, 0.8), target_course=0, side=0),
        "overtaken": dict(speed=(1.5, 3.5), target_course=0, side=0),
    }[name]
    assert (o.speed, t.speed) == expected["speed"] and o.U_d == o.speed
    np.testing.assert_allclose([math.cos(t.course), math.sin(t.course)],
                               [math.cos(math.radians(expected["target_course"])),
                                math.sin(math.radians(expected["target_course"]))], atol=1e-15)
    assert np.sign(t.position[1]) == expected["side"]  # + starboard (east), - port
    if name == "overtaking":
        assert t.position.tolist() == [150.0, 0.0]
    if name == "overtaken":
        assert t.position.tolist() == [-150.0, 0.0]
    if name == "head_on":
        assert t.position.tolist() == [600.0, 0.0]


def read_imazu_csv():
    """The CSV parsed here, independently of the generator: case -> (type, t_end, [rows])."""
    lines = (SCENARIO_DIR / "imazu_cases.csv").read_text().splitlines()
    assert lines[0].startswith("#")  # the header comments that say where the numbers come from are kept
    rows = list(csv.DictReader(ln for ln in lines if not ln.startswith("#")))
    cases = {}
    for r in rows:
        cases.setdefault(int(r["case"]), (r["type"], float(r["t_end_s"]), []))[2].append(r)
    return cases


def test_imazu_files_reproduce_the_csv():
    cases = read_imazu_csv()
    assert sorted(cases) == list(range(1, 23))
    d_safe = PRESETS["open_sea"].params.d_safe
    for k, (_, t_end, rows) in cases.items():
        s = load_scenario(f"imazu_{k:02d}")
        assert (s.duration, s.dt, s.runs, s.seed, s.mpc.preset, s.mpc.period) == (t_end, 1.0, 5, k, "open_sea", 5.0)
        assert s.collision_distance is None and s.d_collision == d_safe
        assert (s.sensor.position_std, s.sensor.filter_R_scale, s.sensor.sigma_a, s.sensor.U_max) == (10, 25, 0.5, 12)
        assert s.sensor.period % s.dt == 0
        o = s.own_ship
        assert o.position.tolist() == [0.0, 0.0] and o.course == 0.0 and o.speed == 10.0 and o.U_d == 10.0
        assert o.waypoints[0].tolist() == [0.0, 0.0] and o.waypoints[-1][1] == 0.0
        assert o.waypoints[-1][0] >= o.speed * t_end
        assert [t.name for t in s.targets] == [r["target"] for r in rows]
        for ship in s.ships:
            assert (ship.length, ship.width) == (100.0, 20.0)
        for t, r in zip(s.targets, rows):
            start = [float(r["dnorth_m"]), float(r["deast_m"])]
            assert t.position.tolist() == start and t.colav == "none"
            assert t.speed == float(r["speed_mps"]) and t.U_d == t.speed
            c = math.radians(float(r["course_deg"]))
            np.testing.assert_allclose([math.cos(t.course), math.sin(t.course)], [math.cos(c), math.sin(c)],
                                       atol=1e-15)
            np.testing.assert_array_equal(t.waypoints, [start, [float(r["route_end_dnorth_m"]),
                                                                float(r["route_end_deast_m"])]])
            leg = t.waypoints[1] - t.waypoints[0]
            bearing = math.degrees(math.atan2(leg[1], leg[0])) % 360.0
            assert bearing == pytest.approx(float(r["route_bearing_deg"]), abs=0.05)


def load_generator():
    spec = importlib.util.spec_from_file_location("make_imazu_scenarios", REPO / "tools" / "make_imazu_scenarios.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_imazu_files_equal_the_generator_output():
    files = load_generator().render()
    assert sorted(files) == [f"{n}.yaml" for n in IMAZU]
    committed = sorted(p.name for p in SCENARIO_DIR.glob("imazu_*.y*ml"))
    assert committed == sorted(files)
    for name, text in files.items():
        assert (SCENARIO_DIR / name).read_text(encoding="utf-8") == text, f"{name} is stale: run the script"


def test_imazu_generator_rejects_a_bad_csv(tmp_path):
    gen = load_generator()
    text = (SCENARIO_DIR / "imazu_cases.csv").read_text()
    p = tmp_path / "bad.csv"
    p.write_text(text.replace(",HO,", ",XX,"))
    with pytest.raises(ValueError, match=r"unknown type 'XX'"):
        gen.render(p)
    p.write_text("\n".join(ln for ln in text.splitlines() if not ln.startswith("22,")))
    with pytest.raises(ValueError, match=r"expected the cases 1..22"):
        gen.render(p)


# ============================================================================================ documentation
DOC = REPO / "docs" / "scenarios.md"


def test_documented_example_loads(tmp_path):
    blocks = re.findall(r"```yaml\n(.*?)```", DOC.read_text(), flags=re.S)
    example = [b for b in blocks if b.startswith("name: harbour_example")]
    assert len(example) == 1
    s = load_scenario(write(tmp_path, example[0]))
    assert s.name == "harbour_example" and (s.runs, s.seed, s.dt, s.duration) == (10, 42, 0.5, 300.0)
    np.testing.assert_array_equal(s.own_ship.position, [0.0, 0.0])
    assert s.own_ship.speed == 4 * 1852 / 3600 and s.sensor.U_max == 8 * 1852 / 3600
    np.testing.assert_array_equal(s.own_ship.speed_plan, [[120.0, 3 * 1852 / 3600]])
    assert s.mpc.n_ps == 3 and s.mpc.config.T == 100 and s.mpc.params.wind_dir == math.pi / 4
    assert s.mpc.behaviours.shape == (2 * 5 * 3, 2, 2) and s.d_collision == 6.0
    ferry, anchored = s.targets
    np.testing.assert_array_equal(ferry.waypoints, [[-260.0, -82.0], [-60.0, 1.0]])
    assert anchored.speed == 0.0 and anchored.colav == "none" and anchored.length == 12.0
    assert s.chart_info["origin"] == (570210.0, 7034815.0) and s.chart_info["n_polygons"] == len(s.polygons) > 0


def test_every_shipped_scenario_is_documented():
    text = DOC.read_text()
    missing = [n for n in builtin_scenarios() if f"`{n}`" not in text]
    assert not missing, f"docs/scenarios.md does not list {missing}"
