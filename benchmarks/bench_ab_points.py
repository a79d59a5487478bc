"""Before/after timing of the paper-figure points on this device, both versions in one interleaved run.

The points are those of ``psbmpc-jax bench`` (``--presets``, default fig5, fig7 and fig9; ``nidelva`` is the
solve of the closed-loop main job, the Nidelva preset with grid grounding at 1 014 behaviours: the Nidelva head-on
with the 13 Table-2 polygons, exact grounding, quadrature, float32, T = 150 s), each solved by this checkout's
package (``new``) and by another copy of it (``old``: a directory holding the package renamed ``psbmpc_old``,
e.g. ``git worktree add /tmp/old <commit> && mkdir /tmp/oldpkg && cp -r /tmp/old/psbmpc_jax
/tmp/oldpkg/psbmpc_old``).  Every slot is compiled first; then ``--repeats`` rounds time every slot once
(:func:`_common.time_interleaved`), so the shared machine's slow and fast spells fall on both versions alike.
Each version solves its own copy of the situation (built by its own bench-points module) with its own default
layouts; the chosen behaviours are recorded and compared.

Usage: python benchmarks/bench_ab_points.py --baseline /tmp/oldpkg [--presets fig5,fig7,fig9] [--values 9,1014]
[--repeats 10]   (``--values``: only the points of those swept values, e.g. on a GPU where each compile takes
half a minute)
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys

import jax

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import environment_meta, time_interleaved, write_results  # noqa: E402


def points_module(pkg_name: str):
    """The module that builds the bench points of ``pkg_name`` and its situation builder: ``apps.bench_points``
    (``situation_for``), or ``bench`` (``_situation``) in a baseline from before the applications moved to
    ``psbmpc_jax.apps``."""
    try:
        bench = importlib.import_module(f"{pkg_name}.apps.bench_points")
        return bench, bench.situation_for
    except ModuleNotFoundError:
        bench = importlib.import_module(f"{pkg_name}.bench")
        return bench, bench._situation


def slots_for(pkg_name: str, label: str, presets, values=None):
    bench, situation_for = points_module(pkg_name)
    pkg = importlib.import_module(pkg_name)
    solve = importlib.import_module(f"{pkg_name}.solve").solve
    out = []
    for preset in presets:
        if preset == "nidelva":        # the closed-loop main job's solve: the Nidelva preset (grid grounding)
            mpc = importlib.import_module(f"{pkg_name}.presets").PRESETS["nidelva"]
            sit = importlib.import_module(f"{pkg_name}.examples").nidelva_head_on()
            planner = pkg.Planner(mpc.config, params=mpc.params, behaviours=bench.behaviours_for(1014))
            prepared = jax.device_put(planner.prepare(sit))
            compiled = solve.lower(*prepared, config=mpc.config).compile()
            ev = jax.block_until_ready(compiled(*prepared))[2]
            out.append({"point": {"version": label, "label": "nidelva preset (grid) n_cbs=1014", "sweep": preset,
                                  "swept": "n_cbs", "value": 1014, "best": int(ev.best)},
                        "call": lambda c=compiled, a=prepared: c(*a)})
            continue
        swept, preset_values, fixed = bench.PRESETS[preset]
        for p in bench.make_points(swept, preset_values, fixed, preset):
            if values is not None and p.value not in values:
                continue
            sit = situation_for(p)
            beh = bench.behaviours_for(p.n_cbs)
            config = pkg.PlannerConfig(T=p.T)
            planner = pkg.Planner(config, params=pkg.Params(r_ct=p.r_ct), behaviours=beh)
            prepared = jax.device_put(planner.prepare(sit))
            compiled = solve.lower(*prepared, config=config).compile()
            ev = jax.block_until_ready(compiled(*prepared))[2]
            out.append({"point": {"version": label, "label": p.label(), "sweep": preset, "swept": swept,
                                  "value": p.value, "best": int(ev.best)},
                        "call": lambda c=compiled, a=prepared: c(*a)})
            print(f"compiled {label} {p.label()}", file=sys.stderr, flush=True)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--baseline", required=True, help="directory holding the package psbmpc_old")
    ap.add_argument("--presets", default="fig5,fig7,fig9")
    ap.add_argument("--values", default=None, help="comma-separated swept values to keep (default: all)")
    ap.add_argument("--repeats", type=int, default=10)
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "results"))
    args = ap.parse_args(argv)
    sys.path.insert(0, os.path.abspath(args.baseline))
    presets = [s.strip() for s in args.presets.split(",") if s.strip()]
    values = None if args.values is None else {float(v) for v in args.values.split(",") if v.strip()}
    new, old = slots_for("psbmpc_jax", "new", presets, values), slots_for("psbmpc_old", "old", presets, values)
    if not new:
        ap.error(f"--values {args.values}: no point of the presets {presets} has those values")
    slots = [s for pair in zip(old, new) for s in pair]
    points = time_interleaved(slots, args.repeats)
    by = {}
    for pt in points:
        by.setdefault(pt["label"], {})[pt["version"]] = pt
    rows = []
    for label, v in by.items():
        ratio = v["new"]["median_ms"] / v["old"]["median_ms"]
        rows.append({"label": label, "old_ms": v["old"]["median_ms"], "new_ms": v["new"]["median_ms"],
                     "new_over_old": round(ratio, 3), "same_best": v["old"]["best"] == v["new"]["best"]})
        print(f"{label:40s} old {v['old']['median_ms']:9.2f} ms  new {v['new']['median_ms']:9.2f} ms  "
              f"x{ratio:.3f}  same choice: {rows[-1]['same_best']}")
    meta = environment_meta("ab_points", baseline=os.path.abspath(args.baseline), presets=presets,
                            values=args.values, repeats=args.repeats, schedule="interleaved", comparison=rows)
    write_results(args.out, "ab_points", meta, points)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
