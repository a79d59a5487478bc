"""Field readers of configuration files (scenario files and the methods' own sections in them): mappings with
checked keys (unknown keys get suggestions), numbers with bounds, points, courses, speeds, choices, and the YAML 1.2
loader (duplicate keys refused).  Degrees and knots are converted to SI here, once.  Each error names the key and
what is allowed."""

from __future__ import annotations
import difflib
import math
import numbers
import re
import numpy as np
import yaml
from .checks import MAX_SPEED_MPS, show

# ---------------------------------------------------------------------------------------------- primitives
def as_mapping(value, where: str) -> dict:
    if not isinstance(value, dict):
        raise ValueError(f"{where} must be a mapping (key: value), got {type(value).__name__} {value!r}"[:300])
    return value


def check_keys(d: dict, allowed, where: str, required=()) -> None:
    for k in d:
        if k not in allowed:
            close = difflib.get_close_matches(str(k), [str(a) for a in allowed], n=1, cutoff=0.6)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise ValueError(f"unknown key {k!r} in {where}{hint}; allowed keys: {', '.join(allowed)}")
    for k in required:
        if k not in d:
            raise ValueError(f"{where}: missing required key {k!r}")


def _path(where: str, key: str) -> str:
    return f"{where}.{key}" if where else key


def is_number(v) -> bool:
    return isinstance(v, numbers.Real) and not isinstance(v, bool)


def as_number(v, where: str, *, gt=None, ge=None, le=None) -> float:
    """A finite real number (int or float, not bool), optionally bounded; returned as float."""
    if not is_number(v):
        raise ValueError(f"{where} must be a finite number, got {v!r}"[:300])
    try:
        x = float(v)
    except OverflowError:
        raise ValueError(f"{where} must be a finite number, got an integer with {len(str(abs(int(v))))} digits "
                         f"(too large)") from None
    if not math.isfinite(x):
        raise ValueError(f"{where} must be a finite number, got {v!r}")
    if gt is not None and not x > gt:
        raise ValueError(f"{where} must be > {gt:g}, got {v!r}")
    if ge is not None and not x >= ge:
        raise ValueError(f"{where} must be >= {ge:g}, got {v!r}")
    if le is not None and not x <= le:
        raise ValueError(f"{where} must be <= {le:g}, got {v!r}")
    return x


def as_string(v, where: str) -> str:
    if not isinstance(v, str) or not v.strip():
        raise ValueError(f"{where} must be a non-empty string, got {v!r}")
    return v


def one_of(d: dict, keys, where: str, *, required: bool) -> str | None:
    """The one key of ``keys`` present in ``d`` (unit alternatives such as speed_mps / speed_kn)."""
    present = [k for k in keys if k in d]
    if len(present) > 1:
        raise ValueError(f"{where}: give only one of {' / '.join(keys)}, got {' and '.join(present)}")
    if not present:
        if required:
            raise ValueError(f"{where}: missing required key, one of {' / '.join(keys)}")
        return None
    return present[0]


def as_point(v, where: str) -> np.ndarray:
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if not isinstance(v, (list, tuple)) or len(v) != 2:
        raise ValueError(f"{where} must be a pair of numbers [a, b], got {v!r}")
    return np.array([as_number(v[0], f"{where}[0]"), as_number(v[1], f"{where}[1]")], dtype=float)


def as_points(v, where: str, *, min_n: int) -> np.ndarray:
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if not isinstance(v, (list, tuple)) or len(v) < min_n:
        n = len(v) if isinstance(v, (list, tuple)) else type(v).__name__
        raise ValueError(f"{where} must be a list of at least {min_n} points [a, b] (shape [n >= {min_n}, 2]), "
                         f"got {n if isinstance(n, str) else f'{n} points'}: {v!r}"[:300])
    return np.stack([as_point(p, f"{where}[{i}]") for i, p in enumerate(v)]).reshape(-1, 2)


def _wrap_deg(deg: float) -> float:
    return (deg + 180.0) % 360.0 - 180.0


def course_rad(deg: float) -> float:
    """Degrees -> radians in [-pi, pi): wrapped in degrees first (exact for whole degrees), converted once."""
    return math.radians(_wrap_deg(deg))


_AXIS_DIRECTIONS = {0.0: (1.0, 0.0), 90.0: (0.0, 1.0), -90.0: (0.0, -1.0), -180.0: (-1.0, 0.0)}


def direction_of(deg: float) -> np.ndarray:
    """Unit vector (north, east) of a course in degrees; exact along the axes (no 1e-16 sine residue)."""
    w = _wrap_deg(deg)
    if w in _AXIS_DIRECTIONS:
        return np.array(_AXIS_DIRECTIONS[w])
    r = math.radians(w)
    return np.array([math.cos(r), math.sin(r)])


def read_speed(d: dict, keys, where: str, *, required: bool, gt=None, ge=None):
    """m/s from one of (``*_mps``, ``*_kn``); knots converted exactly once (1 kn = 1852/3600 m/s)."""
    key = one_of(d, keys, where, required=required)
    if key is None:
        return None
    x = as_number(d[key], _path(where, key), gt=gt, ge=ge)
    # x * 1852 is exact for any speed a file holds, so the result is 1852 x / 3600 correctly rounded
    mps = x * 1852.0 / 3600.0 if key.endswith("_kn") else x
    if mps > MAX_SPEED_MPS:
        raise ValueError(f"{_path(where, key)} ({x:g}) is {mps:g} m/s; at most {MAX_SPEED_MPS:g} m/s "
                         f"({MAX_SPEED_MPS * 3600 / 1852:.1f} kn) allowed -- knots given as m/s (use the _kn key), "
                         f"or km/h?")
    return mps


# ---------------------------------------------------------------------------------------------- YAML
_YAML12_FLOAT = re.compile(r"""^(?:[-+]?[0-9][0-9_]*(?:\.[0-9_]*)?[eE][-+]?[0-9]+
                              |[-+]?\.[0-9_]+[eE][-+]?[0-9]+)$""", re.X)


class _Loader(yaml.SafeLoader):
    """Safe YAML loader that refuses duplicate keys (PyYAML keeps the last one silently) and reads YAML 1.2
    floats such as ``1e3`` (YAML 1.1, and so PyYAML, would read them as strings)."""

    def construct_mapping(self, node, deep=False):
        if isinstance(node, yaml.MappingNode):
            self.flatten_mapping(node)
            seen = set()
            for key_node, _ in node.value:
                key = self.construct_object(key_node, deep=deep)
                try:
                    dup = key in seen
                except TypeError:  # unhashable key: let PyYAML report it
                    continue
                if dup:
                    raise ValueError(f"duplicate key {key!r} at line {key_node.start_mark.line + 1}: every key "
                                     f"may appear only once in a mapping")
                seen.add(key)
        return super().construct_mapping(node, deep=deep)


_Loader.add_implicit_resolver("tag:yaml.org,2002:float", _YAML12_FLOAT, list("-+0123456789."))


def yaml_load(text: str, where: str):
    try:
        return yaml.load(text, Loader=_Loader)  # noqa: S506 -- a SafeLoader subclass
    except yaml.YAMLError as exc:
        raise ValueError(f"{where}: not valid YAML ({exc})") from None
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None


def value_sets(v, where: str, *, lo: float, hi: float) -> tuple[tuple[float, ...], ...]:
    if not isinstance(v, (list, tuple)) or not v:
        raise ValueError(f"{where} must be a non-empty list with one list of values per maneuver, got {v!r}")
    out = []
    for m, s in enumerate(v):
        w = f"{where}[{m}]"
        if not isinstance(s, (list, tuple)) or not s:
            raise ValueError(f"{w} must be a non-empty list of numbers, got {s!r}")
        out.append(tuple(as_number(x, f"{w}[{i}]", ge=lo, le=hi) for i, x in enumerate(s)))
    return tuple(out)


def as_bool(v, where: str) -> bool:
    """A YAML ``true`` / ``false`` (not 0/1, not a string)."""
    if not isinstance(v, bool):
        raise ValueError(f"{where} must be true or false, got {show(v)}")
    return v


def as_choice(v, allowed, where: str) -> str:
    if not isinstance(v, str) or v not in allowed:
        raise ValueError(f"{where} must be one of {', '.join(allowed)}, got {show(v)}")
    return v
