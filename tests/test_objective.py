"""The differentiable objective: grid search == vmap(objective), finite-difference gradients, no NaN at the
edges, and a new cost term added by one module plus its reference counterpart."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from psbmpc_jax import DEFAULT_TERMS, Obstacle, OwnShip, Params, Planner, PlannerConfig, Situation, cost_term
from psbmpc_jax import reference as ref_mod
from psbmpc_jax.costs.base import TermValue, check_terms
from psbmpc_jax.evaluate import evaluate
from psbmpc_jax.objective import objective, value_and_grad
from psbmpc_jax.obstacles import ou_covariance
from psbmpc_jax.solve import solve

from conftest import SMALL_BEHAVIOURS, central_difference, random_situation

T = 30.0
BASE = dict(T=T, dt=0.5, n_samples=128, dtype="float64")
TERM_NAMES = ("do", "colregs", "so", "path")


def cfg64(estimator="quadrature", grounding_mode="exact", **kw):
    return PlannerConfig(estimator=estimator, grounding_mode=grounding_mode, **{**BASE, **kw})


def prepared(seed, config, situation=None):
    planner = Planner(config, behaviours=SMALL_BEHAVIOURS)
    sit = situation or random_situation(seed, n_polygons=2)
    key = jax.random.key(seed) if config.estimator != "quadrature" else None
    return planner.prepare(sit, key=key)


# ============================================================================ grid search == vmap(objective)
@pytest.mark.parametrize("grounding_mode", ["exact", "grid"])
@pytest.mark.parametrize("estimator", ["quadrature", "mc", "ce"])
def test_grid_search_equals_vmap_objective(estimator, grounding_mode):
    cfg = cfg64(estimator, grounding_mode)
    inputs, state, params, samples = prepared(4, cfg)
    last = jnp.asarray([0.5, 0.1])
    ev = evaluate(inputs, last, params, samples, config=cfg)
    table = jnp.asarray(SMALL_BEHAVIOURS)
    fn = jax.jit(jax.vmap(lambda c: objective(c, inputs, params, samples, cfg, last_offsets=last)))
    total, costs = fn(table)
    b = len(SMALL_BEHAVIOURS)
    got_total = np.asarray(ev.total)[:b]
    assert np.all(np.isfinite(got_total))
    np.testing.assert_allclose(np.asarray(total), got_total, rtol=1e-9, atol=1e-12)
    for name in TERM_NAMES:
        np.testing.assert_allclose(np.asarray(costs[name]), np.asarray(ev.costs[name])[:b], rtol=1e-9, atol=1e-12,
                                   err_msg=name)
    # not vacuous: collision, grounding and path all vary across the table
    for name in ("do", "so", "path"):
        assert np.ptp(np.asarray(costs[name])) > 0, name


# ============================================================================ finite differences


def term_fn(name, inputs, params, samples, cfg, per_step=False):
    def f(c):
        total, costs = objective(c, inputs, params, samples, cfg, per_step=per_step)
        return total if name == "total" else costs[name]
    return jax.jit(f)


FD_NAMES = ("total", "do", "so", "path")


def terms_vector_fn(inputs, params, samples, cfg, per_step=False):
    """[total, do, so, path] of one control input (one compile for all the checked terms)."""
    def f(c):
        total, costs = objective(c, inputs, params, samples, cfg, per_step=per_step)
        return jnp.stack([total] + [costs[n] for n in FD_NAMES[1:]])
    return jax.jit(f)


@pytest.mark.parametrize("grounding_mode", ["exact", "grid"])
def test_gradient_per_maneuver_matches_finite_differences(grounding_mode):
    cfg = cfg64(grounding_mode=grounding_mode)
    inputs, _, params, samples = prepared(4, cfg)
    rng = np.random.default_rng(7)
    f = terms_vector_fn(inputs, params, samples, cfg)
    jac = jax.jit(jax.jacrev(f))
    checked = np.zeros(len(FD_NAMES), int)
    for _ in range(3):
        c = np.stack([rng.uniform(0.4, 0.9, 2), rng.uniform(-0.6, 0.6, 2)], axis=-1)     # [n_M = 2, 2]
        g = np.asarray(jac(jnp.asarray(c)))                                            # [terms, n_M, 2]
        fd = np.moveaxis(central_difference_vec(lambda x: np.asarray(f(jnp.asarray(x))), c), -1, 0)
        assert np.all(np.isfinite(g))
        for k, name in enumerate(FD_NAMES):
            scale = max(1.0, float(np.abs(fd[k]).max()))
            np.testing.assert_allclose(g[k], fd[k], rtol=2e-4, atol=1e-6 * scale, err_msg=name)
            checked[k] += np.abs(fd[k]).max() > 1e-8
    assert np.all(checked >= 2), f"a gradient was ~0 everywhere (vacuous check): {dict(zip(FD_NAMES, checked))}"


def central_difference_vec(f, x, h=1e-6):
    """Central differences of a vector-valued f: ``[x.shape..., n_out]``."""
    x = np.asarray(x, float)
    out = None
    for idx in np.ndindex(x.shape):
        e = np.zeros_like(x)
        e[idx] = h
        col = (f(x + e) - f(x - e)) / (2 * h)
        if out is None:
            out = np.zeros(x.shape + col.shape)
        out[idx] = col
    return out


def test_gradient_per_step_matches_finite_differences():
    cfg = cfg64(T=20.0)
    inputs, _, params, samples = prepared(4, cfg, random_situation(4, T=20.0, n_polygons=2))
    f = terms_vector_fn(inputs, params, samples, cfg, per_step=True)
    rng = np.random.default_rng(3)
    n = cfg.n_steps
    c = np.stack([rng.uniform(0.5, 0.9, n), rng.uniform(-0.4, 0.4, n)], axis=-1)             # [N, 2]
    g = np.asarray(jax.jit(jax.jacrev(f))(jnp.asarray(c)))                                   # [terms, N, 2]
    # forward mode agrees with reverse mode along a random direction
    jvp_dir = rng.normal(size=c.shape)
    _, tangent = jax.jvp(f, (jnp.asarray(c),), (jnp.asarray(jvp_dir),))
    np.testing.assert_allclose(np.asarray(tangent), np.sum(g * jvp_dir, axis=(1, 2)), rtol=1e-8, atol=1e-10)
    # central differences on a random subset of steps (all 2N would be slow)
    for k in rng.choice(n, 6, replace=False):
        for j in range(2):
            e = np.zeros_like(c)
            e[k, j] = 1e-6
            fd = (np.asarray(f(jnp.asarray(c + e))) - np.asarray(f(jnp.asarray(c - e)))) / 2e-6
            np.testing.assert_allclose(g[:, k, j], fd, rtol=2e-4, atol=1e-7, err_msg=str((k, j)))
    assert np.all(np.abs(g[:3]).max(axis=(1, 2)) > 1e-6)       # total, collision and grounding all move


def test_colregs_gradient_is_zero_and_finite():
    """The COLREGS indicator is piecewise constant: its gradient is exactly 0 (and finite), as are central
    differences wherever no indicator flips within the step."""
    cfg = cfg64()
    inputs, _, params, samples = prepared(0, cfg)
    f = term_fn("colregs", inputs, params, samples, cfg)
    c = jnp.asarray([[0.8, 0.2], [0.7, -0.1]])
    assert float(f(c)) > 0                                    # the situation violates COLREGS here
    g = np.asarray(jax.grad(f)(c))
    np.testing.assert_array_equal(g, 0.0)
    fd = central_difference(lambda x: float(f(jnp.asarray(x))), np.asarray(c))
    np.testing.assert_array_equal(fd, 0.0)


def test_smooth_flag_uses_quadrature_for_mc():
    cfg_mc = cfg64("mc")
    inputs, _, params, samples = prepared(4, cfg_mc)
    c = jnp.asarray([[0.8, 0.3], [0.6, -0.2]])
    smooth = objective(c, inputs, params, samples, cfg_mc, smooth=True)[0]
    quad = objective(c, inputs, params, None, cfg64())[0]
    assert float(smooth) == pytest.approx(float(quad), rel=1e-12)
    (val, _), g = value_and_grad(c, inputs, params, samples, cfg_mc)
    assert float(val) == pytest.approx(float(quad), rel=1e-12) and np.all(np.isfinite(np.asarray(g)))


def test_per_step_equals_equivalent_behaviour():
    """A behaviour with maneuvers at k = 0 and k = N/2 is the same trajectory as per-step controls holding
    those values: equal collision and grounding costs (the path cost is normalised per maneuver)."""
    cfg = cfg64()
    inputs, _, params, samples = prepared(4, cfg)
    beh = np.array([[0.8, 0.3], [0.6, -0.2]])
    n = cfg.n_steps
    steps = np.repeat(beh, n // 2, axis=0)
    _, a = objective(jnp.asarray(beh), inputs, params, samples, cfg)
    _, b = objective(jnp.asarray(steps), inputs, params, samples, cfg, per_step=True)
    for name in ("do", "colregs", "so"):
        assert float(a[name]) == pytest.approx(float(b[name]), rel=1e-12, abs=1e-14), name
    with pytest.raises(ValueError, match="N = T / dt"):
        objective(jnp.asarray(steps[:-1]), inputs, params, samples, cfg, per_step=True)
    with pytest.raises(ValueError, match=r"\[n_M, 2\]"):
        objective(jnp.zeros((3,)), inputs, params, samples, cfg)


# ============================================================================ no NaN at the edges
def _finite_everywhere(sit, cfg=None, params=Params()):
    """Value, reverse-mode gradient and forward-mode tangent of the objective and of every term finite."""
    cfg = cfg or cfg64()
    planner = Planner(cfg, behaviours=SMALL_BEHAVIOURS, params=params)
    inputs, _, p, samples = planner.prepare(sit)
    c = jnp.asarray([[1.0, 0.0], [1.0, 0.0]])

    def f(x):
        total, costs = objective(x, inputs, p, samples, cfg)
        return jnp.stack([total] + [costs[n] for n in TERM_NAMES])

    @jax.jit        # one compiled program for value, reverse and forward mode (eager dispatch is far slower)
    def all_modes(x):
        v, t = jax.jvp(f, (x,), (jnp.ones_like(x),))
        return v, jax.jacrev(f)(x), t

    v, jac, t = (np.asarray(a) for a in all_modes(c))
    for k, name in enumerate(("total",) + TERM_NAMES):
        assert np.isfinite(v[k]), name
        assert np.all(np.isfinite(jac[k])), (name, jac[k])
        assert np.isfinite(float(t[k])), name
    return float(v[0]), dict(zip(TERM_NAMES, (float(a) for a in v[1:])))


OWN = OwnShip([0.0, 0.0, 0.0, 2.0], [[0.0, 0.0], [500.0, 0.0]], 2.0)
COV = np.diag([4.0, 4.0, 0.1, 0.1])


def test_no_nan_at_zero_distance():
    sit = Situation(OWN, (Obstacle([0.0, 0.0, -2.0, 0.0], COV, n_ps=3),))
    _, costs = _finite_everywhere(sit)
    assert float(costs["do"]) > 0


def test_no_nan_at_zero_relative_velocity():
    sit = Situation(OWN, (Obstacle([0.0, 0.0, 2.0, 0.0], COV, n_ps=1),))   # on the own-ship, same velocity
    _finite_everywhere(sit)


def test_no_nan_inside_land_exact_and_grid():
    box = np.array([[-20.0, -20.0], [-20.0, 20.0], [40.0, 20.0], [40.0, -20.0]])
    sit = Situation(OWN, (), (box,))
    for mode in ("exact", "grid"):
        _, costs = _finite_everywhere(sit, cfg64(grounding_mode=mode))
        assert float(costs["so"]) > 0


def test_no_nan_on_a_polygon_edge_and_vertex():
    edge = np.array([[-20.0, 0.0], [-20.0, 30.0], [20.0, 30.0], [20.0, 0.0]])      # own-ship on the y = 0 edge
    vertex = np.array([[0.0, 0.0], [-20.0, 30.0], [20.0, 30.0]])                   # own-ship on a vertex
    for poly in (edge, vertex):
        _finite_everywhere(Situation(OWN, (), (poly,)), cfg64(), Params(V_w=5.0, wind_dir=1.0))


def test_no_nan_at_the_sigma_shortcut_boundary():
    """Obstacle exactly at R + c_sigma sigma_max at t = 0 (c_sigma chosen so)."""
    d0 = 30.0
    radius = Params().d_safe + 0.5 * (OWN.length + 5.0)
    p0 = COV[:2, :2] + np.asarray(ou_covariance(0.0, Params()))[:2, :2]
    smax = math.sqrt(np.linalg.eigvalsh(p0).max())
    params = Params(c_sigma=(d0 - radius) / smax)
    sit = Situation(OWN, (Obstacle([d0, 0.0, -2.0, 0.0], COV, n_ps=1),))
    _finite_everywhere(sit, params=params)


def test_no_nan_without_obstacles_or_polygons():
    _, costs = _finite_everywhere(Situation(OWN))
    assert float(costs["do"]) == 0.0 and float(costs["so"]) == 0.0 and float(costs["colregs"]) == 0.0


# ============================================================================ a new cost term
@cost_term
class SpeedLoss:
    """Test-only term: weight x mean over the horizon of (1 - U / U_d)^2 (time lost to slowing down)."""

    weight: float = 1.0
    name = "speed_loss"

    def __call__(self, ctx, params, config, samples):
        u_d = jnp.maximum(ctx.own.U[:1], 1e-9)                  # the initial speed stands in for U_d here
        return TermValue(self.weight * jnp.mean((1.0 - ctx.own.U / u_d) ** 2, axis=0))

    def reference(self, own_traj, behaviour, situation, params, config):
        U = own_traj[:, 3]
        return float(self.weight) * float(np.mean((1.0 - U / max(U[0], 1e-9)) ** 2))


def test_a_new_term_is_one_module_plus_its_reference():
    cfg = cfg64()
    sit = random_situation(4, n_polygons=2)
    terms = DEFAULT_TERMS + (SpeedLoss(weight=3.0),)
    planner = Planner(cfg, behaviours=SMALL_BEHAVIOURS, terms=terms)
    res, _ = planner.plan(sit)
    assert planner.cost_names == ("total",) + TERM_NAMES + ("speed_loss",)
    assert list(res.costs) == list(planner.cost_names)
    ref = ref_mod.evaluate_reference(sit, SMALL_BEHAVIOURS, Params(), cfg, extra_terms=terms[4:])
    np.testing.assert_allclose(res.costs["speed_loss"], ref.extra["speed_loss"], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(res.costs["total"], ref.total, rtol=1e-9, atol=1e-12)
    assert res.best_index == ref.best and np.ptp(res.costs["speed_loss"]) > 0
    # its parameter is a traced leaf: a new value does not recompile, and it can be differentiated
    n0 = solve._cache_size()
    res2, _ = Planner(cfg, behaviours=SMALL_BEHAVIOURS, terms=DEFAULT_TERMS + (SpeedLoss(weight=7.0),)).plan(sit)
    assert solve._cache_size() == n0
    np.testing.assert_allclose(res2.costs["speed_loss"], res.costs["speed_loss"] * 7.0 / 3.0, rtol=1e-12)
    inputs, _, p, samples = planner.prepare(sit)
    dw = jax.grad(lambda w: objective(jnp.asarray([[0.5, 0.2], [0.5, 0.0]]), inputs, p, samples, cfg,
                                      DEFAULT_TERMS + (SpeedLoss(weight=w),))[0])(2.0)
    assert float(dw) > 0


def test_bad_terms_are_refused():
    with pytest.raises(ValueError, match="at least one"):
        check_terms(())
    with pytest.raises(ValueError, match="unique"):
        check_terms(DEFAULT_TERMS + (DEFAULT_TERMS[0],))
    with pytest.raises(ValueError, match="cost-term instance"):
        check_terms((SpeedLoss,))
    with pytest.raises(ValueError, match="must define a class attribute name"):
        cost_term(type("NoName", (), {"__call__": lambda self, *a: None}))


def test_extra_term_through_the_sharded_solve():
    """The multi-device out-specs follow the terms: an extra term's column comes back from solve_sharded."""
    from psbmpc_jax.sharding import solve_sharded

    cfg = cfg64()
    terms = DEFAULT_TERMS + (SpeedLoss(weight=2.0),)
    planner = Planner(cfg, behaviours=SMALL_BEHAVIOURS, terms=terms)
    inputs, state, params, samples = planner.prepare(random_situation(4, n_polygons=2))
    plan, nxt, ev = solve(inputs, state, params, samples, config=cfg, terms=terms)
    plan_s, nxt_s, ev_s = solve_sharded(inputs, state, params, samples, cfg, terms=terms)
    b = len(SMALL_BEHAVIOURS)
    assert set(ev_s.costs) == set(TERM_NAMES) | {"speed_loss"}
    for name in ev.costs:
        np.testing.assert_allclose(np.asarray(ev_s.costs[name])[:b], np.asarray(ev.costs[name])[:b], rtol=1e-12)
    assert int(plan_s.best) == int(plan.best) and int(plan_s.status) == 0
    np.testing.assert_array_equal(np.asarray(nxt_s.last_offsets), np.asarray(nxt.last_offsets))


def test_objective_differentiates_through_the_scan_rollouts(monkeypatch):
    """On a GPU ``rollout_kernel="auto"`` is the Pallas kernel, which has no derivative rule: the objective takes
    'auto' as the scan (here with the GPU's layouts chosen on this CPU, where 'auto' would give the interpreted
    kernel) and refuses an explicit 'pallas' naming the field."""
    import importlib

    ev = importlib.import_module("psbmpc_jax.evaluate")       # the module (the package exports a function)
    seen = []
    real = ev.ownship_rollouts
    monkeypatch.setattr(ev, "ownship_rollouts", lambda *a, **k: (seen.append(k.get("kernel")), real(*a, **k))[1])
    cfg = cfg64(layout_platform="gpu")
    inputs, state, params, samples = prepared(1, cfg)
    c = jnp.asarray(np.tile([0.8, 0.1], (SMALL_BEHAVIOURS.shape[1], 1)))
    g = jax.grad(lambda x: objective(x, inputs, params, samples, cfg)[0])(c)
    assert seen and set(seen) == {"scan"} and bool(jnp.all(jnp.isfinite(g)))
    with pytest.raises(ValueError, match="rollout_kernel='pallas' cannot serve the objective"):
        objective(c, inputs, params, samples, cfg64(rollout_kernel="pallas"))
