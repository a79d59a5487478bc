"""The COLREGS option in closed loop (docs/colregs_option.md): on a small crossing the stand-on own-ship keeps
its course and speed while the give-way target acts; and the option's terms through the grid search's evaluator
equal the float64 oracle while the published columns stay unchanged."""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np

from psbmpc_jax import reference_colregs_option as ref
from psbmpc_jax.behaviours import enumerate_behaviours_deg
from psbmpc_jax.costs import colregs_option as co
from psbmpc_jax.evaluate import DEFAULT_TERMS, evaluate
from psbmpc_jax.methods.colregs_option_settings import ColregsOptionSpec
from psbmpc_jax.packing import pack
from psbmpc_jax.params import Params, PlannerConfig
from psbmpc_jax.scenario.load import scenario_from_dict
from psbmpc_jax.sim.simulator import simulate
from psbmpc_jax.situation import Obstacle, OwnShip, Situation

SPEC = ColregsOptionSpec(enabled=True)
THRESH = dict(engage=SPEC.engage_radii, act_cpa=SPEC.act_cpa_radii, act_range=SPEC.act_range_radii,
              clear=SPEC.clear_radii)
WEIGHTS = dict(chi_a=SPEC.chi_apparent, du_a=SPEC.du_apparent, K_stand_on=SPEC.K_stand_on, K_port=SPEC.K_port,
               K_apparent=SPEC.K_apparent, K_hold=SPEC.K_hold, K_early=SPEC.K_early)


def crossing(option: dict) -> dict:
    """The own-ship heads north at 2 m/s; TS1 crosses from its port side at 2 m/s on a collision course (both at
    (150, 0) after 75 s) and runs PSB-MPC too (for it the own-ship is on the starboard side: it gives way)."""
    return {"name": "cso_closed_loop", "simulation": {"dt_s": 0.5, "duration_s": 110},
            "monte_carlo": {"runs": 1, "seed": 0},
            "mpc": {"preset": "nidelva", "update_period_s": 5, "n_ps": 1,
                    "config": {"T": 60.0, "dt": 1.0},
                    "speed_factors": [[1.0, 0.5, 0.0]], "course_offsets_deg": [[-60, -30, -15, 0, 15, 30, 60]],
                    "colregs_option": option},
            "own_ship": {"name": "OS", "position_m": [0, 0], "course_deg": 0, "speed_mps": 2,
                         "waypoints_m": [[0, 0], [1000, 0]]},
            "targets": [{"name": "TS1", "position_m": [150, -150], "course_deg": 90, "speed_mps": 2,
                         "waypoints_m": [[150, -150], [150, 800]], "colav": "psbmpc"}]}


def test_stand_on_keeps_course_and_speed_while_the_give_way_target_acts():
    res = simulate(scenario_from_dict(crossing({"enabled": True})), batch="loop")
    own, ts = res.states[0, 0], res.states[0, 1]
    d = np.hypot(*(ts[:, :2] - own[:, :2]).T)
    k_cpa = int(np.argmin(d))
    assert 20 < res.t[k_cpa] < res.t[-1] - 20            # the CPA lies inside the run (then it is past)
    # up to the CPA the own-ship applied (1, 0) at every update: it kept course and speed
    before = res.solve_t <= res.t[k_cpa]
    assert before.sum() >= 8
    np.testing.assert_array_equal(res.offsets[0, 0, before], np.tile([1.0, 0.0], (int(before.sum()), 1)))
    assert np.max(np.abs(own[:k_cpa + 1, 2])) < math.radians(1.0)
    assert np.allclose(own[:k_cpa + 1, 3], 2.0, atol=0.05)
    # the give-way target altered course by a readily apparent amount (>= 30 deg) to starboard, and they
    # passed clear (R = d_safe + (l_0 + l_i) / 2 = 10 m)
    assert np.degrees(np.max(ts[:k_cpa + 1, 2] - ts[0, 2])) >= 30.0
    assert d.min() > 3 * 10.0, d.min()


def test_terms_through_the_grid_search_equal_the_oracle():
    """The own-ship of a small stand-on crossing, one packed solve: the option terms' columns of the evaluator
    equal the oracle evaluated on the situation's states, and the published columns are unchanged."""
    config = PlannerConfig(T=10.0, dt=1.0, dtype="float64")
    params = Params()
    behaviours = enumerate_behaviours_deg(((1.0, 0.5), (1.0,)), ((-45, -30, -15, 0, 15, 30, 45), (-15, 0, 15)))
    own = OwnShip(state=np.array([0.0, 0.0, 0.0, 2.0]), waypoints=np.array([[0.0, 0.0], [1000.0, 0.0]]),
                  U_d=2.0, length=5.0, width=2.0)
    targets = (Obstacle(state=np.array([100.0, -100.0, 0.0, 2.0]), cov=np.eye(4), length=5.0, width=2.0, n_ps=1),
               Obstacle(state=np.array([40.0, 30.0, -1.5, 0.5]), cov=np.eye(4), length=5.0, width=2.0, n_ps=1))
    inputs = pack(Situation(own, targets, ()), behaviours, config)
    last = jnp.asarray([1.0, math.radians(15)])
    ev = evaluate(inputs, last, params, None, config, DEFAULT_TERMS + co.option_terms(SPEC))
    base = evaluate(inputs, last, params, None, config, DEFAULT_TERMS)
    for k in ("do", "colregs", "so", "path"):
        np.testing.assert_array_equal(np.asarray(ev.costs[k]), np.asarray(base.costs[k]))
    radius = params.d_safe + 0.5 * (own.length + 5.0)
    obs = [(o.state[0], o.state[1], o.state[2], o.state[3], radius, True) for o in targets]
    flags = ref.encounter((0.0, 0.0), 0.0, 2.0, obs, **THRESH)
    want = ref.option_costs(np.asarray(behaviours), np.asarray(last), flags, **WEIGHTS)
    n_b = len(behaviours)
    for k, v in want.items():
        np.testing.assert_allclose(np.asarray(ev.costs[k])[:n_b], v, rtol=1e-12, atol=1e-9, err_msg=k)
    assert flags[0]["stand_on_hold"] and np.ptp(want["stand_on"]) > 0 and np.ptp(want["apparent"]) > 0
    total = sum(np.asarray(ev.costs[k]) for k in ev.costs)
    np.testing.assert_allclose(np.asarray(ev.total)[:n_b], total[:n_b], rtol=1e-12)


def test_without_the_option_the_same_own_ship_manoeuvres_before_the_cpa():
    """The paper-faithful cost on the same encounter (so the test above can fail): the own-ship alters course or
    speed before the CPA."""
    res = simulate(scenario_from_dict(crossing({"enabled": False})), batch="loop")
    own, ts = res.states[0, 0], res.states[0, 1]
    k_cpa = int(np.argmin(np.hypot(*(ts[:, :2] - own[:, :2]).T)))
    before = res.solve_t <= res.t[k_cpa]
    assert np.any(res.offsets[0, 0, before] != np.array([1.0, 0.0]))
