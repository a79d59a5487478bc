"""The grounding cost term (moved into costs/grounding.py once the kernel rewrite lands)."""

from __future__ import annotations

import jax.numpy as jnp

from .base import Context, TermValue, cost_term
from .grounding import grid_grounding_cost, grounding_costs


@cost_term
class GroundingTerm:
    """H_so = max_j H_so^{l,j} (eqs. 15-16): per polygon, the largest g(d, t) along the trajectory.
    Details: ``so_j [B, P]`` (``[B, 1]`` in grid mode: the cost of the nearest land)."""

    name = "so"
    PARAMS = ("G1", "G2", "G3", "G4", "V_w", "wind_dir", "d_safe")
    smooth = True            # piecewise smooth (max over time and polygons)

    def __call__(self, ctx: Context, params, config, samples) -> TermValue:
        own, t = ctx.own, ctx.t
        if config.grounding_mode == "grid":
            grid = ctx.world.grid
            h = grid_grounding_cost(own.x, own.y, t, grid.distance_grid(), params)
            so_j = jnp.where(grid.active, h, 0.0)[:, None]                       # [B, 1]: nearest land
        else:
            poly = ctx.world.polygons
            so_j = grounding_costs(own.x, own.y, t, poly.vertices, poly.next, poly.n, poly.mask, params,
                                   config.grounding_search, poly.blocks, config.layout_platform).T
        # no polygons: a [B, 0] max would be NaN in forward mode; costs are >= 0, padding costs 0
        value = jnp.max(so_j, axis=1) if so_j.shape[1] else jnp.zeros(so_j.shape[:1], own.x.dtype)
        return TermValue(value, {"so_j": so_j})
