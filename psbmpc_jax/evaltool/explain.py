"""Why an encounter got its score: the stages, the manoeuvres, the CPA and every penalty with its value, the
sample that fired it and the condition that decided it -- the terms the scoring computed the score from
(:attr:`~psbmpc_jax.evaltool.results.Encounter.terms`), not a second computation.

    from psbmpc_jax.evaltool import evaluate_tracks
    from psbmpc_jax.evaltool.explain import explain_encounter, explanation_text
    ev = evaluate_tracks(tracks, "inland_small")
    x = explain_encounter(ev, ev.encounters[0])       # JSON-ready dict
    print(explanation_text(x))

Each explanation also says what each penalty costs: how much the situation score would rise were that penalty
0 (or S_safety 1), through the same composition the scoring uses (:func:`~psbmpc_jax.evaltool.encounters.compose`);
the penalty that costs most is the ``dominant`` one.
"""

from __future__ import annotations

import math

import numpy as np

from .encounters import compose
from .geometry import pair_geometry, stages
from .results import Encounter, Evaluation

__all__ = ["COMPOSITION", "explain_encounter", "explain_evaluation", "explanation_text", "penalty_costs",
           "EXPLAIN_SCHEMA"]

#: Schema id of ``explain.json``.
EXPLAIN_SCHEMA = "psbmpc-explain/1"

#: Per situation: the situation score's key, its formula, and the terms it is composed of (Hagen et al. 2023,
#: as reconstructed in docs/evaltool.md).  ``S_safety`` enters as a loss 1 − S_safety; ``P_3+P_pt`` is the
#: pair inside max(P_3, P_pt), which costs more together than either alone.
COMPOSITION = {
    "HO": ("S14", "S14 = max(0, 1 − γ_nsb·P_nsb − γ_sts·P_sts)·(1 − P_delay)·(1 − P_na_delta_chi)",
           ("P_nsb", "P_sts", "P_delay", "P_na_delta_chi")),
    "OTGW": ("S13", "S13 = max(0, S16 − γ_ah,OT·P_ah13), S16 = S_safety·(1 − P_delay)·(1 − P_na_delta)",
             ("S_safety", "P_delay", "P_na_delta", "P_ah13")),
    "CRGW": ("S15", "S15 = max(0, S16 − γ_ah,CR·P_ah15), S16 = S_safety·(1 − P_delay)·(1 − P_na_delta)",
             ("S_safety", "P_delay", "P_na_delta", "P_ah15")),
    "CRSO": ("S15", "S15 = S17 = S_safety·(1 − P_2)·(1 − max(P_3, P_pt))", ("S_safety", "P_2", "P_3", "P_pt", "P_3+P_pt")),
    "OTSO": ("S13", "S13 = S17 = S_safety·(1 − P_2)·(1 − max(P_3, P_pt))",
             ("S_safety", "P_2", "P_3", "P_pt", "P_3+P_pt")),
}


def penalty_costs(e: Encounter, p) -> dict:
    """``{term: cost}`` for a scored encounter: S_sit with that penalty at 0 (S_safety at 1; both of a pair
    ``A+B`` at 0) minus S_sit, the others kept, through :func:`~psbmpc_jax.evaltool.encounters.compose`.
    Empty when not scored."""
    if e.status != "scored" or e.situation not in COMPOSITION:
        return {}
    vals = e.scores.to_dict()
    base = vals["S_sit"]
    out = {}
    for entry in COMPOSITION[e.situation][2]:
        ideal = {n: (1.0 if n == "S_safety" else 0.0) for n in entry.split("+") if vals.get(n) is not None}
        # a stand-on stage not reached (None) already counts as 0 in S17
        out[entry] = compose(e.situation, {**vals, **ideal}, p)["S_sit"] - base if ideal else 0.0
    return out


def _stage_entries(g_r: np.ndarray, st: np.ndarray, e: Encounter, t: np.ndarray, p) -> list[dict]:
    """When and at what range each stage starts for this encounter: stage 1 at the start of the run of
    stage-1 samples before detection, stages 2–4 at the first sample in [detection, CPA] at that stage or
    closer."""
    k1 = e.k_detect
    while k1 > 0 and st[k1 - 1] == 1:
        k1 -= 1
    radius = {1: None, 2: p.r_stage2_m, 3: p.r_stage3_m, 4: p.r_stage4_m}
    out = []
    for x in (1, 2, 3, 4):
        if x == 1:
            k = k1 if k1 < e.k_detect else None
        else:
            hit = np.flatnonzero(st[e.k_detect:e.k_cpa + 1] >= x)
            k = e.k_detect + int(hit[0]) if hit.size else None
        out.append({"stage": x, "k": k, "t_s": None if k is None else float(t[k]),
                    "r_m": None if k is None else float(g_r[k]), "radius_m": radius[x]})
    return out


def _maneuver_rows(ms, lo: int, hi: int, t, r, beta, st, fired: dict) -> list[dict]:
    rows = []
    for m in ms:
        if not m.overlaps(lo, hi):
            continue
        d = m.to_dict(t)
        d.update({"r_start_m": float(r[m.start]), "stage_start": int(st[m.start]),
                  "beta_start_deg": math.degrees(float(beta[m.start])),
                  "fires": sorted(n for n, k in fired.items() if k == m.start)})
        rows.append(d)
    return rows


def explain_encounter(ev: Evaluation, e: Encounter, run: int | None = None) -> dict:
    """The explanation of encounter ``e`` of evaluation ``ev`` as a JSON-ready dict (module docstring)."""
    p, t, tr = ev.params, ev.t, ev.resampled
    if tr is None:
        raise ValueError("explain_encounter needs an Evaluation made by evaluate_tracks (it keeps the resampled "
                         "tracks)")
    i, j = e.vessel_index, e.other_index
    g = pair_geometry(tr.north, tr.east, tr.course, tr.speed, i, j, p)
    st = stages(g.r, p)
    costs = penalty_costs(e, p)
    terms = []
    for term in e.terms:
        d = term.to_dict(t)
        if term.k is not None:
            d.update({"r_m": float(g.r[term.k]), "stage": int(st[term.k])})
        if term.name in costs:
            d["cost"] = costs[term.name]
        terms.append(d)
    fired = {term.name: term.k for term in e.terms if term.k is not None and term.name.startswith("P_")
             and term.value}
    lo, hi = e.k_detect, e.k_cpa
    key, formula, _ = COMPOSITION.get(e.situation, (None, None, ()))
    dominant = max(costs, key=lambda name: costs[name]) if costs and max(costs.values()) > 0 else None
    return {
        "run": run, "vessel": e.vessel, "other": e.other, "situation": e.situation, "status": e.status,
        "score": key, "S_sit": e.scores.S_sit, "S_safety": e.scores.S_safety, "composition": formula,
        "dominant": dominant, "costs": costs,
        "window": {"k_detect": e.k_detect, "k_start": e.k_start, "k_cpa": e.k_cpa, "k_end": e.k_end,
                   "t_detect_s": e.t_detect, "t_start_s": e.t_start, "t_cpa_s": e.t_cpa,
                   "r_detect_m": e.r_detect},
        "stages": _stage_entries(g.r, st, e, t, p),
        "cpa": {"k": e.k_cpa, "t_s": e.t_cpa, "r_m": e.r_cpa, "alpha_deg": math.degrees(e.alpha_cpa),
                "beta_deg": math.degrees(e.beta_cpa)},
        "maneuvers": _maneuver_rows(ev.maneuvers[e.vessel], lo, hi, t, g.r, g.beta, st, fired),
        "other_maneuvers": _maneuver_rows(ev.maneuvers[e.other], lo, hi, t, g.r, g.beta, st, {}),
        "terms": terms,
    }


def explain_evaluation(ev: Evaluation, run: int | None = None) -> list[dict]:
    """:func:`explain_encounter` of every encounter of ``ev``."""
    return [explain_encounter(ev, e, run) for e in ev.encounters]


def _f(v, fmt: str = ".2f", none: str = "—") -> str:
    return none if v is None else format(v, fmt)


def explanation_text(x: dict) -> str:
    """A readable block (a few lines and a table of terms) for one explanation of :func:`explain_encounter`."""
    run = "" if x["run"] is None else f"run {x['run']}  "
    head = f"{run}{x['vessel']} vs {x['other']}: {x['situation']} {x['status']}"
    if x["score"] is not None and x["S_sit"] is not None:
        head += f"  {x['score']} = {x['S_sit']:.3f}"
    if x["S_safety"] is not None:
        head += f"  (S_safety {x['S_safety']:.3f})"
    if x["dominant"] is not None:
        head += f"  dominant: {x['dominant']} (costs {x['costs'][x['dominant']]:.3f})"
    lines = [head]
    if x["composition"]:
        lines.append(f"  {x['composition']}")
    st = [f"{s['stage']} from t {_f(s['t_s'], '.0f')} s (r {_f(s['r_m'], '.1f')} m)" if s["k"] is not None
          else f"{s['stage']} not reached" for s in x["stages"]]
    lines.append("  stages   " + " | ".join(st))
    w, c = x["window"], x["cpa"]
    lines.append(f"  start    t {w['t_start_s']:.0f} s, r_det {w['r_detect_m']:.1f} m;  CPA t {c['t_s']:.0f} s, "
                 f"r {c['r_m']:.1f} m, α {c['alpha_deg']:+.1f}°, β {c['beta_deg']:+.1f}°")
    for who, rows in ((x["vessel"], x["maneuvers"]), (x["other"], x["other_maneuvers"])):
        if not rows:
            lines.append(f"  manoeuvres of {who}: none between detection and CPA")
            continue
        lines.append(f"  manoeuvres of {who}:")
        for m in rows:
            size = (f"course {m['delta_course_deg']:+.1f}°" if m["kind"] == "course"
                    else f"speed {m['delta_speed_mps']:+.2f} m/s")
            fires = f"  -> {', '.join(m['fires'])}" if m.get("fires") else ""
            lines.append(f"    t {m['t_start_s']:.0f}–{m['t_end_s']:.0f} s  {size:18s} stage {m['stage_start']}, "
                         f"r {m['r_start_m']:.1f} m, β {m['beta_start_deg']:+.1f}°{fires}")
    lines.append(f"  {'term':18s} {'value':>7s} {'t [s]':>7s} {'r [m]':>8s} {'stage':>5s} {'cost':>7s}  why")
    for d in x["terms"]:
        lines.append(f"  {d['name']:18s} {_f(d['value'], '7.3f', '      —')} {_f(d.get('t_s'), '7.0f', '      —')} "
                     f"{_f(d.get('r_m'), '8.1f', '       —')} {_f(d.get('stage'), '5d', '    —')} "
                     f"{_f(d.get('cost'), '7.3f', '       ')}  {d['why']}")
    return "\n".join(lines)
