"""The one reader of the package's JSON documents (psbmpc_jax.safe_io.read_json_document) and its users:
errors name the file and what was expected, in the caller's error class."""

import json

import pytest

from psbmpc_jax.campaign.store import CampaignError, read_campaign, task_done
from psbmpc_jax.runfolder import RunFolderError, read_manifest
from psbmpc_jax.safe_io import json_schema, read_json_document


class _MyError(ValueError):
    pass


def _write(path, doc):
    path.write_text(doc if isinstance(doc, str) else json.dumps(doc), encoding="utf-8")
    return path


def test_reads_a_document_of_the_expected_schema(tmp_path):
    p = _write(tmp_path / "a.json", {"schema": "x/1", "v": 3})
    assert read_json_document(p, what="thing", schema="x/1") == {"schema": "x/1", "v": 3}
    assert read_json_document(p, what="thing") == {"schema": "x/1", "v": 3}
    assert read_json_document(_write(tmp_path / "b.json", [1, 2]), what="thing") == [1, 2]


def test_errors_name_the_file_and_what_was_expected(tmp_path):
    with pytest.raises(_MyError, match=r"missing\.json: cannot be read as a thing \(.*No such file"):
        read_json_document(tmp_path / "missing.json", what="thing", error=_MyError)
    bad = _write(tmp_path / "bad.json", "{not json")
    with pytest.raises(_MyError, match=r"bad\.json: cannot be read as a thing \(Expecting"):
        read_json_document(bad, what="thing", schema="x/1", error=_MyError)
    (tmp_path / "bin.json").write_bytes(b"\xff\xfe\x00")
    with pytest.raises(ValueError, match=r"bin\.json: cannot be read as a thing \(.*utf-8"):
        read_json_document(tmp_path / "bin.json", what="thing")
    other = _write(tmp_path / "o.json", {"schema": "x/2"})
    with pytest.raises(_MyError, match=r"o\.json: not a psbmpc-jax thing of this version \(schema 'x/2', "
                                       r"expected 'x/1'\); keep$"):
        read_json_document(other, what="thing", schema="x/1", error=_MyError, note="; keep")
    lst = _write(tmp_path / "l.json", [1])
    with pytest.raises(_MyError, match=r"schema None, expected 'x/1'"):
        read_json_document(lst, what="thing", schema="x/1", error=_MyError)


def test_missing_ok_and_foreign_prefix(tmp_path):
    assert read_json_document(tmp_path / "none.json", what="thing", missing_ok=True) is None
    (tmp_path / "dir.json").mkdir()
    assert read_json_document(tmp_path / "dir.json", what="thing", missing_ok=True) is None
    foreign = _write(tmp_path / "f.json", {"schema": "other-tool/7"})
    assert read_json_document(foreign, what="thing", schema="x/1", foreign_prefix="x/") is None
    assert read_json_document(_write(tmp_path / "l.json", [1]), what="thing", schema="x/1",
                              foreign_prefix="x/") is None
    ours_old = _write(tmp_path / "v0.json", {"schema": "x/0"})
    with pytest.raises(ValueError, match="schema 'x/0', expected 'x/1'"):          # our file, another version
        read_json_document(ours_old, what="thing", schema="x/1", foreign_prefix="x/")


def test_json_schema():
    assert json_schema({"schema": "a/1"}) == "a/1"
    assert json_schema({"schema": 3}) is None
    assert json_schema([1]) is None
    assert json_schema(None) is None


def test_campaign_and_manifest_readers_use_it(tmp_path):
    assert read_campaign(tmp_path) is None
    _write(tmp_path / "campaign.json", {"schema": "psbmpc-sim/1"})
    with pytest.raises(CampaignError, match=r"campaign\.json: not a psbmpc-jax campaign file of this version "
                                            r"\(schema 'psbmpc-sim/1', expected 'psbmpc-campaign/1'\); it is not "
                                            r"overwritten"):
        read_campaign(tmp_path)
    _write(tmp_path / "campaign.json", "[")
    with pytest.raises(CampaignError, match=r"campaign\.json: cannot be read as a campaign file"):
        read_campaign(tmp_path)
    _write(tmp_path / "manifest.json", {"schema": "somebody-else"})
    assert read_manifest(tmp_path, foreign="ignore") is None
    with pytest.raises(RunFolderError, match="not a psbmpc-jax run manifest of this version"):
        read_manifest(tmp_path)


def test_an_unreadable_done_marker_reruns_the_task(tmp_path, caplog):
    (tmp_path / "tasks").mkdir()
    (tmp_path / "tasks" / "t1.parquet").write_bytes(b"x")
    _write(tmp_path / "tasks" / "t1.done.json", "{")
    assert task_done(tmp_path, "t1", "abc") is False
    assert "t1.done.json: cannot be read as a done marker" in caplog.text and "runs again" in caplog.text
    _write(tmp_path / "tasks" / "t1.done.json", [1])
    assert task_done(tmp_path, "t1", "abc") is False


def test_an_unreadable_generation_manifest_is_named_with_the_remedy(tmp_path):
    from psbmpc_jax.scenario_generation import generate_encounters, write_scenarios

    batch = generate_encounters("head_on", 1, seed=1, validate=False)
    for text in ("{", "[1]", '{"files": 3}'):
        _write(tmp_path / "encounters.json", text)
        with pytest.raises(ValueError, match=r"encounters\.json: .*scenario-generation manifest.*; remove it or "
                                             r"choose another folder$"):
            write_scenarios(batch, tmp_path, overwrite=True, validate=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["encounters.json"]     # nothing written
