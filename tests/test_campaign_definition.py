"""Campaign definitions: strict validation naming the field, the cut into tasks, the hash and what changed, and
the command line's errors (no simulation: fast)."""

from __future__ import annotations

import sys

import pytest

from psbmpc_jax.apps.cli import main
from psbmpc_jax.campaign import definition as d
from psbmpc_jax.campaign.store import CampaignError, prepare_folder

BASE = {"scenarios": ["head_on"], "seeds": [0], "runs": 5}


def defn(**changes):
    return d.definition_from_dict({**BASE, **changes}, source="test.yaml")


@pytest.mark.parametrize("changes,field", [
    ({"colour": 1}, "unknown campaign field(s) colour"),
    ({"runs": 0}, "'runs' must be an integer >= 1"),
    ({"runs": 1.5}, "'runs'"),
    ({"runs": None}, "'runs' is required"),
    ({"seeds": [-1]}, "'seeds[0]'"),
    ({"seeds": [1, 1]}, "'seeds' lists a seed more than once"),
    ({"seeds": []}, "'seeds'"),
    ({"chunk_runs": 0}, "'chunk_runs'"),
    ({"chunk_runs": 10_001}, "'chunk_runs'"),
    ({"duration_s": -3}, "'duration_s'"),
    ({"duration_s": True}, "'duration_s'"),
    ({"batch": "gpu"}, "'batch' must be one of auto, vmap, loop"),
    ({"scenarios": []}, "'scenarios' must be a non-empty list"),
    ({"scenarios": ["head_on", "head_on"]}, "'scenarios' lists head_on more than once"),
    ({"methods": [3]}, "'methods[0]'"),
    ({"name": "a b"}, "'name'"),
])
def test_bad_fields_are_refused_naming_them(changes, field):
    with pytest.raises(ValueError) as err:
        defn(**changes)
    assert field in str(err.value)
    assert "test.yaml" in str(err.value)


def test_tasks_cover_every_run_once_in_chunks():
    resolved = d.resolve(defn(runs=7, chunk_runs=3, seeds=[0, 4], methods=["psbmpc", "sbmpc_init"]))
    ts = d.tasks(resolved)
    assert len(ts) == 2 * 2 * 3
    for m in ("psbmpc", "sbmpc_init"):
        for seed in (0, 4):
            mine = [t for t in ts if t.method == m and t.seed == seed]
            assert [(t.run_start, t.runs) for t in mine] == [(0, 3), (3, 3), (6, 1)]
    assert ts[0].task_id == "head_on__psbmpc__s0__r0-3"
    assert len({t.task_id for t in ts}) == len(ts)


def test_resolve_refuses_bad_scenarios_and_methods(tmp_path):
    with pytest.raises(ValueError, match="campaign field 'scenarios'.*not found"):
        d.resolve(defn(scenarios=[str(tmp_path / "missing.yaml")]))
    with pytest.raises(ValueError, match="unknown built-in scenario"):
        d.resolve(defn(scenarios=["head_onn"]))
    with pytest.raises(ValueError, match="with method 'nosuch'"):
        d.resolve(defn(methods=["nosuch"]))
    with pytest.raises(ValueError, match="both run psbmpc on scenario 'head_on'"):
        d.resolve(defn(methods=[None, "psbmpc"]))
    with pytest.raises(ValueError, match="'duration_s'.*multiple"):
        d.resolve(defn(duration_s=10.25))


def test_definition_file_relative_paths_and_overrides(tmp_path):
    sc = tmp_path / "cases" / "mine.yaml"
    sc.parent.mkdir()
    sc.write_text((d.scenario_path("head_on")).read_text().replace("name: head_on", "name: mine"))
    f = tmp_path / "study.yaml"
    f.write_text("scenarios: [cases/mine.yaml]\nseeds: 3\nruns: 10\n")
    got = d.load_definition(f, {"runs": 4, "seeds": None})
    assert got.name == "study" and got.runs == 4 and got.seeds == (3,)
    assert got.scenarios == (str(sc.resolve()),)
    r = d.resolve(got)
    assert r["definition"]["scenarios"][0]["name"] == "mine"


def test_changed_definition_is_refused_naming_the_change(tmp_path):
    out = tmp_path / "c"
    a = d.resolve(defn())
    prepare_folder(out, a)
    assert prepare_folder(out, a)["definition_sha256"] == d.definition_hash(a)     # the same: resumed
    b = d.resolve(defn(runs=6))
    with pytest.raises(CampaignError, match=r"definition.runs: 5 -> 6.*--force"):
        prepare_folder(out, b)
    (out / "tasks" / "x.parquet").write_bytes(b"old")
    (out / "notes.txt").write_text("mine")
    doc = prepare_folder(out, b, force=True)
    assert doc["definition_sha256"] == d.definition_hash(b)
    assert not (out / "tasks" / "x.parquet").exists()
    assert (out / "notes.txt").read_text() == "mine"             # not a campaign file: left alone


def test_foreign_folder_is_refused(tmp_path):
    (tmp_path / "f").mkdir()
    (tmp_path / "f" / "data.csv").write_text("1")
    with pytest.raises(CampaignError, match="not empty and not a campaign folder"):
        prepare_folder(tmp_path / "f", d.resolve(defn()), force=True)


def test_cli_errors(tmp_path, capsys, monkeypatch):
    with pytest.raises(SystemExit) as ex:
        main(["campaign", "--out", str(tmp_path / "o"), "--scenarios", "head_on", "--seeds", "0"])
    assert ex.value.code == 2
    assert "'runs' is required" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["campaign", "--out", str(tmp_path / "o"), "--scenarios", "head_on", "--seeds", "0", "--runs", "2",
              "--ray-address", "auto"])
    assert "need --engine ray" in capsys.readouterr().err
    monkeypatch.setitem(sys.modules, "ray", None)          # as if Ray were not installed
    rc = main(["campaign", "--out", str(tmp_path / "o"), "--scenarios", "head_on", "--seeds", "0", "--runs", "2",
               "--engine", "ray"])
    assert rc == 2
    assert 'pip install "psbmpc-jax[cluster]"' in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
