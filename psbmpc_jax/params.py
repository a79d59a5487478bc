"""Planner parameters.

Two containers, following the habit of keeping *shapes* apart from *values*:

* :class:`PlannerConfig` — static, hashable: everything that fixes an array shape or selects code
  (horizon and time step, estimator, sample counts, dtype, tiling).  Changing it recompiles.
* :class:`Params` — a frozen dataclass registered as a JAX pytree whose leaves are scalars/arrays:
  model constants, weights and thresholds.  Changing a value never recompiles, and a ``Params`` can be
  vmapped over or differentiated.

All angles are radians and all quantities SI inside the package.  Defaults are those of
``SPEC_PSBMPC.md`` (paper Table 1 where it gives them; otherwise the authors' C++ implementation).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, fields

import jax
import numpy as np

ESTIMATORS = ("quadrature", "mc", "ce")
DTYPES = ("float32", "float64")


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
        pc_layout: ``"compact"`` (stream time blocks, evaluate only rows that pass the sigma shortcut)
            or ``"dense"`` (evaluate every (l, i, s, k) point; simple, memory-hungry; for tests and GPUs).
        grounding_mode: ``"exact"`` (every polygon edge, every point; per-polygon costs) or ``"grid"``
            (bilinear lookup in a nearest-land distance grid built once per chart; relative error of the
            grounding cost <= exp(G3·grid_spacing/√2) − 1 without wind; see :mod:`psbmpc_jax.distance_grid`).
        grid_spacing, grid_margin: grid resolution [m] and the margin around the polygons [m] (outside it the
            distance is taken as ``grid_margin``).
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
    pc_layout: str = "compact"
    grounding_mode: str = "exact"
    grid_spacing: float = 0.5
    grid_margin: float = 100.0

    def __post_init__(self) -> None:
        for name in ("T", "dt", "quad_span"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"PlannerConfig.{name} must be a finite number > 0, got {v!r}")
        n = self.T / self.dt
        if abs(n - round(n)) > 1e-9 * max(1.0, n) or round(n) < 1:
            raise ValueError(
                f"PlannerConfig.T / PlannerConfig.dt must be a positive whole number of steps, "
                f"got T={self.T}, dt={self.dt} (T/dt={n})"
            )
        if self.estimator not in ESTIMATORS:
            raise ValueError(f"PlannerConfig.estimator must be one of {ESTIMATORS}, got {self.estimator!r}")
        if self.dtype not in DTYPES:
            raise ValueError(f"PlannerConfig.dtype must be one of {DTYPES}, got {self.dtype!r}")
        if self.grounding_mode not in ("exact", "grid"):
            raise ValueError(
                f"PlannerConfig.grounding_mode must be 'exact' or 'grid', got {self.grounding_mode!r}")
        for name in ("grid_spacing", "grid_margin"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"PlannerConfig.{name} must be a finite number > 0, got {v!r}")
        if self.pc_layout not in ("compact", "dense"):
            raise ValueError(f"PlannerConfig.pc_layout must be 'compact' or 'dense', got {self.pc_layout!r}")
        for name, lo in (("n_samples", 1), ("ce_max_iter", 0), ("n_quad", 2), ("time_block", 1),
                         ("chunk_rows", 1)):
            v = getattr(self, name)
            if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or v < lo:
                raise ValueError(f"PlannerConfig.{name} must be an integer >= {lo}, got {v!r}")

    @property
    def n_steps(self) -> int:
        """N = T / dt; trajectories hold N + 1 samples t_0 .. t_0 + N dt."""
        return int(round(self.T / self.dt))

    def replace(self, **changes) -> "PlannerConfig":
        return dataclasses.replace(self, **changes)


def _pytree_dataclass(cls):
    """Register a frozen dataclass as a pytree whose every field is a leaf."""
    names = tuple(f.name for f in fields(cls))
    jax.tree_util.register_pytree_node(
        cls,
        lambda obj: (tuple(getattr(obj, n) for n in names), None),
        lambda _, leaves: cls(**dict(zip(names, leaves))),
    )
    return cls


@_pytree_dataclass
@dataclass(frozen=True)
class Params:
    """Array-valued planner parameters (a JAX pytree).  See the README table for meaning and source.

    Own-ship model and guidance (SPEC §2): ``os_T_chi``, ``os_T_U`` [s], ``os_lookahead`` (LOS Δ) and
    ``os_R_a`` (acceptance radius) [m].
    Obstacle prediction (SPEC §4-5): ``ob_T_chi``, ``ob_T_U``, ``ob_lookahead``, ``ob_R_a``, ``r_ct``
    (scenario spacing) and the OU parameters ``sigma_x``, ``sigma_y``, ``sigma_xy``, ``gamma_x``,
    ``gamma_y``.
    Maneuver timing (SPEC §3): ``t_ts`` [s], the spacing of the maneuver times; ``nan`` means T / n_M.
    Collision (SPEC §6-7): ``d_safe`` [m], ``K_coll``, ``T_d`` [s], shortcut factor ``c_sigma``, and the
    Cross-Entropy constants ``ce_rho``, ``ce_alpha``, ``ce_chi2``.
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


def validate_params(params: Params) -> None:
    """Host-side check of parameter values; raises ``ValueError`` naming the field and what is allowed."""
    if not isinstance(params, Params):
        raise ValueError(f"params must be a psbmpc_jax.Params, got {type(params).__name__}")
    for f in fields(params):
        v = np.asarray(getattr(params, f.name), dtype=float)
        if v.shape != ():
            raise ValueError(f"Params.{f.name} must be a scalar, got shape {v.shape}")
        v = float(v)
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
    # the OU diffusion matrix [[sx^2, sxy], [sxy, sy^2]] must be positive semi-definite
    sx2, sy2, sxy = float(params.sigma_x) ** 2, float(params.sigma_y) ** 2, float(params.sigma_xy)
    if sxy * sxy > sx2 * sy2 * (1 + 1e-12):
        raise ValueError(
            f"Params.sigma_xy must satisfy sigma_xy^2 <= sigma_x^2 sigma_y^2 (PSD diffusion), got "
            f"sigma_xy={sxy}, sigma_x={params.sigma_x}, sigma_y={params.sigma_y}"
        )


def params_as_arrays(params: Params, dtype) -> Params:
    """The same parameters with every leaf a 0-d array of ``dtype`` (stable jit signature)."""
    return jax.tree_util.tree_map(lambda v: np.asarray(v, dtype=dtype), params)


__all__ = ["PlannerConfig", "Params", "validate_params", "params_as_arrays", "ESTIMATORS", "DTYPES"]
