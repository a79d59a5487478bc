"""Planner parameters.

Two containers, following the habit of keeping *shapes* apart from *values*:

* :class:`PlannerConfig` — static, hashable: everything that fixes an array shape or selects code
  (horizon and time step, estimator, sample counts, dtype, tiling).  Changing it recompiles.
* :class:`Params` — a frozen dataclass registered as a JAX pytree whose leaves are scalars/arrays:
  model constants, weights and thresholds.  Changing a value never recompiles, and a ``Params`` can be
  vmapped over or differentiated.

All angles are radians and all quantities SI inside the package.  Defaults are those of
the PSB-MPC paper (Tengesdal, Johansen, Grande & Blindheim 2022, Table 1) where it gives them, otherwise the authors'
published C++ implementation (``docs/methods/psbmpc.md``, "Parameters and defaults").
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import importlib.abc
import importlib.util
import sys
from dataclasses import dataclass, fields

import numpy as np

from .layouts import GROUNDING_SEARCHES, LAYOUT_PLATFORMS, PC_LAYOUTS, ROLLOUT_KERNELS

ESTIMATORS = ("quadrature", "mc", "ce")
#: ``PlannerConfig.stop_remedy`` values (:mod:`psbmpc_jax.costs.colregs`): the published COLREGS indicator, or
#: the indicator on the own-ship's heading whatever its speed.
STOP_REMEDIES = ("none", "colregs_heading")
DTYPES = ("float32", "float64")

#: Most prediction steps ``T / dt`` a :class:`PlannerConfig` may have.
MAX_HORIZON_STEPS = 100_000
_CONFIG_FLOATS = ("T", "dt", "quad_span", "grid_spacing", "grid_margin")
#: Allowed ranges of the integer :class:`PlannerConfig` fields (upper bounds only stop absurd sizes).
_CONFIG_INTS = {"n_samples": (1, 10_000_000), "ce_max_iter": (0, 1000), "n_quad": (2, 10_000),
                "time_block": (1, 100_000), "chunk_rows": (1, 100_000_000)}


def _finite_float(v) -> bool:
    try:
        return math.isfinite(float(v))
    except OverflowError:
        return False


def _show(v) -> str:
    """``repr(v)``, with huge integers shortened to their number of digits."""
    if isinstance(v, numbers.Integral) and not isinstance(v, bool) and abs(int(v)) >= 10 ** 30:
        return f"(an integer with {len(str(abs(int(v))))} digits)"
    r = repr(v)
    return r if len(r) <= 200 else r[:200] + "..."


@dataclass(frozen=True)
class PlannerConfig:
    """Static configuration (hashable; part of the jit cache key).

    Attributes:
        T: prediction horizon [s].
        dt: prediction time step [s]; ``T / dt`` must be an integer number of steps.
        estimator: collision-probability estimator, one of ``"quadrature"``, ``"mc"``, ``"ce"``.
        n_samples: samples per Monte Carlo estimate (``mc``) and per Cross-Entropy iteration (``ce``).
        ce_max_iter: maximum Cross-Entropy iterations before the final importance-sampling pass.
        n_quad: Gauss-Legendre nodes of the ``quadrature`` estimator.
        quad_span: half-width, in standard deviations, of the integration window of ``quadrature``.
        dtype: ``"float32"`` (fast) or ``"float64"`` (needs ``jax_enable_x64``).
        time_block: time steps per block of the streamed collision kernel.
        chunk_rows: (behaviour, obstacle, scenario) rows per collision-probability chunk.
        pc_layout: ``"compact"`` (stream time blocks, evaluate only rows that pass the sigma shortcut),
            ``"dense"`` (evaluate every (l, i, s, k) point in one pass; memory-hungry; the GPU's) or ``"auto"``
            (compact on the CPU; on a GPU dense while it fits, :func:`psbmpc_jax.layouts.resolve_pc_layout`).
        grounding_mode: ``"exact"`` (every polygon edge, every point; per-polygon costs) or ``"grid"``
            (bilinear lookup in a nearest-land distance grid built once per chart; relative error of the
            grounding cost <= exp(G3·grid_spacing/√2) − 1 without wind; see :mod:`psbmpc_jax.distance_grid`).
        grounding_search: the exact mode's layout: ``"bounded"`` (each polygon's worst time step from distance
            bounds and a few exact distances, proven or else searched as ``culled``; for charts of a few small
            polygons, larger ones go to ``culled``: the CPU's choice, :mod:`psbmpc_jax.bounded_search`),
            ``"culled"`` (a search culling tiles and edge chunks by bounds, many short loop steps), ``"dense"``
            (every edge against every point, 32 edges per loop step, one polygon at a time), ``"flat"`` (every
            polygon's every edge in one masked pass, no loop: the GPU's choice) or ``"auto"`` (bounded on the CPU,
            flat elsewhere).  Same costs.
        rollout_unroll: prediction steps per loop step of the own-ship and obstacle rollouts (an int >= 1, or
            ``"auto"``: 1 on the CPU, :data:`psbmpc_jax.layouts.GPU_UNROLL` on a GPU).  Same trajectories.
        rollout_kernel: ``"scan"`` (the rollouts as ``lax.scan``), ``"pallas"`` (one kernel, each row's rollout
            in registers, :mod:`psbmpc_jax.rollout_kernel`; interpreted on a CPU) or ``"auto"`` (scan on the
            CPU, pallas on a GPU where its self-check passes).  Same trajectories.
        layout_platform: the platform the ``"auto"`` layouts are chosen for: ``"auto"`` (JAX's default backend),
            ``"cpu"`` or ``"gpu"`` (:mod:`psbmpc_jax.layouts`; :meth:`for_platform`).
        grid_spacing, grid_margin: grid resolution [m] and the margin around the polygons [m] (outside it the
            distance is taken as ``grid_margin``).
        stop_remedy: the stop loophole of the Boolean COLREGS indicator (a stopped own-ship never violates, so
            stopping escapes the COLREGS cost): ``"none"`` (default: the papers' cost as published) or
            ``"colregs_heading"`` (the indicator evaluated on the own-ship's heading whatever its speed: a stopped
            give-way ship still violates; :mod:`psbmpc_jax.costs.colregs`, docs/methods/psbmpc.md).  Read by the
            ``psbmpc`` and ``psbmpc_2020`` COLREGS terms.
    """

    T: float = 150.0
    dt: float = 0.5
    estimator: str = "quadrature"
    n_samples: int = 500
    ce_max_iter: int = 6
    n_quad: int = 32
    quad_span: float = 6.0
    dtype: str = "float32"
    time_block: int = 8
    chunk_rows: int = 512
    pc_layout: str = "auto"
    grounding_mode: str = "exact"
    grounding_search: str = "auto"
    grid_spacing: float = 0.5
    grid_margin: float = 100.0
    rollout_unroll: int | str = "auto"
    rollout_kernel: str = "auto"
    layout_platform: str = "auto"
    stop_remedy: str = "none"

    def __post_init__(self) -> None:
        for name in _CONFIG_FLOATS:
            v = getattr(self, name)
            if (isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers.Real) or not _finite_float(v)
                    or v <= 0):
                raise ValueError(f"PlannerConfig.{name} must be a finite number > 0 (int or float, not bool or "
                                 f"str), got {type(v).__name__} {_show(v)}")
            if isinstance(v, (np.floating, np.integer)):      # NumPy scalars: stored as the Python number
                object.__setattr__(self, name, v.item())
        n = self.T / self.dt
        if abs(n - round(n)) > 1e-9 * max(1.0, n) or round(n) < 1:
            raise ValueError(
                f"PlannerConfig.T / PlannerConfig.dt must be a positive whole number of steps, "
                f"got T={self.T}, dt={self.dt} (T/dt={n})"
            )
        if round(n) > MAX_HORIZON_STEPS:
            raise ValueError(f"PlannerConfig.T / PlannerConfig.dt = {round(n)} prediction steps; at most "
                             f"{MAX_HORIZON_STEPS} allowed (T={self.T} s, dt={self.dt} s)")
        for name, allowed in (("estimator", ESTIMATORS), ("dtype", DTYPES), ("grounding_mode", ("exact", "grid")),
                              ("grounding_search", GROUNDING_SEARCHES), ("pc_layout", PC_LAYOUTS),
                              ("layout_platform", LAYOUT_PLATFORMS), ("rollout_kernel", ROLLOUT_KERNELS),
                              ("stop_remedy", STOP_REMEDIES)):
            v = getattr(self, name)
            if not isinstance(v, str) or v not in allowed:
                raise ValueError(f"PlannerConfig.{name} must be one of {allowed}, got {v!r}")
        for name, (lo, hi) in _CONFIG_INTS.items():
            v = getattr(self, name)
            if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)) or not lo <= v <= hi:
                raise ValueError(f"PlannerConfig.{name} must be an integer in {lo}..{hi} (not bool), got "
                                 f"{type(v).__name__} {_show(v)}")
            object.__setattr__(self, name, int(v))

        u = self.rollout_unroll
        if u != "auto" and (isinstance(u, (bool, np.bool_)) or not isinstance(u, (int, np.integer))
                            or not 1 <= u <= MAX_HORIZON_STEPS):
            raise ValueError(f"PlannerConfig.rollout_unroll must be 'auto' or an integer in 1..{MAX_HORIZON_STEPS} "
                             f"(not bool), got {type(u).__name__} {_show(u)}")
        if u != "auto":
            object.__setattr__(self, "rollout_unroll", int(u))

    def for_platform(self, platform: str) -> "PlannerConfig":
        """A copy whose ``"auto"`` layouts are chosen as on ``platform`` (``"cpu"`` or ``"gpu"``) whatever runs
        it: ``grounding_search``, ``rollout_unroll`` and ``rollout_kernel`` resolved, ``layout_platform`` set
        (``pc_layout`` "auto" depends on the problem's size and is resolved when the program is traced)."""
        from .layouts import platform_of, resolve_rollout_kernel, resolve_search, resolve_unroll

        p = platform_of("gpu" if platform not in ("cpu", "auto") else platform)
        return self.replace(grounding_search=resolve_search(self.grounding_search, p),
                            rollout_unroll=resolve_unroll(self.rollout_unroll, p),
                            rollout_kernel=resolve_rollout_kernel(self.rollout_kernel, p), layout_platform=p)

    @property
    def n_steps(self) -> int:
        """N = T / dt; trajectories hold N + 1 samples t_0 .. t_0 + N dt."""
        return int(round(self.T / self.dt))

    def replace(self, **changes) -> "PlannerConfig":
        return dataclasses.replace(self, **changes)


_PYTREES: list = []          # dataclasses to register with JAX (every field a leaf)


def _register_pytrees() -> None:
    """Register the collected dataclasses as pytrees (idempotent; needs jax imported)."""
    import jax

    def register(cls) -> None:
        names = tuple(f.name for f in fields(cls))

        def flatten(obj):
            return tuple(getattr(obj, n) for n in names), None

        def unflatten(_, leaves):
            return cls(**dict(zip(names, leaves)))

        jax.tree_util.register_pytree_node(cls, flatten, unflatten)

    while _PYTREES:
        register(_PYTREES.pop())


class _AfterJaxImport(importlib.abc.MetaPathFinder):
    """Registers the pytrees right after ``jax`` is first imported.

    Importing this module must not import JAX (about 1-2 s): loading and checking a scenario file, and failing
    fast on a bad one, needs only NumPy and shapely.  So when jax is not imported yet, this one-shot finder
    wraps jax's loader and registers the pytrees as soon as ``import jax`` has run, whoever imports it."""

    def find_spec(self, name, path=None, target=None):
        if name != "jax":
            return None
        sys.meta_path.remove(self)
        spec = importlib.util.find_spec("jax")
        if spec is None or spec.loader is None:
            return spec
        run = spec.loader.exec_module

        def exec_module(module):
            run(module)
            _register_pytrees()

        spec.loader.exec_module = exec_module
        return spec


def _pytree_dataclass(cls):
    """Mark a frozen dataclass to be registered as a pytree whose every field is a leaf."""
    _PYTREES.append(cls)
    return cls


@_pytree_dataclass
@dataclass(frozen=True)
class Params:
    """Array-valued planner parameters (a JAX pytree).  See the README table for meaning and source.

    Own-ship model and guidance (Tengesdal et al. 2022, eqs. 3–6 and 19; docs/algorithm.md §2–3): ``os_T_chi``,
    ``os_T_U`` [s], ``os_lookahead`` (LOS Δ) and ``os_R_a`` (acceptance radius) [m].
    Obstacle prediction (Sec. II-A and eqs. 7–8; docs/algorithm.md §5–6): ``ob_T_chi``, ``ob_T_U``,
    ``ob_lookahead``, ``ob_R_a``, ``r_ct`` (scenario spacing) and the OU parameters ``sigma_x``, ``sigma_y``,
    ``sigma_xy``, ``gamma_x``, ``gamma_y``.
    Maneuver timing (docs/algorithm.md §4): ``t_ts`` [s], the spacing of the maneuver times; ``nan`` means T / n_M.
    Collision (eqs. 10–12; docs/algorithm.md §7–8): ``d_safe`` [m], ``K_coll``, ``T_d`` [s], shortcut factor
    ``c_sigma``, and the Cross-Entropy constants ``ce_rho``, ``ce_alpha``, ``ce_chi2``.
    COLREGS: ``kappa``, ``d_close`` [m].
    Grounding: ``G1``, ``G2``, ``G3`` [1/m], ``G4`` [1/s], wind speed ``V_w`` [m/s] and the direction the
    wind blows towards, ``wind_dir`` [rad, NED].
    Path: ``K_u``, ``K_du``, ``K_chi_stbd``, ``K_chi_port``, ``K_dchi_stbd``, ``K_dchi_port``.
    """

    os_T_chi: float = 0.92
    os_T_U: float = 1.44
    os_lookahead: float = 66.0
    os_R_a: float = 5.0
    ob_T_chi: float = 0.92
    ob_T_U: float = 1.44
    ob_lookahead: float = 66.0
    ob_R_a: float = 5.0
    r_ct: float = 10.0
    sigma_x: float = 0.025
    sigma_y: float = 0.025
    sigma_xy: float = 0.0
    gamma_x: float = 0.1
    gamma_y: float = 0.1
    t_ts: float = float("nan")
    d_safe: float = 5.0
    K_coll: float = 25.0
    T_d: float = 100.0
    c_sigma: float = 4.0
    ce_rho: float = 0.9
    ce_alpha: float = 0.9
    ce_chi2: float = 11.618
    kappa: float = 10.0
    d_close: float = 100.0
    G1: float = 100.0
    G2: float = 5.0
    G3: float = 0.25
    G4: float = 0.01
    V_w: float = 0.0
    wind_dir: float = 0.0
    K_u: float = 6.3
    K_du: float = 3.6
    K_chi_stbd: float = 1.5
    K_chi_port: float = 1.8
    K_dchi_stbd: float = 1.0
    K_dchi_port: float = 1.3

    def replace(self, **changes) -> "Params":
        return dataclasses.replace(self, **changes)

    def as_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}


# Fields that must be strictly positive / non-negative; everything must be finite except t_ts (nan = auto).
_POSITIVE = ("os_T_chi", "os_T_U", "os_lookahead", "ob_T_chi", "ob_T_U", "ob_lookahead", "gamma_x",
             "gamma_y", "T_d", "ce_chi2", "d_close")
_NON_NEGATIVE = ("os_R_a", "ob_R_a", "r_ct", "sigma_x", "sigma_y", "d_safe", "K_coll", "c_sigma", "kappa",
                 "G1", "G2", "G3", "G4", "V_w", "K_u", "K_du", "K_chi_stbd", "K_chi_port", "K_dchi_stbd",
                 "K_dchi_port")
_UNIT_INTERVAL = ("ce_rho", "ce_alpha")
#: The same groups, public (the device-side check of :func:`psbmpc_jax.solve.inputs_valid` uses them).
POSITIVE_FIELDS, NON_NEGATIVE_FIELDS, UNIT_INTERVAL_FIELDS = _POSITIVE, _NON_NEGATIVE, _UNIT_INTERVAL


def _param_value(v, name: str) -> float:
    """One Params leaf as float: a real scalar (Python, NumPy or a 0-d array), not bool or str."""
    if isinstance(v, (bool, np.bool_, str, bytes)) or v is None:
        raise ValueError(f"Params.{name} must be a real number, got {type(v).__name__} {v!r}")
    try:
        a = np.asarray(v)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"Params.{name} must be a real number, got {v!r} ({exc})") from None
    if a.dtype.kind not in "iuf":
        raise ValueError(f"Params.{name} must be a real number (int or float), got {type(v).__name__} {v!r}")
    if a.shape != ():
        raise ValueError(f"Params.{name} must be a scalar, got shape {a.shape}")
    try:
        return float(a)
    except OverflowError:
        raise ValueError(f"Params.{name} is too large to be a float") from None


def validate_params(params: Params, config: PlannerConfig | None = None, n_maneuvers: int | None = None) -> None:
    """Host-side check of parameter values; raises ``ValueError`` naming the field and what is allowed.

    Booleans and strings are refused (NumPy scalars and 0-d arrays are accepted); ``wind_dir`` must be in
    radians (``|wind_dir| <= 2 pi``: a larger value is taken for degrees and refused with the ``np.deg2rad``
    value).  With ``config`` the maneuver spacing ``t_ts`` must lie inside the horizon (``t_ts < T``, and
    with ``n_maneuvers`` = n_M: ``(n_M - 1) t_ts < T``, else later maneuvers never start)."""
    if not isinstance(params, Params):
        raise ValueError(f"params must be a psbmpc_jax.Params, got {type(params).__name__}")
    for f in fields(params):
        v = _param_value(getattr(params, f.name), f.name)
        if f.name == "t_ts":
            if not (math.isnan(v) or (math.isfinite(v) and v > 0)):
                raise ValueError(f"Params.t_ts must be > 0 (or nan for T / n_M), got {v}")
            continue
        if not math.isfinite(v):
            raise ValueError(f"Params.{f.name} must be finite, got {v}")
        if f.name in _POSITIVE and not v > 0:
            raise ValueError(f"Params.{f.name} must be > 0, got {v}")
        if f.name in _NON_NEGATIVE and not v >= 0:
            raise ValueError(f"Params.{f.name} must be >= 0, got {v}")
        if f.name in _UNIT_INTERVAL and not 0 < v <= 1:
            raise ValueError(f"Params.{f.name} must be in (0, 1], got {v}")
        if f.name == "wind_dir" and abs(v) > 2 * math.pi:
            raise ValueError(f"Params.wind_dir = {v:g} is not in radians (|wind_dir| <= 2 pi allowed: the direction "
                             f"the wind blows towards, from north); degrees? use np.deg2rad({v:g}) = "
                             f"{math.radians(v):.6g}")
    # the OU diffusion matrix [[sx^2, sxy], [sxy, sy^2]] must be positive semi-definite
    sx2, sy2, sxy = float(params.sigma_x) ** 2, float(params.sigma_y) ** 2, float(params.sigma_xy)
    if sxy * sxy > sx2 * sy2 * (1 + 1e-12):
        raise ValueError(
            f"Params.sigma_xy must satisfy sigma_xy^2 <= sigma_x^2 sigma_y^2 (PSD diffusion), got "
            f"sigma_xy={sxy}, sigma_x={params.sigma_x}, sigma_y={params.sigma_y}"
        )
    if config is not None:
        t_ts = float(params.t_ts)
        if not math.isnan(t_ts):
            n_m = 2 if n_maneuvers is None else int(n_maneuvers)
            if n_m >= 2 and (n_m - 1) * t_ts >= config.T:
                raise ValueError(
                    f"Params.t_ts = {t_ts:g} s puts maneuver {n_m} at {(n_m - 1) * t_ts:g} s, beyond the horizon "
                    f"PlannerConfig.T = {config.T:g} s; allowed: (n_M - 1) * t_ts < T with n_M = {n_m} "
                    f"(t_ts < {config.T / (n_m - 1):g} s), or nan for T / n_M")


def params_as_arrays(params: Params, dtype) -> Params:
    """The same parameters with every leaf a 0-d array of ``dtype`` (stable jit signature)."""
    import jax

    return jax.tree_util.tree_map(lambda v: np.asarray(v, dtype=dtype), params)


if "jax" in sys.modules:
    _register_pytrees()
else:
    sys.meta_path.insert(0, _AfterJaxImport())


__all__ = ["PlannerConfig", "Params", "validate_params", "params_as_arrays", "ESTIMATORS", "DTYPES", "STOP_REMEDIES",
           "MAX_HORIZON_STEPS"]
