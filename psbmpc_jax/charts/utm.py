"""UTM: transverse Mercator projection (Krueger series to n^6, Karney 2011) between lon/lat and UTM (east,
north), the standard zone of a point and exact conversion between zones.  NumPy, host side."""

from __future__ import annotations

import math

import numpy as np

from ..numerics import wrap_angle_host


_ELLIPSOIDS = {"WGS84": (6378137.0, 1.0 / 298.257223563), "ETRS89": (6378137.0, 1.0 / 298.257222101)}
_K0, _FALSE_E, _FALSE_N_SOUTH = 0.9996, 500000.0, 10000000.0


def _tm_series(f: float):
    """Krueger series coefficients (Karney 2011, eqs. 35-36) to order n^6."""
    n = f / (2.0 - f)
    n2, n3, n4, n5, n6 = n ** 2, n ** 3, n ** 4, n ** 5, n ** 6
    A = (1.0 + n2 / 4 + n4 / 64 + n6 / 256) / (1.0 + n)
    alpha = (
        n / 2 - 2 * n2 / 3 + 5 * n3 / 16 + 41 * n4 / 180 - 127 * n5 / 288 + 7891 * n6 / 37800,
        13 * n2 / 48 - 3 * n3 / 5 + 557 * n4 / 1440 + 281 * n5 / 630 - 1983433 * n6 / 1935360,
        61 * n3 / 240 - 103 * n4 / 140 + 15061 * n5 / 26880 + 167603 * n6 / 181440,
        49561 * n4 / 161280 - 179 * n5 / 168 + 6601661 * n6 / 7257600,
        34729 * n5 / 80640 - 3418889 * n6 / 1995840,
        212378941 * n6 / 319334400,
    )
    beta = (
        n / 2 - 2 * n2 / 3 + 37 * n3 / 96 - n4 / 360 - 81 * n5 / 512 + 96199 * n6 / 604800,
        n2 / 48 + n3 / 15 - 437 * n4 / 1440 + 46 * n5 / 105 - 1118711 * n6 / 3870720,
        17 * n3 / 480 - 37 * n4 / 840 - 209 * n5 / 4480 + 5569 * n6 / 90720,
        4397 * n4 / 161280 - 11 * n5 / 504 - 830251 * n6 / 7257600,
        4583 * n5 / 161280 - 108847 * n6 / 3991680,
        20648693 * n6 / 638668800,
    )
    return A, alpha, beta


def tm_coefficients(datum: str = "WGS84"):
    """``(a, f, A, alpha, beta)`` of the transverse Mercator series (Krueger n^6) of ``datum``'s ellipsoid:
    semi-major axis [m], flattening, rectifying-radius factor and the forward / inverse coefficients."""
    if datum not in _ELLIPSOIDS:
        raise ValueError(f"datum must be one of {list(_ELLIPSOIDS)}, got {datum!r}")
    a, f = _ELLIPSOIDS[datum]
    A, alpha, beta = _tm_series(f)
    return a, f, A, alpha, beta


def check_zone(zone) -> int:
    if isinstance(zone, bool) or not isinstance(zone, (int, np.integer)) or not 1 <= zone <= 60:
        raise ValueError(f"UTM zone must be an integer in 1..60, got {zone!r}")
    return int(zone)


def utm_zone_for(lon: float, lat: float) -> int:
    """The standard UTM zone of a lon/lat point [deg], with the Norway (32V) and Svalbard exceptions."""
    lon = (float(lon) + 180.0) % 360.0 - 180.0
    lat = float(lat)
    if 56.0 <= lat < 64.0 and 3.0 <= lon < 12.0:
        return 32
    if 72.0 <= lat < 84.0 and 0.0 <= lon < 42.0:
        return 31 if lon < 9.0 else 33 if lon < 21.0 else 35 if lon < 33.0 else 37
    return int((lon + 180.0) // 6.0) % 60 + 1


def tm_forward(lat, lon, lon0: float, e: float, alpha):
    """Transverse Mercator (Krueger n^6, Karney 2011): lat/lon [deg] -> the normalised (xi, eta) about the
    central meridian ``lon0`` [deg]; multiply by k0 a A for metres."""
    lam = np.radians(np.asarray(lon, float)) - math.radians(lon0)
    lam = wrap_angle_host(lam)
    tau = np.tan(np.radians(np.asarray(lat, float)))
    sig = np.sinh(e * np.arctanh(e * tau / np.sqrt(1.0 + tau ** 2)))
    taup = tau * np.sqrt(1.0 + sig ** 2) - sig * np.sqrt(1.0 + tau ** 2)
    xip = np.arctan2(taup, np.cos(lam))
    etap = np.arcsinh(np.sin(lam) / np.sqrt(taup ** 2 + np.cos(lam) ** 2))
    xi, eta = xip.copy(), etap.copy()
    for j, al in enumerate(alpha, start=1):
        xi = xi + al * np.sin(2 * j * xip) * np.cosh(2 * j * etap)
        eta = eta + al * np.cos(2 * j * xip) * np.sinh(2 * j * etap)
    return xi, eta


def tm_inverse(xi, eta, e: float, beta):
    """Inverse of :func:`tm_forward`: normalised (xi, eta) -> (lat [deg], lon − lon0 [deg])."""
    e2 = e * e
    xip, etap = xi.copy(), eta.copy()
    for j, be in enumerate(beta, start=1):
        xip = xip - be * np.sin(2 * j * xi) * np.cosh(2 * j * eta)
        etap = etap - be * np.cos(2 * j * xi) * np.sinh(2 * j * eta)
    taup = np.sin(xip) / np.sqrt(np.sinh(etap) ** 2 + np.cos(xip) ** 2)
    lam = np.arctan2(np.sinh(etap), np.cos(xip))
    tau = taup.copy()
    for _ in range(6):  # Newton on tau'(tau) = taup (Karney 2011, eqs. 19-21)
        sig = np.sinh(e * np.arctanh(e * tau / np.sqrt(1.0 + tau ** 2)))
        taui = tau * np.sqrt(1.0 + sig ** 2) - sig * np.sqrt(1.0 + tau ** 2)
        tau = tau + (taup - taui) / np.sqrt(1.0 + taui ** 2) * (1.0 + (1.0 - e2) * tau ** 2) / (
            (1.0 - e2) * np.sqrt(1.0 + tau ** 2))
    return np.degrees(np.arctan(tau)), np.degrees(lam)


def lonlat_to_utm(lon, lat, zone: int, *, south: bool = False, datum: str = "WGS84"):
    """Project lon/lat [deg] to UTM (east, north) [m] in ``zone`` (transverse Mercator, Krueger n^6)."""
    zone = check_zone(zone)
    a, f = _ELLIPSOIDS[datum]
    A, alpha, _ = _tm_series(f)
    xi, eta = tm_forward(lat, lon, 6.0 * zone - 183.0, math.sqrt(f * (2.0 - f)), alpha)
    east = _FALSE_E + _K0 * a * A * eta
    north = _K0 * a * A * xi + (_FALSE_N_SOUTH if south else 0.0)
    return east, north


def utm_to_lonlat(east, north, zone: int, *, south: bool = False, datum: str = "WGS84"):
    """Inverse of :func:`lonlat_to_utm`: UTM (east, north) [m] -> (lon, lat) [deg]."""
    zone = check_zone(zone)
    a, f = _ELLIPSOIDS[datum]
    A, _, beta = _tm_series(f)
    xi = (np.asarray(north, float) - (_FALSE_N_SOUTH if south else 0.0)) / (_K0 * a * A)
    eta = (np.asarray(east, float) - _FALSE_E) / (_K0 * a * A)
    lat, dlon = tm_inverse(xi, eta, math.sqrt(f * (2.0 - f)), beta)
    lon = dlon + (6.0 * zone - 183.0)
    return (lon + 180.0) % 360.0 - 180.0, lat


def convert_utm(east, north, from_zone: int, to_zone: int, *, from_south: bool = False,
                to_south: bool = False, datum: str = "WGS84"):
    """Exact conversion of UTM coordinates between zones (through lon/lat)."""
    if from_zone == to_zone and from_south == to_south:
        return np.asarray(east, float).copy(), np.asarray(north, float).copy()
    lon, lat = utm_to_lonlat(east, north, from_zone, south=from_south, datum=datum)
    return lonlat_to_utm(lon, lat, to_zone, south=to_south, datum=datum)
