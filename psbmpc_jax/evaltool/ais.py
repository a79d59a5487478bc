"""AIS-style track files: timestamp, MMSI, latitude, longitude and optional SOG / COG, one row per report.

The format (header names case-insensitive, any column order, extra columns ignored; blank lines and lines
starting with ``#`` skipped)::

    timestamp,MMSI,lat,lon[,SOG,COG]
    2024-05-02T10:00:03Z,257000001,63.4412,10.3901,7.8,45.1
    2024-05-02T10:00:05Z,257000002,63.4518,10.4217,8.1,224.0
    ...

* ``timestamp``: ISO 8601 (``2024-05-02T10:00:03Z``, ``2024-05-02 12:00:03+02:00``; without an offset it is
  read as UTC) or Unix seconds -- one kind for the whole file.  ``BaseDateTime`` is accepted as its name too;
* ``MMSI``: the vessel's identifier (any non-empty text);
* ``lat`` / ``lon`` (also ``latitude`` / ``longitude``): WGS 84 degrees;
* ``SOG`` [knots] and ``COG`` [deg, clockwise from north]: both or neither; without them course and speed are
  derived from the positions (:func:`~psbmpc_jax.evaltool.tracks.derive_course_speed`).  The AIS ranges apply:
  SOG 0 to 102.2 kn (102.3 means "not available"), COG from 0 up to, not including, 360 (360 is "not
  available").

Each vessel is sampled at its own, irregular times (rows in any order).  :func:`load_ais_csv` puts all vessels on
one clock: from the latest first report to the earliest last report (the overlap of the vessels' time spans --
reports outside it are not scored), every ``dt`` seconds (default :data:`DEFAULT_DT_S`); positions and SOG are
interpolated linearly, COG on the unit circle (:func:`~psbmpc_jax.evaltool.tracks.unwrap_interp`).  Positions
are projected to metres north / east of the centroid of all reports with the local transverse Mercator projection
of :func:`psbmpc_jax.geo.latlon_to_ned` (exact to below a millimetre; the flat frame's scale error is 1.2e-6 at
10 km from the centroid and 1.2e-4 at the largest distance accepted, :data:`~psbmpc_jax.geo.LATLON_MAX_DISTANCE_M`).
"""

from __future__ import annotations

import logging
import math
import pathlib

import numpy as np

from ..geo import LATLON_MAX_DISTANCE_M, latlon_to_ned, ned_to_latlon
from .tracks import MAX_TRACK_SPEED_MPS, Tracks, derive_course_speed, own_index, unwrap_interp

__all__ = ["AIS_COLUMNS", "AIS_OPTIONAL_COLUMNS", "COLUMN_ALIASES", "DEFAULT_DT_S", "MAX_SOG_KN", "GAP_WARN_S",
           "KNOT_MPS", "MAX_UNIX_S", "ais_columns", "load_ais_csv", "ais_frame"]

log = logging.getLogger(__name__)

#: Required columns of an AIS-style file (as documented; matched case-insensitively, see :data:`COLUMN_ALIASES`).
AIS_COLUMNS = ("timestamp", "MMSI", "lat", "lon")
#: Optional columns (both or neither): speed over ground [kn], course over ground [deg].
AIS_OPTIONAL_COLUMNS = ("SOG", "COG")
#: Header names accepted for each column (lower case).
COLUMN_ALIASES = {"timestamp": ("timestamp", "basedatetime"), "MMSI": ("mmsi",), "lat": ("lat", "latitude"),
                  "lon": ("lon", "longitude"), "SOG": ("sog",), "COG": ("cog",)}
#: Step of the common clock when none is given [s] (the default evaluation sample interval).
DEFAULT_DT_S = 1.0
#: Largest SOG [kn] an AIS report can carry (ITU-R M.1371: 102.3 kn means "not available").
MAX_SOG_KN = 102.2
#: A vessel without a report for longer than this [s] inside the overlap gets a warning (its track is interpolated
#: linearly across the gap).
GAP_WARN_S = 60.0
#: Unix timestamps [s] must be below this (2100-01-01T00:00:00Z): larger ones are milliseconds or microseconds.
MAX_UNIX_S = 4102444800.0
#: One knot in m/s.
KNOT_MPS = 1852.0 / 3600.0


def ais_columns(header) -> dict[str, int] | None:
    """Column index of each AIS column in ``header`` (missing optional ones left out), or None when a required
    one is missing.  ``ValueError`` when two header cells name the same column."""
    found: dict[str, int] = {}
    for j, h in enumerate(header):
        key = h.strip().lower()
        for col, names in COLUMN_ALIASES.items():
            if key in names:
                if col in found:
                    raise ValueError(f"columns {header[found[col]]!r} and {h!r} both give {col}; keep one")
                found[col] = j
    return found if all(c in found for c in AIS_COLUMNS) else None


def missing_columns(header) -> list[str]:
    """The required AIS columns ``header`` lacks (for the format-detection error)."""
    keys = {h.strip().lower() for h in header}
    return [c for c in AIS_COLUMNS if not keys & set(COLUMN_ALIASES[c])]


def load_ais_csv(p: pathlib.Path, header: list[str], rows: list[tuple[int, list[str]]], own=None,
                 dt: float | None = None) -> Tracks:
    """:class:`Tracks` of an AIS-style file already split into ``header`` and ``(line number, cells)`` rows (see
    the module docstring; :func:`psbmpc_jax.evaltool.load_runs` reads the file and calls this).

    Args:
        own: the own-ship's MMSI (required when the file has several vessels).
        dt: step of the common clock [s] (default :data:`DEFAULT_DT_S`).

    Raises:
        ValueError: naming the file, the row (line number) and the column of the first bad value, or the vessels
            and their time spans when they do not overlap.
    """
    import pandas as pd

    step = DEFAULT_DT_S if dt is None else float(dt)
    if not (math.isfinite(step) and step > 0):
        raise ValueError(f"dt (the common clock's step) must be a finite number of seconds > 0, got {dt!r}")
    cols = ais_columns(header)
    if cols is None:
        raise ValueError(f"{p}: the header lacks AIS columns (required: {', '.join(AIS_COLUMNS)})")
    opt = [c in cols for c in AIS_OPTIONAL_COLUMNS]
    if any(opt) and not all(opt):
        raise ValueError(f"{p}: give both optional columns {' and '.join(AIS_OPTIONAL_COLUMNS)}, or neither "
                         f"(then course and speed are derived from the positions)")
    if not rows:
        raise ValueError(f"{p}: no data rows")
    used = [c for c in (*AIS_COLUMNS, *AIS_OPTIONAL_COLUMNS) if c in cols]
    df = pd.DataFrame([[cells[cols[c]].strip() if cols[c] < len(cells) else "" for c in used] for _, cells in rows],
                      columns=used)
    lines = np.array([line for line, _ in rows])

    def fail(i: int, col: str, why: str):
        raise ValueError(f"{p}: row {lines[i]}, column {header[cols[col]].strip()}: {why}")

    num = {}
    for c in ("lat", "lon", *(AIS_OPTIONAL_COLUMNS if all(opt) else ())):
        v = pd.to_numeric(df[c], errors="coerce").to_numpy(float)
        bad = np.flatnonzero(~np.isfinite(v))
        if bad.size:
            fail(int(bad[0]), c, f"not a number: {df[c].iloc[bad[0]]!r}")
        num[c] = v
    for c, lo, hi, what in (("lat", -90.0, 90.0, "a latitude in degrees: -90 to 90"),
                            ("lon", -180.0, 180.0, "a longitude in degrees: -180 to 180")):
        bad = np.flatnonzero((num[c] < lo) | (num[c] > hi))
        if bad.size:
            i = int(bad[0])
            hint = "; are lat and lon swapped?" if c == "lat" and abs(num["lon"][i]) <= 90 else ""
            fail(i, c, f"{num[c][i]:g} is not {what} allowed{hint}")
    if all(opt):
        sog, cog = num["SOG"], num["COG"]
        bad = np.flatnonzero((sog < 0) | (sog > MAX_SOG_KN))
        if bad.size:
            i = int(bad[0])
            why = ("negative" if sog[i] < 0 else "102.3 is the AIS value for 'not available'" if sog[i] == 102.3
                   else "above the largest speed AIS reports")
            fail(i, "SOG", f"{sog[i]:g} kn is not a speed over ground ({why}; 0 to {MAX_SOG_KN:g} kn allowed)")
        bad = np.flatnonzero((cog < 0) | (cog >= 360))
        if bad.size:
            i = int(bad[0])
            why = "; 360 is the AIS value for 'not available'" if cog[i] == 360 else ""
            fail(i, "COG", f"{cog[i]:g} deg is not a course over ground (0 <= COG < 360 allowed){why}")
    mmsi = df["MMSI"].to_numpy(str)
    empty = np.flatnonzero(mmsi == "")
    if empty.size:
        fail(int(empty[0]), "MMSI", "empty vessel identifier")
    t_abs, t0_text = _times(df["timestamp"], fail)

    names = tuple(str(n) for n in dict.fromkeys(mmsi))      # first-appearance order
    if isinstance(own, (int, np.integer)) and not isinstance(own, bool) and str(own) in names:
        own = str(own)                                      # an MMSI given as a number
    if own is None and len(names) > 1:
        raise ValueError(f"{p}: {len(names)} vessels (MMSI {', '.join(names)}): choose the own-ship by its MMSI "
                         f"(--own-mmsi on the command line, own= in Python)")
    try:
        own_i = own_index(own, names)
    except ValueError as exc:
        raise ValueError(f"{p}: {exc}") from None

    # each vessel's reports in time order; duplicate times refused
    order = {}
    for name in names:
        idx = np.flatnonzero(mmsi == name)
        idx = idx[np.argsort(t_abs[idx], kind="stable")]
        if idx.size < 2:
            raise ValueError(f"{p}: vessel MMSI {name}: at least 2 reports are needed, got {idx.size} "
                             f"(row {lines[idx[0]]})")
        dup = np.flatnonzero(np.diff(t_abs[idx]) == 0)
        if dup.size:
            a, b = idx[dup[0]], idx[dup[0] + 1]
            fail(int(b), "timestamp", f"vessel MMSI {name} has two reports at {df['timestamp'].iloc[b]!r} (rows "
                                      f"{lines[a]} and {lines[b]}); each vessel's timestamps must differ")
        order[name] = idx

    start = max(t_abs[i[0]] for i in order.values())
    end = min(t_abs[i[-1]] for i in order.values())
    if end <= start:
        spans = "; ".join(f"MMSI {n}: {df['timestamp'].iloc[i[0]]} to {df['timestamp'].iloc[i[-1]]}"
                          for n, i in order.items())
        raise ValueError(f"{p}: the vessels' time spans do not overlap ({spans}); every vessel must be reported "
                         f"over a common period")
    n = int(math.floor((end - start) / step + 1e-9)) + 1
    if n < 2:
        raise ValueError(f"{p}: the vessels are all reported for only {end - start:g} s together, shorter than the "
                         f"clock step dt = {step:g} s")
    tk = start + step * np.arange(n)

    # projection about the centroid of all reports (longitude averaged on the circle: the antimeridian is fine)
    lat0 = float(np.mean(num["lat"]))
    lon0 = float(np.degrees(np.arctan2(np.mean(np.sin(np.radians(num["lon"]))),
                                       np.mean(np.cos(np.radians(num["lon"]))))))
    ne = latlon_to_ned(num["lat"], num["lon"], lat0, lon0)
    dist = np.hypot(ne[:, 0], ne[:, 1])
    far = np.flatnonzero(dist > LATLON_MAX_DISTANCE_M)
    if far.size:
        i = int(far[0])
        fail(i, "lat", f"({num['lat'][i]:g}, {num['lon'][i]:g}) lies {dist[i] / 1e3:.1f} km from the centroid of "
                       f"the reports ({lat0:.5f}, {lon0:.5f}); at most {LATLON_MAX_DISTANCE_M / 1e3:g} km is "
                       f"supported by the local projection (split the file, or a wrong position?)")

    out = {k: np.empty((len(names), n)) for k in ("north", "east", "course", "speed")}
    for v, (name, idx) in enumerate(order.items()):
        t, north, east = t_abs[idx], ne[idx, 0], ne[idx, 1]
        jump = np.hypot(np.diff(north), np.diff(east)) / np.diff(t)
        bad = np.flatnonzero(jump > MAX_TRACK_SPEED_MPS)
        if bad.size:
            k = int(bad[0])
            fail(int(idx[k + 1]), "lat", f"vessel MMSI {name} moves {jump[k] * np.diff(t)[k]:.0f} m in "
                 f"{np.diff(t)[k]:g} s since row {lines[idx[k]]} ({jump[k]:.0f} m/s; at most "
                 f"{MAX_TRACK_SPEED_MPS:g} m/s allowed): a position jump or a wrong timestamp?")
        inside = (t >= start) & (t <= end)
        gaps = np.flatnonzero((np.diff(t) > GAP_WARN_S) & (t[1:] > start) & (t[:-1] < end))
        for k in gaps[:3]:
            log.warning("%s: vessel MMSI %s has no report for %.0f s (rows %d to %d); its track is interpolated "
                        "linearly across the gap", p, name, t[k + 1] - t[k], lines[idx[k]], lines[idx[k + 1]])
        if gaps.size > 3:
            log.warning("%s: vessel MMSI %s has %d more gaps longer than %g s (the longest %.0f s)", p, name,
                        gaps.size - 3, GAP_WARN_S, float(np.max(np.diff(t)[gaps[3:]])))
        if (~inside).any():
            log.info("%s: vessel MMSI %s: %d of its %d reports lie outside the common period and are not scored",
                     p, name, int((~inside).sum()), t.size)
        if all(opt):
            course, speed = np.radians(num["COG"][idx]), num["SOG"][idx] * KNOT_MPS
        else:
            c2, s2 = derive_course_speed(t, north[None], east[None])
            course, speed = c2[0], s2[0]
        out["north"][v], out["east"][v] = np.interp(tk, t, north), np.interp(tk, t, east)
        out["course"][v], out["speed"][v] = unwrap_interp(tk, t, course), np.interp(tk, t, speed)
    t0_utc = _iso(start) if t0_text == "iso" else f"{start:.3f} (Unix seconds)"
    log.info("%s: %d vessels on a common clock of %d samples every %g s from %s; projected about (%.5f, %.5f)",
             p, len(names), n, step, t0_utc, lat0, lon0)
    try:
        return Tracks(t=tk - start, north=out["north"], east=out["east"], course=out["course"], speed=out["speed"],
                      names=names, own=own_i, source=str(p), t0_utc=t0_utc)
    except ValueError as exc:
        raise ValueError(f"{p}: {exc}") from None


def _times(col, fail) -> tuple[np.ndarray, str]:
    """Seconds since 1970-01-01 UTC of a timestamp column (all Unix seconds, or all ISO 8601), and its kind."""
    import pandas as pd

    unix = pd.to_numeric(col, errors="coerce").to_numpy(float)
    if np.all(np.isfinite(unix)):
        bad = np.flatnonzero((unix < 0) | (unix >= MAX_UNIX_S))
        if bad.size:
            i = int(bad[0])
            fail(i, "timestamp", f"{col.iloc[i]} is not Unix seconds from 1970 to 2100 (0 <= t < {MAX_UNIX_S:.0f} "
                                 f"allowed); milliseconds or microseconds?")
        return unix, "unix"
    parsed = pd.to_datetime(col, format="ISO8601", utc=True, errors="coerce")
    bad = np.flatnonzero(parsed.isna().to_numpy())
    if bad.size:
        i = int(bad[0])
        kind = ("the file's other timestamps are ISO 8601, so every one must be" if np.isfinite(unix[i])
                else "ISO 8601 such as 2024-05-02T10:00:03Z, or Unix seconds, allowed")
        fail(i, "timestamp", f"not a timestamp: {col.iloc[i]!r} ({kind})")
    secs = (parsed - pd.Timestamp("1970-01-01", tz="UTC")).dt.total_seconds().to_numpy(float)
    return secs, "iso"


def _iso(seconds: float) -> str:
    import pandas as pd

    return pd.Timestamp(round(seconds * 1e3), unit="ms", tz="UTC").isoformat(timespec="milliseconds").replace("+00:00", "Z")


def ais_frame(tracks: Tracks, origin_lat: float, origin_lon: float, start: str = "2024-05-02T10:00:00Z", *,
              report_times: dict | None = None, mmsi: dict | None = None, sog_cog: bool = True):
    """The AIS-style rows of local tracks (the inverse of :func:`load_ais_csv`, to make test and example files):
    a ``pandas.DataFrame`` with the columns timestamp (ISO 8601 UTC, ms), MMSI, lat, lon [, SOG, COG], rounded
    like AIS reports (1e-6 deg, 0.1 kn, 0.1 deg), rows sorted by time.

    Args:
        tracks: north/east tracks about ``(origin_lat, origin_lon)``; ``tracks.t = 0`` is ``start``.
        report_times: vessel name -> the times [s] it reports at (within ``tracks.t``; default every sample);
            positions, course and speed are interpolated there (course on the unit circle).
        mmsi: vessel name -> MMSI text (default the names).
        sog_cog: write SOG and COG (else positions only).
    """
    import pandas as pd

    t0 = pd.Timestamp(start)
    t0 = t0.tz_localize("UTC") if t0.tzinfo is None else t0.tz_convert("UTC")
    parts = []
    for v, name in enumerate(tracks.names):
        tr = np.asarray(tracks.t if report_times is None else report_times[name], float)
        if tr.size and (tr.min() < tracks.t[0] or tr.max() > tracks.t[-1]):
            raise ValueError(f"report_times[{name!r}] must lie within the tracks' {tracks.t[0]:g} to "
                             f"{tracks.t[-1]:g} s")
        north, east = np.interp(tr, tracks.t, tracks.north[v]), np.interp(tr, tracks.t, tracks.east[v])
        lat, lon = ned_to_latlon(north, east, origin_lat, origin_lon)
        stamps = (t0 + pd.to_timedelta(np.round(tr * 1e3), unit="ms"))
        part = {"timestamp": stamps.strftime("%Y-%m-%dT%H:%M:%S.%f").str[:-3] + "Z",
                "MMSI": str((mmsi or {}).get(name, name)), "lat": np.round(lat, 6), "lon": np.round(lon, 6)}
        if sog_cog:
            part["SOG"] = np.round(np.interp(tr, tracks.t, tracks.speed[v]) / KNOT_MPS, 1)
            part["COG"] = np.round(np.degrees(unwrap_interp(tr, tracks.t, tracks.course[v])) % 360.0, 1) % 360.0
        parts.append(pd.DataFrame(part).assign(_t=tr))
    return pd.concat(parts).sort_values("_t", kind="stable").drop(columns="_t").reset_index(drop=True)
