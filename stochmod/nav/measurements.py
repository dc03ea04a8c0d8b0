"""Measurement models of the error-state filter: each gives the innovation ``y = predicted -
measured``, its Jacobian ``H`` with respect to the 9 navigation error states and the noise
covariance ``R``.

Error states (all "estimate minus truth"): position ``dr`` (NED, m), velocity ``dv`` (NED, m/s),
attitude ``psi`` (rad) with ``C_nb_hat = (I - [psi x]) C_nb``. Equations: Gonzalez et al. (2015)
eq. 20g-20j and 20m (GNSS position with lever arm, GNSS velocity, magnetic heading), eq. 23 (R).
Gonzalez's H (eq. 20m) keeps only the position and velocity blocks; here the lever-arm terms
are differentiated as well (Groves 2013, Chapter 14): ``[(C l) x]`` and
``[(C (w x l)) x]`` on the attitude error and, through :meth:`Measurement.rate_jacobian`,
``-C [l x]`` on the error of the body rate, which the filter carries into its gyro-error
states. The body rate is the NED-relative one, ``w_nb = w_ib - C_bn w_in`` (eq. 20h); the
Earth-relative antenna velocity strictly needs ``w_eb = w_ib - C_bn w_ie``, a difference of
``|w_en| |l|``, below 1e-5 m/s for a car.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import attrs
import numpy as np

from stochmod.core.errors import InputError
from stochmod.nav import earth, frames

__all__ = [
    "Snapshot",
    "Measurement",
    "GnssPosition",
    "GnssVelocity",
    "MagneticHeading",
    "ZeroVelocity",
]


class Snapshot(NamedTuple):
    """Navigation estimate at a measurement's time stamp.

    lat, lon (rad), height (m), vel_ned (3,), C_nb (3, 3), w_nb_b: body rate relative to the
    NED frame (rad/s, body axes), w_in: NED-frame rate w.r.t. inertial space (rad/s),
    lever_arm: the filter's current estimate of the IMU-to-antenna lever arm (body, m) when it
    estimates it, else None (the measurement's own lever arm is used)."""

    lat: float
    lon: float
    height: float
    vel_ned: np.ndarray
    C_nb: np.ndarray
    w_nb_b: np.ndarray
    w_in: np.ndarray
    lever_arm: np.ndarray | None = None


class Measurement:
    """Base: ``evaluate(snapshot) -> (y, H_nav, R)`` with ``H_nav`` of shape (m, 9);
    ``lever_arm_jacobian(snapshot)`` gives ``dy/d(lever arm)`` (m, 3), or None when the
    measurement does not depend on the antenna lever arm."""

    kind = "measurement"

    def evaluate(self, s: Snapshot) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # pragma: no cover
        raise NotImplementedError

    def lever_arm_jacobian(self, s: Snapshot) -> np.ndarray | None:
        """Jacobian of the innovation with respect to the lever-arm error (None: independent)."""
        return None

    def rate_jacobian(self, s: Snapshot) -> np.ndarray | None:
        """Jacobian of the innovation with respect to the error of the body rate ``w_nb_b``
        it is predicted with (m, 3), or None when it does not use the body rate. The filter
        carries it into the gyro-error states: the rate is the gyro output less the estimated
        gyro error, so its error is minus the gyro-error estimate's."""
        return None


def _sd3(sd: object, name: str) -> np.ndarray:
    v = np.broadcast_to(np.asarray(sd, dtype=float), (3,)).copy()
    if not np.all(np.isfinite(v)) or np.any(v <= 0):
        raise InputError(f"{name} must be positive and finite, got {sd!r}")
    return v


@attrs.frozen
class GnssPosition(Measurement):
    """Antenna position fix (Gonzalez eq. 20i-20j): ``y = T (p_hat - p_gnss) + C_nb l``.

    Attributes: lat, lon (deg), height (m), sd (N, E, D 1-sigma, m), lever_arm (body, m).
    """

    lat: float
    lon: float
    height: float
    sd: np.ndarray = attrs.field(converter=lambda v: _sd3(v, "GNSS position sd"))
    lever_arm: np.ndarray = attrs.field(factory=lambda: np.zeros(3),
                                        converter=lambda v: np.asarray(v, dtype=float))
    kind = "gnss_position"

    def evaluate(self, s: Snapshot) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        rn, re = earth.principal_radii(s.lat)
        arm = s.C_nb @ (self.lever_arm if s.lever_arm is None else s.lever_arm)
        y = np.array([(s.lat - math.radians(self.lat)) * (rn + s.height),
                      (s.lon - math.radians(self.lon)) * (re + s.height) * math.cos(s.lat),
                      -(s.height - self.height)]) + arm
        H = np.zeros((3, 9))
        H[:, 0:3] = np.eye(3)
        H[:, 6:9] = frames.skew(arm)  # d(C_hat l) = (C l) x psi
        return y, H, np.diag(self.sd**2)

    def lever_arm_jacobian(self, s: Snapshot) -> np.ndarray:
        """``d(C_nb l)/dl = C_nb`` (Gonzalez eq. 20i with the lever arm as a state)."""
        return s.C_nb


@attrs.frozen
class GnssVelocity(Measurement):
    """Antenna velocity (Gonzalez eq. 20h): ``y = v_hat + C_nb (w_nb x l) - v_gnss``.

    Its Jacobian (Groves 2013, Chapter 14, the loosely coupled velocity measurement with a
    lever arm): ``I`` on the velocity error, ``[(C_nb (w_nb x l)) x]`` on the attitude
    error (``d(C_hat a) = (C a) x psi``) and ``-C_nb [l x]`` on the error of the body rate
    (:meth:`rate_jacobian`; the filter maps it to the gyro-error states).

    Attributes: vel_ned (3,), sd (3,) m/s, lever_arm (body, m).
    """

    vel_ned: np.ndarray = attrs.field(converter=lambda v: np.asarray(v, dtype=float))
    sd: np.ndarray = attrs.field(converter=lambda v: _sd3(v, "GNSS velocity sd"))
    lever_arm: np.ndarray = attrs.field(factory=lambda: np.zeros(3),
                                        converter=lambda v: np.asarray(v, dtype=float))
    kind = "gnss_velocity"

    def evaluate(self, s: Snapshot) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        arm_v = s.C_nb @ np.cross(s.w_nb_b, self.lever_arm if s.lever_arm is None else s.lever_arm)
        y = s.vel_ned + arm_v - self.vel_ned
        H = np.zeros((3, 9))
        H[:, 3:6] = np.eye(3)
        H[:, 6:9] = frames.skew(arm_v)
        return y, H, np.diag(self.sd**2)

    def lever_arm_jacobian(self, s: Snapshot) -> np.ndarray:
        """``d(C_nb (w_nb x l))/dl = C_nb [w_nb x]`` (eq. 20h with the lever arm as a state)."""
        return s.C_nb @ frames.skew(s.w_nb_b)

    def rate_jacobian(self, s: Snapshot) -> np.ndarray | None:
        """``d(C_nb (w_nb x l))/dw_nb = -C_nb [l x]`` (None without a lever arm)."""
        arm = self.lever_arm if s.lever_arm is None else s.lever_arm
        return None if not np.any(arm) else -s.C_nb @ frames.skew(arm)


def heading_jacobian(C_nb: np.ndarray) -> np.ndarray:
    """d(heading)/d(psi) for ``C_hat = (I - [psi x]) C``: ``-(cos h tan p, sin h tan p, 1)``."""
    c00, c10, c20 = C_nb[0, 0], C_nb[1, 0], C_nb[2, 0]
    d = c00 * c00 + c10 * c10  # cos^2 pitch
    # heading = atan2(c10, c00); dC = -[psi x] C changes (c00, c10) by (psi_z c10 - psi_y c20,
    # psi_x c20 - psi_z c00)
    return np.array([c00 * c20, c10 * c20, -(c00 * c00 + c10 * c10)]) / d


@attrs.frozen
class MagneticHeading(Measurement):
    """Magnetic heading with declination removed (Gonzalez eq. 19-20g): ``y = psi_hat - psi_m``.

    Attributes: heading (deg), sd (deg).
    """

    heading: float
    sd: float
    kind = "heading"

    def __attrs_post_init__(self) -> None:
        if not (math.isfinite(self.heading) and self.sd > 0):
            raise InputError(f"heading must be finite and sd positive, got {self.heading}, {self.sd}")

    def evaluate(self, s: Snapshot) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        hdg = math.atan2(s.C_nb[1, 0], s.C_nb[0, 0])
        d = (hdg - math.radians(self.heading) + math.pi) % (2 * math.pi) - math.pi
        H = np.zeros((1, 9))
        H[0, 6:9] = heading_jacobian(s.C_nb)
        return np.array([d]), H, np.array([[math.radians(self.sd) ** 2]])


@attrs.frozen
class ZeroVelocity(Measurement):
    """Zero-velocity update for stops: ``y = v_hat``, 1-sigma `sd` m/s per axis."""

    sd: float = 0.02
    kind = "zero_velocity"

    def evaluate(self, s: Snapshot) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if not self.sd > 0:
            raise InputError(f"zero-velocity sd must be positive, got {self.sd}")
        H = np.zeros((3, 9))
        H[:, 3:6] = np.eye(3)
        return np.asarray(s.vel_ned, dtype=float).copy(), H, np.eye(3) * self.sd**2
