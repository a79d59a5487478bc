"""``psbmpc-jax bench``: JSON Lines records in the psbmpc-bench/1 schema, reference budget, argument errors."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from psbmpc_jax.apps.bench_points import behaviours_for
from psbmpc_jax.apps.bench_timing import FIELDS, SCHEMA
from psbmpc_jax.apps.cli import main

FAST = ["--repeats", "2", "--warmup", "0", "--devices", "cpu", "--quiet"]
ONE_POINT = ["--sweep", "n_cbs", "--values", "9", "--T", "10"]

STR = ("schema", "sweep", "swept", "impl", "platform", "device_kind", "host", "estimator", "dtype", "grounding_mode",
       "memory_source", "commit", "timestamp")
INT = ("n_devices", "n_M", "n_cbs", "n_do", "n_ps", "n_so", "n_vertices", "n_ct")
FLOAT_OR_NONE = ("compile_s", "median_ms", "min_ms", "max_ms", "q1_ms", "q3_ms")


def read(path):
    with open(path) as fh:
        return [json.loads(line) for line in fh if line.strip()]


def check_record(rec):
    assert set(rec) == set(FIELDS)
    assert rec["schema"] == SCHEMA
    for k in STR:
        assert isinstance(rec[k], str), k
    for k in INT:
        assert isinstance(rec[k], int) and not isinstance(rec[k], bool), k
    for k in ("T", "dt"):
        assert isinstance(rec[k], float), k
    for k in FLOAT_OR_NONE:
        assert rec[k] is None or isinstance(rec[k], float), k
    assert isinstance(rec["times_ms"], list) and all(isinstance(t, float) for t in rec["times_ms"])
    assert rec["peak_memory_bytes"] is None or isinstance(rec["peak_memory_bytes"], int)
    assert rec["memory_source"] in ("device", "process_rss")
    if rec["impl"] == "jax" and not rec["skipped"]:
        assert isinstance(rec["compiled_memory_bytes"], int) and rec["compiled_memory_bytes"] > 0
    else:
        assert rec["compiled_memory_bytes"] is None
    assert rec["best"] is None or isinstance(rec["best"], int)
    assert isinstance(rec["skipped"], bool)
    assert rec["skip_reason"] is None or isinstance(rec["skip_reason"], str)
    assert set(rec["versions"]) == {"python", "jax", "jaxlib", "numpy"}
    assert rec["impl"] in ("jax", "reference")
    assert rec["schedule"] in ("interleaved", "sequential")
    if rec["impl"] == "reference":
        assert rec["schedule"] == "sequential"
    assert rec["n_ct"] == rec["n_cbs"] * (rec["n_so"] + rec["n_do"] * rec["n_ps"])
    if rec["skipped"]:
        assert rec["times_ms"] == [] and rec["median_ms"] is None and rec["skip_reason"]
    else:
        assert rec["skip_reason"] is None and rec["min_ms"] <= rec["median_ms"] <= rec["max_ms"]
        assert isinstance(rec["best"], int)
    if rec["impl"] == "reference":
        assert rec["dtype"] == "float64" and rec["compile_s"] is None and rec["platform"] == "cpu"
    else:
        assert rec["compile_s"] > 0


def test_smoke_preset_end_to_end(tmp_path, capsys):
    out = tmp_path / "b.jsonl"
    assert main(["bench", "--preset", "smoke", "--out", str(out), *FAST]) == 0
    assert "psbmpc-jax bench: timing on cpu: " in capsys.readouterr().err     # the device, even with --quiet
    recs = read(out)
    for rec in recs:
        check_record(rec)
    jax_recs = [r for r in recs if r["impl"] == "jax"]
    ref_recs = [r for r in recs if r["impl"] == "reference"]
    assert [r["n_cbs"] for r in jax_recs] == [9, 39] and len(ref_recs) == 2
    assert all(r["sweep"] == "smoke" and r["swept"] == "n_cbs" and r["T"] == 10.0 for r in recs)
    assert all(len(r["times_ms"]) == 2 for r in jax_recs)
    assert all(r["grounding_search"] == "bounded" for r in jax_recs)      # auto on the CPU: the layout used
    assert all(r["grounding_search"] is None for r in ref_recs)
    for j, r in zip(jax_recs, ref_recs):   # same situation, same answer (default budget is ample here)
        assert not r["skipped"] and len(r["times_ms"]) == 1
        assert r["best"] == j["best"]


def test_dense_grounding_search_is_recorded_and_chooses_the_same_behaviour(tmp_path):
    out = tmp_path / "d.jsonl"
    for search in ("culled", "dense", "flat"):
        assert main(["bench", *ONE_POINT, "--grounding-search", search, "--reference-budget", "0", "--out",
                     str(out), *FAST]) == 0
    recs = [r for r in read(out) if r["impl"] == "jax"]
    assert [r["grounding_search"] for r in recs] == ["culled", "dense", "flat"]
    assert recs[0]["best"] == recs[1]["best"] == recs[2]["best"]


def test_budget_zero_marks_reference_skipped_and_append_keeps_lines(tmp_path):
    out = tmp_path / "b.jsonl"
    out.write_text('{"earlier": 1}\n')
    args = ["bench", *ONE_POINT, "--reference-budget", "0", "--out", str(out), *FAST]
    assert main(args) == 0
    assert main(args) == 0
    lines = out.read_text().splitlines()
    assert json.loads(lines[0]) == {"earlier": 1}
    recs = [json.loads(x) for x in lines[1:]]
    assert len(recs) == 4
    for rec in recs:
        check_record(rec)
    ref = [r for r in recs if r["impl"] == "reference"]
    assert len(ref) == 2 and all(r["skipped"] and "disabled" in r["skip_reason"] for r in ref)


def test_tiny_budget_skips_with_reason(tmp_path):
    out = tmp_path / "b.jsonl"
    assert main(["bench", "--preset", "smoke", "--reference-budget", "1e-6", "--out", str(out), *FAST]) == 0
    ref = [r for r in read(out) if r["impl"] == "reference"]
    assert len(ref) == 2
    assert not ref[0]["skipped"]      # the first point always runs (nothing used yet), then the budget is spent
    assert ref[1]["skipped"] and "budget" in ref[1]["skip_reason"]
    check_record(ref[1])


@pytest.mark.parametrize("argv, needle", [
    (["--preset", "fig99"], "--preset"),
    (["--sweep", "n_ps", "--values", "1,2"], "odd"),
    (["--preset", "smoke", "--n-ps", "4"], "odd"),
    (["--preset", "smoke", "--repeats", "0"], "--repeats"),
    (["--preset", "smoke", "--repeats", "-3"], "--repeats"),
    (["--sweep", "n_ps", "--values", "a,b"], "--values"),
    (["--sweep", "n_ps", "--values", ","], "--values"),
    (["--sweep", "n_ps"], "--values"),
    (["--sweep", "n_cbs", "--values", "40"], "n_cbs=40"),
    (["--sweep", "n_so", "--values", "14"], "n_so"),
    (["--sweep", "n_bogus", "--values", "1"], "--sweep"),
    (["--preset", "smoke", "--values", "1"], "--values"),
    ([], "--preset"),
    (["--preset", "smoke", "--reference-budget", "-1"], "--reference-budget"),
    (["--preset", "smoke", "--T", "10", "--dt", "0.3"], "--dt"),
    (["--preset", "smoke", "--devices", "tpu"], "--devices"),
    (["--preset", "smoke", "--schedule", "random"], "--schedule"),
])
def test_bad_arguments_give_clear_errors(argv, needle, capsys, tmp_path):
    with pytest.raises(SystemExit) as exc:
        main(["bench", *argv, "--out", str(tmp_path / "x.jsonl")])
    assert exc.value.code == 2
    assert needle in capsys.readouterr().err
    assert not (tmp_path / "x.jsonl").exists()


def test_behaviour_sets_sizes():
    for n in (3, 9, 39, 117, 78, 156, 1014, 2028):
        b = behaviours_for(n)
        assert b.shape[0] == n
    assert behaviours_for(39).shape[1] == 1 and behaviours_for(156).shape[1] == 2
    with pytest.raises(ValueError, match="n_cbs=100"):
        behaviours_for(100)


def test_fixed_fan_presets_scale_r_ct():
    """fig6s/fig7s keep the scenario fan 40 m wide: r_ct = 40 / (n_ps - 1); fig6/fig7 keep Table 1's 10 m."""
    from psbmpc_jax.apps.bench import add_bench_arguments, build_plan
    import argparse

    ap = argparse.ArgumentParser()
    add_bench_arguments(ap)
    pts = build_plan(ap.parse_args(["--preset", "fig6s"]))
    assert [p.n_ps for p in pts] == [1, 11, 21, 41, 61, 81, 101]
    assert pts[0].r_ct == 10.0 and pts[1].r_ct == pytest.approx(4.0) and pts[-1].r_ct == pytest.approx(0.4)
    assert all((p.n_ps - 1) * p.r_ct == pytest.approx(40.0) for p in pts[1:])
    assert all(p.r_ct == 10.0 for p in build_plan(ap.parse_args(["--preset", "fig7"])))
    assert {p.sweep for p in build_plan(ap.parse_args(["--preset", "paper"]))} >= {"fig6s", "fig7s"}


def test_sequential_schedule_gives_the_same_answers(tmp_path):
    inter, seq = tmp_path / "i.jsonl", tmp_path / "s.jsonl"
    assert main(["bench", "--preset", "smoke", "--reference-budget", "0", "--out", str(inter), *FAST]) == 0
    assert main(["bench", "--preset", "smoke", "--reference-budget", "0", "--schedule", "sequential",
                 "--out", str(seq), *FAST]) == 0
    ri = [r for r in read(inter) if r["impl"] == "jax"]
    rs = [r for r in read(seq) if r["impl"] == "jax"]
    assert [r["schedule"] for r in ri] == ["interleaved"] * 2 and [r["schedule"] for r in rs] == ["sequential"] * 2
    for a, b in zip(ri, rs):
        check_record(a)
        check_record(b)
        assert (a["n_cbs"], a["best"], a["n_pc_blocks"]) == (b["n_cbs"], b["best"], b["n_pc_blocks"])
        assert len(a["times_ms"]) == len(b["times_ms"]) == 2


class _FakeEval:
    def __init__(self, best):
        self.best, self.n_pc_blocks = best, 7


def _fake_slots(log, fail_at=None):
    """Two timing slots whose calls append to ``log``; call number ``fail_at`` raises KeyboardInterrupt."""
    from psbmpc_jax.apps.bench_timing import FIELDS

    def make(name, best):
        def call():
            if fail_at is not None and len(log) == fail_at:
                raise KeyboardInterrupt
            log.append(name)
            return _FakeEval(best)
        return {"point": name, "call": call, "rec": dict.fromkeys(FIELDS), "ev": None, "times": []}

    return [make("a", 1), make("b", 2)]


def _runner(repeats):
    import argparse

    from psbmpc_jax.apps.bench_timing import Runner

    return Runner(argparse.Namespace(repeats=repeats), fh=None)


def test_interleaved_rounds_alternate_points():
    log = []
    recs, interrupted = _runner(3).time_jax(_fake_slots(log))
    assert log == ["a", "b", "a", "b", "a", "b"] and not interrupted
    assert [(p, r["best"], r["n_pc_blocks"], len(r["times_ms"])) for p, r in recs] == [("a", 1, 7, 3), ("b", 2, 7, 3)]


def test_interrupt_keeps_the_repeats_timed_so_far():
    log = []
    recs, interrupted = _runner(5).time_jax(_fake_slots(log, fail_at=3))     # a, b, a, then Ctrl-C
    assert interrupted and log == ["a", "b", "a"]
    assert [(p, len(r["times_ms"])) for p, r in recs] == [("a", 2), ("b", 1)]
    log = []
    recs, interrupted = _runner(5).time_jax(_fake_slots(log, fail_at=0))     # nothing timed: nothing written
    assert interrupted and recs == []


def test_compile_time_is_a_real_compile_for_repeated_shapes(tmp_path):
    """Two points with the same shapes: the second must compile again, not load the first's executable
    (a cache hit takes ~1 ms, a compile of the evaluator hundreds of ms)."""
    out = tmp_path / "b.jsonl"
    assert main(["bench", "--sweep", "n_cbs", "--values", "9,9", "--T", "10", "--reference-budget", "0",
                 "--out", str(out), *FAST]) == 0
    jax_recs = [r for r in read(out) if r["impl"] == "jax"]
    assert len(jax_recs) == 2 and all(r["compile_s"] > 0.05 for r in jax_recs), [r["compile_s"] for r in jax_recs]


def test_multi_device_points_match_single_device(tmp_path):
    """--multi-device on 2 forced host devices (a subprocess: the device count is fixed once JAX starts):
    a sharded record per point, compiled ahead of time, with the single-device answer."""
    out = tmp_path / "md.jsonl"
    root = Path(__file__).resolve().parents[1]
    env = dict(os.environ, JAX_PLATFORMS="cpu")
    env["XLA_FLAGS"] = (env.get("XLA_FLAGS", "") + " --xla_force_host_platform_device_count=2").strip()
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(root), env.get("PYTHONPATH")) if p)
    code = ("import sys; from psbmpc_jax.apps.cli import main; sys.exit(main(['bench', '--preset', 'smoke', "
            "'--multi-device', '--reference-budget', '0', '--out', sys.argv[1], "
            + ", ".join(repr(a) for a in FAST) + "]))")
    proc = subprocess.run([sys.executable, "-c", code, str(out)], env=env, capture_output=True, text=True,
                          timeout=300, cwd=str(root))
    assert proc.returncode == 0, proc.stderr[-4000:]
    recs = [r for r in read(out) if r["impl"] == "jax"]
    for rec in recs:
        check_record(rec)
    single = {r["n_cbs"]: r for r in recs if r["n_devices"] == 1}
    multi = {r["n_cbs"]: r for r in recs if r["n_devices"] == 2}
    assert sorted(single) == sorted(multi) == [9, 39]
    for n, r in multi.items():
        assert r["best"] == single[n]["best"] and len(r["times_ms"]) == 2 and r["compile_s"] > 0.05


def test_compiled_memory_grows_with_the_problem(tmp_path):
    """The planned memory of a solve is the point's own: more behaviours (39 and 390: different padded sizes),
    more bytes; the same point twice, the same bytes (the process peak RSS cannot tell either)."""
    out = tmp_path / "m.jsonl"
    assert main(["bench", "--sweep", "n_cbs", "--values", "39,390,39", "--T", "10", "--reference-budget", "0",
                 "--out", str(out), *FAST]) == 0
    mem = [r["compiled_memory_bytes"] for r in read(out) if r["impl"] == "jax"]
    assert mem[1] > mem[0] and mem[2] == mem[0]
