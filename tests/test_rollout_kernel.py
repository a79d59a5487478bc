"""The Pallas rollout kernel (psbmpc_jax/rollout_kernel.py) against the lax.scan rollout, float64, in Pallas's
interpreter on the CPU: own-ship rollouts (one shared path, rows beyond one block, a waypoint switch), obstacle
scenarios (a path per row, lateral offsets, leg speeds), the segments; a solve with the kernel equals the scan's;
the depth report counts the kernel as one launch with no loop steps."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from psbmpc_jax import Planner, PlannerConfig
from psbmpc_jax.depth import sequential_depth_only
from psbmpc_jax.ownship import los_rollout, make_path, pallas_available
from psbmpc_jax.rollout_kernel import ROWS, los_rollout_kernel
from psbmpc_jax.solve import solve

from conftest import SMALL_BEHAVIOURS, random_situation


def _compare(got, want):
    for g, w in zip(got, want):
        np.testing.assert_allclose(np.asarray(g), np.asarray(w), rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("per_row, speeds", [(False, False), (True, False), (True, True)])
def test_kernel_equals_the_scan(per_row, speeds):
    rng = np.random.default_rng(1 + per_row + 2 * speeds)
    n, rows = 37, ROWS + 21                                         # two blocks, the second partly padding
    x0 = jnp.asarray(np.c_[rng.normal(0, 5, (rows, 2)), rng.uniform(-np.pi, np.pi, rows), rng.uniform(0.5, 3, rows)])
    wx = np.array([[0.0, 30.0, 45.0, 90.0]])
    wy = np.array([[0.0, 5.0, 40.0, 60.0]])
    if per_row:                                                     # every row its own path, 3 or 4 waypoints
        wx = wx + rng.normal(0, 2, (rows, 4))
        wy = wy + rng.normal(0, 2, (rows, 4))
        count = rng.integers(3, 5, rows)
    else:
        count = np.array([4])
    path = make_path(jnp.asarray(wx), jnp.asarray(wy), jnp.asarray(count, jnp.int32))
    chi = jnp.asarray(rng.uniform(-0.8, 0.8, (n, rows)))
    u = jnp.asarray(rng.uniform(0.0, 3.0, (n, rows)))
    lat = jnp.asarray(rng.uniform(-10, 10, rows)) if per_row else jnp.zeros(rows)
    seg = jnp.asarray(np.where(rng.uniform(size=(rows, 4)) < 0.5, rng.uniform(0.5, 2.5, (rows, 4)), -1.0)) \
        if speeds else None
    args = (x0, path, chi, u, lat, 8.0, 6.0, 3.0, 5.0, 0.5)
    want, want_z = los_rollout(*args, return_segment=True, seg_speed=seg)
    got = los_rollout_kernel(*args, seg_speed=seg, interpret=True)
    _compare(got[:6], want)
    np.testing.assert_array_equal(np.asarray(got[6]), np.asarray(want_z))
    assert np.asarray(want_z).max() >= 1                                 # some row switched segment
    traj, z = los_rollout(*args, return_segment=True, seg_speed=seg, kernel="pallas")
    _compare(traj, want)


def test_a_solve_with_the_kernel_equals_the_scan_solve():
    sit = random_situation(4, T=20.0, n_polygons=1)
    out = {}
    for kernel in ("scan", "pallas"):
        cfg = PlannerConfig(T=20.0, dtype="float64", rollout_kernel=kernel)
        out[kernel], _ = Planner(cfg, behaviours=SMALL_BEHAVIOURS).plan(sit)
    np.testing.assert_allclose(out["pallas"].costs["total"], out["scan"].costs["total"], rtol=1e-12, atol=1e-12)
    assert out["pallas"].best_index == out["scan"].best_index
    np.testing.assert_allclose(out["pallas"].own_trajectories, out["scan"].own_trajectories, rtol=0, atol=1e-9)


def test_depth_counts_the_kernel_as_one_launch():
    cfg = PlannerConfig(T=20.0, dtype="float64", rollout_kernel="pallas", layout_platform="gpu")
    planner = Planner(cfg, behaviours=SMALL_BEHAVIOURS)
    r = sequential_depth_only(functools.partial(solve, config=cfg), *planner.prepare(random_situation(4, T=20.0)))
    assert r.depth == 0 and [(s.kind, s.executions) for s in r.sites] == [("kernel", 2)]   # own-ship, obstacles


def test_no_compiled_kernel_on_the_cpu_and_bad_kernel_names():
    assert pallas_available("cpu") is False
    x0 = jnp.zeros((3, 4))
    path = make_path(jnp.asarray([[0.0, 10.0]]), jnp.asarray([[0.0, 0.0]]), jnp.asarray([2], jnp.int32))
    with pytest.raises(ValueError, match="z0 needs 'scan'"):
        los_rollout(x0, path, jnp.zeros((4, 3)), jnp.ones((4, 3)), jnp.zeros(3), 5.0, 2.0, 1.0, 1.0, 0.5,
                    z0=jnp.zeros(3, jnp.int32), kernel="pallas")
    with pytest.raises(ValueError, match="PlannerConfig.rollout_kernel must be one of"):
        PlannerConfig(rollout_kernel="cuda")


def test_self_check_runs_eagerly_inside_a_trace():
    """The refinement resolves the rollout layout while tracing; the kernel's self-check must still give a Python
    bool there (it raised TracerBoolConversionError on an H200 and sent the GPU to the scan)."""
    from psbmpc_jax.ownship import _self_check

    seen = []

    @jax.jit
    def traced(x):
        seen.append(_self_check(interpret=True))
        return x + 1.0

    traced(jnp.float32(0.0))
    assert seen == [True]
