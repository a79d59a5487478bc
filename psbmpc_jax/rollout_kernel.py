"""The LOS rollout as one Pallas kernel: each row's whole rollout in registers, one launch for all rows.

:func:`psbmpc_jax.ownship.los_rollout` is a ``lax.scan`` over the N + 1 time steps.  On a GPU every step of a scan
is at least one kernel launch and a synchronisation: two rollouts of 301 steps set a floor of a few milliseconds
per solve whatever the number of rows (``psbmpc-jax bench --depth``).  Unrolling the scan does not help: XLA fuses
the unrolled recurrence into fusions that recompute earlier steps (:mod:`psbmpc_jax.layouts`).  The paper's CUDA
code gives each thread one row's sequential rollout instead, and so does this kernel: a grid of programs over
blocks of :data:`ROWS` rows, each looping over the time steps with the row states in registers and writing every
step's state to the output.

The arithmetic is :func:`~psbmpc_jax.ownship.los_rollout`'s, step for step (same switch test, guidance, Euler
update and wraps); the per-row path lookups are masked sums over the padded waypoint axis instead of gathers.
On the CPU the kernel runs in Pallas's interpreter (for tests: ``tests/test_rollout_kernel.py`` compares it with
the scan in float64).  :func:`psbmpc_jax.ownship.pallas_available` compiles and checks it once per process on an
accelerator;
``PlannerConfig.rollout_kernel="auto"`` uses it on a GPU only where that check passed.
"""

from __future__ import annotations

import functools
from typing import Annotated, Any

import jax
import jax.numpy as jnp

from .array_types import Shape
from .numerics import wrap_angle
from .packing import bucket

#: Rows per program (a power of two, as Triton's blocks must be).
ROWS = 128


def _pick(table, idx, width: int):
    """``table[row, idx[row]]`` for a ``[rows or 1, width]`` table: a masked sum (no gather)."""
    lanes = jax.lax.broadcasted_iota(jnp.int32, (1, width), 1)
    return jnp.sum(jnp.where(idx[:, None] == lanes, table, jnp.zeros((), table.dtype)), axis=1)


def _kernel(sc_ref, x0_ref, tab_ref, seg_ref, ci_ref, ui_ref, lat_ref, lim_ref, *out_refs, n_out: int, wp: int,
            has_speed: bool):
    """One block of rows.  ``sc_ref [1, 8]``: lookahead, R_a, T_chi, T_U, dt; ``x0_ref [4, ROWS]``;
    ``tab_ref [6, rows or 1, wp]``: wx, wy, alpha, ca, sa, seg_len; ``seg_ref [rows or 1, wp]``: leg speeds (< 0:
    none); ``ci_ref, ui_ref [Tp, ROWS]``: course offsets and speed references; ``lat_ref [1, ROWS]``;
    ``lim_ref [1, rows or 1]``: the last segment index n - 2."""
    sc = sc_ref[...]
    lanes8 = jax.lax.broadcasted_iota(jnp.int32, sc.shape, 1)
    scalar = lambda i: jnp.sum(jnp.where(lanes8 == i, sc, jnp.zeros((), sc.dtype)))  # noqa: E731
    lookahead, r_a, t_chi, t_u, dt = (scalar(i) for i in range(5))
    wx, wy, alpha, ca, sa, seg_len = (tab_ref[i] for i in range(6))
    speeds = seg_ref[...]
    lat = lat_ref[0, :]
    last_seg = jnp.broadcast_to(lim_ref[0, :], lat.shape)

    def seg_geometry(z):
        zi = jnp.minimum(z, last_seg)
        return _pick(wx, zi, wp), _pick(wy, zi, wp), _pick(ca, zi, wp), _pick(sa, zi, wp), zi

    def step(k, carry):
        x, y, chi, u, z = carry
        chi_off, u_ref = ci_ref[k, :], ui_ref[k, :]
        wzx, wzy, c_a, s_a, zi = seg_geometry(z)
        along = (x - wzx) * c_a + (y - wzy) * s_a
        nx, ny = _pick(wx, zi + 1, wp) - x, _pick(wy, zi + 1, wp) - y
        switch = (z <= last_seg) & ((nx * nx + ny * ny <= r_a * r_a) | (along >= _pick(seg_len, zi, wp)))
        z = z + switch.astype(z.dtype)
        wzx, wzy, c_a, s_a, zi = seg_geometry(z)
        e = -(x - wzx) * s_a + (y - wzy) * c_a
        chi_los = _pick(alpha, zi, wp) + jnp.where(z <= last_seg, jnp.arctan(-(e - lat) / lookahead), 0.0)
        chi_cmd = chi_los + chi_off
        if has_speed:
            leg_u = _pick(speeds, zi, wp)
            u_ref = jnp.where(leg_u >= 0, leg_u, u_ref)
        c, s = jnp.cos(chi), jnp.sin(chi)
        for ref, v in zip(out_refs, (x, y, chi, u, c, s)):
            ref[k, :] = v
        out_refs[6][k, :] = z
        return (x + dt * u * c, y + dt * u * s, wrap_angle(chi + (dt / t_chi) * wrap_angle(chi_cmd - chi)),
                u + (dt / t_u) * (u_ref - u), z)

    # rows of refs, never slices of loaded values (Triton's lowering has no slice)
    init = (x0_ref[0, :], x0_ref[1, :], x0_ref[2, :], x0_ref[3, :], jnp.zeros(lat.shape, jnp.int32))
    jax.lax.fori_loop(0, n_out, step, init)


def los_rollout_kernel(x0: Annotated[jax.Array, Shape("R 4")], path,
                       chi_offsets: Annotated[jax.Array, Shape("N R")], U_cmd: Annotated[jax.Array, Shape("N R")],
                       lateral_offset: Annotated[Any, Shape("R")], lookahead, R_a, T_chi, T_U, dt, *,
                       seg_speed: Annotated[Any, Shape("R W")] = None,
                       interpret: bool | None = None) -> tuple[Annotated[jax.Array, Shape("T R")], ...]:
    """:func:`psbmpc_jax.ownship.los_rollout` (``z0`` None) as one Pallas kernel: returns the time-major components
    ``(x, y, chi, U, cos chi, sin chi)`` and the active segments, each ``[T, R]`` with T = N + 1 (the initial
    state and one per step; ``path``: per-row padded polylines of ``W`` waypoints, or one shared by every row).
    ``interpret`` None: Pallas's interpreter on the CPU, the compiled kernel elsewhere."""
    from jax.experimental import pallas as pl

    if interpret is None:
        interpret = jax.default_backend() == "cpu"
    dtype = x0.dtype
    n_rows = x0.shape[0]
    n_out = chi_offsets.shape[0] + 1
    rp = -(-n_rows // ROWS) * ROWS
    tp = bucket(n_out)
    w = path.wx.shape[1]
    wp = bucket(w, 2)
    shared = path.wx.shape[0] == 1 and n_rows != 1
    path_rows = 1 if shared else rp

    def rows(a, fill=0.0):                                   # [..., R] -> [..., rp]
        return jnp.pad(a, [(0, 0)] * (a.ndim - 1) + [(0, rp - n_rows)], constant_values=fill)

    def table(a):                                            # [R or 1, W or W-1] -> [path_rows, wp]
        a = jnp.pad(a, ((0, 0), (0, wp - a.shape[1])))
        return a if shared else jnp.pad(a, ((0, path_rows - a.shape[0]), (0, 0)))

    xs_c = jnp.concatenate([chi_offsets, chi_offsets[-1:]])
    xs_u = jnp.concatenate([U_cmd, U_cmd[-1:]])
    time = lambda a: jnp.pad(rows(a), ((0, tp - n_out), (0, 0)))   # noqa: E731
    tabs = jnp.stack([table(a.astype(dtype)) for a in (path.wx, path.wy, path.alpha, path.ca, path.sa,
                                                          path.seg_len)])
    speeds = table(jnp.full_like(path.wx, -1.0) if seg_speed is None else seg_speed.astype(dtype))
    lim = (path.n - 2).astype(jnp.int32)[None, :]
    lim = lim if shared else jnp.pad(lim, ((0, 0), (0, path_rows - lim.shape[1])))
    sc = jnp.zeros((1, 8), dtype).at[0, :5].set(jnp.stack([jnp.asarray(v, dtype) for v in (lookahead, R_a, T_chi,
                                                                                           T_U, dt)]))
    lat = rows(jnp.broadcast_to(jnp.asarray(lateral_offset, dtype), (n_rows,))[None, :])
    x0t = rows(x0.T)
    block = lambda i: (0, i)  # noqa: E731
    path_block = (lambda i: (0, 0, 0)) if shared else (lambda i: (0, i, 0))
    in_specs = [pl.BlockSpec((1, 8), lambda i: (0, 0)), pl.BlockSpec((4, ROWS), block),
                pl.BlockSpec((6, 1 if shared else ROWS, wp), path_block),
                pl.BlockSpec((1 if shared else ROWS, wp), (lambda i: (0, 0)) if shared else (lambda i: (i, 0))),
                pl.BlockSpec((tp, ROWS), block), pl.BlockSpec((tp, ROWS), block), pl.BlockSpec((1, ROWS), block),
                pl.BlockSpec((1, 1 if shared else ROWS), (lambda i: (0, 0)) if shared else block)]
    out_shape = [jax.ShapeDtypeStruct((tp, rp), dtype)] * 6 + [jax.ShapeDtypeStruct((tp, rp), jnp.int32)]
    outs = pl.pallas_call(
        functools.partial(_kernel, n_out=n_out, wp=wp, has_speed=seg_speed is not None),
        out_shape=out_shape, grid=(rp // ROWS,), in_specs=in_specs,
        out_specs=[pl.BlockSpec((tp, ROWS), block)] * 7, interpret=interpret,
    )(sc, x0t, tabs, speeds, time(xs_c), time(xs_u), lat, lim)
    return tuple(o[:n_out, :n_rows] for o in outs)


__all__ = ["ROWS", "los_rollout_kernel"]
