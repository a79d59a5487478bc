"""Shared test setup: 64-bit JAX, an optional persistent compilation cache, a seeded random-situation
builder and helpers to pad packed device arrays to fixed capacities (so that many situations share one
compiled evaluator)."""

from __future__ import annotations

import gc
import math
import os
import subprocess
import sys
from pathlib import Path

#: The tests compile with LLVM's optimisation off (``--xla_backend_optimization_level=0``): XLA's own HLO passes
#: still run, so every test checks the same program a user compiles, and only the machine code is less optimised.
#: Compilation is most of the suite's time, and this cut the suite from 16 min 40 s to 13 min 23 s on the 2-core
#: VM (README "Tests").  PSBMPC_TEST_XLA_O0=0 runs the tests at XLA's default level; the benchmarks, the CLI and
#: the library never set it.  Set before JAX starts its backend (XLA reads XLA_FLAGS once).
O0_FLAG = "--xla_backend_optimization_level=0"
if os.environ.get("PSBMPC_TEST_XLA_O0", "1") != "0" and "xla_backend_optimization_level" not in \
        os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") + " " + O0_FLAG).strip()

import jax  # noqa: E402

# Must happen before any JAX array is created: the float64 evaluator and the reference comparisons need it.
jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from psbmpc_jax.behaviours import enumerate_behaviours_deg  # noqa: E402
from psbmpc_jax.packing import (BehaviourArrays, ChartArrays, ObstacleArrays, OwnShipArrays,  # noqa: E402
                                SolveInputs, WorldArrays)
from psbmpc_jax.situation import Obstacle, OwnShip, Situation  # noqa: E402


# ------------------------------------------------------------------------------------------ memory maps
#: XLA:CPU keeps about 18 memory mappings per compiled program, and JAX's caches keep every program alive.  A
#: process that compiles ~3 500 programs reaches Linux's ``vm.max_map_count`` (65 530 by default): LLVM then fails
#: with "Cannot allocate memory" and the process segfaults.  That was the "random" worker crash of the full suite
#: (README "Tests"; reproduced with 2 750 small jitted functions at 64 461 maps).  After a test, when the worker
#: holds more than this share of the limit, JAX's caches are cleared; later tests compile again what they need.
MAP_SHARE = 0.5


def map_count(path: str = "/proc/self/maps") -> int | None:
    """The number of memory mappings of this process (None where ``/proc`` is not available)."""
    try:
        with open(path, "rb") as fh:
            return sum(1 for _ in fh)
    except OSError:
        return None


def map_limit(path: str = "/proc/sys/vm/max_map_count") -> int | None:
    """The kernel's limit on memory mappings per process (None where it cannot be read)."""
    try:
        with open(path, encoding="ascii") as fh:
            return int(fh.read().strip())
    except (OSError, ValueError):
        return None


def release_compiled_programs(share: float = MAP_SHARE, count=map_count, limit=map_limit) -> bool:
    """Clear JAX's caches (``jax.clear_caches``) when the mappings exceed ``share`` of the limit; True if it did."""
    n, cap = count(), limit()
    if n is None or cap is None or n <= share * cap:
        return False
    jax.clear_caches()
    gc.collect()
    return True


@pytest.hookimpl(trylast=True)
def pytest_runtest_teardown(item, nextitem):
    if release_compiled_programs() and _PROFILE is not None:
        _PROFILE.note_cache_clear()


#: PSBMPC_TEST_PROFILE=DIR: wall and XLA compile time per test (tests/compile_profile.py, tools/suite_profile.py)
_PROFILE = None
if os.environ.get("PSBMPC_TEST_PROFILE"):
    from compile_profile import CompileProfile
    _PROFILE = CompileProfile(os.environ["PSBMPC_TEST_PROFILE"], os.environ.get("PYTEST_XDIST_WORKER", "main"))


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    if _PROFILE is not None:
        _PROFILE.start(item.nodeid)
    try:
        yield
    finally:
        if _PROFILE is not None:
            _PROFILE.stop()


def pytest_configure(config):
    """Persistent XLA compilation cache under .pytest_cache (set PSBMPC_TEST_NO_JAX_CACHE=1 to disable).

    Cold runs are unaffected; warm runs skip most of the (dominant) compile time.

    Under CI (``CI`` set; every CI run starts from a fresh clone, so its cache is always cold) the persistent
    cache is switched off altogether (``jax_enable_compilation_cache``), also for the in-process CLI tests that
    call :func:`psbmpc_jax.enable_compilation_cache`: writing it only costs time there, and a local run saw an
    XLA abort inside a cache write (``put_executable_and_time``) with two workers."""
    if os.environ.get("CI"):
        jax.config.update("jax_enable_compilation_cache", False)
        return
    if os.environ.get("PSBMPC_TEST_NO_JAX_CACHE"):
        return
    try:
        cache_dir = config.cache.mkdir("jax-compilation-cache")
        jax.config.update("jax_compilation_cache_dir", str(cache_dir))
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
    except Exception:  # pragma: no cover - cache is an optimisation only
        pass


# ------------------------------------------------------------------------------------------ 4 host devices
#: The repository root (the subprocess below runs there, with it and tests/ on PYTHONPATH).
ROOT = Path(__file__).resolve().parents[1]


def run_on_four_host_devices(request, script: str, args=(), *, timeout: float = 300) -> subprocess.CompletedProcess:
    """``python -c script *args`` in a process with 4 forced XLA host devices
    (``--xla_force_host_platform_device_count=4``), 64-bit JAX on the CPU, at XLA's default optimisation level
    (as users compile: :data:`O0_FLAG`, the suite's default, is removed), in :data:`ROOT` with the package and
    tests/ importable.  A persistent compilation cache folder (pytest's cache, unless ``-p no:cacheprovider`` or
    ``PSBMPC_TEST_NO_JAX_CACHE``) is appended as the last argument.  Fails the test when the process does not
    exit with 0, showing the ends of its stdout and stderr; returns the finished process."""
    env = dict(os.environ)
    flags = env.get("XLA_FLAGS", "").replace(O0_FLAG, "")
    env["XLA_FLAGS"] = (flags + " --xla_force_host_platform_device_count=4").strip()
    env["PSBMPC_TEST_XLA_O0"] = "0"
    env["JAX_ENABLE_X64"] = "1"
    env["JAX_PLATFORMS"] = "cpu"
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), str(ROOT / "tests"), env.get("PYTHONPATH")) if p)
    args = [str(a) for a in args]
    cache = getattr(request.config, "cache", None)                         # None under -p no:cacheprovider
    if cache is not None and not os.environ.get("PSBMPC_TEST_NO_JAX_CACHE"):
        args.append(str(cache.mkdir("jax-compilation-cache-4dev")))
    proc = subprocess.run([sys.executable, "-c", script, *args], env=env, capture_output=True, text=True,
                          timeout=timeout, cwd=str(ROOT))
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-6000:]
    return proc


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


def star(rng: np.random.Generator, n: int, cx: float, cy: float, r_min: float, r_max: float) -> np.ndarray:
    """A star-shaped simple ring ``[n, 2]`` about (cx, cy): evenly spaced angles with jitter (every angular gap
    < pi, so the ring is star-shaped about its centre and simple), random radii in [r_min, r_max]."""
    ang = (np.arange(n) + rng.uniform(-0.3, 0.3, n)) * (2 * np.pi / n)
    rad = rng.uniform(r_min, r_max, n)
    return np.stack([cx + rad * np.cos(ang), cy + rad * np.sin(ang)], axis=-1)


def central_difference(f, x, h: float = 1e-6) -> np.ndarray:
    """Central-difference gradient of the scalar function ``f`` at ``x`` (any shape), float64."""
    x = np.asarray(x, float)
    g = np.zeros_like(x)
    for idx in np.ndindex(x.shape):
        e = np.zeros_like(x)
        e[idx] = h
        g[idx] = (float(f(x + e)) - float(f(x - e))) / (2 * h)
    return g


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


def pad_arrays(inputs: SolveInputs, *, O=None, S=None, W=None, Wo=None, P=None, V=None, B=None,
               junk: bool = True) -> SolveInputs:
    """Pad packed inputs to (possibly) larger capacities.

    With ``junk=True`` every padding slot -- the new ones and those ``pack`` already made -- is
    deliberately hostile, while staying within the documented contract (masks False, scenario
    probabilities 0 outside the real scenarios): masked obstacles sit on the own-ship with a tiny covariance,
    all their scenario slots "valid" by ``n_ps`` and non-zero weight/zeta; masked polygons are a big box
    around the own-ship; masked behaviours are straight ahead at full speed (the cheapest possible path
    cost); waypoint and vertex slots beyond the valid counts hold far-away garbage.  A correct evaluator
    ignores all of it."""
    own = {k: np.array(v) for k, v in inputs.own._asdict().items()}
    obs = {k: np.array(v) for k, v in inputs.obstacles._asdict().items()}
    poly = {k: np.array(v) for k, v in inputs.world.polygons._asdict().items()}
    beh = {k: np.array(v) for k, v in inputs.behaviours._asdict().items()}
    o0, s0 = obs["probs"].shape
    w0, wo0 = own["wx"].shape[1], obs["wx"].shape[1]
    p0, v0 = poly["vertices"].shape[:2]
    b0 = beh["offsets"].shape[0]
    O, S, W, Wo = O or o0, S or s0, W or w0, Wo or wo0
    P = p0 if P is None else P
    V, B = V or v0, B or b0
    assert O >= o0 and S >= s0 and W >= w0 and Wo >= wo0 and P >= p0 and V >= v0 and B >= b0

    def grow(arr, shape, fill):
        out = np.full(shape, fill, dtype=arr.dtype)
        out[tuple(slice(0, n) for n in arr.shape)] = arr
        return out

    g = 12345.0
    own_wx, own_wy = grow(own["wx"], (1, W), 0.0), grow(own["wy"], (1, W), 0.0)
    obs_state, obs_cov = grow(obs["state"], (O, 4), 0.0), grow(obs["cov"], (O, 4, 4), 0.0)
    obs_length = grow(obs["length"], (O,), 5.0)
    obs_wx, obs_wy = grow(obs["wx"], (O, Wo), 0.0), grow(obs["wy"], (O, Wo), 0.0)
    obs_n, obs_n_ps = grow(obs["n"], (O,), 2), grow(obs["n_ps"], (O,), 1)
    obs_probs = grow(obs["probs"], (O, S), 0.0)
    obs_weight, obs_zeta = grow(obs["weight"], (O,), 0.0), grow(obs["zeta"], (O,), 0.0)
    obs_mask = grow(obs["mask"], (O,), False)
    poly_vertices = grow(poly["vertices"], (P, V, 2), 0.0)
    poly_n, poly_mask = grow(poly["n"], (P,), 3), grow(poly["mask"], (P,), False)
    poly_next = grow(poly["next"], (P, V), 0)
    poly_next[p0:, :3] = [1, 2, 0]
    behaviours = grow(beh["offsets"], (B,) + beh["offsets"].shape[1:], 0.0)
    beh_mask = grow(beh["mask"], (B,), False)
    for i in range(o0, O):  # neutral padding like pack's (a valid 2-point route)
        obs_cov[i] = np.eye(4)
        obs_wx[i, 1] = 1.0
    for j in range(p0, P):
        poly_vertices[j, :3] = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]
    behaviours[b0:] = behaviours[0]

    if junk:
        ox, oy = own["state"][:2]
        own_wx[0, int(own["n"][0]):], own_wy[0, int(own["n"][0]):] = g, -g
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

    dtype = own["state"].dtype
    f = lambda x: jnp.asarray(x, dtype)
    i32 = lambda x: jnp.asarray(x, jnp.int32)
    return SolveInputs(
        own=OwnShipArrays(f(own["state"]), f(own_wx), f(own_wy), i32(own["n"]), f(own["U_d"]), f(own["length"])),
        obstacles=ObstacleArrays(f(obs_state), f(obs_cov), f(obs_length), f(obs_wx), f(obs_wy), i32(obs_n),
                                 i32(obs_n_ps), f(obs_probs), f(obs_weight), f(obs_zeta), jnp.asarray(obs_mask)),
        world=WorldArrays(ChartArrays(f(poly_vertices), i32(poly_next), i32(poly_n), jnp.asarray(poly_mask)),
                          inputs.world.grid),
        behaviours=BehaviourArrays(f(behaviours), jnp.asarray(beh_mask)),
    )


@pytest.fixture
def fixed_caps(monkeypatch):
    """Make ``Planner.plan`` pack every situation to the fixed capacities :data:`CAPS` (hostile padding),
    so that all random situations share one compiled evaluator per config."""
    import psbmpc_jax.planner as planner_mod

    original = planner_mod.pack

    def pack_fixed(situation, behaviours, config, **kw):
        return pad_arrays(original(situation, behaviours, config, **kw), **CAPS)

    monkeypatch.setattr(planner_mod, "pack", pack_fixed)
    return CAPS


from tuned_scenarios import sbmpc_tuned_scenarios  # noqa: E402,F401  (tests import it from conftest)


def run_cli(argv) -> tuple[int, str, str]:
    """``psbmpc-jax ARGV`` in this process: (exit status, stdout, stderr); a ``SystemExit`` gives its code."""
    import contextlib
    import io

    from psbmpc_jax.apps.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = main(argv)
        except SystemExit as exc:
            rc = exc.code
    return rc, out.getvalue(), err.getvalue()
