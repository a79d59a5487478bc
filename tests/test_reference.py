"""Unit tests of the sequential float64 reference (psbmpc_jax.reference and reference_prediction), piece by
piece."""

from __future__ import annotations

import math

import numpy as np
import pytest
from shapely.geometry import Point, Polygon

from psbmpc_jax.behaviours import paper_behaviours
from psbmpc_jax.params import Params, PlannerConfig
from psbmpc_jax.situation import Obstacle, OwnShip, Situation
from psbmpc_jax.reference import (
    ReferenceResult,
    colregs_violation,
    collision_probability,
    evaluate_reference,
    grounding_cost,
    path_cost,
    polygon_distance,
    sigma_max,
)
from psbmpc_jax.reference_prediction import (
    los_rollout,
    maneuver_start_steps,
    obstacle_covariances,
    obstacle_scenarios,
    ou_covariance,
    ownship_trajectory,
    wrap_angle,
)

P = Params()


# ---------------------------------------------------------------------------------------------- wrap
def test_wrap_angle_range_and_values():
    a = np.linspace(-20.0, 20.0, 2001)
    w = wrap_angle(a)
    assert np.all(w >= -math.pi) and np.all(w < math.pi)
    assert np.allclose(np.sin(w), np.sin(a), atol=1e-12) and np.allclose(np.cos(w), np.cos(a), atol=1e-12)
    assert wrap_angle(math.pi) == -math.pi
    assert wrap_angle(3 * math.pi / 2) == pytest.approx(-math.pi / 2, abs=1e-15)
    assert wrap_angle(0.25) == 0.25


# ---------------------------------------------------------------------------------------------- covariance
def test_ou_covariance_closed_form_per_axis():
    sx, sy, g = 0.025, 0.04, 0.1
    params = P.replace(sigma_x=sx, sigma_y=sy, sigma_xy=0.0, gamma_x=g, gamma_y=g)
    for t in (0.0, 0.5, 3.0, 17.25, 150.0):
        sig = ou_covariance(t, params)
        tau = g * t
        for axis, s in ((0, sx), (1, sy)):
            var_p = s**2 / g**3 * 0.5 * (2 * tau + 4 * math.exp(-tau) - math.exp(-2 * tau) - 3)
            cov_pv = s**2 / (2 * g**2) * (1 - math.exp(-tau)) ** 2
            var_v = s**2 / (2 * g) * (1 - math.exp(-2 * tau))
            assert sig[axis, axis] == pytest.approx(var_p, rel=1e-9, abs=1e-15)
            assert sig[axis, 2 + axis] == pytest.approx(cov_pv, rel=1e-9, abs=1e-15)
            assert sig[2 + axis, axis] == pytest.approx(cov_pv, rel=1e-9, abs=1e-15)
            assert sig[2 + axis, 2 + axis] == pytest.approx(var_v, rel=1e-12, abs=1e-15)
        # no coupling between the axes
        for a, b in ((0, 1), (0, 3), (1, 2), (2, 3)):
            assert sig[a, b] == 0.0 and sig[b, a] == 0.0


def _lyapunov_rk4(t_end, h, sx, sy, sxy, gx, gy):
    A = np.array([[0, 0, 1, 0], [0, 0, 0, 1], [0, 0, -gx, 0], [0, 0, 0, -gy]], dtype=float)
    G = np.array([[0, 0], [0, 0], [1, 0], [0, 1]], dtype=float)
    GQG = G @ np.array([[sx**2, sxy], [sxy, sy**2]]) @ G.T

    def f(Pm):
        return A @ Pm + Pm @ A.T + GQG

    n = int(round(t_end / h))
    Pm = np.zeros((4, 4))
    for _ in range(n):
        k1 = f(Pm)
        k2 = f(Pm + 0.5 * h * k1)
        k3 = f(Pm + 0.5 * h * k2)
        k4 = f(Pm + h * k3)
        Pm = Pm + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    return Pm


@pytest.mark.parametrize("t_end", [0.5, 4.0, 25.0])
def test_ou_covariance_general_matches_lyapunov_ode(t_end):
    sx, sy, sxy, gx, gy = 0.3, 0.2, 0.04, 0.1, 0.35
    params = P.replace(sigma_x=sx, sigma_y=sy, sigma_xy=sxy, gamma_x=gx, gamma_y=gy)
    sig = ou_covariance(t_end, params)
    ref = _lyapunov_rk4(t_end, 5e-3, sx, sy, sxy, gx, gy)
    assert np.allclose(sig, sig.T, rtol=0, atol=1e-15)
    assert np.all(np.linalg.eigvalsh(sig) > -1e-14)
    # element-wise relative agreement (every entry is non-zero here)
    assert np.all(np.abs(ref) > 0)
    assert np.max(np.abs(sig - ref) / np.abs(ref)) < 1e-8


def test_obstacle_covariances_start_at_P0_and_grow():
    cov0 = np.diag([2.0, 1.0, 0.1, 0.2])
    cov0[0, 1] = cov0[1, 0] = 0.3
    ob = Obstacle(state=[0, 0, 1, 0], cov=cov0)
    cfg = PlannerConfig(T=10.0, dt=0.5)
    covs = obstacle_covariances(ob, P, cfg)
    assert covs.shape == (21, 4, 4)
    assert np.array_equal(covs[0], ob.cov)
    assert np.allclose(covs[7], ob.cov + ou_covariance(3.5, P), rtol=0, atol=1e-15)
    assert np.all(np.diff(covs[:, 0, 0]) > 0)


def test_sigma_max_is_largest_eigen_std():
    rng = np.random.default_rng(3)
    for _ in range(20):
        M = rng.normal(size=(2, 2))
        S = M @ M.T
        assert sigma_max(S) == pytest.approx(math.sqrt(np.linalg.eigvalsh(S).max()), rel=1e-12)


# ---------------------------------------------------------------------------------------------- P_c
def _brute_force_pc(p, mu, S, R, n_r=500, n_theta=2400):
    """Polar integration of the bivariate normal density over the disc (Gauss-Legendre in r, periodic
    trapezoid in theta; the integrand is smooth so both converge fast)."""
    x, w = np.polynomial.legendre.leggauss(n_r)
    r = 0.5 * R * (x + 1)
    wr = 0.5 * R * w
    th = np.linspace(0, 2 * np.pi, n_theta, endpoint=False)
    X = p[0] + r[:, None] * np.cos(th)[None, :] - mu[0]
    Y = p[1] + r[:, None] * np.sin(th)[None, :] - mu[1]
    Si = np.linalg.inv(S)
    q = Si[0, 0] * X**2 + 2 * Si[0, 1] * X * Y + Si[1, 1] * Y**2
    dens = np.exp(-0.5 * q) / (2 * np.pi * math.sqrt(np.linalg.det(S)))
    return float(np.sum(wr[:, None] * r[:, None] * dens) * (2 * np.pi / n_theta))


GEOMETRIES = [
    # (p, mu, S, R) -- inside, boundary, anisotropic/correlated, narrow near the edge, tail, far tail
    ((0.0, 0.0), (0.0, 0.0), [[4.0, 0.0], [0.0, 4.0]], 10.0),
    ((0.0, 0.0), (10.0, 0.0), [[4.0, 0.0], [0.0, 4.0]], 10.0),
    ((1.0, -2.0), (7.0, 1.0), [[9.0, 4.0], [4.0, 2.5]], 8.0),
    ((0.0, 0.0), (9.8, 1.0), [[0.09, 0.0], [0.0, 0.5]], 10.0),
    ((5.0, 5.0), (5.0 - 9.0, 5.0 + 12.0), [[16.0, -5.0], [-5.0, 3.0]], 12.0),
    ((0.0, 0.0), (0.0, 14.0), [[1.0, 0.3], [0.3, 2.0]], 10.0),
    ((0.0, 0.0), (3.0, -4.0), [[25.0, 0.0], [0.0, 1.0]], 5.0),
]


@pytest.mark.parametrize("geom", GEOMETRIES)
def test_quadrature_matches_brute_force(geom):
    p, mu, S, R = geom
    S = np.array(S)
    q = collision_probability(p, mu, S, R, "quadrature", P, PlannerConfig())
    bf = _brute_force_pc(np.array(p), np.array(mu), S, R)
    assert 0.0 <= q <= 1.0
    assert abs(q - bf) < 5e-6, (q, bf)  # documented bound: 2.4e-6 (docs/algorithm.md §7)


def test_quadrature_centred_isotropic_closed_form():
    for sig, R in ((2.0, 10.0), (5.0, 7.0), (1.0, 1.5)):
        q = collision_probability((3.0, 4.0), (3.0, 4.0), np.eye(2) * sig**2, R, "quadrature", P, PlannerConfig())
        assert q == pytest.approx(1.0 - math.exp(-(R**2) / (2 * sig**2)), abs=5e-6)


@pytest.mark.parametrize("geom", GEOMETRIES[:5])
def test_mc_within_four_standard_errors(geom):
    p, mu, S, R = geom
    S = np.array(S)
    n = 20000
    cfg = PlannerConfig(estimator="mc", n_samples=n)
    Z = np.random.default_rng(12345).standard_normal((n, 2))
    q = collision_probability(p, mu, S, R, "quadrature", P, cfg)
    mc = collision_probability(p, mu, S, R, "mc", P, cfg, samples=Z)
    se = math.sqrt(max(q * (1 - q), 1e-12) / n)
    assert abs(mc - q) <= 4 * se + 2e-5, (mc, q, se)


@pytest.mark.parametrize("geom", GEOMETRIES[:5])
def test_ce_within_four_standard_errors(geom):
    p, mu, S, R = geom
    S = np.array(S)
    n, reps = 2000, 16
    cfg = PlannerConfig(estimator="ce", n_samples=n, ce_max_iter=6)
    rng = np.random.default_rng(777)
    q = collision_probability(p, mu, S, R, "quadrature", P, cfg)
    est = np.array([
        collision_probability(p, mu, S, R, "ce", P, cfg, samples=rng.standard_normal((7, n, 2)))
        for _ in range(reps)
    ])
    assert np.all((est >= 0) & (est <= 1))
    se = est.std(ddof=1) / math.sqrt(reps)
    assert abs(est.mean() - q) <= 4 * se + 2e-4, (est.mean(), q, se)


def test_shortcut_is_exact_zero_beyond_threshold():
    S = np.diag([1.0, 4.0])  # sigma_max = 2
    R = 10.0
    thr = R + P.c_sigma * 2.0
    n = 4
    cfg_mc = PlannerConfig(estimator="mc", n_samples=n)
    # every sample lands at mu + (0, -9): inside the disc around the origin when mu = (0, ~18)
    Z = np.tile([0.0, -4.5], (n, 1))
    beyond = (0.0, thr + 1e-9)
    within = (0.0, thr - 1e-9)
    assert collision_probability((0, 0), beyond, S, R, "mc", P, cfg_mc, samples=Z) == 0.0
    assert collision_probability((0, 0), within, S, R, "mc", P, cfg_mc, samples=Z) == 1.0
    assert collision_probability((0, 0), beyond, S, R, "quadrature", P, PlannerConfig()) == 0.0
    assert collision_probability((0, 0), within, S, R, "quadrature", P, PlannerConfig()) > 0.0
    cfg_ce = PlannerConfig(estimator="ce", n_samples=50)
    Zc = np.random.default_rng(0).standard_normal((cfg_ce.ce_max_iter + 1, 50, 2))
    assert collision_probability((0, 0), beyond, S, R, "ce", P, cfg_ce, samples=Zc) == 0.0


def test_mc_counts_boundary_inclusively():
    # a sample exactly on the circle counts as inside (<= R^2)
    cfg = PlannerConfig(estimator="mc", n_samples=2)
    Z = np.array([[0.0, 0.0], [0.0, 0.0]])
    assert collision_probability((0, 0), (0.0, 5.0), np.eye(2), 5.0, "mc", P, cfg, samples=Z) == 1.0


# ---------------------------------------------------------------------------------------------- LOS rollout
def test_los_straight_path_stays_on_line():
    N, dt = 200, 0.5
    traj = los_rollout([0, 0, 0, 2.0], [(0, 0), (1000, 0)], np.zeros(N), np.full(N, 2.0), 0.0, 66.0, 5.0,
                       0.92, 1.44, dt, N)
    assert traj.shape == (N + 1, 4)
    assert np.all(traj[:, 1] == 0.0) and np.all(traj[:, 2] == 0.0)
    assert np.allclose(traj[:, 3], 2.0, rtol=0, atol=0)
    assert np.allclose(traj[:, 0], 2.0 * dt * np.arange(N + 1), rtol=0, atol=1e-12)


def test_los_lateral_offset_converges_to_offset_line():
    N, dt = 600, 0.5
    traj = los_rollout([0, 0, 0, 2.0], [(0, 0), (5000, 0)], 0.0, 2.0, 10.0, 66.0, 5.0, 0.92, 1.44, dt, N)
    err = np.abs(traj[:, 1] - 10.0)
    assert err[0] == 10.0
    assert err[-1] < 0.05
    assert err[N // 2] < err[N // 4] < err[N // 8] < err[0]
    # negative offset: to port
    traj_p = los_rollout([0, 0, 0, 2.0], [(0, 0), (5000, 0)], 0.0, 2.0, -10.0, 66.0, 5.0, 0.92, 1.44, dt, N)
    assert abs(traj_p[-1, 1] + 10.0) < 0.05


def test_los_holds_last_course_after_the_last_waypoint():
    N, dt = 300, 0.5
    traj = los_rollout([0, 0, 0, 2.0], [(0, 0), (50, 0), (50, 50)], 0.0, 2.0, 0.0, 66.0, 5.0, 0.92, 1.44,
                       dt, N)
    # the path ends at (50, 50) after ~100 m; afterwards the course is held at alpha_1 = pi/2 (east)
    assert traj[-1, 2] == pytest.approx(math.pi / 2, abs=1e-9)
    assert traj[-1, 1] > 50.0 + 100.0
    # heading east in a straight line at the end: x no longer changes
    assert abs(traj[-1, 0] - traj[-50, 0]) < 1e-6


@pytest.mark.parametrize("R_a, switch_x", [(5.0, 95.0), (12.5, 88.0), (0.0, 100.0)])
def test_los_switch_happens_within_acceptance_radius(R_a, switch_x):
    # on the line, heading north at 2 m/s with dt = 0.5 s: x advances exactly 1 m per step and the course
    # stays exactly 0 until the switch to the eastbound segment
    N = 130
    w1 = np.array([100.0, 0.0])
    traj = los_rollout([0, 0, 0, 2.0], [(0, 0), (100, 0), (100, 100)], 0.0, 2.0, 0.0, 66.0, R_a, 0.92,
                       1.44, 0.5, N)
    k = int(np.flatnonzero(traj[1:, 2] != 0.0)[0])  # first step whose command differs from north
    assert traj[k, 0] == switch_x
    d_k = np.linalg.norm(traj[k, :2] - w1)
    d_prev = np.linalg.norm(traj[k - 1, :2] - w1)
    if R_a > 0:
        assert d_k <= R_a < d_prev
    else:  # R_a = 0: the switch is triggered by passing the waypoint (s >= L)
        assert traj[k, 0] >= 100.0 > traj[k - 1, 0]
    assert traj[k + 1, 2] > 0.0  # turning to starboard, towards the east


def test_los_rejects_bad_lengths():
    with pytest.raises(ValueError, match="chi_offsets"):
        los_rollout([0, 0, 0, 1.0], [(0, 0), (10, 0)], np.zeros(3), 1.0, 0.0, 66.0, 5.0, 1.0, 1.0, 0.5, 4)
    with pytest.raises(ValueError, match="waypoints"):
        los_rollout([0, 0, 0, 1.0], [(0, 0)], 0.0, 1.0, 0.0, 66.0, 5.0, 1.0, 1.0, 0.5, 4)


# ---------------------------------------------------------------------------------------------- own-ship
def test_ownship_maneuver_timing():
    own = OwnShip(state=[0, 0, 0, 2.0], waypoints=[(0, 0), (1000, 0)], U_d=2.0)
    cfg = PlannerConfig(T=20.0, dt=0.5)
    beh = np.array([[1.0, 0.0], [0.5, 0.0]])
    assert list(maneuver_start_steps(2, P, cfg)) == [0, 20]
    traj = ownship_trajectory(own, beh, P, cfg)
    assert np.all(traj[:21, 3] == 2.0)
    assert traj[21, 3] < 2.0
    assert traj[-1, 3] == pytest.approx(1.0, abs=1e-3)
    # explicit t_ts
    p2 = P.replace(t_ts=5.0)
    assert list(maneuver_start_steps(2, p2, cfg)) == [0, 10]
    traj2 = ownship_trajectory(own, beh, p2, cfg)
    assert np.all(traj2[:11, 3] == 2.0) and traj2[11, 3] < 2.0


def test_ownship_course_offsets_replace_not_accumulate():
    own = OwnShip(state=[0, 0, 0, 2.0], waypoints=[(0, 0), (1000, 0)], U_d=2.0)
    cfg = PlannerConfig(T=20.0, dt=0.5)
    off = math.radians(30)
    traj = ownship_trajectory(own, np.array([[1.0, off], [1.0, off]]), P, cfg)
    traj1 = ownship_trajectory(own, np.array([[1.0, off]]), P, cfg)
    assert np.array_equal(traj, traj1)  # the same offset twice is one constant offset
    assert traj[-1, 2] > 0.0


# ---------------------------------------------------------------------------------------------- obstacles
@pytest.mark.parametrize("chi", [0.0, math.pi, 1.0])
def test_obstacle_scenarios_offsets_and_order(chi):
    V = 2.0
    ob = Obstacle(state=[10.0, -5.0, V * math.cos(chi), V * math.sin(chi)], cov=np.diag([1e-3, 1e-3, 0.0, 0.0]), n_ps=5)
    cfg = PlannerConfig(T=300.0, dt=1.0)
    sc = obstacle_scenarios(ob, P.replace(r_ct=10.0), cfg)
    assert sc.shape == (5, 301, 4)
    assert np.all(sc[:, 0] == sc[0, 0])
    assert np.allclose(sc[:, :, 3], V, atol=1e-12)
    starboard = np.array([-math.sin(chi), math.cos(chi)])  # unit vector to the right of the course
    lateral = (sc[:, -1, :2] - np.array([10.0, -5.0])) @ starboard
    assert np.allclose(lateral, [-20, -10, 0, 10, 20], atol=0.05)  # j = 0 furthest to port


def test_obstacle_at_rest_stays():
    ob = Obstacle(state=[10.0, 20.0, 0.0, 0.0], cov=np.eye(4), n_ps=3)
    sc = obstacle_scenarios(ob, P, PlannerConfig(T=10.0, dt=0.5))
    assert np.all(sc[:, :, 0] == 10.0) and np.all(sc[:, :, 1] == 20.0) and np.all(sc[:, :, 3] == 0.0)


# ---------------------------------------------------------------------------------------------- COLREGS
def _state(x, y, chi, U):
    return np.array([[x, y, chi, U]])


@pytest.mark.parametrize(
    "obs, expected",
    [
        (_state(50, 10, math.pi, 2.0), True),        # head-on, obstacle to starboard
        (_state(50, -10, math.pi, 2.0), False),      # head-on, obstacle to port
        (_state(150, 10, math.pi, 2.0), False),      # not close
        (_state(50, 50, -math.pi / 2, 2.0), True),   # crossing from starboard
        (_state(-50, 10, 0.0, 4.0), False),          # being overtaken on starboard
        (_state(50, 10, 0.0, 1.0), False),           # overtaking, same course (not crossed)
    ],
)
def test_colregs_violation_geometries(obs, expected):
    own = _state(0, 0, 0.0, 2.0)
    flags = colregs_violation(own, obs, P)
    assert flags.shape == (1,)
    assert bool(flags[0]) is expected


@pytest.mark.parametrize("dx, expected", [(-10.0, True), (10.0, False)])
def test_colregs_starboard_uses_own_course(dx, expected):
    # own-ship heading east: starboard is south (negative x); head-on obstacle heading west
    own = _state(0, 0, math.pi / 2, 2.0)
    obs = _state(dx, 50, -math.pi / 2, 2.0)
    assert bool(colregs_violation(own, obs, P)[0]) is expected


# ---------------------------------------------------------------------------------------------- polygons
def _star_polygon(rng, n):
    ang = np.sort(rng.uniform(0, 2 * np.pi, n))
    rad = rng.uniform(15, 50, n)
    c = rng.uniform(-10, 10, 2)
    return np.stack([c[0] + rad * np.cos(ang), c[1] + rad * np.sin(ang)], axis=1)


def test_polygon_distance_matches_shapely():
    rng = np.random.default_rng(2024)
    n_inside = 0
    for _ in range(12):
        ring = _star_polygon(rng, int(rng.integers(3, 25)))
        poly = Polygon(ring)
        assert poly.is_valid
        for pt in rng.uniform(-70, 70, (40, 2)):
            d, u = polygon_distance(pt, ring)
            if poly.contains(Point(pt)):
                n_inside += 1
                assert d == 0.0 and np.all(u == 0.0)
            else:
                assert d == pytest.approx(poly.exterior.distance(Point(pt)), abs=1e-9)
                assert np.linalg.norm(u) == pytest.approx(1.0, abs=1e-12)
                # p + d u is on the boundary
                assert poly.exterior.distance(Point(pt + d * u)) < 1e-9
    assert n_inside > 20


def test_grounding_cost_hand_values():
    ring = np.array([(0.0, 0.0), (0.0, 10.0), (10.0, 10.0), (10.0, 0.0)])
    cfg = PlannerConfig(T=1.0, dt=1.0)
    # k = 0 at 20 m south of the square, k = 1 inside it
    traj = np.array([[-20.0, 5.0, 0.0, 1.0], [5.0, 5.0, 0.0, 1.0]])
    g0 = P.G1 * math.exp(-P.G3 * (20.0 - P.d_safe))
    g1 = P.G1 * math.exp(-P.G4 * 1.0) * (1 + P.G3 * P.d_safe)
    assert grounding_cost(traj, ring, P, cfg, P.d_safe) == pytest.approx(max(g0, g1), rel=1e-14)
    assert grounding_cost(traj[:1], ring, P, cfg, P.d_safe) == pytest.approx(g0, rel=1e-14)
    # below d_safe outside: linear branch
    near = np.array([[-2.0, 5.0, 0.0, 1.0]])
    assert grounding_cost(near, ring, P, cfg) == pytest.approx(P.G1 * (1 + P.G3 * 3.0), rel=1e-14)
    # wind towards the polygon (north) raises A; wind away does not
    pw = P.replace(V_w=2.0, wind_dir=0.0)
    assert grounding_cost(traj[:1], ring, pw, cfg) == pytest.approx(
        (P.G1 + P.G2 * 4.0) * math.exp(-P.G3 * 15.0), rel=1e-14)
    pw2 = P.replace(V_w=2.0, wind_dir=math.pi)
    assert grounding_cost(traj[:1], ring, pw2, cfg) == pytest.approx(g0, rel=1e-14)


# ---------------------------------------------------------------------------------------------- path cost
def test_path_cost_single_maneuver():
    port = path_cost(np.array([[0.5, -0.5]]), (1.0, 0.0), P)
    stbd = path_cost(np.array([[0.5, 0.5]]), (1.0, 0.0), P)
    assert port == pytest.approx(6.3 * 0.5 + 1.8 * 0.25 + 3.6 * 0.5 + 1.3 * 0.25, rel=1e-14)  # 5.725
    assert stbd == pytest.approx(6.3 * 0.5 + 1.5 * 0.25 + 3.6 * 0.5 + 1.0 * 0.25, rel=1e-14)  # 5.575
    assert port > stbd
    assert path_cost(np.array([[1.0, 0.0]]), (1.0, 0.0), P) == 0.0
    # the change is wrapped: from 3.0 to -3.0 rad is a small starboard change
    wrapped = path_cost(np.array([[1.0, -3.0]]), (1.0, 3.0), P)
    assert wrapped == pytest.approx(1.8 * 9.0 + 1.0 * (2 * math.pi - 6.0) ** 2, rel=1e-12)


def test_path_cost_two_maneuvers():
    beh = np.array([[1.0, 0.5], [0.5, -0.25]])
    expected = (1.5 * 0.25 + (6.3 * 0.5 + 1.8 * 0.0625) + 1.0 * 0.4**2) / 2 + (3.6 * 0.5 + 1.3 * 0.75**2)
    assert path_cost(beh, (1.0, 0.1), P) == pytest.approx(expected, rel=1e-14)
    # with every offset and every change to port, the mirror image of an all-starboard behaviour costs more
    stbd = np.array([[1.0, 0.5], [0.5, 0.75]])
    port = stbd * [[1.0, -1.0]]
    c_stbd, c_port = path_cost(stbd, (1.0, 0.1), P), path_cost(port, (1.0, -0.1), P)
    assert c_stbd == pytest.approx((1.5 * 0.25 + 6.3 * 0.5 + 1.5 * 0.5625 + 1.0 * 0.16) / 2
                                   + 3.6 * 0.5 + 1.0 * 0.0625, rel=1e-14)
    assert c_port == pytest.approx((1.8 * 0.25 + 6.3 * 0.5 + 1.8 * 0.5625 + 1.3 * 0.16) / 2
                                   + 3.6 * 0.5 + 1.3 * 0.0625, rel=1e-14)
    assert c_port > c_stbd


# ---------------------------------------------------------------------------------------------- evaluate
def _head_on_situation(**ob_kwargs):
    own = OwnShip(state=[0.0, 0.0, 0.0, 2.0], waypoints=[(0, 0), (1000, 0)], U_d=2.0)
    ob = Obstacle(state=[300.0, 0.0, -2.0, 0.0], cov=np.diag([1.0, 1.0, 0.1, 0.1]), **ob_kwargs)
    return own, ob


def test_evaluate_head_on_prefers_starboard():
    own, ob = _head_on_situation()
    beh = paper_behaviours(1)
    cfg = PlannerConfig(T=150.0, dt=0.5)
    r = evaluate_reference(Situation(own, (ob,)), beh, P, cfg)
    assert isinstance(r, ReferenceResult)
    B = beh.shape[0]
    for arr in (r.total, r.do, r.colregs, r.so, r.path):
        assert arr.shape == (B,) and np.all(np.isfinite(arr)) and np.all(arr >= 0)
    assert np.allclose(r.total, r.do + r.colregs + r.so + r.path, rtol=1e-14, atol=0)
    assert r.best == int(np.argmin(r.total))
    assert beh[r.best, 0, 1] > 0  # starboard
    assert r.own_traj.shape == (B, 301, 4)
    assert r.obs_traj[0].shape == (5, 301, 4) and r.obs_cov[0].shape == (301, 4, 4)
    assert r.C[0].shape == (B, 5) and r.mu[0].shape == (B, 5) and r.so_j.shape == (B, 0)
    assert set(np.unique(r.mu[0])) <= {0.0, 1.0}
    straight = int(np.flatnonzero((beh[:, 0, 0] == 1.0) & (beh[:, 0, 1] == 0.0))[0])
    assert r.do[straight] > 10.0  # steaming straight into the obstacle is expensive
    port = int(np.flatnonzero((beh[:, 0, 0] == 1.0) & np.isclose(beh[:, 0, 1], -math.radians(45)))[0])
    assert r.colregs[port] == pytest.approx(P.kappa)  # every scenario passes on the wrong side


def test_evaluate_matches_building_blocks():
    own, ob = _head_on_situation(probs=[0.1, 0.2, 0.4, 0.2, 0.1], weight=1.5, zeta=0.7)
    ob2 = Obstacle(state=[60.0, 120.0, 0.0, -2.0], cov=np.eye(4) * 0.5, n_ps=3, length=8.0)
    ring = np.array([(30.0, 15.0), (30.0, 60.0), (70.0, 60.0), (70.0, 15.0)])
    sit = Situation(own, (ob, ob2), (ring,))
    beh = paper_behaviours(1)[::5]
    cfg = PlannerConfig(T=60.0, dt=0.5)
    last = (1.0, 0.1)
    r = evaluate_reference(sit, beh, P, cfg, last_offsets=last)
    N = cfg.n_steps
    for l in range(beh.shape[0]):
        traj = ownship_trajectory(own, beh[l], P, cfg)
        assert np.array_equal(r.own_traj[l], traj)
        assert r.path[l] == path_cost(beh[l], last, P)
        assert r.so_j[l, 0] == grounding_cost(traj, ring, P, cfg, P.d_safe)
        assert r.so[l] == r.so_j[l, 0]
        h_do = h_col = 0.0
        for i, o in enumerate((ob, ob2)):
            sc = obstacle_scenarios(o, P, cfg)
            covs = obstacle_covariances(o, P, cfg)
            R = P.d_safe + 0.5 * (own.length + o.length)
            for s in range(o.n_ps):
                # independent, unvectorised recomputation over every k
                vals = []
                for k in range(N + 1):
                    pk = collision_probability(traj[k, :2], sc[s, k, :2], covs[k, :2, :2], R, "quadrature", P,
                                               cfg)
                    v0 = traj[k, 3] * np.array([math.cos(traj[k, 2]), math.sin(traj[k, 2])])
                    vi = sc[s, k, 3] * np.array([math.cos(sc[s, k, 2]), math.sin(sc[s, k, 2])])
                    vals.append(o.zeta * P.K_coll * float(np.sum((vi - v0) ** 2)) * pk * math.exp(-k * cfg.dt / P.T_d))
                assert r.C[i][l, s] == pytest.approx(max(vals), rel=1e-12, abs=1e-300)
                assert r.mu[i][l, s] == float(colregs_violation(traj, sc[s], P).any())
                h_do += o.weight * o.probs[s] * r.C[i][l, s]
                h_col += o.weight * o.probs[s] * r.mu[i][l, s]
        assert r.do[l] == pytest.approx(h_do, rel=1e-12)
        assert r.colregs[l] == pytest.approx(P.kappa * h_col, rel=1e-12)
    assert np.any(r.so > 0) and np.any(r.do > 0)


def test_evaluate_behaviour_order_is_irrelevant():
    own, ob = _head_on_situation()
    beh = paper_behaviours(1)[::4]
    cfg = PlannerConfig(T=40.0, dt=0.5)
    r = evaluate_reference(Situation(own, (ob,)), beh, P, cfg)
    r_rev = evaluate_reference(Situation(own, (ob,)), beh[::-1], P, cfg)
    assert np.array_equal(r.total, r_rev.total[::-1])


@pytest.mark.parametrize("estimator", ["mc", "ce"])
def test_evaluate_sampling_estimators(estimator):
    own, ob = _head_on_situation()
    beh = paper_behaviours(1)[[3, 6, 9]]
    cfg = PlannerConfig(T=100.0, dt=1.0, estimator=estimator, n_samples=300)
    rng = np.random.default_rng(5)
    shape = (300, 2) if estimator == "mc" else (cfg.ce_max_iter + 1, 300, 2)
    Z = rng.standard_normal(shape)
    r = evaluate_reference(Situation(own, (ob,)), beh, P, cfg, samples=Z)
    rq = evaluate_reference(Situation(own, (ob,)), beh, P, cfg.replace(estimator="quadrature"))
    assert np.all(np.isfinite(r.total)) and np.all(r.do >= 0)
    assert np.array_equal(r.colregs, rq.colregs) and np.array_equal(r.path, rq.path)
    # the same samples give the same numbers (common random numbers, deterministic)
    r2 = evaluate_reference(Situation(own, (ob,)), beh, P, cfg, samples=Z.copy())
    assert np.array_equal(r.total, r2.total)
    # and roughly the quadrature costs (straight ahead collides)
    assert r.do[1] == pytest.approx(rq.do[1], rel=0.3)


# ---------------------------------------------------------------------------------------------- errors
def test_bad_inputs_raise_clear_errors():
    own, ob = _head_on_situation()
    sit = Situation(own, (ob,))
    cfg = PlannerConfig(T=10.0, dt=0.5)
    beh = paper_behaviours(1)[:2]
    with pytest.raises(ValueError, match="behaviours must have shape"):
        evaluate_reference(sit, beh[:, 0, :], P, cfg)
    with pytest.raises(ValueError, match="speed factor"):
        evaluate_reference(sit, beh * [[[2.0, 1.0]]], P, cfg)
    with pytest.raises(ValueError, match="samples"):
        evaluate_reference(sit, beh, P, cfg.replace(estimator="mc", n_samples=10))
    with pytest.raises(ValueError, match=r"samples must have shape"):
        evaluate_reference(sit, beh, P, cfg.replace(estimator="mc", n_samples=10), samples=np.zeros((11, 2)))
    with pytest.raises(ValueError, match=r"samples must have shape"):
        evaluate_reference(sit, beh, P, cfg.replace(estimator="ce", n_samples=10), samples=np.zeros((10, 2)))
    with pytest.raises(ValueError, match="last_offsets"):
        evaluate_reference(sit, beh, P, cfg, last_offsets=(1.0,))
    with pytest.raises(ValueError, match="situation"):
        evaluate_reference(own, beh, P, cfg)
    with pytest.raises(ValueError, match="estimator must be one of"):
        collision_probability((0, 0), (1, 1), np.eye(2), 5.0, "exact", P, cfg)
    with pytest.raises(ValueError, match="Params.K_u"):
        evaluate_reference(sit, beh, P.replace(K_u=-1.0), cfg)
    # quadrature ignores a samples table
    r = evaluate_reference(sit, beh, P, cfg, samples=np.zeros((3, 3)))
    assert np.all(np.isfinite(r.total))


def test_singular_positional_covariance_is_rejected():
    # P_c needs a spread: a singular positional block is refused at construction, naming the field
    with pytest.raises(ValueError, match="obstacle.cov positional block"):
        Obstacle(state=[3.0, 0.0, -2.0, 0.0], cov=np.zeros((4, 4)), n_ps=3)
