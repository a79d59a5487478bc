"""Timing of ``psbmpc-jax bench`` points: the ``psbmpc-bench/1`` record (:data:`SCHEMA`, :data:`FIELDS`,
docs/bench_schema.md), the statistics and memory figures of a point, the device selection of ``--devices``,
the default ``--out`` file and :class:`Runner`, which compiles, warms up and times the JAX points and runs the
sequential float64 reference within its time budget."""

from __future__ import annotations

import datetime as dt
import json
import os
import platform as _platform
import resource
import statistics
import sys
import time

import numpy as np

from ..provenance import commit, versions
from .bench_points import Point, n_vertices

SCHEMA = "psbmpc-bench/1"
FIELDS = ("schema", "sweep", "swept", "impl", "platform", "device_kind", "n_devices", "host", "estimator", "dtype",
          "grounding_mode", "grounding_search", "n_M", "n_cbs", "n_do", "n_ps", "n_so", "n_vertices", "n_ct", "T",
          "dt", "compile_s",
          "times_ms", "median_ms", "min_ms", "max_ms", "q1_ms", "q3_ms", "peak_memory_bytes", "memory_source",
          "compiled_memory_bytes", "r_ct", "best", "n_pc_blocks", "schedule", "skipped", "skip_reason", "versions",
          "commit", "timestamp")


def stats_ms(times_s) -> dict:
    if not times_s:
        return {"times_ms": [], "median_ms": None, "min_ms": None, "max_ms": None, "q1_ms": None, "q3_ms": None}
    ms = [round(t * 1e3, 4) for t in times_s]
    q = statistics.quantiles(ms, n=4, method="inclusive") if len(ms) > 1 else [ms[0]] * 3
    return {"times_ms": ms, "median_ms": float(statistics.median(ms)), "min_ms": float(min(ms)),
            "max_ms": float(max(ms)), "q1_ms": float(q[0]), "q3_ms": float(q[2])}


def peak_rss_bytes() -> int:
    r = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return int(r) if sys.platform == "darwin" else int(r) * 1024


def compiled_memory_bytes(compiled):
    """Device memory XLA planned for one call of a compiled executable (per device for a sharded one):
    arguments + outputs + temporaries - aliased buffers; None where the backend does not report it.

    Unlike the device or process peak this belongs to the point alone and is the same on every run."""
    try:
        m = compiled.memory_analysis()
    except Exception:  # noqa: BLE001 - not every backend implements it
        return None
    if m is None:
        return None
    return int(m.argument_size_in_bytes + m.output_size_in_bytes + m.temp_size_in_bytes - m.alias_size_in_bytes)


def device_peak(device):
    try:
        ms = device.memory_stats()
    except Exception:  # noqa: BLE001 - not every backend implements it
        return None
    if ms and "peak_bytes_in_use" in ms:
        return int(ms["peak_bytes_in_use"])
    return None


def select_devices(which: str) -> dict:
    """{platform: [devices]} for --devices."""
    import jax

    out = {}
    for plat in ("cpu", "gpu"):
        if which not in ("all", plat):
            continue
        try:
            devs = jax.devices(plat)
        except RuntimeError:
            devs = []
        if devs:
            out[plat] = devs
    if not out:
        raise ValueError(f"--devices {which}: no JAX {which} device is available "
                         f"(present: {sorted({d.platform for d in jax.devices()})})")
    return out


def default_out() -> str:
    """``bench_<host>_<UTC timestamp>.jsonl`` in the current folder (the default of ``--out``)."""
    stamp = dt.datetime.now(dt.timezone.utc).strftime("%Y%m%dT%H%M%SZ")
    return os.path.join(os.getcwd(), f"bench_{_platform.node() or 'host'}_{stamp}.jsonl")


class Runner:
    def __init__(self, args, fh):
        self.args, self.fh = args, fh
        self.meta = {"host": _platform.node(), "versions": versions(), "commit": commit()}
        self.ref_used = 0.0
        self.ref_rate = None   # slowest seconds per cost unit seen

    def base_record(self, p: Point, situation, behaviours, impl: str) -> dict:
        n_cbs = len(behaviours)
        n_do = len(situation.obstacles)
        n_so = len(situation.polygons)
        n_ps = max([ob.n_ps for ob in situation.obstacles], default=0)   # 0: no obstacles
        rec = dict.fromkeys(FIELDS)
        rec.update(schema=SCHEMA, sweep=p.sweep, swept=p.swept, impl=impl, host=self.meta["host"],
                   estimator=self.args.estimator, dtype=self.args.dtype, grounding_mode=self.args.grounding,
                   grounding_search=None,
                   n_M=int(behaviours.shape[1]), n_cbs=n_cbs, n_do=n_do, n_ps=int(n_ps), n_so=n_so,
                   n_vertices=n_vertices(situation), n_ct=n_cbs * (n_so + n_do * int(n_ps)), T=float(p.T),
                   r_ct=float(p.r_ct),
                   dt=float(self.args.dt), skipped=False, versions=self.meta["versions"],
                   commit=self.meta["commit"], **stats_ms([]))
        return rec

    def write(self, rec: dict) -> None:
        rec["timestamp"] = dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds")
        assert set(rec) == set(FIELDS), set(rec) ^ set(FIELDS)
        self.fh.write(json.dumps(rec) + "\n")
        self.fh.flush()

    def prepare_jax(self, p, situation, behaviours, config, devices, multi: bool) -> dict:
        """Compile and warm up one point; returns its timing slot (the call, the record so far, no times)."""
        import jax

        from ..params import Params
        from ..planner import Planner
        from ..solve import solve

        dev = devices[0]
        # a point whose padded shapes match an earlier point's (fig6s after fig6, polygon counts padded to
        # the same size in fig10) would load the in-memory executable instead of compiling: compile_s ~1 ms
        jax.clear_caches()
        rss0 = peak_rss_bytes()
        with jax.default_device(dev):
            planner = Planner(config, params=Params(r_ct=p.r_ct), behaviours=behaviours)
            inputs, state, params, samples = planner.prepare(situation, key=jax.random.key(self.args.seed))
        if multi:   # ahead-of-time too: the timed call neither re-places the inputs nor looks up a cache
            from ..sharding import sharded_call

            fn, args, n_b = sharded_call(inputs, state, params, samples, config, devices=devices)
            t0 = time.perf_counter()
            compiled = fn.lower(*args, n_b=n_b).compile()
        else:
            args = jax.device_put((inputs, state, params, samples), dev)
            t0 = time.perf_counter()
            compiled = solve.lower(*args, config=config).compile()
        compile_s = time.perf_counter() - t0
        call = lambda: compiled(*args)[2]  # noqa: E731  (plan, next state, evaluation): one executable
        planned = compiled_memory_bytes(compiled)
        ev = None
        for _ in range(self.args.warmup):
            ev = jax.block_until_ready(call())
        rec = self.base_record(p, situation, behaviours, "jax")
        peak = device_peak(dev)
        if peak is not None:
            rec.update(peak_memory_bytes=peak, memory_source="device")
        else:
            rec.update(peak_memory_bytes=max(0, peak_rss_bytes() - rss0), memory_source="process_rss")
        rec.update(platform=dev.platform, device_kind=dev.device_kind, n_devices=len(devices) if multi else 1,
                   grounding_search=config.grounding_search, compile_s=round(compile_s, 4),
                   schedule=self.args.schedule, compiled_memory_bytes=planned)
        return {"point": p, "call": call, "rec": rec, "ev": ev, "times": []}

    def time_jax(self, slots) -> tuple[list, bool]:
        """Time the prepared points, ``--repeats`` rounds of one call each (one slot: back to back).

        Returns ``(point, record)`` pairs and whether a KeyboardInterrupt cut the rounds short (then only the
        points with at least one timed repeat are returned, each with the repeats it got)."""
        import jax

        interrupted = False
        try:
            for _ in range(self.args.repeats):
                for slot in slots:
                    t0 = time.perf_counter()
                    slot["ev"] = jax.block_until_ready(slot["call"]())
                    slot["times"].append(time.perf_counter() - t0)
        except KeyboardInterrupt:
            interrupted = True
        out = []
        for slot in slots:
            if not slot["times"]:
                continue
            rec, ev = slot["rec"], slot["ev"]
            rec.update(best=int(ev.best), n_pc_blocks=int(ev.n_pc_blocks), **stats_ms(slot["times"]))
            out.append((slot["point"], rec))
        return out, interrupted

    def run_reference(self, p, situation, behaviours, config, samples) -> dict:
        from ..params import Params
        from ..reference import evaluate_reference

        rec = self.base_record(p, situation, behaviours, "reference")
        rec.update(platform="cpu", device_kind="cpu", n_devices=1, dtype="float64", memory_source="process_rss",
                   schedule="sequential")
        budget = self.args.reference_budget
        units = len(behaviours) * (rec["n_do"] * rec["n_ps"] + rec["n_vertices"] / 100.0 + 1.0) * config.n_steps
        left = budget - self.ref_used
        reason = None
        if budget <= 0:
            reason = "reference disabled (--reference-budget 0)"
        elif left <= 0:
            reason = f"reference time budget exhausted ({self.ref_used:.1f} s of {budget:g} s used)"
        elif self.ref_rate is not None and self.ref_rate * units * self.args.reference_repeats > left:
            reason = (f"reference time budget exhausted (estimated "
                      f"{self.ref_rate * units * self.args.reference_repeats:.1f} s > {left:.1f} s left of "
                      f"{budget:g} s)")
        if reason is not None:
            rec.update(skipped=True, skip_reason=reason)
            return rec
        rss0 = peak_rss_bytes()
        ref_samples = None if samples is None else np.asarray(samples, dtype=np.float64)
        cfg64 = config.replace(dtype="float64")
        times, res = [], None
        for _ in range(self.args.reference_repeats):
            t0 = time.perf_counter()
            res = evaluate_reference(situation, behaviours, Params(r_ct=p.r_ct), cfg64, samples=ref_samples)
            times.append(time.perf_counter() - t0)
        assert res is not None          # --reference-repeats is a positive integer
        used = sum(times)
        self.ref_used += used
        rate = used / len(times) / units
        self.ref_rate = rate if self.ref_rate is None else max(self.ref_rate, rate)
        rec.update(best=int(res.best), peak_memory_bytes=max(0, peak_rss_bytes() - rss0), **stats_ms(times))
        return rec


def samples_for_reference(config, seed):
    """The sample table the JAX points use (host float64 copy), None for quadrature."""
    import jax

    from ..costs.collision import standard_normal_table

    s = standard_normal_table(jax.random.key(seed), config, np.dtype(config.dtype))
    return None if s is None else np.asarray(s, dtype=np.float64)
