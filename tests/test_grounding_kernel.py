"""The culled exact grounding kernel (psbmpc_jax/geometry.py, psbmpc_jax/costs/grounding.py), float64.

The culled distances equal the full kernel's and the NumPy reference's on random polygons with holes, tiny
rings, zero-length edges and grid-aligned points; a capacity overflow falls back to the full kernel and stays
exact; ``grounding_costs`` equals ``reference.grounding_cost``; its gradient equals central differences;
degenerate points (on an edge, on a vertex, inside land), zero polygons and wind give no NaN in value, jvp or
vjp; and the grid mode's gradient is finite inside land."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from psbmpc_jax import reference as ref
from psbmpc_jax.costs.grounding import grid_grounding_cost, grounding_costs
from psbmpc_jax.distance_grid import build_distance_grid
from psbmpc_jax.edge_blocks import flat_argmax, flat_distance, host_blocks, nearest_edges
from psbmpc_jax.geometry import (culled_distances, dense_argmax, dense_distances, edge_table, polygon_argmax,
                                 polygon_distance)
from psbmpc_jax.grounding_search import distances_at, search_argmax
from psbmpc_jax.layouts import resolve_search
from psbmpc_jax.params import Params, PlannerConfig
from psbmpc_jax.situation import ring_vertices

DT = 0.5


def star_polygon(rng, centre, r_min, r_max, n):
    """A random star-shaped ring: one angle per sector of ``2 pi / n`` (so any ``n`` works), random radii."""
    ang = 2 * math.pi * (np.arange(n) + rng.uniform(0.1, 0.9, n)) / n + rng.uniform(0.0, 2 * math.pi)
    rad = rng.uniform(r_min, r_max, n)
    return np.asarray(centre, float)[None, :] + rad[:, None] * np.stack([np.cos(ang), np.sin(ang)], axis=1)


def random_chart(rng):
    """1-3 star polygons (some with 1-2 holes), a polygon of many tiny rings (chunks then hold several rings)
    with a repeated vertex (a zero-length edge), and an integer rectangle (grid-aligned edges)."""
    polys = []
    for _ in range(int(rng.integers(1, 4))):
        c, r = rng.uniform(-60.0, 60.0, 2), rng.uniform(12.0, 40.0)
        rings = [star_polygon(rng, c, 0.6 * r, r, int(rng.integers(3, 70)))]
        for _ in range(int(rng.integers(0, 3))):
            off = rng.uniform(-0.15, 0.15, 2) * r
            rings.append(star_polygon(rng, c + off, 0.05 * r, 0.3 * r, int(rng.integers(3, 9)))[::-1])
        polys.append(tuple(rings) if len(rings) > 1 else rings[0])
    outer = np.array([[-20.0, 70.0], [20.0, 70.0], [20.0, 70.0], [20.0, 90.0], [-20.0, 90.0]])
    islands = [np.array([[x, 74.0], [x + 3.0, 74.0], [x + 1.0, 77.0]]) for x in (-16.0, -10.0, -4.0, 2.0, 8.0)]
    polys.append(tuple([outer] + islands))
    polys.append(np.array([[30.0, -80.0], [45.0, -80.0], [45.0, -70.0], [30.0, -70.0]]))
    return polys


def pack_chart(polys, dtype=np.float64):
    """Padded ``vertices [P, V, 2]``, ``next [P, V]``, ``n [P]`` like ``packing.pack`` (junk past ``n``)."""
    rows = [ring_vertices(p) for p in polys]
    V = max(len(v) for v, _ in rows) + 5
    verts = np.full((len(rows), V, 2), 1.0e6, dtype)
    nxt = np.zeros((len(rows), V), np.int32)
    for k, (v, nx) in enumerate(rows):
        verts[k, :len(v)], nxt[k, :len(v)] = v, nx
    return jnp.asarray(verts), jnp.asarray(nxt), jnp.asarray([len(v) for v, _ in rows], jnp.int32)


def trajectories(rng, T, B, polys):
    """``px, py [T, B]``: random walks (step 0.3-4 m), plus points exactly on vertices and edges."""
    start = rng.uniform(-90.0, 90.0, (1, B, 2))
    p = start + np.cumsum(rng.normal(0.0, 1.0, (T, B, 2)) * rng.uniform(0.3, 4.0, (1, B, 1)), axis=0)
    verts, nxt = ring_vertices(polys[0])
    k = rng.integers(0, len(verts), 4)
    p[1, 0], p[2, 0] = verts[k[0]], verts[k[1]]                                # on vertices
    p[3, 0] = 0.5 * (verts[k[2]] + verts[nxt[k[2]]])                            # on (or within rounding of) an edge
    p[4, 0] = [0.0, 80.0]                                                       # on the rectangle's edge row
    p[5, 0] = [-10.0, 74.0]                                                     # on a tiny ring's vertex
    return jnp.asarray(p[..., 0]), jnp.asarray(p[..., 1])


def full_distances(px, py, verts, nxt, n):
    tables = edge_table(verts, nxt)
    return [tuple(np.asarray(a) for a in polygon_distance(px, py, tables[j], n[j])) for j in range(len(n))]


@pytest.mark.parametrize("seed,tile,chunk", [(0, 16, 8), (2, 7, 2), (4, 3, 16)])
def test_culled_distances_equal_full_kernel_and_reference(seed, tile, chunk):
    rng = np.random.default_rng(seed)
    polys = random_chart(rng)
    verts, nxt, n = pack_chart(polys)
    T, B = 41, 6
    px, py = trajectories(rng, T, B, polys)
    (d, ex, ey), overflow = culled_distances(px, py, edge_table(verts, nxt), nxt, n, tile=tile, chunk=chunk,
                                             chunk_cap=64)
    assert not bool(overflow)                                                   # the culled path answered
    pts = np.stack([np.asarray(px).ravel(), np.asarray(py).ravel()], -1)
    for j, (fd, fex, fey) in enumerate(full_distances(px, py, verts, nxt, n)):
        want, unit, _ = ref.polygon_distances(pts, polys[j])
        np.testing.assert_allclose(np.asarray(d[j]), fd, rtol=0, atol=1e-9)
        np.testing.assert_allclose(np.asarray(d[j]).ravel(), want, rtol=0, atol=1e-9)
        np.testing.assert_allclose(np.asarray(ex[j]), fex, rtol=0, atol=1e-9)
        np.testing.assert_allclose(np.asarray(ey[j]), fey, rtol=0, atol=1e-9)
        far = want > 1e-6                                                       # the nearest-boundary vector
        vec = np.stack([np.asarray(ex[j]).ravel(), np.asarray(ey[j]).ravel()], -1)[far]
        np.testing.assert_allclose(vec, unit[far] * want[far, None], rtol=0, atol=1e-9)
    assert np.any(np.asarray(d) == 0.0) and np.any(np.asarray(d) > 0.0)         # inside and outside points


def test_overflow_falls_back_to_the_full_kernel_exactly():
    rng = np.random.default_rng(7)
    polys = random_chart(rng)
    verts, nxt, n = pack_chart(polys)
    px, py = trajectories(rng, 30, 5, polys)
    tables = edge_table(verts, nxt)
    (d, ex, ey), overflow = culled_distances(px, py, tables, nxt, n, chunk_cap=1)
    assert bool(overflow)
    for j, (fd, fex, fey) in enumerate(full_distances(px, py, verts, nxt, n)):
        np.testing.assert_allclose(np.asarray(d[j]), fd, rtol=0, atol=1e-9)      # same edges, summation order
        np.testing.assert_allclose(np.asarray(ex[j]), fex, rtol=0, atol=1e-9)
    # the argmax search too: a tiny capacity gives the same answer as the culled one
    score = lambda d, ex, ey, w: w / (1.0 + d * d)
    bound = lambda d, w: w / (1.0 + d * d)
    args = (px, py, jnp.exp(-0.01 * DT * jnp.arange(30)), score, bound, tables, nxt, n)
    np.testing.assert_array_equal(np.asarray(polygon_argmax(*args, chunk_cap=1)), np.asarray(polygon_argmax(*args)))


def test_argmax_skips_tiles_bounded_by_zero_but_not_land():
    """A score exactly 0 beyond 30 m: far tiles are skipped, tiles deep inside land (far from the boundary
    too) are not; the argmax equals the brute-force one."""
    rng = np.random.default_rng(11)
    big = star_polygon(rng, (0.0, 0.0), 150.0, 200.0, 40)
    polys = [big, star_polygon(rng, (400.0, 0.0), 10.0, 20.0, 12)]
    verts, nxt, n = pack_chart(polys)
    T, B = 40, 8
    start = np.concatenate([rng.uniform(-60.0, 60.0, (B // 2, 2)), rng.uniform(-300.0, 500.0, (B // 2, 2))])
    p = start[None] + np.cumsum(rng.normal(0.0, 2.0, (T, B, 2)), axis=0)
    px, py = jnp.asarray(p[..., 0]), jnp.asarray(p[..., 1])
    tw = jnp.exp(-0.02 * jnp.arange(T))
    score = lambda d, ex, ey, w: jnp.where(d > 30.0, 0.0, w * (31.0 - d))
    bound = lambda d, w: jnp.where(d > 30.0, 0.0, w * (31.0 - d))
    k = np.asarray(polygon_argmax(px, py, tw, score, bound, edge_table(verts, nxt), nxt, n, tile=8))
    pts = np.stack([p[..., 0].ravel(), p[..., 1].ravel()], -1)
    for j, poly in enumerate(polys):
        d = ref.polygon_distances(pts, poly)[0].reshape(T, B)
        want = np.asarray(score(d, 0, 0, np.asarray(tw)[:, None]))
        np.testing.assert_array_equal(k[j], np.argmax(want, axis=0))
    assert np.any(ref.polygon_distances(pts, big)[0].reshape(T, B)[:, : B // 2] == 0.0)


def padded_problem(seed):
    """A random chart whose last polygon is padding (n = 0), its packed arrays and edge tables, and 30 x 6
    trajectories: ``(polys, verts, nxt, n, px, py, tables)``."""
    rng = np.random.default_rng(seed)
    polys = random_chart(rng)
    verts, nxt, n = pack_chart(polys)
    px, py = trajectories(rng, 30, 6, polys)
    return polys, verts, nxt, n.at[-1].set(0), px, py, edge_table(verts, nxt)


@pytest.mark.parametrize("seed,block", [(0, 32), (2, 5), (4, 1)])
def test_dense_search_equals_full_kernel_and_culled_search(seed, block):
    """The dense search (every edge, ``block`` edges per loop step) finds the same nearest edges as the full
    kernel and the same worst time step as the culled search, on random charts with holes, tiny rings, a
    zero-length edge, points on vertices and edges, and a padding polygon (n = 0)."""
    polys, verts, nxt, n, px, py, tables = padded_problem(seed)
    T, B = px.shape
    for j, (fd, fex, fey) in enumerate(full_distances(px, py, verts, nxt, n)):
        for fn in (dense_distances, polygon_distance):
            d, ex, ey = (np.asarray(a) for a in fn(px, py, tables[j], n[j], block=block))
            np.testing.assert_allclose(d, fd, rtol=0, atol=1e-9)
            np.testing.assert_allclose(ex, fex, rtol=0, atol=1e-9)
            np.testing.assert_allclose(ey, fey, rtol=0, atol=1e-9)
    tw = jnp.exp(-0.01 * DT * jnp.arange(T))
    score = lambda d, ex, ey, w: w * (1.0 + 0.3 * ex / (1.0 + d)) / (1.0 + d * d)       # uses the direction
    bound = lambda d, w: jnp.full_like(d, jnp.inf)
    for wd in (True, False):
        want = np.asarray(polygon_argmax(px, py, tw, score, bound, tables, nxt, n, wd))
        got = np.asarray(dense_argmax(px, py, tw, score, tables, n, wd, block=block))
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(np.asarray(search_argmax("dense", px, py, tw, score, bound, tables, nxt, n,
                                                               wd)), want)
    assert np.all(got[-1] == 0)
    with pytest.raises(ValueError, match="grounding search must be one of"):
        search_argmax("fast", px, py, tw, score, bound, tables, nxt, n)


def test_auto_search_is_bounded_on_the_cpu_and_flat_elsewhere():
    assert resolve_search("auto", "cpu") == "bounded"
    assert resolve_search("auto", "gpu") == "flat"
    assert resolve_search("dense", "cpu") == "dense" and resolve_search("culled", "gpu") == "culled"
    assert resolve_search("flat", "cpu") == "flat"
    assert resolve_search("auto") == ("bounded" if jax.default_backend() == "cpu" else "flat")
    with pytest.raises(ValueError, match="grounding search must be one of"):
        resolve_search("grid")


@pytest.mark.parametrize("search", ["bounded", "culled", "dense", "flat"])
@pytest.mark.parametrize("wind", [0.0, 4.0])
def test_grounding_costs_equal_reference(wind, search):
    rng = np.random.default_rng(3)
    polys = random_chart(rng)
    verts, nxt, n = pack_chart(polys)
    T, B = 60, 7
    px, py = trajectories(rng, T, B, polys)
    params = Params(V_w=wind, wind_dir=0.7)
    mask = jnp.asarray([True] * (len(polys) - 1) + [False])                   # the last polygon is padding
    h = np.asarray(grounding_costs(px, py, jnp.arange(T) * DT, verts, nxt, n, mask, params, search))
    cfg = PlannerConfig(dt=DT)
    for j, poly in enumerate(polys[:-1]):
        for b in range(B):
            traj = np.stack([np.asarray(px[:, b]), np.asarray(py[:, b])], -1)
            np.testing.assert_allclose(h[j, b], ref.grounding_cost(traj, poly, params, cfg), rtol=1e-9, atol=1e-300)
    assert np.all(h[-1] == 0.0)


def _outside_problem(seed):
    """Trajectories starting 5-60 m outside two polygons (one with a hole) and moving away: every point outside."""
    rng = np.random.default_rng(seed)
    polys = [(star_polygon(rng, (0.0, 0.0), 15.0, 25.0, 14), star_polygon(rng, (0.0, 0.0), 3.0, 8.0, 6)[::-1]),
             star_polygon(rng, (70.0, 10.0), 6.0, 12.0, 9)]
    T, B = 24, 3
    ang = rng.uniform(0.0, 2 * np.pi, B)
    start = np.stack([30.0 * np.cos(ang), 30.0 * np.sin(ang) - 60.0], -1)     # below both polygons
    vel = np.stack([np.full(B, 1.5), -rng.uniform(0.3, 1.0, B)], -1)              # moving away from them
    p = start[None] + np.arange(T)[:, None, None] * vel[None] * 2.0 + rng.normal(0.0, 0.2, (T, B, 2))
    pts = p.reshape(-1, 2)
    assert all(np.min(ref.polygon_distances(pts, q)[0]) > 1.0 for q in polys)
    return polys, jnp.asarray(p[..., 0]), jnp.asarray(p[..., 1])


@pytest.mark.parametrize("search", ["bounded", "culled", "dense", "flat"])
@pytest.mark.parametrize("wind", [0.0, 3.0])
def test_gradient_equals_central_differences(wind, search):
    polys, px, py = _outside_problem(5)
    verts, nxt, n = pack_chart(polys)
    T = px.shape[0]
    t, mask, params = jnp.arange(T) * DT, jnp.ones(len(polys), bool), Params(V_w=wind, wind_dir=-0.4)
    total = jax.jit(lambda x, y: jnp.sum(grounding_costs(x, y, t, verts, nxt, n, mask, params, search)))
    gx, gy = (np.asarray(g) for g in jax.grad(total, argnums=(0, 1))(px, py))
    assert np.count_nonzero(gx) > 0
    h = 1e-5
    for g, which in ((gx, 0), (gy, 1)):
        fd = np.zeros_like(g)
        for i in range(T):
            for b in range(px.shape[1]):
                e = jnp.zeros_like(px).at[i, b].set(h)
                args_p = (px + e, py) if which == 0 else (px, py + e)
                args_m = (px - e, py) if which == 0 else (px, py - e)
                fd[i, b] = (float(total(*args_p)) - float(total(*args_m))) / (2 * h)
        np.testing.assert_allclose(g, fd, rtol=1e-6, atol=1e-9)


def _finite(tree):
    return all(bool(jnp.all(jnp.isfinite(x))) for x in jax.tree.leaves(tree))


@pytest.mark.parametrize("search", ["bounded", "culled", "dense", "flat"])
@pytest.mark.parametrize("wind", [0.0, 5.0])
def test_degenerate_points_have_no_nan(wind, search):
    """On an edge, on a vertex, inside land, near but outside: value, jvp and vjp are finite."""
    square = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])
    verts, nxt, n = pack_chart([square])
    pts = np.array([[5.0, 0.0], [0.0, 0.0], [10.0, 10.0], [5.0, 5.0], [5.0, -3.0], [-2.0, -2.0]])
    px, py = jnp.asarray(pts[:, :1].T.repeat(2, 0)), jnp.asarray(pts[:, 1:].T.repeat(2, 0))   # [T = 2, B = 6]
    t, params = jnp.arange(2) * DT, Params(V_w=wind, wind_dir=2.0)
    f = lambda x, y: grounding_costs(x, y, t, verts, nxt, n, jnp.ones(1, bool), params, search)
    h, tangent = jax.jvp(f, (px, py), (jnp.ones_like(px), jnp.ones_like(py)))
    _, pull = jax.vjp(f, px, py)
    assert _finite(h) and _finite(tangent) and _finite(pull(jnp.ones_like(h)))
    np.testing.assert_allclose(np.asarray(h)[0, :4], float(params.G1) * (1.0 + float(params.G3) * 5.0))


@pytest.mark.parametrize("search", ["bounded", "culled", "dense", "flat"])
def test_zero_polygons_give_an_empty_nan_free_result(search):
    px, py = jnp.ones((5, 3)), jnp.zeros((5, 3))
    verts, nxt, n, mask = jnp.zeros((0, 4, 2)), jnp.zeros((0, 4), jnp.int32), jnp.zeros(0, jnp.int32), jnp.zeros(0, bool)
    f = lambda x, y: grounding_costs(x, y, jnp.arange(5) * DT, verts, nxt, n, mask, Params(V_w=2.0), search)
    h, tangent = jax.jvp(f, (px, py), (jnp.ones_like(px), jnp.ones_like(py)))
    assert h.shape == (0, 3) and tangent.shape == (0, 3)
    gx, gy = jax.grad(lambda x, y: jnp.sum(f(x, y)), argnums=(0, 1))(px, py)
    assert _finite((gx, gy)) and not np.any(np.asarray(gx))


def test_grid_mode_gradient_is_finite_inside_land():
    square = np.array([[0.0, 0.0], [40.0, 0.0], [40.0, 40.0], [0.0, 40.0]])
    grid = build_distance_grid([square], spacing=1.0, margin=10.0, dtype=np.float64)
    px = jnp.asarray([[20.0, -5.0], [20.5, -4.0]])                              # [T = 2, B = 2]: inside, outside
    py = jnp.asarray([[20.0, 10.0], [21.0, 11.0]])
    for params in (Params(), Params(V_w=4.0, wind_dir=0.3)):
        f = lambda x, y: jnp.sum(grid_grounding_cost(x, y, jnp.arange(2) * DT, grid, params))
        gx, gy = jax.grad(f, argnums=(0, 1))(px, py)
        assert _finite((gx, gy))
        assert float(gx[1, 1]) != 0.0 or float(gy[1, 1]) != 0.0                 # outside: a real gradient


def test_polygon_distance_gradient_at_an_edge_point_is_the_outward_normal():
    square = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])
    verts, nxt, n = pack_chart([square])
    edges = edge_table(verts, nxt)[0]
    grad = jax.grad(lambda x, y: jnp.sum(polygon_distance(x, y, edges, n[0])[0]), argnums=(0, 1))
    gx, gy = grad(jnp.asarray([5.0, 13.0]), jnp.asarray([-2.0, 14.0]))
    np.testing.assert_allclose(np.asarray(gx), [0.0, 3.0 / 5.0], atol=1e-12)
    np.testing.assert_allclose(np.asarray(gy), [-1.0, 4.0 / 5.0], atol=1e-12)
    assert math.isfinite(float(jax.grad(lambda x: polygon_distance(x, jnp.asarray(0.0), edges, n[0])[0])(jnp.asarray(5.0))))


@pytest.mark.parametrize("seed,packed", [(0, True), (2, False), (4, True)])
def test_flat_search_equals_full_kernel_and_culled_search(seed, packed):
    """The flat layout (every polygon's every edge in one pass, psbmpc_jax/edge_blocks.py) finds the same
    distance, inside flag and nearest edge as the full kernel, per polygon, and the same worst time step as the
    culled search, with the host's packed blocks (polygons back to back, padding blocks at the end) and with the
    content-free padded layout; a padding polygon (n = 0) gets index 0."""
    polys, verts, nxt, n, px, py, tables = padded_problem(seed)
    T, B = px.shape
    blocks = jnp.asarray(host_blocks(np.asarray(n), len(polys), verts.shape[1])) if packed else None
    if packed:
        assert blocks.shape[0] >= sum(-(-int(k) // 32) for k in n) and np.all(np.diff(np.asarray(blocks[:, 0])) >= 0)
    full = full_distances(px, py, verts, nxt, n)
    qx, qy = jnp.broadcast_to(px[None], (len(polys), T, B)), jnp.broadcast_to(py[None], (len(polys), T, B))
    d, ex, ey = (np.asarray(a) for a in flat_distance(qx, qy, tables, n, blocks))
    for j, (fd, fex, fey) in enumerate(full[:-1]):
        np.testing.assert_allclose(d[j], fd, rtol=0, atol=1e-9)
        np.testing.assert_allclose(ex[j], fex, rtol=0, atol=1e-9)
        np.testing.assert_allclose(ey[j], fey, rtol=0, atol=1e-9)
    # shared points ([1, T, B]) give the same per-polygon minima as one point set per polygon
    d2s, ins, _ = nearest_edges(px[None], py[None], tables, n, blocks)
    d2p, inp, _ = nearest_edges(qx, qy, tables, n, blocks)
    np.testing.assert_array_equal(np.asarray(d2s), np.asarray(d2p))
    np.testing.assert_array_equal(np.asarray(ins), np.asarray(inp))
    tw = jnp.exp(-0.01 * DT * jnp.arange(T))
    score = lambda d, ex, ey, w: w * (1.0 + 0.3 * ex / (1.0 + d)) / (1.0 + d * d)       # uses the direction
    bound = lambda d, w: jnp.full_like(d, jnp.inf)
    for wd in (True, False):
        want = np.asarray(polygon_argmax(px, py, tw, score, bound, tables, nxt, n, wd))
        got = np.asarray(flat_argmax(px, py, tw, score, tables, n, blocks, wd))
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(np.asarray(search_argmax("flat", px, py, tw, score, bound, tables, nxt, n,
                                                               wd, blocks)), want)
    assert np.all(got[-1] == 0)


def test_flat_nearest_edge_ties_pick_the_first_edge_across_lanes_and_blocks():
    """Exact ties: a 10 m square whose sides are cut into 16 collinear edges each (64 edges, two blocks of 32).
    Its centre is exactly 5 m from eight edges on four sides, in both blocks; the flat pass must return what a
    float64 brute force over the edges in order returns: the first edge of equal distance (slot 7, the bottom
    side), the same squared distance and the even-odd inside flag; also for points on a vertex and outside."""
    side = np.arange(16) * 0.625
    ring = np.concatenate([np.c_[side, np.zeros(16)], np.c_[np.full(16, 10.0), side],
                           np.c_[10.0 - side, np.full(16, 10.0)], np.c_[np.zeros(16), 10.0 - side]])
    verts, nxt, n = pack_chart([ring])
    tables = edge_table(verts, nxt)
    pts = np.array([[5.0, 5.0], [5.0, -3.0], [12.0, 5.0], [0.625, 0.0], [-1.0, -1.0], [2.5, 7.5]])
    px, py = jnp.asarray(pts[:, 0])[None], jnp.asarray(pts[:, 1])[None]
    d2, inside, slot = (np.asarray(a)[0] for a in nearest_edges(px, py, tables, n, jnp.asarray(
        host_blocks(np.asarray(n), 1, verts.shape[1]))))
    a, b = ring, np.roll(ring, -1, axis=0)
    for i, (x, y) in enumerate(pts):
        ab = b - a
        t = np.clip(((x - a[:, 0]) * ab[:, 0] + (y - a[:, 1]) * ab[:, 1]) / np.sum(ab * ab, axis=1), 0.0, 1.0)
        e2 = (x - a[:, 0] - t * ab[:, 0]) ** 2 + (y - a[:, 1] - t * ab[:, 1]) ** 2
        assert d2[i] == e2.min() and slot[i] == int(np.argmin(e2)), (i, d2[i], slot[i], np.flatnonzero(e2 == e2.min()))
        crossings = ((a[:, 1] > y) != (b[:, 1] > y)) & (x < a[:, 0] + (y - a[:, 1]) * ab[:, 0] / np.where(
            ab[:, 1] == 0, 1.0, ab[:, 1]))
        assert bool(inside[i]) == bool(np.sum(crossings) % 2)
    assert slot[0] == 7 and bool(inside[0])


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_segment_min_through_bit_patterns_equals_segment_min(dtype):
    """The flat pass's integer segment minimum of squared distances equals ``jax.ops.segment_min`` on zeros,
    subnormals, the largest float (masked lanes), ordinary values and empty segments (+inf) (x64 is on in the
    tests: conftest)."""
    from psbmpc_jax.edge_blocks import _segment_min_nonnegative

    dt = jnp.dtype(dtype)
    rng = np.random.default_rng(3)
    special = np.array([0.0, np.finfo(dt).tiny / 4, np.finfo(dt).max, 1.0, 1e-30, 3e30], dt)
    x = jnp.asarray(np.concatenate([special, rng.uniform(0, 1e4, 40).astype(dt)])[:, None]
                    * np.ones((1, 3), dt))
    seg = jnp.asarray(np.sort(rng.choice([0, 2, 3, 5], size=x.shape[0])), jnp.int32)    # 1 and 4 empty
    got = np.asarray(_segment_min_nonnegative(x, seg, 6))
    want = np.asarray(jax.ops.segment_min(x, seg, num_segments=6, indices_are_sorted=True))
    assert got.dtype == want.dtype == dt and np.array_equal(got, want) and np.all(np.isinf(got[[1, 4]]))


def test_flat_argmax_in_column_chunks_equals_one_pass(monkeypatch):
    """Above FLAT_STEP_ELEMENTS the columns are split into chunks (a lax.map): the same answer."""
    import psbmpc_jax.edge_blocks as eb

    rng = np.random.default_rng(9)
    polys = random_chart(rng)
    verts, nxt, n = pack_chart(polys)
    px, py = trajectories(rng, 20, 7, polys)
    tables = edge_table(verts, nxt)
    tw = jnp.exp(-0.01 * DT * jnp.arange(20))
    score = lambda d, ex, ey, w: w / (1.0 + d * d)
    one = np.asarray(flat_argmax(px, py, tw, score, tables, n))
    monkeypatch.setattr(eb, "FLAT_STEP_ELEMENTS", 700)
    np.testing.assert_array_equal(np.asarray(flat_argmax(px, py, tw, score, tables, n)), one)


@pytest.mark.parametrize("search", ["bounded", "culled", "dense", "flat"])
def test_distances_at_equal_polygon_distance(search):
    rng = np.random.default_rng(12)
    polys = random_chart(rng)
    verts, nxt, n = pack_chart(polys)
    qx, qy = (a[:len(polys)] for a in trajectories(rng, 20, 5, polys))             # one point set per polygon
    tables = edge_table(verts, nxt)
    d, ex, ey = (np.asarray(a) for a in distances_at(search, qx, qy, tables, n))
    for j in range(len(polys)):
        fd, fex, fey = (np.asarray(a) for a in polygon_distance(qx[j], qy[j], tables[j], n[j]))
        np.testing.assert_allclose(d[j], fd, rtol=0, atol=1e-9)
        np.testing.assert_allclose(ex[j], fex, rtol=0, atol=1e-9)
        np.testing.assert_allclose(ey[j], fey, rtol=0, atol=1e-9)


def test_host_blocks_layout_and_capacity():
    b = host_blocks([3, 70, 32], p_cap=4, v_cap=80)
    assert b.shape == (8, 2)
    np.testing.assert_array_equal(b[:5], [[0, 0], [1, 0], [1, 32], [1, 64], [2, 0]])
    np.testing.assert_array_equal(b[5:], [[3, 80]] * 3)                            # padding: sorted, no valid slot
    with pytest.raises(ValueError, match="edge block capacity 2 is too small"):
        host_blocks([70], p_cap=1, v_cap=70, capacity=2)
