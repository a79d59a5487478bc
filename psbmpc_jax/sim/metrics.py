"""Per-run metrics of closed-loop simulations and their aggregation over Monte Carlo runs (numpy + shapely).

Inputs (NED frame, SI units, course in radians from north, clockwise positive):

* ``t [K]`` sample times [s], strictly increasing;
* ``own [K, 4]`` own-ship rows ``(north, east, chi, U)``; ``targets [n, K, 4]`` the same for each target ship;
* ``route [m, 2]`` own-ship waypoints ``(north, east)``, m >= 2;
* ``polygons``: land, a sequence of ring sets. Each ring set is a tuple/list of ``[n, 2]`` arrays (exterior ring
  first, then holes = water), or a bare ``[n, 2]`` array (one exterior ring); NED metres.

COLREGS geometry used by :func:`classify_encounter` (bearings wrapped to [-180, 180) deg):

* ``beta``  = bearing of the target relative to the own-ship's course (> 0: target on own starboard side);
* ``alpha`` = bearing of the own-ship relative to the target's course (> 0: own-ship on the target's starboard).

Everything returned by :func:`run_metrics` and :func:`aggregate` is plain JSON (floats, ints, bools, strings,
lists, dicts, ``None`` where a quantity does not exist — never NaN).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import shapely

from ..checks import positive, waypoints
from ..numerics import wrap_angle_host
from .stops import STOP_SPEED_MPS, aggregate_ships, longest_stop, ship_metrics, stop_metrics

__all__ = [
    "HEAD_ON_SECTOR_DEG",
    "OVERTAKING_ABAFT_SECTOR_DEG",
    "OVERTAKING_AHEAD_SECTOR_DEG",
    "CROSSING_GIVE_WAY_MAX_DEG",
    "ASTERN_PASSING_ALPHA_DEG",
    "PORT_TURN_LIMIT_DEG",
    "STARBOARD_TURN_MIN_DEG",
    "SPEED_REDUCTION_RATIO",
    "ENCOUNTER_TYPES",
    "relative_bearings",
    "classify_encounter",
    "encounter_type",
    "maneuver_compliance",
    "distance_to_land",
    "cross_track_deviation",
    "course_rate",
    "voyage_metrics",
    "longest_stop",
    "STOP_SPEED_MPS",
    "run_metrics",
    "aggregate",
]

# ------------------------------------------------------------------------------------------ COLREGS thresholds
#: Rule 14 (head-on): each vessel sees the other within this many degrees of its own bow (|beta| and |alpha|
#: both below it) — reciprocal or nearly reciprocal courses, "ahead or nearly ahead".
HEAD_ON_SECTOR_DEG = 22.5
#: Rule 13 (overtaking): a vessel is overtaking when it comes up from more than 22.5 deg abaft the other's beam,
#: i.e. its bearing relative to the other vessel's course exceeds 90 + 22.5 = 112.5 deg (the stern-light sector).
OVERTAKING_ABAFT_SECTOR_DEG = 112.5
#: Rule 13: the overtaken vessel must lie within this sector about the overtaking vessel's bow (the overtaking
#: vessel is approaching from behind, heading towards it).
OVERTAKING_AHEAD_SECTOR_DEG = 67.5
#: Rule 15 (crossing): the own-ship gives way to a target with 0 < beta <= this (target on its starboard side,
#: forward of 22.5 deg abaft the beam); a target anywhere else makes the own-ship the stand-on vessel.
CROSSING_GIVE_WAY_MAX_DEG = 112.5

# --------------------------------------------------------------------------------------- compliance thresholds
#: A course more than this many degrees to port of the route leg counts as a port turn (forbidden in head-on,
#: Rule 14; for the give-way vessel in crossing, Rule 15/16; for the stand-on vessel, Rule 17(c)).
PORT_TURN_LIMIT_DEG = 10.0
#: Rule 16 "early and substantial action": a starboard turn of at least this many degrees from the route leg ...
STARBOARD_TURN_MIN_DEG = 10.0
#: ... or a speed reduction to at most this fraction of the speed at classification.
SPEED_REDUCTION_RATIO = 0.7
#: Passing astern of a crossing target: at CPA the own-ship is abaft the target's beam, |alpha| > 90 deg.
ASTERN_PASSING_ALPHA_DEG = 90.0

ENCOUNTER_TYPES = ("head-on", "crossing-give-way", "crossing-stand-on", "overtaking", "overtaken")


# -------------------------------------------------------------------------------------------------- helpers
def _json_float(v):
    """float, or None for NaN/inf/None."""
    if v is None:
        return None
    v = float(v)
    return v if math.isfinite(v) else None


def _array(a, name: str, shape_desc: str, ndim: int, last: int | None) -> np.ndarray:
    try:
        arr = np.asarray(a, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a numeric array of shape {shape_desc}, got {type(a).__name__}") from exc
    if arr.ndim != ndim or (last is not None and arr.shape[-1] != last):
        raise ValueError(f"{name} must have shape {shape_desc}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite (no NaN/inf)")
    return arr


def _check_t(t) -> np.ndarray:
    t = _array(t, "t", "[K]", 1, None)
    if t.size < 1:
        raise ValueError("t must hold at least one sample")
    if np.any(np.diff(t) <= 0):
        raise ValueError("t must be strictly increasing")
    return t


def _check_traj(a, name: str, K: int) -> np.ndarray:
    a = _array(a, name, "[K, 4] with rows (north, east, chi, U)", 2, 4)
    if a.shape[0] != K:
        raise ValueError(f"{name} must have K = len(t) = {K} rows, got {a.shape[0]}")
    return a


def _check_state(s, name: str) -> np.ndarray:
    return _array(s, name, "[4] = (north, east, chi, U)", 1, 4)


def relative_bearings(own_state, target_state):
    """``(beta, alpha)`` [rad] in [-pi, pi) for states ``[..., 4]`` (north, east, chi, U).

    beta: bearing of the target relative to the own-ship's course; alpha: bearing of the own-ship relative to
    the target's course. Positive = starboard side.
    """
    own_state = np.asarray(own_state, dtype=float)
    target_state = np.asarray(target_state, dtype=float)
    dn = target_state[..., 0] - own_state[..., 0]
    de = target_state[..., 1] - own_state[..., 1]
    beta = wrap_angle_host(np.arctan2(de, dn) - own_state[..., 2])
    alpha = wrap_angle_host(np.arctan2(-de, -dn) - target_state[..., 2])
    return beta, alpha


# ---------------------------------------------------------------------------------------------- encounters
def classify_encounter(own_state, target_state) -> str:
    """COLREGS encounter type at one instant, seen from the own-ship.

    Checked in this order (thresholds are the module constants):

    1. ``"head-on"`` (Rule 14): |beta| < HEAD_ON_SECTOR_DEG and |alpha| < HEAD_ON_SECTOR_DEG.
    2. ``"overtaking"`` (Rule 13, own-ship overtakes the target): |alpha| > OVERTAKING_ABAFT_SECTOR_DEG (own-ship
       more than 22.5 deg abaft the target's beam) and |beta| < OVERTAKING_AHEAD_SECTOR_DEG (target ahead).
    3. ``"overtaken"`` (the target overtakes the own-ship): |beta| > OVERTAKING_ABAFT_SECTOR_DEG and
       |alpha| < OVERTAKING_AHEAD_SECTOR_DEG.
    4. Crossing (Rule 15): ``"crossing-give-way"`` if 0 < beta <= CROSSING_GIVE_WAY_MAX_DEG (target on the
       own-ship's starboard side), otherwise ``"crossing-stand-on"``.

    Args:
        own_state, target_state: ``[4]`` = (north [m], east [m], chi [rad], U [m/s]).
    """
    own_state = _check_state(own_state, "own_state")
    target_state = _check_state(target_state, "target_state")
    beta, alpha = (math.degrees(float(a)) for a in relative_bearings(own_state, target_state))
    if abs(beta) < HEAD_ON_SECTOR_DEG and abs(alpha) < HEAD_ON_SECTOR_DEG:
        return "head-on"
    if abs(alpha) > OVERTAKING_ABAFT_SECTOR_DEG and abs(beta) < OVERTAKING_AHEAD_SECTOR_DEG:
        return "overtaking"
    if abs(beta) > OVERTAKING_ABAFT_SECTOR_DEG and abs(alpha) < OVERTAKING_AHEAD_SECTOR_DEG:
        return "overtaken"
    if 0.0 < beta <= CROSSING_GIVE_WAY_MAX_DEG:
        return "crossing-give-way"
    return "crossing-stand-on"


def _ranges(own: np.ndarray, target: np.ndarray) -> np.ndarray:
    return np.hypot(target[:, 0] - own[:, 0], target[:, 1] - own[:, 1])


def _classification_index(d: np.ndarray, range_m: float | None) -> int | None:
    if range_m is None:
        return 0
    below = np.flatnonzero(d < range_m)
    return int(below[0]) if below.size else None


def encounter_type(t, own, target, range_m):
    """Classify the encounter at the first sample where the range drops below ``range_m`` [m].

    Returns:
        ``(type, t_classified)``: one of :data:`ENCOUNTER_TYPES` and the time [s] of classification (``t[0]`` if
        the range is already below ``range_m``), or ``("none", nan)`` if the range never drops below it.
        ``range_m = None`` classifies at ``t[0]`` whatever the range (the initial geometry).
    """
    t = _check_t(t)
    own = _check_traj(own, "own", t.size)
    target = _check_traj(target, "target", t.size)
    if range_m is not None:
        range_m = positive(range_m, "range_m")
    k = _classification_index(_ranges(own, target), range_m)
    if k is None:
        return "none", float("nan")
    return classify_encounter(own[k], target[k]), float(t[k])


# ----------------------------------------------------------------------------------------- route geometry
def _segment_distances(points: np.ndarray, route: np.ndarray) -> np.ndarray:
    """``[K, m-1]`` distances from each point to each route leg."""
    a = route[:-1][None]                     # [1, L, 2]
    ab = np.diff(route, axis=0)[None]        # [1, L, 2]
    ap = points[:, None, :] - a              # [K, L, 2]
    s = np.clip(np.sum(ap * ab, axis=-1) / np.sum(ab * ab, axis=-1), 0.0, 1.0)
    diff = ap - s[..., None] * ab
    return np.hypot(diff[..., 0], diff[..., 1])


def cross_track_deviation(points, route):
    """Distance [m] from each point ``[K, 2]`` (north, east) to the route polyline ``[m, 2]``: ``[K]``."""
    points = _array(points, "points", "[K, 2] (north, east)", 2, 2)
    route = waypoints(route, "route", 2)
    if points.shape[0] == 0:
        return np.zeros(0)
    return _segment_distances(points, route).min(axis=1)


def _leg_courses(points: np.ndarray, route: np.ndarray) -> np.ndarray:
    """Course [rad] of the route leg nearest to each point (the leg being followed): ``[K]``."""
    legs = np.diff(route, axis=0)
    leg_chi = np.arctan2(legs[:, 1], legs[:, 0])
    return leg_chi[np.argmin(_segment_distances(points, route), axis=1)]


# ------------------------------------------------------------------------------------------------ compliance
def maneuver_compliance(t, own, target, encounter, route, *, d_collision=None):
    """COLREGS compliance of the own-ship's manoeuvre in one encounter, with the evidence.

    The evaluation window runs from the classification time to the closest point of approach (CPA = the sample
    of minimum range at or after classification). Course deviations are ``chi - (course of the nearest route
    leg)``, positive to starboard.  A "port turn" is a first course alteration of more than PORT_TURN_LIMIT_DEG
    that goes to port: the deviation that first exceeds the limit in magnitude is negative.  Heading back to the
    route after a starboard evasive turn (a later port-going deviation) is not a port turn.

    Rules (thresholds are the module constants):

    * head-on (Rule 14): compliant iff the passing is port-to-port (target on the own-ship's port side at CPA)
      and the own-ship did not turn more than PORT_TURN_LIMIT_DEG to port before CPA.
    * crossing-give-way (Rules 15, 16): compliant iff (it passed astern of the target — at CPA |alpha| >
      ASTERN_PASSING_ALPHA_DEG — or it turned >= STARBOARD_TURN_MIN_DEG to starboard, or it slowed down to
      <= SPEED_REDUCTION_RATIO of its speed at classification) and it did not turn more than PORT_TURN_LIMIT_DEG
      to port.
    * crossing-stand-on (Rule 17): compliant iff no port turn of more than PORT_TURN_LIMIT_DEG before CPA (the
      stand-on vessel may act, but not by turning to port for a vessel on its own port side).
    * overtaking (Rule 13): compliant iff it kept clear: the range never fell below ``d_collision`` after
      classification (``d_collision`` [m] is then required).
    * overtaken: ``None`` — the own-ship is the stand-on vessel, no obligation evaluated. ``"none"``: ``None``.

    Args:
        t, own, target, route: see the module docstring.
        encounter: an encounter type string (then the window starts at ``t[0]``), or the ``(type,
            t_classified)`` tuple returned by :func:`encounter_type`.
        d_collision: collision distance [m], required for ``"overtaking"``.

    Returns:
        dict with ``compliant`` (bool or None), ``reason`` (str), ``encounter``, ``t_classified``, ``t_cpa``,
        ``passing_side`` ("port"/"starboard"), ``passed_astern`` (bool), ``max_starboard_deviation_deg``,
        ``max_port_deviation_deg`` (both >= 0), ``min_speed_ratio`` (None if the speed at classification is 0),
        ``min_distance_m`` (after classification). Evidence fields are None for ``"none"``.
    """
    t = _check_t(t)
    own = _check_traj(own, "own", t.size)
    target = _check_traj(target, "target", t.size)
    route = waypoints(route, "route", 2)
    if isinstance(encounter, (tuple, list)):
        if len(encounter) != 2:
            raise ValueError(f"encounter must be a type string or a (type, t_classified) pair, got {encounter!r}")
        enc, t_cls = encounter
    else:
        enc, t_cls = encounter, float(t[0])
    allowed = ENCOUNTER_TYPES + ("none",)
    if enc not in allowed:
        raise ValueError(f"encounter type must be one of {allowed}, got {enc!r}")
    if d_collision is not None:
        d_collision = positive(d_collision, "d_collision")
    empty = {"compliant": None, "encounter": enc, "t_classified": None, "t_cpa": None, "passing_side": None,
             "passed_astern": None, "max_starboard_deviation_deg": None, "max_port_deviation_deg": None,
             "min_speed_ratio": None, "min_distance_m": None, "first_alteration": None}
    if enc == "none":
        return {**empty, "reason": "no encounter: the target never came within the classification range"}
    t_cls = float(t_cls)
    if not math.isfinite(t_cls) or t_cls < t[0] or t_cls > t[-1]:
        raise ValueError(f"t_classified must lie within [t[0], t[-1]] = [{t[0]}, {t[-1]}], got {t_cls}")

    k0 = int(np.searchsorted(t, t_cls, side="left"))
    d = _ranges(own, target)
    k_cpa = k0 + int(np.argmin(d[k0:]))
    win = slice(k0, k_cpa + 1)
    dev = np.degrees(wrap_angle_host(own[win, 2] - _leg_courses(own[win, :2], route)))
    max_stbd = float(max(0.0, dev.max()))
    max_port = float(max(0.0, -dev.min()))
    u0 = own[k0, 3]
    speed_ratio = float(own[win, 3].min() / u0) if u0 > 0 else None
    beta_cpa, alpha_cpa = relative_bearings(own[k_cpa], target[k_cpa])
    side = "port" if beta_cpa < 0 else "starboard"
    astern = bool(abs(math.degrees(float(alpha_cpa))) > ASTERN_PASSING_ALPHA_DEG)
    out = {**empty, "t_classified": float(t[k0]), "t_cpa": float(t[k_cpa]), "passing_side": side,
           "passed_astern": astern, "max_starboard_deviation_deg": max_stbd, "max_port_deviation_deg": max_port,
           "min_speed_ratio": speed_ratio, "min_distance_m": float(d[k0:].min())}
    # the manoeuvre is the FIRST course alteration beyond the limit: heading back to the route after a starboard
    # evasive turn also points to port of the leg, but is not a port turn in the sense of Rules 14/15/17
    beyond = np.flatnonzero(np.abs(dev) > PORT_TURN_LIMIT_DEG)
    first = None if beyond.size == 0 else ("starboard" if dev[beyond[0]] > 0 else "port")
    out["first_alteration"] = first
    port_turn = first == "port"

    if enc == "head-on":
        ok = side == "port" and not port_turn
        reasons = []
        if side != "port":
            reasons.append("passed starboard-to-starboard (target on own starboard side at CPA)")
        if port_turn:
            reasons.append(f"first course alteration was to port (up to {max_port:.1f} deg > {PORT_TURN_LIMIT_DEG} deg)")
        reason = "port-to-port passing without a port turn" if ok else "; ".join(reasons)
    elif enc == "crossing-give-way":
        stbd_turn = max_stbd >= STARBOARD_TURN_MIN_DEG
        slowed = speed_ratio is not None and speed_ratio <= SPEED_REDUCTION_RATIO
        acted = astern or stbd_turn or slowed
        ok = acted and not port_turn
        if ok:
            how = [w for w, f in (("passed astern", astern), (f"turned {max_stbd:.1f} deg to starboard", stbd_turn),
                                  (f"slowed to {speed_ratio if speed_ratio is not None else 0:.2f} of its speed",
                                   slowed)) if f]
            reason = "gave way: " + ", ".join(how)
        elif port_turn:
            reason = f"first course alteration was to port (up to {max_port:.1f} deg) as give-way vessel"
        else:
            reason = ("did not give way: passed ahead of the target without a starboard turn >= "
                      f"{STARBOARD_TURN_MIN_DEG} deg or a speed reduction to <= {SPEED_REDUCTION_RATIO}")
    elif enc == "crossing-stand-on":
        ok = not port_turn
        reason = ("stand-on: no port turn" if ok
                  else f"first course alteration was to port (up to {max_port:.1f} deg) as stand-on vessel")
    elif enc == "overtaking":
        if d_collision is None:
            raise ValueError("d_collision (> 0, metres) is required to evaluate an overtaking encounter")
        ok = out["min_distance_m"] >= d_collision
        reason = (f"kept clear (min range {out['min_distance_m']:.1f} m >= {d_collision} m)" if ok
                  else f"did not keep clear (min range {out['min_distance_m']:.1f} m < {d_collision} m)")
    else:  # overtaken
        return {**out, "compliant": None, "reason": "overtaken: own-ship is the stand-on vessel, no obligation"}
    return {**out, "compliant": bool(ok), "reason": reason}


# ------------------------------------------------------------------------------------------------------ land
def _ring(a, what: str) -> np.ndarray:
    r = _array(a, what, "[n, 2] (north, east)", 2, 2)
    if len(np.unique(r, axis=0)) < 3:
        raise ValueError(f"{what} needs at least 3 distinct vertices, got {r.shape[0]} vertices")
    return r


def _land_geometries(polygons) -> list:
    """Shapely geometries of the land ring sets (invalid ones repaired with make_valid)."""
    if polygons is None:
        return []
    if isinstance(polygons, shapely.Geometry):
        polygons = [polygons]
    if isinstance(polygons, np.ndarray) and polygons.ndim == 2:
        raise ValueError("polygons must be a sequence of ring sets; wrap a single [n, 2] ring in a list")
    if not isinstance(polygons, (Sequence, np.ndarray)):
        raise ValueError(f"polygons must be a sequence of ring sets, got {type(polygons).__name__}")
    geoms = []
    for i, item in enumerate(polygons):
        if isinstance(item, shapely.Geometry):
            g = item
        else:
            rings = None
            try:
                arr = np.asarray(item, dtype=float)
            except (TypeError, ValueError):
                arr = None     # ragged: a set of rings of different lengths
            if arr is not None and arr.ndim == 2:
                rings = [arr]
            elif arr is not None and arr.ndim == 3:
                rings = list(arr)
            elif arr is None and isinstance(item, (Sequence, np.ndarray)) and len(item) > 0:
                rings = list(item)
            if not rings:
                raise ValueError(f"polygons[{i}] must be an [n, 2] ring or a tuple of rings (exterior first, "
                                 f"then holes)")
            rings = [_ring(r, f"polygons[{i}] ring {j}") for j, r in enumerate(rings)]
            g = shapely.Polygon(rings[0], holes=rings[1:])
        if not g.is_valid:
            g = shapely.make_valid(g)
        if not g.is_empty:
            geoms.append(g)
    return geoms


def distance_to_land(points, polygons):
    """Exact distance [m] from each point ``[K, 2]`` (north, east) to the nearest land: ``[K]``.

    0 inside land; holes are water (a point in a hole gets its distance to the hole's shore). ``inf`` everywhere
    when there is no land. ``polygons``: see the module docstring (shapely geometries are accepted too).
    """
    points = _array(points, "points", "[K, 2] (north, east)", 2, 2)
    geoms = _land_geometries(polygons)
    if not geoms:
        return np.full(points.shape[0], np.inf)
    land = shapely.union_all(geoms) if len(geoms) > 1 else geoms[0]
    pts = shapely.points(points)
    return np.asarray(shapely.distance(pts, land), dtype=float)


# ----------------------------------------------------------------------------------------------- motion
def course_rate(t, chi):
    """Course rate [rad/s] between samples: ``wrap(chi[k+1] - chi[k]) / (t[k+1] - t[k])``, shape ``[K-1]``."""
    t = _check_t(t)
    chi = _array(chi, "chi", "[K]", 1, None)
    if chi.shape != t.shape:
        raise ValueError(f"chi must have the shape of t {t.shape}, got {chi.shape}")
    return wrap_angle_host(np.diff(chi)) / np.diff(t)


def voyage_metrics(t, own, route, arrival_radius=None) -> dict:
    """The voyage of the own-ship (Mahipala & Johansen 2024, Table X): from the start to the first sample within
    ``arrival_radius`` of the last waypoint, or the whole run when it never gets there.

    Returns ``arrived`` (bool), ``voyage_time_s`` (time of that first sample minus ``t[0]``; None when it never
    arrives or ``arrival_radius`` is None), and over the voyage: ``path_length_m`` (sum of the distances between
    consecutive positions), ``course_min_deg`` / ``course_max_deg`` (the extremes of the continuous course:
    unwrapped, in degrees, shifted so that the first course lies in [0, 360) -- a course that crosses north
    continues below 0 or above 360, so 350 -> 10 deg reads 350 .. 370), ``speed_min_mps`` / ``speed_max_mps``
    and ``voyage_mean_abs_course_rate_deg_s`` (mean |Δχ|/Δt, None for a single sample); over the whole run the
    own-ship's stops (:func:`psbmpc_jax.sim.stops.stop_metrics`: ``stops``, ``longest_stop_s``,
    ``longest_stop_start_s``, ``stopped_time_s``)."""
    t = _check_t(t)
    own = _check_traj(own, "own", t.size)
    route = waypoints(route, "route", 2)
    k_end = t.size - 1
    arrived = False
    if arrival_radius is not None:
        arrival_radius = positive(arrival_radius, "arrival_radius", allow_zero=True)
        d = np.hypot(own[:, 0] - route[-1, 0], own[:, 1] - route[-1, 1])
        hit = np.flatnonzero(d <= arrival_radius)
        if hit.size:
            k_end, arrived = int(hit[0]), True
    v = own[: k_end + 1]
    course = np.degrees(np.unwrap(v[:, 2]))
    course = course - 360.0 * np.floor(course[0] / 360.0)
    rate = course_rate(t[: k_end + 1], v[:, 2]) if k_end > 0 else np.zeros(0)
    return {
        "arrived": arrived,
        "voyage_time_s": float(t[k_end] - t[0]) if arrived else None,
        "path_length_m": float(np.sum(np.hypot(*np.diff(v[:, :2], axis=0).T))) if k_end > 0 else 0.0,
        "course_min_deg": float(course.min()),
        "course_max_deg": float(course.max()),
        "speed_min_mps": float(v[:, 3].min()),
        "speed_max_mps": float(v[:, 3].max()),
        "voyage_mean_abs_course_rate_deg_s": float(np.degrees(np.abs(rate)).mean()) if rate.size else None,
        **stop_metrics(t, own[:, 3]),
    }


# ------------------------------------------------------------------------------------------------ per run
def _stats(values) -> dict:
    v = np.asarray([x for x in values if x is not None], dtype=float)
    if v.size == 0:
        return {"min": None, "mean": None, "median": None, "max": None, "n": 0}
    return {"min": float(v.min()), "mean": float(v.mean()), "median": float(np.median(v)),
            "max": float(v.max()), "n": int(v.size)}


def run_metrics(t, own, targets, route, polygons, *, d_collision, ground_clearance, solve_times=None,
                target_names=None, classify_range=None, arrival_radius=None, evaluation=None, own_name="own-ship",
                target_routes=None, target_arrival_radii=None):
    """Metrics of one closed-loop run, as a JSON-serialisable dict.

    Args:
        t ``[K]``, own ``[K, 4]``, targets ``[n, K, 4]``, route ``[m, 2]``, polygons: see the module docstring
            (``polygons`` may be empty or None: no land).
        d_collision: [m] > 0; a target with minimum range below it is a collision.
        ground_clearance: [m] >= 0; grounding if the own-ship position comes closer than this to land (the
            simulator passes half the own-ship width).
        solve_times: optional ``[n_solves]`` planner wall times [s].
        target_names: optional n names (default ``"target_<i>"``).
        classify_range: [m] range at which each encounter is classified (:func:`encounter_type`); None
            classifies at ``t[0]`` (the initial geometry).  Not used when ``evaluation`` is given.
        evaluation: an :class:`psbmpc_jax.evaltool.EvalParams`: classify each target's encounter as the COLREGS
            evaluation tool does (:func:`psbmpc_jax.sim.situations.first_encounters`: the situation of the
            first encounter, locked at its start, ``t_classified_s``), so that the metrics and the evaluation name
            one situation; the compliance check then looks at the whole approach, from ``t[0]`` to the CPA (a
            planner acts before the range falls within r_stage2).  The simulator passes the scenario's
            ``evaluation`` section.
        own_name: the own-ship's name in ``ships``.
        target_routes, target_arrival_radii: per target its route ``[m, 2]`` and acceptance radius [m], for its
            arrival in ``ships`` (None: not judged).
        arrival_radius: [m] >= 0, the voyage ends at the first sample this close to the last waypoint (the
            simulator passes the own-ship's acceptance radius R_a); None: the voyage is the whole run and
            ``voyage_time_s`` is None.

    Returns:
        ``{"targets": [{name, min_distance_m, t_cpa_s, collision, encounter, t_classified_s, compliant,
        compliance: {...}}], "collision", "n_targets", "duration_s", "min_distance_land_m", "grounding",
        "path_deviation_mean_m", "path_deviation_max_m", "mean_abs_course_rate_deg_s", "solve_time_mean_s",
        "solve_time_max_s", "solve_time_p95_s", "n_solves"}`` and the :func:`voyage_metrics` (``arrived``,
        ``voyage_time_s``, ``path_length_m``, ``course_min_deg``, ``course_max_deg``, ``speed_min_mps``,
        ``speed_max_mps``, ``voyage_mean_abs_course_rate_deg_s``) with the own-ship's stops (``stops``,
        ``longest_stop_s``, ``longest_stop_start_s``, ``stopped_time_s``), and ``ships``: per ship (own-ship
        first) its stops and arrival (:func:`psbmpc_jax.sim.stops.ship_metrics`); None where a quantity does not
        exist (no land, no solves, a single sample, no arrival).  Each target entry has ``situation``: the
        evaluation tool's code (``HO``, ``CRGW``, ...; None without ``evaluation`` or without an encounter).
    """
    t = _check_t(t)
    K = t.size
    own = _check_traj(own, "own", K)
    tg = np.asarray(targets, dtype=float) if not (isinstance(targets, (list, tuple)) and len(targets) == 0) \
        else np.zeros((0, K, 4))
    if tg.ndim != 3 or tg.shape[1:] != (K, 4):
        raise ValueError(f"targets must have shape [n, K={K}, 4] with rows (north, east, chi, U), got {tg.shape}")
    if not np.all(np.isfinite(tg)):
        raise ValueError("targets must be finite (no NaN/inf)")
    route = waypoints(route, "route", 2)
    d_collision = positive(d_collision, "d_collision")
    ground_clearance = positive(ground_clearance, "ground_clearance", allow_zero=True)
    if classify_range is not None:
        classify_range = positive(classify_range, "classify_range")
    n = tg.shape[0]
    if target_names is None:
        names = [f"target_{i}" for i in range(n)]
    else:
        names = [str(s) for s in target_names]
        if len(names) != n:
            raise ValueError(f"target_names must have one name per target ({n}), got {len(names)}")

    if evaluation is not None:
        from .situations import first_encounters

        found = first_encounters(t, own, tg, evaluation)
    per_target = []
    for i in range(n):
        d = _ranges(own, tg[i])
        k = int(np.argmin(d))
        if evaluation is None:
            enc, t_cls = encounter_type(t, own, tg[i], classify_range)
            situation = None
        else:    # the tool's situation; the check's window still runs from t[0] (a planner acts before r_stage2)
            f = found[i]
            enc, situation = f["encounter"], f["situation"]
            t_cls = float("nan") if f["t_start_s"] is None or enc == "none" else f["t_start_s"]
        window = (enc, t_cls) if evaluation is None else (enc, float(t[0]))
        comp = maneuver_compliance(t, own, tg[i], window, route, d_collision=d_collision)
        if situation == "NAR":
            comp["reason"] = "no applicable COLREGS rule at any sample of the encounter (EvalTool situation NAR)"
        elif evaluation is not None and situation is None:
            comp["reason"] = (f"no encounter: the target never came within the evaluation's r_stage2 "
                              f"({evaluation.r_stage2_m:g} m)")
        per_target.append({"name": names[i], "min_distance_m": float(d[k]), "t_cpa_s": float(t[k]),
                           "collision": bool(d[k] < d_collision), "encounter": enc, "situation": situation,
                           "t_classified_s": _json_float(t_cls), "compliant": comp["compliant"],
                           "compliance": comp})
    if target_routes is None:
        target_routes, target_arrival_radii = [None] * n, [None] * n
    elif target_arrival_radii is None or len(target_routes) != n or len(target_arrival_radii) != n:
        raise ValueError(f"target_routes and target_arrival_radii need one entry per target ({n})")
    ships = ship_metrics(t, np.concatenate([own[None], tg], axis=0), [str(own_name)] + names,
                         [route] + list(target_routes), [arrival_radius] + list(target_arrival_radii))

    land = distance_to_land(own[:, :2], polygons)
    min_land = _json_float(land.min()) if land.size else None
    xte = cross_track_deviation(own[:, :2], route)
    rate = course_rate(t, own[:, 2])
    if solve_times is None:
        st = np.zeros(0)
    else:
        st = np.asarray(solve_times, dtype=float).reshape(-1)
        if not np.all(np.isfinite(st)) or np.any(st < 0):
            raise ValueError("solve_times must be finite and >= 0 seconds")
    return {
        "targets": per_target,
        "n_targets": n,
        "collision": any(p["collision"] for p in per_target),
        "duration_s": float(t[-1] - t[0]),
        "min_distance_land_m": min_land,
        "grounding": bool(min_land is not None and min_land < ground_clearance),
        "path_deviation_mean_m": float(xte.mean()),
        "path_deviation_max_m": float(xte.max()),
        "mean_abs_course_rate_deg_s": float(np.degrees(np.abs(rate)).mean()) if rate.size else None,
        "solve_time_mean_s": float(st.mean()) if st.size else None,
        "solve_time_max_s": float(st.max()) if st.size else None,
        "solve_time_p95_s": float(np.percentile(st, 95)) if st.size else None,
        "n_solves": int(st.size),
        **voyage_metrics(t, own, route, arrival_radius),
        "ships": ships,
    }


# ---------------------------------------------------------------------------------------------- aggregation
def aggregate(metrics) -> dict:
    """Aggregate :func:`run_metrics` dicts over runs (JSON-serialisable).

    Targets are grouped by name (first-seen order). Returns ``runs``, ``collisions`` / ``groundings`` (number of
    runs with any collision / a grounding), ``collided_runs`` / ``grounded_runs`` (run indices),
    ``targets`` (per name: ``min_distance_m`` stats {min, mean, median, max, n}, ``collisions``,
    ``compliance_rate`` over runs where compliance applies (None if it never does), ``n_compliance_evaluated``,
    ``n_compliant``, ``encounters`` {type: count}), ``min_distance_m`` (stats of every target's minimum range),
    ``compliance_rate`` (all targets), ``min_distance_land_m`` stats, ``path_deviation_mean_m`` (mean of run
    means), ``path_deviation_max_m`` (max of run maxima), ``mean_abs_course_rate_deg_s`` stats, and solve times
    (``solve_time_mean_s`` weighted by solves, ``solve_time_max_s``, ``solve_time_p95_s_max`` = the largest
    per-run p95, ``n_solves`` total); the voyage (:func:`voyage_metrics`): ``arrived_runs`` (runs that reached
    the last waypoint), stats of ``voyage_time_s`` (over the runs that arrived), ``path_length_m``,
    ``voyage_mean_abs_course_rate_deg_s``, ``speed_min_mps`` and ``speed_max_mps``, and ``course_min_deg`` /
    ``course_max_deg`` / ``speed_min_mps`` / ``speed_max_mps`` / ``longest_stop_s`` stats (run dicts without them
    are skipped); the own-ship's ``stops_total`` and ``runs_with_stops``, and ``ships``: per ship its stops and
    arrival over the runs (:func:`psbmpc_jax.sim.stops.aggregate_ships`; None when a run dict has no ``ships``).
    Per target also ``situations``: counts by the evaluation tool's code (``"none"`` without one).
    """
    if isinstance(metrics, dict) or not isinstance(metrics, Sequence):
        raise ValueError("metrics must be a list of run_metrics dicts")
    if len(metrics) == 0:
        raise ValueError("metrics must hold at least one run")
    required = ("targets", "collision", "grounding", "min_distance_land_m", "path_deviation_mean_m",
                "path_deviation_max_m", "mean_abs_course_rate_deg_s", "solve_time_mean_s", "solve_time_max_s",
                "solve_time_p95_s", "n_solves")
    for r, m in enumerate(metrics):
        if not isinstance(m, dict) or any(k not in m for k in required):
            missing = [k for k in required if not isinstance(m, dict) or k not in m]
            raise ValueError(f"metrics[{r}] is not a run_metrics dict (missing {missing})")

    collided = [r for r, m in enumerate(metrics) if any(p["collision"] for p in m["targets"])]
    grounded = [r for r, m in enumerate(metrics) if m["grounding"]]
    groups: dict[str, list[dict]] = {}
    for m in metrics:
        for p in m["targets"]:
            groups.setdefault(p["name"], []).append(p)

    def rate(entries):
        judged = [p["compliant"] for p in entries if p["compliant"] is not None]
        return (float(np.mean(judged)) if judged else None), len(judged), int(sum(judged))

    per_target = []
    for name, entries in groups.items():
        r, n_eval, n_ok = rate(entries)
        encounters: dict[str, int] = {}
        situations: dict[str, int] = {}
        for p in entries:
            encounters[p["encounter"]] = encounters.get(p["encounter"], 0) + 1
            sit = p.get("situation") or "none"
            situations[sit] = situations.get(sit, 0) + 1
        per_target.append({"name": name, "min_distance_m": _stats(p["min_distance_m"] for p in entries),
                           "collisions": int(sum(p["collision"] for p in entries)), "compliance_rate": r,
                           "n_compliance_evaluated": n_eval, "n_compliant": n_ok, "encounters": encounters,
                           "situations": situations})
    all_entries = [p for e in groups.values() for p in e]
    r_all, n_eval_all, n_ok_all = rate(all_entries)

    n_solves = [int(m["n_solves"]) for m in metrics]
    total = sum(n_solves)
    weighted = (sum(m["solve_time_mean_s"] * n for m, n in zip(metrics, n_solves) if n) / total) if total else None
    maxima = [m["solve_time_max_s"] for m in metrics if m["solve_time_max_s"] is not None]
    p95s = [m["solve_time_p95_s"] for m in metrics if m["solve_time_p95_s"] is not None]
    return {
        "runs": len(metrics),
        "collisions": len(collided),
        "groundings": len(grounded),
        "collided_runs": collided,
        "grounded_runs": grounded,
        "targets": per_target,
        "min_distance_m": _stats(p["min_distance_m"] for p in all_entries),
        "compliance_rate": r_all,
        "n_compliance_evaluated": n_eval_all,
        "n_compliant": n_ok_all,
        "min_distance_land_m": _stats(m["min_distance_land_m"] for m in metrics),
        "path_deviation_mean_m": float(np.mean([m["path_deviation_mean_m"] for m in metrics])),
        "path_deviation_max_m": float(np.max([m["path_deviation_max_m"] for m in metrics])),
        "mean_abs_course_rate_deg_s": _stats(m["mean_abs_course_rate_deg_s"] for m in metrics),
        "solve_time_mean_s": _json_float(weighted),
        "solve_time_max_s": float(max(maxima)) if maxima else None,
        "solve_time_p95_s_max": float(max(p95s)) if p95s else None,
        "n_solves": int(total),
        "arrived_runs": int(sum(1 for m in metrics if m.get("arrived"))),
        "stops_total": int(sum(m.get("stops", 0) for m in metrics)),
        "runs_with_stops": int(sum(1 for m in metrics if m.get("stops"))),
        "ships": aggregate_ships([m["ships"] for m in metrics]) if all("ships" in m for m in metrics) else None,
        **{key: _stats(m.get(key) for m in metrics)
           for key in ("voyage_time_s", "path_length_m", "course_min_deg", "course_max_deg", "speed_min_mps",
                       "speed_max_mps", "voyage_mean_abs_course_rate_deg_s", "longest_stop_s")},
    }
