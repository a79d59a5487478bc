"""Scenario plausibility checks (issue 11 items 4 and 8): ships on land, routes through land, ships at the same
start, absurd sizes, all refused by load_scenario before anything is simulated; float64 scenarios switch on
64-bit JAX; the mc / ce key comes from the seed.  Host side; nothing is compiled."""

from __future__ import annotations

import copy
import importlib.util
import os
import pathlib
import subprocess
import sys
import time
import warnings

import numpy as np
import pytest
import yaml

from psbmpc_jax import scenario_checks as sc
from psbmpc_jax.charts import NIDELVA_OWN_SHIP_UTM
from psbmpc_jax.scenario import builtin_scenarios, estimator_key, load_scenario, scenario_from_dict

REPO = pathlib.Path(__file__).resolve().parents[1]
SQUARE = [[-50, -50], [-50, 50], [50, 50], [50, -50]]            # land: 100 m x 100 m about (0, 0)


def base() -> dict:
    """Open water, own-ship at (0, 0) going north, one target 600 m ahead."""
    return {
        "name": "t",
        "simulation": {"dt_s": 0.5, "duration_s": 200},
        "mpc": {"preset": "nidelva", "update_period_s": 5},
        "own_ship": {"name": "os", "position_m": [-300, 0], "course_deg": 0, "speed_mps": 2,
                     "waypoints_m": [[-300, 0], [-300, 200], [300, 200]]},
        "targets": [{"name": "TS1", "position_m": [300, 0], "course_deg": 180, "speed_mps": 2,
                     "waypoints_m": [[300, 0], [300, -200], [-300, -200]]}],
    }


def with_land(d: dict, *polys) -> dict:
    d["chart"] = {"polygons_m": [SQUARE, *polys]}
    return d


def write(tmp_path, data: dict, name="s.yaml") -> pathlib.Path:
    p = tmp_path / name
    p.write_text(yaml.safe_dump(data))
    return p


def load(tmp_path, data):
    return load_scenario(write(tmp_path, data))


# ================================================================================================ land
def test_routes_around_the_land_load(tmp_path):
    s = load(tmp_path, with_land(base()))
    assert len(s.polygons) == 1


def test_own_ship_on_land_is_refused_fast_with_ship_and_depth(tmp_path):
    d = with_land(base())
    d["own_ship"].update(position_m=[0, 8], waypoints_m=[[0, 8], [0, 300]])
    with pytest.raises(ValueError, match=r"s.yaml: own-ship 'os' starts 42.0 m inside land \(chart.polygons_m\[0\]\) "
                                         r"at \(0.0, 8.0\)"):
        load(tmp_path, d)      # speed (< 1 s, before any compile) is measured on the CLI, not asserted here


def test_builtin_chart_start_on_land_fails_before_rdp(tmp_path):
    e, n, _ = NIDELVA_OWN_SHIP_UTM
    d = base()
    d.update(chart={"builtin": "trondheim", "rdp_eps_m": 2, "clip_m": 400}, targets=[])
    d["own_ship"] = {"name": "os", "position_utm": [e - 110, n - 115], "course_deg": 0, "speed_mps": 2}
    load_scenario("nidelva")                                    # the chart is cached: time the check alone
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match=r"own-ship 'os' starts 39.0 m inside land \(chart polygon 27, feature 27\)"):
        load(tmp_path, d)
    assert time.perf_counter() - t0 < 1.0


def test_target_start_waypoint_and_legs_on_land(tmp_path):
    d = with_land(base())
    d["targets"][0]["position_m"] = [-40, 0]
    d["targets"][0]["waypoints_m"] = [[-200, 0]]
    with pytest.raises(ValueError, match=r"target 'TS1' \(targets\[0\]\) starts 10.0 m inside land"):
        load(tmp_path, d)

    d = with_land(base())
    d["own_ship"]["waypoints_m"] = [[-300, 0], [0, 20], [300, 200]]
    with pytest.raises(ValueError, match=r"3 geometry problems: own-ship 'os': waypoint 1 \(0.0, 20.0\) lies 30.0 m "
                                         r"inside land .*route leg 0 \(-300.0, 0.0\) -> \(0.0, 20.0\) crosses land"):
        load(tmp_path, d)

    d = with_land(base())
    d["own_ship"]["waypoints_m"] = [[-300, -100], [300, -100], [300, 100]]
    d["targets"][0]["waypoints_m"] = [[300, 0], [300, 300]]
    d["own_ship"]["waypoints_m"] = [[-300, 0], [300, 0]]            # straight through the square
    with pytest.raises(ValueError, match=r"own-ship 'os': route leg 0 \(-300.0, 0.0\) -> \(300.0, 0.0\) crosses land "
                                         r"for 100.0 m \(chart.polygons_m\[0\]\)"):
        load(tmp_path, d)


def test_a_leg_touching_land_is_refused(tmp_path):
    d = with_land(base())
    d["own_ship"]["waypoints_m"] = [[-300, 50], [300, 50]]          # along the square's east edge
    d["own_ship"]["position_m"] = [-300, 50]
    with pytest.raises(ValueError, match=r"route leg 0 .* (touches land|crosses land for 100.0 m)"):
        load(tmp_path, d)


def test_default_route_through_land_says_so(tmp_path):
    d = with_land(base())
    del d["own_ship"]["waypoints_m"]
    with pytest.raises(ValueError, match=r"crosses land for 100.0 m .*the default route: straight along course_deg"):
        load(tmp_path, d)


def test_a_ship_that_never_moves_has_no_route_to_check(tmp_path):
    d = with_land(base())
    d["targets"][0].update(position_m=[200, -100], speed_mps=0, course_deg=90)
    del d["targets"][0]["waypoints_m"]                              # default route east through... nothing sailed
    d["chart"]["polygons_m"].append([[190, 0], [190, 10], [210, 10], [210, 0]])
    assert load(tmp_path, d).targets[0].speed == 0.0


def test_extension_past_the_last_waypoint_into_land_warns(tmp_path):
    d = with_land(base())
    d["own_ship"].update(position_m=[-300, 0], waypoints_m=[[-300, 0], [-200, 0]])   # 100 m, then 300 m more
    with pytest.warns(sc.ScenarioWarning, match=r"own-ship 'os' passes its last waypoint \(-200.0, 0.0\) and, holding "
                                               r"the last leg's course, sails 300 m more .* into land"):
        load(tmp_path, d)


def test_land_check_modes_of_scenario_from_dict():
    d = with_land(base())
    d["own_ship"]["waypoints_m"] = [[-300, 0], [300, 0]]
    with pytest.warns(sc.ScenarioWarning, match="crosses land"):
        scenario_from_dict(d)                                     # default: warn (in-code dicts)
    with pytest.raises(ValueError, match="crosses land"):
        scenario_from_dict(d, land_checks="error")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        scenario_from_dict(d, land_checks="off")
    with pytest.raises(ValueError, match="land_checks must be 'error', 'warn' or 'off'"):
        scenario_from_dict(d, land_checks="strict")


def test_far_away_land_warns():
    d = base()
    d["chart"] = {"polygons_m": [[[90000, 0], [90000, 10], [90010, 0]]]}
    with pytest.warns(sc.ScenarioWarning, match=r"the land is 90 km from every ship's route"):
        scenario_from_dict(d)


# ================================================================================================ ships
def test_two_ships_at_the_same_start(tmp_path):
    d = base()
    d["targets"][0]["position_m"] = [-300, 3]
    with pytest.raises(ValueError, match=r"own-ship 'os' and target 'TS1' \(targets\[0\]\) start 3.0 m apart, closer "
                                         r"than the collision distance 5 m"):
        scenario_from_dict(d, land_checks="off")                  # always an error, whatever the land checks
    d["collision_distance_m"] = 2
    assert scenario_from_dict(d).d_collision == 2.0


@pytest.mark.parametrize("mutate, match", [
    (lambda d: d["own_ship"].update(speed_kn=100, speed_mps=None) or d["own_ship"].pop("speed_mps"),
     r"own_ship.speed_kn \(100\) is 51.4444 m/s; at most 30 m/s \(58.3 kn\) allowed"),
    (lambda d: d["targets"][0].update(nominal_speed_mps=36), r"targets\[0\].nominal_speed_mps \(36\) is 36 m/s"),
    (lambda d: d["own_ship"].update(speed_plan=[{"t_s": 10, "speed_mps": 50}]), r"speed_plan\[0\].speed_mps \(50\)"),
    (lambda d: d["own_ship"].update(length_m=1000), r"own_ship.length_m must be <= 500, got 1000"),
    (lambda d: d["own_ship"].update(position_m=[1e6, 0], waypoints_m=[[1e6 + 10, 0]]),
     r"own_ship.position_m lies 1000 km from the scenario's origin; at most 200 km allowed"),
    (lambda d: d["targets"][0].update(waypoints_m=[[300, 0]] * 0 + [[300, float(k)] for k in range(1, 10002)]),
     r"targets\[0\].waypoints_m: 10001 waypoints; at most 10000 allowed"),
])
def test_ship_limits(mutate, match):
    d = base()
    mutate(d)
    with pytest.raises(ValueError, match=match):
        scenario_from_dict(d)


# ================================================================================================ sizes
@pytest.mark.parametrize("mutate, match", [
    (lambda d: d["simulation"].update(duration_s=1e9), r"simulation.duration_s must be <= 86400, got 1000000000.0"),
    (lambda d: d["simulation"].update(duration_s=10 ** 400),
     r"simulation.duration_s must be a finite number, got an integer with 401 digits"),
    (lambda d: d["simulation"].update(dt_s=0.01, duration_s=86400),
     r"duration_s / simulation.dt_s = 8.64e\+06 steps; at most 1000000 allowed"),
    (lambda d: d.update(monte_carlo={"runs": 10 ** 12}),
     r"monte_carlo.runs must be an integer <= 10000 \(allowed: 1..10000\), got 1000000000000"),
    (lambda d: d.update(monte_carlo={"runs": 10 ** 400}), r"monte_carlo.runs must be an integer <= 10000 .*401 digits"),
    (lambda d: d.update(monte_carlo={"seed": 2 ** 32}), r"monte_carlo.seed must be an integer <= 4294967295"),
    (lambda d: (d.update(monte_carlo={"runs": 10000}), d["simulation"].update(duration_s=86400)),
     r"monte_carlo.runs \(10000\) x 172801 steps .* x 2 ships need about 360.5 GiB of simulator memory; at most 2 GiB"),
    (lambda d: d.update(targets=[dict(d["targets"][0], name=f"T{k}", position_m=[300 + 10 * k, 0])
                                 for k in range(100)]), r"targets: 100 target ships; at most 99 allowed"),
    (lambda d: d["mpc"].update(n_ps=10 ** 12 + 1),
     r"mpc.n_ps must be an odd integer from 1 to 99, got 1000000000001"),
    (lambda d: d["mpc"].update(speed_factors=[[1, 0.5]] * 5, course_offsets_deg=[list(range(-50, 51, 5))] * 5),
     r"make 130691232 control behaviours .* at most 100000 allowed"),
    (lambda d: d["mpc"].update(config={"n_samples": 10 ** 12}), r"PlannerConfig.n_samples must be an integer in"),
    (lambda d: d["mpc"].update(config={"T": True}), r"mpc.config.T must be a number or a name, got True"),
    (lambda d: d["mpc"].update(params={"t_ts": 200}), r"Params.t_ts = 200 s puts maneuver 2 at 200 s, beyond the "
                                                      r"horizon PlannerConfig.T = 150 s"),
])
def test_size_limits(mutate, match):
    d = base()
    mutate(d)
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match=match):
        scenario_from_dict(d)
    assert time.perf_counter() - t0 < 5.0       # refused before any work (a 6 GB allocation would take far longer)


def test_memory_estimate_and_run_size():
    s = scenario_from_dict(base())
    assert sc.simulation_memory_bytes(400, 20, 2) == 8 * 20 * 401 * (4 * 2 + 20)
    assert sc.check_run_size(s) == sc.simulation_memory_bytes(400, 20, 2)
    with pytest.raises(ValueError, match=r"runs must be an integer in 1..10000"):
        sc.check_run_size(s, runs=20000)
    long = scenario_from_dict(dict(base(), simulation={"dt_s": 0.5, "duration_s": 86400}, monte_carlo={"runs": 1}))
    with pytest.raises(ValueError, match=r"5000 runs x 172801 steps x 2 ships need about 180.2 GiB"):
        sc.check_run_size(long, runs=5000)


# ================================================================================================ item 8
def test_float64_scenario_switches_on_x64_itself(tmp_path):
    d = base()
    d["mpc"]["config"] = {"dtype": "float64"}
    path = write(tmp_path, d)
    code = ("import jax; assert not jax.config.jax_enable_x64\n"
            "from psbmpc_jax.scenario import load_scenario\n"
            f"s = load_scenario({str(path)!r})\n"
            "assert s.mpc.config.dtype == 'float64' and jax.config.jax_enable_x64\n"
            "import jax.numpy as jnp; assert jnp.zeros(1).dtype == jnp.float64\n"
            "print('x64 ok')")
    env = {k: v for k, v in os.environ.items() if k != "JAX_ENABLE_X64"}
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, env=env)
    assert r.returncode == 0 and "x64 ok" in r.stdout, r.stderr[-2000:]


def test_estimator_key_comes_from_the_seed():
    import jax

    d = base()
    d["monte_carlo"] = {"seed": 7}
    assert estimator_key(scenario_from_dict(d)) is None                 # quadrature draws nothing
    d["mpc"]["config"] = {"estimator": "mc"}
    s = scenario_from_dict(d)
    k = estimator_key(s)
    np.testing.assert_array_equal(jax.random.key_data(k), jax.random.key_data(jax.random.key(7)))
    np.testing.assert_array_equal(jax.random.key_data(estimator_key(s, seed=3)),
                                  jax.random.key_data(jax.random.key(3)))


# ================================================================================================ built-ins, script
def test_every_builtin_scenario_passes_the_land_checks_without_warnings():
    """No built-in scenario warns, except the declared opt-out of the 000 reconstruction, whose route crosses the
    peninsula on purpose (SPEC_SEEDS §1.9): that one warns exactly once, naming the key."""
    for name in builtin_scenarios():
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            load_scenario(name)
        messages = [str(w.message) for w in caught]
        if name == "smooth_000_reconstruction":
            assert len(messages) == 1 and "allowed by own_ship.allow_route_over_land" in messages[0], messages
        else:
            assert messages == [], (name, messages)


def test_geometry_script_uses_the_library_and_reports_the_loader(tmp_path, capsys):
    spec = importlib.util.spec_from_file_location("check_scenario_geometry",
                                                  REPO / "tools" / "check_scenario_geometry.py")
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    assert script.route_clearances is sc.route_clearances
    good = write(tmp_path, with_land(base()), "good.yaml")
    bad_data = with_land(base())
    bad_data["own_ship"].update(position_m=[0, 8], waypoints_m=[[0, 8], [0, 300]])
    bad = write(tmp_path, bad_data, "bad.yaml")
    assert script.main([str(good)]) == 0
    assert "loader: ok" in capsys.readouterr().out
    assert script.main([str(good), str(bad)]) == 1
    out = capsys.readouterr().out
    assert "loader: REFUSED" in out and "own-ship 'os' starts 42.0 m inside land" in out
    res = sc.route_clearances(copy.deepcopy(bad_data))
    assert res["ships"]["os"]["start_in_water"] is False


def test_rdp_that_makes_a_polygon_self_intersect_is_refused_at_load():
    e, n, _ = NIDELVA_OWN_SHIP_UTM
    d = base()
    d.update(chart={"builtin": "trondheim", "rdp_eps_m": 50}, targets=[])
    d["own_ship"] = {"name": "os", "position_utm": [e, n], "course_deg": 180, "speed_mps": 1,
                     "waypoints_utm": [[e, n], [e - 2, n - 60]]}
    with pytest.raises(ValueError, match=r"chart: polygon [0-9]+ of the land as simplified \(rdp_eps_m = 50.0\) and "
                                         r"clipped is not a valid simple polygon .* use a smaller chart.rdp_eps_m"):
        scenario_from_dict(d, land_checks="off")


def test_loading_a_scenario_does_not_import_jax(tmp_path):
    """A bad scenario fails fast: the loader and the CLI's checks need NumPy and shapely only (importing JAX
    alone takes 1-2 s on 2 cores); Params becomes a pytree as soon as jax is imported, whoever imports it."""
    path = write(tmp_path, with_land(base()))
    code = ("import sys\n"
            "from psbmpc_jax.scenario import load_scenario\n"
            f"s = load_scenario({str(path)!r})\n"
            "assert 'jax' not in sys.modules, 'the scenario loader imported jax'\n"
            "import jax\n"
            "leaves = jax.tree_util.tree_leaves(s.mpc.params)\n"
            "assert len(leaves) > 10 and all(isinstance(v, float) for v in leaves), leaves\n"
            "print('ok')\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stdout.strip() == "ok", r.stderr[-2000:]


def test_cli_refuses_a_start_on_land_before_importing_jax(tmp_path):
    d = with_land(base())
    d["own_ship"]["position_m"] = [0, 0]
    d["own_ship"]["waypoints_m"] = [[0, 0], [-300, 200], [300, 200]]
    path = write(tmp_path, d)
    code = ("import sys\n"
            "from psbmpc_jax.apps.cli import main\n"
            f"try:\n    main(['run', {str(path)!r}])\n"
            "except SystemExit as e:\n    print('exit', e.code)\n"
            "print('jax' in sys.modules)\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.stdout.split() == ["exit", "2", "False"], (r.stdout, r.stderr[-2000:])
    assert "own-ship 'os' starts 50.0 m inside land" in r.stderr
