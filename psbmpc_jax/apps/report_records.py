"""Loading and analysis of ``psbmpc-bench/1`` records for ``psbmpc-jax report``: reading and validating the JSON
Lines files (docs/bench_schema.md), grouping the records per sweep, swept value and implementation, least-squares
fits and the CPU/GPU crossover."""

from __future__ import annotations

import json
import math
import pathlib
import re
from collections import defaultdict

import numpy as np

from ..safe_io import json_schema, read_json_document

__all__ = ["SCHEMA", "REQUIRED_FIELDS", "load_results", "linear_fit", "impl_label", "find_crossover",
           "group_records"]

SCHEMA = "psbmpc-bench/1"

REQUIRED_FIELDS = (
    "schema", "sweep", "swept", "impl", "platform", "device_kind", "n_devices", "host",
    "estimator", "dtype", "grounding_mode",
    "n_M", "n_cbs", "n_do", "n_ps", "n_so", "n_vertices", "n_ct", "T", "dt",
    "compile_s", "times_ms", "median_ms", "min_ms", "max_ms", "q1_ms", "q3_ms",
    "peak_memory_bytes", "memory_source", "best", "skipped", "skip_reason", "versions", "commit", "timestamp",
)
SWEPT_SIZES = ("n_cbs", "n_ps", "n_do", "n_so", "n_vertices")
SCHEDULES = ("interleaved", "sequential")
_INT_FIELDS = ("n_devices", "n_M", "n_cbs", "n_do", "n_ps", "n_so", "n_vertices", "n_ct")


# ----------------------------------------------------------------------------------------------- loading
def _expand(paths) -> list[pathlib.Path]:
    out = []
    for p in paths:
        p = pathlib.Path(p)
        if p.is_dir():
            found = sorted(p.glob("*.jsonl"))
            if not found:
                raise ValueError(f"{p}: directory contains no *.jsonl benchmark files")
            out += found
        elif p.exists():
            out.append(p)
        else:
            raise FileNotFoundError(f"benchmark results file not found: {p}")
    return out


#: What the report reads, for error messages about files that are something else.
EXPECTED = (f"psbmpc-jax report reads the JSON Lines files written by psbmpc-jax bench: one {SCHEMA} record "
            f"per line, each with \"schema\": \"{SCHEMA}\" (see docs/bench_schema.md)")


def _not_bench_file(path, lineno: int, error: str) -> ValueError:
    """The error for a file that is not benchmark results: what it seems to be, and what is expected."""
    kind = ""
    try:   # a whole JSON document (e.g. metrics.json of psbmpc-jax run) rather than JSON Lines?
        schema = json_schema(read_json_document(path, what="JSON document"))
    except ValueError:
        schema = None
    if schema is not None:
        what = " (metrics.json of psbmpc-jax run)" if schema.startswith("psbmpc-sim/") else ""
        kind = f"; this file is one {schema!r} JSON document{what}, not benchmark results"
    return ValueError(f"{path}:{lineno}: {error}{kind}. {EXPECTED}")


def _validate(rec, where: str) -> None:
    if not isinstance(rec, dict):
        raise ValueError(f"{where}: expected a JSON object, got {type(rec).__name__}. {EXPECTED}")
    if "schema" not in rec:
        raise ValueError(f"{where}: no 'schema' field, so not a {SCHEMA} record. {EXPECTED}")
    if rec.get("schema") != SCHEMA:
        raise ValueError(f"{where}: wrong schema {rec.get('schema')!r} (expected {SCHEMA!r}). {EXPECTED}")
    missing = [f for f in REQUIRED_FIELDS if f not in rec]
    if missing:
        raise ValueError(f"{where}: missing field(s) {', '.join(missing)}")
    if rec["swept"] not in SWEPT_SIZES:
        raise ValueError(f"{where}: unknown swept size {rec['swept']!r} (expected one of {SWEPT_SIZES})")
    for f in _INT_FIELDS:
        v = rec[f]
        if not isinstance(v, int) or isinstance(v, bool):
            raise ValueError(f"{where}: field {f!r} must be an integer, got {v!r}")
    if not isinstance(rec["skipped"], bool):
        raise ValueError(f"{where}: field 'skipped' must be true/false, got {rec['skipped']!r}")
    t = rec["times_ms"]
    if not isinstance(t, list) or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in t):
        raise ValueError(f"{where}: field 'times_ms' must be a list of numbers")
    if not rec["skipped"] and not t:
        raise ValueError(f"{where}: record is not skipped but 'times_ms' is empty")
    for f in ("impl", "platform", "sweep", "host"):
        if not isinstance(rec[f], str):
            raise ValueError(f"{where}: field {f!r} must be a string, got {rec[f]!r}")
    if not isinstance(rec["versions"], dict):
        raise ValueError(f"{where}: field 'versions' must be an object")
    if rec.get("schedule", "sequential") not in SCHEDULES:
        raise ValueError(f"{where}: field 'schedule' must be one of {SCHEDULES}, got {rec['schedule']!r}")


def load_results(paths) -> list[dict]:
    """Read, validate and merge ``psbmpc-bench/1`` JSON Lines files (or directories of ``*.jsonl``).

    Blank lines are ignored. Skipped records are kept. Each returned record is the file's dict plus
    ``_source`` (``"file:line"``).

    Raises:
        ValueError: no paths; malformed JSON, wrong ``schema`` or missing/ill-typed fields (the message
            names the file and line); no records at all.
        FileNotFoundError: a path does not exist.
    """
    if isinstance(paths, (str, pathlib.Path)):
        paths = [paths]
    paths = list(paths)
    if not paths:
        raise ValueError("no benchmark results files given")
    records = []
    for path in _expand(paths):
        records_in_file = 0
        try:
            text = pathlib.Path(path).read_text(encoding="utf-8")
        except UnicodeDecodeError:
            raise ValueError(f"{path}: not a text file. {EXPECTED}") from None
        for lineno, line in enumerate(text.split("\n"), 1):
            if not line.strip():
                continue
            where = f"{path}:{lineno}"
            try:
                rec = json.loads(line)
            except json.JSONDecodeError as e:
                if not records_in_file:   # nothing valid yet: probably not a results file at all
                    raise _not_bench_file(path, lineno, f"malformed JSON ({e.msg} at column {e.colno})") \
                        from None
                raise ValueError(f"{where}: malformed JSON ({e.msg} at column {e.colno})") from None
            _validate(rec, where)
            records_in_file += 1
            rec = dict(rec)
            rec.setdefault("schedule", "sequential")   # files written before the field: always sequential
            rec["_source"] = where
            records.append(rec)
    if not records:
        raise ValueError(f"no benchmark records in {', '.join(str(p) for p in paths)} (empty input)")
    return records


# ------------------------------------------------------------------------------------------- analysis
def impl_label(rec: dict) -> str:
    """"reference" for the sequential reference, else "JAX-<PLATFORM>" (+ " x<n>" when n_devices > 1, + " dense"
    for the exact mode's dense grounding search; records without the field used the culled one)."""
    if rec["impl"] == "reference":
        return "reference"
    lab = f"{rec['impl'].upper()}-{rec['platform'].upper()}"
    if rec["n_devices"] > 1:
        lab += f" x{rec['n_devices']}"
    if rec.get("grounding_mode") == "exact" and rec.get("grounding_search", "culled") == "dense":
        lab += " dense"
    return lab


def label_order(labels) -> list[str]:
    def key(lab):
        fixed = {"reference": 0, "JAX-CPU": 1, "JAX-GPU": 2}
        return (fixed.get(lab, 3), lab)
    return sorted(set(labels), key=key)


def linear_fit(x, y) -> dict:
    """Least-squares line ``y ≈ slope·x + intercept``; returns ``slope``, ``intercept``, ``r2``, ``n``.

    R² = 1 − SS_res/SS_tot (1.0 when SS_tot = 0 and the fit is exact, NaN with < 2 distinct x)."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    n = int(x.size)
    if n < 2 or np.unique(x).size < 2:
        return {"slope": math.nan, "intercept": math.nan, "r2": math.nan, "n": n}
    A = np.stack([x, np.ones_like(x)], axis=1)
    (slope, intercept), *_ = np.linalg.lstsq(A, y, rcond=None)
    res = y - (slope * x + intercept)
    ss_res = float(res @ res)
    ss_tot = float(((y - y.mean()) ** 2).sum())
    if ss_tot == 0.0:
        r2 = 1.0 if ss_res <= 1e-30 else math.nan
    else:
        r2 = 1.0 - ss_res / ss_tot
    return {"slope": float(slope), "intercept": float(intercept), "r2": float(r2), "n": n}


def find_crossover(n_ct, cpu_ms, gpu_ms) -> dict:
    """Smallest n_ct at which GPU is faster than CPU.

    Points are sorted by n_ct. Returns ``{"kind": ...}`` with kind
    ``"crossover"`` (``n_ct``: linear interpolation of gpu−cpu between the bracketing points, ``bracket``:
    the raw (n_ct_lo, n_ct_hi)), ``"gpu_always_faster"`` (faster from the smallest measured n_ct) or
    ``"none"`` (no crossover in the measured range)."""
    pts = sorted(zip(n_ct, cpu_ms, gpu_ms))
    if not pts:
        return {"kind": "none"}
    d = [(n, g - c) for n, c, g in pts]
    if d[0][1] < 0:
        return {"kind": "gpu_always_faster", "n_ct": d[0][0], "bracket": (None, d[0][0])}
    for (n0, d0), (n1, d1) in zip(d, d[1:]):
        if d0 >= 0 and d1 < 0:
            n_star = n0 + d0 * (n1 - n0) / (d0 - d1)
            return {"kind": "crossover", "n_ct": float(n_star), "bracket": (n0, n1)}
    return {"kind": "none"}


class Cell:
    """All records of one implementation at one point (sweep, x)."""

    def __init__(self):
        self.times: list[float] = []
        self.records: list[dict] = []

    @property
    def measured(self):
        return [r for r in self.records if not r["skipped"]]

    @property
    def skipped(self) -> bool:
        return not self.measured and bool(self.records)

    @property
    def median(self):
        return float(np.median(self.times)) if self.times else None

    @property
    def skip_reasons(self):
        return sorted({r["skip_reason"] or "no reason given" for r in self.records if r["skipped"]})


def group_records(records):
    """{(sweep, swept): {x: {label: Cell}}} plus n_ct per (sweep, swept, x)."""
    groups = defaultdict(lambda: defaultdict(lambda: defaultdict(Cell)))
    n_ct = {}
    for r in records:
        key = (r["sweep"], r["swept"])
        x = r[r["swept"]]
        cell = groups[key][x][impl_label(r)]
        cell.records.append(r)
        if not r["skipped"]:
            cell.times.extend(float(t) for t in r["times_ms"])
        n_ct.setdefault((key, x), r["n_ct"])
    return groups, n_ct


def natural_key(key):
    """Sort (sweep, swept) keys naturally: fig5 < fig6 < fig10 < custom."""
    return tuple((0, int(t), "") if t.isdigit() else (1, 0, t)
                 for part in key for t in re.findall(r"\d+|\D+", str(part)))


def sorted_keys(groups):
    return sorted(groups, key=natural_key)


def fmt_ms(v):
    if v is None:
        return "—"
    return f"{v:.4g}"


def fmt_x(v):
    return f"{v:.3g}×" if v is not None else "—"

