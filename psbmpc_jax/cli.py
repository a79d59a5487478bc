"""``psbmpc-jax`` command line.

``psbmpc-jax`` (or ``psbmpc-jax example``) solves the built-in paper-scale situation — 1014 control
behaviours, 2 obstacles x 5 prediction scenarios, T = 150 s, dt = 0.5 s — and prints the chosen maneuver,
the cost breakdown of the best behaviours and the solve time (compile time and steady state separately).
"""

from __future__ import annotations

import argparse
import pathlib
import os
import statistics
import sys
import time

from .argtypes import nonneg_int, odd_int, positive_int


def enable_compilation_cache() -> None:
    """Persistent XLA compilation cache (saves the 2-5 s compile on later runs)."""
    import jax

    path = os.environ.get("PSBMPC_JAX_CACHE", os.path.join(os.path.expanduser("~"), ".cache", "psbmpc_jax"))
    try:
        os.makedirs(path, exist_ok=True)
        jax.config.update("jax_compilation_cache_dir", path)
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
    except OSError:  # read-only home: run without the cache
        pass


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="psbmpc-jax", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command")
    ex = sub.add_parser("example", help="solve the built-in paper-scale head-on situation (default)")
    for p in (parser, ex):
        p.add_argument("--estimator", choices=("quadrature", "mc", "ce"), default="quadrature",
                       help="collision-probability estimator (default: quadrature)")
        p.add_argument("--dtype", choices=("float32", "float64"), default="float32")
        p.add_argument("--n-m", type=int, choices=(1, 2), default=2,
                       help="maneuvers per behaviour with the paper sets: 2 -> 1014 behaviours, 1 -> 39")
        p.add_argument("--n-ps", type=odd_int, default=5, help="prediction scenarios per obstacle (odd)")
        p.add_argument("--obstacles", type=int, default=2, help="number of head-on obstacles (>= 0)")
        p.add_argument("--repeats", type=positive_int, default=20, help="steady-state solves to time")
        p.add_argument("--top", type=positive_int, default=5, help="best behaviours to print")
        p.add_argument("--seed", type=int, default=0, help="PRNG seed for the mc/ce sample table")
    from .bench import add_bench_arguments

    bench = sub.add_parser("bench", help="runtime benchmark sweeps (paper Figs. 5-10), JSON Lines records",
                           description="Runtime benchmark sweeps; records follow docs/bench_schema.md.")
    add_bench_arguments(bench)
    parser._bench_parser = bench
    from .report import add_report_arguments

    report = sub.add_parser("report", help="merge benchmark JSON Lines into a Markdown report with figures",
                            description="Merge psbmpc-bench/1 result files (from any machines) into report.md "
                                        "and PNG box plots.")
    add_report_arguments(report)
    run = sub.add_parser("run", help="closed-loop Monte Carlo simulation of scenario files, with metrics and plots",
                         description="Simulate scenarios (built-in names, glob patterns over them such as "
                                     "'imazu_*', or paths to YAML files; see docs/scenarios.md) and write "
                                     "metrics.json, summary.md and figures per scenario.")
    add_run_arguments(run)
    parser._run_parser = run
    return parser


def run_example(args) -> int:
    import jax
    import numpy as np

    if args.obstacles < 0:
        raise SystemExit(f"psbmpc-jax: --obstacles must be >= 0, got {args.obstacles}")
    if args.dtype == "float64":
        jax.config.update("jax_enable_x64", True)
    enable_compilation_cache()
    from . import Planner, PlannerConfig, paper_behaviours
    from .examples import paper_head_on

    situation = paper_head_on(n_ps=args.n_ps, n_obstacles=args.obstacles)
    planner = Planner(PlannerConfig(estimator=args.estimator, dtype=args.dtype),
                      behaviours=paper_behaviours(args.n_m))
    key = jax.random.key(args.seed)
    t0 = time.perf_counter()
    result, state = planner.plan(situation, key=key)
    first = time.perf_counter() - t0
    times = []
    for _ in range(args.repeats):
        result, _ = planner.plan(situation, key=key)
        times.append(result.solve_time_s)

    n_b = len(planner.behaviours)
    n_ps_total = sum(ob.n_ps for ob in situation.obstacles)
    print(f"psbmpc-jax example: n_cbs={n_b}, obstacles={len(situation.obstacles)} x n_ps={args.n_ps} "
          f"(n_ct={n_b * n_ps_total}), T={planner.config.T:g} s, dt={planner.config.dt:g} s, "
          f"estimator={args.estimator}, dtype={args.dtype}, device={jax.devices()[0].device_kind}")
    print(f"chosen behaviour #{result.best_index}: " + ", ".join(
        f"M{m + 1}: u={u:g}, chi={np.rad2deg(c):+g} deg" for m, (u, c) in enumerate(result.offsets)))
    print(f"apply now: U_c = {result.u_opt:g} * U_d, chi_c = chi_d {np.rad2deg(result.chi_opt):+g} deg")
    print(f"\nbest {args.top} behaviours (costs):")
    names = planner.cost_names                     # columns derived from the planner's cost terms
    print(f"{'rank':>4} {'index':>5}  {'maneuvers (u, chi deg)':<30} " + " ".join(f"{n:>9}" for n in names))
    for rank, row in enumerate(result.ranking(args.top), 1):
        man = " ".join(f"({u:g},{c:+.0f})" for u, c in row["maneuvers"])
        print(f"{rank:>4} {row['index']:>5}  {man:<30} " + " ".join(f"{row[n]:9.4f}" for n in names))
    q = statistics.quantiles(times, n=4) if len(times) > 1 else [times[0]] * 3
    print(f"\nsolve time: first call {first * 1e3:.0f} ms (includes compile), steady state over "
          f"{len(times)} solves: median {statistics.median(times) * 1e3:.1f} ms, min {min(times) * 1e3:.1f} ms, "
          f"quartiles {q[0] * 1e3:.1f}-{q[2] * 1e3:.1f} ms")
    return 0


def add_run_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scenarios", nargs="*", help="built-in scenario names or patterns (see --list), or YAML paths")
    p.add_argument("--list", action="store_true", help="list the built-in scenarios and exit")
    p.add_argument("--runs", type=positive_int, default=None, help="Monte Carlo runs (default: the file's)")
    p.add_argument("--seed", type=nonneg_int, default=None, help="base seed >= 0 (default: the file's)")
    p.add_argument("--out", default="results", help="output folder; one sub-folder per scenario (default: results)")
    p.add_argument("--batch", choices=("auto", "vmap", "loop"), default="auto",
                   help="device calls per MPC update: one vmapped call for all runs and ships, or one per solve "
                        "(auto: vmap on an accelerator, loop on the CPU)")
    p.add_argument("--no-figures", action="store_true", help="write metrics only")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def run_scenarios(args, parser) -> int:
    import fnmatch
    import json

    from .scenario import builtin_scenarios, load_scenario

    names = builtin_scenarios()
    if args.list:
        for n in names:
            print(n)
        return 0
    if not args.scenarios:
        parser.error("give at least one scenario (built-in name, pattern or YAML path); --list shows the names")
    selected = []
    for item in args.scenarios:
        if item.endswith((".yaml", ".yml")) or "/" in item:
            selected.append(item)
            continue
        hits = fnmatch.filter(names, item)
        if not hits:
            parser.error(f"no built-in scenario matches {item!r}; built-in: {', '.join(names)}")
        selected += hits
    enable_compilation_cache()
    from .sim import simulate
    from .sim.output import write_index, write_outputs

    scenarios = []
    for item in selected:   # every file is checked before the first simulation starts
        try:
            scenarios.append(load_scenario(item))
        except (ValueError, OSError) as exc:
            parser.error(str(exc))
    failures = 0
    for scenario in scenarios:
        t0 = time.perf_counter()
        result = simulate(scenario, runs=args.runs, seed=args.seed, batch=args.batch, progress=not args.quiet)
        out = pathlib.Path(args.out) / scenario.name
        write_outputs(result, out, figures=not args.no_figures)
        s = result.summary
        bad = s["collisions"] + s["groundings"] + s["pair_collision_runs"] + s["any_ship_groundings"]
        failures += bool(bad)
        print(f"{scenario.name}: {s['runs']} runs in {time.perf_counter() - t0:.0f} s -- own-ship collisions "
              f"{s['collisions']}, groundings {s['groundings']}, any-pair collisions {s['pair_collision_runs']}, "
              f"any-ship groundings {s['any_ship_groundings']}; closest approach "
              + json.dumps({tg["name"]: tg["min_distance_m"]["min"] for tg in s["targets"]})
              + f"; results in {out}/")
    index = write_index(args.out)
    print(f"index of every scenario under {args.out}: {index}")
    return 1 if failures else 0


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command in (None, "example"):
        return run_example(args)
    if args.command == "bench":
        from .bench import build_plan, run_bench, select_devices

        try:   # flag combinations argparse cannot check: a usage error naming the flag
            build_plan(args)
            select_devices(args.devices)
        except ValueError as exc:
            parser._bench_parser.error(str(exc))
        return run_bench(args)
    if args.command == "run":
        return run_scenarios(args, parser._run_parser)
    if args.command == "report":
        from .report import run_report

        return run_report(args)
    raise SystemExit(f"psbmpc-jax: unknown command {args.command!r}")  # argparse already guards this


if __name__ == "__main__":
    sys.exit(main())
