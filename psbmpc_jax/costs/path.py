"""Path / control-deviation cost H_p (eq. 17; docs/algorithm.md §8)."""

from __future__ import annotations

import jax.numpy as jnp

from ..numerics import wrap_angle
from .base import Context, TermValue, cost_term


def _f(u, chi, p):
    k_chi = jnp.where(chi < 0, p.K_chi_port, p.K_chi_stbd)
    return p.K_u * (1.0 - u) + k_chi * chi * chi


def _h(u, chi, u_prev, chi_prev, p):
    dchi = wrap_angle(chi - chi_prev)
    k_dchi = jnp.where(dchi < 0, p.K_dchi_port, p.K_dchi_stbd)
    return p.K_du * jnp.abs(u - u_prev) + k_dchi * dchi * dchi


def path_cost(offsets, last_offsets, params):
    """H_p for every behaviour: ``offsets [B, n_M, 2]``, ``last_offsets [2]`` (u, chi) -> ``[B]``."""
    u, chi = offsets[..., 0], offsets[..., 1]
    n_m = offsets.shape[1]
    first = (jnp.sum(_f(u, chi, params), axis=1)
             + _h(u[:, 0], chi[:, 0], last_offsets[0], last_offsets[1], params)) / n_m
    if n_m == 1:
        return first
    change = jnp.sum(_h(u[:, 1:], chi[:, 1:], u[:, :-1], chi[:, :-1], params), axis=1) / (n_m - 1)
    return first + change


@cost_term
class PathTerm:
    """H_p (eq. 17): deviation from the nominal speed and course and from the last applied offsets.
    For per-step controls (n_M = N) the same formula averages over the N steps."""

    name = "path"
    PARAMS = ("K_u", "K_du", "K_chi_stbd", "K_chi_port", "K_dchi_stbd", "K_dchi_port")
    smooth = True            # piecewise smooth: the port/starboard weights switch at 0

    def __call__(self, ctx: Context, params, config, samples) -> TermValue:
        return TermValue(path_cost(ctx.offsets, ctx.last_offsets, params))
