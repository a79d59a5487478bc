"""Plausibility checks of closed-loop scenarios: size limits, land geometry, ship starts (host side).

Two parts:

* **Checks the loader applies** (:func:`psbmpc_jax.scenario.load_scenario`, before anything is simulated or
  compiled): the size limits below, and :func:`land_issues` -- a ship starting on land, a waypoint on land, a
  route leg through (or touching) land, two ships starting closer than the collision distance; plus warnings
  for legal but suspicious geometry (the straight extension a ship sails after its last waypoint running into
  land, land more than :data:`FAR_LAND_M` from every ship).  :func:`simulation_memory_bytes` estimates the
  simulator's memory and :func:`check_run_size` refuses runs above :data:`MAX_SIM_MEMORY_BYTES`.
* **The geometry report** of ``tools/check_scenario_geometry.py`` (:func:`route_clearances`,
  :func:`check_file`, :func:`format_report`): route clearance to land and nominal CPAs of every pair of
  ships, read from the YAML mapping directly (independently of the loader) so that it also reports on files
  the loader refuses.

Route model (both parts): the start is prepended to the waypoints unless it lies within
:data:`SAME_POINT_M` of the first one (LOS guidance joins the first leg from the start); without waypoints
the route is the straight line along ``course_deg``.
"""

from __future__ import annotations

import math
import pathlib
import warnings
from typing import Sequence

import numpy as np
import shapely
from shapely.geometry import LineString, Point, Polygon

from . import checks

__all__ = [
    "MAX_DURATION_S", "MAX_RUNS", "MAX_SEED", "MAX_STEPS", "MAX_SHIPS", "MAX_WAYPOINTS", "MAX_BEHAVIOURS",
    "MAX_MANEUVERS", "MAX_SHIP_LENGTH_M", "MAX_SHIP_WIDTH_M", "MAX_POSITION_M", "MAX_SIM_MEMORY_BYTES",
    "FAR_LAND_M", "SAME_POINT_M", "ScenarioWarning", "LandVariant", "simulation_memory_bytes", "check_run_size",
    "land_issues", "start_distance_errors", "report_land_issues", "route_clearances", "check_file", "format_report",
]

# ================================================================================================ limits
#: Longest simulation [s]: 24 h.
MAX_DURATION_S = 86_400.0
#: Most Monte Carlo runs.
MAX_RUNS = 10_000
#: Largest Monte Carlo seed (the seed also makes the ``mc`` / ``ce`` estimators' PRNG key: 32 bits).
MAX_SEED = 2 ** 32 - 1
#: Most simulation steps ``duration_s / dt_s``.
MAX_STEPS = 1_000_000
#: Most ships (own-ship and targets).
MAX_SHIPS = 100
#: Most waypoints per ship.
MAX_WAYPOINTS = 10_000
#: Most control behaviours (the product of the speed-factor and course-offset set sizes).
MAX_BEHAVIOURS = 100_000
#: Most maneuvers (sets of speed factors / course offsets).
MAX_MANEUVERS = 10
#: Largest hull length and width [m]; farthest any position or waypoint may lie from the NED origin [m]
#: (defined once, in :mod:`psbmpc_jax.checks`, for the API too).
MAX_SHIP_LENGTH_M = checks.MAX_SHIP_LENGTH_M
MAX_SHIP_WIDTH_M = checks.MAX_SHIP_WIDTH_M
MAX_POSITION_M = checks.MAX_POSITION_M
#: Largest estimated simulator memory [bytes] (2 GiB); see :func:`simulation_memory_bytes`.
MAX_SIM_MEMORY_BYTES = 2 * 1024 ** 3
#: Land farther than this from every ship's start and route draws a warning [m].
FAR_LAND_M = 50_000.0
#: A start within this distance of the first waypoint is on the route [m].
SAME_POINT_M = 1.0


class ScenarioWarning(UserWarning):
    """A scenario is valid but looks wrong (e.g. a ship that sails into land after its last waypoint)."""


def simulation_memory_bytes(n_steps: int, runs: int, n_ships: int) -> int:
    """Estimated memory [bytes] of the simulator's per-step arrays: float64 states ``[runs, ships, steps+1, 4]``
    and, per target, the own-ship's track estimates ``[.., 4]`` and covariances ``[.., 4, 4]``."""
    n_targets = max(0, int(n_ships) - 1)
    per_step = 4 * int(n_ships) + 20 * n_targets
    return 8 * int(runs) * (int(n_steps) + 1) * per_step


def check_run_size(scenario, runs: int | None = None) -> int:
    """Refuse a run whose :func:`simulation_memory_bytes` exceeds :data:`MAX_SIM_MEMORY_BYTES` (or whose
    ``runs`` exceeds :data:`MAX_RUNS`); returns the estimate.  ``runs`` defaults to the scenario's."""
    runs = scenario.runs if runs is None else runs
    if isinstance(runs, bool) or not isinstance(runs, (int, np.integer)) or not 1 <= runs <= MAX_RUNS:
        raise ValueError(f"runs must be an integer in 1..{MAX_RUNS}, got {runs!r}"[:200])
    n_steps = int(round(scenario.duration / scenario.dt))
    est = simulation_memory_bytes(n_steps, runs, len(scenario.ships))
    if est > MAX_SIM_MEMORY_BYTES:
        raise ValueError(f"{runs} runs x {n_steps + 1} steps x {len(scenario.ships)} ships need about "
                         f"{est / 1024 ** 3:.1f} GiB of simulator memory; at most "
                         f"{MAX_SIM_MEMORY_BYTES / 1024 ** 3:.0f} GiB allowed -- fewer runs (monte_carlo.runs), a "
                         f"shorter simulation.duration_s or a larger simulation.dt_s; for many runs, a campaign "
                         f"simulates them in tasks of fewer runs each (psbmpc-jax campaign --chunk-runs, "
                         f"docs/campaigns.md)")
    return est


# ================================================================================================ land checks
class LandVariant:
    """One version of the land to check against: shapely polygons (NED) and a label per polygon."""

    def __init__(self, polygons: Sequence[Polygon], labels: Sequence[str], what: str = ""):
        self.polygons = np.array(list(polygons), dtype=object)
        self.labels = list(labels)
        self.what = what
        if len(self.polygons):
            shapely.prepare(self.polygons)


def _route(position: np.ndarray, waypoints: np.ndarray) -> np.ndarray:
    wps = np.asarray(waypoints, float)
    if np.hypot(*(wps[0] - position)) > SAME_POINT_M:
        return np.vstack([position[None, :], wps])
    return wps


def _fmt(p) -> str:
    return f"({p[0]:.1f}, {p[1]:.1f})"


def _point_in_land(pt, variant: LandVariant):
    """(depth inside land [m], polygon label) of the first polygon covering ``pt``, or None."""
    if not len(variant.polygons):
        return None
    geom = Point(pt)
    hit = np.flatnonzero(shapely.covers(variant.polygons, geom))
    if not hit.size:
        return None
    j = int(hit[0])
    return float(variant.polygons[j].boundary.distance(geom)), variant.labels[j]


def _line_in_land(a, b, variant: LandVariant):
    """(length inside land [m], polygon label) of the first polygon the segment a-b meets, or None."""
    if not len(variant.polygons):
        return None
    line = LineString([a, b])
    hit = np.flatnonzero(shapely.intersects(variant.polygons, line))
    if not hit.size:
        return None
    lengths = [float(variant.polygons[j].intersection(line).length) for j in hit]
    k = int(np.argmax(lengths))
    return lengths[k], variant.labels[int(hit[k])]


def _nominal_distance(ship, duration: float) -> float:
    """Distance [m] the ship covers at its nominal speed (speed plan honoured) within ``duration``."""
    if ship.speed_plan is None or not len(ship.speed_plan):
        return float(ship.U_d) * duration
    t = np.r_[0.0, ship.speed_plan[:, 0], duration]
    u = np.r_[ship.U_d, ship.speed_plan[:, 1]]
    return float(np.sum(u * np.diff(t)))


def land_issues(ships, roles: Sequence[str], variants: Sequence[LandVariant], *, duration: float,
                default_routes: Sequence[bool] = (),
                ship_pairs: bool = True) -> tuple[list[str], list[str]]:
    """Geometry problems of a scenario's ships: ``(errors, warnings)`` as messages.

    Args:
        ships: :class:`psbmpc_jax.scenario.ShipSpec` s (own-ship first), NED.
        roles: per ship how to name it, e.g. ``"own-ship 'OS'"``, ``"target 'TS1' (targets[0])"``.
        variants: the land to check against (e.g. as loaded, and as simplified for the planner).
        duration: simulation length [s] (for the extension past the last waypoint).
        default_routes: per ship, whether its route is the default straight line (said in the message).
        ship_pairs: also check the distance of the land to the routes (once per scenario: off when checking a
            second land variant).

    Errors: a start, a waypoint or a route leg on or through land (waypoints and legs of a ship whose speeds
    -- initial, nominal, speed plan -- are all 0 are not checked: it never leaves its start).
    Warnings: the straight extension after the last waypoint (within ``duration`` at nominal speed) reaching
    land; all land farther than :data:`FAR_LAND_M` from every ship's route.
    """
    errors, warns = [], []
    for i, (s, who) in enumerate(zip(ships, roles)):
        default = bool(default_routes[i]) if i < len(default_routes) else False
        route_note = " (the default route: straight along course_deg; give waypoints_m)" if default else ""
        route = _route(s.position, s.waypoints)
        moves = max([float(s.speed), float(s.U_d)] + ([] if s.speed_plan is None else
                                                     [float(u) for u in np.asarray(s.speed_plan)[:, 1]])) > 0
        for v in variants:
            hit = _point_in_land(s.position, v)
            if hit is not None:
                errors.append(f"{who} starts {hit[0]:.1f} m inside land ({hit[1]}{v.what}) at {_fmt(s.position)}")
                continue
            if not moves:          # speed 0 throughout: the ship stays at its start, its route is never sailed
                continue
            for k, w in enumerate(s.waypoints):
                hit = _point_in_land(w, v)
                if hit is not None and not np.array_equal(w, s.position):
                    errors.append(f"{who}: waypoint {k} {_fmt(w)} lies {hit[0]:.1f} m inside land ({hit[1]}{v.what})")
            for k, (a, b) in enumerate(zip(route[:-1], route[1:])):
                hit = _line_in_land(a, b, v)
                if hit is not None:
                    how = f"crosses land for {hit[0]:.1f} m" if hit[0] > 0 else "touches land"
                    errors.append(f"{who}: route leg {k} {_fmt(a)} -> {_fmt(b)} {how} ({hit[1]}{v.what})"
                                  f"{route_note}")
        # the straight extension past the last waypoint (the simulator holds the last leg's course)
        length = float(np.sum(np.hypot(*np.diff(route, axis=0).T)))
        beyond = _nominal_distance(s, duration) - length
        if moves and beyond > 0 and len(route) >= 2:
            d = route[-1] - route[-2]
            end = route[-1] + beyond * d / np.hypot(*d)
            for v in variants:
                hit = _line_in_land(route[-1], end, v)
                if hit is not None:
                    warns.append(f"{who} passes its last waypoint {_fmt(route[-1])} and, holding the last leg's "
                                 f"course, sails {beyond:.0f} m more within the simulation -- into land "
                                 f"({hit[1]}{v.what}); extend its waypoints")
                    break
    if not ship_pairs:
        return errors, warns
    # land that is nowhere near the ships: a misplaced chart (swapped coordinates, wrong origin or zone)
    land = [v for v in variants if len(v.polygons)]
    if land:
        routes = shapely.union_all([LineString(_route(s.position, s.waypoints)) for s in ships])
        near = float(np.min(shapely.distance(land[0].polygons, routes)))
        if near > FAR_LAND_M:
            warns.append(f"the land is {near / 1000:.0f} km from every ship's route (more than "
                         f"{FAR_LAND_M / 1000:.0f} km): a misplaced chart? check the origin, the CRS and the "
                         f"coordinate order ([lon, lat] / [lat, lon], UTM [east, north])")
    return errors, warns


def start_distance_errors(ships, roles: Sequence[str], d_collision: float) -> list[str]:
    """Messages for every pair of ships whose starts are closer than ``d_collision`` (collided at t = 0)."""
    out = []
    for i in range(len(ships)):
        for j in range(i + 1, len(ships)):
            d = float(np.hypot(*(ships[i].position - ships[j].position)))
            if d < d_collision:
                out.append(f"{roles[i]} and {roles[j]} start {d:.1f} m apart, closer than the collision "
                           f"distance {d_collision:g} m (collision_distance_m, default mpc d_safe); move one")
    return out


def report_land_issues(errors: list[str], warns: list[str], mode: str) -> None:
    """Raise (``mode="error"``) or warn about the problems found by :func:`land_issues`."""
    if mode == "off":
        return
    for w in warns:
        warnings.warn(w, ScenarioWarning, stacklevel=4)
    if not errors:
        return
    head = errors[0] if len(errors) == 1 else f"{len(errors)} geometry problems: " + "; ".join(errors[:5]) + (
        f"; ... ({len(errors) - 5} more)" if len(errors) > 5 else "")
    if mode == "error":
        raise ValueError(head)
    warnings.warn(head, ScenarioWarning, stacklevel=4)


# ================================================================================================ the report
KNOT = 1852.0 / 3600.0       # m/s per knot
SAMPLE_DT_S = 1.0            # CPA sampling step [s]


def _speed(ship: dict, key: str, default=None):
    if f"{key}_mps" in ship:
        return float(ship[f"{key}_mps"])
    if f"{key}_kn" in ship:
        return float(ship[f"{key}_kn"]) * KNOT
    return default


def _land(data: dict, base_dir: pathlib.Path | None):
    """(list of land variants, each a list of shapely Polygons in NED; chart or None for UTM conversion)."""
    chart_cfg = data.get("chart")
    if not chart_cfg:
        return [], None
    if "polygons_m" in chart_cfg:
        polys = [Polygon([(float(n), float(e)) for n, e in ring]) for ring in chart_cfg["polygons_m"]]
        polys = [p if p.is_valid else shapely.make_valid(p) for p in polys]
        return [polys], None
    from . import charts

    origin_cfg = chart_cfg.get("origin_utm")
    origin = None if origin_cfg is None else (float(origin_cfg["east"]), float(origin_cfg["north"]))
    zone = None if origin_cfg is None or "zone" not in origin_cfg else int(origin_cfg["zone"])
    if "builtin" in chart_cfg:
        name = str(chart_cfg["builtin"]).lower()
        if name not in charts.BUILTIN_CHARTS:
            raise ValueError(f"unknown builtin chart {chart_cfg['builtin']!r} (known: {charts.BUILTIN_CHARTS})")
        chart = charts.load_chart(name, origin, zone=zone)
    elif "file" in chart_cfg:
        path = pathlib.Path(chart_cfg["file"])
        if not path.is_absolute() and base_dir is not None:
            path = base_dir / path
        kwargs = {} if zone is None else {"zone": zone}
        chart = charts.load_chart(path, origin, **kwargs)
    else:
        raise ValueError("chart needs one of builtin / file / polygons_m")
    if "origin_latlon" in data and origin is None:
        o = data["origin_latlon"]
        e, n = charts.lonlat_to_utm(float(o["lon"]), float(o["lat"]), chart.zone, south=chart.crs_info.south,
                                    datum=chart.crs_info.datum)
        chart = chart.with_origin((float(e), float(n)))
    variants = [list(chart.polygons)]
    if chart_cfg.get("rdp_eps_m"):
        from .rdp import simplify_chart

        variants.append(list(simplify_chart(chart, float(chart_cfg["rdp_eps_m"])).polygons))
    return variants, chart


def _point(ship: dict, key: str, chart, data: dict):
    if f"{key}_m" in ship:
        return np.asarray(ship[f"{key}_m"], float)
    if f"{key}_utm" in ship:
        if chart is None:
            raise ValueError(f"ship {ship.get('name')!r}: {key}_utm needs a chart with a UTM origin")
        return chart.utm_to_local(np.asarray(ship[f"{key}_utm"], float))
    if f"{key}_latlon" in ship:
        ll = np.asarray(ship[f"{key}_latlon"], float)
        if chart is not None:
            from .charts import lonlat_to_utm

            e, n = lonlat_to_utm(ll[..., 1], ll[..., 0], chart.zone, south=chart.crs_info.south,
                                 datum=chart.crs_info.datum)
            return chart.utm_to_local(np.stack([e, n], axis=-1))
        o = data.get("origin_latlon")
        if o is None:
            raise ValueError(f"ship {ship.get('name')!r}: {key}_latlon needs origin_latlon or a UTM chart")
        from .geo import latlon_to_ned

        return latlon_to_ned(ll[..., 0], ll[..., 1], float(o["lat"]), float(o["lon"]))
    return None


def _report_route(ship: dict, chart, duration: float, data: dict) -> tuple[np.ndarray, np.ndarray]:
    """(start [2], route [n, 2]) in NED metres."""
    start = _point(ship, "position", chart, data)
    if start is None:
        raise ValueError(f"ship {ship.get('name')!r} has no position_m / position_utm / position_latlon")
    wps = _point(ship, "waypoints", chart, data)
    if wps is None:
        speed = _speed(ship, "speed", 0.0)
        length = max(2.0 * speed * duration, 1000.0)
        chi = math.radians(float(ship["course_deg"]))
        route = np.stack([start, start + length * np.array([math.cos(chi), math.sin(chi)])])
    elif len(wps) == 1 or np.hypot(*(wps[0] - start)) > SAME_POINT_M:
        route = np.concatenate([start[None], wps])
    else:
        route = wps
    return start, route


def _speed_profile(ship: dict, t: np.ndarray) -> np.ndarray:
    """Nominal speed [m/s] at times ``t``."""
    u0 = _speed(ship, "nominal_speed", None)
    if u0 is None:
        u0 = _speed(ship, "speed", 0.0)
    u = np.full_like(t, u0, dtype=float)
    for row in ship.get("speed_plan") or []:
        u = np.where(t >= float(row["t_s"]), _speed(row, "speed"), u)
    return u


def _along(route: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Points at arc lengths ``s`` along ``route`` extended (far) beyond its last point along the last leg."""
    d = route[-1] - route[-2]
    ext = np.concatenate([route, (route[-1] + 1e6 * d / np.hypot(*d))[None]])
    cum = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(ext, axis=0).T))])
    return np.stack([np.interp(s, cum, ext[:, 0]), np.interp(s, cum, ext[:, 1])], axis=-1)


def _clearance(geom, variants) -> float:
    """Smallest distance [m] from ``geom`` to land over all chart variants (inf without land)."""
    best = math.inf
    for polys in variants:
        if polys:
            best = min(best, float(np.min(shapely.distance(np.array(polys, dtype=object), geom))))
    return best


def _inside(pt, variants) -> bool:
    return any(bool(np.any(shapely.contains(np.array(p, dtype=object), pt))) for p in variants if p)


def _cpa(pa: np.ndarray, pb: np.ndarray, t: np.ndarray) -> tuple[float, float]:
    """Exact minimum of |pa - pb| with both linearly interpolated between samples: (cpa, t_cpa)."""
    r = pa - pb
    dr = np.diff(r, axis=0)
    den = np.sum(dr * dr, axis=1)
    tau = np.where(den > 0, -np.sum(r[:-1] * dr, axis=1) / np.where(den > 0, den, 1.0), 0.0)
    tau = np.clip(tau, 0.0, 1.0)
    d = np.hypot(*(r[:-1] + tau[:, None] * dr).T)
    k = int(np.argmin(d))
    return float(d[k]), float(t[k] + tau[k] * (t[k + 1] - t[k]))


def route_clearances(data: dict, base_dir=None) -> dict:
    """Geometry of a scenario dict (as ``yaml.safe_load`` returns it).

    Land: the chart as loaded (builtin / file / inline ``polygons_m``) and, when ``rdp_eps_m`` is given, also
    the RDP-simplified chart the planner sees; the reported clearance is the smaller of the two.  ``clip_m``
    is ignored: clipping only removes land, so the unclipped chart gives the conservative (smaller) clearance.

    Returns ``{"name", "duration_s", "d_safe_m", "collision_distance_m", "n_land_polygons", "ships", "pairs"}``:
    ``ships[name]`` has ``role``, ``colav``, ``start`` (NED), ``start_in_water``, ``start_clearance_m``,
    ``legs`` (list of ``{"from", "to", "length_m", "course_deg", "clearance_m"}``), ``min_leg_clearance_m``,
    ``beyond_route_m`` (nominal distance covered past the last waypoint within the duration),
    ``extension_clearance_m`` (clearance of that part, ``None`` if 0) and ``min_clearance_m`` (over both);
    ``pairs`` is a list of ``{"a", "b", "cpa_m", "t_cpa_s", "a_at", "b_at"}`` for every pair of ships, the
    own-ship first (CPA when every ship follows its route at its nominal speed, ``speed_plan`` honoured,
    sampled every 1 s with the exact minimum of the linearly interpolated relative position in each
    interval).  Distances in metres, NED frame (north, east).
    """
    base_dir = None if base_dir is None else pathlib.Path(base_dir)
    duration = float(data["simulation"]["duration_s"])
    variants, chart = _land(data, base_dir)

    mpc = data.get("mpc") or {}
    from .presets import get_preset

    d_safe = float((mpc.get("params") or {}).get("d_safe", get_preset(mpc.get("preset", "nidelva")).params.d_safe))
    coll = data.get("collision_distance_m")

    ships = [("own_ship", data["own_ship"])] + [("target", s) for s in data.get("targets") or []]
    t = np.arange(0.0, duration + 1e-9, SAMPLE_DT_S)
    if t[-1] < duration:
        t = np.append(t, duration)
    out_ships, tracks = {}, {}
    for role, ship in ships:
        name = str(ship["name"])
        start, route = _report_route(ship, chart, duration, data)
        legs = []
        for a, b in zip(route[:-1], route[1:]):
            d = b - a
            legs.append({"from": a.round(2).tolist(), "to": b.round(2).tolist(),
                         "length_m": float(np.hypot(*d)),
                         "course_deg": float(math.degrees(math.atan2(d[1], d[0])) % 360.0),
                         "clearance_m": _clearance(LineString([a, b]), variants)})
        u = _speed_profile(ship, t)
        # piecewise-constant speed: integrate with the left value (exact for plan steps on the 1 s grid)
        s = np.concatenate([[0.0], np.cumsum(u[:-1] * np.diff(t))])
        route_len = float(np.sum(np.hypot(*np.diff(route, axis=0).T)))
        beyond = max(0.0, float(s[-1]) - route_len)
        ext_clear = None
        if beyond > 0.0:
            end = _along(route, np.array([route_len + beyond]))[0]
            ext_clear = _clearance(LineString([route[-1], end]), variants)
        tracks[name] = _along(route, s)
        leg_min = min(leg["clearance_m"] for leg in legs)
        out_ships[name] = {
            "role": role,
            "colav": ship.get("colav", "psbmpc" if role == "own_ship" else "none"),
            "start": start.round(2).tolist(),
            "start_in_water": not _inside(Point(start), variants),
            "start_clearance_m": _clearance(Point(start), variants),
            "legs": legs,
            "route_length_m": route_len,
            "min_leg_clearance_m": leg_min,
            "beyond_route_m": beyond,
            "extension_clearance_m": ext_clear,
            "min_clearance_m": leg_min if ext_clear is None else min(leg_min, ext_clear),
        }
    names = list(tracks)
    pairs = []
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            cpa, tc = _cpa(tracks[a], tracks[b], t)
            k = min(int(np.searchsorted(t, tc)), len(t) - 1)
            pairs.append({"a": a, "b": b, "cpa_m": cpa, "t_cpa_s": tc,
                          "a_at": tracks[a][k].round(1).tolist(), "b_at": tracks[b][k].round(1).tolist()})
    return {"name": data.get("name"), "duration_s": duration, "d_safe_m": d_safe,
            "collision_distance_m": d_safe if coll is None else float(coll),
            "n_land_polygons": [len(v) for v in variants], "ships": out_ships, "pairs": pairs}


def check_file(path) -> dict:
    """:func:`route_clearances` of a scenario YAML file (read with ``yaml.safe_load``)."""
    import yaml

    path = pathlib.Path(path)
    with open(path, encoding="utf-8") as f:
        data = yaml.safe_load(f)
    return route_clearances(data, base_dir=path.parent)


def format_report(res: dict) -> str:
    """:func:`route_clearances` as a text table."""
    lines = [f"scenario {res['name']}: duration {res['duration_s']:g} s, d_safe {res['d_safe_m']:g} m, "
             f"collision distance {res['collision_distance_m']:g} m, land polygons {res['n_land_polygons']}"]
    lines.append("  ship          start (n, e)          in water  start clr  min leg clr  past route  ext clr")
    for name, sh in res["ships"].items():
        ext = "-" if sh["extension_clearance_m"] is None else f"{sh['extension_clearance_m']:.1f}"
        lines.append(f"  {name:<12s} ({sh['start'][0]:9.1f}, {sh['start'][1]:8.1f})  {str(sh['start_in_water']):<8s}"
                     f"  {sh['start_clearance_m']:8.1f}  {sh['min_leg_clearance_m']:10.1f}  {sh['beyond_route_m']:9.1f}"
                     f"  {ext:>7s}")
        for j, leg in enumerate(sh["legs"]):
            lines.append(f"      leg {j}: ({leg['from'][0]:8.1f}, {leg['from'][1]:8.1f}) -> ({leg['to'][0]:8.1f}, "
                         f"{leg['to'][1]:8.1f})  {leg['length_m']:7.1f} m  course {leg['course_deg']:6.1f} deg  "
                         f"clearance {leg['clearance_m']:6.1f} m")
    lines.append("  nominal CPA (routes at nominal speed):")
    for p in res["pairs"]:
        lines.append(f"    {p['a']:>10s} - {p['b']:<10s}  {p['cpa_m']:7.1f} m at t = {p['t_cpa_s']:6.1f} s  "
                     f"({p['a_at'][0]:.0f}, {p['a_at'][1]:.0f}) / ({p['b_at'][0]:.0f}, {p['b_at'][1]:.0f})")
    return "\n".join(lines)
