"""Settings of the COLREGS option (beyond the papers): the ``mpc.colregs_option`` section of a scenario file,
parsed here (registered by :mod:`psbmpc_jax.methods.builtin`).  Light: no JAX.

The option adds cost terms (:mod:`psbmpc_jax.costs.colregs_option`) to the grid-search methods of the PSB-MPC
family (``psbmpc``, ``sbmpc``, ``psbmpc_2020``, ``informed_sbmpc``).  It is off by default: without the section,
or with ``enabled: false``, every method runs its published cost unchanged.  docs/colregs_option.md."""

from __future__ import annotations

import math
from typing import Any
from dataclasses import asdict, dataclass

from ..config import as_bool, as_mapping, as_number, check_keys

#: The option's terms, in the order they are added: Rule 17 stand-on duty, Rule 8 readily apparent alterations,
#: Rule 8 / 13 hold the avoidance heading until past and clear, early action by the give-way vessel.
TERM_KEYS = ("stand_on", "apparent", "hold", "early")
#: Methods whose cost the option extends (grid searches; the refinement of ``psbmpc_refine`` would not see it).
OPTION_METHODS = ("psbmpc", "sbmpc", "psbmpc_2020", "informed_sbmpc")


@dataclass(frozen=True)
class ColregsOptionSpec:
    """``mpc.colregs_option``.  Distances are multiples of the pair's safety radius R_i = d_safe + (l_0 + l_i)/2
    (the collision term's radius), so one set of values fits ships of every size.

    Attributes:
        enabled: add the option's terms (default false: the published cost).
        stand_on, apparent, hold, early: which of the terms to add (each default true when enabled).
        hold_path: while some target is engaged and none is one to stand on for, weight off the course-deviation part (K_chi_port, K_chi_stbd)
            of the path term H_p, so holding an avoidance offset costs nothing (``psbmpc`` only: the other
            methods' costs have their own manoeuvring terms, left as published).
        freeze_course: while some target is engaged (not past and clear), freeze the course reference at the
            active leg's direction: the ship is commanded that direction plus its course offset, so LOS guidance
            does not pull it back to the route before the target is past (:mod:`psbmpc_jax.methods.colregs_hold`).
        engage_radii: a target is engaged while its range is below this many R_i (default 40).
        act_cpa_radii: a nominal CPA (own-ship keeping its present course and speed, the target its velocity)
            below this many R_i is a risk of collision (default 2).
        act_range_radii: below this range (in R_i) the stand-on vessel may act, if the CPA is a risk (Rule
            17(a)(ii)/(b)); above it the give-way vessel can still act, so it keeps course and speed (default 4).
        clear_radii: a target is past and clear when its range opens and exceeds this many R_i (default 4).
        chi_apparent_deg: course alterations below this are not readily apparent (Rule 8(b); default 30).
        du_apparent: speed-factor changes below this are not readily apparent (default 0.5).
        K_stand_on, K_port, K_apparent, K_hold, K_early: the terms' weights (>= 0).
    """

    enabled: bool = False
    stand_on: bool = True
    apparent: bool = True
    hold: bool = True
    early: bool = True
    hold_path: bool = True
    freeze_course: bool = False
    engage_radii: float = 40.0
    act_cpa_radii: float = 2.0
    act_range_radii: float = 4.0
    clear_radii: float = 4.0
    chi_apparent_deg: float = 30.0
    du_apparent: float = 0.5
    K_stand_on: float = 10000.0
    K_port: float = 10000.0
    K_apparent: float = 100.0
    K_hold: float = 100.0
    K_early: float = 100.0

    @property
    def chi_apparent(self) -> float:
        """:attr:`chi_apparent_deg` in radians."""
        return math.radians(self.chi_apparent_deg)

    def active(self) -> tuple[str, ...]:
        """The keys of the terms to add (empty when not enabled)."""
        return tuple(k for k in TERM_KEYS if self.enabled and getattr(self, k))


#: Numeric keys -> (lower bound, whether the bound is open, upper bound or None).
_NUMBERS = {"engage_radii": (0.0, True, 1e4), "act_cpa_radii": (0.0, True, 1e4), "act_range_radii": (0.0, True, 1e4),
            "clear_radii": (0.0, True, 1e4), "chi_apparent_deg": (0.0, True, 90.0), "du_apparent": (0.0, True, 1.0),
            "K_stand_on": (0.0, False, None), "K_port": (0.0, False, None), "K_apparent": (0.0, False, None),
            "K_hold": (0.0, False, None), "K_early": (0.0, False, None)}
_SWITCHES = ("enabled",) + TERM_KEYS + ("hold_path", "freeze_course")
#: Methods whose cost holds the PSB-MPC path term H_p, which ``hold_path`` weights.
HOLD_PATH_METHODS = ("psbmpc",)
_KEYS = _SWITCHES + tuple(_NUMBERS)


def parse_colregs_option(d, method: str | None = None, *, where: str = "mpc.colregs_option",
                         base: ColregsOptionSpec | None = None) -> ColregsOptionSpec:
    """``mpc.colregs_option`` (or a ship's ``colregs_option``, ``where``) -> :class:`ColregsOptionSpec`; the keys
    it gives override ``base`` (default: the defaults).  ValueError naming the field and what is allowed.
    ``method``: the ship's method (the own-ship's ``mpc.method`` for the ``mpc`` section); an enabled option needs
    one of :data:`OPTION_METHODS`."""
    w = where
    d = as_mapping(d, w)
    check_keys(d, _KEYS, w)
    kw: dict[str, Any] = asdict(base) if base is not None else {}
    for k in _SWITCHES:
        if k in d:
            kw[k] = as_bool(d[k], f"{w}.{k}")
    for k, (lo, open_, hi) in _NUMBERS.items():
        if k in d:
            kw[k] = as_number(d[k], f"{w}.{k}", **({"gt": lo} if open_ else {"ge": lo}), le=hi)
    spec = ColregsOptionSpec(**kw)
    if spec.enabled and not spec.active():
        raise ValueError(f"{w}: enabled with every term off ({', '.join(TERM_KEYS)} all false); switch a term on "
                         f"or set enabled: false")
    if spec.enabled and method is not None and method not in OPTION_METHODS:
        what = "mpc.method" if where == "mpc.colregs_option" else "the ship's method (colav)"
        raise ValueError(f"{w}.enabled: the option extends the grid-search methods {', '.join(OPTION_METHODS)}; "
                         f"{what} is {method!r} (its cost would not see the option)")
    if spec.enabled and d.get("hold_path") is True and method is not None and method not in HOLD_PATH_METHODS:
        raise ValueError(f"{w}.hold_path: weights the path term of {', '.join(HOLD_PATH_METHODS)}; the cost of "
                         f"{method!r} has none (set it false or leave it out)")
    if spec.enabled and spec.act_range_radii >= spec.engage_radii:
        raise ValueError(f"{w}.act_range_radii ({spec.act_range_radii:g}) must be below engage_radii "
                         f"({spec.engage_radii:g})")
    return spec


def parse_ship_option(d, colav: str, where: str, base: ColregsOptionSpec | None) -> ColregsOptionSpec:
    """A ship's own ``colregs_option`` section (``where``: e.g. ``targets[0].colregs_option``): the keys it gives
    override the scenario's ``mpc.colregs_option`` (``base``), for this ship alone.  Refused for a ship that runs
    no collision avoidance (``colav: none``), and, when it is enabled, for a method the option does not extend."""
    if colav == "none":
        raise ValueError(f"{where}: the ship runs no collision avoidance (colav: none), so it has no cost to add "
                         f"the option to; leave the section out or give the ship a method "
                         f"({', '.join(OPTION_METHODS)})")
    return parse_colregs_option(d, colav, where=where, base=base)


def ship_option(scenario, i: int) -> ColregsOptionSpec:
    """Ship ``i``'s resolved option: its own section over ``mpc.colregs_option`` when it gives one
    (``ShipSpec.colregs_option``), else ``mpc.colregs_option``."""
    own = getattr(scenario.ships[i], "colregs_option", None)
    return own if own is not None else scenario.mpc.colregs_option


def option_in_use(scenario) -> bool:
    """Whether some ship that runs a method the option extends has it enabled."""
    return any(ship_option(scenario, i).enabled for i, s in enumerate(scenario.ships) if s.colav in OPTION_METHODS)


__all__ = ["ColregsOptionSpec", "TERM_KEYS", "OPTION_METHODS", "parse_colregs_option", "parse_ship_option",
           "ship_option", "option_in_use"]
