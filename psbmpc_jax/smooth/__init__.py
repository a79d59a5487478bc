"""The smooth two-stage planner of Mahipala & Johansen (2024, Smooth-SBMPC, Secs. VI–VII): building blocks.

* :mod:`.land_hit` — :func:`first_land_hit`: N_TP of the initialisation stage (the first trajectory index that
  collides with land: ship-domain disc meets land, or the segment from the previous point meets an edge),
  vectorised over behaviours and jitted; :func:`land_collision_flags`: the per-point flags.
* :mod:`.corridor` — Algorithm 3, the cross-track-error corridor (as a cross-track inequality: choice SM-8,
  docs/algorithm.md §12): :func:`buffer_land` / :func:`buffered_chart` (shapely buffer by r_dom, packed for the device
  once), :func:`cross_track_corridor` (jitted ray cast), :func:`cross_track_corridor_shapely` (host oracle),
  :func:`cross_track_residuals` (constraints h <= 0 for the optimiser) and the :class:`Corridor` result.
* :mod:`.init_stage` — Algorithms 1–2 (the original SB-MPC in closed loop over T_init):
  :func:`~.init_stage.init_stage` (not re-exported here: the name is the module's).
* :mod:`.docp` — the DOCP (27) and one jitted step (init stage → corridor → multi-start DOCP → safeguard):
  :func:`smooth_sbmpc_step`, :data:`DOCP_SOLVER`.
* :mod:`.planner` — :class:`SmoothSBMPCPlanner` (host API: :meth:`~SmoothSBMPCPlanner.plan` for one ship,
  :meth:`~SmoothSBMPCPlanner.plan_batch` for R runs in one device call) and its :class:`SmoothPlan`.

See ``docs/corridor.md`` for the equations and conventions.
"""

from .corridor import (Corridor, boundary_points, buffer_land, buffered_chart, corridor_kernel,
                       cross_track_corridor, cross_track_corridor_shapely, cross_track_residuals)
from .land_hit import first_land_hit, land_collision_flags
from .init_stage import InitResult, ShipModel, SmoothSettings, SmoothWeights
from .docp import DOCP_SOLVER, SmoothStep, smooth_sbmpc_step
from .planner import SmoothPlan, SmoothSBMPCPlanner

__all__ = [
    "Corridor", "boundary_points", "buffer_land", "buffered_chart", "corridor_kernel", "cross_track_corridor",
    "cross_track_corridor_shapely", "cross_track_residuals", "first_land_hit", "land_collision_flags",
    "InitResult", "ShipModel", "SmoothSettings", "SmoothWeights", "DOCP_SOLVER", "SmoothStep",
    "smooth_sbmpc_step", "SmoothPlan", "SmoothSBMPCPlanner",
]
