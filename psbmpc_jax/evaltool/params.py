"""Parameters of the COLREGS evaluation (one frozen dataclass) and the preset registry.

Every field carries its unit in its name (``_m``, ``_deg``, ``_mps`` ...); angles are given in degrees here, at
the boundary, and converted to radians once where they are used.  The defaults are those of
the ``evaluator.yaml`` of the original tool (tagged [CFG]; the tags are explained in ``docs/evaltool.md``), except the
sampling interval: 1 s instead of the yaml's 2 s, so that per-sample and per-second rates agree (``docs/evaltool.md``,
"Choices made where our specification is ambiguous", item 1).

Presets:

* ``default``: the yaml's defaults (open-water ranges of the original tool's configuration file).
* ``inland_small``: the twelve values of Table V of the Smooth-SBMPC paper (Mahipala & Johansen 2024: 80/45/16 m stages,
  7/6/5/4 m CPA ranges, ε_U 0.2 m/s, Δχ_ap 13°, Δχ_md 1°, ΔU_ap 0.2, ΔU_md 0.1), everything else default.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any
from dataclasses import dataclass, fields

__all__ = ["EvalParams", "PRESETS", "get_params", "preset_names", "STAND_ON_MODES", "DELAY_REFERENCES",
           "PORT_TURN_STAGES", "RANGE_FIELDS", "scaled_params"]

#: Allowed values of :attr:`EvalParams.stand_on_mode` (Rule 17, stand-on vessel; ``docs/evaltool.md``, choice 13).
STAND_ON_MODES = ("reproduce", "intended")
#: Allowed values of :attr:`EvalParams.delay_reference` (give-way vessel, Rules 8 and 16; ``docs/evaltool.md``, choice
#: 14).
DELAY_REFERENCES = ("encounter_start", "stage3")
#: Allowed values of :attr:`EvalParams.port_turn_stages` (Rule 17(c); ``docs/evaltool.md``, choice 20).
PORT_TURN_STAGES = ("3-4", "4")


@dataclass(frozen=True)
class EvalParams:
    """All parameters of the evaluation (``docs/evaltool.md``, "Parameters"; yaml key in brackets).

    Sampling and manoeuvre detection:
        sample_interval_s: Δt of the common grid every vessel is resampled onto [s] (``sample_interval``; the
            yaml has 2.0 s; we use 1.0 s so that per-sample and per-second rates agree).
        epsilon_speed_mps: ε_U, below this speed a vessel is "not moving" and no course manoeuvre starts
            (``epsilon_speed``).
        epsilon_d_course_deg_s: ε_dχ, course-rate threshold of a course manoeuvre (``epsilon_d_course``).
        epsilon_d_speed_mps2: ε_dU, acceleration threshold of a speed manoeuvre (``epsilon_d_speed``).
        smoothing_sigma_samples: σ of the Gaussian filter applied to course and speed before differentiating
            (hard-coded 2 samples in the tool; 0 disables smoothing).
        course_end_below_threshold: also end a course manoeuvre when |χ'| < ε_dχ ([REC] for noise-free data;
            False gives the tool's rule: end on a sign change of the rate or two exact zeros only).

    Stages and CPA ranges:
        r_stage2_m, r_stage3_m, r_stage4_m: stage radii (``r_colregs_{2,3,4}_max``), r2 > r3 > r4 > 0.
        r_pref_m, r_min_m, r_nm_m, r_col_m: preferred / minimum / near-miss / collision CPA ranges,
            r_pref > r_min > r_nm > r_col >= 0.

    Manoeuvre size:
        delta_course_md_deg, delta_course_app_deg: minimum detectable and readily apparent course change.
        delta_speed_md_rel, delta_speed_app_rel: the same for the relative speed change (fraction of the speed
            at the reference sample).

    Classification:
        theta_crit_ot_deg, theta_crit_ho_deg, theta_crit_cr_deg, theta_ot_min_deg, theta_ot_max_deg: the
            sector limits of Woerner's Algorithm 5 (starboard-positive angles).
        overtaking_speed_margin_mps: the overtaking speed tests need U_i > U_j + margin (resp. U_i + margin <
            U_j); Hagen's AIS code used 0.2 m/s, our default is 0.
        scan_for_situation: True: the encounter starts at the first sample after detection whose geometry is
            not NAR ([REC]); False: classify at the detection sample only ([LIN]).
        stationary_contact_angle_deg: contact angle α used when the other vessel is not moving (Hagen's code:
            180°).

    Penalty bands and weights:
        theta_sm_deg: θ_SM, starboard turn that clears P_nsb.
        alpha_ahead_cr_min_deg, alpha_ahead_cr_max_deg: P_ah15 band of the contact angle at CPA.
        alpha_ahead_ot_absmax_deg: P_ah13 band |α_c| < this.
        alpha_cut_deg, beta_cut_deg: cut angles of S_α and S_β.
        gamma_min, gamma_nm, gamma_col: S_r weights; gamma_alpha, gamma_beta: S_Θ weights;
        gamma_ahead_ot, gamma_ahead_cr: weights of P_ah13 and P_ah15; gamma_ho_sts, gamma_ho_nsb: weights of
        P_sts and P_nsb in S14; gamma_na_delta_chi, gamma_na_delta_u: non-apparent penalty weights;
        gamma_so_delta_chi, gamma_so_delta_u_up, gamma_so_delta_u_down: stand-on stage penalty weights;
        gamma_c: give-way compensation C_x,gw; gamma_pt: port-turn penalty of the stand-on vessel.

    Choices where the sources disagree (``docs/evaltool.md``, "Choices made where our specification is ambiguous"):
        stand_on_mode: ``"reproduce"`` (P_x = man_x·min(1, Σ + C), fits the SBMPC Table VII) or ``"intended"``
            (P_x = man_x·max(0, Σ − C)).
        delay_reference: ``"encounter_start"`` (P_delay = (r_det − r_man)/(r_det − r_cpa), Woerner) or
            ``"stage3"`` ((r_Stage3 − r_man)/(r_Stage3 − r_cpa)).
        risk_gate: skip the COLREG scores of an encounter whose constant-velocity DCPA at its start is at least
            r_pref ([REC], off by default: no source gates by risk; choice 16).
        port_turn_stages: where P_pt looks for the stand-on vessel's port turn: ``"3-4"`` (a manoeuvre overlapping
            stages 3-4: the evaluation tool's reference implementation, the default) or ``"4"`` (stage 4 only:
            the tool's score table, "S_pt: score for stand-on behavior during Stage 4"; choice 20).
    """

    sample_interval_s: float = 1.0
    epsilon_speed_mps: float = 0.2
    epsilon_d_course_deg_s: float = 0.3
    epsilon_d_speed_mps2: float = 0.05
    smoothing_sigma_samples: float = 2.0
    course_end_below_threshold: bool = True

    r_stage2_m: float = 2500.0
    r_stage3_m: float = 1100.0
    r_stage4_m: float = 200.0
    r_pref_m: float = 190.0
    r_min_m: float = 100.0
    r_nm_m: float = 50.0
    r_col_m: float = 30.0

    delta_course_md_deg: float = 2.0
    delta_course_app_deg: float = 30.0
    delta_speed_md_rel: float = 0.2
    delta_speed_app_rel: float = 0.5

    theta_crit_ot_deg: float = 45.0
    theta_crit_ho_deg: float = 13.0
    theta_crit_cr_deg: float = -10.0
    theta_ot_min_deg: float = 112.5
    theta_ot_max_deg: float = 247.5
    overtaking_speed_margin_mps: float = 0.0
    scan_for_situation: bool = True
    stationary_contact_angle_deg: float = 180.0

    theta_sm_deg: float = 10.0
    alpha_ahead_cr_min_deg: float = -25.0
    alpha_ahead_cr_max_deg: float = 165.0
    alpha_ahead_ot_absmax_deg: float = 45.0
    alpha_cut_deg: float = 90.0
    beta_cut_deg: float = 90.0

    gamma_min: float = 0.2
    gamma_nm: float = 0.3
    gamma_col: float = 0.5
    gamma_alpha: float = 0.25
    gamma_beta: float = 0.75
    gamma_ahead_ot: float = 0.3
    gamma_ahead_cr: float = 0.5
    gamma_ho_sts: float = 0.6
    gamma_ho_nsb: float = 0.4
    gamma_na_delta_chi: float = 0.5
    gamma_na_delta_u: float = 0.5
    gamma_so_delta_chi: float = 0.5
    gamma_so_delta_u_up: float = 0.25
    gamma_so_delta_u_down: float = 0.25
    gamma_c: float = 0.2
    gamma_pt: float = 0.7

    stand_on_mode: str = "reproduce"
    delay_reference: str = "encounter_start"
    risk_gate: bool = False
    port_turn_stages: str = "3-4"

    def __post_init__(self):
        _validate(self)

    def replace(self, **changes) -> "EvalParams":
        """A copy with ``changes`` applied (validated; an unknown name raises ValueError)."""
        unknown = sorted(set(changes) - {f.name for f in fields(self)})
        if unknown:
            raise ValueError(f"unknown EvalParams field(s): {', '.join(unknown)}")
        return dataclasses.replace(self, **changes)

    def as_dict(self) -> dict:
        """``{field: value}`` (JSON-ready)."""
        return dataclasses.asdict(self)

    def rad(self, name: str) -> float:
        """The angle field ``<name>_deg`` in radians (``p.rad("theta_sm")``)."""
        return math.radians(getattr(self, f"{name}_deg"))


# ------------------------------------------------------------------------------------------------ validation
_GAMMAS = ("gamma_min", "gamma_nm", "gamma_col", "gamma_alpha", "gamma_beta", "gamma_ahead_ot", "gamma_ahead_cr",
           "gamma_ho_sts", "gamma_ho_nsb", "gamma_na_delta_chi", "gamma_na_delta_u", "gamma_so_delta_chi",
           "gamma_so_delta_u_up", "gamma_so_delta_u_down", "gamma_c", "gamma_pt")


def _check(p: EvalParams, name: str, lo: float, hi: float, *, lo_open=False, hi_open=False, note=""):
    """Raise ValueError unless ``lo (<|<=) p.name (<|<=) hi``; the message names the field and the range."""
    v = getattr(p, name)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ValueError(f"EvalParams.{name} must be a finite number, got {v!r}")
    ok = (v > lo if lo_open else v >= lo) and (v < hi if hi_open else v <= hi)
    if not ok:
        rng = f"{'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"
        raise ValueError(f"EvalParams.{name} must be in {rng}{note}, got {v!r}")


def _validate(p: EvalParams) -> None:
    inf = math.inf
    _check(p, "sample_interval_s", 0, inf, lo_open=True, hi_open=True)
    _check(p, "epsilon_speed_mps", 0, inf, hi_open=True)
    _check(p, "epsilon_d_course_deg_s", 0, inf, lo_open=True, hi_open=True)
    _check(p, "epsilon_d_speed_mps2", 0, inf, lo_open=True, hi_open=True)
    _check(p, "smoothing_sigma_samples", 0, 50)
    _check(p, "r_stage4_m", 0, inf, lo_open=True, hi_open=True)
    _check(p, "r_stage3_m", p.r_stage4_m, inf, lo_open=True, hi_open=True, note=" (above r_stage4_m)")
    _check(p, "r_stage2_m", p.r_stage3_m, inf, lo_open=True, hi_open=True, note=" (above r_stage3_m)")
    _check(p, "r_col_m", 0, inf, hi_open=True)
    _check(p, "r_nm_m", p.r_col_m, inf, lo_open=True, hi_open=True, note=" (above r_col_m)")
    _check(p, "r_min_m", p.r_nm_m, inf, lo_open=True, hi_open=True, note=" (above r_nm_m)")
    _check(p, "r_pref_m", p.r_min_m, inf, lo_open=True, hi_open=True, note=" (above r_min_m)")
    _check(p, "delta_course_md_deg", 0, 180)
    _check(p, "delta_course_app_deg", p.delta_course_md_deg, 180, lo_open=True, note=" (above delta_course_md_deg)")
    _check(p, "delta_speed_md_rel", 0, 1)
    _check(p, "delta_speed_app_rel", p.delta_speed_md_rel, 1, lo_open=True, note=" (above delta_speed_md_rel)")
    _check(p, "theta_crit_ot_deg", 0, 90, lo_open=True)
    _check(p, "theta_crit_ho_deg", 0, 90, lo_open=True)
    _check(p, "theta_crit_cr_deg", -90, 90)
    _check(p, "theta_ot_min_deg", 90, 180, hi_open=True)
    _check(p, "theta_ot_max_deg", 180, 270, lo_open=True)
    _check(p, "overtaking_speed_margin_mps", 0, inf, hi_open=True)
    _check(p, "stationary_contact_angle_deg", -180, 180)
    _check(p, "theta_sm_deg", 0, 180, lo_open=True)
    _check(p, "alpha_ahead_cr_min_deg", -180, 180)
    _check(p, "alpha_ahead_cr_max_deg", p.alpha_ahead_cr_min_deg, 180, lo_open=True,
           note=" (above alpha_ahead_cr_min_deg)")
    _check(p, "alpha_ahead_ot_absmax_deg", 0, 180)
    _check(p, "alpha_cut_deg", 0, 180, lo_open=True)
    _check(p, "beta_cut_deg", 0, 180, lo_open=True)
    for g in _GAMMAS:
        _check(p, g, 0, 1)
    for name in ("course_end_below_threshold", "scan_for_situation", "risk_gate"):
        if not isinstance(getattr(p, name), bool):
            raise ValueError(f"EvalParams.{name} must be True or False, got {getattr(p, name)!r}")
    if p.stand_on_mode not in STAND_ON_MODES:
        raise ValueError(f"EvalParams.stand_on_mode must be one of {STAND_ON_MODES}, got {p.stand_on_mode!r}")
    if p.delay_reference not in DELAY_REFERENCES:
        raise ValueError(f"EvalParams.delay_reference must be one of {DELAY_REFERENCES}, got {p.delay_reference!r}")
    if p.port_turn_stages not in PORT_TURN_STAGES:
        raise ValueError(f"EvalParams.port_turn_stages must be one of {PORT_TURN_STAGES}, got {p.port_turn_stages!r}")


# --------------------------------------------------------------------------------------------------- presets
#: The Smooth-SBMPC paper's Table V (Mahipala & Johansen 2024): the twelve values it changed from the tool's defaults.
INLAND_SMALL_CHANGES: dict[str, Any] = dict(
    r_stage2_m=80.0, r_stage3_m=45.0, r_stage4_m=16.0,
    r_pref_m=7.0, r_min_m=6.0, r_nm_m=5.0, r_col_m=4.0,
    epsilon_speed_mps=0.2,
    delta_course_app_deg=13.0, delta_course_md_deg=1.0,
    delta_speed_app_rel=0.2, delta_speed_md_rel=0.1,
)

#: name -> parameters.
PRESETS: dict[str, EvalParams] = {
    "default": EvalParams(),
    "inland_small": EvalParams(**INLAND_SMALL_CHANGES),
}


def preset_names() -> tuple[str, ...]:
    return tuple(PRESETS)


def get_params(preset: str | EvalParams | None = "default", **overrides) -> EvalParams:
    """The preset ``preset`` (a name of :data:`PRESETS`, or an :class:`EvalParams` itself) with ``overrides``
    applied.  Raises ValueError for an unknown preset or field, or an invalid value."""
    if preset is None:
        preset = "default"
    if isinstance(preset, EvalParams):
        base = preset
    elif preset in PRESETS:
        base = PRESETS[preset]
    else:
        raise ValueError(f"unknown EvalTool preset {preset!r}; known: {', '.join(PRESETS)}")
    return base.replace(**overrides) if overrides else base


#: The stage radii and CPA ranges (the fields :func:`scaled_params` multiplies).
RANGE_FIELDS = ("r_stage2_m", "r_stage3_m", "r_stage4_m", "r_pref_m", "r_min_m", "r_nm_m", "r_col_m")


def scaled_params(preset: str | EvalParams | None = "default", range_scale: float = 1.0, **overrides) -> EvalParams:
    """:func:`get_params` with the preset's :data:`RANGE_FIELDS` multiplied by ``range_scale`` (> 0) before the
    ``overrides`` apply: one knob to carry the open-water ranges to another ship size (e.g. 5/30 for vessels whose
    collision distance is 5 m against the default r_col of 30 m)."""
    if isinstance(range_scale, bool) or not isinstance(range_scale, (int, float)) or not (
            math.isfinite(range_scale) and range_scale > 0):
        raise ValueError(f"range_scale must be a finite number > 0, got {range_scale!r}")
    base = get_params(preset)
    return base.replace(**({k: getattr(base, k) * range_scale for k in RANGE_FIELDS} | overrides))
