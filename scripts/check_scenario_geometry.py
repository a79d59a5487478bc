#!/usr/bin/env python
"""Geometry check of closed-loop scenario files: route clearance to land and nominal CPAs.

Reads a scenario YAML with ``yaml.safe_load`` and :mod:`psbmpc_jax.charts` only -- independently of the
loader in ``psbmpc_jax.scenario`` -- and reports

* per ship: whether the start is in water, its distance to land, and the minimum distance to land of every
  leg of its route (start prepended, see below), plus the part of the route's extension beyond the last
  waypoint that the ship covers within ``simulation.duration_s`` at nominal speed (the simulator keeps the
  last leg's course after the route ends);
* per pair of ships: the closest point of approach (CPA) when every ship follows its route at its nominal
  speed (``nominal_speed_*``, else the initial speed; ``speed_plan`` honoured), sampled every 1 s with the
  exact minimum of the linearly interpolated relative position inside each sample interval.

Land: the chart as loaded (builtin / file / inline ``polygons_m``) and, when ``rdp_eps_m`` is given, also the
RDP-simplified chart the planner sees; the reported clearance is the smaller of the two.  ``clip_m`` is
ignored: clipping only removes land, so the unclipped chart gives the conservative (smaller) clearance.

Route model (nominal, for this check): ``waypoints_*`` with one point -> the start is prepended; with >= 2
points the start is prepended unless it coincides with the first waypoint (within 1 m; the LOS guidance
then joins the first leg from the start); no waypoints -> a straight line from the start along
``course_deg``, ``max(2 * speed * duration, 1000)`` m long.

Usage::

    python scripts/check_scenario_geometry.py                      # the built-in nidelva and sakshaug files
    python scripts/check_scenario_geometry.py path/to/scenario.yaml ...
"""

from __future__ import annotations

import argparse
import math
import pathlib
import sys

import numpy as np
import shapely
import yaml
from shapely.geometry import LineString, Point, Polygon

REPO = pathlib.Path(__file__).resolve().parents[1]
SCENARIO_DIR = REPO / "psbmpc_jax" / "scenarios"
DEFAULT_FILES = (SCENARIO_DIR / "nidelva.yaml", SCENARIO_DIR / "sakshaug.yaml")

KNOT = 1852.0 / 3600.0       # m/s per knot
SAMPLE_DT_S = 1.0            # CPA sampling step [s]
SAME_POINT_M = 1.0           # start == first waypoint within this distance


# ------------------------------------------------------------------------------------------------ parsing
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
    from psbmpc_jax import charts

    origin_cfg = chart_cfg.get("origin_utm")
    origin = None if origin_cfg is None else (float(origin_cfg["east"]), float(origin_cfg["north"]))
    zone = None if origin_cfg is None or "zone" not in origin_cfg else int(origin_cfg["zone"])
    if "builtin" in chart_cfg:
        if chart_cfg["builtin"] != "trondheim":
            raise ValueError(f"unknown builtin chart {chart_cfg['builtin']!r} (known: trondheim)")
        chart = charts.trondheim_chart("psbmpc", origin=origin, zone=zone)
    elif "file" in chart_cfg:
        path = pathlib.Path(chart_cfg["file"])
        if not path.is_absolute() and base_dir is not None:
            path = base_dir / path
        kwargs = {} if zone is None else {"zone": zone}
        chart = charts.load_chart(path, origin, **kwargs)
    else:
        raise ValueError("chart needs one of builtin / file / polygons_m")
    variants = [list(chart.polygons)]
    if chart_cfg.get("rdp_eps_m"):
        from psbmpc_jax.rdp import simplify_chart

        variants.append(list(simplify_chart(chart, float(chart_cfg["rdp_eps_m"])).polygons))
    return variants, chart


def _point(ship: dict, key: str, chart):
    if f"{key}_m" in ship:
        return np.asarray(ship[f"{key}_m"], float)
    if f"{key}_utm" in ship:
        if chart is None:
            raise ValueError(f"ship {ship.get('name')!r}: {key}_utm needs a chart with a UTM origin")
        return chart.utm_to_local(np.asarray(ship[f"{key}_utm"], float))
    return None


def _route(ship: dict, chart, duration: float) -> tuple[np.ndarray, np.ndarray]:
    """(start [2], route [n, 2]) in NED metres."""
    start = _point(ship, "position", chart)
    if start is None:
        raise ValueError(f"ship {ship.get('name')!r} has no position_m / position_utm")
    wps = _point(ship, "waypoints", chart)
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


# ------------------------------------------------------------------------------------------------ the check
def route_clearances(data: dict, base_dir=None) -> dict:
    """Geometry of a scenario dict (as ``yaml.safe_load`` returns it).

    Returns ``{"name", "duration_s", "d_safe_m", "collision_distance_m", "n_land_polygons", "ships", "pairs"}``:
    ``ships[name]`` has ``role``, ``colav``, ``start`` (NED), ``start_in_water``, ``start_clearance_m``,
    ``legs`` (list of ``{"from", "to", "length_m", "course_deg", "clearance_m"}``), ``min_leg_clearance_m``,
    ``beyond_route_m`` (nominal distance covered past the last waypoint within the duration),
    ``extension_clearance_m`` (clearance of that part, ``None`` if 0) and ``min_clearance_m`` (over both);
    ``pairs`` is a list of ``{"a", "b", "cpa_m", "t_cpa_s", "a_at", "b_at"}`` for every pair of ships, the
    own-ship first.  Distances in metres, NED frame (north, east).
    """
    base_dir = None if base_dir is None else pathlib.Path(base_dir)
    duration = float(data["simulation"]["duration_s"])
    variants, chart = _land(data, base_dir)

    mpc = data.get("mpc") or {}
    from psbmpc_jax.presets import get_preset

    d_safe = float((mpc.get("params") or {}).get("d_safe", get_preset(mpc.get("preset", "nidelva")).params.d_safe))
    coll = data.get("collision_distance_m")

    ships = [("own_ship", data["own_ship"])] + [("target", s) for s in data.get("targets") or []]
    t = np.arange(0.0, duration + 1e-9, SAMPLE_DT_S)
    if t[-1] < duration:
        t = np.append(t, duration)
    out_ships, tracks = {}, {}
    for role, ship in ships:
        name = str(ship["name"])
        start, route = _route(ship, chart, duration)
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
    path = pathlib.Path(path)
    with open(path, encoding="utf-8") as f:
        data = yaml.safe_load(f)
    return route_clearances(data, base_dir=path.parent)


def format_report(res: dict) -> str:
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


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("files", nargs="*", help="scenario YAML files (default: the nidelva and sakshaug files)")
    args = ap.parse_args(argv)
    for f in args.files or DEFAULT_FILES:
        print(f"== {f}")
        print(format_report(check_file(f)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
