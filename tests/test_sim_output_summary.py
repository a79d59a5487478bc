"""Summaries that tell the truth: stops (count, longest, when) and arrival per ship and run, aggregated, in
metrics.json and summary.md; one encounter classification -- the COLREGS evaluation tool's -- in every table
(a target the old classifier called head-on at t0 and the tool calls crossing stand-on).  Synthetic
trajectories, no solver."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from psbmpc_jax.evaltool import evaluate_tracks, get_params, tracks_from_simulation
from psbmpc_jax.scenario import scenario_from_dict
from psbmpc_jax.sim import SimulationResult
from psbmpc_jax.sim.metrics import aggregate, run_metrics
from psbmpc_jax.sim.output import colregs_evaluation, metrics_document, summary_markdown, write_outputs
from psbmpc_jax.sim.simulator import COST_NAMES, summarize
from psbmpc_jax.sim.simulator import run_metrics as sim_run_metrics
from psbmpc_jax.sim.situations import SITUATION_NAMES, first_encounters
from psbmpc_jax.sim.stops import (STOP_MIN_DURATION_S, STOP_SPEED_MPS, aggregate_ships, arrival, ship_metrics,
                                  stop_intervals, stop_metrics)


# ==================================================================================================== stops
def stops_reference(t, u, thr, dmin):
    """Plain-Python reference: walk the samples, collect the slow stretches, keep those lasting >= dmin."""
    out, start = [], None
    for k in range(len(t)):
        slow = u[k] <= thr
        if slow and start is None:
            start = k
        if start is not None and (not slow or k == len(t) - 1):
            end = k if slow else k - 1
            if t[end] - t[start] >= dmin:
                out.append((float(t[start]), float(t[end])))
            start = None
    return out


def test_stop_intervals_against_a_reference():
    rng = np.random.default_rng(1)
    for _ in range(300):
        n = int(rng.integers(1, 60))
        t = np.cumsum(rng.uniform(0.1, 2.0, n))
        u = np.where(rng.uniform(size=n) < 0.5, rng.uniform(0, 0.25, n), rng.uniform(0, 3, n))
        dmin = float(rng.choice([0.0, 1.0, 5.0]))
        assert stop_intervals(t, u, 0.2, dmin) == stops_reference(t, u, 0.2, dmin)


def test_stops_by_hand():
    t = np.arange(0.0, 31.0)                                     # 0 .. 30 s
    u = np.full(t.size, 2.0)
    u[3:6] = 0.1                                                 # 3..5: 2 s, too short to be a stop
    u[10:17] = 0.0                                               # 10..16: 6 s
    u[20:26] = STOP_SPEED_MPS                                    # 20..25: 5 s exactly (at the threshold: stopped)
    u[28:] = 0.05                                                # 28..30: 2 s at the end, too short
    assert STOP_SPEED_MPS == 0.2 and STOP_MIN_DURATION_S == 5.0
    assert stop_intervals(t, u) == [(10.0, 16.0), (20.0, 25.0)]
    assert stop_metrics(t, u) == {"stops": 2, "longest_stop_s": 6.0, "longest_stop_start_s": 10.0,
                                  "stopped_time_s": 11.0}
    assert stop_metrics(t, np.full(t.size, 1.0)) == {"stops": 0, "longest_stop_s": 0.0, "longest_stop_start_s": None,
                                                     "stopped_time_s": 0.0}
    u2 = u.copy()
    u2[20:27] = 0.0                                              # 20..26: 6 s, a tie: the first one counts
    assert stop_metrics(t, u2)["longest_stop_start_s"] == 10.0
    assert stop_metrics(t, np.zeros(t.size))["longest_stop_s"] == 30.0      # stopped the whole run
    for bad, match in (((t, u[:-1]), "speed must have the shape"), ((t[::-1], u), "strictly increasing"),
                       ((t, np.where(t > 3, np.nan, 1.0)), "finite")):
        with pytest.raises(ValueError, match=match):
            stop_intervals(*bad)
    with pytest.raises(ValueError, match="min_duration must be >= 0"):
        stop_intervals(t, u, min_duration=-1)


def test_arrival_by_hand():
    t = np.arange(5.0)
    pos = np.array([[0.0, 0.0], [4.0, 0.0], [8.0, 0.0], [9.5, 0.0], [12.0, 0.0]])
    route = np.array([[0.0, 0.0], [10.0, 0.0]])
    assert arrival(t, pos, route, 2.0) == {"arrived": True, "arrival_time_s": 2.0}    # 2 m away at t = 2: within
    assert arrival(t, pos, route, 0.1) == {"arrived": False, "arrival_time_s": None}
    assert arrival(t, pos, route, None) == {"arrived": None, "arrival_time_s": None}
    with pytest.raises(ValueError, match="positions must have shape"):
        arrival(t, pos[:3], route, 1.0)


def test_ship_metrics_and_their_aggregate():
    t = np.arange(0.0, 21.0)
    def ship(u, north0=0.0):
        return np.column_stack([north0 + np.cumsum(u) - u[0], np.zeros_like(t), np.zeros_like(t), u])
    moving = np.full(t.size, 1.0)
    stopping = moving.copy()
    stopping[5:12] = 0.0                                         # 5..11: 6 s
    routes = [np.array([[0.0, 0.0], [10.0, 0.0]]), None]
    run0 = ship_metrics(t, np.stack([ship(moving), ship(stopping, 50)]), ["OS", "TS"], routes, [0.5, None])
    run1 = ship_metrics(t, np.stack([ship(stopping), ship(moving, 50)]), ["OS", "TS"], routes, [0.5, None])
    assert run0[0] == {"name": "OS", "stops": 0, "longest_stop_s": 0.0, "longest_stop_start_s": None,
                       "stopped_time_s": 0.0, "arrived": True, "arrival_time_s": 10.0}
    assert run1[0]["stops"] == 1 and run1[0]["longest_stop_start_s"] == 5.0
    assert run1[0]["arrival_time_s"] == 17.0                     # 10 m, 7 samples later than without the stop
    assert run0[1]["arrived"] is None                            # no route given: not judged
    agg = aggregate_ships([run0, run1])
    os_, ts = agg
    assert os_["runs"] == 2 and os_["stops_total"] == 1 and os_["runs_with_stops"] == 1
    assert os_["longest_stop"] == {"s": 6.0, "run": 1, "start_s": 5.0}
    assert os_["longest_stop_s"] == {"min": 0.0, "mean": 3.0, "median": 3.0, "max": 6.0, "n": 2}
    assert os_["arrived_runs"] == 2 and os_["arrival_time_s"] == {"min": 10.0, "mean": 13.5, "median": 13.5,
                                                                  "max": 17.0, "n": 2}
    assert ts["longest_stop"] == {"s": 6.0, "run": 0, "start_s": 5.0} and ts["arrived_runs"] is None
    json.dumps(agg, allow_nan=False)


def test_run_metrics_carry_the_stops():
    t = np.arange(0.0, 41.0)
    u = np.full(t.size, 1.0)
    u[10:21] = 0.0
    own = np.column_stack([np.cumsum(u) - u[0], np.zeros_like(t), np.zeros_like(t), u])
    tgt = own.copy()
    tgt[:, 1] = 300.0
    kw = dict(d_collision=1.0, ground_clearance=0.0, arrival_radius=1.0, own_name="OS",
              target_routes=[np.array([[0.0, 300.0], [5.0, 300.0]])], target_arrival_radii=[1.0])
    m = run_metrics(t, own, tgt[None], np.array([[0.0, 0.0], [25.0, 0.0]]), (), **kw)
    assert (m["stops"], m["longest_stop_s"], m["longest_stop_start_s"], m["stopped_time_s"]) == (1, 10.0, 10.0, 10.0)
    assert [s["name"] for s in m["ships"]] == ["OS", "target_0"]
    assert m["ships"][0]["arrival_time_s"] == 35.0 and m["ships"][1]["arrival_time_s"] == 4.0
    s = aggregate([m, m])
    assert s["stops_total"] == 2 and s["runs_with_stops"] == 2 and s["ships"][0]["longest_stop"]["run"] == 0
    with pytest.raises(ValueError, match="target_routes and target_arrival_radii need one entry per target"):
        run_metrics(t, own, tgt[None], np.array([[0.0, 0.0], [25.0, 0.0]]), (), d_collision=1.0,
                    ground_clearance=0.0, target_routes=[], target_arrival_radii=[])


# =================================================================================== synthetic closed loops
SCENARIO = {
    "name": "truth", "description": "own-ship stops once; TS1 crossing from port at a fine angle, TS2 far away",
    "simulation": {"dt_s": 0.5, "duration_s": 120},
    "monte_carlo": {"runs": 2, "seed": 3},
    "mpc": {"preset": "nidelva", "update_period_s": 5, "speed_factors": [[1.0, 0.0]], "course_offsets_deg": [[0]]},
    "own_ship": {"name": "OS", "position_m": [0, 0], "course_deg": 0, "speed_mps": 2,
                 "waypoints_m": [[0, 0], [150, 0]]},
    "targets": [{"name": "TS1", "position_m": [285.3, -92.7], "course_deg": 144, "speed_mps": 2, "colav": "none"},
                {"name": "TS2", "position_m": [5000, 5000], "course_deg": 90, "speed_mps": 2, "colav": "none"}],
    "evaluation": {"preset": "default"},
}


def make_result(runs: int = 2) -> SimulationResult:
    """Straight motion; the own-ship stops from t = 20 s (run 0: 25 s, run 1: 10 s) and then goes on north."""
    sc = scenario_from_dict(SCENARIO)
    t = np.arange(241) * 0.5
    states = np.zeros((runs, 3, t.size, 4))
    for r in range(runs):
        u = np.full(t.size, 2.0)
        u[(t >= 20) & (t <= 20 + (25 if r == 0 else 10))] = 0.0
        north = np.concatenate([[0.0], np.cumsum(u[:-1] * 0.5)])
        states[r, 0] = np.column_stack([north, np.zeros_like(t), np.zeros_like(t), u])
        for i, tg in enumerate(SCENARIO["targets"], start=1):
            chi = math.radians(tg["course_deg"])
            n0, e0 = tg["position_m"]
            states[r, i] = np.column_stack([n0 + 2 * t * math.cos(chi), e0 + 2 * t * math.sin(chi),
                                            np.full_like(t, chi), np.full_like(t, 2.0)])
    M = 24
    res = SimulationResult(scenario=sc, t=t, states=states, track_x=np.full((runs, 2, t.size, 4), np.nan),
                           track_P=np.full((runs, 2, t.size, 4, 4), np.nan), solve_t=t[::10][:M],
                           offsets=np.full((runs, 3, M, 2), np.nan), best_costs=np.full((runs, 3, M, len(COST_NAMES)),
                                                                                         np.nan),
                           calls=[{"t_s": 0.0, "solves": runs, "device_calls": runs, "wall_s": 0.01}], snapshot=None,
                           metrics=[], solve_wall=np.full((runs, 3, M), np.nan))
    res.metrics = [sim_run_metrics(res, r) for r in range(runs)]
    res.summary = summarize(res, mode="loop", grid_exceeded=None)
    return res


@pytest.fixture(scope="module")
def truth():
    return make_result()


def test_first_encounters_are_the_evaluation_tools(truth):
    p = truth.scenario.evaluation
    for r in range(2):
        st = truth.states[r]
        found = first_encounters(truth.t, st[0], st[1:], p)
        ev = evaluate_tracks(tracks_from_simulation(truth)[r], p)
        for j, name in enumerate(("TS1", "TS2")):
            encs = ev.of(other=name)
            if not encs:
                assert found[j] == {"situation": None, "encounter": "none", "t_start_s": None, "t_detect_s": None}
                continue
            assert found[j]["situation"] == encs[0].situation
            assert found[j]["t_start_s"] == pytest.approx(encs[0].t_start)
            assert found[j]["encounter"] == SITUATION_NAMES[encs[0].situation]
    assert [f["situation"] for f in found] == ["CRSO", None]     # TS2 never within r_Stage2 (2500 m)


def test_one_classification_in_every_table(truth, tmp_path):
    """TS1 starts 18 deg off the bow on each side (|beta|, |alpha| < 22.5 deg): the metrics' own t0 rule calls it
    head-on; the evaluation tool (13 deg head-on sector) crossing stand-on.  Every table says CRSO now."""
    from psbmpc_jax.sim.metrics import encounter_type

    st = truth.states[0]
    assert encounter_type(truth.t, st[0], st[1], None)[0] == "head-on"          # what the old tables said
    for m in truth.metrics:
        tg = {x["name"]: x for x in m["targets"]}
        assert (tg["TS1"]["encounter"], tg["TS1"]["situation"]) == ("crossing-stand-on", "CRSO")
        assert tg["TS1"]["compliance"]["encounter"] == "crossing-stand-on"
        assert tg["TS1"]["compliant"] is True                                  # it never turned to port
        assert (tg["TS2"]["encounter"], tg["TS2"]["situation"], tg["TS2"]["compliant"]) == ("none", None, None)
        assert "never came within the evaluation's r_stage2 (2500 m)" in tg["TS2"]["compliance"]["reason"]
    ev = colregs_evaluation(truth)
    md = summary_markdown(truth, ev)
    rows = [ln for ln in md.splitlines() if ln.startswith("| TS1 | CRSO")]
    assert len(rows) == 2                                                  # the first table and the EvalTool's
    assert not [ln for ln in md.splitlines() if ln.startswith("| TS1 |") and "head-on" in ln]
    assert "| TS2 | none: 2 |" in md
    doc = metrics_document(truth, evaluation=ev)
    sits = {p["other"]: p["situations"] for p in doc["colregs_evaluation"]["aggregate"]["pairs"]}
    assert sits == {"TS1": {"CRSO": 2}}
    assert {t["name"]: t["situations"] for t in doc["summary"]["targets"]} == {"TS1": {"CRSO": 2}, "TS2": {"none": 2}}


def test_stops_and_arrival_in_metrics_and_summary(truth, tmp_path):
    m0, m1 = truth.metrics
    assert (m0["stops"], m0["longest_stop_s"], m0["longest_stop_start_s"]) == (1, 25.0, 20.0)
    assert (m1["stops"], m1["longest_stop_s"], m1["longest_stop_start_s"]) == (1, 10.0, 20.0)
    # 40 m before the stop, on again from 45.5 s (30.5 s) at 2 m/s: 145 m, R_a = 5 m short of the last waypoint,
    # at 98 s (83 s)
    assert m0["ships"][0]["arrival_time_s"] == 98.0 and m1["ships"][0]["arrival_time_s"] == 83.0
    s = truth.summary
    own = s["ships"][0]
    assert own["name"] == "OS" and own["longest_stop"] == {"s": 25.0, "run": 0, "start_s": 20.0}
    assert own["arrived_runs"] == 2 and own["arrival_time_s"]["min"] == 83.0
    assert s["stops_total"] == 2 and s["runs_with_stops"] == 2 and s["longest_stop_s"]["max"] == 25.0
    write_outputs(truth, tmp_path / "r", figures=False)
    doc = json.loads((tmp_path / "r" / "metrics.json").read_text())
    assert doc["runs"][0]["ships"][0]["longest_stop_start_s"] == 20.0
    assert doc["summary"]["ships"][0]["longest_stop"] == {"s": 25.0, "run": 0, "start_s": 20.0}
    md = (tmp_path / "r" / "summary.md").read_text()
    assert ("**own-ship stops: 2 in 2 of 2 runs, longest 25.0 s (run 0, from t = 20.0 s); arrived at its last "
            "waypoint: 2 of 2 runs**") in md
    assert "| OS | 2 of 2 | 2 | 25.0 (run 0, from t = 20.0 s) | 2 of 2 | 83.0 / 90.5 / 98.0 |" in md
    assert "| TS1 | 0 of 2 | 0 | — |" in md
    assert "at or below 0.2 m/s for at least 5 s" in md


def test_scenario_settings_store_the_evaluation(truth):
    doc = metrics_document(truth)
    assert doc["scenario"]["evaluation"] == get_params("default").as_dict()
