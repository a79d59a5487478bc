"""Benchmark report generator (psbmpc_jax.apps.report): loading/validation, tables, crossover, fits, figures.

Fixtures in tests/fixtures/bench/: bench_cpu.jsonl (JAX-CPU + reference for fig5/6/7/9/10, with skipped
reference points), bench_gpu.jsonl (JAX-GPU for fig5/fig7; the model timings cross JAX-CPU at n_ct = 5000,
between the measured fig5 points n_ct = 2535 and 5070) and bench_disagree.jsonl (a point where the
reference and JAX choose different behaviours)."""

from __future__ import annotations

import argparse
import json
import pathlib
import re
import struct

import numpy as np
import pytest

from psbmpc_jax.apps import report, report_records

FIX = pathlib.Path(__file__).parent / "fixtures" / "bench"
CPU, GPU, DIS = FIX / "bench_cpu.jsonl", FIX / "bench_gpu.jsonl", FIX / "bench_disagree.jsonl"


def _png_size(path):
    data = pathlib.Path(path).read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    return struct.unpack(">II", data[16:24])


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    recs = report_records.load_results([CPU, GPU])
    path = report.write_report(recs, out)
    return recs, out, path.read_text()


def test_load_merges_and_keeps_skipped():
    recs = report_records.load_results([CPU, GPU])
    n_lines = sum(1 for p in (CPU, GPU) for line in p.read_text().splitlines() if line.strip())
    assert len(recs) == n_lines
    skipped = [r for r in recs if r["skipped"]]
    assert skipped and all(r["impl"] == "reference" and r["times_ms"] == [] for r in skipped)
    assert {report_records.impl_label(r) for r in recs} == {"reference", "JAX-CPU", "JAX-GPU"}
    assert report_records.load_results(FIX) and len(report_records.load_results(FIX)) == n_lines + 4  # directory input


def test_impl_label_multi_device():
    r = json.loads(GPU.read_text().splitlines()[0])
    r["n_devices"] = 4
    assert report_records.impl_label(r) == "JAX-GPU x4"


def test_impl_label_dense_grounding_search():
    """Records of the dense exact search are their own series; records without the field used the culled one."""
    r = json.loads(GPU.read_text().splitlines()[0])
    r.pop("grounding_search", None)
    assert report_records.impl_label(dict(r, grounding_mode="exact")) == "JAX-GPU"
    assert report_records.impl_label(dict(r, grounding_mode="exact", grounding_search="dense")) == "JAX-GPU dense"
    assert report_records.impl_label(dict(r, grounding_mode="grid", grounding_search="dense")) == "JAX-GPU"


def test_report_contents(rendered):
    _, out, md = rendered
    assert (out / "report.md").exists()
    # header
    assert "cpu-box" in md and "gpu-box" in md and "NVIDIA H100 80GB HBM3" in md and "abc1234" in md
    assert "0.4.35" in md
    # speed-up tables for every sweep, skipped reference points marked
    for sweep in ("fig5", "fig6", "fig7", "fig9", "fig10"):
        assert f"### Sweep `{sweep}`" in md
    assert "JAX-CPU vs reference" in md and "JAX-GPU vs JAX-CPU" in md
    assert "SKIPPED†" in md and "reference time budget exhausted" in md
    row = next(line for line in md.splitlines() if line.startswith("| 2028 | 10140 |"))
    assert "SKIPPED†" in row
    # crossover within the built-in bracket [2535, 5070] (model crossover at 5000)
    m = re.search(r"`fig5` \(n_cbs\), JAX-GPU vs JAX-CPU.*crossover at n_ct ≈ (\d+) \(bracket n_ct ∈ "
                  r"\[(\d+), (\d+)\]\)", md)
    assert m, md
    n_star, lo, hi = map(int, m.groups())
    assert (lo, hi) == (2535, 5070) and lo <= n_star <= hi and abs(n_star - 5000) < 300
    assert "fig7` (n_ps), JAX-GPU vs JAX-CPU" in md and "faster at every measured point" in md
    # fits and the R² check
    assert "R²" in md
    assert re.search(r"\| fig5 \| n_cbs \| JAX-CPU \| 6 \| [\d.e-]+ \| [\d.e-]+ \| 0\.9\d{3}", md)
    assert "`fig5` (n_cbs), JAX-CPU: R² = " in md and "PASS" in md and "FAIL" not in md
    # consistency
    assert "All implementations chose the same behaviour" in md and "MISMATCH" not in md
    assert "All paper figures (5, 6, 7, 9, 10) had data." in md


def test_figures_are_images(rendered):
    _, out, md = rendered
    for name in ("fig5", "fig6", "fig7", "fig9", "fig10"):
        p = out / f"{name}.png"
        assert p.exists() and f"({name}.png)" in md
        assert p.stat().st_size > 10_000
        w, h = _png_size(p)
        assert w >= 500 and h >= 350


def test_missing_figures_reported(tmp_path):
    recs = [r for r in report_records.load_results([CPU]) if r["sweep"] == "fig5"]
    md = report.write_report(recs, tmp_path).read_text()
    assert (tmp_path / "fig5.png").exists() and not (tmp_path / "fig6.png").exists()
    assert "Figures without data (not drawn)" in md and "fig6" in md and "fig10" in md
    assert "no crossover can be computed" in md


def test_disagreeing_best_flagged(tmp_path):
    md = report.write_report(report_records.load_results([DIS]), tmp_path).read_text()
    assert "WARNING" in md and "**MISMATCH**" in md
    row = next(line for line in md.splitlines() if line.startswith("| custom | n_cbs | 117 |"))
    assert "MISMATCH" in row and "reference: 9" in row and "JAX-CPU: 4" in row


def test_linear_fit_exact():
    x = np.array([13, 39, 117, 507, 1014, 2028], dtype=float)
    f = report_records.linear_fit(x, 0.0123 * x + 4.56)
    assert abs(f["r2"] - 1.0) < 1e-12
    assert f["slope"] == pytest.approx(0.0123, rel=1e-10) and f["intercept"] == pytest.approx(4.56, rel=1e-10)
    assert np.isnan(report_records.linear_fit([1.0], [2.0])["r2"])
    noisy = report_records.linear_fit(x, x + np.array([50.0, -50, 50, -50, 50, -50]))
    assert 0.9 < noisy["r2"] < 1.0


def test_find_crossover():
    c = report_records.find_crossover([100, 1000, 4000, 6000], [1, 3, 9, 13], [9, 9.3, 10.2, 10.8])
    assert c["kind"] == "crossover" and c["bracket"] == (4000, 6000)
    # d = 1.2 at 4000, -2.2 at 6000 -> 4000 + 1.2 * 2000 / 3.4
    assert c["n_ct"] == pytest.approx(4000 + 1.2 * 2000 / 3.4)
    assert report_records.find_crossover([1, 2], [1, 2], [5, 6])["kind"] == "none"
    assert report_records.find_crossover([1, 2], [5, 6], [1, 2])["kind"] == "gpu_always_faster"


def _first_record():
    return json.loads(CPU.read_text().splitlines()[0])


@pytest.mark.parametrize("mutate, message", [
    (lambda lines: lines[:1] + ["{not json"], r"bad\.jsonl:2: malformed JSON"),
    (lambda lines: [json.dumps({**_first_record(), "schema": "psbmpc-bench/0"})], r"bad\.jsonl:1: wrong schema"),
    (lambda lines: [json.dumps({k: v for k, v in _first_record().items() if k not in ("best", "n_ct")})],
     r"bad\.jsonl:1: missing field\(s\) n_ct, best"),
    (lambda lines: ["[1, 2]"], r"bad\.jsonl:1: expected a JSON object"),
    (lambda lines: [json.dumps({**_first_record(), "times_ms": []})], r"not skipped but 'times_ms' is empty"),
    (lambda lines: [], r"empty input"),
    (lambda lines: [json.dumps({**_first_record(), "schedule": "random"})], r"bad\.jsonl:1: field 'schedule'"),
])
def test_malformed_inputs(tmp_path, mutate, message):
    bad = tmp_path / "bad.jsonl"
    bad.write_text("\n".join(mutate(CPU.read_text().splitlines())) + "\n")
    with pytest.raises(ValueError, match=message):
        report_records.load_results([bad])


def test_load_errors(tmp_path):
    with pytest.raises(ValueError, match="no benchmark results files"):
        report_records.load_results([])
    with pytest.raises(FileNotFoundError, match="not found: .*nope.jsonl"):
        report_records.load_results([tmp_path / "nope.jsonl"])


def _args(argv):
    return report.add_report_arguments(argparse.ArgumentParser()).parse_args(argv)


def test_cli(tmp_path, capsys):
    assert _args([]).out == "benchmarks/report"
    assert report.run_report(_args([])) == 2
    assert "no benchmark results files given" in capsys.readouterr().err
    assert report.run_report(_args([str(tmp_path / "missing.jsonl")])) == 2
    assert "not found" in capsys.readouterr().err
    (tmp_path / "empty.jsonl").write_text("\n")
    assert report.run_report(_args([str(tmp_path / "empty.jsonl")])) == 2
    assert "empty input" in capsys.readouterr().err
    out = tmp_path / "rep"
    assert report.main_report([str(CPU), str(GPU), "--out", str(out)]) == 0
    assert "wrote" in capsys.readouterr().out and (out / "report.md").exists() and (out / "fig5.png").exists()


def test_cli_report_subcommand(tmp_path):
    """`psbmpc-jax report FILES --out DIR` renders the report through the console entry point."""
    from psbmpc_jax.apps.cli import main

    fixtures = FIX
    rc = main(["report", str(fixtures / "bench_cpu.jsonl"), str(fixtures / "bench_gpu.jsonl"),
               "--out", str(tmp_path / "rep")])
    assert rc == 0
    text = (tmp_path / "rep" / "report.md").read_text()
    assert "crossover" in text.lower() and (tmp_path / "rep" / "fig5.png").stat().st_size > 10_000
    assert main(["report", str(tmp_path / "missing.jsonl"), "--out", str(tmp_path / "x")]) != 0


def test_work_fit_section_from_n_pc_blocks(tmp_path):
    """n_ps sweeps with recorded n_pc_blocks get a runtime-vs-work fit; a perfectly linear model gives R² = 1."""
    recs = [json.loads(line) for line in CPU.read_text().splitlines() if line.strip()]
    fig7 = [r for r in recs if r["sweep"] == "fig7" and r["impl"] == "jax" and not r["skipped"]]
    assert len(fig7) >= 3
    for k, r in enumerate(fig7):
        r["n_pc_blocks"] = 1000 * (k + 1)
        r["median_ms"] = 5.0 + 0.002 * r["n_pc_blocks"]
        r["times_ms"] = [r["median_ms"]] * 3
        r["min_ms"] = r["max_ms"] = r["q1_ms"] = r["q3_ms"] = r["median_ms"]
    path = tmp_path / "w.jsonl"
    path.write_text("".join(json.dumps(r) + "\n" for r in fig7))
    md = report.write_report(report_records.load_results([path]), tmp_path / "out").read_text()
    assert "## Runtime vs evaluated collision work (n_ps sweeps)" in md
    row = next(line for line in md.splitlines() if line.startswith("| fig7 | JAX-CPU |"))
    assert row.endswith("| 1.0000 |") and "| 2 |" in row      # slope 2 µs/block, R² = 1
    # files without the field (older results) render without the section
    md_old = report.write_report(report_records.load_results([CPU]), tmp_path / "old").read_text()
    assert "evaluated collision work" not in md_old


def test_schedule_defaults_to_sequential_and_shows_in_config(tmp_path):
    """Files written before the ``schedule`` field were timed point by point: they load as sequential."""
    recs = report_records.load_results([CPU])
    assert "schedule" not in _first_record() and {r["schedule"] for r in recs} == {"sequential"}
    lines = [json.loads(x) for x in CPU.read_text().splitlines() if x.strip()]
    f = tmp_path / "inter.jsonl"
    f.write_text("".join(json.dumps({**r, "schedule": "interleaved" if r["impl"] == "jax" else "sequential"}) + "\n"
                         for r in lines))
    md = report.write_report(report_records.load_results([f]), tmp_path / "out").read_text()
    assert "JAX timing schedule: interleaved" in md and "JAX timing schedule: sequential" not in md


def test_planned_memory_column(tmp_path):
    """compiled_memory_bytes shows as a per-implementation column in the speed-up tables (MB); files without
    the field (the fixtures) get no such column."""
    lines = [json.loads(x) for x in CPU.read_text().splitlines() if x.strip()]
    assert "compiled_memory_bytes" not in lines[0]
    plain = report.write_report(report_records.load_results([CPU]), tmp_path / "a").read_text()
    assert "planned memory [MB] |" not in plain
    f = tmp_path / "mem.jsonl"
    f.write_text("".join(json.dumps({**r, "compiled_memory_bytes": (r["n_cbs"] * 1000 if r["impl"] == "jax"
                                                                   else None)}) + "\n" for r in lines))
    md = report.write_report(report_records.load_results([f]), tmp_path / "b").read_text()
    assert "JAX-CPU planned memory [MB]" in md
    row = next(x for x in md.splitlines() if x.startswith("| 1014 |") and "planned" not in x)
    assert row.rstrip(" |").endswith("1.01")     # 1014 * 1000 bytes = 1.01 MB
