"""One PSB-MPC solve: build a situation, plan once, print the chosen maneuver and the cheapest behaviours.

    python examples/01_single_solve.py            # the paper's 1014 behaviours (n_M = 2)
    python examples/01_single_solve.py --quick    # 39 behaviours (n_M = 1); also PSBMPC_EXAMPLE_QUICK=1

The own-ship heads north at 2 m/s on a straight route.  One vessel comes head-on (slightly to port of the
track) and one crosses from starboard; both are tracker estimates with a 4x4 covariance and five LOS
prediction scenarios each.  There is no land, so the grounding cost ``so`` is 0.
"""

from __future__ import annotations

import os
import sys

import numpy as np

from psbmpc_jax import Obstacle, OwnShip, Planner, PlannerConfig, Situation, paper_behaviours

QUICK = os.environ.get("PSBMPC_EXAMPLE_QUICK") == "1" or "--quick" in sys.argv[1:]


def situation() -> Situation:
    own = OwnShip(state=[0.0, 0.0, 0.0, 2.0],              # x north [m], y east [m], course [rad], speed [m/s]
                  waypoints=[[0.0, 0.0], [2000.0, 0.0]],    # the route ahead
                  U_d=2.0, length=5.0, width=3.0)
    cov = np.diag([4.0, 4.0, 0.05, 0.05])                   # position [m^2], velocity [m^2/s^2]
    head_on = Obstacle(state=[300.0, -3.0, -2.0, 0.0],      # [x, y, V_x, V_y]: coming south at 2 m/s
                       cov=cov, length=5.0, width=3.0, n_ps=5)
    crossing = Obstacle(state=[200.0, 150.0, 0.0, -1.5],    # from starboard, heading west at 1.5 m/s
                        cov=cov, length=5.0, width=3.0, n_ps=5)
    return Situation(own, (head_on, crossing), polygons=())


def main() -> int:
    behaviours = paper_behaviours(1 if QUICK else 2)
    planner = Planner(PlannerConfig(estimator="quadrature"), behaviours=behaviours)
    state = planner.init_state()                            # last applied offsets (1, 0)
    result, state = planner.plan(situation(), state)        # first call compiles (a few seconds)

    print(f"{len(behaviours)} behaviours, {planner.config.T:g} s horizon, dt {planner.config.dt:g} s, "
          f"solve {result.solve_time_s * 1e3:.0f} ms (first call, includes compilation)")
    print(f"chosen behaviour #{result.best_index}: " + ", ".join(
        f"M{m + 1}: u={u:g}, chi={np.rad2deg(c):+g} deg" for m, (u, c) in enumerate(result.offsets)))
    print(f"apply now: speed factor {result.u_opt:g}, course offset {np.rad2deg(result.chi_opt):+.0f} deg "
          f"({'starboard' if result.chi_opt > 0 else 'port' if result.chi_opt < 0 else 'keep course'})")

    names = planner.cost_names                              # ("total", "do", "colregs", "so", "path")
    print("\nranking (cheapest first):")
    print(f"{'rank':>4} {'index':>5}  {'maneuvers (u, chi deg)':<24}" + "".join(f"{n:>10}" for n in names))
    for rank, row in enumerate(result.ranking(5), 1):
        man = " ".join(f"({u:g},{c:+.0f})" for u, c in row["maneuvers"])
        print(f"{rank:>4} {row['index']:>5}  {man:<24}" + "".join(f"{row[n]:10.4f}" for n in names))

    # the next call reuses the compiled solve (same shapes): this is the steady-state time
    result2, _ = planner.plan(situation(), state)
    print(f"\nsecond solve (compiled): {result2.solve_time_s * 1e3:.1f} ms")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
