"""Limits derived from resources: memory estimates from shapes, checked before anything is allocated.

A setting that is inside its documented range can still ask for more memory than the machine has (a horizon of
50 000 s, a 10⁷-sample Monte Carlo estimate, a track of 10⁹ samples).  Rather than fail deep inside XLA or NumPy
with an out-of-memory traceback — or after a long simulation, losing its results — the entry points estimate
the memory of the work from its shapes and refuse it up front with :class:`ResourceError`, naming the setting,
the estimate and the limit.

* :func:`memory_limit` — the memory the work may use: the available memory of the host (``psutil`` when
  installed, else ``/proc/meminfo`` MemAvailable, else ``os.sysconf``), or of the accelerator
  (``Device.memory_stats``); the environment variable ``PSBMPC_MEMORY_LIMIT`` (bytes, or ``"8GiB"``,
  ``"500MB"``) overrides it.
* :func:`evaluation_bytes` — the peak memory of scoring one run of tracks (:func:`psbmpc_jax.evaltool.evaluate_tracks`).
* :func:`solve_bytes` — the peak memory of one grid-search solve (:func:`psbmpc_jax.solve.solve`) from its
  configuration and padded sizes.
* :func:`check` — refuse an estimate above the limit.

The estimates are linear models of the dominant arrays whose coefficients were measured (peak traced NumPy
memory for the evaluation, XLA's compiled memory analysis and the process's peak RSS for the solve; the
measurements are in ``docs/limits.md``).  They are estimates: the check leaves a margin
(:data:`HEADROOM`), and a refusal says how to shrink the work.
"""

from __future__ import annotations

import logging
import math
import os
import re

log = logging.getLogger(__name__)

#: Fraction of the memory limit an estimate may take (the rest: the interpreter, JAX's runtime, estimation error).
HEADROOM = 0.8

_UNITS = {"": 1, "b": 1, "kb": 10 ** 3, "mb": 10 ** 6, "gb": 10 ** 9, "tb": 10 ** 12, "kib": 2 ** 10,
          "mib": 2 ** 20, "gib": 2 ** 30, "tib": 2 ** 40}


class ResourceError(ValueError):
    """A setting asks for more memory than the limit: the message names the setting, the estimate and the limit."""


def parse_bytes(text: str, where: str = "PSBMPC_MEMORY_LIMIT") -> int:
    """``"8GiB"``, ``"500 MB"``, ``"123456"`` -> bytes (ValueError naming ``where`` otherwise)."""
    m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+(?:[eE][+-]?[0-9]+)?)\s*([A-Za-z]*)\s*", str(text))
    if not m or m.group(2).lower() not in _UNITS:
        raise ValueError(f"{where} must be a number of bytes, optionally with a unit (B, kB, MB, GB, KiB, MiB, "
                         f"GiB, TiB), got {text!r}")
    v = float(m.group(1)) * _UNITS[m.group(2).lower()]
    if not (math.isfinite(v) and v > 0):
        raise ValueError(f"{where} must be > 0 bytes, got {text!r}")
    return int(v)


def fmt_bytes(n: float) -> str:
    """``1.5 GiB``, ``320 MiB``, ``12 KiB``."""
    for unit, size in (("TiB", 2 ** 40), ("GiB", 2 ** 30), ("MiB", 2 ** 20), ("KiB", 2 ** 10)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{int(n)} B"


def _host_available() -> tuple[int | None, str]:
    try:
        import psutil                                   # optional

        return int(psutil.virtual_memory().available), "available host memory (psutil)"
    except ImportError:
        pass
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024, "available host memory (/proc/meminfo MemAvailable)"
    except (OSError, ValueError, IndexError):
        pass
    try:
        return (int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE")),
                "free host memory (os.sysconf)")
    except (ValueError, OSError, AttributeError):
        return None, "unknown"


def _cgroup_limit() -> int | None:
    """The remaining memory of this process's cgroup (v2), if it has a limit."""
    try:
        with open("/sys/fs/cgroup/memory.max", encoding="ascii") as fh:
            cap = fh.read().strip()
        if cap == "max":
            return None
        with open("/sys/fs/cgroup/memory.current", encoding="ascii") as fh:
            return max(0, int(cap) - int(fh.read().strip()))
    except (OSError, ValueError):
        return None


def memory_limit(platform: str | None = None) -> tuple[int | None, str]:
    """``(bytes, source)``: the memory a new piece of work may use, and where the number comes from.

    ``platform``: ``"cpu"`` (host memory), ``"gpu"`` / ``"tpu"`` (the first such device's
    ``memory_stats()``: bytes_limit − bytes_in_use), or None (JAX's default backend if JAX is imported, else the
    host).  ``PSBMPC_MEMORY_LIMIT`` overrides it.  ``(None, "unknown")`` when nothing can be read: then nothing
    is refused."""
    env = os.environ.get("PSBMPC_MEMORY_LIMIT")
    if env:
        return parse_bytes(env), "PSBMPC_MEMORY_LIMIT"
    if platform is None:
        import sys

        platform = "cpu"
        if "jax" in sys.modules:
            try:
                platform = sys.modules["jax"].default_backend()
            except RuntimeError:
                platform = "cpu"
    if platform != "cpu":
        try:
            import jax

            dev = jax.devices(platform)[0]
            stats = dev.memory_stats() or {}
            if "bytes_limit" in stats:
                return (int(stats["bytes_limit"]) - int(stats.get("bytes_in_use", 0)),
                        f"free memory of {dev.device_kind} (memory_stats)")
        except (RuntimeError, ValueError, IndexError):
            pass
    avail, source = _host_available()
    cg = _cgroup_limit()
    if cg is not None and (avail is None or cg < avail):
        return cg, "remaining memory of this process's cgroup (/sys/fs/cgroup/memory.max)"
    return avail, source


def check(setting: str, estimate: float, what: str, hint: str = "", platform: str | None = None,
          limit: tuple[int | None, str] | None = None) -> None:
    """Raise :class:`ResourceError` when ``estimate`` bytes exceed :data:`HEADROOM` of the memory limit.

    ``setting``: the setting(s) to change (``"mpc.config.T"``); ``what``: the work and its shape in words;
    ``hint``: how to shrink it."""
    cap, source = limit if limit is not None else memory_limit(platform)
    if cap is None:
        log.debug("memory limit unknown: %s (%s) not checked", what, fmt_bytes(estimate))
        return
    if estimate > HEADROOM * cap:
        raise ResourceError(
            f"{setting}: {what} needs about {fmt_bytes(estimate)} of memory; the limit is {fmt_bytes(HEADROOM * cap)} "
            f"({HEADROOM:.0%} of the {source}, {fmt_bytes(cap)})" + (f". {hint}" if hint else ""))


# ------------------------------------------------------------------------------------------------ evaluation
#: Peak bytes of :func:`psbmpc_jax.evaltool.evaluate_tracks` per resampled sample: 8 x (4 per vessel + 3 per
#: scored pair + 6), measured with tracemalloc (n = 1e5, 3e5; 2-5 vessels; "own" and "all" pairs: 17, 24, 36 and
#: 38 words per sample, fitted exactly), times a margin of 1.5 for encounter-rich tracks.
EVAL_WORDS = (4.0, 3.0, 6.0)
EVAL_MARGIN = 1.5


def evaluation_samples(span_s: float, dt: float) -> int:
    """Samples of the common grid an evaluation resamples onto: floor(span / dt) + 1 (float: no overflow)."""
    return int(min(math.floor(span_s / dt + 1e-9) + 1, 2 ** 62))


def evaluation_bytes(n_samples: int, n_vessels: int, pairs: str = "own") -> float:
    """Estimated peak memory [bytes] of scoring one run of ``n_vessels`` tracks resampled to ``n_samples``."""
    n_pairs = n_vessels * (n_vessels - 1) if pairs == "all" else max(n_vessels - 1, 0)
    a, b, c = EVAL_WORDS
    return EVAL_MARGIN * 8.0 * float(n_samples) * (a * n_vessels + b * n_pairs + c)


TRACKS_HINT = "Use a larger sample interval or shorter tracks (timestamps in milliseconds where seconds belong?)"


def check_evaluation(span_s: float, dt: float, n_vessels: int, pairs: str = "own", *, setting: str,
                     hint: str = TRACKS_HINT, limit: tuple[int | None, str] | None = None) -> int:
    """The number of samples of an evaluation, after :func:`check` of its memory (``setting`` names what to
    change, e.g. ``"evaluation.sample_interval_s"``)."""
    n = evaluation_samples(span_s, dt)
    est = evaluation_bytes(n, n_vessels, pairs)
    check(setting, est, f"scoring tracks of {span_s:.6g} s sampled every {dt:.6g} s ({n:.3g} samples) x "
                        f"{n_vessels} vessels", hint=hint, platform="cpu", limit=limit)
    return n


__all__ = ["ResourceError", "HEADROOM", "memory_limit", "check", "parse_bytes", "fmt_bytes", "evaluation_samples",
           "evaluation_bytes", "check_evaluation"]
