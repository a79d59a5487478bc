"""The Ray engine (psbmpc-jax campaign --engine ray): the same rows as the local engine, each task a Ray remote
function on a local Ray with 2 CPUs.  Skipped when Ray is not installed (pip install "psbmpc-jax[cluster]");
the error without Ray is tested in test_campaign_definition.py.  The issue's 200-run, 3-scenario, 2-method check
(local, Ray, killed workers resumed) runs with PSBMPC_SLOW_TESTS=1."""

from __future__ import annotations

import os
import signal
import threading
import time

import pandas as pd
import pytest

from psbmpc_jax.campaign import KEY_COLUMNS, comparable, definition_from_dict, run_campaign
from psbmpc_jax.campaign.store import RUNS_FILE

ray = pytest.importorskip("ray", reason="Ray is not installed: pip install \"psbmpc-jax[cluster]\" (or ray)")

SPEC = {"name": "tiny", "scenarios": ["head_on", "crossing_give_way"], "methods": ["psbmpc"], "seeds": [3],
        "runs": 2, "chunk_runs": 1, "duration_s": 10}


def test_ray_gives_the_rows_of_the_local_engine(tmp_path):
    local = run_campaign(definition_from_dict(SPEC), tmp_path / "local")
    assert not local["failed"]
    seen = []
    res = run_campaign(definition_from_dict(SPEC), tmp_path / "ray", engine="ray", workers=2,
                       on_done=lambda ok, tid, info: seen.append((ok, tid)))
    assert not res["failed"] and res["ran"] == 4
    assert sorted(seen) == sorted((True, t) for t in pd.read_parquet(tmp_path / "ray" / RUNS_FILE).task_id.unique())
    got = pd.read_parquet(tmp_path / "ray" / RUNS_FILE)
    assert not got.duplicated(list(KEY_COLUMNS)).any()
    pd.testing.assert_frame_equal(comparable(got), comparable(pd.read_parquet(tmp_path / "local" / RUNS_FILE)))


@pytest.mark.slow
@pytest.mark.skipif(not os.environ.get("PSBMPC_SLOW_TESTS"), reason="long (1 200 runs three times): PSBMPC_SLOW_TESTS=1")
def test_200_run_campaign_same_rows_local_ray_and_killed_workers(tmp_path):
    """The issue's check: a 200-run, 3-scenario, 2-method campaign (scenarios cut to 10 s) gives the same rows
    through the local engine, Ray with 2 workers, and local workers of which one is killed mid-way (SIGKILL) and
    the campaign resumed.  ``PSBMPC_CAMPAIGN_SLOW_RUNS`` sets the runs (default 200)."""
    from test_campaign_workers import markers, worker_pids

    runs = int(os.environ.get("PSBMPC_CAMPAIGN_SLOW_RUNS", "200"))
    from conftest import sbmpc_tuned_scenarios

    spec = {"name": "big", "scenarios": sbmpc_tuned_scenarios(tmp_path / "scenarios"),
            "methods": ["psbmpc", "sbmpc"], "seeds": [0], "runs": runs, "chunk_runs": max(1, runs // 4),
            "duration_s": 10}
    assert not run_campaign(definition_from_dict(spec), tmp_path / "local")["failed"]
    ref = comparable(pd.read_parquet(tmp_path / "local" / RUNS_FILE))
    assert len(ref) == 3 * 2 * runs * 2
    assert not run_campaign(definition_from_dict(spec), tmp_path / "ray", engine="ray", workers=2)["failed"]
    pd.testing.assert_frame_equal(comparable(pd.read_parquet(tmp_path / "ray" / RUNS_FILE)), ref)
    out = tmp_path / "killed"
    killed = []

    def kill_one():
        deadline = time.monotonic() + 1800
        while markers(out) < 3 and time.monotonic() < deadline:
            time.sleep(0.05)
        for pid in worker_pids():
            os.kill(pid, signal.SIGKILL)
            killed.append(pid)

    th = threading.Thread(target=kill_one)
    th.start()
    first = run_campaign(definition_from_dict(spec), out, workers=2)
    th.join()
    assert killed and first["failed"] and all("worker process died" in v for v in first["failed"].values())
    second = run_campaign(definition_from_dict(spec), out, workers=2)
    assert not second["failed"] and second["ran"] == len(first["failed"])
    pd.testing.assert_frame_equal(comparable(pd.read_parquet(out / RUNS_FILE)), ref)
