"""Every polygon's edges in one dense, masked pass: the loop-free layout of the exact grounding search.

The culled search (:func:`psbmpc_jax.geometry.polygon_argmax`) and the dense one
(:func:`psbmpc_jax.geometry.dense_argmax`) visit the polygons one at a time (a ``scan``) and their edges in loop
steps (``fori_loop``): hundreds of short, sequential steps.  On a GPU each loop step is at least one kernel launch
and a synchronisation, so those searches cost a floor of milliseconds whatever the work.  This layout has no loop
at all (at the sizes of the paper's figures; very large point sets are split into a few column chunks):

* the chart's edges are cut into **blocks** of :data:`BLOCK_EDGES` edge slots, each block inside one polygon
  (block k covers slots ``start[k] .. start[k] + 31`` of polygon ``poly[k]``; slots past the polygon's edge count
  are masked).  The host packs the blocks of the real polygons back to back (:func:`host_blocks`, stored in
  :attr:`psbmpc_jax.packing.ChartArrays.blocks`), so a chart of 13 polygons and 2 500 edges has about 90 blocks
  instead of 13 x (largest polygon / 32);
* every block is evaluated against every point at once (``[K, 32, points]``, reduced over its 32 edges inside
  one fusion): the smallest squared distance, the lane of that edge and the parity of the ray crossings;
* a segment reduction over the blocks of each polygon gives its distance, inside flag and nearest edge (the
  first block of equal distance, then the first lane: the first edge of equal distance, as the sequential
  searches).

The numbers are those of :func:`psbmpc_jax.geometry.polygon_distance` (same per-edge arithmetic, exact minima),
so the worst time step and the cost are the same as with the other searches.  It does far more arithmetic than
the culled search (every edge against every point): the GPU's layout, not the CPU's
(:func:`psbmpc_jax.layouts.resolve_search`).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from .geometry import edge_terms
from .numerics import safe_sqrt

#: Edge slots per block.
BLOCK_EDGES = 32
#: Largest ``blocks x points`` of one pass (2^27 elements, 512 MiB per float32 temporary); more points are split
#: into column chunks (a ``lax.map``, one loop step per chunk).
FLAT_STEP_ELEMENTS = 1 << 27


def host_blocks(n_edges, p_cap: int, v_cap: int, capacity: int | None = None) -> np.ndarray:
    """Blocks ``[K, 2]`` int32 (polygon, first slot) of polygons with ``n_edges`` edges each, back to back; padded
    to ``capacity`` blocks (default: a power of two >= 4) with blocks of polygon ``p_cap - 1`` (so the polygon
    column stays sorted) that start at ``v_cap`` (no valid slot)."""
    rows = [(j, s) for j, n in enumerate(n_edges) for s in range(0, int(n), BLOCK_EDGES)]
    k = len(rows)
    cap = max(4, 1 << max(k - 1, 0).bit_length()) if capacity is None else int(capacity)
    if cap < k:
        raise ValueError(f"edge block capacity {cap} is too small: the chart needs {k} blocks of {BLOCK_EDGES} edges")
    out = np.zeros((cap, 2), np.int32)
    out[:, 0], out[:, 1] = max(p_cap - 1, 0), v_cap
    if rows:
        out[:k] = np.asarray(rows, np.int32)
    return out


def padded_blocks(n_polygons: int, v_cap: int) -> np.ndarray:
    """The content-independent block layout: ``ceil(v_cap / 32)`` blocks for every polygon slot (the fallback
    when the chart carries no packed blocks; correct for any edge counts, more work)."""
    nb = -(-v_cap // BLOCK_EDGES)
    poly = np.repeat(np.arange(n_polygons, dtype=np.int32), nb)
    start = np.tile(np.arange(nb, dtype=np.int32) * BLOCK_EDGES, n_polygons)
    return np.stack([poly, start], axis=-1)


def _layout(tables, n, blocks):
    """Block rows ``[K, 32, 8]``, polygon ``[K]``, first slot ``[K]`` and lane validity ``[K, 32]``."""
    P, V = tables.shape[:2]
    n = jnp.asarray(n)
    blocks = jnp.asarray(padded_blocks(P, V) if blocks is None else blocks, jnp.int32)
    poly, start = blocks[:, 0], blocks[:, 1]
    slot = start[:, None] + jnp.arange(BLOCK_EDGES, dtype=jnp.int32)[None, :]
    valid = slot < n[poly][:, None]
    rows = tables[poly[:, None], jnp.minimum(slot, V - 1)]
    return rows, poly, start, valid


def _lane_reduce(a, b):
    """Combines two (squared distance, lane, crossing parity) partials: the smaller distance with the lower lane
    on ties (the first edge of equal distance, as the sequential searches), the parities xor-ed."""
    (ea, la, pa), (eb, lb, pb) = a, b
    take_b = (eb < ea) | ((eb == ea) & (lb < la))
    return jnp.where(take_b, eb, ea), jnp.where(take_b, lb, la), pa ^ pb


def _block_pass(px, py, rows, valid, track):
    """Points ``px, py [K or 1, *S]`` against every block: per block the smallest squared distance ``[K, *S]``,
    the lane of its (first) edge (when ``track``) and the crossing parity (int32 0/1).

    The 32 lanes are the minor-most axis and the three results come from one variadic reduction over it: on a GPU
    that is one row-reduction kernel that evaluates each edge once.  (With the lanes second and three separate
    reductions, XLA on an H200 evaluated the edges twice: a column reduction for the distance, 4.8 ms at fig5's
    1 014 behaviours, and the parity as a loop inside the segment scatter, 9.0 ms; profile in
    ``benchmarks/results/h200_20261129_floor/``.)"""
    K = rows.shape[0]
    lead = (K,) + (1,) * (px.ndim - 1) + (BLOCK_EDGES,)
    e = tuple(rows[:, :, c].reshape(lead) for c in range(8))
    _, _, e2, cross = edge_terms(px[..., None], py[..., None], e)
    v = valid.reshape(lead)
    e2 = jnp.where(v, e2, jnp.finfo(px.dtype).max)
    lane = lax.broadcasted_iota(jnp.int32, e2.shape, e2.ndim - 1)
    par = (cross & v).astype(jnp.int32)
    init = (jnp.asarray(jnp.inf, e2.dtype), jnp.int32(BLOCK_EDGES), jnp.int32(0))
    bmin, lane, par = lax.reduce((e2, lane, par), init, _lane_reduce, (e2.ndim - 1,))
    return bmin, (lane if track else None), par


def _segment_min_nonnegative(x, segments, num_segments: int):
    """``jax.ops.segment_min`` of non-negative floats (squared distances) through their bit patterns: for such
    floats the integer order of the bits is the float order, so the minimum is the same number, but a GPU takes an
    integer minimum with one atomic instruction where a float one needs a compare-and-swap loop (the float
    segment minimum was 0.59 ms of fig5's 1 014-behaviour solve on an H200).  Empty segments give +inf, as
    ``segment_min`` does."""
    itype = jnp.int32 if x.dtype == jnp.float32 else jnp.int64
    m = jax.ops.segment_min(lax.bitcast_convert_type(x, itype), segments, num_segments=num_segments,
                            indices_are_sorted=True)
    return jnp.where(m == jnp.iinfo(itype).max, jnp.inf, lax.bitcast_convert_type(m, x.dtype)).astype(x.dtype)


def nearest_edges(px, py, tables, n, blocks=None, *, track=True):
    """Per polygon, for points ``px, py`` of shape ``[1, *S]`` (shared by all polygons) or ``[P, *S]`` (one point
    set per polygon): the smallest squared edge distance ``d2 [P, *S]``, the even-odd inside flag and (``track``)
    the slot of the first nearest edge (else None).  Not differentiable (the caller recomputes the distance to the
    chosen edge).  ``tables [P, V, 8]``: :func:`psbmpc_jax.geometry.edge_table`; ``n [P]`` valid edges; ``blocks``:
    :func:`host_blocks` (None: :func:`padded_blocks`)."""
    px, py, tables = (lax.stop_gradient(a) for a in (px, py, tables))
    P = tables.shape[0]
    rows, poly, start, valid = _layout(tables, n, blocks)
    if px.shape[0] == P and P != 1:
        px, py = px[poly], py[poly]
    bmin, lane, par = _block_pass(px, py, rows, valid, track)
    seg = dict(num_segments=P, indices_are_sorted=True)
    d2 = _segment_min_nonnegative(bmin, poly, P)
    inside = (jax.ops.segment_sum(par, poly, **seg) & 1) == 1
    if not track:
        return d2, inside, None
    K = rows.shape[0]
    k = jnp.arange(K, dtype=jnp.int32).reshape((K,) + (1,) * (bmin.ndim - 1))
    first = jnp.minimum(jax.ops.segment_min(jnp.where(bmin == d2[poly], k, K), poly, **seg), K - 1)
    slot = start[first] + jnp.take_along_axis(lane, first, axis=0)
    return d2, inside, slot


def _edge_at(tables, slot):
    """The 8 edge columns of the edge at ``slot [P, *S]`` of each polygon (a tuple of ``[P, *S]``)."""
    P, V = tables.shape[:2]
    pidx = jnp.arange(P).reshape((P,) + (1,) * (slot.ndim - 1))
    r = tables[pidx, jnp.clip(slot, 0, V - 1)]
    return tuple(r[..., c] for c in range(8))


def flat_distance(qx, qy, tables, n, blocks=None):
    """Distance and nearest-boundary vector of one point set per polygon ``qx, qy [P, *S]``: ``d, ex, ey`` as
    :func:`psbmpc_jax.geometry.polygon_distance` (0 inside; reverse- and forward-differentiable w.r.t. the points:
    the nearest edge is found without gradients, the distance recomputed to it)."""
    d2, inside, slot = nearest_edges(qx, qy, tables, n, blocks)
    nn = jnp.asarray(n).reshape((-1,) + (1,) * (qx.ndim - 1))
    qvx, qvy, e2, _ = edge_terms(qx, qy, _edge_at(tables, slot))
    near = ~inside & (nn > 0)
    d = jnp.where(inside, 0.0, safe_sqrt(jnp.where(nn > 0, e2, d2)))
    return d, jnp.where(near, -qvx, 0.0), jnp.where(near, -qvy, 0.0)


def flat_argmax(px, py, tw, score, tables, n, blocks=None, with_direction=True):
    """For every polygon and column, the time index maximising ``score(d, ex, ey, w)`` over the points
    ``px, py [T, B]`` (time feature ``tw [T]``): ``[P, B]`` int32, the first of equal maxima (0 for a polygon with
    no edge), as :func:`psbmpc_jax.geometry.polygon_argmax`.  ``with_direction`` (may be traced): False if
    ``score`` ignores (ex, ey).  Not differentiable."""
    px, py, tw, tables = (lax.stop_gradient(a) for a in (px, py, tw, tables))
    n = jnp.asarray(n)
    T, B = px.shape
    P = tables.shape[0]
    if P == 0:
        return jnp.zeros((0, B), jnp.int32)
    K = (padded_blocks(*tables.shape[:2]) if blocks is None else blocks).shape[0]

    def columns(cx, cy):
        d2, inside, slot = nearest_edges(cx[None], cy[None], tables, n, blocks)      # [P, T, b]
        d = jnp.where(inside, 0.0, jnp.sqrt(d2))
        qvx, qvy, _, _ = edge_terms(cx[None], cy[None], _edge_at(tables, slot))
        keep = (~inside) & with_direction
        s = score(d, jnp.where(keep, -qvx, 0.0), jnp.where(keep, -qvy, 0.0), tw[None, :, None])
        return jnp.where((n > 0)[:, None], jnp.argmax(s, axis=1).astype(jnp.int32), 0)

    n_chunks = max(1, -(-(K * T * B) // FLAT_STEP_ELEMENTS))
    if n_chunks == 1:
        return columns(px, py)
    width = -(-B // n_chunks)
    pad = n_chunks * width - B
    padc = lambda a: jnp.pad(a, ((0, 0), (0, pad)), mode="edge").reshape(T, n_chunks, width).transpose(1, 0, 2)
    out = lax.map(lambda c: columns(*c), (padc(px), padc(py)))                        # [chunks, P, width]
    return out.transpose(1, 0, 2).reshape(P, n_chunks * width)[:, :B]


__all__ = ["BLOCK_EDGES", "FLAT_STEP_ELEMENTS", "host_blocks", "padded_blocks", "nearest_edges", "flat_distance",
           "flat_argmax"]
