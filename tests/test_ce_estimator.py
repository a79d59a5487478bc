"""The Cross-Entropy estimator point by point against the float64 reference (``reference._pc_ce``).

The evaluator computes each refit's elite moments from the standard-normal table mapped through the proposal's
Cholesky factor (one product of the elite mask with a table of z, z_x^2, z_x z_y, z_y^2), and the final pass's
proposal Mahalanobis distance as |z|^2; the reference sums the samples themselves.  In float64 both must give
the same estimate: every refit branch is exercised (converged at once, refitted, too few elites, far away)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from psbmpc_jax.costs.collision import pc_ce
from psbmpc_jax.params import Params
from psbmpc_jax.reference import _pc_ce


def _cases(rng, n):
    """Own-ship p, obstacle mean mu, covariance S, radius R: near, far, tight and wide covariances."""
    out = []
    for i in range(n):
        R = rng.uniform(3.0, 20.0)
        p = rng.uniform(-50.0, 50.0, 2)
        dist = R * rng.choice([0.0, 0.3, 1.0, 2.0, 4.0]) * rng.uniform(0.5, 1.5)
        a = rng.uniform(0, 2 * np.pi)
        mu = p + dist * np.array([np.cos(a), np.sin(a)])
        sx, sy = rng.uniform(0.3, 15.0, 2)
        c = rng.uniform(-0.9, 0.9) * sx * sy
        out.append((p, mu, np.array([[sx * sx, c], [c, sy * sy]]), R))
    return out


def test_ce_matches_the_float64_reference_point_by_point():
    assert jax.config.jax_enable_x64
    rng = np.random.default_rng(11)
    params = Params()
    z = np.asarray(jax.random.normal(jax.random.key(3), (7, 400, 2), jnp.float64))
    cases = _cases(rng, 60)
    dx = jnp.asarray([mu[0] - p[0] for p, mu, _, _ in cases])
    dy = jnp.asarray([mu[1] - p[1] for p, mu, _, _ in cases])
    S = np.stack([s for _, _, s, _ in cases])
    R = jnp.asarray([r for *_, r in cases])
    got = np.asarray(jax.jit(pc_ce)(dx, dy, jnp.asarray(S[:, 0, 0]), jnp.asarray(S[:, 0, 1]),
                                    jnp.asarray(S[:, 1, 1]), R, jnp.asarray(z), params.ce_rho, params.ce_alpha,
                                    params.ce_chi2))
    want = np.array([_pc_ce(p, mu, s, r, z, params) for p, mu, s, r in cases])
    # the cases reach 0, small, mid-range and clipped estimates
    assert np.sum(want == 0) >= 2 and np.sum(want == 1) >= 2 and np.sum((want > 1e-3) & (want < 0.9)) >= 20
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)


def test_ce_elite_moments_survive_a_degenerate_elite_set():
    """Elites along a line (a nearly singular obstacle covariance): the refitted covariance stays positive
    semi-definite (no NaN) and the estimate matches the reference."""
    params = Params()
    z = np.asarray(jax.random.normal(jax.random.key(5), (7, 300, 2), jnp.float64))
    S = np.array([[4.0, 2.0 * 0.9999], [2.0 * 0.9999, 1.0]])
    got = float(jax.jit(pc_ce)(jnp.asarray(3.0), jnp.asarray(1.0), S[0, 0], S[0, 1], S[1, 1], jnp.asarray(5.0),
                               jnp.asarray(z), params.ce_rho, params.ce_alpha, params.ce_chi2))
    want = _pc_ce(np.zeros(2), np.array([3.0, 1.0]), S, 5.0, z, params)
    assert np.isfinite(got) and want > 0
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)
