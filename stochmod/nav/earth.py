"""WGS84 Earth model: radii of curvature, normal gravity, Earth and transport rates, and
conversions between geodetic coordinates, ECEF and a local NED frame.

Sources: Gonzalez et al. (2015), ``gonzalez2015-unified-ins-gps-model.txt``: Table I (WGS84
constants), eq. 9 (Earth rate), eq. 10 (transport rate), eq. 11a-b (radii), eq. 16a-d and
Table II (gravity), eq. 20j (curvilinear-to-Cartesian scaling).

Units: SI inside. The Earth-model functions take latitude in **radians**; the coordinate helpers
(:func:`lla_to_ecef`, :func:`lla_to_ned` ...) take and return latitude/longitude in **degrees**
(the public edge), heights in metres above the ellipsoid.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

__all__ = [
    "A",
    "B",
    "E2",
    "ECCENTRICITY",
    "OMEGA_IE",
    "GRAVITY_G0",
    "GRAVITY_G1",
    "GRAVITY_G2",
    "principal_radii",
    "gravity_ned",
    "earth_rate_ned",
    "transport_rate_ned",
    "ned_scale",
    "lla_to_ecef",
    "ecef_to_lla",
    "ecef_to_ned_dcm",
    "lla_to_ned",
    "ned_to_lla",
]

#: Semi-major axis a, m (Table I).
A = 6378137.0
#: Semi-minor axis b, m (Table I).
B = 6356752.3142
#: First eccentricity e (Table I).
ECCENTRICITY = 0.0818191908426
#: e^2.
E2 = ECCENTRICITY**2
#: Earth rotation rate Omega, rad/s (Table I).
OMEGA_IE = 7.292115e-5
#: Normal-gravity constants of eq. 16b (Table II): g0 in m/s^2, g1 and g2 dimensionless.
GRAVITY_G0 = 9.780318
GRAVITY_G1 = 5.3024e-3
GRAVITY_G2 = 5.9e-6


def principal_radii(lat: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Meridian and prime-vertical radii of curvature (eq. 11a, 11b).

    Parameters
    ----------
    lat : array_like
        Geodetic latitude, rad.

    Returns
    -------
    R_N, R_E : ndarray
        Meridian radius ``a (1 - e^2) / (1 - e^2 sin^2 lat)^(3/2)`` (the seed's R_M) and
        prime-vertical radius ``a / sqrt(1 - e^2 sin^2 lat)`` (the seed's R_N), m.
    """
    s2 = np.sin(np.asarray(lat, dtype=float)) ** 2
    w = 1.0 - E2 * s2
    return A * (1.0 - E2) / w**1.5, A / np.sqrt(w)


def gravity_ned(lat: ArrayLike, height: ArrayLike) -> np.ndarray:
    """Normal gravity vector in NED, m/s^2 (eq. 16a-16d with Table II).

    ``g(0) = g0 (1 + g1 sin^2 lat - g2 sin^2 2lat)`` and ``g = g(0) / (1 + h / R0)^2`` with
    ``R0 = sqrt(R_N R_E)``; the vector is ``(0, 0, g)``. Shape ``broadcast(lat, height) + (3,)``.
    """
    lat, height = np.broadcast_arrays(np.asarray(lat, dtype=float), np.asarray(height, dtype=float))
    rn, re = principal_radii(lat)
    g0 = GRAVITY_G0 * (1.0 + GRAVITY_G1 * np.sin(lat) ** 2 - GRAVITY_G2 * np.sin(2 * lat) ** 2)
    g = g0 / (1.0 + height / np.sqrt(rn * re)) ** 2
    z = np.zeros_like(g)
    return np.stack([z, z, g], -1)


def earth_rate_ned(lat: ArrayLike) -> np.ndarray:
    """Earth rotation rate in NED, ``(Omega cos lat, 0, -Omega sin lat)``, rad/s (eq. 9)."""
    lat = np.asarray(lat, dtype=float)
    return np.stack([OMEGA_IE * np.cos(lat), np.zeros_like(lat), -OMEGA_IE * np.sin(lat)], -1)


def transport_rate_ned(lat: ArrayLike, height: ArrayLike, vel_ned: ArrayLike) -> np.ndarray:
    """Transport rate of the NED frame over the Earth, rad/s (eq. 10).

    ``(v_E / (R_E + h), -v_N / (R_N + h), -v_E tan(lat) / (R_E + h))``.
    """
    lat = np.asarray(lat, dtype=float)
    height = np.asarray(height, dtype=float)
    v = np.asarray(vel_ned, dtype=float)
    rn, re = principal_radii(lat)
    ve = v[..., 1] / (re + height)
    return np.stack([ve, -v[..., 0] / (rn + height), -ve * np.tan(lat)], -1)


def ned_scale(lat: ArrayLike, height: ArrayLike) -> np.ndarray:
    """Metres per radian of latitude and longitude, and -1 per metre of height: the diagonal of
    the seed's ``T_p^r`` (eq. 20j) with the sign that maps a height change to a down change.

    Returns shape ``broadcast(lat, height) + (3,)``: ``(R_N + h, (R_E + h) cos lat, -1)``.
    """
    lat, height = np.broadcast_arrays(np.asarray(lat, dtype=float), np.asarray(height, dtype=float))
    rn, re = principal_radii(lat)
    return np.stack([rn + height, (re + height) * np.cos(lat), -np.ones_like(lat)], -1)


def lla_to_ecef(lat: ArrayLike, lon: ArrayLike, height: ArrayLike) -> np.ndarray:
    """ECEF position, m, from latitude and longitude in **degrees** and ellipsoidal height, m."""
    lat, lon = np.radians(np.asarray(lat, dtype=float)), np.radians(np.asarray(lon, dtype=float))
    height = np.asarray(height, dtype=float)
    _, re = principal_radii(lat)
    r = (re + height) * np.cos(lat)
    return np.stack([r * np.cos(lon), r * np.sin(lon), (re * (1.0 - E2) + height) * np.sin(lat)], -1)


def ecef_to_lla(xyz: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Latitude, longitude (degrees) and ellipsoidal height (m) of ECEF points.

    Bowring's initial value followed by Newton-type fixed-point iterations on the latitude,
    converged to below 1e-12 rad anywhere outside the Earth's centre.
    """
    xyz = np.asarray(xyz, dtype=float)
    x, y, z = xyz[..., 0], xyz[..., 1], xyz[..., 2]
    p = np.hypot(x, y)
    lon = np.arctan2(y, x)
    ep2 = E2 / (1.0 - E2)
    theta = np.arctan2(z * A, p * B)
    lat = np.arctan2(z + ep2 * B * np.sin(theta) ** 3, p - E2 * A * np.cos(theta) ** 3)
    for _ in range(3):
        _, re = principal_radii(lat)
        lat = np.arctan2(z + E2 * re * np.sin(lat), p)
    _, re = principal_radii(lat)
    c, s = np.cos(lat), np.sin(lat)
    # height from the larger of the two projections (stable at the poles and the equator)
    height = np.where(np.abs(c) > 0.5, p / np.where(c == 0, 1.0, c) - re,
                      z / np.where(s == 0, 1.0, s) - re * (1.0 - E2))
    return np.degrees(lat), np.degrees(lon), height


def ecef_to_ned_dcm(lat: ArrayLike, lon: ArrayLike) -> np.ndarray:
    """Rotation ``C_ne`` mapping ECEF vectors to NED at latitude/longitude in **degrees**."""
    lat, lon = np.radians(np.asarray(lat, dtype=float)), np.radians(np.asarray(lon, dtype=float))
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    return np.stack(
        [
            np.stack([-sl * co, -sl * so, cl], -1),
            np.stack([-so, co, np.zeros_like(lat)], -1),
            np.stack([-cl * co, -cl * so, -sl], -1),
        ],
        -2,
    )


def lla_to_ned(lat: ArrayLike, lon: ArrayLike, height: ArrayLike,
               lat0: float, lon0: float, height0: float) -> np.ndarray:
    """NED coordinates, m, of points relative to the origin ``(lat0, lon0, height0)`` (deg, m).

    Exact (through ECEF): the NED frame is the tangent frame at the origin.
    """
    d = lla_to_ecef(lat, lon, height) - lla_to_ecef(lat0, lon0, height0)
    return np.einsum("ij,...j->...i", ecef_to_ned_dcm(lat0, lon0), d)


def ned_to_lla(ned: ArrayLike, lat0: float, lon0: float, height0: float
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inverse of :func:`lla_to_ned`: latitude, longitude (deg) and height (m)."""
    ned = np.asarray(ned, dtype=float)
    d = np.einsum("ji,...j->...i", ecef_to_ned_dcm(lat0, lon0), ned)
    return ecef_to_lla(d + lla_to_ecef(lat0, lon0, height0))
