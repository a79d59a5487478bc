"""A collision-avoidance controller written outside psbmpc_jax: "turn to starboard until the closest point of
approach is clear".

At each MPC update every ship this controller runs tries a short list of manoeuvres, in order of preference,
and keeps the first one whose straight-line closest point of approach (CPA) to every other ship, within
``horizon_s``, stays at least ``d_safe_m`` away.  If none does, it keeps the last (slow right down).

It uses only the public protocol of :mod:`psbmpc_jax.methods`:

* :class:`CpaSettings` and :func:`parse_section` are its settings and the parser of its own section of a scenario
  file, ``mpc.cpa`` (registered with :func:`psbmpc_jax.methods.registry.register_section` when this module is
  imported);
* :class:`CpaMethod` is the *method*: its name, and ``build`` which makes the controller for the ships that
  run it;
* :class:`CpaController` is the *controller*: ``decide_ship(observation, run, ship)`` returns the offsets
  ``(speed factor, course offset [rad])`` that the simulator applies on top of the ship's route guidance until
  the next update.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from psbmpc_jax.config import as_mapping, as_number, check_keys
from psbmpc_jax.methods import Method, Observation, ShipController
from psbmpc_jax.methods.registry import SECTIONS, register_section

#: Candidate manoeuvres (speed factor, course offset [deg]), most preferred first.
MANOEUVRES = ((1.0, 0.0), (1.0, 15.0), (1.0, 30.0), (1.0, 45.0), (1.0, 60.0), (0.5, 60.0), (0.0, 0.0))


def cpa(p_own, v_own, p_other, v_other, horizon: float) -> float:
    """Distance [m] at the closest point of approach within ``horizon`` [s] of two ships moving in straight
    lines (positions and velocities in north/east metres and m/s)."""
    dp, dv = np.subtract(p_other, p_own), np.subtract(v_other, v_own)
    vv = float(dv @ dv)
    t = 0.0 if vv < 1e-12 else min(max(-float(dp @ dv) / vv, 0.0), horizon)
    return float(np.hypot(*(dp + t * dv)))


class CpaController(ShipController):
    """Decides one (run, ship) at a time (:class:`psbmpc_jax.methods.ShipController` loops over them)."""

    def __init__(self, ships, *, d_safe_m: float, horizon_s: float):
        super().__init__(ships)
        self.d_safe, self.horizon = float(d_safe_m), float(horizon_s)

    def others(self, obs: Observation, r: int, i: int):
        """(position, velocity) of every other ship as ship ``i`` knows it: the own-ship (ship 0) through its
        tracker (skipping targets not measured yet), a target through the true states."""
        for j in range(obs.states.shape[1]):
            if j == i:
                continue
            if i == 0:
                x = obs.tracks[r, j - 1]                         # north, east, V_north, V_east
                if not np.all(np.isfinite(x)):
                    continue
                yield x[:2], x[2:]
            else:
                n, e, chi, u = obs.states[r, j]
                yield (n, e), (u * math.cos(chi), u * math.sin(chi))

    def decide_ship(self, obs: Observation, r: int, i: int) -> tuple[float, float]:
        north, east, course, speed = obs.states[r, i]
        nominal = float(obs.speeds[r, i])
        others = list(self.others(obs, r, i))
        for factor, offset_deg in MANOEUVRES:
            chi = course + math.radians(offset_deg)
            v = (factor * nominal * math.cos(chi), factor * nominal * math.sin(chi))
            if all(cpa((north, east), v, p, w, self.horizon) >= self.d_safe for p, w in others):
                return factor, math.radians(offset_deg)
        factor, offset_deg = MANOEUVRES[-1]
        return factor, math.radians(offset_deg)


@dataclass(frozen=True)
class CpaSettings:
    """The settings of :class:`CpaMethod`: the clearance to keep [m] and how far ahead to look [s]."""

    d_safe_m: float = 30.0
    horizon_s: float = 120.0

    def __post_init__(self):
        for name in ("d_safe_m", "horizon_s"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
                raise ValueError(f"CpaSettings.{name} must be a number > 0, got {v!r}")


def parse_section(d, context) -> CpaSettings:
    """``mpc.cpa`` of a scenario file (``d_safe_m``, ``horizon_s``; both optional)."""
    d = as_mapping(d, "mpc.cpa")
    check_keys(d, ("d_safe_m", "horizon_s"), "mpc.cpa")
    return CpaSettings(**{k: as_number(v, f"mpc.cpa.{k}", gt=0) for k, v in d.items()})


if "cpa" not in SECTIONS:                      # once, however often the module is imported
    register_section("cpa", parse_section, CpaSettings)


class CpaMethod(Method):
    """The method: what scenario files name (``mpc.method: cpa_controller:CpaMethod`` or, once registered,
    ``cpa``) and how its controller is built.  Its settings are the file's ``mpc.cpa`` section, unless some are
    given in code (``CpaMethod(d_safe_m=40)``), which then win."""

    name = "cpa"
    description = "turn to starboard until the straight-line CPA is clear (example)"

    def __init__(self, **settings):
        self.given = asdict(CpaSettings(**settings)) if settings else {}      # validated now
        self.given = {k: v for k, v in self.given.items() if k in settings}

    def settings(self, scenario) -> CpaSettings:
        return CpaSettings(**{**asdict(scenario.mpc.cpa), **self.given})

    def build(self, scenario, ships, context):
        s = self.settings(scenario)
        return CpaController(ships, d_safe_m=s.d_safe_m, horizon_s=s.horizon_s)

    def record(self, scenario) -> dict:
        return {**asdict(self.settings(scenario)), "manoeuvres": [list(m) for m in MANOEUVRES]}

    def describe(self, scenario) -> str:
        s = self.settings(scenario)
        return f"d_safe {s.d_safe_m:g} m, horizon {s.horizon_s:g} s"
