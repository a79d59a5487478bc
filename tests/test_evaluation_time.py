"""The time of an evaluation estimated before it starts (psbmpc_jax.limits.check_evaluation_time): samples x
(vessels, scored pairs), calibrated on the committed records of benchmarks/bench_evaluation_time.py; an
evaluation that would take hours is refused naming the file(s), samples, vessels, pairs, the estimate and the
limit (library and command line, before anything is scored); the shipped track example is accepted and its
estimate logged.  No test here times anything: the estimate is compared with committed measurements."""

from __future__ import annotations

import json
import pathlib

import numpy as np
import pytest
from conftest import run_cli

from psbmpc_jax import limits
from psbmpc_jax.evaltool import evaluate_file, evaluate_tracks, load_runs
from psbmpc_jax.evaltool.evaluate import run_shapes
from psbmpc_jax.evaltool.tracks import Tracks

ROOT = pathlib.Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
AIS_EXAMPLE = ROOT / "examples" / "ais" / "crossing_trondheimsfjord.csv"




def hours_csv(path: pathlib.Path, vessels: int = 10) -> pathlib.Path:
    """A tiny file whose evaluation is long: ``vessels`` vessels, two rows each, 10^9 s apart (10^9 samples at the
    default 1 s): with every ordered pair scored, about 3.5 h by the model."""
    rows = ["t_s,vessel,north_m,east_m"]
    for t in (0, 1_000_000_000):
        rows += [f"{t},v{v},{1000.0 * v + (1.0 if t else 0.0) * (1 if v % 2 else -1) * 1000.0},{100 * v}"
                 for v in range(vessels)]
    path.write_text("\n".join(rows) + "\n")
    return path


@pytest.fixture(autouse=True)
def default_limit(monkeypatch):
    monkeypatch.delenv(limits.EVALUATION_TIME_ENV, raising=False)


# ------------------------------------------------------------------------------------------------ the model
def test_estimate_is_samples_times_vessels_and_pairs():
    a, b, c = limits.EVAL_TIME_S
    assert limits.evaluation_seconds(1000, 2) == pytest.approx(1000 * (2 * a + b + c))
    assert limits.evaluation_seconds(1000, 5, "all") == pytest.approx(1000 * (5 * a + 20 * b + c))
    assert limits.scored_pairs(5, "own") == 4 and limits.scored_pairs(5, "all") == 20
    assert limits.evaluation_seconds(2000, 3) == pytest.approx(2 * limits.evaluation_seconds(1000, 3))


def _records(prefix):
    files = sorted(RESULTS.glob(f"{prefix}_cpu_*.json"))
    assert files, f"no committed {prefix} record in {RESULTS}"
    return [(f.name, p) for f in files for p in json.loads(f.read_text())["points"]]


def test_estimate_within_a_factor_of_the_recorded_evaluations():
    """Every evaluation recorded by benchmarks/bench_evaluation_time.py (evaluate_tracks alone, 2 x 10^5 to 10^7
    samples, 2-8 vessels, own-ship and all pairs, an encounter-rich track) lies within 0.6-1.6 times the
    estimate (measured: 0.9-1.35)."""
    seen = 0
    for name, p in _records("evaluation_time"):
        est = limits.evaluation_seconds(p["samples"], p["vessels"], p["pairs"])
        assert 0.6 <= est / p["median_s"] <= 1.6, (name, p, est)
        seen += 1
    assert seen >= 8


def test_tested_limits_track_records_bound_the_estimate_from_above():
    """The tested-limits cases ``track`` / ``track_1e7`` timed a whole fresh process (Python's start, building and
    validating the tracks) at a load average of ~10 on two cores: the estimate of the scoring alone lies below
    that wall time, within a factor 8 of it (measured: 0.16 and 0.23)."""
    pts = [(n, p) for n, p in _records("tested_limits") if p.get("case") in ("track", "track_1e7")]
    assert {p["case"] for _, p in pts} == {"track", "track_1e7"}
    for name, p in pts:
        est = limits.evaluation_seconds(p["samples"], p["vessels"])
        assert p["wall_s"] / 8 <= est <= p["wall_s"], (name, p, est)


# ------------------------------------------------------------------------------------------------ the limit
def test_limit_default_environment_and_off(monkeypatch):
    assert limits.evaluation_time_limit()[0] == limits.EVALUATION_TIME_LIMIT_S == 3600.0
    monkeypatch.setenv(limits.EVALUATION_TIME_ENV, "10")
    assert limits.evaluation_time_limit() == (10.0, f"{limits.EVALUATION_TIME_ENV}=10")
    with pytest.raises(limits.ResourceError, match="the limit is 10 s"):
        limits.check_evaluation_time([(10 ** 7, 2)], what="x", sample_interval="sample_interval_s = 1 s")
    monkeypatch.setenv(limits.EVALUATION_TIME_ENV, "off")
    assert limits.check_evaluation_time([(10 ** 12, 50)], "all", what="x", sample_interval="s") > 1e6
    monkeypatch.setenv(limits.EVALUATION_TIME_ENV, "soon")
    with pytest.raises(ValueError, match=limits.EVALUATION_TIME_ENV):
        limits.evaluation_time_limit()


def test_many_runs_that_take_hours_are_refused_naming_what_drives_them():
    """5 000 runs of 10^6 samples of two vessels (each run within the memory limit): about 107 min."""
    runs = [(10 ** 6, 2)] * 5000
    with pytest.raises(limits.ResourceError) as err:
        limits.check_evaluation_time(runs, "own", what="evaluation of trajectories.npz",
                                     sample_interval="sample_interval_s = 1 s")
    msg = str(err.value)
    for part in ("evaluation of trajectories.npz", "5000 run(s)", "5e+09 samples", "sample_interval_s = 1 s",
                 "2 vessels", "1 scored pair(s) per run (pairs = own)", "about 107 min", "the limit is 60 min",
                 limits.EVALUATION_TIME_ENV):
        assert part in msg, (part, msg)
    assert limits.check_evaluation_time(runs[:2000], what="x", sample_interval="s") == pytest.approx(2570.0)


def test_evaluate_file_refuses_hours_before_scoring(tmp_path, monkeypatch):
    path = hours_csv(tmp_path / "tracks.csv")
    called = []
    monkeypatch.setattr("psbmpc_jax.evaltool.evaluate.evaluate_tracks", lambda *a, **k: called.append(a))
    with pytest.raises(limits.ResourceError) as err:
        evaluate_file(path, pairs="all")
    msg = str(err.value)
    assert msg.startswith(f"evaluation of {path}: 1 run(s), 1e+09 samples in all (sample_interval_s = 1 s) x up to "
                          f"10 vessels, 90 scored pair(s) per run (pairs = all): scoring takes about 3.46 h")
    assert not called


def test_evaluate_tracks_checks_its_own_run(monkeypatch):
    t = np.arange(0.0, 601.0)
    tr = Tracks.from_arrays(t, [t, 500.0 - t], [0 * t, 0 * t + 5.0], names=("own", "ts"), source="mine.csv")
    monkeypatch.setenv(limits.EVALUATION_TIME_ENV, "1e-6")
    with pytest.raises(limits.ResourceError, match=r"^evaluation of mine\.csv: 1 run\(s\), 601 samples .*the limit "
                                                   r"is 1e-06 s"):
        evaluate_tracks(tr)
    monkeypatch.delenv(limits.EVALUATION_TIME_ENV)
    assert evaluate_tracks(tr).encounters


# ------------------------------------------------------------------------------------------------ the command
def test_command_line_refuses_hours_naming_file_samples_vessels_pairs(tmp_path):
    path = hours_csv(tmp_path / "tracks.csv")
    out = tmp_path / "scores.json"
    rc, stdout, stderr = run_cli(["evaluate", str(path), "--pairs", "all", "--out", str(out)])
    assert rc == 2 and "Traceback" not in stderr and not out.exists() and stdout == ""
    log, refusal = stderr.strip().splitlines()
    assert log.startswith(f"psbmpc-jax evaluate: scoring {path}: about 3.46 h (1 run(s), 1e+09 samples x up to 10 "
                          f"vessels, 90 scored pair(s) per run")
    assert refusal.startswith(f"psbmpc-jax evaluate: evaluation of {path}: 1 run(s), 1e+09 samples in all "
                              f"(sample_interval_s = 1 s) x up to 10 vessels, 90 scored pair(s) per run "
                              f"(--pairs = all)")
    assert "the limit is 60 min" in refusal and "--pairs own" in refusal and "--set sample_interval_s" in refusal
    # the same files, several at once: the refusal names them all and counts their runs together
    second = hours_csv(tmp_path / "more.csv", vessels=2)
    rc, _, stderr = run_cli(["evaluate", str(second), str(path), "--pairs", "all"])
    assert rc == 2 and f"evaluation of 2 track files ({second}, {path}): 2 run(s), 2e+09 samples" in stderr


def test_shipped_track_example_is_accepted_and_its_estimate_logged():
    runs = load_runs(AIS_EXAMPLE, own="257000001")
    est = limits.check_evaluation_time(run_shapes(runs, 1.0), what="x", sample_interval="s")
    assert 0 < est < 1.0
    rc, stdout, stderr = run_cli(["evaluate", str(AIS_EXAMPLE), "--own-mmsi", "257000001", "--range-scale",
                                  "0.16666667"])
    assert rc == 0, stderr
    assert f"psbmpc-jax evaluate: scoring {AIS_EXAMPLE}: about " in stderr and "1 encounter(s)" in stdout


def test_quiet_command_line_does_not_log_the_estimate(tmp_path):
    rc, _, stderr = run_cli(["-q", "evaluate", str(AIS_EXAMPLE), "--own-mmsi", "257000001"])
    assert rc == 0 and "scoring" not in stderr
    rc, _, stderr = run_cli(["-q", "evaluate", str(hours_csv(tmp_path / "t.csv")), "--pairs", "all"])
    assert rc == 2 and "scoring takes about 3.46 h" in stderr and "psbmpc-jax evaluate: scoring" not in stderr
