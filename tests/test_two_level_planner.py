"""The two-level method (psbmpc_jax/two_level/planner.py, psbmpc_jax/methods/two_level.py): one update's
command is the upper level's plus the SB-MPC's modification; a head-on target in a channel makes the first
manoeuvre a starboard one; the static circle and the corridor hold in a short closed loop; ``mpc.two_level`` in
the scenario file (good and bad keys); the simulator applies the absolute commands."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from psbmpc_jax.methods.sbmpc_family import SbmpcSettings
from psbmpc_jax.params import PlannerConfig
from psbmpc_jax.methods.two_level_settings import TwoLevelSpec
from psbmpc_jax.scenario import scenario_from_dict
from psbmpc_jax.sim import simulate
from psbmpc_jax.two_level.path_mpc import PathMpcSettings, rk4_step
from psbmpc_jax.two_level.planner import TwoLevelPlanner, TwoLevelSettings
from psbmpc_jax.status import Status

# a straight channel 60 m wide heading north (banks at east +-30 m), a rock on the route at 120 m
BANKS = [np.array([[-50.0, 30.0], [400.0, 30.0], [400.0, 60.0], [-50.0, 60.0]]),
         np.array([[-50.0, -30.0], [400.0, -30.0], [400.0, -60.0], [-50.0, -60.0]])]
SETTINGS = TwoLevelSettings(
    path=PathMpcSettings(N_p=15, U_max=3.0, r_os=3.0), corridor_half_width=25.0, corridor_sample=2.0,
    corridor_radius=60.0, corridor_margin=5.0, r_accept=5.0, d_critical=20.0, d_close=20.0, zeta_d_safe=3.0,
    sbmpc=SbmpcSettings(d_safe=15.0, d_cl=100.0), plan_stride=3)
CONFIG = PlannerConfig(T=40.0, dt=1.0, grounding_mode="grid", grid_spacing=1.0, dtype="float64")


@pytest.fixture(scope="module")
def planner():
    return TwoLevelPlanner([[0.0, 0.0], [300.0, 0.0]], BANKS, circles=[{"center_m": [120.0, 0.0], "radius_m": 6.0}],
                           U_ref=2.0, settings=SETTINGS, config=CONFIG)


def test_command_is_the_upper_level_plus_the_sbmpc_modification(planner):
    plan, state = planner.plan([0.0, 0.0, 0.0, 2.0], np.zeros((0, 4)))
    assert plan.chi_c == pytest.approx(math.remainder(plan.chi_d + plan.chi_m, 2 * math.pi), abs=1e-12)
    assert plan.U_c == pytest.approx(plan.U_d * plan.U_m, rel=1e-12)
    assert plan.chi_m == 0.0 and plan.U_m == 1.0                   # open channel, no target: no modification
    assert int(plan.path.status) in (Status.OK, Status.MAX_ITER) and float(plan.path.violation) <= 1e-3
    assert state.j == 0 and state.u_plan.shape == (15, 2)
    assert plan.nominal_route[0].tolist() == [0.0, 0.0] and len(plan.nominal_route) == 2      # "hold": straight on
    chi = math.atan2(*(plan.nominal_route[1] - plan.nominal_route[0])[::-1])
    assert chi == pytest.approx(plan.chi_d, abs=1e-9)


def test_nominal_plan_follows_the_upper_levels_positions(planner):
    """C-001-7 as the SPEC chose it (``nominal="plan"``): the SB-MPC's route runs through the planned positions."""
    import dataclasses

    p2 = TwoLevelPlanner([[0.0, 0.0], [300.0, 0.0]], BANKS, U_ref=2.0,
                         settings=dataclasses.replace(SETTINGS, nominal="plan"), config=CONFIG)
    plan, _ = p2.plan([0.0, 0.0, 0.3, 2.0], np.zeros((0, 4)))
    route = plan.nominal_route
    assert len(route) == 15 // 3 + 2
    np.testing.assert_allclose(route[1:-1], np.asarray(plan.path.x)[::3][1:, :2], atol=1e-9)


def test_head_on_target_first_manoeuvre_is_to_starboard(planner):
    """A target 100 m ahead on a reciprocal course: the SB-MPC's first non-zero course modification is to
    starboard (positive) and the own-ship passes it at a distance."""
    own, tg = np.array([0.0, 0.0, 0.0, 2.0]), np.array([[100.0, -2.0, math.pi, 1.5]])
    state, first, d_min = None, None, np.inf
    for _ in range(40):
        plan, state = planner.plan(own, tg, state)
        if first is None and plan.chi_m != 0.0:
            first = plan.chi_m
        own = np.asarray(rk4_step(own, np.array([plan.chi_c, plan.U_c]), 1.0, 3.0, 5.0))
        tg[0, :2] += tg[0, 3] * np.array([math.cos(tg[0, 2]), math.sin(tg[0, 2])])
        d_min = min(d_min, float(np.hypot(*(own[:2] - tg[0, :2]))))
    assert first is not None and first > 0
    assert d_min > 10.0
    assert np.all(np.abs(plan.target_paths[0, :, 1]) < 30.0)        # the target's prediction stays in the water


def test_bad_settings_name_the_field():
    with pytest.raises(ValueError, match="TwoLevelSettings.nominal"):
        TwoLevelSettings(nominal="mpc")
    with pytest.raises(ValueError, match="TwoLevelSettings.beta"):
        TwoLevelSettings(beta=4.0)
    with pytest.raises(ValueError, match="U_ref"):
        TwoLevelPlanner([[0.0, 0.0], [10.0, 0.0]], U_ref=0.0)
    with pytest.raises(ValueError, match="waypoints"):
        TwoLevelPlanner([[0.0, 0.0]], U_ref=1.0)


def test_bad_plan_inputs_name_the_argument(planner):
    with pytest.raises(ValueError, match="own_state must be 4 finite numbers"):
        planner.plan([0.0, 0.0, float("nan"), 1.0], np.zeros((0, 4)))
    with pytest.raises(ValueError, match=r"targets must be a finite \[I, 4\] array"):
        planner.plan([0.0, 0.0, 0.0, 1.0], np.zeros((2, 3)))
    with pytest.raises(ValueError, match=r"targets must be a finite \[I, 4\] array"):
        planner.plan([0.0, 0.0, 0.0, 1.0], [[10.0, 0.0, np.inf, 1.0]])


# ============================================================================================ scenario + simulator
TINY = {
    "name": "tiny_two_level", "description": "A channel, one target head-on: the two-level method",
    "simulation": {"dt_s": 1, "duration_s": 30}, "monte_carlo": {"runs": 1, "seed": 2},
    "collision_distance_m": 3,
    "mpc": {"preset": "nidelva", "update_period_s": 1, "method": "two_level", "sbmpc": {"d_safe_m": 15, "d_cl_m": 100},
            "two_level": {"N_p": 15, "dt_s": 1, "U_max_mps": 3, "r_os_m": 3, "r_accept_m": 5, "sbmpc_T_s": 40,
                          "sbmpc_dt_s": 1, "plan_stride": 3,
                          "corridor": {"half_width_m": 25, "sample_m": 2, "radius_m": 60, "margin_m": 5},
                          "prediction": {"beta_deg": 5, "d_critical_m": 20},
                          "zeta": {"d_close_m": 20, "d_safe_m": 3},
                          "static_obstacles": [{"center_m": [150, 0], "radius_m": 5}]}},
    "sensor": {"position_std_m": 0.3, "period_s": 1, "filter_R_scale": 1, "sigma_a_mps2": 0.05, "U_max_mps": 4},
    "chart": {"polygons_m": [b.tolist() for b in BANKS]},
    "own_ship": {"name": "OS", "position_m": [0, 0], "course_deg": 0, "speed_mps": 2, "waypoints_m": [[300, 0]],
                 "T_chi_s": 3, "T_U_s": 5, "length_m": 4, "width_m": 2},
    "targets": [{"name": "H", "position_m": [80, -2], "course_deg": 180, "speed_mps": 1.5,
                 "waypoints_m": [[-100, -2]], "length_m": 4, "width_m": 2}],
}


def test_scenario_keys_parse_into_the_spec():
    spec = scenario_from_dict(copy.deepcopy(TINY)).mpc.two_level
    assert spec.N_p == 15 and spec.U_max == 3.0 and spec.sbmpc_T == 40.0 and spec.sbmpc_dt == 1.0
    assert spec.corridor_half_width == 25.0 and spec.corridor_margin == 5.0 and spec.circle_margin == 2.0
    assert spec.beta == pytest.approx(math.radians(5)) and spec.d_close == 20.0 and spec.zeta_d_safe == 3.0
    assert spec.static_obstacles == (((150.0, 0.0), 5.0),)
    assert scenario_from_dict({**copy.deepcopy(TINY), "mpc": {**TINY["mpc"], "two_level": {}}}).mpc.two_level \
        == TwoLevelSpec()


@pytest.mark.parametrize("key,value,match", [
    ("N_p", 0, "mpc.two_level.N_p"),
    ("chi_span_deg", 200, "chi_span_deg must be in"),
    ("Q_diag", [1, 2], "Q_diag must be a list of 4"),
    ("nominal", "mpc", "mpc.two_level.nominal"),
    ("corridor", {"width_m": 3}, "mpc.two_level.corridor"),
    ("prediction", {"beta_deg": 0}, "prediction.beta_deg"),
    ("zeta", {"shape": "abs"}, "zeta.shape"),
    ("static_obstacles", [{"center_m": [1, 2]}], r"static_obstacles\[0\]"),
    ("static_obstacles", [{"center_m": [1], "radius_m": 2}], r"static_obstacles\[0\].center_m"),
    ("sbmpc_T_s", 40.5, "sbmpc_T_s"),
])
def test_bad_scenario_keys_name_the_key(key, value, match):
    d = copy.deepcopy(TINY)
    d["mpc"]["two_level"][key] = value
    with pytest.raises(ValueError, match=match):
        scenario_from_dict(d)


def test_targets_cannot_run_two_level():
    d = copy.deepcopy(TINY)
    d["targets"][0]["colav"] = "two_level"
    with pytest.raises(ValueError, match="two_level"):
        scenario_from_dict(d)


def test_closed_loop_applies_the_absolute_commands_and_keeps_clear():
    r = simulate(scenario_from_dict(copy.deepcopy(TINY)), batch="loop")
    m = r.metrics[0]
    assert not m["collision"] and not m["grounding"]
    own = r.states[0, 0]                                           # [K+1, 4]
    assert np.all(np.hypot(own[:, 0] - 150.0, own[:, 1]) >= 5.0 + 3.0 - 0.5)   # circle + r_os (one-step slack)
    assert np.max(np.abs(own[:, 1])) < 30.0 - 3.0                  # inside the channel
    assert r.method == "two_level" and r.colav_info is not None
    assert np.nanmax(r.colav_info["violation"]) <= 1e-3
    off = r.offsets[0, 0]                                          # the SB-MPC's (U_m, chi_m) per update
    assert np.any(off[:, 1] > 0) and not np.any(off[:, 1] < 0)     # starboard modifications only (head-on)


def test_seed_001_scenarios_are_the_generators_output_and_load():
    import pathlib
    import subprocess
    import sys

    from psbmpc_jax.scenario import load_scenario

    repo = pathlib.Path(__file__).resolve().parents[1]
    gen = subprocess.run([sys.executable, str(repo / "tools" / "make_mahipala2023.py"), "--check"],
                         capture_output=True, text=True)
    assert gen.returncode == 0, gen.stdout + gen.stderr
    counts = {}
    for name in ("1_reference", "2_head_on", "3_crossing", "4_head_on_crossing", "5_overtaking",
                 "6_overtaking_crossing", "7_combined"):
        sc = load_scenario(f"mahipala2023_{name}")
        assert sc.mpc.method == "two_level" and sc.runs >= 10 and sc.polygons
        assert len(sc.mpc.two_level.static_obstacles) == 2
        counts[name] = len(sc.targets)
    assert counts == {"1_reference": 0, "2_head_on": 1, "3_crossing": 1, "4_head_on_crossing": 2, "5_overtaking": 1,
                      "6_overtaking_crossing": 2, "7_combined": 3}


def test_sbmpc_every_holds_the_modification_between_solves():
    import dataclasses

    p = TwoLevelPlanner([[0.0, 0.0], [300.0, 0.0]], BANKS, U_ref=2.0,
                        settings=dataclasses.replace(SETTINGS, sbmpc_every=3), config=CONFIG)
    own, tg = np.array([0.0, 0.0, 0.0, 2.0]), np.array([[60.0, -1.0, math.pi, 1.5]])
    plans, state = [], None
    for _ in range(4):
        plan, state = p.plan(own, tg, state)
        plans.append(plan)
    assert [pl.sbmpc is not None for pl in plans] == [True, False, False, True]
    for pl in plans[1:3]:
        assert (pl.chi_m, pl.U_m) == (plans[0].chi_m, plans[0].U_m)
        assert pl.chi_c == pytest.approx(math.remainder(pl.chi_d + pl.chi_m, 2 * math.pi), abs=1e-12)
    with pytest.raises(ValueError, match="sbmpc_every"):
        TwoLevelSettings(sbmpc_every=0)


def test_scenario_defaults_are_the_library_defaults():
    """mpc.two_level's defaults (TwoLevelSpec, kept free of JAX for the scenario loader) equal the library's
    (TwoLevelSettings, PathMpcSettings), except sbmpc_every: scenario files use SPEC §2.4's 5 (MPC every 1 s,
    SB-MPC every 5 s), the library solves both levels at every call unless told otherwise."""
    spec, lib, path = TwoLevelSpec(), TwoLevelSettings(), PathMpcSettings()
    for name in ("N_p", "dt", "Q", "M", "chi_span", "U_max", "r_os"):
        assert getattr(spec, name) == getattr(path, name), name
    names = {"compare": "prediction_compare", "zeta_shape": "zeta_shape"}
    for name in ("corridor_half_width", "corridor_sample", "corridor_radius", "corridor_margin", "circle_margin",
                 "r_accept", "beta", "d_critical", "compare", "eta1", "eta2", "d_close", "zeta_d_safe", "zeta_shape",
                 "nominal", "plan_stride"):
        assert getattr(spec, name) == getattr(lib, names.get(name, name)), name
    assert (spec.sbmpc_every, lib.sbmpc_every) == (5, 1)
