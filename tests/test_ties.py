"""Degenerate choices (issue 11, item 3; docs/algorithm.md §11): hazards at the present and ties.

* An obstacle exactly at the own-ship gives every behaviour the same collision cost (its maximum over time is
  at t_0, which every behaviour shares); the plain argmin then let an artefact of the COLREGS indicator pick a
  port turn in a head-on.  The selection ranks such a pair by its future collision cost without the COLREGS
  indicator: the choice is a starboard turn.
* Starting inside land gives every behaviour the same grounding cost; the selection ranks that polygon by g
  at the horizon end with the signed distance: the choice leaves land, through the nearest boundary.
* Ties (totals within a few float epsilons) go to the smallest |chi_1|, then starboard, then the highest
  speed, then the lowest index.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np

from psbmpc_jax import Capacities, Params, Planner, PlannerConfig
from psbmpc_jax.behaviours import paper_behaviours
from psbmpc_jax.evaluate import Evaluation
from psbmpc_jax.ownship import Trajectory
from psbmpc_jax.packing import pack
from psbmpc_jax.situation import Obstacle, OwnShip, Situation
from psbmpc_jax.solve import break_ties, selection_cost

#: One config and one set of capacities for every solve of this file: one compile (grid grounding: it compiles
#: faster than the exact kernel; the exact branch of the selection is tested on a hand-made evaluation below).
CFG = PlannerConfig(T=60.0, dt=0.5, dtype="float64", grounding_mode="grid", grid_spacing=1.0)
CAPS = Capacities(obstacles=1, scenarios=5, waypoints=2, obstacle_waypoints=2, polygons=1, vertices=4, behaviours=64)
BEH = paper_behaviours(1)                     # 3 speeds x 13 course offsets (-90 .. 90 deg)
#: A 20 m wide, 1 km long strip of land along the east axis (x in [-10, 10]).
STRIP = np.array([[-10.0, -500.0], [-10.0, 500.0], [10.0, 500.0], [10.0, -500.0]])
#: The same strip 1.5 km astern (no influence): with it every situation here has a distance grid of one shape.
FAR_LAND = STRIP - [1500.0, 0.0]


def plan(sit, behaviours=BEH, params=None):
    res, _ = Planner(CFG, params=params, behaviours=behaviours, capacities=CAPS).plan(sit)
    return res


def test_obstacle_at_own_ship_head_on_turns_starboard():
    own = OwnShip(state=[0.0, 0.0, 0.0, 2.0], waypoints=[[0.0, 0.0], [2000.0, 0.0]], U_d=2.0)
    ob = Obstacle(state=[0.0, 0.0, -2.0, 0.0], cov=np.diag([4.0, 4.0, 0.05, 0.05]), n_ps=5)
    res = plan(Situation(own, (ob,), (FAR_LAND,)))
    do, total = res.costs["do"], res.costs["total"]
    # the degenerate case: every behaviour has the same collision cost, so the plain argmin of the totals
    # (docs §8) is decided by the COLREGS indicator, which here favours a port turn
    assert do.min() > 0 and np.ptp(do) <= 1e-12 * do.max()
    assert BEH[int(np.argmin(total)), 0, 1] < 0
    assert res.chi_opt > 0, res.offsets                     # the selection turns to starboard
    assert res.status == "ok" and res.best_index != int(np.argmin(total))


def first_step_outside(traj):
    """First time step at which each trajectory ``[B, T, 4]`` is off the strip (T when never)."""
    off = (np.abs(traj[..., 0]) > 10.0) | (np.abs(traj[..., 1]) > 500.0)
    return np.where(off.any(axis=1), off.argmax(axis=1), traj.shape[1])


def test_inside_land_leaves_land_through_the_nearest_boundary():
    # own-ship 5 m inside the strip's north edge, heading east along it: keeping course stays aground
    own = OwnShip(state=[5.0, 0.0, math.pi / 2, 2.0], waypoints=[[5.0, 0.0], [5.0, 2000.0]], U_d=2.0)
    res = plan(Situation(own, (), (STRIP,)))
    so, traj = res.costs["so"], res.own_trajectories
    assert so.min() > 0 and np.ptp(so) == 0                       # every behaviour the same grounding cost
    keep = int(np.argmin(res.costs["total"]))                      # the plain argmin: keep course, stay aground
    assert tuple(BEH[keep, 0]) == (1.0, 0.0) and first_step_outside(traj)[keep] == traj.shape[1]
    best = res.best_index
    assert res.chi_opt < 0 and traj[best, -1, 0] > 10.0           # a port turn, off the land to the north
    exits = first_step_outside(traj)
    assert exits[best] * CFG.dt <= exits.min() * CFG.dt + 3.0, (exits[best], exits.min())


def test_ties_break_toward_keep_course_then_starboard_then_speed():
    off = lambda rows: jnp.asarray([[[u, math.radians(c)]] for u, c in rows])     # [B, 1, 2]
    valid = jnp.ones(4, bool)
    same = jnp.full(4, 7.0)
    assert int(break_ties(same, valid, off([(1, -30), (0.5, 30), (1, 30), (1, 45)]))) == 2       # starboard, u=1
    assert int(break_ties(same, valid, off([(1, -30), (0.5, 0), (1, 15), (1, 0)]))) == 3         # keep course
    assert int(break_ties(same, valid, off([(1, 30), (1, 30), (1, 30), (1, 30)]))) == 0          # lowest index
    near = jnp.asarray([7.0 * (1 + 1e-15), 7.0, 7.0 * (1 + 1e-9), 8.0])      # 1e-15: a tie, 1e-9: not
    assert int(break_ties(near, valid, off([(1, 0), (1, 30), (1, 0), (1, 0)]))) == 0
    assert int(break_ties(near, jnp.asarray([False, True, True, True]), off([(1, 0), (1, 30), (1, 0), (1, 0)]))) == 1
    assert int(break_ties(near, jnp.zeros(4, bool), off([(1, 0)] * 4))) == -1
    # through the planner: +-30 deg cost exactly the same with symmetric path weights; argmin takes the first
    sym = Params(K_chi_port=1.5, K_chi_stbd=1.5, K_dchi_port=1.0, K_dchi_stbd=1.0)
    own = OwnShip(state=[0.0, 0.0, 0.0, 2.0], waypoints=[[0.0, 0.0], [2000.0, 0.0]], U_d=2.0)
    table = np.array([[[1.0, -math.radians(30)]], [[1.0, math.radians(30)]]])
    res = plan(Situation(own, (), (FAR_LAND,)), table, sym)
    assert res.costs["total"][0] == res.costs["total"][1] and res.best_index == 1


def test_exact_mode_inside_land_uses_the_signed_distance_at_the_horizon_end():
    """selection_cost on a hand-made exact-mode evaluation (two polygons: the strip the own-ship is in, whose
    cost is the same for every behaviour, and an island whose cost varies): the strip's cost is replaced by g
    at the horizon end, decreasing from deep inside land to the boundary and beyond; the island's is kept."""
    island = np.array([[40.0, -5.0], [40.0, 5.0], [50.0, 5.0], [50.0, -5.0]])
    own = OwnShip(state=[5.0, 0.0, 0.0, 2.0], waypoints=[[5.0, 0.0], [50.0, 0.0]], U_d=2.0)
    cfg = CFG.replace(grounding_mode="exact")
    inputs = pack(Situation(own, (), (STRIP, island)), np.zeros((3, 1, 2)), cfg,
                  capacities=Capacities(behaviours=3), origin=(0.0, 0.0))
    end_x = jnp.asarray([0.0, 8.0, 30.0])             # deep inside, 2 m inside, 20 m off the strip
    xs = jnp.stack([jnp.full(3, 5.0), end_x])         # [T=2, B]
    z = jnp.zeros_like(xs)
    p = Params()
    so_j = jnp.stack([jnp.full(3, 225.0), jnp.asarray([0.5, 1.0, 3.0])], axis=1)        # [B, P]
    so = so_j.max(axis=1)
    ev = Evaluation(jnp.int32(0), jnp.zeros((1, 2)), so + 1.0, {"so": so, "path": jnp.ones(3)}, {"so_j": so_j},
                    Trajectory(xs, z, z, z, z, z), None, None, {})
    rank = np.asarray(selection_cost(ev, inputs, p, cfg))
    g = lambda d: p.G1 * math.exp(-p.G4 * cfg.T) * (1 + p.G3 * (p.d_safe - d))          # the linear branch
    g_off = p.G1 * math.exp(-p.G4 * cfg.T - p.G3 * (20.0 - p.d_safe))                    # 20 m off the strip
    np.testing.assert_allclose(rank, [1.0 + g(-10.0), 1.0 + g(-2.0), 1.0 + max(g_off, 3.0)], rtol=1e-12)
    assert rank[0] > rank[1] > rank[2]
    # not saturated (the strip's costs differ): the total as it is
    so_j2 = so_j.at[0, 0].add(1.0)
    ev2 = ev._replace(costs={"so": so_j2.max(axis=1), "path": jnp.ones(3)}, details={"so_j": so_j2})
    np.testing.assert_array_equal(np.asarray(selection_cost(ev2, inputs, p, cfg)), np.asarray(ev2.total))
