"""COLREGS rule 14/15 violation test (Johansen et al. 2016; docs/algorithm.md §8), and the stop remedy.

As published, HEAD-ON and CROSSED need a moving own-ship (‖v_0‖ > 0.05 m/s), so a stopped own-ship never
violates: the stop loophole (docs/methods/psbmpc.md "The stop loophole").  With the remedy
``PlannerConfig.stop_remedy = "colregs_heading"`` the geometric tests use the own-ship's heading (course χ)
whatever its speed: a stopped give-way ship with the target close on its starboard side still violates.  For a
moving own-ship the two are the same test (its velocity points along χ)."""

from __future__ import annotations

import math

import jax.numpy as jnp

from ..numerics import ordered_sum
from ..params import STOP_REMEDIES as _STOP_REMEDIES
from .base import Context, TermValue, cost_term
from .collision import pair_geometry

COS_22_5 = math.cos(math.radians(22.5))
COS_67_5 = math.cos(math.radians(67.5))


#: ``PlannerConfig.stop_remedy`` values (:data:`psbmpc_jax.params.STOP_REMEDIES`): ``"none"`` (the published
#: cost: a stopped own-ship is exempt from the COLREGS test) and ``"colregs_heading"`` (the test on the
#: own-ship's heading whatever its speed).
STOP_REMEDIES = _STOP_REMEDIES
#: The published speed guard of HEAD-ON and CROSSED [m/s].
V_GUARD = 0.05


def violation(dx, dy, v0x, v0y, vix, viy, cos_chi, sin_chi, d_close, *, heading: bool = False):
    """Boolean violation indicator for arrays of (own-ship, obstacle) point pairs.

    ``dx, dy``: obstacle minus own-ship position; ``v0``/``vi``: velocities; ``cos_chi``, ``sin_chi``: own
    course.  True when CLOSE ∧ STARBOARD ∧ (HEAD-ON ∨ (CROSSED ∧ ¬OVERTAKEN)); HEAD-ON and CROSSED both require
    ‖v_0‖ > 0.05 m/s (docs/algorithm.md §8).

    ``heading=True`` (static; the stop remedy ``"colregs_heading"``): the direction tests of HEAD-ON, CROSSED
    and OVERTAKEN use the unit heading (cos χ, sin χ) in place of v_0/‖v_0‖ and the speed guard is dropped, so
    the obligation holds whatever the own-ship's speed; OVERTAKEN still compares the speeds (‖v_i‖ > ‖v_0‖: a
    stopped ship is overtaken by every target from astern).  Where ‖v_0‖ > 0.05 m/s and v_0 points along χ (the
    kinematic model's trajectories) this is the published test."""
    if heading:
        return _violation_heading(dx, dy, v0x, v0y, vix, viy, cos_chi, sin_chi, d_close)
    d2 = dx * dx + dy * dy
    d = jnp.sqrt(d2)
    v0_dot_vi = v0x * vix + v0y * viy
    n0 = jnp.sqrt(v0x * v0x + v0y * v0y)
    ni = jnp.sqrt(vix * vix + viy * viy)
    n0ni = n0 * ni
    close = d < d_close
    starboard = cos_chi * dy - sin_chi * dx > 0
    # v0 . L > cos(67.5) |v0| with L = Δp / d, written without dividing (L = 0 when d = 0)
    ahead = jnp.where(d > 0, (v0x * dx + v0y * dy) > COS_67_5 * n0 * d, False)
    head_on = (n0 > 0.05) & (v0_dot_vi < -COS_22_5 * n0ni) & ahead
    # [choice] like HEAD-ON, CROSSED needs a moving own-ship: the test is direction-only, so without the
    # guard a stopping ship's 1e-56 m/s velocity (float64) and its exact 0 (float32 underflow) disagree
    crossed = (n0 > 0.05) & (v0_dot_vi < COS_67_5 * n0ni)
    overtaken = (v0_dot_vi > COS_67_5 * n0ni) & (ni > n0)
    return close & starboard & (head_on | (crossed & ~overtaken))


def _violation_heading(dx, dy, v0x, v0y, vix, viy, cos_chi, sin_chi, d_close):
    """:func:`violation` with ``heading=True``: the own-ship's direction is its heading (cos χ, sin χ)."""
    d = jnp.sqrt(dx * dx + dy * dy)
    n0 = jnp.sqrt(v0x * v0x + v0y * v0y)
    ni = jnp.sqrt(vix * vix + viy * viy)
    h_dot_vi = cos_chi * vix + sin_chi * viy          # ĥ·v_i: the published v_0·v_i divided by ‖v_0‖
    close = d < d_close
    starboard = cos_chi * dy - sin_chi * dx > 0
    ahead = jnp.where(d > 0, (cos_chi * dx + sin_chi * dy) > COS_67_5 * d, False)
    head_on = (h_dot_vi < -COS_22_5 * ni) & ahead
    crossed = h_dot_vi < COS_67_5 * ni
    overtaken = (h_dot_vi > COS_67_5 * ni) & (ni > n0)
    return close & starboard & (head_on | (crossed & ~overtaken))


def check_stop_remedy(value, where: str = "stop_remedy") -> str:
    """``value`` if it is one of :data:`STOP_REMEDIES`, else ValueError naming ``where`` and the allowed values."""
    if not isinstance(value, str) or value not in STOP_REMEDIES:
        raise ValueError(f"{where} must be one of {STOP_REMEDIES}, got {value!r}")
    return value


@cost_term
class ColregsTerm:
    """H_colregs = κ Σ_i w_i Σ_s P_s μ_s^{l,i}: μ = 1 when any predicted time step violates rules 14/15.
    Details: ``mu [B, O, S]`` (0/1).  Piecewise constant in the controls (its gradient is 0 almost
    everywhere); the refinement stage replaces it by a smooth form.  ``config.stop_remedy`` selects the
    published test (``"none"``) or the test on the heading whatever the speed (``"colregs_heading"``)."""

    name = "colregs"
    PARAMS = ("kappa", "d_close")
    smooth = False

    def __call__(self, ctx: Context, params, config, samples) -> TermValue:
        own, obs = ctx.own, ctx.obstacles
        n_t = own.x.shape[0]
        n_o, n_s = ctx.scen_weight.shape
        dx, dy, valid_os = pair_geometry(ctx)
        wx, wy = obs.vx.reshape(n_t, n_o * n_s), obs.vy.reshape(n_t, n_o * n_s)
        viol = violation(dx, dy, own.vx[:, None], own.vy[:, None], wx[:, :, None], wy[:, :, None],
                         own.cos_chi[:, None], own.sin_chi[:, None], params.d_close,
                         heading=stop_remedy(config) == "colregs_heading") & valid_os[None, :, None]
        mu = jnp.any(viol, axis=0).astype(own.x.dtype).T.reshape(-1, n_o, n_s)        # [B, O, S]
        return TermValue(params.kappa * ordered_sum(ctx.scen_weight[None] * mu), {"mu": mu})


def stop_remedy(config) -> str:
    """The stop remedy of a :class:`~psbmpc_jax.params.PlannerConfig` (``"none"`` for an object without the
    field, e.g. a config built before it existed)."""
    return check_stop_remedy(getattr(config, "stop_remedy", "none"), "PlannerConfig.stop_remedy")
