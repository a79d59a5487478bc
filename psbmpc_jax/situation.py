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

Every constructor validates its input and raises ``ValueError`` naming the field and what is allowed.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import checks


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
    return arr


def _polygon(value, name: str):
    """A polygon is one ring ``[n, 2]`` or a tuple of rings (outer ring first, then holes)."""
    if isinstance(value, (list, tuple)) and len(value) > 0 and np.ndim(value[0]) == 2:
        return tuple(_ring(r, f"{name}[{k}]") for k, r in enumerate(value))
    return _ring(value, name)


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
        object.__setattr__(self, "state", state)
        object.__setattr__(self, "waypoints", checks.waypoints(self.waypoints, "own_ship.waypoints", 2))
        object.__setattr__(self, "U_d", checks.positive(self.U_d, "own_ship.U_d", allow_zero=True))
        object.__setattr__(self, "length", checks.positive(self.length, "own_ship.length"))
        object.__setattr__(self, "width", checks.positive(self.width, "own_ship.width"))


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

    def __post_init__(self) -> None:
        object.__setattr__(self, "state", checks.finite_array(self.state, "obstacle.state", (4,)))
        cov = checks.finite_array(self.cov, "obstacle.cov", (4, 4))
        _check_psd(cov, "obstacle.cov")
        pos_eig = np.linalg.eigvalsh(0.5 * (cov[:2, :2] + cov[:2, :2].T))
        if pos_eig.min() <= 0:
            raise ValueError(
                "obstacle.cov positional block cov[:2, :2] must be positive definite (a collision probability "
                f"needs a spread), got eigenvalues {pos_eig.tolist()}"
            )
        object.__setattr__(self, "cov", 0.5 * (cov + cov.T))
        object.__setattr__(self, "length", checks.positive(self.length, "obstacle.length"))
        object.__setattr__(self, "width", checks.positive(self.width, "obstacle.width"))
        if self.waypoints is not None:
            object.__setattr__(self, "waypoints", checks.waypoints(self.waypoints, "obstacle.waypoints", 2))
        n_ps = self.n_ps
        if isinstance(n_ps, bool) or not isinstance(n_ps, (int, np.integer)) or n_ps < 1 or n_ps % 2 == 0:
            raise ValueError(f"obstacle.n_ps must be an odd integer >= 1, got {n_ps!r}")
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
        obstacles = tuple(self.obstacles)
        for i, ob in enumerate(obstacles):
            if not isinstance(ob, Obstacle):
                raise ValueError(f"situation.obstacles[{i}] must be an Obstacle, got {type(ob).__name__}")
        object.__setattr__(self, "obstacles", obstacles)
        polys = []
        for j, poly in enumerate(self.polygons):
            polys.append(_polygon(poly, f"situation.polygons[{j}]"))
        object.__setattr__(self, "polygons", tuple(polys))
