"""Strapdown mechanisation in the local-level NED frame with quaternion attitude.

The equations are Gonzalez et al. (2015) eqs. 9-19 (``gonzalez2015-unified-ins-gps-model.txt``):
Earth rate (eq. 9), transport rate (eq. 10), radii (eq. 11), quaternion attitude update by a
rotation vector (eq. 13), DCM (eq. 14), Euler angles (eq. 15), normal gravity (eq. 16), velocity
(eq. 17) and position (eq. 18). The seed integrates them with one Euler step per sample; here
the same equations are integrated to second order so that 100 Hz data stay within centimetres
over ten minutes:

- IMU samples are turned into increments over each interval. Rates are integrated with a linear
  model between samples (trapezoid); the second-order coning term
  ``h^2/12 w_{k-1} x w_k`` and sculling term ``h^2/12 (w_{k-1} x f_k + f_{k-1} x w_k)`` follow from
  that model. Increments use the previous-interval corrections, generalised to unequal
  intervals: ``c (dtheta_{k-1} x dtheta_k)`` and ``c (dtheta_{k-1} x dv_k + dv_{k-1} x dtheta_k)``
  with ``c = h_k^2 / (6 h_{k-1} (h_k + h_{k-1}))`` (``c = 1/12`` at a constant rate).
- Attitude: ``q <- q(-zeta) * q * q(phi)`` with the body rotation vector ``phi`` (eq. 13 in
  rotation-vector form) and the navigation-frame rotation ``zeta = (w_ie + w_en) h`` at the middle
  of the interval.
- Velocity: ``dv_n = (I - [zeta x]/2) C_nb (dv + dtheta x dv / 2 + sculling)``, plus gravity and
  Coriolis (eq. 17c) at the middle of the interval (extrapolated from the two previous epochs).
- Position: eq. 18 with the trapezoid of the old and new velocity.

The hot loop is plain Python on floats (the ``math`` module): on 3-vectors a float expression
costs less than the overhead of one numpy call.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import attrs
import numpy as np
from numpy.typing import ArrayLike

from stochmod.core.errors import InputError
from stochmod.nav import earth, frames
from stochmod.nav.records import IMU_KINDS, TrajectoryArrays, check_time

__all__ = [
    "Mechanisation",
    "NavState",
    "StrapdownResult",
    "check_imu",
    "imu_increments",
    "strapdown",
]

_OM = earth.OMEGA_IE
_A, _E2 = earth.A, earth.E2
_G0, _G1, _G2 = earth.GRAVITY_G0, earth.GRAVITY_G1, earth.GRAVITY_G2
_SQ1E2 = math.sqrt(1.0 - _E2)


@attrs.define
class NavState:
    """Navigation state: attitude quaternion ``q_nb`` (scalar first, body to NED), NED velocity
    (m/s), latitude and longitude (rad) and ellipsoidal height (m)."""

    q_nb: np.ndarray
    vel_ned: np.ndarray
    lat: float
    lon: float
    height: float

    @classmethod
    def from_degrees(cls, *, lat: float, lon: float, height: float, vel_ned: ArrayLike,
                     rph: ArrayLike) -> NavState:
        """State from latitude/longitude (deg), height (m), NED velocity (m/s) and roll, pitch,
        heading (deg)."""
        vel = np.asarray(vel_ned, dtype=float).reshape(-1)
        rph = np.asarray(rph, dtype=float).reshape(-1)
        vals = [lat, lon, height, *vel, *rph]
        if vel.size != 3 or rph.size != 3:
            raise InputError("vel_ned and rph must have three components each")
        if not np.all(np.isfinite(vals)):
            raise InputError(f"initial state must be finite, got {vals}")
        if abs(lat) >= 90.0:
            raise InputError(f"latitude must be within (-90, 90) deg, got {lat}")
        return cls(frames.rph_to_quat(rph), vel, math.radians(lat), math.radians(lon),
                   float(height))

    @property
    def rph(self) -> np.ndarray:
        """Roll, pitch, heading, deg."""
        return frames.quat_to_rph(self.q_nb)

    @property
    def C_nb(self) -> np.ndarray:
        """Body-to-NED rotation matrix."""
        return frames.quat_to_dcm(self.q_nb)


class Mechanisation:
    """Single-step strapdown integrator on scalar floats (the filter's inner loop).

    Parameters
    ----------
    state : NavState
        The state at the first epoch.
    gravity : callable, optional
        ``gravity(lat, h) -> g``: normal gravity magnitude (m/s^2) at geodetic latitude `lat`
        (rad) and ellipsoidal height `h` (m), down in NED; default eq. 16 with Table II. For
        comparisons with another tool's simulator, whose ideal IMU holds its own gravity model
        (a difference of 1e-5 m/s^2 drives the vertical channel, and through the Coriolis term
        the horizontal position, by centimetres in ten minutes).

    Notes
    -----
    :meth:`step` advances by one interval of length ``dt`` given the (already bias-corrected)
    angle and velocity increments and their coning/sculling terms. The attributes ``q``
    (tuple of 4), ``v`` (tuple of 3), ``lat``, ``lon``, ``h`` hold the current state; the filter
    corrects them in place between steps (:meth:`set_state`).
    """

    __slots__ = ("_dtp", "_gravity", "_prev", "dv_n", "h", "lat", "lon", "q", "v", "w_in")

    def __init__(self, state: NavState, gravity: Callable[[float, float], float] | None = None
                 ) -> None:
        self._gravity = gravity
        self.set_state(state)

    def set_state(self, state: NavState) -> None:
        """Replace the state (keeps nothing of the previous extrapolation history)."""
        q = frames.quat_normalize(state.q_nb)
        self.q = tuple(float(x) for x in q)
        self.v = tuple(float(x) for x in np.asarray(state.vel_ned, dtype=float))
        self.lat, self.lon, self.h = float(state.lat), float(state.lon), float(state.height)
        self._prev = None
        self._dtp = 0.0
        self.dv_n = [0.0, 0.0, 0.0]
        self.w_in = (0.0, 0.0, 0.0)

    def state(self) -> NavState:
        """The current state as a :class:`NavState`."""
        return NavState(np.array(self.q), np.array(self.v), self.lat, self.lon, self.h)

    def step(self, dt: float, dth: Sequence[float], dvb: Sequence[float],
             con: Sequence[float], scu: Sequence[float]) -> None:
        """Advance the state over an interval.

        Parameters
        ----------
        dt : float
            Interval length, s.
        dth, dvb : 3-sequences
            Angle increment (rad) and velocity increment (m/s) in the body frame.
        con, scu : 3-sequences
            Coning (rad) and sculling (m/s) corrections of the interval.

        Notes
        -----
        ``dv_n`` accumulates the specific-force velocity increments in NED (m/s) until the
        caller resets it (the filter's mean specific force over its step); ``w_in`` is the
        NED frame's rate w.r.t. inertial space at the start of the interval.
        """
        q0, q1, q2, q3 = self.q
        vn, ve, vd = self.v
        lat, h = self.lat, self.h
        # Earth model at the start of the interval: eqs. 9, 10, 11, 16
        sl, cl = math.sin(lat), math.cos(lat)
        s2 = sl * sl
        w = 1.0 - _E2 * s2
        sw = math.sqrt(w)
        re = _A / sw
        rn = re * (1.0 - _E2) / w
        if self._gravity is None:
            g = _G0 * (1.0 + _G1 * s2 - _G2 * 4.0 * s2 * cl * cl) / (1.0 + h * sw / (re * _SQ1E2)) ** 2
        else:
            g = float(self._gravity(lat, h))
        wen_n, wen_e = ve / (re + h), -vn / (rn + h)
        wen_d = -wen_n * sl / cl
        wx, wy, wz = _OM * cl + wen_n, wen_e, -_OM * sl + wen_d
        # eq. 17c without the specific force: g - (2 w_ie + w_en) x v
        cx, cz = wx + _OM * cl, wz - _OM * sl
        ax_, ay_, az_ = wy * vd - cz * ve, cz * vn - cx * vd, g - (cx * ve - wy * vn)
        ax_ = -ax_
        ay_ = -ay_
        prev = self._prev
        self._prev = (wx, wy, wz, ax_, ay_, az_)
        self.w_in = (wx, wy, wz)
        if prev is None:
            zx, zy, zz = wx * dt, wy * dt, wz * dt
            mx, my, mz = ax_ * dt, ay_ * dt, az_ * dt
        else:  # linear extrapolation to the middle of the interval
            k = 0.5 * dt / self._dtp
            k1 = 1.0 + k
            zx, zy, zz = (k1 * wx - k * prev[0]) * dt, (k1 * wy - k * prev[1]) * dt, (k1 * wz - k * prev[2]) * dt
            mx, my, mz = (k1 * ax_ - k * prev[3]) * dt, (k1 * ay_ - k * prev[4]) * dt, (k1 * az_ - k * prev[5]) * dt
        self._dtp = dt
        # body velocity increment: rotation and sculling compensation
        ax, ay, az = dth
        bx, by, bz = dvb
        ux = bx + 0.5 * (ay * bz - az * by) + scu[0]
        uy = by + 0.5 * (az * bx - ax * bz) + scu[1]
        uz = bz + 0.5 * (ax * by - ay * bx) + scu[2]
        # C_nb from q (eq. 14, scalar first) applied to u
        fx = (q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3) * ux + 2.0 * ((q1 * q2 - q0 * q3) * uy + (q1 * q3 + q0 * q2) * uz)
        fy = (q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3) * uy + 2.0 * ((q1 * q2 + q0 * q3) * ux + (q2 * q3 - q0 * q1) * uz)
        fz = (q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3) * uz + 2.0 * ((q1 * q3 - q0 * q2) * ux + (q2 * q3 + q0 * q1) * uy)
        # navigation-frame rotation over the interval: (I - [zeta x] / 2)
        fx, fy, fz = (fx - 0.5 * (zy * fz - zz * fy), fy - 0.5 * (zz * fx - zx * fz),
                      fz - 0.5 * (zx * fy - zy * fx))
        acc = self.dv_n
        acc[0] += fx
        acc[1] += fy
        acc[2] += fz
        vn1, ve1, vd1 = vn + fx + mx, ve + fy + my, vd + fz + mz
        # attitude: q <- q(-zeta) * q * q(phi)   (eq. 13 as rotation vectors)
        px, py, pz = ax + con[0], ay + con[1], az + con[2]
        a2 = px * px + py * py + pz * pz
        if a2 < 2.5e-3:  # |phi| < 0.05 rad: series exact to ~1e-15
            s = 0.5 - a2 / 48.0 + a2 * a2 / 3840.0
            c = 1.0 - a2 / 8.0 + a2 * a2 / 384.0 - a2 * a2 * a2 / 46080.0
        else:
            a = math.sqrt(a2)
            s, c = math.sin(0.5 * a) / a, math.cos(0.5 * a)
        r1, r2, r3 = s * px, s * py, s * pz
        t0 = q0 * c - q1 * r1 - q2 * r2 - q3 * r3
        t1 = q0 * r1 + q1 * c + q2 * r3 - q3 * r2
        t2 = q0 * r2 - q1 * r3 + q2 * c + q3 * r1
        t3 = q0 * r3 + q1 * r2 - q2 * r1 + q3 * c
        # q(-zeta): |zeta| < 1e-3 rad, so the second-order series is exact to double precision
        l0 = 1.0 - (zx * zx + zy * zy + zz * zz) / 8.0
        l1, l2, l3 = -0.5 * zx, -0.5 * zy, -0.5 * zz
        n0 = l0 * t0 - l1 * t1 - l2 * t2 - l3 * t3
        n1 = l0 * t1 + l1 * t0 + l2 * t3 - l3 * t2
        n2 = l0 * t2 - l1 * t3 + l2 * t0 + l3 * t1
        n3 = l0 * t3 + l1 * t2 - l2 * t1 + l3 * t0
        nrm = 1.0 / math.sqrt(n0 * n0 + n1 * n1 + n2 * n2 + n3 * n3)  # eq. 13h
        self.q = (n0 * nrm, n1 * nrm, n2 * nrm, n3 * nrm)
        # position: eq. 18 with the mean velocity of the interval; the radii and cosine at the
        # middle latitude from first-order expansions (the latitude step is < 1e-5 rad)
        h1 = h - 0.5 * (vd + vd1) * dt
        hm = 0.5 * (h + h1)
        dlat = 0.5 * (vn + vn1) * dt / (rn + hm)
        half = 0.5 * dlat
        cm = cl - sl * half
        rem = re * (1.0 + _E2 * sl * cl * half / w)
        self.lon += 0.5 * (ve + ve1) * dt / ((rem + hm) * cm)
        self.lat, self.h = lat + dlat, h1
        self.v = (vn1, ve1, vd1)


def imu_increments(time: np.ndarray, gyro: np.ndarray, accel: np.ndarray, kind: str
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Angle and velocity increments with coning and sculling terms for every interval.

    Returns
    -------
    dt : ndarray (n-1,)
        Interval lengths, s.
    dtheta, dv : ndarray (n-1, 3)
        Increments over ``(time[k], time[k+1]]``.
    coning, sculling : ndarray (n-1, 3)
        Second-order corrections (see the module notes).
    """
    if kind not in IMU_KINDS:
        raise InputError(f"kind must be one of {IMU_KINDS}, got {kind!r}")
    h = np.diff(time)
    if kind == "rate":
        w0, w1, f0, f1 = gyro[:-1], gyro[1:], accel[:-1], accel[1:]
        hh = h[:, None]
        dth = 0.5 * (w0 + w1) * hh
        dv = 0.5 * (f0 + f1) * hh
        k = hh * hh / 12.0
        con = k * np.cross(w0, w1)
        scu = k * (np.cross(w0, f1) + np.cross(f0, w1))
        return h, dth, dv, con, scu
    dth, dv = gyro[1:], accel[1:]
    hp = np.concatenate([h[:1], h[:-1]])  # the interval before the first one: assumed equal
    c = (h * h / (6.0 * hp * (h + hp)))[:, None]
    con = c * np.cross(gyro[:-1], dth)
    scu = c * (np.cross(gyro[:-1], dv) + np.cross(accel[:-1], dth))
    return h, dth, dv, con, scu


@attrs.frozen
class StrapdownResult(TrajectoryArrays):
    """Free-inertial trajectory at the IMU time stamps (time s, lat/lon deg, height m,
    vel_ned m/s, rph deg)."""


def check_imu(time: ArrayLike, gyro: ArrayLike, accel: ArrayLike
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """IMU arrays checked: strictly increasing finite time (s, at least two samples) and
    finite (n, 3) gyro and accel of the same length (InputError naming the problem)."""
    t = check_time(time, "time")
    if t.size < 2:
        raise InputError("strapdown needs at least two IMU samples")
    out = []
    for name, x in (("gyro", gyro), ("accel", accel)):
        a = np.asarray(x, dtype=float)
        if a.shape != (t.size, 3):
            raise InputError(f"{name} must have shape ({t.size}, 3), got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise InputError(f"{name} contains non-finite values")
        out.append(a)
    return t, out[0], out[1]


def strapdown(time: ArrayLike, gyro: ArrayLike, accel: ArrayLike, *, lat: float, lon: float,
              height: float, vel_ned: ArrayLike, rph: ArrayLike, kind: str = "rate",
              gravity: Callable[[float, float], float] | None = None) -> StrapdownResult:
    """Free-inertial navigation from the state at ``time[0]``.

    Parameters
    ----------
    time : array_like (n,)
        IMU time stamps, s; strictly increasing, any spacing.
    gyro, accel : array_like (n, 3)
        ``kind="rate"``: angular rate w.r.t. inertial space (rad/s) and specific force (m/s^2),
        body axes x forward, y right, z down. ``kind="increment"``: angle (rad) and velocity
        (m/s) increments over the interval ENDING at each stamp (the first row only enters
        the coning/sculling correction of the second interval).
    lat, lon : float
        Initial latitude and longitude, deg.
    height : float
        Initial ellipsoidal height, m.
    vel_ned : array_like (3,)
        Initial NED velocity, m/s.
    rph : array_like (3,)
        Initial roll, pitch, heading, deg (``C_nb = Rz(heading) Ry(pitch) Rx(roll)``).
    kind : {"rate", "increment"}
    gravity : callable, optional
        ``gravity(lat_rad, height_m) -> m/s^2``, the normal gravity (default eq. 16 with Table
        II; :class:`Mechanisation`).

    Returns
    -------
    StrapdownResult
    """
    t, g, a = check_imu(time, gyro, accel)
    mech = Mechanisation(NavState.from_degrees(lat=lat, lon=lon, height=height, vel_ned=vel_ned,
                                               rph=rph), gravity)
    h, dth, dv, con, scu = imu_increments(t, g, a, kind)
    rows = [(mech.lat, mech.lon, mech.h, *mech.v, *mech.q)]
    append, step = rows.append, mech.step
    for hk, a_, b_, c_, s_ in zip(h.tolist(), dth.tolist(), dv.tolist(), con.tolist(),
                                  scu.tolist()):
        step(hk, a_, b_, c_, s_)
        append((mech.lat, mech.lon, mech.h, *mech.v, *mech.q))
    arr = np.array(rows)
    return StrapdownResult(t, np.degrees(arr[:, 0]), np.degrees(arr[:, 1]), arr[:, 2],
                           arr[:, 3:6], frames.quat_to_rph(arr[:, 6:10]))
