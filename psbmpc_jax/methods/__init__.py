"""Collision-avoidance methods behind one protocol.

- :mod:`~psbmpc_jax.methods.base`: :class:`Method` (a named recipe: what it may run, how it builds its
  controller, what it records), :class:`Controller` (``init`` / ``decide``), the :class:`Observation` a controller
  gets at each MPC update and the :class:`Decision` it returns;
- :mod:`~psbmpc_jax.methods.registry`: :data:`REGISTRY`, :func:`register`, :func:`get_method` (registered names,
  the ``psbmpc_jax.methods`` entry point group, import paths ``package.module:Name``);
- :mod:`~psbmpc_jax.methods.builtin`: the built-in methods (registered on import);
- :mod:`~psbmpc_jax.methods.sbmpc_family`: the SB-MPC family's settings and cost-term sets;
- the controllers: :mod:`~psbmpc_jax.methods.grid` (every grid-search method), :mod:`~psbmpc_jax.methods.smooth`,
  :mod:`~psbmpc_jax.methods.two_level`.

Importing this package does not import JAX (the scenario loader uses it); the controllers import their solvers
when a method builds one.  Writing your own controller: ``docs/controllers.md``.
"""

from .base import (COST_NAMES, INFO_NAMES, BuildContext, Controller, Decision, DesignShip, Method, Observation,
                   ShipController, tracked_targets)
from .registry import (ENTRY_POINT_GROUP, REGISTRY, Controllers, build_controllers, get_method, is_import_path,
                       names, register, unregister)
from . import builtin  # noqa: F401  (registers the built-in methods)
from .sbmpc_family import (INFORMED_MANOEUVRING, MAX_N_MC, SBMPC_FAMILY, SBMPC_PRESETS, SbmpcSettings,
                           informed_terms, manoeuvring_term, psbmpc2020_terms, sbmpc_settings, sbmpc_terms)

__all__ = ["COST_NAMES", "INFO_NAMES", "BuildContext", "Controller", "Decision", "DesignShip", "Method", "Observation",
           "ShipController", "tracked_targets", "ENTRY_POINT_GROUP", "REGISTRY", "Controllers", "build_controllers",
           "get_method", "is_import_path", "names", "register", "unregister", "INFORMED_MANOEUVRING", "MAX_N_MC",
           "SBMPC_FAMILY", "SBMPC_PRESETS", "SbmpcSettings", "informed_terms", "manoeuvring_term",
           "psbmpc2020_terms", "sbmpc_settings", "sbmpc_terms"]
