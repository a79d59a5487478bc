"""The method registry: one name per method, and the lookup the scenario loader, the simulator and the results
share.

A name is found, in this order, among

1. the methods registered with :func:`register` (the built-in ones, :mod:`psbmpc_jax.methods.builtin`, and any
   a program registers before it loads a scenario);
2. the methods packages publish through the ``psbmpc_jax.methods`` entry point group
   (``[project.entry-points."psbmpc_jax.methods"]`` ``my_method = "my_pkg.module:MyMethod"``), loaded on first
   use;
3. an import path ``package.module:Name`` naming a :class:`~psbmpc_jax.methods.base.Method` subclass or
   instance (``mpc.method: my_pkg.controllers:Cautious``).

Anything else is refused with the list of known names.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import re
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..params import PlannerConfig
from .base import BuildContext, Controller, Decision, Method, Observation

#: The entry point group packages register their methods in.
ENTRY_POINT_GROUP = "psbmpc_jax.methods"

#: Registered methods by name, in registration order (the order controllers are called in an update).
REGISTRY: dict[str, Method] = {}
#: Methods found by entry point or import path, by the name a scenario gave.
_FOUND: dict[str, Method] = {}
_IMPORT_PATH = re.compile(r"^[A-Za-z_][\w]*(\.[A-Za-z_][\w]*)*:[A-Za-z_][\w]*(\.[A-Za-z_][\w]*)*$")


def _as_method(obj, where: str) -> Method:
    """A :class:`Method` instance from a class or an instance (TypeError naming ``where`` otherwise)."""
    if isinstance(obj, type):
        if not issubclass(obj, Method):
            raise TypeError(f"{where}: {obj.__module__}.{obj.__qualname__} is not a psbmpc_jax.methods.Method "
                            "subclass")
        obj = obj()
    if not isinstance(obj, Method):
        raise TypeError(f"{where}: expected a psbmpc_jax.methods.Method subclass or instance, got "
                        f"{type(obj).__name__}")
    if not isinstance(obj.name, str) or not obj.name:
        raise TypeError(f"{where}: {type(obj).__name__}.name must be a non-empty string, got {obj.name!r}")
    return obj


def register(method, *, replace: bool = False):
    """Add ``method`` (a :class:`Method` subclass or instance) to :data:`REGISTRY` under its ``name``; returns it
    unchanged, so it can decorate a class.  A name may be registered once unless ``replace``."""
    m = _as_method(method, "register()")
    if m.name == "none":
        raise ValueError("'none' means 'no collision avoidance' and cannot name a method")
    if m.name in REGISTRY and not replace:
        raise ValueError(f"method {m.name!r} is registered already")
    REGISTRY[m.name] = m
    return method


def unregister(name: str) -> None:
    """Remove ``name`` from :data:`REGISTRY` (KeyError if it is not there)."""
    del REGISTRY[name]


def is_import_path(name) -> bool:
    """Whether ``name`` has the form ``package.module:Name``."""
    return isinstance(name, str) and bool(_IMPORT_PATH.match(name))


def _entry_points() -> dict:
    try:
        return {ep.name: ep for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP)}
    except Exception:          # a broken installation's metadata must not break the built-in methods
        return {}


def names() -> tuple[str, ...]:
    """Every method name a scenario may use without an import path: the registered ones, then those published
    by entry points."""
    return tuple(REGISTRY) + tuple(n for n in _entry_points() if n not in REGISTRY)


def get_method(name, where: str = "method", *, none_ok: bool = False) -> Method:
    """The method ``name`` (a registered name, an entry point name or an import path ``package.module:Name``).
    Raises ValueError naming ``where`` and the known names for anything else (``none_ok``: the message says that
    ``'none'`` is allowed too), ImportError/TypeError (also naming ``where``) when an import path does not lead
    to a method."""
    if isinstance(name, str):
        if name in REGISTRY:
            return REGISTRY[name]
        if name in _FOUND:
            return _FOUND[name]
        eps = _entry_points()
        if name in eps:
            _FOUND[name] = _as_method(eps[name].load(), f"{where}: entry point {name!r} ({eps[name].value})")
            return _FOUND[name]
        if is_import_path(name):
            _FOUND[name] = _as_method(_load(name, where), f"{where} {name!r}")
            return _FOUND[name]
    raise ValueError(f"{where} must be {chr(39) + 'none' + chr(39) + ', ' if none_ok else ''}a known method "
                     f"({', '.join(names())}) or an import path 'package.module:Name' of a "
                     f"psbmpc_jax.methods.Method, got {name!r}"[:400])


def _load(path: str, where: str):
    module, _, attr = path.partition(":")
    try:
        obj = importlib.import_module(module)
    except ImportError as exc:
        raise ImportError(f"{where} {path!r}: cannot import module {module!r}: {exc}") from exc
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise ImportError(f"{where} {path!r}: module {module!r} has no attribute {attr!r}")
        obj = getattr(obj, part)
    return obj


@dataclass(frozen=True)
class SectionContext:
    """What a section parser gets besides its own mapping: the whole ``mpc`` mapping of the file, the own-ship's
    method, the MPC update period [s], the PSB-MPC configuration (None for the sections parsed before it) and the
    sections parsed so far (key -> settings)."""

    mpc: dict
    method: str
    period: float
    config: PlannerConfig | None = None
    parsed: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Section:
    """A method's own section of a scenario file, ``mpc.<key>``: ``parse(mapping, context) -> settings`` (a
    ValueError naming ``mpc.<key>.<field>`` for bad input), ``default()`` (the settings of a file without the
    section) and whether it is parsed after the PSB-MPC configuration (``after_config``: it may read
    ``context.config``)."""

    key: str
    parse: Callable
    default: Callable
    after_config: bool = False


#: The methods' sections of ``mpc``, by key, in parsing order (every section is validated whatever the method,
#: so one file can carry the settings of every method).
SECTIONS: dict[str, Section] = {}


def register_section(key: str, parse: Callable, default: Callable, *, after_config: bool = False) -> None:
    """Let the scenario loader hand ``mpc.<key>`` to ``parse`` (see :class:`Section`); a key may be registered
    once."""
    if not isinstance(key, str) or not key.isidentifier():
        raise ValueError(f"a section key must be an identifier, got {key!r}")
    if key in SECTIONS:
        raise ValueError(f"section mpc.{key} is registered already")
    SECTIONS[key] = Section(key, parse, default, after_config)


def check_ships(method: Method, ships: tuple, ship_names) -> None:
    """ValueError if ``method`` plans the own-ship only and ``ships`` holds a target."""
    if method.own_ship_only and tuple(ships) != (0,):
        bad = [ship_names[i] for i in ships if i != 0]
        raise ValueError(f"ship(s) {bad}: method {method.name} plans the own-ship only")


@dataclass
class Controllers:
    """The controllers of a scenario's ships (:func:`build_controllers`): ``controllers`` in call order,
    ``own`` the own-ship's method (None when it runs no collision avoidance), ``methods`` per ship (``"none"``
    or a method name) and the ``controlled`` ship mask."""

    controllers: list
    own: Method | None
    methods: tuple = ()
    controlled: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))

    @property
    def method(self) -> str | None:
        """The own-ship's method name as the scenario gives it (None without collision avoidance)."""
        return None if self.own is None else self.methods[0]

    def init(self, n_runs: int) -> None:
        for c in self.controllers:
            c.init(n_runs)

    def decide(self, obs: Observation) -> list[Decision]:
        """One MPC update: every controller's decision for every run."""
        return [c.decide(obs) for c in self.controllers]

    @property
    def snapshots(self) -> bool:
        """Whether a controller can return the own-ship's full evaluation (:attr:`Decision.snapshot`)."""
        return any(getattr(c, "snapshots", False) for c in self.controllers)

    @property
    def splits_runs(self) -> bool:
        """Whether a controller splits its vmapped batch over :attr:`BuildContext.devices` (``splits_runs``)."""
        return any(getattr(c, "splits_runs", False) for c in self.controllers)

    @property
    def uses_grid(self) -> bool:
        """Whether a controller packs the chart's distance grid (``grounding_mode: grid``)."""
        return any(getattr(c, "uses_grid", False) for c in self.controllers)


def build_controllers(scenario, context: BuildContext = BuildContext(), methods: tuple | None = None) -> Controllers:
    """One controller per method in use, for all the ships that run it (per ship: its ``colav``, the own-ship's
    being ``mpc.method``; or ``methods``), registered methods in registration order, then the others in ship
    order."""
    methods = tuple(s.colav for s in scenario.ships) if methods is None else tuple(methods)
    found = {}
    for i, m in enumerate(methods):
        if m != "none" and m not in found:
            found[m] = get_method(m, f"ship {scenario.ships[i].name!r} colav", none_ok=True)
    order = [m for m in REGISTRY if m in found] + [m for m in found if m not in REGISTRY]
    names_ = [s.name for s in scenario.ships]
    controllers = []
    for m in order:
        ships = tuple(i for i, x in enumerate(methods) if x == m)
        check_ships(found[m], ships, names_)
        c = found[m].build(scenario, ships, context)
        if not isinstance(c, Controller):
            raise TypeError(f"method {m!r}: build() must return a controller (ships, init, decide), got "
                            f"{type(c).__name__}")
        if tuple(c.ships) != ships:
            raise ValueError(f"method {m!r}: its controller runs ships {tuple(c.ships)}, expected {ships}")
        controllers.append(c)
    own = None if methods[0] == "none" else found[methods[0]]
    return Controllers(controllers=controllers, own=own, methods=methods,
                       controlled=np.array([m != "none" for m in methods]))


__all__ = ["SECTIONS", "Section", "SectionContext", "register_section", "ENTRY_POINT_GROUP", "REGISTRY", "register", "unregister", "names", "get_method", "is_import_path",
           "check_ships", "Controllers", "build_controllers"]
