"""Grounding cost (eqs. 15-16, SPEC §7; docs/algorithm.md §8) on padded polygon arrays.

Polygons arrive prepared (simplified, range-filtered) as ``vertices [P, V, 2]`` with ``next [P, V]`` (the
next vertex of the same ring: a polygon may hold several rings — outer ring and holes — back to back) and
``n_vertices [P]`` (valid slots = edges).  The exact kernel loops over the real edges of each polygon with a
dynamic trip count (no work on padding), carrying per-(time, behaviour) running minima; per-edge constants
are computed once, outside the loop.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from ..numerics import safe_sqrt


def grounding_g(d, t, phi, params):
    """g(d, t): exponential above d_safe, linear continuation below (monotone, continuous)."""
    amp = params.G1 + params.G2 * phi * params.V_w ** 2
    above = amp * jnp.exp(-(params.G3 * (d - params.d_safe) + params.G4 * t))
    below = amp * jnp.exp(-params.G4 * t) * (1.0 + params.G3 * (params.d_safe - d))
    return jnp.where(d >= params.d_safe, above, below)


def edge_table(vertices, nxt):
    """Per-edge constants ``[..., V]``: a, b - a, 1/|b - a|^2 (0 for a zero-length edge), b_y and the
    crossing slope (b_x - a_x)/(b_y - a_y) (0 for a horizontal edge, which never straddles)."""
    ax, ay = vertices[..., 0], vertices[..., 1]
    b = jnp.take_along_axis(vertices, nxt[..., None], axis=-2)
    bx, by = b[..., 0], b[..., 1]
    abx, aby = bx - ax, by - ay
    l2 = abx * abx + aby * aby
    inv_l2 = jnp.where(l2 > 0, 1.0 / jnp.where(l2 > 0, l2, 1.0), 0.0)
    slope = jnp.where(aby != 0, abx / jnp.where(aby != 0, aby, 1.0), 0.0)
    return jnp.stack([ax, ay, abx, aby, inv_l2, by, slope], axis=-1)


def polygon_distance(px, py, edges, n, with_direction=True):
    """Distance from points ``px, py [...]`` to one polygon given by its edge table ``edges [V, 7]`` and
    ``n`` valid edges.

    Returns (d, ex, ey): distance (0 inside, even-odd rule) and the vector from the point to the nearest
    boundary point (0 inside).  ``with_direction`` may be a traced boolean: when False the loop does not
    track the nearest edge (about 15 % less work) and (ex, ey) are zeros."""
    big = jnp.asarray(jnp.finfo(px.dtype).max, px.dtype)

    def edge_geometry(e):
        ax, ay, abx, aby, inv_l2, by, slope = (edges[e, i] for i in range(7))
        apx, apy = px - ax, py - ay
        t = jnp.clip((apx * abx + apy * aby) * inv_l2, 0.0, 1.0)
        qx, qy = apx - t * abx, apy - t * aby
        cross = ((ay > py) != (by > py)) & (px < ax + apy * slope)
        return qx * qx + qy * qy, cross

    def body_dir(e, carry):
        d2, best, inside = carry
        e2, cross = edge_geometry(e)
        closer = e2 < d2
        return jnp.where(closer, e2, d2), jnp.where(closer, e, best), inside ^ cross

    def body_plain(e, carry):
        d2, inside = carry
        e2, cross = edge_geometry(e)
        return jnp.minimum(e2, d2), inside ^ cross

    def run_dir(_):
        init = (jnp.full(px.shape, big), jnp.zeros(px.shape, jnp.int32), jnp.zeros(px.shape, bool))
        d2, best, inside = jax.lax.fori_loop(0, n, body_dir, init)
        # nearest-point vector from the winning edge, once per point
        ax, ay, abx, aby, inv_l2 = (edges[best, i] for i in range(5))
        t = jnp.clip(((px - ax) * abx + (py - ay) * aby) * inv_l2, 0.0, 1.0)
        return d2, inside, ax + t * abx - px, ay + t * aby - py

    def run_plain(_):
        d2, inside = jax.lax.fori_loop(0, n, body_plain, (jnp.full(px.shape, big), jnp.zeros(px.shape, bool)))
        return d2, inside, jnp.zeros_like(px), jnp.zeros_like(px)

    d2, inside, ex, ey = jax.lax.cond(with_direction, run_dir, run_plain, None)
    d = jnp.where(inside, 0.0, safe_sqrt(d2))            # gradient-safe on the boundary (d2 = 0)
    return d, jnp.where(inside, 0.0, ex), jnp.where(inside, 0.0, ey)


def grounding_costs(px, py, t, vertices, nxt, n_vertices, poly_mask, params):
    """H_so^{l,j} for every polygon: own positions ``px, py [T, B]`` (time-major), times ``t [T]`` -> ``[P, B]``.

    Padding polygons (``poly_mask`` False) cost 0."""
    wx, wy = jnp.cos(params.wind_dir), jnp.sin(params.wind_dir)
    tables = edge_table(vertices, nxt)                                          # [P, V, 7]

    def one(carry, poly):
        edges, n, valid = poly
        # the nearest-point direction only matters for the wind term
        d, ex, ey = polygon_distance(px, py, edges, n, with_direction=(params.V_w * params.G2) != 0)
        dpos = d > 0
        dd = jnp.where(dpos, d, 1.0)
        phi = jnp.where(dpos, jnp.maximum(0.0, (wx * ex + wy * ey) / dd), 0.0)
        g = grounding_g(d, t[:, None], phi, params)
        return carry, jnp.where(valid, jnp.max(g, axis=0), 0.0)

    _, h = jax.lax.scan(one, None, (tables, n_vertices, poly_mask))
    return h


def grid_grounding_cost(px, py, t, grid, params):
    """H_so from a nearest-land distance grid (fast mode): own positions ``px, py [T, B]`` -> ``[B]``.

    The direction to land for the wind term is minus the interpolated distance gradient."""
    from ..distance_grid import interpolate

    d, gx, gy = interpolate(grid, px, py)
    gn = jnp.sqrt(gx * gx + gy * gy)
    ok = (gn > 0) & (d > 0)
    gs = jnp.where(ok, gn, 1.0)
    phi = jnp.where(ok, jnp.maximum(0.0, -(jnp.cos(params.wind_dir) * gx + jnp.sin(params.wind_dir) * gy) / gs),
                    0.0)
    return jnp.max(grounding_g(d, t[:, None], phi, params), axis=0)
