"""A local-engine worker process: ``python -m psbmpc_jax.campaign.worker FOLDER`` reads task ids from stdin, one a
line, runs each (:func:`psbmpc_jax.campaign.executor.run_task`) and answers one JSON line per task on stdout
(``{"ok": true, "info": ...}`` or ``{"ok": false, "error": ...}``).  Everything else the process prints goes to
stderr, so the answers stay readable.  It compiles once and serves tasks until stdin closes."""

from __future__ import annotations

import json
import os
import sys


def main(argv=None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 1:
        print("usage: python -m psbmpc_jax.campaign.worker CAMPAIGN_FOLDER", file=sys.stderr)
        return 2
    answers = os.fdopen(os.dup(sys.stdout.fileno()), "w", buffering=1)
    os.dup2(sys.stderr.fileno(), sys.stdout.fileno())      # stray prints of libraries go to stderr

    from ..cache import enable_compilation_cache
    from .definition import tasks
    from .executor import run_task
    from .store import read_campaign

    enable_compilation_cache()
    folder = args[0]
    doc = read_campaign(folder)
    if doc is None:
        print(f"{folder}: not a campaign folder", file=sys.stderr)
        return 2
    by_id = {t.task_id: t for t in tasks(doc["resolved"])}
    for line in sys.stdin:
        tid = line.strip()
        if not tid:
            continue
        try:
            if tid not in by_id:
                raise KeyError(f"no task {tid!r} in the campaign of {folder}")
            msg = {"ok": True, "info": run_task(folder, by_id[tid], doc)}
        except Exception as exc:          # reported to the parent, which goes on with the other tasks
            msg = {"ok": False, "error": f"{type(exc).__name__}: {exc}"}
        answers.write(json.dumps(msg) + "\n")
        answers.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
