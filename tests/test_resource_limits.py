"""Limits derived from resources (psbmpc_jax.limits) and physically meaningless tracks and charts refused: the
memory estimate is checked before anything is allocated, the message names the setting, the estimate and the
limit; implausible units (degrees read as metres, 1e300 m, 1e6 m/s) and a [lat, lon] chart are refused."""

from __future__ import annotations

import json
import time
import tracemalloc

import numpy as np
import pytest

from psbmpc_jax import limits
from psbmpc_jax.chart_order import great_circle_m, swapped_order
from psbmpc_jax.evaltool import evaluate_file, evaluate_tracks
from psbmpc_jax.evaltool.tracks import Tracks
from psbmpc_jax.scenario import load_scenario, scenario_from_dict


# ------------------------------------------------------------------------------------------------ the limit
def test_parse_bytes_and_the_environment_override(monkeypatch):
    assert limits.parse_bytes("8GiB") == 8 * 2 ** 30 and limits.parse_bytes("500 MB") == 500 * 10 ** 6
    assert limits.parse_bytes("123") == 123
    for bad in ("lots", "-5GB", "8 parsecs", "0"):
        with pytest.raises(ValueError, match="PSBMPC_MEMORY_LIMIT"):
            limits.parse_bytes(bad)
    monkeypatch.setenv("PSBMPC_MEMORY_LIMIT", "3GiB")
    assert limits.memory_limit() == (3 * 2 ** 30, "PSBMPC_MEMORY_LIMIT")


def test_memory_limit_reads_the_host(monkeypatch):
    monkeypatch.delenv("PSBMPC_MEMORY_LIMIT", raising=False)
    cap, source = limits.memory_limit("cpu")
    assert cap is None or (cap > 0 and "memory" in source)


def test_check_names_setting_estimate_and_limit():
    limits.check("x", 0.79 * 2 ** 30, "work", limit=(2 ** 30, "test"))              # under 80 %: accepted
    with pytest.raises(limits.ResourceError) as err:
        limits.check("mpc.config.T", 3 * 2 ** 30, "a solve of 100000 steps", hint="a shorter T",
                     limit=(2 ** 30, "test memory"))
    msg = str(err.value)
    assert msg.startswith("mpc.config.T: a solve of 100000 steps needs about 3 GiB") and "test memory" in msg
    assert "819 MiB" in msg and "a shorter T" in msg
    limits.check("x", 1e30, "work", limit=(None, "unknown"))                        # unknown: nothing refused


# ------------------------------------------------------------------------------------------------ evaluation
def line_tracks(n_in, span, V=2):
    t = np.linspace(0.0, span, n_in)
    north = np.stack([np.linspace(0.0, 2.0 * span, n_in) * (1 - 2 * (v % 2)) + 500.0 * v for v in range(V)])
    east = np.stack([np.full(n_in, 10.0 * v) for v in range(V)])
    return Tracks.from_arrays(t, north, east)


@pytest.mark.parametrize("n, V, pairs", [(60_000, 2, "own"), (40_000, 3, "all")])
def test_evaluation_estimate_bounds_the_measured_peak(n, V, pairs):
    """The estimate is above the measured peak (tracemalloc) and within a factor 2 of it (not vacuous)."""
    tr = line_tracks(50, n - 1, V)
    tracemalloc.start()
    evaluate_tracks(tr, pairs=pairs)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    est = limits.evaluation_bytes(n, V, pairs)
    assert peak <= est <= 2.0 * peak, (peak, est)


def test_runaway_track_span_is_refused_before_allocating(tmp_path):
    """4 rows, timestamps in milliseconds: 1e9 s at 1 s sampling. Refused in well under a second."""
    p = tmp_path / "ms.csv"
    p.write_text("t_s,vessel,north_m,east_m\n0,own,0,0\n0,ts,100,0\n1000000000,own,1000,0\n1000000000,ts,-1000,0\n")
    t0 = time.perf_counter()
    with pytest.raises(limits.ResourceError, match=r"ms\.csv: sample_interval_s: scoring tracks of 1e\+09 s .* "
                                                   r"needs about .* GiB of memory; the limit is .*milliseconds"):
        evaluate_file(p)
    assert time.perf_counter() - t0 < 2.0


def test_scenario_sample_interval_is_checked_at_load():
    d = {"name": "t", "simulation": {"dt_s": 0.5, "duration_s": 400}, "evaluation": {"sample_interval_s": 1e-6},
         "mpc": {"preset": "nidelva", "update_period_s": 5},
         "own_ship": {"name": "OS", "position_m": [0, 0], "course_deg": 0, "speed_mps": 2},
         "targets": [{"name": "TS1", "position_m": [600, 0], "course_deg": 180, "speed_mps": 2}]}
    with pytest.raises(limits.ResourceError, match=r"evaluation\.sample_interval_s: scoring tracks of 400 s sampled "
                                                   r"every 1e-06 s \(4e\+08 samples\)"):
        scenario_from_dict(d, land_checks="off")
    d["evaluation"]["sample_interval_s"] = 0.5
    scenario_from_dict(d, land_checks="off")


CSV_DEG = ("t_s,vessel,north_m,east_m,course_deg,speed_mps\n0,own,63.4300,10.3900,0,5\n0,ts,63.4400,10.3900,180,5\n"
           "60,own,63.4327,10.3900,0,5\n60,ts,63.4373,10.3900,180,5\n120,own,63.4354,10.3900,0,5\n"
           "120,ts,63.4346,10.3900,180,5\n")


@pytest.mark.parametrize("text, match", [
    (CSV_DEG, r"deg\.csv: north/east look like latitude/longitude in degrees.*given speeds reach 5 m/s"),
    (CSV_DEG.replace(",0,5\n", ",0,0\n").replace(",180,5\n", ",180,0\n"),
     r"look like latitude/longitude in degrees.*no vessel moves faster than"),
    ("t_s,vessel,north_m,east_m\n0,own,0,0\n0,ts,1e300,0\n10,own,10,0\n10,ts,1e300,0\n",
     r"north: 1e\+300 m for vessel 1 at sample 0 .* is not a position on Earth"),
    ("t_s,vessel,north_m,east_m,course_deg,speed_mps\n0,own,0,0,0,1e6\n0,ts,100,0,180,1\n10,own,10,0,0,1e6\n"
     "10,ts,90,0,180,1\n", r"speed: 1e\+06 m/s for vessel 0 at sample 0"),
    ("t_s,vessel,north_m,east_m\n0,own,0,0\n0,ts,100,0\n1,own,5000,0\n1,ts,90,0\n",
     r"speed: 5000 m/s for vessel 0 at sample 0"),
    ("t_s,vessel,north_m,east_m,course_deg,speed_mps\n0,own,0,0,0,5\n0,ts,100,0,180,5\n1,own,5000,0,0,5\n"
     "1,ts,90,0,180,5\n", r"north/east: 5000 m/s \(derived from the positions\) for vessel 0"),
])
def test_meaningless_tracks_are_refused(tmp_path, text, match):
    p = tmp_path / "deg.csv"
    p.write_text(text)
    with pytest.raises(ValueError, match=match):
        evaluate_file(p)


def test_tracks_in_metres_near_the_origin_are_scored(tmp_path):
    """Not refused as degrees: positions within +-90 m but moving at ship speeds."""
    p = tmp_path / "m.csv"
    p.write_text("t_s,vessel,north_m,east_m\n" + "".join(
        f"{k},own,{-80 + 2 * k},0\n{k},ts,{80 - 2 * k},1\n" for k in range(0, 81, 10)))
    evaluate_file(p)


def test_non_utf8_track_file_names_the_file_and_encoding(tmp_path):
    p = tmp_path / "latin.csv"
    p.write_bytes("t_s,vessel,north_m,east_m\n0,f\u00e6rge,0,0\n".encode("latin-1"))
    with pytest.raises(ValueError, match=r"latin\.csv: a track file must be UTF-8 text; byte 29 \(line 2\) is 0xe6"):
        evaluate_file(p)


# ------------------------------------------------------------------------------------------------ charts
RING_LATLON = [[63.4300, 10.4000], [63.4300, 10.4100], [63.4350, 10.4100], [63.4350, 10.4000], [63.4300, 10.4000]]


def geojson(path, ring):
    path.write_text(json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {}, "geometry": {"type": "Polygon", "coordinates": [ring]}}]}))
    return path


def chart_scenario(path):
    return {"name": "t", "simulation": {"dt_s": 0.5, "duration_s": 100},
            "origin_latlon": {"lat": 63.428, "lon": 10.39}, "chart": {"file": str(path)},
            "mpc": {"preset": "nidelva", "update_period_s": 5},
            "own_ship": {"name": "OS", "position_m": [0, 0], "course_deg": 0, "speed_mps": 2}}


def test_geojson_in_lat_lon_order_is_refused(tmp_path):
    bad = geojson(tmp_path / "latlon.geojson", RING_LATLON)
    with pytest.raises(ValueError, match=r"origin_latlon: the chart's coordinates look like \[lat, lon\] order"):
        scenario_from_dict(chart_scenario(bad))
    good = geojson(tmp_path / "lonlat.geojson", [[lon, lat] for lat, lon in RING_LATLON])
    assert len(scenario_from_dict(chart_scenario(good)).polygons) == 1


def test_swapped_order_needs_the_exchange_to_be_near():
    assert swapped_order([63.43], [10.40], 10.39, 63.428, 100e3)
    assert not swapped_order([10.40], [63.43], 10.39, 63.428, 100e3)          # right order
    assert not swapped_order([120.0], [10.0], 10.39, 63.428, 100e3)           # |lon| > 90: no latitude
    assert not swapped_order([-40.0], [20.0], 10.39, 63.428, 100e3)           # far either way
    assert great_circle_m(0.0, 0.0, 0.0, 1.0) == pytest.approx(111_195, rel=1e-4)


def test_a_file_path_is_checked_too(tmp_path):
    p = tmp_path / "s.yaml"
    import yaml

    d = chart_scenario(geojson(tmp_path / "latlon.geojson", RING_LATLON))
    p.write_text(yaml.safe_dump(d))
    with pytest.raises(ValueError, match=r"s\.yaml: origin_latlon: the chart's coordinates look like"):
        load_scenario(p)


# ------------------------------------------------------------------------------------------------ the solve
def _solve_scenario(method="psbmpc", **mpc):
    return {"name": "t", "simulation": {"dt_s": 0.5, "duration_s": 400},
            "mpc": {"preset": "nidelva", "update_period_s": 5, "method": method, **mpc},
            "own_ship": {"name": "OS", "position_m": [0, 0], "course_deg": 0, "speed_mps": 2},
            "targets": [{"name": "TS1", "position_m": [600, 0], "course_deg": 180, "speed_mps": 2}]}


@pytest.mark.parametrize("mpc, method, match", [
    (dict(config={"estimator": "mc", "n_samples": 10 ** 7}), "psbmpc",
     r"mpc\.config\.n_samples: one solve .* needs about 155 GiB of memory; the limit is 6\.4 GiB"),
    (dict(config={"estimator": "ce", "n_samples": 10 ** 6}), "psbmpc", r"mpc\.config\.n_samples: .* 66\.\d GiB"),
    (dict(sbmpc={"n_mc": 10 ** 6}), "psbmpc_2020", r"mpc\.sbmpc\.n_mc: .*n_mc = 1000000.* needs about 1\.19 TiB"),
    (dict(config={"T": 50000}), "psbmpc", r"mpc\.config\.T \(with dt_s and the behaviours\): one solve \(100000 "
                                          r"steps x 1024 behaviours x 5 obstacle scenarios"),
])
def test_solves_that_cannot_fit_are_refused_at_load(monkeypatch, mpc, method, match):
    monkeypatch.setenv("PSBMPC_MEMORY_LIMIT", "8GiB")
    t0 = time.perf_counter()
    with pytest.raises(limits.ResourceError, match=match):
        scenario_from_dict(_solve_scenario(method, **mpc), land_checks="off")
    assert time.perf_counter() - t0 < 5.0
    monkeypatch.setenv("PSBMPC_MEMORY_LIMIT", "4TiB")                     # a machine that has it: accepted
    monkeypatch.setenv("PSBMPC_UPDATE_TIME_LIMIT", "off")                 # (mc / ce at 1e6+ samples: minutes
    monkeypatch.setenv("PSBMPC_SIMULATION_TIME_LIMIT", "off")             # per update, refused by time)
    scenario_from_dict(_solve_scenario(method, **mpc), land_checks="off")


def test_planner_refuses_before_compiling(monkeypatch):
    import jax

    from psbmpc_jax import Obstacle, OwnShip, Planner, PlannerConfig, Situation

    own = OwnShip([0.0, 0.0, 0.0, 2.0], [[0.0, 0.0], [500.0, 0.0]], 2.0)
    sit = Situation(own, (Obstacle([60.0, 2.0, -2.0, 0.0], np.diag([4.0, 4.0, 0.1, 0.1]), n_ps=3),))
    monkeypatch.setenv("PSBMPC_MEMORY_LIMIT", "8GiB")
    with pytest.raises(limits.ResourceError, match=r"PlannerConfig\.n_samples .* 155 GiB"):
        Planner(PlannerConfig(estimator="mc", n_samples=10 ** 7)).prepare(sit, key=jax.random.key(0))


def _compiled_bytes(config, behaviours, terms=None, n_ps=5):
    """XLA's memory analysis (temporaries + outputs) of one compiled solve, and its padded sizes."""
    import jax

    from psbmpc_jax import Obstacle, OwnShip, Planner, Situation
    from psbmpc_jax.evaluate import DEFAULT_TERMS
    from psbmpc_jax.solve import solve_arrays

    terms = DEFAULT_TERMS if terms is None else terms
    own = OwnShip([0.0, 0.0, 0.0, 2.0], [[0.0, 0.0], [5000.0, 0.0]], 2.0)
    sit = Situation(own, (Obstacle([300.0, 5.0, -2.0, 0.0], np.diag([4.0, 4.0, 0.1, 0.1]), n_ps=n_ps),))
    inputs, state, params, samples = Planner(config, behaviours=behaviours, terms=terms).prepare(
        sit, key=jax.random.key(0))
    comp = jax.jit(solve_arrays, static_argnames=("config", "terms")).lower(
        inputs, state, params, samples, config=config, terms=terms).compile()
    ma = comp.memory_analysis()
    return (ma.temp_size_in_bytes + ma.output_size_in_bytes, int(inputs.behaviours.offsets.shape[0]),
            int(np.prod(np.shape(inputs.obstacles.probs))))


def test_solve_estimate_matches_the_compiled_memory():
    """The estimate against XLA's own analysis of the compiled solve (the fit's data: within 5 %; a linear
    model, so a wrong coefficient shows at once)."""
    from psbmpc_jax import PlannerConfig, paper_behaviours
    from psbmpc_jax.methods.sbmpc_family import SbmpcSettings, psbmpc2020_terms

    cases = [(PlannerConfig(T=300.0, dt=0.5), paper_behaviours(2), None, 0),
             (PlannerConfig(T=150.0, dt=0.5, estimator="mc", n_samples=40_000), paper_behaviours(1), None, 0),
             (PlannerConfig(T=150.0, dt=0.5), paper_behaviours(1),
              psbmpc2020_terms(SbmpcSettings(n_mc=2000), with_grounding=False), 2000)]
    for config, beh, terms, n_mc in cases:
        measured, n_b, n_os = _compiled_bytes(config, beh, terms, n_ps=1 if n_mc else 5)
        est = limits.solve_bytes(config, n_b, n_os, land=False, n_mc=n_mc)
        assert abs(est - measured) <= 0.05 * measured, (config, est, measured)


def test_padded_sizes_are_the_packing_capacities():
    from psbmpc_jax.packing import bucket, bucket_behaviours, bucket_scenarios

    for n_b, n_o, n_ps in ((39, 0, 1), (1014, 1, 5), (1015, 3, 11), (64, 5, 99)):
        assert limits.padded_sizes(n_b, n_o, n_ps) == (bucket_behaviours(n_b),
                                                        bucket(max(n_o, 1)) * bucket_scenarios(n_ps))
