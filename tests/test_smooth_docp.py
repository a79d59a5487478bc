"""Smooth-SBMPC MPC stage (psbmpc_jax/smooth/docp.py), float64.

* the warm start (the init stage's offsets) is exactly feasible, and the applied sequence is never worse than it
  (lower or equal J_d, violation <= 1e-3) on random channel situations, with one start and with several;
* J_d's gradient (the whole DOCP cost: rollout, smooth collision risk, fuzzy COLREGS, Γ) matches central
  differences;
* one compilation serves new values of the state, targets, weights and the numeric solver settings;
* the multi-start: ``vmap`` == ``map`` == a Python loop of ``solve_docp`` over the same starts; ``n_starts=1`` is
  the single solve from Ψ; the starts are Ψ then the best constant behaviours at τ₀;
* a narrow corridor: the optimum lies on the corridor bound (active constraint, positive multiplier);
* bad inputs are refused with the field's name."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from psbmpc_jax.nlp import best_index, max_violation, safeguard, solve_docp
from psbmpc_jax.packing import pack_world
from psbmpc_jax.params import PlannerConfig
from psbmpc_jax.smooth import buffered_chart, cross_track_corridor, cross_track_residuals
from psbmpc_jax.smooth import docp as D
from psbmpc_jax.smooth.docp import (DOCP_SOLVER, DocpArgs, bounds, docp_cost, prepare_step, problem,
                                    smooth_sbmpc_step)
from psbmpc_jax.smooth.init_stage import (COURSE_OFFSETS_DEG, SPEED_FACTORS, ShipModel, SmoothSettings,
                                          SmoothWeights, behaviour_table)

# the DOCP's mechanics in the route frame, the corridor at the samples (the DocpArgs built here hold the route and
# the route-frame offsets); the terminal-LOS frame and the clearance between samples: test_smooth_guidance.py,
# test_smooth_clearance.py
SETTINGS = SmoothSettings(T_init=16.0, T_mpc=8.0, dt=1.0, n_y=51, chi_d_mode="route_los", corridor_check="samples")
BANKS = [np.array([[-50.0, 14.0], [150.0, 14.0], [150.0, 30.0], [-50.0, 30.0]]),
         np.array([[-50.0, -14.0], [150.0, -14.0], [150.0, -30.0], [-50.0, -30.0]])]
ROUTE = np.array([[0.0, 0.0], [140.0, 0.0]])
LAST = np.array([1.0, 0.0])
LAND = pack_world(BANKS, PlannerConfig(dtype="float64")).polygons
BUF = buffered_chart(BANKS, SETTINGS.corridor_land_buffer)


def random_situation(rng):
    state0 = np.array([0.0, rng.uniform(-3.0, 3.0), rng.uniform(-0.2, 0.2), rng.uniform(0.6, 1.0)])
    target = np.array([[rng.uniform(15.0, 25.0), rng.uniform(-2.0, 2.0), math.pi + rng.uniform(-0.2, 0.2),
                        rng.uniform(0.3, 0.8)]])
    return state0, target


_prepare = jax.jit(prepare_step, static_argnames=("settings", "n_starts"))


def prepared(state0, targets, n_starts=1, route=ROUTE, segment=0, weights=SmoothWeights()):
    return _prepare(jnp.asarray(state0), jnp.asarray(route), jnp.asarray(targets), jnp.asarray(LAST),
                    jnp.asarray(segment, jnp.int32), LAND, BUF, weights, ShipModel(), settings=SETTINGS,
                    n_starts=n_starts)


# ================================================================================ feasibility and safeguard
def test_refinement_is_never_worse_than_its_feasible_warm_start():
    f, eq, ineq = problem(SETTINGS)
    rng = np.random.default_rng(0)
    improved = 0
    n = SETTINGS.n_mpc
    for case in range(5):
        state0, target = random_situation(rng)
        n_starts = 1 if case < 3 else 3
        step = smooth_sbmpc_step(state0, ROUTE, target, LAST, LAND, BUF, settings=SETTINGS, n_starts=n_starts)
        args = DocpArgs(step.init.psi[0], ROUTE, target, LAST, step.init.psi[n], step.corridor, SmoothWeights(),
                        ShipModel())
        lower, upper = bounds(n, step.init.psi.dtype)
        warm_violation = float(max_violation(step.init.controls[:n], lower=lower, upper=upper, eq=eq, ineq=ineq,
                                             args=args))
        assert warm_violation <= 1e-9                                     # Ψ is the rollout of its offsets
        assert float(step.warm_cost) == pytest.approx(float(f(step.init.controls[:n], args)), rel=1e-12)
        assert float(step.cost) <= float(step.warm_cost) + 1e-9
        assert float(step.violation) <= DOCP_SOLVER.tol
        np.testing.assert_array_equal(np.asarray(step.apply), np.asarray(step.controls[0]))
        assert step.starts.shape == (n_starts, n, 2) and step.start_cost.shape == (n_starts,)
        improved += float(step.cost) < float(step.warm_cost) - 1e-6
    assert improved >= 3                                                  # the DOCP does refine


# ================================================================================ gradient of J_d
def test_docp_cost_gradient_matches_central_differences():
    """∂J_d/∂u of the whole DOCP cost at random interior controls, targets in the FIS and collision-gate
    transition zones (crossing and head-on, 8-45 m), away from the RB jump dead astern."""
    rng = np.random.default_rng(3)
    grad = jax.jit(jax.grad(docp_cost), static_argnames="settings")
    value = jax.jit(docp_cost, static_argnames="settings")
    route = np.array([[0.0, 0.0], [400.0, 0.0]])                          # one segment: no switch in the rollout
    n = SETTINGS.n_mpc
    checked = 0
    for _ in range(5):
        state0 = np.array([0.0, rng.uniform(-2.0, 2.0), rng.uniform(-0.2, 0.2), rng.uniform(0.6, 1.0)])
        targets = np.array([[rng.uniform(8.0, 20.0), rng.uniform(6.0, 14.0), -math.pi / 2 + rng.uniform(-0.3, 0.3),
                             rng.uniform(0.5, 1.0)],
                            [rng.uniform(25.0, 45.0), rng.uniform(-3.0, 3.0), math.pi + rng.uniform(-0.2, 0.2),
                             rng.uniform(0.3, 0.8)]])
        corridor = cross_track_corridor(np.stack([np.linspace(0.0, 8.0, n + 1), np.zeros(n + 1)], -1), BUF, 20.0)
        args = DocpArgs(jnp.asarray(state0), jnp.asarray(route), jnp.asarray(targets), jnp.asarray([0.8, 0.1]),
                        jnp.zeros(4), corridor, SmoothWeights(), ShipModel())
        u = np.stack([rng.uniform(0.2, 0.9, n), rng.uniform(-1.2, 1.2, n)], axis=-1)
        g = np.asarray(grad(jnp.asarray(u), args, settings=SETTINGS))
        h = 1e-6
        fd = np.zeros_like(u)
        for idx in np.ndindex(*u.shape):
            e = np.zeros_like(u)
            e[idx] = h
            fd[idx] = (float(value(jnp.asarray(u + e), args, settings=SETTINGS))
                       - float(value(jnp.asarray(u - e), args, settings=SETTINGS))) / (2 * h)
        np.testing.assert_allclose(g, fd, rtol=2e-5, atol=2e-6 * max(1.0, np.abs(fd).max()))
        checked += np.linalg.norm(g) > 1e-2
    assert checked == 5


# ================================================================================ compilation
def test_values_do_not_recompile():
    rng = np.random.default_rng(5)
    state0, target = random_situation(rng)
    smooth_sbmpc_step(state0, ROUTE, target, LAST, LAND, BUF, settings=SETTINGS)
    size = D._step_jit._cache_size()
    for k in range(3):
        state0, target = random_situation(rng)
        solver = DOCP_SOLVER.replace(tol=1e-3 * (k + 1), mu0=10.0 ** (k + 1), rel_tol=1e-6 / (k + 1))
        weights = SmoothWeights(kappa=5.0 + k, d_safe=8.0 + k, eps=10.0 ** -(6 + k), k_ntp=0.5 * (k + 1))
        step = smooth_sbmpc_step(state0, ROUTE, target, LAST + np.array([-0.1 * k, 0.05 * k]), LAND, BUF,
                                 weights=weights, settings=SETTINGS, solver=solver, segment=0)
        assert np.isfinite(float(step.cost))
    assert D._step_jit._cache_size() == size
    smooth_sbmpc_step(state0, ROUTE, target, LAST, LAND, BUF, settings=SETTINGS, n_starts=2)
    assert D._step_jit._cache_size() == size + 1                          # n_starts is static


# ================================================================================ multi-start
def test_multistart_vmap_equals_map_equals_a_loop_of_single_solves():
    rng = np.random.default_rng(1)
    state0, target = random_situation(rng)
    n_starts = 3
    prep = prepared(state0, target, n_starts)
    f, eq, ineq = problem(SETTINGS)
    lower, upper = bounds(SETTINGS.n_mpc, jnp.float64)
    loop = [solve_docp(f, u0, lower=lower, upper=upper, eq=eq, ineq=ineq, settings=DOCP_SOLVER, args=prep.args)
            for u0 in prep.starts]
    loop_f = np.array([float(r.f) for r in loop])
    loop_v = np.array([float(r.max_violation) for r in loop])
    best = int(best_index(jnp.asarray(loop_f), jnp.asarray(loop_v), DOCP_SOLVER.tol))
    steps = {b: smooth_sbmpc_step(state0, ROUTE, target, LAST, LAND, BUF, settings=SETTINGS, n_starts=n_starts,
                                  batch=b) for b in ("map", "vmap")}
    for b, st in steps.items():
        np.testing.assert_allclose(np.asarray(st.starts), np.asarray(prep.starts), rtol=0, atol=1e-12)
        np.testing.assert_allclose(np.asarray(st.start_cost), loop_f, rtol=1e-7, atol=1e-9)
        np.testing.assert_allclose(np.asarray(st.start_violation), loop_v, rtol=0, atol=1e-6)  # ~1e-7: rounding
        # the best start: the same one, or one whose cost ties with it to rounding (starts reaching one optimum)
        k = int(st.best)
        assert k == best or abs(loop_f[k] - loop_f[best]) <= 1e-7 * abs(loop_f[best]), b
        kept = safeguard(loop[k], prep.starts, f, lower=lower, upper=upper, eq=eq, ineq=ineq, args=prep.args,
                         tol=DOCP_SOLVER.tol)                 # against the best of the starts, as the step does
        assert int(st.warm_index) == int(kept.warm_index)
        np.testing.assert_allclose(np.asarray(st.controls), np.asarray(kept.u), rtol=0, atol=1e-7)
        assert float(st.cost) == pytest.approx(float(kept.f), rel=1e-7)
        assert bool(st.used_warm) == bool(kept.used_warm)
        assert int(st.iterations) >= n_starts            # (the counts themselves follow rounding: not compared)


def test_starts_are_psi_then_the_best_constant_behaviours_and_one_start_is_the_single_solve():
    rng = np.random.default_rng(2)
    state0, target = random_situation(rng)
    n = SETTINGS.n_mpc
    prep = prepared(state0, target, n_starts=5)
    table = np.asarray(behaviour_table(jnp.float64))
    assert table.shape == (len(COURSE_OFFSETS_DEG) * len(SPEED_FACTORS), 2)
    starts = np.asarray(prep.starts)
    np.testing.assert_array_equal(starts[0], np.asarray(prep.init.controls[:n]))
    cost = np.asarray(prep.init.first_cost)
    same = np.all(table[:, None, :] == starts[0][None], axis=(1, 2))
    order = np.argsort(np.where(same, np.inf, cost), kind="stable")[:4]
    for k, b in enumerate(order):
        np.testing.assert_array_equal(starts[1 + k], np.broadcast_to(table[b], (n, 2)))
    # one start: the plain solve from Ψ and its safeguard
    f, eq, ineq = problem(SETTINGS)
    lower, upper = bounds(n, jnp.float64)
    one = prepared(state0, target, n_starts=1)
    res = solve_docp(f, one.starts[0], lower=lower, upper=upper, eq=eq, ineq=ineq, settings=DOCP_SOLVER, args=one.args)
    kept = safeguard(res, one.starts[0], f, lower=lower, upper=upper, eq=eq, ineq=ineq, args=one.args,
                     tol=DOCP_SOLVER.tol)
    step = smooth_sbmpc_step(state0, ROUTE, target, LAST, LAND, BUF, settings=SETTINGS, n_starts=1)
    np.testing.assert_allclose(np.asarray(step.controls), np.asarray(kept.u), rtol=0, atol=1e-9)
    assert int(step.solver.inner_iterations) == int(res.inner_iterations) == int(step.iterations)


def test_segment_is_a_value():
    """The active segment as an argument equals slicing the route (same Ψ, same refined sequence)."""
    route = np.array([[-60.0, 0.0], [0.0, 0.0], [140.0, 0.0]])
    rng = np.random.default_rng(4)
    state0, target = random_situation(rng)
    a = smooth_sbmpc_step(state0, route, target, LAST, LAND, BUF, settings=SETTINGS, segment=1)
    b = smooth_sbmpc_step(state0, route[1:], target, LAST, LAND, BUF, settings=SETTINGS, segment=0)
    np.testing.assert_allclose(np.asarray(a.init.psi), np.asarray(b.init.psi), rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.asarray(a.controls), np.asarray(b.controls), rtol=0, atol=1e-9)
    np.testing.assert_array_equal(np.asarray(a.init.segment), np.asarray(b.init.segment) + 1)


# ================================================================================ corridor-bound optimum
def test_optimum_on_the_corridor_bound():
    """The warm start holds a 69° starboard offset; Γ wants smaller offsets, the full terminal state (Ψ's) and
    the corridor of Ψ constrain.  Over T_mpc = 8 s the terminal state leaves little room: the optimum without a
    binding corridor deviates ~3 cm to starboard of Ψ.  With a 2 cm corridor the optimum rides its starboard
    bound e⁺ (active to 1e-6 m, positive multiplier) and costs between the free optimum and the warm start."""
    from psbmpc_jax.smooth.init_stage import rollout_controls, route_path

    n = SETTINGS.n_mpc
    f, eq, ineq = problem(SETTINGS)
    lower, upper = bounds(n, jnp.float64)
    route = jnp.asarray([[0.0, 0.0], [400.0, 0.0]])
    state0 = jnp.asarray([0.0, 0.0, 0.0, 1.0])
    warm = jnp.broadcast_to(jnp.asarray([1.0, 1.2]), (n, 2))
    psi = rollout_controls(state0, route_path(route), warm, ShipModel(), SETTINGS.dt)
    out = {}
    for half_width in (20.0, 0.02):
        corridor = cross_track_corridor(psi[:, :2], buffered_chart([], SETTINGS.corridor_land_buffer), half_width)
        args = DocpArgs(state0, route, jnp.zeros((0, 4)), jnp.asarray([1.0, 0.0]), psi[n], corridor,
                        SmoothWeights(), ShipModel())
        res = solve_docp(f, warm, lower=lower, upper=upper, eq=eq, ineq=ineq, settings=DOCP_SOLVER, args=args)
        assert int(res.status) == 0 and float(res.max_violation) <= 1e-5
        lo, hi = (np.asarray(a)[1:] for a in cross_track_residuals(D._states(res.u, args, SETTINGS)[:, :2],
                                                                      corridor))
        out[half_width] = (res, lo, hi)
    free, _, free_hi = out[20.0]
    assert (free_hi + 20.0).max() > 0.025                                 # free optimum: beyond 2 cm to starboard
    res, lo, hi = out[0.02]
    active = int(np.argmax(hi))
    assert abs(hi[active]) <= 1e-6 and lo.max() < -1e-3                   # on e⁺, off e⁻
    assert float(res.lam_ineq[n + active]) > 1e-2                         # positive multiplier of that bound
    warm_cost = float(f(warm, args))
    assert float(free.f) < float(res.f) < warm_cost


# ================================================================================ validation
@pytest.mark.parametrize("kw, match", [
    (dict(state0=np.zeros(3)), "state0"), (dict(route=np.zeros((1, 2))), "route"),
    (dict(targets=np.zeros(4)), "targets"), (dict(last=np.zeros(3)), "last"),
    (dict(state0=np.array([0.0, np.nan, 0.0, 1.0])), "state0"), (dict(n_starts=0), "n_starts"),
    (dict(n_starts=41), "n_starts"), (dict(n_starts=2.0), "n_starts"), (dict(batch="pmap"), "batch"),
    (dict(segment=1), "segment"), (dict(segment=-1), "segment"), (dict(segment=0.5), "segment"),
    (dict(settings="fast"), "settings"), (dict(solver=dict(tol=1e-3)), "solver"),
    (dict(land="chart"), "land"),
])
def test_bad_inputs_are_refused(kw, match):
    args = dict(state0=np.array([0.0, 0.0, 0.0, 1.0]), route=ROUTE, targets=np.zeros((0, 4)), last=LAST,
                land=LAND, buffered_land=BUF)
    args.update({k: v for k, v in kw.items() if k in args})
    opts = {k: v for k, v in kw.items() if k not in args}
    with pytest.raises(ValueError, match=match):
        smooth_sbmpc_step(args["state0"], args["route"], args["targets"], args["last"], args["land"],
                          args["buffered_land"], **{"settings": SETTINGS, **opts})


# ================================================================================ previous-plan start
_prepare_prev = jax.jit(prepare_step, static_argnames=("settings", "n_starts"))


def test_previous_plan_is_start_one_and_without_one_the_starts_are_unchanged():
    rng = np.random.default_rng(11)
    state0, target = random_situation(rng)
    n = SETTINGS.n_mpc
    prev = np.stack([rng.uniform(0.1, 1.0, n), rng.uniform(-1.5, 1.5, n)], axis=-1)
    plain = prepared(state0, target, n_starts=4)

    def with_previous(valid):
        return _prepare_prev(jnp.asarray(state0), jnp.asarray(ROUTE), jnp.asarray(target), jnp.asarray(LAST),
                             jnp.asarray(0, jnp.int32), LAND, BUF, SmoothWeights(), ShipModel(), settings=SETTINGS,
                             n_starts=4, previous=D.Previous(jnp.asarray(prev), jnp.asarray(valid)))

    on, off = np.asarray(with_previous(True).starts), np.asarray(with_previous(False).starts)
    base = np.asarray(plain.starts)
    np.testing.assert_array_equal(off, base)                       # no previous plan: Ψ + 3 behaviours
    np.testing.assert_array_equal(on[0], base[0])                  # Ψ stays row 0 (the safeguard's fallback)
    np.testing.assert_array_equal(on[1], prev)
    np.testing.assert_array_equal(on[2:], base[1:3])               # then the two best behaviours


def test_shift_controls():
    c = np.arange(12.0).reshape(6, 2)
    np.testing.assert_array_equal(D.shift_controls(c, 0), c)
    np.testing.assert_array_equal(D.shift_controls(c, 2), np.concatenate([c[2:], c[-1:], c[-1:]]))
    np.testing.assert_array_equal(D.shift_controls(c, 6), np.repeat(c[-1:], 6, axis=0))
    batch = np.stack([c, -c])
    np.testing.assert_array_equal(D.shift_controls(batch, 1)[1], D.shift_controls(-c, 1))
    for bad in (-1, 7, 1.0, True):
        with pytest.raises(ValueError, match="steps"):
            D.shift_controls(c, bad)


def test_step_from_a_previous_plan_keeps_the_safeguard_and_resolving_from_its_own_plan_is_no_worse():
    """With the previous plan as start 1 the kept sequence is still never worse than Ψ (J_d, violation); and
    re-solving the same situation with the first solve's kept sequence as the previous plan ends at a J_d no
    higher than the first: the safeguard's reference is the best of the starts themselves, and that start is
    feasible at the first solve's J_d.  (The solver's own result from it need not be: the augmented Lagrangian
    restarts with zero multipliers, and on an H100 it ended 4e-4 higher; only the safeguard guarantees this.)"""
    rng = np.random.default_rng(5)
    for _ in range(3):
        state0, target = random_situation(rng)
        first = smooth_sbmpc_step(state0, ROUTE, target, LAST, LAND, BUF, settings=SETTINGS, n_starts=3)
        again = smooth_sbmpc_step(state0, ROUTE, target, LAST, LAND, BUF, settings=SETTINGS, n_starts=3,
                                  previous=np.asarray(first.controls))
        for st in (first, again):
            assert float(st.cost) <= float(st.warm_cost) * (1 + 1e-12) + 1e-12
            assert float(st.violation) <= 1e-3
            if bool(st.used_warm):                                   # the kept start, unchanged
                np.testing.assert_array_equal(np.asarray(st.controls), np.asarray(st.starts[int(st.warm_index)]))
        assert int(first.warm_index) == 0                            # Ψ: the behaviours miss its terminal state
        np.testing.assert_array_equal(np.asarray(again.starts[1]), np.asarray(first.controls))
        assert int(again.warm_index) in (0, 1)
        assert float(again.cost) <= float(first.cost) * (1 + 1e-12) + 1e-12


@pytest.mark.parametrize("kw, match", [
    (dict(previous=np.zeros((8, 2)) + [0.5, 0.0], n_starts=1), "n_starts >= 2"),
    (dict(previous=np.zeros((7, 2)) + [0.5, 0.0], n_starts=2), r"previous must be \[8, 2\]"),
    (dict(previous=np.zeros((8, 2)) + [0.5, 3.5], n_starts=2), "previous must lie in the route frame's box"),
    (dict(previous=np.zeros((8, 2)) + [0.05, 0.0], n_starts=2), "previous must lie in the route frame's box"),
    (dict(previous=np.full((8, 2), np.nan), n_starts=2), "previous must be finite"),
    (dict(previous=np.full((8, 2), "a"), n_starts=2), "previous must be numeric"),
])
def test_bad_previous_is_refused(kw, match):
    with pytest.raises(ValueError, match=match):
        smooth_sbmpc_step(np.array([0.0, 0.0, 0.0, 1.0]), ROUTE, np.zeros((0, 4)), LAST, LAND, BUF,
                          settings=SETTINGS, **kw)
