"""Write a simulation's results: ``metrics.json`` (summary + per-run metrics + provenance), ``summary.md``,
the figures of :mod:`psbmpc_jax.sim.plots` and, on request, every run's trajectories
(``trajectories.csv`` / ``trajectories.npz``, read back with :func:`load_trajectories`)."""

from __future__ import annotations

import csv
import datetime as _dt
import json
import math
import pathlib
from dataclasses import dataclass

import numpy as np

from ..provenance import commit, versions

SCHEMA = "psbmpc-sim/1"
#: Schema id of ``trajectories.npz`` (and of the column layout of ``trajectories.csv``).
TRAJECTORY_SCHEMA = "psbmpc-traj/1"
#: Significant digits of the measured numbers in ``metrics.json`` (the scenario's settings are written exactly).
METRICS_DIGITS = 6

__all__ = ["SCHEMA", "TRAJECTORY_SCHEMA", "METRICS_DIGITS", "Trajectories", "write_outputs", "write_index",
           "write_trajectories", "load_trajectories", "summary_markdown", "scenario_info", "provenance",
           "metrics_document", "colregs_evaluation", "evaluation_markdown"]


def round_sig(v: float, digits: int) -> float:
    """``v`` rounded to ``digits`` significant digits (finite floats only)."""
    return float(f"{v:.{digits}g}")


def _clean(obj, digits: int | None = None):
    """JSON-safe: NumPy scalars/arrays to Python, NaN/inf to None; floats rounded to ``digits`` significant
    digits when given."""
    if isinstance(obj, dict):
        return {str(k): _clean(v, digits) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v, digits) for v in obj]
    if isinstance(obj, np.ndarray):
        return _clean(obj.tolist(), digits)
    if isinstance(obj, (np.bool_, bool)):
        return bool(obj)
    if isinstance(obj, (np.integer, int)):
        return int(obj)
    if isinstance(obj, (np.floating, float)):
        if not math.isfinite(obj):
            return None
        return round_sig(float(obj), digits) if digits else float(obj)
    return obj


def scenario_info(sc) -> dict:
    """The settings a reader needs to reproduce the numbers (SI units)."""
    p = sc.mpc.params
    return {
        "name": sc.name, "description": sc.description, "source": sc.source,
        "duration_s": sc.duration, "dt_s": sc.dt, "runs": sc.runs, "seed": sc.seed,
        "collision_distance_m": sc.d_collision,
        "mpc": {"method": sc.mpc.method, "preset": sc.mpc.preset, "update_period_s": sc.mpc.period,
                "n_ps": sc.mpc.n_ps, "n_cbs": int(len(sc.mpc.behaviours)), "config": vars(sc.mpc.config).copy(),
                "params": p.as_dict(), **method_settings(sc)},
        "sensor": vars(sc.sensor).copy(),
        "chart": sc.chart_info,
        "ships": [{"name": s.name, "colav": s.colav, "length_m": s.length, "width_m": s.width,
                   "U_d_mps": s.U_d, "start_m": s.position, "course_deg": math.degrees(s.course),
                   "T_chi_s": s.T_chi, "T_U_s": s.T_U, "lookahead_m": s.lookahead, "R_a_m": s.R_a}
                  for s in sc.ships],
    }


def method_settings(sc) -> dict:
    """What every method in use records about itself (:meth:`psbmpc_jax.methods.Method.record`): the own-ship's
    at the top level (e.g. ``smooth``, ``fis``, ``solver``, ``refine``, ``sbmpc``), and every ship's method under
    ``methods`` (name -> its record; the PSB-MPC ``params`` and ``config`` above are shared by all)."""
    from ..methods.registry import get_method

    in_use = dict.fromkeys(s.colav for s in sc.ships if s.colav != "none")
    records = {name: get_method(name).record(sc) for name in in_use}
    own = sc.own_ship.colav
    return {**(records[own] if own != "none" else {}), "methods": records}


def colregs_evaluation(result) -> dict:
    """The COLREGS evaluation (:mod:`psbmpc_jax.evaltool`, Hagen et al. 2023 reconstructed) of every run of
    ``result``, with the scenario's ``evaluation`` parameters, own-ship against every target:
    ``{"params", "pairs", "aggregate", "runs"}`` -- ``aggregate`` per target and over all (counts by situation
    and status, count/mean/min/max of every score that applies), ``runs`` per run the encounters (target,
    situation, status, CPA time and range, the scores that apply)."""
    from ..evaltool import aggregate, evaluate_tracks, tracks_from_simulation

    params = result.scenario.evaluation
    evs = [evaluate_tracks(tr, params, pairs="own") for tr in tracks_from_simulation(result)]
    runs = [[{"other": e.other, "situation": e.situation, "status": e.status, "t_cpa_s": e.t_cpa,
              "r_cpa_m": e.r_cpa, "scores": {k: v for k, v in e.scores.to_dict().items() if v is not None}}
             for e in ev.encounters] for ev in evs]
    return {"params": params.as_dict(), "pairs": "own", "aggregate": aggregate(evs), "runs": runs}


#: Scores shown in the evaluation table of ``summary.md`` (all are in ``metrics.json``).
SUMMARY_SCORES = ("S_sit", "S_safety", "S_r", "S_theta")
#: Penalties listed when they apply (mean over the encounters where they do).
SUMMARY_PENALTIES = ("P_delay", "P_na_delta", "P_nsb", "P_sts", "P_ah13", "P_ah15", "P_2", "P_3", "P_pt")


def evaluation_markdown(ev: dict) -> list[str]:
    """The ``summary.md`` lines of :func:`colregs_evaluation`: one row per target."""
    agg = ev["aggregate"]
    lines = ["## COLREGS evaluation (EvalTool, Hagen et al. 2023 reconstructed; docs/evaltool.md)", "",
             f"Own-ship against each target, scores in [0, 1] (1 best), mean (min) over the encounters where they "
             f"apply; stages at {ev['params']['r_stage2_m']:g} / {ev['params']['r_stage3_m']:g} / "
             f"{ev['params']['r_stage4_m']:g} m, CPA ranges r_pref {ev['params']['r_pref_m']:g}, r_min "
             f"{ev['params']['r_min_m']:g}, r_nm {ev['params']['r_nm_m']:g}, r_col {ev['params']['r_col_m']:g} m "
             f"(the scenario's `evaluation` section).", "",
             "| target | encounters (situation: count) | status | " + " | ".join(SUMMARY_SCORES)
             + " | penalties (mean where applied) |",
             "|---|---|---|" + "---|" * len(SUMMARY_SCORES) + "---|"]

    def cell(st):
        return "—" if not st["n"] else f"{st['mean']:.2f} ({st['min']:.2f})"

    for pair in agg["pairs"]:
        sc = pair["scores"]
        pen = [f"{k} {sc[k]['mean']:.2f}" for k in SUMMARY_PENALTIES if sc[k]["n"] and sc[k]["mean"] > 0]
        sit = ", ".join(f"{k}: {v}" for k, v in pair["situations"].items())
        status = ", ".join(f"{k}: {v}" for k, v in pair["statuses"].items())
        lines.append(f"| {pair['other']} | {sit} | {status} | " + " | ".join(cell(sc[k]) for k in SUMMARY_SCORES)
                     + f" | {', '.join(pen) or '—'} |")
    if not agg["pairs"]:
        lines.append("| — | no encounter within r_Stage2 | | " + " | ".join("—" for _ in SUMMARY_SCORES) + " | |")
    return lines + [""]


def provenance() -> dict:
    return {"created_utc": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
            "commit": commit(), "versions": versions()}


def _fmt(v, nd=1):
    return "—" if v is None else (f"{v:.{nd}f}" if isinstance(v, float) else str(v))


def summary_markdown(result, evaluation: dict | None = None) -> str:
    """``summary.md``: the settings, the safety figures per target and the COLREGS evaluation
    (``evaluation``: :func:`colregs_evaluation` of ``result``, computed when not given)."""
    sc, s = result.scenario, result.summary
    m = sc.mpc
    from ..methods.registry import get_method

    details = get_method(m.method).describe(sc)
    how = f"own-ship method `{m.method}`" + (f" ({details})" if details else "")
    lines = [f"# {sc.name}: {s['runs']} closed-loop runs", "",
             sc.description or "", "",
             f"- {how}, MPC every {m.period:g} s, simulation {sc.duration:g} s at dt {sc.dt:g} s, seed {sc.seed}",
             f"- collision distance {sc.d_collision:g} m (centre to centre); grounding: own-ship centre closer "
             f"to land than half its width",
             f"- **own-ship collisions: {s['collisions']} of {s['runs']} runs; groundings: {s['groundings']}**; "
             f"runs where any pair of ships collided: {s['pair_collision_runs']}; runs where any ship grounded: "
             f"{s['any_ship_groundings']}",
             f"- device: {s['device']} ({s['platform']}), batch mode `{s['batch_mode']}`, "
             f"{s.get('mpc_solves_total', s.get('solves'))} solves in "
             f"{s['device_calls']} device calls ({s['mpc_updates']} MPC updates), median amortised solve time "
             f"{_fmt(None if s['solve_wall_s_amortised_median'] is None else 1e3 * s['solve_wall_s_amortised_median'])} ms",
             ""]
    if s.get("grid_region_exceeded"):
        lines += ["**Warning:** a ship left the region covered by the distance grid; grounding costs there "
                  "were computed as open water.", ""]
    if s.get("chart_clip_exceeded"):
        lines += ["**Warning:** a ship came so far from the routes that its predictions reached beyond the land "
                  "kept by `chart.clip_m`; raise `clip_m`.", ""]
    lines += ["| target | encounter | min distance [m] (min / median / max over runs) | collisions | COLREGS maneuver matched |",
              "|---|---|---|---|---|"]
    for tg in s["targets"]:                       # the aggregate over runs (sim.metrics.aggregate)
        d = tg["min_distance_m"]
        judged = tg["n_compliance_evaluated"]
        comp_txt = f"{tg['n_compliant']}/{judged}" if judged else "n/a"
        lines.append(f"| {tg['name']} | {', '.join(sorted(tg['encounters']))} | {d['min']:.1f} / {d['median']:.1f} / "
                     f"{d['max']:.1f} | {tg['collisions']} | {comp_txt} |")
    if sc.polygons:
        d = s["min_distance_land_m"]
        lines += ["", f"Minimum own-ship distance to land over runs: {d['min']:.1f} m (median {d['median']:.1f} m)."]
    lines += ["", f"Mean path deviation {s['path_deviation_mean_m']:.1f} m; mean absolute course rate "
                  f"{s['mean_abs_course_rate_deg_s']['mean']:.3f} deg/s.", ""]
    if "path_length_m" in s:
        def rng(key, nd=1):
            st = s[key]
            return "—" if st["n"] == 0 else f"{st['mean']:.{nd}f} (min {st['min']:.{nd}f}, max {st['max']:.{nd}f})"

        lines += [f"Voyage (start to the first time within R_a of the last waypoint; the whole run if never): "
                  f"{s.get('arrived_runs', 0)} of {s['runs']} runs arrived; voyage time {rng('voyage_time_s')} s, "
                  f"path length {rng('path_length_m')} m; course {_fmt(s['course_min_deg']['min'])}–"
                  f"{_fmt(s['course_max_deg']['max'])} deg, speed {_fmt(s['speed_min_mps']['min'], 2)}–"
                  f"{_fmt(s['speed_max_mps']['max'], 2)} m/s (extremes over runs).", ""]
    lines += evaluation_markdown(colregs_evaluation(result) if evaluation is None else evaluation)
    return "\n".join(lines)


def metrics_document(result, digits: int | None = METRICS_DIGITS, evaluation: dict | None = None) -> dict:
    """The content of ``metrics.json`` (JSON-safe): schema, the scenario's settings (exact), the summary, the
    per-run metrics, the per-update device calls, the COLREGS evaluation (:func:`colregs_evaluation`, computed
    when ``evaluation`` is not given; floats rounded to ``digits`` significant digits), and provenance.  The
    summary has one count of solves, ``mpc_solves_total``; each run has its own-ship's ``solve_times_s``."""
    summary = {k: v for k, v in result.summary.items() if k != "solves"}   # "solves": older in-memory name
    evaluation = colregs_evaluation(result) if evaluation is None else evaluation
    doc = {"schema": SCHEMA, "scenario": _clean(scenario_info(result.scenario)),
           "summary": _clean(summary, digits), "runs": _clean(result.metrics, digits),
           "device_calls": _clean(result.calls, digits), "colregs_evaluation": _clean(evaluation, digits)}
    doc.update(provenance())
    return doc


def write_outputs(result, out_dir, *, figures: bool = True, plot_runs=None, animate: bool = False,
                  trajectories: bool = False) -> dict:
    """Write ``metrics.json`` and ``summary.md``; unless ``figures=False`` the PNG figures of
    :func:`psbmpc_jax.sim.plots.write_figures` for the runs ``plot_runs`` (default: run 0); with
    ``animate=True`` an animation of each of those runs (GIF, and MP4 when ffmpeg is installed); with
    ``trajectories=True`` every run's trajectories as ``trajectories.csv`` and ``trajectories.npz``.
    Returns ``{name: path}``."""
    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    evaluation = colregs_evaluation(result)
    (out / "metrics.json").write_text(json.dumps(metrics_document(result, evaluation=evaluation), indent=1) + "\n")
    (out / "summary.md").write_text(summary_markdown(result, evaluation))
    paths = {"metrics": out / "metrics.json", "summary": out / "summary.md"}
    if trajectories:
        for p in write_trajectories(result, out):
            paths[p.name] = p
    if figures:
        from .plots import write_figures

        for p in write_figures(result, out, runs=plot_runs):
            paths[p.stem] = p
    if animate:
        from .plots import animate_run

        runs = [0] if plot_runs is None else list(plot_runs)
        for r in runs:
            stem = "animation" if plot_runs is None else f"animation_run{r}"
            for p in animate_run(result, r, out / f"{stem}.gif"):
                paths[p.name] = p
    return paths


# ------------------------------------------------------------------------------------------- trajectories
def _cost_names(result) -> tuple:
    from .simulator import COST_NAMES

    return tuple(COST_NAMES)[: result.best_costs.shape[-1]]


def _csv_columns(cost_names) -> list[str]:
    return (["run", "ship", "ship_name", "t_s", "north_m", "east_m", "course_deg", "speed_mps", "solve",
             "speed_factor", "course_offset_deg", "solve_wall_s"] + [f"cost_{n}" for n in cost_names])


#: Significant digits of the floats in trajectories.csv (the NPZ file keeps every bit).
CSV_DIGITS = 12


def _fmt_col(values) -> list[str]:
    """Each float with CSV_DIGITS significant digits; empty for NaN (no solve at that row)."""
    return ["" if v != v else format(v, f".{CSV_DIGITS}g") for v in np.asarray(values, dtype=float).tolist()]


def write_trajectories(result, out_dir, formats=("csv", "npz")) -> list[pathlib.Path]:
    """Write every run's trajectories into ``out_dir``: ``trajectories.csv`` and/or ``trajectories.npz``.

    CSV (one row per run, ship and time step, run-major): ``run, ship, ship_name, t_s, north_m, east_m,
    course_deg, speed_mps`` (the true states; course in degrees from north, clockwise; 12 significant
    digits), then per solve --
    filled on the rows of the steps at which that ship solved, empty elsewhere -- ``solve`` (1 or 0),
    ``speed_factor``, ``course_offset_deg`` (the chosen first maneuver, applied until the next solve),
    ``solve_wall_s`` and ``cost_<term>`` (``cost_total``, ``cost_do``, ``cost_colregs``, ``cost_so``,
    ``cost_path``: the chosen behaviour's cost terms).

    NPZ: the arrays of :class:`Trajectories` under the same names (course and offsets in radians), plus
    ``schema`` = :data:`TRAJECTORY_SCHEMA`.  Read either with :func:`load_trajectories`.
    """
    formats = tuple(formats)
    bad = [f for f in formats if f not in ("csv", "npz")]
    if bad or not formats:
        raise ValueError(f"formats must be a non-empty subset of ('csv', 'npz'), got {formats!r}")
    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    tr = Trajectories.from_result(result)
    paths = []
    if "npz" in formats:
        path = out / "trajectories.npz"
        np.savez_compressed(path, schema=np.array(TRAJECTORY_SCHEMA), scenario=np.array(tr.scenario or ""),
                            t=tr.t, ship_names=np.array(tr.ship_names), states=tr.states, solve_t=tr.solve_t,
                            offsets=tr.offsets, costs=tr.costs, cost_names=np.array(tr.cost_names),
                            solve_wall=tr.solve_wall)
        paths.append(path)
    if "csv" in formats:
        path = out / "trajectories.csv"
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
        with open(path, "w", newline="", encoding="utf-8") as fh:
            w = csv.writer(fh)
            w.writerow(_csv_columns(tr.cost_names))
            w.writerows(zip(*cols))
        paths.append(path)
    return paths


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

    @classmethod
    def from_result(cls, result) -> "Trajectories":
        """The trajectories of a :class:`~psbmpc_jax.sim.SimulationResult`."""
        wall = result.solve_wall
        if wall is None:
            wall = np.full(result.offsets.shape[:-1], np.nan)
        return cls(scenario=result.scenario.name, t=np.asarray(result.t, float),
                   ship_names=[s.name for s in result.scenario.ships], states=np.asarray(result.states, float),
                   solve_t=np.asarray(result.solve_t, float), offsets=np.asarray(result.offsets, float),
                   costs=np.asarray(result.best_costs, float), cost_names=_cost_names(result),
                   solve_wall=np.asarray(wall, float))

    @property
    def runs(self) -> int:
        return int(self.states.shape[0])


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
        ValueError: a file that is not a trajectory export (the message says what is expected).
    """
    p = pathlib.Path(path)
    if p.is_dir():
        for name in ("trajectories.npz", "trajectories.csv"):
            if (p / name).is_file():
                p = p / name
                break
        else:
            raise FileNotFoundError(f"{p}: no trajectories.npz or trajectories.csv (write them with "
                                    f"psbmpc-jax run --save-trajectories)")
    if not p.is_file():
        raise FileNotFoundError(f"trajectory file not found: {p}")
    if p.suffix == ".npz":
        return _load_npz(p)
    if p.suffix == ".csv":
        return _load_csv(p)
    raise ValueError(f"{p}: expected a trajectories .npz or .csv file written by psbmpc-jax run "
                     f"--save-trajectories")


def _load_npz(p: pathlib.Path) -> Trajectories:
    with np.load(p, allow_pickle=False) as z:
        schema = str(z["schema"]) if "schema" in z.files else None
        if schema != TRAJECTORY_SCHEMA:
            raise ValueError(f"{p}: not a {TRAJECTORY_SCHEMA} trajectory file (schema {schema!r}); expected the "
                             f"trajectories.npz of psbmpc-jax run --save-trajectories")
        return Trajectories(scenario=str(z["scenario"]) or None, t=z["t"], ship_names=[str(s) for s in z["ship_names"]],
                            states=z["states"], solve_t=z["solve_t"], offsets=z["offsets"], costs=z["costs"],
                            cost_names=tuple(str(s) for s in z["cost_names"]), solve_wall=z["solve_wall"])


def _load_csv(p: pathlib.Path) -> Trajectories:
    with open(p, newline="", encoding="utf-8") as fh:
        reader = csv.reader(fh)
        header = next(reader, None)
        fixed = _csv_columns(())
        if header is None or header[: len(fixed)] != fixed or not all(h.startswith("cost_") for h in header[len(fixed):]):
            raise ValueError(f"{p}: not a {TRAJECTORY_SCHEMA} trajectory CSV; expected the header "
                             f"{','.join(fixed)},cost_<term>... of psbmpc-jax run --save-trajectories")
        rows = list(reader)
    cost_names = tuple(h[len("cost_"):] for h in header[len(fixed):])
    if not rows:
        raise ValueError(f"{p}: the trajectory CSV has no rows")
    cols = list(zip(*rows))

    def num(j):
        return np.array([float(v) if v != "" else np.nan for v in cols[j]])

    run, ship = np.array(cols[0], dtype=int), np.array(cols[1], dtype=int)
    t_all = num(3)
    R, S = int(run.max()) + 1, int(ship.max()) + 1
    t = np.unique(t_all)
    K1 = t.size
    if len(rows) != R * S * K1:
        raise ValueError(f"{p}: expected {R} runs x {S} ships x {K1} steps = {R * S * K1} rows, got {len(rows)}")
    step = np.searchsorted(t, t_all)
    states = np.full((R, S, K1, 4), np.nan)
    states[run, ship, step] = np.stack([num(4), num(5), np.radians(num(6)), num(7)], axis=1)
    names = [""] * S
    for s_idx, name in zip(ship.tolist(), cols[2]):
        names[s_idx] = name
    solved = np.array(cols[8], dtype=int) == 1
    solve_t = np.unique(t_all[solved])
    M = solve_t.size
    per = np.stack([num(j) for j in range(9, len(header))], axis=1)            # [rows, 3 + C]
    block = np.full((R, S, M, per.shape[1]), np.nan)
    m = np.searchsorted(solve_t, t_all[solved])
    block[run[solved], ship[solved], m] = per[solved]
    offsets = np.stack([block[..., 0], np.radians(block[..., 1])], axis=-1)
    return Trajectories(scenario=None, t=t, ship_names=names, states=states, solve_t=solve_t, offsets=offsets,
                        costs=block[..., 3:], cost_names=cost_names, solve_wall=block[..., 2])


def write_index(out_dir) -> pathlib.Path:
    """``index.md`` over every ``*/metrics.json`` under ``out_dir``: one row per scenario with its method, runs,
    collisions, groundings, the closest approach to any target and to land, COLREGS compliance and the
    median amortised solve time."""
    out = pathlib.Path(out_dir)
    rows = []
    for path in sorted(out.glob("*/metrics.json")):
        doc = json.loads(path.read_text())
        s = doc["summary"]
        tmin = [t["min_distance_m"]["min"] for t in s["targets"] if t["min_distance_m"]["min"] is not None]
        land = s["min_distance_land_m"]["min"]
        n_ok, n_eval = s.get("n_compliant", 0), s.get("n_compliance_evaluated", 0)
        solve = s.get("solve_wall_s_amortised_median")
        rows.append(
            f"| [{s['scenario']}]({path.parent.name}/summary.md) | {s.get('method') or 'none'} | {s['runs']} | "
            f"{len(s['targets'])} | "
            f"{s['collisions']} | {s['groundings']} | {s['pair_collision_runs']} | "
            + (f"{min(tmin):.1f}" if tmin else "—") + " | " + ("—" if land is None else f"{land:.1f}") + " | "
            + (f"{n_ok}/{n_eval}" if n_eval else "n/a") + " | "
            + ("—" if solve is None else f"{1e3 * solve:.1f}") + f" | {doc.get('commit', '?')[:9]} |")
    text = "\n".join([
        "# Closed-loop results", "",
        "Written by `psbmpc-jax run` (one folder per scenario: metrics.json, summary.md, figures). Collisions: "
        "own-ship runs with a centre distance below the collision distance; pair collisions: runs in which two "
        "ships of which one runs PSB-MPC collided; COLREGS: runs × targets whose encounter the own-ship's "
        "manoeuvre matched, of those with an obligation (see docs/simulation.md).", "",
        "| scenario | method | runs | targets | collisions | groundings | pair collisions | closest approach [m] | "
        "closest to land [m] | COLREGS matched | solve [ms] | commit |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|", *rows, ""])
    (out / "index.md").write_text(text)
    return out / "index.md"
