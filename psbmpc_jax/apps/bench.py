"""Runtime benchmark sweeps (paper Sec. IV-B/C, Figs. 5, 6, 7, 9, 10): ``psbmpc-jax bench``.

Every point is written as one JSON Lines record in the ``psbmpc-bench/1`` format of ``docs/bench_schema.md``
(appended and flushed as soon as it is measured: the JAX points of a sweep after their interleaved rounds,
see Schedule below; so an interrupted sweep keeps what it measured).

Situations (all on the Trondheim chart, :func:`psbmpc_jax.examples.nidelva_head_on`):

* dynamic sweeps (``n_cbs``, ``n_ps``, ``n_do``): the Nidelva head-on — own-ship at 2 m/s, ``n_do`` 5 m
  vessels coming head-on at 2 m/s (the paper's two at 45 % and 80 % of the open-water run, extra ones at
  25 %, 35 %, ... of it, alternating 3 m either side of the track), ``n_ps`` scenarios per obstacle, and the
  13 Table 2 polygons after RDP at 2 m (``n_so = 13``); defaults ``n_do = 2``, ``n_ps = 5``.
* static sweeps (``n_so``, ``n_vertices``): the own-ship standing still at the same spot (U = U_d = 0), no
  obstacles; ``n_so``: the first n Table 2 polygons after RDP; ``n_vertices``: the largest polygon alone,
  the swept values being RDP thresholds eps [m] with 0 = the raw polygon (21 961 vertices; 1 734 at 2 m).

Behaviour sets per ``n_cbs`` (course offsets "k evenly spaced" = ``numpy.linspace(-60, 60, k)`` deg, k = 1 -> {0}):

* 39 / 1014: the paper's Table 1 sets (n_M = 1: speeds {1, 0.5, 0} x 13 courses; n_M = 2: that x {1, 0.5}
  x 13 courses);
* other multiples of 3 up to 117: n_M = 1, speeds {1, 0.5, 0} x k = n_cbs / 3 evenly spaced courses;
* other multiples of 78: n_M = 2, the paper's first maneuver (3 x 13) x speeds {1, 0.5} x k = n_cbs / 78
  evenly spaced courses;
* other sweeps use the paper set of ``--n-m`` (default 2: 1014 behaviours).

Presets (``--preset paper --reference-budget 1500 --repeats 60`` measured 863 s on this project's 2-core
CPU, 92 records, no reference point skipped; with the default budget of 120 s the later reference
points are written as skipped):

* ``fig5``: n_cbs in 9, 39, 156, 390, 1014, 2028 (n_ps = 1)
* ``fig6``: n_ps in 1, 11, 21, 41, 61, 81, 101 at n_cbs = 39 (the paper's Fig. 6 range)
* ``fig7``: n_ps in 1, 5, 11, 21, 31, 41 at n_cbs = 1014 (wide enough that the n_ps-dependent work
  shows above the fixed grounding cost of the 13 polygons)
* ``fig9``: the largest polygon raw and after RDP at 2 m (n_vertices 21 961 and 1 734), 1014 behaviours
* ``fig10``: n_so in 1..13, 1014 behaviours
* ``fig6s``, ``fig7s``: the n_ps sweeps of fig6/fig7 (fig7s up to 31) at a fixed scenario fan: r_ct =
  40 m / (n_ps - 1), so every scenario stays within the +-20 m band of the paper's n_ps = 5 fan and more
  scenarios sample the same band more finely; with the fixed r_ct of fig6/fig7 the added outer scenarios
  (up to +-500 m) never come near the own-ship, the sigma-shortcut drops them, and the work saturates
* ``paper``: all of the above; ``smoke``: T = 10 s, n_cbs in 9, 39 (a few seconds, for tests)
* ``refine``: not a sweep — the PSB-MPC + refinement benchmark (:func:`refine_benchmark`, docs/refine.md):
  the refinement of the Nidelva situation (Nidelva preset, grid grounding) at the cases of
  :data:`REFINE_CASES` (1, 4 and 16 starts, ``map`` and ``vmap``; T 150 s with a 60 s refine horizon, T 60 s,
  and the Smooth-SBMPC paper's 60 s / 20 s at dt 1 s), with the grid search, one ``value_and_grad`` of the
  smooth objective and one library solve as separate slots.  Its records have their own schema
  (``psbmpc-bench-refine/1``, one JSON line per slot, fields :data:`REFINE_FIELDS`); ``psbmpc-jax report``
  does not read them.  ``benchmarks/bench_refine.py`` runs the same and writes one JSON document.

Depth (``--depth``): instead of timing, every point's solve step is run once through
:func:`psbmpc_jax.depth.sequential_depth_only` and its loop iterations are counted (the GPU latency floor); one
``psbmpc-depth/1`` record per point (docs/bench_schema.md), in a file of its own (``psbmpc-jax report`` does not
read them).  ``--layout-platform gpu`` counts the GPU's layouts on any machine.

Per point and platform: compile time (``lower().compile()``), ``--warmup`` untimed calls, ``--repeats`` timed
calls with ``block_until_ready``, statistics, peak memory (device ``memory_stats()["peak_bytes_in_use"]``,
a process-lifetime peak, where the device reports it; else the growth of the process peak RSS during the
point), the memory XLA planned for one call of the compiled solve (``compiled_memory_bytes``: arguments +
outputs + temporaries, a per-point figure that, unlike the peaks, does not depend on what ran before), the
chosen behaviour. Reference points (``impl = "reference"``: the float64 sequential NumPy
evaluator on the same situation and sample table) run ``--reference-repeats`` times (default 1) while the
total reference wall time stays within ``--reference-budget`` seconds: a point whose estimated time (from
the slowest rate seen so far, per behaviour x (scenarios + vertices/100 + 1)) exceeds what is left, or any
point once the budget is spent, is written with ``skipped: true`` and a ``skip_reason``; with a budget of 0
every reference point is written as skipped ("reference disabled"). One running reference point is never
interrupted, so the budget can be overshot by one point.

Schedule (``--schedule``, field ``schedule``): ``interleaved`` (default) compiles and warms up every point of
one sweep on one device first and then times them round-robin — repeat 1 of every point, repeat 2 of every
point, ... — so a slow spell of a shared machine lands on all points of the sweep alike instead of on the few
points measured during it; ``sequential`` times each point's repeats back to back.  On this project's shared
2-core VM the sequential fig7s medians moved by up to 1.8x between spells (370 ms for 25 repeats, then
206 ms, at one point), while the interleaved medians rose monotonically with n_ps (R² 0.99).  JAX records of
an interleaved sweep are written when its last round ends; an interrupt (Ctrl-C) during the rounds writes
every point timed so far with the repeats it got, then stops.
"""

from __future__ import annotations

import argparse
import itertools
import os
import sys
import time

from ..layouts import GROUNDING_SEARCHES
from .argtypes import nonneg_float, nonneg_int, odd_int, positive_float, positive_int
from .bench_depth import depth_out_problem, run_depth
from .bench_points import PAPER_FIGS, PRESETS, SWEEPS, Point, behaviours_for, make_points, parse_values, \
    point_config, situation_for
from .bench_refine import run_refine_bench
from .bench_timing import Runner, default_out, samples_for_reference, select_devices

ESTIMATORS = ("quadrature", "mc", "ce")
SCHEDULES = ("interleaved", "sequential")


# ------------------------------------------------------------------------------------------ arguments
def add_bench_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_mutually_exclusive_group()
    g.add_argument("--preset", choices=tuple(k for k in PRESETS if k != "smoke") + ("paper", "smoke", "refine"),
                   help="paper figure sweep (fig5/fig6/fig7/fig9/fig10), fig6s/fig7s (n_ps sweeps at a fixed "
                        "scenario fan width), all of these (paper), smoke, or refine (the PSB-MPC + refinement "
                        "benchmark at Nidelva scale; its own record schema, see docs/refine.md)")
    g.add_argument("--sweep", choices=SWEEPS, help="explicit sweep of one size (needs --values)")
    p.add_argument("--values", help="comma-separated values for --sweep, e.g. 1,3,5 (n_vertices: RDP eps [m], 0=raw)")
    p.add_argument("--estimator", choices=ESTIMATORS, default="quadrature")
    p.add_argument("--dtype", choices=("float32", "float64"), default="float32")
    p.add_argument("--grounding", choices=("exact", "grid"), default="exact", help="grounding mode")
    p.add_argument("--grounding-search", choices=GROUNDING_SEARCHES, default="auto",
                   help="exact mode's layout (PlannerConfig.grounding_search; default auto: bounded on the CPU, "
                        "flat on a GPU; records hold the one used)")
    p.add_argument("--n-m", type=int, choices=(1, 2), default=None,
                   help="paper behaviour set for sweeps other than n_cbs: 1 -> 39, 2 -> 1014 (default)")
    p.add_argument("--n-ps", type=odd_int, default=None, help="scenarios per obstacle when not swept (odd, "
                   "default 5; fig5 and smoke: 1)")
    p.add_argument("--n-do", type=nonneg_int, default=None, help="obstacles when not swept (default 2)")
    p.add_argument("--T", type=positive_float, default=None, help="horizon [s] (default 150; smoke: 10)")
    p.add_argument("--dt", type=positive_float, default=0.5, help="time step [s] (default 0.5)")
    p.add_argument("--repeats", type=positive_int, default=30, help="timed steady-state solves per point "
                   "(default 30)")
    p.add_argument("--schedule", choices=SCHEDULES, default="interleaved",
                   help="interleaved (default): time the points of a sweep round-robin, one repeat each per "
                        "round, so machine load drifts hit every point alike; sequential: each point's repeats "
                        "back to back")
    p.add_argument("--warmup", type=nonneg_int, default=2, help="untimed solves after compiling (default 2)")
    p.add_argument("--reference-budget", type=nonneg_float, default=120.0,
                   help="total wall seconds for reference points (default 120; 0 disables the reference)")
    p.add_argument("--reference-repeats", type=positive_int, default=1, help="reference solves per point")
    p.add_argument("--devices", choices=("all", "cpu", "gpu"), default="all",
                   help="JAX platforms to run on (default all: CPU and the GPU if present)")
    p.add_argument("--multi-device", action="store_true",
                   help="also run on all devices of a platform with evaluate_sharded when it has several")
    p.add_argument("--out", help="JSON Lines file to append to (default: bench_<host>_<timestamp>.jsonl in the "
                   "current folder)")
    p.add_argument("--seed", type=int, default=0, help="PRNG seed of the mc/ce sample table")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.add_argument("--depth", action="store_true",
                   help="instead of timing, count the loop iterations each point's solve executes (the GPU latency "
                        "floor, psbmpc_jax.depth): one psbmpc-depth/1 record per point, its table printed unless "
                        "--quiet; the --out file must not hold timing records")
    p.add_argument("--layout-platform", choices=("cpu", "gpu"), default=None,
                   help="choose the configuration's auto layouts as on this platform (default: the platform the "
                        "point runs on); with --depth, count a GPU program's loops on the CPU")


def build_plan(args) -> list[Point]:
    """Validated list of points for the parsed arguments (raises ValueError naming the flag)."""
    if args.preset is None and args.sweep is None:
        raise ValueError("psbmpc-jax bench: give --preset {fig5,fig6,fig7,fig9,fig10,paper,smoke} or --sweep "
                         "{n_cbs,n_ps,n_do,n_so,n_vertices} with --values")
    if args.preset is not None and args.values is not None:
        raise ValueError("--values only goes with --sweep, not with --preset")
    if getattr(args, "depth", False):
        if args.preset == "refine":
            raise ValueError("--depth does not apply to --preset refine (it counts the grid search's loops)")
        problem = depth_out_problem(getattr(args, "out", None), depth=True)
        if problem:
            raise ValueError(problem)
    elif args.preset != "refine":
        problem = depth_out_problem(getattr(args, "out", None), depth=False)
        if problem:
            raise ValueError(problem)
    if args.preset == "refine":
        for flag, value in (("--n-ps", args.n_ps), ("--n-do", args.n_do), ("--T", args.T), ("--n-m", args.n_m)):
            if value is not None:
                raise ValueError(f"{flag} does not apply to --preset refine (fixed cases: "
                                 f"psbmpc_jax.apps.bench_refine.REFINE_CASES)")
        if args.dt != 0.5:
            raise ValueError("--dt does not apply to --preset refine (fixed cases: "
                             "psbmpc_jax.apps.bench_refine.REFINE_CASES)")
        return []
    if args.sweep is not None and args.values is None:
        raise ValueError(f"--sweep {args.sweep} needs --values, e.g. --values 1,3,5")
    if args.sweep == "n_cbs" and args.n_m is not None:
        raise ValueError("--n-m cannot be combined with --sweep n_cbs (n_cbs fixes the behaviour sets)")
    if args.sweep == "n_ps" and args.n_ps is not None:
        raise ValueError("--n-ps cannot be combined with --sweep n_ps")
    if args.sweep == "n_do" and args.n_do is not None:
        raise ValueError("--n-do cannot be combined with --sweep n_do")
    overrides = {}
    if args.n_ps is not None:
        overrides["n_ps"] = args.n_ps
    if args.n_do is not None:
        overrides["n_do"] = args.n_do
    if args.T is not None:
        overrides["T"] = args.T
    if args.n_m is not None:
        overrides["n_cbs"] = 39 if args.n_m == 1 else 1014
    if args.preset is not None:
        names = PAPER_FIGS if args.preset == "paper" else (args.preset,)
        pts = []
        for name in names:
            swept, values, fixed = PRESETS[name]
            fixed = {**fixed, **{k: v for k, v in overrides.items() if k != swept}}
            pts += make_points(swept, values, fixed, name)
    else:
        pts = make_points(args.sweep, parse_values(args.values, args.sweep), overrides, "custom")
    for p in pts:
        n = p.T / args.dt
        if abs(n - round(n)) > 1e-9 * max(1.0, n):
            raise ValueError(f"--T / --dt must be a whole number of steps, got T={p.T}, dt={args.dt}")
    return pts


# -------------------------------------------------------------------------------------------- running
def run_bench(args) -> int:
    """Entry point of ``psbmpc-jax bench`` (``args`` from :func:`add_bench_arguments`)."""
    import jax

    if args.dtype == "float64":
        jax.config.update("jax_enable_x64", True)
    if args.preset == "refine":
        return run_refine_bench(args)
    points = build_plan(args)
    if getattr(args, "depth", False):
        return run_depth(args, points)
    platforms = select_devices(args.devices)
    # which device(s) the timings come from, always printed (also with --quiet): a GPU host without JAX's CUDA
    # build silently runs on the CPU otherwise
    print("psbmpc-jax bench: timing on " + "; ".join(
        f"{plat}: {devs[0].device_kind} x{len(devs)}" for plat, devs in platforms.items()), file=sys.stderr,
        flush=True)

    # no persistent compilation cache here and the in-memory one is cleared per point (prepare_jax):
    # compile_s is a real compile, not a cache load
    runs = []   # (platform, devices, multi)
    for plat, devs in platforms.items():
        runs.append((devs[:1], False))
        if args.multi_device and len(devs) > 1:
            runs.append((devs, True))
    total = len(points) * (len(runs) + 1)
    out = args.out or default_out()
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    done = 0
    t_start = time.perf_counter()

    def progress(p, what, rec):
        if args.quiet:
            return
        val = ("skipped" if rec["skipped"] else f"{rec['median_ms']:.1f} ms")
        print(f"[{done}/{total}] {p.label()} {what} {val}", file=sys.stderr, flush=True)

    def config_for(p, platform="cpu"):
        return point_config(args, p, getattr(args, "layout_platform", None) or platform)

    # interleaved: one timing group per (sweep, device run); sequential: one group per point
    sweeps = [list(g) for _, g in itertools.groupby(points, key=lambda p: p.sweep)]
    with open(out, "a", encoding="utf-8") as fh:
        runner = Runner(args, fh)
        for sweep_pts in sweeps:
            items = [(p, behaviours_for(p.n_cbs), situation_for(p)) for p in sweep_pts]
            for devs, multi in runs:
                groups = [items] if args.schedule == "interleaved" else [[it] for it in items]
                for group in groups:
                    slots = []
                    for p, beh, sit in group:
                        slots.append(runner.prepare_jax(p, sit, beh, config_for(p, devs[0].platform), devs, multi))
                        if not args.quiet and len(group) > 1:
                            print(f"[{done}/{total}] {p.label()} jax/{devs[0].platform} compiled in "
                                  f"{slots[-1]['rec']['compile_s']:.1f} s", file=sys.stderr, flush=True)
                    if not args.quiet and len(group) > 1:
                        print(f"[{done}/{total}] timing {len(group)} points round-robin, {args.repeats} rounds",
                              file=sys.stderr, flush=True)
                    recs, interrupted = runner.time_jax(slots)
                    for p, rec in recs:
                        runner.write(rec)
                        done += 1
                        progress(p, f"jax/{rec['platform']}" + (f" x{rec['n_devices']}" if multi else ""), rec)
                    if interrupted:
                        print(f"psbmpc-jax bench: interrupted; {done} records appended to {out}", file=sys.stderr)
                        raise KeyboardInterrupt
            for p, beh, sit in items:
                config = config_for(p)
                samples = samples_for_reference(config, args.seed) if args.reference_budget > 0 else None
                rec = runner.run_reference(p, sit, beh, config, samples)
                runner.write(rec)
                done += 1
                progress(p, "reference", rec)
    if not args.quiet:
        print(f"psbmpc-jax bench: {done} records appended to {out} in {time.perf_counter() - t_start:.0f} s",
              file=sys.stderr)
    return 0

__all__ = ["run_bench", "add_bench_arguments", "build_plan"]
