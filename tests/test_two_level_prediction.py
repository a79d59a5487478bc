"""Ground-avoiding CV target prediction of seed 001, eq. (2) (psbmpc_jax/two_level/prediction.py), float64.

The ray distance d_LOSg equals the NumPy oracle (psbmpc_jax/reference_two_level.py) and shapely on random
star polygons (one with a hole, possibly overlapping) for random rays, vertex-aimed rays, origins inside land
and in a hole, with one block and with many blocks per polygon; exact hand-made cases (through a vertex,
grazing a vertex, along an edge, on the boundary, missing, the range cap).  The prediction equals the oracle
step by step (rtol 1e-9) in both compare modes with per-target β / d_critical / max_range; a target heading
at a wall turns away by ±β steps and stays out of land, a clear target flies the exact constant-velocity
line; an empty chart gives straight lines; no NaN (also starting inside land); bad inputs raise ValueError
naming the field."""

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
from psbmpc_jax.reference_two_level import ground_avoiding_cv_reference, ray_land_distance_reference
from psbmpc_jax.two_level.prediction import (DEFAULT_BETA, ground_avoiding_cv, predict_targets,
                                             ray_land_distance)

from conftest import star

CFG = PlannerConfig(dtype="float64")
#: One chart shape for every prediction test (random land, the wall, "no land"): one compilation per mode.
CAPS = Capacities(polygons=4, vertices=64)
N_TARGETS, N_STEPS = 6, 40
N_RAYS = 160

ray_jit = jax.jit(ray_land_distance, static_argnames=("block",))


def chart_of(polygons, caps=CAPS):
    return pack_world(polygons, CFG, caps).polygons


def random_land(rng, k=3):
    """k star polygons in a 300 m box; the first one has a star hole around its centre (clear of the shell) and
    overlaps no other polygon, the others may overlap each other."""
    polys, centres = [], []
    for j in range(k):
        cx, cy = rng.uniform(-100, 100, 2)
        while j and math.hypot(cx - centres[0][0], cy - centres[0][1]) < 125.0:
            cx, cy = rng.uniform(-130, 130, 2)
        if j == 0:
            outer = star(rng, int(rng.integers(8, 20)), cx, cy, 45.0, 70.0)
            hole = star(rng, int(rng.integers(4, 10)), cx, cy, 12.0, 30.0)[::-1]
            polys.append((outer, hole))
        else:
            polys.append(star(rng, int(rng.integers(4, 20)), cx, cy, 15.0, 50.0))
        centres.append((cx, cy))
    return polys, np.array(centres)


def shapely_land(polys):
    return unary_union([Polygon(p[0], p[1:]) if isinstance(p, tuple) else Polygon(p) for p in polys])


def shapely_ray(land, o, chi, max_range):
    """d_LOSg by shapely: 0 inside, else the distance to the ray segment's intersection with the boundary."""
    pt = Point(o)
    if land.covers(pt):
        return 0.0
    end = (o[0] + max_range * math.cos(chi), o[1] + max_range * math.sin(chi))
    hit = LineString([tuple(o), end]).intersection(land.boundary)
    return math.inf if hit.is_empty else pt.distance(hit)


def vertex_rays(rng, polys, n):
    """Rays from random outside points aimed exactly at a vertex where the ray enters or leaves the polygon
    (the two neighbours strictly on opposite sides of the ray's line): origins, courses, the vertex distance."""
    rings = [r for p in polys for r in (p if isinstance(p, tuple) else (p,))]
    out = []
    while len(out) < n:
        ring = rings[int(rng.integers(len(rings)))]
        i = int(rng.integers(len(ring)))
        v, a, b = ring[i], ring[i - 1], ring[(i + 1) % len(ring)]
        o = v + rng.uniform(30.0, 120.0) * np.array([math.cos(th := rng.uniform(0, 2 * np.pi)), math.sin(th)])
        d = v - o
        ca = d[0] * (a - o)[1] - d[1] * (a - o)[0]
        cb = d[0] * (b - o)[1] - d[1] * (b - o)[0]
        if ca * cb < 0 and min(abs(ca), abs(cb)) > 1e-3 * float(d @ d):
            out.append((o, math.atan2(d[1], d[0]), float(np.hypot(*d))))
    return (np.array([o for o, _, _ in out]), np.array([c for _, c, _ in out]), np.array([r for _, _, r in out]))


# ------------------------------------------------------------------------------------------ ray distance
@pytest.mark.parametrize("seed", range(3))
def test_ray_distance_matches_oracles(seed):
    rng = np.random.default_rng(2300 + seed)
    polys, centres = random_land(rng, k=3)
    chart = chart_of(polys)
    land = shapely_land(polys)
    n_vert, n_in = 40, 4
    n_rand = N_RAYS - n_vert - 2 * n_in
    vo, vchi, vdist = vertex_rays(rng, polys, n_vert)
    origins = np.concatenate([rng.uniform(-200, 200, (n_rand, 2)), vo,
                              centres[1:2].repeat(n_in, 0) + rng.normal(0, 1.0, (n_in, 2)),   # inside land
                              centres[0:1].repeat(n_in, 0) + rng.normal(0, 1.0, (n_in, 2))])  # in the hole
    chis = np.concatenate([rng.uniform(-np.pi, np.pi, n_rand), vchi, rng.uniform(-np.pi, np.pi, 2 * n_in)])
    max_range = np.where(rng.uniform(size=N_RAYS) < 0.3, np.inf, rng.uniform(20.0, 400.0, N_RAYS))
    max_range[n_rand:n_rand + n_vert] = np.inf

    ref = np.array([ray_land_distance_reference(o, c, polys, r) for o, c, r in zip(origins, chis, max_range)])
    shp = np.array([shapely_ray(land, o, c, min(r, 1e4)) for o, c, r in zip(origins, chis, max_range)])
    finite = np.isfinite(ref)
    assert np.array_equal(finite, np.isfinite(shp))
    np.testing.assert_allclose(ref[finite], shp[finite], rtol=0, atol=1e-7)
    # the oracle case mix is what the test claims
    assert np.all(ref[n_rand + n_vert:n_rand + n_vert + n_in] == 0.0)          # inside land
    assert np.all(ref[n_rand + n_vert + n_in:] > 0.0)                           # in the hole: water
    assert np.all(ref[n_rand:n_rand + n_vert] <= vdist + 1e-9)                  # the vertex (or before) is hit
    assert (ref[n_rand:n_rand + n_vert] > vdist - 1e-9).sum() >= 5             # some hit the vertex itself
    assert (~finite).sum() >= 10 and (finite & (ref > 0)).sum() >= 20

    for block in (256, 5):                          # one block per polygon / many blocks per polygon
        d = np.asarray(ray_jit(jnp.asarray(origins), jnp.asarray(chis), chart, jnp.asarray(max_range), block=block))
        assert not np.any(np.isnan(d))
        assert np.array_equal(np.isfinite(d), finite)
        np.testing.assert_allclose(d[finite], ref[finite], rtol=1e-9, atol=1e-9)


def test_ray_distance_exact_cases():
    """Axis-aligned rays (cos 0 = 1, sin 0 = 0 exactly): hits through a vertex, grazing a vertex, along an
    edge, from the boundary; a miss; the range cap (t <= max_range hits); a hole; overlapping polygons (the
    even-odd parity is per polygon, so their overlap stays land)."""
    diamond = np.array([[10.0, 0.0], [20.0, 10.0], [30.0, 0.0], [20.0, -10.0]])        # enter at a vertex
    graze = np.array([[10.0, 100.0], [20.0, 105.0], [20.0, 110.0]])                     # touch a vertex only
    rect = np.array([[10.0, 200.0], [20.0, 200.0], [20.0, 205.0], [10.0, 205.0]])       # along an edge
    holed = (np.array([[-100.0, -100.0], [-100.0, -50.0], [-50.0, -50.0], [-50.0, -100.0]]),
             np.array([[-90.0, -90.0], [-60.0, -90.0], [-60.0, -60.0], [-90.0, -60.0]]))
    sq_a = np.array([[300.0, 0.0], [320.0, 0.0], [320.0, 20.0], [300.0, 20.0]])          # two overlapping
    sq_b = np.array([[310.0, 0.0], [330.0, 0.0], [330.0, 20.0], [310.0, 20.0]])          # polygons
    polys = [diamond, graze, rect, holed, sq_a, sq_b]
    chart = chart_of(polys, Capacities(polygons=8, vertices=64))
    cases = [  # origin, course, max_range, expected
        ((0.0, 0.0), 0.0, 100.0, 10.0),
        ((0.0, 100.0), 0.0, 100.0, 10.0),
        ((0.0, 200.0), 0.0, 100.0, 10.0),
        ((15.0, 200.0), 0.0, 100.0, 0.0),         # on the collinear edge
        ((20.0, 0.0), 0.0, 100.0, 0.0),           # inside the diamond
        ((0.0, 0.0), 0.0, 10.0, 10.0),            # hit exactly at the cap
        ((0.0, 0.0), 0.0, 9.99, math.inf),        # beyond the cap
        ((0.0, 300.0), 0.0, 1e6, math.inf),       # nothing ahead
        ((-75.0, -75.0), 0.0, 100.0, 15.0),       # inside the hole: water, the hole's ring is land's edge
        ((-95.0, -75.0), 0.0, 100.0, 0.0),        # in the ring between shell and hole
        ((-120.0, -75.0), 0.0, 100.0, 20.0),
        ((-120.0, -75.0), 0.0, math.inf, 20.0),
        ((315.0, 10.0), 0.0, 100.0, 0.0),         # in the overlap of two polygons: land
        ((290.0, 10.0), 0.0, 100.0, 10.0),
        ((340.0, 10.0), math.pi, 100.0, 10.0),    # cos(pi) = -1 exactly, sin(pi) ~ 1.2e-16
    ]
    o = np.array([c[0] for c in cases])
    chi = np.array([c[1] for c in cases])
    r = np.array([c[2] for c in cases])
    want = np.array([c[3] for c in cases])
    got = np.asarray(jax.jit(ray_land_distance)(jnp.asarray(o), jnp.asarray(chi), chart, jnp.asarray(r)))
    np.testing.assert_array_equal(got, want)
    ref = np.array([ray_land_distance_reference(c[0], c[1], polys, c[2]) for c in cases])
    np.testing.assert_array_equal(ref, want)


# ------------------------------------------------------------------------------------------ prediction
def random_targets(rng, centres):
    """N_TARGETS targets: most 40-110 m from a land centre and heading roughly at it, one far and
    random, one starting inside land (the second polygon's centre); speeds 0-4 m/s (one at rest)."""
    out = []
    for i in range(N_TARGETS):
        c = centres[int(rng.integers(len(centres)))]
        if i == N_TARGETS - 1:
            out.append([*centres[1], rng.uniform(-np.pi, np.pi), 2.0])
            continue
        th = rng.uniform(-np.pi, np.pi)
        p = c + rng.uniform(40.0, 110.0) * np.array([math.cos(th), math.sin(th)])
        chi = math.atan2(*(c - p)[::-1]) + rng.normal(0.0, 0.3)
        U = 0.0 if i == 0 else rng.uniform(1.0, 4.0)
        out.append([p[0], p[1], chi, U])
    return np.array(out)


@pytest.mark.parametrize("compare", ["plus", "both"])
def test_prediction_matches_reference(compare):
    n_turns = n_plus = n_minus = 0
    for seed in range(3):
        rng = np.random.default_rng(4100 + seed)
        polys, centres = random_land(rng, k=3)
        chart = chart_of(polys)
        state = random_targets(rng, centres)
        beta = rng.uniform(math.radians(2.0), math.radians(12.0), N_TARGETS)
        d_crit = rng.uniform(20.0, 80.0, N_TARGETS)
        max_range = None if seed == 0 else d_crit * rng.uniform(1.2, 3.0, N_TARGETS)
        dt = 1.0 if seed == 0 else 1.5
        got = predict_targets(state, chart, N_STEPS, dt, beta=beta, d_critical=d_crit, max_range=max_range,
                              compare=compare)
        pos, chi, d_los = ground_avoiding_cv_reference(state, polys, N_STEPS, dt, beta=beta, d_critical=d_crit,
                                                       max_range=max_range, compare=compare)
        assert got.positions.shape == (N_TARGETS, N_STEPS + 1, 2) and got.courses.shape == (N_TARGETS, N_STEPS + 1)
        assert got.d_los.shape == (N_TARGETS, N_STEPS)
        assert not any(np.any(np.isnan(np.asarray(a))) for a in got)
        np.testing.assert_allclose(np.asarray(got.positions), pos, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(np.asarray(got.courses), chi, rtol=1e-9, atol=1e-12)
        finite = np.isfinite(d_los)
        assert np.array_equal(np.isfinite(np.asarray(got.d_los)), finite)
        np.testing.assert_allclose(np.asarray(got.d_los)[finite], d_los[finite], rtol=1e-9, atol=1e-9)
        steps = np.diff(chi, axis=1) / beta[:, None]
        assert np.allclose(steps, np.round(steps), atol=1e-9) and np.all(np.abs(np.round(steps)) <= 1)
        n_turns += int(np.sum(np.round(steps) != 0))
        n_plus += int(np.sum(np.round(steps) > 0))
        n_minus += int(np.sum(np.round(steps) < 0))
        assert d_los[-1, 0] == 0.0 and got.d_los[-1, 0] == 0.0             # the target starting inside land
    assert n_turns >= 20 and n_plus >= 5 and n_minus >= 3, (n_turns, n_plus, n_minus)


#: A long wall across the course of targets heading north from the origin (x in [100, 120], y in ±500).
WALL = np.array([[100.0, -500.0], [100.0, 500.0], [120.0, 500.0], [120.0, -500.0]])


def test_target_heading_at_a_wall_turns_away_and_a_clear_one_keeps_its_course():
    chart = chart_of([WALL])
    U, n = 2.0, 120
    state = np.array([[0.0, 0.0, 0.0, U],                       # straight at it: tie-free +β (starboard)
                      [0.0, 0.0, math.radians(-10.0), U],       # slightly to port: turns to port (−β)
                      [0.0, 0.0, math.radians(10.0), U],        # slightly to starboard: turns to starboard
                      [0.0, 0.0, math.pi, U],                   # away from the wall: clear
                      [50.0, 30.0, math.radians(90.0), 3.0],    # parallel to it: clear
                      [-10.0, 0.0, 0.0, 0.0]])                  # at rest, 110 m off: clear (d_LOSg = inf)
    beta = DEFAULT_BETA
    for compare in ("plus", "both"):
        out = predict_targets(state, chart, n, 1.0, compare=compare)
        pos, chi, d_los = (np.asarray(a) for a in out)
        assert not np.any(np.isnan(pos)) and not np.any(np.isnan(chi))
        steps = np.round(np.diff(chi, axis=1) / beta)
        np.testing.assert_allclose(np.diff(chi, axis=1), steps * beta, atol=1e-12)
        assert set(np.unique(steps)) <= {-1.0, 0.0, 1.0}
        for i, sign in ((0, 1.0), (1, -1.0), (2, 1.0)):
            turned = steps[i][steps[i] != 0]
            assert len(turned) >= 9 and np.all(turned == sign), (compare, i)   # turns away, >= 45 degrees
            assert pos[i, :, 0].max() < 100.0 - 2.0                             # never reaches the wall
            np.testing.assert_allclose(np.hypot(*np.diff(pos[i], axis=0).T), U, rtol=1e-12)   # constant U
        # a target with a clear course keeps it exactly: the constant-velocity line
        for i in (3, 4, 5):
            assert np.all(chi[i] == state[i, 2]) and np.all(np.isinf(d_los[i]))
            k = np.arange(n + 1)[:, None]
            cv = state[i, :2] + k * state[i, 3] * np.array([math.cos(state[i, 2]), math.sin(state[i, 2])])
            np.testing.assert_allclose(pos[i], cv, rtol=1e-12, atol=1e-9)


def test_empty_chart_gives_straight_lines_and_no_nan():
    rng = np.random.default_rng(7)
    state = np.column_stack([rng.uniform(-100, 100, (N_TARGETS, 2)), rng.uniform(-np.pi, np.pi, N_TARGETS),
                             rng.uniform(0.0, 5.0, N_TARGETS)])
    k = np.arange(N_STEPS + 1)[None, :, None]
    cv = state[:, None, :2] + k * 2.0 * state[:, None, 3:4] * np.stack([np.cos(state[:, 2]), np.sin(state[:, 2])],
                                                                        axis=1)[:, None, :]
    for chart in (chart_of([]), pack_world([], CFG).polygons):     # padded-but-empty and zero polygons
        out = predict_targets(state, chart, N_STEPS, 2.0)
        assert np.all(np.asarray(out.courses) == state[:, 2:3])
        assert np.all(np.isinf(np.asarray(out.d_los)))
        np.testing.assert_allclose(np.asarray(out.positions), cv, rtol=1e-12, atol=1e-9)
    assert pack_world([], CFG).polygons.vertices.shape[0] == 0


def test_single_state_inside_land_and_inside_a_users_jit():
    """A single state [4] drops the target axis; a target starting inside land gets d_LOSg = 0 and turns +β
    every step while inside, without NaN; the wrapper traces inside a caller's jit."""
    chart = chart_of([WALL])
    one = np.array([110.0, 0.0, 0.0, 1.0])                      # inside the wall, heading north
    out = predict_targets(one, chart, N_STEPS)
    assert out.positions.shape == (N_STEPS + 1, 2) and out.courses.shape == (N_STEPS + 1,)
    pos, chi, d_los = (np.asarray(a) for a in out)
    assert not np.any(np.isnan(pos)) and not np.any(np.isnan(chi)) and not np.any(np.isnan(d_los))
    inside = (pos[:-1, 0] >= 100.0) & (pos[:-1, 0] <= 120.0)
    assert inside[0] and np.all(d_los[inside] == 0.0)
    np.testing.assert_allclose(np.diff(chi)[inside], DEFAULT_BETA, rtol=1e-12)
    ref = ground_avoiding_cv_reference(one, [WALL], N_STEPS, 1.0, beta=DEFAULT_BETA, d_critical=50.0)
    np.testing.assert_allclose(pos, ref[0][0], rtol=1e-9, atol=1e-9)

    state = np.tile(one, (N_TARGETS, 1))
    state[:, 1] += np.arange(N_TARGETS) * 10.0
    jitted = jax.jit(lambda s, b: predict_targets(s, chart, N_STEPS, beta=b).positions)
    np.testing.assert_allclose(np.asarray(jitted(jnp.asarray(state), DEFAULT_BETA)),
                               np.asarray(predict_targets(state, chart, N_STEPS).positions), rtol=1e-12)
    # the raw kernel is traceable with static n_steps / compare
    kern = jax.jit(ground_avoiding_cv, static_argnames=("n_steps", "compare", "block"))
    raw = kern(jnp.asarray(state), chart, n_steps=N_STEPS, dt=1.0, beta=DEFAULT_BETA, d_critical=50.0)
    np.testing.assert_allclose(np.asarray(raw.positions), np.asarray(jitted(jnp.asarray(state), DEFAULT_BETA)),
                               rtol=1e-12)


# ------------------------------------------------------------------------------------------ validation
GOOD = np.array([[0.0, 0.0, 0.0, 2.0], [10.0, 0.0, 1.0, 1.0]])


@pytest.mark.parametrize("kwargs, field", [
    (dict(state=np.zeros(3)), "state"),
    (dict(state=np.zeros((2, 5))), "state"),
    (dict(state=np.zeros((0, 4))), "state"),
    (dict(state=np.array([[0.0, np.nan, 0.0, 1.0]])), "state"),
    (dict(state=np.array([[0.0, 0.0, 0.0, -1.0]])), "state speed U"),
    (dict(state=np.array([["a", "b", "c", "d"]])), "state"),
    (dict(n_steps=0), "n_steps"),
    (dict(n_steps=1.5), "n_steps"),
    (dict(n_steps=True), "n_steps"),
    (dict(dt=0.0), "dt"),
    (dict(dt=-1.0), "dt"),
    (dict(dt=np.nan), "dt"),
    (dict(dt=[1.0, 2.0]), "dt"),
    (dict(beta=0.0), "beta"),
    (dict(beta=-0.1), "beta"),
    (dict(beta=math.pi), "beta"),
    (dict(beta=np.inf), "beta"),
    (dict(beta=np.nan), "beta"),
    (dict(beta=np.full(3, 0.1)), "beta"),
    (dict(beta=np.array([0.1, 0.0])), "beta"),
    (dict(d_critical=0.0), "d_critical"),
    (dict(d_critical=-5.0), "d_critical"),
    (dict(d_critical=np.inf), "d_critical"),
    (dict(d_critical=np.ones((2, 2))), "d_critical"),
    (dict(max_range=0.0), "max_range"),
    (dict(max_range=np.nan), "max_range"),
    (dict(max_range=-np.inf), "max_range"),
    (dict(compare="minus"), "compare"),
    (dict(compare=None), "compare"),
    (dict(chart=np.zeros((1, 4, 2))), "chart"),
    (dict(block=0), "block"),
])
def test_bad_inputs_raise_value_error_naming_the_field(kwargs, field):
    args = dict(state=GOOD, chart=chart_of([WALL]), n_steps=5)
    args.update(kwargs)
    with pytest.raises(ValueError, match=field):
        predict_targets(**args)


def test_good_edge_values_are_accepted():
    """max_range = +inf (uncapped), per-target arrays, integer states, n_steps = 1."""
    out = predict_targets(GOOD.astype(int), chart_of([WALL]), 1, beta=np.array([0.1, 3.0]),
                          d_critical=np.array([1.0, 500.0]), max_range=np.inf)
    assert out.positions.shape == (2, 2, 2) and out.positions.dtype == jnp.float64
