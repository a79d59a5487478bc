"""Grounding cost (eqs. 15-16, SPEC §7; docs/algorithm.md §8) on padded polygon arrays.

Polygons arrive prepared (simplified, range-filtered) as ``vertices [P, V, 2]`` with ``n_vertices [P]``;
each is a ring, implicitly closed.  The exact kernel loops over the real edges of each polygon with a
dynamic trip count (no work on padding), carrying per-(behaviour, time) running minima.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp


def grounding_g(d, t, phi, params):
    """g(d, t): exponential above d_safe, linear continuation below (monotone, continuous)."""
    amp = params.G1 + params.G2 * phi * params.V_w ** 2
    above = amp * jnp.exp(-(params.G3 * (d - params.d_safe) + params.G4 * t))
    below = amp * jnp.exp(-params.G4 * t) * (1.0 + params.G3 * (params.d_safe - d))
    return jnp.where(d >= params.d_safe, above, below)


def polygon_distance(px, py, ring, n):
    """Distance from points ``px, py [...]`` to one ring (``ring [V, 2]``, ``n`` valid vertices).

    Returns (d, ex, ey): distance (0 inside, even-odd rule) and the vector from the point to the nearest
    boundary point (unnormalised)."""
    big = jnp.asarray(jnp.finfo(px.dtype).max, px.dtype)

    def body(e, carry):
        d2, ex, ey, inside = carry
        a = ring[e]
        b = ring[jnp.where(e + 1 < n, e + 1, 0)]
        abx, aby = b[0] - a[0], b[1] - a[1]
        apx, apy = px - a[0], py - a[1]
        l2 = abx * abx + aby * aby
        t = jnp.where(l2 > 0, jnp.clip((apx * abx + apy * aby) / jnp.where(l2 > 0, l2, 1.0), 0.0, 1.0), 0.0)
        qx, qy = a[0] + t * abx - px, a[1] + t * aby - py
        e2 = qx * qx + qy * qy
        closer = e2 < d2
        d2, ex, ey = jnp.where(closer, e2, d2), jnp.where(closer, qx, ex), jnp.where(closer, qy, ey)
        straddle = (a[1] > py) != (b[1] > py)
        dy = jnp.where(straddle, b[1] - a[1], 1.0)
        cross = straddle & (px < a[0] + (py - a[1]) * (b[0] - a[0]) / dy)
        return d2, ex, ey, inside ^ cross

    init = (jnp.full(px.shape, big), jnp.zeros_like(px), jnp.zeros_like(px), jnp.zeros(px.shape, bool))
    d2, ex, ey, inside = jax.lax.fori_loop(0, n, body, init)
    d = jnp.where(inside, 0.0, jnp.sqrt(d2))
    return d, jnp.where(inside, 0.0, ex), jnp.where(inside, 0.0, ey)


def grounding_costs(px, py, t, vertices, n_vertices, poly_mask, params):
    """H_so^{l,j} for every polygon: own positions ``px, py [T, B]`` (time-major), times ``t [T]`` -> ``[P, B]``.

    Padding polygons (``poly_mask`` False) cost 0."""
    wx, wy = jnp.cos(params.wind_dir), jnp.sin(params.wind_dir)

    def one(carry, poly):
        ring, n, valid = poly
        d, ex, ey = polygon_distance(px, py, ring, n)
        dpos = d > 0
        dd = jnp.where(dpos, d, 1.0)
        phi = jnp.where(dpos, jnp.maximum(0.0, (wx * ex + wy * ey) / dd), 0.0)
        g = grounding_g(d, t[:, None], phi, params)
        return carry, jnp.where(valid, jnp.max(g, axis=0), 0.0)

    _, h = jax.lax.scan(one, None, (vertices, n_vertices, poly_mask))
    return h
