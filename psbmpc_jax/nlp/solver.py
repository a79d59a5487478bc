"""A generic, jitted augmented-Lagrangian solver for small smooth problems (see ``docs/solver.md``)::

    minimise f(u, args)  over u (any shape, e.g. [N, 2])
    s.t.     eq(u, args)   = 0     [m_e]
             ineq(u, args) <= 0    [m_i]
             lower <= u <= upper   (elementwise, ±inf allowed)

Outer loop: Powell-Hestenes-Rockafellar augmented Lagrangian

    L(u; λ, ν, μ) = f + λ·h + μ/2 |h|² + (|max(0, ν + μ g)|² - |ν|²) / (2 μ)

with first-order multiplier updates λ += μ h, ν = max(0, ν + μ g) and penalty growth μ *= growth when the
constraint measure max(|h|, |max(g, -ν/μ)|) did not fall below ``decrease`` times its previous value.
Inner loop: optax L-BFGS (zoom line search) on a smooth box reparametrisation (:mod:`.boxmap`), or Adam
followed by projection onto the box; early stop on the gradient norm.  Both loops are ``lax.while_loop``
with static bounds, so one compilation serves every value of the data (``args``, u0, bounds, numeric
settings).

``f``, ``eq`` and ``ineq`` are STATIC arguments of the jitted functions (hashed by identity): pass
module-level functions (or the same object every call) and put every number that changes into ``args``;
a fresh ``lambda`` per call recompiles every call.
"""

from __future__ import annotations

from functools import partial
from typing import Callable

import jax
import jax.numpy as jnp
import optax
from jax import lax

from ..jitting import with_jitted
from . import boxmap
from .settings import (CONVERGED, INFEASIBLE, MAX_ITER, NON_FINITE, MultistartResult, Safeguarded,
                       SolverResult, SolverSettings)

_DEFAULT = SolverSettings()


# ---------------------------------------------------------------------------------------------- helpers
def _float_array(x, dtype=None):
    """A strongly typed floating array (a weak type -- e.g. from ``jnp.full(n, 0.5)`` -- is another jit
    cache key)."""
    x = jnp.asarray(x)
    if dtype is None:
        dtype = x.dtype if jnp.issubdtype(x.dtype, jnp.floating) else jnp.result_type(float)
    return x.astype(dtype)


def _bound(b, fill, shape, dtype, name):
    if b is None:
        return jnp.full(shape, fill, dtype)
    b = jnp.asarray(b, dtype)
    try:
        return jnp.broadcast_to(b, shape)
    except ValueError:
        raise ValueError(f"{name} must broadcast to u0's shape {shape}, got shape {b.shape}") from None


def _objective(f, args, dtype):
    def fu(u):
        v = jnp.asarray(f(u, args))
        if v.size != 1:
            raise ValueError(f"f(u, args) must return a scalar, got shape {v.shape}")
        return v.reshape(()).astype(dtype)
    return fu


def _constraint(c, args, dtype, name):
    if c is None:
        return lambda u: jnp.zeros((0,), dtype)
    return lambda u: jnp.ravel(jnp.asarray(c(u, args))).astype(dtype)


def _max0(x):
    return jnp.max(x, initial=0.0) if x.size else jnp.zeros((), x.dtype)


def _violation(u, h, g, lower, upper):
    """max(|h|, max(g, 0), box violation) -- NaN if anything is NaN."""
    box = jnp.maximum(lower - u, u - upper)
    return jnp.maximum(jnp.maximum(_max0(jnp.abs(h)), _max0(g)), _max0(box))


def _all_finite(*xs):
    out = jnp.asarray(True)
    for x in xs:
        out = out & jnp.all(jnp.isfinite(x))
    return out


def _inf_norm(x):
    return _max0(jnp.abs(x))


# ---------------------------------------------------------------------------------------------- inner loops
def _inner_lbfgs(phi, z0, s: SolverSettings, grad_tol, active):
    """L-BFGS (fresh memory) with a zoom line search on phi from z0.

    Stops at max_inner iterations, grad inf-norm <= grad_tol, a step that does not decrease phi (rejected:
    line-search failure) or a non-finite value/gradient (rejected; finite=False).  Returns (z, iterations,
    accepted steps, finite, grad inf-norm, stalled) where stalled = it stopped on a line-search failure with a
    grad inf-norm above max(grad_tol, sqrt(eps) * max(|phi|, 1)) -- not explained by rounding."""
    ls = optax.scale_by_zoom_linesearch(max_linesearch_steps=s.max_linesearch_steps, initial_guess_strategy="one")
    opt = optax.lbfgs(memory_size=s.memory_size, linesearch=ls)
    v0, g0 = jax.value_and_grad(phi)(z0)
    ok0 = _all_finite(v0, g0)

    def cond(c):
        z, st, v, g, k, n_acc, ok, stop = c
        return active & (k < s.max_inner) & ok & ~stop & (_inf_norm(g) > grad_tol)

    def body(c):
        z, st, v, g, k, n_acc, ok, stop = c
        upd, st2 = opt.update(g, st, z, value=v, grad=g, value_fn=phi)
        z2 = z + upd
        v2 = optax.tree.get(st2, "value")
        g2 = optax.tree.get(st2, "grad")
        fin = _all_finite(v2, g2, z2)
        accept = fin & (v2 <= v) & jnp.any(z2 != z)
        pick = lambda new, old: jnp.where(accept, new, old)  # noqa: E731
        return pick(z2, z), st2, pick(v2, v), pick(g2, g), k + 1, n_acc + accept, fin, ~accept

    zero = jnp.int32(0)
    z, _, v, g, k, n_acc, ok, stop = lax.while_loop(cond, body, (z0, opt.init(z0), v0, g0, zero, zero, ok0,
                                                                 jnp.asarray(False)))
    gn = _inf_norm(g)
    floor = jnp.sqrt(jnp.finfo(gn.dtype).eps) * jnp.maximum(jnp.abs(v), 1.0)
    stalled = stop & (gn > jnp.maximum(grad_tol, floor))
    return z, k, n_acc, ok, gn, stalled


def _inner_adam(phi, u0, lower, upper, s: SolverSettings, lr, grad_tol, active):
    """Adam steps followed by projection onto the box.  Stops on the projected-gradient inf-norm."""
    opt = optax.adam(lr)
    vg = jax.value_and_grad(phi)

    def pg(u, g):
        return _inf_norm(u - jnp.clip(u - g, lower, upper))

    v0, g0 = vg(u0)
    ok0 = _all_finite(v0, g0)

    def cond(c):
        u, st, g, k, ok = c
        return active & (k < s.max_inner) & ok & (pg(u, g) > grad_tol)

    def body(c):
        u, st, g, k, ok = c
        upd, st2 = opt.update(g, st, u)
        u2 = optax.projections.projection_box(u + upd, lower, upper)
        v2, g2 = vg(u2)
        fin = _all_finite(v2, g2, u2)
        return jnp.where(fin, u2, u), st2, jnp.where(fin, g2, g), k + 1, fin

    u, _, g, k, ok = lax.while_loop(cond, body, (u0, opt.init(u0), g0, jnp.int32(0), ok0))
    return u, k, ok, pg(u, g), jnp.asarray(False)


# ---------------------------------------------------------------------------------------------- solver
def _solve(f, u0, lower, upper, eq, ineq, settings, args) -> SolverResult:
    if not isinstance(settings, SolverSettings):
        raise TypeError(f"settings must be a SolverSettings, got {type(settings).__name__}")
    s = settings
    u0 = _float_array(u0)
    dtype, shape = u0.dtype, u0.shape
    lower = _bound(lower, -jnp.inf, shape, dtype, "lower")
    upper = _bound(upper, jnp.inf, shape, dtype, "upper")
    num = {n: jnp.asarray(getattr(s, n), dtype) for n in ("tol", "rel_tol", "grad_tol", "mu0", "growth",
                                                           "mu_max", "decrease", "learning_rate",
                                                           "start_margin", "multiplier_max")}
    fu = _objective(f, args, dtype)
    heq = _constraint(eq, args, dtype, "eq")
    gin = _constraint(ineq, args, dtype, "ineq")
    m_e = jax.eval_shape(heq, u0).shape[0]
    m_i = jax.eval_shape(gin, u0).shape[0]
    empty_box = jnp.any(lower > upper)

    if s.method == "lbfgs":
        to_u = lambda w: boxmap.forward(w, lower, upper, s.box_map)  # noqa: E731
        w0 = boxmap.inverse(u0, lower, upper, s.box_map, num["start_margin"])
    else:
        to_u = lambda w: w  # noqa: E731
        w0 = jnp.clip(u0, lower, upper)

    def aug(u, lam, nu, mu):
        val = fu(u)
        if m_e:
            h = heq(u)
            val = val + lam @ h + 0.5 * mu * (h @ h)
        if m_i:
            g = gin(u)
            val = val + (jnp.sum(jnp.maximum(0.0, nu + mu * g) ** 2) - nu @ nu) / (2.0 * mu)
        return val

    u_start = to_u(w0)
    f_start = fu(u_start)
    h0, g0 = heq(u_start), gin(u_start)
    ok0 = _all_finite(f_start, h0, g0)
    zero_i = jnp.int32(0)
    init = dict(w=w0, lam=jnp.zeros((m_e,), dtype), nu=jnp.zeros((m_i,), dtype), mu=num["mu0"],
                k=zero_i, n_in=zero_i, f_prev=f_start,
                V_prev=jnp.maximum(_max0(jnp.abs(h0)), _max0(g0)),
                converged=jnp.asarray(False), nonfinite=~ok0, gnorm=jnp.asarray(jnp.inf, dtype),
                stalled=jnp.asarray(False))

    def cond(c):
        return (c["k"] < s.max_outer) & ~c["converged"] & ~c["nonfinite"]

    def body(c):
        lam, nu, mu = c["lam"], c["nu"], c["mu"]
        active = cond(c)            # always True here, except for finished lanes of a vmapped batch
        if s.method == "lbfgs":
            phi = lambda w: aug(to_u(w), lam, nu, mu)  # noqa: E731
            w, k_in, n_acc, ok_in, gnorm, stalled = _inner_lbfgs(phi, c["w"], s, num["grad_tol"], active)
        else:
            phi = lambda w: aug(w, lam, nu, mu)  # noqa: E731
            w, k_in, ok_in, gnorm, stalled = _inner_adam(phi, c["w"], lower, upper, s, num["learning_rate"],
                                                         num["grad_tol"], active)
            n_acc = k_in
        u = to_u(w)
        fval, h, g = fu(u), heq(u), gin(u)
        fin = _all_finite(fval, h, g)
        ok = ok_in & fin
        viol = _violation(u, h, g, lower, upper)
        V = jnp.maximum(_max0(jnp.abs(h)), _max0(jnp.abs(jnp.maximum(g, -nu / mu))))
        lmax = num["multiplier_max"]
        lam2 = jnp.clip(lam + mu * h, -lmax, lmax)
        nu2 = jnp.clip(nu + mu * g, 0.0, lmax)
        mu2 = jnp.where(V > num["decrease"] * c["V_prev"], jnp.minimum(mu * num["growth"], num["mu_max"]), mu)
        scale = jnp.maximum(jnp.maximum(jnp.abs(fval), jnp.abs(c["f_prev"])), 1.0)
        # a stalled inner loop that accepted no step leaves f unchanged: that is no evidence of convergence
        conv = ((viol <= num["tol"]) & (jnp.abs(fval - c["f_prev"]) <= num["rel_tol"] * scale)
                & ~(stalled & (n_acc == 0)))
        keep = lambda new, old: jnp.where(ok, new, old)  # noqa: E731
        return dict(w=jnp.where(fin, w, c["w"]), lam=keep(lam2, lam), nu=keep(nu2, nu), mu=keep(mu2, mu),
                    k=c["k"] + 1, n_in=c["n_in"] + k_in, f_prev=keep(fval, c["f_prev"]),
                    V_prev=keep(V, c["V_prev"]), converged=ok & conv, nonfinite=~ok, gnorm=gnorm, stalled=stalled)

    c = lax.while_loop(cond, body, init)
    u = jnp.clip(to_u(c["w"]), lower, upper)
    fval, h, g = fu(u), heq(u), gin(u)
    viol = _violation(u, h, g, lower, upper)
    nonfinite = c["nonfinite"] | ~_all_finite(fval, viol)
    status = jnp.where(nonfinite, NON_FINITE,
                       jnp.where(empty_box, INFEASIBLE,
                                 jnp.where(c["converged"], CONVERGED,
                                           jnp.where(viol <= num["tol"], MAX_ITER, INFEASIBLE))))
    return SolverResult(u=u, f=fval, max_violation=viol, status=status.astype(jnp.int32),
                        outer_iterations=c["k"], inner_iterations=c["n_in"], lam_eq=c["lam"],
                        lam_ineq=c["nu"], mu=c["mu"], grad_norm=c["gnorm"], stalled=c["stalled"])


_STATIC_FNS = ("f", "eq", "ineq")


def _check_settings(settings):
    if not isinstance(settings, SolverSettings):
        raise TypeError(f"settings must be a SolverSettings, got {type(settings).__name__}")


def _strong(x):
    x = jnp.asarray(x)
    return x.astype(x.dtype) if getattr(x, "weak_type", False) else x


def _as_arrays(tree):
    """Every leaf as a strongly typed jax Array: jit keys NumPy and jax arrays, and weak and strong types,
    apart (each would be another compilation), so the public wrappers normalise once here."""
    return jax.tree_util.tree_map(_strong, tree)


def _prepare(u0, lower, upper, args, batched=False):
    u0 = _float_array(u0)
    if batched and (u0.ndim < 1 or u0.shape[0] < 1):
        raise ValueError(f"u0s must have a leading starts axis [S, ...] with S >= 1, got shape {u0.shape}")
    shape = u0.shape[1:] if batched else u0.shape
    return (u0, _bound(lower, -jnp.inf, shape, u0.dtype, "lower"), _bound(upper, jnp.inf, shape, u0.dtype, "upper"),
            _as_arrays(args))


@partial(jax.jit, static_argnames=_STATIC_FNS)
def _solve_jit(f, u0, lower, upper, eq, ineq, settings, args):
    return _solve(f, u0, lower, upper, eq, ineq, settings, args)


BATCH_MODES = ("vmap", "map")


@partial(jax.jit, static_argnames=_STATIC_FNS + ("batch",))
def _multistart_jit(f, u0s, lower, upper, eq, ineq, settings, args, batch="vmap"):
    one = lambda u0: _solve(f, u0, lower, upper, eq, ineq, settings, args)  # noqa: E731
    res = jax.vmap(one)(u0s) if batch == "vmap" else lax.map(one, u0s)
    return MultistartResult(results=res, best=best_index(res.f, res.max_violation,
                                                         jnp.asarray(settings.tol, u0s.dtype)))


@with_jitted(_solve_jit)
def solve_docp(f: Callable, u0, *, lower, upper, eq: Callable | None = None, ineq: Callable | None = None,
               settings: SolverSettings = _DEFAULT, args=None) -> SolverResult:
    """Solve min f(u, args) s.t. eq(u, args) = 0, ineq(u, args) <= 0, lower <= u <= upper.

    Jitted (:data:`solve_docp.jitted`); ``f``, ``eq``, ``ineq`` are static (hashed by identity), everything
    else -- u0, bounds, ``args`` (any pytree) and the numeric fields of ``settings`` -- is traced, so new
    values do not recompile.  Inputs are converted to jax arrays and the bounds broadcast to u0's shape before
    the jitted call (so NumPy/jax inputs, scalar/array/None bounds share one compilation).  Also usable inside
    ``jit``/``vmap``.

    Args:
        f: ``f(u, args) -> scalar``, smooth.
        u0: start, any shape (e.g. ``[N, 2]``); moved into the box (see ``SolverSettings.start_margin``).
        lower, upper: bounds broadcastable to u0's shape; ``None`` or ±inf for none.
        eq: ``eq(u, args) -> [m_e]`` (any shape, raveled), = 0 at a solution; None for none.
        ineq: ``ineq(u, args) -> [m_i]``, <= 0 at a solution; None for none.
        settings: :class:`SolverSettings` (static loop bounds/method, traced numeric values).
        args: pytree of data passed to f, eq and ineq.

    Returns:
        :class:`SolverResult` (status 0 ok/converged, 3 max-iter, 4 infeasible, 5 non-finite).
    """
    _check_settings(settings)
    u0, lower, upper, args = _prepare(u0, lower, upper, args)
    return _solve_jit(f, u0, lower, upper, eq, ineq, settings, args)


@with_jitted(_multistart_jit)
def solve_multistart(f: Callable, u0s, *, lower, upper, eq: Callable | None = None, ineq: Callable | None = None,
                     settings: SolverSettings = _DEFAULT, args=None, batch: str = "vmap") -> MultistartResult:
    """:func:`solve_docp` from each of the starts ``u0s [S, ...]`` (bounds, args and settings shared).

    ``batch="vmap"`` (default): ``jax.vmap`` over the starts -- the loops run in lockstep, every iteration
    costs the slowest start's line search and a ``lax.cond`` runs both branches, so on a CPU it is much slower
    than S separate solves (see docs/solver.md); ``batch="map"``: ``lax.map``, the starts one after another
    in one compiled call (identical results up to rounding), the faster choice on a CPU.

    Returns :class:`MultistartResult`: ``results`` with a leading [S] axis and ``best``, the lowest f among the
    starts with max_violation <= settings.tol, or the least violation when none is feasible.  Jitted
    (:data:`solve_multistart.jitted`), f/eq/ineq/batch static."""
    _check_settings(settings)
    if batch not in BATCH_MODES:
        raise ValueError(f"batch must be one of {BATCH_MODES}, got {batch!r}")
    u0s, lower, upper, args = _prepare(u0s, lower, upper, args, batched=True)
    return _multistart_jit(f, u0s, lower, upper, eq, ineq, settings, args, batch=batch)




def best_index(f, violation, tol):
    """Index of the best of S candidates: lowest f among those with finite f and violation <= tol; if none
    is feasible, the least finite violation; 0 when nothing is finite.  Traceable."""
    finite = jnp.isfinite(f) & jnp.isfinite(violation)
    feasible = finite & (violation <= tol)
    by_f = jnp.argmin(jnp.where(feasible, f, jnp.inf))
    by_v = jnp.argmin(jnp.where(finite, violation, jnp.inf))
    return jnp.where(jnp.any(feasible), by_f, by_v).astype(jnp.int32)


def max_violation(u, *, lower=None, upper=None, eq=None, ineq=None, args=None):
    """max(|eq(u)|, max(ineq(u), 0), box violation of u) -- the measure in :class:`SolverResult`."""
    u = _float_array(u)
    lower = _bound(lower, -jnp.inf, u.shape, u.dtype, "lower")
    upper = _bound(upper, jnp.inf, u.shape, u.dtype, "upper")
    h = _constraint(eq, args, u.dtype, "eq")(u)
    g = _constraint(ineq, args, u.dtype, "ineq")(u)
    return _violation(u, h, g, lower, upper)


def _better_or_equal(fa, va, fb, vb, tol):
    """Is candidate a at least as good as b?  Feasible (finite, violation <= tol) beats infeasible; among
    feasible the lower f wins (ties: a); among infeasible the lower violation wins; non-finite loses."""
    ok_a = jnp.isfinite(fa) & jnp.isfinite(va)
    ok_b = jnp.isfinite(fb) & jnp.isfinite(vb)
    feas_a, feas_b = ok_a & (va <= tol), ok_b & (vb <= tol)
    both_infeasible = jnp.where(ok_a & ok_b, va <= vb, ok_a)
    return jnp.where(feas_a & feas_b, fa <= fb, jnp.where(feas_a | feas_b, feas_a, both_infeasible))


def _safeguard(result: SolverResult, u_warm, f: Callable, *, lower=None, upper=None, eq=None, ineq=None,
               args=None, tol=1e-3) -> Safeguarded:
    u_warm = jnp.asarray(u_warm, result.u.dtype)
    stacked = u_warm.ndim == result.u.ndim + 1
    if (u_warm.shape[1:] if stacked else u_warm.shape) != result.u.shape:
        raise ValueError(f"u_warm must have the result's shape {result.u.shape} or be a stack [W, "
                         f"{', '.join(map(str, result.u.shape))}] of warm starts, got {u_warm.shape}")
    if stacked and u_warm.shape[0] == 0:
        raise ValueError("u_warm must hold at least one warm start, got an empty stack")
    tol = jnp.asarray(tol, result.u.dtype)
    objective = _objective(f, args, result.u.dtype)
    violation = partial(max_violation, lower=lower, upper=upper, eq=eq, ineq=ineq, args=args)
    if stacked:                                   # the reference: the best of the warm starts themselves
        f_all, v_all = jax.vmap(objective)(u_warm), jax.vmap(violation)(u_warm)
        index = best_index(f_all, v_all, tol)
        u_warm, f_w, v_w = u_warm[index], f_all[index], v_all[index]
    else:
        index = jnp.asarray(0, jnp.int32)
        f_w, v_w = objective(u_warm), violation(u_warm)
        f_all, v_all = f_w, v_w
    warm_ok = jnp.isfinite(f_w) & jnp.isfinite(v_w)
    keep = _better_or_equal(result.f, result.max_violation, f_w, v_w, tol)
    keep = keep & ~((result.status == NON_FINITE) & warm_ok)
    use_warm = ~keep
    return Safeguarded(u=jnp.where(use_warm, u_warm, result.u), f=jnp.where(use_warm, f_w, result.f),
                       max_violation=jnp.where(use_warm, v_w, result.max_violation), used_warm=use_warm,
                       warm_index=index, warm_f=f_all, warm_violation=v_all)


_safeguard_jit = jax.jit(_safeguard, static_argnames=_STATIC_FNS)


@with_jitted(_safeguard_jit)
def safeguard(result: SolverResult, u_warm, f: Callable, *, lower=None, upper=None, eq: Callable | None = None,
              ineq: Callable | None = None, args=None, tol=1e-3) -> Safeguarded:
    """Keep the solver's result only if it is at least as good as the warm start.

    Evaluates f and the max violation (the solver's measure, box included) at ``u_warm`` and returns
    :class:`Safeguarded` ``(u, f, max_violation, used_warm, warm_index, warm_f, warm_violation)``: the warm
    start (``used_warm=True``) when the result is less feasible (the warm start feasible -- violation <= tol --
    and the result not, or both infeasible and the result's violation larger), when both are feasible and the
    result's f is higher, or when the result's status is 3 (non-finite) and the warm start is finite.  Ties
    keep the result.

    ``u_warm`` is one warm start (the result's shape) or a stack ``[W, ...]`` of them; with a stack the
    reference is the best of the warm starts themselves by :func:`best_index` (feasible first, then the lowest
    f, ties to the lower index), whose index is ``warm_index`` (0 for a single warm start), so the kept
    sequence is never worse than any of them.  Jitted (f, eq, ineq static); also usable inside jit.
    """
    u_warm = _float_array(u_warm, result.u.dtype)
    shape = result.u.shape
    return _safeguard_jit(result, u_warm, f, lower=_bound(lower, -jnp.inf, shape, u_warm.dtype, "lower"),
                          upper=_bound(upper, jnp.inf, shape, u_warm.dtype, "upper"), eq=eq, ineq=ineq,
                          args=_as_arrays(args), tol=_as_arrays(tol))


__all__ = ["solve_docp", "solve_multistart", "safeguard", "max_violation", "best_index", "BATCH_MODES"]
