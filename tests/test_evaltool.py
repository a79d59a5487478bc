"""EvalTool (psbmpc_jax.evaltool): every formula against hand values, the SPEC's published compositions
(SPEC_EVALTOOL §5, the "[PUB]" numbers of the Smooth-SBMPC paper's Tables VI–IX and CCTA 2023), and the scripted
test cases of SPEC §6 (T1–T7), built synthetically here."""

from __future__ import annotations

import math

import numpy as np
import pytest

from psbmpc_jax.evaltool import EvalParams, evaluate_tracks, get_params
from psbmpc_jax.evaltool import scores as sc
from psbmpc_jax.evaltool.geometry import classify, pair_geometry, stages, wrap
from psbmpc_jax.evaltool.maneuvers import detect_maneuvers, gaussian_smooth
from psbmpc_jax.evaltool.synthetic import scripted_tracks

INLAND = get_params("inland_small")
DEG = math.radians
T_80 = 100 - 80 / math.sqrt(2)          # T5/T6: the time the range first reaches 80 m (43.43 s)


# ------------------------------------------------------------------------------------------ §6.0 unit checks
@pytest.mark.parametrize("r, expected", [(7, 1), (6.5, 0.9), (6, 0.8), (5, 0.5), (4.5, 0.25), (4, 0), (3, 0),
                                         (100, 1), (5.5, 0.65)])
def test_range_score_pieces(r, expected):
    assert sc.range_score(r, INLAND) == pytest.approx(expected, abs=1e-12)


def test_range_score_vectorised_and_monotone():
    r = np.linspace(0, 10, 201)
    s = sc.range_score(r, INLAND)
    assert s.shape == r.shape
    assert np.all(np.diff(s) >= 0) and s[0] == 0 and s[-1] == 1


@pytest.mark.parametrize("alpha, beta, expected", [(90, 90, 1.0), (-90, -90, 1.0), (90, -90, 1.0), (0, 0, 0.0),
                                                   (-75, -105, 0.25 * (1 - math.cos(DEG(75))) + 0.75)])
def test_pose_score(alpha, beta, expected):
    s_theta, s_a, s_b = sc.pose_score(DEG(alpha), DEG(beta), INLAND)
    assert s_theta == pytest.approx(expected, abs=1e-12)
    assert s_theta == pytest.approx(0.25 * s_a + 0.75 * s_b)


def test_pose_score_spec_value_and_cut():
    assert sc.pose_score(DEG(-75), DEG(-105), INLAND)[0] == pytest.approx(0.9353, abs=5e-5)
    p = INLAND.replace(alpha_cut_deg=60.0)
    # inside the cut: (1 − cos α)/(1 − cos 60°) = 2(1 − cos α); outside it: 1
    assert sc.angle_score(DEG(30), DEG(60)) == pytest.approx(2 * (1 - math.cos(DEG(30))))
    assert sc.pose_score(DEG(70), DEG(0), p)[1] == 1.0


@pytest.mark.parametrize("alpha, beta, expected", [(-90, -90, 0.0), (90, 90, 1.0), (-75, -105, 0.0664),
                                                   (0, 0, 0.9375)])
def test_p_sts(alpha, beta, expected):
    assert sc.p_sts(DEG(alpha), DEG(beta)) == pytest.approx(expected, abs=5e-5)


def test_p_sts_is_the_squared_complement():
    a, b = DEG(-80), DEG(-95)
    assert sc.p_sts(a, b) == pytest.approx(1 - (0.25 * (1 - math.sin(a)) * (1 - math.sin(b))) ** 2)


def test_f_course_and_non_apparent_components():
    # SPEC §6.0: f_χ at Δχ = 8° with (1°, 13°) → 1 − (7/12)² = 0.6597, P_Δχ^¬ap = 0.3299
    assert sc.f_course(DEG(8), INLAND) == pytest.approx(1 - (7 / 12) ** 2)
    total, p_chi, p_u = sc.non_apparent(DEG(8), 0.0, INLAND)
    assert p_chi == pytest.approx(0.3299, abs=5e-5) and p_u == 0 and total == pytest.approx(p_chi)
    assert sc.f_course(DEG(0.5), INLAND) == 0 and sc.f_course(DEG(13), INLAND) == 0


def test_f_speed_is_linear_between_thresholds():
    assert sc.f_speed(0.05, INLAND) == 0.0                      # below detectable
    assert sc.f_speed(0.15, INLAND) == pytest.approx(0.5)        # halfway between 0.1 and 0.2
    assert sc.f_speed(0.2, INLAND) == 0.0                        # apparent


def test_non_apparent_total_is_zero_when_either_change_is_apparent():
    total, p_chi, p_u = sc.non_apparent(DEG(8), 0.25, INLAND)  # speed reduction 25 % >= 20 %: apparent
    assert total == 0.0 and p_chi > 0
    total, p_chi, p_u = sc.non_apparent(DEG(8), 0.15, INLAND)
    assert total == pytest.approx(0.5 * (1 - (7 / 12) ** 2) + 0.5 * 0.5)


def test_p_delay():
    assert sc.p_delay(80, None, 10) == 1.0
    assert sc.p_delay(80, 40, 7.76) == pytest.approx(40 / 72.24)     # T3 with an ideal detector: 0.554
    assert sc.p_delay(80, 82, 10) == 0.0                             # manoeuvre before the start: clipped
    assert sc.p_delay(10, 5, 10) == 0.0                              # r_det <= r_cpa


@pytest.mark.parametrize("man, stbd, port, expected", [(False, 0, 40, 0.0), (True, 0, 30, 1.0), (True, 30, 0, 0.0),
                                                       (True, 5, 0, 0.5), (True, 12, 11, 0.0), (True, 2, 8, 0.8)])
def test_p_nsb(man, stbd, port, expected):
    assert sc.p_nsb(man, DEG(stbd), DEG(port), INLAND) == pytest.approx(expected)


def test_ahead_penalties():
    assert sc.p_ah13(DEG(18.5), INLAND) == 1 and sc.p_ah13(DEG(-90), INLAND) == 0
    assert sc.p_ah15(DEG(30), INLAND) == 1 and sc.p_ah15(DEG(-24), INLAND) == 1
    assert sc.p_ah15(DEG(-120), INLAND) == 0 and sc.p_ah15(DEG(170), INLAND) == 0


def test_stage_penalty_modes():
    p = INLAND
    assert sc.stage_penalty(False, 1, 1, 1, 0.2, p) == 0.0                     # man_x gate
    assert sc.stage_penalty(True, 1, 0, 0, 0.2, p) == pytest.approx(0.7)       # reproduce: 0.5 + 0.2
    assert sc.stage_penalty(True, 1, 1, 1, 0.2, p) == 1.0                       # capped at 1
    q = p.replace(stand_on_mode="intended")
    assert sc.stage_penalty(True, 1, 0, 0, 0.2, q) == pytest.approx(0.3)       # intended: 0.5 − 0.2
    assert sc.stage_penalty(True, 0, 0, 0, 0.2, q) == 0.0


# ------------------------------------------------------------------------------------- §5 published numbers
def test_pub_safety_and_s16():
    """Table VI, Sim 1 (red target): S_r 0.85174, S_Θ 0.75188 → S_safety 0.96321; P_delay 0.64116 → S16 =
    S15 = 0.34564."""
    s_safe = sc.safety_score(0.85174, 0.75188)
    assert round(s_safe, 5) == 0.96321
    s16 = sc.s16(0.96321, 0.64116, 0.0)
    assert round(s16, 5) == 0.34564
    assert round(sc.s15_give_way(s16, 0.0, INLAND), 5) == 0.34564


def test_pub_ccta_compositions():
    assert round(sc.safety_score(0.94, 0.97), 3) == 0.998             # CCTA II(b), printed 1.0
    assert sc.s16(1.0, 0.75, 0.0) == pytest.approx(0.25)               # CCTA II(a)
    s14 = sc.s14(0.0, 0.02, 0.16, 0.0, INLAND)                         # CCTA I(a): 0.83
    assert round(s14, 2) == 0.83


def test_safety_score_special_cases():
    assert sc.safety_score(1.0, 0.0) == 1.0
    assert sc.safety_score(0.0, 0.7, collided=True) == 0.0
    assert sc.safety_score(0.0, 0.7) == pytest.approx(0.7)


def test_pub_s14():
    """Table VI Sim 2: P_sts 0.075006 → 0.955; Table VIII Sim 1: P_sts 0.086949, P_delay 0.25389 → 0.70719."""
    assert round(sc.s14(0.0, 0.075006, 0.0, 0.0, INLAND), 3) == 0.955
    assert round(sc.s14(0.0, 0.086949, 0.25389, 0.0, INLAND), 5) == 0.70719


def test_pub_stand_on_table_vii():
    """P_2 = 0.2 + 0.5·P_2,Δχ in reproduce mode with C = 0.2 (0.7 / 0.2 / 0.53154); S17 = 0.09 and 0.24."""
    for p_chi, expected in [(1.0, 0.7), (0.0, 0.2), (0.66308, 0.53154)]:
        assert round(sc.stage_penalty(True, p_chi, 0, 0, 0.2, INLAND), 5) == expected
    p_3 = sc.stage_penalty(True, 1.0, 0, 0, 0.2, INLAND)
    assert round(sc.s17(1.0, 0.7, p_3, 0.7), 5) == 0.09
    assert round(sc.s17(1.0, 0.2, p_3, 0.0), 5) == 0.24


def test_pub_s13_table_ix():
    assert sc.s13_give_way(1.0, 0.0, INLAND) == 1.0
    assert sc.s13_give_way(1.0, 1.0, INLAND) == pytest.approx(0.7)


# --------------------------------------------------------------------------------------- geometry, classes
def test_wrap_range():
    a = wrap(np.array([math.pi, -math.pi, 3 * math.pi, 0.1, -3.2]))
    assert np.all(a > -math.pi) and np.all(a <= math.pi)
    assert a[0] == pytest.approx(math.pi) and a[1] == pytest.approx(math.pi)


def test_bearing_and_contact_angle_signs():
    # own at origin heading north; target 100 m east heading north: β = +90° (starboard beam), α = −90°
    north, east = np.array([[0.0], [0.0]]), np.array([[0.0], [100.0]])
    course, speed = np.zeros((2, 1)), np.ones((2, 1))
    g = pair_geometry(north, east, course, speed, 0, 1, INLAND)
    assert np.degrees(g.beta[0]) == pytest.approx(90) and np.degrees(g.alpha[0]) == pytest.approx(-90)
    speed[1] = 0.0                                     # the target does not move: α := 180°
    g = pair_geometry(north, east, course, speed, 0, 1, INLAND)
    assert np.degrees(g.alpha[0]) == pytest.approx(180)


def test_stages():
    assert stages([100, 80, 60, 45, 30, 16, 5], INLAND).tolist() == [1, 2, 2, 3, 3, 4, 4]


@pytest.mark.parametrize("alpha, beta, u_i, u_j, expected", [
    (0, 0, 1, 1, "HO"), (-45, 45, 1, 1, "CRGW"), (45, -45, 1, 1, "CRSO"),
    (180, 0, 1.5, 0.5, "OTGW"), (0, 180, 0.5, 1.5, "OTSO"), (180, 0, 0.5, 1.5, "NAR"),
    (-5, 45, 1, 1, "NAR"), (150, 150, 1, 1, "NAR"), (10, 10, 1, 1, "HO"), (12, 20, 1, 1, "NAR")])
def test_classify(alpha, beta, u_i, u_j, expected):
    assert classify(DEG(alpha), DEG(beta), u_i, u_j, INLAND)[()] == expected


def test_classification_is_symmetric_for_crossing():
    """i is CRGW towards j exactly when j is CRSO towards i (away from the sector boundaries)."""
    rng = np.random.default_rng(3)
    a, b = rng.uniform(-math.pi, math.pi, 4000), rng.uniform(-math.pi, math.pi, 4000)
    ij = classify(a, b, np.ones(4000), np.ones(4000), INLAND)
    ji = classify(b, a, np.ones(4000), np.ones(4000), INLAND)
    assert np.sum(ij == "CRGW") > 100
    assert np.array_equal(ij == "CRGW", ji == "CRSO")
    assert np.array_equal(ij == "HO", ji == "HO")


# ------------------------------------------------------------------------------------------------ manoeuvres
def test_gaussian_smooth_matches_scipy():
    ndimage = pytest.importorskip("scipy.ndimage")
    x = np.random.default_rng(0).normal(size=57).cumsum()
    for sigma in (0.7, 2.0, 5.0):
        assert np.allclose(gaussian_smooth(x, sigma), ndimage.gaussian_filter1d(x, sigma), atol=1e-12)
    short = np.arange(5.0)
    assert np.allclose(gaussian_smooth(short, 2.0), ndimage.gaussian_filter1d(short, 2.0), atol=1e-12)


def test_turn_and_speed_change_are_detected():
    t = np.arange(0, 200.0)
    course = np.radians(np.interp(t, [60, 70], [0, 30]))
    speed = np.interp(t, [120, 124], [2.0, 1.0])                     # 0.25 m/s², well above ε_dU
    ms = detect_maneuvers(course, speed, 1.0, INLAND)
    kinds = [m.kind for m in ms]
    assert kinds == ["course", "speed"]
    turn, slow = ms
    assert 56 <= turn.start <= 60 and 70 <= turn.end <= 74          # the smoother fires ~2 s early
    assert math.degrees(turn.delta_course) == pytest.approx(30, abs=1.5)
    # the net change sums the rate over the above-threshold run only: the smoothed tails are left out
    assert 116 <= slow.start <= 120 and -1.0 <= slow.delta_speed <= -0.8


def test_no_course_manoeuvre_below_the_speed_gate():
    t = np.arange(0, 100.0)
    course = np.radians(np.interp(t, [40, 50], [0, 30]))
    assert detect_maneuvers(course, np.full(t.size, 0.1), 1.0, INLAND) == []


def test_sign_change_ends_a_course_manoeuvre():
    t = np.arange(0, 200.0)
    course = np.radians(np.interp(t, [40, 50, 60, 70], [0, 30, 30, 0]))
    ms = detect_maneuvers(course, np.ones(t.size), 1.0, INLAND.replace(course_end_below_threshold=False))
    assert [m.kind for m in ms] == ["course", "course"]
    assert ms[0].delta_course > 0 > ms[1].delta_course


# ------------------------------------------------------------------------------------- §6 scripted scenarios
def own(knots=(), speed=1.0, **kw):
    return dict(start_ne=(0.0, 0.0), course_deg=0.0, speed_mps=speed, course_knots=list(knots), **kw)


def head_on_target(knots=()):
    return dict(start_ne=(200.0, 0.0), course_deg=180.0, speed_mps=1.0, course_knots=list(knots))


def run(vessels, duration=200.0, pairs="own", params=INLAND, **kw):
    return evaluate_tracks(scripted_tracks(vessels, duration), params, pairs=pairs, **kw)


def angles_cpa(e):
    """(α_c, β_c) of an encounter in degrees."""
    return math.degrees(e.alpha_cpa), math.degrees(e.beta_cpa)


def only(ev, vessel="O", other="T"):
    encs = ev.of(vessel, other)
    assert len(encs) == 1, [e.to_dict() for e in ev.encounters]
    return encs[0]


def test_t1_port_to_port_head_on_with_early_starboard_turn():
    e = only(run({"O": own([(60, 0), (70, 30)]), "T": head_on_target()}))
    s = e.scores
    assert e.situation == "HO" and e.status == "scored"
    assert e.r_cpa == pytest.approx(18.12, abs=0.05)
    assert angles_cpa(e) == pytest.approx((-75, -105), abs=1)
    assert s.S_safety == 1 and s.S_theta == pytest.approx(0.935, abs=0.01)
    assert s.P_delay == 0 and s.P_na_delta_chi == 0 and s.P_nsb == 0
    assert s.P_sts == pytest.approx(0.066, abs=0.005)
    assert s.S14 == pytest.approx(0.960, abs=0.01) and s.S_sit == s.S14
    assert s.S15 is None and s.S13 is None and s.S17 is None and s.P_ah15 is None   # not applicable: None


def test_t1_variant_both_turn():
    e = only(run({"O": own([(60, 0), (70, 30)]), "T": head_on_target([(60, 180), (70, 210)])}))
    assert e.r_cpa == pytest.approx(34.9, abs=0.1)
    assert e.scores.P_sts == pytest.approx(0.0, abs=1e-3)
    assert e.scores.S14 == pytest.approx(1.0, abs=0.01)


def test_t1_target_that_never_acts_gets_p_delay_one():
    e = only(run({"O": own([(60, 0), (70, 30)]), "T": head_on_target()}, pairs="all"), "T", "O")
    assert e.situation == "HO" and e.scores.P_delay == 1 and e.scores.S14 == 0 and e.maneuver is None


def test_t2_starboard_to_starboard():
    e = only(run({"O": own([(60, 0), (70, -30)]), "T": head_on_target()}))
    s = e.scores
    assert e.situation == "HO" and s.S_safety == 1
    assert s.P_sts == pytest.approx(1.0, abs=1e-6) and s.P_nsb == 1 and s.P_delay == 0
    assert s.S14 == pytest.approx(0.0, abs=1e-6)


def test_t3_late_turn_is_delayed():
    e = only(run({"O": own([(80, 0), (90, 30)]), "T": head_on_target()}))
    s = e.scores
    assert e.r_cpa == pytest.approx(7.76, abs=0.05) and s.S_r == 1
    assert s.P_sts == pytest.approx(0.066, abs=0.005)
    assert e.r_maneuver == pytest.approx(44, abs=2.1)          # detector-dependent: fires ~2 s early
    assert s.P_delay == pytest.approx(0.50, abs=0.03) and s.S14 == pytest.approx(0.48, abs=0.03)
    # the composition: S14 = (1 − 0.6 P_sts)(1 − P_delay)
    assert s.S14 == pytest.approx((1 - 0.6 * s.P_sts) * (1 - s.P_delay))


def test_t4_no_action():
    e = only(run({"O": own(), "T": head_on_target()}))
    s = e.scores
    assert e.r_cpa == pytest.approx(0, abs=1e-6) and s.S_r == 0 and s.S_safety == 0
    assert s.P_delay == 1 and s.P_nsb == 0 and s.S14 == 0


def crossing_target_starboard():
    return dict(start_ne=(100.0, 100.0), course_deg=270.0, speed_mps=1.0)


def test_t5_give_way_passing_ahead():
    e = only(run({"O": own([(T_80, 0), (T_80 + 10, -30)]), "T": crossing_target_starboard()}))
    s = e.scores
    assert e.situation == "CRGW"
    assert e.r_cpa == pytest.approx(19.03, abs=0.1) and s.S_safety == 1
    assert s.S_theta == pytest.approx(0.7835, abs=0.01)
    assert math.degrees(e.alpha_cpa) == pytest.approx(30, abs=1.5)
    assert s.P_ah15 == 1 and s.P_delay == 0 and s.P_na_delta == 0 and s.S16 == 1
    assert s.S15 == pytest.approx(0.50, abs=0.01) and s.S_sit == s.S15
    assert s.P_nsb is None and s.P_sts is None and s.S14 is None


def test_t5b_give_way_passing_astern():
    e = only(run({"O": own([(T_80, 0), (T_80 + 10, 30)]), "T": crossing_target_starboard()}))
    s = e.scores
    assert e.r_cpa == pytest.approx(18.71, abs=0.05)
    assert angles_cpa(e) == pytest.approx((-120, -60), abs=1)
    assert s.S_theta == pytest.approx(0.625, abs=0.01) and s.P_ah15 == 0 and s.S15 == pytest.approx(1.0)


def test_t5c_non_apparent_turn():
    """8° starboard at Δχ_ap = 13°.  The SPEC prints r_cpa = 5.38 m (S15 = 0.543), which does not follow from
    its scenario: integrating the scripted turn gives r_cpa = 5.08 m (continuous) / 5.11 m (1 s grid); the
    composition S15 = S16 = S_safety·(1 − P_Δ^¬ap) holds exactly (see docs/evaltool.md)."""
    e = only(run({"O": own([(T_80, 0), (T_80 + 10, 8)]), "T": crossing_target_starboard()}))
    s = e.scores
    assert e.r_cpa == pytest.approx(5.1, abs=0.05)
    assert s.S_r == pytest.approx(float(sc.range_score(e.r_cpa, INLAND)))
    assert s.P_na_delta == pytest.approx(0.33, abs=0.025) and s.P_ah15 == 0
    assert s.S_safety == pytest.approx(s.S_r + (1 - s.S_r) * s.S_theta)
    assert s.S15 == pytest.approx(s.S_safety * (1 - s.P_na_delta)) and s.S15 == pytest.approx(0.52, abs=0.02)


def crossing_target_port():
    return dict(start_ne=(100.0, -100.0), course_deg=90.0, speed_mps=1.0)


def test_t6_stand_on_turning_to_port():
    e = only(run({"O": own([(70, 0), (80, -30)]), "T": crossing_target_port()}))
    s = e.scores
    assert e.situation == "CRSO" and e.r_cpa == pytest.approx(8.99, abs=0.05) and s.S_safety == 1
    assert e.stage_first_t[2] == pytest.approx(44) and e.stage_first_t[3] == pytest.approx(69)
    assert s.P_2 == 0 and s.C_2_gw == 0 and s.C_3_gw == 0
    assert s.P_3 == pytest.approx(0.5) and s.P_3_delta_chi == 1 and s.P_pt == pytest.approx(0.7)
    assert s.S17 == pytest.approx(0.30, abs=0.01) and s.S15 == s.S17 == s.S_sit
    assert s.P_delay is None and s.S16 is None                    # give-way scores do not apply


def test_t6_with_give_way_compensation():
    """O is give-way (CRGW) to a third vessel X at the same time: C = 0.2 in both stages; reproduce mode gives
    P_3 = 0.7 and the smoother artefact P_2 = 0.2, so S17 = 0.24 (SPEC §6 T6); intended mode P_3 = 0.3."""
    vessels = {"O": own([(70, 0), (80, -30)]), "T": crossing_target_port(),
               "X": dict(start_ne=(120.0, 110.0), course_deg=270.0, speed_mps=1.0)}
    ev = run(vessels)
    assert only(ev, "O", "X").situation == "CRGW"
    s = only(ev, "O", "T").scores
    assert s.C_2_gw == 0.2 and s.C_3_gw == 0.2
    assert s.P_3 == pytest.approx(0.7) and s.P_2 == pytest.approx(0.2) and s.S17 == pytest.approx(0.24)
    s = only(run(vessels, stand_on_mode="intended"), "O", "T").scores
    assert s.P_3 == pytest.approx(0.3) and s.P_2 == 0 and s.S17 == pytest.approx(0.30)


def test_t6_port_turn_in_stage_3_only_counts_with_the_default_stages():
    """The T6 port turn (70-80 s) lies in stage 3: P_pt fires with port_turn_stages "3-4" (the default) and not
    with "4" (the score table's "stand-on behavior during Stage 4"); the rest of the scores are the same."""
    vessels = {"O": own([(70, 0), (80, -30)]), "T": crossing_target_port()}
    e3, e4 = only(run(vessels)), only(run(vessels, port_turn_stages="4"))
    assert e3.scores.P_pt == pytest.approx(0.7) and e4.scores.P_pt == 0
    assert e4.scores.P_3 == e3.scores.P_3 == pytest.approx(0.5) and e4.scores.S17 == pytest.approx(0.50, abs=0.01)
    assert e3.stage_first_t[3] == pytest.approx(69) and (4 not in e3.stage_first_t or e3.stage_first_t[4] > 80)
    with pytest.raises(ValueError, match=r"EvalParams.port_turn_stages must be one of \('3-4', '4'\), got '3'"):
        run(vessels, port_turn_stages="3")


def test_t6b_stand_on_turning_to_starboard():
    s = only(run({"O": own([(70, 0), (80, 30)]), "T": crossing_target_port()})).scores
    assert s.P_pt == 0 and s.P_3 == pytest.approx(0.5) and s.S17 == pytest.approx(0.50, abs=0.01)


def test_t6c_stand_on_keeps_course_give_way_acts():
    ev = run({"O": own(), "T": dict(crossing_target_port(), course_knots=[(T_80, 90), (T_80 + 10, 120)])},
             pairs="all")
    o, t = only(ev, "O", "T"), only(ev, "T", "O")
    assert o.situation == "CRSO" and t.situation == "CRGW"
    assert o.r_cpa == pytest.approx(18.71, abs=0.05)
    assert angles_cpa(o) == pytest.approx((-60, -120), abs=1)
    assert o.scores.S17 == pytest.approx(1.0) and o.scores.S15 == pytest.approx(1.0)
    assert t.scores.S15 == pytest.approx(1.0)


OT_OWN = [(20, 0), (25, -30), (45, -30), (50, 0)]


def overtaken_target():
    return dict(start_ne=(100.0, 0.0), course_deg=0.0, speed_mps=0.5)


def test_t7_overtaking_across_the_bow():
    ev = run({"O": own(OT_OWN + [(115, 0), (125, 90)], speed=1.5), "T": overtaken_target()})
    e = only(ev)
    s = e.scores
    assert e.situation == "OTGW" and e.t_start == pytest.approx(20)
    assert e.r_cpa == pytest.approx(11.16, abs=0.05) and s.S_safety == 1
    assert 15 < math.degrees(e.alpha_cpa) < 25                      # 18.5° continuous; the 1 s grid moves it
    assert s.P_ah13 == 1 and s.P_delay == 0 and s.P_na_delta == 0 and s.S16 == 1
    assert s.S13 == pytest.approx(0.70, abs=0.01) and s.S_sit == s.S13


def test_t7_reference_passing_abeam():
    ev = run({"O": own(OT_OWN, speed=1.5), "T": overtaken_target()}, pairs="all")
    o, t = only(ev, "O", "T"), only(ev, "T", "O")
    assert o.r_cpa == pytest.approx(18.84, abs=0.05)
    assert angles_cpa(o) == pytest.approx((-90, 90), abs=1.5)
    assert o.scores.S13 == pytest.approx(1.0)
    assert t.situation == "OTSO" and t.scores.S13 == pytest.approx(1.0) and t.scores.S17 == pytest.approx(1.0)


# ---------------------------------------------------------------------------------- encounter bookkeeping
def test_delay_reference_stage3_option():
    vessels = {"O": own([(80, 0), (90, 30)]), "T": head_on_target()}
    e = only(run(vessels, delay_reference="stage3"))
    expected = (45 - e.r_maneuver) / (45 - e.r_cpa)                 # r_man ≈ 44 m: just inside stage 3
    assert e.scores.P_delay == pytest.approx(max(0.0, expected))
    assert e.scores.P_delay < only(run(vessels)).scores.P_delay


def test_scan_for_situation_option():
    """Starting inside r_Stage2 with a geometry that is NAR at first (a faster target on a parallel course,
    abaft O's starboard beam: β = 120°, α = −60°): the scan finds the later crossing geometry (β <= 112.5°);
    without it the encounter stays NAR."""
    vessels = {"O": own(), "T": dict(start_ne=(-25.0, 43.3), course_deg=0.0, speed_mps=2.0)}
    scanned = run(vessels, duration=120)
    locked = run(vessels, duration=120, scan_for_situation=False)
    assert only(locked).situation == "NAR" and only(locked).status == "nar"
    assert only(scanned).situation == "CRGW" and only(scanned).k_start > only(scanned).k_detect == 0


def test_incomplete_encounter_is_not_scored():
    e = only(run({"O": own(), "T": head_on_target()}, duration=90))   # ends before the CPA (t = 100 s)
    assert e.status == "incomplete" and e.scores.S_sit is None and e.scores.S_safety is None


def test_nar_gets_only_safety_scores():
    # diverging from the start, well inside r_Stage2
    e = only(run({"O": own(), "T": dict(start_ne=(-20.0, 0.0), course_deg=180.0, speed_mps=1.0)}, duration=30))
    assert e.situation == "NAR" and e.status == "nar"
    assert e.scores.S_safety == 1 and e.scores.S_sit is None and e.scores.P_delay is None


def test_not_moving_vessel_is_not_scored():
    ev = run({"O": own(speed=0.0), "T": head_on_target()}, pairs="all", duration=300)
    o, t = only(ev, "O", "T"), only(ev, "T", "O")
    assert o.status == "not_moving" and o.scores.S_safety is None
    assert t.situation == "OTGW" and t.status == "scored"            # stationary contact: α := 180°


def test_risk_gate_option():
    # a target passing 15 m abeam to port on a parallel opposite course (head-on by the sectors): no risk
    # (DCPA 15 m >= r_pref 7 m)
    vessels = {"O": own(), "T": dict(start_ne=(200.0, -15.0), course_deg=180.0, speed_mps=1.0)}
    plain, gated = only(run(vessels)), only(run(vessels, risk_gate=True))
    assert plain.status == "scored" and plain.scores.P_delay == 1   # SPEC §7.13: no gate by default
    assert gated.status == "no_risk" and gated.scores.S_sit is None and gated.scores.S_safety == 1
    assert plain.situation == "HO" and gated.dcpa_start == pytest.approx(15, abs=0.1)


def test_two_separate_encounters_with_one_target():
    # T passes head-on, leaves r_Stage2, turns round, speeds up and overtakes O from behind
    vessels = {"O": own(), "T": dict(start_ne=(200.0, -15.0), course_deg=180.0, speed_mps=1.0,
                                     course_knots=[(150, 180), (160, 360)], speed_knots=[(150, 1.0), (160, 2.0)])}
    encs = run(vessels, duration=400).of("O", "T")
    assert len(encs) == 2 and encs[0].t_cpa < encs[1].t_detect
    assert [e.situation for e in encs] == ["HO", "OTSO"]


def test_non_uniform_input_and_derived_course_speed_give_the_same_scores():
    base = scripted_tracks({"O": own([(60, 0), (70, 30)]), "T": head_on_target()}, 200, step_s=0.05)
    rng = np.random.default_rng(1)
    keep = np.sort(np.concatenate([[0, base.t.size - 1], rng.choice(np.arange(1, base.t.size - 1), 2500, False)]))
    from psbmpc_jax.evaltool import Tracks
    sparse = Tracks.from_arrays(base.t[keep], base.north[:, keep], base.east[:, keep], base.course[:, keep],
                                base.speed[:, keep], names=base.names)
    derived = Tracks.from_arrays(base.t, base.north, base.east, names=base.names)
    s0 = only(evaluate_tracks(base, INLAND)).scores.S14
    assert only(evaluate_tracks(sparse, INLAND)).scores.S14 == pytest.approx(s0, abs=0.005)
    assert only(evaluate_tracks(derived, INLAND)).scores.S14 == pytest.approx(s0, abs=0.005)


def test_to_dict_is_json_ready():
    import json

    ev = run({"O": own([(60, 0), (70, 30)]), "T": head_on_target()}, pairs="all")
    doc = json.loads(json.dumps(ev.to_dict(), allow_nan=False))
    enc = doc["encounters"][0]
    assert enc["situation"] == "HO" and enc["scores"]["S15"] is None
    assert enc["scores"]["S14"] == pytest.approx(ev.encounters[0].scores.S14)
    assert enc["alpha_cpa_deg"] == pytest.approx(math.degrees(ev.encounters[0].alpha_cpa))
    assert doc["params"]["r_stage2_m"] == 80 and doc["maneuvers"]["O"][0]["kind"] == "course"


def test_default_preset_sees_no_small_vessel_problem():
    """With the open-water defaults (r_pref 190 m) the same T1 geometry is unsafe: S_r < 1 lowers S_safety."""
    e = only(run({"O": own([(60, 0), (70, 30)]), "T": head_on_target()}, params=EvalParams()))
    assert e.scores.S_r < 0.5 and e.scores.S_safety < 1
