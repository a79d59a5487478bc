"""Float64 NumPy/``math`` oracle of the Smooth-SBMPC cost components (docs/smooth_sbmpc.md).

Written independently of the JAX code (:mod:`psbmpc_jax.costs.colregs_fuzzy`, :mod:`psbmpc_jax.costs.sbmpc`,
:mod:`psbmpc_jax.costs.manoeuvring`): plain scalar loops over targets, times and output-grid points, every
constant transcribed again from the paper's tables.  The tests compare the two on random inputs (atol 1e-10).

States are (x, y, χ, U) in NED (x north, y east [m], χ [rad] clockwise from north, U [m/s]).  Controls are
(speed factor U_m, course offset χ_m [rad]).
"""

from __future__ import annotations

import math

import numpy as np

_LN99 = math.log(99.0)

# Tables I-III (degrees, slopes per degree) and the output membership functions (mu_false read as [0.05, -114.878]:
# choice SM-3, docs/algorithm.md §12).
_OT = (67.5, -1.5317)
_CR_RISE, _CR_FALL = (67.5, 0.919), (157.5, -0.919)
_HO = (157.5, 0.919)
_SB = (0.0, 0.919)
_SBAH_FALL = (67.5, -0.919)
_MU_TRUE = (0.95, 114.878)
_MU_FALSE = (0.05, -114.878)
_COS_22_5 = math.cos(math.radians(22.5))
_COS_67_5 = math.cos(math.radians(67.5))


# ------------------------------------------------------------------------------------------ scalar helpers
def sigmoid(z: float, a1: float, a2: float) -> float:
    """1 / (1 + exp(−a₂ (z − a₁))), without overflow."""
    x = a2 * (z - a1)
    if x >= 0:
        return 1.0 / (1.0 + math.exp(-x))
    e = math.exp(x)
    return e / (1.0 + e)


def smax(a: float, b: float, eps: float) -> float:
    return 0.5 * (a + b + math.sqrt((a - b) * (a - b) + eps))


def smin(a: float, b: float, eps: float) -> float:
    return -smax(-a, -b, eps)


def clip(v: float) -> float:
    return 1.0 if v > 1.0 else (0.0 if v < 0.0 else v)


def wrap_pm_pi(a: float) -> float:
    """Wrap to (−π, π]."""
    w = a - 2.0 * math.pi * math.floor((a + math.pi) / (2.0 * math.pi))     # [−π, π)
    return math.pi if w <= -math.pi else w


# ------------------------------------------------------------------------------------------ geometry
def encounter_inputs(own, tgt) -> tuple[float, float, float]:
    """(ΔCOG [rad] ∈ [0, π], RB [rad] ∈ (−π, π], d [m]) of one pair of states; RB = 0 at d = 0."""
    xo, yo, cho = float(own[0]), float(own[1]), float(own[2])
    xt, yt, cht = float(tgt[0]), float(tgt[1]), float(tgt[2])
    dx, dy = xt - xo, yt - yo
    d = math.hypot(dx, dy)
    rb = 0.0 if (dx == 0.0 and dy == 0.0) else wrap_pm_pi(math.atan2(dy, dx) - cho)
    return abs(wrap_pm_pi(cht - cho)), rb, d


# ------------------------------------------------------------------------------------------ FIS
def fis_memberships(dcog_deg: float, rb_deg: float, d: float, d_cl: float, e_cl: float) -> dict:
    sb = sigmoid(rb_deg, *_SB)
    return {
        "OT": sigmoid(dcog_deg, *_OT),
        "CR": sigmoid(dcog_deg, *_CR_RISE) * sigmoid(dcog_deg, *_CR_FALL),
        "HO": sigmoid(dcog_deg, *_HO),
        "SB": sb,
        "SBAH": sb * sigmoid(rb_deg, *_SBAH_FALL),
        "CL": sigmoid(d, d_cl, -_LN99 / e_cl),
    }


def fis_mu(delta_cog: float, rb: float, d: float, *, d_cl: float = 40.0, e_cl: float = 5.0, eps: float = 1e-6,
           n_y: int = 201, completion: str = "default_false", angles: str = "rad") -> float:
    """FIS_colregs output μ of one (ΔCOG, RB, d) triple (rectangle-rule CoG over n_y points)."""
    if completion not in ("default_false", "literal"):
        raise ValueError(f"completion must be 'default_false' or 'literal', got {completion!r}")
    k = 1.0 if angles == "deg" else 180.0 / math.pi
    m = fis_memberships(float(delta_cog) * k, float(rb) * k, float(d), d_cl, e_cl)
    r1 = clip(smin(smin(m["HO"], m["SBAH"], eps), m["CL"], eps))
    r2 = clip(smin(smin(m["CR"], m["SB"], eps), m["CL"], eps))
    r3 = clip(smin(1.0 - m["SB"], 1.0 - m["CL"], eps))
    r_t = clip(smax(r1, r2, eps))
    r_f = clip(smax(r3, 1.0 - r_t, eps)) if completion == "default_false" else r3
    num = den = 0.0
    for n in range(n_y):
        y = n / (n_y - 1)
        a = smax(r_t * sigmoid(y, *_MU_TRUE), r_f * sigmoid(y, *_MU_FALSE), eps)
        num += y * a
        den += a
    return num / den if den > 0 else 0.5


def fis_mu_states(own, tgt, **kw) -> float:
    return fis_mu(*encounter_inputs(own, tgt), **kw)


# ------------------------------------------------------------------------------------------ SB-MPC pieces
def sigma_coll(d: float, d_safe: float, w_coll: float = 0.1) -> float:
    return sigmoid(d, d_safe, -_LN99 / (w_coll * d_safe))


def adhoc_risk(d: float, t: float, d_safe: float, p: float = 1.0, q: float = 4.0, crisp: bool = False) -> float:
    if t == 0:
        raise ValueError("R is singular at t = 0 (tau_0)")
    if crisp and d > d_safe:
        return 0.0
    d_eff = max(d, 1e-3 * d_safe)
    return abs(t) ** (-p) * (d_safe / d_eff) ** q


def collision_weight(own, tgt, K_coll: float = 1.0) -> float:
    ex = own[3] * math.cos(own[2]) - tgt[3] * math.cos(tgt[2])
    ey = own[3] * math.sin(own[2]) - tgt[3] * math.sin(tgt[2])
    return K_coll * (ex * ex + ey * ey)


def collision_hazard(own, tgt, t: float, *, d_safe: float = 10.0, K_coll: float = 1.0, p: float = 1.0,
                     q: float = 4.0, w_coll: float = 0.1, risk: str = "smooth") -> float:
    d = math.hypot(tgt[0] - own[0], tgt[1] - own[1])
    c = collision_weight(own, tgt, K_coll)
    if risk == "crisp":
        return c * adhoc_risk(d, t, d_safe, p, q, crisp=True)
    if risk != "smooth":
        raise ValueError(f"risk must be 'smooth' or 'crisp', got {risk!r}")
    return sigma_coll(d, d_safe, w_coll) * c * adhoc_risk(d, t, d_safe, p, q)


def colregs_boolean(own, tgt, d_cl: float = 40.0, v_eps: float = 0.05) -> float:
    """Johansen's μ (5)-(10), 1.0 or 0.0, with the speed guard ‖v_o‖ > v_eps on HEAD-ON and CROSSED."""
    vo = (own[3] * math.cos(own[2]), own[3] * math.sin(own[2]))
    vi = (tgt[3] * math.cos(tgt[2]), tgt[3] * math.sin(tgt[2]))
    no, ni = math.hypot(*vo), math.hypot(*vi)
    dot = vo[0] * vi[0] + vo[1] * vi[1]
    dx, dy = tgt[0] - own[0], tgt[1] - own[1]
    d = math.hypot(dx, dy)
    close = d < d_cl
    rb = math.atan2(dy, dx) - own[2]
    starboard = d > 0 and math.sin(rb) > 0            # RB in (0, π)
    ahead = d > 0 and (vo[0] * dx + vo[1] * dy) / d > _COS_67_5 * no
    head_on = no > v_eps and dot < -_COS_22_5 * no * ni and ahead
    crossed = no > v_eps and dot < _COS_67_5 * no * ni
    overtaken = dot > _COS_67_5 * no * ni and ni > no
    return 1.0 if (close and starboard and (head_on or (crossed and not overtaken))) else 0.0


def applied_trajectory(situation, behaviour, last_offsets, params, config) -> np.ndarray:
    """The own-ship trajectory ``[N+1, 4]`` of the applied offsets ``last_offsets`` held over every maneuver of
    ``behaviour``'s shape (the rollout the transitional term compares passing sides against)."""
    from .reference_prediction import ownship_trajectory

    held = np.broadcast_to(np.asarray(last_offsets, float), np.shape(behaviour)).copy()
    return ownship_trajectory(situation.own_ship, held, params, config)


def transitional_situation(own, tgt, d_cl: float) -> bool:
    """CLOSE ∧ (OVERTAKING ∨ OVERTAKEN ∨ CROSSED) of the present states (x, y, χ, U) (the JAX
    ``costs.sbmpc.transitional_situation``)."""
    vo = own[3] * np.array([math.cos(own[2]), math.sin(own[2])])
    vi = tgt[3] * np.array([math.cos(tgt[2]), math.sin(tgt[2])])
    L = np.array([tgt[0] - own[0], tgt[1] - own[1]])
    dot, norms = float(vo @ vi), float(own[3] * tgt[3])
    if not float(L @ L) < d_cl * d_cl:
        return False
    same = dot > math.cos(math.radians(67.5)) * norms
    overtaken = same and tgt[3] > own[3]
    overtaking = same and own[3] > tgt[3] and float(vo @ L) > 0
    crossed = own[3] > 0.05 and dot < math.cos(math.radians(67.5)) * norms and dot >= -math.cos(math.radians(22.5)) * norms
    return bool(overtaken or overtaking or crossed)


def passing_side(own_traj, tgt_traj) -> int:
    """+1 / −1 / 0: the side (starboard / port / dead ahead or astern) of the target at the closest point of the
    two trajectories ``[K, 4]`` (first step of the smallest distance)."""
    d2 = [(b[0] - a[0]) ** 2 + (b[1] - a[1]) ** 2 for a, b in zip(own_traj, tgt_traj)]
    k = int(np.argmin(d2))
    a, b = own_traj[k], tgt_traj[k]
    s = (b[1] - a[1]) * math.cos(a[2]) - (b[0] - a[0]) * math.sin(a[2])
    return int(np.sign(s))


def sbmpc_cost(own_traj, targets, t, *, component: str = "joint", aggregation: str = "max", d_safe: float = 10.0,
               K_coll: float = 1.0, p: float = 1.0, q: float = 4.0, w_coll: float = 0.1, kappa: float = 10.0,
               d_cl: float = 40.0, e_cl: float = 5.0, eps: float = 1e-6, n_y: int = 201,
               completion: str = "default_false", risk: str = "smooth", colregs: str = "fis",
               lambda_T: float = 0.0, applied_traj=None, joint_extra=None) -> float:
    """Aggregated SB-MPC hazard of one own-ship trajectory ``[T, 4]`` against target trajectories (a list of
    ``[T, 4]``) at times ``t [T]`` (``t[0]`` = τ₀ is skipped).  ``component``: ``"coll"`` (σCR or crisp CR),
    ``"colregs"`` (κμ) or ``"joint"`` (their sum per (target, time)); ``aggregation``: ``"max"`` or ``"sum"``
    over (target, time); no target gives 0.  ``lambda_T > 0`` with ``applied_traj [T, 4]`` (the rollout of the
    applied offsets) adds λ·T per (target, time) to the joint component: T = 1 when the target is in a
    transitional situation now and passes on the other side than under the applied offsets (τ ≥ τ₀ + T_s).
    ``joint_extra [T]`` (an own-ship-only term, the ζ of Mahipala & Johansen 2023) is added per (target, time) to the
    joint component; with no target the result is then max over τ ≥ τ₀ + T_s of ``joint_extra``."""
    if aggregation not in ("max", "sum"):
        raise ValueError(f"aggregation must be 'max' or 'sum', got {aggregation!r}")
    if component not in ("coll", "colregs", "joint"):
        raise ValueError(f"component must be 'coll', 'colregs' or 'joint', got {component!r}")
    own_traj = np.asarray(own_traj, dtype=float)
    out = 0.0
    first = True
    for tgt_traj in targets:
        tgt_traj = np.asarray(tgt_traj, dtype=float)
        T_i = 0.0
        if lambda_T > 0 and component == "joint":
            if applied_traj is None:
                raise ValueError("lambda_T > 0 needs applied_traj (the rollout of the applied offsets)")
            applied = np.asarray(applied_traj, dtype=float)
            flip = passing_side(own_traj[1:], tgt_traj[1:]) * passing_side(applied[1:], tgt_traj[1:]) < 0
            T_i = float(flip and transitional_situation(own_traj[0], tgt_traj[0], d_cl))
        for k in range(1, len(own_traj)):
            own, tgt = own_traj[k], tgt_traj[k]
            h = 0.0
            if component in ("coll", "joint"):
                h += collision_hazard(own, tgt, float(t[k]), d_safe=d_safe, K_coll=K_coll, p=p, q=q, w_coll=w_coll,
                                      risk=risk)
            if component in ("colregs", "joint"):
                if colregs == "fis":
                    mu = fis_mu_states(own, tgt, d_cl=d_cl, e_cl=e_cl, eps=eps, n_y=n_y, completion=completion)
                elif colregs == "boolean":
                    mu = colregs_boolean(own, tgt, d_cl)
                else:
                    raise ValueError(f"colregs must be 'fis' or 'boolean', got {colregs!r}")
                h += kappa * mu
            if component == "joint":
                h += lambda_T * T_i
                if joint_extra is not None:
                    h += float(joint_extra[k])
            if aggregation == "sum":
                out += h
            elif first or h > out:
                out = h
            first = False
    if first and joint_extra is not None and component == "joint" and len(own_traj) > 1:
        extra = np.asarray(joint_extra, dtype=float)[1:]
        out = float(np.sum(extra)) if aggregation == "sum" else float(np.max(extra))
    return float(out)


def land_distance(points, polygons) -> np.ndarray:
    """Distance of each point ``[K, 2]`` to the nearest of the situation's ``polygons`` (0 inside; +inf with
    none), from the float64 polygon distance of :mod:`psbmpc_jax.reference`."""
    from . import reference as ref
    from .situation import polygon_rings

    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    d = np.full(len(pts), np.inf)
    for poly in polygons:
        rings = polygon_rings(poly)
        d = np.minimum(d, ref.polygon_distances(pts, rings[0] if len(rings) == 1 else tuple(rings))[0])
    return d


def signed_land_distance(points, polygons) -> np.ndarray:
    """Signed distance of each point ``[K, 2]`` to the land ``polygons`` (rings ``[n, 2]``; negative inside a
    polygon, even–odd rule per polygon), from shapely in float64."""
    from shapely.geometry import Point, Polygon

    polys = [Polygon(np.asarray(r, dtype=float)) for r in polygons]
    out = []
    for p in np.asarray(points, dtype=float).reshape(-1, 2):
        pt = Point(p)
        d = min(poly.exterior.distance(pt) for poly in polys)
        out.append(-d if any(poly.contains(pt) for poly in polys) else d)
    return np.asarray(out)


# ------------------------------------------------------------------------------------------ DOCP guidance
def route_los_courses(positions, waypoints, segment: int, lookahead: float, R_a: float) -> np.ndarray:
    """LOS courses [rad] of the route ``waypoints [W, 2]`` at ``positions [K, 2]`` visited in order, starting on
    ``segment``: at each position the waypoint switch (within ``R_a`` of the next waypoint, or past the
    segment's end), then α_z + atan(−e/Δ) (α of the last segment past the last waypoint).  Plain loops."""
    w = np.asarray(waypoints, dtype=float)
    n = len(w)
    alpha = [math.atan2(w[z + 1, 1] - w[z, 1], w[z + 1, 0] - w[z, 0]) for z in range(n - 1)]
    seg_len = [math.hypot(w[z + 1, 0] - w[z, 0], w[z + 1, 1] - w[z, 1]) for z in range(n - 1)]
    z = int(segment)
    out = []
    for x, y in np.asarray(positions, dtype=float).reshape(-1, 2):
        if z <= n - 2:
            along = (x - w[z, 0]) * math.cos(alpha[z]) + (y - w[z, 1]) * math.sin(alpha[z])
            if math.hypot(x - w[z + 1, 0], y - w[z + 1, 1]) <= R_a or along >= seg_len[z]:
                z += 1
        if z <= n - 2:
            e = -(x - w[z, 0]) * math.sin(alpha[z]) + (y - w[z, 1]) * math.cos(alpha[z])
            out.append(alpha[z] + math.atan(-e / lookahead))
        else:
            out.append(alpha[n - 2])
    return np.asarray(out)


def line_los_courses(positions, p0, p_end, heading: float, lookahead: float) -> np.ndarray:
    """LOS courses [rad] on the line from ``p0`` through ``p_end`` (``heading`` when they coincide) at
    ``positions [K, 2]``: α + atan(−e/Δ), e the cross-track error (starboard positive), no switching."""
    d = np.asarray(p_end, dtype=float) - np.asarray(p0, dtype=float)
    alpha = math.atan2(d[1], d[0]) if math.hypot(*d) > 1e-6 else math.atan2(math.sin(heading), math.cos(heading))
    out = []
    for x, y in np.asarray(positions, dtype=float).reshape(-1, 2):
        e = -(x - p0[0]) * math.sin(alpha) + (y - p0[1]) * math.cos(alpha)
        out.append(alpha + math.atan(-e / lookahead))
    return np.asarray(out)


def terminal_los_offsets(psi, offsets, waypoints, segment: int, n: int, lookahead: float, R_a: float) -> np.ndarray:
    """The first ``n`` route-frame course offsets of Ψ (``offsets [>= n]``, applied at Ψ's states ``psi [>= n + 1,
    4]``) re-expressed against LOS on the line from Ψ_0 through Ψ_n: χ_m + wrap(χ_route − χ_line)."""
    psi = np.asarray(psi, dtype=float)
    chi_r = route_los_courses(psi[:n, :2], waypoints, segment, lookahead, R_a)
    chi_l = line_los_courses(psi[:n, :2], psi[0, :2], psi[n, :2], float(psi[0, 2]), lookahead)
    return np.asarray(offsets, dtype=float)[:n] + np.array([wrap_pm_pi(a) for a in chi_r - chi_l])


# ------------------------------------------------------------------------------------------ manoeuvring
def side_weight(z: float, upper_port: float, upper_stbd: float, s_chi: float) -> float:
    return upper_port * sigmoid(z, 0.0, -s_chi) + upper_stbd * sigmoid(z, 0.0, s_chi)


def gamma_smooth(u_m, chi_m, u_last, chi_last, *, k_U=2.5, k_chi_port=1.8, k_chi_stbd=1.5, Delta_U=2.0,
                 Delta_chi_port=1.2, Delta_chi_stbd=0.9, s_chi=math.log(99.0) / math.radians(5.0)) -> float:
    dchi = chi_m - chi_last
    return (k_U * (1.0 - u_m) ** 2 + side_weight(chi_m, k_chi_port, k_chi_stbd, s_chi) * chi_m ** 2
            + Delta_U * (u_m - u_last) ** 2 + side_weight(dchi, Delta_chi_port, Delta_chi_stbd, s_chi) * dchi ** 2)


def gamma_johansen(u_m, chi_m, u_last, chi_last, *, k_U=2.5, k_chi_port=1.8, k_chi_stbd=1.5, Delta_U=2.0,
                   Delta_chi_port=1.2, Delta_chi_stbd=0.9, side="change") -> float:
    dchi = chi_m - chi_last
    k_chi = k_chi_port if chi_m < 0 else k_chi_stbd
    if side == "change":
        port = dchi < 0
    elif side == "offset":
        port = chi_m < 0
    else:
        raise ValueError(f"side must be 'change' or 'offset', got {side!r}")
    d_chi = Delta_chi_port if port else Delta_chi_stbd
    return k_U * (1.0 - u_m) + k_chi * chi_m ** 2 + Delta_U * abs(u_m - u_last) + d_chi * dchi ** 2


def gamma_sequence(controls, last, *, form="smooth", side="change", **weights) -> float:
    """Σ_k Γ(u_k; u_{k−1}), u_{−1} = last; ``controls [N, 2]`` (speed factor, course offset)."""
    total = 0.0
    prev_u, prev_chi = float(last[0]), float(last[1])
    for u, chi in np.asarray(controls, dtype=float):
        if form == "smooth":
            total += gamma_smooth(u, chi, prev_u, prev_chi, **weights)
        elif form == "johansen":
            w = {k: v for k, v in weights.items() if k != "s_chi"}
            total += gamma_johansen(u, chi, prev_u, prev_chi, side=side, **w)
        else:
            raise ValueError(f"form must be 'smooth' or 'johansen', got {form!r}")
        prev_u, prev_chi = u, chi
    return float(total)


def per_step_controls(behaviour, n_steps: int, dt: float, t_ts: float) -> np.ndarray:
    """Per-maneuver offsets ``[n_M, 2]`` -> per-step controls ``[N, 2]``: step k uses the last maneuver m
    with round(m t_ts / dt) <= k (t_ts NaN: T / n_M)."""
    beh = np.asarray(behaviour, dtype=float)
    n_m = beh.shape[0]
    if math.isnan(t_ts):
        t_ts = n_steps * dt / n_m
    starts = [int(np.round(m * t_ts / dt)) for m in range(n_m)]
    out = np.empty((n_steps, 2))
    for k in range(n_steps):
        active = 0
        for m in range(n_m):
            if starts[m] <= k:
                active = m
        out[k] = beh[active]
    return out


def manoeuvring_cost(behaviour, last, *, n_steps: int, dt: float, t_ts: float = float("nan"),
                     aggregation="max", form="smooth", side="change", **weights) -> float:
    """The manoeuvring term of one behaviour ``[n_M, 2]``: ``"max"`` chains Γ over the maneuvers,
    ``"sum"`` over the N per-step controls (see :class:`psbmpc_jax.costs.manoeuvring.SmoothManoeuvringTerm`)."""
    if aggregation == "max":
        controls = np.asarray(behaviour, dtype=float)
    elif aggregation == "sum":
        controls = per_step_controls(behaviour, n_steps, dt, t_ts)
    else:
        raise ValueError(f"aggregation must be 'max' or 'sum', got {aggregation!r}")
    return gamma_sequence(controls, last, form=form, side=side, **weights)


__all__ = [
    "sigmoid", "smax", "smin", "clip", "wrap_pm_pi", "encounter_inputs", "fis_memberships", "fis_mu", "fis_mu_states",
    "sigma_coll", "adhoc_risk", "collision_weight", "collision_hazard", "colregs_boolean", "sbmpc_cost",
    "side_weight", "gamma_smooth", "gamma_johansen", "gamma_sequence", "per_step_controls", "manoeuvring_cost",
    "signed_land_distance", "route_los_courses", "line_los_courses", "terminal_los_offsets",
]


def obstacle_targets(situation, params, config):
    """Every (obstacle, scenario) trajectory ``[N + 1, 4]`` of a situation, from the float64 reference: the
    point targets the smooth terms' ``reference`` methods compare with."""
    from .reference_prediction import obstacle_scenarios

    return [traj for ob in situation.obstacles for traj in obstacle_scenarios(ob, params, config)]
