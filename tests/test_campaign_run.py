"""Campaigns end to end on tiny scenarios (10 s, 3 scenarios x 2 methods, in this process): one row per run x
ship with the metrics simulate() gives, rows that do not depend on the cut into tasks, and a second call that
skips the finished tasks.  Killed processes: test_campaign_resume.py, test_campaign_workers.py; Ray:
test_campaign_ray.py."""

from __future__ import annotations

import dataclasses
import tempfile

import pandas as pd
import pytest

from psbmpc_jax.campaign import KEY_COLUMNS, definition_from_dict, rows, run_campaign
from psbmpc_jax.campaign.store import RUNS_FILE, read_campaign
from psbmpc_jax.scenario import load_scenario
from psbmpc_jax.sim import simulate

from conftest import sbmpc_tuned_scenarios

# the three river scenarios with mpc.sbmpc tuned for their boats (the sbmpc defaults fit 30 m ships only)
SCENARIOS = sbmpc_tuned_scenarios(tempfile.mkdtemp(prefix="campaign_scenarios_"))
SPEC = {"name": "tiny", "scenarios": SCENARIOS, "methods": ["psbmpc", "sbmpc"],
        "seeds": [0], "runs": 3, "chunk_runs": 2, "duration_s": 10}
N_TASKS = 3 * 2 * 2


def comparable(path) -> pd.DataFrame:
    return rows.comparable(pd.read_parquet(path))


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    out = tmp_path_factory.mktemp("ref")
    res = run_campaign(definition_from_dict(SPEC), out)
    assert not res["failed"] and res["ran"] == N_TASKS
    return out


def test_rows_are_one_per_run_and_ship_and_match_simulate(reference):
    df = pd.read_parquet(reference / RUNS_FILE)
    assert len(df) == 3 * 2 * 3 * 2                    # scenarios x methods x runs x ships
    assert not df.duplicated(list(KEY_COLUMNS)).any()
    assert list(df.columns[:5]) == list(KEY_COLUMNS)
    assert set(df.method) == {"psbmpc", "sbmpc"} and sorted(set(df.run)) == [0, 1, 2]
    own, tgt = df[df.own_ship], df[~df.own_ship]
    assert own.target_min_distance_m.isna().all() and tgt.target_min_distance_m.notna().all()
    for col in ("colregs_S_safety", "colregs_P_delay", "colregs_situation", "run_collision", "ship_stops"):
        assert col in df.columns
    # run 2 of crossing_give_way / sbmpc as one simulate() call would give it
    sc = dataclasses.replace(load_scenario(SCENARIOS[1], method="sbmpc"), duration=10.0)
    res = simulate(sc, runs=1, seed=0, run_start=2)
    row = df[(df.scenario == "crossing_give_way") & (df.method == "sbmpc") & (df.run == 2) & (df.ship == "TS1")]
    assert row.target_min_distance_m.item() == res.metrics[0]["targets"][0]["min_distance_m"]
    assert row.run_path_deviation_max_m.item() == res.metrics[0]["path_deviation_max_m"]
    doc = read_campaign(reference)
    assert doc["complete"] and doc["rows"] == len(df) and len(doc["tasks"]) == N_TASKS


def test_rows_do_not_depend_on_the_cut_into_tasks(reference, tmp_path):
    res = run_campaign(definition_from_dict({**SPEC, "chunk_runs": 3}), tmp_path / "c")
    assert res["tasks"] == 3 * 2
    pd.testing.assert_frame_equal(comparable(tmp_path / "c" / RUNS_FILE), comparable(reference / RUNS_FILE))


def test_second_call_skips_finished_tasks(reference):
    res = run_campaign(definition_from_dict(SPEC), reference)
    assert res["skipped"] == N_TASKS and res["ran"] == 0 and not res["failed"]


def test_trajectories_are_stored_on_request(tmp_path):
    spec = {**SPEC, "scenarios": [SCENARIOS[1]], "methods": ["sbmpc"], "trajectories": True}
    res = run_campaign(definition_from_dict(spec), tmp_path / "t")
    assert not res["failed"]
    tr = pd.read_parquet(tmp_path / "t" / "trajectories.parquet")
    sim = simulate(dataclasses.replace(load_scenario(SCENARIOS[1], method="sbmpc"), duration=10.0),
                   runs=3, seed=0)
    n_steps = sim.states.shape[2]
    assert len(tr) == 3 * 2 * n_steps
    assert not tr.duplicated(["run", "ship", "t_s"]).any()
    one = tr[(tr.run == 2) & (tr.ship == "TS1")].sort_values("t_s")
    assert one.north_m.tolist() == sim.states[2, 1, :, 0].tolist()
    assert one.speed_mps.tolist() == sim.states[2, 1, :, 3].tolist()
    assert read_campaign(tmp_path / "t")["trajectories_parquet"]["rows"] == len(tr)
