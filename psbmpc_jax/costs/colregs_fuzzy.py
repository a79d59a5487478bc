"""Smooth-SBMPC COLREGS fuzzy inference system FIS_colregs (Mahipala & Johansen 2024, §V, Tables I-IV,
rules (19)-(21), eq. (22)); docs/smooth_sbmpc.md "Smooth cost components".

Pure, vectorised, differentiable ``jax.numpy`` functions.  Every array input broadcasts against the others;
the output has their common shape.  Angles are radians unless ``angles="deg"`` is passed; inside, the
membership functions are evaluated in degrees (the paper's tables are in degrees).

Inputs of one (target, time) pair:

* ``delta_cog`` = ΔCOG = |wrap(χ_i − χ_o)| ∈ [0, π] (course difference),
* ``rb`` = relative bearing of the target from the own-ship, positive to starboard, in (−π, π],
* ``d``  = distance [m].

:func:`encounter_inputs` computes them from own-ship and target states ``(x, y, χ, U)``.

Algorithm (the documented choices C-000-2, -3, -4, -5, -15)::

    OT = sig(ΔCOG; 67.5°, −1.5317/°)                 CR = sig(ΔCOG; 67.5°, 0.919)·sig(ΔCOG; 157.5°, −0.919)
    HO = sig(ΔCOG; 157.5°, 0.919)                    SB = sig(RB; 0°, 0.919)
    SBAH = sig(RB; 0°, 0.919)·sig(RB; 67.5°, −0.919) CL = sig(d; d_cl, −ln 99 / e_cl)
    T(y) = sig(y; 0.95, 114.878)                     F(y) = sig(y; 0.05, −114.878)
    r1 = clip(min_ε(min_ε(HO, SBAH), CL)),  r2 = clip(min_ε(min_ε(CR, SB), CL)),  r3 = clip(min_ε(1 − SB, 1 − CL))
    r_T = clip(max_ε(r1, r2));  r_F = clip(max_ε(r3, 1 − r_T))  ("default_false")  or  r_F = r3  ("literal")
    agg(y_n) = max_ε(r_T·T(y_n), r_F·F(y_n)),  y_n = n / (N_y − 1)
    μ = Σ y_n agg(y_n) / Σ agg(y_n)

with sig(z; a₁, a₂) = 1 / (1 + exp(−a₂ (z − a₁))), max_ε(a, b) = (a + b + √((a − b)² + ε)) / 2,
min_ε(a, b) = −max_ε(−a, −b) and clip(v) = min(max(v, 0), 1) (crisp).

Smoothness: μ is smooth in (ΔCOG, RB, d) except where a crisp clip is active (rule strengths at 0 or 1),
and the inputs have two kinks/jumps of their own: |·| in ΔCOG at 0 and π (the membership functions are flat
there) and the jump of RB at ±π (dead astern: SB(−180°) ≈ 0 but SB(180°) ≈ 1).  The jump is accepted and
documented; finite-difference checks must stay away from it.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..numerics import safe_sqrt

LN99 = math.log(99.0)
RAD2DEG = 180.0 / math.pi
DEG2RAD = math.pi / 180.0

# Table I-III parameters as printed in the paper ([GIVEN]); every slope is 2 ln 99 / w (1 % -> 99 % over a
# width w: 6°, 10°, 0.08).  Angles in degrees, slopes per degree.
OT_CENTRE, OT_SLOPE = 67.5, -1.5317
CR_LO, CR_HI, CR_SLOPE = 67.5, 157.5, 0.919
HO_CENTRE, HO_SLOPE = 157.5, 0.919
SB_CENTRE, SB_SLOPE = 0.0, 0.919
SBAH_HI = 67.5
MU_TRUE_CENTRE, MU_FALSE_CENTRE, MU_SLOPE = 0.95, 0.05, 114.878   # C-000-3: mu_false = [0.05, -114.878]

#: Defaults ([NOT GIVEN -> PROPOSED]): smooth-max epsilon, output grid size, COLREGS distance, its extension.
DEFAULT_EPS = 1e-6
DEFAULT_N_Y = 201
DEFAULT_D_CL = 40.0
DEFAULT_E_CL = 5.0

COMPLETIONS = ("default_false", "literal")
ANGLE_UNITS = ("rad", "deg")


# ------------------------------------------------------------------------------------------ validation
def concrete_float(value):
    """``float(value)`` when ``value`` is a concrete real number (Python/NumPy scalar, 0-d array, concrete
    JAX scalar), else ``None`` (tracers and arrays with several elements are not validated here)."""
    if isinstance(value, jax.core.Tracer):
        return None
    if isinstance(value, bool):
        return float(value)
    if isinstance(value, (int, float, np.integer, np.floating)):
        return float(value)
    if isinstance(value, (np.ndarray, jax.Array)) and value.ndim == 0 and (
            np.issubdtype(value.dtype, np.floating) or np.issubdtype(value.dtype, np.integer)):
        try:
            return float(value)
        except Exception:  # pragma: no cover - abstract values
            return None
    return None


def check_param(name: str, value, *, lo: float | None = None, hi: float | None = None,
                lo_open: bool = False, hi_open: bool = False) -> None:
    """Raise ``ValueError`` naming ``name`` and the allowed range when the concrete ``value`` is outside it
    (or not finite).  Traced or array values are not checked."""
    if isinstance(value, (str, bytes)):
        raise ValueError(f"{name} must be a real number, got {value!r}")
    v = concrete_float(value)
    if v is None:          # traced, array-valued or a placeholder JAX put there while unflattening
        return
    lo_s = "-inf" if lo is None else f"{lo:g}"
    hi_s = "inf" if hi is None else f"{hi:g}"
    rng = f"{'(' if lo is None or lo_open else '['}{lo_s}, {hi_s}{')' if hi is None or hi_open else ']'}"
    bad = not math.isfinite(v)
    if lo is not None:
        bad |= v <= lo if lo_open else v < lo
    if hi is not None:
        bad |= v >= hi if hi_open else v > hi
    if bad:
        raise ValueError(f"{name} must be finite and in {rng}, got {v!r}")


def check_choice(name: str, value, allowed) -> None:
    if not isinstance(value, str) or value not in allowed:
        raise ValueError(f"{name} must be one of {tuple(allowed)}, got {value!r}")


def check_n_y(n_y) -> None:
    if isinstance(n_y, bool) or not isinstance(n_y, (int, np.integer)) or n_y < 2:
        raise ValueError(f"n_y must be an integer >= 2 (points of the output grid on [0, 1]), got {n_y!r}")


def check_fis_params(d_cl=DEFAULT_D_CL, e_cl=DEFAULT_E_CL, eps=DEFAULT_EPS, n_y=DEFAULT_N_Y,
                     completion="default_false") -> None:
    """Validate the FIS parameters: ``d_cl > 0``, ``e_cl > 0``, ``eps >= 0``, integer ``n_y >= 2``,
    ``completion`` in :data:`COMPLETIONS`."""
    check_param("d_cl", d_cl, lo=0.0, lo_open=True)
    check_param("e_cl", e_cl, lo=0.0, lo_open=True)
    check_param("eps", eps, lo=0.0)
    check_n_y(n_y)
    check_choice("completion", completion, COMPLETIONS)


# ------------------------------------------------------------------------------------------ operators
def sig(z, a1, a2):
    """sig(z; a₁, a₂) = 1 / (1 + exp(−a₂ (z − a₁))), numerically stable (``jax.nn.sigmoid``)."""
    return jax.nn.sigmoid(a2 * (z - a1))


def smooth_max(a, b, eps):
    """max_ε(a, b) = (a + b + √((a − b)² + ε)) / 2 (eq. 30); the exact max for ε = 0 (finite gradient at
    a tie)."""
    diff = a - b
    return 0.5 * (a + b + safe_sqrt(diff * diff + eps))


def smooth_min(a, b, eps):
    """min_ε(a, b) = −max_ε(−a, −b)."""
    return -smooth_max(-a, -b, eps)


def clip01(v):
    """clip(v) = min(max(v, 0), 1) (crisp)."""
    return jnp.clip(v, 0.0, 1.0)


# ------------------------------------------------------------------------------------------ the FIS
class Memberships(NamedTuple):
    """Degrees of membership of one input triple (Tables I-III)."""

    OT: jax.Array
    CR: jax.Array
    HO: jax.Array
    SB: jax.Array
    SBAH: jax.Array
    CL: jax.Array


class RuleStrengths(NamedTuple):
    """Clipped firing strengths: rules (19)-(21) and the two output weights."""

    r1: jax.Array
    r2: jax.Array
    r3: jax.Array
    r_T: jax.Array
    r_F: jax.Array


def memberships(delta_cog_deg, rb_deg, d, d_cl=DEFAULT_D_CL, e_cl=DEFAULT_E_CL) -> Memberships:
    """Membership degrees from ΔCOG [deg], RB [deg] and d [m] (C-000-2: dsigmf = product of a rising and a
    falling sigmoid; C-000-5: CL = sig(d; d_cl, −ln 99 / e_cl), so CL(d_cl) = 0.5 and CL(d_cl + e_cl) = 0.01).
    OT is computed for completeness; the rule base does not use it (NOT OVERTAKEN is implied by CR)."""
    sb = sig(rb_deg, SB_CENTRE, SB_SLOPE)
    return Memberships(
        OT=sig(delta_cog_deg, OT_CENTRE, OT_SLOPE),
        CR=sig(delta_cog_deg, CR_LO, CR_SLOPE) * sig(delta_cog_deg, CR_HI, -CR_SLOPE),
        HO=sig(delta_cog_deg, HO_CENTRE, HO_SLOPE),
        SB=sb,
        SBAH=sb * sig(rb_deg, SBAH_HI, -SB_SLOPE),
        CL=sig(d, d_cl, -LN99 / e_cl),
    )


def rule_strengths(m: Memberships, eps=DEFAULT_EPS, completion: str = "default_false") -> RuleStrengths:
    """Rules (19)-(21) with min_ε for AND, 1 − (·) for NOT, max_ε for the OR of the two "true" rules; every
    strength clipped to [0, 1].  ``completion="default_false"`` (C-000-4) fires "false" with
    max_ε(r3, 1 − r_T), so the FIS reproduces the Boolean original where no rule fires; ``"literal"`` uses
    r3 alone."""
    check_choice("completion", completion, COMPLETIONS)
    r1 = clip01(smooth_min(smooth_min(m.HO, m.SBAH, eps), m.CL, eps))
    r2 = clip01(smooth_min(smooth_min(m.CR, m.SB, eps), m.CL, eps))
    r3 = clip01(smooth_min(1.0 - m.SB, 1.0 - m.CL, eps))
    r_t = clip01(smooth_max(r1, r2, eps))
    r_f = clip01(smooth_max(r3, 1.0 - r_t, eps)) if completion == "default_false" else r3
    return RuleStrengths(r1, r2, r3, r_t, r_f)


def output_grid(n_y: int, dtype=None):
    """y_n = n / (N_y − 1), n = 0..N_y − 1."""
    return jnp.linspace(0.0, 1.0, n_y, dtype=dtype)


def defuzzify(r_t, r_f, eps=DEFAULT_EPS, n_y: int = DEFAULT_N_Y):
    """Centre of gravity (rectangle rule on ``n_y`` points of [0, 1]) of the aggregate
    max_ε(r_T·T(y), r_F·F(y)) (product implication, C-000-15).  An all-zero aggregate (possible only with
    ε = 0 and the literal completion) gives 0.5, the CoG of a flat output."""
    check_n_y(n_y)
    r_t, r_f = jnp.broadcast_arrays(jnp.asarray(r_t), jnp.asarray(r_f))
    y = output_grid(n_y, jnp.result_type(r_t.dtype, float))
    t_y = sig(y, MU_TRUE_CENTRE, MU_SLOPE)
    f_y = sig(y, MU_FALSE_CENTRE, -MU_SLOPE)
    agg = smooth_max(r_t[..., None] * t_y, r_f[..., None] * f_y, eps)
    num = jnp.sum(y * agg, axis=-1)
    den = jnp.sum(agg, axis=-1)
    pos = den > 0
    return jnp.where(pos, num / jnp.where(pos, den, 1.0), 0.5)


def fis_colregs(delta_cog, rb, d, *, d_cl=DEFAULT_D_CL, e_cl=DEFAULT_E_CL, eps=DEFAULT_EPS,
                n_y: int = DEFAULT_N_Y, completion: str = "default_false", angles: str = "rad"):
    """The crisp COLREGS output μ ∈ (0, 1) of FIS_colregs for arrays of (ΔCOG, RB, d).

    Args:
        delta_cog: course difference |wrap(χ_i − χ_o)| ∈ [0, π] (or [0, 180] with ``angles="deg"``).
        rb: relative bearing of the target, positive to starboard, in (−π, π] (or degrees).
        d: own-ship–target distance [m].
        d_cl: COLREGS "close" distance [m] (> 0); e_cl: its extension [m] (> 0, proposed: own-ship length).
        eps: smooth max/min parameter ε (≥ 0; proposed 1e-6). n_y: output grid points (integer ≥ 2).
        completion: ``"default_false"`` (C-000-4, default) or ``"literal"`` (rule (21) only).
        angles: ``"rad"`` (default) or ``"deg"``.
    """
    check_fis_params(d_cl, e_cl, eps, n_y, completion)
    check_choice("angles", angles, ANGLE_UNITS)
    scale = 1.0 if angles == "deg" else RAD2DEG
    dcog, rbv, dv = jnp.broadcast_arrays(jnp.asarray(delta_cog) * scale, jnp.asarray(rb) * scale, jnp.asarray(d))
    rs = rule_strengths(memberships(dcog, rbv, dv, d_cl, e_cl), eps, completion)
    return defuzzify(rs.r_T, rs.r_F, eps, n_y)


# ------------------------------------------------------------------------------------------ geometry
def wrap_to_pi(a):
    """Wrap angles to (−π, π] (+π stays +π: a target dead astern counts as starboard, RB = +180°)."""
    return math.pi - jnp.mod(math.pi - a, 2.0 * math.pi)


def safe_atan2(y, x):
    """atan2 with a finite gradient at (0, 0), where it returns 0."""
    zero = (x == 0) & (y == 0)
    return jnp.where(zero, 0.0, jnp.arctan2(jnp.where(zero, 0.0, y), jnp.where(zero, 1.0, x)))


def encounter_inputs_xy(own_x, own_y, own_chi, tgt_x, tgt_y, tgt_chi):
    """(ΔCOG [rad] ∈ [0, π], RB [rad] ∈ (−π, π], d [m]) from positions and courses (broadcast).

    ΔCOG = |wrap(χ_i − χ_o)|, RB = wrap(atan2(y_i − y_o, x_i − x_o) − χ_o) (NED: x north, y east, RB > 0 to
    starboard), d = ‖p_i − p_o‖.  At d = 0 the bearing is taken as dead ahead (RB = 0); value and gradient
    stay finite."""
    dx, dy = tgt_x - own_x, tgt_y - own_y
    zero = (dx == 0) & (dy == 0)
    d = safe_sqrt(dx * dx + dy * dy)
    bearing = jnp.where(zero, own_chi, safe_atan2(dy, dx))
    rb = wrap_to_pi(bearing - own_chi)
    dcog = jnp.abs(wrap_to_pi(tgt_chi - own_chi))
    return dcog, rb, d


def encounter_inputs(own_state, target_state):
    """(ΔCOG, RB, d) from state arrays ``[..., 4]`` = (x, y, χ, U) (speeds are not used: the FIS inputs
    depend on positions and courses only).  The two arrays broadcast."""
    o, t = jnp.asarray(own_state), jnp.asarray(target_state)
    if o.shape[-1] != 4 or t.shape[-1] != 4:
        raise ValueError(f"states must be [..., 4] (x, y, chi, U), got shapes {o.shape} and {t.shape}")
    return encounter_inputs_xy(o[..., 0], o[..., 1], o[..., 2], t[..., 0], t[..., 1], t[..., 2])


def fis_colregs_states(own_state, target_state, **fis_kwargs):
    """μ of FIS_colregs for own-ship and target states ``[..., 4]`` (x, y, χ, U); keywords as
    :func:`fis_colregs` (``angles`` is fixed to radians)."""
    dcog, rb, d = encounter_inputs(own_state, target_state)
    return fis_colregs(dcog, rb, d, **fis_kwargs)


__all__ = [
    "DEFAULT_EPS", "DEFAULT_N_Y", "DEFAULT_D_CL", "DEFAULT_E_CL", "COMPLETIONS", "Memberships", "RuleStrengths",
    "sig", "smooth_max", "smooth_min", "clip01", "memberships", "rule_strengths", "output_grid", "defuzzify",
    "fis_colregs", "wrap_to_pi", "safe_atan2", "encounter_inputs_xy", "encounter_inputs", "fis_colregs_states",
    "check_fis_params", "check_param", "check_choice", "check_n_y", "concrete_float",
]
