"""The reliability suite: property-based tests (hypothesis) over the three ways data enters the library -- a
scenario file, a track file and the Python API -- asserting one of two outcomes for every input: a ``ValueError``
that names the field (file, row or column) it refuses, or a result that is finite and within its documented
range.  Never a crash of another type, a raw traceback from deep inside, or a silent nonsense result.

The examples are derandomised (the same inputs on every run), so the suite is reproducible in CI; a failure
prints the input that broke it."""

from __future__ import annotations

import copy
import math
import pathlib
import warnings

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings, strategies as st

from psbmpc_jax import Obstacle, OwnShip, Planner, PlannerConfig, Situation
from psbmpc_jax.evaltool.evaluate import evaluate_tracks
from psbmpc_jax.evaltool.tracks import load_tracks
from psbmpc_jax.scenario import scenario_from_dict

ROOT = pathlib.Path(__file__).resolve().parents[1]
PROPERTY = settings(max_examples=60, derandomize=True, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])

#: Values a careless or malicious file may hold where a number, a string or a list is expected.
WILD = st.one_of(
    st.sampled_from([float("nan"), float("inf"), -float("inf"), 0, -1, 1e300, -1e300, 1e-300, 7, 400, 360.0,
                     True, False, None, "", "abc", "5", [], [1], [[0, 0]], {}, {"x": 1}]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-10**12, max_value=10**12),
    st.text(max_size=8),
)


def _leaves(node, path=()):
    """Every (path, value) leaf of a scenario dict; list items are addressed by index."""
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _leaves(v, path + (k,))
    elif isinstance(node, list) and node and isinstance(node[0], (dict, list)):
        for i, v in enumerate(node):
            yield from _leaves(v, path + (i,))
    else:
        yield path, node


def _dotted(path) -> str:
    out = ""
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out


BASE = yaml.safe_load((ROOT / "scenarios" / "head_on.yaml").read_text())
BASE["simulation"]["duration_s"] = 60
LEAVES = [p for p, _ in _leaves(BASE) if p[0] not in ("name", "description")]


def _set(d, path, value):
    node = d
    for p in path[:-1]:
        node = node[p]
    node[path[-1]] = value


@PROPERTY
@given(path=st.sampled_from(LEAVES), value=WILD)
def test_a_scenario_field_set_to_anything_loads_or_is_refused_by_name(path, value):
    data = copy.deepcopy(BASE)
    _set(data, path, value)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            scenario = scenario_from_dict(data)
    except ValueError as exc:
        msg = str(exc)
        named = _dotted(path)
        # the field itself, or its parent when the value has the wrong shape for the parent (a waypoint list)
        parent = _dotted(path[:-1]) if isinstance(path[-1], int) else None
        assert named in msg or (parent and parent in msg), f"{named} = {value!r}: {msg}"
        return
    # loaded: what the simulator reads is finite and in its documented range
    assert math.isfinite(scenario.dt) and scenario.dt > 0
    assert math.isfinite(scenario.duration) and scenario.duration > 0
    assert isinstance(scenario.runs, int) and scenario.runs >= 1
    for ship in (scenario.own_ship, *scenario.targets):
        numbers = np.concatenate([np.ravel(ship.position), [ship.course, ship.speed, ship.U_d, ship.length,
                                                            ship.width], np.ravel(ship.waypoints)])
        assert np.all(np.isfinite(numbers)), ship
        assert ship.length > 0 and ship.width > 0 and 0 <= ship.speed and 0 <= ship.U_d, ship


def _track_csv(n_vessels: int, n: int) -> list[list[str]]:
    rows = []
    for t in range(n):
        for v in range(n_vessels):
            north = 2.0 * t * 5 if v == 0 else 600.0 - 2.0 * t * 5
            rows.append([str(5 * t), f"v{v}", f"{north:g}", f"{3.0 * v:g}"])
    return rows


CELL = st.sampled_from(["", "nan", "inf", "-inf", "1e400", "1e300", "abc", "-5", "0", "1e-300", " 7 ", "5,5"])


@PROPERTY
@given(n_vessels=st.integers(1, 3), n=st.integers(1, 40), edits=st.lists(
    st.tuples(st.integers(0, 10**6), st.integers(0, 3), CELL), max_size=3), drop_header=st.booleans())
def test_a_track_file_with_any_cells_scores_or_is_refused_naming_file_and_place(tmp_path, n_vessels, n, edits,
                                                                               drop_header):
    rows = _track_csv(n_vessels, n)
    for r, c, cell in edits:
        rows[r % len(rows)][c] = cell
    header = [] if drop_header else ["t_s,vessel,north_m,east_m"]
    path = tmp_path / "tracks.csv"
    path.write_text("\n".join(header + [",".join(r) for r in rows]) + "\n")
    try:
        tracks = load_tracks(path)
        ev = evaluate_tracks(tracks, "default")
    except ValueError as exc:
        msg = str(exc)
        assert "tracks.csv" in msg, msg
        return
    assert n_vessels >= 2 or not ev.encounters
    for enc in ev.encounters:
        for name in ("S_safety", "S_sit"):
            v = getattr(enc.scores, name)
            assert v is None or (math.isfinite(v) and 0.0 <= v <= 1.0), (name, v)


@pytest.fixture(scope="module")
def small_planner():
    return Planner(PlannerConfig(estimator="quadrature", T=30.0, dt=1.0))


NUMBER = st.one_of(st.sampled_from([float("nan"), float("inf"), -float("inf"), 0.0, -1.0, 1e9, 1e30, -1e30, 1e-30,
                                    7.0, 40.0, 400.0]),
                   st.floats(min_value=-1e6, max_value=1e6, allow_nan=False))

API_FIELDS = [("own", "state", i) for i in range(4)] + [("own", "U_d", None), ("own", "length", None),
                                                       ("own", "width", None)] + \
             [("obstacle", "state", i) for i in range(4)] + [("obstacle", "cov", i) for i in range(4)] + \
             [("obstacle", "length", None), ("obstacle", "weight", None), ("obstacle", "zeta", None)]


@settings(max_examples=40, derandomize=True, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(field=st.sampled_from(API_FIELDS), value=NUMBER)
def test_an_api_value_set_to_anything_plans_finitely_or_is_refused_by_name(small_planner, field, value):
    who, name, index = field
    own = dict(state=[0.0, 0.0, 0.0, 2.0], waypoints=[[0.0, 0.0], [2000.0, 0.0]], U_d=2.0, length=5.0, width=3.0)
    obs = dict(state=[300.0, 4.0, -2.0, 0.0], cov=np.diag([4.0, 4.0, 0.05, 0.05]), length=5.0, n_ps=3)
    target = own if who == "own" else obs
    if index is None:
        target[name] = value
    elif name == "cov":
        cov = np.array(target["cov"], float)
        cov[index, index] = value
        target["cov"] = cov
    else:
        vec = list(target[name])
        vec[index] = value
        target[name] = vec
    try:
        situation = Situation(OwnShip(**own), (Obstacle(**obs),), polygons=())
    except ValueError as exc:
        prefix = "own_ship" if who == "own" else "obstacle"
        assert f"{prefix}.{name}" in str(exc), str(exc)
        return
    result, _ = small_planner.plan(situation, small_planner.init_state())
    total = np.asarray(result.costs["total"])
    assert np.isfinite(total[result.best_index]), (field, value)
    assert np.all(np.isfinite(np.asarray(result.own_trajectories)[result.best_index])), (field, value)
