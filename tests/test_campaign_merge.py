"""psbmpc-jax merge: campaign folders combine into one table; a row key found twice is refused naming it, as a
duplicate (identical rows) or a conflict (different values); incomplete or changed inputs are refused."""

from __future__ import annotations

import json
import shutil

import pandas as pd
import pytest

from psbmpc_jax.apps.cli import main
from psbmpc_jax.campaign import CampaignError, definition_from_dict, merge_folders, run_campaign
from psbmpc_jax.campaign.store import CAMPAIGN_FILE, RUNS_FILE
from psbmpc_jax.safe_io import OutputError

SPEC = {"scenarios": ["head_on"], "methods": ["psbmpc"], "runs": 2, "chunk_runs": 2, "duration_s": 10}


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    base = tmp_path_factory.mktemp("m")
    for name, changes in (("a", {"seeds": [0], "trajectories": True}), ("b", {"seeds": [1], "trajectories": True}),
                          ("c", {"seeds": [0], "duration_s": 15})):
        assert not run_campaign(definition_from_dict({**SPEC, "name": name, **changes}), base / name)["failed"]
    return base


def test_merge_combines_rows(folders, tmp_path, capsys):
    rc = main(["merge", str(folders / "a"), str(folders / "b"), "--out", str(tmp_path / "ab")])
    assert rc == 0, capsys.readouterr().err
    got = pd.read_parquet(tmp_path / "ab" / RUNS_FILE)
    a, b = (pd.read_parquet(folders / n / RUNS_FILE) for n in "ab")
    assert len(got) == len(a) + len(b) == 8
    assert sorted(set(got.seed)) == [0, 1] and set(got.campaign) == {"a", "b"}
    doc = json.loads((tmp_path / "ab" / CAMPAIGN_FILE).read_text())
    assert doc["kind"] == "merge" and doc["rows"] == 8 and len(doc["sources"]) == 2
    traj = pd.read_parquet(tmp_path / "ab" / "trajectories.parquet")         # both inputs have trajectories
    assert len(traj) == sum(len(pd.read_parquet(folders / n / "trajectories.parquet")) for n in "ab")
    assert doc["trajectories_parquet"]["rows"] == len(traj)
    # a merge is itself an input of a merge, but not a folder to write into without --force
    assert main(["merge", str(folders / "a"), str(folders / "b"), "--out", str(tmp_path / "ab")]) == 2
    assert "earlier merge; pass --force" in capsys.readouterr().err
    assert main(["merge", str(folders / "a"), str(folders / "b"), "--out", str(tmp_path / "ab"), "--force"]) == 0


def test_duplicate_rows_are_refused(folders, tmp_path):
    shutil.copytree(folders / "a", tmp_path / "a2")
    with pytest.raises(CampaignError, match=r"occur in more than one folder.*'seed': 0, 'run': 0.*identical "
                                            r"\(duplicate\)"):
        merge_folders([folders / "a", tmp_path / "a2"], tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_conflicting_rows_are_refused(folders, tmp_path):
    with pytest.raises(CampaignError, match=r"different values \(conflict\)"):
        merge_folders([folders / "a", folders / "c"], tmp_path / "out")


def test_bad_inputs_are_refused(folders, tmp_path):
    with pytest.raises(OutputError, match="is one of the folders to merge"):
        merge_folders([folders / "a", folders / "b"], folders / "a")
    with pytest.raises(CampaignError, match="no campaign.json"):
        merge_folders([folders / "a", tmp_path], tmp_path / "out")
    bad = tmp_path / "bad"
    shutil.copytree(folders / "b", bad)
    (bad / RUNS_FILE).write_bytes((bad / RUNS_FILE).read_bytes() + b"x")
    with pytest.raises(CampaignError, match="SHA-256 differs"):
        merge_folders([folders / "a", bad], tmp_path / "out")
    doc = json.loads((bad / CAMPAIGN_FILE).read_text())
    (bad / CAMPAIGN_FILE).write_text(json.dumps({**doc, "complete": False}))
    with pytest.raises(CampaignError, match="not complete"):
        merge_folders([folders / "a", bad], tmp_path / "out")
