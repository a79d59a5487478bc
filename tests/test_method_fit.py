"""Method settings carry the ship they were tuned for: every shipped scenario x every built-in method either
loads with settings that fit its ships or is refused with the reason (Method.check_fit, DesignShip)."""

import warnings

import numpy as np
import pytest
import yaml

from psbmpc_jax.design_ship import SCALE_PARAMS
from psbmpc_jax.methods import REGISTRY, DesignShip
from psbmpc_jax.params import Params
from psbmpc_jax.presets import PRESETS
from psbmpc_jax.scenario import builtin_scenarios, load_scenario, scenario_from_dict
from psbmpc_jax.scenario.schema import SCENARIO_DIR

BUILTIN_METHODS = ("psbmpc", "psbmpc_refine", "sbmpc", "psbmpc_2020", "informed_sbmpc", "smooth_sbmpc", "sbmpc_init",
                   "two_level")


def _load(name, method=None):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_scenario(name, method=method)


@pytest.mark.parametrize("scenario", builtin_scenarios())
def test_every_scenario_by_every_method_fits_or_is_refused_by_name(scenario):
    own = _load(scenario)                                 # the file's own method always fits
    for method in BUILTIN_METHODS:
        design = REGISTRY[method].design_for(own.mpc)     # psbmpc, psbmpc_refine: the preset's design ship
        try:
            sc = _load(scenario, method=method)
        except ValueError as exc:
            msg = str(exc)
            assert design is not None, f"{scenario} x {method}: refused without a design ship: {msg}"
            assert f"method {method} on ship " in msg and "were tuned for" in msg, msg
            assert REGISTRY[method].untuned(own.mpc.given, own.mpc) is not None, msg
            continue
        # loaded: either the method's tuning is the scenario's (its section given, or no design ship) or the
        # ships that run it lie inside the design ship's range
        if design is not None and REGISTRY[method].untuned(sc.mpc.given, sc.mpc) is not None:
            assert REGISTRY[method].design_for(sc.mpc) == design
            assert design.misfit(sc.own_ship.length, sc.own_ship.U_d) is None, (scenario, method)


def test_design_ship_rule_edges():
    d = DesignShip(30.0, 9.0, "a test ship")
    assert d.misfit(10.0, 3.0) is None and d.misfit(90.0, 27.0) is None          # the factor 3 is inclusive
    assert d.misfit(9.99, 9.0) == "length 9.99 m outside 10-90 m"
    assert d.misfit(30.0, 27.01) == "cruise speed 27.01 m/s outside 3-27 m/s"
    assert d.misfit(0.0, 9.0) is None                     # a point target has no hull to compare
    explicit = DesignShip(10.0, 5.0, "bounded", speed_range=(4.0, 5.0))
    assert explicit.misfit(10.0, 4.0) is None and "outside 4-5 m/s" in explicit.misfit(10.0, 2.0)


def test_giving_the_methods_section_is_taking_responsibility_for_the_tuning():
    data = yaml.safe_load((SCENARIO_DIR / "head_on.yaml").read_text())
    with pytest.raises(ValueError, match=r"method informed_sbmpc on ship 'OS': its default settings \(mpc.informed "
                                         r"not in the file\) were tuned for Akdağ, Fossen & Johansen 2022 .* length "
                                         r"5 m outside 38.7-348 m; cruise speed 2 m/s outside 2-18 m/s|length 5 m"):
        scenario_from_dict(data, method="informed_sbmpc")
    data["mpc"]["informed"] = {"d_init_m": 400, "xtd_threshold_m": 20}
    assert scenario_from_dict(data, method="informed_sbmpc").mpc.method == "informed_sbmpc"
    # two-level: its speed bound is the ship's speed, so a 2 m/s boat needs its own U_max_mps
    data = yaml.safe_load((SCENARIO_DIR / "head_on.yaml").read_text())
    with pytest.raises(ValueError, match=r"method two_level .* cruise speed 2 m/s outside 4-5 m/s"):
        scenario_from_dict(data, method="two_level")
    data["mpc"]["two_level"] = {"U_max_mps": 2}
    assert scenario_from_dict(data, method="two_level").mpc.method == "two_level"


def test_a_target_running_a_method_is_checked_too():
    data = yaml.safe_load((SCENARIO_DIR / "head_on.yaml").read_text())
    data["targets"][0]["colav"] = "sbmpc"
    with pytest.raises(ValueError, match=r"method sbmpc on ship 'TS1': .* Tengesdal, Brekke & Johansen 2020"):
        scenario_from_dict(data)
    data["mpc"]["sbmpc"] = {"preset": "river"}
    assert scenario_from_dict(data).targets[0].colav == "sbmpc"


def test_a_source_that_names_only_a_length_or_only_a_speed():
    by_length = DesignShip(5.0, None, "5 m vessels")
    assert by_length.misfit(15.0, 40.0) is None and by_length.misfit(15.01, 1.0) == "length 15.01 m outside 1.67-15 m"
    by_speed = DesignShip(None, 10.0, "10 m/s ships")
    assert by_speed.misfit(400.0, 5.0) is None
    assert by_speed.misfit(400.0, 3.0) == "cruise speed 3 m/s outside 3.33-30 m/s"


def test_every_mpc_preset_names_its_design_ship():
    for name, preset in PRESETS.items():
        d = preset.design_ship
        assert d is not None and d.source.startswith(f"preset {name}: "), name
        assert d.length_m is not None or d.speed_mps is not None, name
    assert (PRESETS["tengesdal2020"].design_ship.length_m, PRESETS["tengesdal2020"].design_ship.speed_mps) == (30, 9)
    assert (PRESETS["akdag2022"].design_ship.length_m, PRESETS["akdag2022"].design_ship.speed_mps) == (116, 6)


def _scaled_for_100m() -> dict:
    """Every scale-dependent parameter, scaled from the nidelva preset's 5 m vessels to a 100 m ship."""
    nidelva = PRESETS["nidelva"].params
    return {k: float(getattr(nidelva, k)) * 20.0 for k in SCALE_PARAMS}


def _large_ships_on_the_nidelva_preset():
    data = yaml.safe_load((SCENARIO_DIR / "head_on.yaml").read_text())
    del data["mpc"]["params"]                            # the preset's tuning as it is
    data["mpc"].pop("method", None)
    data["own_ship"]["length_m"] = 100.0
    return data


@pytest.mark.parametrize("method", ["psbmpc", "psbmpc_refine"])
def test_the_psbmpc_family_checks_the_ships_against_the_preset(method):
    data = _large_ships_on_the_nidelva_preset()
    everything = ", ".join(SCALE_PARAMS)
    with pytest.raises(ValueError, match=rf"method {method} on ship 'OS': its default settings \(mpc.params "
                                         rf"{everything} not in the file\) were tuned for preset nidelva: Tengesdal "
                                         r"et al. 2022, Table 1 \(river, 5 m vessels\) .* length 100 m outside "
                                         rf"1.67-15 m\. Give mpc.params {everything} tuned for this ship"):
        scenario_from_dict(data, method=method)
    data["own_ship"]["length_m"] = 15.0                  # the factor 3 is inclusive; the preset names no speed
    data["own_ship"]["speed_mps"] = 7.0
    assert scenario_from_dict(data, method=method).mpc.method == method
    data = _large_ships_on_the_nidelva_preset()
    data["mpc"]["params"] = _scaled_for_100m()           # the file tunes the preset for its ship
    assert scenario_from_dict(data, method=method).own_ship.length == 100.0
    data = _large_ships_on_the_nidelva_preset()
    data["mpc"]["preset"] = "tengesdal2020"               # or picks the preset made for its ship (30 m at 9 m/s)
    data["own_ship"]["length_m"], data["own_ship"]["speed_mps"] = 60.0, 6.0
    assert scenario_from_dict(data, method=method).mpc.preset == "tengesdal2020"


def test_a_target_running_psbmpc_is_checked_against_the_preset():
    data = yaml.safe_load((SCENARIO_DIR / "head_on.yaml").read_text())
    del data["mpc"]["params"]
    data["targets"][0]["colav"] = "psbmpc"
    data["targets"][0]["length_m"] = 60.0
    with pytest.raises(ValueError, match=r"method psbmpc on ship 'TS1': .* preset nidelva: .* length 60 m outside"):
        scenario_from_dict(data)


@pytest.mark.parametrize("method", ["psbmpc", "psbmpc_refine"])
@pytest.mark.parametrize("params", [{"K_coll": 50.0}, {"K_chi_port": 6.0}, {"K_coll": 50.0, "kappa": 3.0}])
def test_a_weight_under_mpc_params_does_not_tune_the_preset_for_another_ship(method, params):
    # before: any key under mpc.params skipped the check, so a lone weight let a 100 m ship run the 5 m tuning
    data = _large_ships_on_the_nidelva_preset()
    data["mpc"]["params"] = params
    with pytest.raises(ValueError, match=rf"method {method} on ship 'OS': its default settings \(mpc.params "
                                         rf"{', '.join(SCALE_PARAMS)} not in the file\) were tuned for preset "
                                         r"nidelva: .* length 100 m outside 1.67-15 m"):
        scenario_from_dict(data, method=method)
    data["mpc"]["params"] = {**params, **_scaled_for_100m()}      # with the scale-dependent ones as well: accepted
    sc = scenario_from_dict(data, method=method)
    assert sc.mpc.params.d_safe == 100.0 and set(sc.mpc.given_params) == set(params) | set(SCALE_PARAMS)


def test_a_partial_scale_override_is_refused_naming_what_is_missing():
    data = _large_ships_on_the_nidelva_preset()
    scaled = _scaled_for_100m()
    data["mpc"]["params"] = {k: scaled[k] for k in ("d_safe", "r_ct", "d_close")}
    rest = ", ".join(k for k in SCALE_PARAMS if k not in ("d_safe", "r_ct", "d_close"))
    with pytest.raises(ValueError, match=rf"\(mpc.params {rest} not in the file\)") as info:
        scenario_from_dict(data)
    assert "d_safe" not in str(info.value).split("were tuned")[0]
    data["mpc"]["params"] = {k: v for k, v in scaled.items() if k != "ob_T_U"}
    with pytest.raises(ValueError, match=r"\(mpc.params ob_T_U not in the file\)"):
        scenario_from_dict(data)


def test_a_fitting_ship_needs_no_scale_parameters():
    # the shipped head_on gives only K_chi_port: its 5 m ships fit the nidelva preset, so it loads as before
    data = yaml.safe_load((SCENARIO_DIR / "head_on.yaml").read_text())
    assert set(data["mpc"]["params"]) == {"K_chi_port"}
    assert scenario_from_dict(data).mpc.given_params == ("K_chi_port",)


def test_the_scale_parameters_are_the_ones_the_ship_scale_presets_change():
    fields = set(Params.__dataclass_fields__)
    assert set(SCALE_PARAMS) <= fields and len(set(SCALE_PARAMS)) == len(SCALE_PARAMS)
    default = Params()
    for name in ("tengesdal2020", "akdag2022"):       # presets made for ships of another scale than Params()'s
        p = PRESETS[name].params
        changed = {k for k in fields if not np.array_equal(getattr(p, k), getattr(default, k), equal_nan=True)}
        assert changed == set(SCALE_PARAMS), (name, changed ^ set(SCALE_PARAMS))
