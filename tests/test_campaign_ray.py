"""The Ray engine (psbmpc-jax campaign --engine ray): the same rows as the local engine, each task a Ray remote
function on a local Ray with 2 CPUs.  Skipped when Ray is not installed (pip install "psbmpc-jax[cluster]");
the error without Ray is tested in test_campaign_definition.py."""

from __future__ import annotations

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
