"""PSB-MPC + refinement (psbmpc_jax.refine, docs/refine.md): the smooth DOCP warm-started from the grid search.

Most tests share ONE compiled refinement: float64, T = 20 s, the small 30-behaviour table, situations packed to
the fixed capacities of ``conftest.CAPS`` (the ``fixed_caps`` fixture pads ``Planner.plan``'s inputs; the
direct calls pad with ``pad_arrays``), so new situations are new values, not new shapes.
"""

from __future__ import annotations

import math
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from conftest import CAPS, SMALL_BEHAVIOURS, central_difference, pad_arrays, random_situation
from psbmpc_jax import Obstacle, OwnShip, Planner, PlannerConfig, Situation
from psbmpc_jax.costs.base import TermValue, cost_term
from psbmpc_jax.costs.collision import CollisionTerm
from psbmpc_jax.costs.colregs_fuzzy import encounter_inputs_xy, fis_colregs
from psbmpc_jax.evaluate import DEFAULT_TERMS
from psbmpc_jax.nlp import solve_docp
from psbmpc_jax.objective import objective
from psbmpc_jax.refine import (FastCollisionTerm, RefineSettings, Refinement, ScenarioFuzzyColregsTerm, box,
                               behaviour_controls, problem, refine, refine_data, smooth_terms, warm_indices)
from psbmpc_jax.solve import PlannerState, solve

T = 20.0
CFG = PlannerConfig(T=T, dt=0.5, dtype="float64")
N = CFG.n_steps
SETTINGS = RefineSettings(n_starts=2, horizon=10.0)


def prepared(situation, config=CFG, state=None, behaviours=SMALL_BEHAVIOURS):
    """Padded device inputs and the grid search of ``situation`` (one compiled shape for every situation)."""
    planner = Planner(config, behaviours=behaviours)
    inputs, state, params, samples = planner.prepare(situation, state)
    inputs = pad_arrays(inputs, **CAPS, junk=False)
    plan, _, ev = solve(inputs, state, params, samples, config=config)
    return inputs, state, params, samples, plan, ev


@partial(jax.jit, static_argnames=("config", "smooth"))
def per_step_objective(controls, inputs, params, samples, last_offsets, terms, config=CFG, smooth=True):
    """psbmpc_jax.objective of per-step controls, jitted: the oracles below call it with many situations of one
    padded shape, and the eager form dispatched thousands of small ops per call (18 s for the first)."""
    return objective(controls, inputs, params, samples, config, terms, last_offsets=last_offsets, per_step=True,
                     smooth=smooth)[0]


#: its value and gradient in the controls (one compilation per term set, shared by the parametrised cases)
per_step_value_and_grad = jax.jit(jax.value_and_grad(per_step_objective))


def smooth_f(controls, inputs, state, params, samples, config=CFG, settings=SETTINGS):
    """The oracle: psbmpc_jax.objective with the refinement's smooth terms (per step, smooth)."""
    n_m = SMALL_BEHAVIOURS.shape[1] if settings.path_changes == "grid" else None
    terms = smooth_terms(DEFAULT_TERMS, settings.colregs, settings.path_eps, settings.fis_e_cl, settings.fis_n_y,
                         path_maneuvers=n_m)
    return per_step_objective(controls, inputs, params, samples, jnp.asarray(state.last_offsets), terms, config)


def finite(ref: Refinement) -> bool:
    leaves = jax.tree.leaves(ref)
    return all(bool(np.all(np.isfinite(np.asarray(x, float)))) for x in leaves)


# ------------------------------------------------------------------------------------------ the cost terms
def path_oracle(controls, last, p, eps, n_maneuvers):
    """Float64 NumPy H_p of per-step ``controls [n, 2]`` (SmoothPathTerm's definition, docs/refine.md C-R-3)."""
    u, chi = controls[:, 0], controls[:, 1]
    n = len(u)
    sabs = lambda x: np.sqrt(x * x + eps * eps) - eps  # noqa: E731
    f = p["K_u"] * (1 - u) + np.where(chi < 0, p["K_chi_port"], p["K_chi_stbd"]) * chi ** 2

    def h(u1, c1, u0, c0):
        d = (c1 - c0 + np.pi) % (2 * np.pi) - np.pi
        return p["K_du"] * sabs(u1 - u0) + np.where(d < 0, p["K_dchi_port"], p["K_dchi_stbd"]) * d * d

    m = n if n_maneuvers is None else n_maneuvers
    return (f.sum() / n + h(u[0], chi[0], last[0], last[1]) / m
            + h(u[1:], chi[1:], u[:-1], chi[:-1]).sum() / max(m - 1, 1))


def test_smooth_path_term_against_its_oracle_and_equal_to_the_grid_on_a_behaviour():
    """Random per-step controls, both change weightings, against the float64 oracle; with the grid's n_M the
    per-step form of a behaviour (equal maneuver blocks) costs exactly the grid's H_p (eps = 0), while the
    per-control form makes its change n/n_M times cheaper."""
    from types import SimpleNamespace

    from psbmpc_jax.costs.path import path_cost
    from psbmpc_jax.refine import SmoothPathTerm

    params = Planner(CFG).params
    p = {k: float(getattr(params, k)) for k in SmoothPathTerm.PARAMS}
    rng = np.random.default_rng(3)
    for n_m in (None, 1, 2, 3):
        for _ in range(3):
            c = np.stack([rng.uniform(0.0, 1.0, 12), rng.uniform(-1.5, 1.5, 12)], axis=-1)
            last = np.array([rng.uniform(0, 1), rng.uniform(-1, 1)])
            ctx = SimpleNamespace(offsets=jnp.asarray(c)[None], last_offsets=jnp.asarray(last))
            got = float(SmoothPathTerm(eps=0.02, n_maneuvers=n_m)(ctx, params, CFG, None).value[0])
            np.testing.assert_allclose(got, path_oracle(c, last, p, 0.02, n_m), rtol=1e-12)
    behaviour = np.array([[0.5, 0.4], [1.0, -0.3]])
    last = np.array([1.0, 0.0])
    per_step = np.repeat(behaviour, 20, axis=0)                                     # N = 40, two equal blocks
    grid = float(path_cost(jnp.asarray(behaviour)[None], jnp.asarray(last), params)[0])
    ctx = SimpleNamespace(offsets=jnp.asarray(per_step)[None], last_offsets=jnp.asarray(last))
    same = float(SmoothPathTerm(eps=0.0, n_maneuvers=2)(ctx, params, CFG, None).value[0])
    np.testing.assert_allclose(same, grid, rtol=1e-12)
    cheaper = float(SmoothPathTerm(eps=0.0)(ctx, params, CFG, None).value[0])
    assert cheaper < grid
    with pytest.raises(ValueError, match="n_maneuvers"):
        SmoothPathTerm(n_maneuvers=0)
    # differentiable, finite at a zero change (the smoothed |du|), both weightings
    for n_m in (None, 2):
        g = jax.grad(lambda x: SmoothPathTerm(eps=0.01, n_maneuvers=n_m)(
            SimpleNamespace(offsets=x[None], last_offsets=jnp.asarray([1.0, 0.0])), params, CFG, None).value[0])(
            jnp.asarray(np.tile([1.0, 0.0], (5, 1))))
        assert np.all(np.isfinite(np.asarray(g)))
    # the gradient against central differences at random interior points (changes away from 0 and ±π)
    for n_m in (None, 2):
        c = np.stack([rng.uniform(0.2, 0.9, 6), rng.uniform(-0.6, 0.6, 6)], axis=-1)
        fn = lambda x, n_m=n_m: SmoothPathTerm(eps=0.02, n_maneuvers=n_m)(  # noqa: E731
            SimpleNamespace(offsets=jnp.asarray(x)[None], last_offsets=jnp.asarray([0.7, 0.1])), params, CFG,
            None).value[0]
        np.testing.assert_allclose(np.asarray(jax.grad(fn)(jnp.asarray(c))), central_difference(fn, c), rtol=1e-6,
                                   atol=1e-8)



@cost_term
class NaiveFuzzyColregs:
    """κ Σ w P max_k μ_FIS by the dense max (the definition of ScenarioFuzzyColregsTerm)."""

    name = "colregs"

    def __call__(self, ctx, params, config, samples):
        own, obs = ctx.own, ctx.obstacles
        n_t = own.x.shape[0]
        n_o, n_s = ctx.scen_weight.shape
        fl = lambda a: a.reshape(n_t, n_o * n_s)[:, :, None]  # noqa: E731
        dcog, rb, d = encounter_inputs_xy(own.x[:, None], own.y[:, None], own.chi[:, None], fl(obs.x), fl(obs.y),
                                          fl(obs.chi))
        mu = fis_colregs(dcog, rb, d, d_cl=params.d_close, e_cl=5.0, n_y=201)
        mu = jnp.where(ctx.scen_valid.reshape(-1)[None, :, None], mu, 0.0)
        mu = jnp.max(mu, axis=0).T.reshape(-1, n_o, n_s)
        return TermValue(params.kappa * jnp.sum(ctx.scen_weight[None] * mu, axis=(1, 2)))


@pytest.mark.parametrize("seed", [0, 2])
def test_fast_terms_equal_their_dense_definitions(seed):
    """FastCollisionTerm == CollisionTerm and ScenarioFuzzyColregsTerm == the dense max, value and gradient
    (float64), also when the active points overflow the collision term's capacity (several chunks)."""
    inputs, state, params, samples, _, _ = prepared(random_situation(seed, T=T))
    rng = np.random.default_rng(seed)
    u = jnp.asarray(np.stack([rng.uniform(0.3, 1.0, N), rng.uniform(-0.8, 0.8, N)], axis=1))
    pairs = [((CollisionTerm(),), (FastCollisionTerm(),)), ((CollisionTerm(),), (FastCollisionTerm(capacity=3),)),
             ((NaiveFuzzyColregs(),), (ScenarioFuzzyColregsTerm(),))]
    last = jnp.asarray([1.0, 0.0])                                     # objective's default
    for dense, fast in pairs:
        va, ga = per_step_value_and_grad(u, inputs, params, samples, last, dense)
        vb, gb = per_step_value_and_grad(u, inputs, params, samples, last, fast)
        assert float(va) > 0
        np.testing.assert_allclose(float(vb), float(va), rtol=1e-12)
        np.testing.assert_allclose(np.asarray(gb), np.asarray(ga), rtol=1e-9, atol=1e-12 * float(jnp.max(jnp.abs(ga))))


# ------------------------------------------------------------------------------------------ the refinement
@pytest.mark.parametrize("seed", [0, 1, 3, 4, 5])
def test_refined_smooth_cost_not_above_warm_cost(seed):
    inputs, state, params, samples, plan, ev = prepared(random_situation(seed, T=T))
    r = refine(inputs, plan, state, params, samples, CFG, SETTINGS, evaluation=ev)
    assert finite(r)
    assert float(r.cost) <= float(r.warm_cost) * (1 + 1e-12)
    assert r.controls.shape == (N, 2) and r.apply.shape == (2,)
    np.testing.assert_array_equal(np.asarray(r.apply), np.asarray(r.controls[0]))
    # the reported costs are the oracle's: the smooth objective and the grid's cost of the kept controls
    np.testing.assert_allclose(float(r.cost), float(smooth_f(r.controls, inputs, state, params, samples)), rtol=1e-9)
    grid = per_step_objective(r.controls, inputs, params, samples, jnp.asarray(state.last_offsets), DEFAULT_TERMS,
                              smooth=False)
    np.testing.assert_allclose(float(r.grid_cost), float(grid), rtol=1e-9)
    # the warm cost is the lowest smooth cost over the warm starts, the grid's choice first
    idx = warm_indices(plan.best, ev, inputs, params, CFG, SETTINGS.n_starts)
    assert int(idx[0]) == int(plan.best)
    warm = [smooth_f(behaviour_controls(inputs.behaviours.offsets[i], params, CFG), inputs, state, params, samples)
            for i in np.asarray(idx)]
    np.testing.assert_allclose(float(r.warm_cost), min(float(w) for w in warm), rtol=1e-9)
    # inside the table's box; the controls beyond the refine horizon are the kept start's behaviour
    lo, hi = (np.asarray(b) for b in box(inputs.behaviours))
    c = np.asarray(r.controls)
    assert np.all(c >= lo - 1e-12) and np.all(c <= hi + 1e-12) and float(r.violation) == 0.0
    tail = np.asarray(behaviour_controls(inputs.behaviours.offsets[int(r.behaviour)], params, CFG))[20:]
    np.testing.assert_array_equal(c[20:], tail)
    assert int(idx[int(r.start_index)]) == int(r.behaviour)


def test_refinement_improves_a_head_on():
    """A head-on 10 m to starboard: the refinement lowers the smooth cost strictly (not the warm start)."""
    own = OwnShip(state=[0.0, 0.0, 0.0, 2.0], waypoints=[[0.0, 0.0], [400.0, 0.0]], U_d=2.0)
    target = Obstacle(state=[60.0, 10.0, -2.0, 0.0], cov=np.diag([4.0, 4.0, 0.05, 0.05]), n_ps=3)
    inputs, state, params, samples, plan, ev = prepared(Situation(own, (target,)))
    r = refine(inputs, plan, state, params, samples, CFG, SETTINGS, evaluation=ev)
    assert not bool(r.used_warm)
    assert float(r.cost) < float(r.warm_cost) - 1e-6


def test_evaluation_is_optional():
    inputs, state, params, samples, plan, ev = prepared(random_situation(1, T=T))
    a = refine(inputs, plan, state, params, samples, CFG, SETTINGS, evaluation=ev)
    n0 = refine.jitted._cache_size()
    b = refine(inputs, plan, state, params, samples, CFG, SETTINGS)
    np.testing.assert_allclose(np.asarray(b.controls), np.asarray(a.controls), rtol=1e-12, atol=1e-12)
    assert refine.jitted._cache_size() == n0        # the grid is evaluated outside: one compiled refinement


def test_multistart_vmap_equals_map_equals_loop():
    inputs, state, params, samples, plan, ev = prepared(random_situation(3, T=T))
    s = SETTINGS
    by_map = refine(inputs, plan, state, params, samples, CFG, s, evaluation=ev)
    by_vmap = refine(inputs, plan, state, params, samples, CFG, s.replace(batch="vmap"), evaluation=ev)
    for a, b in zip(jax.tree.leaves(by_map), jax.tree.leaves(by_vmap)):
        np.testing.assert_allclose(np.asarray(a, float), np.asarray(b, float), rtol=1e-9, atol=1e-9)
    # loop: every start solved on its own with the library solver; the best (lowest f) is the kept one
    idx = warm_indices(plan.best, ev, inputs, params, CFG, s.n_starts)
    f, f_full = problem(CFG, 20, 1)
    terms = smooth_terms(path_maneuvers=SMALL_BEHAVIOURS.shape[1])
    data = refine_data(inputs, jnp.asarray(state.last_offsets), params, CFG, terms)
    lo, hi = box(inputs.behaviours)
    results = []
    for i in np.asarray(idx):
        warm = behaviour_controls(inputs.behaviours.offsets[i], params, CFG)
        res = solve_docp(f, warm[:20], lower=jnp.broadcast_to(lo, (20, 2)), upper=jnp.broadcast_to(hi, (20, 2)),
                         settings=s.solver, args=(data, warm[20:]))
        results.append((float(res.f), np.concatenate([np.asarray(res.u), np.asarray(warm[20:])])))
    best = min(range(s.n_starts), key=lambda k: results[k][0])
    if not bool(by_map.used_warm):
        assert int(by_map.start_index) == best
        np.testing.assert_allclose(np.asarray(by_map.controls), results[best][1], rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(float(by_map.cost), results[best][0], rtol=1e-9)


def test_no_recompilation_when_values_change():
    inputs, state, params, samples, plan, ev = prepared(random_situation(4, T=T))
    refine(inputs, plan, state, params, samples, CFG, SETTINGS, evaluation=ev)
    n0 = refine.jitted._cache_size()
    inputs2, state2, params2, samples2, plan2, ev2 = prepared(random_situation(5, T=T), state=PlannerState((0.5, 0.2)))
    params2 = params2.replace(K_coll=jnp.asarray(40.0, jnp.float64), kappa=jnp.asarray(3.0, jnp.float64))
    s2 = SETTINGS.replace(solver=SETTINGS.solver.replace(rel_tol=1e-3, start_margin=0.01), path_eps=0.05,
                          fis_e_cl=8.0)
    r = refine(inputs2, plan2, state2, params2, samples2, CFG, s2, evaluation=ev2)
    assert finite(r)
    assert refine.jitted._cache_size() == n0


def test_gradient_of_the_refine_objective_matches_finite_differences():
    """FD check of the function the solver minimises (decision blocks + tail), float64, central differences
    along random directions at interior points of the box."""
    inputs, state, params, samples, plan, ev = prepared(random_situation(0, T=T))
    f, _ = problem(CFG, 20, 2)
    data = refine_data(inputs, jnp.asarray(state.last_offsets), params, CFG, smooth_terms())
    rng = np.random.default_rng(7)
    tail = jnp.asarray(np.tile([[1.0, 0.1]], (N - 20, 1)))
    f_z = lambda z: f(z, (data, tail))  # noqa: E731
    fz = jax.jit(f_z)                                           # the differences: one compiled evaluation
    g = jax.jit(jax.value_and_grad(f_z))
    for _ in range(3):
        z = jnp.asarray(np.stack([rng.uniform(0.4, 0.95, 10), rng.uniform(-0.7, 0.7, 10)], axis=1))
        _, grad = g(z)
        v = jnp.asarray(rng.normal(size=z.shape))
        h = 1e-6
        fd = (float(fz(z + h * v)) - float(fz(z - h * v))) / (2 * h)
        an = float(jnp.sum(grad * v))
        assert math.isfinite(an)
        np.testing.assert_allclose(an, fd, rtol=2e-4, atol=1e-6 * max(1.0, abs(fd)))


@pytest.mark.parametrize("field, value", [
    ("n_starts", 0), ("n_starts", 2.5), ("n_starts", True), ("batch", "pmap"), ("horizon", -1.0),
    ("horizon", float("nan")), ("horizon", "60"), ("colregs", "boolean"), ("solver", {"max_inner": 3}),
    ("block", 0), ("path_eps", -0.1), ("fis_e_cl", 0.0), ("fis_n_y", 1), ("pc_capacity", 0),
    ("path_changes", "maneuver"),
])
def test_bad_settings_rejected(field, value):
    with pytest.raises(ValueError, match=f"RefineSettings.{field}"):
        RefineSettings(**{field: value})


def test_settings_that_do_not_fit_the_problem_are_rejected():
    inputs, state, params, samples, plan, ev = prepared(random_situation(0, T=T))
    with pytest.raises(ValueError, match="RefineSettings.horizon"):
        refine(inputs, plan, state, params, samples, CFG, RefineSettings(horizon=20.25), evaluation=ev)
    with pytest.raises(ValueError, match="RefineSettings.horizon"):
        refine(inputs, plan, state, params, samples, CFG, RefineSettings(horizon=30.0), evaluation=ev)
    with pytest.raises(ValueError, match="RefineSettings.n_starts"):
        refine(inputs, plan, state, params, samples, CFG, RefineSettings(n_starts=65), evaluation=ev)
    with pytest.raises(ValueError, match="refine must be"):
        Planner(CFG, behaviours=SMALL_BEHAVIOURS).plan(random_situation(0, T=T), refine={"n_starts": 2})
    with pytest.raises(ValueError, match="RefineSettings.horizon"):
        Planner(CFG, behaviours=SMALL_BEHAVIOURS).plan(random_situation(0, T=T), refine=RefineSettings(horizon=21.0))


# ------------------------------------------------------------------------------------------ the planner
def _head_on(**own_kw) -> Situation:
    own = OwnShip(state=[0.0, 0.0, 0.0, 2.0], waypoints=[[0.0, 0.0], [400.0, 0.0]], U_d=2.0, **own_kw)
    target = Obstacle(state=[60.0, 2.0, -2.0, 0.0], cov=np.diag([4.0, 4.0, 0.05, 0.05]), n_ps=3)
    return Situation(own, (target,))


def _land_strip():
    return np.array([[20.0, 15.0], [60.0, 15.0], [60.0, 40.0], [20.0, 40.0]])


@pytest.mark.parametrize("case", ["obstacles", "obstacles_and_land", "land_only", "nothing"])
def test_planner_refine_with_and_without_obstacles_and_land(case, fixed_caps):
    base = _head_on()
    obstacles = base.obstacles if "obstacles" in case else ()
    polygons = (_land_strip(),) if "land" in case else ()
    sit = Situation(base.own_ship, obstacles, polygons)
    planner = Planner(CFG, behaviours=SMALL_BEHAVIOURS)
    state = PlannerState((1.0, 0.1))
    plain, plain_state = planner.plan(sit, state)
    res, nxt = planner.plan(sit, state, refine=SETTINGS)
    assert plain.refined is None and res.refined is not None
    assert res.best_index == plain.best_index                     # the grid search itself is unchanged
    r = res.refined
    assert finite(r) and isinstance(r.controls, np.ndarray) and r.controls.shape == (N, 2)
    assert nxt.last_offsets == tuple(float(v) for v in r.apply)
    assert float(r.cost) <= float(r.warm_cost) * (1 + 1e-12)
    assert set(r.costs) == {"do", "colregs", "so", "path"}
    # trajectory in the user's frame: it starts at the own-ship
    np.testing.assert_allclose(r.trajectory[0], sit.own_ship.state, atol=1e-9)
    assert res.refine_time_s > 0


def test_refine_none_is_the_grid_search_unchanged(fixed_caps):
    sit = random_situation(2, T=T)
    planner = Planner(CFG, behaviours=SMALL_BEHAVIOURS)
    a, sa = planner.plan(sit)
    b, sb = planner.plan(sit, refine=None)
    assert a.best_index == b.best_index and sa.last_offsets == sb.last_offsets == (a.u_opt, a.chi_opt)
    for k in a.costs:
        np.testing.assert_array_equal(a.costs[k], b.costs[k])
    assert b.refined is None and b.refine_time_s is None


def test_origin_invariance_float32():
    """The same situation shifted by UTM-sized offsets gives the same refined controls (float32)."""
    cfg = PlannerConfig(T=T, dt=0.5)
    settings = RefineSettings(n_starts=2, horizon=10.0)
    base = random_situation(1, T=T, n_polygons=1)

    def shifted(sit, d):
        d = np.asarray(d, float)
        own = sit.own_ship
        o = OwnShip(state=np.r_[own.state[:2] + d, own.state[2:]], waypoints=np.asarray(own.waypoints) + d,
                    U_d=own.U_d, length=own.length, width=own.width)
        obs = tuple(Obstacle(state=np.r_[ob.state[:2] + d, ob.state[2:]], cov=ob.cov, length=ob.length,
                             width=ob.width, waypoints=None if ob.waypoints is None else np.asarray(ob.waypoints) + d,
                             n_ps=ob.n_ps, probs=ob.probs, weight=ob.weight, zeta=ob.zeta) for ob in sit.obstacles)
        polys = tuple(np.asarray(p) + d for p in sit.polygons)
        return Situation(o, obs, polys)

    out = []
    for d in ((0.0, 0.0), (7_034_567.3, 569_871.9)):
        planner = Planner(cfg, behaviours=SMALL_BEHAVIOURS)
        res, _ = planner.plan(shifted(base, d), refine=settings)
        out.append(res)
    a, b = out[0].refined, out[1].refined
    assert out[0].best_index == out[1].best_index
    # float32 rounding of the (differently shifted) local positions, amplified by the iterations of the solver:
    # measured 2.5e-4 rad at most (of a 0.78 rad offset), the costs to 1e-6 relative
    np.testing.assert_allclose(b.controls, a.controls, atol=1e-3)
    np.testing.assert_allclose(b.cost, a.cost, rtol=1e-4)
    np.testing.assert_allclose(b.grid_cost, a.grid_cost, rtol=1e-4)
    np.testing.assert_allclose(b.trajectory[:, :2] - np.asarray((7_034_567.3, 569_871.9)), a.trajectory[:, :2],
                               atol=0.05)


# ------------------------------------------------------------------------------------------ edges
def test_no_nan_at_the_edges(fixed_caps):
    planner = Planner(CFG, behaviours=SMALL_BEHAVIOURS)
    inside = OwnShip(state=[40.0, 25.0, 0.0, 2.0], waypoints=[[40.0, 25.0], [400.0, 25.0]], U_d=2.0)
    on_top = Obstacle(state=[0.0, 0.0, -2.0, 0.0], cov=np.diag([4.0, 4.0, 0.05, 0.05]), n_ps=3)
    base = _head_on()
    cases = {
        "own-ship inside land": Situation(inside, base.obstacles, (_land_strip(),)),
        "obstacle at the own-ship": Situation(base.own_ship, (on_top,), ()),
        "zero obstacles": Situation(base.own_ship, (), ()),
        "stopped own-ship": Situation(OwnShip(state=[0.0, 0.0, 0.0, 0.0], waypoints=[[0.0, 0.0], [400.0, 0.0]],
                                              U_d=2.0), (on_top,), (_land_strip(),)),
    }
    for name, sit in cases.items():
        res, nxt = planner.plan(sit, refine=SETTINGS)
        r = res.refined
        assert finite(r), name
        assert float(r.cost) <= float(r.warm_cost) * (1 + 1e-12), name
        assert 0.0 <= nxt.last_offsets[0] <= 1.0, name


# ------------------------------------------------------------------------------------------ the bench preset
def test_bench_refine_preset_is_accepted_and_checked():
    import argparse

    from psbmpc_jax.apps.bench import add_bench_arguments, build_plan
    from psbmpc_jax.apps.bench_refine import REFINE_CASES

    ap = argparse.ArgumentParser()
    add_bench_arguments(ap)
    assert build_plan(ap.parse_args(["--preset", "refine"])) == []
    for extra in (["--n-ps", "3"], ["--T", "60"], ["--n-do", "1"], ["--dt", "1.0"]):
        with pytest.raises(ValueError, match=extra[0]):
            build_plan(ap.parse_args(["--preset", "refine", *extra]))
    assert {c[0] for c in REFINE_CASES} == {"nidelva", "nidelva_u10", "nidelva_T60", "paper000"}
    from psbmpc_jax.presets import build_mpc

    for case, overrides, *_ in REFINE_CASES:                  # every case's overrides are valid config fields
        assert build_mpc("nidelva", overrides)[0].replace(**overrides) is not None, case
    assert any(c[3] == 1 for c in REFINE_CASES) and any(c[3] == 16 and c[4] == "vmap" for c in REFINE_CASES)


def test_previous_plan_start():
    """``previous_start``: the previous refinement (``PlannerState.warm_start``) is start 1.  Without one (None
    or NaN throughout) the result equals the plain refinement; re-refining a situation from its own refined plan
    ends no higher (the plan is a warm start, and the safeguard keeps the lowest of them); the warm cost is the
    lowest over the grid's choice, the previous plan and the runner-ups.  One compilation for all of it."""
    s = SETTINGS.replace(previous_start=True)                     # 2 starts: the grid's choice, then the plan
    inputs, state, params, samples, plan, ev = prepared(random_situation(1, T=T))
    plain = refine(inputs, plan, state, params, samples, CFG, SETTINGS, evaluation=ev)
    n0 = None
    for none in (None, np.full((N, 2), np.nan)):
        r = refine(inputs, plan, PlannerState(state.last_offsets, none), params, samples, CFG, s, evaluation=ev)
        np.testing.assert_allclose(np.asarray(r.controls), np.asarray(plain.controls), rtol=0, atol=1e-12)
        assert int(r.behaviour) >= 0
        n0 = refine.jitted._cache_size() if n0 is None else n0
    prev = np.asarray(plain.controls)
    again = refine(inputs, plan, PlannerState(state.last_offsets, prev), params, samples, CFG, s, evaluation=ev)
    assert refine.jitted._cache_size() == n0                              # a previous plan is a value
    assert finite(again)
    assert float(again.cost) <= float(plain.cost) * (1 + 1e-12) + 1e-12
    f_prev = float(smooth_f(jnp.asarray(prev), inputs, state, params, samples, settings=s))
    assert float(again.warm_cost) <= f_prev * (1 + 1e-12)
    # a plan from elsewhere (e.g. the last one, shifted): start 1, index -1 when it is the kept one
    from psbmpc_jax.numerics import shift_controls

    rng = np.random.default_rng(0)
    other = np.stack([rng.uniform(0.5, 1.0, N), rng.uniform(-0.5, 0.5, N)], axis=-1)
    r = refine(inputs, plan, PlannerState(state.last_offsets, shift_controls(other, 3)), params, samples, CFG, s,
               evaluation=ev)
    assert finite(r) and float(r.cost) <= float(r.warm_cost) * (1 + 1e-12)
    assert (int(r.behaviour) == -1) == (int(r.start_index) == 1)


@pytest.mark.parametrize("warm_start, settings, match", [
    (np.zeros((N, 2)), SETTINGS, r"warm_start is only used with RefineSettings\(previous_start=True\)"),
    (np.zeros((N - 1, 2)), SETTINGS.replace(previous_start=True), r"warm_start must be .*\[40, 2\]"),
    (np.tile([1.5, 0.0], (N, 1)), SETTINGS.replace(previous_start=True), "speed factors in"),
    (np.where(np.arange(N)[:, None] == 3, np.nan, np.full((N, 2), 0.5)), SETTINGS.replace(previous_start=True),
     "finite"),
])
def test_bad_previous_plan_rejected(warm_start, settings, match):
    inputs, state, params, samples, plan, ev = prepared(random_situation(0, T=T))
    with pytest.raises(ValueError, match=match):
        refine(inputs, plan, PlannerState(state.last_offsets, warm_start), params, samples, CFG, settings,
               evaluation=ev)
    with pytest.raises(ValueError, match="RefineSettings.previous_start"):
        RefineSettings(n_starts=1, previous_start=True)
    with pytest.raises(ValueError, match="RefineSettings.previous_start"):
        RefineSettings(previous_start=1)


def test_refine_rollout_follows_the_configs_unroll():
    """The refinement's own-ship rollout (what its smooth objective differentiates) takes
    ``PlannerConfig.rollout_unroll`` (a GPU runs each loop step as a kernel launch): with 10 steps per loop step
    the trajectory and the gradient of a function of it equal those with 1 (float64), and the sequential depth
    drops by about 10x."""
    from psbmpc_jax.depth import sequential_depth_only
    from psbmpc_jax.refine import rollout

    inputs, state, params, samples, plan, ev = prepared(random_situation(0, T=T))
    data = refine_data(inputs, jnp.asarray(state.last_offsets), params, CFG, smooth_terms())
    c = jnp.asarray(np.stack([np.linspace(0.5, 0.9, N), np.linspace(-0.5, 0.5, N)], axis=1))
    out = {}
    for u in (1, 10):
        cfg = CFG.replace(rollout_unroll=u)
        g = lambda c, cfg=cfg: jnp.sum(jnp.sin(rollout(c, data, cfg).x) + rollout(c, data, cfg).chi)  # noqa: E731
        out[u] = jax.jit(jax.value_and_grad(g))(c)
        out[f"depth{u}"] = sequential_depth_only(lambda c, cfg=cfg: rollout(c, data, cfg).x, c).depth
    np.testing.assert_allclose(float(out[10][0]), float(out[1][0]), rtol=1e-12)
    np.testing.assert_allclose(np.asarray(out[10][1]), np.asarray(out[1][1]), rtol=1e-10, atol=1e-12)
    assert out["depth1"] >= N and out["depth10"] <= out["depth1"] // 10 + 2, out


def test_the_refinement_traces_its_objective_few_times(monkeypatch):
    """A structural guard on the refinement's program size (its compile time is most of this file's): the smooth
    objective is one jitted function, so the solver's start, line search, checks, safeguard and reported costs
    reuse one trace instead of tracing the cost terms at every site (10 traces, 126 000 StableHLO lines before;
    4 and about 77 000 after, with bit-identical results)."""
    import psbmpc_jax.refine as R

    inputs, state, params, samples, plan, ev = prepared(random_situation(0, T=T))
    captured = {}
    monkeypatch.setattr(R, "_refine_jit", lambda *a, **k: captured.update(a=a, k=k))
    R.refine(inputs, plan, state, params, samples, CFG, SETTINGS, evaluation=ev)
    monkeypatch.undo()
    traces = []
    real = R.term_costs
    monkeypatch.setattr(R, "term_costs", lambda *a, **k: (traces.append(1), real(*a, **k))[1])
    R.problem.cache_clear()                 # the objective's jit is made (and traced) afresh under the counter
    # make_jaxpr traces afresh (jax.jit would reuse a trace of _refine that an earlier test in this process made)
    jax.make_jaxpr(partial(R._refine, **captured["k"]))(*captured["a"])
    assert 1 <= len(traces) <= 4, len(traces)
