"""Settings of the Smooth-SBMPC methods (``smooth_sbmpc``, ``sbmpc_init``) and of the gradient solver they share
with the refinement: the ``mpc.smooth``, ``mpc.fis`` and ``mpc.solver`` sections of a scenario file, parsed here
(registered as sections by :mod:`psbmpc_jax.methods.builtin`).  Light: no JAX."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


from ..checks import integer, multiple_of
from ..config import (as_bool, as_choice, as_mapping, as_number, check_keys)


#: The Smooth-SBMPC methods (their own model and tuning; the PSB-MPC preset only supplies defaults).
SMOOTH_METHODS = ("smooth_sbmpc", "sbmpc_init")


@dataclass(frozen=True)
class SmoothSpec:
    """``mpc.smooth``: Smooth-SBMPC's horizons and corridor (Mahipala & Johansen 2024; its defaults are
    those of :class:`psbmpc_jax.smooth.init_stage.SmoothSettings`, which reads them here).  Seconds and metres.

    Attributes:
        T_init, T_mpc: horizons of the initialisation stage and of the DOCP (T_init > T_mpc, multiples of dt).
        dt: T_s, the discretisation step of both stages.
        corridor_half_width: Δd.  domain_radius: r_dom, the ship-domain radius (N_TP and the corridor buffer).
        k_ntp: grounding-penalty weight per lost trajectory point.
        terminal: ``"full"``, ``"position"`` or ``"soft"`` terminal condition of the DOCP.
        n_starts: starts of the DOCP solve (multi-start).
        previous_start: start 1 of the DOCP is the previous update's kept sequence, shifted (needs
            n_starts >= 2; ignored by ``sbmpc_init``, which has no DOCP).
        chi_d_mode: the DOCP's guidance: ``"terminal_los"`` (LOS on the line from the ship through the
            initialisation stage's point at τ₀ + T_mpc, the paper's; default) or ``"route_los"`` (the route's LOS).
        corridor_land_buffer: the corridor's land buffer [m] (its ray cast and the clearance between samples),
            apart from domain_radius (N_TP).
        corridor_check: ``"continuous"`` (the corridor plus a proven clearance bound of every plan segment;
            default) or ``"samples"`` (the corridor at the 1-s samples only).
        targets: what the planner sees of the targets: ``"tracks"`` (the own-ship's Kalman-filter tracks;
            default) or ``"true_states"`` (their true states, as the paper's simulations).
    """

    T_init: float = 60.0
    T_mpc: float = 20.0
    dt: float = 1.0
    corridor_half_width: float = 20.0
    domain_radius: float = 4.0
    k_ntp: float = 1.0
    terminal: str = "full"
    n_starts: int = 4
    previous_start: bool = False
    chi_d_mode: str = "terminal_los"
    corridor_land_buffer: float = 4.0
    corridor_check: str = "continuous"
    targets: str = "tracks"


@dataclass(frozen=True)
class FisSpec:
    """``mpc.fis``: the fuzzy COLREGS inference of Smooth-SBMPC (d_cl, e_cl [m], smooth-max ε, output grid n_y,
    rule-table completion ``"default_false"`` or ``"literal"``)."""

    d_cl: float = 40.0
    e_cl: float = 5.0
    eps: float = 1e-6
    n_y: int = 201
    completion: str = "default_false"


@dataclass(frozen=True)
class SolverSpec:
    """``mpc.solver``: overrides of the gradient solver of the smooth DOCP and of the PSB-MPC refinement
    (:class:`psbmpc_jax.nlp.SolverSettings`: outer / inner iterations, feasibility tolerance, inner method).
    None: the method's own default (the refinement's is deliberately cheap, ``psbmpc_jax.refine.DEFAULT_SOLVER``)."""

    max_outer: int | None = None
    max_inner: int | None = None
    tol: float | None = None
    method: str | None = None

    def given(self) -> dict:
        """The fields the file sets (SolverSettings field name -> value)."""
        return {k: v for k, v in vars(self).items() if v is not None}


#: Upper limits of the method settings (plausibility, like the rest of the file).
MAX_METHOD_STEPS = 10_000      # T_init_s / dt_s, T_mpc_s / dt_s


MAX_STARTS = 64


MAX_SOLVER_ITERATIONS = 100_000


#: (max_outer, max_inner) of the solver when ``mpc.solver`` does not set them: Smooth-SBMPC's DOCP uses the
#: library defaults of ``psbmpc_jax.nlp.SolverSettings``, the refinement its own cheap ``DEFAULT_SOLVER``
#: (tests/test_update_time.py checks both against the JAX-side settings).  Used by the time estimate at load.
DOCP_SOLVER_ITERATIONS = (20, 50)
REFINE_SOLVER_ITERATIONS = (1, 8)


MAX_FIS_NY = 100_001


_SMOOTH_KEYS = ("T_init_s", "T_mpc_s", "dt_s", "corridor_half_width_m", "domain_radius_m", "k_ntp", "terminal",
                "n_starts", "previous_start", "chi_d_mode", "corridor_land_buffer_m", "corridor_check", "targets")


_CHI_D_MODES = ("terminal_los", "route_los")


_CORRIDOR_CHECKS = ("continuous", "samples")


_TARGET_SOURCES = ("tracks", "true_states")


_FIS_KEYS = ("d_cl_m", "e_cl_m", "eps", "n_y", "completion")


_SOLVER_KEYS = ("max_outer", "max_inner", "tol", "method")


_TERMINALS = ("full", "position", "soft")


_COMPLETIONS = ("default_false", "literal")


_SOLVER_METHODS = ("lbfgs", "adam")


def parse_smooth(d) -> SmoothSpec:
    w = "mpc.smooth"
    d = as_mapping(d, w)
    check_keys(d, _SMOOTH_KEYS, w)
    kw: dict[str, Any] = {}          # field name -> its parsed value (fields of several types)
    for key, name in (("T_init_s", "T_init"), ("T_mpc_s", "T_mpc"), ("dt_s", "dt"),
                      ("corridor_half_width_m", "corridor_half_width")):
        if key in d:
            kw[name] = as_number(d[key], f"{w}.{key}", gt=0)
    if "domain_radius_m" in d:
        kw["domain_radius"] = as_number(d["domain_radius_m"], f"{w}.domain_radius_m", ge=0)
    if "k_ntp" in d:
        kw["k_ntp"] = as_number(d["k_ntp"], f"{w}.k_ntp", ge=0)
    if "terminal" in d:
        kw["terminal"] = as_choice(d["terminal"], _TERMINALS, f"{w}.terminal")
    if "n_starts" in d:
        kw["n_starts"] = integer(d["n_starts"], f"{w}.n_starts", ge=1, le=MAX_STARTS)
    if "previous_start" in d:
        kw["previous_start"] = as_bool(d["previous_start"], f"{w}.previous_start")
    if "chi_d_mode" in d:
        kw["chi_d_mode"] = as_choice(d["chi_d_mode"], _CHI_D_MODES, f"{w}.chi_d_mode")
    if "corridor_land_buffer_m" in d:
        kw["corridor_land_buffer"] = as_number(d["corridor_land_buffer_m"], f"{w}.corridor_land_buffer_m", ge=0)
    if "corridor_check" in d:
        kw["corridor_check"] = as_choice(d["corridor_check"], _CORRIDOR_CHECKS, f"{w}.corridor_check")
    if "targets" in d:
        kw["targets"] = as_choice(d["targets"], _TARGET_SOURCES, f"{w}.targets")
    spec = SmoothSpec(**kw)
    if spec.previous_start and spec.n_starts < 2:
        raise ValueError(f"{w}.previous_start needs {w}.n_starts >= 2 (start 0 is always the trajectory Ψ), "
                         f"got n_starts {spec.n_starts}")
    for key, name in (("T_init_s", "T_init"), ("T_mpc_s", "T_mpc")):
        given = f"{w}.{key}" + ("" if key in d else " (default)")
        n = multiple_of(getattr(spec, name), spec.dt, given, f"{w}.dt_s" + ("" if "dt_s" in d else " (default)"))
        if n > MAX_METHOD_STEPS:
            raise ValueError(f"{given} / {w}.dt_s = {n} steps; at most {MAX_METHOD_STEPS} allowed")
    if not spec.T_init > spec.T_mpc:
        raise ValueError(f"{w}.T_init_s ({spec.T_init:g}) must be > {w}.T_mpc_s ({spec.T_mpc:g}): the DOCP's "
                         f"terminal state is taken from the initialisation stage's trajectory")
    return spec


def parse_fis(d) -> FisSpec:
    w = "mpc.fis"
    d = as_mapping(d, w)
    check_keys(d, _FIS_KEYS, w)
    kw: dict[str, Any] = {}          # field name -> its parsed value (fields of several types)
    if "d_cl_m" in d:
        kw["d_cl"] = as_number(d["d_cl_m"], f"{w}.d_cl_m", gt=0)
    if "e_cl_m" in d:
        kw["e_cl"] = as_number(d["e_cl_m"], f"{w}.e_cl_m", gt=0)
    if "eps" in d:
        kw["eps"] = as_number(d["eps"], f"{w}.eps", gt=0)
    if "n_y" in d:
        kw["n_y"] = integer(d["n_y"], f"{w}.n_y", ge=2, le=MAX_FIS_NY)
    if "completion" in d:
        kw["completion"] = as_choice(d["completion"], _COMPLETIONS, f"{w}.completion")
    return FisSpec(**kw)


def parse_solver(d) -> SolverSpec:
    w = "mpc.solver"
    d = as_mapping(d, w)
    check_keys(d, _SOLVER_KEYS, w)
    kw: dict[str, Any] = {}          # field name -> its parsed value (fields of several types)
    for key in ("max_outer", "max_inner"):
        if key in d:
            kw[key] = integer(d[key], f"{w}.{key}", ge=1, le=MAX_SOLVER_ITERATIONS)
    if "tol" in d:
        kw["tol"] = as_number(d["tol"], f"{w}.tol", gt=0)
    if "method" in d:
        kw["method"] = as_choice(d["method"], _SOLVER_METHODS, f"{w}.method")
    return SolverSpec(**kw)
