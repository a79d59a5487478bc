"""The method protocol: what the closed-loop simulator hands a controller (:class:`Observation`), what it gets
back (:class:`Decision`), and the two interfaces every collision-avoidance method implements (:class:`Method`,
:class:`Controller`).

A *method* is a named recipe (``mpc.method`` of the own-ship, ``colav`` of a target) that builds a *controller*
for the ships that run it.  One controller serves every ship of its method and every Monte Carlo run at once,
so that the solves of one update can be batched on the device.  At each MPC update the simulator calls
``controller.decide(observation)`` and applies the returned decision until the next update; nothing else passes
between them.

This module is light (NumPy only): the scenario loader imports the registry, and loading a scenario must not
import JAX.  The heavy parts of a method are imported inside its :meth:`Method.build`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Protocol, runtime_checkable

import numpy as np

from ..design_ship import DesignShip

if TYPE_CHECKING:                        # for the annotations only
    from ..situation import Situation

#: Columns of ``SimulationResult.best_costs`` and of :attr:`Decision.costs`: the total, then the PSB-MPC terms
#: of :data:`psbmpc_jax.evaluate.DEFAULT_TERMS` in order (NaN where a method has no such column).
COST_NAMES = ("total", "do", "colregs", "so", "path")
#: Per-update diagnostics a method may report for the own-ship (``SimulationResult.colav_info``; NaN where not
#: applicable): final cost, warm-start cost, constraint violation, whether the warm start was kept, solver status
#: and iterations.
INFO_NAMES = ("cost", "warm_cost", "violation", "used_warm", "status", "iterations")
#: Size [m] a point target (``length_m: 0``) gets in a PSB-MPC situation, which needs a positive hull.
POINT_HULL_M = 1e-6


def velocity_state(xs) -> np.ndarray:
    """A true state (x, y, χ, U) as an obstacle estimate ``[x, y, V_x, V_y]``."""
    return np.array([xs[0], xs[1], xs[3] * np.cos(xs[2]), xs[3] * np.sin(xs[2])])


def route_distance(p, route) -> float:
    """Distance [m] from point ``p [2]`` to the polyline ``route [m, 2]`` (the cross-track distance the route
    exchange's supervisor compares with ``mpc.informed.xtd_threshold``)."""
    p, route = np.asarray(p, float), np.asarray(route, float)
    a, b = route[:-1], route[1:]
    ab = b - a
    L2 = np.einsum("ij,ij->i", ab, ab)
    u = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.where(L2 > 0, L2, 1.0), 0.0, 1.0)
    return float(np.min(np.hypot(*(a + u[:, None] * ab - p).T)))


def tracked_targets(track_x: np.ndarray) -> np.ndarray:
    """Tracks ``[..., 4]`` (north, east, V_north, V_east) -> point targets ``[..., 4]`` (north, east, course
    ``atan2(V_east, V_north)`` [rad], speed ``|V|``)."""
    x = np.asarray(track_x, float)
    return np.stack([x[..., 0], x[..., 1], np.arctan2(x[..., 3], x[..., 2]), np.hypot(x[..., 2], x[..., 3])],
                    axis=-1)


@dataclass(frozen=True, eq=False)
class Observation:
    """What the controllers see at one MPC update, for every Monte Carlo run (axis ``R``) and ship (axis ``n``;
    ship 0 is the own-ship).  Built by the simulator, read by the controllers, never written back.

    Attributes:
        scenario: the :class:`~psbmpc_jax.scenario.Scenario` (ships, chart polygons, ``mpc`` settings, sensor).
        t: the time of the update [s].
        states: true states ``[R, n, 4]`` (north, east, course, speed).
        tracks, track_covs: the own-ship's target estimates ``[R, n - 1, 4]`` (north, east, V_north, V_east) and
            covariances ``[R, n - 1, 4, 4]`` (NaN before a target's first measurement).
        offsets: the (speed factor, course offset [rad]) applied until now ``[R, n, 2]``.
        segments: every ship's active route segment ``[R, n]`` (an index into ``routes``).
        routes: every ship's route extended past its last waypoint, padded ``[n, W, 2]``; ``route_len [n]`` rows
            of each are real.
        speeds: every ship's nominal speed now ``[R, n]`` [m/s] (its speed plan, or its active leg's speed).
        shared: per run and ship, the route ``[m, 2]`` and leg speeds (``[m - 1]`` or None) that ship last shared
            by route exchange (from its active segment at the time), or None (nothing received).
        target_cov: the covariance ``[4, 4]`` of the true-state estimates a target planner gets of the others.
        grid: the chart's nearest-land distance grid (``grounding_mode: grid``), or None.
        keep: the ``(run, ship)`` whose full evaluation the simulator would like in :attr:`Decision.snapshot`
            (for plots), or None.
    """

    scenario: Any
    t: float
    states: np.ndarray
    tracks: np.ndarray
    track_covs: np.ndarray
    offsets: np.ndarray
    segments: np.ndarray
    routes: np.ndarray
    route_len: np.ndarray
    speeds: np.ndarray
    shared: tuple
    target_cov: np.ndarray
    grid: Any = None
    keep: tuple | None = None

    @property
    def n_runs(self) -> int:
        """The number of Monte Carlo runs ``R``."""
        return int(self.states.shape[0])

    def route(self, i: int, r: int | None = None) -> np.ndarray:
        """Ship ``i``'s extended route ``[m, 2]``: whole, or from run ``r``'s active segment on."""
        start = 0 if r is None else int(self.segments[r, i])
        return self.routes[i, start: int(self.route_len[i])]

    def situation(self, r: int, i: int, n_ps: int | None = None, informed: bool = False) -> "Situation":
        """What ship ``i`` of run ``r`` plans with, as a PSB-MPC :class:`~psbmpc_jax.situation.Situation`: its
        remaining route from the active segment, the others through the own-ship's tracks (ship 0) or as true
        states with :attr:`target_cov` (targets), predicted with ``n_ps`` scenarios each (None: ``mpc.n_ps``;
        1: straight lines).  ``informed`` (Informed SB-MPC): one scenario each, along the route a ship shared
        while it is within ``mpc.informed.xtd_threshold`` of it (else a straight line), with the Rule-18 role it
        shared."""
        from ..situation import Obstacle, OwnShip, Situation

        sc = self.scenario
        s = sc.ships[i]
        own = OwnShip(state=self.states[r, i], waypoints=self.route(i, r), U_d=float(self.speeds[r, i]),
                      length=s.length, width=s.width)
        if informed:
            return Situation(own, tuple(self._informed_obstacle(r, i, j) for j in range(len(sc.ships)) if j != i),
                             sc.polygons)
        obstacles = []
        for j, o in enumerate(sc.ships):
            if j == i:
                continue
            est, cov = self._estimate(r, i, j)
            # a point target (length_m: 0) enters with a negligible hull: the planner needs a positive size
            obstacles.append(Obstacle(state=est, cov=cov, length=max(o.length, POINT_HULL_M),
                                      width=max(o.width, POINT_HULL_M), n_ps=sc.mpc.n_ps if n_ps is None else n_ps))
        return Situation(own, tuple(obstacles), sc.polygons)

    def _estimate(self, r: int, i: int, j: int):
        """Ship ``j`` as planner ``i`` of run ``r`` sees it: the own-ship through its tracks, a target planner
        through true states."""
        if i == 0:
            return self.tracks[r, j - 1], self.track_covs[r, j - 1]
        return velocity_state(self.states[r, j]), self.target_cov

    def _informed_obstacle(self, r: int, i: int, j: int):
        from ..situation import Obstacle

        sc = self.scenario
        o, xs = sc.ships[j], self.states[r, j]
        est, cov = self._estimate(r, i, j)
        received = self.shared[r][j]
        route, legs = received if received is not None and sc.mpc.informed.route_exchange else (None, None)
        if route is not None and route_distance(xs[:2], route) > sc.mpc.informed.xtd_threshold:
            route = legs = None                               # the XTD supervisor: off its plan, straight line
        return Obstacle(state=est, cov=cov, length=max(o.length, POINT_HULL_M), width=max(o.width, POINT_HULL_M),
                        n_ps=1, waypoints=route, leg_speeds=legs,
                        rule18=bool(received is not None and o.rule18_role != "pdv"))


@dataclass
class Decision:
    """What one controller decided at one update, per job ``(run, ship)``.

    Attributes:
        jobs: the ``(run, ship)`` pairs, in the order of the arrays.
        first: offsets ``(u, chi)`` applied at the update ``[n, 2]`` (speed factor on the nominal speed, course
            offset [rad] on LOS guidance).
        costs: the chosen behaviour's cost columns ``[n, len(COST_NAMES)]`` (NaN where a method has none).
        walls: wall time of each job [s] (amortised over the jobs of one device call).
        device_calls, wall: device calls of this update and their wall time [s].
        sequences: per-step offsets ``[n, N, 2]`` (row ``j`` applies from ``t_update + j * seq_dt`` on, the last
            row to the end of the period), or None: ``first`` is held until the next update.
        seq_dt: the step of ``sequences`` [s].
        info: :data:`INFO_NAMES` -> ``[n]`` (refinement / DOCP diagnostics) or None.
        snapshot: the full evaluation of the job :attr:`Observation.keep` asked for (a
            :class:`~psbmpc_jax.packing.PlanResult`), or None.
        commands: absolute commands ``(U, chi)`` ``[n, 2]`` [m/s, rad] applied as they are (not on top of LOS
            guidance) until the next update, or None; a NaN row: that job applies ``first`` over LOS guidance.
    """

    jobs: list
    first: np.ndarray
    costs: np.ndarray
    walls: np.ndarray
    device_calls: int
    wall: float
    sequences: np.ndarray | None = None
    seq_dt: float | None = None
    info: dict | None = None
    snapshot: Any = None
    commands: np.ndarray | None = None

    def __post_init__(self):
        n = len(self.jobs)
        for name in ("first", "costs", "walls"):
            v = np.asarray(getattr(self, name))
            want = (n, 2) if name == "first" else (n, len(COST_NAMES)) if name == "costs" else (n,)
            if v.shape != want:
                raise ValueError(f"Decision.{name} must have shape {want} (one row per job), got {v.shape}")


@runtime_checkable
class Controller(Protocol):
    """The interface of a controller: built by :meth:`Method.build` for the ``ships`` that run its method.

    ``decide`` is the batched form: one call per update for every run and ship of the controller, returning a
    :class:`Decision` with one job per ``(run, ship)``.  A controller that plans one ship at a time can subclass
    :class:`ShipController` instead.  Optional attributes the simulator reads when present: ``uses_grid`` (the
    controller packs the chart's distance grid, so the simulator should build it) and ``snapshots`` (it can fill
    :attr:`Decision.snapshot`)."""

    ships: tuple

    def init(self, n_runs: int) -> None:
        """Forget any memory of an earlier simulation; ``n_runs`` runs follow."""

    def decide(self, obs: Observation) -> Decision:
        """The decision of every run and ship of this controller at the update ``obs``."""


class ShipController:
    """A convenience base for controllers that decide one (run, ship) at a time: implement
    :meth:`decide_ship`; :meth:`decide` loops over runs and ships and times each call."""

    uses_grid = False
    snapshots = False

    def __init__(self, ships=(0,)):
        self.ships = tuple(int(i) for i in ships)

    def init(self, n_runs: int) -> None:
        """No memory by default."""

    def decide_ship(self, obs: Observation, r: int, i: int) -> tuple[float, float]:
        """The offsets ``(speed factor, course offset [rad])`` ship ``i`` of run ``r`` applies until the next
        update."""
        raise NotImplementedError

    def decide(self, obs: Observation) -> Decision:
        import time

        jobs = [(r, i) for r in range(obs.n_runs) for i in self.ships]
        first, walls = np.zeros((len(jobs), 2)), np.zeros(len(jobs))
        t_all = time.perf_counter()
        for n, (r, i) in enumerate(jobs):
            t0 = time.perf_counter()
            first[n] = self.decide_ship(obs, r, i)
            walls[n] = time.perf_counter() - t0
        return Decision(jobs=jobs, first=first, costs=np.full((len(jobs), len(COST_NAMES)), np.nan), walls=walls,
                        device_calls=0, wall=time.perf_counter() - t_all)


@dataclass(frozen=True)
class BuildContext:
    """What the simulator hands :meth:`Method.build` besides the scenario: the batch mode (``"vmap"``: one
    device call per update; ``"loop"``: one per solve), the PSB-MPC parameters as arrays, the estimator's sample
    table, the PRNG key (None for the ``quadrature`` estimator) and the local devices to split the vmapped batch
    over (None: the default device; :func:`psbmpc_jax.sharding.solve_batch`).  A controller that splits its batch
    over them says so with a class attribute ``splits_runs = True``."""

    mode: str = "loop"
    params: Any = None
    samples: Any = None
    key: Any = None
    devices: Any = None


class Method:
    """A collision-avoidance method: its name, what it may run, how it builds its controller and what the
    results record about it.  Subclass it (class attributes + :meth:`build`) and register an instance with
    :func:`psbmpc_jax.methods.register`, or name the class in a scenario by import path
    (``mpc.method: my_pkg.my_module:MyMethod``).

    Attributes:
        name: the name scenario files use (``mpc.method``, ``colav``).
        description: one line for listings.
        own_ship_only: whether only the own-ship (ship 0) may run it.
        diagnostics: whether its controller reports :data:`INFO_NAMES` per update for the own-ship
            (``SimulationResult.colav_info``).
        tuning_sections: the ``mpc.<key>`` sections that hold its scale-bearing settings.
        design_ship: the ship its default settings were tuned for (:class:`DesignShip`), or None.
            :meth:`check_fit` refuses a ship outside it (:meth:`design_for`: a method whose tuning is the
            scenario's preset takes the preset's) when the file gives none of :attr:`tuning_sections`.
    """

    name: str = ""                  # class attributes; a wrapper (psbmpc_refine) sets them per instance
    description: str = ""
    own_ship_only: ClassVar[bool] = False
    diagnostics: ClassVar[bool] = False
    tuning_sections: tuple = ()
    design_ship: ClassVar[DesignShip | None] = None

    def design_for(self, mpc) -> DesignShip | None:
        """The design ship of this method's settings in a scenario whose ``mpc`` section is ``mpc`` (an
        :class:`~psbmpc_jax.scenario.MPCSpec`, or None): :attr:`design_ship`."""
        return self.design_ship

    def untuned(self, given_sections, mpc=None) -> str | None:
        """The scale-bearing settings the file leaves at their defaults, as the error names them
        (``"mpc.informed"``), or None when the file tunes the method for its ships (gives one of
        :attr:`tuning_sections`; ``given_sections``: the ``mpc`` keys it gives, ``mpc``: the scenario's
        :class:`~psbmpc_jax.scenario.MPCSpec`, or None)."""
        if any(k in given_sections for k in self.tuning_sections):
            return None
        return " / ".join(f"mpc.{k}" for k in self.tuning_sections)

    def check_fit(self, ships, given_sections, mpc=None) -> None:
        """ValueError when this method's default settings do not fit one of ``ships`` (each with ``name``,
        ``length`` [m] and ``U_d`` [m/s]): the file leaves its scale-bearing settings at their defaults
        (:meth:`untuned`; ``given_sections``: the ``mpc`` keys it gives) and a ship lies outside the design ship
        (:meth:`design_for` of ``mpc``)."""
        design = self.design_for(mpc)
        sections = None if design is None else self.untuned(given_sections, mpc)
        if design is None or sections is None:
            return
        for ship in ships:
            why = design.misfit(float(ship.length), float(ship.U_d))
            if why:
                raise ValueError(
                    f"method {self.name} on ship {ship.name!r}: its default settings ({sections} not in the file) "
                    f"were tuned for {design.source} and fit "
                    f"ships within a factor {design.factor:g} of it; {why}. Give {sections} tuned for this ship "
                    f"(see the method's documentation page), or choose a method that fits it")

    def build(self, scenario, ships: tuple, context: BuildContext) -> Controller:
        """The controller of ``ships`` (indices into ``scenario.ships``) in ``scenario``."""
        raise NotImplementedError(f"method {self.name!r} does not implement build()")

    def record(self, scenario) -> dict:
        """The settings this method ran with in ``scenario``, resolved (defaults filled in), as plain values
        (``metrics.json`` records them under ``scenario.mpc.methods.<name>``; the own-ship's also at the top of
        ``scenario.mpc``)."""
        return {}

    def describe(self, scenario) -> str:
        """A few words on the settings, for ``summary.md`` (after the method's name)."""
        return ""

    def __repr__(self) -> str:
        return f"<method {self.name}>"


__all__ = ["COST_NAMES", "INFO_NAMES", "POINT_HULL_M", "Observation", "Decision", "Controller", "ShipController",
           "BuildContext", "DesignShip", "Method", "velocity_state", "route_distance", "tracked_targets"]
