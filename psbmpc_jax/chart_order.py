"""Coordinate-order check of a geographic chart: [lat, lon] given where GeoJSON (RFC 7946) wants [lon, lat].

Read in the wrong order, a chart is still a valid set of polygons — mirrored, stretched and placed elsewhere on
Earth — so it cannot be refused from its own coordinates.  It can be refused against a reference position (the
scenario's origin, or any point the chart must be near): :func:`swapped_order` says whether the chart is far
from the reference as read and near it with the two coordinates exchanged, and :func:`check_near` raises a
``ValueError`` saying so.
"""

from __future__ import annotations

import math

import numpy as np

#: Mean Earth radius [m] (the distances here only decide "near" or "far").
EARTH_RADIUS_M = 6_371_008.8


def great_circle_m(lon1, lat1, lon2, lat2) -> float:
    """Haversine distance [m] between two (lon, lat) points [deg]."""
    p1, p2 = math.radians(lat1), math.radians(lat2)
    dp, dl = p2 - p1, math.radians(lon2 - lon1)
    a = math.sin(dp / 2) ** 2 + math.cos(p1) * math.cos(p2) * math.sin(dl / 2) ** 2
    return 2 * EARTH_RADIUS_M * math.asin(min(1.0, math.sqrt(a)))


def swapped_order(lon, lat, ref_lon: float, ref_lat: float, near_m: float) -> bool:
    """True when the points ``(lon, lat)`` [deg] (arrays) lie farther than ``near_m`` from the reference by their
    centre, and within ``near_m`` of it with the two coordinates exchanged: the chart was written [lat, lon]."""
    lon, lat = np.asarray(lon, float).ravel(), np.asarray(lat, float).ravel()
    if lon.size == 0:
        return False
    c_lon, c_lat = float(np.mean(lon)), float(np.mean(lat))
    if abs(c_lon) > 90.0:                 # then it cannot be a latitude: the order read is the only one possible
        return False
    return (great_circle_m(c_lon, c_lat, ref_lon, ref_lat) > near_m
            and great_circle_m(c_lat, c_lon, ref_lon, ref_lat) <= near_m)


def check_near(lon, lat, ref_lon: float, ref_lat: float, near_m: float, what: str) -> None:
    """``ValueError`` when the chart points (lon, lat) [deg] are in [lat, lon] order relative to the reference
    (:func:`swapped_order`); ``what`` names the reference (e.g. ``"chart.origin_utm"``)."""
    if swapped_order(lon, lat, ref_lon, ref_lat, near_m):
        c_lon, c_lat = float(np.mean(lon)), float(np.mean(lat))
        raise ValueError(
            f"{what}: the chart's coordinates look like [lat, lon] order: read as [lon, lat] (the GeoJSON order, "
            f"RFC 7946) its centre is at lat {c_lat:.4f}, lon {c_lon:.4f}, "
            f"{great_circle_m(c_lon, c_lat, ref_lon, ref_lat) / 1000:.0f} km from lat {ref_lat:.4f}, lon "
            f"{ref_lon:.4f}; exchanged it would be within {near_m / 1000:.0f} km. Write every position of the chart "
            f"as [lon, lat] (or, if the chart is right, check that {what} is not the one with lat and lon exchanged)")


__all__ = ["swapped_order", "check_near", "great_circle_m"]
