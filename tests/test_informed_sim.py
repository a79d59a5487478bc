"""Informed SB-MPC in the simulator (seed 002): the YAML keys of route exchange, Rule-18 roles and the 3-DOF
truth model (good and bad), the exchange with delay and dropouts, the XTD supervisor, prediction along a shared
plan, the d_init gate, 3-DOF motion per ship, and a short closed loop of the seed-002 scenarios."""

from __future__ import annotations

import copy
import dataclasses

import jax.numpy as jnp
import numpy as np
import pytest

from psbmpc_jax.evaluate import evaluate
from psbmpc_jax.packing import pack
from psbmpc_jax.params import Params, PlannerConfig
from psbmpc_jax.methods.informed_settings import INFORMED_TERM_FIELDS
from psbmpc_jax.scenario import VESSEL_MODELS, load_scenario, scenario_from_dict
from psbmpc_jax.sim import simulate, vessel3dof
from psbmpc_jax.methods.base import route_distance
from psbmpc_jax.sim.simulator import _ClosedLoop
from psbmpc_jax.situation import Obstacle, OwnShip, Situation

BASE = {
    "name": "informed_tiny",
    "description": "two PSVs, the target shares a route that turns away",
    "simulation": {"dt_s": 1.0, "duration_s": 20},
    "monte_carlo": {"runs": 2, "seed": 4},
    "collision_distance_m": 116,
    "mpc": {"preset": "akdag2022", "update_period_s": 5, "method": "informed_sbmpc", "config": {"T": 100},
            "informed": {"d_init_m": 2000}},
    "sensor": {"position_std_m": 2, "period_s": 1, "filter_R_scale": 25, "sigma_a_mps2": 0.5, "U_max_mps": 9},
    "own_ship": {"name": "OS", "position_m": [0, 0], "course_deg": 0, "speed_mps": 6, "length_m": 116,
                 "width_m": 20, "waypoints_m": [[0, 0], [9000, 0]]},
    "targets": [{"name": "TS1", "position_m": [1500, 50], "course_deg": 180, "speed_mps": 6, "length_m": 116,
                 "width_m": 20, "waypoints_m": [[1500, 50], [1000, 50], [1000, 3000]], "shares_route": True,
                 "rule18_role": "ram"}],
}


def scen(**changes) -> dict:
    d = copy.deepcopy(BASE)
    for path, value in changes.items():
        *head, last = path.split("__")
        node = d
        for k in head:
            node = node[int(k)] if k.isdigit() else node[k]
        if value is None:
            node.pop(last)
        else:
            node[last] = value
    return d


def loop_of(d, runs=2):
    sc = scenario_from_dict(d)
    return _ClosedLoop(sc, runs, sc.seed, "loop", None, 0)


# ============================================================================= keys
def test_ship_and_informed_keys_parse():
    sc = scenario_from_dict(scen(targets__0__motion_model="3dof", targets__0__vessel_model="psv_116m",
                                 mpc__informed={"route_exchange": False, "xtd_threshold_m": 50, "d_init_m": 1500,
                                                "exchange_delay_s": 10, "exchange_dropout": 0.25,
                                                "classify": "sectors_t0", "circular": True,
                                                "term": {"rho_r18": 5, "c_dist": 400}}))
    t, inf = sc.targets[0], sc.mpc.informed
    assert (t.shares_route, t.rule18_role, t.motion_model, t.vessel_model) == (True, "ram", "3dof", "psv_116m")
    assert (sc.own_ship.shares_route, sc.own_ship.rule18_role, sc.own_ship.motion_model) == (False, "pdv", "kinematic")
    assert (inf.route_exchange, inf.xtd_threshold, inf.d_init, inf.exchange_delay, inf.exchange_dropout) == (
        False, 50.0, 1500.0, 10.0, 0.25)
    assert (inf.classify, inf.circular, inf.term) == ("sectors_t0", True, {"rho_r18": 5.0, "c_dist": 400.0})
    assert sc.own_ship.colav == "informed_sbmpc"


def test_the_names_the_loader_keeps_match_the_modules():
    from psbmpc_jax.costs.informed import InformedSbmpcTerm

    numeric = [f.name for f in dataclasses.fields(InformedSbmpcTerm) if f.name not in InformedSbmpcTerm.STATIC]
    assert tuple(numeric) == INFORMED_TERM_FIELDS
    assert VESSEL_MODELS == tuple(vessel3dof.PRESETS)


@pytest.mark.parametrize("change, match", [
    (dict(targets__0__rule18_role="tug"), r"targets\[0\].rule18_role must be one of pdv, nuc, ram, cbd, fishing, "
                                          r"sailing, got 'tug'"),
    (dict(targets__0__shares_route="yes"), r"targets\[0\].shares_route must be true or false"),
    (dict(targets__0__motion_model="6dof"), r"targets\[0\].motion_model must be one of kinematic, 3dof"),
    (dict(targets__0__motion_model="3dof"), r"targets\[0\]: motion_model 3dof needs vessel_model \(one of "
                                            r"psv_116m, small_5m\)"),
    (dict(targets__0__vessel_model="psv_116m"), r"targets\[0\].vessel_model: only with motion_model: 3dof"),
    (dict(own_ship__motion_model="3dof", own_ship__vessel_model="tanker"), r"own_ship.vessel_model must be one of"),
    (dict(mpc__informed={"xtd_m": 3}), r"unknown key 'xtd_m' in mpc.informed"),
    (dict(mpc__informed={"xtd_threshold_m": 0}), r"mpc.informed.xtd_threshold_m must be > 0"),
    (dict(mpc__informed={"exchange_dropout": 1.5}), r"mpc.informed.exchange_dropout must be <= 1"),
    (dict(mpc__informed={"exchange_delay_s": -1}), r"mpc.informed.exchange_delay_s must be >= 0"),
    (dict(mpc__informed={"classify": "woerner"}), r"mpc.informed.classify must be one of velocity, sectors_t0"),
    (dict(mpc__informed={"term": {"rho18": 1}}), r"unknown key 'rho18' in mpc.informed.term"),
    (dict(mpc__informed={"route_exchange": 1}), r"mpc.informed.route_exchange must be true or false"),
    (dict(targets__0__colav="smooth_sbmpc"), r"targets\[0\].colav: smooth_sbmpc plans the own-ship only"),
])
def test_bad_keys_name_the_ship_or_key(change, match):
    with pytest.raises(ValueError, match=match):
        scenario_from_dict(scen(**change))


# ============================================================================= exchange and supervisor
def test_route_distance_by_hand():
    route = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 100.0]])
    assert route_distance([50.0, 30.0], route) == pytest.approx(30.0)
    assert route_distance([130.0, 50.0], route) == pytest.approx(30.0)
    assert route_distance([-40.0, -30.0], route) == pytest.approx(50.0)           # before the first point
    assert route_distance([100.0, 0.0], route) == pytest.approx(0.0)


def test_exchange_delay_and_dropout():
    lp = loop_of(scen())
    lp.exchange(0)
    assert lp.received_seg[:, 1].tolist() == [0, 0] and lp.received_seg[:, 0].tolist() == [-1, -1]   # OS shares none
    lp = loop_of(scen(mpc__informed={"exchange_delay_s": 10}))
    lp.exchange(0)
    assert lp.received_seg[:, 1].tolist() == [-1, -1]                                 # not due yet
    lp.seg[:, 1] = 1
    lp.exchange(5)
    lp.exchange(10)                                                                   # t = 10: the plan of t = 0
    assert lp.received_seg[:, 1].tolist() == [0, 0]
    lp.exchange(15)
    assert lp.received_seg[:, 1].tolist() == [1, 1]
    lp = loop_of(scen(mpc__informed={"exchange_dropout": 1.0}))
    for k in range(0, 20, 5):
        lp.exchange(k)
    assert lp.received_seg[:, 1].tolist() == [-1, -1]                                 # every message lost
    lp = loop_of(scen(mpc__informed={"exchange_dropout": 0.5}), runs=40)
    lp.exchange(0)
    got = np.mean(lp.received_seg[:, 1] >= 0)
    assert 0.2 < got < 0.8                                                            # some lost, some delivered


def test_informed_situation_route_role_and_supervisor():
    lp = loop_of(scen())
    lp.measure(0)
    lp.exchange(0)
    ob = lp.observe(0).situation(0, 0, n_ps=1, informed=True).obstacles[0]
    np.testing.assert_allclose(ob.waypoints, lp.shared_route(0, 1))
    assert ob.rule18 and ob.n_ps == 1
    # the target 150 m off its plan: the supervisor predicts a straight line
    lp.states[0, 1, 0, 1] += 150.0
    ob = lp.observe(0).situation(0, 0, n_ps=1, informed=True).obstacles[0]
    assert ob.waypoints is None and ob.rule18                                         # the role is still known
    # route exchange off: straight lines; a ship that shares nothing: no role either
    lp = loop_of(scen(mpc__informed={"route_exchange": False}))
    lp.measure(0)
    lp.exchange(0)
    assert lp.observe(0).situation(0, 0, informed=True).obstacles[0].waypoints is None
    lp = loop_of(scen(targets__0__shares_route=False))
    lp.measure(0)
    lp.exchange(0)
    ob = lp.observe(0).situation(0, 0, informed=True).obstacles[0]
    assert ob.waypoints is None and not ob.rule18


def test_prediction_follows_the_shared_plan():
    """The evaluator predicts an obstacle with a shared route along it (LOS, one scenario): after the turn it
    heads east, while the straight-line prediction keeps going south."""
    cfg = PlannerConfig(T=300.0, dt=5.0)
    prm = Params(ob_T_chi=15.0, ob_T_U=30.0, os_T_chi=15.0, os_T_U=30.0, ob_lookahead=300.0)
    own = OwnShip(state=[0.0, 0.0, 0.0, 6.0], waypoints=np.array([[0.0, 0.0], [9000.0, 0.0]]), U_d=6.0)
    route = np.array([[1500.0, 50.0], [1000.0, 50.0], [1000.0, 3000.0]])
    cov = np.diag([4.0, 4.0, 0.1, 0.1])
    beh = np.array([[[1.0, 0.0]]])
    ends = []
    for wps in (route, None):
        sit = Situation(own, (Obstacle([1500.0, 50.0, -6.0, 0.0], cov, n_ps=1, waypoints=wps),))
        ev = evaluate(pack(sit, beh, cfg), jnp.asarray([1.0, 0.0]), prm, None, config=cfg)
        ends.append((float(ev.obstacles.x[-1, 0, 0]), float(ev.obstacles.y[-1, 0, 0])))
    (xr, yr), (xs, ys) = ends
    assert abs(xr - 1000.0) < 60.0 and yr > 1000.0                                    # along the plan: east
    assert xs < 0.0 and abs(ys - 50.0) < 1.0                                          # straight on: south


def test_rule18_reaches_the_context():
    cfg = PlannerConfig(T=50.0, dt=5.0)
    own = OwnShip(state=[0.0, 0.0, 0.0, 6.0], waypoints=np.array([[0.0, 0.0], [9000.0, 0.0]]), U_d=6.0)
    cov = np.diag([4.0, 4.0, 0.1, 0.1])
    sit = Situation(own, (Obstacle([800.0, 50.0, -6.0, 0.0], cov, n_ps=1, rule18=True),
                          Obstacle([600.0, -300.0, 0.0, 5.0], cov, n_ps=1)))
    inputs = pack(sit, np.array([[[1.0, 0.0]]]), cfg)
    assert inputs.obstacles.r18[:2].tolist() == [True, False] and not inputs.obstacles.r18[2:].any()
    with pytest.raises(ValueError, match=r"obstacle.rule18 must be True or False"):
        Obstacle([0.0, 0.0, 0.0, 0.0], cov, rule18="ram")


# ============================================================================= gate, 3-DOF motion, closed loop
def test_d_init_gate_rests_the_planner():
    res = simulate(scenario_from_dict(scen(mpc__informed={"d_init_m": 500})), runs=2)      # target 1.5 km away
    assert np.all(res.offsets[:, 0] == np.array([1.0, 0.0]))
    assert all(c["device_calls"] == 0 for c in res.calls)
    assert np.all(np.isnan(res.solve_wall[:, 0])) and res.metrics[0]["solve_times_s"] == []   # no solve timed
    res = simulate(scenario_from_dict(scen()), runs=2)
    assert all(c["device_calls"] >= 1 for c in res.calls)


def test_3dof_ships_move_with_the_manoeuvring_model():
    d = scen(targets__0__motion_model="3dof", targets__0__vessel_model="psv_116m", targets__0__colav="none",
             targets__0__course_deg=135)                         # starts 45 deg off its route: it turns
    d["mpc"]["informed"]["d_init_m"] = 100                         # the own-ship rests: only the models move
    sc = scenario_from_dict(d)
    res = simulate(sc, runs=1)
    # the target (3-DOF PSV) replayed by hand from its start with the same commands
    lp = _ClosedLoop(sc, 1, sc.seed, "loop", None, 0)
    full = vessel3dof.from_sim_state(lp.states[:, [1], 0])
    from psbmpc_jax.sim.vessel import los_course

    states = lp.states.copy()
    for k in range(3):
        chi, lp.seg = los_course(states[:, :, k, :2], lp.seg, lp.routes_ext, lp.n_wp, lp.lookahead, lp.R_a)
        full = vessel3dof.step(full, chi[:, [1]], np.array([[6.0]]), sc.dt, vessel3dof.stack_params(
            [vessel3dof.preset("psv_116m")]))
        states[:, 1, k + 1] = vessel3dof.sim_view(full)[:, 0]
        states[:, 0, k + 1] = res.states[:, 0, k + 1]
    np.testing.assert_allclose(res.states[0, 1, 1:4], states[0, 1, 1:4], rtol=0, atol=1e-9)
    # the kinematic own-ship is unchanged by the other ship's model
    kin = copy.deepcopy(d)
    del kin["targets"][0]["motion_model"], kin["targets"][0]["vessel_model"]
    ref = simulate(scenario_from_dict(kin), runs=1)
    np.testing.assert_allclose(res.states[0, 0], ref.states[0, 0], atol=1e-9)
    assert not np.allclose(res.states[0, 1], ref.states[0, 1])


@pytest.mark.parametrize("name", ["akdag2022_stand_on_rule18", "akdag2022_three_ships"])
def test_seed_002_scenarios_run(name):
    sc = load_scenario(name)
    sc = dataclasses.replace(sc, duration=60.0)
    res = simulate(sc, runs=1)
    planners = [i for i, s in enumerate(sc.ships) if s.colav != "none"]
    assert np.all(np.isfinite(res.states)) and np.all(np.isfinite(res.offsets[:, planners]))
    assert all(s.motion_model == "3dof" for s in sc.ships)


# ============================================================================= leg speeds of shared plans
def test_prediction_at_leg_speeds_matches_the_reference():
    """An obstacle with per-leg speeds is predicted at each leg's speed (after the last waypoint the last
    leg's): the evaluator's float64 rollout equals the sequential reference's, and its speed settles at the
    second leg's value after the turn."""
    from psbmpc_jax import reference_prediction as pred

    cfg = PlannerConfig(T=300.0, dt=5.0, dtype="float64")
    prm = Params(ob_T_chi=15.0, ob_T_U=30.0, ob_lookahead=300.0)
    own = OwnShip(state=[0.0, 0.0, 0.0, 6.0], waypoints=np.array([[0.0, 0.0], [9000.0, 0.0]]), U_d=6.0)
    route = np.array([[1500.0, 50.0], [1000.0, 50.0], [1000.0, 3000.0]])
    ob = Obstacle([1500.0, 50.0, -6.0, 0.0], np.diag([4.0, 4.0, 0.1, 0.1]), n_ps=1, waypoints=route,
                  leg_speeds=[6.0, 2.5])
    ev = evaluate(pack(Situation(own, (ob,)), np.array([[[1.0, 0.0]]]), cfg), jnp.asarray([1.0, 0.0]), prm, None,
                  config=cfg)
    got = np.stack([np.asarray(getattr(ev.obstacles, c))[:, 0, 0] for c in ("x", "y", "chi", "U")], axis=1)
    ref = pred.obstacle_scenarios(ob, prm, cfg)[0]
    np.testing.assert_allclose(got, ref, rtol=1e-10, atol=1e-8)
    assert got[-1, 3] == pytest.approx(2.5, abs=0.05) and got[10, 3] == pytest.approx(6.0, abs=0.05)
    with pytest.raises(ValueError, match=r"obstacle.leg_speeds needs obstacle.waypoints"):
        Obstacle([0.0, 0.0, 1.0, 0.0], np.eye(4), leg_speeds=[1.0])
    with pytest.raises(ValueError, match=r"obstacle.leg_speeds"):
        Obstacle([0.0, 0.0, 1.0, 0.0], np.eye(4), waypoints=route, leg_speeds=[1.0])          # 2 legs, 1 speed


def test_leg_speeds_in_the_file_move_the_ship_and_are_shared():
    d = scen(targets__0__leg_speeds_mps=[6.0, 3.0], targets__0__colav="none", simulation__duration_s=200)
    d["mpc"]["informed"]["d_init_m"] = 100                       # the own-ship rests: the target moves freely
    sc = scenario_from_dict(d)
    assert sc.targets[0].leg_speeds.tolist() == [6.0, 3.0]
    res = simulate(sc, runs=1)
    U = res.states[0, 1, :, 3]
    assert U[30] == pytest.approx(6.0, abs=0.05) and U[-1] < 3.5                # first leg 6 m/s, then 3 m/s
    lp = loop_of(d)
    lp.exchange(0)
    np.testing.assert_allclose(lp.shared_leg_speeds(0, 1), [6.0, 3.0, 3.0])      # + the extension leg
    lp.measure(0)
    ob = lp.observe(0).situation(0, 0, n_ps=1, informed=True).obstacles[0]
    np.testing.assert_allclose(ob.leg_speeds, [6.0, 3.0, 3.0])


@pytest.mark.parametrize("change, match", [
    (dict(targets__0__leg_speeds_mps=[6.0]), r"targets\[0\].leg_speeds_mps must be a list of 2 speeds"),
    (dict(targets__0__leg_speeds_mps=[6.0, -1]), r"targets\[0\].leg_speeds_mps\[1\] must be >= 0"),
    (dict(targets__0__leg_speeds_mps=[6.0, 0.0], targets__0__colav="informed_sbmpc"),
     r"targets\[0\].leg_speeds_mps: every leg speed must be > 0"),
    (dict(targets__0__leg_speeds_mps=[6.0, 3.0], targets__0__waypoints_m=None), r"needs the ship's waypoints"),
    (dict(targets__0__leg_speeds_mps=[6.0, 3.0], targets__0__speed_plan=[{"t_s": 5, "speed_mps": 2}]),
     r"leg_speeds_mps and speed_plan are exclusive"),
])
def test_bad_leg_speeds(change, match):
    with pytest.raises(ValueError, match=match):
        scenario_from_dict(scen(**change))
