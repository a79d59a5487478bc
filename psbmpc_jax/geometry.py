"""Device polygon geometry: edge tables, exact point-to-polygon distances, and a culled search.

Axes: T time samples, B columns (behaviours), P polygons, V vertex slots, S time steps per tile,
N = B * ceil(T / S) tiles, M edge slots per chunk.  Slot i of a polygon is the edge from vertex i to vertex
``next[i]`` (a polygon holds its rings back to back, each closing on itself); the first ``n`` slots are valid.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
from jax import lax

from .numerics import safe_sqrt

#: Columns of :func:`edge_table`.
EDGE_COLUMNS = ("ax", "ay", "abx", "aby", "inv_l2", "bx", "by", "slope")


def edge_table(vertices, nxt):
    """Per-edge constants ``[..., V, 8]`` (:data:`EDGE_COLUMNS`): a, b - a, 1/|b - a|^2 (0 for a zero-length
    edge), b and the crossing slope (b_x - a_x)/(b_y - a_y) (0 for a horizontal edge, which never straddles)."""
    ax, ay = vertices[..., 0], vertices[..., 1]
    b = jnp.take_along_axis(vertices, nxt[..., None], axis=-2)
    bx, by = b[..., 0], b[..., 1]
    abx, aby = bx - ax, by - ay
    l2 = abx * abx + aby * aby
    inv_l2 = jnp.where(l2 > 0, 1.0 / jnp.where(l2 > 0, l2, 1.0), 0.0)
    slope = jnp.where(aby != 0, abx / jnp.where(aby != 0, aby, 1.0), 0.0)
    return jnp.stack([ax, ay, abx, aby, inv_l2, bx, by, slope], axis=-1)


def edge_terms(px, py, edge):
    """Points ``px, py`` against one edge (its 8 columns, broadcastable): the vector from the nearest point of
    the edge to the point, its squared length, and whether the edge crosses the ray from the point to +x
    (half-open in y: the even-odd rule)."""
    ax, ay, abx, aby, inv_l2, _, by, slope = edge
    apx, apy = px - ax, py - ay
    t = jnp.clip((apx * abx + apy * aby) * inv_l2, 0.0, 1.0)
    qx, qy = apx - t * abx, apy - t * aby
    cross = ((ay > py) != (by > py)) & (px < ax + apy * slope)
    return qx, qy, qx * qx + qy * qy, cross


def _scan_edges(px, py, edges, n, track_best):
    """Non-differentiable search over the ``n`` valid edges (dynamic trip count): the smallest squared distance,
    the index of its edge (when ``track_best``, else 0) and the even-odd inside flag."""
    px, py = lax.stop_gradient(px), lax.stop_gradient(py)
    edges = lax.stop_gradient(edges)

    def body(e, carry):
        d2, best, inside = carry
        _, _, e2, cross = edge_terms(px, py, tuple(edges[e, i] for i in range(8)))
        closer = e2 < d2
        best = jnp.where(closer, e, best) if track_best else best
        return jnp.where(closer, e2, d2), best, inside ^ cross

    init = (jnp.full(px.shape, jnp.finfo(px.dtype).max, px.dtype), jnp.zeros(px.shape, jnp.int32),
            jnp.zeros(px.shape, bool))
    return lax.fori_loop(0, n, body, init)


def polygon_distance(px, py, edges, n, with_direction=True, *, block=1):
    """Distance from points ``px, py [...]`` to one polygon given by its edge table ``edges [V, 8]`` and ``n``
    valid edges.

    Returns (d, ex, ey): distance (0 inside, even-odd rule) and the vector from the point to the nearest
    boundary point (0 inside).  With ``with_direction`` (static) the nearest edge is found without gradients
    and (d, ex, ey) are computed from it: reverse- and forward-differentiable w.r.t. ``px, py``.  Without it
    (the distance-grid build) the loop does not track the nearest edge (about 15 % less work), (ex, ey) are
    zeros and d is forward-only.  ``block`` (static): edges per loop step of the nearest-edge search with
    direction (1: one edge per step; > 1: :func:`_dense_nearest`, the same edge, fewer and wider steps - the
    choice for few points and many edges, above all on a GPU)."""
    if not with_direction:
        d2, _, inside = _scan_edges(px, py, edges, n, track_best=False)
        zero = jnp.zeros_like(px)
        return jnp.where(inside, 0.0, safe_sqrt(d2)), zero, zero
    if block > 1:
        d2, best, inside = _dense_nearest(*(lax.stop_gradient(a) for a in (px, py, edges)), n, block)
    else:
        d2, best, inside = _scan_edges(px, py, edges, n, track_best=True)
    qx, qy, e2, _ = edge_terms(px, py, tuple(edges[best, i] for i in range(8)))
    near = ~inside & (n > 0)
    d = jnp.where(inside, 0.0, safe_sqrt(jnp.where(n > 0, e2, d2)))   # gradient-safe on the boundary
    return d, jnp.where(near, -qx, 0.0), jnp.where(near, -qy, 0.0)


# ----------------------------------------------------------------------------------------- culled search
class TimeTiles(NamedTuple):
    """Points ``x, y [N, S]`` in tiles (row n = column b * nt + block i) with their time features ``w [N, S]``
    and validity ``valid [N, S]`` (False on the padding past T); per tile its box (x/y min/max ``[N]``),
    centre, half-diagonal ``h`` and the largest time feature ``w_max``."""

    x: jax.Array
    y: jax.Array
    w: jax.Array
    valid: jax.Array
    xmin: jax.Array
    xmax: jax.Array
    ymin: jax.Array
    ymax: jax.Array
    cx: jax.Array
    cy: jax.Array
    h: jax.Array
    w_max: jax.Array


class EdgeChunks(NamedTuple):
    """One polygon's edges in chunks of M slots: ``rows [C + 1, 8, M]`` (invalid slots and chunk C are null
    edges), per chunk ``lo, hi [C, 2]`` (box of its valid edges), ``v0 [C, 2]`` (its first vertex),
    ``odd_y [C, 4]`` (y of its odd-degree vertices, -inf padded), and the number of valid chunks ``n``."""

    rows: jax.Array
    lo: jax.Array
    hi: jax.Array
    v0: jax.Array
    odd_y: jax.Array
    n: jax.Array


def time_tiles(px, py, tw, S):
    """:class:`TimeTiles` of ``S`` time steps of the points ``px, py [T, B]`` with time features ``tw [T]`` (the
    last point repeated to fill the last tile)."""
    T, B = px.shape
    nt = -(-T // S)
    pad = lambda a: jnp.concatenate([a, jnp.broadcast_to(a[-1:], (nt * S - T,) + a.shape[1:])])
    tiled = lambda a: pad(a).T.reshape(B * nt, S)
    x, y = tiled(px), tiled(py)
    w = jnp.tile(pad(tw).reshape(nt, S), (B, 1))
    valid = jnp.tile((jnp.arange(nt * S) < T).reshape(nt, S), (B, 1))
    xmin, xmax, ymin, ymax = x.min(1), x.max(1), y.min(1), y.max(1)
    hx, hy = 0.5 * (xmax - xmin), 0.5 * (ymax - ymin)
    # the half-diagonal, rounded up a little so that every point of the box is within h of the centre
    h = jnp.sqrt(hx * hx + hy * hy) * (1.0 + 4 * jnp.finfo(px.dtype).eps)
    return TimeTiles(x, y, w, valid, xmin, xmax, ymin, ymax, xmin + hx, ymin + hy, h,
                  jnp.max(jnp.where(valid, w, -jnp.inf), axis=1))


def _null_edge(dtype):
    big = jnp.sqrt(jnp.finfo(dtype).max) / 8
    return jnp.array([big, big, 0.0, 0.0, 0.0, big, big, 0.0], dtype)


def edge_chunks(edges, nxt, n, M):
    """:class:`EdgeChunks` of every polygon (leading axis P), from ``edges [P, V, 8]``, ``nxt [P, V]``, ``n [P]``.
    Also returns whether some chunk has more than 4 odd-degree vertices (impossible for rings stored back to
    back; then the caller falls back to the full search)."""
    P, V = nxt.shape
    C = -(-V // M)
    Vp = C * M
    slot = jnp.arange(Vp, dtype=jnp.int32)
    valid = slot[None, :] < n[:, None]                                            # [P, Vp]
    edges = jnp.pad(edges, ((0, 0), (0, Vp - V), (0, 0)))
    nxt = jnp.pad(nxt, ((0, 0), (0, Vp - V)))
    null = _null_edge(edges.dtype)
    rows = jnp.concatenate([jnp.where(valid[..., None], edges, null), jnp.broadcast_to(null, (P, M, 8))], axis=1)
    rows = jnp.swapaxes(rows.reshape(P, C + 1, M, 8), -1, -2)                    # [P, C + 1, 8, M]
    # the previous edge of each vertex: prv[nxt[i]] = i
    pidx = jnp.broadcast_to(jnp.arange(P)[:, None], (P, Vp))
    prv = jnp.zeros((P, Vp), jnp.int32).at[pidx, jnp.where(valid, nxt, Vp)].set(
        jnp.broadcast_to(slot, (P, Vp)), mode="drop")
    start_odd = valid & (prv // M != slot // M)                                  # a_i's other edge elsewhere
    end_odd = valid & (nxt // M != slot // M)                                    # b_i's other edge elsewhere
    ax, ay, bx, by = edges[..., 0], edges[..., 1], edges[..., 5], edges[..., 6]
    inf = jnp.asarray(jnp.inf, edges.dtype)
    cm = lambda a: a.reshape(P, C, M)
    lo_x = cm(jnp.where(valid, jnp.minimum(ax, bx), inf)).min(-1)
    hi_x = cm(jnp.where(valid, jnp.maximum(ax, bx), -inf)).max(-1)
    lo_y = cm(jnp.where(valid, jnp.minimum(ay, by), inf)).min(-1)
    hi_y = cm(jnp.where(valid, jnp.maximum(ay, by), -inf)).max(-1)
    v0 = jnp.stack([cm(ax)[..., 0], cm(ay)[..., 0]], -1)
    flags = jnp.concatenate([cm(start_odd), cm(end_odd)], -1)                    # [P, C, 2M]
    ys = jnp.concatenate([cm(ay), cm(by)], -1)
    pos = jnp.cumsum(flags, -1) - 1
    pick = flags[..., None] & (pos[..., None] == jnp.arange(4))                  # [P, C, 2M, 4]
    odd_y = jnp.where(pick.any(-2), jnp.where(pick, ys[..., None], 0).sum(-2), -inf)
    odd_overflow = jnp.any(flags.sum(-1) > 4)
    return EdgeChunks(rows, jnp.stack([lo_x, lo_y], -1), jnp.stack([hi_x, hi_y], -1), v0, odd_y,
                   (n + M - 1) // M), odd_overflow


def _set_bits(words, pos, bits):
    """OR ``bits [N]`` (uint32, fitting from bit ``pos % 32`` on) into ``words [W, N]`` at bit ``pos``."""
    w = pos // 32
    word = lax.dynamic_index_in_dim(words, w, keepdims=False) | (bits << (pos % 32).astype(jnp.uint32))
    return lax.dynamic_update_index_in_dim(words, word, w, axis=0)


def _nth_bit(words, before, j):
    """Position of the ``j``-th (from 0) set bit of every column of ``words [W, N]`` (bit b of word w is
    position 32 w + b), -1 where there are fewer; ``before [W, N]``: the set bits in the words before."""
    W = words.shape[0]
    w = sum((before[i] <= j).astype(jnp.int32) for i in range(1, W)) if W > 1 else jnp.zeros_like(before[0])
    pick = jnp.arange(W)[:, None] == w
    word = jnp.sum(jnp.where(pick, words, 0), axis=0, dtype=jnp.uint32)
    r = j - jnp.sum(jnp.where(pick, before, 0), axis=0)
    found = r < lax.population_count(word).astype(jnp.int32)
    pos = w * 32
    for width in (16, 8, 4, 2, 1):                                               # binary search in the word
        low = word & jnp.uint32((1 << width) - 1)
        c = lax.population_count(low).astype(jnp.int32)
        up = r >= c
        r, word, pos = jnp.where(up, r - c, r), jnp.where(up, word >> width, low), jnp.where(up, pos + width, pos)
    return jnp.where(found, pos, -1)


def _bits_before(words):
    """Set bits in the words before each word of ``words [W, N]``: ``[W, N]`` int32."""
    counts = lax.population_count(words).astype(jnp.int32)
    return jnp.cumsum(counts, axis=0) - counts


class _Live(NamedTuple):
    """One polygon's culling result per tile ``[N]``: live-edge bit words ``words [KC M / 32, N]`` (bit
    q M + k: lane k of candidate chunk ``ids[q]``), ``before`` (set bits in earlier words), ``ids [KC, N]``,
    ``n_live`` (live edges), ``par`` (crossings of the ray from the box's corner (xmax, ymax) by every non-live
    edge), ``idle`` (score 0 at every point: not evaluated) and whether ``KC`` overflowed."""

    words: jax.Array
    before: jax.Array
    ids: jax.Array
    n_live: jax.Array
    par: jax.Array
    idle: jax.Array
    overflow: jax.Array


def _cull(tiles: TimeTiles, ch: EdgeChunks, tol, bound, M, KC) -> _Live:
    """The live edges of every tile for one polygon (module docstring, steps 1-4)."""
    N = tiles.x.shape[0]
    xmin, xmax, ymin, ymax = tiles.xmin, tiles.xmax, tiles.ymin, tiles.ymax
    C = ch.lo.shape[0]
    dtype = xmin.dtype

    # 1. upper bound on the boundary distance of every point of a tile: its farthest corner to a chunk vertex
    def ub_body(f, ub2):
        vx, vy = ch.v0[f, 0], ch.v0[f, 1]
        ux = jnp.maximum(jnp.abs(vx - xmin), jnp.abs(vx - xmax))
        uy = jnp.maximum(jnp.abs(vy - ymin), jnp.abs(vy - ymax))
        return jnp.minimum(ub2, ux * ux + uy * uy)

    lim2 = jnp.square(jnp.sqrt(lax.fori_loop(0, ch.n, ub_body, jnp.full((N,), jnp.inf, dtype))) + tol)

    # 2. candidate chunks: box gap <= that bound.  The others are separated from the tile and add their
    #    crossings of the ray from the corner (xmax, ymax) to ``par``; ``par_all`` adds every chunk's, the
    #    parity of the whole tile when no chunk box comes near it.
    def cand_body(f, carry):
        words, cnt, par, par_all, gap2 = carry
        lo, hi = ch.lo[f], ch.hi[f]
        dx = jnp.maximum(0.0, jnp.maximum(lo[0] - xmax, xmin - hi[0]))
        dy = jnp.maximum(0.0, jnp.maximum(lo[1] - ymax, ymin - hi[1]))
        g2 = dx * dx + dy * dy
        cand = g2 <= lim2
        odd = (ch.odd_y[f, 0] > ymax) ^ (ch.odd_y[f, 1] > ymax) ^ (ch.odd_y[f, 2] > ymax) ^ (ch.odd_y[f, 3] > ymax)
        cross = (lo[0] > xmax) & odd
        return (_set_bits(words, f, cand.astype(jnp.uint32)), cnt + cand, par ^ (cross & ~cand), par_all ^ cross,
                jnp.minimum(gap2, g2))

    zeros = jnp.zeros(N, bool)
    words, n_cand, par, par_all, gap2 = lax.fori_loop(
        0, ch.n, cand_body, (jnp.zeros((-(-C // 32), N), jnp.uint32), jnp.zeros(N, jnp.int32), zeros, zeros,
                             jnp.full((N,), jnp.inf, dtype)))
    # tiles wholly outside whose score is bounded by 0 (past exp underflow) need no evaluation
    lb = jnp.sqrt(gap2) - tol
    idle = (lb > 0) & ~par_all & (bound(lb, tiles.w_max) == 0) if bound is not None else zeros
    n_cand = jnp.where(idle, 0, n_cand)
    before = _bits_before(words)

    # 3. the candidate chunks' edges against the tile: centre distance (``dc2``: the centre's nearest edge is
    #    in a candidate chunk), box gap, crossing of the ray from the corner
    cx, cy, qx, qy = tiles.cx[:, None], tiles.cy[:, None], xmax[:, None], ymax[:, None]
    q_max = jnp.minimum(jnp.max(n_cand), KC)

    def gather_body(q, carry):
        ids, e2s, g2s, crs, dc2 = carry
        f = _nth_bit(words, before, q)
        f = jnp.where((f >= 0) & ~idle, f, C)                                    # C: the null chunk
        r = ch.rows[f]                                                           # [N, 8, M]
        e = tuple(r[:, i] for i in range(8))
        ax, ay, bx, by = e[0], e[1], e[5], e[6]
        _, _, e2, _ = edge_terms(cx, cy, e)
        _, _, _, cross = edge_terms(qx, qy, e)
        dx = jnp.maximum(0.0, jnp.maximum(jnp.minimum(ax, bx) - qx, xmin[:, None] - jnp.maximum(ax, bx)))
        dy = jnp.maximum(0.0, jnp.maximum(jnp.minimum(ay, by) - qy, ymin[:, None] - jnp.maximum(ay, by)))
        put = lambda a, v: lax.dynamic_update_index_in_dim(a, v, q, axis=0)
        return put(ids, f), put(e2s, e2), put(g2s, dx * dx + dy * dy), put(crs, cross), jnp.minimum(dc2, e2.min(1))

    ids, e2s, g2s, crs, dc2 = lax.fori_loop(0, q_max, gather_body, (
        jnp.full((KC, N), C, jnp.int32), jnp.zeros((KC, N, M), dtype), jnp.zeros((KC, N, M), dtype),
        jnp.zeros((KC, N, M), bool), jnp.full((N,), jnp.inf, dtype)))

    # 4. live edges: those that can be nearest to some point of the tile; the others add their crossings to par
    dc = jnp.sqrt(dc2)
    near2, gap2 = jnp.square(dc + 2 * tiles.h + tol)[:, None], jnp.square(dc + tiles.h + tol)[:, None]
    lanes = jnp.arange(M, dtype=jnp.uint32)

    def live_body(q, carry):
        lwords, count, par = carry
        live = (q < n_cand)[:, None] & (e2s[q] <= near2) & (g2s[q] <= gap2)
        bits = jnp.sum(live.astype(jnp.uint32) << lanes, axis=1, dtype=jnp.uint32)
        return (_set_bits(lwords, q * M, bits), count + jnp.sum(live, axis=1, dtype=jnp.int32),
                par ^ (jnp.sum(~live & crs[q], axis=1) % 2 == 1))

    lwords, count, par = lax.fori_loop(0, q_max, live_body, (jnp.zeros((-(-KC * M // 32), N), jnp.uint32),
                                                             jnp.zeros(N, jnp.int32), par))
    return _Live(lwords, _bits_before(lwords), ids, count, par, idle, jnp.max(n_cand) > KC)


def _nearest(tiles: TimeTiles, ch: EdgeChunks, live: _Live, M, track):
    """Distance and nearest-boundary vector of every tile point to one polygon from its tile's live edges
    (module docstring, step 5): ``d, ex, ey [N, S]``; (ex, ey) are zeros unless ``track``."""
    x, y, qx, qy = tiles.x, tiles.y, tiles.xmax[:, None], tiles.ymax[:, None]
    C = ch.lo.shape[0]

    def body(j, carry):
        d2, vx, vy, inside = carry
        pos = _nth_bit(live.words, live.before, j)
        q, k = jnp.maximum(pos, 0) // M, jnp.maximum(pos, 0) % M
        f = jnp.where(pos >= 0, jnp.take_along_axis(live.ids, q[None], 0)[0], C)
        r = ch.rows[f, :, k]                                                     # [N, 8]
        e = tuple(r[:, i, None] for i in range(8))
        ex, ey, e2, cross = edge_terms(x, y, e)
        ax, ay, bx, by = e[0], e[1], e[5], e[6]
        portal = ((ax > qx) & (ay <= qy) & (y < ay)) ^ ((bx > qx) & (by <= qy) & (y < by))
        closer = e2 < d2
        if track:
            vx, vy = jnp.where(closer, ex, vx), jnp.where(closer, ey, vy)
        return jnp.where(closer, e2, d2), vx, vy, inside ^ cross ^ portal

    init = (jnp.full(x.shape, jnp.finfo(x.dtype).max, x.dtype), jnp.zeros_like(x), jnp.zeros_like(x),
            jnp.broadcast_to(live.par[:, None], x.shape))
    d2, vx, vy, inside = lax.fori_loop(0, jnp.max(live.n_live), body, init)
    return jnp.where(inside, 0.0, jnp.sqrt(d2)), jnp.where(inside, 0.0, -vx), jnp.where(inside, 0.0, -vy)


def _prepare(px, py, tw, edges, nxt, n, tile, chunk):
    """Tiles (S <= ``tile`` time steps, the fewest padded steps), every polygon's chunks, the rounding
    tolerance and whether some chunk holds too many odd-degree vertices."""
    T = px.shape[0]
    tiles = time_tiles(px, py, tw, -(-T // -(-T // tile)))
    chunks, odd_overflow = edge_chunks(edges, nxt, n, chunk)
    valid = jnp.arange(edges.shape[1])[None, :] < n[:, None]
    scale = jnp.maximum(jnp.max(jnp.abs(jnp.where(valid[..., None], edges[..., :2], 0.0))),
                        jnp.maximum(jnp.max(jnp.abs(px)), jnp.max(jnp.abs(py))))
    return tiles, chunks, 64 * jnp.finfo(px.dtype).eps * (scale + 1.0), odd_overflow


#: Time steps per tile of :func:`polygon_argmax` (at most; the horizon is split into equal tiles).  Larger tiles
#: cull fewer edges but cost fewer, cheaper culling passes; on the 2-core CPU the argmax alone at 1 014 behaviours
#: took (tile 32 / 64 / 128): 44 / 33 / 30 ms on the 13 Nidelva polygons (T 150 s), 298 / 151 / 95 ms on the
#: raw 21 961-vertex polygon (fig9, own-ship still), 50 / 38 / 29 ms on three 59-vertex islands beside a 9 m/s
#: route (T 120 s) (benchmarks/bench_layout_choices.py, results/layout_choices_cpu_20261128T054017Z.json).
ARGMAX_TILE = 128


def polygon_argmax(px, py, tw, score, bound, edges, nxt, n, with_direction=True, *, tile=ARGMAX_TILE, chunk=8,
                   chunk_cap=16):
    """For every polygon and column, the time index maximising ``score(d, ex, ey, w)`` over the points
    ``px, py [T, B]``: ``[P, B]`` int32 (the first of equal maxima up to rounding; 0 for a polygon with
    ``n`` = 0).

    d, ex, ey: distance and nearest-boundary vector as in :func:`polygon_distance`; w: the time feature
    ``tw [T]`` of the point.  ``bound(d, w)``: an upper bound of ``score`` over every distance >= d, time
    feature <= w and direction.  ``with_direction`` (may be traced): False if ``score`` ignores (ex, ey),
    which are then zeros.  ``tile``, ``chunk``, ``chunk_cap``: S, M, KC of the module docstring.  Not
    differentiable (an integer result); exact: a capacity overflow falls back to visiting every edge."""
    px, py, tw, edges = (lax.stop_gradient(a) for a in (px, py, tw, edges))
    T, B = px.shape
    if edges.shape[0] == 0:
        return jnp.zeros((0, B), jnp.int32)
    tiles, chunks, tol, odd_overflow = _prepare(px, py, tw, edges, nxt, n, tile, chunk)

    def one(overflow, ch):
        live = _cull(tiles, ch, tol, bound, chunk, chunk_cap)

        def best():
            d, ex, ey = lax.cond(with_direction, lambda: _nearest(tiles, ch, live, chunk, True),
                                 lambda: _nearest(tiles, ch, live, chunk, False))
            s = jnp.where(tiles.valid, jnp.where(live.idle[:, None], 0.0, score(d, ex, ey, tiles.w)), -jnp.inf)
            return jnp.argmax(s.reshape(B, -1), axis=1).astype(jnp.int32)

        return overflow | live.overflow, lax.cond(jnp.all(live.idle), lambda: jnp.zeros(B, jnp.int32), best)

    overflow, k = lax.scan(one, odd_overflow, chunks)
    return lax.cond(overflow, lambda: dense_argmax(px, py, tw, score, edges, n, with_direction, block=1),
                    lambda: k)


# ------------------------------------------------------------------------------------------ dense search
def _dense_nearest(px, py, edges, n, block):
    """Every valid edge, ``block`` edge slots at a time (one ``[block, T, B]`` evaluation per loop step): the
    smallest squared distance, the slot of its edge (the first of equal ones, as :func:`_scan_edges`) and the
    even-odd inside flag.  Few long loop steps instead of many short ones: the GPU-friendly layout."""
    V = edges.shape[0]
    nb = -(-V // block)
    rows = jnp.pad(edges, ((0, nb * block - V), (0, 0))).reshape(nb, block, 8)
    slot = jnp.arange(block)
    big = jnp.finfo(px.dtype).max
    lead = (block,) + (1,) * px.ndim                # edge columns against points of any shape

    def body(i, carry):
        d2, best, inside = carry
        e = rows[i]
        _, _, e2, cross = edge_terms(px[None], py[None], tuple(e[:, c].reshape(lead) for c in range(8)))
        valid = (i * block + slot < n).reshape(lead)
        e2 = jnp.where(valid, e2, big)
        j = jnp.argmin(e2, axis=0).astype(jnp.int32)
        m = jnp.take_along_axis(e2, j[None], axis=0)[0]
        closer = m < d2
        odd = (jnp.sum((cross & valid).astype(jnp.int32), axis=0) & 1) == 1
        best = jnp.where(closer, (i * block).astype(jnp.int32) + j, best)
        return jnp.where(closer, m, d2), best, inside ^ odd

    init = (jnp.full(px.shape, big, px.dtype), jnp.zeros(px.shape, jnp.int32), jnp.zeros(px.shape, bool))
    return lax.fori_loop(0, (n + block - 1) // block, body, init)


def dense_distances(px, py, edges, n, *, block=32):
    """:func:`polygon_distance` (with direction, not differentiable) by the dense search: ``d, ex, ey`` of the
    points ``px, py [T, B]`` to one polygon (edge table ``edges [V, 8]``, ``n`` valid edges)."""
    px, py, edges = (lax.stop_gradient(a) for a in (px, py, edges))
    d2, best, inside = _dense_nearest(px, py, edges, n, block)
    qx, qy, e2, _ = edge_terms(px, py, tuple(edges[best, c] for c in range(8)))
    near = ~inside & (n > 0)
    d = jnp.where(inside, 0.0, safe_sqrt(jnp.where(n > 0, e2, d2)))
    return d, jnp.where(near, -qx, 0.0), jnp.where(near, -qy, 0.0)


#: Largest ``block * T * B`` of one dense loop step (2^25 elements: 128 MiB per float32 temporary).
DENSE_STEP_ELEMENTS = 1 << 25


def dense_block(n_points: int, largest: int = 32) -> int:
    """Edges per dense loop step for ``n_points`` = T * B points: the largest power of two <= ``largest`` whose
    step stays within :data:`DENSE_STEP_ELEMENTS` (at least 1)."""
    b = largest
    while b > 1 and b * n_points > DENSE_STEP_ELEMENTS:
        b //= 2
    return b


def dense_argmax(px, py, tw, score, edges, n, with_direction=True, *, block=None):
    """:func:`polygon_argmax` without culling: every polygon's every valid edge against every point, ``block``
    edges per loop step (``[P, B]`` int32; 0 for a polygon with ``n`` = 0; ``block`` None:
    :func:`dense_block` of the point count).  The same answer as the culled
    search (the first of equal maxima up to rounding); fewer, wider steps: faster where the culled search's
    many small loop steps dominate (a GPU), slower and ``block``x the memory on a CPU."""
    px, py, tw, edges = (lax.stop_gradient(a) for a in (px, py, tw, edges))
    T, B = px.shape
    if edges.shape[0] == 0:
        return jnp.zeros((0, B), jnp.int32)
    block = dense_block(T * B) if block is None else block

    def one(_, poly):
        e, k = poly
        d, ex, ey = dense_distances(px, py, e, k, block=block)
        ex, ey = jnp.where(with_direction, ex, 0.0), jnp.where(with_direction, ey, 0.0)
        best = jnp.argmax(score(d, ex, ey, tw[:, None]), axis=0).astype(jnp.int32)
        return None, jnp.where(k > 0, best, 0)

    return lax.scan(one, None, (edges, n))[1]


def culled_distances(px, py, edges, nxt, n, *, tile=32, chunk=8, chunk_cap=16):
    """Distance and nearest-boundary vector of the points ``px, py [T, B]`` to every polygon through the
    culled kernel: ``d, ex, ey [P, T, B]`` (as :func:`polygon_distance`, not differentiable) and whether a
    capacity overflowed (then the result comes from visiting every edge).  For tests and diagnostics;
    :func:`polygon_argmax` reduces over time without storing these."""
    px, py, edges = (lax.stop_gradient(a) for a in (px, py, edges))
    T, B = px.shape
    if edges.shape[0] == 0:
        empty = jnp.zeros((0, T, B), px.dtype)
        return (empty, empty, empty), jnp.asarray(False)
    tiles, chunks, tol, odd_overflow = _prepare(px, py, jnp.zeros(T, px.dtype), edges, nxt, n, tile, chunk)
    untile = lambda a: a.reshape(B, -1).T[:T]

    def one(overflow, ch):
        live = _cull(tiles, ch, tol, None, chunk, chunk_cap)
        return overflow | live.overflow, tuple(untile(a) for a in _nearest(tiles, ch, live, chunk, True))

    overflow, out = lax.scan(one, odd_overflow, chunks)

    def full():
        return jax.vmap(lambda e, k: polygon_distance(px, py, e, k))(edges, n)

    return lax.cond(overflow, full, lambda: out), overflow
