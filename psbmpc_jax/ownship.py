"""Kinematic model + LOS path following (Tengesdal et al. 2022, eqs. 3–6 and 19; docs/algorithm.md §2-4), as
``lax.scan`` rollouts.

The same follower predicts the own-ship under every control behaviour (kernel 1) and every obstacle
prediction scenario.  Rows are independent: axis R is B behaviours for the own-ship, O*S for obstacles.
Trajectories are returned time-major, as a :class:`Trajectory` of component arrays ``[N+1, R]``
(structure of arrays: the collision kernel reads x, y, vx, vy separately, and reduces over time along the
leading axis).
"""

from __future__ import annotations

import concurrent.futures
import logging
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .numerics import wrap_angle
from .rollout_kernel import los_rollout_kernel

log = logging.getLogger(__name__)


class Path(NamedTuple):
    """Padded polylines, one per row: waypoints ``wx, wy [R, W]``, counts ``n [R]`` (>= 2).

    ``alpha, ca, sa, seg_len [R, W-1]`` are the segment angles, their cos/sin and lengths (padding
    segments hold zeros and are never selected)."""

    wx: jax.Array
    wy: jax.Array
    n: jax.Array
    alpha: jax.Array
    ca: jax.Array
    sa: jax.Array
    seg_len: jax.Array


class Trajectory(NamedTuple):
    """Predicted states, each time-major ``[N+1, R]``: position x, y, course chi, speed U, and cos/sin of the course
    (computed by the rollout anyway; the collision and COLREGS kernels reuse them)."""

    x: jax.Array
    y: jax.Array
    chi: jax.Array
    U: jax.Array
    cos_chi: jax.Array
    sin_chi: jax.Array

    @property
    def vx(self):
        return self.U * self.cos_chi

    @property
    def vy(self):
        return self.U * self.sin_chi


def make_path(wx, wy, n) -> Path:
    """Segment data for padded waypoints ``wx, wy [R, W]`` with ``n [R]`` valid points each."""
    dx, dy = jnp.diff(wx, axis=-1), jnp.diff(wy, axis=-1)
    valid = jnp.arange(wx.shape[-1] - 1) < (n[..., None] - 1)
    dx, dy = jnp.where(valid, dx, 1.0), jnp.where(valid, dy, 0.0)
    alpha = jnp.arctan2(dy, dx)
    seg_len = jnp.sqrt(dx * dx + dy * dy)
    return Path(wx, wy, n, alpha, jnp.cos(alpha), jnp.sin(alpha), seg_len)


def _take(table, idx):
    """Per-row lookup ``table[r, idx[r]]``; a single shared row is a plain 1-D gather."""
    if table.shape[0] == 1:
        return jnp.take(table[0], idx, mode="clip")
    return jnp.take_along_axis(table, idx[:, None], axis=1)[:, 0]


def los_step(path: Path, z, x, y, lateral_offset, lookahead, R_a):
    """One step of the LOS law at position ``(x, y)`` on active segment ``z``: the waypoint switch (within R_a of
    the segment's end waypoint, or past the segment's end), then χ_los = α_z + atan(−(e − offset)/Δ) (α_z alone past
    the last waypoint).  Returns ``(z, zi, chi_los)``: the segment after the switch, its clipped table index and
    the LOS course.  :func:`los_rollout` steps it; the Smooth-SBMPC guidance frame evaluates it along a given
    trajectory, so both use the same arithmetic."""
    last_seg = path.n - 2

    def seg_geometry(z):
        zi = jnp.minimum(z, last_seg)
        return (_take(path.wx, zi), _take(path.wy, zi), _take(path.ca, zi), _take(path.sa, zi), zi)

    wzx, wzy, ca, sa, zi = seg_geometry(z)
    along = (x - wzx) * ca + (y - wzy) * sa
    nx, ny = _take(path.wx, zi + 1) - x, _take(path.wy, zi + 1) - y
    switch = (z <= last_seg) & ((nx * nx + ny * ny <= R_a * R_a) | (along >= _take(path.seg_len, zi)))
    z = z + switch.astype(z.dtype)
    wzx, wzy, ca, sa, zi = seg_geometry(z)
    e = -(x - wzx) * sa + (y - wzy) * ca
    chi_los = _take(path.alpha, zi) + jnp.where(z <= last_seg, jnp.arctan(-(e - lateral_offset) / lookahead), 0.0)
    return z, zi, chi_los


def los_rollout(x0, path: Path, chi_offsets, U_cmd, lateral_offset, lookahead, R_a, T_chi, T_U, dt,
                unroll: int = 1, z0=None, return_segment: bool = False, seg_speed=None, kernel: str = "scan"):
    """Roll the kinematic model with LOS guidance forward N steps for R rows.

    Args:
        x0: initial states ``[R, 4]`` (x, y, chi, U).
        path: per-row padded polylines.
        chi_offsets, U_cmd: per-step course offset and speed reference, ``[N, R]`` (time-major).
        lateral_offset: per-row lateral path offset ``[R]`` (positive = starboard).
        lookahead, R_a, T_chi, T_U, dt: scalars.
        z0: optional initial active segment per row ``[R]`` (int32; default 0, the first segment).
        return_segment: also return the active segment used at each emitted state, ``[N+1, R]`` (a
            closed loop that steps one state at a time carries it to the next call as ``z0``).
        seg_speed: optional per-row leg speeds ``[R, W]`` [m/s]: where the active leg's entry is >= 0 it replaces
            the speed reference (a shared plan's leg speeds; after the last waypoint the last leg's).
        kernel: ``"scan"`` (a ``lax.scan`` over the steps, ``unroll`` per loop step) or ``"pallas"``
            (:func:`psbmpc_jax.rollout_kernel.los_rollout_kernel`: one kernel, each row's rollout in registers;
            not with ``z0``).  The same states.

    Returns the :class:`Trajectory` (and the segments when ``return_segment``).
    """
    if kernel == "pallas":
        if z0 is not None:
            raise ValueError("los_rollout: kernel='pallas' starts every row on its first segment; z0 needs 'scan'")
        outs = los_rollout_kernel(x0, path, chi_offsets, U_cmd, lateral_offset, lookahead, R_a, T_chi, T_U, dt,
                                  seg_speed=seg_speed)
        return (Trajectory(*outs[:6]), outs[6]) if return_segment else Trajectory(*outs[:6])
    if kernel not in ("scan", "pallas"):
        raise ValueError(f"rollout kernel must be 'scan' or 'pallas', got {kernel!r}")
    n_rows = x0.shape[0]

    def step(carry, xs):
        x, y, chi, U, z = carry
        chi_off, u_ref = xs
        z, zi, chi_los = los_step(path, z, x, y, lateral_offset, lookahead, R_a)
        chi_cmd = chi_los + chi_off
        if seg_speed is not None:
            leg_u = _take(seg_speed, zi)
            u_ref = jnp.where(leg_u >= 0, leg_u, u_ref)
        c, s = jnp.cos(chi), jnp.sin(chi)
        x_new = x + dt * U * c
        y_new = y + dt * U * s
        chi_new = wrap_angle(chi + (dt / T_chi) * wrap_angle(chi_cmd - chi))
        U_new = U + (dt / T_U) * (u_ref - U)
        # emit the state *before* the update: N+1 steps give states 0..N without a concatenate
        return (x_new, y_new, chi_new, U_new, z), (x, y, chi, U, c, s, z)

    # the initial course is kept as given (not wrapped): +pi and -pi differ in the first Euler step's rounding
    z_init = jnp.zeros(n_rows, jnp.int32) if z0 is None else jnp.broadcast_to(jnp.asarray(z0, jnp.int32), (n_rows,))
    init = (x0[:, 0], x0[:, 1], x0[:, 2], x0[:, 3], z_init)
    xs = (jnp.concatenate([chi_offsets, chi_offsets[-1:]]), jnp.concatenate([U_cmd, U_cmd[-1:]]))
    _, outs = jax.lax.scan(step, init, xs, unroll=unroll)      # one extra (discarded) update at the end
    traj = Trajectory(*outs[:6])
    return (traj, outs[6]) if return_segment else traj


_AVAILABLE: dict[str, bool] = {}


def pallas_available(platform: str | None = None) -> bool:
    """Whether the compiled kernel runs on ``platform`` (default: JAX's default backend) and equals the scan on a
    small problem; checked once per process and platform.  False on the CPU (there it only interprets)."""
    platform = platform or jax.default_backend()
    if platform == "cpu":
        return False
    if platform not in _AVAILABLE:
        try:
            _AVAILABLE[platform] = _self_check()
        except Exception as exc:  # noqa: BLE001 - any lowering or runtime failure means: use the scan
            log.warning("Pallas rollout kernel unavailable on %s (%s: %s); using the lax.scan rollout", platform,
                        type(exc).__name__, str(exc).splitlines()[0] if str(exc) else "")
            _AVAILABLE[platform] = False
    return _AVAILABLE[platform]


def _self_check(interpret: bool = False) -> bool:
    """The kernel against the scan on a small random problem, run in a thread of its own: the refinement resolves
    its layouts while tracing, and JAX's trace state is per thread, so there the two ``jit`` calls run eagerly
    instead of being staged into the caller's trace (where ``bool`` failed on a tracer and sent an H200 to the
    scan, 2026-11-29).  ``interpret``: Pallas's interpreter (the CPU tests)."""
    with concurrent.futures.ThreadPoolExecutor(max_workers=1) as pool:
        return pool.submit(_compare_kernel_and_scan, interpret).result()


def _compare_kernel_and_scan(interpret: bool) -> bool:
    rng = np.random.default_rng(0)
    n, rows = 40, 200
    x0 = jnp.asarray(np.c_[rng.normal(0, 5, (rows, 2)), rng.uniform(-math.pi, math.pi, rows),
                           rng.uniform(0.5, 3, rows)], jnp.float32)
    path = make_path(jnp.asarray([[0.0, 60.0, 90.0]], jnp.float32), jnp.asarray([[0.0, 10.0, 70.0]], jnp.float32),
                     jnp.asarray([3], jnp.int32))
    chi = jnp.asarray(rng.uniform(-1, 1, (n, rows)), jnp.float32)
    u = jnp.asarray(rng.uniform(0, 3, (n, rows)), jnp.float32)
    lat = jnp.zeros(rows, jnp.float32)
    args = (x0, path, chi, u, lat, 10.0, 5.0, 1.0, 2.0, 0.5)
    want = jax.jit(lambda *a: los_rollout(*a))(*args)
    got = jax.jit(lambda *a: los_rollout_kernel(*a, interpret=interpret))(*args)
    return all(bool(jnp.allclose(g, w_, rtol=1e-4, atol=1e-3)) for g, w_ in zip(got[:6], want))



def maneuver_index(n_steps: int, n_m: int, t_ts, dt):
    """Active maneuver per step ``[N]``: the largest M with k_M <= k, k_M = round(M t_ts / dt)."""
    k_m = jnp.round(jnp.arange(n_m) * t_ts / dt).astype(jnp.int32)
    k = jnp.arange(n_steps, dtype=jnp.int32)
    return jnp.sum(k[:, None] >= k_m[None, :], axis=1) - 1


def ownship_rollouts(own_state, path: Path, U_d, offsets, params, n_steps: int, dt, unroll: int = 1,
                     kernel: str = "scan"):
    """Own-ship trajectory under every behaviour (kernel 1, rollout part).

    Args:
        own_state: ``[4]``; path: a single-row :class:`Path` (``[1, W]``); U_d: nominal speed;
        offsets: behaviour table ``[B, n_M, 2]``; params: :class:`~psbmpc_jax.params.Params`.
    """
    n_b, n_m = offsets.shape[0], offsets.shape[1]
    t_ts = jnp.where(jnp.isnan(params.t_ts), n_steps * dt / n_m, params.t_ts)
    m_of_k = maneuver_index(n_steps, n_m, t_ts, dt)                       # [N]
    chi_off = offsets[:, :, 1].T[m_of_k]                                   # [N, B]
    u_ref = U_d * offsets[:, :, 0].T[m_of_k]                               # [N, B]
    x0 = jnp.broadcast_to(own_state, (n_b, 4))
    zeros = jnp.zeros((n_b,), own_state.dtype)
    return los_rollout(x0, path, chi_off, u_ref, zeros, params.os_lookahead, params.os_R_a,
                       params.os_T_chi, params.os_T_U, dt, unroll=unroll, kernel=kernel)
