"""The duration a caller will simulate, given at load (``load_scenario(..., duration_s=)``): validated as the
file's ``simulation.duration_s``, every duration-dependent check made for it (not for the file's), recorded in
``Scenario.overrides`` and the run's metrics; a campaign's ``duration_s`` is loaded this way by its definition and
its tasks, so a file whose own duration x chunk runs exceeds the simulation-time limit runs in a campaign that
cuts it short, and a campaign that lengthens a short file beyond the limit is refused naming the campaign's field.
No simulation runs here (the task's ``simulate`` is replaced)."""

from __future__ import annotations

import pytest
import yaml

from psbmpc_jax.campaign import definition as d
from psbmpc_jax.campaign.executor import run_task
from psbmpc_jax.campaign.store import prepare_folder
from psbmpc_jax.scenario import load_scenario
from psbmpc_jax.sim.output import scenario_info


def scenario_file(tmp_path, duration_s: float, name: str = "long") -> str:
    """Two ships head-on, 1 014 behaviours, a 0.5 s MPC period: about 2.1 s of simulation per simulated minute
    and run by the model; 86 400 s x 50 runs is days (above the 24 h limit), 60 s x 50 runs under 2 min."""
    d_ = {"name": name, "simulation": {"dt_s": 0.5, "duration_s": duration_s}, "monte_carlo": {"runs": 1},
          "mpc": {"preset": "nidelva", "update_period_s": 0.5},
          "own_ship": {"name": "OS", "position_m": [0, 0], "course_deg": 0, "speed_mps": 2,
                       "waypoints_m": [[0, 0], [100000, 0]]},
          "targets": [{"name": "TS1", "position_m": [2000, 10], "course_deg": 180, "speed_mps": 2,
                       "waypoints_m": [[2000, 10], [-90000, 10]]}]}
    p = tmp_path / f"{name}.yaml"
    p.write_text(yaml.safe_dump(d_))
    return str(p)


@pytest.fixture(autouse=True)
def default_limits(monkeypatch):
    for env in ("PSBMPC_SIMULATION_TIME_LIMIT", "PSBMPC_UPDATE_TIME_LIMIT"):
        monkeypatch.delenv(env, raising=False)


# ------------------------------------------------------------------------------------------------ load_scenario
def test_override_replaces_the_duration_and_is_recorded(tmp_path):
    path = scenario_file(tmp_path, 120.0)
    sc = load_scenario(path, duration_s=30, duration_setting="my duration")
    assert sc.duration == 30.0
    assert sc.overrides == {"simulation.duration_s": {"file": 120.0, "used": 30.0, "by": "my duration"}}
    assert scenario_info(sc)["overrides"] == sc.overrides and scenario_info(sc)["duration_s"] == 30.0
    plain = load_scenario(path)
    assert plain.duration == 120.0 and plain.overrides == {} and scenario_info(plain)["overrides"] == {}


@pytest.mark.parametrize("value, message", [
    (-5, r"my duration must be > 0, got -5"),
    (True, r"my duration must be a finite number"),
    ("60", r"my duration must be a finite number"),
    (float("nan"), r"my duration must be a finite number"),
    (10.25, r"my duration \(10\.25\) must be a multiple of simulation\.dt_s \(0\.5\)"),
    (0.25, r"simulation\.dt_s \(0\.5\) must be <= my duration \(0\.25\)"),
    (10 ** 9, r"my duration must be .*<="),
])
def test_override_is_validated_as_the_files_field(tmp_path, value, message):
    with pytest.raises(ValueError, match=message):
        load_scenario(scenario_file(tmp_path, 60.0), duration_s=value, duration_setting="my duration")


def test_shorter_override_loads_a_file_refused_for_its_own_duration(tmp_path):
    """The file's 86 400 s x 50 runs is days: refused naming simulation.duration_s; cut to 60 s it loads."""
    path = scenario_file(tmp_path, 86400.0)
    with pytest.raises(ValueError, match=r"simulation\.duration_s = 86400 / mpc\.update_period_s = 0\.5.*runs = 50.*"
                                         r"the simulation takes about .* days"):
        load_scenario(path, runs=50)
    sc = load_scenario(path, runs=50, duration_s=60, duration_setting="campaign field 'duration_s'")
    assert sc.duration == 60.0


def test_longer_override_is_refused_naming_it(tmp_path):
    path = scenario_file(tmp_path, 60.0)
    assert load_scenario(path, runs=50).duration == 60.0
    with pytest.raises(ValueError, match=r"campaign field 'duration_s' = 86400 / mpc\.update_period_s = 0\.5.*"
                                         r"campaign chunk_runs = 50.*the simulation takes about .* days"):
        load_scenario(path, runs=50, runs_setting="campaign chunk_runs", duration_s=86400,
                      duration_setting="campaign field 'duration_s'")


def test_speed_plan_is_read_against_the_files_duration(tmp_path):
    """A speed-plan entry after a shorter override's end is not an error (it never applies); one after the
    file's own end still is, whatever the override."""
    path = tmp_path / "plan.yaml"
    doc = yaml.safe_load(open(scenario_file(tmp_path, 120.0)).read())
    doc["own_ship"]["speed_plan"] = [{"t_s": 0, "speed_mps": 2}, {"t_s": 90, "speed_mps": 1}]
    path.write_text(yaml.safe_dump(doc))
    assert load_scenario(path, duration_s=30).duration == 30.0
    doc["own_ship"]["speed_plan"][1]["t_s"] = 150
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(ValueError, match=r"speed_plan\[1\]\.t_s \(150\) must be < simulation\.duration_s \(120\)"):
        load_scenario(path, duration_s=300)


# ------------------------------------------------------------------------------------------------ campaigns
def campaign(path, **changes):
    return d.definition_from_dict({"scenarios": [path], "seeds": [0], "runs": 100, "chunk_runs": 50, **changes},
                                  source="test.yaml")


def test_campaign_with_a_shorter_duration_accepts_a_long_file(tmp_path):
    """Refused by the previous code (the file's 86 400 s x 50 runs was checked before the campaign's 60 s)."""
    path = scenario_file(tmp_path, 86400.0)
    with pytest.raises(ValueError, match=r"simulation\.duration_s = 86400 .*campaign chunk_runs = 50"):
        d.resolve(campaign(path))
    resolved = d.resolve(campaign(path, duration_s=60))
    assert resolved["definition"]["duration_s"] == 60.0 and len(d.tasks(resolved)) == 2


def test_campaign_with_a_longer_duration_is_refused_naming_its_field(tmp_path):
    path = scenario_file(tmp_path, 60.0)
    d.resolve(campaign(path))
    with pytest.raises(ValueError) as err:
        d.resolve(campaign(path, duration_s=86400))
    msg = str(err.value)
    assert msg.startswith(f"campaign scenario {path!r}: {path}: campaign field 'duration_s' = 86400 / "
                          f"mpc.update_period_s = 0.5"), msg
    assert "campaign chunk_runs = 50" in msg and "days" in msg
    with pytest.raises(ValueError, match=r"campaign field 'duration_s' \(60\.25\) must be a multiple of "
                                         r"simulation\.dt_s"):
        d.resolve(campaign(path, duration_s=60.25))


def test_campaign_task_loads_with_the_campaigns_duration(tmp_path, monkeypatch):
    """A task simulates the scenario loaded with the campaign's duration (recorded in its overrides), even for a
    file whose own duration x the task's runs is above the limit."""
    path = scenario_file(tmp_path, 86400.0)
    resolved = d.resolve(campaign(path, duration_s=60))
    doc = prepare_folder(tmp_path / "camp", resolved)
    task = d.tasks(resolved)[0]
    seen = []

    class Stop(Exception):
        pass

    def fake_simulate(sc, **kw):
        seen.append((sc, kw))
        raise Stop

    monkeypatch.setattr("psbmpc_jax.sim.simulate", fake_simulate)
    with pytest.raises(Stop):
        run_task(tmp_path / "camp", task, doc)
    (sc, kw), = seen
    assert sc.duration == 60.0 and kw["runs"] == 50
    assert sc.overrides == {"simulation.duration_s": {"file": 86400.0, "used": 60.0,
                                                      "by": "campaign field 'duration_s'"}}


def test_campaign_command_line_names_the_duration_flag(tmp_path, capsys):
    from psbmpc_jax.apps.cli import main

    path = scenario_file(tmp_path, 60.0)
    rc = main(["campaign", "--out", str(tmp_path / "o"), "--scenarios", path, "--seeds", "0", "--runs", "100",
               "--chunk-runs", "50", "--duration", "86400"])
    err = capsys.readouterr().err
    assert rc == 2 and "campaign field 'duration_s' (--duration) = 86400 / mpc.update_period_s" in err, err
    assert not (tmp_path / "o").exists()
