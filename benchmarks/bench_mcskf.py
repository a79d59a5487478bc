"""MCS + KF collision risk (Tengesdal et al. 2020, psbmpc_jax.costs.mcskf) against the library's quadrature
estimator (psbmpc_jax.costs.collision.pc_quadrature) on the same (step, obstacle, behaviour) points.

For every obstacle count O (default 1, 5, 13) and B = 39 behaviours, T = 401 steps (T = 200 s, dt = 0.5 s):

* ``mcskf``: the MC measurements y of every point (4-D samples x̄ + L z, ``"mean_cpa"`` event, N_MC samples per
  step from a shared table Z [T, N_MC, 4]) and the KF along the horizon (ℙ̂ = W·y): the estimator only;
* ``term``: the whole eq. (20) term (:class:`~psbmpc_jax.costs.mcskf.Psbmpc2020Term` on a Context: the table
  drawn from its key, MCS + KF, C, the discount, Johansen's μ, the sums and the max over obstacles);
* ``quadrature``: ``pc_quadrature`` (n_quad = 32, span 6σ: PlannerConfig's defaults) of every point with the
  constant positional covariance, no σ-shortcut (the evaluator's compact layout would skip far points; here
  every point is computed, as the MC estimator computes every point);
* ``mc2d``: the library's positional Monte Carlo ``pc_mc`` with the same N_MC, for scale.

Each slot is jitted, compiled first (compile time recorded), warmed up, then timed round-robin (one repeat of
every slot per round, so that a slow spell of this shared machine lands on every slot alike);
``block_until_ready``; median / quartiles.  Per-pair time = median / (B·O) (one pair = one (behaviour,
obstacle) over all T steps).  Geometry: random own-ship courses at 5 m/s, obstacles within 1 km at 2-9 m/s,
covariance diag(25, 25, 4, 4) plus random correlation (it does not change the MC cost; the quadrature cost is
data-independent too).

Usage: python benchmarks/bench_mcskf.py [--repeats 20] [--obstacles 1,5,13] [--n-mc 100] [--dtype float32]
Writes benchmarks/results/mcskf_<platform>_<UTC stamp>.json (environment_meta: device, versions, commit).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time

import jax

jax.config.update("jax_enable_x64", True)  # only for --dtype float64; float32 runs are unaffected

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

from psbmpc_jax.costs import mcskf as mk  # noqa: E402
from psbmpc_jax.costs.base import Context  # noqa: E402
from psbmpc_jax.costs.collision import pc_mc, pc_quadrature  # noqa: E402
from psbmpc_jax.ownship import Trajectory  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import environment_meta, stats, write_results  # noqa: E402


def geometry(n_b: int, n_o: int, n_t: int, dt: float, dtype, seed: int = 0):
    """Own-ship rows [T, B] and obstacles [T, O] on straight lines, covariances [O, 4, 4]."""
    rng = np.random.default_rng(seed)
    t = np.arange(n_t) * dt
    chi_o = np.radians(np.linspace(-90, 90, n_b))
    own = np.stack([5 * t[:, None] * np.cos(chi_o), 5 * t[:, None] * np.sin(chi_o),
                    np.broadcast_to(chi_o, (n_t, n_b)), np.full((n_t, n_b), 5.0)], -1)
    p0 = np.stack([rng.uniform(100, 1000, n_o), rng.uniform(-400, 400, n_o)], -1)
    chi_i, U_i = rng.uniform(-math.pi, math.pi, n_o), rng.uniform(2, 9, n_o)
    obs = np.stack([p0[:, 0] + U_i * np.cos(chi_i) * t[:, None], p0[:, 1] + U_i * np.sin(chi_i) * t[:, None],
                    np.broadcast_to(chi_i, (n_t, n_o)), np.broadcast_to(U_i, (n_t, n_o))], -1)
    cov = np.empty((n_o, 4, 4))
    for o in range(n_o):
        A = rng.normal(0, 0.5, (4, 4))
        cov[o] = np.diag([25.0, 25.0, 4.0, 4.0]) + A @ A.T
    c = lambda a: jnp.asarray(a, dtype)                                         # noqa: E731
    return c(t), c(own), c(obs), c(cov)


def traj(a):
    return Trajectory(a[..., 0], a[..., 1], a[..., 2], a[..., 3], jnp.cos(a[..., 2]), jnp.sin(a[..., 2]))


def relative(own, obs):
    vo = own[..., 3] * jnp.cos(own[..., 2]), own[..., 3] * jnp.sin(own[..., 2])
    vi = obs[..., 3] * jnp.cos(obs[..., 2]), obs[..., 3] * jnp.sin(obs[..., 2])
    return (obs[:, :, None, 0] - own[:, None, :, 0], obs[:, :, None, 1] - own[:, None, :, 1],
            vi[0][:, :, None] - vo[0][:, None, :], vi[1][:, :, None] - vo[1][:, None, :])   # [T, O, B]


def slots(n_b, n_o, n_t, dt, n_mc, dtype):
    """name -> (jitted function, args)."""
    t, own, obs, cov = geometry(n_b, n_o, n_t, dt, dtype)
    z = mk.normal_table(jax.random.key(1), n_t, n_mc, dtype)
    z2 = jax.random.normal(jax.random.key(2), (n_mc, 2), dtype)

    @jax.jit
    def f_mcskf(own, obs, cov, z):
        dpx, dpy, dvx, dvy = relative(own, obs)
        L = mk.cholesky4(cov)
        e = jnp.einsum("knj,pij->kpni", z, L)[:, :, None]                    # [T, O, 1, N, 4]
        y, tc = mk._inside_fraction(dpx, dpy, dvx, dvy, e, 40.0, 0.25, "mean_cpa")
        K = mk.kf_gains(n_t, 5e-5, 1e-3, 0.3, dtype)
        return mk.kf_apply(y, K), tc

    @jax.jit
    def f_quad(own, obs, cov):
        dpx, dpy, _, _ = relative(own, obs)
        s = lambda i, j: cov[None, :, None, i, j]                              # noqa: E731
        return pc_quadrature(dpx, dpy, s(0, 0), s(0, 1), s(1, 1), jnp.asarray(40.0, dtype), 32, 6.0)

    @jax.jit
    def f_mc2d(own, obs, cov, z2):
        dpx, dpy, _, _ = relative(own, obs)
        s = lambda i, j: jnp.broadcast_to(cov[None, :, None, i, j], dpx.shape)  # noqa: E731
        return pc_mc(dpx, dpy, s(0, 0), s(0, 1), s(1, 1), jnp.asarray(40.0, dtype), z2)

    term = mk.Psbmpc2020Term(n_mc=n_mc)
    valid = jnp.ones((n_o, 1), bool)
    ctx = Context(t=t, offsets=None, last_offsets=None, own=traj(own), obstacles=traj(obs[:, :, None]),
                  obs_cov=jnp.broadcast_to(cov[:, None], (n_o, n_t, 4, 4)), cov_stats=None, scen_valid=valid,
                  radius=None, zeta_k=None, scen_weight=valid.astype(dtype), world=None, dense=False)
    f_term = jax.jit(lambda term, ctx: term(ctx).value)
    return {"mcskf": (f_mcskf, (own, obs, cov, z)), "term": (f_term, (term, ctx)),
            "quadrature": (f_quad, (own, obs, cov)), "mc2d": (f_mc2d, (own, obs, cov, z2))}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--warmup", type=int, default=2)
    ap.add_argument("--behaviours", type=int, default=39)
    ap.add_argument("--obstacles", default="1,5,13")
    ap.add_argument("--T", type=float, default=200.0)
    ap.add_argument("--dt", type=float, default=0.5)
    ap.add_argument("--n-mc", type=int, default=100)
    ap.add_argument("--dtype", default="float32", choices=("float32", "float64"))
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "results"))
    a = ap.parse_args(argv)
    dtype = jnp.dtype(a.dtype)
    n_t = int(round(a.T / a.dt)) + 1
    points = []
    for n_o in (int(v) for v in a.obstacles.split(",")):
        fns = slots(a.behaviours, n_o, n_t, a.dt, a.n_mc, dtype)
        compile_s = {}
        for name, (f, args) in fns.items():
            t0 = time.perf_counter()
            jax.block_until_ready(f(*args))
            compile_s[name] = time.perf_counter() - t0
            for _ in range(a.warmup):
                jax.block_until_ready(f(*args))
        times = {name: [] for name in fns}
        for _ in range(a.repeats):
            for name, (f, args) in fns.items():
                t0 = time.perf_counter()
                jax.block_until_ready(f(*args))
                times[name].append(time.perf_counter() - t0)
        n_pairs = a.behaviours * n_o
        for name in fns:
            st = stats(times[name])
            points.append({"slot": name, "n_behaviours": a.behaviours, "n_obstacles": n_o, "n_steps_plus_1": n_t,
                           "n_pairs": n_pairs, "n_points": n_pairs * n_t, "n_mc": a.n_mc, "dtype": a.dtype,
                           "first_call_s": round(compile_s[name], 3), **st,
                           "per_pair_us": round(st["median_ms"] * 1e3 / n_pairs, 3),
                           "per_point_ns": round(st["median_ms"] * 1e6 / (n_pairs * n_t), 3)})
            print(f"O={n_o:3d} {name:10s} median {st['median_ms']:9.3f} ms  per pair {points[-1]['per_pair_us']:9.3f} "
                  f"us  first call {compile_s[name]:.2f} s")
        q = statistics_median(points, n_o, "quadrature")
        for name in ("mcskf", "term", "mc2d"):
            print(f"O={n_o:3d} {name} / quadrature = {statistics_median(points, n_o, name) / q:.2f}")
    meta = environment_meta("mcskf", repeats=a.repeats, warmup=a.warmup, schedule="round-robin",
                            T=a.T, dt=a.dt, d_safe=40.0, quad=dict(n_quad=32, span=6.0))
    return write_results(a.out, "mcskf", meta, points)


def statistics_median(points, n_o, slot):
    return next(p["median_ms"] for p in points if p["n_obstacles"] == n_o and p["slot"] == slot)


if __name__ == "__main__":
    main()
