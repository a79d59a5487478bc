"""Algorithm 3, the cross-track corridor (psbmpc_jax/smooth/corridor.py), float64.

The jitted device ray cast against the buffered, packed chart equals the shapely oracle to 1e-6 m on random
polygons with holes and random trajectories; rays that hit nothing give ±Δd; a straight channel gives the
exact half-widths (SPEC_SEEDS §5.3 item 4) along every direction, axis-parallel included; the inside-land
convention; zero-length segments; residual gradients; input validation."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from shapely.geometry import Point, Polygon

from psbmpc_jax.packing import Capacities
from psbmpc_jax.smooth import (Corridor, boundary_points, buffer_land, buffered_chart,
                               cross_track_corridor, cross_track_corridor_shapely, cross_track_residuals)

from conftest import star

#: One capacity for every random chart: a single compilation of the kernel for the random tests.
CAPS = Capacities(polygons=8, vertices=1024)
R_DOM = 4.0


def random_land(rng, k=4):
    """k star polygons in a 400 m box, some with a star hole (tuples of rings), possibly overlapping."""
    polys = []
    for _ in range(k):
        cx, cy = rng.uniform(-150, 150, 2)
        outer = star(rng, int(rng.integers(5, 25)), cx, cy, 25.0, 70.0)
        shell = Polygon(outer)
        clear = Point(cx, cy).distance(shell.exterior) if shell.contains(Point(cx, cy)) else 0.0
        if rng.uniform() < 0.6 and clear > 25.0:
            hole = star(rng, int(rng.integers(4, 12)), cx, cy, 0.3 * clear, 0.8 * clear)[::-1]
            polys.append((outer, hole))
        else:
            polys.append(outer)
    return polys


def random_walk(rng, n=40, step=(2.0, 15.0)):
    """A wandering trajectory [n+1, 2] through the box, with a few zero-length segments."""
    p = rng.uniform(-200, 200, 2)
    course = rng.uniform(0, 2 * np.pi)
    out = [p.copy()]
    for _ in range(n):
        course += rng.normal(0, 0.4)
        s = 0.0 if rng.uniform() < 0.08 else rng.uniform(*step)
        p = p + s * np.array([math.cos(course), math.sin(course)])
        out.append(p.copy())
    return np.array(out)


def assert_same(dev: Corridor, host: Corridor, atol=1e-6):
    np.testing.assert_allclose(np.asarray(dev.tangent), host.tangent, atol=1e-12)
    np.testing.assert_allclose(np.asarray(dev.normal), host.normal, atol=1e-12)
    np.testing.assert_array_equal(np.asarray(dev.inside), host.inside)
    np.testing.assert_allclose(np.asarray(dev.upper), host.upper, atol=atol, rtol=0)
    np.testing.assert_allclose(np.asarray(dev.lower), host.lower, atol=atol, rtol=0)


# ------------------------------------------------------------------------------------- device == oracle
@pytest.mark.parametrize("seed", range(6))
def test_device_matches_shapely_on_random_land(seed):
    rng = np.random.default_rng(1000 + seed)
    land = random_land(rng, k=int(rng.integers(2, 6)))
    chart = buffered_chart(land, R_DOM, capacities=CAPS)
    delta_d = float(rng.uniform(10.0, 60.0))
    n_hits = n_inside = 0
    for _ in range(4):
        P = random_walk(rng)
        dev = cross_track_corridor(P, chart, delta_d)
        host = cross_track_corridor_shapely(P, land, R_DOM, delta_d)
        assert_same(dev, host)
        assert np.all(host.lower <= 0) and np.all(host.upper >= 0)
        n_hits += int(np.sum((np.abs(host.upper) < delta_d) & ~host.inside))
        n_hits += int(np.sum((np.abs(host.lower) < delta_d) & ~host.inside))
        n_inside += int(host.inside.sum())
    assert n_hits > 0            # the cases do exercise ray hits (and usually inside points)


def test_device_matches_shapely_holes_and_dense_hits():
    """Trajectories inside a holed polygon's hole (water): every ray hits the hole boundary."""
    rng = np.random.default_rng(7)
    outer = np.array([[-300.0, -300.0], [300.0, -300.0], [300.0, 300.0], [-300.0, 300.0]])
    hole = star(rng, 30, 0.0, 0.0, 80.0, 140.0)[::-1]
    island = star(rng, 9, 20.0, -10.0, 8.0, 20.0)
    land = [(outer, hole), island]
    chart = buffered_chart(land, R_DOM, capacities=CAPS)
    P = random_walk(rng, n=40, step=(1.0, 4.0)) * 0.25
    dev = cross_track_corridor(P, chart, 200.0)
    host = cross_track_corridor_shapely(P, land, R_DOM, 200.0)
    assert_same(dev, host)
    free = ~host.inside
    assert np.all(host.upper[free] < 200.0) and np.all(host.lower[free] > -200.0)


# ------------------------------------------------------------------------------------- no hit: ±Δd
def test_rays_hitting_nothing_give_full_half_width():
    rng = np.random.default_rng(3)
    P = random_walk(rng)
    far = [np.array([[5000.0, 5000.0], [5100.0, 5000.0], [5050.0, 5100.0]])]
    for land in ([], far):
        chart = buffered_chart(land, R_DOM, capacities=CAPS)
        for delta_d in (5.0, 20.0):
            dev = cross_track_corridor(P, chart, delta_d)
            host = cross_track_corridor_shapely(P, land, R_DOM, delta_d)
            assert_same(dev, host)
            np.testing.assert_array_equal(np.asarray(dev.upper), delta_d)
            np.testing.assert_array_equal(np.asarray(dev.lower), -delta_d)
            assert not np.asarray(dev.inside).any()


# ------------------------------------------------------------------------------------- straight channel
def rot(theta):
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


@pytest.mark.parametrize("course_deg", [0.0, 90.0, 180.0, -90.0, 30.0, 135.0])
def test_straight_channel_exact_half_widths(course_deg):
    """SPEC_SEEDS §5.3 item 4, along every direction (axis-parallel ones included): banks at 12 m (starboard)
    and 30 m (port) from the centre line; r_dom = 4 → e⁺ = 12 − 4 = 8; e⁻ = −min(Δd, 26)."""
    R = rot(math.radians(course_deg))     # (north, east) of the track frame (along, starboard)
    starboard = np.array([[-1000.0, 12.0], [1000.0, 12.0], [1000.0, 200.0], [-1000.0, 200.0]]) @ R.T
    port = np.array([[-1000.0, -200.0], [1000.0, -200.0], [1000.0, -30.0], [-1000.0, -30.0]]) @ R.T
    P = np.stack([np.linspace(-150.0, 150.0, 41), np.zeros(41)], 1) @ R.T
    land = [starboard, port]
    chart = buffered_chart(land, R_DOM, capacities=CAPS)
    for delta_d, want_lo in ((20.0, -20.0), (40.0, -26.0)):
        dev = cross_track_corridor(P, chart, delta_d)
        host = cross_track_corridor_shapely(P, land, R_DOM, delta_d)
        assert_same(dev, host, atol=1e-9)
        np.testing.assert_allclose(np.asarray(dev.upper), 8.0, atol=1e-9)
        np.testing.assert_allclose(np.asarray(dev.lower), want_lo, atol=1e-9)
        np.testing.assert_allclose(np.asarray(dev.normal), np.tile(R @ [0.0, 1.0], (41, 1)), atol=1e-12)
    # wide channel (half-width 30 m both sides), Δd = 20 → ±20 (the SPEC's first case)
    wide = [np.array([[-1000.0, 30.0], [1000.0, 30.0], [1000.0, 200.0], [-1000.0, 200.0]]) @ R.T, port]
    dev = cross_track_corridor(P, buffered_chart(wide, R_DOM, capacities=CAPS), 20.0)
    np.testing.assert_allclose(np.asarray(dev.upper), 20.0, atol=1e-12)
    np.testing.assert_allclose(np.asarray(dev.lower), -20.0, atol=1e-12)
    # the boundary points g± lie on the buffered banks
    g_plus, g_minus = boundary_points(cross_track_corridor(P, chart, 40.0))
    G = buffer_land(land, R_DOM)
    for g in np.concatenate([np.asarray(g_plus), np.asarray(g_minus)]):
        assert G.boundary.distance(Point(g)) < 1e-6


@pytest.mark.parametrize("course_deg", [0.0, 90.0])
def test_axis_parallel_track_residuals_do_not_degenerate(course_deg):
    """The literal per-coordinate box of (28) has zero width across an axis-parallel track; the cross-track
    form keeps the whole corridor: sideways offsets inside it are feasible, along-track offsets free."""
    R = rot(math.radians(course_deg))
    land = [np.array([[-1000.0, 12.0], [1000.0, 12.0], [1000.0, 200.0], [-1000.0, 200.0]]) @ R.T]
    P = np.stack([np.linspace(0.0, 100.0, 41), np.zeros(41)], 1) @ R.T
    c = cross_track_corridor(P, buffered_chart(land, R_DOM, capacities=CAPS), 20.0)
    along, side = R @ [1.0, 0.0], R @ [0.0, 1.0]
    lo, up = cross_track_residuals(P + 7.0 * along + 5.0 * side, c)     # e = +5 in [−20, 8]
    np.testing.assert_allclose(np.asarray(lo), -25.0, atol=1e-9)
    np.testing.assert_allclose(np.asarray(up), -3.0, atol=1e-9)
    lo, up = cross_track_residuals(P + 10.0 * side, c)                   # 2 m past the starboard bound
    np.testing.assert_allclose(np.asarray(up), 2.0, atol=1e-9)
    lo, up = cross_track_residuals(P - 21.0 * side, c)                   # 1 m past the port bound
    np.testing.assert_allclose(np.asarray(lo), 1.0, atol=1e-9)


# ------------------------------------------------------------------------------------- conventions
def test_inside_buffered_land_collapses_bounds():
    square = np.array([[0.0, 0.0], [50.0, 0.0], [50.0, 50.0], [0.0, 50.0]])
    # points: in water, in land, within r_dom of land (inside the buffer only), in water again
    P = np.array([[-30.0, 25.0], [25.0, 25.0], [-2.0, 25.0], [-30.0, -40.0], [-60.0, -40.0], [-60.0, -80.0]])
    chart = buffered_chart([square], R_DOM, capacities=CAPS)
    dev = cross_track_corridor(P, chart, 30.0)
    host = cross_track_corridor_shapely(P, [square], R_DOM, 30.0)
    assert_same(dev, host)
    np.testing.assert_array_equal(host.inside, [False, True, True, False, False, False])
    assert np.all(np.asarray(dev.upper)[1:3] == 0) and np.all(np.asarray(dev.lower)[1:3] == 0)
    # residuals there: the reference itself is feasible (e = 0), any sideways move is not
    lo, up = cross_track_residuals(P, dev)
    assert np.all(np.asarray(lo) <= 0) and np.all(np.asarray(up) <= 0)


def test_collinear_edge_and_vertex_hits():
    """Rays along a polygon edge / through a vertex (the parallel branch of the kernel), r_dom = 0."""
    square = np.array([[-15.0, 0.0], [-5.0, 0.0], [-5.0, 10.0], [-15.0, 10.0]])
    diamond = np.array([[20.0, 0.0], [30.0, -10.0], [40.0, 0.0], [30.0, 10.0]])
    P = np.array([[0.0, 0.0], [0.0, 5.0], [0.0, 30.0], [0.0, 40.0], [0.0, 45.0], [0.0, 60.0]])  # east-bound: stbd = −x
    land = [square, diamond]
    dev = cross_track_corridor(P, buffered_chart(land, 0.0, capacities=CAPS), 50.0)
    host = cross_track_corridor_shapely(P, land, 0.0, 50.0)
    assert_same(dev, host, atol=1e-12)
    np.testing.assert_allclose(np.asarray(dev.upper)[:2], 5.0)     # the square's edge x = −5
    np.testing.assert_allclose(np.asarray(dev.lower)[:2], [-20.0, -25.0])   # diamond vertex (20, 0), edge


def test_rays_aimed_exactly_at_vertices_never_slip_between_edges():
    """Rays aimed at the tip of a kite (the boundary crosses the ray's line at a vertex), random directions and
    positions far from the origin, float64 and float32: the hit is the vertex distance, never the full
    half-width.  (The kernel decides from the end points' sides of the line, land_hit.ray_edge_t; a per-edge
    Cramer solve, the kernel's earlier form, was seen to slip between the two edges in the prediction's
    random tests - these cases did not make it slip, so this checks the vertex case, not that regression.)"""
    rng = np.random.default_rng(12)
    for _ in range(30):
        heading = rng.uniform(0, 2 * math.pi)
        t = np.array([math.cos(heading), math.sin(heading)])
        n = np.array([-t[1], t[0]])                                     # starboard normal: the +ray
        P = rng.uniform(-5e3, 5e3, (1, 2)) + np.arange(8)[:, None] * 7.3 * t[None]
        dist = rng.uniform(3.0, 20.0, len(P))
        land = []
        for k, (p, d) in enumerate(zip(P, dist)):
            v = p + d * n                                               # the vertex on the ray
            w = rng.uniform(2.0, 6.0)
            land.append(np.array([v, v + 8 * n + w * t, v + 12 * n, v + 8 * n - w * t]))   # a kite, tip at v
        for dtype, tol in (("float64", 1e-9), ("float32", 1e-2)):
            c = cross_track_corridor(P.astype(dtype), buffered_chart(land, 0.0, capacities=CAPS, dtype=dtype), 50.0,
                                     heading=heading)
            np.testing.assert_allclose(np.asarray(c.upper), dist, rtol=0, atol=tol)


def test_zero_length_segments_and_heading():
    chart = buffered_chart([], R_DOM, capacities=CAPS)
    P = np.array([[0.0, 0.0], [0.0, 0.0], [10.0, 0.0], [10.0, 0.0], [10.0, 10.0], [10.0, 10.0]])
    for c in (cross_track_corridor(P, chart, 20.0), cross_track_corridor_shapely(P, [], R_DOM, 20.0)):
        # leading zero → next non-zero (north); later zeros → previous; last step → previous
        np.testing.assert_allclose(np.asarray(c.tangent),
                                   [[1, 0], [1, 0], [1, 0], [0, 1], [0, 1], [0, 1]], atol=1e-15)
        np.testing.assert_allclose(np.asarray(c.normal)[0], [0, 1], atol=1e-15)   # north-bound: starboard east
    still = np.zeros((6, 2))
    with pytest.raises(ValueError, match="heading"):
        cross_track_corridor(still, chart, 20.0)
    with pytest.raises(ValueError, match="heading"):
        cross_track_corridor_shapely(still, [], R_DOM, 20.0)
    h = math.radians(90.0)   # east
    for c in (cross_track_corridor(still, chart, 20.0, heading=h),
              cross_track_corridor_shapely(still, [], R_DOM, 20.0, heading=h),
              cross_track_corridor(still[:1], chart, 20.0, heading=h)):
        np.testing.assert_allclose(np.asarray(c.tangent), np.tile([0.0, 1.0], (len(c.tangent), 1)), atol=1e-15)
        np.testing.assert_allclose(np.asarray(c.normal), np.tile([-1.0, 0.0], (len(c.tangent), 1)), atol=1e-15)


# ------------------------------------------------------------------------------------- gradients, jit
def test_residual_gradients_finite():
    rng = np.random.default_rng(11)
    land = random_land(rng, 4)
    P = random_walk(rng)
    c = cross_track_corridor(P, buffered_chart(land, R_DOM, capacities=CAPS), 25.0)
    x = jnp.asarray(P + rng.normal(0, 15.0, P.shape))

    def penalty(x):
        lo, up = cross_track_residuals(x, c)
        return jnp.sum(jax.nn.relu(lo) ** 2 + jax.nn.relu(up) ** 2) + jnp.sum(lo) + jnp.sum(up)

    g = jax.grad(penalty)(x)
    assert np.all(np.isfinite(np.asarray(g)))
    jl, ju = jax.jacobian(lambda x: cross_track_residuals(x, c))(x)
    n = np.asarray(c.normal)
    np.testing.assert_allclose(np.einsum("jjk->jk", np.asarray(ju)), n, atol=1e-15)
    np.testing.assert_allclose(np.einsum("jjk->jk", np.asarray(jl)), -n, atol=1e-15)
    # batched positions [K, N+1, 2]
    lo, up = cross_track_residuals(jnp.stack([x, x]), c)
    assert lo.shape == up.shape == (2, len(P))


def test_traceable_under_jit_and_vmap():
    """The public wrapper traced inside a caller's jit and vmap (shape checks only; Δd traced too)."""
    rng = np.random.default_rng(5)
    land = random_land(rng, 3)
    chart = buffered_chart(land, R_DOM, capacities=CAPS)
    Ps = np.stack([random_walk(rng) for _ in range(3)])
    f = jax.jit(jax.vmap(lambda p, d: cross_track_corridor(p, chart, d), in_axes=(0, None)))
    out = f(jnp.asarray(Ps), 30.0)
    for k in range(3):
        assert_same(jax.tree.map(lambda a: a[k], out), cross_track_corridor_shapely(Ps[k], land, R_DOM, 30.0))


# ------------------------------------------------------------------------------------- validation
def test_validation_names_the_field():
    chart = buffered_chart([], R_DOM, capacities=CAPS)
    P = np.stack([np.arange(6.0), np.zeros(6)], 1)
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="delta_d"):
            cross_track_corridor(P, chart, bad)
        with pytest.raises(ValueError, match="delta_d"):
            cross_track_corridor_shapely(P, [], R_DOM, bad)
    for bad in (-1.0, float("inf")):
        with pytest.raises(ValueError, match="r_dom"):
            buffered_chart([], bad)
        with pytest.raises(ValueError, match="r_dom"):
            cross_track_corridor_shapely(P, [], bad, 10.0)
    for shape in ((3,), (3, 3), (0, 2), (2, 3, 2)):
        with pytest.raises(ValueError, match="positions"):
            cross_track_corridor(np.zeros(shape), chart, 10.0)
        with pytest.raises(ValueError, match="positions"):
            cross_track_corridor_shapely(np.zeros(shape), [], R_DOM, 10.0)
    with pytest.raises(ValueError, match="positions"):
        cross_track_corridor(np.array([[0.0, 0.0], [np.nan, 1.0]]), chart, 10.0)
    with pytest.raises(ValueError, match="chart"):
        cross_track_corridor(P, "not a chart", 10.0)
    with pytest.raises(ValueError, match="heading"):
        cross_track_corridor(P, chart, 10.0, heading=float("nan"))
    with pytest.raises(ValueError, match="polygons"):
        buffered_chart([np.zeros((2, 2))], R_DOM)
    c = cross_track_corridor(P, chart, 10.0)
    with pytest.raises(ValueError, match="positions"):
        cross_track_residuals(np.zeros((5, 2)), c)
