"""Small numerical helpers shared by the device kernels (pure jax.numpy)."""

from __future__ import annotations

import math

import jax.numpy as jnp
from jax.scipy.special import ndtr

TWO_PI = 2.0 * math.pi


def wrap_angle(a):
    """Wrap angles to [-pi, pi)."""
    return a - TWO_PI * jnp.floor((a + math.pi) / TWO_PI)


def normal_cdf(x):
    """Standard normal CDF."""
    return ndtr(x)


def safe_sqrt(x):
    """sqrt with a finite gradient at 0 (double-where)."""
    pos = x > 0
    return jnp.where(pos, jnp.sqrt(jnp.where(pos, x, 1.0)), 0.0)
