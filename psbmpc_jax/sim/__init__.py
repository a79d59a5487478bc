"""Closed-loop simulation: true vessel motion, target tracking, Monte Carlo runs, metrics and outputs.

    from psbmpc_jax.scenario import load_scenario
    from psbmpc_jax.sim import simulate, load_trajectories, write_trajectories
    result = simulate(load_scenario("head_on"), runs=5)
    print(result.summary["collisions"])
    write_trajectories(result, "out/head_on")              # trajectories.csv and trajectories.npz
    tr = load_trajectories("out/head_on")                   # Trajectories: t, states, offsets, costs, ...
"""

from .output import Trajectories, load_trajectories, write_outputs, write_trajectories
from .simulator import SimulationResult, simulate

__all__ = ["SimulationResult", "simulate", "Trajectories", "load_trajectories", "write_trajectories",
           "write_outputs"]
