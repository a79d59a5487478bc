"""The command line never destroys an input and reads run folders with their own settings:

* ``evaluate X --out X`` (also through a symlink, another spelling, a hard link, or a file of the run folder it
  reads) is refused before anything is written; an existing file of another kind needs ``--force``;
* ``evaluate RUN_FOLDER`` uses the evaluation settings stored with the run (unless ``--preset`` /
  ``--range-scale`` say otherwise), prints the ranges it used, and reproduces the scores of the run's
  metrics.json and summary.md (a real short scenario);
* ``run`` into a folder that holds another run is refused before simulating; ``--force`` replaces exactly that
  run's files (an earlier run's trajectories do not survive a run without ``--save-trajectories``).
"""

from __future__ import annotations

import json
import os
import time

import pytest
from conftest import run_cli

from psbmpc_jax.runfolder import read_manifest
from psbmpc_jax.sim.output import evaluation_markdown

TINY = (
    "name: tiny_eval\n"
    "description: 'Head-on, open water: a short run for the run-folder tests'\n"
    "simulation: {dt_s: 0.5, duration_s: 60}\n"
    "monte_carlo: {runs: 2, seed: 4}\n"
    "mpc: {preset: nidelva, update_period_s: 5, config: {T: 40},\n"
    "      speed_factors: [[1.0, 0.0]], course_offsets_deg: [[-30, 0, 30]]}\n"
    "sensor: {position_std_m: 2, U_max_mps: 4}\n"
    "own_ship: {name: OS, position_m: [0, 0], course_deg: 0, speed_mps: 2, waypoints_m: [[0, 0], [100, 0]]}\n"
    "targets:\n  - {name: TS1, position_m: [120, 10], course_deg: 180, speed_mps: 2}\n"
    "evaluation: {range_scale: 0.05}\n")

USER_CSV = "t_s,vessel,north_m,east_m\n" + "".join(
    f"{t},own,{t},0\n{t},ferry,{200 - t},5\n" for t in range(0, 200, 2))




@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """One real CLI run with trajectories (compiles once for the module)."""
    base = tmp_path_factory.mktemp("cli")
    scen = base / "tiny_eval.yaml"
    scen.write_text(TINY)
    rc, out, err = run_cli(["run", str(scen), "--out", str(base / "out"), "--save-trajectories", "--no-figures",
                            "--quiet"])
    assert rc == 0, err
    return scen, base / "out" / "tiny_eval", out


# ============================================================================== evaluate: never over an input
def test_out_naming_the_input_is_refused(tmp_path):
    tracks = tmp_path / "tracks.csv"
    tracks.write_text(USER_CSV)
    (tmp_path / "sub").mkdir()
    os.symlink(tracks, tmp_path / "link.csv")
    os.link(tracks, tmp_path / "hard.csv")
    spellings = [tracks, tmp_path / "sub" / ".." / "tracks.csv", tmp_path / "link.csv", tmp_path / "hard.csv"]
    for out in spellings:
        rc, _, err = run_cli(["evaluate", str(tracks), "--out", str(out)])
        assert rc == 2 and "refusing to write over it" in err, (out, err)
        rc, _, err = run_cli(["evaluate", str(out), "--out", str(tracks)])          # the other way round
        assert rc == 2 and "refusing to write over it" in err, (out, err)
    assert tracks.read_text() == USER_CSV and (tmp_path / "hard.csv").read_text() == USER_CSV
    assert sorted(p.name for p in tmp_path.iterdir()) == ["hard.csv", "link.csv", "sub", "tracks.csv"]
    rc, out, _ = run_cli(["evaluate", str(tracks), "--out", str(tmp_path / "scores.json")])
    assert rc == 0 and json.loads((tmp_path / "scores.json").read_text())["schema"] == "psbmpc-eval/1"
    rc, _, _ = run_cli(["evaluate", str(tracks), "--out", str(tmp_path / "scores.json")])   # an earlier output
    assert rc == 0


def test_out_over_another_file_or_unwritable(tmp_path):
    tracks = tmp_path / "tracks.csv"
    tracks.write_text(USER_CSV)
    notes = tmp_path / "notes.json"
    notes.write_text('{"mine": 1}')
    rc, _, err = run_cli(["evaluate", str(tracks), "--out", str(notes)])
    assert rc == 2 and "not an earlier psbmpc-jax evaluate output" in err and "--force" in err
    assert notes.read_text() == '{"mine": 1}'
    assert run_cli(["evaluate", str(tracks), "--out", str(notes), "--force"])[0] == 0
    assert json.loads(notes.read_text())["schema"] == "psbmpc-eval/1"
    rc, _, err = run_cli(["evaluate", str(tracks), "--out", str(tracks / "x.json")])
    assert rc == 2 and "is a file, not a folder" in err and "Traceback" not in err
    rc, _, err = run_cli(["evaluate", str(tracks), "--out", str(tmp_path)])
    assert rc == 2 and "is a folder; give a file name" in err


def test_files_of_a_run_folder_are_protected(tiny_run):
    _, folder, _ = tiny_run
    before = {n: (folder / n).read_bytes() for n in read_manifest(folder)["files"]}
    for name in ("metrics.json", "summary.md", "manifest.json", "trajectories.npz"):
        for src in (folder, folder / "trajectories.csv"):
            rc, _, err = run_cli(["evaluate", str(src), "--out", str(folder / name)])
            assert rc == 2 and "refusing to write over it" in err, (src, name, err)
    assert {n: (folder / n).read_bytes() for n in before} == before


# ============================================================================ evaluate: a run's own settings
def test_evaluate_run_uses_the_stored_settings_and_reproduces_the_summary(tiny_run, tmp_path):
    _, folder, _ = tiny_run
    metrics = json.loads((folder / "metrics.json").read_text())
    stored = metrics["scenario"]["evaluation"]
    assert stored["r_stage2_m"] == pytest.approx(125.0) and stored["r_col_m"] == pytest.approx(1.5)
    rc, out, err = run_cli(["evaluate", str(folder), "--out", str(tmp_path / "scores.json")])
    assert rc == 0, err
    assert ("ranges: stages r_Stage2/3/4 125 / 55 / 10 m, CPA ranges r_pref 9.5, r_min 5, r_nm 2.5, r_col 1.5 m, "
            "sample interval 1 s (from the run's stored evaluation settings") in out
    doc = json.loads((tmp_path / "scores.json").read_text())
    f = doc["files"][0]
    assert f["params"] == stored and doc["params"] == stored
    # the scores of every encounter equal those the run stored (metrics.json keeps 6 significant digits)
    stored_runs = metrics["colregs_evaluation"]["runs"]
    assert len(f["runs"]) == len(stored_runs) == 2
    for cli_run, run in zip(f["runs"], stored_runs):
        assert [e["situation"] for e in cli_run["encounters"]] == [e["situation"] for e in run]
        for e_cli, e_run in zip(cli_run["encounters"], run):
            for k, v in e_run["scores"].items():
                assert e_cli["scores"][k] == pytest.approx(v, rel=1e-5, abs=1e-9), k
    # and the table of summary.md, rebuilt from evaluate's aggregate, is the one in the file
    rebuilt = evaluation_markdown({"params": f["params"], "aggregate": f["aggregate"]})
    summary = (folder / "summary.md").read_text()
    table = [ln for ln in rebuilt if ln.startswith("| ")]
    assert len(table) >= 2 and all(ln in summary for ln in table)
    # the CSV (12 significant digits) gives the same scores to 1e-6
    rc, _, _ = run_cli(["evaluate", str(folder / "trajectories.csv"), "--out", str(tmp_path / "csv.json")])
    csv_runs = json.loads((tmp_path / "csv.json").read_text())["files"][0]["runs"]
    for a, b in zip(csv_runs, f["runs"]):
        for ea, eb in zip(a["encounters"], b["encounters"]):
            for k, v in eb["scores"].items():
                assert (ea["scores"][k] is None) == (v is None) and (v is None or abs(ea["scores"][k] - v) < 1e-6), k


def test_command_line_settings_replace_or_change_the_stored_ones(tiny_run):
    _, folder, _ = tiny_run
    rc, out, _ = run_cli(["evaluate", str(folder), "--range-scale", "1"])
    assert rc == 0 and "stages r_Stage2/3/4 2500 / 1100 / 200 m" in out
    assert "from preset default x 1, replacing the run's stored settings" in out
    rc, out, _ = run_cli(["evaluate", str(folder), "--set", "r_stage2_m=150"])
    assert rc == 0 and "stages r_Stage2/3/4 150 / 55 / 10 m" in out and "with r_stage2_m=150" in out
    rc, _, err = run_cli(["evaluate", str(folder), "--set", "r_stage3_m=400"])     # above the stored r_stage2
    assert rc == 2 and "--set on the run's stored settings: EvalParams.r_stage2_m" in err


def test_a_stale_run_folder_is_refused_by_evaluate(tiny_run, tmp_path):
    import shutil

    _, folder, _ = tiny_run
    copy = tmp_path / "copy"
    shutil.copytree(folder, copy)
    lines = (copy / "trajectories.csv").read_text().splitlines(keepends=True)
    (copy / "trajectories.csv").write_text("".join(lines[: len(lines) // 2 + 1]))     # cut at the run boundary
    os.remove(copy / "trajectories.npz")
    rc, _, err = run_cli(["evaluate", str(copy)])
    assert rc == 2 and "trajectories.csv" in err and "bytes, but run" in err and "truncated" in err
    with open(copy / "metrics.json", "a") as fh:
        fh.write("\n")
    rc, _, err = run_cli(["evaluate", str(copy / "trajectories.csv")])
    assert rc == 2 and "metrics.json" in err


# =============================================================================== run: the overwrite rule
def test_rerun_refused_before_simulating_then_force_replaces(tiny_run, tmp_path):
    import shutil

    scen, original, _ = tiny_run
    out = tmp_path / "out"
    shutil.copytree(original.parent, out)                  # the other tests keep the fixture's folder intact
    folder = out / original.name
    first = read_manifest(folder)
    t0 = time.perf_counter()
    rc, _, err = run_cli(["run", str(scen), "--out", str(out), "--quiet"])
    assert rc == 2 and "holds the results of another run" in err and "--force" in err
    assert time.perf_counter() - t0 < 5.0 and read_manifest(folder) == first
    rc, _, err = run_cli(["run", str(scen), str(scen), "--out", str(out), "--quiet"])
    assert rc == 2 and "would both write" in err
    (folder / "my_notes.txt").write_text("keep")
    rc, stdout, err = run_cli(["run", str(scen), "--out", str(out), "--quiet", "--no-figures", "--force"])
    assert rc == 0, err
    assert "own-ship " in stdout and "arrived in" in stdout
    second = read_manifest(folder)
    assert second["complete"] and second["run_id"] != first["run_id"]
    assert set(second["files"]) == {"metrics.json", "summary.md"}
    assert not (folder / "trajectories.npz").exists() and not (folder / "trajectories.csv").exists()
    assert (folder / "my_notes.txt").read_text() == "keep"
    rc, _, err = run_cli(["evaluate", str(folder)])
    assert rc == 2 and "wrote no trajectories" in err
    index = (out / "index.md").read_text()
    assert second["run_id"][:8] in index
