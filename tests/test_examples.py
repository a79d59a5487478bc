"""The scripts in ``examples/`` run (quick mode: ``PSBMPC_EXAMPLE_QUICK=1``) and print what they promise.

Each example runs in its own Python process, as a user would run it.  The selected examples are started
together (their time is mostly XLA compilation, one core each) and share the persistent compilation cache of
the test suite (``.pytest_cache``; ``PSBMPC_TEST_NO_JAX_CACHE=1`` disables it), so a warm run is fast.
"""

from __future__ import annotations

import os
import pathlib
import re
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
NAMES = ("01_single_solve", "02_custom_cost_term", "03_gradient", "04_closed_loop")
#: Wall-clock limit of one example [s] (quick mode needs well under a minute on 2 CPU cores).
TIMEOUT_S = 300


def test_every_example_is_tested():
    assert sorted(p.stem for p in EXAMPLES.glob("*.py")) == sorted(NAMES)


def _selected(session) -> list[str]:
    names = []
    for item in session.items:
        callspec = getattr(item, "callspec", None)
        if item.module.__name__ == __name__ and callspec is not None and "name" in callspec.params:
            names.append(callspec.params["name"])
    return names or list(NAMES)


@pytest.fixture(scope="module")
def started(request, tmp_path_factory):
    """Start every selected example at once; ``{name: (process, stdout file, output folder)}``."""
    env = dict(os.environ, PSBMPC_EXAMPLE_QUICK="1", PYTHONUNBUFFERED="1")
    cache = getattr(request.config, "cache", None)            # None under -p no:cacheprovider
    if cache is not None and not os.environ.get("PSBMPC_TEST_NO_JAX_CACHE"):
        env.setdefault("JAX_COMPILATION_CACHE_DIR", str(cache.mkdir("jax-compilation-cache")))
        env.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0.5")
    procs = {}
    for name in _selected(request.session):
        work = tmp_path_factory.mktemp(name)
        args = [sys.executable, str(EXAMPLES / f"{name}.py")]
        if name == "04_closed_loop":
            args += ["--out", str(work / "out")]
        log = open(work / "stdout.txt", "w+")
        procs[name] = (subprocess.Popen(args, cwd=work, env=env, stdout=log, stderr=subprocess.STDOUT), log, work)
    yield procs
    for proc, log, _ in procs.values():
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        log.close()


def _finish(started, name) -> tuple[str, pathlib.Path]:
    proc, log, work = started[name]
    try:
        proc.wait(timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
    log.seek(0)
    out = log.read()
    assert proc.returncode == 0, f"examples/{name}.py exited with {proc.returncode}:\n{out[-4000:]}"
    return out, work


def _number(pattern: str, text: str) -> float:
    m = re.search(pattern, text)
    assert m, f"no match for {pattern!r} in:\n{text}"
    return float(m.group(1))


@pytest.mark.parametrize("name", NAMES)
def test_example(name, started):
    out, work = _finish(started, name)
    if name == "01_single_solve":
        assert re.search(r"^chosen behaviour #\d+: M1: u=", out, flags=re.M), out
        assert "ranking (cheapest first):" in out
        rows = re.findall(r"^\s+(\d)\s+\d+\s+\(", out, flags=re.M)
        assert rows == ["1", "2", "3", "4", "5"], out
    elif name == "02_custom_cost_term":
        assert "cost columns: total, do, colregs, so, path, comfort" in out, out
        assert len(re.findall(r"^with comfort weight \d+: chosen #\d+", out, flags=re.M)) == 2, out
    elif name == "03_gradient":
        fd = _number(r"central difference of d total / d chi_1: ([-+\d.e]+)", out)
        grad = _number(r"\(gradient ([-+\d.e]+)\)", out)
        assert abs(fd - grad) <= 1e-4 * max(1.0, abs(grad)), out
        grid = _number(r"(?m)^grid search: .* total ([-+\d.e]+)$", out)
        objective = _number(r"objective at it:\s+total ([-+\d.e]+)", out)
        assert abs(grid - objective) <= 2e-6 * max(1.0, abs(grid)), out   # both printed with 6 decimals
        refined = _number(r"(?m)^refined: total ([-+\d.e]+)", out)
        assert refined <= grid, out
    elif name == "04_closed_loop":
        assert re.search(r"^own-ship collisions: 0, closest approach", out, flags=re.M), out
        folder = work / "out" / "head_on"
        for f in ("metrics.json", "summary.md", "trajectories.csv", "trajectories.npz"):
            assert (folder / f).is_file(), f
        assert "trajectories: 201 steps x 2 ships x 1 run(s)" in out, out
