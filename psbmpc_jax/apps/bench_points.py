"""The points of a ``psbmpc-jax bench`` sweep and their situations: the behaviour set of each ``n_cbs``, the
Nidelva head-on / standing-still situations, the preset sweeps, the parsing of ``--values`` and each point's
:class:`~psbmpc_jax.params.PlannerConfig` (the rules are in the module docstring of
:mod:`psbmpc_jax.apps.bench`)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache
from typing import Any

import numpy as np

SWEEPS = ("n_cbs", "n_ps", "n_do", "n_so", "n_vertices")

#: (swept, values, fixed settings) per preset figure.
PRESETS: dict[str, tuple[str, tuple, dict[str, Any]]] = {
    "fig5": ("n_cbs", (9, 39, 156, 390, 1014, 2028), {"n_ps": 1}),
    "fig6": ("n_ps", (1, 11, 21, 41, 61, 81, 101), {"n_cbs": 39}),
    "fig7": ("n_ps", (1, 5, 11, 21, 31, 41), {"n_cbs": 1014}),
    "fig6s": ("n_ps", (1, 11, 21, 41, 61, 81, 101), {"n_cbs": 39, "spread": 40.0}),
    "fig7s": ("n_ps", (1, 5, 11, 21, 31), {"n_cbs": 1014, "spread": 40.0}),
    "fig9": ("n_vertices", (0.0, 2.0), {"n_cbs": 1014}),
    "fig10": ("n_so", tuple(range(1, 14)), {"n_cbs": 1014}),
    "smoke": ("n_cbs", (9, 39), {"n_ps": 1, "T": 10.0}),
}
PAPER_FIGS = ("fig5", "fig6", "fig7", "fig9", "fig10", "fig6s", "fig7s")


@dataclass(frozen=True)
class Point:
    sweep: str            # preset/figure name or "custom"
    swept: str
    value: float
    n_cbs: int = 1014
    n_ps: int = 5
    n_do: int = 2
    n_so: int = 13
    eps: float = 2.0      # RDP threshold [m], 0 = raw polygons
    still: bool = False   # own-ship standing still, no obstacles
    largest_only: bool = False
    T: float = 150.0
    spread: float = 0.0   # > 0: lateral span of the scenario fan [m], r_ct = spread / (n_ps - 1)

    @property
    def r_ct(self) -> float:
        """Scenario spacing of this point: the default 10 m (Table 1), or the fixed fan width over n_ps - 1."""
        from ..params import Params

        return self.spread / (self.n_ps - 1) if self.spread > 0 and self.n_ps > 1 else Params().r_ct

    def label(self) -> str:
        v = self.value
        if self.swept == "n_vertices":
            return f"{self.sweep} n_vertices(rdp eps={v:g} m{', raw' if v == 0 else ''})"
        return f"{self.sweep} {self.swept}={int(v) if float(v).is_integer() else v}"


def behaviours_for(n_cbs: int) -> np.ndarray:
    """The behaviour table of ``n_cbs`` behaviours (rules in the module docstring)."""
    from ..behaviours import PAPER_COURSES_DEG, PAPER_SPEEDS, enumerate_behaviours_deg, paper_behaviours

    if n_cbs == 39:
        return paper_behaviours(1)
    if n_cbs == 1014:
        return paper_behaviours(2)
    if n_cbs % 3 == 0 and 3 <= n_cbs <= 117:
        return enumerate_behaviours_deg([PAPER_SPEEDS[0]], [np.linspace(-60.0, 60.0, n_cbs // 3)])
    if n_cbs % 78 == 0 and n_cbs >= 78:
        return enumerate_behaviours_deg(PAPER_SPEEDS, [PAPER_COURSES_DEG, np.linspace(-60.0, 60.0, n_cbs // 78)])
    raise ValueError(f"--values: n_cbs={n_cbs} is not supported; allowed: 39, 1014, multiples of 3 up to 117 "
                     f"(n_M=1) or multiples of 78 (n_M=2)")


@lru_cache(maxsize=8)
def _nidelva(eps: float, n_ps: int, rdp: bool):
    from ..examples import nidelva_head_on

    return nidelva_head_on(eps=eps, n_ps=n_ps, n_so=13, rdp=rdp)


def situation_for(p: Point):
    from ..examples import nidelva_polygons
    from ..situation import Obstacle, OwnShip, Situation

    rdp = p.eps > 0
    eps = p.eps if rdp else 2.0
    if p.still:   # same spot and heading as the dynamic situations, standing still, no obstacles
        own = _nidelva(2.0, 1, True).own_ship
        own = OwnShip(state=np.array([own.state[0], own.state[1], own.state[2], 0.0]), waypoints=own.waypoints, U_d=0.0,
                      length=own.length, width=own.width)
        rings, _ = nidelva_polygons(eps, 13 if p.largest_only else p.n_so, rdp)
        polys = (rings[-1],) if p.largest_only else tuple(rings)
        return Situation(own, (), polys)
    base = _nidelva(eps, p.n_ps, rdp)
    own = base.own_ship
    obstacles = list(base.obstacles[:p.n_do])
    if p.n_do > 2:
        w = np.asarray(own.waypoints, float)
        pos, run_vec = w[0], w[-1] - w[0]
        run = float(np.hypot(*run_vec))
        u = run_vec / run
        for k in range(2, p.n_do):
            frac = 0.25 + 0.1 * ((k - 2) % 8)
            q = pos + frac * run * u + (-1.0) ** k * 3.0 * np.array([-u[1], u[0]])
            obstacles.append(Obstacle(state=np.array([q[0], q[1], -2.0 * u[0], -2.0 * u[1]]), cov=np.diag([4.0, 4.0, .05, .05]),
                                      length=5.0, width=3.0, n_ps=p.n_ps))
    return Situation(own, tuple(obstacles), tuple(base.polygons[:p.n_so]))


def n_vertices(situation) -> int:
    from ..situation import polygon_rings

    return int(sum(sum(len(r) for r in polygon_rings(poly)) for poly in situation.polygons))


def make_points(swept: str, values, fixed: dict, sweep_name: str) -> list[Point]:
    base = Point(sweep=sweep_name, swept=swept, value=0, **fixed)
    pts = []
    for v in values:
        if swept == "n_cbs":
            pts.append(replace(base, value=v, n_cbs=int(v)))
        elif swept == "n_ps":
            pts.append(replace(base, value=v, n_ps=int(v)))
        elif swept == "n_do":
            pts.append(replace(base, value=v, n_do=int(v)))
        elif swept == "n_so":
            pts.append(replace(base, value=v, n_so=int(v), still=True))
        elif swept == "n_vertices":
            pts.append(replace(base, value=float(v), eps=float(v), still=True, largest_only=True, n_so=1))
    return pts


def parse_values(text: str, swept: str) -> list:
    items = [s.strip() for s in text.split(",")]
    if not text.strip() or all(not s for s in items):
        raise ValueError(f"--values must be a comma-separated list of numbers, got {text!r}")
    if any(not s for s in items):
        raise ValueError(f"--values: empty item in {text!r} (two commas in a row, or a leading or trailing "
                         f"comma); give e.g. --values 1,3,5")
    out = []
    for s in items:
        try:
            v = float(s)
        except ValueError:
            raise ValueError(f"--values: {s!r} is not a number (expected e.g. --values 1,3,5)") from None
        if swept == "n_vertices":
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"--values for n_vertices are RDP thresholds eps >= 0 [m] (0 = raw), got {s}")
            out.append(v)
            continue
        if not float(v).is_integer():
            raise ValueError(f"--values for {swept} must be integers, got {s}")
        v = int(v)
        lo = 0 if swept == "n_do" else 1
        if v < lo:
            raise ValueError(f"--values for {swept} must be >= {lo}, got {v}")
        if swept == "n_ps" and v % 2 == 0:
            raise ValueError(f"--values: n_ps must be odd, got {v}")
        if swept == "n_so" and v > 13:
            raise ValueError(f"--values: n_so must be in [1, 13] (Table 2 polygons), got {v}")
        if swept == "n_cbs":
            behaviours_for(v)  # raises with the allowed values
        out.append(v)
    return out


def point_config(args, p: Point, platform: str):
    """The point's :class:`~psbmpc_jax.params.PlannerConfig`, its ``"auto"`` layouts chosen as on ``platform``
    (:meth:`~psbmpc_jax.params.PlannerConfig.for_platform`)."""
    from ..params import PlannerConfig

    config = PlannerConfig(T=p.T, dt=args.dt, estimator=args.estimator, dtype=args.dtype,
                           grounding_mode=args.grounding, grounding_search=args.grounding_search)
    return config.for_platform(platform)
