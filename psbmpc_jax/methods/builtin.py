"""The built-in methods, registered when :mod:`psbmpc_jax.methods` is imported.

======================  =======================================================================================
``psbmpc``              PSB-MPC grid search over the behaviour table (Tengesdal et al. 2022); the first manoeuvre
                        of the chosen behaviour is held until the next update
``psbmpc_refine``       ``psbmpc`` wrapped by the gradient refinement (:class:`Refined`)
``sbmpc``               the same grid search with the original SB-MPC cost (Johansen et al. 2016), straight-line
                        targets (:func:`psbmpc_jax.methods.sbmpc_family.sbmpc_terms`)
``psbmpc_2020``         the same grid search with the probabilistic cost of Tengesdal, Brekke & Johansen 2020
                        (:func:`psbmpc_jax.methods.sbmpc_family.psbmpc2020_terms`)
``informed_sbmpc``      the same grid search with the Informed SB-MPC cost (Akdağ, Fossen & Johansen 2022): route
                        exchange, Rule 18, bearing-shaped d_safe; the planner rests beyond ``d_init``
``smooth_sbmpc``        Smooth-SBMPC: initialisation stage + gradient DOCP (:mod:`psbmpc_jax.methods.smooth`)
``sbmpc_init``          Smooth-SBMPC's initialisation stage alone
``two_level``           the two-level MPC: path-following NMPC + SB-MPC with grounding cost
                        (:mod:`psbmpc_jax.methods.two_level`), absolute course/speed commands
======================  =======================================================================================

Each class builds its controller in :meth:`build` (the heavy imports happen there, not at import) and says in
:meth:`record` which settings it ran with.
"""

from __future__ import annotations

import dataclasses
from dataclasses import asdict
from typing import Any

from ..design_ship import SCALE_PARAMS
from .base import BuildContext, DesignShip, Method
from .colregs_option_settings import (OPTION_METHODS, ColregsOptionSpec, option_in_use, parse_colregs_option,
                                      ship_option)
from .informed_settings import InformedSpec, parse_informed
from .refine_settings import RefineSpec, parse_refine
from .registry import SectionContext, register, register_section
from .sbmpc_family import SbmpcSettings, parse_sbmpc
from .stop_remedy_settings import REMEDY_METHODS, remedy_in_use, ship_remedy
from .smooth_settings import SMOOTH_METHODS, FisSpec, SmoothSpec, SolverSpec, parse_fis, parse_smooth, parse_solver
from .two_level_settings import TwoLevelSpec, parse_two_level


def resolved(obj):
    """A settings object as plain values: a dataclass (nested ones too) as a dict, a mapping's values and a
    sequence's items likewise, a plain object with attributes as ``vars``; anything else as it is."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: resolved(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, dict):
        return {str(k): resolved(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [resolved(v) for v in obj]
    if hasattr(obj, "__dict__") and not callable(obj):
        return {k: resolved(v) for k, v in vars(obj).items() if not k.startswith("_")}
    return obj


def option_groups(scenario, ships, method: str) -> list:
    """``ships`` (indices of the ships that run ``method``) grouped by their resolved COLREGS option and stop
    remedy (:func:`~psbmpc_jax.methods.colregs_option_settings.ship_option`: a ship's own ``colregs_option`` over
    ``mpc.colregs_option``; :func:`~psbmpc_jax.methods.stop_remedy_settings.ship_remedy`: its own ``stop_remedy``
    over ``mpc.config.stop_remedy``), in ship order: ``[(ships of the group, its ColregsOptionSpec, its stop
    remedy)]``.  ValueError when the option is on for a ship whose ``method`` it does not extend
    (docs/colregs_option.md)."""
    groups: dict = {}
    for i in ships:
        groups.setdefault((ship_option(scenario, i), ship_remedy(scenario, i)), []).append(int(i))
    out = []
    for (spec, remedy), members in groups.items():
        if spec.enabled and method not in OPTION_METHODS:
            names = [scenario.ships[i].name for i in members]
            raise ValueError(f"mpc.colregs_option is enabled for ship(s) {names}, but method {method} does not take "
                             f"it (only {', '.join(OPTION_METHODS)} do)")
        out.append((tuple(members), spec, remedy))
    return out


def with_remedy(mpc, remedy: str):
    """``mpc`` (the scenario's ``MPCSpec``) with ``config.stop_remedy`` set to ``remedy`` (the same object when
    it already is)."""
    if mpc.config.stop_remedy == remedy:
        return mpc
    return dataclasses.replace(mpc, config=dataclasses.replace(mpc.config, stop_remedy=remedy))


def option_terms(spec) -> tuple:
    """The cost terms of a resolved option (empty when it is off)."""
    if not spec.enabled:
        return ()
    from ..costs.colregs_option import option_terms as build

    return build(spec)


def held_path(terms, spec) -> tuple:
    """``terms`` with the path term weighted off while engaged when the option has ``hold_path``
    (:func:`psbmpc_jax.costs.colregs_option.with_held_path`); unchanged when the option is off."""
    if not spec.enabled:
        return tuple(terms)
    from ..costs.colregs_option import with_held_path

    return with_held_path(terms, spec)


def grid_controllers(scenario, ships, method: str, build):
    """The controller of ``ships`` for a grid-search ``method``: ``build(group ships, option terms, freeze, mpc)``
    (a :class:`~psbmpc_jax.methods.grid.GridController`; ``freeze`` its argument of that name, ``mpc`` the
    scenario's ``MPCSpec`` with the group's stop remedy, :func:`with_remedy`) once when every ship has the same
    option and remedy, else once per group (:func:`option_groups`), combined into a
    :class:`~psbmpc_jax.methods.grid.GroupedController`."""
    def one(members, spec, remedy):
        return build(members, option_terms(spec), spec if spec.enabled and spec.freeze_course else None,
                     with_remedy(scenario.mpc, remedy))

    groups = option_groups(scenario, ships, method)
    if len(groups) == 1:
        return one(*groups[0])
    from .grid import GroupedController

    return GroupedController([one(*group) for group in groups])


def option_record(scenario) -> dict:
    """The COLREGS option's settings for a method's record: ``{"colregs_option": ...}`` (``mpc.colregs_option``,
    the default of every ship) when it is on, else nothing (the records of the published costs stay as they
    were).  Each ship's resolved option is in the ships' records (:func:`ship_option_record`)."""
    spec = scenario.mpc.colregs_option
    return {"colregs_option": asdict(spec)} if spec.enabled else {}


def ship_option_record(scenario, i: int) -> dict:
    """Ship ``i``'s resolved option and stop remedy for the ships' records: ``{"colregs_option": ...}`` when the
    option is on for some ship of the scenario and ship ``i`` runs a method it extends (enabled or not);
    ``{"stop_remedy": ...}`` when a remedy is in use
    (:func:`~psbmpc_jax.methods.stop_remedy_settings.remedy_in_use`) and ship ``i`` runs a method that reads it;
    else nothing (the records of the published costs stay as they were)."""
    colav = scenario.ships[i].colav
    out: dict[str, Any] = {}
    if colav in OPTION_METHODS and option_in_use(scenario):
        out["colregs_option"] = asdict(ship_option(scenario, i))
    if colav in REMEDY_METHODS and remedy_in_use(scenario):
        out["stop_remedy"] = ship_remedy(scenario, i)
    return out


def _sbmpc_family_grounding(scenario) -> bool:
    """The grounding term only where there is land to ground on (``mpc.sbmpc.grounding`` and polygons)."""
    return bool(scenario.mpc.sbmpc.grounding and scenario.polygons)


class Psbmpc(Method):
    """PSB-MPC: the grid search with the default cost terms and ``mpc.n_ps`` prediction scenarios.  Its tuning
    is the preset (``mpc.preset``, adjusted by ``mpc.params``): the design ship is the preset's."""

    name = "psbmpc"
    description = "PSB-MPC grid search (Tengesdal et al. 2022)"
    tuning_sections = ("params",)

    def design_for(self, mpc) -> DesignShip | None:
        from ..presets import get_preset      # not one of the light method modules (tests/test_layers.py)

        return None if mpc is None else get_preset(mpc.preset).design_ship

    def untuned(self, given_sections, mpc=None) -> str | None:
        """The preset's scale-dependent parameters (:data:`psbmpc_jax.design_ship.SCALE_PARAMS`) that
        ``mpc.params`` does not give, or None when it gives all of them: a weight alone (``K_coll``,
        ``K_chi_port``) does not tune the preset for another ship."""
        given = () if mpc is None else mpc.given_params
        missing = [k for k in SCALE_PARAMS if k not in given]
        return f"mpc.params {', '.join(missing)}" if missing else None

    def build(self, scenario, ships, context: BuildContext):
        from .grid import GridController

        from ..evaluate import DEFAULT_TERMS

        return grid_controllers(scenario, ships, self.name, lambda group, option, freeze, mpc: GridController(
            group, context.mode, mpc, context.params, context.samples, method=self.name,
            terms=held_path(DEFAULT_TERMS, ship_option(scenario, group[0])) + option, devices=context.devices,
            freeze=freeze))

    def record(self, scenario) -> dict:
        m = scenario.mpc      # its weights and solver configuration are mpc.params / mpc.config (recorded apart)
        return {"preset": m.preset, "n_ps": m.n_ps, "n_cbs": len(m.behaviours), **option_record(scenario)}

    def describe(self, scenario) -> str:
        m = scenario.mpc
        return f"preset `{m.preset}`, {len(m.behaviours)} behaviours, n_ps {m.n_ps}"


class Refined(Method):
    """A grid-search method wrapped by the gradient refinement (:func:`psbmpc_jax.refine.refine`, settings
    ``mpc.refine`` / ``mpc.solver`` / ``mpc.fis``): the wrapped method's controller, whose solves are refined
    after the search and applied as per-step controls."""

    diagnostics = True

    def __init__(self, base: Method, name: str, description: str):
        self.base, self.name, self.description = base, name, description
        self.tuning_sections = base.tuning_sections

    def design_for(self, mpc) -> DesignShip | None:
        return self.base.design_for(mpc)

    def untuned(self, given_sections, mpc=None) -> str | None:
        return self.base.untuned(given_sections, mpc)

    def build(self, scenario, ships, context: BuildContext):
        groups = option_groups(scenario, ships, self.name)   # refused when the option is on for a ship
        if len(groups) > 1:          # one refined controller plans every ship of the method: one group
            raise ValueError(f"method {self.name}: its ships plan with one refined controller, so they need the same "
                             f"stop remedy and COLREGS option settings; got stop remedy "
                             + "; ".join(f"{remedy!r} for {[scenario.ships[i].name for i in members]}"
                                         for members, _, remedy in groups)
                             + " -- give them the same stop_remedy (and colregs_option)")
        from .grid import GridController

        controller = self.base.build(scenario, ships, context)
        if not isinstance(controller, GridController):
            raise TypeError(f"method {self.name} refines a grid search; method {self.base.name} built a "
                            f"{type(controller).__name__}, not a GridController")
        controller.enable_refinement()
        controller.method = self.name
        return controller

    def record(self, scenario) -> dict:
        from .grid import refine_function, refine_settings

        _, settings_cls = refine_function()
        m = scenario.mpc
        return {**self.base.record(scenario), "refine": asdict(m.refine), "solver": m.solver.given(),
                "resolved": resolved(refine_settings(m, settings_cls))}

    def describe(self, scenario) -> str:
        return self.base.describe(scenario)


class Sbmpc(Method):
    """The original SB-MPC cost on the grid search, straight-line targets (``mpc.sbmpc``)."""

    name = "sbmpc"
    description = "original SB-MPC (Johansen et al. 2016), straight-line targets"
    tuning_sections = ("sbmpc",)
    design_ship = DesignShip(30.0, 9.0, "Tengesdal, Brekke & Johansen 2020, Table 1 (30 m vessels at 9 m/s)")

    def terms(self, scenario):
        """The method's published cost terms (the COLREGS option's are added per group of ships in :meth:`build`)."""
        from .sbmpc_family import sbmpc_terms

        return sbmpc_terms(scenario.mpc.sbmpc, with_grounding=_sbmpc_family_grounding(scenario))

    def build(self, scenario, ships, context: BuildContext):
        from .grid import GridController

        published = self.terms(scenario)
        return grid_controllers(scenario, ships, self.name, lambda group, option, freeze, mpc: GridController(
            group, context.mode, mpc, context.params, context.samples, method=self.name, n_ps=1,
            terms=published + option, devices=context.devices, freeze=freeze))

    def record(self, scenario) -> dict:
        return {"sbmpc": asdict(scenario.mpc.sbmpc), "grounding_term": _sbmpc_family_grounding(scenario),
                **option_record(scenario)}

    def describe(self, scenario) -> str:
        return f"{len(scenario.mpc.behaviours)} behaviours, straight-line targets"


class Psbmpc2020(Sbmpc):
    """The probabilistic SB-MPC of 2020 (Monte-Carlo CPA probability + scalar Kalman filter), ``mpc.sbmpc``."""

    name = "psbmpc_2020"
    description = "PSB-MPC of Tengesdal, Brekke & Johansen 2020 (MCS + scalar KF collision probability)"

    def terms(self, scenario):
        from .sbmpc_family import psbmpc2020_terms

        return psbmpc2020_terms(scenario.mpc.sbmpc, with_grounding=_sbmpc_family_grounding(scenario))


class InformedSbmpc(Method):
    """Informed SB-MPC (``mpc.informed``): route exchange, Rule 18, bearing-shaped d_safe."""

    name = "informed_sbmpc"
    description = "Informed SB-MPC (Akdağ, Fossen & Johansen 2022): route exchange, Rule 18, shaped d_safe"
    tuning_sections = ("informed",)
    design_ship = DesignShip(116.0, 6.0, "Akdağ, Fossen & Johansen 2022 (116 m offshore vessels at about 6 m/s)")

    def build(self, scenario, ships, context: BuildContext):
        from .grid import GridController
        from .sbmpc_family import informed_terms

        inf = scenario.mpc.informed
        return grid_controllers(scenario, ships, self.name, lambda group, option, freeze, mpc: GridController(
            group, context.mode, mpc, context.params, context.samples, terms=informed_terms(inf) + option,
            n_ps=1, method=self.name, informed=True, d_init=inf.d_init, devices=context.devices, freeze=freeze))

    def record(self, scenario) -> dict:
        from .sbmpc_family import informed_terms

        term, manoeuvring = informed_terms(scenario.mpc.informed)
        return {"informed": asdict(scenario.mpc.informed), "term": resolved(term), "manoeuvring": resolved(manoeuvring),
                **option_record(scenario)}

    def describe(self, scenario) -> str:
        return f"{len(scenario.mpc.behaviours)} behaviours, d_init {scenario.mpc.informed.d_init:g} m"


class SmoothSbmpc(Method):
    """Smooth-SBMPC (``mpc.smooth``, ``mpc.fis``, ``mpc.solver``), the own-ship only."""

    name = "smooth_sbmpc"
    description = "Smooth-SBMPC: initialisation stage + DOCP"
    own_ship_only = True
    diagnostics = True
    tuning_sections = ("smooth", "fis")
    design_ship = DesignShip(5.0, 1.0, "Mahipala & Johansen 2024 (a small inland vessel, about 5 m, at about 1 m/s)")

    def build(self, scenario, ships, context: BuildContext):
        from .smooth import SmoothController

        return SmoothController(scenario)

    def record(self, scenario) -> dict:
        from .smooth import smooth_arguments

        m = scenario.mpc
        return {"smooth": asdict(m.smooth), "fis": asdict(m.fis), "solver": m.solver.given(),
                "resolved": resolved(smooth_arguments(scenario))}

    def describe(self, scenario) -> str:
        sm = scenario.mpc.smooth
        return f"T_init {sm.T_init:g} s, T_mpc {sm.T_mpc:g} s, T_s {sm.dt:g} s"


class SbmpcInit(SmoothSbmpc):
    """Smooth-SBMPC's initialisation stage alone (the original SB-MPC of that paper's comparison)."""

    name = "sbmpc_init"
    description = "Smooth-SBMPC's initialisation stage alone"


class TwoLevel(Method):
    """The two-level MPC (``mpc.two_level``, ``mpc.sbmpc``), the own-ship only."""

    name = "two_level"
    description = "two-level MPC: path-following NMPC + SB-MPC with grounding cost"
    own_ship_only = True
    diagnostics = True
    tuning_sections = ("two_level",)
    # the upper level's cost (7) pulls toward the next waypoint, so the ship runs at the speed bound U_max (5 m/s
    # by default): the defaults fit a cruise speed from 0.8 U_max to U_max; r_os 5 m is a ~10 m hull's circle
    design_ship = DesignShip(10.0, TwoLevelSpec.U_max, "our fjord-scale proposal (a ~10 m vessel, speed bound "
                             f"U_max {TwoLevelSpec.U_max:g} m/s)", speed_range=(0.8 * TwoLevelSpec.U_max,
                                                                                TwoLevelSpec.U_max))

    def build(self, scenario, ships, context: BuildContext):
        from .two_level import TwoLevelController

        return TwoLevelController(scenario)

    def record(self, scenario) -> dict:
        from .two_level import two_level_settings

        settings, config = two_level_settings(scenario)
        m = scenario.mpc
        return {"two_level": asdict(m.two_level), "sbmpc": asdict(m.sbmpc),
                "resolved": {"settings": resolved(settings), "config": resolved(config)}}

    def describe(self, scenario) -> str:
        return f"path MPC N_p {scenario.mpc.two_level.N_p}, SB-MPC {len(scenario.mpc.behaviours)} behaviours"


def _smooth_section(d, ctx: SectionContext) -> SmoothSpec:
    from ..checks import multiple_of

    smooth = parse_smooth(d)
    if ctx.method in SMOOTH_METHODS:
        multiple_of(ctx.period, smooth.dt, "mpc.update_period_s",
                    "mpc.smooth.dt_s" if "dt_s" in (ctx.mpc.get("smooth") or {}) else "mpc.smooth.dt_s (default)")
    return smooth


def _refine_section(d, ctx: SectionContext) -> RefineSpec:
    """``mpc.refine``, with ``mpc.fis.e_cl_m`` / ``n_y`` when the file gives them (the refinement's FIS)."""
    assert ctx.config is not None, "mpc.refine is parsed after the PSB-MPC configuration (after_config)"
    refine = parse_refine(d, ctx.config)
    fis, given = ctx.parsed["fis"], ctx.mpc.get("fis") or {}
    return dataclasses.replace(refine, fis_e_cl=fis.e_cl if "e_cl_m" in given else None,
                               fis_n_y=fis.n_y if "n_y" in given else None)


# the sections of mpc each built-in method reads (parsed in this order, whatever the method)
register_section("smooth", _smooth_section, SmoothSpec)
register_section("fis", lambda d, ctx: parse_fis(d), FisSpec)
register_section("solver", lambda d, ctx: parse_solver(d), SolverSpec)
register_section("refine", _refine_section, RefineSpec, after_config=True)
register_section("sbmpc", lambda d, ctx: parse_sbmpc(d), SbmpcSettings, after_config=True)
register_section("informed", lambda d, ctx: parse_informed(d), InformedSpec, after_config=True)
register_section("two_level", lambda d, ctx: parse_two_level(d), TwoLevelSpec, after_config=True)
register_section("colregs_option", lambda d, ctx: parse_colregs_option(d, ctx.method), ColregsOptionSpec)

PSBMPC = Psbmpc()
for _method in (PSBMPC, Refined(PSBMPC, "psbmpc_refine", "PSB-MPC grid search + gradient refinement"), Sbmpc(),
                Psbmpc2020(), InformedSbmpc(), SmoothSbmpc(), SbmpcInit(), TwoLevel()):
    register(_method)

__all__ = ["Psbmpc", "Refined", "Sbmpc", "Psbmpc2020", "InformedSbmpc", "SmoothSbmpc", "SbmpcInit", "TwoLevel",
           "PSBMPC"]
