"""SmoothSBMPCPlanner (psbmpc_jax/smooth/planner.py): the host API the closed-loop simulator uses.

``plan`` equals the matching row of ``plan_batch`` (different states, targets, last offsets and active
segments in one call), the ``init_only`` path is the init stage's first offsets, results do not depend on
the frame's origin (UTM-sized coordinates in float32), no targets and no land work, and bad inputs are
refused with the field's name."""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
import pytest

from psbmpc_jax.packing import pack_world
from psbmpc_jax.params import PlannerConfig
from psbmpc_jax.smooth import SmoothSBMPCPlanner, SmoothSettings, smooth_sbmpc_step
from psbmpc_jax.smooth.init_stage import init_stage

SETTINGS = SmoothSettings(T_init=16.0, T_mpc=8.0, dt=1.0, n_y=51)
BANKS = [np.array([[-50.0, 14.0], [150.0, 14.0], [150.0, 30.0], [-50.0, 30.0]]),
         np.array([[-50.0, -14.0], [150.0, -14.0], [150.0, -30.0], [-50.0, -30.0]])]
ROUTE = np.array([[-40.0, 0.0], [0.0, 0.0], [140.0, 0.0]])
N = SETTINGS.n_mpc


def runs(R=3, seed=0):
    rng = np.random.default_rng(seed)
    states = np.stack([[rng.uniform(-5.0, 5.0), rng.uniform(-3.0, 3.0), rng.uniform(-0.2, 0.2), rng.uniform(0.6, 1.0)]
                       for _ in range(R)])
    targets = np.stack([[[rng.uniform(15.0, 25.0), rng.uniform(-2.0, 2.0), math.pi + rng.uniform(-0.2, 0.2), 0.6],
                         [rng.uniform(20.0, 40.0), rng.uniform(8.0, 12.0), -math.pi / 2, 0.5]] for _ in range(R)])
    last = np.stack([[rng.uniform(0.5, 1.0), rng.uniform(-0.3, 0.3)] for _ in range(R)])
    segments = np.arange(R) % 2
    segments[0] = 1
    return states, targets, last, segments


@pytest.fixture(scope="module")
def planner():
    return SmoothSBMPCPlanner(BANKS, settings=SETTINGS, n_starts=2, dtype="float64")


def test_plan_equals_the_plan_batch_row(planner):
    states, targets, last, segments = runs()
    batch = planner.plan_batch(states, ROUTE, targets, last, segments)
    assert batch.apply.shape == (3, 2) and batch.controls.shape == (3, N, 2)
    assert batch.psi.shape == (3, SETTINGS.n_init + 1, 4) and batch.cost.shape == (3,)
    for r in range(3):
        one = planner.plan(states[r], ROUTE, targets[r], last[r], segments[r])
        for name in ("apply", "controls", "psi", "cost", "warm_cost"):
            np.testing.assert_allclose(np.asarray(getattr(batch, name))[r], np.asarray(getattr(one, name)),
                                       rtol=1e-7, atol=1e-7, err_msg=name)
        assert bool(batch.used_warm[r]) == bool(one.used_warm) and int(batch.status[r]) == int(one.status)
        assert float(one.cost) <= float(one.warm_cost) + 1e-9 and float(one.violation) <= 1e-3
        np.testing.assert_array_equal(one.apply, one.controls[0])
    # the planner's step is smooth_sbmpc_step (same chart, same start count)
    land = pack_world(BANKS, PlannerConfig(dtype="float64")).polygons
    step = smooth_sbmpc_step(states[0], ROUTE, targets[0], last[0], land, planner.charts(planner.origin)[1],
                             settings=SETTINGS, n_starts=2, segment=int(segments[0]))
    np.testing.assert_allclose(batch.controls[0], np.asarray(step.controls), rtol=1e-7, atol=1e-7)


def test_init_only_applies_the_init_stage_offsets():
    p = SmoothSBMPCPlanner(BANKS, settings=SETTINGS, init_only=True, dtype="float64")
    states, targets, last, segments = runs(seed=1)
    batch = p.plan_batch(states, ROUTE, targets, last, segments)
    land = pack_world(BANKS, PlannerConfig(dtype="float64")).polygons
    for r in range(3):
        init = init_stage(states[r], ROUTE, targets[r], last[r], land, settings=SETTINGS, segment=int(segments[r]))
        one = p.plan(states[r], ROUTE, targets[r], last[r], segments[r])
        np.testing.assert_array_equal(one.apply, np.asarray(init.controls[0]))
        np.testing.assert_array_equal(one.controls, np.asarray(init.controls[:N]))
        np.testing.assert_allclose(one.psi, np.asarray(init.psi), rtol=0, atol=1e-12)
        np.testing.assert_allclose(batch.controls[r], one.controls, rtol=0, atol=1e-12)
        assert float(one.cost) == float(one.warm_cost) == float(init.cost[0])
        assert bool(one.used_warm) and int(one.status) == 0 and int(one.iterations) == 0 and float(one.violation) == 0


def test_origin_invariance_with_utm_coordinates_in_float32():
    """The same situation in a frame shifted by (7.0e6, 5.5e5) m gives the same plan (float32: without the
    local origin the positions would be quantised to 0.5 m); Ψ comes back in the user's frame."""
    shift = np.array([7.0e6, 5.5e5])
    states, targets, last, segments = runs(R=1, seed=2)
    out = []
    for o in (np.zeros(2), shift):
        p = SmoothSBMPCPlanner([b + o for b in BANKS], settings=SETTINGS, n_starts=1, dtype="float32")
        s, t = states[0].copy(), targets[0].copy()
        s[:2] += o
        t[:, :2] += o
        plan = p.plan(s, ROUTE + o, t, last[0], segments[0])
        assert p.origin is not None and np.all(np.abs(s[:2] - p.origin) <= 1e4)
        out.append((plan, o))
    (a, _), (b, o) = out
    assert b.psi.dtype == np.float64
    np.testing.assert_allclose(b.psi[:, :2] - o, a.psi[:, :2], rtol=0, atol=2e-3)
    np.testing.assert_allclose(b.psi[:, 2:], a.psi[:, 2:], rtol=0, atol=1e-4)
    np.testing.assert_allclose(b.controls, a.controls, rtol=0, atol=1e-3)
    assert float(b.cost) == pytest.approx(float(a.cost), rel=1e-3)


def test_no_targets_and_no_land():
    p = SmoothSBMPCPlanner((), settings=SETTINGS, init_only=True, dtype="float64")
    plan = p.plan([0.0, 0.0, 0.0, 1.0], ROUTE, np.zeros((0, 4)), [1.0, 0.0], 1)
    np.testing.assert_array_equal(plan.apply, [1.0, 0.0])                # nothing to avoid: straight on
    batch = p.plan_batch(np.zeros((2, 4)) + [0, 0, 0, 1.0], ROUTE, np.zeros((2, 0, 4)), np.ones((2, 2)) * [1, 0],
                         np.array([1, 1]))
    np.testing.assert_array_equal(batch.apply, [[1.0, 0.0], [1.0, 0.0]])


@pytest.mark.parametrize("call, match", [
    (lambda p: p.plan(np.zeros(3), ROUTE, np.zeros((0, 4)), [1, 0]), "state0"),
    (lambda p: p.plan([0, 0, 0, np.nan], ROUTE, np.zeros((0, 4)), [1, 0]), "state0"),
    (lambda p: p.plan([0, 0, 0, 1], ROUTE[:1], np.zeros((0, 4)), [1, 0]), "route"),
    (lambda p: p.plan([0, 0, 0, 1], ROUTE, np.zeros(4), [1, 0]), "targets"),
    (lambda p: p.plan([0, 0, 0, 1], ROUTE, np.zeros((0, 4)), [1, 0, 0]), "last"),
    (lambda p: p.plan([0, 0, 0, 1], ROUTE, np.zeros((0, 4)), [1, 0], 2), "segment"),
    (lambda p: p.plan([0, 0, 0, 1], ROUTE, np.zeros((0, 4)), [1, 0], 0.5), "segment"),
    (lambda p: p.plan_batch(np.zeros((2, 4)), ROUTE, np.zeros((3, 0, 4)), np.zeros((2, 2)), [0, 0]), "targets"),
    (lambda p: p.plan_batch(np.zeros((2, 4)), ROUTE, np.zeros((2, 0, 4)), np.zeros((2, 2)), [0]), "segments"),
    (lambda p: p.plan_batch(np.zeros((2, 4)), ROUTE, np.zeros((2, 0, 4)), np.zeros((1, 2)), [0, 0]), "last"),
    (lambda p: p.plan_batch(np.zeros((0, 4)), ROUTE, np.zeros((0, 0, 4)), np.zeros((0, 2)), []), "states"),
])
def test_bad_plan_inputs_are_refused(call, match):
    p = SmoothSBMPCPlanner((), settings=SETTINGS, init_only=True, dtype="float64")
    with pytest.raises(ValueError, match=match):
        call(p)


@pytest.mark.parametrize("kw, match", [
    (dict(n_starts=0), "n_starts"), (dict(n_starts=41), "n_starts"), (dict(batch="pmap"), "batch"),
    (dict(dtype="float16"), "dtype"), (dict(init_only="yes"), "init_only"), (dict(weights=1.0), "weights"),
    (dict(model="ship"), "model"), (dict(settings=SmoothSettings, ), "settings"), (dict(solver=1e-3), "solver"),
    (dict(polygons=[np.zeros((2, 2))]), "polygons"),
])
def test_bad_planner_options_are_refused(kw, match):
    polygons = kw.pop("polygons", ())
    with pytest.raises(ValueError, match=match):
        SmoothSBMPCPlanner(polygons, **kw)


def test_float32_under_64_bit_jax_keeps_float32():
    p = SmoothSBMPCPlanner(BANKS, settings=SETTINGS, init_only=True, dtype="float32")
    plan = p.plan([0.0, 0.0, 0.0, 1.0], ROUTE, np.zeros((0, 4)), [1.0, 0.0], 1)
    assert plan.apply.dtype == np.float32 and plan.controls.dtype == np.float32 and plan.psi.dtype == np.float64
    assert jnp.asarray(1.0).dtype == jnp.float64                          # (the session is 64-bit)


def test_previous_plan_rows_equal_single_plans_and_a_nan_row_means_none():
    """``previous_start``: ``plan_batch`` with a previous plan per run (NaN throughout for a run without one)
    equals ``plan`` row by row, with ``previous=None`` for that run; the kept sequence is never worse than Ψ."""
    p = SmoothSBMPCPlanner(BANKS, settings=SETTINGS, n_starts=2, dtype="float64", previous_start=True)  # fixture's jit
    states, targets, last, segments = runs(seed=3)
    rng = np.random.default_rng(3)
    previous = np.stack([np.stack([rng.uniform(0.2, 1.0, N), rng.uniform(-1.0, 1.0, N)], axis=-1) for _ in range(3)])
    previous[1] = np.nan
    batch = p.plan_batch(states, ROUTE, targets, last, segments, previous=previous)
    for r in range(3):
        one = p.plan(states[r], ROUTE, targets[r], last[r], segments[r], previous=None if r == 1 else previous[r])
        np.testing.assert_allclose(batch.controls[r], one.controls, rtol=1e-7, atol=1e-7)
        np.testing.assert_allclose(batch.cost[r], one.cost, rtol=1e-7, atol=1e-7)
        assert float(one.cost) <= float(one.warm_cost) + 1e-9 and float(one.violation) <= 1e-3
    # no previous plan at all is the plain planner with the same number of starts
    plain = SmoothSBMPCPlanner(BANKS, settings=SETTINGS, n_starts=2, dtype="float64")
    a = p.plan(states[0], ROUTE, targets[0], last[0], segments[0])
    b = plain.plan(states[0], ROUTE, targets[0], last[0], segments[0])
    np.testing.assert_allclose(a.controls, b.controls, rtol=0, atol=1e-9)


@pytest.mark.parametrize("kw, call, match", [
    (dict(previous_start=True, n_starts=1), None, "previous_start needs"),
    (dict(previous_start=True, init_only=True), None, "previous_start needs"),
    (dict(previous_start="yes"), None, "previous_start must be a bool"),
    (dict(), lambda p: p.plan([0, 0, 0, 1], ROUTE, np.zeros((0, 4)), [1, 0], 1, previous=np.ones((N, 2))),
     "previous is only used with previous_start"),
    (dict(previous_start=True), lambda p: p.plan([0, 0, 0, 1], ROUTE, np.zeros((0, 4)), [1, 0], 1,
                                                 previous=np.ones((N + 1, 2))), "previous must be"),
    (dict(previous_start=True), lambda p: p.plan_batch(np.zeros((2, 4)) + [0, 0, 0, 1], ROUTE, np.zeros((2, 0, 4)),
                                                       np.ones((2, 2)), [1, 1], previous=np.ones((2, N, 2)) * [1, 3.5]),
     "box"),
    (dict(previous_start=True), lambda p: p.plan_batch(np.zeros((2, 4)) + [0, 0, 0, 1], ROUTE, np.zeros((2, 0, 4)),
                                                       np.ones((2, 2)), [1, 1],
                                                       previous=np.where(np.arange(N)[None, :, None] == 0, np.nan,
                                                                         np.ones((2, N, 2)))), "finite"),
])
def test_bad_previous_plan_options_are_refused(kw, call, match):
    with pytest.raises(ValueError, match=match):
        p = SmoothSBMPCPlanner((), settings=SETTINGS, dtype="float64", **({"n_starts": 2} | kw))
        call(p)


def test_last_offsets_from_the_terminal_los_frame_are_accepted_beyond_the_box():
    """With ``chi_d_mode="terminal_los"`` the applied offsets come back converted to the route frame (a box offset
    plus the difference of the two LOS courses), so the next update's ``last`` may leave [-pi/2, pi/2]: the
    reconstructed scene's 18-run set stopped with "last: the course offset chi_m must be in [-pi/2, pi/2] rad
    (the DOCP's box), got 1.57854".  Accepted up to 3 pi/2 there; the route frame and the init stage alone keep
    the box.  (A zero-length route leg, checked after ``last``, stops each call before anything compiles.)"""
    zero_leg = np.array([[0.0, 0.0], [0.0, 0.0], [10.0, 0.0]])
    state, no_targets = [0.0, 0.0, 0.0, 1.0], np.zeros((0, 4))
    wide = SmoothSBMPCPlanner((), settings=SETTINGS, dtype="float64")
    assert SETTINGS.chi_d_mode == "terminal_los"
    for chi in (1.57854, -1.57854, 3 * math.pi / 2 - 1e-3):
        with pytest.raises(ValueError, match="leg 0 has zero length"):            # last passed
            wide.plan(state, zero_leg, no_targets, [1.0, chi])
        with pytest.raises(ValueError, match="leg 0 has zero length"):
            wide.plan_batch(np.array([state]), zero_leg, no_targets[None], np.array([[1.0, chi]]), [0])
    with pytest.raises(ValueError, match=r"last: the course offset chi_m must be in \[-3pi/2, 3pi/2\] rad .*"
                                         r"got 4\.72"):
        wide.plan(state, zero_leg, no_targets, [1.0, 3 * math.pi / 2 + 0.01])
    with pytest.raises(ValueError, match=r"speed factor U_m must be in"):
        wide.plan(state, zero_leg, no_targets, [1.5, 0.0])
    route_los = SmoothSettings(T_init=16.0, T_mpc=8.0, dt=1.0, n_y=51, chi_d_mode="route_los")
    for p in (SmoothSBMPCPlanner((), settings=route_los, dtype="float64"),
              SmoothSBMPCPlanner((), settings=SETTINGS, init_only=True, dtype="float64")):
        with pytest.raises(ValueError, match=r"last: the course offset chi_m must be in \[-pi/2, pi/2\] rad "
                                             r"\(the DOCP's box\), got 1\.57854"):
            p.plan(state, zero_leg, no_targets, [1.0, 1.57854])
