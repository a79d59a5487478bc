"""Meaningless input is refused with a message naming the field and what is allowed (or, inside jit, flagged):
documented bounds that fire, the smooth planner's public entry, the differentiable objective, the low-level
solve's status, and a scenario file that is not UTF-8."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from psbmpc_jax import Obstacle, OwnShip, Params, Planner, PlannerConfig, Situation, paper_behaviours
from psbmpc_jax.methods.two_level_settings import parse_two_level
from psbmpc_jax.objective import objective, value_and_grad
from psbmpc_jax.scenario import load_scenario, scenario_from_dict
from psbmpc_jax.solve import STATUS_INVALID_INPUT, STATUS_NAMES, STATUS_OK, inputs_valid, params_valid, solve


def scenario(**mpc):
    return {"name": "t", "simulation": {"dt_s": 0.5, "duration_s": 400},
            "mpc": {"preset": "nidelva", "update_period_s": 5, **mpc},
            "own_ship": {"name": "OS", "position_m": [0, 0], "course_deg": 0, "speed_mps": 2},
            "targets": [{"name": "TS1", "position_m": [600, 0], "course_deg": 180, "speed_mps": 2}]}


# ------------------------------------------------------------------------------------------ scenario bounds
def test_two_level_U_max_bound_fires():
    assert parse_two_level({"U_max_mps": 30}).U_max == 30.0
    with pytest.raises(ValueError, match=r"mpc\.two_level\.U_max_mps must be in \(0, 30\] m/s, got 31"):
        parse_two_level({"U_max_mps": 31})
    with pytest.raises(ValueError, match=r"mpc\.two_level\.U_max_mps must be > 0"):
        parse_two_level({"U_max_mps": 0})


@pytest.mark.parametrize("n_ps", [101, 0, 4, 1.0, True])
def test_mpc_n_ps_is_odd_from_1_to_99(n_ps):
    with pytest.raises(ValueError, match=r"mpc\.n_ps must be an odd integer from 1 to 99, got"):
        scenario_from_dict(scenario(n_ps=n_ps), land_checks="off")


def test_mpc_n_ps_99_is_accepted():
    assert scenario_from_dict(scenario(n_ps=99), land_checks="off").mpc.n_ps == 99


def test_non_utf8_scenario_file_names_the_file_and_the_encoding(tmp_path):
    p = tmp_path / "latin.yaml"
    p.write_bytes("name: t\ndescription: Tr\u00f8ndelag\n".encode("latin-1"))
    with pytest.raises(ValueError) as err:
        load_scenario(p)
    msg = str(err.value)
    assert str(p) in msg and "UTF-8" in msg and "line 2" in msg and "0xf8" in msg, msg


# ------------------------------------------------------------------------------------------ smooth planner
@pytest.fixture(scope="module")
def smooth_planner():
    from psbmpc_jax.smooth.init_stage import SmoothSettings
    from psbmpc_jax.smooth.planner import SmoothSBMPCPlanner

    return SmoothSBMPCPlanner((), init_only=True, settings=SmoothSettings(T_init=20.0, T_mpc=10.0, dt=1.0))


ROUTE = np.array([[0.0, 0.0], [500.0, 0.0]])


@pytest.mark.parametrize("change, match", [
    (dict(state0=[0.0, 0.0, 90.0, 1.0]), r"state0: course \(column 2\) = 90 is not in radians.*np\.deg2rad"),
    (dict(state0=[0.0, 0.0, 0.0, 400.0]), r"state0: speed \(column 3\) = 400 m/s is not a plausible ship speed"),
    (dict(state0=[0.0, 0.0, 0.0, -1.0]), r"state0: speed \(column 3\) = -1 m/s"),
    (dict(last=[5.0, 0.0]), r"last: the speed factor U_m must be in \[0\.1, 1\]"),
    (dict(last=[1.0, 2.0]), r"last: the course offset chi_m must be in \[-pi/2, pi/2\] rad"),
    (dict(route=np.array([[0.0, 0.0], [0.0, 0.0], [500.0, 0.0]])), r"route: leg 0 has zero length"),
    (dict(targets=np.array([[100.0, 0.0, 0.0, 400.0]])), r"targets: speed \(column 3\) = 400 m/s"),
    (dict(targets=np.array([[100.0, 0.0, -20.0, 1.0]])), r"targets: course \(column 2\) = -20"),
])
def test_smooth_planner_refuses_meaningless_input(smooth_planner, change, match):
    args = {**dict(state0=[0.0, 0.0, 0.0, 1.0], route=ROUTE, targets=np.zeros((0, 4)), last=[1.0, 0.0]), **change}
    with pytest.raises(ValueError, match=match):
        smooth_planner.plan(**args)
    batch = dict(states=np.asarray(args["state0"], float)[None], route=args["route"],
                 targets=np.asarray(args["targets"], float)[None], last=np.asarray(args["last"], float)[None],
                 segments=np.zeros(1, np.int32))
    with pytest.raises(ValueError, match=match.replace("state0", "states")):
        smooth_planner.plan_batch(**batch)


@pytest.mark.parametrize("field, value", [("U_d", 400.0), ("U_d", 0.0), ("lookahead", -1.0), ("T_chi", math.nan),
                                          ("R_a", -2.0)])
def test_smooth_planner_refuses_a_meaningless_ship_model(field, value):
    from psbmpc_jax.smooth.init_stage import ShipModel
    from psbmpc_jax.smooth.planner import SmoothSBMPCPlanner

    with pytest.raises(ValueError, match=rf"model\.{field} must be a finite number"):
        SmoothSBMPCPlanner((), model=ShipModel(**{field: value}))


# ------------------------------------------------------------------------------------------ objective, solve
CFG = PlannerConfig(T=20.0, dt=0.5, dtype="float64")
OWN = OwnShip([0.0, 0.0, 0.0, 2.0], [[0.0, 0.0], [500.0, 0.0]], 2.0)


@pytest.fixture(scope="module")
def prepared():
    sit = Situation(OWN, (Obstacle([40.0, 2.0, -2.0, 0.0], np.diag([4.0, 4.0, 0.1, 0.1]), n_ps=3),))
    return Planner(CFG, behaviours=paper_behaviours(1)).prepare(sit)


@pytest.mark.parametrize("controls, match", [([[1.5, 0.0]], r"controls\[0, 0\] = 1\.5: .*speed factor u in \[0, 1\]"),
                                             ([[-0.1, 0.0]], r"controls\[0, 0\] = -0\.1"),
                                             ([[1.0, 4.0]], r"controls\[0, 1\] = 4: .*\[-pi, pi\] rad"),
                                             ([[math.nan, 0.0]], r"controls\[0, 0\] = nan is not finite"),
                                             ([[1.0, math.inf]], r"controls\[0, 1\] = inf is not finite")])
def test_objective_refuses_concrete_controls_outside_the_box(prepared, controls, match):
    inputs, _, params, samples = prepared
    with pytest.raises(ValueError, match=match):
        objective(np.asarray(controls), inputs, params, samples, CFG)


def test_objective_last_offsets_are_checked(prepared):
    inputs, _, params, samples = prepared
    with pytest.raises(ValueError, match=r"last_offsets\[0, 0\] = 2"):
        objective(np.asarray([[1.0, 0.0]]), inputs, params, samples, CFG, last_offsets=np.asarray([2.0, 0.0]))


def test_traced_objective_gives_nan_not_a_finite_cost(prepared):
    """Inside jit (no host check possible) NaN or out-of-box controls and invalid inputs give NaN costs —
    before, NaN controls reported a collision cost of 0 and u = 1.5 a negative path cost."""
    inputs, _, params, samples = prepared
    f = jax.jit(lambda c, p: objective(c, inputs, p, samples, CFG))
    total, costs = f(jnp.asarray([[1.0, 0.0]]), params)
    assert np.isfinite(float(total)) and float(costs["do"]) > 0          # a real collision cost here
    for c in ([[math.nan, 0.0]], [[1.5, 0.0]], [[1.0, -4.0]]):
        total, costs = f(jnp.asarray(c), params)
        assert np.isnan(float(total)) and all(np.isnan(float(v)) for v in costs.values()), c
    total, _ = f(jnp.asarray([[1.0, 0.0]]), params.replace(K_coll=jnp.asarray(-1.0)))
    assert np.isnan(float(total))
    # value_and_grad (jitted, smooth) agrees
    (v, _), g = value_and_grad(jnp.asarray([[math.nan, 0.0]]), inputs, params, samples, CFG)
    assert np.isnan(float(v))
    (v, _), g = value_and_grad(jnp.asarray([[0.9, 0.1]]), inputs, params, samples, CFG)
    assert np.isfinite(float(v)) and np.all(np.isfinite(np.asarray(g)))


def _nan_own(inputs):
    return inputs._replace(own=inputs.own._replace(state=jnp.asarray(inputs.own.state).at[0].set(jnp.nan)))


def test_solve_status_is_not_ok_for_non_finite_input_or_invalid_params(prepared):
    inputs, state, params, samples = prepared
    plan, nxt, _ = solve(inputs, state, params, samples, config=CFG)
    assert int(plan.status) == STATUS_OK
    cases = {"NaN own-ship state": (_nan_own(inputs), params),
             "NaN obstacle covariance": (inputs._replace(obstacles=inputs.obstacles._replace(
                 cov=jnp.asarray(inputs.obstacles.cov).at[0, 0, 0].set(jnp.inf))), params),
             "T_d < 0": (inputs, params.replace(T_d=jnp.asarray(-5.0))),
             "K_coll NaN": (inputs, params.replace(K_coll=jnp.asarray(math.nan))),
             "ce_rho > 1": (inputs, params.replace(ce_rho=jnp.asarray(1.5))),
             "wind_dir in degrees": (inputs, params.replace(wind_dir=jnp.asarray(90.0)))}
    for name, (inp, prm) in cases.items():
        plan, nxt, _ = solve(inp, state, prm, samples, config=CFG)
        assert int(plan.status) == STATUS_INVALID_INPUT, name
        assert STATUS_NAMES[int(plan.status)].startswith("invalid input")
        np.testing.assert_array_equal(np.asarray(nxt.last_offsets), [1.0, 0.0])       # previous offsets kept


def test_device_checks_agree_with_the_host_checks():
    """params_valid (device) accepts what validate_params (host) accepts, refuses what it refuses."""
    from psbmpc_jax.params import validate_params

    assert bool(params_valid(Params()))
    for change in (dict(G3=-1.0), dict(gamma_x=0.0), dict(ce_alpha=0.0), dict(t_ts=-1.0), dict(sigma_xy=1.0),
                   dict(V_w=math.inf)):
        with pytest.raises(ValueError):
            validate_params(Params(**change))
        assert not bool(params_valid(Params(**change))), change
    assert bool(params_valid(Params(t_ts=math.nan))) and bool(params_valid(Params(t_ts=5.0)))


def test_inputs_valid_ignores_padding(prepared):
    """Padding rows (masked obstacles, unused route slots) may hold anything: only real rows count."""
    inputs, state, params, samples = prepared
    assert bool(inputs_valid(inputs, state.last_offsets, params, samples))
    assert not bool(inputs_valid(_nan_own(inputs), state.last_offsets, params, samples))
    assert not bool(inputs_valid(inputs, jnp.asarray([math.nan, 0.0]), params, samples))
