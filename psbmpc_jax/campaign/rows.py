"""Tidy rows of a simulation: one row per run x ship, every per-run metric of :func:`psbmpc_jax.sim.simulate` and
every COLREGS score of the evaluation tool as columns, plus the settings that tell rows apart.

Column groups (docs/campaigns.md lists them all):

- keys and settings: ``campaign``, ``scenario``, ``method``, ``seed``, ``run``, ``ship``, ``ship_index``,
  ``own_ship``, ``task_id``, ``scenario_sha256``, ``duration_s``, ``dt_s``, ``mpc_period_s``, ``batch_mode``,
  ``n_ships``, ``package_version``, ``commit``, ``platform``, ``device``;
- ``ship_*``: the row's ship (its collision avoidance, stops, arrival, distance to land, grounding, closest
  approach to any other ship, whether it was in a pair collision that counts);
- ``run_*``: the own-ship's per-run metrics (collision, grounding, path deviation, solve times, voyage, ...),
  repeated on every ship row of the run (count runs on the ``own_ship`` rows);
- ``target_*`` (target rows only): the own-ship's metrics against this target (closest approach, collision,
  encounter type, the simple manoeuvre check);
- ``colregs_*`` (target rows only): the evaluation tool's first encounter of the own-ship with this target
  (situation, status, CPA) and every score and penalty (``colregs_S_sit``, ``colregs_P_delay``, ...; null
  where it does not apply), and the number of encounters.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["KEY_COLUMNS", "EXECUTION_COLUMNS", "simulation_rows", "rows_frame", "comparable", "trajectory_frame"]

#: The columns that identify a row: one row per scenario x method x seed x run x ship.
KEY_COLUMNS = ("scenario", "method", "seed", "run", "ship")
#: Integer columns (never null).
_INT = {"seed", "run", "ship_index", "n_ships"}
#: Boolean columns (nullable: null where a metric does not apply).
_BOOL = {"own_ship", "ship_arrived", "ship_grounded", "ship_pair_collision", "run_collision", "run_grounding",
         "run_arrived", "target_collision", "target_compliant", "target_compliance_compliant",
         "target_compliance_passed_astern"}
#: Text columns.
_STR = {"campaign", "scenario", "method", "ship", "task_id", "scenario_sha256", "batch_mode", "package_version",
        "commit", "platform", "device", "ship_colav", "target_encounter", "target_situation",
        "target_compliance_encounter", "target_compliance_passing_side", "target_compliance_first_alteration",
        "target_compliance_reason", "colregs_situation", "colregs_status"}


def _scalar(v):
    if isinstance(v, (np.bool_, bool)):
        return bool(v)
    if isinstance(v, (np.integer, int)):
        return int(v)
    if isinstance(v, (np.floating, float)):
        return float(v)
    return v


def _run_columns(m: dict) -> dict:
    """The own-ship's scalar per-run metrics as ``run_*`` (lists: their length, as ``run_<name>_count``)."""
    out = {}
    for k, v in m.items():
        if k in ("run", "targets", "ships", "solve_times_s", "pair_min_distance_m", "ships_min_distance_land_m",
                 "ships_grounded"):
            continue
        if isinstance(v, dict):
            continue
        if isinstance(v, (list, tuple)):
            out[f"run_{k}_count"] = len(v)
        else:
            out[f"run_{k}"] = _scalar(v)
    return out


def _target_columns(t: dict | None) -> dict:
    if t is None:
        return {}
    out = {f"target_{k}": _scalar(v) for k, v in t.items() if k not in ("name", "compliance")
           and not isinstance(v, (dict, list))}
    comp = t.get("compliance") or {}
    out.update({f"target_compliance_{k}": _scalar(v) for k, v in comp.items()
                if not isinstance(v, (dict, list))})
    return out


def _colregs_columns(encounters: list) -> dict:
    from ..evaltool.results import SCORE_NAMES

    out: dict[str, Any] = {"colregs_encounters": len(encounters)}
    first = encounters[0] if encounters else {}
    out.update(colregs_situation=first.get("situation"), colregs_status=first.get("status"),
               colregs_t_cpa_s=first.get("t_cpa_s"), colregs_r_cpa_m=first.get("r_cpa_m"))
    scores = first.get("scores") or {}
    out.update({f"colregs_{k}": scores.get(k) for k in SCORE_NAMES})
    return out


def simulation_rows(result, evaluation: dict, settings: dict) -> list[dict]:
    """The tidy rows of ``result`` (a :class:`~psbmpc_jax.sim.SimulationResult`): one per run x ship, in run
    then ship order.  ``evaluation``: :func:`psbmpc_jax.sim.output.colregs_evaluation` of ``result`` (or its
    ``{"error"}`` form: the ``colregs_*`` columns are then null and ``colregs_error`` says why); ``settings``:
    the key and settings columns common to all rows (campaign, method, seed, task id, ...)."""
    sc = result.scenario
    ships = sc.ships
    names = [s.name for s in ships]
    ev_runs = evaluation.get("runs") if "error" not in evaluation else None
    s = result.summary
    common = {**settings, "scenario": sc.name, "duration_s": float(sc.duration), "dt_s": float(sc.dt),
              "mpc_period_s": float(sc.mpc.period), "batch_mode": s.get("batch_mode"), "n_ships": len(ships),
              "platform": s.get("platform"), "device": s.get("device")}
    rows = []
    for i_run, m in enumerate(result.metrics):
        run_cols = _run_columns(m)
        per_ship = {sh["name"]: sh for sh in (m.get("ships") or [])}
        targets = {t["name"]: t for t in m.get("targets", [])}
        land = m.get("ships_min_distance_land_m") or {}
        grounded = set(m.get("ships_grounded") or [])
        pairs = m.get("pair_min_distance_m") or {}
        bad_pairs = set(m.get("pair_collisions") or [])
        encounters = ev_runs[i_run] if ev_runs is not None else None
        for i, name in enumerate(names):
            sh = per_ship.get(name, {})
            mine = [f"{names[min(i, j)]}-{names[max(i, j)]}" for j in range(len(names)) if j != i]   # its pairs
            row = {**common, "run": int(m["run"]), "ship": name, "ship_index": i, "own_ship": i == 0,
                   "ship_colav": ships[i].colav,
                   "ship_stops": sh.get("stops"), "ship_longest_stop_s": sh.get("longest_stop_s"),
                   "ship_longest_stop_start_s": sh.get("longest_stop_start_s"),
                   "ship_stopped_time_s": sh.get("stopped_time_s"), "ship_arrived": sh.get("arrived"),
                   "ship_arrival_time_s": sh.get("arrival_time_s"),
                   "ship_min_distance_land_m": land.get(name), "ship_grounded": name in grounded,
                   "ship_min_distance_any_ship_m": min((pairs[k] for k in mine if k in pairs), default=None),
                   "ship_pair_collision": any(k in bad_pairs for k in mine),
                   **run_cols}
            if i > 0:
                row.update(_target_columns(targets.get(name)))
                if encounters is not None:
                    row.update(_colregs_columns([e for e in encounters if e["other"] == name]))
            if ev_runs is None:
                row["colregs_error"] = evaluation.get("error")
            rows.append(row)
    return rows


def _kind(name: str, values) -> str:
    if name in _INT:
        return "int"
    if name in _BOOL:
        return "bool"
    if name in _STR or name.endswith("_error"):
        return "str"
    seen = [v for v in values if v is not None and not (isinstance(v, float) and math.isnan(v))]
    if seen and all(isinstance(v, bool) for v in seen):
        return "bool"
    if seen and all(isinstance(v, str) for v in seen):
        return "str"
    if name.endswith(("_count", "_encounters", "stops", "n_solves", "n_targets")):
        return "count"
    return "float"


def rows_frame(rows: list[dict]):
    """A pandas DataFrame of ``rows`` with fixed column types (so tasks concatenate into one table): integers
    ``int64``, flags the nullable ``boolean``, text ``string``, counts the nullable ``Int64``, all else
    ``float64`` (null as NaN)."""
    import pandas as pd

    cols = list(dict.fromkeys([*(k for k in KEY_COLUMNS if rows and k in rows[0]), "ship_index", "own_ship",
                               *(k for r in rows for k in r)]))
    cols = [c for c in cols if any(c in r for r in rows)]
    data = {}
    for c in cols:
        vals = [r.get(c) for r in rows]
        kind = _kind(c, vals)
        if kind == "int":
            data[c] = pd.array(vals, dtype="int64")
        elif kind == "bool":
            data[c] = pd.array(vals, dtype="boolean")
        elif kind == "str":
            data[c] = pd.array([None if v is None else str(v) for v in vals], dtype="string")
        elif kind == "count":
            data[c] = pd.array(vals, dtype="Int64")
        else:
            data[c] = np.array([np.nan if v is None else float(v) for v in vals], dtype="float64")
    return pd.DataFrame(data, columns=cols)


#: Columns that depend on how and when a row was computed, not on the simulation: wall-clock solve times, the
#: task that held the run (it depends on ``chunk_runs``) and the package's commit.
EXECUTION_COLUMNS = ("task_id", "commit", "run_solve_time_mean_s", "run_solve_time_max_s", "run_solve_time_p95_s")


def comparable(frame):
    """``frame`` without :data:`EXECUTION_COLUMNS`, columns sorted by name and rows by :data:`KEY_COLUMNS`: two
    executions of one campaign (other engines, other ``chunk_runs``, a resume) give equal frames."""
    df = frame.drop(columns=[c for c in EXECUTION_COLUMNS if c in frame.columns])
    return df[sorted(df.columns)].sort_values(list(KEY_COLUMNS)).reset_index(drop=True)


def trajectory_frame(result, method: str, seed: int):
    """Every run's true trajectories as a long table: one row per run x ship x time step, columns ``scenario``,
    ``method``, ``seed``, ``run``, ``ship``, ``t_s``, ``north_m``, ``east_m``, ``course_deg``, ``speed_mps``."""
    import pandas as pd

    st = np.asarray(result.states)                       # [R, n, K+1, 4]
    R, n, K1, _ = st.shape
    names = np.array([s.name for s in result.scenario.ships], dtype=object)
    runs = result.run_start + np.arange(R)
    return pd.DataFrame({
        "scenario": pd.array(np.full(R * n * K1, result.scenario.name, dtype=object), dtype="string"),
        "method": pd.array(np.full(R * n * K1, method, dtype=object), dtype="string"),
        "seed": np.full(R * n * K1, seed, dtype="int64"),
        "run": np.repeat(runs, n * K1).astype("int64"),
        "ship": pd.array(np.tile(np.repeat(names, K1), R), dtype="string"),
        "t_s": np.tile(np.asarray(result.t, float), R * n),
        "north_m": st[..., 0].ravel(), "east_m": st[..., 1].ravel(),
        "course_deg": np.degrees(st[..., 2]).ravel(), "speed_mps": st[..., 3].ravel()})
