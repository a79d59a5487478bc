"""Tests of the jitted JAX evaluator and the host-side planner API against the float64 NumPy reference.

Compile budget: most tests pack situations to the fixed capacities ``conftest.CAPS`` (``fixed_caps``
fixture) and use the small two-maneuver table ``SMALL_BEHAVIOURS`` with T = 30 s, dt = 0.5 s, so that all
random situations share one compiled evaluator per (estimator, dtype, layout) config.
"""

from __future__ import annotations

import itertools
import math
import os
import subprocess
import sys
import textwrap
from dataclasses import replace
from functools import lru_cache, partial

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import psbmpc_jax
from psbmpc_jax import (
    Obstacle,
    OwnShip,
    Params,
    Planner,
    PlannerConfig,
    PlannerState,
    PlanResult,
    Situation,
    enumerate_behaviours,
    enumerate_behaviours_deg,
    evaluate,
    pack,
    paper_behaviours,
)
from psbmpc_jax import reference as ref_mod
from psbmpc_jax import reference_prediction as pred
from psbmpc_jax.costs import collision as col
from psbmpc_jax.evaluate import Evaluation, evaluate_arrays
from psbmpc_jax.packing import SolveInputs
from psbmpc_jax.solve import solve
from psbmpc_jax.examples import paper_head_on
from psbmpc_jax.obstacles import obstacle_covariances, ou_covariance
from psbmpc_jax.packing import bucket, bucket_behaviours, bucket_scenarios, unpack

from conftest import CAPS, SMALL_BEHAVIOURS, pad_arrays, random_situation

TERMS = ("total", "do", "colregs", "so", "path")
ESTIMATORS = ("quadrature", "mc", "ce")
# 3 obstacles (2 with routes) + 2 polygons / 2 obstacles / 2 obstacles + 1 polygon / 3-waypoint own route,
# 1 obstacle with a route, 2 polygons
SEEDS = (0, 2, 4, 5)
BASE = dict(T=30.0, dt=0.5, n_samples=128)
RTOL, ATOL = 1e-5, 1e-9


def cfg64(estimator: str = "quadrature", **kw) -> PlannerConfig:
    return PlannerConfig(dtype="float64", estimator=estimator, **{**BASE, **kw})


def key_for(seed: int):
    return jax.random.key(1000 + seed)


def table64(estimator: str, seed: int, config: PlannerConfig | None = None):
    """The common-random-number table the planner draws for ``key_for(seed)``, as float64 NumPy."""
    config = config or cfg64(estimator)
    z = col.standard_normal_table(key_for(seed), config, jnp.float64)
    return None if z is None else np.asarray(z, dtype=np.float64)


@lru_cache(maxsize=None)
def reference(seed: int, estimator: str, last: tuple = (1.0, 0.0)) -> ref_mod.ReferenceResult:
    cfg = cfg64(estimator)
    return ref_mod.evaluate_reference(random_situation(seed), SMALL_BEHAVIOURS, Params(), cfg, last_offsets=last,
                                      samples=table64(estimator, seed))


def assert_traj_close(got, want, rtol=1e-9, atol=1e-8):
    """[..., 4] trajectories (x, y, chi, U), courses included (both keep the initial course as given and
    wrap every later one to [-pi, pi))."""
    got, want = np.asarray(got), np.asarray(want)
    assert got.shape == want.shape
    np.testing.assert_allclose(got, want, rtol=rtol, atol=atol)


def assert_costs_close(got: dict, want, rtol=RTOL, atol=ATOL):
    for term in TERMS:
        w = want[term] if isinstance(want, dict) else getattr(want, term)
        np.testing.assert_allclose(got[term], w, rtol=rtol, atol=atol, err_msg=term)


def assert_results_equal(a: PlanResult, b: PlanResult, rtol=1e-12, atol=1e-12):
    """Two PlanResults of the same situation agree (to float64 round-off)."""
    assert a.best_index == b.best_index
    np.testing.assert_array_equal(a.offsets, b.offsets)
    assert_costs_close(a.costs, b.costs, rtol=rtol, atol=atol)
    for ca, cb in zip(a.collision_cost, b.collision_cost, strict=True):
        np.testing.assert_allclose(ca, cb, rtol=rtol, atol=atol)
    for ma, mb in zip(a.colregs_indicator, b.colregs_indicator, strict=True):
        np.testing.assert_array_equal(ma, mb)
    np.testing.assert_allclose(a.grounding_per_polygon, b.grounding_per_polygon, rtol=rtol, atol=atol)
    assert_traj_close(a.own_trajectories, b.own_trajectories, rtol=rtol, atol=atol)


def plan64(seed: int, estimator: str, **cfg_kw) -> PlanResult:
    planner = Planner(cfg64(estimator, **cfg_kw), behaviours=SMALL_BEHAVIOURS)
    result, _ = planner.plan(random_situation(seed), key=key_for(seed))
    return result


# ============================================================================ JAX evaluator == reference
@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("estimator", ESTIMATORS)
def test_evaluator_matches_reference(fixed_caps, estimator, seed):
    sit = random_situation(seed)
    res = plan64(seed, estimator)
    ref = reference(seed, estimator)
    B = len(SMALL_BEHAVIOURS)
    # the situation is an interacting one (otherwise the comparison would be vacuous)
    assert np.any(ref.do > 0) and res.n_pc_blocks > 0
    assert_costs_close(res.costs, ref)
    for term in TERMS:
        assert res.costs[term].shape == (B,)
    assert len(res.collision_cost) == len(sit.obstacles)
    for i, ob in enumerate(sit.obstacles):
        assert res.collision_cost[i].shape == (B, ob.n_ps)
        np.testing.assert_allclose(res.collision_cost[i], ref.C[i], rtol=RTOL, atol=ATOL)
        np.testing.assert_array_equal(res.colregs_indicator[i], ref.mu[i])
        assert_traj_close(res.obstacle_trajectories[i], ref.obs_traj[i])
    np.testing.assert_allclose(res.grounding_per_polygon, ref.so_j, rtol=RTOL, atol=ATOL)
    assert_traj_close(res.own_trajectories, ref.own_traj)
    # argmin: identical to the reference, equal to a brute-force argmin (ties -> lowest index)
    assert res.best_index == ref.best
    assert res.best_index == int(np.argmin(res.costs["total"]))
    np.testing.assert_array_equal(res.offsets, SMALL_BEHAVIOURS[res.best_index])
    assert (res.u_opt, res.chi_opt) == tuple(SMALL_BEHAVIOURS[res.best_index, 0])


def test_evaluator_matches_reference_natural_buckets_and_obstacle_covariances():
    """Planner.plan with the package's own bucketing (no fixed caps; n_ps = 11 -> 16 scenario slots),
    plus obs_cov from the raw Evaluation."""
    base = random_situation(0)
    rng = np.random.default_rng(11)
    obstacles = (replace(base.obstacles[0], n_ps=11, probs=rng.dirichlet(np.ones(11))),
                 replace(base.obstacles[1], n_ps=7, probs=None)) + base.obstacles[2:]
    sit = Situation(base.own_ship, obstacles, base.polygons)
    planner = Planner(cfg64("quadrature"), behaviours=SMALL_BEHAVIOURS)
    res, state = planner.plan(sit)
    ref = ref_mod.evaluate_reference(sit, SMALL_BEHAVIOURS, Params(), cfg64("quadrature"))
    assert_costs_close(res.costs, ref)
    assert res.best_index == ref.best
    for i in range(len(sit.obstacles)):
        np.testing.assert_allclose(res.collision_cost[i], ref.C[i], rtol=RTOL, atol=ATOL)
        np.testing.assert_array_equal(res.colregs_indicator[i], ref.mu[i])
        assert_traj_close(res.obstacle_trajectories[i], ref.obs_traj[i])
    arrays, state, p, samples = planner.prepare(sit)
    assert arrays.obstacles.probs.shape == (4, 16)
    ev = evaluate(arrays, state.last_offsets, p, samples, config=planner.config)
    for i in range(len(sit.obstacles)):
        np.testing.assert_allclose(np.asarray(ev.obs_cov[i]), ref.obs_cov[i], rtol=1e-12, atol=1e-14)
    # padded behaviours cost +inf and are never chosen
    assert np.all(np.isinf(np.asarray(ev.total)[len(SMALL_BEHAVIOURS):]))
    np.testing.assert_array_equal(np.asarray(ev.best_offsets), np.asarray(arrays.behaviours.offsets)[int(ev.best)])


NONDEFAULT = Params(
    os_T_chi=1.3, os_T_U=2.0, os_lookahead=40.0, os_R_a=8.0, ob_T_chi=0.7, ob_T_U=3.0, ob_lookahead=90.0,
    ob_R_a=3.0, r_ct=7.0, sigma_x=0.05, sigma_y=0.03, sigma_xy=0.001, gamma_x=0.2, gamma_y=0.05, t_ts=7.0,
    d_safe=7.0, K_coll=40.0, T_d=60.0, c_sigma=3.0, ce_rho=0.7, ce_alpha=0.6, ce_chi2=9.0, kappa=4.0,
    d_close=60.0, G1=80.0, G2=3.0, G3=0.15, G4=0.02, V_w=3.0, wind_dir=0.7, K_u=4.0, K_du=2.0, K_chi_stbd=1.1,
    K_chi_port=2.2, K_dchi_stbd=0.8, K_dchi_port=1.6)


@pytest.mark.parametrize("estimator", ESTIMATORS)
def test_evaluator_matches_reference_nondefault_params_and_state(fixed_caps, estimator):
    """Every Params field is passed through (per call), plus explicit t_ts, wind, a stationary obstacle and a
    non-default planner state."""
    base = random_situation(5)
    own = base.own_ship
    p_mid = own.state[:2] + 20.0 * np.array([math.cos(own.state[2]), math.sin(own.state[2])])
    still = Obstacle(state=[p_mid[0] + 3.0, p_mid[1] - 2.0, 0.0, 0.0], cov=np.diag([2.0, 3.0, 0.01, 0.01]),
                     n_ps=3, probs=[0.2, 0.5, 0.3], weight=1.3, zeta=0.8)
    closed = np.vstack([base.polygons[0], base.polygons[0][:1]])   # explicitly closed ring: a zero-length edge
    sit = Situation(own, base.obstacles + (still,), (closed,) + base.polygons[1:])
    last = (0.5, -0.3)
    planner = Planner(cfg64(estimator), behaviours=SMALL_BEHAVIOURS)    # constructor params: defaults
    res, _ = planner.plan(sit, PlannerState(last), key=key_for(5), params=NONDEFAULT)
    ref = ref_mod.evaluate_reference(sit, SMALL_BEHAVIOURS, NONDEFAULT, cfg64(estimator), last_offsets=last,
                                     samples=table64(estimator, 5))
    assert np.any(ref.do > 0) and np.any(ref.colregs > 0) and np.ptp(ref.so) > 0
    assert_costs_close(res.costs, ref)
    for i in range(len(sit.obstacles)):
        np.testing.assert_allclose(res.collision_cost[i], ref.C[i], rtol=RTOL, atol=ATOL)
        np.testing.assert_array_equal(res.colregs_indicator[i], ref.mu[i])
        assert_traj_close(res.obstacle_trajectories[i], ref.obs_traj[i])
    assert_traj_close(res.own_trajectories, ref.own_traj)
    assert res.best_index == ref.best
    # the per-call params really were used (the defaults give other costs)
    default = ref_mod.evaluate_reference(sit, SMALL_BEHAVIOURS, Params(), cfg64(estimator), last_offsets=last,
                                         samples=table64(estimator, 5))
    assert not np.allclose(res.costs["total"], default.total, rtol=1e-3)


# Regression: the initial course used to be wrapped (+pi -> -pi), which flipped the first Euler step's
# rounding and put an exactly-on-track obstacle on the other side of the STARBOARD test.
def test_exact_head_on_on_track_matches_reference(fixed_caps):
    sit = Situation(OwnShip([0.0, 0.0, 0.0, 2.0], [[0.0, 0.0], [100.0, 0.0]], 2.0),
                    (Obstacle([60.0, 0.0, -2.0, 0.0], np.eye(4), n_ps=1),))
    res, _ = Planner(cfg64("quadrature"), behaviours=SMALL_BEHAVIOURS).plan(sit)
    ref = ref_mod.evaluate_reference(sit, SMALL_BEHAVIOURS, Params(), cfg64("quadrature"))
    np.testing.assert_array_equal(res.colregs_indicator[0], ref.mu[0])
    assert_costs_close(res.costs, ref)
    assert res.obstacle_trajectories[0][0, 0, 2] == math.atan2(0.0, -2.0)


def test_empty_situation_costs_only_the_path(fixed_caps):
    own = random_situation(1).own_ship
    planner = Planner(cfg64("quadrature"), behaviours=SMALL_BEHAVIOURS)
    res, _ = planner.plan(Situation(own))
    ref = ref_mod.evaluate_reference(Situation(own), SMALL_BEHAVIOURS, Params(), cfg64())
    assert_costs_close(res.costs, ref)
    for term in ("do", "colregs", "so"):
        assert np.all(res.costs[term] == 0.0)
    assert res.collision_cost == [] and res.grounding_per_polygon.shape == (len(SMALL_BEHAVIOURS), 0)
    assert res.best_index == int(np.argmin(ref.path))


# ============================================================================ float32
@pytest.mark.parametrize("seed", SEEDS)
def test_float32_picks_the_float64_argmin(fixed_caps, seed):
    planner = Planner(PlannerConfig(dtype="float32", **BASE), behaviours=SMALL_BEHAVIOURS)
    arrays, state, p, samples = planner.prepare(random_situation(seed))
    ev = evaluate(arrays, state.last_offsets, p, samples, config=planner.config)
    # no silent promotion to float64 even though x64 is enabled for the session
    for name in ("total", "C", "mu", "so_j", "obs_cov", "best_offsets"):
        assert getattr(ev, name).dtype == jnp.float32, name
    for name in ("do", "colregs", "so", "path"):
        assert ev.costs[name].dtype == jnp.float32, name
    assert ev.own.x.dtype == jnp.float32 and ev.obstacles.x.dtype == jnp.float32
    res, _ = planner.plan(random_situation(seed))
    # the returned offsets are exactly the (float64) table row
    np.testing.assert_array_equal(res.offsets, SMALL_BEHAVIOURS[res.best_index])
    ref = reference(seed, "quadrature")
    scale = np.max(np.abs(ref.total))
    np.testing.assert_allclose(res.costs["total"], ref.total, rtol=2e-4, atol=1e-6 * scale)
    # The argmin should be the same; if a float64 near-tie makes that ill-posed, the float32 choice must at
    # least be optimal to 1e-4 relative in float64.
    if res.best_index != ref.best:
        assert ref.total[res.best_index] <= ref.total[ref.best] * (1 + 1e-4), (res.best_index, ref.best)
    else:
        assert res.best_index == ref.best


# Regression: plan() used to build the next state from the float32-rounded offset (float32(pi) > pi).
def test_float32_plan_with_course_offset_pi(fixed_caps):
    beh = np.array([[[1.0, math.pi], [1.0, math.pi]], [[1.0, -math.pi], [1.0, -math.pi]]])
    planner = Planner(PlannerConfig(dtype="float32", **BASE), behaviours=beh)  # validate_behaviours accepts it
    res, state = planner.plan(random_situation(1))
    assert abs(state.last_offsets[1]) == pytest.approx(math.pi, abs=1e-6)


# ============================================================================ layouts / tiling
LAYOUTS = [
    ("quadrature", dict(pc_layout="dense")),
    ("ce", dict(pc_layout="dense")),
    ("quadrature", dict(time_block=5, chunk_rows=7)),
    ("mc", dict(time_block=128, chunk_rows=2048)),
]


@pytest.mark.parametrize("estimator, layout", LAYOUTS, ids=[f"{e}-{l}" for e, l in LAYOUTS])
def test_layout_and_tiling_do_not_change_results(fixed_caps, estimator, layout):
    for seed in (0, 4):
        base = plan64(seed, estimator)
        other = plan64(seed, estimator, **layout)
        assert_results_equal(other, base)
        if layout.get("pc_layout") != "dense":
            assert other.n_pc_blocks > 0


# ============================================================================ estimators vs quadrature
def _pc_grid():
    rows = []
    covs = [np.array([[4.0, 0.0], [0.0, 4.0]]), np.array([[9.0, 3.0], [3.0, 2.0]]),
            np.array([[0.3, 0.0], [0.0, 4.0]])]
    for R, S, frac, ang in itertools.product((5.0, 10.0), covs, (0.0, 0.5, 1.0, 1.5),
                                             (0.0, math.radians(60), math.radians(135))):
        d = frac * R
        rows.append((d * math.cos(ang), d * math.sin(ang), S[0, 0], S[0, 1], S[1, 1], R))
    # a few tail points (P small but non-zero)
    rows += [(13.0, 0.0, 4.0, 0.0, 4.0, 10.0), (0.0, 15.0, 9.0, 1.0, 4.0, 10.0), (7.0, 4.0, 1.0, 0.2, 1.5, 5.0)]
    return np.array(rows).T


def test_mc_and_ce_agree_with_quadrature_within_sampling_error():
    dx, dy, sxx, sxy, syy, R = (jnp.asarray(v) for v in _pc_grid())
    n = 2000
    p = Params()
    q = np.asarray(col.pc_quadrature(dx, dy, sxx, sxy, syy, R))
    assert q.min() < 0.01 and q.max() > 0.99  # the grid spans small and large probabilities
    z_mc = jax.random.normal(jax.random.key(7), (n, 2), jnp.float64)
    mc = np.asarray(col.pc_mc(dx, dy, sxx, sxy, syy, R, z_mc))
    assert np.all((mc >= 0) & (mc <= 1))
    tol = 4 * np.sqrt(q * (1 - q) / n) + 1e-3
    assert np.all(np.abs(mc - q) <= tol), np.max(np.abs(mc - q) - tol)
    # CE is importance sampling: its error is not binomial (and min(1, .) biases it slightly low as P -> 1),
    # so its sampling error is measured over independent tables: each estimate within 4 empirical standard
    # deviations, the mean within 4 standard errors (+ half a standard deviation for the clipping bias).
    reps = 16
    z_ce = jax.random.normal(jax.random.key(8), (reps, 7, n, 2), jnp.float64)
    ce_fn = lambda z: col.pc_ce(dx, dy, sxx, sxy, syy, R, z, p.ce_rho, p.ce_alpha, p.ce_chi2)
    ce = np.asarray(jax.jit(jax.vmap(ce_fn))(z_ce))
    assert np.all((ce >= 0) & (ce <= 1))
    sd = ce.std(axis=0, ddof=1)
    assert sd.max() < 0.05                                         # a usable estimator at N = 2000
    assert np.all(np.abs(ce - q) <= 4 * np.maximum(sd, np.sqrt(q * (1 - q) / n)) + 1e-3)
    mean_err = np.abs(ce.mean(axis=0) - q)
    assert np.all(mean_err <= 4 * sd / math.sqrt(reps) + 0.5 * sd + 1e-3), np.max(mean_err)
    # the dispatcher routes to the same functions
    for est, z, want in (("mc", z_mc, mc), ("ce", z_ce[0], ce[0]), ("quadrature", None, q)):
        got = col.collision_probability(dx, dy, sxx, sxy, syy, R, p, PlannerConfig(estimator=est, n_samples=n), z)
        np.testing.assert_allclose(np.asarray(got), want, rtol=1e-12, atol=1e-15)


def test_jax_estimators_match_reference_pointwise():
    """Point-by-point: JAX quadrature/mc/ce == reference._pc_* (same tables), on the same grid."""
    dx, dy, sxx, sxy, syy, R = _pc_grid()
    n = 300
    p = Params()
    z_mc = np.asarray(jax.random.normal(jax.random.key(1), (n, 2), jnp.float64))
    z_ce = np.asarray(jax.random.normal(jax.random.key(2), (7, n, 2), jnp.float64))
    J = lambda a: jnp.asarray(a)
    nq, span = PlannerConfig().n_quad, PlannerConfig().quad_span
    q = np.asarray(col.pc_quadrature(J(dx), J(dy), J(sxx), J(sxy), J(syy), J(R), nq, span))
    mc = np.asarray(col.pc_mc(J(dx), J(dy), J(sxx), J(sxy), J(syy), J(R), J(z_mc)))
    ce = np.asarray(col.pc_ce(J(dx), J(dy), J(sxx), J(sxy), J(syy), J(R), J(z_ce), p.ce_rho, p.ce_alpha, p.ce_chi2))
    for k in range(len(dx)):
        S = np.array([[sxx[k], sxy[k]], [sxy[k], syy[k]]])
        mu = (dx[k], dy[k])
        assert q[k] == pytest.approx(ref_mod._pc_quadrature((0, 0), mu, S, R[k], nq, span), rel=1e-9, abs=1e-13)
        assert mc[k] == pytest.approx(ref_mod._pc_mc((0, 0), mu, S, R[k], z_mc), rel=1e-12, abs=1e-12)
        assert ce[k] == pytest.approx(ref_mod._pc_ce((0, 0), mu, S, R[k], z_ce, p), rel=1e-8, abs=1e-12)
    # non-default quadrature nodes / span, CE without refinement iterations and other CE constants
    q2 = np.asarray(col.pc_quadrature(J(dx), J(dy), J(sxx), J(sxy), J(syy), J(R), 10, 4.0))
    p2 = Params(ce_rho=0.5, ce_alpha=0.3, ce_chi2=5.0)
    ce0 = np.asarray(col.pc_ce(J(dx), J(dy), J(sxx), J(sxy), J(syy), J(R), J(z_ce[:1]), 0.9, 0.9, 11.618))
    ce2 = np.asarray(col.pc_ce(J(dx), J(dy), J(sxx), J(sxy), J(syy), J(R), J(z_ce), p2.ce_rho, p2.ce_alpha,
                               p2.ce_chi2))
    assert not np.allclose(q2, q) and not np.allclose(ce0, ce)
    for k in range(len(dx)):
        S = np.array([[sxx[k], sxy[k]], [sxy[k], syy[k]]])
        mu = (dx[k], dy[k])
        assert q2[k] == pytest.approx(ref_mod._pc_quadrature((0, 0), mu, S, R[k], 10, 4.0), rel=1e-9, abs=1e-13)
        assert ce0[k] == pytest.approx(ref_mod._pc_ce((0, 0), mu, S, R[k], z_ce[:1], p), rel=1e-8, abs=1e-12)
        assert ce2[k] == pytest.approx(ref_mod._pc_ce((0, 0), mu, S, R[k], z_ce, p2), rel=1e-8, abs=1e-12)


# ============================================================================ vmap == loop
def test_vmap_over_situations_equals_loop(fixed_caps):
    cfg = cfg64("mc")
    planner = Planner(cfg, behaviours=SMALL_BEHAVIOURS)
    base = random_situation(0)
    states = ([base.own_ship.state[0], base.own_ship.state[1], base.own_ship.state[2], 2.0],
              [base.own_ship.state[0] + 5.0, base.own_ship.state[1] - 3.0, base.own_ship.state[2] + 0.3, 2.5])
    sits = [base] + [replace(base, own_ship=replace(base.own_ship, state=np.array(s))) for s in states]
    sits.append(random_situation(2))  # a different situation padded to the same shapes
    key = key_for(0)
    packed = [planner.prepare(s, key=key) for s in sits]
    last, p, samples = jnp.asarray([1.0, 0.0]), packed[0][2], packed[0][3]
    batch = jax.tree.map(lambda *xs: jnp.stack(xs), *[a for a, _, _, _ in packed])
    batched = jax.jit(jax.vmap(partial(evaluate_arrays, config=cfg), in_axes=(0, None, None, None)))(
        batch, last, p, samples)
    batched_jit = jax.vmap(partial(evaluate, config=cfg), in_axes=(0, None, None, None))(batch, last, p, samples)
    totals = []
    for b, (arrays, _, _, _) in enumerate(packed):
        single = evaluate(arrays, last, p, samples, config=cfg)
        for out in (batched, batched_jit):
            for got, want in zip(jax.tree.leaves(out), jax.tree.leaves(single), strict=True):
                np.testing.assert_allclose(np.asarray(got)[b], np.asarray(want), rtol=1e-12, atol=1e-12)
        totals.append(np.asarray(single.total))
    # the batch members really differ
    assert not np.allclose(totals[0], totals[1]) and not np.allclose(totals[0], totals[3])


def test_vmap_over_params_equals_loop(fixed_caps):
    cfg = cfg64("quadrature")
    planner = Planner(cfg, behaviours=SMALL_BEHAVIOURS)
    arrays, state, p, samples = planner.prepare(random_situation(0))
    last = state.last_offsets
    k_coll = np.array([5.0, 25.0, 80.0])
    p_batch = replace(p, K_coll=jnp.asarray(k_coll))
    axes = jax.tree.map(lambda _: None, p)
    axes = replace(axes, K_coll=0)
    out = jax.vmap(lambda pp: evaluate(arrays, last, pp, samples, config=cfg), in_axes=(axes,))(p_batch)
    for b, kc in enumerate(k_coll):
        single = evaluate(arrays, last, replace(p, K_coll=np.asarray(kc)), samples, config=cfg)
        np.testing.assert_allclose(np.asarray(out.total)[b], np.asarray(single.total), rtol=1e-12, atol=1e-12)
        assert int(out.best[b]) == int(single.best)
    # H_do is linear in K_coll
    np.testing.assert_allclose(np.asarray(out.costs["do"])[2], np.asarray(out.costs["do"])[0] * 16.0, rtol=1e-12, atol=1e-12)


# ============================================================================ padding / permutation invariance
def test_padding_invariance():
    seed = 0
    sit = random_situation(seed)
    cfg = cfg64("quadrature")
    planner = Planner(cfg, behaviours=SMALL_BEHAVIOURS)
    arrays, state, p, samples = planner.prepare(sit)
    last = state.last_offsets
    natural = unpack(evaluate(arrays, last, p, samples, config=cfg), sit, SMALL_BEHAVIOURS, 0.0)
    big = pad_arrays(arrays, O=8, S=7, W=8, Wo=8, P=4, V=32, B=128)
    assert big.obstacles.probs.shape == (8, 7) and big.behaviours.offsets.shape[0] == 128
    for padded in (pad_arrays(arrays, **CAPS), big, pad_arrays(arrays, O=8, S=7, W=8, Wo=8, P=4, V=32, B=128,
                                                               junk=False)):
        ev = evaluate(padded, last, p, samples, config=cfg)
        res = unpack(ev, sit, SMALL_BEHAVIOURS, 0.0)
        assert_results_equal(res, natural)
        for i, ob in enumerate(sit.obstacles):
            assert_traj_close(res.obstacle_trajectories[i], natural.obstacle_trajectories[i], rtol=1e-12, atol=1e-12)
        # padded behaviours are never chosen although their (straight-ahead) path cost is zero
        assert np.all(np.isinf(np.asarray(ev.total)[len(SMALL_BEHAVIOURS):]))
        # padded obstacles / scenarios contribute nothing
        c, mu = np.asarray(ev.C), np.asarray(ev.mu)
        assert np.all(c[:, len(sit.obstacles):] == 0) and np.all(mu[:, len(sit.obstacles):] == 0)
        for i, ob in enumerate(sit.obstacles):
            assert np.all(c[:, i, ob.n_ps:] == 0) and np.all(mu[:, i, ob.n_ps:] == 0)
    ref = reference(seed, "quadrature")
    assert_costs_close(natural.costs, ref)


def test_obstacle_and_polygon_permutation_invariance(fixed_caps):
    seed = 0
    sit = random_situation(seed)
    assert len(sit.obstacles) == 3 and len(sit.polygons) == 2
    perm = (2, 0, 1)
    sit_p = Situation(sit.own_ship, tuple(sit.obstacles[i] for i in perm), sit.polygons[::-1])
    planner = Planner(cfg64("quadrature"), behaviours=SMALL_BEHAVIOURS)
    a, _ = planner.plan(sit)
    b, _ = planner.plan(sit_p)
    assert_costs_close(b.costs, a.costs, rtol=1e-12, atol=1e-12)
    assert b.best_index == a.best_index
    for new, old in enumerate(perm):
        np.testing.assert_allclose(b.collision_cost[new], a.collision_cost[old], rtol=1e-12, atol=1e-12)
        np.testing.assert_array_equal(b.colregs_indicator[new], a.colregs_indicator[old])
    np.testing.assert_allclose(b.grounding_per_polygon, a.grounding_per_polygon[:, ::-1], rtol=1e-12, atol=1e-12)


# ============================================================================ argmin
def test_argmin_ties_go_to_the_lowest_index(fixed_caps):
    sit = random_situation(4)
    planner = Planner(cfg64("quadrature"), behaviours=SMALL_BEHAVIOURS)
    first, _ = planner.plan(sit)
    best = SMALL_BEHAVIOURS[first.best_index]
    worst = SMALL_BEHAVIOURS[int(np.argmax(first.costs["total"]))]
    other = SMALL_BEHAVIOURS[(first.best_index + 1) % len(SMALL_BEHAVIOURS)]
    table = np.stack([worst, other, best, worst, best, best])
    res, _ = Planner(cfg64("quadrature"), behaviours=table).plan(sit)
    tot = res.costs["total"]
    assert tot[2] == tot[4] == tot[5]  # identical rows cost exactly the same
    assert res.best_index == 2 == int(np.argmin(tot))
    np.testing.assert_array_equal(res.offsets, best)


# ============================================================================ compilation
def test_no_recompilation_when_only_values_change(fixed_caps):
    if not hasattr(solve, "_cache_size"):
        pytest.skip("jax.jit(...)._cache_size() not available in this JAX version")
    cfg = cfg64("mc")
    planner = Planner(cfg, behaviours=SMALL_BEHAVIOURS)
    sit = random_situation(0)
    r0, _ = planner.plan(sit, key=key_for(0))
    n0 = solve._cache_size()
    own = replace(sit.own_ship, state=sit.own_ship.state + np.array([3.0, -2.0, 0.2, 0.5]))
    obs = tuple(replace(ob, state=ob.state + np.array([1.0, 2.0, 0.1, -0.1])) for ob in sit.obstacles)
    sit2 = Situation(own, obs, sit.polygons)
    params2 = Params(K_coll=40.0, d_safe=8.0, G1=50.0, kappa=3.0, T_d=80.0)
    r1, s1 = planner.plan(sit2, key=key_for(99), params=params2)
    r2, _ = planner.plan(random_situation(1), PlannerState((0.5, 0.2)), key=key_for(5))   # fewer obstacles
    assert solve._cache_size() == n0
    assert not np.allclose(r1.costs["total"], r0.costs["total"])
    # a static config change does recompile (exactly once)
    other = Planner(cfg.replace(quad_span=6.5, estimator="quadrature", n_quad=20), behaviours=SMALL_BEHAVIOURS)
    other.plan(sit)
    assert solve._cache_size() == n0 + 1
    other.plan(sit2, params=params2)
    assert solve._cache_size() == n0 + 1


def test_bucketing_keeps_shapes_for_nearby_sizes():
    assert [bucket(n, 1) for n in (1, 2, 3, 4, 5)] == [1, 2, 4, 4, 8]
    assert bucket(0, 0) == 0 and bucket(0, 1) == 1
    assert [bucket_scenarios(n) for n in (1, 3, 5, 9, 11)] == [1, 3, 5, 9, 16]
    assert bucket_behaviours(39) == bucket_behaviours(40) == 64 and bucket_behaviours(1014) == 1024
    cfg = cfg64()
    sit = random_situation(0)
    three = Situation(sit.own_ship, sit.obstacles, sit.polygons)
    four = Situation(sit.own_ship, sit.obstacles + sit.obstacles[:1], sit.polygons)
    a = pack(three, paper_behaviours(1), cfg)
    b = pack(four, paper_behaviours(1)[:38], cfg)
    assert jax.tree.map(jnp.shape, a) == jax.tree.map(jnp.shape, b)
    assert a.obstacles.state.dtype == jnp.float64 and a.own.n.dtype == jnp.int32


# ============================================================================ planner state
def test_planner_state_feeds_the_path_cost(fixed_caps):
    sit = random_situation(2)
    planner = Planner(cfg64("quadrature"), behaviours=SMALL_BEHAVIOURS)
    assert planner.init_state() == PlannerState() and PlannerState().last_offsets == (1.0, 0.0)
    r1, s1 = planner.plan(sit)
    assert isinstance(s1, PlannerState)
    assert s1.last_offsets == (r1.u_opt, r1.chi_opt) == tuple(SMALL_BEHAVIOURS[r1.best_index, 0])
    last = (0.5, math.radians(15.0))
    r2, _ = planner.plan(sit, PlannerState(last))
    want = [ref_mod.path_cost(b, last, Params()) for b in SMALL_BEHAVIOURS]
    np.testing.assert_allclose(r2.costs["path"], want, rtol=1e-12, atol=1e-12)
    for term in ("do", "colregs", "so"):  # only the path term depends on the state
        np.testing.assert_array_equal(r2.costs[term], r1.costs[term])
    # a behaviour whose first maneuver equals the last offsets has no change cost: cheaper than from (1, 0)
    same = np.flatnonzero(np.all(np.isclose(SMALL_BEHAVIOURS[:, 0], last), axis=1))
    assert same.size > 0
    for l in same:
        assert r2.costs["path"][l] < r1.costs["path"][l]
    # ... and exactly zero change cost: H_p(b; last = b_1) is f-terms + later changes only, while every other
    # first maneuver pays h(b_1; last) > 0
    for l, b in enumerate(SMALL_BEHAVIOURS):
        no_change = ref_mod.path_cost(b, tuple(b[0]), Params())
        if l in same:
            assert r2.costs["path"][l] == pytest.approx(no_change, rel=1e-12)
        else:
            assert r2.costs["path"][l] > no_change
    # feeding the returned state into the next solve uses it
    r3, _ = planner.plan(sit, s1)
    np.testing.assert_allclose(r3.costs["path"], [ref_mod.path_cost(b, s1.last_offsets, Params()) for b in SMALL_BEHAVIOURS],
                               rtol=1e-12, atol=1e-12)


# ============================================================================ behaviours
def test_paper_behaviour_enumeration():
    b2, b1 = paper_behaviours(2), paper_behaviours(1)
    assert b2.shape == (1014, 2, 2) and b1.shape == (39, 1, 2)
    courses = np.deg2rad([-60, -45, -30, -15, -10, -5, 0, 5, 10, 15, 30, 45, 60])
    want = np.array(list(itertools.product((1.0, 0.5, 0.0), courses, (1.0, 0.5), courses))).reshape(-1, 2, 2)
    np.testing.assert_allclose(b2, want, rtol=0, atol=1e-15)
    # the last maneuver's course varies fastest, then its speed
    assert np.all(b2[:13, 1, 1] == courses) and np.all(b2[:13, :, 0] == 1.0) and b2[13, 1, 0] == 0.5
    np.testing.assert_allclose(b1.reshape(39, 2), list(itertools.product((1.0, 0.5, 0.0), courses)), atol=1e-15)
    with pytest.raises(ValueError):
        paper_behaviours(3)


def test_custom_behaviours_three_maneuvers():
    speeds = ([1.0], [1.0, 0.5], [0.0, 0.25])
    courses = ([0.0, 0.1], [-0.2], [0.3, 0.4, -0.5])
    b = enumerate_behaviours(speeds, courses)
    assert b.shape == (1 * 2 * 2 * 1 * 2 * 3, 3, 2)
    want = np.array(list(itertools.product(*[v for pair in zip(speeds, courses) for v in pair]))).reshape(-1, 3, 2)
    np.testing.assert_array_equal(b, want)
    deg = enumerate_behaviours_deg(speeds, [np.rad2deg(c) for c in courses])
    np.testing.assert_allclose(deg, b, rtol=0, atol=1e-15)
    # an n_M = 3 table plans and its path cost matches the reference
    sit = random_situation(1)
    cfg = PlannerConfig(dtype="float64", T=20.0, dt=0.5)
    res, _ = Planner(cfg, behaviours=b).plan(sit)
    ref = ref_mod.evaluate_reference(sit, b, Params(), cfg)
    assert_costs_close(res.costs, ref)
    assert res.best_index == ref.best and res.offsets.shape == (3, 2)


# ============================================================================ OU covariance
def test_ou_covariance_spec_closed_form():
    sx, sy, g = 0.025, 0.04, 0.1
    p = Params(sigma_x=sx, sigma_y=sy, sigma_xy=0.0, gamma_x=g, gamma_y=g)
    t = np.array([0.0, 0.5, 3.0, 17.25, 150.0])
    sig = np.asarray(ou_covariance(jnp.asarray(t), p))
    assert sig.shape == (5, 4, 4)
    for k, tk in enumerate(t):
        tau = g * tk
        for axis, s in ((0, sx), (1, sy)):
            var_p = s**2 / g**3 * 0.5 * (2 * tau + 4 * math.exp(-tau) - math.exp(-2 * tau) - 3)
            cov_pv = s**2 / (2 * g**2) * (1 - math.exp(-tau)) ** 2
            var_v = s**2 / (2 * g) * (1 - math.exp(-2 * tau))
            assert sig[k, axis, axis] == pytest.approx(var_p, rel=1e-9, abs=1e-15)
            assert sig[k, axis, 2 + axis] == pytest.approx(cov_pv, rel=1e-9, abs=1e-15)
            assert sig[k, 2 + axis, axis] == pytest.approx(cov_pv, rel=1e-9, abs=1e-15)
            assert sig[k, 2 + axis, 2 + axis] == pytest.approx(var_v, rel=1e-12, abs=1e-15)
        for a, b in ((0, 1), (0, 3), (1, 2), (2, 3)):
            assert sig[k, a, b] == 0.0 and sig[k, b, a] == 0.0


def test_ou_covariance_general_matches_reference():
    p = Params(sigma_x=0.3, sigma_y=0.2, sigma_xy=0.04, gamma_x=0.1, gamma_y=0.35)
    t = np.array([0.0, 0.5, 4.0, 25.0, 150.0])
    sig = np.asarray(ou_covariance(jnp.asarray(t), p))
    for k, tk in enumerate(t):
        want = pred.ou_covariance(tk, p)
        np.testing.assert_allclose(sig[k], want, rtol=1e-12, atol=1e-16)
        np.testing.assert_allclose(sig[k], sig[k].T, rtol=1e-14, atol=1e-16)
    P0 = np.diag([2.0, 1.0, 0.1, 0.2])
    P0[0, 1] = P0[1, 0] = 0.3
    ob = Obstacle(state=[0, 0, 1, 0], cov=P0)
    cfg = PlannerConfig(T=10.0, dt=0.5)
    got = np.asarray(obstacle_covariances(jnp.asarray(P0)[None], p, cfg.n_steps, cfg.dt))[0]
    np.testing.assert_allclose(got, pred.obstacle_covariances(ob, p, cfg), rtol=1e-12, atol=1e-15)


# ============================================================================ head-on
def test_head_on_default_planner_turns_starboard():
    sit = paper_head_on()
    planner = Planner()
    assert len(planner.behaviours) == 1014 and planner.config.dtype == "float32"
    assert planner.config.estimator == "quadrature"
    res, state = planner.plan(sit)
    assert res.chi_opt > 0, res.offsets
    assert state.last_offsets[1] > 0
    assert res.costs["colregs"][res.best_index] == 0.0
    straight = int(np.flatnonzero(np.all(planner.behaviours == np.array([[1.0, 0.0], [1.0, 0.0]]), axis=(1, 2)))[0])
    assert res.costs["total"][straight] > res.costs["total"][res.best_index]
    assert res.costs["do"][straight] > 0
    rows = res.ranking(3)
    assert rows[0]["index"] == res.best_index and rows[0]["total"] <= rows[1]["total"] <= rows[2]["total"]


def test_head_on_single_obstacle_one_maneuver():
    sit = paper_head_on(n_obstacles=1)
    beh = paper_behaviours(1)
    cfg = PlannerConfig(T=100.0, dt=0.5, dtype="float64")
    res, _ = Planner(cfg, behaviours=beh).plan(sit)
    assert res.chi_opt > 0 and res.offsets.shape == (1, 2)
    ref = ref_mod.evaluate_reference(sit, beh, Params(), cfg)
    assert res.best_index == ref.best
    assert_costs_close(res.costs, ref)
    # turning to port would violate COLREGS in every scenario
    port = int(np.flatnonzero((beh[:, 0, 0] == 1.0) & np.isclose(beh[:, 0, 1], -math.radians(45)))[0])
    assert res.costs["colregs"][port] == pytest.approx(Params().kappa)


# ============================================================================ bad input
def _own(**kw):
    d = dict(state=[0.0, 0.0, 0.0, 2.0], waypoints=[[0.0, 0.0], [100.0, 0.0]], U_d=2.0)
    d.update(kw)
    return OwnShip(**d)


def _obs(**kw):
    d = dict(state=[50.0, 0.0, -1.0, 0.0], cov=np.eye(4), n_ps=3)
    d.update(kw)
    return Obstacle(**d)


BAD_CONSTRUCTORS = [
    ("own_ship.state", lambda: _own(state=[0.0, np.nan, 0.0, 2.0])),
    ("own_ship.state", lambda: _own(state=[0.0, 0.0, np.inf, 2.0])),
    ("own_ship.state", lambda: _own(state=[0.0, 0.0, 0.0])),
    ("own_ship.state speed", lambda: _own(state=[0.0, 0.0, 0.0, -1.0])),
    ("own_ship.U_d", lambda: _own(U_d=-0.5)),
    ("own_ship.U_d", lambda: _own(U_d=np.nan)),
    ("own_ship.waypoints", lambda: _own(waypoints=[[0.0, 0.0, 0.0], [1.0, 2.0, 3.0]])),
    ("own_ship.waypoints", lambda: _own(waypoints=[[0.0, 0.0]])),
    ("own_ship.waypoints", lambda: _own(waypoints=[[0.0, 0.0], [0.0, 0.0]])),
    ("obstacle.state", lambda: _obs(state=[np.nan, 0.0, 0.0, 0.0])),
    ("obstacle.state", lambda: _obs(state=[0.0, 0.0, -np.inf, 0.0])),
    ("obstacle.cov", lambda: _obs(cov=np.diag([1.0, 1.0, -1.0, 1.0]))),
    ("obstacle.cov", lambda: _obs(cov=np.eye(4) + np.triu(np.ones((4, 4)), 1))),  # not symmetric
    ("obstacle.cov", lambda: _obs(cov=np.eye(3))),
    ("obstacle.cov", lambda: _obs(cov=np.full((4, 4), np.nan))),
    ("obstacle.cov positional block", lambda: _obs(cov=np.diag([1.0, 0.0, 1.0, 1.0]))),
    ("obstacle.cov positional block", lambda: _obs(cov=np.array([[1.0, 1.0, 0, 0], [1.0, 1.0, 0, 0],
                                                                  [0, 0, 1.0, 0], [0, 0, 0, 1.0]]))),
    ("obstacle.waypoints", lambda: _obs(waypoints=[[0.0, 0.0], [1.0, 1.0]][0])),
    ("obstacle.waypoints", lambda: _obs(waypoints=np.zeros((3, 3)))),
    ("obstacle.n_ps", lambda: _obs(n_ps=2)),
    ("obstacle.n_ps", lambda: _obs(n_ps=0)),
    ("obstacle.n_ps", lambda: _obs(n_ps=3.0)),
    ("obstacle.probs", lambda: _obs(probs=[0.2, 0.2, 0.2])),
    ("obstacle.probs", lambda: _obs(probs=[0.5, 0.5])),
    ("obstacle.probs", lambda: _obs(probs=[1.2, -0.1, -0.1])),
    ("obstacle.weight", lambda: _obs(weight=-1.0)),
    ("obstacle.zeta", lambda: _obs(zeta=np.nan)),
    ("situation.own_ship", lambda: Situation(own_ship="ship")),
    (r"situation.obstacles\[0\]", lambda: Situation(_own(), ("obstacle",))),
    (r"situation.polygons\[0\]", lambda: Situation(_own(), (), ([[0.0, 0.0], [1.0, 1.0]],))),
    (r"situation.polygons\[0\]", lambda: Situation(_own(), (), ([[0.0, 0.0], [1.0, np.nan], [2.0, 0.0]],))),
    ("speed factor set of maneuver 1 is empty", lambda: enumerate_behaviours([[]], [[0.0]])),
    ("course offset set of maneuver 2 is empty", lambda: enumerate_behaviours([[1.0], [1.0]], [[0.0], []])),
    ("speed factor must be in", lambda: enumerate_behaviours([[1.5]], [[0.0]])),
    ("speed factor must be in", lambda: enumerate_behaviours([[-0.1]], [[0.0]])),
    ("course offset must be in", lambda: enumerate_behaviours([[1.0]], [[3.5]])),
    ("course offset must be in", lambda: enumerate_behaviours_deg([[1.0]], [[-181.0]])),
    ("speed_sets and course_sets", lambda: enumerate_behaviours([[1.0], [1.0]], [[0.0]])),
    ("speed_sets is empty", lambda: enumerate_behaviours([], [])),
    ("behaviours must have shape", lambda: Planner(behaviours=np.zeros((3, 2)))),
    ("behaviours must have shape", lambda: Planner(behaviours=np.zeros((0, 1, 2)))),
    ("behaviours must have shape", lambda: Planner(behaviours=np.zeros((3, 1, 3)))),
    ("behaviour speed factor", lambda: Planner(behaviours=np.array([[[2.0, 0.0]]]))),
    ("behaviour course offset", lambda: Planner(behaviours=np.array([[[1.0, -4.0]]]))),
    ("behaviours must be finite", lambda: Planner(behaviours=np.array([[[1.0, np.nan]]]))),
    ("PlannerConfig.estimator", lambda: PlannerConfig(estimator="exact")),
    ("PlannerConfig.dtype", lambda: PlannerConfig(dtype="float16")),
    ("PlannerConfig.dtype", lambda: PlannerConfig(dtype=np.float32)),
    ("PlannerConfig.T / PlannerConfig.dt", lambda: PlannerConfig(T=10.25, dt=0.5)),
    ("PlannerConfig.T / PlannerConfig.dt", lambda: PlannerConfig(T=0.2, dt=0.5)),
    ("PlannerConfig.dt", lambda: PlannerConfig(dt=0.0)),
    ("PlannerConfig.T", lambda: PlannerConfig(T=np.nan)),
    ("PlannerConfig.n_samples", lambda: PlannerConfig(n_samples=0)),
    ("PlannerConfig.time_block", lambda: PlannerConfig(time_block=2.5)),
    ("PlannerConfig.pc_layout", lambda: PlannerConfig(pc_layout="sparse")),
    ("Params.K_coll", lambda: Planner(params=Params(K_coll=-1.0))),
    ("Params.d_safe", lambda: Planner(params=Params(d_safe=np.nan))),
    ("Params.gamma_x", lambda: Planner(params=Params(gamma_x=0.0))),
    ("Params.ce_rho", lambda: Planner(params=Params(ce_rho=1.5))),
    ("Params.t_ts", lambda: Planner(params=Params(t_ts=-1.0))),
    ("Params.sigma_xy", lambda: Planner(params=Params(sigma_x=0.1, sigma_y=0.1, sigma_xy=0.5))),
    ("Params.K_u", lambda: Planner(params=Params(K_u=np.array([1.0, 2.0])))),
    ("PlannerState.last_offsets", lambda: PlannerState((1.5, 0.0))),
    ("PlannerState.last_offsets", lambda: PlannerState((1.0, 4.0))),
    ("PlannerState.last_offsets", lambda: PlannerState((np.nan, 0.0))),
    ("config must be a PlannerConfig", lambda: Planner(config={"T": 10.0})),
    ("params must be a psbmpc_jax.Params", lambda: Planner(params={"K_coll": 1.0})),
]


@pytest.mark.parametrize("match, build", BAD_CONSTRUCTORS, ids=[f"{i}-{m}" for i, (m, _) in enumerate(BAD_CONSTRUCTORS)])
def test_bad_input_raises_value_error_naming_the_field(match, build):
    with pytest.raises(ValueError, match=match):
        build()


def test_bad_plan_arguments_raise_before_any_device_work(monkeypatch):
    calls = []
    import psbmpc_jax.planner as planner_mod

    monkeypatch.setattr(planner_mod, "solve", lambda *a, **k: calls.append(1))
    sit = Situation(_own(), (_obs(),))
    planner = Planner(PlannerConfig(T=10.0, dt=0.5, estimator="mc"), behaviours=paper_behaviours(1))
    with pytest.raises(ValueError, match="key"):
        planner.plan(sit)                                               # mc without a PRNG key
    with pytest.raises(ValueError, match="key"):
        Planner(PlannerConfig(T=10.0, dt=0.5, estimator="ce"), behaviours=paper_behaviours(1)).plan(sit)
    with pytest.raises(ValueError, match="Params.K_coll"):
        planner.plan(sit, key=jax.random.key(0), params=Params(K_coll=-1.0))
    with pytest.raises(ValueError, match="Params.d_safe"):
        planner.plan(sit, key=jax.random.key(0), params=Params(d_safe=np.nan))
    with pytest.raises(ValueError, match="state must be a PlannerState"):
        planner.plan(sit, (1.0, 0.0), key=jax.random.key(0))
    with pytest.raises(ValueError, match="situation must be a psbmpc_jax.Situation"):
        planner.plan(sit.own_ship, key=jax.random.key(0))
    assert calls == []


def test_float64_without_x64_is_rejected():
    code = textwrap.dedent("""
        import jax
        jax.config.update("jax_enable_x64", False)
        from psbmpc_jax import Planner, PlannerConfig
        Planner(PlannerConfig(dtype="float32"))   # fine
        try:
            Planner(PlannerConfig(dtype="float64"))
        except ValueError as e:
            assert "jax_enable_x64" in str(e), str(e)
            print("REJECTED")
    """)
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env = {**os.environ, "JAX_ENABLE_X64": "0",
           "PYTHONPATH": os.pathsep.join([root] + [p for p in [os.environ.get("PYTHONPATH")] if p])}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, env=env, cwd=root)
    assert out.returncode == 0, out.stderr
    assert "REJECTED" in out.stdout


def test_public_api_exports():
    for name in psbmpc_jax.__all__:
        assert hasattr(psbmpc_jax, name), name
    assert psbmpc_jax.SolveInputs is SolveInputs and psbmpc_jax.Evaluation is Evaluation
