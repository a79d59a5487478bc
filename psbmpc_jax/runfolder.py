"""Run folders: the results of one ``psbmpc-jax run`` of one scenario, with a manifest that says which files
belong to the run, their sizes and SHA-256 hashes, and whether the run completed.

``manifest.json`` (schema :data:`MANIFEST_SCHEMA`)::

    {"schema": "psbmpc-run/1", "run_id": "<32 hex digits>", "complete": true,
     "created_utc": "...", "completed_utc": "...", "scenario": "head_on",
     "package": {"version": "...", "commit": "..."},
     "files": {"metrics.json": {"size": 1234, "sha256": "..."}, ...}}

How a run is written (:class:`RunWriter`): every file goes first into a hidden staging folder
``.psbmpc-staging-<run id>`` inside the run folder (each atomically); the previous results stay untouched and
valid meanwhile.  Then the commit: ``manifest.json`` is replaced by one that says ``complete: false`` and lists
what is about to be replaced, the previous run's files are removed (exactly those its manifest lists), the new
files are moved in (``os.replace``), the staging folder goes, and the final manifest (``complete: true``, every
file with size and hash) is written last.  A kill at any moment leaves either the previous run complete (with
a staging folder that the next run removes), or a folder whose manifest says it is incomplete -- which every
reader refuses -- never a mix that reads as complete.

The overwrite rule (:func:`run_folder_problem`): a run folder may be written when it does not exist, is empty,
or holds only files that do not belong to a run (they are left alone).  A folder that holds another run (a
``manifest.json``, a leftover staging folder, or -- written before manifests existed -- files with the names
``run`` writes) is refused unless ``force``; with ``force`` exactly that run's files are replaced: those its
manifest lists (or, for an older folder without a manifest, the files named like ``run``'s outputs), never
others.  A ``manifest.json`` that is not a psbmpc-jax manifest is never overwritten.

Readers (:func:`verify_member`) check a file against the manifest of its folder: the run must be complete,
the file listed, and its size and hash those recorded.
"""

from __future__ import annotations

import datetime as _dt
import fnmatch
import hashlib
import json
import logging
import os
import pathlib
import re
import shutil
import uuid

from .safe_io import TEMP_SUFFIX, OutputError, atomic_write_text, read_json_document

__all__ = ["MANIFEST", "MANIFEST_SCHEMA", "STAGING_PREFIX", "OUTPUT_PATTERNS", "RunFolderError", "new_run_id",
           "sha256_file", "read_manifest", "run_folder_problem", "require_complete", "verify_member", "RunWriter"]

log = logging.getLogger(__name__)

MANIFEST = "manifest.json"
MANIFEST_SCHEMA = "psbmpc-run/1"
#: Hidden staging folders of :class:`RunWriter` (``.psbmpc-staging-<run id>``).
STAGING_PREFIX = ".psbmpc-staging-"
_STAGING_RE = re.compile(re.escape(STAGING_PREFIX) + r"[0-9a-f]{32}$")
#: The temporary files of :func:`psbmpc_jax.safe_io.atomic_open` (``.<name>.<random>.tmp``).
_TEMP_RE = re.compile(r"^\.(.+)\.[A-Za-z0-9_]{8}" + re.escape(TEMP_SUFFIX) + "$")
#: The names ``psbmpc-jax run`` writes into a scenario's folder (for folders written before manifests existed).
OUTPUT_PATTERNS = ("metrics.json", "summary.md", "trajectories.csv", "trajectories.npz", "map.png", "map_run*.png",
                   "distances.png", "distances_run*.png", "course_speed.png", "course_speed_run*.png",
                   "monte_carlo.png", "animation.gif", "animation.mp4", "animation_run*.gif", "animation_run*.mp4")


class RunFolderError(ValueError):
    """A run folder or one of its files fails a check; the message names the file and what is wrong."""


def new_run_id() -> str:
    """A fresh run id: 32 random hexadecimal digits (UUID 4)."""
    return uuid.uuid4().hex


def sha256_file(path, chunk: int = 1 << 20) -> str:
    """Hex SHA-256 of the file at ``path``."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while block := fh.read(chunk):
            h.update(block)
    return h.hexdigest()


def _now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")


def read_manifest(folder, *, foreign: str = "raise") -> dict | None:
    """The manifest of ``folder``, or None when it has none.

    Args:
        foreign: what a ``manifest.json`` of another tool (valid JSON without a ``psbmpc-run/`` schema) gives:
            ``"raise"`` (writers: it is never overwritten) or ``"ignore"`` (readers: None, the folder is no run
            folder and its files are checked on their own).

    Raises:
        RunFolderError: a ``manifest.json`` that cannot be read, a psbmpc-jax manifest of another version, or
            (``foreign="raise"``) one of another tool.
    """
    path = pathlib.Path(folder) / MANIFEST
    doc = read_json_document(path, what="run manifest", schema=MANIFEST_SCHEMA, error=RunFolderError,
                             missing_ok=True, foreign_prefix="psbmpc-run/" if foreign == "ignore" else None)
    if doc is None:
        if path.is_file():
            log.debug("%s: not a psbmpc-jax run manifest; ignored", path)
        return None
    if not isinstance(doc.get("files"), dict) or not isinstance(doc.get("run_id"), str):
        raise RunFolderError(f"{path}: a run manifest without run_id or files")
    return doc


def _staging_folders(folder: pathlib.Path) -> list[pathlib.Path]:
    if not folder.is_dir():
        return []
    return sorted(p for p in folder.iterdir() if p.is_dir() and _STAGING_RE.match(p.name))


def _legacy_outputs(folder: pathlib.Path) -> list[str]:
    """Files named like ``run``'s outputs in a folder without a manifest."""
    if not folder.is_dir():
        return []
    return sorted(p.name for p in folder.iterdir()
                  if p.is_file() and any(fnmatch.fnmatchcase(p.name, pat) for pat in OUTPUT_PATTERNS))


def _describe(doc: dict) -> str:
    state = "complete" if doc.get("complete") else "incomplete: interrupted while it was written"
    what = f"scenario {doc['scenario']!r}" if doc.get("scenario") else f"{doc.get('command', 'unknown command')!r}"
    return f"run {doc['run_id']} of {what}, created {doc.get('created_utc', '?')}, {state}"


def run_folder_problem(folder, *, force: bool = False, option: str = "--out") -> str | None:
    """Why results cannot be written into the run folder ``folder`` under the overwrite rule (module
    docstring), or None.  Nothing is changed."""
    folder = pathlib.Path(folder)
    if folder.exists() and not folder.is_dir():
        return f"{option + ': ' if option.startswith('--') else ''}{folder} exists and is not a folder"
    if not folder.exists():
        return None
    try:
        doc = read_manifest(folder)
    except RunFolderError as exc:
        return f"{exc}; it is not overwritten, remove it or choose another folder"
    hint = "pass --force to replace them (only that run's files are removed)" if option.startswith("--") \
        else "pass force=True to replace them (only that run's files are removed)"
    if doc is not None:
        return None if force else f"{folder} holds the results of another run ({_describe(doc)}); {hint}"
    legacy, staging = _legacy_outputs(folder), _staging_folders(folder)
    if (legacy or staging) and not force:
        what = ", ".join(legacy[:4]) + (" ..." if len(legacy) > 4 else "") if legacy else staging[0].name
        return (f"{folder} holds results of an earlier run without a manifest ({what}); {hint}")
    return None


def require_complete(doc: dict, path) -> None:
    """Raise :class:`RunFolderError` naming ``path`` unless the manifest ``doc`` says the run completed."""
    if not doc.get("complete"):
        p = pathlib.Path(path)
        folder = p if p.is_dir() else p.parent
        raise RunFolderError(f"{p}: the run that wrote this folder did not complete ({_describe(doc)}; see "
                             f"{folder / MANIFEST}); its files are not used -- run it again (with --force)")


def verify_member(path, *, require_manifest: bool = False) -> dict | None:
    """Check the file ``path`` against the manifest of its folder; returns the manifest (None when the folder
    has none and ``require_manifest`` is False -- a bare file, checked by its reader alone).

    Raises:
        RunFolderError: the run is incomplete, the file is not listed (a file left from another run, or added
            later), or its size or SHA-256 differs from the recorded one (truncated, changed, or from another
            run) -- the message names the file and what is wrong.
    """
    p = pathlib.Path(path)
    doc = read_manifest(p.parent, foreign="ignore")
    if doc is None:
        if require_manifest:
            raise RunFolderError(f"{p.parent}: no {MANIFEST}; not a run folder written by psbmpc-jax run")
        return None
    where = f"{p.parent / MANIFEST}"
    require_complete(doc, p)
    entry = doc["files"].get(p.name)
    if entry is None:
        raise RunFolderError(f"{p}: not a file of run {doc['run_id']} (not listed in {where}): it is left from "
                             f"another run or was added later")
    size = p.stat().st_size
    if size != entry.get("size"):
        raise RunFolderError(f"{p}: {size} bytes, but run {doc['run_id']} wrote {entry.get('size')} bytes "
                             f"({where}): the file was truncated, changed or comes from another run")
    if sha256_file(p) != entry.get("sha256"):
        raise RunFolderError(f"{p}: its SHA-256 differs from the one run {doc['run_id']} recorded ({where}): the "
                             f"file was changed or comes from another run")
    return doc


class RunWriter:
    """Writes one run folder (module docstring): files go to :attr:`staging` (use :meth:`path` for a name's
    place there), :meth:`commit` moves them in and writes the manifest last; :meth:`abort` drops them.

    Args:
        folder: the run folder (created if missing).
        force: replace the results of another run held there (the overwrite rule); otherwise such a folder
            raises :class:`OutputError`.
        meta: extra manifest fields (e.g. ``{"scenario": name}``).
    """

    def __init__(self, folder, *, force: bool = False, meta: dict | None = None):
        self.folder = pathlib.Path(folder)
        problem = run_folder_problem(self.folder, force=force, option="force")
        if problem:
            raise OutputError(problem)
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise OutputError(f"cannot create the run folder {self.folder}: {exc.strerror or exc}") from None
        self.run_id = new_run_id()
        self.created_utc = _now()
        self.meta = dict(meta or {})
        self.staging = self.folder / f"{STAGING_PREFIX}{self.run_id}"
        try:
            self.staging.mkdir()
        except OSError as exc:
            raise OutputError(f"cannot write in the run folder {self.folder}: {exc.strerror or exc}") from None
        self._names: list[str] = []

    def path(self, name: str) -> pathlib.Path:
        """Where the file ``name`` is written before the commit (registered as one of the run's files)."""
        if "/" in name or os.sep in name or name in ("", ".", "..", MANIFEST) or name.startswith(STAGING_PREFIX):
            raise ValueError(f"not a run file name: {name!r}")
        if name not in self._names:
            self._names.append(name)
        return self.staging / name

    def adopt(self, paths) -> None:
        """Register files that another writer put into :attr:`staging` (e.g. figures)."""
        for p in paths:
            p = pathlib.Path(p)
            if p.parent.resolve() != self.staging.resolve():
                raise ValueError(f"{p} is not in the staging folder {self.staging}")
            self.path(p.name)

    def _manifest(self, complete: bool, files: dict, replacing=()) -> dict:
        from . import __version__
        from .provenance import commit

        doc = {"schema": MANIFEST_SCHEMA, "run_id": self.run_id, "complete": complete,
               "created_utc": self.created_utc, "completed_utc": _now() if complete else None, **self.meta,
               "package": {"version": __version__, "commit": commit()}, "files": files}
        if not complete:
            doc["replacing"] = sorted(replacing)
            doc["staging"] = self.staging.name
        return doc

    def commit(self) -> dict[str, pathlib.Path]:
        """Move the staged files into the run folder, replacing the previous run's; write the manifest last.
        Returns ``{name: final path}``."""
        missing = [n for n in self._names if not (self.staging / n).is_file()]
        if missing:
            raise RuntimeError(f"files registered but not written: {missing}")
        files = {n: {"size": (self.staging / n).stat().st_size, "sha256": sha256_file(self.staging / n)}
                 for n in self._names}
        old = read_manifest(self.folder)
        if old is not None:
            old_names = set(old["files"]) | set(old.get("replacing", ()))
        else:
            old_names = set(_legacy_outputs(self.folder))
        old_staging = [p for p in _staging_folders(self.folder) if p != self.staging]
        if old is not None and old.get("staging"):
            old_staging.append(self.folder / old["staging"])
        atomic_write_text(self.folder / MANIFEST,
                          json.dumps(self._manifest(False, {}, old_names | set(self._names)), indent=1) + "\n")
        for name in sorted(old_names - set(self._names)):
            target = self.folder / name
            if target.is_file() or target.is_symlink():
                target.unlink()
        for name in self._names:
            os.replace(self.staging / name, self.folder / name)
        shutil.rmtree(self.staging, ignore_errors=True)
        for p in old_staging:
            if _STAGING_RE.match(p.name):
                shutil.rmtree(p, ignore_errors=True)
        ours = old_names | set(self._names) | {MANIFEST}
        for p in self.folder.iterdir():        # temporary files of writes that a kill interrupted
            m = _TEMP_RE.match(p.name)
            if m and m.group(1) in ours and p.is_file():
                p.unlink()
        atomic_write_text(self.folder / MANIFEST, json.dumps(self._manifest(True, files), indent=1) + "\n")
        log.info("run %s written to %s (%d files)", self.run_id, self.folder, len(files))
        return {n: self.folder / n for n in self._names}

    def abort(self) -> None:
        """Drop the staged files; the folder keeps what it held before."""
        shutil.rmtree(self.staging, ignore_errors=True)
