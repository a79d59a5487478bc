"""Host-side description of one planning situation (validated NumPy, float64).

Frame: NED — x north, y east [m]; courses from north, clockwise positive [rad]; speeds [m/s].

* :class:`OwnShip` — state ``[x, y, chi, U]``, the remaining route (the active segment is the first one),
  nominal speed ``U_d``, size.
* :class:`Obstacle` — tracker estimate ``[x, y, V_x, V_y]`` with 4x4 covariance, size, optional route
  (waypoints) for route exchange, the number of prediction scenarios, their probabilities, the cost weight
  ``w_i`` and track-loss modifier ``zeta_i``.
* :class:`Situation` — own-ship, obstacles and grounding polygons (already simplified / range-filtered;
  each a ring of vertices ``[n, 2]``, implicitly closed, or a tuple of such rings — outer ring and holes —
  combined with the even-odd rule).

Every constructor validates its input and raises ``ValueError`` naming the field and what is allowed:
booleans and strings where numbers belong, a course with ``|chi| > 2 pi`` (degrees passed by mistake; use
``np.deg2rad``), speeds above :data:`psbmpc_jax.checks.MAX_SPEED_MPS` (30 m/s) for the own-ship and above
:data:`MAX_OBSTACLE_SPEED_MPS` (60 m/s: tracker estimates are noisy) for obstacles, positions, waypoints and
land vertices farther than :data:`psbmpc_jax.checks.MAX_EARTH_M` (the Earth's circumference) from the frame's
origin (any metric frame, UTM included, is accepted), hull lengths
above 500 m and widths above 100 m, ``None`` or a single
:class:`Obstacle` / ring where a tuple or list belongs, and polygons that are not valid simple polygons
(self-intersecting rings, zero area, holes outside their outer ring or overlapping each other:
``shapely.validation.explain_validity`` says why).  NumPy scalars and arrays are accepted everywhere.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import checks

#: Highest obstacle speed estimate accepted [m/s]: twice the ship speed limit, since tracker estimates are noisy.
MAX_OBSTACLE_SPEED_MPS = 2.0 * checks.MAX_SPEED_MPS

#: Most prediction scenarios per obstacle.
MAX_N_PS = 101

#: Validity verdicts of polygons already checked (content key -> None or the reason); bounded.
_VALIDITY_CACHE: dict = {}
_VALIDITY_CACHE_SIZE = 4096


def _check_psd(P: np.ndarray, name: str) -> None:
    if not np.allclose(P, P.T, rtol=1e-9, atol=1e-12 * max(1.0, np.abs(P).max())):
        raise ValueError(f"{name} must be symmetric")
    eig = np.linalg.eigvalsh(0.5 * (P + P.T))
    if eig.min() < -1e-9 * max(1.0, eig.max()):
        raise ValueError(f"{name} must be positive semi-definite, got eigenvalues {eig.tolist()}")


def _ring(value, name: str) -> np.ndarray:
    arr = checks.finite_array(value, name)
    if arr.ndim != 2 or arr.shape[1] != 2 or arr.shape[0] < 3:
        raise ValueError(f"{name} must be a ring of shape [n >= 3, 2] (north, east), got {arr.shape}")
    return checks.local_positions(arr, name)


def _validity(rings: tuple) -> str | None:
    """Why the rings (outer ring, holes) are not a valid polygon, or ``None`` (shapely; cached by content)."""
    key = tuple((r.shape, r.tobytes()) for r in rings)
    if key in _VALIDITY_CACHE:
        return _VALIDITY_CACHE[key]
    import shapely
    import shapely.validation
    from shapely.geometry import Polygon

    why = None
    poly = Polygon(rings[0], rings[1:])
    if not poly.is_valid:
        why = shapely.validation.explain_validity(poly)
    elif Polygon(rings[0]).area <= 0.0:
        why = "zero area (collinear vertices)"
    else:
        for k, h in enumerate(rings[1:], start=1):
            if Polygon(h).area <= 0.0:
                why = f"hole (ring {k}) has zero area"
                break
    if len(_VALIDITY_CACHE) >= _VALIDITY_CACHE_SIZE:
        _VALIDITY_CACHE.clear()
    _VALIDITY_CACHE[key] = why
    return why


def _polygon(value, name: str):
    """A polygon is one ring ``[n, 2]`` or a tuple of rings (outer ring first, then holes); it must be a valid
    simple polygon (shapely ``is_valid``, non-zero area; holes inside the outer ring)."""
    if value is None:
        raise ValueError(f"{name} must be a ring [n >= 3, 2] (north, east) or a tuple (outer ring, holes...), "
                         f"got None")
    out: np.ndarray | tuple[np.ndarray, ...]
    if isinstance(value, (list, tuple)) and len(value) > 0 and np.ndim(value[0]) == 2:
        rings = tuple(_ring(r, f"{name}[{k}]") for k, r in enumerate(value))
        out = rings
    else:
        ring = _ring(value, name)
        rings = (ring,)
        out = ring
    why = _validity(rings)
    if why is not None:
        what = "outer ring + holes" if len(rings) > 1 else "ring"
        raise ValueError(f"{name} ({what}) is not a valid simple polygon: {why}; allowed: a non-self-intersecting "
                         f"outer ring with non-zero area and holes inside it (repair with shapely.make_valid, or a "
                         f"smaller RDP epsilon)")
    return out


def _safe_ndim(value) -> int:
    try:
        return int(np.ndim(value))
    except ValueError:      # ragged (a tuple of rings of different lengths)
        return -1


def _sequence(value, name: str, item: str, single_type=None) -> tuple:
    """A tuple or list (NumPy arrays of items accepted) -> tuple; ``None`` and a single item are refused."""
    if value is None:
        raise ValueError(f"{name} must be a tuple/list of {item} (use () for none), got None")
    if single_type is not None and isinstance(value, single_type):
        raise ValueError(f"{name} must be a tuple/list of {item}, got a single {type(value).__name__}; pass a "
                         f"tuple/list of {item}, e.g. ({name.split('.')[-1][:-1]},)")
    if isinstance(value, (str, bytes, dict)) or not hasattr(value, "__iter__"):
        raise ValueError(f"{name} must be a tuple/list of {item}, got {type(value).__name__}")
    return tuple(value)


def polygon_rings(polygon) -> tuple[np.ndarray, ...]:
    """The rings of a polygon as stored in :class:`Situation` (a single ring -> a 1-tuple)."""
    return polygon if isinstance(polygon, tuple) else (polygon,)


def ring_vertices(polygon) -> tuple[np.ndarray, np.ndarray]:
    """A polygon's rings back to back: vertices ``[n, 2]`` and, per vertex, the index of the next vertex of
    the same ring ``[n]`` (each ring closes on itself; the even-odd rule over all edges handles holes)."""
    verts, nxt, start = [], [], 0
    for ring in polygon_rings(polygon):
        n = len(ring)
        verts.append(np.asarray(ring, dtype=float))
        nxt.append(start + (np.arange(n) + 1) % n)
        start += n
    return np.concatenate(verts), np.concatenate(nxt).astype(np.int32)


@dataclass(frozen=True)
class OwnShip:
    """Own-ship: state ``[x, y, chi, U]``, route ``waypoints [n >= 2, 2]`` and nominal speed ``U_d``."""

    state: np.ndarray
    waypoints: np.ndarray
    U_d: float
    length: float = 5.0
    width: float = 3.0

    def __post_init__(self) -> None:
        state = checks.finite_array(self.state, "own_ship.state", (4,))
        if state[3] < 0:
            raise ValueError(f"own_ship.state speed U must be >= 0 m/s, got {state[3]}")
        checks.course(state[2], "own_ship.state course chi (state[2], radians)")
        checks.speed(state[3], "own_ship.state speed U (state[3])")
        checks.local_positions(state[:2], "own_ship.state position (x, y)")
        object.__setattr__(self, "state", state)
        object.__setattr__(self, "waypoints", checks.local_positions(
            checks.waypoints(self.waypoints, "own_ship.waypoints", 2), "own_ship.waypoints"))
        object.__setattr__(self, "U_d", checks.speed(self.U_d, "own_ship.U_d"))
        object.__setattr__(self, "length", checks.hull(self.length, "own_ship.length", checks.MAX_SHIP_LENGTH_M))
        object.__setattr__(self, "width", checks.hull(self.width, "own_ship.width", checks.MAX_SHIP_WIDTH_M))


@dataclass(frozen=True)
class Obstacle:
    """A tracked dynamic obstacle.

    Attributes:
        state: ``[x, y, V_x, V_y]`` estimate (NED position [m], velocity [m/s]).
        cov: 4x4 symmetric PSD covariance of ``state``.
        length, width: size [m].
        waypoints: optional route ``[n >= 2, 2]``; ``None`` predicts a straight line along the velocity.
        n_ps: number of prediction scenarios (odd, >= 1).
        probs: scenario probabilities ``[n_ps]`` (non-negative, summing to 1); ``None`` = uniform.
        weight: cost weight ``w_i >= 0``.
        zeta: track-loss modifier ``zeta_i >= 0`` (1 unless the track was lost).
        leg_speeds: optional speed [m/s] per leg of ``waypoints`` (``[len(waypoints) - 1]``, a shared plan's):
            the prediction follows each leg at its speed (after the last waypoint the last leg's); None: the
            present speed throughout.
        rule18: the obstacle has priority under COLREGS Rule 18 (not under command, restricted in its ability
            to manoeuvre, constrained by draught, fishing, sailing) as it shared; read by the Informed SB-MPC
            term (its P_R18 parameter set).
    """

    state: np.ndarray
    cov: np.ndarray
    length: float = 5.0
    width: float = 3.0
    waypoints: np.ndarray | None = None
    n_ps: int = 5
    probs: np.ndarray | None = None
    weight: float = 1.0
    zeta: float = 1.0
    rule18: bool = False
    leg_speeds: np.ndarray | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.rule18, (bool, np.bool_)):
            raise ValueError(f"obstacle.rule18 must be True or False, got {self.rule18!r}")
        object.__setattr__(self, "rule18", bool(self.rule18))
        state = checks.finite_array(self.state, "obstacle.state", (4,))
        v = float(np.hypot(state[2], state[3]))
        if v > MAX_OBSTACLE_SPEED_MPS:
            raise ValueError(f"obstacle.state velocity (V_x, V_y) = ({state[2]:g}, {state[3]:g}) is {v:g} m/s; at "
                             f"most {MAX_OBSTACLE_SPEED_MPS:g} m/s allowed (state is [x, y, V_x, V_y] in m and m/s: "
                             f"knots or km/h given as m/s, or [x, y, course, speed] by mistake?)")
        checks.local_positions(state[:2], "obstacle.state position (x, y)")
        object.__setattr__(self, "state", state)
        cov = checks.finite_array(self.cov, "obstacle.cov", (4, 4))
        _check_psd(cov, "obstacle.cov")
        pos_eig = np.linalg.eigvalsh(0.5 * (cov[:2, :2] + cov[:2, :2].T))
        if pos_eig.min() <= 0:
            raise ValueError(
                "obstacle.cov positional block cov[:2, :2] must be positive definite (a collision probability "
                f"needs a spread), got eigenvalues {pos_eig.tolist()}"
            )
        object.__setattr__(self, "cov", 0.5 * (cov + cov.T))
        object.__setattr__(self, "length", checks.hull(self.length, "obstacle.length", checks.MAX_SHIP_LENGTH_M))
        object.__setattr__(self, "width", checks.hull(self.width, "obstacle.width", checks.MAX_SHIP_WIDTH_M))
        if self.waypoints is not None:
            object.__setattr__(self, "waypoints", checks.local_positions(
                checks.waypoints(self.waypoints, "obstacle.waypoints", 2), "obstacle.waypoints"))
        if self.leg_speeds is not None:
            if self.waypoints is None:
                raise ValueError("obstacle.leg_speeds needs obstacle.waypoints (one speed per leg)")
            legs = checks.finite_array(self.leg_speeds, "obstacle.leg_speeds", (len(self.waypoints) - 1,))
            if np.any(legs < 0) or np.any(legs > MAX_OBSTACLE_SPEED_MPS):
                raise ValueError(f"obstacle.leg_speeds must be in [0, {MAX_OBSTACLE_SPEED_MPS:g}] m/s, got "
                                 f"{legs.tolist()}")
            object.__setattr__(self, "leg_speeds", legs)
        n_ps = self.n_ps
        if (isinstance(n_ps, (bool, np.bool_)) or not isinstance(n_ps, (int, np.integer)) or n_ps < 1
                or n_ps % 2 == 0):
            raise ValueError(f"obstacle.n_ps must be an odd integer >= 1, got {n_ps!r}")
        if n_ps > MAX_N_PS:
            raise ValueError(f"obstacle.n_ps must be an odd integer <= {MAX_N_PS}, got {checks.show(n_ps)}")
        object.__setattr__(self, "n_ps", int(n_ps))
        if self.probs is None:
            probs = np.full(n_ps, 1.0 / n_ps)
        else:
            probs = checks.finite_array(self.probs, "obstacle.probs", (n_ps,))
            if np.any(probs < 0) or abs(probs.sum() - 1.0) > 1e-6:
                raise ValueError(
                    f"obstacle.probs must be {n_ps} non-negative numbers summing to 1, got {probs.tolist()}"
                )
        object.__setattr__(self, "probs", probs)
        object.__setattr__(self, "weight", checks.positive(self.weight, "obstacle.weight", allow_zero=True))
        object.__setattr__(self, "zeta", checks.positive(self.zeta, "obstacle.zeta", allow_zero=True))


@dataclass(frozen=True)
class Situation:
    """Own-ship, dynamic obstacles and grounding polygons at the time of one solve (t_0 = 0)."""

    own_ship: OwnShip
    obstacles: tuple[Obstacle, ...] = field(default_factory=tuple)
    polygons: tuple[np.ndarray, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        if not isinstance(self.own_ship, OwnShip):
            raise ValueError(f"situation.own_ship must be an OwnShip, got {type(self.own_ship).__name__}")
        obstacles = _sequence(self.obstacles, "situation.obstacles", "Obstacle", Obstacle)
        for i, ob in enumerate(obstacles):
            if not isinstance(ob, Obstacle):
                raise ValueError(f"situation.obstacles[{i}] must be an Obstacle, got {type(ob).__name__}")
        object.__setattr__(self, "obstacles", obstacles)
        polygons = self.polygons
        if isinstance(polygons, np.ndarray) and polygons.ndim == 2:
            raise ValueError(f"situation.polygons must be a tuple/list of polygons, got one array of shape "
                             f"{polygons.shape}; pass (ring,) for a single polygon")
        if isinstance(polygons, (list, tuple)) and len(polygons) > 0 and _safe_ndim(polygons[0]) == 1:
            raise ValueError(f"situation.polygons must be a tuple/list of polygons, got a single ring of "
                             f"{len(polygons)} points; pass (ring,) for a single polygon")
        polys = []
        for j, poly in enumerate(_sequence(polygons, "situation.polygons", "polygons (rings [n, 2] or tuples of "
                                           "rings)")):
            polys.append(_polygon(poly, f"situation.polygons[{j}]"))
        object.__setattr__(self, "polygons", tuple(polys))
