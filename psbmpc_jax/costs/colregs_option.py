"""The COLREGS option (beyond the papers; docs/colregs_option.md): four cost terms that add the duties the
published PSB-MPC cost leaves out, for the grid-search methods of the PSB-MPC family.

Every term reads the encounter of each obstacle *now* (the first sample of its predictions and of the own-ship's
rollouts, the same for every behaviour), so the classification does not depend on the controls; the controls enter
only through the behaviour's offsets ``[B, n_M, 2]`` (speed factor u, course offset χ [rad], + = starboard) and
the applied ``last_offsets``.  Distances are multiples of the pair's safety radius R_i (``Context.radius``).

Encounter of obstacle i (own-ship at p_0 with course χ_0 and speed U_0; obstacle at p_i with velocity v_i):

* relative bearing β = wrap(atan2(Δy, Δx) − χ_0) (+ = starboard), relative course Δχ = wrap(χ_i − χ_0);
* nominal CPA: both keep their present velocities; t_cpa = max(0, −Δp·Δv / |Δv|²), d_cpa = |Δp + Δv t_cpa|;
  *closing* when Δp·Δv < 0;
* head-on: |β| < 22.5° and |wrap(Δχ − π)| < 22.5°; overtaken (own-ship stands on): |β| > 112.5°, U_i > U_0,
  |Δχ| < 67.5°; crossing with the target on the port side (own-ship stands on): β < 0, 0 < Δχ < π, not
  head-on (the whole port side: a target that drifts abaft the beam while crossing astern stays one to stand on
  for, as the encounter was judged when it began); crossing from starboard (own-ship gives way): 0 < β < 112.5°, −π < Δχ < 0, not head-on;
  overtaking (own-ship gives way): the own-ship more than 22.5° abaft the target's beam (|α| > 112.5°, α the
  bearing of the own-ship from the target relative to the target's course) and U_0 > U_i;
* engaged: valid, range < engage·R_i and not past and clear; past and clear: not closing and range > clear·R_i;
* risk: closing and d_cpa < act_cpa·R_i.

Terms (each ``[B]``, averaged over the n_M maneuvers; χ_{−1}, u_{−1} = ``last_offsets``):

* ``stand_on`` (Rule 17): while some engaged stand-on target is not yet a risk within act_range·R_i (the
  give-way vessel can still act), K_stand_on · mean_m[((χ_m − χ_{m−1})/χ_a)² + ((u_m − u_{m−1})/u_a)²] (keep
  course and speed); once a crossing target on the port side is a risk within that range, K_port · mean_m
  (min(χ_m, 0)/χ_a)² (Rule 17(c), a crossing rule: not to port for a crossing vessel on the port side).
* ``apparent`` (Rule 8(b)): while any target is engaged, K_apparent · mean_m[b(χ_m; χ_a) + b(χ_m − χ_{m−1}; χ_a)
  + b(1 − u_m; u_a)], b(z; a) = sin²(π z / a) for |z| < a, else 0: 0 for no alteration and for a readily
  apparent one, 1 at half the threshold (C¹).
* ``hold`` (Rule 8(d)/(e): keep the avoidance heading until past and clear): while any target is engaged,
  K_hold · mean_m (max(0, sign(χ_{m−1})(χ_{m−1} − χ_m))/χ_a)²: a course offset moving back toward (or past) the
  route.
* ``early`` (Rules 8(a), 16): while a give-way target (head-on, crossing from starboard, overtaking) is engaged
  and a risk, K_early · c(χ_0; χ_a), c(z; a) = cos²(π z / (2a)) for |z| < a, else 0 (C¹): the first maneuver
  must be a readily apparent course alteration from the range engage·R_i on.

The float64 NumPy oracle is :mod:`psbmpc_jax.reference_colregs_option`.
"""

from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import jax.numpy as jnp

from ..numerics import wrap_angle
from .base import Context, TermValue, cost_term
from .path import PathTerm, path_cost

D22 = math.radians(22.5)
D67 = math.radians(67.5)
D112 = math.radians(112.5)


def encounter(p0, chi0, u0, pi_, vi, radius, valid, *, engage, act_cpa, act_range, clear):
    """Per-obstacle flags ``[O]`` of the encounter now: own-ship position ``p0 (x, y)``, course, speed; obstacle
    positions ``pi_ (x [O], y [O])`` and velocities ``vi (vx [O], vy [O])``; ``radius [O]``; ``valid [O]``.
    Returns a dict of boolean arrays: ``engaged``, ``stand_on`` (engaged, and one to stand on for),
    ``stand_on_hold``, ``port_act``, ``give_way``."""
    dx, dy = pi_[0] - p0[0], pi_[1] - p0[1]
    v0x, v0y = u0 * jnp.cos(chi0), u0 * jnp.sin(chi0)
    dvx, dvy = vi[0] - v0x, vi[1] - v0y
    rng = jnp.sqrt(dx * dx + dy * dy)
    dot = dx * dvx + dy * dvy
    dv2 = dvx * dvx + dvy * dvy
    t_cpa = jnp.where(dv2 > 0, jnp.maximum(0.0, -dot / jnp.where(dv2 > 0, dv2, 1.0)), 0.0)
    d_cpa = jnp.sqrt((dx + dvx * t_cpa) ** 2 + (dy + dvy * t_cpa) ** 2)
    closing = dot < 0
    beta = wrap_angle(jnp.arctan2(dy, dx) - chi0)
    ui = jnp.sqrt(vi[0] ** 2 + vi[1] ** 2)
    dchi = wrap_angle(jnp.arctan2(vi[1], vi[0]) - chi0)
    head_on = (jnp.abs(beta) < D22) & (jnp.abs(wrap_angle(dchi - math.pi)) < D22)
    overtaken = (jnp.abs(beta) > D112) & (ui > u0) & (jnp.abs(dchi) < D67)
    cross_port = (beta < 0) & (dchi > 0) & ~head_on
    cross_stbd = (beta > 0) & (beta < D112) & (dchi < 0) & ~head_on
    alpha = wrap_angle(jnp.arctan2(-dy, -dx) - jnp.arctan2(vi[1], vi[0]))       # own-ship seen from the target
    overtaking = (jnp.abs(alpha) > D112) & (u0 > ui)
    clear_ = ~closing & (rng > clear * radius)
    engaged = valid & (rng < engage * radius) & ~clear_
    risk = closing & (d_cpa < act_cpa * radius)
    may_act = risk & (rng < act_range * radius)
    stand_on = engaged & (cross_port | overtaken) & ~overtaking
    # Rule 17(c) is a crossing rule: an overtaking target dead astern has no defined side (β = ±180° flips with noise)
    port_act = engaged & cross_port & ~overtaking & may_act
    return {"engaged": engaged, "stand_on": stand_on, "stand_on_hold": stand_on & ~may_act, "port_act": port_act,
            "give_way": engaged & risk & (head_on | cross_stbd | overtaking)}


def context_encounter(ctx: Context, term) -> dict:
    """:func:`encounter` of a :class:`Context`: the own-ship and scenario 0 of every obstacle at sample 0."""
    own, obs = ctx.own, ctx.obstacles
    return encounter((own.x[0, 0], own.y[0, 0]), own.chi[0, 0], own.U[0, 0], (obs.x[0, :, 0], obs.y[0, :, 0]),
                     (obs.vx[0, :, 0], obs.vy[0, :, 0]), ctx.radius, ctx.scen_valid[:, 0], engage=term.engage_radii,
                     act_cpa=term.act_cpa_radii, act_range=term.act_range_radii, clear=term.clear_radii)


def previous(offsets, last):
    """The offsets one maneuver earlier ``[B, n_M, 2]``: maneuver m's predecessor, ``last`` for m = 0."""
    first = jnp.broadcast_to(jnp.asarray(last, offsets.dtype), offsets[:, :1].shape)
    return jnp.concatenate([first, offsets[:, :-1]], axis=1)


def bump(z, a):
    """b(z; a) = sin²(π z / a) for |z| < a, else 0 (0 at z = 0 and |z| = a, 1 at |z| = a/2; C¹)."""
    return jnp.where(jnp.abs(z) < a, jnp.sin(math.pi * z / a) ** 2, 0.0)


def step_down(z, a):
    """c(z; a) = cos²(π z / (2a)) for |z| < a, else 0 (1 at z = 0, 0 from |z| = a on; C¹)."""
    return jnp.where(jnp.abs(z) < a, jnp.cos(0.5 * math.pi * z / a) ** 2, 0.0)


def stand_on_cost(offsets, last, hold, port, *, chi_a, du_a, K_stand_on, K_port):
    """``[B]``: keep course and speed (``hold``, a scalar bool) / no port offset (``port``)."""
    prev = previous(offsets, last)
    keep = jnp.mean(((offsets[..., 1] - prev[..., 1]) / chi_a) ** 2 + ((offsets[..., 0] - prev[..., 0]) / du_a) ** 2,
                    axis=1)
    to_port = jnp.mean((jnp.minimum(offsets[..., 1], 0.0) / chi_a) ** 2, axis=1)
    return jnp.where(hold, K_stand_on * keep, 0.0) + jnp.where(port, K_port * to_port, 0.0)


def apparent_cost(offsets, last, engaged, *, chi_a, du_a, K_apparent):
    """``[B]``: Rule 8(b) small alterations while ``engaged`` (scalar bool)."""
    prev = previous(offsets, last)
    chi = offsets[..., 1]
    per_m = bump(chi, chi_a) + bump(chi - prev[..., 1], chi_a) + bump(1.0 - offsets[..., 0], du_a)
    return jnp.where(engaged, K_apparent * jnp.mean(per_m, axis=1), 0.0)


def hold_cost(offsets, last, engaged, *, chi_a, K_hold):
    """``[B]``: a course offset moving back toward the route while ``engaged`` (scalar bool)."""
    prev = previous(offsets, last)[..., 1]
    back = jnp.maximum(0.0, jnp.sign(prev) * (prev - offsets[..., 1])) / chi_a
    return jnp.where(engaged, K_hold * jnp.mean(back * back, axis=1), 0.0)


def early_cost(offsets, give_way, *, chi_a, K_early):
    """``[B]``: no readily apparent first course alteration while a give-way target is a risk (``give_way``)."""
    return jnp.where(give_way, K_early * step_down(offsets[:, 0, 1], chi_a), 0.0)



@dataclasses.dataclass(frozen=True)
class _Thresholds:
    """The encounter thresholds every option term reads (multiples of the pair's safety radius R_i, and the
    smallest readily apparent course change); each term adds its own weights."""

    engage_radii: float = 40.0
    act_cpa_radii: float = 2.0
    act_range_radii: float = 4.0
    clear_radii: float = 4.0
    chi_apparent: float = math.radians(30.0)


def _option_term(name: str):
    def deco(cls):
        cls.name = name
        cls.PARAMS = ()
        cls.smooth = True
        return cost_term(cls)
    return deco


@_option_term("stand_on")
class StandOnTerm(_Thresholds):
    """Rule 17 stand-on duty (module docstring).  Details: ``stand_on_hold [B]``, ``stand_on_port [B]`` (0/1)."""

    du_apparent: float = 0.5
    K_stand_on: float = 10000.0
    K_port: float = 10000.0

    def __call__(self, ctx: Context, params, config, samples) -> TermValue:
        e = context_encounter(ctx, self)
        hold, port = jnp.any(e["stand_on_hold"]), jnp.any(e["port_act"])
        value = stand_on_cost(ctx.offsets, ctx.last_offsets, hold, port, chi_a=self.chi_apparent,
                              du_a=self.du_apparent, K_stand_on=self.K_stand_on, K_port=self.K_port)
        ones = jnp.ones_like(value)
        return TermValue(value, {"stand_on_hold": ones * hold, "stand_on_port": ones * port})


@_option_term("apparent")
class ApparentTerm(_Thresholds):
    """Rule 8(b) readily apparent alterations (module docstring)."""

    du_apparent: float = 0.5
    K_apparent: float = 100.0

    def __call__(self, ctx: Context, params, config, samples) -> TermValue:
        engaged = jnp.any(context_encounter(ctx, self)["engaged"])
        return TermValue(apparent_cost(ctx.offsets, ctx.last_offsets, engaged, chi_a=self.chi_apparent,
                                       du_a=self.du_apparent, K_apparent=self.K_apparent))


@_option_term("hold")
class HoldTerm(_Thresholds):
    """Hold the avoidance heading until past and clear (module docstring)."""

    K_hold: float = 100.0

    def __call__(self, ctx: Context, params, config, samples) -> TermValue:
        engaged = jnp.any(context_encounter(ctx, self)["engaged"])
        return TermValue(hold_cost(ctx.offsets, ctx.last_offsets, engaged, chi_a=self.chi_apparent, K_hold=self.K_hold))


@_option_term("early")
class EarlyTerm(_Thresholds):
    """Early, readily apparent action by the give-way vessel (module docstring)."""

    K_early: float = 100.0

    def __call__(self, ctx: Context, params, config, samples) -> TermValue:
        give_way = jnp.any(context_encounter(ctx, self)["give_way"])
        return TermValue(early_cost(ctx.offsets, give_way, chi_a=self.chi_apparent, K_early=self.K_early))


def held_path_cost(offsets, last, params, engaged):
    """``[B]``: H_p (:func:`psbmpc_jax.costs.path.path_cost`) with its course-deviation weights K_chi_port and
    K_chi_stbd set to 0 while ``engaged`` (scalar bool; :class:`HeldPathTerm`: some target engaged and none to
    stand on for): holding a course offset costs nothing then, so the planner has no reason to return to the
    route before the target is past and clear."""
    weights = SimpleNamespace(**{k: getattr(params, k) for k in PathTerm.PARAMS})
    weights.K_chi_port = jnp.where(engaged, 0.0, params.K_chi_port)
    weights.K_chi_stbd = jnp.where(engaged, 0.0, params.K_chi_stbd)
    return path_cost(offsets, last, weights)


@cost_term
class HeldPathTerm(_Thresholds):
    """The path term H_p (column ``path``) with its course-deviation part weighted off while some target is engaged
    and none is one to stand on for (``hold_path``; replaces :class:`~psbmpc_jax.costs.path.PathTerm`, same
    parameters).  A stand-on vessel keeps the published weights: its late action (Rule 17(b)) is best small and
    brief, and without them its return to the route came late and as one port turn the evaluator penalises."""

    name = "path"
    PARAMS = PathTerm.PARAMS
    smooth = True

    def __call__(self, ctx: Context, params, config, samples) -> TermValue:
        e = context_encounter(ctx, self)
        held = jnp.any(e["engaged"]) & ~jnp.any(e["stand_on"])
        return TermValue(held_path_cost(ctx.offsets, ctx.last_offsets, params, held))


def with_held_path(terms, spec) -> tuple:
    """``terms`` with the path term replaced by :class:`HeldPathTerm` (the spec's thresholds) when the option is
    enabled with ``hold_path``; unchanged otherwise (and for a cost without :class:`PathTerm`)."""
    if not (spec.enabled and spec.hold_path):
        return tuple(terms)
    held = _from_spec(HeldPathTerm, spec)
    return tuple(held if isinstance(t, PathTerm) else t for t in terms)


TERM_CLASSES: dict[str, type] = {"stand_on": StandOnTerm, "apparent": ApparentTerm, "hold": HoldTerm, "early": EarlyTerm}


def option_terms(spec) -> tuple:
    """The terms a :class:`~psbmpc_jax.methods.colregs_option_settings.ColregsOptionSpec` switches on (empty when
    it is not enabled), each with the spec's thresholds and its weight."""
    return tuple(_from_spec(TERM_CLASSES[key], spec) for key in spec.active())


#: The spec's settings an option term may take (its thresholds and weights).
_SPEC_FIELDS = ("engage_radii", "act_cpa_radii", "act_range_radii", "clear_radii", "chi_apparent", "du_apparent",
                "K_stand_on", "K_port", "K_apparent", "K_hold", "K_early")


def _from_spec(cls, spec):
    """The option term ``cls`` with the spec's values of those of its fields in :data:`_SPEC_FIELDS`."""
    names = {f.name for f in dataclasses.fields(cls)}
    return cls(**{k: getattr(spec, k) for k in _SPEC_FIELDS if k in names})


__all__ = ["encounter", "bump", "step_down", "stand_on_cost", "apparent_cost", "hold_cost", "early_cost",
           "StandOnTerm", "ApparentTerm", "HoldTerm", "EarlyTerm", "TERM_CLASSES", "option_terms", "held_path_cost",
           "HeldPathTerm", "with_held_path"]
