"""Write a simulation's results into a run folder: ``metrics.json`` (summary + per-run metrics + provenance),
``summary.md``, the figures of :mod:`psbmpc_jax.sim.plots`, on request every run's trajectories
(``trajectories.csv`` / ``trajectories.npz``, read back with :func:`load_trajectories`), and ``manifest.json``
last (:mod:`psbmpc_jax.runfolder`: run id, files with sizes and hashes, completeness).  Every file is
written atomically; a folder that holds another run is replaced only with ``force`` and then exactly that
run's files go."""

from __future__ import annotations

import datetime as _dt
import json
import logging
import math
import pathlib

import numpy as np

from ..provenance import commit, versions
from ..safe_io import atomic_write_text, read_json_document
from ..runfolder import MANIFEST, RunFolderError, RunWriter, verify_member
from .trajectories import (CSV_DIGITS, TRAJECTORY_SCHEMA, Trajectories, load_trajectories, write_trajectories,
                           write_trajectory_files)

SCHEMA = "psbmpc-sim/1"
#: Significant digits of the measured numbers in ``metrics.json`` (the scenario's settings are written exactly).
METRICS_DIGITS = 6

__all__ = ["SCHEMA", "TRAJECTORY_SCHEMA", "METRICS_DIGITS", "CSV_DIGITS", "Trajectories", "write_outputs",
           "write_index", "write_trajectories", "load_trajectories", "summary_markdown", "scenario_info",
           "provenance", "metrics_document", "colregs_evaluation", "evaluation_markdown", "stops_markdown"]

log = logging.getLogger(__name__)


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
    """The settings a reader needs to reproduce the numbers (SI units); ``overrides``: the file's settings its
    loader replaced (a campaign's ``duration_s``: ``Scenario.overrides``); a ship's resolved COLREGS option is in
    its entry of ``ships`` when the option is on for some ship (docs/colregs_option.md), its resolved stop remedy
    when a remedy is in use (docs/methods/psbmpc.md)."""
    from ..methods.builtin import ship_option_record

    p = sc.mpc.params
    return {
        "name": sc.name, "description": sc.description, "source": sc.source,
        "duration_s": sc.duration, "dt_s": sc.dt, "runs": sc.runs, "seed": sc.seed, "overrides": sc.overrides,
        "collision_distance_m": sc.d_collision,
        "mpc": {"method": sc.mpc.method, "preset": sc.mpc.preset, "update_period_s": sc.mpc.period,
                "n_ps": sc.mpc.n_ps, "n_cbs": int(len(sc.mpc.behaviours)), "config": vars(sc.mpc.config).copy(),
                "params": p.as_dict(), **method_settings(sc)},
        "sensor": vars(sc.sensor).copy(),
        "evaluation": sc.evaluation.as_dict(),
        "chart": sc.chart_info,
        "ships": [{"name": s.name, "colav": s.colav, "length_m": s.length, "width_m": s.width,
                   "U_d_mps": s.U_d, "start_m": s.position, "course_deg": math.degrees(s.course),
                   "T_chi_s": s.T_chi, "T_U_s": s.T_U, "lookahead_m": s.lookahead, "R_a_m": s.R_a,
                   **ship_option_record(sc, i)}
                  for i, s in enumerate(sc.ships)],
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
    """The ``summary.md`` lines of :func:`colregs_evaluation`: one row per target (or the error that stopped
    the evaluation)."""
    head = "## COLREGS evaluation (EvalTool, Hagen et al. 2023 reconstructed; docs/evaltool.md)"
    if "error" in ev:
        return [head, "", f"**The evaluation failed:** {ev['error']}. The simulation's results above and in "
                          f"metrics.json are complete; score the trajectories later with psbmpc-jax evaluate.", ""]
    agg = ev["aggregate"]
    lines = [head, "",
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


def _own_stops_line(s: dict) -> str:
    own = (s.get("ships") or [None])[0]
    if own is None:
        return f"- own-ship arrived in {s.get('arrived_runs', 0)} of {s['runs']} runs"
    ls = own["longest_stop"]
    longest = "" if ls is None else f", longest {ls['s']:.1f} s (run {ls['run']}, from t = {ls['start_s']:.1f} s)"
    arrived = "n/a" if own["arrived_runs"] is None else f"{own['arrived_runs']} of {own['runs']} runs"
    return (f"- **own-ship stops: {own['stops_total']} in {own['runs_with_stops']} of {own['runs']} runs{longest}; "
            f"arrived at its last waypoint: {arrived}**")


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
             _own_stops_line(s),
             f"- device: {s['device']} ({s['platform']}), batch mode `{s['batch_mode']}`, "
             + (f"runs split over {s['devices']} devices, " if s.get("devices", 1) > 1 else "")
             + f"{s.get('mpc_solves_total', s.get('solves'))} solves in "
             f"{s['device_calls']} device calls ({s['mpc_updates']} MPC updates), median amortised solve time "
             f"{_fmt(None if s['solve_wall_s_amortised_median'] is None else 1e3 * s['solve_wall_s_amortised_median'])} ms",
             ""]
    if s.get("grid_region_exceeded"):
        lines += ["**Warning:** a ship left the region covered by the distance grid; grounding costs there "
                  "were computed as open water.", ""]
    if s.get("chart_clip_exceeded"):
        lines += ["**Warning:** a ship came so far from the routes that its predictions reached beyond the land "
                  "kept by `chart.clip_m`; raise `clip_m`.", ""]
    lines += ["| target | situation (EvalTool; first encounter, runs) | min distance [m] (min / median / max over "
              "runs) | collisions | simple manoeuvre check passed |",
              "|---|---|---|---|---|"]
    for tg in s["targets"]:                       # the aggregate over runs (sim.metrics.aggregate)
        d = tg["min_distance_m"]
        judged = tg["n_compliance_evaluated"]
        comp_txt = f"{tg['n_compliant']}/{judged}" if judged else "n/a"
        sits = tg.get("situations") or tg["encounters"]
        lines.append(f"| {tg['name']} | {', '.join(f'{k}: {v}' for k, v in sorted(sits.items()))} | {d['min']:.1f} / "
                     f"{d['median']:.1f} / {d['max']:.1f} | {tg['collisions']} | {comp_txt} |")
    lines += ["", "Situations as the COLREGS evaluation below classifies them (HO head-on, CRGW / CRSO crossing "
                  "give-way / stand-on, OTGW overtaking, OTSO overtaken, NAR no applicable rule; none: never within "
                  "its r_Stage2). The simple check judges the own-ship's first course alteration and passing "
                  "against that situation (docs/simulation.md)."]
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
    lines += stops_markdown(s, sc)
    lines += evaluation_markdown(colregs_evaluation(result) if evaluation is None else evaluation)
    return "\n".join(lines)


def stops_markdown(s: dict, sc) -> list[str]:
    """The stops-and-arrival lines of ``summary.md`` from the summary's ``ships`` (every ship)."""
    from .stops import STOP_MIN_DURATION_S, STOP_SPEED_MPS

    ships = s.get("ships")
    if not ships:
        return []
    lines = ["## Stops and arrival", "",
             f"A stop: speed over ground at or below {STOP_SPEED_MPS:g} m/s for at least {STOP_MIN_DURATION_S:g} s; "
             f"arrival: the first time within the ship's acceptance radius R_a of its last waypoint.", "",
             "| ship | runs with a stop | stops | longest stop [s] (run, start) | arrived | arrival time [s] "
             "(min / median / max) |", "|---|---|---|---|---|---|"]
    for sh in ships:
        ls = sh["longest_stop"]
        longest = "—" if ls is None else f"{ls['s']:.1f} (run {ls['run']}, from t = {ls['start_s']:.1f} s)"
        arr = sh["arrival_time_s"]
        arrived = "n/a" if sh["arrived_runs"] is None else f"{sh['arrived_runs']} of {sh['runs']}"
        at = "—" if not arr["n"] else f"{arr['min']:.1f} / {arr['median']:.1f} / {arr['max']:.1f}"
        lines.append(f"| {sh['name']} | {sh['runs_with_stops']} of {sh['runs']} | {sh['stops_total']} | {longest} | "
                     f"{arrived} | {at} |")
    return lines + [""]


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


def safe_colregs_evaluation(result) -> dict:
    """:func:`colregs_evaluation`, or ``{"error", "params"}`` when the evaluation fails: a scoring failure
    never costs the simulation's results (they are written with the error stated)."""
    try:
        return colregs_evaluation(result)
    except (ValueError, MemoryError, FloatingPointError) as exc:
        log.warning("the COLREGS evaluation of %s failed: %s", result.scenario.name, exc)
        return {"error": f"{type(exc).__name__}: {exc}", "params": result.scenario.evaluation.as_dict()}


def write_outputs(result, out_dir, *, figures: bool = True, plot_runs=None, animate: bool = False,
                  trajectories: bool = False, force: bool = False) -> dict:
    """Write the run folder ``out_dir``: ``metrics.json`` and ``summary.md``; unless ``figures=False`` the PNG
    figures of :func:`psbmpc_jax.sim.plots.write_figures` for the runs ``plot_runs`` (default: run 0); with
    ``animate=True`` an animation of each of those runs (GIF, and MP4 when ffmpeg is installed); with
    ``trajectories=True`` every run's trajectories as ``trajectories.csv`` and ``trajectories.npz``; and
    ``manifest.json`` last (:mod:`psbmpc_jax.runfolder`).

    Every file is staged first and moved in at the end, so a failure or a kill while the results are produced
    leaves the folder as it was.  A folder that holds another run is refused unless ``force``; then exactly the
    files of that run are replaced (files of no run are never touched).

    Returns ``{name: path}`` (``metrics``, ``summary``, ``manifest``, and each other file by its name or stem).

    Raises:
        OutputError: the folder cannot be written, or holds another run and ``force`` is False.
    """
    writer = RunWriter(out_dir, force=force, meta={"scenario": result.scenario.name})
    try:
        keys = {}
        if trajectories:       # the simulation's data first
            tr = Trajectories.from_result(result)
            written = write_trajectory_files(tr, {f: writer.path(f"trajectories.{f}") for f in ("csv", "npz")},
                                             run_id=writer.run_id)
            keys.update({p.name: p.name for p in written})
        evaluation = safe_colregs_evaluation(result)
        doc = metrics_document(result, evaluation=evaluation)
        doc["run_id"] = writer.run_id
        atomic_write_text(writer.path("metrics.json"), json.dumps(doc, indent=1) + "\n")
        atomic_write_text(writer.path("summary.md"), summary_markdown(result, evaluation))
        keys.update(metrics="metrics.json", summary="summary.md")
        if figures:
            from .plots import write_figures

            made = write_figures(result, writer.staging, runs=plot_runs)
            writer.adopt(made)
            keys.update({p.stem: p.name for p in made})
        if animate:
            from .plots import animate_run

            runs = [0] if plot_runs is None else list(plot_runs)
            for r in runs:
                stem = "animation" if plot_runs is None else f"animation_run{r}"
                made = animate_run(result, r, writer.staging / f"{stem}.gif")
                writer.adopt(made)
                keys.update({p.name: p.name for p in made})
        final = writer.commit()
    except BaseException:
        writer.abort()
        raise
    paths = {key: final[name] for key, name in keys.items()}
    paths["manifest"] = writer.folder / MANIFEST
    return paths


def write_index(out_dir) -> pathlib.Path:
    """``index.md`` over every run folder ``*/`` under ``out_dir`` whose run completed and whose metrics.json is
    the one its manifest lists: one row per scenario with its method, runs, collisions, groundings, the closest
    approach to any target and to land, COLREGS compliance, the median amortised solve time, the run id and
    the commit.  Folders that fail the check are named below the table with the reason.  Written atomically."""
    out = pathlib.Path(out_dir)
    rows, skipped = [], []
    for path in sorted(out.glob("*/metrics.json")):
        try:
            manifest = verify_member(path, require_manifest=True)
            assert manifest is not None          # require_manifest: a member of a run folder or an error
            doc = read_json_document(path, what="metrics file", schema=SCHEMA, error=RunFolderError)
        except RunFolderError as exc:
            skipped.append(f"- `{path.parent.name}/`: {exc}")
            continue
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
            + ("—" if solve is None else f"{1e3 * solve:.1f}") + f" | {manifest['run_id'][:8]} | "
            f"{doc.get('commit', '?')[:9]} |")
    lines = [
        "# Closed-loop results", "",
        "Written by `psbmpc-jax run` (one run folder per scenario: metrics.json, summary.md, figures, "
        "manifest.json). Collisions: own-ship runs with a centre distance below the collision distance; pair "
        "collisions: runs in which two ships of which one runs PSB-MPC collided; COLREGS: runs × targets whose "
        "first encounter passed the simple manoeuvre check, of those with an obligation (see docs/simulation.md).",
        "",
        "| scenario | method | runs | targets | collisions | groundings | pair collisions | closest approach [m] | "
        "closest to land [m] | COLREGS matched | solve [ms] | run | commit |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|", *rows, ""]
    if skipped:
        lines += ["Not listed (their results cannot be trusted as they are):", "", *skipped, ""]
    return atomic_write_text(out / "index.md", "\n".join(lines))
