"""Pair geometry (range, relative bearing β, contact angle α), stages and the COLREGS classification
(``docs/evaltool.md``, "Pipeline" steps 3, 4 and 6), vectorised over the samples of a pair of vessels.

Angles are starboard-positive and wrapped to (−π, π] (as in Woerner's and the tool's own code; ``docs/evaltool.md``,
choice 17).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..numerics import wrap_angle_host
from .params import EvalParams

__all__ = ["wrap", "PairGeometry", "pair_geometry", "stages", "classify", "SITUATIONS", "GIVE_WAY", "STAND_ON",
           "both_passed"]

#: Situation codes (Pipeline step 6): i overtaken (stand-on), i overtaking (give-way), head-on, crossing give-way,
#: crossing stand-on, no applicable rule.
SITUATIONS = ("OTSO", "OTGW", "HO", "CRGW", "CRSO", "NAR")
#: Situations in which the evaluated vessel has a give-way role (HO: both give way).
GIVE_WAY = frozenset({"OTGW", "HO", "CRGW"})
#: Situations in which the evaluated vessel stands on.
STAND_ON = frozenset({"OTSO", "CRSO"})


def wrap(a):
    """Angle(s) wrapped to (−π, π] (:func:`psbmpc_jax.numerics.wrap_angle_host` with ``include_pi``)."""
    return wrap_angle_host(np.asarray(a, float), include_pi=True)[()]


@dataclass(frozen=True)
class PairGeometry:
    """Per-sample geometry of vessel i (evaluated) against vessel j, arrays ``[n]``.

    Attributes:
        r: range [m].
        beta: relative bearing of j seen from i, relative to i's course [rad].
        alpha: contact angle: bearing of i seen from j, relative to j's course [rad] (the configured
            stationary contact angle where j does not move).
    """

    r: np.ndarray
    beta: np.ndarray
    alpha: np.ndarray


def pair_geometry(north, east, course, speed, i: int, j: int, p: EvalParams) -> PairGeometry:
    """Range, β and α of vessel ``i`` against ``j`` from ``[V, n]`` arrays (Pipeline step 3)."""
    dn, de = north[j] - north[i], east[j] - east[i]
    r = np.hypot(dn, de)
    los = np.arctan2(de, dn)                                       # bearing i -> j
    beta = wrap(los - course[i])
    alpha = wrap(los + np.pi - course[j])
    alpha = np.where(speed[j] < p.epsilon_speed_mps, p.rad("stationary_contact_angle"), alpha)
    return PairGeometry(r=r, beta=np.asarray(beta, float), alpha=np.asarray(alpha, float))


def stages(r, p: EvalParams) -> np.ndarray:
    """Stage 1–4 of every sample from the range alone (Pipeline step 4)."""
    r = np.asarray(r, float)
    return (1 + (r <= p.r_stage2_m).astype(int) + (r <= p.r_stage3_m) + (r <= p.r_stage4_m)).astype(int)


def classify(alpha, beta, u_i, u_j, p: EvalParams) -> np.ndarray:
    """The situation of i towards j per sample (array of :data:`SITUATIONS` strings), first match wins in
    the order OTSO, OTGW, HO, CRGW, CRSO, else NAR ([WOE]/[LIN], Pipeline step 6)."""
    a, b = np.degrees(np.asarray(alpha, float)), np.degrees(np.asarray(beta, float))
    a360, b360 = np.mod(a, 360.0), np.mod(b, 360.0)
    u_i, u_j = np.asarray(u_i, float), np.asarray(u_j, float)
    ot_min, ot_max = p.theta_ot_min_deg, p.theta_ot_max_deg
    margin = p.overtaking_speed_margin_mps
    tests = [
        ("OTSO", (ot_min < b360) & (b360 < ot_max) & (np.abs(a) < p.theta_crit_ot_deg) & (u_i + margin < u_j)),
        ("OTGW", (ot_min < a360) & (a360 < ot_max) & (np.abs(b) < p.theta_crit_ot_deg) & (u_i > u_j + margin)),
        ("HO", (np.abs(b) < p.theta_crit_ho_deg) & (np.abs(a) < p.theta_crit_ho_deg)),
        ("CRGW", (0 <= b) & (b <= ot_min) & (-ot_min <= a) & (a <= p.theta_crit_cr_deg)),
        ("CRSO", (0 < a) & (a < ot_min) & (-ot_min < b) & (b <= p.theta_crit_cr_deg)),
    ]
    out = np.full(np.broadcast(a, b).shape, "NAR", dtype=object)
    done = np.zeros(out.shape, dtype=bool)
    for name, hit in tests:
        sel = hit & ~done
        out[sel] = name
        done |= sel
    return out


def both_passed(alpha, beta, p: EvalParams) -> np.ndarray:
    """True where each vessel lies more than 22.5° abaft the other's beam (|β| and |α| > θ_OT,min) ([LIN],
    Pipeline step 5)."""
    lim = p.rad("theta_ot_min")
    return (np.abs(np.asarray(beta, float)) > lim) & (np.abs(np.asarray(alpha, float)) > lim)
