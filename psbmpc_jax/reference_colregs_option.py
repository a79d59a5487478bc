"""Float64 NumPy oracle of the COLREGS option's cost terms (:mod:`psbmpc_jax.costs.colregs_option`): plain loops
over obstacles, behaviours and maneuvers, written from docs/colregs_option.md, sharing no code with the kernel."""

from __future__ import annotations

import math

import numpy as np


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def encounter(p0, chi0, u0, obstacles, *, engage, act_cpa, act_range, clear):
    """Flags of every obstacle: ``obstacles`` is a list of ``(x, y, vx, vy, radius, valid)``.  Returns a list of
    dicts with ``engaged``, ``stand_on`` (engaged, and one to stand on for), ``stand_on_hold``, ``port_act``,
    ``give_way`` (Python bools)."""
    out = []
    d22, d67, d112 = (math.radians(a) for a in (22.5, 67.5, 112.5))
    v0 = (u0 * math.cos(chi0), u0 * math.sin(chi0))
    for x, y, vx, vy, radius, valid in obstacles:
        dx, dy = x - p0[0], y - p0[1]
        dvx, dvy = vx - v0[0], vy - v0[1]
        rng = math.hypot(dx, dy)
        dot = dx * dvx + dy * dvy
        dv2 = dvx * dvx + dvy * dvy
        t_cpa = max(0.0, -dot / dv2) if dv2 > 0 else 0.0
        d_cpa = math.hypot(dx + dvx * t_cpa, dy + dvy * t_cpa)
        closing = dot < 0
        beta = _wrap(math.atan2(dy, dx) - chi0)
        ui = math.hypot(vx, vy)
        dchi = _wrap(math.atan2(vy, vx) - chi0)
        head_on = abs(beta) < d22 and abs(_wrap(dchi - math.pi)) < d22
        overtaken = abs(beta) > d112 and ui > u0 and abs(dchi) < d67
        alpha = _wrap(math.atan2(-dy, -dx) - math.atan2(vy, vx))
        overtaking = abs(alpha) > d112 and u0 > ui
        cross_port = beta < 0 and dchi > 0 and not head_on
        cross_stbd = 0 < beta < d112 and dchi < 0 and not head_on
        past_clear = (not closing) and rng > clear * radius
        engaged = bool(valid) and rng < engage * radius and not past_clear
        risk = closing and d_cpa < act_cpa * radius
        may_act = risk and rng < act_range * radius
        stand_on = engaged and (cross_port or overtaken) and not overtaking
        out.append({"engaged": engaged, "stand_on": stand_on, "stand_on_hold": stand_on and not may_act,
                    "port_act": engaged and cross_port and not overtaking and may_act,
                    "give_way": engaged and risk and (head_on or cross_stbd or overtaking)})
    return out


def _bump(z: float, a: float) -> float:
    return math.sin(math.pi * z / a) ** 2 if abs(z) < a else 0.0


def _step_down(z: float, a: float) -> float:
    return math.cos(0.5 * math.pi * z / a) ** 2 if abs(z) < a else 0.0


def option_costs(offsets, last, flags, *, chi_a, du_a, K_stand_on, K_port, K_apparent, K_hold, K_early):
    """The four costs ``{name: [B]}`` of behaviours ``offsets [B, n_M, 2]`` given the applied ``last (u, χ)``
    and the per-obstacle ``flags`` of :func:`encounter`."""
    offsets = np.asarray(offsets, np.float64)
    hold_so = any(f["stand_on_hold"] for f in flags)
    port = any(f["port_act"] for f in flags)
    engaged = any(f["engaged"] for f in flags)
    give_way = any(f["give_way"] for f in flags)
    n_b, n_m = offsets.shape[:2]
    out = {k: np.zeros(n_b) for k in ("stand_on", "apparent", "hold", "early")}
    for b in range(n_b):
        u_prev, c_prev = float(last[0]), float(last[1])
        keep = to_port = small = back = 0.0
        for m in range(n_m):
            u, c = float(offsets[b, m, 0]), float(offsets[b, m, 1])
            keep += ((c - c_prev) / chi_a) ** 2 + ((u - u_prev) / du_a) ** 2
            to_port += (min(c, 0.0) / chi_a) ** 2
            small += _bump(c, chi_a) + _bump(c - c_prev, chi_a) + _bump(1.0 - u, du_a)
            s = (c_prev > 0) - (c_prev < 0)
            back += (max(0.0, s * (c_prev - c)) / chi_a) ** 2
            u_prev, c_prev = u, c
        out["stand_on"][b] = (K_stand_on * keep / n_m if hold_so else 0.0) + (K_port * to_port / n_m if port else 0.0)
        out["apparent"][b] = K_apparent * small / n_m if engaged else 0.0
        out["hold"][b] = K_hold * back / n_m if engaged else 0.0
        out["early"][b] = K_early * _step_down(float(offsets[b, 0, 1]), chi_a) if give_way else 0.0
    return out


__all__ = ["encounter", "option_costs"]
