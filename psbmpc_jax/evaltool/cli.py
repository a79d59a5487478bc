"""``psbmpc-jax evaluate``: COLREGS scores of saved trajectories (the simulator's ``trajectories.npz`` /
``trajectories.csv`` or output folder, or a user CSV in the documented column format, docs/evaltool.md).

    psbmpc-jax evaluate results/head_on/trajectories.npz --range-scale 0.16666667
    psbmpc-jax evaluate my_ais_tracks.csv --own ferry --preset inland_small --set r_stage2_m=120 --out scores.json

Prints, per file, one line per encounter (run, vessels, situation, status, CPA range, S_sit, S_safety, the
penalties that apply) and the summary over runs per pair of vessels; ``--out`` writes everything as JSON.
Exit status 2 (with a message naming the file) for a file that cannot be read or scored.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import pathlib
import sys

from .aggregate import aggregate
from .evaluate import PAIR_MODES, evaluate_tracks
from .params import PRESETS, EvalParams, scaled_params
from .tracks import load_runs

#: Penalties printed per encounter when they apply and are > 0.
PRINTED_PENALTIES = ("P_delay", "P_na_delta", "P_nsb", "P_sts", "P_ah13", "P_ah15", "P_2", "P_3", "P_pt")


def add_evaluate_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("paths", nargs="+", help="trajectories.npz / trajectories.csv / a `run` output folder / a user "
                                            "CSV (columns t_s, vessel, north_m, east_m[, course_deg, speed_mps])")
    p.add_argument("--preset", choices=tuple(PRESETS), default="default",
                   help="parameter preset (default: the SPEC's open-water values; inland_small: seed 000 Table V)")
    p.add_argument("--range-scale", type=float, default=1.0, metavar="X",
                   help="multiply the preset's stage radii and CPA ranges by X > 0 (e.g. 5/30 for 5 m vessels "
                        "whose collision distance is 5 m)")
    p.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE", dest="overrides",
                   help="override one EvalParams field after the scaling (repeatable), e.g. r_stage2_m=300")
    p.add_argument("--own", default=None, help="name of the own-ship (default: the file's own-ship / first vessel)")
    p.add_argument("--pairs", choices=PAIR_MODES, default="own",
                   help="own: own-ship against every other vessel (default); all: every ordered pair")
    p.add_argument("--out", default=None, help="write the scores as JSON to this file")


def _value(field: dataclasses.Field, text: str):
    if field.type in (bool, "bool"):
        low = text.strip().lower()
        if low not in ("true", "false", "1", "0"):
            raise ValueError(f"--set {field.name}: true or false expected, got {text!r}")
        return low in ("true", "1")
    if field.type in (str, "str"):
        return text
    try:
        return float(text)
    except ValueError:
        raise ValueError(f"--set {field.name}: a number expected, got {text!r}") from None


def params_from_args(args) -> EvalParams:
    """The :class:`EvalParams` of ``--preset``, ``--range-scale`` and ``--set`` (ValueError naming the option)."""
    if not (math.isfinite(args.range_scale) and args.range_scale > 0):
        raise ValueError(f"--range-scale must be a finite number > 0, got {args.range_scale:g}")
    fields = {f.name: f for f in dataclasses.fields(EvalParams)}
    kw = {}
    for item in args.overrides:
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep:
            raise ValueError(f"--set expects FIELD=VALUE, got {item!r}")
        if key not in fields:
            raise ValueError(f"--set: unknown field {key!r}; allowed: {', '.join(fields)}")
        kw[key] = _value(fields[key], text)
    return scaled_params(args.preset, args.range_scale, **kw)


def _fmt(v, nd: int = 2) -> str:
    return "—" if v is None else f"{v:.{nd}f}"


def encounter_line(run: int, e) -> str:
    s = e.scores
    pen = [f"{k} {getattr(s, k):.2f}" for k in PRINTED_PENALTIES if getattr(s, k) is not None and getattr(s, k) > 0]
    return (f"  run {run:3d}  {e.vessel} vs {e.other}: {e.situation:4s} {e.status:10s} CPA {_fmt(e.r_cpa, 1)} m at "
            f"{_fmt(e.t_cpa, 0)} s  S_sit {_fmt(s.S_sit)}  S_safety {_fmt(s.S_safety)}"
            + (f"  [{', '.join(pen)}]" if pen else ""))


def run_evaluate(args, parser: argparse.ArgumentParser) -> int:
    try:
        params = params_from_args(args)
    except ValueError as exc:
        parser.error(str(exc))
    docs = []
    for path in args.paths:
        try:
            runs = load_runs(path, own=args.own)
            evs = [evaluate_tracks(tr, params, pairs=args.pairs) for tr in runs]
        except (OSError, ValueError, KeyError) as exc:
            print(f"psbmpc-jax evaluate: {path}: {exc}", file=sys.stderr)
            return 2
        agg = aggregate(evs)
        print(f"{path}: {len(evs)} run(s), {agg['encounters']} encounter(s)")
        for r, ev in enumerate(evs):
            for e in ev.encounters:
                print(encounter_line(r, e))
        for pair in agg["pairs"]:
            sc = pair["scores"]
            print(f"  {pair['vessel']} vs {pair['other']} over {pair['runs_with_encounter']} run(s): "
                  f"S_sit mean {_fmt(sc['S_sit']['mean'])} (min {_fmt(sc['S_sit']['min'])}), S_safety mean "
                  f"{_fmt(sc['S_safety']['mean'])} (min {_fmt(sc['S_safety']['min'])}); situations {pair['situations']}")
        docs.append({"path": str(path), "aggregate": agg, "runs": [ev.to_dict() for ev in evs]})
    if args.out:
        out = pathlib.Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps({"params": params.as_dict(), "pairs": args.pairs, "files": docs}, indent=1) + "\n")
        print(f"wrote {out}")
    return 0


__all__ = ["add_evaluate_arguments", "params_from_args", "run_evaluate", "encounter_line"]
