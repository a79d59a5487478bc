"""3-DOF manoeuvring truth model (psbmpc_jax.sim.vessel3dof): against an independent integration (scipy
solve_ivp of a separately written ODE), physics checks, the kinematic limit against sim/vessel.py, parameter
validation, zero speed and heading wrap-around."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import fsolve

from psbmpc_jax.sim import vessel3dof as v3
from psbmpc_jax.sim.vessel import kinematic_step

PSV = v3.preset("psv_116m")
SMALL = v3.preset("small_5m")


# ------------------------------------------------------------------ (a) independent integration
def reference_rhs(p: v3.Vessel3DOFParams, psi_c: float, u_c: float):
    """The closed-loop ODE written out scalar by scalar from the documented equations (docs/vessel3dof.md),
    independently of the module's vectorised code."""
    M = np.array(p.M)
    Minv = np.linalg.inv(M)
    D0, D1 = np.array(p.D0), np.array(p.D1)
    m11, m22, m23 = M[0, 0], M[1, 1], 0.5 * (M[1, 2] + M[2, 1])

    def f(t, z):
        x, y, psi, u, v, r = z
        U = math.sqrt(u * u + v * v)
        Ue = max(U, p.U_floor)
        nu = np.array([u, v, r])
        Cnu = np.array([-(m22 * v + m23 * r) * r, m11 * u * r, (m22 * v + m23 * r) * u - m11 * u * v])
        Dnu = D0 @ nu + Ue * (D1 @ nu) + np.array([p.X_uu * abs(u) * u, 0.0, 0.0])
        n = Cnu + Dnu
        tau_X = min(max(m11 * p.k_u * (u_c - u) + n[0], -p.X_rev), p.X_max)
        e = math.remainder(psi_c - psi, 2.0 * math.pi)
        r_d = min(max(p.k_psi * e, -p.r_max), p.r_max)
        # r_dot = Minv[2] (tau - n) with tau = (tau_X, c_YN tau_N, tau_N) and Minv[2, 0] = 0
        tau_N = (p.k_r * (r_d - r) + Minv[2, 1] * n[1] + Minv[2, 2] * n[2]) / (Minv[2, 1] * p.c_YN + Minv[2, 2])
        lim = p.N0 + p.N2 * U * U
        tau_N = min(max(tau_N, -lim), lim)
        nu_dot = np.linalg.solve(M, np.array([tau_X, p.c_YN * tau_N, tau_N]) - n)
        return [u * math.cos(psi) - v * math.sin(psi), u * math.sin(psi) + v * math.cos(psi), r, *nu_dot]

    return f


@pytest.mark.parametrize("name, U_max, seed", [("psv_116m", 8.0, 1), ("small_5m", 3.0, 2)])
def test_against_solve_ivp(name, U_max, seed):
    """Random initial states and held commands: step() at dt = 0.5 s for 60 s (PSV) / 20 s (5 m) vs DOP853 at
    rtol 1e-10: positions within 1 cm, heading within 1e-5 rad, velocities within 1e-5."""
    p = v3.preset(name)
    rng = np.random.default_rng(seed)
    n = 4
    s0 = np.column_stack([rng.uniform(-50, 50, n), rng.uniform(-50, 50, n), rng.uniform(-np.pi, np.pi, n),
                          rng.uniform(0.0, U_max, n), rng.uniform(-0.05, 0.05, n) * U_max,
                          rng.uniform(-0.5, 0.5, n) * p.r_max])
    chi_c = rng.uniform(-np.pi, np.pi, n)
    U_c = rng.uniform(0.0, U_max, n)
    T, dt = (60.0, 0.5) if name == "psv_116m" else (20.0, 0.5)
    s = s0.copy()
    P = v3.stack_params(p)
    for _ in range(int(T / dt)):
        s = v3.step(s, chi_c, U_c, dt, P)
    for i in range(n):
        sol = solve_ivp(reference_rhs(p, chi_c[i], U_c[i]), (0.0, T), s0[i], method="DOP853", rtol=1e-10,
                        atol=1e-9)
        ref = sol.y[:, -1]
        # RK4 is 4th order between the saturation kinks; across them it drops order: 1 cm after 60 s
        assert np.hypot(*(s[i, :2] - ref[:2])) < 1e-2, (i, s[i], ref)
        assert abs(math.remainder(s[i, 2] - ref[2], 2 * math.pi)) < 1e-5
        np.testing.assert_allclose(s[i, 3:], ref[3:], atol=1e-5)


def test_batched_per_ship_params_match_single_steps():
    """[runs, ships, 6] with one parameter set per ship equals stepping each ship alone."""
    rng = np.random.default_rng(3)
    s = np.zeros((3, 2, 6))
    s[..., 2] = rng.uniform(-3, 3, (3, 2))
    s[..., 3] = [6.0, 2.0]
    chi_c, U_c = rng.uniform(-3, 3, (3, 2)), np.array([[7.0, 1.5]] * 3)
    out = v3.step(s, chi_c, U_c, 1.0, [PSV, SMALL])
    assert out.shape == (3, 2, 6)
    for j, p in enumerate([PSV, SMALL]):
        # the batch uses the smaller of the two max_substep values for both ships: agreement to RK4 accuracy
        np.testing.assert_allclose(out[:, j], v3.step(s[:, j], chi_c[:, j], U_c[:, j], 1.0, p), rtol=0, atol=1e-7)


def test_substeps_make_large_dt_consistent():
    """dt = 1 s (internal substeps) agrees with ten dt = 0.1 s calls."""
    s0 = v3.from_sim_state(np.array([0.0, 0.0, 0.3, 1.0]))
    a = v3.step(s0, 1.2, 2.0, 1.0, SMALL)
    b = s0
    for _ in range(10):
        b = v3.step(b, 1.2, 2.0, 0.1, SMALL)
    np.testing.assert_allclose(a, b, atol=1e-6)


# ------------------------------------------------------------------------------- (b) physics
def run(p, s, chi_c, U_c, T, dt=0.5):
    P = v3.stack_params(p)
    for _ in range(int(round(T / dt))):
        s = v3.step(s, chi_c, U_c, dt, P)
    return s


@pytest.mark.parametrize("p, U0, U_c", [(PSV, 0.0, 7.0), (PSV, 7.0, 3.5), (SMALL, 0.5, 2.0)])
def test_straight_run_converges_to_commanded_speed(p, U0, U_c):
    s = run(p, v3.from_sim_state(np.array([0.0, 0.0, 0.4, U0])), 0.4, U_c, T=20.0 / p.k_u)
    assert abs(s[3] - U_c) < 1e-4 * U_c
    assert abs(s[4]) < 1e-9 and abs(s[5]) < 1e-9 and abs(s[2] - 0.4) < 1e-9
    view = v3.sim_view(s)
    assert abs(view[2] - 0.4) < 1e-9 and abs(view[3] - U_c) < 1e-4 * U_c
    # the track is the commanded straight line
    assert abs(-s[0] * math.sin(0.4) + s[1] * math.cos(0.4)) < 1e-6


@pytest.mark.parametrize("p, U, dchi", [(PSV, 7.0, 90.0), (SMALL, 2.0, -120.0)])
def test_turn_converges_to_commanded_heading_and_course(p, U, dchi):
    chi_c = math.radians(dchi)
    s = run(p, v3.from_sim_state(np.array([0.0, 0.0, 0.0, U])), chi_c, U, T=abs(chi_c) / p.r_max + 12.0 / p.k_psi)
    assert abs(math.remainder(s[2] - chi_c, 2 * math.pi)) < math.radians(0.05)
    assert abs(math.remainder(v3.sim_view(s)[2] - chi_c, 2 * math.pi)) < math.radians(0.1)
    assert abs(s[3] - U) < 1e-3 * U


def test_turn_rate_is_limited_by_the_rate_limit():
    """A 170 deg course change: the yaw rate never exceeds r_max and holds it mid-turn."""
    s = v3.from_sim_state(np.array([0.0, 0.0, 0.0, 7.0]))
    chi_c = math.radians(170.0)
    rs = []
    for _ in range(120):
        s = v3.step(s, chi_c, 7.0, 1.0, PSV)
        rs.append(s[5])
    rs = np.array(rs)
    assert rs.max() <= PSV.r_max * (1 + 1e-6)
    assert np.isclose(rs[60], PSV.r_max, rtol=1e-3)


def test_steady_turn_rate_is_limited_by_the_yaw_actuator():
    """Without a rate limit and with weak thrusters, the yaw moment saturates and the steady turn is the
    equilibrium of the equations of motion at tau_N = N0 + N2 U^2, well below the commanded rate."""
    p = SMALL.replace(r_max=math.inf, N0=20.0)
    P = v3.stack_params(p)
    s = v3.from_sim_state(np.array([0.0, 0.0, 0.0, 2.0]))
    for _ in range(1500):
        s = v3.step(s, s[2] + math.radians(170.0), 2.0, 0.1, P)
    tau = v3.control_forces(P, s[2], s[3:], s[2] + math.radians(170.0), 2.0)
    U = math.hypot(s[3], s[4])
    lim = p.N0 + p.N2 * U * U
    assert tau[2] == pytest.approx(lim, rel=1e-9)                       # saturated yaw moment
    assert s[5] < 0.5 * p.k_psi * math.radians(170.0)                 # far below the heading loop's demand
    # steady state: nu_dot = 0 with the saturated tau (surge force from the autopilot at the reached state)
    M, D0, D1 = np.array(p.M), np.array(p.D0), np.array(p.D1)

    def residual(z):
        u, v, r = z
        nu = np.array([u, v, r])
        m11, m22, m23 = M[0, 0], M[1, 1], 0.5 * (M[1, 2] + M[2, 1])
        C = np.array([-(m22 * v + m23 * r) * r, m11 * u * r, (m22 * v + m23 * r) * u - m11 * u * v])
        Uz = max(math.hypot(u, v), p.U_floor)
        N = p.N0 + p.N2 * (u * u + v * v)
        return np.array([tau[0], p.c_YN * N, N]) - C - D0 @ nu - Uz * (D1 @ nu)

    eq = fsolve(residual, s[3:], xtol=1e-12)
    np.testing.assert_allclose(s[3:], eq, rtol=1e-4, atol=1e-6)
    assert abs(eq[2]) > 0.2                     # a real turn, not the trivial equilibrium


@pytest.mark.parametrize("p", [PSV, SMALL])
def test_zero_commands_in_still_water_decay(p):
    """Zero speed and heading commands: surge and yaw rate are driven to rest, the sway velocity decays freely
    (its low-speed damping is U_floor * D1[1, 1]: time constant m22 / (U_floor D1[1, 1]), 150 s for the PSV)."""
    scale = math.sqrt(p.length / 116.0)
    s0 = np.array([0.0, 0.0, 0.0, 6.0 * scale, 0.3 * scale, 0.5 * p.r_max])
    T_v = p.M[1][1] / (p.U_floor * p.D1[1][1])
    s = run(p, s0, 0.0, 0.0, T=max(30.0 / p.k_u, 8.0 * T_v))
    assert abs(s[3]) < 1e-6 * s0[3] and abs(s[5]) < 1e-6 * p.r_max and abs(s[2]) < 1e-4
    assert abs(s[4]) < 2e-3 * s0[4]
    speed = [math.hypot(*x[3:5]) for x in (s0, run(p, s0, 0.0, 0.0, T=10.0 / p.k_u))]
    assert speed[1] < 0.01 * speed[0]


def test_presets_step_response_times():
    """The presets' measured 63 % course/speed rise times (documented in docs/vessel3dof.md)."""
    T_chi, T_U = v3.step_response_times(PSV, 7.0, 10.0, dt=0.5, horizon=60.0)
    assert 12.0 < T_chi < 18.0 and T_U == pytest.approx(30.0, rel=0.02)
    T_chi, T_U = v3.step_response_times(SMALL, 2.0, 10.0, dt=0.1, horizon=12.0)
    assert 2.0 < T_chi < 3.5 and T_U == pytest.approx(5.0, rel=0.02)


# ---------------------------------------------------------------------------- (c) kinematic limit
def test_kinematic_limit_matches_kinematic_model():
    """A fast, near-massless vessel follows course and speed commands like sim/vessel.py's kinematic model with
    the same time constants: positions within 5 cm, course within 0.5 deg (yaw-rate lag 1/k_r = 5 ms), speed
    within 0.01 m/s over 60 s of course and speed changes (about 250 m of track).  The PSV is far off."""
    T_chi, T_U = 2.0, 3.0
    p = v3.kinematic_limit_params(T_chi, T_U)
    dt_kin, dt = 0.01, 0.1
    kin = np.array([0.0, 0.0, 0.0, 2.0])
    s = v3.from_sim_state(kin)
    psv = v3.from_sim_state(kin)
    P = v3.stack_params(p)
    worst = np.zeros(3)
    for k in range(600):
        t = k * dt
        chi_c = 0.0 if t < 5 else (1.0 if t < 25 else (-0.8 if t < 40 else 2.9))
        U_c = 2.0 if t < 10 else (5.0 if t < 30 else 3.0)
        for _ in range(int(round(dt / dt_kin))):
            kin = kinematic_step(kin, chi_c, U_c, T_chi, T_U, dt_kin)
        s = v3.step(s, chi_c, U_c, dt, P)
        psv = v3.step(psv, chi_c, U_c, dt, PSV)
        view = v3.sim_view(s)
        err = [np.hypot(*(view[:2] - kin[:2])), abs(math.remainder(view[2] - kin[2], 2 * math.pi)),
               abs(view[3] - kin[3])]
        worst = np.maximum(worst, err)
    assert worst[0] < 0.05 and worst[1] < math.radians(0.5) and worst[2] < 0.01, worst
    assert np.hypot(*(v3.sim_view(psv)[:2] - kin[:2])) > 20.0


# ------------------------------------------------------------------------------- (d) validation
@pytest.mark.parametrize("field, value", [
    ("k_u", 0.0), ("k_psi", -1.0), ("k_r", math.nan), ("r_max", 0.0), ("max_substep", 0.0), ("X_max", -1.0),
    ("X_rev", -1.0), ("N2", -1.0), ("U_floor", -0.1), ("X_uu", math.inf), ("length", 0.0),
    ("M", np.diag([1.0, 1.0, -1.0])), ("M", [[1.0, 0.1, 0.0], [0.1, 1.0, 0.0], [0.0, 0.0, 1.0]]),
    ("M", np.eye(2)), ("D0", np.ones((2, 3))), ("D1", np.full((3, 3), np.nan)), ("D0", -np.eye(3)),
    ("c_YN", "x"),
])
def test_validation_names_the_field(field, value):
    with pytest.raises(ValueError, match=field):
        SMALL.replace(**{field: value})


def test_validation_no_yaw_actuator_and_unknown_preset():
    with pytest.raises(ValueError, match="N0 and N2"):
        SMALL.replace(N0=0.0, N2=0.0)
    with pytest.raises(ValueError, match="vessel_model"):
        v3.preset("tanker")
    with pytest.raises(ValueError, match="state"):
        v3.step(np.zeros(4), 0.0, 1.0, 0.1, SMALL)


# --------------------------------------------------------------------- (e) zero speed, wrap-around
@pytest.mark.parametrize("p", [PSV, SMALL])
def test_zero_speed_no_nan(p):
    s = np.zeros((2, 6))
    out = v3.step(s, np.array([0.0, 2.0]), 0.0, 1.0, p)
    assert np.all(np.isfinite(out))
    np.testing.assert_array_equal(out[0], 0.0)
    view = v3.sim_view(out)
    assert np.all(np.isfinite(view))
    assert view[0, 2] == 0.0 and view[0, 3] == 0.0
    assert out[1, 5] > 0.0                       # turns towards the command even at zero speed (thrusters)


@pytest.mark.parametrize("p, U", [(PSV, 7.0), (SMALL, 2.0)])
def test_heading_wraps_and_turns_the_short_way(p, U):
    psi0, chi_c = math.pi - 0.05, -math.pi + 0.05                 # 0.1 rad to starboard across +-pi
    s = v3.from_sim_state(np.array([0.0, 0.0, psi0, U]))
    P = v3.stack_params(p)
    psis = []
    for _ in range(int(10.0 / p.k_psi)):
        s = v3.step(s, chi_c, U, 1.0, P)
        psis.append(s[2])
        assert -math.pi <= s[2] < math.pi
    assert s[5] >= -1e-9 and min(np.abs(np.array(psis))) > math.pi - 0.06   # never turned through 0
    assert abs(math.remainder(s[2] - chi_c, 2 * math.pi)) < 1e-3
    assert abs(math.remainder(v3.sim_view(s)[2] - chi_c, 2 * math.pi)) < 2e-3
