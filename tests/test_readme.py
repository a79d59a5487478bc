"""The README's library example runs as written and gives what the README says it gives."""

from __future__ import annotations

import pathlib
import re

import numpy as np

README = pathlib.Path(__file__).resolve().parents[1] / "README.md"


def _python_blocks():
    return re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)


def test_readme_library_example_runs():
    blocks = _python_blocks()
    assert blocks, "README has no python example"
    namespace: dict = {}
    exec(compile(blocks[0], str(README), "exec"), namespace)  # noqa: S102 - our own documentation
    result, state = namespace["result"], namespace["state"]
    assert result.costs["total"].shape == (1014,)
    assert result.own_trajectories.shape == (1014, 301, 4)
    assert result.obstacle_trajectories[0].shape == (5, 301, 4)
    # the head-on target on the own-ship's track: the chosen first maneuver turns to starboard
    assert result.chi_opt > 0
    assert state.last_offsets == (result.u_opt, result.chi_opt)
    ranking = result.ranking(3)
    assert [r["index"] for r in ranking][0] == result.best_index
    assert np.all(np.diff([r["total"] for r in ranking]) >= 0)


def test_readme_commands_match_ci():
    text = README.read_text()
    ci = (README.parent / ".ci" / "run").read_text()
    test_cmd = 'python3 -m pip install -q -e ".[test]" && python3 -m pytest -q'
    assert test_cmd in text
    # .ci/run runs the same two steps
    assert 'python3 -m pip install -q -e ".[test]"' in ci and "python3 -m pytest -q" in ci
    assert "python3 -m pip install -e . && psbmpc-jax run nidelva" in text


def test_readme_charts_example_runs():
    blocks = [b for b in _python_blocks() if "psbmpc_jax.charts" in b]
    assert blocks, "README has no charts example"
    namespace: dict = {}
    exec(compile(blocks[0], str(README), "exec"), namespace)  # noqa: S102
    polygons = namespace["polygons"]
    assert 1 <= len(polygons) < len(namespace["chart"].polygons)
    # every ring set is (outer, holes...) with rings of shape [n >= 3, 2]
    assert all(r.ndim == 2 and r.shape[0] >= 3 and r.shape[1] == 2 for rings in polygons for r in rings)


def test_readme_objective_example_runs():
    blocks = _python_blocks()
    objective_block = [b for b in blocks if "objective(" in b]
    assert objective_block, "README has no objective example"
    namespace: dict = {}
    exec(compile(blocks[0], str(README), "exec"), namespace)  # noqa: S102
    exec(compile(objective_block[0].replace("\n  ", "\n").strip(), str(README), "exec"), namespace)  # noqa: S102
    g = np.asarray(namespace["g"])
    assert g.shape == (2, 2) and np.all(np.isfinite(g)) and np.abs(g).max() > 0
