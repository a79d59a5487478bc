"""Per-run metrics and aggregation (psbmpc_jax.sim.metrics) on hand-built trajectories with known answers."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from psbmpc_jax.sim.metrics import (
    CROSSING_GIVE_WAY_MAX_DEG,
    HEAD_ON_SECTOR_DEG,
    OVERTAKING_ABAFT_SECTOR_DEG,
    PORT_TURN_LIMIT_DEG,
    SPEED_REDUCTION_RATIO,
    STARBOARD_TURN_MIN_DEG,
    aggregate,
    classify_encounter,
    course_rate,
    cross_track_deviation,
    distance_to_land,
    encounter_type,
    maneuver_compliance,
    relative_bearings,
    run_metrics,
)

T = np.arange(0.0, 200.0 + 1e-9, 0.5)          # 401 samples
NORTH_ROUTE = np.array([[0.0, 0.0], [3000.0, 0.0]])


def straight(n0, e0, chi, U, t=T):
    return np.column_stack([n0 + U * math.cos(chi) * t, e0 + U * math.sin(chi) * t,
                            np.full_like(t, chi), np.full_like(t, U)])


def integrate(chi, U, n0=0.0, e0=0.0, t=T):
    """Own-ship rows from course/speed histories (exact for piecewise-constant chi, U between samples)."""
    chi = np.broadcast_to(np.asarray(chi, float), t.shape)
    U = np.broadcast_to(np.asarray(U, float), t.shape)
    dt = np.diff(t)
    n = n0 + np.concatenate([[0.0], np.cumsum(U[:-1] * np.cos(chi[:-1]) * dt)])
    e = e0 + np.concatenate([[0.0], np.cumsum(U[:-1] * np.sin(chi[:-1]) * dt)])
    return np.column_stack([n, e, chi, U])


def turn(deg, start=20.0, duration=10.0, t=T):
    """Course history: 0 until ``start``, then a linear turn to ``deg`` over ``duration`` seconds (+ = starboard)."""
    return np.radians(deg) * np.clip((t - start) / duration, 0.0, 1.0)


# ----------------------------------------------------------------------------------------------- geometry
def state(n, e, chi_deg, U=5.0):
    return np.array([n, e, math.radians(chi_deg), U])


@pytest.mark.parametrize("own, target, expected", [
    (state(0, 0, 0), state(1000, -20, 180), "head-on"),
    (state(0, 0, 90), state(10, 800, -90), "head-on"),
    (state(0, 0, 0), state(500, 500, -90), "crossing-give-way"),        # from starboard, beta = 45
    (state(0, 0, 0), state(0, 500, 180), "crossing-give-way"),          # abeam to starboard, beta = 90
    (state(0, 0, 0), state(500, -500, 90), "crossing-stand-on"),        # from port, beta = -45
    (state(0, 0, 0), state(200, 10, 0, 3.0), "overtaking"),
    (state(0, 0, 0), state(200, 150, 30, 3.0), "overtaking"),
    (state(0, 0, 0, 3.0), state(-200, 10, 0, 8.0), "overtaken"),
    (state(0, 0, 45, 3.0), state(-300, -250, 30, 8.0), "overtaken"),
    (state(0, 0, 0), state(-400, 300, 90), "crossing-stand-on"),       # abaft own starboard beam (beta > 112.5)
])
def test_classify_encounter_table(own, target, expected):
    assert classify_encounter(own, target) == expected


def test_relative_bearings_hand_values():
    beta, alpha = relative_bearings(state(0, 0, 0), state(500, 500, -90))
    assert math.degrees(beta) == pytest.approx(45.0)
    assert math.degrees(alpha) == pytest.approx(-45.0)      # own-ship on the target's port bow
    beta, alpha = relative_bearings(state(0, 0, 90), state(0, -100, 90))
    assert math.degrees(beta) == pytest.approx(-180.0)      # wrapped into [-180, 180)


def test_head_on_threshold_is_the_constant():
    inside = math.radians(HEAD_ON_SECTOR_DEG - 0.5)
    outside = math.radians(HEAD_ON_SECTOR_DEG + 0.5)
    own = state(0, 0, 0)
    tgt = lambda b: np.array([1000 * math.cos(b), 1000 * math.sin(b), math.pi + b, 5.0])   # alpha = 0
    assert classify_encounter(own, tgt(inside)) == "head-on"
    assert classify_encounter(own, tgt(outside)) == "crossing-give-way"
    assert classify_encounter(own, tgt(-outside)) == "crossing-stand-on"


def test_overtaking_threshold_is_the_constant():
    own = state(0, 0, 0)
    # target dead ahead (beta = 0); own-ship's bearing from the target = 180 - target course
    just_abaft = state(300, 0, 180 - OVERTAKING_ABAFT_SECTOR_DEG - 0.5, 3.0)
    just_forward = state(300, 0, 180 - OVERTAKING_ABAFT_SECTOR_DEG + 0.5, 3.0)
    assert classify_encounter(own, just_abaft) == "overtaking"
    assert classify_encounter(own, just_forward) != "overtaking"


def _away_from_thresholds(own, tgt):
    b, a = (abs(math.degrees(float(v))) for v in relative_bearings(own, tgt))
    thr = (0.0, HEAD_ON_SECTOR_DEG, 67.5, OVERTAKING_ABAFT_SECTOR_DEG, 180.0)
    return all(abs(b - x) > 1e-3 and abs(a - x) > 1e-3 for x in thr)


@settings(max_examples=200, deadline=None)
@given(st.floats(-2000, 2000), st.floats(-2000, 2000), st.floats(-math.pi, math.pi),
       st.floats(-math.pi, math.pi), st.floats(-math.pi, math.pi), st.floats(-5e3, 5e3), st.floats(-5e3, 5e3))
def test_classification_invariant_to_rotation_and_translation_mirror_swaps_sides(n, e, c0, c1, rot, dn, de):
    own, tgt = np.array([0.0, 0.0, c0, 5.0]), np.array([n, e, c1, 5.0])
    assume(math.hypot(n, e) > 1.0 and _away_from_thresholds(own, tgt))
    kind = classify_encounter(own, tgt)
    cr, sr = math.cos(rot), math.sin(rot)
    move = lambda s: np.array([cr * s[0] - sr * s[1] + dn, sr * s[0] + cr * s[1] + de, s[2] + rot, s[3]])
    assert classify_encounter(move(own), move(tgt)) == kind
    mirror = lambda s: np.array([s[0], -s[1], -s[2], s[3]])        # reflect east: port <-> starboard
    beta_deg = abs(math.degrees(float(relative_bearings(own, tgt)[0])))
    swap = {"crossing-give-way": "crossing-stand-on", "crossing-stand-on": "crossing-give-way"}
    # abaft the give-way sector (|beta| > 112.5 deg) a crossing target makes the own-ship stand-on on both sides
    expected = swap.get(kind, kind) if beta_deg <= CROSSING_GIVE_WAY_MAX_DEG else kind
    assert classify_encounter(mirror(own), mirror(tgt)) == expected


# ------------------------------------------------------------------------------------------- encounters
def test_head_on_reciprocal_courses_min_distance_tcpa_and_passing_side():
    own = straight(0, 0, 0.0, 5.0)
    for offset, side, ok in ((-20.0, "port", True), (20.0, "starboard", False)):
        tgt = straight(1000, offset, math.pi, 5.0)
        m = run_metrics(T, own, tgt[None], NORTH_ROUTE, [], d_collision=10.0, ground_clearance=2.0)
        p = m["targets"][0]
        assert p["min_distance_m"] == pytest.approx(20.0, abs=1e-9)
        assert p["t_cpa_s"] == pytest.approx(1000.0 / 10.0)          # closing speed 10 m/s
        assert p["encounter"] == "head-on" and p["t_classified_s"] == 0.0
        assert p["compliance"]["passing_side"] == side
        assert p["compliance"]["t_cpa"] == pytest.approx(100.0)
        assert p["compliant"] is ok
        assert p["collision"] is False


def test_encounter_type_uses_first_sample_below_range():
    own = straight(0, 0, 0.0, 5.0)
    tgt = straight(1000, -20, math.pi, 5.0)
    kind, t_cls = encounter_type(T, own, tgt, 500.0)
    # range = sqrt((1000 - 10 t)² + 20²) < 500 first at the sample after 10 t = 500 - sqrt(500² - 20²) ...
    t_exact = (1000.0 - math.sqrt(500.0 ** 2 - 20.0 ** 2)) / 10.0
    assert kind == "head-on"
    assert t_exact < t_cls <= t_exact + 0.5
    assert encounter_type(T, own, tgt, 5000.0) == ("head-on", 0.0)
    kind, t_cls = encounter_type(T, own, tgt, 15.0)                 # never closer than 20 m
    assert kind == "none" and math.isnan(t_cls)


def test_crossing_from_starboard_and_port():
    own = straight(0, 0, 0.0, 5.0)
    stbd = straight(500, 500, -math.pi / 2, 5.0)
    port = straight(500, -500, math.pi / 2, 5.0)
    assert encounter_type(T, own, stbd, 1000.0)[0] == "crossing-give-way"
    assert encounter_type(T, own, port, 1000.0)[0] == "crossing-stand-on"


def test_overtaking_and_overtaken():
    own = straight(0, 0, 0.0, 8.0)
    slow_ahead = straight(200, 10, 0.0, 3.0)
    assert encounter_type(T, own, slow_ahead, 500.0)[0] == "overtaking"
    ok = maneuver_compliance(T, own, slow_ahead, "overtaking", NORTH_ROUTE, d_collision=5.0)
    bad = maneuver_compliance(T, own, slow_ahead, "overtaking", NORTH_ROUTE, d_collision=50.0)
    assert ok["compliant"] is True and bad["compliant"] is False
    assert ok["min_distance_m"] == pytest.approx(10.0) and ok["t_cpa"] == pytest.approx(40.0)   # 200 / 5
    with pytest.raises(ValueError, match="d_collision"):
        maneuver_compliance(T, own, slow_ahead, "overtaking", NORTH_ROUTE)

    own_slow = straight(0, 0, 0.0, 3.0)
    fast_behind = straight(-200, 10, 0.0, 8.0)
    assert encounter_type(T, own_slow, fast_behind, 500.0)[0] == "overtaken"
    res = maneuver_compliance(T, own_slow, fast_behind, "overtaken", NORTH_ROUTE)
    assert res["compliant"] is None and "stand-on" in res["reason"]


# ------------------------------------------------------------------------------------------- compliance
def test_head_on_starboard_turn_is_compliant_port_turn_is_not():
    tgt = straight(1000, 0, math.pi, 5.0)                          # dead ahead, collision course
    stbd = integrate(turn(30.0), 5.0)
    port = integrate(turn(-30.0), 5.0)
    assert encounter_type(T, stbd, tgt, 2000.0)[0] == "head-on"
    r = maneuver_compliance(T, stbd, tgt, "head-on", NORTH_ROUTE)
    assert r["compliant"] is True and r["passing_side"] == "port"
    assert r["max_starboard_deviation_deg"] == pytest.approx(30.0)
    assert r["max_port_deviation_deg"] == 0.0
    r = maneuver_compliance(T, port, tgt, "head-on", NORTH_ROUTE)
    assert r["compliant"] is False and r["passing_side"] == "starboard"
    assert r["max_port_deviation_deg"] == pytest.approx(30.0)
    assert r["max_port_deviation_deg"] > PORT_TURN_LIMIT_DEG
    assert "port" in r["reason"]


def test_head_on_small_port_wiggle_within_limit_passes_port_to_port():
    tgt = straight(1000, -60, math.pi, 5.0)
    own = integrate(turn(-(PORT_TURN_LIMIT_DEG - 2.0), start=5.0, duration=5.0) * (T < 15)
                    + turn(0.0), 5.0)
    r = maneuver_compliance(T, own, tgt, "head-on", NORTH_ROUTE)
    assert r["max_port_deviation_deg"] == pytest.approx(PORT_TURN_LIMIT_DEG - 2.0)
    assert r["compliant"] is True


def test_crossing_give_way_rules():
    tgt = straight(600, 620, -math.pi / 2, 6.0)                    # from starboard, would pass 14 m astern of us
    straight_own = straight(0, 0, 0.0, 6.0)
    assert encounter_type(T, straight_own, tgt, 2000.0)[0] == "crossing-give-way"
    r = maneuver_compliance(T, straight_own, tgt, "crossing-give-way", NORTH_ROUTE)
    assert r["compliant"] is False and "did not give way" in r["reason"]
    assert r["passed_astern"] is False and r["min_distance_m"] == pytest.approx(20.0 / math.sqrt(2.0), abs=0.1)

    r = maneuver_compliance(T, integrate(turn(35.0), 6.0), tgt, "crossing-give-way", NORTH_ROUTE)
    assert r["compliant"] is True and r["max_starboard_deviation_deg"] >= STARBOARD_TURN_MIN_DEG

    slow = integrate(0.0, np.where(T < 10.0, 6.0, 2.0))
    r = maneuver_compliance(T, slow, tgt, "crossing-give-way", NORTH_ROUTE)
    assert r["min_speed_ratio"] == pytest.approx(1.0 / 3.0)
    assert r["min_speed_ratio"] <= SPEED_REDUCTION_RATIO
    assert r["compliant"] is True and r["passed_astern"] is True

    r = maneuver_compliance(T, integrate(turn(-35.0), 6.0), tgt, "crossing-give-way", NORTH_ROUTE)
    assert r["compliant"] is False and r["max_port_deviation_deg"] == pytest.approx(35.0)


def test_crossing_give_way_passing_astern_without_action():
    own = straight(0, 0, 0.0, 2.0)
    fast = straight(300, 600, -math.pi / 2, 10.0)                  # crosses own bow 180 m ahead
    r = maneuver_compliance(T, own, fast, ("crossing-give-way", 0.0), NORTH_ROUTE)
    assert r["passed_astern"] is True and r["max_starboard_deviation_deg"] == 0.0
    assert r["compliant"] is True


def test_crossing_stand_on_rules():
    tgt = straight(600, -600, math.pi / 2, 6.0)                    # from port
    r = maneuver_compliance(T, straight(0, 0, 0.0, 6.0), tgt, "crossing-stand-on", NORTH_ROUTE)
    assert r["compliant"] is True
    r = maneuver_compliance(T, integrate(turn(40.0), 6.0), tgt, "crossing-stand-on", NORTH_ROUTE)
    assert r["compliant"] is True                                   # Rule 17: may act, to starboard
    r = maneuver_compliance(T, integrate(turn(-40.0), 6.0), tgt, "crossing-stand-on", NORTH_ROUTE)
    assert r["compliant"] is False


def test_deviation_is_relative_to_the_route_leg():
    route = np.array([[0.0, 0.0], [0.0, 3000.0]])                 # leg course 90 deg (east)
    own = straight(0, 0, math.radians(75.0), 5.0)                  # 15 deg to port of the leg
    tgt = straight(0, 1000, -math.pi / 2, 5.0)
    r = maneuver_compliance(T, own, tgt, "head-on", route)
    assert r["max_port_deviation_deg"] == pytest.approx(15.0)
    assert r["max_starboard_deviation_deg"] == 0.0


def test_no_encounter_is_not_applicable():
    own = straight(0, 0, 0.0, 5.0)
    r = maneuver_compliance(T, own, straight(5000, 5000, 0.0, 5.0), ("none", float("nan")), NORTH_ROUTE)
    assert r["compliant"] is None and r["t_cpa"] is None


# ---------------------------------------------------------------------------------------------- land etc.
SQUARE = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 100.0], [0.0, 100.0]])
HOLE = np.array([[40.0, 40.0], [60.0, 40.0], [60.0, 60.0], [40.0, 60.0]])


def test_distance_to_land_square_with_hole():
    pts = np.array([[50.0, 50.0], [20.0, 50.0], [-30.0, 50.0], [130.0, 140.0], [45.0, 50.0], [100.0, 50.0]])
    d = distance_to_land(pts, [(SQUARE, HOLE)])
    np.testing.assert_allclose(d, [10.0, 0.0, 30.0, 50.0, 5.0, 0.0], atol=1e-12)
    d_no_hole = distance_to_land(pts, [SQUARE])                    # bare [n, 2] ring
    np.testing.assert_allclose(d_no_hole[:2], [0.0, 0.0])
    far = SQUARE + [0.0, 200.0]                                    # second island, east at 200..300
    d2 = distance_to_land(np.array([[50.0, 170.0]]), [(SQUARE, HOLE), far])
    assert d2[0] == pytest.approx(30.0)
    assert np.all(np.isinf(distance_to_land(pts, [])))
    ragged = [(SQUARE, np.array([[40.0, 40.0], [60.0, 40.0], [50.0, 60.0]]))]
    assert distance_to_land(np.array([[50.0, 45.0]]), ragged)[0] == pytest.approx(5.0)


def test_cross_track_deviation_parallel_line_and_beyond_the_end():
    pts = np.column_stack([np.linspace(0, 1000, 11), np.full(11, 30.0)])
    np.testing.assert_allclose(cross_track_deviation(pts, [[0, 0], [1000, 0]]), 30.0)
    np.testing.assert_allclose(cross_track_deviation([[1040.0, 30.0]], [[0, 0], [1000, 0]]), [50.0])
    route = np.array([[0.0, 0.0], [1000.0, 0.0], [1000.0, 1000.0]])
    np.testing.assert_allclose(cross_track_deviation([[990.0, 500.0], [500.0, -7.0]], route), [10.0, 7.0])


def test_course_rate_of_a_constant_turn_across_the_wrap():
    t = np.cumsum(np.r_[0.0, np.random.default_rng(0).uniform(0.2, 1.0, 300)])
    chi = (0.03 * t + math.pi) % (2 * math.pi) - math.pi           # wraps several times
    np.testing.assert_allclose(course_rate(t, chi), 0.03, rtol=1e-9)
    np.testing.assert_allclose(course_rate(t, -chi), -0.03, rtol=1e-9)


# ----------------------------------------------------------------------------------------- run / aggregate
def head_on_run(offset, d_collision, polygons=(), solve_times=None, cross_east=500.0):
    """Own-ship north at 5 m/s; a head-on target offset ``offset`` m east (CPA |offset| m at t = 100 s) and a target
    crossing from starboard that meets the own-ship at t = 100 s if ``cross_east`` = 500 (else misses by
    |cross_east - 500| / sqrt(2) m)."""
    own = straight(0, 0, 0.0, 5.0)
    tgts = np.stack([straight(1000, offset, math.pi, 5.0), straight(500, cross_east, -math.pi / 2, 5.0)])
    return run_metrics(T, own, tgts, NORTH_ROUTE, list(polygons), d_collision=d_collision, ground_clearance=5.0,
                       solve_times=solve_times, target_names=["ho", "cross"], classify_range=800.0)


def test_run_metrics_fields_collision_and_json():
    island = [np.array([[0.0, 12.0], [1000.0, 12.0], [1000.0, 100.0], [0.0, 100.0]])]
    m = head_on_run(-20.0, 30.0, island, solve_times=[0.1, 0.2, 0.3, 0.4])
    json.dumps(m, allow_nan=False)
    ho, cross = m["targets"]
    assert ho["name"] == "ho" and ho["collision"] is True and m["collision"] is True
    assert cross["encounter"] == "crossing-give-way" and cross["collision"] is True   # same point at t = 100
    assert cross["min_distance_m"] == pytest.approx(0.0, abs=1e-9)
    assert m["min_distance_land_m"] == pytest.approx(12.0) and m["grounding"] is False
    assert m["path_deviation_mean_m"] == pytest.approx(0.0, abs=1e-9)
    assert m["path_deviation_max_m"] == pytest.approx(0.0, abs=1e-9)
    assert m["mean_abs_course_rate_deg_s"] == 0.0
    assert m["solve_time_mean_s"] == pytest.approx(0.25) and m["solve_time_max_s"] == 0.4
    assert m["solve_time_p95_s"] == pytest.approx(np.percentile([0.1, 0.2, 0.3, 0.4], 95))
    assert m["n_solves"] == 4

    m2 = head_on_run(-20.0, 10.0)
    json.dumps(m2, allow_nan=False)
    assert m2["targets"][0]["collision"] is False
    assert m2["min_distance_land_m"] is None and m2["grounding"] is False
    assert m2["solve_time_mean_s"] is None and m2["n_solves"] == 0

    near = [np.array([[0.0, 3.0], [1000.0, 3.0], [1000.0, 100.0], [0.0, 100.0]])]
    assert head_on_run(-20.0, 10.0, near)["grounding"] is True

    far = straight(1e5, 1e5, 0.0, 1.0)
    m3 = run_metrics(T, straight(0, 0, 0.0, 5.0), far[None], NORTH_ROUTE, None, d_collision=10.0,
                     ground_clearance=1.0, classify_range=500.0)
    json.dumps(m3, allow_nan=False)
    assert m3["targets"][0]["encounter"] == "none" and m3["targets"][0]["t_classified_s"] is None


def test_aggregate_counts_and_stats():
    island = [np.array([[0.0, 3.0], [1000.0, 3.0], [1000.0, 100.0], [0.0, 100.0]])]
    runs = [head_on_run(-20.0, 10.0, solve_times=[1.0, 3.0]),       # head-on ok; cross collides (0 m)
            head_on_run(20.0, 30.0, island, solve_times=[2.0]),     # starboard passing; collisions; grounding
            head_on_run(-40.0, 30.0, cross_east=560.0)]             # nothing (40 m and 42.4 m)
    agg = aggregate(runs)
    json.dumps(agg, allow_nan=False)
    assert agg["runs"] == 3
    assert agg["collisions"] == 2 and agg["collided_runs"] == [0, 1]
    assert agg["groundings"] == 1 and agg["grounded_runs"] == [1]
    ho = agg["targets"][0]
    assert ho["name"] == "ho"
    assert ho["min_distance_m"] == {"min": pytest.approx(20.0), "mean": pytest.approx(80.0 / 3.0),
                                    "median": pytest.approx(20.0), "max": pytest.approx(40.0), "n": 3}
    assert ho["compliance_rate"] == pytest.approx(2.0 / 3.0) and ho["n_compliance_evaluated"] == 3
    assert ho["encounters"] == {"head-on": 3}
    assert agg["targets"][1]["collisions"] == 2
    assert agg["targets"][1]["min_distance_m"]["max"] == pytest.approx(60.0 / math.sqrt(2.0), abs=0.01)
    assert agg["min_distance_m"]["n"] == 6 and agg["min_distance_m"]["min"] == pytest.approx(0.0, abs=1e-9)
    assert agg["n_compliance_evaluated"] == 6
    assert agg["min_distance_land_m"]["n"] == 1 and agg["min_distance_land_m"]["min"] == pytest.approx(3.0)
    assert agg["solve_time_mean_s"] == pytest.approx(2.0) and agg["solve_time_max_s"] == 3.0
    assert agg["n_solves"] == 3
    assert agg["path_deviation_max_m"] == pytest.approx(0.0, abs=1e-9)


# ------------------------------------------------------------------------------------------------ bad input
@pytest.mark.parametrize("call, match", [
    (lambda: classify_encounter([0, 0, 0], state(1, 1, 0)), "own_state"),
    (lambda: encounter_type(T[::-1], straight(0, 0, 0, 1), straight(9, 9, 0, 1), 10.0), "increasing"),
    (lambda: encounter_type(T, straight(0, 0, 0, 1)[:-1], straight(9, 9, 0, 1), 10.0), "rows"),
    (lambda: encounter_type(T, straight(0, 0, 0, 1), straight(9, 9, 0, 1), -1.0), "range_m"),
    (lambda: maneuver_compliance(T, straight(0, 0, 0, 1), straight(9, 9, 0, 1), "sideways", NORTH_ROUTE),
     "encounter type must be one of"),
    (lambda: maneuver_compliance(T, straight(0, 0, 0, 1), straight(9, 9, 0, 1), "head-on", [[0.0, 0.0]]),
     "at least 2 waypoints"),
    (lambda: maneuver_compliance(T, straight(0, 0, 0, 1), straight(9, 9, 0, 1), ("head-on", 1e6), NORTH_ROUTE),
     "t_classified"),
    (lambda: distance_to_land([[0.0, 0.0]], [np.array([[0.0, 0.0], [1.0, 1.0]])]), "3 distinct"),
    (lambda: distance_to_land([[0.0, 0.0]], SQUARE), "sequence of ring sets"),
    (lambda: distance_to_land([[0.0, np.nan]], [SQUARE]), "finite"),
    (lambda: cross_track_deviation([[0.0, 0.0]], [[0.0, 0.0], [0.0, 0.0]]), "zero-length"),
    (lambda: course_rate([0.0, 1.0], [0.0]), "shape"),
    (lambda: run_metrics(T, straight(0, 0, 0, 1), np.zeros((1, 3, 4)), NORTH_ROUTE, [], d_collision=1.0,
                         ground_clearance=1.0), "targets"),
    (lambda: run_metrics(T, straight(0, 0, 0, 1), np.zeros((0, T.size, 4)), NORTH_ROUTE, [], d_collision=0.0,
                         ground_clearance=1.0), "d_collision"),
    (lambda: run_metrics(T, straight(0, 0, 0, 1), np.zeros((1, T.size, 4)), NORTH_ROUTE, [], d_collision=1.0,
                         ground_clearance=1.0, target_names=["a", "b"]), "target_names"),
    (lambda: run_metrics(T, straight(0, 0, 0, 1), [], NORTH_ROUTE, [], d_collision=1.0, ground_clearance=1.0,
                         solve_times=[-1.0]), "solve_times"),
    (lambda: aggregate([]), "at least one run"),
    (lambda: aggregate([{"targets": []}]), "missing"),
])
def test_bad_inputs_raise_value_error(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_longest_stop_by_hand():
    from psbmpc_jax.sim.metrics import STOP_SPEED_MPS, longest_stop

    t = np.arange(10) * 2.0                                   # 0, 2, ..., 18 s
    u = np.array([2, 0.1, 0.0, 0.2, 1, 0.05, 2, 0.1, 0.1, 0.1])
    # slow (<= 0.2) runs: samples 1-3 (4 s), 5 alone (0 s), 7-9 to the end (4 s)
    assert longest_stop(t, u) == 4.0
    assert longest_stop(t, u, threshold=0.0) == 0.0          # one isolated sample at exactly 0
    assert longest_stop(t, np.full(10, 3.0)) == 0.0
    assert longest_stop(t, np.zeros(10)) == 18.0
    assert STOP_SPEED_MPS == 0.2
    with pytest.raises(ValueError, match="speed must have the shape"):
        longest_stop(t, u[:-1])
    with pytest.raises(ValueError, match="threshold"):
        longest_stop(t, u, threshold=-1.0)
