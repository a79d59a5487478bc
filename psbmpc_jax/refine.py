"""PSB-MPC + refinement: a gradient-based DOCP on a smooth form of the PSB-MPC cost, warm-started from the best
behaviours of the grid search (docs/refine.md).

>>> plan, next_state, ev = solve(inputs, state, params, samples, config=config)
>>> ref = refine(inputs, plan, state, params, samples, config, RefineSettings(), evaluation=ev)
>>> ref.apply          # (speed factor, course offset) to apply now; ref.controls [N, 2] per step

``state`` is the planner state passed TO the solve (its ``last_offsets`` are the previously applied offsets the
path cost compares with), not the one the solve returned.

Problem (one per warm start, solved by :func:`psbmpc_jax.nlp.solve_docp`; L-BFGS on the box map)::

    minimise  J_s(u)  over the per-step controls of the first N_r = T_refine / dt steps (blocks of
              ``block`` steps share one control), the rest of the horizon following the warm behaviour
    s.t.      min(table speeds) <= u_k <= max(table speeds),  min(table courses) <= chi_k <= max(table courses)

J_s is :func:`psbmpc_jax.objective.objective` with ``per_step=True, smooth=True`` and the smooth terms
(:func:`smooth_terms`): the collision term through the quadrature estimator (:class:`FastCollisionTerm`, the same
cost evaluated faster), the grounding term (exact or grid), the fuzzy COLREGS term
:class:`ScenarioFuzzyColregsTerm` in place of the Boolean indicator (or none), and the path term with a smoothed
|Δu| (:class:`SmoothPathTerm`).  The control-independent parts of the context (obstacle scenarios, covariances)
are computed once per call, not per evaluation; the maxima over time are differentiated at their maximiser only
(docs/refine.md, "Cost of one evaluation").

Multi-start: the ``n_starts`` best behaviours by the grid's own ranking (the selected one first), solved with
``lax.map`` (``batch="map"``) or ``vmap``; the best feasible result is kept (:func:`psbmpc_jax.nlp.best_index`)
and then safeguarded (:func:`psbmpc_jax.nlp.safeguard`) against the best warm start on the SAME smooth
objective: a result worse or less feasible than it is replaced by it (``used_warm``).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from . import checks
from .array_types import HostOrDevice
from .costs.base import Context, TermValue, check_terms, cost_term
from .costs.collision import CollisionTerm, collision_probability
from .costs.colregs import ColregsTerm
from .costs.colregs_fuzzy import (DEFAULT_E_CL, DEFAULT_EPS, DEFAULT_N_Y, RAD2DEG, check_fis_params, check_param,
                                  defuzzify, encounter_inputs_xy, fis_colregs, memberships, rule_strengths)
from .costs.path import PathTerm
from .evaluate import DEFAULT_TERMS, context, cost_terms, evaluate
from .jitting import with_jitted
from .layouts import resolve_unroll
from .methods.refine_settings import RefineSpec
from .nlp import BATCH_MODES, SolverSettings, best_index, safeguard, solve_docp
from .numerics import safe_sqrt, wrap_angle
from .ownship import Path, Trajectory, los_rollout, make_path, maneuver_index
from .packing import BehaviourArrays, SolveInputs
from .params import Params, PlannerConfig
from .solve import Plan, PlannerState, selection_cost

COLREGS_MODES = ("fis", "none")

#: Solver defaults of the refinement (measured, docs/refine.md): the problem has no constraint but the box, so
#: one augmented-Lagrangian iteration is plain L-BFGS on the box map; a second one only confirms convergence.
DEFAULT_SOLVER = SolverSettings(max_outer=1, max_inner=8, memory_size=8, max_linesearch_steps=8,
                                rel_tol=1e-4, grad_tol=1e-5)


# ------------------------------------------------------------------------------------------ smooth terms
# Both terms below are a maximum over time of an expensive smooth function g(k) (per obstacle and scenario).
# Its value is g(k*), k* = argmax_k g(k), and its gradient (almost everywhere) is that of g at k*.  So g is
# evaluated at every k WITHOUT gradient (forward only, cheap), and again at k* only WITH it: the same value and
# gradient as the dense max (``jnp.max``) except at exact ties, where ``jnp.max`` splits the cotangent and this
# gives it to the first maximiser.  In reverse mode this is the difference between back-propagating through
# T·O·S points and through O·S points (docs/refine.md, "Cost of one evaluation").
_sg = jax.lax.stop_gradient


def fis_mu(delta_cog, rb, d, d_cl, e_cl, eps, n_y: int):
    """:func:`psbmpc_jax.costs.colregs_fuzzy.fis_colregs` (radians, default completion), the same numbers, with
    an ``optimization_barrier`` between the rule strengths and the defuzzification: without it XLA fuses the
    two across the output grid and the reverse-mode program took 14 s to compile (3 s with it)."""
    rs = rule_strengths(memberships(delta_cog * RAD2DEG, rb * RAD2DEG, d, d_cl, e_cl), eps)
    r_t, r_f = jax.lax.optimization_barrier((rs.r_T, rs.r_F))
    return defuzzify(r_t, r_f, eps, n_y)


def _one_row(ctx: Context) -> bool:
    return ctx.own.x.ndim == 2 and ctx.own.x.shape[1] == 1


@cost_term(static=("capacity",))
class FastCollisionTerm:
    """:class:`~psbmpc_jax.costs.collision.CollisionTerm` (H_do, the σ-shortcut included) for ONE control
    sequence, evaluated for the refinement: the points that pass the σ-shortcut are compacted into ``capacity``
    slots (static) and sent through the estimator without gradient (more active points: several chunks of
    ``capacity``, in a loop; exact either way); the maximising time of every (obstacle, scenario) is then
    evaluated again with gradient.  Same value as ``CollisionTerm`` (to rounding), same gradient
    except at ties of the maximum over time.  Several rows (a behaviour table) fall back to ``CollisionTerm``.
    Details: ``C [B, O, S]``."""

    name = "do"
    PARAMS = CollisionTerm.PARAMS
    smooth = True

    capacity: int = 256

    def __post_init__(self):
        if isinstance(self.capacity, bool) or not isinstance(self.capacity, (int, np.integer)) or self.capacity < 1:
            raise ValueError(f"FastCollisionTerm.capacity must be an integer >= 1, got {self.capacity!r}")

    def __call__(self, ctx: Context, params, config, samples) -> TermValue:
        if not _one_row(ctx):
            return CollisionTerm()(ctx, params, config, samples)
        own, obs = ctx.own, ctx.obstacles
        n_t = own.x.shape[0]
        n_o, n_s = ctx.scen_weight.shape
        n_os = n_o * n_s
        flat = lambda a: a.reshape(n_t, n_os)  # noqa: E731
        o_of = jnp.arange(n_os) // n_s
        sxx, sxy, syy, smax = (c.T[:, o_of] for c in ctx.cov_stats)                    # [T, O·S]
        rad = jnp.repeat(ctx.radius, n_s)                                              # [O·S]
        zk = jnp.repeat(ctx.zeta_k, n_s)
        disc = jnp.exp(-ctx.t / params.T_d)                                            # [T]
        live = ctx.scen_valid.reshape(n_os)
        geo = dict(dx=flat(obs.x) - own.x, dy=flat(obs.y) - own.y, dvx=flat(obs.vx) - own.vx,
                   dvy=flat(obs.vy) - own.vy, sxx=sxx, sxy=sxy, syy=syy)
        thr = rad[None] + params.c_sigma * smax
        act = (geo["dx"] ** 2 + geo["dy"] ** 2 <= thr * thr) & live[None]             # [T, O·S]

        def point(g, k, j):
            """The term at points (time k, obstacle-scenario j) of the geometry ``g`` (any index shape)."""
            p = collision_probability(g["dx"][k, j], g["dy"][k, j], g["sxx"][k, j], g["sxy"][k, j],
                                      g["syy"][k, j], rad[j], params, config, samples)
            return jnp.where(act[k, j], zk[j] * (g["dvx"][k, j] ** 2 + g["dvy"][k, j] ** 2) * p * disc[k], 0.0)

        g0 = _sg(geo)
        n_pts = n_t * n_os
        cap = min(self.capacity, n_pts)
        n_chunks = -(-n_pts // cap)
        count = jnp.sum(act)
        # the active points first (flat index k·O·S + j), padded to whole chunks; the chunks holding active
        # points go through the estimator, one chunk of `cap` points per loop iteration (usually one)
        order = jnp.nonzero(act.reshape(-1), size=n_chunks * cap, fill_value=0)[0]

        def chunk(c, acc):
            pos = c * cap + jnp.arange(cap)
            idx = jax.lax.dynamic_slice(order, (c * cap,), (cap,))
            vals = jnp.where(pos < count, point(g0, idx // n_os, idx % n_os), 0.0)
            return acc.at[idx].max(vals)

        acc0 = jnp.zeros((n_pts,), own.x.dtype)
        terms = _sg(jax.lax.fori_loop(0, (count + cap - 1) // cap, chunk, acc0).reshape(n_t, n_os))  # >= 0
        c = point(geo, jnp.argmax(terms, axis=0), jnp.arange(n_os)).reshape(1, n_o, n_s)
        return TermValue(jnp.sum(ctx.scen_weight[None] * c, axis=(1, 2)), {"C": c})


@cost_term(static=("n_y",))
class ScenarioFuzzyColregsTerm:
    """The PSB-MPC COLREGS cost with the fuzzy indicator: H = κ Σ_i w_i Σ_s P_s max_k μ_FIS(k), i.e. the
    Boolean term (:class:`psbmpc_jax.costs.colregs.ColregsTerm`, "any k violates") with μ ∈ {0, 1} replaced by
    FIS_colregs (:func:`psbmpc_jax.costs.colregs_fuzzy.fis_colregs`) and "any" by the max over k.  κ and the
    close distance d_cl = ``Params.d_close`` come from ``Params``; ``e_cl`` (width of the "close" edge), ``eps``
    (smooth max/min) and ``n_y`` (output grid, static) are the term's own.  μ_FIS has a floor of about 0.031
    (every pair pays it), a constant that does not move the minimiser.  The max over k is taken as above (μ at
    every k without gradient, again at the maximiser with it).  Details: ``mu_fis [B, O, S]``."""

    name = "colregs"
    PARAMS = ("kappa", "d_close")
    smooth = True

    e_cl: float = DEFAULT_E_CL
    eps: float = DEFAULT_EPS
    n_y: int = DEFAULT_N_Y

    def __post_init__(self):
        check_fis_params(40.0, self.e_cl, self.eps, self.n_y)

    def __call__(self, ctx: Context, params, config, samples) -> TermValue:
        own, obs = ctx.own, ctx.obstacles
        n_t, n_b = own.x.shape
        n_o, n_s = ctx.scen_weight.shape
        n_os = n_o * n_s
        flat = lambda a: a.reshape(n_t, n_os)[:, :, None]  # noqa: E731   [T, O·S, 1]
        live = ctx.scen_valid.reshape(n_os)[None, :, None]

        def mu(ox, oy, ochi, tx, ty, tchi, barrier=True):
            dcog, rb, d = encounter_inputs_xy(ox, oy, ochi, tx, ty, tchi)
            if barrier:        # the points differentiated: fast to compile
                return fis_mu(dcog, rb, d, params.d_close, self.e_cl, self.eps, self.n_y)
            # every point, no gradient: the fused form runs 2-5x faster (measured)
            return fis_colregs(dcog, rb, d, d_cl=params.d_close, e_cl=self.e_cl, eps=self.eps, n_y=self.n_y)

        own_xyc = (own.x[:, None], own.y[:, None], own.chi[:, None])                       # [T, 1, B]
        obs_xyc = (flat(obs.x), flat(obs.y), flat(obs.chi))                                # [T, O·S, 1]
        every = jnp.where(live, mu(*_sg(own_xyc), *_sg(obs_xyc), barrier=False), 0.0)                     # [T, O·S, B]
        k = jnp.argmax(every, axis=0)                                                      # [O·S, B]
        at = lambda a: jnp.take_along_axis(a, k[None], axis=0)[0]  # noqa: E731           [O·S, B]
        at_o = lambda a: jnp.broadcast_to(a, (n_t, n_os, n_b))  # noqa: E731
        m = mu(*(at(at_o(a)) for a in own_xyc), *(at(at_o(a)) for a in obs_xyc))
        m = jnp.where(live[0], m, 0.0).T.reshape(n_b, n_o, n_s)                            # [B, O, S]
        return TermValue(params.kappa * jnp.sum(ctx.scen_weight[None] * m, axis=(1, 2)), {"mu_fis": m})


PATH_CHANGES = ("grid", "per_step")


@cost_term(static=("n_maneuvers",))
class SmoothPathTerm:
    """The path cost H_p of :class:`psbmpc_jax.costs.path.PathTerm` with |Δu| replaced by
    √(Δu² + eps²) − eps (eps = 0: the exact term; the difference is at most K_du·eps).  The port/starboard
    weights switch where their quadratic vanishes, so the rest is already C¹.

    ``n_maneuvers`` (static): None weighs the changes as ``PathTerm`` does for the controls it is given (the
    change from the last applied offsets by 1/n, the n − 1 step-to-step changes summed by 1/(n − 1), n the
    number of controls: per-step controls make every change n/n_M times cheaper than in the grid search).  An
    integer n_M (the grid's maneuver count) weighs them as the grid search does: the first change by 1/n_M, the
    later ones summed by 1/max(n_M − 1, 1).  The deviation part Σ f / n stays an average over the controls.  A
    per-step sequence that holds a behaviour's n_M maneuvers for equal numbers of steps then costs exactly that
    behaviour's H_p (eps = 0; docs/refine.md, C-R-3)."""

    name = "path"
    PARAMS = ("K_u", "K_du", "K_chi_stbd", "K_chi_port", "K_dchi_stbd", "K_dchi_port")
    smooth = True

    eps: float = 1e-2
    n_maneuvers: int | None = None

    def __post_init__(self):
        check_param("SmoothPathTerm.eps", self.eps, lo=0.0)
        m = self.n_maneuvers
        if m is not None and (isinstance(m, bool) or not isinstance(m, (int, np.integer)) or m < 1):
            raise ValueError(f"SmoothPathTerm.n_maneuvers must be None or an integer >= 1, got {m!r}")

    def __call__(self, ctx: Context, params, config, samples) -> TermValue:
        p, eps = params, self.eps
        sabs = lambda x: safe_sqrt(x * x + eps * eps) - eps  # noqa: E731

        def f(u, chi):
            return p.K_u * (1.0 - u) + jnp.where(chi < 0, p.K_chi_port, p.K_chi_stbd) * chi * chi

        def h(u, chi, u_prev, chi_prev):
            dchi = wrap_angle(chi - chi_prev)
            return p.K_du * sabs(u - u_prev) + jnp.where(dchi < 0, p.K_dchi_port, p.K_dchi_stbd) * dchi * dchi

        offsets, last = ctx.offsets, ctx.last_offsets
        u, chi = offsets[..., 0], offsets[..., 1]
        n_m = offsets.shape[1]
        first_w, later_w = ((1.0 / n_m, 1.0 / max(n_m - 1, 1)) if self.n_maneuvers is None else
                            (1.0 / self.n_maneuvers, 1.0 / max(self.n_maneuvers - 1, 1)))
        value = jnp.sum(f(u, chi), axis=1) / n_m + h(u[:, 0], chi[:, 0], last[0], last[1]) * first_w
        if n_m > 1:
            value = value + jnp.sum(h(u[:, 1:], chi[:, 1:], u[:, :-1], chi[:, :-1]), axis=1) * later_w
        return TermValue(value)


def smooth_terms(terms=DEFAULT_TERMS, colregs: str = "fis", path_eps: float = 1e-2, fis_e_cl: float = DEFAULT_E_CL,
                 fis_n_y: int = DEFAULT_N_Y, pc_capacity: int = 256, path_maneuvers: int | None = None) -> tuple:
    """The refinement's smooth objective terms from the grid search's ``terms``: every Boolean
    :class:`~psbmpc_jax.costs.colregs.ColregsTerm` replaced by :class:`ScenarioFuzzyColregsTerm`
    (``colregs="fis"``) or dropped (``"none"``), every :class:`~psbmpc_jax.costs.path.PathTerm` by
    :class:`SmoothPathTerm`, every :class:`~psbmpc_jax.costs.collision.CollisionTerm` by
    :class:`FastCollisionTerm` (the same cost; evaluated through the quadrature estimator by the refinement);
    other terms (grounding, custom terms) are kept as they are.  ``path_maneuvers``: the
    :class:`SmoothPathTerm`'s ``n_maneuvers`` (None: per-control change weights)."""
    out: list = []
    for t in check_terms(terms):
        if isinstance(t, CollisionTerm):
            out.append(FastCollisionTerm(capacity=pc_capacity))
        elif isinstance(t, ColregsTerm):
            if colregs == "fis":
                out.append(ScenarioFuzzyColregsTerm(e_cl=fis_e_cl, n_y=fis_n_y))
        elif isinstance(t, PathTerm):
            out.append(SmoothPathTerm(eps=path_eps, n_maneuvers=path_maneuvers))
        else:
            out.append(t)
    return check_terms(out)


# ------------------------------------------------------------------------------------------ settings
def _default_solver() -> SolverSettings:
    return DEFAULT_SOLVER


@dataclasses.dataclass(frozen=True)
class RefineSettings:
    """Settings of :func:`refine` (validated on construction: ``ValueError`` naming the field).

    Attributes:
        n_starts: warm starts, the ``n_starts`` best behaviours by the grid's own ranking (the selected one
            first); integer >= 1 (and <= the behaviour table's size).
        batch: ``"map"`` (the starts one after another in one compiled call; the faster choice on a CPU) or
            ``"vmap"`` (vectorised; lockstep while loops).
        horizon: T_refine [s]: the controls of the first T_refine s are refined (per step, or per block), the
            rest of the horizon follows the warm behaviour; ``None`` = the config's T.  A whole number of
            steps dt, in (0, T].
        colregs: ``"fis"``: the fuzzy COLREGS term replaces the Boolean indicator in the smooth objective;
            ``"none"``: dropped.
        solver: :class:`~psbmpc_jax.nlp.SolverSettings` of each start (default :data:`DEFAULT_SOLVER`).
        block: steps per decision variable (1 = per-step controls; k: one control held for k steps), >= 1.
        path_eps: smoothing of |Δu| in the path term (:class:`SmoothPathTerm`), >= 0.
        fis_e_cl: width [m] of the fuzzy "close" edge around ``Params.d_close``, > 0.
        fis_n_y: points of the FIS output grid, integer >= 2 (static: changing it recompiles).
        pc_capacity: (time, obstacle, scenario) points passing the σ-shortcut that the collision term sends
            through the estimator at once (:class:`FastCollisionTerm`; more: several chunks), integer >= 1
            (static).
        path_changes: how the smooth path term weighs control changes (static): ``"grid"`` (default) as the
            grid search weighs its maneuvers' (first change 1/n_M, later ones 1/(n_M − 1), n_M the behaviour
            table's maneuver count), so a change costs the same in both stages; ``"per_step"`` by the number of
            refined controls (``PathTerm``'s formula applied to per-step controls: each change n/n_M times
            cheaper; the form before C-R-3).
        previous_start: start 1 is the previous refinement's per-step controls, ``PlannerState.warm_start``
            ``[N, 2]`` of the state passed to the solve, already shifted to begin now (:func:`shift_controls`);
            the grid's choice stays start 0.  A state without one (None, or NaN throughout) uses the grid's
            starts.  Needs ``n_starts >= 2``; a value (switching it does not recompile).
    """

    n_starts: int = RefineSpec.n_starts
    batch: str = "map"
    horizon: float | None = RefineSpec.horizon
    colregs: str = RefineSpec.colregs
    solver: SolverSettings = dataclasses.field(default_factory=_default_solver)
    block: int = 1
    path_eps: float = 1e-2
    fis_e_cl: float = DEFAULT_E_CL
    fis_n_y: int = DEFAULT_N_Y
    pc_capacity: int = 256
    path_changes: str = "grid"
    previous_start: bool = False

    def __post_init__(self):
        def int_field(name, lo):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo:
                raise ValueError(f"RefineSettings.{name} must be an integer >= {lo}, got {v!r}")
            object.__setattr__(self, name, int(v))

        def float_field(name, ok, allowed):
            v = getattr(self, name)
            try:
                if isinstance(v, (bool, str, bytes)):
                    raise TypeError
                f = float(v)
            except (TypeError, ValueError):
                raise ValueError(f"RefineSettings.{name} must be a real number {allowed}, got {v!r}") from None
            if not math.isfinite(f) or not ok(f):
                raise ValueError(f"RefineSettings.{name} must be finite and {allowed}, got {v!r}")
            object.__setattr__(self, name, f)

        int_field("n_starts", 1)
        int_field("block", 1)
        int_field("fis_n_y", 2)
        int_field("pc_capacity", 1)
        if not isinstance(self.previous_start, (bool, np.bool_)):
            raise ValueError(f"RefineSettings.previous_start must be a bool, got {self.previous_start!r}")
        object.__setattr__(self, "previous_start", bool(self.previous_start))
        if self.previous_start and self.n_starts < 2:
            raise ValueError(f"RefineSettings.previous_start needs n_starts >= 2 (start 0 is the grid's choice), "
                             f"got n_starts {self.n_starts}")
        if self.path_changes not in PATH_CHANGES:
            raise ValueError(f"RefineSettings.path_changes must be one of {PATH_CHANGES}, got {self.path_changes!r}")
        if self.batch not in BATCH_MODES:
            raise ValueError(f"RefineSettings.batch must be one of {BATCH_MODES}, got {self.batch!r}")
        if self.colregs not in COLREGS_MODES:
            raise ValueError(f"RefineSettings.colregs must be one of {COLREGS_MODES}, got {self.colregs!r}")
        if not isinstance(self.solver, SolverSettings):
            raise ValueError(f"RefineSettings.solver must be a psbmpc_jax.nlp.SolverSettings, got "
                             f"{type(self.solver).__name__}")
        if self.horizon is not None:
            float_field("horizon", lambda v: v > 0, "> 0 (seconds) or None")
        float_field("path_eps", lambda v: v >= 0, ">= 0")
        float_field("fis_e_cl", lambda v: v > 0, "> 0 (metres)")

    def replace(self, **changes) -> "RefineSettings":
        return dataclasses.replace(self, **changes)

    def n_refine(self, config: PlannerConfig) -> int:
        """Refined steps N_r = T_refine / dt for ``config`` (``ValueError`` naming ``horizon`` if it does not
        fit: not a whole number of steps, or beyond T)."""
        n = config.n_steps
        if self.horizon is None:
            return n
        k = self.horizon / config.dt
        if abs(k - round(k)) > 1e-9 * max(1.0, k) or round(k) < 1:
            raise ValueError(f"RefineSettings.horizon must be a whole number of steps dt = {config.dt} s, got "
                             f"{self.horizon} s")
        if round(k) > n:
            raise ValueError(f"RefineSettings.horizon must be <= the config's T = {config.T} s, got "
                             f"{self.horizon} s")
        return int(round(k))

    def static(self, config: PlannerConfig) -> tuple:
        """The fields that shape the compiled refinement (part of its jit key)."""
        return (self.n_starts, self.batch, self.n_refine(config), self.colregs, self.block, self.fis_n_y,
                self.pc_capacity, self.path_changes)


class Refinement(NamedTuple):
    """Result of :func:`refine` (device arrays; :meth:`Planner.plan` returns it as NumPy in the user's frame).

    Attributes:
        controls: ``[N, 2]`` per-step (speed factor, course offset rad) over the config's horizon (dt = config.dt):
            the refined controls, or the best warm start's when ``used_warm``.
        apply: ``[2]`` the first row, what the ship applies now.
        cost: smooth objective value of ``controls``.
        warm_cost: smooth objective value of the best warm start (the lowest over the starts).
        violation: box violation of ``controls`` (0 inside the box).
        used_warm: the safeguard replaced the solver's result by the best warm start.
        status: solver status of the best start (0 ok/converged, 3 max-iter, 4 infeasible, 5 non-finite: :class:`psbmpc_jax.status.Status`).
        iterations: L-BFGS iterations of the best start (summed over outer iterations).
        start_index: which warm start (0 = the grid's choice, 1 = its runner-up, ...; with ``previous_start``
            and a previous plan, 1 = that plan and the runner-ups from 2) the kept controls come from (the best
            warm start's when ``used_warm``).
        behaviour: the behaviour-table index of that start (−1: the previous-plan start, ``previous_start``).
        grid_cost: the ORIGINAL (grid search's) cost of ``controls``: the objective with the grid's terms,
            ``smooth=False`` (per-step form of the path term).
        warm_grid_cost: the same for the best warm start.
        trajectory: ``[N+1, 4]`` (x, y, chi, U) of the own-ship under ``controls`` (the inputs' frame;
            the user's frame from :meth:`Planner.plan`).
        costs: the smooth objective's terms at ``controls`` (name -> scalar).
    """

    controls: jax.Array
    apply: jax.Array
    cost: jax.Array
    warm_cost: jax.Array
    violation: jax.Array
    used_warm: jax.Array
    status: jax.Array
    iterations: jax.Array
    start_index: jax.Array
    behaviour: jax.Array
    grid_cost: jax.Array
    warm_grid_cost: jax.Array
    trajectory: jax.Array
    costs: dict


# ------------------------------------------------------------------------------------------ the objective
class RefineData(NamedTuple):
    """Traced data of the smooth objective: everything the context holds except the own-ship rollout."""

    state0: HostOrDevice       # [4]
    path: Path                 # one row
    U_d: HostOrDevice
    t: jax.Array
    last_offsets: jax.Array
    obstacles: Trajectory
    obs_cov: jax.Array
    cov_stats: tuple
    scen_valid: HostOrDevice
    radius: HostOrDevice
    zeta_k: HostOrDevice
    scen_weight: HostOrDevice
    world: object
    params: Params
    terms: tuple


def refine_data(inputs: SolveInputs, last_offsets, params: Params, config: PlannerConfig, terms) -> RefineData:
    """The control-independent part of the objective's context (obstacle scenarios, covariances, chart),
    computed once per refinement.  ``params.t_ts`` is set to dt (per-step controls)."""
    inputs = jax.tree.map(jnp.asarray, inputs)
    dtype = inputs.own.state.dtype
    params = params.replace(t_ts=jnp.asarray(config.dt, dtype))
    dummy = jnp.ones((config.n_steps, 2), dtype)
    one = inputs._replace(behaviours=BehaviourArrays(dummy[None], jnp.ones((1,), bool)))
    ctx = context(one, last_offsets, params, config, dense=True)
    own = inputs.own
    return RefineData(own.state, make_path(own.wx, own.wy, own.n), own.U_d, ctx.t, ctx.last_offsets, ctx.obstacles,
                      ctx.obs_cov, ctx.cov_stats, ctx.scen_valid, ctx.radius, ctx.zeta_k, ctx.scen_weight, ctx.world,
                      params, tuple(terms))


def rollout(controls, d: RefineData, config: PlannerConfig) -> Trajectory:
    """Own-ship trajectory ``[N+1]`` under per-step controls ``[N, 2]`` (time-major, one row), a ``lax.scan`` of
    ``config.rollout_unroll`` steps per loop step (``"auto"``: 1 on a CPU, :data:`psbmpc_jax.layouts.GPU_UNROLL`
    on a GPU), as the grid search's rollouts: on a GPU each loop step of the rollout and of its reverse pass is a
    kernel launch, and the refinement is a chain of such rollouts."""
    p = d.params
    unroll = resolve_unroll(getattr(config, "rollout_unroll", 1), getattr(config, "layout_platform", "auto"))
    return los_rollout(d.state0[None], d.path, controls[:, 1:2], d.U_d * controls[:, 0:1],
                       jnp.zeros((1,), controls.dtype), p.os_lookahead, p.os_R_a, p.os_T_chi, p.os_T_U, config.dt,
                       unroll=unroll)


def term_costs(controls, d: RefineData, config: PlannerConfig, samples=None) -> dict:
    """The terms ``d.terms`` of per-step controls ``[N, 2]`` (name -> scalar) with ``config``'s estimator; their
    sum is :func:`psbmpc_jax.objective.objective` ``(controls, ..., d.terms, per_step=True)``."""
    ctx = Context(t=d.t, offsets=controls[None], last_offsets=d.last_offsets, own=rollout(controls, d, config),
                  obstacles=d.obstacles, obs_cov=d.obs_cov, cov_stats=d.cov_stats, scen_valid=d.scen_valid,
                  radius=d.radius, zeta_k=d.zeta_k, scen_weight=d.scen_weight, world=d.world, dense=True)
    costs, _, _ = cost_terms(ctx, d.params, samples, config, d.terms)
    return {k: v[0] for k, v in costs.items()}


def smooth_costs(controls, d: RefineData, config: PlannerConfig) -> dict:
    """The smooth objective's terms of per-step controls ``[N, 2]`` (name -> scalar), the collision term through
    the quadrature estimator; their sum is :func:`psbmpc_jax.objective.objective` ``(controls, ..., d.terms,
    per_step=True, smooth=True)``."""
    cfg = config if config.estimator == "quadrature" else config.replace(estimator="quadrature")
    return term_costs(controls, d, cfg)


def grid_terms_fast(terms) -> tuple:
    """The grid search's ``terms`` with every :class:`CollisionTerm` as :class:`FastCollisionTerm` (the same
    value for one control sequence, any estimator)."""
    return tuple(FastCollisionTerm() if isinstance(t, CollisionTerm) else t for t in check_terms(terms))


def full_controls(z, tail, n_ref: int, block: int):
    """Decision variables ``z [ceil(N_r / block), 2]`` -> per-step controls ``[N, 2]``: each row of z held for
    ``block`` steps over the first N_r steps, then ``tail [N - N_r, 2]``."""
    u = jnp.repeat(z, block, axis=0, total_repeat_length=z.shape[0] * block)[:n_ref]
    return jnp.concatenate([u, tail], axis=0) if tail.shape[0] else u


@functools.lru_cache(maxsize=None)
def problem(config: PlannerConfig, n_ref: int, block: int):
    """``f(z, (data, tail))`` and ``f_full(u, (data, tail))`` for static sizes (cached: the solver hashes them by
    identity, so one compilation serves every call)."""

    @jax.jit
    def f_full(u, a):
        d, _ = a
        # the data's dtype: optax's line search computes its trial points with a float64 step when 64-bit JAX
        # is on, which would promote a float32 problem
        return sum(smooth_costs(u.astype(d.state0.dtype), d, config).values())

    def f(z, a):
        return f_full(full_controls(z.astype(a[0].state0.dtype), a[1], n_ref, block), a)

    return f, f_full


# ------------------------------------------------------------------------------------------ warm starts
def behaviour_controls(offsets, params: Params, config: PlannerConfig):
    """Per-step controls ``[N, 2]`` of a behaviour ``[n_M, 2]`` (maneuver M from step round(M t_ts / dt))."""
    n, n_m = config.n_steps, offsets.shape[0]
    t_ts = jnp.where(jnp.isnan(params.t_ts), n * config.dt / n_m, params.t_ts)
    return offsets[maneuver_index(n, n_m, t_ts, config.dt)]


def warm_indices(plan_best, evaluation, inputs: SolveInputs, params, config, n_starts: int):
    """The ``n_starts`` best behaviours by the grid's ranking (:func:`psbmpc_jax.solve.selection_cost`), the
    plan's choice first; slots beyond the valid behaviours repeat the choice."""
    valid = inputs.behaviours.mask & jnp.isfinite(evaluation.total)
    rank = jnp.where(valid, selection_cost(evaluation, inputs, params, config), jnp.inf)
    rank = rank.at[plan_best].set(-jnp.inf)
    order = jnp.argsort(rank, stable=True)[:n_starts]
    return jnp.where(jnp.isfinite(rank[order]), order, plan_best).astype(jnp.int32)


def box(behaviours: BehaviourArrays):
    """``(lower [2], upper [2])``: the (speed factor, course offset) ranges of the table's valid behaviours."""
    off = behaviours.offsets.reshape(behaviours.offsets.shape[0], -1, 2)
    m = behaviours.mask[:, None, None]
    lo = jnp.min(jnp.where(m, off, jnp.inf), axis=(0, 1))
    hi = jnp.max(jnp.where(m, off, -jnp.inf), axis=(0, 1))
    return lo, hi


# ------------------------------------------------------------------------------------------ refine
def _refine(inputs, best, last_offsets, params, samples, evaluation, solver, path_eps, fis_e_cl, grid_terms,
            previous=None, *, config, static):
    n_starts, batch, n_ref, colregs, block, fis_n_y, pc_capacity, path_changes = static
    inputs = jax.tree.map(jnp.asarray, inputs)
    dtype = inputs.own.state.dtype
    n = config.n_steps
    last = jnp.asarray(last_offsets, dtype)
    n_maneuvers = int(inputs.behaviours.offsets.shape[1]) if path_changes == "grid" else None
    terms = smooth_terms(grid_terms, colregs, path_eps, fis_e_cl, fis_n_y, pc_capacity, n_maneuvers)
    data = refine_data(inputs, last, params, config, terms)
    f, f_full = problem(config, n_ref, block)

    idx = warm_indices(best, evaluation, inputs, params, config, n_starts)                    # [S]
    warm = jax.vmap(lambda o: behaviour_controls(o, params, config))(inputs.behaviours.offsets[idx])   # [S, N, 2]
    if previous is not None:                   # (controls [N, 2], valid): start 1, the grid's runner-ups after it
        controls, valid = previous
        shifted = jnp.concatenate([warm[:1], controls.astype(dtype)[None], warm[1:-1]], axis=0)
        warm = jnp.where(valid, shifted, warm)
        idx = jnp.where(valid, jnp.concatenate([idx[:1], jnp.full((1,), -1, idx.dtype), idx[1:-1]]), idx)
    n_blk = -(-n_ref // block)
    z0 = warm[:, 0:n_ref:block]                                                              # [S, n_blk, 2]
    tails = warm[:, n_ref:]
    lo, hi = box(inputs.behaviours)
    lower, upper = jnp.broadcast_to(lo, (n_blk, 2)), jnp.broadcast_to(hi, (n_blk, 2))

    def one(args):
        z, tail = args
        return solve_docp(f, z, lower=lower, upper=upper, settings=solver, args=(data, tail))

    res = jax.vmap(one)((z0, tails)) if batch == "vmap" else lax.map(one, (z0, tails))
    tol = jnp.asarray(solver.tol, dtype)
    k = best_index(res.f, res.max_violation, tol)
    r = jax.tree.map(lambda a: a[k], res)

    # safeguard on the same smooth objective, over full per-step controls, against the best of the warm starts
    # (nlp.best_index: they are all inside the box, so the lowest finite cost, ties to the lower index)
    lower_n, upper_n = jnp.broadcast_to(lo, (n, 2)), jnp.broadcast_to(hi, (n, 2))
    u_res = full_controls(r.u, tails[k], n_ref, block)
    full = r._replace(u=u_res)
    kept = safeguard(full, warm, f_full, lower=lower_n, upper=upper_n, args=(data, None), tol=tol)
    w = kept.warm_index
    start = jnp.where(kept.used_warm, w, k).astype(jnp.int32)

    data_grid = data._replace(terms=grid_terms_fast(grid_terms))
    grid = jax.jit(lambda u, d, s: sum(term_costs(u, d, config, s).values()))  # noqa: E731
    traj = rollout(kept.u, data, config)
    trajectory = jnp.stack([traj.x[:, 0], traj.y[:, 0], traj.chi[:, 0], traj.U[:, 0]], axis=-1)
    return Refinement(controls=kept.u, apply=kept.u[0], cost=kept.f, warm_cost=kept.warm_f[w],
                      violation=kept.max_violation, used_warm=kept.used_warm, status=r.status,
                      iterations=r.inner_iterations, start_index=start, behaviour=idx[start],
                      grid_cost=grid(kept.u, data_grid, samples), warm_grid_cost=grid(warm[w], data_grid, samples),
                      trajectory=trajectory,
                      costs=smooth_costs(kept.u, data, config))


_refine_jit = jax.jit(_refine, static_argnames=("config", "static"))


@with_jitted(_refine_jit)
def refine(inputs: SolveInputs, plan: Plan, state: PlannerState, params: Params, samples, config: PlannerConfig,
           settings: RefineSettings = RefineSettings(), terms=None, *, evaluation=None) -> Refinement:
    """Refine the grid search's plan with the smooth DOCP (module docstring, docs/refine.md).

    Args:
        inputs, params, samples, config: as passed to :func:`psbmpc_jax.solve.solve` (the local frame).
        plan: the :class:`~psbmpc_jax.solve.Plan` it returned (``plan.best``: the first warm start).
        state: the :class:`~psbmpc_jax.solve.PlannerState` passed TO that solve (previously applied offsets).
        settings: :class:`RefineSettings`.
        terms: the grid search's cost terms (default :data:`~psbmpc_jax.evaluate.DEFAULT_TERMS`); the smooth
            objective is :func:`smooth_terms` of them.
        evaluation: the :class:`~psbmpc_jax.evaluate.Evaluation` of that solve (its third output); without it
            the grid search is evaluated again here to rank the warm starts.

    Returns:
        :class:`Refinement`.  Jitted: values (inputs, params, numeric solver settings, ``path_eps``,
        ``fis_e_cl``) never recompile; the config, shapes, term classes and the static settings do.
    """
    if not isinstance(settings, RefineSettings):
        raise ValueError(f"settings must be a RefineSettings, got {type(settings).__name__}")
    if not isinstance(config, PlannerConfig):
        raise ValueError(f"config must be a PlannerConfig, got {type(config).__name__}")
    terms = check_terms(DEFAULT_TERMS if terms is None else terms)
    n_b = int(np.shape(inputs.behaviours.mask)[0])
    if settings.n_starts > n_b:
        raise ValueError(f"RefineSettings.n_starts must be <= the behaviour table's (padded) size {n_b}, got "
                         f"{settings.n_starts}")
    static = settings.static(config)                       # validates the horizon against the config
    dtype = np.dtype(config.dtype)
    if not settings.previous_start and state.warm_start is not None \
            and not isinstance(state.warm_start, jax.core.Tracer):
        raise ValueError("PlannerState.warm_start is only used with RefineSettings(previous_start=True)")
    # with 2+ starts the previous-plan row is always passed (not valid without one): no recompile either way
    previous = (previous_plan(state.warm_start if settings.previous_start else None, config.n_steps, dtype)
                if settings.n_starts >= 2 else None)
    last = jnp.asarray(state.last_offsets, dtype)
    if evaluation is None:      # evaluated here, outside the refinement's jit: both calls share one compilation
        evaluation = evaluate(inputs, last, params, samples, config, terms)
    return _refine_jit(inputs, jnp.asarray(plan.best, jnp.int32), last, params,
                       samples, evaluation, settings.solver, jnp.asarray(settings.path_eps, dtype),
                       jnp.asarray(settings.fis_e_cl, dtype), terms, previous, config=config, static=static)


def previous_plan(warm_start, n: int, dtype):
    """``PlannerState.warm_start`` as the previous-plan start ``(controls [n, 2], valid)``: None or NaN
    throughout -> not valid; otherwise finite per-step (speed factor, course offset [rad]) controls ``[n, 2]``
    with speed factors in [0, 1] and |offset| <= pi (:func:`psbmpc_jax.checks.control_plan`, ``ValueError``
    naming the field)."""
    if warm_start is None:
        return np.zeros((n, 2), dtype), np.asarray(False)
    a, missing = checks.control_plan(warm_start, "PlannerState.warm_start", n=n, lower=(0.0, -np.pi),
                                     upper=(1.0, np.pi), what="speed factor, course offset rad", tol=1e-12,
                                     box="the refinement's box: speed factors in [0, 1], course offsets in "
                                         "[-pi, pi] rad")
    if missing:
        return np.zeros((n, 2), dtype), np.asarray(False)
    return a.astype(dtype), np.asarray(True)




__all__ = ["RefineSettings", "Refinement", "refine", "smooth_terms", "ScenarioFuzzyColregsTerm", "SmoothPathTerm",
           "DEFAULT_SOLVER", "COLREGS_MODES", "refine_data", "smooth_costs", "rollout", "full_controls",
           "behaviour_controls", "warm_indices", "box", "problem", "RefineData", "FastCollisionTerm", "term_costs",
           "grid_terms_fast", "fis_mu", "previous_plan", "PATH_CHANGES"]
