"""The scores and penalties of the EvalTool as plain functions (``docs/evaltool.md``, "Scores and penalties").

Every function is pure and takes numbers (radians for angles, metres for ranges, fractions for relative speed
changes) plus, where needed, an :class:`~psbmpc_jax.evaltool.params.EvalParams`.  The functions that map a
quantity through a fixed curve (:func:`range_score`, :func:`pose_score`, :func:`p_sts`, :func:`ramp` ...) accept
NumPy arrays as well. Every result lies in [0, 1]. The certainty tag of each formula ([PUB], [CFG], [LIN], [WOE],
[REC]: ``docs/evaltool.md``, "Provenance and licence") is in its docstring.
"""

from __future__ import annotations

import math

import numpy as np

from .params import EvalParams

__all__ = ["ramp", "range_score", "angle_score", "pose_score", "safety_score", "p_delay", "f_course", "f_speed",
           "non_apparent", "p_nsb", "p_sts", "s14", "s16", "s13_give_way", "p_ah13", "p_ah15", "s15_give_way",
           "stage_penalty", "p_port_turn", "s17"]


def ramp(x, lo: float, hi: float):
    """ramp(x; lo, hi) = clip((x − lo)/(hi − lo), 0, 1) (manoeuvre magnitudes)."""
    return np.clip((np.asarray(x, float) - lo) / (hi - lo), 0.0, 1.0)[()]


# ------------------------------------------------------------------------------------------ safety at CPA
def range_score(r_cpa, p: EvalParams):
    """S_r: four linear pieces from 1 at r_pref to 0 at r_col, slopes set by γ_min, γ_nm, γ_col
    ([CFG] weights, structure consistent with [PUB]; safety at CPA)."""
    r = np.asarray(r_cpa, float)
    s = (1.0 - p.gamma_min * ramp(p.r_pref_m - r, 0.0, p.r_pref_m - p.r_min_m)
         - p.gamma_nm * ramp(p.r_min_m - r, 0.0, p.r_min_m - p.r_nm_m)
         - p.gamma_col * ramp(p.r_nm_m - r, 0.0, p.r_nm_m - p.r_col_m))
    s = np.where(r < p.r_col_m, 0.0, s)
    return np.clip(s, 0.0, 1.0)[()]


def angle_score(angle, cut: float):
    """S_α or S_β: (1 − cos a)/(1 − cos a_cut) if |a| < a_cut, else 1 ([CFG] cut form, safety at CPA)."""
    a = np.asarray(angle, float)
    s = np.where(np.abs(a) < cut, (1.0 - np.cos(a)) / (1.0 - math.cos(cut)), 1.0)
    return np.clip(s, 0.0, 1.0)[()]


def pose_score(alpha_c, beta_c, p: EvalParams):
    """(S_Θ, S_α, S_β) with S_Θ = γ_α·S_α + γ_β·S_β ([CFG], safety at CPA)."""
    s_a = angle_score(alpha_c, p.rad("alpha_cut"))
    s_b = angle_score(beta_c, p.rad("beta_cut"))
    return float(np.clip(p.gamma_alpha * s_a + p.gamma_beta * s_b, 0.0, 1.0)), float(s_a), float(s_b)


def safety_score(s_r: float, s_theta: float, collided: bool = False) -> float:
    """S_safety = 0 on collision (r_cpa < r_col, [REC]), 1 if S_r = 1, else S_r + (1 − S_r)·S_Θ ([PUB]:
    0.85174, 0.75188 → 0.96321)."""
    if collided:
        return 0.0
    if s_r >= 1.0:
        return 1.0
    return float(np.clip(s_r + (1.0 - s_r) * s_theta, 0.0, 1.0))


# ------------------------------------------------------------------------------------------ give-way vessel
def p_delay(r_det: float, r_man: float | None, r_cpa: float) -> float:
    """P_delay = 1 without a manoeuvre, else clip((r_det − r_man)/(r_det − r_cpa), 0, 1); 0 when
    r_det − r_cpa ≤ 0 ([WOE]/[LIN], give-way vessel, Rules 8 and 16). With the ``stage3`` reference pass r_Stage3 as
    ``r_det``."""
    if r_man is None:
        return 1.0
    den = r_det - r_cpa
    if den <= 0:
        return 0.0
    return float(np.clip((r_det - r_man) / den, 0.0, 1.0))


def f_course(delta_chi: float, p: EvalParams) -> float:
    """f_χ: 0 below Δχ_md, 1 − ((Δχ − Δχ_md)/(Δχ_ap − Δχ_md))² in between, 0 from Δχ_ap
    ([REC], give-way vessel, Rules 8 and 16)."""
    md, ap = p.rad("delta_course_md"), p.rad("delta_course_app")
    if delta_chi < md or delta_chi >= ap:
        return 0.0
    return float(1.0 - ((delta_chi - md) / (ap - md)) ** 2)


def f_speed(delta_u_rel: float, p: EvalParams) -> float:
    """f_U: 0 below ΔU_md, 1 − (ΔU − ΔU_md)/(ΔU_ap − ΔU_md) in between, 0 from ΔU_ap ([REC], give-way vessel, Rules 8
    and 16)."""
    md, ap = p.delta_speed_md_rel, p.delta_speed_app_rel
    if delta_u_rel < md or delta_u_rel >= ap:
        return 0.0
    return float(1.0 - (delta_u_rel - md) / (ap - md))


def non_apparent(delta_chi: float, delta_u_rel: float, p: EvalParams) -> tuple[float, float, float]:
    """(P_Δ^¬ap, P_Δχ^¬ap, P_ΔU^¬ap) for the give-way vessel's largest course deviation ``delta_chi`` [rad]
    and largest relative speed reduction ``delta_u_rel`` ([REC], give-way vessel, Rules 8 and 16): the components are
    γ·f; the total is 0 when either change is apparent, otherwise min(1, sum)."""
    pc = p.gamma_na_delta_chi * f_course(delta_chi, p)
    pu = p.gamma_na_delta_u * f_speed(delta_u_rel, p)
    apparent = delta_chi >= p.rad("delta_course_app") or delta_u_rel >= p.delta_speed_app_rel
    return (0.0 if apparent else min(1.0, pc + pu)), pc, pu


def s16(s_safety: float, p_delay_: float, p_na: float) -> float:
    """S16 = S_safety·(1 − P_delay)·(1 − P_Δ^¬ap) ([PUB]: 0.96321, 0.64116, 0 → 0.34564)."""
    return float(np.clip(s_safety * (1.0 - p_delay_) * (1.0 - p_na), 0.0, 1.0))


# ------------------------------------------------------------------------------------------------ head-on
def p_sts(alpha_c, beta_c):
    """P_sts = 1 − [¼(1 − sin α_c)(1 − sin β_c)]²: 0 for port-to-port (−90°, −90°), 1 for
    starboard-to-starboard ([LIN] form, magnitude consistent with [PUB]; Rule 14, head-on)."""
    a, b = np.asarray(alpha_c, float), np.asarray(beta_c, float)
    return np.clip(1.0 - (0.25 * (1.0 - np.sin(a)) * (1.0 - np.sin(b))) ** 2, 0.0, 1.0)[()]


def p_nsb(maneuvered: bool, turn_starboard: float, turn_port: float, p: EvalParams) -> float:
    """P_nsb from the largest starboard (Δχ⁺) and port (Δχ⁻) course deviations [rad] ([REC], Rule 14, head-on):
    0 without a manoeuvre; 1 for a mainly-port turn of at least θ_SM; else clip(1 − Δχ⁺/θ_SM, 0, 1)."""
    if not maneuvered:
        return 0.0
    sm = p.rad("theta_sm")
    if turn_port >= sm and turn_port > turn_starboard:
        return 1.0
    return float(np.clip(1.0 - turn_starboard / sm, 0.0, 1.0))


def s14(p_nsb_: float, p_sts_: float, p_delay_: float, p_na_chi: float, p: EvalParams) -> float:
    """S14 = max(0, 1 − γ_nsb·P_nsb − γ_sts·P_sts)·(1 − P_delay)·(1 − P_Δχ^¬ap) ([PUB]: P_sts 0.086949
    with P_delay 0.25389 → 0.70719; P_sts 0.075006 → 0.955)."""
    base = max(0.0, 1.0 - p.gamma_ho_nsb * p_nsb_ - p.gamma_ho_sts * p_sts_)
    return float(np.clip(base * (1.0 - p_delay_) * (1.0 - p_na_chi), 0.0, 1.0))


# ------------------------------------------------------------------------------------ overtaking, crossing
def p_ah13(alpha_c: float, p: EvalParams) -> float:
    """P_ah13 = 1 if |α_c| < α_ah,OT (the overtaker passed ahead of the overtaken vessel's bow) ([LIN]/[CFG])."""
    return 1.0 if abs(alpha_c) < p.rad("alpha_ahead_ot_absmax") else 0.0


def s13_give_way(s16_: float, p_ah13_: float, p: EvalParams) -> float:
    """OTGW: S13 = max(0, S16 − γ_ah,OT·P_ah13) ([LIN]/[CFG], Rule 13, overtaking)."""
    return float(np.clip(s16_ - p.gamma_ahead_ot * p_ah13_, 0.0, 1.0))


def p_ah15(alpha_c: float, p: EvalParams) -> float:
    """P_ah15 = 1 if α_ah,min < α_c < α_ah,max (the give-way vessel crossed the stand-on vessel's bow)
    ([WOE]/[CFG]/[LIN], Rule 15, crossing)."""
    return 1.0 if p.rad("alpha_ahead_cr_min") < alpha_c < p.rad("alpha_ahead_cr_max") else 0.0


def s15_give_way(s16_: float, p_ah15_: float, p: EvalParams) -> float:
    """CRGW: S15 = max(0, S16 − γ_ah,CR·P_ah15) ([CFG], Rule 15, crossing)."""
    return float(np.clip(s16_ - p.gamma_ahead_cr * p_ah15_, 0.0, 1.0))


# ------------------------------------------------------------------------------------------ stand-on vessel
def stage_penalty(maneuvered: bool, p_chi: float, p_u_up: float, p_u_down: float, compensation: float,
                  p: EvalParams) -> float:
    """P_x of a stand-on stage (Rule 17, stand-on vessel):
    man_x·min(1, γ_Δχ·P_Δχ + γ_ΔU↑·P_ΔU↑ + γ_ΔU↓·P_ΔU↓ + C) in ``reproduce`` mode ([PUB] fit of Table VII),
    man_x·max(0, … − C) in ``intended`` mode."""
    if not maneuvered:
        return 0.0
    total = p.gamma_so_delta_chi * p_chi + p.gamma_so_delta_u_up * p_u_up + p.gamma_so_delta_u_down * p_u_down
    if p.stand_on_mode == "reproduce":
        return float(min(1.0, total + compensation))
    return float(max(0.0, min(1.0, total - compensation)))


def p_port_turn(port_turn: bool, p: EvalParams) -> float:
    """P_pt = γ_pt if the stand-on vessel turned to port (towards a vessel on its port side) in stages 3–4
    ([LIN] value, [PUB] magnitude)."""
    return p.gamma_pt if port_turn else 0.0


def s17(s_safety: float, p_2: float, p_3: float, p_pt: float) -> float:
    """S17 = S_safety·(1 − P_2)·(1 − max(P_3, P_pt)) ([PUB] as a fit: 0.09 and 0.24 of Table VII)."""
    return float(np.clip(s_safety * (1.0 - p_2) * (1.0 - max(p_3, p_pt)), 0.0, 1.0))
