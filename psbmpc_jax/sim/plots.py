"""Figures of a closed-loop simulation (matplotlib is imported only inside these functions).

North-east maps are drawn north up: east on the horizontal axis, north on the vertical, equal aspect.
"""

from __future__ import annotations

import contextlib
import pathlib

import numpy as np

from ..plots import land_patch, plot_candidates
from ..safe_io import OutputError, atomic_open, file_output_problem
from ..situation import polygon_rings

__all__ = ["SHIP_COLORS", "plot_map", "plot_distances", "plot_course_speed", "plot_course_speed_compare",
           "plot_monte_carlo", "write_figures", "animate_run", "parse_runs"]

SHIP_COLORS = ("tab:red", "tab:green", "tab:blue", "tab:purple", "black", "tab:orange", "tab:brown", "tab:cyan")


def _ship_outline(n, e, chi, length, width, scale):
    """A pointed hull polygon (east, north) of the given size, scaled up by ``scale`` for visibility."""
    L, W = 0.5 * length * scale, 0.5 * width * scale
    body = np.array([[L, 0.0], [0.4 * L, W], [-L, W], [-L, -W], [0.4 * L, -W]])      # (forward, starboard)
    c, s = np.cos(chi), np.sin(chi)
    north = n + body[:, 0] * c - body[:, 1] * s
    east = e + body[:, 0] * s + body[:, 1] * c
    return np.stack([east, north], axis=1)


#: Half-size [m, before scaling] of the diamond a point target (length_m: 0) is drawn as.
POINT_MARK_M = 1.0


def _hull(ship, state, scale):
    """The outline of ``ship`` at ``state`` (north, east, chi): its hull, or a diamond for a point target."""
    if getattr(ship, "is_point", False):
        r = POINT_MARK_M * scale
        c, s = np.cos(state[2]), np.sin(state[2])
        body = np.array([[r, 0.0], [0.0, r], [-r, 0.0], [0.0, -r]])                  # (forward, starboard)
        return np.stack([state[1] + body[:, 0] * s + body[:, 1] * c, state[0] + body[:, 0] * c - body[:, 1] * s],
                        axis=1)
    return _ship_outline(state[0], state[1], state[2], ship.length, ship.width, scale)


def _ship_label(ship, i: int, method) -> str:
    """``name (own-ship) [method]`` / ``name [method]`` / ``name (point)``."""
    text = ship.name + (" (own-ship)" if i == 0 else "")
    if i == 0 and ship.colav != "none":
        text += f" [{method or ship.colav}]"
    elif ship.colav != "none":
        text += " [PSB-MPC]" if ship.colav == "psbmpc" else f" [{ship.colav}]"
    return text + (" (point)" if getattr(ship, "is_point", False) else "")


def _draw_land(ax, polygons):
    for poly in polygons:        # ring sets hold open rings: close them for the patch
        ax.add_patch(land_patch([np.vstack([r, r[:1]]) for r in map(np.asarray, polygon_rings(poly))]))


def plot_map(result, run: int = 0, ax=None, n_instants: int = 5, ship_scale: float | None = None):
    """Paper-Fig.-1/4a-style north-east plot of one run: land, every ship's trajectory, the ships at
    ``n_instants`` instants (numbered t1, t2, ...), the own-ship's route, and -- when the run is the
    snapshot run -- the candidate trajectories of that solve coloured by their cost."""
    import matplotlib.pyplot as plt

    sc = result.scenario
    _check_run(result, run)
    if ax is None:
        _, ax = plt.subplots(figsize=(8, 7))
    states = result.states[run]
    xy = states[..., :2]
    span = float(np.max(np.ptp(xy.reshape(-1, 2), axis=0))) or 1.0
    scale = ship_scale or max(1.0, 0.025 * span / max(s.length for s in sc.ships))
    _draw_land(ax, sc.polygons)
    snap = result.snapshot
    if snap is not None and snap["run"] == run:
        plot_candidates(ax, snap["own_trajectories"], snap["total_cost"], snap["best_index"],
                        label=f"chosen at t = {snap['t_s']:.0f} s",
                        colorbar_label=f"candidate cost H (solve at t = {snap['t_s']:.0f} s)")
    route = sc.own_ship.waypoints
    ax.plot(route[:, 1], route[:, 0], ":", color="gray", lw=1.0, zorder=2, label="own-ship route")
    idx = np.linspace(0, len(result.t) - 1, n_instants).round().astype(int)
    for i, ship in enumerate(sc.ships):
        col = SHIP_COLORS[i % len(SHIP_COLORS)]
        ax.plot(xy[i, :, 1], xy[i, :, 0], "-", color=col, lw=1.2, zorder=3,
                label=_ship_label(ship, i, getattr(result, "method", None)))
        for n, k in enumerate(idx):
            hull = _hull(ship, states[i, k, :3], scale)
            ax.fill(hull[:, 0], hull[:, 1], color=col, alpha=0.35 + 0.65 * n / max(len(idx) - 1, 1), zorder=5)
            if i == 0:
                ax.annotate(f"t{n + 1}", (xy[i, k, 1], xy[i, k, 0]), textcoords="offset points", xytext=(6, 6),
                            fontsize=7, zorder=6)
    ax.set_aspect("equal")
    pad = 0.08 * span
    lo, hi = xy.reshape(-1, 2).min(axis=0) - pad, xy.reshape(-1, 2).max(axis=0) + pad
    widen = np.maximum(0.0, 0.6 * np.max(hi - lo) - (hi - lo)) / 2      # no sliver-shaped maps
    lo, hi = lo - widen, hi + widen
    ax.set_xlim(lo[1], hi[1])
    ax.set_ylim(lo[0], hi[0])
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    times = ", ".join(f"t{n + 1} = {result.t[k]:.0f} s" for n, k in enumerate(idx))
    ax.set_title(f"{sc.name}, run {run}: {times}\n(ships drawn ×{scale:.0f})", fontsize=8)
    ax.legend(fontsize=7, loc="best")
    return ax


def plot_distances(result, run: int = 0, ax=None):
    """Distance from the own-ship to every target and to land over time (paper Fig. 4b style)."""
    import matplotlib.pyplot as plt

    from .metrics import distance_to_land

    sc = result.scenario
    _check_run(result, run)
    if ax is None:
        _, ax = plt.subplots(figsize=(8, 4))
    own = result.states[run, 0, :, :2]
    for i, ship in enumerate(sc.targets, start=1):
        d = np.hypot(*(result.states[run, i, :, :2] - own).T)
        ax.plot(result.t, d, color=SHIP_COLORS[i % len(SHIP_COLORS)], label=f"to {ship.name}")
    if sc.polygons:
        ax.plot(result.t, distance_to_land(own, sc.polygons), color="#8c6d31", ls="--", label="to land")
    ax.axhline(sc.d_collision, color="red", lw=1.0, label=f"collision distance {sc.d_collision:g} m")
    ax.set_yscale("log")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("distance [m]")
    ax.set_title(f"{sc.name}, run {run}: own-ship distances", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)
    return ax


def plot_monte_carlo(result, ax=None):
    """Box plots of the minimum distances over all runs, per target and to land (paper Fig. 4c style)."""
    import matplotlib.pyplot as plt

    sc = result.scenario
    if ax is None:
        _, ax = plt.subplots(figsize=(max(4, 1.4 * (len(sc.targets) + 1)), 4))
    data, labels = [], []
    for i, ship in enumerate(sc.targets):
        data.append([m["targets"][i]["min_distance_m"] for m in result.metrics])
        labels.append(ship.name)
    if sc.polygons:
        data.append([m["min_distance_land_m"] for m in result.metrics])
        labels.append("land")
    if data:
        ax.boxplot(data, showmeans=True)
        ax.set_xticks(range(1, len(labels) + 1), labels)
    ax.axhline(sc.d_collision, color="red", lw=1.0, label=f"collision distance {sc.d_collision:g} m")
    ax.set_ylabel("minimum distance [m]")
    ax.set_title(f"{sc.name}: minimum distances over {len(result.metrics)} runs", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(True, axis="y", alpha=0.3)
    return ax


def plot_course_speed(result, run: int = 0, axes=None):
    """Course and speed of every ship over time, and the offsets each ship with collision avoidance applied
    at its MPC updates (course offset and speed factor; PSB-MPC holds them until the next update, the gradient
    methods follow their per-step sequences in between).

    Args:
        axes: three matplotlib axes (course, speed, offsets), default a new figure.
    Returns the three axes."""
    import matplotlib.pyplot as plt

    sc = result.scenario
    _check_run(result, run)
    if axes is None:
        _, axes = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
    ax_c, ax_u, ax_o = axes
    states = result.states[run]
    ax_o2 = None   # twin axis of the speed factors, made with the first PSB-MPC ship
    for i, ship in enumerate(sc.ships):
        col = SHIP_COLORS[i % len(SHIP_COLORS)]
        label = f"{ship.name}{' (own-ship)' if i == 0 else ''}"
        ax_c.plot(result.t, np.degrees(np.unwrap(states[i, :, 2])), color=col, lw=1.1, label=label)
        ax_u.plot(result.t, states[i, :, 3], color=col, lw=1.1, label=label)
        off = result.offsets[run, i]
        if np.isfinite(off[:, 0]).any():
            t_step = np.append(result.solve_t, result.t[-1])
            ax_o.step(t_step, np.degrees(np.append(off[:, 1], off[-1, 1])), where="post", color=col, lw=1.1,
                      label=f"{ship.name}: course offset")
            if ax_o2 is None:
                ax_o2 = ax_o.twinx()
                ax_o2.set_ylabel("speed factor u (dotted)")
                ax_o2.set_ylim(-0.05, 1.05)
            ax_o2.step(t_step, np.append(off[:, 0], off[-1, 0]), where="post", color=col, lw=0.9, ls=":",
                       label=f"{ship.name}: speed factor")
    ax_c.set_ylabel("course [deg]")
    ax_u.set_ylabel("speed [m/s]")
    ax_o.set_ylabel("course offset [deg]")
    ax_o.set_xlabel("t [s]")
    ax_c.set_title(f"{sc.name}, run {run}: course, speed and applied MPC offsets", fontsize=9)
    ax_c.legend(fontsize=7, loc="best")
    if ax_o.lines:
        ax_o.legend(fontsize=7, loc="upper left")
    else:
        ax_o.text(0.5, 0.5, "no ship runs collision avoidance", transform=ax_o.transAxes, ha="center",
                  va="center")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    return axes


def plot_course_speed_compare(results, run: int = 0, labels=None, axes=None):
    """The own-ship's course and speed over time in several simulations of the same scenario, overlaid -- e.g.
    the same file run with ``--method smooth_sbmpc`` and ``--method sbmpc_init`` (in the style of Fig. 15 of Mahipala
    & Johansen 2024).

    Args:
        results: :class:`~psbmpc_jax.sim.SimulationResult` s, or a mapping label -> result.
        run: the run drawn of each.
        labels: one per result (default: the mapping's keys, else each result's method).
        axes: two matplotlib axes (course, speed), default a new figure.
    Returns the two axes."""
    import matplotlib.pyplot as plt

    if isinstance(results, dict):
        labels = list(results) if labels is None else list(labels)
        results = list(results.values())
    results = list(results)
    if not results:
        raise ValueError("results must hold at least one simulation result")
    labels = [str(getattr(r, "method", None) or "none") for r in results] if labels is None else list(labels)
    if len(labels) != len(results):
        raise ValueError(f"labels must have one entry per result ({len(results)}), got {len(labels)}")
    if axes is None:
        _, axes = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True)
    ax_c, ax_u = axes
    for n, (res, label) in enumerate(zip(results, labels)):
        _check_run(res, run)
        own = res.states[run, 0]
        col = SHIP_COLORS[(n + 2) % len(SHIP_COLORS)]
        course = np.degrees(np.unwrap(own[:, 2]))
        course -= 360.0 * np.floor(course[0] / 360.0)          # the first course in [0, 360)
        ax_c.plot(res.t, course, color=col, lw=1.2, label=label)
        ax_u.plot(res.t, own[:, 3], color=col, lw=1.2, label=label)
    ax_c.set_ylabel("course [deg]")
    ax_u.set_ylabel("speed [m/s]")
    ax_u.set_xlabel("t [s]")
    ax_c.set_title(f"{results[0].scenario.name}, run {run}: own-ship course and speed", fontsize=9)
    ax_c.legend(fontsize=7, loc="best")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    return axes


def _check_run(result, run: int) -> None:
    n = result.states.shape[0]
    if isinstance(run, bool) or not isinstance(run, (int, np.integer)) or not 0 <= run < n:
        raise ValueError(f"run must be an integer in [0, {n}) (the simulation has {n} runs), got {run!r}")


def parse_runs(text: str, n_runs: int | None = None) -> list[int] | None:
    """Runs to draw from text: ``"all"`` (None: every run, resolved by :func:`write_figures`) or a
    comma-separated list of run indices such as ``"0,3,5"``.  With ``n_runs`` the indices are checked and
    ``"all"`` becomes ``range(n_runs)``.  Raises ValueError saying what is allowed."""
    text = str(text).strip()
    if text.lower() == "all":
        return None if n_runs is None else list(range(n_runs))
    items = [s.strip() for s in text.split(",")]
    if not text or any(s == "" for s in items):
        raise ValueError(f"expected 'all' or comma-separated run indices such as 0,3,5 (no empty items), "
                         f"got {text!r}")
    runs = []
    for s in items:
        try:
            v = int(s)
        except ValueError:
            raise ValueError(f"expected 'all' or run indices (integers >= 0) such as 0,3,5, got {s!r}") from None
        if v < 0:
            raise ValueError(f"run indices must be >= 0, got {v}")
        if n_runs is not None and v >= n_runs:
            raise ValueError(f"run {v} does not exist: the simulation has {n_runs} run{'s' if n_runs != 1 else ''} "
                             f"(0..{n_runs - 1})")
        if v not in runs:
            runs.append(v)
    return runs


def write_figures(result, out_dir, run: int = 0, dpi: int = 120, *, runs=None) -> list[pathlib.Path]:
    """Write the figures to ``out_dir``; returns the paths.

    Per drawn run: ``map.png`` (:func:`plot_map`), ``distances.png`` (:func:`plot_distances`) and
    ``course_speed.png`` (:func:`plot_course_speed`); once: ``monte_carlo.png`` (:func:`plot_monte_carlo`).

    Args:
        run: the run drawn when ``runs`` is None (file names without a run suffix).
        runs: run indices, or ``"all"`` / a text such as ``"0,3,5"`` (:func:`parse_runs`): each drawn run's
            figures get the suffix ``_run<r>`` (``map_run3.png``, ...).
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    n_runs = result.states.shape[0]
    if isinstance(runs, str):
        runs = parse_runs(runs, n_runs)
    if runs is None:
        chosen, suffix = [run], lambda r: ""
    else:
        chosen, suffix = list(runs), lambda r: f"_run{r}"
    for r in chosen:
        _check_run(result, r)
    out = pathlib.Path(out_dir)
    problem = file_output_problem(out / "monte_carlo.png")      # a file in the way, no permission: say so
    if problem:
        raise OutputError(f"write_figures: {problem}")
    out.mkdir(parents=True, exist_ok=True)
    paths = []

    def save(fig, name):
        fig.tight_layout()
        with atomic_open(out / name, "wb") as fh:               # complete or absent, never a partial PNG
            fig.savefig(fh, dpi=dpi, format="png")
        plt.close(fig)
        paths.append(out / name)

    for r in chosen:
        fig, ax = plt.subplots(figsize=(8, 7))
        plot_map(result, r, ax)
        save(fig, f"map{suffix(r)}.png")
        fig, ax = plt.subplots(figsize=(8, 4))
        plot_distances(result, r, ax)
        save(fig, f"distances{suffix(r)}.png")
        fig, axes = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
        plot_course_speed(result, r, axes)
        save(fig, f"course_speed{suffix(r)}.png")
    fig, ax = plt.subplots(figsize=(8, 4))
    plot_monte_carlo(result, ax)
    save(fig, "monte_carlo.png")
    return paths


def animate_run(result, run: int = 0, path="animation.gif", *, fps: int = 10, max_frames: int = 120,
                dpi: int = 80, mp4: bool | None = None) -> list[pathlib.Path]:
    """Animate one run north up: land, routes, every ship's track so far and its hull (scaled up for
    visibility), the time in the title.  Writes ``path`` as a GIF (matplotlib's PillowWriter) and, when
    ffmpeg is installed (``mp4=None``) or ``mp4=True``, the same animation as MP4 next to it.

    Args:
        fps: frames per second of the files.
        max_frames: at most this many frames, evenly spaced over the run (the last step always included).
    Returns the written paths."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    from matplotlib import animation

    _check_run(result, run)
    if max_frames < 2:
        raise ValueError(f"max_frames must be >= 2, got {max_frames}")
    sc = result.scenario
    path = pathlib.Path(path)
    problem = file_output_problem(path)
    if problem:
        raise OutputError(f"animate_run: {problem}")
    path.parent.mkdir(parents=True, exist_ok=True)
    states = result.states[run]
    xy = states[..., :2]
    K1 = states.shape[1]
    frames = np.unique(np.linspace(0, K1 - 1, min(max_frames, K1)).round().astype(int))
    span = float(np.max(np.ptp(xy.reshape(-1, 2), axis=0))) or 1.0
    scale = max(1.0, 0.025 * span / max(s.length for s in sc.ships))

    fig, ax = plt.subplots(figsize=(6.4, 5.6))
    _draw_land(ax, sc.polygons)
    tracks, hulls = [], []
    for i, ship in enumerate(sc.ships):
        col = SHIP_COLORS[i % len(SHIP_COLORS)]
        route = ship.waypoints
        ax.plot(route[:, 1], route[:, 0], ":", color=col, lw=0.8, alpha=0.6, zorder=2)
        (line,) = ax.plot([], [], "-", color=col, lw=1.2, zorder=3, label=ship.name + (" (own-ship)" if i == 0 else ""))
        tracks.append(line)
        hull = plt.Polygon(np.zeros((4 if getattr(ship, "is_point", False) else 5, 2)), closed=True, color=col,
                           alpha=0.9, zorder=5)
        ax.add_patch(hull)
        hulls.append(hull)
    pad = 0.08 * span
    lo, hi = xy.reshape(-1, 2).min(axis=0) - pad, xy.reshape(-1, 2).max(axis=0) + pad
    widen = np.maximum(0.0, 0.6 * np.max(hi - lo) - (hi - lo)) / 2
    lo, hi = lo - widen, hi + widen
    ax.set_xlim(lo[1], hi[1])
    ax.set_ylim(lo[0], hi[0])
    ax.set_aspect("equal")
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    ax.legend(fontsize=7, loc="upper right")
    title = ax.set_title("", fontsize=9)

    def draw(k):
        for i, ship in enumerate(sc.ships):
            tracks[i].set_data(xy[i, : k + 1, 1], xy[i, : k + 1, 0])
            hulls[i].set_xy(_hull(ship, states[i, k, :3], scale))
        title.set_text(f"{sc.name}, run {run}: t = {result.t[k]:.0f} s (ships drawn x{scale:.0f})")
        return tracks + hulls + [title]

    writers: list[tuple[pathlib.Path, animation.AbstractMovieWriter]] = [(path, animation.PillowWriter(fps=fps))]
    if (animation.writers.is_available("ffmpeg") if mp4 is None else mp4):
        writers.append((path.with_suffix(".mp4"), animation.FFMpegWriter(fps=fps)))
    try:
        with contextlib.ExitStack() as stack:   # one pass over the frames feeds every writer
            for target, writer in writers:
                stack.enter_context(writer.saving(fig, str(target), dpi))
            for k in frames:
                draw(int(k))
                for _, writer in writers:
                    writer.grab_frame()
    finally:
        plt.close(fig)
    return [target for target, _ in writers]
