"""Campaign folders: the resolved definition, one Parquet file and one done marker per task, and the campaign's
one table ``runs.parquet``.

Layout::

    DIR/campaign.json             schema psbmpc-campaign/1: the resolved definition, its SHA-256, the tasks,
                                  and (once every task is done) the table's rows and SHA-256
    DIR/tasks/<task id>.parquet   the task's rows (written atomically)
    DIR/tasks/<task id>.traj.parquet  with ``trajectories: true``: the task's trajectories
    DIR/tasks/<task id>.done.json written after them: rows, SHA-256 of the Parquet file(s), definition hash
    DIR/runs.parquet              every task's rows, in task order (written atomically when all are done)
    DIR/trajectories.parquet      with ``trajectories: true``: every task's trajectories, likewise

A task counts as done only when its marker names this campaign's definition hash and its Parquet file has the
recorded size and SHA-256; anything else is run again (its files are replaced atomically).  A folder that holds
another campaign (a different resolved definition) is refused naming what changed, unless ``force``: then
exactly this tool's files are removed first (``campaign.json``, ``runs.parquet``, ``tasks/*.parquet``,
``tasks/*.done.json``), never others.
"""

from __future__ import annotations

import datetime as _dt
import json
import logging
import pathlib
import re

from ..runfolder import sha256_file
from ..safe_io import TEMP_SUFFIX, OutputError, atomic_open, atomic_write_text, read_json_document
from .definition import definition_hash, differences, tasks

__all__ = ["SCHEMA", "CAMPAIGN_FILE", "RUNS_FILE", "CampaignError", "prepare_folder", "read_campaign",
           "task_done", "write_task", "assemble", "verified_table"]

log = logging.getLogger(__name__)

SCHEMA = "psbmpc-campaign/1"
CAMPAIGN_FILE = "campaign.json"
RUNS_FILE = "runs.parquet"
TRAJECTORIES_FILE = "trajectories.parquet"
TASKS_DIR = "tasks"
_TASK_FILE_RE = re.compile(r"^[A-Za-z0-9_.-]+\.(parquet|done\.json)$")


class CampaignError(ValueError):
    """A campaign folder cannot be used as asked; the message names the folder or file and what is wrong."""


def _now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")


def read_campaign(folder) -> dict | None:
    """``campaign.json`` of ``folder`` (None when there is none); a file of another schema raises."""
    return read_json_document(pathlib.Path(folder) / CAMPAIGN_FILE, what="campaign file", schema=SCHEMA,
                              error=CampaignError, missing_ok=True, note="; it is not overwritten")


def _our_files(folder: pathlib.Path) -> list[pathlib.Path]:
    out = [folder / n for n in (CAMPAIGN_FILE, RUNS_FILE, TRAJECTORIES_FILE) if (folder / n).is_file()]
    tdir = folder / TASKS_DIR
    if tdir.is_dir():
        out += [p for p in tdir.iterdir() if p.is_file() and (_TASK_FILE_RE.match(p.name)
                                                             or p.name.endswith(TEMP_SUFFIX))]
    return out


def prepare_folder(folder, resolved: dict, *, force: bool = False) -> dict:
    """Open ``folder`` for the campaign ``resolved``: create it (or adopt an empty one), resume the same
    campaign, or refuse another (module docstring).  Returns the campaign document (``campaign.json``)."""
    folder = pathlib.Path(folder)
    if folder.exists() and not folder.is_dir():
        raise CampaignError(f"--out {folder}: exists and is not a folder")
    digest = definition_hash(resolved)
    old = read_campaign(folder) if folder.is_dir() else None
    if old is not None and old.get("kind") == "merge":
        raise CampaignError(f"{folder} holds merged results (psbmpc-jax merge), not a campaign to resume; choose "
                            f"another folder")
    if old is not None and old.get("definition_sha256") == digest:
        log.info("resuming campaign %s in %s", resolved["definition"]["name"], folder)
        return old
    if old is not None:
        changed = differences(old.get("resolved", {}), resolved)
        if not force:
            raise CampaignError(
                f"{folder} holds another campaign (definition {old.get('definition_sha256', '?')[:12]}, this one "
                f"{digest[:12]}); what changed: " + "; ".join(changed[:8]) + (" ..." if len(changed) > 8 else "")
                + ". Use another --out folder, or --force to discard that campaign's results and start afresh")
        for p in _our_files(folder):
            p.unlink()
        log.info("--force: removed the results of campaign %s from %s", old.get("definition_sha256", "?")[:12],
                 folder)
    elif folder.is_dir():
        other = sorted(p.name for p in folder.iterdir())
        if other:
            raise CampaignError(f"--out {folder}: not empty and not a campaign folder (holds "
                                f"{', '.join(other[:5])}{' ...' if len(other) > 5 else ''}); choose an empty or new "
                                f"folder")
    try:
        (folder / TASKS_DIR).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot create the campaign folder {folder}: {exc.strerror or exc}") from None
    from .. import __version__

    doc = {"schema": SCHEMA, "kind": "campaign", "definition_sha256": digest, "created_utc": _now(),
           "package_version": __version__, "resolved": resolved,
           "tasks": [t.task_id for t in tasks(resolved)], "complete": False}
    atomic_write_text(folder / CAMPAIGN_FILE, json.dumps(doc, indent=1) + "\n")
    return doc


def _marker(folder: pathlib.Path, task_id: str) -> pathlib.Path:
    return folder / TASKS_DIR / f"{task_id}.done.json"


def _table(folder: pathlib.Path, task_id: str) -> pathlib.Path:
    return folder / TASKS_DIR / f"{task_id}.parquet"


def _traj(folder: pathlib.Path, task_id: str) -> pathlib.Path:
    return folder / TASKS_DIR / f"{task_id}.traj.parquet"


def _intact(path: pathlib.Path, rec) -> bool:
    return isinstance(rec, dict) and path.is_file() and path.stat().st_size == rec.get("size") \
        and sha256_file(path) == rec.get("sha256")


def task_done(folder, task_id: str, digest: str) -> bool:
    """Whether the task's rows are on disk for the campaign ``digest`` (marker and table agree)."""
    folder = pathlib.Path(folder)
    m, t = _marker(folder, task_id), _table(folder, task_id)
    if not (m.is_file() and t.is_file()):
        return False
    try:
        doc = read_json_document(m, what="done marker")
    except ValueError as exc:
        log.warning("%s; the task runs again", exc)
        return False
    if not isinstance(doc, dict) or doc.get("definition_sha256") != digest:
        return False
    if not _intact(t, doc):
        log.warning("%s: differs from its done marker (size or SHA-256); the task runs again", t)
        return False
    if "trajectories" in doc and not _intact(_traj(folder, task_id), doc["trajectories"]):
        log.warning("%s: missing or differs from its done marker; the task runs again", _traj(folder, task_id))
        return False
    return True


def write_task(folder, task_id: str, digest: str, frame, info: dict, trajectories=None) -> pathlib.Path:
    """Write a task's rows (``frame``, a DataFrame) and ``trajectories`` (a DataFrame, or None) atomically, then
    its done marker (``info`` added)."""
    folder = pathlib.Path(folder)
    extra = {}
    if trajectories is not None:
        p = _traj(folder, task_id)
        with atomic_open(p, "wb") as fh:
            trajectories.to_parquet(fh, index=False)
        extra["trajectories"] = {"rows": int(len(trajectories)), "size": p.stat().st_size, "sha256": sha256_file(p)}
    t = _table(folder, task_id)
    with atomic_open(t, "wb") as fh:
        frame.to_parquet(fh, index=False)
    doc = {"task_id": task_id, "definition_sha256": digest, "rows": int(len(frame)), "size": t.stat().st_size,
           "sha256": sha256_file(t), "completed_utc": _now(), **extra, **info}
    atomic_write_text(_marker(folder, task_id), json.dumps(doc, indent=1) + "\n")
    return t


def _unified_schema(paths):
    import pyarrow as pa
    import pyarrow.parquet as pq

    schemas = [pq.read_schema(p) for p in paths]
    fields = {}
    for s in schemas:
        for f in s:
            if f.name not in fields or pa.types.is_null(fields[f.name].type):
                fields[f.name] = f.with_nullable(True)
            elif not pa.types.is_null(f.type) and f.type != fields[f.name].type:
                raise CampaignError(f"column {f.name!r} has type {f.type} in one task file and {fields[f.name].type} "
                                    f"in another")
    return pa.schema(list(fields.values()), metadata=schemas[0].metadata if schemas else None)


def _conformed(table, schema):
    import pyarrow as pa

    cols = [table.column(f.name).cast(f.type) if f.name in table.column_names
            else pa.nulls(table.num_rows, f.type) for f in schema]
    return pa.Table.from_arrays(cols, schema=schema)


def concat_files(paths, out) -> int:
    """Stream the Parquet files ``paths`` (one at a time, in order) into one file ``out`` (atomically), their
    columns unified (a column a file lacks is null there); returns the rows written."""
    import pyarrow.parquet as pq

    schema = _unified_schema(paths)
    n = 0
    with atomic_open(out, "wb") as fh:
        with pq.ParquetWriter(fh, schema) as writer:
            for p in paths:
                t = _conformed(pq.read_table(p), schema)
                writer.write_table(t)
                n += t.num_rows
    return n


def assemble(folder, doc: dict) -> pathlib.Path:
    """Write ``runs.parquet`` from every task's rows (all must be done) and mark the campaign complete."""
    folder = pathlib.Path(folder)
    digest = doc["definition_sha256"]
    missing = [tid for tid in doc["tasks"] if not task_done(folder, tid, digest)]
    if missing:
        raise CampaignError(f"{folder}: {len(missing)} task(s) not done ({', '.join(missing[:3])}"
                            f"{' ...' if len(missing) > 3 else ''}); run the campaign again to finish them")
    out = folder / RUNS_FILE
    rows = concat_files([_table(folder, tid) for tid in doc["tasks"]], out)
    extra = {}
    if doc["resolved"]["definition"].get("trajectories"):
        tp = folder / TRAJECTORIES_FILE
        n = concat_files([_traj(folder, tid) for tid in doc["tasks"]], tp)
        extra["trajectories_parquet"] = {"rows": n, "size": tp.stat().st_size, "sha256": sha256_file(tp)}
    doc = {**doc, "complete": True, "completed_utc": _now(), "rows": rows,
           "runs_parquet": {"size": out.stat().st_size, "sha256": sha256_file(out)}, **extra}
    atomic_write_text(folder / CAMPAIGN_FILE, json.dumps(doc, indent=1) + "\n")
    return out


def verified_table(folder) -> tuple[pathlib.Path, dict]:
    """``runs.parquet`` of a complete campaign (or merge) folder, checked against ``campaign.json`` (size and
    SHA-256); returns (path, campaign document)."""
    folder = pathlib.Path(folder)
    doc = read_campaign(folder)
    if doc is None:
        raise CampaignError(f"{folder}: no {CAMPAIGN_FILE}; not a campaign folder written by psbmpc-jax campaign")
    if not doc.get("complete"):
        raise CampaignError(f"{folder}: the campaign is not complete (tasks still to run); run it again to finish")
    p = folder / RUNS_FILE
    rec = doc.get("runs_parquet") or {}
    if not p.is_file():
        raise CampaignError(f"{p}: missing, but {folder / CAMPAIGN_FILE} says the campaign is complete")
    if p.stat().st_size != rec.get("size") or sha256_file(p) != rec.get("sha256"):
        raise CampaignError(f"{p}: its size or SHA-256 differs from the one recorded in {folder / CAMPAIGN_FILE}: "
                            f"the file was changed or comes from another campaign")
    return p, doc
