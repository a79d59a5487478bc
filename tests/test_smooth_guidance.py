"""The DOCP's guidance frame of Smooth-SBMPC (psbmpc_jax/smooth/guidance.py, docp.docp_frame), float64.

* ``chi_d_mode="terminal_los"``: Ψ's offsets re-expressed against LOS on the line from the ship through Ψ_N agree
  with the float64 loop oracle (``reference_smooth.terminal_los_offsets``), and rolled out on that line (by the
  NumPy LOS rollout of ``reference_prediction``) reproduce Ψ to 1e-9 m; the warm start satisfies the terminal
  equality and the corridor; the applied offset is carried into the frame; the conversion back to the route
  frame inverts it; the applied sequence, rolled out on the route's LOS, gives the DOCP plan's trajectory;
* a re-expressed offset outside the box sends that update to the route frame;
* ``"route_los"`` is the route frame unchanged;
* settings: bad values refused with the field's name, the mode recorded with the run's settings."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from psbmpc_jax import reference_smooth as RS
from psbmpc_jax.methods.smooth_settings import parse_smooth
from psbmpc_jax.packing import pack_world
from psbmpc_jax.params import PlannerConfig
from psbmpc_jax.reference_prediction import los_rollout as np_los_rollout
from psbmpc_jax.smooth import buffered_chart
from psbmpc_jax.smooth.docp import docp_frame, prepare_step, problem, smooth_sbmpc_step, to_route_frame
from psbmpc_jax.smooth.guidance import LINE_LENGTH, los_courses
from psbmpc_jax.smooth.init_stage import (InitResult, ShipModel, SmoothSettings, SmoothWeights, rollout_controls,
                                          route_path)

SETTINGS = SmoothSettings(T_init=16.0, T_mpc=8.0, dt=1.0, n_y=51)              # terminal_los, continuous
BANKS = [np.array([[-50.0, 14.0], [150.0, 14.0], [150.0, 30.0], [-50.0, 30.0]]),
         np.array([[-50.0, -14.0], [150.0, -14.0], [150.0, -30.0], [-50.0, -30.0]])]
ROUTE = np.array([[0.0, 0.0], [30.0, 0.0], [60.0, 10.0], [140.0, 10.0]])      # turns: route LOS != line LOS
LAND = pack_world(BANKS, PlannerConfig(dtype="float64")).polygons
BUF = buffered_chart(BANKS, SETTINGS.corridor_land_buffer)
MODEL = ShipModel()

_prepare = jax.jit(prepare_step, static_argnames=("settings", "n_starts"))

SITUATIONS = [  # state0, targets, last, segment
    (np.array([0.0, 2.0, 0.1, 0.9]), np.array([[20.0, 1.0, math.pi, 0.5]]), np.array([1.0, 0.2]), 0),
    (np.array([24.0, -3.0, 0.4, 1.0]), np.array([[45.0, 8.0, math.pi - 0.3, 0.6]]), np.array([0.5, -0.3]), 0),
    (np.array([35.0, 4.0, 0.2, 0.8]), np.zeros((0, 4)), np.array([1.0, 0.5]), 1),
]


def prepared(state0, targets, last, segment, settings=SETTINGS):
    return _prepare(jnp.asarray(state0), jnp.asarray(ROUTE), jnp.asarray(targets), jnp.asarray(last),
                    jnp.asarray(segment, jnp.int32), LAND, BUF, SmoothWeights(), MODEL, settings=settings, n_starts=1)


def line_waypoints(p0, p_end):
    d = np.asarray(p_end) - np.asarray(p0)
    t = d / np.hypot(*d)
    return np.array([p0, p0 + LINE_LENGTH * t])


@pytest.mark.parametrize("k", range(len(SITUATIONS)))
def test_warm_start_reproduces_psi_in_the_terminal_los_frame(k):
    state0, targets, last, segment = SITUATIONS[k]
    prep = prepared(state0, targets, last, segment)
    n = SETTINGS.n_mpc
    psi = np.asarray(prep.init.psi)
    route_u = np.asarray(prep.init.controls)
    assert not bool(prep.frame.route_frame)
    # the oracle's re-expression (plain loops) equals the device's
    want = RS.terminal_los_offsets(psi, route_u[:, 1], ROUTE, segment, n, MODEL.lookahead, MODEL.R_a)
    warm = np.asarray(prep.starts[0])
    np.testing.assert_allclose(warm[:, 1], want, atol=1e-10)
    np.testing.assert_array_equal(warm[:, 0], route_u[:n, 0])
    assert np.max(np.abs(want - route_u[:n, 1])) > 1e-3          # the frames do differ here
    # the NumPy LOS rollout on the line reproduces Ψ
    lw = line_waypoints(psi[0, :2], psi[n, :2])
    traj = np_los_rollout(psi[0], lw, want, MODEL.U_d * route_u[:n, 0], 0.0, MODEL.lookahead, MODEL.R_a,
                          MODEL.T_chi, MODEL.T_U, SETTINGS.dt, n)
    np.testing.assert_allclose(traj[:, :2], psi[:n + 1, :2], atol=1e-9)
    np.testing.assert_allclose(np.cos(traj[:, 2] - psi[:n + 1, 2]), 1.0, atol=1e-15)
    np.testing.assert_allclose(traj[:, 3], psi[:n + 1, 3], atol=1e-12)
    # ... and so does the device rollout in the DOCP's frame: the terminal equality and the corridor hold
    states = rollout_controls(prep.args.state0, prep.args.path, prep.starts[0], MODEL, SETTINGS.dt,
                              z0=prep.args.segment)
    np.testing.assert_allclose(np.asarray(states)[:, :2], psi[:n + 1, :2], atol=1e-9)
    _, eq, ineq = problem(SETTINGS)
    assert np.max(np.abs(np.asarray(eq(prep.starts[0], prep.args)))) <= 1e-9
    assert np.max(np.asarray(ineq(prep.starts[0], prep.args))[:2 * n]) <= 1e-9          # the corridor part
    # the applied offset carried into the frame at τ₀
    chi_r = RS.route_los_courses(state0[None, :2], ROUTE, segment, MODEL.lookahead, MODEL.R_a)[0]
    chi_l = RS.line_los_courses(state0[None, :2], psi[0, :2], psi[n, :2], psi[0, 2], MODEL.lookahead)[0]
    assert abs(float(prep.args.last[1]) - (last[1] + RS.wrap_pm_pi(chi_r - chi_l))) <= 1e-10
    assert float(prep.args.last[0]) == last[0]
    # back to the route frame: the init stage's offsets again
    back = to_route_frame(prep.starts[0], prep.args.state0, prep.frame, MODEL, SETTINGS)
    np.testing.assert_allclose(np.asarray(back), route_u[:n], atol=1e-9)


def test_applied_sequence_gives_the_planned_trajectory_on_the_route():
    state0, targets, last, segment = SITUATIONS[0]
    st = smooth_sbmpc_step(state0, ROUTE, targets, last, LAND, BUF, settings=SETTINGS)
    n = SETTINGS.n_mpc
    assert not bool(st.route_frame)
    psi = np.asarray(st.init.psi)
    lw = line_waypoints(psi[0, :2], psi[n, :2])
    u_docp = np.asarray(st.docp_controls)
    plan = np_los_rollout(state0, lw, u_docp[:, 1], MODEL.U_d * u_docp[:, 0], 0.0, MODEL.lookahead, MODEL.R_a,
                          MODEL.T_chi, MODEL.T_U, SETTINGS.dt, n)
    u = np.asarray(st.controls)
    applied = np_los_rollout(state0, ROUTE[segment:], u[:, 1], MODEL.U_d * u[:, 0], 0.0, MODEL.lookahead, MODEL.R_a,
                             MODEL.T_chi, MODEL.T_U, SETTINGS.dt, n)
    np.testing.assert_allclose(applied[:, :2], plan[:, :2], atol=1e-9)
    np.testing.assert_array_equal(np.asarray(st.apply), u[0])
    # never worse than its warm start, feasible, on every situation (the defaults: terminal LOS, continuous)
    for state0, targets, last, segment in SITUATIONS:
        st = smooth_sbmpc_step(state0, ROUTE, targets, last, LAND, BUF, settings=SETTINGS, segment=segment)
        assert float(st.violation) <= 1e-3
        assert float(st.cost) <= float(st.warm_cost) * (1 + 1e-12) + 1e-12


def test_route_los_is_the_route_frame():
    state0, targets, last, segment = SITUATIONS[1]
    s = SmoothSettings(T_init=16.0, T_mpc=8.0, dt=1.0, n_y=51, chi_d_mode="route_los")
    prep = prepared(state0, targets, last, segment, settings=s)
    n = s.n_mpc
    assert bool(prep.frame.route_frame)
    np.testing.assert_array_equal(np.asarray(prep.starts[0]), np.asarray(prep.init.controls[:n]))
    np.testing.assert_array_equal(np.asarray(prep.args.last), last)
    for a, b in zip(prep.args.path, route_path(jnp.asarray(ROUTE))):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    back = to_route_frame(prep.starts[0], prep.args.state0, prep.frame, MODEL, s)
    np.testing.assert_allclose(np.asarray(back), np.asarray(prep.init.controls[:n]), atol=1e-12)


def test_offsets_outside_the_box_send_the_update_to_the_route_frame():
    """Ψ holds +86° while Ψ_N lies 30° to port of the route: re-expressed, the offset would be ~116°."""
    n = SETTINGS.n_mpc
    psi = np.zeros((SETTINGS.n_init + 1, 4))
    psi[:, 0] = np.arange(SETTINGS.n_init + 1) * math.cos(-0.52)
    psi[:, 1] = np.arange(SETTINGS.n_init + 1) * math.sin(-0.52)
    psi[:, 3] = 1.0
    controls = np.tile([1.0, 1.5], (SETTINGS.n_init, 1))
    init = InitResult(jnp.asarray(psi), jnp.asarray(controls), jnp.zeros(SETTINGS.n_init),
                      jnp.zeros(SETTINGS.n_init, jnp.int32), jnp.zeros(SETTINGS.n_init + 1, jnp.int32), jnp.zeros(39))
    route = jnp.asarray([[0.0, 0.0], [100.0, 0.0]])
    frame = docp_frame(init, jnp.asarray(psi[0]), jnp.asarray([1.0, 0.0]), route, 0, MODEL, SETTINGS)
    assert bool(frame.route_frame)
    np.testing.assert_array_equal(np.asarray(frame.warm), controls[:n])
    np.testing.assert_array_equal(np.asarray(frame.last), [1.0, 0.0])
    # a milder Ψ fits: the line frame
    init2 = init._replace(controls=jnp.asarray(np.tile([1.0, 0.3], (SETTINGS.n_init, 1))))
    frame2 = docp_frame(init2, jnp.asarray(psi[0]), jnp.asarray([1.0, 0.0]), route, 0, MODEL, SETTINGS)
    assert not bool(frame2.route_frame)
    assert np.all(np.abs(np.asarray(frame2.warm)[:, 1]) <= math.pi / 2)


def test_los_courses_match_the_oracle_across_waypoint_switches():
    rng = np.random.default_rng(4)
    xy = np.stack([np.linspace(-5, 150, 60), rng.uniform(-6, 12, 60)], axis=1)
    for z0 in (0, 1, 2):
        chi, _ = los_courses(route_path(jnp.asarray(ROUTE)), jnp.asarray(xy), z0, MODEL.lookahead, MODEL.R_a)
        want = RS.route_los_courses(xy, ROUTE, z0, MODEL.lookahead, MODEL.R_a)
        np.testing.assert_allclose(np.asarray(chi), want, atol=1e-12)


# ================================================================================ settings
@pytest.mark.parametrize("kw, match", [
    (dict(chi_d_mode="segment"), r"chi_d_mode must be one of \('terminal_los', 'route_los'\)"),
    (dict(corridor_land_buffer=-1.0), "corridor_land_buffer must be a finite number >= 0"),
    (dict(corridor_land_buffer=float("nan")), "corridor_land_buffer must be a finite number >= 0"),
    (dict(corridor_check="sometimes"), r"corridor_check must be one of \('continuous', 'samples'\)"),
])
def test_bad_settings_are_refused(kw, match):
    with pytest.raises(ValueError, match=match):
        SmoothSettings(**kw)


@pytest.mark.parametrize("d, match", [
    ({"chi_d_mode": "segment"}, r"mpc.smooth.chi_d_mode must be one of terminal_los, route_los"),
    ({"corridor_land_buffer_m": -2}, r"mpc.smooth.corridor_land_buffer_m must be >= 0"),
    ({"corridor_check": "never"}, r"mpc.smooth.corridor_check must be one of continuous, samples"),
    ({"targets": True}, r"mpc.smooth.targets must be one of tracks, true_states"),
])
def test_bad_yaml_values_name_the_key(d, match):
    with pytest.raises(ValueError, match=match):
        parse_smooth(d)


def test_defaults_and_record():
    from psbmpc_jax.methods.builtin import SmoothSbmpc
    from psbmpc_jax.scenario import load_scenario

    spec = parse_smooth({})
    assert (spec.chi_d_mode, spec.corridor_land_buffer, spec.corridor_check, spec.targets) == (
        "terminal_los", 4.0, "continuous", "tracks")
    spec = parse_smooth({"chi_d_mode": "route_los", "corridor_land_buffer_m": 5, "corridor_check": "samples",
                         "targets": "true_states"})
    assert (spec.chi_d_mode, spec.corridor_land_buffer, spec.corridor_check, spec.targets) == (
        "route_los", 5.0, "samples", "true_states")
    with pytest.warns(Warning):
        sc = load_scenario("smooth_000_reconstruction")
    rec = SmoothSbmpc().record(sc)
    assert rec["smooth"]["chi_d_mode"] == "terminal_los" and rec["smooth"]["corridor_land_buffer"] == 4.0
    assert "chi_d_mode='terminal_los'" in repr(rec["resolved"]) or rec["resolved"]["settings"]["chi_d_mode"] == \
        "terminal_los"
