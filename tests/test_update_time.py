"""The time of an MPC update estimated from shapes (psbmpc_jax.update_time): settings whose update would not
finish are refused at load / before the first compile, naming the setting, the estimate and the limit, and
the override (PSBMPC_UPDATE_TIME_LIMIT); the defaults pass; the light defaults match the JAX-side settings.
The comparison of the model with a fresh measurement is slow (PSBMPC_SLOW_TESTS=1)."""

from __future__ import annotations

import copy
import os
import time

import numpy as np
import pytest

from psbmpc_jax import update_time
from psbmpc_jax.limits import ResourceError
from psbmpc_jax.methods.smooth_settings import DOCP_SOLVER_ITERATIONS, REFINE_SOLVER_ITERATIONS
from psbmpc_jax.scenario import scenario_from_dict
from psbmpc_jax.config import yaml_load
from psbmpc_jax.scenario.load import builtin_path

SLOW = os.environ.get("PSBMPC_SLOW_TESTS") == "1"
#: The built-in smooth scenario's own-ship route crosses its peninsula on purpose (allowed, warned about).
pytestmark = pytest.mark.filterwarnings("ignore:.*allowed by own_ship.allow_route_over_land")

REFINE = {"name": "t", "simulation": {"dt_s": 0.5, "duration_s": 60},
          "mpc": {"method": "psbmpc_refine", "preset": "nidelva", "update_period_s": 5, "config": {"T": 60}},
          "own_ship": {"name": "OS", "position_m": [0, 0], "course_deg": 0, "speed_mps": 2},
          "targets": [{"name": "TS1", "position_m": [600, 0], "course_deg": 180, "speed_mps": 2}]}


def smooth_file() -> dict:
    path = builtin_path("smooth_000_reconstruction")
    return yaml_load(path.read_text(encoding="utf-8"), str(path))


@pytest.fixture(autouse=True)
def default_limit(monkeypatch):
    monkeypatch.delenv(update_time.ENV, raising=False)
    monkeypatch.delenv("PSBMPC_SIMULATION_TIME_LIMIT", raising=False)


def test_light_defaults_match_the_solver_settings():
    from psbmpc_jax.nlp import SolverSettings
    from psbmpc_jax.refine import DEFAULT_SOLVER
    from psbmpc_jax.smooth.docp import DOCP_SOLVER

    assert (SolverSettings().max_outer, SolverSettings().max_inner) == DOCP_SOLVER_ITERATIONS
    assert (DOCP_SOLVER.max_outer, DOCP_SOLVER.max_inner) == DOCP_SOLVER_ITERATIONS
    assert (DEFAULT_SOLVER.max_outer, DEFAULT_SOLVER.max_inner) == REFINE_SOLVER_ITERATIONS


def test_the_limit_and_its_override(monkeypatch):
    assert update_time.time_limit()[0] == update_time.DEFAULT_LIMIT_S
    monkeypatch.setenv(update_time.ENV, "900")
    assert update_time.time_limit() == (900.0, f"{update_time.ENV}=900")
    monkeypatch.setenv(update_time.ENV, "off")
    assert update_time.time_limit()[0] is None
    for bad in ("-1", "0", "nan", "ten"):
        monkeypatch.setenv(update_time.ENV, bad)
        with pytest.raises(ValueError, match=f"{update_time.ENV} must be a number of seconds > 0 or 'off'"):
            update_time.time_limit()


def test_estimates_grow_with_the_shapes():
    small = sum(update_time.refine_parts(120, 10, 1, 1, 8).values())
    assert small > 0
    assert sum(update_time.refine_parts(120, 10, 4, 1, 8).values()) > 3 * small          # starts
    assert sum(update_time.refine_parts(300, 10, 1, 1, 8).values()) > 1.5 * small        # horizon
    assert sum(update_time.refine_parts(120, 10, 1, 2, 40).values()) > 6 * small         # iterations
    init = update_time.smooth_parts(60, 20, 4, 4, 20, 50)
    assert init["init"] > 0 and init["docp"] > 0
    assert update_time.smooth_parts(120, 20, 4, 4, 20, 50)["init"] > 3.9 * init["init"]  # quadratic in N_init
    assert update_time.smooth_parts(60, 20, 4, 4, 20, 50, init_only=True)["docp"] == 0


def test_refine_iterations_at_the_documented_maximum_are_refused_at_load():
    d = copy.deepcopy(REFINE)
    scenario_from_dict(d, land_checks="off")                                 # the defaults pass
    d["mpc"]["solver"] = {"max_outer": 100_000, "max_inner": 100_000}
    with pytest.raises(ResourceError, match=r"mpc\.solver\.max_outer x mpc\.solver\.max_inner: the refinement "
                                            r"\(4 start\(s\) x 100000 x 100000 solver iterations .* takes about "
                                            r"[0-9.e+]+ days per MPC update .* the limit is 5 min \(the default; "
                                            r"PSBMPC_UPDATE_TIME_LIMIT=<seconds>.*set PSBMPC_UPDATE_TIME_LIMIT"):
        scenario_from_dict(d, land_checks="off")


def test_smooth_initialisation_horizon_is_refused_at_load_and_the_override_lets_it_load(monkeypatch):
    d = smooth_file()
    s = scenario_from_dict(copy.deepcopy(d), base_dir=builtin_path("smooth_000_reconstruction").parent)
    assert s.mpc.method == "smooth_sbmpc"                                  # the built-in file passes
    d["mpc"]["smooth"] = dict(d["mpc"].get("smooth") or {}, T_init_s=10_000)
    base = builtin_path("smooth_000_reconstruction").parent
    with pytest.raises(ResourceError, match=r"mpc\.smooth\.T_init_s \(with dt_s\): Smooth-SBMPC \(initialisation "
                                            r"stage 10000 steps x 4 target\(s\).* the limit is 5 min"):
        scenario_from_dict(copy.deepcopy(d), base_dir=base)
    monkeypatch.setenv(update_time.ENV, "off")
    with pytest.raises(ResourceError, match=r"mpc\.smooth\.T_init_s = 10000 .* the simulation takes about"):
        scenario_from_dict(copy.deepcopy(d), base_dir=base)              # 20 runs x 221 such updates: days
    monkeypatch.setenv("PSBMPC_SIMULATION_TIME_LIMIT", "off")
    assert scenario_from_dict(copy.deepcopy(d), base_dir=base).mpc.smooth.T_init == 10_000


def test_smooth_solver_iterations_are_refused_naming_the_solver_section():
    d = smooth_file()
    d["mpc"]["solver"] = {"max_outer": 100_000, "max_inner": 100_000}
    with pytest.raises(ResourceError, match=r"mpc\.solver\.max_outer x mpc\.solver\.max_inner: Smooth-SBMPC"):
        scenario_from_dict(d, base_dir=builtin_path("smooth_000_reconstruction").parent)


def test_planner_refuses_the_refinement_before_the_grid_search_compiles(monkeypatch):
    import dataclasses

    import psbmpc_jax.planner as planner_mod
    from psbmpc_jax import Obstacle, OwnShip, Situation
    from psbmpc_jax.presets import build_mpc
    from psbmpc_jax.refine import DEFAULT_SOLVER, RefineSettings

    def no_solve(*a, **kw):
        raise AssertionError("the grid search was called")

    monkeypatch.setattr(planner_mod, "solve", no_solve)
    config, params, beh = build_mpc("nidelva", {"T": 60.0})
    planner = planner_mod.Planner(config, params, beh)
    own = OwnShip(state=[0.0, 0.0, 0.0, 2.0], waypoints=[[0.0, 0.0], [2000.0, 0.0]], U_d=2.0)
    situation = Situation(own, (Obstacle(state=[300.0, 4.0, -2.0, 0.0], cov=np.diag([4.0, 4.0, 0.05, 0.05]),
                                         n_ps=5),), polygons=())
    many = RefineSettings(solver=dataclasses.replace(DEFAULT_SOLVER, max_outer=1000, max_inner=10_000))
    with pytest.raises(ResourceError, match=r"RefineSettings\.solver\.max_outer x max_inner: the refinement"):
        planner.plan(situation, refine=many)


def test_smooth_planner_refuses_before_compiling(monkeypatch):
    import psbmpc_jax.smooth.planner as sp
    from psbmpc_jax.smooth.init_stage import SmoothSettings

    def no_jit(*a, **kw):
        raise AssertionError("the step was compiled")

    monkeypatch.setattr(sp, "_plan_jit", no_jit)
    monkeypatch.setattr(sp, "_plan_batch_jit", no_jit)
    planner = sp.SmoothSBMPCPlanner(settings=SmoothSettings(T_init=5000.0, T_mpc=20.0))
    own, route = np.array([0.0, 0.0, 0.0, 1.0]), np.array([[0.0, 0.0], [500.0, 0.0]])
    targets, last = np.array([[200.0, 0.0, np.pi, 1.0]]), np.array([1.0, 0.0])
    with pytest.raises(ResourceError, match=r"settings\.T_init / dt: Smooth-SBMPC \(initialisation stage 5000 "
                                            r"steps x 1 target"):
        planner.plan(own, route, targets, last)
    with pytest.raises(ResourceError, match=r"settings\.T_init / dt"):
        planner.plan_batch(own[None], route, targets[None], last[None], [0])


@pytest.mark.skipif(not SLOW, reason="times a compiled initialisation stage (PSBMPC_SLOW_TESTS=1)")
def test_the_model_against_a_fresh_measurement():
    """The initialisation stage at T_init 75 s with 3 targets, not one of the measured sizes: the estimate is an
    upper bound (measured median at most 1.5 times it: a shared machine's load moves the times) and not more
    than 10 times the measurement."""
    import sys

    sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "benchmarks"))
    from bench_smooth import channel_polygons, situation
    from psbmpc_jax.smooth import SmoothSBMPCPlanner
    from psbmpc_jax.smooth.init_stage import SmoothSettings

    planner = SmoothSBMPCPlanner(channel_polygons(), settings=SmoothSettings(T_init=75.0), init_only=True)
    own, route, targets, last = situation(50.0)
    planner.plan(own, route, targets[:3], last)
    times = []
    for _ in range(5):
        t0 = time.perf_counter()
        planner.plan(own, route, targets[:3], last)
        times.append(time.perf_counter() - t0)
    est = update_time.smooth_parts(75, 20, 3, 1, 1, 1, init_only=True)["init"]
    assert est / 10 < float(np.median(times)) < 1.5 * est, (est, times)
