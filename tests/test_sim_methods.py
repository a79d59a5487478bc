"""Own-ship methods in the closed-loop simulator (psbmpc_jax/methods/): the ``mpc.method`` / ``mpc.smooth`` /
``mpc.fis`` / ``mpc.solver`` / ``mpc.refine`` keys (good and bad), point targets, the dispatch (who runs what),
the voyage metrics of seed 000 on hand-computed trajectories, short closed loops of every method available
(PSB-MPC; the refinement's per-step controls through a stand-in refine function; the original SB-MPC through
the init-stage adapter), ``psbmpc-jax run --method``, and the reconstructed seed-000 scenario file.

Closed loops of the real ``psbmpc_jax.refine`` / ``psbmpc_jax.smooth.planner`` skip cleanly while those modules
are missing; the long ones (the DOCP compiles for more than a minute on a 2-core CPU) run only with
``PSBMPC_SLOW_TESTS=1``."""

from __future__ import annotations

import contextlib
import copy
import importlib.util
import io
import json
import math
import os
import pathlib
from typing import NamedTuple

import numpy as np
import pytest
import yaml

from psbmpc_jax.apps.cli import main
from psbmpc_jax.methods.refine_settings import RefineSpec
from psbmpc_jax.methods.smooth_settings import FisSpec, SmoothSpec, SolverSpec
from psbmpc_jax.scenario import METHODS, load_scenario, scenario_from_dict
from psbmpc_jax.scenario_checks import ScenarioWarning
from psbmpc_jax.methods import grid, smooth
from psbmpc_jax.methods.base import tracked_targets
from psbmpc_jax.methods.registry import build_controllers
from psbmpc_jax.sim import simulate
from psbmpc_jax.sim.metrics import aggregate, run_metrics, voyage_metrics

REPO = pathlib.Path(__file__).resolve().parents[1]
RECONSTRUCTION = REPO / "scenarios" / "smooth_000_reconstruction.yaml"
HAVE_REFINE = importlib.util.find_spec("psbmpc_jax.refine") is not None
HAVE_PLANNER = importlib.util.find_spec("psbmpc_jax.smooth.planner") is not None
#: Long tests: marked ``slow`` and run only with PSBMPC_SLOW_TESTS=1.
slow = [pytest.mark.slow, pytest.mark.skipif(not os.environ.get("PSBMPC_SLOW_TESTS"),
                                             reason="long (the DOCP compiles for minutes): PSBMPC_SLOW_TESTS=1")]

# a channel 28 m wide heading north, a point target head-on; tiny PSB-MPC and smooth settings
BANKS = [[[-50.0, 14.0], [150.0, 14.0], [150.0, 30.0], [-50.0, 30.0]],
         [[-50.0, -14.0], [150.0, -14.0], [150.0, -30.0], [-50.0, -30.0]]]
TINY = {
    "name": "tiny_methods",
    "description": "A channel, one point target head-on: a tiny case for the method tests",
    "simulation": {"dt_s": 0.5, "duration_s": 4},
    "monte_carlo": {"runs": 2, "seed": 3},
    "collision_distance_m": 2,
    "mpc": {"preset": "nidelva", "update_period_s": 2, "n_ps": 1, "config": {"T": 20},
            "speed_factors": [[1.0]], "course_offsets_deg": [[-30, 0, 30]],
            "smooth": {"T_init_s": 8, "T_mpc_s": 4, "dt_s": 1, "n_starts": 1},
            "fis": {"n_y": 21},
            "solver": {"max_outer": 2, "max_inner": 5}},
    "sensor": {"position_std_m": 0.5, "period_s": 0.5, "filter_R_scale": 1, "sigma_a_mps2": 0.05, "U_max_mps": 2},
    "chart": {"polygons_m": BANKS},
    "own_ship": {"name": "OS", "position_m": [0, 0], "course_deg": 0, "speed_mps": 1, "waypoints_m": [[140, 0]],
                 "T_chi_s": 3, "T_U_s": 5, "lookahead_m": 15, "R_a_m": 5, "length_m": 5, "width_m": 2},
    "targets": [{"name": "P", "position_m": [25, 1], "course_deg": 180, "speed_mps": 0.5, "waypoints_m": [[-100, 1]],
                 "length_m": 0, "width_m": 0}],
}


def tiny(**mpc) -> dict:
    d = copy.deepcopy(TINY)
    d["mpc"].update(mpc)
    return d


def with_(path, value, data=None):
    """``data`` (default a copy of TINY) with the key at dotted ``path`` set (None: deleted)."""
    d = copy.deepcopy(TINY) if data is None else data
    *head, last = path.split(".")
    node = d
    for k in head:
        node = node[int(k)] if isinstance(node, list) else node[k]
    if value is None:
        node.pop(last)
    else:
        node[last] = value
    return d


# ============================================================================================= YAML keys
def test_method_keys_parse_into_the_spec():
    d = tiny(method="smooth_sbmpc",
             smooth={"T_init_s": 30, "T_mpc_s": 10, "dt_s": 0.5, "corridor_half_width_m": 12, "domain_radius_m": 3,
                     "k_ntp": 2.5, "terminal": "soft", "n_starts": 2, "previous_start": True},
             fis={"d_cl_m": 35, "e_cl_m": 4, "eps": 1e-5, "n_y": 101, "completion": "literal"},
             solver={"max_outer": 7, "max_inner": 9, "tol": 1e-4, "method": "adam"},
             refine={"n_starts": 3, "horizon_s": 10, "colregs": "none", "previous_start": True})
    m = scenario_from_dict(d).mpc
    assert m.method == "smooth_sbmpc"
    assert m.smooth == SmoothSpec(T_init=30.0, T_mpc=10.0, dt=0.5, corridor_half_width=12.0, domain_radius=3.0,
                                  k_ntp=2.5, terminal="soft", n_starts=2, previous_start=True)
    assert m.fis == FisSpec(d_cl=35.0, e_cl=4.0, eps=1e-5, n_y=101, completion="literal")
    assert m.solver == SolverSpec(max_outer=7, max_inner=9, tol=1e-4, method="adam")
    assert m.refine == RefineSpec(n_starts=3, horizon=10.0, colregs="none", fis_e_cl=4.0, fis_n_y=101,
                                  previous_start=True)


def test_defaults_are_the_method_modules_defaults():
    """A file without the sections gets exactly the defaults of SmoothSettings / SmoothWeights / SolverSettings."""
    from psbmpc_jax.smooth.init_stage import SmoothSettings, SmoothWeights

    m = load_scenario("head_on").mpc
    assert m.method == "psbmpc"                                      # existing files: unchanged
    s, w = SmoothSettings(), SmoothWeights()
    assert (m.smooth.T_init, m.smooth.T_mpc, m.smooth.dt, m.smooth.corridor_half_width, m.smooth.domain_radius,
            m.smooth.terminal) == (s.T_init, s.T_mpc, s.dt, s.corridor_half_width, s.r_dom, s.terminal)
    assert (m.smooth.k_ntp, m.fis.d_cl, m.fis.e_cl, m.fis.eps) == (w.k_ntp, w.d_cl, w.e_cl, w.eps)
    assert (m.fis.n_y, m.fis.completion) == (s.n_y, s.fis_completion)
    assert m.solver == SolverSpec() and m.solver.given() == {}              # each method's own solver default
    assert m.refine == RefineSpec()
    sc = load_scenario("head_on", method="smooth_sbmpc")
    assert smooth.smooth_arguments(sc)["solver"] is None
    kw = grid.refine_settings(sc.mpc, FakeRefineSettings).kw
    assert "solver" not in kw and "fis_n_y" not in kw


def test_preset_is_optional_only_for_the_smooth_methods():
    for method in ("smooth_sbmpc", "sbmpc_init"):
        sc = scenario_from_dict(with_("mpc.preset", None, tiny(method=method)))
        assert sc.mpc.preset == "nidelva" and sc.mpc.method == method
    for method in ("psbmpc", "psbmpc_refine"):
        with pytest.raises(ValueError, match=rf"mpc: missing required key 'preset' \(required for mpc.method {method}"):
            scenario_from_dict(with_("mpc.preset", None, tiny(method=method)))


BAD = [
    ("method", with_("mpc.method", "smooth"), r"mpc.method must be a known method \(psbmpc, psbmpc_refine, sbmpc, "
                                              r"psbmpc_2020, informed_sbmpc, smooth_sbmpc, sbmpc_init, two_level\) or an "
                                              r"import path 'package.module:Name' of a psbmpc_jax.methods.Method, "
                                              r"got 'smooth'"),
    ("method_type", with_("mpc.method", 3), r"mpc.method must be a known method .*got 3"),
    ("smooth_unknown", with_("mpc.smooth.T_init", 8), r"unknown key 'T_init' in mpc.smooth \(did you mean "
                                                      r"'T_init_s'\?\); allowed keys: T_init_s, T_mpc_s"),
    ("smooth_mapping", with_("mpc.smooth", [1]), r"mpc.smooth must be a mapping"),
    ("terminal", with_("mpc.smooth.terminal", "hard"), r"mpc.smooth.terminal must be one of full, position, soft, "
                                                       r"got 'hard'"),
    ("T_init_not_longer", with_("mpc.smooth.T_init_s", 4), r"mpc.smooth.T_init_s \(4\) must be > mpc.smooth.T_mpc_s"),
    ("T_mpc_multiple", with_("mpc.smooth.T_mpc_s", 4.5), r"mpc.smooth.T_mpc_s \(4.5\) must be a multiple of "
                                                         r"mpc.smooth.dt_s \(1\)"),
    ("T_init_default_multiple", with_("mpc.smooth", {"dt_s": 7}),
     r"mpc.smooth.T_init_s \(default\) \(60\) must be a multiple of mpc.smooth.dt_s \(7\)"),
    ("smooth_dt_zero", with_("mpc.smooth.dt_s", 0), r"mpc.smooth.dt_s must be > 0, got 0"),
    ("domain_negative", with_("mpc.smooth.domain_radius_m", -1), r"mpc.smooth.domain_radius_m must be >= 0"),
    ("n_starts", with_("mpc.smooth.n_starts", 0), r"mpc.smooth.n_starts must be an integer >= 1, got 0"),
    ("n_starts_float", with_("mpc.smooth.n_starts", 2.0), r"mpc.smooth.n_starts must be an integer >= 1, got 2.0"),
    ("k_ntp", with_("mpc.smooth.k_ntp", "high"), r"mpc.smooth.k_ntp must be a finite number, got 'high'"),
    ("refine_previous_start", with_("mpc.refine", {"n_starts": 1, "previous_start": True}),
     r"mpc.refine.previous_start needs mpc.refine.n_starts >= 2 \(start 0 is the grid's choice\), got n_starts 1"),
    ("refine_previous_start_type", with_("mpc.refine", {"previous_start": "on"}),
     r"mpc.refine.previous_start must be true or false"),
    ("previous_start", with_("mpc.smooth.previous_start", "yes"), r"mpc.smooth.previous_start must be true or false"),
    ("previous_start_one_start", with_("mpc.smooth.previous_start", True),
     r"mpc.smooth.previous_start needs mpc.smooth.n_starts >= 2 \(start 0 is always the trajectory Ψ\), got "
     r"n_starts 1"),
    ("period_vs_smooth_dt", with_("mpc.smooth.dt_s", 4, tiny(method="sbmpc_init",
                                                             smooth={"T_init_s": 16, "T_mpc_s": 8})),
     r"mpc.update_period_s \(2\) must be a multiple of mpc.smooth.dt_s \(4\)"),
    ("fis_unknown", with_("mpc.fis.d_cl", 3), r"unknown key 'd_cl' in mpc.fis .*allowed keys: d_cl_m, e_cl_m"),
    ("fis_n_y", with_("mpc.fis.n_y", 1), r"mpc.fis.n_y must be an integer >= 2, got 1"),
    ("fis_completion", with_("mpc.fis.completion", "default_true"),
     r"mpc.fis.completion must be one of default_false, literal, got 'default_true'"),
    ("fis_d_cl", with_("mpc.fis.d_cl_m", 0), r"mpc.fis.d_cl_m must be > 0, got 0"),
    ("solver_unknown", with_("mpc.solver.max_iter", 3), r"unknown key 'max_iter' in mpc.solver.*allowed keys: "
                                                        r"max_outer, max_inner, tol, method"),
    ("solver_outer", with_("mpc.solver.max_outer", 0), r"mpc.solver.max_outer must be an integer >= 1, got 0"),
    ("solver_method", with_("mpc.solver.method", "newton"), r"mpc.solver.method must be one of lbfgs, adam, "
                                                            r"got 'newton'"),
    ("solver_tol", with_("mpc.solver.tol", -1e-3), r"mpc.solver.tol must be > 0"),
    ("refine_unknown", with_("mpc.refine", {"horizon": 5}), r"unknown key 'horizon' in mpc.refine .*allowed keys: "
                                                            r"n_starts, horizon_s, colregs"),
    ("refine_colregs", with_("mpc.refine", {"colregs": "boolean"}), r"mpc.refine.colregs must be one of fis, none"),
    ("refine_horizon_long", with_("mpc.refine", {"horizon_s": 30}),
     r"mpc.refine.horizon_s \(30\) must be <= the PSB-MPC horizon mpc.config T \(20\)"),
    ("refine_horizon_step", with_("mpc.refine", {"horizon_s": 10.2}),
     r"mpc.refine.horizon_s \(10.2\) must be a multiple of the PSB-MPC step mpc.config dt \(0.5\)"),
    ("point_half", with_("targets.0.width_m", 3), r"targets\[0\]: length_m and width_m must both be 0 \(a point "
                                                  r"object\) or both > 0, got 0 and 3"),
    ("own_point", with_("own_ship.length_m", 0), r"own_ship.length_m must be > 0, got 0"),
    ("over_land_type", with_("own_ship.allow_route_over_land", "yes"),
     r"own_ship.allow_route_over_land must be true or false, got 'yes'"),
    ("over_land_target", with_("targets.0.allow_route_over_land", True),
     r"targets\[0\].allow_route_over_land: allowed only for the own-ship"),
    ("smooth_speed_plan", with_("own_ship.speed_plan", [{"t_s": 1, "speed_mps": 0.5}], tiny(method="smooth_sbmpc")),
     r"own_ship.speed_plan: not supported with mpc.method smooth_sbmpc"),
]


@pytest.mark.parametrize("data, match", [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_bad_method_keys(data, match):
    with pytest.raises(ValueError, match=match):
        scenario_from_dict(data)


def test_other_methods_sections_are_validated_but_unused():
    """One file can carry the settings of every method; --method picks one (no error for the others')."""
    sc = scenario_from_dict(tiny(method="psbmpc", refine={"n_starts": 2}))
    assert sc.mpc.method == "psbmpc" and sc.mpc.smooth.T_init == 8.0 and sc.mpc.refine.n_starts == 2


def test_method_override(tmp_path):
    path = tmp_path / "m.yaml"
    path.write_text(yaml.safe_dump(tiny()))
    assert load_scenario(path).mpc.method == "psbmpc"
    # methods whose default settings were tuned for another ship (tiny's own-ship: 5 m at 1 m/s) are refused
    # until the file gives their section (Method.check_fit)
    own_tuning = {"sbmpc": {"sbmpc": {"preset": "river"}}, "psbmpc_2020": {"sbmpc": {"preset": "river"}},
                  "informed_sbmpc": {"informed": {"d_init_m": 300}}, "two_level": {"two_level": {"U_max_mps": 1}}}
    for method in METHODS:
        if method in own_tuning:
            with pytest.raises(ValueError, match=rf"method {method} on ship 'OS': its default settings \(mpc\.\w+ "
                                                 r"not in the file\) were tuned for .* fit ships within a factor 3"):
                load_scenario(path, method=method)
            assert scenario_from_dict(tiny(**own_tuning[method]), method=method).mpc.method == method
            continue
        assert load_scenario(path, method=method).mpc.method == method
        assert scenario_from_dict(tiny(), method=method).mpc.method == method
    with pytest.raises(ValueError, match=r"method \(the override of mpc.method\) must be a known method"):
        scenario_from_dict(tiny(), method="three_level")
    # the override is validated like the file: here the smooth step does not divide the update period
    d = tiny(smooth={"T_init_s": 9, "T_mpc_s": 3, "dt_s": 3})
    assert scenario_from_dict(d).mpc.method == "psbmpc"
    with pytest.raises(ValueError, match=r"mpc.update_period_s \(2\) must be a multiple of mpc.smooth.dt_s \(3\)"):
        scenario_from_dict(d, method="smooth_sbmpc")


def test_point_targets_and_route_over_land():
    sc = scenario_from_dict(tiny())
    assert sc.targets[0].is_point and not sc.own_ship.is_point
    # a route through land is refused, unless the own-ship says it crosses it on purpose (then a warning)
    wall = [[[5.0, -10.0], [10.0, -10.0], [10.0, 0.5], [5.0, 0.5]]]
    d = with_("chart.polygons_m", BANKS + wall)
    with pytest.raises(ValueError, match=r"own-ship 'OS': route leg 0 .* crosses land"):
        scenario_from_dict(d, land_checks="error")
    d["own_ship"]["allow_route_over_land"] = True
    with pytest.warns(ScenarioWarning, match=r"crosses land .*allowed by own_ship.allow_route_over_land"):
        sc = scenario_from_dict(d, land_checks="error")
    assert sc.own_ship.allow_route_over_land
    # a start on land is still an error
    d["own_ship"]["position_m"] = [7, 0]
    with pytest.raises(ValueError, match=r"own-ship 'OS' starts .* inside land"):
        scenario_from_dict(d, land_checks="error")


# ============================================================================================= dispatch
def test_dispatch_who_runs_what(monkeypatch):
    sc = scenario_from_dict(tiny())
    c = build_controllers(sc)
    assert c.method == "psbmpc" and [type(g).__name__ for g in c.controllers] == ["GridController"]
    assert c.controllers[0].ships == (0,) and c.controllers[0].refine_ships == () and c.snapshots
    # a target with its own PSB-MPC keeps it under a smooth own-ship method; the own-ship gets the smooth planner
    monkeypatch.setattr(smooth, "smooth_planner_class", lambda: smooth.SmoothStepPlanner)
    d = tiny(method="sbmpc_init")
    d["targets"][0]["colav"] = "psbmpc"
    c = build_controllers(scenario_from_dict(d))
    assert [type(g).__name__ for g in c.controllers] == ["GridController", "SmoothController"]     # registry order
    assert c.controllers[0].ships == (1,) and not c.snapshots and list(c.controlled) == [True, True]
    assert c.controllers[1].planner.init_only and c.methods == ("sbmpc_init", "psbmpc")
    # no collision avoidance on the own-ship: no method, no planner
    d = tiny(method="smooth_sbmpc")
    d["own_ship"]["colav"] = "none"
    c = build_controllers(scenario_from_dict(d))
    assert c.method is None and c.own is None and c.controllers == []


def test_smooth_planner_arguments_come_from_the_file():
    sc = scenario_from_dict(tiny(method="smooth_sbmpc", fis={"d_cl_m": 30, "n_y": 21, "completion": "literal"}))
    kw = smooth.smooth_arguments(sc)
    m, s, w, sol = kw["model"], kw["settings"], kw["weights"], kw["solver"]
    own = sc.own_ship
    assert (m.U_d, m.lookahead, m.R_a, m.T_chi, m.T_U) == (own.U_d, 15.0, 5.0, 3.0, 5.0)
    assert (s.T_init, s.T_mpc, s.dt, s.n_y, s.fis_completion) == (8.0, 4.0, 1.0, 21, "literal")
    assert (w.d_cl, sol.max_outer, sol.max_inner) == (30.0, 2, 5)
    assert kw["n_starts"] == 1 and kw["init_only"] is False and kw["dtype"] == "float32"
    assert smooth.smooth_arguments(scenario_from_dict(tiny(method="sbmpc_init")))["init_only"] is True
    assert "previous_start" not in kw                                  # off: the planner's own default
    on = {"T_init_s": 8, "T_mpc_s": 4, "dt_s": 1, "n_starts": 2, "previous_start": True}
    assert smooth.smooth_arguments(scenario_from_dict(tiny(method="smooth_sbmpc", smooth=on)))["previous_start"]
    assert "previous_start" not in smooth.smooth_arguments(scenario_from_dict(tiny(method="sbmpc_init", smooth=on)))


class PreviousRecorder:
    """A planner with ``SmoothSBMPCPlanner``'s interface that records the ``previous`` plans the simulator hands
    it and returns distinct, known sequences (row j of update m, run r: U 1, χ = 0.01 (10 m + j) + 0.001 r)."""

    seen: list = []

    def __init__(self, polygons=(), *, settings, previous_start=False, **kw):
        assert previous_start
        self.n = settings.n_mpc

    def plan_batch(self, states, route, targets, last, segments, previous=None):
        m, R = len(PreviousRecorder.seen), len(states)
        PreviousRecorder.seen.append(None if previous is None else np.array(previous))
        chi = 0.01 * (10 * m + np.arange(self.n))[None, :] + 0.001 * np.arange(R)[:, None]
        controls = np.stack([np.ones_like(chi), chi], axis=-1)
        zero = np.zeros(R)
        return smooth.StepPlan(controls[:, 0], controls, np.zeros((R, 9, 4)), zero, zero, zero, np.ones(R, bool),
                              zero.astype(int), zero.astype(int), np.zeros(R, bool))


def test_the_simulator_hands_the_shifted_previous_plan_to_the_next_update(monkeypatch):
    monkeypatch.setattr(smooth, "smooth_planner_class", lambda: PreviousRecorder)
    PreviousRecorder.seen = []
    on = {"T_init_s": 8, "T_mpc_s": 4, "dt_s": 1, "n_starts": 2, "previous_start": True}
    r = simulate(scenario_from_dict(tiny(method="smooth_sbmpc", smooth=on)), batch="loop")
    first, second = PreviousRecorder.seen                             # updates at 0 s and 2 s (period 2 s)
    assert first is None
    chi0 = 0.01 * np.arange(4)[None, :] + 0.001 * np.arange(2)[:, None]
    expected = np.concatenate([chi0[:, 2:], chi0[:, 3:], chi0[:, 3:]], axis=1)   # 2 steps on, last row repeated
    np.testing.assert_allclose(second[..., 1], expected, atol=1e-12)
    np.testing.assert_allclose(second[..., 0], 1.0)
    np.testing.assert_allclose(r.offsets[:, 0, 1, 1], 0.01 * 10 + 0.001 * np.arange(2))   # update 1's first row


@pytest.mark.skipif(HAVE_PLANNER, reason="psbmpc_jax.smooth.planner exists")
def test_missing_planner_is_a_clear_error():
    with pytest.raises(ImportError, match=r"mpc.method smooth_sbmpc / sbmpc_init needs psbmpc_jax.smooth.planner"):
        simulate(scenario_from_dict(tiny(method="smooth_sbmpc")), runs=1)


@pytest.mark.skipif(HAVE_REFINE, reason="psbmpc_jax.refine exists")
def test_missing_refine_is_a_clear_error():
    with pytest.raises(ImportError, match=r"mpc.method psbmpc_refine needs psbmpc_jax.refine"):
        simulate(scenario_from_dict(tiny(method="psbmpc_refine")), runs=1)


def test_tracked_targets_and_consistent_sequences():
    tx = np.array([[[10.0, 5.0, 0.0, 2.0], [0.0, 0.0, -1.0, 0.0]]])
    out = tracked_targets(tx)
    np.testing.assert_allclose(out, [[[10.0, 5.0, np.pi / 2, 2.0], [0.0, 0.0, np.pi, 1.0]]])
    first = np.array([[1.0, 0.1], [0.5, 0.0]])
    ctrl = np.array([[[1.0, 0.1], [0.9, 0.2]], [[1.0, 0.3], [0.8, 0.3]]])   # job 1 starts elsewhere: held
    np.testing.assert_array_equal(grid.consistent_sequences(first, ctrl),
                                  [[[1.0, 0.1], [0.9, 0.2]], [[0.5, 0.0], [0.5, 0.0]]])


# ============================================================================================= metrics
def test_voyage_metrics_hand_computed():
    t = np.arange(5.0)
    deg = np.radians
    own = np.array([[0.0, 0.0, deg(350.0), 0.5],
                    [3.0, 4.0, deg(10.0), 1.0],          # 5 m
                    [6.0, 8.0, deg(20.0), 2.0],          # 5 m: within 1 m of the last waypoint -> arrival at t = 2
                    [6.0, 8.0, deg(90.0), 3.0],
                    [9.0, 12.0, deg(-170.0), 0.1]])
    route = np.array([[0.0, 0.0], [6.5, 8.0]])
    v = voyage_metrics(t, own, route, arrival_radius=1.0)
    assert v["arrived"] and v["voyage_time_s"] == 2.0
    assert v["path_length_m"] == pytest.approx(10.0)
    # the continuous course: 350 -> 10 -> 20 deg is 350 .. 380 (first course in [0, 360))
    assert v["course_min_deg"] == pytest.approx(350.0) and v["course_max_deg"] == pytest.approx(380.0)
    assert (v["speed_min_mps"], v["speed_max_mps"]) == (0.5, 2.0)
    assert v["voyage_mean_abs_course_rate_deg_s"] == pytest.approx(15.0)
    # never within the radius: the whole run, no voyage time
    v = voyage_metrics(t, own, route, arrival_radius=0.1)
    assert not v["arrived"] and v["voyage_time_s"] is None
    assert v["path_length_m"] == pytest.approx(15.0)
    assert (v["speed_min_mps"], v["speed_max_mps"]) == (0.1, 3.0)
    # 350, 370, 380, 450, then -170 deg = 550 (continuous: +100 deg from 450)
    assert (v["course_min_deg"], v["course_max_deg"]) == (pytest.approx(350.0), pytest.approx(550.0))
    assert voyage_metrics(t, own, route)["voyage_time_s"] is None            # no radius: no arrival
    # a course crossing north to port reads below 0
    own2 = own.copy()
    own2[:, 2] = deg(np.array([10.0, -10.0, -20.0, -20.0, -20.0]))
    v = voyage_metrics(t, own2, route, arrival_radius=0.1)
    assert (v["course_min_deg"], v["course_max_deg"]) == (pytest.approx(-20.0), pytest.approx(10.0))


def test_voyage_metrics_in_run_metrics_and_aggregate():
    t = np.arange(0.0, 11.0)
    own = np.column_stack([t, np.zeros_like(t), np.zeros_like(t), np.ones_like(t)])     # 1 m/s north
    route = np.array([[0.0, 0.0], [8.0, 0.0]])
    kw = dict(d_collision=1.0, ground_clearance=0.0)
    a = run_metrics(t, own, [], route, (), arrival_radius=2.0, **kw)                     # within 2 m at t = 6
    b = run_metrics(t, own, [], np.array([[0.0, 0.0], [50.0, 0.0]]), (), arrival_radius=2.0, **kw)
    assert (a["voyage_time_s"], a["path_length_m"], a["arrived"]) == (6.0, 6.0, True)
    assert (b["voyage_time_s"], b["path_length_m"], b["arrived"]) == (None, 10.0, False)
    s = aggregate([a, b])
    assert s["arrived_runs"] == 1
    assert s["voyage_time_s"] == {"min": 6.0, "mean": 6.0, "median": 6.0, "max": 6.0, "n": 1}
    assert s["path_length_m"]["min"] == 6.0 and s["path_length_m"]["max"] == 10.0
    assert s["course_min_deg"]["min"] == 0.0 and s["speed_max_mps"]["max"] == 1.0
    json.dumps(s)                                                                         # plain JSON, no NaN


# ============================================================================================= closed loops
def speed_factors_applied(result, run: int = 0) -> np.ndarray:
    """The own-ship's speed factor at each step, read back from the true motion (U_{k+1} = U_k + dt/T_U (u U_d -
    U_k); open water speed, no speed plan)."""
    sc = result.scenario
    U = result.states[run, 0, :, 3]
    return ((U[1:] - U[:-1]) * sc.own_ship.T_U / sc.dt + U[:-1]) / sc.own_ship.U_d


@pytest.fixture(scope="module")
def psbmpc_run():
    return simulate(scenario_from_dict(tiny()), batch="loop")


def test_psbmpc_with_point_targets(psbmpc_run):
    r = psbmpc_run
    assert r.method == "psbmpc" and r.summary["method"] == "psbmpc" and r.colav_info is None
    assert r.summary["colav_diagnostics"] is None
    assert np.isfinite(r.states).all() and np.isfinite(r.offsets[:, 0]).all() and np.isfinite(r.best_costs[:, 0]).all()
    assert r.summary["mpc_solves_total"] == 2 * 2 and r.summary["device_calls"] == 4
    m = r.metrics[0]
    assert {"path_length_m", "voyage_time_s", "course_min_deg", "course_max_deg", "speed_min_mps",
            "speed_max_mps", "arrived"} <= set(m)
    assert m["ships_grounded"] == []                                       # a point target in water
    # PSB-MPC holds the chosen offsets over the period: the speed factor read back equals them
    np.testing.assert_allclose(speed_factors_applied(r), np.repeat(r.offsets[0, 0, :, 0], 4), atol=1e-9)


class FakeRefinement(NamedTuple):
    controls: np.ndarray
    apply: np.ndarray
    cost: float
    warm_cost: float
    violation: float
    used_warm: bool
    status: int
    iterations: int
    start_index: int


class FakeRefineSettings:
    def __init__(self, **kw):
        self.kw = kw


class FakePreviousSettings(FakeRefineSettings):
    def __init__(self, **kw):
        super().__init__(**kw)
        self.previous_start = kw.get("previous_start", False)


def test_refine_previous_start_hands_the_shifted_refinement_to_the_next_update(monkeypatch):
    """mpc.refine.previous_start: each refined ship's next solve state carries its last refined controls,
    shifted by the update period (2 s = 4 steps of config.dt 0.5 s); the first update gets NaN (none)."""
    seen = []

    def fake_refine(inputs, plan, state, params, samples, config, settings, evaluation=None):
        seen.append(None if state.warm_start is None else np.array(state.warm_start))
        j = np.arange(40.0)
        controls = np.stack([1.0 - 0.01 * j, 0.01 * j + 0.1 * len(seen)], axis=-1)
        return FakeRefinement(controls, controls[0], 1.0, 2.0, 0.0, False, 0, 7, 0)

    monkeypatch.setattr(grid, "refine_function", lambda: (fake_refine, FakePreviousSettings))
    d = tiny(method="psbmpc_refine", refine={"n_starts": 2, "previous_start": True})
    simulate(scenario_from_dict(d), batch="loop")
    assert len(seen) == 4 and all(w is not None and w.shape == (40, 2) for w in seen)
    assert np.isnan(seen[0]).all() and np.isnan(seen[1]).all()            # update 0, runs 0 and 1: none yet
    for run in (0, 1):
        j = np.arange(40.0)
        made = np.stack([1.0 - 0.01 * j, 0.01 * j + 0.1 * (run + 1)], axis=-1)       # what update 0 returned
        np.testing.assert_allclose(seen[2 + run], np.concatenate([made[4:], np.repeat(made[-1:], 4, axis=0)]))
    # the default: on with two or more starts, off with one; off when the file says so
    for refine, on in (({"n_starts": 2}, True), ({"n_starts": 1}, False), ({"previous_start": False}, False), ({}, True)):
        sc = scenario_from_dict(tiny(method="psbmpc_refine", refine=refine))
        assert sc.mpc.refine.previous_start is on
        assert grid.refine_settings(sc.mpc, FakeRefineSettings).kw.get("previous_start", False) is on


def test_refine_path_applies_the_per_step_controls(monkeypatch):
    """psbmpc_refine through a stand-in refine(): row j of its controls applies from t_update + j * config.dt on."""
    calls = []

    def fake_refine(inputs, plan, state, params, samples, config, settings, evaluation=None):
        assert int(evaluation.best) == int(plan.best)                        # the solve's own evaluation
        calls.append((np.asarray(state.last_offsets, float), int(plan.best), settings.kw, config.dt))
        j = np.arange(40.0)
        controls = np.stack([1.0 - 0.05 * j, 0.01 * j], axis=-1)
        return FakeRefinement(controls, controls[0], 1.0, 2.0, 0.0, False, 0, 7, 0)

    monkeypatch.setattr(grid, "refine_function", lambda: (fake_refine, FakeRefineSettings))
    d = tiny(method="psbmpc_refine", refine={"n_starts": 2, "horizon_s": 10, "colregs": "none"})
    r = simulate(scenario_from_dict(d), batch="loop")
    assert r.method == "psbmpc_refine" and len(calls) == 2 * 2                 # the own-ship of 2 runs, 2 updates
    kw = calls[0][2]
    assert (kw["n_starts"], kw["horizon"], kw["colregs"]) == (2, 10.0, "none")
    assert kw["fis_n_y"] == 21 and "fis_e_cl" not in kw                     # mpc.fis keys the file gives
    assert (kw["solver"].max_outer, kw["solver"].max_inner) == (2, 5) and calls[0][3] == 0.5
    np.testing.assert_allclose(calls[0][0], [1.0, 0.0])                       # the first plan: nothing applied yet
    np.testing.assert_allclose(calls[2][0], [1.0 - 0.05 * 3, 0.03])           # then the last row applied (j = 3)
    # config.dt = dt = 0.5 s: step j of each 4-step period applies row j
    np.testing.assert_allclose(speed_factors_applied(r), np.tile(1.0 - 0.05 * np.arange(4), 2), atol=1e-9)
    np.testing.assert_allclose(r.offsets[:, 0, :, 0], 1.0)
    np.testing.assert_allclose(r.colav_info["cost"], 1.0)
    np.testing.assert_allclose(r.colav_info["iterations"], 7.0)
    diag = r.summary["colav_diagnostics"]
    assert diag["updates"] == 4 and diag["used_warm_fraction"] == 0.0 and diag["cost_improvement_median"] == 1.0
    assert r.summary["device_calls"] == 4 + 4                                  # the solves, then the refinements


class RecordingPlanner(smooth.SmoothStepPlanner):
    """The init-stage adapter, recording what the simulator hands it."""

    seen: list = []

    def plan_batch(self, states, route, targets, last, segments):
        plan = super().plan_batch(states, route, targets, last, segments)
        RecordingPlanner.seen.append(dict(states=np.array(states), route=np.array(route), targets=np.array(targets),
                                          last=np.array(last), segments=np.array(segments),
                                          controls=np.array(plan.controls)))
        return plan


@pytest.fixture(scope="module")
def init_run():
    mp = pytest.MonkeyPatch()
    mp.setattr(smooth, "smooth_planner_class", lambda: RecordingPlanner)
    RecordingPlanner.seen = []
    try:
        yield simulate(scenario_from_dict(tiny(method="sbmpc_init")), batch="loop"), list(RecordingPlanner.seen)
    finally:
        mp.undo()


def test_sbmpc_init_closed_loop(init_run):
    r, seen = init_run
    assert r.method == "sbmpc_init" and r.summary["method"] == "sbmpc_init" and r.snapshot is None
    assert len(seen) == 2 and r.summary["device_calls"] == 2 and r.summary["mpc_solves_total"] == 4
    assert np.isnan(r.best_costs[:, 0]).all() and np.isfinite(r.colav_info["cost"]).all()
    # the original SB-MPC's offsets come from the behaviour table (26a), (26b)
    u, chi = r.offsets[:, 0, :, 0], np.degrees(r.offsets[:, 0, :, 1])
    assert np.isin(np.round(u, 6), [0.1, 0.5, 1.0]).all() and np.allclose(chi, np.round(chi / 15) * 15, atol=1e-4)
    # what the planner got: the true own-ship state, the route extended, the targets through the tracks
    # (course = atan2 of the track velocity, speed = its norm) and the offsets applied last
    first, second = seen
    np.testing.assert_allclose(first["states"], r.states[:, 0, 0])
    np.testing.assert_allclose(second["states"], r.states[:, 0, 4])
    np.testing.assert_allclose(first["route"][:2], [[0.0, 0.0], [140.0, 0.0]])
    tx = r.track_x[:, 0, 4]
    np.testing.assert_allclose(second["targets"][:, 0], np.column_stack(
        [tx[:, 0], tx[:, 1], np.arctan2(tx[:, 3], tx[:, 2]), np.hypot(tx[:, 2], tx[:, 3])]))
    assert not np.allclose(second["targets"][:, 0, :2], r.states[:, 1, 4, :2])   # tracking noise, not truth
    np.testing.assert_allclose(first["last"], [[1.0, 0.0]] * 2)
    assert second["segments"].tolist() == [0, 0]
    # per-step controls at T_s = 1 s with dt = 0.5 s: row j applies on steps 2j, 2j + 1 of each period
    rows = np.array([call["controls"] for call in seen])                       # [updates, R, N, 2]
    u_steps = speed_factors_applied(r, 1)
    expected = np.concatenate([np.repeat(rows[m, 1, :2, 0], 2) for m in range(2)])
    np.testing.assert_allclose(u_steps, expected, atol=1e-6)
    np.testing.assert_allclose(second["last"][1], rows[0, 1, 1])             # the row applied last


def test_metrics_and_figures_of_a_method_run(init_run, psbmpc_run, tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from psbmpc_jax.sim.output import metrics_document, summary_markdown
    from psbmpc_jax.sim.plots import plot_course_speed_compare, plot_map, write_figures

    r, _ = init_run
    doc = json.loads(json.dumps(metrics_document(r)))
    assert doc["scenario"]["mpc"]["method"] == "sbmpc_init" and doc["summary"]["method"] == "sbmpc_init"
    assert doc["scenario"]["mpc"]["smooth"]["T_init"] == 8.0 and doc["summary"]["colav_diagnostics"]["updates"] == 4
    assert "own-ship method `sbmpc_init`" in summary_markdown(r) and "Voyage" in summary_markdown(r)
    ax = plot_map(r)
    assert any("[sbmpc_init]" in t.get_text() for t in ax.get_legend().get_texts())
    assert any("(point)" in t.get_text() for t in ax.get_legend().get_texts())
    plt.close(ax.figure)
    axes = plot_course_speed_compare({"SB-MPC": r, "PSB-MPC": psbmpc_run})
    assert [ln.get_label() for ln in axes[0].lines] == ["SB-MPC", "PSB-MPC"] and len(axes[1].lines) == 2
    plt.close(axes[0].figure)
    assert {p.name for p in write_figures(r, tmp_path)} >= {"map.png", "course_speed.png"}


# ============================================================================================= CLI
def test_cli_method_override(tmp_path, monkeypatch, psbmpc_run, init_run):
    monkeypatch.setattr(smooth, "smooth_planner_class", lambda: smooth.SmoothStepPlanner)
    path = tmp_path / "tiny_methods.yaml"
    path.write_text(yaml.safe_dump(tiny()))
    out = tmp_path / "out"
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        rc = main(["run", str(path), "--method", "sbmpc_init", "--out", str(out), "--no-figures", "--quiet"])
    assert rc == 0, buf.getvalue()
    doc = json.loads((out / "tiny_methods_sbmpc_init" / "metrics.json").read_text())
    assert doc["scenario"]["mpc"]["method"] == "sbmpc_init" and doc["summary"]["method"] == "sbmpc_init"
    assert "(method sbmpc_init)" in buf.getvalue()
    assert "| sbmpc_init |" in (out / "index.md").read_text()
    with contextlib.redirect_stdout(io.StringIO()):                               # the file's own method
        assert main(["run", str(path), "--out", str(out), "--no-figures", "--quiet"]) == 0
    assert json.loads((out / "tiny_methods" / "metrics.json").read_text())["summary"]["method"] == "psbmpc"


def test_cli_method_errors(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["run", "head_on", "--method", "three_level", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "--method must be a known method" in err and "got 'three_level'" in err
    assert "two_level" in err                                                   # the known names, listed
    path = tmp_path / "nopreset.yaml"
    path.write_text(yaml.safe_dump(with_("mpc.preset", None, tiny(method="smooth_sbmpc"))))
    with pytest.raises(SystemExit) as exc:
        main(["run", str(path), "--method", "psbmpc", "--out", str(tmp_path)])
    assert exc.value.code == 2 and "missing required key 'preset'" in capsys.readouterr().err


# ============================================================================================= seed 000 scenario
def test_reconstruction_scenario_loads_and_is_marked():
    with pytest.warns(ScenarioWarning, match=r"allowed by own_ship.allow_route_over_land"):
        sc = load_scenario("smooth_000_reconstruction")
    assert "RECONSTRUCTED" in sc.description and "RECONSTRUCTED" in RECONSTRUCTION.read_text().splitlines()[0]
    assert sc.mpc.method == "smooth_sbmpc" and sc.duration == 220 and sc.dt == 1 and sc.mpc.period == 1
    assert sc.runs == 20 and sc.d_collision == 4
    assert all(t.is_point and t.colav == "none" for t in sc.targets) and len(sc.targets) == 4
    own = sc.own_ship
    assert (own.U_d, own.lookahead, own.R_a, own.T_chi, own.T_U) == (1.0, 15.0, 5.0, 3.0, 5.0)
    # route coordinates: chi0 = 105 deg, the route 160 m long
    chi0 = math.radians(105.0)
    s_e = lambda p: (p[0] * math.cos(chi0) + p[1] * math.sin(chi0), -p[0] * math.sin(chi0) + p[1] * math.cos(chi0))
    assert s_e(own.waypoints[-1]) == (pytest.approx(160.0, abs=0.02), pytest.approx(0.0, abs=0.02))
    starts = {t.name: s_e(t.position) for t in sc.targets}
    expected = {"Green": (35, -6), "Red": (95, 70), "Magenta": (125, -75), "Cyan": (230, 2)}
    for name, (s, e) in expected.items():
        assert starts[name] == (pytest.approx(s, abs=0.02), pytest.approx(e, abs=0.02)), name
    # without the opt-out the route through the peninsula is refused
    data = yaml.safe_load(RECONSTRUCTION.read_text())
    data["own_ship"].pop("allow_route_over_land")
    with pytest.raises(ValueError, match=r"route leg 0 .* crosses land for 13.0 m"):
        scenario_from_dict(data, land_checks="error")
    for method in METHODS:      # every method runs this file (--method) but the one tuned for 116 m ships
        if method == "informed_sbmpc":
            with pytest.raises(ValueError, match=r"method informed_sbmpc on ship 'OS': .* length 5 m outside"):
                load_scenario("smooth_000_reconstruction", method=method)
            continue
        with pytest.warns(ScenarioWarning):
            assert load_scenario("smooth_000_reconstruction", method=method).mpc.method == method


def test_reconstruction_targets_stay_in_water():
    from psbmpc_jax.sim.metrics import distance_to_land

    with pytest.warns(ScenarioWarning):
        sc = load_scenario("smooth_000_reconstruction")
    t = np.arange(0.0, sc.duration + 1.0)
    for tg in sc.targets:                    # straight lines at constant speed, as the simulator moves them
        p = tg.position + np.outer(t * tg.speed, [math.cos(tg.course), math.sin(tg.course)])
        assert distance_to_land(p, sc.polygons).min() > 5.0, tg.name


# ============================================================================================= the real modules
@pytest.mark.skipif(not HAVE_PLANNER, reason="psbmpc_jax.smooth.planner not there yet")
def test_sbmpc_init_with_the_planner():
    pytest.importorskip("psbmpc_jax.smooth.planner")
    r = simulate(scenario_from_dict(tiny(method="sbmpc_init")), batch="loop")
    assert r.method == "sbmpc_init" and np.isfinite(r.states).all() and np.isfinite(r.offsets[:, 0]).all()
    assert r.summary["device_calls"] == 2


@pytest.mark.skipif(not HAVE_PLANNER, reason="psbmpc_jax.smooth.planner not there yet")
@slow[0]
@slow[1]
def test_smooth_sbmpc_with_the_planner():
    pytest.importorskip("psbmpc_jax.smooth.planner")
    r = simulate(scenario_from_dict(tiny(method="smooth_sbmpc")), batch="loop")
    assert r.method == "smooth_sbmpc" and np.isfinite(r.states).all() and np.isfinite(r.offsets[:, 0]).all()
    assert r.summary["colav_diagnostics"]["updates"] == 4


@pytest.mark.skipif(not HAVE_REFINE, reason="psbmpc_jax.refine not there yet")
@slow[0]
@slow[1]
def test_psbmpc_refine_with_refine():
    pytest.importorskip("psbmpc_jax.refine")
    # float64: with 64-bit JAX on (conftest) and a float32 config the refinement's rollout mixes dtypes (a
    # refine.py matter, reported); the plain CLI (32-bit JAX) runs float32
    d = tiny(method="psbmpc_refine", config={"T": 20, "dtype": "float64"})
    r = simulate(scenario_from_dict(d), batch="loop")
    assert r.method == "psbmpc_refine" and np.isfinite(r.states).all() and np.isfinite(r.offsets[:, 0]).all()
    assert r.summary["colav_diagnostics"]["updates"] == 4


@slow[0]
@slow[1]
def test_smooth_sbmpc_with_the_step_adapter(monkeypatch):
    """The full Smooth-SBMPC step (init stage, corridor, DOCP, safeguard) in the closed loop, via the adapter."""
    monkeypatch.setattr(smooth, "smooth_planner_class", lambda: smooth.SmoothStepPlanner)
    # float64 as in tests/test_smooth_docp.py: float32 under 64-bit JAX (conftest) mixes dtypes in the DOCP
    d = tiny(method="smooth_sbmpc", config={"T": 20, "dtype": "float64"})
    r = simulate(scenario_from_dict(d), batch="loop")
    assert r.method == "smooth_sbmpc" and np.isfinite(r.states).all()
    info = r.colav_info
    assert np.all(info["violation"] <= 1e-3 + 1e-9) and np.all(info["cost"] <= info["warm_cost"] + 1e-6)


# ============================================================================================= refine block
def test_refine_block_is_the_update_period_by_default_and_block_s_overrides_it():
    from psbmpc_jax.refine import RefineSettings

    sc = scenario_from_dict(tiny(method="psbmpc_refine"))
    mpc = sc.mpc
    assert mpc.refine.block is None
    want = max(1, round(min(mpc.period, mpc.config.T) / mpc.config.dt))
    assert grid.refine_settings(mpc, RefineSettings).block == want
    d = tiny(method="psbmpc_refine", refine={"block_s": 2 * sc.mpc.config.dt})
    m2 = scenario_from_dict(d).mpc
    assert m2.refine.block == 2 * sc.mpc.config.dt
    assert grid.refine_settings(m2, RefineSettings).block == 2


@pytest.mark.parametrize("block_s, match", [(0, "block_s"), (-1, "block_s"), ("x", "block_s"),
                                            (1e6, "refined horizon"), (0.3, "multiple")])
def test_refine_block_s_errors(block_s, match):
    with pytest.raises(ValueError, match=match):
        scenario_from_dict(tiny(method="psbmpc_refine", refine={"block_s": block_s}))
