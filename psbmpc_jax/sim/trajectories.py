"""Every run's trajectories of a simulation as files: ``trajectories.csv`` / ``trajectories.npz`` (schema
:data:`TRAJECTORY_SCHEMA`), written atomically by :func:`write_trajectories` and read back, checked, by
:func:`load_trajectories`.

A file inside a run folder (one with a ``manifest.json``, :mod:`psbmpc_jax.runfolder`) is read only when the
run completed, the file is listed and its size and SHA-256 are those recorded.  A file on its own is checked by
what it says about itself: the CSV declares the shape it holds (``n_runs``, ``n_ships``, ``n_steps`` on every
row), so a file cut anywhere -- also at a run boundary -- is refused; the NPZ is a zip archive whose damage
:mod:`numpy` detects.
"""

from __future__ import annotations

import csv
import logging
import pathlib
import zipfile
import zlib
from dataclasses import dataclass

import numpy as np

from ..safe_io import OutputError, atomic_open, file_output_problem
from ..runfolder import RunFolderError, read_manifest, require_complete, verify_member

__all__ = ["TRAJECTORY_SCHEMA", "READABLE_SCHEMAS", "CSV_DIGITS", "SHAPE_COLUMNS", "Trajectories",
           "write_trajectories", "write_trajectory_files", "load_trajectories", "csv_columns"]

log = logging.getLogger(__name__)

#: Schema id of ``trajectories.npz`` and of the column layout of ``trajectories.csv``.
TRAJECTORY_SCHEMA = "psbmpc-traj/2"
#: Schemas :func:`load_trajectories` reads (``/1``: before the declared shape and the run id).
READABLE_SCHEMAS = ("psbmpc-traj/1", TRAJECTORY_SCHEMA)
#: Significant digits of the floats in trajectories.csv (the NPZ file keeps every bit).
CSV_DIGITS = 12
#: The last columns of the CSV: the shape of the whole file, the same on every row.
SHAPE_COLUMNS = ("n_runs", "n_ships", "n_steps")


@dataclass
class Trajectories:
    """Every run's trajectories of one simulation, as written by :func:`write_trajectories` (NumPy arrays;
    NED metres, radians, seconds; ship 0 is the own-ship).

    Attributes:
        scenario: scenario name (None when read from a CSV file, which does not record it).
        t: time of each step ``[K+1]`` [s].
        ship_names: ``n_ships`` names.
        states: true states ``[R, n_ships, K+1, 4]`` = (north, east, course, speed).
        solve_t: time of each MPC update ``[M]`` [s].
        offsets: chosen first maneuver per solve ``[R, n_ships, M, 2]`` = (speed factor, course offset), NaN
            for ships without PSB-MPC.
        costs: the chosen behaviour's cost terms per solve ``[R, n_ships, M, len(cost_names)]``.
        cost_names: the cost columns (``total`` first, then the terms).
        solve_wall: wall time of each solve ``[R, n_ships, M]`` [s].
        run_id: the run folder's run id the NPZ file was written for (None: a CSV, or written on its own).
    """

    scenario: str | None
    t: np.ndarray
    ship_names: list
    states: np.ndarray
    solve_t: np.ndarray
    offsets: np.ndarray
    costs: np.ndarray
    cost_names: tuple
    solve_wall: np.ndarray
    run_id: str | None = None

    @classmethod
    def from_result(cls, result) -> "Trajectories":
        """The trajectories of a :class:`~psbmpc_jax.sim.SimulationResult`."""
        from .simulator import COST_NAMES

        wall = result.solve_wall
        if wall is None:
            wall = np.full(result.offsets.shape[:-1], np.nan)
        return cls(scenario=result.scenario.name, t=np.asarray(result.t, float),
                   ship_names=[s.name for s in result.scenario.ships], states=np.asarray(result.states, float),
                   solve_t=np.asarray(result.solve_t, float), offsets=np.asarray(result.offsets, float),
                   costs=np.asarray(result.best_costs, float),
                   cost_names=tuple(COST_NAMES)[: result.best_costs.shape[-1]], solve_wall=np.asarray(wall, float))

    @property
    def runs(self) -> int:
        return int(self.states.shape[0])


# ------------------------------------------------------------------------------------------------ writing
def csv_columns(cost_names, shape: bool = True) -> list[str]:
    """The header of ``trajectories.csv`` (``shape=False``: the ``psbmpc-traj/1`` header, without
    :data:`SHAPE_COLUMNS`)."""
    return (["run", "ship", "ship_name", "t_s", "north_m", "east_m", "course_deg", "speed_mps", "solve",
             "speed_factor", "course_offset_deg", "solve_wall_s"] + [f"cost_{n}" for n in cost_names]
            + (list(SHAPE_COLUMNS) if shape else []))


def _fmt_col(values) -> list[str]:
    """Each float with CSV_DIGITS significant digits; empty for NaN (no solve at that row)."""
    return ["" if v != v else format(v, f".{CSV_DIGITS}g") for v in np.asarray(values, dtype=float).tolist()]


def _write_npz(tr: Trajectories, path: pathlib.Path, run_id: str | None) -> None:
    with atomic_open(path, "wb") as fh:
        np.savez_compressed(fh, schema=np.array(TRAJECTORY_SCHEMA), scenario=np.array(tr.scenario or ""),
                            run_id=np.array(run_id or ""), t=tr.t, ship_names=np.array(tr.ship_names),
                            states=tr.states, solve_t=tr.solve_t, offsets=tr.offsets, costs=tr.costs,
                            cost_names=np.array(tr.cost_names), solve_wall=tr.solve_wall)


def _write_csv(tr: Trajectories, path: pathlib.Path) -> None:
    R, S, K1, _ = tr.states.shape
    n = R * S * K1
    run = np.repeat(np.arange(R), S * K1)
    ship = np.tile(np.repeat(np.arange(S), K1), R)
    step = np.tile(np.arange(K1), R * S)
    # per-solve columns on the rows of the solve steps (of the ships that solved)
    solve_cols = np.full((n, 3 + len(tr.cost_names)), np.nan)
    solved = np.zeros(n, dtype=int)
    if tr.solve_t.size:
        steps = np.searchsorted(tr.t, tr.solve_t)
        per = np.concatenate([tr.offsets[..., :1], np.degrees(tr.offsets[..., 1:]), tr.solve_wall[..., None],
                              tr.costs], axis=-1)                              # [R, S, M, 3 + C]
        rows = (np.arange(R)[:, None, None] * S + np.arange(S)[None, :, None]) * K1 + steps[None, None, :]
        has = np.isfinite(tr.offsets[..., 0])
        solve_cols[rows[has]] = per[has]
        solved[rows[has]] = 1
    st = tr.states.reshape(n, 4)
    names = np.asarray(tr.ship_names, dtype=object)[ship]
    cols = [[str(v) for v in run.tolist()], [str(v) for v in ship.tolist()], names.tolist(),
            _fmt_col(tr.t[step]), _fmt_col(st[:, 0]), _fmt_col(st[:, 1]), _fmt_col(np.degrees(st[:, 2])),
            _fmt_col(st[:, 3]), [str(v) for v in solved.tolist()]]
    cols += [_fmt_col(solve_cols[:, j]) for j in range(solve_cols.shape[1])]
    cols += [[str(R)] * n, [str(S)] * n, [str(K1)] * n]
    with atomic_open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(csv_columns(tr.cost_names))
        w.writerows(zip(*cols))


def write_trajectory_files(tr: Trajectories, paths: dict, run_id: str | None = None) -> list[pathlib.Path]:
    """Write ``tr`` to ``paths`` (``{"csv": path, "npz": path}``, either or both), each atomically; the NPZ
    file records ``run_id``."""
    out = []
    if "npz" in paths:
        _write_npz(tr, pathlib.Path(paths["npz"]), run_id)
        out.append(pathlib.Path(paths["npz"]))
    if "csv" in paths:
        _write_csv(tr, pathlib.Path(paths["csv"]))
        out.append(pathlib.Path(paths["csv"]))
    return out


def write_trajectories(result, out_dir, formats=("csv", "npz"), *, overwrite: bool = False) -> list[pathlib.Path]:
    """Write every run's trajectories into ``out_dir``: ``trajectories.csv`` and/or ``trajectories.npz``, each
    atomically (complete or absent, never partial).

    CSV (one row per run, ship and time step, run-major): ``run, ship, ship_name, t_s, north_m, east_m,
    course_deg, speed_mps`` (the true states; course in degrees from north, clockwise; 12 significant
    digits), then per solve --
    filled on the rows of the steps at which that ship solved, empty elsewhere -- ``solve`` (1 or 0),
    ``speed_factor``, ``course_offset_deg`` (the chosen first maneuver, applied until the next solve),
    ``solve_wall_s`` and ``cost_<term>`` (``cost_total``, ``cost_do``, ``cost_colregs``, ``cost_so``,
    ``cost_path``: the chosen behaviour's cost terms), and last the shape of the whole file, the same on every
    row: ``n_runs, n_ships, n_steps`` (a file cut short is recognised by its reader).

    NPZ: the arrays of :class:`Trajectories` under the same names (course and offsets in radians), plus
    ``schema`` = :data:`TRAJECTORY_SCHEMA` and ``run_id``.  Read either with :func:`load_trajectories`.

    Raises:
        ValueError: unknown formats.
        OutputError: ``out_dir`` cannot be written, it is a run folder (``manifest.json``: write trajectories
            there with ``write_outputs(..., trajectories=True)``), or a file exists already and ``overwrite``
            is False.
    """
    formats = tuple(formats)
    bad = [f for f in formats if f not in ("csv", "npz")]
    if bad or not formats:
        raise ValueError(f"formats must be a non-empty subset of ('csv', 'npz'), got {formats!r}")
    out = pathlib.Path(out_dir)
    if out.is_dir() and (out / "manifest.json").exists():
        raise OutputError(f"{out} is a run folder (it has a manifest.json): files added to it would not belong to "
                          f"its run; write the trajectories with write_outputs(..., trajectories=True) or into "
                          f"another folder")
    paths = {f: out / f"trajectories.{f}" for f in formats}
    for p in paths.values():
        problem = file_output_problem(p)
        if problem:
            raise OutputError(problem)
        if p.exists() and not overwrite:
            raise OutputError(f"{p} exists already; pass overwrite=True to replace it, or write into another "
                              f"folder")
    out.mkdir(parents=True, exist_ok=True)
    return write_trajectory_files(Trajectories.from_result(result), paths)


# ------------------------------------------------------------------------------------------------ reading
def _pick(folder: pathlib.Path) -> pathlib.Path:
    """The trajectory file of a folder: the NPZ (exact, smaller) before the CSV; in a run folder only a
    file its manifest lists."""
    present = [folder / n for n in ("trajectories.npz", "trajectories.csv") if (folder / n).is_file()]
    doc = read_manifest(folder, foreign="ignore")
    if doc is not None:
        require_complete(doc, folder)
        listed = [p for p in present if p.name in doc["files"]]
        if listed:
            return listed[0]
        if present:
            return present[0]                # verify_member says why it does not belong
        raise FileNotFoundError(f"{folder}: run {doc['run_id']} wrote no trajectories (run it with "
                                f"--save-trajectories)")
    if not present:
        raise FileNotFoundError(f"{folder}: no trajectories.npz or trajectories.csv (write them with "
                                f"psbmpc-jax run --save-trajectories)")
    return present[0]


def load_trajectories(path) -> Trajectories:
    """Read trajectories written by ``psbmpc-jax run --save-trajectories`` (:func:`write_trajectories`).

    Args:
        path: ``trajectories.npz``, ``trajectories.csv``, or the scenario's output folder holding one of them
            (the NPZ file is preferred: it is exact and smaller).

    Returns:
        :class:`Trajectories` (course and course offsets in radians, also when read from the CSV file, whose
        degrees are converted back).

    Raises:
        FileNotFoundError: no such file, or a folder without trajectories.
        ValueError: a file that is not a trajectory export, or one that is damaged or cut short; in a run folder
            (:class:`~psbmpc_jax.runfolder.RunFolderError`, a ValueError): an incomplete run, a file the
            manifest does not list (left from another run), or a size or hash that differs from the recorded
            one.  The message names the file and what is wrong.
    """
    p = pathlib.Path(path)
    if p.is_dir():
        p = _pick(p)
    if not p.is_file():
        raise FileNotFoundError(f"trajectory file not found: {p}")
    if p.suffix not in (".npz", ".csv"):
        raise ValueError(f"{p}: expected a trajectories .npz or .csv file written by psbmpc-jax run "
                         f"--save-trajectories")
    doc = verify_member(p)
    tr = _load_npz(p) if p.suffix == ".npz" else _load_csv(p)
    if doc is not None and tr.run_id and tr.run_id != doc["run_id"]:
        raise RunFolderError(f"{p}: written for run {tr.run_id}, but the folder's manifest is run {doc['run_id']}")
    return tr


def _load_npz(p: pathlib.Path) -> Trajectories:
    try:
        with np.load(p, allow_pickle=False) as z:
            schema = str(z["schema"]) if "schema" in z.files else None
            if schema not in READABLE_SCHEMAS:
                raise ValueError(f"{p}: not a {TRAJECTORY_SCHEMA} trajectory file (schema {schema!r}); expected "
                                 f"the trajectories.npz of psbmpc-jax run --save-trajectories")
            run_id = str(z["run_id"]) if "run_id" in z.files else ""
            return Trajectories(scenario=str(z["scenario"]) or None, t=z["t"],
                                ship_names=[str(s) for s in z["ship_names"]], states=z["states"],
                                solve_t=z["solve_t"], offsets=z["offsets"], costs=z["costs"],
                                cost_names=tuple(str(s) for s in z["cost_names"]), solve_wall=z["solve_wall"],
                                run_id=run_id or None)
    except (zipfile.BadZipFile, zlib.error, EOFError, OSError, KeyError) as exc:
        raise ValueError(f"{p}: cannot be read as a trajectory NPZ file, it is damaged or cut short "
                         f"({type(exc).__name__}: {exc})") from None


def _shape(p, header, rows) -> tuple[int, int, int] | None:
    """The declared (runs, ships, steps) of a ``psbmpc-traj/2`` CSV (None for ``/1``)."""
    if header[-3:] != list(SHAPE_COLUMNS):
        return None
    try:
        declared = {(int(r[-3]), int(r[-2]), int(r[-1])) for r in rows}
    except ValueError:
        raise ValueError(f"{p}: the columns {', '.join(SHAPE_COLUMNS)} must hold integers") from None
    if len(declared) != 1:
        raise ValueError(f"{p}: the rows declare different shapes in {', '.join(SHAPE_COLUMNS)}: "
                         f"{sorted(declared)[:3]}; the file is damaged or assembled from several files")
    return declared.pop()


def _load_csv(p: pathlib.Path) -> Trajectories:
    with open(p, newline="", encoding="utf-8") as fh:
        reader = csv.reader(fh)
        header = next(reader, None)
        fixed = csv_columns((), shape=False)
        costs = header[len(fixed):] if header else []
        if costs[-3:] == list(SHAPE_COLUMNS):
            costs = costs[:-3]
        if header is None or header[: len(fixed)] != fixed or not all(h.startswith("cost_") for h in costs):
            raise ValueError(f"{p}: not a {TRAJECTORY_SCHEMA} trajectory CSV; expected the header "
                             f"{','.join(fixed)},cost_<term>...,{','.join(SHAPE_COLUMNS)} of psbmpc-jax run "
                             f"--save-trajectories")
        rows = list(reader)
    cost_names = tuple(h[len("cost_"):] for h in costs)
    if not rows:
        raise ValueError(f"{p}: the trajectory CSV has no rows")
    short = [i for i, r in enumerate(rows) if len(r) != len(header)]
    if short:
        raise ValueError(f"{p}: row {short[0] + 2} has {len(rows[short[0]])} cells, the header {len(header)}: the "
                         f"file is cut short or damaged")
    declared = _shape(p, header, rows)
    if declared is None:
        log.warning("%s: a psbmpc-traj/1 CSV (written before the files declared their shape): whether it is "
                    "complete cannot be checked", p)
    cols = list(zip(*rows))

    def num(j):
        return np.array([float(v) if v != "" else np.nan for v in cols[j]])

    run, ship = np.array(cols[0], dtype=int), np.array(cols[1], dtype=int)
    t_all = num(3)
    R, S = int(run.max()) + 1, int(ship.max()) + 1
    t = np.unique(t_all)
    K1 = t.size
    if declared is not None and declared != (R, S, K1):
        raise ValueError(f"{p}: declares {declared[0]} runs x {declared[1]} ships x {declared[2]} steps "
                         f"({', '.join(SHAPE_COLUMNS)}) but holds {R} x {S} x {K1}: the file is cut short or "
                         f"damaged")
    if len(rows) != R * S * K1:
        raise ValueError(f"{p}: expected {R} runs x {S} ships x {K1} steps = {R * S * K1} rows, got {len(rows)}")
    step = np.searchsorted(t, t_all)
    seen = np.zeros((R, S, K1), dtype=int)
    np.add.at(seen, (run, ship, step), 1)
    if np.any(seen != 1):
        r, s, k = (int(v) for v in np.argwhere(seen != 1)[0])
        raise ValueError(f"{p}: run {r}, ship {s}, t = {t[k]:g} s appears {seen[r, s, k]} times (once expected)")
    states = np.full((R, S, K1, 4), np.nan)
    states[run, ship, step] = np.stack([num(4), num(5), np.radians(num(6)), num(7)], axis=1)
    names = [""] * S
    for s_idx, name in zip(ship.tolist(), cols[2]):
        names[s_idx] = name
    solved = np.array(cols[8], dtype=int) == 1
    solve_t = np.unique(t_all[solved])
    M = solve_t.size
    per = np.stack([num(j) for j in range(9, len(fixed) + len(cost_names))], axis=1)     # [rows, 3 + C]
    block = np.full((R, S, M, per.shape[1]), np.nan)
    m = np.searchsorted(solve_t, t_all[solved])
    block[run[solved], ship[solved], m] = per[solved]
    offsets = np.stack([block[..., 0], np.radians(block[..., 1])], axis=-1)
    return Trajectories(scenario=None, t=t, ship_names=names, states=states, solve_t=solve_t, offsets=offsets,
                        costs=block[..., 3:], cost_names=cost_names, solve_wall=block[..., 2])
