"""The exact grounding searches behind one call (``PlannerConfig.grounding_search``).

For every polygon and behaviour the time step where a grounding score is largest (:func:`search_argmax`), then
the distance and direction to that polygon at that step (:func:`distances_at`, differentiable).  Three layouts, the
same numbers (:mod:`psbmpc_jax.layouts` picks one per platform):

* ``culled`` (:func:`psbmpc_jax.geometry.polygon_argmax`): tiles of time steps and chunks of edges culled by
  distance bounds, one polygon at a time: the least arithmetic, many short loop steps (the CPU's);
* ``dense`` (:func:`psbmpc_jax.geometry.dense_argmax`): every edge against every point, 32 edges per loop step,
  one polygon at a time;
* ``flat`` (:mod:`psbmpc_jax.edge_blocks`): every polygon's every edge in one masked pass, no loop (the GPU's).
"""

from __future__ import annotations

from jax import lax

from .bounded_search import bounded_argmax, use_bounded
from .edge_blocks import flat_argmax, flat_distance
from .geometry import dense_argmax, dense_block, polygon_argmax, polygon_distance
from .layouts import resolve_search


def search_argmax(search, px, py, tw, score, bound, edges, nxt, n, with_direction=True, blocks=None):
    """``[P, B]`` int32: for every polygon and column the time index of ``px, py [T, B]`` maximising
    ``score(d, ex, ey, w)`` (:func:`psbmpc_jax.geometry.polygon_argmax` documents the arguments).  ``bound`` and
    ``nxt`` are used by ``culled`` only, ``blocks`` (the chart's edge blocks) by ``flat`` only."""
    search = resolve_search(search)
    if search == "dense":
        return dense_argmax(px, py, tw, score, edges, n, with_direction)
    if search == "bounded" and use_bounded(edges):
        return bounded_argmax(px, py, tw, score, bound, edges, nxt, n, with_direction)
    if search in ("bounded", "culled"):
        return polygon_argmax(px, py, tw, score, bound, edges, nxt, n, with_direction)
    return flat_argmax(px, py, tw, score, edges, n, blocks, with_direction)


def distances_at(search, qx, qy, edges, n, blocks=None):
    """Distance and nearest-boundary vector ``d, ex, ey [P, B]`` of one point per polygon and column ``qx, qy
    [P, B]``, differentiable w.r.t. the points: one polygon at a time (``culled``: one edge per loop step;
    ``dense``: :func:`psbmpc_jax.geometry.dense_block` edges per step) or all polygons in one pass (``flat``)."""
    search = resolve_search(search)
    if search == "flat":
        return flat_distance(qx, qy, edges, n, blocks)
    block = dense_block(qx.shape[1]) if search == "dense" else 1

    def one(_, poly):
        e, k, x, y = poly
        return None, polygon_distance(x, y, e, k, block=block)

    return lax.scan(one, None, (edges, n, qx, qy))[1]


__all__ = ["distances_at", "search_argmax"]
