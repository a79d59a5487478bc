"""psbmpc_jax — Probabilistic Scenario-Based MPC for ship collision avoidance and anti-grounding in JAX.

Public API::

    from psbmpc_jax import Planner, PlannerConfig, Params, OwnShip, Obstacle, Situation
    planner = Planner(PlannerConfig(estimator="quadrature"))
    result, state = planner.plan(situation)

See the README for the parameter table and ``docs/algorithm.md`` for the exact cost.
"""

from .behaviours import enumerate_behaviours, enumerate_behaviours_deg, paper_behaviours
from .evaluate import Evaluation, SituationArrays, evaluate
from .params import Params, PlannerConfig
from .planner import Planner, PlannerState, PlanResult, pack_situation
from .problem import Obstacle, OwnShip, Situation
from .sharding import evaluate_sharded

__version__ = "0.1.0"

__all__ = [
    "Planner", "PlannerConfig", "PlannerState", "PlanResult", "Params", "OwnShip", "Obstacle", "Situation",
    "enumerate_behaviours", "enumerate_behaviours_deg", "paper_behaviours", "evaluate", "Evaluation",
    "SituationArrays", "pack_situation", "evaluate_sharded", "__version__",
]
