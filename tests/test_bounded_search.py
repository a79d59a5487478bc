"""The bounded grounding search (psbmpc_jax/bounded_search.py), float64: the same worst time step as the culled
search and as brute force over every point, proven without the fallback in the usual case, every round and the
fallback exercised, and the chart-size gate."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from psbmpc_jax.bounded_search import (
    BOUNDED_MAX_CHUNKS,
    bounded_argmax,
    bounded_candidates,
    use_bounded,
)
from psbmpc_jax.costs.grounding import _search_score
from psbmpc_jax.geometry import edge_table, polygon_argmax, polygon_distance
from psbmpc_jax.grounding_search import search_argmax
from psbmpc_jax.params import Params
from psbmpc_jax.situation import ring_vertices

jax.config.update("jax_enable_x64", True)


def islands():
    """Three star-shaped islands (58 + 59 + 59 vertices), one with a hole, as in the CPU-target benchmark."""
    out = []
    for (cx, cy, r, n) in ((100.0, 60.0, 25.0, 58), (300.0, 120.0, 30.0, 59), (520.0, -40.0, 20.0, 59)):
        a = 2 * math.pi * np.arange(n) / n
        rad = r * (1.0 + 0.25 * np.sin(5 * a))
        out.append(np.stack([cx + rad * np.cos(a), cy + rad * np.sin(a)], axis=-1))
    hole = np.array([[295.0, 115.0], [295.0, 125.0], [305.0, 125.0], [305.0, 115.0]])   # clockwise
    return [out[0], (out[1], hole), out[2]]


def pack(polys):
    rows = [ring_vertices(p) for p in polys]
    V = max(len(v) for v, _ in rows) + 3
    verts = np.full((len(rows) + 1, V, 2), 1.0e6)
    nxt = np.zeros((len(rows) + 1, V), np.int32)
    for k, (v, nx) in enumerate(rows):
        verts[k, :len(v)], nxt[k, :len(v)] = v, nx
    n = jnp.asarray([len(v) for v, _ in rows] + [0], jnp.int32)                # and a padding polygon
    return edge_table(jnp.asarray(verts), jnp.asarray(nxt)), jnp.asarray(nxt), n


def fan(B, T=241, dt=0.5, seed=0):
    """``px, py [T, B]``: straight runs at 3-9 m/s from near the origin in a fan of courses, some turning, a few
    through the islands (land: distance 0) and some standing still."""
    rng = np.random.default_rng(seed)
    t = dt * np.arange(T)[:, None]
    chi = rng.uniform(-0.6, 0.9, B) + np.where(rng.uniform(size=B) < 0.3, 0.004 * t, 0.0)
    u = rng.uniform(3.0, 9.0, B) * (rng.uniform(size=B) > 0.05)
    x = np.cumsum(u * np.cos(chi) * dt, axis=0) + rng.uniform(-20, 20, B)
    y = np.cumsum(u * np.sin(chi) * dt, axis=0) + rng.uniform(-20, 20, B)
    return jnp.asarray(x), jnp.asarray(y), jnp.exp(-Params().G4 * jnp.asarray(t[:, 0]))


def brute(px, py, tw, score, tables, n, wd):
    """The first worst time step over every point, from the full distance kernel."""
    out = []
    for j in range(len(n)):
        d, ex, ey = polygon_distance(px, py, tables[j], n[j])
        if not wd:
            ex, ey = jnp.zeros_like(ex), jnp.zeros_like(ey)
        s = np.asarray(score(d, ex, ey, tw[:, None]))
        out.append(np.argmax(s, axis=0) if int(n[j]) > 0 else np.zeros(px.shape[1], int))
    return np.stack(out)


@pytest.mark.parametrize("wind", [0.0, 6.0])
def test_bounded_search_is_proven_and_equals_culled_and_brute_force(wind):
    """The grounding score of the default parameters (with wind: the direction to land matters): every
    (polygon, column) proven by the bounds without the fallback, the same steps as the culled search and as
    brute force over every point."""
    params = Params(V_w=wind, wind_dir=0.3)
    score, bound = _search_score(params)
    tables, nxt, n = pack(islands())
    px, py, tw = fan(160)
    wd = wind > 0
    k, proven = bounded_candidates(px, py, tw, score, bound, tables, nxt, n, wd)
    assert bool(jnp.all(proven))
    want = brute(px, py, tw, score, tables, n, wd)
    np.testing.assert_array_equal(np.asarray(k), want)
    np.testing.assert_array_equal(np.asarray(polygon_argmax(px, py, tw, score, bound, tables, nxt, n, wd)), want)
    np.testing.assert_array_equal(np.asarray(bounded_argmax(px, py, tw, score, bound, tables, nxt, n, wd)), want)
    assert np.any(want[:3] > 0) and np.all(want[3] == 0)


def test_every_round_and_the_fallback():
    """Small first rounds leave pairs unproven for the later ones (each round proves more, the last whole
    columns); a round too small for the unproven pairs leaves them to the culled search: the same answer."""
    score, bound = _search_score(Params())
    tables, nxt, n = pack(islands())
    px, py, tw = fan(96, seed=1)
    want = brute(px, py, tw, score, tables, n, False)
    open_after = []
    for rounds in (((1, 1.0),), ((1, 1.0), (1, 1.0)), ((1, 1.0), (1, 1.0), (None, 1.0))):
        k, proven = bounded_candidates(px, py, tw, score, bound, tables, nxt, n, False, rounds=rounds)
        open_after.append(int(jnp.sum(~proven)))
        np.testing.assert_array_equal(np.asarray(k)[np.asarray(proven)], want[np.asarray(proven)])
    assert open_after[0] > open_after[1] > open_after[2] == 0
    tight = ((1, 1.0), (None, 1e-9))                                            # room for one pair only
    k, proven = bounded_candidates(px, py, tw, score, bound, tables, nxt, n, False, rounds=tight)
    assert not bool(jnp.all(proven))
    np.testing.assert_array_equal(np.asarray(bounded_argmax(px, py, tw, score, bound, tables, nxt, n, False,
                                                            rounds=tight)), want)


def test_unbounded_scores_fall_back_to_the_culled_search():
    """A score the bound cannot cap (``bound`` = inf: non-monotone parameters) proves nothing; the answer is the
    culled search's, ties to the first step included (a score constant in time)."""
    tables, nxt, n = pack(islands())
    px, py, tw = fan(40, seed=2)
    score = lambda d, ex, ey, w: w * jnp.cos(0.2 * d)
    bound = lambda d, w: jnp.full_like(d, jnp.inf)
    _, proven = bounded_candidates(px, py, tw, score, bound, tables, nxt, n, False)
    assert not bool(jnp.any(proven[:3]))
    want = brute(px, py, tw, score, tables, n, False)                           # the padding polygon aside
    np.testing.assert_array_equal(np.asarray(bounded_argmax(px, py, tw, score, bound, tables, nxt, n, False))[:3],
                                  want[:3])
    flat = lambda d, ex, ey, w: jnp.zeros_like(d)                               # every score 0: the first step
    _, fbound = _search_score(Params())
    k, proven = bounded_candidates(px, py, tw, flat, fbound, tables, nxt, n, False)
    assert bool(jnp.any(proven)) and not np.any(np.asarray(k)[np.asarray(proven)])
    assert not np.any(np.asarray(bounded_argmax(px, py, tw, flat, fbound, tables, nxt, n, False)))


def test_far_columns_are_proven_zero_at_the_first_step():
    """Columns so far from land that every bound underflows to 0: proven, step 0 (as the culled search)."""
    score, bound = _search_score(Params())
    tables, nxt, n = pack(islands())
    px, py, tw = fan(8, seed=3)
    px = px + 5.0e4
    k, proven = bounded_candidates(px, py, tw, score, bound, tables, nxt, n, True)
    assert bool(jnp.all(proven)) and not np.any(np.asarray(k))
    np.testing.assert_array_equal(np.asarray(k), np.asarray(polygon_argmax(px, py, tw, score, bound, tables, nxt,
                                                                           n, True)))


def test_the_gate_sends_large_charts_to_the_culled_search():
    """``bounded`` runs the bounded search up to BOUNDED_MAX_CHUNKS chunks, the culled one above (the same
    steps either way)."""
    tables, nxt, n = pack(islands())
    assert use_bounded(tables) and not use_bounded(tables[:0])
    big = jnp.zeros((BOUNDED_MAX_CHUNKS + 1, 8, 8))
    assert not use_bounded(big)
    score, bound = _search_score(Params())
    px, py, tw = fan(24, seed=4)
    want = np.asarray(polygon_argmax(px, py, tw, score, bound, tables, nxt, n, False))
    np.testing.assert_array_equal(np.asarray(search_argmax("bounded", px, py, tw, score, bound, tables, nxt, n,
                                                           False)), want)
    many = jnp.concatenate([tables] * 6), jnp.concatenate([nxt] * 6), jnp.concatenate([n] * 6)
    assert not use_bounded(many[0])
    np.testing.assert_array_equal(np.asarray(search_argmax("bounded", px, py, tw, score, bound, *many, False)),
                                  np.tile(want, (6, 1)))
