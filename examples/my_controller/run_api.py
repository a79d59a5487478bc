"""Run the example controller through the Python API: register it under a name, then simulate a scenario that
names it.

    PYTHONPATH=examples/my_controller python examples/my_controller/run_api.py
"""

from __future__ import annotations

import pathlib

from cpa_controller import CpaMethod

from psbmpc_jax.methods import REGISTRY, register
from psbmpc_jax.scenario import load_scenario
from psbmpc_jax.sim import simulate


def main() -> None:
    if "cpa" not in REGISTRY:
        register(CpaMethod(d_safe_m=40.0))                 # now `mpc.method: cpa` works in any scenario
    here = pathlib.Path(__file__).parent
    scenario = load_scenario(here / "head_on_cpa.yaml", method="cpa")
    result = simulate(scenario, runs=2)
    for m in result.metrics:
        print(f"run {m['run']}: closest approach {min(m['pair_min_distance_m'].values()):.1f} m, "
              f"collision {m['collision']}")


if __name__ == "__main__":
    main()
