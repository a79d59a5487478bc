"""Built-in example situations (no chart needed)."""

from __future__ import annotations

import numpy as np

from .problem import Obstacle, OwnShip, Situation


def paper_head_on(n_ps: int = 5, n_obstacles: int = 2) -> Situation:
    """Nidelva-like river head-on at paper scale (Sec. IV-C, Table 1), without the chart.

    Own-ship at the origin heading north (upstream) at 2 m/s on a straight route; ``n_obstacles`` vessels
    (default 2) coming downstream (south) at 2 m/s, 5 m long, staggered 150 m apart and a few metres
    either side of the own-ship's track, each with a conservative tracker covariance."""
    if n_obstacles < 0:
        raise ValueError(f"n_obstacles must be >= 0, got {n_obstacles}")
    own = OwnShip(state=[0.0, 0.0, 0.0, 2.0], waypoints=[[0.0, 0.0], [2000.0, 0.0]], U_d=2.0, length=5.0,
                  width=3.0)
    cov = np.diag([4.0, 4.0, 0.05, 0.05])
    obstacles = []
    for i in range(n_obstacles):
        north = 250.0 + 150.0 * i
        east = (-1.0) ** i * 4.0
        obstacles.append(Obstacle(state=[north, east, -2.0, 0.0], cov=cov, length=5.0, width=3.0, n_ps=n_ps))
    return Situation(own, tuple(obstacles))
