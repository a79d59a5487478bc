"""Drawing COLREGS-typed encounters: :func:`generate_encounter` (one scenario mapping), :func:`generate_encounters`
(a reproducible batch), the land they are placed on (:class:`Land`) and the resolved context of a batch
(:func:`prepare`).

One target of type ``kind``, given the own-ship (start p_o, course, speed, velocity v_o):

1. draw the target speed U_t, the relative course χ_rel, DCPA, TCPA and the side of passing s = ±1 uniformly from
   the type's ranges (for overtaking U_t <= U_o - ΔU, for overtaken U_t >= U_o + ΔU);
2. v_rel = v_t - v_o; the relative position at the CPA is d = s · DCPA · n (n ⊥ v_rel, unit), so the target starts
   at p_t = p_o + d - v_rel · TCPA (back-propagated along the straight relative track);
3. round the written values (positions 0.01 m, course 0.001°, speed 0.001 m/s) and recompute the geometry from
   them;
4. keep the draw only if, at the times the evaluation tool may classify the pair (the first sample inside its
   stage-2 range), its own classification gives ``kind`` for every bearing and contact angle within the sector
   margin; the relative bearing lies in the type's bearing arc; the starts are far enough apart and the targets'
   tracks stay apart; and, on a chart, no start lies on land or within the land margin and no straight track
   (over the whole simulation, so to the CPA and beyond) comes within the margin of land.

Every rejected draw is counted by its reason (:data:`REJECTION_REASONS`).  After ``max_tries`` draws without an
encounter the generator gives up with a ValueError that lists the counts.
"""

from __future__ import annotations

import logging
import math
import warnings
from collections import Counter
from dataclasses import dataclass, field

import numpy as np
import shapely
from shapely.geometry import LineString, Point, Polygon

from ..charts import Chart
from ..evaltool.params import EvalParams
from ..scenario import scenario_from_dict
from .sectors import (CHECK_SAMPLES, check_feasible, min_distance, pair_angles, robust_class, start_time,
                      velocity)
from .settings import ENCOUNTER_TYPES, GenerationSettings, get_settings, in_arc

__all__ = ["Land", "GenerationContext", "GeneratedEncounter", "EncounterBatch", "prepare", "generate_encounter",
           "generate_encounters", "REJECTION_REASONS", "MAX_TRIES", "MAX_TARGETS"]

log = logging.getLogger(__name__)

#: Why a draw was rejected (the keys of the rejection counts).
REJECTION_REASONS = ("speed", "start_range", "sector", "bearing", "separation", "own_start_on_land",
                     "own_start_near_land", "own_track_near_land", "target_start_on_land", "target_start_near_land",
                     "target_track_near_land", "loader")
#: Default bound on the draws (own-ship and target draws together) of one encounter.
MAX_TRIES = 20_000
#: Draws of one target before the own-ship is drawn again.
TARGET_TRIES = 500
#: Most targets per encounter.
MAX_TARGETS = 20


class Land:
    """Land polygons (NED, shapely) with the two checks of the generator: a point's and a segment's clearance."""

    def __init__(self, polygons=()):
        self.polygons = tuple(polygons)
        self.tree = shapely.STRtree(list(self.polygons)) if self.polygons else None

    def __bool__(self) -> bool:
        return bool(self.polygons)

    def on_land(self, pt) -> bool:
        return self.tree is not None and self.tree.query(Point(pt), predicate="intersects").size > 0

    def near(self, geom, margin: float) -> bool:
        """Whether land lies within ``margin`` of ``geom`` (a point or a segment), touching included."""
        if self.tree is None:
            return False
        return self.tree.query(geom, predicate="dwithin", distance=max(margin, 0.0)).size > 0 if margin > 0 else (
            self.tree.query(geom, predicate="intersects").size > 0)


@dataclass(frozen=True)
class GenerationContext:
    """A batch's resolved inputs: settings, the evaluation parameters and collision distance the scenario files
    will have, the land, the template the files are built from, and the simulation length."""

    settings: GenerationSettings
    types: tuple
    evaluation: EvalParams
    d_collision: float
    land: Land
    template: dict
    duration_s: float
    base_dir: object = None


@dataclass(frozen=True)
class GeneratedEncounter:
    """One generated encounter.

    Attributes:
        scenario: the scenario-file mapping (what :func:`psbmpc_jax.scenario.scenario_from_dict` reads).
        types: the requested type of each target.
        targets: per target what was drawn and what it gives: ``relative_course_deg``, ``target_speed_mps``,
            ``dcpa_m``, ``tcpa_s`` (of the written, rounded values), ``side`` (+1: at the CPA the target lies to the
            right of the relative velocity v_t - v_o, -1: to its left), ``t_start_s`` (when the evaluation
            classifies), ``bearing_deg`` and ``contact_angle_deg`` then, ``start_range_m``.
        rejections: draws rejected before this one was kept, by reason.
        validated: whether the scenario loader accepted the mapping (``validate=True``).
    """

    scenario: dict
    types: tuple
    targets: tuple
    rejections: dict
    validated: bool


@dataclass(frozen=True)
class EncounterBatch:
    """Encounters of one seed: ``encounters[i]`` was drawn from ``numpy.random.default_rng([seed, i])``."""

    encounters: tuple
    seed: int
    types: tuple
    settings: GenerationSettings
    rejections: dict = field(default_factory=dict)


# ------------------------------------------------------------------------------------------------ context
def _types(types) -> tuple:
    if isinstance(types, str):
        types = (types,)
    if not isinstance(types, (list, tuple)) or not types:
        raise ValueError(f"types must be an encounter type or a non-empty list of them (one per target), got "
                         f"{types!r}; types: {', '.join(ENCOUNTER_TYPES)}")
    if len(types) > MAX_TARGETS:
        raise ValueError(f"types: {len(types)} targets; at most {MAX_TARGETS} allowed")
    for k in types:
        if k not in ENCOUNTER_TYPES:
            raise ValueError(f"unknown encounter type {k!r}; types: {', '.join(ENCOUNTER_TYPES)}")
    return tuple(types)


def _polygons_of(scenario) -> list[Polygon]:
    return [Polygon(rs[0], list(rs[1:])) for rs in scenario.polygons]


def prepare(types, settings="harbour", chart=None, base_dir=None) -> GenerationContext:
    """Check the settings for ``types`` against the scenario the files will be (evaluation parameters, collision
    distance, land) and return the context of a batch.

    Args:
        types: an encounter type, or one per target.
        settings: a preset name or :class:`GenerationSettings`.
        chart: ``None`` (open water, unless the template has a ``chart`` section), a scenario file's ``chart``
            section (a mapping: ``builtin`` / ``file`` / ``polygons_m`` ...; written into every file and loaded for
            the checks), or a :class:`psbmpc_jax.charts.Chart` (used for the checks; the template must then also
            name that land in its ``chart`` section, since a file cannot hold a Chart object).
        base_dir: folder a ``chart.file`` path is relative to (the folder the files will be written to).
    """
    types = _types(types)
    s = get_settings(settings)
    template = dict(s.template)
    chart_obj = None
    if isinstance(chart, Chart):
        chart_obj = chart
        if "chart" not in template:
            raise ValueError("chart: a Chart object places the encounters, but the scenario files must name the "
                             "same land: add a chart section (builtin / file / polygons_m) to the template, or pass "
                             "that section as chart")
    elif isinstance(chart, dict):
        template["chart"] = dict(chart)
    elif chart is not None:
        raise ValueError(f"chart must be None, a chart section (mapping) or a psbmpc_jax.charts.Chart, got "
                         f"{type(chart).__name__}")
    duration = s.duration_s(types)
    # a stand-in own-ship of the size and speed the files will have (the method's settings are checked against it)
    probe = dict(template, name="probe", simulation={"dt_s": s.dt_s, "duration_s": duration},
                 own_ship={"name": "OS", "position_m": [0.0, 0.0], "course_deg": 0.0,
                           "speed_mps": 0.5 * (s.own_speed_mps[0] + s.own_speed_mps[1]),
                           "length_m": s.ship_length_m, "width_m": s.ship_width_m})
    if "chart" in probe:
        probe["chart"] = {k: v for k, v in dict(probe["chart"]).items() if k != "clip_m"}   # all the land
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            sc = scenario_from_dict(probe, base_dir=base_dir, land_checks="off")
    except ValueError as exc:
        raise ValueError(f"template: {exc}") from None
    p = sc.evaluation
    land = Land(chart_obj.polygons if chart_obj is not None else _polygons_of(sc))
    if s.min_separation_m < sc.d_collision:
        raise ValueError(f"min_separation_m ({s.min_separation_m:g}) must be >= the scenario's collision distance "
                         f"({sc.d_collision:g} m: collision_distance_m, else the mpc preset's d_safe)")
    if s.own_speed_mps[0] <= p.epsilon_speed_mps:
        raise ValueError(f"own_speed_mps low ({s.own_speed_mps[0]:g}) must be > the evaluation's epsilon_speed_mps "
                         f"({p.epsilon_speed_mps:g}): slower ships count as not moving")
    for k in sorted(set(types)):
        r = s.types[k]
        if r.target_speed_mps[0] <= p.epsilon_speed_mps:
            raise ValueError(f"types.{k}.target_speed_mps low ({r.target_speed_mps[0]:g}) must be > the evaluation's "
                             f"epsilon_speed_mps ({p.epsilon_speed_mps:g}): slower ships count as not moving")
        if r.dcpa_m[1] >= p.r_stage2_m:
            raise ValueError(f"types.{k}.dcpa_m high ({r.dcpa_m[1]:g}) must be < the evaluation's stage-2 radius "
                             f"r_stage2_m ({p.r_stage2_m:g} m), or the encounter never starts")
        check_feasible(k, r, p, s.sector_margin_deg, f"types.{k}")
    return GenerationContext(settings=s, types=types, evaluation=p, d_collision=sc.d_collision, land=land,
                             template=template, duration_s=duration, base_dir=base_dir)


# ------------------------------------------------------------------------------------------------ drawing
@dataclass
class _Ship:
    pos: np.ndarray
    course: float
    speed: float

    @property
    def vel(self) -> np.ndarray:
        return velocity(self.course, self.speed)


def _uniform_arc(rng, arc) -> float:
    return float(rng.uniform(arc[0], arc[1])) % 360.0


def _land_reason(ctx: GenerationContext, ship: _Ship, who: str) -> str | None:
    land, m = ctx.land, ctx.settings.land_margin_m
    if not land:
        return None
    if land.on_land(ship.pos):
        return f"{who}_start_on_land"
    if land.near(Point(ship.pos), m):
        return f"{who}_start_near_land"
    end = ship.pos + ship.vel * ctx.duration_s
    if land.near(LineString([ship.pos, end]), m):
        return f"{who}_track_near_land"
    return None


def _draw_own(rng, ctx: GenerationContext) -> tuple[_Ship | None, str | None]:
    s = ctx.settings
    pos = np.round([rng.uniform(*s.own_north_m), rng.uniform(*s.own_east_m)], 2)
    own = _Ship(pos=pos, course=round(_uniform_arc(rng, s.own_course_deg), 3) % 360.0,
                speed=round(float(rng.uniform(*s.own_speed_mps)), 3))
    return own, _land_reason(ctx, own, "own")


def _draw_target(rng, kind: str, own: _Ship, others: list, ctx: GenerationContext):
    """One draw of a target of ``kind``: (ship, record) or (None, rejection reason)."""
    s, p = ctx.settings, ctx.evaluation
    r = s.types[kind]
    lo, hi = r.target_speed_mps
    gap = s.min_speed_difference_mps + p.overtaking_speed_margin_mps
    if kind == "overtaking":
        hi = min(hi, own.speed - gap)
    elif kind == "overtaken":
        lo = max(lo, own.speed + gap)
    if lo > hi:
        return None, "speed"
    u_t = round(float(rng.uniform(lo, hi)), 3)
    chi_rel = float(rng.uniform(*r.relative_course_deg))
    dcpa, tcpa = float(rng.uniform(*r.dcpa_m)), float(rng.uniform(*r.tcpa_s))
    side = 1.0 if rng.random() < 0.5 else -1.0
    tgt = _Ship(pos=np.zeros(2), course=round((own.course + chi_rel) % 360.0, 3) % 360.0, speed=u_t)
    v_rel = tgt.vel - own.vel
    w = float(np.hypot(*v_rel))
    if w < 1e-6:
        return None, "speed"
    normal = np.array([-v_rel[1], v_rel[0]]) / w
    tgt.pos = np.round(own.pos + side * dcpa * normal - v_rel * tcpa, 2)
    p_rel = tgt.pos - own.pos
    t_s = start_time(p_rel, v_rel, p.r_stage2_m)
    if not math.isfinite(t_s):
        return None, "sector"
    if s.start_within_stage2 and t_s > 0.0:
        return None, "start_range"
    ts = t_s + np.linspace(0.0, 2.0 * p.sample_interval_s, CHECK_SAMPLES)
    beta, alpha = pair_angles(p_rel + v_rel * ts[:, None], own.course, tgt.course)
    if not robust_class(kind, beta, alpha, own.speed, tgt.speed, p, s.sector_margin_deg).all():
        return None, "sector"
    if r.relative_bearing_deg is not None and not in_arc(float(beta[0]), r.relative_bearing_deg):
        return None, "bearing"
    sep = s.min_separation_m
    if np.hypot(*p_rel) < sep:
        return None, "separation"
    for o in others:
        if min_distance(tgt.pos - o.pos, tgt.vel - o.vel, ctx.duration_s) < sep:
            return None, "separation"
    why = _land_reason(ctx, tgt, "target")
    if why:
        return None, why
    t_cpa = max(0.0, -float(p_rel @ v_rel) / (w * w))
    rec = {"type": kind, "relative_course_deg": round((tgt.course - own.course + 180.0) % 360.0 - 180.0, 3),
           "target_speed_mps": u_t, "dcpa_m": round(float(np.hypot(*(p_rel + v_rel * t_cpa))), 3),
           "tcpa_s": round(t_cpa, 3), "side": int(side), "t_start_s": round(float(t_s), 3),
           "bearing_deg": round(float(beta[0]), 3), "contact_angle_deg": round(float(alpha[0]), 3),
           "start_range_m": round(float(np.hypot(*p_rel)), 3)}
    return tgt, rec


def _entry(name: str, ship: _Ship, ctx: GenerationContext, own: bool) -> dict:
    s = ctx.settings
    end = np.round(ship.pos + ship.vel * ctx.duration_s, 2)
    d = {"name": name, "position_m": [float(ship.pos[0]), float(ship.pos[1])], "course_deg": float(ship.course),
         "speed_mps": float(ship.speed), "waypoints_m": [[float(ship.pos[0]), float(ship.pos[1])],
                                                         [float(end[0]), float(end[1])]],
         "length_m": s.ship_length_m, "width_m": s.ship_width_m}
    if not own:
        d["colav"] = "none"
    return d


def _describe(types, recs, seed, index) -> str:
    parts = [f"TS{i + 1} {r['type']}: bearing {r['bearing_deg']:.1f} deg, relative course "
             f"{r['relative_course_deg']:.1f} deg, {r['target_speed_mps']:.2f} m/s, DCPA {r['dcpa_m']:.1f} m, "
             f"TCPA {r['tcpa_s']:.0f} s" for i, r in enumerate(recs)]
    src = "" if seed is None else f" (seed {seed}, encounter {index})"
    return (f"Generated {' + '.join(types)} encounter{src} by psbmpc_jax.scenario_generation; straight target "
            f"tracks. " + "; ".join(parts) + ".")


def _give_up(types, tries: int, counts: Counter, last_loader: str | None) -> ValueError:
    shown = ", ".join(f"{k}: {v}" for k, v in counts.most_common()) or "none"
    extra = f"; last loader error: {last_loader}" if last_loader else ""
    return ValueError(f"could not draw a {' + '.join(types)} encounter in {tries} draws (rejections: {shown}){extra}; "
                      f"widen the ranges (own-ship box, DCPA, TCPA, relative course), lower the land margin or "
                      f"raise max_tries")


def _draw(rng, ctx: GenerationContext, name: str, seed, index, validate: bool, max_tries: int) -> GeneratedEncounter:
    counts: Counter = Counter()
    tries, last_loader = 0, None
    while tries < max_tries:
        tries += 1
        own, why = _draw_own(rng, ctx)
        if why:
            counts[why] += 1
            continue
        assert own is not None                  # no rejection reason: a ship was drawn
        placed: list[_Ship] = []
        recs = []
        for kind in ctx.types:
            for _ in range(TARGET_TRIES):
                if tries >= max_tries:
                    raise _give_up(ctx.types, tries, counts, last_loader)
                tries += 1
                tgt, rec = _draw_target(rng, kind, own, placed, ctx)
                if tgt is not None:
                    placed.append(tgt)
                    recs.append(rec)
                    break
                counts[rec] += 1
            else:
                break                      # this own-ship leaves no room for the target: draw it again
        if len(placed) < len(ctx.types):
            continue
        scenario = {"name": name, "description": _describe(ctx.types, recs, seed, index), **ctx.template}
        scenario["simulation"] = {"dt_s": ctx.settings.dt_s, "duration_s": ctx.duration_s}
        scenario["own_ship"] = _entry("OS", own, ctx, True)
        scenario["targets"] = [_entry(f"TS{i + 1}", t, ctx, False) for i, t in enumerate(placed)]
        if validate:
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    scenario_from_dict(scenario, base_dir=ctx.base_dir, land_checks="error")
            except ValueError as exc:
                counts["loader"] += 1
                last_loader = str(exc)[:300]
                continue
        return GeneratedEncounter(scenario=scenario, types=ctx.types, targets=tuple(recs), rejections=dict(counts),
                                  validated=validate)
    raise _give_up(ctx.types, tries, counts, last_loader)


def _seed(seed) -> int:
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < 2 ** 63:
        raise ValueError(f"seed must be an integer in [0, 2**63), got {seed!r}")
    return int(seed)


def _max_tries(v) -> int:
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not 1 <= v <= 10_000_000:
        raise ValueError(f"max_tries must be an integer in [1, 10000000], got {v!r}")
    return int(v)


def generate_encounter(types, *, seed: int, index: int = 0, settings=None, chart=None, base_dir=None,
                       name: str | None = None, validate: bool = True, max_tries: int = MAX_TRIES,
                       context: GenerationContext | None = None) -> GeneratedEncounter:
    """One encounter: the own-ship and one target per entry of ``types``, drawn from
    ``numpy.random.default_rng([seed, index])``.

    Args:
        types: an encounter type of :data:`~psbmpc_jax.scenario_generation.ENCOUNTER_TYPES` or a list, one per
            target (``["head_on", "crossing_give_way"]``).
        seed, index: the random stream (encounter ``index`` of a batch with this seed).
        settings: a preset name (``"harbour"``, ``"open_sea"``) or :class:`GenerationSettings` (default
            ``"harbour"``).
        chart: open water (None), a scenario ``chart`` section, or a Chart (see :func:`prepare`).
        base_dir: folder a ``chart.file`` path is relative to.
        name: the scenario's name (default ``<type>_<index:04d>``).
        validate: load the mapping with :func:`psbmpc_jax.scenario.scenario_from_dict` (land checks as errors) and
            redraw if it refuses (counted as ``loader``).
        max_tries: bound on the draws (own-ship and targets together).
        context: a :func:`prepare` result to reuse (it holds the settings, chart and base_dir, so those are not
            given; ``types`` must be its types).

    Raises:
        ValueError: bad arguments or settings (naming the field), or no encounter within ``max_tries`` draws
            (with the rejection counts).
    """
    if context is None:
        ctx = prepare(types, "harbour" if settings is None else settings, chart, base_dir)
    else:
        if not isinstance(context, GenerationContext):
            raise ValueError(f"context must be a GenerationContext (from prepare), got {type(context).__name__}")
        if settings is not None or chart is not None or base_dir is not None:
            raise ValueError("give either context (it holds the settings, chart and base_dir) or settings / chart / "
                             "base_dir, not both")
        if _types(types) != context.types:
            raise ValueError(f"types {_types(types)} differ from the context's {context.types}")
        ctx = context
    seed, max_tries = _seed(seed), _max_tries(max_tries)
    if isinstance(index, bool) or not isinstance(index, (int, np.integer)) or index < 0:
        raise ValueError(f"index must be an integer >= 0, got {index!r}")
    default = ctx.types[0] if len(set(ctx.types)) == 1 else "mixed"
    name = f"{default}_{int(index):04d}" if name is None else name
    if not isinstance(name, str) or not name.strip():
        raise ValueError(f"name must be a non-empty string, got {name!r}")
    rng = np.random.default_rng([seed, int(index)])
    return _draw(rng, ctx, name, seed, int(index), bool(validate), max_tries)


def generate_encounters(types, n: int, *, seed: int, settings="harbour", chart=None, base_dir=None,
                        prefix: str | None = None, validate: bool = True,
                        max_tries: int = MAX_TRIES) -> EncounterBatch:
    """``n`` encounters (:func:`generate_encounter` with indices 0..n-1 of ``seed``; encounter i does not depend
    on ``n``), named ``<prefix>_<i:04d>`` (default prefix: the type, or ``mixed``)."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 1 <= n <= 100_000:
        raise ValueError(f"n must be an integer in [1, 100000], got {n!r}")
    ctx = prepare(types, settings, chart, base_dir)
    if prefix is None:
        prefix = ctx.types[0] if len(set(ctx.types)) == 1 else "mixed"
    if not isinstance(prefix, str) or not prefix or not all(c.isalnum() or c in "_-." for c in prefix):
        raise ValueError(f"prefix must be a non-empty name of letters, digits, '_', '-' or '.', got {prefix!r}")
    out = []
    total: Counter[str] = Counter()
    for i in range(int(n)):
        e = generate_encounter(ctx.types, seed=seed, index=i, name=f"{prefix}_{i:04d}", validate=validate,
                               max_tries=max_tries, context=ctx)
        total.update(e.rejections)
        out.append(e)
    log.info("generated %d %s encounters (seed %d); rejected draws: %s", n, "+".join(ctx.types), seed,
             dict(total) or "none")
    return EncounterBatch(encounters=tuple(out), seed=int(seed), types=ctx.types, settings=ctx.settings,
                          rejections=dict(total))
