"""Single against multiple shooting for the two-level method's upper level (Mahipala & Johansen 2023 print multiple
shooting, eqs. 6 and 8; the library solves single shooting, docs/algorithm.md §15): the same cost (7), box (9),
circles (10) and corridor (11) on the same NLP core, from the same start.

Usage:  python benchmarks/bench_shooting.py [--repeats 20] [--out benchmarks/results]

Multiple shooting: the unknowns are w = (u_0 … u_{N_p−1}, x_1 … x_{N_p}) with the defects
x_{k+1} − RK4(x_k, u_k) = 0 as equality constraints of the augmented Lagrangian, the states' box free.  Cases:
the fjord reconstruction of the two-level paper (N_p 30) and the Smooth-SBMPC scene (N_p 20) from their starts (cold)
and the
fjord case after 20 closed-loop steps.  Records the cost of the result (evaluated by rolling the commands
out, so both are judged on the same trajectory), the constraint violation, iterations and the solve time
(interleaved rounds).
"""

from __future__ import annotations

import os
import sys

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import interleaved_parser, run_interleaved  # noqa: E402
from bench_path_mpc import build  # noqa: E402


def multiple_shooting(settings):
    from psbmpc_jax.two_level import path_mpc as pm

    N = settings.N_p

    def split(w):
        return w[:N], w[N:]

    def states(w, d):
        u, x = split(w)
        return jnp.concatenate([d.x0[None], x[:, :4]], axis=0), u[:, :2]

    def cost(w, d):
        xs, u = states(w, d)
        ref = jnp.concatenate([d.legs.wp[d.j + 1], d.legs.psi[d.j][None], d.U_ref[None]])
        e = xs[1:] - ref
        e = e.at[:, 2].set(pm.wrap(e[:, 2]))
        Q, M = jnp.asarray(settings.Q, w.dtype), jnp.asarray(settings.M, w.dtype)
        du = jnp.diff(jnp.concatenate([d.u_prev[None], u], axis=0), axis=0)
        du = du.at[:, 0].set(pm.wrap(du[:, 0]))
        return jnp.sum(e * e * Q) + jnp.sum(du * du * M)

    def eq(w, d):
        xs, u = states(w, d)
        h = settings.dt / settings.rk4_substeps

        def step(x, uk):
            for _ in range(settings.rk4_substeps):
                x = pm.rk4_step(x, uk, h, settings.T_chi, settings.T_U)
            return x
        nxt = jax.vmap(step)(xs[:-1], u)
        r = nxt - xs[1:]
        return r.at[:, 2].set(pm.wrap(r[:, 2])).ravel()

    def ineq(w, d):
        xs, _ = states(w, d)
        p = xs[1:, :2]
        parts = [pm.corridor_residuals(p, d.legs, d.j).ravel()]
        if d.circles.radius.shape[0]:
            from psbmpc_jax.two_level.static_obstacles import StaticCircles, circle_residuals
            parts.append(circle_residuals(p, StaticCircles(d.circles.centre, d.circles.radius), settings.r_os).ravel())
        return jnp.concatenate(parts)

    return cost, eq, ineq


def cases():
    import jax.numpy as jnp

    from psbmpc_jax.two_level.path_mpc import PathMpcData, rk4_step, solve_path_mpc

    out = []
    for case, name, steps in (("fjord_start", "mahipala2023_7_combined", 0), ("fjord_t20", "mahipala2023_7_combined", 20),
                              ("smooth000_start", "smooth_000_reconstruction", 0)):
        sc, planner, x0, _ = build(name)
        s = planner.settings.path
        dtype = jnp.float64 if jax.config.jax_enable_x64 else jnp.float32
        legs = jax.tree.map(lambda a: jnp.asarray(a, dtype), planner.legs)
        circ = jax.tree.map(lambda a: jnp.asarray(a, dtype), planner.circle_arrays)
        x, u_prev, prev = np.asarray(x0, float), np.asarray(x0[2:], float), None
        for _ in range(steps):                       # a short closed loop of the library's solver
            d = PathMpcData(jnp.asarray(x, dtype), jnp.asarray(u_prev, dtype), jnp.asarray(0, jnp.int32),
                            jnp.asarray(planner.U_ref, dtype), legs, circ)
            r = jax.device_get(solve_path_mpc(d, s, previous=prev))
            prev, u_prev = np.asarray(r.u), np.asarray(r.u[0])
            x = np.asarray(rk4_step(jnp.asarray(x, dtype), jnp.asarray(u_prev, dtype), s.dt, s.T_chi, s.T_U))
        d = PathMpcData(jnp.asarray(x, dtype), jnp.asarray(u_prev, dtype), jnp.asarray(0, jnp.int32),
                        jnp.asarray(planner.U_ref, dtype), legs, circ)
        out.append((case, name, s, d))
    return out


def main(argv=None) -> int:
    from psbmpc_jax.nlp import solve_docp
    from psbmpc_jax.two_level import path_mpc as pm

    args = interleaved_parser(__doc__.splitlines()[0], 20).parse_args(argv)
    slots = []
    for case, name, s, d in cases():
        u0 = pm.warm_start(d, s)
        lo, hi = pm.command_box(d, s, u0.dtype)
        cost, eq, ineq = multiple_shooting(s)
        x_init = pm.rollout(d.x0, u0, s)[1:]                 # the same start: the states of the start's rollout
        # decision: rows 0..N-1 are u (2 columns used), rows N..2N-1 are x (4 columns): pad u to 4 columns
        W0 = jnp.concatenate([jnp.pad(u0, ((0, 0), (0, 2))), x_init], axis=0)
        inf = jnp.asarray(jnp.inf, u0.dtype)
        Wlo = jnp.concatenate([jnp.pad(lo, ((0, 0), (0, 2))), jnp.full_like(x_init, -inf)], axis=0)
        Whi = jnp.concatenate([jnp.pad(hi, ((0, 0), (0, 2))), jnp.full_like(x_init, inf)], axis=0)

        def run_single(d=d, s=s):
            return pm.solve_path_mpc(d, s)

        def run_multiple(d=d, W0=W0, Wlo=Wlo, Whi=Whi, cost=cost, eq=eq, ineq=ineq):
            return solve_docp(cost, W0, lower=Wlo, upper=Whi, eq=eq, ineq=ineq, settings=pm.DEFAULT_SOLVER, args=d)

        r1 = jax.device_get(run_single())
        r2 = jax.device_get(run_multiple())
        u_ms = np.asarray(r2.u)[: s.N_p, :2]
        f_ms_rollout = float(pm.path_mpc_cost(jnp.asarray(u_ms, u0.dtype), d, s))
        viol_ms_rollout = float(np.max(np.maximum(np.asarray(pm.path_mpc_ineq(jnp.asarray(u_ms, u0.dtype), d, s)), 0)))
        common = {"case": case, "scenario": name, "N_p": s.N_p}
        slots.append({"point": dict(common, what="single_shooting", n_unknowns=2 * s.N_p, cost=float(r1.cost),
                                    violation=float(r1.violation), status=int(r1.status), outer=int(r1.outer),
                                    inner=int(r1.inner)), "call": run_single})
        slots.append({"point": dict(common, what="multiple_shooting", n_unknowns=6 * s.N_p, cost=float(r2.f),
                                    cost_of_rollout=f_ms_rollout, violation_of_rollout=viol_ms_rollout,
                                    violation=float(r2.max_violation), status=int(r2.status),
                                    outer=int(r2.outer_iterations), inner=int(r2.inner_iterations)),
                      "call": run_multiple})
    run_interleaved(slots, args, "shooting", "two-level upper level: single vs multiple shooting", hide=("scenario",),
                    x64=bool(jax.config.jax_enable_x64))
    return 0


if __name__ == "__main__":
    sys.exit(main())
