"""Smooth-SBMPC MPC stage (psbmpc_jax/smooth/docp.py), float64: on random channel situations the warm start
(the init stage's offsets) is exactly feasible (terminal equality and corridor), and the applied sequence is
never worse than it — lower or equal J_d, violation <= 1e-3 — with one compilation for all situations."""

from __future__ import annotations

import numpy as np

from psbmpc_jax.nlp import SolverSettings, max_violation, solve_docp
from psbmpc_jax.packing import pack_world
from psbmpc_jax.params import PlannerConfig
from psbmpc_jax.smooth import buffered_chart
from psbmpc_jax.smooth.docp import DocpArgs, bounds, problem, smooth_sbmpc_step
from psbmpc_jax.smooth.init_stage import ShipModel, SmoothSettings, SmoothWeights

SETTINGS = SmoothSettings(T_init=16.0, T_mpc=8.0, dt=1.0, n_y=51)
SOLVER = SolverSettings()          # 8 outer iterations are too few here: the safeguard then keeps the warm start
BANKS = [np.array([[-50.0, 14.0], [150.0, 14.0], [150.0, 30.0], [-50.0, 30.0]]),
         np.array([[-50.0, -14.0], [150.0, -14.0], [150.0, -30.0], [-50.0, -30.0]])]
ROUTE = np.array([[0.0, 0.0], [140.0, 0.0]])


def test_refinement_is_never_worse_than_its_feasible_warm_start():
    land = pack_world(BANKS, PlannerConfig(dtype="float64")).polygons
    buf = buffered_chart(BANKS, SETTINGS.r_dom)
    f, eq, ineq = problem(SETTINGS)
    rng = np.random.default_rng(0)
    improved = 0
    for _ in range(3):
        state0 = np.array([0.0, rng.uniform(-3.0, 3.0), rng.uniform(-0.2, 0.2), rng.uniform(0.6, 1.0)])
        target = np.array([[rng.uniform(15.0, 25.0), rng.uniform(-2.0, 2.0), np.pi + rng.uniform(-0.2, 0.2),
                            rng.uniform(0.3, 0.8)]])
        step = smooth_sbmpc_step(state0, ROUTE, target, np.array([1.0, 0.0]), land, buf, settings=SETTINGS,
                                 solver=SOLVER)
        n = SETTINGS.n_mpc
        args = DocpArgs(step.init.psi[0], ROUTE, target, np.array([1.0, 0.0]), step.init.psi[n], step.corridor,
                        SmoothWeights(), ShipModel())
        lower, upper = bounds(n, step.init.psi.dtype)
        warm_violation = float(max_violation(step.init.controls[:n], lower=lower, upper=upper, eq=eq, ineq=ineq,
                                             args=args))
        assert warm_violation <= 1e-9                                     # Ψ is the rollout of its offsets
        assert float(step.cost) <= float(step.warm_cost) + 1e-9
        assert float(step.violation) <= SOLVER.tol
        np.testing.assert_array_equal(np.asarray(step.apply), np.asarray(step.controls[0]))
        improved += float(step.cost) < float(step.warm_cost) - 1e-6
    assert improved >= 1                                                  # the DOCP does refine
    assert solve_docp.jitted._cache_size() == 1                            # one compilation for all situations
