"""Named MPC tunings: the paper's Nidelva (Table 1) and Sakshaug (Table 3) situations and an open-sea tuning
for the Imazu cases.

A preset is (PlannerConfig, Params, behaviour sets).  Scenario files name a preset and may override any
field; :func:`build_mpc` applies the overrides and validates them.
"""

from __future__ import annotations

import dataclasses
import difflib
from dataclasses import dataclass

import numpy as np

from .behaviours import PAPER_COURSES_DEG, PAPER_SPEEDS, SAKSHAUG_COURSES_DEG, enumerate_behaviours_deg
from .design_ship import DesignShip
from .params import Params, PlannerConfig, validate_params


@dataclass(frozen=True)
class MPCPreset:
    """One tuning: static config, parameter values, per-maneuver speed-factor and course-offset sets [deg], and
    the ship it was made for (``design_ship``, where its source names a ship length or speed; the methods whose
    tuning is the preset refuse ships outside it, :meth:`psbmpc_jax.methods.Method.check_fit`)."""

    name: str
    description: str
    config: PlannerConfig
    params: Params
    speed_sets: tuple[tuple[float, ...], ...]
    course_sets_deg: tuple[tuple[float, ...], ...]
    n_ps: int = 5
    design_ship: DesignShip | None = None

    def behaviours(self) -> np.ndarray:
        return enumerate_behaviours_deg(self.speed_sets, self.course_sets_deg)


PRESETS: dict[str, MPCPreset] = {
    "nidelva": MPCPreset(
        name="nidelva",
        description="Tengesdal et al. 2022, Table 1 (river, 5 m vessels): T 150 s, dt 0.5 s, r_ct 10 m, d_safe 5 m, "
                    "1014 behaviours",
        config=PlannerConfig(T=150.0, dt=0.5, grounding_mode="grid", grid_spacing=1.0),
        params=Params(),
        speed_sets=PAPER_SPEEDS,
        course_sets_deg=(PAPER_COURSES_DEG, PAPER_COURSES_DEG),
        design_ship=DesignShip(5.0, None, "preset nidelva: Tengesdal et al. 2022, Table 1 (river, 5 m vessels)"),
    ),
    "sakshaug": MPCPreset(
        name="sakshaug",
        description="Tengesdal et al. 2022, Table 3 (narrow strait, 10 m vessels): T 150 s, dt 1 s, r_ct 20 m, "
                    "d_safe 10 m, course offsets +-90 deg in 15 deg steps, 1014 behaviours",
        config=PlannerConfig(T=150.0, dt=1.0, grounding_mode="grid", grid_spacing=1.0),
        params=Params(r_ct=20.0, d_safe=10.0, d_close=300.0),
        speed_sets=PAPER_SPEEDS,
        course_sets_deg=(SAKSHAUG_COURSES_DEG, SAKSHAUG_COURSES_DEG),
        design_ship=DesignShip(10.0, None, "preset sakshaug: Tengesdal et al. 2022, Table 3 (narrow strait, 10 m "
                                           "vessels)"),
    ),
    "open_sea": MPCPreset(
        name="open_sea",
        description="Open sea (Imazu cases, 10 m/s ships): T 300 s, dt 1 s, r_ct 50 m, d_safe 100 m, "
                    "d_close 500 m, K_chi_port 6, course offsets +-90 deg in 15 deg steps, 1014 behaviours",
        config=PlannerConfig(T=300.0, dt=1.0),
        # d_close 500 m and K_chi_port 6 (4x starboard): with d_close 1500 m and the default 1.8 the cheapest way
        # to clear the COLREGS indicator of a crossing target from starboard was a small port turn that merely
        # pushed the crossing beyond the horizon (measured: first alteration to port in Imazu 02, 05, 09, 14,
        # 16); with these values they turn to starboard (docs/simulation.md, "Presets and tuning")
        params=Params(r_ct=50.0, d_safe=100.0, d_close=500.0, K_chi_port=6.0, T_d=200.0, os_lookahead=500.0, ob_lookahead=500.0,
                      os_R_a=50.0, ob_R_a=50.0, os_T_chi=5.0, os_T_U=10.0, ob_T_chi=5.0, ob_T_U=10.0),
        speed_sets=PAPER_SPEEDS,
        course_sets_deg=(SAKSHAUG_COURSES_DEG, SAKSHAUG_COURSES_DEG),
        design_ship=DesignShip(None, 10.0, "preset open_sea: our open-sea tuning for the Imazu cases (10 m/s ships)"),
    ),
    "tengesdal2020": MPCPreset(
        name="tengesdal2020",
        description="Tengesdal, Brekke & Johansen 2020 (30 m vessels at 9 m/s): T 200 s, dt 0.5 s, "
                    "d_safe 40 m, 39 behaviours (one maneuver, speeds 1/0.5/0, courses +-90 deg in 15 deg steps), "
                    "own-ship T_chi 3 s, T_U 5 s, LOS lookahead 150 m, n_ps 1 (straight-line tracks)",
        config=PlannerConfig(T=200.0, dt=0.5),
        params=Params(d_safe=40.0, d_close=200.0, r_ct=40.0, os_T_chi=3.0, os_T_U=5.0, ob_T_chi=3.0, ob_T_U=5.0,
                      os_lookahead=150.0, ob_lookahead=150.0, os_R_a=30.0, ob_R_a=30.0),
        speed_sets=((1.0, 0.5, 0.0),),
        course_sets_deg=(SAKSHAUG_COURSES_DEG,),
        n_ps=1,
        design_ship=DesignShip(30.0, 9.0, "preset tengesdal2020: Tengesdal, Brekke & Johansen 2020 (30 m vessels at "
                                          "9 m/s)"),
    ),
    "akdag2022": MPCPreset(
        name="akdag2022",
        description="Akdağ, Fossen & Johansen 2022 (116 m PSVs at ~6 m/s, open sea): T 600 s, dt 5 s, "
                    "39 behaviours (speeds 1/0.5/0, courses +-90 deg in 15 deg steps), kinematic prediction with "
                    "T_chi 15 s, T_U 30 s (fitted to the 3-DOF PSV model), LOS lookahead 600 m, n_ps 1",
        config=PlannerConfig(T=600.0, dt=5.0),
        params=Params(d_safe=120.0, d_close=1800.0, r_ct=100.0, os_T_chi=15.0, os_T_U=30.0, ob_T_chi=15.0,
                      ob_T_U=30.0, os_lookahead=600.0, ob_lookahead=600.0, os_R_a=150.0, ob_R_a=150.0),
        speed_sets=((1.0, 0.5, 0.0),),
        course_sets_deg=(SAKSHAUG_COURSES_DEG,),
        n_ps=1,
        design_ship=DesignShip(116.0, 6.0, "preset akdag2022: Akdağ, Fossen & Johansen 2022 (116 m PSVs at about "
                                           "6 m/s)"),
    ),
}

_CONFIG_FIELDS = tuple(f.name for f in dataclasses.fields(PlannerConfig))
_PARAM_FIELDS = tuple(f.name for f in dataclasses.fields(Params))


def _did_you_mean(bad, allowed) -> str:
    """`` (did you mean 'K_coll'?)`` for the first unknown name with a close match, else ``""``."""
    for name in bad:
        close = difflib.get_close_matches(str(name), allowed, n=1, cutoff=0.6)
        if close:
            return f" (did you mean {close[0]!r} for {name!r}?)"
    return ""


def get_preset(name: str) -> MPCPreset:
    if name not in PRESETS:
        raise ValueError(f"unknown MPC preset {name!r}{_did_you_mean([name], sorted(PRESETS))}; allowed: {sorted(PRESETS)}")
    return PRESETS[name]


def build_mpc(preset: str, config_overrides: dict | None = None, param_overrides: dict | None = None,
              speed_sets=None, course_sets_deg=None):
    """(PlannerConfig, Params, behaviours [B, n_M, 2]) of ``preset`` with overrides applied and validated.

    Raises:
        ValueError: unknown preset or field names, or values the config/params reject.
    """
    p = get_preset(preset)
    config_overrides = dict(config_overrides or {})
    param_overrides = dict(param_overrides or {})
    bad = sorted(set(config_overrides) - set(_CONFIG_FIELDS))
    if bad:
        raise ValueError(f"unknown PlannerConfig field(s) {bad}{_did_you_mean(bad, _CONFIG_FIELDS)}; "
                         f"allowed: {list(_CONFIG_FIELDS)}")
    bad = sorted(set(param_overrides) - set(_PARAM_FIELDS))
    if bad:
        raise ValueError(f"unknown Params field(s) {bad}{_did_you_mean(bad, _PARAM_FIELDS)}; "
                         f"allowed: {list(_PARAM_FIELDS)}")
    config = p.config.replace(**config_overrides)
    params = p.params.replace(**{k: float(v) for k, v in param_overrides.items()})
    validate_params(params)
    speeds = p.speed_sets if speed_sets is None else speed_sets
    courses = p.course_sets_deg if course_sets_deg is None else course_sets_deg
    return config, params, enumerate_behaviours_deg(speeds, courses)   # raises on mismatched set counts
