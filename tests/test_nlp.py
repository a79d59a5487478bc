"""Tests of the generic constrained solver :mod:`psbmpc_jax.nlp` (float64: conftest enables x64).

Problems share module-level functions and argument structures so that they share compilations: the
"quadratic family" (u [10, 2], f = ½ (u - c)ᵀ Q (u - c) over the raveled u) with no constraints, 4 linear
equalities (like the DOCP's 4 terminal equalities) or 2N corridor inequalities (like (28)).
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from psbmpc_jax.nlp import (CONVERGED, INFEASIBLE, MAX_ITER, NON_FINITE, SolverResult, SolverSettings, best_index,
                            max_violation, safeguard, solve_docp, solve_multistart)

assert jax.config.jax_enable_x64, "tests/conftest.py must enable float64"

N = 10                      # trajectory steps of the quadratic family, u [N, 2]
S = SolverSettings()        # passed explicitly everywhere (an omitted default is a different trace)
INF = jnp.full((N, 2), jnp.inf)


# ------------------------------------------------------------------------------------------ problems
def quad(u, a):
    d = u.ravel() - a["c"]
    return 0.5 * d @ (a["Q"] @ d)


def lin_eq(u, a):
    return a["A"] @ u.ravel() - a["b"]


def corridor(u, a):
    """Cross-track e_k = n·(u_k - P_k) inside [emin_k, emax_k]: 2N inequalities <= 0."""
    e = jnp.sum((u - a["P"]) * a["n"], axis=-1)
    return jnp.concatenate([e - a["emax"], a["emin"] - e])


def rosen(u, a):
    return jnp.sum(100.0 * (u[1:] - u[:-1] ** 2) ** 2 + (1.0 - u[:-1]) ** 2)


def double_well(u, a):
    """Nonconvex: a tilted double well per component (local minima near ±1)."""
    return jnp.sum((u ** 2 - 1.0) ** 2) + a["tilt"] @ u


def sum_eq(u, a):
    return jnp.sum(u, keepdims=True) - a["total"]


def spd(rng, n, lam_min=1.0):
    M = rng.normal(size=(n, n))
    return M @ M.T / n + lam_min * np.eye(n)


def quad_args(seed):
    rng = np.random.default_rng(seed)
    return {"Q": jnp.asarray(spd(rng, 2 * N)), "c": jnp.asarray(rng.normal(0.0, 2.0, 2 * N))}


# ------------------------------------------------------------------------------------------ basic accuracy
def test_unconstrained_convex_quadratic():
    a = quad_args(0)
    res = solve_docp(quad, jnp.zeros((N, 2)), lower=-INF, upper=INF, settings=S, args=a)
    assert int(res.status) == CONVERGED
    np.testing.assert_allclose(np.asarray(res.u).ravel(), np.asarray(a["c"]), atol=1e-6, rtol=0)
    assert float(res.f) < 1e-10
    assert res.u.shape == (N, 2) and res.u.dtype == jnp.float64


def test_box_bound_active_lands_on_bound():
    """Diagonal Q: the solution is clip(c, lower, upper); the components with c outside the box land on the
    bound (to rounding), the others reach c."""
    rng = np.random.default_rng(1)
    c = rng.normal(0.0, 2.0, 2 * N)
    a = {"Q": jnp.diag(jnp.asarray(rng.uniform(0.5, 3.0, 2 * N))), "c": jnp.asarray(c)}
    lo, hi = np.full((N, 2), -1.0), np.full((N, 2), 1.5)
    lo[:, 1] = 0.1                                              # a DOCP-like (χ, U) box: U in [0.1, 1]
    hi[:, 1] = 1.0
    res = solve_docp(quad, jnp.full((N, 2), 0.5), lower=lo, upper=hi, settings=S, args=a)
    expect = np.clip(c.reshape(N, 2), lo, hi)
    u = np.asarray(res.u)
    assert int(res.status) == CONVERGED
    active = (c.reshape(N, 2) < lo) | (c.reshape(N, 2) > hi)
    assert active.sum() >= 5 and (~active).sum() >= 3             # the case really has both kinds
    np.testing.assert_allclose(u[active], expect[active], atol=1e-9, rtol=0)
    np.testing.assert_allclose(u, expect, atol=1e-6, rtol=0)
    assert np.all(u >= lo) and np.all(u <= hi)
    assert float(res.max_violation) == 0.0


def test_equality_quadratic_matches_kkt_solution():
    rng = np.random.default_rng(2)
    a = quad_args(2)
    A = rng.normal(size=(4, 2 * N))
    b = rng.normal(size=4)
    a.update(A=jnp.asarray(A), b=jnp.asarray(b))
    Q, c = np.asarray(a["Q"]), np.asarray(a["c"])
    K = np.block([[Q, A.T], [A, np.zeros((4, 4))]])
    sol = np.linalg.solve(K, np.concatenate([Q @ c, b]))
    u_star, lam_star = sol[:2 * N], sol[2 * N:]
    res = solve_docp(quad, jnp.zeros((N, 2)), lower=-INF, upper=INF, eq=lin_eq, settings=S, args=a)
    assert int(res.status) == CONVERGED
    np.testing.assert_allclose(np.asarray(res.u).ravel(), u_star, atol=1e-5, rtol=0)
    np.testing.assert_allclose(np.asarray(res.lam_eq), lam_star, atol=1e-3 * max(1.0, np.abs(lam_star).max()))
    assert float(res.max_violation) <= 1e-5


def corridor_case():
    """u [N, 2] trajectory, reference points alternately outside both sides of a slanted corridor."""
    t_hat = np.array([math.cos(0.3), math.sin(0.3)])
    n_hat = np.array([-t_hat[1], t_hat[0]])
    P = 5.0 * np.arange(1, N + 1)[:, None] * t_hat
    emax = 2.0 + 0.1 * np.arange(N)
    emin = -1.5 - 0.05 * np.arange(N)
    e_ref = np.array([4.0, -3.0, 1.0, 6.0, -0.5, -5.0, 2.5, 0.0, 3.0, -2.0])
    ref = P + e_ref[:, None] * n_hat + np.linspace(-1.0, 1.0, N)[:, None] * t_hat
    a = {"Q": jnp.eye(2 * N), "c": jnp.asarray(ref.ravel()), "P": jnp.asarray(P),
         "n": jnp.asarray(np.tile(n_hat, (N, 1))), "emin": jnp.asarray(emin), "emax": jnp.asarray(emax)}
    e_star = np.clip(e_ref, emin, emax)
    u_star = ref + (e_star - e_ref)[:, None] * n_hat
    return a, ref, e_ref, e_star, u_star, emin, emax


def test_corridor_inequalities_land_on_the_bound():
    a, ref, e_ref, e_star, u_star, emin, emax = corridor_case()
    box = jnp.full((N, 2), 200.0)                          # inactive box, as in the DOCP (bounds always present)
    res = solve_docp(quad, jnp.asarray(ref) * 0.0 + jnp.asarray(a["P"]), lower=-box, upper=box,
                     ineq=corridor, settings=S, args=a)
    assert int(res.status) == CONVERGED
    assert float(res.max_violation) <= 1e-3
    u = np.asarray(res.u)
    e = np.sum((u - np.asarray(a["P"])) * np.asarray(a["n"]), axis=-1)
    up, down = e_ref > emax, e_ref < emin
    assert up.sum() >= 3 and down.sum() >= 2
    np.testing.assert_allclose(e[up], emax[up], atol=1e-3)
    np.testing.assert_allclose(e[down], emin[down], atol=1e-3)
    np.testing.assert_allclose(u, u_star, atol=1e-3)
    # multipliers: (u - ref) + ν n = 0 on the upper side, (u - ref) - ν n = 0 on the lower side
    nu = np.asarray(res.lam_ineq)
    np.testing.assert_allclose(nu[:N][up], (e_ref - emax)[up], atol=1e-2)
    np.testing.assert_allclose(nu[N:][down], (emin - e_ref)[down], atol=1e-2)
    assert np.all(nu[:N][~up] < 1e-6) and np.all(nu[N:][~down] < 1e-6)


def test_rosenbrock_from_standard_start():
    res = solve_docp(rosen, jnp.array([-1.2, 1.0]), lower=jnp.full(2, -jnp.inf), upper=jnp.full(2, jnp.inf),
                     settings=S, args=None)
    assert int(res.status) == CONVERGED
    np.testing.assert_allclose(np.asarray(res.u), [1.0, 1.0], atol=1e-4, rtol=0)
    assert float(res.f) < 1e-8
    assert int(res.inner_iterations) <= S.max_outer * S.max_inner


# ------------------------------------------------------------------------------------------ multi-start
MS_ARGS = {"tilt": jnp.asarray([0.3, -0.2, 0.1]), "total": jnp.asarray(0.4)}
MS_BOX = (jnp.full(3, -2.0), jnp.full(3, 2.0))
MS_STARTS = jnp.asarray(np.random.default_rng(4).uniform(-1.8, 1.8, (6, 3)))


#: absolute tolerance of "the batched solve equals the single solves": the residual fields (max_violation ~1e-7,
#: grad_norm ~1e-6 at these solutions) are near zero, where rtol means nothing; an H100 in float64 gave
#: differences of 2.5e-12 and 5.2e-12 in them (reduction order), the CPU none. 1e-10 is 1e-4 of the solver's tol
SAME_ATOL = 1e-10


def test_multistart_vmap_equals_loop_and_picks_best_feasible():
    lo, hi = MS_BOX
    multi = solve_multistart(double_well, MS_STARTS, lower=lo, upper=hi, eq=sum_eq, settings=S, args=MS_ARGS)
    assert multi.results.u.shape == (6, 3)
    loop = [solve_docp(double_well, u0, lower=lo, upper=hi, eq=sum_eq, settings=S, args=MS_ARGS) for u0 in MS_STARTS]
    for i, r in enumerate(loop):
        for name in SolverResult._fields:
            np.testing.assert_allclose(np.asarray(getattr(multi.results, name)[i]), np.asarray(getattr(r, name)),
                                       rtol=1e-9, atol=SAME_ATOL, err_msg=f"start {i}, field {name}")
    f = np.array([float(r.f) for r in loop])
    feasible = np.array([float(r.max_violation) <= S.tol for r in loop])
    assert feasible.all()
    assert len(np.unique(np.round(f, 6))) >= 2                  # the starts really reach different minima
    assert int(multi.best) == int(np.argmin(np.where(feasible, f, np.inf)))
    best = multi.best_result()
    assert float(best.f) == pytest.approx(f.min())


def test_multistart_map_equals_vmap():
    lo, hi = MS_BOX
    kw = dict(lower=lo, upper=hi, eq=sum_eq, settings=S, args=MS_ARGS)
    v = solve_multistart(double_well, MS_STARTS, **kw)
    m = solve_multistart(double_well, MS_STARTS, batch="map", **kw)
    for name in SolverResult._fields:
        np.testing.assert_allclose(np.asarray(getattr(m.results, name)), np.asarray(getattr(v.results, name)),
                                   rtol=1e-9, atol=SAME_ATOL, err_msg=name)
    assert int(m.best) == int(v.best)


def test_best_index_prefers_feasible_then_least_violation():
    f = jnp.array([1.0, -5.0, 0.5, jnp.nan])
    v = jnp.array([1e-4, 0.2, 1e-5, 0.0])
    assert int(best_index(f, v, 1e-3)) == 2                  # -5 is infeasible; NaN f never wins
    assert int(best_index(f, jnp.array([0.3, 0.2, 0.5, 0.0]), 1e-3)) == 1   # none feasible: least violation
    assert int(best_index(jnp.full(3, jnp.nan), jnp.zeros(3), 1e-3)) == 0


# ------------------------------------------------------------------------------------------ warm starts and safeguard
def test_result_cost_not_above_warm_start_on_random_convex_problems():
    for seed in range(10, 16):
        rng = np.random.default_rng(seed)
        a = quad_args(seed)
        lo = rng.uniform(-3.0, -0.5, (N, 2))
        hi = rng.uniform(0.5, 3.0, (N, 2))
        u_warm = rng.uniform(lo, hi)
        res = solve_docp(quad, jnp.asarray(u_warm), lower=lo, upper=hi, settings=S, args=a)
        f_warm = float(quad(jnp.asarray(u_warm), a))
        assert int(res.status) == CONVERGED, seed
        assert float(res.f) <= f_warm, seed
        assert float(res.max_violation) == 0.0
        kept = safeguard(res, jnp.asarray(u_warm), quad, lower=lo, upper=hi, args=a, tol=S.tol)
        assert not bool(kept.used_warm) and float(kept.f) == float(res.f)


def test_safeguard_falls_back_to_the_warm_start():
    rng = np.random.default_rng(5)
    a = quad_args(5)
    A = rng.normal(size=(4, 2 * N))
    a.update(A=jnp.asarray(A), b=jnp.asarray(rng.normal(size=4)))
    kw = dict(lower=-INF, upper=INF, eq=lin_eq, args=a, tol=1e-3)
    res = solve_docp(quad, jnp.zeros((N, 2)), lower=-INF, upper=INF, eq=lin_eq, settings=S, args=a)
    assert int(res.status) == CONVERGED
    null = np.linalg.svd(A)[2][-1].reshape(N, 2)             # a direction along which A u is unchanged
    u_feas = np.asarray(res.u) + 0.1 * null                 # a feasible warm start, slightly worse than res

    def fake(u, status=CONVERGED):
        u = jnp.asarray(u)
        return res._replace(u=u, f=quad(u, a), max_violation=max_violation(u, eq=lin_eq, args=a),
                            status=jnp.int32(status))

    # 1. the solver's optimum beats a feasible warm start: kept
    out = safeguard(res, jnp.asarray(u_feas), quad, **kw)
    assert not bool(out.used_warm)
    np.testing.assert_array_equal(np.asarray(out.u), np.asarray(res.u))
    # 2. a feasible result with a HIGHER cost than the feasible warm start: warm start
    worse = np.asarray(res.u) + 0.7 * null
    assert float(quad(jnp.asarray(worse), a)) > float(quad(jnp.asarray(u_feas), a)) > float(res.f)
    out = safeguard(fake(worse), jnp.asarray(u_feas), quad, **kw)
    assert bool(out.used_warm)
    np.testing.assert_array_equal(np.asarray(out.u), u_feas)
    assert float(out.f) == pytest.approx(float(quad(jnp.asarray(u_feas), a)))
    # 3. an infeasible result (even with a lower cost) against a feasible warm start: warm start
    infeas = fake(np.asarray(a["c"]).reshape(N, 2))             # the unconstrained minimum
    assert float(infeas.f) < float(res.f) and float(infeas.max_violation) > 1e-3
    assert bool(safeguard(infeas, jnp.asarray(u_feas), quad, **kw).used_warm)
    # 4. status 3 (non-finite) result: warm start
    assert bool(safeguard(fake(res.u, NON_FINITE), jnp.asarray(u_feas), quad, **kw).used_warm)
    # 5. both infeasible: the less infeasible one is kept
    far = jnp.asarray(u_feas) + 1.0
    near = jnp.asarray(u_feas) + 0.01
    assert not bool(safeguard(fake(near, INFEASIBLE), far, quad, **kw).used_warm)
    assert bool(safeguard(fake(far, INFEASIBLE), near, quad, **kw).used_warm)
    # 6. a stack of warm starts: the reference is the best of them (feasible first, then f), its index returned
    better = np.asarray(res.u) + 0.05 * null                     # feasible, cheaper than u_feas, dearer than res
    stack = jnp.asarray(np.stack([u_feas, np.asarray(a["c"]).reshape(N, 2), better, worse]))
    out = safeguard(fake(worse), stack, quad, **kw)              # an infeasible cheap start (1) is not the reference
    assert bool(out.used_warm) and int(out.warm_index) == 2
    np.testing.assert_array_equal(np.asarray(out.u), better)
    assert float(out.f) == pytest.approx(float(quad(jnp.asarray(better), a)))
    assert float(out.max_violation) == pytest.approx(float(max_violation(jnp.asarray(better), eq=lin_eq, args=a)))
    out = safeguard(fake(u_feas), stack, quad, **kw)             # the result is worse than start 2: replaced
    assert bool(out.used_warm) and int(out.warm_index) == 2
    out = safeguard(res, stack, quad, **kw)                      # the optimum beats every start: kept
    assert not bool(out.used_warm) and int(out.warm_index) == 2
    np.testing.assert_array_equal(np.asarray(out.u), np.asarray(res.u))
    # f and the violation of every warm start come back (no second evaluation for a caller's report)
    np.testing.assert_allclose(np.asarray(out.warm_f), [float(quad(u, a)) for u in stack], rtol=1e-12)
    np.testing.assert_allclose(np.asarray(out.warm_violation),
                               [float(max_violation(u, eq=lin_eq, args=a)) for u in stack], rtol=1e-12, atol=1e-12)
    # a stack of one is the single warm start; ties go to the lower index
    one = safeguard(fake(worse), stack[:1], quad, **kw)
    single = safeguard(fake(worse), stack[0], quad, **kw)
    assert int(one.warm_index) == int(single.warm_index) == 0
    np.testing.assert_array_equal(np.asarray(one.u), np.asarray(single.u))
    assert np.shape(one.warm_f) == (1,) and np.shape(single.warm_f) == np.shape(single.warm_violation) == ()
    assert float(single.warm_f) == float(one.warm_f[0]) == pytest.approx(float(quad(stack[0], a)), rel=1e-12)
    assert int(safeguard(fake(worse), jnp.stack([stack[2], stack[2]]), quad, **kw).warm_index) == 0
    # none feasible: the least violation is the reference
    out = safeguard(fake(far, INFEASIBLE), jnp.stack([far + 1.0, near, far]), quad, **kw)
    assert bool(out.used_warm) and int(out.warm_index) == 1


@pytest.mark.parametrize("u_warm, match", [
    (np.zeros((N + 1, 2)), r"u_warm must have the result's shape \(10, 2\) or be a stack \[W, 10, 2\]"),
    (np.zeros((2, N, 3)), r"u_warm must have the result's shape"),
    (np.zeros((0, N, 2)), "at least one warm start"),
])
def test_safeguard_rejects_warm_starts_of_another_shape(u_warm, match):
    res = solve_docp(quad, jnp.zeros((N, 2)), lower=-1.0, upper=1.0, settings=S, args=quad_args(1))
    with pytest.raises(ValueError, match=match):
        safeguard(res, u_warm, quad, lower=-1.0, upper=1.0, args=quad_args(1))


# ------------------------------------------------------------------------------------------ compilation
def test_no_recompilation_when_numeric_data_change():
    lo, hi = jnp.full((N, 2), -1.0), jnp.full((N, 2), 1.0)
    a0 = quad_args(20)
    solve_docp(quad, jnp.zeros((N, 2)), lower=lo, upper=hi, settings=S, args=a0)
    size = solve_docp.jitted._cache_size()
    outs = []
    for seed, s in [(21, S.replace(tol=1e-4, mu0=3.0)),
                    (22, S.replace(grad_tol=1e-9, rel_tol=np.float64(1e-8))),
                    (23, S.replace(growth=4.0, learning_rate=0.5, start_margin=1e-2))]:
        a = {k: np.asarray(v) for k, v in quad_args(seed).items()}        # NumPy data: converted, no recompile
        lower = -1.0 - 0.1 * seed if seed == 21 else np.asarray(lo) - 0.1 * seed  # scalar or array bounds
        outs.append(solve_docp(quad, np.full((N, 2), 0.1 * seed - 2.0), lower=lower, upper=hi + seed,
                               settings=s, args=a))
        assert solve_docp.jitted._cache_size() == size
    assert len({float(r.f) for r in outs}) == 3                 # they did solve different problems
    # a static setting does recompile (the check above can fail): projected Adam on the same problem
    adam = S.replace(method="adam", learning_rate=0.05, max_inner=200)
    res = solve_docp(quad, jnp.zeros((N, 2)), lower=lo, upper=hi, settings=adam, args=a0)
    assert solve_docp.jitted._cache_size() == size + 1
    ref = solve_docp(quad, jnp.zeros((N, 2)), lower=lo, upper=hi, settings=S, args=a0)
    assert int(res.status) in (CONVERGED, MAX_ITER) and float(res.f) == pytest.approx(float(ref.f), rel=1e-3)
    u = np.asarray(res.u)
    assert np.all(np.abs(u) <= 1.0) and np.any(np.abs(u) == 1.0)   # projection: exactly on the bound


# ------------------------------------------------------------------------------------------ validation
@pytest.mark.parametrize("field,value", [
    ("max_outer", 0), ("max_outer", 2.5), ("max_outer", True), ("max_inner", 0), ("memory_size", 0),
    ("max_linesearch_steps", 0), ("tol", 0.0), ("tol", -1e-3), ("tol", float("nan")), ("tol", "small"),
    ("rel_tol", -1.0), ("grad_tol", float("inf")), ("mu0", 0.0), ("growth", 1.0), ("mu_max", 0.5),
    ("decrease", 1.0), ("learning_rate", 0.0), ("start_margin", 0.5), ("multiplier_max", -1.0),
    ("method", "newton"), ("box_map", "sigmoid"),
])
def test_bad_settings_rejected(field, value):
    with pytest.raises(ValueError, match=f"SolverSettings.{field} must"):
        SolverSettings(**{field: value})


def test_bad_arguments_rejected():
    with pytest.raises(TypeError, match="SolverSettings"):
        solve_docp(rosen, jnp.zeros(2), lower=None, upper=None, settings={"tol": 1e-3})
    with pytest.raises(ValueError, match="lower must broadcast"):
        solve_docp(rosen, jnp.zeros(2), lower=jnp.zeros(3), upper=None, settings=S)
    with pytest.raises(ValueError, match="u0s must have a leading"):
        solve_multistart(rosen, jnp.zeros(()), lower=None, upper=None, settings=S)
    with pytest.raises(ValueError, match="batch must be one of"):
        solve_multistart(rosen, jnp.zeros((2, 2)), lower=None, upper=None, settings=S, batch="pmap")


def test_settings_numeric_fields_are_leaves():
    leaves, treedef = jax.tree_util.tree_flatten(S)
    assert len(leaves) == 10 and all(isinstance(x, float) for x in leaves)
    back = jax.tree_util.tree_unflatten(treedef, leaves)
    assert back.static == S.static and back.tol == S.tol
    assert jax.tree_util.tree_structure(S.replace(tol=1e-5)) == treedef
    assert jax.tree_util.tree_structure(S.replace(max_inner=7)) != treedef


# ------------------------------------------------------------------------------------------ non-finite values
def nan_gradient_for_positive_u0(u, a):
    """Finite VALUE everywhere, NaN GRADIENT once u[0] > 0 (the classic unguarded-where bug)."""
    x = u[0]
    return jnp.sum((u - 1.0) ** 2) + jnp.where(x > 100.0, jnp.sqrt(-x), 0.0)


def test_nan_objective_gives_status_3_without_hanging():
    # f NaN everywhere (a NaN in the data): status 3 at once, the start comes back
    a = quad_args(30)
    bad = dict(a, c=a["c"].at[3].set(jnp.nan))
    u0 = jnp.linspace(-1.0, 1.0, 2 * N).reshape(N, 2)
    res = solve_docp(quad, u0, lower=-INF, upper=INF, settings=S, args=bad)
    assert int(res.status) == NON_FINITE
    assert int(res.outer_iterations) == 0 and int(res.inner_iterations) == 0
    np.testing.assert_array_equal(np.asarray(res.u), np.asarray(u0))
    assert np.isnan(float(res.f))
    # a NaN in the start: the same
    res = solve_docp(quad, jnp.zeros((N, 2)).at[2, 1].set(jnp.nan), lower=-INF, upper=INF, settings=S, args=a)
    assert int(res.status) == NON_FINITE and int(res.inner_iterations) == 0
    # NaN gradients met on the way (u[0] > 0): the zoom line search backs off them, so the solver ends at the
    # edge of the NaN region with a finite iterate; the line search keeps failing there with a large gradient,
    # which is NOT convergence: status 1 (feasible, not converged) after the outer budget, and it terminates
    box = jnp.full(3, 5.0)
    res = solve_docp(nan_gradient_for_positive_u0, jnp.full(3, -1.0), lower=-box, upper=box, settings=S)
    assert np.all(np.isfinite(np.asarray(res.u))) and np.isfinite(float(res.f))
    assert -1e-3 < float(res.u[0]) <= 0.0
    assert float(res.grad_norm) > 1.0
    assert int(res.status) == MAX_ITER and int(res.outer_iterations) == S.max_outer
    assert int(res.inner_iterations) < S.max_outer * S.max_inner
