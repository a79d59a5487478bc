"""The stop remedy per ship: a ship entry's ``stop_remedy`` key over the scenario's ``mpc.config.stop_remedy``
(:attr:`psbmpc_jax.params.PlannerConfig.stop_remedy`).  Light: no JAX.

The remedy changes the Boolean COLREGS indicator (:mod:`psbmpc_jax.costs.colregs`), so it is read only by the
methods whose cost holds that indicator: :data:`REMEDY_METHODS`.  Ships of one method with different remedies
plan in different groups, exactly as ships with different COLREGS options do
(:func:`psbmpc_jax.methods.builtin.option_groups`).  docs/methods/psbmpc.md, "The stop loophole and its remedy"."""

from __future__ import annotations

from ..params import STOP_REMEDIES

#: Methods whose cost holds the Boolean COLREGS indicator that the remedy changes: the PSB-MPC COLREGS term
#: (``psbmpc``, and the grid search of ``psbmpc_refine``) and the cost of Tengesdal, Brekke & Johansen 2020.
REMEDY_METHODS = ("psbmpc", "psbmpc_refine", "psbmpc_2020")


def parse_ship_remedy(value, colav: str, where: str, name: str | None = None) -> str:
    """A ship entry's ``stop_remedy`` (``where``: e.g. ``targets[0].stop_remedy``): one of
    :data:`~psbmpc_jax.params.STOP_REMEDIES`, for a ship whose method (``colav``) is one of
    :data:`REMEDY_METHODS`.  ValueError naming ``where`` otherwise: a bad value (with the allowed ones), or a
    ship whose method has no COLREGS indicator for the remedy to change (the key would be ignored); ``name``:
    the ship's name, quoted in the message."""
    if name is not None:
        where = f"{where} (ship {name!r})"
    if colav not in REMEDY_METHODS:
        what = "runs no collision avoidance (colav: none)" if colav == "none" else f"runs method {colav!r}"
        raise ValueError(f"{where}: the ship {what}, whose cost has no Boolean COLREGS indicator for the stop "
                         f"remedy to change; only {', '.join(REMEDY_METHODS)} read it (leave the key out)")
    if not isinstance(value, str) or value not in STOP_REMEDIES:
        raise ValueError(f"{where} must be one of {', '.join(STOP_REMEDIES)}, got {value!r}")
    return value


def check_scenario_remedy(remedy: str, methods) -> None:
    """``mpc.config.stop_remedy`` other than ``"none"`` needs a ship that reads it: ValueError naming the field and
    the scenario's methods when none of them (``methods``: every ship's, own-ship first) is one of
    :data:`REMEDY_METHODS` (the setting would be ignored)."""
    methods = tuple(methods)
    if remedy != "none" and not any(m in REMEDY_METHODS for m in methods):
        raise ValueError(f"mpc.config.stop_remedy = {remedy!r}: no ship of the scenario runs a method that reads it "
                         f"(the ships run {', '.join(dict.fromkeys(methods))}; only {', '.join(REMEDY_METHODS)} "
                         f"have the Boolean COLREGS indicator it changes); leave it out or set it to 'none'")


def ship_remedy(scenario, i: int) -> str:
    """Ship ``i``'s resolved stop remedy: its own ``stop_remedy`` when it gives one (``ShipSpec.stop_remedy``),
    else ``mpc.config.stop_remedy``."""
    own = getattr(scenario.ships[i], "stop_remedy", None)
    return own if own is not None else scenario.mpc.config.stop_remedy


def remedy_in_use(scenario) -> bool:
    """Whether some ship gives its own ``stop_remedy`` or some ship that runs a method reading it resolves to a
    remedy other than ``"none"``."""
    return any(getattr(s, "stop_remedy", None) is not None
               or (s.colav in REMEDY_METHODS and ship_remedy(scenario, i) != "none")
               for i, s in enumerate(scenario.ships))


__all__ = ["REMEDY_METHODS", "parse_ship_remedy", "check_scenario_remedy", "ship_remedy", "remedy_in_use"]
