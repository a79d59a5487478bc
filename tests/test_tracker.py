"""Constant-velocity Kalman filter (psbmpc_jax.sim.tracker): matrices, exactness, consistency (NEES), masks,
the TrackerBank and input validation."""

from __future__ import annotations

import math
from statistics import NormalDist

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from psbmpc_jax.sim.tracker import (
    CONSERVATIVE_R_FACTOR,
    CONSERVATIVE_SIGMA_A,
    TrackerBank,
    cv_model,
    initiate,
    nees,
    predict,
    update,
)

R_TRUE = 25.0 * np.eye(2)       # seed 004 §7: diag(25, 25) m², i.e. 5 m position noise std
DT = 2.5                        # 0.4 Hz measurements


def chi2_bounds(dof: int, p_low: float, p_high: float) -> tuple[float, float]:
    """Chi-square quantiles by the Wilson–Hilferty approximation (accurate to <0.1 % for dof in the hundreds)."""
    def q(p):
        z = NormalDist().inv_cdf(p)
        h = 2.0 / (9.0 * dof)
        return dof * (1.0 - h + z * math.sqrt(h)) ** 3
    return q(p_low), q(p_high)


def test_wilson_hilferty_matches_sampled_quantiles():
    rng = np.random.default_rng(1)
    draws = rng.chisquare(800, size=200_000)
    lo, hi = chi2_bounds(800, 0.005, 0.995)
    assert np.quantile(draws, 0.005) == pytest.approx(lo, rel=2e-3)
    assert np.quantile(draws, 0.995) == pytest.approx(hi, rel=2e-3)


# ------------------------------------------------------------------------------------------------ matrices
def test_cv_model_hand_values():
    F, Q = cv_model(2.0, 0.5)
    np.testing.assert_array_equal(F, [[1, 0, 2, 0], [0, 1, 0, 2], [0, 0, 1, 0], [0, 0, 0, 1]])
    q = 0.25
    expected = q * np.array([[8 / 3, 0, 2, 0], [0, 8 / 3, 0, 2], [2, 0, 2, 0], [0, 2, 0, 2]])
    np.testing.assert_allclose(Q, expected, rtol=1e-15)
    assert np.all(np.linalg.eigvalsh(Q) > 0)
    _, Q0 = cv_model(1.0, 0.0)
    np.testing.assert_array_equal(Q0, np.zeros((4, 4)))


def test_initiate_hand_values_and_seed_004_velocity_variance():
    R = np.array([[625.0, 10.0], [10.0, 400.0]])
    x, P = initiate([100.0, -50.0], R, U_max=9.0)
    np.testing.assert_array_equal(x, [100.0, -50.0, 0.0, 0.0])
    np.testing.assert_array_equal(P[:2, :2], R)
    np.testing.assert_array_equal(P[:2, 2:], np.zeros((2, 2)))
    assert P[2, 2] == P[3, 3] == pytest.approx(20.25)    # "surpassing 20 (m/s)² initially"
    assert P[2, 3] == 0.0
    _, P3 = initiate([0.0, 0.0], R, U_max=9.0, kappa=3.0)
    assert P3[2, 2] == pytest.approx(9.0)


def test_initiate_broadcasts_over_batch_axes():
    z = np.arange(3 * 5 * 2, dtype=float).reshape(3, 5, 2)
    x, P = initiate(z, R_TRUE, 10.0)
    assert x.shape == (3, 5, 4) and P.shape == (3, 5, 4, 4)
    np.testing.assert_array_equal(x[..., :2], z)
    np.testing.assert_array_equal(x[..., 2:], 0.0)
    np.testing.assert_array_equal(P[2, 4, :2, :2], R_TRUE)


@settings(max_examples=30, deadline=None)
@given(st.floats(-1e4, 1e4), st.floats(-1e4, 1e4), st.floats(-12, 12), st.floats(-12, 12),
       st.floats(0.01, 30.0), st.integers(1, 20))
def test_predict_noise_free_cv_target_is_exact(n0, e0, vn, ve, dt, steps):
    x = np.array([n0, e0, vn, ve])
    P = np.diag([4.0, 9.0, 1.0, 2.0])
    xk, Pk = x, P
    for _ in range(steps):
        xk, Pk = predict(xk, Pk, dt, 0.0)
    T = dt * steps
    np.testing.assert_allclose(xk, [n0 + vn * T, e0 + ve * T, vn, ve], rtol=1e-12, atol=1e-8)
    F, _ = cv_model(T, 0.0)             # sigma_a = 0: P propagates exactly as F(T) P F(T)ᵀ
    np.testing.assert_allclose(Pk, F @ P @ F.T, rtol=1e-10)


def test_predict_adds_process_noise_and_stays_symmetric():
    x, P = initiate([0.0, 0.0], R_TRUE, 9.0)
    x1, P1 = predict(x, P, DT, 0.5)
    F, Q = cv_model(DT, 0.5)
    np.testing.assert_allclose(P1, F @ P @ F.T + Q)
    np.testing.assert_array_equal(P1, P1.T)


def test_update_reduces_trace_and_matches_textbook_form():
    rng = np.random.default_rng(3)
    A = rng.normal(size=(6, 4, 4))
    P = A @ np.swapaxes(A, -1, -2) + np.eye(4)
    x = rng.normal(size=(6, 4)) * 10
    z = rng.normal(size=(6, 2)) * 10
    xu, Pu, nis = update(x, P, z, R_TRUE)
    assert np.all(np.trace(Pu, axis1=-2, axis2=-1) < np.trace(P, axis1=-2, axis2=-1))
    np.testing.assert_array_equal(Pu, np.swapaxes(Pu, -1, -2))
    Hm = np.hstack([np.eye(2), np.zeros((2, 2))])
    for i in range(6):                                   # textbook (non-Joseph) form, one track at a time
        S = Hm @ P[i] @ Hm.T + R_TRUE
        K = P[i] @ Hm.T @ np.linalg.inv(S)
        nu = z[i] - Hm @ x[i]
        np.testing.assert_allclose(xu[i], x[i] + K @ nu, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(Pu[i], (np.eye(4) - K @ Hm) @ P[i], rtol=1e-8, atol=1e-8)
        assert nis[i] == pytest.approx(nu @ np.linalg.solve(S, nu), rel=1e-10)


# ------------------------------------------------------------------------------------------------ consistency
def simulate(n_runs, n_steps, sigma_true, filt_R, filt_sigma_a, U_max, seed):
    """Targets with CV truth (white-noise acceleration sigma_true, 0 = straight lines), 5 m position noise every
    2.5 s, filtered from single-point initiation. Returns the mean NEES over runs at each step [n_steps]."""
    rng = np.random.default_rng(seed)
    chi = rng.uniform(-np.pi, np.pi, n_runs)
    U = rng.uniform(2.0, 10.0, n_runs)
    xt = np.column_stack([rng.uniform(-2000, 2000, (n_runs, 2)), U * np.cos(chi), U * np.sin(chi)])
    F, Q = cv_model(DT, sigma_true)
    L = np.linalg.cholesky(Q) if sigma_true > 0 else np.zeros((4, 4))
    out = np.empty(n_steps)
    x = P = None
    for k in range(n_steps):
        if k:
            xt = xt @ F.T + rng.normal(size=(n_runs, 4)) @ L.T
            x, P = predict(x, P, DT, filt_sigma_a)
        z = xt[:, :2] + rng.normal(0.0, 5.0, (n_runs, 2))
        if k == 0:
            x, P = initiate(z, filt_R, U_max)
        else:
            x, P, _ = update(x, P, z, filt_R)
        out[k] = nees(xt, x, P).mean()
    return out


N_RUNS = 200


@pytest.mark.parametrize("sigma", [0.0, 0.05], ids=["straight-lines", "white-noise-acceleration"])
def test_nees_consistency_with_true_model(sigma):
    """Average NEES over 200 runs within the two-sided 99 % chi-square bounds (4N dof)/N at late times.

    Straight-line truth is matched by sigma_a = 0 (any sigma_a > 0 makes the filter conservative there: with
    sigma_a = 0.01 the late mean NEES is about 2); the second case draws the truth from eq. (3) with the same Q.
    """
    mean_nees = simulate(N_RUNS, 100, sigma, R_TRUE, sigma, U_max=10.0, seed=7)
    lo, hi = chi2_bounds(4 * N_RUNS, 0.005, 0.995)
    for k in (50, 75, 99):
        assert lo / N_RUNS < mean_nees[k] < hi / N_RUNS, (k, mean_nees[k], lo / N_RUNS, hi / N_RUNS)


def test_small_process_noise_on_straight_lines_is_conservative_not_overconfident():
    mean_nees = simulate(N_RUNS, 100, 0.0, R_TRUE, 0.01, U_max=10.0, seed=7)
    _, hi = chi2_bounds(4 * N_RUNS, 0.005, 0.995)
    assert np.all(mean_nees[50:] < hi / N_RUNS)
    assert mean_nees[50:].mean() < 4.0


def test_seed_004_conservative_tuning_gives_low_nees():
    mean_nees = simulate(N_RUNS, 100, 0.0, CONSERVATIVE_R_FACTOR * R_TRUE, CONSERVATIVE_SIGMA_A, 9.0, seed=11)
    assert CONSERVATIVE_R_FACTOR == 25.0 and CONSERVATIVE_SIGMA_A == 0.5
    assert np.all(mean_nees[5:] < 1.0)        # far below 4: covariance much larger than the actual error


# ------------------------------------------------------------------------------------------------ masks
def test_masked_update_leaves_state_unchanged_and_nis_nan():
    x, P = initiate(np.array([[0.0, 0.0], [100.0, 50.0], [-30.0, 20.0]]), R_TRUE, 9.0)
    x, P = predict(x, P, DT, 0.5)
    z = np.array([[3.0, -2.0], [np.nan, np.nan], [-25.0, 22.0]])
    mask = np.array([True, False, True])
    xu, Pu, nis = update(x, P, z, R_TRUE, mask=mask)
    np.testing.assert_array_equal(xu[1], x[1])
    np.testing.assert_array_equal(Pu[1], P[1])
    assert np.isnan(nis[1]) and np.all(np.isfinite(nis[[0, 2]]))
    assert not np.allclose(xu[0], x[0]) and np.all(np.isfinite(xu))
    x_all, P_all, _ = update(x[[0, 2]], P[[0, 2]], z[[0, 2]], R_TRUE)
    np.testing.assert_allclose(xu[[0, 2]], x_all)
    np.testing.assert_allclose(Pu[[0, 2]], P_all)


def test_tracker_bank_initiation_prediction_and_update():
    bank = TrackerBank((2, 3), CONSERVATIVE_R_FACTOR * R_TRUE, CONSERVATIVE_SIGMA_A, U_max=9.0)
    assert bank.x.shape == (2, 3, 4) and bank.P.shape == (2, 3, 4, 4)
    assert not bank.initiated.any() and np.isnan(bank.x).all()
    bank.step(DT)                                          # nothing initiated: nothing happens
    assert np.isnan(bank.x).all()

    z0 = np.arange(12, dtype=float).reshape(2, 3, 2) * 10.0
    mask0 = np.array([[True, False, True], [False, True, False]])
    nis = bank.measure(z0, mask0)
    assert np.isnan(nis).all()                             # initiation, not an update
    np.testing.assert_array_equal(bank.initiated, mask0)
    np.testing.assert_array_equal(bank.x[mask0, :2], z0[mask0])
    np.testing.assert_array_equal(bank.x[mask0, 2:], 0.0)
    _, P_doc = initiate([0.0, 0.0], CONSERVATIVE_R_FACTOR * R_TRUE, 9.0)
    for P in bank.P[mask0]:
        np.testing.assert_array_equal(P, P_doc)
    assert np.isnan(bank.x[~mask0]).all()

    x_before, P_before = bank.x.copy(), bank.P.copy()
    bank.step(DT)
    x_pred, P_pred = predict(x_before[mask0], P_before[mask0], DT, CONSERVATIVE_SIGMA_A)
    np.testing.assert_allclose(bank.x[mask0], x_pred)
    np.testing.assert_allclose(bank.P[mask0], P_pred)

    z1 = z0 + 5.0
    nis = bank.measure(z1)                                  # all measured: 3 updates + 3 initiations
    assert bank.initiated.all()
    assert np.all(np.isfinite(nis[mask0])) and np.isnan(nis[~mask0]).all()
    x_upd, P_upd, nis_ref = update(x_pred, P_pred, z1[mask0], CONSERVATIVE_R_FACTOR * R_TRUE)
    np.testing.assert_allclose(bank.x[mask0], x_upd)
    np.testing.assert_allclose(bank.P[mask0], P_upd)
    np.testing.assert_allclose(nis[mask0], nis_ref)
    np.testing.assert_array_equal(bank.x[~mask0, :2], z1[~mask0])


def test_tracker_bank_tracks_a_straight_line_target():
    bank = TrackerBank((1,), R_TRUE, 0.01, U_max=10.0)
    rng = np.random.default_rng(5)
    truth = np.array([0.0, 0.0, 3.0, -4.0])
    for k in range(80):
        if k:
            truth[:2] += DT * truth[2:]
            bank.step(DT)
        bank.measure((truth[:2] + rng.normal(0, 5.0, 2))[None])
    assert np.hypot(*(bank.x[0, :2] - truth[:2])) < 10.0
    assert np.hypot(*(bank.x[0, 2:] - truth[2:])) < 0.3


# ------------------------------------------------------------------------------------------------ bad input
@pytest.mark.parametrize("call, match", [
    (lambda: cv_model(0.0, 0.5), "dt"),
    (lambda: cv_model(-1.0, 0.5), "dt"),
    (lambda: cv_model(float("nan"), 0.5), "dt"),
    (lambda: cv_model(1.0, -0.1), "sigma_a"),
    (lambda: initiate([0.0, 0.0, 0.0], R_TRUE, 9.0), "trailing shape"),
    (lambda: initiate([0.0, 0.0], np.eye(3), 9.0), "trailing shape"),
    (lambda: initiate([0.0, 0.0], [[1.0, 2.0], [0.0, 1.0]], 9.0), "symmetric"),
    (lambda: initiate([0.0, 0.0], -np.eye(2), 9.0), "positive definite"),
    (lambda: initiate([0.0, 0.0], R_TRUE, 0.0), "U_max"),
    (lambda: initiate([0.0, 0.0], R_TRUE, 9.0, kappa=0.0), "kappa"),
    (lambda: initiate([np.nan, 0.0], R_TRUE, 9.0), "finite"),
    (lambda: predict(np.zeros(4), np.eye(4), 0.0, 0.5), "dt"),
    (lambda: predict(np.zeros(3), np.eye(4), 1.0, 0.5), "x"),
    (lambda: update(np.zeros(4), np.eye(4), [np.nan, 0.0], R_TRUE), "z must be finite"),
    (lambda: update(np.zeros((2, 4)), np.eye(4), np.zeros((2, 2)), R_TRUE, mask=[1, 0]), "boolean"),
    (lambda: update(np.zeros((2, 4)), np.eye(4), np.zeros((2, 2)), R_TRUE, mask=np.ones(3, bool)), "mask"),
    (lambda: nees(np.zeros(4), np.zeros(4), np.eye(3)), "P"),
    (lambda: TrackerBank((2, -1), R_TRUE, 0.5, 9.0), "n_batch_shape"),
    (lambda: TrackerBank((2,), R_TRUE, -0.5, 9.0), "sigma_a"),
    (lambda: TrackerBank((2,), np.zeros((2, 2)), 0.5, 9.0), "positive definite"),
    (lambda: TrackerBank((2,), R_TRUE, 0.5, 9.0).step(0.0), "dt"),
    (lambda: TrackerBank((2,), R_TRUE, 0.5, 9.0).measure(np.zeros((3, 2))), "shape"),
    (lambda: TrackerBank((2,), R_TRUE, 0.5, 9.0).measure(np.zeros((2, 2)), np.array([1, 1])), "mask"),
    (lambda: TrackerBank((2,), R_TRUE, 0.5, 9.0).measure(np.full((2, 2), np.nan)), "finite"),
])
def test_bad_inputs_raise_value_error(call, match):
    with pytest.raises(ValueError, match=match):
        call()
