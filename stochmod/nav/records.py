"""Plain data records shared by the navigation modules: IMU samples and GNSS fixes.

Units: SI; latitude/longitude in degrees (the public edge), heights ellipsoidal in metres,
velocities NED in m/s. Arrays are validated on construction (finite, shapes, increasing time).
"""

from __future__ import annotations

import attrs
import numpy as np

from stochmod.core.fields import array_field
from stochmod.core.errors import InputError

__all__ = ["ImuData", "GnssData", "TrajectoryArrays", "IMU_KINDS", "check_time"]

#: ``"rate"``: angular rate (rad/s) and specific force (m/s^2) at the time stamp;
#: ``"increment"``: angle (rad) and velocity (m/s) increments over the interval ENDING at the stamp.
IMU_KINDS = ("rate", "increment")


def _as_float(value: object) -> np.ndarray:
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"expected numeric array data: {exc}") from None


def check_time(time: np.ndarray, name: str = "time", *, strict: bool = True) -> np.ndarray:
    """Return `time` as a finite 1-D float array, strictly increasing, or raise InputError."""
    t = np.asarray(time, dtype=float)
    if t.ndim != 1 or t.size == 0:
        raise InputError(f"{name} must be a non-empty 1-D array, got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        raise InputError(f"{name} contains non-finite values")
    d = np.diff(t)
    if strict and np.any(d <= 0):
        i = int(np.flatnonzero(d <= 0)[0])
        raise InputError(f"{name} must increase strictly: {name}[{i + 1}] = {t[i + 1]!r} "
                         f"follows {t[i]!r}")
    return t


def _check_rows(arr: np.ndarray, n: int, name: str, width: int = 3) -> None:
    if arr.shape != (n, width):
        raise InputError(f"{name} must have shape ({n}, {width}), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} contains non-finite values")


@attrs.frozen
class ImuData:
    """IMU samples in the body frame (x forward, y right, z down).

    Attributes
    ----------
    time : ndarray (n,)
        Time stamps, s, strictly increasing (any spacing).
    gyro : ndarray (n, 3)
        Angular rate w.r.t. inertial space, rad/s (``kind="rate"``), or angle increments, rad,
        over the interval ending at the stamp (``kind="increment"``).
    accel : ndarray (n, 3)
        Specific force, m/s^2, or velocity increments, m/s.
    kind : {"rate", "increment"}
    """

    time: np.ndarray = array_field(converter=_as_float)
    gyro: np.ndarray = array_field(converter=_as_float)
    accel: np.ndarray = array_field(converter=_as_float)
    kind: str = "rate"

    def __attrs_post_init__(self) -> None:
        if self.kind not in IMU_KINDS:
            raise InputError(f"kind must be one of {IMU_KINDS}, got {self.kind!r}")
        t = check_time(self.time, "imu time")
        if t.size < 2:
            raise InputError("an IMU record needs at least two samples")
        _check_rows(self.gyro, t.size, "gyro")
        _check_rows(self.accel, t.size, "accel")

    @property
    def n(self) -> int:
        """Number of samples."""
        return self.time.size


@attrs.frozen
class GnssData:
    """GNSS fixes (antenna position, optional NED velocity and standard deviations).

    Attributes
    ----------
    time : ndarray (m,)
        Time stamps, s (same clock as the IMU), strictly increasing.
    lat, lon : ndarray (m,)
        Latitude and longitude, deg.
    height : ndarray (m,)
        Ellipsoidal height, m.
    vel_ned : ndarray (m, 3) or None
        NED velocity, m/s; used by the filter when present.
    sd : ndarray (m, 3) or None
        1-sigma of the north, east, down position, m (the filter's default otherwise).
    sd_vel : ndarray (m, 3) or None
        1-sigma of the velocity, m/s (the filter's default otherwise).
    """

    time: np.ndarray = array_field(converter=_as_float)
    lat: np.ndarray = array_field(converter=_as_float)
    lon: np.ndarray = array_field(converter=_as_float)
    height: np.ndarray = array_field(converter=_as_float)
    vel_ned: np.ndarray | None = attrs.field(
        default=None, converter=attrs.converters.optional(_as_float))
    sd: np.ndarray | None = attrs.field(
        default=None, converter=attrs.converters.optional(_as_float))
    sd_vel: np.ndarray | None = attrs.field(
        default=None, converter=attrs.converters.optional(_as_float))

    def __attrs_post_init__(self) -> None:
        t = check_time(self.time, "gnss time")
        for name in ("lat", "lon", "height"):
            v = getattr(self, name)
            if v.shape != t.shape or not np.all(np.isfinite(v)):
                raise InputError(f"gnss {name} must be finite with shape {t.shape}, got {v.shape}")
        if np.any(np.abs(self.lat) > 90):
            raise InputError("gnss lat must be in degrees within [-90, 90]")
        for name in ("vel_ned", "sd", "sd_vel"):
            v = getattr(self, name)
            if v is not None:
                _check_rows(v, t.size, f"gnss {name}")
        for name in ("sd", "sd_vel"):
            v = getattr(self, name)
            if v is not None and np.any(v <= 0):
                raise InputError(f"gnss {name} must be positive")

    @property
    def n(self) -> int:
        """Number of fixes."""
        return self.time.size

    def select(self, keep: np.ndarray) -> GnssData:
        """The fixes where the boolean mask `keep` is true."""
        opt = {k: (None if getattr(self, k) is None else getattr(self, k)[keep])
               for k in ("vel_ned", "sd", "sd_vel")}
        return GnssData(self.time[keep], self.lat[keep], self.lon[keep], self.height[keep], **opt)


@attrs.frozen
class TrajectoryArrays:
    """Navigation solution or reference sampled at `time` (the base of trajectories and results).

    Attributes
    ----------
    time : ndarray (n,)
        s.
    lat, lon : ndarray (n,)
        deg.
    height : ndarray (n,)
        m (ellipsoidal).
    vel_ned : ndarray (n, 3)
        m/s.
    rph : ndarray (n, 3)
        Roll, pitch, heading, deg.
    """

    time: np.ndarray = array_field()
    lat: np.ndarray = array_field()
    lon: np.ndarray = array_field()
    height: np.ndarray = array_field()
    vel_ned: np.ndarray = array_field()
    rph: np.ndarray = array_field()

    @property
    def n(self) -> int:
        """Number of samples."""
        return self.time.size
