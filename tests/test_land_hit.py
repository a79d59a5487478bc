"""N_TP of the initialisation stage (psbmpc_jax/smooth/land_hit.py) against a shapely oracle, float64.

A point collides when its r_dom disc meets land (distance ≤ r_dom, inside = 0) or when the segment from the
previous point meets land; N_TP is the first colliding index, N when none.  Random star polygons with
holes, overlapping polygons, random trajectories batched over behaviours; the thin-polygon jump
(SPEC_SEEDS §5.3 item 5); touching and collinear segments; jit / shapes / validation."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from shapely.geometry import LineString, Point, Polygon
from shapely.ops import unary_union

from psbmpc_jax import PlannerConfig
from psbmpc_jax.packing import Capacities, pack_world
from psbmpc_jax.smooth import first_land_hit, land_collision_flags

from conftest import star

CFG = PlannerConfig(dtype="float64")
CAPS = Capacities(polygons=8, vertices=64)
R_DOM = 4.0
B, N = 6, 30


def chart_of(polygons, caps=CAPS):
    return pack_world(polygons, CFG, caps).polygons


def random_land(rng, k):
    polys = []
    for _ in range(k):
        cx, cy = rng.uniform(-120, 120, 2)
        outer = star(rng, int(rng.integers(4, 20)), cx, cy, 10.0, 50.0)
        shell = Polygon(outer)
        clear = Point(cx, cy).distance(shell.exterior) if shell.contains(Point(cx, cy)) else 0.0
        if rng.uniform() < 0.6 and clear > 12.0:
            polys.append((outer, star(rng, int(rng.integers(3, 10)), cx, cy, 0.3 * clear, 0.8 * clear)[::-1]))
        else:
            polys.append(outer)
    # a thin sliver (2 m wide, random orientation): sampled trajectories jump over it
    c, a = rng.uniform(-100, 100, 2), rng.uniform(0, np.pi)
    u, v = np.array([math.cos(a), math.sin(a)]), np.array([-math.sin(a), math.cos(a)])
    polys.append(np.array([c - 60 * u - v, c + 60 * u - v, c + 60 * u + v, c - 60 * u + v]))
    return polys


def to_shapely(p):
    return Polygon(p[0], p[1:]) if isinstance(p, tuple) else Polygon(p)


def oracle(traj, polygons, r_dom):
    """(flags [N+1], N_TP) with shapely: distance(point, land) <= r_dom or the segment intersects land."""
    land = unary_union([to_shapely(p) for p in polygons]) if polygons else None
    flags = np.zeros(len(traj), bool)
    for j, p in enumerate(traj):
        if land is None:
            continue
        hit = land.distance(Point(p)) <= r_dom
        if j > 0 and not np.array_equal(traj[j - 1], p):
            hit = hit or LineString([traj[j - 1], p]).intersects(land)
        flags[j] = hit
    n_tp = int(np.argmax(flags)) if flags.any() else len(traj) - 1
    return flags, n_tp


def random_trajs(rng, b=B, n=N, step=(3.0, 20.0)):
    out = np.zeros((b, n + 1, 2))
    for k in range(b):
        p, course = rng.uniform(-180, 180, 2), rng.uniform(0, 2 * np.pi)
        out[k, 0] = p
        for j in range(n):
            course += rng.normal(0, 0.3)
            p = p + rng.uniform(*step) * np.array([math.cos(course), math.sin(course)])
            out[k, j + 1] = p
    return out


@pytest.mark.parametrize("seed", range(6))
def test_matches_shapely_oracle(seed):
    rng = np.random.default_rng(2000 + seed)
    land = random_land(rng, int(rng.integers(2, 7)))
    chart = chart_of(land)
    trajs = random_trajs(rng)
    r = (0.0, R_DOM, 9.0, 2.0, R_DOM, 0.5)[seed]
    flags = np.asarray(land_collision_flags(trajs, chart, r))
    n_tp = np.asarray(first_land_hit(trajs, chart, r))
    assert n_tp.shape == (B,) and n_tp.dtype == np.int32
    for k in range(B):
        want_flags, want = oracle(trajs[k], land, r)
        np.testing.assert_array_equal(flags[k], want_flags, err_msg=f"behaviour {k}")
        assert n_tp[k] == want


def test_random_jumps_over_slivers():
    """Thin random slivers and long steps: many collisions only the segment test sees, all as the oracle."""
    rng = np.random.default_rng(77)
    land = []
    for _ in range(6):
        c, a, w = rng.uniform(-120, 120, 2), rng.uniform(0, np.pi), rng.uniform(0.2, 1.5)
        u, v = np.array([math.cos(a), math.sin(a)]), np.array([-math.sin(a), math.cos(a)])
        land.append(np.array([c - 50 * u - w * v, c + 50 * u - w * v, c + 50 * u + w * v, c - 50 * u + w * v]))
    chart = chart_of(land)
    trajs = random_trajs(rng, step=(15.0, 30.0))
    r = 2.0
    flags = np.asarray(land_collision_flags(trajs, chart, r))
    n_tp = np.asarray(first_land_hit(trajs, chart, r))
    shp = unary_union([to_shapely(p) for p in land])
    segment_only = 0
    for k in range(B):
        want_flags, want = oracle(trajs[k], land, r)
        np.testing.assert_array_equal(flags[k], want_flags, err_msg=f"behaviour {k}")
        assert n_tp[k] == want
        segment_only += sum(f and shp.distance(Point(p)) > r for f, p in zip(want_flags, trajs[k]))
    assert segment_only >= 3


def test_overlapping_polygons_and_holes():
    """Even-odd per polygon: the overlap of two polygons is land; a hole is water (away from its rim)."""
    a = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 100.0], [0.0, 100.0]])
    b = np.array([[50.0, 50.0], [150.0, 50.0], [150.0, 150.0], [50.0, 150.0]])
    holed = (np.array([[300.0, 0.0], [500.0, 0.0], [500.0, 200.0], [300.0, 200.0]]),
             np.array([[350.0, 50.0], [350.0, 150.0], [450.0, 150.0], [450.0, 50.0]]))
    land = [a, b, holed]
    chart = chart_of(land)
    pts = np.array([[75.0, 75.0], [400.0, 100.0], [320.0, 100.0], [-20.0, -20.0], [353.0, 100.0]])
    # each point as its own 1-point trajectory (no segments): only the disc test
    flags = np.asarray(land_collision_flags(pts[:, None, :], chart, R_DOM))[:, 0]
    np.testing.assert_array_equal(flags, [True, False, True, False, True])
    for k, p in enumerate(pts):
        assert flags[k] == oracle(p[None], land, R_DOM)[0][0]


def test_thin_polygon_jump_is_caught_by_the_segment_test():
    """SPEC_SEEDS §5.3 item 5: a 0.5 m wall between two samples 10 m apart, each ≥ 4.75 m from it."""
    wall = np.array([[-0.25, -50.0], [0.25, -50.0], [0.25, 50.0], [-0.25, 50.0]])
    x = np.arange(-25.0, 26.0, 10.0)                                       # -25, -15, -5, 5, 15, 25
    trajs = np.stack([np.stack([x, np.zeros(6)], 1),                        # jumps the wall between 2 and 3
                      np.stack([x, np.full(6, 52.0)], 1)])                  # passes 2 m beyond its end
    chart = chart_of([wall])
    d = np.array([Polygon(wall).distance(Point(p)) for p in trajs[0]])
    assert np.all(d > R_DOM)                                               # no point test fires
    np.testing.assert_array_equal(np.asarray(land_collision_flags(trajs, chart, R_DOM)),
                                  [[False, False, False, True, False, False], [False] * 6])
    # the jump is caught at the point after it; passing within r_dom of land (no sample within r_dom, no
    # contact) is not a collision under the SPEC's rule
    np.testing.assert_array_equal(np.asarray(first_land_hit(trajs, chart, R_DOM)), [3, 5])
    # a domain reaching the wall from the samples: the first sample within 6 m collides (x = -5; the second
    # trajectory's sample there is hypot(4.75, 2) = 5.15 m from the wall's end)
    np.testing.assert_array_equal(np.asarray(first_land_hit(trajs, chart, 6.0)), [2, 2])


def test_touching_and_collinear_segments_count():
    """Closed segments: touching a corner or running along an edge is a collision (r_dom = 0)."""
    square = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])
    chart = chart_of([square])
    trajs = np.array([[[-20.0, 20.0], [20.0, -20.0]],          # through the corner (0, 0) only
                      [[-30.0, 0.0], [30.0, 0.0]],             # collinear with the edge y = 0
                      [[-30.0, -1.0], [30.0, -1.0]]])          # misses by 1 m
    flags = np.asarray(land_collision_flags(trajs, chart, 0.0))
    np.testing.assert_array_equal(flags, [[False, True], [False, True], [False, False]])
    for k in range(3):
        np.testing.assert_array_equal(flags[k], oracle(trajs[k], [square], 0.0)[0])
    # a domain of 2 m: the 1 m miss still has both samples far away and no contact (the SPEC's rule)
    np.testing.assert_array_equal(np.asarray(land_collision_flags(trajs, chart, 2.0))[2], [False, False])


def test_no_land_gives_n():
    rng = np.random.default_rng(1)
    trajs = random_trajs(rng)
    empty = pack_world([], CFG).polygons                                  # no polygon slot at all
    assert empty.vertices.shape[0] == 0
    np.testing.assert_array_equal(np.asarray(first_land_hit(trajs, empty, R_DOM)), N)
    masked = chart_of([])                                                 # capacity 8, all masked out
    np.testing.assert_array_equal(np.asarray(first_land_hit(trajs, masked, R_DOM)), N)


def test_start_on_land_and_shapes():
    rng = np.random.default_rng(1)
    trajs = random_trajs(rng)
    # starting on land: N_TP = 0 for every behaviour
    island = np.array([[-5.0, -5.0], [5.0, -5.0], [5.0, 5.0], [-5.0, 5.0]])
    start = trajs - trajs[:, :1]
    np.testing.assert_array_equal(np.asarray(first_land_hit(start, chart_of([island]), R_DOM)), 0)
    # a single trajectory -> scalar; extra leading axes kept (flattened into one call)
    masked = chart_of([])
    assert first_land_hit(trajs[0], masked, R_DOM).shape == ()
    assert first_land_hit(trajs.reshape(2, 3, N + 1, 2), masked, R_DOM).shape == (2, 3)
    assert land_collision_flags(trajs.reshape(2, 3, N + 1, 2), masked, R_DOM).shape == (2, 3, N + 1)


def test_jit_vmap_and_block_invariance():
    rng = np.random.default_rng(9)
    land = random_land(rng, 4)
    chart = chart_of(land)
    trajs = random_trajs(rng)
    ref = np.asarray(first_land_hit(trajs, chart, R_DOM))
    # traced inside a caller's jit + vmap (shape checks only), with a small block: same result
    f = jax.jit(jax.vmap(lambda t, r: first_land_hit(t, chart, r, block=7), in_axes=(0, None)))
    np.testing.assert_array_equal(np.asarray(f(jnp.asarray(trajs), R_DOM)), ref)


def test_validation_names_the_field():
    chart = chart_of([])
    traj = np.zeros((5, 2))
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="r_dom"):
            first_land_hit(traj, chart, bad)
    with pytest.raises(ValueError, match="r_dom"):
        first_land_hit(traj, chart, np.ones(2))
    for shape in ((5,), (5, 3), (0, 2), (2, 0, 2)):
        with pytest.raises(ValueError, match="traj_xy"):
            first_land_hit(np.zeros(shape), chart, R_DOM)
    with pytest.raises(ValueError, match="traj_xy"):
        first_land_hit(np.array([[0.0, 0.0], [np.nan, 1.0]]), chart, R_DOM)
    with pytest.raises(ValueError, match="chart"):
        first_land_hit(traj, [np.zeros((3, 2))], R_DOM)
    with pytest.raises(ValueError, match="block"):
        first_land_hit(traj, chart, R_DOM, block=0)


def test_land_clearance_equals_shapely_capped_at_reach():
    """land_clearance (the N_TP kernel's distance pass for one point, used by C-000-16) against shapely on random
    points around a holed polygon and a triangle: the distance to land (0 inside, not inside a hole), capped at
    the reach."""
    import shapely

    from psbmpc_jax.packing import pack_world
    from psbmpc_jax.params import PlannerConfig
    from psbmpc_jax.smooth.land_hit import land_clearance

    outer = np.array([[0.0, 0.0], [40.0, 0.0], [40.0, 30.0], [0.0, 30.0]])
    hole = np.array([[10.0, 10.0], [25.0, 10.0], [25.0, 20.0], [10.0, 20.0]])
    tri = np.array([[60.0, 5.0], [75.0, 5.0], [65.0, 25.0]])
    chart = pack_world([(outer, hole), tri], PlannerConfig(dtype="float64")).polygons
    land = shapely.unary_union([shapely.Polygon(outer, [hole]), shapely.Polygon(tri)])
    pts = np.random.default_rng(3).uniform([-20.0, -20.0], [90.0, 50.0], size=(200, 2))
    fn = jax.jit(jax.vmap(lambda q, r: land_clearance(q, chart, r), in_axes=(0, None)))
    for reach in (4.0, 50.0):
        want = np.minimum([land.distance(shapely.Point(q)) for q in pts], reach)
        np.testing.assert_allclose(np.asarray(fn(jnp.asarray(pts), reach)), want, rtol=0, atol=1e-9)
    assert np.any(want == 0.0) and np.any((want > 0.0) & (want < 50.0))   # inside, near and far points drawn
