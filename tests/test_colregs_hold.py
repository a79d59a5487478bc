"""Holding the avoidance heading (docs/colregs_option.md, "The held heading"): ``hold_path`` (the path term's
course-deviation part weighted off while a target is engaged and none is one to stand on for) against its float64 oracle (H_p of
:mod:`psbmpc_jax.reference` with K_chi = 0) and finite differences, and through the grid search's evaluator;
``freeze_course`` (:mod:`psbmpc_jax.methods.colregs_hold`): the hold condition against the float64 oracle, the
moved route by hand, and in closed loop the give-way vessel's avoidance heading held (it drifts back under LOS
guidance without it)."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from psbmpc_jax import reference_colregs_option as ref
from psbmpc_jax.behaviours import enumerate_behaviours_deg
from psbmpc_jax.costs import colregs_option as co
from psbmpc_jax.evaluate import DEFAULT_TERMS, evaluate
from psbmpc_jax.packing import pack
from psbmpc_jax.params import Params, PlannerConfig
from psbmpc_jax.reference import path_cost as ref_path_cost
from psbmpc_jax.methods.colregs_hold import engaged_now, frozen_reference
from psbmpc_jax.methods.colregs_option_settings import ColregsOptionSpec
from psbmpc_jax.scenario.load import scenario_from_dict
from psbmpc_jax.sim.simulator import simulate
from psbmpc_jax.situation import Obstacle, OwnShip, Situation

SPEC = ColregsOptionSpec(enabled=True, freeze_course=True)
THRESH = dict(engage=SPEC.engage_radii, act_cpa=SPEC.act_cpa_radii, act_range=SPEC.act_range_radii,
              clear=SPEC.clear_radii)


# ------------------------------------------------------------------------------------------ hold_path
PARAMS = Params(K_chi_port=6.0, K_chi_stbd=1.5, K_dchi_port=1.3, K_dchi_stbd=1.0, K_u=6.3, K_du=3.6)


def oracle_held_path(offsets, last, engaged):
    """Float64: H_p of every behaviour, with K_chi_port = K_chi_stbd = 0 while engaged."""
    p = PARAMS.replace(K_chi_port=0.0, K_chi_stbd=0.0) if engaged else PARAMS
    return np.array([ref_path_cost(b, last, p) for b in np.asarray(offsets, float)])


@pytest.mark.parametrize("n_m", [1, 3])
@pytest.mark.parametrize("engaged", [False, True])
def test_held_path_equals_the_oracle(n_m, engaged):
    rng = np.random.default_rng(n_m + 10 * engaged)
    offsets = np.stack([rng.uniform(0, 1, (40, n_m)), rng.uniform(-1.5, 1.5, (40, n_m))], axis=-1)
    last = np.array([0.5, 0.4])
    got = np.asarray(co.held_path_cost(jnp.asarray(offsets), jnp.asarray(last), PARAMS, jnp.asarray(engaged)))
    assert got.dtype == np.float64                                   # tests/conftest.py enables x64
    np.testing.assert_allclose(got, oracle_held_path(offsets, last, engaged), rtol=1e-12, atol=1e-12)
    if engaged:           # it is the published H_p less the course-deviation part: lower wherever chi != 0
        assert np.all(got < oracle_held_path(offsets, last, False))


def test_held_path_gradients_equal_finite_differences():
    rng = np.random.default_rng(5)
    x = jnp.asarray(np.stack([rng.uniform(0.1, 0.9, (1, 3)), rng.uniform(0.1, 1.2, (1, 3))
                              * rng.choice([-1, 1], (1, 3))], axis=-1))
    last = jnp.asarray([0.7, -0.3])
    for engaged in (False, True):
        fn = jax.jit(lambda z, engaged=engaged: co.held_path_cost(z, last, PARAMS, jnp.asarray(engaged))[0])
        g = np.asarray(jax.grad(fn)(x))
        for idx in np.ndindex(*x.shape):
            h = 1e-6
            e = np.zeros(x.shape)
            e[idx] = h
            fd = (float(fn(x + e)) - float(fn(x - e))) / (2 * h)
            assert g[idx] == pytest.approx(fd, rel=1e-6, abs=1e-8), (engaged, idx)


def test_held_path_through_the_evaluator_and_only_with_the_option():
    """One packed solve with an engaged give-way target: the ``path`` column is H_p with K_chi = 0 (the oracle),
    the other published columns unchanged; out of range, or with a target to stand on for, it is the published
    H_p."""
    config = PlannerConfig(T=10.0, dt=1.0, dtype="float64")
    behaviours = enumerate_behaviours_deg(((1.0, 0.5), (1.0,)), ((-45, -15, 0, 15, 45), (-15, 0, 15)))
    own = OwnShip(state=np.array([0.0, 0.0, 0.0, 2.0]), waypoints=np.array([[0.0, 0.0], [1000.0, 0.0]]),
                  U_d=2.0, length=5.0, width=2.0)
    last = jnp.asarray([1.0, math.radians(30)])
    spec = ColregsOptionSpec(enabled=True)
    terms = co.with_held_path(DEFAULT_TERMS, spec)
    assert [t.name for t in terms] == [t.name for t in DEFAULT_TERMS]
    assert isinstance(terms[3], co.HeldPathTerm) and terms[:3] == DEFAULT_TERMS[:3]
    assert co.with_held_path(DEFAULT_TERMS, ColregsOptionSpec(enabled=True, hold_path=False)) == DEFAULT_TERMS
    assert co.with_held_path(DEFAULT_TERMS, ColregsOptionSpec()) == DEFAULT_TERMS
    n_b = len(behaviours)
    # R = 5 + 5 = 10 m. Head-on at 10 R: engaged, the own-ship gives way (held); at 500 R: not engaged; crossing
    # from port at 14 R: engaged, but the own-ship stands on (the published weights)
    for state, engaged in (([100.0, 0.0, -2.0, 0.0], True), ([5000.0, 0.0, -2.0, 0.0], False),
                           ([100.0, -100.0, 0.0, 2.0], False)):
        target = Obstacle(state=np.array(state), cov=np.eye(4), length=5.0, width=2.0, n_ps=1)
        inputs = pack(Situation(own, (target,), ()), behaviours, config)
        ev = evaluate(inputs, last, PARAMS, None, config, terms)
        if engaged:
            base = evaluate(inputs, last, PARAMS, None, config, DEFAULT_TERMS)
            for k in ("do", "colregs", "so"):
                np.testing.assert_array_equal(np.asarray(ev.costs[k]), np.asarray(base.costs[k]))
        want = oracle_held_path(np.asarray(behaviours), np.asarray(last), engaged)
        np.testing.assert_allclose(np.asarray(ev.costs["path"])[:n_b], want, rtol=1e-12, atol=1e-12)


def test_closed_loop_hold_path_keeps_the_starboard_offset_until_past():
    """The give-way own-ship with a heavy starboard course weight (K_chi_stbd 20): with ``hold_path`` the offset
    costs nothing while the target is engaged, so it turns 60 deg to starboard and keeps that offset at every
    update until the target is past and clear, then returns in one step; without it the published weight makes a
    port turn cheaper, and it passes closer."""
    runs = {}
    for hp in (True, False):
        d = give_way(False)
        d["mpc"]["colregs_option"]["hold_path"] = hp
        d["mpc"]["params"] = {"K_chi_stbd": 20.0}
        d["simulation"]["duration_s"] = 100
        runs[hp] = simulate(scenario_from_dict(d), batch="loop")
    res = runs[True]
    own, ts = res.states[0, 0], res.states[0, 1]
    dist = np.hypot(*(ts[:, :2] - own[:, :2]).T)
    chi = res.offsets[0, 0, :, 1]
    first = int(np.argmax(chi != 0.0))
    back = first + int(np.argmax(chi[first:] == 0.0))
    assert back > first + 8 and np.all(chi[first:back] >= math.radians(60.0) - 1e-9)     # held, then one return
    # the return comes once the target is past and clear: the range opening (at the update) and above 4 R_i
    k = int(np.searchsorted(res.t, res.solve_t[back]))
    vel = lambda s: s[3] * np.array([math.cos(s[2]), math.sin(s[2])])       # noqa: E731
    assert np.dot(ts[k, :2] - own[k, :2], vel(ts[k]) - vel(own[k])) > 0 and dist[k] > 4 * 10.0
    # ... and not one update earlier
    k0 = int(np.searchsorted(res.t, res.solve_t[back - 1]))
    assert np.dot(ts[k0, :2] - own[k0, :2], vel(ts[k0]) - vel(own[k0])) < 0 or dist[k0] <= 4 * 10.0
    assert dist.min() > 4 * 10.0
    off = runs[False]
    assert np.min(off.offsets[0, 0, :, 1]) < 0.0                      # the published weight: a port turn
    assert np.hypot(*(off.states[0, 1, :, :2] - off.states[0, 0, :, :2]).T).min() < dist.min()


# ------------------------------------------------------------------------------------------ freeze_course
def test_engaged_now_equals_the_oracle_over_random_situations():
    rng = np.random.default_rng(3)
    d_safe, seen = 5.0, {True: 0, False: 0}
    for _ in range(200):
        chi0, u0 = rng.uniform(-math.pi, math.pi), rng.uniform(0.5, 4.0)
        own = OwnShip(state=np.array([10.0, -20.0, chi0, u0]), waypoints=np.array([[0.0, 0.0], [500.0, 300.0]]),
                      U_d=u0, length=6.0, width=2.0)
        obs = []
        for _ in range(int(rng.integers(1, 4))):
            r, b = rng.uniform(5.0, 700.0), rng.uniform(-math.pi, math.pi)
            c, s = rng.uniform(-math.pi, math.pi), rng.uniform(0.0, 4.0)
            obs.append(Obstacle(state=np.array([10 + r * math.cos(b), -20 + r * math.sin(b), s * math.cos(c),
                                                s * math.sin(c)]), cov=np.eye(4), length=rng.uniform(2, 20),
                                width=2.0, n_ps=1))
        sit = Situation(own, tuple(obs), ())
        rows = [(o.state[0], o.state[1], o.state[2], o.state[3], d_safe + 0.5 * (own.length + o.length), True)
                for o in obs]
        want = any(f["engaged"] for f in ref.encounter((10.0, -20.0), chi0, u0, rows, **THRESH))
        got = engaged_now(sit, d_safe, SPEC)
        assert got == want
        seen[got] += 1
    assert min(seen.values()) > 20, seen                      # both outcomes exercised
    assert engaged_now(Situation(own, (), ()), d_safe, SPEC) is False


def test_frozen_reference_moves_the_route_onto_the_ship():
    # leg from (0, 0) heading 045 deg; the ship 30 m to starboard of it
    a = math.radians(45.0)
    p = np.array([100 * math.cos(a), 100 * math.sin(a)]) + 30.0 * np.array([-math.sin(a), math.cos(a)])
    own = OwnShip(state=np.array([p[0], p[1], a + 0.5, 3.0]),
                  waypoints=np.array([[0.0, 0.0], [400 * math.cos(a), 400 * math.sin(a)], [500.0, 0.0]]), U_d=3.0)
    sit, alpha = frozen_reference(Situation(own, (), ()))
    assert alpha == pytest.approx(a, abs=1e-12)
    moved = sit.own_ship.waypoints
    np.testing.assert_allclose(moved - own.waypoints, np.tile(30.0 * np.array([-math.sin(a), math.cos(a)]),
                                                              (3, 1)), atol=1e-9)
    # the ship lies on the moved first leg: zero cross-track error
    d = moved[1] - moved[0]
    e = -(p[0] - moved[0, 0]) * d[1] / np.hypot(*d) + (p[1] - moved[0, 1]) * d[0] / np.hypot(*d)
    assert abs(e) < 1e-9
    np.testing.assert_array_equal(sit.own_ship.state, own.state)
    assert sit.own_ship.U_d == own.U_d


def give_way(freeze: bool) -> dict:
    """The own-ship (OS) heads north on a collision course with TS1 crossing from its starboard side: OS gives
    way.  TS1 runs no method.  60 s."""
    return {"name": "gw_hold", "simulation": {"dt_s": 0.5, "duration_s": 60},
            "monte_carlo": {"runs": 1, "seed": 0},
            "mpc": {"preset": "nidelva", "update_period_s": 5, "n_ps": 1, "config": {"T": 60.0, "dt": 1.0},
                    "speed_factors": [[1.0]], "course_offsets_deg": [[-30, 0, 30, 60]],
                    "colregs_option": {"enabled": True, "freeze_course": freeze}},
            "own_ship": {"name": "OS", "position_m": [0, 0], "course_deg": 0, "speed_mps": 2,
                         "waypoints_m": [[0, 0], [1000, 0]]},
            "targets": [{"name": "TS1", "position_m": [150, 150], "course_deg": 270, "speed_mps": 2,
                         "waypoints_m": [[150, 150], [150, -800]], "colav": "none"}]}


def test_closed_loop_the_avoidance_heading_is_held_and_drifts_back_without():
    held = simulate(scenario_from_dict(give_way(True)), batch="loop")
    los = simulate(scenario_from_dict(give_way(False)), batch="loop")
    for res in (held, los):       # both turn to starboard by a readily apparent offset within 10 s (the tracker
        assert np.max(res.offsets[0, 0, :3, 1]) >= math.radians(30.0)      # needs a few measurements first)
    # with the frozen reference the heading settles at the route direction (0) plus the applied offset, within
    # the autopilot's lag, at every step of every update period from 15 s on while the offset is kept
    own = held.states[0, 0]
    chi_off = held.offsets[0, 0, :, 1]
    k_upd = np.searchsorted(held.solve_t, held.t, side="right") - 1
    late = (held.t >= 15.0) & (held.t <= 45.0)
    steady = late & np.r_[True, np.diff(chi_off[k_upd]) == 0]
    err = np.degrees(np.abs(own[steady, 2] - chi_off[k_upd[steady]]))
    assert steady.sum() > 20 and err.max() < 3.0, err.max()
    # under LOS guidance the same offset leaves the heading short of it, more so as the cross-track error grows
    own_l = los.states[0, 0]
    chi_l = los.offsets[0, 0, :, 1]
    k_l = np.searchsorted(los.solve_t, los.t, side="right") - 1
    gap = np.degrees(chi_l[k_l] - own_l[:, 2])
    assert gap[(los.t >= 30.0) & (los.t <= 45.0)].max() > 10.0
    # the held ship is farther off its route (east) at the end of the window: it kept its avoidance heading
    assert held.states[0, 0, int(np.searchsorted(held.t, 45.0)), 1] > los.states[0, 0, int(np.searchsorted(los.t, 45.0)), 1]
