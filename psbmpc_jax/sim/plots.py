"""Figures of a closed-loop simulation (matplotlib is imported only inside these functions).

North-east maps are drawn north up: east on the horizontal axis, north on the vertical, equal aspect.
"""

from __future__ import annotations

import pathlib

import numpy as np

from ..plots import land_patch
from ..situation import polygon_rings

SHIP_COLORS = ("tab:red", "tab:green", "tab:blue", "tab:purple", "black", "tab:orange", "tab:brown", "tab:cyan")


def _ship_outline(n, e, chi, length, width, scale):
    """A pointed hull polygon (east, north) of the given size, scaled up by ``scale`` for visibility."""
    L, W = 0.5 * length * scale, 0.5 * width * scale
    body = np.array([[L, 0.0], [0.4 * L, W], [-L, W], [-L, -W], [0.4 * L, -W]])      # (forward, starboard)
    c, s = np.cos(chi), np.sin(chi)
    north = n + body[:, 0] * c - body[:, 1] * s
    east = e + body[:, 0] * s + body[:, 1] * c
    return np.stack([east, north], axis=1)


def _draw_land(ax, polygons):
    for poly in polygons:        # ring sets hold open rings: close them for the patch
        ax.add_patch(land_patch([np.vstack([r, r[:1]]) for r in map(np.asarray, polygon_rings(poly))]))


def plot_map(result, run: int = 0, ax=None, n_instants: int = 5, ship_scale: float | None = None):
    """Paper-Fig.-1/4a-style north-east plot of one run: land, every ship's trajectory, the ships at
    ``n_instants`` instants (numbered t1, t2, ...), the own-ship's route, and -- when the run is the
    snapshot run -- the candidate trajectories of that solve coloured by their cost."""
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection
    from matplotlib.colors import LogNorm

    sc = result.scenario
    if ax is None:
        _, ax = plt.subplots(figsize=(8, 7))
    states = result.states[run]
    xy = states[..., :2]
    span = float(np.max(np.ptp(xy.reshape(-1, 2), axis=0))) or 1.0
    scale = ship_scale or max(1.0, 0.025 * span / max(s.length for s in sc.ships))
    _draw_land(ax, sc.polygons)
    snap = result.snapshot
    if snap is not None and snap["run"] == run:
        traj = snap["own_trajectories"]                             # [B, N+1, 4]
        cost = np.asarray(snap["total_cost"], float)
        finite = np.isfinite(cost)
        lo = max(np.min(cost[finite]), 1e-3)
        segs = [np.stack([tr[:, 1], tr[:, 0]], axis=1) for tr in traj[finite]]
        order = np.argsort(-cost[finite])                            # cheapest drawn last (on top)
        lc = LineCollection([segs[i] for i in order], cmap="viridis_r",
                            norm=LogNorm(vmin=lo, vmax=max(np.max(cost[finite]), lo * 10)), lw=0.5, alpha=0.5,
                            zorder=2)
        lc.set_array(cost[finite][order])
        ax.add_collection(lc)
        best = traj[snap["best_index"]]
        ax.plot(best[:, 1], best[:, 0], "-", color="magenta", lw=1.6, zorder=4,
                label=f"chosen at t = {snap['t_s']:.0f} s")
        plt.colorbar(lc, ax=ax, shrink=0.7, label=f"candidate cost H (solve at t = {snap['t_s']:.0f} s)")
    route = sc.own_ship.waypoints
    ax.plot(route[:, 1], route[:, 0], ":", color="gray", lw=1.0, zorder=2, label="own-ship route")
    idx = np.linspace(0, len(result.t) - 1, n_instants).round().astype(int)
    for i, ship in enumerate(sc.ships):
        col = SHIP_COLORS[i % len(SHIP_COLORS)]
        ax.plot(xy[i, :, 1], xy[i, :, 0], "-", color=col, lw=1.2, zorder=3,
                label=f"{ship.name}{' (own-ship)' if i == 0 else ''}{' [PSB-MPC]' if ship.colav == 'psbmpc' else ''}")
        for n, k in enumerate(idx):
            hull = _ship_outline(*states[i, k, :3], ship.length, ship.width, scale)
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


def write_figures(result, out_dir, run: int = 0, dpi: int = 120) -> list[pathlib.Path]:
    """Write ``map.png``, ``distances.png`` and ``monte_carlo.png`` to ``out_dir``; returns the paths."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, fn in (("map.png", lambda ax: plot_map(result, run, ax)),
                     ("distances.png", lambda ax: plot_distances(result, run, ax)),
                     ("monte_carlo.png", lambda ax: plot_monte_carlo(result, ax))):
        fig, ax = plt.subplots(figsize=(8, 7) if name == "map.png" else (8, 4))
        fn(ax)
        fig.tight_layout()
        fig.savefig(out / name, dpi=dpi)
        plt.close(fig)
        paths.append(out / name)
    return paths
