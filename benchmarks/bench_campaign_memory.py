"""Campaign memory and throughput: peak RSS and wall time of campaigns of one short scenario at growing numbers
of runs (the local engine, one process: memory must not grow with the number of runs, since every task's rows go
to disk), of a campaign of the three-ship Nidelva scenario, and runs per minute for the local engine and Ray with
1 and 2 local workers, interleaved over ``--repeats``.

Each measurement is a fresh ``psbmpc-jax campaign`` process into a fresh folder (the compilation cache warm after
the first); peak RSS is the process's maximum resident set and CPU time its user + system time (``getrusage`` of
the child and its waited-for children; Ray's worker processes are not its children, so memory is measured for the
local engine only).  Runs per minute are from the process's wall time (start-up, compile-cache loading and Ray's
start included) and from the sum of the tasks' own times.  The load average before and after each point is
recorded: wall times and runs per minute depend on what else the machine runs; peak memory does not.

``per-task`` runs one campaign of many small tasks in a fresh process through ``run_campaign`` and records the
process's resident memory and its peak so far after every task (a leak would show as a rise task by task).
``--parts`` chooses what runs (``memory``, ``per-task``, ``nidelva``, ``throughput``; default all); each call
writes one ``benchmarks/results/campaign_memory_<platform>_<UTC>.json`` with the device, versions and commit.
Do not commit in this checkout while it runs: every task checks the package's commit, so the tasks after a
commit fail (docs/campaigns.md); a failed campaign ends the call, which still writes what it measured before.

    python benchmarks/bench_campaign_memory.py                       # ~4 min on the 2-core VM
    python benchmarks/bench_campaign_memory.py --parts memory --sizes 1000 10000 --duration 60 --chunk-runs 500
    python benchmarks/bench_campaign_memory.py --parts nidelva --nidelva-runs 200
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

#: Runs the campaign command in a child; prints the children's peak RSS [KiB] (Linux ru_maxrss) and user + system
#: CPU time [s] as the last line.
_WRAP = ("import resource, subprocess, sys; rc = subprocess.run(sys.argv[1:]).returncode; "
         "u = resource.getrusage(resource.RUSAGE_CHILDREN); print(u.ru_maxrss, u.ru_utime + u.ru_stime); "
         "sys.exit(rc)")

class CampaignFailed(RuntimeError):
    """A measured campaign did not finish: recorded with the points measured before it (none is lost)."""


PARTS = ("memory", "per-task", "nidelva", "throughput")


def _proc_status_mib() -> dict:
    """This process's resident memory now and its peak so far [MiB] (Linux /proc/self/status)."""
    out = {}
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith(("VmRSS:", "VmHWM:")):
                out["rss_mib" if line.startswith("VmRSS") else "peak_rss_mib"] = int(line.split()[1]) // 1024
    return out


def per_task_child(folder: str, runs: int, chunk_runs: int, scenario: str, duration: float) -> None:
    """In a fresh process: a campaign run with ``run_campaign`` (the local engine, one process), printing one JSON
    line per finished task with the process's memory then -- the rise task by task that the peak alone hides."""
    from psbmpc_jax.cache import enable_compilation_cache
    from psbmpc_jax.campaign import definition_from_dict, run_campaign

    enable_compilation_cache()
    defn = definition_from_dict({"scenarios": [scenario], "seeds": [0], "runs": runs, "chunk_runs": chunk_runs,
                                 "duration_s": duration})
    n = [0]

    def on_done(ok, task_id, info):
        n[0] += 1
        print(json.dumps({"task": n[0], "task_id": task_id, "ok": ok, **_proc_status_mib()}), flush=True)

    res = run_campaign(defn, folder, on_done=on_done)
    if res["failed"]:
        raise SystemExit(f"tasks failed: {res['failed']}")


def campaign(out: pathlib.Path, runs: int, *, scenario: str, duration: float | None, chunk_runs: int,
             engine: str = "local", workers: int = 1) -> dict:
    cmd = [sys.executable, "-m", "psbmpc_jax.apps.cli", "campaign", "--out", str(out), "--quiet",
           "--scenarios", scenario, "--seeds", "0", "--runs", str(runs), "--chunk-runs", str(chunk_runs),
           "--engine", engine, "--workers", str(workers)]
    if duration is not None:
        cmd += ["--duration", str(duration)]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", _WRAP, *cmd], env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise CampaignFailed(f"campaign failed, exit status {proc.returncode} ({' '.join(cmd)}):\n"
                             f"{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}")
    rss_kib, cpu_s = proc.stdout.strip().splitlines()[-1].split()
    markers = [json.loads(p.read_text()) for p in (out / "tasks").glob("*.done.json")]
    task_s = sum(m["wall_s"] for m in markers)
    table = out / "runs.parquet"
    return {"scenario": scenario, "duration_s": duration, "chunk_runs": chunk_runs, "engine": engine,
            "workers": workers, "runs": runs, "tasks": len(markers), "wall_s": round(wall, 2),
            "cpu_s": round(float(cpu_s), 1), "task_wall_sum_s": round(task_s, 2),
            "runs_per_min": round(60 * runs / wall, 2),
            "runs_per_min_tasks": round(60 * runs / task_s, 2) if task_s else None,
            "peak_rss_mib": round(int(rss_kib) / 1024, 1), "peak_rss_bytes": int(rss_kib) * 1024,
            "runs_parquet_mib": round(table.stat().st_size / 2**20, 2) if table.exists() else None,
            "load_avg_1min": [round(load0, 2), round(os.getloadavg()[0], 2)]}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--parts", nargs="+", choices=PARTS, default=list(PARTS))
    ap.add_argument("--scenario", default="head_on")
    ap.add_argument("--duration", type=float, default=10.0, help="cut the scenario to this duration [s]")
    ap.add_argument("--sizes", type=int, nargs="+", default=[20, 200],
                    help="runs of the memory campaigns, smallest first (issue: 1000 10000)")
    ap.add_argument("--chunk-runs", type=int, default=20, help="runs per task of the memory campaigns")
    ap.add_argument("--nidelva-runs", type=int, default=20, help="runs of the Nidelva campaign (issue: 200)")
    ap.add_argument("--nidelva-duration", type=float, default=None,
                    help="cut Nidelva to this duration [s] (default: its own 360 s)")
    ap.add_argument("--nidelva-chunk-runs", type=int, default=50)
    ap.add_argument("--throughput-runs", type=int, default=40, help="runs of each throughput campaign")
    ap.add_argument("--throughput-chunk-runs", type=int, default=20)
    ap.add_argument("--repeats", type=int, default=1, help="rounds of the interleaved throughput slots")
    ap.add_argument("--no-ray", action="store_true", help="skip the Ray slots")
    ap.add_argument("--no-warm-up", action="store_true",
                    help="skip the first campaign that fills the compilation cache (when an earlier call did)")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results"))
    ap.add_argument("--per-task-runs", type=int, default=1000, help="runs of the per-task memory campaign")
    ap.add_argument("--per-task-chunk-runs", type=int, default=50)
    ap.add_argument("--per-task-child", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.per_task_child:
        per_task_child(args.per_task_child, args.per_task_runs, args.per_task_chunk_runs, args.scenario,
                       args.duration)
        return 0
    if args.sizes != sorted(args.sizes):
        ap.error(f"--sizes must be given smallest first, got {args.sizes}")
    from _common import environment_meta, write_results

    versions = {}
    for mod in ("pandas", "pyarrow", "ray"):
        try:
            versions[mod] = __import__(mod).__version__
        except ImportError:
            versions[mod] = None
    use_ray = versions["ray"] is not None and not args.no_ray
    short = {"scenario": args.scenario, "duration": args.duration}
    points = []

    def record(point):
        points.append(point)
        print(json.dumps(point), flush=True)

    error = None
    try:
        with tempfile.TemporaryDirectory(prefix="campaign_bench_") as tmp:
            tmp = pathlib.Path(tmp)
            if ("memory" in args.parts or "throughput" in args.parts) and not args.no_warm_up:  # fills the cache
                record({"what": "warm-up", **campaign(tmp / "warm", min(args.sizes[0], args.chunk_runs), **short,
                                                      chunk_runs=args.chunk_runs)})
            if "memory" in args.parts:
                for runs in args.sizes:
                    record({"what": "memory", **campaign(tmp / f"m{runs}", runs, **short,
                                                         chunk_runs=args.chunk_runs)})
            if "per-task" in args.parts:
                cmd = [sys.executable, __file__, "--per-task-child", str(tmp / "per_task"), "--scenario",
                       args.scenario, "--duration", str(args.duration), "--per-task-runs", str(args.per_task_runs),
                       "--per-task-chunk-runs", str(args.per_task_chunk_runs)]
                t0 = time.perf_counter()
                proc = subprocess.run(cmd, env={**os.environ, "PYTHONPATH": str(ROOT)}, capture_output=True,
                                      text=True)
                if proc.returncode != 0:
                    raise CampaignFailed(f"per-task campaign failed:\n{proc.stdout[-2000:]}\n"
                                         f"{proc.stderr[-2000:]}")
                lines = [json.loads(x) for x in proc.stdout.splitlines() if x.startswith("{")]
                record({"what": "per-task", "scenario": args.scenario, "duration_s": args.duration,
                        "runs": args.per_task_runs, "chunk_runs": args.per_task_chunk_runs,
                        "wall_s": round(time.perf_counter() - t0, 2), "tasks": lines})
            if "nidelva" in args.parts:
                record({"what": "nidelva", **campaign(tmp / "nidelva", args.nidelva_runs, scenario="nidelva",
                                                      duration=args.nidelva_duration,
                                                      chunk_runs=args.nidelva_chunk_runs)})
            if "throughput" in args.parts:
                slots = [("local", 1), ("local", 2)] + ([("ray", 1), ("ray", 2)] if use_ray else [])
                for rep in range(args.repeats):
                    for engine, workers in slots:
                        record({"what": "throughput", "repeat": rep,
                                **campaign(tmp / f"t_{engine}{workers}_{rep}", args.throughput_runs, **short,
                                           chunk_runs=args.throughput_chunk_runs, engine=engine, workers=workers)})
    except CampaignFailed as exc:       # a campaign that fails (e.g. the checkout's commit changed under it, so its
        error = str(exc)                # tasks refuse to run) ends the measurement; what was measured is kept
        print(error, file=sys.stderr)
    summary = {}
    mem = [p for p in points if p["what"] == "memory"]
    if mem:
        summary["peak_rss_mib_by_runs"] = {p["runs"]: p["peak_rss_mib"] for p in mem}
        summary["peak_rss_ratio_largest_over_smallest"] = round(mem[-1]["peak_rss_mib"] / mem[0]["peak_rss_mib"], 3)
    per = [p for p in points if p["what"] == "per-task"]
    if per:
        t = per[0]["tasks"]
        half = len(t) // 2
        summary["per_task_peak_rss_mib_after_first_half_and_last"] = [t[half - 1]["peak_rss_mib"],
                                                                       t[-1]["peak_rss_mib"]]
        summary["per_task_rss_mib_range"] = [min(x["rss_mib"] for x in t), max(x["rss_mib"] for x in t)]
    nid = [p for p in points if p["what"] == "nidelva"]
    if nid:
        summary["nidelva_peak_rss_mib"] = nid[0]["peak_rss_mib"]
    thr = [p for p in points if p["what"] == "throughput"]
    if thr:
        by = {}
        for p in thr:
            by.setdefault(f"{p['engine']}{p['workers']}", []).append(p["runs_per_min"])
        summary["runs_per_min_median"] = {k: round(statistics.median(v), 2) for k, v in by.items()}
    if not use_ray and "throughput" in args.parts:
        summary["ray"] = "skipped: " + ("--no-ray" if args.no_ray else "Ray is not installed")
    if error is not None:
        summary["error"] = error[:3000]
    meta = environment_meta("campaign_memory", versions_extra=versions, args=vars(args), summary=summary,
                            note="runs/min from each campaign process's wall time (start-up and compile-cache "
                                 "loading included) and from the sum of its tasks' times; the machine was shared "
                                 "with other jobs (load_avg_1min before/after each point)")
    write_results(args.out, "campaign_memory", meta, points)
    print(json.dumps(summary))
    return 0 if error is None else 1


if __name__ == "__main__":
    sys.exit(main())
