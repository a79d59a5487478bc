"""Fast grounding mode (nearest-land distance grid) against the exact kernel, and grounding behaviour."""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
import pytest
import shapely
from shapely.geometry import Polygon

from psbmpc_jax import Obstacle, OwnShip, Params, Planner, PlannerConfig, Situation, paper_behaviours
from psbmpc_jax.distance_grid import build_distance_grid, interpolate, relative_error_bound

from conftest import star


def channel_situation(seed):
    """The channel with a random star-shaped island and one obstacle ahead (3 scenarios)."""
    rng = np.random.default_rng(seed)
    own = OwnShip([0.0, 0.0, 0.0, 2.0], [[0.0, 0.0], [500.0, 0.0]], 2.0)
    polys = channel() + (star(rng, 12, rng.uniform(50, 250), rng.uniform(-25, 25), 2.0, 8.0),)
    return Situation(own, (Obstacle([200.0, 5.0, -2.0, 0.0], np.diag([4.0, 4.0, 0.1, 0.1]), n_ps=3),), polys)


def channel():
    """A straight north-going channel 60 m wide (east in [-30, 30]) between two banks, and a rock."""
    west = np.array([[-100.0, -200.0], [600.0, -200.0], [600.0, -30.0], [-100.0, -30.0]])
    east = np.array([[-100.0, 30.0], [600.0, 30.0], [600.0, 200.0], [-100.0, 200.0]])
    rock = star(np.random.default_rng(5), 9, 300.0, 15.0, 3.0, 6.0)
    return (west, east, rock)


@pytest.mark.parametrize("spacing", [0.5, 2.0])
def test_grid_distance_within_lipschitz_bound(spacing):
    rng = np.random.default_rng(0)
    polys = (star(rng, 30, 0.0, 0.0, 20.0, 60.0), star(rng, 7, 150.0, 40.0, 5.0, 15.0))
    grid = build_distance_grid(polys, spacing=spacing, margin=30.0, dtype=np.float64)
    pts = rng.uniform(-100, 200, size=(4000, 2))
    d, _, _ = interpolate(grid, jnp.asarray(pts[:, 0]), jnp.asarray(pts[:, 1]))
    union = shapely.union_all([Polygon(p) for p in polys])
    exact = shapely.distance(shapely.points(pts), union)
    in_grid = np.all((pts >= np.asarray(grid.origin)) &
                     (pts <= np.asarray(grid.origin) + spacing * (np.array(grid.values.shape) - 1)), axis=1)
    err = np.abs(np.asarray(d) - exact)[in_grid]
    assert err.max() <= spacing / math.sqrt(2) + 1e-9
    assert err.max() > 0  # it is an approximation: a zero error everywhere would mean the test is vacuous
    # outside the grid the distance is the margin, a lower bound of the true distance
    assert np.all(np.asarray(d)[~in_grid] == 30.0) and np.all(exact[~in_grid] >= 30.0 - 1e-9)


@pytest.mark.parametrize("seed", [0, 1])
def test_grid_mode_cost_within_documented_bound(seed):
    sit = channel_situation(seed)
    beh = paper_behaviours(1)
    base = dict(T=60.0, dt=0.5, dtype="float64")
    exact, _ = Planner(PlannerConfig(**base), behaviours=beh).plan(sit)
    for spacing in (0.25, 1.0):
        fast, _ = Planner(PlannerConfig(grounding_mode="grid", grid_spacing=spacing, **base),
                          behaviours=beh).plan(sit)
        ratio = fast.costs["so"] / exact.costs["so"]
        bound = relative_error_bound(spacing, Params().G3)
        assert np.all(np.abs(ratio - 1.0) <= bound + 1e-9), (spacing, ratio.min(), ratio.max(), bound)
        for term in ("do", "colregs", "path"):
            np.testing.assert_allclose(fast.costs[term], exact.costs[term], rtol=1e-12)
        assert fast.grounding_per_polygon.shape == (len(beh), 0)


def test_grid_mode_without_land_costs_nothing():
    own = OwnShip([0.0, 0.0, 0.0, 2.0], [[0.0, 0.0], [500.0, 0.0]], 2.0)
    res, _ = Planner(PlannerConfig(T=20.0, grounding_mode="grid"), behaviours=paper_behaviours(1)).plan(
        Situation(own))
    assert np.all(res.costs["so"] == 0.0)


@pytest.mark.parametrize("mode", ["exact", "grid"])
def test_driving_into_the_bank_costs_more_than_staying_in_the_channel(mode):
    own = OwnShip([0.0, 0.0, 0.0, 2.0], [[0.0, 0.0], [500.0, 0.0]], 2.0)
    sit = Situation(own, (), channel())
    beh = paper_behaviours(1)
    res, _ = Planner(PlannerConfig(T=100.0, grounding_mode=mode), behaviours=beh).plan(sit)
    so = res.costs["so"]
    deg = np.rad2deg(beh[:, 0, 1])
    full = beh[:, 0, 0] == 1.0
    pick = lambda a: so[full & np.isclose(deg, a)][0]
    straight, hard_port, hard_stbd = pick(0.0), pick(-60.0), pick(60.0)
    assert hard_port > 10 * straight and hard_stbd > 10 * straight
    # and the planner keeps to the channel
    assert abs(np.rad2deg(res.chi_opt)) <= 15


@pytest.mark.parametrize("seed", [0, 1])
def test_dense_grounding_search_gives_the_culled_plan(seed):
    """PlannerConfig.grounding_search="dense" (the GPU layout) changes how the worst time step is found, not
    the costs: every behaviour's costs and the chosen behaviour equal the culled search's."""
    sit = channel_situation(seed)
    beh = paper_behaviours(1)
    base = dict(T=60.0, dt=0.5, dtype="float64")
    culled, _ = Planner(PlannerConfig(**base), behaviours=beh).plan(sit)
    dense, _ = Planner(PlannerConfig(grounding_search="dense", **base), behaviours=beh).plan(sit)
    for term in culled.costs:
        np.testing.assert_allclose(dense.costs[term], culled.costs[term], rtol=1e-12, atol=0)
    np.testing.assert_allclose(dense.grounding_per_polygon, culled.grounding_per_polygon, rtol=1e-12, atol=0)
    assert dense.best_index == culled.best_index and np.max(culled.costs["so"]) > 0


def test_grid_bad_input():
    with pytest.raises(ValueError, match="grounding_search must be one of"):
        PlannerConfig(grounding_search="fast")
    with pytest.raises(ValueError, match="grounding_mode"):
        PlannerConfig(grounding_mode="fast")
    with pytest.raises(ValueError, match="grid_spacing"):
        PlannerConfig(grid_spacing=0.0)
    with pytest.raises(ValueError, match="at least one polygon"):
        build_distance_grid([], 1.0)
    with pytest.raises(ValueError, match="max_cells"):
        build_distance_grid(channel(), spacing=0.01, max_cells=1000)


# ---------------------------------------------------------------------------------------- real chart
@pytest.fixture(scope="module")
def nidelva_chart():
    from psbmpc_jax.charts import nidelva_own_ship_ned, trondheim_chart
    from psbmpc_jax.rdp import simplify_chart

    chart = simplify_chart(trondheim_chart("psbmpc"), 2.0)
    return chart, np.asarray(nidelva_own_ship_ned(chart), dtype=float)


def _water_situations(chart, centre, n, seed):
    """Random own-ship positions in open water within 150 m of the Nidelva point, random courses, the chart
    range-filtered to d_so = 200 m around each."""
    from psbmpc_jax.charts import range_filter, to_ring_sets

    land = shapely.union_all(list(chart.polygons))
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        p = centre + rng.uniform(-150, 150, 2)
        if land.distance(shapely.Point(p)) < 8.0:
            continue
        course = rng.uniform(-np.pi, np.pi)
        near = range_filter(chart, p, 200.0)
        own = OwnShip([p[0], p[1], course, 2.0], [p, p + 300.0 * np.array([np.cos(course), np.sin(course)])], 2.0)
        ob = Obstacle([p[0] + 60 * np.cos(course), p[1] + 60 * np.sin(course), -2 * np.cos(course),
                       -2 * np.sin(course)], np.diag([4.0, 4.0, 0.1, 0.1]), n_ps=3)
        out.append(Situation(own, (ob,), tuple(to_ring_sets(near.polygons))))
    return out


def test_exact_grounding_matches_reference_on_trondheim_polygons(nidelva_chart):
    from psbmpc_jax import reference as ref_mod

    chart, centre = nidelva_chart
    beh = paper_behaviours(1)
    cfg = PlannerConfig(T=40.0, dt=0.5, dtype="float64")
    planner = Planner(cfg, behaviours=beh)
    for sit in _water_situations(chart, centre, 3, seed=1):
        assert len(sit.polygons) >= 1
        res, _ = planner.plan(sit)
        ref = ref_mod.evaluate_reference(sit, beh, Params(), cfg)
        np.testing.assert_allclose(res.grounding_per_polygon, ref.so_j, rtol=1e-5, atol=1e-12)
        for term in ("total", "so", "do", "colregs", "path"):
            np.testing.assert_allclose(res.costs[term], getattr(ref, term), rtol=1e-5, atol=1e-12, err_msg=term)
        assert res.best_index == ref.best


def test_grid_mode_within_bound_on_trondheim_chart(nidelva_chart):
    chart, centre = nidelva_chart
    beh = paper_behaviours(1)
    base = dict(T=60.0, dt=0.5, dtype="float64")
    bound = relative_error_bound(0.5, Params().G3)
    for sit in _water_situations(chart, centre, 2, seed=2):
        exact, _ = Planner(PlannerConfig(**base), behaviours=beh).plan(sit)
        fast, _ = Planner(PlannerConfig(grounding_mode="grid", **base), behaviours=beh).plan(sit)
        ratio = fast.costs["so"] / exact.costs["so"]
        assert np.all(np.abs(ratio - 1) <= bound + 1e-9), (ratio.min(), ratio.max())


def test_nidelva_bank_costs_more_than_the_channel():
    from psbmpc_jax.examples import nidelva_head_on

    sit = nidelva_head_on()
    sit = Situation(sit.own_ship, (), sit.polygons)       # grounding only
    beh = paper_behaviours(1)
    res, _ = Planner(PlannerConfig(T=150.0), behaviours=beh).plan(sit)
    so = res.costs["so"]
    deg = np.rad2deg(beh[:, 0, 1])
    full = beh[:, 0, 0] == 1.0
    pick = lambda a: so[full & np.isclose(deg, a)][0]
    # along the river (0 deg, the longest open-water run) is far cheaper than a hard turn into either bank
    assert pick(-60.0) > 5 * pick(0.0) and pick(60.0) > 5 * pick(0.0)
