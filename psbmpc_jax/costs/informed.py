"""The cost of Informed SB-MPC (Akdağ, Fossen & Johansen 2022, Secs. 2.2 and 2.4; docs/informed_sbmpc.md).

H^k = max_i max_{t ≥ t₀+T_s} ( C_i R_i + κ_i μ_i + ρ_i ζ_i ) + γ·max_t 𝓖   (eq. 2 without f)

with 𝓖 read outside the max (choice IS-4; the choices IS-n are listed in docs/algorithm.md §14).

Pure, vectorised ``jax.numpy`` pieces (NED: x north, y east [m], courses [rad] clockwise from north; β, α
clockwise positive = starboard, in (−π, π]):

* :func:`relative_bearing` β (target seen from the own-ship) and :func:`contact_angle` α (own-ship seen from
  the target, relative to the target's heading);
* :func:`adaptive_d_safe`: d_safe = c_dist / (|β|^k + l) (eq. 10, β in radians, per predicted t: our reading IS-7);
* :func:`colregs_woerner`: μ = CLOSE ∧ (R13 ∨ R14 ∨ R15) of eq. (5) read in NED (R15's printed "∨ ¬ON" as "∧ ¬ON", the
  paper's counter-clockwise β mirrored: choices IS-1, IS-2), with the encounter flags from the predicted velocities
  per t (``classify="velocity"``, choice IS-3) or classified once at t₀ from Woerner-type sectors
  (``classify="sectors_t0"``);
* :func:`rule18_zeta`: ζ of eq. (6) (m = 1.1, n = 1), gated by d ≤ d_close (choice IS-5);
* :func:`grounding_penalty`: 𝓖 of eq. (8), d clamped ≥ 0.1 m;

and :class:`InformedSbmpcTerm` (``"informed"``) that puts them into the evaluator with per-target parameter
sets P_default / P_R18 (eq. 11; per-target sets for the target terms, P_default for f and 𝓖: choice IS-8).  The
manoeuvring cost f (eq. 7) is ``SmoothManoeuvringTerm(form="johansen", side="offset")`` (the side from the sign
of the candidate offset: choice IS-6); route exchange and the XTD supervisor are prediction (the obstacles'
trajectories), not cost.
"""

from __future__ import annotations

import math

import jax.numpy as jnp

from ..distance_grid import interpolate
from ..geometry import edge_table
from ..grounding_search import distances_at, search_argmax
from ..layouts import resolve_search
from ..numerics import safe_sqrt
from .base import Context, TermValue, cost_term
from .colregs_fuzzy import check_choice, check_param
from .sbmpc import V_EPS, term_value, adhoc_risk, collision_weight, context_pairs

# ------------------------------------------------------------------------------------------ constants
DEG = math.pi / 180.0
COS_22_5 = math.cos(22.5 * DEG)
COS_67_5 = math.cos(67.5 * DEG)
#: Threshold angles of eqs. (5)-(6) [rad].
R13_SECTOR = 22.5 * DEG
R14_PORT_LIMIT = 13.0 * DEG
ZETA_BOW = 22.5 * DEG
ZETA_BEAM = 90.0 * DEG
#: Sectors of the flag alternative (choice IS-3): head-on |β|, |α| < 13°; OG |α| > 112.5° ∧ |β| < 67.5°;
#: ON |β| > 112.5° ∧ |α| < 67.5°; otherwise crossing if |β| ≤ 112.5°.
HEAD_ON_SECTOR = 13.0 * DEG
ABAFT_SECTOR = 112.5 * DEG
AHEAD_SECTOR = 67.5 * DEG
#: 𝓖 evaluates (d_saf / max(d, G_D_FLOOR))^q_g (our choice: clamp d ≥ 0.1 m).
G_D_FLOOR = 0.1

# Our proposed values (open sea, 116 m ships; the paper gives none): docs/informed_sbmpc.md, "Parameters".
DEFAULT_K_COLL, DEFAULT_K_COLL_R18 = 0.5, 1.0
DEFAULT_KAPPA, DEFAULT_KAPPA_R18 = 3.0, 3.0
DEFAULT_RHO, DEFAULT_RHO_R18 = 0.0, 3.0
DEFAULT_P, DEFAULT_Q = 1.0, 4.0
DEFAULT_C_DIST, DEFAULT_C_DIST_R18 = 500.0, 1000.0
DEFAULT_D_CLOSE = 1800.0
DEFAULT_K, DEFAULT_L = 2.0, 1.0
DEFAULT_M, DEFAULT_N = 1.1, 1.0
DEFAULT_GAMMA, DEFAULT_P_G, DEFAULT_Q_G, DEFAULT_D_STATIC_SAFE = 1.0, 1.0, 4.0, 200.0

CLASSIFY = ("velocity", "sectors_t0")
#: Per-target fields: (P_default name, P_R18 name).
TARGET_FIELDS = (("K_coll", "K_coll_r18"), ("kappa", "kappa_r18"), ("rho", "rho_r18"), ("c_dist", "c_dist_r18"),
                 ("p", "p_r18"), ("q", "q_r18"), ("d_close", "d_close_r18"))


# ------------------------------------------------------------------------------------------ geometry
def relative_bearing(own_x, own_y, own_chi, tgt_x, tgt_y):
    """β = bearing of the target from the own-ship relative to the own heading, in (−π, π], clockwise positive
    (starboard); 0 at d = 0.  Computed as atan2 of the target's body-frame (starboard, forward) coordinates."""
    dx, dy = tgt_x - own_x, tgt_y - own_y
    c, s = jnp.cos(own_chi), jnp.sin(own_chi)
    stbd, fwd = -dx * s + dy * c, dx * c + dy * s
    ok = (stbd != 0) | (fwd != 0)                  # atan2(0, 0) = 0 with a finite gradient
    return jnp.arctan2(jnp.where(ok, stbd, 0.0), jnp.where(ok, fwd, 1.0))


def contact_angle(own_x, own_y, tgt_x, tgt_y, tgt_chi):
    """α = bearing of the own-ship from the target relative to the target's heading, in (−π, π]."""
    return relative_bearing(tgt_x, tgt_y, tgt_chi, own_x, own_y)


def _abs_pow(a, k):
    """|a|^k with |0|^0 = 1 and finite values/gradients at a = 0 (for k > 0: 0)."""
    a = jnp.abs(a)
    pos = a > 0
    return jnp.where(pos, jnp.exp(k * jnp.log(jnp.where(pos, a, 1.0))), jnp.where(k == 0, 1.0, 0.0))


def adaptive_d_safe(beta, c_dist=DEFAULT_C_DIST, k=DEFAULT_K, l=DEFAULT_L):
    """d_safe = c_dist / (|β|^k + l) (eq. 10; β in radians, IS-7).  k = 2, l = 1, c_dist = 500 m: 500 m
    ahead, 309 m at 45°, 144 m abeam, 76 m at 135°, 46 m astern."""
    check_param("c_dist", c_dist, lo=0.0, lo_open=True)
    check_param("k", k, lo=0.0)
    check_param("l", l, lo=0.0, lo_open=True)
    return c_dist / (_abs_pow(beta, k) + l)


# ------------------------------------------------------------------------------------------ COLREGS (5)
def encounter_flags_velocity(own_x, own_y, own_chi, own_U, tgt_x, tgt_y, tgt_chi, tgt_U):
    """(OG, ON, HO, CR) from the velocities of one instant (IS-3, Johansen's tests):
    OG: v_o·v_i > cos 67.5° ‖v_o‖‖v_i‖ ∧ ‖v_o‖ > ‖v_i‖; ON: the same with ‖v_i‖ > ‖v_o‖;
    HO: ‖v_o‖ > 0.05 ∧ v_o·v_i < −cos 22.5° ‖v_o‖‖v_i‖ ∧ v_o·L > cos 67.5° ‖v_o‖;
    CR: ‖v_o‖ > 0.05 ∧ v_o·v_i < cos 67.5° ‖v_o‖‖v_i‖ (LIB CROSSED with its speed guard)."""
    own_U, tgt_U = jnp.abs(own_U), jnp.abs(tgt_U)
    dot = own_U * tgt_U * jnp.cos(tgt_chi - own_chi)
    n0ni = own_U * tgt_U
    dx, dy = tgt_x - own_x, tgt_y - own_y
    d = safe_sqrt(dx * dx + dy * dy)
    along = own_U * (jnp.cos(own_chi) * dx + jnp.sin(own_chi) * dy)
    ahead = (d > 0) & (along > COS_67_5 * own_U * d)
    same = dot > COS_67_5 * n0ni
    og = same & (own_U > tgt_U)
    on = same & (tgt_U > own_U)
    ho = (own_U > V_EPS) & (dot < -COS_22_5 * n0ni) & ahead
    cr = (own_U > V_EPS) & (dot < COS_67_5 * n0ni)
    return og, on, ho, cr


def encounter_flags_sectors(beta0, alpha0):
    """(OG, ON, HO, CR) classified once from the bearings at t₀ (the flag alternative of IS-3):
    HO |β| < 13° ∧ |α| < 13°; OG |α| > 112.5° ∧ |β| < 67.5°; ON |β| > 112.5° ∧ |α| < 67.5°; otherwise CR
    (= CR_GW ∨ CR_SO) when |β| ≤ 112.5° (β₀ = 0 counts as crossing)."""
    b, a = jnp.abs(beta0), jnp.abs(alpha0)
    ho = (b < HEAD_ON_SECTOR) & (a < HEAD_ON_SECTOR)
    og = (a > ABAFT_SECTOR) & (b < AHEAD_SECTOR)
    on = (b > ABAFT_SECTOR) & (a < AHEAD_SECTOR)
    cr = ~(ho | og | on) & (b <= ABAFT_SECTOR)
    return og, on, ho, cr


def woerner_mu(beta, d, flags, d_close=DEFAULT_D_CLOSE):
    """μ = (d < d_close) ∧ (R13 ∨ R14 ∨ R15) from the flags (OG, ON, HO, CR) and β(t) (NED, IS-1/2):
    R13 = OG ∧ |β| < 22.5°, R14 = HO ∧ β > −13°, R15 = CR ∧ β ≥ 0 ∧ ¬ON.  Boolean."""
    og, on, ho, cr = flags
    r13 = og & (jnp.abs(beta) < R13_SECTOR)
    r14 = ho & (beta > -R14_PORT_LIMIT)
    r15 = cr & (beta >= 0) & ~on
    return (d < d_close) & (r13 | r14 | r15)


def colregs_woerner(own_x, own_y, own_chi, own_U, tgt_x, tgt_y, tgt_chi, tgt_U, d_close=DEFAULT_D_CLOSE, *,
                    classify: str = "velocity", t0=None):
    """μ ∈ {0, 1} of eq. (5) (NED reading, choices IS-1 and IS-2) as the arrays' float dtype, all inputs broadcast.

    ``classify="velocity"``: OG/ON/HO/CR from the predicted velocities at each t (:func:`encounter_flags_velocity`);
    ``"sectors_t0"``: classified once from β, α at t₀ (:func:`encounter_flags_sectors`), ``t0`` = (own_x0,
    own_y0, own_chi0, tgt_x0, tgt_y0, tgt_chi0) (broadcast against the other inputs); β(t) per t either way."""
    check_choice("classify", classify, CLASSIFY)
    check_param("d_close", d_close, lo=0.0, lo_open=True)
    dx, dy = tgt_x - own_x, tgt_y - own_y
    d = safe_sqrt(dx * dx + dy * dy)
    beta = relative_bearing(own_x, own_y, own_chi, tgt_x, tgt_y)
    if classify == "velocity":
        flags = encounter_flags_velocity(own_x, own_y, own_chi, own_U, tgt_x, tgt_y, tgt_chi, tgt_U)
    else:
        if t0 is None or len(t0) != 6:
            raise ValueError("classify='sectors_t0' needs t0 = (own_x0, own_y0, own_chi0, tgt_x0, tgt_y0, tgt_chi0)")
        ox, oy, oc, tx, ty, tc = t0
        flags = encounter_flags_sectors(relative_bearing(ox, oy, oc, tx, ty), contact_angle(ox, oy, tx, ty, tc))
    dtype = jnp.result_type(own_x, tgt_x, float)
    return woerner_mu(beta, d, flags, d_close).astype(dtype)


# ------------------------------------------------------------------------------------------ Rule 18 (6)
def rule18_zeta(beta, alpha, m=DEFAULT_M, n=DEFAULT_N, *, d=None, d_close=DEFAULT_D_CLOSE):
    """ζ of eq. (6): m if |β| ≤ 22.5° ∨ |α| ≤ 22.5° (first branch first), n if 22.5° < |α| ≤ 90°, else 0.
    With ``d`` given, gated by d ≤ d_close (IS-5)."""
    check_param("m", m, lo=0.0)
    check_param("n", n, lo=0.0)
    b, a = jnp.abs(beta), jnp.abs(alpha)
    z = jnp.where((b <= ZETA_BOW) | (a <= ZETA_BOW), m, jnp.where(a <= ZETA_BEAM, n, 0.0))
    if d is not None:
        check_param("d_close", d_close, lo=0.0, lo_open=True)
        z = jnp.where(d <= d_close, z, 0.0)
    return z


# ------------------------------------------------------------------------------------------ grounding (8)
def grounding_penalty(d, t, d_static_safe=DEFAULT_D_STATIC_SAFE, p_g=DEFAULT_P_G, q_g=DEFAULT_Q_G):
    """𝓖 = |t|^(−p_g)·(d_saf / max(d, 0.1 m))^q_g where d ≤ d_saf, else 0 (eq. 8; ``t`` = t − t₀ ≠ 0; d = 0
    inside land)."""
    check_param("d_static_safe", d_static_safe, lo=0.0, lo_open=True)
    check_param("p_g", p_g, lo=0.0)
    check_param("q_g", q_g, lo=0.0)
    d_eff = jnp.maximum(d, G_D_FLOOR)
    g = jnp.abs(t) ** (-p_g) * jnp.exp(q_g * jnp.log(d_static_safe / d_eff))
    return jnp.where(d <= d_static_safe, g, 0.0)


def _time_feature(t, p_g):
    """w(t) = |t|^(−p_g) for t ≠ 0 and 0 at t₀ (so the argmax never picks t₀)."""
    pos = t != 0
    return jnp.where(pos, jnp.exp(-p_g * jnp.log(jnp.abs(jnp.where(pos, t, 1.0)))), 0.0)


def _g_shape(d, d_static_safe, q_g):
    return jnp.where(d <= d_static_safe, jnp.exp(q_g * jnp.log(d_static_safe / jnp.maximum(d, G_D_FLOOR))), 0.0)


def max_grounding_penalty(ctx: Context, config, d_static_safe, p_g, q_g):
    """max over t ≥ t₀ + T_s of 𝓖(d(t), t) per row ``[B]``, d = distance to the nearest chart polygon (0 inside).

    Exact mode: per polygon the maximising time from the exact search
    (:func:`psbmpc_jax.geometry.search_argmax`, ``config.grounding_search``; 𝓖 falls with d, so max_t 𝓖(min_j d_j) = max_j max_t 𝓖(d_j)),
    then 𝓖 there from the point's nearest edge.  ``config.grounding_mode == "grid"``: d from the distance grid."""
    own, t = ctx.own, ctx.t
    n_b = own.x.shape[1]
    zero = jnp.zeros((n_b,), own.x.dtype)
    world = ctx.world
    if world is None or own.x.shape[0] < 2:
        return zero
    w = _time_feature(t, p_g)
    if getattr(config, "grounding_mode", "exact") == "grid":
        grid = world.grid
        px, py = own.x[1:], own.y[1:]
        d, _, _ = interpolate(grid.distance_grid(), px, py)
        # outside the grid (≥ grid_margin from land) interpolate answers d = margin; count no land there, so a
        # margin < d_static_safe does not put a penalty on the open sea (it only misses land beyond the margin)
        nx, ny = grid.values.shape
        fx, fy = (px - grid.origin[0]) / grid.spacing, (py - grid.origin[1]) / grid.spacing
        covered = (fx >= 0) & (fx <= nx - 1) & (fy >= 0) & (fy <= ny - 1)
        g = jnp.where(covered, w[1:, None] * _g_shape(d, d_static_safe, q_g), 0.0)
        return jnp.where(grid.active, jnp.max(g, axis=0), 0.0)
    poly = world.polygons
    if poly.vertices.shape[0] == 0:
        return zero
    tables = edge_table(poly.vertices, poly.next)
    n_edges = jnp.where(poly.mask, poly.n, 0)

    def score(d, ex, ey, tw):
        return tw * _g_shape(d, d_static_safe, q_g)

    def bound(d, tw):
        return score(d, None, None, tw)

    search = resolve_search(getattr(config, "grounding_search", "auto"), getattr(config, "layout_platform", None))
    blocks = poly.blocks
    k = search_argmax(search, own.x, own.y, w, score, bound, tables, poly.next, n_edges, False, blocks)   # [P, B]
    cols = jnp.arange(n_b)
    d, _, _ = distances_at(search, own.x[k, cols], own.y[k, cols], tables, n_edges, blocks)
    h = jnp.where(poly.mask[:, None], w[k] * _g_shape(d, d_static_safe, q_g), 0.0)                # [P, B]
    return jnp.max(h, axis=0)


# ------------------------------------------------------------------------------------------ the term
def target_roles(ctx, n_o: int):
    """The Rule-18 role of every obstacle ``[O]`` bool from ``getattr(ctx, "obstacle_r18", None)`` (None: all
    power-driven)."""
    r18 = getattr(ctx, "obstacle_r18", None)
    if r18 is None:
        return jnp.zeros((n_o,), bool)
    r18 = jnp.asarray(r18)
    if r18.shape != (n_o,):
        raise ValueError(f"ctx.obstacle_r18 must be [O] = [{n_o}] bool, got shape {r18.shape}")
    return r18.astype(bool)


@cost_term(static=("classify", "circular", "grounding"))
class InformedSbmpcTerm:
    """The Informed SB-MPC hazard (eq. 2 without f): per (target, t ≥ t₀ + T_s)
    h = K_coll‖v_o − v_i‖²·R(d, t; d_safe(β(t))) + κ μ + ρ ζ with the target's parameter set (P_default, or
    the ``*_r18`` fields where ``ctx.obstacle_r18`` is True), one joint max over targets and time, plus
    γ·max_t 𝓖 (own-ship only, P_default).  Not smooth (crisp gates, Boolean μ, piecewise ζ).

    Static: ``classify`` ("velocity" | "sectors_t0"), ``circular`` (True: d_safe = c_dist, eq. 10 with
    k = l = 0: the paper's circle that the droplet is cut from), ``grounding`` (False: no 𝓖, e.g. when the
    library's grounding term is used instead).  Every number is a traced leaf.
    Details: ``informed_i [B, O, S]`` (per target, max over time of h) and ``informed_g [B]`` (γ·max_t 𝓖)."""

    name = "informed"
    PARAMS = ("K_coll", "kappa", "rho", "c_dist", "p", "q", "d_close", "K_coll_r18", "kappa_r18", "rho_r18",
              "c_dist_r18", "p_r18", "q_r18", "d_close_r18", "k", "l", "m", "n", "gamma", "p_g", "q_g",
              "d_static_safe")
    smooth = False

    K_coll: float = DEFAULT_K_COLL
    kappa: float = DEFAULT_KAPPA
    rho: float = DEFAULT_RHO
    c_dist: float = DEFAULT_C_DIST
    p: float = DEFAULT_P
    q: float = DEFAULT_Q
    d_close: float = DEFAULT_D_CLOSE
    K_coll_r18: float = DEFAULT_K_COLL_R18
    kappa_r18: float = DEFAULT_KAPPA_R18
    rho_r18: float = DEFAULT_RHO_R18
    c_dist_r18: float = DEFAULT_C_DIST_R18
    p_r18: float = DEFAULT_P
    q_r18: float = DEFAULT_Q
    d_close_r18: float = DEFAULT_D_CLOSE
    k: float = DEFAULT_K
    l: float = DEFAULT_L
    m: float = DEFAULT_M
    n: float = DEFAULT_N
    gamma: float = DEFAULT_GAMMA
    p_g: float = DEFAULT_P_G
    q_g: float = DEFAULT_Q_G
    d_static_safe: float = DEFAULT_D_STATIC_SAFE
    classify: str = "velocity"
    circular: bool = False
    grounding: bool = True

    def __post_init__(self):
        for suffix in ("", "_r18"):
            check_param("K_coll" + suffix, getattr(self, "K_coll" + suffix), lo=0.0)
            check_param("kappa" + suffix, getattr(self, "kappa" + suffix), lo=0.0)
            check_param("rho" + suffix, getattr(self, "rho" + suffix), lo=0.0)
            check_param("c_dist" + suffix, getattr(self, "c_dist" + suffix), lo=0.0, lo_open=True)
            check_param("p" + suffix, getattr(self, "p" + suffix), lo=0.0)
            check_param("q" + suffix, getattr(self, "q" + suffix), lo=0.0)
            check_param("d_close" + suffix, getattr(self, "d_close" + suffix), lo=0.0, lo_open=True)
        check_param("k", self.k, lo=0.0)
        check_param("l", self.l, lo=0.0, lo_open=True)
        check_param("m", self.m, lo=0.0)
        check_param("n", self.n, lo=0.0)
        check_param("gamma", self.gamma, lo=0.0)
        check_param("p_g", self.p_g, lo=0.0)
        check_param("q_g", self.q_g, lo=0.0)
        check_param("d_static_safe", self.d_static_safe, lo=0.0, lo_open=True)
        check_choice("classify", self.classify, CLASSIFY)
        for name in ("circular", "grounding"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{name} must be a bool (True or False), got {getattr(self, name)!r}")

    def target_params(self, role):
        """The per-target parameters ``{name: [...]}`` for a role mask (True = P_R18)."""
        return {a: jnp.where(role, getattr(self, b), getattr(self, a)) for a, b in TARGET_FIELDS}

    def hazard(self, ctx: Context):
        """h ``[K, O·S, B]`` for t ≥ t₀ + T_s (before the target mask)."""
        o, x, t, _ = context_pairs(ctx)
        n_o, n_s = ctx.scen_valid.shape
        role = jnp.broadcast_to(target_roles(ctx, n_o)[:, None], (n_o, n_s)).reshape(1, n_o * n_s, 1)
        P = self.target_params(role)
        (ox, oy, oc, oU), (tx, ty, tc, tU) = o, x
        dx, dy = tx - ox, ty - oy
        d = safe_sqrt(dx * dx + dy * dy)
        beta = relative_bearing(ox, oy, oc, tx, ty)
        alpha = contact_angle(ox, oy, tx, ty, tc)
        if self.circular:
            d_safe = jnp.broadcast_to(P["c_dist"], d.shape)
        else:
            d_safe = adaptive_d_safe(beta, P["c_dist"], self.k, self.l)
        c = collision_weight(oU * jnp.cos(oc), oU * jnp.sin(oc), tU * jnp.cos(tc), tU * jnp.sin(tc), P["K_coll"])
        r = adhoc_risk(d, t, d_safe, P["p"], P["q"], crisp=True)
        if self.classify == "velocity":
            flags = encounter_flags_velocity(ox, oy, oc, oU, tx, ty, tc, tU)
        else:
            own, obs = ctx.own, ctx.obstacles
            n_os = n_o * n_s
            t0x, t0y, t0c = (a[0].reshape(n_os)[:, None] for a in (obs.x, obs.y, obs.chi))
            o0x, o0y, o0c = (a[0][None, :] for a in (own.x, own.y, own.chi))
            flags = encounter_flags_sectors(relative_bearing(o0x, o0y, o0c, t0x, t0y),
                                            contact_angle(o0x, o0y, t0x, t0y, t0c))
        mu = woerner_mu(beta, d, flags, P["d_close"]).astype(d.dtype)
        zeta = rule18_zeta(beta, alpha, self.m, self.n, d=d, d_close=P["d_close"])
        return c * r + P["kappa"] * mu + P["rho"] * zeta

    def __call__(self, ctx: Context, params, config, samples) -> TermValue:
        h = self.hazard(ctx)
        out = term_value(ctx, h, "max", "informed_i")
        value = out.value
        if self.grounding:
            g = self.gamma * max_grounding_penalty(ctx, config, self.d_static_safe, self.p_g, self.q_g)
        else:
            g = jnp.zeros_like(value)
        return TermValue(value + g, {**out.details, "informed_g": g})

    def reference(self, own_traj, behaviour, situation, params, config, r18=None):
        """Float64 oracle (:func:`psbmpc_jax.reference_informed.informed_cost`).  ``r18``: optional per-obstacle
        role mask; default ``getattr(obstacle, "rule18", False)``."""
        from .. import reference_informed as ri

        return ri.term_reference(self, own_traj, situation, params, config, r18=r18)


__all__ = [
    "CLASSIFY", "TARGET_FIELDS", "relative_bearing", "contact_angle", "adaptive_d_safe", "encounter_flags_velocity",
    "encounter_flags_sectors", "woerner_mu", "colregs_woerner", "rule18_zeta", "grounding_penalty",
    "max_grounding_penalty", "target_roles", "InformedSbmpcTerm",
]
