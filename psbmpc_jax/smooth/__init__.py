"""The smooth two-stage planner of SPEC_SEEDS §1.5–1.6 (000): building blocks.

* :mod:`.land_hit` — :func:`first_land_hit`: N_TP of the initialisation stage (the first trajectory index that
  collides with land: ship-domain disc meets land, or the segment from the previous point meets an edge),
  vectorised over behaviours and jitted; :func:`land_collision_flags`: the per-point flags.
* :mod:`.corridor` — Algorithm 3, the cross-track-error corridor (choice C-000-8): :func:`buffer_land` /
  :func:`buffered_chart` (shapely buffer by r_dom, packed for the device once), :func:`cross_track_corridor`
  (jitted ray cast), :func:`cross_track_corridor_shapely` (host oracle), :func:`cross_track_residuals`
  (constraints h <= 0 for the optimiser) and the :class:`Corridor` result.

See ``docs/corridor.md`` for the equations and conventions.
"""

from .corridor import (Corridor, boundary_points, buffer_land, buffered_chart, corridor_kernel,
                       cross_track_corridor, cross_track_corridor_shapely, cross_track_residuals)
from .land_hit import first_land_hit, land_collision_flags

__all__ = [
    "Corridor", "boundary_points", "buffer_land", "buffered_chart", "corridor_kernel", "cross_track_corridor",
    "cross_track_corridor_shapely", "cross_track_residuals", "first_land_hit", "land_collision_flags",
]
