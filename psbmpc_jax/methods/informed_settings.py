"""Settings of Informed SB-MPC (``informed_sbmpc``): the ``mpc.informed`` section of a scenario file, parsed here
(registered by :mod:`psbmpc_jax.methods.builtin`).  Light: no JAX."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


from ..config import (as_bool, as_choice, as_mapping, as_number, check_keys)


#: Numeric fields of :class:`psbmpc_jax.costs.informed.InformedSbmpcTerm` that ``mpc.informed.term`` may set
#: (listed here: loading a scenario must not import JAX; a test keeps the two in step).
INFORMED_TERM_FIELDS = ("K_coll", "kappa", "rho", "c_dist", "p", "q", "d_close", "K_coll_r18", "kappa_r18", "rho_r18",
                        "c_dist_r18", "p_r18", "q_r18", "d_close_r18", "k", "l", "m", "n", "gamma", "p_g", "q_g",
                        "d_static_safe")


INFORMED_CLASSIFY = ("velocity", "sectors_t0")


@dataclass(frozen=True)
class InformedSpec:
    """``mpc.informed``: Informed SB-MPC (Akdağ, Fossen & Johansen 2022; ``informed_sbmpc``).

    Attributes:
        route_exchange: planners predict a target that shares its route along that route (False: straight lines
            for every target, the paper's "without route exchange").
        xtd_threshold: the supervisor falls back to a straight line for a target farther than this from its
            shared route [m] (STM 2019: 100 m).
        d_init: the planner is active only while some target is within this range [m]; else it applies (1, 0)
            and forgets its last offsets.
        exchange_delay: age of the plans a planner uses [s] (the latest plan published at or before t − delay).
        exchange_dropout: probability that a published plan is lost (the receiver keeps the last one it got).
        classify: how the COLREGS situations are found: ``"velocity"`` (per predicted time) or
            ``"sectors_t0"`` (Woerner sectors at t₀).
        circular: a circular safety region of radius c_dist instead of the bearing-shaped one (eq. 10).
        term: overrides of the term's numbers (:data:`INFORMED_TERM_FIELDS`, e.g. ``c_dist``, ``rho_r18``).
    """

    route_exchange: bool = True
    xtd_threshold: float = 100.0
    d_init: float = 2000.0
    exchange_delay: float = 0.0
    exchange_dropout: float = 0.0
    classify: str = "velocity"
    circular: bool = False
    term: dict = field(default_factory=dict)


_INFORMED_KEYS = ("route_exchange", "xtd_threshold_m", "d_init_m", "exchange_delay_s", "exchange_dropout", "classify",
                  "circular", "term")


def parse_informed(d) -> InformedSpec:
    w = "mpc.informed"
    d = as_mapping(d, w)
    check_keys(d, _INFORMED_KEYS, w)
    kw: dict[str, Any] = {}
    for key in ("route_exchange", "circular"):
        if key in d:
            kw[key] = as_bool(d[key], f"{w}.{key}")
    for key, name in (("xtd_threshold_m", "xtd_threshold"), ("d_init_m", "d_init")):
        if key in d:
            kw[name] = as_number(d[key], f"{w}.{key}", gt=0)
    if "exchange_delay_s" in d:
        kw["exchange_delay"] = as_number(d["exchange_delay_s"], f"{w}.exchange_delay_s", ge=0)
    if "exchange_dropout" in d:
        kw["exchange_dropout"] = as_number(d["exchange_dropout"], f"{w}.exchange_dropout", ge=0, le=1)
    if "classify" in d:
        kw["classify"] = as_choice(d["classify"], INFORMED_CLASSIFY, f"{w}.classify")
    if "term" in d:
        t = as_mapping(d["term"] or {}, f"{w}.term")
        check_keys(t, INFORMED_TERM_FIELDS, f"{w}.term")
        kw["term"] = {k: as_number(v, f"{w}.term.{k}", ge=0) for k, v in t.items()}
    return InformedSpec(**kw)
