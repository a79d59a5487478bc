"""COLREGS-typed encounter generation (psbmpc_jax.scenario_generation): the evaluation tool classifies the straight
tracks of what it generates as requested; ranges, seeds, files, charts and errors."""

from __future__ import annotations

import importlib.util
import json
import math
import pathlib

import numpy as np
import pytest
import shapely
from shapely.geometry import LineString, Point, Polygon

from psbmpc_jax.charts import Chart
from psbmpc_jax.evaltool import EvalParams, evaluate_tracks
from psbmpc_jax.scenario import load_scenario, scenario_from_dict
from psbmpc_jax.scenario_generation import (ENCOUNTER_TYPES, MANIFEST, SITUATION_CODES, classify_straight_line,
                                            generate_encounter, generate_encounters, get_settings, prepare,
                                            settings_from_dict, straight_line_tracks, write_scenarios)
from psbmpc_jax.scenario_generation.sectors import min_distance, pair_angles, start_time

REPO = pathlib.Path(__file__).resolve().parents[1]
N_PER_TYPE = 200

#: two square islands (inline chart section, local NED metres)
ISLANDS = {"polygons_m": [[[200, -100], [400, -100], [400, 100], [200, 100]],
                          [[-300, 200], [-100, 200], [-100, 400], [-300, 400]]]}
ISLAND_POLYS = [Polygon(r) for r in ISLANDS["polygons_m"]]


def _targets(scenario: dict):
    return scenario["targets"]


# ------------------------------------------------------------------------------------------ kernels vs NumPy
def test_kernels_match_a_dense_float64_reference():
    rng = np.random.default_rng(7)
    t = np.linspace(0.0, 2000.0, 200_001)                      # 10 ms steps
    for _ in range(40):
        p = rng.uniform(-800, 800, 2)
        v = rng.uniform(-5, 5, 2)
        r2 = rng.uniform(50, 600)
        rng_t = np.hypot(p[0] + v[0] * t, p[1] + v[1] * t)
        inside = np.flatnonzero(rng_t <= r2)
        ts = start_time(p, v, r2)
        if inside.size == 0:
            assert math.isnan(ts) or ts > 2000.0
        else:
            assert ts == pytest.approx(t[inside[0]], abs=1.1e-2)
        t_end = rng.uniform(10, 2000)
        sel = t <= t_end
        assert min_distance(p, v, t_end) == pytest.approx(rng_t[sel].min(), abs=1e-6 + 1e-2 * np.hypot(*v))
        chi_o, chi_t = rng.uniform(0, 360, 2)
        beta, alpha = pair_angles(p, chi_o, chi_t)
        los = math.degrees(math.atan2(p[1], p[0]))
        assert math.cos(math.radians(beta - (los - chi_o))) == pytest.approx(1.0)
        assert math.cos(math.radians(alpha - (los + 180.0 - chi_t))) == pytest.approx(1.0)
        assert -180.0 < beta <= 180.0 and -180.0 < alpha <= 180.0


# ------------------------------------------------------------------------------------------ classification
@pytest.mark.parametrize("kind", ENCOUNTER_TYPES)
def test_generated_encounters_are_classified_as_requested(kind):
    s = get_settings("harbour")
    batch = generate_encounters(kind, N_PER_TYPE, seed=11, validate=False)
    got = [classify_straight_line(e.scenario) for e in batch.encounters]
    assert got == [(SITUATION_CODES[kind],)] * N_PER_TYPE
    r = s.types[kind]
    for e in batch.encounters:
        rec = e.targets[0]
        own, tgt = e.scenario["own_ship"], _targets(e.scenario)[0]
        # the drawn values (recomputed from the written, rounded ones) lie in the requested ranges
        assert r.dcpa_m[0] - 0.05 <= rec["dcpa_m"] <= r.dcpa_m[1] + 0.05
        assert r.tcpa_s[0] - 0.05 <= rec["tcpa_s"] <= r.tcpa_s[1] + 0.05
        assert r.target_speed_mps[0] - 1e-3 <= tgt["speed_mps"] <= r.target_speed_mps[1] + 1e-3
        assert s.own_speed_mps[0] - 1e-3 <= own["speed_mps"] <= s.own_speed_mps[1] + 1e-3
        lo, hi = r.relative_course_deg
        assert (rec["relative_course_deg"] - lo) % 360.0 <= hi - lo + 2e-3
        if kind == "overtaking":
            assert tgt["speed_mps"] <= own["speed_mps"] - s.min_speed_difference_mps + 1e-9
        if kind == "overtaken":
            assert tgt["speed_mps"] >= own["speed_mps"] + s.min_speed_difference_mps - 1e-9
    # the margin: the head-on bearings stay 2 degrees inside the evaluation's 13-degree sector
    if kind == "head_on":
        b = np.array([e.targets[0]["bearing_deg"] for e in batch.encounters])
        a = np.array([e.targets[0]["contact_angle_deg"] for e in batch.encounters])
        assert np.abs(b).max() <= 11.0 and np.abs(a).max() <= 11.0
        assert np.abs(b).max() > 5.0                    # and the sector is used, not only its centre


def test_recorded_cpa_matches_the_written_tracks():
    batch = generate_encounters("crossing_stand_on", 20, seed=3, validate=False)
    for e in batch.encounters:
        tr = straight_line_tracks(e.scenario, dt_s=0.01)
        r = np.hypot(tr.north[1] - tr.north[0], tr.east[1] - tr.east[0])
        k = int(np.argmin(r))
        assert r[k] == pytest.approx(e.targets[0]["dcpa_m"], abs=2e-3)
        assert tr.t[k] == pytest.approx(e.targets[0]["tcpa_s"], abs=0.011)
        assert r[0] == pytest.approx(e.targets[0]["start_range_m"], abs=1e-3)


def test_several_targets_each_classified_and_apart():
    types = list(ENCOUNTER_TYPES)
    batch = generate_encounters(types, 25, seed=5, validate=False)
    s = get_settings("harbour")
    for e in batch.encounters:
        assert classify_straight_line(e.scenario) == tuple(SITUATION_CODES[k] for k in types)
        tr = straight_line_tracks(e.scenario, dt_s=0.5)
        pos = np.stack([tr.north, tr.east], axis=-1)                      # [V, n, 2]
        for i in range(len(types)):
            for j in range(i + 1, len(types)):
                d = np.hypot(*(pos[1 + i] - pos[1 + j]).T)
                assert d.min() >= s.min_separation_m - 1e-6
        assert all(np.hypot(*(pos[0, 0] - pos[v, 0])) >= s.min_separation_m for v in range(1, len(types) + 1))


def test_the_evaluation_parameters_of_the_template_are_followed():
    """A wider head-on sector in the file's evaluation section widens what is generated; the scenario's own
    parameters classify it as head-on."""
    s = get_settings("harbour", template={"evaluation": {"range_scale": 0.16666667, "theta_crit_ho_deg": 20.0}},
                     types={"head_on": {"relative_course_deg": (150.0, 210.0)}})
    batch = generate_encounters("head_on", 150, seed=2, settings=s, validate=False)
    b = np.array([abs(e.targets[0]["bearing_deg"]) for e in batch.encounters])
    assert b.max() > 13.0 and b.max() <= 18.0
    assert all(classify_straight_line(e.scenario) == ("HO",) for e in batch.encounters)


def test_open_sea_preset_and_start_within_stage2():
    s = get_settings("open_sea", start_within_stage2=True)
    batch = generate_encounters("crossing_give_way", 40, seed=4, settings=s, validate=False)
    p = prepare("crossing_give_way", s).evaluation
    assert batch.rejections.get("start_range", 0) > 0
    for e in batch.encounters:
        assert e.targets[0]["t_start_s"] == 0.0 and e.targets[0]["start_range_m"] <= p.r_stage2_m
        assert classify_straight_line(e.scenario) == ("CRGW",)


def test_bearing_filter_is_honoured_and_counted():
    s = get_settings("harbour", types={"crossing_give_way": {"relative_bearing_deg": (40.0, 60.0)}})
    batch = generate_encounters("crossing_give_way", 30, seed=9, settings=s, validate=False)
    assert batch.rejections["bearing"] > 0
    assert all(40.0 <= e.targets[0]["bearing_deg"] <= 60.0 for e in batch.encounters)


# ------------------------------------------------------------------------------------------ reproducibility
def test_a_seed_reproduces_the_encounters():
    a = generate_encounters(["head_on", "overtaken"], 6, seed=21, validate=False)
    b = generate_encounters(["head_on", "overtaken"], 3, seed=21, validate=False)
    c = generate_encounters(["head_on", "overtaken"], 3, seed=22, validate=False)
    assert [e.scenario for e in a.encounters[:3]] == [e.scenario for e in b.encounters]
    one = generate_encounter(["head_on", "overtaken"], seed=21, index=4, name="mixed_0004", validate=False)
    assert one.scenario == a.encounters[4].scenario
    assert [e.scenario["own_ship"] for e in c.encounters] != [e.scenario["own_ship"] for e in b.encounters]


# ------------------------------------------------------------------------------------------ files
def test_files_load_classify_and_are_never_overwritten(tmp_path):
    out = tmp_path / "gen"
    batches = {k: generate_encounters(k, 4, seed=1) for k in ENCOUNTER_TYPES}
    written = {k: write_scenarios(b, out / k) for k, b in batches.items()}
    for k, paths in written.items():
        assert [p.name for p in paths] == [f"{k}_{i:04d}.yaml" for i in range(4)]
        for p in paths:
            sc = load_scenario(p)                                           # the loader's land checks as errors
            assert classify_straight_line(sc) == (SITUATION_CODES[k],)
        doc = json.loads((out / k / MANIFEST).read_text())
        assert doc["seed"] == 1 and doc["types"] == [k] and len(doc["files"]) == 4
        assert doc["files"][0]["targets"][0]["type"] == k
        assert not [f for f in (out / k).iterdir() if f.name.endswith(".tmp")]
    # refused without overwrite; nothing changed
    before = {p: p.read_bytes() for p in (out / "head_on").iterdir()}
    other = generate_encounters("head_on", 4, seed=2, validate=False)
    with pytest.raises(FileExistsError, match="already exist"):
        write_scenarios(other, out / "head_on")
    assert {p: p.read_bytes() for p in (out / "head_on").iterdir()} == before
    # overwrite: replaced, and the previous batch's extra files removed (no mix of two batches)
    fewer = generate_encounters("head_on", 2, seed=2)
    write_scenarios(fewer, out / "head_on", overwrite=True)
    names = sorted(p.name for p in (out / "head_on").iterdir())
    assert names == [MANIFEST, "head_on_0000.yaml", "head_on_0001.yaml"]
    assert load_scenario(out / "head_on" / "head_on_0000.yaml").own_ship.speed == pytest.approx(
        fewer.encounters[0].scenario["own_ship"]["speed_mps"])


def test_write_refuses_what_the_loader_refuses(tmp_path):
    e = generate_encounter("head_on", seed=0, validate=False)
    bad = dict(e.scenario, targets=[dict(e.scenario["targets"][0], position_m=e.scenario["own_ship"]["position_m"])])
    broken = type(e)(scenario=bad, types=e.types, targets=e.targets, rejections={}, validated=False)
    with pytest.raises(ValueError, match="head_on_0000.yaml: the scenario loader refuses"):
        write_scenarios([broken], tmp_path / "x")
    assert not (tmp_path / "x").exists()


# ------------------------------------------------------------------------------------------ charts
def _clearance(pt, polys) -> float:
    return min(p.distance(Point(pt)) for p in polys)


@pytest.mark.parametrize("kind", ENCOUNTER_TYPES)
def test_on_a_chart_no_start_or_track_near_land(kind):
    s = get_settings("harbour", own_north_m=(-500.0, 500.0), own_east_m=(-500.0, 500.0), land_margin_m=15.0)
    batch = generate_encounters(kind, 25, seed=6, settings=s, chart=ISLANDS)
    land_rejections = sum(v for k, v in batch.rejections.items() if "land" in k)
    assert land_rejections > 0                                     # the islands were in the way and were avoided
    for e in batch.encounters:
        assert e.scenario["chart"] == ISLANDS
        sc = scenario_from_dict(e.scenario, land_checks="error")
        assert classify_straight_line(sc) == (SITUATION_CODES[kind],)
        for ship in [e.scenario["own_ship"]] + e.scenario["targets"]:
            assert _clearance(ship["position_m"], ISLAND_POLYS) >= 15.0 - 1e-9
            track = LineString(ship["waypoints_m"])
            assert min(p.distance(track) for p in ISLAND_POLYS) >= 15.0 - 0.02


def test_a_chart_object_with_its_section():
    chart = Chart(polygons=tuple(ISLAND_POLYS), origin=(0.0, 0.0), crs="EPSG:32632", source="test islands")
    s = get_settings("harbour", own_north_m=(-500.0, 500.0), own_east_m=(-500.0, 500.0),
                     template={"chart": ISLANDS})
    batch = generate_encounters("overtaking", 10, seed=3, settings=s, chart=chart)
    assert all(_clearance(e.scenario["own_ship"]["position_m"], ISLAND_POLYS) >= s.land_margin_m
               for e in batch.encounters)
    with pytest.raises(ValueError, match="chart section"):
        generate_encounters("overtaking", 1, seed=3, chart=chart)


def test_gives_up_with_counts_when_the_own_ship_box_is_land():
    s = get_settings("harbour", own_north_m=(250.0, 350.0), own_east_m=(-50.0, 50.0))
    with pytest.raises(ValueError, match=r"could not draw a head_on encounter in 300 draws \(rejections: "
                                         r"own_start_on_land: 300"):
        generate_encounter("head_on", seed=0, settings=s, chart=ISLANDS, max_tries=300)


# ------------------------------------------------------------------------------------------ bad input
@pytest.mark.parametrize("overrides, message", [
    ({"types": {"overtaking": {"target_speed_mps": (3.2, 4.0)}}}, "types.overtaking.target_speed_mps"),
    ({"types": {"overtaken": {"target_speed_mps": (1.0, 1.9)}}}, "types.overtaken.target_speed_mps"),
    ({"types": {"head_on": {"relative_course_deg": (90.0, 120.0)}}},
     r"types.head_on.relative_course_deg \[90.0, 120.0\] can never give a head_on encounter.*160..200"),
    ({"types": {"head_on": {"relative_bearing_deg": (20.0, 40.0)}}}, "bearings that can: -10..10"),
    ({"types": {"crossing_stand_on": {"dcpa_m": (0.0, 500.0)}}}, "types.crossing_stand_on.dcpa_m high"),
    ({"types": {"head_on": {"tcpa_s": (0.0, 10.0)}}}, r"types.head_on.tcpa_s must be \(low, high\)"),
    ({"types": {"head_on": {"speed": 1}}}, "types.head_on: unknown key"),
    ({"types": {"rammed": {}}}, "unknown encounter type 'rammed'"),
    ({"own_speed_mps": (0.1, 2.0)}, "own_speed_mps low .* epsilon_speed_mps"),
    ({"own_course_deg": (0.0, 400.0)}, "own_course_deg must span at most 360"),
    ({"min_separation_m": 2.0}, "min_separation_m .* collision distance"),
    ({"sector_margin_deg": -1.0}, "sector_margin_deg must be in"),
    ({"start_within_stage2": 1}, "start_within_stage2 must be True or False"),
    ({"template": {"own_ship": {}}}, r"template: key\(s\) \['own_ship'\] not allowed"),
    ({"template": {"simulation": {"dt_s": 0.5, "duration_s": 10}}}, "template.simulation must hold dt_s only"),
    ({"colour": "red"}, r"unknown setting\(s\) \['colour'\]"),
])
def test_bad_settings_name_the_field(overrides, message):
    with pytest.raises(ValueError, match=message):
        prepare(list(ENCOUNTER_TYPES), get_settings("harbour", **overrides))


def test_bad_arguments_name_the_argument():
    with pytest.raises(ValueError, match="unknown encounter type 'headon'"):
        generate_encounter("headon", seed=0)
    with pytest.raises(ValueError, match="seed must be an integer"):
        generate_encounter("head_on", seed=-1)
    with pytest.raises(ValueError, match="n must be an integer"):
        generate_encounters("head_on", 0, seed=0)
    with pytest.raises(ValueError, match="unknown generation preset 'river'"):
        settings_from_dict({"preset": "river"})
    with pytest.raises(ValueError, match="chart must be None"):
        generate_encounter("head_on", seed=0, chart="trondheim")
    with pytest.raises(ValueError, match="prefix must be"):
        generate_encounters("head_on", 1, seed=0, prefix="../x")
    ctx = prepare("head_on")
    with pytest.raises(ValueError, match="give either context"):
        generate_encounter("head_on", seed=0, context=ctx, settings="open_sea")
    with pytest.raises(ValueError, match="differ from the context's"):
        generate_encounter("overtaking", seed=0, context=ctx)
    with pytest.raises(ValueError, match="max_tries must be"):
        generate_encounter("head_on", seed=0, context=ctx, max_tries=0)


def test_settings_from_a_mapping_merge_into_the_preset():
    s = settings_from_dict({"preset": "open_sea", "types": {"overtaking": {"dcpa_m": [0, 100]}},
                            "own_north_m": [0, 1000]})
    assert s.types["overtaking"].dcpa_m == (0.0, 100.0) and s.own_north_m == (0.0, 1000.0)
    assert s.types["head_on"] == get_settings("open_sea").types["head_on"]
    assert s.template["mpc"]["preset"] == "open_sea"


# ------------------------------------------------------------------------------------------ the script
def _tool():
    spec = importlib.util.spec_from_file_location("generate_encounters", REPO / "tools" / "generate_encounters.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_the_script_writes_checks_and_refuses(tmp_path, capsys):
    tool = _tool()
    out = str(tmp_path / "g")
    assert tool.main(["head_on", "crossing_give_way", "--count", "3", "--seed", "4", "--out", out, "--check"]) == 0
    text = capsys.readouterr().out
    assert "wrote 3 scenario files" in text and "0 files differ" in text
    assert sorted(p.name for p in (tmp_path / "g").iterdir()) == [MANIFEST] + [f"mixed_{i:04d}.yaml" for i in range(3)]
    assert tool.main(["head_on", "--count", "1", "--seed", "4", "--out", out]) == 2
    assert "already exist" in capsys.readouterr().err
    assert tool.main(["overtaking", "--seed", "0", "--out", str(tmp_path / "h"), "--own-north", "5", "1"]) == 2
    assert "own_north_m must be (low, high)" in capsys.readouterr().err
    assert tool.main(["overtaking", "--seed", "0", "--out", str(tmp_path / "h"), "--chart-clip-m", "100"]) == 2


def test_the_cli_subcommand_is_the_script(tmp_path, capsys):
    """``psbmpc-jax generate`` takes the script's options and writes the same files (same seed, same bytes)."""
    from psbmpc_jax.apps.cli import main

    a, b = tmp_path / "cli", tmp_path / "tool"
    args = ["head_on", "overtaken", "--count", "2", "--seed", "7"]
    assert main(["generate", *args, "--out", str(a), "--check"]) == 0
    assert "0 files differ" in capsys.readouterr().out
    assert _tool().main([*args, "--out", str(b)]) == 0
    names = sorted(p.name for p in a.glob("*.yaml"))
    assert names == sorted(p.name for p in b.glob("*.yaml")) and len(names) == 2
    assert all((a / n).read_bytes() == (b / n).read_bytes() for n in names)
    assert main(["generate", "head_on", "--seed", "7", "--out", str(a)]) == 2
    err = capsys.readouterr().err
    assert "psbmpc-jax generate: error:" in err and "already exist" in err


def test_evaluation_on_straight_tracks_is_the_full_pipeline():
    """straight_line_tracks gives the evaluation tool constant course and speed; its encounter starts where the
    generator says (the first 1 s sample inside the stage-2 range)."""
    e = generate_encounter("head_on", seed=8, validate=False)
    sc = scenario_from_dict(e.scenario)
    ev = evaluate_tracks(straight_line_tracks(sc), sc.evaluation)
    assert len(ev.encounters) == 1
    enc = ev.encounters[0]
    assert enc.situation == "HO" and enc.status == "scored"
    assert enc.t_start == pytest.approx(math.ceil(e.targets[0]["t_start_s"] - 1e-9), abs=1.0)
    assert isinstance(sc.evaluation, EvalParams)
    assert shapely.__version__  # shapely is a dependency of the chart checks
