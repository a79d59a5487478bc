"""Campaign rows at full size (a verification, recorded like a benchmark): one campaign of 3 scenarios x 2 methods
x ``--runs`` runs run four ways through the command line, each into its own folder, and their per-run rows
compared:

1. ``local``: the local engine in one process (the reference);
2. ``ray``: Ray with ``--workers`` local workers (skipped, and said so, without Ray);
3. ``worker-killed``: local engine with ``--workers`` worker processes; once ``--kill-after`` of the tasks are
   done, one worker process is killed (SIGKILL) while it runs a task; the campaign reports that task as failed,
   and the same command again runs only it;
4. ``group-killed``: the same, but the whole campaign (the command and its workers: its process group) is killed
   (SIGKILL) once ``--kill-after`` of the tasks are done; the same command again runs what is missing.

For each: the rows (``psbmpc_jax.campaign.comparable``: without the columns that depend on when and where a row
was computed) must equal the reference's, with every (scenario, method, seed, run, ship) exactly once -- nothing
lost, nothing duplicated -- and the resumed call must skip exactly the tasks that were done before the kill.
The scenarios are ``head_on``, ``crossing_give_way`` and ``overtaking`` with ``mpc.sbmpc: {preset: river}`` (so
``sbmpc`` fits their boats), cut to ``--duration``; methods ``psbmpc`` and ``sbmpc``.  Writes
``benchmarks/results/campaign_rows_<platform>_<UTC>.json`` (device, versions, commit) and exits 1 when a check
fails.  The unit tests check the same at small size (tests/test_campaign_resume.py, test_campaign_workers.py,
test_campaign_ray.py; the last one also at this size with PSBMPC_SLOW_TESTS=1).

    python benchmarks/bench_campaign_rows.py                 # 200 runs: 1 200 runs per way
    python benchmarks/bench_campaign_rows.py --runs 20       # a quick look
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import re
import signal
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "tests"))
from processes import children  # noqa: E402  (tests/processes.py: the campaign tests use it too)

_SUMMARY = re.compile(r"(\d+) tasks \((\d+) done before, (\d+) run now\)")


def markers(folder: pathlib.Path) -> int:
    return len(list((folder / "tasks").glob("*.done.json"))) if (folder / "tasks").is_dir() else 0


class Campaign:
    def __init__(self, file: pathlib.Path, tmp: pathlib.Path):
        self.file, self.tmp = file, tmp
        self.env = {**os.environ, "PYTHONPATH": str(ROOT)}

    def cmd(self, out, *extra) -> list[str]:
        return [sys.executable, "-m", "psbmpc_jax.apps.cli", "campaign", str(self.file), "--out", str(out),
                "--quiet", *extra]

    def run(self, out, *extra, expect_rc=0) -> dict:
        t0 = time.perf_counter()
        proc = subprocess.run(self.cmd(out, *extra), env=self.env, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if proc.returncode != expect_rc:
            raise SystemExit(f"campaign {' '.join(extra)} into {out}: exit status {proc.returncode}, expected "
                             f"{expect_rc}:\n{proc.stdout[-2000:]}\n{proc.stderr[-3000:]}")
        m = _SUMMARY.search(proc.stdout)
        if m is None:
            raise SystemExit(f"no summary line in the campaign's output:\n{proc.stdout[-2000:]}")
        tasks, before, ran = map(int, m.groups())
        return {"args": list(extra), "exit_status": proc.returncode, "wall_s": round(wall, 1), "tasks": tasks,
                "done_before": before, "ran": ran, "failed_line": proc.stdout.strip().splitlines()[-1]
                if proc.returncode else None}

    def killed(self, out, n_tasks: int, kill_after: float, workers: int, *, group: bool) -> dict:
        """Start the campaign with ``workers`` local workers; once ``kill_after`` of the tasks are done, kill one
        worker (``group`` False) or the whole process group (``group`` True) with SIGKILL; then run it again."""
        want = max(1, int(kill_after * n_tasks))
        t0 = time.perf_counter()
        proc = subprocess.Popen(self.cmd(out, "--workers", str(workers)), env=self.env, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True, start_new_session=True)
        while markers(out) < want and proc.poll() is None:
            time.sleep(0.05)
        if proc.poll() is not None:
            raise SystemExit(f"the campaign ended before {want} tasks were done:\n{proc.stderr.read()[-3000:]}")
        workers_now = children(proc.pid, b"psbmpc_jax.campaign.worker")
        if not workers_now:
            proc.kill()
            raise SystemExit("no campaign worker process found to kill")
        done_at_kill = markers(out)
        if group:
            os.killpg(proc.pid, signal.SIGKILL)
        else:
            os.kill(workers_now[0], signal.SIGKILL)
        stdout, stderr = proc.communicate()
        first = {"wall_s": round(time.perf_counter() - t0, 1), "exit_status": proc.returncode,
                 "tasks_done_at_kill": done_at_kill, "tasks_done_after": markers(out),
                 "killed": "process group (command and workers)" if group else f"worker pid {workers_now[0]}",
                 "table_written": (out / "runs.parquet").exists(),
                 "last_line": stdout.strip().splitlines()[-1] if stdout.strip() else None}
        if group:
            left = [p for p in workers_now if pathlib.Path(f"/proc/{p}").exists()
                    and b"psbmpc_jax.campaign.worker" in pathlib.Path(f"/proc/{p}/cmdline").read_bytes()]
            first["workers_left_alive"] = len(left)
        second = self.run(out, "--workers", str(workers))
        return {"first": first, "resume": second}


def compare(ref, folder: pathlib.Path, expected_rows: int, keys_expected: set) -> dict:
    import pandas as pd

    from psbmpc_jax.campaign import KEY_COLUMNS, comparable

    got = pd.read_parquet(folder / "runs.parquet")
    keys = set(map(tuple, got[list(KEY_COLUMNS)].itertuples(index=False)))
    out = {"rows": len(got), "expected_rows": expected_rows,
           "duplicated_keys": int(got.duplicated(list(KEY_COLUMNS)).sum()),
           "missing_runs": len({k[:4] for k in keys_expected} - {k[:4] for k in keys}),
           "task_files": len(list((folder / "tasks").glob("*.parquet")))}
    if ref is None:
        out["identical_to_reference"] = None
        return out
    try:
        pd.testing.assert_frame_equal(comparable(got), ref)
        out["identical_to_reference"] = True
    except AssertionError as exc:
        out["identical_to_reference"] = False
        out["difference"] = str(exc)[:2000]
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=200, help="runs per scenario x method (issue: 200)")
    ap.add_argument("--chunk-runs", type=int, default=50)
    ap.add_argument("--duration", type=float, default=10.0, help="cut the scenarios to this duration [s]")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--kill-after", type=float, default=0.4, help="fraction of the tasks done before the kill")
    ap.add_argument("--ways", nargs="+", default=["local", "ray", "worker-killed", "group-killed"],
                    choices=["local", "ray", "worker-killed", "group-killed"])
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results"))
    args = ap.parse_args()
    if "local" not in args.ways:
        ap.error("--ways must include local (the reference)")
    import pandas as pd
    import yaml
    from _common import environment_meta, write_results
    from tuned_scenarios import sbmpc_tuned_scenarios

    from psbmpc_jax.campaign import KEY_COLUMNS, comparable

    try:
        import ray
        ray_version = ray.__version__
    except ImportError:
        ray_version = None
    points, ok = [], True
    with tempfile.TemporaryDirectory(prefix="campaign_rows_") as tmp:
        tmp = pathlib.Path(tmp)
        spec = {"name": "rows_check", "scenarios": sbmpc_tuned_scenarios(tmp / "scenarios"),
                "methods": ["psbmpc", "sbmpc"], "seeds": [0], "runs": args.runs, "chunk_runs": args.chunk_runs,
                "duration_s": args.duration}
        file = tmp / "rows_check.yaml"
        file.write_text(yaml.safe_dump(spec, sort_keys=False))
        c = Campaign(file, tmp)
        n_tasks = 3 * 2 * -(-args.runs // args.chunk_runs)
        ref = None
        for way in args.ways:
            out = tmp / way
            if way == "local":
                info = c.run(out)
            elif way == "ray":
                if ray_version is None:
                    points.append({"way": way, "skipped": "Ray is not installed (pip install \"psbmpc-jax[cluster]\")"})
                    print(json.dumps(points[-1]), flush=True)
                    continue
                info = c.run(out, "--engine", "ray", "--workers", str(args.workers))
            else:
                info = c.killed(out, n_tasks, args.kill_after, args.workers, group=way == "group-killed")
            if ref is None:
                frame = pd.read_parquet(out / "runs.parquet")
                ref = comparable(frame)
                keys_expected = set(map(tuple, frame[list(KEY_COLUMNS)].itertuples(index=False)))
                expected_rows = 3 * 2 * args.runs * 2          # every scenario has 2 ships: 2 rows per run
                cmp = compare(None, out, expected_rows, keys_expected)
                cmp["identical_to_reference"] = True
            else:
                cmp = compare(ref, out, expected_rows, keys_expected)
            checks = [cmp["rows"] == expected_rows, cmp["duplicated_keys"] == 0, cmp["missing_runs"] == 0,
                      cmp["identical_to_reference"] is True]
            if way.endswith("killed"):
                first, resume = info["first"], info["resume"]
                checks += [first["exit_status"] != 0, not first["table_written"],
                           first["tasks_done_after"] < n_tasks,
                           resume["done_before"] == first["tasks_done_after"],
                           resume["ran"] == n_tasks - first["tasks_done_after"]]
                if way == "group-killed":
                    checks.append(first["workers_left_alive"] == 0)
                else:
                    checks.append(resume["ran"] == 1)
            point = {"way": way, **info, **cmp, "ok": all(checks)}
            ok &= point["ok"]
            points.append(point)
            print(json.dumps(point), flush=True)
    meta = environment_meta("campaign_rows", versions_extra={"pandas": pd.__version__, "ray": ray_version},
                            args=vars(args), n_tasks=n_tasks, all_ok=ok,
                            note="rows compared with psbmpc_jax.campaign.comparable (the solve times, task_id and "
                                 "commit dropped); the machine was shared with other jobs")
    write_results(args.out, "campaign_rows", meta, points)
    print("all checks passed" if ok else "SOME CHECK FAILED")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
