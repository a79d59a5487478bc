"""Shared helpers of the benchmark scripts: environment metadata, timing statistics, result files."""

from __future__ import annotations

import datetime as dt
import json
import os
import platform
import statistics

import jax
import numpy as np

from psbmpc_jax.provenance import commit


def jaxlib_version():
    try:
        import jaxlib

        return jaxlib.__version__
    except (ImportError, AttributeError):
        return None


def stats(times_s):
    q = statistics.quantiles(times_s, n=4)
    ms = lambda v: round(v * 1e3, 3)
    return {"median_ms": ms(statistics.median(times_s)), "min_ms": ms(min(times_s)), "max_ms": ms(max(times_s)),
            "q1_ms": ms(q[0]), "q3_ms": ms(q[2]), "n": len(times_s)}


def time_compiled(prepared, config, repeats: int, warmup: int = 1):
    """Compile the solve step for ``prepared = (inputs, state, params, samples)`` (from ``Planner.prepare``;
    timed separately), run ``warmup`` untimed calls, then ``repeats`` timed calls with ``block_until_ready``.
    Returns (compile_s, times_s, last Evaluation)."""
    import time

    from psbmpc_jax.solve import solve

    t0 = time.perf_counter()
    compiled = solve.lower(*prepared, config=config).compile()
    compile_s = time.perf_counter() - t0
    for _ in range(warmup):
        jax.block_until_ready(compiled(*prepared))
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = jax.block_until_ready(compiled(*prepared))
        times.append(time.perf_counter() - t0)
    return compile_s, times, out[2]


def time_interleaved(slots, repeats: int) -> list:
    """Time ``slots`` (dicts with ``point``, a dict, and ``call``, a no-argument function returning device
    arrays) round-robin: one untimed call each, then ``repeats`` rounds timing every slot once per round with
    ``block_until_ready`` (the machine's slow and fast spells fall on every slot alike).  Returns one point per
    slot: its ``point`` with :func:`stats` of its times."""
    import time

    for s in slots:
        jax.block_until_ready(s["call"]())
    times = [[] for _ in slots]
    for _ in range(repeats):
        for s, t in zip(slots, times):
            t0 = time.perf_counter()
            jax.block_until_ready(s["call"]())
            t.append(time.perf_counter() - t0)
    return [dict(s["point"], **stats(t)) for s, t in zip(slots, times)]


def environment_meta(benchmark: str, **extra) -> dict:
    """Device, versions, commit and date of this run (recorded with every result file)."""
    dev = jax.devices()[0]
    return {"benchmark": benchmark, "device_kind": dev.device_kind, "platform": dev.platform,
            "n_devices": jax.device_count(), "cpu_count": os.cpu_count(), "machine": platform.machine(),
            "python": platform.python_version(), "jax": jax.__version__, "jaxlib": jaxlib_version(),
            "numpy": np.__version__, "commit": commit(),
            "date": dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds"), **extra}


def write_results(out: str, prefix: str, meta: dict, points: list) -> str:
    """Write ``<out>/<prefix>_<platform>_<UTC timestamp>.json`` and return its path."""
    os.makedirs(out, exist_ok=True)
    stamp = dt.datetime.now(dt.timezone.utc).strftime("%Y%m%dT%H%M%SZ")
    path = os.path.join(out, f"{prefix}_{meta['platform']}_{stamp}.json")
    with open(path, "w") as fh:
        json.dump({"meta": meta, "points": points}, fh, indent=1)
    print(f"wrote {path}")
    return path


def interleaved_parser(description: str, repeats: int):
    """The command line of an interleaved benchmark script: ``--repeats`` and ``--out`` (default: results/)."""
    import argparse

    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("--repeats", type=int, default=repeats)
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "results"))
    return ap


def run_interleaved(slots, args, prefix: str, benchmark: str, hide=(), **extra) -> str:
    """:func:`time_interleaved` over ``slots`` with ``args.repeats``, one line per point printed (floats to 4
    decimals; quartiles and ``hide`` left out), written by :func:`write_results` under ``args.out`` with
    :func:`environment_meta` (``schedule="interleaved"``, the load average, ``extra``).  Returns the path."""
    points = time_interleaved(slots, args.repeats)
    skip = {"min_ms", "max_ms", "q1_ms", "q3_ms", *hide}
    for p in points:
        print({k: (round(v, 4) if isinstance(v, float) else v) for k, v in p.items() if k not in skip})
    meta = environment_meta(benchmark, repeats=args.repeats, schedule="interleaved", load_avg=os.getloadavg(),
                            **extra)
    return write_results(args.out, prefix, meta, points)
