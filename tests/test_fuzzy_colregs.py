"""FIS_colregs of Smooth-SBMPC (psbmpc_jax.costs.colregs_fuzzy): the spec's test vectors, the float64 oracle
(psbmpc_jax.reference_smooth) on random inputs, the encounter geometry, finite-difference gradients w.r.t.
positions, no NaN at the degenerate points, and parameter validation."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from psbmpc_jax import reference_smooth as rs
from psbmpc_jax.costs import colregs_fuzzy as cf
from psbmpc_jax.costs.sbmpc import colregs_boolean

from conftest import central_difference

# (ΔCOG [deg], RB [deg], d [m]) and μ with the default-false completion / the literal rule base (SPEC §1.4:
# ε = 1e-6, N_y = 201, d_cl = 40 m, e_cl = 5 m).
SPEC_CASES = np.array([(90.0, 45.0, 20.0), (178.0, 10.0, 20.0), (90.0, -45.0, 20.0), (90.0, 45.0, 200.0),
                       (10.0, 45.0, 20.0), (90.0, -45.0, 200.0)])
SPEC_DEFAULT_FALSE = [0.9687, 0.9687, 0.0309, 0.0309, 0.0309, 0.0309]
SPEC_LITERAL = [0.9694, 0.9694, 0.5144, 0.5144, 0.5144, 0.0309]
FIS = dict(d_cl=40.0, e_cl=5.0, eps=1e-6, n_y=201)

# jitted once per module (eager dispatch of the many small ops is slow); the numeric parameters are traced
fis = jax.jit(cf.fis_colregs, static_argnames=("n_y", "completion", "angles"))
fis_states = jax.jit(cf.fis_colregs_states, static_argnames=("n_y", "completion"))
encounter = jax.jit(cf.encounter_inputs)


def test_x64_is_on():
    assert jnp.asarray(1.0).dtype == jnp.float64


# ============================================================================ spec test vectors
@pytest.mark.parametrize("completion, expected", [("default_false", SPEC_DEFAULT_FALSE), ("literal", SPEC_LITERAL)])
def test_spec_vectors(completion, expected):
    dcog, rb, d = SPEC_CASES.T
    mu_deg = np.asarray(fis(dcog, rb, d, completion=completion, angles="deg", **FIS))
    mu_rad = np.asarray(fis(np.radians(dcog), np.radians(rb), d, completion=completion, **FIS))
    np.testing.assert_allclose(mu_deg, expected, atol=1e-4)
    np.testing.assert_allclose(mu_rad, mu_deg, rtol=0, atol=1e-12)
    ref = [rs.fis_mu(*c, completion=completion, angles="deg", **FIS) for c in SPEC_CASES]
    np.testing.assert_allclose(mu_deg, ref, rtol=0, atol=1e-10)


def test_defaults_are_the_proposed_values():
    dcog, rb, d = SPEC_CASES.T
    np.testing.assert_allclose(np.asarray(fis(dcog, rb, d, angles="deg")), SPEC_DEFAULT_FALSE, atol=1e-4)


def test_spec_vectors_from_states_agree_with_the_boolean_original():
    """Build own-ship/target states realising each spec case: the FIS (default-false completion) says
    "violation" (μ > 0.5) exactly where Johansen's Boolean μ is 1."""
    own = np.array([0.0, 0.0, 0.3, 1.5])                       # own course 0.3 rad, 1.5 m/s
    tgts = []
    for dcog, rb, d in SPEC_CASES:
        bearing = own[2] + math.radians(rb)
        chi_t = own[2] + math.radians(dcog)                    # ΔCOG = |wrap(χ_t − χ_o)|
        tgts.append([d * math.cos(bearing), d * math.sin(bearing), chi_t, 1.0])
    tgts = np.array(tgts)
    dcog, rb, d = (np.asarray(a) for a in encounter(own, tgts))
    np.testing.assert_allclose(np.degrees(dcog), SPEC_CASES[:, 0], atol=1e-9)
    np.testing.assert_allclose(np.degrees(rb), SPEC_CASES[:, 1], atol=1e-9)
    np.testing.assert_allclose(d, SPEC_CASES[:, 2], atol=1e-9)
    mu = np.asarray(fis_states(own, tgts))
    np.testing.assert_allclose(mu, SPEC_DEFAULT_FALSE, atol=1e-4)
    boolean = np.asarray(jax.jit(colregs_boolean)(own, tgts, d_cl=40.0))
    np.testing.assert_array_equal(boolean, [1, 1, 0, 0, 0, 0])
    np.testing.assert_array_equal(mu > 0.5, boolean == 1)


# ============================================================================ oracle on random inputs
@pytest.mark.parametrize("completion, eps, n_y", [("default_false", 1e-6, 201), ("literal", 1e-6, 201),
                                                  ("literal", 1e-4, 11), ("default_false", 0.0, 51),
                                                  ("default_false", 1e-8, 2)])
def test_fis_matches_the_oracle(completion, eps, n_y):
    rng = np.random.default_rng(7 + n_y)
    n = 60
    dcog = rng.uniform(0.0, math.pi, n)
    rb = rng.uniform(-math.pi, math.pi, n)
    d = rng.uniform(0.0, 80.0, n)
    d_cl, e_cl = rng.uniform(20.0, 60.0), rng.uniform(1.0, 10.0)
    kw = dict(d_cl=d_cl, e_cl=e_cl, eps=eps, n_y=n_y, completion=completion)
    got = np.asarray(fis(dcog, rb, d, **kw))
    ref = np.array([rs.fis_mu(a, b, c, **kw) for a, b, c in zip(dcog, rb, d)])
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-10)
    assert np.all((got > 0) & (got < 1))
    assert np.ptp(got) > (0.5 if n_y > 2 else 0.0)            # both "true" and "false" outputs occur


def test_memberships_match_the_oracle():
    rng = np.random.default_rng(3)
    dcog, rb, d = rng.uniform(0, 180, 40), rng.uniform(-180, 180, 40), rng.uniform(0, 80, 40)
    m = jax.jit(cf.memberships)(dcog, rb, d, 35.0, 4.0)
    for i in range(40):
        ref = rs.fis_memberships(dcog[i], rb[i], d[i], 35.0, 4.0)
        for name in ("OT", "CR", "HO", "SB", "SBAH", "CL"):
            assert abs(float(getattr(m, name)[i]) - ref[name]) < 1e-12, name


def test_geometry_matches_the_oracle():
    rng = np.random.default_rng(11)
    own = np.stack([rng.uniform(-50, 50, 50), rng.uniform(-50, 50, 50), rng.uniform(-7, 7, 50),
                    rng.uniform(0, 3, 50)], axis=1)
    tgt = np.stack([rng.uniform(-50, 50, 50), rng.uniform(-50, 50, 50), rng.uniform(-7, 7, 50),
                    rng.uniform(0, 3, 50)], axis=1)
    dcog, rb, d = (np.asarray(a) for a in encounter(own, tgt))
    ref = np.array([rs.encounter_inputs(o, t) for o, t in zip(own, tgt)])
    np.testing.assert_allclose(dcog, ref[:, 0], atol=1e-12)
    np.testing.assert_allclose(rb, ref[:, 1], atol=1e-12)
    np.testing.assert_allclose(d, ref[:, 2], atol=1e-12)
    assert np.all((dcog >= 0) & (dcog <= math.pi)) and np.all((rb > -math.pi) & (rb <= math.pi))
    mu = np.asarray(fis_states(own, tgt, d_cl=60.0))
    np.testing.assert_allclose(mu, [rs.fis_mu_states(o, t, d_cl=60.0) for o, t in zip(own, tgt)], atol=1e-10)


def test_bearing_convention():
    """NED, clockwise positive: a target to the east of a north-going own-ship is on the starboard beam;
    dead astern is +180° (RB ∈ (−180°, 180°]); ΔCOG of opposite courses is 180°."""
    own = np.array([0.0, 0.0, 0.0, 1.0])
    tgts = np.array([[10.0, 0.0, math.pi, 1.0], [0.0, 10.0, 0.0, 1.0], [0.0, -10.0, 0.0, 1.0],
                     [-10.0, 0.0, -math.pi / 2, 1.0], [-10.0, -1e-300, 0.0, 1.0]])
    dcog, rb, d = (np.degrees(np.asarray(a)) for a in encounter(own, tgts))
    np.testing.assert_allclose(rb, [0.0, 90.0, -90.0, 180.0, 180.0], atol=1e-9)
    np.testing.assert_allclose(dcog, [180.0, 0.0, 0.0, 90.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(np.asarray(cf.wrap_to_pi(jnp.array([math.pi, -math.pi, 3 * math.pi, 0.5]))),
                               [math.pi, math.pi, math.pi, 0.5], atol=1e-12)


def test_vectorised_broadcasting():
    dcog = np.radians(np.array([[10.0], [90.0], [178.0]]))          # [3, 1]
    rb = np.radians(np.array([[-45.0, 10.0, 45.0, 120.0]]))          # [1, 4]
    mu = np.asarray(fis(dcog, rb, 20.0))
    assert mu.shape == (3, 4)
    for i in range(3):
        for j in range(4):
            assert abs(mu[i, j] - rs.fis_mu(dcog[i, 0], rb[0, j], 20.0)) < 1e-10


# ============================================================================ operators and memberships
def test_membership_shapes():
    m = cf.memberships(np.array([67.5, 157.5, 112.5]), np.array([0.0, 67.5, 30.0]), np.array([40.0, 45.0, 0.0]),
                       40.0, 5.0)
    np.testing.assert_allclose(np.asarray(m.CL), [0.5, 0.01, 1.0], atol=1e-12)     # C-000-5
    np.testing.assert_allclose(float(m.SB[0]), 0.5, atol=1e-12)
    np.testing.assert_allclose(float(m.OT[0]), 0.5, atol=1e-12)
    assert float(m.CR[2]) > 0.98 and float(m.HO[1]) == pytest.approx(0.5)       # bump ≈ 1 inside the range
    assert float(m.SBAH[2]) > 0.98 and float(m.SBAH[1]) == pytest.approx(0.5)
    # the printed slopes are 2 ln 99 / w: 1 % -> 99 % over w = 6°, 10°, 0.08
    for slope, w in ((-cf.OT_SLOPE, 6.0), (cf.SB_SLOPE, 10.0), (cf.MU_SLOPE, 0.08)):
        assert slope == pytest.approx(2 * math.log(99) / w, rel=1e-4)
    # the output membership functions' centroids by the FIS's own rectangle rule (201 points; spec: 0.9739 /
    # 0.0261, area 0.0525 each)
    y = np.linspace(0, 1, 201)
    t_y = np.asarray(cf.sig(y, cf.MU_TRUE_CENTRE, cf.MU_SLOPE))
    f_y = np.asarray(cf.sig(y, cf.MU_FALSE_CENTRE, -cf.MU_SLOPE))
    assert np.sum(y * t_y) / np.sum(t_y) == pytest.approx(0.9739, abs=1e-4)
    assert np.sum(y * f_y) / np.sum(f_y) == pytest.approx(0.0261, abs=1e-4)


def test_smooth_max_min():
    a = jnp.array([0.0, 0.3, 1.0, -2.0])
    b = jnp.array([0.0, 0.7, 0.2, -2.0])
    both = jax.jit(lambda a, b, e: (cf.smooth_max(a, b, e), cf.smooth_min(a, b, e)))
    for eps in (0.0, 1e-6, 1e-2):
        mx, mn = (np.asarray(v) for v in both(a, b, eps))
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        assert np.all(mx >= hi - 1e-15) and np.all(mx - hi <= math.sqrt(eps) / 2 + 1e-15)
        assert np.all(mn <= lo + 1e-15) and np.all(lo - mn <= math.sqrt(eps) / 2 + 1e-15)
    np.testing.assert_allclose(np.asarray(both(a, b, 0.0)[0]), np.maximum(a, b), atol=0)
    grad = jax.jit(jax.grad(lambda x, e: cf.smooth_max(x, 0.0, e)))
    assert np.isfinite(float(grad(0.0, 0.0)))                           # tie with ε = 0: finite
    assert float(grad(0.0, 1e-6)) == pytest.approx(0.5)


def test_coverage_hole_of_the_literal_rule_base():
    """C-000-4: a close target on the port side fires no rule of the literal rule base; with ε > 0 the CoG of
    the (≈ √ε/2 flat) aggregate is ≈ 0.5, the default-false completion gives the "false" output.  An
    aggregate that is exactly 0 (ε = 0, no rule at all) falls back to 0.5 with finite gradients."""
    port_close = (np.radians([90.0, 90.0]), np.radians([-90.0, -120.0]), np.array([5.0, 15.0]))
    np.testing.assert_allclose(np.asarray(fis(*port_close, completion="literal")), 0.5144, atol=2e-3)
    np.testing.assert_allclose(np.asarray(fis(*port_close)), SPEC_DEFAULT_FALSE[2], atol=1e-4)
    v, g = jax.jit(jax.value_and_grad(lambda r: cf.defuzzify(r, r, 0.0, 11)))(0.0)
    assert float(v) == 0.5 and np.isfinite(float(g))


# ============================================================================ gradients


@pytest.mark.parametrize("completion", cf.COMPLETIONS)
def test_gradient_wrt_positions_matches_central_differences(completion):
    """d μ / d (x_o, y_o, x_i, y_i) in float64, at random encounters in the transition zones (|RB| < 150°, so
    away from the RB jump dead astern)."""
    rng = np.random.default_rng(5)

    def mu_of(pos, chi_o, chi_t):
        dcog, rb, d = cf.encounter_inputs_xy(pos[0], pos[1], chi_o, pos[2], pos[3], chi_t)
        return cf.fis_colregs(dcog, rb, d, completion=completion, **FIS)

    grad = jax.jit(jax.grad(mu_of))
    value = jax.jit(mu_of)
    norms = []
    for _ in range(12):
        chi_o = rng.uniform(-math.pi, math.pi)
        rb = math.radians(rng.uniform(-150.0, 150.0))
        d = rng.uniform(36.0, 46.0)                           # inside CL's transition (d_cl = 40, e_cl = 5)
        chi_t = chi_o + math.radians(rng.choice([rng.uniform(60, 75), rng.uniform(150, 165), rng.uniform(5, 170)]))
        own = rng.uniform(-100, 100, 2)
        pos = np.r_[own, own + d * np.array([math.cos(chi_o + rb), math.sin(chi_o + rb)])]
        g = np.asarray(grad(pos, chi_o, chi_t))
        fd = central_difference(lambda p: float(value(p, chi_o, chi_t)), pos)
        np.testing.assert_allclose(g, fd, rtol=1e-5, atol=1e-8)
        norms.append(np.linalg.norm(g))
    assert max(norms) > 1e-2                                  # not vacuous: μ does move with the positions


def test_no_nan_at_degenerate_points():
    """d = 0, zero own speed, a target exactly astern, a target exactly ahead on a reciprocal course: finite
    values and gradients (positions, courses)."""
    def mu_of(state_pair):
        own, tgt = state_pair[:4], state_pair[4:]
        return cf.fis_colregs_states(own, tgt)

    cases = [
        [0.0, 0.0, 0.4, 1.0, 0.0, 0.0, 2.0, 1.0],                          # d = 0
        [0.0, 0.0, 0.4, 0.0, 10.0, 5.0, 2.0, 1.0],                         # own-ship stopped
        [0.0, 0.0, 0.0, 1.0, -20.0, 0.0, 0.0, 1.0],                        # exactly astern, same course
        [0.0, 0.0, 0.0, 1.0, 20.0, 0.0, math.pi, 1.0],                     # exactly ahead, head-on (ΔCOG = π)
        [5.0, 5.0, -math.pi, 0.0, 5.0, 5.0, math.pi, 0.0],                 # everything degenerate
    ]
    vg = jax.jit(jax.value_and_grad(mu_of))
    for c in cases:
        v, g = vg(jnp.asarray(c))
        assert np.isfinite(float(v)) and np.all(np.isfinite(np.asarray(g))), c
    # astern counts as starboard (RB = +180°): SB ≈ 1, far target, so μ is the "false" output
    assert float(vg(jnp.asarray(cases[2]))[0]) == pytest.approx(SPEC_DEFAULT_FALSE[-1], abs=1e-3)


# ============================================================================ validation
@pytest.mark.parametrize("kw, match", [
    (dict(eps=-1e-9), "eps"), (dict(n_y=1), "n_y"), (dict(n_y=20.0), "n_y"), (dict(d_cl=0.0), "d_cl"),
    (dict(e_cl=-1.0), "e_cl"), (dict(completion="strict"), "completion"), (dict(angles="grad"), "angles"),
    (dict(eps=float("nan")), "eps"), (dict(d_cl="40"), "d_cl"),
])
def test_bad_parameters_are_refused(kw, match):
    with pytest.raises(ValueError, match=match):
        cf.fis_colregs(0.5, 0.5, 10.0, **kw)


def test_bad_state_shapes_are_refused():
    with pytest.raises(ValueError, match=r"\[\.\.\., 4\]"):
        cf.encounter_inputs(np.zeros(3), np.zeros(4))
