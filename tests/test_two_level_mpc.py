"""The upper level of the two-level MPC (psbmpc_jax/two_level/path_mpc.py): RK4 rollout and cost against
float64 NumPy, gradients against central differences, the closed loop on a straight channel (reaches the
waypoint inside the corridor) and around a static circle, no recompilation for new values, bad input."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from psbmpc_jax.two_level import path_mpc as pm
from psbmpc_jax.two_level.path_mpc import (PathMpcData, PathMpcSettings, make_circles, make_legs, path_coordinates,
                                           rk4_step, solve_path_mpc)

from conftest import central_difference
from psbmpc_jax.status import Status

SET = PathMpcSettings(N_p=20, U_max=4.0)


def np_rollout(x0, u, s: PathMpcSettings):
    def f(x, uk):
        w = math.atan2(math.sin(uk[0] - x[2]), math.cos(uk[0] - x[2]))
        return np.array([x[3] * math.cos(x[2]), x[3] * math.sin(x[2]), w / s.T_chi, (uk[1] - x[3]) / s.T_U])
    xs, x, h = [np.array(x0, float)], np.array(x0, float), s.dt / s.rk4_substeps
    for uk in u:
        for _ in range(s.rk4_substeps):
            k1 = f(x, uk)
            k2 = f(x + h / 2 * k1, uk)
            k3 = f(x + h / 2 * k2, uk)
            k4 = f(x + h * k3, uk)
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        xs.append(x)
    return np.array(xs)


def np_cost(x0, u, u_prev, wp_next, psi, U_ref, s: PathMpcSettings):
    xs = np_rollout(x0, u, s)[1:]
    e = xs - np.array([*wp_next, psi, U_ref])
    e[:, 2] = np.arctan2(np.sin(e[:, 2]), np.cos(e[:, 2]))
    du = np.diff(np.vstack([u_prev, u]), axis=0)
    du[:, 0] = np.arctan2(np.sin(du[:, 0]), np.cos(du[:, 0]))
    return float(np.sum(e * e * np.array(s.Q)) + np.sum(du * du * np.array(s.M)))


def data(x0, u_prev, legs, circles, j=0, U_ref=3.0):
    return PathMpcData(jnp.asarray(x0, float), jnp.asarray(u_prev, float), jnp.asarray(j, jnp.int32),
                       jnp.asarray(U_ref, float), legs, circles)


def test_rollout_and_cost_equal_numpy_and_gradients_equal_central_differences():
    rng = np.random.default_rng(0)
    s = PathMpcSettings(N_p=8, rk4_substeps=2)
    legs = make_legs([[0.0, 0.0], [200.0, 50.0]], half_width=30.0)
    circles = make_circles([[100.0, 40.0]], [10.0])
    for _ in range(3):
        x0 = np.array([*rng.uniform(-20, 20, 2), rng.uniform(-1, 1), rng.uniform(0.5, 4)])
        u = np.stack([rng.uniform(-1.0, 1.5, 8), rng.uniform(0.0, 4.0, 8)], axis=1)
        u_prev = np.array([0.2, 2.0])
        np.testing.assert_allclose(np.asarray(pm.rollout(jnp.asarray(x0), jnp.asarray(u), s)),
                                   np_rollout(x0, u, s), rtol=1e-12, atol=1e-9)
        d = data(x0, u_prev, legs, circles)
        want = np_cost(x0, u, u_prev, [200.0, 50.0], math.atan2(50, 200), 3.0, s)
        assert float(pm.path_mpc_cost(jnp.asarray(u), d, s)) == pytest.approx(want, rel=1e-12)
        for fn in (jax.jit(lambda v: pm.path_mpc_cost(v, d, s)),
                   jax.jit(lambda v: jnp.sum(jnp.sin(pm.path_mpc_ineq(v, d, s))))):
            g = np.asarray(jax.jit(jax.grad(fn))(jnp.asarray(u)))
            np.testing.assert_allclose(g, central_difference(fn, u, 1e-6), rtol=1e-5, atol=1e-6)


def closed_loop(legs, circles, x0, steps, goal, settings=SET):
    x, u_prev, prev, j = np.asarray(x0, float), np.asarray(x0, float)[2:], None, 0
    traj, results = [x.copy()], []
    n_legs = int(legs.psi.shape[0])
    for _ in range(steps):
        r = solve_path_mpc(data(x, u_prev, legs, circles, j), settings, previous=prev)
        results.append(r)
        prev, u_prev = np.asarray(r.u), np.asarray(r.u[0])
        x = np.asarray(rk4_step(jnp.asarray(x), jnp.asarray(u_prev), settings.dt, settings.T_chi, settings.T_U))
        traj.append(x.copy())
        xp, _ = path_coordinates(jnp.asarray(x[:2]), legs.wp[j], legs.psi[j])
        if j < n_legs - 1 and float(xp) >= float(legs.length[j]) - 10.0:
            j += 1
        if np.hypot(*(x[:2] - goal)) < 10.0:
            break
    return np.array(traj), results


def test_straight_channel_reaches_the_waypoint_inside_the_corridor():
    """Start 10 m to starboard of the leg, heading 17° off it, in a ±20 m corridor with a static circle on
    the track line: the ship passes the circle at r + r_os, never leaves the corridor (tolerance 1e-3 m
    plus the model mismatch of one step, here none) and reaches the waypoint."""
    legs = make_legs([[0.0, 0.0], [300.0, 0.0]], half_width=20.0)
    circles = make_circles([[150.0, 0.0]], [12.0])
    compiled_before = pm._solve_jit._cache_size()
    traj, results = closed_loop(legs, circles, [0.0, 10.0, 0.3, 3.0], 160, np.array([300.0, 0.0]))
    assert np.hypot(*(traj[-1, :2] - [300.0, 0.0])) < 10.0
    assert np.max(np.abs(traj[:, 1])) <= 20.0 + 1e-3
    assert np.min(np.hypot(traj[:, 0] - 150.0, traj[:, 1])) >= 12.0 + SET.r_os - 1e-3
    assert all(int(r.status) in (Status.OK, Status.MAX_ITER) and float(r.violation) <= 1e-3 for r in results)
    # no recompilation: every solve after the first reused the compiled solver
    assert pm._solve_jit._cache_size() - compiled_before <= 1


def test_narrow_corridor_bound_is_active_and_held():
    """Start 1 m to starboard heading 20° towards the +3 m bound of a ±3 m corridor: the plans lean on the
    bound (a predicted point on it), the executed track never leaves it."""
    legs = make_legs([[0.0, 0.0], [200.0, 0.0]], half_width=3.0)
    traj, results = closed_loop(legs, make_circles(), [0.0, 1.0, 0.35, 3.0], 80, np.array([200.0, 0.0]))
    assert np.max(np.abs(traj[:, 1])) <= 3.0 + 1e-3
    assert all(float(r.violation) <= 1e-3 for r in results)
    gap = [np.abs(np.asarray(pm.corridor_residuals(r.x[1:, :2], legs, 0))).min() for r in results[:10]]
    assert min(gap) < 1e-2


def test_leg_switching_follows_a_turning_route():
    """Two legs (a 45° turn) in ±20 m corridors: the plan switches frames past the first leg's end and the
    ship reaches the last waypoint without violating either corridor."""
    legs = make_legs([[0.0, 0.0], [150.0, 0.0], [250.0, 100.0]], half_width=20.0)
    traj, results = closed_loop(legs, make_circles(), [0.0, 0.0, 0.0, 3.0], 160, np.array([250.0, 100.0]))
    assert np.hypot(*(traj[-1, :2] - [250.0, 100.0])) < 10.0
    assert all(float(r.violation) <= 1e-3 for r in results)
    # the residuals switch frame: a point 30 m past the corner on leg 1 is judged in leg 1's frame
    p = jnp.asarray([[150.0 + 30 / math.sqrt(2), 30 / math.sqrt(2)]])
    np.testing.assert_allclose(np.asarray(pm.corridor_residuals(p, legs, 0)), [[-20.0, -20.0]], atol=1e-9)


def test_bad_input():
    with pytest.raises(ValueError, match="N_p"):
        PathMpcSettings(N_p=0)
    with pytest.raises(ValueError, match="Q must be 4"):
        PathMpcSettings(Q=(1.0, 2.0))
    with pytest.raises(ValueError, match="chi_span"):
        PathMpcSettings(chi_span=4.0)
    with pytest.raises(ValueError, match="zero length"):
        make_legs([[0.0, 0.0], [0.0, 0.0]])
    with pytest.raises(ValueError, match="lower must be <= 0"):
        make_legs([[0.0, 0.0], [10.0, 0.0]], [(np.array([0.0, 10.0]), np.array([1.0, 1.0]), np.array([2.0, 2.0]))])
    with pytest.raises(ValueError, match="radii"):
        make_circles([[0.0, 0.0]], [-1.0])
    legs = make_legs([[0.0, 0.0], [10.0, 0.0]])
    with pytest.raises(ValueError, match="active leg"):
        solve_path_mpc(data([0, 0, 0, 1], [0, 1], legs, make_circles(), j=3), SET)
    with pytest.raises(ValueError, match="x0 must be"):
        solve_path_mpc(data([0, 0, 0], [0, 1], legs, make_circles()), SET)
    with pytest.raises(ValueError, match="previous must have shape"):
        solve_path_mpc(data([0, 0, 0, 1], [0, 1], legs, make_circles()), SET, previous=np.zeros((3, 2)))
