"""Running a campaign's tasks: one task = one :func:`psbmpc_jax.sim.simulate` call whose rows go to disk at
once (:func:`run_task`).  Engines:

- ``local`` (default, no extra dependency): ``workers=1`` runs the tasks one after another in this process;
  ``workers=N`` keeps N worker processes (``python -m psbmpc_jax.campaign.worker``), each fed one task at a time,
  so each compiles once and a worker that dies (killed, out of memory) loses only the task it was running --
  the others go on, a fresh worker takes its place, and the lost task is reported (a re-run does it).
- ``ray``: each task a Ray remote function (``ray.init(address=...)`` for a cluster, a local Ray otherwise;
  ``gpus_per_task`` as a Ray resource).

Every engine writes the same rows (the task's rows do not depend on where it ran).
"""

from __future__ import annotations

import hashlib
import json
import os
import pathlib
import queue
import subprocess
import sys
import threading
import time

from .definition import Task, load_task_scenario, scenario_path, tasks
from .store import CampaignError, read_campaign, write_task

__all__ = ["ENGINES", "run_task", "run_local", "run_ray", "ray_missing_message"]

ENGINES = ("local", "ray")


def run_task(folder, task: Task, doc: dict) -> dict:
    """Simulate one task and write its rows (``tasks/<id>.parquet`` and the done marker); returns
    ``{"task_id", "rows", "runs", "wall_s"}``."""
    from .. import __version__
    from ..provenance import commit
    from ..scenario.load import estimator_key
    from ..sim import simulate
    from ..sim.output import safe_colregs_evaluation
    from .rows import rows_frame, simulation_rows, trajectory_frame

    t0 = time.perf_counter()
    d = doc["resolved"]["definition"]
    pkg = doc["resolved"]["package"]
    here = {"version": __version__, "commit": commit()}
    if here != pkg:
        raise RuntimeError(f"task {task.task_id}: this process runs psbmpc-jax {here['version']} at commit "
                           f"{here['commit']}, but the campaign was defined with {pkg['version']} at commit "
                           f"{pkg['commit']}; its rows would mix two versions of the code. Run every worker with "
                           f"the campaign's version (or start a new campaign folder)")
    rec = next(s for s in d["scenarios"] if s["item"] == task.scenario)
    now = hashlib.sha256(scenario_path(task.scenario).read_bytes()).hexdigest()
    if now != rec["sha256"]:
        raise RuntimeError(f"task {task.task_id}: the scenario file {rec['file']} changed since the campaign was "
                           f"defined (SHA-256 {rec['sha256'][:12]} then, {now[:12]} now); its rows would not match "
                           f"the others. Restore the file, or start a new campaign folder")
    sc = load_task_scenario(task.scenario, task.method, task.runs, d.get("duration_s"))
    result = simulate(sc, runs=task.runs, seed=task.seed, run_start=task.run_start, batch=d["batch"],
                      key=estimator_key(sc, task.seed))
    evaluation = safe_colregs_evaluation(result)
    settings = {"campaign": d["name"], "method": result.method or "none", "seed": task.seed,
                "task_id": task.task_id, "scenario_sha256": rec["sha256"], "package_version": pkg["version"],
                "commit": pkg["commit"]}
    frame = rows_frame(simulation_rows(result, evaluation, settings))
    traj = trajectory_frame(result, settings["method"], task.seed) if d.get("trajectories") else None
    wall = time.perf_counter() - t0
    write_task(folder, task.task_id, doc["definition_sha256"], frame, {"runs": task.runs, "wall_s": wall},
               trajectories=traj)
    return {"task_id": task.task_id, "rows": len(frame), "runs": task.runs, "wall_s": wall}


_REPORT_LOCK = threading.Lock()


def _report(on_done, ok: bool, task_id: str, info) -> None:
    """Call ``on_done`` (from one thread at a time: the local engine's worker threads share it)."""
    if on_done is not None:
        with _REPORT_LOCK:
            on_done(ok, task_id, info)


def run_local(folder, doc: dict, pending: list[Task], *, workers: int = 1, on_done=None) -> dict[str, str]:
    """Run ``pending`` with the local engine (module docstring).  ``on_done(ok, task_id, info)`` is called
    after each task (info: :func:`run_task`'s dict, or the error text).  Returns ``{task_id: error}`` of the
    tasks that failed."""
    failed: dict[str, str] = {}
    if workers <= 1:
        for t in pending:
            try:
                info = run_task(folder, t, doc)
            except Exception as exc:        # one bad task does not stop the others; reported at the end
                failed[t.task_id] = f"{type(exc).__name__}: {exc}"
                _report(on_done, False, t.task_id, failed[t.task_id])
                continue
            _report(on_done, True, t.task_id, info)
        return failed
    todo: queue.Queue = queue.Queue()
    for t in pending:
        todo.put(t.task_id)
    lock = threading.Lock()
    threads = [threading.Thread(target=_drive_worker, args=(folder, todo, failed, lock, on_done), daemon=True)
               for _ in range(min(workers, len(pending)))]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    return failed


def worker_env() -> dict:
    """Environment of a worker process (local or Ray): this package first on ``PYTHONPATH``, and JAX's 64-bit
    mode and ``XLA_FLAGS`` as in this process, so a task computes the same numbers wherever it runs."""
    env = {"PYTHONPATH": os.pathsep.join([str(pathlib.Path(__file__).resolve().parents[2])] + [
        p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p])}
    if "jax" in sys.modules:
        env["JAX_ENABLE_X64"] = "1" if sys.modules["jax"].config.jax_enable_x64 else "0"
    if os.environ.get("XLA_FLAGS"):
        env["XLA_FLAGS"] = os.environ["XLA_FLAGS"]
    return env


def _start_worker(folder) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "psbmpc_jax.campaign.worker", str(folder)],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, bufsize=1,
                            env={**os.environ, **worker_env()})


def _drive_worker(folder, todo: queue.Queue, failed: dict, lock: threading.Lock, on_done) -> None:
    """One worker process's loop: send it a task id, wait for its answer line; a worker that dies loses that
    task (reported) and is replaced for the next one."""
    proc = None
    try:
        while True:
            try:
                tid = todo.get_nowait()
            except queue.Empty:
                break
            if proc is None:
                proc = _start_worker(folder)
            try:
                assert proc.stdin is not None and proc.stdout is not None     # opened with PIPE
                proc.stdin.write(tid + "\n")
                proc.stdin.flush()
                line = proc.stdout.readline()
            except (BrokenPipeError, OSError):
                line = ""
            if not line:
                rc = proc.wait()
                proc = None
                why = f"worker process died (exit status {rc}{', killed by signal ' + str(-rc) if rc < 0 else ''})"
                with lock:
                    failed[tid] = why
                _report(on_done, False, tid, why)
                continue
            msg = json.loads(line)
            if msg.get("ok"):
                _report(on_done, True, tid, msg["info"])
            else:
                with lock:
                    failed[tid] = msg["error"]
                _report(on_done, False, tid, msg["error"])
    finally:
        if proc is not None and proc.stdin is not None:
            proc.stdin.close()
            proc.wait()


def ray_missing_message() -> str:
    return ("--engine ray needs Ray, which is not installed: pip install \"psbmpc-jax[cluster]\" (or pip install "
            "ray); the local engine (--engine local, the default) needs nothing extra")


def run_ray(folder, doc: dict, pending: list[Task], *, address: str | None = None, workers: int | None = None,
            gpus_per_task: float = 0.0, on_done=None) -> dict[str, str]:
    """Run ``pending`` as Ray remote functions (``ray.init(address=address)``; without an address a local Ray
    with ``workers`` CPUs).  The campaign folder must be reachable by every Ray worker at the same path (a
    shared file system on a cluster).  Returns ``{task_id: error}`` of the tasks that failed."""
    try:
        import ray
    except ImportError:
        raise RuntimeError(ray_missing_message()) from None
    started = False
    if not ray.is_initialized():
        kwargs = {"address": address} if address else {"num_cpus": workers or os.cpu_count() or 1}
        ray.init(include_dashboard=False, log_to_driver=False, ignore_reinit_error=True,
                 runtime_env={"env_vars": worker_env()},
                 **kwargs)
        started = True
    remote = ray.remote(num_cpus=1, num_gpus=gpus_per_task, max_retries=0)(_ray_task)
    failed: dict[str, str] = {}
    try:
        refs = {remote.remote(str(folder), t.task_id): t.task_id for t in pending}
        while refs:
            ready, _ = ray.wait(list(refs), num_returns=1)
            tid = refs.pop(ready[0])
            try:
                info = ray.get(ready[0])
            except Exception as exc:        # a task's error or a lost worker: reported, the others go on
                failed[tid] = f"{type(exc).__name__}: {str(exc).strip().splitlines()[-1] if str(exc).strip() else exc}"
                _report(on_done, False, tid, failed[tid])
                continue
            _report(on_done, True, tid, info)
    finally:
        if started:
            ray.shutdown()
    return failed


def _ray_task(folder: str, task_id: str) -> dict:
    """The body of a Ray task: the campaign document and the task from the folder, then :func:`run_task`."""
    from ..cache import enable_compilation_cache

    enable_compilation_cache()
    doc = read_campaign(folder)
    if doc is None:
        raise CampaignError(f"{folder}: no campaign.json; the campaign folder is gone or was never prepared")
    task = next(t for t in tasks(doc["resolved"]) if t.task_id == task_id)
    return run_task(folder, task, doc)
