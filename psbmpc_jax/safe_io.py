"""Writing result files safely: atomically (a temporary file in the same folder, then ``os.replace``), never
over an input, and with errors that name the path and what is wrong.

* :func:`atomic_open` / :func:`atomic_write_text` / :func:`atomic_write_bytes`: the file appears complete or
  not at all -- a failure (an exception, a full disk, a kill) leaves at most a hidden temporary file
  ``.<name>.<random>.tmp`` next to it, never a partial ``<name>``.
* :func:`same_file`: whether two spellings name one file (symlinks, ``..``, hard links, a case-insensitive
  file system).
* :func:`file_output_problem`: why a file cannot be written at a path (a folder there, a file where a folder
  is needed, no permission), as a message; :class:`OutputError` carries such a message.
* :func:`read_json_document`: the one reader of the JSON files the package writes and reads back (manifests,
  campaign files, metrics): errors name the file and what was expected, raised as the caller's error class.
"""

from __future__ import annotations

import contextlib
import json
import os
import pathlib
import tempfile

__all__ = ["OutputError", "atomic_open", "atomic_write_text", "atomic_write_bytes", "same_file",
           "file_output_problem", "check_output_file", "TEMP_SUFFIX", "read_json_document",
           "json_schema"]

#: Suffix of the temporary files of :func:`atomic_open` (hidden: they start with a dot).
TEMP_SUFFIX = ".tmp"


class OutputError(OSError):
    """A result file cannot be written where asked; the message names the path and the reason."""


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


_FILE_MODE = 0o666 & ~_umask()          # what open(path, "w") would give a new file


@contextlib.contextmanager
def atomic_open(path, mode: str = "w", *, encoding: str | None = "utf-8", newline: str | None = None):
    """Open a temporary file next to ``path`` for writing; on a clean exit it is flushed, synced to disk and
    renamed onto ``path`` (``os.replace``: atomic on POSIX and Windows); on an exception it is removed and
    ``path`` is left as it was.

    Args:
        path: the final file.
        mode: ``"w"`` (text) or ``"wb"`` (binary).
        encoding, newline: as for :func:`open` (text mode only).

    Raises:
        OutputError: the folder does not exist or cannot be written, or ``path`` is a folder.
    """
    if mode not in ("w", "wb"):
        raise ValueError(f"mode must be 'w' or 'wb', got {mode!r}")
    path = pathlib.Path(path)
    problem = file_output_problem(path, create_parents=False)
    if problem:
        raise OutputError(problem)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=TEMP_SUFFIX, dir=path.parent)
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None
    try:
        opened = os.fdopen(fd, "wb") if "b" in mode else os.fdopen(fd, "w", encoding=encoding, newline=newline)
        with opened as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, _FILE_MODE)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def atomic_write_text(path, text: str, *, encoding: str = "utf-8") -> pathlib.Path:
    """Write ``text`` to ``path`` atomically (:func:`atomic_open`); returns the path."""
    with atomic_open(path, "w", encoding=encoding, newline="") as fh:
        fh.write(text)
    return pathlib.Path(path)


def atomic_write_bytes(path, data: bytes) -> pathlib.Path:
    """Write ``data`` to ``path`` atomically (:func:`atomic_open`); returns the path."""
    with atomic_open(path, "wb") as fh:
        fh.write(data)
    return pathlib.Path(path)


def same_file(a, b) -> bool:
    """True when the paths ``a`` and ``b`` name the same file: the same resolved path (symlinks, ``.`` and
    ``..`` followed) or, when both exist, the same device and inode (hard links, case-insensitive names)."""
    pa, pb = pathlib.Path(a).expanduser(), pathlib.Path(b).expanduser()
    if os.path.realpath(pa) == os.path.realpath(pb):
        return True
    try:
        return os.path.samefile(pa, pb)
    except OSError:
        return False


def _nearest_existing(p: pathlib.Path) -> pathlib.Path:
    p = p.absolute()
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def file_output_problem(path, *, create_parents: bool = True) -> str | None:
    """Why a file cannot be written at ``path`` (its missing parent folders created when
    ``create_parents``), as a message naming the path; None if it can.  Nothing is created."""
    p = pathlib.Path(path).expanduser()
    if p.is_dir():
        return f"{p} is a folder; give a file name"
    base = _nearest_existing(p.parent)
    if not base.is_dir():
        return f"cannot write {p}: {base} is a file, not a folder"
    if base != p.parent.absolute() and not create_parents:
        return f"cannot write {p}: the folder {p.parent} does not exist"
    if not os.access(base, os.W_OK | os.X_OK):
        return f"cannot write {p}: no permission to write in {base}"
    return None


def check_output_file(path, *, overwrite: bool = True, what: str = "output file") -> pathlib.Path:
    """``path`` as a Path if a file can be written there; else :class:`OutputError` naming it (an existing
    file when ``overwrite=False`` is refused too)."""
    p = pathlib.Path(path).expanduser()
    problem = file_output_problem(p)
    if problem:
        raise OutputError(f"{what}: {problem}")
    if not overwrite and p.exists():
        raise OutputError(f"{what} {p} exists already; remove it, choose another name or pass overwrite=True")
    return p


def json_schema(doc) -> str | None:
    """The ``"schema"`` member of a JSON document when it is an object with a string there, else None."""
    schema = doc.get("schema") if isinstance(doc, dict) else None
    return schema if isinstance(schema, str) else None


def read_json_document(path, *, what: str, schema: str | None = None, error: type[Exception] = ValueError,
                       missing_ok: bool = False, foreign_prefix: str | None = None, note: str = ""):
    """The JSON document at ``path``, its ``"schema"`` checked.

    Args:
        path: the file.
        what: what the file should be, a noun taking "a", for messages (``"run manifest"``).
        schema: the expected ``"schema"`` member; None: any JSON value is returned unchecked.
        error: the exception class raised (called with the message alone).
        missing_ok: no file at ``path`` gives None instead of an error.
        foreign_prefix: with ``schema``: a document whose schema does not start with this prefix (another
            tool's file, or no JSON object at all) gives None; one that does but differs from ``schema`` (another
            version) still raises.
        note: appended to the wrong-schema message (``"; it is not overwritten"``).

    Raises:
        error: ``"<path>: cannot be read as a <what> (<reason>)"`` (no such file, unreadable, not UTF-8, not
            JSON) or ``"<path>: not a psbmpc-jax <what> of this version (schema <found>, expected
            <schema>)<note>"``.
    """
    path = pathlib.Path(path)
    if missing_ok and not path.is_file():
        return None
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise error(f"{path}: cannot be read as a {what} ({exc})") from None
    if schema is None:
        return doc
    found = doc.get("schema") if isinstance(doc, dict) else None
    if found != schema:
        if foreign_prefix is not None and not (isinstance(found, str) and found.startswith(foreign_prefix)):
            return None
        raise error(f"{path}: not a psbmpc-jax {what} of this version (schema {found!r}, expected {schema!r}){note}")
    return doc
