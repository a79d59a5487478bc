"""COLREGS CROSSED needs a moving own-ship (docs/algorithm.md §8): a vanishing velocity must not classify."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from psbmpc_jax import Params, Planner, PlannerConfig, paper_behaviours
from psbmpc_jax import reference as ref_mod
from psbmpc_jax.costs.colregs import violation


@pytest.mark.parametrize("speed", [0.0, 1e-56, 1e-30, 0.04])
def test_stopped_own_ship_never_violates_crossing(speed):
    # obstacle 30 m ahead and 10 m to starboard, coming head-on: CLOSE and STARBOARD hold
    args = dict(dx=jnp.array(30.0), dy=jnp.array(10.0), v0x=jnp.array(speed), v0y=jnp.array(0.0),
                vix=jnp.array(-2.0), viy=jnp.array(0.0), cos_chi=jnp.array(1.0), sin_chi=jnp.array(0.0),
                d_close=100.0)
    assert not bool(violation(**args))
    # ... while a moving own-ship in the same geometry does violate
    assert bool(violation(**{**args, "v0x": jnp.array(1.0)}))
    own = np.array([[0.0, 0.0, 0.0, speed]] * 2)
    obs = np.array([[30.0, 10.0, np.pi, 2.0]] * 2)
    assert not np.any(ref_mod.colregs_violation(own, obs, Params()))


def test_float32_and_float64_agree_on_a_stopping_behaviour():
    """The benchmark found this: on the Nidelva head-on, 'stop, 0 deg' got +kappa in float64 only."""
    from psbmpc_jax.examples import nidelva_head_on

    sit = nidelva_head_on(n_ps=1)
    beh = paper_behaviours(1)
    r64, _ = Planner(PlannerConfig(dtype="float64", T=80.0), behaviours=beh).plan(sit)
    r32, _ = Planner(PlannerConfig(dtype="float32", T=80.0), behaviours=beh).plan(sit)
    np.testing.assert_array_equal(r64.costs["colregs"], r32.costs["colregs"])
    assert r32.best_index == r64.best_index
