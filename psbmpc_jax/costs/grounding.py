"""Grounding cost (Tengesdal et al. 2022, eqs. 15-16; docs/algorithm.md §8) on padded polygon arrays.

Polygons arrive prepared (simplified, range-filtered) as ``vertices [P, V, 2]`` with ``next [P, V]`` (the
next vertex of the same ring: a polygon may hold several rings — outer ring and holes — back to back) and
``n_vertices [P]`` (valid slots = edges).

Exact mode: H_so^{l,j} = max_k g(d_{j,k}, t_k).  The maximising time of every (polygon, behaviour) is found by
the culled search :func:`psbmpc_jax.geometry.polygon_argmax` or the dense one (``PlannerConfig.grounding_search``;
exact, not differentiated); the cost is then g
at that point, from the point's nearest edge (:func:`psbmpc_jax.geometry.polygon_distance`).  The gradient of
a max is the gradient at its argmax, so the cost is reverse- and forward-differentiable w.r.t. the positions.
"""

from __future__ import annotations

import jax.numpy as jnp

from ..distance_grid import interpolate
from ..geometry import edge_table
from ..grounding_search import distances_at, search_argmax
from ..layouts import resolve_search
from ..numerics import safe_sqrt


def grounding_g(d, t, phi, params):
    """g(d, t): exponential above d_safe, linear continuation below (monotone, continuous)."""
    amp = params.G1 + params.G2 * phi * params.V_w ** 2
    above = amp * jnp.exp(-(params.G3 * (d - params.d_safe) + params.G4 * t))
    below = amp * jnp.exp(-params.G4 * t) * (1.0 + params.G3 * (params.d_safe - d))
    return jnp.where(d >= params.d_safe, above, below)


def _wind_phi(d, ex, ey, params):
    """phi: the cosine between the wind and the direction to land (0 inside land or against the wind)."""
    dpos = d > 0
    toward = jnp.cos(params.wind_dir) * ex + jnp.sin(params.wind_dir) * ey
    return jnp.where(dpos, jnp.maximum(0.0, toward / jnp.where(dpos, d, 1.0)), 0.0)


def _search_score(params):
    """g as ``score(d, ex, ey, w)`` of the time feature w = exp(-G4 t), and ``bound(d, w)``: g at phi = 1, an
    upper bound over every distance >= d and time feature <= w (+inf unless the parameters make g monotone)."""
    def shape(d):
        return jnp.where(d >= params.d_safe, jnp.exp(-params.G3 * (d - params.d_safe)),
                         1.0 + params.G3 * (params.d_safe - d))

    def score(d, ex, ey, w):
        return (params.G1 + params.G2 * _wind_phi(d, ex, ey, params) * params.V_w ** 2) * w * shape(d)

    monotone = (params.G1 >= 0) & (params.G2 >= 0) & (params.G3 >= 0)

    def bound(d, w):
        return jnp.where(monotone, (params.G1 + params.G2 * params.V_w ** 2) * w * shape(d), jnp.inf)

    return score, bound


def grounding_costs(px, py, t, vertices, nxt, n_vertices, poly_mask, params, search="auto", blocks=None,
                    platform=None):
    """H_so^{l,j} for every polygon: own positions ``px, py [T, B]`` (time-major), times ``t [T]`` -> ``[P, B]``.

    Padding polygons (``poly_mask`` False) cost 0.  ``search`` (static; ``PlannerConfig.grounding_search``):
    ``"culled"`` (the culled argmax search, then each polygon's nearest edge one edge per loop step: the CPU
    layout), ``"dense"`` (every edge, 32 edges per loop step in both) or ``"flat"`` (every polygon's every edge in
    one pass, with the chart's edge ``blocks``: the GPU layout); ``"auto"``: by platform
    (:func:`psbmpc_jax.layouts.resolve_search`, ``platform`` as ``PlannerConfig.layout_platform``).  The same costs
    either way."""
    search = resolve_search(search, platform)
    tables = edge_table(vertices, nxt)                                          # [P, V, 8]
    score, bound = _search_score(params)
    windy = (params.V_w * params.G2) != 0                  # the nearest-point direction matters
    k = search_argmax(search, px, py, jnp.exp(-params.G4 * t), score, bound, tables, nxt,
                      jnp.where(poly_mask, n_vertices, 0), windy, blocks)       # [P, B]
    cols = jnp.arange(px.shape[1])
    d, ex, ey = distances_at(search, px[k, cols], py[k, cols], tables, n_vertices, blocks)
    g = grounding_g(d, t[k], _wind_phi(d, ex, ey, params), params)
    return jnp.where(poly_mask[:, None], g, 0.0)


def grid_grounding_cost(px, py, t, grid, params):
    """H_so from a nearest-land distance grid (fast mode): own positions ``px, py [T, B]`` -> ``[B]``.

    The direction to land for the wind term is minus the interpolated distance gradient (gradient-safe where
    that gradient vanishes, e.g. inside land)."""
    d, gx, gy = interpolate(grid, px, py)
    gn = safe_sqrt(gx * gx + gy * gy)
    ok = (gn > 0) & (d > 0)
    gs = jnp.where(ok, gn, 1.0)
    phi = jnp.where(ok, jnp.maximum(0.0, -(jnp.cos(params.wind_dir) * gx + jnp.sin(params.wind_dir) * gy) / gs),
                    0.0)
    return jnp.max(grounding_g(d, t[:, None], phi, params), axis=0)
