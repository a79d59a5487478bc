"""Geometry of the upper level of the two-level MPC (seed 001): path frames (eqs. 3-4) and leg switching
(psbmpc_jax/two_level/path_frame.py), the riparian-land corridor per leg (Algorithm 1, choices C-001-4 and
C-001-8; two_level/riparian.py) and static circles (eqs. 10, 12; two_level/static_obstacles.py).

Checks: the transforms round-trip and match eq. (3) written out, eq. (4) equals re-transforming from NED,
y_p > 0 to starboard, jit / grad with a traced leg index; the switching rule; the device leg corridor equals
the shapely oracle (1e-6 m) on a channel with banks and an island (also against the exact half-widths and the
unclipped chart) and on random charts; the cache; piecewise-linear bounds and their gradient; land crossing a
leg becomes an enclosing circle and leaves the corridor; circle residuals and gradients (no NaN at the
centre); ValueErrors naming the field."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import shapely
from shapely.geometry import LineString, Point, Polygon

from psbmpc_jax.smooth.corridor import cross_track_corridor_shapely
from psbmpc_jax.two_level.path_frame import (active_leg, from_leg_frame, from_path_frame, leg_angles, path_legs,
                                             switch_frame, to_leg_frame, to_path_frame)
from psbmpc_jax.two_level.riparian import (LegCorridor, clear_corridor_cache, corridor_bounds,
                                           corridor_cache_info, corridor_residuals, crossing_land_circles,
                                           land_key, leg_corridor, leg_corridors)
from psbmpc_jax.two_level.static_obstacles import (StaticCircles, circle_residuals, circles_from_land,
                                                   concat_circles, enclosing_circle, from_yaml)

from conftest import central_difference, star


def rot(psi):
    return np.array([[math.cos(psi), math.sin(psi)], [-math.sin(psi), math.cos(psi)]])


def random_route(rng, n=4):
    w = [rng.uniform(-500, 500, 2)]
    for _ in range(n - 1):
        ang = rng.uniform(-math.pi, math.pi)
        w.append(w[-1] + rng.uniform(20, 300) * np.array([math.cos(ang), math.sin(ang)]))
    return np.array(w)


# ============================================================================================ path frame
def test_leg_angles_and_eq3():
    w = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0], [0.0, 0.0]])
    np.testing.assert_allclose(leg_angles(w), [0.0, math.pi / 2, math.pi, -math.pi / 2])
    rng = np.random.default_rng(0)
    for _ in range(20):
        w = random_route(rng, 5)
        psi = leg_angles(w)
        p = rng.uniform(-800, 800, (7, 2))
        for j in range(4):
            q = np.asarray(to_path_frame(p, w, j))
            np.testing.assert_allclose(q, (p - w[j]) @ rot(psi[j]).T, rtol=0, atol=1e-9)
            np.testing.assert_allclose(np.asarray(from_path_frame(q, w, j)), p, rtol=0, atol=1e-9)
            # WP_{j+1} sits at (l_j, 0)
            l_j = np.linalg.norm(w[j + 1] - w[j])
            np.testing.assert_allclose(np.asarray(to_path_frame(w[j + 1], w, j)), [l_j, 0.0], atol=1e-9)
    legs = path_legs(w)
    np.testing.assert_allclose(legs.psi, leg_angles(w))
    # the same transform from leg data (start, psi), also with a traced leg index into PathLegs
    f = jax.jit(lambda p, legs, j: to_leg_frame(p, legs.start[j], legs.psi[j]))
    for j in range(4):
        q = np.asarray(to_path_frame(p, w, j))
        np.testing.assert_allclose(np.asarray(f(p, legs, jnp.int32(j))), q, atol=1e-9)
        np.testing.assert_allclose(np.asarray(from_leg_frame(q, legs.start[j], legs.psi[j])), p, atol=1e-9)
    np.testing.assert_allclose(legs.start, w[:-1])
    np.testing.assert_allclose(legs.tangent, np.stack([np.cos(legs.psi), np.sin(legs.psi)], 1), atol=1e-12)


def test_switch_frame_equals_retransform():
    rng = np.random.default_rng(1)
    for _ in range(30):
        w = random_route(rng, 5)
        p = rng.uniform(-800, 800, (6, 2))
        for j in range(3):
            q = np.asarray(to_path_frame(p, w, j))
            x1, y1 = switch_frame(q[:, 0], q[:, 1], w, j)
            np.testing.assert_allclose(np.stack([x1, y1], 1), np.asarray(to_path_frame(p, w, j + 1)),
                                       rtol=0, atol=1e-9)


def test_starboard_is_positive_y():
    north = np.array([[0.0, 0.0], [100.0, 0.0]])
    east = np.array([[0.0, 0.0], [0.0, 100.0]])
    assert float(to_path_frame([50.0, 5.0], north, 0)[1]) == pytest.approx(5.0)      # east of a north leg
    assert float(to_path_frame([50.0, -5.0], north, 0)[1]) == pytest.approx(-5.0)
    assert float(to_path_frame([-5.0, 50.0], east, 0)[1]) == pytest.approx(5.0)      # south of an east leg
    assert float(to_path_frame([-5.0, 50.0], east, 0)[0]) == pytest.approx(50.0)


def test_path_frame_jit_grad_traced_leg():
    rng = np.random.default_rng(2)
    w = random_route(rng, 4)
    p = rng.uniform(-300, 300, (5, 2))
    f = jax.jit(lambda p, w, j: to_path_frame(p, w, j))
    g = jax.jit(lambda q, w, j: from_path_frame(q, w, j))
    for j in range(3):
        q = f(p, w, jnp.int32(j))
        np.testing.assert_allclose(np.asarray(q), np.asarray(to_path_frame(p, w, j)), atol=1e-9)
        np.testing.assert_allclose(np.asarray(g(q, w, jnp.int32(j))), p, atol=1e-9)
        # d y_p / d p = the starboard normal, d x_p / d p = the tangent
        psi = leg_angles(w)[j]
        gy = jax.grad(lambda x: to_path_frame(x, w, j)[1])(jnp.asarray(p[0]))
        gx = jax.grad(lambda x: to_path_frame(x, w, j)[0])(jnp.asarray(p[0]))
        np.testing.assert_allclose(np.asarray(gy), [-math.sin(psi), math.cos(psi)], atol=1e-12)
        np.testing.assert_allclose(np.asarray(gx), [math.cos(psi), math.sin(psi)], atol=1e-12)
    # gradient w.r.t. the waypoints against central differences
    fun = lambda ww: jnp.sum(to_path_frame(p, ww, 1) * jnp.array([0.3, -0.7]))
    gw = np.asarray(jax.grad(fun)(jnp.asarray(w)))
    np.testing.assert_allclose(gw, central_difference(fun, w, 1e-5), atol=1e-6)
    # switch_frame under jit with a traced index
    q = np.asarray(to_path_frame(p, w, 0))
    sw = jax.jit(lambda x, y, j: switch_frame(x, y, w, j))
    np.testing.assert_allclose(np.stack(sw(q[:, 0], q[:, 1], jnp.int32(0)), 1), np.asarray(to_path_frame(p, w, 1)),
                               atol=1e-9)


def test_active_leg_rule():
    w = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 100.0], [200.0, 100.0]])
    assert active_leg([50.0, 3.0], w, 0, 5.0) == 0
    assert active_leg([100.0, -30.0], w, 0, 5.0) == 1                 # x_p = l_0 exactly
    assert active_leg([99.999, -30.0], w, 0, 5.0) == 0
    assert active_leg([96.0, 2.0], w, 0, 5.0) == 1                    # within R_a of WP_1
    assert active_leg([94.0, 2.0], w, 0, 5.0) == 0
    assert active_leg([96.0, 2.0], w, 0, 0.0) == 0
    assert active_leg([150.0, 100.0], w, 2, 5.0) == 2                 # never past the last leg
    assert active_leg([500.0, 900.0], w, 2, 5.0) == 2
    assert active_leg([400.0, 400.0], w, 0, 5.0) == 2                 # past both ends: skips to the last leg
    assert active_leg([150.0, 50.0], w, 1, 5.0) == 1                  # never goes back
    assert active_leg([120.0, 101.0], w, 0, 5.0) == 2                 # past leg 0 and leg 1
    # the traced version agrees with the host one
    rng = np.random.default_rng(3)
    wr = random_route(rng, 6)
    fj = jax.jit(lambda p, j, r: active_leg(p, wr, j, r))
    for _ in range(40):
        p = rng.uniform(-900, 900, 2)
        j = int(rng.integers(0, 5))
        r = float(rng.uniform(0, 80))
        assert int(fj(jnp.asarray(p), jnp.int32(j), r)) == active_leg(p, wr, j, r)


def test_path_frame_validation():
    w = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]])
    with pytest.raises(ValueError, match="waypoints must have shape"):
        to_path_frame([0.0, 0.0], np.zeros((1, 2)), 0)
    with pytest.raises(ValueError, match="waypoints must have shape"):
        leg_angles(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="waypoints must be finite"):
        to_path_frame([0.0, 0.0], [[0.0, 0.0], [np.nan, 1.0]], 0)
    with pytest.raises(ValueError, match="waypoints: leg 1 .*zero length"):
        leg_angles([[0.0, 0.0], [1.0, 0.0], [1.0, 0.0]])
    with pytest.raises(ValueError, match="j = 2 is out of range"):
        to_path_frame([0.0, 0.0], w, 2)
    with pytest.raises(ValueError, match="j = -1 is out of range"):
        from_path_frame([0.0, 0.0], w, -1)
    with pytest.raises(ValueError, match="j must be an integer"):
        to_path_frame([0.0, 0.0], w, True)
    with pytest.raises(ValueError, match="j must be an integer"):
        to_path_frame([0.0, 0.0], w, 0.5)
    with pytest.raises(ValueError, match="points must have shape"):
        to_path_frame([0.0, 0.0, 1.0], w, 0)
    with pytest.raises(ValueError, match="points must be finite"):
        to_path_frame([np.inf, 0.0], w, 0)
    with pytest.raises(ValueError, match="j = 1 is out of range.*next leg"):
        switch_frame(1.0, 2.0, w, 1)
    with pytest.raises(ValueError, match="switch_frame needs a next leg"):
        switch_frame(1.0, 2.0, w[:2], 0)
    with pytest.raises(ValueError, match="r_accept must be a finite number >= 0"):
        active_leg([0.0, 0.0], w, 0, -1.0)
    with pytest.raises(ValueError, match="position must have shape"):
        active_leg([0.0, 0.0, 0.0], w, 0, 1.0)


# ============================================================================================ corridor
PSI = math.radians(30.0)
T = np.array([math.cos(PSI), math.sin(PSI)])
N = np.array([-T[1], T[0]])              # starboard
START = np.array([120.0, -40.0])
L = 200.0
MARGIN = 3.0
DD = 50.0


def _frame_poly(corners_p):
    """A polygon given by (x_p, y_p) corners of the test leg's frame, in NED."""
    return np.array([START + x * T + y * N for x, y in corners_p])


def channel_land():
    """Banks at y_p = +30 (starboard) and y_p = -20 (port) along the whole leg and beyond, a square island
    at x_p in [80, 110], y_p in [12, 20] (starboard side) and one at x_p in [140, 150], y_p in [-4, 4] that
    crosses the leg."""
    star_bank = _frame_poly([(-100, 30), (L + 100, 30), (L + 100, 90), (-100, 90)])
    port_bank = _frame_poly([(-100, -20), (-100, -70), (L + 100, -70), (L + 100, -20)])
    island = _frame_poly([(80, 12), (110, 12), (110, 20), (80, 20)])
    crossing = _frame_poly([(140, -4), (150, -4), (150, 4), (140, 4)])
    return [star_bank, port_bank, Polygon(island), crossing]


def test_channel_corridor_device_equals_oracle_and_exact():
    clear_corridor_cache()
    w = np.array([START, START + L * T, START + L * T + 100 * np.array([1.0, 0.0])])
    land = channel_land()
    circles = []
    dev = leg_corridor(w, 0, land, margin=MARGIN, half_width=DD, sample=5.0, static_circles_out=circles)
    ora = leg_corridor(w, 0, land, margin=MARGIN, half_width=DD, sample=5.0, device=False)
    assert isinstance(dev, LegCorridor)
    np.testing.assert_allclose(dev.s, np.linspace(0, L, 41))
    for k in ("lower", "upper"):
        np.testing.assert_allclose(getattr(dev, k), getattr(ora, k), rtol=0, atol=1e-6)
    np.testing.assert_array_equal(dev.inside, ora.inside)
    assert not dev.inside.any()
    assert float(dev.psi) == pytest.approx(PSI) and float(dev.length) == pytest.approx(L)
    np.testing.assert_allclose(dev.start, START)
    # exact half-widths: banks minus the margin, the island's flat side minus the margin; the crossing
    # square is not in the corridor (it is a static circle instead)
    s = dev.s
    on_island = (s >= 80) & (s <= 110)
    np.testing.assert_allclose(dev.lower, -(20 - MARGIN), atol=1e-9)
    np.testing.assert_allclose(dev.upper[on_island], 12 - MARGIN, atol=1e-9)
    far = (s <= 80 - MARGIN) | (s >= 110 + MARGIN)
    np.testing.assert_allclose(dev.upper[far], 30 - MARGIN, atol=1e-9)
    assert np.all(dev.upper <= 30 - MARGIN + 1e-9)
    # the crossing square -> one enclosing circle: centre at its middle, radius half-diagonal + margin
    assert len(circles) == 1
    c, r = circles[0]
    np.testing.assert_allclose(c, START + 145 * T, atol=1e-6)
    assert r == pytest.approx(math.hypot(5, 4) + 2.0, abs=1e-6)
    # clipping + leg-local coordinates change nothing: the oracle on the whole (unclipped) chart in NED,
    # without the crossing square, gives the same bounds
    pos = START + s[:, None] * T
    full = cross_track_corridor_shapely(pos, land[:3], MARGIN, DD, heading=PSI)
    np.testing.assert_allclose(dev.lower, full.lower, atol=1e-6)
    np.testing.assert_allclose(dev.upper, full.upper, atol=1e-6)


def test_channel_corridor_radius_selects_land():
    clear_corridor_cache()
    w = np.array([START, START + L * T])
    land = channel_land()
    # R_RG = 15 m: the island (12 m) stays, the banks (20, 30 m) are dropped -> full half-width there
    c = leg_corridor(w, 0, land, margin=MARGIN, half_width=DD, sample=10.0, radius=15.0)
    np.testing.assert_allclose(c.lower, -DD)
    np.testing.assert_allclose(c.upper[(c.s >= 80) & (c.s <= 110)], 12 - MARGIN, atol=1e-9)
    assert np.all(c.upper[(c.s < 70) | (c.s > 120)] == DD)
    # no land at all -> +-dd everywhere
    c0 = leg_corridor(w, 0, [], margin=MARGIN, half_width=20.0, sample=10.0)
    np.testing.assert_array_equal(c0.upper, 20.0)
    np.testing.assert_array_equal(c0.lower, -20.0)


@pytest.mark.parametrize("seed", [0, 1])
def test_random_chart_device_equals_oracle(seed):
    clear_corridor_cache()
    rng = np.random.default_rng(seed)
    w = np.array([[0.0, 0.0], [150.0, 40.0], [260.0, -60.0], [300.0, 120.0]])
    land = []
    for _ in range(10):
        j = int(rng.integers(0, 3))
        x = rng.uniform(0.1, 0.9)
        base = w[j] + x * (w[j + 1] - w[j])
        land.append(star(rng, int(rng.integers(5, 14)), *(base + rng.uniform(-60, 60, 2)), 4.0, 20.0))
    land.append(star(rng, 8, *(w[1] + 0.3 * (w[2] - w[1])), 3.0, 8.0))         # crosses leg 1
    out_d, out_o = [], []
    dev = leg_corridors(w, land, margin=2.5, half_width=40.0, sample=4.0, static_circles_out=out_d)
    ora = leg_corridors(w, land, margin=2.5, half_width=40.0, sample=4.0, static_circles_out=out_o, device=False)
    for d, o in zip(dev, ora):
        assert np.all(d.lower <= 0) and np.all(d.upper >= 0)
        assert np.all(d.lower >= -40.0) and np.all(d.upper <= 40.0)
        np.testing.assert_allclose(d.lower, o.lower, rtol=0, atol=1e-6)
        np.testing.assert_allclose(d.upper, o.upper, rtol=0, atol=1e-6)
        np.testing.assert_array_equal(d.inside, o.inside)
        assert np.all(d.lower[d.inside] == 0) and np.all(d.upper[d.inside] == 0)
    assert len(out_d) == len(out_o) >= 1
    assert sum(int(d.inside.sum()) for d in dev) + sum(int((d.upper < 40).sum()) for d in dev) > 10   # land seen
    circles, remaining = crossing_land_circles(w, land, 2.0)
    assert circles.n_circles == len(out_d)
    # every remaining piece is clear of every leg
    for p in remaining:
        for j in range(3):
            assert not p.intersects(LineString([w[j], w[j + 1]]))


def test_cache_hits_and_keys():
    clear_corridor_cache()
    w = np.array([START, START + L * T])
    land = channel_land()
    a = leg_corridor(w, 0, land, margin=MARGIN, sample=10.0, device=False)
    info = corridor_cache_info()
    assert info["misses"] == 1 and info["hits"] == 0
    copy = [np.array(p) if isinstance(p, np.ndarray) else p for p in land]        # same content, new objects
    b = leg_corridor(w.copy(), 0, copy, margin=MARGIN, sample=10.0, device=False)
    assert b is a and corridor_cache_info()["hits"] == 1
    # a route that shares the leg hits too
    c = leg_corridor(np.vstack([w, w[-1] + [50.0, 0.0]]), 0, land, margin=MARGIN, sample=10.0, device=False)
    assert c is a
    d = leg_corridor(w, 0, land, margin=MARGIN + 1, sample=10.0, device=False)
    assert d is not a and corridor_cache_info()["misses"] == 2
    moved = [land[0] + 1.0] + land[1:]
    assert land_key(moved) != land_key(land)
    e = leg_corridor(w, 0, moved, margin=MARGIN, sample=10.0, device=False)
    assert e is not a
    with pytest.raises(ValueError):
        a.upper[0] = 1.0                      # cached arrays are read-only
    # circles reach static_circles_out on a cache hit too
    out = []
    leg_corridor(w, 0, land, margin=MARGIN, sample=10.0, device=False, static_circles_out=out)
    assert len(out) == 1


def test_corridor_bounds_interpolation_and_gradient():
    cor = LegCorridor(s=np.array([0.0, 10.0, 20.0, 30.0]), lower=np.array([-5.0, -3.0, -3.0, -8.0]),
                      upper=np.array([4.0, 6.0, 2.0, 2.0]), inside=np.zeros(4, bool), start=np.zeros(2),
                      psi=np.float64(0.0), length=np.float64(30.0))
    q = np.array([-4.0, 0.0, 5.0, 10.0, 12.5, 25.0, 30.0, 45.0])
    lo, up = corridor_bounds(cor, q)
    np.testing.assert_allclose(np.asarray(lo), [-5, -5, -4, -3, -3, -5.5, -8, -8])
    np.testing.assert_allclose(np.asarray(up), [4, 4, 5, 6, 5, 2, 2, 2])
    lo2, up2 = jax.jit(corridor_bounds)(cor, jnp.asarray(q))
    np.testing.assert_allclose(np.asarray(up2), np.asarray(up))
    # gradient w.r.t. s_query vs central differences (away from the knots), 0 outside the leg
    pts = np.array([-3.0, 3.3, 14.1, 27.2, 40.0])
    for which in (0, 1):
        g = np.asarray(jax.vmap(jax.grad(lambda x: corridor_bounds(cor, x)[which]))(jnp.asarray(pts)))
        h = 1e-6
        fd = (np.asarray(corridor_bounds(cor, pts + h)[which]) - np.asarray(corridor_bounds(cor, pts - h)[which])) / (2 * h)
        np.testing.assert_allclose(g, fd, atol=1e-6)
        assert g[0] == 0 and g[-1] == 0
    # residuals from NED positions (leg along psi = 0 from the origin): y_p = east
    r_lo, r_up = corridor_residuals(np.array([[5.0, 0.0], [5.0, 6.0], [5.0, -4.5]]), cor)
    np.testing.assert_allclose(np.asarray(r_lo), [-4.0, -10.0, 0.5])
    np.testing.assert_allclose(np.asarray(r_up), [-5.0, 1.0, -9.5])
    gr = jax.grad(lambda p: corridor_residuals(p, cor)[1])(jnp.array([5.0, 1.0]))
    np.testing.assert_allclose(np.asarray(gr), [-0.2, 1.0], atol=1e-12)       # d(y - g_rh(x))/d(n, e)


def test_device_corridor_rotated_leg_residuals():
    clear_corridor_cache()
    w = np.array([START, START + L * T])
    c = leg_corridor(w, 0, channel_land(), margin=MARGIN, sample=10.0)
    # a point 26 m to starboard at x_p = 40 is 1 m past the starboard bound (27); 10 m to port is feasible
    p = START + 40 * T + np.array([[26.0], [-10.0]]) * N
    r_lo, r_up = corridor_residuals(p, c)
    np.testing.assert_allclose(np.asarray(r_up), [26 - 27, -10 - 27], atol=1e-9)
    np.testing.assert_allclose(np.asarray(r_lo), [-17 - 26, -17 + 10], atol=1e-9)


# ============================================================================================ crossing land
def test_crossing_land_becomes_enclosing_circle_and_leaves_corridor():
    clear_corridor_cache()
    w = np.array([[0.0, 0.0], [200.0, 0.0], [400.0, -100.0]])
    rng = np.random.default_rng(7)
    rock = star(rng, 9, 100.0, 3.0, 5.0, 12.0)               # crosses leg 0
    part = star(rng, 7, 108.0, -4.0, 3.0, 6.0)                # overlaps the rock: same piece
    corner = star(rng, 8, 200.0, 0.0, 6.0, 9.0)               # on WP_1: crosses legs 0 and 1
    bank = np.array([[-50.0, 25.0], [250.0, 25.0], [250.0, 60.0], [-50.0, 60.0]])
    land = [rock, part, corner, bank]
    circles, remaining = crossing_land_circles(w, land, 2.0)
    assert circles.n_circles == 2 and len(remaining) == 1
    merged = Polygon(rock).union(Polygon(part))
    for piece in (merged, Polygon(corner)):
        k = int(np.argmin(np.linalg.norm(circles.centres - np.asarray(piece.centroid.coords[0]), axis=1)))
        c, r = circles.centres[k], circles.radii[k]
        verts = np.asarray(piece.exterior.coords)
        assert np.all(np.linalg.norm(verts - c, axis=1) <= r - 2.0 + 1e-9)       # inside the circle
        assert Point(c).buffer(r - 2.0 + 1e-6, quad_segs=256).covers(piece.buffer(-1e-3))
        assert r - 2.0 == pytest.approx(shapely.minimum_bounding_radius(piece), abs=1e-9)   # margin added
    assert remaining[0].equals(Polygon(bank))
    # the corridor: the crossing pieces' parts within 2 x margin of the leg are circles (split_crossing), the
    # rest stays land: no sample inside, never wider than the bank alone, equal to it away from the pieces
    out = []
    with_rock = leg_corridors(w, land, margin=3.0, half_width=30.0, sample=5.0, static_circles_out=out,
                              device=False)
    bank_only = leg_corridors(w, [bank], margin=3.0, half_width=30.0, sample=5.0, device=False)
    for j, (a, b) in enumerate(zip(with_rock, bank_only)):
        assert not a.inside.any()
        assert np.all(a.upper <= b.upper + 1e-9) and np.all(a.lower >= b.lower - 1e-9)
        away = (np.abs(a.s - 100.0) > 30.0) & (a.s > 15.0) & (a.s < a.s[-1] - 15.0) if j == 0 else a.s > 15.0
        np.testing.assert_array_equal(a.lower[away], b.lower[away])
        np.testing.assert_array_equal(a.upper[away], b.upper[away])
    assert np.any(with_rock[0].lower > bank_only[0].lower + 1e-6)      # the rock's far part still bounds it
    assert len(out) == 3                # the rock once, the corner piece once per leg (its near part per leg)
    got = StaticCircles.from_pairs(out)
    pieces = shapely.union_all([Polygon(rock), Polygon(part), Polygon(corner)])
    near = [g for leg in (LineString(w[:2]), LineString(w[1:2 + 1]))
            for g in shapely.get_parts(pieces.intersection(leg.buffer(6.0))) if g.intersects(leg)]
    for c, r in zip(got.centres, got.radii):       # each circle covers a piece's part within 6 m of a leg
        assert any(Point(c).buffer(r - 2.0 + 1e-6, quad_segs=256).covers(g.buffer(-1e-3)) for g in near)
    # legs=[1]: only the corner piece crosses leg 1
    c1, rem1 = crossing_land_circles(w, land, 0.0, legs=[1])
    assert c1.n_circles == 1 and len(rem1) == 2
    # land within the margin of the leg without touching it stays in RG and flags samples inside
    near = np.array([[50.0, 1.0], [60.0, 1.0], [60.0, 8.0], [50.0, 8.0]])
    c = leg_corridor(w, 0, [near], margin=3.0, half_width=30.0, sample=5.0, device=False)
    assert c.inside[(c.s >= 50) & (c.s <= 60)].all() and not c.inside[c.s < 45].any()
    assert np.all(c.upper[c.inside] == 0) and np.all(c.lower[c.inside] == 0)


# ============================================================================================ static circles
def test_circle_residuals_values_and_gradients():
    rng = np.random.default_rng(5)
    circles = StaticCircles.build(rng.uniform(-50, 50, (3, 2)), rng.uniform(1, 10, 3))
    p = rng.uniform(-60, 60, (6, 2))
    r_os = 2.5
    h = np.asarray(circle_residuals(p, circles, r_os))
    ref = circles.radii[None] + r_os - np.linalg.norm(p[:, None] - circles.centres[None], axis=-1)
    np.testing.assert_allclose(h, ref, atol=1e-12)
    assert h.shape == (6, 3)
    fun = lambda x: jnp.sum(circle_residuals(x, circles, r_os) * jnp.arange(1.0, 4.0))
    g = np.asarray(jax.grad(fun)(jnp.asarray(p)))
    np.testing.assert_allclose(g, central_difference(fun, p, 1e-6), atol=1e-6)
    # at a centre: value r + r_os, finite gradient (no NaN)
    at = circles.centres[:1]
    np.testing.assert_allclose(np.asarray(circle_residuals(at, circles, r_os))[0, 0], circles.radii[0] + r_os)
    g0 = np.asarray(jax.grad(lambda x: jnp.sum(circle_residuals(x, circles, r_os)))(jnp.asarray(at)))
    assert np.all(np.isfinite(g0))
    # batch axes, traced r_os, no circles
    hb = jax.jit(circle_residuals)(jnp.asarray(p)[None].repeat(2, 0), circles, 2.5)
    np.testing.assert_allclose(np.asarray(hb[1]), h, atol=1e-12)
    assert circle_residuals(p, StaticCircles.empty(), r_os).shape == (6, 0)


def test_static_circles_inputs():
    c = from_yaml([{"center_m": [10, -5.5], "radius_m": 3}, {"center_m": [0.0, 0.0], "radius_m": 0.5}])
    np.testing.assert_allclose(c.centres, [[10, -5.5], [0, 0]])
    np.testing.assert_allclose(c.radii, [3, 0.5])
    assert from_yaml(None).n_circles == 0 and from_yaml([]).n_circles == 0
    bad = [
        ([{"center_m": [0, 0], "radius_m": -1}], r"static_obstacles\[0\]\.radius_m must be >= 0"),
        ([{"center_m": [0, 0], "radius_m": 1}, {"center_m": [0], "radius_m": 1}],
         r"static_obstacles\[1\]\.center_m must be a list \[north, east\]"),
        ([{"center_m": [0, "x"], "radius_m": 1}], r"static_obstacles\[0\]\.center_m\[1\] must be a finite number"),
        ([{"center_m": [0, 0], "radius_m": True}], r"static_obstacles\[0\]\.radius_m must be a finite number"),
        ([{"center_m": [0, 0], "radius_m": float("nan")}], r"static_obstacles\[0\]\.radius_m must be a finite"),
        ([{"center_m": [0, 0]}], r"static_obstacles\[0\]\.radius_m is missing"),
        ([{"center_m": [0, 0], "radius_m": 1, "r": 2}], r"static_obstacles\[0\]: unknown key\(s\) r"),
        ([5], r"static_obstacles\[0\] must be a mapping"),
        ({"center_m": [0, 0]}, r"static_obstacles must be a list"),
    ]
    for entries, msg in bad:
        with pytest.raises(ValueError, match=msg):
            from_yaml(entries)
    with pytest.raises(ValueError, match="circles.centres must have shape"):
        StaticCircles.build(np.zeros((2, 3)), np.ones(2))
    with pytest.raises(ValueError, match=r"circles.radii must have shape \[2\]"):
        StaticCircles.build(np.zeros((2, 2)), np.ones(3))
    with pytest.raises(ValueError, match="circles.radii must be finite and >= 0"):
        StaticCircles.build(np.zeros((1, 2)), [-1.0])
    with pytest.raises(ValueError, match="circles.centres must be finite"):
        StaticCircles.build([[np.nan, 0.0]], [1.0])
    with pytest.raises(ValueError, match="r_os must be a finite number >= 0"):
        circle_residuals(np.zeros((2, 2)), c, -1.0)
    with pytest.raises(ValueError, match=r"positions must have shape \[\.\.\., K, 2\]"):
        circle_residuals(np.zeros(2), c, 1.0)
    with pytest.raises(ValueError, match="circles must be a StaticCircles"):
        circle_residuals(np.zeros((2, 2)), (np.zeros((1, 2)), np.ones(1)), 1.0)
    both = concat_circles(c, StaticCircles.empty(), c)
    assert both.n_circles == 4
    # circles from land: one per piece of the union, margin added
    sq = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 3.0], [0.0, 3.0]])
    cl = circles_from_land([sq, sq + [2.0, 0.0], sq + [100.0, 0.0]], 1.0)
    assert cl.n_circles == 2
    np.testing.assert_allclose(sorted(cl.radii), [3.5, 1.0 + math.hypot(3.0, 1.5)], atol=1e-9)
    centre, radius = enclosing_circle(Polygon(sq), 0.0)
    np.testing.assert_allclose(centre, [2.0, 1.5], atol=1e-9)
    assert radius == pytest.approx(2.5)


def test_corridor_validation():
    w = np.array([[0.0, 0.0], [100.0, 0.0]])
    land = [np.array([[10.0, 10.0], [20.0, 10.0], [20.0, 20.0]])]
    cases = [
        (dict(margin=-1.0), "margin must be a finite number >= 0"),
        (dict(margin=1.0, half_width=0.0), "half_width must be a finite number > 0"),
        (dict(margin=1.0, sample=float("nan")), "sample must be a finite number > 0"),
        (dict(margin=1.0, radius=-2.0), "radius must be a finite number >= 0"),
        (dict(margin=1.0, circle_margin=-2.0), "circle_margin must be a finite number >= 0"),
        (dict(margin=1.0, quad_segs=0), "quad_segs must be an integer >= 1"),
        (dict(margin=1.0, device="yes"), "device must be True or False"),
        (dict(margin=1.0, static_circles_out=()), "static_circles_out must be a list"),
        (dict(margin=1.0, sample=1e-5), "use a larger spacing"),
    ]
    for kw, msg in cases:
        with pytest.raises(ValueError, match=msg):
            leg_corridor(w, 0, land, **kw)
    with pytest.raises(ValueError, match="j = 1 is out of range"):
        leg_corridor(w, 1, land, margin=1.0)
    with pytest.raises(ValueError, match="waypoints: leg 0 .*zero length"):
        leg_corridor(np.zeros((2, 2)), 0, land, margin=1.0)
    with pytest.raises(ValueError, match=r"land_polygons\[1\] ring 0 must be a finite array"):
        leg_corridor(w, 0, [land[0], np.zeros((2, 2))], margin=1.0)
    with pytest.raises(ValueError, match=r"legs\[\] = 3 is out of range"):
        crossing_land_circles(w, land, 1.0, legs=[3])
    with pytest.raises(TypeError):
        leg_corridor(w, 0, land)                               # margin is required
    cor = leg_corridor(w, 0, land, margin=1.0, sample=50.0, device=False)
    with pytest.raises(ValueError, match="corridor must be a LegCorridor"):
        corridor_bounds(tuple(cor), 1.0)
    with pytest.raises(ValueError, match=r"positions must have shape \[\.\.\., 2\]"):
        corridor_residuals(np.zeros(3), cor)
