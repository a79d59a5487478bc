"""What the encounter generator draws from: the ranges per encounter type (:class:`EncounterRanges`), the
own-ship's ranges and the scenario-file template (:class:`GenerationSettings`), two presets
(:data:`PRESETS`) and the reader of a settings mapping (:func:`settings_from_dict`).

Units are in the field names (``_deg``, ``_mps``, ``_m``, ``_s``).  A range is a pair ``(low, high)`` with
``low <= high``; an angle range is an arc read clockwise from ``low`` to ``high`` in degrees (``(160, 200)``
contains 180, ``(-30, 30)`` contains 0; at most 360° wide).  Every check names the field
(``types.overtaking.target_speed_mps``) and what is allowed; nothing is clamped.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import numbers
from dataclasses import dataclass
from types import MappingProxyType

from ..checks import MAX_SPEED_MPS

__all__ = ["ENCOUNTER_TYPES", "SITUATION_CODES", "EncounterRanges", "GenerationSettings", "PRESETS",
           "get_settings", "settings_from_dict", "number_range", "angle_range", "in_arc", "TEMPLATE_KEYS"]

#: The encounter types, named from the own-ship's side (COLREGS Rules 13-15).
ENCOUNTER_TYPES = ("head_on", "crossing_give_way", "crossing_stand_on", "overtaking", "overtaken")

#: Encounter type -> the situation code the evaluation tool gives the own-ship (:mod:`psbmpc_jax.evaltool`).
SITUATION_CODES = MappingProxyType({"head_on": "HO", "crossing_give_way": "CRGW", "crossing_stand_on": "CRSO",
                                    "overtaking": "OTGW", "overtaken": "OTSO"})

#: Top-level keys a template may hold: the scenario file's sections the generator does not write itself
#: (``name``, ``description``, ``own_ship``, ``targets`` and ``simulation.duration_s`` are generated).
TEMPLATE_KEYS = ("simulation", "monte_carlo", "collision_distance_m", "evaluation", "mpc", "sensor", "chart",
                 "origin_latlon")

#: Longest time to CPA [s] a range may ask for (the simulation must hold it).
MAX_TCPA_S = 20_000.0


# ------------------------------------------------------------------------------------------------ range checks
def _num(v, name: str) -> float:
    if isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(float(v)):
        raise ValueError(f"{name} must be a finite number, got {v!r}")
    return float(v)


def number_range(v, name: str, *, lo: float = -math.inf, hi: float = math.inf, lo_open: bool = False,
                 hi_open: bool = False) -> tuple[float, float]:
    """``v`` as ``(low, high)`` with ``lo (<|<=) low <= high (<|<=) hi``; ValueError naming ``name`` else."""
    if isinstance(v, (str, bytes)) or not hasattr(v, "__len__") or len(v) != 2:
        raise ValueError(f"{name} must be a pair (low, high), got {v!r}")
    a, b = _num(v[0], f"{name}[0]"), _num(v[1], f"{name}[1]")
    ok_lo = a > lo if lo_open else a >= lo
    ok_hi = b < hi if hi_open else b <= hi
    if not (ok_lo and ok_hi and a <= b):
        allowed = f"{'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"
        raise ValueError(f"{name} must be (low, high) with low <= high, both in {allowed}, got {v!r}")
    return a, b


def angle_range(v, name: str) -> tuple[float, float]:
    """An arc ``(low, high)`` in degrees, read clockwise from low to high: ``low <= high <= low + 360``."""
    a, b = number_range(v, name)
    if b - a > 360.0:
        raise ValueError(f"{name} must span at most 360 degrees (an arc from low clockwise to high), got {v!r}")
    return a, b


def in_arc(x, arc) -> "bool | object":
    """Whether angle(s) ``x`` [deg] lie on the arc ``(low, high)`` (clockwise from low); NumPy arrays work."""
    lo, hi = arc
    return ((x - lo) % 360.0) <= (hi - lo) + 1e-9


# ------------------------------------------------------------------------------------------------ dataclasses
@dataclass(frozen=True)
class EncounterRanges:
    """The ranges one target of an encounter type is drawn from (uniformly, then kept only if its geometry is
    of the requested type: see :func:`psbmpc_jax.scenario_generation.generate_encounter`).

    Attributes:
        relative_course_deg: target course minus own-ship course, an arc [deg].
        target_speed_mps: target speed over ground [m/s].
        dcpa_m: distance at the closest point of approach of the straight tracks [m].
        tcpa_s: time of the closest point of approach after the start [s].
        relative_bearing_deg: bearing of the target from the own-ship relative to its course (starboard
            positive), an arc [deg], measured when the evaluation tool classifies the encounter (the start, or the
            first time the range falls to its stage-2 radius); ``None``: the type's whole sector.
    """

    relative_course_deg: tuple
    target_speed_mps: tuple
    dcpa_m: tuple
    tcpa_s: tuple
    relative_bearing_deg: tuple | None = None

    def checked(self, where: str) -> "EncounterRanges":
        """A copy with every range validated and converted to float pairs (errors name ``where.field``)."""
        return EncounterRanges(
            relative_course_deg=angle_range(self.relative_course_deg, f"{where}.relative_course_deg"),
            target_speed_mps=number_range(self.target_speed_mps, f"{where}.target_speed_mps", lo=0.0,
                                          hi=MAX_SPEED_MPS, lo_open=True),
            dcpa_m=number_range(self.dcpa_m, f"{where}.dcpa_m", lo=0.0),
            tcpa_s=number_range(self.tcpa_s, f"{where}.tcpa_s", lo=0.0, hi=MAX_TCPA_S, lo_open=True),
            relative_bearing_deg=None if self.relative_bearing_deg is None else angle_range(
                self.relative_bearing_deg, f"{where}.relative_bearing_deg"))


@dataclass(frozen=True)
class GenerationSettings:
    """Everything the generator draws from, besides the requested types, the seed and the chart.

    Attributes:
        own_speed_mps: own-ship speed [m/s].
        own_course_deg: own-ship course, an arc [deg].
        own_north_m, own_east_m: the box the own-ship's start is drawn from, in the scenario's NED frame [m]
            (``(0, 0)`` and ``(0, 0)``: the origin).
        types: encounter type -> :class:`EncounterRanges` (every type of :data:`ENCOUNTER_TYPES`).
        sector_margin_deg: the generated geometry stays this far inside the evaluation tool's sectors, in
            relative bearing and in contact angle, so that sampling and rounding cannot change the class.
        min_speed_difference_mps: overtaking / overtaken: the slower ship is at least this much slower (on top of
            the evaluation's ``overtaking_speed_margin_mps``).
        min_separation_m: smallest distance between two ships' starts, and between two targets' straight tracks
            during the simulation (targets do not avoid each other); at least the scenario's collision distance.
        land_margin_m: smallest distance of a start and of a straight track (over the whole simulation, so the
            track to the CPA included) to land; only with a chart.
        after_cpa_s: the simulation runs this long after the latest CPA (``duration_s`` = largest ``tcpa_s``
            high of the requested types + this, rounded up to a multiple of ``simulation.dt_s``).
        ship_length_m, ship_width_m: hull size written for every ship.
        start_within_stage2: keep only targets that start within the evaluation's stage-2 radius, so that the
            evaluation classifies the encounter at t = 0, before any collision-avoidance manoeuvre (for closed-loop
            runs; the default, False, lets ships start farther apart, classified when the range falls to it).
        template: the scenario file's other sections (keys of :data:`TEMPLATE_KEYS`; ``simulation`` holds
            ``dt_s`` only).
    """

    own_speed_mps: tuple
    own_course_deg: tuple
    types: dict
    template: dict
    own_north_m: tuple = (0.0, 0.0)
    own_east_m: tuple = (0.0, 0.0)
    sector_margin_deg: float = 2.0
    min_speed_difference_mps: float = 0.5
    min_separation_m: float = 20.0
    land_margin_m: float = 20.0
    after_cpa_s: float = 120.0
    ship_length_m: float = 5.0
    ship_width_m: float = 3.0
    start_within_stage2: bool = False

    def __post_init__(self):
        object.__setattr__(self, "own_speed_mps", number_range(self.own_speed_mps, "own_speed_mps", lo=0.0,
                                                               hi=MAX_SPEED_MPS, lo_open=True))
        object.__setattr__(self, "own_course_deg", angle_range(self.own_course_deg, "own_course_deg"))
        object.__setattr__(self, "own_north_m", number_range(self.own_north_m, "own_north_m", lo=-1e5, hi=1e5))
        object.__setattr__(self, "own_east_m", number_range(self.own_east_m, "own_east_m", lo=-1e5, hi=1e5))
        if not isinstance(self.types, dict):
            raise ValueError(f"types must be a mapping of encounter type -> EncounterRanges, got "
                             f"{type(self.types).__name__}")
        unknown = sorted(set(self.types) - set(ENCOUNTER_TYPES))
        missing = [k for k in ENCOUNTER_TYPES if k not in self.types]
        if unknown or missing:
            raise ValueError(f"types must hold exactly the encounter types {', '.join(ENCOUNTER_TYPES)}; "
                             f"unknown: {unknown or 'none'}, missing: {missing or 'none'}")
        types = {}
        for k in ENCOUNTER_TYPES:
            r = self.types[k]
            if not isinstance(r, EncounterRanges):
                raise ValueError(f"types.{k} must be an EncounterRanges, got {type(r).__name__}")
            types[k] = r.checked(f"types.{k}")
        object.__setattr__(self, "types", types)
        for name, lo, hi in (("sector_margin_deg", 0.0, 10.0), ("min_speed_difference_mps", 0.0, MAX_SPEED_MPS),
                             ("min_separation_m", 0.0, 1e5), ("land_margin_m", 0.0, 1e5),
                             ("after_cpa_s", 0.0, MAX_TCPA_S), ("ship_length_m", 0.0, 500.0),
                             ("ship_width_m", 0.0, 100.0)):
            v = _num(getattr(self, name), name)
            if not lo <= v <= hi:
                raise ValueError(f"{name} must be in [{lo:g}, {hi:g}], got {v!r}")
            object.__setattr__(self, name, v)
        if self.ship_length_m <= 0 or self.ship_width_m <= 0:
            raise ValueError(f"ship_length_m and ship_width_m must be > 0 (the own-ship has a hull), got "
                             f"{self.ship_length_m:g} and {self.ship_width_m:g}")
        if not isinstance(self.start_within_stage2, bool):
            raise ValueError(f"start_within_stage2 must be True or False, got {self.start_within_stage2!r}")
        self._check_speeds()
        object.__setattr__(self, "template", _checked_template(self.template))

    def _check_speeds(self) -> None:
        """Refuse overtaking / overtaken ranges that cannot produce the type for any own-ship speed."""
        d = self.min_speed_difference_mps
        o_lo, o_hi = self.own_speed_mps
        t_lo, t_hi = self.types["overtaking"].target_speed_mps
        if t_lo > o_hi - d:
            raise ValueError(f"types.overtaking.target_speed_mps {[t_lo, t_hi]}: overtaking needs a target slower "
                             f"than the own-ship by at least min_speed_difference_mps ({d:g}); its low ({t_lo:g}) "
                             f"must be <= own_speed_mps high ({o_hi:g}) - {d:g} = {o_hi - d:g}")
        t_lo, t_hi = self.types["overtaken"].target_speed_mps
        if t_hi < o_lo + d:
            raise ValueError(f"types.overtaken.target_speed_mps {[t_lo, t_hi]}: being overtaken needs a target "
                             f"faster than the own-ship by at least min_speed_difference_mps ({d:g}); its high "
                             f"({t_hi:g}) must be >= own_speed_mps low ({o_lo:g}) + {d:g} = {o_lo + d:g}")

    @property
    def dt_s(self) -> float:
        """The simulation step of the template."""
        return float(self.template["simulation"]["dt_s"])

    def duration_s(self, types) -> float:
        """The simulation length for targets of ``types``: largest ``tcpa_s`` high + ``after_cpa_s``, rounded up
        to a multiple of ``dt_s``."""
        t = max(self.types[k].tcpa_s[1] for k in types) + self.after_cpa_s
        dt = self.dt_s
        return float(math.ceil(t / dt - 1e-9) * dt)

    def as_dict(self) -> dict:
        """JSON-ready ``{field: value}`` (ranges as lists)."""
        out = {}
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if f.name == "types":
                v = {k: {g.name: (None if getattr(r, g.name) is None else list(getattr(r, g.name)))
                         for g in dataclasses.fields(r)} for k, r in v.items()}
            elif isinstance(v, tuple):
                v = list(v)
            elif isinstance(v, dict):
                v = copy.deepcopy(v)
            out[f.name] = v
        return out


def _checked_template(t) -> dict:
    if not isinstance(t, dict):
        raise ValueError(f"template must be a mapping of scenario-file sections, got {type(t).__name__}")
    bad = [k for k in t if k not in TEMPLATE_KEYS]
    if bad:
        raise ValueError(f"template: key(s) {bad} not allowed; a template holds {', '.join(TEMPLATE_KEYS)} (name, "
                         f"description, own_ship, targets and simulation.duration_s are generated)")
    for k in ("simulation", "mpc"):
        if k not in t:
            raise ValueError(f"template: missing required section {k!r}")
    sim = t["simulation"]
    if not isinstance(sim, dict) or set(sim) != {"dt_s"}:
        raise ValueError(f"template.simulation must hold dt_s only (duration_s is generated), got {sim!r}")
    dt = _num(sim["dt_s"], "template.simulation.dt_s")
    if not dt > 0:
        raise ValueError(f"template.simulation.dt_s must be > 0, got {dt!r}")
    return copy.deepcopy(t)


# ------------------------------------------------------------------------------------------------ presets
def _ranges(course, speed, dcpa, tcpa) -> EncounterRanges:
    return EncounterRanges(relative_course_deg=course, target_speed_mps=speed, dcpa_m=dcpa, tcpa_s=tcpa)


#: Harbour scale, as the shipped basic encounters (``head_on``, ``crossing_give_way``, ... ): 5 m vessels at
#: 1-4 m/s, the ``nidelva`` MPC tuning (d_safe 5 m) and the evaluation's open-water ranges x 5/30.
HARBOUR = GenerationSettings(
    own_speed_mps=(1.5, 3.0), own_course_deg=(0.0, 360.0),
    types={"head_on": _ranges((160.0, 200.0), (1.0, 3.0), (0.0, 30.0), (90.0, 240.0)),
           "crossing_give_way": _ranges((200.0, 340.0), (1.0, 3.0), (0.0, 30.0), (90.0, 240.0)),
           "crossing_stand_on": _ranges((20.0, 160.0), (1.0, 3.0), (0.0, 30.0), (90.0, 240.0)),
           "overtaking": _ranges((-30.0, 30.0), (0.5, 2.5), (0.0, 30.0), (90.0, 300.0)),
           "overtaken": _ranges((-30.0, 30.0), (2.0, 4.0), (0.0, 30.0), (90.0, 300.0))},
    template={"simulation": {"dt_s": 0.5}, "monte_carlo": {"runs": 20, "seed": 0},
              "mpc": {"preset": "nidelva", "update_period_s": 5, "params": {"K_chi_port": 6.0}},
              "evaluation": {"range_scale": 0.16666667},
              "sensor": {"position_std_m": 2, "period_s": 2.5, "filter_R_scale": 25, "sigma_a_mps2": 0.5,
                         "U_max_mps": 4}},
    sector_margin_deg=2.0, min_speed_difference_mps=0.5, min_separation_m=20.0, land_margin_m=20.0,
    after_cpa_s=120.0, ship_length_m=5.0, ship_width_m=3.0)

#: Open sea, as the shipped Imazu cases: 100 m ships at 3-12 m/s, the ``open_sea`` MPC tuning (d_safe 100 m)
#: and the evaluation's open-water ranges x 100/30.
OPEN_SEA = GenerationSettings(
    own_speed_mps=(7.0, 10.0), own_course_deg=(0.0, 360.0),
    types={"head_on": _ranges((160.0, 200.0), (6.0, 12.0), (0.0, 600.0), (300.0, 900.0)),
           "crossing_give_way": _ranges((200.0, 340.0), (6.0, 12.0), (0.0, 600.0), (300.0, 900.0)),
           "crossing_stand_on": _ranges((20.0, 160.0), (6.0, 12.0), (0.0, 600.0), (300.0, 900.0)),
           "overtaking": _ranges((-30.0, 30.0), (3.0, 9.0), (0.0, 600.0), (300.0, 1200.0)),
           "overtaken": _ranges((-30.0, 30.0), (8.0, 12.0), (0.0, 600.0), (300.0, 1200.0))},
    template={"simulation": {"dt_s": 1.0}, "monte_carlo": {"runs": 20, "seed": 0},
              "mpc": {"preset": "open_sea", "update_period_s": 5},
              "evaluation": {"range_scale": 3.33333333},
              "sensor": {"position_std_m": 10, "period_s": 2, "filter_R_scale": 25, "sigma_a_mps2": 0.5,
                         "U_max_mps": 12}},
    sector_margin_deg=2.0, min_speed_difference_mps=1.0, min_separation_m=300.0, land_margin_m=200.0,
    after_cpa_s=300.0, ship_length_m=100.0, ship_width_m=20.0)

#: name -> settings.
PRESETS = MappingProxyType({"harbour": HARBOUR, "open_sea": OPEN_SEA})


def get_settings(preset: "str | GenerationSettings" = "harbour", **overrides) -> GenerationSettings:
    """The preset ``preset`` (a name of :data:`PRESETS` or a :class:`GenerationSettings`) with ``overrides``
    (fields of :class:`GenerationSettings`; ``types`` may be partial: ``{"head_on": {"dcpa_m": (0, 10)}}``)."""
    if isinstance(preset, GenerationSettings):
        base = preset
    elif isinstance(preset, str) and preset in PRESETS:
        base = PRESETS[preset]
    else:
        raise ValueError(f"unknown generation preset {preset!r}; known: {', '.join(PRESETS)}")
    if not overrides:
        return base
    names = [f.name for f in dataclasses.fields(GenerationSettings)]
    unknown = sorted(set(overrides) - set(names))
    if unknown:
        raise ValueError(f"unknown setting(s) {unknown}; allowed: preset, {', '.join(names)}")
    if "types" in overrides:
        overrides = dict(overrides, types=_merge_types(base.types, overrides["types"]))
    if "template" in overrides and overrides["template"] is not None:
        t = overrides["template"]
        if not isinstance(t, dict):
            raise ValueError(f"template must be a mapping of scenario-file sections, got {type(t).__name__}")
        overrides = dict(overrides, template={**base.template, **t})
    return dataclasses.replace(base, **overrides)


def _merge_types(base: dict, new) -> dict:
    if not isinstance(new, dict):
        raise ValueError(f"types must be a mapping of encounter type -> ranges, got {type(new).__name__}")
    out = dict(base)
    fields_ = [f.name for f in dataclasses.fields(EncounterRanges)]
    for k, v in new.items():
        if k not in ENCOUNTER_TYPES:
            raise ValueError(f"types: unknown encounter type {k!r}; known: {', '.join(ENCOUNTER_TYPES)}")
        if isinstance(v, EncounterRanges):
            out[k] = v
            continue
        if not isinstance(v, dict):
            raise ValueError(f"types.{k} must be a mapping of {', '.join(fields_)}, got {v!r}")
        bad = sorted(set(v) - set(fields_))
        if bad:
            raise ValueError(f"types.{k}: unknown key(s) {bad}; allowed: {', '.join(fields_)}")
        out[k] = dataclasses.replace(base[k], **v)
    return out


def settings_from_dict(d) -> GenerationSettings:
    """Settings from a mapping (e.g. a YAML file): ``preset`` (default ``harbour``) and any field of
    :class:`GenerationSettings` overriding it (``types`` partially, ``template`` section by section)."""
    if not isinstance(d, dict):
        raise ValueError(f"generation settings must be a mapping, got {type(d).__name__}")
    d = dict(d)
    return get_settings(d.pop("preset", "harbour"), **d)
