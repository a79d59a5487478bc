"""The Informed SB-MPC cost (seed 002; psbmpc_jax.costs.informed) against hand values and its float64 oracle
(psbmpc_jax.reference_informed): the adaptive safety distance (10), the Woerner-threshold COLREGS indicator (5)
in both classification modes, the Rule-18 term (6), the grounding penalty (8), the term on a hand-made Context
and through the evaluator with and without Rule-18 targets, the effect of P_R18 in a stand-on crossing, edge
cases (d = 0, zero speeds, no targets, inside land, float32) and parameter validation."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from psbmpc_jax import Obstacle, OwnShip, Params, PlannerConfig, Situation
from psbmpc_jax import reference as ref_mod
from psbmpc_jax import reference_prediction as pred
from psbmpc_jax import reference_informed as ri
from psbmpc_jax import reference_smooth as rs
from psbmpc_jax.behaviours import enumerate_behaviours_deg
from psbmpc_jax.costs import informed as inf
from psbmpc_jax.costs import manoeuvring as mv
from psbmpc_jax.costs import sbmpc as sb
from psbmpc_jax.costs.base import Context, cost_term
from psbmpc_jax.evaluate import evaluate
from psbmpc_jax.ownship import Trajectory
from psbmpc_jax.packing import pack, pack_world

D = math.pi / 180.0
SEARCH = enumerate_behaviours_deg(((1.0, 0.5, 0.0),), (tuple(range(-90, 91, 15)),))       # 002's 39 (C-002-10)
#: Ship-scale lags (116 m PSVs): the library's 5 m-boat defaults are unstable at dt = 5 s.
PARAMS = Params(os_T_chi=15.0, os_T_U=30.0, ob_T_chi=15.0, ob_T_U=30.0, os_lookahead=400.0, ob_lookahead=400.0)
COV = np.diag([25.0, 25.0, 1.0, 1.0])
OWN = np.array([0.0, 0.0, 0.0, 5.0])                       # north at 5 m/s


def with_roles(ctx, r18):
    """``ctx`` with the Rule-18 mask ``obstacle_r18`` replaced."""
    return ctx._replace(obstacle_r18=r18)


@cost_term
class Roles:
    """Test wrapper: the informed term with a given per-obstacle Rule-18 mask in the context (and in its
    reference)."""

    name = "informed"
    inner: object
    r18: object

    def __call__(self, ctx, params, config, samples):
        return self.inner(with_roles(ctx, self.r18), params, config, samples)

    def reference(self, own_traj, behaviour, situation, params, config):
        r18 = np.asarray(self.r18)[: len(situation.obstacles)]
        return self.inner.reference(own_traj, behaviour, situation, params, config, r18=r18)


def state(x, y, chi, U):
    return np.array([x, y, chi, U], float)


def jax_mu(own, tgt, d_close=1800.0, classify="velocity"):
    t0 = (own[0], own[1], own[2], tgt[0], tgt[1], tgt[2]) if classify == "sectors_t0" else None
    return float(inf.colregs_woerner(*own, *tgt, d_close, classify=classify, t0=t0))


def ref_mu(own, tgt, d_close=1800.0, classify="velocity"):
    beta, alpha = ri.beta_alpha(own, tgt)
    flags = ri.flags_velocity(own, tgt) if classify == "velocity" else ri.flags_sectors(beta, alpha)
    return ri.mu(beta, math.hypot(tgt[0] - own[0], tgt[1] - own[1]), flags, d_close)


# ============================================================================ adaptive d_safe (10)
def test_adaptive_d_safe_hand_values():
    beta = np.array([0.0, 45.0, 90.0, 135.0, 180.0]) * D
    k2 = np.asarray(inf.adaptive_d_safe(beta, 500.0, 2.0, 1.0))
    np.testing.assert_allclose(k2, [500, 309, 144, 76, 46], atol=0.5)              # SPEC §3.4, k = 2
    # SPEC §3.4 k = 1 row "500/280/195/149/121": 500/(π/2 + 1) = 194.49, so 1 m tolerance
    np.testing.assert_allclose(np.asarray(inf.adaptive_d_safe(beta, 500.0, 1.0, 1.0)), [500, 280, 195, 149, 121],
                               atol=1.0)
    np.testing.assert_allclose(np.asarray(inf.adaptive_d_safe(-beta, 500.0, 2.0, 1.0)), k2)   # symmetric
    np.testing.assert_allclose(np.asarray(inf.adaptive_d_safe(beta, 500.0, 0.0, 1.0)), 250.0)  # k = 0: a circle
    np.testing.assert_allclose(k2, [ri.d_safe(b, 500.0, 2.0, 1.0) for b in beta], rtol=1e-14)
    g = jax.grad(lambda b: inf.adaptive_d_safe(b, 500.0, 2.0, 1.0))(0.0)
    assert np.isfinite(float(g))


# ============================================================================ COLREGS (5)
MU_CASES = {
    # name: (target state, μ)      own-ship: (0, 0), north, 5 m/s
    "head-on, starboard bow": (state(1000.0, 50.0, math.pi, 5.0), 1.0),
    "head-on, port bow 20 deg": (state(1000 * math.cos(20 * D), -1000 * math.sin(20 * D), math.pi, 5.0), 0.0),
    "head-on, port bow 5 deg (R14: beta > -13 deg)": (state(1000 * math.cos(5 * D), -1000 * math.sin(5 * D),
                                                            math.pi, 5.0), 1.0),
    "crossing from starboard": (state(800.0, 800.0, -math.pi / 2, 5.0), 1.0),
    "crossing from port": (state(800.0, -800.0, math.pi / 2, 5.0), 0.0),
    "overtaken (target from astern, faster)": (state(-300.0, 20.0, 0.0, 8.0), 0.0),
    "overtaking, target dead ahead": (state(500.0, 0.0, 0.0, 2.0), 1.0),
    "overtaking, target 30 deg to starboard": (state(500 * math.cos(30 * D), 500 * math.sin(30 * D), 0.0, 2.0), 0.0),
    "crossing from starboard, beyond d_close": (state(1400.0, 1400.0, -math.pi / 2, 5.0), 0.0),
}


@pytest.mark.parametrize("classify", inf.CLASSIFY)
@pytest.mark.parametrize("name", list(MU_CASES))
def test_woerner_mu_by_hand(name, classify):
    tgt, expected = MU_CASES[name]
    assert jax_mu(OWN, tgt, classify=classify) == expected, name
    assert ref_mu(OWN, tgt, classify=classify) == expected, name


def test_woerner_differs_from_johansen_and_between_modes():
    port5 = MU_CASES["head-on, port bow 5 deg (R14: beta > -13 deg)"][0]
    assert rs.colregs_boolean(OWN, port5, 1800.0) == 0.0 and jax_mu(OWN, port5) == 1.0    # R14's 13° port margin
    parked = state(500.0, 0.0, 0.0, 0.0)              # a stopped target dead ahead, heading north
    assert jax_mu(OWN, parked) == 0.0                 # velocity flags: not crossing, not overtaking (‖v_i‖ = 0)
    assert jax_mu(OWN, parked, classify="sectors_t0") == 1.0      # sectors: overtaking (|α| = 180°), R13
    assert ref_mu(OWN, parked, classify="sectors_t0") == 1.0 and ref_mu(OWN, parked) == 0.0


@pytest.mark.parametrize("classify", inf.CLASSIFY)
def test_woerner_mu_matches_the_oracle_on_random_states(classify):
    rng = np.random.default_rng(5)
    n = 600
    own = np.stack([rng.uniform(-800, 800, n), rng.uniform(-800, 800, n), rng.uniform(-math.pi, math.pi, n),
                    rng.uniform(0.0, 6.0, n)], 1)
    tgt = np.stack([rng.uniform(-800, 800, n), rng.uniform(-800, 800, n), rng.uniform(-math.pi, math.pi, n),
                    rng.uniform(0.0, 6.0, n)], 1)
    t0 = (own[:, 0], own[:, 1], own[:, 2], tgt[:, 0], tgt[:, 1], tgt[:, 2]) if classify == "sectors_t0" else None
    got = np.asarray(jax.jit(lambda o, x: inf.colregs_woerner(*o.T, *x.T, 1000.0, classify=classify, t0=t0))(own, tgt))
    ref = [ref_mu(a, b, 1000.0, classify) for a, b in zip(own, tgt)]
    np.testing.assert_array_equal(got, ref)
    assert 0.1 < got.mean() < 0.9


# ============================================================================ Rule 18 (6)
ZETA_CASES = {
    # target state, expected ζ (m = 1.1, n = 1); own-ship (0, 0) north
    "target ahead of us (beta = 0, alpha = 90: first branch wins)": (state(1000.0, 0.0, math.pi / 2, 3.0), 1.1),
    "us ahead of the target (alpha = -16.7)": (state(-1000.0, 300.0, 0.0, 3.0), 1.1),
    "us 45 deg on the target's bow": (state(-700.0, -700.0, 0.0, 3.0), 1.0),
    "us abaft the target's beam, target 50 deg to starboard": (state(500.0, 600.0, 0.0, 3.0), 0.0),
    "astern of each other": (state(-600.0, -600.0, math.pi, 3.0), 0.0),
}


@pytest.mark.parametrize("name", list(ZETA_CASES))
def test_rule18_zeta_by_hand(name):
    tgt, expected = ZETA_CASES[name]
    beta = float(inf.relative_bearing(*OWN[:3], *tgt[:2]))
    alpha = float(inf.contact_angle(*OWN[:2], *tgt[:3]))
    d = math.hypot(*tgt[:2])
    assert float(inf.rule18_zeta(beta, alpha, d=d, d_close=1800.0)) == pytest.approx(expected), name
    assert ri.zeta(*ri.beta_alpha(OWN, tgt), d, 1800.0) == pytest.approx(expected), name
    assert float(inf.rule18_zeta(beta, alpha, d=d, d_close=0.5 * d)) == 0.0                # the d_close gate
    assert float(inf.rule18_zeta(beta, alpha, 2.0, 0.5)) == {1.1: 2.0, 1.0: 0.5, 0.0: 0.0}[expected]


def test_rule18_zeta_boundaries_and_bearings():
    # |α| = 90° is still n, 22.5° < |α| ≤ 90° gives n; the gate is d ≤ d_close (inclusive)
    z = np.asarray(inf.rule18_zeta(np.full(4, 100 * D), np.array([90.0, 90.01, 22.5, -22.6]) * D))
    np.testing.assert_allclose(z, [1.0, 0.0, 1.1, 1.0])
    assert float(inf.rule18_zeta(0.0, 180 * D, d=1800.0, d_close=1800.0)) == pytest.approx(1.1)
    # bearings: clockwise positive (starboard), α relative to the target's heading
    assert float(inf.relative_bearing(0.0, 0.0, 0.0, 0.0, 100.0)) == pytest.approx(math.pi / 2)
    assert float(inf.relative_bearing(0.0, 0.0, math.pi / 2, 100.0, 0.0)) == pytest.approx(-math.pi / 2)
    assert float(inf.contact_angle(0.0, 0.0, 100.0, 0.0, math.pi / 2)) == pytest.approx(math.pi / 2)
    assert float(inf.relative_bearing(0.0, 0.0, 0.3, 0.0, 0.0)) == 0.0                     # d = 0


# ============================================================================ grounding (8)
def test_grounding_penalty_by_hand():
    d = np.array([100.0, 200.0, 200.01, 0.0, 0.05, 50.0])
    t = np.array([5.0, 4.0, 5.0, 5.0, 5.0, 10.0])
    g = np.asarray(inf.grounding_penalty(d, t, 200.0, 1.0, 4.0))
    np.testing.assert_allclose(g, [16.0 / 5, 1.0 / 4, 0.0, 2000.0 ** 4 / 5, 2000.0 ** 4 / 5, 256.0 / 10], rtol=1e-12)
    np.testing.assert_allclose(g, [ri.grounding(a, b, 200.0, 1.0, 4.0) for a, b in zip(d, t)], rtol=1e-13)
    g32 = np.asarray(inf.grounding_penalty(jnp.asarray(d, jnp.float32), jnp.asarray(t, jnp.float32), 200.0, 1.0, 4.0))
    assert g32.dtype == np.float32 and np.all(np.isfinite(g32))                            # d = 0: clamped, finite
    np.testing.assert_allclose(g32, g, rtol=1e-5)
    assert np.isfinite(float(jax.grad(lambda x: inf.grounding_penalty(x, 5.0))(0.0)))


# ============================================================================ the term on a hand-made Context
def make_context(rng, B=4, O=3, S=2, T=41, dt=5.0, dtype=np.float64, polygons=None):
    """Own-ship rows on straight lines (north at 5 m/s, courses −30°…+45°) and straight-line targets that pass
    near them; obstacle 2 and scenario 1 of obstacles 0/1 are padding, parked on row 0 (d = 0).  An island at
    (900, 250) unless ``polygons`` is given."""
    t = np.arange(T) * dt
    own = []
    for b in range(B):
        chi, U = (-30.0 + 25.0 * b) * D, 5.0 - 0.5 * b
        own.append(np.stack([U * t * math.cos(chi), U * t * math.sin(chi), np.full(T, chi), np.full(T, U)], 1))
    own = np.stack(own, axis=1)
    obs = np.zeros((T, O, S, 4))
    for o in range(O):
        for s in range(S):
            chi, U = rng.uniform(-math.pi, math.pi), rng.uniform(0.0, 6.0)
            meet = rng.uniform(50.0, 180.0)
            start = np.array([5.0 * meet, 0.0]) + rng.normal(0, 150, 2) - U * meet * np.array([math.cos(chi),
                                                                                               math.sin(chi)])
            obs[:, o, s] = np.stack([start[0] + U * t * math.cos(chi), start[1] + U * t * math.sin(chi),
                                     np.full(T, chi), np.full(T, U)], 1)
    valid = np.zeros((O, S), bool)
    valid[0, 0] = valid[1, :] = True
    obs[:, ~valid] = own[:, :1]
    traj = lambda a: Trajectory(*(jnp.asarray(v, dtype) for v in (a[..., 0], a[..., 1], a[..., 2], a[..., 3],
                                                                   np.cos(a[..., 2]), np.sin(a[..., 2]))))
    if polygons is None:
        polygons = (np.array([[850.0, 200.0], [950.0, 200.0], [950.0, 300.0], [850.0, 300.0]]),)
    cfg = PlannerConfig(T=(T - 1) * dt, dt=dt, dtype=np.dtype(dtype).name)
    world = jax.tree.map(jnp.asarray, pack_world(polygons, cfg))
    ctx = Context(t=jnp.asarray(t, dtype), offsets=jnp.zeros((B, 1, 2), dtype), last_offsets=jnp.asarray([1.0, 0.0]),
                  own=traj(own), obstacles=traj(obs), obs_cov=None, cov_stats=None, scen_valid=jnp.asarray(valid),
                  radius=None, zeta_k=None, scen_weight=None, world=world, dense=False)
    targets = [obs[:, o, s] for o in range(O) for s in range(S) if valid[o, s]]
    obstacle_of = [o for o in range(O) for s in range(S) if valid[o, s]]
    return ctx, own, targets, obstacle_of, t, polygons, cfg


@jax.jit
def run_term(term, ctx):
    return term(ctx, Params(), PlannerConfig(T=200.0, dt=5.0, dtype="float64"), None)


def ref_rows(term, own, targets, roles, t, polygons):
    kw = {name: float(getattr(term, name)) for name in term.PARAMS}
    return [ri.informed_cost(own[:, b], targets, roles, t, polygons, classify=term.classify, circular=term.circular,
                             grounding_on=term.grounding, **kw) for b in range(own.shape[1])]


TERM_CASES = [
    dict(),
    dict(classify="sectors_t0"),
    dict(circular=True, c_dist=300.0, c_dist_r18=600.0),
    dict(K_coll=2.0, kappa=1.0, rho=0.5, p=0.7, q=3.0, d_close=900.0, k=1.0, l=0.5, m=2.0, n=0.5, gamma=3.0,
         p_g=0.5, q_g=2.0, d_static_safe=300.0, K_coll_r18=4.0, kappa_r18=2.0, rho_r18=5.0, p_r18=1.5, q_r18=2.0,
         d_close_r18=1200.0),
]


@pytest.mark.parametrize("roles", [None, (True, False, False), (False, True, True)])
@pytest.mark.parametrize("kw", TERM_CASES)
def test_term_on_a_context_matches_the_oracle(kw, roles):
    ctx, own, targets, obstacle_of, t, polygons, _ = make_context(np.random.default_rng(7))
    term = inf.InformedSbmpcTerm(**kw)
    out = run_term(term, ctx if roles is None else with_roles(ctx, jnp.asarray(roles)))
    target_roles = [False] * len(targets) if roles is None else [roles[o] for o in obstacle_of]
    ref = ref_rows(term, own, targets, target_roles, t, polygons)
    np.testing.assert_allclose(np.asarray(out.value), [r["total"] for r in ref], rtol=1e-11, atol=1e-10)
    np.testing.assert_allclose(np.asarray(out.details["informed_g"]), [r["g"] for r in ref], rtol=1e-11, atol=1e-10)
    detail = np.asarray(out.details["informed_i"])
    assert detail.shape == (4, 3, 2) and np.all(detail[:, ~np.asarray(ctx.scen_valid)] == 0)
    np.testing.assert_allclose(detail[:, np.asarray(ctx.scen_valid)], [r["per_target"] for r in ref], rtol=1e-11,
                               atol=1e-10)
    joint = np.array([r["joint"] for r in ref])
    assert np.ptp(joint) > 0 and np.any(np.array([r["g"] for r in ref]) > 0)                 # not vacuous
    assert np.any(joint > 10.0)                                                               # some C·R active


def test_roles_select_the_parameter_set():
    ctx, own, targets, obstacle_of, t, polygons, _ = make_context(np.random.default_rng(7))
    term = inf.InformedSbmpcTerm(grounding=False)
    pdv = np.asarray(run_term(term, ctx).details["informed_i"])
    all_r18 = np.asarray(run_term(term, with_roles(ctx, jnp.ones(3, bool))).details["informed_i"])
    # P_R18 with the P_default numbers is P_default: the role only picks a set
    same = inf.InformedSbmpcTerm(grounding=False, K_coll_r18=0.5, rho_r18=0.0, c_dist_r18=500.0)
    np.testing.assert_array_equal(np.asarray(run_term(same, with_roles(ctx, jnp.ones(3, bool))).details["informed_i"]),
                                  pdv)
    assert np.all(all_r18 >= pdv) and np.any(all_r18 > pdv)   # larger K_coll, c_dist, ρ > 0 (ζ ≥ 0)
    mixed = np.asarray(run_term(term, with_roles(ctx, jnp.asarray([False, True, False]))).details["informed_i"])
    np.testing.assert_array_equal(mixed[:, 0], pdv[:, 0])
    np.testing.assert_array_equal(mixed[:, 1], all_r18[:, 1])
    with pytest.raises(ValueError, match="obstacle_r18"):
        run_term(term, with_roles(ctx, jnp.ones(2, bool)))


def test_edges_d0_zero_speeds_no_targets_inside_land_float32():
    ctx, own, targets, obstacle_of, t, polygons, _ = make_context(np.random.default_rng(7))
    term = inf.InformedSbmpcTerm(rho=3.0)
    # every target sits on row 0 with zero speeds; one row stopped inside the island
    obs = ctx.obstacles._replace(x=jnp.broadcast_to(ctx.own.x[:, :1, None], ctx.obstacles.x.shape),
                                 y=jnp.broadcast_to(ctx.own.y[:, :1, None], ctx.obstacles.y.shape),
                                 U=jnp.zeros_like(ctx.obstacles.U))
    own_x = ctx.own.x.at[:, 1].set(900.0)
    own_y = ctx.own.y.at[:, 1].set(250.0)
    own_u = ctx.own.U.at[:, 0].set(0.0).at[:, 1].set(0.0)
    edge = ctx._replace(obstacles=obs, own=ctx.own._replace(x=own_x, y=own_y, U=own_u))
    out = run_term(term, edge)
    v = np.asarray(out.value)
    assert np.all(np.isfinite(v)) and np.all(np.isfinite(np.asarray(out.details["informed_i"])))
    # row 1 inside land from t₀: γ·𝓖 = (200 / 0.1)^4 / T_s, at t = T_s
    assert float(out.details["informed_g"][1]) == pytest.approx((200.0 / 0.1) ** 4 / 5.0, rel=1e-12)
    ref = ri.informed_cost(np.stack([np.asarray(a)[:, 1] for a in (own_x, own_y, ctx.own.chi, own_u)], 1), [], [],
                           t, polygons, rho=3.0)
    assert float(out.details["informed_g"][1]) == pytest.approx(ref["g"], rel=1e-12) and ref["joint"] == 0.0
    # no targets (every scenario masked): only γ𝓖, and every per-target detail is 0
    empty = run_term(term, ctx._replace(scen_valid=jnp.zeros_like(ctx.scen_valid)))
    np.testing.assert_allclose(np.asarray(empty.value), np.asarray(empty.details["informed_g"]))
    assert np.all(np.asarray(empty.details["informed_i"]) == 0)
    # no chart and no targets: 0
    bare = run_term(term, ctx._replace(scen_valid=jnp.zeros_like(ctx.scen_valid), world=None))
    assert np.all(np.asarray(bare.value) == 0)
    # gradient w.r.t. the own-ship positions stays finite at d = 0
    g = jax.jit(jax.grad(lambda x, edge: jnp.sum(term(edge._replace(own=edge.own._replace(x=x)), Params(),
                                                     PlannerConfig(), None).value)))(edge.own.x, edge)
    assert np.all(np.isfinite(np.asarray(g)))


def test_grid_grounding_mode_matches_the_exact_distance():
    polygons = (np.array([[850.0, 200.0], [950.0, 200.0], [950.0, 300.0], [850.0, 300.0]]),
                np.array([[550.0, 420.0], [650.0, 420.0], [600.0, 520.0]]))
    ctx, own, *_ = make_context(np.random.default_rng(7), polygons=polygons)
    term = inf.InformedSbmpcTerm(grounding=True)
    f = jax.jit(lambda term, ctx, cfg: term(ctx, Params(), cfg, None).details["informed_g"], static_argnums=2)
    exact = np.asarray(f(term, ctx, PlannerConfig(T=200.0, dt=5.0, dtype="float64")))
    assert np.count_nonzero(exact > 0) >= 2
    t = np.asarray(ctx.t)
    np.testing.assert_allclose(exact, [ri.informed_cost(own[:, b], [], [], t, polygons)["g"] for b in range(4)],
                               rtol=1e-11)                                # min over two polygons
    for margin in (300.0, 50.0):
        cfg = PlannerConfig(T=200.0, dt=5.0, dtype="float64", grounding_mode="grid", grid_spacing=1.0,
                            grid_margin=margin)
        grid_ctx = ctx._replace(world=jax.tree.map(jnp.asarray, pack_world(polygons, cfg)))
        got = np.asarray(f(term, grid_ctx, cfg))
        if margin > term.d_static_safe:               # the grid sees every point within d_static_safe
            np.testing.assert_allclose(got, exact, rtol=0.05)
        else:                                         # the open sea beyond the margin costs nothing
            assert np.all(got <= exact * 1.05 + 1e-12) and np.all(np.isfinite(got))
    far = ctx._replace(own=ctx.own._replace(x=ctx.own.x - 5000.0))
    assert np.all(np.asarray(f(term, far._replace(world=grid_ctx.world), cfg)) == 0)


def test_float32_matches_float64():
    ctx64, *_ = make_context(np.random.default_rng(7))
    ctx32, *_ = make_context(np.random.default_rng(7), dtype=np.float32)
    term = inf.InformedSbmpcTerm(rho=3.0)
    roles = jnp.asarray([True, False, False])
    f = jax.jit(lambda term, ctx: term(ctx, Params(), PlannerConfig(dtype="float32"), None))
    v32 = f(term, with_roles(ctx32, roles)).value
    v64 = np.asarray(run_term(term, with_roles(ctx64, roles)).value)
    assert v32.dtype == jnp.float32 and np.all(np.isfinite(np.asarray(v32)))
    np.testing.assert_allclose(np.asarray(v32), v64, rtol=2e-3)


def test_numeric_fields_are_traced_and_modes_static():
    ctx, *_ = make_context(np.random.default_rng(7))
    f = jax.jit(lambda term, ctx: term(ctx, Params(), PlannerConfig(), None).value)
    f(inf.InformedSbmpcTerm(), ctx)
    n0 = f._cache_size()
    f(inf.InformedSbmpcTerm(kappa=1.0, c_dist_r18=700.0, k=1.0, gamma=0.0), ctx)
    assert f._cache_size() == n0                                               # new values: no recompile
    f(inf.InformedSbmpcTerm(circular=True), ctx)
    assert f._cache_size() == n0 + 1                                           # a static field: one more
    leaves, treedef = jax.tree_util.tree_flatten(inf.InformedSbmpcTerm(classify="sectors_t0"))
    assert len(leaves) == len(inf.InformedSbmpcTerm.PARAMS)
    assert all(isinstance(v, float) for v in leaves)
    assert jax.tree_util.tree_unflatten(treedef, leaves) == inf.InformedSbmpcTerm(classify="sectors_t0")
    assert inf.InformedSbmpcTerm.STATIC == ("classify", "circular", "grounding") and not inf.InformedSbmpcTerm.smooth


# ============================================================================ through the evaluator
def random_situation(seed: int) -> Situation:
    """Own-ship north at 5 m/s, four straight-line targets around it (some come within d_safe), an island to
    starboard."""
    rng = np.random.default_rng(seed)
    own = OwnShip(state=OWN, waypoints=np.array([[0.0, 0.0], [6000.0, 0.0]]), U_d=5.0, length=116.0, width=20.0)
    obs = []
    for i in range(4):
        pos = rng.uniform([300.0, -900.0], [1500.0, 900.0])
        course, speed = rng.uniform(0, 2 * np.pi), rng.uniform(0.0, 6.0)
        obs.append(Obstacle([pos[0], pos[1], speed * np.cos(course), speed * np.sin(course)], COV, length=116.0,
                            width=20.0, n_ps=3 if i == 0 else 1))
    obs.append(Obstacle([1200.0, 30.0, -5.0, 0.0], COV, length=116.0, width=20.0, n_ps=1))      # head-on
    island = np.array([[500.0, 250.0], [700.0, 250.0], [700.0, 450.0], [500.0, 450.0]])
    return Situation(own, tuple(obs), (island,))


@pytest.mark.parametrize("seed, r18", [(0, None), (1, (True, False, True, False, False)),
                                       (2, (False, False, False, False, True))])
def test_grid_search_matches_the_float64_reference(seed, r18):
    cfg = PlannerConfig(T=200.0, dt=5.0, dtype="float64")
    sit = random_situation(seed)
    inputs = pack(sit, SEARCH, cfg)
    n_o = inputs.obstacles.mask.shape[0]
    mask = np.zeros(n_o, bool)
    if r18 is not None:
        mask[: len(r18)] = r18
    informed = inf.InformedSbmpcTerm(classify="sectors_t0" if seed == 2 else "velocity")
    terms = (Roles(informed, jnp.asarray(mask)), mv.SmoothManoeuvringTerm(form="johansen", side="offset"))
    last = (1.0, 0.0)
    ev = evaluate(inputs, jnp.asarray(last), PARAMS, None, config=cfg, terms=terms)
    ref = ref_mod.evaluate_reference(sit, SEARCH, PARAMS, cfg, last_offsets=last, extra_terms=terms)
    got = np.asarray(ev.costs["informed"])[: len(SEARCH)]
    np.testing.assert_allclose(got, ref.extra["informed"], rtol=1e-9, atol=1e-9)
    assert np.ptp(got) > 0 and np.any(np.asarray(ev.details["informed_g"])[: len(SEARCH)] > 0)
    total = sum(np.asarray(ref.extra[t.name]) for t in terms)
    assert int(ev.best) == int(np.argmin(total))


def test_reference_reads_the_obstacle_role_attribute():
    cfg = PlannerConfig(T=100.0, dt=5.0, dtype="float64")
    sit = random_situation(1)
    marked = list(sit.obstacles)
    for ob in marked:
        object.__setattr__(ob, "rule18", True)                # what the Obstacle field will carry
    sit_marked = Situation(sit.own_ship, tuple(marked), sit.polygons)
    term = inf.InformedSbmpcTerm()
    traj = pred.ownship_trajectory(sit.own_ship, SEARCH[6], PARAMS, cfg)
    by_attr = term.reference(traj, SEARCH[6], sit_marked, PARAMS, cfg)
    explicit = term.reference(traj, SEARCH[6], random_situation(1), PARAMS, cfg, r18=[True] * 5)
    plain = term.reference(traj, SEARCH[6], random_situation(1), PARAMS, cfg)
    assert by_attr == explicit and by_attr != plain
    with pytest.raises(ValueError, match="one flag per obstacle"):
        term.reference(traj, SEARCH[6], sit, PARAMS, cfg, r18=[True])


def test_rule18_set_makes_the_stand_on_ship_keep_out_of_the_way():
    """Crossing with the target from port (the own-ship stands on under Rule 15), target first at the
    crossing point.  As a power-driven target (P_default) the own-ship keeps speed and passes its stern at a few
    hundred metres; with the target's Rule-18 priority (P_R18) it stops and keeps well clear (paper Fig. 7)."""
    cfg = PlannerConfig(T=600.0, dt=5.0, dtype="float64")
    own = OwnShip(state=OWN, waypoints=np.array([[0.0, 0.0], [8000.0, 0.0]]), U_d=5.0, length=116.0, width=20.0)
    target = Obstacle([2000.0, -1500.0, 0.0, 5.0], COV, length=116.0, width=20.0, n_ps=1)     # heading east
    inputs = pack(Situation(own, (target,)), SEARCH, cfg)
    gamma = mv.SmoothManoeuvringTerm(form="johansen", side="offset")
    keep, stop = 6, 32                                         # (1, 0°), (0, 0°)
    assert tuple(SEARCH[keep, 0]) == (1.0, 0.0) and tuple(SEARCH[stop, 0]) == (0.0, 0.0)
    out = {}
    for role in (False, True):
        mask = np.zeros(inputs.obstacles.mask.shape[0], bool)
        mask[0] = role
        ev = evaluate(inputs, jnp.asarray([1.0, 0.0]), PARAMS, None, config=cfg,
                      terms=(Roles(inf.InformedSbmpcTerm(), jnp.asarray(mask)), gamma))
        b = int(ev.best)
        ox, oy = np.asarray(ev.own.x)[:, b], np.asarray(ev.own.y)[:, b]
        tx, ty = np.asarray(ev.obstacles.x)[:, 0, 0], np.asarray(ev.obstacles.y)[:, 0, 0]
        d = np.hypot(tx - ox, ty - oy)
        out[role] = (SEARCH[b, 0], float(d.min()), np.asarray(ev.total)[: len(SEARCH)])
    (beh_pdv, cpa_pdv, tot_pdv), (beh_r18, cpa_r18, tot_r18) = out[False], out[True]
    assert beh_pdv[0] == 1.0 and beh_r18[0] < 1.0                       # keeps speed / slows down (stops)
    assert cpa_r18 > 2.0 * cpa_pdv and cpa_r18 > 1000.0
    assert tot_pdv[keep] < tot_pdv[stop] and tot_r18[stop] < tot_r18[keep]


# ============================================================================ validation
@pytest.mark.parametrize("kw, match", [
    (dict(K_coll=-1.0), r"K_coll must be finite and in \[0, inf\)"),
    (dict(K_coll_r18=-1.0), "K_coll_r18"),
    (dict(kappa_r18=float("nan")), "kappa_r18"),
    (dict(rho=-0.1), "rho"),
    (dict(c_dist=0.0), r"c_dist must be finite and in \(0, inf\)"),
    (dict(c_dist_r18=-5.0), "c_dist_r18"),
    (dict(q=-1.0), "q must"),
    (dict(p_r18=-1.0), "p_r18"),
    (dict(d_close_r18=0.0), "d_close_r18"),
    (dict(k=-1.0), "k must"),
    (dict(l=0.0), r"l must be finite and in \(0, inf\)"),
    (dict(m=-1.0), "m must"),
    (dict(gamma=-1.0), "gamma"),
    (dict(q_g=-1.0), "q_g"),
    (dict(d_static_safe=0.0), "d_static_safe"),
    (dict(classify="woerner"), r"classify must be one of \('velocity', 'sectors_t0'\)"),
    (dict(circular="yes"), "circular must be a bool"),
    (dict(grounding=1), "grounding must be a bool"),
])
def test_bad_parameters_are_refused(kw, match):
    with pytest.raises(ValueError, match=match):
        inf.InformedSbmpcTerm(**kw)


def test_bad_function_arguments_are_refused():
    with pytest.raises(ValueError, match="c_dist"):
        inf.adaptive_d_safe(0.1, -1.0)
    with pytest.raises(ValueError, match="l must"):
        inf.adaptive_d_safe(0.1, 500.0, 2.0, 0.0)
    with pytest.raises(ValueError, match="classify"):
        inf.colregs_woerner(0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.0, 1.0, classify="sectors")
    with pytest.raises(ValueError, match="t0"):
        inf.colregs_woerner(0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.0, 1.0, classify="sectors_t0")
    with pytest.raises(ValueError, match="d_static_safe"):
        inf.grounding_penalty(1.0, 1.0, 0.0)
    with pytest.raises(ValueError, match="m must"):
        inf.rule18_zeta(0.0, 0.0, m=-1.0)
    with pytest.raises(ValueError, match="roles"):
        ri.informed_cost(np.zeros((3, 4)), [np.zeros((3, 4))], [], [0.0, 1.0, 2.0])
    assert sb.V_EPS == 0.05                                    # the speed guard shared with SB-MPC's μ
