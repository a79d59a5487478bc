"""Shared test setup: 64-bit JAX, an optional persistent compilation cache, a seeded random-situation
builder and helpers to pad packed device arrays to fixed capacities (so that many situations share one
compiled evaluator)."""

from __future__ import annotations

import math
import os

import jax

# Must happen before any JAX array is created: the float64 evaluator and the reference comparisons need it.
jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from psbmpc_jax.behaviours import enumerate_behaviours_deg  # noqa: E402
from psbmpc_jax.evaluate import SituationArrays  # noqa: E402
from psbmpc_jax.problem import Obstacle, OwnShip, Situation  # noqa: E402


def pytest_configure(config):
    """Persistent XLA compilation cache under .pytest_cache (set PSBMPC_TEST_NO_JAX_CACHE=1 to disable).

    Cold runs are unaffected; warm runs skip most of the (dominant) compile time."""
    if os.environ.get("PSBMPC_TEST_NO_JAX_CACHE"):
        return
    try:
        cache_dir = config.cache.mkdir("jax-compilation-cache")
        jax.config.update("jax_compilation_cache_dir", str(cache_dir))
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
    except Exception:  # pragma: no cover - cache is an optimisation only
        pass


# ------------------------------------------------------------------------------------------ behaviours
#: A small two-maneuver table (B = 2*5*1*3 = 30): speeds x courses for M1, course changes for M2.
SMALL_BEHAVIOURS = enumerate_behaviours_deg(((1.0, 0.5), (1.0,)),
                                            ((-45.0, -15.0, 0.0, 15.0, 45.0), (-30.0, 0.0, 30.0)))


@pytest.fixture(scope="session")
def small_behaviours() -> np.ndarray:
    return SMALL_BEHAVIOURS.copy()


# ------------------------------------------------------------------------------------------ situations
def _rot(a: float) -> np.ndarray:
    return np.array([math.cos(a), math.sin(a)])


def _random_cov(rng: np.random.Generator) -> np.ndarray:
    """A random 4x4 SPD covariance with a correlated, positive-definite positional block (std ~0.7-3 m)."""
    A = rng.normal(size=(4, 4)) * np.array([1.5, 1.5, 0.1, 0.1])[:, None]
    return A @ A.T + np.diag([0.5, 0.5, 0.01, 0.01])


def star_polygon(rng: np.random.Generator, centre, r_min: float, r_max: float, n: int) -> np.ndarray:
    """A random star-shaped ring (sorted angles, random radii) around ``centre``."""
    ang = np.sort(rng.uniform(0.0, 2 * math.pi, n))
    while np.min(np.diff(np.r_[ang, ang[0] + 2 * math.pi])) < 0.05:
        ang = np.sort(rng.uniform(0.0, 2 * math.pi, n))
    rad = rng.uniform(r_min, r_max, n)
    return np.asarray(centre, float)[None, :] + rad[:, None] * np.stack([np.cos(ang), np.sin(ang)], axis=1)


def random_situation(seed: int, *, T: float = 30.0, n_obstacles: int | None = None, n_polygons: int | None = None,
                     max_n_ps: int = 5, max_vertices: int = 12) -> Situation:
    """A random but *interacting* situation for a horizon of ``T`` seconds.

    Own-ship: random heading and speed, a route of 2-3 waypoints starting at its position.  Obstacles
    (1-3): each aimed to pass within a few metres of the own-ship's nominal path at a random time inside the
    horizon, random speed/course, random SPD covariance, n_ps in {1, 3, 5} (<= ``max_n_ps``) with Dirichlet
    probabilities, random weight/zeta/length, half of them with a 2-3 waypoint route.  Polygons (0-2):
    small star-shaped rings 12-35 m to the side of the own-ship's path, so that grounding costs vary across
    behaviours.
    """
    rng = np.random.default_rng(seed)
    chi0 = rng.uniform(-math.pi, math.pi)
    U = rng.uniform(1.5, 3.0)
    p0 = rng.uniform(-200.0, 200.0, 2)
    # route: first leg roughly along the heading, then 0-1 extra waypoints with a turn
    n_wp = int(rng.integers(2, 4))
    leg_course = chi0 + rng.uniform(-0.3, 0.3)
    wps = [p0 + rng.normal(0.0, 3.0, 2)]
    for _ in range(n_wp - 1):
        wps.append(wps[-1] + rng.uniform(0.5, 1.2) * U * T * _rot(leg_course))
        leg_course += rng.uniform(-1.0, 1.0)
    own = OwnShip(state=[p0[0], p0[1], chi0, U * rng.uniform(0.8, 1.1)], waypoints=np.array(wps),
                  U_d=U, length=float(rng.uniform(4.0, 10.0)), width=3.0)

    def own_nominal(t: float) -> np.ndarray:  # straight-line approximation of where the own-ship will be
        return p0 + U * t * _rot(chi0)

    n_o = int(rng.integers(1, 4)) if n_obstacles is None else n_obstacles
    obstacles = []
    for i in range(n_o):
        t_meet = rng.uniform(0.3, 0.9) * T
        meet = own_nominal(t_meet) + rng.normal(0.0, 4.0, 2)
        V = rng.uniform(0.5, 3.5) if rng.uniform() > 0.1 else 0.0
        course = rng.uniform(-math.pi, math.pi)
        vel = V * _rot(course)
        start = meet - vel * t_meet
        choices = [n for n in (1, 3, 5) if n <= max_n_ps]
        n_ps = int(rng.choice(choices))
        probs = rng.dirichlet(np.full(n_ps, 2.0)) if n_ps > 1 else None
        waypoints = None
        if V > 0 and rng.uniform() < 0.5:
            w = [start + rng.normal(0.0, 2.0, 2)]
            c = course
            for _ in range(int(rng.integers(1, 3))):
                w.append(w[-1] + rng.uniform(0.4, 1.0) * V * T * _rot(c))
                c += rng.uniform(-0.8, 0.8)
            waypoints = np.array(w)
        obstacles.append(Obstacle(state=[start[0], start[1], vel[0], vel[1]], cov=_random_cov(rng),
                                  length=float(rng.uniform(4.0, 12.0)), width=3.0, waypoints=waypoints,
                                  n_ps=n_ps, probs=probs, weight=float(rng.uniform(0.5, 2.0)),
                                  zeta=float(rng.uniform(0.5, 1.5))))

    n_p = int(rng.integers(0, 3)) if n_polygons is None else n_polygons
    polys = []
    for _ in range(n_p):
        t_c = rng.uniform(0.3, 1.0) * T
        side = rng.choice([-1.0, 1.0])
        normal = _rot(chi0 + side * math.pi / 2)
        centre = own_nominal(t_c) + rng.uniform(12.0, 35.0) * normal
        polys.append(star_polygon(rng, centre, 3.0, 10.0, int(rng.integers(3, max_vertices + 1))))
    return Situation(own, tuple(obstacles), tuple(polys))


@pytest.fixture(scope="session")
def make_situation():
    return random_situation


# ------------------------------------------------------------------------------------------ padding
#: Capacities big enough for every :func:`random_situation` (n_M = 2 tables of <= 64 behaviours).
CAPS = dict(O=4, S=5, W=4, Wo=4, P=2, V=16, B=64)


def pad_arrays(sit: SituationArrays, *, O=None, S=None, W=None, Wo=None, P=None, V=None, B=None,
               junk: bool = True) -> SituationArrays:
    """Pad packed arrays to (possibly) larger capacities.

    With ``junk=True`` every padding slot -- the new ones and those ``pack_situation`` already made -- is
    deliberately hostile, while staying within the documented contract (masks False, scenario
    probabilities 0 outside the real scenarios): masked obstacles sit on the own-ship with a tiny covariance,
    all their scenario slots "valid" by ``n_ps`` and non-zero weight/zeta; masked polygons are a big box
    around the own-ship; masked behaviours are straight ahead at full speed (the cheapest possible path
    cost); waypoint and vertex slots beyond the valid counts hold far-away garbage.  A correct evaluator
    ignores all of it."""
    a = {k: np.array(v) for k, v in sit._asdict().items()}
    o0, s0 = a["obs_probs"].shape
    w0, wo0 = a["own_wx"].shape[1], a["obs_wx"].shape[1]
    p0, v0 = a["poly_vertices"].shape[:2]
    b0 = a["behaviours"].shape[0]
    O, S, W, Wo = O or o0, S or s0, W or w0, Wo or wo0
    P = p0 if P is None else P
    V, B = V or v0, B or b0
    assert O >= o0 and S >= s0 and W >= w0 and Wo >= wo0 and P >= p0 and V >= v0 and B >= b0

    def grow(arr, shape, fill):
        out = np.full(shape, fill, dtype=arr.dtype)
        out[tuple(slice(0, n) for n in arr.shape)] = arr
        return out

    g = 12345.0
    own_wx, own_wy = grow(a["own_wx"], (1, W), 0.0), grow(a["own_wy"], (1, W), 0.0)
    obs_state, obs_cov = grow(a["obs_state"], (O, 4), 0.0), grow(a["obs_cov"], (O, 4, 4), 0.0)
    obs_length = grow(a["obs_length"], (O,), 5.0)
    obs_wx, obs_wy = grow(a["obs_wx"], (O, Wo), 0.0), grow(a["obs_wy"], (O, Wo), 0.0)
    obs_n, obs_n_ps = grow(a["obs_n"], (O,), 2), grow(a["obs_n_ps"], (O,), 1)
    obs_probs = grow(a["obs_probs"], (O, S), 0.0)
    obs_weight, obs_zeta = grow(a["obs_weight"], (O,), 0.0), grow(a["obs_zeta"], (O,), 0.0)
    obs_mask = grow(a["obs_mask"], (O,), False)
    poly_vertices = grow(a["poly_vertices"], (P, V, 2), 0.0)
    poly_n, poly_mask = grow(a["poly_n"], (P,), 3), grow(a["poly_mask"], (P,), False)
    poly_next = grow(a["poly_next"], (P, V), 0)
    poly_next[p0:, :3] = [1, 2, 0]
    behaviours = grow(a["behaviours"], (B,) + a["behaviours"].shape[1:], 0.0)
    beh_mask = grow(a["beh_mask"], (B,), False)
    for i in range(o0, O):  # neutral padding like pack_situation's (a valid 2-point route)
        obs_cov[i] = np.eye(4)
        obs_wx[i, 1] = 1.0
    for j in range(p0, P):
        poly_vertices[j, :3] = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]
    behaviours[b0:] = behaviours[0]

    if junk:
        ox, oy = a["own_state"][:2]
        own_wx[0, int(a["own_n"][0]):], own_wy[0, int(a["own_n"][0]):] = g, -g
        for i in range(O):
            if not obs_mask[i]:
                obs_state[i] = [ox + 1.0, oy, -1.0, 0.0]
                obs_cov[i] = np.eye(4) * 0.01
                obs_wx[i, :2], obs_wy[i, :2] = [ox + 1.0, ox - 99.0], [oy, oy]
                obs_n[i], obs_n_ps[i], obs_weight[i], obs_zeta[i] = 2, S, 1.0, 1.0
            obs_wx[i, obs_n[i]:], obs_wy[i, obs_n[i]:] = g, -g
        for j in range(P):
            if not poly_mask[j]:
                poly_vertices[j, :4] = np.array([[-50.0, -50.0], [-50.0, 50.0], [50.0, 50.0], [50.0, -50.0]]) + [ox, oy]
                poly_n[j] = 4
                poly_next[j, :4] = [1, 2, 3, 0]
            poly_vertices[j, poly_n[j]:] = g
        behaviours[~beh_mask] = np.array([1.0, 0.0])

    f = lambda x: jnp.asarray(x, a["own_state"].dtype)
    i32 = lambda x: jnp.asarray(x, jnp.int32)
    return SituationArrays(
        own_state=f(a["own_state"]), own_wx=f(own_wx), own_wy=f(own_wy), own_n=i32(a["own_n"]),
        U_d=f(a["U_d"]), own_length=f(a["own_length"]), obs_state=f(obs_state), obs_cov=f(obs_cov),
        obs_length=f(obs_length), obs_wx=f(obs_wx), obs_wy=f(obs_wy), obs_n=i32(obs_n), obs_n_ps=i32(obs_n_ps),
        obs_probs=f(obs_probs), obs_weight=f(obs_weight), obs_zeta=f(obs_zeta), obs_mask=jnp.asarray(obs_mask),
        poly_vertices=f(poly_vertices), poly_next=i32(poly_next), poly_n=i32(poly_n),
        poly_mask=jnp.asarray(poly_mask),
        grid_values=sit.grid_values, grid_origin=sit.grid_origin, grid_spacing=sit.grid_spacing,
        grid_margin=sit.grid_margin, grid_active=sit.grid_active,
        behaviours=f(behaviours), beh_mask=jnp.asarray(beh_mask), last_offsets=f(a["last_offsets"]),
    )


@pytest.fixture
def fixed_caps(monkeypatch):
    """Make ``Planner.plan`` pack every situation to the fixed capacities :data:`CAPS` (hostile padding),
    so that all random situations share one compiled evaluator per config."""
    import psbmpc_jax.planner as planner_mod

    original = planner_mod.pack_situation

    def pack_fixed(situation, behaviours, state, config, grid=None):
        return pad_arrays(original(situation, behaviours, state, config, grid), **CAPS)

    monkeypatch.setattr(planner_mod, "pack_situation", pack_fixed)
    return CAPS
