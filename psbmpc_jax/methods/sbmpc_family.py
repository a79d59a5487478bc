"""The SB-MPC family as cost-term sets of the one grid search (:func:`psbmpc_jax.solve.solve`).

Every method below searches the same behaviour table with the same evaluator; only the cost terms (and the
obstacle prediction they assume) differ -- one objective, several aggregations:

===============  ===========================================================================================
``psbmpc``       the PSB-MPC cost of Tengesdal et al. 2022 (:data:`psbmpc_jax.evaluate.DEFAULT_TERMS`):
                 Σ_i w_i Σ_s P_s max_k(C P̂ e^{−t/T_d}) + κ-COLREGS + grounding + path; LOS scenarios
``sbmpc``        the original SB-MPC (Johansen, Perez & Cristofaro 2016):
                 max_i max_{k≥1} (K_coll‖Δv‖²·R + κ·μ) + Γ, with the ad hoc risk R = k^{−p}(d_safe/d)^q inside
                 d_safe, the Boolean COLREGS indicator μ, Γ of Tengesdal et al. 2020 eqs. (10)-(13);
                 straight-line (constant-velocity) targets, one scenario
``psbmpc_2020``  the first probabilistic SB-MPC (Tengesdal, Brekke & Johansen 2020, eq. 20):
                 max_i (Σ_k C·P̂·e^{−(t_k + t_cpa − t₀)/T_c} + κ Σ_k μ) + Γ, P̂ the Monte-Carlo 4-D CPA
                 probability smoothed by a scalar Kalman filter along the horizon
                 (:mod:`psbmpc_jax.costs.mcskf`), the track covariance held constant; straight-line targets
===============  ===========================================================================================

Both SB-MPC variants optionally add the PSB-MPC grounding term (``grounding=True``; the 2020 paper has no land,
g = 0; on a chart the ship would otherwise ignore it).  Their parameters are one frozen
:class:`SbmpcSettings` (scenario files: ``mpc.sbmpc``); the default preset ``tengesdal2020`` is Table 1
of Tengesdal, Brekke & Johansen 2020 with proposed values for what the paper leaves out.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from .. import checks
from ..checks import integer, show
from ..config import as_bool, as_mapping, as_number, check_keys

# the cost terms are imported where they are built: loading a scenario (which reads SbmpcSettings) must not
# import JAX (tests/test_scenario_checks.py)

#: SbmpcSettings fields that must be > 0 (the others >= 0).
_POSITIVE = ("d_safe", "d_cl", "T_c", "r_P", "V0")
#: Grid-search methods whose cost terms this module builds.
SBMPC_FAMILY = ("sbmpc", "psbmpc_2020")


@dataclass(frozen=True)
class SbmpcSettings:
    """Parameters of ``sbmpc`` and ``psbmpc_2020`` (SI units; Tengesdal, Brekke & Johansen 2020, Table 1, unless marked).

    Attributes:
        d_safe: safety-zone radius [m] (bare, no ship-size addition; Table 1: 40 m).
        K_coll: collision-cost weight of C = K_coll‖v_o − v_i‖² [(s/m)²] (not in the paper; our proposal 1).
        p, q: exponents of the ad hoc risk R (SB-MPC only; "typical" 1 and 4).
        kappa: COLREGS weight κ (Table 1: 10).
        lambda_T: weight λ of the COLREGS-transitional term of Johansen et al. 2016 eq. (11) (``sbmpc``; 0 = off,
            our choice; the papers give no value).
        d_cl: COLREGS range of the Boolean indicator [m] (not in the paper; our proposal 200).
        k_U, Delta_U: speed-reduction weight K_u and speed-change weight K_Δu (Table 1: 9, 8).
        k_chi_port, k_chi_stbd: course-offset weights K_χ [rad⁻²] (Table 1: 1.8, 1.5).
        Delta_chi_port, Delta_chi_stbd: course-change weights K_Δχ [rad⁻²] (Table 1: 1.2, 0.9); the side is the
            sign of the NEW offset (eq. 13).
        T_c: discount time constant of eq. (20) [s] (psbmpc_2020; Table 1: 6).
        n_mc: Monte-Carlo samples per prediction step (psbmpc_2020; Table 1: 100).
        q_P, r_P: process and measurement variances of the probability's scalar Kalman filter (Table 1).
        V0: prior variance of that filter (its prior mean is 0; §5, §7: 0.3).
        seed: seed of the standard-normal sample table [N + 1, n_mc, 4] (psbmpc_2020; common random numbers for
            every behaviour, obstacle, ship and solve).
        grounding: add the PSB-MPC grounding term (``mpc.params`` G1-G4) on a chart.
    """

    d_safe: float = 40.0
    K_coll: float = 1.0
    p: float = 1.0
    q: float = 4.0
    kappa: float = 10.0
    lambda_T: float = 0.0
    d_cl: float = 200.0
    k_U: float = 9.0
    Delta_U: float = 8.0
    k_chi_port: float = 1.8
    k_chi_stbd: float = 1.5
    Delta_chi_port: float = 1.2
    Delta_chi_stbd: float = 0.9
    T_c: float = 6.0
    n_mc: int = 100
    q_P: float = 5e-5
    r_P: float = 1e-3
    V0: float = 0.3
    seed: int = 0
    grounding: bool = True

    def __post_init__(self):
        for f in dataclasses.fields(self):
            name, v = f"SbmpcSettings.{f.name}", getattr(self, f.name)
            if f.name in ("n_mc", "seed"):
                checks.integer(v, name, ge=1 if f.name == "n_mc" else 0, le=MAX_N_MC)
            elif f.name == "grounding":
                if not isinstance(v, bool):
                    raise ValueError(f"{name} must be true or false, got {v!r}")
            else:
                checks.positive(v, name, allow_zero=f.name not in _POSITIVE)

    def manoeuvring(self) -> dict:
        """The weights of Γ (eqs. 10-13) as :class:`~psbmpc_jax.costs.manoeuvring.SmoothManoeuvringTerm` fields."""
        return dict(k_U=self.k_U, Delta_U=self.Delta_U, k_chi_port=self.k_chi_port, k_chi_stbd=self.k_chi_stbd,
                    Delta_chi_port=self.Delta_chi_port, Delta_chi_stbd=self.Delta_chi_stbd)


#: Upper bound of ``n_mc`` and ``seed`` (plausibility).
MAX_N_MC = 1_000_000

#: Named parameter sets (``mpc.sbmpc.preset``).
SBMPC_PRESETS: dict[str, SbmpcSettings] = {
    # Tengesdal, Brekke & Johansen 2020, Table 1 (30 m vessels at 9 m/s) + proposed values (K_coll 1, d_cl 200 m, p 1, q 4)
    "tengesdal2020": SbmpcSettings(),
    # the same weights scaled to 5 m river vessels at 2 m/s (Nidelva-like): d_safe and d_cl as the nidelva
    # preset's d_safe + ship sizes and d_close
    "river": SbmpcSettings(d_safe=10.0, d_cl=100.0),
}


def sbmpc_settings(preset: str = "tengesdal2020", **overrides) -> SbmpcSettings:
    """A preset of :data:`SBMPC_PRESETS` with ``overrides`` (field -> value); unknown names raise."""
    if not isinstance(preset, str) or preset not in SBMPC_PRESETS:
        raise ValueError(f"sbmpc preset must be one of {', '.join(SBMPC_PRESETS)}, got {preset!r}")
    names = {f.name for f in dataclasses.fields(SbmpcSettings)}
    bad = sorted(set(overrides) - names)
    if bad:
        raise ValueError(f"unknown SB-MPC setting(s) {bad}; allowed: {', '.join(sorted(names))}")
    return dataclasses.replace(SBMPC_PRESETS[preset], **overrides)


# ---------------------------------------------------------------------------------- the mpc.sbmpc section
MAX_SBMPC_INT = 1_000_000      # mpc.sbmpc.n_mc, seed


#: ``mpc.sbmpc`` keys -> :class:`~psbmpc_jax.methods.SbmpcSettings` fields (units in the key where there is one).
_SBMPC_KEYS = {"d_safe_m": "d_safe", "K_coll": "K_coll", "p": "p", "q": "q", "kappa": "kappa", "lambda_T": "lambda_T",
               "d_cl_m": "d_cl",
               "k_U": "k_U", "Delta_U": "Delta_U", "k_chi_port": "k_chi_port", "k_chi_stbd": "k_chi_stbd",
               "Delta_chi_port": "Delta_chi_port", "Delta_chi_stbd": "Delta_chi_stbd", "T_c_s": "T_c",
               "n_mc": "n_mc", "q_P": "q_P", "r_P": "r_P", "V0": "V0", "seed": "seed", "grounding": "grounding"}


_SBMPC_POSITIVE = ("d_safe_m", "d_cl_m", "T_c_s", "r_P", "V0")


def parse_sbmpc(d) -> SbmpcSettings:
    w = "mpc.sbmpc"
    d = as_mapping(d, w)
    check_keys(d, ("preset",) + tuple(_SBMPC_KEYS), w)
    preset = d.get("preset", "tengesdal2020")
    base = SBMPC_PRESETS.get(preset) if isinstance(preset, str) else None
    if base is None:
        raise ValueError(f"{w}.preset must be one of {', '.join(SBMPC_PRESETS)}, got {show(preset)}")
    kw: dict[str, Any] = {}          # field name -> its parsed value (fields of several types)
    for key, name in _SBMPC_KEYS.items():
        if key not in d or key == "preset":
            continue
        v = d[key]
        if key == "grounding":
            kw[name] = as_bool(v, f"{w}.grounding")
        elif key in ("n_mc", "seed"):
            lo = 1 if key == "n_mc" else 0
            kw[name] = integer(v, f"{w}.{key}", ge=lo, le=MAX_SBMPC_INT)
        elif key in _SBMPC_POSITIVE:
            kw[name] = as_number(v, f"{w}.{key}", gt=0)
        else:
            kw[name] = as_number(v, f"{w}.{key}", ge=0)
    return dataclasses.replace(base, **kw)


def manoeuvring_term(s: SbmpcSettings):
    """Γ of Tengesdal, Brekke & Johansen 2020 (eqs. 10-13): linear speed term, |Δu|, the Δχ side from the sign of the new offset
    (a :class:`~psbmpc_jax.costs.manoeuvring.SmoothManoeuvringTerm`)."""
    from ..costs.manoeuvring import SmoothManoeuvringTerm

    return SmoothManoeuvringTerm(aggregation="max", form="johansen", side="offset", **s.manoeuvring())


def sbmpc_terms(s: SbmpcSettings = SbmpcSettings(), *, with_grounding: bool | None = None) -> tuple:
    """The original SB-MPC: the joint max over (obstacle, k ≥ 1) of K_coll‖Δv‖²R + κμ (+ λT when
    ``s.lambda_T > 0``) (crisp R, Boolean μ), plus Γ, plus the grounding term when ``with_grounding`` (default
    ``s.grounding``)."""
    from ..costs.sbmpc import DEFAULT_LAMBDA_T, SbmpcHazardTerm

    hazard = SbmpcHazardTerm(d_safe=s.d_safe, K_coll=s.K_coll, p=s.p, q=s.q, kappa=s.kappa, d_cl=s.d_cl,
                             aggregation="max", risk="crisp", colregs="boolean", transitional=s.lambda_T > 0,
                             lambda_T=s.lambda_T if s.lambda_T > 0 else DEFAULT_LAMBDA_T)
    return _with_grounding((hazard, manoeuvring_term(s)), s.grounding if with_grounding is None else with_grounding)


def psbmpc2020_terms(s: SbmpcSettings = SbmpcSettings(), *, with_grounding: bool | None = None) -> tuple:
    """The PSB-MPC of Tengesdal, Brekke & Johansen 2020 (eq. 20): the MCS+KF collision term with its summed COLREGS, plus Γ, plus the
    grounding term when ``with_grounding`` (default ``s.grounding``)."""
    from ..costs.mcskf import Psbmpc2020Term

    risk = Psbmpc2020Term(d_safe=s.d_safe, K_coll=s.K_coll, kappa=s.kappa, d_cl=s.d_cl, T_c=s.T_c, q_P=s.q_P,
                          r_P=s.r_P, V0=s.V0, n_mc=s.n_mc, seed=s.seed)
    return _with_grounding((risk, manoeuvring_term(s)), s.grounding if with_grounding is None else with_grounding)


#: Γ weights of Informed SB-MPC (proposed: the SB-MPC reference defaults).
INFORMED_MANOEUVRING = dict(k_U=2.5, Delta_U=2.0, k_chi_port=1.8, k_chi_stbd=1.5, Delta_chi_port=1.2,
                            Delta_chi_stbd=0.9)


def informed_terms(informed=None) -> tuple:
    """Informed SB-MPC (Akdağ, Fossen & Johansen 2022, eq. 2): :class:`~psbmpc_jax.costs.informed.InformedSbmpcTerm` (C·R with the
    bearing-shaped d_safe, Woerner μ, Rule-18 ζ with per-target P_default / P_R18, grounding 𝓖) and Γ of eq. (7)
    (side from the new offset).  ``informed``: a :class:`psbmpc_jax.methods.informed_settings.InformedSpec` (its ``classify``,
    ``circular`` and ``term`` overrides) or None for the defaults."""
    from ..costs.informed import InformedSbmpcTerm
    from ..costs.manoeuvring import SmoothManoeuvringTerm

    kw = {} if informed is None else dict(informed.term, classify=informed.classify, circular=informed.circular)
    return (InformedSbmpcTerm(**kw),
            SmoothManoeuvringTerm(aggregation="max", form="johansen", side="offset", **INFORMED_MANOEUVRING))


def _with_grounding(terms: tuple, on: bool) -> tuple:
    if not on:
        return terms
    from ..costs.grounding_term import GroundingTerm

    return terms + (GroundingTerm(),)


__all__ = ["SBMPC_FAMILY", "SbmpcSettings", "SBMPC_PRESETS", "MAX_N_MC", "sbmpc_settings", "manoeuvring_term",
           "sbmpc_terms", "psbmpc2020_terms", "informed_terms", "INFORMED_MANOEUVRING"]
