"""Initialisation stage of Smooth-SBMPC (Mahipala & Johansen 2024, Sec. VI, Algorithms 1 and 2), one jitted
``lax.scan``.

At every inner step j = 0 .. N_init − 1 the original SB-MPC chooses one of the 39 behaviours (course offsets
−90 … 90° in 15° steps × speed factors {0.1, 0.5, 1}) by

    total_k = max_i max_{τ ≥ τ_j + T_s} (σ_coll C R + κ μ_FIS)_k  +  Γ_smooth(U*, χ*; Ū, χ̄)  +  k_NTP (N_init − N_TP,k)

over a prediction of T_init from the *inner* state (own-ship: LOS along the route, re-evaluated along each
prediction, choice SM-11 of docs/algorithm.md §12; targets: constant velocity, point objects); ties go to the first
behaviour in enumeration order. The chosen offsets are applied for one step of the kinematic model (13) and become the
"last" offsets of the next inner step (Alg. 1 prints this update reversed: choice SM-6); the targets advance by one
step of (14). The result is the trajectory Ψ (N_init + 1 states: choice SM-12) and the N_init applied offsets; rolled
out from the same start with :func:`psbmpc_jax.ownship.los_rollout` the offsets reproduce Ψ exactly (the route segment
is carried through the loop), which is what makes Ψ a feasible warm start of the DOCP (27).

Own-ship states are ``(x, y, χ, U)``; targets ``(x, y, χ, U)``; controls ``(U_m, χ_m)`` (speed factor, course
offset [rad]), the package's column order.
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..costs.manoeuvring import gamma_smooth
from ..costs.sbmpc import sbmpc_costs
from ..methods.smooth_settings import FisSpec, SmoothSpec
from ..ownship import los_rollout, make_path
from .land_hit import first_land_hit, land_clearance

#: Course offsets (26a) [deg] and speed factors (26b) of the 39 behaviours.
COURSE_OFFSETS_DEG = tuple(float(c) for c in range(-90, 91, 15))
SPEED_FACTORS = (0.1, 0.5, 1.0)

#: The DOCP's guidance frames (:mod:`psbmpc_jax.smooth.guidance`) and the corridor checks.
CHI_D_MODES = ("terminal_los", "route_los")
CORRIDOR_CHECKS = ("continuous", "samples")


def _positive(name, value):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")


@dataclasses.dataclass(frozen=True)
class SmoothSettings:
    """Static settings of Smooth-SBMPC (changing one recompiles).  Times in seconds, distances in metres.

    T_init, T_mpc: horizons of the initialisation stage and of the DOCP (T_init > T_mpc, both multiples of dt).
    dt: T_s, the discretisation step of both stages.  r_dom: ship-domain radius (N_TP and the corridor buffer).
    corridor_half_width: Δd.  terminal: ``"full"`` (x, y, χ, U), ``"position"`` or ``"soft"`` (a quadratic
    penalty ``terminal_weight`` instead of an equality).  fis_completion: ``"default_false"`` or ``"literal"``.
    n_y: output grid of the FIS defuzzification.
    chi_d_mode: the DOCP's guidance, ``"terminal_los"`` (LOS on the line from the ship through Ψ_N, the paper's;
    default) or ``"route_los"`` (the route's LOS, as the init stage).  corridor_land_buffer: b [m], the land
    buffer of the corridor (its ray cast and the clearance between samples), apart from r_dom.  corridor_check:
    ``"continuous"`` (the corridor plus the proven clearance bound of every plan segment,
    :mod:`psbmpc_jax.smooth.clearance`; default) or ``"samples"`` (the corridor at the samples only).

    The defaults shared with scenario files are defined once, by the ``mpc.smooth`` and ``mpc.fis`` sections
    (:class:`~psbmpc_jax.methods.smooth_settings.SmoothSpec`, :class:`~psbmpc_jax.methods.smooth_settings.FisSpec`)."""

    T_init: float = SmoothSpec.T_init
    T_mpc: float = SmoothSpec.T_mpc
    dt: float = SmoothSpec.dt
    r_dom: float = SmoothSpec.domain_radius
    corridor_half_width: float = SmoothSpec.corridor_half_width
    terminal: str = SmoothSpec.terminal
    terminal_weight: float = 10.0
    fis_completion: str = FisSpec.completion
    n_y: int = FisSpec.n_y
    chi_d_mode: str = SmoothSpec.chi_d_mode
    corridor_land_buffer: float = SmoothSpec.corridor_land_buffer
    corridor_check: str = SmoothSpec.corridor_check

    def __post_init__(self):
        for name in ("T_init", "T_mpc", "dt", "corridor_half_width", "terminal_weight"):
            _positive(name, getattr(self, name))
        if isinstance(self.r_dom, bool) or not isinstance(self.r_dom, (int, float)) or not self.r_dom >= 0:
            raise ValueError(f"r_dom must be a number >= 0, got {self.r_dom!r}")
        for name in ("T_init", "T_mpc"):
            n = getattr(self, name) / self.dt
            if abs(n - round(n)) > 1e-9 or round(n) < 1:
                raise ValueError(f"{name} must be a positive multiple of dt = {self.dt}, got {getattr(self, name)}")
        if not self.T_init > self.T_mpc:
            raise ValueError(f"T_init must be > T_mpc (the DOCP's terminal state comes from Psi), got "
                             f"T_init = {self.T_init}, T_mpc = {self.T_mpc}")
        if self.terminal not in ("full", "position", "soft"):
            raise ValueError(f"terminal must be one of 'full', 'position', 'soft', got {self.terminal!r}")
        if self.fis_completion not in ("default_false", "literal"):
            raise ValueError(f"fis_completion must be 'default_false' or 'literal', got {self.fis_completion!r}")
        if self.chi_d_mode not in CHI_D_MODES:
            raise ValueError(f"chi_d_mode must be one of {CHI_D_MODES}, got {self.chi_d_mode!r}")
        b = self.corridor_land_buffer
        if isinstance(b, bool) or not isinstance(b, (int, float)) or not math.isfinite(b) or b < 0:
            raise ValueError(f"corridor_land_buffer must be a finite number >= 0 [m], got {b!r}")
        if self.corridor_check not in CORRIDOR_CHECKS:
            raise ValueError(f"corridor_check must be one of {CORRIDOR_CHECKS}, got {self.corridor_check!r}")
        if isinstance(self.n_y, bool) or not isinstance(self.n_y, int) or self.n_y < 2:
            raise ValueError(f"n_y must be an integer >= 2, got {self.n_y!r}")

    @property
    def n_init(self) -> int:
        return int(round(self.T_init / self.dt))

    @property
    def n_mpc(self) -> int:
        return int(round(self.T_mpc / self.dt))


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class SmoothWeights:
    """Numeric tuning of the smooth costs (pytree leaves: a new value never recompiles). Defaults: our proposals where
    Mahipala & Johansen 2024 give none (d_safe 10 m, d_cl 40 m, e_cl = L_os = 5 m, K_coll 1 s²/m², κ 10, p 1, q 4, Γ
    weights of Tengesdal, Brekke & Johansen 2020, Table 1, k_NTP 1 per lost point, ε 1e-6)."""

    d_safe: float = 10.0
    K_coll: float = 1.0
    kappa: float = 10.0
    p: float = 1.0
    q: float = 4.0
    w_coll: float = 0.1
    d_cl: float = FisSpec.d_cl
    e_cl: float = FisSpec.e_cl
    eps: float = FisSpec.eps
    k_U: float = 2.5
    k_chi_port: float = 1.8
    k_chi_stbd: float = 1.5
    Delta_U: float = 2.0
    Delta_chi_port: float = 1.2
    Delta_chi_stbd: float = 0.9
    k_ntp: float = SmoothSpec.k_ntp


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class ShipModel:
    """Own-ship kinematic model (13) and LOS guidance: nominal speed U_d [m/s], LOS lookahead Δ and
    waypoint acceptance radius R_a [m], course and speed time constants T_χ, T_U [s]."""

    U_d: float = 1.0
    lookahead: float = 15.0
    R_a: float = 5.0
    T_chi: float = 3.0
    T_U: float = 5.0


class InitResult(NamedTuple):
    """Ψ ``[N_init + 1, 4]``, the applied offsets ``[N_init, 2]`` (U_m, χ_m), the chosen behaviour's total cost
    and N_TP per inner step ``[N_init]``, the route segment at each state of Ψ ``[N_init + 1]`` and the total
    cost of every behaviour at τ₀ (the first inner step, ``[39]``: the multi-start of the DOCP takes its best
    constant behaviours from it)."""

    psi: jax.Array
    controls: jax.Array
    cost: jax.Array
    n_tp: jax.Array
    segment: jax.Array
    first_cost: jax.Array


def behaviour_table(dtype=jnp.float32) -> jax.Array:
    """The 39 behaviours ``[39, 2]`` (U*, χ* [rad]), course-major (ties: first in this order)."""
    return jnp.asarray([(u, math.radians(c)) for c in COURSE_OFFSETS_DEG for u in SPEED_FACTORS], dtype)


def route_path(route):
    """A single-row :class:`~psbmpc_jax.ownship.Path` of the route ``[W >= 2, 2]``."""
    route = jnp.asarray(route)
    return make_path(route[None, :, 0], route[None, :, 1], jnp.asarray([route.shape[0]], jnp.int32))


def target_predictions(targets, t):
    """Constant-velocity (14) target states ``[T, I, 4]`` at times ``t [T]`` from ``targets [I, 4]``."""
    x, y, chi, U = (targets[:, k] for k in range(4))
    tt = t[:, None]
    return jnp.stack([x + U * jnp.cos(chi) * tt, y + U * jnp.sin(chi) * tt,
                      jnp.broadcast_to(chi, tt.shape[:1] + chi.shape), jnp.broadcast_to(U, tt.shape[:1] + U.shape)],
                     axis=-1)


def rollout_controls(x0, path, controls, model: ShipModel, dt, z0=0, return_segment=False, unroll=1):
    """Own-ship states ``[N + 1, 4]`` of (13) with LOS along ``path`` under per-step controls ``[N, 2]``
    (``unroll``: of the scan; ``True`` unrolls it fully, which lets XLA fuse a short horizon into a few
    kernels)."""
    n = controls.shape[0]
    out = los_rollout(x0[None, :], path, controls[:, 1:2], model.U_d * controls[:, 0:1],
                      jnp.zeros((1,), x0.dtype), model.lookahead, model.R_a, model.T_chi, model.T_U, dt,
                      z0=jnp.asarray(z0, jnp.int32)[None], return_segment=True, unroll=unroll)
    traj, seg = out
    states = jnp.stack([traj.x[:, 0], traj.y[:, 0], traj.chi[:, 0], traj.U[:, 0]], axis=-1)[:n + 1]
    return (states, seg[:n + 1, 0]) if return_segment else states


def pair_kwargs(weights: SmoothWeights, settings: SmoothSettings) -> dict:
    return dict(d_safe=weights.d_safe, K_coll=weights.K_coll, p=weights.p, q=weights.q, w_coll=weights.w_coll,
                d_cl=weights.d_cl, e_cl=weights.e_cl, eps=weights.eps, n_y=settings.n_y,
                completion=settings.fis_completion)


def gamma_weights(weights: SmoothWeights) -> dict:
    return dict(k_U=weights.k_U, k_chi_port=weights.k_chi_port, k_chi_stbd=weights.k_chi_stbd,
                Delta_U=weights.Delta_U, Delta_chi_port=weights.Delta_chi_port, Delta_chi_stbd=weights.Delta_chi_stbd)


#: Choice SM-16 (our addition, docs/algorithm.md §12): when the inner state is already within r_dom of land, the N_TP
#: test uses this fraction of its present clearance as the domain radius.
DOMAIN_SHRINK = 0.9


def domain_radius(state, chart, r_dom):
    """The ship-domain radius of the N_TP test at one inner state (choice SM-16, docs/smooth_sbmpc.md):
    ``min(r_dom, DOMAIN_SHRINK · clearance)``, clearance = the state's distance to land.  With the plain r_dom a
    state already closer than r_dom to land (a closed loop that follows a plan along the corridor's edge ends
    there by millimetres of tracking error) flags point 0 of every behaviour: N_TP = 0 for all 39, the penalty
    no longer tells them apart, and the search picks by Γ alone, back towards the route and into land
    (measured: 16 of 20 groundings in the reconstructed 000 scenario).  With the shrunk radius the behaviours
    that close in further are still penalised and those that keep or open the distance are not.  Inside land
    (clearance 0) the radius is 0: point 0 is flagged for all behaviours, as before."""
    r_dom = jnp.asarray(r_dom, state.dtype)
    clearance = land_clearance(state[:2], chart, r_dom)          # capped at r_dom
    return jnp.where(clearance < r_dom, DOMAIN_SHRINK * clearance, r_dom)


def behaviour_costs(state, z, targets, last, path, chart, weights: SmoothWeights, model: ShipModel,
                    settings: SmoothSettings):
    """Algorithm 2 for one inner state: ``(total [39], n_tp [39], hazard [39], gamma [39])``."""
    n = settings.n_init
    table = behaviour_table(state.dtype)
    n_b = table.shape[0]
    chi_off = jnp.broadcast_to(table[:, 1], (n, n_b))
    u_cmd = jnp.broadcast_to(model.U_d * table[:, 0], (n, n_b))
    traj = los_rollout(jnp.broadcast_to(state, (n_b, 4)), path, chi_off, u_cmd, jnp.zeros((n_b,), state.dtype),
                       model.lookahead, model.R_a, model.T_chi, model.T_U, settings.dt,
                       z0=jnp.broadcast_to(z, (n_b,)))
    own = jnp.stack([traj.x, traj.y, traj.chi, traj.U], axis=-1).transpose(1, 0, 2)   # [39, N + 1, 4]
    t = jnp.arange(n + 1, dtype=state.dtype) * settings.dt
    if targets.shape[0]:
        tg = target_predictions(targets, t)
        hazard = jax.vmap(lambda o: sbmpc_costs(o, tg, t, aggregation="max", kappa=weights.kappa,
                                                **pair_kwargs(weights, settings))["joint"])(own)
    else:
        hazard = jnp.zeros((n_b,), state.dtype)
    gamma = gamma_smooth(table[:, 0], table[:, 1], last[0], last[1], **gamma_weights(weights))
    n_tp = first_land_hit(own[..., :2], chart, domain_radius(state, chart, settings.r_dom))
    total = hazard + gamma + weights.k_ntp * (n - n_tp).astype(state.dtype)
    return total, n_tp, hazard, gamma


def init_stage_traced(state0, route, targets, last, chart, weights, model, settings: SmoothSettings,
                      segment=0) -> InitResult:
    """Traceable Algorithm 1 (no validation): see :func:`init_stage`.  ``segment``: the active route segment at
    τ₀ (int32 scalar, may be traced)."""
    path = route_path(route)
    table = behaviour_table(state0.dtype)
    dt = settings.dt
    z0 = jnp.asarray(segment, jnp.int32)

    def step(carry, _):
        state, z, tg, lst = carry
        total, n_tp, _, _ = behaviour_costs(state, z, tg, lst, path, chart, weights, model, settings)
        k = jnp.argmin(total)                                    # ties: the first in enumeration order
        u = table[k]
        states, seg = rollout_controls(state, path, u[None, :], model, dt, z0=z, return_segment=True)
        x, yv, chi, U = (tg[:, i] for i in range(4))
        tg_next = jnp.stack([x + U * jnp.cos(chi) * dt, yv + U * jnp.sin(chi) * dt, chi, U], axis=-1)
        return (states[1], seg[1], tg_next, u), (states[1], u, total[k], n_tp[k], seg[1], total)

    init = (state0, z0, targets, last)
    _, (states, controls, cost, n_tp, seg, totals) = jax.lax.scan(step, init, None, length=settings.n_init)
    psi = jnp.concatenate([state0[None, :], states], axis=0)
    return InitResult(psi, controls, cost, n_tp, jnp.concatenate([z0[None], seg]), totals[0])


_init_stage_jit = jax.jit(init_stage_traced, static_argnames=("settings",))


def check_segment(segment, n_waypoints: int, name: str = "segment") -> int:
    """A concrete active-segment index: an integer in [0, W − 2] (``W`` waypoints); returns it as ``int``."""
    arr = None if isinstance(segment, jax.core.Tracer) else np.asarray(segment)
    if arr is None or arr.ndim != 0 or not np.issubdtype(arr.dtype, np.integer):
        raise ValueError(f"{name} must be an integer route-segment index, got {segment!r}")
    z = int(arr)
    if not 0 <= z <= n_waypoints - 2:
        raise ValueError(f"{name} must be in [0, {n_waypoints - 2}] (segment z runs from waypoint z to z + 1 of "
                         f"the {n_waypoints} waypoints), got {z}")
    return z


def init_stage(state0, route, targets, last, chart, weights: SmoothWeights = SmoothWeights(),
               model: ShipModel = ShipModel(), settings: SmoothSettings = SmoothSettings(),
               segment: int = 0) -> InitResult:
    """Algorithm 1 (jitted): Ψ and the applied offsets over T_init.

    Args:
        state0: own-ship state ``[4]`` (x, y, χ, U) at τ₀.
        route: own-ship waypoints ``[W >= 2, 2]`` (the whole route).
        targets: target states ``[I, 4]`` (x, y, χ, U), point objects, constant velocity; ``I`` may be 0.
        last: the last applied offsets ``[2]`` (U_m,last, χ_m,last).
        chart: the land polygons packed by :func:`psbmpc_jax.packing.pack_world` (``ChartArrays`` or
            ``WorldArrays``), unbuffered: N_TP uses the ship-domain radius ``settings.r_dom``.
        segment: the active route segment at τ₀ (0 ≤ segment ≤ W − 2: from waypoint ``segment`` to the next);
            a value, not a shape, so runs on different segments share one compilation.
    """
    if not isinstance(settings, SmoothSettings):
        raise ValueError(f"settings must be a SmoothSettings, got {type(settings).__name__}")
    state0 = jnp.asarray(state0)
    dtype = state0.dtype if jnp.issubdtype(state0.dtype, jnp.floating) else jnp.float32
    state0 = state0.astype(dtype)
    route, targets, last = (jnp.asarray(a, dtype) for a in (route, targets, last))
    if state0.shape != (4,):
        raise ValueError(f"state0 must be [4] (x, y, chi, U), got shape {state0.shape}")
    if route.ndim != 2 or route.shape[1] != 2 or route.shape[0] < 2:
        raise ValueError(f"route must be [W >= 2, 2] waypoints, got shape {route.shape}")
    if targets.ndim != 2 or targets.shape[1] != 4:
        raise ValueError(f"targets must be [I, 4] (x, y, chi, U), got shape {targets.shape}")
    if last.shape != (2,):
        raise ValueError(f"last must be [2] (U_m, chi_m), got shape {last.shape}")
    z = check_segment(segment, route.shape[0])
    return _init_stage_jit(state0, route, targets, last, chart, weights, model, settings, jnp.asarray(z, jnp.int32))
