"""Input-validation helpers shared by several modules (host side, NumPy float64).

Each check returns the validated value (converted) or raises ``ValueError`` naming the input and what is
allowed:

* :func:`finite_array` — a finite float array, optionally of an exact shape or number of dimensions
  (the situation types, the simulator's metrics and tracker); booleans and strings are refused;
* :func:`real` — one finite real number (Python or NumPy int/float, not bool, not a string), as float;
* :func:`positive` — a finite scalar ``> 0`` (or ``>= 0``);
* :func:`waypoints` — a route ``[n, 2]`` (north, east) without zero-length segments;
* :func:`integer` — an integer (not bool; NumPy integers accepted) with a lower and optional upper bound;
* :func:`multiple_of` — the number of steps a duration holds, which must be a whole multiple of the step;
* :func:`course` / :func:`speed` — an angle in radians (refusing degrees by mistake) and a plausible ship speed;
* :func:`prng_key` — the PRNG key of the ``mc`` / ``ce`` estimators;
* :func:`control_plan` — a previous plan of per-step controls ``[..., n, 2]`` handed back as a start (the
  refinement's ``PlannerState.warm_start``, Smooth-SBMPC's ``previous``): numeric, of its shape, finite or NaN
  throughout (no plan), inside the solver's box.

Plausibility limits shared by the Python API and the scenario files are module constants
(:data:`MAX_SPEED_MPS`, :data:`MAX_ANGLE_RAD`).
"""

from __future__ import annotations

import math
import numbers

import numpy as np

#: Tolerance of the "is a multiple of the simulation step" checks (relative to the number of steps).
MULTIPLE_TOL = 1e-9

#: Highest plausible ship speed [m/s] (58 kn: above the fastest high-speed craft in service).  Speeds above
#: it are refused everywhere (own-ship, obstacles, scenario ships) -- usually km/h or knots passed as m/s.
MAX_SPEED_MPS = 30.0
#: Largest hull length and width [m] (above the largest ships afloat), refused everywhere above.
MAX_SHIP_LENGTH_M = 500.0
MAX_SHIP_WIDTH_M = 100.0
#: Farthest any position or waypoint of a scenario file may lie from its NED origin [m] (at 200 km float32
#: positions still resolve 2 cm, and a larger value is a unit mix-up: lat/lon or UTM given as local metres).
MAX_POSITION_M = 200_000.0
#: Farthest a position, waypoint or land vertex handed to the planner's API may lie from the frame's origin [m]:
#: the Earth's circumference.  The API takes any metric frame, UTM included (the planner re-centres on the
#: own-ship to keep float32 precision), so only values that are no position on Earth are refused.
MAX_EARTH_M = 4.0e7

#: Largest magnitude [rad] accepted for a course or direction: 2 pi.  Larger values are almost always degrees
#: passed where radians belong (``np.deg2rad`` converts them).
MAX_ANGLE_RAD = 2.0 * math.pi


def _is_bool(v) -> bool:
    return isinstance(v, (bool, np.bool_))


def real(value, name: str) -> float:
    """One finite real number: a Python or NumPy int/float or a 0-d numeric array (not bool, not a string)."""
    if isinstance(value, np.ndarray) and value.shape == () and value.dtype.kind in "iuf":
        value = value[()]
    if _is_bool(value) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} must be a real number (int or float, not bool or str), got "
                         f"{type(value).__name__} {value!r}"[:300])
    try:
        x = float(value)
    except OverflowError:
        raise ValueError(f"{name} is too large to be a float, got an integer with {len(str(math.trunc(value)))} "
                         f"digits") from None
    if not math.isfinite(x):
        raise ValueError(f"{name} must be finite (no NaN/inf), got {x}")
    return x


def _has_bool(value) -> bool:
    if isinstance(value, (list, tuple)):
        return any(_has_bool(v) for v in value)
    return _is_bool(value)


def _numeric(value, name: str) -> np.ndarray:
    """``value`` as a float array; booleans, strings, None and ragged nestings are refused."""
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a numeric array, got {value!r} ({exc})"[:300]) from None
    kind = arr.dtype.kind
    if isinstance(value, (list, tuple)) and kind in "iuf" and _has_bool(value):
        kind = "b"                                # [0, 0, True, 1] became an int array: refuse it all the same
    if kind in "bUSc" or (kind == "O" and any(x is None or _is_bool(x) or isinstance(x, (str, bytes, complex))
                                              for x in arr.ravel())):
        raise ValueError(f"{name} must be numeric (real numbers, not bool/str/None), got {value!r}"[:300])
    try:
        return np.array(arr, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ValueError(f"{name} must be numeric, got {value!r} ({exc})"[:300]) from None


def finite_array(value, name: str, shape: tuple | None = None, *, ndim: int | None = None) -> np.ndarray:
    """``value`` as a finite float array (a copy), of shape ``shape`` and/or ``ndim`` dimensions if given."""
    if value is None:
        raise ValueError(f"{name} must be numeric, got None")
    arr = _numeric(value, name)
    if shape is not None and arr.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
    if ndim is not None and arr.ndim != ndim:
        raise ValueError(f"{name} must be a {ndim}-d array, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite (no NaN/inf), got {arr.tolist()}"[:300])
    return arr


def positive(value, name: str, *, allow_zero: bool = False) -> float:
    """A finite scalar ``> 0`` (``>= 0`` with ``allow_zero``), as float."""
    v = finite_array(value, name, ())
    if v < 0 or (v == 0 and not allow_zero):
        raise ValueError(f"{name} must be {'>= 0' if allow_zero else '> 0'}, got {float(v)}")
    return float(v)


def hull(value, name: str, limit: float) -> float:
    """A hull dimension [m]: finite, ``> 0`` and at most ``limit`` (a larger value is a unit error)."""
    v = positive(value, name)
    if v > limit:
        raise ValueError(f"{name} must be at most {limit:g} m (a hull dimension in metres), got {v:g}")
    return v


def waypoints(value, name: str, min_points: int) -> np.ndarray:
    """A route ``[n >= min_points, 2]`` (north, east) with no repeated consecutive waypoint."""
    if value is None:
        raise ValueError(f"{name} must be an array [n >= {min_points}, 2] (north, east), got None")
    wps = finite_array(value, name)
    if wps.ndim != 2 or wps.shape[1] != 2:
        raise ValueError(f"{name} must have shape [n, 2] (north, east), got {wps.shape}")
    if wps.shape[0] < min_points:
        raise ValueError(f"{name} needs at least {min_points} waypoints, got {wps.shape[0]}")
    if wps.shape[0] >= 2 and np.any(np.linalg.norm(np.diff(wps, axis=0), axis=1) == 0):
        raise ValueError(f"{name} has repeated consecutive waypoints (zero-length segment)")
    return wps


def integer(v, where: str, *, ge: int, le: int | None = None) -> int:
    """An integer (not bool; Python or NumPy) ``>= ge`` (and ``<= le`` if given), as int."""
    ok = not _is_bool(v) and isinstance(v, (numbers.Integral, np.integer))
    if not ok or v < ge:
        raise ValueError(f"{where} must be an integer >= {ge}, got {show(v)}")
    if le is not None and v > le:
        raise ValueError(f"{where} must be an integer <= {le} (allowed: {ge}..{le}), got {show(v)}")
    return int(v)


def show(v) -> str:
    """``repr(v)`` shortened: huge integers by their number of digits, long texts cut."""
    if isinstance(v, (numbers.Integral, np.integer)) and not _is_bool(v) and abs(int(v)) >= 10 ** 30:
        return f"an integer with {len(str(abs(int(v))))} digits"
    r = repr(v)
    return r if len(r) <= 200 else r[:200] + "..."


def multiple_of(value: float, step: float, what: str, step_what: str) -> int:
    """``value / step`` as an int >= 1; ``value`` must be a whole multiple of ``step`` (to :data:`MULTIPLE_TOL`)."""
    n = value / step
    k = round(n)
    if k < 1 or abs(n - k) > MULTIPLE_TOL * max(1.0, abs(n)):
        raise ValueError(f"{what} ({value:g}) must be a multiple of {step_what} ({step:g})")
    return int(k)


def course(value, name: str) -> float:
    """An angle in radians with ``|value| <= 2 pi``; larger magnitudes are refused as probable degrees."""
    x = float(finite_array(value, name, ()))
    if abs(x) > MAX_ANGLE_RAD:
        raise ValueError(f"{name} = {x:g} is not an angle in radians (|angle| <= 2 pi = {MAX_ANGLE_RAD:.4f} "
                         f"allowed); degrees? convert them with np.deg2rad({x:g}) = {math.radians(x):.6g}")
    return x


def speed(value, name: str, *, allow_zero: bool = True, limit: float = MAX_SPEED_MPS) -> float:
    """A ship speed in m/s, ``0 <= value <= MAX_SPEED_MPS`` (``> 0`` without ``allow_zero``)."""
    v = positive(value, name, allow_zero=allow_zero)
    if v > limit:
        raise ValueError(f"{name} = {v:g} m/s is not a plausible ship speed (at most {limit:g} m/s = "
                         f"{limit * 3600 / 1852:.0f} kn allowed); knots or km/h given as m/s?")
    return v


def prng_key(key, name: str = "key"):
    """A JAX PRNG key for the ``mc`` / ``ce`` estimators: a typed key (``jax.random.key(seed)``) or a legacy
    raw ``uint32[2]`` key (``jax.random.PRNGKey(seed)``), one key (not a batch).  Returned unchanged."""
    import jax
    import jax.numpy as jnp

    hint = "pass key=jax.random.key(seed) with an integer seed"
    if key is None:
        raise ValueError(f"{name}: the mc / ce estimators draw samples and need a PRNG key; {hint}")
    if _is_bool(key) or isinstance(key, (numbers.Number, str, bytes)):
        raise ValueError(f"{name} must be a JAX PRNG key, got {type(key).__name__} {key!r}; {hint}"[:300])
    dtype = getattr(key, "dtype", None)
    if dtype is not None and jnp.issubdtype(dtype, jax.dtypes.prng_key):
        if np.shape(key) != ():
            raise ValueError(f"{name} must be a single PRNG key, got a batch of shape {np.shape(key)}; {hint}")
        return key
    if dtype is not None and np.dtype(dtype) == np.uint32 and np.shape(key) == (2,):
        return key
    raise ValueError(f"{name} must be a JAX PRNG key (jax.random.key(seed), or a raw uint32[2] from "
                     f"jax.random.PRNGKey), got {type(key).__name__} with dtype {dtype} and shape "
                     f"{np.shape(key) if dtype is not None else '-'}; {hint}")


def control_plan(value, name: str, *, n: int, lower, upper, box: str, what: str, lead: tuple = (),
                 missing_ok: bool = True, tol: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """A previous plan of per-step controls ``lead + [n, 2]`` (``what`` names the two columns) as
    ``(controls float64, missing)``.  ``missing`` (shape ``lead``) marks a plan that is NaN throughout: no
    previous plan (for a run of a batch, or with ``missing_ok`` for the single plan; otherwise an error).  A
    partly non-finite plan is an error, and so is a control outside ``[lower, upper]`` (per column, ``tol``
    slack) -- ``box`` says that box in words.  ``ValueError`` names ``name`` and what is allowed."""
    try:
        a = np.asarray(value)
    except (TypeError, ValueError) as exc:                 # a ragged nesting
        raise ValueError(f"{name} must be a numeric array {list(lead) + [n, 2]} ({what}), got {value!r} "
                         f"({exc})"[:300]) from None
    if a.dtype.kind not in "iuf":
        raise ValueError(f"{name} must be numeric, got dtype {a.dtype}")
    a = a.astype(np.float64)
    if a.shape != (*lead, n, 2):
        raise ValueError(f"{name} must be {list(lead) + [n, 2]} ({what}) per step, got shape {a.shape}")
    missing = np.all(np.isnan(a), axis=(-2, -1))
    hint = f" (NaN throughout means: no previous plan{' for that run' if lead else ''})"
    if not (lead or missing_ok):                   # a single plan that must be there: NaN is no "no plan"
        missing, hint = np.zeros((), bool), ""
    if np.any(~np.isfinite(a) & ~missing[..., None, None]):
        raise ValueError(f"{name} must be finite{hint}")
    lo, hi = np.asarray(lower, np.float64), np.asarray(upper, np.float64)
    inside = missing[..., None, None] | ((a >= lo - tol) & (a <= hi + tol))
    if not np.all(inside):
        raise ValueError(f"{name} must lie in {box}")
    return a, missing


def local_positions(value: np.ndarray, name: str, limit: float = MAX_EARTH_M) -> np.ndarray:
    """``value`` (finite, last axis north/east [m]) unchanged, or an error when a point lies farther than
    ``limit`` (:data:`MAX_EARTH_M`) from the frame's origin."""
    pts = np.asarray(value, float).reshape(-1, 2)
    far = np.hypot(pts[:, 0], pts[:, 1])
    if far.size and far.max() > limit:
        i = int(np.argmax(far))
        raise ValueError(f"{name}: point {pts[i].tolist()} lies {far[i] / 1000:.6g} km from the frame's origin; at "
                         f"most {limit / 1000:.0f} km allowed (no position on Earth is farther) -- positions are "
                         "metres (north, east), not millimetres or degrees")
    return value
