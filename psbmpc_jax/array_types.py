"""Array types for annotations (no runtime effect).

:data:`HostOrDevice`: a field filled with NumPy arrays on the host (validated inputs, results brought back with
``jax.device_get``) and with JAX arrays (or tracers) inside a jitted function; the pytrees the host oracles and
the device kernels share (the packed inputs, a corridor, static circles, a smooth plan) hold either.
"""

from __future__ import annotations

from typing import TypeAlias, Union

import jax
import numpy as np

HostOrDevice: TypeAlias = Union[jax.Array, np.ndarray]

__all__ = ["HostOrDevice"]
