"""Closed-loop simulation of a :class:`~psbmpc_jax.scenario.Scenario`, Monte Carlo runs batched.

Per simulation step (``scenario.dt``), for all runs at once (NumPy arrays ``[R, n_ships, ...]``):

1. every ``sensor.period``: noisy position measurements of the targets update the own-ship's Kalman-filter
   tracks (constant-velocity model, single-point initiation; :mod:`psbmpc_jax.sim.tracker`);
2. every ``mpc.period``: every ship that runs PSB-MPC solves once.  The own-ship sees the targets through
   its tracks (estimate + covariance); targets that run their own PSB-MPC see the other ships' true states
   with a small fixed covariance (``sensor.colav_target_cov``).  All solves of one update -- every run and
   every PSB-MPC ship -- go to the device together, as one ``vmap``-ed call (``batch="vmap"``) or one call
   each (``batch="loop"``); the planner state (last applied offsets) is carried per run and ship;
3. the true vessels move one step: LOS guidance on their routes with the MPC's course offset and speed
   factor, kinematic model with autopilot lags (:mod:`psbmpc_jax.sim.vessel`).

Randomness: run ``r`` draws its measurement noise from ``numpy.random.default_rng([seed, r])``, so a run
replays identically whatever the number of runs simulated with it.
"""

from __future__ import annotations

import functools
import sys
import time
from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np

from ..costs.collision import standard_normal_table
from ..distance_grid import build_distance_grid
from ..evaluate import evaluate, evaluate_arrays
from ..params import params_as_arrays
from ..planner import PlannerState, check_dtype, pack_situation, unpack
from ..problem import Obstacle, OwnShip, Situation
from ..scenario import Scenario
from . import metrics as metrics_mod
from .tracker import TrackerBank
from .vessel import extend_route, kinematic_step, los_course, nominal_speed, pad_routes, wrap

BATCH_MODES = ("auto", "vmap", "loop")
COST_NAMES = ("total", "do", "colregs", "so", "path")


@dataclass
class SimulationResult:
    """Everything a closed-loop simulation produced (NumPy, host).

    Attributes:
        scenario: the scenario simulated (with ``runs``/``seed`` as used).
        t: times ``[K+1]`` [s].
        states: true states ``[R, n_ships, K+1, 4]`` (north, east, course, speed); ship 0 is the own-ship.
        track_x, track_P: the own-ship's target estimates ``[R, n_targets, K+1, 4]`` and covariances
            ``[..., 4, 4]`` (after the measurement update of that step, if any).
        solve_t: MPC update times ``[M]``.
        offsets: applied (speed factor, course offset [rad]) ``[R, n_ships, M, 2]`` (nan for ships without
            PSB-MPC).
        best_costs: cost terms of the chosen behaviour ``[R, n_ships, M, 5]`` (total, do, colregs, so, path).
        calls: one dict per MPC update: time, number of solves, number of device calls (1 with vmap, one per
            solve in the loop), wall time of all of them [s].
        snapshot: one solve of run ``snapshot_run``'s own-ship kept in full (all candidate trajectories and
            their costs) for the paper-Fig.-1-style plot: the first solve that chose to manoeuvre.
        metrics: per-run metrics (:func:`psbmpc_jax.sim.metrics.run_metrics` plus per-ship land distances
            and the minimum distance between every pair of ships).
        summary: :func:`psbmpc_jax.sim.metrics.aggregate` of ``metrics`` plus run information.
    """

    scenario: Scenario
    t: np.ndarray
    states: np.ndarray
    track_x: np.ndarray
    track_P: np.ndarray
    solve_t: np.ndarray
    offsets: np.ndarray
    best_costs: np.ndarray
    calls: list
    snapshot: dict | None
    metrics: list
    summary: dict = field(default_factory=dict)


# ------------------------------------------------------------------------------------------- device calls
@functools.lru_cache(maxsize=8)
def _batched_evaluate(config):
    return jax.jit(jax.vmap(functools.partial(evaluate_arrays, config=config), in_axes=(0, None, None)))


@jax.jit
def _pick(ev):
    """Best index and its five cost terms (works batched: leading axes are kept)."""
    costs = jnp.stack([ev.total, ev.do, ev.colregs, ev.so, ev.path], axis=-1)          # [..., B, 5]
    return ev.best, jnp.take_along_axis(costs, ev.best[..., None, None], axis=-2)[..., 0, :]


_WAYPOINT_FIELDS = ("own_wx", "own_wy", "obs_wx", "obs_wy")


def stack_arrays(items):
    """Stack packed situations along a new leading axis, padding waypoint capacities to the largest
    (padding waypoints beyond the valid count never enter the guidance)."""
    w_own = max(a.own_wx.shape[-1] for a in items)
    w_obs = max(a.obs_wx.shape[-1] for a in items)

    def pad(a):
        rep = {}
        for name in _WAYPOINT_FIELDS:
            v = getattr(a, name)
            w = w_own if name.startswith("own") else w_obs
            if v.shape[-1] < w:
                rep[name] = jnp.pad(v, [(0, 0)] * (v.ndim - 1) + [(0, w - v.shape[-1])], mode="edge")
        return a._replace(**rep)

    return jax.tree.map(lambda *xs: jnp.stack(xs), *[pad(a) for a in items])


def resolve_batch_mode(batch: str) -> str:
    """``auto`` -> ``vmap`` on an accelerator, ``loop`` on the CPU (where one call per solve measured faster:
    see ``benchmarks/results``)."""
    if batch not in BATCH_MODES:
        raise ValueError(f"batch must be one of {BATCH_MODES}, got {batch!r}")
    if batch == "auto":
        return "loop" if jax.default_backend() == "cpu" else "vmap"
    return batch


# ------------------------------------------------------------------------------------------- helpers
def _check_multiple(value: float, step: float, what: str) -> int:
    n = value / step
    if abs(n - round(n)) > 1e-9 * max(1.0, n) or round(n) < 1:
        raise ValueError(f"{what} ({value} s) must be a positive multiple of the simulation step ({step} s)")
    return int(round(n))


def grid_region(scenario: Scenario, routes) -> tuple:
    """The area the distance grid must cover: every route and start, plus the farthest a ship can travel
    in one horizon, plus a 25 % allowance for avoidance manoeuvres off the routes.  Returns (region, reach):
    predictions stay on the grid as long as every ship stays ``reach`` inside the region (checked after the
    run and reported as ``grid_region_exceeded``)."""
    pts = np.concatenate([np.asarray(r, float) for r in routes] + [s.position[None] for s in scenario.ships])
    fastest = max(max(s.speed, s.U_d, *(s.speed_plan[:, 1] if s.speed_plan is not None else [0.0]))
                  for s in scenario.ships)
    reach = fastest * scenario.mpc.config.T
    pad = reach + 0.25 * float(np.max(np.ptp(pts, axis=0))) + 50.0
    return (tuple(pts.min(axis=0) - pad), tuple(pts.max(axis=0) + pad)), reach


class _Progress:
    def __init__(self, total: int, label: str, enabled: bool):
        self.total, self.label, self.enabled = total, label, enabled
        self.t0 = time.perf_counter()
        self.last = -1

    def update(self, k: int) -> None:
        if not self.enabled:
            return
        step = 2 if sys.stderr.isatty() else 25       # a log file gets four lines, a terminal a live bar
        pct = int(100 * k / max(self.total, 1)) // step * step
        if pct == self.last:
            return
        self.last = pct
        bar = "#" * (pct // 4) + "." * (25 - pct // 4)
        el = time.perf_counter() - self.t0
        eta = el / max(k, 1) * (self.total - k)
        sys.stderr.write(("\r" if sys.stderr.isatty() else "") + f"{self.label} [{bar}] {pct:3d}%  {el:6.1f} s elapsed, ~{eta:5.0f} s left")
        if k >= self.total or not sys.stderr.isatty():
            sys.stderr.write("\n")
        sys.stderr.flush()


# ------------------------------------------------------------------------------------------- simulation
def simulate(scenario: Scenario, *, runs: int | None = None, seed: int | None = None, batch: str = "auto",
             progress: bool = False, snapshot_run: int = 0, key=None) -> SimulationResult:
    """Run ``runs`` Monte Carlo closed-loop simulations of ``scenario`` (default: the scenario's).

    Args:
        runs, seed: override the scenario's Monte Carlo settings.
        batch: ``"vmap"`` (all solves of one MPC update in one device call), ``"loop"`` (one call per solve)
            or ``"auto"``.
        progress: draw a progress bar on stderr.
        snapshot_run: the run whose first manoeuvring own-ship solve is kept in full for plotting.
        key: PRNG key for the ``mc``/``ce`` estimators' samples (required for those; unused by ``quadrature``).
    """
    if not isinstance(scenario, Scenario):
        raise ValueError(f"scenario must be a psbmpc_jax.scenario.Scenario, got {type(scenario).__name__}")
    runs = scenario.runs if runs is None else runs
    seed = scenario.seed if seed is None else seed
    if isinstance(runs, bool) or not isinstance(runs, (int, np.integer)) or runs < 1:
        raise ValueError(f"runs must be an integer >= 1, got {runs!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    if not 0 <= snapshot_run < runs:
        raise ValueError(f"snapshot_run must be in [0, {runs}), got {snapshot_run}")
    mode = resolve_batch_mode(batch)
    mpc, sensor = scenario.mpc, scenario.sensor
    config = mpc.config
    check_dtype(config)
    if config.estimator != "quadrature" and key is None:
        raise ValueError(f"estimator {config.estimator!r} draws samples: pass key=jax.random.key(...)")
    dt = scenario.dt
    n_steps = _check_multiple(scenario.duration, dt, "duration")
    mpc_every = _check_multiple(mpc.period, dt, "mpc.period")
    meas_every = _check_multiple(sensor.period, dt, "sensor.period")

    ships = scenario.ships
    n_ships, n_tg = len(ships), len(ships) - 1
    routes = [s.waypoints for s in ships]
    routes_ext, n_wp = pad_routes([extend_route(r) for r in routes])
    colav = np.array([s.colav == "psbmpc" for s in ships])
    lookahead = np.array([s.lookahead for s in ships])
    R_a = np.array([s.R_a for s in ships])
    T_chi = np.array([s.T_chi for s in ships])
    T_U = np.array([s.T_U for s in ships])

    dtype = np.dtype(config.dtype)
    p_arrays = params_as_arrays(mpc.params, dtype)
    samples = standard_normal_table(key, config, dtype)
    grid = None
    if config.grounding_mode == "grid" and scenario.polygons:
        region, grid_reach = grid_region(scenario, routes)
        grid = build_distance_grid(scenario.polygons, config.grid_spacing, config.grid_margin, dtype=dtype,
                                   region=region)
        grid_lo, grid_hi = np.asarray(region[0]), np.asarray(region[1])

    # ---- state
    R = runs
    K = n_steps
    t = np.arange(K + 1) * dt
    states = np.empty((R, n_ships, K + 1, 4))
    states[:, :, 0] = np.array([[s.position[0], s.position[1], s.course, s.speed] for s in ships])
    seg = np.zeros((R, n_ships), dtype=np.int64)
    u_c = np.ones((R, n_ships))
    chi_off = np.zeros((R, n_ships))
    rngs = [np.random.default_rng([int(seed), r]) for r in range(R)]
    R_filter = sensor.filter_R_scale * sensor.position_std ** 2 * np.eye(2)
    tracker = TrackerBank((R, n_tg), R_filter, sensor.sigma_a, sensor.U_max) if n_tg else None
    track_x = np.full((R, n_tg, K + 1, 4), np.nan)
    track_P = np.full((R, n_tg, K + 1, 4, 4), np.nan)
    solve_steps = list(range(0, K, mpc_every))
    M = len(solve_steps)
    offsets = np.full((R, n_ships, M, 2), np.nan)
    best_costs = np.full((R, n_ships, M, 5), np.nan)
    calls, snapshot, snap_pending = [], None, True
    colav_idx = np.flatnonzero(colav)
    pos_var, vel_var = sensor.colav_target_cov
    true_cov = np.diag([pos_var, pos_var, vel_var, vel_var])
    bar = _Progress(K, f"{scenario.name} ({R} runs)", progress)

    def situation(r: int, i: int, k: int) -> Situation:
        s = ships[i]
        x = states[r, i, k]
        z = seg[r, i]
        own = OwnShip(state=x, waypoints=routes_ext[i, z: n_wp[i]], U_d=nominal_speed(s, t[k]),
                      length=s.length, width=s.width)
        obstacles = []
        for j in range(n_ships):
            if j == i:
                continue
            o = ships[j]
            if i == 0:           # the own-ship sees the targets through its tracker
                est, cov = track_x[r, j - 1, k], track_P[r, j - 1, k]
            else:                # a PSB-MPC target sees the true state with a small fixed covariance
                xs = states[r, j, k]
                est = np.array([xs[0], xs[1], xs[3] * np.cos(xs[2]), xs[3] * np.sin(xs[2])])
                cov = true_cov
            obstacles.append(Obstacle(state=est, cov=cov, length=o.length, width=o.width, n_ps=mpc.n_ps))
        return Situation(own, tuple(obstacles), scenario.polygons)

    for k in range(K + 1):
        bar.update(k)
        if tracker is not None:
            if k % meas_every == 0:
                z = states[:, 1:, k, :2] + sensor.position_std * np.stack([g.normal(size=(n_tg, 2)) for g in rngs])
                tracker.measure(z)
            track_x[:, :, k], track_P[:, :, k] = tracker.x, tracker.P
        if k == K:
            break
        if k % mpc_every == 0 and len(colav_idx):
            m = k // mpc_every
            jobs = [(r, i) for r in range(R) for i in colav_idx]
            packed = [pack_situation(situation(r, i, k), mpc.behaviours, PlannerState((u_c[r, i], chi_off[r, i])),
                                     config, grid) for r, i in jobs]
            t0 = time.perf_counter()
            snap_job = jobs.index((snapshot_run, 0)) if (snap_pending and colav[0]) else None
            if mode == "vmap":
                ev = _batched_evaluate(config)(stack_arrays(packed), p_arrays, samples)
                best, costs = jax.device_get(_pick(ev))
                snap_ev = jax.tree.map(lambda a: a[snap_job], ev) if snap_job is not None else None
            else:
                outs, snap_ev = [], None
                for n, a in enumerate(packed):
                    ev = evaluate(a, p_arrays, samples, config=config)
                    outs.append(_pick(ev))
                    if n == snap_job:
                        snap_ev = ev
                host = jax.device_get(outs)
                best, costs = np.array([b for b, _ in host]), np.stack([c for _, c in host])
            wall = time.perf_counter() - t0
            calls.append({"t_s": float(t[k]), "solves": len(jobs), "device_calls": 1 if mode == "vmap" else len(jobs),
                          "wall_s": wall})
            for n, (r, i) in enumerate(jobs):
                u, c = mpc.behaviours[int(best[n])][0]
                u_c[r, i], chi_off[r, i] = u, c
                offsets[r, i, m] = (u, c)
                best_costs[r, i, m] = costs[n]
            if snap_ev is not None:
                manoeuvring = bool(u_c[snapshot_run, 0] != 1.0 or chi_off[snapshot_run, 0] != 0.0)
                if snapshot is None or manoeuvring:
                    res = unpack(snap_ev, situation(snapshot_run, 0, k), mpc.behaviours, wall,
                                 per_polygon=config.grounding_mode == "exact")
                    snapshot = {"t_s": float(t[k]), "run": snapshot_run, "best_index": res.best_index,
                                "own_trajectories": res.own_trajectories, "total_cost": res.costs["total"],
                                "obstacle_trajectories": res.obstacle_trajectories, "manoeuvring": manoeuvring}
                snap_pending = not manoeuvring
        # ---- true motion
        pos = states[:, :, k, :2]
        chi_los, seg = los_course(pos, seg, routes_ext, n_wp, lookahead, R_a)
        U_cmd = u_c * np.array([nominal_speed(s, t[k]) for s in ships])
        states[:, :, k + 1] = kinematic_step(states[:, :, k], chi_los + chi_off, U_cmd, T_chi, T_U, dt)
        if tracker is not None:
            tracker.step(dt)

    grid_exceeded = None
    if grid is not None:   # every prediction must have stayed on the grid (see grid_region)
        xy = states[..., :2]
        grid_exceeded = bool(np.any(xy < grid_lo + grid_reach) or np.any(xy > grid_hi - grid_reach))
    result = SimulationResult(
        scenario=scenario, t=t, states=states, track_x=track_x, track_P=track_P,
        solve_t=t[solve_steps] if M else np.zeros(0), offsets=offsets, best_costs=best_costs, calls=calls,
        snapshot=snapshot, metrics=[],
    )
    result.metrics = [run_metrics(result, r) for r in range(R)]
    result.summary = summarize(result, mode=mode, grid_exceeded=grid_exceeded)
    return result


# ------------------------------------------------------------------------------------------- metrics
def run_metrics(result: SimulationResult, r: int) -> dict:
    """Metrics of run ``r``: :func:`psbmpc_jax.sim.metrics.run_metrics` for the own-ship, plus the minimum
    distance to land of every ship and the minimum distance between every pair of ships (targets that run
    their own PSB-MPC must not collide with each other either)."""
    sc = result.scenario
    states = result.states[r]
    own_solves = [c["wall_s"] / c["solves"] for c in result.calls] if sc.own_ship.colav == "psbmpc" else []
    out = metrics_mod.run_metrics(
        result.t, states[0], states[1:], sc.own_ship.waypoints, sc.polygons, d_collision=sc.d_collision,
        ground_clearance=0.5 * sc.own_ship.width, solve_times=own_solves or None,
        target_names=[s.name for s in sc.targets], classify_range=None)
    out["run"] = r
    ships = sc.ships
    if sc.polygons:
        land = [float(np.min(metrics_mod.distance_to_land(states[i, :, :2], sc.polygons))) for i in range(len(ships))]
        out["ships_min_distance_land_m"] = {s.name: d for s, d in zip(ships, land)}
        out["ships_grounded"] = [s.name for s, d in zip(ships, land) if d < 0.5 * s.width]
    pairs, controlled = {}, []
    for i in range(len(ships)):
        for j in range(i + 1, len(ships)):
            d = np.hypot(*(states[i, :, :2] - states[j, :, :2]).T)
            name = f"{ships[i].name}-{ships[j].name}"
            pairs[name] = float(d.min())
            if "psbmpc" in (ships[i].colav, ships[j].colav):
                controlled.append(name)
    out["pair_min_distance_m"] = pairs
    # a collision counts against the method only if one of the two ships runs PSB-MPC; two route-following
    # targets meeting each other is part of the scenario (reported, not counted)
    out["pair_collisions"] = [k for k in controlled if pairs[k] < sc.d_collision]
    out["uncontrolled_pair_collisions"] = [k for k in pairs if k not in controlled and pairs[k] < sc.d_collision]
    return out


def summarize(result: SimulationResult, *, mode: str, grid_exceeded: bool | None) -> dict:
    """Aggregate over runs, plus how the simulation ran (batch mode, device calls, timing)."""
    sc = result.scenario
    summary = metrics_mod.aggregate(result.metrics)
    walls = np.array([c["wall_s"] for c in result.calls]) if result.calls else np.zeros(0)
    per_solve = np.array([c["wall_s"] / c["solves"] for c in result.calls]) if result.calls else np.zeros(0)
    summary.update({
        "scenario": sc.name,
        "runs": len(result.metrics),
        "seed": sc.seed,
        "any_ship_groundings": sum(1 for m in result.metrics if m.get("ships_grounded")),
        "pair_collision_runs": sum(1 for m in result.metrics if m["pair_collisions"]),
        "pair_min_distance_m": {k: float(min(m["pair_min_distance_m"][k] for m in result.metrics))
                                for k in (result.metrics[0]["pair_min_distance_m"] if result.metrics else {})},
        "batch_mode": mode,
        "device": str(jax.devices()[0].device_kind),
        "platform": jax.default_backend(),
        "mpc_updates": len(result.calls),
        "device_calls": int(sum(c["device_calls"] for c in result.calls)),
        "solves": int(sum(c["solves"] for c in result.calls)),
        "call_wall_s_median": float(np.median(walls)) if walls.size else None,
        "solve_wall_s_amortised_median": float(np.median(per_solve)) if per_solve.size else None,
        "grid_region_exceeded": grid_exceeded,
    })
    return summary
