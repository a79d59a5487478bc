"""EvalTool input and bookkeeping: parameters and presets, the user CSV format and its errors, the simulator's
trajectory export, evaluate_file and the aggregation over runs."""

from __future__ import annotations

import json
import math
import pathlib
from types import SimpleNamespace

import numpy as np
import pytest

from psbmpc_jax.evaltool import (PRESETS, SCORE_NAMES, EvalParams, Tracks, aggregate, evaluate_file,
                                 evaluate_tracks, get_params, load_runs, load_tracks, tracks_from_simulation)
from psbmpc_jax.evaltool.synthetic import scripted_tracks

HEAD_ON = {"own": dict(start_ne=(0.0, 0.0), course_deg=0.0, speed_mps=1.0, course_knots=[(60, 0), (70, 30)]),
           "ferry": dict(start_ne=(200.0, 0.0), course_deg=180.0, speed_mps=1.0)}


# ------------------------------------------------------------------------------------------------- params
def test_presets():
    assert set(PRESETS) >= {"default", "inland_small"}
    d, s = get_params("default"), get_params("inland_small")
    assert d == EvalParams() and d.r_stage2_m == 2500 and d.r_pref_m == 190
    assert (s.r_stage2_m, s.r_stage3_m, s.r_stage4_m) == (80, 45, 16)
    assert (s.r_pref_m, s.r_min_m, s.r_nm_m, s.r_col_m) == (7, 6, 5, 4)
    assert (s.delta_course_app_deg, s.delta_course_md_deg) == (13, 1)
    assert (s.delta_speed_app_rel, s.delta_speed_md_rel) == (0.2, 0.1)
    assert s.gamma_ho_sts == d.gamma_ho_sts and s.epsilon_speed_mps == 0.2          # everything else default
    assert get_params("inland_small", r_pref_m=8).r_pref_m == 8


def test_params_are_frozen_and_serialisable():
    p = EvalParams()
    with pytest.raises(Exception):
        p.r_pref_m = 1.0                                       # frozen
    assert json.loads(json.dumps(p.as_dict()))["gamma_pt"] == 0.7


@pytest.mark.parametrize("change, message", [
    (dict(r_stage3_m=3000.0), r"r_stage2_m must be in \(3000, inf\)"),
    (dict(r_stage4_m=-1.0), r"r_stage4_m must be in \(0, inf\)"),
    (dict(gamma_pt=1.5), r"gamma_pt must be in \[0, 1\], got 1.5"),
    (dict(delta_course_app_deg=1.0), r"delta_course_app_deg must be in \(2, 180\]"),
    (dict(sample_interval_s=0.0), r"sample_interval_s must be in \(0, inf\)"),
    (dict(stand_on_mode="lenient"), r"stand_on_mode must be one of \('reproduce', 'intended'\)"),
    (dict(delay_reference="x"), r"delay_reference must be one of"),
    (dict(risk_gate=1), r"risk_gate must be True or False"),
    (dict(r_min_m=float("nan")), r"r_min_m must be a finite number"),
])
def test_params_validation_names_the_field_and_range(change, message):
    with pytest.raises(ValueError, match=message):
        EvalParams().replace(**change)


def test_unknown_preset_and_field():
    with pytest.raises(ValueError, match="unknown EvalTool preset 'open_sea'; known: default, inland_small"):
        get_params("open_sea")
    with pytest.raises(ValueError, match="unknown EvalParams field"):
        get_params("default", r_pref=3)


# --------------------------------------------------------------------------------------------- user CSV
def write_user_csv(path, tracks: Tracks, with_course=True, order="time-major"):
    lines = ["t_s,vessel,north_m,east_m" + (",course_deg,speed_mps" if with_course else "")]
    idx = [(k, v) for k in range(tracks.t.size) for v in range(tracks.n_vessels)]
    if order == "vessel-major":
        idx.sort(key=lambda kv: (kv[1], kv[0]))
    for k, v in idx:
        row = f"{tracks.t[k]:.6f},{tracks.names[v]},{tracks.north[v, k]:.6f},{tracks.east[v, k]:.6f}"
        if with_course:
            row += f",{math.degrees(tracks.course[v, k]):.6f},{tracks.speed[v, k]:.6f}"
        lines.append(row)
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture(scope="module")
def head_on_tracks():
    return scripted_tracks(HEAD_ON, 200, step_s=0.5)


@pytest.mark.parametrize("with_course, order", [(True, "time-major"), (False, "vessel-major")])
def test_user_csv_round_trip(tmp_path, head_on_tracks, with_course, order):
    path = write_user_csv(tmp_path / "tracks.csv", head_on_tracks, with_course, order)
    tr = load_tracks(path)
    assert tr.names == ("own", "ferry") and tr.own == 0 and tr.t.size == head_on_tracks.t.size
    assert np.allclose(tr.north, head_on_tracks.north, atol=1e-5)
    ref = evaluate_tracks(head_on_tracks, "inland_small").encounters[0].scores
    got = evaluate_file(path, "inland_small")
    assert len(got) == 1 and got[0].source == str(path)
    assert got[0].encounters[0].scores.S14 == pytest.approx(ref.S14, abs=0.005)
    assert got[0].encounters[0].scores.S14 == pytest.approx(0.96, abs=0.01)


def test_user_csv_own_ship_by_name(tmp_path, head_on_tracks):
    path = write_user_csv(tmp_path / "tracks.csv", head_on_tracks)
    ev = evaluate_file(path, "inland_small", own="ferry")[0]
    assert ev.names[ev.own] == "ferry" and [e.vessel for e in ev.encounters] == ["ferry"]
    assert ev.encounters[0].scores.P_delay == 1                      # the ferry never acted
    with pytest.raises(ValueError, match="unknown own-ship 'tug'; vessels: own, ferry"):
        load_tracks(path, own="tug")


GOOD = "t_s,vessel,north_m,east_m\n0,a,0,0\n0,b,100,0\n1,a,1,0\n1,b,99,0\n2,a,2,0\n2,b,98,0\n"


@pytest.mark.parametrize("text, message", [
    ("t_s,vessel,north_m\n0,a,0\n1,a,1\n", r"missing column\(s\) east_m"),
    ("vessel,north_m,east_m\n", r"missing column\(s\) t_s"),
    (GOOD.replace("1,b,99,0", "1,b,abc,0"), r"row 5, column north_m: not a number: 'abc'"),
    (GOOD.replace("2,a,2,0", "0.5,a,2,0"), r"row 6: vessel 'a': time 0.5 s does not increase"),
    (GOOD.replace("2,b,98,0", "2,b,nan,0"), r"row 7, column north_m: NaN or infinite value"),
    ("t_s,vessel,north_m,east_m\n0,a,0,0\n0,b,1,1\n", r"vessel 'a': at least 2 samples are needed, got 1"),
    (GOOD.replace("2,b,98,0", "3,b,98,0"), r"vessel 'b' has different sample times"),
    (GOOD.replace("t_s,vessel,north_m,east_m", "t_s,vessel,north_m,east_m,course_deg"), r"both optional columns"),
    ("", r"empty file"),
    ("t_s,vessel,north_m,east_m\n", r"no data rows"),
    (GOOD.replace("1,a,1,0", "1,,1,0"), r"row 4: empty vessel id"),
])
def test_bad_user_csv_gives_clear_errors(tmp_path, text, message):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        load_tracks(path)


def test_good_small_csv_and_comments(tmp_path):
    path = tmp_path / "ok.csv"
    path.write_text("# AIS extract\n" + GOOD + "\n")
    tr = load_tracks(path, own="b")
    assert tr.own == 1 and np.allclose(tr.speed, 1.0) and np.allclose(np.degrees(tr.course[1]), 180)


def test_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError):
        load_tracks(tmp_path / "nope.csv")


def test_tracks_validation():
    t = np.arange(3.0)
    with pytest.raises(ValueError, match="at least 2 samples"):
        Tracks.from_arrays([0.0], [[0.0]], [[0.0]], [[0.0]], [[1.0]])
    with pytest.raises(ValueError, match="strictly increasing; sample 2"):
        Tracks.from_arrays([0, 1, 1], [t], [t], [t], [t])
    with pytest.raises(ValueError, match="east: NaN or infinite value for vessel 0 at sample 1"):
        Tracks.from_arrays(t, [t], [[0, np.nan, 0]], [t], [t])
    with pytest.raises(ValueError, match="give both course and speed"):
        Tracks.from_arrays(t, [t], [t], course=[t])
    with pytest.raises(ValueError, match="vessel names must be unique"):
        Tracks.from_arrays(t, [t, t], [t, t], names=["a", "a"])
    with pytest.raises(ValueError, match="shorter than one sample interval"):
        evaluate_tracks(Tracks.from_arrays([0, 0.5], [[0, 1], [5, 6]], [[0, 0], [0, 0]]), "inland_small")
    with pytest.raises(ValueError, match="pairs must be one of"):
        evaluate_tracks(Tracks.from_arrays(t, [t, t], [t, t + 1]), pairs="some")


def test_derived_course_holds_through_a_stop():
    t = np.arange(6.0)
    north = np.array([[0, 1, 2, 2, 2, 2.0]])
    east = np.array([[0, 0, 0, 0, 0, 1.0]])
    tr = Tracks.from_arrays(t, north, east)
    assert np.allclose(tr.speed[0, [0, 1, 3]], [1, 1, 0])
    assert np.allclose(tr.course[0, :3], 0) and tr.course[0, 3] == pytest.approx(0)   # held while stopped


# ---------------------------------------------------------------------------------------- simulator export
def fake_simulation(runs=2):
    """A SimulationResult-like object with what write_trajectories reads: run 0 turns to starboard (T1),
    run 1 never acts (T4)."""
    t = np.arange(0.0, 200.5, 0.5)
    states = np.zeros((runs, 2, t.size, 4))
    for r in range(runs):
        knots = [(60, 0), (70, 30)] if r == 0 else []
        tr = scripted_tracks({"OS": dict(HEAD_ON["own"], course_knots=knots), "TS1": HEAD_ON["ferry"]}, 200, 0.5)
        states[r] = np.stack([tr.north, tr.east, tr.course, tr.speed], axis=-1)
    M = 3
    return SimpleNamespace(
        scenario=SimpleNamespace(name="head_on_fake", ships=[SimpleNamespace(name="OS"), SimpleNamespace(name="TS1")]),
        t=t, states=states, solve_t=np.array([0.0, 5.0, 10.0]), offsets=np.full((runs, 2, M, 2), np.nan),
        best_costs=np.full((runs, 2, M, 5), np.nan), solve_wall=np.full((runs, 2, M), np.nan))


@pytest.mark.parametrize("fmt", ["npz", "csv"])
def test_simulator_export_is_read_per_run(tmp_path, fmt):
    from psbmpc_jax.sim.output import write_trajectories

    write_trajectories(fake_simulation(), tmp_path, formats=(fmt,))
    path = tmp_path / f"trajectories.{fmt}"
    runs = load_runs(path)
    assert len(runs) == 2 and runs[0].names == ("OS", "TS1") and runs[0].own == 0
    evs = evaluate_file(path, "inland_small")
    s14 = [ev.encounters[0].scores.S14 for ev in evs]
    assert s14[0] == pytest.approx(0.96, abs=0.01) and s14[1] == 0.0
    assert load_tracks(tmp_path, run=1).source.endswith("run 1")          # the folder works too
    with pytest.raises(ValueError, match="run 5 out of range: the file has 2 run"):
        load_tracks(path, run=5)


def test_tracks_from_a_simulation_result():
    from psbmpc_jax.evaltool import tracks_from_simulation

    runs = tracks_from_simulation(fake_simulation(), own="TS1")
    assert len(runs) == 2 and runs[1].own == 1 and runs[1].source == "head_on_fake run 1"
    ev = evaluate_tracks(runs[0], "inland_small")
    assert [(e.vessel, e.situation) for e in ev.encounters] == [("TS1", "HO")]
    assert ev.encounters[0].scores.P_delay == 1                     # the target never acted


# ------------------------------------------------------------------------------------------------ aggregate
def test_aggregate_over_runs():
    good = evaluate_tracks(scripted_tracks(HEAD_ON, 200), "inland_small", pairs="all")
    lazy = evaluate_tracks(scripted_tracks({"own": dict(HEAD_ON["own"], course_knots=[]),
                                            "ferry": HEAD_ON["ferry"]}, 200), "inland_small", pairs="all")
    agg = aggregate([good, lazy])
    assert agg["runs"] == 2 and agg["encounters"] == 4 and agg["situations"] == {"HO": 4}
    pair = next(p for p in agg["pairs"] if p["vessel"] == "own" and p["other"] == "ferry")
    st = pair["scores"]["S14"]
    s_good = good.of("own")[0].scores.S14
    assert st["n"] == 2 and st["min"] == 0.0 and st["max"] == pytest.approx(s_good)
    assert st["mean"] == pytest.approx(s_good / 2)
    assert pair["scores"]["S15"] == {"n": 0, "mean": None, "min": None, "max": None}   # None skipped, not 0
    assert pair["runs_with_encounter"] == 2 and set(pair["scores"]) == set(SCORE_NAMES)
    json.dumps(agg, allow_nan=False)
    assert aggregate(good)["runs"] == 1


# ------------------------------------------------------------------------------------------------------ docs
def test_docs_quick_start_runs_and_prints_what_it_says(capsys):
    import pathlib
    import re

    doc = (pathlib.Path(__file__).resolve().parents[1] / "docs" / "evaltool.md").read_text()
    block = re.findall(r"```python\n(.*?)```", doc, flags=re.S)[0]
    namespace: dict = {}
    exec(compile(block, "docs/evaltool.md", "exec"), namespace)  # noqa: S102 - our own documentation
    printed = capsys.readouterr().out.strip()
    promised = re.search(r"^# (ferry .*)$", block, flags=re.M).group(1)
    assert printed == promised
    assert namespace["summary"]["situations"] == {"HO": 1}


# ============================================================================= wiring: scenario key, run, CLI
def _head_on_dict(**evaluation):
    import yaml

    d = yaml.safe_load((pathlib.Path(__file__).resolve().parents[1] / "scenarios" / "head_on.yaml").read_text())
    d["simulation"]["duration_s"] = 200
    if evaluation:
        d["evaluation"] = evaluation
    return d


def test_scenario_evaluation_section_preset_scale_and_overrides():
    from psbmpc_jax.evaltool import PRESETS as EP
    from psbmpc_jax.scenario import load_scenario, scenario_from_dict

    assert load_scenario("head_on").evaluation.r_col_m == pytest.approx(5.0, rel=1e-6)          # 30 m x 1/6
    assert load_scenario("smooth_000_reconstruction").evaluation == EP["inland_small"]
    assert load_scenario("tengesdal2020_a").evaluation == EP["default"]
    sc = scenario_from_dict(_head_on_dict(preset="inland_small", range_scale=2, r_col_m=3))
    assert (sc.evaluation.r_stage2_m, sc.evaluation.r_nm_m, sc.evaluation.r_col_m) == (160.0, 10.0, 3.0)
    d = _head_on_dict()
    d.pop("evaluation", None)
    assert scenario_from_dict(d).evaluation == EP["default"]


@pytest.mark.parametrize("section, match", [
    ({"preset": "inland"}, r"evaluation.preset must be one of default, inland_small, got 'inland'"),
    ({"range_scale": 0}, r"evaluation.range_scale must be > 0"),
    ({"r_stage": 3}, r"unknown key 'r_stage' in evaluation; allowed: preset, range_scale, "),
    ({"r_col_m": -1}, r"evaluation: EvalParams.r_col_m must be"),
    ([1, 2], r"evaluation must be a mapping"),
])
def test_scenario_evaluation_section_errors(section, match):
    from psbmpc_jax.scenario import scenario_from_dict

    d = _head_on_dict()
    d["evaluation"] = section
    with pytest.raises(ValueError, match=match):
        scenario_from_dict(d)


def test_run_outputs_carry_the_scores(tmp_path):
    """``write_outputs`` puts the evaluation of every run into metrics.json and a table into summary.md; the
    per-run scores are those of evaluate_tracks on the same trajectories, and ``psbmpc-jax evaluate`` on the
    written trajectories gives the same numbers."""
    import json

    from psbmpc_jax.apps.cli import main
    from psbmpc_jax.scenario import scenario_from_dict
    from psbmpc_jax.sim import simulate
    from psbmpc_jax.sim.output import write_outputs

    sc = scenario_from_dict(_head_on_dict(range_scale=0.16666667))
    res = simulate(sc, runs=2)
    write_outputs(res, tmp_path, figures=False, trajectories=True)
    doc = json.loads((tmp_path / "metrics.json").read_text())
    ev = doc["colregs_evaluation"]
    assert ev["pairs"] == "own" and ev["params"]["r_col_m"] == pytest.approx(5.0)
    assert ev["aggregate"]["runs"] == 2 and len(ev["runs"]) == 2
    direct = [evaluate_tracks(tr, sc.evaluation) for tr in tracks_from_simulation(res)]
    for run, evd in zip(ev["runs"], direct):
        assert [e["situation"] for e in run] == [e.situation for e in evd.encounters] == ["HO"]
        assert run[0]["scores"]["S_sit"] == pytest.approx(evd.encounters[0].scores.S_sit, rel=1e-5)
        assert run[0]["scores"]["S_safety"] == pytest.approx(evd.encounters[0].scores.S_safety, rel=1e-5)
    md = (tmp_path / "summary.md").read_text()
    assert "## COLREGS evaluation" in md and "| TS1 | HO: 2 | scored: 2 |" in md
    out = tmp_path / "scores.json"
    assert main(["evaluate", str(tmp_path / "trajectories.npz"), "--range-scale", "0.16666667", "--out", str(out)]) == 0
    cli = json.loads(out.read_text())
    got = [r["encounters"][0]["scores"]["S_sit"] for r in cli["files"][0]["runs"]]
    assert got == pytest.approx([e.encounters[0].scores.S_sit for e in direct], rel=1e-9)


def test_evaluate_cli_errors(tmp_path, capsys):
    from psbmpc_jax.apps.cli import main

    bad = tmp_path / "bad.csv"
    bad.write_text("a,b\n1,2\n")
    assert main(["evaluate", str(bad)]) == 2
    assert "missing column(s) t_s, vessel, north_m, east_m" in capsys.readouterr().err
    assert main(["evaluate", str(tmp_path / "none.npz")]) == 2
    assert "not found" in capsys.readouterr().err
    for argv, match in ((["--set", "r_stag=3"], "--set: unknown field 'r_stag'"),
                        (["--set", "r_col_m"], "--set expects FIELD=VALUE"),
                        (["--set", "r_col_m=abc"], "--set r_col_m: a number expected"),
                        (["--range-scale", "-1"], "--range-scale must be a finite number > 0"),
                        (["--set", "r_col_m=500"], "EvalParams.r_nm_m must be in (500, inf) (above r_col_m)")):
        with pytest.raises(SystemExit) as exc:
            main(["evaluate", str(bad), *argv])
        assert exc.value.code == 2 and match in capsys.readouterr().err, argv
