"""The COLREGS option per ship (docs/colregs_option.md, "Per ship"): a ship's own ``colregs_option`` section
switches the option on or off for that ship alone and overrides the scenario's ``mpc.colregs_option``; the terms
are built only for the ships that have it; every ship's resolved option is recorded; bad values are refused
naming the ship's field."""

from __future__ import annotations

import math

import numpy as np
import pytest

from psbmpc_jax.costs.colregs_option import HeldPathTerm
from psbmpc_jax.evaluate import DEFAULT_TERMS
from psbmpc_jax.methods.base import BuildContext
from psbmpc_jax.methods.colregs_option_settings import ColregsOptionSpec, ship_option
from psbmpc_jax.methods.grid import GridController, GroupedController
from psbmpc_jax.methods.registry import build_controllers
from psbmpc_jax.scenario.load import scenario_from_dict
from psbmpc_jax.sim.output import scenario_info
from psbmpc_jax.sim.simulator import simulate

OPTION_NAMES = ["stand_on", "apparent", "hold", "early"]


def crossing(mpc_option=None, own=None, target=None, target_colav="psbmpc", duration=110.0) -> dict:
    """The own-ship heads north at 2 m/s; TS1 crosses from its port side on a collision course (both at
    (150, 0) after 75 s): the own-ship stands on, TS1 (when it runs a method) gives way."""
    d = {"name": "cso_per_ship", "simulation": {"dt_s": 0.5, "duration_s": duration},
         "monte_carlo": {"runs": 1, "seed": 0},
         "mpc": {"preset": "nidelva", "update_period_s": 5, "n_ps": 1, "config": {"T": 60.0, "dt": 1.0},
                 "speed_factors": [[1.0, 0.5, 0.0]], "course_offsets_deg": [[-60, -30, -15, 0, 15, 30, 60]]},
         "own_ship": {"name": "OS", "position_m": [0, 0], "course_deg": 0, "speed_mps": 2,
                      "waypoints_m": [[0, 0], [1000, 0]]},
         "targets": [{"name": "TS1", "position_m": [150, -150], "course_deg": 90, "speed_mps": 2,
                      "waypoints_m": [[150, -150], [150, 800]], "colav": target_colav}]}
    if mpc_option is not None:
        d["mpc"]["colregs_option"] = mpc_option
    if own is not None:
        d["own_ship"]["colregs_option"] = own
    if target is not None:
        d["targets"][0]["colregs_option"] = target
    return d


def names(controller) -> list:
    return [t.name for t in controller.terms[len(DEFAULT_TERMS):]]


def test_one_ship_with_the_option_one_without_builds_the_terms_for_that_one_only():
    sc = scenario_from_dict(crossing(own={"enabled": True, "act_range_radii": 5}))
    assert ship_option(sc, 0).enabled and ship_option(sc, 0).act_range_radii == 5
    assert ship_option(sc, 1) == ColregsOptionSpec() and not sc.mpc.colregs_option.enabled
    (c,) = build_controllers(sc, BuildContext(params=sc.mpc.params)).controllers
    assert isinstance(c, GroupedController) and c.ships == (0, 1)
    by_ship = {g.ships: g for g in c.groups}
    assert set(by_ship) == {(0,), (1,)}
    assert names(by_ship[(0,)]) == OPTION_NAMES and by_ship[(0,)].terms[:3] == DEFAULT_TERMS[:3]
    assert isinstance(by_ship[(0,)].terms[3], HeldPathTerm)             # hold_path (default on)
    assert by_ship[(1,)].terms == DEFAULT_TERMS
    assert by_ship[(0,)].terms[0 + len(DEFAULT_TERMS)].act_range_radii == 5
    # the records: each ship its resolved option, and they differ
    ships = scenario_info(sc)["ships"]
    assert ships[0]["colregs_option"]["enabled"] is True and ships[0]["colregs_option"]["act_range_radii"] == 5
    assert ships[1]["colregs_option"] == {**ships[0]["colregs_option"], "enabled": False, "act_range_radii": 4.0}


def test_a_ship_switches_off_the_scenario_option_and_inherits_the_rest():
    sc = scenario_from_dict(crossing(mpc_option={"enabled": True, "chi_apparent_deg": 45},
                                     target={"enabled": False}))
    assert ship_option(sc, 0).enabled and not ship_option(sc, 1).enabled
    assert ship_option(sc, 1).chi_apparent_deg == 45            # the rest from mpc.colregs_option
    (c,) = build_controllers(sc, BuildContext(params=sc.mpc.params)).controllers
    by_ship = {g.ships: g for g in c.groups}
    assert names(by_ship[(0,)]) == OPTION_NAMES and by_ship[(1,)].terms == DEFAULT_TERMS
    # a ship's override of one threshold keeps the scenario's other values
    sc2 = scenario_from_dict(crossing(mpc_option={"enabled": True, "chi_apparent_deg": 45},
                                      target={"act_range_radii": 3}))
    t = ship_option(sc2, 1)
    assert t.enabled and t.act_range_radii == 3 and t.chi_apparent_deg == 45
    assert ship_option(sc2, 0).act_range_radii == 4


def test_same_option_everywhere_is_one_controller_and_records_stay_as_they_were():
    on = scenario_from_dict(crossing(mpc_option={"enabled": True}, target={"enabled": True}))
    (c,) = build_controllers(on, BuildContext(params=on.mpc.params)).controllers
    assert isinstance(c, GridController) and c.ships == (0, 1) and names(c) == OPTION_NAMES
    off = scenario_from_dict(crossing())
    (c,) = build_controllers(off, BuildContext(params=off.mpc.params)).controllers
    assert isinstance(c, GridController) and c.terms == DEFAULT_TERMS
    assert all("colregs_option" not in s for s in scenario_info(off)["ships"])    # paper-faithful: unchanged
    # a target with colav none records nothing even when the option is on
    none_t = scenario_from_dict(crossing(mpc_option={"enabled": True}, target_colav="none"))
    ships = scenario_info(none_t)["ships"]
    assert ships[0]["colregs_option"]["enabled"] is True and "colregs_option" not in ships[1]


@pytest.mark.parametrize("where, section, colav, message", [
    ("target", {"enabled": True, "K_hold": -1}, "psbmpc", "targets[0].colregs_option.K_hold must be >= 0"),
    ("target", {"enabled": "on"}, "psbmpc", "targets[0].colregs_option.enabled must be true or false"),
    ("own", {"act_rang_radii": 3}, "psbmpc", "unknown key 'act_rang_radii' in own_ship.colregs_option"),
    ("own", {"enabled": True, "act_range_radii": 45}, "psbmpc",
     "own_ship.colregs_option.act_range_radii (45) must be below engage_radii (40)"),
    ("target", {"enabled": True}, "none", "targets[0].colregs_option: the ship runs no collision avoidance"),
    ("target", {"enabled": True}, "psbmpc_refine",
     "targets[0].colregs_option.enabled: the option extends the grid-search methods"),
    ("target", [1], "psbmpc", "targets[0].colregs_option must be a mapping"),
    ("target", {"enabled": True, "hold_path": True}, "sbmpc",
     "targets[0].colregs_option.hold_path: weights the path term of psbmpc; the cost of 'sbmpc' has none"),
])
def test_bad_ship_sections_are_refused_naming_the_field(where, section, colav, message):
    kw = {"own": section} if where == "own" else {"target": section}
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)").replace("[", r"\[")
                       .replace("]", r"\]")):
        scenario_from_dict(crossing(target_colav=colav, **kw))


def test_a_refined_target_is_refused_when_the_scenario_option_reaches_it():
    """mpc.colregs_option on, a target running psbmpc_refine without its own section: refused when built."""
    sc = scenario_from_dict(crossing(mpc_option={"enabled": True}, target_colav="psbmpc_refine"))
    with pytest.raises(ValueError, match=r"enabled for ship\(s\) \['TS1'\], but method psbmpc_refine"):
        build_controllers(sc, BuildContext(params=sc.mpc.params))
    # switched off for that ship, it builds
    ok = scenario_from_dict(crossing(mpc_option={"enabled": True}, target={"enabled": False},
                                     target_colav="psbmpc_refine"))
    assert len(build_controllers(ok, BuildContext(params=ok.mpc.params)).controllers) == 2


def test_closed_loop_the_stand_on_own_ship_with_the_option_and_the_give_way_target_without():
    """Only the own-ship has the option: it keeps (1, 0) up to the CPA while the target, on the published cost,
    gives way; the two groups are solved at every update."""
    res = simulate(scenario_from_dict(crossing(own={"enabled": True})), batch="loop")
    own, ts = res.states[0, 0], res.states[0, 1]
    d = np.hypot(*(ts[:, :2] - own[:, :2]).T)
    k_cpa = int(np.argmin(d))
    assert 20 < res.t[k_cpa] < res.t[-1] - 20
    before = res.solve_t <= res.t[k_cpa]
    assert before.sum() >= 8
    np.testing.assert_array_equal(res.offsets[0, 0, before], np.tile([1.0, 0.0], (int(before.sum()), 1)))
    assert np.max(np.abs(own[:k_cpa + 1, 2])) < math.radians(1.0)
    # the target planned on the published cost and manoeuvred; they passed clear (R = 10 m)
    assert np.any(res.offsets[0, 1, before] != np.array([1.0, 0.0]))
    assert d.min() > 3 * 10.0, d.min()
