"""``jax.jit`` with the call bound to the function's signature first: one compiled program per shape.

``jax.jit`` keys its cache on how the arguments were passed: ``solve(inputs, state, params, samples,
config=c)`` and ``solve(..., config=c, terms=DEFAULT_TERMS)`` (what :class:`psbmpc_jax.Planner` passes) are two
entries, two compiles of the same program (about 5 s each at paper scale).  :func:`canonical_jit` binds every call
to the signature, fills in the defaults and passes the arguments the same way every time: leading parameters
positionally, the static ones and everything after the first static one by keyword.
"""

from __future__ import annotations

import functools
import inspect
from typing import Any, Callable, ParamSpec, Protocol, TypeVar, cast

import jax

_P = ParamSpec("_P")
_R = TypeVar("_R", covariant=True)


class WithJitted(Protocol[_P, _R]):
    """A public function (argument checks, then its jitted program) whose program is ``.jitted`` (to lower, count
    its compiled entries, ...), typed: calls keep the function's signature."""

    jitted: Any

    def __call__(self, *args: _P.args, **kwargs: _P.kwargs) -> _R: ...


def with_jitted(jitted: Any) -> Callable[[Callable[_P, _R]], WithJitted[_P, _R]]:
    """Decorator: attach ``jitted`` (a ``jax.jit`` or :class:`CanonicalJit` program) to the function as
    ``.jitted``; the function is returned unchanged."""

    def attach(fun: Callable[_P, _R]) -> WithJitted[_P, _R]:
        setattr(fun, "jitted", jitted)
        return cast("WithJitted[_P, _R]", fun)      # it has .jitted now (set just above)
    return attach


class CanonicalJit:
    """A jitted function (``jax.jit(fun, static_argnames=...)``) whose calls, :meth:`lower` and :meth:`trace`
    pass the arguments in one canonical way.  ``__wrapped__`` is the plain function."""

    def __init__(self, fun, static_argnames: tuple[str, ...]):
        functools.update_wrapper(self, fun)
        self._sig = inspect.signature(fun)
        self._static = tuple(static_argnames)
        names = list(self._sig.parameters)
        first_static = min(names.index(n) for n in self._static)
        self._positional = tuple(names[:first_static])
        self._jit = jax.jit(fun, static_argnames=self._static)

    def _bind(self, args, kwargs):
        b = self._sig.bind(*args, **kwargs)
        b.apply_defaults()
        a = b.arguments
        return [a[n] for n in self._positional], {n: v for n, v in a.items() if n not in self._positional}

    def __call__(self, *args, **kwargs):
        pos, kw = self._bind(args, kwargs)
        return self._jit(*pos, **kw)

    def lower(self, *args, **kwargs):
        """``jax.jit(...).lower`` of the canonical call; its ``compile()`` returns a program that binds its
        (dynamic) arguments the same way, so ``solve.lower(*a, config=c).compile()(*a)`` works."""
        pos, kw = self._bind(args, kwargs)
        return _Lowered(self._jit.lower(*pos, **kw), self)

    def trace(self, *args, **kwargs):
        pos, kw = self._bind(args, kwargs)
        return self._jit.trace(*pos, **kw)

    def _cache_size(self) -> int:
        return self._jit._cache_size()  # type: ignore[attr-defined]  # the stub of jax.jit's result lacks these methods

    def clear_cache(self) -> None:
        self._jit.clear_cache()  # type: ignore[attr-defined]  # the stub of jax.jit's result lacks these methods


class _Lowered:
    """A lowered canonical call (attributes of JAX's ``Lowered`` pass through)."""

    def __init__(self, lowered, owner: CanonicalJit):
        self._lowered, self._owner = lowered, owner

    def compile(self, *args, **kwargs):
        return _Compiled(self._lowered.compile(*args, **kwargs), self._owner)

    def __getattr__(self, name):
        return getattr(self._lowered, name)


class _Compiled:
    """A compiled canonical call: called with the dynamic arguments only, bound like :class:`CanonicalJit`'s
    (defaults filled in); attributes of JAX's ``Compiled`` (``memory_analysis``, ``as_text``, ...) pass through."""

    def __init__(self, compiled, owner: CanonicalJit):
        self._compiled = compiled
        params = [p for n, p in owner._sig.parameters.items() if n not in owner._static]
        self._sig = owner._sig.replace(parameters=params)
        self._positional = owner._positional

    def __call__(self, *args, **kwargs):
        b = self._sig.bind(*args, **kwargs)
        b.apply_defaults()
        a = b.arguments
        return self._compiled(*[a[n] for n in self._positional],
                              **{n: v for n, v in a.items() if n not in self._positional})

    def __getattr__(self, name):
        return getattr(self._compiled, name)


def canonical_jit(*, static_argnames: tuple[str, ...]):
    """Decorator: :class:`CanonicalJit` of the function."""
    return lambda fun: CanonicalJit(fun, static_argnames)


__all__ = ["CanonicalJit", "canonical_jit"]
