"""COLREGS rule 14/15 violation test (Johansen et al. 2016; docs/algorithm.md §8)."""

from __future__ import annotations

import math

import jax.numpy as jnp

from .base import Context, TermValue, cost_term
from .collision import pair_geometry

COS_22_5 = math.cos(math.radians(22.5))
COS_67_5 = math.cos(math.radians(67.5))


def violation(dx, dy, v0x, v0y, vix, viy, cos_chi, sin_chi, d_close):
    """Boolean violation indicator for arrays of (own-ship, obstacle) point pairs.

    ``dx, dy``: obstacle minus own-ship position; ``v0``/``vi``: velocities; ``cos_chi``, ``sin_chi``: own
    course.  True when CLOSE ∧ STARBOARD ∧ (HEAD-ON ∨ (CROSSED ∧ ¬OVERTAKEN)); HEAD-ON and CROSSED both require
    ‖v_0‖ > 0.05 m/s (docs/algorithm.md §8)."""
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


@cost_term
class ColregsTerm:
    """H_colregs = κ Σ_i w_i Σ_s P_s μ_s^{l,i}: μ = 1 when any predicted time step violates rules 14/15.
    Details: ``mu [B, O, S]`` (0/1).  Piecewise constant in the controls (its gradient is 0 almost
    everywhere); the refinement stage replaces it by a smooth form."""

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
                         own.cos_chi[:, None], own.sin_chi[:, None], params.d_close) & valid_os[None, :, None]
        mu = jnp.any(viol, axis=0).astype(own.x.dtype).T.reshape(-1, n_o, n_s)        # [B, O, S]
        return TermValue(params.kappa * jnp.sum(ctx.scen_weight[None] * mu, axis=(1, 2)), {"mu": mu})
