"""Ground-avoiding constant-velocity target prediction of Mahipala & Johansen (MED 2023, Sec. III, eq. 2;
docs/two_level_prediction.md).

A target with state (x, y, χ, U) (NED: x north, y east [m], course χ [rad] clockwise from north, speed U
[m/s], constant) is predicted over k = 0..n_steps, step ``dt`` [s]:

    p_{k+1} = p_k + dt U (cos χ_k, sin χ_k)
    χ_{k+1} = χ_k                 if d_LOSg(k) >= d_critical
            = χ_k + β             if d_LOSg(β+) >= d_LOSg(k)          (compare="plus", the printed eq. 2)
            = χ_k − β             otherwise

* **Ordering (follows the equation literally).** Step k moves the target with the course χ_k it holds, and
  χ_{k+1} is decided from the *same* p_k and χ_k: d_LOSg(k) is measured from p_k along χ_k, d_LOSg(β±) from
  p_k along χ_k ± β.  So the course decided at step k first acts on the move p_{k+1} → p_{k+2}; courses[k]
  is always the course flown from p_k to p_{k+1}.
* **d_LOSg** is the distance from p_k to the first land point on its course ray: the smallest t >= 0 with
  p_k + t (cos χ, sin χ) on a land edge (edges are closed: a ray through a vertex or grazing one hits), 0 when
  p_k is inside land, +inf when nothing is hit within ``max_range`` (treated as clear).  The ray/edge test
  (:func:`psbmpc_jax.smooth.land_hit.ray_edge_t`) is robust at vertices: a ray through a vertex cannot slip between its two edges.
  Rays are capped at ``max_range`` (default 2 d_critical, our proposal: the paper gives no range).
* **β** is a per-step angle [rad] (β > 0 = starboard turn in NED): the proposed 5° per step holds for dt = 1 s
  as given; it is *not* rescaled with ``dt`` (a turn rate of β / dt).  Ties (both rays equally clear, or both
  clear) turn to +β.
* ``compare="both"`` (the option of choice TL-2, docs/algorithm.md §15): compare d_LOSg(β+) with d_LOSg(β−) and turn
  to the larger (ties → +β). The paper's text says "least ... distance to the ground" while the equation turns towards
  more clearance; the default follows the equation.
* Courses are not wrapped (χ_k = χ_0 + m β for an integer m); U is held constant.

Inside test: even–odd rule per polygon (its rings, i.e. holes, back to back as packed by
:func:`psbmpc_jax.packing.pack_world`), then "inside any polygon".  For interior-disjoint polygons this is
the one even–odd parity over all the chart's edges that :func:`psbmpc_jax.smooth.corridor.corridor_kernel`
uses; unlike that parity it stays right for overlapping polygons (the raw chart of a situation is not a union).
The ray distance itself is the first hit over *every* edge, which from outside land is a point of the union's
boundary whether or not the polygons overlap.

:func:`ray_land_distance` and :func:`ground_avoiding_cv` are traceable kernels (no validation, no gradient
through the ray casts); :func:`predict_targets` is the validated, jitted entry point.  The chart is a
:class:`~psbmpc_jax.packing.ChartArrays` (:func:`psbmpc_jax.packing.pack_world`, *unbuffered* land), visited in
blocks of edge slots (:func:`psbmpc_jax.smooth.land_hit.edge_blocks`) with exact culling: blocks whose box
misses every ray's box skip the ray test, blocks that no origin's +x ray can cross skip the parity.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from ..methods.two_level_settings import TwoLevelSpec
from ..packing import ChartArrays
from ..smooth.land_hit import (DEFAULT_BLOCK, as_chart, box_near, concrete_float, crossings, cull_tolerance,
                               edge_blocks, may_cross, ray_edge_t)

#: Our proposed defaults (the paper gives no numbers): β = 5° per step at dt = 1 s, d_critical = 50 m, ray range 2
#: d_critical (defined once, by the scenario files' ``mpc.two_level.prediction`` section).
DEFAULT_BETA = TwoLevelSpec.beta
DEFAULT_D_CRITICAL = TwoLevelSpec.d_critical
DEFAULT_DT = 1.0
COMPARE_MODES = ("plus", "both")


class TargetPrediction(NamedTuple):
    """Predicted targets (a leading ``[n_targets]`` axis, absent for a single state ``[4]``).

    ``positions [..., n_steps+1, 2]`` (north, east) [m], p_0 = the state's position; ``courses [...,
    n_steps+1]`` [rad] (courses[k] is flown from p_k to p_{k+1}; courses[0] = χ_0); ``d_los [..., n_steps]``:
    d_LOSg(k) [m] from p_k along courses[k] (0 inside land, +inf when clear within max_range), the value that
    decided courses[k+1]."""

    positions: jax.Array
    courses: jax.Array
    d_los: jax.Array


# --------------------------------------------------------------------------------------------- kernels
def ray_land_distance(origins, directions, chart: ChartArrays, max_range, block: int = DEFAULT_BLOCK) -> jax.Array:
    """d_LOSg of rays ``origins [R, 2]`` (north, east) [m] along the courses ``directions [R]`` [rad]: per ray the
    smallest t >= 0 with origin + t (cos χ, sin χ) on a closed land edge, +inf when there is none within
    ``max_range`` [m] (scalar or ``[R]``; +inf allowed), 0 when the origin is inside land (even–odd per
    polygon, see the module docstring).  ``chart``: :class:`~psbmpc_jax.packing.ChartArrays` (an empty chart
    gives +inf everywhere).  ``block`` (static): edge slots visited at once.  Traceable, no validation,
    no gradient (the result is ``stop_gradient``-ed)."""
    O = lax.stop_gradient(jnp.asarray(origins))
    dtype = O.dtype
    chi = lax.stop_gradient(jnp.asarray(directions, dtype))
    R = O.shape[0]
    rng = lax.stop_gradient(jnp.broadcast_to(jnp.asarray(max_range, dtype), (R,)))
    ox, oy = O[:, 0:1], O[:, 1:2]                                                   # [R, 1]
    dx, dy = jnp.cos(chi)[:, None], jnp.sin(chi)[:, None]
    inf = jnp.asarray(jnp.inf, dtype)
    if R == 0:
        return jnp.zeros((0,), dtype)
    blocks = edge_blocks(chart, block, per_polygon=True)
    reach = jnp.max(rng)
    olo, ohi = O.min(0), O.max(0)
    rlo, rhi = olo - reach, ohi + reach            # every ray's box (a square: no inf * 0 for an infinite range)
    tol = cull_tolerance(olo, ohi)

    def per_block(carry, blk):
        tmin, parity, inside = carry
        e, v, start, lo, hi = blk
        inside = inside | (start & parity)          # a new polygon closes the previous one's parity
        parity = jnp.where(start, False, parity)
        tmin = lax.cond(box_near(lo, hi, rlo, rhi, tol),
                        lambda: jnp.minimum(tmin, jnp.min(jnp.where(v, ray_edge_t(ox, oy, dx, dy, e), inf), axis=1)),
                        lambda: tmin)
        parity = lax.cond(may_cross(lo, hi, olo, ohi, tol),
                          lambda: parity ^ (jnp.sum(v & crossings(ox, oy, e), axis=1) % 2 == 1), lambda: parity)
        return (tmin, parity, inside), None

    zeros = jnp.zeros(R, bool)
    (tmin, parity, inside), _ = lax.scan(
        per_block, (jnp.full(R, inf), zeros, zeros),
        lax.stop_gradient((blocks.edges, blocks.valid, blocks.first, blocks.lo, blocks.hi)))
    inside = inside | parity
    d = jnp.where(tmin <= rng, tmin, inf)
    return jnp.where(inside, jnp.zeros_like(d), d)


def ground_avoiding_cv(state, chart: ChartArrays, n_steps: int, dt, *, beta, d_critical, max_range=None,
                       compare: str = "plus", block: int = DEFAULT_BLOCK) -> TargetPrediction:
    """Eq. (2) for ``state [n_targets, 4]`` or ``[4]`` as (x, y, χ, U) over k = 0..``n_steps`` (module
    docstring): a ``lax.scan`` over the steps, vectorised over the targets (2 rays per target and step, 3 with
    ``compare="both"``).  ``beta`` [rad per step], ``d_critical`` [m], ``max_range`` [m] (default
    2 d_critical): scalars or ``[n_targets]``; ``dt`` [s] scalar.  ``n_steps``, ``compare`` and ``block`` are
    static.  Traceable, no validation (see :func:`predict_targets`)."""
    if compare not in COMPARE_MODES:
        raise ValueError(f"compare must be one of {COMPARE_MODES}, got {compare!r}")
    s = jnp.asarray(state)
    if not jnp.issubdtype(s.dtype, jnp.floating):
        s = s.astype(jnp.result_type(float))
    single = s.ndim == 1
    s = s.reshape(-1, 4)
    n, dtype = s.shape[0], s.dtype
    per = lambda x: jnp.broadcast_to(jnp.asarray(x, dtype), (n,))
    beta, d_crit = per(beta), per(d_critical)
    rng = 2.0 * d_crit if max_range is None else per(max_range)
    step = jnp.asarray(dt, dtype) * s[:, 3]                                         # dt U [n]
    signs = (0.0, 1.0, -1.0) if compare == "both" else (0.0, 1.0)
    n_rays = len(signs)

    def one_step(carry, _):
        p, chi = carry
        dirs = jnp.concatenate([chi + sg * beta for sg in signs])                   # [n_rays n]
        d = ray_land_distance(jnp.tile(p, (n_rays, 1)), dirs, chart, jnp.tile(rng, n_rays), block)
        d0, dp = d[:n], d[n:2 * n]
        other = d[2 * n:] if compare == "both" else d0
        turn = jnp.where(dp >= other, beta, -beta)
        chi_next = jnp.where(d0 >= d_crit, chi, chi + turn)
        p_next = p + step[:, None] * jnp.stack([jnp.cos(chi), jnp.sin(chi)], axis=1)
        return (p_next, chi_next), (p_next, chi_next, d0)

    p0, chi0 = s[:, :2], s[:, 2]
    _, (ps, chis, d0s) = lax.scan(one_step, (p0, chi0), None, length=int(n_steps))
    positions = jnp.concatenate([p0[:, None], jnp.swapaxes(ps, 0, 1)], axis=1)
    courses = jnp.concatenate([chi0[:, None], jnp.swapaxes(chis, 0, 1)], axis=1)
    d_los = jnp.swapaxes(d0s, 0, 1)
    if single:
        positions, courses, d_los = positions[0], courses[0], d_los[0]
    return TargetPrediction(positions, courses, d_los)


_predict_jit = jax.jit(ground_avoiding_cv, static_argnames=("n_steps", "compare", "block"))


# --------------------------------------------------------------------------------------------- validation
def _per_target(value, name: str, n: int, *, lo: float, hi: float = math.inf, lo_open: bool = True,
                allow_inf: bool = False, what: str = ""):
    """A scalar or ``[n]`` float parameter with every (concrete) entry finite (or +inf with ``allow_inf``) and
    in (lo, hi) (``lo_open``) / [lo, hi)."""
    if isinstance(value, bool) or np.ndim(value) not in (0, 1) or (np.ndim(value) == 1 and np.shape(value) != (n,)):
        raise ValueError(f"{name} must be a scalar or an array [n_targets = {n}] {what}, got shape "
                         f"{np.shape(value)}")
    if isinstance(value, jax.core.Tracer):
        return value
    arr = np.asarray(value)
    if arr.dtype.kind not in "iuf":
        raise ValueError(f"{name} must be numeric {what}, got dtype {arr.dtype}")
    arr = arr.astype(float)
    finite = np.isfinite(arr) | (allow_inf & (arr == np.inf))
    bad = ~finite | (arr <= lo if lo_open else arr < lo) | ((arr >= hi) if math.isfinite(hi) else False)
    if np.any(bad):
        rel = ">" if lo_open else ">="
        bound = ("finite or +inf" if allow_inf else "finite") + f", {rel} {lo:g}" + (
            f" and < {hi:g}" if math.isfinite(hi) else "")
        raise ValueError(f"{name} must be {bound} {what}, got {arr[bad].ravel()[0]!r}")
    return value


def _check_state(state):
    shape = np.shape(state)
    if len(shape) not in (1, 2) or shape[-1] != 4 or (len(shape) == 2 and shape[0] < 1):
        raise ValueError(f"state must have shape [4] or [n_targets >= 1, 4] as (x north [m], y east [m], "
                         f"course chi [rad], speed U [m/s]), got {shape}")
    if isinstance(state, jax.core.Tracer):
        return
    arr = np.asarray(state)
    if arr.dtype.kind not in "iuf":
        raise ValueError(f"state must be numeric, got dtype {arr.dtype}")
    if not np.all(np.isfinite(arr)):
        raise ValueError("state must be finite (no NaN/inf)")
    if np.any(arr[..., 3] < 0):
        raise ValueError(f"state speed U (state[..., 3]) must be >= 0 m/s, got {arr[..., 3].min()!r}")


def _check_static_int(value, name: str, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


# --------------------------------------------------------------------------------------------- public
def predict_targets(state, chart, n_steps: int, dt=DEFAULT_DT, *, beta=DEFAULT_BETA,
                    d_critical=DEFAULT_D_CRITICAL, max_range=None, compare: str = "plus",
                    block: int = DEFAULT_BLOCK) -> TargetPrediction:
    """Validated, jitted :func:`ground_avoiding_cv`: the ground-avoiding CV prediction (eq. 2) of targets
    ``state [n_targets, 4]`` (or one ``[4]``) as (x north [m], y east [m], χ [rad], U [m/s] >= 0) against the
    *unbuffered* land ``chart`` (:class:`~psbmpc_jax.packing.ChartArrays` or the ``WorldArrays`` holding it)
    over ``n_steps`` (integer >= 1) steps of ``dt`` > 0 [s].

    ``beta``: course change per step [rad], finite, 0 < β < π (default 5°; per step, not rescaled with dt);
    ``d_critical`` > 0 [m] (default 50); ``max_range`` > 0 [m] (+inf: uncapped) or None (= 2 d_critical),
    each a scalar or one value per target; ``compare``: ``"plus"`` (eq. 2: d(β+) against d_LOSg) or
    ``"both"`` (d(β+) against d(β−)).  Raises ``ValueError`` naming the field on a bad value; traced values
    are checked by shape only."""
    _check_state(state)
    chart = as_chart(chart)
    n_steps = _check_static_int(n_steps, "n_steps", 1)
    block = _check_static_int(block, "block", 1)
    if not isinstance(compare, str) or compare not in COMPARE_MODES:
        raise ValueError(f"compare must be one of {COMPARE_MODES}, got {compare!r}")
    if np.ndim(dt) != 0 or isinstance(dt, bool):
        raise ValueError(f"dt must be a scalar [s], got shape {np.shape(dt)}")
    v = concrete_float(dt)
    if v is not None and (not math.isfinite(v) or v <= 0):
        raise ValueError(f"dt must be a finite number > 0 [s], got {v}")
    n = 1 if np.ndim(state) == 1 else np.shape(state)[0]
    _per_target(beta, "beta", n, lo=0.0, hi=math.pi, what="[rad per step]")
    _per_target(d_critical, "d_critical", n, lo=0.0, what="[m]")
    if max_range is not None:
        _per_target(max_range, "max_range", n, lo=0.0, allow_inf=True, what="[m] (+inf: uncapped rays)")
    s = jnp.asarray(state)
    if not jnp.issubdtype(s.dtype, jnp.floating):
        s = s.astype(jnp.asarray(chart.vertices).dtype)
    dtype = s.dtype
    per = lambda x: jnp.broadcast_to(jnp.asarray(x, dtype), (n,))   # one shape per n: one compilation
    d_crit = per(d_critical)
    rng = 2.0 * d_crit if max_range is None else per(max_range)
    out = _predict_jit(s.reshape(n, 4), chart, n_steps, jnp.asarray(dt, dtype), beta=per(beta), d_critical=d_crit,
                       max_range=rng, compare=compare, block=block)
    if np.ndim(state) == 1:
        out = TargetPrediction(*(a[0] for a in out))
    return out


__all__ = ["TargetPrediction", "ray_land_distance", "ground_avoiding_cv", "predict_targets",
           "DEFAULT_BETA", "DEFAULT_D_CRITICAL", "DEFAULT_DT", "COMPARE_MODES"]
