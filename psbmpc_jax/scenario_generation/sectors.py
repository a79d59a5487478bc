"""The geometry of one generated pair: straight tracks, the time the evaluation tool classifies the encounter, the
relative bearing and contact angle then, and whether the evaluation tool's own classification
(:func:`psbmpc_jax.evaltool.geometry.classify`, the sectors of Woerner 2016 as used by Hagen et al. 2023) gives
the requested type with a margin.

Angles in degrees, starboard positive, as in the evaluation tool: the relative bearing β is the bearing of the
target seen from the own-ship relative to the own-ship's course; the contact angle α is the bearing of the
own-ship seen from the target relative to the target's course.  For straight tracks the line of sight turns
monotonically, so a class that holds at the ends of a short time interval (with a margin) holds throughout.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from ..evaltool.geometry import classify
from ..evaltool.params import EvalParams
from .settings import SITUATION_CODES, in_arc

__all__ = ["velocity", "start_time", "pair_angles", "robust_class", "feasible_table", "check_feasible",
           "min_distance", "CHECK_SAMPLES"]

#: Number of times in [t_start, t_start + 2 Δt] (Δt the evaluation's sample interval) at which the class is checked:
#: the evaluation classifies at the first sample inside the stage-2 range, which lies in [t_start, t_start + Δt).
CHECK_SAMPLES = 5


def velocity(course_deg: float, speed: float) -> np.ndarray:
    """[north, east] velocity [m/s] of a ship on ``course_deg`` at ``speed``."""
    c = math.radians(course_deg)
    return np.array([speed * math.cos(c), speed * math.sin(c)])


def start_time(p_rel: np.ndarray, v_rel: np.ndarray, r_stage2: float) -> float:
    """When the evaluation tool's encounter starts: 0 if the ships start within ``r_stage2``, else the first time
    the range |p_rel + v_rel t| falls to it; ``nan`` if it never does."""
    r0 = float(np.hypot(*p_rel))
    if r0 <= r_stage2:
        return 0.0
    a = float(v_rel @ v_rel)
    b = 2.0 * float(p_rel @ v_rel)
    c = r0 * r0 - r_stage2 * r_stage2
    disc = b * b - 4 * a * c
    if a <= 0.0 or disc < 0.0 or b >= 0.0:
        return math.nan
    return (-b - math.sqrt(disc)) / (2 * a)


def pair_angles(p_rel, own_course_deg: float, target_course_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """(β, α) [deg] in (-180, 180] for relative position(s) ``p_rel`` [..., 2] (target minus own-ship)."""
    p = np.asarray(p_rel, float)
    los = np.degrees(np.arctan2(p[..., 1], p[..., 0]))
    beta = 180.0 - np.mod(180.0 - (los - own_course_deg), 360.0)
    alpha = 180.0 - np.mod(180.0 - (los + 180.0 - target_course_deg), 360.0)
    return beta, alpha


_OFFSETS = np.array([(i, j) for i in (-1.0, 0.0, 1.0) for j in (-1.0, 0.0, 1.0)])


def robust_class(kind: str, beta_deg, alpha_deg, u_own, u_target, p: EvalParams, margin_deg: float) -> np.ndarray:
    """True where the evaluation tool classifies the own-ship's situation as ``kind`` for every relative bearing
    and contact angle within ``margin_deg`` of (β, α) (checked at the 9 points β + {-m, 0, m} x α + {-m, 0, m}:
    the sectors are boxes in (β, α), at least 2 x the margin wide, so the corners decide)."""
    b = np.asarray(beta_deg, float)[..., None] + margin_deg * _OFFSETS[:, 0]
    a = np.asarray(alpha_deg, float)[..., None] + margin_deg * _OFFSETS[:, 1]
    u_i = np.broadcast_to(np.asarray(u_own, float)[..., None], b.shape)
    u_j = np.broadcast_to(np.asarray(u_target, float)[..., None], b.shape)
    cls = classify(np.radians(a), np.radians(b), u_i, u_j, p)
    return np.all(cls == SITUATION_CODES[kind], axis=-1)


def min_distance(p_rel: np.ndarray, v_rel: np.ndarray, t_end: float) -> float:
    """Smallest |p_rel + v_rel t| for t in [0, t_end]."""
    vv = float(v_rel @ v_rel)
    t = 0.0 if vv <= 0.0 else min(max(-float(p_rel @ v_rel) / vv, 0.0), t_end)
    return float(np.hypot(*(p_rel + v_rel * t)))


# --------------------------------------------------------------------------------------- what a type allows
@lru_cache(maxsize=32)
def feasible_table(kind: str, p: EvalParams, margin_deg: float) -> np.ndarray:
    """Boolean [360, 360] table over integer (β, α) in [-179, 180] degrees: True where the type holds within
    ceil(margin) degrees around the point (for the overtaking types with the ships' speeds in the right order;
    for the others with either order)."""
    grid = np.arange(-179.0, 181.0)
    b, a = np.meshgrid(grid, grid, indexing="ij")
    code = SITUATION_CODES[kind]
    orders = {"overtaking": ((2.0, 1.0),), "overtaken": ((1.0, 2.0),)}.get(kind, ((1.0, 2.0), (2.0, 1.0)))
    base = np.ones(b.shape, dtype=bool)
    for u_i, u_j in orders:
        base &= classify(np.radians(a), np.radians(b), np.full(b.shape, u_i), np.full(b.shape, u_j), p) == code
    k = int(math.ceil(margin_deg))
    out = base.copy()
    for i in (-k, 0, k):                    # erosion by the margin (the grid wraps around like the angles)
        for j in (-k, 0, k):
            out &= np.roll(base, (i, j), axis=(0, 1))
    return out


def _arc_text(values: np.ndarray) -> str:
    """The integer angles ``values`` (a sorted subset of -179..180) as arcs ``a..b``."""
    if values.size == 0:
        return "none"
    v = np.sort(np.mod(values + 179.0, 360.0) - 179.0)
    gaps = np.flatnonzero(np.diff(v) > 1.0)
    runs = np.split(v, gaps + 1)
    if len(runs) > 1 and runs[0][0] == -179.0 and runs[-1][-1] == 180.0:
        runs = [np.concatenate([runs[-1], runs[0] + 360.0])] + runs[1:-1]
    return ", ".join(f"{r[0]:g}..{r[-1]:g}" for r in runs)


def check_feasible(kind: str, ranges, p: EvalParams, margin_deg: float, where: str) -> None:
    """Refuse ranges whose relative course (and relative bearing, if given) can never give ``kind`` with these
    evaluation parameters: relative course = 180 - α + β, so the sector bounds it.  The message names the field
    and the courses / bearings the type allows (on a 1-degree grid)."""
    ok = feasible_table(kind, p, margin_deg)
    grid = np.arange(-179.0, 181.0)
    b, a = np.meshgrid(grid, grid, indexing="ij")
    course = np.mod(180.0 - a + b, 360.0)
    lo, hi = ranges.relative_course_deg
    sel = ok & (in_arc(course, (lo - 0.5, hi + 0.5)) if hi - lo < 359.0 else ok)
    if not sel.any():
        allowed = _arc_text(np.unique(np.mod(course[ok] + 179.0, 360.0) - 179.0))
        raise ValueError(f"{where}.relative_course_deg {[lo, hi]} can never give a {kind} encounter with these "
                         f"evaluation sectors (margin {margin_deg:g} deg); relative courses that can: {allowed} deg")
    if ranges.relative_bearing_deg is None:
        return
    blo, bhi = ranges.relative_bearing_deg
    in_b = in_arc(b, (blo - 0.5, bhi + 0.5)) if bhi - blo < 359.0 else np.ones_like(ok)
    if not (ok & in_b).any():
        allowed = _arc_text(np.unique(b[ok]))
        raise ValueError(f"{where}.relative_bearing_deg {[blo, bhi]} lies outside the {kind} sector (margin "
                         f"{margin_deg:g} deg); bearings that can: {allowed} deg")
    if not (sel & in_b).any():
        raise ValueError(f"{where}: relative_bearing_deg {[blo, bhi]} and relative_course_deg {[lo, hi]} together "
                         f"can never give a {kind} encounter (contact angle = 180 - relative course + bearing "
                         f"falls outside the sector); widen one of them")
