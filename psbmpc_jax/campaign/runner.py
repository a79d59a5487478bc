"""One call that runs a campaign into a folder: resolve and check the definition, open (or resume) the folder,
run the tasks not yet done with the chosen engine, and write ``runs.parquet`` when every task is done."""

from __future__ import annotations

import logging
import pathlib
import time

from .definition import CampaignDefinition, resolve, tasks
from .executor import ENGINES, run_local, run_ray
from .store import RUNS_FILE, assemble, prepare_folder, task_done, verified_table

__all__ = ["run_campaign"]

log = logging.getLogger(__name__)


def run_campaign(defn: CampaignDefinition, out, *, engine: str = "local", workers: int = 1,
                 ray_address: str | None = None, gpus_per_task: float = 0.0, force: bool = False,
                 on_done=None) -> dict:
    """Run the campaign ``defn`` into the folder ``out`` (docs/campaigns.md).

    Finished tasks of the same campaign are skipped (resume); a folder of another campaign is refused unless
    ``force``.  ``on_done(ok, task_id, info)`` is called after every task.

    Returns ``{"folder", "tasks", "skipped", "ran", "failed" ({task_id: error}), "runs_parquet" (None until every
    task is done), "wall_s"}``.
    """
    if engine not in ENGINES:
        raise ValueError(f"engine must be one of {', '.join(ENGINES)}, got {engine!r}")
    if engine == "ray":
        try:
            import ray  # noqa: F401
        except ImportError:
            from .executor import ray_missing_message

            raise RuntimeError(ray_missing_message()) from None
    t0 = time.perf_counter()
    resolved = resolve(defn)
    folder = pathlib.Path(out)
    doc = prepare_folder(folder, resolved, force=force)
    all_tasks = tasks(resolved)
    pending = [t for t in all_tasks if not task_done(folder, t.task_id, doc["definition_sha256"])]
    log.info("campaign %s: %d tasks, %d done before, %d to run", defn.name, len(all_tasks),
             len(all_tasks) - len(pending), len(pending))
    if engine == "ray":
        failed = run_ray(folder, doc, pending, address=ray_address, workers=workers, gpus_per_task=gpus_per_task,
                         on_done=on_done) if pending else {}
    else:
        failed = run_local(folder, doc, pending, workers=workers, on_done=on_done) if pending else {}
    table = None
    if not failed:
        if doc.get("complete") and not pending:
            table, _ = verified_table(folder)
        else:
            table = assemble(folder, doc)
    return {"folder": folder, "tasks": len(all_tasks), "skipped": len(all_tasks) - len(pending),
            "ran": len(pending) - len(failed), "failed": failed,
            "runs_parquet": table if table is None else folder / RUNS_FILE, "wall_s": time.perf_counter() - t0}
