"""The psbmpc polygon CSV format: line 1 ``rows,cols`` (rows = 2), line 2 the eastings, line 3 the northings;
polygons separated by a column of ``-1``."""

from __future__ import annotations

import pathlib

import numpy as np

from .build import RawPolygon, build_chart
from .chart import Chart
from .crs import parse_crs


_SEPARATOR = -1.0


def read_text(path, what: str) -> str:
    p = pathlib.Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{what} file not found: {p}")
    try:
        return p.read_text(encoding="utf-8-sig")
    except (UnicodeDecodeError, OSError) as exc:
        raise ValueError(f"{p}: cannot read as text ({exc}); expected a {what} file") from None


def parse_psbmpc_csv(text: str, where: str) -> list[RawPolygon]:
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    if len(lines) < 3:
        raise ValueError(f"{where}: a psbmpc polygon CSV needs 3 lines ('rows,cols', eastings, northings), got "
                         f"{len(lines)}" + (" (empty file)" if not lines else ""))
    try:
        rows, cols = (int(v) for v in lines[0].split(","))
    except ValueError:
        raise ValueError(f"{where}: line 1 must be 'rows,cols' (two integers, rows = 2), "
                         f"got {lines[0][:60]!r}") from None
    if rows != 2 or len(lines) != 3:
        raise ValueError(f"{where}: expected rows = 2 and exactly 2 data lines (eastings, northings), got rows = "
                         f"{rows} and {len(lines) - 1} data lines")
    data = []
    for k, name in ((1, "eastings"), (2, "northings")):
        try:
            arr = np.array([float(v) for v in lines[k].split(",")])
        except ValueError:
            raise ValueError(f"{where}: line {k + 1} ({name}) must be comma-separated numbers") from None
        if len(arr) != cols:
            raise ValueError(f"{where}: line {k + 1} ({name}) has {len(arr)} values, line 1 says cols = {cols}")
        data.append(arr)
    E, N = data
    sepE, sepN = E == _SEPARATOR, N == _SEPARATOR
    if np.any(sepE != sepN):
        c = int(np.argmax(sepE != sepN))
        raise ValueError(f"{where}: column {c + 1} is -1 in only one row; polygons are separated by a column of -1 "
                         f"in both rows")
    raws, start, fid = [], 0, 0
    for stop in [*np.flatnonzero(sepE), len(E)]:
        if stop > start:
            raws.append(RawPolygon(np.stack([E[start:stop], N[start:stop]], axis=1), [], fid))
            fid += 1
        start = stop + 1
    if not raws:
        raise ValueError(f"{where}: no polygon vertices (only separators)")
    return raws


def load_psbmpc_csv(path, origin=None, *, crs: str = "EPSG:32632", zone: int | None = None) -> Chart:
    """Load a psbmpc polygon CSV (line 1 ``rows,cols``; line 2 eastings; line 3 northings; polygons separated
    by a column of -1; trailing separator optional).

    Args:
        path: the ``.csv`` file.
        origin: local origin ``(E0, N0)`` in the output CRS; default the centre of the bounding box of all
            vertices, rounded to whole metres.
        crs: the file's CRS (the format has no CRS field); default WGS 84 / UTM zone 32N, as the authors' files.
        zone: convert to this UTM zone (exact); default keep the file's zone.
    Polygon ids are their 0-based positions in the file."""
    where = str(path)
    raws = parse_psbmpc_csv(read_text(path, "psbmpc CSV"), where)
    info = parse_crs(crs)
    return build_chart(raws, info, origin=origin, zone=zone, source=where, report={})
