"""The COLREGS option's held course reference (``mpc.colregs_option.freeze_course``; docs/colregs_option.md).

A grid-search method applies its course offset χ over LOS guidance, χ_cmd = χ_LOS + χ.  Once the own-ship has
altered course, its cross-track error e grows and χ_LOS = α + atan(−e/Δ) turns it back toward the route, so an
avoidance heading held as an offset drifts back before the target is past (the ``hold`` term only stops the
planner from returning on purpose).  With ``freeze_course``, while some target is *engaged* (the option's hold
condition: within ``engage_radii`` R_i and not past and clear), the course reference is frozen at the active
leg's direction α:

* the planner plans on the route moved sideways by e (so the own-ship is on it: the LOS course at the start of
  every rollout is α), and
* the ship is commanded the absolute course α + χ and speed u·U_d until the next update (not LOS + χ).

So the heading α + χ the planner chose is held as long as it keeps χ, whatever the cross-track error.  Once
every target is past and clear (or beyond the engagement range), LOS guidance on the real route takes over again
and brings the ship back.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np


def engaged_now(situation, d_safe: float, spec) -> bool:
    """Whether some obstacle of ``situation`` is engaged by the option's definition (the ``engaged`` flag of
    :func:`psbmpc_jax.costs.colregs_option.encounter`, on the obstacles' present estimates): range below
    ``engage_radii`` R_i and not past and clear; R_i = d_safe + (l_0 + l_i)/2."""
    from ..costs.colregs_option import encounter

    obs = situation.obstacles
    if not obs:
        return False
    own = situation.own_ship
    x = np.array([o.state for o in obs], float)              # [O, 4]: x, y, vx, vy
    radius = np.array([d_safe + 0.5 * (own.length + o.length) for o in obs], float)
    flags = encounter((own.state[0], own.state[1]), own.state[2], own.state[3], (x[:, 0], x[:, 1]),
                      (x[:, 2], x[:, 3]), radius, np.ones(len(obs), bool), engage=spec.engage_radii,
                      act_cpa=spec.act_cpa_radii, act_range=spec.act_range_radii, clear=spec.clear_radii)
    return bool(np.any(np.asarray(flags["engaged"])))


def frozen_reference(situation):
    """``(situation on the moved route, α)``: the own-ship's remaining route moved sideways by its cross-track
    error on the active (first) leg, so that it lies on that leg, and the leg's direction α [rad]."""
    own = situation.own_ship
    wp = np.asarray(own.waypoints, float)
    d = wp[1] - wp[0]
    alpha = math.atan2(d[1], d[0])
    s, c = math.sin(alpha), math.cos(alpha)
    e = -(own.state[0] - wp[0, 0]) * s + (own.state[1] - wp[0, 1]) * c         # + = starboard of the leg
    moved = wp + e * np.array([-s, c])
    return dataclasses.replace(situation, own_ship=dataclasses.replace(own, waypoints=moved)), alpha


__all__ = ["engaged_now", "frozen_reference"]
