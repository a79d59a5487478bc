"""Core-evaluator benchmark: paper-scale solve without polygons, JAX vs the sequential reference.

Usage:  python benchmarks/bench_core.py [--repeats 30] [--reference-repeats 1] [--out benchmarks/results]

For each (estimator, dtype) point it records the compile time and the steady-state device time of the
jitted evaluator separately (warm-up, ``block_until_ready``, repeats: median / min / max / quartiles), the
chosen behaviour, and — in the same run — the wall time of the float64 sequential reference
(`psbmpc_jax.reference.evaluate_reference`, Algorithm 2) on the same situation and sample table, with the
speed-up.  Results go to ``<out>/core_<device>_<timestamp>.json`` with device, versions and commit.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import jax

jax.config.update("jax_enable_x64", True)  # float64 points need it; float32 points are unaffected

import numpy as np  # noqa: E402

from psbmpc_jax import Planner, PlannerConfig, paper_behaviours  # noqa: E402
from psbmpc_jax.examples import paper_head_on  # noqa: E402
from psbmpc_jax.reference import evaluate_reference  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import environment_meta, stats, time_compiled, write_results  # noqa: E402


def bench_point(estimator: str, dtype: str, repeats: int, ref_repeats: int, seed: int = 0) -> dict:
    situation = paper_head_on()
    behaviours = paper_behaviours(2)
    config = PlannerConfig(estimator=estimator, dtype=dtype)
    planner = Planner(config, behaviours=behaviours)
    key = jax.random.key(seed)
    prepared = planner.prepare(situation, key=key)

    compile_s, times, ev = time_compiled(prepared, config, repeats, warmup=3)
    best = int(ev.best)

    samples = prepared[3]  # the standard-normal table the JAX solve used (Planner.prepare's 4th item)
    ref_samples = None if samples is None else np.asarray(samples, dtype=np.float64)
    ref_times, ref = [], None
    for _ in range(ref_repeats):
        t0 = time.perf_counter()
        ref = evaluate_reference(situation, behaviours, planner.params,
                                 config.replace(dtype="float64"), samples=ref_samples)
        ref_times.append(time.perf_counter() - t0)
    n_b = len(behaviours)
    point = {
        "estimator": estimator, "dtype": dtype, "n_cbs": n_b, "n_do": len(situation.obstacles),
        "n_ps": [ob.n_ps for ob in situation.obstacles], "n_so": 0, "T": config.T, "dt": config.dt,
        "n_ct": n_b * sum(ob.n_ps for ob in situation.obstacles),
        "config": {k: getattr(config, k) for k in ("n_samples", "n_quad", "time_block", "chunk_rows",
                                                   "pc_layout")},
        "compile_s": round(compile_s, 3),
        "jax": stats(times),
        "best": best,
        "n_pc_blocks": int(ev.n_pc_blocks),
    }
    if ref is not None:
        ref_ms = statistics.median(ref_times) * 1e3
        point["reference"] = {"median_ms": round(ref_ms, 1), "n": len(ref_times), "best": int(ref.best),
                              "same_best": int(ref.best) == best}
        point["speedup_vs_reference"] = round(ref_ms / point["jax"]["median_ms"], 1)
    return point


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=30)
    ap.add_argument("--reference-repeats", type=int, default=1)
    ap.add_argument("--estimators", default="quadrature,mc,ce")
    ap.add_argument("--dtypes", default="float32,float64")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "results"))
    args = ap.parse_args(argv)
    if args.repeats < 2:
        ap.error("--repeats must be >= 2")
    meta = environment_meta("core paper-scale solve without polygons (issue: core evaluator)",
                            situation="psbmpc_jax.examples.paper_head_on(): 1014 behaviours, 2 obstacles x 5 "
                                      "scenarios")
    points = []
    for estimator in args.estimators.split(","):
        for dtype in args.dtypes.split(","):
            p = bench_point(estimator, dtype, args.repeats, args.reference_repeats)
            points.append(p)
            ref = p.get("reference", {})
            print(f"{estimator:>10} {dtype}: compile {p['compile_s']:.1f} s, steady median "
                  f"{p['jax']['median_ms']:.1f} ms (min {p['jax']['min_ms']:.1f}), best {p['best']}; "
                  f"reference {ref.get('median_ms', float('nan')):.0f} ms best {ref.get('best')} "
                  f"-> speed-up x{p.get('speedup_vs_reference', float('nan'))}", flush=True)
    write_results(args.out, "core", meta, points)
    return 0


if __name__ == "__main__":
    sys.exit(main())
