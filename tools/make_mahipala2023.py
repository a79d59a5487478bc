"""Write the seven scenarios of Simulation 2 of Mahipala & Johansen (2023, Section VI) on the package's Trondheim
chart: ``scenarios/mahipala2023_<k>_<name>.yaml``.

The paper gives no coordinates, speeds or durations; these are RECONSTRUCTED: the own-ship (5 m, 2 m/s) runs
the river Nidelva upstream along the ``nidelva`` scenario's route, two artificial static obstacles (circles,
r = 5 m) sit on that route at 180 m and 250 m, and point-like 5 m targets without collision avoidance play the
paper's encounters:

1. no targets (the reference path);
2. head-on: HO comes downstream and meets the own-ship near s = 325 m (t ~ 160 s);
3. crossing: CR crosses from the own-ship's starboard (west) bank at 0.4 m/s, reaching the route at s ~ 120 m
   (t ~ 60 s; the own-ship gives way);
4. head-on + crossing in close proximity: HO' meets the own-ship near s = 130 m while CR crosses there;
5. overtaking right after the second static obstacle: OT (0.6 m/s upstream) is caught near s = 470 m;
6. overtaking + crossing: 5 with CR2 crossing from starboard at s ~ 480 m (it waits until t = 176 s);
7. all combined: HO, CR and OT of 2, 3 and 5.

``python tools/make_mahipala2023.py [--check]`` (``--check`` exits 1 when a committed file differs).
"""

from __future__ import annotations

import argparse
import math
import pathlib
import sys

import numpy as np
import yaml

ROOT = pathlib.Path(__file__).resolve().parents[1]
OUT = ROOT / "scenarios"
#: the nidelva scenario's own-ship route in the Trondheim chart's default NED frame [m] (upstream)
ROUTE = np.array([[-439.3, 413.1], [-499.3, 411.1], [-699.3, 328.1], [-998.3, 196.1], [-1099.3, 150.1],
                  [-1199.3, 121.1], [-1319.3, 107.1]])
U = 2.0
CIRCLES = (180.0, 250.0)


def along(s: float, offset: float = 0.0) -> tuple[np.ndarray, float]:
    """The point at arc length ``s`` on ROUTE, ``offset`` [m] to starboard of it, and the route's course there."""
    seg = np.diff(ROUTE, axis=0)
    lengths = np.hypot(*seg.T)
    cum = np.concatenate([[0.0], np.cumsum(lengths)])
    j = int(np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(seg) - 1))
    t = seg[j] / lengths[j]
    n = np.array([-t[1], t[0]])
    p = ROUTE[j] + (s - cum[j]) * t + offset * n
    return p, math.atan2(t[1], t[0])


def path(s0: float, s1: float, offset: float, step: float = 50.0) -> list:
    """Waypoints along the route from s0 to s1 (either direction), ``offset`` to the route's starboard."""
    ss = np.arange(s0, s1, step if s1 > s0 else -step).tolist() + [s1]
    return [[round(float(v), 1) for v in along(s, offset)[0]] for s in ss]


def r1(v) -> list:
    return [round(float(x), 1) for x in v]


def stop_at(d: dict, t_s: float) -> dict:
    """The target stops (nominal speed 0) from ``t_s`` on: at the end of its path, before it would hold its
    last course into the bank."""
    d.setdefault("speed_plan", []).append({"t_s": round(t_s, 1), "speed_mps": 0.0})
    return d


def downstream(name: str, s_start: float, speed: float = U) -> dict:
    """A target coming downstream along the route, 3 m to its own starboard (the route's port), to s = 10 m."""
    p, chi = along(s_start, -3.0)
    return stop_at({"name": name, "position_m": r1(p), "course_deg": round(math.degrees(chi + math.pi) % 360, 1),
                    "speed_mps": speed, "nominal_speed_mps": speed, "waypoints_m": path(s_start, 10.0, -3.0),
                    "length_m": 5, "width_m": 2}, (s_start - 10.0) / speed)


def upstream(name: str, s_start: float, speed: float) -> dict:
    p, chi = along(s_start, 2.0)
    return {"name": name, "position_m": r1(p), "course_deg": round(math.degrees(chi) % 360, 1),
            "speed_mps": speed, "nominal_speed_mps": speed, "waypoints_m": path(s_start, 1000.0, 2.0),
            "length_m": 5, "width_m": 2}


def crossing(name: str, s_cross: float, speed: float, wait_s: float = 0.0, start_off: float = 24.0) -> dict:
    """A target crossing the river from the route's starboard (west) side to port, reaching the route at
    arc length ``s_cross``; it waits ``wait_s`` seconds first (a speed plan)."""
    p0, chi = along(s_cross, start_off)
    p1, _ = along(s_cross, -22.0)
    course = math.atan2(p1[1] - p0[1], p1[0] - p0[0])
    d = {"name": name, "position_m": r1(p0), "course_deg": round(math.degrees(course) % 360, 1),
         "speed_mps": 0.0 if wait_s else speed, "nominal_speed_mps": 0.0 if wait_s else speed,
         "waypoints_m": [r1(p1)], "length_m": 5, "width_m": 2}
    if wait_s:
        d["speed_plan"] = [{"t_s": wait_s, "speed_mps": speed}]
    return stop_at(d, wait_s + (start_off + 22.0) / speed)


HO = downstream("HO", 650.0)
HO_NEAR = downstream("HO", 260.0)
CR = crossing("CR", 120.0, 0.4)
OT = upstream("OT", 330.0, 0.6)
CR2 = crossing("CR2", 480.0, 0.4, wait_s=176.0)
CASES = (
    ("1_reference", "no targets: the reference path", ()),
    ("2_head_on", "head-on: HO meets the own-ship near s = 325 m (t ~ 160 s)", (HO,)),
    ("3_crossing", "crossing from starboard: CR reaches the route near s = 120 m (t ~ 60 s); give way", (CR,)),
    ("4_head_on_crossing", "head-on and crossing in close proximity near s = 130 m (t ~ 60-65 s)", (HO_NEAR, CR)),
    ("5_overtaking", "overtaking OT (0.6 m/s) right after the second static obstacle, near s = 470 m", (OT,)),
    ("6_overtaking_crossing", "overtaking OT with CR2 crossing from starboard near s = 480 m", (OT, CR2)),
    ("7_combined", "HO, CR and OT of scenarios 2, 3 and 5 together", (HO, CR, OT)),
)


def scenario(key: str, what: str, targets) -> dict:
    circles = [{"center_m": r1(along(s)[0]), "radius_m": 5} for s in CIRCLES]
    return {
        "name": f"mahipala2023_{key}",
        "description": (f"RECONSTRUCTED (Mahipala & Johansen, MED 2023) Simulation 2, scenario {key[0]}: "
                        f"{what}. Own-ship 5 m at 2 m/s upstream in the river Nidelva (Trondheim chart, the nidelva "
                        f"route), two artificial static obstacles (r 5 m) on the route at s = 180 and 250 m; "
                        f"targets without collision avoidance. Geometry proposed here, not the paper's (it gives "
                        f"none). Regenerate: python tools/make_mahipala2023.py"),
        "simulation": {"dt_s": 1, "duration_s": 360},
        "monte_carlo": {"runs": 10, "seed": 0},
        "collision_distance_m": 5,
        "mpc": {
            "preset": "nidelva", "update_period_s": 1, "method": "two_level",
            "sbmpc": {"preset": "river", "k_U": 2.5, "Delta_U": 2.0},
            "two_level": {
                "N_p": 30, "dt_s": 1, "U_max_mps": 2, "r_os_m": 3, "r_accept_m": 10, "sbmpc_T_s": 120,
                "sbmpc_dt_s": 1, "plan_stride": 5,
                "corridor": {"half_width_m": 30, "sample_m": 2, "radius_m": 80, "margin_m": 5,
                             "circle_margin_m": 2},
                "prediction": {"beta_deg": 5, "d_critical_m": 30},
                "zeta": {"eta1": 0.25, "eta2": 0.01, "d_close_m": 30, "d_safe_m": 3, "shape": "printed"},
                "static_obstacles": circles,
            },
        },
        "evaluation": {"range_scale": 0.16666667},
        "sensor": {"position_std_m": 0.5, "period_s": 1, "filter_R_scale": 1, "sigma_a_mps2": 0.05,
                   "U_max_mps": 4},
        "chart": {"builtin": "trondheim", "rdp_eps_m": 2, "clip_m": 400},
        "own_ship": {"name": "OS", "position_m": r1(ROUTE[0]), "course_deg": round(math.degrees(along(0.0)[1]) % 360, 1),
                     "speed_mps": U, "nominal_speed_mps": U, "waypoints_m": [r1(p) for p in ROUTE[1:]],
                     "length_m": 5, "width_m": 2},
        "targets": list(targets),
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="exit 1 when a committed file differs")
    args = ap.parse_args(argv)
    bad = 0
    for key, what, targets in CASES:
        text = ("# RECONSTRUCTED scenario of Mahipala & Johansen 2023 (see tools/make_mahipala2023.py); generated, do not "
                "edit.\n"
                + yaml.safe_dump(scenario(key, what, targets), sort_keys=False, width=120))
        path = OUT / f"mahipala2023_{key}.yaml"
        if args.check:
            if not path.exists() or path.read_text() != text:
                print(f"differs: {path}")
                bad += 1
        else:
            path.write_text(text)
            print(f"wrote {path}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
