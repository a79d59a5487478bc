"""Persistent XLA compilation cache for library users and the command line.

Compiling the planner takes a few seconds per problem shape; with the cache enabled a later process that
solves the same shapes loads the compiled program from disk instead::

    import psbmpc_jax
    psbmpc_jax.enable_compilation_cache()            # ~/.cache/psbmpc_jax, or $PSBMPC_JAX_CACHE
    psbmpc_jax.enable_compilation_cache("/tmp/jc")   # a folder of your choice

``psbmpc-jax example`` and ``psbmpc-jax run`` call it; ``psbmpc-jax bench`` does not (its compile times must
be real compiles).
"""

from __future__ import annotations

import os
import pathlib

__all__ = ["DEFAULT_CACHE_ENV", "default_cache_dir", "enable_compilation_cache"]

#: Environment variable that overrides the default cache folder.
DEFAULT_CACHE_ENV = "PSBMPC_JAX_CACHE"


def default_cache_dir() -> pathlib.Path:
    """``$PSBMPC_JAX_CACHE`` if set, else ``~/.cache/psbmpc_jax``."""
    env = os.environ.get(DEFAULT_CACHE_ENV)
    return pathlib.Path(env).expanduser() if env else pathlib.Path.home() / ".cache" / "psbmpc_jax"


def enable_compilation_cache(path=None, *, min_compile_time_s: float = 0.5) -> pathlib.Path | None:
    """Store compiled XLA programs in ``path`` and reuse them in later processes.

    Args:
        path: cache folder, created if missing.  Default: ``$PSBMPC_JAX_CACHE`` if set, else the folder JAX
            is configured with already (``jax_compilation_cache_dir``, e.g. from ``JAX_COMPILATION_CACHE_DIR``),
            else ``~/.cache/psbmpc_jax``.
        min_compile_time_s: only programs that took at least this long to compile are stored.

    Returns:
        The folder in use, or ``None`` when it cannot be created or written (the process then runs without a
        persistent cache; nothing is raised, the cache is an optimisation only) or when the cache configured
        already is a remote URL (kept as it is).

    Call it before the first solve: JAX opens the cache at the first compilation of the process. Calling it
    again with another folder switches to that folder for later compilations.
    """
    import jax

    if path is not None:
        folder = pathlib.Path(path).expanduser()
    elif not os.environ.get(DEFAULT_CACHE_ENV) and jax.config.jax_compilation_cache_dir:  # type: ignore[attr-defined]  # jax's Config stub lacks its flags
        configured = str(jax.config.jax_compilation_cache_dir)  # type: ignore[attr-defined]  # jax's Config stub lacks its flags
        if "://" in configured:   # a remote cache (gs://...) configured by the user: leave it as it is
            jax.config.update("jax_persistent_cache_min_compile_time_secs", float(min_compile_time_s))
            return None
        folder = pathlib.Path(configured)   # keep the folder already in use
    else:
        folder = default_cache_dir()
    try:
        folder.mkdir(parents=True, exist_ok=True)
        if not os.access(folder, os.W_OK | os.X_OK):
            return None
    except OSError:  # read-only home, a file in the way: run without the cache
        return None
    folder = folder.resolve()
    if jax.config.jax_compilation_cache_dir != str(folder):  # type: ignore[attr-defined]  # jax's Config stub lacks its flags
        jax.config.update("jax_compilation_cache_dir", str(folder))
        try:  # a cache JAX already opened keeps its folder until reset
            from jax.experimental.compilation_cache import compilation_cache

            compilation_cache.reset_cache()
        except (ImportError, AttributeError):  # pragma: no cover - older/newer JAX without it
            pass
    jax.config.update("jax_persistent_cache_min_compile_time_secs", float(min_compile_time_s))
    return folder
