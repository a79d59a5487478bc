"""Recorded trajectories: the :class:`Tracks` container, its validation, resampling, and file loading.

Three file kinds are read by :func:`load_tracks` / :func:`load_runs` (a CSV's kind is told by its header):

* the simulator's export (``trajectories.npz`` / ``trajectories.csv`` of ``psbmpc-jax run
  --save-trajectories``, or the folder holding them), read with :func:`psbmpc_jax.sim.output.load_trajectories`;
  ship 0 is the own-ship, and each Monte Carlo run is one :class:`Tracks`;
* a simple user CSV (e.g. AIS tracks), one row per vessel per time::

      t_s,vessel,north_m,east_m[,course_deg,speed_mps]
      0,own,0,0,0,1.0
      0,ferry,200,0,180,1.0
      1,own,1,0,0,1.0
      ...

  ``t_s`` in seconds (any origin), ``vessel`` any non-empty string, positions in metres in a local
  north/east frame, ``course_deg`` over ground clockwise from north, ``speed_mps`` over ground.  The two last
  columns are optional (both or neither); without them course and speed are derived from the positions.  The
  vessels' rows may interleave in any way, but each vessel's times must be strictly increasing down the file,
  and every vessel needs the same times (at least two).  Extra columns are ignored; blank lines and lines
  starting with ``#`` are skipped;
* an AIS-style CSV (``timestamp,MMSI,lat,lon[,SOG,COG]``, irregular per-vessel reports): resampled onto a common
  clock and projected to local metres by :mod:`psbmpc_jax.evaltool.ais`.
"""

from __future__ import annotations

import csv
import io
import math
import pathlib
from dataclasses import dataclass

import numpy as np

from ..checks import MAX_EARTH_M
from ..numerics import wrap_angle_host

__all__ = ["Tracks", "load_tracks", "load_runs", "tracks_from_simulation", "USER_COLUMNS", "OPTIONAL_COLUMNS", "derive_course_speed",
           "unwrap_interp", "check_units", "MAX_POSITION_M", "MAX_TRACK_SPEED_MPS"]

#: Required columns of the user CSV format.
USER_COLUMNS = ("t_s", "vessel", "north_m", "east_m")
#: Optional columns of the user CSV format (both or neither).
OPTIONAL_COLUMNS = ("course_deg", "speed_mps")
#: Largest |north|, |east| [m] of a track: the Earth's circumference (no position on Earth is farther from any
#: local origin; a larger value is a unit error or a corrupt file).
MAX_POSITION_M = MAX_EARTH_M
#: Largest speed [m/s] of a track, given or derived from the positions (194 kn: above any vessel, with room for
#: position noise; a larger value is a unit error, e.g. km/h or mm/s, or a position jump).
MAX_TRACK_SPEED_MPS = 100.0


@dataclass(frozen=True, eq=False)          # holds arrays: compare fields explicitly
class Tracks:
    """Time-stamped states of V vessels on one common time axis (NED metres, radians, seconds).

    Attributes:
        t: sample times ``[n]`` [s], strictly increasing, n >= 2 (uniform or not).
        north, east: positions ``[V, n]`` [m].
        course: course over ground ``[V, n]`` [rad], clockwise from north.
        speed: speed over ground ``[V, n]`` [m/s].
        names: V vessel names (unique).
        own: index of the own-ship.
        source: where the tracks came from (file name and run), for reports.
        t0_utc: the clock time of t = 0 (ISO 8601 UTC, or Unix seconds) for tracks read from an AIS-style
            file, else None.
    """

    t: np.ndarray
    north: np.ndarray
    east: np.ndarray
    course: np.ndarray
    speed: np.ndarray
    names: tuple
    own: int = 0
    source: str | None = None
    t0_utc: str | None = None

    def __post_init__(self):
        _validate_tracks(self)

    @property
    def n_vessels(self) -> int:
        return int(self.north.shape[0])

    @property
    def own_name(self) -> str:
        return self.names[self.own]

    @classmethod
    def from_arrays(cls, t, north, east, course=None, speed=None, names=None, own=0, source=None) -> "Tracks":
        """Build (and validate) tracks from array-likes ``[V, n]`` (a single vessel may be ``[n]``).

        ``course`` [rad] and ``speed`` [m/s] are derived from the positions (:func:`derive_course_speed`) when
        None.  ``names`` defaults to ``vessel0 …``; ``own`` is an index or a name.
        """
        t = np.asarray(t, dtype=float)
        north, east = np.atleast_2d(np.asarray(north, dtype=float)), np.atleast_2d(np.asarray(east, dtype=float))
        if (course is None) != (speed is None):
            raise ValueError("give both course and speed, or neither (then both are derived from the positions)")
        if course is None:
            _check_time(t, "t")
            if north.shape != east.shape or north.shape[-1] != t.size:
                raise ValueError(f"north and east must have shape [V, {t.size}], got {north.shape} and {east.shape}")
            course, speed = derive_course_speed(t, north, east)
        course, speed = np.atleast_2d(np.asarray(course, dtype=float)), np.atleast_2d(np.asarray(speed, dtype=float))
        names = tuple(f"vessel{i}" for i in range(north.shape[0])) if names is None else tuple(str(n) for n in names)
        return cls(t=t, north=north, east=east, course=course, speed=speed, names=names,
                   own=own_index(own, names), source=source)

    def resample(self, dt: float) -> "Tracks":
        """The tracks linearly interpolated onto t_k = t_0 + k·dt, t_k <= t_end (course through its unwrapped
        form, so a turn through north is not interpolated the long way round)."""
        if not dt > 0:
            raise ValueError(f"dt must be > 0, got {dt!r}")
        n = int(math.floor((self.t[-1] - self.t[0]) / dt + 1e-9)) + 1
        if n < 2:
            raise ValueError(f"the tracks span {self.t[-1] - self.t[0]:g} s, shorter than one sample interval "
                             f"({dt:g} s)")
        tk = self.t[0] + dt * np.arange(n)
        tk[-1] = min(tk[-1], self.t[-1])

        def lin(a):
            return np.stack([np.interp(tk, self.t, row) for row in a])

        course = np.stack([unwrap_interp(tk, self.t, row) for row in self.course])
        return Tracks(t=tk, north=lin(self.north), east=lin(self.east), course=course, speed=lin(self.speed),
                      names=self.names, own=self.own, source=self.source, t0_utc=self.t0_utc)


def unwrap_interp(tk, t, angle) -> np.ndarray:
    """Angle ``angle(t)`` [rad] interpolated at ``tk`` through its unwrapped form, wrapped to (−π, π]."""
    a = np.interp(tk, t, np.unwrap(angle))
    return wrap_angle_host(np.asarray(a), include_pi=True)


def derive_course_speed(t, north, east, min_speed: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """Course over ground [rad] and speed [m/s] ``[V, n]`` from positions ``[V, n]`` by (second-order) finite
    differences in time.  Where a vessel does not move (speed < ``min_speed``) the course is held from the last
    moving sample (the first moving one at the start; 0 if it never moves)."""
    t = np.asarray(t, float)
    vn = np.gradient(np.asarray(north, float), t, axis=-1)
    ve = np.gradient(np.asarray(east, float), t, axis=-1)
    speed = np.hypot(vn, ve)
    course = np.arctan2(ve, vn)
    for v in range(course.shape[0]):
        moving = speed[v] >= min_speed
        if not moving.any():
            course[v] = 0.0
            continue
        idx = np.where(moving, np.arange(t.size), -1)
        idx = np.maximum.accumulate(idx)
        idx[idx < 0] = int(np.argmax(moving))
        course[v] = course[v][idx]
    return course, speed


# -------------------------------------------------------------------------------------------- validation
def _check_time(t: np.ndarray, what: str) -> None:
    if t.ndim != 1:
        raise ValueError(f"{what} must be one-dimensional, got shape {t.shape}")
    if t.size < 2:
        raise ValueError(f"{what}: at least 2 samples are needed, got {t.size}")
    if not np.all(np.isfinite(t)):
        k = int(np.flatnonzero(~np.isfinite(t))[0])
        raise ValueError(f"{what}: non-finite time at sample {k}")
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        k = int(bad[0]) + 1
        raise ValueError(f"{what}: times must be strictly increasing; sample {k} ({t[k]:g} s) does not follow "
                         f"sample {k - 1} ({t[k - 1]:g} s)")


def _validate_tracks(tr: Tracks) -> None:
    _check_time(tr.t, "t")
    n = tr.t.size
    for name in ("north", "east", "course", "speed"):
        a = getattr(tr, name)
        if a.ndim != 2 or a.shape[1] != n:
            raise ValueError(f"{name} must have shape [V, {n}] (vessels x samples), got {a.shape}")
        if a.shape[0] != tr.north.shape[0]:
            raise ValueError(f"{name} has {a.shape[0]} vessels, north has {tr.north.shape[0]}")
        bad = np.argwhere(~np.isfinite(a))
        if bad.size:
            v, k = (int(x) for x in bad[0])
            raise ValueError(f"{name}: NaN or infinite value for vessel {v} at sample {k} (t = {tr.t[k]:g} s)")
    if np.any(tr.speed < 0):
        v, k = (int(x) for x in np.argwhere(tr.speed < 0)[0])
        raise ValueError(f"speed: negative value for vessel {v} at sample {k}")
    for name in ("north", "east"):
        a = getattr(tr, name)
        if np.any(np.abs(a) > MAX_POSITION_M):
            v, k = (int(x) for x in np.argwhere(np.abs(a) > MAX_POSITION_M)[0])
            raise ValueError(f"{name}: {a[v, k]:g} m for vessel {v} at sample {k} (t = {tr.t[k]:g} s) is not a "
                             f"position on Earth (|{name}| <= {MAX_POSITION_M:g} m, the Earth's circumference, "
                             f"allowed); a unit error or a corrupt file?")
    _check_speeds(tr.speed, tr.t, "speed")
    if len(tr.names) != tr.north.shape[0]:
        raise ValueError(f"{len(tr.names)} names for {tr.north.shape[0]} vessels")
    if len(set(tr.names)) != len(tr.names):
        raise ValueError(f"vessel names must be unique, got {list(tr.names)}")
    if tr.north.shape[0] < 1:
        raise ValueError("no vessels")
    if not (isinstance(tr.own, (int, np.integer)) and 0 <= tr.own < tr.north.shape[0]):
        raise ValueError(f"own must be a vessel index in [0, {tr.north.shape[0] - 1}], got {tr.own!r}")


def _check_speeds(speed: np.ndarray, t: np.ndarray, name: str, how: str = "") -> None:
    """Refuse a speed above :data:`MAX_TRACK_SPEED_MPS` (``how``: e.g. "derived from the positions")."""
    bad = speed > MAX_TRACK_SPEED_MPS
    if np.any(bad):
        v, k = (int(x) for x in np.argwhere(bad)[0])
        raise ValueError(f"{name}: {speed[v, k]:g} m/s{f' ({how})' if how else ''} for vessel {v} at sample {k} (t = {t[k]:g} s) is not "
                         f"a plausible ship speed (at most {MAX_TRACK_SPEED_MPS:g} m/s allowed); positions or speeds "
                         f"in other units (km/h, knots, mm), or a position jump?")


def check_units(tr: "Tracks") -> None:
    """Units plausibility of tracks about to be scored (``ValueError`` naming the field):

    * the speeds implied by the positions are at most :data:`MAX_TRACK_SPEED_MPS`;
    * positions in degrees: when every position lies within ±90 (north) / ±180 (east) and no vessel moves faster
      than 0.05 m/s by its positions although some vessel moves (given speeds above 0.5 m/s, or a displacement),
      the positions are latitudes / longitudes read as metres — refused, with the conversion to use."""
    try:
        _check_units(tr)
    except ValueError as exc:
        raise ValueError(f"{tr.source}: {exc}" if tr.source else str(exc)) from None


def _check_units(tr: "Tracks") -> None:
    dt = np.diff(tr.t)
    step = np.hypot(np.diff(tr.north, axis=1), np.diff(tr.east, axis=1)) / dt              # [V, n - 1] m/s
    _check_speeds(np.concatenate([step, step[:, -1:]], axis=1), tr.t, "north/east", "derived from the positions")
    in_deg = np.all(np.abs(tr.north) <= 90.0) and np.all(np.abs(tr.east) <= 180.0)
    moved = np.any(step > 0)
    if in_deg and moved and step.max() < 0.05:
        given = float(tr.speed.max())
        why = (f"the given speeds reach {given:g} m/s while the positions move at most {step.max():.3g} m/s"
               if given > 0.5 else f"no vessel moves faster than {step.max():.3g} m/s")
        raise ValueError(
            f"north/east look like latitude/longitude in degrees, not metres: every position is within +-90 / +-180 "
            f"and {why}. Convert them to a local north/east frame in metres first (e.g. "
            f"psbmpc_jax.geo.latlon_to_ned(lat, lon, origin_lat, origin_lon))")


def own_index(own, names) -> int:
    """Index of the own-ship given as an index or a name."""
    if own is None:
        return 0
    if isinstance(own, (int, np.integer)) and not isinstance(own, bool):
        if not 0 <= own < len(names):
            raise ValueError(f"own-ship index {own} out of range: there are {len(names)} vessels")
        return int(own)
    if str(own) in names:
        return names.index(str(own))
    raise ValueError(f"unknown own-ship {own!r}; vessels: {', '.join(names)}")


# ------------------------------------------------------------------------------------------------ loading
def load_runs(path, own=None, dt: float | None = None) -> list[Tracks]:
    """Every run in a trajectory file, one :class:`Tracks` each.

    Args:
        path: a user CSV file (:data:`USER_COLUMNS`), an AIS-style CSV (:mod:`psbmpc_jax.evaltool.ais`), or the
            simulator's ``trajectories.npz`` / ``trajectories.csv`` (or the folder holding them).
        own: the own-ship, by name or index (default: the first vessel: ship 0 of a simulator export, the
            vessel of the first data row of a user CSV); the MMSI for an AIS file (required there when it has
            several vessels).
        dt: the common clock's step [s] for an AIS file (default
            :data:`psbmpc_jax.evaltool.ais.DEFAULT_DT_S`); refused for the other kinds, which have their own
            sample times.

    Raises:
        FileNotFoundError: no such file.
        ValueError: a malformed file (the message names the column, row or vessel).
    """
    p = pathlib.Path(path)
    if p.is_dir() or p.suffix == ".npz" or (p.suffix == ".csv" and p.is_file() and _is_sim_csv(p)):
        _no_dt(p, dt, "a simulator export")
        return _load_sim(p, own)
    if not p.is_file():
        raise FileNotFoundError(f"trajectory file not found: {p}")
    return [_load_csv(p, own, dt)]


def _no_dt(p, dt, kind: str) -> None:
    if dt is not None:
        raise ValueError(f"{p}: dt (--dt) sets the common clock of AIS-style files only; this is {kind}, whose "
                         f"sample times are used as they are")


def load_tracks(path, own=None, run: int = 0, dt: float | None = None) -> Tracks:
    """One run of a trajectory file (see :func:`load_runs`; ``run`` picks the Monte Carlo run of a simulator
    export, a user CSV has only run 0)."""
    runs = load_runs(path, own=own, dt=dt)
    if not 0 <= run < len(runs):
        raise ValueError(f"{path}: run {run} out of range: the file has {len(runs)} run(s)")
    return runs[run]


def _is_sim_csv(p: pathlib.Path) -> bool:
    with open(p, "rb") as fh:                   # bytes: a file that is not UTF-8 is reported by the reader
        first = fh.readline()
    return first.lstrip(b"\xef\xbb\xbf").startswith(b"run,ship,ship_name,")


def _load_sim(p: pathlib.Path, own) -> list[Tracks]:
    from ..sim.output import load_trajectories          # lazy: the simulator package imports JAX

    return tracks_from_simulation(load_trajectories(p), own=own, source=str(p))


def tracks_from_simulation(sim, own=None, source: str | None = None) -> list[Tracks]:
    """One :class:`Tracks` per Monte Carlo run of a simulation: ``sim`` is a
    :class:`psbmpc_jax.sim.output.Trajectories` (as read by ``load_trajectories``) or a
    :class:`psbmpc_jax.sim.SimulationResult` (ship 0 is the own-ship unless ``own`` says otherwise)."""
    if not hasattr(sim, "ship_names"):                 # a SimulationResult: take its true states
        from ..sim.output import Trajectories

        sim = Trajectories.from_result(sim)
    names = tuple(str(n) for n in sim.ship_names)
    own_i = own_index(own, names)
    label = source or sim.scenario or "simulation"
    states = np.asarray(sim.states, float)                 # [R, ships, K+1, 4]
    return [Tracks(t=np.asarray(sim.t, float), north=s[..., 0], east=s[..., 1], course=s[..., 2], speed=s[..., 3],
                   names=names, own=own_i, source=f"{label} run {r}") for r, s in enumerate(states)]


def _load_csv(p: pathlib.Path, own, dt) -> Tracks:
    """A user CSV in local metres or an AIS-style CSV, told apart by the header."""
    from . import ais

    header, rows = _read_csv(p)
    col = {h: i for i, h in enumerate(header)}
    missing = [c for c in USER_COLUMNS if c not in col]
    if not missing:
        _no_dt(p, dt, "a north/east track file")
        return _load_user_csv(p, header, rows, own)
    try:
        found = ais.ais_columns(header)
    except ValueError as exc:
        raise ValueError(f"{p}: {exc}") from None
    if found is not None:
        return ais.load_ais_csv(p, header, rows, own=own, dt=dt)
    raise ValueError(
        f"{p}: the header fits neither accepted format: north/east tracks need "
        f"{','.join(USER_COLUMNS)}[,{','.join(OPTIONAL_COLUMNS)}] (missing column(s) {', '.join(missing)}); "
        f"AIS-style tracks need {','.join(ais.AIS_COLUMNS)}[,{','.join(ais.AIS_OPTIONAL_COLUMNS)}] (missing "
        f"column(s) {', '.join(ais.missing_columns(header))}); got {','.join(header)}")


def _load_user_csv(p: pathlib.Path, header, rows, own) -> Tracks:
    col = {h: i for i, h in enumerate(header)}
    have_opt = [c in col for c in OPTIONAL_COLUMNS]
    if any(have_opt) and not all(have_opt):
        raise ValueError(f"{p}: give both optional columns {' and '.join(OPTIONAL_COLUMNS)}, or neither")
    if not rows:
        raise ValueError(f"{p}: no data rows")
    num_cols = ["t_s", "north_m", "east_m"] + (list(OPTIONAL_COLUMNS) if all(have_opt) else [])
    values = {c: _numeric_column(p, rows, col[c], c) for c in num_cols}
    vessels = [r[1][col["vessel"]].strip() if col["vessel"] < len(r[1]) else "" for r in rows]
    for (line, _), v in zip(rows, vessels):
        if not v:
            raise ValueError(f"{p}: row {line}: empty vessel id")
    names = tuple(dict.fromkeys(vessels))                  # first-appearance order
    return _assemble(p, names, np.array(vessels, dtype=object), values, [line for line, _ in rows], own)


def _read_csv(p: pathlib.Path) -> tuple[list[str], list[tuple[int, list[str]]]]:
    """Header and ``(line number, cells)`` of the data rows; blank lines and ``#`` comments skipped."""
    raw = p.read_bytes()
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        raise ValueError(f"{p}: a track file must be UTF-8 text; byte {exc.start} (line {line}) is "
                         f"0x{raw[exc.start]:02x}, which is not UTF-8 ({exc.reason})") from None
    lines = [(i, row) for i, row in enumerate(csv.reader(io.StringIO(text, newline="")), start=1)
             if row and any(c.strip() for c in row) and not row[0].lstrip().startswith("#")]
    if not lines:
        raise ValueError(f"{p}: empty file; expected a header: {','.join(USER_COLUMNS)} or "
                         f"timestamp,MMSI,lat,lon")
    header = [h.strip() for h in lines[0][1]]
    return header, lines[1:]


def _numeric_column(p, rows, j: int, name: str) -> np.ndarray:
    out = np.empty(len(rows))
    for i, (line, cells) in enumerate(rows):
        cell = cells[j].strip() if j < len(cells) else ""
        try:
            out[i] = float(cell)
        except ValueError:
            raise ValueError(f"{p}: row {line}, column {name}: not a number: {cell!r}") from None
        if not math.isfinite(out[i]):
            raise ValueError(f"{p}: row {line}, column {name}: NaN or infinite value")
    return out


def _assemble(p, names, vessels, values, lines, own) -> Tracks:
    """Arrange the long-format rows into ``[V, n]`` arrays; every vessel must have the same times."""
    t_all = values["t_s"]
    t0 = t_all[vessels == names[0]]
    arrays = {c: np.empty((len(names), t0.size)) for c in values if c != "t_s"}
    for v, name in enumerate(names):
        order = np.flatnonzero(vessels == name)             # file order
        tv = t_all[order]
        if tv.size < 2:
            raise ValueError(f"{p}: vessel {name!r}: at least 2 samples are needed, got {tv.size}")
        bad = np.flatnonzero(np.diff(tv) <= 0)
        if bad.size:
            a, b = order[bad[0]], order[bad[0] + 1]
            raise ValueError(f"{p}: row {lines[b]}: vessel {name!r}: time {tv[bad[0] + 1]:g} s does not increase "
                             f"on its previous row {lines[a]} ({tv[bad[0]]:g} s); each vessel's times must be "
                             f"strictly increasing")
        if tv.size != t0.size or not np.array_equal(tv, t0):
            raise ValueError(f"{p}: vessel {name!r} has different sample times from vessel {names[0]!r}; every "
                             f"vessel needs a row at every time")
        for c in arrays:
            arrays[c][v] = values[c][order]
    course = np.radians(arrays["course_deg"]) if "course_deg" in arrays else None
    speed = arrays.get("speed_mps")
    try:
        return Tracks.from_arrays(t0, arrays["north_m"], arrays["east_m"], course=course, speed=speed,
                                  names=names, own=own, source=str(p))
    except ValueError as e:
        raise ValueError(f"{p}: {e}") from None
