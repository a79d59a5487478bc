"""Plotting (matplotlib is imported only here).

Charts are drawn north up: **east on the horizontal axis, north on the vertical**, equal aspect, metres in
the chart's local NED frame (the polygons' shapely (x, y) = (north, east) are swapped for drawing).
"""

from __future__ import annotations

import pathlib

import numpy as np

__all__ = ["land_patch", "plot_chart", "plot_candidates", "plot_plan", "write_rdp_figure"]


def _rings(poly):
    yield np.asarray(poly.exterior.coords)
    for r in poly.interiors:
        yield np.asarray(r.coords)


def land_patch(rings, *, facecolor="#d9c9a3", edgecolor="#6b5a3a", lw: float = 0.6, zorder: int = 1):
    """One filled patch of a polygon with holes, drawn north up: ``rings`` are closed (first point repeated at
    the end) ``[n, 2]`` (north, east) arrays, exterior first; holes are cut out (even-odd)."""
    from matplotlib.patches import PathPatch
    from matplotlib.path import Path

    verts, codes = [], []
    for ring in rings:
        xy = np.asarray(ring)[:, ::-1]  # (east, north)
        verts.append(xy)
        codes += [Path.MOVETO] + [Path.LINETO] * (len(xy) - 2) + [Path.CLOSEPOLY]
    return PathPatch(Path(np.vstack(verts), codes), facecolor=facecolor, edgecolor=edgecolor, lw=lw, zorder=zorder)


def plot_candidates(ax, trajectories, costs, best_index: int, *, label: str | None = None, lw: float = 0.5,
                    alpha: float = 0.5, colorbar: bool = True, colorbar_label: str = "candidate cost H"):
    """Draw own-ship candidate trajectories ``[B, N+1, >=2]`` (north, east, ...) north up, coloured by their
    total cost ``[B]`` (log scale, cheapest drawn on top; behaviours with a non-finite cost are left out) and
    the chosen one (``best_index``) in magenta.  Returns the LineCollection (None if no cost is finite)."""
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection
    from matplotlib.colors import LogNorm

    traj = np.asarray(trajectories, dtype=float)
    cost = np.asarray(costs, dtype=float)
    finite = np.isfinite(cost)
    lc = None
    if finite.any():
        lo = max(float(np.min(cost[finite])), 1e-3)
        hi = max(float(np.max(cost[finite])), lo * 10)
        segs = [np.stack([tr[:, 1], tr[:, 0]], axis=1) for tr in traj[finite]]
        order = np.argsort(-cost[finite])                  # cheapest drawn last (on top)
        lc = LineCollection([segs[i] for i in order], cmap="viridis_r", norm=LogNorm(vmin=lo, vmax=hi), lw=lw,
                            alpha=alpha, zorder=2)
        lc.set_array(np.maximum(cost[finite][order], lo))
        ax.add_collection(lc)
        if colorbar:
            plt.colorbar(lc, ax=ax, shrink=0.7, label=colorbar_label)
    best = traj[int(best_index)]
    ax.plot(best[:, 1], best[:, 0], "-", color="magenta", lw=1.6, zorder=4, label=label or "chosen")
    return lc


def plot_plan(result, situation=None, ax=None, *, scenarios: bool = True, title: str | None = None):
    """Draw one solve (a :class:`~psbmpc_jax.PlanResult` from :meth:`~psbmpc_jax.Planner.plan`), north up:
    the own-ship's candidate trajectories coloured by their total cost (log scale), the chosen one in
    magenta, each obstacle's prediction scenarios (dashed, one colour per obstacle), the land polygons and
    the own-ship's route.

    Args:
        result: the PlanResult.
        situation: the :class:`~psbmpc_jax.Situation` that was solved, for the polygons and the route
            (default: the one the result was computed from).
        ax: matplotlib axes (default: a new figure).
        scenarios: draw the obstacles' prediction scenarios.
        title: axes title (default: the chosen behaviour and its first maneuver).
    Returns the axes.

    Example::

        result, state = planner.plan(situation)
        ax = plot_plan(result)
        ax.figure.savefig("plan.png")
    """
    import matplotlib.pyplot as plt

    if situation is None:   # the situation the result was unpacked with (PlanResult keeps it)
        situation = getattr(result, "situation", None) or getattr(result, "_situation", None)
    if ax is None:
        _, ax = plt.subplots(figsize=(8, 7))
    if situation is not None:
        from .situation import polygon_rings

        for poly in situation.polygons:
            rings = [np.vstack([r, r[:1]]) for r in map(np.asarray, polygon_rings(poly))]
            ax.add_patch(land_patch(rings))
        wp = np.asarray(situation.own_ship.waypoints, dtype=float)
        ax.plot(wp[:, 1], wp[:, 0], ":", color="gray", lw=1.0, zorder=2, label="own-ship route")
    traj = result.own_trajectories
    plot_candidates(ax, traj, result.costs["total"], result.best_index,
                    label=f"chosen: behaviour {result.best_index}")
    ax.plot([traj[0, 0, 1]], [traj[0, 0, 0]], "o", color="magenta", ms=5, zorder=5)
    colours = ("tab:red", "tab:green", "tab:blue", "tab:purple", "tab:orange", "tab:brown", "tab:cyan")
    if scenarios:
        for i, obs in enumerate(result.obstacle_trajectories):
            col = colours[i % len(colours)]
            for s_idx, tr in enumerate(np.asarray(obs)):
                ax.plot(tr[:, 1], tr[:, 0], "--", color=col, lw=0.9, alpha=0.8, zorder=3,
                        label=f"obstacle {i} ({len(obs)} scenarios)" if s_idx == 0 else None)
            ax.plot([obs[0, 0, 1]], [obs[0, 0, 0]], "s", color=col, ms=5, zorder=5)
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    if title is None:
        u, chi = result.offsets[0]
        title = (f"behaviour {result.best_index}: first maneuver u = {u:g}, chi offset = {np.degrees(chi):+.0f} deg, "
                 f"total cost {result.costs['total'][result.best_index]:.3g}")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7, loc="best")
    return ax


def plot_chart(chart, ax=None, simplified=None, *, own_ship=None, d_so=None, land_color="#d9c9a3",
               edge_color="#6b5a3a", simplified_color="#d62728", show_vertices: bool = False,
               simplified_vertices: bool = True,
               label_ids: bool = False, title: str | None = None):
    """Draw ``chart`` (filled polygons) and, optionally, ``simplified`` (a chart with the same origin, e.g. the
    RDP result) as an overlay outline with its vertices.

    Args:
        chart: a :class:`psbmpc_jax.charts.Chart`.
        ax: matplotlib axes (default: a new figure).
        simplified: an RDP-simplified chart to overlay (red outline and vertex dots).
        own_ship: optional local (north, east) position to mark; with ``d_so`` the range circle too.
        show_vertices: also mark the vertices of ``chart``.
        simplified_vertices: mark the vertices of ``simplified`` (default True).
        label_ids: write each polygon's file index at its representative point.
    Returns the axes.
    """
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(7, 7))
    for poly, pid in zip(chart.polygons, chart.ids):
        ax.add_patch(land_patch(_rings(poly), facecolor=land_color, edgecolor=edge_color))
        if show_vertices:
            for ring in _rings(poly):
                ax.plot(ring[:-1, 1], ring[:-1, 0], ".", color="black", ms=3.0, zorder=2)
        if label_ids:
            rp = poly.representative_point()
            ax.annotate(str(pid), (rp.y, rp.x), fontsize=6, ha="center", va="center", zorder=4)
    if simplified is not None:
        first = True
        for poly in simplified.polygons:
            for ring in _rings(poly):
                ax.plot(ring[:, 1], ring[:, 0], "-", color=simplified_color, lw=0.9, zorder=3,
                        label="RDP" if first else None)
                if simplified_vertices:
                    ax.plot(ring[:-1, 1], ring[:-1, 0], "o", mec=simplified_color, mfc="none", ms=4.5, mew=0.9,
                            zorder=3)
                first = False
    if own_ship is not None:
        n, e = own_ship
        ax.plot([e], [n], "o", color="tab:blue", ms=5, zorder=5, label="own-ship")
        if d_so is not None:
            t = np.linspace(0, 2 * np.pi, 256)
            ax.plot(e + d_so * np.sin(t), n + d_so * np.cos(t), "--", color="tab:blue", lw=0.8, zorder=5,
                    label=f"d_so = {d_so:g} m")
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    if title:
        ax.set_title(title, fontsize=9)
    return ax


def write_rdp_figure(path="docs/figures/trondheim_rdp.png", eps: float = 2.0, *, dpi: int = 130) -> pathlib.Path:
    """Write the RDP illustration for the shipped Trondheim chart: (a) the whole chart with its RDP result
    (eps) and the Nidelva own-ship position with the d_so = 200 m circle, (b) the largest polygon (the
    21 961-vertex land around Nidelva) before/after, (c) a 400 m detail of its river bank showing the
    vertices.  Returns the path."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    from .charts import nidelva_own_ship_ned, trondheim_chart
    from .rdp import simplify_chart

    chart = trondheim_chart("psbmpc")
    simp = simplify_chart(chart, eps, anchor="open")
    own = nidelva_own_ship_ned(chart)
    big = int(np.argmax(chart.n_vertices))
    sub = lambda c, idx: type(c)(tuple(c.polygons[i] for i in idx), c.origin, c.crs, c.source,
                                 tuple(c.ids[i] for i in idx), tuple(c.layers[i] for i in idx), c.report)

    fig, axes = plt.subplots(1, 3, figsize=(16, 6.2), gridspec_kw=dict(width_ratios=[1.25, 1.0, 1.0]))
    plot_chart(chart, axes[0], simp, own_ship=own, d_so=200.0, simplified_vertices=False,
               title=f"Trondheim chart (61 polygons, {chart.total_vertices} vertices) and RDP eps = {eps:g} m "
                     f"({simp.total_vertices} vertices)")
    n0, e0 = own
    axes[0].set_xlim(e0 - 3200, e0 + 2000)
    axes[0].set_ylim(n0 - 2600, n0 + 1800)
    axes[0].legend(loc="lower right", fontsize=7)

    pb, ps = sub(chart, [big]), sub(simp, [big])
    plot_chart(pb, axes[1], ps, simplified_vertices=False, title=f"largest polygon (file index {chart.ids[big]}): "
                                     f"{chart.n_vertices[big]} -> {simp.n_vertices[big]} vertices")

    # detail: a 400 m window on the river bank of the largest polygon near the own-ship
    ring = np.asarray(chart.polygons[big].exterior.coords)
    k = int(np.argmin(np.hypot(ring[:, 0] - (n0 - 700), ring[:, 1] - (e0 - 300))))
    cn, ce = ring[k]
    plot_chart(pb, axes[2], ps, show_vertices=True,
               title=f"detail (400 m): original vertices (black) and RDP eps = {eps:g} m (red circles)")
    axes[2].set_xlim(ce - 200, ce + 200)
    axes[2].set_ylim(cn - 200, cn + 200)
    axes[1].add_patch(matplotlib.patches.Rectangle((ce - 200, cn - 200), 400, 400, fill=False, lw=1.0,
                                                   color="black", zorder=6))
    fig.suptitle("psbmpc_jax: Nidelva chart (WGS 84 / UTM 32N, local NED about the 'piren' origin), "
                 "Ramer-Douglas-Peucker simplification", fontsize=10)
    fig.tight_layout()
    out = pathlib.Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=dpi)
    plt.close(fig)
    return out


if __name__ == "__main__":  # pragma: no cover
    print(write_rdp_figure())
