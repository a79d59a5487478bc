"""The COLREGS option (``mpc.colregs_option``, docs/colregs_option.md): its settings validated like every other
field, off by default (the published terms unchanged), each term against the float64 NumPy oracle
(:mod:`psbmpc_jax.reference_colregs_option`) and against finite differences.  The evaluator wiring and the closed
loop: tests/test_colregs_option_sim.py."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from psbmpc_jax import reference_colregs_option as ref
from psbmpc_jax.costs import colregs_option as co
from psbmpc_jax.evaluate import DEFAULT_TERMS
from psbmpc_jax.methods.builtin import option_terms
from psbmpc_jax.methods.colregs_option_settings import ColregsOptionSpec, parse_colregs_option
from psbmpc_jax.scenario.load import scenario_from_dict

SPEC = ColregsOptionSpec(enabled=True)
THRESH = dict(engage=SPEC.engage_radii, act_cpa=SPEC.act_cpa_radii, act_range=SPEC.act_range_radii,
              clear=SPEC.clear_radii)
WEIGHTS = dict(chi_a=SPEC.chi_apparent, du_a=SPEC.du_apparent, K_stand_on=SPEC.K_stand_on, K_port=SPEC.K_port,
               K_apparent=SPEC.K_apparent, K_hold=SPEC.K_hold, K_early=SPEC.K_early)


# ------------------------------------------------------------------------------------------ settings
def base_scenario(**mpc_extra) -> dict:
    """A small crossing: the own-ship heads north, TS1 crosses from port (the own-ship stands on)."""
    return {"name": "cso_small", "simulation": {"dt_s": 0.5, "duration_s": 60},
            "monte_carlo": {"runs": 1, "seed": 0},
            "mpc": {"preset": "nidelva", "update_period_s": 5, **mpc_extra},
            "own_ship": {"name": "OS", "position_m": [0, 0], "course_deg": 0, "speed_mps": 2,
                         "waypoints_m": [[0, 0], [1000, 0]]},
            "targets": [{"name": "TS1", "position_m": [150, -150], "course_deg": 90, "speed_mps": 2,
                         "waypoints_m": [[150, -150], [150, 800]], "colav": "none"}]}


def test_off_by_default_and_the_published_terms_unchanged():
    sc = scenario_from_dict(base_scenario())
    assert sc.mpc.colregs_option == ColregsOptionSpec() and not sc.mpc.colregs_option.enabled
    assert option_terms(sc.mpc.colregs_option) == ()
    assert DEFAULT_TERMS + option_terms(sc.mpc.colregs_option) == DEFAULT_TERMS
    off = scenario_from_dict(base_scenario(colregs_option={"enabled": False, "act_range_radii": 5}))
    assert option_terms(off.mpc.colregs_option) == ()


def test_enabled_builds_the_four_terms_with_the_file_values():
    sc = scenario_from_dict(base_scenario(colregs_option={"enabled": True, "act_range_radii": 5.5, "early": False,
                                                          "chi_apparent_deg": 45}))
    terms = option_terms(sc.mpc.colregs_option)
    assert [t.name for t in terms] == ["stand_on", "apparent", "hold"]
    assert terms[0].act_range_radii == 5.5 and terms[1].chi_apparent == pytest.approx(math.radians(45))


@pytest.mark.parametrize("section, message", [
    ({"enabled": True, "act_range": 3}, "unknown key 'act_range' in mpc.colregs_option"),
    ({"enabled": "yes"}, "mpc.colregs_option.enabled must be true or false"),
    ({"enabled": True, "act_cpa_radii": 0}, "mpc.colregs_option.act_cpa_radii must be > 0"),
    ({"enabled": True, "K_hold": -1}, "mpc.colregs_option.K_hold must be >= 0"),
    ({"enabled": True, "chi_apparent_deg": 120}, "mpc.colregs_option.chi_apparent_deg must be <= 90"),
    ({"enabled": True, "du_apparent": float("nan")}, "mpc.colregs_option.du_apparent must be a finite number"),
    ({"enabled": True, "act_range_radii": 50}, "act_range_radii (50) must be below engage_radii (40)"),
    ({"enabled": True, "stand_on": False, "apparent": False, "hold": False, "early": False}, "every term off"),
    ([1, 2], "mpc.colregs_option must be a mapping"),
])
def test_bad_settings_are_refused_naming_the_field(section, message):
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        scenario_from_dict(base_scenario(colregs_option=section))


@pytest.mark.parametrize("method", ["psbmpc_refine", "smooth_sbmpc", "two_level"])
def test_methods_the_option_does_not_reach_are_refused(method):
    with pytest.raises(ValueError, match="mpc.colregs_option.enabled: the option extends the grid-search"):
        parse_colregs_option({"enabled": True}, method)
    parse_colregs_option({"enabled": False}, method)          # off: any method


# ------------------------------------------------------------------------------------------ oracle
def random_encounters(rng, n_obs):
    """Own-ship state and ``n_obs`` obstacles (x, y, vx, vy, radius, valid) around it, every sector and course."""
    p0 = rng.uniform(-100, 100, 2)
    chi0, u0 = rng.uniform(-math.pi, math.pi), rng.uniform(0.5, 5.0)
    rad = rng.uniform(10.0, 30.0, n_obs)
    r = rad * rng.uniform(0.5, 50.0, n_obs)
    b = rng.uniform(-math.pi, math.pi, n_obs)
    c, s = rng.uniform(-math.pi, math.pi, n_obs), rng.uniform(0.0, 6.0, n_obs)
    obs = np.column_stack([p0[0] + r * np.cos(b), p0[1] + r * np.sin(b), s * np.cos(c), s * np.sin(c), rad,
                           rng.uniform(size=n_obs) < 0.9])
    return p0, chi0, u0, obs


@jax.jit
def _flags(p0, chi0, u0, o):
    return co.encounter((p0[0], p0[1]), chi0, u0, (o[:, 0], o[:, 1]), (o[:, 2], o[:, 3]), o[:, 4], o[:, 5] > 0.5,
                        **THRESH)


def jax_flags(p0, chi0, u0, obs):
    e = _flags(jnp.asarray(p0), jnp.asarray(chi0), jnp.asarray(u0), jnp.asarray(obs))
    return {k: np.asarray(v) for k, v in e.items()}


def test_encounter_flags_equal_the_oracle_over_random_geometries():
    rng = np.random.default_rng(0)
    seen = {k: 0 for k in ("engaged", "stand_on", "stand_on_hold", "port_act", "give_way")}
    for _ in range(150):
        p0, chi0, u0, obs = random_encounters(rng, 6)
        want = ref.encounter(p0, chi0, u0, [tuple(o) for o in obs], **THRESH)
        got = jax_flags(p0, chi0, u0, obs)
        for k in seen:
            np.testing.assert_array_equal(got[k], [w[k] for w in want], err_msg=k)
            seen[k] += int(got[k].sum())
    assert all(v > 5 for v in seen.values()), seen            # every flag exercised


def test_encounter_classifies_the_textbook_cases():
    """R = 10 m: a port crossing at 100 m on a collision course (stand on), the same at 30 m (may act, not to
    port), a starboard crossing (give way), a head-on (give way), an overtaking target from astern (stand on)."""
    def flags(x, y, course_deg, speed):
        c = math.radians(course_deg)
        return ref.encounter((0.0, 0.0), 0.0, 2.0, [(x, y, speed * math.cos(c), speed * math.sin(c), 10.0, True)],
                             **THRESH)[0]
    far = flags(100.0, -100.0, 90.0, 2.0)
    assert far["stand_on_hold"] and not far["port_act"] and not far["give_way"]
    near = flags(20.0, -20.0, 90.0, 2.0)
    assert near["port_act"] and not near["stand_on_hold"]
    assert flags(100.0, 100.0, -90.0, 2.0)["give_way"]
    assert flags(300.0, 0.0, 180.0, 2.0)["give_way"]
    assert flags(-60.0, 0.0, 0.0, 3.0)["stand_on_hold"]
    close_astern = flags(-20.0, 0.0, 0.0, 3.0)      # overtaken, a risk within 4 R: may act, to either side
    assert not close_astern["stand_on_hold"] and not close_astern["port_act"]
    gone = flags(-100.0, 0.0, 180.0, 2.0)        # astern and opening beyond 3 R: past and clear
    assert not any(gone.values())


def offsets_table(rng, n_b, n_m):
    u = rng.choice([0.0, 0.25, 0.5, 0.8, 1.0], size=(n_b, n_m))
    chi = np.radians(rng.choice([-90, -45, -30, -20, -15, -5, 0, 5, 10, 15, 29, 30, 45, 60], size=(n_b, n_m)))
    return np.stack([u, chi + rng.normal(0, 0.02, chi.shape)], axis=-1)


@pytest.mark.parametrize("n_m", [1, 2, 3])
def test_costs_equal_the_oracle(n_m):
    rng = np.random.default_rng(n_m)
    for trial in range(15):
        p0, chi0, u0, obs = random_encounters(rng, 3)
        want_flags = ref.encounter(p0, chi0, u0, [tuple(o) for o in obs], **THRESH)
        offsets = offsets_table(rng, 64, n_m)
        last = np.array([rng.choice([0.5, 1.0]), math.radians(rng.choice([-30, 0, 15, 45]))])
        want = ref.option_costs(offsets, last, want_flags, **WEIGHTS)
        f = jax_flags(p0, chi0, u0, obs)
        hold, port = bool(f["stand_on_hold"].any()), bool(f["port_act"].any())
        engaged, gw = bool(f["engaged"].any()), bool(f["give_way"].any())
        off, lst = jnp.asarray(offsets), jnp.asarray(last)
        a = SPEC.chi_apparent
        got = {"stand_on": co.stand_on_cost(off, lst, hold, port, chi_a=a, du_a=SPEC.du_apparent,
                                            K_stand_on=SPEC.K_stand_on, K_port=SPEC.K_port),
               "apparent": co.apparent_cost(off, lst, engaged, chi_a=a, du_a=SPEC.du_apparent,
                                            K_apparent=SPEC.K_apparent),
               "hold": co.hold_cost(off, lst, engaged, chi_a=a, K_hold=SPEC.K_hold),
               "early": co.early_cost(off, gw, chi_a=a, K_early=SPEC.K_early)}
        for k in want:
            np.testing.assert_allclose(np.asarray(got[k]), want[k], rtol=1e-12, atol=1e-9, err_msg=f"{k} {trial}")


def test_costs_are_positive_where_the_rules_say():
    """Hand values, R-free: χ_a 30°, u_a 0.5."""
    a = math.radians(30)
    off = jnp.asarray([[[1.0, math.radians(15)]], [[1.0, math.radians(30)]], [[0.75, 0.0]], [[1.0, -a]]])
    last = jnp.asarray([1.0, 0.0])
    app = np.asarray(co.apparent_cost(off, last, True, chi_a=a, du_a=0.5, K_apparent=1.0))
    # 15°: offset and change at half the threshold (1 + 1); 30°: readily apparent (0); u 0.75: 1; -30°: 0
    np.testing.assert_allclose(app, [2.0, 0.0, 1.0, 0.0], atol=1e-12)
    so = np.asarray(co.stand_on_cost(off, last, True, False, chi_a=a, du_a=0.5, K_stand_on=1.0, K_port=0.0))
    np.testing.assert_allclose(so, [0.25, 1.0, 0.25, 1.0], atol=1e-12)
    port = np.asarray(co.stand_on_cost(off, last, False, True, chi_a=a, du_a=0.5, K_stand_on=0.0, K_port=1.0))
    np.testing.assert_allclose(port, [0.0, 0.0, 0.0, 1.0], atol=1e-12)
    back = np.asarray(co.hold_cost(off, jnp.asarray([1.0, 2 * a]), True, chi_a=a, K_hold=1.0))
    np.testing.assert_allclose(back, [(1.5) ** 2, 1.0, 4.0, 9.0], atol=1e-12)
    early = np.asarray(co.early_cost(off, True, chi_a=a, K_early=1.0))
    np.testing.assert_allclose(early, [0.5, 0.0, 1.0, 0.0], atol=1e-12)
    for fn in (app, so, back, early):
        assert np.all(fn >= 0)


# ------------------------------------------------------------------------------------------ gradients
@pytest.mark.parametrize("name", ["stand_on", "apparent", "hold", "early"])
def test_gradients_equal_finite_differences(name):
    a = SPEC.chi_apparent
    fns = {"stand_on": lambda o, l: co.stand_on_cost(o, l, True, True, chi_a=a, du_a=0.5, K_stand_on=3.0,
                                                     K_port=5.0),
           "apparent": lambda o, l: co.apparent_cost(o, l, True, chi_a=a, du_a=0.5, K_apparent=2.0),
           "hold": lambda o, l: co.hold_cost(o, l, True, chi_a=a, K_hold=4.0),
           "early": lambda o, l: co.early_cost(o, True, chi_a=a, K_early=2.0)}
    fn = fns[name]
    rng = np.random.default_rng(7)
    last = jnp.asarray([0.9, math.radians(20)])
    for _ in range(10):
        # away from the kinks (χ = 0, |χ| = χ_a, |Δχ| = χ_a, χ = χ_last, 1 - u = u_a)
        chi = rng.choice([-1, 1], size=(1, 3)) * rng.uniform(math.radians(3), math.radians(80), (1, 3))
        u = rng.uniform(0.05, 0.95, (1, 3))
        x = np.stack([u, chi], axis=-1)
        g = np.asarray(jax.grad(lambda o: fn(o, last)[0])(jnp.asarray(x)))
        h = 1e-6
        for idx in np.ndindex(x.shape):
            xp, xm = x.copy(), x.copy()
            xp[idx] += h
            xm[idx] -= h
            fd = (float(fn(jnp.asarray(xp), last)[0]) - float(fn(jnp.asarray(xm), last)[0])) / (2 * h)
            assert g[idx] == pytest.approx(fd, rel=1e-5, abs=1e-6), (name, idx)
        assert np.all(np.isfinite(g))


def test_controllers_get_the_terms_only_when_enabled():
    from psbmpc_jax.methods.base import BuildContext
    from psbmpc_jax.methods.registry import REGISTRY, build_controllers

    sc = scenario_from_dict(base_scenario())
    ctx = BuildContext(params=sc.mpc.params)
    off = build_controllers(sc, ctx).controllers[0]
    assert off.terms == DEFAULT_TERMS and "colregs_option" not in REGISTRY["psbmpc"].record(sc)
    on_sc = scenario_from_dict(base_scenario(colregs_option={"enabled": True}))
    on = build_controllers(on_sc, ctx).controllers[0]
    # the path term weighted off while engaged (hold_path, default on): tests/test_colregs_hold.py
    assert on.terms[:3] == DEFAULT_TERMS[:3] and isinstance(on.terms[3], co.HeldPathTerm)
    assert [t.name for t in on.terms[4:]] == ["stand_on", "apparent", "hold", "early"]
    assert REGISTRY["psbmpc"].record(on_sc)["colregs_option"]["enabled"] is True
    # every method the option extends records it when on, and only then
    for name in ("psbmpc", "sbmpc", "psbmpc_2020", "informed_sbmpc"):
        assert REGISTRY[name].record(on_sc)["colregs_option"] == REGISTRY["psbmpc"].record(on_sc)["colregs_option"]
        assert "colregs_option" not in REGISTRY[name].record(sc), name
    # a method the option does not reach is refused when built too (e.g. after the file was parsed for psbmpc)
    with pytest.raises(ValueError, match="method psbmpc_refine does not take it"):
        REGISTRY["psbmpc_refine"].build(on_sc, (0,), ctx)


def test_term_defaults_are_the_settings_defaults():
    """The term classes repeat the settings' defaults (the cost module may not import the method protocol's
    settings: tests/test_layers.py); a term built on its own must weigh what the default file section weighs."""
    import dataclasses

    spec = ColregsOptionSpec()
    for cls in co.TERM_CLASSES.values():
        for f in dataclasses.fields(cls):
            want = spec.chi_apparent if f.name == "chi_apparent" else getattr(spec, f.name)
            assert f.default == want, (cls.__name__, f.name)
