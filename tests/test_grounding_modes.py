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


def star(rng, n, cx, cy, r_min, r_max):
    ang = (np.arange(n) + rng.uniform(-0.3, 0.3, n)) * (2 * np.pi / n)
    rad = rng.uniform(r_min, r_max, n)
    return np.stack([cx + rad * np.cos(ang), cy + rad * np.sin(ang)], axis=-1)


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
    rng = np.random.default_rng(seed)
    own = OwnShip([0.0, 0.0, 0.0, 2.0], [[0.0, 0.0], [500.0, 0.0]], 2.0)
    polys = channel() + (star(rng, 12, rng.uniform(50, 250), rng.uniform(-25, 25), 2.0, 8.0),)
    sit = Situation(own, (Obstacle([200.0, 5.0, -2.0, 0.0], np.diag([4.0, 4.0, 0.1, 0.1]), n_ps=3),), polys)
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


def test_grid_bad_input():
    with pytest.raises(ValueError, match="grounding_mode"):
        PlannerConfig(grounding_mode="fast")
    with pytest.raises(ValueError, match="grid_spacing"):
        PlannerConfig(grid_spacing=0.0)
    with pytest.raises(ValueError, match="at least one polygon"):
        build_distance_grid([], 1.0)
    with pytest.raises(ValueError, match="max_cells"):
        build_distance_grid(channel(), spacing=0.01, max_cells=1000)
