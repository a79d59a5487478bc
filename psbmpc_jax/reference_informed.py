"""Float64 NumPy/``math`` oracle of the Informed SB-MPC cost (Akdağ, Fossen & Johansen 2022; docs/informed_sbmpc.md).

Written independently of :mod:`psbmpc_jax.costs.informed`: plain scalar loops over targets and times, the
thresholds transcribed again from eqs. (5), (6), (8), (10) of the paper and the choices of docs/algorithm.md §14.
Point-to-polygon distances come from :func:`psbmpc_jax.reference.polygon_distances` (the library's NumPy oracle of the
chart distance).

States are (x, y, χ, U) in NED (x north, y east [m], χ [rad] clockwise from north, U [m/s]); bearings β, α are
clockwise positive (starboard), in (−π, π].
"""

from __future__ import annotations

import math

import numpy as np

_D = math.pi / 180.0
_COS_22_5 = math.cos(22.5 * _D)
_COS_67_5 = math.cos(67.5 * _D)
_V_EPS = 0.05


# ------------------------------------------------------------------------------------------ scalar pieces
def bearing(own_x: float, own_y: float, own_chi: float, tgt_x: float, tgt_y: float) -> float:
    """Bearing of (tgt_x, tgt_y) from (own_x, own_y) relative to the heading own_chi, clockwise positive: atan2
    of the (starboard, forward) body-frame coordinates (0 at the same point)."""
    dx, dy = tgt_x - own_x, tgt_y - own_y
    c, s = math.cos(own_chi), math.sin(own_chi)
    return math.atan2(-dx * s + dy * c, dx * c + dy * s)


def beta_alpha(own, tgt) -> tuple[float, float]:
    """(β, α): the target seen from the own-ship, the own-ship seen from the target (relative to its heading)."""
    return (bearing(own[0], own[1], own[2], tgt[0], tgt[1]), bearing(tgt[0], tgt[1], tgt[2], own[0], own[1]))


def d_safe(beta: float, c_dist: float, k: float, l: float, circular: bool = False) -> float:
    """Eq. (10): c_dist / (|β|^k + l); ``circular``: c_dist (k = l = 0)."""
    if circular:
        return c_dist
    b = abs(beta)
    pw = (1.0 if k == 0 else 0.0) if b == 0 else b ** k
    return c_dist / (pw + l)


def risk(d: float, t: float, ds: float, p: float, q: float) -> float:
    """Eq. (4), crisp, with d floored at 1e-3 d_safe (as the SB-MPC pieces)."""
    if d > ds:
        return 0.0
    return abs(t) ** (-p) * (ds / max(d, 1e-3 * ds)) ** q


def flags_velocity(own, tgt) -> tuple[bool, bool, bool, bool]:
    """(OG, ON, HO, CR) from the velocities of one instant (IS-3)."""
    uo, ui = abs(own[3]), abs(tgt[3])
    dot = uo * ui * math.cos(tgt[2] - own[2])
    dx, dy = tgt[0] - own[0], tgt[1] - own[1]
    d = math.hypot(dx, dy)
    ahead = d > 0 and uo * (math.cos(own[2]) * dx + math.sin(own[2]) * dy) > _COS_67_5 * uo * d
    same = dot > _COS_67_5 * uo * ui
    og = same and uo > ui
    on = same and ui > uo
    ho = uo > _V_EPS and dot < -_COS_22_5 * uo * ui and ahead
    cr = uo > _V_EPS and dot < _COS_67_5 * uo * ui
    return og, on, ho, cr


def flags_sectors(beta0: float, alpha0: float) -> tuple[bool, bool, bool, bool]:
    """(OG, ON, HO, CR) classified at t₀ from the sectors (flag alternative of IS-3)."""
    b, a = abs(beta0), abs(alpha0)
    if b < 13.0 * _D and a < 13.0 * _D:
        return False, False, True, False
    if a > 112.5 * _D and b < 67.5 * _D:
        return True, False, False, False
    if b > 112.5 * _D and a < 67.5 * _D:
        return False, True, False, False
    return False, False, False, b <= 112.5 * _D


def mu(beta: float, d: float, flags, d_close: float) -> float:
    """Eq. (5) in NED (IS-1/2): CLOSE ∧ (R13 ∨ R14 ∨ R15)."""
    og, on, ho, cr = flags
    if not d < d_close:
        return 0.0
    r13 = og and abs(beta) < 22.5 * _D
    r14 = ho and beta > -13.0 * _D
    r15 = cr and beta >= 0.0 and not on
    return 1.0 if (r13 or r14 or r15) else 0.0


def zeta(beta: float, alpha: float, d: float, d_close: float, m: float = 1.1, n: float = 1.0) -> float:
    """Eq. (6), gated by d ≤ d_close."""
    if d > d_close:
        return 0.0
    if abs(beta) <= 22.5 * _D or abs(alpha) <= 22.5 * _D:
        return m
    if abs(alpha) <= 90.0 * _D:
        return n
    return 0.0


def grounding(d: float, t: float, d_saf: float, p_g: float, q_g: float) -> float:
    """Eq. (8) with d clamped ≥ 0.1 m."""
    if d > d_saf:
        return 0.0
    return abs(t) ** (-p_g) * (d_saf / max(d, 0.1)) ** q_g


# ------------------------------------------------------------------------------------------ the cost
_P_KEYS = ("K_coll", "kappa", "rho", "c_dist", "p", "q", "d_close")


def informed_cost(own_traj, targets, roles, t, polygons=(), *, K_coll=0.5, kappa=3.0, rho=0.0, c_dist=500.0, p=1.0,
                  q=4.0, d_close=1800.0, K_coll_r18=1.0, kappa_r18=3.0, rho_r18=3.0, c_dist_r18=1000.0, p_r18=1.0,
                  q_r18=4.0, d_close_r18=1800.0, k=2.0, l=1.0, m=1.1, n=1.0, gamma=1.0, p_g=1.0, q_g=4.0,
                  d_static_safe=200.0, classify="velocity", circular=False, grounding_on=True) -> dict:
    """The Informed SB-MPC hazard of one own-ship trajectory ``[T, 4]`` at times ``t [T]`` (``t[0]`` = t₀ is
    skipped) against ``targets`` (a list of ``[T, 4]``) with Rule-18 ``roles`` (one bool per target) and chart
    ``polygons`` (rings or ring tuples).

    Returns ``{"total", "joint", "g", "per_target"}``: joint = max over (target, t) of C R + κ μ + ρ ζ with the
    target's set (0 with no target), g = γ max_t 𝓖(min over polygons of d), total = joint + g, per_target = the
    max over t of each target's h."""
    if classify not in ("velocity", "sectors_t0"):
        raise ValueError(f"classify must be 'velocity' or 'sectors_t0', got {classify!r}")
    own_traj = np.asarray(own_traj, dtype=float)
    if len(roles) != len(targets):
        raise ValueError(f"roles must hold one flag per target ({len(targets)}), got {len(roles)}")
    sets = {False: dict(K_coll=K_coll, kappa=kappa, rho=rho, c_dist=c_dist, p=p, q=q, d_close=d_close),
            True: dict(K_coll=K_coll_r18, kappa=kappa_r18, rho=rho_r18, c_dist=c_dist_r18, p=p_r18, q=q_r18,
                       d_close=d_close_r18)}
    per_target = []
    for tgt_traj, role in zip(targets, roles):
        P = sets[bool(role)]
        tgt_traj = np.asarray(tgt_traj, dtype=float)
        flags0 = flags_sectors(*beta_alpha(own_traj[0], tgt_traj[0])) if classify == "sectors_t0" else None
        best = 0.0
        for kk in range(1, len(own_traj)):
            own, tgt = own_traj[kk], tgt_traj[kk]
            d = math.hypot(tgt[0] - own[0], tgt[1] - own[1])
            beta, alpha = beta_alpha(own, tgt)
            dvx = own[3] * math.cos(own[2]) - tgt[3] * math.cos(tgt[2])
            dvy = own[3] * math.sin(own[2]) - tgt[3] * math.sin(tgt[2])
            c = P["K_coll"] * (dvx * dvx + dvy * dvy)
            r = risk(d, float(t[kk]), d_safe(beta, P["c_dist"], k, l, circular), P["p"], P["q"])
            flags = flags_velocity(own, tgt) if flags0 is None else flags0
            h = c * r + P["kappa"] * mu(beta, d, flags, P["d_close"]) + P["rho"] * zeta(beta, alpha, d, P["d_close"],
                                                                                      m, n)
            best = max(best, h)
        per_target.append(best)
    joint = max(per_target, default=0.0)
    g = 0.0
    if grounding_on and len(polygons) and len(own_traj) > 1:
        from .reference import polygon_distances

        dmin = np.full(len(own_traj), np.inf)
        for poly in polygons:
            dj, _, _ = polygon_distances(own_traj[:, :2], poly)
            dmin = np.minimum(dmin, dj)
        g = gamma * max(grounding(float(dmin[kk]), float(t[kk]), d_static_safe, p_g, q_g)
                        for kk in range(1, len(own_traj)))
    return {"total": joint + g, "joint": joint, "g": g, "per_target": per_target}


def situation_targets(situation, params, config, r18=None) -> tuple[list, list]:
    """Every (obstacle, scenario) trajectory ``[N + 1, 4]`` of a situation (float64 reference prediction) and its
    role: ``r18[i]`` when given (one flag per obstacle), else ``getattr(obstacle, "rule18", False)``."""
    from .reference_prediction import obstacle_scenarios

    obstacles = situation.obstacles
    if r18 is not None:
        r18 = [bool(v) for v in np.asarray(r18, dtype=bool).reshape(-1)]
        if len(r18) != len(obstacles):
            raise ValueError(f"r18 must hold one flag per obstacle ({len(obstacles)}), got {len(r18)}")
    targets, roles = [], []
    for i, ob in enumerate(obstacles):
        role = r18[i] if r18 is not None else bool(getattr(ob, "rule18", False))
        for traj in obstacle_scenarios(ob, params, config):
            targets.append(traj)
            roles.append(role)
    return targets, roles


def term_reference(term, own_traj, situation, params, config, r18=None) -> float:
    """:meth:`psbmpc_jax.costs.informed.InformedSbmpcTerm.reference`: the term's float64 value for one own-ship
    trajectory (times k·dt)."""
    targets, roles = situation_targets(situation, params, config, r18)
    t = [kk * float(config.dt) for kk in range(len(own_traj))]
    kw = {name: float(getattr(term, name)) for name in term.PARAMS}
    out = informed_cost(own_traj, targets, roles, t, situation.polygons, classify=term.classify,
                        circular=term.circular, grounding_on=term.grounding, **kw)
    return float(out["total"])


__all__ = ["bearing", "beta_alpha", "d_safe", "risk", "flags_velocity", "flags_sectors", "mu", "zeta", "grounding",
           "informed_cost", "situation_targets", "term_reference"]
