"""``psbmpc-jax merge``: combine the tables of complete campaign folders (or earlier merges) into one folder.

Rows are identified by :data:`~psbmpc_jax.campaign.rows.KEY_COLUMNS` (scenario, method, seed, run, ship).  A key
found in two inputs is refused, naming the key and the folders, and saying whether the two rows are identical (a
duplicate: the same campaign merged twice, or overlapping campaigns) or differ (a conflict: e.g. the same seed
simulated with another scenario file or code version).  Rows of the same scenario name from different scenario
files (``scenario_sha256``) are a conflict too.  The output folder gets ``runs.parquet`` and ``campaign.json``
(``kind: merge``, the sources with their definition hashes), and ``trajectories.parquet`` when every input has
its trajectories.
"""

from __future__ import annotations

import datetime as _dt
import json
import logging
import pathlib

from ..runfolder import sha256_file
from ..safe_io import OutputError, atomic_write_text, same_file
from .rows import KEY_COLUMNS
from .store import (CAMPAIGN_FILE, RUNS_FILE, SCHEMA, TRAJECTORIES_FILE, CampaignError, concat_files, read_campaign,
                    verified_table)

__all__ = ["merge_folders"]

log = logging.getLogger(__name__)


def _keys(path):
    import pyarrow.parquet as pq

    return pq.read_table(path, columns=list(KEY_COLUMNS) + ["scenario_sha256"]).to_pandas()


def _row(path, key: tuple) -> dict:
    import pyarrow.parquet as pq

    t = pq.read_table(path, filters=[(c, "==", v) for c, v in zip(KEY_COLUMNS, key)]).to_pandas()
    return t.drop(columns=[c for c in ("campaign", "task_id") if c in t.columns]).iloc[0].to_dict()


def _verified_trajectories(folder: pathlib.Path, doc: dict):
    """The folder's ``trajectories.parquet`` checked against ``campaign.json`` (None when it has none)."""
    rec = doc.get("trajectories_parquet")
    if rec is None:
        return None
    p = folder / TRAJECTORIES_FILE
    if not p.is_file() or p.stat().st_size != rec.get("size") or sha256_file(p) != rec.get("sha256"):
        raise CampaignError(f"{p}: missing, or its size or SHA-256 differs from the one recorded in "
                            f"{folder / CAMPAIGN_FILE}")
    return p


def _same(a: dict, b: dict) -> bool:
    import math

    if set(a) != set(b):
        return False
    for k in a:
        x, y = a[k], b[k]
        nx = x is None or (isinstance(x, float) and math.isnan(x)) or str(x) == "<NA>"
        ny = y is None or (isinstance(y, float) and math.isnan(y)) or str(y) == "<NA>"
        if nx and ny:
            continue
        if nx != ny or x != y:
            return False
    return True


def _output_problem(out: pathlib.Path, inputs, force: bool) -> str | None:
    if out.exists() and not out.is_dir():
        return f"--out {out}: exists and is not a folder"
    for f in inputs:
        if out.exists() and same_file(out, f):
            return f"--out {out} is one of the folders to merge; choose a new folder"
    if not out.is_dir() or not any(out.iterdir()):
        return None
    try:
        doc = read_campaign(out)
    except CampaignError as exc:
        return str(exc)
    if doc is not None and doc.get("kind") == "merge":
        if force:
            return None
        return f"--out {out} holds an earlier merge; pass --force to replace it (its runs.parquet and campaign.json)"
    return f"--out {out}: not empty and not an earlier merge; choose an empty or new folder"


def merge_folders(inputs, out, *, force: bool = False) -> dict:
    """Merge the complete campaign folders ``inputs`` into ``out`` (module docstring); returns
    ``{"folder", "rows", "sources"}``.

    Raises:
        CampaignError: an input that is not a complete, intact campaign folder, or rows that collide.
        OutputError: ``out`` cannot be written or holds something else.
    """
    inputs = [pathlib.Path(p) for p in inputs]
    out = pathlib.Path(out)
    if len(inputs) < 2:
        raise CampaignError(f"merge needs at least two campaign folders, got {len(inputs)}")
    problem = _output_problem(out, inputs, force)
    if problem:
        raise OutputError(problem)
    tables, sources, trajs = [], [], []
    for f in inputs:
        path, doc = verified_table(f)
        tables.append(path)
        trajs.append(_verified_trajectories(f, doc))
        sources.append({"folder": str(f.resolve()), "kind": doc.get("kind"), "name": (
            doc.get("resolved", {}).get("definition", {}).get("name") or doc.get("name")),
            "definition_sha256": doc.get("definition_sha256"), "rows": doc.get("rows"),
            "runs_parquet_sha256": doc["runs_parquet"]["sha256"]})
    import pandas as pd

    frames = []
    for i, p in enumerate(tables):
        k = _keys(p)
        k["_source"] = i
        frames.append(k)
    keys = pd.concat(frames, ignore_index=True)
    files = keys.groupby("scenario")["scenario_sha256"].nunique()
    mixed = sorted(files[files > 1].index)
    if mixed:
        where = {s: sorted({str(inputs[i]) for i in keys.loc[keys.scenario == s, "_source"]}) for s in mixed}
        raise CampaignError("conflicting rows: scenario " + "; ".join(f"{s!r} comes from different scenario files "
                                                                      f"in {', '.join(where[s])}" for s in mixed[:3])
                            + " (rows of one scenario name must come from one file)")
    dup = keys[keys.duplicated(list(KEY_COLUMNS), keep=False)]
    if len(dup):
        first = dup.groupby(list(KEY_COLUMNS), sort=True)["_source"].apply(list)
        lines = []
        for key, srcs in list(first.items())[:5]:
            a, b = _row(tables[srcs[0]], key), _row(tables[srcs[1]], key)
            what = "identical (duplicate)" if _same(a, b) else "different values (conflict)"
            lines.append(f"{dict(zip(KEY_COLUMNS, key))} in {inputs[srcs[0]]} and {inputs[srcs[1]]}: {what}")
        raise CampaignError(f"{len(first)} row key(s) occur in more than one folder; nothing was written: "
                            + "; ".join(lines) + (" ..." if len(first) > 5 else ""))
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot create {out}: {exc.strerror or exc}") from None
    extra = {}
    if all(t is not None for t in trajs):       # every input has its trajectories: they are merged too
        n = concat_files(trajs, out / TRAJECTORIES_FILE)
        extra["trajectories_parquet"] = {"rows": n, "size": (out / TRAJECTORIES_FILE).stat().st_size,
                                         "sha256": sha256_file(out / TRAJECTORIES_FILE)}
    elif (out / TRAJECTORIES_FILE).is_file():    # the earlier merge's (replaced with --force): not left beside
        (out / TRAJECTORIES_FILE).unlink()
    rows = concat_files(tables, out / RUNS_FILE)
    doc = {"schema": SCHEMA, "kind": "merge", "complete": True, **extra,
           "created_utc": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
           "sources": sources, "rows": rows,
           "runs_parquet": {"size": (out / RUNS_FILE).stat().st_size, "sha256": sha256_file(out / RUNS_FILE)}}
    atomic_write_text(out / CAMPAIGN_FILE, json.dumps(doc, indent=1) + "\n")
    log.info("merged %d folders into %s (%d rows)", len(inputs), out, rows)
    return {"folder": out, "rows": rows, "sources": sources}
