"""SB-MPC manoeuvring cost Γ: the original (Johansen et al. 2016, eq. 12 with the concrete forms of
Tengesdal et al. 2020, eqs. 10-13) and the smooth form of Smooth-SBMPC (Mahipala & Johansen 2024, eqs. 23-25);
docs/smooth_sbmpc.md "Smooth cost components".

Controls follow the library's layout: column 0 is the speed factor U_m [–], column 1 the course offset χ_m
[rad, positive = starboard].  "last" is the previously applied (U_m,last, χ_m,last).

* Γ_johansen(U_m, χ_m; U_last, χ_last) = k_U (1 − U_m) + k_χ(χ_m) χ_m² + Δ_U |U_m − U_last|
  + Δ_χ(side) (χ_m − χ_last)², with k_χ = k_χ,port if χ_m < 0 else k_χ,stbd and the Δ_χ side from the sign of
  the change χ_m − χ_last (``side="change"``, as docs/algorithm.md §8 and eq. 24) or of the new offset χ_m
  (``side="offset"``, Tengesdal et al. eq. 13).
* Γ_smooth(U_m, χ_m; U_last, χ_last) = k_U (1 − U_m)² + k_χ^mod(χ_m) χ_m² + Δ_U (U_m − U_last)²
  + Δ_χ^mod(Δχ) Δχ², Δχ = χ_m − χ_last, with the sigmoid-asymmetric weights (23)-(24)
  w^mod(z) = upper_port·sig(z; 0, −s) + upper_stbd·sig(z; 0, +s), s = ln 99 / (5° in rad) ≈ 52.6 rad⁻¹
  (the weight is the one-sided constant within 1 % for |z| ≥ 5°).

Offsets are not wrapped: SB-MPC bounds them to [−90°, 90°], so |χ_m − χ_last| ≤ 180°.
"""

from __future__ import annotations

import math

import jax.numpy as jnp

from ..ownship import maneuver_index
from .base import Context, TermValue
from .colregs_fuzzy import check_choice, check_param, sig
from .sbmpc import smooth_cost_term

#: Our proposed weights (Mahipala & Johansen 2024 give none): k_U, Δ_U (SB-MPC reference defaults), k_χ and Δ_χ
#: port/starboard (rad⁻², Tengesdal et al. 2020 Table 1).
DEFAULT_K_U = 2.5
DEFAULT_DELTA_U = 2.0
DEFAULT_K_CHI_PORT = 1.8
DEFAULT_K_CHI_STBD = 1.5
DEFAULT_DELTA_CHI_PORT = 1.2
DEFAULT_DELTA_CHI_STBD = 0.9
#: Slope of the port/starboard sigmoids: 1 % -> 99 % within ±5°.
DEFAULT_S_CHI = math.log(99.0) / math.radians(5.0)

FORMS = ("smooth", "johansen")
SIDES = ("change", "offset")
AGGREGATIONS = ("max", "sum")
WEIGHT_NAMES = ("k_U", "k_chi_port", "k_chi_stbd", "Delta_U", "Delta_chi_port", "Delta_chi_stbd")
PARAMS_ALL = WEIGHT_NAMES + ("s_chi",)


def check_weights(k_U=DEFAULT_K_U, k_chi_port=DEFAULT_K_CHI_PORT, k_chi_stbd=DEFAULT_K_CHI_STBD,
                  Delta_U=DEFAULT_DELTA_U, Delta_chi_port=DEFAULT_DELTA_CHI_PORT,
                  Delta_chi_stbd=DEFAULT_DELTA_CHI_STBD, s_chi=DEFAULT_S_CHI) -> None:
    """All weights ≥ 0, the sigmoid slope ``s_chi`` > 0 (ValueError naming the field otherwise)."""
    for name, v in zip(WEIGHT_NAMES, (k_U, k_chi_port, k_chi_stbd, Delta_U, Delta_chi_port, Delta_chi_stbd)):
        check_param(name, v, lo=0.0)
    check_param("s_chi", s_chi, lo=0.0, lo_open=True)


def side_weight(z, upper_port, upper_stbd, s_chi=DEFAULT_S_CHI):
    """Sigmoid-asymmetric weight (eqs. 23-24): upper_port·sig(z; 0, −s) + upper_stbd·sig(z; 0, +s) (lower
    limits 0): ≈ upper_port for z ≤ −5°, ≈ upper_stbd for z ≥ 5°, their mean at 0."""
    return upper_port * sig(z, 0.0, -s_chi) + upper_stbd * sig(z, 0.0, s_chi)


def gamma_smooth(u_m, chi_m, u_last, chi_last, *, k_U=DEFAULT_K_U, k_chi_port=DEFAULT_K_CHI_PORT,
                 k_chi_stbd=DEFAULT_K_CHI_STBD, Delta_U=DEFAULT_DELTA_U, Delta_chi_port=DEFAULT_DELTA_CHI_PORT,
                 Delta_chi_stbd=DEFAULT_DELTA_CHI_STBD, s_chi=DEFAULT_S_CHI):
    """Γ_smooth (eq. 25) for arrays (broadcast) of (U_m, χ_m) and the last applied (U_m,last, χ_m,last)."""
    check_weights(k_U, k_chi_port, k_chi_stbd, Delta_U, Delta_chi_port, Delta_chi_stbd, s_chi)
    du = u_m - u_last
    dchi = chi_m - chi_last
    return (k_U * (1.0 - u_m) ** 2 + side_weight(chi_m, k_chi_port, k_chi_stbd, s_chi) * chi_m * chi_m
            + Delta_U * du * du + side_weight(dchi, Delta_chi_port, Delta_chi_stbd, s_chi) * dchi * dchi)


def gamma_johansen(u_m, chi_m, u_last, chi_last, *, k_U=DEFAULT_K_U, k_chi_port=DEFAULT_K_CHI_PORT,
                   k_chi_stbd=DEFAULT_K_CHI_STBD, Delta_U=DEFAULT_DELTA_U, Delta_chi_port=DEFAULT_DELTA_CHI_PORT,
                   Delta_chi_stbd=DEFAULT_DELTA_CHI_STBD, side: str = "change"):
    """Γ_johansen (eq. 12 with constant asymmetric weights; piecewise smooth, kinks at χ = 0 and U = U_last)."""
    check_weights(k_U, k_chi_port, k_chi_stbd, Delta_U, Delta_chi_port, Delta_chi_stbd)
    check_choice("side", side, SIDES)
    dchi = chi_m - chi_last
    k_chi = jnp.where(chi_m < 0, k_chi_port, k_chi_stbd)
    port = (dchi < 0) if side == "change" else (chi_m < 0)
    d_chi = jnp.where(port, Delta_chi_port, Delta_chi_stbd)
    return k_U * (1.0 - u_m) + k_chi * chi_m * chi_m + Delta_U * jnp.abs(u_m - u_last) + d_chi * dchi * dchi


def gamma(u_m, chi_m, u_last, chi_last, *, form: str = "smooth", side: str = "change", **weights):
    """Γ of the chosen ``form`` (``"smooth"``: eq. 25; ``"johansen"``: eq. 12; ``side`` only for the latter)."""
    check_choice("form", form, FORMS)
    if form == "smooth":
        return gamma_smooth(u_m, chi_m, u_last, chi_last, **weights)
    weights = {k: v for k, v in weights.items() if k != "s_chi"}
    return gamma_johansen(u_m, chi_m, u_last, chi_last, side=side, **weights)


def gamma_sequence(controls, last, *, form: str = "smooth", side: str = "change", **weights):
    """Σ_k Γ(u_k; u_{k−1}) over a control sequence ``controls [..., N, 2]`` (speed factor, course offset) with
    u_{−1} = ``last [..., 2]`` (our reading SM-13, docs/algorithm.md §12: "last" inside the DOCP is the previous
    step's control, the applied one at τ₀). For N = 1 this is Γ of one constant behaviour (eq. 2). Returns
    ``[...]``."""
    c = jnp.asarray(controls)
    lst = jnp.asarray(last, c.dtype)
    if c.ndim < 2 or c.shape[-1] != 2 or c.shape[-2] < 1:
        raise ValueError(f"controls must be [..., N >= 1, 2] (speed factor, course offset), got {c.shape}")
    if lst.shape[-1:] != (2,):
        raise ValueError(f"last must be [..., 2] (speed factor, course offset), got {lst.shape}")
    prev = jnp.concatenate([jnp.broadcast_to(lst[..., None, :], c.shape[:-2] + (1, 2)), c[..., :-1, :]], axis=-2)
    g = gamma(c[..., 0], c[..., 1], prev[..., 0], prev[..., 1], form=form, side=side, **weights)
    return jnp.sum(g, axis=-1)


def per_step_controls(offsets, n_steps: int, dt, t_ts):
    """Expand per-maneuver offsets ``[B, n_M, 2]`` to per-step controls ``[B, N, 2]`` (maneuver m starts at
    step round(m t_ts / dt), as the rollout does; ``t_ts`` NaN means T / n_M)."""
    offsets = jnp.asarray(offsets)
    n_m = offsets.shape[1]
    t_ts = jnp.where(jnp.isnan(t_ts), n_steps * dt / n_m, t_ts)
    return offsets[:, maneuver_index(n_steps, n_m, t_ts, dt), :]


@smooth_cost_term("aggregation", "form", "side")
class SmoothManoeuvringTerm:
    """Γ of Smooth-SBMPC as a cost term (name ``"manoeuvring"``).

    ``aggregation="max"`` (initialisation stage, eq. 2): Γ once per behaviour, Γ(u; last) for a constant
    behaviour (n_M = 1); with n_M > 1 maneuvers, the chain Σ_m Γ(u_m; u_{m−1}), u_{−1} = last.
    ``aggregation="sum"`` (DOCP, eq. 27): Σ_{k=0}^{N−1} Γ(u_k; u_{k−1}) over the N per-step controls (the
    maneuvers expanded to steps; with per-step controls, n_M = N, the rows themselves), u_{−1} = the applied
    ``ctx.last_offsets`` (choice SM-13).  ``form``: ``"smooth"`` (eq. 25) or ``"johansen"`` (eq. 12; ``side`` picks
    the Δ_χ side rule)."""

    name = "manoeuvring"
    PARAMS = PARAMS_ALL

    k_U: float = DEFAULT_K_U
    k_chi_port: float = DEFAULT_K_CHI_PORT
    k_chi_stbd: float = DEFAULT_K_CHI_STBD
    Delta_U: float = DEFAULT_DELTA_U
    Delta_chi_port: float = DEFAULT_DELTA_CHI_PORT
    Delta_chi_stbd: float = DEFAULT_DELTA_CHI_STBD
    s_chi: float = DEFAULT_S_CHI
    aggregation: str = "max"
    form: str = "smooth"
    side: str = "change"

    def __post_init__(self):
        check_weights(**self.weights())
        check_choice("aggregation", self.aggregation, AGGREGATIONS)
        check_choice("form", self.form, FORMS)
        check_choice("side", self.side, SIDES)

    @property
    def smooth(self) -> bool:
        return self.form == "smooth"

    def weights(self) -> dict:
        return {n: getattr(self, n) for n in PARAMS_ALL}

    def __call__(self, ctx: Context, params, config, samples) -> TermValue:
        controls = ctx.offsets
        if self.aggregation == "sum":
            controls = per_step_controls(controls, ctx.t.shape[0] - 1, config.dt, params.t_ts)
        value = gamma_sequence(controls, ctx.last_offsets, form=self.form, side=self.side, **self.weights())
        return TermValue(value)

    def reference(self, own_traj, behaviour, situation, params, config, last_offsets=(1.0, 0.0)):
        from .. import reference_smooth as rs

        return rs.manoeuvring_cost(behaviour, last_offsets, n_steps=len(own_traj) - 1, dt=float(config.dt),
                                   t_ts=float(params.t_ts), aggregation=self.aggregation, form=self.form,
                                   side=self.side, **{k: float(v) for k, v in self.weights().items()})


__all__ = [
    "DEFAULT_K_U", "DEFAULT_DELTA_U", "DEFAULT_K_CHI_PORT", "DEFAULT_K_CHI_STBD", "DEFAULT_DELTA_CHI_PORT",
    "DEFAULT_DELTA_CHI_STBD", "DEFAULT_S_CHI", "FORMS", "SIDES", "side_weight", "gamma_smooth", "gamma_johansen",
    "gamma", "gamma_sequence", "per_step_controls", "check_weights", "SmoothManoeuvringTerm",
]
