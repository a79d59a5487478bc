"""Campaign memory and throughput: peak RSS of a small and a large campaign of one short scenario (the local
engine, one process: memory must not grow with the number of runs, since every task's rows go to disk), and runs
per minute for the local engine and Ray with 1 and 2 local workers, interleaved over ``--repeats``.

Each measurement is a fresh ``psbmpc-jax campaign`` process into a fresh folder (the compilation cache warm after
the first); peak RSS is the process's maximum resident set (``getrusage`` of the child; Ray's worker processes are
not its children, so memory is measured for the local engine only).  Runs per minute are from the process's wall
time (start-up, compile-cache loading and Ray's start included) and from the sum of the tasks' own times.

The issue's sizes are ``--small 1000 --large 10000 --duration 60``; on a 2-core CPU one 60 s head-on run takes
about 2 s, so those take hours there and the defaults below are cut to a few minutes.  Writes
``benchmarks/results/campaign_memory_<platform>_<UTC>.json`` with the device, versions and commit.

    python benchmarks/bench_campaign_memory.py                       # ~4 min on the 2-core VM
    python benchmarks/bench_campaign_memory.py --small 1000 --large 10000 --duration 60 --chunk-runs 500
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

#: Runs the campaign command in a child and prints the child's peak RSS [KiB] (Linux ru_maxrss) as the last line.
_WRAP = ("import resource, subprocess, sys; rc = subprocess.run(sys.argv[1:]).returncode; "
         "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss); sys.exit(rc)")


def campaign(out: pathlib.Path, args, runs: int, *, engine: str = "local", workers: int = 1) -> dict:
    cmd = [sys.executable, "-m", "psbmpc_jax.apps.cli", "campaign", "--out", str(out), "--quiet",
           "--scenarios", args.scenario, "--seeds", "0", "--runs", str(runs), "--chunk-runs", str(args.chunk_runs),
           "--duration", str(args.duration), "--engine", engine, "--workers", str(workers)]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", _WRAP, *cmd], env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"campaign failed ({' '.join(cmd)}):\n{proc.stderr[-3000:]}")
    rss_kib = int(proc.stdout.strip().splitlines()[-1])
    markers = [json.loads(p.read_text()) for p in (out / "tasks").glob("*.done.json")]
    task_s = sum(m["wall_s"] for m in markers)
    return {"engine": engine, "workers": workers, "runs": runs, "tasks": len(markers), "wall_s": round(wall, 2),
            "task_wall_sum_s": round(task_s, 2), "runs_per_min": round(60 * runs / wall, 2),
            "runs_per_min_tasks": round(60 * runs / task_s, 2) if task_s else None,
            "peak_rss_mib": round(rss_kib / 1024, 1)}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenario", default="head_on")
    ap.add_argument("--duration", type=float, default=10.0, help="cut the scenario to this duration [s]")
    ap.add_argument("--small", type=int, default=20, help="runs of the small campaign (issue: 1000)")
    ap.add_argument("--large", type=int, default=200, help="runs of the large campaign (issue: 10000)")
    ap.add_argument("--chunk-runs", type=int, default=20)
    ap.add_argument("--throughput-runs", type=int, default=40, help="runs of each throughput campaign")
    ap.add_argument("--repeats", type=int, default=1, help="rounds of the interleaved throughput slots")
    ap.add_argument("--no-ray", action="store_true", help="skip the Ray slots")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results"))
    args = ap.parse_args()
    from _common import environment_meta, write_results

    versions = {}
    for mod in ("pandas", "pyarrow", "ray"):
        try:
            versions[mod] = __import__(mod).__version__
        except ImportError:
            versions[mod] = None
    use_ray = versions["ray"] is not None and not args.no_ray
    points = []
    with tempfile.TemporaryDirectory(prefix="campaign_bench_") as tmp:
        tmp = pathlib.Path(tmp)
        campaign(tmp / "warm", args, min(args.small, args.chunk_runs))        # fills the compilation cache
        for label, runs in (("small", args.small), ("large", args.large)):
            p = campaign(tmp / label, args, runs)
            points.append({"what": "memory", "size": label, **p})
            print(json.dumps(points[-1]), flush=True)
        slots = [("local", 1), ("local", 2)] + ([("ray", 1), ("ray", 2)] if use_ray else [])
        for rep in range(args.repeats):
            for engine, workers in slots:
                p = campaign(tmp / f"t_{engine}{workers}_{rep}", args, args.throughput_runs, engine=engine,
                             workers=workers)
                points.append({"what": "throughput", "repeat": rep, **p})
                print(json.dumps(points[-1]), flush=True)
    small = next(p for p in points if p.get("size") == "small")
    large = next(p for p in points if p.get("size") == "large")
    summary = {"peak_rss_ratio_large_over_small": round(large["peak_rss_mib"] / small["peak_rss_mib"], 3)}
    meta = environment_meta("campaign_memory", versions_extra=versions, args=vars(args), summary=summary,
                            note="runs/min from each campaign process's wall time (start-up and compile-cache "
                                 "loading included) and from the sum of its tasks' times")
    write_results(args.out, "campaign_memory", meta, points)
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())
