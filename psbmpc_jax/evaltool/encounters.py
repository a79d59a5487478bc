"""Encounter detection (``docs/evaltool.md``, "Pipeline" step 5) and the scoring of one encounter (same page, "Scores
and penalties").

:func:`find_windows` splits the samples of one ordered pair (i, j) into encounters: one per entry of the range
into the stage-2 disc.  :func:`score_window` computes every applicable score of one encounter.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import scores as sc
from .geometry import GIVE_WAY, STAND_ON, PairGeometry, both_passed, classify, wrap
from .maneuvers import Maneuver
from .params import EvalParams
from .results import Encounter, EncounterScores

__all__ = ["Window", "find_windows", "score_window", "dcpa"]


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
    course/speed and manoeuvres, and its give-way windows with other vessels (for C_x,gw)."""

    w: Window
    g: PairGeometry
    stage: np.ndarray
    course: np.ndarray
    speed: np.ndarray
    maneuvers: list
    give_way_spans: list
    p: EvalParams


def _safety(ctx: PairContext) -> dict:
    p, k_c = ctx.p, ctx.w.k_c
    r_cpa = float(ctx.g.r[k_c])
    s_r = float(sc.range_score(r_cpa, p))
    s_theta, s_a, s_b = sc.pose_score(ctx.g.alpha[k_c], ctx.g.beta[k_c], p)
    s_safe = sc.safety_score(s_r, s_theta, collided=r_cpa < p.r_col_m)
    return {"S_safety": s_safe, "S_r": s_r, "S_theta": s_theta, "S_alpha": s_a, "S_beta": s_b}


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


def _give_way(ctx: PairContext, s_safety: float) -> tuple[dict, Maneuver | None, float | None]:
    """P_delay, the non-apparent penalties and S16 (give-way vessel, Rules 8 and 16)."""
    p, w, r = ctx.p, ctx.w, ctx.g.r
    m = _give_way_maneuver(ctx)
    r_man = None if m is None else float(r[m.start])
    r_ref = float(r[w.k_s]) if p.delay_reference == "encounter_start" else p.r_stage3_m
    pd = sc.p_delay(r_ref, r_man, float(r[w.k_c]))
    dev = _course_dev(ctx, w.k_s, w.k_c, w.k_s)
    d_chi = float(np.max(np.abs(dev)))
    d_u = max(0.0, float(np.max(-_rel_speed(ctx, w.k_s, w.k_c, w.k_s))))
    pna, pna_chi, pna_u = sc.non_apparent(d_chi, d_u, p)
    out = {"P_delay": pd, "P_na_delta": pna, "P_na_delta_chi": pna_chi, "P_na_delta_u": pna_u,
           "S16": sc.s16(s_safety, pd, pna)}
    return out, m, r_man


def _head_on(ctx: PairContext, gw: dict, m: Maneuver | None) -> dict:
    """P_nsb, P_sts and S14 (Rule 14, head-on)."""
    p, w = ctx.p, ctx.w
    dev = _course_dev(ctx, w.k_s, w.k_c, w.k_s)
    nsb = sc.p_nsb(m is not None, max(0.0, float(dev.max())), max(0.0, float(-dev.min())), p)
    sts = float(sc.p_sts(ctx.g.alpha[w.k_c], ctx.g.beta[w.k_c]))
    s = sc.s14(nsb, sts, gw["P_delay"], gw["P_na_delta_chi"], p)
    return {"P_nsb": nsb, "P_sts": sts, "S14": s, "S_sit": s}


def _stage(ctx: PairContext, x: int) -> dict:
    """P_x and its parts for the stand-on vessel in stage x (Rule 17, stand-on vessel); None entries if the encounter
    has no sample in stage x."""
    p, w = ctx.p, ctx.w
    idx = w.k_s + np.flatnonzero(ctx.stage[w.k_s:w.k_c + 1] == x)
    keys = [f"P_{x}", f"P_{x}_delta_chi", f"P_{x}_delta_u_up", f"P_{x}_delta_u_down", f"C_{x}_gw"]
    if idx.size == 0:
        return dict.fromkeys(keys)
    k0, k1 = int(idx[0]), int(idx[-1])
    dev = np.abs(np.asarray(wrap(ctx.course[idx] - ctx.course[k0]), float))
    rel = (ctx.speed[idx] - ctx.speed[k0]) / max(float(ctx.speed[k0]), p.epsilon_speed_mps, 1e-9)
    md, ap = p.rad("delta_course_md"), p.rad("delta_course_app")
    p_chi = float(sc.ramp(dev.max(), md, ap))
    p_up = float(sc.ramp(max(0.0, float(rel.max())), p.delta_speed_md_rel, p.delta_speed_app_rel))
    p_down = float(sc.ramp(max(0.0, float(-rel.min())), p.delta_speed_md_rel, p.delta_speed_app_rel))
    man = any(m.overlaps(k0, k1) for m in ctx.maneuvers)
    comp = p.gamma_c if any(a <= k1 and b >= k0 for a, b in ctx.give_way_spans) else 0.0
    px = sc.stage_penalty(man, p_chi, p_up, p_down, comp, p)
    return dict(zip(keys, [px, p_chi, p_up, p_down, comp]))


def _port_turn(ctx: PairContext) -> bool:
    """A course manoeuvre overlapping stages 3–4 of [k_s, k_c] with a net port turn of at least Δχ_md, the
    other vessel on the port side (β < 0) at its start (Rule 17, stand-on vessel)."""
    w = ctx.w
    idx = w.k_s + np.flatnonzero(ctx.stage[w.k_s:w.k_c + 1] >= 3)
    if idx.size == 0:
        return False
    md = ctx.p.rad("delta_course_md")
    return any(m.kind == "course" and m.overlaps(int(idx[0]), int(idx[-1])) and m.delta_course <= -md
               and ctx.g.beta[m.start] < 0 for m in ctx.maneuvers)


def _stand_on(ctx: PairContext, s_safety: float) -> dict:
    """The stage penalties, P_pt and S17 (Rule 17, stand-on vessel)."""
    out = {**_stage(ctx, 2), **_stage(ctx, 3)}
    ppt = sc.p_port_turn(_port_turn(ctx), ctx.p)
    out["P_pt"] = ppt
    out["S17"] = sc.s17(s_safety, out["P_2"] or 0.0, out["P_3"] or 0.0, ppt)
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


def score_window(ctx: PairContext, names, t, dcpa_start: float) -> Encounter:
    """Score one encounter (every applicable score; None for the rest)."""
    w, g = ctx.w, ctx.g
    status = _status(ctx, dcpa_start)
    vals: dict = {}
    man, r_man = None, None
    if status in ("scored", "nar", "no_risk"):
        vals.update(_safety(ctx))
    if status == "scored":
        s_safe = vals["S_safety"]
        if w.situation in GIVE_WAY:
            gw, man, r_man = _give_way(ctx, s_safe)
            vals.update(gw)
            if w.situation == "HO":
                vals.update(_head_on(ctx, gw, man))
            elif w.situation == "OTGW":
                vals["P_ah13"] = sc.p_ah13(g.alpha[w.k_c], ctx.p)
                vals["S13"] = vals["S_sit"] = sc.s13_give_way(gw["S16"], vals["P_ah13"], ctx.p)
            else:
                vals["P_ah15"] = sc.p_ah15(g.alpha[w.k_c], ctx.p)
                vals["S15"] = vals["S_sit"] = sc.s15_give_way(gw["S16"], vals["P_ah15"], ctx.p)
        elif w.situation in STAND_ON:
            vals.update(_stand_on(ctx, s_safe))
            key = "S13" if w.situation == "OTSO" else "S15"
            vals[key] = vals["S_sit"] = vals["S17"]
    stage_t = {x: float(t[w.k_s + int(np.flatnonzero(ctx.stage[w.k_s:w.k_c + 1] >= x)[0])])
               for x in (2, 3, 4) if np.any(ctx.stage[w.k_s:w.k_c + 1] >= x)}
    return Encounter(
        vessel=names[w.i], other=names[w.j], vessel_index=w.i, other_index=w.j, situation=w.situation,
        status=status, k_detect=w.k_d, k_start=w.k_s, k_cpa=w.k_c, k_end=w.k_end, t_detect=float(t[w.k_d]),
        t_start=float(t[w.k_s]), t_cpa=float(t[w.k_c]), r_detect=float(g.r[w.k_s]), r_cpa=float(g.r[w.k_c]),
        alpha_cpa=float(g.alpha[w.k_c]), beta_cpa=float(g.beta[w.k_c]), dcpa_start=dcpa_start,
        stage_first_t=stage_t, maneuver=man, r_maneuver=r_man, scores=EncounterScores(**vals))
