"""The lower level's cost of the two-level MPC (psbmpc_jax/costs/zeta.py): the SB-MPC hazard with seed 001's
grounding cost ζ (eq. 15) joined per (time, target) inside the max, against its float64 reference (exact
polygon distances in NumPy), in both ζ shapes, with and without targets; without land it is the SB-MPC hazard."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from psbmpc_jax import reference as ref_mod
from psbmpc_jax.behaviours import enumerate_behaviours_deg
from psbmpc_jax.costs.sbmpc import SbmpcHazardTerm
from psbmpc_jax.costs.zeta import SbmpcZetaTerm, zeta_cost
from psbmpc_jax.evaluate import evaluate
from psbmpc_jax.packing import pack
from psbmpc_jax.params import Params, PlannerConfig
from psbmpc_jax.situation import Obstacle, OwnShip, Situation

SEARCH = enumerate_behaviours_deg(((1.0, 0.5, 0.0),), (tuple(range(-90, 91, 15)),))
CFG = PlannerConfig(T=60.0, dt=1.0, dtype="float64")
HAZARD = SbmpcHazardTerm(d_safe=20.0, risk="crisp", colregs="boolean", kappa=3.0, d_cl=200.0)


def situation(targets=True, land=True):
    own = OwnShip(state=[0.0, 0.0, 0.0, 4.0], waypoints=np.array([[0.0, 0.0], [600.0, 0.0]]), U_d=4.0)
    obs = (Obstacle([200.0, 5.0, -3.0, 0.0], np.diag([4.0, 4.0, 0.1, 0.1]), n_ps=1),
           Obstacle([120.0, -150.0, 0.5, 2.5], np.diag([4.0, 4.0, 0.1, 0.1]), n_ps=1)) if targets else ()
    bank = np.array([[-50.0, 40.0], [400.0, 40.0], [400.0, 80.0], [-50.0, 80.0]])
    islet = np.array([[150.0, -45.0], [175.0, -30.0], [160.0, -15.0], [140.0, -28.0]])
    return Situation(own, obs, (bank, islet) if land else ())


def costs(term, sit, last=(1.0, 0.0)):
    ev = evaluate(pack(sit, SEARCH, CFG), jnp.asarray(last), Params(), None, config=CFG, terms=(term,))
    ref = ref_mod.evaluate_reference(sit, SEARCH, Params(), CFG, last_offsets=last, extra_terms=(term,))
    return np.asarray(ev.costs[term.name])[: len(SEARCH)], np.asarray(ref.extra[term.name]), ev


@pytest.mark.parametrize("shape,targets", [("printed", True), ("psbmpc", True), ("printed", False)])
def test_zeta_joined_hazard_matches_its_float64_reference(shape, targets):
    term = SbmpcZetaTerm(hazard=HAZARD, eta1=0.25, eta2=0.01, d_safe_g=15.0, d_close=50.0, shape=shape)
    got, want, ev = costs(term, situation(targets=targets))
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)
    z = np.asarray(ev.details["zeta"])[: len(SEARCH)]
    assert np.ptp(z) > 0 and np.all(got >= z - 1e-12)          # land matters and the max includes ζ
    if not targets:
        np.testing.assert_allclose(got, z, rtol=0, atol=0)      # C-001-5: max_t ζ with no target


def test_without_land_it_is_the_sbmpc_hazard():
    sit = situation(land=False)
    got, _, _ = costs(SbmpcZetaTerm(hazard=HAZARD), sit)
    plain, _, _ = costs(HAZARD, sit)
    np.testing.assert_allclose(got, plain, rtol=0, atol=0)
    assert np.ptp(plain) > 0


def test_zeta_shapes():
    d = np.array([0.0, 5.0, 10.0, 15.0, 49.0, 51.0])
    t = np.full_like(d, 2.0)
    printed = np.asarray(zeta_cost(d, t, eta1=0.2, eta2=0.1, d_safe=10.0, d_close=50.0))
    np.testing.assert_allclose(printed, np.where(d <= 50, np.exp(-(0.2 * np.abs(d - 10) + 0.2)), 0.0), rtol=1e-12)
    assert np.argmax(printed) == 2                              # the printed form peaks at d_safe
    grow = np.asarray(zeta_cost(d, t, eta1=0.2, eta2=0.1, d_safe=10.0, d_close=50.0, shape="psbmpc"))
    assert np.all(np.diff(grow[:5]) < 0) and grow[-1] == 0.0     # the 003 form keeps growing towards land
    with pytest.raises(ValueError, match="shape"):
        zeta_cost(d, t, shape="abs")
    with pytest.raises(ValueError, match="d_close"):
        SbmpcZetaTerm(d_close=0.0)
    with pytest.raises(ValueError, match="aggregation='max'"):
        SbmpcZetaTerm(hazard=SbmpcHazardTerm(aggregation="sum"))
