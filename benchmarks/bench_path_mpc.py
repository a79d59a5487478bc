"""Solve time of the two-level method's upper level (the path-following NMPC, psbmpc_jax/two_level/path_mpc.py)
and of one whole two-level update, on the default device.

Usage:  python benchmarks/bench_path_mpc.py [--repeats 30] [--out benchmarks/results]

Cases (interleaved rounds, every slot timed once per round; float64 as the scenarios run it under x64,
float32 otherwise):
* ``fjord``: the reconstruction of Mahipala & Johansen (2023) on the Trondheim chart (``mahipala2023_7_combined``: N_p
  30, dt 1 s, the river's corridors, two static circles), from the own-ship's start; cold start (the applied command
  held) and warm start (the previous plan shifted, as in the closed loop);
* ``smooth000``: the reconstructed Smooth-SBMPC scene (Mahipala & Johansen 2024) (``smooth_000_reconstruction``: N_p
  20);
* ``update``: one whole ``TwoLevelPlanner.plan`` (upper level + target prediction + 39-behaviour SB-MPC) of
  each scenario at its start, targets included.
"""

from __future__ import annotations

import os
import sys
import warnings

import jax
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import interleaved_parser, run_interleaved  # noqa: E402


def build(name):
    from psbmpc_jax.scenario import load_scenario
    from psbmpc_jax.methods.two_level import TwoLevelController

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sc = load_scenario(name, method="two_level")
    planner = TwoLevelController(sc).planner
    own = sc.own_ship
    x0 = np.array([*own.position, own.course, own.speed])
    targets = np.array([[*t.position, t.course, t.speed] for t in sc.targets]).reshape(-1, 4)
    return sc, planner, x0, targets


def slots_for(case, name):
    import jax.numpy as jnp

    from psbmpc_jax.two_level.path_mpc import PathMpcData, solve_path_mpc

    sc, planner, x0, targets = build(name)
    s = planner.settings
    dtype = jnp.float64 if planner.config.dtype == "float64" or jax.config.jax_enable_x64 else jnp.float32
    data = PathMpcData(jnp.asarray(x0, dtype), jnp.asarray(x0[2:], dtype), jnp.asarray(0, jnp.int32),
                       jnp.asarray(planner.U_ref, dtype), jax.tree.map(lambda a: jnp.asarray(a, dtype), planner.legs),
                       jax.tree.map(lambda a: jnp.asarray(a, dtype), planner.circle_arrays))
    first = jax.device_get(solve_path_mpc(data, s.path))
    prev = np.asarray(first.u)
    out = []
    for label, previous in (("cold", None), ("warm", prev)):
        def call(previous=previous):
            return solve_path_mpc(data, s.path, previous=previous)
        r = jax.device_get(call())
        out.append({"point": {"case": case, "what": f"path_mpc_{label}", "scenario": name, "N_p": s.path.N_p,
                              "dt": s.path.dt, "n_circles": int(planner.circles.n_circles),
                              "inner_iterations": int(r.inner), "outer_iterations": int(r.outer),
                              "status": int(r.status), "violation": float(r.violation)},
                    "call": call})
    state = {"s": None}

    def update():
        plan, _ = planner.plan(x0, targets, state["s"])
        return plan.chi_c
    update()
    out.append({"point": {"case": case, "what": "two_level_update", "scenario": name, "N_p": s.path.N_p,
                          "n_targets": int(len(targets)), "sbmpc_T": planner.config.T, "sbmpc_dt": planner.config.dt},
                "call": update})
    return out


def main(argv=None) -> int:
    args = interleaved_parser(__doc__.splitlines()[0], 30).parse_args(argv)
    slots = slots_for("fjord", "mahipala2023_7_combined") + slots_for("smooth000", "smooth_000_reconstruction")
    run_interleaved(slots, args, "path_mpc", "two-level MPC: upper-level NMPC solve and whole update",
                    x64=bool(jax.config.jax_enable_x64))
    return 0


if __name__ == "__main__":
    sys.exit(main())
