"""Encounter detection (``docs/evaltool.md``, "Pipeline" step 5) and the scoring of one encounter (same page, "Scores
and penalties").

:func:`find_windows` splits the samples of one ordered pair (i, j) into encounters: one per entry of the range
into the stage-2 disc.  :func:`score_window` computes every applicable score of one encounter and records each
as a :class:`~psbmpc_jax.evaltool.results.Term` (value, the sample that fired it, the condition), the basis of
:mod:`psbmpc_jax.evaltool.explain`; :func:`compose` builds the situation scores from the penalties.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import scores as sc
from .geometry import GIVE_WAY, STAND_ON, PairGeometry, both_passed, classify, wrap
from .maneuvers import Maneuver
from .params import EvalParams
from .results import Encounter, EncounterScores, Term

__all__ = ["Window", "find_windows", "score_window", "dcpa", "compose"]


@dataclass(frozen=True)
class Window:
    """The sample indices of one encounter of i with j (before scoring).

    ``k_d`` detection, ``k_s`` start (situation locked here), ``k_c`` CPA, ``k_end`` end of the CPA search
    window (exclusive); ``complete`` is False when the CPA is the last sample of the data."""

    i: int
    j: int
    k_d: int
    k_s: int
    k_c: int
    k_end: int
    situation: str
    complete: bool


def _first(mask: np.ndarray, start: int) -> int:
    """First index >= start where ``mask`` is True, or ``mask.size``."""
    hit = np.flatnonzero(mask[start:])
    return int(start + hit[0]) if hit.size else int(mask.size)


def find_windows(g: PairGeometry, u_i, u_j, i: int, j: int, p: EvalParams) -> list[Window]:
    """Every encounter of i with j (Pipeline step 5): detection at each entry of the range into r_Stage2; the CPA
    window ends at the first sample where the range leaves r_Stage2 or both vessels have passed each other;
    the CPA is the minimum range in the window; the start is the first non-NAR sample in [k_d, k_c] (or k_d
    itself with ``scan_for_situation=False``)."""
    inside = g.r <= p.r_stage2_m
    passed = both_passed(g.alpha, g.beta, p)
    n, k, out = g.r.size, 0, []
    while k < n:
        k_d = _first(inside, k)
        if k_d >= n:
            break
        k_exit = _first(~inside, k_d + 1)
        k_end = min(k_exit, _first(passed, k_d + 1))
        k_c = k_d + int(np.argmin(g.r[k_d:k_end]))
        sit = classify(g.alpha[k_d:k_c + 1], g.beta[k_d:k_c + 1], u_i[k_d:k_c + 1], u_j[k_d:k_c + 1], p)
        k_s = k_d
        if p.scan_for_situation:
            found = np.flatnonzero(sit != "NAR")
            k_s = k_d + int(found[0]) if found.size else k_d
        out.append(Window(i, j, k_d, k_s, k_c, k_end, str(sit[k_s - k_d]), complete=k_c < n - 1))
        k = k_exit
    return out


def dcpa(north, east, course, speed, i: int, j: int, k: int) -> float:
    """Constant-velocity distance at the closest point of approach predicted at sample k [m]."""
    pos = np.array([north[j, k] - north[i, k], east[j, k] - east[i, k]])
    vel = (speed[j, k] * np.array([math.cos(course[j, k]), math.sin(course[j, k])])
           - speed[i, k] * np.array([math.cos(course[i, k]), math.sin(course[i, k])]))
    vv = float(vel @ vel)
    t = 0.0 if vv < 1e-12 else max(0.0, -float(pos @ vel) / vv)
    return float(np.linalg.norm(pos + t * vel))


# ---------------------------------------------------------------------------------------------------- scoring
@dataclass(frozen=True)
class PairContext:
    """What scoring one encounter needs: the window, the pair geometry, stages, the evaluated vessel's raw
    course/speed and manoeuvres, and its give-way windows with other vessels (for C_x,gw) as
    ``(other vessel's name, k_s, k_c)``."""

    w: Window
    g: PairGeometry
    stage: np.ndarray
    course: np.ndarray
    speed: np.ndarray
    maneuvers: list
    give_way_spans: list
    p: EvalParams


def _deg(x) -> float:
    return math.degrees(float(x))


def _man_text(m: Maneuver) -> str:
    """A manoeuvre in words: ``course +12.3°`` or ``speed -0.40 m/s``."""
    if m.kind == "course":
        return f"course {_deg(m.delta_course):+.1f}°"
    return f"speed {m.delta_speed:+.2f} m/s"


def _safety(ctx: PairContext) -> tuple[dict, list[Term]]:
    p, k_c = ctx.p, ctx.w.k_c
    r_cpa = float(ctx.g.r[k_c])
    a_c, b_c = float(ctx.g.alpha[k_c]), float(ctx.g.beta[k_c])
    s_r = float(sc.range_score(r_cpa, p))
    s_theta, s_a, s_b = sc.pose_score(a_c, b_c, p)
    collided = r_cpa < p.r_col_m
    s_safe = sc.safety_score(s_r, s_theta, collided=collided)
    ranges = {"r_cpa_m": r_cpa, "r_pref_m": p.r_pref_m, "r_min_m": p.r_min_m, "r_nm_m": p.r_nm_m,
              "r_col_m": p.r_col_m}
    if r_cpa >= p.r_pref_m:
        why_r = f"r_cpa {r_cpa:.1f} m ≥ r_pref {p.r_pref_m:g} m"
    elif collided:
        why_r = f"r_cpa {r_cpa:.1f} m < r_col {p.r_col_m:g} m (collision)"
    else:
        band = ("r_min, r_pref" if r_cpa >= p.r_min_m else "r_nm, r_min" if r_cpa >= p.r_nm_m else "r_col, r_nm")
        why_r = f"r_cpa {r_cpa:.1f} m in [{band}) = ramps of γ_min/γ_nm/γ_col below r_pref {p.r_pref_m:g} m"
    if collided:
        why_s = f"collision (r_cpa {r_cpa:.1f} m < r_col {p.r_col_m:g} m): 0"
    elif s_r >= 1.0:
        why_s = "S_r = 1: 1"
    else:
        why_s = f"S_r + (1 − S_r)·S_Θ = {s_r:.4f} + {1 - s_r:.4f}·{s_theta:.4f}"
    terms = [
        Term("S_r", s_r, k_c, why_r, ranges),
        Term("S_alpha", s_a, k_c, f"contact angle at CPA α_c {_deg(a_c):+.1f}° (1 from |α_c| ≥ {p.alpha_cut_deg:g}°)",
             {"alpha_cpa_deg": _deg(a_c)}),
        Term("S_beta", s_b, k_c, f"relative bearing at CPA β_c {_deg(b_c):+.1f}° (1 from |β_c| ≥ {p.beta_cut_deg:g}°)",
             {"beta_cpa_deg": _deg(b_c)}),
        Term("S_theta", s_theta, k_c, f"γ_α·S_α + γ_β·S_β = {p.gamma_alpha:g}·{s_a:.4f} + {p.gamma_beta:g}·{s_b:.4f}",
             {"gamma_alpha": p.gamma_alpha, "gamma_beta": p.gamma_beta}),
        Term("S_safety", s_safe, k_c, why_s, {"collision": bool(collided)}),
    ]
    return {"S_safety": s_safe, "S_r": s_r, "S_theta": s_theta, "S_alpha": s_a, "S_beta": s_b}, terms


def _course_dev(ctx: PairContext, lo: int, hi: int, ref: int) -> np.ndarray:
    """wrap(χ_k − χ_ref) for k in [lo, hi] [rad]."""
    return np.asarray(wrap(ctx.course[lo:hi + 1] - ctx.course[ref]), float).reshape(-1)


def _rel_speed(ctx: PairContext, lo: int, hi: int, ref: int) -> np.ndarray:
    """(U_k − U_ref)/U_ref for k in [lo, hi] (the reference floored at ε_U, and at 1e-9)."""
    u_ref = max(float(ctx.speed[ref]), ctx.p.epsilon_speed_mps, 1e-9)
    return (ctx.speed[lo:hi + 1] - ctx.speed[ref]) / u_ref


def _give_way_maneuver(ctx: PairContext) -> Maneuver | None:
    """The first manoeuvre of the evaluated vessel overlapping [k_s, k_c] (Pipeline step 2)."""
    return next((m for m in ctx.maneuvers if m.overlaps(ctx.w.k_s, ctx.w.k_c)), None)


def _delay_why(ctx: PairContext, m: Maneuver | None, r_ref: float, r_man: float | None, r_cpa: float) -> str:
    ref = "r_det" if ctx.p.delay_reference == "encounter_start" else "r_Stage3"
    if m is None:
        return "no manoeuvre overlaps the encounter [start, CPA]: 1"
    assert r_man is not None                    # the range at the manoeuvre's start, set with m
    head = f"first manoeuvre ({_man_text(m)}) starts at r_man {r_man:.1f} m (stage {int(ctx.stage[m.start])})"
    if r_ref - r_cpa <= 0:
        return f"{head}; {ref} {r_ref:.1f} m ≤ r_cpa {r_cpa:.1f} m: 0"
    if r_man >= r_ref:
        return f"{head}, at or beyond {ref} {r_ref:.1f} m: 0"
    return (f"{head}: ({ref} − r_man)/({ref} − r_cpa) = ({r_ref:.1f} − {r_man:.1f})/({r_ref:.1f} − {r_cpa:.1f})"
            + (" clipped to 1" if r_man < r_cpa else ""))


def _band_why(what: str, x: float, md: float, ap: float, unit: str, value: float, shape: str) -> str:
    if x < md:
        return f"{what} {x:.3g}{unit} < detectable {md:g}{unit}: 0"
    if x >= ap:
        return f"{what} {x:.3g}{unit} ≥ apparent {ap:g}{unit}: 0"
    return f"{what} {x:.3g}{unit} between detectable {md:g}{unit} and apparent {ap:g}{unit}: {shape} = {value:.4f}"


def _give_way(ctx: PairContext) -> tuple[dict, Maneuver | None, float | None, list[Term]]:
    """P_delay, the non-apparent penalties and S16 (give-way vessel, Rules 8 and 16), and their terms."""
    p, w, r = ctx.p, ctx.w, ctx.g.r
    m = _give_way_maneuver(ctx)
    r_man = None if m is None else float(r[m.start])
    r_ref = float(r[w.k_s]) if p.delay_reference == "encounter_start" else p.r_stage3_m
    r_cpa = float(r[w.k_c])
    pd = sc.p_delay(r_ref, r_man, r_cpa)
    dev = _course_dev(ctx, w.k_s, w.k_c, w.k_s)
    k_chi = w.k_s + int(np.argmax(np.abs(dev)))
    d_chi = float(np.max(np.abs(dev)))
    rel = _rel_speed(ctx, w.k_s, w.k_c, w.k_s)
    k_u = w.k_s + int(np.argmax(-rel))
    d_u = max(0.0, float(np.max(-rel)))
    pna, pna_chi, pna_u = sc.non_apparent(d_chi, d_u, p)
    chi_md, chi_ap = p.delta_course_md_deg, p.delta_course_app_deg
    if d_chi >= p.rad("delta_course_app") or d_u >= p.delta_speed_app_rel:
        why_na = "an apparent change (course or speed): 0"
    else:
        why_na = f"min(1, P_Δχ^¬ap + P_ΔU^¬ap) = min(1, {pna_chi:.4f} + {pna_u:.4f})"
    terms = [
        Term("P_delay", pd, None if m is None else m.start, _delay_why(ctx, m, r_ref, r_man, r_cpa),
             {"r_ref_m": r_ref, "r_man_m": r_man, "r_cpa_m": r_cpa, "delay_reference": p.delay_reference,
              "maneuver_kind": None if m is None else m.kind}),
        Term("P_na_delta_chi", pna_chi, k_chi,
             _band_why("largest course deviation from the start course", _deg(d_chi), chi_md, chi_ap, "°", pna_chi,
                       f"γ_na,Δχ·(1 − ((Δχ − Δχ_md)/(Δχ_ap − Δχ_md))²) = {p.gamma_na_delta_chi:g}·f_χ"),
             {"delta_chi_deg": _deg(d_chi), "delta_course_md_deg": chi_md, "delta_course_app_deg": chi_ap}),
        Term("P_na_delta_u", pna_u, k_u,
             _band_why("largest relative speed reduction", d_u, p.delta_speed_md_rel, p.delta_speed_app_rel, "",
                       pna_u, f"γ_na,ΔU·(1 − (ΔU − ΔU_md)/(ΔU_ap − ΔU_md)) = {p.gamma_na_delta_u:g}·f_U"),
             {"delta_u_rel": d_u}),
        Term("P_na_delta", pna, k_chi if pna_chi >= pna_u else k_u, why_na, {}),
    ]
    out = {"P_delay": pd, "P_na_delta": pna, "P_na_delta_chi": pna_chi, "P_na_delta_u": pna_u}
    return out, m, r_man, terms


def _head_on(ctx: PairContext, m: Maneuver | None) -> tuple[dict, list[Term]]:
    """P_nsb and P_sts (Rule 14, head-on), and their terms."""
    p, w = ctx.p, ctx.w
    dev = _course_dev(ctx, w.k_s, w.k_c, w.k_s)
    stbd, port = max(0.0, float(dev.max())), max(0.0, float(-dev.min()))
    k_stbd, k_port = w.k_s + int(np.argmax(dev)), w.k_s + int(np.argmin(dev))
    nsb = sc.p_nsb(m is not None, stbd, port, p)
    sm = p.theta_sm_deg
    if m is None:
        why, k = "no manoeuvre in the encounter: 0 (the loss is P_delay's)", None
    elif port >= p.rad("theta_sm") and port > stbd:
        why, k = (f"mainly a port turn: largest port deviation from the start course {_deg(port):.1f}° ≥ θ_SM "
                  f"{sm:g}° and > largest starboard deviation {_deg(stbd):.1f}°: 1"), k_port
    else:
        why, k = (f"largest starboard deviation {_deg(stbd):.1f}° (port {_deg(port):.1f}°): clip(1 − Δχ⁺/θ_SM, 0, 1) "
                  f"with θ_SM {sm:g}°"), k_stbd
    a_c, b_c = ctx.g.alpha[w.k_c], ctx.g.beta[w.k_c]
    sts = float(sc.p_sts(a_c, b_c))
    terms = [Term("P_nsb", nsb, k, why, {"turn_starboard_deg": _deg(stbd), "turn_port_deg": _deg(port),
                                         "theta_sm_deg": sm}),
             Term("P_sts", sts, w.k_c, f"1 − [¼(1 − sin α_c)(1 − sin β_c)]² with α_c {_deg(a_c):+.1f}°, β_c "
                  f"{_deg(b_c):+.1f}° (0 port-to-port, 1 starboard-to-starboard)",
                  {"alpha_cpa_deg": _deg(a_c), "beta_cpa_deg": _deg(b_c)})]
    return {"P_nsb": nsb, "P_sts": sts}, terms


def _stage(ctx: PairContext, x: int) -> tuple[dict, list[Term]]:
    """P_x and its parts for the stand-on vessel in stage x (Rule 17, stand-on vessel), and their terms; None entries if the
    encounter has no sample in stage x."""
    p, w = ctx.p, ctx.w
    idx = w.k_s + np.flatnonzero(ctx.stage[w.k_s:w.k_c + 1] == x)
    keys = [f"P_{x}", f"P_{x}_delta_chi", f"P_{x}_delta_u_up", f"P_{x}_delta_u_down", f"C_{x}_gw"]
    if idx.size == 0:
        return dict.fromkeys(keys), [Term(f"P_{x}", None, None, f"stage {x} not reached between the encounter "
                                                                 f"start and the CPA: counts as 0")]
    k0, k1 = int(idx[0]), int(idx[-1])
    signed = np.asarray(wrap(ctx.course[idx] - ctx.course[k0]), float)
    dev = np.abs(signed)
    rel = (ctx.speed[idx] - ctx.speed[k0]) / max(float(ctx.speed[k0]), p.epsilon_speed_mps, 1e-9)
    md, ap = p.rad("delta_course_md"), p.rad("delta_course_app")
    p_chi = float(sc.ramp(dev.max(), md, ap))
    up, down = max(0.0, float(rel.max())), max(0.0, float(-rel.min()))
    p_up = float(sc.ramp(up, p.delta_speed_md_rel, p.delta_speed_app_rel))
    p_down = float(sc.ramp(down, p.delta_speed_md_rel, p.delta_speed_app_rel))
    man = next((m for m in ctx.maneuvers if m.overlaps(k0, k1)), None)
    gw = next((other for other, a, b in ctx.give_way_spans if a <= k1 and b >= k0), None)
    comp = p.gamma_c if gw is not None else 0.0
    px = sc.stage_penalty(man is not None, p_chi, p_up, p_down, comp, p)
    k_chi = int(idx[int(np.argmax(dev))])
    ramp_u = f"ramp(·; {p.delta_speed_md_rel:g}, {p.delta_speed_app_rel:g})"
    sign = "+" if p.stand_on_mode == "reproduce" else "−"
    if man is None:
        why = f"no manoeuvre overlaps stage {x}: 0 (man_{x} = 0)"
    else:
        why = (f"manoeuvre ({_man_text(man)}, starting in stage {int(ctx.stage[man.start])}) overlaps stage {x} "
               f"(man_{x} = 1): "
               f"{'min(1' if sign == '+' else 'max(0'}, {p.gamma_so_delta_chi:g}·{p_chi:.4f} + "
               f"{p.gamma_so_delta_u_up:g}·{p_up:.4f} + {p.gamma_so_delta_u_down:g}·{p_down:.4f} {sign} {comp:g})")
    terms = [
        Term(f"P_{x}_delta_chi", p_chi, k_chi, f"largest course deviation in stage {x} from its start course "
             f"{_deg(dev.max()):.1f}° ({'starboard' if signed[int(np.argmax(dev))] >= 0 else 'port'}): "
             f"ramp(·; {p.delta_course_md_deg:g}°, {p.delta_course_app_deg:g}°)",
             {"delta_chi_deg": _deg(dev.max()), "signed_delta_chi_deg": _deg(signed[int(np.argmax(dev))])}),
        Term(f"P_{x}_delta_u_up", p_up, int(idx[int(np.argmax(rel))]),
             f"largest relative speed increase in stage {x} {up:.3f}: {ramp_u}", {"delta_u_rel": up}),
        Term(f"P_{x}_delta_u_down", p_down, int(idx[int(np.argmin(rel))]),
             f"largest relative speed reduction in stage {x} {down:.3f}: {ramp_u}", {"delta_u_rel": down}),
        Term(f"C_{x}_gw", comp, k0 if gw is not None else None,
             f"give-way to {gw} during stage {x}: γ_c" if gw is not None else f"no give-way role during stage {x}: 0",
             {"give_way_to": gw}),
        Term(f"P_{x}", px, None if man is None else man.start, why,
             {"stage_start_k": k0, "stage_end_k": k1, "maneuver": None if man is None else _man_text(man),
              "stand_on_mode": p.stand_on_mode}),
    ]
    return dict(zip(keys, [px, p_chi, p_up, p_down, comp])), terms


def _port_turn(ctx: PairContext) -> tuple[float, Term]:
    """P_pt: a course manoeuvre overlapping stages 3–4 (``port_turn_stages="4"``: stage 4) of [k_s, k_c] with a
    net port turn of at least Δχ_md, the other vessel on the port side (β < 0) at its start (Rule 17(c)); and
    its term."""
    w, p = ctx.w, ctx.p
    first = 4 if p.port_turn_stages == "4" else 3
    where = "stage 4" if first == 4 else "stages 3–4"
    idx = w.k_s + np.flatnonzero(ctx.stage[w.k_s:w.k_c + 1] >= first)
    if idx.size == 0:
        return 0.0, Term("P_pt", 0.0, None, f"{where} not reached before the CPA: 0")
    md = p.rad("delta_course_md")
    m = next((m for m in ctx.maneuvers if m.kind == "course" and m.overlaps(int(idx[0]), int(idx[-1]))
              and m.delta_course <= -md and ctx.g.beta[m.start] < 0), None)
    value = sc.p_port_turn(m is not None, p)
    if m is None:
        return value, Term("P_pt", value, None, f"no course manoeuvre overlapping {where} turns to port (≥ "
                           f"{p.delta_course_md_deg:g}°) with the other vessel on the port side: 0")
    b0 = _deg(ctx.g.beta[m.start])
    return value, Term("P_pt", value, m.start, f"course manoeuvre {_deg(m.delta_course):+.1f}° (to port) starting in "
                       f"stage {int(ctx.stage[m.start])} with the other vessel on the port side (β {b0:+.1f}°): γ_pt",
                       {"delta_course_deg": _deg(m.delta_course), "beta_start_deg": b0})


def _stand_on(ctx: PairContext) -> tuple[dict, list[Term]]:
    """The stage penalties and P_pt (Rule 17, stand-on vessel), and their terms."""
    v2, t2 = _stage(ctx, 2)
    v3, t3 = _stage(ctx, 3)
    ppt, tpt = _port_turn(ctx)
    return {**v2, **v3, "P_pt": ppt}, [*t2, *t3, tpt]


def compose(situation: str, v: dict, p: EvalParams) -> dict:
    """The situation scores of ``situation`` from the safety score and the penalties in ``v`` (docs/evaltool.md, "Scores and penalties"):
    S16 (give-way), S14, S13 or S15, S17 (stand-on) and S_sit.  The scoring computes them with this function;
    :mod:`psbmpc_jax.evaltool.explain` calls it with one penalty set to 0 to say what each costs."""
    out: dict = {}
    if situation in GIVE_WAY:
        out["S16"] = sc.s16(v["S_safety"], v["P_delay"], v["P_na_delta"])
        if situation == "HO":
            out["S14"] = out["S_sit"] = sc.s14(v["P_nsb"], v["P_sts"], v["P_delay"], v["P_na_delta_chi"], p)
        elif situation == "OTGW":
            out["S13"] = out["S_sit"] = sc.s13_give_way(out["S16"], v["P_ah13"], p)
        else:
            out["S15"] = out["S_sit"] = sc.s15_give_way(out["S16"], v["P_ah15"], p)
    elif situation in STAND_ON:
        out["S17"] = sc.s17(v["S_safety"], v["P_2"] or 0.0, v["P_3"] or 0.0, v["P_pt"])
        out["S13" if situation == "OTSO" else "S15"] = out["S_sit"] = out["S17"]
    return out


def _status(ctx: PairContext, dcpa_start: float) -> str:
    w, p = ctx.w, ctx.p
    if not w.complete:
        return "incomplete"
    if np.all(ctx.speed[w.k_s:w.k_c + 1] < p.epsilon_speed_mps):
        return "not_moving"
    if w.situation == "NAR":
        return "nar"
    if p.risk_gate and dcpa_start >= p.r_pref_m:
        return "no_risk"
    return "scored"


def _ahead_term(ctx: PairContext, name: str, value: float) -> Term:
    """P_ah13 / P_ah15: the contact angle at CPA against the 'ahead' band."""
    p, k_c = ctx.p, ctx.w.k_c
    a_c = _deg(ctx.g.alpha[k_c])
    if name == "P_ah13":
        band = f"|α_c| < {p.alpha_ahead_ot_absmax_deg:g}°"
    else:
        band = f"{p.alpha_ahead_cr_min_deg:g}° < α_c < {p.alpha_ahead_cr_max_deg:g}°"
    inside = "inside" if value > 0 else "outside"
    return Term(name, value, k_c, f"contact angle at CPA α_c {a_c:+.1f}° {inside} the ahead band {band} "
                f"(passed {'ahead of' if value > 0 else 'clear of'} the other vessel's bow): {value:g}",
                {"alpha_cpa_deg": a_c})


def _score_terms(situation: str, v: dict, p: EvalParams) -> list[Term]:
    """The terms of the situation score (and S16 for a give-way role): the formula with the numbers put in."""
    out = []
    if situation in GIVE_WAY:
        out.append(Term("S16", v["S16"], None, f"S_safety·(1 − P_delay)·(1 − P_Δ^¬ap) = {v['S_safety']:.4f}·"
                        f"{1 - v['P_delay']:.4f}·{1 - v['P_na_delta']:.4f}"))
    if situation == "HO":
        why = (f"max(0, 1 − γ_nsb·P_nsb − γ_sts·P_sts)·(1 − P_delay)·(1 − P_Δχ^¬ap) = max(0, 1 − "
               f"{p.gamma_ho_nsb:g}·{v['P_nsb']:.4f} − {p.gamma_ho_sts:g}·{v['P_sts']:.4f})·{1 - v['P_delay']:.4f}"
               f"·{1 - v['P_na_delta_chi']:.4f}")
        return out + [Term("S14", v["S14"], None, why)]
    if situation == "OTGW":
        return out + [Term("S13", v["S13"], None, f"max(0, S16 − γ_ah,OT·P_ah13) = max(0, {v['S16']:.4f} − "
                     f"{p.gamma_ahead_ot:g}·{v['P_ah13']:g})")]
    if situation == "CRGW":
        return out + [Term("S15", v["S15"], None, f"max(0, S16 − γ_ah,CR·P_ah15) = max(0, {v['S16']:.4f} − "
                     f"{p.gamma_ahead_cr:g}·{v['P_ah15']:g})")]
    key = "S13" if situation == "OTSO" else "S15"
    why = (f"S17 = S_safety·(1 − P_2)·(1 − max(P_3, P_pt)) = {v['S_safety']:.4f}·{1 - (v['P_2'] or 0.0):.4f}·"
           f"{1 - max(v['P_3'] or 0.0, v['P_pt']):.4f}")
    return [Term("S17", v["S17"], None, why), Term(key, v[key], None, f"{key} = S17 ({situation})")]


def score_window(ctx: PairContext, names, t, dcpa_start: float) -> Encounter:
    """Score one encounter (every applicable score; None for the rest), with the terms it was
    computed from (:attr:`Encounter.terms`)."""
    w, g = ctx.w, ctx.g
    status = _status(ctx, dcpa_start)
    vals: dict = {}
    terms: list[Term] = []
    man, r_man = None, None
    if status in ("scored", "nar", "no_risk"):
        safety, st = _safety(ctx)
        vals.update(safety)
        terms += st
    if status == "scored":
        if w.situation in GIVE_WAY:
            gw, man, r_man, gt = _give_way(ctx)
            vals.update(gw)
            terms += gt
            if w.situation == "HO":
                ho, ht = _head_on(ctx, man)
                vals.update(ho)
                terms += ht
            elif w.situation == "OTGW":
                vals["P_ah13"] = sc.p_ah13(g.alpha[w.k_c], ctx.p)
                terms.append(_ahead_term(ctx, "P_ah13", vals["P_ah13"]))
            else:
                vals["P_ah15"] = sc.p_ah15(g.alpha[w.k_c], ctx.p)
                terms.append(_ahead_term(ctx, "P_ah15", vals["P_ah15"]))
        elif w.situation in STAND_ON:
            so, sot = _stand_on(ctx)
            vals.update(so)
            terms += sot
        vals.update(compose(w.situation, vals, ctx.p))
        terms += _score_terms(w.situation, vals, ctx.p)
    stage_t = {x: float(t[w.k_s + int(np.flatnonzero(ctx.stage[w.k_s:w.k_c + 1] >= x)[0])])
               for x in (2, 3, 4) if np.any(ctx.stage[w.k_s:w.k_c + 1] >= x)}
    return Encounter(
        vessel=names[w.i], other=names[w.j], vessel_index=w.i, other_index=w.j, situation=w.situation,
        status=status, k_detect=w.k_d, k_start=w.k_s, k_cpa=w.k_c, k_end=w.k_end, t_detect=float(t[w.k_d]),
        t_start=float(t[w.k_s]), t_cpa=float(t[w.k_c]), r_detect=float(g.r[w.k_s]), r_cpa=float(g.r[w.k_c]),
        alpha_cpa=float(g.alpha[w.k_c]), beta_cpa=float(g.beta[w.k_c]), dcpa_start=dcpa_start,
        stage_first_t=stage_t, maneuver=man, r_maneuver=r_man, scores=EncounterScores(**vals), terms=tuple(terms))
