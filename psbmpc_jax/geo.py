"""Latitude / longitude <-> the local NED frame (host side, NumPy float64).

Scenario files may give positions as ``[lat, lon]`` degrees (WGS 84) about a geographic origin
``{lat, lon}`` (see ``docs/scenarios.md``).  Without a UTM chart they are converted with a **local transverse
Mercator projection** centred on the origin: central meridian = the origin's longitude, scale 1 on it, and
the origin's own northing subtracted, so the origin maps to ``(0, 0)`` and local north is true north along
the origin's meridian.  The series are Krueger's to order n^6 (Karney 2011), the same that
:mod:`psbmpc_jax.charts` uses for UTM, so the projection itself is exact to well below a millimetre.

How well the flat NED frame represents the sphere-like earth -- the only approximation -- depends on the
distance ``d`` east or west of the origin's meridian: the scale is ``1 + d^2 / (2 R^2)`` (R ~ 6371 km), i.e.
distances are too long by 1.2e-6 (1.2 cm per 10 km) at d = 10 km, 3.1e-5 at 50 km and 1.2e-4 at 100 km; the
grid north differs from true north by the meridian convergence ``~ (lon - lon0) sin(lat)`` (0.08 deg at 10 km
east at 63 deg N).  The loader accepts lat/lon positions up to :data:`LATLON_MAX_DISTANCE_M` (100 km) from
the origin and refuses farther ones -- usually ``[lon, lat]`` given where ``[lat, lon]`` belongs.

With a UTM chart (``chart.builtin`` / ``chart.file``) lat/lon positions are projected to the chart's UTM zone
instead (:func:`psbmpc_jax.charts.lonlat_to_utm`), so they land exactly where the chart is.

API: :func:`latlon_to_ned`, :func:`ned_to_latlon`, :func:`check_latlon`.
"""

from __future__ import annotations

import math

import numpy as np

from .charts import tm_coefficients, tm_forward, tm_inverse

__all__ = ["latlon_to_ned", "ned_to_latlon", "check_latlon", "LATLON_MAX_DISTANCE_M"]

#: Farthest a lat/lon position may lie from the scenario's geographic origin [m].
LATLON_MAX_DISTANCE_M = 100_000.0

#: Largest |latitude| [deg] accepted (the local projection needs a defined north).
MAX_ABS_LAT_DEG = 89.0


def check_latlon(lat, lon, name: str) -> tuple[float, float]:
    """A finite ``(lat, lon)`` in degrees with ``|lat| <= 89`` and ``-180 <= lon <= 180``; the message names
    ``name`` and hints at a swapped order when swapping would fit."""
    lat, lon = float(lat), float(lon)
    if not (math.isfinite(lat) and math.isfinite(lon)):
        raise ValueError(f"{name} must be finite degrees [lat, lon], got [{lat}, {lon}]")
    if abs(lat) > MAX_ABS_LAT_DEG or abs(lon) > 180.0:
        hint = ("; it looks like [lon, lat] -- give [lat, lon]" if abs(lon) <= MAX_ABS_LAT_DEG and abs(lat) <= 180.0
                else "")
        raise ValueError(f"{name} = [{lat:g}, {lon:g}] is not [lat, lon] in degrees (|lat| <= {MAX_ABS_LAT_DEG:g}, "
                         f"|lon| <= 180 allowed){hint}")
    return lat, lon


def latlon_to_ned(lat, lon, origin_lat: float, origin_lon: float, *, datum: str = "WGS84") -> np.ndarray:
    """Degrees ``lat, lon`` (scalars or arrays) -> local ``[..., 2]`` (north, east) [m] about the origin, by the
    local transverse Mercator projection described in the module docstring."""
    a, f, A, alpha, _ = tm_coefficients(datum)
    e = math.sqrt(f * (2.0 - f))
    xi, eta = tm_forward(lat, lon, origin_lon, e, alpha)
    xi0, _ = tm_forward(origin_lat, origin_lon, origin_lon, e, alpha)
    return np.stack([a * A * (xi - xi0), a * A * eta], axis=-1)


def ned_to_latlon(north, east, origin_lat: float, origin_lon: float, *,
                  datum: str = "WGS84") -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`latlon_to_ned`: local (north, east) [m] -> (lat, lon) [deg]."""
    a, f, A, alpha, beta = tm_coefficients(datum)
    e = math.sqrt(f * (2.0 - f))
    xi0, _ = tm_forward(origin_lat, origin_lon, origin_lon, e, alpha)
    xi = np.asarray(north, float) / (a * A) + xi0
    eta = np.asarray(east, float) / (a * A)
    lat, dlon = tm_inverse(xi, eta, e, beta)
    lon = dlon + origin_lon
    return lat, (lon + 180.0) % 360.0 - 180.0
