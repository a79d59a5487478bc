"""No internal labels a reader cannot resolve.

A user has the package, its docstrings (rendered in the API reference), the docs site, the README, the examples,
the scenario files and the experiments, but not the project's internal specifications.  So none of these may
cite them: no ``SPEC``/``SPEC_SEEDS``/``SPEC_EVALTOOL`` section (``SPEC §3.2``, ``SPEC_SEEDS §1.5``, "the SPEC's
note"), no choice label of those specifications (``C-000-8``, ``C-002-4``) and no internal paper number ("seed
000", "seed paper 001").  Cite the paper by authors and year (with its equation, section or figure), state the
choice in a few words, or link the docs page that explains it: the choices are listed, with their public ids
(SM-n, TL-n, IS-n, SB-n), in ``docs/algorithm.md`` sections 12–15 and in ``docs/evaltool.md``.

Not checked: ``tests/`` (internal traceability may stay there) and the ``results/`` folders under
``experiments/`` and ``benchmarks/``: they are records of past runs and keep the text (such as a scenario's
description) they were made with.
"""

from __future__ import annotations

import importlib.util
import pathlib
import re

import pytest

PACKAGE_DIR = pathlib.Path(importlib.util.find_spec("psbmpc_jax").submodule_search_locations[0]).resolve()
REPO = PACKAGE_DIR.parent

#: (what, pattern) of every internal label a reader cannot resolve.
LABELS = (
    ("internal specification", re.compile(r"\bSPEC(?:_[A-Z]+)?\b")),
    ("choice label of the internal specification", re.compile(r"\bC-\d{3}-\d+\b")),
    ("internal paper number", re.compile(r"\b(?:seed|paper)[ -](?:paper[ -])?0\d\d\b", re.IGNORECASE)),
    ("path of the internal specifications", re.compile(r"/work/shared|\.\./shared/")),
)

#: Reader-facing text: (folder or file relative to the repository, glob patterns).
SOURCES = (
    ("psbmpc_jax", ("**/*.py",)),
    ("docs", ("**/*.md", "**/*.py")),
    ("examples", ("**/*.py", "**/*.md", "**/*.yaml")),
    ("experiments", ("**/*.py", "**/*.md", "**/*.yaml")),
    ("scenarios", ("**/*.yaml", "**/*.md")),
    ("benchmarks", ("*.py", "*.md")),
    ("tools", ("**/*.py", "**/*.md")),
)
TOP_FILES = ("README.md", "mkdocs.yml", "CITATION.cff")


def find_labels(text: str) -> list[tuple[int, str, str]]:
    """Every internal label in ``text`` as (line number, what, the matched text)."""
    found = []
    for n, line in enumerate(text.splitlines(), 1):
        for what, pat in LABELS:
            found.extend((n, what, m.group(0)) for m in pat.finditer(line))
    return found


def reader_files() -> list[pathlib.Path]:
    files = {REPO / f for f in TOP_FILES if (REPO / f).is_file()}
    for folder, globs in SOURCES:
        root = REPO / folder
        for g in globs:
            files.update(p for p in root.glob(g)
                         if p.is_file() and "results" not in p.relative_to(REPO).parts and "__pycache__" not in p.parts)
    return sorted(files)


@pytest.mark.parametrize("text, labels", [
    ("the sampling interval follows SPEC §4.1", ["SPEC"]),
    ("(SPEC_SEEDS §1.5–1.6)", ["SPEC_SEEDS"]),
    ("``SPEC_EVALTOOL.md``", ["SPEC_EVALTOOL"]),
    ("the SPEC's note", ["SPEC"]),
    ("read as C-001-3: every move", ["C-001-3"]),
    ("(C-000-15) and (C-002-10)", ["C-000-15", "C-002-10"]),
    ("Smooth-SBMPC (seed 000)", ["seed 000"]),
    ("RECONSTRUCTED scenario of seed paper 000", ["seed paper 000"]),
    ("Seed 004 §7", ["Seed 004"]),
    ("the two-level MPC of paper 001", ["paper 001"]),
    ("see ../shared/SPEC_PSBMPC.md", ["SPEC_PSBMPC", "../shared/"]),
    # what stays allowed: public ids, paper citations, identifiers that merely contain the letters
    ("choice SM-8 (docs/algorithm.md §12); Tengesdal et al. (2022, eq. 16)", []),
    ("PartitionSpec, ShipSpec, SPECIAL, seed=0, random seed 1, 1 000 runs, SB-7, case paper000", []),
])
def test_the_scanner_finds_labels(text, labels):
    assert [m for _, _, m in find_labels(text)] == labels


def test_no_internal_labels_in_reader_facing_text():
    if not (REPO / "docs").is_dir():
        pytest.skip("no docs/ folder (not a source checkout)")
    files = reader_files()
    rel = {p.relative_to(REPO).as_posix() for p in files}
    # the scan covers what it claims to: the package, the docs, the README, examples, scenarios, experiments
    assert len(files) > 150 and {"README.md", "psbmpc_jax/params.py", "docs/algorithm.md", "docs/evaltool.md",
                                 "scenarios/smooth_000_reconstruction.yaml", "examples/my_controller/README.md",
                                 "experiments/README.md"} <= rel
    bad = [f"{p.relative_to(REPO).as_posix()}:{n}: {what} {m!r}"
           for p in files for n, what, m in find_labels(p.read_text(encoding="utf-8"))]
    assert not bad, ("internal labels a reader cannot resolve (cite the paper by authors and year, state the "
                     "choice, or link the docs page that explains it):\n" + "\n".join(bad))
