"""The bounded grounding search's tile selection by ``lax.top_k`` (long horizons) gives the unrolled selection's
answers, and keeps the program small: unrolled, compiling one solve grew as the square of the tiles per column
(T = 600 s at dt = 0.5 s passed 21 GB and 15 minutes of compilation on the 2-core VM)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import psbmpc_jax.bounded_search as bs
from psbmpc_jax.costs.grounding import _search_score
from psbmpc_jax.params import Params

from test_bounded_search import brute, fan, islands, pack

jax.config.update("jax_enable_x64", True)


def test_keep_top_k_equals_the_unrolled_keep():
    rng = np.random.default_rng(0)
    v = rng.integers(0, 5, size=(40, 3, 7)).astype(float)             # many ties
    v[rng.uniform(size=v.shape) < 0.1] = np.inf
    for k in (1, 3, 6):
        a = bs._keep(jnp.asarray(v), k)                                  # 40 k <= 2048: unrolled
        b = bs._keep_top_k(jnp.asarray(v), k)
        for x, y in zip(a, b):
            np.testing.assert_array_equal(np.asarray(x), np.asarray(y))


@pytest.mark.parametrize("seed", [0, 1])
def test_top_k_path_gives_the_same_worst_steps(monkeypatch, seed):
    score, bound = _search_score(Params())
    tables, nxt, n = pack(islands())
    px, py, tw = fan(48, T=401, seed=seed)
    want = brute(px, py, tw, score, tables, n, False)
    k0, p0 = bs.bounded_candidates(px, py, tw, score, bound, tables, nxt, n, False)
    monkeypatch.setattr(bs, "KEEP_UNROLL_MAX", 0)                         # every selection by top_k
    k1, p1 = bs.bounded_candidates(px, py, tw, score, bound, tables, nxt, n, False)
    np.testing.assert_array_equal(np.asarray(p1), np.asarray(p0))
    np.testing.assert_array_equal(np.asarray(k1)[np.asarray(p1)], want[np.asarray(p1)])
    np.testing.assert_array_equal(np.asarray(bs.bounded_argmax(px, py, tw, score, bound, tables, nxt, n, False)),
                                  want)


def test_program_size_does_not_grow_with_the_square_of_the_tiles():
    """HLO size of the bounded search at 1 201 and 4 801 steps: about linear in the steps (was quadratic)."""
    score, bound = _search_score(Params())
    tables, nxt, n = pack(islands())

    def size(T):
        px, py, tw = fan(8, T=T)
        f = jax.jit(lambda x, y, w: bs.bounded_argmax(x, y, w, score, bound, tables, nxt, n, False))
        return len(f.lower(px, py, tw).as_text())
    s1, s4 = size(1201), size(4801)
    assert s4 < 2.0 * s1, (s1, s4)
