"""experiments/akdag2022/kappa_table.py: the rules that decide whether each of Akdağ et al.'s (2022) head-on /
give-way findings holds in a run, the table it builds, its input checks, one real cell end to end, and the
committed table re-rendered from its JSON."""

import importlib.util
import json
import pathlib

import pytest

REPO = pathlib.Path(__file__).resolve().parents[1]
SCRIPT = REPO / "experiments" / "akdag2022" / "kappa_table.py"
COMMITTED = REPO / "experiments" / "akdag2022" / "results" / "kappa_table"


@pytest.fixture(scope="module")
def kt():
    spec = importlib.util.spec_from_file_location("akdag2022_kappa_table", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def rec(side="starboard", offset=30.0, dist=600.0, t=300.0):
    """A run record with the fields of run.records that the table reads."""
    return {"first_manoeuvre_side": side, "first_manoeuvre_t_s": None if side == "none" else t,
            "min_distance_m": dist, "min_speed_factor": 1.0, "max_abs_course_offset_deg": offset,
            "passed_ahead_of_target": False, "passed_astern_of_rule18_ship": {}, "collision": False}


def test_the_rule_of_each_finding(kt):
    assert kt.holds("head_on_no_re", rec("starboard")) and not kt.holds("head_on_no_re", rec("port"))
    assert not kt.holds("head_on_no_re", rec("none", 0.0))
    assert kt.holds("head_on_re", rec("port")) and kt.holds("head_on_re", rec("none", 0.0))
    assert not kt.holds("head_on_re", rec("starboard")) and not kt.holds("head_on_re", rec("speed only", 0.0))
    assert kt.holds("give_way_no_re", rec("starboard")) and not kt.holds("give_way_no_re", rec("port"))
    # give way with route exchange: keeps on (|offset| <= 15 deg) and keeps d_safe (>= 500 m)
    assert kt.holds("give_way_re", rec("port", 15.0, 500.0))
    assert not kt.holds("give_way_re", rec("port", 30.0, 1000.0))
    assert not kt.holds("give_way_re", rec("none", 0.0, 499.9))
    with pytest.raises(ValueError, match="finding must be one of"):
        kt.holds("overtaken", rec())


def test_cell_counts_runs_and_the_text_says_yes_partly_no(kt):
    c = kt.cell("head_on_re", [rec("port", 30, 625), rec("port", 30, 620), rec("starboard", 20, 611)])
    assert c["holds_runs"] == 2 and c["aggregate"]["runs"] == 3
    assert kt.cell_text(c) == "partly 2/3 · port · 30° · 620 m"
    assert kt.cell_text(kt.cell("head_on_no_re", [rec("starboard", 20, 549)])) == "**yes** 1/1 · stb · 20° · 549 m"
    assert kt.cell_text(kt.cell("head_on_no_re", [rec("none", 0, 300)])).startswith("no 0/1 · none")
    with pytest.raises(ValueError, match="at least one run"):
        kt.cell("head_on_re", [])


def test_markdown_lists_the_grid_points_where_every_finding_holds(kt):
    grid = {"findings": ["head_on_no_re", "head_on_re"], "classify": ["velocity"], "kappa": [0.0, 3.0],
            "K_coll": [0.5]}
    res = {"head_on_no_re": {"velocity": {"0": {"0.5": kt.cell("head_on_no_re", [rec("port")])},
                                          "3": {"0.5": kt.cell("head_on_no_re", [rec("starboard")])}}},
           "head_on_re": {"velocity": {"0": {"0.5": kt.cell("head_on_re", [rec("port")])},
                                       "3": {"0.5": kt.cell("head_on_re", [rec("port")])}}}}
    md = kt.markdown({"grid": grid, "results": res})
    assert md.count("| classification | κ | K_coll 0.5 |") == 2
    assert "| velocity | 3 | **yes** 1/1 · stb" in md and "| velocity | 0 | no 0/1 · port" in md
    assert md.rstrip().endswith("every run:** velocity, κ 3, K_coll 0.5.")
    res["head_on_re"]["velocity"]["3"]["0.5"] = kt.cell("head_on_re", [rec("port"), rec("starboard")])
    assert kt.markdown({"grid": grid, "results": res}).rstrip().endswith("every run:** none.")


@pytest.mark.parametrize("argv, match", [
    (["--classify", "velocity,woerner"], "--classify: comma-separated subset of velocity, sectors_t0"),
    (["--kappa", "1,-2"], "--kappa: at least one number, all >= 0"),
    (["--K-coll", "x"], "--K-coll: comma-separated numbers expected"),
    (["--findings", "overtaken"], "--findings: comma-separated subset of head_on_no_re"),
])
def test_bad_arguments_are_refused_by_name(kt, tmp_path, argv, match):
    with pytest.raises(SystemExit, match=match):
        kt.main([*argv, "--out", str(tmp_path / "out")])
    assert not (tmp_path / "out").exists()


def test_one_real_cell_end_to_end_and_no_overwrite(kt, tmp_path):
    out = tmp_path / "table"
    argv = ["--runs", "1", "--kappa", "3", "--K-coll", "0.5", "--classify", "velocity", "--findings",
            "head_on_no_re", "--out", str(out)]
    assert kt.main(argv) == 0
    doc = json.loads((out / "comparison.json").read_text())
    c = doc["results"]["head_on_no_re"]["velocity"]["3"]["0.5"]
    assert c["aggregate"]["runs"] == 1 and len(c["runs"]) == 1 and c["aggregate"]["collisions"] == 0
    assert c["holds_runs"] == int(kt.holds("head_on_no_re", c["runs"][0]))
    assert (out / "comparison.md").read_text() == kt.markdown(doc)
    with pytest.raises(SystemExit, match="already holds results"):
        kt.main(argv)


def test_the_committed_table_is_what_the_builder_makes_of_its_json(kt):
    if not (COMMITTED / "comparison.json").is_file():
        pytest.skip("no committed kappa table (not a source checkout)")
    doc = json.loads((COMMITTED / "comparison.json").read_text())
    assert set(doc["grid"]["findings"]) == set(kt.FINDINGS)
    for f, per in doc["results"].items():
        for cl in per.values():
            for kc in cl.values():
                for c in kc.values():
                    assert c["holds_runs"] == sum(kt.holds(f, r) for r in c["runs"])
    assert (COMMITTED / "comparison.md").read_text() == kt.markdown(doc)


def test_resume_refuses_a_finished_table_and_cells_of_another_grid_or_commit(kt, tmp_path, monkeypatch):
    import psbmpc_jax.provenance as prov

    monkeypatch.setattr(prov, "commit", lambda: "abc")
    grid = {"findings": ["head_on_no_re"], "classify": ["velocity"], "kappa": [3.0], "K_coll": [0.5]}
    cells = {"head_on_no_re": {"velocity": {"3": {"0.5": kt.cell("head_on_no_re", [rec()])}}}}
    path = tmp_path / "comparison.json"

    def write(**changes):
        path.write_text(json.dumps({"commit": "abc", "runs": 1, "grid": grid, "complete": False, "results": cells,
                                    **changes}))

    write()
    assert kt.resumable(tmp_path, 1, grid) == cells
    assert kt.resumable(tmp_path / "new", 1, grid) == {}
    with pytest.raises(SystemExit, match="needs --out"):
        kt.resumable(None, 1, grid)
    for changes, match in (({"complete": True}, "a finished table"), ({"commit": "def"}, "has commit 'def'"),
                           ({"runs": 3}, "has runs 3"), ({"grid": {**grid, "kappa": [1.0]}}, "has grid")):
        write(**changes)
        with pytest.raises(SystemExit, match=match):
            kt.resumable(tmp_path, 1, grid)
    write(commit="abc-dirty")        # a checkout with uncommitted changes: the cells' source is not known
    monkeypatch.setattr(prov, "commit", lambda: "abc-dirty")
    with pytest.raises(SystemExit, match="commit first"):
        kt.resumable(tmp_path, 1, grid)
