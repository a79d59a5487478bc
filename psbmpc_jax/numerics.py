"""Small numerical helpers shared by the device kernels (pure jax.numpy), and their host (NumPy float64) twins.

The one angle wrap of the package: :func:`wrap_angle` on the device, :func:`wrap_angle_host` on the host (the
closed-loop simulator, the metrics, the chart projection, the float64 oracles, the evaluation tool).  JAX is
imported inside the device helpers, not at the top: modules that must not import JAX (the chart and scenario
loaders, the oracles, the evaluation tool) use the host helpers from here."""

from __future__ import annotations

import math

import numpy as np

TWO_PI = 2.0 * math.pi


def wrap_angle(a):
    """Wrap angles to [-pi, pi) (jax.numpy, traceable; derivative 1): ``a - 2 pi floor((a + pi) / 2 pi)``."""
    import jax.numpy as jnp

    return a - TWO_PI * jnp.floor((a + math.pi) / TWO_PI)


def wrap_angle_host(a, *, include_pi: bool = False):
    """Wrap angles on the host, in float64: to [-pi, pi), ``(a + pi) mod 2 pi - pi`` (both ends map to -pi);
    with ``include_pi`` to (-pi, pi], ``pi - (pi - a) mod 2 pi`` = ``-wrap_angle_host(-a)`` (both ends map to +pi:
    a relative bearing of exactly 180 deg stays +180 deg).

    A Python float for a Python number, else a NumPy array or scalar (never a JAX array, whatever the JAX dtype
    settings); it agrees with :func:`wrap_angle` to a few ulp (floor and mod round differently).  At the ends the
    sum rounds: an input within an ulp beyond an odd multiple of pi can give the other end (+pi, resp. -pi)."""
    if type(a) is float and not include_pi:          # the fast path (the float64 oracle's inner loops)
        return (a + math.pi) % TWO_PI - math.pi
    if isinstance(a, (float, int)) and not isinstance(a, bool):
        if include_pi:
            return math.pi - (math.pi - float(a)) % TWO_PI
        return (float(a) + math.pi) % TWO_PI - math.pi
    if include_pi:
        return math.pi - np.mod(math.pi - np.asarray(a, dtype=float), TWO_PI)
    return np.mod(np.asarray(a, dtype=float) + math.pi, TWO_PI) - math.pi


def normal_cdf(x):
    """Standard normal CDF."""
    from jax.scipy.special import ndtr

    return ndtr(x)


def safe_sqrt(x):
    """sqrt with a finite gradient at 0 (double-where)."""
    import jax.numpy as jnp

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


def ordered_sum(x, first_axis: int = 1):
    """The sum of ``x`` over its axes from ``first_axis`` on, added one element after the other in row-major order
    (a left fold): the order is fixed by this code, not chosen by the compiler, so a solve's sum has the same
    bits whatever the batch it is computed in (``jnp.sum`` lets XLA pick the order, and XLA:CPU picks it by the
    whole array's shape: the same solve summed in a vmapped batch of 8 or of 4 differed in the last bit)."""
    flat = x.reshape(x.shape[:first_axis] + (-1,))
    total = flat[..., 0]
    for j in range(1, flat.shape[-1]):
        total = total + flat[..., j]
    return total

