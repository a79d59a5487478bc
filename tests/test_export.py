"""Trajectory export (CSV / NPZ and their reader) and the metrics.json document, on a small synthetic
SimulationResult (no solver involved: fast)."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from psbmpc_jax.scenario import scenario_from_dict
from psbmpc_jax.sim import SimulationResult, Trajectories, load_trajectories, write_trajectories
from psbmpc_jax.sim.output import METRICS_DIGITS, metrics_document, summary_markdown, write_outputs
from psbmpc_jax.sim.simulator import COST_NAMES, run_metrics, summarize

SCENARIO = {
    "name": "synthetic", "description": "two ships head-on", "simulation": {"dt_s": 0.5, "duration_s": 20},
    "monte_carlo": {"runs": 2, "seed": 3},
    "mpc": {"preset": "nidelva", "update_period_s": 5, "speed_factors": [[1.0, 0.5]],
            "course_offsets_deg": [[-30, 0, 30]]},
    "own_ship": {"name": "OS", "position_m": [0, 0], "course_deg": 0, "speed_mps": 2,
                 "waypoints_m": [[0, 0], [400, 0]]},
    "targets": [{"name": "TS1", "position_m": [80, 20], "course_deg": 180, "speed_mps": 2, "colav": "none"}],
}


def synthetic_result(runs: int = 2) -> SimulationResult:
    """Own-ship (PSB-MPC) north at 2 m/s with a starboard jog, a target south 20 m east; 4 MPC updates."""
    sc = scenario_from_dict(SCENARIO)
    rng = np.random.default_rng(0)
    t = np.arange(41) * 0.5
    states = np.zeros((runs, 2, t.size, 4))
    for r in range(runs):
        jog = (r + 1) * 3.0 * np.clip((t - 5) / 5, 0, 1)
        states[r, 0] = np.stack([2 * t, jog, np.where((t > 5) & (t < 10), 0.3, 0.0), np.full_like(t, 2.0)], 1)
        states[r, 1] = np.stack([80 - 2 * t, np.full_like(t, 20.0), np.full_like(t, math.pi), np.full_like(t, 2.0)], 1)
    steps = np.arange(0, 40, 10)
    M = steps.size
    offsets = np.full((runs, 2, M, 2), np.nan)
    offsets[:, 0] = np.stack([np.where(np.arange(M) % 2, 0.5, 1.0), np.radians([30.0, 0.0, -30.0, 0.0])], -1)
    costs = np.full((runs, 2, M, len(COST_NAMES)), np.nan)
    costs[:, 0] = rng.uniform(0.0, 3.0, (runs, M, len(COST_NAMES)))
    wall = np.full((runs, 2, M), np.nan)
    wall[:, 0] = rng.uniform(0.001, 0.02, (runs, M)) + 1e-9 / 3
    calls = [{"t_s": float(t[k]), "solves": runs, "device_calls": runs, "wall_s": float(wall[:, 0, m].sum())}
             for m, k in enumerate(steps)]
    res = SimulationResult(scenario=sc, t=t, states=states, track_x=np.full((runs, 1, t.size, 4), np.nan),
                           track_P=np.full((runs, 1, t.size, 4, 4), np.nan), solve_t=t[steps], offsets=offsets,
                           best_costs=costs, calls=calls, snapshot=None, metrics=[], solve_wall=wall)
    res.metrics = [run_metrics(res, r) for r in range(runs)]
    res.summary = summarize(res, mode="loop", grid_exceeded=None)
    return res


@pytest.fixture(scope="module")
def result():
    return synthetic_result()


def test_csv_and_npz_round_trip(result, tmp_path):
    paths = write_trajectories(result, tmp_path)
    assert sorted(p.name for p in paths) == ["trajectories.csv", "trajectories.npz"]
    npz, from_csv = load_trajectories(tmp_path / "trajectories.npz"), load_trajectories(tmp_path / "trajectories.csv")
    assert load_trajectories(tmp_path).scenario == "synthetic"          # a folder: the NPZ file
    assert isinstance(npz, Trajectories) and npz.runs == 2 and from_csv.scenario is None
    np.testing.assert_array_equal(npz.states, result.states)            # NPZ: exact
    np.testing.assert_array_equal(npz.offsets, result.offsets)
    np.testing.assert_array_equal(npz.costs, result.best_costs)
    np.testing.assert_array_equal(npz.solve_wall, result.solve_wall)
    for name in ("t", "states", "solve_t", "offsets", "costs", "solve_wall"):   # CSV: 12 significant digits
        np.testing.assert_allclose(getattr(from_csv, name), getattr(npz, name), rtol=1e-10, atol=1e-12,
                                   equal_nan=True, err_msg=name)
    assert from_csv.ship_names == npz.ship_names == ["OS", "TS1"]
    assert from_csv.cost_names == npz.cost_names == tuple(COST_NAMES)


def test_csv_layout(result, tmp_path):
    (path,) = write_trajectories(result, tmp_path, formats=("csv",))
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 2 * 2 * 41                                        # runs x ships x steps
    assert list(rows[0])[:8] == ["run", "ship", "ship_name", "t_s", "north_m", "east_m", "course_deg", "speed_mps"]
    assert [k for k in rows[0] if k.startswith("cost_")] == [f"cost_{n}" for n in COST_NAMES]
    first = rows[0]                                                       # run 0, own-ship, t = 0: a solve
    assert (first["run"], first["ship"], first["ship_name"], first["solve"]) == ("0", "0", "OS", "1")
    assert float(first["course_offset_deg"]) == pytest.approx(30.0) and float(first["speed_factor"]) == 1.0
    assert rows[1]["solve"] == "0" and rows[1]["cost_total"] == "" and rows[1]["speed_factor"] == ""
    target = [r for r in rows if r["ship"] == "1"]
    assert target and all(r["solve"] == "0" and r["course_offset_deg"] == "" for r in target)
    assert float(target[0]["course_deg"]) == pytest.approx(180.0)
    assert sum(r["solve"] == "1" for r in rows) == 2 * 4                  # own-ship solves of both runs


def test_reader_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="--save-trajectories"):
        load_trajectories(tmp_path)
    bad = tmp_path / "trajectories.csv"
    bad.write_text("a,b\n1,2\n")
    with pytest.raises(ValueError, match="not a psbmpc-traj/2 trajectory CSV"):
        load_trajectories(bad)
    np.savez(tmp_path / "other.npz", x=np.zeros(3))
    with pytest.raises(ValueError, match="not a psbmpc-traj/2 trajectory file"):
        load_trajectories(tmp_path / "other.npz")
    with pytest.raises(ValueError, match="formats"):
        write_trajectories(synthetic_result(1), tmp_path, formats=("xlsx",))


def _significant_digits(x: float) -> int:
    """Digits of the shortest text that reads back as ``x`` (what json.dumps writes)."""
    mantissa = repr(x).lower().split("e")[0].replace("-", "").replace(".", "")
    return max(len(mantissa.lstrip("0").rstrip("0")), 1)


def test_metrics_document(result, tmp_path):
    doc = metrics_document(result)
    s = doc["summary"]
    assert s["mpc_solves_total"] == 2 * 4 and s["mpc_updates"] == 4 and s["device_calls"] == 8
    assert "solves" not in s and "n_solves" not in s                      # one count of solves
    assert "solves" in result.summary                                     # the older in-memory name stays
    for r, run in enumerate(doc["runs"]):
        assert len(run["solve_times_s"]) == run["n_solves"] == 4
        np.testing.assert_allclose(run["solve_times_s"], result.solve_wall[r, 0], rtol=1e-5)
    floats = []

    def walk(o):
        if isinstance(o, dict):
            for v in o.values():
                walk(v)
        elif isinstance(o, list):
            for v in o:
                walk(v)
        elif isinstance(o, float):
            floats.append(o)

    walk({k: doc[k] for k in ("summary", "runs", "device_calls")})
    assert floats and max(_significant_digits(x) for x in floats) <= METRICS_DIGITS
    assert doc["scenario"]["seed"] == 3 and doc["scenario"]["mpc"]["n_cbs"] == 6   # settings as given
    paths = write_outputs(result, tmp_path, figures=False, trajectories=True)
    assert json.loads(paths["metrics"].read_text())["summary"]["mpc_solves_total"] == 8
    assert {"trajectories.csv", "trajectories.npz"} <= set(paths)
    assert "8 solves in 8 device calls" in summary_markdown(result)
