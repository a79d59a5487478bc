"""The SB-MPC family as methods (psbmpc_jax/methods.py) and a planner per ship in the simulator
(psbmpc_jax/methods/): the SB-MPC grid search against its float64 reference, the ``mpc.sbmpc`` and per-ship
``colav`` keys (good and bad), the registry, a mixed-method closed loop in which every ship runs its own method,
the random traffic generator and the seed-004 scenario files."""

from __future__ import annotations

import copy
import dataclasses
import importlib.util
import pathlib
import subprocess
import sys

import jax.numpy as jnp
import numpy as np
import pytest

from psbmpc_jax import reference as ref_mod
from psbmpc_jax.behaviours import enumerate_behaviours_deg
from psbmpc_jax.evaluate import evaluate
from psbmpc_jax.methods.sbmpc_family import SBMPC_PRESETS, SbmpcSettings, sbmpc_settings, sbmpc_terms
from psbmpc_jax.packing import pack
from psbmpc_jax.params import Params, PlannerConfig
from psbmpc_jax.scenario import METHODS, load_scenario, scenario_from_dict
from psbmpc_jax.sim import simulate
from psbmpc_jax.methods.base import BuildContext
from psbmpc_jax.methods.registry import REGISTRY, build_controllers
from psbmpc_jax.situation import Obstacle, OwnShip, Situation
from psbmpc_jax.traffic import random_targets

REPO = pathlib.Path(__file__).resolve().parents[1]
HAVE_MCSKF = importlib.util.find_spec("psbmpc_jax.costs.mcskf") is not None
SEARCH = enumerate_behaviours_deg(((1.0, 0.5, 0.0),), (tuple(range(-90, 91, 15)),))     # seed 004's 39


# ============================================================================= SB-MPC grid = float64 reference
def _situation(seed: int) -> Situation:
    """Own-ship north at 9 m/s, five straight-line targets around it (some inside d_safe within the horizon)."""
    rng = np.random.default_rng(seed)
    own = OwnShip(state=[0.0, 0.0, 0.0, 9.0], waypoints=np.array([[0.0, 0.0], [3000.0, 0.0]]), U_d=9.0, length=30.0,
                  width=6.0)
    obs = []
    for _ in range(5):
        pos = rng.uniform([150.0, -300.0], [900.0, 300.0])
        course, speed = rng.uniform(0, 2 * np.pi), rng.uniform(0.0, 9.0)
        obs.append(Obstacle([pos[0], pos[1], speed * np.cos(course), speed * np.sin(course)],
                            np.diag([25.0, 25.0, 4.0, 4.0]), length=30.0, width=6.0, n_ps=1))
    obs.append(Obstacle([400.0, 0.0, -5.0, 0.0], np.diag([25.0, 25.0, 4.0, 4.0]), n_ps=1))      # head-on
    return Situation(own, tuple(obs))


@pytest.mark.parametrize("seed", [0])
def test_sbmpc_grid_search_matches_its_float64_reference(seed):
    """The 39-behaviour SB-MPC search (joint max over obstacles and k >= 1 of K_coll|dv|^2 R + kappa mu, plus
    Gamma of seed 004 with the new-offset side rule) through the jitted evaluator equals the terms' float64
    reference, behaviour by behaviour, and the chosen behaviour is the reference's argmin."""
    cfg = PlannerConfig(T=100.0, dt=0.5, dtype="float64")
    sit = _situation(seed)
    terms = sbmpc_terms(SbmpcSettings(), with_grounding=False)
    last = (0.5, 0.2618)
    ev = evaluate(pack(sit, SEARCH, cfg), jnp.asarray(last), Params(), None, config=cfg, terms=terms)
    ref = ref_mod.evaluate_reference(sit, SEARCH, Params(), cfg, last_offsets=last, extra_terms=terms)
    total = np.zeros(len(SEARCH))
    for term in terms:
        got = np.asarray(ev.costs[term.name])[: len(SEARCH)]
        np.testing.assert_allclose(got, ref.extra[term.name], rtol=1e-9, atol=1e-9, err_msg=term.name)
        assert np.ptp(got) > 0, term.name                                     # rows differ: not vacuous
        total += np.asarray(ref.extra[term.name])
    assert int(ev.best) == int(np.argmin(total))
    hazard = np.asarray(ev.costs["sbmpc"])[: len(SEARCH)]
    assert np.any(hazard > 0)                                                 # some behaviour enters d_safe


def test_sbmpc_terms_are_the_original_forms():
    hazard, gamma, *rest = sbmpc_terms(sbmpc_settings(kappa=3.0, d_safe=25.0))
    assert (hazard.aggregation, hazard.risk, hazard.colregs) == ("max", "crisp", "boolean")
    assert (hazard.kappa, hazard.d_safe, hazard.d_cl) == (3.0, 25.0, 200.0) and not hazard.smooth
    assert (gamma.form, gamma.side, gamma.k_U, gamma.Delta_U) == ("johansen", "offset", 9.0, 8.0)
    assert [t.name for t in rest] == ["so"]
    assert [t.name for t in sbmpc_terms(SbmpcSettings(grounding=False))] == ["sbmpc", "manoeuvring"]


@pytest.mark.parametrize("kw, match", [
    (dict(d_safe=0.0), r"SbmpcSettings.d_safe must be > 0"),
    (dict(kappa=-1.0), r"SbmpcSettings.kappa must be >= 0"),
    (dict(T_c=float("nan")), r"SbmpcSettings.T_c must be finite \(no NaN/inf\)"),
    (dict(n_mc=0), r"SbmpcSettings.n_mc must be an integer >= 1, got 0"),
    (dict(n_mc=2_000_000), r"SbmpcSettings.n_mc must be an integer <= 1000000"),
    (dict(n_mc=2.5), r"SbmpcSettings.n_mc must be an integer"),
    (dict(grounding="yes"), r"SbmpcSettings.grounding must be true or false"),
])
def test_settings_validation(kw, match):
    with pytest.raises(ValueError, match=match):
        SbmpcSettings(**kw)


def test_settings_presets_and_unknown_names():
    assert sbmpc_settings() == SBMPC_PRESETS["tengesdal2020"] == SbmpcSettings()
    assert sbmpc_settings("river").d_safe == 10.0
    with pytest.raises(ValueError, match=r"sbmpc preset must be one of tengesdal2020, river, got 'x'"):
        sbmpc_settings("x")
    with pytest.raises(ValueError, match=r"unknown SB-MPC setting\(s\) \['dsafe'\]"):
        sbmpc_settings(dsafe=3.0)


# ============================================================================= scenario keys
BASE = {
    "name": "mixed",
    "description": "open water, three ships crossing, each with its own method",
    "simulation": {"dt_s": 0.5, "duration_s": 10},
    "monte_carlo": {"runs": 2, "seed": 1},
    "mpc": {"preset": "tengesdal2020", "update_period_s": 5, "config": {"T": 40},
            "sbmpc": {"d_safe_m": 40, "n_mc": 16, "seed": 3}},
    "sensor": {"position_std_m": 5, "period_s": 2.5, "filter_R_scale": 25, "sigma_a_mps2": 0.5, "U_max_mps": 9},
    "own_ship": {"name": "OS", "position_m": [0, 0], "course_deg": 0, "speed_mps": 9, "length_m": 30, "width_m": 6},
    "targets": [
        {"name": "A", "position_m": [400, 0], "course_deg": 180, "speed_mps": 5, "colav": "sbmpc", "length_m": 30,
         "width_m": 6},
        {"name": "B", "position_m": [300, 250], "course_deg": 270, "speed_mps": 6, "colav": "psbmpc_2020",
         "length_m": 30, "width_m": 6},
        {"name": "C", "position_m": [300, -250], "course_deg": 90, "speed_mps": 6, "colav": "sbmpc", "length_m": 30,
         "width_m": 6},
    ],
}


def mixed(**changes) -> dict:
    d = copy.deepcopy(BASE)
    for path, value in changes.items():
        *head, last = path.split("__")
        node = d
        for k in head:
            node = node[int(k)] if k.isdigit() else node[k]
        node[last] = value
    return d


def test_per_ship_methods_parse():
    sc = scenario_from_dict(mixed())
    assert [s.colav for s in sc.ships] == ["psbmpc", "sbmpc", "psbmpc_2020", "sbmpc"]
    assert (sc.mpc.sbmpc.d_safe, sc.mpc.sbmpc.n_mc, sc.mpc.sbmpc.seed, sc.mpc.sbmpc.kappa) == (40.0, 16, 3, 10.0)
    # the own-ship's method is mpc.method: no key, 'psbmpc' (on) or the same name
    sc = scenario_from_dict(mixed(mpc__method="sbmpc"))
    assert sc.own_ship.colav == "sbmpc"
    sc = scenario_from_dict(mixed(mpc__method="sbmpc", own_ship__colav="sbmpc"))
    assert sc.own_ship.colav == "sbmpc"
    sc = scenario_from_dict(mixed(mpc__method="psbmpc_2020", own_ship__colav="psbmpc"))
    assert sc.own_ship.colav == "psbmpc_2020"
    assert scenario_from_dict(mixed(), method="sbmpc").own_ship.colav == "sbmpc"      # run --method


@pytest.mark.parametrize("change, match", [
    (dict(own_ship__colav="sbmpc"), r"own_ship.colav: the own-ship runs mpc.method \(psbmpc\), got colav 'sbmpc'; "
                                    r"set mpc.method: sbmpc"),
    (dict(targets__1__colav="smooth_sbmpc"), r"targets\[1\].colav: smooth_sbmpc plans the own-ship only"),
    (dict(targets__0__colav="sb-mpc"), r"targets\[0\].colav must be 'none', a known method \(psbmpc, .*got 'sb-mpc'"),
    (dict(targets__0__colav=3), r"targets\[0\].colav must be 'none', a known method .*got 3"),
    (dict(targets__0__speed_mps=0), r"targets\[0\]: a ship with colav sbmpc needs a nominal speed > 0"),
    (dict(mpc__sbmpc={"preset": "tengesdal"}), r"mpc.sbmpc.preset must be one of tengesdal2020, river, got "
                                               r"'tengesdal'"),
    (dict(mpc__sbmpc={"dsafe_m": 3}), r"unknown key 'dsafe_m' in mpc.sbmpc"),
    (dict(mpc__sbmpc={"d_safe_m": 0}), r"mpc.sbmpc.d_safe_m must be > 0"),
    (dict(mpc__sbmpc={"kappa": -2}), r"mpc.sbmpc.kappa must be >= 0"),
    (dict(mpc__sbmpc={"n_mc": 0}), r"mpc.sbmpc.n_mc must be an integer >= 1"),
    (dict(mpc__sbmpc={"n_mc": 2_000_000}), r"mpc.sbmpc.n_mc must be an integer <= 1000000"),
    (dict(mpc__sbmpc={"grounding": "no"}), r"mpc.sbmpc.grounding must be true or false"),
    (dict(mpc__method="sbmpc2020"), r"mpc.method must be a known method \(psbmpc, .*psbmpc_2020, .*two_level\) or "
                                    r"an import path 'package.module:Name' .*got 'sbmpc2020'"),
])
def test_bad_methods_and_settings_name_the_ship_or_key(change, match):
    with pytest.raises(ValueError, match=match):
        scenario_from_dict(mixed(**change))


# ============================================================================= registry and closed loop
def test_registry_covers_every_method_and_groups_by_method():
    assert set(REGISTRY) == set(METHODS)
    assert {n for n, m in REGISTRY.items() if m.own_ship_only} == {"smooth_sbmpc", "sbmpc_init", "two_level"}
    sc = scenario_from_dict(mixed())
    c = build_controllers(sc)
    by = {g.method: g.ships for g in c.controllers}
    assert by == {"psbmpc": (0,), "sbmpc": (1, 3), "psbmpc_2020": (2,)}
    assert c.methods == ("psbmpc", "sbmpc", "psbmpc_2020", "sbmpc") and c.snapshots and c.uses_grid
    g = {g.method: g for g in c.controllers}
    assert g["sbmpc"].n_ps == 1 and g["psbmpc_2020"].n_ps == 1 and g["psbmpc"].n_ps is None
    assert [t.name for t in g["sbmpc"].terms] == ["sbmpc", "manoeuvring"]            # open water: no grounding
    with pytest.raises(ValueError, match=r"ship 'A' colav must be 'none', a known method \(psbmpc, .*got 'foo'"):
        build_controllers(sc, methods=("psbmpc", "foo", "none", "none"))
    with pytest.raises(ValueError, match=r"ship\(s\) \['A'\]: method smooth_sbmpc plans the own-ship only"):
        build_controllers(sc, methods=("none", "smooth_sbmpc", "none", "none"))


@pytest.mark.skipif(not HAVE_MCSKF, reason="psbmpc_jax.costs.mcskf missing")
@pytest.mark.parametrize("mode", ["vmap"])
def test_mixed_method_closed_loop_runs_each_ships_own_method(mode):
    sc = scenario_from_dict(mixed())
    res = simulate(sc, runs=2, batch=mode)
    # 2 updates (t = 0, 5 s); every ship decided at each of them, with its own method's cost columns
    assert np.all(np.isfinite(res.offsets))
    tot = res.best_costs[..., 0]
    assert np.all(np.isfinite(tot))
    assert np.all(np.isfinite(res.best_costs[:, 0, :, 1:]))                 # PSB-MPC: every default column
    assert np.all(np.isnan(res.best_costs[:, 1:, :, 1:]))                   # the SB-MPC family: only the total
    # one device call per method and update under vmap, one per solve in the loop
    per_update = [c["device_calls"] for c in res.calls]
    assert per_update == ([3, 3] if mode == "vmap" else [8, 8])
    # the same ship planned by another method decides differently somewhere (the method really is per ship)
    other = scenario_from_dict(mixed(targets__0__colav="psbmpc", targets__2__colav="psbmpc"))
    res2 = simulate(other, runs=2, batch=mode)
    assert not np.allclose(res.best_costs[:, 1], res2.best_costs[:, 1], equal_nan=True)


def test_sbmpc_only_scenario_on_a_chart_adds_grounding_and_batches():
    d = mixed(mpc__method="sbmpc")
    d["targets"] = d["targets"][:1]
    d["chart"] = {"polygons_m": [[[150, 60], [250, 60], [250, 120], [150, 120]]]}
    sc = scenario_from_dict(d, land_checks="warn")
    (g,) = build_controllers(sc, BuildContext(mode="vmap")).controllers
    assert g.ships == (0, 1) and [t.name for t in g.terms] == ["sbmpc", "manoeuvring", "so"]
    res = simulate(sc, runs=2)
    assert np.all(np.isfinite(res.offsets)) and not res.metrics[0]["grounding"]


# ============================================================================= traffic and scenario files
def test_random_targets_are_seeded_separated_and_in_range():
    a = random_targets(13, seed=5)
    assert a == random_targets(13, seed=5) and a != random_targets(13, seed=6)
    pos = np.array([t["position_m"] for t in a])
    assert np.all((pos[:, 0] >= 0) & (pos[:, 0] <= 1000) & (np.abs(pos[:, 1]) <= 400))
    d = np.hypot(*(pos[:, None] - pos[None]).transpose(2, 0, 1)) + np.eye(13) * 1e9
    assert d.min() >= 80 and np.hypot(*pos.T).min() >= 80
    speeds = [t["speed_mps"] for t in a]
    assert min(speeds) >= 2 and max(speeds) <= 9 and all(0 <= t["course_deg"] < 360 for t in a)
    assert {t["colav"] for t in a} == {"none"} and [t["name"] for t in a][:2] == ["TS1", "TS2"]


@pytest.mark.parametrize("kw, match", [
    (dict(n=-1), r"n must be an integer in \[0, 1000\]"),
    (dict(seed=-3), r"seed must be an integer >= 0"),
    (dict(north_range_m=(5, 1)), r"north_range_m must be finite with"),
    (dict(speed_range_mps=(-1, 2)), r"speed_range_mps must be finite with 0 <= low"),
    (dict(min_separation_m=-1.0), r"min_separation_m must be a finite number >= 0"),
    (dict(n=50, north_range_m=(0, 100), east_range_m=(0, 100)), r"cannot place target \d+ of 50"),
])
def test_random_targets_bad_input(kw, match):
    args = dict(n=3, seed=0) | kw
    with pytest.raises(ValueError, match=match):
        random_targets(args.pop("n"), **args)


def test_seed_004_scenarios_load_and_b_is_the_generators_output():
    a, b = load_scenario("tengesdal2020_a"), load_scenario("tengesdal2020_b")
    for sc in (a, b):
        assert sc.mpc.method == "psbmpc_2020" and sc.mpc.sbmpc == SbmpcSettings() and sc.dt == 0.1
        assert (sc.mpc.config.T, sc.mpc.config.dt, len(sc.mpc.behaviours)) == (200.0, 0.5, 39)
        assert (sc.sensor.position_std, sc.sensor.period, sc.sensor.filter_R_scale, sc.sensor.U_max) == (5, 2.5, 25, 9)
    assert len(a.targets) == 1 and len(b.targets) == 13
    gen = subprocess.run([sys.executable, str(REPO / "tools" / "make_tengesdal2020_b.py"), "--check"],
                         capture_output=True, text=True)
    assert gen.returncode == 0, gen.stderr
    assert load_scenario("tengesdal2020_a", method="sbmpc").own_ship.colav == "sbmpc"
    assert dataclasses.replace(a.mpc.sbmpc, d_safe=40.0) == a.mpc.sbmpc


# ============================================================================= the COLREGS-transitional term
def _crossing_situation() -> Situation:
    """Own-ship north at 9 m/s; a target crossing from starboard (heading west) that the straight own-ship
    passes ahead of, one overtaken target and one stationary object (no transitional situation)."""
    own = OwnShip(state=[0.0, 0.0, 0.0, 9.0], waypoints=np.array([[0.0, 0.0], [3000.0, 0.0]]), U_d=9.0, length=30.0,
                  width=6.0)
    cov = np.diag([25.0, 25.0, 4.0, 4.0])
    return Situation(own, (Obstacle([250.0, 160.0, 0.0, -6.0], cov, n_ps=1),       # crossing from starboard
                           Obstacle([-120.0, 15.0, 11.0, 0.0], cov, n_ps=1),       # overtaking us from astern
                           Obstacle([500.0, -60.0, 0.0, 0.0], cov, n_ps=1)))       # not moving


@pytest.mark.parametrize("last", [(1.0, 0.0), (0.5, 0.7854)])
def test_transitional_term_matches_its_reference_and_changes_the_ranking(last):
    """λT (Johansen 2016 eq. 11, Hagen 2018 reading): the evaluator's SB-MPC hazard with the transitional term
    equals the float64 reference (which rolls out the applied offsets itself) behaviour by behaviour; it adds
    exactly λ to some behaviours (those that flip the passing side of a crossing / overtaking target) and
    nothing to the applied behaviour itself."""
    cfg = PlannerConfig(T=60.0, dt=0.5, dtype="float64")
    sit = _crossing_situation()
    on = sbmpc_terms(SbmpcSettings(lambda_T=7.0, d_cl=400.0), with_grounding=False)
    off = sbmpc_terms(SbmpcSettings(d_cl=400.0), with_grounding=False)
    assert on[0].transitional and on[0].needs_applied and not off[0].transitional
    ev_on = evaluate(pack(sit, SEARCH, cfg), jnp.asarray(last), Params(), None, config=cfg, terms=on)
    ev_off = evaluate(pack(sit, SEARCH, cfg), jnp.asarray(last), Params(), None, config=cfg, terms=off)
    ref = ref_mod.evaluate_reference(sit, SEARCH, Params(), cfg, last_offsets=last, extra_terms=on[:1])
    got = np.asarray(ev_on.costs["sbmpc"])[: len(SEARCH)]
    np.testing.assert_allclose(got, ref.extra["sbmpc"], rtol=1e-9, atol=1e-9)
    base = np.asarray(ev_off.costs["sbmpc"])[: len(SEARCH)]
    added = got - base
    assert np.all(added >= -1e-9) and np.all(added <= 7.0 + 1e-9)
    assert np.any(added > 1.0)                                                # some behaviours flip a side
    same = np.flatnonzero(np.all(np.isclose(SEARCH[:, 0], np.asarray(last), atol=1e-3), axis=1))
    if same.size:                                                             # the applied behaviour: no flip
        assert added[same[0]] == pytest.approx(0.0, abs=1e-9)


def test_transitional_situations_by_hand():
    from psbmpc_jax.costs import sbmpc as sb

    def sit(own, tgt, d_cl=500.0):
        return bool(sb.transitional_situation(*(jnp.asarray(v) for v in own + tgt), d_cl))

    own = (0.0, 0.0, 0.0, 5.0)
    assert sit(own, (200.0, 150.0, -np.pi / 2, 5.0))                          # crossing from starboard
    assert not sit(own, (400.0, 0.0, np.pi, 5.0))                             # head-on: not transitional
    assert sit(own, (-100.0, 10.0, 0.0, 8.0))                                 # overtaken
    assert sit(own, (100.0, 10.0, 0.0, 2.0))                                  # overtaking (target ahead)
    assert not sit(own, (-100.0, 10.0, 0.0, 2.0))                             # slower target astern: neither
    assert not sit(own, (200.0, 150.0, -np.pi / 2, 5.0), d_cl=100.0)          # not close
    assert not sit(own, (200.0, 150.0, -np.pi / 2, 0.0))                      # not moving
    side = sb.passing_side(jnp.zeros((3, 1)), jnp.asarray([[0.0], [5.0], [10.0]]), jnp.zeros((3, 1)),
                           jnp.asarray([[50.0], [20.0], [30.0]]), jnp.asarray([[3.0], [-4.0], [1.0]]))
    assert float(side[0]) == -1.0                                             # closest at step 1: to port


def test_transitional_term_needs_the_applied_rollout_and_is_a_setting():
    from psbmpc_jax.costs import sbmpc as sb

    with pytest.raises(ValueError, match=r"lambda_T must be finite and in \[0, inf\)"):
        sb.SbmpcHazardTerm(lambda_T=-1.0, transitional=True)
    with pytest.raises(ValueError, match=r"transitional must be True or False"):
        sb.SbmpcHazardTerm(transitional="yes")
    ctx = sb.Context(t=None, offsets=None, last_offsets=None, own=None, obstacles=None, obs_cov=None, cov_stats=None,
                     scen_valid=None, radius=None, zeta_k=None, scen_weight=None, world=None, dense=False)
    with pytest.raises(ValueError, match=r"needs Context.own_applied"):
        sb.transitional_indicator(ctx)
    sc = scenario_from_dict(mixed(mpc__sbmpc={"lambda_T": 4}))
    assert sc.mpc.sbmpc.lambda_T == 4.0
    hazard = sbmpc_terms(sc.mpc.sbmpc)[0]
    assert hazard.transitional and hazard.lambda_T == 4.0 and not hazard.smooth
    with pytest.raises(ValueError, match=r"mpc.sbmpc.lambda_T must be >= 0"):
        scenario_from_dict(mixed(mpc__sbmpc={"lambda_T": -1}))
