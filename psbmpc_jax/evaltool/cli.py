"""``psbmpc-jax evaluate``: COLREGS scores of saved trajectories (the simulator's ``trajectories.npz`` /
``trajectories.csv`` or run folder, or a user CSV in the documented column format, docs/evaltool.md).

    psbmpc-jax evaluate results/head_on                      # a run folder: the run's own evaluation settings
    psbmpc-jax evaluate results/head_on/trajectories.npz --range-scale 0.16666667
    psbmpc-jax evaluate my_tracks.csv --own ferry --preset inland_small --set r_stage2_m=120 --out scores.json
    psbmpc-jax evaluate examples/ais/crossing_trondheimsfjord.csv --own-mmsi 257000001 --range-scale 0.16666667

The parameters: ``--preset`` / ``--range-scale`` when given; otherwise, for a run folder (or a file in one), the
evaluation settings stored with the run (``metrics.json``: the scenario's ``evaluation`` section), else the
``default`` preset; ``--set`` then changes single fields.  Prints, per file, the ranges used and where they came
from, one line per encounter (run, vessels, situation, status, CPA range, S_sit, S_safety, the penalties that
apply) and the summary over runs per pair of vessels; ``--out`` writes everything as JSON (atomically; never
over an input file or a file of a run folder it reads, nor over another file unless ``--force``).

``--explain`` prints, per encounter, the stages, the manoeuvres, the CPA and every score and penalty with its
value, when it fired and why (:mod:`psbmpc_jax.evaltool.explain`); ``--out`` is then a folder that receives
``explain.json`` (with the evaluation settings), ``explain.txt`` and one figure per encounter, written as a
run folder (:mod:`psbmpc_jax.runfolder`: staged, manifest last; another run's folder only with ``--force``,
never an input's folder).
Before scoring anything, every file is read and the time of scoring all their runs is estimated, printed on
stderr and checked against the limit (:func:`psbmpc_jax.limits.check_evaluation_time`, 1 h or
``PSBMPC_EVALUATION_TIME_LIMIT``).  Exit status 2 (with a message naming the file) for a file that cannot be read
or scored, or for an evaluation above the time limit.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import pathlib
import sys

from ..safe_io import OutputError, atomic_write_text, file_output_problem, read_json_document, same_file
from .aggregate import aggregate
from ..limits import check_evaluation_time, describe_evaluation
from .evaluate import PAIR_MODES, evaluate_tracks, run_shapes
from .explain import EXPLAIN_SCHEMA, explain_encounter, explanation_text
from .params import PRESETS, EvalParams, scaled_params
from .tracks import load_runs

#: Penalties printed per encounter when they apply and are > 0.
PRINTED_PENALTIES = ("P_delay", "P_na_delta", "P_nsb", "P_sts", "P_ah13", "P_ah15", "P_2", "P_3", "P_pt")
#: Schema id of the ``--out`` document.
OUTPUT_SCHEMA = "psbmpc-eval/1"
#: Files of a folder that ``evaluate`` may read (never written over).
_READ_IN_FOLDER = ("trajectories.npz", "trajectories.csv", "metrics.json", "manifest.json")


def add_evaluate_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("paths", nargs="+", help="trajectories.npz / trajectories.csv / a `run` output folder / a user "
                                            "CSV (columns t_s, vessel, north_m, east_m[, course_deg, speed_mps]) / "
                                            "an AIS-style CSV (columns timestamp, MMSI, lat, lon[, SOG, COG])")
    p.add_argument("--preset", choices=tuple(PRESETS), default=None,
                   help="parameter preset (default: a run's stored evaluation settings, else 'default', the "
                        "open-water values; inland_small: Mahipala & Johansen 2024, Table V)")
    p.add_argument("--range-scale", type=float, default=None, metavar="X",
                   help="multiply the preset's stage radii and CPA ranges by X > 0 (e.g. 5/30 for 5 m vessels "
                        "whose collision distance is 5 m); with it the preset replaces a run's stored settings")
    p.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE", dest="overrides",
                   help="override one EvalParams field after the scaling (repeatable), e.g. r_stage2_m=300; on a "
                        "run's stored settings too")
    p.add_argument("--own", "--own-mmsi", default=None, dest="own",
                   help="the own-ship: its name, or its MMSI in an AIS-style file (default: the file's own-ship / "
                        "first vessel; required for an AIS-style file with several vessels)")
    p.add_argument("--dt", type=float, default=None, metavar="SECONDS",
                   help="AIS-style files only: step of the common clock the vessels' reports are resampled onto "
                        "(default 1 s)")
    p.add_argument("--pairs", choices=PAIR_MODES, default="own",
                   help="own: own-ship against every other vessel (default); all: every ordered pair")
    p.add_argument("--out", default=None, help="write the scores as JSON to this file (atomically; an existing "
                                               "file is replaced only if it is an earlier evaluate output)")
    p.add_argument("--force", action="store_true", help="let --out replace an existing file of another kind (with "
                                                        "--explain: the files of an earlier output folder)")
    p.add_argument("--explain", action="store_true",
                   help="explain every score: stages, manoeuvres, CPA and each penalty with its value, time and "
                        "condition; with --out FOLDER also explain.json, explain.txt and one figure per encounter")


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


def _overrides(args) -> dict:
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
    return kw


def params_from_args(args, stored: EvalParams | None = None) -> EvalParams:
    """The :class:`EvalParams` of the command line (ValueError naming the option): ``--preset`` and
    ``--range-scale`` when either is given, else ``stored`` (a run's own settings) when given, else the
    ``default`` preset; then the ``--set`` fields."""
    scale = getattr(args, "range_scale", None)
    if scale is not None and not (math.isfinite(scale) and scale > 0):
        raise ValueError(f"--range-scale must be a finite number > 0, got {scale:g}")
    kw = _overrides(args)
    preset = getattr(args, "preset", None)
    if stored is not None and preset is None and scale is None:
        try:
            return stored.replace(**kw) if kw else stored
        except ValueError as exc:
            raise ValueError(f"--set on the run's stored settings: {exc}") from None
    return scaled_params(preset or "default", 1.0 if scale is None else scale, **kw)


def _run_folder(path: pathlib.Path) -> pathlib.Path | None:
    """The run folder ``path`` is or lies in (a folder with a psbmpc-jax manifest), else None."""
    from ..runfolder import read_manifest

    folder = path if path.is_dir() else path.parent
    return folder if read_manifest(folder, foreign="ignore") is not None else None


def stored_params(path) -> tuple[EvalParams, str] | None:
    """The evaluation settings stored with the run whose folder ``path`` is or lies in (``metrics.json``: the
    scenario's ``evaluation`` section, else the parameters its evaluation recorded), and the file they came
    from; None outside a run folder.  metrics.json is checked against the run's manifest first."""
    from ..runfolder import verify_member

    folder = _run_folder(pathlib.Path(path))
    if folder is None:
        return None
    metrics = folder / "metrics.json"
    if not metrics.is_file():
        raise FileNotFoundError(f"{metrics}: the run folder has no metrics.json")
    verify_member(metrics)
    doc = read_json_document(metrics, what="run's metrics file")
    if not isinstance(doc, dict):
        raise ValueError(f"{metrics}: not a run's metrics file (a JSON {type(doc).__name__}, not an object)")
    stored = doc.get("scenario", {}).get("evaluation") or doc.get("colregs_evaluation", {}).get("params")
    if not stored:
        return None
    try:
        return EvalParams(**stored), str(metrics)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{metrics}: the stored evaluation settings cannot be used ({exc})") from None


def ranges_line(p: EvalParams) -> str:
    """The ranges of ``p`` in one line (what ``evaluate`` prints)."""
    return (f"stages r_Stage2/3/4 {p.r_stage2_m:g} / {p.r_stage3_m:g} / {p.r_stage4_m:g} m, CPA ranges r_pref "
            f"{p.r_pref_m:g}, r_min {p.r_min_m:g}, r_nm {p.r_nm_m:g}, r_col {p.r_col_m:g} m, sample interval "
            f"{p.sample_interval_s:g} s")


def _protected(paths) -> list[pathlib.Path]:
    """Every file ``evaluate`` reads or that belongs to a run folder it reads."""
    from ..runfolder import read_manifest

    out = []
    for path in paths:
        p = pathlib.Path(path).expanduser()
        if p.is_file() or not p.exists():
            out.append(p)
        folder = p if p.is_dir() else p.parent
        out += [folder / n for n in _READ_IN_FOLDER if p.is_dir() or n in ("metrics.json", "manifest.json")]
        try:
            doc = read_manifest(folder)
        except ValueError:
            doc = None
        if doc is not None:
            out += [folder / n for n in doc["files"]]
    return out


def output_problem(out, paths, force: bool = False) -> str | None:
    """Why ``--out`` may not be written, or None: it names an input file or a file of a run folder read (also
    through a symlink or another spelling), it cannot be written, or it is an existing file that is not an
    earlier ``evaluate`` output (unless ``force``)."""
    o = pathlib.Path(out).expanduser()
    for p in _protected(paths):
        if same_file(o, p):
            return (f"--out {out}: that is {p}, a file this command reads or a result of the run it reads; "
                    f"refusing to write over it (choose another file)")
    problem = file_output_problem(o)
    if problem:
        return f"--out {out}: {problem}"
    if o.is_file() and not force:
        try:
            read_json_document(o, what="evaluate output", schema=OUTPUT_SCHEMA)
        except ValueError:
            return (f"--out {out}: the file exists and is not an earlier psbmpc-jax evaluate output; choose "
                    f"another name, remove it, or pass --force to replace it")
    return None


def explain_out_problem(out, paths, force: bool = False) -> str | None:
    """Why ``--out`` cannot be the ``--explain`` folder, or None: it is a file, it is (or holds) an input or
    the folder of one, or it holds another run's results and ``force`` is not given
    (:func:`psbmpc_jax.runfolder.run_folder_problem`)."""
    import os

    from ..runfolder import run_folder_problem

    o = pathlib.Path(out).expanduser()
    if o.exists() and not o.is_dir():
        return (f"--out {out}: with --explain, --out is a folder (explain.json, explain.txt and the figures go "
                f"there), and {o} is a file")
    real = os.path.realpath(o)
    for path in paths:
        p = pathlib.Path(path).expanduser()
        folder = p if p.is_dir() else p.parent
        inside = os.path.commonpath([real, os.path.realpath(p)]) == real
        if same_file(o, folder) or inside:
            return (f"--out {out}: that folder holds {path}, which this command reads; choose another folder for "
                    f"the explanation")
    return run_folder_problem(o, force=force)


def _slug(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in str(name))[:40] or "_"


def write_explanations(out, doc: dict, text: str, figures: list, force: bool = False) -> dict:
    """Write the ``--explain`` folder ``out``: ``explain.json`` (``doc``), ``explain.txt`` (``text``) and one
    figure per ``(Evaluation, Encounter, explanation, file name)`` of ``figures``, as a run folder (staged,
    the manifest last; :class:`psbmpc_jax.runfolder.RunWriter`).  Returns ``{name: path}``."""
    from ..runfolder import RunWriter
    from .explain_plot import plot_explanation

    w = RunWriter(out, force=force, meta={"command": "psbmpc-jax evaluate --explain", "schema_of_content":
                                          doc["schema"]})
    try:
        atomic_write_text(w.path("explain.json"), json.dumps(doc, indent=1) + "\n")
        atomic_write_text(w.path("explain.txt"), text + "\n")
        for ev, e, x, name in figures:
            plot_explanation(ev, e, x, w.path(name))
        return w.commit()
    except BaseException:
        w.abort()
        raise


def _fmt(v, nd: int = 2) -> str:
    return "—" if v is None else f"{v:.{nd}f}"


def encounter_line(run: int, e) -> str:
    s = e.scores
    pen = [f"{k} {getattr(s, k):.2f}" for k in PRINTED_PENALTIES if getattr(s, k) is not None and getattr(s, k) > 0]
    return (f"  run {run:3d}  {e.vessel} vs {e.other}: {e.situation:4s} {e.status:10s} CPA {_fmt(e.r_cpa, 1)} m at "
            f"{_fmt(e.t_cpa, 0)} s  S_sit {_fmt(s.S_sit)}  S_safety {_fmt(s.S_safety)}"
            + (f"  [{', '.join(pen)}]" if pen else ""))


def _file_failed(path, exc) -> int:
    """Report a file that cannot be read or scored (its name first) and return the exit status 2."""
    text = str(exc)
    named = text.startswith(str(path)) or text.startswith(str(pathlib.Path(path)))
    print(f"psbmpc-jax evaluate: {text if named else f'{path}: {text}'}", file=sys.stderr)
    return 2


def _check_time(loaded, pairs: str, quiet: bool = False) -> float:
    """Log the estimated time of scoring every run of every file read (``loaded``: ``(path, stored, params,
    runs)``) on stderr (not when ``quiet``: ``psbmpc-jax -q``), and refuse it above the limit
    (:func:`psbmpc_jax.limits.check_evaluation_time`: ResourceError naming the files, samples, vessels, pairs,
    estimate and limit)."""
    shapes, paths = [], [str(path) for path, *_ in loaded]
    for _, _, params, runs in loaded:
        shapes += run_shapes(runs, params.sample_interval_s)
    dts = sorted({params.sample_interval_s for _, _, params, _ in loaded})
    what = paths[0] if len(paths) == 1 else (f"{len(paths)} track files ({', '.join(paths[:3])}"
                                             + (", ..." if len(paths) > 3 else "") + ")")
    if not quiet:
        print(f"psbmpc-jax evaluate: scoring {what}: {describe_evaluation(shapes, pairs)}", file=sys.stderr,
              flush=True)
    return check_evaluation_time(
        shapes, pairs, what=f"evaluation of {what}", pairs_setting="--pairs",
        sample_interval="sample_interval_s = " + " / ".join(f"{dt:g}" for dt in dts) + " s",
        hint="Fewer or shorter track files per call" + (", --pairs own" if pairs == "all" else "")
             + " or a larger sample interval (--set sample_interval_s=...)")


def run_evaluate(args, parser: argparse.ArgumentParser) -> int:
    try:                                          # the options alone: a usage error before any file is read
        _overrides(args)
        if args.range_scale is not None and not (math.isfinite(args.range_scale) and args.range_scale > 0):
            raise ValueError(f"--range-scale must be a finite number > 0, got {args.range_scale:g}")
        if args.dt is not None and not (math.isfinite(args.dt) and args.dt > 0):
            raise ValueError(f"--dt must be a finite number of seconds > 0, got {args.dt:g}")
    except ValueError as exc:
        parser.error(str(exc))
    if args.out:
        if args.explain:
            problem = explain_out_problem(args.out, args.paths, force=args.force)
        else:
            problem = output_problem(args.out, args.paths, force=args.force)
        if problem:
            parser.error(problem)
    loaded = []                 # every file read (and its settings) before any is scored: the time of them all
    for path in args.paths:
        try:
            stored = stored_params(path)
        except (OSError, ValueError) as exc:
            print(f"psbmpc-jax evaluate: {exc}", file=sys.stderr)
            return 2
        try:
            params = params_from_args(args, None if stored is None else stored[0])
        except ValueError as exc:
            parser.error(str(exc) if stored is None else f"{path}: {exc}")
        try:
            loaded.append((path, stored, params, load_runs(path, own=args.own, dt=args.dt)))
        except (OSError, ValueError, KeyError) as exc:
            return _file_failed(path, exc)
    try:
        _check_time(loaded, args.pairs, quiet=getattr(args, "log_quiet", False))
    except ValueError as exc:
        print(f"psbmpc-jax evaluate: {exc}", file=sys.stderr)
        return 2
    docs: list[dict] = []
    texts: list[str] = []
    figures: list[tuple] = []
    for path, stored, params, runs in loaded:
        try:
            evs = [evaluate_tracks(tr, params, pairs=args.pairs) for tr in runs]
        except (OSError, ValueError, KeyError) as exc:
            return _file_failed(path, exc)
        explicit = args.preset is not None or args.range_scale is not None
        if stored is not None and not explicit:
            source = f"the run's stored evaluation settings ({stored[1]})"
        else:
            source = f"preset {args.preset or 'default'}" + (
                f" x {args.range_scale:g}" if args.range_scale is not None else "")
            if stored is not None:
                source += f", replacing the run's stored settings ({stored[1]})"
        if args.overrides:
            source += ", with " + ", ".join(args.overrides)
        agg = aggregate(evs)
        print(f"{path}: {len(evs)} run(s), {agg['encounters']} encounter(s)")
        print(f"  ranges: {ranges_line(params)} (from {source})")
        if runs[0].t0_utc is not None:
            tr = runs[0]
            print(f"  AIS reports of {tr.n_vessels} vessels (MMSI {', '.join(tr.names)}) resampled every "
                  f"{tr.t[1] - tr.t[0]:g} s over their common period: t = 0 s is {tr.t0_utc}, t = {tr.t[-1]:g} s "
                  f"the end (reports outside it are not scored; -v counts them); own-ship {tr.own_name}")
        explained = []
        for r, ev in enumerate(evs):
            for n, e in enumerate(ev.encounters):
                if not args.explain:
                    print(encounter_line(r, e))
                    continue
                x = explain_encounter(ev, e, r)
                x["figure"] = (f"explain_f{len(docs)}_run{r:03d}_{n:02d}_{_slug(e.vessel)}_vs_{_slug(e.other)}.png"
                               if args.out else None)
                texts.append(explanation_text(x))
                print(texts[-1] + "\n")
                if args.out:
                    figures.append((ev, e, x, x["figure"]))
                explained.append(x)
        for pair in agg["pairs"]:
            sc = pair["scores"]
            print(f"  {pair['vessel']} vs {pair['other']} over {pair['runs_with_encounter']} run(s): "
                  f"S_sit mean {_fmt(sc['S_sit']['mean'])} (min {_fmt(sc['S_sit']['min'])}), S_safety mean "
                  f"{_fmt(sc['S_safety']['mean'])} (min {_fmt(sc['S_safety']['min'])}); situations {pair['situations']}")
        if args.explain:
            docs.append({"path": str(path), "params": params.as_dict(), "params_from": source, "aggregate": agg,
                         "encounters": explained} | ({"t0_utc": runs[0].t0_utc} if runs[0].t0_utc else {}))
            continue
        docs.append({"path": str(path), "params": params.as_dict(), "params_from": source, "aggregate": agg,
                     "runs": [ev.to_dict() for ev in evs]} | ({"t0_utc": runs[0].t0_utc} if runs[0].t0_utc else {}))
    if args.out and args.explain:
        same = all(d["params"] == docs[0]["params"] for d in docs)
        doc = {"schema": EXPLAIN_SCHEMA, "params": docs[0]["params"] if same else None, "pairs": args.pairs,
               "files": docs}
        try:
            written = write_explanations(args.out, doc, "\n\n".join(texts), figures, force=args.force)
        except (OSError, OutputError, ValueError) as exc:
            print(f"psbmpc-jax evaluate: --out {args.out}: {exc}", file=sys.stderr)
            return 2
        print(f"wrote {args.out}: explain.json, explain.txt and {len(written) - 2} figure(s)")
        return 0
    if args.out:
        same = all(d["params"] == docs[0]["params"] for d in docs)
        doc = {"schema": OUTPUT_SCHEMA, "params": docs[0]["params"] if same else None, "pairs": args.pairs,
               "files": docs}
        try:
            out = pathlib.Path(args.out).expanduser()
            out.parent.mkdir(parents=True, exist_ok=True)
            atomic_write_text(out, json.dumps(doc, indent=1) + "\n")
        except OSError as exc:
            print(f"psbmpc-jax evaluate: --out {args.out}: {exc}", file=sys.stderr)
            return 2
        print(f"wrote {out}")
    return 0


__all__ = ["add_evaluate_arguments", "params_from_args", "run_evaluate", "encounter_line", "stored_params",
           "output_problem", "explain_out_problem", "write_explanations", "ranges_line", "OUTPUT_SCHEMA"]
