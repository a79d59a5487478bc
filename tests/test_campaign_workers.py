"""The local engine with worker processes: the same rows as one process, and a worker killed (SIGKILL) while it
runs a task loses only that task -- the others finish, the lost one is reported, and a second call does it."""

from __future__ import annotations

import os
import pathlib
import signal
import threading
import time

import pandas as pd
import pytest
from processes import children

from psbmpc_jax.campaign import KEY_COLUMNS, comparable, definition_from_dict, run_campaign
from psbmpc_jax.campaign.store import RUNS_FILE

SPEC = {"name": "tiny", "scenarios": ["head_on", "crossing_give_way"], "methods": ["psbmpc"], "seeds": [3],
        "runs": 3, "chunk_runs": 1, "duration_s": 10}
N_TASKS = 2 * 3


def markers(folder) -> int:
    return len(list((folder / "tasks").glob("*.done.json"))) if (folder / "tasks").is_dir() else 0


def worker_pids() -> list[int]:
    """This process's campaign worker processes (children running psbmpc_jax.campaign.worker)."""
    return children(os.getpid(), b"psbmpc_jax.campaign.worker")


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    out = tmp_path_factory.mktemp("ref")
    assert not run_campaign(definition_from_dict(SPEC), out)["failed"]
    return pd.read_parquet(out / RUNS_FILE)


@pytest.mark.skipif(not pathlib.Path("/proc/self/stat").exists(), reason="needs /proc to find the worker processes")
def test_worker_killed_loses_only_its_task(reference, tmp_path):
    out = tmp_path / "w"
    killed = []

    def kill_one():
        deadline = time.monotonic() + 120
        while markers(out) < 2 and time.monotonic() < deadline:
            time.sleep(0.02)
        pids = worker_pids()
        if pids:
            os.kill(pids[0], signal.SIGKILL)
            killed.append(pids[0])

    th = threading.Thread(target=kill_one)
    th.start()
    first = run_campaign(definition_from_dict(SPEC), out, workers=2)
    th.join()
    assert killed, "no worker process was found to kill"
    assert len(first["failed"]) == 1, first["failed"]
    (why,) = first["failed"].values()
    assert "worker process died" in why and "signal 9" in why
    assert first["ran"] == N_TASKS - 1 and first["runs_parquet"] is None
    assert not (out / RUNS_FILE).exists()
    second = run_campaign(definition_from_dict(SPEC), out, workers=2)
    assert second["ran"] == 1 and second["skipped"] == N_TASKS - 1 and not second["failed"]
    got = pd.read_parquet(out / RUNS_FILE)
    assert len(got) == len(reference) and not got.duplicated(list(KEY_COLUMNS)).any()
    pd.testing.assert_frame_equal(comparable(got), comparable(reference))
