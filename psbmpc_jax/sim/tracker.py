"""Constant-velocity Kalman filter for target tracking in the closed-loop simulator (Tengesdal, Brekke & Johansen
2020, Secs. 2.2 and 7).

Model (Tengesdal, Brekke & Johansen 2020, eqs. (3)-(7)), NED frame, SI units::

    x = [north, east, V_north, V_east]        (m, m, m/s, m/s)
    x_{k+1} = F x_k + v_k,   v_k ~ N(0, Q)       (discretised white-noise acceleration, "CV model")
    z_k     = H x_k + w_k,   w_k ~ N(0, R)       (position measurement, radar/AIS; H = [I2 0])

    F = [[1, 0, dt, 0], [0, 1, 0, dt], [0, 0, 1, 0], [0, 0, 0, 1]]
    Q = sigma_a² [[dt³/3, 0, dt²/2, 0], [0, dt³/3, 0, dt²/2], [dt²/2, 0, dt, 0], [0, dt²/2, 0, dt]]

``sigma_a`` [m/s²] is the process-noise strength (the spectral density of the acceleration is sigma_a²), chosen
from the expected manoeuvrability of the vessel; ``dt`` may vary between steps.

Track initiation is single-point (Mallick & Scala 2008, as used in Tengesdal, Brekke & Johansen 2020, Sec. 7): the
first measurement gives the position, the velocity starts at zero, and the prior covariance is ``blockdiag(R, (U_max /
kappa)² I2)`` where ``U_max`` is the (a-priori known) maximum target speed. ``kappa`` says how many standard
deviations U_max spans in each velocity component; with U_max = 9 m/s and kappa = 2 the initial velocity variance is
20.25 (m/s)², the "velocity variance surpassing 20 (m/s)² initially" of Tengesdal, Brekke & Johansen (2020).

Conservative tuning (Tengesdal, Brekke & Johansen 2020, Sec. 7): to mimic unreliable radar in bad weather and to allow
fast manoeuvres, the filter in the simulations uses a measurement covariance 25 times the true one (true R = diag(25,
25) m², so the filter R = diag(625, 625) m²) and sigma_a = 0.5 m/s² for every target — see ``CONSERVATIVE_R_FACTOR``
and ``CONSERVATIVE_SIGMA_A``. This makes the estimates (and the velocity/course in particular) markedly uncertain,
which is what the probabilistic collision cost of the PSB-MPC is meant to account for.

All functions are pure numpy (float64) and broadcast over any leading batch axes ``...`` (e.g. [runs, targets]):
``x [..., 4]``, ``P [..., 4, 4]``, ``z [..., 2]``, measurement covariance ``R [2, 2]`` or ``[..., 2, 2]``.
"""

from __future__ import annotations

import numpy as np

from ..checks import positive

__all__ = [
    "CONSERVATIVE_R_FACTOR",
    "CONSERVATIVE_SIGMA_A",
    "DEFAULT_KAPPA",
    "H",
    "cv_model",
    "initiate",
    "predict",
    "update",
    "nees",
    "TrackerBank",
]

#: Tengesdal, Brekke & Johansen 2020, Sec. 7: the filter's measurement covariance is this many times the true one
#: (conservative tuning).
CONSERVATIVE_R_FACTOR = 25.0
#: Tengesdal, Brekke & Johansen 2020, Sec. 7: process-noise strength of the conservatively tuned filter [m/s²].
CONSERVATIVE_SIGMA_A = 0.5
#: Default number of standard deviations that U_max spans in each velocity component at initiation.
DEFAULT_KAPPA = 2.0

#: Measurement matrix (Tengesdal, Brekke & Johansen 2020, eq. (6)): position is measured.
H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])


# ----------------------------------------------------------------------------------------------- validation
def _as_array(a, name: str, last_shape: tuple, *, finite: bool = True) -> np.ndarray:
    try:
        arr = np.asarray(a, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a numeric array with trailing shape {last_shape}, got {a!r}") from exc
    n = len(last_shape)
    if arr.ndim < n or arr.shape[arr.ndim - n:] != last_shape:
        raise ValueError(f"{name} must have trailing shape {last_shape}, got shape {arr.shape}")
    if finite and not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite (no NaN/inf)")
    return arr


def _check_covariance(C: np.ndarray, name: str) -> None:
    if not np.allclose(C, np.swapaxes(C, -1, -2), rtol=1e-9, atol=1e-9 * max(1.0, float(np.max(np.abs(C))))):
        raise ValueError(f"{name} must be symmetric")
    try:
        np.linalg.cholesky(C)
    except np.linalg.LinAlgError as exc:
        raise ValueError(f"{name} must be positive definite") from exc


def _symmetrize(P: np.ndarray) -> np.ndarray:
    return 0.5 * (P + np.swapaxes(P, -1, -2))


# ------------------------------------------------------------------------------------------------- model
def cv_model(dt, sigma_a):
    """Transition matrix F and process-noise covariance Q of the CV model (Tengesdal, Brekke & Johansen 2020, eqs.
    (5), (7)).

    Args:
        dt: sampling interval [s], > 0.
        sigma_a: process-noise strength [m/s²], >= 0.

    Returns:
        ``(F [4, 4], Q [4, 4])``.
    """
    dt = positive(dt, "dt")
    sigma_a = positive(sigma_a, "sigma_a", allow_zero=True)
    F = np.eye(4)
    F[0, 2] = F[1, 3] = dt
    q = sigma_a ** 2
    a, b, c = q * dt ** 3 / 3.0, q * dt ** 2 / 2.0, q * dt
    Q = np.array([[a, 0.0, b, 0.0], [0.0, a, 0.0, b], [b, 0.0, c, 0.0], [0.0, b, 0.0, c]])
    return F, Q


def initiate(z, R, U_max, kappa=DEFAULT_KAPPA):
    """Single-point track initiation (Mallick & Scala 2008; Tengesdal, Brekke & Johansen 2020, Sec. 7).

    Position = the measurement, velocity = 0, ``P = blockdiag(R, (U_max / kappa)² I2)``.

    Args:
        z: ``[..., 2]`` first position measurement (north, east) [m].
        R: ``[2, 2]`` or ``[..., 2, 2]`` measurement covariance of the filter [m²], symmetric positive definite.
        U_max: maximum target speed [m/s], > 0 (assumed known a priori).
        kappa: how many standard deviations U_max spans per velocity component, > 0. U_max = 9 m/s, kappa = 2
            gives a velocity variance of 20.25 (m/s)² (the paper: "surpassing 20 (m/s)² initially").

    Returns:
        ``(x [..., 4], P [..., 4, 4])``.
    """
    z = _as_array(z, "z", (2,))
    R = _as_array(R, "R", (2, 2))
    _check_covariance(R, "R")
    U_max = positive(U_max, "U_max")
    kappa = positive(kappa, "kappa")
    batch = np.broadcast_shapes(z.shape[:-1], R.shape[:-2])
    x = np.zeros(batch + (4,))
    x[..., :2] = z
    P = np.zeros(batch + (4, 4))
    P[..., :2, :2] = R
    P[..., 2, 2] = P[..., 3, 3] = (U_max / kappa) ** 2
    return x, P


def predict(x, P, dt, sigma_a):
    """Kalman prediction over ``dt`` seconds: ``x <- F x``, ``P <- F P Fᵀ + Q``.

    Args:
        x: ``[..., 4]`` state estimates; P: ``[..., 4, 4]`` covariances.
        dt: [s] > 0; sigma_a: [m/s²] >= 0.

    Returns:
        ``(x [..., 4], P [..., 4, 4])`` (new arrays).
    """
    x = _as_array(x, "x", (4,), finite=False)
    P = _as_array(P, "P", (4, 4), finite=False)
    F, Q = cv_model(dt, sigma_a)
    x_new = x @ F.T
    P_new = _symmetrize(F @ P @ F.T + Q)
    return x_new, P_new


def update(x, P, z, R, mask=None):
    """Kalman measurement update with H = [I2 0] and the Joseph-form covariance.

    ``S = H P Hᵀ + R``, ``K = P Hᵀ S⁻¹``, ``x <- x + K ν`` with innovation ``ν = z - H x``,
    ``P <- (I - K H) P (I - K H)ᵀ + K R Kᵀ`` (symmetrised), and the normalised innovation squared
    ``nis = νᵀ S⁻¹ ν`` (chi-square with 2 degrees of freedom for a consistent filter).

    Args:
        x: ``[..., 4]``; P: ``[..., 4, 4]``; z: ``[..., 2]`` position measurements [m].
        R: ``[2, 2]`` or ``[..., 2, 2]`` filter measurement covariance [m²] (symmetric positive definite).
        mask: optional ``[...]`` bool, True where a measurement is available. Where False, x and P come back
            unchanged and nis is NaN (z may then hold anything, NaN included).

    Returns:
        ``(x [..., 4], P [..., 4, 4], nis [...])``.
    """
    x = _as_array(x, "x", (4,), finite=False)
    P = _as_array(P, "P", (4, 4), finite=False)
    z = _as_array(z, "z", (2,), finite=False)
    R = _as_array(R, "R", (2, 2))
    _check_covariance(R, "R")
    batch = np.broadcast_shapes(x.shape[:-1], P.shape[:-2], z.shape[:-1], R.shape[:-2])
    if mask is None:
        m = np.ones(batch, dtype=bool)
    else:
        m = np.asarray(mask)
        if m.dtype != bool:
            raise ValueError(f"mask must be a boolean array, got dtype {m.dtype}")
        try:
            batch = np.broadcast_shapes(batch, m.shape)
        except ValueError as exc:
            raise ValueError(f"mask shape {m.shape} does not broadcast with the batch shape {batch}") from exc
        m = np.broadcast_to(m, batch)
    x = np.broadcast_to(x, batch + (4,))
    P = np.broadcast_to(P, batch + (4, 4))
    z = np.broadcast_to(z, batch + (2,))
    if not np.all(np.isfinite(z[m])):
        raise ValueError("z must be finite wherever mask is True")
    # Harmless stand-ins where there is no measurement, so neither NaN nor a singular S can arise there.
    xs = np.where(m[..., None], x, 0.0)
    Ps = np.where(m[..., None, None], P, np.eye(4))
    zs = np.where(m[..., None], z, 0.0)

    nu = zs - xs[..., :2]                                      # [..., 2]
    S = Ps[..., :2, :2] + R                                    # [..., 2, 2]
    S_inv = np.linalg.inv(S)
    K = Ps[..., :, :2] @ S_inv                                 # [..., 4, 2] = P Hᵀ S⁻¹
    x_upd = xs + np.einsum("...ij,...j->...i", K, nu)
    IKH = np.eye(4) - K @ H                                    # [..., 4, 4]
    P_upd = _symmetrize(IKH @ Ps @ np.swapaxes(IKH, -1, -2) + K @ R @ np.swapaxes(K, -1, -2))
    nis = np.einsum("...i,...ij,...j->...", nu, S_inv, nu)

    x_out = np.where(m[..., None], x_upd, x)
    P_out = np.where(m[..., None, None], P_upd, P)
    nis = np.where(m, nis, np.nan)
    return x_out, P_out, nis


def nees(x_true, x, P):
    """Normalised estimation error squared ``(x_true - x)ᵀ P⁻¹ (x_true - x)``, shape ``[...]``.

    For a consistent filter it is chi-square distributed with 4 degrees of freedom (mean 4); a value well below
    4 on average means a conservative (pessimistic) filter, well above 4 an overconfident one.
    """
    x_true = _as_array(x_true, "x_true", (4,))
    x = _as_array(x, "x", (4,))
    P = _as_array(P, "P", (4, 4))
    e = x_true - x
    sol = np.linalg.solve(P, e[..., None])[..., 0]
    return np.einsum("...i,...i->...", e, sol)


# ------------------------------------------------------------------------------------------- tracker bank
class TrackerBank:
    """A batch of CV Kalman filters (one per target and run), for the closed-loop simulator.

    Tracks start un-initiated; ``x`` and ``P`` hold NaN there. ``measure`` initiates a track with its first
    measurement (single-point initiation) and updates the tracks that already exist; ``step`` predicts every
    initiated track over ``dt`` seconds.

    Args:
        n_batch_shape: batch shape of the bank, e.g. ``(runs, targets)``; a bare int is taken as ``(n,)``.
        R_filter: ``[2, 2]`` measurement covariance *used by the filter* [m²] (the paper's conservative
            tuning: 25 × the true R).
        sigma_a: process-noise strength [m/s²] (Tengesdal, Brekke & Johansen 2020: 0.5).
        U_max: maximum target speed for initiation [m/s].
        kappa: see :func:`initiate`.

    Attributes:
        x: ``[*batch, 4]`` estimates; P: ``[*batch, 4, 4]`` covariances; initiated: ``[*batch]`` bool.
    """

    def __init__(self, n_batch_shape, R_filter, sigma_a, U_max, kappa=DEFAULT_KAPPA):
        if isinstance(n_batch_shape, (int, np.integer)):
            n_batch_shape = (int(n_batch_shape),)
        try:
            shape = tuple(int(n) for n in n_batch_shape)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"n_batch_shape must be a tuple of non-negative ints, got {n_batch_shape!r}") from exc
        if any(n < 0 for n in shape) or any(int(n) != n for n in n_batch_shape):
            raise ValueError(f"n_batch_shape must be a tuple of non-negative ints, got {n_batch_shape!r}")
        R = _as_array(R_filter, "R_filter", (2, 2))
        if R.shape != (2, 2):
            raise ValueError(f"R_filter must have shape (2, 2), got {R.shape}")
        _check_covariance(R, "R_filter")
        self.batch_shape = shape
        self.R = R
        self.sigma_a = positive(sigma_a, "sigma_a", allow_zero=True)
        self.U_max = positive(U_max, "U_max")
        self.kappa = positive(kappa, "kappa")
        self.initiated = np.zeros(shape, dtype=bool)
        self.x = np.full(shape + (4,), np.nan)
        self.P = np.full(shape + (4, 4), np.nan)

    def step(self, dt):
        """Predict every initiated track over ``dt`` seconds (> 0)."""
        dt = positive(dt, "dt")
        sel = self.initiated
        if np.any(sel):
            self.x[sel], self.P[sel] = predict(self.x[sel], self.P[sel], dt, self.sigma_a)

    def measure(self, z, mask=None):
        """Feed position measurements ``z [*batch, 2]`` (where ``mask [*batch]`` is True; default: all).

        Un-initiated tracks are initiated from their measurement; initiated ones get a Kalman update.

        Returns:
            nis ``[*batch]``: normalised innovation squared of the updated tracks, NaN elsewhere (no
            measurement, or a track initiated by this measurement).
        """
        z = _as_array(z, "z", (2,), finite=False)
        if z.shape != self.batch_shape + (2,):
            raise ValueError(f"z must have shape {self.batch_shape + (2,)}, got {z.shape}")
        if mask is None:
            m = np.ones(self.batch_shape, dtype=bool)
        else:
            m = np.asarray(mask)
            if m.dtype != bool or m.shape != self.batch_shape:
                raise ValueError(f"mask must be a bool array of shape {self.batch_shape}, got {m.dtype} {m.shape}")
        if not np.all(np.isfinite(z[m])):
            raise ValueError("z must be finite wherever mask is True")
        nis = np.full(self.batch_shape, np.nan)
        upd = m & self.initiated
        if np.any(upd):
            self.x[upd], self.P[upd], nis[upd] = update(self.x[upd], self.P[upd], z[upd], self.R)
        new = m & ~self.initiated
        if np.any(new):
            self.x[new], self.P[new] = initiate(z[new], self.R, self.U_max, self.kappa)
            self.initiated = self.initiated | new
        return nis
