"""The stop remedy per ship (docs/methods/psbmpc.md, "The stop loophole and its remedy"): a ship entry's
``stop_remedy`` key over the scenario's ``mpc.config.stop_remedy``; ships of one method with different remedies
plan in different groups (the grouping of the per-ship COLREGS option, on (option, remedy)); each ship's resolved
remedy recorded; bad values and ships whose method has no COLREGS indicator refused naming the ship's field."""

from __future__ import annotations

import json

import numpy as np
import pytest

from psbmpc_jax.methods.base import BuildContext
from psbmpc_jax.methods.grid import GridController, GroupedController
from psbmpc_jax.methods.registry import build_controllers
from psbmpc_jax.methods.stop_remedy_settings import REMEDY_METHODS, ship_remedy
from psbmpc_jax.params import STOP_REMEDIES
from psbmpc_jax.scenario.load import scenario_from_dict
from psbmpc_jax.sim.output import scenario_info, write_outputs
from psbmpc_jax.sim.simulator import simulate

HEADING = "colregs_heading"


def give_way(own=None, targets=(None,), colavs=("psbmpc",), mpc_remedy=None, duration=60.0, method=None) -> dict:
    """The own-ship heads north at 2 m/s; TS1 comes from its starboard side heading west on a collision course
    (both at (100, 0) after 50 s): the own-ship gives way.  Further targets (TS2, ...) cross far ahead.  ``own`` /
    ``targets[i]``: the ships' ``stop_remedy`` keys (None: no key); ``colavs[i]``: the targets' methods."""
    d = {"name": "stop_remedy_per_ship", "simulation": {"dt_s": 0.5, "duration_s": duration},
         "monte_carlo": {"runs": 1, "seed": 0},
         "mpc": {"preset": "nidelva", "update_period_s": 5, "n_ps": 1, "config": {"T": 60.0, "dt": 1.0},
                 "speed_factors": [[1.0, 0.0]], "course_offsets_deg": [[-30, 0, 30]]},
         "own_ship": {"name": "OS", "position_m": [0, 0], "course_deg": 0, "speed_mps": 2,
                      "waypoints_m": [[0, 0], [1000, 0]]},
         "targets": [{"name": f"TS{i + 1}", "position_m": [100 + 400 * i, 100], "course_deg": 270,
                      "speed_mps": 2, "waypoints_m": [[100 + 400 * i, 100], [100 + 400 * i, -800]],
                      "colav": colav} for i, colav in enumerate(colavs)]}
    if method is not None:
        d["mpc"]["method"] = method
    if mpc_remedy is not None:
        d["mpc"]["config"]["stop_remedy"] = mpc_remedy
    if own is not None:
        d["own_ship"]["stop_remedy"] = own
    for i, r in enumerate(targets):
        if r is not None:
            d["targets"][i]["stop_remedy"] = r
    return d


def controller(sc):
    (c,) = build_controllers(sc, BuildContext(params=sc.mpc.params)).controllers
    return c


# ============================================================================ parsing
def test_a_ship_key_overrides_the_scenario_remedy_and_the_others_inherit_it():
    sc = scenario_from_dict(give_way(own=HEADING))
    assert sc.ships[0].stop_remedy == HEADING and sc.ships[1].stop_remedy is None
    assert sc.mpc.config.stop_remedy == "none"
    assert [ship_remedy(sc, i) for i in range(2)] == [HEADING, "none"]
    # the scenario-wide remedy on, one target switches it off
    sc = scenario_from_dict(give_way(targets=(None, "none"), colavs=("psbmpc", "psbmpc"), mpc_remedy=HEADING))
    assert [ship_remedy(sc, i) for i in range(3)] == [HEADING, HEADING, "none"]
    assert sc.ships[2].stop_remedy == "none" and sc.ships[1].stop_remedy is None
    # without any key: the scenario's (default "none") for everyone, nothing stored per ship
    sc = scenario_from_dict(give_way())
    assert [s.stop_remedy for s in sc.ships] == [None, None] and ship_remedy(sc, 1) == "none"
    assert STOP_REMEDIES == ("none", HEADING) and set(REMEDY_METHODS) == {"psbmpc", "psbmpc_refine", "psbmpc_2020"}


# ============================================================================ errors
@pytest.mark.parametrize("kw, message", [
    (dict(targets=("heading",)), "targets[0].stop_remedy (ship 'TS1') must be one of none, colregs_heading, got "
                                 "'heading'"),
    (dict(own=True), "own_ship.stop_remedy (ship 'OS') must be one of none, colregs_heading, got True"),
    (dict(own=None, targets=(["colregs_heading"],)), "targets[0].stop_remedy (ship 'TS1') must be one of"),
    (dict(targets=(HEADING,), colavs=("none",)),
     "targets[0].stop_remedy (ship 'TS1'): the ship runs no collision avoidance (colav: none), whose cost has no "
     "Boolean COLREGS indicator"),
    (dict(targets=(HEADING,), colavs=("sbmpc",)),
     "targets[0].stop_remedy (ship 'TS1'): the ship runs method 'sbmpc', whose cost has no Boolean COLREGS "
     "indicator for the stop remedy to change; only psbmpc, psbmpc_refine, psbmpc_2020 read it"),
    (dict(targets=("none",), colavs=("informed_sbmpc",)),
     "targets[0].stop_remedy (ship 'TS1'): the ship runs method 'informed_sbmpc'"),
    (dict(own=HEADING, method="sbmpc_init"), "own_ship.stop_remedy (ship 'OS'): the ship runs method 'sbmpc_init'"),
])
def test_bad_values_and_ships_without_the_indicator_are_refused_naming_the_field(kw, message):
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)").replace("[", r"\[")
                       .replace("]", r"\]")):
        scenario_from_dict(give_way(**kw))


def test_refined_ships_with_different_remedies_are_refused_when_built():
    """``psbmpc_refine`` plans its ships with one refined controller: different remedies are refused by name."""
    sc = scenario_from_dict(give_way(targets=(HEADING, None), colavs=("psbmpc_refine", "psbmpc_refine"),
                                     method="psbmpc_refine"))
    with pytest.raises(ValueError, match=r"method psbmpc_refine: its ships plan with one refined controller, .*"
                                         r"got stop remedy 'none' for \['OS', 'TS2'\]; 'colregs_heading' for "
                                         r"\['TS1'\]"):
        build_controllers(sc, BuildContext(params=sc.mpc.params))
    same = scenario_from_dict(give_way(own=HEADING, targets=(HEADING,), colavs=("psbmpc_refine",),
                                       method="psbmpc_refine"))
    c = controller(same)
    assert isinstance(c, GridController) and c.solver.config.stop_remedy == HEADING and c.refine_ships == (0, 1)


# ============================================================================ grouping
def test_different_remedies_plan_in_groups_and_one_remedy_is_one_controller():
    sc = scenario_from_dict(give_way(own=HEADING, targets=(None, HEADING), colavs=("psbmpc", "psbmpc")))
    c = controller(sc)
    assert isinstance(c, GroupedController) and c.ships == (0, 1, 2)
    by_ship = {g.ships: g for g in c.groups}
    assert set(by_ship) == {(0, 2), (1,)}
    assert by_ship[(0, 2)].solver.config.stop_remedy == HEADING and by_ship[(1,)].solver.config.stop_remedy == "none"
    assert by_ship[(0, 2)].mpc.config.stop_remedy == HEADING       # the group's packing sees the same config
    # only the remedy differs between the groups' configs
    a, b = by_ship[(0, 2)].solver.config, by_ship[(1,)].solver.config
    assert a.replace(stop_remedy="none") == b
    # the same remedy for all, given per ship or scenario-wide: one controller, as before
    for d in (give_way(own=HEADING, targets=(HEADING,)), give_way(mpc_remedy=HEADING),
              give_way(own="none", targets=("none",))):
        c = controller(scenario_from_dict(d))
        assert isinstance(c, GridController) and c.ships == (0, 1)
        assert c.solver.config.stop_remedy == ship_remedy(scenario_from_dict(d), 0)


def test_groups_on_the_colregs_option_and_the_remedy_together():
    """OS: COLREGS option on, no remedy; TS1: option off, remedy; TS2: both off -> three groups."""
    d = give_way(targets=(HEADING, None), colavs=("psbmpc", "psbmpc"))
    d["own_ship"]["colregs_option"] = {"enabled": True}
    c = controller(scenario_from_dict(d))
    by_ship = {g.ships: g for g in c.groups}
    assert set(by_ship) == {(0,), (1,), (2,)}
    assert [by_ship[(i,)].solver.config.stop_remedy for i in range(3)] == ["none", HEADING, "none"]
    assert len(by_ship[(0,)].terms) > len(by_ship[(1,)].terms) == len(by_ship[(2,)].terms)


def test_the_2020_cost_groups_on_the_remedy_too():
    d = give_way(own=HEADING, colavs=("psbmpc_2020",), method="psbmpc_2020")
    d["mpc"]["sbmpc"] = {"d_safe_m": 10, "d_cl_m": 40}           # tuned for these 5 m ships (not the 30 m default)
    sc = scenario_from_dict(d)
    c = controller(sc)
    assert isinstance(c, GroupedController)
    assert {g.ships: g.solver.config.stop_remedy for g in c.groups} == {(0,): HEADING, (1,): "none"}


# ============================================================================ records
def test_records_stay_as_they_were_without_a_remedy_and_name_each_ships_remedy_with_one():
    assert all("stop_remedy" not in s for s in scenario_info(scenario_from_dict(give_way()))["ships"])
    ships = scenario_info(scenario_from_dict(give_way(mpc_remedy=HEADING, colavs=("psbmpc", "none"))))["ships"]
    assert [s.get("stop_remedy") for s in ships] == [HEADING, HEADING, None]    # colav none: nothing to record
    # an explicit "none" on one ship is recorded (every ship that reads the remedy then is)
    ships = scenario_info(scenario_from_dict(give_way(targets=("none",))))["ships"]
    assert [s.get("stop_remedy") for s in ships] == ["none", "none"]


# ============================================================================ closed loop
def test_closed_loop_only_the_own_ship_has_the_remedy(monkeypatch, tmp_path):
    """The give-way own-ship with the remedy, the stand-on target with the published test, 60 s: every update
    solves the own-ship with ``colregs_heading`` and the target with ``none``; at the own-ship's solves the remedy
    charges stop behaviours that the published test would not (re-evaluated on the same inputs); metrics.json
    records each ship's remedy."""
    import psbmpc_jax.methods.grid as grid

    sc = scenario_from_dict(give_way(own=HEADING))
    beh = np.asarray(sc.mpc.behaviours)
    stops = np.flatnonzero(beh[:, 0, 0] == 0.0)
    assert stops.size == 3
    original, calls = grid.solve, []

    def recording(inputs, state, params, samples, config=None, terms=None):
        out = original(inputs, state, params, samples, config=config, terms=terms)
        published = original(inputs, state, params, samples, config=config.replace(stop_remedy="none"), terms=terms)
        calls.append((config.stop_remedy, np.asarray(out[2].details["mu"])[stops, 0, 0],
                      np.asarray(published[2].details["mu"])[stops, 0, 0]))
        return out

    monkeypatch.setattr(grid, "solve", recording)
    res = simulate(sc, batch="loop")
    n_updates = len(res.solve_t)
    assert n_updates == 12 and len(calls) == 2 * n_updates
    assert [c[0] for c in calls] == [HEADING, "none"] * n_updates          # own-ship's group first, each update
    own = [c for c in calls[0::2]]
    assert any(np.any(mu > pub) for _, mu, pub in own)                     # the remedy charged a stop ...
    assert all(np.all(mu >= pub) for _, mu, pub in own)                    # ... and never excused one
    for _, mu, pub in calls[1::2]:                                         # the target: the published test
        np.testing.assert_array_equal(mu, pub)
    monkeypatch.setattr(grid, "solve", original)
    write_outputs(res, tmp_path / "run", figures=False)
    doc = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert [(s["name"], s["stop_remedy"]) for s in doc["scenario"]["ships"]] == [("OS", HEADING), ("TS1", "none")]
    assert doc["scenario"]["mpc"]["config"]["stop_remedy"] == "none"     # the scenario-wide default, unchanged


def test_a_scenario_wide_remedy_no_ship_reads_is_refused():
    """``mpc.config.stop_remedy`` on a scenario none of whose ships runs a method with the Boolean COLREGS indicator
    would be ignored: refused naming the field and the ships' methods; accepted when one ship reads it."""
    with pytest.raises(ValueError,
                       match=r"mpc.config.stop_remedy = 'colregs_heading': no ship .* \(the ships run sbmpc, none;"):
        scenario_from_dict(give_way(mpc_remedy=HEADING, method="sbmpc", colavs=("none",)))
    sc = scenario_from_dict(give_way(mpc_remedy=HEADING, colavs=("none",)))          # the own-ship reads it
    assert ship_remedy(sc, 0) == HEADING
