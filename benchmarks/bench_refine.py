"""PSB-MPC + refinement benchmark at Nidelva scale (docs/refine.md): the Nidelva head-on on the Trondheim chart
(2 obstacles x 5 scenarios, the 13 Table-2 polygons after RDP 2 m, grid grounding, 1014 behaviours), the Nidelva
preset, float32, this device.  Slots (``psbmpc_jax.apps.bench_refine.REFINE_CASES``):

* ``refine``: the whole ``psbmpc_jax.refine.refine`` call (warm starts from the grid's ranking, the solves,
  the safeguard, the grid cost of the result), at 1, 4 and 16 starts, ``map`` and ``vmap``, for
  "nidelva" (T 150 s, refine horizon 60 s), "nidelva_T60" (T 60 s, refined over all of it) and "paper000"
  (the Smooth-SBMPC paper's T 60 s / T_mpc 20 s at dt 1 s);
* ``grid``: the grid search (``solve``) of the same configuration, for scale;
* ``value_and_grad``: ONE evaluation of the smooth objective and its gradient at the grid's choice;
* ``solve_one``: the library solve (``psbmpc_jax.nlp.solve_docp``) of one start alone.

``refine`` ~ ``solve_one`` + overhead; ``solve_one`` ~ (evaluations per iteration) x ``value_and_grad`` x
iterations.  Slots are compiled first, then timed round-robin (one repeat of each per round).  The same
benchmark is ``psbmpc-jax bench --preset refine`` (JSON Lines records, schema psbmpc-bench-refine/1).

Usage: python benchmarks/bench_refine.py [--repeats 20] [--warmup 2] [--cases nidelva,nidelva_u10,nidelva_T60,paper000]
                                        [--slots nidelva:1:map,nidelva:16:vmap]
``--slots`` keeps only the named (case, starts, batch) entries of REFINE_CASES (each compiles for a minute or
more on a small CPU host: a short lent-GPU session times a few).
Writes benchmarks/results/refine_<platform>_<UTC stamp>.json.
"""

from __future__ import annotations

import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import environment_meta, write_results  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--warmup", type=int, default=2)
    ap.add_argument("--cases", default=None,
                    help="comma-separated case names of psbmpc_jax.apps.bench_refine.REFINE_CASES (default: "
                         "nidelva,nidelva_T60,paper000; every case when --slots is given)")
    ap.add_argument("--slots", default=None,
                    help="comma-separated case:starts:batch entries of REFINE_CASES to keep (default: all of --cases)")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "results"))
    args = ap.parse_args(argv)
    from psbmpc_jax.apps.bench_refine import REFINE_CASES, refine_benchmark

    known = sorted({c[0] for c in REFINE_CASES})
    cases_arg = args.cases or (",".join(known) if args.slots is not None else "nidelva,nidelva_T60,paper000")
    names = [c for c in cases_arg.split(",") if c]
    if args.repeats < 2 or args.warmup < 0 or not names or any(n not in known for n in names):
        ap.error(f"--repeats >= 2, --warmup >= 0 and --cases from {','.join(known)}")
    cases = tuple(c for c in REFINE_CASES if c[0] in names)
    if args.slots is not None:
        entries = {e for e in args.slots.split(",") if e}
        known_slots = {f"{c[0]}:{c[3]}:{c[4]}" for c in cases}
        if not entries or not entries <= known_slots:
            ap.error(f"--slots: unknown entries {sorted(entries - known_slots)}; allowed (within --cases): "
                     f"{','.join(sorted(known_slots))}")
        cases = tuple(c for c in cases if f"{c[0]}:{c[3]}:{c[4]}" in entries)
    points = refine_benchmark(args.repeats, args.warmup, cases, log=lambda m: print(m, flush=True))
    meta = environment_meta("PSB-MPC + refinement at Nidelva scale (Nidelva head-on on the chart, grid grounding, "
                            "float32)", repeats=args.repeats, warmup=args.warmup, schedule="interleaved",
                            cases=[list(c[:1]) + [c[1], c[2], c[3], c[4]] for c in cases])
    write_results(args.out, "refine", meta, points)
    return 0


if __name__ == "__main__":
    sys.exit(main())
