"""Array types for annotations: what a field may hold, and the shapes of the kernels' arguments and results.

:data:`HostOrDevice`: a field filled with NumPy arrays on the host (validated inputs, results brought back with
``jax.device_get``) and with JAX arrays (or tracers) inside a jitted function; the pytrees the host oracles and
the device kernels share (the packed inputs, a corridor, static circles, a smooth plan) hold either.

:class:`Shape`: the shape of an array argument or result, written in the annotation
(``Annotated[jax.Array, Shape("B n_M 2")]``, the notation of the jaxtyping package without depending on it).
Dimension names are the documentation's (``B`` behaviours, ``n_M`` maneuvers, ``O`` obstacles, ``S`` scenarios
per obstacle, ``P`` polygons, ``N`` time steps, ``R`` rollout rows); an integer is a fixed size and
``Shape("")`` a scalar.  Nothing is checked when the functions run (the hot path stays as it is);
:func:`check_shapes` checks arrays against the annotations of a function or a NamedTuple, binding each name to
one size (the tests call it on small cases, ``tests/test_array_types.py``).
"""

from __future__ import annotations

import typing
from dataclasses import dataclass
from typing import Any, TypeAlias, Union

import jax
import numpy as np

HostOrDevice: TypeAlias = Union[jax.Array, np.ndarray]


@dataclass(frozen=True)
class Shape:
    """A shape in an ``Annotated`` annotation: dimension names (or integer sizes) separated by spaces, ``""``
    for a scalar."""

    dims: str

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.dims.split())

    def check(self, shape: tuple, sizes: dict[str, int], what: str) -> None:
        """ValueError when ``shape`` does not match, naming ``what``; binds the names not yet in ``sizes``."""
        names = self.names
        if len(shape) != len(names):
            raise ValueError(f"{what}: shape {tuple(shape)} has {len(shape)} axes, the annotation "
                             f"[{self.dims}] has {len(names)}")
        for axis, (name, size) in enumerate(zip(names, shape)):
            want = int(name) if name.isdigit() else sizes.setdefault(name, int(size))
            if int(size) != want:
                raise ValueError(f"{what}: axis {axis} ({name}) has size {int(size)}, expected {want} "
                                 f"(annotation [{self.dims}])")


def _shape(hint: Any) -> Shape | None:
    return next((m for m in getattr(hint, "__metadata__", ()) if isinstance(m, Shape)), None)


def shapes_of(obj: Any) -> dict[str, Any]:
    """The :class:`Shape` annotations of a function's parameters and result (key ``"return"``) or of a
    NamedTuple's fields, by name (names without one are left out).  A result annotated as a tuple of arrays
    (``tuple[Annotated[...], int]``) gives a tuple with one :class:`Shape` (or None) per element; one of any
    length (``tuple[Annotated[...], ...]``) gives ``(shape, Ellipsis)``, every element that shape."""
    hints = typing.get_type_hints(obj, include_extras=True)
    out: dict[str, Any] = {}
    for name, hint in hints.items():
        shape = _shape(hint)
        if shape is not None:
            out[name] = shape
        elif typing.get_origin(hint) is tuple:
            parts = tuple(a if a is Ellipsis else _shape(a) for a in typing.get_args(hint))
            if any(isinstance(p, Shape) for p in parts):
                out[name] = parts
    return out


def check_shapes(annotated: Any, values: dict[str, Any], sizes: dict[str, int] | None = None) -> dict[str, int]:
    """Check ``values`` (name -> array; ``"return"`` for a function's result) against the :class:`Shape`
    annotations of ``annotated`` (a function or a NamedTuple); every name of ``values`` must be annotated.
    Returns the sizes the dimension names were bound to (pass ``sizes`` to share them between calls)."""
    sizes = {} if sizes is None else sizes
    shapes = shapes_of(annotated)
    where = getattr(annotated, "__qualname__", repr(annotated))
    for name, value in values.items():
        if name not in shapes:
            raise ValueError(f"{where}.{name} has no Shape annotation (annotated: {sorted(shapes)})")
        shape = shapes[name]
        if isinstance(shape, Shape):
            shape.check(np.shape(value), sizes, f"{where}.{name}")
            continue
        if len(shape) == 2 and shape[1] is Ellipsis:
            shape = (shape[0],) * len(value) if isinstance(value, tuple) else shape
        if not isinstance(value, tuple) or len(value) != len(shape):
            raise ValueError(f"{where}.{name}: expected a tuple of {len(shape)}, got {type(value).__name__}")
        for k, (part, v) in enumerate(zip(shape, value)):
            if part is not None:
                part.check(np.shape(v), sizes, f"{where}.{name}[{k}]")
    return sizes


__all__ = ["HostOrDevice", "Shape", "shapes_of", "check_shapes"]
