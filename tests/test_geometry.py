"""Device point-to-polygon distance kernel (costs/grounding.py) against shapely, float64.

Property tests with hypothesis: random simple polygons (star-shaped, optionally with a star-shaped hole)
and random points; the kernel's distance (0 inside, even-odd rule over all rings) equals shapely's to 1e-6 m,
the nearest-point vector lands on the boundary, and gradients are finite."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import Point, Polygon

from psbmpc_jax import Obstacle, OwnShip, Params, PlannerConfig, Planner, Situation, paper_behaviours
from psbmpc_jax import reference as ref_mod
from psbmpc_jax.geometry import edge_table, polygon_distance
from psbmpc_jax.packing import pack
from psbmpc_jax.situation import ring_vertices

from conftest import star


EDGE_CAPACITY = 64


@jax.jit
def _distance(px, py, verts, nxt, n):
    """The kernel on an edge table padded past its ``n`` valid edges (as pack pads it): every hypothesis example
    (3-60 vertices) reuses this one compilation."""
    return polygon_distance(px, py, edge_table(verts, nxt), n)


def device_distance(rings, pts):
    """Pack one polygon (tuple of rings) like pack does and run the device kernel."""
    verts, nxt = ring_vertices(tuple(rings))
    n = len(verts)
    assert n <= EDGE_CAPACITY
    pad = EDGE_CAPACITY - n
    verts = np.concatenate([verts, np.full((pad, 2), np.nan)])      # padding: never read (n is the loop bound)
    nxt = np.concatenate([nxt, np.arange(n, EDGE_CAPACITY)])
    return _distance(jnp.asarray(pts[:, 0]), jnp.asarray(pts[:, 1]), jnp.asarray(verts), jnp.asarray(nxt),
                     jnp.asarray(n, jnp.int32))


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(3, 40), hole=st.booleans())
def test_distance_matches_shapely(seed, n, hole):
    rng = np.random.default_rng(seed)
    outer = star(rng, n, 0.0, 0.0, 20.0, 60.0)
    rings = [outer]
    clearance = Point(0.0, 0.0).distance(Polygon(outer).exterior)
    if hole and Polygon(outer).contains(Point(0.0, 0.0)) and clearance > 2.0:
        # a hole that fits: radii within 20-80 % of the centre's clearance to the outer ring
        rings.append(star(rng, max(3, n // 2), 0.0, 0.0, 0.2 * clearance, 0.8 * clearance)[::-1])
    shp = Polygon(rings[0], rings[1:])
    assert shp.is_valid
    pts = rng.uniform(-90, 90, size=(200, 2))
    pts[:20] = rings[0][rng.integers(0, n, 20)] * rng.uniform(0.97, 1.03, (20, 1))  # near the boundary
    d, ex, ey = (np.asarray(a) for a in device_distance(rings, pts))
    want = shapely.distance(shapely.points(pts), shp)
    np.testing.assert_allclose(d, want, atol=1e-6, rtol=0)
    outside = d > 1e-9
    # the nearest-point vector has length d and ends on the boundary
    np.testing.assert_allclose(np.hypot(ex, ey)[outside], d[outside], atol=1e-6)
    ends = shapely.points(pts[outside] + np.stack([ex, ey], -1)[outside])
    np.testing.assert_allclose(shapely.distance(ends, shp.boundary), 0.0, atol=1e-6)
    assert np.all(ex[~outside] == 0) and np.all(ey[~outside] == 0)


def test_hole_counts_as_water():
    outer = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 100.0], [0.0, 100.0]])
    hole = np.array([[40.0, 40.0], [40.0, 60.0], [60.0, 60.0], [60.0, 40.0]])
    pts = np.array([[50.0, 50.0], [45.0, 50.0], [20.0, 20.0], [-10.0, 50.0]])
    d, _, _ = device_distance([outer, hole], pts)
    np.testing.assert_allclose(np.asarray(d), [10.0, 5.0, 0.0, 10.0], atol=1e-12)


def test_distance_gradient_is_finite():
    outer = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 100.0], [0.0, 100.0]])
    f = lambda x, y: jnp.sum(device_distance([outer], np.zeros((1, 2)))[0] * 0 +
                             polygon_distance(x, y, edge_table(jnp.asarray(outer),
                                                               jnp.array([1, 2, 3, 0])), 4)[0])
    gx, gy = jax.grad(f, argnums=(0, 1))(jnp.array([-10.0, 50.0, 130.0]), jnp.array([50.0, 50.0, 120.0]))
    assert np.all(np.isfinite(gx)) and np.all(np.isfinite(gy))
    np.testing.assert_allclose(np.asarray(gx), [-1.0, 0.0, 30 / math.hypot(30, 20)], atol=1e-12)


def test_evaluator_with_holed_polygon_matches_reference():
    """A polygon with a hole goes through pack and the evaluator like the reference says."""
    outer = np.array([[-50.0, 15.0], [250.0, 15.0], [250.0, 120.0], [-50.0, 120.0]])
    hole = np.array([[20.0, 30.0], [20.0, 100.0], [200.0, 100.0], [200.0, 30.0]])
    own = OwnShip([0.0, 0.0, 0.0, 2.0], [[0.0, 0.0], [400.0, 0.0]], 2.0)
    sit = Situation(own, (Obstacle([150.0, 5.0, -2.0, 0.0], np.diag([4.0, 4.0, 0.1, 0.1]), n_ps=3),),
                    polygons=((outer, hole), star(np.random.default_rng(3), 12, 100.0, -60.0, 10.0, 30.0)))
    cfg = PlannerConfig(T=40.0, dt=0.5, dtype="float64")
    beh = paper_behaviours(1)
    res, _ = Planner(cfg, behaviours=beh).plan(sit)
    ref = ref_mod.evaluate_reference(sit, beh, Params(), cfg)
    for term in ("total", "do", "colregs", "so", "path"):
        np.testing.assert_allclose(res.costs[term], getattr(ref, term), rtol=1e-9, atol=1e-12, err_msg=term)
    np.testing.assert_allclose(res.grounding_per_polygon, ref.so_j, rtol=1e-9, atol=1e-12)
    assert res.best_index == ref.best
    # the hole really is water: a starboard turn into the hole costs less than one into solid land would
    polys = pack(sit, beh, cfg).world.polygons
    assert int(polys.n[0]) == 8 and list(np.asarray(polys.next[0, :8])) == [1, 2, 3, 0, 5, 6, 7, 4]
