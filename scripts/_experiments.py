"""What the experiment scripts (``tengesdal2020_experiments.py``, ``akdag2022_experiments.py``) share: the output
folder and provenance header of a comparison, and writing ``comparison.json`` / ``comparison.md``."""

from __future__ import annotations

import datetime as dt
import json
import pathlib
import platform

REPO = pathlib.Path(__file__).resolve().parents[1]


def start(out, prefix: str, **settings) -> tuple[pathlib.Path, dict]:
    """The output folder (``out``, default ``benchmarks/results/<prefix>_<UTC stamp>``, created) and the
    comparison document's header: creation time, commit, device and versions, ``settings``, empty results."""
    import jax

    from psbmpc_jax.provenance import commit

    stamp = dt.datetime.now(dt.timezone.utc).strftime("%Y%m%dT%H%M%SZ")
    folder = pathlib.Path(out or REPO / "benchmarks" / "results" / f"{prefix}_{stamp}")
    folder.mkdir(parents=True, exist_ok=True)
    doc = {"created_utc": stamp, "commit": commit(), **settings, "device": str(jax.devices()[0]),
           "jax": jax.__version__, "python": platform.python_version(), "machine": platform.machine(),
           "results": {}}
    return folder, doc


def finish(folder: pathlib.Path, doc: dict, markdown: str) -> None:
    """Write ``comparison.json`` and ``comparison.md`` and print the table."""
    (folder / "comparison.json").write_text(json.dumps(doc, indent=2) + "\n")
    (folder / "comparison.md").write_text(markdown)
    print(markdown)
    print("wrote", folder)
