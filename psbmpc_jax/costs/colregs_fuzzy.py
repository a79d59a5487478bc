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

Algorithm (with our readings SM-2, SM-3, SM-4, SM-5 and SM-15 of docs/algorithm.md §12 where the paper's printed
tables are ambiguous)::

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

Evaluation (speed; the same μ to float rounding): :func:`fis_colregs` sums the CoG by :func:`defuzzify_fast` —
the linear parts of max_ε from precomputed moments, the square roots explicitly at the ~40 % of grid points
where T or F is not negligible and by a Taylor series elsewhere, with a hand-written JVP — and computes the
geometry with a vectorised atan2 (:func:`atan2_poly`) and a ``ceil``-based :func:`wrap_to_pi`;
:func:`defuzzify` is the literal definition.

Smoothness: μ is smooth in (ΔCOG, RB, d) except where a crisp clip is active (rule strengths at 0 or 1),
and the inputs have two kinks/jumps of their own: |·| in ΔCOG at 0 and π (the membership functions are flat
there) and the jump of RB at ±π (dead astern: SB(−180°) ≈ 0 but SB(180°) ≈ 1).  The jump is accepted and
documented; finite-difference checks must stay away from it.
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from ..numerics import safe_sqrt

LN99 = math.log(99.0)
RAD2DEG = 180.0 / math.pi
DEG2RAD = math.pi / 180.0

# Table I-III parameters as printed in the paper; every slope is 2 ln 99 / w (1 % -> 99 % over a
# width w: 6°, 10°, 0.08).  Angles in degrees, slopes per degree.
OT_CENTRE, OT_SLOPE = 67.5, -1.5317
CR_LO, CR_HI, CR_SLOPE = 67.5, 157.5, 0.919
HO_CENTRE, HO_SLOPE = 157.5, 0.919
SB_CENTRE, SB_SLOPE = 0.0, 0.919
SBAH_HI = 67.5
#: SM-3 (docs/algorithm.md §12): mu_false printed "[0, 05 114.878, 0, 1]", read as [0.05, -114.878].
MU_TRUE_CENTRE, MU_FALSE_CENTRE, MU_SLOPE = 0.95, 0.05, 114.878

#: Defaults (our proposals: the paper gives none): smooth-max epsilon, output grid size, COLREGS distance, its
#: extension.
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
    """Membership degrees from ΔCOG [deg], RB [deg] and d [m] (SM-2: dsigmf = product of a rising and a falling
    sigmoid; SM-5: CL = sig(d; d_cl, −ln 99 / e_cl), so CL(d_cl) = 0.5 and CL(d_cl + e_cl) = 0.01). OT is computed for
    completeness; the rule base does not use it (NOT OVERTAKEN is implied by CR)."""
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
    strength clipped to [0, 1]. ``completion="default_false"`` (our completion SM-4: the printed rules leave regions
    where none fires) fires "false" with max_ε(r3, 1 − r_T), so the FIS reproduces the Boolean original where no rule
    fires; ``"literal"`` uses r3 alone."""
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
    max_ε(r_T·T(y), r_F·F(y)) (product implication, our reading SM-15).  An all-zero aggregate (possible only with
    ε = 0 and the literal completion) gives 0.5, the CoG of a flat output.  Evaluated literally (every grid
    point); :func:`defuzzify_fast` computes the same value faster for strengths in [0, 1]."""
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


#: :func:`defuzzify_fast`'s split evaluation: grid points where both output memberships are <= FAST_TAU are the
#: "middle" (summed by a three-term Taylor series of the square root about sqrt(eps)); it is used when
#: eps >= FAST_EPS_MIN, where the series' relative error (TAU^2/eps)^3/16 is below float64 rounding.
FAST_TAU = 1e-7
FAST_EPS_MIN = 1e-9


@functools.lru_cache(maxsize=None)
def _fast_tables(n_y: int):
    """Float64 constants of the split evaluation for ``n_y`` grid points: the outer points (y, T, F) and the
    moment sums of the linear parts and of the middle points' Taylor series."""
    y = np.linspace(0.0, 1.0, n_y)
    t = 1.0 / (1.0 + np.exp(-MU_SLOPE * (y - MU_TRUE_CENTRE)))
    f = 1.0 / (1.0 + np.exp(MU_SLOPE * (y - MU_FALSE_CENTRE)))
    mid = np.maximum(t, f) <= FAST_TAU
    out = ~mid
    tm, fm = t[mid], f[mid]
    powers = (np.ones_like(tm), tm * tm, tm * fm, fm * fm, tm ** 4, tm ** 3 * fm, tm * tm * fm * fm, tm * fm ** 3,
              fm ** 4)
    moments = tuple(tuple(float(np.sum(w * v)) for v in powers) for w in (np.ones_like(tm), y[mid]))
    linear = (float(t.sum()), float(f.sum()), float((y * t).sum()), float((y * f).sum()))
    return tuple(zip(y[out].tolist(), t[out].tolist(), f[out].tolist())), moments, linear


def _split_core(r_t, r_f, eps, n_y: int, derivs: bool):
    """The CoG of :func:`defuzzify` for eps >= FAST_EPS_MIN, in one elementwise pass; with ``derivs`` also
    its partial derivatives with respect to (r_T, r_F, ε), accumulated in the same pass.

    With a_n = r_T T(y_n), b_n = r_F F(y_n): max_ε(a, b) = (a + b + √((a − b)² + ε))/2, so both sums are
    linear in (r_T, r_F) (precomputed moments of T and F) plus S_w = Σ w_n √(x_n² + ε), x_n = a_n − b_n,
    w ∈ {1, y}.  S_w is summed explicitly over the outer grid points (unrolled: one fused loop over the
    pairs, ~78 square roots instead of 201 for N_y = 201) and by √ε (1 + u/2 − u²/8), u = x²/ε, over the
    middle points (|x_n| <= FAST_TAU): there u <= 1e-5, and the omitted term u³/16 is below float64
    rounding.  The series' sums are polynomials in (r_T, r_F) with precomputed moments."""
    outer, moments, linear = _fast_tables(n_y)
    dt = r_t.dtype
    c = lambda v: jnp.asarray(v, dt)  # noqa: E731
    zero = jnp.zeros_like(r_t)
    s0 = s1 = zero
    if derivs:
        ga0 = ga1 = gb0 = gb1 = ge0 = ge1 = zero
    for y_n, t_n, f_n in outer:
        x = c(t_n) * r_t - c(f_n) * r_f
        if derivs:
            inv = lax.rsqrt(x * x + eps)
            sq = (x * x + eps) * inv
            xi = x * inv
            ga0, ga1 = ga0 + c(t_n) * xi, ga1 + c(y_n * t_n) * xi
            gb0, gb1 = gb0 - c(f_n) * xi, gb1 - c(y_n * f_n) * xi
            ge0, ge1 = ge0 + inv, ge1 + c(y_n) * inv
        else:
            sq = jnp.sqrt(x * x + eps)
        s0 = s0 + sq
        s1 = s1 + c(y_n) * sq
    a, b = r_t, r_f
    a2, b2, ab = a * a, b * b, a * b
    se = jnp.sqrt(eps)

    def middle(m):
        m = [c(v) for v in m]
        x2 = a2 * m[1] - 2.0 * ab * m[2] + b2 * m[3]
        x4 = a2 * a2 * m[4] - 4.0 * a2 * ab * m[5] + 6.0 * a2 * b2 * m[6] - 4.0 * ab * b2 * m[7] + b2 * b2 * m[8]
        val = se * m[0] + x2 / (2.0 * se) - x4 / (8.0 * eps * se)
        if not derivs:
            return val, None
        x2a = 2.0 * (a * m[1] - b * m[2])
        x2b = 2.0 * (b * m[3] - a * m[2])
        x4a = 4.0 * (a2 * a * m[4] - 3.0 * a2 * b * m[5] + 3.0 * a * b2 * m[6] - b2 * b * m[7])
        x4b = 4.0 * (b2 * b * m[8] - 3.0 * b2 * a * m[7] + 3.0 * b * a2 * m[6] - a2 * a * m[5])
        va = x2a / (2.0 * se) - x4a / (8.0 * eps * se)
        vb = x2b / (2.0 * se) - x4b / (8.0 * eps * se)
        ve = m[0] / (2.0 * se) - x2 / (4.0 * eps * se) + 3.0 * x4 / (16.0 * eps * eps * se)
        return val, (va, vb, ve)

    (m0, d0), (m1, d1) = middle(moments[0]), middle(moments[1])
    s0, s1 = s0 + m0, s1 + m1
    t_sum, f_sum, yt_sum, yf_sum = (c(v) for v in linear)
    den = a * t_sum + b * f_sum + s0          # twice the denominator: >= sqrt(eps) N_y > 0
    mu = (a * yt_sum + b * yf_sum + s1) / den
    if not derivs:
        return mu
    # d/dv of the explicit sums of sqrt((a t - b f)^2 + eps): x t / sq, -x f / sq and 1 / (2 sq)
    d_a = ((yt_sum + ga1 + d1[0]) - mu * (t_sum + ga0 + d0[0])) / den
    d_b = ((yf_sum + gb1 + d1[1]) - mu * (f_sum + gb0 + d0[1])) / den
    d_e = ((0.5 * ge1 + d1[2]) - mu * (0.5 * ge0 + d0[2])) / den
    return mu, d_a, d_b, d_e


@functools.partial(jax.custom_jvp, nondiff_argnums=(3,))
def _defuzzify_split(r_t, r_f, eps, n_y: int):
    """:func:`_split_core`'s CoG, with a hand-written JVP: the partial derivatives are accumulated in the same
    fused pass as the value, so reverse mode only multiplies by them (autodiff through the ~80 unrolled
    terms would emit hundreds of small kernels)."""
    return _split_core(r_t, r_f, eps, n_y, derivs=False)


@_defuzzify_split.defjvp
def _defuzzify_split_jvp(n_y, primals, tangents):
    r_t, r_f, eps = primals
    mu, d_a, d_b, d_e = _split_core(r_t, r_f, eps, n_y, derivs=True)
    t_a, t_b, t_e = tangents
    return mu, d_a * t_a + d_b * t_b + d_e * t_e


def defuzzify_fast(r_t, r_f, eps=DEFAULT_EPS, n_y: int = DEFAULT_N_Y):
    """:func:`defuzzify` for rule strengths ``r_t, r_f`` in [0, 1] (as :func:`rule_strengths` clips them), to
    float rounding, faster: by :func:`_defuzzify_split` when ε >= :data:`FAST_EPS_MIN` (a traced ε chooses at
    run time with ``lax.cond``; the choice does not depend on the strengths, so it stays a branch under
    ``vmap`` over them), else literally.  Strengths outside [0, 1] may lose accuracy: use :func:`defuzzify`."""
    check_n_y(n_y)
    r_t, r_f = jnp.broadcast_arrays(jnp.asarray(r_t), jnp.asarray(r_f))
    dt = jnp.result_type(r_t.dtype, float)
    r_t, r_f = r_t.astype(dt), r_f.astype(dt)
    e = concrete_float(eps)
    if e is not None:
        return _defuzzify_split(r_t, r_f, e, n_y) if e >= FAST_EPS_MIN else defuzzify(r_t, r_f, e, n_y)
    eps = jnp.asarray(eps, dt)
    return lax.cond(jnp.all(eps >= FAST_EPS_MIN), lambda: _defuzzify_split(r_t, r_f, eps, n_y),
                    lambda: defuzzify(r_t, r_f, eps, n_y))


def fis_colregs(delta_cog, rb, d, *, d_cl=DEFAULT_D_CL, e_cl=DEFAULT_E_CL, eps=DEFAULT_EPS,
                n_y: int = DEFAULT_N_Y, completion: str = "default_false", angles: str = "rad"):
    """The crisp COLREGS output μ ∈ (0, 1) of FIS_colregs for arrays of (ΔCOG, RB, d).

    Args:
        delta_cog: course difference |wrap(χ_i − χ_o)| ∈ [0, π] (or [0, 180] with ``angles="deg"``).
        rb: relative bearing of the target, positive to starboard, in (−π, π] (or degrees).
        d: own-ship–target distance [m].
        d_cl: COLREGS "close" distance [m] (> 0); e_cl: its extension [m] (> 0, proposed: own-ship length).
        eps: smooth max/min parameter ε (≥ 0; proposed 1e-6). n_y: output grid points (integer ≥ 2).
        completion: ``"default_false"`` (choice SM-4, default) or ``"literal"`` (rule (21) only).
        angles: ``"rad"`` (default) or ``"deg"``.
    """
    check_fis_params(d_cl, e_cl, eps, n_y, completion)
    check_choice("angles", angles, ANGLE_UNITS)
    scale = 1.0 if angles == "deg" else RAD2DEG
    dcog, rbv, dv = jnp.broadcast_arrays(jnp.asarray(delta_cog) * scale, jnp.asarray(rb) * scale, jnp.asarray(d))
    return fis_degrees(dcog, rbv, dv, d_cl, e_cl, eps, n_y, completion)


def fis_degrees(dcog_deg, rb_deg, d, d_cl=DEFAULT_D_CL, e_cl=DEFAULT_E_CL, eps=DEFAULT_EPS, n_y: int = DEFAULT_N_Y,
                completion: str = "default_false"):
    """μ of FIS_colregs from ΔCOG and RB in degrees and d [m] (same shape; no validation): memberships →
    rule strengths → CoG.  The CoG is :func:`_defuzzify_split` when ε >= :data:`FAST_EPS_MIN`, else
    :func:`defuzzify` (equal to float rounding).  A traced ε chooses at run time with one ``lax.cond`` around
    the whole per-pair computation: besides choosing, it keeps XLA:CPU from splitting the ~80 unrolled square
    roots into one kernel each (which it does when their sum feeds a reduction in the same computation, and
    which costs ~10x)."""
    def run(fast: bool):
        rs = rule_strengths(memberships(dcog_deg, rb_deg, d, d_cl, e_cl), eps, completion)
        return _defuzzify_split(rs.r_T, rs.r_F, eps, n_y) if fast else defuzzify(rs.r_T, rs.r_F, eps, n_y)

    e = concrete_float(eps)
    if e is not None:
        return run(e >= FAST_EPS_MIN)
    dt = jnp.result_type(dcog_deg, float)
    return lax.cond(jnp.all(jnp.asarray(eps, dt) >= FAST_EPS_MIN), lambda: run(True), lambda: run(False))


# ------------------------------------------------------------------------------------------ geometry
def wrap_to_pi(a):
    """Wrap angles to (−π, π] (+π stays +π: a target dead astern counts as starboard, RB = +180°).

    a − 2π·ceil((a − π)/2π) (exact for |a| <= π, where the multiple is 0), then a one-step correction of the
    rounding at the ends; no ``jnp.mod`` (a slow scalar ``fmod`` on XLA:CPU)."""
    two_pi = 2.0 * math.pi
    w = a - two_pi * jnp.ceil((a - math.pi) / two_pi)
    return jnp.where(w > math.pi, w - two_pi, jnp.where(w <= -math.pi, w + two_pi, w))


# Cephes atan (double precision, |error| <= 1 ulp after the octant reduction): atan(t) = t + t z P(z)/Q(z),
# z = t², for t in [0, 0.66]; atan(a) = π/4 + atan((a − 1)/(a + 1)) for a in (0.66, 1].
_ATAN_P = (-8.750608600031904122785e-1, -1.615753718733365076637e1, -7.500855792314704667340e1,
           -1.228866684490136173410e2, -6.485021904942025371773e1)
_ATAN_Q = (2.485846490142306297962e1, 1.650270098316988542046e2, 4.328810604912902668951e2,
           4.853903996359136964868e2, 1.945506571482613964425e2)
_MOREBITS = 6.123233995736765886130e-17        # π/2 − float64(π/2)


def atan2_poly(y, x):
    """atan2(y, x) ∈ [−π, π] by octant reduction and the Cephes rational approximation (within 1-2 ulp of
    ``jnp.arctan2`` in float64 and float32; smooth away from the negative x-axis; ``atan2(±0, x < 0) = ±π``
    as IEEE).  Elementwise arithmetic only, so XLA:CPU vectorises it (``jnp.arctan2`` is a scalar call there)."""
    ax, ay = jnp.abs(x), jnp.abs(y)
    swap = ay > ax
    num, den = jnp.where(swap, ax, ay), jnp.where(swap, ay, ax)
    a = num / jnp.where(den > 0, den, 1.0)                                   # [0, 1]
    big = a > 0.66
    t = jnp.where(big, (a - 1.0) / (a + 1.0), a)
    z = t * t
    p = (((_ATAN_P[0] * z + _ATAN_P[1]) * z + _ATAN_P[2]) * z + _ATAN_P[3]) * z + _ATAN_P[4]
    q = ((((z + _ATAN_Q[0]) * z + _ATAN_Q[1]) * z + _ATAN_Q[2]) * z + _ATAN_Q[3]) * z + _ATAN_Q[4]
    r = t + t * (z * p / q)
    r = jnp.where(big, r + (math.pi / 4 + 0.5 * _MOREBITS), r)
    r = jnp.where(swap, (math.pi / 2 + _MOREBITS) - r, r)
    r = jnp.where(jnp.signbit(x), (math.pi + 2.0 * _MOREBITS) - r, r)
    return jnp.where(jnp.signbit(y), -r, r)


def safe_atan2(y, x):
    """atan2 with a finite gradient at (0, 0), where it returns 0 (:func:`atan2_poly` elsewhere)."""
    zero = (x == 0) & (y == 0)
    return jnp.where(zero, 0.0, atan2_poly(jnp.where(zero, 0.0, y), jnp.where(zero, 1.0, x)))


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
    "defuzzify_fast", "fis_degrees", "FAST_TAU", "FAST_EPS_MIN", "fis_colregs", "wrap_to_pi", "atan2_poly",
    "safe_atan2", "encounter_inputs_xy", "encounter_inputs", "fis_colregs_states",
    "check_fis_params", "check_param", "check_choice", "check_n_y", "concrete_float",
]
