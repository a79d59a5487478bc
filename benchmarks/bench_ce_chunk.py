"""Cross-Entropy chunking before/after (issue 11, item 2), in ONE interleaved run on this device.

The compact collision kernel sends its (row, time-block) items through the estimator in chunks.  Before: one
loop of ``chunk_rows`` (512) items per chunk, so 205 items paid for 512.  After: full 512-item chunks while
at least 512 items are left, then 64-item chunks (``collision.TAIL_ROWS``) for the rest.  Variants, each
compiled once (ahead of time) and then timed round-robin (one call of every slot per round, so a slow spell
of this shared machine lands on every slot alike):

* ``old``: ``chunk_rows=512`` with the tail disabled (``TAIL_ROWS`` patched above 512 while lowering) — the
  chunking before the change (same code otherwise, ``C_future`` accumulator included);
* ``new``: ``chunk_rows=512``, bulk + 64-row tail (the default now);
* ``all64``: ``chunk_rows=64`` (one loop of 64-item chunks), for reference.

Points: the paper-scale Nidelva head-on (2 obstacles x 5 scenarios, 13 polygons after RDP 2 m) with the
n_M = 1 paper set (B = 39, ``paper_behaviours(1)``) and the n_M = 2 set (B = 1014), and the chart-free paper
head-on with B = 39; T = 150 s, dt = 0.5 s, float32, ``estimator="ce"`` (500 samples, 6 iterations).  The
answers are compared with ``old``: the choice, bitwise equality of every collision cost C and total, and their
largest relative difference (float32 results may differ in the last bits between chunk shapes, as they already
did between ``chunk_rows`` values before the change: XLA vectorises the estimator per shape; in float64 the
kernel's results are bitwise identical, ``tests/test_ce_chunk.py``).

Usage: python benchmarks/bench_ce_chunk.py [--rounds 5] [--out benchmarks/results]
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import jax
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from _common import environment_meta, stats, write_results  # noqa: E402

from psbmpc_jax import Planner, PlannerConfig  # noqa: E402
from psbmpc_jax.behaviours import paper_behaviours  # noqa: E402
from psbmpc_jax.costs import collision as col  # noqa: E402
from psbmpc_jax.examples import nidelva_head_on, paper_head_on  # noqa: E402
from psbmpc_jax.solve import solve  # noqa: E402

CHUNK = 512
VARIANTS = {"old": (CHUNK, 10 ** 9), "new": (CHUNK, col.TAIL_ROWS), "all64": (64, col.TAIL_ROWS)}


def items_processed(n: int, chunk: int, tail: int) -> int:
    """Estimator slots paid for ``n`` items: full chunks, then ``tail``-item chunks (or one loop of ``chunk``)."""
    if chunk <= tail:
        return -(-n // chunk) * chunk
    return n // chunk * chunk + -(-(n % chunk) // tail) * tail


def compile_variant(prepared, config, tail: int):
    """Ahead-of-time compile of the solve step with ``collision.TAIL_ROWS = tail`` (read while tracing)."""
    saved = col.TAIL_ROWS
    col.TAIL_ROWS = tail
    try:
        jax.clear_caches()                       # no reuse of a trace made with another TAIL_ROWS
        t0 = time.perf_counter()
        compiled = solve.lower(*prepared, config=config).compile()
        return compiled, time.perf_counter() - t0
    finally:
        col.TAIL_ROWS = saved


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rounds", type=int, default=5, help="timed calls of every slot (interleaved)")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "results"))
    args = ap.parse_args(argv)

    points = [("nidelva_head_on", nidelva_head_on(), 39), ("paper_head_on", paper_head_on(), 39),
              ("nidelva_head_on", nidelva_head_on(), 1014)]
    slots = []
    for name, sit, n_b in points:
        beh = paper_behaviours(1 if n_b == 39 else 2)
        for variant, (chunk, tail) in VARIANTS.items():
            cfg = PlannerConfig(T=150.0, dt=0.5, dtype="float32", estimator="ce", chunk_rows=chunk)
            prepared = jax.device_put(Planner(cfg, behaviours=beh).prepare(sit, key=jax.random.key(0)))
            compiled, compile_s = compile_variant(prepared, cfg, tail)
            plan, _, ev = jax.block_until_ready(compiled(*prepared))          # warm-up, and the answers
            slots.append(dict(situation=name, B=n_b, variant=variant, chunk_rows=chunk, tail_rows=min(tail, chunk),
                              compile_s=round(compile_s, 2), fn=compiled, args=prepared, times=[],
                              answer=jax.device_get((ev.C, ev.total, plan.best)), n_items=int(ev.n_pc_blocks)))
            print(f"compiled {name} B={n_b} {variant}: {compile_s:.1f} s, {slots[-1]['n_items']} items", flush=True)
    for r in range(args.rounds):
        for s in slots:
            t0 = time.perf_counter()
            jax.block_until_ready(s["fn"](*s["args"]))
            s["times"].append(time.perf_counter() - t0)
        print(f"round {r + 1}/{args.rounds} done", flush=True)

    out = []
    for s in slots:
        ref = next(o for o in slots if o["situation"] == s["situation"] and o["B"] == s["B"] and o["variant"] == "old")
        same = all(np.array_equal(a, b) for a, b in zip(s["answer"], ref["answer"]))
        (c, tot, best), (c0, tot0, best0) = s["answer"], ref["answer"]
        fin = np.isfinite(tot0)
        rel = lambda a, b: float(np.max(np.abs(a - b)) / max(float(np.max(np.abs(b))), 1e-30))
        row = {k: s[k] for k in ("situation", "B", "variant", "chunk_rows", "tail_rows", "compile_s", "n_items")}
        row.update(items_paid=items_processed(s["n_items"], s["chunk_rows"], s["tail_rows"]),
                   best=int(best), same_best_as_old=bool(best == best0), identical_to_old=bool(same),
                   max_rel_diff_C_vs_old=rel(c, c0), max_rel_diff_total_vs_old=rel(tot[fin], tot0[fin]),
                   **stats(s["times"]), times_ms=[round(t * 1e3, 3) for t in s["times"]])
        out.append(row)
        print(f"{row['situation']:16s} B={row['B']:5d} {row['variant']:6s} items {row['n_items']:6d} "
              f"paid {row['items_paid']:6d}  median {row['median_ms']:9.1f} ms  (min {row['min_ms']:.1f})  "
              f"same best={row['same_best_as_old']} bitwise={same} rel.diff C {row['max_rel_diff_C_vs_old']:.1e}")
    meta = environment_meta("bench_ce_chunk", rounds=args.rounds, estimator="ce", dtype="float32", T=150.0,
                            dt=0.5, n_samples=PlannerConfig().n_samples, ce_max_iter=PlannerConfig().ce_max_iter,
                            old="chunk_rows=512, one loop (tail disabled)",
                            new=f"chunk_rows=512 bulk + {col.TAIL_ROWS}-row tail", all64="chunk_rows=64")
    write_results(args.out, "ce_chunk", meta, out)


if __name__ == "__main__":
    main()
