"""The upper level of the two-level MPC (Mahipala & Johansen 2023, Sec. IV, eqs. 5–12): a path-following NMPC on the
project's JAX NLP core (:mod:`psbmpc_jax.nlp`).

Decision: the absolute course and speed commands u_k = (χ_d,k, U_d,k), k = 0..N_p−1 (single shooting; the
states follow from x₀ by RK4 of the continuous form of the paper's model (1), which is printed without dt (choice
TL-1, docs/algorithm.md §15)

    ẋ = U cos χ,  ẏ = U sin χ,  χ̇ = wrap(χ_d − χ)/T_χ,  U̇ = (U_d − U)/T_U        (NED, χ from north)

over the MPC step).  Single shooting has the same optimum as the paper's multiple shooting (the defect
constraints (8) are eliminated exactly) with 2 N_p instead of 6 N_p + 4 unknowns; see docs/two_level.md.

Cost (7), with our reading of its index ranges (choice TL-3: every move including the first, from the applied
command):

    Σ_{k=1}^{N_p} ‖x_k − x_ref‖²_Q + Σ_{k=0}^{N_p−1} ‖u_k − u_{k−1}‖²_M,   u_{−1} = the applied command

with x_ref = (WP_{j+1}, ψ_j, U_ref) (the next waypoint, the leg angle, the cruise speed) and the course
errors wrapped.  Constraints: the box (9) χ_d ∈ [ψ_j − χ_span, ψ_j + χ_span] (unwrapped around the leg
angle; default χ_span 90°), U_d ∈ [0, U_max]; the static circles (10)/(12) ‖p_k − c_i‖ ≥ r_i + r_os; the
riparian corridor (11) lower_j(s) ≤ y_p ≤ upper_j(s) in the frame of the leg each predicted point is on
(the current leg while x_p ≤ l_j, the next one after), the bounds piecewise linear in the along-track s
(choice TL-4: the corridor is sampled at other points than the MPC steps). The augmented-Lagrangian solver
(:func:`psbmpc_jax.nlp.solve_docp`) handles both inequality sets; the box is exact (reparametrised).
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..methods.two_level_settings import TwoLevelSpec
from ..nlp import STATUS_NAMES, SolverSettings, max_violation, solve_docp
from ..status import Status
from ..numerics import wrap_angle as wrap
from .path_frame import to_leg_frame
from .static_obstacles import StaticCircles, circle_residuals


@dataclasses.dataclass(frozen=True)
class PathMpcSettings:
    """Tuning of the upper level (defaults: our proposals where Mahipala & Johansen 2023 give no values).

    Attributes:
        N_p: prediction steps (static).
        dt: MPC step [s].
        Q: weights of (x, y, χ, U) errors to the reference (position weights small: x_ref is the waypoint).
        M: weights of the (χ_d, U_d) changes between steps.
        chi_span: half-width of the course box around the leg angle [rad] (< π).
        U_max: speed-command upper bound [m/s].
        T_chi, T_U: course and speed time constants of the model [s].
        r_os: radius of the circle enclosing the own-ship [m] (added to every static circle).
        rk4_substeps: RK4 substeps per MPC step (static).

    The defaults shared with scenario files are defined once, by the ``mpc.two_level`` section
    (:class:`~psbmpc_jax.methods.two_level_settings.TwoLevelSpec`).
    """

    N_p: int = TwoLevelSpec.N_p
    dt: float = TwoLevelSpec.dt
    Q: tuple = TwoLevelSpec.Q
    M: tuple = TwoLevelSpec.M
    chi_span: float = TwoLevelSpec.chi_span
    U_max: float = TwoLevelSpec.U_max
    T_chi: float = 3.0
    T_U: float = 5.0
    r_os: float = TwoLevelSpec.r_os
    rk4_substeps: int = 1

    def __post_init__(self):
        for name in ("N_p", "rk4_substeps"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise ValueError(f"PathMpcSettings.{name} must be an integer >= 1, got {v!r}")
        for name in ("dt", "U_max", "T_chi", "T_U"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
                raise ValueError(f"PathMpcSettings.{name} must be a finite number > 0, got {v!r}")
        if isinstance(self.r_os, bool) or not isinstance(self.r_os, (int, float)) or not (
                math.isfinite(self.r_os) and self.r_os >= 0):
            raise ValueError(f"PathMpcSettings.r_os must be a finite number >= 0, got {self.r_os!r}")
        if not (isinstance(self.chi_span, (int, float)) and 0 < self.chi_span < math.pi):
            raise ValueError(f"PathMpcSettings.chi_span must be in (0, pi) rad, got {self.chi_span!r}")
        for name, n in (("Q", 4), ("M", 2)):
            v = getattr(self, name)
            try:
                arr = np.asarray(v, dtype=float)
            except (TypeError, ValueError):
                arr = None
            if arr is None or arr.shape != (n,) or not np.all(np.isfinite(arr)) or np.any(arr < 0):
                raise ValueError(f"PathMpcSettings.{name} must be {n} finite weights >= 0, got {v!r}")
            object.__setattr__(self, name, tuple(float(x) for x in arr))


class Legs(NamedTuple):
    """The route as the upper level sees it (device arrays, fixed shapes): waypoints ``wp [L+1, 2]``, leg
    angles ``psi [L]`` and lengths ``length [L]``, and per leg its corridor samples ``s [L, S]`` (along-track,
    increasing) with the cross-track bounds ``lower [L, S]`` (≤ 0, port) and ``upper [L, S]`` (≥ 0,
    starboard).  A leg without land nearby has the bounds ±half-width."""

    wp: jax.Array
    psi: jax.Array
    length: jax.Array
    s: jax.Array
    lower: jax.Array
    upper: jax.Array


class Circles(NamedTuple):
    """Static obstacles: ``centre [C, 2]``, ``radius [C]`` (C may be 0)."""

    centre: jax.Array
    radius: jax.Array


class PathMpcData(NamedTuple):
    """One solve's data (a pytree; new values never recompile): own state ``x0 = (x, y, χ, U)``, the applied
    command ``u_prev = (χ, U)``, the active leg ``j`` (int32), the cruise speed ``U_ref``, the route and the
    static circles."""

    x0: jax.Array
    u_prev: jax.Array
    j: jax.Array
    U_ref: jax.Array
    legs: Legs
    circles: Circles


class PathMpcResult(NamedTuple):
    """``u [N_p, 2]`` (χ_d, U_d), predicted states ``x [N_p+1, 4]``, the cost, the max constraint violation
    [m], the solver status (0 ok/converged, 3 max-iter, 4 infeasible, 5 non-finite: :class:`psbmpc_jax.status.Status`) and iteration counts."""

    u: jax.Array
    x: jax.Array
    cost: jax.Array
    violation: jax.Array
    status: jax.Array
    outer: jax.Array
    inner: jax.Array


def model_rhs(x, u, T_chi, T_U):
    chi, U = x[..., 2], x[..., 3]
    return jnp.stack([U * jnp.cos(chi), U * jnp.sin(chi), wrap(u[..., 0] - chi) / T_chi,
                      (u[..., 1] - U) / T_U], axis=-1)


def rk4_step(x, u, h, T_chi, T_U):
    k1 = model_rhs(x, u, T_chi, T_U)
    k2 = model_rhs(x + 0.5 * h * k1, u, T_chi, T_U)
    k3 = model_rhs(x + 0.5 * h * k2, u, T_chi, T_U)
    k4 = model_rhs(x + h * k3, u, T_chi, T_U)
    return x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


def rollout(x0, u, settings: PathMpcSettings):
    """States ``[N_p + 1, 4]`` from ``x0`` under ``u [N_p, 2]`` (RK4, ``rk4_substeps`` per MPC step)."""
    h = settings.dt / settings.rk4_substeps
    dtype = jnp.result_type(x0, u)                 # the line search may hand over promoted iterates
    x0, u = jnp.asarray(x0, dtype), jnp.asarray(u, dtype)

    def step(x, uk):
        for _ in range(settings.rk4_substeps):
            x = rk4_step(x, uk, h, settings.T_chi, settings.T_U)
        return x, x

    _, xs = jax.lax.scan(step, x0, u)
    return jnp.concatenate([x0[None], xs], axis=0)


def path_coordinates(p, wp, psi):
    """(x_p, y_p) of positions ``p [..., 2]`` in the frame of a leg starting at ``wp`` with angle ``psi``
    (eq. 3, :func:`~psbmpc_jax.two_level.path_frame.to_leg_frame`: y_p > 0 to starboard)."""
    q = to_leg_frame(p, wp, psi)
    return q[..., 0], q[..., 1]


def _leg(legs: Legs, j):
    return (legs.wp[j], legs.psi[j], legs.length[j], legs.s[j], legs.lower[j], legs.upper[j])


def corridor_residuals(p, legs: Legs, j):
    """Eq. (11) residuals ``[K, 2]`` (≤ 0 feasible) of positions ``p [K, 2]``: each point in the frame of leg
    j while its x_p ≤ l_j, else of leg j + 1 (when there is one)."""
    n_legs = legs.psi.shape[0]
    jn = jnp.minimum(j + 1, n_legs - 1)

    def res(leg):
        wp, psi, _, s, lo, hi = leg
        xp, yp = path_coordinates(p, wp, psi)
        return jnp.stack([yp - jnp.interp(xp, s, hi), jnp.interp(xp, s, lo) - yp], axis=-1), xp

    r_here, xp_here = res(_leg(legs, j))
    r_next, _ = res(_leg(legs, jn))
    beyond = (xp_here > legs.length[j]) & (jn != j)
    return jnp.where(beyond[:, None], r_next, r_here)


def _reference(data: PathMpcData):
    n_legs = data.legs.psi.shape[0]
    j = jnp.clip(data.j, 0, n_legs - 1)
    return jnp.concatenate([data.legs.wp[j + 1], data.legs.psi[j][None], data.U_ref[None]])


def path_mpc_cost(u, data: PathMpcData, settings: PathMpcSettings):
    """Eq. (7) (our reading TL-3: every move including the first, course errors wrapped)."""
    x = rollout(data.x0, u, settings)[1:]
    ref = _reference(data)
    e = x - ref
    e = e.at[:, 2].set(wrap(e[:, 2]))
    Q, M = jnp.asarray(settings.Q, u.dtype), jnp.asarray(settings.M, u.dtype)
    du = jnp.diff(jnp.concatenate([data.u_prev[None], u], axis=0), axis=0)
    du = du.at[:, 0].set(wrap(du[:, 0]))
    return jnp.sum(e * e * Q) + jnp.sum(du * du * M)


def path_mpc_ineq(u, data: PathMpcData, settings: PathMpcSettings):
    """Corridor (11) and circle (10) residuals of the predicted positions k = 1..N_p, raveled (≤ 0)."""
    p = rollout(data.x0, u, settings)[1:, :2]
    parts = [corridor_residuals(p, data.legs, data.j).ravel()]
    if data.circles.radius.shape[0]:
        parts.append(circle_residuals(p, StaticCircles(data.circles.centre, data.circles.radius),
                                      settings.r_os).ravel())
    return jnp.concatenate(parts)


def _problem(settings: PathMpcSettings):
    """(f, ineq) closed over the static settings; cached so that the solver's jit cache (keyed by the
    functions' identity) is reused across solves."""
    return _PROBLEMS.setdefault(settings, (lambda u, d: path_mpc_cost(u, d, settings),
                                           lambda u, d: path_mpc_ineq(u, d, settings)))


_PROBLEMS: dict = {}


def command_box(data: PathMpcData, settings: PathMpcSettings, dtype):
    """Bounds (9) of u: χ_d within ±chi_span of the active leg angle, U_d in [0, U_max]."""
    n_legs = data.legs.psi.shape[0]
    psi = data.legs.psi[jnp.clip(data.j, 0, n_legs - 1)]
    lo = jnp.stack([psi - settings.chi_span, jnp.zeros_like(psi)])
    hi = jnp.stack([psi + settings.chi_span, jnp.full_like(psi, settings.U_max)])
    shape = (settings.N_p, 2)
    return jnp.broadcast_to(lo.astype(dtype), shape), jnp.broadcast_to(hi.astype(dtype), shape)


def unwrap_near(chi, centre):
    """χ moved by whole turns to within π of ``centre``."""
    return centre + wrap(chi - centre)


def warm_start(data: PathMpcData, settings: PathMpcSettings, previous=None):
    """The previous solution shifted one step (its last command held), or — without one — the applied
    command held; courses unwrapped around the active leg angle and clipped into the box."""
    lo, hi = command_box(data, settings, data.x0.dtype)
    psi = (lo[0, 0] + hi[0, 0]) / 2
    if previous is None:
        u0 = jnp.broadcast_to(data.u_prev, (settings.N_p, 2))
    else:
        prev = jnp.asarray(previous, data.x0.dtype)
        u0 = jnp.concatenate([prev[1:], prev[-1:]], axis=0)
    u0 = jnp.stack([unwrap_near(u0[:, 0], psi), u0[:, 1]], axis=-1)
    return jnp.clip(u0, lo, hi)


def _solve(data: PathMpcData, u0, settings: PathMpcSettings, solver: SolverSettings) -> PathMpcResult:
    f, ineq = _problem(settings)
    lo, hi = command_box(data, settings, u0.dtype)
    res = solve_docp.jitted(f, u0, lo, hi, None, ineq, solver, data)
    x = rollout(data.x0, res.u, settings)
    viol = max_violation(res.u, lower=lo, upper=hi, ineq=ineq, args=data)
    return PathMpcResult(res.u, x, res.f, viol, res.status, res.outer_iterations, res.inner_iterations)


_solve_jit = jax.jit(_solve, static_argnames=("settings",))

#: Solver defaults of the upper level (measured on the straight-channel and island tests).
DEFAULT_SOLVER = SolverSettings(max_outer=15, max_inner=60, tol=1e-3)


def solve_path_mpc(data: PathMpcData, settings: PathMpcSettings = PathMpcSettings(), *, previous=None,
                   solver: SolverSettings = DEFAULT_SOLVER) -> PathMpcResult:
    """One upper-level solve (jitted; new data values never recompile).  ``previous``: the last solution's
    ``u [N_p, 2]`` (warm start, shifted by one step)."""
    if not isinstance(settings, PathMpcSettings):
        raise ValueError(f"settings must be a PathMpcSettings, got {type(settings).__name__}")
    if not isinstance(solver, SolverSettings):
        raise ValueError(f"solver must be a psbmpc_jax.nlp.SolverSettings, got {type(solver).__name__}")
    check_data(data)
    if previous is not None and np.shape(previous) != (settings.N_p, 2):
        raise ValueError(f"previous must have shape ({settings.N_p}, 2) (N_p, [chi_d, U_d]), got "
                         f"{np.shape(previous)}")
    u0 = warm_start(data, settings, previous)
    return _solve_jit(data, u0, settings, solver)


def check_data(data: PathMpcData) -> None:
    """Host-side validation of a :class:`PathMpcData` (``ValueError`` naming the field)."""
    if not isinstance(data, PathMpcData):
        raise ValueError(f"data must be a PathMpcData, got {type(data).__name__}")
    legs = data.legs
    L = np.shape(legs.psi)[0] if np.ndim(legs.psi) == 1 else -1
    if L < 1 or np.shape(legs.wp) != (L + 1, 2):
        raise ValueError(f"legs.wp must be [L+1, 2] and legs.psi [L] with L >= 1, got {np.shape(legs.wp)} and "
                         f"{np.shape(legs.psi)}")
    S = np.shape(legs.s)
    if len(S) != 2 or S[0] != L or S[1] < 2 or np.shape(legs.lower) != S or np.shape(legs.upper) != S:
        raise ValueError(f"legs.s, legs.lower, legs.upper must all be [L, S] with S >= 2 (L = {L}), got "
                         f"{np.shape(legs.s)}, {np.shape(legs.lower)}, {np.shape(legs.upper)}")
    for name, arr in (("legs.wp", legs.wp), ("legs.s", legs.s), ("legs.lower", legs.lower),
                      ("legs.upper", legs.upper), ("x0", data.x0), ("u_prev", data.u_prev)):
        if not isinstance(arr, jax.core.Tracer) and not np.all(np.isfinite(np.asarray(arr))):
            raise ValueError(f"{name} must be finite")
    if np.shape(data.x0) != (4,) or np.shape(data.u_prev) != (2,):
        raise ValueError(f"x0 must be [4] (x, y, chi, U) and u_prev [2] (chi, U), got {np.shape(data.x0)} and "
                         f"{np.shape(data.u_prev)}")
    if not isinstance(data.j, jax.core.Tracer) and not 0 <= int(data.j) < L:
        raise ValueError(f"j (active leg) must be in 0..{L - 1}, got {int(data.j)}")
    c = data.circles
    if np.ndim(c.centre) != 2 or np.shape(c.centre)[1:] != (2,) or np.shape(c.radius) != np.shape(c.centre)[:1]:
        raise ValueError(f"circles.centre must be [C, 2] and circles.radius [C], got {np.shape(c.centre)} and "
                         f"{np.shape(c.radius)}")


def make_legs(waypoints, corridors=None, *, half_width: float = 50.0, n_samples: int = 2, dtype=None) -> Legs:
    """:class:`Legs` from ``waypoints [L+1, 2]`` and per leg its corridor ``(s, lower, upper)`` (NumPy, any
    common length; None: the band ±``half_width`` on every leg).  All legs are resampled to one length S."""
    wp = np.asarray(waypoints, dtype=float)
    if wp.ndim != 2 or wp.shape[1] != 2 or wp.shape[0] < 2 or not np.all(np.isfinite(wp)):
        raise ValueError(f"waypoints must be a finite [n >= 2, 2] array (north, east) [m], got shape {wp.shape}")
    d = np.diff(wp, axis=0)
    length = np.hypot(d[:, 0], d[:, 1])
    if np.any(length <= 0):
        raise ValueError(f"waypoints: leg {int(np.argmin(length))} has zero length")
    psi = np.arctan2(d[:, 1], d[:, 0])
    L = len(psi)
    if corridors is None:
        corridors = [(np.array([0.0, length[j]]), np.full(2, -half_width), np.full(2, half_width))
                     for j in range(L)]
    if len(corridors) != L:
        raise ValueError(f"corridors: one (s, lower, upper) per leg expected ({L}), got {len(corridors)}")
    S = max(max(len(c[0]) for c in corridors), n_samples)
    s_all, lo_all, hi_all = [], [], []
    for j, (s, lo, hi) in enumerate(corridors):
        s, lo, hi = (np.asarray(a, dtype=float) for a in (s, lo, hi))
        if s.ndim != 1 or len(s) < 2 or lo.shape != s.shape or hi.shape != s.shape or np.any(np.diff(s) <= 0):
            raise ValueError(f"corridors[{j}]: s must be increasing with >= 2 samples and lower/upper the same "
                             f"shape, got {s.shape}, {lo.shape}, {hi.shape}")
        if np.any(lo > 0) or np.any(hi < 0):
            raise ValueError(f"corridors[{j}]: lower must be <= 0 and upper >= 0 (cross-track bounds)")
        grid = np.linspace(s[0], s[-1], S)
        s_all.append(grid)
        lo_all.append(np.interp(grid, s, lo))
        hi_all.append(np.interp(grid, s, hi))
    as_j = (lambda a: jnp.asarray(a, dtype)) if dtype is not None else jnp.asarray
    return Legs(as_j(wp), as_j(psi), as_j(length), as_j(np.stack(s_all)), as_j(np.stack(lo_all)),
                as_j(np.stack(hi_all)))


def make_circles(centres=None, radii=None, dtype=None) -> Circles:
    c = np.zeros((0, 2)) if centres is None else np.asarray(centres, dtype=float).reshape(-1, 2)
    r = np.zeros(0) if radii is None else np.asarray(radii, dtype=float).reshape(-1)
    if r.shape != c.shape[:1] or not np.all(np.isfinite(c)) or np.any(~np.isfinite(r) | (r <= 0)):
        raise ValueError(f"static circles: centres [C, 2] and radii [C] > 0 expected, got {c.shape}, {r.shape}")
    as_j = (lambda a: jnp.asarray(a, dtype)) if dtype is not None else jnp.asarray
    return Circles(as_j(c), as_j(r))


def status_name(result: PathMpcResult) -> str:
    return STATUS_NAMES[Status(int(result.status))]


__all__ = ["PathMpcSettings", "PathMpcData", "PathMpcResult", "Legs", "Circles", "DEFAULT_SOLVER", "rollout",
           "rk4_step", "path_coordinates", "path_mpc_cost", "path_mpc_ineq", "corridor_residuals", "command_box",
           "warm_start", "solve_path_mpc", "check_data", "make_legs", "make_circles", "status_name", "unwrap_near"]
