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
import datetime as dt
import itertools
import json
import os
import platform as _platform
import resource
import statistics
import sys
import time
from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np

from .argtypes import nonneg_float, nonneg_int, odd_int, positive_float, positive_int
from .provenance import commit, versions

SCHEMA = "psbmpc-bench/1"
SWEEPS = ("n_cbs", "n_ps", "n_do", "n_so", "n_vertices")
ESTIMATORS = ("quadrature", "mc", "ce")
FIELDS = ("schema", "sweep", "swept", "impl", "platform", "device_kind", "n_devices", "host", "estimator", "dtype",
          "grounding_mode", "grounding_search", "n_M", "n_cbs", "n_do", "n_ps", "n_so", "n_vertices", "n_ct", "T",
          "dt", "compile_s",
          "times_ms", "median_ms", "min_ms", "max_ms", "q1_ms", "q3_ms", "peak_memory_bytes", "memory_source",
          "compiled_memory_bytes", "r_ct", "best", "n_pc_blocks", "schedule", "skipped", "skip_reason", "versions", "commit", "timestamp")

#: (swept, values, fixed settings) per preset figure.
PRESETS = {
    "fig5": ("n_cbs", (9, 39, 156, 390, 1014, 2028), {"n_ps": 1}),
    "fig6": ("n_ps", (1, 11, 21, 41, 61, 81, 101), {"n_cbs": 39}),
    "fig7": ("n_ps", (1, 5, 11, 21, 31, 41), {"n_cbs": 1014}),
    "fig6s": ("n_ps", (1, 11, 21, 41, 61, 81, 101), {"n_cbs": 39, "spread": 40.0}),
    "fig7s": ("n_ps", (1, 5, 11, 21, 31), {"n_cbs": 1014, "spread": 40.0}),
    "fig9": ("n_vertices", (0.0, 2.0), {"n_cbs": 1014}),
    "fig10": ("n_so", tuple(range(1, 14)), {"n_cbs": 1014}),
    "smoke": ("n_cbs", (9, 39), {"n_ps": 1, "T": 10.0}),
}
PAPER_FIGS = ("fig5", "fig6", "fig7", "fig9", "fig10", "fig6s", "fig7s")
SCHEDULES = ("interleaved", "sequential")


# ----------------------------------------------------------------------------------------------- metadata
def stats_ms(times_s) -> dict:
    if not times_s:
        return {"times_ms": [], "median_ms": None, "min_ms": None, "max_ms": None, "q1_ms": None, "q3_ms": None}
    ms = [round(t * 1e3, 4) for t in times_s]
    q = statistics.quantiles(ms, n=4, method="inclusive") if len(ms) > 1 else [ms[0]] * 3
    return {"times_ms": ms, "median_ms": float(statistics.median(ms)), "min_ms": float(min(ms)),
            "max_ms": float(max(ms)), "q1_ms": float(q[0]), "q3_ms": float(q[2])}


def peak_rss_bytes() -> int:
    r = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return int(r) if sys.platform == "darwin" else int(r) * 1024


def compiled_memory_bytes(compiled):
    """Device memory XLA planned for one call of a compiled executable (per device for a sharded one):
    arguments + outputs + temporaries - aliased buffers; None where the backend does not report it.

    Unlike the device or process peak this belongs to the point alone and is the same on every run."""
    try:
        m = compiled.memory_analysis()
    except Exception:  # noqa: BLE001 - not every backend implements it
        return None
    if m is None:
        return None
    return int(m.argument_size_in_bytes + m.output_size_in_bytes + m.temp_size_in_bytes - m.alias_size_in_bytes)


def device_peak(device):
    try:
        ms = device.memory_stats()
    except Exception:  # noqa: BLE001 - not every backend implements it
        return None
    if ms and "peak_bytes_in_use" in ms:
        return int(ms["peak_bytes_in_use"])
    return None


# ---------------------------------------------------------------------------------------------- points
@dataclass(frozen=True)
class Point:
    sweep: str            # preset/figure name or "custom"
    swept: str
    value: float
    n_cbs: int = 1014
    n_ps: int = 5
    n_do: int = 2
    n_so: int = 13
    eps: float = 2.0      # RDP threshold [m], 0 = raw polygons
    still: bool = False   # own-ship standing still, no obstacles
    largest_only: bool = False
    T: float = 150.0
    spread: float = 0.0   # > 0: lateral span of the scenario fan [m], r_ct = spread / (n_ps - 1)

    @property
    def r_ct(self) -> float:
        """Scenario spacing of this point: the default 10 m (Table 1), or the fixed fan width over n_ps - 1."""
        from .params import Params

        return self.spread / (self.n_ps - 1) if self.spread > 0 and self.n_ps > 1 else Params().r_ct

    def label(self) -> str:
        v = self.value
        if self.swept == "n_vertices":
            return f"{self.sweep} n_vertices(rdp eps={v:g} m{', raw' if v == 0 else ''})"
        return f"{self.sweep} {self.swept}={int(v) if float(v).is_integer() else v}"


def behaviours_for(n_cbs: int) -> np.ndarray:
    """The behaviour table of ``n_cbs`` behaviours (rules in the module docstring)."""
    from .behaviours import PAPER_COURSES_DEG, PAPER_SPEEDS, enumerate_behaviours_deg, paper_behaviours

    if n_cbs == 39:
        return paper_behaviours(1)
    if n_cbs == 1014:
        return paper_behaviours(2)
    if n_cbs % 3 == 0 and 3 <= n_cbs <= 117:
        return enumerate_behaviours_deg([PAPER_SPEEDS[0]], [np.linspace(-60.0, 60.0, n_cbs // 3)])
    if n_cbs % 78 == 0 and n_cbs >= 78:
        return enumerate_behaviours_deg(PAPER_SPEEDS, [PAPER_COURSES_DEG, np.linspace(-60.0, 60.0, n_cbs // 78)])
    raise ValueError(f"--values: n_cbs={n_cbs} is not supported; allowed: 39, 1014, multiples of 3 up to 117 "
                     f"(n_M=1) or multiples of 78 (n_M=2)")


@lru_cache(maxsize=8)
def _nidelva(eps: float, n_ps: int, rdp: bool):
    from .examples import nidelva_head_on

    return nidelva_head_on(eps=eps, n_ps=n_ps, n_so=13, rdp=rdp)


def _situation(p: Point):
    from .examples import nidelva_polygons
    from .situation import Obstacle, OwnShip, Situation

    rdp = p.eps > 0
    eps = p.eps if rdp else 2.0
    if p.still:   # same spot and heading as the dynamic situations, standing still, no obstacles
        own = _nidelva(2.0, 1, True).own_ship
        own = OwnShip(state=[own.state[0], own.state[1], own.state[2], 0.0], waypoints=own.waypoints, U_d=0.0,
                      length=own.length, width=own.width)
        rings, _ = nidelva_polygons(eps, 13 if p.largest_only else p.n_so, rdp)
        polys = (rings[-1],) if p.largest_only else tuple(rings)
        return Situation(own, (), polys)
    base = _nidelva(eps, p.n_ps, rdp)
    own = base.own_ship
    obstacles = list(base.obstacles[:p.n_do])
    if p.n_do > 2:
        w = np.asarray(own.waypoints, float)
        pos, run_vec = w[0], w[-1] - w[0]
        run = float(np.hypot(*run_vec))
        u = run_vec / run
        for k in range(2, p.n_do):
            frac = 0.25 + 0.1 * ((k - 2) % 8)
            q = pos + frac * run * u + (-1.0) ** k * 3.0 * np.array([-u[1], u[0]])
            obstacles.append(Obstacle(state=[q[0], q[1], -2.0 * u[0], -2.0 * u[1]], cov=np.diag([4.0, 4.0, .05, .05]),
                                      length=5.0, width=3.0, n_ps=p.n_ps))
    return Situation(own, tuple(obstacles), tuple(base.polygons[:p.n_so]))


def n_vertices(situation) -> int:
    from .situation import polygon_rings

    return int(sum(sum(len(r) for r in polygon_rings(poly)) for poly in situation.polygons))


def make_points(swept: str, values, fixed: dict, sweep_name: str) -> list[Point]:
    base = Point(sweep=sweep_name, swept=swept, value=0, **fixed)
    pts = []
    for v in values:
        if swept == "n_cbs":
            pts.append(replace(base, value=v, n_cbs=int(v)))
        elif swept == "n_ps":
            pts.append(replace(base, value=v, n_ps=int(v)))
        elif swept == "n_do":
            pts.append(replace(base, value=v, n_do=int(v)))
        elif swept == "n_so":
            pts.append(replace(base, value=v, n_so=int(v), still=True))
        elif swept == "n_vertices":
            pts.append(replace(base, value=float(v), eps=float(v), still=True, largest_only=True, n_so=1))
    return pts


def parse_values(text: str, swept: str) -> list:
    items = [s.strip() for s in text.split(",")]
    if not text.strip() or all(not s for s in items):
        raise ValueError(f"--values must be a comma-separated list of numbers, got {text!r}")
    if any(not s for s in items):
        raise ValueError(f"--values: empty item in {text!r} (two commas in a row, or a leading or trailing "
                         f"comma); give e.g. --values 1,3,5")
    out = []
    for s in items:
        try:
            v = float(s)
        except ValueError:
            raise ValueError(f"--values: {s!r} is not a number (expected e.g. --values 1,3,5)") from None
        if swept == "n_vertices":
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"--values for n_vertices are RDP thresholds eps >= 0 [m] (0 = raw), got {s}")
            out.append(v)
            continue
        if not float(v).is_integer():
            raise ValueError(f"--values for {swept} must be integers, got {s}")
        v = int(v)
        lo = 0 if swept == "n_do" else 1
        if v < lo:
            raise ValueError(f"--values for {swept} must be >= {lo}, got {v}")
        if swept == "n_ps" and v % 2 == 0:
            raise ValueError(f"--values: n_ps must be odd, got {v}")
        if swept == "n_so" and v > 13:
            raise ValueError(f"--values: n_so must be in [1, 13] (Table 2 polygons), got {v}")
        if swept == "n_cbs":
            behaviours_for(v)  # raises with the allowed values
        out.append(v)
    return out


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
    p.add_argument("--grounding-search", choices=("auto", "culled", "dense", "flat"), default="auto",
                   help="exact mode's layout (PlannerConfig.grounding_search; default auto: culled on the CPU, "
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
                                 f"psbmpc_jax.bench.REFINE_CASES)")
        if args.dt != 0.5:
            raise ValueError("--dt does not apply to --preset refine (fixed cases: psbmpc_jax.bench.REFINE_CASES)")
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
        values = parse_values(args.values, args.sweep)
        pts = make_points(args.sweep, values, overrides, "custom")
    for p in pts:
        n = p.T / args.dt
        if abs(n - round(n)) > 1e-9 * max(1.0, n):
            raise ValueError(f"--T / --dt must be a whole number of steps, got T={p.T}, dt={args.dt}")
    return pts


def select_devices(which: str) -> dict:
    """{platform: [devices]} for --devices."""
    import jax

    out = {}
    for plat in ("cpu", "gpu"):
        if which not in ("all", plat):
            continue
        try:
            devs = jax.devices(plat)
        except RuntimeError:
            devs = []
        if devs:
            out[plat] = devs
    if not out:
        raise ValueError(f"--devices {which}: no JAX {which} device is available "
                         f"(present: {sorted({d.platform for d in jax.devices()})})")
    return out


def default_out() -> str:
    """``bench_<host>_<UTC timestamp>.jsonl`` in the current folder (the default of ``--out``)."""
    stamp = dt.datetime.now(dt.timezone.utc).strftime("%Y%m%dT%H%M%SZ")
    return os.path.join(os.getcwd(), f"bench_{_platform.node() or 'host'}_{stamp}.jsonl")


# -------------------------------------------------------------------------------------------- running
class Runner:
    def __init__(self, args, fh):
        self.args, self.fh = args, fh
        self.meta = {"host": _platform.node(), "versions": versions(), "commit": commit()}
        self.ref_used = 0.0
        self.ref_rate = None   # slowest seconds per cost unit seen

    def base_record(self, p: Point, situation, behaviours, impl: str) -> dict:
        n_cbs = len(behaviours)
        n_do = len(situation.obstacles)
        n_so = len(situation.polygons)
        n_ps = max([ob.n_ps for ob in situation.obstacles], default=0)   # 0: no obstacles
        rec = dict.fromkeys(FIELDS)
        rec.update(schema=SCHEMA, sweep=p.sweep, swept=p.swept, impl=impl, host=self.meta["host"],
                   estimator=self.args.estimator, dtype=self.args.dtype, grounding_mode=self.args.grounding,
                   grounding_search=None,
                   n_M=int(behaviours.shape[1]), n_cbs=n_cbs, n_do=n_do, n_ps=int(n_ps), n_so=n_so,
                   n_vertices=n_vertices(situation), n_ct=n_cbs * (n_so + n_do * int(n_ps)), T=float(p.T),
                   r_ct=float(p.r_ct),
                   dt=float(self.args.dt), skipped=False, versions=self.meta["versions"],
                   commit=self.meta["commit"], **stats_ms([]))
        return rec

    def write(self, rec: dict) -> None:
        rec["timestamp"] = dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds")
        assert set(rec) == set(FIELDS), set(rec) ^ set(FIELDS)
        self.fh.write(json.dumps(rec) + "\n")
        self.fh.flush()

    def prepare_jax(self, p, situation, behaviours, config, devices, multi: bool) -> dict:
        """Compile and warm up one point; returns its timing slot (the call, the record so far, no times)."""
        import jax

        from .params import Params
        from .planner import Planner
        from .solve import solve

        dev = devices[0]
        # a point whose padded shapes match an earlier point's (fig6s after fig6, polygon counts padded to
        # the same size in fig10) would load the in-memory executable instead of compiling: compile_s ~1 ms
        jax.clear_caches()
        rss0 = peak_rss_bytes()
        with jax.default_device(dev):
            planner = Planner(config, params=Params(r_ct=p.r_ct), behaviours=behaviours)
            inputs, state, params, samples = planner.prepare(situation, key=jax.random.key(self.args.seed))
        if multi:   # ahead-of-time too: the timed call neither re-places the inputs nor looks up a cache
            from .sharding import sharded_call

            fn, args, n_b = sharded_call(inputs, state, params, samples, config, devices=devices)
            t0 = time.perf_counter()
            compiled = fn.lower(*args, n_b=n_b).compile()
        else:
            args = jax.device_put((inputs, state, params, samples), dev)
            t0 = time.perf_counter()
            compiled = solve.lower(*args, config=config).compile()
        compile_s = time.perf_counter() - t0
        call = lambda: compiled(*args)[2]  # noqa: E731  (plan, next state, evaluation): one executable
        planned = compiled_memory_bytes(compiled)
        ev = None
        for _ in range(self.args.warmup):
            ev = jax.block_until_ready(call())
        rec = self.base_record(p, situation, behaviours, "jax")
        peak = device_peak(dev)
        if peak is not None:
            rec.update(peak_memory_bytes=peak, memory_source="device")
        else:
            rec.update(peak_memory_bytes=max(0, peak_rss_bytes() - rss0), memory_source="process_rss")
        rec.update(platform=dev.platform, device_kind=dev.device_kind, n_devices=len(devices) if multi else 1,
                   grounding_search=config.grounding_search, compile_s=round(compile_s, 4), schedule=self.args.schedule, compiled_memory_bytes=planned)
        return {"point": p, "call": call, "rec": rec, "ev": ev, "times": []}

    def time_jax(self, slots) -> tuple[list, bool]:
        """Time the prepared points, ``--repeats`` rounds of one call each (one slot: back to back).

        Returns ``(point, record)`` pairs and whether a KeyboardInterrupt cut the rounds short (then only the
        points with at least one timed repeat are returned, each with the repeats it got)."""
        import jax

        interrupted = False
        try:
            for _ in range(self.args.repeats):
                for slot in slots:
                    t0 = time.perf_counter()
                    slot["ev"] = jax.block_until_ready(slot["call"]())
                    slot["times"].append(time.perf_counter() - t0)
        except KeyboardInterrupt:
            interrupted = True
        out = []
        for slot in slots:
            if not slot["times"]:
                continue
            rec, ev = slot["rec"], slot["ev"]
            rec.update(best=int(ev.best), n_pc_blocks=int(ev.n_pc_blocks), **stats_ms(slot["times"]))
            out.append((slot["point"], rec))
        return out, interrupted

    def run_reference(self, p, situation, behaviours, config, samples) -> dict:
        from .params import Params
        from .reference import evaluate_reference

        rec = self.base_record(p, situation, behaviours, "reference")
        rec.update(platform="cpu", device_kind="cpu", n_devices=1, dtype="float64", memory_source="process_rss",
                   schedule="sequential")
        budget = self.args.reference_budget
        units = len(behaviours) * (rec["n_do"] * rec["n_ps"] + rec["n_vertices"] / 100.0 + 1.0) * config.n_steps
        left = budget - self.ref_used
        reason = None
        if budget <= 0:
            reason = "reference disabled (--reference-budget 0)"
        elif left <= 0:
            reason = f"reference time budget exhausted ({self.ref_used:.1f} s of {budget:g} s used)"
        elif self.ref_rate is not None and self.ref_rate * units * self.args.reference_repeats > left:
            reason = (f"reference time budget exhausted (estimated "
                      f"{self.ref_rate * units * self.args.reference_repeats:.1f} s > {left:.1f} s left of "
                      f"{budget:g} s)")
        if reason is not None:
            rec.update(skipped=True, skip_reason=reason)
            return rec
        rss0 = peak_rss_bytes()
        ref_samples = None if samples is None else np.asarray(samples, dtype=np.float64)
        cfg64 = config.replace(dtype="float64")
        times, res = [], None
        for _ in range(self.args.reference_repeats):
            t0 = time.perf_counter()
            res = evaluate_reference(situation, behaviours, Params(r_ct=p.r_ct), cfg64, samples=ref_samples)
            times.append(time.perf_counter() - t0)
        used = sum(times)
        self.ref_used += used
        rate = used / len(times) / units
        self.ref_rate = rate if self.ref_rate is None else max(self.ref_rate, rate)
        rec.update(best=int(res.best), peak_memory_bytes=max(0, peak_rss_bytes() - rss0), **stats_ms(times))
        return rec


def _samples_for_reference(config, seed):
    """The sample table the JAX points use (host float64 copy), None for quadrature."""
    import jax

    from .costs.collision import standard_normal_table

    s = standard_normal_table(jax.random.key(seed), config, np.dtype(config.dtype))
    return None if s is None else np.asarray(s, dtype=np.float64)


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
            items = [(p, behaviours_for(p.n_cbs), _situation(p)) for p in sweep_pts]
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
                samples = _samples_for_reference(config, args.seed) if args.reference_budget > 0 else None
                rec = runner.run_reference(p, sit, beh, config, samples)
                runner.write(rec)
                done += 1
                progress(p, "reference", rec)
    if not args.quiet:
        print(f"psbmpc-jax bench: {done} records appended to {out} in {time.perf_counter() - t_start:.0f} s",
              file=sys.stderr)
    return 0


# ------------------------------------------------------------------------------------------------ depth
DEPTH_SCHEMA = "psbmpc-depth/1"
DEPTH_FIELDS = ("schema", "sweep", "swept", "value", "n_cbs", "n_ps", "n_do", "n_so", "n_vertices", "T", "dt",
                "estimator", "dtype", "grounding_mode", "layout_platform", "grounding_search", "pc_layout",
                "rollout_unroll", "rollout_kernel", "platform", "host", "depth", "loop_executions", "sites", "versions", "commit",
                "timestamp")


def point_config(args, p: Point, platform: str):
    """The point's :class:`~psbmpc_jax.params.PlannerConfig`, its ``"auto"`` layouts chosen as on ``platform``
    (:meth:`~psbmpc_jax.params.PlannerConfig.for_platform`)."""
    from .params import PlannerConfig

    config = PlannerConfig(T=p.T, dt=args.dt, estimator=args.estimator, dtype=args.dtype,
                           grounding_mode=args.grounding, grounding_search=args.grounding_search)
    return config.for_platform(platform)


def depth_out_problem(path, depth: bool) -> str | None:
    """Why ``--out`` cannot take this run's records: ``psbmpc-jax report`` reads files of ``psbmpc-bench/1``
    records only, so depth records (``depth``) and timing records go to separate files.  None if it can."""
    if not path or not os.path.isfile(path):
        return None
    try:
        with open(path, encoding="utf-8") as fh:
            for lineno, line in enumerate(fh, 1):
                if not line.strip():
                    continue
                try:
                    schema = json.loads(line).get("schema")
                except (ValueError, AttributeError):
                    schema = None
                if depth and schema != DEPTH_SCHEMA:
                    return (f"--depth --out {path}: line {lineno} is not a {DEPTH_SCHEMA} record "
                            f"({schema or 'no schema'}); depth records go to a file of their own, or "
                            f"psbmpc-jax report could no longer read it: give another --out")
                if not depth and schema == DEPTH_SCHEMA:
                    return (f"--out {path}: line {lineno} is a {DEPTH_SCHEMA} record (psbmpc-jax bench --depth); "
                            f"timing records go to another file: give another --out")
    except (OSError, UnicodeDecodeError):
        return None      # unreadable: the CLI's own check of --out reports it
    return None


def run_depth(args, points) -> int:
    """``psbmpc-jax bench --depth``: per point the :func:`psbmpc_jax.depth.sequential_depth_only` of the solve step
    (:func:`psbmpc_jax.solve.solve` on the inputs the timing would use), one ``psbmpc-depth/1`` record each."""
    import functools

    import jax

    from .depth import sequential_depth_only
    from .params import Params
    from .planner import Planner
    from .solve import solve

    dev = jax.devices()[0] if args.devices == "all" else select_devices(args.devices)[args.devices][0]
    layout_platform = args.layout_platform or ("cpu" if dev.platform == "cpu" else "gpu")
    out = args.out or default_out()
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    meta = {"host": _platform.node(), "versions": versions(), "commit": commit()}
    with open(out, "a", encoding="utf-8") as fh:
        for i, p in enumerate(points, 1):
            behaviours, situation = behaviours_for(p.n_cbs), _situation(p)
            config = point_config(args, p, layout_platform)
            with jax.default_device(dev):
                planner = Planner(config, params=Params(r_ct=p.r_ct), behaviours=behaviours)
                inputs, state, params, samples = planner.prepare(situation, key=jax.random.key(args.seed))
                t0 = time.perf_counter()
                report = sequential_depth_only(functools.partial(solve, config=config), inputs, state, params,
                                               samples)
            rec = dict.fromkeys(DEPTH_FIELDS)
            rec.update(schema=DEPTH_SCHEMA, sweep=p.sweep, swept=p.swept, value=p.value, n_cbs=len(behaviours),
                       n_ps=int(max([ob.n_ps for ob in situation.obstacles], default=0)),
                       n_do=len(situation.obstacles), n_so=len(situation.polygons),
                       n_vertices=n_vertices(situation), T=float(p.T), dt=float(args.dt), estimator=config.estimator,
                       dtype=config.dtype, grounding_mode=config.grounding_mode, layout_platform=layout_platform,
                       grounding_search=config.grounding_search, pc_layout=config.pc_layout,
                       rollout_unroll=config.rollout_unroll, rollout_kernel=config.rollout_kernel,
                       platform=dev.platform,
                       **meta, **report.to_dict(),
                       timestamp=dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds"))
            assert set(rec) == set(DEPTH_FIELDS), set(rec) ^ set(DEPTH_FIELDS)
            fh.write(json.dumps(rec) + "\n")
            fh.flush()
            if not args.quiet:
                print(f"[{i}/{len(points)}] {p.label()} ({layout_platform} layouts): depth {report.depth}, "
                      f"{report.loop_executions} loop executions ({time.perf_counter() - t0:.1f} s)\n"
                      f"{report.table()}\n", flush=True)
    if not args.quiet:
        print(f"psbmpc-jax bench: {len(points)} depth records appended to {out}", file=sys.stderr)
    return 0


# ------------------------------------------------------------------------------------------- refinement
REFINE_SCHEMA = "psbmpc-bench-refine/1"
#: The refinement benchmark's cases: (case, PlannerConfig overrides of the Nidelva preset, refine horizon [s]
#: (None: the config's T), starts, batch).  "nidelva": the preset's T = 150 s with a 60 s refine horizon;
#: "nidelva_T60": the whole MPC horizon 60 s; "paper000": the Smooth-SBMPC paper's T_init 60 s / T_mpc 20 s at
#: dt 1 s (docs/smooth_sbmpc.md).  Always 2 obstacles x 5 scenarios and the 13 Table 2 polygons (grid mode).
REFINE_CASES = (
    ("nidelva", {}, 60.0, 1, "map"),
    ("nidelva", {}, 60.0, 4, "map"),
    ("nidelva", {}, 60.0, 16, "map"),
    ("nidelva", {}, 60.0, 16, "vmap"),
    ("nidelva_T60", {"T": 60.0}, None, 1, "map"),
    ("nidelva_T60", {"T": 60.0}, None, 16, "vmap"),
    ("paper000", {"T": 60.0, "dt": 1.0}, 20.0, 1, "map"),
    ("paper000", {"T": 60.0, "dt": 1.0}, 20.0, 16, "vmap"),
)
REFINE_FIELDS = ("schema", "case", "what", "platform", "device_kind", "host", "dtype", "estimator", "grounding_mode",
                 "T", "dt", "horizon", "n_steps", "n_refine", "n_starts", "batch", "block", "max_outer", "max_inner",
                 "n_cbs", "n_do", "n_ps", "n_so", "compile_s", "times_ms", "median_ms", "min_ms", "max_ms", "q1_ms",
                 "q3_ms", "iterations", "status", "used_warm", "start_index", "cost", "warm_cost", "grid_cost",
                 "warm_grid_cost", "grid_total", "schedule", "versions", "commit", "timestamp")


def _refine_slots(cases, dtype: str, log):
    """Compile and warm up every slot of the refinement benchmark: per configuration the grid search
    (``grid``), one ``value_and_grad`` of the smooth objective at the grid's choice (``value_and_grad``) and
    one library solve from it (``solve_one``: :func:`psbmpc_jax.nlp.solve_docp` alone); per case the whole
    :func:`psbmpc_jax.refine.refine` call (``refine``)."""
    import jax
    import jax.numpy as jnp

    from .examples import nidelva_head_on
    from .nlp import solve_docp
    from .planner import Planner
    from .presets import build_mpc
    from .refine import RefineSettings, behaviour_controls, box, problem, refine, refine_data, smooth_terms
    from .solve import solve

    sit = nidelva_head_on()
    slots, prepared = [], {}
    for case, overrides, horizon, n_starts, batch in cases:
        key = (case, tuple(sorted(overrides.items())), horizon)
        settings = RefineSettings(n_starts=n_starts, batch=batch, horizon=horizon)
        if key not in prepared:
            config, params, beh = build_mpc("nidelva", {**overrides, "dtype": dtype})
            planner = Planner(config, params, beh)
            inputs, state, p, samples = planner.prepare(sit)
            base = dict(case=case, dtype=dtype, estimator=config.estimator, grounding_mode=config.grounding_mode,
                        T=config.T, dt=config.dt, horizon=horizon, n_steps=config.n_steps,
                        n_refine=settings.n_refine(config), n_cbs=len(beh), n_do=len(sit.obstacles),
                        n_ps=max(o.n_ps for o in sit.obstacles), n_so=len(sit.polygons))
            t0 = time.perf_counter()
            grid = solve.lower(inputs, state, p, samples, config=config).compile()
            grid_s = time.perf_counter() - t0
            plan, _, ev = jax.block_until_ready(grid(inputs, state, p, samples))
            n_ref = settings.n_refine(config)
            data = refine_data(inputs, jnp.asarray(state.last_offsets, config.dtype), p, config, smooth_terms())
            f, _ = problem(config, n_ref, 1)
            warm = behaviour_controls(jnp.asarray(inputs.behaviours.offsets)[plan.best], p, config)
            args = (data, warm[n_ref:])
            z0 = warm[:n_ref]
            lo, hi = box(jax.tree.map(jnp.asarray, inputs.behaviours))
            lower, upper = jnp.broadcast_to(lo, z0.shape), jnp.broadcast_to(hi, z0.shape)
            t0 = time.perf_counter()
            vg = jax.jit(jax.value_and_grad(f)).lower(z0, args).compile()
            vg_s = time.perf_counter() - t0
            solver = settings.solver
            t0 = time.perf_counter()
            one = solve_docp.jitted.lower(f, z0, lower, upper, None, None, solver, args).compile()
            one_s = time.perf_counter() - t0
            res = jax.block_until_ready(one(z0, lower, upper, solver, args))
            common = dict(base, n_starts=1, batch=None, block=1, max_outer=solver.max_outer,
                          max_inner=solver.max_inner, grid_total=float(plan.total))
            slots.append(dict(rec=dict(common, what="grid", n_starts=None, compile_s=grid_s),
                              call=lambda g=grid, a=(inputs, state, p, samples): g(*a)))
            slots.append(dict(rec=dict(common, what="value_and_grad", compile_s=vg_s),
                              call=lambda g=vg, z=z0, a=args: g(z, a)))
            slots.append(dict(rec=dict(common, what="solve_one", compile_s=one_s, iterations=int(res.inner_iterations),
                                       status=int(res.status), cost=float(res.f), warm_cost=float(f(z0, args))),
                              call=lambda g=one, z=z0, lo=lower, hi=upper, s=solver, a=args: g(z, lo, hi, s, a)))
            prepared[key] = (config, inputs, state, p, samples, plan, ev, base)
            log(f"{case}: grid search compiled in {grid_s:.1f} s, value_and_grad in {vg_s:.1f} s, one solve in "
                f"{one_s:.1f} s ({int(res.inner_iterations)} iterations)")
        config, inputs, state, p, samples, plan, ev, base = prepared[key]
        t0 = time.perf_counter()
        r = jax.block_until_ready(refine(inputs, plan, state, p, samples, config, settings, evaluation=ev))
        compile_s = time.perf_counter() - t0
        rec = dict(base, what="refine", n_starts=n_starts, batch=batch, block=settings.block,
                   max_outer=settings.solver.max_outer, max_inner=settings.solver.max_inner, compile_s=compile_s,
                   iterations=int(r.iterations), status=int(r.status), used_warm=bool(r.used_warm),
                   start_index=int(r.start_index), cost=float(r.cost), warm_cost=float(r.warm_cost),
                   grid_cost=float(r.grid_cost), warm_grid_cost=float(r.warm_grid_cost), grid_total=float(plan.total))
        a = (inputs, plan, state, p, samples, config, settings)
        slots.append(dict(rec=rec, call=lambda a=a, e=ev: refine(*a, evaluation=e)))
        log(f"{case} {n_starts} start(s) {batch}: compiled in {compile_s:.1f} s, {int(r.iterations)} iterations, "
            f"smooth cost {float(r.warm_cost):.4g} -> {float(r.cost):.4g}")
    return slots


def refine_benchmark(repeats: int = 20, warmup: int = 2, cases=REFINE_CASES, dtype: str = "float32",
                     log=lambda msg: None) -> list[dict]:
    """The refinement benchmark on the default device: compile every slot, ``warmup`` untimed calls each, then
    ``repeats`` rounds timing every slot once per round (interleaved).  Returns one record per slot (the
    :data:`REFINE_FIELDS` that apply; timings in ms)."""
    import jax

    slots = _refine_slots(cases, dtype, log)
    for slot in slots:
        for _ in range(warmup):
            jax.block_until_ready(slot["call"]())
        slot["times"] = []
    log(f"timing {len(slots)} slots round-robin, {repeats} rounds")
    for _ in range(repeats):
        for slot in slots:
            t0 = time.perf_counter()
            jax.block_until_ready(slot["call"]())
            slot["times"].append(time.perf_counter() - t0)
    dev = jax.devices()[0]
    out = []
    for slot in slots:
        rec = dict(slot["rec"], platform=dev.platform, device_kind=dev.device_kind, schedule="interleaved",
                   **stats_ms(slot["times"]))
        if isinstance(rec.get("compile_s"), float):
            rec["compile_s"] = round(rec["compile_s"], 3)
        out.append(rec)
        log(f"{rec['case']:>12} {rec['what']:>14} {rec.get('n_starts') or '':>3} {rec.get('batch') or '':>5}: "
            f"median {rec['median_ms']:.2f} ms" + (f", {rec['iterations']} iterations" if rec.get('iterations')
                                                     is not None else ""))
    return out


def run_refine_bench(args) -> int:
    """``psbmpc-jax bench --preset refine``: :func:`refine_benchmark` on each selected platform, one
    ``psbmpc-bench-refine/1`` JSON line per slot appended to ``--out``."""
    import jax

    out = args.out or default_out()
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    log = (lambda msg: None) if args.quiet else (lambda msg: print(f"[refine] {msg}", file=sys.stderr, flush=True))
    meta = {"host": _platform.node(), "versions": versions(), "commit": commit()}
    n = 0
    with open(out, "a", encoding="utf-8") as fh:
        for plat, devs in select_devices(args.devices).items():
            with jax.default_device(devs[0]):
                recs = refine_benchmark(args.repeats, args.warmup, dtype=args.dtype, log=log)
            for rec in recs:
                full = dict.fromkeys(REFINE_FIELDS)
                full.update(rec, schema=REFINE_SCHEMA, host=meta["host"], versions=meta["versions"],
                            commit=meta["commit"],
                            timestamp=dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds"))
                assert set(full) == set(REFINE_FIELDS), set(full) ^ set(REFINE_FIELDS)
                fh.write(json.dumps(full) + "\n")
                n += 1
            fh.flush()
    if not args.quiet:
        print(f"psbmpc-jax bench: {n} refine records appended to {out}", file=sys.stderr)
    return 0


__all__ = ["run_bench", "add_bench_arguments", "build_plan", "behaviours_for", "FIELDS", "SCHEMA", "PRESETS",
           "DEPTH_FIELDS", "DEPTH_SCHEMA", "run_depth", "point_config", "depth_out_problem",
           "REFINE_CASES", "REFINE_FIELDS", "REFINE_SCHEMA", "refine_benchmark", "run_refine_bench"]
