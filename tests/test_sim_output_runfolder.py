"""Run folders never lose or mix data: atomic result files, the manifest and its checks by every reader, the
overwrite rule, a kill at every step of the commit, a truncated trajectories.csv with and without a manifest,
clear errors of the export and plot writers, and index.md over verified runs only.  Synthetic results (no
solver): fast."""

from __future__ import annotations

import fnmatch
import json
import logging
import os
import shutil
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

from psbmpc_jax.safe_io import OutputError, atomic_open, atomic_write_text, file_output_problem, same_file
from psbmpc_jax.sim import load_trajectories, write_outputs, write_trajectories
from psbmpc_jax import runfolder as rf
from psbmpc_jax.sim.output import write_index
from psbmpc_jax.runfolder import MANIFEST, RunFolderError, read_manifest, run_folder_problem, verify_member

from test_export import synthetic_result  # noqa: E402  (tests/ is on sys.path)


@pytest.fixture(scope="module")
def two():
    return synthetic_result(2)


@pytest.fixture(scope="module")
def three():
    return synthetic_result(3)


def run_files(folder) -> set[str]:
    """The files of ``folder`` that are run outputs (named like them) -- what a reader could mistake for the
    run's."""
    return {p.name for p in folder.iterdir() if p.is_file() and any(
        fnmatch.fnmatchcase(p.name, pat) for pat in rf.OUTPUT_PATTERNS)}


def assert_consistent(folder, *, after_kill: bool = False) -> dict:
    """The folder's manifest is complete, lists exactly the run files present, and each verifies (after a kill a
    staging folder may be left; the next write removes it)."""
    doc = read_manifest(folder)
    assert doc is not None and doc["complete"] is True
    assert run_files(folder) == set(doc["files"])
    for name in doc["files"]:
        assert verify_member(folder / name) == doc
    if not after_kill:
        assert not [p for p in folder.iterdir() if p.name.startswith(rf.STAGING_PREFIX) or p.suffix == ".tmp"]
    return doc


# ============================================================================================ atomic writing
def test_atomic_write_leaves_the_old_file_on_failure(tmp_path):
    path = tmp_path / "a.txt"
    atomic_write_text(path, "old\n")
    with pytest.raises(RuntimeError, match="boom"):
        with atomic_open(path, "w") as fh:
            fh.write("new, half written")
            raise RuntimeError("boom")
    assert path.read_text() == "old\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt"]          # no temporary file left
    atomic_write_text(path, "new\n")
    assert path.read_text() == "new\n" and oct(path.stat().st_mode & 0o777) != "0o600"


def test_same_file_and_output_problems(tmp_path):
    f = tmp_path / "tracks.csv"
    f.write_text("x")
    (tmp_path / "sub").mkdir()
    os.symlink(f, tmp_path / "link.csv")
    os.link(f, tmp_path / "hard.csv")
    assert same_file(f, tmp_path / "sub" / ".." / "tracks.csv")
    assert same_file(f, tmp_path / "link.csv") and same_file(f, tmp_path / "hard.csv")
    assert not same_file(f, tmp_path / "other.csv")
    assert "is a folder" in file_output_problem(tmp_path / "sub")
    assert "is a file, not a folder" in file_output_problem(f / "x.json")
    assert file_output_problem(tmp_path / "new" / "deeper" / "x.json") is None
    with pytest.raises(OutputError, match="does not exist"):
        with atomic_open(tmp_path / "new" / "x.json"):
            pass


# ===================================================================================== manifest and readers
def test_run_folder_has_a_manifest_that_every_file_matches(two, tmp_path):
    paths = write_outputs(two, tmp_path / "r", figures=False, trajectories=True)
    folder = tmp_path / "r"
    doc = assert_consistent(folder)
    assert set(doc["files"]) == {"metrics.json", "summary.md", "trajectories.csv", "trajectories.npz"}
    assert paths["manifest"] == folder / MANIFEST and paths["metrics"] == folder / "metrics.json"
    assert doc["scenario"] == "synthetic" and len(doc["run_id"]) == 32 and doc["package"]["version"]
    assert json.loads((folder / "metrics.json").read_text())["run_id"] == doc["run_id"]
    tr = load_trajectories(folder)
    assert tr.run_id == doc["run_id"] and tr.runs == 2
    np.testing.assert_array_equal(tr.states, two.states)
    assert load_trajectories(folder / "trajectories.csv").runs == 2


def test_truncated_csv_is_refused_with_and_without_the_manifest(three, tmp_path):
    write_outputs(three, tmp_path / "r", figures=False, trajectories=True)
    csv_path = tmp_path / "r" / "trajectories.csv"
    lines = csv_path.read_text().splitlines(keepends=True)
    per_run = (len(lines) - 1) // 3
    cut = "".join(lines[: 1 + 2 * per_run])                                  # cut at the run boundary 2 | 3
    csv_path.write_text(cut)
    with pytest.raises(RunFolderError, match=r"trajectories.csv: \d+ bytes, but run [0-9a-f]+ wrote \d+ bytes"):
        load_trajectories(csv_path)
    bare = tmp_path / "bare"
    bare.mkdir()
    (bare / "trajectories.csv").write_text(cut)                             # a copy outside any run folder
    with pytest.raises(ValueError, match=r"declares 3 runs x 2 ships x 41 steps .* holds 2 x 2 x 41: the file is cut"):
        load_trajectories(bare / "trajectories.csv")
    (bare / "trajectories.csv").write_text(cut + lines[1 + 2 * per_run][:25])    # cut inside a row
    with pytest.raises(ValueError, match=r"row \d+ has \d+ cells, the header \d+: the file is cut short"):
        load_trajectories(bare / "trajectories.csv")
    one_ship = "".join(lines[: 1 + 41])                                     # run 0, ship 0 only: looks whole
    (bare / "trajectories.csv").write_text(one_ship)
    with pytest.raises(ValueError, match="declares 3 runs x 2 ships x 41 steps"):
        load_trajectories(bare / "trajectories.csv")


def test_folder_prefers_the_npz_and_a_broken_csv_is_still_refused(three, tmp_path):
    write_outputs(three, tmp_path / "r", figures=False, trajectories=True)
    folder = tmp_path / "r"
    (folder / "trajectories.csv").write_text("run,ship,ship_name\n")
    assert load_trajectories(folder).runs == 3                              # the verified NPZ
    os.remove(folder / "trajectories.npz")
    with pytest.raises(RunFolderError, match="trajectories.csv: .* bytes"):
        load_trajectories(folder)


def test_stale_and_foreign_files_are_refused(two, three, tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    write_outputs(three, a, figures=False, trajectories=True)
    write_outputs(two, b, figures=False)                                     # no trajectories in run b
    shutil.copy(a / "trajectories.npz", b / "trajectories.npz")              # a stale file beside run b
    run_b = read_manifest(b)["run_id"]
    with pytest.raises(RunFolderError, match=rf"trajectories.npz: not a file of run {run_b} .* left from another"):
        load_trajectories(b)
    with pytest.raises(RunFolderError, match="not a file of run"):
        load_trajectories(b / "trajectories.npz")
    c = tmp_path / "c"
    write_outputs(two, c, figures=False, trajectories=True)
    shutil.copy(a / "trajectories.csv", c / "trajectories.csv")              # a listed name, another run's file
    with pytest.raises(RunFolderError, match="trajectories.csv: .* comes from another run"):
        load_trajectories(c / "trajectories.csv")


def test_a_bare_file_still_loads(two, tmp_path, caplog):
    write_trajectories(two, tmp_path)                                        # a user's own export: no manifest
    assert load_trajectories(tmp_path).runs == 2 and load_trajectories(tmp_path).run_id is None
    # a psbmpc-traj/1 CSV (no declared shape) still reads, with a warning that completeness is unchecked
    lines = (tmp_path / "trajectories.csv").read_text().splitlines()
    v1 = "\n".join(",".join(line.split(",")[:-3]) for line in lines) + "\n"
    old = tmp_path / "old"
    old.mkdir()
    (old / "trajectories.csv").write_text(v1)
    with caplog.at_level(logging.WARNING):
        assert load_trajectories(old / "trajectories.csv").runs == 2
    assert "cannot be checked" in caplog.text
    npz = (tmp_path / "trajectories.npz").read_bytes()
    (old / "trajectories.npz").write_bytes(npz[: len(npz) // 2])
    with pytest.raises(ValueError, match="trajectories.npz: cannot be read .* damaged or cut short"):
        load_trajectories(old / "trajectories.npz")


def test_incomplete_or_foreign_manifest(two, tmp_path):
    folder = tmp_path / "r"
    write_outputs(two, folder, figures=False, trajectories=True)
    doc = read_manifest(folder)
    atomic_write_text(folder / MANIFEST, json.dumps({**doc, "complete": False}))
    with pytest.raises(RunFolderError, match="did not complete"):
        load_trajectories(folder)
    (folder / MANIFEST).write_text(json.dumps({**doc, "schema": "psbmpc-run/9"}))
    with pytest.raises(RunFolderError, match="not a psbmpc-jax run manifest of this version"):
        load_trajectories(folder)
    (folder / MANIFEST).write_text("{ cut")
    with pytest.raises(RunFolderError, match="cannot be read as a run manifest"):
        load_trajectories(folder)
    # another tool's manifest.json: the folder is no run folder; its files are read (and checked) on their own
    (folder / MANIFEST).write_text(json.dumps({"schema": "other-tool/3", "files": {}}))
    assert load_trajectories(folder).runs == 2
    assert "not overwritten" in run_folder_problem(folder, force=True)     # but never written over
    with pytest.raises(OutputError, match="not a psbmpc-jax run manifest"):
        write_outputs(two, folder, figures=False, force=True)
    assert json.loads((folder / MANIFEST).read_text())["schema"] == "other-tool/3"


# ======================================================================================== the overwrite rule
def test_rerun_is_refused_then_force_replaces_exactly_the_old_run(two, three, tmp_path):
    folder = tmp_path / "r"
    write_outputs(three, folder, figures=False, trajectories=True)
    old = read_manifest(folder)
    (folder / "notes.txt").write_text("my notes")
    (folder / "map_extra.png").write_bytes(b"mine")                          # a file of no run
    with pytest.raises(OutputError, match=r"holds the results of another run \(run [0-9a-f]+ of scenario "
                                          r"'synthetic', .*complete\); pass force=True"):
        write_outputs(two, folder, figures=False)
    assert read_manifest(folder) == old                                      # refused before anything changed
    write_outputs(two, folder, figures=False, force=True)                    # no trajectories this time
    new = assert_consistent(folder)
    assert new["run_id"] != old["run_id"]
    assert not (folder / "trajectories.npz").exists() and not (folder / "trajectories.csv").exists()
    assert (folder / "notes.txt").read_text() == "my notes" and (folder / "map_extra.png").read_bytes() == b"mine"
    with pytest.raises(FileNotFoundError, match=f"run {new['run_id']} wrote no trajectories"):
        load_trajectories(folder)


def test_folder_without_a_manifest(two, tmp_path):
    folder = tmp_path / "legacy"                                             # results written before manifests
    folder.mkdir()
    for name in ("metrics.json", "summary.md", "trajectories.npz", "map_run3.png"):
        (folder / name).write_text("old")
    (folder / "README.txt").write_text("keep")
    assert "without a manifest (map_run3.png, metrics.json, summary.md, trajectories.npz)" in \
        run_folder_problem(folder, option="--out")
    with pytest.raises(OutputError, match="without a manifest"):
        write_outputs(two, folder, figures=False)
    write_outputs(two, folder, figures=False, force=True)
    assert_consistent(folder)
    assert not (folder / "map_run3.png").exists() and not (folder / "trajectories.npz").exists()
    assert (folder / "README.txt").read_text() == "keep"
    other = tmp_path / "other"                                               # only unrelated files: fine
    other.mkdir()
    (other / "data.csv").write_text("x")
    assert run_folder_problem(other) is None
    write_outputs(two, other, figures=False)
    assert (other / "data.csv").read_text() == "x"


def test_failure_while_writing_keeps_the_previous_results(two, three, tmp_path, monkeypatch):
    folder = tmp_path / "r"
    write_outputs(three, folder, figures=False, trajectories=True)
    before = read_manifest(folder)
    from psbmpc_jax.sim import output

    def broken(*a, **k):
        raise RuntimeError("disk full (simulated)")

    monkeypatch.setattr(output, "summary_markdown", broken)
    with pytest.raises(RuntimeError, match="disk full"):
        write_outputs(two, folder, figures=False, trajectories=True, force=True)
    assert assert_consistent(folder) == before                               # untouched, no staging left
    assert load_trajectories(folder).runs == 3


def test_scoring_failure_keeps_the_simulation_results(two, tmp_path, monkeypatch):
    from psbmpc_jax.sim import output

    def broken(result):
        raise ValueError("scoring ran out of memory (simulated)")

    monkeypatch.setattr(output, "colregs_evaluation", broken)
    write_outputs(two, tmp_path / "r", figures=False, trajectories=True)
    assert_consistent(tmp_path / "r")
    doc = json.loads((tmp_path / "r" / "metrics.json").read_text())
    assert doc["colregs_evaluation"]["error"] == "ValueError: scoring ran out of memory (simulated)"
    assert "**The evaluation failed:** ValueError: scoring ran out" in (tmp_path / "r" / "summary.md").read_text()


# ==================================================================================== a kill at every step
class Killed(BaseException):
    """Stands for SIGKILL: nothing after it runs (the writer's own clean-up is disabled too)."""


def test_a_kill_at_any_step_of_the_commit_never_leaves_a_mix(two, three, tmp_path, monkeypatch):
    """Every file-system change of write_outputs(force=True) over an earlier run is a kill point: after the kill
    the folder holds the previous run complete, or the new run complete, or a manifest that says 'incomplete'
    (every reader refuses it) -- and the next write_outputs(force=True) leaves exactly the new run."""
    base = tmp_path / "base"
    write_outputs(three, base, figures=False, trajectories=True)
    old = read_manifest(base)
    real = {"replace": os.replace, "unlink": os.unlink, "rmtree": shutil.rmtree}
    outcomes, k = [], 0
    while True:
        folder = tmp_path / f"k{k}"
        shutil.copytree(base, folder)
        calls = {"n": 0}

        def step(name):
            def wrapped(*a, **kw):
                calls["n"] += 1
                if calls["n"] == k + 1:
                    raise Killed(name)
                return real[name](*a, **kw)
            return wrapped

        monkeypatch.setattr(os, "replace", step("replace"))
        monkeypatch.setattr(os, "unlink", step("unlink"))
        monkeypatch.setattr(shutil, "rmtree", step("rmtree"))
        monkeypatch.setattr(rf.RunWriter, "abort", lambda self: None)
        try:
            write_outputs(two, folder, figures=False, force=True)            # the new run: no trajectories
            finished = True
        except Killed:
            finished = False
        finally:
            monkeypatch.undo()
        doc = read_manifest(folder)
        if doc["complete"]:
            assert_consistent(folder, after_kill=True)
            state = "old" if doc["run_id"] == old["run_id"] else "new"
            if state == "old":
                assert load_trajectories(folder).runs == 3
            else:
                assert "trajectories.npz" not in doc["files"]
        else:
            state = "incomplete"
            with pytest.raises(RunFolderError, match="did not complete"):
                load_trajectories(folder)
            with pytest.raises(RunFolderError, match="did not complete"):
                verify_member(folder / "metrics.json")
        write_outputs(two, folder, figures=False, force=True)                # recovery
        assert set(assert_consistent(folder)["files"]) == {"metrics.json", "summary.md"}
        outcomes.append(state)
        if finished:
            break
        k += 1
    assert outcomes[0] == "old" and outcomes[-1] == "new" and "incomplete" in outcomes
    assert k >= 8                                                           # every step was a kill point


def test_sigkill_at_random_moments(tmp_path):
    """A real SIGKILL of a process that rewrites a run folder in a loop: every time, the folder reads as one
    complete run or is marked incomplete (then refused)."""
    folder = tmp_path / "r"
    code = textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(os.path.dirname(__file__))!r})
        from test_export import synthetic_result
        from psbmpc_jax.sim import write_outputs
        results = [synthetic_result(1), synthetic_result(3)]
        write_outputs(results[0], {str(folder)!r}, figures=False, trajectories=True, force=True)
        print("ready", flush=True)
        i = 0
        while True:
            i += 1
            write_outputs(results[i % 2], {str(folder)!r}, figures=False, trajectories=True, force=True)
    """)
    rng = np.random.default_rng(0)
    states = []
    for _ in range(2):
        proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, cwd=os.getcwd())
        assert proc.stdout.readline().strip() == b"ready"
        time.sleep(float(rng.uniform(0.05, 0.6)))
        proc.kill()
        proc.wait(timeout=60)
        doc = read_manifest(folder)
        if doc["complete"]:
            assert_consistent(folder, after_kill=True)
            assert load_trajectories(folder).runs in (1, 3)
            states.append("complete")
        else:
            with pytest.raises(RunFolderError, match="did not complete"):
                load_trajectories(folder)
            states.append("incomplete")
    assert states


# ========================================================================================= the other writers
def test_export_and_plot_writers_give_clear_errors(two, tmp_path):
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    with pytest.raises(OutputError, match="a_file is a file, not a folder"):
        write_trajectories(two, blocker / "sub")
    write_trajectories(two, tmp_path / "t", formats=("csv",))
    with pytest.raises(OutputError, match="trajectories.csv exists already; pass overwrite=True"):
        write_trajectories(two, tmp_path / "t", formats=("csv",))
    assert write_trajectories(two, tmp_path / "t", formats=("csv",), overwrite=True)
    write_outputs(two, tmp_path / "run", figures=False)
    with pytest.raises(OutputError, match="is a run folder"):
        write_trajectories(two, tmp_path / "run")
    from psbmpc_jax.sim.plots import animate_run, write_figures

    with pytest.raises(OutputError, match="write_figures: .*a_file is a file, not a folder"):
        write_figures(two, blocker / "figs")
    (tmp_path / "anim.gif").mkdir()
    with pytest.raises(OutputError, match="animate_run: .*anim.gif is a folder"):
        animate_run(two, 0, tmp_path / "anim.gif")
    with pytest.raises(OutputError, match="a_file exists and is not a folder"):
        write_outputs(two, blocker, figures=False)


def test_figures_are_staged_and_listed(two, tmp_path):
    paths = write_outputs(two, tmp_path / "r", figures=True, plot_runs=[1])
    doc = assert_consistent(tmp_path / "r")
    assert {"map_run1.png", "distances_run1.png", "course_speed_run1.png", "monte_carlo.png"} <= set(doc["files"])
    assert paths["map_run1"] == tmp_path / "r" / "map_run1.png"


def test_index_lists_verified_runs_only(two, tmp_path):
    write_outputs(two, tmp_path / "good", figures=False)
    write_outputs(two, tmp_path / "changed", figures=False)
    with open(tmp_path / "changed" / "metrics.json", "a") as fh:
        fh.write(" ")
    (tmp_path / "legacy").mkdir()
    shutil.copy(tmp_path / "good" / "metrics.json", tmp_path / "legacy" / "metrics.json")
    text = write_index(tmp_path).read_text()
    rows = [ln for ln in text.splitlines() if ln.startswith("| [")]
    assert len(rows) == 1 and "(good/summary.md)" in rows[0] and read_manifest(tmp_path / "good")["run_id"][:8] in rows[0]
    assert "`changed/`" in text and "bytes, but run" in text
    assert "`legacy/`" in text and "no manifest.json" in text
