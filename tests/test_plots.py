"""Figures of a simulation (run selection, course/speed, animation) and plot_plan for one solve, on synthetic
results (no solver involved: fast)."""

from __future__ import annotations

import types

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402
from PIL import Image  # noqa: E402

from psbmpc_jax.packing import PlanResult  # noqa: E402
from psbmpc_jax.plots import plot_plan  # noqa: E402
from psbmpc_jax.situation import Obstacle, OwnShip, Situation  # noqa: E402
from psbmpc_jax.sim.plots import animate_run, parse_runs, plot_course_speed, write_figures  # noqa: E402
from test_export import synthetic_result  # noqa: E402


@pytest.fixture(scope="module")
def result():
    res = synthetic_result(runs=3)
    B, N = 4, 20   # a snapshot solve of run 0 for the map's candidate trajectories
    traj = np.zeros((B, N + 1, 4))
    for b in range(B):
        traj[b, :, 0] = np.linspace(0, 40, N + 1)
        traj[b, :, 1] = np.linspace(0, 5.0 * (b - 1.5), N + 1)
    res.snapshot = {"t_s": 0.0, "run": 0, "best_index": 2, "own_trajectories": traj,
                    "total_cost": np.array([3.0, 1.0, 0.5, np.inf]), "obstacle_trajectories": [],
                    "manoeuvring": True}
    return res


def test_parse_runs():
    assert parse_runs("0,3,5") == [0, 3, 5] and parse_runs(" 2 , 2 ") == [2]
    assert parse_runs("all") is None and parse_runs("ALL", 3) == [0, 1, 2]
    for bad, msg in (("1,,3", "no empty items"), ("", "no empty items"), ("a", "integers"), ("-1", ">= 0")):
        with pytest.raises(ValueError, match=msg):
            parse_runs(bad)
    with pytest.raises(ValueError, match="run 3 does not exist: the simulation has 3 runs"):
        parse_runs("0,3", 3)


def test_write_figures_default_and_selected_runs(result, tmp_path):
    names = sorted(p.name for p in write_figures(result, tmp_path / "a", dpi=40))
    assert names == ["course_speed.png", "distances.png", "map.png", "monte_carlo.png"]
    names = sorted(p.name for p in write_figures(result, tmp_path / "b", runs="0,2", dpi=40))
    assert names == ["course_speed_run0.png", "course_speed_run2.png", "distances_run0.png", "distances_run2.png",
                     "map_run0.png", "map_run2.png", "monte_carlo.png"]
    for p in (tmp_path / "b").iterdir():
        assert p.stat().st_size > 3_000
    with pytest.raises(ValueError, match=r"run must be an integer in \[0, 3\)"):
        write_figures(result, tmp_path / "d", runs=[5])
    with pytest.raises(ValueError, match="run 7 does not exist"):
        write_figures(result, tmp_path / "d", runs="7")


def test_course_speed_panels(result):
    axes = plot_course_speed(result, 1)
    course, speed, offsets = axes
    assert len(course.lines) == len(speed.lines) == 2                  # both ships
    np.testing.assert_allclose(speed.lines[1].get_ydata(), result.states[1, 1, :, 3])
    assert len(offsets.lines) == 1                                     # the PSB-MPC own-ship's course offset
    assert offsets.lines[0].get_ydata()[0] == pytest.approx(30.0)
    plt.close("all")
    with pytest.raises(ValueError, match=r"run must be an integer in \[0, 3\)"):
        plot_course_speed(result, 3)


def test_animation_gif(result, tmp_path):
    paths = animate_run(result, 1, tmp_path / "anim.gif", max_frames=4, mp4=False)
    assert paths == [tmp_path / "anim.gif"]
    with Image.open(paths[0]) as im:
        assert im.format == "GIF" and im.n_frames == 4


def _fake_plan():
    """A PlanResult around a hand-made evaluation: 5 candidates (one infeasible), 1 obstacle x 3 scenarios."""
    B, T = 5, 21
    own = types.SimpleNamespace(x=np.zeros((T, B)), y=np.zeros((T, B)), chi=np.zeros((T, B)), U=np.ones((T, B)))
    for b in range(B):
        own.x[:, b] = np.linspace(0, 100, T)
        own.y[:, b] = np.linspace(0, 10.0 * (b - 2), T)
    o_shape = (T, 1, 3)
    obs = types.SimpleNamespace(x=np.zeros(o_shape), y=np.zeros(o_shape), chi=np.zeros(o_shape), U=np.ones(o_shape))
    for s in range(3):
        obs.x[:, 0, s] = np.linspace(150, 50, T)
        obs.y[:, 0, s] = np.linspace(0, 8.0 * (s - 1), T)
    total = np.array([4.0, 2.0, 0.7, 1.5, np.inf])
    ev = types.SimpleNamespace(best=np.int32(2), total=total, costs={"do": np.zeros(B), "path": total},
                               own=own, obstacles=obs)
    situation = Situation(OwnShip([0, 0, 0, 2], [[0, 0], [300, 0]], 2.0),
                          (Obstacle([150, 0, -2, 0], np.eye(4), n_ps=3),),
                          (np.array([[20.0, 30.0], [80.0, 30.0], [80.0, 60.0], [20.0, 60.0]]),))
    behaviours = np.zeros((B, 1, 2))
    behaviours[:, 0, 0] = 1.0
    behaviours[:, 0, 1] = np.radians([-30, -15, 0, 15, 30])
    return PlanResult(ev, situation, behaviours, 0.01, names=("total", "do", "path")), situation


def test_plot_plan(tmp_path):
    plan, situation = _fake_plan()
    ax = plot_plan(plan)                                               # polygons from the result's situation
    (lc,) = [c for c in ax.collections if isinstance(c, LineCollection)]
    assert len(lc.get_segments()) == 4                                  # the infinite-cost candidate left out
    chosen = [ln for ln in ax.lines if ln.get_label().startswith("chosen")]
    assert len(chosen) == 1 and np.allclose(chosen[0].get_xdata(), plan.own_trajectories[2, :, 1])
    assert sum(ln.get_linestyle() == "--" for ln in ax.lines) == 3      # the obstacle's 3 scenarios
    assert len(ax.patches) == 1                                        # the land polygon
    assert "behaviour 2" in ax.get_title()
    ax.figure.savefig(tmp_path / "plan.png")
    assert (tmp_path / "plan.png").stat().st_size > 10_000
    fig, ax2 = plt.subplots()
    assert plot_plan(plan, situation, ax=ax2, scenarios=False, title="t") is ax2
    assert sum(ln.get_linestyle() == "--" for ln in ax2.lines) == 0 and ax2.get_title() == "t"
    plt.close("all")
