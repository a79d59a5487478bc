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
* :func:`evaluation_seconds` / :func:`check_evaluation_time` — the *time* of an evaluation (samples x vessels x
  scored pairs, every run of every track file), refused above :func:`evaluation_time_limit` (1 h, or
  ``PSBMPC_EVALUATION_TIME_LIMIT``).

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
    n_pairs = scored_pairs(n_vessels, pairs)
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


# ------------------------------------------------------------------------------------------ evaluation time
#: Seconds of :func:`psbmpc_jax.evaltool.evaluate_tracks` per resampled sample: EVAL_TIME_S[0] per vessel
#: (resampling, manoeuvre detection) + EVAL_TIME_S[1] per scored pair (geometry, encounter windows, scores) +
#: EVAL_TIME_S[2].  Least-squares fit (rounded) to the medians of benchmarks/bench_evaluation_time.py on the 2-core
#: CPU machine (benchmarks/results/evaluation_time_cpu_20261129T194858Z.json: 2 x 10^5 samples with 2 / 3 / 5 / 8
#: vessels, own-ship and all-pairs scoring, 10^6 samples of one pair; load average 1.3-3.4): every recorded
#: evaluation within 0.9-1.35 times the model, the encounter-rich one (106 encounters) and 10^7 samples of one
#: pair (14.1 s) included.  The tested-limits record of 10^7 samples of one pair
#: (benchmarks/results/tested_limits_cpu_20261129T132410Z.json, case track_1e7: 79 s) timed a whole fresh process
#: (starting Python, building and validating the tracks) at a load average of 10-11 on the two cores: 6.2 times
#: this model's 12.9 s; the estimate is that of a lightly loaded machine.
EVAL_TIME_S = (0.45e-6, 0.085e-6, 0.3e-6)
#: Seconds one evaluation (every run of every track file one call scores) may take unless
#: ``PSBMPC_EVALUATION_TIME_LIMIT`` says otherwise.
EVALUATION_TIME_LIMIT_S = 3600.0
EVALUATION_TIME_ENV = "PSBMPC_EVALUATION_TIME_LIMIT"


def scored_pairs(n_vessels: int, pairs: str = "own") -> int:
    """The pairs an evaluation scores: ``own``: the own-ship against every other vessel (V - 1); ``all``: every
    ordered pair (V x (V - 1))."""
    return n_vessels * (n_vessels - 1) if pairs == "all" else max(n_vessels - 1, 0)


def evaluation_seconds(n_samples: float, n_vessels: int, pairs: str = "own") -> float:
    """Estimated seconds of scoring one run of ``n_vessels`` tracks resampled to ``n_samples`` (:data:`EVAL_TIME_S`)."""
    a, b, c = EVAL_TIME_S
    return float(n_samples) * (a * n_vessels + b * scored_pairs(n_vessels, pairs) + c)


def evaluation_time_limit() -> tuple[float | None, str]:
    """``(seconds, source)``: the time one evaluation may take; ``(None, ...)`` when
    ``PSBMPC_EVALUATION_TIME_LIMIT`` is ``off``."""
    from .update_time import limit_from_env

    return limit_from_env(EVALUATION_TIME_ENV, EVALUATION_TIME_LIMIT_S)


def _evaluation_total(runs, pairs: str) -> tuple[float, float, int]:
    """``(seconds, samples, most vessels)`` of the runs ``[(n_samples, n_vessels), ...]``."""
    runs = [(float(n), int(v)) for n, v in runs]
    return (sum(evaluation_seconds(n, v, pairs) for n, v in runs), sum(n for n, _ in runs),
            max((v for _, v in runs), default=0))


def check_evaluation_time(runs, pairs: str = "own", *, what: str, sample_interval: str, pairs_setting: str = "pairs",
                          hint: str = "", limit: tuple[float | None, str] | None = None) -> float:
    """Refuse an evaluation whose estimated time exceeds :func:`evaluation_time_limit`; returns the estimate [s].

    ``runs``: ``(n_samples, n_vessels)`` of every run the evaluation scores (:func:`evaluation_samples`);
    ``what``: the tracks in words, their file(s) named (``"tracks.csv"``); ``sample_interval``: the sample
    interval(s) with the setting that sets them (``"sample_interval_s = 1 s"``); ``pairs_setting``: the caller's
    name of the pair mode.  The message names them with the samples, vessels, pairs, the estimate and the limit."""
    from .update_time import fmt_seconds

    total, samples, n_v = _evaluation_total(runs, pairs)
    cap, source = limit if limit is not None else evaluation_time_limit()
    if cap is None or total <= cap:
        return total
    a, b, c = (x * 1e6 for x in EVAL_TIME_S)
    raise ResourceError(
        f"{what}: {len(runs)} run(s), {samples:.3g} samples in all ({sample_interval}) x up to {n_v} vessels, "
        f"{scored_pairs(n_v, pairs)} scored pair(s) per run ({pairs_setting} = {pairs}): scoring takes about "
        f"{fmt_seconds(total)} (samples x ({a:g} µs per vessel + {b:g} µs per pair + {c:g} µs), measured on a "
        f"2-core CPU); the limit is {fmt_seconds(cap)} ({source}). "
        + (f"{hint}; to" if hint else "Fewer or shorter tracks, a larger sample interval, or fewer pairs; to")
        + f" score them anyway, set {EVALUATION_TIME_ENV} to more seconds (or 'off')")


def describe_evaluation(runs, pairs: str = "own") -> str:
    """``about 12 s (3 run(s), 1e+07 samples x up to 2 vessels, 1 scored pair(s) per run)``: the estimate of
    :func:`check_evaluation_time` in words, for a log line."""
    from .update_time import fmt_seconds

    total, samples, n_v = _evaluation_total(runs, pairs)
    return (f"about {fmt_seconds(total)} ({len(runs)} run(s), {samples:.3g} samples x up to {n_v} "
            f"vessels, {scored_pairs(n_v, pairs)} scored pair(s) per run; estimated with times measured on a 2-core "
            f"CPU)")


# ------------------------------------------------------------------------------------------------ the solve
#: Bytes per (time step, behaviour) of one solve's buffers in float32 (scaled by itemsize / 4): XLA's compiled
#: memory analysis (temporaries + outputs) of :func:`psbmpc_jax.solve.solve` fitted over T = 150 / 600 s
#: (dt 0.5 s), 64 / 1 024 behaviours, 5 / 16 / 20 obstacle scenarios (docs/limits.md): 18.5 + 2.1 per obstacle
#: scenario (temporaries), 24.5 + 0.07 per obstacle scenario (the evaluation returned: trajectories, costs),
#: 24 with land (the grounding search; measured with one polygon).
SOLVE_PER_POINT = dict(base=43.0, per_scenario=2.2, land=24.0)
#: The collision estimator's chunk buffer: chunk_rows x time_block x width x itemsize x this factor (measured: mc
#: 1.00 at n_samples 2e4 / 8e4, ce 4.25 at ce_max_iter 2 and 6, quadrature: n_quad nodes).
ESTIMATOR_FACTOR = dict(quadrature=1.0, mc=1.0, ce=4.25)
#: Compiling and running JAX: the process's own memory besides the solve's buffers (measured RSS after compiling
#: one solve: 0.5 GB without land, 1.6-1.9 GB with the bounded grounding search).
RUNTIME_OVERHEAD = 2 * 2 ** 30


#: The psbmpc_2020 risk term (Monte Carlo + Kalman filter): bytes per (time step, obstacle scenario, behaviour,
#: sample) in float32 (measured: 4.25 at n_mc 100 / 1 000 / 4 000; peak RSS rose 314 MB for the 328 MB estimated).
MCSKF_PER_SAMPLE = 4.25


def solve_parts(config, n_behaviours: int, n_obstacle_scenarios: int, land: bool = True,
                n_mc: int = 0) -> dict:
    """The estimate of :func:`solve_bytes` by what drives it: ``{"horizon": ..., "estimator": ..., "n_mc": ...}``
    [bytes] (the per-point buffers, the collision estimator's chunk and sample table, the psbmpc_2020 term)."""
    item = 8 if config.dtype == "float64" else 4
    points = (config.n_steps + 1) * float(n_behaviours)
    c = SOLVE_PER_POINT
    per_point = c["base"] + c["per_scenario"] * n_obstacle_scenarios + (c["land"] if land else 0.0)
    width = {"quadrature": config.n_quad, "mc": config.n_samples}.get(config.estimator, config.n_samples)
    chunk = config.chunk_rows * min(config.time_block, config.n_steps + 1) * float(width) * item
    table = {"quadrature": 0, "mc": 2 * config.n_samples,
             "ce": 2 * config.n_samples * (config.ce_max_iter + 1)}[config.estimator] * item
    return {"horizon": per_point * points * item / 4,
            "estimator": ESTIMATOR_FACTOR[config.estimator] * chunk + table,
            "n_mc": MCSKF_PER_SAMPLE * points * n_obstacle_scenarios * float(n_mc) * item / 4}


def solve_bytes(config, n_behaviours: int, n_obstacle_scenarios: int, land: bool = True, n_mc: int = 0) -> float:
    """Estimated peak memory [bytes] of one :func:`psbmpc_jax.solve.solve` call of ``config`` (a
    :class:`~psbmpc_jax.params.PlannerConfig`) with ``n_behaviours`` behaviours and ``n_obstacle_scenarios``
    (obstacles x scenarios, padded), ``n_mc`` samples of the psbmpc_2020 risk term (0: not used), without the
    runtime overhead (:data:`RUNTIME_OVERHEAD`)."""
    return sum(solve_parts(config, n_behaviours, n_obstacle_scenarios, land, n_mc).values())


def padded_sizes(n_behaviours: int, n_obstacles: int, n_ps: int) -> tuple[int, int]:
    """The device capacities a solve of these sizes gets by default (as :mod:`psbmpc_jax.packing` buckets them,
    without importing JAX): behaviours to a multiple of 64, obstacles to a power of two (at least 1), scenarios
    exact up to 9 then to a multiple of 8.  Returns ``(B, O x S)``."""
    o = max(int(n_obstacles), 1)
    o = 1 << (o - 1).bit_length()
    s = n_ps if n_ps <= 9 else -(-n_ps // 8) * 8
    return -(-int(n_behaviours) // 64) * 64, o * s


#: What to change for each part of the estimate (the message names the largest).
SOLVE_SETTINGS = {"horizon": "PlannerConfig.T / dt (the horizon) and the behaviours",
                  "estimator": "PlannerConfig.n_samples (with chunk_rows x time_block)",
                  "n_mc": "the psbmpc_2020 term's n_mc"}


def check_solve(config, n_behaviours: int, n_obstacle_scenarios: int, land: bool = True, *, n_mc: int = 0,
                settings: dict | None = None, solves: int = 1, platform: str | None = None,
                limit: tuple[int | None, str] | None = None) -> float:
    """:func:`check` of ``solves`` simultaneous solves (a vmapped batch) plus :data:`RUNTIME_OVERHEAD`; returns the
    estimate.  The message names the setting behind the largest part of the estimate (``settings`` maps the
    parts of :func:`solve_parts` to the caller's names; default :data:`SOLVE_SETTINGS`)."""
    parts = solve_parts(config, n_behaviours, n_obstacle_scenarios, land, n_mc)
    est = solves * sum(parts.values()) + RUNTIME_OVERHEAD
    names = {**SOLVE_SETTINGS, **(settings or {})}
    top = max(parts, key=lambda name: parts[name])
    what = (f"{'one solve' if solves == 1 else f'{solves} solves at once'} ({config.n_steps} steps x "
            f"{n_behaviours} behaviours x {n_obstacle_scenarios} obstacle scenarios, estimator {config.estimator}"
            + (f" with n_samples = {config.n_samples}" if config.estimator != "quadrature" else "")
            + (f", n_mc = {n_mc}" if n_mc else "") + "; "
            + ", ".join(f"{k} {fmt_bytes(v)}" for k, v in parts.items() if v) + ")")
    hints = {"horizon": "A shorter horizon T (or a larger dt) or fewer behaviours",
             "estimator": "Fewer samples, or a smaller chunk_rows (the estimator's buffer is chunk_rows x "
                          "time_block x n_samples)",
             "n_mc": "Fewer n_mc samples, a shorter horizon or fewer behaviours"}
    check(names[top], est, what, hint=hints[top], platform=platform, limit=limit)
    return est


__all__ = ["ResourceError", "HEADROOM", "memory_limit", "check", "parse_bytes", "fmt_bytes", "evaluation_samples",
           "evaluation_bytes", "check_evaluation",
           "scored_pairs", "evaluation_seconds", "evaluation_time_limit", "check_evaluation_time",
           "describe_evaluation", "EVAL_TIME_S", "EVALUATION_TIME_LIMIT_S", "EVALUATION_TIME_ENV", "solve_bytes",
           "solve_parts", "check_solve", "padded_sizes", "RUNTIME_OVERHEAD"]
