"""Explain the COLREGS scores of the committed closed-loop results (experiments/closed_loop/results/).

The committed run folders keep no trajectories, so the runs are simulated again with the same scenario files
and seeds (``psbmpc-jax run ... --save-trajectories``); this script re-scores those tracks with each run's
stored evaluation settings, checks that every score equals the committed ``metrics.json`` (to its 6 digits),
explains every encounter (psbmpc_jax.evaltool.explain) and writes, per scenario and target, what each
penalty costs, which one dominates and a few facts that separate the evaluator's reading from the planner's
behaviour (docs/colregs_scores.md).

    psbmpc-jax run head_on crossing_stand_on overtaken imazu_01 imazu_04 imazu_11 nidelva \\
        --save-trajectories --no-figures --out /tmp/cl
    python experiments/colregs_explain/explain_closed_loop.py /tmp/cl --out /tmp/colregs_explain

It writes ``summary.md``, ``summary.json`` and the figure of run 0 of every scenario and target into the
--out folder (a run folder: a folder holding another run's results only with --force).
"""

from __future__ import annotations

import argparse
import json
import pathlib
import statistics
import sys

import numpy as np

from psbmpc_jax.evaltool import EvalParams, evaluate_file
from psbmpc_jax.evaltool.encounters import compose
from psbmpc_jax.evaltool.explain import explain_encounter
from psbmpc_jax.evaltool.explain_plot import plot_explanation
from psbmpc_jax.runfolder import RunWriter
from psbmpc_jax.safe_io import atomic_write_text

ROOT = pathlib.Path(__file__).resolve().parents[2]
COMMITTED = ROOT / "experiments" / "closed_loop" / "results"
SCENARIOS = ("head_on", "crossing_stand_on", "overtaken", "imazu_01", "imazu_04", "imazu_11", "nidelva",
             "imazu_16", "crossing_give_way", "overtaking")


def find_tracks(runs: pathlib.Path, name: str) -> pathlib.Path | None:
    hits = sorted(runs.glob(f"**/{name}/trajectories.npz"))
    return hits[0].parent if hits else None


def check_committed(name: str, evs, stored: dict) -> int:
    """Every score of the re-scored runs equals the committed one (6 significant digits); returns the count."""
    n = 0
    if len(evs) != len(stored["runs"]):
        raise SystemExit(f"{name}: {len(evs)} runs re-scored, {len(stored['runs'])} committed")
    for r, (ev, encs) in enumerate(zip(evs, stored["runs"])):
        if [e.other for e in ev.encounters] != [d["other"] for d in encs]:
            raise SystemExit(f"{name} run {r}: other encounters than the committed ones")
        for e, d in zip(ev.encounters, encs):
            for key, value in d["scores"].items():
                mine = getattr(e.scores, key)
                if (mine is None) != (value is None) or (value is not None and abs(mine - value) >
                                                         max(1e-5 * abs(value), 1e-6)):
                    raise SystemExit(f"{name} run {r} {e.other} {key}: re-scored {mine}, committed {value}")
                n += 1
    return n


def facts(ev, e, x) -> dict:
    """What one explanation says about the reading: where the encounter started, when the first action came,
    and the stage of the manoeuvre that fired P_pt."""
    terms = {d["name"]: d for d in x["terms"]}
    out = {"S_sit": e.scores.S_sit, "situation": e.situation, "dominant": x["dominant"], "costs": x["costs"],
           "start_after_detection": e.k_start > e.k_detect, "stage_at_start": None}
    st = {s["stage"]: s for s in x["stages"]}
    out["stage_at_start"] = max(s for s, v in st.items() if v["k"] is not None and v["k"] <= e.k_start) \
        if any(v["k"] is not None and v["k"] <= e.k_start for v in st.values()) else None
    d = terms.get("P_delay")
    if d is not None:
        out["first_action_before_start"] = d["k"] is not None and d["k"] < e.k_start
        out["first_action_stage"] = d.get("stage")
        out["first_action_r_m"] = d.get("r_m")
    d = terms.get("P_nsb")
    if d is not None and d["value"]:
        out["nsb_s_before_cpa"] = e.t_cpa - d["t_s"] if d.get("t_s") is not None else None
        # the same deviations measured from the course at the first sample (the route's course) instead of
        # the encounter start: is the turn still mainly to port?  (an alternative reading, not the evaluator)
        c = ev.resampled.course[e.vessel_index]
        dev = np.degrees(np.angle(np.exp(1j * (c[e.k_start:e.k_cpa + 1] - c[0]))))
        port, stbd = max(0.0, -dev.min()), max(0.0, dev.max())
        out["nsb_port_from_route"] = bool(port >= ev.params.theta_sm_deg and port > stbd)
    d = terms.get("P_pt")
    if d is not None and d["value"]:
        k4 = st[4]["k"]
        m = next(m for m in x["maneuvers"] if m["start"] == d["k"] and m["kind"] == "course")
        in_stage4 = k4 is not None and m["end"] > k4
        out["pt_overlaps_stage4"] = in_stage4
        if not in_stage4:             # Table XI: S_pt "stand-on behaviour during Stage 4" (see docs)
            out["S_sit_pt_stage4_only"] = compose(e.situation, {**e.scores.to_dict(), "P_pt": 0.0},
                                                  ev.params)["S_sit"]
    return out


def summarise(rows: list[dict]) -> dict:
    costs: dict = {}
    for r in rows:
        for k, v in r["costs"].items():
            costs.setdefault(k, []).append(v)
    dom: dict = {}
    for r in rows:
        dom[r["dominant"] or "none"] = dom.get(r["dominant"] or "none", 0) + 1
    pt = [r.get("S_sit_pt_stage4_only", r["S_sit"]) for r in rows]

    def frac(key):
        vals = [r[key] for r in rows if key in r]
        return None if not vals else sum(bool(v) for v in vals) / len(vals)

    return {"n": len(rows), "situations": sorted({r["situation"] for r in rows}),
            "S_sit_mean": statistics.fmean(r["S_sit"] for r in rows),
            "S_sit_min": min(r["S_sit"] for r in rows),
            "mean_cost": {k: statistics.fmean(v) for k, v in costs.items()},
            "dominant": dict(sorted(dom.items(), key=lambda kv: -kv[1])),
            "start_after_detection": frac("start_after_detection"),
            "first_action_before_start": frac("first_action_before_start"),
            "first_action_stage": sorted({r["first_action_stage"] for r in rows if r.get("first_action_stage")}),
            "stage_at_start": sorted({r["stage_at_start"] for r in rows if r.get("stage_at_start")}),
            "nsb_s_before_cpa_median": (statistics.median(v) if (v := [r["nsb_s_before_cpa"] for r in rows
                                                                     if r.get("nsb_s_before_cpa") is not None])
                                        else None),
            "nsb_fired": sum("nsb_port_from_route" in r for r in rows),
            "nsb_port_also_from_route": sum(bool(r.get("nsb_port_from_route")) for r in rows),
            "pt_fired": sum("pt_overlaps_stage4" in r for r in rows),
            "pt_before_stage4": sum(r.get("pt_overlaps_stage4") is False for r in rows),
            "S_sit_mean_pt_stage4_only": statistics.fmean(pt)}


def table(summary: dict) -> str:
    lines = ["| scenario | target | n | situation | S_sit mean (min) | dominant (count) | mean cost per term | "
             "started after detection | first action before start | first action in stage | P_nsb > 0 / mainly port also "
             "from the route course | P_pt fired / before stage 4 | S_sit mean, P_pt in stage 4 only |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for (scen, target), s in summary.items():
        cost = ", ".join(f"{k} {v:.2f}" for k, v in sorted(s["mean_cost"].items(), key=lambda kv: -kv[1]) if v > 5e-3)
        dom = ", ".join(f"{k} {v}" for k, v in s["dominant"].items())
        f = (lambda v: "—" if v is None else f"{100 * v:.0f} %")
        lines.append(f"| {scen} | {target} | {s['n']} | {'/'.join(s['situations'])} | {s['S_sit_mean']:.2f} "
                     f"({s['S_sit_min']:.2f}) | {dom} | {cost or '—'} | {f(s['start_after_detection'])} | "
                     f"{f(s['first_action_before_start'])} | {','.join(map(str, s['first_action_stage'])) or '—'} | "
                     f"{s['nsb_fired']} / {s['nsb_port_also_from_route']} | {s['pt_fired']} / {s['pt_before_stage4']} | {s['S_sit_mean_pt_stage4_only']:.2f} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", help="folder holding the re-run scenarios (each SCENARIO/trajectories.npz)")
    ap.add_argument("--out", required=True, help="output folder (a run folder)")
    ap.add_argument("--force", action="store_true", help="replace the results of an earlier run in --out")
    ap.add_argument("--scenarios", nargs="+", default=list(SCENARIOS))
    args = ap.parse_args(argv)
    runs = pathlib.Path(args.runs)
    writer = RunWriter(args.out, force=args.force, meta={"command": "experiments/colregs_explain/"
                                                                   "explain_closed_loop.py"})
    try:
        summary, checked, doc = {}, {}, {}
        for name in args.scenarios:
            folder = find_tracks(runs, name)
            if folder is None:
                print(f"{name}: no re-run tracks under {runs}; skipped", file=sys.stderr)
                continue
            stored = json.loads((COMMITTED / name / "metrics.json").read_text())["colregs_evaluation"]
            params = EvalParams(**stored["params"])
            evs = evaluate_file(folder, params)
            checked[name] = check_committed(name, evs, stored)
            rows: dict = {}
            for r, ev in enumerate(evs):
                for e in ev.encounters:
                    if e.status != "scored":
                        continue
                    x = explain_encounter(ev, e, r)
                    rows.setdefault(e.other, []).append(facts(ev, e, x))
                    if r == 0:
                        plot_explanation(ev, e, x, writer.path(f"{name}_run0_{e.other}.png"), dpi=70)
            for other, rs in rows.items():
                summary[name, other] = summarise(rs)
            doc[name] = {"params": params.as_dict(), "scores_checked": checked[name],
                         "targets": {o: summary[name, o] for o in rows}}
            print(f"{name}: {len(evs)} runs re-scored, {checked[name]} scores equal to the committed ones")
        atomic_write_text(writer.path("summary.json"), json.dumps({"scenarios": doc}, indent=1) + "\n")
        atomic_write_text(writer.path("summary.md"), "# Explained COLREGS scores of the committed closed-loop "
                          "runs\n\nWritten by `experiments/colregs_explain/explain_closed_loop.py`; "
                          "see docs/colregs_scores.md.\n\n" + table(summary) + "\n\nScores checked equal to "
                          "the committed metrics.json: " + ", ".join(f"{k} {v}" for k, v in checked.items())
                          + ".\n")
        writer.commit()
    except BaseException:
        writer.abort()
        raise
    print(table(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())
