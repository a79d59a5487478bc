#!/usr/bin/env python3
"""Run one scenario with several own-ship methods on the same seeds and compare them.

    python experiments/compare_methods.py smooth_000_reconstruction --methods sbmpc_init,smooth_sbmpc --runs 20 \\
        --out /tmp/smooth_reconstruction
    python experiments/compare_methods.py nidelva --methods psbmpc,psbmpc_refine --runs 20 --out /tmp/nidelva

Shared by the studies ``nidelva_refinement/`` and ``smooth_sbmpc/`` (their READMEs give the exact commands).

Every method sees the same traffic, the same measurement noise (run r draws from ``default_rng([seed, r])``)
and the same targets' controllers; only the own-ship's ``mpc.method`` changes.  Writes, under ``--out``
(required; a folder that already holds files is refused unless ``--force``):

* ``<method>/``: the simulator's usual output (``metrics.json``, ``summary.md``, figures of run 0);
* ``comparison.json``: per method the safety and smoothness figures (collisions,
  groundings, shore clearance, mean |course rate|, path length, voyage time, course and speed ranges, the longest
  stop) aggregated over the runs, the wall time, and the provenance (commit, versions, device);
* ``course_speed_compare.png``: course and speed over time of run 0 for every method (as Fig. 16 of the
  Smooth-SBMPC paper, Mahipala & Johansen 2024).
"""

from __future__ import annotations

import argparse
import json
import pathlib
import platform
import sys
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[0]))   # experiments/: comparison.py
from comparison import output_folder, utc_stamp  # noqa: E402


def _stat(summary: dict, key: str, which: str = "mean"):
    v = summary.get(key)
    return v.get(which) if isinstance(v, dict) else v


def method_record(result, wall_s: float) -> dict:
    s = result.summary
    land = [m["min_distance_land_m"] for m in result.metrics if m["min_distance_land_m"] is not None]
    return {
        "method": s["method"],
        "runs": s["runs"],
        "collisions": s["collisions"],
        "groundings": s["groundings"],
        "min_distance_land_m": {"min": min(land) if land else None, "mean": sum(land) / len(land) if land else None},
        "min_distance_targets_m": {t["name"]: t["min_distance_m"]["min"] for t in s["targets"]},
        "mean_abs_course_rate_deg_s": s["mean_abs_course_rate_deg_s"],
        "voyage_mean_abs_course_rate_deg_s": s.get("voyage_mean_abs_course_rate_deg_s"),
        "path_length_m": s.get("path_length_m"),
        "arrived_runs": s.get("arrived_runs"),
        "voyage_time_s": s.get("voyage_time_s"),
        "course_min_deg": s.get("course_min_deg"),
        "course_max_deg": s.get("course_max_deg"),
        "speed_min_mps": s.get("speed_min_mps"),
        "speed_max_mps": s.get("speed_max_mps"),
        "longest_stop_s": s.get("longest_stop_s"),
        "colav_diagnostics": s.get("colav_diagnostics"),
        "solve_time_mean_s": s.get("solve_time_mean_s"),
        "mpc_solves_total": s.get("mpc_solves_total"),
        "wall_s": round(wall_s, 1),
    }


def ratios(records: dict, base: str) -> dict:
    """Each method's mean course rate, path length and shore clearance relative to ``base``."""
    b = records[base]
    out = {}
    for name, r in records.items():
        if name == base:
            continue
        cr_b, cr = _stat(b, "mean_abs_course_rate_deg_s"), _stat(r, "mean_abs_course_rate_deg_s")
        pl_b, pl = _stat(b, "path_length_m"), _stat(r, "path_length_m")
        out[name] = {
            "course_rate_change": (cr / cr_b - 1.0) if cr_b else None,
            "path_length_change": (pl / pl_b - 1.0) if pl_b else None,
            "min_distance_land_change_m": (r["min_distance_land_m"]["min"] - b["min_distance_land_m"]["min"])
            if r["min_distance_land_m"]["min"] is not None and b["min_distance_land_m"]["min"] is not None else None,
        }
    return {"relative_to": base, "methods": out}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("scenario", help="built-in scenario name or YAML path")
    p.add_argument("--methods", required=True,
                   help="comma-separated mpc.method values; the first is the baseline of the ratios")
    p.add_argument("--runs", type=int, default=None, help="Monte Carlo runs (default: the scenario's)")
    p.add_argument("--seed", type=int, default=None, help="base seed (default: the scenario's)")
    p.add_argument("--first-run", type=int, default=0,
                   help="Monte Carlo index of the first run (default 0): runs first .. first + runs - 1, each the same "
                        "as in a larger set from 0 (to extend a committed set without re-running it)")
    p.add_argument("--out", required=True, help="output folder (new, or empty)")
    p.add_argument("--force", action="store_true", help="write into an --out folder that already holds results")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    args = p.parse_args(argv)
    if args.first_run < 0:
        p.error(f"--first-run must be >= 0, got {args.first_run}")

    from psbmpc_jax.scenario import METHODS, load_scenario

    methods = [m.strip() for m in args.methods.split(",")]
    bad = [m for m in methods if m not in METHODS]
    if bad or not methods or len(set(methods)) != len(methods):
        p.error(f"--methods: distinct values from {', '.join(METHODS)} expected, got {args.methods!r}")
    scenarios = {m: load_scenario(args.scenario, method=m) for m in methods}     # every file error before work
    name = scenarios[methods[0]].name
    stamp = utc_stamp()
    out = output_folder(args.out, args.out, force=args.force)

    import jax
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from psbmpc_jax.provenance import commit
    from psbmpc_jax.sim import simulate
    from psbmpc_jax.sim.output import write_outputs
    from psbmpc_jax.sim.plots import plot_course_speed_compare

    results, records = {}, {}
    for m in methods:
        sc = scenarios[m]
        t0 = time.perf_counter()
        res = simulate(sc, runs=args.runs, seed=args.seed, progress=not args.quiet, run_start=args.first_run)
        wall = time.perf_counter() - t0
        write_outputs(res, out / m, figures=True, force=args.force)
        results[m], records[m] = res, method_record(res, wall)
        r = records[m]
        print(f"{m}: {r['runs']} runs in {wall:.0f} s; collisions {r['collisions']}, groundings {r['groundings']}, "
              f"shore clearance min {r['min_distance_land_m']['min']}, mean |course rate| "
              f"{_stat(r, 'mean_abs_course_rate_deg_s')} deg/s, path {_stat(r, 'path_length_m')} m, "
              f"longest stop max {_stat(r, 'longest_stop_s', 'max')} s", flush=True)

    fig, axes = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True)
    plot_course_speed_compare(results, run=0, axes=axes)
    fig.tight_layout()
    fig.savefig(out / "course_speed_compare.png", dpi=120)
    plt.close(fig)

    first = scenarios[methods[0]]
    doc = {
        "scenario": name,
        "source": first.source,
        "runs": records[methods[0]]["runs"],
        "seed": first.seed if args.seed is None else args.seed,
        "first_run": args.first_run,
        "methods": records,
        "ratios": ratios(records, methods[0]),
        "commit": commit(),
        "device": str(jax.devices()[0].device_kind),
        "platform": jax.default_backend(),
        "versions": {"python": platform.python_version(), "jax": jax.__version__},
        "command": " ".join([pathlib.Path(sys.argv[0]).name] + list(sys.argv[1:] if argv is None else argv)),
        "utc": stamp,
    }
    (out / "comparison.json").write_text(json.dumps(doc, indent=1, default=float) + "\n")
    print(f"wrote {out / 'comparison.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
