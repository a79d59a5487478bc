"""The explanation of every score (psbmpc_jax.evaltool.explain, ``psbmpc-jax evaluate --explain``):

* the explained terms recompose the reported S_safety and S_sit to 1e-12 through the documented formulas
  (written out again here, independently of the scoring code), for every encounter of the scripted cases of
  docs/evaltool.md (T1–T7, both roles) and of a committed closed-loop run (head_on, whose re-scored tracks give
  the committed metrics.json scores);
* each penalty names the sample that fired it and the condition (the late manoeuvre of T3, the port turn of T2,
  the stand-on port turn of T6, no manoeuvre in T4) and the stage entries are where the range crosses the
  stage radii;
* the command line prints the explanation and writes explain.json, explain.txt and one figure per encounter
  into a run folder (never into an input's folder; another run's folder only with --force).
"""

from __future__ import annotations

import json
import math
import pathlib

import numpy as np
import pytest
from conftest import run_cli

from psbmpc_jax.evaltool import EvalParams, evaluate_file, evaluate_tracks, get_params
from psbmpc_jax.evaltool.explain import COMPOSITION, explain_encounter, explanation_text
from psbmpc_jax.evaltool.synthetic import scripted_tracks
from psbmpc_jax.runfolder import read_manifest

INLAND = get_params("inland_small")
T_80 = 100 - 80 / math.sqrt(2)
ROOT = pathlib.Path(__file__).resolve().parents[1]
COMMITTED = ROOT / "experiments" / "colregs_explain" / "tracks" / "head_on.npz"
COMMITTED_METRICS = ROOT / "experiments" / "closed_loop" / "results" / "head_on" / "metrics.json"


def own(knots=(), speed=1.0):
    return dict(start_ne=(0.0, 0.0), course_deg=0.0, speed_mps=speed, course_knots=list(knots))


HO_T = dict(start_ne=(200.0, 0.0), course_deg=180.0, speed_mps=1.0)
CR_STBD = dict(start_ne=(100.0, 100.0), course_deg=270.0, speed_mps=1.0)
CR_PORT = dict(start_ne=(100.0, -100.0), course_deg=90.0, speed_mps=1.0)
OT_T = dict(start_ne=(100.0, 0.0), course_deg=0.0, speed_mps=0.5)
OT_OWN = [(20, 0), (25, -30), (45, -30), (50, 0)]

CASES = {
    "T1": {"O": own([(60, 0), (70, 30)]), "T": HO_T},
    "T2": {"O": own([(60, 0), (70, -30)]), "T": HO_T},
    "T3": {"O": own([(80, 0), (90, 30)]), "T": HO_T},
    "T4": {"O": own(), "T": HO_T},
    "T5": {"O": own([(T_80, 0), (T_80 + 10, -30)]), "T": CR_STBD},
    "T5c": {"O": own([(T_80, 0), (T_80 + 10, 8)]), "T": CR_STBD},
    "T6": {"O": own([(70, 0), (80, -30)]), "T": CR_PORT},
    "T6_gw": {"O": own([(70, 0), (80, -30)]), "T": CR_PORT,
              "X": dict(start_ne=(120.0, 110.0), course_deg=270.0, speed_mps=1.0)},
    "T6b": {"O": own([(70, 0), (80, 30)]), "T": CR_PORT},
    "T6c": {"O": own(), "T": dict(CR_PORT, course_knots=[(T_80, 90), (T_80 + 10, 120)])},
    "T7": {"O": own(OT_OWN + [(115, 0), (125, 90)], speed=1.5), "T": OT_T},
    "T7_ref": {"O": own(OT_OWN, speed=1.5), "T": OT_T},
}


@pytest.fixture(scope="module")
def evaluations():
    return {name: evaluate_tracks(scripted_tracks(v, 200.0), INLAND, pairs="all") for name, v in CASES.items()}


# --------------------------------------------------------------------- the documented formulas, written again
def range_score(r: float, p: EvalParams) -> float:
    if r >= p.r_pref_m:
        return 1.0
    if r < p.r_col_m:
        return 0.0
    if r >= p.r_min_m:
        return 1 - p.gamma_min * (p.r_pref_m - r) / (p.r_pref_m - p.r_min_m)
    if r >= p.r_nm_m:
        return 1 - p.gamma_min - p.gamma_nm * (p.r_min_m - r) / (p.r_min_m - p.r_nm_m)
    return 1 - p.gamma_min - p.gamma_nm - p.gamma_col * (p.r_nm_m - r) / (p.r_nm_m - p.r_col_m)


def recompose(x: dict, p: EvalParams) -> tuple[float, float | None]:
    """(S_safety, S_sit) from the explained terms alone."""
    v = {d["name"]: d["value"] for d in x["terms"]}
    r_cpa = x["cpa"]["r_m"]
    assert v["S_r"] == pytest.approx(range_score(r_cpa, p), abs=1e-12)
    assert v["S_theta"] == pytest.approx(p.gamma_alpha * v["S_alpha"] + p.gamma_beta * v["S_beta"], abs=1e-12)
    if r_cpa < p.r_col_m:
        s_safety = 0.0
    elif v["S_r"] >= 1:
        s_safety = 1.0
    else:
        s_safety = v["S_r"] + (1 - v["S_r"]) * v["S_theta"]
    sit = x["situation"]
    if x["status"] != "scored":
        return s_safety, None
    if sit == "HO":
        s = (max(0.0, 1 - p.gamma_ho_nsb * v["P_nsb"] - p.gamma_ho_sts * v["P_sts"]) * (1 - v["P_delay"])
             * (1 - v["P_na_delta_chi"]))
    elif sit in ("OTGW", "CRGW"):
        s16 = s_safety * (1 - v["P_delay"]) * (1 - v["P_na_delta"])
        assert v["S16"] == pytest.approx(s16, abs=1e-12)
        s = max(0.0, s16 - (p.gamma_ahead_ot * v["P_ah13"] if sit == "OTGW" else p.gamma_ahead_cr * v["P_ah15"]))
    else:
        s = s_safety * (1 - (v["P_2"] or 0.0)) * (1 - max(v["P_3"] or 0.0, v["P_pt"]))
    return s_safety, s


def check_recomposes(ev) -> int:
    n = 0
    for e in ev.encounters:
        x = explain_encounter(ev, e)
        if e.status in ("incomplete", "not_moving"):
            assert x["terms"] == []
            continue
        s_safety, s_sit = recompose(x, ev.params)
        assert abs(s_safety - e.scores.S_safety) <= 1e-12
        if s_sit is not None:
            assert abs(s_sit - e.scores.S_sit) <= 1e-12, (e.vessel, e.other, s_sit, e.scores.S_sit)
            n += 1
        # every reported score is explained, with the same value
        reported = {k: v for k, v in e.scores.to_dict().items() if v is not None and k != "S_sit"}
        explained = {d["name"]: d["value"] for d in x["terms"] if d["value"] is not None}
        assert reported == pytest.approx(explained, abs=0) and len(explained) == len(x["terms"]) - sum(
            d["value"] is None for d in x["terms"])
    return n


@pytest.mark.parametrize("case", sorted(CASES))
def test_explained_terms_recompose_the_scores(evaluations, case):
    ev = evaluations[case]
    assert check_recomposes(ev) >= 1


def test_every_situation_is_covered(evaluations):
    seen = {e.situation for ev in evaluations.values() for e in ev.encounters if e.status == "scored"}
    assert seen == set(COMPOSITION)


def test_committed_closed_loop_run_is_rescored_and_recomposes():
    stored = json.loads(COMMITTED_METRICS.read_text())["colregs_evaluation"]
    p = EvalParams(**stored["params"])
    evs = evaluate_file(COMMITTED, p)
    assert len(evs) == len(stored["runs"]) == 20
    n = 0
    for ev, encs in zip(evs, stored["runs"]):
        assert [e.other for e in ev.encounters] == [d["other"] for d in encs]
        for e, d in zip(ev.encounters, encs):                 # the committed scores, to their 6 digits
            for key, value in d["scores"].items():
                assert getattr(e.scores, key) == pytest.approx(value, rel=1e-5, abs=1e-6), key
        n += check_recomposes(ev)
    assert n == 20


# ------------------------------------------------------------------------------------------ when and why
def term(x, name):
    return next(d for d in x["terms"] if d["name"] == name)


def only_x(ev, vessel="O", other="T"):
    (e,) = ev.of(vessel, other)
    return e, explain_encounter(ev, e)


def test_late_manoeuvre_fires_p_delay_at_its_start(evaluations):
    ev = evaluations["T3"]
    e, x = only_x(ev)
    d = term(x, "P_delay")
    assert d["k"] == e.maneuver.start and d["r_m"] == pytest.approx(e.r_maneuver)
    assert d["stage"] == 3 and "first manoeuvre (course +" in d["why"]
    assert x["dominant"] == "P_delay"
    # its cost: S14 would be (1 − 0.6 P_sts)(1 − P_Δχ^¬ap) without it
    s = e.scores
    assert x["costs"]["P_delay"] == pytest.approx((1 - 0.6 * s.P_sts) - s.S14, abs=1e-12)
    (m,) = [m for m in x["maneuvers"] if "P_delay" in m["fires"]]
    assert m["t_start_s"] == pytest.approx(78, abs=2) and m["delta_course_deg"] > 25


def test_no_action_and_port_turns(evaluations):
    _, x = only_x(evaluations["T4"])
    assert term(x, "P_delay")["value"] == 1 and term(x, "P_delay")["k"] is None
    assert "no manoeuvre" in term(x, "P_delay")["why"]
    e, x = only_x(evaluations["T2"])
    d = term(x, "P_nsb")
    assert d["value"] == 1 and "mainly a port turn" in d["why"] and d["data"]["turn_port_deg"] > 25
    assert e.k_start <= d["k"] <= e.k_cpa
    e, x = only_x(evaluations["T6"])
    d = term(x, "P_pt")
    assert d["value"] == pytest.approx(0.7) and d["data"]["beta_start_deg"] < 0 and d["data"]["delta_course_deg"] < 0
    # max(P_3, P_pt): P_3 alone costs nothing, P_pt alone 0.5 − 0.3, both 1 − 0.3
    assert x["costs"]["P_3"] == 0.0 and x["costs"]["P_pt"] == pytest.approx(0.5 - 0.3, abs=1e-12)
    assert x["dominant"] == "P_3+P_pt" and x["costs"]["P_3+P_pt"] == pytest.approx(0.7, abs=1e-12)
    assert term(x, "P_3")["k"] is not None and term(x, "P_2")["value"] == 0
    _, x = only_x(evaluations["T6_gw"])
    assert term(x, "C_3_gw")["data"]["give_way_to"] == "X"
    _, x = only_x(evaluations["T7"])
    assert x["dominant"] == "P_ah13" and "inside the ahead band" in term(x, "P_ah13")["why"]
    _, x = only_x(evaluations["T1"])
    assert x["S_sit"] > 0.95 and x["dominant"] == "P_sts"


def test_stage_entries_are_the_crossings_of_the_stage_radii(evaluations):
    ev = evaluations["T6"]
    e, x = only_x(ev)
    tr = ev.resampled
    r = np.hypot(tr.north[1] - tr.north[0], tr.east[1] - tr.east[0])
    entries = {s["stage"]: s for s in x["stages"]}
    assert entries[1]["t_s"] == 0
    for stage, radius in ((2, INLAND.r_stage2_m), (3, INLAND.r_stage3_m), (4, INLAND.r_stage4_m)):
        k = entries[stage]["k"]
        assert r[k] <= radius < r[k - 1] and entries[stage]["radius_m"] == radius
    assert entries[2]["t_s"] == pytest.approx(44) and entries[3]["t_s"] == pytest.approx(69)
    text = explanation_text(x)
    assert "stages   1 from t 0 s" in text and "P_pt" in text and "dominant: P_3+P_pt" in text


# -------------------------------------------------------------------------------------------- command line


def write_csv(path, vessels):
    tr = scripted_tracks(vessels, 200.0, step_s=0.5)
    rows = ["t_s,vessel,north_m,east_m,course_deg,speed_mps"]
    for k in range(0, tr.t.size, 2):
        for v, name in enumerate(tr.names):
            rows.append(f"{tr.t[k]:g},{name},{float(tr.north[v, k])!r},{float(tr.east[v, k])!r},"
                        f"{math.degrees(tr.course[v, k])!r},{float(tr.speed[v, k])!r}")
    path.write_text("\n".join(rows) + "\n")
    return path


def test_cli_explain_prints_and_writes_a_folder(tmp_path):
    (tmp_path / "in").mkdir()
    csv = write_csv(tmp_path / "in" / "t6.csv", CASES["T6_gw"])
    out = tmp_path / "explained"
    rc, text, err = run_cli(["evaluate", str(csv), "--preset", "inland_small", "--explain", "--out", str(out)])
    assert rc == 0, err
    assert "dominant: P_3+P_pt" in text and "term" in text and "stages   1 from t 0 s" in text
    doc = json.loads((out / "explain.json").read_text())
    assert doc["schema"] == "psbmpc-explain/1" and doc["params"] == INLAND.as_dict()
    encs = doc["files"][0]["encounters"]
    assert [(x["vessel"], x["other"]) for x in encs] == [("O", "T"), ("O", "X")]
    manifest = read_manifest(out)
    assert manifest["complete"] and set(manifest["files"]) == {"explain.json", "explain.txt"} | {
        x["figure"] for x in encs}
    assert all((out / x["figure"]).stat().st_size > 10_000 for x in encs)
    assert (out / "explain.txt").read_text().strip() in text
    # again: refused without --force, replaced with it
    rc, _, err = run_cli(["evaluate", str(csv), "--preset", "inland_small", "--explain", "--out", str(out)])
    assert rc == 2 and "holds the results of another run" in err
    rc, _, err = run_cli(["evaluate", str(csv), "--preset", "inland_small", "--explain", "--out", str(out),
                          "--force"])
    assert rc == 0, err
    assert read_manifest(out)["run_id"] != manifest["run_id"]
    # never into the input's folder, never onto a file
    for bad, msg in ((csv.parent, "which this command reads"), (csv, "with --explain, --out is a folder")):
        rc, _, err = run_cli(["evaluate", str(csv), "--preset", "inland_small", "--explain", "--out", str(bad),
                              "--force"])
        assert rc == 2 and msg in err
    assert csv.is_file()


def test_cli_explain_without_out_only_prints(tmp_path):
    csv = write_csv(tmp_path / "t3.csv", CASES["T3"])
    rc, text, err = run_cli(["evaluate", str(csv), "--preset", "inland_small", "--explain"])
    assert rc == 0, err
    assert "HO scored  S14 = 0.4" in text and "dominant: P_delay" in text
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t3.csv"]
