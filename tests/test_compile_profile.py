"""The suite's own profiler (tests/compile_profile.py) and its summary (tools/test_profile.py)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import pytest

from compile_profile import CompileProfile

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
import suite_profile  # noqa: E402


def test_a_compile_is_recorded_with_its_program_name(tmp_path):
    prof = CompileProfile(str(tmp_path), "w0")
    try:
        def profiled_program(x):
            return jnp.sin(x) * 3.0 + x.shape[0]

        prof.start("tests/test_x.py::test_a")
        jax.jit(profiled_program)(jnp.arange(7.0)).block_until_ready()
        prof.stop()
        prof.start("tests/test_x.py::test_b")                   # nothing compiled: the cached program
        prof.stop()
    finally:
        prof.close()
    a, b = (json.loads(line) for line in (tmp_path / "w0.jsonl").read_text().splitlines())
    assert a["test"].endswith("test_a") and a["n_compiles"] >= 1 and a["compile_s"] > 0
    assert any("profiled_program" in name for name in a["programs"]) and a["wall_s"] >= a["compile_s"]
    assert b["n_compiles"] == 0 and b["programs"] == {}


def test_summary_sums_files_and_programs(tmp_path, capsys):
    rows = [{"test": "tests/test_a.py::t1", "wall_s": 10.0, "compile_s": 6.0, "trace_s": 1.0, "lower_s": 1.0,
             "cache_saved_s": 0.0, "n_compiles": 2, "programs": {"jit(solve)": 5.0, "jit(add)": 1.0}},
            {"test": "tests/test_b.py::t2", "wall_s": 4.0, "compile_s": 2.0, "trace_s": 0.0, "lower_s": 0.0,
             "cache_saved_s": 0.0, "n_compiles": 1, "programs": {"jit(solve)": 2.0}}]
    (tmp_path / "gw0.jsonl").write_text("\n".join(json.dumps(r) for r in rows) + "\n")
    suite_profile.main([str(tmp_path)])
    out = capsys.readouterr().out
    assert "2 tests: 14 worker-s, of which trace+lower+compile 10 s (71 %), 3 compiles" in out
    solve = next(line for line in out.splitlines() if line.startswith("jit(solve)"))
    assert solve.split()[1:] == ["7.0", "2", "2"]
    rec = tmp_path / "rec" / "profile.json"
    suite_profile.main([str(tmp_path), "--json", str(rec), "--commit", "abc123"])
    doc = json.loads(rec.read_text())
    assert doc["meta"]["commit"] == "abc123" and doc["totals"] == {
        "tests": 2, "worker_s": 14.0, "trace_lower_compile_s": 10.0, "compiles": 3, "cache_clears": 0,
        "compile_s_after_clears_upper_bound": 0.0}
    assert doc["programs"]["jit(solve)"] == {"compile_s": 7.0, "tests": 2}
    assert list(doc["files"]) == ["tests/test_a.py", "tests/test_b.py"]
    with pytest.raises(SystemExit, match="exists"):                 # a record is never overwritten
        suite_profile.main([str(tmp_path), "--json", str(rec)])


def test_summary_refuses_an_empty_folder_and_a_bad_line(tmp_path):
    with pytest.raises(SystemExit, match="no \\*.jsonl profile lines"):
        suite_profile.main([str(tmp_path)])
    (tmp_path / "gw1.jsonl").write_text("{not json\n")
    with pytest.raises(SystemExit, match="gw1.jsonl:1: not a JSON line"):
        suite_profile.main([str(tmp_path)])


def test_cache_clears_and_the_compiles_after_them_are_counted_per_worker(tmp_path):
    """A clear after a test (the memory-map guard) evicts what that worker compiled before: a later compile of a
    program of the same name in that worker counts; the other worker's does not."""
    prof = CompileProfile(str(tmp_path), "gw0")
    try:
        prof.start("tests/test_x.py::a")
        prof.note_cache_clear()
        prof.stop()
    finally:
        prof.close()
    assert json.loads((tmp_path / "gw0.jsonl").read_text())["caches_cleared"] is True
    row = lambda test, progs, cleared=False: {"test": test, "wall_s": 1.0, "compile_s": sum(progs.values()),  # noqa: E731
                                              "trace_s": 0.0, "lower_s": 0.0, "n_compiles": len(progs),
                                              "programs": progs, "caches_cleared": cleared}
    (tmp_path / "gw0.jsonl").write_text("\n".join(json.dumps(r) for r in [
        row("t::1", {"jit(solve)": 5.0}), row("t::2", {"jit(f)": 1.0}, cleared=True),
        row("t::3", {"jit(solve)": 4.0, "jit(g)": 2.0}), row("t::4", {"jit(f)": 1.5})]) + "\n")
    (tmp_path / "gw1.jsonl").write_text(json.dumps(row("t::5", {"jit(solve)": 3.0})) + "\n")
    assert suite_profile.cache_clears(suite_profile.load(tmp_path)) == (1, 5.5)
