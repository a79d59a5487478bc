"""Simulate a built-in scenario in closed loop (a few Monte Carlo runs) and write the results.

    python examples/04_closed_loop.py                          # head_on, 2 runs of 400 s, figures
    python examples/04_closed_loop.py crossing_give_way --runs 3 --out out/examples
    python examples/04_closed_loop.py --quick                  # 1 run of 100 s, 39 behaviours, no figures
                                                               # (also PSBMPC_EXAMPLE_QUICK=1)

Each MPC update (every 5 s here) the own-ship's PSB-MPC plans from the Kalman-filter tracks of the other
vessels; the true vessels move on.  ``psbmpc-jax run`` does the same from the command line.  This writes,
into ``OUT/SCENARIO/``:

* ``metrics.json`` and ``summary.md`` -- per-run and aggregated metrics (closest approaches, collisions,
  COLREGS classification, solve times) with the settings and versions;
* ``trajectories.csv`` / ``trajectories.npz`` -- every run's true states and the chosen maneuvers, read back
  with :func:`psbmpc_jax.sim.load_trajectories`;
* the figures (map, distances, Monte Carlo) unless ``--quick`` or ``--no-figures``.

``psbmpc-jax run --list`` lists the built-in scenarios; any scenario YAML file works too (docs/scenarios.md).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import pathlib
import time

from psbmpc_jax import paper_behaviours
from psbmpc_jax.scenario import builtin_scenarios, load_scenario
from psbmpc_jax.sim import load_trajectories, simulate, write_outputs


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scenario", nargs="?", default="head_on", help=f"one of: {', '.join(builtin_scenarios())}, "
                                                                  "or a .yaml path")
    p.add_argument("--runs", type=int, default=None, help="Monte Carlo runs (default 2; 1 with --quick)")
    p.add_argument("--out", default="out/examples", help="output folder (default out/examples)")
    p.add_argument("--no-figures", action="store_true", help="write metrics and trajectories only")
    p.add_argument("--quick", action="store_true", help="1 run of at most 100 s, 39 behaviours, no figures")
    args = p.parse_args(argv)
    quick = args.quick or os.environ.get("PSBMPC_EXAMPLE_QUICK") == "1"

    scenario = load_scenario(args.scenario)
    if quick:                                   # a shorter simulation and the paper's 39 one-maneuver behaviours
        scenario = dataclasses.replace(scenario, duration=min(scenario.duration, 100.0),
                                       mpc=dataclasses.replace(scenario.mpc, behaviours=paper_behaviours(1)))
    runs = args.runs or (1 if quick else 2)
    print(f"{scenario.name}: {len(scenario.targets)} target(s), {scenario.duration:g} s, {runs} run(s), "
          f"{len(scenario.mpc.behaviours)} behaviours, MPC update every {scenario.mpc.period:g} s")

    t0 = time.perf_counter()
    result = simulate(scenario, runs=runs)
    s = result.summary
    print(f"simulated in {time.perf_counter() - t0:.1f} s ({s['solves']} solves, the first one compiling; "
          f"median {s['solve_wall_s_amortised_median'] * 1e3:.1f} ms per solve)")

    out = pathlib.Path(args.out) / scenario.name
    # a run folder: its manifest.json lists every file; force=True replaces this example's earlier results
    paths = write_outputs(result, out, figures=not (quick or args.no_figures), trajectories=True, force=True)
    closest = {tg["name"]: round(tg["min_distance_m"]["min"], 1) for tg in s["targets"]}
    print(f"own-ship collisions: {s['collisions']}, closest approach [m]: {closest}")
    tr = load_trajectories(out)                 # the exported trajectories, read back
    print(f"trajectories: {len(tr.t)} steps x {tr.states.shape[1]} ships x {tr.states.shape[0]} run(s)")
    print("wrote: " + ", ".join(sorted(str(q) for q in paths.values())))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
