"""One set of defaults: what a scenario file's method sections parse to when they give nothing
(``psbmpc_jax/methods/*_settings.py``) is what the planners use when called without settings.

The values are defined once, in the light settings modules (loading a scenario must not import JAX, so the
planners read them there, not the other way round); these tests go through the same conversions the
controllers use (``smooth_arguments``, ``two_level_settings``, ``refine_settings``), so a default written again
somewhere, with another value, fails here.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
from types import SimpleNamespace

from psbmpc_jax.methods.refine_settings import RefineSpec, parse_refine
from psbmpc_jax.methods.sbmpc_family import SbmpcSettings
from psbmpc_jax.methods.smooth_settings import FisSpec, SmoothSpec, parse_fis, parse_smooth, parse_solver
from psbmpc_jax.methods.two_level_settings import TwoLevelSpec, parse_two_level
from psbmpc_jax.params import PlannerConfig


def _planner_defaults(cls) -> dict:
    return {k: p.default for k, p in inspect.signature(cls.__init__).parameters.items()
            if p.default is not inspect.Parameter.empty}


def test_smooth_sections_parse_to_the_smooth_planners_defaults():
    from psbmpc_jax.methods.smooth import smooth_arguments
    from psbmpc_jax.smooth.init_stage import ShipModel, SmoothSettings, SmoothWeights
    from psbmpc_jax.smooth.planner import SmoothSBMPCPlanner

    model = ShipModel()
    own = SimpleNamespace(U_d=model.U_d, lookahead=model.lookahead, R_a=model.R_a, T_chi=model.T_chi, T_U=model.T_U)
    mpc = SimpleNamespace(smooth=parse_smooth({}), fis=parse_fis({}), solver=parse_solver({}), method="smooth_sbmpc",
                          config=SimpleNamespace(dtype="float32"))
    args = smooth_arguments(SimpleNamespace(mpc=mpc, own_ship=own))
    assert args["settings"] == SmoothSettings()
    assert args["weights"] == SmoothWeights()
    assert args["model"] == model
    assert args["solver"] is None                      # the planner's own default solver
    defaults = _planner_defaults(SmoothSBMPCPlanner)
    assert args["n_starts"] == defaults["n_starts"] == 4
    assert args.get("previous_start", False) == defaults["previous_start"] is False
    # the values themselves (unchanged by defining them once)
    assert (SmoothSpec.T_init, SmoothSpec.T_mpc, SmoothSpec.dt, SmoothSpec.domain_radius) == (60.0, 20.0, 1.0, 4.0)
    assert (FisSpec.d_cl, FisSpec.e_cl, FisSpec.eps, FisSpec.n_y) == (40.0, 5.0, 1e-6, 201)


def test_two_level_section_parses_to_the_two_level_planners_defaults():
    from psbmpc_jax.methods.two_level import two_level_settings
    from psbmpc_jax.two_level import prediction
    from psbmpc_jax.two_level.path_mpc import PathMpcSettings
    from psbmpc_jax.two_level.planner import TwoLevelSettings

    path = PathMpcSettings()
    spec = parse_two_level({})
    config = PlannerConfig()
    scenario = SimpleNamespace(mpc=SimpleNamespace(two_level=spec, sbmpc=SbmpcSettings(), config=config),
                               own_ship=SimpleNamespace(T_chi=path.T_chi, T_U=path.T_U))
    settings, lower = two_level_settings(scenario)
    assert settings.path == path
    # the one default that differs on purpose: a scenario file's SB-MPC solves every 5th update (the proposal:
    # MPC every 1 s, SB-MPC every 5 s), the planner's API every update
    assert (spec.sbmpc_every, TwoLevelSettings().sbmpc_every) == (5, 1)
    assert settings == dataclasses.replace(TwoLevelSettings(), sbmpc_every=spec.sbmpc_every)
    assert lower == config                             # no sbmpc_T_s / sbmpc_dt_s: mpc.config's T and dt
    assert (prediction.DEFAULT_BETA, prediction.DEFAULT_D_CRITICAL) == (spec.beta, spec.d_critical)
    assert (TwoLevelSpec.beta, TwoLevelSpec.chi_span, TwoLevelSpec.N_p) == (math.radians(5.0), math.pi / 2, 30)


def test_refine_section_parses_to_the_refinements_defaults():
    from psbmpc_jax.refine import RefineSettings

    spec = parse_refine({}, PlannerConfig())
    ref = RefineSettings()
    assert (spec.n_starts, spec.horizon, spec.colregs) == (ref.n_starts, ref.horizon, ref.colregs) == (4, None, "fis")
    # previous_start: the section's default is "on whenever n_starts >= 2" (resolved by the parser), the
    # refinement's own default is off; the two are different settings, not one default written twice
    assert spec.previous_start is True and ref.previous_start is False
    assert RefineSpec.n_starts == 4
