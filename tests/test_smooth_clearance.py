"""Land clearance of the DOCP's plan between samples (psbmpc_jax/smooth/clearance.py), float64.

* the signed distance equals the float64 shapely oracle (``reference_smooth.signed_land_distance``) outside,
  inside, near edges and vertices, and its gradient central differences (at a tie between two banks: one of
  the one-sided derivatives);
* the corner the 1-s samples missed: two samples 4.0 m from a convex corner of land, the segment between them
  3.8 m from it -- a sample check passes, the segment constraint does not;
* the proof: on random plans past the corner, every segment whose constraint holds keeps >= b from land
  (shapely), and the bound is not vacuous (some segments pass, some fail);
* the DOCP's inequalities include it with ``corridor_check="continuous"`` only; their gradient matches central
  differences."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from shapely.geometry import LineString, Polygon

from psbmpc_jax import reference_smooth as RS
from psbmpc_jax.packing import pack_world
from psbmpc_jax.params import PlannerConfig
from psbmpc_jax.smooth.clearance import Clearance, segment_residuals, signed_clearance
from psbmpc_jax.smooth.land_hit import edge_blocks

# a square of land with its corner at the origin (north <= 0, east <= 0), and a second polygon east of it
SQUARE = np.array([[-40.0, -40.0], [0.0, -40.0], [0.0, 0.0], [-40.0, 0.0]])
BANK = np.array([[-40.0, 12.0], [0.0, 12.0], [0.0, 30.0], [-40.0, 30.0]])
POLYS = [SQUARE, BANK]
CHART = pack_world(POLYS, PlannerConfig(dtype="float64")).polygons
B = 4.0


def clearance(n, lo=(-60.0, -60.0), hi=(60.0, 60.0), cap=50.0, slack=None):
    return Clearance(edge_blocks(CHART), jnp.asarray(lo), jnp.asarray(hi), jnp.asarray(cap), jnp.asarray(B),
                     jnp.zeros(n) if slack is None else jnp.asarray(slack))


def sd(points, cap=50.0):
    c = clearance(1, cap=cap)
    return signed_clearance(jnp.asarray(points, jnp.float64).reshape(-1, 2), c.blocks, c.lo, c.hi, c.cap)


def test_signed_distance_matches_the_oracle():
    rng = np.random.default_rng(0)
    pts = np.concatenate([rng.uniform(-45, 35, (200, 2)),
                          [[0.0, 0.0], [1e-7, 1e-7], [-1.0, -1.0], [-20.0, 6.0], [3.0, -3.0], [-20.0, 12.0]]])
    got = np.asarray(sd(pts))
    want = RS.signed_land_distance(pts, POLYS)
    far = np.abs(want) > 1e-6           # the distance is floored at 1e-6 m (a finite gradient on an edge)
    np.testing.assert_allclose(got[far], np.minimum(want[far], 50.0), atol=1e-10)
    assert np.all(np.abs(got[~far]) <= 1e-6 + 1e-12) and (~far).sum() == 3
    assert np.any(want < 0) and np.any(want > 0)


@pytest.mark.parametrize("p", [[3.0, 2.0], [-20.0, 5.0], [-10.0, -10.5], [2.0, -15.0], [-39.0, 20.0]])
def test_signed_distance_gradient(p):
    g = np.asarray(jax.grad(lambda q: sd(q[None])[0])(jnp.asarray(p)))
    h = 1e-6
    fd = [(float(sd(np.asarray(p) + h * e)[0]) - float(sd(np.asarray(p) - h * e)[0])) / (2 * h)
          for e in np.eye(2)]
    np.testing.assert_allclose(g, fd, atol=1e-7)


def test_gradient_at_a_tie_is_a_one_sided_derivative():
    """(−20, 6) is 6 m from both the square and the bank: the distance has a kink there."""
    p = np.array([-20.0, 6.0])
    g = np.asarray(jax.grad(lambda q: sd(q[None])[0])(jnp.asarray(p)))
    h = 1e-6
    right = (float(sd(p + [0, h])[0]) - float(sd(p)[0])) / h
    left = (float(sd(p)[0]) - float(sd(p - [0, h])[0])) / h
    # a generalised gradient (JAX's min shares it between equal values): within the one-sided derivatives
    assert min(left, right) - 1e-6 <= g[1] <= max(left, right) + 1e-6 and abs(right - left) > 1.9
    assert abs(g[0]) <= 1e-9


def straight_plan(mid, direction, step, k_before, k_after):
    """States [K, 4] on a straight line through ``mid``: samples at (j + 1/2) * step from it, speed step/dt."""
    d = np.asarray(direction, float) / np.hypot(*direction)
    ks = np.arange(-k_before, k_after + 1) - 0.5
    pos = np.asarray(mid) + ks[:, None] * step * d
    return np.c_[pos, np.full(len(ks), math.atan2(d[1], d[0])), np.full(len(ks), step)]


def test_the_corner_the_samples_missed():
    """A run past the convex corner at the origin: the samples at +-1.25 m of the closest point are 4.0 m from
    land, the segment between them passes 3.8 m from the corner."""
    mid = np.array([3.8, 3.8]) / math.sqrt(2)
    states = straight_plan(mid, [1.0, -1.0], 2.5, 1, 1)
    samples = RS.signed_land_distance(states[:, :2], POLYS)
    assert samples.min() >= B - 1e-3                              # a check at the samples passes (4.00 m)
    seg = LineString(states[1:3, :2]).distance(Polygon(SQUARE))
    assert seg < 3.81                                              # ... but the segment comes within 3.8 m
    g = np.asarray(segment_residuals(jnp.asarray(states), clearance(len(states) - 1), 1.0))
    assert g[1] > 0.4                                              # the segment constraint refuses it


def test_segments_that_pass_keep_the_buffer():
    rng = np.random.default_rng(1)
    land = Polygon(SQUARE)
    passed = failed = 0
    for _ in range(60):
        k = 12
        heading = rng.uniform(-math.pi, math.pi)
        step = rng.uniform(0.1, 1.0)
        turn = np.cumsum(rng.normal(0, 0.3, k))
        start = rng.uniform(-3, 12, 2) + [0.0, 0.0]
        pos = [start]
        for j in range(k):
            pos.append(pos[-1] + step * np.array([math.cos(heading + turn[j]), math.sin(heading + turn[j])]))
        pos = np.asarray(pos)
        chi = np.r_[heading + turn, heading + turn[-1]]
        states = np.c_[pos, chi, np.full(k + 1, step)]
        g = np.asarray(segment_residuals(jnp.asarray(states), clearance(k), 1.0))
        for j in range(k):
            d = LineString(pos[j:j + 2]).distance(land)
            if g[j] <= 0:
                passed += 1
                assert d >= B - 1e-9, (j, d, g[j])
            else:
                failed += 1
    assert passed > 50 and failed > 50


def test_docp_inequalities_carry_the_clearance_only_when_continuous():
    from psbmpc_jax.smooth import buffered_chart
    from psbmpc_jax.smooth.docp import prepare_step, problem
    from psbmpc_jax.smooth.init_stage import ShipModel, SmoothSettings, SmoothWeights

    banks = [np.array([[-50.0, 14.0], [150.0, 14.0], [150.0, 30.0], [-50.0, 30.0]]),
             np.array([[-50.0, -14.0], [150.0, -14.0], [150.0, -30.0], [-50.0, -30.0]])]
    land = pack_world(banks, PlannerConfig(dtype="float64")).polygons
    out = {}
    for check in ("continuous", "samples"):
        s = SmoothSettings(T_init=12.0, T_mpc=6.0, dt=1.0, n_y=21, corridor_check=check)
        prep = jax.jit(prepare_step, static_argnames=("settings", "n_starts"))(
            jnp.asarray([0.0, 8.0, 0.3, 1.0]), jnp.asarray([[0.0, 0.0], [140.0, 0.0]]), jnp.zeros((0, 4)),
            jnp.asarray([1.0, 0.0]), jnp.asarray(0, jnp.int32), land, buffered_chart(banks, s.corridor_land_buffer),
            SmoothWeights(), ShipModel(), settings=s, n_starts=1)
        _, _, ineq = problem(s)
        out[check] = (prep, ineq, s)
    n = 6
    prep, ineq, s = out["continuous"]
    u = prep.starts[0]
    h = np.asarray(ineq(u, prep.args))
    assert h.shape == (3 * n,) and np.asarray(out["samples"][1](out["samples"][0].starts[0],
                                                                 out["samples"][0].args)).shape == (2 * n,)
    # the gradient of the clearance part against central differences at random interior controls
    rng = np.random.default_rng(2)
    f = lambda v: ineq(v, prep.args)[2 * n:]                                              # noqa: E731
    for _ in range(3):
        v = jnp.asarray(np.c_[rng.uniform(0.3, 0.9, n), rng.uniform(-0.6, 0.8, n)])
        jac = np.asarray(jax.jacfwd(f)(v))
        eps = 1e-6
        for i in range(n):
            for c in range(2):
                e = np.zeros((n, 2))
                e[i, c] = eps
                fd = (np.asarray(f(v + e)) - np.asarray(f(v - e))) / (2 * eps)
                np.testing.assert_allclose(jac[:, i, c], fd, atol=2e-6)
