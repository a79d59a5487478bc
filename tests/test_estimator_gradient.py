"""The derivative of the sampling estimators (mc, ce): a score-function estimate of the derivative of the
collision probability, from the same samples.

The estimates themselves are sample averages of indicators (piecewise constant in the relative position), so
their own derivative is 0 almost everywhere — no descent direction — and before this change autodiff gave a
partial one instead (the kinetic-energy factor's, or for ce the importance weights' with the indicators held,
biased and sometimes of the wrong sign).  Now their JVP is the likelihood-ratio estimate: for
P = Pr(|mu + e| <= R), e ~ N(0, S), dP/dmu = E[1 S^-1 e], dP/dS = E[1 (S^-1 e e^T S^-1 - S^-1)] / 2 and dP/dR from
the scale invariance.  Checked against a float64 NumPy reference of that estimate on the same samples, and —
statistically, within a few standard errors — against finite differences of the float64 quadrature reference.
"""

from __future__ import annotations

import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from psbmpc_jax import Obstacle, OwnShip, Planner, PlannerConfig, Situation
from psbmpc_jax.costs.collision import pc_ce, pc_mc, pc_quadrature
from psbmpc_jax.objective import objective
from psbmpc_jax.params import Params
from psbmpc_jax.reference import collision_probability as ref_pc

#: (mu_x, mu_y, sxx, sxy, syy, R): near the disc edge, off-centre with correlation, far in the tail, inside
POINTS = [(3.0, -4.0, 6.0, 1.5, 3.0, 5.0), (8.0, 2.0, 9.0, -2.0, 4.0, 6.0), (12.0, 9.0, 16.0, 3.0, 10.0, 7.5),
          (1.0, 0.5, 4.0, 0.0, 4.0, 6.0)]
NAMES = ("dx", "dy", "sxx", "sxy", "syy", "R")


def ref_mc_score(point, z):
    """float64 NumPy reference of the mc score-function derivative: (P, gradient [6], per-sample terms
    [n, 6]) with the gradient w.r.t. (dx, dy, sxx, sxy, syy, R)."""
    mx, my, sxx, sxy, syy, R = point
    S = np.array([[sxx, sxy], [sxy, syy]])
    L = np.linalg.cholesky(S)
    r = z @ L.T                                                          # samples minus the mean
    inside = ((mx + r[:, 0]) ** 2 + (my + r[:, 1]) ** 2 <= R * R).astype(float)
    Si = np.linalg.inv(S)
    s = r @ Si
    per = np.zeros((len(z), 6))
    per[:, 0], per[:, 1] = inside * s[:, 0], inside * s[:, 1]
    per[:, 2] = 0.5 * inside * (s[:, 0] ** 2 - Si[0, 0])
    per[:, 3] = inside * (s[:, 0] * s[:, 1] - Si[0, 1])                 # the off-diagonal entry counts twice
    per[:, 4] = 0.5 * inside * (s[:, 1] ** 2 - Si[1, 1])
    per[:, 5] = -(mx * per[:, 0] + my * per[:, 1] + 2.0 * (sxx * per[:, 2] + sxy * per[:, 3] + syy * per[:, 4])) / R
    return inside.mean(), per.mean(axis=0), per


def quadrature_fd(point, h=1e-5):
    """Central differences of the float64 quadrature reference (128 nodes) w.r.t. the six inputs."""
    cfg = PlannerConfig(n_quad=128, quad_span=10.0)
    params = Params(c_sigma=100.0)                                      # no shortcut

    def p(v):
        mx, my, sxx, sxy, syy, R = v
        return ref_pc((0.0, 0.0), (mx, my), [[sxx, sxy], [sxy, syy]], R, "quadrature", params, cfg)
    out = np.zeros(6)
    for k in range(6):
        e = np.zeros(6)
        e[k] = h
        out[k] = (p(np.add(point, e)) - p(np.subtract(point, e))) / (2 * h)
    return out


def jax_grad(fn, point):
    args = [jnp.asarray(v, jnp.float64) for v in point]
    return np.asarray(jax.grad(fn, argnums=tuple(range(6)))(*args))


@pytest.mark.parametrize("point", POINTS)
def test_mc_derivative_is_the_score_function_estimate(point):
    z = np.asarray(jax.random.normal(jax.random.key(5), (200_000, 2), jnp.float64))
    p_ref, g_ref, per = ref_mc_score(point, z)
    g = jax_grad(lambda *a: pc_mc(*a, jnp.asarray(z)), point)
    assert float(pc_mc(*[jnp.asarray(v) for v in point], jnp.asarray(z))) == pytest.approx(p_ref, abs=1e-15)
    np.testing.assert_allclose(g, g_ref, rtol=1e-9, atol=1e-12)          # the same estimate as the reference
    # ... which agrees with the derivative of the probability (quadrature) within 5 standard errors
    se = per.std(axis=0) / np.sqrt(len(z))
    fd = quadrature_fd(point)
    assert np.all(np.abs(g - fd) <= 5 * se + 1e-6), dict(zip(NAMES, zip(g, fd, se)))
    assert np.abs(fd).max() > 1e-3                                       # a real slope, not a flat tail


@pytest.mark.parametrize("point", POINTS[:3])
def test_ce_derivative_agrees_with_the_quadrature_derivative(point):
    """The ce derivative, averaged over independent sample tables, within 5 standard errors of the quadrature
    derivative (the standard error from the spread over the tables)."""
    args = [jnp.asarray(v, jnp.float64) for v in point]
    grad = jax.jit(jax.grad(lambda a, z: pc_ce(*a, z, 0.9, 0.9, 11.618)))
    gs = np.array([np.asarray(grad(args, jax.random.normal(jax.random.key(k), (7, 20_000, 2), jnp.float64)))
                   for k in range(8)])
    mean, se = gs.mean(axis=0), gs.std(axis=0, ddof=1) / np.sqrt(len(gs))
    fd = quadrature_fd(point)
    assert np.all(np.abs(mean - fd) <= 5 * se + 2e-4 * np.abs(fd).max()), dict(zip(NAMES, zip(mean, fd, se)))


def test_quadrature_derivative_matches_its_reference():
    """The smooth estimator's autodiff derivative is the quadrature reference's central difference."""
    for point in POINTS:
        g = jax_grad(lambda *a: pc_quadrature(*a, n_quad=128, span=10.0), point)
        np.testing.assert_allclose(g, quadrature_fd(point), rtol=1e-5, atol=1e-8)


def test_sampling_derivative_is_zero_for_padding_and_finite():
    """A degenerate covariance (padding rows) or a zero radius gives a zero tangent, never NaN."""
    z = jax.random.normal(jax.random.key(0), (1000, 2), jnp.float64)
    zc = jax.random.normal(jax.random.key(0), (7, 1000, 2), jnp.float64)
    for point in [(0.0, 0.0, 0.0, 0.0, 0.0, 5.0), (1.0, 1.0, 4.0, 0.0, 4.0, 0.0)]:
        g = jax_grad(lambda *a: pc_mc(*a, z), point)
        assert np.all(np.isfinite(g)) and np.all(g[:2] == 0.0)
        g = jax_grad(lambda *a: pc_ce(*a, zc, 0.9, 0.9, 11.618), point)
        assert np.all(np.isfinite(g))


# --------------------------------------------------------------------------------------- through objective
sys.path.insert(0, str(__import__("pathlib").Path(__file__).parent))
from conftest import SMALL_BEHAVIOURS, random_situation  # noqa: E402


@pytest.mark.parametrize("estimator", ["mc", "ce"])
def test_objective_collision_gradient_agrees_with_quadrature(estimator):
    """d H_do / d controls with mc / ce, averaged over independent keys, within 5 standard errors of the
    central differences of the quadrature objective."""
    c = np.array([[0.8, 0.3], [0.6, -0.2]])
    sit = random_situation(5, n_polygons=0, n_obstacles=1)
    base = dict(T=30.0, dt=0.5, dtype="float64", n_samples=5000)
    quad = PlannerConfig(**base)
    inputs, _, params, _ = Planner(quad, behaviours=SMALL_BEHAVIOURS).prepare(sit)
    fq = jax.jit(lambda x: objective(x, inputs, params, None, quad)[1]["do"])
    fd = np.zeros_like(c)
    for idx in np.ndindex(c.shape):
        e = np.zeros_like(c)
        e[idx] = 1e-6
        fd[idx] = (float(fq(c + e)) - float(fq(c - e))) / 2e-6
    cfg = PlannerConfig(estimator=estimator, **base)
    planner = Planner(cfg, behaviours=SMALL_BEHAVIOURS)
    grad = jax.jit(jax.grad(lambda x, s: objective(x, inputs, params, s, cfg)[1]["do"]))
    gs = np.array([np.asarray(grad(jnp.asarray(c), planner.prepare(sit, key=jax.random.key(k))[3]))
                   for k in range(6)])
    mean, se = gs.mean(axis=0), gs.std(axis=0, ddof=1) / np.sqrt(len(gs))
    assert np.all(np.isfinite(gs))
    assert np.all(np.abs(mean - fd) <= 5 * se + 0.01 * np.abs(fd).max()), (mean, fd, se)
    assert np.abs(fd).max() > 1.0


@pytest.mark.parametrize("estimator", ["mc", "ce"])
def test_objective_gradient_finite_at_zero_distance_with_padding(estimator):
    own = OwnShip([0.0, 0.0, 0.0, 2.0], [[0.0, 0.0], [500.0, 0.0]], 2.0)
    sit = Situation(own, (Obstacle([0.0, 0.0, -2.0, 0.0], np.diag([4.0, 4.0, 0.1, 0.1]), n_ps=3),
                          Obstacle([40.0, 3.0, 0.0, 0.0], np.diag([4.0, 4.0, 0.1, 0.1]), n_ps=1)))
    cfg = PlannerConfig(T=20.0, dt=0.5, dtype="float64", n_samples=500, estimator=estimator)
    inputs, _, params, samples = Planner(cfg, behaviours=SMALL_BEHAVIOURS).prepare(sit, key=jax.random.key(0))
    f = lambda x: objective(x, inputs, params, samples, cfg)[1]["do"]       # noqa: E731
    c = jnp.asarray([[1.0, 0.0], [1.0, 0.0]])
    g = np.asarray(jax.grad(f)(c))
    _, t = jax.jvp(f, (c,), (jnp.ones_like(c),))
    assert np.all(np.isfinite(g)) and np.isfinite(float(t)) and float(f(c)) > 0
