"""Initial alignment: static coarse alignment (levelling from the accelerometers, heading from
the magnetometer or a given value) and in-motion alignment from GNSS velocity.

Levelling: at rest the accelerometers read ``f_b = C_bn (0, 0, -g)``, so
``roll = atan2(-f_y, -f_z)`` and ``pitch = atan2(f_x, sqrt(f_y^2 + f_z^2))`` (the inverse of
Gonzalez eq. 14/15 for gravity only). In motion, the heading is the GNSS course
``atan2(v_E, v_N)`` and the pitch the climb angle (a land vehicle moves along its x axis).
"""

from __future__ import annotations

import math

import attrs
import numpy as np
from numpy.typing import ArrayLike

from stochmod.core.errors import InputError
from stochmod.nav.records import GnssData
from stochmod.nav.strapdown import NavState, check_imu

__all__ = ["InitialState", "level", "static_alignment", "align_from_gnss"]


@attrs.frozen
class InitialState:
    """Initial navigation state and its 1-sigma (Gonzalez eq. 24).

    Attributes
    ----------
    lat, lon : float
        deg.
    height : float
        m.
    vel_ned : array_like (3,)
        m/s.
    rph : array_like (3,)
        Roll, pitch, heading, deg.
    time : float or None
        Time of the state, s (None: the first IMU time). IMU samples before it are skipped.
    sd_position : float or (3,)
        N, E, D 1-sigma, m.
    sd_velocity : float or (3,)
        m/s.
    sd_attitude : float or (3,)
        Roll, pitch, heading 1-sigma, deg (taken as the psi-angle sigmas).
    """

    lat: float
    lon: float
    height: float
    vel_ned: np.ndarray = attrs.field(converter=lambda v: np.asarray(v, dtype=float))
    rph: np.ndarray = attrs.field(converter=lambda v: np.asarray(v, dtype=float))
    time: float | None = None
    sd_position: object = 3.0
    sd_velocity: object = 0.3
    sd_attitude: object = (1.0, 1.0, 3.0)

    def nav_state(self) -> NavState:
        """The state as a :class:`NavState` (radians inside)."""
        return NavState.from_degrees(lat=self.lat, lon=self.lon, height=self.height,
                                     vel_ned=self.vel_ned, rph=self.rph)

    def covariance(self) -> np.ndarray:
        """9x9 diagonal initial covariance of the navigation error states."""
        sd = np.concatenate([np.broadcast_to(np.asarray(v, dtype=float), (3,)) for v in
                             (self.sd_position, self.sd_velocity,
                              np.radians(np.asarray(self.sd_attitude, dtype=float)))])
        if not np.all(np.isfinite(sd)) or np.any(sd <= 0):
            raise InputError(f"initial standard deviations must be positive, got {sd}")
        return np.diag(sd**2)


def _mean_specific_force(time: np.ndarray, accel: np.ndarray, kind: str) -> np.ndarray:
    if kind == "increment":
        span = time[-1] - time[0]
        if span <= 0:
            raise InputError("levelling needs at least two increments")
        return accel[1:].sum(axis=0) / span
    return accel.mean(axis=0)


def level(f_b: ArrayLike) -> tuple[float, float]:
    """Roll and pitch (deg) from a mean specific force at rest (m/s^2, body axes)."""
    f = np.asarray(f_b, dtype=float).reshape(-1)
    if f.shape != (3,) or not np.all(np.isfinite(f)):
        raise InputError(f"specific force must be three finite numbers, got {f_b!r}")
    if np.linalg.norm(f) < 1.0:
        raise InputError(f"specific force {f} is far from gravity: the unit is not at rest "
                         "or the data are not in m/s^2")
    return (math.degrees(math.atan2(-f[1], -f[2])),
            math.degrees(math.atan2(f[0], math.hypot(f[1], f[2]))))


def static_alignment(time: ArrayLike, gyro: ArrayLike, accel: ArrayLike, *, lat: float,
                     lon: float, height: float, kind: str = "rate",
                     heading: float | None = None, mag: ArrayLike | None = None,
                     declination: float = 0.0, sd_heading: float = 5.0) -> InitialState:
    """Coarse alignment of a unit at rest over the given samples.

    Parameters
    ----------
    time, gyro, accel, kind
        IMU samples while static (as :func:`stochmod.nav.strapdown`).
    lat, lon, height
        Known position (deg, m).
    heading : float, optional
        Known heading, deg.
    mag : array_like (3,) or (n, 3), optional
        Magnetometer readings (any unit) for the heading (Gonzalez eq. 19a-b); used when
        `heading` is None.
    declination : float
        Magnetic declination D, deg (eq. 19b).
    sd_heading : float
        1-sigma of the heading, deg.

    Returns
    -------
    InitialState
        At the last time stamp, zero velocity.
    """
    t, _, a = check_imu(time, gyro, accel)
    roll, pitch = level(_mean_specific_force(t, a, kind))
    if heading is None:
        if mag is None:
            raise InputError("static alignment needs a heading or magnetometer readings")
        m = np.atleast_2d(np.asarray(mag, dtype=float)).mean(axis=0)
        r, p = math.radians(roll), math.radians(pitch)
        # eq. 19a: horizontal components of the magnetic field
        mx = m[0] * math.cos(p) + m[1] * math.sin(r) * math.sin(p) + m[2] * math.cos(r) * math.sin(p)
        my = m[1] * math.cos(r) - m[2] * math.sin(r)
        heading = math.degrees(math.atan2(-my, mx)) + declination  # eq. 19b (NED, y right)
    heading = (heading + 180.0) % 360.0 - 180.0
    return InitialState(lat, lon, height, np.zeros(3), np.array([roll, pitch, heading]),
                        time=float(t[-1]), sd_position=1.0, sd_velocity=0.05,
                        sd_attitude=(0.5, 0.5, sd_heading))


def align_from_gnss(time: ArrayLike, gyro: ArrayLike, accel: ArrayLike, gnss: GnssData, *,
                    kind: str = "rate", min_speed: float = 3.0, window: float = 1.0
                    ) -> InitialState:
    """In-motion alignment at the first GNSS fix with speed above `min_speed` m/s.

    Position and velocity from the fix (velocity from neighbouring fixes when the record has
    none), heading from the course, pitch from the climb angle, roll from the accelerometers
    averaged over `window` seconds before the fix.
    """
    t, _, a = check_imu(time, gyro, accel)
    if gnss.n < 2:
        raise InputError("GNSS alignment needs at least two fixes")
    if gnss.vel_ned is not None:
        vel = gnss.vel_ned
    else:
        from stochmod.nav.earth import ned_scale

        scale = ned_scale(np.radians(gnss.lat), gnss.height)
        pos = np.stack([np.radians(gnss.lat), np.radians(gnss.lon), gnss.height], -1) * scale
        vel = np.gradient(pos, gnss.time, axis=0)
    speed = np.linalg.norm(vel[:, :2], axis=1)
    ok = np.flatnonzero((speed >= min_speed) & (gnss.time >= t[0] + window) & (gnss.time < t[-2]))
    if ok.size == 0:
        raise InputError(f"no GNSS fix with horizontal speed >= {min_speed} m/s inside the IMU "
                         "record: give init or use static_alignment")
    i = int(ok[0])
    v = vel[i]
    sel = (t > gnss.time[i] - window) & (t <= gnss.time[i])
    f = _mean_specific_force(t[sel], a[sel], kind)
    roll = math.degrees(math.atan2(-f[1], -f[2]))
    pitch = math.degrees(math.atan2(-v[2], math.hypot(v[0], v[1])))
    hdg = math.degrees(math.atan2(v[1], v[0]))
    sd_pos = gnss.sd[i] if gnss.sd is not None else 3.0
    return InitialState(float(gnss.lat[i]), float(gnss.lon[i]), float(gnss.height[i]), v,
                        np.array([roll, pitch, hdg]), time=float(gnss.time[i]),
                        sd_position=sd_pos, sd_velocity=0.5, sd_attitude=(2.0, 2.0, 5.0))
