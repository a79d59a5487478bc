"""Write a simulation's results: ``metrics.json`` (summary + per-run metrics + provenance), ``summary.md``
and the figures of :mod:`psbmpc_jax.sim.plots`."""

from __future__ import annotations

import datetime as _dt
import json
import math
import pathlib

import numpy as np

from ..provenance import commit, versions

SCHEMA = "psbmpc-sim/1"


def _clean(obj):
    """JSON-safe: NumPy scalars/arrays to Python, NaN/inf to None."""
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _clean(obj.tolist())
    if isinstance(obj, (np.bool_, bool)):
        return bool(obj)
    if isinstance(obj, (np.integer, int)):
        return int(obj)
    if isinstance(obj, (np.floating, float)):
        return float(obj) if math.isfinite(obj) else None
    return obj


def scenario_info(sc) -> dict:
    """The settings a reader needs to reproduce the numbers (SI units)."""
    p = sc.mpc.params
    return {
        "name": sc.name, "description": sc.description, "source": sc.source,
        "duration_s": sc.duration, "dt_s": sc.dt, "runs": sc.runs, "seed": sc.seed,
        "collision_distance_m": sc.d_collision,
        "mpc": {"preset": sc.mpc.preset, "update_period_s": sc.mpc.period, "n_ps": sc.mpc.n_ps,
                "n_cbs": int(len(sc.mpc.behaviours)), "config": vars(sc.mpc.config).copy(),
                "params": p.as_dict()},
        "sensor": vars(sc.sensor).copy(),
        "chart": sc.chart_info,
        "ships": [{"name": s.name, "colav": s.colav, "length_m": s.length, "width_m": s.width,
                   "U_d_mps": s.U_d, "start_m": s.position, "course_deg": math.degrees(s.course)}
                  for s in sc.ships],
    }


def provenance() -> dict:
    return {"created_utc": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
            "commit": commit(), "versions": versions()}


def _fmt(v, nd=1):
    return "—" if v is None else (f"{v:.{nd}f}" if isinstance(v, float) else str(v))


def summary_markdown(result) -> str:
    sc, s = result.scenario, result.summary
    lines = [f"# {sc.name}: {s['runs']} closed-loop runs", "",
             sc.description or "", "",
             f"- preset `{sc.mpc.preset}`, {len(sc.mpc.behaviours)} behaviours, n_ps {sc.mpc.n_ps}, MPC every "
             f"{sc.mpc.period:g} s, simulation {sc.duration:g} s at dt {sc.dt:g} s, seed {sc.seed}",
             f"- collision distance {sc.d_collision:g} m (centre to centre); grounding: own-ship centre closer "
             f"to land than half its width",
             f"- **own-ship collisions: {s['collisions']} of {s['runs']} runs; groundings: {s['groundings']}**; "
             f"runs where any pair of ships collided: {s['pair_collision_runs']}; runs where any ship grounded: "
             f"{s['any_ship_groundings']}",
             f"- device: {s['device']} ({s['platform']}), batch mode `{s['batch_mode']}`, {s['solves']} solves in "
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
    return "\n".join(lines)


def write_outputs(result, out_dir, *, figures: bool = True) -> dict:
    """Write ``metrics.json``, ``summary.md`` and (unless ``figures=False``) the PNG figures."""
    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    doc = {"schema": SCHEMA, "scenario": scenario_info(result.scenario), "summary": result.summary,
           "runs": result.metrics, "device_calls": result.calls, **provenance()}
    (out / "metrics.json").write_text(json.dumps(_clean(doc), indent=1) + "\n")
    (out / "summary.md").write_text(summary_markdown(result))
    paths = {"metrics": out / "metrics.json", "summary": out / "summary.md"}
    if figures:
        from .plots import write_figures

        for p in write_figures(result, out):
            paths[p.stem] = p
    return paths


def write_index(out_dir) -> pathlib.Path:
    """``index.md`` over every ``*/metrics.json`` under ``out_dir``: one row per scenario with its runs,
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
            f"| [{s['scenario']}]({path.parent.name}/summary.md) | {s['runs']} | {len(s['targets'])} | "
            f"{s['collisions']} | {s['groundings']} | {s['pair_collision_runs']} | "
            f"{min(tmin):.1f} | " + ("—" if land is None else f"{land:.1f}") + " | "
            + (f"{n_ok}/{n_eval}" if n_eval else "n/a") + " | "
            + ("—" if solve is None else f"{1e3 * solve:.1f}") + f" | {doc.get('commit', '?')[:9]} |")
    text = "\n".join([
        "# Closed-loop results", "",
        "Written by `psbmpc-jax run` (one folder per scenario: metrics.json, summary.md, figures). Collisions: "
        "own-ship runs with a centre distance below the collision distance; pair collisions: runs in which two "
        "ships of which one runs PSB-MPC collided; COLREGS: runs × targets whose encounter the own-ship's "
        "manoeuvre matched, of those with an obligation (see docs/simulation.md).", "",
        "| scenario | runs | targets | collisions | groundings | pair collisions | closest approach [m] | "
        "closest to land [m] | COLREGS matched | solve [ms] | commit |",
        "|---|---|---|---|---|---|---|---|---|---|---|", *rows, ""])
    (out / "index.md").write_text(text)
    return out / "index.md"
