"""The time of one MPC update estimated from its shapes, checked before anything is compiled.

Memory is not the only way a setting inside its documented range can fail: the gradient refinement
(``psbmpc_refine``) at 100 000 x 100 000 solver iterations, or Smooth-SBMPC with ``T_init`` = 10 000 steps, fit
in memory but would not finish one update.  The entry points (loading a scenario, ``Planner.plan(refine=...)``,
``SmoothSBMPCPlanner.plan`` / ``plan_batch``) estimate the seconds of one update of one run from its shapes and
refuse it with :class:`psbmpc_jax.limits.ResourceError` when the estimate exceeds the limit, naming the setting,
the estimate and the limit, and how to raise the limit knowingly.

* :func:`time_limit` -- the seconds an update may take: :data:`DEFAULT_LIMIT_S`, or the environment variable
  ``PSBMPC_UPDATE_TIME_LIMIT`` (seconds, or ``off`` for no check).
* :func:`refine_parts` / :func:`check_refine` -- the refinement (after the grid search, which is not counted).
* :func:`smooth_parts` / :func:`check_smooth` -- Smooth-SBMPC (initialisation stage and DOCP).
* :func:`grid_search_parts` / :func:`check_grid_search` -- the grid search (one :func:`psbmpc_jax.solve.solve`
  of the PSB-MPC family), also the first part of a refinement's update.
* :data:`TWO_LEVEL_UPDATE_S` -- the two-level MPC's update (measured, not modelled from shapes).

:mod:`psbmpc_jax.simulation_time` builds the time of a whole simulation from these.

The estimates are linear models whose coefficients were measured on the project's 2-core CPU machine at small
sizes (``benchmarks/bench_update_time.py``; docs/limits.md, "Time of an update").  They count every solver
iteration the settings allow (each start runs ``max_outer x max_inner`` iterations; the refinement's do end on
max-iter at almost every update), so they are upper bounds for a solver that stops early.  On a faster machine
or an accelerator the same settings run faster: raise the limit there.  Light: no JAX.
"""

from __future__ import annotations

import math
import os

from .limits import ResourceError

#: Seconds one MPC update of one run may take unless ``PSBMPC_UPDATE_TIME_LIMIT`` says otherwise.
DEFAULT_LIMIT_S = 300.0
ENV = "PSBMPC_UPDATE_TIME_LIMIT"

# ------------------------------------------------------------------------------- measured coefficients [s]
#: Refinement: one solver iteration of one start, REFINE_ITER[0] + REFINE_ITER[1] x (N + 1), N the PSB-MPC horizon
#: in steps (the objective rolls out the whole horizon), at 2 obstacles x 5 scenarios; scaled by
#: obstacle scenarios / 10 above 10 (the forward pass runs over every (step, obstacle scenario) point).  Fitted to
#: ``solve_one`` at N = 60 and 300 (8 iterations: 0.67 and 1.69 ms per iteration; 1.03 ms at N = 120 against
#: 0.93 modelled) times 1.22, the whole start's time per iteration in ``refine`` (16 starts - 1 start: 16.5 ms per
#: start of 8 iterations at N = 300) over ``solve_one``'s (benchmarks/results/refine_cpu_20261123T204124Z.json).
REFINE_ITER = (0.496e-3, 5.18e-6)
#: Refinement, once per update (ranking the warm starts, the safeguard, the grid costs of the result), in
#: iterations of one start: 23.4 ms for 1 start - 16.5 ms per start = 6.9 ms at N = 300, 3.4 iterations.
REFINE_FIXED_ITERATIONS = 3.4
#: Smooth-SBMPC initialisation stage: N_init x (N_init + 1) x (SMOOTH_INIT[0] + SMOOTH_INIT[1] x targets)
#: (N_init inner steps, each predicting 39 behaviours over N_init steps).  An upper bound: the stage's time also
#: depends on how much land the predictions reach (N_TP's culling), so the least-squares fit over N_init 30 / 60 /
#: 90 / 120 / 240 with 1 to 4 targets on the reconstruction channel is scaled by 2.94, until no measured case
#: lies above it (90 steps with 2 targets, the predictions reaching the peninsula: 1 025 ms; the others are 2.1 to
#: 3.7 times below it, e.g. 240 steps with 4 targets 2 603 ms against 9 528 modelled;
#: benchmarks/results/update_time_cpu_20261129T13*.json).
SMOOTH_INIT = (8.57e-5, 1.98e-5)
#: Smooth-SBMPC DOCP, one inner iteration of one start: SMOOTH_ITER[0] (the solver's own machinery: optax L-BFGS
#: and its zoom line search, measured on a trivial objective of the same size) + SMOOTH_ITER[1] x N_mpc x
#: (1 + targets) (J_d's value and gradient): 83.3 ms for 240 inner iterations at N_mpc 20 with 4 targets, 0.347 ms
#: per iteration (benchmarks/results/smooth_step_cpu_20261123T210417Z.json, "docp").
SMOOTH_ITER = (0.2e-3, 1.47e-6)
#: Grid search, one solve, float32: GRID_FIXED_S + points x (GRID_POINT["base"] + land + obstacle scenarios x
#: GRID_POINT[<estimator>] x max(1, n_samples / 500) for mc / ce), points = (N + 1) x padded behaviours; land:
#: GRID_POINT["exact_vertex"] x chart vertices with exact grounding, GRID_POINT["grid"] with grid grounding.
#: Fitted to records of the 2-core CPU machine (benchmarks/results/): without obstacles 5.7 ms at 1 014 behaviours,
#: N 300 and one small polygon (bench_cpu_paper_v4.jsonl "fig10"): base 1.5e-8; exact grounding 2.2e-10 per point
#: and vertex (the "fig9" vertex sweep: 1 734 and 21 961 vertices, 122 and 1 477 ms); the obstacle-scenario term
#: between the head-on simulation (24 ms per solve with 1 x 5 obstacle scenarios, no land;
#: sim_devices_cpu_20261129T100239Z.json, loop mode) and the core solve (29.7 ms with 2 x 5;
#: core_cpu_20261122T085054Z.json); ce 31 times quadrature at 500 samples (974 against 29.7 ms, the same record; mc
#: as quadrature there).  Grid grounding's land term (1e-8 per point) was not measured alone: the Nidelva
#: simulation (grid grounding, 303 vertices: 14.7 ms per solve; sim_batch_cpu_20261122T133758Z.json) runs below the
#: estimate with it.  The obstacle-scenario term is an upper bound where the sigma-shortcut culls far scenarios
#: (the n_ps sweep "fig7": 225 ms measured at 2 x 41 scenarios, 430 ms estimated).
GRID_FIXED_S = 2e-3
GRID_POINT = dict(base=1.5e-8, exact_vertex=2.2e-10, grid=1e-8, quadrature=1e-8, mc=1e-8, ce=3.1e-7)
#: float64 against float32, the same records: 6.7 without land (core: 198 / 29.7 ms), 57 for exact grounding
#: ("fig9": 6 959 / 122 ms).
GRID_FLOAT64 = dict(base=6.7, land=57.0)
#: The two-level MPC, one update of the own-ship (the path-following NMPC and its SB-MPC): 6.0 ms with 3 targets
#: and 8.0 ms with 4 (medians, benchmarks/results/path_mpc_cpu_20261126T114628Z.json); taken as 8 ms + 2 ms per
#: target above 4 (not measured above 4).
TWO_LEVEL_UPDATE_S = (8.0e-3, 2.0e-3)


def limit_from_env(name: str, default_s: float) -> tuple[float | None, str]:
    """``(seconds, source)`` of a time limit set by the environment variable ``name`` (seconds > 0, or ``off`` /
    ``none`` / ``inf``: ``(None, ...)``, nothing refused), ``default_s`` when unset; ``ValueError`` naming the
    variable for anything else."""
    env = os.environ.get(name)
    if env is None or not env.strip():
        return default_s, f"the default; {name}=<seconds> or {name}=off raises it"
    if env.strip().lower() in ("off", "none", "inf"):
        return None, f"{name}={env}"
    try:
        v = float(env)
    except ValueError:
        v = float("nan")
    if not (math.isfinite(v) and v > 0):
        raise ValueError(f"{name} must be a number of seconds > 0 or 'off', got {env!r}")
    return v, f"{name}={env}"


def time_limit() -> tuple[float | None, str]:
    """``(seconds, source)``: the time one update may take; ``(None, ...)`` when ``PSBMPC_UPDATE_TIME_LIMIT`` is
    ``off`` (nothing is refused)."""
    return limit_from_env(ENV, DEFAULT_LIMIT_S)


def fmt_seconds(s: float) -> str:
    """``0.42 s``, ``12 min``, ``3.1 h``, ``2.5e+03 days``."""
    if s < 120:
        return f"{s:.3g} s"
    if s < 7200:
        return f"{s / 60:.3g} min"
    if s < 2 * 86400:
        return f"{s / 3600:.3g} h"
    return f"{s / 86400:.3g} days"


def refine_parts(n_steps: int, n_obstacle_scenarios: int, n_starts: int, max_outer: int, max_inner: int) -> dict:
    """Seconds of one refinement by part: ``{"iterations": ..., "fixed": ...}`` (``n_steps``: the PSB-MPC
    horizon in steps; the grid search before it is not counted)."""
    it = (REFINE_ITER[0] + REFINE_ITER[1] * (n_steps + 1)) * max(1.0, n_obstacle_scenarios / 10.0)
    return {"iterations": float(n_starts) * max_outer * max_inner * it, "fixed": REFINE_FIXED_ITERATIONS * it}


def smooth_parts(n_init: int, n_mpc: int, n_targets: int, n_starts: int, max_outer: int, max_inner: int,
                 init_only: bool = False) -> dict:
    """Seconds of one Smooth-SBMPC update of one run by part: ``{"init": ..., "docp": ...}``."""
    init = float(n_init) * (n_init + 1) * (SMOOTH_INIT[0] + SMOOTH_INIT[1] * n_targets)
    docp = 0.0 if init_only else (float(n_starts) * max_outer * max_inner
                                  * (SMOOTH_ITER[0] + SMOOTH_ITER[1] * n_mpc * (1 + n_targets)))
    return {"init": init, "docp": docp}


def grid_search_parts(n_steps: int, n_behaviours: int, n_obstacle_scenarios: int, land_vertices: int = 0,
                      grounding_mode: str = "exact", dtype: str = "float32", estimator: str = "quadrature",
                      n_samples: int = 500) -> dict:
    """Seconds of one grid-search solve by part: ``{"fixed", "points", "land", "collision"}`` (``n_behaviours``
    and ``n_obstacle_scenarios`` as padded, :func:`psbmpc_jax.limits.padded_sizes`; ``land_vertices`` 0: open
    water)."""
    points = (n_steps + 1) * float(n_behaviours)
    wide = dtype == "float64"
    scale = max(1.0, n_samples / 500.0) if estimator in ("mc", "ce") else 1.0
    if not land_vertices:
        land = 0.0
    elif grounding_mode == "grid":
        land = points * GRID_POINT["grid"] * (GRID_FLOAT64["base"] if wide else 1.0)
    else:
        land = points * land_vertices * GRID_POINT["exact_vertex"] * (GRID_FLOAT64["land"] if wide else 1.0)
    base = GRID_FLOAT64["base"] if wide else 1.0
    return {"fixed": GRID_FIXED_S, "points": points * GRID_POINT["base"] * base, "land": land,
            "collision": points * n_obstacle_scenarios * GRID_POINT[estimator] * scale * base}


def _config_parts(config, n_behaviours: int, n_obstacle_scenarios: int, land_vertices: int) -> dict:
    """:func:`grid_search_parts` for a :class:`~psbmpc_jax.params.PlannerConfig`."""
    return grid_search_parts(config.n_steps, n_behaviours, n_obstacle_scenarios, land_vertices,
                             config.grounding_mode, config.dtype, config.estimator, config.n_samples)


def grid_search_seconds(config, n_behaviours: int, n_obstacle_scenarios: int, land_vertices: int = 0) -> float:
    """:func:`grid_search_parts` summed, for a :class:`~psbmpc_jax.params.PlannerConfig`."""
    return sum(_config_parts(config, n_behaviours, n_obstacle_scenarios, land_vertices).values())


def two_level_seconds(n_targets: int) -> float:
    """Seconds of one two-level MPC update (:data:`TWO_LEVEL_UPDATE_S`)."""
    return TWO_LEVEL_UPDATE_S[0] + TWO_LEVEL_UPDATE_S[1] * max(0, n_targets - 4)


def check(setting: str, estimate: float, what: str, hint: str,
          limit: tuple[float | None, str] | None = None) -> float:
    """Raise :class:`~psbmpc_jax.limits.ResourceError` when ``estimate`` seconds exceed the limit; returns the
    estimate."""
    cap, source = limit if limit is not None else time_limit()
    if cap is not None and estimate > cap:
        raise ResourceError(
            f"{setting}: {what} takes about {fmt_seconds(estimate)} per MPC update (estimated from its shapes with "
            f"the times measured on a 2-core CPU); the limit is {fmt_seconds(cap)} ({source}). {hint}. To run it "
            f"anyway, set {ENV} to more seconds (or 'off')")
    return estimate


def _largest(ratios: dict) -> str:
    """The name whose ratio to its default is the largest (the setting a refusal names)."""
    return max(ratios, key=lambda name: ratios[name])


def check_refine(n_steps: int, n_obstacle_scenarios: int, n_starts: int, max_outer: int, max_inner: int, *,
                 names: dict | None = None, limit=None) -> float:
    """:func:`check` of one refinement (:func:`refine_parts`).  ``names`` maps ``"horizon"``, ``"starts"``,
    ``"iterations"`` to the caller's names of those settings (defaults: RefineSettings' and SolverSettings')."""
    parts = refine_parts(n_steps, n_obstacle_scenarios, n_starts, max_outer, max_inner)
    n = {"horizon": "PlannerConfig.T / dt", "starts": "RefineSettings.n_starts",
         "iterations": "RefineSettings.solver.max_outer x max_inner", **(names or {})}
    top = _largest({"iterations": max_outer * max_inner / 8.0, "starts": n_starts / 4.0, "horizon": n_steps / 300.0})
    what = (f"the refinement ({n_starts} start(s) x {max_outer} x {max_inner} solver iterations over {n_steps} "
            f"steps x {n_obstacle_scenarios} obstacle scenarios)")
    hints = {"iterations": "Fewer solver iterations (the refinement's default is 1 x 8)",
             "starts": "Fewer starts", "horizon": "A shorter horizon or a larger dt"}
    return check(n[top], sum(parts.values()), what, hints[top], limit)


def check_smooth(n_init: int, n_mpc: int, n_targets: int, n_starts: int, max_outer: int, max_inner: int,
                 init_only: bool = False, *, names: dict | None = None, limit=None) -> float:
    """:func:`check` of one Smooth-SBMPC update of one run (:func:`smooth_parts`).  ``names`` maps ``"T_init"``,
    ``"T_mpc"``, ``"starts"``, ``"iterations"`` to the caller's names of those settings."""
    parts = smooth_parts(n_init, n_mpc, n_targets, n_starts, max_outer, max_inner, init_only)
    n = {"T_init": "SmoothSettings.T_init / dt", "T_mpc": "SmoothSettings.T_mpc / dt",
         "starts": "n_starts", "iterations": "SolverSettings.max_outer x max_inner", **(names or {})}
    if parts["init"] >= parts["docp"]:
        top = "T_init"
    else:
        top = _largest({"iterations": max_outer * max_inner / 1000.0, "starts": n_starts / 4.0,
                        "T_mpc": n_mpc / 20.0})
    what = (f"Smooth-SBMPC (initialisation stage {n_init} steps x {n_targets} target(s)"
            + ("" if init_only else f"; DOCP {n_starts} start(s) x {max_outer} x {max_inner} iterations over "
                                    f"{n_mpc} steps")
            + "; " + ", ".join(f"{k} {fmt_seconds(v)}" for k, v in parts.items() if v) + ")")
    hints = {"T_init": "A shorter initialisation horizon or a larger dt (its time grows with the square of its "
                       "steps)",
             "T_mpc": "A shorter DOCP horizon or a larger dt", "starts": "Fewer starts",
             "iterations": "Fewer solver iterations (the DOCP's default is 20 x 50)"}
    return check(n[top], sum(parts.values()), what, hints[top], limit)


def check_grid_search(config, n_behaviours: int, n_obstacle_scenarios: int, land_vertices: int = 0, *,
                      names: dict | None = None, limit=None) -> float:
    """:func:`check` of one grid-search solve (:func:`grid_search_parts`).  ``names`` maps ``"horizon"``,
    ``"behaviours"``, ``"samples"``, ``"land"`` to the caller's names of those settings."""
    parts = _config_parts(config, n_behaviours, n_obstacle_scenarios, land_vertices)
    n = {"horizon": "PlannerConfig.T / dt", "behaviours": "the behaviours", "samples": "PlannerConfig.n_samples",
         "land": "the chart's vertices (with grounding_mode exact)", **(names or {})}
    if parts["land"] >= max(parts["points"], parts["collision"]) and config.grounding_mode == "exact":
        top = "land"
    elif config.estimator != "quadrature" and parts["collision"] > parts["points"] + parts["land"]:
        top = "samples"
    else:
        top = _largest({"horizon": config.n_steps / 300.0, "behaviours": n_behaviours / 1024.0})
    what = (f"the grid search ({config.n_steps} steps x {n_behaviours} behaviours x {n_obstacle_scenarios} obstacle "
            f"scenarios, {config.dtype}, estimator {config.estimator}"
            + (f" with n_samples = {config.n_samples}" if config.estimator != "quadrature" else "")
            + (f", {land_vertices} chart vertices, grounding {config.grounding_mode}" if land_vertices else "") + ")")
    hints = {"horizon": "A shorter horizon or a larger dt", "behaviours": "Fewer behaviours",
             "samples": "Fewer samples (or the quadrature estimator)",
             "land": "grounding_mode grid, or a simpler chart (chart.rdp_eps_m, chart.clip_m)"}
    return check(n[top], sum(parts.values()), what, hints[top], limit)


__all__ = ["DEFAULT_LIMIT_S", "ENV", "time_limit", "fmt_seconds", "refine_parts", "smooth_parts", "check",
           "check_refine", "check_smooth", "grid_search_parts", "grid_search_seconds", "check_grid_search",
           "two_level_seconds", "TWO_LEVEL_UPDATE_S"]
