"""The ``mpc`` section of a scenario file (method, preset, PSB-MPC configuration and the methods' own sections),
the ``evaluation`` section and a ship's ``colav``."""

from __future__ import annotations
import dataclasses
import math
import numbers
import numpy as np
from .. import scenario_checks as limits
from ..checks import MAX_SPEED_MPS, integer, multiple_of, show
from ..evaltool.params import PRESETS as EVAL_PRESETS
from ..evaltool.params import EvalParams
from ..evaltool.params import scaled_params
from ..methods.registry import REGISTRY, get_method
from ..methods.sbmpc_family import SBMPC_PRESETS, SbmpcSettings
from ..params import PlannerConfig, validate_params
from ..situation import MAX_N_PS

from .fields import as_bool, as_choice, as_mapping, as_number, check_keys, course_rad, is_number, value_sets
from .schema import FisSpec, INFORMED_CLASSIFY, INFORMED_TERM_FIELDS, InformedSpec, MAX_FIS_NY, MAX_METHOD_STEPS, MAX_SBMPC_INT, MAX_SOLVER_ITERATIONS, MAX_STARTS, MPCSpec, RefineSpec, SMOOTH_DEFAULT_PRESET, SMOOTH_METHODS, SmoothSpec, SolverSpec, TwoLevelSpec


def method_name(value, where: str, *, none_ok: bool = False) -> str:
    """``value`` if it names a method (:func:`psbmpc_jax.methods.get_method`; ``"none"`` too when ``none_ok``),
    else ValueError naming ``where`` and what is allowed."""
    if none_ok and value == "none":
        return value
    try:
        get_method(value, where, none_ok=none_ok)
    except (ImportError, TypeError) as exc:
        raise ValueError(str(exc)) from exc
    return value


_MPC_KEYS = ("preset", "update_period_s", "n_ps", "config", "params", "speed_factors", "course_offsets_deg",
             "method", "smooth", "fis", "solver", "refine", "sbmpc", "informed", "two_level")


_SMOOTH_KEYS = ("T_init_s", "T_mpc_s", "dt_s", "corridor_half_width_m", "domain_radius_m", "k_ntp", "terminal",
                "n_starts", "previous_start")


_FIS_KEYS = ("d_cl_m", "e_cl_m", "eps", "n_y", "completion")


_SOLVER_KEYS = ("max_outer", "max_inner", "tol", "method")


_REFINE_KEYS = ("n_starts", "horizon_s", "colregs", "block_s", "previous_start")


_TERMINALS = ("full", "position", "soft")


_COMPLETIONS = ("default_false", "literal")


_SOLVER_METHODS = ("lbfgs", "adam")


_REFINE_COLREGS = ("fis", "none")


def read_mpc(d, dt: float) -> MPCSpec:
    from ..presets import PRESETS, build_mpc

    d = as_mapping(d, "mpc")
    check_keys(d, _MPC_KEYS, "mpc", required=("update_period_s",))
    method = d.get("method", "psbmpc")
    method_name(method, "mpc.method")
    if "preset" not in d and method not in SMOOTH_METHODS:
        raise ValueError(f"mpc: missing required key 'preset' (required for mpc.method {method}; optional only "
                         f"for {' / '.join(SMOOTH_METHODS)}, which then take their defaults from "
                         f"{SMOOTH_DEFAULT_PRESET!r})")
    preset = d.get("preset", SMOOTH_DEFAULT_PRESET)
    if not isinstance(preset, str) or preset not in PRESETS:
        raise ValueError(f"mpc.preset must be one of {sorted(PRESETS)}, got {preset!r}")
    period = as_number(d["update_period_s"], "mpc.update_period_s", gt=0)
    multiple_of(period, dt, "mpc.update_period_s", "simulation.dt_s")
    smooth = _smooth_spec(d.get("smooth", {}) or {})
    fis = _fis_spec(d.get("fis", {}) or {})
    solver = _solver_spec(d.get("solver", {}) or {})
    if method in SMOOTH_METHODS:
        multiple_of(period, smooth.dt, "mpc.update_period_s",
                    "mpc.smooth.dt_s" if "dt_s" in (d.get("smooth") or {}) else "mpc.smooth.dt_s (default)")
    n_ps = d.get("n_ps", PRESETS[preset].n_ps)
    if isinstance(n_ps, bool) or not isinstance(n_ps, numbers.Integral) or n_ps < 1 or n_ps % 2 == 0:
        raise ValueError(f"mpc.n_ps must be an odd integer >= 1, got {n_ps!r}"[:300])
    if n_ps > MAX_N_PS:
        raise ValueError(f"mpc.n_ps must be an odd integer <= {MAX_N_PS}, got {show(n_ps)}")

    config = dict(as_mapping(d.get("config", {}) or {}, "mpc.config"))
    params_in = dict(as_mapping(d.get("params", {}) or {}, "mpc.params"))
    params = {}
    for k, v in params_in.items():
        if k == "wind_dir":
            raise ValueError("mpc.params.wind_dir: angles in scenario files are in degrees; use wind_dir_deg "
                             "(direction the wind blows towards, from north, clockwise)")
        if k == "wind_dir_deg":
            params["wind_dir"] = course_rad(as_number(v, "mpc.params.wind_dir_deg"))
        elif k == "t_ts" and is_number(v) and math.isnan(float(v)):
            params[k] = float("nan")  # nan = T / n_M, the documented default
        else:
            params[k] = as_number(v, f"mpc.params.{k}")
    has_s, has_c = "speed_factors" in d, "course_offsets_deg" in d
    if has_s != has_c:
        raise ValueError("mpc.speed_factors and mpc.course_offsets_deg must be given together (one set of each "
                         "per maneuver)")
    speeds = courses = None
    if has_s:
        speeds = value_sets(d["speed_factors"], "mpc.speed_factors", lo=0.0, hi=1.0)
        courses = value_sets(d["course_offsets_deg"], "mpc.course_offsets_deg", lo=-180.0, hi=180.0)
        if len(speeds) != len(courses):
            raise ValueError(f"mpc.speed_factors and mpc.course_offsets_deg need one set per maneuver, got "
                             f"{len(speeds)} and {len(courses)} sets")
        if len(speeds) > limits.MAX_MANEUVERS:
            raise ValueError(f"mpc.speed_factors: {len(speeds)} maneuvers; at most {limits.MAX_MANEUVERS} allowed")
        n_b = math.prod(len(a) * len(b) for a, b in zip(speeds, courses))
        if n_b > limits.MAX_BEHAVIOURS:
            raise ValueError(f"mpc.speed_factors x mpc.course_offsets_deg make {n_b} control behaviours (the product "
                             f"of all set sizes); at most {limits.MAX_BEHAVIOURS} allowed")
    for k, v in config.items():
        if isinstance(v, bool) or (isinstance(v, numbers.Integral) and abs(v) > 10 ** 15):
            raise ValueError(f"mpc.config.{k} must be a number or a name, got {v!r}"[:200])
    try:
        cfg, prm, behaviours = build_mpc(preset, config, params, speeds, courses)
        validate_params(prm, cfg, np.shape(behaviours)[1])
    except (ValueError, TypeError, OverflowError) as exc:
        raise ValueError(f"mpc ({preset!r} with the file's overrides): {exc}") from None
    if cfg.dtype == "float64":
        _enable_x64()
    refine = _refine_spec(d.get("refine", {}) or {}, cfg)
    given = d.get("fis") or {}
    refine = dataclasses.replace(refine, fis_e_cl=fis.e_cl if "e_cl_m" in given else None,
                                 fis_n_y=fis.n_y if "n_y" in given else None)
    return MPCSpec(preset=preset, config=cfg, params=prm, behaviours=np.asarray(behaviours, dtype=float),
                   n_ps=int(n_ps), period=period, method=method, smooth=smooth, fis=fis, solver=solver,
                   refine=refine, sbmpc=_sbmpc_spec(d.get("sbmpc", {}) or {}),
                   informed=_informed_spec(d.get("informed", {}) or {}),
                   two_level=_two_level_spec(d.get("two_level", {}) or {}))


_TWO_LEVEL_KEYS = ("N_p", "dt_s", "Q_diag", "M_diag", "chi_span_deg", "U_max_mps", "r_os_m", "corridor", "r_accept_m",
                   "prediction", "zeta", "nominal", "plan_stride", "static_obstacles", "sbmpc_T_s", "sbmpc_dt_s",
                   "sbmpc_every")


_TL_CORRIDOR_KEYS = ("half_width_m", "sample_m", "radius_m", "margin_m", "circle_margin_m")


_TL_PREDICTION_KEYS = ("beta_deg", "d_critical_m", "compare")


_TL_ZETA_KEYS = ("eta1", "eta2", "d_close_m", "d_safe_m", "shape")


def _two_level_spec(d) -> TwoLevelSpec:
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
    if "U_max_mps" in kw and kw["U_max"] > MAX_SPEED_MPS:
        raise ValueError(f"{w}.U_max_mps must be <= {MAX_SPEED_MPS} m/s, got {kw['U_max']}")
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


_INFORMED_KEYS = ("route_exchange", "xtd_threshold_m", "d_init_m", "exchange_delay_s", "exchange_dropout", "classify",
                  "circular", "term")


def _informed_spec(d) -> InformedSpec:
    w = "mpc.informed"
    d = as_mapping(d, w)
    check_keys(d, _INFORMED_KEYS, w)
    kw = {}
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


#: ``mpc.sbmpc`` keys -> :class:`~psbmpc_jax.methods.SbmpcSettings` fields (units in the key where there is one).
_SBMPC_KEYS = {"d_safe_m": "d_safe", "K_coll": "K_coll", "p": "p", "q": "q", "kappa": "kappa", "lambda_T": "lambda_T",
               "d_cl_m": "d_cl",
               "k_U": "k_U", "Delta_U": "Delta_U", "k_chi_port": "k_chi_port", "k_chi_stbd": "k_chi_stbd",
               "Delta_chi_port": "Delta_chi_port", "Delta_chi_stbd": "Delta_chi_stbd", "T_c_s": "T_c",
               "n_mc": "n_mc", "q_P": "q_P", "r_P": "r_P", "V0": "V0", "seed": "seed", "grounding": "grounding"}


_SBMPC_POSITIVE = ("d_safe_m", "d_cl_m", "T_c_s", "r_P", "V0")


def _sbmpc_spec(d) -> SbmpcSettings:
    w = "mpc.sbmpc"
    d = as_mapping(d, w)
    check_keys(d, ("preset",) + tuple(_SBMPC_KEYS), w)
    preset = d.get("preset", "tengesdal2020")
    base = SBMPC_PRESETS.get(preset) if isinstance(preset, str) else None
    if base is None:
        raise ValueError(f"{w}.preset must be one of {', '.join(SBMPC_PRESETS)}, got {show(preset)}")
    kw = {}
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


def read_evaluation(d) -> EvalParams:
    """The ``evaluation`` section: ``preset`` (default ``default``), ``range_scale`` (> 0, multiplies the
    preset's stage radii and CPA ranges, :data:`psbmpc_jax.evaltool.params.RANGE_FIELDS`; default 1) and any
    :class:`EvalParams` field (applied after the scaling)."""
    d = dict(as_mapping(d, "evaluation"))
    preset = d.pop("preset", "default")
    if not isinstance(preset, str) or preset not in EVAL_PRESETS:
        raise ValueError(f"evaluation.preset must be one of {', '.join(EVAL_PRESETS)}, got {show(preset)}")
    scale = as_number(d.pop("range_scale"), "evaluation.range_scale", gt=0, le=1000) if "range_scale" in d else 1.0
    names = [f.name for f in dataclasses.fields(EvalParams)]
    for k in d:
        if k not in names:
            raise ValueError(f"unknown key {k!r} in evaluation; allowed: preset, range_scale, {', '.join(names)}")
    try:
        return scaled_params(preset, scale, **d)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"evaluation: {exc}") from None


def ship_colav(value, own: bool, method: str, where: str) -> str:
    """A ship's method: ``"none"`` or a method name (:func:`method_name`).  The own-ship's is ``mpc.method``
    (``psbmpc``, the historic "on", or the same name as ``mpc.method``); a target's is the name it gives (not a
    method that plans the own-ship only)."""
    method_name(value, f"{where}.colav", none_ok=True)
    if value == "none":
        return value
    if own:
        if value not in ("psbmpc", method):
            raise ValueError(f"{where}.colav: the own-ship runs mpc.method ({method}), got colav {value!r}; set "
                             f"mpc.method: {value} (or colav: psbmpc, which means 'on, with mpc.method')")
        return method
    if get_method(value).own_ship_only:
        targets_ok = [n for n, m in REGISTRY.items() if not m.own_ship_only]
        raise ValueError(f"{where}.colav: {value} plans the own-ship only; a target may run "
                         f"{', '.join(targets_ok)}, another method that plans targets, or none")
    return value


def _smooth_spec(d) -> SmoothSpec:
    w = "mpc.smooth"
    d = as_mapping(d, w)
    check_keys(d, _SMOOTH_KEYS, w)
    kw = {}
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


def _fis_spec(d) -> FisSpec:
    w = "mpc.fis"
    d = as_mapping(d, w)
    check_keys(d, _FIS_KEYS, w)
    kw = {}
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


def _solver_spec(d) -> SolverSpec:
    w = "mpc.solver"
    d = as_mapping(d, w)
    check_keys(d, _SOLVER_KEYS, w)
    kw = {}
    for key in ("max_outer", "max_inner"):
        if key in d:
            kw[key] = integer(d[key], f"{w}.{key}", ge=1, le=MAX_SOLVER_ITERATIONS)
    if "tol" in d:
        kw["tol"] = as_number(d["tol"], f"{w}.tol", gt=0)
    if "method" in d:
        kw["method"] = as_choice(d["method"], _SOLVER_METHODS, f"{w}.method")
    return SolverSpec(**kw)


def _refine_spec(d, config: PlannerConfig) -> RefineSpec:
    w = "mpc.refine"
    d = as_mapping(d, w)
    check_keys(d, _REFINE_KEYS, w)
    kw = {}
    if "n_starts" in d:
        kw["n_starts"] = integer(d["n_starts"], f"{w}.n_starts", ge=1, le=MAX_STARTS)
    if "horizon_s" in d:
        h = as_number(d["horizon_s"], f"{w}.horizon_s", gt=0)
        if h > config.T * (1 + 1e-9):
            raise ValueError(f"{w}.horizon_s ({h:g}) must be <= the PSB-MPC horizon mpc.config T ({config.T:g}); "
                             f"leave it out for the whole horizon")
        multiple_of(h, config.dt, f"{w}.horizon_s", "the PSB-MPC step mpc.config dt")
        kw["horizon"] = h
    if "colregs" in d:
        kw["colregs"] = as_choice(d["colregs"], _REFINE_COLREGS, f"{w}.colregs")
    if "block_s" in d:
        b = as_number(d["block_s"], f"{w}.block_s", gt=0)
        limit = kw.get("horizon", config.T)
        if b > limit * (1 + 1e-9):
            raise ValueError(f"{w}.block_s ({b:g}) must be <= the refined horizon ({limit:g} s)")
        multiple_of(b, config.dt, f"{w}.block_s", "the PSB-MPC step mpc.config dt")
        kw["block"] = b
    n_starts = kw.get("n_starts", RefineSpec.n_starts)
    if "previous_start" in d:
        kw["previous_start"] = as_bool(d["previous_start"], f"{w}.previous_start")
        if kw["previous_start"] and n_starts < 2:
            raise ValueError(f"{w}.previous_start needs {w}.n_starts >= 2 (start 0 is the grid's choice), got "
                             f"n_starts {n_starts}")
    else:
        kw["previous_start"] = n_starts >= 2          # the default: on whenever there is a second start
    return RefineSpec(**kw)


def _enable_x64() -> None:
    """``mpc.config.dtype: float64`` needs 64-bit JAX: switch it on now, before any array is built (a process-wide
    JAX setting; arrays created before keep their dtype)."""
    import jax

    if not jax.config.jax_enable_x64:
        jax.config.update("jax_enable_x64", True)
