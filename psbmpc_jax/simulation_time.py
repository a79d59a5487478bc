"""The time of a whole closed-loop simulation estimated from its shapes, checked when a scenario is loaded.

Every setting of a scenario file can be inside its own bound while their product is not: 86 400 s at a 0.5 s MPC
period is 172 800 updates per run, times 10 000 runs, times the ships that run an MPC, times the seconds of one
update (paper scale: 0.2 s).  :func:`estimate` multiplies them out -- MPC updates per run (``duration_s /
update_period_s``) x runs x, for every ship that runs a planner, the seconds of one update of its method
(:mod:`psbmpc_jax.update_time`), plus the simulator's own work per step and run -- and :func:`check` refuses a
simulation above the limit with :class:`psbmpc_jax.limits.ResourceError` naming the settings that drive it, the
estimate and the limit.

* :func:`time_limit` -- :data:`DEFAULT_LIMIT_S` (24 h), or the environment variable
  ``PSBMPC_SIMULATION_TIME_LIMIT`` (seconds, or ``off``).
* :func:`estimate` -- ``(seconds, parts)`` of a :class:`~psbmpc_jax.scenario.Scenario` with ``runs`` runs.
* :func:`check` -- called by :func:`psbmpc_jax.scenario.scenario_from_dict` (the file's runs, or the runs its
  caller will simulate: ``load_scenario(..., runs=N)``) and by
  :func:`psbmpc_jax.sim.simulate` (a ``runs`` override, e.g. ``psbmpc-jax run --runs``).
* :func:`describe` -- one line for the command line's log before a run.

Calibration (the coefficients of :mod:`psbmpc_jax.update_time` and :data:`SIM_STEP_S`): the per-update times of
``update_time`` (grid search: ``core_cpu_20261122T085054Z.json`` and ``bench_cpu_paper_v4.jsonl``; refinement:
``refine_cpu_20261123T204124Z.json``; Smooth-SBMPC: ``update_time_cpu_20261129T13*.json`` and
``smooth_step_cpu_20261123T210417Z.json``; two-level: ``path_mpc_cpu_20261126T114628Z.json``) and the simulator's
host time per step from ``sim_batch_cpu_20261122T133758Z.json`` (all in ``benchmarks/results/``; 2-core CPU).
``tests/test_simulation_time.py`` compares the estimate with the simulations recorded in
``sim_batch_cpu_20261122T133758Z.json``, ``sim_devices_cpu_20261129T100239Z.json`` and
``progress_eta_cpu_20261129T094053Z.json``.  Compiling is not counted (tens of seconds per scenario, once).
Light: no JAX.
"""

from __future__ import annotations

import math

from . import update_time
from .limits import ResourceError, padded_sizes

#: Seconds a whole simulation (all runs) may take unless ``PSBMPC_SIMULATION_TIME_LIMIT`` says otherwise.
DEFAULT_LIMIT_S = 24 * 3600.0
ENV = "PSBMPC_SIMULATION_TIME_LIMIT"
#: The simulator's host work per simulation step and run (ship dynamics, tracking, bookkeeping), besides the
#: planners: the Nidelva record (4 runs x 121 steps, 3 ships, loop mode) spent 2.773 s in all and 2.123 s in the
#: solves: 0.65 s / 484 = 1.3 ms per step and run.
SIM_STEP_S = 1.3e-3

#: The methods whose update is the grid search (with their prediction scenarios per obstacle; None: mpc.n_ps).
GRID_SEARCH_N_PS = {"psbmpc": None, "psbmpc_refine": None, "sbmpc": 1, "psbmpc_2020": 1, "informed_sbmpc": 1}


def time_limit() -> tuple[float | None, str]:
    """``(seconds, source)``: the time a whole simulation may take; ``(None, ...)`` when
    ``PSBMPC_SIMULATION_TIME_LIMIT`` is ``off``."""
    return update_time.limit_from_env(ENV, DEFAULT_LIMIT_S)


def update_seconds(mpc, method: str, n_obstacles: int, land_vertices: int = 0) -> float:
    """Seconds of one update of one ship running ``method`` with the scenario's ``mpc`` settings among
    ``n_obstacles`` other ships; 0 for a method whose time is not modelled (a user's controller, ``none``)."""
    from .methods.smooth_settings import DOCP_SOLVER_ITERATIONS, REFINE_SOLVER_ITERATIONS, SMOOTH_METHODS

    given = mpc.solver.given()
    if method in GRID_SEARCH_N_PS:
        n_ps = GRID_SEARCH_N_PS[method] or mpc.n_ps
        n_b, n_os = padded_sizes(len(mpc.behaviours), n_obstacles, n_ps)
        t = update_time.grid_search_seconds(mpc.config, n_b, n_os, land_vertices)
        if method == "psbmpc_refine":
            mo, mi = (given.get(k, d) for k, d in zip(("max_outer", "max_inner"), REFINE_SOLVER_ITERATIONS))
            t += sum(update_time.refine_parts(mpc.config.n_steps, n_os, mpc.refine.n_starts, mo, mi).values())
        return t
    if method in SMOOTH_METHODS:
        sm = mpc.smooth
        mo, mi = (given.get(k, d) for k, d in zip(("max_outer", "max_inner"), DOCP_SOLVER_ITERATIONS))
        return sum(update_time.smooth_parts(int(round(sm.T_init / sm.dt)), int(round(sm.T_mpc / sm.dt)), n_obstacles,
                                            sm.n_starts, mo, mi, init_only=method == "sbmpc_init").values())
    if method == "two_level":
        return update_time.two_level_seconds(n_obstacles)
    return 0.0


def planners(scenario) -> list[str]:
    """The method of every ship that runs a planner (the own-ship's is ``mpc.method``)."""
    out = [scenario.mpc.method] if scenario.own_ship.colav != "none" else []
    return out + [t.colav for t in scenario.targets if t.colav != "none"]


def estimate(scenario, runs: int | None = None) -> tuple[float, dict]:
    """``(seconds, parts)`` of simulating ``scenario`` with ``runs`` runs (default: the scenario's): parts
    ``updates`` (MPC updates per run), ``update_s`` (the seconds of one update of all ships), ``planners``,
    ``steps``, ``runs``, ``planning_s`` and ``simulator_s``."""
    runs = scenario.runs if runs is None else int(runs)
    n_ships = 1 + len(scenario.targets)
    land = sum(len(r) for rs in scenario.polygons for r in rs)        # chart vertices
    steps = int(round(scenario.duration / scenario.dt))
    updates = int(math.floor(scenario.duration / scenario.mpc.period + 1e-9)) + 1
    methods = planners(scenario)
    per_update = sum(update_seconds(scenario.mpc, m, n_ships - 1, land) for m in methods)
    planning = float(updates) * runs * per_update
    simulator = float(steps) * runs * SIM_STEP_S
    return planning + simulator, dict(updates=updates, update_s=per_update, planners=methods, steps=steps,
                                      runs=runs, planning_s=planning, simulator_s=simulator)


def describe(scenario, runs: int | None = None) -> str:
    """``about 3.2 min: 2 runs x 45 MPC updates x 0.21 s (3 planners) + the simulator 0.4 s``."""
    total, p = estimate(scenario, runs)
    return (f"about {update_time.fmt_seconds(total)} ({p['runs']} run(s) x {p['updates']} MPC updates x "
            f"{update_time.fmt_seconds(p['update_s'])} per update of {len(p['planners'])} planner(s) "
            f"[{', '.join(sorted(set(p['planners']))) or 'none'}] + the simulator "
            f"{update_time.fmt_seconds(p['simulator_s'])}; estimated from the shapes with times measured on a 2-core "
            f"CPU, compiling not counted)")


def check(scenario, runs: int | None = None, *, runs_setting: str = "monte_carlo.runs",
          limit: tuple[float | None, str] | None = None) -> float:
    """Refuse a simulation whose :func:`estimate` exceeds the limit (:func:`time_limit`), naming the settings
    that drive it with their values (the duration by the name of its override when the loader replaced the file's,
    ``Scenario.overrides``), the estimate and the limit; returns the estimate."""
    total, p = estimate(scenario, runs)
    cap, source = limit if limit is not None else time_limit()
    if cap is None or total <= cap:
        return total
    mpc = scenario.mpc
    methods = set(p["planners"])
    shape = []                      # what sets the time of one update, per kind of planner
    if methods & set(GRID_SEARCH_N_PS):
        shape.append(f"{len(mpc.behaviours)} behaviours (mpc.speed_factors x mpc.course_offsets_deg) over "
                     f"mpc.config.T = {mpc.config.T:g} s")
    if methods & {"smooth_sbmpc", "sbmpc_init"}:
        shape.append(f"mpc.smooth.T_init_s = {mpc.smooth.T_init:g} and T_mpc_s = {mpc.smooth.T_mpc:g}")
    duration = scenario.overrides.get("simulation.duration_s", {}).get("by", "simulation.duration_s")
    settings = (f"{duration} = {scenario.duration:g} / mpc.update_period_s = {mpc.period:g} "
                f"({p['updates']} MPC updates per run; simulation.dt_s = {scenario.dt:g}: {p['steps']} steps), "
                f"{runs_setting} = {p['runs']}, " + "".join(f"{x}, " for x in shape)
                + f"{len(p['planners'])} ship(s) planning ({', '.join(sorted(methods))})")
    raise ResourceError(
        f"{settings}: the simulation takes about {update_time.fmt_seconds(total)} ({p['runs']} run(s) x "
        f"{p['updates']} updates x {update_time.fmt_seconds(p['update_s'])} per update, plus the simulator "
        f"{update_time.fmt_seconds(p['simulator_s'])}; estimated from the shapes with the times measured on a "
        f"2-core CPU); the limit is {update_time.fmt_seconds(cap)} ({source}). Fewer runs, a shorter duration_s, "
        f"a longer update_period_s or a smaller planner (fewer behaviours, a shorter horizon); to run it anyway, set {ENV} to more seconds (or 'off'); "
        f"a campaign splits many runs into tasks (psbmpc-jax campaign)")


__all__ = ["DEFAULT_LIMIT_S", "ENV", "SIM_STEP_S", "GRID_SEARCH_N_PS", "time_limit", "update_seconds", "planners",
           "estimate", "describe", "check"]
