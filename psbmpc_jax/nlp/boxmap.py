"""Smooth reparametrisations u = map(z) of a box [lower, upper] (elementwise), used by the ``"lbfgs"``
inner method so that an unconstrained quasi-Newton method handles the bounds.

Per component, by which bounds are finite (the maps of MINUIT's internal/external parameters):

* both:  ``u = l + (h - l) (1 + sin z) / 2``  (``kind="sin"``)  or  ``u = l + (h - l) (1 + tanh z) / 2``
  (``kind="tanh"``).  With ``sin`` an active bound is reached at a finite z (z = ±π/2) where the reduced
  problem in z has a NON-degenerate minimum (u - h ≈ -(h - l)(z - π/2)²/4), so L-BFGS converges to the bound
  superlinearly; with ``tanh`` the bound is only reached as z → ∓∞.
* lower only: ``u = l - 1 + sqrt(z² + 1)``;  upper only: ``u = h + 1 - sqrt(z² + 1)``;  none: ``u = z``.

Every map is smooth and onto its box.  Its derivative vanishes on the bound itself, so a start ON a bound
would freeze that component: :func:`inverse` first moves the start into the interior by ``margin`` (a
fraction of the width for two finite bounds, an absolute distance for one).  With ``sin`` and margin 1e-3
the derivative at the moved start is still 0.063·(h - l)/2 (with ``tanh``: 0.004·(h - l)/2).
Infinite bounds are handled with double ``where`` so that no NaN/inf reaches a gradient.
"""

from __future__ import annotations

import jax.numpy as jnp


def _parts(lower, upper):
    fl, fu = jnp.isfinite(lower), jnp.isfinite(upper)
    both, lo_only, up_only = fl & fu, fl & ~fu, ~fl & fu
    l = jnp.where(fl, lower, 0.0)
    h = jnp.where(fu, upper, 0.0)
    width = jnp.where(both, h - l, 1.0)
    return both, lo_only, up_only, l, h, width


def forward(z, lower, upper, kind: str = "sin"):
    """u = map(z) for the box [lower, upper] (arrays of z's shape, ±inf for a missing bound)."""
    both, lo_only, up_only, l, h, width = _parts(lower, upper)
    s = 0.5 * (1.0 + (jnp.sin(z) if kind == "sin" else jnp.tanh(z)))
    r = jnp.sqrt(z * z + 1.0)
    return jnp.where(both, l + width * s, jnp.where(lo_only, l - 1.0 + r, jnp.where(up_only, h + 1.0 - r, z)))


def inverse(u, lower, upper, kind: str = "sin", margin=1e-3):
    """A z with map(z) = u moved ``margin`` into the interior (u outside the box is first clipped)."""
    both, lo_only, up_only, l, h, width = _parts(lower, upper)
    wsafe = jnp.where(width > 0, width, 1.0)
    frac = jnp.clip((u - l) / wsafe, margin, 1.0 - margin)
    c = 2.0 * frac - 1.0
    z_both = jnp.arcsin(c) if kind == "sin" else jnp.arctanh(c)
    d_lo = jnp.maximum(jnp.where(lo_only, u - l, 1.0), margin)
    d_up = jnp.maximum(jnp.where(up_only, h - u, 1.0), margin)
    z_lo = jnp.sqrt((d_lo + 1.0) ** 2 - 1.0)
    z_up = jnp.sqrt((d_up + 1.0) ** 2 - 1.0)
    return jnp.where(both, z_both, jnp.where(lo_only, z_lo, jnp.where(up_only, z_up, u)))


__all__ = ["forward", "inverse"]
