"""What the study scripts share: where a run writes (a new folder, never over an earlier result), the provenance
header of a comparison, and writing ``comparison.json`` / ``comparison.md``.

Users: ``tengesdal2020/run.py``, ``akdag2022/run.py`` and ``kappa_table.py``, ``mahipala2023/run.py`` (the folder above theirs is put
on ``sys.path`` by each), ``compare_methods.py``, ``nidelva_refinement/stop_analysis.py`` and
``smooth_sbmpc/ablation.py``.
"""

from __future__ import annotations

import datetime as dt
import json
import pathlib
import platform

EXPERIMENTS = pathlib.Path(__file__).resolve().parent


def utc_stamp() -> str:
    return dt.datetime.now(dt.timezone.utc).strftime("%Y%m%dT%H%M%SZ")


def output_folder(out, default: pathlib.Path, *, force: bool = False) -> pathlib.Path:
    """The folder a run writes into, created: ``out`` or else ``default``.

    A folder that already holds files is refused (``SystemExit`` naming it and the way out) unless ``force``:
    a run never overwrites an earlier result silently."""
    folder = pathlib.Path(out) if out else pathlib.Path(default)
    if folder.exists() and not folder.is_dir():
        raise SystemExit(f"--out {folder}: exists and is not a folder")
    if folder.is_dir() and any(folder.iterdir()) and not force:
        raise SystemExit(f"--out {folder}: the folder already holds results; give a new folder, or --force to "
                         f"write over them")
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def output_file(out, default: pathlib.Path, *, force: bool = False) -> pathlib.Path:
    """The file a run writes: ``out`` or else ``default``; an existing file is refused unless ``force``."""
    path = pathlib.Path(out) if out else pathlib.Path(default)
    if path.exists() and not force:
        raise SystemExit(f"--out {path}: the file exists; give a new file name, or --force to write over it")
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def start(out, study: pathlib.Path, force: bool = False, **settings) -> tuple[pathlib.Path, dict]:
    """The output folder (``out``, default ``<study>/results_<UTC stamp>``; see :func:`output_folder`) and the
    comparison document's header: creation time, commit, device and versions, ``settings``, empty results."""
    import jax

    from psbmpc_jax.provenance import commit

    stamp = utc_stamp()
    folder = output_folder(out, pathlib.Path(study) / f"results_{stamp}", force=force)
    doc = {"created_utc": stamp, "commit": commit(), **settings, "device": str(jax.devices()[0]),
           "jax": jax.__version__, "python": platform.python_version(), "machine": platform.machine(),
           "results": {}}
    return folder, doc


def finish(folder: pathlib.Path, doc: dict, markdown: str) -> None:
    """Write ``comparison.json`` and ``comparison.md`` (each atomically: complete or not at all) and print the
    table."""
    from psbmpc_jax.safe_io import atomic_write_text

    atomic_write_text(folder / "comparison.json", json.dumps(doc, indent=2) + "\n")
    atomic_write_text(folder / "comparison.md", markdown)
    print(markdown)
    print("wrote", folder)
