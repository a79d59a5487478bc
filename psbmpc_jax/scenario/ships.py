"""The own-ship and target entries of a scenario file: position, course, speed, route, speed plan, vessel model,
route exchange and collision avoidance."""

from __future__ import annotations
import dataclasses
from typing import Any

import numpy as np
from shapely.geometry import LineString, Point
from .. import scenario_checks as limits
from ..charts import lonlat_to_utm
from ..checks import MAX_SPEED_MPS, show
from ..geo import LATLON_MAX_DISTANCE_M, check_latlon, latlon_to_ned

from ..config import as_bool, as_choice, as_mapping, as_number, as_point, as_points, as_string, check_keys, course_rad, direction_of, one_of, read_speed
from .mpc import ship_colav
from ..methods.colregs_option_settings import parse_ship_option
from ..methods.smooth_settings import SMOOTH_METHODS
from ..methods.stop_remedy_settings import parse_ship_remedy
from .schema import DEFAULT_ROUTE_MIN_M, MOTION_MODELS, RULE18_ROLES, ShipSpec, VESSEL_MODELS


_SHIP_KEYS = ("name", "position_m", "position_utm", "position_latlon", "course_deg", "speed_mps", "speed_kn",
              "nominal_speed_mps", "nominal_speed_kn", "waypoints_m", "waypoints_utm", "waypoints_latlon", "speed_plan", "length_m", "width_m", "T_chi_s",
              "T_U_s", "lookahead_m", "R_a_m", "colav", "allow_route_over_land", "shares_route", "rule18_role",
              "motion_model", "vessel_model", "leg_speeds_mps", "colregs_option", "stop_remedy")


_PLAN_KEYS = ("t_s", "speed_mps", "speed_kn")


def route_geometry(ship: ShipSpec):
    """The ship's start and route as one shapely geometry (what ``chart.clip_m`` buffers)."""
    pts = np.vstack([ship.position[None, :], ship.waypoints])
    keep = np.r_[True, np.any(pts[1:] != pts[:-1], axis=1)]
    pts = pts[keep]
    return Point(pts[0]) if len(pts) == 1 else LineString(pts)


# ---------------------------------------------------------------------------------------------- ships
def read_ship(d, where: str, *, own: bool, ctx: dict) -> ShipSpec:
    d = as_mapping(d, where)
    check_keys(d, _SHIP_KEYS, where, required=("name", "course_deg"))
    name = as_string(d["name"], f"{where}.name")
    chart = ctx["chart"]

    def utm_allowed(key):
        if chart is None:
            raise ValueError(f"{where}.{key}: UTM coordinates need a builtin or file chart (its origin converts "
                             f"them to local NED); use {key.replace('_utm', '_m')} [north, east] instead")

    def from_latlon(ll: np.ndarray, key: str) -> np.ndarray:
        """[n, 2] (lat, lon) degrees -> [n, 2] NED (the chart's UTM zone, or the local TM about origin_latlon)."""
        for k, (la, lo) in enumerate(ll):
            check_latlon(la, lo, f"{where}.{key}" + (f"[{k}]" if key.startswith("waypoints") else ""))
        if chart is not None:
            ci = chart.crs_info
            e, n = lonlat_to_utm(ll[:, 1], ll[:, 0], chart.zone, south=ci.south, datum=ci.datum)
            return chart.utm_to_local(np.stack([e, n], axis=-1))
        o = ctx["origin_latlon"]
        if o is None:
            raise ValueError(f"{where}.{key}: lat/lon positions need origin_latlon {{lat, lon}} (the geographic "
                             f"position of the NED origin) or a builtin / file chart")
        ned = latlon_to_ned(ll[:, 0], ll[:, 1], o[0], o[1])
        far = np.hypot(ned[:, 0], ned[:, 1])
        if far.max() > LATLON_MAX_DISTANCE_M:
            k = int(np.argmax(far))
            raise ValueError(f"{where}.{key}: [{ll[k, 0]:g}, {ll[k, 1]:g}] lies {far[k] / 1000:.0f} km from "
                             f"origin_latlon; at most {LATLON_MAX_DISTANCE_M / 1000:.0f} km allowed (local projection) "
                             f"-- positions are [lat, lon], not [lon, lat]")
        return ned

    def near_origin(pts: np.ndarray, key: str) -> None:
        dist = np.hypot(pts[..., 0], pts[..., 1]).reshape(-1)
        if dist.max() > limits.MAX_POSITION_M:
            k = int(np.argmax(dist))
            hint = {"_utm": "UTM is [east, north] in the chart's zone", "_latlon": "positions are [lat, lon]",
                    "_m": "local metres [north, east] about the origin"}[key[key.rindex("_"):]]
            raise ValueError(f"{where}.{key}" + (f"[{k}]" if pts.ndim == 2 else "") + f" lies {dist[k] / 1000:.0f} "
                             f"km from the scenario's origin; at most {limits.MAX_POSITION_M / 1000:.0f} km allowed -- "
                             f"{hint}")

    pkey = one_of(d, ("position_m", "position_utm", "position_latlon"), where, required=True)
    assert pkey is not None                     # required=True: one of them or an error
    pos = as_point(d[pkey], f"{where}.{pkey}")
    if pkey == "position_utm":
        utm_allowed(pkey)
        pos = chart.utm_to_local(pos)
    elif pkey == "position_latlon":
        pos = from_latlon(pos[None, :], pkey)[0]
    near_origin(pos, pkey)
    course_deg = as_number(d["course_deg"], f"{where}.course_deg")
    course = course_rad(course_deg)
    speed = read_speed(d, ("speed_mps", "speed_kn"), where, required=True, ge=0)
    U_d = read_speed(d, ("nominal_speed_mps", "nominal_speed_kn"), where, required=False, ge=0)
    U_d = speed if U_d is None else U_d

    colav = ship_colav(d.get("colav", "psbmpc" if own else "none"), own, ctx.get("method", "psbmpc"), where)
    if colav != "none" and not U_d > 0:
        raise ValueError(f"{where}: a ship with colav {colav} needs a nominal speed > 0 (nominal_speed_mps, "
                         f"default the initial speed), got {U_d:g} m/s")
    over_land = as_bool(d.get("allow_route_over_land", False), f"{where}.allow_route_over_land")
    if over_land and not own:
        raise ValueError(f"{where}.allow_route_over_land: allowed only for the own-ship (its controller avoids the "
                         f"land; a target follows its route and would sail through it)")
    method = ctx.get("method", "psbmpc")
    if own and colav in SMOOTH_METHODS and "speed_plan" in d:
        raise ValueError(f"{where}.speed_plan: not supported with mpc.method {method} (the Smooth-SBMPC model has "
                         f"one nominal speed, nominal_speed_mps); leave it out or use another method")

    plan = None
    if "speed_plan" in d:
        sp = d["speed_plan"]
        if isinstance(sp, (list, tuple)) and len(sp) > limits.MAX_WAYPOINTS:
            raise ValueError(f"{where}.speed_plan: {len(sp)} entries; at most {limits.MAX_WAYPOINTS} allowed")
        if not isinstance(sp, (list, tuple)) or not sp:
            raise ValueError(f"{where}.speed_plan must be a non-empty list of {{t_s, speed_mps | speed_kn}} "
                             f"(leave it out for a constant nominal speed), got {sp!r}")
        rows: list = []
        for i, e in enumerate(sp):
            w = f"{where}.speed_plan[{i}]"
            e = as_mapping(e, w)
            check_keys(e, _PLAN_KEYS, w, required=("t_s",))
            t = as_number(e["t_s"], f"{w}.t_s", ge=0)
            if t >= ctx["duration"]:
                raise ValueError(f"{w}.t_s ({t:g}) must be < simulation.duration_s ({ctx['duration']:g}); a "
                                 f"later entry would never apply")
            if rows and not t > rows[-1][0]:
                raise ValueError(f"{w}.t_s ({t:g}) must be greater than the previous entry's ({rows[-1][0]:g}); "
                                 f"speed_plan times must increase strictly")
            rows.append((t, read_speed(e, ("speed_mps", "speed_kn"), w, required=True, ge=0)))
        plan = np.array(rows, dtype=float)

    wkey = one_of(d, ("waypoints_m", "waypoints_utm", "waypoints_latlon"), where, required=False)
    if wkey is None:
        U_max = max([speed, U_d] + ([] if plan is None else list(plan[:, 1])))
        length = max(2.0 * U_max * ctx["route_duration"], DEFAULT_ROUTE_MIN_M)
        wps = np.stack([pos, pos + length * direction_of(course_deg)])
    else:
        if isinstance(d[wkey], (list, tuple)) and len(d[wkey]) > limits.MAX_WAYPOINTS:
            raise ValueError(f"{where}.{wkey}: {len(d[wkey])} waypoints; at most {limits.MAX_WAYPOINTS} allowed")
        wps = as_points(d[wkey], f"{where}.{wkey}", min_n=1)
        if wkey == "waypoints_utm":
            utm_allowed(wkey)
            wps = chart.utm_to_local(wps)
        elif wkey == "waypoints_latlon":
            wps = from_latlon(wps, wkey)
        near_origin(wps, wkey)
        if len(wps) == 1:
            wps = np.vstack([pos[None, :], wps])
        same = np.flatnonzero(np.all(wps[1:] == wps[:-1], axis=1))
        if same.size:
            k = int(same[0])
            raise ValueError(f"{where}.{wkey}: route points {k} and {k + 1} coincide ({wps[k].tolist()}); a route "
                             f"needs distinct consecutive points (with one point given, the start position is "
                             f"prepended)")

    prm = ctx["params"]
    pre = "os_" if own else "ob_"

    def opt(key, default, **bounds):
        return as_number(d[key], f"{where}.{key}", **bounds) if key in d else float(default)

    def size(key, default, le):
        if own or key not in d:       # the own-ship has a hull; a target may be a point object (0 and 0)
            return opt(key, default, gt=0, le=le)
        x = as_number(d[key], f"{where}.{key}", ge=0, le=le)
        return x

    spec = ShipSpec(
        name=name, position=pos, course=course, speed=speed, waypoints=np.asarray(wps, dtype=float), U_d=U_d,
        speed_plan=plan,
        length=size("length_m", 5.0, limits.MAX_SHIP_LENGTH_M),
        width=size("width_m", 3.0, limits.MAX_SHIP_WIDTH_M),
        T_chi=opt("T_chi_s", getattr(prm, pre + "T_chi"), gt=0), T_U=opt("T_U_s", getattr(prm, pre + "T_U"), gt=0),
        lookahead=opt("lookahead_m", getattr(prm, pre + "lookahead"), gt=0),
        R_a=opt("R_a_m", getattr(prm, pre + "R_a"), ge=0),
        colav=colav, allow_route_over_land=over_land,
    )
    if not own and (spec.length == 0.0) != (spec.width == 0.0):
        raise ValueError(f"{where}: length_m and width_m must both be 0 (a point object) or both > 0, got "
                         f"{spec.length:g} and {spec.width:g}")
    ctx.setdefault("default_routes", []).append(wkey is None)
    out = _exchange_and_motion(d, where)
    if "colregs_option" in d:
        out["colregs_option"] = parse_ship_option(d["colregs_option"], colav, f"{where}.colregs_option",
                                                  ctx.get("colregs_option"))
    if "stop_remedy" in d:
        out["stop_remedy"] = parse_ship_remedy(d["stop_remedy"], colav, f"{where}.stop_remedy", name)
    if "leg_speeds_mps" in d:
        ls = d["leg_speeds_mps"]
        if wkey is None:
            raise ValueError(f"{where}.leg_speeds_mps needs the ship's waypoints (one speed per leg)")
        if plan is not None:
            raise ValueError(f"{where}: leg_speeds_mps and speed_plan are exclusive (speeds per leg or over time)")
        n_legs = len(spec.waypoints) - 1
        if not isinstance(ls, (list, tuple)) or len(ls) != n_legs:
            raise ValueError(f"{where}.leg_speeds_mps must be a list of {n_legs} speeds (one per leg of the route), "
                             f"got {show(ls)}")
        out["leg_speeds"] = np.array([as_number(v, f"{where}.leg_speeds_mps[{i}]", ge=0, le=MAX_SPEED_MPS)
                                      for i, v in enumerate(ls)])
        if colav != "none" and not np.all(out["leg_speeds"] > 0):
            raise ValueError(f"{where}.leg_speeds_mps: every leg speed must be > 0 for a ship that runs a method "
                             f"(its planner needs a nominal speed), got {out['leg_speeds'].tolist()}")
    return dataclasses.replace(spec, **out)


def _exchange_and_motion(d, where: str) -> dict:
    """``shares_route``, ``rule18_role``, ``motion_model`` and ``vessel_model`` of one ship."""
    out: dict[str, Any] = {}
    if "shares_route" in d:
        out["shares_route"] = as_bool(d["shares_route"], f"{where}.shares_route")
    if "rule18_role" in d:
        out["rule18_role"] = as_choice(d["rule18_role"], RULE18_ROLES, f"{where}.rule18_role")
    if "motion_model" in d:
        out["motion_model"] = as_choice(d["motion_model"], MOTION_MODELS, f"{where}.motion_model")
    if "vessel_model" in d:
        if out.get("motion_model") != "3dof":
            raise ValueError(f"{where}.vessel_model: only with motion_model: 3dof")
        out["vessel_model"] = as_choice(d["vessel_model"], VESSEL_MODELS, f"{where}.vessel_model")
    elif out.get("motion_model") == "3dof":
        raise ValueError(f"{where}: motion_model 3dof needs vessel_model (one of {', '.join(VESSEL_MODELS)})")
    return out
