"""experiments/nidelva_refinement/stop_analysis.py: its term decomposition (why the grid search stops) on
hand-made costs."""

import importlib.util
import pathlib

import numpy as np
import pytest

SCRIPT = pathlib.Path(__file__).resolve().parents[1] / "experiments" / "nidelva_refinement" / "stop_analysis.py"


@pytest.fixture(scope="module")
def script():
    spec = importlib.util.spec_from_file_location("nidelva_stop_analysis", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def update(costs):
    """One update's (total, {term: [B]}) from rows per behaviour, plus one padded behaviour (+inf)."""
    names = ("colregs", "do", "path", "so")
    parts = {k: np.array([row[i] for row in costs] + [np.inf]) for i, k in enumerate(names)}
    return sum(parts.values()), parts


def test_why_stop_decomposes_the_gap_to_the_cheapest_moving_behaviour(script):
    # behaviours [B, n_M, 2]: 0 stops, 1 and 2 move (speed factor 1, 0.5), 3 slows to just under the threshold
    behaviours = np.array([[[0.0, 0.0]], [[1.0, 0.0]], [[0.5, 0.3]], [[0.04, 0.0]]])
    seen = [
        # update 0, run 0: the grid stops; cheapest mover is 2 (total 6 against 1's 7); collision decides
        update([(0, 1, 2, 0), (0, 5, 1, 1), (0, 4, 1, 1), (9, 9, 9, 9)]),
        # update 0, run 1: the grid moves (behaviour 1): not counted
        update([(0, 1, 2, 0), (0, 0, 1, 0), (0, 4, 1, 1), (9, 9, 9, 9)]),
        # update 1, run 0: the grid stops; the only finite mover is 1; grounding decides
        update([(1, 0, 3, 0), (1, 0.5, 1, 4), (np.inf, 0, 0, 0), (9, 9, 9, 9)]),
        # update 1, run 1: the grid "stops" with behaviour 3 (0.04 < 0.05); COLREGS decides
        update([(9, 9, 9, 9), (3, 0, 1, 0), (4, 0, 1, 0), (0, 0, 2, 0)]),
    ]
    best = np.array([[0, 1], [0, 3]])
    stopped = np.array([[False, False], [True, True]])
    why = script.why_stop(seen, behaviours, best, stopped)
    moving, still = why["moving"], why["already_stopped"]
    assert moving["updates"] == 1 and still["updates"] == 2
    assert moving["decided_by"] == {"colregs": 0, "do": 1, "path": 0, "so": 0}
    assert moving["median_gap"] == pytest.approx(6 - 3)
    assert moving["median_term_gap"] == {"colregs": 0.0, "do": 3.0, "path": -1.0, "so": 1.0}
    assert still["decided_by"] == {"colregs": 1, "do": 0, "path": 0, "so": 1}
    assert still["updates_where_term_favours_stop"] == {"colregs": 1, "do": 1, "path": 0, "so": 1}
    assert still["median_term_gap"]["path"] == pytest.approx(np.median([1 - 3, 1 - 2]))


def test_why_stop_refuses_a_total_that_is_not_the_sum_of_its_terms(script):
    behaviours = np.array([[[0.0, 0.0]], [[1.0, 0.0]]])
    total, parts = update([(0, 1, 2, 0), (0, 5, 1, 1)])
    with pytest.raises(RuntimeError, match="not the sum of its terms"):
        script.why_stop([(total + 1.0, parts)], behaviours, np.array([[0]]), np.array([[False]]))


def test_why_stop_with_no_stop_counts_nothing(script):
    behaviours = np.array([[[0.0, 0.0]], [[1.0, 0.0]]])
    why = script.why_stop([update([(0, 1, 2, 0), (0, 0, 1, 0)])], behaviours, np.array([[1]]),
                          np.array([[False]]))
    assert why["moving"] == {"updates": 0} and why["already_stopped"] == {"updates": 0}
