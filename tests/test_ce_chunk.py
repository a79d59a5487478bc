"""The compact collision kernel's chunking (issue 11, item 2): the work is sent through the estimator in full
chunks of ``chunk_rows`` items and then a tail of 64-item chunks (``collision.TAIL_ROWS``), so a small problem
does not pay for a 512-row chunk.  Every item's value is the same whichever chunk computes it: the collision
costs (and ``C_future``) must be identical for every chunk size.  Tested with the Cross-Entropy estimator, the
expensive one the issue measured (the chunking is the same code for every estimator)."""

from __future__ import annotations

import functools

import jax
import numpy as np

from psbmpc_jax import Capacities, Planner, PlannerConfig
from psbmpc_jax.costs import collision as col
from psbmpc_jax.evaluate import context

from conftest import SMALL_BEHAVIOURS, random_situation

#: A short horizon and a small Cross-Entropy budget keep the compile of every chunk size quick; the behaviour
#: capacity is the table's size (30), so the item count is not a multiple of 64.
BASE = dict(T=10.0, dt=0.5, dtype="float64", estimator="ce", n_samples=64, ce_max_iter=1, time_block=3)


def test_chunk_size_does_not_change_the_answers():
    cfg = PlannerConfig(**BASE)
    planner = Planner(cfg, behaviours=SMALL_BEHAVIOURS, capacities=Capacities(behaviours=len(SMALL_BEHAVIOURS)))
    inputs, state, params, samples = planner.prepare(random_situation(4, T=cfg.T), key=jax.random.key(4))
    ctx = jax.jit(lambda i, l, p: context(i, l, p, cfg))(inputs, state.last_offsets, params)._replace(dense=False)

    def kernel(chunk_rows: int):
        c = cfg.replace(chunk_rows=chunk_rows)
        out = jax.jit(lambda params, samples: col.collision_kernel(ctx, params, c, samples))(params, samples)
        cost, future, n_items = jax.device_get(out)
        return np.asarray(cost), np.asarray(future), int(n_items)

    # 512: a full bulk chunk, then the 64-row tail; 25: below the tail size (one loop of 25-row chunks)
    outs = {cr: kernel(cr) for cr in (512, 25)}
    c0, f0, n0 = outs[512]
    assert 512 < n0 < 1024 and (n0 % 512) % 64 and n0 % 25, n0      # partial chunks in every loop
    assert np.count_nonzero(c0) > 10 and np.all(f0 <= c0)
    # bit equality on the CPU; a GPU fuses each chunk shape differently (FMA contraction), and an H100 gave
    # 1-ulp differences (3.4e-16 relative) between 512- and 25-row chunks, so there a few ulp are allowed
    same = (np.testing.assert_array_equal if jax.default_backend() == "cpu"
            else functools.partial(np.testing.assert_allclose, rtol=8 * np.finfo(np.float64).eps, atol=0))
    for cr, (c, f, n) in outs.items():
        assert n == n0
        same(c, c0, err_msg=f"chunk_rows={cr}")
        same(f, f0, err_msg=f"chunk_rows={cr}")
