"""``psbmpc-jax run``: an mc-estimator scenario end to end with trajectories, selected runs, an animation and
metrics.json; argument errors before any work (unwritable --out, --plot-runs, names with suggestions);
--list; no BrokenPipe traceback."""

from __future__ import annotations

import contextlib
import io
import json
import os
import subprocess
import sys
import time

import numpy as np
import pytest

from psbmpc_jax.apps.cli import main
from psbmpc_jax.sim import load_trajectories

TINY_MC = (
    "name: tiny_mc\n"
    "description: 'Head-on, open water: a tiny case for the CLI tests'\n"
    "simulation: {dt_s: 0.5, duration_s: 10}\n"
    "monte_carlo: {runs: 2, seed: 4}\n"
    "mpc: {preset: nidelva, update_period_s: 5, config: {estimator: mc, n_samples: 64, T: 40},\n"
    "      speed_factors: [[1.0]], course_offsets_deg: [[-30, 0, 30]]}\n"
    "sensor: {position_std_m: 2, U_max_mps: 4}\n"
    "own_ship: {name: OS, position_m: [0, 0], course_deg: 0, speed_mps: 2}\n"
    "targets:\n  - {name: TS1, position_m: [120, 10], course_deg: 180, speed_mps: 2}\n")


@pytest.fixture(scope="module")
def tiny_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("scen") / "tiny_mc.yaml"
    path.write_text(TINY_MC)
    return path


@pytest.fixture(scope="module")
def mc_run(tiny_file, tmp_path_factory):
    """One CLI run of an mc scenario with every output option (compiles once for the module)."""
    out = tmp_path_factory.mktemp("out")
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        rc = main(["run", str(tiny_file), "--seed", "7", "--out", str(out), "--save-trajectories",
                   "--plot-runs", "1", "--animate", "--quiet"])
    return rc, out / "tiny_mc", buf.getvalue()


def test_mc_scenario_end_to_end(mc_run):
    rc, folder, stdout = mc_run
    assert rc == 0
    doc = json.loads((folder / "metrics.json").read_text())
    assert doc["scenario"]["mpc"]["config"]["estimator"] == "mc"
    assert doc["scenario"]["seed"] == 7 and doc["summary"]["seed"] == 7   # the --seed in use is recorded
    s = doc["summary"]
    assert s["mpc_solves_total"] == 2 * 2 and "solves" not in s and "n_solves" not in s
    assert [len(r["solve_times_s"]) for r in doc["runs"]] == [2, 2]
    lines = stdout.strip().splitlines()
    assert lines[0].startswith("tiny_mc: 2 runs in ") and "closest approach TS1 " in lines[0]
    assert lines[-1].startswith("psbmpc-jax run: 1 scenario, 2 runs in ") and "all passed" in lines[-1]
    assert "{" not in stdout                                             # plain text, no JSON


def test_outputs_of_the_options(mc_run):
    _, folder, _ = mc_run
    names = {p.name for p in folder.iterdir()}
    assert {"map_run1.png", "distances_run1.png", "course_speed_run1.png", "monte_carlo.png",
            "animation_run1.gif", "trajectories.csv", "trajectories.npz", "summary.md"} <= names
    assert "map.png" not in names and "map_run0.png" not in names      # only the runs asked for
    tr = load_trajectories(folder)
    assert tr.states.shape == (2, 2, 21, 4) and tr.solve_t.tolist() == [0.0, 5.0]
    doc = json.loads((folder / "metrics.json").read_text())
    for r, run in enumerate(doc["runs"]):                                 # the export agrees with the metrics
        np.testing.assert_allclose(run["solve_times_s"], tr.solve_wall[r, 0], rtol=1e-5)
        d = np.hypot(*(tr.states[r, 0, :, :2] - tr.states[r, 1, :, :2]).T).min()
        assert run["targets"][0]["min_distance_m"] == pytest.approx(d, rel=1e-5)


def _fails_fast(argv, capsys, needle):
    t0 = time.perf_counter()
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert needle in err, err
    assert time.perf_counter() - t0 < 5.0          # refused before any compile or simulation
    return err


def test_unwritable_out_fails_before_the_work(tiny_file, tmp_path, capsys):
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    err = _fails_fast(["run", str(tiny_file), "--out", str(blocker / "sub")], capsys, "--out")
    assert "is a file" in err
    _fails_fast(["run", str(tiny_file), "--out", str(blocker)], capsys, "is not a folder")


def test_plot_runs_checked_against_the_runs(tiny_file, tmp_path, capsys):
    out = str(tmp_path / "o")
    _fails_fast(["run", str(tiny_file), "--plot-runs", "0,5", "--out", out], capsys,
                "--plot-runs: run 5 does not exist: scenario 'tiny_mc' has 2 runs")
    _fails_fast(["run", str(tiny_file), "--plot-runs", "0,,1", "--out", out], capsys, "argument --plot-runs")
    assert not (tmp_path / "o").exists()


def test_did_you_mean(tmp_path, capsys):
    err = _fails_fast(["run", "head_onn", "--out", str(tmp_path)], capsys, "no built-in scenario matches")
    assert "did you mean 'head_on'?" in err
    err = _fails_fast(["run", str(tmp_path / "head_on.yaml"), "--out", str(tmp_path)], capsys, "not found")
    assert "psbmpc-jax run head_on" in err
    (tmp_path / "my_case.yaml").write_text("name: x\n")
    err = _fails_fast(["run", str(tmp_path / "my_cas.yaml"), "--out", str(tmp_path)], capsys, "not found")
    assert "did you mean" in err and "my_case.yaml" in err


def test_list_has_descriptions_and_paths(capsys):
    assert main(["run", "--list"]) == 0
    lines = capsys.readouterr().out.splitlines()
    head_on = next(ln for ln in lines if ln.startswith("head_on "))
    name, rest = head_on.split(None, 1)
    assert "Head-on" in rest and rest.rstrip().endswith("head_on.yaml") and os.path.isfile(rest.split()[-1])
    assert all(len(ln.split()) >= 3 for ln in lines)


def test_no_broken_pipe_traceback():
    """`psbmpc-jax run --list | head -1`: the reader is gone before the listing is written."""
    proc = subprocess.Popen([sys.executable, "-c", "import sys; from psbmpc_jax.apps.cli import main; "
                             "sys.exit(main(['run', '--list']))"], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()                     # like head -1 exiting: every write gets EPIPE
    err = proc.stderr.read().decode()
    proc.wait(timeout=120)
    assert "Traceback" not in err and "BrokenPipe" not in err, err
