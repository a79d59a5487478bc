"""The closed-loop registry: which group runs the ships of each method (a ship's ``colav``; the own-ship's is
``mpc.method``).

One :class:`Method` per name of :data:`psbmpc_jax.scenario.METHODS`.  :func:`build_groups` makes one group per
method present in a scenario, holding every ship that runs it, so their solves batch.  A new controller is one
more :func:`register` call (no if-chains in the simulator): its ``group`` function gets
``(scenario, ships, mode, params, samples, key, smooth_planner_cls)`` and returns an object with ``ships`` and
``update(loop, k, keep_job) -> Decisions`` (:mod:`psbmpc_jax.sim.colav`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from ..evaluate import DEFAULT_TERMS
from ..methods import informed_terms, psbmpc2020_terms, sbmpc_terms
from .colav import GridGroup, SmoothGroup
from .colav_two_level import TwoLevelGroup


@dataclass(frozen=True)
class Method:
    """One closed-loop controller.

    Attributes:
        name: the method's name (``mpc.method`` / ``colav``).
        description: one line for listings.
        group: builds the group of the given ships (see the module docstring).
        targets: whether a target ship may run it (the smooth planners plan ship 0 only).
    """

    name: str
    description: str
    group: Callable
    targets: bool = True


REGISTRY: dict[str, Method] = {}


def register(method: Method) -> Method:
    """Add ``method`` to :data:`REGISTRY` (a name may be registered once)."""
    if method.name in REGISTRY:
        raise ValueError(f"method {method.name!r} is registered already")
    REGISTRY[method.name] = method
    return method


def _grid(ships, mode, scenario, params, samples, *, method, terms=DEFAULT_TERMS, n_ps=None, refine=False):
    return GridGroup(ships, mode, scenario.mpc, params, samples, refine_ships=ships if refine else (), terms=terms,
                     n_ps=n_ps, method=method)


def _sbmpc_family_grounding(scenario) -> bool:
    """The grounding term only where there is land to ground on (``mpc.sbmpc.grounding`` and polygons)."""
    return bool(scenario.mpc.sbmpc.grounding and scenario.polygons)


register(Method("psbmpc", "PSB-MPC grid search (Tengesdal et al. 2022)",
                lambda sc, ships, mode, params, samples, key, _: _grid(ships, mode, sc, params, samples,
                                                                       method="psbmpc")))
register(Method("psbmpc_refine", "PSB-MPC grid search + gradient refinement (psbmpc_jax.refine)",
                lambda sc, ships, mode, params, samples, key, _: _grid(ships, mode, sc, params, samples,
                                                                       method="psbmpc_refine", refine=True)))
register(Method("sbmpc", "original SB-MPC (Johansen et al. 2016; seed 004 eqs. 8-13), straight-line targets",
                lambda sc, ships, mode, params, samples, key, _: _grid(
                    ships, mode, sc, params, samples, method="sbmpc", n_ps=1,
                    terms=sbmpc_terms(sc.mpc.sbmpc, with_grounding=_sbmpc_family_grounding(sc)))))
register(Method("psbmpc_2020", "PSB-MPC of seed 004 (MCS + scalar KF collision probability, eq. 20)",
                lambda sc, ships, mode, params, samples, key, _: _grid(
                    ships, mode, sc, params, samples, method="psbmpc_2020", n_ps=1,
                    terms=psbmpc2020_terms(sc.mpc.sbmpc, with_grounding=_sbmpc_family_grounding(sc)))))
register(Method("informed_sbmpc", "Informed SB-MPC (seed 002): route exchange, Rule 18, bearing-shaped d_safe",
                lambda sc, ships, mode, params, samples, key, _: GridGroup(
                    ships, mode, sc.mpc, params, samples, terms=informed_terms(sc.mpc.informed), n_ps=1,
                    method="informed_sbmpc", informed=True, d_init=sc.mpc.informed.d_init)))
register(Method("smooth_sbmpc", "Smooth-SBMPC (seed 000): init stage + DOCP", lambda sc, ships, mode, params, samples,
                key, cls: SmoothGroup(sc, cls), targets=False))
register(Method("sbmpc_init", "Smooth-SBMPC's initialisation stage alone (seed 000 Sim 01)",
                lambda sc, ships, mode, params, samples, key, cls: SmoothGroup(sc, cls), targets=False))
register(Method("two_level", "two-level MPC (seed 001): path-following NMPC + SB-MPC with grounding cost",
                lambda sc, ships, mode, params, samples, key, cls: TwoLevelGroup(sc), targets=False))


def build_groups(scenario, mode: str, params, samples, methods, *, key=None, smooth_planner_cls=None) -> list:
    """One group per method in ``methods`` (per ship: ``"none"`` or a registered name), in registry order."""
    unknown = sorted({m for m in methods if m != "none" and m not in REGISTRY})
    if unknown:
        raise ValueError(f"unknown method(s) {unknown}; registered: {', '.join(REGISTRY)}")
    groups = []
    for name, method in REGISTRY.items():
        ships = tuple(i for i, m in enumerate(methods) if m == name)
        if not ships:
            continue
        if not method.targets and ships != (0,):
            bad = [scenario.ships[i].name for i in ships if i != 0]
            raise ValueError(f"ship(s) {bad}: method {name} plans the own-ship only")
        groups.append(method.group(scenario, ships, mode, params, samples, key, smooth_planner_cls))
    return groups


__all__ = ["Method", "REGISTRY", "register", "build_groups"]
