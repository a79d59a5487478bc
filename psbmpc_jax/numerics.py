"""Small numerical helpers shared by the device kernels (pure jax.numpy), and the host (NumPy float64) twin
of :func:`wrap_angle` that the closed-loop simulator steps and measures with."""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
from jax.scipy.special import ndtr

TWO_PI = 2.0 * math.pi


def wrap_angle(a):
    """Wrap angles to [-pi, pi)."""
    return a - TWO_PI * jnp.floor((a + math.pi) / TWO_PI)


def wrap_angle_host(a):
    """Wrap angles to [-pi, pi) on the host, in float64: ``(a + pi) mod 2 pi - pi``.

    A Python float for a Python number, else a NumPy array (never a JAX array, whatever the JAX dtype
    settings); it agrees with :func:`wrap_angle` to a few ulp (floor and mod round differently)."""
    if isinstance(a, (float, int)) and not isinstance(a, bool):
        return (float(a) + math.pi) % TWO_PI - math.pi
    return np.mod(np.asarray(a, dtype=float) + math.pi, TWO_PI) - math.pi


def normal_cdf(x):
    """Standard normal CDF."""
    return ndtr(x)


def safe_sqrt(x):
    """sqrt with a finite gradient at 0 (double-where)."""
    pos = x > 0
    return jnp.where(pos, jnp.sqrt(jnp.where(pos, x, 1.0)), 0.0)


def shift_controls(controls, steps: int):
    """A kept sequence ``[..., N, 2]`` as seen ``steps`` steps later: rows ``steps…N−1``, then the last row
    repeated (host NumPy; ``steps`` in [0, N]): a receding-horizon plan handed to the next update as a start."""
    c = np.asarray(controls)
    n = c.shape[-2]
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or not 0 <= steps <= n:
        raise ValueError(f"steps must be an integer in [0, {n}], got {steps!r}")
    if steps == 0:
        return c.copy()
    tail = np.repeat(c[..., -1:, :], steps, axis=-2)
    return np.concatenate([c[..., steps:, :], tail], axis=-2)
