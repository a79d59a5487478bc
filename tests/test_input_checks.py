"""Input checks of the Python API (issue 11 item 5): every bad input raises a ValueError naming the field and
what is allowed; NumPy scalars are accepted.  Host side only: nothing here compiles."""

from __future__ import annotations

import argparse
import math

import numpy as np
import pytest

from psbmpc_jax import Obstacle, OwnShip, Params, PlannerConfig, Situation
from psbmpc_jax import checks
from psbmpc_jax.apps import argtypes
from psbmpc_jax.params import validate_params

WPS = [[0.0, 0.0], [100.0, 0.0]]
COV = np.diag([4.0, 4.0, 0.1, 0.1])
SQUARE = np.array([[0.0, 0.0], [0.0, 10.0], [10.0, 10.0], [10.0, 0.0]])


def own(**kw):
    args = dict(state=[0.0, 0.0, 0.0, 2.0], waypoints=WPS, U_d=2.0)
    args.update(kw)
    return OwnShip(**args)


def obstacle(**kw):
    args = dict(state=[100.0, 0.0, -2.0, 0.0], cov=COV)
    args.update(kw)
    return Obstacle(**args)


# ------------------------------------------------------------------------------------------ courses and speeds
def test_course_in_degrees_is_refused_with_the_deg2rad_value():
    with pytest.raises(ValueError, match=r"own_ship.state course chi .* = 90 is not an angle in radians.*"
                                         r"np.deg2rad\(90\) = 1.5708"):
        own(state=[0.0, 0.0, 90.0, 2.0])
    for chi in (2 * math.pi, -2 * math.pi, 3.0, -3.1):          # radians, also unwrapped up to one turn
        assert own(state=[0.0, 0.0, chi, 2.0]).state[2] == chi


@pytest.mark.parametrize("kw, match", [
    (dict(state=[0.0, 0.0, 0.0, 31.0]), r"own_ship.state speed U \(state\[3\]\) = 31 m/s is not a plausible ship "
                                        r"speed \(at most 30 m/s"),
    (dict(U_d=45.0), r"own_ship.U_d = 45 m/s is not a plausible ship speed \(at most 30 m/s"),
    (dict(state=[0.0, 0.0, 0.0, -1.0]), r"speed U must be >= 0"),
])
def test_implausible_own_ship_speeds(kw, match):
    with pytest.raises(ValueError, match=match):
        own(**kw)
    assert own(state=[0.0, 0.0, 0.0, 30.0], U_d=30.0).U_d == 30.0


def test_obstacle_speed_limit():
    with pytest.raises(ValueError, match=r"obstacle.state velocity .* is 70.7107 m/s; at most 60 m/s"):
        obstacle(state=[0.0, 0.0, 50.0, 50.0])
    obstacle(state=[0.0, 0.0, 40.0, 0.0])                     # noisy estimates up to 60 m/s are accepted


@pytest.mark.parametrize("make, match", [
    (lambda: own(state=[5e7, 0.0, 0.0, 2.0]), r"own_ship.state position \(x, y\): point \[50000000.0, 0.0\] lies "
                                              r"50000 km from the frame's origin; at most 40000 km allowed"),
    (lambda: own(waypoints=[[0.0, 0.0], [0.0, -3e9]]), r"own_ship.waypoints: point .* not millimetres or degrees"),
    (lambda: obstacle(state=[1e9, 0.0, 0.0, 0.0]), r"obstacle.state position .* at most 40000 km"),
    (lambda: obstacle(waypoints=[[0.0, 0.0], [1e9, 0.0]]), r"obstacle.waypoints: point .* at most 40000 km"),
    (lambda: own(length=501.0), r"own_ship.length must be at most 500 m \(a hull dimension in metres\), got 501"),
    (lambda: obstacle(width=5000.0), r"obstacle.width must be at most 100 m"),
    (lambda: Situation(own(), (), polygons=(np.array([[0.0, 0.0], [0.0, 1.0], [5e7, 0.0]]),)),
     r"polygon.* point \[50000000.0, 0.0\] lies 50000 km"),
])
def test_positions_off_the_earth_and_implausible_hulls_are_refused(make, match):
    with pytest.raises(ValueError, match=match):
        make()
    # UTM coordinates (the planner re-centres on the own-ship) and the largest hulls are accepted
    own(state=[7035254.0, 569796.0, 0.0, 2.0], waypoints=[[7035254.0, 569796.0], [7036254.0, 569796.0]],
        length=500.0, width=100.0)


# ------------------------------------------------------------------------------------------ types
@pytest.mark.parametrize("make, match", [
    (lambda: own(state=[0.0, 0.0, 0.0, True]), r"own_ship.state must be numeric \(real numbers, not bool"),
    (lambda: own(state=[0.0, 0.5, 0.0, True]), r"own_ship.state must be numeric"),
    (lambda: own(state=[0.0, 0.0, 0.0, "2"]), r"own_ship.state must be numeric"),
    (lambda: own(state=None), r"own_ship.state must be numeric, got None"),
    (lambda: own(waypoints=None), r"own_ship.waypoints must be an array \[n >= 2, 2\]"),
    (lambda: own(U_d="fast"), r"own_ship.U_d must be numeric"),
    (lambda: own(length=True), r"own_ship.length must be numeric"),
    (lambda: obstacle(cov="big"), r"obstacle.cov must be numeric"),
    (lambda: obstacle(n_ps=True), r"obstacle.n_ps must be an odd integer >= 1"),
    (lambda: obstacle(n_ps=103), r"obstacle.n_ps must be an odd integer <= 101"),
])
def test_bools_strings_and_none_are_refused(make, match):
    with pytest.raises(ValueError, match=match):
        make()


def test_numpy_scalars_are_accepted():
    o = own(state=np.array([0.0, 0.0, 0.5, 2.0], np.float32), U_d=np.float32(2.0), length=np.int64(5),
            width=np.float64(3.0))
    assert o.U_d == 2.0 and o.length == 5.0 and o.state.dtype == np.float64
    ob = obstacle(n_ps=np.int64(3), length=np.float32(6.0), weight=np.int32(1))
    assert ob.n_ps == 3 and isinstance(ob.n_ps, int)
    cfg = PlannerConfig(T=np.int64(150), dt=np.float32(0.5), n_samples=np.int64(100), n_quad=np.int32(16))
    assert cfg.n_steps == 300 and type(cfg.T) is int and type(cfg.n_samples) is int and type(cfg.dt) is float
    validate_params(Params(d_safe=np.float32(5.0), K_coll=np.int64(30), wind_dir=np.float64(1.0)))


# ------------------------------------------------------------------------------------------ PlannerConfig, Params
@pytest.mark.parametrize("kw, match", [
    (dict(T=True), r"PlannerConfig.T must be a finite number > 0 \(int or float, not bool or str\), got bool True"),
    (dict(T="150"), r"PlannerConfig.T must be a finite number > 0 .* got str '150'"),
    (dict(dt=np.bool_(True)), r"PlannerConfig.dt must be a finite number > 0"),
    (dict(T=10 ** 400), r"PlannerConfig.T must be a finite number > 0 .*an integer with 401 digits"),
    (dict(n_samples=True), r"PlannerConfig.n_samples must be an integer in 1..10000000 \(not bool\), got bool"),
    (dict(n_samples=10 ** 12), r"PlannerConfig.n_samples must be an integer in 1..10000000"),
    (dict(n_quad=2.0), r"PlannerConfig.n_quad must be an integer in 2..10000"),
    (dict(T=1e6, dt=0.5), r"2000000 prediction steps; at most 100000 allowed"),
    (dict(estimator=["mc"]), r"PlannerConfig.estimator must be one of \('quadrature', 'mc', 'ce'\), got \['mc'\]"),
])
def test_planner_config_refuses(kw, match):
    with pytest.raises(ValueError, match=match):
        PlannerConfig(**kw)


@pytest.mark.parametrize("kw, match", [
    (dict(K_coll="abc"), r"Params.K_coll must be a real number, got str 'abc'"),
    (dict(K_coll=True), r"Params.K_coll must be a real number, got bool True"),
    (dict(d_safe=None), r"Params.d_safe must be a real number, got NoneType"),
    (dict(wind_dir=90), r"Params.wind_dir = 90 is not in radians .*np.deg2rad\(90\) = 1.5708"),
    (dict(wind_dir=-7.0), r"Params.wind_dir = -7 is not in radians"),
    (dict(G3=[1.0, 2.0]), r"Params.G3 must be a scalar"),
])
def test_params_refuse(kw, match):
    with pytest.raises(ValueError, match=match):
        validate_params(Params(**kw))


def test_t_ts_beyond_the_horizon():
    cfg = PlannerConfig(T=150.0)
    validate_params(Params(t_ts=100.0), cfg)                          # 2 maneuvers: the 2nd at 100 s < 150 s
    with pytest.raises(ValueError, match=r"Params.t_ts = 200 s puts maneuver 2 at 200 s, beyond the horizon "
                                         r"PlannerConfig.T = 150 s"):
        validate_params(Params(t_ts=200.0), cfg)
    with pytest.raises(ValueError, match=r"maneuver 3 at 160 s.*t_ts < 75 s"):
        validate_params(Params(t_ts=80.0), cfg, n_maneuvers=3)
    validate_params(Params(t_ts=float("nan")), cfg, n_maneuvers=3)   # nan = T / n_M
    validate_params(Params(t_ts=200.0))                                # without a config nothing to compare


# ------------------------------------------------------------------------------------------ Situation
def test_single_obstacle_and_none_lists():
    with pytest.raises(ValueError, match=r"situation.obstacles must be a tuple/list of Obstacle, got a single "
                                         r"Obstacle; pass a tuple/list of Obstacle"):
        Situation(own(), obstacle())
    with pytest.raises(ValueError, match=r"situation.obstacles must be a tuple/list of Obstacle \(use \(\) for none\), "
                                         r"got None"):
        Situation(own(), None)
    with pytest.raises(ValueError, match=r"situation.polygons must be a tuple/list of polygons .* got None"):
        Situation(own(), (), None)
    with pytest.raises(ValueError, match=r"got one array of shape \(4, 2\); pass \(ring,\)"):
        Situation(own(), (), SQUARE)
    with pytest.raises(ValueError, match=r"got a single ring of 4 points; pass \(ring,\)"):
        Situation(own(), (), SQUARE.tolist())
    s = Situation(own(), [obstacle()], [SQUARE])                      # lists are fine
    assert isinstance(s.obstacles, tuple) and len(s.polygons) == 1


@pytest.mark.parametrize("poly, match", [
    (np.array([[0.0, 0.0], [10.0, 10.0], [10.0, 0.0], [0.0, 10.0]]),
     r"\(ring\) is not a valid simple polygon: Self-intersection"),
    (np.array([[0.0, 0.0], [5.0, 5.0], [10.0, 10.0]]), r"\(ring\) is not a valid simple polygon"),
    ((SQUARE, SQUARE + 20.0), r"\(outer ring \+ holes\) is not a valid simple polygon: Hole lies outside shell"),
    ((SQUARE * 3, SQUARE + 2.0, SQUARE + 4.0), r"\(outer ring \+ holes\) is not a valid simple polygon"),
])
def test_invalid_polygons_are_refused_with_shapely_reason(poly, match):
    with pytest.raises(ValueError, match=r"situation.polygons\[0\] " + match):
        Situation(own(), (), (poly,))


def test_valid_polygons_pass_and_are_cached():
    hole = SQUARE * 0.2 + 4.0
    s = Situation(own(), (), ((SQUARE, hole), np.vstack([SQUARE, SQUARE[:1]])))   # closed ring: still valid
    assert len(s.polygons) == 2
    Situation(own(), (), ((SQUARE, hole),))                          # second time from the cache


# ------------------------------------------------------------------------------------------ PRNG keys
def test_prng_key_check():
    import jax

    k = jax.random.key(3)
    assert checks.prng_key(k) is k
    raw = jax.random.PRNGKey(3)
    assert checks.prng_key(raw) is raw
    for bad, match in [(None, r"need a PRNG key"), (42, r"must be a JAX PRNG key, got int 42"),
                       ("seed", r"got str"), (np.zeros(3), r"must be a JAX PRNG key"),
                       (jax.random.split(k, 2), r"single PRNG key, got a batch of shape \(2,\)")]:
        with pytest.raises(ValueError, match=match):
            checks.prng_key(bad, "key")


# ------------------------------------------------------------------------------------------ helpers, argtypes
def test_checks_helpers():
    assert checks.real(np.float32(1.5), "x") == 1.5 and checks.real(np.array(2), "x") == 2.0
    for bad in (True, "1", None, float("nan"), 10 ** 400):
        with pytest.raises(ValueError, match="x "):
            checks.real(bad, "x")
    assert checks.integer(np.int64(7), "n", ge=1, le=10) == 7
    with pytest.raises(ValueError, match=r"n must be an integer <= 10 \(allowed: 1..10\), got an integer with 400 "):
        checks.integer(10 ** 399, "n", ge=1, le=10)
    with pytest.raises(ValueError, match=r"n must be an integer >= 1, got True"):
        checks.integer(True, "n", ge=1)


def test_argtypes_limits():
    assert argtypes.runs_int("20") == 20 and argtypes.seed_int("0") == 0
    for fn, text, match in [(argtypes.positive_int, "1" * 400, "400-character"),
                            (argtypes.positive_int, "2000000000", "<= 1000000000"),
                            (argtypes.runs_int, "10001", "<= 10000"),
                            (argtypes.seed_int, str(2 ** 32), "<= 4294967295"),
                            (argtypes.seed_int, "-1", ">= 0")]:
        with pytest.raises(argparse.ArgumentTypeError, match=match):
            fn(text)


def test_unknown_keys_suggest_the_close_name():
    from psbmpc_jax import presets
    from psbmpc_jax.scenario import scenario_from_dict

    with pytest.raises(ValueError, match=r"unknown key 'nam' .*did you mean 'name'"):
        scenario_from_dict({"nam": "x"})
    with pytest.raises(ValueError, match=r"did you mean 'K_coll' for 'K_col'"):
        presets.build_mpc("nidelva", param_overrides={"K_col": 1.0})


def test_planner_refuses_t_ts_beyond_the_horizon_and_a_bad_key():
    from psbmpc_jax import Params, Planner, PlannerConfig

    with pytest.raises(ValueError, match="t_ts"):
        Planner(PlannerConfig(T=60.0), params=Params(t_ts=100.0))
    with pytest.raises(ValueError, match="key"):
        from psbmpc_jax import OwnShip, Situation

        own = OwnShip([0.0, 0.0, 0.0, 2.0], [[0.0, 0.0], [500.0, 0.0]], 2.0)
        Planner(PlannerConfig(estimator="mc")).prepare(Situation(own, ()), key=12345)


# ------------------------------------------------------------------ previous plans (refinement, Smooth-SBMPC)
def test_control_plan_accepts_a_plan_in_the_box_and_marks_missing_ones():
    control_plan = checks.control_plan
    box = dict(n=3, lower=(0.1, -1.0), upper=(1.0, 1.0), box="B", what="U, chi")
    plan = [[0.1, -1.0], [1.0, 1.0], [0.5, 0.0]]
    a, missing = control_plan(plan, "p", **box)
    assert a.dtype == np.float64 and not bool(missing)
    np.testing.assert_array_equal(a, plan)
    a, missing = control_plan(np.full((3, 2), np.nan), "p", **box)          # NaN throughout: no plan
    assert bool(missing)
    runs = np.stack([plan, np.full((3, 2), np.nan)])
    a, missing = control_plan(runs, "p", lead=(2,), missing_ok=False, **box)  # a run without one
    np.testing.assert_array_equal(missing, [False, True])
    control_plan(np.asarray(plan) + [0.0, 1e-7], "p", **box)              # within the slack (tol 1e-6)


@pytest.mark.parametrize("value, kw, match", [
    (np.full((3, 2), "a"), {}, r"p must be numeric, got dtype <U1"),
    ([[0.5, 0.0], [0.5], [0.5, 0.0]], {}, r"p must be a numeric array \[3, 2\] \(U, chi\), got \[\[0.5"),
    (np.zeros((3, 2), bool), {}, r"p must be numeric, got dtype bool"),
    ([[0.5, None], [0.5, 0.0], [0.5, 0.0]], {}, r"p must be numeric, got dtype object"),
    (np.zeros((2, 2)) + 0.5, {}, r"p must be \[3, 2\] \(U, chi\) per step, got shape \(2, 2\)"),
    (np.zeros((2, 3, 2)) + 0.5, {}, r"p must be \[3, 2\]"),
    (np.zeros((3, 2)) + 0.5, dict(lead=(2,)), r"p must be \[2, 3, 2\]"),
    (np.full((3, 2), np.nan), dict(missing_ok=False), r"p must be finite$"),
    (np.where(np.eye(3, 2) > 0, np.nan, 0.5), {}, r"p must be finite \(NaN throughout means: no previous plan\)"),
    (np.stack([np.where(np.eye(3, 2) > 0, np.inf, 0.5), np.full((3, 2), 0.5)]), dict(lead=(2,)),
     r"NaN throughout means: no previous plan for that run"),
    (np.zeros((3, 2)) + [1.01, 0.0], {}, r"p must lie in B"),
    (np.zeros((3, 2)) + [0.5, -1.1], {}, r"p must lie in B"),
    (np.zeros((3, 2)) + [0.05, 0.0], dict(tol=0.1), None),                 # the slack is the caller's
])
def test_control_plan_refuses_bad_plans_naming_the_field(value, kw, match):
    control_plan = checks.control_plan
    box = dict(n=3, lower=(0.1, -1.0), upper=(1.0, 1.0), box="B", what="U, chi")
    if match is None:
        control_plan(value, "p", **box, **kw)
        return
    with pytest.raises(ValueError, match=match):
        control_plan(value, "p", **box, **kw)
