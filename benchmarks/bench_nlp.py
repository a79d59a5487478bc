"""Micro-benchmark of the generic constrained solver :mod:`psbmpc_jax.nlp` (issue 12 item 4), float64, this device.

Two parts, both written to ``benchmarks/results/nlp_<platform>_<UTC timestamp>.json``:

* ``docp``: a problem of the DOCP's size and structure (eq. 27 of Mahipala & Johansen 2024, single shooting): controls
  u = (χ_m, U_m) ``[N, 2]`` for N in {40, 120}, box −90°..90° × 0.1..1, a first-order course/speed +
  kinematic rollout (``lax.scan``), a smooth NONCONVEX cost (Gaussian bumps of O moving obstacles, O chosen
  so that one evaluation costs ~1e4 flops, + the Γ-like control and smoothness penalties), 4 terminal
  equalities (the full state at the horizon = the warm start's, which is feasible by construction, as Ψ is)
  and 2N cross-track corridor inequalities (|e_k| <= Δd = 20 m, narrowed to 6 m on one side over a stretch).
  Timed: compile, one solve from the warm start, and 16 starts (warm start + 15 smooth perturbations) with
  :func:`solve_multistart`, ``batch="vmap"`` and ``batch="map"``; for each inner method (``lbfgs`` with the sin
  box map, ``adam``).
* ``suite``: the problems of ``tests/test_nlp.py`` (unconstrained/box/equality quadratic, corridor, Rosenbrock)
  solved with ``lbfgs``+``sin``, ``lbfgs``+``tanh`` and ``adam``: error against the known solution, status,
  iterations and steady-state time -- the measurement behind the default inner method (docs/solver.md).

Timing protocol: ``solve_docp.jitted.lower(...).compile()`` timed separately, one warm-up call, then the median of
``--repeats`` calls with ``block_until_ready``; the load average is recorded (the development VM is shared).

Usage: python benchmarks/bench_nlp.py [--repeats 20] [--sizes 40,120] [--out benchmarks/results] [--no-suite]
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import environment_meta, stats, write_results  # noqa: E402

from psbmpc_jax.nlp import STATUS_NAMES, SolverSettings, solve_docp, solve_multistart  # noqa: E402
from psbmpc_jax.nlp.solver import _prepare  # noqa: E402

DT, U_D, T_CHI, T_U, DELTA_D = 1.0, 4.0, 4.0, 8.0, 20.0


# ------------------------------------------------------------------------------------------ DOCP-sized problem
def rollout(u, a):
    """States [N + 1, 4] (north, east, course, speed) of the controls u [N, 2] = (χ_m, U_m)."""
    def step(x, uk):
        n, e, chi, U = x
        chi_c = a["chi_d"] + uk[0]
        U_c = U_D * uk[1]
        nxt = jnp.stack([n + DT * U * jnp.cos(chi), e + DT * U * jnp.sin(chi),
                         chi + DT / T_CHI * jnp.sin(chi_c - chi), U + DT / T_U * (U_c - U)])
        return nxt, nxt
    _, xs = jax.lax.scan(step, a["x0"], u)
    return jnp.concatenate([a["x0"][None], xs], axis=0)


def docp_cost(u, a):
    x = rollout(u, a)
    p = x[1:, :2]                                                      # [N, 2]
    t = DT * jnp.arange(1, u.shape[0] + 1)
    obs = a["o_p"][None] + t[:, None, None] * a["o_v"][None]             # [N, O, 2]
    d2 = jnp.sum((p[:, None, :] - obs) ** 2, axis=-1)
    collision = jnp.sum(a["o_w"] * jnp.exp(-d2 / (2.0 * a["sigma"] ** 2)))
    du = jnp.diff(jnp.concatenate([a["u_last"][None], u], axis=0), axis=0)
    gamma = jnp.sum(a["k"][0] * u[:, 0] ** 2 + a["k"][1] * (1.0 - u[:, 1]) ** 2
                    + a["k"][2] * du[:, 0] ** 2 + a["k"][3] * du[:, 1] ** 2)
    return collision + gamma


def docp_terminal(u, a):
    xT = rollout(u, a)[-1]
    return (xT - a["x_T"]) * a["eq_scale"]


def docp_corridor(u, a):
    p = rollout(u, a)[1:, :2]
    e = jnp.sum((p - a["P"]) * a["n_hat"], axis=-1)
    return jnp.concatenate([e - a["e_max"], a["e_min"] - e])


def docp_problem(N: int, seed: int = 0):
    """Args pytree, box and warm start of a DOCP-sized problem with N steps."""
    rng = np.random.default_rng(seed)
    n_obs = max(1, round(1e4 / (16 * N)))                           # ~16 flops per (step, obstacle) pair
    chi_d = 0.2
    x0 = jnp.asarray([0.0, 0.0, chi_d, U_D])
    k = np.arange(N)
    u_warm = np.stack([0.25 * np.sin(2 * np.pi * k / N), np.full(N, 0.9)], axis=1)   # the init stage's sequence
    base = {"chi_d": jnp.asarray(chi_d), "x0": x0}
    xs = np.asarray(rollout(jnp.asarray(u_warm), base))
    P = xs[1:, :2]
    seg = np.diff(xs[:, :2], axis=0)
    t_hat = seg / np.maximum(np.linalg.norm(seg, axis=1, keepdims=True), 1e-9)
    n_hat = np.stack([-t_hat[:, 1], t_hat[:, 0]], axis=1)
    e_max = np.full(N, DELTA_D)
    e_max[N // 3: N // 2] = 6.0                                          # "land" narrows one side
    # obstacles: moving, each crossing the warm path near a random time
    t_meet = rng.uniform(0.2, 0.9, n_obs) * N * DT
    idx = np.clip((t_meet / DT).astype(int) - 1, 0, N - 1)
    o_v = rng.normal(0.0, 2.0, (n_obs, 2))
    o_p = P[idx] + rng.normal(0.0, 4.0, (n_obs, 2)) - t_meet[:, None] * o_v
    args = dict(base, o_p=jnp.asarray(o_p), o_v=jnp.asarray(o_v), o_w=jnp.asarray(rng.uniform(5.0, 20.0, n_obs)),
                sigma=jnp.asarray(12.0), k=jnp.asarray([2.0, 2.0, 20.0, 20.0]), u_last=jnp.asarray(u_warm[0]),
                x_T=jnp.asarray(xs[-1]), eq_scale=jnp.asarray([0.1, 0.1, 10.0, 1.0]), P=jnp.asarray(P),
                n_hat=jnp.asarray(n_hat), e_max=jnp.asarray(e_max), e_min=jnp.asarray(np.full(N, -DELTA_D)))
    lower = np.tile([-math.pi / 2, 0.1], (N, 1))
    upper = np.tile([math.pi / 2, 1.0], (N, 1))
    starts = [u_warm]
    for _ in range(15):                                                 # smooth random perturbations
        c = rng.normal(0.0, 1.0, (4, 2))
        s = np.linspace(0.0, 1.0, N)[:, None]
        pert = c[0] * np.sin(np.pi * s) + c[1] * np.sin(2 * np.pi * s) + c[2] * np.sin(3 * np.pi * s)
        starts.append(np.clip(u_warm + pert * [0.3, 0.1], lower + 1e-3, upper - 1e-3))
    return args, lower, upper, jnp.asarray(np.stack(starts)), n_obs


def time_call(fn, repeats):
    jax.block_until_ready(fn())
    times = []
    out = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = jax.block_until_ready(fn())
        times.append(time.perf_counter() - t0)
    return times, out


def summary(r, i=None):
    g = (lambda x: np.asarray(x)) if i is None else (lambda x: np.asarray(x)[i])
    st = int(g(r.status))
    return {"status": st, "status_name": STATUS_NAMES[st], "f": float(g(r.f)),
            "max_violation": float(g(r.max_violation)), "outer": int(g(r.outer_iterations)),
            "inner": int(g(r.inner_iterations)), "stalled": bool(g(r.stalled))}


def bench_docp(N, method, repeats, batches=("map", "vmap")):
    args, lower, upper, starts, n_obs = docp_problem(N)
    settings = SolverSettings(method=method, learning_rate=0.01, max_inner=50)
    fn_kw = dict(eq=docp_terminal, ineq=docp_corridor)
    u0, lo, hi, a = _prepare(starts[0], lower, upper, args)
    cost_flops = jax.jit(docp_cost).lower(u0, a).compile().cost_analysis()
    cost_flops = cost_flops[0] if isinstance(cost_flops, list) else cost_flops
    point = {"N": N, "method": method, "n_obstacles": n_obs,
             "f_flops_xla": float(cost_flops.get("flops", float("nan"))) if cost_flops else None,
             "n_eq": 4, "n_ineq": 2 * N}
    t0 = time.perf_counter()
    single = solve_docp.jitted.lower(docp_cost, u0, lo, hi, docp_terminal, docp_corridor, settings, a).compile()
    point["compile_single_s"] = round(time.perf_counter() - t0, 3)
    times, res = time_call(lambda: single(u0, lo, hi, settings, a), repeats)
    point["single"] = stats(times)
    point["single_result"] = summary(res)
    point["warm_f"] = float(docp_cost(u0, a))
    us, lo_, hi_, a_ = _prepare(starts, lower, upper, args, batched=True)
    for batch in batches:
        t0 = time.perf_counter()
        multi = solve_multistart.jitted.lower(docp_cost, us, lo_, hi_, docp_terminal, docp_corridor, settings, a_,
                                              batch=batch).compile()
        point[f"compile_multistart16_{batch}_s"] = round(time.perf_counter() - t0, 3)
        times, m = time_call(lambda: multi(us, lo_, hi_, settings, a_), 2 if batch == "vmap" else max(2, repeats // 4))
        point[f"multistart16_{batch}"] = stats(times)
        point[f"multistart16_{batch}_best"] = int(m.best)
        point[f"multistart16_{batch}_results"] = [summary(m.results, i) for i in range(starts.shape[0])]
    # the same through the public wrapper (conversion overhead included), for reference
    times, _ = time_call(lambda: solve_docp(docp_cost, starts[0], lower=lower, upper=upper, settings=settings,
                                            args=args, **fn_kw), max(3, repeats // 4))
    point["single_via_wrapper"] = stats(times)
    return point


# ------------------------------------------------------------------------------------------ test-problem suite
NS = 10


def quad(u, a):
    d = u.ravel() - a["c"]
    return 0.5 * d @ (a["Q"] @ d)


def lin_eq(u, a):
    return a["A"] @ u.ravel() - a["b"]


def corridor(u, a):
    e = jnp.sum((u - a["P"]) * a["n"], axis=-1)
    return jnp.concatenate([e - a["emax"], a["emin"] - e])


def rosen(u, a):
    return jnp.sum(100.0 * (u[1:] - u[:-1] ** 2) ** 2 + (1.0 - u[:-1]) ** 2)


def suite_problems():
    rng = np.random.default_rng(0)
    M = rng.normal(size=(2 * NS, 2 * NS))
    Q = M @ M.T / (2 * NS) + np.eye(2 * NS)
    c = rng.normal(0.0, 2.0, 2 * NS)
    inf = np.full((NS, 2), np.inf)
    out = {"unconstrained": (quad, None, None, np.zeros((NS, 2)), -inf, inf, {"Q": Q, "c": c}, c.reshape(NS, 2))}
    d = rng.uniform(0.5, 3.0, 2 * NS)
    lo, hi = np.full((NS, 2), -1.0), np.full((NS, 2), 1.5)
    out["box"] = (quad, None, None, np.full((NS, 2), 0.5), lo, hi, {"Q": np.diag(d), "c": c},
                  np.clip(c.reshape(NS, 2), lo, hi))
    A, b = rng.normal(size=(4, 2 * NS)), rng.normal(size=4)
    K = np.block([[Q, A.T], [A, np.zeros((4, 4))]])
    u_star = np.linalg.solve(K, np.concatenate([Q @ c, b]))[:2 * NS].reshape(NS, 2)
    out["equality"] = (quad, lin_eq, None, np.zeros((NS, 2)), -inf, inf, {"Q": Q, "c": c, "A": A, "b": b}, u_star)
    t_hat = np.array([math.cos(0.3), math.sin(0.3)])
    n_hat = np.array([-t_hat[1], t_hat[0]])
    P = 5.0 * np.arange(1, NS + 1)[:, None] * t_hat
    emax, emin = 2.0 + 0.1 * np.arange(NS), -1.5 - 0.05 * np.arange(NS)
    e_ref = np.array([4.0, -3.0, 1.0, 6.0, -0.5, -5.0, 2.5, 0.0, 3.0, -2.0])
    ref = P + e_ref[:, None] * n_hat + np.linspace(-1.0, 1.0, NS)[:, None] * t_hat
    u_c = ref + (np.clip(e_ref, emin, emax) - e_ref)[:, None] * n_hat
    out["corridor"] = (quad, None, corridor, P, np.full((NS, 2), -200.0), np.full((NS, 2), 200.0),
                       {"Q": np.eye(2 * NS), "c": ref.ravel(), "P": P, "n": np.tile(n_hat, (NS, 1)), "emin": emin,
                        "emax": emax}, u_c)
    out["rosenbrock"] = (rosen, None, None, np.array([-1.2, 1.0]), np.full(2, -np.inf), np.full(2, np.inf), None,
                         np.ones(2))
    out["rosenbrock_box"] = (rosen, None, None, np.array([-1.2, 1.0]), np.full(2, -2.0), np.array([2.0, 0.8]),
                             None, np.array([0.894755899, 0.8]))
    return out


def bench_suite(repeats):
    variants = {"lbfgs_sin": SolverSettings(method="lbfgs", box_map="sin"),
                "lbfgs_tanh": SolverSettings(method="lbfgs", box_map="tanh"),
                "adam": SolverSettings(method="adam", learning_rate=0.05)}
    points = []
    for name, (f, eq, ineq, u0, lo, hi, args, u_star) in suite_problems().items():
        for vname, s in variants.items():
            u0_, lo_, hi_, a_ = _prepare(u0, lo, hi, args)
            t0 = time.perf_counter()
            comp = solve_docp.jitted.lower(f, u0_, lo_, hi_, eq, ineq, s, a_).compile()
            compile_s = time.perf_counter() - t0
            times, r = time_call(lambda: comp(u0_, lo_, hi_, s, a_), repeats)
            points.append({"problem": name, "variant": vname, **summary(r),
                           "max_abs_error": float(np.max(np.abs(np.asarray(r.u) - u_star))),
                           "compile_s": round(compile_s, 3), "time": stats(times)})
            print(f"  {name:15s} {vname:10s} err {points[-1]['max_abs_error']:.2e} status {points[-1]['status']} "
                  f"inner {points[-1]['inner']:4d} median {points[-1]['time']['median_ms']:.2f} ms", flush=True)
    return points


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--sizes", default="40,120")
    ap.add_argument("--methods", default="lbfgs,adam")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "results"))
    ap.add_argument("--batches", default="map,vmap", help="multistart batch modes to time")
    ap.add_argument("--no-suite", action="store_true")
    ns = ap.parse_args(argv)
    batches = tuple(ns.batches.split(","))
    load0 = os.getloadavg()
    points = []
    for N in [int(x) for x in ns.sizes.split(",")]:
        for method in ns.methods.split(","):
            p = bench_docp(N, method, ns.repeats, batches)
            points.append({"part": "docp", **p})
            r = p["single_result"]
            print(f"docp N={N:3d} {method:5s}: compile {p['compile_single_s']:.1f} s, single median "
                  f"{p['single']['median_ms']:.1f} ms ({r['status_name']}, f {r['f']:.4g} vs warm {p['warm_f']:.4g}, "
                  f"viol {r['max_violation']:.1e}, {r['outer']} outer / {r['inner']} inner)", flush=True)
            for b in batches:
                best = p[f"multistart16_{b}_best"]
                print(f"    16 starts ({b}): median {p[f'multistart16_{b}']['median_ms']:.1f} ms (compile "
                      f"{p[f'compile_multistart16_{b}_s']:.1f} s), best start {best} f "
                      f"{p[f'multistart16_{b}_results'][best]['f']:.4g}", flush=True)
    if not ns.no_suite:
        print("suite (test problems):")
        points += [{"part": "suite", **p} for p in bench_suite(ns.repeats)]
    meta = environment_meta("nlp", dtype="float64", repeats=ns.repeats, loadavg_before=list(load0),
                            loadavg_after=list(os.getloadavg()))
    write_results(ns.out, "nlp", meta, points)


if __name__ == "__main__":
    main()
