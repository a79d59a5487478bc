"""Peak memory of the largest settings that were run (the README's "Tested limits" table, docs/limits.md).

Every case runs in a fresh process (its peak resident memory, ``ru_maxrss`` of that child, is the number), on
this device, float32:

* ``runtime``: import psbmpc_jax and JAX and compile one tiny solve (the floor every other case includes);
* ``behaviours``: one ``Planner.plan`` with 16 380 behaviours (2 maneuvers: 91 course offsets x 3 speed factors,
  then 30 x 2), T 150 s, dt 0.5 s, one target with 5 scenarios, open water;
* ``scenarios``: the paper's 1014 behaviours, T 150 s, 8 targets x 9 scenarios (72 obstacle scenarios);
* ``horizon``: 1014 behaviours, T 10 000 s at dt 0.5 s (20 000 steps), one target x 5 scenarios;
* ``runs``: ``simulate`` of a 60 s head-on with 3 behaviours and 300 Monte Carlo runs (the device's default
  batch mode);
* ``track``: ``evaluate_tracks`` of 2 vessels x 2 000 000 samples (1 s apart: 23 days);
* ``behaviours_65k``, ``horizon_40k``, ``horizon_100k``, ``track_1e7``, ``runs_1000``: 65 160 behaviours,
  T 20 000 s (40 000 steps), T 50 000 s (100 000 steps, PlannerConfig's bound), 10⁷ samples, 1 000 runs.

Each case also records the memory estimate of :mod:`psbmpc_jax.limits` where there is one, and its wall time.

Usage: python benchmarks/bench_tested_limits.py [--cases runtime,behaviours,...]
Writes benchmarks/results/tested_limits_<platform>_<UTC stamp>.json.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path[:0] = [os.path.dirname(os.path.abspath(__file__)), ROOT]    # this checkout's psbmpc_jax: its commit is recorded
from _common import environment_meta, write_results  # noqa: E402

SOLVE = """
import json, numpy as np
from psbmpc_jax import Planner, OwnShip, Obstacle, Situation, limits
from psbmpc_jax.behaviours import enumerate_behaviours_deg
from psbmpc_jax.presets import build_mpc
T, n_targets, n_ps, wide = {T}, {n_targets}, {n_ps}, {wide}
speeds, courses = None, None
if wide:   # 2 maneuvers: 91 x 3 speeds then 30 x 2 speeds = 16 380 behaviours (wide=4: 181 x 3, 60 x 2 = 65 160)
    k = 1 if wide is True else 2
    speeds = [[1.0, 0.5, 0.0], [1.0, 0.5]]
    courses = [list(np.linspace(-90, 90, 90 * k + 1)), list(np.linspace(-87, 87, 30 * k))]
config, params, beh = build_mpc("nidelva", {{"T": T, "dtype": "float32", "estimator": "quadrature"}},
                                speed_sets=speeds, course_sets_deg=courses)
own = OwnShip(state=[0.0, 0.0, 0.0, 2.0], waypoints=[[0.0, 0.0], [40000.0, 0.0]], U_d=2.0, length=5.0, width=3.0)
obs = tuple(Obstacle(state=[300.0 + 60 * i, 4.0 - 10 * i, -2.0, 0.0], cov=np.diag([4.0, 4.0, 0.05, 0.05]),
                     length=5.0, n_ps=n_ps) for i in range(n_targets))
planner = Planner(config, params, beh)
result, _ = planner.plan(Situation(own, obs, polygons=()))
n_b, n_os = limits.padded_sizes(len(beh), n_targets, n_ps)
est = limits.solve_bytes(config, n_b, n_os, land=False)
print(json.dumps(dict(behaviours=len(beh), steps=config.n_steps, obstacle_scenarios=n_targets * n_ps,
                      estimate_bytes=est + limits.RUNTIME_OVERHEAD, estimate_solve_bytes=est,
                      best=int(result.best_index))))
"""

RUNS = """
import json
from psbmpc_jax.scenario import scenario_from_dict
from psbmpc_jax.sim import simulate
d = {{"name": "runs", "simulation": {{"dt_s": 0.5, "duration_s": 60}}, "monte_carlo": {{"runs": {runs}, "seed": 1}},
     "mpc": {{"preset": "nidelva", "update_period_s": 5, "config": {{"T": 40}},
             "speed_factors": [[1.0, 0.0]], "course_offsets_deg": [[-30, 0, 30]]}},
     "own_ship": {{"name": "OS", "position_m": [0, 0], "course_deg": 0, "speed_mps": 2, "waypoints_m": [[0, 0], [200, 0]]}},
     "targets": [{{"name": "TS1", "position_m": [160, 10], "course_deg": 180, "speed_mps": 2}}]}}
res = simulate(scenario_from_dict(d, land_checks="off"))
print(json.dumps(dict(runs={runs}, steps=121, ships=2, result=type(res).__name__)))
"""

TRACK = """
import json, numpy as np
from psbmpc_jax import limits
from psbmpc_jax.evaltool import evaluate_tracks
from psbmpc_jax.evaltool.tracks import Tracks
n = {n}
t = np.arange(n, dtype=float)
own = np.stack([t * 0.5, np.zeros(n), np.zeros(n), np.full(n, 0.5)], -1)
other = np.stack([1.0e6 - t * 0.5, np.full(n, 30.0), np.full(n, np.pi), np.full(n, 0.5)], -1)
tracks = Tracks(t=t, north=np.stack([own[:, 0], other[:, 0]]), east=np.stack([own[:, 1], other[:, 1]]),
                course=np.stack([own[:, 2], other[:, 2]]), speed=np.stack([own[:, 3], other[:, 3]]), names=("own", "ts"))
ev = evaluate_tracks(tracks)
print(json.dumps(dict(samples=n, vessels=2, encounters=len(ev.encounters),
                      estimate_bytes=limits.evaluation_bytes(n, 2))))
"""

#: Appended to every case: the child's own peak resident memory [bytes] (ru_maxrss is in KiB on Linux).
PEAK = "\nimport resource\nprint(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024)\n"

CASES = {
    "runtime": SOLVE.format(T=10.0, n_targets=1, n_ps=1, wide=False),
    "behaviours": SOLVE.format(T=150.0, n_targets=1, n_ps=5, wide=True),
    "scenarios": SOLVE.format(T=150.0, n_targets=8, n_ps=9, wide=False),
    "horizon": SOLVE.format(T=10000.0, n_targets=1, n_ps=5, wide=False),
    "runs": RUNS.format(runs=300),
    "track": TRACK.format(n=2_000_000),
    "behaviours_65k": SOLVE.format(T=150.0, n_targets=1, n_ps=5, wide=4),
    "horizon_40k": SOLVE.format(T=20000.0, n_targets=1, n_ps=5, wide=False),
    "track_1e7": TRACK.format(n=10_000_000),
    "horizon_100k": SOLVE.format(T=50000.0, n_targets=1, n_ps=5, wide=False),
    "runs_1000": RUNS.format(runs=1000),
}


def run_case(name: str, timeout: float) -> dict:
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-c", CASES[name] + PEAK], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            cwd=ROOT, env=env)
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
        return dict(case=name, error=f"timed out after {timeout:g} s")
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        return dict(case=name, error=err.decode()[-3000:])
    lines = out.decode().splitlines()
    return dict(case=name, wall_s=round(wall, 2), peak_rss_bytes=int(lines[-1]), **json.loads(lines[-2]))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--timeout", type=float, default=170.0, help="seconds per case")
    ap.add_argument("--out", default=os.path.join(ROOT, "benchmarks", "results"))
    args = ap.parse_args(argv)
    names = [c for c in args.cases.split(",") if c]
    if not names or any(n not in CASES for n in names):
        ap.error(f"--cases from {','.join(CASES)}")
    for name in names:     # one file per case
        p = run_case(name, args.timeout)
        print(json.dumps(p)[:400], flush=True)
        meta = environment_meta("peak resident memory of the largest tested settings (fresh process per case)",
                                load_average=os.getloadavg())
        write_results(args.out, "tested_limits", meta, [p])
    return 0


if __name__ == "__main__":
    sys.exit(main())
