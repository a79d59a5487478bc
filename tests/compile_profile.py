"""Where the suite's time goes: wall time, XLA compile time and compile count per test.

Off by default.  ``PSBMPC_TEST_PROFILE=DIR python -m pytest ...`` writes one JSON line per test to
``DIR/<worker>.jsonl`` (test id, wall seconds of setup + call + teardown, seconds and count of XLA backend
compiles, jaxpr tracing and MLIR lowering seconds, the compiled functions' names with their seconds, and whether
the memory-map guard cleared JAX's caches after it).
``python tools/suite_profile.py DIR`` sums it per file and lists the programs compiled most often.
It uses JAX's own monitoring events (``jax.monitoring``), so it measures what JAX reports, nothing patched."""

from __future__ import annotations

import json
import os
import time
from collections import defaultdict

import jax.monitoring

EVENTS = {"/jax/core/compile/backend_compile_duration": "compile",
          "/jax/core/compile/jaxpr_trace_duration": "trace",
          "/jax/core/compile/jaxpr_to_mlir_module_duration": "lower",
          "/jax/compilation_cache/compile_time_saved_sec": "cache_saved"}


class CompileProfile:
    """Collects JAX's compile events between :meth:`start` and :meth:`stop` of each test."""

    def __init__(self, folder: str, worker: str):
        os.makedirs(folder, exist_ok=True)
        self.path = os.path.join(folder, f"{worker}.jsonl")
        self.current: dict | None = None
        jax.monitoring.register_event_duration_secs_listener(self._listen)

    def _listen(self, event: str, duration: float, **kwargs) -> None:
        kind = EVENTS.get(event)
        if kind is None or self.current is None:
            return
        self.current[kind + "_s"] += duration
        if kind == "compile":
            self.current["n_compiles"] += 1
            self.current["programs"][str(kwargs.get("fun_name", "?"))] += duration

    def close(self) -> None:
        """Stop listening to JAX's events."""
        jax.monitoring.unregister_event_duration_listener(self._listen)

    def start(self, nodeid: str) -> None:
        self.current = {"test": nodeid, "t0": time.perf_counter(), "compile_s": 0.0, "trace_s": 0.0,
                        "lower_s": 0.0, "cache_saved_s": 0.0, "n_compiles": 0, "programs": defaultdict(float),
                        "caches_cleared": False}

    def note_cache_clear(self) -> None:
        """The memory-map guard (conftest) cleared JAX's caches after the current test: later tests compile
        again what they need."""
        if self.current is not None:
            self.current["caches_cleared"] = True

    def stop(self) -> None:
        rec, self.current = self.current, None
        if rec is None:
            return
        rec["wall_s"] = time.perf_counter() - rec.pop("t0")
        rec["programs"] = {k: round(v, 3) for k, v in rec["programs"].items()}
        with open(self.path, "a", encoding="utf-8") as fh:
            fh.write(json.dumps(rec) + "\n")
