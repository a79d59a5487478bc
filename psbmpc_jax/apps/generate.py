"""``psbmpc-jax generate``: COLREGS-typed encounters as scenario files (:mod:`psbmpc_jax.scenario_generation`).

One positional TYPE per target (head_on, crossing_give_way, crossing_stand_on, overtaking, overtaken).  Writes
``<prefix>_<i>.yaml`` and ``encounters.json`` (seed, settings, rejection counts, what was drawn) into ``--out``;
refuses to write over existing files unless ``--overwrite``.  ``--check`` loads every file written with the
scenario loader and reports the evaluation tool's classification of the straight tracks (exit status 1 if a
target is not classified as requested).  Bad input: a message naming the option or field, exit status 2.
"""

from __future__ import annotations

import argparse
import collections

from ..config import yaml_load
from ..scenario import load_scenario
from ..scenario_generation import (ENCOUNTER_TYPES, PRESETS, SITUATION_CODES, classify_straight_line,
                                   generate_encounters, get_settings, settings_from_dict, write_scenarios)

#: Errors of the user's input or of existing files: a message and exit status 2, no traceback.
USER_ERRORS = (ValueError, FileExistsError, FileNotFoundError)


def add_generate_arguments(ap: argparse.ArgumentParser) -> None:
    """The options of ``psbmpc-jax generate`` (and of ``tools/generate_encounters.py``)."""
    ap.add_argument("types", nargs="+", choices=ENCOUNTER_TYPES, metavar="TYPE",
                    help=f"encounter type of each target: {', '.join(ENCOUNTER_TYPES)}")
    ap.add_argument("--count", type=int, default=1, help="number of scenario files (default 1)")
    ap.add_argument("--seed", type=int, required=True, help="random seed (file i uses default_rng([seed, i]))")
    ap.add_argument("--out", required=True, help="output folder (created if missing)")
    ap.add_argument("--preset", default="harbour", choices=tuple(PRESETS), help="generation preset (default harbour)")
    ap.add_argument("--settings", help="YAML file of generation settings (preset + fields of GenerationSettings)")
    ap.add_argument("--own-north", type=float, nargs=2, metavar=("LO", "HI"), help="own-ship start north range [m]")
    ap.add_argument("--own-east", type=float, nargs=2, metavar=("LO", "HI"), help="own-ship start east range [m]")
    ch = ap.add_mutually_exclusive_group()
    ch.add_argument("--chart-builtin", help="place the encounters on a built-in chart (e.g. trondheim)")
    ch.add_argument("--chart-file", help="place them on a chart file (path as the scenario files will read it)")
    ap.add_argument("--chart-clip-m", type=float, help="chart.clip_m of the files")
    ap.add_argument("--chart-rdp-eps-m", type=float, help="chart.rdp_eps_m of the files")
    ap.add_argument("--prefix", help="file and scenario name prefix (default: the type, or 'mixed')")
    ap.add_argument("--max-tries", type=int, default=20_000, help="draws per encounter before giving up")
    ap.add_argument("--overwrite", action="store_true", help="replace existing files (and the previous batch's)")
    ap.add_argument("--check", action="store_true", help="load every file and classify its straight tracks")


def _settings(args):
    if args.settings:
        with open(args.settings, encoding="utf-8") as fh:
            d = yaml_load(fh.read(), args.settings)
        if not isinstance(d, dict):
            raise ValueError(f"{args.settings}: generation settings must be a mapping")
        if "preset" not in d:
            d = {"preset": args.preset, **d}
        s = settings_from_dict(d)
    else:
        s = get_settings(args.preset)
    over = {}
    if args.own_north:
        over["own_north_m"] = tuple(args.own_north)
    if args.own_east:
        over["own_east_m"] = tuple(args.own_east)
    return get_settings(s, **over) if over else s


def _chart(args):
    if not (args.chart_builtin or args.chart_file):
        if args.chart_clip_m is not None or args.chart_rdp_eps_m is not None:
            raise ValueError("--chart-clip-m / --chart-rdp-eps-m need --chart-builtin or --chart-file")
        return None
    c = {"builtin": args.chart_builtin} if args.chart_builtin else {"file": args.chart_file}
    if args.chart_clip_m is not None:
        c["clip_m"] = args.chart_clip_m
    if args.chart_rdp_eps_m is not None:
        c["rdp_eps_m"] = args.chart_rdp_eps_m
    return c


def run(args) -> int:
    settings = _settings(args)
    batch = generate_encounters(args.types, args.count, seed=args.seed, settings=settings, chart=_chart(args),
                                base_dir=args.out, prefix=args.prefix, max_tries=args.max_tries)
    paths = write_scenarios(batch, args.out, overwrite=args.overwrite, validate=False)
    shown = ", ".join(f"{k} {v}" for k, v in sorted(batch.rejections.items())) or "none"
    print(f"wrote {len(paths)} scenario files to {args.out} (rejected draws: {shown})")
    if not args.check:
        return 0
    want = tuple(SITUATION_CODES[k] for k in args.types)
    got: collections.Counter[str] = collections.Counter()
    bad = []
    for p in paths:
        cls = classify_straight_line(load_scenario(p))
        got.update(cls)
        if cls != want:
            bad.append(f"{p.name}: {cls}")
    print(f"straight-line classification: {dict(got)} (requested {want} per file); {len(bad)} files differ")
    for b in bad[:10]:
        print("  " + b)
    return 1 if bad else 0
