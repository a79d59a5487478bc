"""Local origin (issue 11, item 1; docs/algorithm.md §11): device positions are relative to a local origin, so
float32 results do not depend on where the user's frame puts the situation — the same situation at the origin
and at UTM-sized coordinates gives the same costs, choice and (shifted back) trajectories, where packing the
raw UTM coordinates in float32 is visibly wrong."""

from __future__ import annotations

import numpy as np
import pytest

from psbmpc_jax import Planner, PlannerConfig
from psbmpc_jax.behaviours import paper_behaviours
from psbmpc_jax.examples import paper_head_on
from psbmpc_jax.packing import ORIGIN_SNAP, default_origin, pack, snap_origin, unpack
from psbmpc_jax.planner import RECENTRE_DISTANCE
from psbmpc_jax.situation import Obstacle, OwnShip, Situation
from psbmpc_jax.solve import solve

#: A UTM 32N position near Trondheim (north, east) [m]: float32 spacing there is 0.5 m (north) / 0.06 m (east).
UTM = np.array([7_035_254.0, 569_796.0])
#: Grid grounding: the planner builds the distance grid about its origin (the exact mode's polygons go through
#: the same shift in pack_world, checked below), and it compiles faster than the exact kernel.
CFG = PlannerConfig(T=100.0, dt=0.5, dtype="float32", grounding_mode="grid", grid_spacing=1.0)


def shifted(sit: Situation, offset) -> Situation:
    """``sit`` translated by ``offset`` (every position: own-ship, routes, obstacles, polygons)."""
    off = np.asarray(offset, float)
    o = sit.own_ship
    own = OwnShip(np.r_[o.state[:2] + off, o.state[2:]], o.waypoints + off, o.U_d, o.length, o.width)
    obs = tuple(Obstacle(np.r_[b.state[:2] + off, b.state[2:]], b.cov, b.length, b.width,
                         None if b.waypoints is None else b.waypoints + off, b.n_ps, b.probs, b.weight, b.zeta)
                for b in sit.obstacles)
    return Situation(own, obs, tuple(p + off for p in sit.polygons))


def head_on_with_land() -> Situation:
    """The paper head-on (two obstacles; one with a route) and an island to starboard."""
    base = paper_head_on()
    route = np.array([[400.0, -4.0], [150.0, 10.0], [-200.0, 10.0]])
    ob = base.obstacles[1]
    obstacles = (base.obstacles[0], Obstacle(ob.state, ob.cov, ob.length, ob.width, waypoints=route, n_ps=ob.n_ps))
    island = np.array([[60.0, 22.0], [60.0, 45.0], [95.0, 48.0], [100.0, 25.0]])
    return Situation(base.own_ship, obstacles, (island,))


def test_float32_results_do_not_depend_on_the_origin():
    beh = paper_behaviours(1)
    sit = head_on_with_land()
    far = shifted(sit, UTM)
    at_zero, _ = Planner(CFG, behaviours=beh).plan(sit)
    planner = Planner(CFG, behaviours=beh)
    at_utm, _ = planner.plan(far)
    np.testing.assert_array_equal(planner.origin, snap_origin(UTM))
    np.testing.assert_array_equal(at_utm.origin, planner.origin)
    assert at_zero.costs["do"].max() > 1.0 and at_zero.costs["so"].max() > 1.0      # both hazards interact
    # per-behaviour costs to float32 rounding (the two local frames differ by (254, -204) m), the same choice
    for term, want in at_zero.costs.items():
        np.testing.assert_allclose(at_utm.costs[term], want, rtol=2e-4, atol=2e-4 * np.abs(want).max(), err_msg=term)
    assert at_utm.best_index == at_zero.best_index
    # trajectories come back in the user's frame
    np.testing.assert_allclose(at_utm.own_trajectories[..., :2] - UTM, at_zero.own_trajectories[..., :2], atol=1e-2)
    np.testing.assert_allclose(at_utm.own_trajectories[..., 2:], at_zero.own_trajectories[..., 2:], atol=1e-4)
    for a, b in zip(at_utm.obstacle_trajectories, at_zero.obstacle_trajectories, strict=True):
        np.testing.assert_allclose(a[..., :2] - UTM, b[..., :2], atol=1e-2)

    # the same packing without the shift (origin (0, 0): raw UTM coordinates in float32) is what the issue saw
    # (the planner's grid, of the same shape: no recompile)
    raw = pack(far, beh, CFG, origin=(0.0, 0.0), grid=planner.distance_grid(far))
    plan, _, ev = solve(raw, *planner.prepare(far)[1:], config=CFG, terms=planner.terms)    # no recompile
    bad = unpack(ev, far, beh, 0.0, origin=(0.0, 0.0))
    err = np.abs(bad.costs["total"] - at_zero.costs["total"]) / np.abs(at_zero.costs["total"]).max()
    assert err.max() > 1e-2, err.max()
    assert np.abs(bad.own_trajectories[..., :2] - UTM - at_zero.own_trajectories[..., :2]).max() > 1.0


def test_pack_and_unpack_default_origin_round_trip():
    """pack / unpack without an origin use default_origin: the chart's centre (one origin for every solve over
    a chart, as stack/vmap needs), else the own-ship; solve + unpack returns the user's frame."""
    beh = paper_behaviours(1)
    far = shifted(head_on_with_land(), UTM + [206.0, 0.0])     # own-ship and island centre in different km cells
    o = default_origin(far)
    centre = 0.5 * (far.polygons[0].min(axis=0) + far.polygons[0].max(axis=0))
    np.testing.assert_array_equal(o, np.round(centre / ORIGIN_SNAP) * ORIGIN_SNAP)
    np.testing.assert_array_equal(default_origin(Situation(far.own_ship, far.obstacles)),
                                  snap_origin(far.own_ship.state[:2]))
    planner = Planner(CFG, behaviours=beh)
    want, _ = planner.plan(far)
    assert np.any(planner.origin != o)                      # the planner's origin is its own: another frame
    inputs = pack(far, beh, CFG, grid=planner.distance_grid(far))     # a grid in the user's frame, shifted by o
    np.testing.assert_allclose(np.asarray(inputs.own.state[:2], float), far.own_ship.state[:2] - o, atol=1e-3)
    np.testing.assert_allclose(np.asarray(inputs.world.polygons.vertices[0, :4], float), far.polygons[0] - o,
                               atol=1e-3)
    _, state, params, samples = planner.prepare(far)
    plan, _, ev = solve(inputs, state, params, samples, config=CFG, terms=planner.terms)
    got = unpack(ev, far, beh, 0.0)
    assert got.best_index == want.best_index == int(plan.best)
    np.testing.assert_allclose(got.own_trajectories[..., :2], want.own_trajectories[..., :2], atol=1e-2)
    with pytest.raises(ValueError, match="origin"):
        pack(far, beh, CFG, world=inputs.world)


def test_planner_origin_is_kept_until_the_own_ship_drifts_far():
    """The planner's origin (and with it the cached packed chart) stays while the own-ship is within
    RECENTRE_DISTANCE of it; grid mode builds the distance grid about it (cached per origin)."""
    beh = paper_behaviours(1)
    sit = shifted(head_on_with_land(), UTM)
    for mode in ("exact", "grid"):
        planner = Planner(CFG.replace(grounding_mode=mode), behaviours=beh)
        inputs, *_ = planner.prepare(sit)
        o, world = planner.origin.copy(), inputs.world
        near = shifted(sit, (0.6 * RECENTRE_DISTANCE, -0.6 * RECENTRE_DISTANCE))
        inputs2, *_ = planner.prepare(Situation(near.own_ship, near.obstacles, sit.polygons))   # same chart
        np.testing.assert_array_equal(planner.origin, o)
        if mode == "exact":
            assert inputs2.world is world                                        # cache hit
        np.testing.assert_allclose(np.asarray(inputs2.own.state[:2], float), near.own_ship.state[:2] - o, atol=1e-2)
        far = shifted(sit, (1.2 * RECENTRE_DISTANCE, 0.0))
        inputs3, *_ = planner.prepare(far)
        np.testing.assert_array_equal(planner.origin, snap_origin(far.own_ship.state[:2]))
        np.testing.assert_allclose(np.asarray(inputs3.world.polygons.vertices[0, :4], float),
                                   far.polygons[0] - planner.origin, atol=1e-3)
        if mode == "grid":
            g = inputs3.world.grid
            # the device grid's corner is local and its distances were computed about the origin: at the grid
            # node nearest to the island's first vertex (distance 0) the value is at most h/sqrt(2) (1-Lipschitz)
            corner = np.asarray(g.origin, float)
            assert np.all(np.abs(corner) < 2 * RECENTRE_DISTANCE)
            i, j = np.round((far.polygons[0][0] - planner.origin - corner) / float(g.spacing)).astype(int)
            assert float(np.asarray(g.values)[i, j]) <= float(g.spacing) / np.sqrt(2.0) + 1e-3
