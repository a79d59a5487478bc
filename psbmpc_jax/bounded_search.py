"""The bounded grounding search: each polygon's worst time step from distance bounds and a few exact distances.

Axes: T time samples, B columns (behaviours), P polygons, V edge slots, C edge chunks of M slots, S time steps per
tile, nt tiles per column.

The culled search (:func:`psbmpc_jax.geometry.polygon_argmax`) evaluates every tile's live edges in lock step, so
the few tiles that pass close to a small island set the work of all of them.  For charts of a few small polygons
most of that work is not needed: the score ``g(d, t)`` falls by e^-1 every 4 m of distance (G3 = 0.25 /m), so only
a handful of tiles per column can hold the maximum.  This search finds them with bounds and proves it:

1. Per (polygon, tile of S steps): a lower bound of the distance of every point of the tile to the polygon's
   boundary (the gap between the tile's box and the nearest box of a chunk of M consecutive edges), 0 where the
   tile may be inside the polygon.  A tile whose box meets no chunk box holds no boundary point, so all of it is
   inside or all outside: the even-odd parity of the ray from its corner counts only chunks wholly to the right,
   from their odd-degree vertices (as the culled search does).  Upper bound of the tile's score:
   ``bound(lb, w_max)``.
2. Round 1, every (polygon, column): the exact distances (all edges, one loop step per chunk) and scores of the
   points of its K tiles of largest bound; the first of the largest scores.
3. Proven when that score is larger than every bound left out, or when it and every bound left out are 0 (the
   first time step, as the other searches).
4. Later rounds (:data:`ROUNDS`), only the unproven pairs, in blocks of an eighth of the round's capacity (a loop
   over as many blocks as hold them, none when every pair is proven): their next tiles by bound, the last round
   every time step of the column.  Pairs still unproven - non-monotone parameters (``bound`` = inf), more
   unproven pairs than a round holds, a chunk with too many odd-degree vertices - send the whole call to the
   culled search (``lax.cond``: on a CPU only the branch taken runs).

The same answer as the culled search (the first of equal maxima, the distances from the same edge terms); not
differentiated (an integer result).  Everything is elementwise, unrolled over chunks and tiles where XLA:CPU's
reductions over a short axis were several times slower.  The CPU choice for charts of at most
:data:`BOUNDED_MAX_CHUNKS` chunks (:func:`use_bounded`): on three islands of 176 vertices beside a route, the
grounding search went from +370 % to +63 % of the quadrature solve at 1 014 behaviours, and from +520 % to +170 %
at 7 098 (benchmarks/bench_cpu_targets.py, results/cpu_targets_cpu_20261129T030005Z.json).
"""

from __future__ import annotations

import jax.numpy as jnp
from jax import lax

from .geometry import edge_chunks, edge_terms, polygon_argmax, time_tiles

#: Time steps per tile and edge slots per chunk.
TILE, CHUNK = 8, 8
#: The rounds: (tiles evaluated, the share of (polygon, column) pairs that may need the round); None: every tile.
ROUNDS = ((3, 1.0), (6, 0.5), (None, 1 / 16))

#: Largest ``P * C`` (polygons x chunks of the longest) for which ``auto`` picks this search on a CPU.
BOUNDED_MAX_CHUNKS = 64


def use_bounded(edges) -> bool:
    """Whether the chart ``edges [P, V, 8]`` is small enough for the bounded search (static shapes)."""
    P, V = edges.shape[0], edges.shape[1]
    return 0 < P * (-(-V // CHUNK)) <= BOUNDED_MAX_CHUNKS


def _lower_bound(ch, xmin, xmax, ymin, ymax, tol):
    """Lower bound of the boundary distance of every point of the boxes (x/y min/max ``[..., P, B]``) to their
    polygon (``ch``: :class:`psbmpc_jax.geometry.EdgeChunks`, leading axis P): 0 where the box meets a chunk box or
    lies inside the polygon.  One pass per chunk (unrolled: XLA:CPU fuses it; a reduction over a chunk axis ran
    9x slower)."""
    g2, inside = None, None
    for c in range(ch.lo.shape[1]):
        lx, ly = ch.lo[:, c, 0, None], ch.lo[:, c, 1, None]                    # [P, 1]; invalid chunks: +inf
        hx, hy = ch.hi[:, c, 0, None], ch.hi[:, c, 1, None]
        dx = jnp.maximum(0.0, jnp.maximum(lx - xmax, xmin - hx))
        dy = jnp.maximum(0.0, jnp.maximum(ly - ymax, ymin - hy))
        oy = ch.odd_y[:, c, :, None]                                            # [P, 4, 1]
        odd = (oy[:, 0] > ymax) ^ (oy[:, 1] > ymax) ^ (oy[:, 2] > ymax) ^ (oy[:, 3] > ymax)
        cross = (lx > xmax) & odd                                               # wholly right of the corner
        g2 = dx * dx + dy * dy if g2 is None else jnp.minimum(g2, dx * dx + dy * dy)
        inside = cross if inside is None else inside ^ cross
    near = (g2 <= tol * tol) | inside
    return jnp.where(near, 0.0, jnp.maximum(jnp.sqrt(g2) - tol, 0.0))


def _first_max(values):
    """Index of the first largest of ``values [L, ...]`` along the leading axis and that value (unrolled
    comparisons: XLA:CPU's variadic argmax reduction is 4x slower at these sizes)."""
    best, idx = values[0], jnp.zeros(values.shape[1:], jnp.int32)
    for j in range(1, values.shape[0]):
        better = values[j] > best
        best, idx = jnp.where(better, values[j], best), jnp.where(better, j, idx)
    return idx, best


#: Most comparisons :func:`_keep` unrolls (``min(k, L) * L``); above it, ``lax.top_k``.  Unrolled, the program
#: grows as the square of the tiles per column: at 1 200 steps (T = 600 s, dt = 0.5 s: 150 tiles) compiling
#: one solve passed 21 GB and 15 min; the default 300 steps (38 tiles, 1 444 comparisons) stay unrolled.
KEEP_UNROLL_MAX = 2048


def _keep(values, k):
    """The ``k`` largest of ``values [L, ...]`` along the leading axis: their indices ``[k, ...]``, the largest
    value left out (-inf when none is) and ``values`` with the kept ones set to -inf."""
    L = values.shape[0]
    if min(k, L) * L > KEEP_UNROLL_MAX:
        return _keep_top_k(values, min(k, L))
    lead = jnp.arange(L).reshape((L,) + (1,) * (values.ndim - 1))
    idx = []
    for _ in range(min(k, L)):
        i, _ = _first_max(values)
        idx.append(i)
        values = jnp.where(lead == i, -jnp.inf, values)
    return jnp.stack(idx), jnp.max(values, axis=0), values


def _keep_top_k(values, k):
    """:func:`_keep` by ``lax.top_k`` (equal values: the lower index first, as the unrolled form).  Where fewer
    than ``k`` values are finite, the rest of the indices are those of -inf values (the unrolled form repeats
    index 0): such tiles were evaluated already or bound nothing, so the answer is the same."""
    L = values.shape[0]
    rest_shape = values.shape[1:]
    flat = jnp.moveaxis(values, 0, -1).reshape(-1, L)                          # [N, L]
    _, idx = lax.top_k(flat, k)                                                # [N, k]
    flat = flat.at[jnp.arange(flat.shape[0])[:, None], idx].set(-jnp.inf)
    idx = jnp.moveaxis(idx.reshape(rest_shape + (k,)), -1, 0).astype(jnp.int32)
    values = jnp.moveaxis(flat.reshape(rest_shape + (L,)), -1, 0)
    return idx, jnp.max(values, axis=0), values


def _exact(x, y, rows, n_chunks, with_direction, trailing=0):
    """Distance and nearest-boundary vector of the points ``x, y [..., Q]`` to polygon q's edges ``rows [Q, C+1,
    8, M]`` (:class:`psbmpc_jax.geometry.EdgeChunks` rows: null edges past the valid ones): ``d, ex, ey`` as
    :func:`psbmpc_jax.geometry.polygon_distance` (the first nearest edge in slot order), one loop step per
    chunk of M edges (unrolled inside), ``n_chunks`` steps.  ``trailing``: the axes of ``x`` after Q.  (One loop
    step per edge instead ran the later rounds 6x slower.)"""
    M = rows.shape[-1]
    lane = lambda a: a.reshape(a.shape + (1,) * trailing)

    def body(c, carry):
        d2, vx, vy, inside = carry
        r = lax.dynamic_index_in_dim(rows, c, axis=1, keepdims=False)          # [Q, 8, M]
        for m in range(M):
            ex, ey, e2, cross = edge_terms(x, y, tuple(lane(r[:, i, m]) for i in range(8)))
            closer = e2 < d2
            d2 = jnp.where(closer, e2, d2)
            if with_direction:
                vx, vy = jnp.where(closer, ex, vx), jnp.where(closer, ey, vy)
            inside = inside ^ cross
        return d2, vx, vy, inside

    zero = jnp.zeros(x.shape, x.dtype)
    init = (jnp.full(x.shape, jnp.finfo(x.dtype).max, x.dtype), zero, zero, jnp.zeros(x.shape, bool))
    d2, vx, vy, inside = lax.fori_loop(0, n_chunks, body, init)
    return jnp.where(inside, 0.0, jnp.sqrt(d2)), jnp.where(inside, 0.0, -vx), jnp.where(inside, 0.0, -vy)


def _best_step(s, t, T):
    """The largest score over the leading axis of ``s [L, ...]`` and the first time step ``t`` holding it."""
    best = jnp.max(s, axis=0)
    return best, jnp.min(jnp.where(s == best, t, T), axis=0).astype(jnp.int32)


def bounded_argmax(px, py, tw, score, bound, edges, nxt, n, with_direction=True, **sizes):
    """For every polygon and column, the time index maximising ``score(d, ex, ey, w)`` over the points
    ``px, py [T, B]``: ``[P, B]`` int32, as :func:`psbmpc_jax.geometry.polygon_argmax` (same arguments, which it
    falls back to where the bounds prove nothing; module docstring).  ``with_direction`` may be traced;
    ``sizes``: the keyword arguments of :func:`bounded_candidates`."""
    px, py, tw, edges = (lax.stop_gradient(a) for a in (px, py, tw, edges))
    if edges.shape[0] == 0:
        return jnp.zeros((0, px.shape[1]), jnp.int32)
    k, proven = bounded_candidates(px, py, tw, score, bound, edges, nxt, n, with_direction, **sizes)
    return lax.cond(jnp.all(proven), lambda: k, lambda: polygon_argmax(px, py, tw, score, bound, edges, nxt, n,
                                                                       with_direction))


def _proof(best, k, rest, empty):
    """The answer where proven (module docstring, step 4) and whether it is."""
    zero = (best == 0) & (rest <= 0)
    return jnp.where(empty | zero, 0, k), (best > rest) | zero | empty


def bounded_candidates(px, py, tw, score, bound, edges, nxt, n, with_direction=True, *, tile=TILE,
                       rounds=ROUNDS, chunk=CHUNK):
    """The bounded answer ``[P, B]`` int32 and whether it is proven for every (polygon, column) ``[P, B]`` bool
    (where it is not, the answer may be wrong).  ``rounds``: ``(tiles, share)`` per round (module docstring):
    every (polygon, column) in the first, the unproven ones after, at most ``share`` of them (``tiles`` None: all
    the column's tiles)."""
    T, B = px.shape
    P = edges.shape[0]
    tiles = time_tiles(px, py, tw, -(-T // -(-T // tile)))
    S = tiles.x.shape[1]
    nt = tiles.x.shape[0] // B
    ch, odd_overflow = edge_chunks(edges, nxt, n, chunk)
    valid_e = jnp.arange(edges.shape[1])[None, :] < n[:, None]
    scale = jnp.maximum(jnp.max(jnp.abs(jnp.where(valid_e[..., None], edges[..., :2], 0.0))),
                        jnp.maximum(jnp.max(jnp.abs(px)), jnp.max(jnp.abs(py))))
    tol = 64 * jnp.finfo(px.dtype).eps * (scale + 1.0)
    n_chunks = jnp.max(ch.n)
    empty = jnp.broadcast_to((n == 0)[:, None], (P, B))
    # the direction only where the score reads it (its two selects and carried arrays per edge slowed round 1 by
    # half): a traced switch, so each round's edge loop is in the program twice
    exact = lambda x, y, rows, trailing: lax.cond(
        with_direction, lambda: _exact(x, y, rows, n_chunks, True, trailing),
        lambda: _exact(x, y, rows, n_chunks, False, trailing))

    def points(keep, lead):
        """Time steps ``[K * S, ...]`` of the kept tiles ``keep [K, ...]`` and whether they are before T."""
        t = (keep[:, None] * S + jnp.arange(S).reshape((S,) + (1,) * (keep.ndim - 1))).reshape((-1,) + lead)
        return jnp.minimum(t, T - 1), t < T

    # round 1, every (polygon, column): tile bounds [nt, P, B], the exact scores of the best tiles' points
    by_tile = lambda a: a.reshape(B, nt).T[:, None, :]                           # [nt, 1, B]
    lb = _lower_bound(ch, *(by_tile(a) for a in (tiles.xmin, tiles.xmax, tiles.ymin, tiles.ymax)), tol)
    ub = bound(lb, by_tile(tiles.w_max))
    first, share = rounds[0]
    keep, rest, ub = _keep(ub, first)
    t, t_ok = points(keep, (P, B))
    cols = jnp.arange(B)
    d, ex, ey = exact(px[t, cols], py[t, cols], ch.rows, 1)
    best, k = _best_step(jnp.where(t_ok, score(d, ex, ey, tw[t]), -jnp.inf), t, T)
    k, proven = _proof(best, k, rest, empty)

    # later rounds, the unproven (polygon, column) pairs only, at most ``share`` of them, in blocks of an eighth of
    # that: a loop over as many blocks as hold them (none: the round is skipped), one copy of the round's program
    best, k, proven, ub = best.reshape(-1), k.reshape(-1), proven.reshape(-1), ub.reshape(nt, -1)
    empty = empty.reshape(-1)
    for more, share in rounds[1:]:
        cap = max(1, int(P * B * share))
        Q = max(1, cap // 8)
        n_blocks = -(-cap // Q)
        count = jnp.sum(~proven)
        order = jnp.nonzero(~proven, size=n_blocks * Q, fill_value=0)[0]

        def block(j, carry, *, more=more, Q=Q, order=order, count=count):
            best, k, proven, ub = carry
            q = lax.dynamic_slice_in_dim(order, j * Q, Q)
            kq, bq = k[q], best[q]
            if more is None:                        # every step of the column: nothing left out
                t = jnp.broadcast_to(jnp.arange(T)[:, None], (T, Q))
                t_ok, rest, ubq = jnp.ones((T, Q), bool), jnp.full((Q,), -jnp.inf, bq.dtype), None
            else:
                keep, rest, ubq = _keep(ub[:, q], more)
                t, t_ok = points(keep, (Q,))
            d, ex, ey = exact(px[t, q % B], py[t, q % B], ch.rows[q // B], 0)
            b2, k2 = _best_step(jnp.where(t_ok, score(d, ex, ey, tw[t]), -jnp.inf), t, T)
            better = (b2 > bq) | ((b2 == bq) & (k2 < kq))
            kq, pq = _proof(jnp.maximum(b2, bq), jnp.where(better, k2, kq), rest, empty[q])
            at = jnp.where(j * Q + jnp.arange(Q) < count, q, P * B)             # the padding entries: dropped
            ub = ub if ubq is None else ub.at[:, at].set(ubq, mode="drop")
            return (best.at[at].set(jnp.maximum(b2, bq), mode="drop"), k.at[at].set(kq, mode="drop"),
                    proven.at[at].set(pq, mode="drop"), ub)

        # more unproven pairs than the round holds: the round is skipped (with shares that fall from round to
        # round, as ROUNDS, the call then ends in the culled search whatever this round would prove)
        n_run = jnp.where(count > cap, 0, -(-count // Q))
        best, k, proven, ub = lax.fori_loop(0, n_run, block, (best, k, proven, ub))
    return k.reshape(P, B), proven.reshape(P, B) & ~odd_overflow


__all__ = ["BOUNDED_MAX_CHUNKS", "CHUNK", "ROUNDS", "TILE", "bounded_argmax", "bounded_candidates", "use_bounded"]
