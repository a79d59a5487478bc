"""Closed-loop scenario files: schema (frozen dataclasses, SI units and radians inside), YAML loading and
validation.

The YAML format is documented in ``docs/scenarios.md``; degrees and knots appear only in the file (with the
unit in the field name) and are converted exactly once, here.

API: :func:`load_scenario` (a ``.yaml``/``.yml`` path or a built-in name), :func:`scenario_from_dict` (a
parsed mapping), :func:`builtin_scenarios` (the names of the files in ``psbmpc_jax/scenarios/``).  Every
problem in a file raises ``ValueError`` naming the key and what is allowed; nothing is clamped or dropped.

Modules: :mod:`~psbmpc_jax.scenario.schema` (the dataclasses), :mod:`~psbmpc_jax.scenario.load` (the entry
points), :mod:`~psbmpc_jax.scenario.mpc` (the ``mpc`` and ``evaluation`` sections),
:mod:`~psbmpc_jax.scenario.ships` (ship entries), :mod:`~psbmpc_jax.scenario.world` (sensor and chart); the
field readers are :mod:`psbmpc_jax.config`.  The methods' own sections (``mpc.smooth``, ``mpc.refine``,
``mpc.sbmpc``, ``mpc.informed``, ``mpc.two_level``, ...) are parsed by the methods' settings modules, which the
registry hands the loader (:data:`psbmpc_jax.methods.registry.SECTIONS`).  Which names a ship's ``colav`` / ``mpc.method`` may
take is the method registry's answer (:func:`psbmpc_jax.methods.get_method`).
"""

from .load import builtin_path, builtin_scenarios, estimator_key, load_scenario, scenario_from_dict
from ..methods.smooth_settings import SMOOTH_METHODS
from .schema import (COLAV_MODES, KNOT, METHODS, MOTION_MODELS, OWN_SHIP_ONLY_METHODS, RULE18_ROLES, SCENARIO_DIR,
                     VESSEL_MODELS, MPCSpec, Scenario, SensorSpec, ShipSpec)
from .ships import route_geometry

__all__ = [
    "ShipSpec", "SensorSpec", "MPCSpec", "RULE18_ROLES", "MOTION_MODELS", "VESSEL_MODELS", "Scenario",
    "COLAV_MODES", "METHODS", "SMOOTH_METHODS", "OWN_SHIP_ONLY_METHODS", "KNOT", "SCENARIO_DIR",
    "scenario_from_dict", "load_scenario", "builtin_scenarios", "builtin_path", "estimator_key", "route_geometry",
]
