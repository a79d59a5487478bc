"""The psbmpc-jax command line: example, run, bench and report (help texts are plain text, no markup)."""

from __future__ import annotations

import argparse
import difflib
import logging
import os
import pathlib
import statistics
import sys
import tempfile
import time

from ..cache import enable_compilation_cache
from ..methods import get_method, names
from .argtypes import devices_arg, nonneg_int, odd_int, positive_int, runs_int, seed_int



def method_arg(value: str) -> str:
    """``--method``: a registered method, an entry point's or an import path ``package.module:Name`` (the
    registry's rules, :func:`psbmpc_jax.methods.get_method`); anything else is refused with the known names."""
    try:
        get_method(value, "--method")
    except (ValueError, ImportError, TypeError) as err:
        raise argparse.ArgumentTypeError(str(err)) from None
    return value

DESCRIPTION = """\
PSB-MPC ship collision avoidance in JAX.

  psbmpc-jax example  solve the built-in paper-scale head-on situation once (1014 control
                      behaviours, 2 obstacles x 5 prediction scenarios, T = 150 s, dt = 0.5 s):
                      the chosen maneuver, the best behaviours' costs and the solve time
  psbmpc-jax run      closed-loop Monte Carlo simulation of scenario files, metrics (with COLREGS
                      scores) and figures
  psbmpc-jax evaluate COLREGS safety/compliance scores of saved or user trajectories
  psbmpc-jax generate COLREGS-typed encounters (head-on, crossing, overtaking) as scenario files
  psbmpc-jax campaign scenarios x methods x seeds x runs in resumable tasks (local or Ray), one table
  psbmpc-jax merge    combine campaign folders into one table
  psbmpc-jax bench    runtime benchmark sweeps (JSON Lines records)
  psbmpc-jax report   Markdown report with figures from benchmark records

Without a subcommand psbmpc-jax runs example, and example's options may follow directly
(psbmpc-jax --n-m 1 is psbmpc-jax example --n-m 1). psbmpc-jax SUBCOMMAND --help lists the
options of each subcommand.

Messages of the library (warnings by default) go to stderr: -v adds information (what was
read, written, resampled), -vv debugging detail; -q shows only its errors and no progress
bars (Python warnings, such as a scenario file's, are still shown).
These options come before the subcommand: psbmpc-jax -q run head_on.
"""

#: The options of the top-level parser that may precede the subcommand.
GLOBAL_FLAGS = ("-q", "--quiet", "-v", "--verbose", "-vv", "-vvv")
#: Marks the handler :func:`configure_logging` installs (replaced, not stacked, on a second call).
_HANDLER_NAME = "psbmpc-jax-cli"


def configure_logging(verbosity: int) -> None:
    """Route the library's log messages (logger ``psbmpc_jax``) to stderr: ``verbosity`` -1 (``-q``) errors
    only, 0 warnings, 1 (``-v``) information, 2 (``-vv``) debugging detail."""
    level = {-1: logging.ERROR, 0: logging.WARNING, 1: logging.INFO}.get(verbosity, logging.DEBUG)
    logger = logging.getLogger("psbmpc_jax")
    for h in [h for h in logger.handlers if h.get_name() == _HANDLER_NAME]:
        logger.removeHandler(h)
    handler = logging.StreamHandler(sys.stderr)
    handler.set_name(_HANDLER_NAME)
    handler.setFormatter(logging.Formatter("psbmpc-jax %(levelname)s %(name)s: %(message)s" if verbosity >= 2
                                           else "psbmpc-jax: %(levelname)s: %(message)s"))
    logger.addHandler(handler)
    logger.setLevel(level)


# ------------------------------------------------------------------------------------------ output checks
def _probe_dir(folder: pathlib.Path) -> str | None:
    """None if a file can be created in ``folder``, else why not."""
    try:
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as exc:
        return exc.strerror or str(exc)
    return None


def _nearest_existing(p: pathlib.Path) -> pathlib.Path:
    p = p.absolute()
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def _dir_problem(p: pathlib.Path) -> str | None:
    if p.exists() and not p.is_dir():
        return f"{p} exists and is not a folder"
    base = _nearest_existing(p)
    if not base.is_dir():
        return f"cannot create the folder, {base} is a file"
    why = _probe_dir(base)
    return f"cannot write in {base} ({why})" if why else None


def output_dir_problem(path, option: str) -> str | None:
    """Why the folder ``path`` (created if missing) cannot be written, as a message naming ``option``; None
    if it can.  Nothing is created."""
    why = _dir_problem(pathlib.Path(path).expanduser())
    return f"{option} {path}: {why}" if why else None


def output_file_problem(path, option: str) -> str | None:
    """Why the file ``path`` cannot be appended to (its folder created if missing); None if it can."""
    p = pathlib.Path(path).expanduser()
    if p.is_dir():
        return f"{option} {path}: is a folder; give a file name"
    if p.exists():
        try:
            with open(p, "a", encoding="utf-8"):
                pass
        except OSError as exc:
            return f"{option} {path}: cannot append to it ({exc.strerror or exc})"
        return None
    why = _dir_problem(p.parent)
    return f"{option} {path}: {why}" if why else None


# ------------------------------------------------------------------------------------------------ parser
class CliParser(argparse.ArgumentParser):
    """The top-level parser; ``subcommands`` holds each subcommand's parser by name (its ``error()`` prints the
    subcommand's usage)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.subcommands: dict[str, argparse.ArgumentParser] = {}


def build_parser() -> CliParser:
    from .. import __version__

    parser = CliParser(prog="psbmpc-jax", description=DESCRIPTION,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"psbmpc-jax {__version__}")
    parser.add_argument("-v", "--verbose", action="count", default=0, dest="verbosity",
                        help="more messages on stderr: -v information, -vv debugging detail")
    parser.add_argument("-q", "--quiet", action="store_true", dest="log_quiet",
                        help="only the library's errors on stderr, and no progress bars")
    sub = parser.add_subparsers(dest="command", metavar="SUBCOMMAND")
    ex = sub.add_parser("example", help="solve the built-in paper-scale head-on situation (the default)",
                        description="Solve the built-in paper-scale head-on situation and print the chosen "
                                    "maneuver, the best behaviours' costs and the solve time (compile time and "
                                    "steady state separately).")
    add_example_arguments(ex)
    parser.subcommands["example"] = ex
    run = sub.add_parser("run", help="closed-loop Monte Carlo simulation of scenario files, with metrics and plots",
                         description="Simulate scenarios (built-in names, glob patterns over them such as "
                                     "'imazu_*', or paths to YAML files; see docs/scenarios.md) and write "
                                     "metrics.json, summary.md and figures per scenario, and an index.md over "
                                     "all of them. Exit status 1 when any run had a collision or grounding.")
    add_run_arguments(run)
    parser.subcommands["run"] = run
    from .bench import add_bench_arguments

    bench = sub.add_parser("bench", help="runtime benchmark sweeps (paper Figs. 5-10), JSON Lines records",
                           description="Runtime benchmark sweeps; records follow docs/bench_schema.md.")
    add_bench_arguments(bench)
    parser.subcommands["bench"] = bench
    from .report import add_report_arguments

    report = sub.add_parser("report", help="merge benchmark JSON Lines into a Markdown report with figures",
                            description="Merge psbmpc-bench/1 result files (from any machines) into report.md "
                                        "and PNG box plots.")
    add_report_arguments(report)
    parser.subcommands["report"] = report
    from ..evaltool.cli import add_evaluate_arguments

    ev = sub.add_parser("evaluate", help="COLREGS safety/compliance scores of saved trajectories (EvalTool)",
                        description="Score recorded trajectories with the COLREGS evaluation of Hagen et al. 2023 "
                                    "(reconstructed; docs/evaltool.md): the simulator's trajectories.npz / .csv "
                                    "or output folder, a user CSV (columns t_s, vessel, north_m, east_m[, "
                                    "course_deg, speed_mps]) or an AIS-style CSV (columns timestamp, MMSI, lat, "
                                    "lon[, SOG, COG]; irregular reports, resampled onto a common clock). Exit "
                                    "status 2 for a file that cannot be read.")
    add_evaluate_arguments(ev)
    parser.subcommands["evaluate"] = ev
    from .generate import add_generate_arguments

    gen = sub.add_parser("generate", help="COLREGS-typed encounters (head-on, crossing, overtaking) as scenario files",
                         description="Draw encounters of the requested types from documented ranges of bearing, "
                                     "course, speed, CPA and time to CPA (docs/encounter_generation.md), in open "
                                     "water or on a chart, and write them as scenario files. Exit status 2 for bad "
                                     "input, 1 if --check finds a file not classified as requested.")
    add_generate_arguments(gen)
    parser.subcommands["generate"] = gen
    from .campaign import add_campaign_arguments, add_merge_arguments

    camp = sub.add_parser("campaign", help="scenarios x methods x seeds x runs as resumable tasks",
                          description="Run a campaign (docs/campaigns.md).")
    add_campaign_arguments(camp)
    parser.subcommands["campaign"] = camp
    merge = sub.add_parser("merge", help="combine campaign folders into one runs.parquet",
                           description="Merge complete campaign folders (docs/campaigns.md).")
    add_merge_arguments(merge)
    parser.subcommands["merge"] = merge
    return parser


def add_example_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--estimator", choices=("quadrature", "mc", "ce"), default="quadrature",
                   help="collision-probability estimator (default: quadrature)")
    p.add_argument("--dtype", choices=("float32", "float64"), default="float32")
    p.add_argument("--n-m", type=int, choices=(1, 2), default=2,
                   help="maneuvers per behaviour with the paper sets: 2 -> 1014 behaviours, 1 -> 39")
    p.add_argument("--n-ps", type=odd_int, default=5, help="prediction scenarios per obstacle (odd)")
    p.add_argument("--obstacles", type=nonneg_int, default=2, help="number of head-on obstacles (>= 0)")
    p.add_argument("--repeats", type=positive_int, default=20, help="steady-state solves to time")
    p.add_argument("--top", type=positive_int, default=5, help="best behaviours to print")
    p.add_argument("--seed", type=seed_int, default=0, help="PRNG seed for the mc/ce sample table")


def _plot_runs(text: str):
    from ..sim.plots import parse_runs

    try:
        return parse_runs(text)      # None = all (resolved once the number of runs is known)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_run_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scenarios", nargs="*", help="built-in scenario names or patterns (see --list), or YAML paths")
    p.add_argument("--list", action="store_true",
                   help="list the built-in scenarios (name, description, file) and exit")
    p.add_argument("--method", type=method_arg, default=None,
                   help="the own-ship's controller, overriding the file's mpc.method: one of "
                        f"{', '.join(names())} (docs/methods/), or your own as an import path package.module:Name "
                        "(docs/controllers.md). The results go to OUT/SCENARIO_METHOD, so methods can be "
                        "compared side by side")
    p.add_argument("--runs", type=runs_int, default=None, help="Monte Carlo runs (default: the file's)")
    p.add_argument("--seed", type=seed_int, default=None,
                   help="base seed >= 0 (default: the file's); also seeds the mc/ce sample table")
    p.add_argument("--out", default="results", help="output folder; one sub-folder per scenario (default: results)")
    p.add_argument("--batch", choices=("auto", "vmap", "loop"), default="auto",
                   help="device calls per MPC update: one vmapped call for all runs and ships, or one per solve "
                        "(auto: vmap on an accelerator, loop on the CPU; vmap with --devices > 1)")
    p.add_argument("--devices", type=devices_arg, default=1, metavar="N|all",
                   help="split the vmapped call of each MPC update (every run and ship) over N local devices, or "
                        "all of them (default 1); same results as one device; grid-search methods only")
    p.add_argument("--plot-runs", type=_plot_runs, default=False, metavar="RUNS",
                   help="runs to draw map, distance and course/speed figures of: 'all' or indices such as 0,3,5 "
                        "(files named map_run3.png, ...); default: run 0 (map.png, ...)")
    p.add_argument("--animate", action="store_true",
                   help="also write an animation of each drawn run (GIF; MP4 too when ffmpeg is installed)")
    p.add_argument("--save-trajectories", action="store_true",
                   help="write every run's trajectories, chosen offsets and cost terms to trajectories.csv and "
                        "trajectories.npz (read them with psbmpc_jax.sim.load_trajectories)")
    p.add_argument("--no-figures", action="store_true", help="no PNG figures (metrics, and what is asked for)")
    p.add_argument("--force", action="store_true",
                   help="replace the results of an earlier run in a scenario's folder (only the files listed in "
                        "its manifest.json are removed; other files are left alone); without it such a folder "
                        "is refused before anything is simulated")
    p.add_argument("--quiet", action="store_true", help="no progress bar, and only the library's errors on stderr (as psbmpc-jax -q)")


# ------------------------------------------------------------------------------------------------ example
def run_example(args) -> int:
    import jax
    import numpy as np

    if args.dtype == "float64":
        jax.config.update("jax_enable_x64", True)
    enable_compilation_cache()
    from .. import Planner, PlannerConfig, paper_behaviours
    from ..examples import paper_head_on

    situation = paper_head_on(n_ps=args.n_ps, n_obstacles=args.obstacles)
    planner = Planner(PlannerConfig(estimator=args.estimator, dtype=args.dtype),
                      behaviours=paper_behaviours(args.n_m))
    key = jax.random.key(args.seed)
    t0 = time.perf_counter()
    result, state = planner.plan(situation, key=key)
    first = time.perf_counter() - t0
    times = []
    for _ in range(args.repeats):
        result, _ = planner.plan(situation, key=key)
        times.append(result.solve_time_s)

    n_b = len(planner.behaviours)
    n_ps_total = sum(ob.n_ps for ob in situation.obstacles)
    seed = f" (seed {args.seed})" if args.estimator != "quadrature" else ""
    print(f"psbmpc-jax example: n_cbs={n_b}, obstacles={len(situation.obstacles)} x n_ps={args.n_ps} "
          f"(n_ct={n_b * n_ps_total}), T={planner.config.T:g} s, dt={planner.config.dt:g} s, "
          f"estimator={args.estimator}{seed}, dtype={args.dtype}, device={jax.devices()[0].device_kind}")
    print(f"chosen behaviour #{result.best_index}: " + ", ".join(
        f"M{m + 1}: u={u:g}, chi={np.rad2deg(c):+g} deg" for m, (u, c) in enumerate(result.offsets)))
    print(f"apply now: U_c = {result.u_opt:g} * U_d, chi_c = chi_d {np.rad2deg(result.chi_opt):+g} deg")
    print(f"\nbest {args.top} behaviours (costs):")
    names = planner.cost_names                     # columns derived from the planner's cost terms
    print(f"{'rank':>4} {'index':>5}  {'maneuvers (u, chi deg)':<30} " + " ".join(f"{n:>9}" for n in names))
    for rank, row in enumerate(result.ranking(args.top), 1):
        man = " ".join(f"({u:g},{c:+.0f})" for u, c in row["maneuvers"])
        print(f"{rank:>4} {row['index']:>5}  {man:<30} " + " ".join(f"{row[n]:9.4f}" for n in names))
    q = statistics.quantiles(times, n=4) if len(times) > 1 else [times[0]] * 3
    print(f"\nsolve time: first call {first * 1e3:.0f} ms (includes compile), steady state over "
          f"{len(times)} solves: median {statistics.median(times) * 1e3:.1f} ms, min {min(times) * 1e3:.1f} ms, "
          f"quartiles {q[0] * 1e3:.1f}-{q[2] * 1e3:.1f} ms")
    return 0


# ---------------------------------------------------------------------------------------------------- run
def scenario_listing() -> list[tuple[str, str, str]]:
    """(name, one-line description, file path) of every built-in scenario."""
    import yaml

    from ..scenario import SCENARIO_DIR, builtin_scenarios

    rows = []
    for name in builtin_scenarios():
        path = next((SCENARIO_DIR / f"{name}{ext}" for ext in (".yaml", ".yml")
                     if (SCENARIO_DIR / f"{name}{ext}").is_file()), SCENARIO_DIR / f"{name}.yaml")
        try:
            desc = (yaml.safe_load(path.read_text(encoding="utf-8")) or {}).get("description", "")
        except (OSError, yaml.YAMLError, AttributeError):
            desc = ""
        rows.append((name, _one_line(str(desc or "")), str(path)))
    return rows


def _one_line(desc: str, width: int = 72) -> str:
    """The lead-in of a description (up to the first ':', ';' or '. ' outside parentheses), at most ``width``
    characters."""
    desc = " ".join(desc.split())
    depth = 0
    for i, ch in enumerate(desc):
        depth += (ch == "(") - (ch == ")")
        if depth == 0 and i >= 10 and ch in ":;." and (i + 1 == len(desc) or desc[i + 1] == " "):
            desc = desc[:i]
            break
    if len(desc) > width:
        desc = desc[: width - 3].rsplit(" ", 1)[0].rstrip(",;:") + "..."
    return desc


def _did_you_mean(word: str, candidates) -> str:
    close = difflib.get_close_matches(word, list(candidates), n=3, cutoff=0.6)
    return f"; did you mean {' or '.join(repr(c) for c in close)}?" if close else ""


def _missing_file_hint(item: str, names) -> str:
    """A suggestion for a scenario path that does not exist: a built-in of that name, or a similar file."""
    p = pathlib.Path(item).expanduser()
    if p.stem in names:
        return f"; the built-in scenario {p.stem!r} is given by its name alone: psbmpc-jax run {p.stem}"
    if p.parent.is_dir():
        files = [f.name for f in p.parent.iterdir() if f.suffix in (".yaml", ".yml")]
        close = difflib.get_close_matches(p.name, files, n=3, cutoff=0.6)
        if close:
            return f"; did you mean {' or '.join(repr(str(p.parent / c)) for c in close)}?"
    return _did_you_mean(p.stem, names)


def output_folder(name: str, method: str | None) -> str:
    """The scenario's folder under ``--out``: its name, with ``_<method>`` appended when ``--method`` is given (an
    import path's ``.`` and ``:`` as ``_``)."""
    return name if method is None else f"{name}_{method.replace(':', '_').replace('.', '_')}"


def _verdict(s: dict) -> str:
    bad = [(s["collisions"], "own-ship collision"), (s["groundings"], "own-ship grounding"),
           (s["pair_collision_runs"], "collision between other ships"),
           (s["any_ship_groundings"], "grounding of any ship")]
    failed = [f"{n} run{'s' if n != 1 else ''} with {what}" for n, what in bad if n]
    return "FAILED: " + ", ".join(failed) if failed else "no collisions or groundings"


def _stops_text(s: dict) -> str:
    """The own-ship's stops and arrival over the runs, for the line per scenario."""
    own = (s.get("ships") or [None])[0]
    if own is None:
        return f"arrived in {s.get('arrived_runs', 0)} of {s['runs']} runs"
    ls = own["longest_stop"]
    stops = "no stops" if ls is None else (f"{own['stops_total']} stop{'s' if own['stops_total'] != 1 else ''} "
                                           f"(longest {ls['s']:.0f} s)")
    arrived = "" if own["arrived_runs"] is None else f", arrived in {own['arrived_runs']} of {own['runs']} runs"
    return stops + arrived


def run_scenarios(args, parser) -> int:
    import fnmatch

    from ..scenario import builtin_scenarios, load_scenario

    names = builtin_scenarios()
    if args.list:
        rows = scenario_listing()
        width = max((len(n) for n, _, _ in rows), default=4)
        dwidth = max((len(d) for _, d, _ in rows), default=0)
        for n, d, path in rows:
            print(f"{n:<{width}}  {d:<{dwidth}}  {path}")
        return 0
    if not args.scenarios:
        parser.error("give at least one scenario (built-in name, pattern or YAML path); --list shows the names")
    selected = []
    for item in args.scenarios:
        if item.endswith((".yaml", ".yml")) or "/" in item or os.sep in item:
            selected.append(item)
            continue
        hits = fnmatch.filter(names, item)
        if not hits:
            parser.error(f"no built-in scenario matches {item!r}{_did_you_mean(item, names)} "
                         f"(psbmpc-jax run --list shows them with their descriptions)")
        selected += hits
    scenarios = []
    for item in selected:   # every file is checked before the first simulation starts
        try:
            scenarios.append(load_scenario(item, method=args.method, runs=args.runs, runs_setting="--runs"))
        except FileNotFoundError as exc:
            parser.error(f"{exc}{_missing_file_hint(item, names)}")
        except (ValueError, OSError) as exc:
            parser.error(str(exc))
    plot_runs: dict[str, list[int] | None] = {}
    for sc in scenarios:   # --plot-runs against each scenario's number of runs
        n_runs = args.runs or sc.runs
        if args.plot_runs is False:
            plot_runs[sc.name] = None
        elif args.plot_runs is None:
            plot_runs[sc.name] = list(range(n_runs))
        else:
            too_big = [r for r in args.plot_runs if r >= n_runs]
            if too_big:
                parser.error(f"argument --plot-runs: run {too_big[0]} does not exist: scenario {sc.name!r} has "
                             f"{n_runs} run{'s' if n_runs != 1 else ''} (0..{n_runs - 1})")
            plot_runs[sc.name] = list(args.plot_runs)
    problem = output_dir_problem(args.out, "--out")
    if problem:
        parser.error(problem)
    from ..runfolder import run_folder_problem

    folders: dict[pathlib.Path, str] = {}
    for sc in scenarios:
        folder = pathlib.Path(args.out) / output_folder(sc.name, args.method)
        if folder in folders:
            parser.error(f"scenarios {folders[folder]!r} and {sc.name!r} would both write {folder}; give each "
                         f"scenario once (or give the files different names)")
        folders[folder] = sc.name
    for folder in folders:   # the overwrite rule, for every scenario before the first simulation
        problem = run_folder_problem(folder, force=args.force, option="--out")
        if problem:
            parser.error(problem)

    import jax

    from ..sim.simulator import check_devices_split

    for sc in scenarios:    # --devices against this machine and each scenario's methods, before the first run
        try:
            check_devices_split(sc, args.devices, args.batch)
        except ValueError as exc:
            parser.error(f"argument --devices: {exc}")
    enable_compilation_cache()
    from ..sim import simulate
    from ..sim.output import write_index, write_outputs

    failures, total_runs, t_all = [], 0, time.perf_counter()
    for scenario in scenarios:
        t0 = time.perf_counter()
        seed = scenario.seed if args.seed is None else args.seed
        # mc / ce draw their sample table from a key: seeded like the measurement noise
        key = jax.random.key(seed) if scenario.mpc.config.estimator != "quadrature" else None
        if not args.quiet:      # the estimate before the run (simulate refuses it above the limit)
            from ..simulation_time import describe

            print(f"psbmpc-jax run: {scenario.name}: {describe(scenario, args.runs)}", file=sys.stderr, flush=True)
        result = simulate(scenario, runs=args.runs, seed=args.seed, batch=args.batch, progress=not args.quiet,
                          key=key, devices=args.devices)
        out = pathlib.Path(args.out) / output_folder(scenario.name, args.method)
        try:
            write_outputs(result, out, figures=not args.no_figures, plot_runs=plot_runs[scenario.name],
                          animate=args.animate, trajectories=args.save_trajectories, force=args.force)
        except OSError as exc:      # OutputError included: the folder changed while simulating, a full disk
            print(f"psbmpc-jax run: {scenario.name}: the results could not be written: {exc}", file=sys.stderr)
            return 2
        s = result.summary
        total_runs += s["runs"]
        verdict = _verdict(s)
        if verdict.startswith("FAILED"):
            failures.append(f"{scenario.name} ({verdict[len('FAILED: '):]})")
        closest = ", ".join(f"{tg['name']} {tg['min_distance_m']['min']:.1f} m" for tg in s["targets"]
                            if tg["min_distance_m"]["min"] is not None)
        land = s["min_distance_land_m"]["min"]
        print(f"{scenario.name}: {s['runs']} runs in {time.perf_counter() - t0:.0f} s (method "
              f"{s['method'] or 'none'}): {verdict}; "
              f"closest approach {closest or 'n/a'}" + (f", to land {land:.1f} m" if land is not None else "")
              + f"; own-ship {_stops_text(s)}; {s['mpc_solves_total']} MPC solves; results in {out}{os.sep}")
    try:
        index = write_index(args.out)
    except OSError as exc:
        print(f"psbmpc-jax run: index.md could not be written: {exc}", file=sys.stderr)
        return 2
    n_sc = len(scenarios)
    head = (f"psbmpc-jax run: {n_sc} scenario{'s' if n_sc != 1 else ''}, {total_runs} run"
            f"{'s' if total_runs != 1 else ''} in {time.perf_counter() - t_all:.0f} s")
    if failures:
        print(f"{head}: {len(failures)} with failures: {'; '.join(failures)}. Index: {index}")
    else:
        print(f"{head}: all passed (no collisions or groundings). Index: {index}")
    return 1 if failures else 0


# ---------------------------------------------------------------------------------------------------- main
def _with_default_subcommand(argv: list[str]) -> list[str]:
    """``psbmpc-jax`` and ``psbmpc-jax --n-m 1`` are ``psbmpc-jax example ...``."""
    lead = 0
    while lead < len(argv) and argv[lead] in GLOBAL_FLAGS:     # psbmpc-jax -q run ...: the global flags first
        lead += 1
    head, rest = argv[:lead], argv[lead:]
    if not rest:
        return [*head, "example"]
    if rest[0].startswith("-") and rest[0] not in ("-h", "--help", "--version"):
        return [*head, "example", *rest]
    return argv


def _main(argv) -> int:
    parser = build_parser()
    args = parser.parse_args(_with_default_subcommand(list(sys.argv[1:] if argv is None else argv)))
    quiet = args.log_quiet or getattr(args, "quiet", False)
    if quiet and hasattr(args, "quiet"):
        args.quiet = True                 # -q before the subcommand: also its progress output off
    configure_logging(-1 if quiet else args.verbosity)
    if args.command == "example":
        return run_example(args)
    if args.command == "bench":
        from .bench import build_plan, run_bench
        from .bench_timing import default_out, select_devices

        try:   # flag combinations argparse cannot check: a usage error naming the flag
            build_plan(args)
            select_devices(args.devices)
        except ValueError as exc:
            parser.subcommands["bench"].error(str(exc))
        args.out = args.out or default_out()
        problem = output_file_problem(args.out, "--out")
        if problem:
            parser.subcommands["bench"].error(problem)
        return run_bench(args)
    if args.command == "run":
        return run_scenarios(args, parser.subcommands["run"])
    if args.command == "evaluate":
        from ..evaltool.cli import run_evaluate

        return run_evaluate(args, parser.subcommands["evaluate"])
    if args.command == "generate":
        from .generate import USER_ERRORS, run

        try:
            return run(args)
        except USER_ERRORS as exc:
            print(f"psbmpc-jax generate: error: {exc}", file=sys.stderr)
            return 2
    if args.command in ("campaign", "merge"):
        from . import campaign

        return (campaign.run_campaign_cli(args, parser.subcommands["campaign"]) if args.command == "campaign"
                else campaign.run_merge_cli(args, parser.subcommands["merge"]))
    if args.command == "report":
        from .report import run_report

        if args.results:
            problem = output_dir_problem(args.out, "--out")
            if problem:
                parser.subcommands["report"].error(problem)
        return run_report(args)
    raise SystemExit(f"psbmpc-jax: unknown command {args.command!r}")  # argparse already guards this


def main(argv=None) -> int:
    """Entry point of the ``psbmpc-jax`` console script; returns the exit status.  The logging set up for the
    command (:func:`configure_logging`) is undone when it returns, so a program calling ``main`` keeps its own."""
    logger = logging.getLogger("psbmpc_jax")
    level = logger.level
    try:
        return _main_guarded(argv)
    finally:
        for h in [h for h in logger.handlers if h.get_name() == _HANDLER_NAME]:
            logger.removeHandler(h)
        logger.setLevel(level)


def _main_guarded(argv) -> int:
    try:
        rc = _main(argv)
        sys.stdout.flush()
        return rc
    except BrokenPipeError:
        # stdout went to a command that stopped reading (psbmpc-jax run --list | head -1): no traceback, and
        # no second error when Python flushes stdout at exit
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        except (OSError, ValueError):
            pass
        return 1
    except KeyboardInterrupt:
        print("psbmpc-jax: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
