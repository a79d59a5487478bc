"""Smooth-SBMPC initialisation stage (psbmpc_jax/smooth/init_stage.py), float64.

The jitted scan equals an independent float64 loop of Algorithms 1-2 (NumPy LOS rollout of the reference,
reference_smooth costs, shapely N_TP); Ψ is reproduced by rolling out its own offsets (a feasible warm start);
the scan does not recompile when weights change; a head-on target gives a starboard turn; land across the
route is avoided through the N_TP penalty; bad settings are refused."""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
import pytest
import shapely

from psbmpc_jax import reference_prediction as pred
from psbmpc_jax import reference_smooth as rs
from psbmpc_jax.packing import pack_world
from psbmpc_jax.params import PlannerConfig
from psbmpc_jax.smooth.init_stage import (COURSE_OFFSETS_DEG, SPEED_FACTORS, ShipModel, SmoothSettings, SmoothWeights,
                                          _init_stage_jit, init_stage, rollout_controls, route_path)

CFG = PlannerConfig(dtype="float64")
SETTINGS = SmoothSettings(T_init=8.0, T_mpc=4.0, dt=1.0, n_y=101)
MODEL = ShipModel()


def chart_of(polys):
    return pack_world(polys, CFG).polygons


def oracle_n_tp(traj, polys, r_dom):
    """First index j whose domain disc meets land or whose segment from j-1 meets land (shapely)."""
    land = shapely.unary_union([shapely.Polygon(p) for p in polys]) if polys else None
    for j in range(len(traj)):
        if land is None:
            break
        pt = shapely.Point(traj[j])
        if land.distance(pt) <= r_dom:
            return j
        if j > 0 and shapely.LineString([traj[j - 1], traj[j]]).intersects(land):
            return j
    return len(traj) - 1


def oracle_radius(state, polys, r_dom):
    """C-000-16: min(r_dom, 0.9 x clearance) when the state is closer than r_dom to land (0 inside)."""
    if not len(polys):
        return r_dom
    land = shapely.unary_union([shapely.Polygon(p) for p in polys])
    clearance = land.distance(shapely.Point(state[:2]))
    return 0.9 * clearance if clearance < r_dom else r_dom


def oracle_init_stage(state0, route, targets, last, polys, w: SmoothWeights, s: SmoothSettings, m: ShipModel):
    """Algorithms 1-2 as plain float64 loops (route LOS re-evaluated along each prediction, C-000-11)."""
    n = s.n_init
    t = np.arange(n + 1) * s.dt
    table = [(u, math.radians(c)) for c in COURSE_OFFSETS_DEG for u in SPEED_FACTORS]
    state, tg, lst = np.asarray(state0, float), np.asarray(targets, float), np.asarray(last, float)
    psi, controls = [state], []
    kw = dict(d_safe=w.d_safe, K_coll=w.K_coll, p=w.p, q=w.q, w_coll=w.w_coll, kappa=w.kappa, d_cl=w.d_cl,
              e_cl=w.e_cl, eps=w.eps, n_y=s.n_y, completion=s.fis_completion)
    gw = dict(k_U=w.k_U, k_chi_port=w.k_chi_port, k_chi_stbd=w.k_chi_stbd, Delta_U=w.Delta_U,
              Delta_chi_port=w.Delta_chi_port, Delta_chi_stbd=w.Delta_chi_stbd)
    for _ in range(n):
        tg_traj = [np.stack([x + U * math.cos(c) * t, y + U * math.sin(c) * t, np.full_like(t, c), np.full_like(t, U)],
                            -1) for x, y, c, U in tg]
        totals = []
        for u, c in table:
            own = pred.los_rollout(state, route, c, m.U_d * u, 0.0, m.lookahead, m.R_a, m.T_chi, m.T_U, s.dt, n)
            hazard = rs.sbmpc_cost(own, tg_traj, t, component="joint", aggregation="max", **kw) if len(tg) else 0.0
            gamma = rs.gamma_smooth(u, c, lst[0], lst[1], **gw)
            totals.append(hazard + gamma + w.k_ntp * (n - oracle_n_tp(own[:, :2], polys, oracle_radius(state, polys,
                                                                                                   s.r_dom))))
        k = int(np.argmin(totals))
        u, c = table[k]
        controls.append((u, c))
        lst = np.array([u, c])
        psi.append(psi[-1])        # replaced below by the exact rollout of the applied offsets
        tg = np.array([[x + U * math.cos(cc) * s.dt, y + U * math.sin(cc) * s.dt, cc, U] for x, y, cc, U in tg])
        seq = np.asarray(controls)
        full = pred.los_rollout(state0, route, seq[:, 1], m.U_d * seq[:, 0], 0.0, m.lookahead, m.R_a, m.T_chi,
                               m.T_U, s.dt, len(seq))
        state = full[-1]
        psi[-1] = state
    return np.asarray(psi), np.asarray(controls)


ROUTE = np.array([[0.0, 0.0], [120.0, 0.0]])
STATE0 = np.array([0.0, 0.0, 0.0, 1.0])
HEAD_ON = np.array([[30.0, 0.5, math.pi, 0.8]])


@pytest.mark.parametrize("case", ["head_on", "land", "crossing_and_land"])
def test_scan_equals_float64_loop_oracle(case):
    polys, targets = [], HEAD_ON
    if case in ("land", "crossing_and_land"):
        polys = [np.array([[10.0, -4.0], [10.0, 3.0], [16.0, 3.0], [16.0, -4.0]])]
    if case == "land":
        targets = np.zeros((0, 4))
    if case == "crossing_and_land":
        targets = np.array([[25.0, -20.0, math.pi / 2, 1.0], [40.0, 1.0, math.pi, 0.5]])
    w = SmoothWeights()
    got = init_stage(STATE0, ROUTE, targets, np.array([1.0, 0.0]), chart_of(polys), w, MODEL, SETTINGS)
    want_psi, want_u = oracle_init_stage(STATE0, ROUTE, targets, [1.0, 0.0], polys, w, SETTINGS, MODEL)
    np.testing.assert_allclose(np.asarray(got.controls), want_u, atol=1e-12)
    np.testing.assert_allclose(np.asarray(got.psi), want_psi, atol=1e-9)
    if case != "head_on":                                             # the applied path itself stays off land
        land = shapely.Polygon(polys[0])
        assert min(land.distance(shapely.Point(p)) for p in np.asarray(got.psi)[:, :2]) > 0.0


def test_psi_is_the_rollout_of_its_offsets_and_turns_starboard_head_on():
    route = np.array([[0.0, 0.0], [40.0, 0.0], [40.0, 60.0]])       # two segments: the segment is carried
    s = SmoothSettings(T_init=12.0, T_mpc=4.0, dt=1.0, n_y=51)
    got = init_stage(STATE0, route, HEAD_ON, np.array([1.0, 0.0]), chart_of([]), settings=s)
    states = rollout_controls(jnp.asarray(STATE0), route_path(jnp.asarray(route)), got.controls, MODEL, s.dt)
    np.testing.assert_allclose(np.asarray(states), np.asarray(got.psi), atol=1e-12)
    assert float(got.controls[0, 1]) > 0.0                           # starboard in a head-on


def test_weights_do_not_recompile_and_bad_settings_are_refused():
    chart = chart_of([])
    before = _init_stage_jit._cache_size()
    for kappa in (5.0, 20.0):
        init_stage(STATE0, ROUTE, HEAD_ON, np.array([1.0, 0.0]), chart, SmoothWeights(kappa=kappa), MODEL, SETTINGS)
    assert _init_stage_jit._cache_size() - before <= 1
    for bad, match in ((dict(T_init=4.0, T_mpc=4.0), "T_init must be > T_mpc"),
                       (dict(T_init=7.5), "multiple of dt"), (dict(dt=0.0), "dt must be"),
                       (dict(terminal="hard"), "terminal"), (dict(n_y=1), "n_y"), (dict(r_dom=-1.0), "r_dom")):
        with pytest.raises(ValueError, match=match):
            SmoothSettings(**{**dict(T_init=8.0, T_mpc=4.0, dt=1.0), **bad})
    with pytest.raises(ValueError, match="route"):
        init_stage(STATE0, ROUTE[:1], HEAD_ON, np.array([1.0, 0.0]), chart, settings=SETTINGS)
    with pytest.raises(ValueError, match="targets"):
        init_stage(STATE0, ROUTE, HEAD_ON[0], np.array([1.0, 0.0]), chart, settings=SETTINGS)


def test_active_segment_is_an_argument_and_first_cost_is_the_first_inner_evaluation():
    """``segment`` equals slicing the route (Ψ and offsets exactly, segments shifted), one compilation for
    every segment; ``first_cost`` is Algorithm 2's totals at τ₀; a bad segment is refused."""
    from psbmpc_jax.smooth.init_stage import behaviour_costs

    route = np.array([[-50.0, 0.0], [0.0, 0.0], [40.0, 0.0], [40.0, 60.0]])
    chart = chart_of([])
    a = init_stage(STATE0, route, HEAD_ON, np.array([1.0, 0.0]), chart, settings=SETTINGS, segment=1)
    size = _init_stage_jit._cache_size()
    c = init_stage(STATE0, route, HEAD_ON, np.array([1.0, 0.0]), chart, settings=SETTINGS, segment=0)
    assert _init_stage_jit._cache_size() == size                     # the segment is a value
    b = init_stage(STATE0, route[1:], HEAD_ON, np.array([1.0, 0.0]), chart, settings=SETTINGS)
    np.testing.assert_array_equal(np.asarray(a.psi), np.asarray(b.psi))
    np.testing.assert_array_equal(np.asarray(a.controls), np.asarray(b.controls))
    np.testing.assert_array_equal(np.asarray(a.segment), np.asarray(b.segment) + 1)
    assert int(a.segment[0]) == 1 and int(c.segment[0]) == 0
    total, *_ = behaviour_costs(jnp.asarray(STATE0), jnp.asarray(1, jnp.int32), jnp.asarray(HEAD_ON),
                                jnp.asarray([1.0, 0.0]), route_path(jnp.asarray(route)), chart, SmoothWeights(),
                                MODEL, SETTINGS)
    np.testing.assert_allclose(np.asarray(a.first_cost), np.asarray(total), rtol=1e-12, atol=1e-12)
    assert float(a.cost[0]) == float(np.min(np.asarray(a.first_cost)))
    for bad in (-1, 3, 1.0, True, np.array([1])):
        with pytest.raises(ValueError, match="segment"):
            init_stage(STATE0, route, HEAD_ON, np.array([1.0, 0.0]), chart, settings=SETTINGS, segment=bad)


@pytest.mark.parametrize("clearance", [3.0, 0.5])
def test_state_inside_the_domain_still_ranks_behaviours_by_land(clearance):
    """C-000-16: an inner state closer than r_dom to land. With the plain r_dom every behaviour would hit at
    point 0 (same N_TP, the penalty could not tell them apart); with the shrunk radius the behaviours that turn
    away from the wall keep N_TP = N and those that turn into it do not."""
    # wall along the route, `clearance` m to starboard (east), 4 m domain
    wall = [np.array([[-50.0, clearance], [200.0, clearance], [200.0, clearance + 20.0], [-50.0, clearance + 20.0]])]
    chart = chart_of(wall)
    assert SETTINGS.r_dom > clearance
    from psbmpc_jax.smooth.init_stage import behaviour_costs, domain_radius, route_path
    radius = float(domain_radius(jnp.asarray(STATE0), chart, SETTINGS.r_dom))
    assert radius == pytest.approx(0.9 * clearance, rel=1e-9)
    _, n_tp, _, _ = behaviour_costs(jnp.asarray(STATE0), jnp.asarray(0, jnp.int32), jnp.zeros((0, 4)),
                                    jnp.asarray([1.0, 0.0]), route_path(ROUTE), chart, SmoothWeights(), MODEL,
                                    SETTINGS)
    n_tp = np.asarray(n_tp).reshape(len(COURSE_OFFSETS_DEG), len(SPEED_FACTORS))
    port = [i for i, c in enumerate(COURSE_OFFSETS_DEG) if c <= -30]
    stbd = [i for i, c in enumerate(COURSE_OFFSETS_DEG) if c >= 30]
    assert np.all(n_tp[port] == SETTINGS.n_init)          # turning away: no hit
    full = SPEED_FACTORS.index(1.0) if isinstance(SPEED_FACTORS, (list, tuple)) else list(SPEED_FACTORS).index(1.0)
    assert np.all(n_tp[stbd, full] < SETTINGS.n_init)     # turning into the wall at full speed: hit
    assert np.all(n_tp > 0)                               # point 0 is no longer a hit for every behaviour
    # the plain radius (what C-000-16 replaces) makes every behaviour hit at point 0
    from psbmpc_jax.smooth.land_hit import first_land_hit
    assert np.all(np.asarray(first_land_hit(np.zeros((1, 2, 2)), chart, SETTINGS.r_dom)) == 0)


def test_domain_radius_is_r_dom_away_from_land_and_zero_inside():
    from psbmpc_jax.smooth.init_stage import domain_radius
    box = [np.array([[10.0, -4.0], [10.0, 3.0], [16.0, 3.0], [16.0, -4.0]])]
    chart = chart_of(box)
    assert float(domain_radius(jnp.asarray(STATE0), chart, SETTINGS.r_dom)) == SETTINGS.r_dom
    inside = jnp.asarray([12.0, 0.0, 0.0, 1.0])
    assert float(domain_radius(inside, chart, SETTINGS.r_dom)) == 0.0
    assert float(domain_radius(jnp.asarray(STATE0), chart_of([]), SETTINGS.r_dom)) == SETTINGS.r_dom
