"""The lower level of the two-level MPC (Mahipala & Johansen 2023, Sec. V): the SB-MPC hazard with the grounding cost
ζ of eq. (15) joined per (time, target) inside the max (our reading TL-5, docs/algorithm.md §15), ``max_i max_t (C R +
κ μ + ζ)``.

    ζ(d, t) = exp(−(η₁ |d − d_safe| + η₂ t))             if d ≤ d_close, else 0     (``shape="printed"``)
    ζ(d, t) = exp(−(η₁ (d − d_safe) + η₂ t)) for d ≥ d_safe, exp(−η₂ t)(1 + η₁ (d_safe − d)) below,
              0 beyond d_close                                                    (``shape="psbmpc"``, TL-6)

d: the own-ship's distance to land at each predicted step (0 inside land): the nearest-land distance grid in
``grounding_mode="grid"``, every polygon's exact distance otherwise.  t = τ − τ₀ [s].  The printed form peaks
at d = d_safe and falls again deeper inside (as printed, choice TL-6); the option shaped like the grounding cost of
Tengesdal et al. (2022, eq. 16) keeps growing. With no target (every target slot masked) the value is max_t ζ.
"""

from __future__ import annotations

import jax.numpy as jnp

from ..distance_grid import interpolate
from ..geometry import culled_distances, edge_table
from .base import Context, TermValue, cost_term
from .colregs_fuzzy import check_choice, check_param
from .sbmpc import SbmpcHazardTerm

ZETA_SHAPES = ("printed", "psbmpc")
#: Our proposal (the paper gives no values): η₁ = G3, η₂ = G4 of the library, d_close 50 m.
DEFAULT_ETA1 = 0.25
DEFAULT_ETA2 = 0.01
DEFAULT_D_CLOSE = 50.0


def zeta_cost(d, t, *, eta1=DEFAULT_ETA1, eta2=DEFAULT_ETA2, d_safe=10.0, d_close=DEFAULT_D_CLOSE,
              shape: str = "printed"):
    """ζ(d, t) of eq. (15) (``shape="printed"``) or its variant shaped like Tengesdal et al. (2022, eq. 16)
    (``"psbmpc"``); broadcast."""
    check_choice("shape", shape, ZETA_SHAPES)
    decay = jnp.exp(-eta2 * t)
    if shape == "printed":
        z = jnp.exp(-(eta1 * jnp.abs(d - d_safe))) * decay
    else:
        z = jnp.where(d >= d_safe, jnp.exp(-eta1 * (d - d_safe)), 1.0 + eta1 * (d_safe - d)) * decay
    return jnp.where(d <= d_close, z, 0.0)


def own_land_distance(ctx: Context, config):
    """Distance [m] of every own-ship sample to the nearest land, 0 inside: ``[T, B]`` (+inf without a chart)."""
    own = ctx.own
    world = ctx.world
    if world is None:
        return jnp.full(own.x.shape, jnp.inf, own.x.dtype)
    if config.grounding_mode == "grid":
        d, _, _ = interpolate(world.grid.distance_grid(), own.x, own.y)
        return jnp.where(world.grid.active, d, jnp.inf)
    poly = world.polygons
    if poly.vertices.shape[0] == 0:
        return jnp.full(own.x.shape, jnp.inf, own.x.dtype)
    (d, _, _), _ = culled_distances(own.x, own.y, edge_table(poly.vertices, poly.next), poly.next,
                                    jnp.where(poly.mask, poly.n, 0))
    d = jnp.where(poly.mask[:, None, None], d, jnp.inf)
    return jnp.min(d, axis=0)


@cost_term(static=("shape",))
class SbmpcZetaTerm:
    """max over (target, τ ≥ τ₀ + T_s) of the SB-MPC hazard ``hazard`` (its C R + κ μ, crisp R and Boolean μ in
    the two-level method) plus ζ (eq. 15) of the own-ship at τ; with no valid target, max_τ ζ.  Not
    differentiable (used by the grid search).  Details: ``sbmpc_i [B, O, S]`` (with ζ) and ``zeta [B]``
    (max_τ ζ alone)."""

    name = "sbmpc"
    PARAMS = ()

    hazard: SbmpcHazardTerm = SbmpcHazardTerm(risk="crisp", colregs="boolean")
    eta1: float = DEFAULT_ETA1
    eta2: float = DEFAULT_ETA2
    d_safe_g: float = 10.0
    d_close: float = DEFAULT_D_CLOSE
    shape: str = "printed"

    smooth = False

    def __post_init__(self):
        if not isinstance(self.hazard, SbmpcHazardTerm) or self.hazard.aggregation != "max":
            raise ValueError("hazard must be an SbmpcHazardTerm with aggregation='max'")
        check_param("eta1", self.eta1, lo=0.0)
        check_param("eta2", self.eta2, lo=0.0)
        check_param("d_safe_g", self.d_safe_g, lo=0.0)
        check_param("d_close", self.d_close, lo=0.0, lo_open=True)
        check_choice("shape", self.shape, ZETA_SHAPES)

    @property
    def needs_applied(self) -> bool:
        return self.hazard.transitional

    def __call__(self, ctx: Context, params, config, samples) -> TermValue:
        h, valid = self.hazard.pair_hazard(ctx)
        z = zeta_cost(own_land_distance(ctx, config)[1:], ctx.t[1:, None], eta1=self.eta1, eta2=self.eta2,
                      d_safe=self.d_safe_g, d_close=self.d_close, shape=self.shape)         # [K, B]
        h = jnp.where(valid[None, :, None], h, 0.0) + z[:, None, :]                       # [K, O·S, B]
        z_max = jnp.max(z, axis=0) if z.shape[0] else jnp.zeros(z.shape[1:], z.dtype)
        n_o, n_s = ctx.scen_valid.shape
        if h.shape[0] == 0 or h.shape[1] == 0:
            return TermValue(z_max, {"sbmpc_i": jnp.zeros((z.shape[1], n_o, n_s), z.dtype), "zeta": z_max})
        per_target = jnp.max(h, axis=0)                                                   # [O·S, B]
        value = jnp.maximum(jnp.max(per_target, axis=0), z_max)
        return TermValue(value, {"sbmpc_i": per_target.T.reshape(-1, n_o, n_s), "zeta": z_max})

    def reference(self, own_traj, behaviour, situation, params, config, last_offsets=(1.0, 0.0)):
        """Float64 oracle: ζ from the exact polygon distances (NumPy), joined per (target, time) with the
        hazard's own float64 reference."""
        import numpy as np

        from .. import reference_smooth as rs

        own_traj = np.asarray(own_traj, dtype=float)
        t = np.arange(len(own_traj)) * float(config.dt)
        d = rs.land_distance(own_traj[:, :2], situation.polygons)
        z = np.where(d <= self.d_close,
                     (np.exp(-self.eta1 * np.abs(d - self.d_safe_g)) if self.shape == "printed" else
                      np.where(d >= self.d_safe_g, np.exp(-self.eta1 * (d - self.d_safe_g)),
                               1.0 + self.eta1 * (self.d_safe_g - d))) * np.exp(-self.eta2 * t), 0.0)
        hz = self.hazard
        applied = (rs.applied_trajectory(situation, behaviour, last_offsets, params, config) if hz.transitional
                   else None)
        return rs.sbmpc_cost(own_traj, rs.obstacle_targets(situation, params, config), t, component="joint",
                             aggregation="max", kappa=hz.kappa, lambda_T=hz.lambda_T if hz.transitional else 0.0,
                             applied_traj=applied, joint_extra=z, **hz.pair_kwargs())


__all__ = ["ZETA_SHAPES", "DEFAULT_ETA1", "DEFAULT_ETA2", "DEFAULT_D_CLOSE", "zeta_cost", "own_land_distance",
           "SbmpcZetaTerm"]
