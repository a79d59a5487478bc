"""Loading a scenario: :func:`scenario_from_dict` (a parsed mapping), :func:`load_scenario` (a ``.yaml`` path or a
built-in name), :func:`builtin_scenarios`, :func:`estimator_key`."""

from __future__ import annotations
import copy
import os
import pathlib
from typing import Any

import numpy as np
import shapely
import shapely.validation
from shapely.geometry import Polygon
from .. import limits as resources
from .. import simulation_time
from .. import scenario_checks as limits
from ..charts import count_vertices, to_ring_sets
from ..checks import integer, multiple_of

from ..config import as_mapping, as_number, as_string, check_keys, yaml_load
from .mpc import method_name, read_evaluation, read_mpc
from .schema import SCENARIO_DIR, Scenario
from .ships import read_ship
from .world import chart_source, clip_polygons, read_origin_latlon, read_sensor
from ..methods.registry import get_method
from ..methods.stop_remedy_settings import check_scenario_remedy


_TOP_KEYS = ("name", "description", "simulation", "monte_carlo", "collision_distance_m", "evaluation", "mpc", "sensor",
             "chart",
             "origin_latlon", "own_ship", "targets")


_TOP_REQUIRED = ("name", "simulation", "mpc", "own_ship")


_SIM_KEYS = ("dt_s", "duration_s")


_MC_KEYS = ("runs", "seed")


# ---------------------------------------------------------------------------------------------- sections
def _simulation(d) -> tuple[float, float]:
    d = as_mapping(d, "simulation")
    check_keys(d, _SIM_KEYS, "simulation", required=_SIM_KEYS)
    dt = as_number(d["dt_s"], "simulation.dt_s", gt=0)
    return dt, _duration(d["duration_s"], dt, "simulation.duration_s")


def _duration(value, dt: float, setting: str) -> float:
    """A simulation's duration [s]: the file's ``simulation.duration_s`` or a caller's override (``setting`` names
    it): a number in (0, MAX_DURATION_S], at least ``dt``, a multiple of it, at most MAX_STEPS steps."""
    duration = as_number(value, setting, gt=0, le=limits.MAX_DURATION_S)
    if dt > duration:
        raise ValueError(f"simulation.dt_s ({dt:g}) must be <= {setting} ({duration:g})")
    if duration / dt > limits.MAX_STEPS * (1 + 1e-9):
        raise ValueError(f"{setting} / simulation.dt_s = {duration / dt:.6g} steps; at most "
                         f"{limits.MAX_STEPS} allowed (a larger dt_s or a shorter duration_s)")
    multiple_of(duration, dt, setting, "simulation.dt_s")
    return duration


def _monte_carlo(d) -> tuple[int, int]:
    d = as_mapping(d, "monte_carlo")
    check_keys(d, _MC_KEYS, "monte_carlo")
    runs = integer(d.get("runs", 20), "monte_carlo.runs", ge=1, le=limits.MAX_RUNS)
    seed = integer(d.get("seed", 0), "monte_carlo.seed", ge=0, le=limits.MAX_SEED)
    return runs, seed


# ---------------------------------------------------------------------------------------------- public API
def scenario_from_dict(data: dict, base_dir=None, source: str | None = None, *, land_checks: str = "warn",
                       method: str | None = None, simulated_runs: int | None = None,
                       runs_setting: str = "runs", duration_s: float | None = None,
                       duration_setting: str = "duration_s") -> Scenario:
    """Validate a scenario mapping (the parsed YAML, schema in ``docs/scenarios.md``) and build a
    :class:`Scenario` in SI units, radians and the local NED frame.

    Args:
        data: the mapping; not modified.
        base_dir: folder that ``chart.file`` is relative to (default: the current directory).
        source: recorded in ``Scenario.source`` (the file path).
        land_checks: what to do with the geometry problems of
            :func:`psbmpc_jax.scenario_checks.land_issues` (a ship starting on land, a waypoint on land, a route
            leg through land, two ships starting closer than the collision distance): ``"error"`` raises
            ``ValueError`` (what :func:`load_scenario` does), ``"warn"`` (default here) issues a
            :class:`~psbmpc_jax.scenario_checks.ScenarioWarning` per problem, ``"off"`` skips the checks.
        method: overrides ``mpc.method`` (one of :data:`METHODS`; ``psbmpc-jax run --method``) before the
            mapping is validated, so the file is checked as if it said so.
        simulated_runs, runs_setting: the runs the caller will simulate when not the mapping's (the simulator's
            memory and the time of the whole simulation are checked for them, and a refusal names them as
            ``runs_setting``).
        duration_s, duration_setting: a duration [s] that replaces ``simulation.duration_s`` (a campaign's
            ``duration_s``), validated as the file's field is (a refusal names it as ``duration_setting``); every
            check that depends on the duration (the simulator's memory, the evaluation's memory, the time of the
            whole simulation, the land checks) is made for it, not for the file's.  The ships are read against
            the longer of the two (a ``speed_plan`` entry after a shorter override's end never applies; a default
            route is long enough for a longer one).  Recorded in ``Scenario.overrides``.

    Raises:
        ValueError: unknown or missing keys, wrong types, non-finite numbers, values out of range, unit
            alternatives given twice, times that are not multiples of ``simulation.dt_s``, bad overrides, bad
            charts, sizes above the limits of :mod:`psbmpc_jax.scenario_checks` -- the message names the key and
            says what is allowed.
    """
    if land_checks not in ("error", "warn", "off"):
        raise ValueError(f"land_checks must be 'error', 'warn' or 'off', got {land_checks!r}")
    data = copy.deepcopy(as_mapping(data, "the scenario"))
    check_keys(data, _TOP_KEYS, "the scenario (top level)", required=_TOP_REQUIRED)
    if method is not None:
        method_name(method, "method (the override of mpc.method)")
        data["mpc"] = {**as_mapping(data["mpc"], "mpc"), "method": method}
    name = as_string(data["name"], "name")
    description = data.get("description", "")
    if not isinstance(description, str):
        raise ValueError(f"description must be a string, got {description!r}")
    dt, duration = _simulation(data["simulation"])
    file_duration, overrides = duration, {}
    if duration_s is not None:
        duration = _duration(duration_s, dt, duration_setting)
        overrides["simulation.duration_s"] = {"file": file_duration, "used": duration, "by": duration_setting}
    runs, seed = _monte_carlo(data.get("monte_carlo", {}) or {})
    mpc = read_mpc(data["mpc"], dt)
    sensor = read_sensor(data.get("sensor", {}) or {}, dt)
    coll = None
    if "collision_distance_m" in data:
        coll = as_number(data["collision_distance_m"], "collision_distance_m", gt=0)
    origin_ll = read_origin_latlon(data["origin_latlon"]) if "origin_latlon" in data else None
    evaluation = read_evaluation(data.get("evaluation", {}) or {})

    chart = inline = None
    info: dict[str, Any] = dict(source=None, origin=None, crs=None)
    rdp_eps = clip = None
    if "chart" in data:
        chart, inline, info, rdp_eps, clip = chart_source(data["chart"], base_dir, origin_ll)
    info["origin_latlon"] = origin_ll

    tl = data.get("targets", [])
    if tl is None:
        tl = []
    if not isinstance(tl, (list, tuple)):
        raise ValueError(f"targets must be a list of ships, got {type(tl).__name__}")
    if len(tl) + 1 > limits.MAX_SHIPS:
        raise ValueError(f"targets: {len(tl)} target ships; at most {limits.MAX_SHIPS - 1} allowed (plus the "
                         f"own-ship)")
    n_steps = int(round(duration / dt))
    # the simulator's memory for the runs the caller will simulate in one call (the file's by default)
    if simulated_runs is not None:
        simulated_runs = integer(simulated_runs, runs_setting, ge=1)
    sim_runs, runs_name = (runs, "monte_carlo.runs") if simulated_runs is None else (simulated_runs, runs_setting)
    mem = limits.simulation_memory_bytes(n_steps, sim_runs, len(tl) + 1)
    if mem > limits.MAX_SIM_MEMORY_BYTES:
        dur = "simulation.duration_s" if duration_s is None else duration_setting
        raise ValueError(f"{runs_name} ({sim_runs}) x {n_steps + 1} steps ({dur} / simulation.dt_s) x "
                         f"{len(tl) + 1} ships need about {mem / 1024 ** 3:.1f} GiB of simulator memory; at most "
                         f"{limits.MAX_SIM_MEMORY_BYTES / 1024 ** 3:.0f} GiB allowed -- fewer runs, a shorter "
                         f"duration_s or a larger dt_s")

    # scoring every run after the simulation: checked now, not after the simulation has run
    resources.check_evaluation(duration, evaluation.sample_interval_s, len(tl) + 1, "own",
                               setting="evaluation.sample_interval_s",
                               hint="Use a larger evaluation.sample_interval_s (default 1 s)")

    # the ships: speed plans against the file's duration, default routes long enough for the longer of the two
    ctx = dict(chart=chart, duration=file_duration, route_duration=max(duration, file_duration), params=mpc.params,
               origin_latlon=origin_ll, method=mpc.method, colregs_option=mpc.colregs_option)
    own = read_ship(data["own_ship"], "own_ship", own=True, ctx=ctx)
    targets = tuple(read_ship(t, f"targets[{i}]", own=False, ctx=ctx) for i, t in enumerate(tl))
    seen = {own.name: "own_ship"}
    for i, t in enumerate(targets):
        if t.name in seen:
            raise ValueError(f"duplicate ship name {t.name!r} ({seen[t.name]} and targets[{i}]); ship names must "
                             f"be unique")
        seen[t.name] = f"targets[{i}]"

    # land: loaded -> RDP (builtin / file charts) -> clip about the routes -> ring sets
    polys: list[Polygon] = list(chart.polygons) if chart is not None else list(inline or ())
    info.update(n_polygons_loaded=len(polys), n_vertices_loaded=count_vertices(polys))
    if chart is not None:
        labels = [f"chart polygon {j}, feature {fid}" + (f" of layer {lay!r}" if lay else "")
                  for j, (fid, lay) in enumerate(zip(chart.ids, chart.layers))]
    else:
        labels = [f"chart.polygons_m[{j}]" for j in range(len(polys))]
    roles = [f"own-ship {own.name!r}"] + [f"target {t.name!r} (targets[{i}])" for i, t in enumerate(targets)]
    d_coll = float(mpc.params.d_safe if coll is None else coll)

    close = limits.start_distance_errors((own,) + targets, roles, d_coll)
    if close:
        raise ValueError(close[0] if len(close) == 1 else f"{len(close)} pairs of ships start too close: "
                         + "; ".join(close[:5]))
    reported: set = set()

    def land_check(variant, first):
        if land_checks == "off":
            return
        errors, warns = limits.land_issues((own,) + targets, roles, [variant], duration=duration,
                                           default_routes=ctx.get("default_routes", ()), ship_pairs=first)
        if own.allow_route_over_land:   # the file says so: the own-ship's legs over land are warned about
            leg = f"{roles[0]}: route leg "
            warns = warns + [m + " (allowed by own_ship.allow_route_over_land)" for m in errors if m.startswith(leg)]
            errors = [m for m in errors if not m.startswith(leg)]
        fresh = [m for m in errors + warns if not any(m.startswith(r) for r in reported)]
        errors, warns = [m for m in errors if m in fresh], [m for m in warns if m in fresh]
        reported.update(r for r in roles for m in errors + warns if m.startswith(r))
        limits.report_land_issues(errors, warns, land_checks)

    land_check(limits.LandVariant(polys, labels), True)       # before RDP: a start on land fails fast
    if chart is not None and rdp_eps is not None:
        from ..rdp import simplify_chart

        loaded_chart = chart
        chart = simplify_chart(chart, rdp_eps)
        polys = list(chart.polygons)
        info.update(n_vertices_rdp=count_vertices(polys),
                    rdp_degenerate_kept=int(chart.report.get("rdp_degenerate_kept", 0)),
                    rdp_holes_dropped=int(chart.report.get("rdp_holes_dropped", 0)))
        same = len(polys) == len(loaded_chart.polygons)
        land_check(limits.LandVariant(polys, labels if same else [f"simplified chart polygon {j}"
                                                                  for j in range(len(polys))],
                                      f", as simplified with rdp_eps_m = {rdp_eps:g}"), False)
    if clip is not None:
        polys, clip_info = clip_polygons(polys, (own,) + targets, clip)
        info.update(clip_info)

    for j, q in enumerate(polys):   # what Situation (the planner) will accept: RDP can make rings self-intersect
        if not q.is_valid:
            raise ValueError(f"chart: polygon {j} of the land as simplified (rdp_eps_m = {rdp_eps}) and clipped is not "
                             f"a valid simple polygon ({shapely.validation.explain_validity(q)}); the planner refuses "
                             f"it -- use a smaller chart.rdp_eps_m")
    rings = tuple(tuple(np.asarray(r, dtype=float) for r in rs) for rs in to_ring_sets(polys)) if polys else ()
    info.update(rdp_eps_m=rdp_eps, clip_m=clip, n_polygons=len(rings),
                n_vertices=int(sum(len(r) for rs in rings for r in rs)))
    check_scenario_remedy(mpc.config.stop_remedy, [own.colav] + [t.colav for t in targets])
    _check_method_fit(mpc, own, targets)
    _check_solve_memory(mpc, len(targets), bool(rings))
    _check_update_time(mpc, len(targets), int(info["n_vertices"]))
    scenario = Scenario(name=name, description=description, own_ship=own, targets=targets, sensor=sensor, mpc=mpc,
                        polygons=rings, chart_info=info, dt=dt, duration=duration, runs=runs, seed=seed,
                        collision_distance=coll, source=source, evaluation=evaluation, overrides=overrides)
    # the whole simulation: updates x runs x planners, for the runs the caller will make (the file's by default)
    if simulated_runs is None:
        simulation_time.check(scenario)
    else:
        simulation_time.check(scenario, simulated_runs, runs_setting=runs_setting)
    return scenario


#: The methods whose solve is the grid search (:func:`psbmpc_jax.solve.solve`), with their scenarios per obstacle
#: (None: ``mpc.n_ps``); their memory is estimated at load (:func:`psbmpc_jax.limits.check_solve`).  The
#: smooth and two-level planners' memory is not estimated.
GRID_SEARCH_N_PS = simulation_time.GRID_SEARCH_N_PS


def _check_method_fit(mpc, own, targets) -> None:
    """Refuse a method whose default settings were tuned for ships of another scale than the ones that run it
    (:meth:`psbmpc_jax.methods.Method.check_fit`; a file that tunes the method for its ships, by the method's
    own section or, for the grid search, every scale-dependent parameter under ``mpc.params``, is not checked)."""
    runs: dict = {mpc.method: [own]}
    for t in targets:
        if t.colav != "none":
            runs.setdefault(t.colav, []).append(t)
    for name, ships in runs.items():
        get_method(name).check_fit(ships, mpc.given, mpc)


def _check_solve_memory(mpc, n_targets: int, land: bool) -> None:
    """Refuse a grid-search configuration whose solve cannot fit in memory (one solve: the CPU's loop batch mode;
    the vmap batch mode holds one per run and ship at once), before anything is compiled."""
    if mpc.method not in GRID_SEARCH_N_PS:
        return
    n_ps = GRID_SEARCH_N_PS[mpc.method] or mpc.n_ps
    n_b, n_os = resources.padded_sizes(len(mpc.behaviours), n_targets, n_ps)   # no JAX import while loading
    sb = mpc.sections.get("sbmpc")
    n_mc = int(getattr(sb, "n_mc", 0)) if mpc.method == "psbmpc_2020" else 0
    resources.check_solve(mpc.config, n_b, n_os, land, n_mc=n_mc,
                          settings={"horizon": "mpc.config.T (with dt_s and the behaviours)",
                                    "estimator": "mpc.config.n_samples", "n_mc": "mpc.sbmpc.n_mc"})


def _check_update_time(mpc, n_targets: int, land_vertices: int) -> None:
    """Refuse a grid-search, refinement or Smooth-SBMPC configuration whose update would take longer than the limit
    (:mod:`psbmpc_jax.update_time`), before anything is compiled."""
    from .. import update_time
    from ..methods.smooth_settings import DOCP_SOLVER_ITERATIONS, REFINE_SOLVER_ITERATIONS, SMOOTH_METHODS

    given = mpc.solver.given()
    names = {"iterations": "mpc.solver.max_outer x mpc.solver.max_inner"}
    if mpc.method in GRID_SEARCH_N_PS:
        n_b, n_os = resources.padded_sizes(len(mpc.behaviours), n_targets, GRID_SEARCH_N_PS[mpc.method] or mpc.n_ps)
        update_time.check_grid_search(mpc.config, n_b, n_os, land_vertices,
                                      names={"horizon": "mpc.config.T (with dt)",
                                             "behaviours": "mpc.speed_factors x mpc.course_offsets_deg (the "
                                                           "behaviours)", "samples": "mpc.config.n_samples",
                                             "land": "the chart's vertices (mpc.config.grounding_mode exact)"})
    if mpc.method == "psbmpc_refine":
        mo, mi = (given.get(k, d) for k, d in zip(("max_outer", "max_inner"), REFINE_SOLVER_ITERATIONS))
        _, n_os = resources.padded_sizes(len(mpc.behaviours), n_targets, mpc.n_ps)
        update_time.check_refine(mpc.config.n_steps, n_os, mpc.refine.n_starts, mo, mi,
                                 names=dict(names, horizon="mpc.config.T (with dt)", starts="mpc.refine.n_starts"))
    elif mpc.method in SMOOTH_METHODS:
        sm = mpc.smooth
        mo, mi = (given.get(k, d) for k, d in zip(("max_outer", "max_inner"), DOCP_SOLVER_ITERATIONS))
        update_time.check_smooth(int(round(sm.T_init / sm.dt)), int(round(sm.T_mpc / sm.dt)), n_targets, sm.n_starts,
                                 mo, mi, init_only=mpc.method == "sbmpc_init",
                                 names=dict(names, T_init="mpc.smooth.T_init_s (with dt_s)",
                                            T_mpc="mpc.smooth.T_mpc_s (with dt_s)", starts="mpc.smooth.n_starts"))


def estimator_key(scenario: Scenario, seed: int | None = None):
    """The PRNG key of the ``mc`` / ``ce`` estimators for a scenario run: ``jax.random.key(seed)`` with the
    scenario's ``monte_carlo.seed`` (or ``seed``); ``None`` for the ``quadrature`` estimator (it draws nothing)."""
    if scenario.mpc.config.estimator == "quadrature":
        return None
    import jax

    seed = integer(scenario.seed if seed is None else seed, "seed", ge=0, le=limits.MAX_SEED)
    return jax.random.key(seed)


def builtin_scenarios() -> list[str]:
    """Sorted names of the scenario files shipped in ``psbmpc_jax/scenarios/`` (``*.yaml``, ``*.yml``)."""
    if not SCENARIO_DIR.is_dir():
        return []
    return sorted({p.stem for p in SCENARIO_DIR.iterdir() if p.suffix in (".yaml", ".yml") and p.is_file()})


def builtin_path(name: str) -> pathlib.Path:
    """The file of the built-in scenario ``name`` (:func:`builtin_scenarios`); an unknown name raises ValueError
    listing the built-in ones."""
    for ext in (".yaml", ".yml"):
        p = SCENARIO_DIR / f"{name}{ext}"
        if p.is_file():
            return p
    raise ValueError(f"unknown built-in scenario {name!r}; built-in scenarios: {', '.join(builtin_scenarios())} "
                     f"(or give the path of a .yaml / .yml file)")


def read_utf8(path, what: str) -> str:
    """The text of ``path``, UTF-8 (a byte-order mark is skipped); a file in another encoding raises ValueError
    naming the file, the encoding expected and where the first byte that is not UTF-8 is (byte offset, line)."""
    raw = pathlib.Path(path).read_bytes()
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        raise ValueError(
            f"{path}: a {what} must be UTF-8 text; byte {exc.start} (line {line}) is 0x{raw[exc.start]:02x}, which "
            f"is not UTF-8 ({exc.reason}). Save the file as UTF-8 (e.g. iconv -f latin1 -t utf-8)") from None


def load_scenario(path_or_name, *, land_checks: str = "error", method: str | None = None,
                  runs: int | None = None, runs_setting: str = "runs", duration_s: float | None = None,
                  duration_setting: str = "duration_s") -> Scenario:
    """Load and validate a scenario: a path to a ``.yaml`` / ``.yml`` file, or the name of a built-in scenario
    (:func:`builtin_scenarios`, e.g. ``"head_on"``, ``"imazu_01"``).

    Everything is checked before anything is simulated or compiled, the land geometry included
    (``land_checks="error"``: a ship starting on land, a waypoint or route leg on or through land, two ships
    starting closer than the collision distance raise; see :func:`scenario_from_dict`).  ``method`` overrides
    the file's ``mpc.method`` (validated as if the file said so).  ``runs``: the Monte Carlo runs the caller will
    simulate when not the file's (a ``--runs`` override, a campaign's tasks): the time of the whole simulation is
    checked for them (:mod:`psbmpc_jax.simulation_time`) instead of for the file's ``monte_carlo.runs``, and a
    refusal names them as ``runs_setting``.  ``duration_s``: the duration the caller will simulate when not the
    file's ``simulation.duration_s`` (a campaign's ``duration_s``): validated as the file's field (a refusal names
    it as ``duration_setting``), every check that depends on the duration made for it, and recorded in
    ``Scenario.overrides`` (the run's ``metrics.json``: ``scenario.overrides``).

    Raises:
        ValueError: unknown built-in name (the message lists them), invalid YAML or an invalid scenario.
        FileNotFoundError: a ``.yaml`` / ``.yml`` path that does not exist.
    """
    if isinstance(path_or_name, os.PathLike):
        s = os.fspath(path_or_name)
        path_like = True
    elif isinstance(path_or_name, str) and path_or_name.strip():
        s = path_or_name
        path_like = s.lower().endswith((".yaml", ".yml")) or "/" in s or os.sep in s
    else:
        raise ValueError(f"load_scenario needs a .yaml/.yml path or a built-in scenario name "
                         f"({', '.join(builtin_scenarios())}), got {path_or_name!r}")
    if path_like:
        path = pathlib.Path(s).expanduser()
        if path.suffix.lower() not in (".yaml", ".yml"):
            raise ValueError(f"scenario files must end in .yaml or .yml, got {s!r}")
        if not path.is_file():
            raise FileNotFoundError(f"scenario file not found: {path}")
    else:
        path = builtin_path(s)
    where = str(path)
    data = yaml_load(read_utf8(path, "scenario file"), where)
    if not isinstance(data, dict):
        raise ValueError(f"{where}: a scenario file must hold a mapping at the top level, got "
                         f"{type(data).__name__}")
    try:
        return scenario_from_dict(data, base_dir=path.parent, source=where, land_checks=land_checks, method=method,
                                  simulated_runs=runs, runs_setting=runs_setting, duration_s=duration_s,
                                  duration_setting=duration_setting)
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None
