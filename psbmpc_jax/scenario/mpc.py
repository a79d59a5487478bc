"""The ``mpc`` section of a scenario file (method, preset, PSB-MPC configuration and the methods' own sections),
the ``evaluation`` section and a ship's ``colav``."""

from __future__ import annotations
import dataclasses
import math
import numbers
import numpy as np
from .. import scenario_checks as limits
from ..checks import multiple_of, show
from ..evaltool.params import PRESETS as EVAL_PRESETS
from ..evaltool.params import EvalParams
from ..evaltool.params import scaled_params
from ..methods.registry import REGISTRY, SECTIONS, SectionContext, get_method
from ..params import validate_params
from ..situation import MAX_N_PS

from ..config import as_mapping, as_number, check_keys, course_rad, is_number, value_sets
from ..methods.smooth_settings import SMOOTH_METHODS
from .schema import MPCSpec, SMOOTH_DEFAULT_PRESET


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


#: Most prediction scenarios per obstacle a scenario file may ask for (``mpc.n_ps``, documented 1 to 99; the
#: library's own bound, :data:`psbmpc_jax.situation.MAX_N_PS`, is not lower).
MPC_MAX_N_PS = min(99, MAX_N_PS)

#: The keys of ``mpc`` besides the methods' own sections (:data:`psbmpc_jax.methods.registry.SECTIONS`).
_MPC_KEYS = ("preset", "update_period_s", "n_ps", "config", "params", "speed_factors", "course_offsets_deg",
             "method")


def _sections(d, ctx: SectionContext, after_config: bool) -> None:
    """Parse the registered sections of one phase into ``ctx.parsed`` (each by its method's settings module)."""
    for key, section in SECTIONS.items():
        if section.after_config == after_config:
            ctx.parsed[key] = section.parse(d.get(key, {}) or {}, ctx)


def read_mpc(d, dt: float) -> MPCSpec:
    from ..presets import PRESETS, build_mpc

    d = as_mapping(d, "mpc")
    method = d.get("method", "psbmpc")
    method_name(method, "mpc.method")       # first: an outside method may register its own section on import
    check_keys(d, _MPC_KEYS + tuple(SECTIONS), "mpc", required=("update_period_s",))
    if "preset" not in d and method not in SMOOTH_METHODS:
        raise ValueError(f"mpc: missing required key 'preset' (required for mpc.method {method}; optional only "
                         f"for {' / '.join(SMOOTH_METHODS)}, which then take their defaults from "
                         f"{SMOOTH_DEFAULT_PRESET!r})")
    preset = d.get("preset", SMOOTH_DEFAULT_PRESET)
    if not isinstance(preset, str) or preset not in PRESETS:
        raise ValueError(f"mpc.preset must be one of {sorted(PRESETS)}, got {preset!r}")
    period = as_number(d["update_period_s"], "mpc.update_period_s", gt=0)
    multiple_of(period, dt, "mpc.update_period_s", "simulation.dt_s")
    ctx = SectionContext(mpc=d, method=method, period=period)
    _sections(d, ctx, after_config=False)
    n_ps = d.get("n_ps", PRESETS[preset].n_ps)
    if (isinstance(n_ps, bool) or not isinstance(n_ps, numbers.Integral) or int(n_ps) < 1 or int(n_ps) % 2 == 0
            or int(n_ps) > MPC_MAX_N_PS):
        raise ValueError(f"mpc.n_ps must be an odd integer from 1 to {MPC_MAX_N_PS}, got {show(n_ps)}")

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
        if isinstance(v, bool) or (isinstance(v, numbers.Integral) and abs(int(v)) > 10 ** 15):
            raise ValueError(f"mpc.config.{k} must be a number or a name, got {v!r}"[:200])
    try:
        cfg, prm, behaviours = build_mpc(preset, config, params, speeds, courses)
        validate_params(prm, cfg, np.shape(behaviours)[1])
    except (ValueError, TypeError, OverflowError) as exc:
        raise ValueError(f"mpc ({preset!r} with the file's overrides): {exc}") from None
    if cfg.dtype == "float64":
        _enable_x64()
    ctx = dataclasses.replace(ctx, config=cfg)
    _sections(d, ctx, after_config=True)
    return MPCSpec(preset=preset, config=cfg, params=prm, behaviours=np.asarray(behaviours, dtype=float),
                   n_ps=int(n_ps), period=period, method=method, sections=dict(ctx.parsed),
                   given=tuple(k for k in (*SECTIONS, "params") if k in d), given_params=tuple(params_in))


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


def _enable_x64() -> None:
    """``mpc.config.dtype: float64`` needs 64-bit JAX: switch it on now, before any array is built (a process-wide
    JAX setting; arrays created before keep their dtype)."""
    import jax

    if not jax.config.jax_enable_x64:  # type: ignore[attr-defined]  # jax's Config stub lacks its flags
        jax.config.update("jax_enable_x64", True)
