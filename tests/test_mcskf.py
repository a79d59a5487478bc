"""The MCS + KF collision risk of Tengesdal, Brekke & Johansen 2020 (psbmpc_jax.costs.mcskf) against its float64
oracle (psbmpc_jax.reference_mcskf): the scalar KF (hand gains, W·y = the recursive filter), the Cholesky
factor, the CPA time, the Monte-Carlo estimator on a shared table, the estimator against the exact probability
(10⁶ samples), the Fig. 3 unit case of SPEC_SEEDS §4.4 (exact table, filtered peak), the eq. (20) term on a
hand-made Context and through the evaluator, gradients where the term is differentiable, degenerate inputs
and parameter validation."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from psbmpc_jax import Obstacle, OwnShip, Params, PlannerConfig, Situation
from psbmpc_jax import reference as ref_mod
from psbmpc_jax import reference_mcskf as rm
from psbmpc_jax.behaviours import enumerate_behaviours_deg
from psbmpc_jax.costs import mcskf as mk
from psbmpc_jax.costs.base import Context
from psbmpc_jax.costs.collision import pc_quadrature
from psbmpc_jax.evaluate import evaluate
from psbmpc_jax.ownship import Trajectory
from psbmpc_jax.packing import pack

FIG3_SIGMA = np.diag([25.0, 25.0, 4.0, 4.0])
#: SPEC_SEEDS §4.4 Fig. 3 table (exact P(I), d_safe = 40 m), t [s] -> P
FIG3_TABLE = {0: 0.294, 2: 0.305, 4: 0.311, 6: 0.307, 8: 0.292, 10: 0.254, 12: 0.186, 13: 0.154, 13.75: 0.145,
              16: 0.108, 20: 0.009}


def fig3_relative(t):
    """Own-ship stationary at (100, 0); obstacle from (55, −55) east at 4 m/s: Δp, Δv at times t."""
    t = np.asarray(t, float)
    return np.full_like(t, -45.0), -55.0 + 4.0 * t, np.zeros_like(t), np.full_like(t, 4.0)


def random_spd(rng, pos=25.0, vel=2.0):
    A = rng.normal(0, 1, (4, 4)) * np.sqrt([pos, pos, vel, vel])[:, None]
    return A @ A.T / 4.0 + np.diag([pos, pos, vel, vel]) * 0.5


# ============================================================================ the scalar KF
def test_kf_gains_hand_values():
    K = np.asarray(jax.jit(mk.kf_gains, static_argnums=0)(300, 5e-5, 1e-3, 0.3))
    np.testing.assert_allclose(K[:5], [0.9967, 0.5114, 0.3596, 0.2906, 0.2540], atol=5e-5)
    assert K[-1] == pytest.approx(0.200, abs=1e-6)
    v_prior_inf = K[-1] * 1e-3 / (1.0 - K[-1])                     # K = V⁻/(V⁻ + r)
    assert v_prior_inf == pytest.approx(2.5e-4, rel=1e-4)
    np.testing.assert_allclose(K, rm.kf_gains(300, 5e-5, 1e-3, 0.3), rtol=1e-14)
    assert np.all(np.diff(K) <= 0) and np.all(np.diff(K[:20]) < 0)
    K32 = np.asarray(mk.kf_gains(50, 5e-5, 1e-3, 0.3, dtype=jnp.float32))
    assert K32.dtype == np.float32
    np.testing.assert_allclose(K32, K[:50], rtol=2e-6)           # V = K r_P: no cancellation (2.4e-7 on a CPU)


@pytest.mark.parametrize("P0", [0.0, 0.4])
def test_smoothing_matrix_equals_the_recursive_filter(P0):
    rng = np.random.default_rng(0)
    n = 401
    y = rng.uniform(0, 1, (n, 7))
    y[:, 0] = 1.0                                                    # the clip at 1 never binds
    K = mk.kf_gains(n, 5e-5, 1e-3, 0.3)
    W, b = (np.asarray(a) for a in mk.kf_weights(K))
    assert np.all(np.triu(W, 1) == 0) and np.all(np.diag(W) > 0)
    np.testing.assert_allclose(W.sum(axis=1) + b, 1.0, atol=1e-13)   # weights and prior weight sum to 1
    np.testing.assert_allclose(W[:60, :60], rm.kf_matrix(60), rtol=1e-12, atol=1e-300)
    p_mat = np.asarray(jax.jit(mk.kf_apply)(y, K, P0))
    p_rec = np.asarray(jax.jit(mk.kf_filter)(y, K, P0))
    p_ref = np.stack([rm.kf_filter(y[:, c], P0=P0) for c in range(y.shape[1])], axis=1)
    np.testing.assert_allclose(p_mat, p_ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(p_rec, p_ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(p_ref[:, 0], 1.0 - (1.0 - P0) * b, atol=1e-12)
    # steady state: an exponential smoother of weight K_inf = 0.2
    step = np.r_[np.zeros(200), np.ones(201)]
    p = np.asarray(mk.kf_apply(step[:, None], K))[:, 0]
    assert p[200] == pytest.approx(0.2, abs=1e-4) and p[201] == pytest.approx(0.36, abs=1e-4)


# ============================================================================ pieces of the estimator
def test_cholesky4_definite_and_semidefinite():
    rng = np.random.default_rng(1)
    S = np.stack([random_spd(rng) for _ in range(5)]
                 + [np.diag([25.0, 25.0, 0.0, 0.0]), np.zeros((4, 4)), np.diag([4.0, 0.0, 1.0, 0.0])])
    L = np.asarray(jax.jit(mk.cholesky4)(S))
    assert np.all(np.isfinite(L)) and np.all(np.triu(L, 1) == 0)
    np.testing.assert_allclose(L @ np.swapaxes(L, -1, -2), S, atol=1e-12)
    for a, s in zip(L, S):
        np.testing.assert_allclose(a, rm.cholesky4(s), rtol=1e-13, atol=1e-13)
    g = jax.grad(lambda s: jnp.sum(mk.cholesky4(s)))(jnp.asarray(S[5:]))
    assert np.all(np.isfinite(np.asarray(g)))


def test_cpa_time_cases():
    cases = [((-45.0, -55.0), (0.0, 4.0), 13.75), ((-45.0, 5.0), (0.0, 4.0), 0.0),      # closing / opening
             ((100.0, 0.0), (-0.2, 0.0), 0.0), ((100.0, 0.0), (-0.25, 0.0), 400.0),    # below / at ε_v
             ((10.0, 0.0), (0.0, 0.0), 0.0), ((0.0, 0.0), (3.0, 1.0), 0.0)]            # Δv = 0, Δp = 0
    arr = np.array([[*p, *v] for p, v, _ in cases])
    got = np.asarray(jax.jit(mk.cpa_time)(*arr.T, 0.25))
    np.testing.assert_allclose(got, [c[2] for c in cases], rtol=1e-14)
    np.testing.assert_allclose(got, [rm.cpa_time(p, v, 0.25) for p, v, _ in cases], rtol=1e-14)
    g = jax.grad(lambda a: jnp.sum(mk.cpa_time(*a.T, 0.25)))(jnp.asarray(arr))
    assert np.all(np.isfinite(np.asarray(g)))


@pytest.mark.parametrize("event", mk.EVENTS)
def test_mcs_estimates_equal_the_reference_on_the_same_table(event):
    rng = np.random.default_rng(2)
    n_t, n_p, n_mc = 6, 8, 64
    dp = rng.uniform(-90, 90, (n_t, n_p, 2))
    dv = rng.uniform(-6, 6, (n_t, n_p, 2))
    dv[0, 0] = 0.0                                                   # zero relative velocity
    dp[1, 1] = 0.0                                                   # zero distance
    S = np.stack([random_spd(rng) for _ in range(n_p)])
    Z = np.asarray(mk.normal_table(jax.random.key(3), n_t, n_mc, jnp.float64))
    L = mk.cholesky4(S)
    f = jax.jit(mk.mcs_estimates, static_argnames="event")
    y, tc = (np.asarray(a) for a in f(dp[..., 0], dp[..., 1], dv[..., 0], dv[..., 1], L, Z[:, None], 40.0,
                                      eps_v=0.25, event=event))
    Lr = [rm.cholesky4(s) for s in S]
    for k in range(n_t):
        for p in range(n_p):
            yr, tr = rm.mcs_estimate(dp[k, p], dv[k, p], Lr[p], Z[k], 40.0, 0.25, event)
            assert y[k, p] == yr and tc[k, p] == pytest.approx(tr, rel=1e-13, abs=1e-13), (k, p)
    assert 5 < np.count_nonzero((y > 0) & (y < 1))                  # not vacuous
    # common random numbers: a repeated pair on the same step gives the same estimate; other steps differ
    same = f(dp[0, :1, 0].repeat(2), dp[0, :1, 1].repeat(2), dv[0, :1, 0].repeat(2), dv[0, :1, 1].repeat(2),
             L[:1], Z[0], 40.0, event=event)[0]
    assert float(same[0]) == float(same[1]) == y[0, 0]


def test_exact_probability_three_ways():
    """The reference's disc quadrature against the Marcum-Q series (isotropic) and the library's pc_quadrature
    (anisotropic), so that the "exact" values the MC is checked against are themselves checked."""
    for dist, sigma in [(45.0, 27.95), (45.9, 5.0), (10.0, 30.0), (0.0, 12.0), (80.0, 20.0)]:
        a = rm.disc_probability([dist, 0.0], sigma ** 2 * np.eye(2), 40.0)
        b = rm.disc_probability_isotropic(dist, sigma, 40.0)
        assert a == pytest.approx(b, abs=1e-9), (dist, sigma)
    rng = np.random.default_rng(4)
    for _ in range(5):
        m = rng.uniform(-60, 60, 2)
        A = rng.normal(0, 12, (2, 2))
        S = A @ A.T + 4 * np.eye(2)
        q = float(pc_quadrature(jnp.float64(m[0]), jnp.float64(m[1]), jnp.float64(S[0, 0]), jnp.float64(S[0, 1]),
                                jnp.float64(S[1, 1]), jnp.float64(40.0), n_quad=64, span=8.0))
        assert rm.disc_probability(m, S, 40.0) == pytest.approx(q, abs=1e-6)


def test_mc_with_a_million_samples_matches_the_exact_probability():
    rng = np.random.default_rng(5)
    n_p = 6
    dp = rng.uniform(-70, 70, (n_p, 2))
    dv = rng.uniform(-5, 5, (n_p, 2))
    S = np.stack([random_spd(rng, 60.0, 3.0) for _ in range(n_p)])
    z = jax.random.normal(jax.random.key(6), (1_000_000, 4), jnp.float64)
    y, _ = jax.jit(mk.mcs_estimates)(dp[:, 0], dp[:, 1], dv[:, 0], dv[:, 1], mk.cholesky4(S), z, 40.0)
    exact = np.array([rm.exact_probability(dp[p], dv[p], S[p], 40.0) for p in range(n_p)])
    np.testing.assert_allclose(np.asarray(y), exact, atol=0.005)
    assert np.count_nonzero((exact > 0.05) & (exact < 0.95)) >= 2  # not vacuous


# ============================================================================ Fig. 3 (SPEC_SEEDS §4.4)
def test_fig3_exact_table():
    ts = np.array(sorted(FIG3_TABLE))
    exact = np.array([rm.exact_probability(p[:2], p[2:], FIG3_SIGMA, 40.0) for p in np.stack(fig3_relative(ts), 1)])
    np.testing.assert_allclose(exact, [FIG3_TABLE[t] for t in ts], atol=0.002)
    z = jax.random.normal(jax.random.key(7), (1_000_000, 4), jnp.float64)
    y, tc = jax.jit(mk.mcs_estimates)(*fig3_relative(ts), mk.cholesky4(FIG3_SIGMA), z, 40.0)
    np.testing.assert_allclose(np.asarray(y), [FIG3_TABLE[t] for t in ts], atol=0.005)
    np.testing.assert_allclose(np.asarray(y), exact, atol=0.005)
    np.testing.assert_allclose(np.asarray(tc), np.maximum(13.75 - ts, 0.0), atol=1e-12)
    # the alternative reading ("each sample's own CPA") starts at 0.41 and falls: not "a maximum right above 0.3"
    y_alt, _ = jax.jit(mk.mcs_estimates, static_argnames="event")(*fig3_relative(ts), mk.cholesky4(FIG3_SIGMA), z,
                                                                   40.0, event="sample_cpa")
    y_alt = np.asarray(y_alt)
    assert y_alt[0] == pytest.approx(0.41, abs=0.01) and np.all(np.diff(y_alt) < 0.003)


def test_fig3_filtered_peak_over_seeds():
    """N_MC = 100, dt = 0.5 s, 200 seeds: the mean of the filtered probability peaks in [0.30, 0.36] at
    t ≈ 4–6 s and then falls; the filter cuts the spread of the raw MC estimate."""
    dt, n_seeds = 0.5, 200
    ts = np.arange(0.0, 25.0 + dt / 2, dt)
    L = mk.cholesky4(FIG3_SIGMA)
    rel = fig3_relative(ts)
    K = mk.kf_gains(len(ts), 5e-5, 1e-3, 0.3)

    @jax.jit
    def run(key):
        z = mk.normal_table(key, len(ts), 100, jnp.float64)
        y, _ = mk.mcs_estimates(*rel, L, z, 40.0)
        return y, mk.kf_apply(y, K)

    y, p = (np.asarray(a) for a in jax.vmap(run)(jax.random.split(jax.random.key(8), n_seeds)))
    mean = p.mean(axis=0)
    k_max = int(np.argmax(mean))
    assert 0.30 <= mean[k_max] <= 0.36 and 3.5 <= ts[k_max] <= 6.5, (mean[k_max], ts[k_max])
    assert mean[ts == 14.0][0] < 0.2 and mean[-1] < 0.03 and np.all(np.diff(mean[ts >= 8]) < 0)
    per_run_max = p.max(axis=1)
    assert 0.30 <= np.median(per_run_max) <= 0.37
    k5 = int(np.argmin(np.abs(ts - 5.0)))
    assert p[:, k5].std() < 0.5 * y[:, k5].std()                    # 0.017 vs 0.046 in SPEC §4.4


# ============================================================================ the eq. (20) term
def traj(a):
    a = np.asarray(a)
    return Trajectory(*(jnp.asarray(v) for v in (a[..., 0], a[..., 1], a[..., 2], a[..., 3], np.cos(a[..., 2]),
                                                  np.sin(a[..., 2]))))


def make_context(rng, B=4, T=21, dt=1.0, dtype=np.float64):
    """Own-ship rows heading north at 5 m/s with different courses (row 3 repeats row 0); 3 obstacles × 2
    scenarios near the own-ship's path; obstacle 2 and scenario 1 of obstacle 0 masked (padding parked on the
    own-ship); a covariance growing in time (the term must use only index 0)."""
    t = np.arange(T) * dt
    chis = [-0.5, 0.0, 0.6, -0.5]
    own = np.stack([np.stack([5 * t * math.cos(c), 5 * t * math.sin(c), np.full(T, c), np.full(T, 5.0)], 1)
                    for c in chis[:B]], axis=1)                                        # [T, B, 4]
    obs = np.zeros((T, 3, 2, 4))
    starts = [((90.0, 40.0), -math.pi / 2, 4.0), ((120.0, -10.0), math.pi, 3.0), ((60.0, 60.0), math.pi, 2.0)]
    for o, ((x0, y0), chi, U) in enumerate(starts):
        for s in range(2):
            c = chi + 0.3 * s + rng.normal(0, 0.05)
            obs[:, o, s] = np.stack([x0 + U * t * math.cos(c), y0 + 10 * s + U * t * math.sin(c), np.full(T, c),
                                     np.full(T, U)], 1)
    valid = np.array([[True, False], [True, True], [False, False]])
    obs[:, ~valid] = own[:, :1]
    S0 = np.stack([random_spd(rng, 30.0, 2.0) for _ in range(3)])
    cov = S0[:, None] + (np.arange(T)[None, :, None, None] * 5.0) * np.eye(4)         # [O, T, 4, 4]
    weight = np.array([[0.7, 0.3], [0.25, 0.75], [0.5, 0.5]]) * np.array([[2.0], [1.0], [1.0]])
    c = lambda a: jnp.asarray(a, dtype)                                                # noqa: E731
    ctx = Context(t=c(t), offsets=None, last_offsets=None, own=traj(own.astype(dtype)),
                  obstacles=traj(obs.astype(dtype)), obs_cov=c(cov), cov_stats=None, scen_valid=jnp.asarray(valid),
                  radius=None, zeta_k=None, scen_weight=c(weight * valid), world=None, dense=True)
    obstacles = [(obs[:, o].transpose(1, 0, 2), weight[o] * valid[o], S0[o]) for o in range(3)]
    return ctx, own, obstacles, t


@jax.jit
def run_term(term, ctx):
    return term(ctx, None, None, None)


@pytest.mark.parametrize("event, include_t0", [("mean_cpa", True), ("mean_cpa", False), ("sample_cpa", True)])
def test_term_matches_the_reference_on_a_context(event, include_t0):
    ctx, own, obstacles, t = make_context(np.random.default_rng(10))
    term = mk.Psbmpc2020Term(n_mc=40, seed=3, event=event, include_t0=include_t0, K_coll=2.0, kappa=5.0, d_cl=150.0)
    out = run_term(term, ctx)
    Z = np.asarray(term.table(len(t), jnp.float64))
    kw = term._kw()
    refs = [rm.psbmpc2020_cost(own[:, b], obstacles, t, Z, **kw) for b in range(own.shape[1])]
    value = np.asarray(out.value)
    np.testing.assert_allclose(value, [r["value"] for r in refs], rtol=1e-5)
    np.testing.assert_allclose(value, [r["value"] for r in refs], rtol=1e-12)
    d = {k: np.asarray(v) for k, v in out.details.items()}
    valid = np.asarray(ctx.scen_valid)
    for b, r in enumerate(refs):
        np.testing.assert_allclose(d["psbmpc2020_h"][b], r["h"], rtol=1e-12, atol=1e-12)
        for key, rk in (("psbmpc2020_i", "bracket"), ("psbmpc2020_coll_i", "coll"),
                        ("psbmpc2020_colregs_i", "colregs")):
            np.testing.assert_allclose(d[key][b][valid], np.asarray(r[rk])[valid], rtol=1e-12, atol=1e-12)
    for key in ("psbmpc2020_i", "psbmpc2020_coll_i", "psbmpc2020_colregs_i", "psbmpc2020_pmax"):
        assert d[key].shape == (4, 3, 2) and np.all(d[key][:, ~valid] == 0)
    np.testing.assert_allclose(d["psbmpc2020_h"].max(axis=1), value, rtol=1e-14)
    # not vacuous: rows differ, the collision and the COLREGS parts both act, a row repeated gives the same value
    assert np.ptp(value[:3]) > 1.0 and value[3] == value[0]
    assert d["psbmpc2020_coll_i"].max() > 1.0 and d["psbmpc2020_colregs_i"].max() > 0
    assert 0.05 < d["psbmpc2020_pmax"].max() <= 1.0


def test_term_float32_against_the_reference_on_its_table():
    ctx, own, obstacles, t = make_context(np.random.default_rng(10), dtype=np.float32)
    term = mk.Psbmpc2020Term(n_mc=40, seed=3)
    out = run_term(term, ctx)
    assert out.value.dtype == jnp.float32 and all(v.dtype == jnp.float32 for v in out.details.values())
    Z = np.asarray(term.table(len(t), jnp.float32), dtype=float)
    ref = [rm.psbmpc2020_cost(own[:, b], obstacles, t, Z, **term._kw())["value"] for b in range(own.shape[1])]
    np.testing.assert_allclose(np.asarray(out.value), ref, rtol=1e-4)


def test_term_uses_the_covariance_at_t0_and_the_series():
    ctx, *_ = make_context(np.random.default_rng(10))
    term = mk.Psbmpc2020Term(n_mc=40, seed=3)
    v = np.asarray(run_term(term, ctx).value)
    frozen = ctx._replace(obs_cov=jnp.broadcast_to(ctx.obs_cov[:, :1], ctx.obs_cov.shape))
    np.testing.assert_array_equal(np.asarray(run_term(term, frozen).value), v)
    grown = ctx._replace(obs_cov=ctx.obs_cov.at[:, 0].add(200.0 * jnp.eye(4)))
    assert not np.allclose(np.asarray(run_term(term, grown).value), v)
    sr = jax.jit(lambda c: term.series(c))(ctx)
    assert sr["y"].shape == sr["P"].shape == (21, 6, 4)
    np.testing.assert_allclose(np.asarray(sr["P"]), np.asarray(mk.kf_filter(sr["y"], mk.kf_gains(21))), atol=1e-12)
    with pytest.raises(ValueError, match="z must be"):
        term.series(ctx, z=np.zeros((21, 10, 4)))


def test_numeric_fields_are_traced_and_static_fields_recompile():
    ctx, *_ = make_context(np.random.default_rng(10))
    run_term(mk.Psbmpc2020Term(n_mc=16), ctx)
    n0 = run_term._cache_size()
    run_term(mk.Psbmpc2020Term(n_mc=16, d_safe=30.0, kappa=2.0, T_c=9.0, q_P=1e-4), ctx)
    assert run_term._cache_size() == n0
    run_term(mk.Psbmpc2020Term(n_mc=17), ctx)
    assert run_term._cache_size() == n0 + 1
    leaves, treedef = jax.tree_util.tree_flatten(mk.Psbmpc2020Term(n_mc=16, d_safe=30.0))
    assert jax.tree_util.tree_unflatten(treedef, leaves) == mk.Psbmpc2020Term(n_mc=16, d_safe=30.0)


# ============================================================================ through the evaluator
def test_grid_search_with_the_term_matches_the_reference():
    cfg = PlannerConfig(T=30.0, dt=1.0, dtype="float64")
    cov = np.diag([25.0, 25.0, 4.0, 4.0])
    own = OwnShip(state=[0.0, 0.0, 0.0, 6.0], waypoints=np.array([[0.0, 0.0], [1000.0, 0.0]]), U_d=6.0)
    obstacles = (Obstacle([150.0, 8.0, -5.0, 0.0], cov, n_ps=1), Obstacle([90.0, 70.0, 0.0, -3.0], cov * 2, n_ps=1))
    sit = Situation(own, obstacles)
    search = enumerate_behaviours_deg(((0.5, 1.0),), ((-60, -30, 0, 30, 60),))
    term = mk.Psbmpc2020Term(n_mc=50, seed=1)
    ev = evaluate(pack(sit, search, cfg), jnp.asarray([1.0, 0.0]), Params(), None, config=cfg, terms=(term,))
    ref = ref_mod.evaluate_reference(sit, search, Params(), cfg, extra_terms=(term,))
    got = np.asarray(ev.costs["psbmpc2020"])[: len(search)]
    np.testing.assert_allclose(got, ref.extra["psbmpc2020"], rtol=1e-10)
    assert np.ptp(got) > 1.0 and np.asarray(ev.details["psbmpc2020_pmax"]).max() > 0.1


# ============================================================================ gradients and edges
def _value_of_own(term, ctx, own_xy, own_U):
    own = ctx.own._replace(x=own_xy[..., 0], y=own_xy[..., 1], U=own_U)
    return jnp.sum(term(ctx._replace(own=own), None, None, None).value)


def test_gradient_where_differentiable():
    """The MC count and μ are piecewise constant; C and the discount are smooth: away from the jumps (a step
    of 1e-6 m crosses none) the reverse-mode gradient equals central differences and is not zero."""
    ctx, *_ = make_context(np.random.default_rng(10), B=3)
    term = mk.Psbmpc2020Term(n_mc=40, seed=3)
    xy = np.stack([np.asarray(ctx.own.x), np.asarray(ctx.own.y)], -1)
    U = np.asarray(ctx.own.U)
    vg = jax.jit(jax.value_and_grad(lambda a, u: _value_of_own(term, ctx, a, u), argnums=(0, 1)))
    _, (gxy, gU) = vg(xy, U)
    gxy, gU = np.asarray(gxy), np.asarray(gU)
    assert np.abs(gxy).max() > 1e-3 and np.abs(gU).max() > 1e-3
    h = 1e-6
    checked = 0
    for idx in [(3, 0, 0), (5, 1, 1), (8, 2, 0), (10, 0, 1), (12, 1, 0)]:
        e = np.zeros_like(xy)
        e[idx] = h
        fd = (float(vg(xy + e, U)[0]) - float(vg(xy - e, U)[0])) / (2 * h)
        assert gxy[idx] == pytest.approx(fd, rel=1e-5, abs=1e-7), idx
        checked += abs(fd) > 1e-4
    for idx in [(4, 0), (9, 2)]:
        e = np.zeros_like(U)
        e[idx] = h
        fd = (float(vg(xy, U + e)[0]) - float(vg(xy, U - e)[0])) / (2 * h)
        assert gU[idx] == pytest.approx(fd, rel=1e-5, abs=1e-7), idx
        checked += abs(fd) > 1e-4
    assert checked >= 3


def test_edges_give_finite_values_and_gradients():
    ctx, *_ = make_context(np.random.default_rng(10), B=2)
    term = mk.Psbmpc2020Term(n_mc=20)
    # every target on the own-ship row 0 with its velocity (zero distance, zero relative velocity), zero covariance
    n_t = ctx.t.shape[0]
    same = lambda a: jnp.broadcast_to(a[:, :1, None], (n_t, 3, 2))                # noqa: E731
    obs = Trajectory(*(same(a) for a in ctx.own))
    edge = ctx._replace(obstacles=obs, obs_cov=jnp.zeros_like(ctx.obs_cov))
    xy = np.stack([np.asarray(ctx.own.x), np.asarray(ctx.own.y)], -1)
    U = np.asarray(ctx.own.U)
    for c in (edge, edge._replace(scen_valid=jnp.zeros_like(ctx.scen_valid))):
        v, g = jax.jit(jax.value_and_grad(lambda a, u: _value_of_own(term, c, a, u), argnums=(0, 1)))(xy, U)
        assert np.isfinite(float(v)) and all(np.all(np.isfinite(np.asarray(x))) for x in g)
    # zero distance and zero Δv: t_cpa = 0, every sample inside, ℙ̂ → 1, C = 0 for row 0
    sr = jax.jit(term.series)(edge)
    assert float(sr["P"][-1, 0, 0]) == pytest.approx(1.0, abs=1e-4) and float(jnp.max(sr["t_cpa"][:, :, 0])) == 0.0
    # an empty mask: value 0; no obstacle at all (O = 0): value 0
    out = run_term(term, edge._replace(scen_valid=jnp.zeros_like(ctx.scen_valid)))
    assert np.all(np.asarray(out.value) == 0)
    empty = ctx._replace(obstacles=Trajectory(*(a[:, :0] for a in ctx.obstacles)), obs_cov=ctx.obs_cov[:0],
                         scen_valid=ctx.scen_valid[:0], scen_weight=ctx.scen_weight[:0])
    out = term(empty)
    assert np.all(np.asarray(out.value) == 0) and out.details["psbmpc2020_i"].shape == (2, 0, 2)


# ============================================================================ validation
@pytest.mark.parametrize("kw, match", [
    (dict(n_mc=0), "n_mc"), (dict(n_mc=2.5), "n_mc"), (dict(seed=-1), "seed"), (dict(event="cpa"), "event"),
    (dict(include_t0="yes"), "include_t0"), (dict(d_safe=0.0), "d_safe"), (dict(eps_v=-0.1), "eps_v"),
    (dict(q_P=-1e-5), "q_P"), (dict(r_P=0.0), "r_P"), (dict(V0=-0.3), "V0"), (dict(P0=1.5), "P0"),
    (dict(T_c=0.0), "T_c"), (dict(K_coll=-1.0), "K_coll"), (dict(kappa=-10.0), "kappa"), (dict(d_cl=0.0), "d_cl"),
    (dict(d_safe=float("nan")), "d_safe"),
])
def test_bad_term_parameters_are_refused(kw, match):
    with pytest.raises(ValueError, match=match):
        mk.Psbmpc2020Term(**kw)


def test_bad_function_arguments_are_refused():
    with pytest.raises(ValueError, match="n must"):
        mk.kf_gains(-1)
    with pytest.raises(ValueError, match="r_P"):
        mk.kf_gains(5, r_P=0.0)
    with pytest.raises(ValueError, match="n_mc"):
        mk.normal_table(jax.random.key(0), 5, 0)
    with pytest.raises(ValueError, match="S must"):
        mk.cholesky4(np.eye(3))
    with pytest.raises(ValueError, match="event"):
        mk.mcs_estimates(0.0, 0.0, 0.0, 0.0, np.eye(4), np.zeros((3, 4)), event="both")
    with pytest.raises(ValueError, match="d_safe"):
        mk.mcs_estimates(0.0, 0.0, 0.0, 0.0, np.eye(4), np.zeros((3, 4)), -1.0)
    with pytest.raises(ValueError, match="event"):
        rm.mcs_estimate((0.0, 0.0), (0.0, 0.0), np.eye(4), np.zeros((3, 4)), event="both")
