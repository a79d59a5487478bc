"""Land clearance of the DOCP's plan between its samples (a proven sample bound; docs/smooth_sbmpc.md).

The corridor of Algorithm 3 constrains the plan's cross-track error at Ψ's samples only; a plan that keeps
every sample inside its cross-section can still cut a corner of land between two samples (or beside a sample,
along the track).  This module adds a constraint per step k = 0 … N − 1 of the plan that bounds the clearance
of the whole straight segment x_k → x_{k+1} (the kinematic model's motion in one step is that segment, of
length ℓ_k = T_s U_k):

    g_k = 2 b + ℓ_k − sd(x_k) − sd(x_{k+1})  ≤  0,

with sd the signed distance to the (unbuffered) land polygons (negative inside) and b the corridor's land
buffer.  **Proof.** sd is 1-Lipschitz, so a point p of the segment at arc length a from x_k has
sd(p) ≥ max(sd(x_k) − a, sd(x_{k+1}) − (ℓ_k − a)) ≥ (sd(x_k) + sd(x_{k+1}) − ℓ_k)/2 ≥ b.  The bound is exact
for a segment straight toward the shore and conservative by at most ℓ_k/2 for one parallel to it.

x_0 is the present state and x_N is fixed by the terminal condition, so the first and the last segment are
relaxed by what the warm start Ψ lacks there (``slack``: max(0, g_k(Ψ)) for k = 0 and N − 1, 0 elsewhere);
the plan is never required to do better than the fixed end points allow.

:func:`signed_clearance` is the traceable kernel (differentiable almost everywhere: the gradient of the
distance to the nearest edge; the even–odd inside test is piecewise constant).  Edge blocks farther than
``cap`` from the box every plan position lies in are skipped (exact: a plan's speed is bounded, so its reach is).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
from jax import lax

from ..packing import ChartArrays
from .land_hit import EdgeBlocks, box_near, crossings, cull_tolerance, edge_blocks, may_cross, point_edge_d2

#: Distances are floored at this before the square root (a finite gradient on an edge) [m²].
D2_FLOOR = 1e-12


class Clearance(NamedTuple):
    """Data of the clearance constraint of one DOCP (a pytree).

    Attributes:
        blocks: the land's edge blocks (:func:`psbmpc_jax.smooth.land_hit.edge_blocks`, per polygon).
        lo, hi: ``[2]`` the box every plan position lies in.
        cap: distances beyond it count as ``cap`` (> 2 b + the longest step: never active).
        buffer: b [m].
        slack: ``[N]`` the relaxation of each segment's constraint (non-zero only for the first and the last).
    """

    blocks: EdgeBlocks
    lo: jax.Array
    hi: jax.Array
    cap: jax.Array
    buffer: jax.Array
    slack: jax.Array


def signed_clearance(points, blocks: EdgeBlocks, lo, hi, cap):
    """Signed distance ``[K]`` of ``points [K, 2]`` (north, east) to the land of ``blocks`` (negative inside,
    even–odd rule per polygon), capped at ``cap``.  Every point must lie in the box ``[lo, hi]`` (blocks farther
    than ``cap`` from it are skipped).  Traceable, differentiable in ``points``."""
    px, py = points[:, 0:1], points[:, 1:2]
    dtype = points.dtype
    big = jnp.asarray(jnp.finfo(dtype).max, dtype)
    cap = jnp.asarray(cap, dtype)
    tol = cull_tolerance(lo, hi)
    e_all, v_all, first_all, blo, bhi = lax.stop_gradient((blocks.edges, blocks.valid, blocks.first, blocks.lo,
                                                           blocks.hi))

    def per_block(carry, blk):
        d2, parity, inside = carry
        e, v, start, bl, bh = blk
        inside = inside | (start & parity)
        parity = jnp.where(start, False, parity)
        parity = lax.cond(may_cross(bl, bh, lo, hi, tol),
                          lambda: parity ^ (jnp.sum(v & crossings(px, py, e), axis=1) % 2 == 1), lambda: parity)
        d2 = lax.cond(box_near(bl, bh, lo, hi, cap + tol),
                      lambda: jnp.minimum(d2, jnp.min(jnp.where(v, point_edge_d2(px, py, e), big), axis=1)),
                      lambda: d2)
        return (d2, parity, inside), None

    k = points.shape[0]
    zeros = jnp.zeros(k, bool)
    (d2, parity, inside), _ = lax.scan(per_block, (jnp.full((k,), big, dtype), zeros, zeros),
                                       (e_all, v_all, first_all, blo, bhi))
    inside = inside | parity
    d = jnp.sqrt(jnp.maximum(jnp.minimum(d2, cap * cap), D2_FLOOR))
    return jnp.where(inside, -d, d)


def segment_residuals(states, c: Clearance, dt):
    """g_k − slack_k ``[N]`` (feasible when <= 0) of the plan ``states [N + 1, 4]`` (x, y, χ, U)."""
    sd = signed_clearance(states[:, :2], c.blocks, c.lo, c.hi, c.cap)
    length = dt * states[:-1, 3]
    return 2.0 * c.buffer + length - sd[:-1] - sd[1:] - c.slack


def make_clearance(chart: ChartArrays, psi_states, state0, U_d, buffer, dt) -> Clearance:
    """The :class:`Clearance` of a DOCP whose warm start is ``psi_states [N + 1, 4]`` (Ψ's first N + 1 states),
    starting at ``state0 [4]`` with nominal speed ``U_d`` (the plan's speed never exceeds max(U_0, U_d), so its
    positions stay within N T_s max(U_0, U_d) of the start)."""
    dtype = psi_states.dtype
    n = psi_states.shape[0] - 1
    u_max = jnp.maximum(state0[3], jnp.asarray(U_d, dtype))
    reach = n * dt * u_max + 1.0
    lo, hi = state0[:2] - reach, state0[:2] + reach
    buffer = jnp.asarray(buffer, dtype)
    cap = 2.0 * buffer + dt * u_max + 1.0
    blocks = edge_blocks(chart, per_polygon=True)
    base = Clearance(blocks, lo, hi, cap, buffer, jnp.zeros(n, dtype))
    g = lax.stop_gradient(segment_residuals(psi_states, base, dt))
    ends = (jnp.arange(n) == 0) | (jnp.arange(n) == n - 1)
    return base._replace(slack=jnp.where(ends, jnp.maximum(g, 0.0), 0.0))


__all__ = ["Clearance", "signed_clearance", "segment_residuals", "make_clearance", "D2_FLOOR"]
