"""Manoeuvre detection: when a vessel changed course or speed (``docs/evaltool.md``, "Pipeline" step 2; the tool's own
``VesselData`` event detector, [LIN]).

Course (unwrapped) and speed are smoothed with a Gaussian filter (σ in samples), differentiated by central
differences (per second, so the thresholds keep their units whatever the sample interval), and thresholded:

* a **course manoeuvre** starts at the first sample with |χ'| >= ε_dχ and U >= ε_U while none is running, and
  ends when the turn rate changes sign, is exactly 0 on two samples, U drops below ε_U, or (option
  ``course_end_below_threshold``, [REC]) |χ'| falls below ε_dχ;
* a **speed manoeuvre** is a run of samples with |U'| >= ε_dU of one sign.

Each manoeuvre carries its net change (Δχ = Σχ'·Δt, ΔU = ΣU'·Δt over [start, end)).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .params import EvalParams

__all__ = ["Maneuver", "gaussian_smooth", "smoothed_rates", "detect_maneuvers"]


@dataclass(frozen=True)
class Maneuver:
    """One detected manoeuvre of one vessel.

    Attributes:
        kind: ``"course"`` or ``"speed"``.
        start, end: sample indices, ``[start, end)`` on the evaluation grid (end > start).
        delta_course: net course change over the manoeuvre [rad] (starboard positive).
        delta_speed: net speed change over the manoeuvre [m/s].
    """

    kind: str
    start: int
    end: int
    delta_course: float
    delta_speed: float

    def overlaps(self, lo: int, hi: int) -> bool:
        """True if the manoeuvre shares a sample with the inclusive index range [lo, hi]."""
        return self.start <= hi and self.end > lo

    def to_dict(self, t: np.ndarray | None = None) -> dict:
        d = {"kind": self.kind, "start": int(self.start), "end": int(self.end),
             "delta_course_deg": math.degrees(self.delta_course), "delta_speed_mps": float(self.delta_speed)}
        if t is not None:
            d["t_start_s"] = float(t[self.start])
            d["t_end_s"] = float(t[min(self.end, t.size - 1)])
        return d


def gaussian_smooth(x, sigma: float, truncate: float = 4.0) -> np.ndarray:
    """Gaussian filter of a 1-D signal with σ in samples, half-sample symmetric ("reflect") padding and the
    kernel truncated at ``truncate``·σ (the same as ``scipy.ndimage.gaussian_filter1d``'s defaults).
    σ = 0 returns a copy."""
    x = np.asarray(x, float)
    if sigma <= 0:
        return x.copy()
    radius = int(truncate * sigma + 0.5)
    k = np.arange(-radius, radius + 1)
    w = np.exp(-0.5 * (k / sigma) ** 2)
    w /= w.sum()
    padded = np.pad(x, radius, mode="symmetric")
    while padded.size < x.size + 2 * radius:           # signal shorter than the kernel: keep reflecting
        padded = np.pad(padded, radius, mode="symmetric")
    off = (padded.size - x.size - 2 * radius) // 2
    padded = padded[off:off + x.size + 2 * radius]
    return np.convolve(padded, w[::-1], mode="valid")


def smoothed_rates(course, speed, dt: float, sigma: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(smoothed speed, course rate χ' [rad/s], acceleration U' [m/s²]) of one vessel on a uniform grid."""
    chi = gaussian_smooth(np.unwrap(np.asarray(course, float)), sigma)
    u = gaussian_smooth(np.asarray(speed, float), sigma)
    if chi.size < 2:
        return u, np.zeros_like(chi), np.zeros_like(u)
    return u, np.gradient(chi, dt), np.gradient(u, dt)


def _course_maneuvers(rate, u, dt: float, p: EvalParams) -> list[Maneuver]:
    eps, eps_u = math.radians(p.epsilon_d_course_deg_s), p.epsilon_speed_mps
    out, k, n = [], 0, rate.size
    while k < n:
        if abs(rate[k]) >= eps and u[k] >= eps_u:
            start, sign = k, np.sign(rate[k])
            k += 1
            while k < n and not _course_ends(rate, u, k, sign, eps, eps_u, p.course_end_below_threshold):
                k += 1
            out.append(Maneuver("course", start, k, float(rate[start:k].sum() * dt), 0.0))
        else:
            k += 1
    return out


def _course_ends(rate, u, k: int, sign: float, eps: float, eps_u: float, below: bool) -> bool:
    """End test of a running course manoeuvre at sample k."""
    return bool(np.sign(rate[k]) == -sign or (rate[k] == 0 and rate[k - 1] == 0) or u[k] < eps_u
                or (below and abs(rate[k]) < eps))


def _speed_maneuvers(accel, dt: float, p: EvalParams) -> list[Maneuver]:
    sign = np.where(np.abs(accel) >= p.epsilon_d_speed_mps2, np.sign(accel), 0).astype(int)
    change = np.flatnonzero(np.diff(np.concatenate([[0], sign, [0]])) != 0)   # run boundaries
    out = []
    for a, b in zip(change[:-1], change[1:]):
        if sign[a] != 0:
            out.append(Maneuver("speed", int(a), int(b), 0.0, float(accel[a:b].sum() * dt)))
    return out


def detect_maneuvers(course, speed, dt: float, p: EvalParams) -> list[Maneuver]:
    """Course and speed manoeuvres of one vessel on a uniform grid of step ``dt``, merged and sorted by start
    (course first on a tie)."""
    u, rate, accel = smoothed_rates(course, speed, dt, p.smoothing_sigma_samples)
    found = _course_maneuvers(rate, u, dt, p) + _speed_maneuvers(accel, dt, p)
    return sorted(found, key=lambda m: (m.start, m.kind != "course"))
