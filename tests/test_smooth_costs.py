"""Smooth-SBMPC cost components (psbmpc_jax.costs.sbmpc, psbmpc_jax.costs.manoeuvring) against the float64
oracle (psbmpc_jax.reference_smooth): risk pieces, the Boolean COLREGS indicator, the max-max / sum-sum
aggregations, Γ_johansen / Γ_smooth, gradients, the cost terms on a hand-made Context and through the
package's evaluator and objective, and parameter validation."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from psbmpc_jax import Obstacle, OwnShip, Params, PlannerConfig, Situation
from psbmpc_jax import reference as ref_mod
from psbmpc_jax import reference_smooth as rs
from psbmpc_jax.behaviours import enumerate_behaviours_deg
from psbmpc_jax.costs import manoeuvring as mv
from psbmpc_jax.costs import sbmpc as sb
from psbmpc_jax.costs.base import Context
from psbmpc_jax.evaluate import evaluate
from psbmpc_jax.objective import objective
from psbmpc_jax.ownship import Trajectory
from psbmpc_jax.packing import pack

from conftest import central_difference

LN99 = math.log(99.0)


def random_states(rng, shape, spread=40.0):
    return np.stack([rng.uniform(-spread, spread, shape), rng.uniform(-spread, spread, shape),
                     rng.uniform(-math.pi, math.pi, shape), rng.uniform(0.0, 2.0, shape)], axis=-1)


# ============================================================================ risk pieces
def test_sigma_coll_gate_c_000_1():
    d_safe = 12.0
    d = jnp.array([0.9 * d_safe, d_safe, 1.1 * d_safe, 0.0, 10 * d_safe])
    s = np.asarray(jax.jit(sb.sigma_coll)(d, d_safe))
    np.testing.assert_allclose(s[:3], [0.99, 0.5, 0.01], atol=1e-12)
    assert s[3] == pytest.approx(1.0, abs=1e-12) and s[4] == pytest.approx(0.0, abs=1e-12)
    assert sb.coll_slope(d_safe) == pytest.approx(-LN99 / (0.1 * d_safe)) and sb.coll_slope(d_safe) < 0
    np.testing.assert_allclose(s, [rs.sigma_coll(float(v), d_safe) for v in d], atol=1e-14)


def test_adhoc_risk_crisp_and_ungated():
    d_safe, p, q = 10.0, 1.0, 4.0
    d = np.array([2.0, 5.0, 9.99, 10.0, 10.01, 30.0, 0.0])
    t = np.array([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 2.0])
    f = jax.jit(sb.adhoc_risk, static_argnames="crisp")
    smooth, crisp = np.asarray(f(d, t, d_safe, p, q)), np.asarray(f(d, t, d_safe, p, q, crisp=True))
    np.testing.assert_allclose(smooth[:6], t[:6] ** -p * (d_safe / d[:6]) ** q, rtol=1e-14)
    np.testing.assert_allclose(crisp, np.where(d <= d_safe, smooth, 0.0), rtol=0, atol=0)
    assert smooth[6] == pytest.approx(0.5 * 1e3 ** 4)                      # d floored at 1e-3 d_safe
    for crisp_flag in (False, True):
        ref = [rs.adhoc_risk(a, b, d_safe, p, q, crisp=crisp_flag) for a, b in zip(d, t)]
        np.testing.assert_allclose(crisp if crisp_flag else smooth, ref, rtol=1e-13)
    g = jax.jit(jax.grad(lambda x: sb.adhoc_risk(x, 2.0, d_safe)))(0.0)
    assert np.isfinite(float(g))


@pytest.mark.parametrize("risk", sb.RISK_FORMS)
def test_collision_hazard_matches_the_oracle(risk):
    rng = np.random.default_rng(1)
    own, tgt = random_states(rng, 200, 15.0), random_states(rng, 200, 15.0)
    t = rng.uniform(0.5, 20.0, 200)
    kw = dict(d_safe=11.0, K_coll=0.7, p=1.3, q=3.0, w_coll=0.15, risk=risk)

    @jax.jit
    def f(own, tgt, t):
        c, _ = sb.pair_components(*own.T, *tgt.T, t, need=("coll",), **kw)
        return c

    got = np.asarray(f(own, tgt, t))
    ref = [rs.collision_hazard(o, x, s, **kw) for o, x, s in zip(own, tgt, t)]
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-10)
    assert np.count_nonzero(got > 1e-6) > 10                                # not vacuous
    vo = own[:, 3, None] * np.stack([np.cos(own[:, 2]), np.sin(own[:, 2])], 1)
    vi = tgt[:, 3, None] * np.stack([np.cos(tgt[:, 2]), np.sin(tgt[:, 2])], 1)
    np.testing.assert_allclose(np.asarray(sb.collision_weight(*vo.T, *vi.T, 0.7)),
                               0.7 * np.sum((vo - vi) ** 2, axis=1), rtol=1e-13)


def test_boolean_colregs_cases_and_oracle():
    own = np.array([0.0, 0.0, 0.0, 1.0])                                    # north at 1 m/s
    cases = {
        "head-on, slightly starboard": ([20.0, 2.0, math.pi, 1.0], 1.0),
        "crossing from starboard": ([15.0, 10.0, -math.pi / 2, 1.0], 1.0),
        "crossing from port": ([15.0, -10.0, math.pi / 2, 1.0], 0.0),
        "overtaken from starboard quarter": ([-10.0, 3.0, 0.2, 2.0], 0.0),
        "crossing from starboard, far": ([150.0, 100.0, -math.pi / 2, 1.0], 0.0),
    }
    f = jax.jit(sb.colregs_boolean, static_argnames=())
    for name, (tgt, expected) in cases.items():
        assert float(f(own, np.array(tgt), 40.0)) == expected, name
        assert rs.colregs_boolean(own, tgt, 40.0) == expected, name
    stopped = own.copy()
    stopped[3] = 0.0
    assert float(f(stopped, np.array(cases["crossing from starboard"][0]), 40.0)) == 0.0    # ‖v_o‖ guard
    rng = np.random.default_rng(2)
    o, x = random_states(rng, 400, 30.0), random_states(rng, 400, 30.0)
    got = np.asarray(f(o, x, 40.0))
    np.testing.assert_array_equal(got, [rs.colregs_boolean(a, b, 40.0) for a, b in zip(o, x)])
    assert 0 < got.sum() < len(got)


def test_aggregate():
    rng = np.random.default_rng(3)
    h = rng.uniform(0, 1, (5, 4, 3))
    valid = np.array([True, False, True, True])
    h[:, 1] = 99.0                                                          # a masked target
    np.testing.assert_allclose(np.asarray(sb.aggregate(h, "max", valid)), h[:, valid].max(axis=(0, 1)))
    np.testing.assert_allclose(np.asarray(sb.aggregate(h, "sum", valid)), h[:, valid].sum(axis=(0, 1)))
    np.testing.assert_allclose(np.asarray(sb.aggregate(h, "max")), 99.0)
    assert np.asarray(sb.aggregate(np.zeros((5, 0, 3)), "max")).tolist() == [0.0, 0.0, 0.0]
    with pytest.raises(ValueError, match="aggregation"):
        sb.aggregate(h, "mean")
    with pytest.raises(ValueError, match=r"\[K, I, \.\.\.\]"):
        sb.aggregate(np.zeros(5), "max")


# ============================================================================ sbmpc_costs vs the oracle
def random_encounter(rng, T=9, I=3):
    """Own-ship and targets on straight lines that pass close to each other (so every piece is active)."""
    t = np.arange(T) * 1.5
    chi_o, U_o = rng.uniform(-math.pi, math.pi), rng.uniform(0.5, 1.5)
    own = np.stack([U_o * t * math.cos(chi_o), U_o * t * math.sin(chi_o), np.full(T, chi_o), np.full(T, U_o)], 1)
    tg = []
    for _ in range(I):
        chi, U = rng.uniform(-math.pi, math.pi), rng.uniform(0.0, 1.5)
        meet = own[rng.integers(2, T)] [:2] + rng.normal(0, 4, 2)
        k = rng.integers(2, T)
        start = meet - U * t[k] * np.array([math.cos(chi), math.sin(chi)])
        tg.append(np.stack([start[0] + U * t * math.cos(chi), start[1] + U * t * math.sin(chi), np.full(T, chi),
                            np.full(T, U)], 1))
    return own, np.stack(tg, axis=1), t


COMBOS = [("max", "smooth", "fis", "default_false"), ("sum", "smooth", "fis", "literal"),
          ("max", "crisp", "boolean", "default_false"), ("sum", "crisp", "boolean", "default_false")]


@pytest.mark.parametrize("aggregation, risk, colregs, completion", COMBOS)
def test_sbmpc_costs_match_the_oracle(aggregation, risk, colregs, completion):
    rng = np.random.default_rng(4)
    kw = dict(d_safe=10.0, K_coll=1.3, p=1.0, q=4.0, w_coll=0.1, kappa=7.0, d_cl=30.0, e_cl=4.0, eps=1e-6,
              n_y=101, completion=completion, risk=risk, colregs=colregs)
    static = ("aggregation", "n_y", "completion", "risk", "colregs")
    f = jax.jit(sb.sbmpc_costs, static_argnames=static)
    spread = []
    for _ in range(6):
        own, tg, t = random_encounter(rng)
        got = f(own, tg, t, aggregation=aggregation, **kw)
        for comp in ("coll", "colregs", "joint"):
            ref = rs.sbmpc_cost(own, [tg[:, i] for i in range(tg.shape[1])], t, component=comp,
                                aggregation=aggregation, **kw)
            np.testing.assert_allclose(float(got[comp]), ref, rtol=1e-12, atol=1e-10, err_msg=comp)
        spread.append([float(got[c]) for c in ("coll", "colregs", "joint")])
        if aggregation == "sum":
            assert float(got["joint"]) == pytest.approx(float(got["coll"]) + float(got["colregs"]), rel=1e-12)
        else:
            lo, hi = max(float(got["coll"]), float(got["colregs"])), float(got["coll"]) + float(got["colregs"])
            assert lo * (1 - 1e-12) <= float(got["joint"]) <= hi * (1 + 1e-12)
    assert np.ptp(np.array(spread), axis=0).min() > 0                        # every component varies


def test_joint_max_is_not_the_sum_of_maxes():
    """Eq. (2) maximises σCR + κμ jointly: a collision risk at one time and a COLREGS violation at another
    count once, not twice."""
    t = np.array([0.0, 1.0, 2.0])
    own = np.array([[0, 0, 0, 1.0], [1, 0, 0, 1.0], [2, 0, 0, 1.0]])
    tg = np.array([[[30, 30, 0, 0.0]], [[3, 0, 0, 0.0]], [[2, 20, -math.pi / 2, 1.0]]])
    f = jax.jit(sb.sbmpc_costs, static_argnames=("aggregation", "risk", "colregs"))
    out = f(own, tg, t, aggregation="max", risk="crisp", colregs="boolean", d_safe=5.0, d_cl=40.0)
    # t=1: a stopped target 2 m ahead (risk, no violation); t=2: crossing from starboard at 20 m (violation,
    # no risk)
    coll = 1.0 * (5.0 / 2.0) ** 4 * 1.0
    assert float(out["coll"]) == pytest.approx(coll) and float(out["colregs"]) == 10.0
    assert float(out["joint"]) == pytest.approx(coll)                       # not coll + 10


def test_sbmpc_gradient_wrt_positions_and_no_nan():
    """Reverse-mode gradient of the DOCP sum (smooth risk + FIS) w.r.t. own-ship and target positions equals
    central differences; finite at d = 0 and with the own-ship stopped."""
    rng = np.random.default_rng(8)
    kw = dict(aggregation="sum", d_safe=10.0, d_cl=30.0, e_cl=4.0, n_y=51)

    def cost(own_xy, tg_xy, own, tg, t):
        own = own.at[:, :2].set(own_xy)
        tg = tg.at[:, :, :2].set(tg_xy)
        return sb.sbmpc_costs(own, tg, t, **kw)["joint"]

    vg = jax.jit(jax.value_and_grad(cost, argnums=(0, 1)))
    val = lambda *a: vg(*a)[0]                                              # noqa: E731 (one compile)
    nontrivial = 0
    for _ in range(3):
        own, tg, t = random_encounter(rng, T=5, I=2)
        own_xy, tg_xy = own[:, :2].copy(), tg[:, :, :2].copy()
        _, (g_own, g_tg) = vg(own_xy, tg_xy, own, tg, t)
        fd_own = central_difference(lambda p: float(val(p, tg_xy, own, tg, t)), own_xy, h=1e-5)
        fd_tg = central_difference(lambda p: float(val(own_xy, p, own, tg, t)), tg_xy, h=1e-5)
        scale = max(np.abs(fd_own).max(), np.abs(fd_tg).max(), 1.0)
        np.testing.assert_allclose(np.asarray(g_own), fd_own, rtol=1e-5, atol=1e-6 * scale)
        np.testing.assert_allclose(np.asarray(g_tg), fd_tg, rtol=1e-5, atol=1e-6 * scale)
        nontrivial += np.abs(fd_own).max() > 1e-3
    assert nontrivial >= 2
    # degenerate: target on the own-ship (d = 0) at every time, own-ship stopped
    own = np.zeros((5, 4))
    tg = np.zeros((5, 2, 4))
    tg[..., 3] = 1.0
    for speed in (0.0, 1.0):
        own[:, 3] = speed
        v, (g_own, g_tg) = vg(own[:, :2], tg[:, :, :2], own, tg, t)
        assert np.isfinite(float(v))
        assert np.all(np.isfinite(np.asarray(g_own))) and np.all(np.isfinite(np.asarray(g_tg)))


# ============================================================================ manoeuvring cost
W = dict(k_U=2.5, k_chi_port=1.8, k_chi_stbd=1.5, Delta_U=2.0, Delta_chi_port=1.2, Delta_chi_stbd=0.9)


def test_side_weights_proposed_form():
    deg = np.radians([-90.0, -5.0, 0.0, 5.0, 90.0])
    w = np.asarray(mv.side_weight(deg, 1.8, 1.5))
    np.testing.assert_allclose(w[[0, 4]], [1.8, 1.5], rtol=1e-12)
    np.testing.assert_allclose(w[[1, 3]], [0.99 * 1.8 + 0.01 * 1.5, 0.01 * 1.8 + 0.99 * 1.5], rtol=1e-12)
    assert w[2] == pytest.approx(1.65)
    assert mv.DEFAULT_S_CHI == pytest.approx(LN99 / math.radians(5.0)) and 52.6 < mv.DEFAULT_S_CHI < 52.7


@pytest.mark.parametrize("form, side", [("smooth", "change"), ("johansen", "change"), ("johansen", "offset")])
def test_gamma_matches_the_oracle(form, side):
    rng = np.random.default_rng(9)
    c = np.stack([rng.uniform(0.1, 1.0, 300), rng.uniform(-math.pi / 2, math.pi / 2, 300)], 1)
    last = np.stack([rng.uniform(0.1, 1.0, 300), rng.uniform(-math.pi / 2, math.pi / 2, 300)], 1)
    c[:20, 1] = rng.uniform(-0.1, 0.1, 20)                                  # inside the sigmoid transition
    g = np.asarray(jax.jit(mv.gamma, static_argnames=("form", "side"))(*c.T, *last.T, form=form, side=side, **W))
    ref_fn = rs.gamma_smooth if form == "smooth" else (lambda *a, **k: rs.gamma_johansen(*a, side=side, **k))
    np.testing.assert_allclose(g, [ref_fn(*a, *b, **W) for a, b in zip(c, last)], rtol=1e-13, atol=1e-12)
    seq = jax.jit(mv.gamma_sequence, static_argnames=("form", "side"))
    for n in (1, 7):
        got = float(seq(c[:n], last[0], form=form, side=side, **W))
        assert got > 0 and got == pytest.approx(rs.gamma_sequence(c[:n], last[0], form=form, side=side, **W),
                                                rel=1e-13)


def test_gamma_smooth_structure():
    """Port dearer than starboard, zero at (U_m, χ_m) = (1, 0) = last, squares (25), the smooth limit of the
    constant weights away from 0, and a gradient equal to central differences."""
    g = lambda u, chi, ul=1.0, cl=0.0: float(mv.gamma_smooth(u, chi, ul, cl, **W))
    assert g(1.0, 0.0) == 0.0
    a = math.radians(30)
    assert g(1.0, -a) > g(1.0, a)
    assert g(1.0, -a) == pytest.approx(1.8 * a * a + 1.2 * a * a, rel=1e-6)
    assert g(0.5, 0.0) == pytest.approx(2.5 * 0.25 + 2.0 * 0.25)
    assert g(1.0, a, 1.0, a) == pytest.approx(1.5 * a * a, rel=1e-6)        # no change: only k_χ
    grad = jax.jit(jax.grad(lambda x: mv.gamma_sequence(x, jnp.array([0.8, 0.1]), **W)))
    val = jax.jit(lambda x: mv.gamma_sequence(x, jnp.array([0.8, 0.1]), **W))
    x = np.array([[0.6, 0.02], [0.9, -0.04], [0.5, 0.5], [0.5, -0.3]])
    np.testing.assert_allclose(np.asarray(grad(x)), central_difference(lambda v: float(val(v)), x), rtol=1e-6,
                               atol=1e-8)


def test_per_step_controls_match_the_oracle():
    beh = np.array([[0.5, 0.3], [1.0, -0.2], [0.1, 0.0]])
    expand = jax.jit(mv.per_step_controls, static_argnames="n_steps")
    for t_ts in (float("nan"), 4.0, 2.6):
        got = np.asarray(expand(beh[None], 10, 1.0, t_ts))[0]
        np.testing.assert_array_equal(got, rs.per_step_controls(beh, 10, 1.0, t_ts))
    assert np.asarray(expand(beh[None], 10, 1.0, 4.0))[0, :, 0].tolist() == [0.5] * 4 + [1.0] * 4 + [0.1] * 2


# ============================================================================ terms on a hand-made Context
def make_context(rng, B=3, O=3, S=2, T=8, dt=1.0):
    """Own-ship rows and (obstacle, scenario) targets that come close; obstacle 2 and scenario 1 of every
    obstacle are padding (masked), parked on the own-ship."""
    t = np.arange(T) * dt
    own = []
    for b in range(B):
        chi, U = 0.3 * b - 0.3, 1.0 - 0.2 * b
        own.append(np.stack([U * t * math.cos(chi), U * t * math.sin(chi), np.full(T, chi), np.full(T, U)], 1))
    own = np.stack(own, axis=1)                                             # [T, B, 4]
    obs = np.zeros((T, O, S, 4))
    for o in range(O):
        for s in range(S):
            chi, U = rng.uniform(-math.pi, math.pi), rng.uniform(0.2, 1.5)
            start = np.array([5.0, 0.0]) + rng.normal(0, 3, 2) - U * 5 * np.array([math.cos(chi), math.sin(chi)])
            obs[:, o, s] = np.stack([start[0] + U * t * math.cos(chi), start[1] + U * t * math.sin(chi),
                                     np.full(T, chi), np.full(T, U)], 1)
    valid = np.array([[True, False], [True, False], [False, False]])
    obs[:, ~valid] = own[:, :1]                                             # hostile padding: d = 0 to row 0
    traj = lambda a: Trajectory(*(jnp.asarray(v) for v in (a[..., 0], a[..., 1], a[..., 2], a[..., 3],
                                                            np.cos(a[..., 2]), np.sin(a[..., 2]))))
    offsets = np.array([[[1.0, -0.3]], [[0.8, 0.0]], [[0.6, 0.3]]])[:B]
    ctx = Context(t=jnp.asarray(t), offsets=jnp.asarray(offsets), last_offsets=jnp.asarray([0.9, 0.1]),
                  own=traj(own), obstacles=traj(obs), obs_cov=None, cov_stats=None, scen_valid=jnp.asarray(valid),
                  radius=None, zeta_k=None, scen_weight=None, world=None, dense=True)
    targets = [obs[:, o, s] for o in range(O) for s in range(S) if valid[o, s]]
    return ctx, own, targets, t


@jax.jit
def run_term(term, ctx):
    return term(ctx, Params(), PlannerConfig(T=7.0, dt=1.0, dtype="float64"), None)


TERMS = [
    (sb.SmoothCollisionTerm, dict(d_safe=6.0, K_coll=1.5), "coll"),
    (sb.SmoothCollisionTerm, dict(d_safe=6.0, risk="crisp"), "coll"),
    (sb.FuzzyColregsTerm, dict(kappa=4.0, d_cl=25.0, n_y=41), "colregs"),
    (sb.SbmpcHazardTerm, dict(d_safe=6.0, d_cl=25.0, n_y=41), "joint"),
    (sb.SbmpcHazardTerm, dict(d_safe=6.0, risk="crisp", colregs="boolean"), "joint"),
]


@pytest.mark.parametrize("aggregation", sb.AGGREGATIONS)
@pytest.mark.parametrize("cls, kw, component", TERMS)
def test_terms_on_a_context_match_the_oracle(cls, kw, component, aggregation):
    ctx, own, targets, t = make_context(np.random.default_rng(12))
    term = cls(aggregation=aggregation, **kw)
    out = run_term(term, ctx)
    okw = {k: v for k, v in kw.items() if k != "kappa"}
    ref = [rs.sbmpc_cost(own[:, b], targets, t, component=component, aggregation=aggregation,
                         kappa=kw.get("kappa", 10.0), **okw) for b in range(own.shape[1])]
    np.testing.assert_allclose(np.asarray(out.value), ref, rtol=1e-12, atol=1e-10)
    assert np.ptp(ref) > 0                                                  # rows differ: not vacuous
    (detail,) = out.details.values()
    assert detail.shape == (3, 3, 2) and np.all(np.asarray(detail)[:, ~np.asarray(ctx.scen_valid)] == 0)
    agg = np.max if aggregation == "max" else np.sum
    np.testing.assert_allclose(agg(np.asarray(detail).reshape(3, -1), axis=1), np.asarray(out.value), rtol=1e-12)


def test_numeric_fields_are_traced_and_static_fields_recompile():
    ctx, *_ = make_context(np.random.default_rng(12))
    run_term(sb.SbmpcHazardTerm(kappa=1.0, n_y=41), ctx)
    n0 = run_term._cache_size()
    v1 = run_term(sb.SbmpcHazardTerm(kappa=3.0, d_safe=7.0, n_y=41), ctx).value
    assert run_term._cache_size() == n0                                     # new values: no recompile
    run_term(sb.SbmpcHazardTerm(kappa=3.0, n_y=43, aggregation="sum"), ctx)
    assert run_term._cache_size() == n0 + 1                                 # a static field: one more
    leaves, treedef = jax.tree_util.tree_flatten(sb.SbmpcHazardTerm(kappa=3.0, d_safe=7.0, n_y=41))
    assert all(not isinstance(v, str) for v in leaves)
    again = jax.tree_util.tree_unflatten(treedef, leaves)
    assert again == sb.SbmpcHazardTerm(kappa=3.0, d_safe=7.0, n_y=41)
    assert np.all(np.isfinite(np.asarray(v1)))


@pytest.mark.parametrize("aggregation", sb.AGGREGATIONS)
@pytest.mark.parametrize("form", mv.FORMS)
def test_manoeuvring_term_on_a_context(aggregation, form):
    ctx, *_ = make_context(np.random.default_rng(12))
    out = run_term(mv.SmoothManoeuvringTerm(aggregation=aggregation, form=form, k_U=3.0), ctx)
    w = dict(W, k_U=3.0)
    ref = [rs.manoeuvring_cost(np.asarray(ctx.offsets[b]), [0.9, 0.1], n_steps=7, dt=1.0, aggregation=aggregation,
                               form=form, **w) for b in range(3)]
    np.testing.assert_allclose(np.asarray(out.value), ref, rtol=1e-13)
    if aggregation == "max":                                                # one constant behaviour: Γ(u; last)
        fn = rs.gamma_smooth if form == "smooth" else rs.gamma_johansen
        np.testing.assert_allclose(ref, [fn(*np.asarray(ctx.offsets[b, 0]), 0.9, 0.1, **w) for b in range(3)])
    else:                                  # N = 7 steps of one constant behaviour: Γ(u; last) + 6 Γ(u; u)
        fn = rs.gamma_smooth if form == "smooth" else rs.gamma_johansen
        np.testing.assert_allclose(ref, [fn(*np.asarray(ctx.offsets[b, 0]), 0.9, 0.1, **w)
                                         + 6 * fn(*np.asarray(ctx.offsets[b, 0]), *np.asarray(ctx.offsets[b, 0]), **w)
                                         for b in range(3)], rtol=1e-13)


# ============================================================================ through evaluate / objective
SEARCH = enumerate_behaviours_deg(((0.1, 0.5, 1.0),), ((-90, -75, -60, -45, -30, -15, 0, 15, 30, 45, 60, 75, 90),))
COV = np.diag([1.0, 1.0, 0.1, 0.1])


def smooth_sbmpc_situation():
    own = OwnShip(state=[0.0, 0.0, 0.0, 1.0], waypoints=np.array([[0.0, 0.0], [200.0, 0.0]]), U_d=1.0)
    obstacles = (Obstacle([25.0, 3.0, -1.0, 0.0], COV, n_ps=1), Obstacle([15.0, -12.0, 0.0, 0.8], COV, n_ps=1),
                 Obstacle([12.0, 14.0, 0.0, -0.9], COV, n_ps=1))
    return Situation(own, obstacles)


def test_grid_search_with_the_smooth_terms_matches_the_reference():
    """The initialisation-stage search (39 constant behaviours, "max" aggregation) through the jitted
    evaluator equals the terms' float64 reference counterparts (evaluate_reference(extra_terms=...))."""
    cfg = PlannerConfig(T=20.0, dt=1.0, dtype="float64")
    sit = smooth_sbmpc_situation()
    terms = (sb.SbmpcHazardTerm(n_y=101), mv.SmoothManoeuvringTerm(), sb.FuzzyColregsTerm(n_y=101))
    ev = evaluate(pack(sit, SEARCH, cfg), jnp.asarray([1.0, 0.0]), Params(), None, config=cfg, terms=terms)
    rows = [0, 5, 6, 9, 18, 19, 25, 32, 38]
    ref = ref_mod.evaluate_reference(sit, SEARCH[rows], Params(), cfg, extra_terms=terms)
    for term in terms:
        got = np.asarray(ev.costs[term.name])[rows]
        np.testing.assert_allclose(got, ref.extra[term.name], rtol=1e-10, atol=1e-10, err_msg=term.name)
        assert np.ptp(got) > 0, term.name
    total = np.asarray(ev.total)[: len(SEARCH)]
    assert np.all(np.isfinite(total)) and int(ev.best) < len(SEARCH)


def test_docp_objective_per_step_sum_terms_gradient():
    """The DOCP form (per-step controls, "sum" aggregation) through psbmpc_jax.objective: finite value and
    gradient equal to central differences (a few coordinates), and the manoeuvring term equals Γ summed over
    the steps with last = previous step."""
    cfg = PlannerConfig(T=12.0, dt=1.0, dtype="float64")
    sit = smooth_sbmpc_situation()
    inputs = pack(sit, SEARCH[:1], cfg)
    terms = (sb.SmoothCollisionTerm(aggregation="sum"), sb.FuzzyColregsTerm(aggregation="sum", n_y=51),
             mv.SmoothManoeuvringTerm(aggregation="sum"))
    last = jnp.asarray([0.9, 0.05])

    def f(c):
        total, costs = objective(c, inputs, Params(), None, cfg, terms, last_offsets=last, per_step=True)
        return total, costs

    vg = jax.jit(jax.value_and_grad(f, has_aux=True))
    rng = np.random.default_rng(0)
    u = np.stack([rng.uniform(0.5, 1.0, 12), rng.uniform(-0.4, 0.4, 12)], axis=1)
    (total, costs), g = vg(u)
    g = np.asarray(g)
    assert np.isfinite(float(total)) and np.all(np.isfinite(g)) and np.abs(g).max() > 0
    assert float(costs["manoeuvring"]) == pytest.approx(rs.gamma_sequence(u, np.asarray(last), **W), rel=1e-12)
    for idx in [(0, 1), (3, 0), (5, 1), (11, 1)]:
        e = np.zeros_like(u)
        e[idx] = 1e-6
        fd = (float(vg(u + e)[0][0]) - float(vg(u - e)[0][0])) / 2e-6
        assert g[idx] == pytest.approx(fd, rel=1e-5, abs=1e-7), idx


# ============================================================================ validation
@pytest.mark.parametrize("cls, kw, match", [
    (sb.SmoothCollisionTerm, dict(d_safe=0.0), "d_safe"),
    (sb.SmoothCollisionTerm, dict(K_coll=-1.0), "K_coll"),
    (sb.SmoothCollisionTerm, dict(w_coll=0.0), "w_coll"),
    (sb.SmoothCollisionTerm, dict(aggregation="mean"), "aggregation"),
    (sb.SmoothCollisionTerm, dict(risk="soft"), "risk"),
    (sb.FuzzyColregsTerm, dict(eps=-1e-6), "eps"),
    (sb.FuzzyColregsTerm, dict(n_y=1), "n_y"),
    (sb.FuzzyColregsTerm, dict(kappa=-1.0), "kappa"),
    (sb.FuzzyColregsTerm, dict(e_cl=0.0), "e_cl"),
    (sb.SbmpcHazardTerm, dict(colregs="rules"), "colregs"),
    (sb.SbmpcHazardTerm, dict(q=-4.0), "q"),
    (sb.SbmpcHazardTerm, dict(completion="none"), "completion"),
    (mv.SmoothManoeuvringTerm, dict(k_chi_port=-1.0), "k_chi_port"),
    (mv.SmoothManoeuvringTerm, dict(s_chi=0.0), "s_chi"),
    (mv.SmoothManoeuvringTerm, dict(form="quadratic"), "form"),
    (mv.SmoothManoeuvringTerm, dict(side="both"), "side"),
    (mv.SmoothManoeuvringTerm, dict(aggregation="min"), "aggregation"),
])
def test_bad_term_parameters_are_refused(cls, kw, match):
    with pytest.raises(ValueError, match=match):
        cls(**kw)


def test_bad_function_arguments_are_refused():
    with pytest.raises(ValueError, match="d_safe"):
        sb.sigma_coll(1.0, -2.0)
    with pytest.raises(ValueError, match="p must"):
        sb.adhoc_risk(1.0, 1.0, 10.0, p=-1.0)
    with pytest.raises(ValueError, match="own_traj"):
        sb.sbmpc_costs(np.zeros((5, 4)), np.zeros((4, 2, 4)), np.arange(5.0))
    with pytest.raises(ValueError, match="t must"):
        sb.sbmpc_costs(np.zeros((5, 4)), np.zeros((5, 2, 4)), np.arange(4.0))
    with pytest.raises(ValueError, match="controls"):
        mv.gamma_sequence(np.zeros((3, 3)), np.zeros(2))
    with pytest.raises(ValueError, match="Delta_U"):
        mv.gamma_smooth(1.0, 0.0, 1.0, 0.0, Delta_U=-2.0)
