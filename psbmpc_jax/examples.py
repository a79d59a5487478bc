"""Built-in example situations (no chart needed)."""

from __future__ import annotations

import numpy as np

from .situation import Obstacle, OwnShip, Situation


def paper_head_on(n_ps: int = 5, n_obstacles: int = 2) -> Situation:
    """Nidelva-like river head-on at paper scale (Sec. IV-C, Table 1), without the chart.

    Own-ship at the origin heading north (upstream) at 2 m/s on a straight route; ``n_obstacles`` vessels
    (default 2) coming downstream (south) at 2 m/s, 5 m long, staggered 150 m apart and a few metres
    either side of the own-ship's track, each with a conservative tracker covariance."""
    if n_obstacles < 0:
        raise ValueError(f"n_obstacles must be >= 0, got {n_obstacles}")
    own = OwnShip(state=np.array([0.0, 0.0, 0.0, 2.0]), waypoints=np.array([[0.0, 0.0], [2000.0, 0.0]]), U_d=2.0,
                  length=5.0, width=3.0)
    cov = np.diag([4.0, 4.0, 0.05, 0.05])
    obstacles = []
    for i in range(n_obstacles):
        north = 250.0 + 150.0 * i
        east = (-1.0) ** i * 4.0
        obstacles.append(Obstacle(state=np.array([north, east, -2.0, 0.0]), cov=cov, length=5.0, width=3.0, n_ps=n_ps))
    return Situation(own, tuple(obstacles))


def nidelva_polygons(eps: float = 2.0, n_so: int = 13, rdp: bool = True):
    """The paper's Table 2 polygons (Trondheim chart, local NED about the 'piren' origin) in Table 2 order,
    the first ``n_so`` of them, simplified with RDP at ``eps`` metres (``rdp=False``: as loaded).

    Returns (ring sets for :class:`Situation`, the chart they came from)."""
    from .charts import TABLE2_FILE_INDICES, Chart, to_ring_sets, trondheim_chart
    from .rdp import simplify_chart

    if not 1 <= n_so <= len(TABLE2_FILE_INDICES):
        raise ValueError(f"n_so must be in [1, {len(TABLE2_FILE_INDICES)}], got {n_so}")
    chart = trondheim_chart("psbmpc")
    by_id = {i: p for i, p in zip(chart.ids, chart.polygons)}
    sel = [by_id[i] for i in TABLE2_FILE_INDICES[:n_so]]
    sub = Chart(polygons=tuple(sel), origin=chart.origin, crs=chart.crs, source=chart.source + " (Table 2)",
                ids=TABLE2_FILE_INDICES[:n_so])
    if rdp:
        sub = simplify_chart(sub, eps)
    return to_ring_sets(sub.polygons), chart


def _free_heading(position, polygons, max_run: float = 800.0):
    """The course [rad] with the longest straight run of open water from ``position`` and that run [m]."""
    import shapely
    from shapely.geometry import LineString, Point, Polygon

    land = shapely.union_all([Polygon(r[0], r[1:]) for r in polygons])
    best = (0.0, 0.0)
    for deg in range(0, 360, 2):
        c = np.deg2rad(deg)
        end = (position[0] + max_run * np.cos(c), position[1] + max_run * np.sin(c))
        hit = LineString([tuple(position), end]).intersection(land)
        run = max_run if hit.is_empty else Point(position).distance(hit)
        if run > best[1]:
            best = (float(c), float(run))
    return best


def nidelva_head_on(eps: float = 2.0, n_ps: int = 5, n_so: int = 13, rdp: bool = True) -> Situation:
    """Paper-scale Nidelva situation with the chart: the own-ship at :data:`~psbmpc_jax.charts.NIDELVA_OWN_SHIP_UTM`
    (river centre) at 2 m/s along the longest open-water run, two 5 m vessels coming head-on at 2 m/s,
    and the Table 2 polygons after RDP at ``eps``."""
    from .charts import nidelva_own_ship_ned

    rings, chart = nidelva_polygons(eps, n_so, rdp)
    pos = np.asarray(nidelva_own_ship_ned(chart), dtype=float)
    course, run = _free_heading(pos, rings)
    u = np.array([np.cos(course), np.sin(course)])
    own = OwnShip(state=np.array([pos[0], pos[1], course, 2.0]),
                  waypoints=np.array([pos, pos + max(run, 50.0) * u]), U_d=2.0, length=5.0, width=3.0)
    cov = np.diag([4.0, 4.0, 0.05, 0.05])
    obstacles = []
    for k, frac in enumerate((0.45, 0.8)):
        p = pos + frac * run * u + (-1.0) ** k * 3.0 * np.array([-u[1], u[0]])
        obstacles.append(Obstacle(state=np.array([p[0], p[1], -2.0 * u[0], -2.0 * u[1]]), cov=cov, length=5.0, width=3.0,
                                  n_ps=n_ps))
    return Situation(own, tuple(obstacles), tuple(rings))
