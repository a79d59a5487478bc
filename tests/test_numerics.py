"""The one angle wrap (psbmpc_jax.numerics): the device wrap against a float64 NumPy reference, the host twin at
both ends of its interval, and bit for bit against the formulas it replaced (the oracle's wrap, the evaluation
tool's (−π, π] wrap, the chart projection's inline wrap), its derivative, and that importing it needs no JAX."""

from __future__ import annotations

import math
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from psbmpc_jax.numerics import TWO_PI, wrap_angle, wrap_angle_host

PI = math.pi
EDGES = [PI, -PI, 3 * PI, -3 * PI, np.nextafter(PI, 0.0), np.nextafter(PI, 4.0), np.nextafter(-PI, 0.0),
         np.nextafter(-PI, -4.0), 0.0, -0.0, 1e-20, -1e-20, 2 * PI, -2 * PI, 100.0, -100.0, 1e6, -1e6]


def _samples(n=4001, seed=0):
    rng = np.random.default_rng(seed)
    return np.concatenate([np.array(EDGES, float), rng.uniform(-50.0, 50.0, n), np.linspace(-4 * PI, 4 * PI, 1001)])


# the formulas the unified helper replaced, written out as they were (float64 NumPy)
def _old_lower(a):          # reference_prediction.wrap_angle / wrap_scalar, charts tm_forward, numerics host
    return np.mod(np.asarray(a, float) + np.pi, 2 * np.pi) - np.pi


def _old_upper(a):          # evaltool.geometry.wrap, evaltool.tracks.unwrap_interp
    return (np.pi - np.mod(np.pi - np.asarray(a, float), 2 * np.pi))[()]


def test_host_wrap_is_bit_identical_to_the_formulas_it_replaced():
    a = _samples()
    np.testing.assert_array_equal(wrap_angle_host(a), _old_lower(a))
    np.testing.assert_array_equal(wrap_angle_host(a, include_pi=True), _old_upper(a))
    np.testing.assert_array_equal(wrap_angle_host(a, include_pi=True), -wrap_angle_host(-a))
    # the Python-float path (the oracle's inner loop) gives the same bits as the array path
    for x in a[:200]:
        lo, up = wrap_angle_host(float(x)), wrap_angle_host(float(x), include_pi=True)
        assert type(lo) is float and type(up) is float
        assert lo == _old_lower(x) and up == _old_upper(x), x
        assert math.copysign(1.0, lo) == math.copysign(1.0, float(_old_lower(x)))


def test_host_wrap_intervals_and_ends():
    a = _samples()
    lo, up = wrap_angle_host(a), wrap_angle_host(a, include_pi=True)
    # in the interval, but for the one rounding at its ends (kept bit for bit: the oracle and the recorded runs
    # used it): an input an ulp beyond an odd multiple of pi can land on the other end
    out_lo, out_up = ~((lo >= -PI) & (lo < PI)), ~((up > -PI) & (up <= PI))
    assert np.all(np.abs(np.abs(lo[out_lo]) - PI) <= np.spacing(PI))
    assert np.all(np.abs(np.abs(up[out_up]) - PI) <= np.spacing(PI))
    assert out_lo.sum() <= 1 and out_up.sum() <= 1
    assert wrap_angle_host(np.nextafter(-PI, -4.0)) == PI             # the end case, as it always was
    assert wrap_angle_host(np.nextafter(PI, 4.0), include_pi=True) == -PI
    assert wrap_angle_host(PI) == -PI and wrap_angle_host(-PI) == -PI
    assert wrap_angle_host(PI, include_pi=True) == PI and wrap_angle_host(-PI, include_pi=True) == PI
    assert wrap_angle_host(3 * PI / 2) == pytest.approx(-PI / 2, abs=1e-15)
    assert wrap_angle_host(0.25) == 0.25 and wrap_angle_host(7) == pytest.approx(7 - TWO_PI, abs=1e-15)
    # same angle: differs from the input by a whole number of turns
    turns = (a - lo) / TWO_PI
    np.testing.assert_allclose(turns, np.round(turns), atol=1e-9)
    # types: a NumPy array in, a NumPy array out (never JAX); 0-d in, NumPy scalar out
    assert isinstance(wrap_angle_host(np.array([1.0, 5.0])), np.ndarray)
    assert isinstance(wrap_angle_host(np.asarray(5.0)), np.floating)


def test_device_wrap_matches_the_float64_reference():
    a = _samples()
    w = np.asarray(wrap_angle(jnp.asarray(a, jnp.float64)))      # x64 is on for the suite (conftest)
    ref = a - TWO_PI * np.floor((a + PI) / TWO_PI)            # float64 NumPy, the device formula
    np.testing.assert_array_equal(w, ref)
    out = ~((w >= -PI) & (w < PI))                                    # the end case: an ulp below an odd
    assert out.sum() <= 1 and np.all(np.abs(np.abs(w[out]) - PI) <= 2 * np.spacing(PI))   # multiple of pi
    assert float(wrap_angle(jnp.float32(0.0))) == 0.0
    # floor and mod round differently: the device and host wraps agree to a few ulp (mod to 2 pi where both
    # sit at an end of the interval)
    d = np.abs(w - wrap_angle_host(a))
    d = np.minimum(d, np.abs(d - TWO_PI))
    assert d.max() <= 8 * np.spacing(100.0 + 1e6)


@pytest.mark.parametrize("x", [0.3, -2.9, PI, -PI, 3 * PI, np.nextafter(PI, 0.0), 7.0])
def test_device_wrap_gradient(x):
    """d wrap / da = 1 everywhere (the turn count is piecewise constant), also at the ends, where JAX takes the
    floor's derivative 0; away from the ends central finite differences agree."""
    g = float(jax.grad(wrap_angle)(jnp.float64(x)))
    assert g == 1.0
    h = 1e-6
    if min(abs(x - PI), abs(x + PI), abs(x - 3 * PI)) > 10 * h:
        fd = (float(wrap_angle(jnp.float64(x + h))) - float(wrap_angle(jnp.float64(x - h)))) / (2 * h)
        assert fd == pytest.approx(1.0, abs=1e-8)


def test_numerics_imports_no_jax():
    """The host helpers serve modules that must not import JAX (chart and scenario loaders, oracles, evaltool)."""
    code = ("import sys, psbmpc_jax.numerics as n, psbmpc_jax.charts, psbmpc_jax.reference_prediction, "
            "psbmpc_jax.evaltool.geometry\n"
            "assert n.wrap_angle_host(3.5) < 0\n"
            "print('jax' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
