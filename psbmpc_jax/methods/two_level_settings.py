"""Settings of the two-level MPC (``two_level``): the ``mpc.two_level`` section of a scenario file, parsed here
(registered by :mod:`psbmpc_jax.methods.builtin`).  Light: no JAX."""

from __future__ import annotations

import math
from dataclasses import dataclass


from ..checks import MAX_SPEED_MPS, integer, multiple_of
from ..config import (as_choice, as_mapping, as_number, check_keys)
from .smooth_settings import MAX_METHOD_STEPS


@dataclass(frozen=True)
class TwoLevelSpec:
    """``mpc.two_level``: the two-level MPC of Mahipala & Johansen 2023 (docs/two_level.md; defaults
    at fjord scale).  SI units and radians inside (the file gives degrees where a key ends in ``_deg``).

    Attributes:
        N_p, dt: the upper level's steps and step [s].  Q, M: its weights of (x, y, χ, U) errors and of the
            (χ_d, U_d) moves.  chi_span: the course box around the leg angle [rad].  U_max: speed bound [m/s].
            r_os: own-ship circle radius [m] (added to every static circle).
        corridor_half_width, corridor_sample, corridor_radius, corridor_margin, circle_margin: Algorithm 1 of
            the paper and its corridor margins [m].  r_accept: leg switching radius [m].
        beta, d_critical, compare: the targets' ground-avoiding prediction (eq. 2; β [rad per step]).
        eta1, eta2, d_close, zeta_d_safe, zeta_shape: ζ of eq. (15).
        nominal, plan_stride: the SB-MPC's nominal references (``plan`` / ``hold``).
        sbmpc_every: the SB-MPC solves every this many updates (default: MPC every 1 s, SB-MPC every 5 s).
        static_obstacles: circles ``((north, east), radius)`` [m].
        sbmpc_T, sbmpc_dt: the lower level's horizon and step [s] (None: ``mpc.config``'s T and dt).
    """

    N_p: int = 30
    dt: float = 1.0
    Q: tuple = (1e-3, 1e-3, 1.0, 1.0)
    M: tuple = (10.0, 1.0)
    chi_span: float = math.pi / 2
    U_max: float = 5.0
    r_os: float = 5.0
    corridor_half_width: float = 50.0
    corridor_sample: float = 5.0
    corridor_radius: float = 500.0
    corridor_margin: float = 7.0
    circle_margin: float = 2.0
    r_accept: float = 20.0
    beta: float = math.radians(5.0)
    d_critical: float = 50.0
    compare: str = "plus"
    eta1: float = 0.25
    eta2: float = 0.01
    d_close: float = 50.0
    zeta_d_safe: float = 50.0
    zeta_shape: str = "printed"
    nominal: str = "hold"
    plan_stride: int = 5
    sbmpc_every: int = 5
    static_obstacles: tuple = ()
    sbmpc_T: float | None = None
    sbmpc_dt: float | None = None


_TWO_LEVEL_KEYS = ("N_p", "dt_s", "Q_diag", "M_diag", "chi_span_deg", "U_max_mps", "r_os_m", "corridor", "r_accept_m",
                   "prediction", "zeta", "nominal", "plan_stride", "static_obstacles", "sbmpc_T_s", "sbmpc_dt_s",
                   "sbmpc_every")


_TL_CORRIDOR_KEYS = ("half_width_m", "sample_m", "radius_m", "margin_m", "circle_margin_m")


_TL_PREDICTION_KEYS = ("beta_deg", "d_critical_m", "compare")


_TL_ZETA_KEYS = ("eta1", "eta2", "d_close_m", "d_safe_m", "shape")


def parse_two_level(d) -> TwoLevelSpec:
    w = "mpc.two_level"
    d = as_mapping(d, w)
    check_keys(d, _TWO_LEVEL_KEYS, w)
    kw: dict = {}
    if "N_p" in d:
        kw["N_p"] = integer(d["N_p"], f"{w}.N_p", ge=1, le=MAX_METHOD_STEPS)
    for key in ("plan_stride", "sbmpc_every"):
        if key in d:
            kw[key] = integer(d[key], f"{w}.{key}", ge=1, le=MAX_METHOD_STEPS)
    for key, name in (("dt_s", "dt"), ("U_max_mps", "U_max"), ("r_accept_m", "r_accept"), ("sbmpc_T_s", "sbmpc_T"),
                      ("sbmpc_dt_s", "sbmpc_dt")):
        if key in d:
            kw[name] = as_number(d[key], f"{w}.{key}", gt=0)
    if ("sbmpc_T_s" in d) != ("sbmpc_dt_s" in d):
        raise ValueError(f"{w}.sbmpc_T_s and {w}.sbmpc_dt_s must be given together")
    if "sbmpc_T" in kw:
        multiple_of(kw["sbmpc_T"], kw["sbmpc_dt"], f"{w}.sbmpc_T_s", f"{w}.sbmpc_dt_s")
    if "U_max" in kw and kw["U_max"] > MAX_SPEED_MPS:          # kw holds the field's name, U_max
        raise ValueError(f"{w}.U_max_mps must be in (0, {MAX_SPEED_MPS:g}] m/s, got {kw['U_max']:g}")
    if "r_os_m" in d:
        kw["r_os"] = as_number(d["r_os_m"], f"{w}.r_os_m", ge=0)
    if "chi_span_deg" in d:
        v = as_number(d["chi_span_deg"], f"{w}.chi_span_deg", gt=0)
        if v >= 180:
            raise ValueError(f"{w}.chi_span_deg must be in (0, 180), got {v:g}")
        kw["chi_span"] = math.radians(v)
    for key, name, n in (("Q_diag", "Q", 4), ("M_diag", "M", 2)):
        if key in d:
            v = d[key]
            if not isinstance(v, (list, tuple)) or len(v) != n:
                raise ValueError(f"{w}.{key} must be a list of {n} weights >= 0, got {v!r}"[:300])
            kw[name] = tuple(as_number(x, f"{w}.{key}[{i}]", ge=0) for i, x in enumerate(v))
    if "nominal" in d:
        kw["nominal"] = as_choice(d["nominal"], ("plan", "hold"), f"{w}.nominal")
    sub = as_mapping(d.get("corridor", {}) or {}, f"{w}.corridor")
    check_keys(sub, _TL_CORRIDOR_KEYS, f"{w}.corridor")
    for key, name, lo in (("half_width_m", "corridor_half_width", "gt"), ("sample_m", "corridor_sample", "gt"),
                          ("radius_m", "corridor_radius", "gt"), ("margin_m", "corridor_margin", "ge"),
                          ("circle_margin_m", "circle_margin", "ge")):
        if key in sub:
            kw[name] = as_number(sub[key], f"{w}.corridor.{key}", **{lo: 0})
    sub = as_mapping(d.get("prediction", {}) or {}, f"{w}.prediction")
    check_keys(sub, _TL_PREDICTION_KEYS, f"{w}.prediction")
    if "beta_deg" in sub:
        v = as_number(sub["beta_deg"], f"{w}.prediction.beta_deg", gt=0)
        if v >= 180:
            raise ValueError(f"{w}.prediction.beta_deg must be in (0, 180) degrees per step, got {v:g}")
        kw["beta"] = math.radians(v)
    if "d_critical_m" in sub:
        kw["d_critical"] = as_number(sub["d_critical_m"], f"{w}.prediction.d_critical_m", gt=0)
    if "compare" in sub:
        kw["compare"] = as_choice(sub["compare"], ("plus", "both"), f"{w}.prediction.compare")
    sub = as_mapping(d.get("zeta", {}) or {}, f"{w}.zeta")
    check_keys(sub, _TL_ZETA_KEYS, f"{w}.zeta")
    for key, name in (("eta1", "eta1"), ("eta2", "eta2"), ("d_safe_m", "zeta_d_safe")):
        if key in sub:
            kw[name] = as_number(sub[key], f"{w}.zeta.{key}", ge=0)
    if "d_close_m" in sub:
        kw["d_close"] = as_number(sub["d_close_m"], f"{w}.zeta.d_close_m", gt=0)
    if "shape" in sub:
        kw["zeta_shape"] = as_choice(sub["shape"], ("printed", "psbmpc"), f"{w}.zeta.shape")
    circles = d.get("static_obstacles", []) or []
    if not isinstance(circles, (list, tuple)):
        raise ValueError(f"{w}.static_obstacles must be a list of {{center_m: [north, east], radius_m: r}}, got "
                         f"{circles!r}"[:300])
    out = []
    for i, c in enumerate(circles):
        where = f"{w}.static_obstacles[{i}]"
        c = as_mapping(c, where)
        check_keys(c, ("center_m", "radius_m"), where, required=("center_m", "radius_m"))
        ctr = c["center_m"]
        if not isinstance(ctr, (list, tuple)) or len(ctr) != 2:
            raise ValueError(f"{where}.center_m must be [north, east] in metres, got {ctr!r}"[:300])
        out.append(((as_number(ctr[0], f"{where}.center_m[0]"), as_number(ctr[1], f"{where}.center_m[1]")),
                    as_number(c["radius_m"], f"{where}.radius_m", gt=0)))
    kw["static_obstacles"] = tuple(out)
    return TwoLevelSpec(**kw)
