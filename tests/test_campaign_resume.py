"""A campaign whose process is killed (SIGKILL) after some tasks resumes where it stopped: the finished tasks
are kept, the rest run, and the table equals that of an uninterrupted campaign -- nothing lost, nothing
duplicated."""

from __future__ import annotations

import os
import pathlib
import signal
import subprocess
import sys
import time

import pandas as pd
import pytest

from psbmpc_jax.campaign import KEY_COLUMNS, comparable, definition_from_dict, run_campaign
from psbmpc_jax.campaign.store import RUNS_FILE

ROOT = pathlib.Path(__file__).resolve().parents[1]
SPEC = {"name": "tiny", "scenarios": ["head_on", "crossing_give_way"], "methods": ["psbmpc"], "seeds": [3],
        "runs": 4, "chunk_runs": 1, "duration_s": 10}
N_TASKS = 2 * 4


def markers(folder) -> int:
    return len(list((folder / "tasks").glob("*.done.json"))) if (folder / "tasks").is_dir() else 0


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    out = tmp_path_factory.mktemp("ref")
    assert not run_campaign(definition_from_dict(SPEC), out)["failed"]
    return pd.read_parquet(out / RUNS_FILE)


def test_campaign_process_killed_midway_then_resumed(reference, tmp_path):
    out = tmp_path / "k"
    cmd = [sys.executable, "-m", "psbmpc_jax.apps.cli", "campaign", "--out", str(out), "--quiet", "--name", "tiny",
           "--scenarios", *SPEC["scenarios"], "--methods", "psbmpc", "--seeds", "3", "--runs", "4",
           "--chunk-runs", "1", "--duration", "10"]
    env = {**os.environ, "PYTHONPATH": str(ROOT), "JAX_ENABLE_X64": "1"}     # 64-bit JAX, as in this process
    proc = subprocess.Popen(cmd, env=env, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 120
    while markers(out) < 2 and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    assert proc.poll() is None, proc.stderr.read().decode()[-2000:]
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    proc.stderr.close()
    done = markers(out)
    assert 2 <= done < N_TASKS and not (out / RUNS_FILE).exists()
    res = run_campaign(definition_from_dict(SPEC), out)
    assert res["skipped"] == done and res["ran"] == N_TASKS - done and not res["failed"]
    got = pd.read_parquet(out / RUNS_FILE)
    assert len(got) == len(reference) and not got.duplicated(list(KEY_COLUMNS)).any()
    pd.testing.assert_frame_equal(comparable(got), comparable(reference))


def test_damaged_task_file_runs_again(reference, tmp_path):
    """A task whose Parquet file no longer matches its done marker is not trusted: it runs again."""
    out = tmp_path / "d"
    run_campaign(definition_from_dict(SPEC), out)
    victim = sorted((out / "tasks").glob("*.parquet"))[0]
    victim.write_bytes(victim.read_bytes()[:-10])
    res = run_campaign(definition_from_dict(SPEC), out)
    assert res["ran"] == 1 and res["skipped"] == N_TASKS - 1
    pd.testing.assert_frame_equal(comparable(pd.read_parquet(out / RUNS_FILE)), comparable(reference))


def test_changed_scenario_file_or_code_fails_the_task_not_the_table(tmp_path, monkeypatch):
    """A scenario file edited after the campaign was defined, or a worker on another version of the code, makes
    its tasks fail with the reason; nothing is written for them."""
    from psbmpc_jax.campaign import definition as d
    from psbmpc_jax.campaign.executor import run_task
    from psbmpc_jax.campaign.store import prepare_folder

    sc = tmp_path / "mine.yaml"
    sc.write_text(d.scenario_path("head_on").read_text())
    resolved = d.resolve(definition_from_dict({**SPEC, "scenarios": [str(sc)], "runs": 1}))
    doc = prepare_folder(tmp_path / "c", resolved)
    task = d.tasks(resolved)[0]
    sc.write_text(sc.read_text() + "\n# edited\n")
    with pytest.raises(RuntimeError, match="scenario file .*mine.yaml changed since the campaign was defined"):
        run_task(tmp_path / "c", task, doc)
    sc.write_text(d.scenario_path("head_on").read_text())
    monkeypatch.setattr("psbmpc_jax.provenance.commit", lambda: "0" * 40)
    with pytest.raises(RuntimeError, match="rows would mix two versions of the code"):
        run_task(tmp_path / "c", task, doc)
    assert not list((tmp_path / "c" / "tasks").iterdir())
