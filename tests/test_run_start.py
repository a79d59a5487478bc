"""``simulate(..., run_start=a)``: runs [a, b) simulated alone equal the same runs of one bigger call bit for bit
(the measurement noise and route-exchange draws depend on the run's Monte Carlo index, not on its position in
the call), and bad values are refused naming the argument."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from psbmpc_jax.scenario import load_scenario
from psbmpc_jax.sim import simulate


@pytest.fixture(scope="module")
def scenario():
    return dataclasses.replace(load_scenario("crossing_give_way"), duration=40.0)


@pytest.fixture(scope="module")
def whole(scenario):
    return simulate(scenario, runs=3, seed=5)


@pytest.mark.parametrize("start,count", [(1, 2), (2, 1)])
def test_chunk_equals_same_runs_of_one_call(scenario, whole, start, count):
    part = simulate(scenario, runs=count, seed=5, run_start=start)
    rows = slice(start, start + count)
    for name in ("states", "track_x", "track_P", "offsets", "best_costs"):
        np.testing.assert_array_equal(getattr(part, name), getattr(whole, name)[rows], err_msg=name)
    assert part.run_start == start
    assert [m["run"] for m in part.metrics] == list(range(start, start + count))
    for a, b in zip(part.metrics, whole.metrics[rows]):
        assert a["targets"][0]["min_distance_m"] == b["targets"][0]["min_distance_m"]


def test_run_start_changes_the_draws(scenario, whole):
    """Run 0 of a call that starts at 1 is run 1, not run 0: the noise differs from run 0's."""
    part = simulate(scenario, runs=1, seed=5, run_start=1)
    assert not np.array_equal(part.track_x[0], whole.track_x[0])


@pytest.mark.parametrize("bad", [-1, 1.5, "2"])
def test_bad_run_start_is_refused(scenario, bad):
    with pytest.raises((ValueError, TypeError), match="run_start"):
        simulate(scenario, runs=1, seed=5, run_start=bad)


def test_chunk_equals_one_call_under_vmap_too(scenario):
    """With all solves of an update in one vmapped call the batch size changes with the chunk; the runs do not."""
    whole = simulate(scenario, runs=3, seed=5, batch="vmap")
    part = simulate(scenario, runs=2, seed=5, run_start=1, batch="vmap")
    np.testing.assert_array_equal(part.states, whole.states[1:])
    np.testing.assert_array_equal(part.offsets, whole.offsets[1:])
