"""Closed-loop simulation: true vessel motion, target tracking, Monte Carlo runs, metrics and outputs.

    from psbmpc_jax.scenario import load_scenario
    from psbmpc_jax.sim import simulate
    result = simulate(load_scenario("head_on"), runs=5)
    print(result.summary["collisions"])
"""

from .simulator import SimulationResult, simulate

__all__ = ["SimulationResult", "simulate"]
