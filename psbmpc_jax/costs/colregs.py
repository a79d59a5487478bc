"""COLREGS rule 14/15 violation test (Johansen et al. 2016; docs/algorithm.md §8)."""

from __future__ import annotations

import math

import jax.numpy as jnp

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
