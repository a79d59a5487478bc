"""A controller from outside the package (examples/my_controller/) in closed loop: named by import path in a
scenario file, registered through the Python API, published through an entry point; unknown names refused."""

from __future__ import annotations

import contextlib
import importlib.metadata
import io
import json
import math
import pathlib

import numpy as np
import pytest
import yaml

from psbmpc_jax.apps.cli import main
from psbmpc_jax.methods import REGISTRY, Decision, Method, register, registry, unregister
from psbmpc_jax.scenario import load_scenario, scenario_from_dict
from psbmpc_jax.sim import simulate

EXAMPLE = pathlib.Path(__file__).resolve().parents[1] / "examples" / "my_controller"
SCENARIO = EXAMPLE / "head_on_cpa.yaml"


@pytest.fixture
def cpa(monkeypatch):
    """The example's module, importable as ``cpa_controller`` (as with PYTHONPATH=examples/my_controller)."""
    monkeypatch.syspath_prepend(str(EXAMPLE))
    import cpa_controller

    registry._FOUND.clear()
    yield cpa_controller
    registry._FOUND.clear()


def _short(path=SCENARIO, **mpc) -> dict:
    d = yaml.safe_load(path.read_text())
    d["simulation"]["duration_s"] = 100
    d["mpc"].update(mpc)
    return d


def _allowed(cpa_module) -> set:
    return {(u, round(math.radians(c), 9)) for u, c in cpa_module.MANOEUVRES}


def _offsets_are_the_controllers(res, cpa_module, ship=0):
    got = {(float(u), round(float(c), 9)) for u, c in res.offsets[:, ship].reshape(-1, 2)}
    assert got <= _allowed(cpa_module)
    return got


def test_the_yaml_file_names_the_controller_by_import_path(cpa, tmp_path):
    sc = load_scenario(SCENARIO)
    assert sc.mpc.method == sc.own_ship.colav == "cpa_controller:CpaMethod"
    res = simulate(scenario_from_dict(_short(), base_dir=EXAMPLE), runs=2)
    assert res.method == "cpa_controller:CpaMethod" and res.colav_info is None
    got = _offsets_are_the_controllers(res, cpa)
    assert any(c > 0 for _, c in got)                       # it did turn to starboard for the head-on target
    assert all(np.isnan(res.best_costs).ravel())            # no cost columns: not a grid search
    assert not any(m["collision"] for m in res.metrics)
    # the command line runs it too, and metrics.json records the method's own settings
    out = tmp_path / "out"
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["run", str(SCENARIO), "--runs", "1", "--out", str(out), "--no-figures", "--quiet"]) == 0
    doc = json.loads((out / "head_on_cpa" / "metrics.json").read_text())
    assert doc["summary"]["method"] == "cpa_controller:CpaMethod"
    rec = doc["scenario"]["mpc"]["methods"]["cpa_controller:CpaMethod"]
    assert rec["d_safe_m"] == 30.0 and rec["horizon_s"] == 120.0 and doc["scenario"]["mpc"]["d_safe_m"] == 30.0


def test_the_python_api_registers_it_under_a_name_for_own_ship_and_targets(cpa):
    register(cpa.CpaMethod(d_safe_m=60.0))
    try:
        assert "cpa" in registry.names()
        with pytest.raises(ValueError, match="method 'cpa' is registered already"):
            register(cpa.CpaMethod())
        d = _short(method="cpa")
        d["targets"][0]["colav"] = "cpa"                    # a target may run it too (it plans any ship)
        res = simulate(scenario_from_dict(d), runs=1)
        assert res.method == "cpa"
        _offsets_are_the_controllers(res, cpa, ship=0)
        _offsets_are_the_controllers(res, cpa, ship=1)
        assert np.isfinite(res.offsets).all()
        # the settings passed in code are what ran: a smaller d_safe turns less
        unregister("cpa")
        register(cpa.CpaMethod(d_safe_m=5.0))
        res5 = simulate(scenario_from_dict(d), runs=1)
        assert np.nanmax(res5.offsets[..., 1]) < np.nanmax(res.offsets[..., 1])
    finally:
        REGISTRY.pop("cpa", None)


def test_its_own_section_of_the_file_is_parsed_by_its_module(cpa):
    sc = load_scenario(SCENARIO)
    assert sc.mpc.cpa == cpa.CpaSettings(d_safe_m=30.0, horizon_s=120.0)
    d = _short()
    d["mpc"]["cpa"] = {"d_safe_m": 55, "horizon_s": 90}
    sc = scenario_from_dict(d)
    assert cpa.CpaMethod().settings(sc) == cpa.CpaSettings(55.0, 90.0)
    assert cpa.CpaMethod(d_safe_m=20.0).settings(sc) == cpa.CpaSettings(20.0, 90.0)     # code wins
    res = simulate(sc, runs=1)
    _offsets_are_the_controllers(res, cpa)
    d["mpc"]["cpa"] = {"d_safe_m": -1}
    with pytest.raises(ValueError, match=r"mpc.cpa.d_safe_m must be > 0, got -1"):
        scenario_from_dict(d)
    d["mpc"]["cpa"] = {"d_safe": 30}
    with pytest.raises(ValueError, match=r"unknown key 'd_safe' in mpc.cpa \(did you mean 'd_safe_m'"):
        scenario_from_dict(d)
    with pytest.raises(ValueError, match=r"CpaSettings.horizon_s must be a number > 0, got 0"):
        cpa.CpaMethod(horizon_s=0)


def test_an_entry_point_publishes_it(cpa, monkeypatch):
    ep = importlib.metadata.EntryPoint(name="cpa_ep", value="cpa_controller:CpaMethod",
                                       group=registry.ENTRY_POINT_GROUP)
    monkeypatch.setattr(registry, "_entry_points", lambda: {"cpa_ep": ep})
    assert "cpa_ep" in registry.names()
    res = simulate(scenario_from_dict(_short(method="cpa_ep")), runs=1)
    assert res.method == "cpa_ep"
    _offsets_are_the_controllers(res, cpa)


@pytest.mark.parametrize("name, match", [
    ("cpa_typo", r"mpc.method must be a known method \(psbmpc, psbmpc_refine, .*two_level\) or an import path "
                 r"'package.module:Name' of a psbmpc_jax.methods.Method, got 'cpa_typo'"),
    ("no_such_module:Thing", r"mpc.method 'no_such_module:Thing': cannot import module 'no_such_module'"),
    ("cpa_controller:Nothing", r"mpc.method 'cpa_controller:Nothing': module 'cpa_controller' has no attribute"),
    ("cpa_controller:cpa", r"mpc.method 'cpa_controller:cpa': expected a psbmpc_jax.methods.Method subclass or "
                           r"instance, got function"),
])
def test_unknown_names_are_refused_with_the_known_ones(cpa, name, match):
    with pytest.raises(ValueError, match=match):
        scenario_from_dict(_short(method=name))


def test_a_target_cannot_run_an_own_ship_only_method_and_bad_decisions_are_caught(cpa):
    class OwnOnly(cpa.CpaMethod):
        name = "own_only_cpa"
        own_ship_only = True

    register(OwnOnly())
    try:
        d = _short()
        d["targets"][0]["colav"] = "own_only_cpa"
        with pytest.raises(ValueError, match=r"targets\[0\].colav: own_only_cpa plans the own-ship only"):
            scenario_from_dict(d)
    finally:
        unregister("own_only_cpa")
    with pytest.raises(ValueError, match=r"Decision.first must have shape \(2, 2\) \(one row per job\), got \(1, 2\)"):
        Decision(jobs=[(0, 0), (1, 0)], first=np.zeros((1, 2)), costs=np.zeros((2, 5)), walls=np.zeros(2),
                 device_calls=0, wall=0.0)

    class NotAController(Method):
        name = "broken"

        def build(self, scenario, ships, context):
            return object()

    register(NotAController())
    try:
        with pytest.raises(TypeError, match=r"method 'broken': build\(\) must return a controller"):
            simulate(scenario_from_dict(_short(method="broken")), runs=1)
    finally:
        unregister("broken")
