"""The README stays short and its library example runs as written; the examples moved from it to the documentation
pages run too; `.ci/run` runs the README's test command and then builds the documentation."""

from __future__ import annotations

import pathlib
import re

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
QUICKSTART = ROOT / "docs" / "quickstart.md"
CHARTS = ROOT / "docs" / "charts.md"

#: the README is the front page; everything longer lives in docs/
MAX_README_LINES = 250


def _python_blocks(path: pathlib.Path) -> list[str]:
    return re.findall(r"```python\n(.*?)```", path.read_text(), flags=re.DOTALL)


def _run(block: str, path: pathlib.Path, namespace: dict) -> dict:
    exec(compile(block, str(path), "exec"), namespace)  # noqa: S102 - our own documentation
    return namespace


def test_readme_is_short():
    n = len(README.read_text().splitlines())
    assert n <= MAX_README_LINES, f"README.md has {n} lines, at most {MAX_README_LINES} allowed: move detail to docs/"


def _check_library_example(namespace: dict) -> None:
    result, state = namespace["result"], namespace["state"]
    assert result.costs["total"].shape == (1014,)
    assert result.own_trajectories.shape == (1014, 301, 4)
    assert result.obstacle_trajectories[0].shape == (5, 301, 4)
    # the head-on target on the own-ship's track: the chosen first maneuver turns to starboard
    assert result.chi_opt > 0
    assert state.last_offsets == (result.u_opt, result.chi_opt)
    ranking = result.ranking(3)
    assert ranking[0]["index"] == result.best_index
    assert np.all(np.diff([r["total"] for r in ranking]) >= 0)


def test_readme_library_example_runs():
    blocks = _python_blocks(README)
    assert len(blocks) == 1, "README has exactly one python example (the library API)"
    assert len(blocks[0].strip().splitlines()) <= 25, "the README's example stays about 20 lines"
    _check_library_example(_run(blocks[0], README, {}))


def test_quickstart_starts_with_the_readme_example():
    assert _python_blocks(QUICKSTART)[0] == _python_blocks(README)[0]


def test_readme_commands_match_ci():
    text = README.read_text()
    ci = (ROOT / ".ci" / "run").read_text()
    test_cmd = 'python3 -m pip install -q -e ".[test]" && python3 -m pytest -q'
    assert test_cmd in text
    # .ci/run runs the same two steps, then the lint and the strict documentation build (after the tests)
    assert 'python3 -m pip install -q -e ".[test]"' in ci and "python3 -m pytest -q" in ci
    assert "python3 -m pip install -e . && psbmpc-jax run nidelva" in text
    docs = 'python3 -m mkdocs build --strict'
    assert docs in ci and ci.index(docs) > ci.index("python3 -m pytest -q")
    # and the lint (ruff's rules are in pyproject.toml; ruff is in the test extra)
    lint = "python3 -m ruff check ."
    assert lint in ci and ci.index(lint) > ci.index("python3 -m pytest -q")
    types = "python3 -m mypy"
    assert types in ci and ci.index(types) > ci.index("python3 -m pytest -q")


def test_readme_links_resolve():
    """Every relative link of the README points at a file of the repository (the docs site checks its own)."""
    for target in re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", README.read_text()):
        if "://" not in target:
            assert (ROOT / target).is_file(), f"README links to missing {target}"


def test_charts_example_runs():
    blocks = [b for b in _python_blocks(CHARTS) if "psbmpc_jax.charts" in b]
    assert blocks, "docs/charts.md has no charts example"
    namespace = _run(blocks[0], CHARTS, {})
    polygons = namespace["polygons"]
    assert 1 <= len(polygons) < len(namespace["chart"].polygons)
    # every ring set is (outer, holes...) with rings of shape [n >= 3, 2]
    assert all(r.ndim == 2 and r.shape[0] >= 3 and r.shape[1] == 2 for rings in polygons for r in rings)


def test_objective_example_runs():
    blocks = _python_blocks(QUICKSTART)
    objective_block = [b for b in blocks if "objective(" in b]
    assert objective_block, "docs/quickstart.md has no objective example"
    namespace = _run(blocks[0], QUICKSTART, {})
    _run(objective_block[0].replace("\n  ", "\n").strip(), QUICKSTART, namespace)
    g = np.asarray(namespace["g"])
    assert g.shape == (2, 2) and np.all(np.isfinite(g)) and np.abs(g).max() > 0


#: labels only the project's own notes can resolve (issue numbers, specification sections, seed-paper numbers,
#: specification choice ids); the documentation cites papers by authors and year and explains its own choice ids
INTERNAL_LABELS = {
    "specification document name or section": re.compile(r"\bSPEC(?:_[A-Z]+)?\b|§"),
    "seed-paper number": re.compile(r"\bseeds? ?-?0\d\d\b", re.IGNORECASE),
    "specification choice id": re.compile(r"\bC-(?:00\d|R)-"),
    "issue number": re.compile(r"\bissues? #?\d+", re.IGNORECASE),
}


def _documentation_pages() -> list[pathlib.Path]:
    return [README, *sorted((ROOT / "docs").rglob("*.md"))]


def test_documentation_has_no_internal_labels():
    found = []
    for page in _documentation_pages():
        for n, line in enumerate(page.read_text().splitlines(), 1):
            for what, pattern in INTERNAL_LABELS.items():
                if pattern.search(line):
                    found.append(f"{page.relative_to(ROOT)}:{n}: {what}: {line.strip()[:100]}")
    assert not found, "labels a reader cannot resolve:\n" + "\n".join(found)


def _nav_files(node) -> list[str]:
    if isinstance(node, str):
        return [node]
    if isinstance(node, dict):
        return [f for v in node.values() for f in _nav_files(v)]
    return [f for v in node for f in _nav_files(v)]


def test_docs_nav_lists_every_page():
    """mkdocs.yml's nav and docs/ agree (the strict site build in .ci/run checks the rest: links, anchors, API)."""
    import yaml

    config = yaml.load((ROOT / "mkdocs.yml").read_text(), Loader=yaml.BaseLoader)
    nav = _nav_files(config["nav"])
    pages = sorted(str(p.relative_to(ROOT / "docs")) for p in (ROOT / "docs").rglob("*.md"))
    assert len(nav) == len(set(nav)), "a page is listed twice in mkdocs.yml's nav"
    assert sorted(nav) == pages, (
        f"in nav but missing: {sorted(set(nav) - set(pages))}; not in nav: {sorted(set(pages) - set(nav))}")


#: The README's "Tested limits" rows and the benchmarks/bench_tested_limits.py case each comes from.
TESTED_LIMIT_ROWS = {"behaviours": "behaviours_65k", "obstacle scenarios": "scenarios", "horizon": "horizon_100k",
                     "Monte Carlo runs": "runs_1000", "track length (`evaluate_tracks`)": "track_1e7"}


def test_readme_tested_limits_come_from_the_committed_measurements():
    """Every row of the README's "Tested limits" table states the peak memory and time of its committed
    measurement (benchmarks/results/tested_limits_cpu_*.json), and the case ran without an error."""
    import json

    from psbmpc_jax.limits import fmt_bytes

    section = README.read_text().split("## Tested limits", 1)[1].split("\n## ", 1)[0]
    rows = {cells[0]: cells for cells in ([c.strip() for c in line.strip("|").split("|")]
                                          for line in section.splitlines() if line.startswith("| "))}
    measured = {}
    for path in sorted((ROOT / "benchmarks" / "results").glob("tested_limits_cpu_*.json")):
        for point in json.loads(path.read_text())["points"]:
            measured[point["case"]] = point                                   # the latest file of a case wins
    for label, case in TESTED_LIMIT_ROWS.items():
        assert label in rows, f"README Tested limits: no row {label!r}"
        point = measured[case]
        assert "error" not in point, (case, point["error"])
        _, _, memory, wall = rows[label]
        assert memory == fmt_bytes(point["peak_rss_bytes"]), (label, memory, point["peak_rss_bytes"])
        assert wall == f"{point['wall_s']:.0f} s", (label, wall, point["wall_s"])


#: The README's "Tested limits" rows that come from the campaign benchmark (benchmarks/bench_campaign_memory.py):
#: label -> the kind of point in benchmarks/results/campaign_memory_cpu_*.json ("memory": the one with most runs).
CAMPAIGN_LIMIT_ROWS = {"campaign runs (`psbmpc-jax campaign`)": "memory", "Nidelva campaign": "nidelva"}


def test_readme_campaign_limits_come_from_the_committed_measurements():
    """The README's campaign rows state the peak memory, wall time and runs of the committed campaign record."""
    import json

    from psbmpc_jax.limits import fmt_bytes

    section = README.read_text().split("## Tested limits", 1)[1].split("\n## ", 1)[0]
    rows = {cells[0]: cells for cells in ([c.strip() for c in line.strip("|").split("|")]
                                          for line in section.splitlines() if line.startswith("| "))}
    measured = {}
    for path in sorted((ROOT / "benchmarks" / "results").glob("campaign_memory_cpu_*.json")):
        for point in json.loads(path.read_text())["points"]:
            if point["what"] in ("memory", "nidelva") and (
                    point["what"] != "memory" or point["runs"] >= measured.get("memory", {}).get("runs", 0)):
                measured[point["what"]] = point
    for label, what in CAMPAIGN_LIMIT_ROWS.items():
        assert label in rows, f"README Tested limits: no row {label!r}"
        point = measured[what]
        _, tested, memory, wall = rows[label]
        assert tested.startswith(f"{point['runs']:,} runs".replace(",", " ")), (label, tested, point["runs"])
        assert memory == fmt_bytes(point.get("peak_rss_bytes", point["peak_rss_mib"] * 2 ** 20)), (label, memory)
        assert wall == f"{point['wall_s']:.0f} s", (label, wall, point["wall_s"])

