"""Grid grounding: the derivative exactly on grid lines and cell corners.

The bilinear interpolant is continuous and piecewise bilinear; a point exactly on a grid line belongs to the
cell on its + side, so its derivative there is the one-sided derivative from the + side (from the − side on
the grid's last line).  These tests compare value and derivative with a float64 NumPy reference of that rule,
with one-sided finite differences, and — through the objective — with central differences of the float64
reference cost on a straight coast (where the interpolant is smooth across the lines).  Before the fix the
derivative was halved on every grid line (the 1/2 tie derivative of ``jnp.clip`` at its bounds).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from psbmpc_jax import OwnShip, Params, Planner, PlannerConfig, Situation
from psbmpc_jax import reference as ref_mod
from psbmpc_jax.distance_grid import DistanceGrid, build_distance_grid, interpolate
from psbmpc_jax.objective import objective, value_and_grad
from psbmpc_jax.reference_prediction import ownship_trajectory


def ref_bilinear(values, origin, h, margin, px, py):
    """float64 NumPy reference: (d, dd/dx, dd/dy) with the + side cell on a grid line (the − side cell on the
    last line), ``margin`` and a zero derivative outside the grid."""
    values = np.asarray(values, float)
    nx, ny = values.shape
    d, gx, gy = (np.zeros(np.shape(px)) for _ in range(3))
    for idx in np.ndindex(np.shape(px)):
        fx, fy = (px[idx] - origin[0]) / h, (py[idx] - origin[1]) / h
        if not (0 <= fx <= nx - 1 and 0 <= fy <= ny - 1):
            d[idx] = margin
            continue
        i, j = min(int(np.floor(fx)), nx - 2), min(int(np.floor(fy)), ny - 2)
        a, b = fx - i, fy - j
        v00, v10, v01, v11 = values[i, j], values[i + 1, j], values[i, j + 1], values[i + 1, j + 1]
        d[idx] = (1 - a) * (1 - b) * v00 + a * (1 - b) * v10 + (1 - a) * b * v01 + a * b * v11
        gx[idx] = ((1 - b) * (v10 - v00) + b * (v11 - v01)) / h
        gy[idx] = ((1 - a) * (v01 - v00) + a * (v11 - v10)) / h
    return d, gx, gy


def lattice_points(nx, ny, origin, h):
    """Points on grid lines and corners (exactly: binary-exact origin and spacing), and cell interiors."""
    xs = origin[0] + h * np.array([0.0, 1.0, 2.0, 3.5, nx - 2.0, nx - 1.5, nx - 1.0])
    ys = origin[1] + h * np.array([0.0, 1.0, 2.5, 4.0, ny - 2.0, ny - 1.0])
    return np.meshgrid(xs, ys, indexing="ij")


@pytest.mark.parametrize("h,origin", [(0.5, (-3.0, 1.5)), (0.25, (2.0, -1.25))])
def test_interpolate_derivative_on_grid_lines_and_corners(h, origin):
    rng = np.random.default_rng(3)
    nx, ny = 8, 7
    values = rng.uniform(0.0, 10.0, (nx, ny))
    grid = DistanceGrid(jnp.asarray(values), jnp.asarray(origin), jnp.asarray(h), jnp.asarray(30.0))
    px, py = lattice_points(nx, ny, origin, h)
    fx, fy = (px - origin[0]) / h, (py - origin[1]) / h
    assert np.all(fx == np.round(fx * 2) / 2) and np.any(fx == np.round(fx))     # points really on the lines
    d, gx, gy = (np.asarray(v) for v in interpolate(grid, jnp.asarray(px), jnp.asarray(py)))
    rd, rgx, rgy = ref_bilinear(values, origin, h, 30.0, px, py)
    np.testing.assert_allclose(d, rd, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(gx, rgx, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(gy, rgy, rtol=1e-12, atol=1e-12)
    # automatic derivative = the bilinear derivative of the same cell (= the reference), also on lines
    ax, ay = jax.grad(lambda x, y: jnp.sum(interpolate(grid, x, y)[0]), argnums=(0, 1))(jnp.asarray(px),
                                                                                       jnp.asarray(py))
    np.testing.assert_allclose(np.asarray(ax), rgx, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(np.asarray(ay), rgy, rtol=1e-12, atol=1e-12)
    # ... and one-sided finite differences of the reference: from the + side, from the − side on the last line
    eps = 1e-7
    sx = np.where(np.isclose(fx, nx - 1), -1.0, 1.0)
    sy = np.where(np.isclose(fy, ny - 1), -1.0, 1.0)
    fdx = (ref_bilinear(values, origin, h, 30.0, px + sx * eps, py)[0] - rd) / (sx * eps)
    fdy = (ref_bilinear(values, origin, h, 30.0, px, py + sy * eps)[0] - rd) / (sy * eps)
    np.testing.assert_allclose(np.asarray(ax), fdx, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(np.asarray(ay), fdy, rtol=1e-5, atol=1e-6)
    assert np.abs(rgx).min() > 0 or np.abs(rgx).max() > 1.0      # random values: real slopes, not vacuous


def test_interpolate_derivative_of_a_linear_field_is_the_field_slope_everywhere():
    """On a linear field the interpolant is the field: the derivative on every line and corner is its slope
    (central differences agree); the old clipped weights gave half of it on the lines."""
    h, origin, nx, ny = 0.5, (-2.0, -3.0), 9, 10
    xs, ys = np.meshgrid(origin[0] + h * np.arange(nx), origin[1] + h * np.arange(ny), indexing="ij")
    grid = DistanceGrid(jnp.asarray(3.0 * xs - 2.0 * ys + 40.0), jnp.asarray(origin), jnp.asarray(h),
                        jnp.asarray(100.0))
    px, py = lattice_points(nx, ny, origin, h)
    inner = (px > origin[0]) & (px < xs.max()) & (py > origin[1]) & (py < ys.max())
    ax, ay = jax.grad(lambda x, y: jnp.sum(interpolate(grid, x, y)[0]), argnums=(0, 1))(jnp.asarray(px),
                                                                                       jnp.asarray(py))
    np.testing.assert_allclose(np.asarray(ax)[inner], 3.0, rtol=1e-12)
    np.testing.assert_allclose(np.asarray(ay)[inner], -2.0, rtol=1e-12)
    np.testing.assert_allclose(np.asarray(ax), 3.0, rtol=1e-12)             # the edges too: one-sided = slope
    f = lambda x, y: float(interpolate(grid, jnp.asarray(x), jnp.asarray(y))[0])        # noqa: E731
    for x, y in zip(px[inner], py[inner]):
        assert (f(x + 1e-6, y) - f(x - 1e-6, y)) / 2e-6 == pytest.approx(3.0, rel=1e-6)
        assert (f(x, y + 1e-6) - f(x, y - 1e-6)) / 2e-6 == pytest.approx(-2.0, rel=1e-6)


# ----------------------------------------------------------------------------------------- through objective
#: A straight coast x + y/2 = 80 (north-east of the own-ship): the distance to it is linear in (x, y) on the
#: water side, so the grid interpolant is that distance exactly and smooth across the grid lines.
COAST = np.array([[80.0 + 150.0, -300.0], [80.0 - 150.0, 300.0], [600.0, 300.0], [600.0, -300.0]])
CFG = PlannerConfig(T=30.0, dt=0.5, dtype="float64", grounding_mode="grid", grid_spacing=1.0)


def coast_problem():
    own = OwnShip([0.0, 0.0, 0.0, 2.0], [[0.0, 0.0], [500.0, 0.0]], 2.0)
    sit = Situation(own, (), (COAST,))
    planner = Planner(CFG, behaviours=np.array([[[1.0, 0.0]]]))
    inputs, _, params, samples = planner.prepare(sit)
    return sit, inputs, params, samples


#: The last applied offsets: away from c's values, so that the path cost's kinks |u - u_last| and the port /
#: starboard switch of chi - chi_last are not at the checked point (its chi^2 kink at chi = 0 has slope 0).
LAST = (0.8, 0.1)


def reference_cost(sit, c, params=Params()):
    """float64 NumPy reference of so + path (no obstacles): exact distance = the grid's on this coast."""
    traj = ownship_trajectory(sit.own_ship, c, params, CFG)
    return ref_mod.grounding_cost(traj, COAST, params, CFG) + ref_mod.path_cost(c, LAST, params)


def test_objective_gradient_on_grid_corners_matches_the_reference():
    sit, inputs, params, samples = coast_problem()
    c = np.array([[1.0, 0.0]])
    traj = ownship_trajectory(sit.own_ship, c, Params(), CFG)
    grid = Planner(CFG).distance_grid(sit)
    fx, fy = traj[:, 0] - float(np.asarray(grid.origin)[0]), traj[:, 1] - float(np.asarray(grid.origin)[1])
    assert np.all(fx == np.round(fx)) and np.all(fy == np.round(fy))       # every position on a cell corner
    (total, costs), g = value_and_grad(jnp.asarray(c), inputs, params, samples, CFG,
                                       last_offsets=jnp.asarray(LAST))
    assert float(total) == pytest.approx(reference_cost(sit, c), rel=1e-9)
    assert float(costs["so"]) > 1.0                                         # the coast matters
    eps = 1e-6
    fd = np.zeros_like(c)
    for idx in np.ndindex(c.shape):
        e = np.zeros_like(c)
        e[idx] = eps
        fd[idx] = (reference_cost(sit, c + e) - reference_cost(sit, c - e)) / (2 * eps)
    np.testing.assert_allclose(np.asarray(g), fd, rtol=1e-5, atol=1e-7)
    so = jax.grad(lambda x: objective(x, inputs, params, samples, CFG)[1]["so"])(jnp.asarray(c))
    fd_so = np.array([[(ref_mod.grounding_cost(ownship_trajectory(sit.own_ship, c + e, Params(), CFG), COAST,
                                               Params(), CFG)
                        - ref_mod.grounding_cost(ownship_trajectory(sit.own_ship, c - e, Params(), CFG), COAST,
                                                 Params(), CFG)) / (2 * eps)
                       for e in (np.array([[eps, 0.0]]), np.array([[0.0, eps]]))]])
    np.testing.assert_allclose(np.asarray(so), fd_so, rtol=1e-5, atol=1e-7)
    assert np.all(np.abs(fd_so) > 0.1)                         # both speed and course move the grounding cost


def test_grid_built_from_the_coast_is_linear_near_the_track():
    """The premise of the objective test: the built grid is the coast's linear distance around the track."""
    grid = build_distance_grid([COAST], spacing=1.0, margin=100.0, dtype=np.float64,
                               region=((-20.0, -20.0), (70.0, 20.0)))
    xs, ys = np.meshgrid(-20.0 + np.arange(91), -20.0 + np.arange(41), indexing="ij")
    np.testing.assert_allclose(np.asarray(grid.values), (80.0 - xs - ys / 2) / np.sqrt(1.25), rtol=1e-12)
