"""The DOCP's guidance frame (χ_d of Smooth-SBMPC's MPC stage, Mahipala & Johansen 2024, Section VIII).

The paper takes the DOCP's desired course χ_d from LOS guidance toward the initialisation stage's point at
τ₀ + T_mpc (Ψ_N).  ``chi_d_mode="terminal_los"`` (the default) does that: the DOCP's reference is the straight
line from the ship's position at τ₀ through Ψ_N (:func:`line_path`), followed by the same LOS law as the route
(lookahead Δ), without waypoint switching (the line runs on past Ψ_N; the terminal condition ends the horizon
there).  ``"route_los"`` keeps the route's LOS inside the DOCP, as the initialisation stage uses.

Offsets are relative to a frame: the course command is χ_c = χ_d(x) + χ_m.  The init stage's offsets and the
applied offsets live in the route frame; :func:`to_frame` re-expresses a sequence of route-frame offsets in
another frame *along the trajectory it produces* (χ_m' = χ_m + χ_d^route(x_k) − χ_d^other(x_k), wrapped), so
the re-expressed sequence, rolled out in the other frame, gives the same commands and hence the same states
(Ψ is reproduced to rounding); :func:`from_frame` is the inverse, for the DOCP's result.

:func:`los_courses` evaluates the LOS law of :func:`psbmpc_jax.ownship.los_rollout` (waypoint switching
included) at given positions with the rollout's own step (:func:`psbmpc_jax.ownship.los_step`), so the courses
are the ones the rollout used.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from ..numerics import wrap_angle
from ..ownship import Path, los_step
from .init_stage import CHI_D_MODES

#: Length [m] of the DOCP's line reference beyond the ship (the line is followed without switching; its far end
#: only has to stay out of reach of the acceptance-radius and end-of-segment tests).
LINE_LENGTH = 1.0e6

#: A Ψ_N closer than this to the ship [m] gives no direction; the line then follows the ship's course.
MIN_LINE = 1.0e-6


def los_courses(path: Path, xy, z0, lookahead, R_a):
    """The LOS course ``[K]`` at positions ``xy [K, 2]`` visited in order, starting on segment ``z0`` of the
    single-row ``path``: at each position the waypoint switch, then χ_los = α_z + atan(−e/Δ) (α_z alone past the
    last waypoint), by :func:`psbmpc_jax.ownship.los_step`, the step :func:`psbmpc_jax.ownship.los_rollout`
    takes.  Also returns the segment used at each position ``[K]``."""
    zero = jnp.zeros((1,), xy.dtype)

    def step(z, p):
        z, _, chi = los_step(path, z, p[0:1], p[1:2], zero, lookahead, R_a)
        return z, (chi[0], z[0])

    _, (chi, seg) = jax.lax.scan(step, jnp.asarray(z0, jnp.int32).reshape(1), xy)
    return chi, seg


def line_path(p0, p_end, heading, width: int) -> Path:
    """The single-row :class:`~psbmpc_jax.ownship.Path` of the line from ``p0 [2]`` through ``p_end [2]``
    (``heading`` [rad] orients it when the two coincide), padded to ``width`` waypoints (the route's, so that it
    can replace the route path inside one compiled problem).  Its one segment is :data:`LINE_LENGTH` long: the
    LOS law follows the line without switching."""
    dtype = p0.dtype
    d = p_end - p0
    length = jnp.sqrt(jnp.sum(d * d))
    ok = length > MIN_LINE
    t = jnp.where(ok, d / jnp.where(ok, length, 1.0), jnp.stack([jnp.cos(heading), jnp.sin(heading)]).astype(dtype))
    alpha = jnp.arctan2(t[1], t[0])
    far = p0 + jnp.asarray(LINE_LENGTH, dtype) * t
    pts = jnp.concatenate([p0[None], jnp.broadcast_to(far, (width - 1, 2))])
    pad = lambda v: jnp.full((1, width - 1), v, dtype)                                     # noqa: E731
    return Path(pts[None, :, 0], pts[None, :, 1], jnp.asarray([2], jnp.int32), pad(alpha), pad(jnp.cos(alpha)),
                pad(jnp.sin(alpha)), pad(LINE_LENGTH))


def select_path(use_first, first: Path, second: Path) -> Path:
    """``first`` where ``use_first`` (a traced bool), else ``second`` (same shapes): one compiled problem for
    both frames."""
    return jax.tree.map(lambda a, b: jnp.where(use_first, a, b), first, second)


def reexpress(offsets, xy, route: Path, z_route, other: Path, z_other, lookahead, R_a):
    """Route-frame course offsets ``[K]`` applied at positions ``xy [K, 2]`` as offsets in the ``other`` frame:
    χ_m + wrap(χ_d^route − χ_d^other), both LOS courses evaluated along ``xy``."""
    chi_r, _ = los_courses(route, xy, z_route, lookahead, R_a)
    chi_o, _ = los_courses(other, xy, z_other, lookahead, R_a)
    return offsets + wrap_angle(chi_r - chi_o)


__all__ = ["CHI_D_MODES", "LINE_LENGTH", "MIN_LINE", "los_courses", "line_path", "select_path", "reexpress"]
