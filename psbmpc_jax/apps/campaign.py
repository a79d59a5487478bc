"""``psbmpc-jax campaign`` (scenarios x methods x seeds x runs, cut into tasks, resumable, local or Ray) and
``psbmpc-jax merge`` (combine campaign folders); docs/campaigns.md."""

from __future__ import annotations

import argparse
import sys
import time

from .argtypes import nonneg_float, positive_float, positive_int, seed_int

EPILOG_CAMPAIGN = ("Exit status: 0 all tasks done and runs.parquet written; 1 some tasks failed (the others are "
                   "on disk; run the same command again to do the rest); 2 bad input or a folder that cannot be "
                   "used.")


def _campaign_runs(text: str) -> int:
    from ..campaign.definition import MAX_CAMPAIGN_RUNS

    v = positive_int(text)
    if v > MAX_CAMPAIGN_RUNS:
        raise argparse.ArgumentTypeError(f"expected a number of runs <= {MAX_CAMPAIGN_RUNS}, got {v}")
    return v


def add_campaign_arguments(p: argparse.ArgumentParser) -> None:
    p.epilog = EPILOG_CAMPAIGN
    p.add_argument("file", nargs="?", help="campaign file (YAML; docs/campaigns.md); the flags below override it, "
                                           "and without a file they define the campaign")
    p.add_argument("--out", required=True, help="campaign folder: created, or resumed when it holds the same "
                                                "campaign")
    p.add_argument("--name", default=None, help="campaign name (default: the file's stem, or 'campaign')")
    p.add_argument("--scenarios", nargs="+", default=None, metavar="SCENARIO",
                   help="built-in scenario names or YAML paths")
    p.add_argument("--methods", nargs="+", default=None, metavar="METHOD",
                   help="own-ship methods (default: each scenario's own mpc.method)")
    p.add_argument("--seeds", nargs="+", type=seed_int, default=None, metavar="SEED", help="base seeds")
    p.add_argument("--runs", type=_campaign_runs, default=None, help="runs per scenario x method x seed")
    p.add_argument("--chunk-runs", type=positive_int, default=None, help="at most this many runs per task "
                                                                         "(default 50)")
    p.add_argument("--duration", type=positive_float, default=None, metavar="SECONDS",
                   help="cut every scenario to this duration [s]")
    p.add_argument("--batch", choices=("auto", "vmap", "loop"), default=None, help="as psbmpc-jax run --batch")
    p.add_argument("--trajectories", action="store_true", default=None,
                   help="also store every run's trajectories (trajectories.parquet)")
    p.add_argument("--engine", choices=("local", "ray"), default="local",
                   help="local (default, no extra dependency) or ray (pip install \"psbmpc-jax[cluster]\")")
    p.add_argument("--workers", type=positive_int, default=1,
                   help="local: worker processes (1: tasks one after another in this process); ray without "
                        "--ray-address: CPUs of the local Ray")
    p.add_argument("--ray-address", default=None, help="Ray cluster address (ray.init(address=...)); the campaign "
                                                       "folder must be on a file system every node sees")
    p.add_argument("--gpus-per-task", type=nonneg_float, default=0.0, help="Ray: GPUs each task asks for")
    p.add_argument("--force", action="store_true",
                   help="the folder holds a different campaign: remove its campaign files and start afresh")
    p.add_argument("--quiet", action="store_true", help="no line per task")


def add_merge_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("folders", nargs="+", help="complete campaign folders (or earlier merges)")
    p.add_argument("--out", required=True, help="folder for the merged runs.parquet and campaign.json")
    p.add_argument("--force", action="store_true", help="replace an earlier merge in --out")


def _flag_names(text: str, args) -> str:
    """An error message with the campaign field given by a flag named as the flag too (``--duration``)."""
    if args.duration is not None:
        text = text.replace("campaign field 'duration_s'", "campaign field 'duration_s' (--duration)")
    return text


def run_campaign_cli(args, parser) -> int:
    from ..campaign import definition as d
    from ..campaign.runner import run_campaign
    from ..campaign.store import CampaignError
    from ..safe_io import OutputError

    overrides = {"name": args.name, "scenarios": args.scenarios, "methods": args.methods, "seeds": args.seeds,
                 "runs": args.runs, "chunk_runs": args.chunk_runs, "duration_s": args.duration,
                 "batch": args.batch, "trajectories": args.trajectories}
    try:
        if args.file:
            defn = d.load_definition(args.file, overrides)
        else:
            defn = d.definition_from_dict({k: v for k, v in overrides.items() if v is not None},
                                          source="command line")
    except FileNotFoundError as exc:
        parser.error(str(exc))
    except ValueError as exc:
        parser.error(_flag_names(str(exc), args))
    if args.engine == "local" and (args.ray_address or args.gpus_per_task):
        parser.error("--ray-address and --gpus-per-task need --engine ray")
    from ..cache import enable_compilation_cache

    enable_compilation_cache()
    n_done = [0]
    t0 = time.perf_counter()

    def on_done(ok, tid, info):
        n_done[0] += 1
        if args.quiet:
            return
        if ok:
            print(f"[{n_done[0]}] {tid}: {info['runs']} runs in {info['wall_s']:.1f} s "
                  f"({time.perf_counter() - t0:.0f} s elapsed)", file=sys.stderr, flush=True)
        else:
            print(f"[{n_done[0]}] {tid}: FAILED: {info}", file=sys.stderr, flush=True)

    try:
        res = run_campaign(defn, args.out, engine=args.engine, workers=args.workers, ray_address=args.ray_address,
                           gpus_per_task=args.gpus_per_task, force=args.force, on_done=on_done)
    except (CampaignError, OutputError, ValueError) as exc:
        print(f"psbmpc-jax campaign: error: {_flag_names(str(exc), args)}", file=sys.stderr)
        return 2
    except RuntimeError as exc:        # --engine ray without Ray
        print(f"psbmpc-jax campaign: error: {exc}", file=sys.stderr)
        return 2
    head = (f"psbmpc-jax campaign {defn.name}: {res['tasks']} tasks ({res['skipped']} done before, {res['ran']} run "
            f"now) in {res['wall_s']:.0f} s")
    if res["failed"]:
        print(f"{head}; {len(res['failed'])} FAILED: " + "; ".join(f"{k}: {v}" for k, v in
                                                                  list(res["failed"].items())[:5])
              + f". Run the same command again to do them (finished tasks are kept in {res['folder']}/tasks).")
        return 1
    print(f"{head}. Table: {res['runs_parquet']}")
    return 0


def run_merge_cli(args, parser) -> int:
    from ..campaign.merge import merge_folders
    from ..campaign.store import CampaignError
    from ..safe_io import OutputError

    try:
        res = merge_folders(args.folders, args.out, force=args.force)
    except (CampaignError, OutputError) as exc:
        print(f"psbmpc-jax merge: error: {exc}", file=sys.stderr)
        return 2
    print(f"psbmpc-jax merge: {len(args.folders)} folders, {res['rows']} rows -> {res['folder']}/runs.parquet")
    return 0
