"""Command-line polish: plain help texts, options under their subcommands, the default subcommand, example
with a sampling estimator, bench/report argument and output checks, and the compilation cache call."""

from __future__ import annotations

import argparse
import json
import os
import pathlib

import jax
import pytest

import psbmpc_jax
from psbmpc_jax.apps import cli
from psbmpc_jax.apps.bench_timing import default_out
from psbmpc_jax.apps.cli import build_parser, main

FIX = pathlib.Path(__file__).resolve().parent / "fixtures" / "bench"


def _subparsers(parser):
    (action,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return action.choices


def test_help_texts_are_plain():
    parser = build_parser()
    texts = {"psbmpc-jax": parser.format_help()}
    texts.update({name: p.format_help() for name, p in _subparsers(parser).items()})
    assert set(texts) == {"psbmpc-jax", "example", "run", "bench", "report", "evaluate", "generate", "campaign",
                          "merge"}
    for name, text in texts.items():
        assert "``" not in text and ":func:" not in text and ":class:" not in text, name
    top = texts["psbmpc-jax"]
    assert "--n-ps" not in top and "--estimator" not in top           # example's options live under example
    assert all(f"psbmpc-jax {c}" in top for c in ("example", "run", "bench", "report", "evaluate", "campaign", "merge"))
    assert "--estimator" in texts["example"] and "--save-trajectories" in texts["run"]
    assert "--range-scale" in texts["evaluate"] and "t_s, vessel, north_m, east_m" in texts["evaluate"]


def test_no_subcommand_runs_the_example(monkeypatch):
    seen = []
    monkeypatch.setattr(cli, "run_example", lambda args: seen.append(args) or 0)
    assert main([]) == 0
    assert main(["--n-m", "1", "--estimator", "mc", "--seed", "3"]) == 0
    assert main(["example", "--obstacles", "0"]) == 0
    assert [a.command for a in seen] == ["example"] * 3
    assert (seen[0].n_m, seen[0].estimator) == (2, "quadrature")
    assert (seen[1].n_m, seen[1].estimator, seen[1].seed) == (1, "mc", 3) and seen[2].obstacles == 0


def test_version_and_bad_values(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0 and psbmpc_jax.__version__ in capsys.readouterr().out
    with pytest.raises(SystemExit) as exc:
        main(["example", "--obstacles", "-1"])
    assert exc.value.code == 2 and "--obstacles" in capsys.readouterr().err


def test_example_with_a_sampling_estimator(capsys):
    """--estimator mc: the sample table comes from --seed (small sizes: one compile; ce works the same way and
    compiles several times longer)."""
    assert main(["example", "--estimator", "mc", "--seed", "5", "--n-m", "1", "--obstacles", "1", "--n-ps", "1",
                 "--repeats", "1", "--top", "2"]) == 0
    out = capsys.readouterr().out
    assert "estimator=mc (seed 5)" in out and "chosen behaviour #" in out and "solve time:" in out


@pytest.mark.parametrize("values", ["1,,3", ",1", "1,"])
def test_bench_empty_list_items(values, tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["bench", "--sweep", "n_cbs", "--values", values, "--out", str(tmp_path / "b.jsonl")])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "--values: empty item" in err


def test_bench_unwritable_out_and_default_folder(tmp_path, capsys, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    for out, needle in ((blocker / "b.jsonl", "is not a folder"), (tmp_path, "is a folder")):
        with pytest.raises(SystemExit) as exc:
            main(["bench", "--preset", "smoke", "--devices", "cpu", "--out", str(out)])
        err = capsys.readouterr().err
        assert exc.value.code == 2 and "--out" in err and needle in err
    monkeypatch.chdir(tmp_path)
    path = pathlib.Path(default_out())
    assert path.parent == tmp_path and path.name.startswith("bench_") and path.suffix == ".jsonl"


def test_report_on_other_files(tmp_path, capsys):
    metrics = tmp_path / "metrics.json"
    metrics.write_text(json.dumps({"schema": "psbmpc-sim/1", "summary": {}}, indent=1))
    assert main(["report", str(metrics), "--out", str(tmp_path / "rep")]) == 2
    err = capsys.readouterr().err
    assert "psbmpc-sim/1" in err and "metrics.json of psbmpc-jax run" in err and "psbmpc-bench/1" in err
    (tmp_path / "x.csv").write_text("a,b\n1,2\n")
    assert main(["report", str(tmp_path / "x.csv"), "--out", str(tmp_path / "rep")]) == 2
    err = capsys.readouterr().err
    assert "x.csv:1" in err and "JSON Lines files written by psbmpc-jax bench" in err
    (tmp_path / "p.png").write_bytes(b"\x89PNG\r\n\x1a\n\xff\xfe")
    assert main(["report", str(tmp_path / "p.png"), "--out", str(tmp_path / "rep")]) == 2
    assert "not a text file" in capsys.readouterr().err
    (tmp_path / "rec.jsonl").write_text(json.dumps({"name": "x"}) + "\n")
    assert main(["report", str(tmp_path / "rec.jsonl"), "--out", str(tmp_path / "rep")]) == 2
    assert "no 'schema' field" in capsys.readouterr().err
    blocker = tmp_path / "blocker"
    blocker.write_text("x")
    with pytest.raises(SystemExit) as exc:
        main(["report", str(FIX / "bench_cpu.jsonl"), "--out", str(blocker / "rep")])
    assert exc.value.code == 2 and "--out" in capsys.readouterr().err


@pytest.fixture
def restore_cache_config():
    before = (jax.config.jax_compilation_cache_dir, jax.config.jax_persistent_cache_min_compile_time_secs)
    yield
    jax.config.update("jax_compilation_cache_dir", before[0])
    jax.config.update("jax_persistent_cache_min_compile_time_secs", before[1])
    from jax.experimental.compilation_cache import compilation_cache

    compilation_cache.reset_cache()


def test_enable_compilation_cache(tmp_path, monkeypatch, restore_cache_config):
    folder = psbmpc_jax.enable_compilation_cache(tmp_path / "jc", min_compile_time_s=1.5)
    assert folder == (tmp_path / "jc").resolve() and folder.is_dir()
    assert jax.config.jax_compilation_cache_dir == str(folder)
    assert jax.config.jax_persistent_cache_min_compile_time_secs == 1.5
    # no path: the folder configured already stays; $PSBMPC_JAX_CACHE overrides it
    monkeypatch.delenv("PSBMPC_JAX_CACHE", raising=False)
    assert psbmpc_jax.enable_compilation_cache() == folder
    monkeypatch.setenv("PSBMPC_JAX_CACHE", str(tmp_path / "env"))
    assert psbmpc_jax.enable_compilation_cache() == (tmp_path / "env").resolve()
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert psbmpc_jax.enable_compilation_cache(blocker / "sub") is None      # no cache, no exception
    assert "enable_compilation_cache" in psbmpc_jax.__all__ and cli.enable_compilation_cache is \
        psbmpc_jax.enable_compilation_cache
    assert os.path.basename(str(psbmpc_jax.cache.default_cache_dir())) in ("env", "psbmpc_jax")
