"""psbmpc_jax — Probabilistic Scenario-Based MPC for ship collision avoidance and anti-grounding in JAX.

Public API::

    from psbmpc_jax import Planner, PlannerConfig, Params, OwnShip, Obstacle, Situation
    planner = Planner(PlannerConfig(estimator="quadrature"))
    result, state = planner.plan(situation)
    total, costs = objective(controls, inputs, params, None, config)    # differentiable, one control input

See the README for the parameter table and ``docs/algorithm.md`` for the exact cost.
"""

import importlib
import sys
import types
from typing import TYPE_CHECKING

#: Public name -> the submodule that defines it.  Loaded on first access (PEP 562), so that importing a
#: host-only submodule -- the scenario loader, the CLI's argument parsing -- does not import JAX.
_EXPORTS = {
    "enumerate_behaviours": "behaviours", "enumerate_behaviours_deg": "behaviours", "paper_behaviours": "behaviours",
    "enable_compilation_cache": "cache", "cost_term": "costs.base",
    "DEFAULT_TERMS": "evaluate", "Evaluation": "evaluate", "evaluate": "evaluate",
    "objective": "objective",
    "Capacities": "packing", "PlanResult": "packing", "SolveInputs": "packing", "pack": "packing",
    "Params": "params", "PlannerConfig": "params", "Planner": "planner",
    "Obstacle": "situation", "OwnShip": "situation", "Situation": "situation",
    "solve_sharded": "sharding", "Plan": "solve", "PlannerState": "solve", "solve": "solve",
    "Status": "status",
}

if TYPE_CHECKING:  # pragma: no cover - for static analysis only
    from .behaviours import enumerate_behaviours, enumerate_behaviours_deg, paper_behaviours
    from .cache import enable_compilation_cache
    from .costs.base import cost_term
    from .evaluate import DEFAULT_TERMS, Evaluation, evaluate
    from .objective import objective
    from .packing import Capacities, PlanResult, SolveInputs, pack
    from .params import Params, PlannerConfig
    from .planner import Planner
    from .situation import Obstacle, OwnShip, Situation
    from .sharding import solve_sharded
    from .solve import Plan, PlannerState, solve
    from .status import Status


#: Public functions named like the submodule that defines them: the package attribute is the function (as
#: ``from psbmpc_jax import evaluate`` has always given), even after the submodule is imported -- which would
#: otherwise bind the name to the module.
_SHADOWED = frozenset(n for n, m in _EXPORTS.items() if n == m)


class _Package(types.ModuleType):
    def __setattr__(self, name, value):
        if name in _SHADOWED and isinstance(value, types.ModuleType):
            return          # the import system binding a submodule: keep resolving the name to the function
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package


def __getattr__(name):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'psbmpc_jax' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_EXPORTS))


from importlib.metadata import PackageNotFoundError as _NoMetadata, version as _dist_version

try:    # the installed distribution's version (pyproject.toml)
    __version__ = _dist_version("psbmpc-jax")
except _NoMetadata:  # pragma: no cover - a source tree that was never installed has no metadata
    __version__ = "0+unknown"

__all__ = [
    "Planner", "PlannerConfig", "PlannerState", "PlanResult", "Params", "OwnShip", "Obstacle", "Situation",
    "enumerate_behaviours", "enumerate_behaviours_deg", "paper_behaviours", "evaluate", "Evaluation",
    "SolveInputs", "Capacities", "pack", "solve", "Plan", "Status", "solve_sharded", "objective", "cost_term",
    "DEFAULT_TERMS", "enable_compilation_cache", "__version__",
]
