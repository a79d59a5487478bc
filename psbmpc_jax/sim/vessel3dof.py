"""3-DOF manoeuvring model (Fossen 2021) with a speed/heading autopilot: an alternative *truth* ship model for
the closed-loop simulator, next to the kinematic one in :mod:`psbmpc_jax.sim.vessel` (Akdağ, Fossen & Johansen 2022,
eq. 1).

    eta_dot = R(psi) nu,        M nu_dot + C(nu) nu + D(nu) nu = tau

with ``eta = (x, y, psi)`` in NED (x north, y east, psi clockwise from north) and ``nu = (u, v, r)`` surge, sway
and yaw rate in the body frame.  Everything is NumPy float64, vectorised over any leading batch axes (the
simulator's ``[runs, ships]``); the parameters may differ per ship through :func:`stack_params`.

* ``M`` (3x3): rigid-body + added mass, port-starboard symmetric (no surge coupling).
* ``C(nu)``: Coriolis-centripetal matrix of the total ``M`` (rigid body + added mass, Fossen 2021 Ch. 3 and 6),
  ``[[0, 0, -m22 v - m23 r], [0, 0, m11 u], [m22 v + m23 r, -m11 u, 0]]`` with ``m23`` the mean of
  ``M[1, 2]`` and ``M[2, 1]``.
* ``D(nu) = D0 + max(U, U_floor) D1 + diag(X_uu |u|, 0, 0)``: constant linear damping, speed-proportional
  linear damping (the manoeuvring derivatives, which scale with speed) and optional quadratic surge drag.
* ``tau = (tau_X, c_YN tau_N, tau_N)``: a surge force and a yaw moment from a rudder-like actuator whose sway
  force is ``c_YN`` times its moment; ``tau_X`` in ``[-X_rev, X_max]``, ``|tau_N| <= N0 + N2 U^2``.

Autopilot (continuous, evaluated inside the integrator; the commands are held over the step):

* surge speed, feedback-linearising: ``tau_X = m11 k_u (u_c - u) + [C(nu) nu + D(nu) nu]_X`` so that
  ``u_dot = -k_u (u - u_c)`` while unsaturated;
* heading, proportional with a rate limit, through a feedback-linearising yaw-rate loop:
  ``r_d = sat(k_psi wrap(psi_c - psi), r_max)`` and ``tau_N`` such that ``r_dot = k_r (r_d - r)`` while
  unsaturated.  The heading command is the course command (``psi_c = chi_c``, no crab-angle compensation:
  without current the sway velocity, hence the crab angle, vanishes on straight legs; LOS absorbs the
  transient drift in turns).

Integration: classic RK4 with ``ceil(dt / max_substep)`` equal substeps per call of :func:`step`.

The presets (:data:`PRESETS`) and their sources are described in ``docs/vessel3dof.md``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..numerics import wrap_angle_host as wrap

RHO_WATER = 1025.0          # kg/m^3, as MSS clarke83.m
STATE_FIELDS = ("x", "y", "psi", "u", "v", "r")


def _mat3(value, name: str) -> tuple:
    a = np.asarray(value, dtype=float)
    if a.shape != (3, 3):
        raise ValueError(f"{name} must be a 3x3 matrix, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be finite")
    return tuple(tuple(float(x) for x in row) for row in a)


@dataclass(frozen=True)
class Vessel3DOFParams:
    """One vessel: model matrices, actuator limits and autopilot gains (SI units, radians).

    Matrices are stored as nested tuples (hashable); :meth:`arrays` returns them as NumPy arrays."""

    name: str
    length: float                  # m (documentation, and the scale of the presets)
    M: tuple | np.ndarray          # 3x3 inertia incl. added mass [kg, kg m, kg m^2]
    D0: tuple | np.ndarray         # 3x3 constant linear damping
    D1: tuple | np.ndarray         # 3x3 linear damping per m/s of speed over ground
    X_uu: float = 0.0              # quadratic surge drag coefficient [N s^2/m^2], >= 0
    U_floor: float = 0.0           # D1 is scaled by max(U, U_floor) [m/s], >= 0
    X_max: float = math.inf        # max forward surge force [N], > 0
    X_rev: float = math.inf        # max astern (braking) surge force [N], >= 0
    N0: float = math.inf           # yaw moment available at any speed (thrusters) [N m], >= 0
    N2: float = 0.0                # speed-squared yaw moment (rudder) [N m s^2/m^2], >= 0
    c_YN: float = 0.0              # sway force per yaw moment of the yaw actuator [1/m]
    k_u: float = 0.2               # surge speed loop gain [1/s], > 0
    k_psi: float = 0.3             # heading gain [1/s], > 0
    k_r: float = 1.2               # yaw-rate loop gain [1/s], > 0
    r_max: float = math.inf        # yaw-rate command limit [rad/s], > 0
    max_substep: float = 0.1       # RK4 substep limit [s], > 0
    source: str = ""               # where the numbers come from

    def __post_init__(self):
        for f in ("M", "D0", "D1"):
            object.__setattr__(self, f, _mat3(getattr(self, f), f))
        M = np.asarray(self.M)
        if M[0, 1] != 0.0 or M[0, 2] != 0.0 or M[1, 0] != 0.0 or M[2, 0] != 0.0:
            raise ValueError("M must not couple surge with sway/yaw (M[0,1], M[0,2], M[1,0], M[2,0] must be 0)")
        if np.any(np.linalg.eigvalsh(0.5 * (M + M.T)) <= 0.0):
            raise ValueError("M must be positive definite")
        D0, D1 = np.asarray(self.D0), np.asarray(self.D1)
        if D0[0, 0] < 0.0 or D1[0, 0] < 0.0:
            raise ValueError("D0[0,0] and D1[0,0] (surge damping) must be >= 0")
        positive = ("length", "X_max", "k_u", "k_psi", "k_r", "r_max", "max_substep")
        non_negative = ("X_uu", "U_floor", "X_rev", "N0", "N2")
        for f in positive + non_negative + ("c_YN",):
            v = getattr(self, f)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or math.isnan(v):
                raise ValueError(f"{f} must be a number, got {v!r}")
            object.__setattr__(self, f, float(v))
        for f in positive:
            if not getattr(self, f) > 0.0:
                raise ValueError(f"{f} must be > 0, got {getattr(self, f)}")
        for f in non_negative:
            if not getattr(self, f) >= 0.0:
                raise ValueError(f"{f} must be >= 0, got {getattr(self, f)}")
        for f in ("length", "k_u", "k_psi", "k_r", "max_substep", "X_uu", "U_floor", "N2", "c_YN"):
            if not math.isfinite(getattr(self, f)):
                raise ValueError(f"{f} must be finite, got {getattr(self, f)}")
        if self.N0 == 0.0 and self.N2 == 0.0:
            raise ValueError("N0 and N2 are both 0: the vessel has no yaw actuator")
        Minv = np.linalg.inv(M)
        if abs(Minv[2, 1] * self.c_YN + Minv[2, 2]) < 1e-12 * abs(Minv[2, 2]):
            raise ValueError("c_YN makes the yaw actuator's effect on the yaw rate vanish")

    def replace(self, **changes) -> "Vessel3DOFParams":
        return dataclasses.replace(self, **changes)

    def arrays(self) -> dict:
        """The parameters as float arrays (matrices ``[3, 3]``, scalars ``[]``)."""
        out = {f.name: np.asarray(getattr(self, f.name), dtype=float) for f in dataclasses.fields(self)
               if f.name not in ("name", "source")}
        out["Minv"] = np.linalg.inv(out["M"])
        return out


def stack_params(params) -> dict:
    """A sequence of :class:`Vessel3DOFParams` (one per ship) -> arrays with a leading ship axis ``[n, ...]``,
    broadcasting against states ``[..., n, 6]``.  A single :class:`Vessel3DOFParams` gives unbatched arrays."""
    if isinstance(params, Vessel3DOFParams):
        return params.arrays()
    if isinstance(params, dict):
        return params
    per = [p.arrays() for p in params]
    return {k: np.stack([a[k] for a in per]) for k in per[0]}


# ------------------------------------------------------------------------------------------------ dynamics
def _mv(A, x):
    """Batched 3x3 matrix times 3-vector: ``A [..., 3, 3]`` (or ``[3, 3]``), ``x [..., 3]``."""
    return np.einsum("...ij,...j->...i", A, x)


def coriolis_times_nu(M, nu):
    """``C(nu) nu`` of the total inertia ``M`` (rigid body + added mass): ``[..., 3]``."""
    u, v, r = nu[..., 0], nu[..., 1], nu[..., 2]
    m11, m22 = M[..., 0, 0], M[..., 1, 1]
    m23 = 0.5 * (M[..., 1, 2] + M[..., 2, 1])
    a = m22 * v + m23 * r
    return np.stack([-a * r, m11 * u * r, a * u - m11 * u * v], axis=-1)


def damping_times_nu(p, nu):
    """``D(nu) nu = D0 nu + max(U, U_floor) D1 nu + (X_uu |u| u, 0, 0)``: ``[..., 3]``."""
    u, v = nu[..., 0], nu[..., 1]
    U = np.maximum(np.hypot(u, v), p["U_floor"])
    out = _mv(p["D0"], nu) + U[..., None] * _mv(p["D1"], nu)
    return out + np.stack([p["X_uu"] * np.abs(u) * u, np.zeros_like(u), np.zeros_like(u)], axis=-1)


def control_forces(p, psi, nu, psi_c, u_c):
    """Autopilot output ``tau [..., 3]`` (after saturation) for heading command ``psi_c`` and surge speed
    command ``u_c``."""
    u, v, r = nu[..., 0], nu[..., 1], nu[..., 2]
    n = coriolis_times_nu(p["M"], nu) + damping_times_nu(p, nu)
    Minv = p["Minv"]
    # surge: feedback linearisation (M has no surge coupling)
    tau_X = p["M"][..., 0, 0] * p["k_u"] * (u_c - u) + n[..., 0]
    tau_X = np.clip(tau_X, -p["X_rev"], p["X_max"])
    # heading: P on heading with a rate limit, then a feedback-linearising yaw-rate loop
    r_d = np.clip(p["k_psi"] * wrap(psi_c - psi), -p["r_max"], p["r_max"])
    rdot_d = p["k_r"] * (r_d - r)
    a21, a22 = Minv[..., 2, 1], Minv[..., 2, 2]
    tau_N = (rdot_d + a21 * n[..., 1] + a22 * n[..., 2]) / (a21 * p["c_YN"] + a22)
    U2 = u * u + v * v
    N_lim = p["N0"] + p["N2"] * U2
    tau_N = np.clip(tau_N, -N_lim, N_lim)
    return np.stack([tau_X, p["c_YN"] * tau_N, tau_N], axis=-1)


def derivatives(state, psi_c, u_c, p):
    """Closed-loop state derivative ``[..., 6]`` of ``state [..., 6] = (x, y, psi, u, v, r)``."""
    psi, nu = state[..., 2], state[..., 3:6]
    u, v, r = nu[..., 0], nu[..., 1], nu[..., 2]
    c, s = np.cos(psi), np.sin(psi)
    tau = control_forces(p, psi, nu, psi_c, u_c)
    rhs = tau - coriolis_times_nu(p["M"], nu) - damping_times_nu(p, nu)
    nu_dot = _mv(p["Minv"], rhs)
    return np.concatenate([np.stack([c * u - s * v, s * u + c * v, r], axis=-1), nu_dot], axis=-1)


def step(state, chi_c, U_c, dt: float, params) -> np.ndarray:
    """Advance ``state [..., 6]`` (x, y, psi, u, v, r) by ``dt`` seconds under course command ``chi_c`` and
    speed command ``U_c`` (``[...]``, held over the step); RK4 with ``ceil(dt / max_substep)`` substeps.

    ``params``: one :class:`Vessel3DOFParams`, a sequence of them (one per ship, the last batch axis of
    ``state``) or the dict of :func:`stack_params` (precompute it once for speed); a batch of several
    parameter sets uses the smallest ``max_substep`` of them for all ships.  The heading command is the
    course command; the surge speed command is ``U_c``.  ``psi`` of the result is wrapped to [-pi, pi)."""
    p = stack_params(params)
    x = np.asarray(state, dtype=float)
    if x.shape[-1] != 6:
        raise ValueError(f"state must have 6 components (x, y, psi, u, v, r) in its last axis, got {x.shape}")
    if not dt > 0.0:
        raise ValueError(f"dt must be > 0, got {dt}")
    psi_c = np.broadcast_to(np.asarray(chi_c, dtype=float), x.shape[:-1])
    u_c = np.broadcast_to(np.asarray(U_c, dtype=float), x.shape[:-1])
    n_sub = int(math.ceil(dt / float(np.min(p["max_substep"])) - 1e-9))
    h = dt / n_sub
    for _ in range(n_sub):
        k1 = derivatives(x, psi_c, u_c, p)
        k2 = derivatives(x + 0.5 * h * k1, psi_c, u_c, p)
        k3 = derivatives(x + 0.5 * h * k2, psi_c, u_c, p)
        k4 = derivatives(x + h * k3, psi_c, u_c, p)
        x = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    x = x.copy()
    x[..., 2] = wrap(x[..., 2])
    return x


# ------------------------------------------------------------------------------------- simulator's view
def sim_view(state) -> np.ndarray:
    """``[..., 6]`` -> the simulator's 4-state ``[..., 4]`` (x, y, course over ground chi, speed over ground U),
    ``chi = wrap(psi + atan2(v, u))`` (``chi = psi`` at exactly zero speed)."""
    s = np.asarray(state, dtype=float)
    u, v = s[..., 3], s[..., 4]
    return np.stack([s[..., 0], s[..., 1], wrap(s[..., 2] + np.arctan2(v, u)), np.hypot(u, v)], axis=-1)


def from_sim_state(state4) -> np.ndarray:
    """The simulator's ``[..., 4]`` (x, y, chi, U) -> ``[..., 6]``: heading = course, surge = U, no sway or
    yaw rate (a ship on a straight course in still water)."""
    s = np.asarray(state4, dtype=float)
    z = np.zeros(s.shape[:-1])
    return np.stack([s[..., 0], s[..., 1], wrap(s[..., 2]), s[..., 3], z, z], axis=-1)


# ---------------------------------------------------------------------------------------------- presets
def added_mass_surge(m: float, L: float, rho: float = RHO_WATER) -> float:
    """Söding (1982) added mass in surge, ``-X_udot = 2.7 rho nabla^(5/3) / L^2`` (as MSS addedMassSurge.m)."""
    return 2.7 * rho * (m / rho) ** (5.0 / 3.0) / L ** 2


def clarke83_matrices(L: float, B: float, T: float, Cb: float, R66: float, xg: float = 0.0,
                      rho: float = RHO_WATER):
    """Rigid-body and added mass and the speed-proportional linear manoeuvring matrix from Clarke, Gedling &
    Hine (1983) as coded in Fossen's MSS ``clarke83.m``: returns ``(m, M_RB, M_A, N1)`` with the
    dimensional hydrodynamic linear damping ``N(U) = U * N1`` (sway/yaw; surge is set separately)."""
    nabla = Cb * L * B * T
    m = rho * nabla
    Iz = m * R66 ** 2 + m * xg ** 2
    M_RB = np.array([[m, 0.0, 0.0], [0.0, m, m * xg], [0.0, m * xg, Iz]])
    S = math.pi * (T / L) ** 2
    Yvd = -S * (1.0 + 0.16 * Cb * B / T - 5.1 * (B / L) ** 2)
    Yrd = -S * (0.67 * B / L - 0.0033 * (B / T) ** 2)
    Nvd = -S * (1.1 * B / L - 0.041 * B / T)
    Nrd = -S * (1.0 / 12.0 + 0.017 * Cb * B / T - 0.33 * B / L)
    Yv = -S * (1.0 + 0.4 * Cb * B / T)
    Yr = -S * (-0.5 + 2.2 * B / L - 0.08 * B / T)
    Nv = -S * (0.5 + 2.4 * T / L)
    Nr = -S * (0.25 + 0.039 * B / T - 0.56 * B / L)
    Tinv = np.diag([1.0, 1.0, L])
    MA_prime = np.array([[0.0, 0.0, 0.0], [0.0, -Yvd, -Yrd], [0.0, -Nvd, -Nrd]])
    N_prime = np.array([[0.0, 0.0, 0.0], [0.0, -Yv, -Yr], [0.0, -Nv, -Nr]])
    # Fossen 2021 App. D: M = (rho L^3 / 2) Tinv^2 (T M' Tinv) = (rho L^3 / 2) Tinv M' Tinv, T = diag(1, 1, 1/L)
    M_A = 0.5 * rho * L ** 3 * (Tinv @ MA_prime @ Tinv)
    M_A[0, 0] = added_mass_surge(m, L, rho)
    N1 = 0.5 * rho * L ** 2 * (Tinv @ N_prime @ Tinv)
    return m, M_RB, M_A, N1


def _coriolis_jacobian(M) -> np.ndarray:
    """Jacobian of ``C(nu) nu`` at ``nu = (1, 0, 0)`` (per m/s of surge speed)."""
    m11, m22, m23 = M[0, 0], M[1, 1], 0.5 * (M[1, 2] + M[2, 1])
    return np.array([[0.0, 0.0, 0.0], [0.0, 0.0, m11], [0.0, m22 - m11, m23]])


def rudder_coefficients(L: float, T: float, Cb: float, rho: float = RHO_WATER, aspect: float = 0.7,
                        delta_max_deg: float = 30.0):
    """Rudder model of Fossen (2021) §9.5.1 as coded in MSS ``shipClarke83``: rudder height ``0.7 T``,
    aspect ratio 0.7, ``x_R = -0.45 L``, ``a_H = 0.4``, ``x_H = -L``.  Returns ``(N2, c_YN)``: the largest yaw
    moment per U^2 (at ``delta_max``) and the rudder's sway force per yaw moment."""
    b = 0.7 * T
    A_R = b ** 2 / aspect
    C_N = 6.13 * aspect / (aspect + 2.25)
    a_H, x_R, x_H = 0.4, -0.45 * L, -1.0 * L
    N_d = -0.25 * (x_R + a_H * x_H) * rho * A_R * C_N            # per U^2, > 0
    Y_d = -0.25 * (1.0 + a_H) * rho * A_R * C_N                 # per U^2, < 0
    return N_d * math.sin(2.0 * math.radians(delta_max_deg)), Y_d / N_d


def clarke83_vessel(name: str, L: float, B: float, T: float, Cb: float, *, X_max: float, X_rev: float,
                    N0: float, k_u: float, k_psi: float, k_r: float, r_max: float, max_substep: float,
                    U_floor: float, source: str, T_surge: float | None = None) -> Vessel3DOFParams:
    """A :class:`Vessel3DOFParams` from main particulars: Clarke (1983) derivatives (MSS ``clarke83.m``),
    Söding's surge added mass, surge damping ``(m - X_udot) / T_surge`` (MSS default ``T_surge = L`` seconds),
    radius of gyration ``0.27 L`` above 100 m else ``0.25 L`` (MSS), CG at midship, the MSS rudder model.

    Clarke's measured derivatives contain the linearised added-mass Coriolis/Munk terms; ``C(nu)`` of the
    model is computed from the total ``M``, so ``D1`` is Clarke's ``N1`` minus the added-mass part of the
    linearised ``C``: the model then linearises (straight run at speed U) to Fossen's linear manoeuvring
    model ``M nu_dot + (C_RB(U) + N(U)) nu``."""
    R66 = 0.27 * L if L > 100.0 else 0.25 * L
    m, M_RB, M_A, N1 = clarke83_matrices(L, B, T, Cb, R66)
    M = M_RB + M_A
    D1 = N1 - (_coriolis_jacobian(M) - _coriolis_jacobian(M_RB))
    D0 = np.zeros((3, 3))
    D0[0, 0] = M[0, 0] / (L if T_surge is None else T_surge)
    N2, c_YN = rudder_coefficients(L, T, Cb)
    return Vessel3DOFParams(name=name, length=L, M=M, D0=D0, D1=D1, X_uu=0.0, U_floor=U_floor, X_max=X_max,
                            X_rev=X_rev, N0=N0, N2=N2, c_YN=c_YN, k_u=k_u, k_psi=k_psi, k_r=k_r, r_max=r_max,
                            max_substep=max_substep, source=source)


#: Froude scale factors from the MSS supply vessel (L = 76.2 m) whose thruster set sizes the actuators.
_MSS_SUPPLY_L = 76.2
_MSS_SUPPLY_X_MAX = 2 * 31.2 * 160.0 ** 2          # two main propellers, K n_max^2 = 798.7 kN each [N]
_MSS_SUPPLY_N_TUNNEL = 3.2 * 250.0 ** 2 * (30.0 + 22.0 + 22.0 + 30.0)   # 4 tunnel thrusters, pure moment [N m]
#: Main particulars of the 80 m PSV (full load) of the SbS_PSV simulator (carlosouza87/SbS_PSV, dimensions.m)
_PSV80 = dict(L=80.0, B=19.0, T=6.6, Cb=0.73)


def _froude_psv(L: float) -> dict:
    lam = L / _PSV80["L"]
    return dict(L=L, B=_PSV80["B"] * lam, T=_PSV80["T"] * lam, Cb=_PSV80["Cb"])


#: Assumed top speeds at full thrust (linear surge drag): sizes the surge damping of the presets [m/s].
PSV_U_MAX = 9.0            # ~17.5 kn for the 116 m PSV
SMALL_U_MAX = 4.0          # river craft (the river scenarios run at 2 m/s)
PSV_K_PSI = 1.0 / 7.5      # heading gains: course 63 % rise times ~15 s (PSV) and ~3 s (5 m), measured
SMALL_K_PSI = 1.0 / 1.5


def _surge_mass(hull: dict) -> float:
    L = hull["L"]
    m, _, M_A, _ = clarke83_matrices(L, hull["B"], hull["T"], hull["Cb"], 0.27 * L if L > 100.0 else 0.25 * L)
    return m + M_A[0, 0]


def _psv_116m() -> Vessel3DOFParams:
    lam = 116.0 / _MSS_SUPPLY_L
    X_max = _MSS_SUPPLY_X_MAX * lam ** 3
    hull = _froude_psv(116.0)
    return clarke83_vessel(
        "psv_116m", **hull, T_surge=PSV_U_MAX * _surge_mass(hull) / X_max,
        X_max=X_max, X_rev=X_max, N0=_MSS_SUPPLY_N_TUNNEL * lam ** 4,
        k_u=1.0 / 30.0, k_psi=PSV_K_PSI, k_r=4.0 * PSV_K_PSI, r_max=math.radians(1.5), max_substep=0.25,
        U_floor=1.0,
        source="Clarke et al. (1983) derivatives (MSS clarke83.m) for the 80 m PSV of carlosouza87/SbS_PSV "
               "Froude-scaled to 116 m; thrusters of MSS supply.py Froude-scaled from 76.2 m; top speed 9 m/s "
               "assumed; NOT Minne (2017)")


def _small_5m(psv: Vessel3DOFParams) -> Vessel3DOFParams:
    lam = 5.0 / _MSS_SUPPLY_L
    hull = _froude_psv(5.0)
    t_scale = math.sqrt(5.0 / 116.0)                             # Froude time scale
    T_surge = psv.M[0][0] / psv.D0[0][0] * t_scale
    X_max = SMALL_U_MAX * _surge_mass(hull) / T_surge
    return clarke83_vessel(
        "small_5m", **hull, T_surge=T_surge, X_max=X_max, X_rev=X_max, N0=_MSS_SUPPLY_N_TUNNEL * lam ** 4,
        k_u=1.0 / 5.0, k_psi=SMALL_K_PSI, k_r=4.0 * SMALL_K_PSI, r_max=psv.r_max / t_scale, max_substep=0.05,
        U_floor=psv.U_floor * t_scale,
        source="psv_116m hull, surge time constant, yaw thrusters, rate limit and U_floor Froude-scaled to 5 m; "
               "top speed 4 m/s assumed (thrust sized by it); autopilot gains for the river scenarios")


def kinematic_limit_params(T_chi: float, T_U: float, k_r: float = 200.0) -> Vessel3DOFParams:
    """A near-massless vessel with a fast yaw-rate loop and no actuator limits: its heading and surge obey
    ``psi_dot ~ wrap(chi_c - psi) / T_chi`` and ``u_dot = (U_c - u) / T_U``, the kinematic model of
    :mod:`psbmpc_jax.sim.vessel` with the same time constants (sway stays ~1e-4 of the speed times r)."""
    M = np.diag([1e-3, 1.0, 1.0])
    D0 = np.diag([0.0, 10.0, 0.0])
    return Vessel3DOFParams(name="kinematic_limit", length=1.0, M=M, D0=D0, D1=np.zeros((3, 3)), k_u=1.0 / T_U,
                            k_psi=1.0 / T_chi, k_r=k_r, max_substep=1.0 / k_r, source="test/limit set")


_PSV = _psv_116m()
#: The named parameter sets (YAML ``vessel_model``).
PRESETS = {"psv_116m": _PSV, "small_5m": _small_5m(_PSV)}


def preset(name: str | None) -> Vessel3DOFParams:
    """The named preset (``psv_116m`` or ``small_5m``)."""
    if name not in PRESETS:
        raise ValueError(f"vessel_model must be one of {sorted(PRESETS)}, got {name!r}")
    return PRESETS[name]


# ----------------------------------------------------------------------------------- step-response fit
def step_response_times(params: Vessel3DOFParams, U0: float, dchi_deg: float = 30.0, dU: float | None = None,
                        dt: float = 0.1, horizon: float | None = None) -> tuple[float, float]:
    """Measured 63 % rise times ``(T_chi, T_U)`` [s] from a straight run at ``U0``: a course-command step of
    ``dchi_deg`` at constant speed command (the course over ground of :func:`sim_view`), and a speed-command
    step ``U0 -> U0 + dU`` (default ``-U0 / 2``: the planner's "slow forward") at constant course.  These are
    what the kinematic model's ``T_chi`` and ``T_U`` would be fitted to."""
    dU = -0.5 * U0 if dU is None else dU
    horizon = horizon or 40.0 / params.k_psi + 20.0 / params.k_u
    n = int(round(horizon / dt))
    p = stack_params(params)
    s0 = from_sim_state(np.array([0.0, 0.0, 0.0, U0]))
    dchi = math.radians(dchi_deg)
    s = np.stack([s0, s0])
    chi_c, U_c = np.array([dchi, 0.0]), np.array([U0, U0 + dU])
    chi_hist, U_hist = np.empty(n + 1), np.empty(n + 1)
    v = sim_view(s)
    chi_hist[0], U_hist[0] = v[0, 2], v[1, 3]
    for k in range(n):
        s = step(s, chi_c, U_c, dt, p)
        v = sim_view(s)
        chi_hist[k + 1], U_hist[k + 1] = v[0, 2], v[1, 3]
    t = np.arange(n + 1) * dt

    def rise(y, target):
        frac = (y - y[0]) / (target - y[0])
        i = int(np.argmax(frac >= 1.0 - math.exp(-1.0)))
        if frac[i] < 1.0 - math.exp(-1.0):
            return math.inf
        f0, f1 = frac[i - 1], frac[i]
        return float(t[i - 1] + dt * ((1.0 - math.exp(-1.0)) - f0) / (f1 - f0))

    return rise(chi_hist, dchi), rise(U_hist, U0 + dU)
