"""The stop remedy of the Boolean COLREGS indicator (``PlannerConfig.stop_remedy``, docs/methods/psbmpc.md "The
stop loophole"): the published test exempts a stopped own-ship; ``"colregs_heading"`` evaluates it on the heading
whatever the speed.  Float64 oracle (:func:`psbmpc_jax.reference.colregs_violation_heading`, written in angles)
against the JAX indicator, the PSB-MPC term and the 2020 term; the published test kept as the default; the
setting read from a scenario file and refused when wrong."""

from __future__ import annotations

import copy
import math
import pathlib

import jax.numpy as jnp
import numpy as np
import pytest
import yaml

from psbmpc_jax import Params, PlannerConfig
from psbmpc_jax import reference as ref_mod
from psbmpc_jax.behaviours import enumerate_behaviours_deg
from psbmpc_jax.costs import mcskf as mk
from psbmpc_jax.costs.colregs import STOP_REMEDIES, violation
from psbmpc_jax.costs.sbmpc import colregs_boolean_xy
from psbmpc_jax.evaluate import DEFAULT_TERMS, evaluate
from psbmpc_jax.packing import pack
from psbmpc_jax.params import STOP_REMEDIES as CONFIG_STOP_REMEDIES
from psbmpc_jax.situation import Obstacle, OwnShip, Situation


def random_pairs(rng, n, own_speed):
    """(own [n, 4], obstacle [n, 4]) states (x, y, χ, U): obstacles within 150 m, any course, 0-5 m/s."""
    own = np.column_stack([rng.uniform(-50, 50, n), rng.uniform(-50, 50, n), rng.uniform(-np.pi, np.pi, n),
                           np.broadcast_to(own_speed, (n,))])
    r, b = rng.uniform(1.0, 150.0, n), rng.uniform(-np.pi, np.pi, n)
    obs = np.column_stack([own[:, 0] + r * np.cos(b), own[:, 1] + r * np.sin(b), rng.uniform(-np.pi, np.pi, n),
                           rng.uniform(0.0, 5.0, n)])
    return own, obs


def jax_violation(own, obs, d_close, heading):
    c, s = np.cos(own[:, 2]), np.sin(own[:, 2])
    ci, si = np.cos(obs[:, 2]), np.sin(obs[:, 2])
    out = violation(jnp.asarray(obs[:, 0] - own[:, 0]), jnp.asarray(obs[:, 1] - own[:, 1]),
                    jnp.asarray(own[:, 3] * c), jnp.asarray(own[:, 3] * s), jnp.asarray(obs[:, 3] * ci),
                    jnp.asarray(obs[:, 3] * si), jnp.asarray(c), jnp.asarray(s), d_close, heading=heading)
    return np.asarray(out)


def test_the_two_lists_of_remedies_are_one():
    assert STOP_REMEDIES == CONFIG_STOP_REMEDIES == ("none", "colregs_heading")
    assert PlannerConfig().stop_remedy == "none"           # the papers' cost is the default


@pytest.mark.parametrize("own_speed", [0.0, 1e-30, 0.03, 0.5, 2.0, 9.0])
def test_jax_heading_test_equals_the_float64_oracle(own_speed):
    own, obs = random_pairs(np.random.default_rng(1), 4000, own_speed)
    want = np.array([ref_mod.colregs_violation_heading(o, b, 100.0) for o, b in zip(own, obs)])
    got = jax_violation(own, obs, 100.0, heading=True)
    np.testing.assert_array_equal(got, want)
    assert 100 < want.sum() < 3900                        # both outcomes are exercised


@pytest.mark.parametrize("own_speed", [0.06, 0.5, 2.0, 9.0])
def test_a_moving_own_ship_gets_the_published_test(own_speed):
    """For ‖v_0‖ > 0.05 m/s the remedy changes nothing: oracle-heading = oracle-published = JAX-published."""
    own, obs = random_pairs(np.random.default_rng(2), 4000, own_speed)
    published = np.array([bool(ref_mod.colregs_violation(o[None], b[None], Params(d_close=100.0))[0])
                          for o, b in zip(own, obs)])
    heading = np.array([ref_mod.colregs_violation_heading(o, b, 100.0) for o, b in zip(own, obs)])
    np.testing.assert_array_equal(heading, published)
    np.testing.assert_array_equal(jax_violation(own, obs, 100.0, heading=False), published)


@pytest.mark.parametrize("own_speed", [0.0, 1e-56, 0.04])
def test_a_stopped_give_way_ship_violates_only_with_the_remedy(own_speed):
    """A target 60 m off the starboard bow crossing from starboard (give-way for the own-ship), and one coming
    head-on 10 m to starboard: the published test exempts the stopped ship, the remedy does not."""
    own = np.array([[0.0, 0.0, 0.0, own_speed]] * 2)
    obs = np.array([[40.0, 45.0, -math.pi / 2, 3.0],          # crossing from starboard
                    [30.0, 10.0, math.pi, 2.0]])              # head-on, on the starboard bow
    assert not np.any(ref_mod.colregs_violation(own, obs, Params()))
    assert np.all(ref_mod.colregs_violation(own, obs, Params(), stop_remedy="colregs_heading"))
    assert not np.any(jax_violation(own, obs, 100.0, heading=False))
    assert np.all(jax_violation(own, obs, 100.0, heading=True))
    # the 2020 / SB-MPC form (states in, float out) agrees
    mu = colregs_boolean_xy(*(jnp.asarray(own[:, k]) for k in range(4)), *(jnp.asarray(obs[:, k]) for k in range(4)),
                            100.0, heading=True)
    np.testing.assert_array_equal(np.asarray(mu), [1.0, 1.0])


def test_a_stopped_ship_is_still_overtaken():
    """A faster target from astern on the same course overtakes a stopped ship: no violation either way."""
    own = np.array([[0.0, 0.0, 0.0, 0.0]])
    obs = np.array([[-20.0, 5.0, 0.1, 2.0]])
    assert not ref_mod.colregs_violation(own, obs, Params(), stop_remedy="colregs_heading")[0]
    assert not jax_violation(own, obs, 100.0, heading=True)[0]


def crossing_situation(speed=0.0):
    """A give-way crossing: the own-ship (stopped by default) on a route north at 2 m/s, a target from starboard
    heading west, and one head-on."""
    cov = np.diag([4.0, 4.0, 0.05, 0.05])
    own = OwnShip(state=[0.0, 0.0, 0.0, speed], waypoints=np.array([[0.0, 0.0], [1000.0, 0.0]]), U_d=2.0,
                  length=5.0, width=3.0)
    obstacles = (Obstacle(state=[70.0, 60.0, 0.0, -2.0], cov=cov, length=5.0, width=3.0, n_ps=3),
                 Obstacle(state=[120.0, 8.0, -2.0, 0.0], cov=cov, length=5.0, width=3.0, n_ps=1))
    return Situation(own, obstacles)


@pytest.mark.parametrize("remedy", STOP_REMEDIES)
def test_psbmpc_colregs_term_equals_the_reference(remedy):
    cfg = PlannerConfig(T=60.0, dt=1.0, dtype="float64", stop_remedy=remedy)
    sit = crossing_situation()
    beh = enumerate_behaviours_deg(((1.0, 0.5, 0.0),), ((-60, -30, 0, 30, 60),))
    ev = evaluate(pack(sit, beh, cfg), jnp.asarray([1.0, 0.0]), Params(), None, config=cfg, terms=DEFAULT_TERMS)
    ref = ref_mod.evaluate_reference(sit, beh, Params(), cfg)
    got = np.asarray(ev.costs["colregs"])[: len(beh)]
    np.testing.assert_array_equal(got, ref.colregs)
    np.testing.assert_allclose(np.asarray(ev.total)[: len(beh)], ref.total, rtol=1e-9, atol=1e-9)
    stops = np.flatnonzero(np.asarray(beh)[:, 0, 0] == 0.0)
    if remedy == "none":
        assert np.all(ref.colregs[stops] == 0.0)            # the loophole: every stop is free of COLREGS
    else:
        assert np.all(ref.colregs[stops] > 0.0)             # ... and no longer with the remedy


@pytest.mark.parametrize("remedy", STOP_REMEDIES)
def test_psbmpc2020_term_equals_the_reference(remedy):
    cfg = PlannerConfig(T=40.0, dt=1.0, dtype="float64", stop_remedy=remedy)
    sit = crossing_situation()
    beh = enumerate_behaviours_deg(((1.0, 0.0),), ((-60, 0, 30),))
    term = mk.Psbmpc2020Term(n_mc=20, seed=3, d_safe=10.0, d_cl=100.0)
    ev = evaluate(pack(sit, beh, cfg), jnp.asarray([1.0, 0.0]), Params(), None, config=cfg, terms=(term,))
    ref = ref_mod.evaluate_reference(sit, beh, Params(), cfg, extra_terms=(term,))
    got = np.asarray(ev.costs["psbmpc2020"])[: len(beh)]
    np.testing.assert_allclose(got, ref.extra["psbmpc2020"], rtol=1e-10, atol=1e-12)
    col = np.asarray(ev.details["psbmpc2020_colregs_i"])[: len(beh)]
    stop_0deg = int(np.flatnonzero((np.asarray(beh)[:, 0, 0] == 0.0) & (np.asarray(beh)[:, 0, 1] == 0.0))[0])
    assert (col[stop_0deg].sum() > 0) == (remedy == "colregs_heading")


def test_refinement_fuzzy_colregs_has_no_speed_guard():
    """The gradient refinement replaces the Boolean term by FIS_colregs of (Δχ, bearing, distance): no speed
    enters it, so its smooth COLREGS cost never had the loophole and needs no remedy (nor a new gradient)."""
    from psbmpc_jax.costs.colregs_fuzzy import encounter_inputs_xy, fis_colregs

    own = jnp.asarray([0.0, 0.0, 0.0])
    tgt = jnp.asarray([40.0, 45.0, -math.pi / 2])
    mu = fis_colregs(*encounter_inputs_xy(*own, *tgt), d_cl=100.0)
    assert float(mu) > 0.5
    import inspect

    assert "U" not in inspect.signature(encounter_inputs_xy).parameters


def test_the_scenario_file_selects_and_validates_the_remedy():
    from psbmpc_jax.scenario import scenario_from_dict
    import psbmpc_jax

    d = yaml.safe_load((pathlib.Path(psbmpc_jax.__file__).parent / "scenarios" / "tengesdal2020_b.yaml").read_text())
    assert scenario_from_dict(copy.deepcopy(d)).mpc.config.stop_remedy == "none"
    d["mpc"]["config"] = {"stop_remedy": "colregs_heading"}
    assert scenario_from_dict(copy.deepcopy(d)).mpc.config.stop_remedy == "colregs_heading"
    d["mpc"]["config"] = {"stop_remedy": "heading"}
    with pytest.raises(ValueError, match=r"stop_remedy must be one of \('none', 'colregs_heading'\), got 'heading'"):
        scenario_from_dict(d)
    with pytest.raises(ValueError, match="stop_remedy"):
        PlannerConfig(stop_remedy=None)
    with pytest.raises(ValueError, match="stop_remedy must be one of"):
        ref_mod.colregs_violation(np.zeros((1, 4)), np.ones((1, 4)), Params(), stop_remedy="on")


# ============================================================================ closed loop
def test_closed_loop_a_stopping_give_way_ship_does_not_escape_colregs_with_the_remedy():
    """The congested-traffic scenario (``tengesdal2020_b``), ``psbmpc_2020``, its first 30 s: with the published
    cost the own-ship stops from the 15 s update on and the stop behaviour it picks carries no COLREGS cost at the
    updates where it is nearly stopped (the loophole); with the remedy the same stop behaviour carries COLREGS cost
    there and the own-ship sets off again before 30 s."""
    import dataclasses

    from psbmpc_jax.scenario import load_scenario
    from psbmpc_jax.sim import simulate

    seen = {}
    for remedy in STOP_REMEDIES:
        sc = load_scenario("tengesdal2020_b")
        sc = dataclasses.replace(sc, duration=30.0, mpc=dataclasses.replace(
            sc.mpc, config=sc.mpc.config.replace(stop_remedy=remedy)))
        import psbmpc_jax.methods.grid as grid

        original, evals = grid.solve, []

        def recording(*a, **kw):
            out = original(*a, **kw)
            evals.append((np.asarray(out[2].total), np.asarray(out[2].details["psbmpc2020_colregs_i"])))
            return out

        grid.solve = recording
        try:
            res = simulate(sc, runs=1, progress=False, batch="loop")
        finally:
            grid.solve = original
        beh = np.asarray(sc.mpc.behaviours)
        stop_0 = int(np.flatnonzero((beh[:, 0, 0] == 0.0) & (beh[:, 0, 1] == 0.0))[0])
        k = np.searchsorted(res.t, res.solve_t)
        seen[remedy] = dict(u=res.offsets[0, 0, :, 0], speed=res.states[0, 0, k, 3],
                            stop_colregs=np.array([c[stop_0].sum() for _, c in evals]))
    paper, fixed = seen["none"], seen["colregs_heading"]
    slow = paper["speed"] < 3.5                                    # the updates at 20 s and 25 s
    assert slow.sum() >= 2 and np.all(paper["u"][slow] == 0.0)     # the published cost keeps it stopping ...
    assert np.all(paper["stop_colregs"][slow] == 0.0)              # ... where stopping is free of COLREGS
    assert np.all(fixed["stop_colregs"][slow] > 0.0)               # the remedy charges the same stop
    assert np.any(fixed["u"][slow] > 0.0) and fixed["speed"][-1] > 2.0    # and the own-ship sets off again
