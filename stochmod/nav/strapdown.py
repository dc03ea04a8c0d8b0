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

One interval is :func:`mech_step`, compiled by numba without fast-math flags (so its results
are the plain Python function's to the bit) on a state vector of floats;
:func:`mech_steps` runs it over a record and the filter over its covariance steps.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import attrs
import numpy as np
from numpy.typing import ArrayLike

from stochmod.core.errors import InputError
from stochmod.core.jit import compiled
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

    __slots__ = ("_gravity", "_x")

    def __init__(self, state: NavState, gravity: Callable[[float, float], float] | None = None
                 ) -> None:
        self._gravity = gravity
        self._x = np.zeros(STATE_SIZE)
        self.set_state(state)

    def set_state(self, state: NavState) -> None:
        """Replace the state (keeps nothing of the previous extrapolation history)."""
        x = self._x
        x[:] = 0.0
        x[_Q] = frames.quat_normalize(state.q_nb)
        x[_V] = np.asarray(state.vel_ned, dtype=float)
        x[0], x[1], x[2] = float(state.lat), float(state.lon), float(state.height)

    def state(self) -> NavState:
        """The current state as a :class:`NavState`."""
        return NavState(np.array(self.q), np.array(self.v), self.lat, self.lon, self.h)

    @property
    def x(self) -> np.ndarray:
        """The state vector the compiled step works on (``lat, lon, h, v, q``, then the
        extrapolation history, ``w_in`` and ``dv_n``; a view, not a copy)."""
        return self._x

    lat = property(lambda self: float(self._x[0]),
                   lambda self, v: self._x.__setitem__(0, v), doc="Latitude, rad.")
    lon = property(lambda self: float(self._x[1]),
                   lambda self, v: self._x.__setitem__(1, v), doc="Longitude, rad.")
    h = property(lambda self: float(self._x[2]),
                 lambda self, v: self._x.__setitem__(2, v), doc="Ellipsoidal height, m.")
    v = property(lambda self: tuple(self._x[_V].tolist()),
                 lambda self, v: self._x.__setitem__(_V, v), doc="NED velocity (3 floats), m/s.")
    q = property(lambda self: tuple(self._x[_Q].tolist()),
                 lambda self, v: self._x.__setitem__(_Q, v),
                 doc="Attitude quaternion ``q_nb`` (4 floats, scalar first).")
    w_in = property(lambda self: tuple(self._x[_W_IN].tolist()),
                    doc="NED-frame rate w.r.t. inertial space at the start of the last step.")
    dv_n = property(lambda self: self._x[_DV_N], lambda self, v: self._x.__setitem__(_DV_N, v),
                    doc="Accumulated NED specific-force velocity increments (a view), m/s.")

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
        x = self._x
        g = math.nan if self._gravity is None else float(self._gravity(x[0], x[2]))
        mech_step(x, dt, dth[0], dth[1], dth[2], dvb[0], dvb[1], dvb[2], con[0], con[1], con[2],
                  scu[0], scu[1], scu[2], g)


#: Layout of :attr:`Mechanisation.x`: lat, lon, h (0-2), velocity (3-5), quaternion (6-9), the
#: previous step's frame rate and gravity/Coriolis term (10-15), whether there is one (16), the
#: previous step's length (17), ``w_in`` (18-20), ``dv_n`` (21-23).
STATE_SIZE = 24
_V, _Q, _W_IN, _DV_N = slice(3, 6), slice(6, 10), slice(18, 21), slice(21, 24)


@compiled(fastmath=frozenset())  # no flag: the compiled step gives the plain one's bits
def mech_step(x: np.ndarray, dt: float, ax: float, ay: float, az: float, bx: float, by: float,
              bz: float, c0: float, c1: float, c2: float, s0: float, s1: float, s2_: float,
              g: float) -> None:
    """One interval of the mechanisation on the state vector `x` (:attr:`Mechanisation.x`,
    updated in place): angle increment ``a``, velocity increment ``b``, coning ``c`` and
    sculling ``s`` terms; gravity `g` (m/s^2), NaN for eq. 16."""
    q0, q1, q2, q3 = x[6], x[7], x[8], x[9]
    vn, ve, vd = x[3], x[4], x[5]
    lat, h = x[0], x[2]
    # Earth model at the start of the interval: eqs. 9, 10, 11, 16
    sl, cl = math.sin(lat), math.cos(lat)
    s2 = sl * sl
    w = 1.0 - _E2 * s2
    sw = math.sqrt(w)
    re = _A / sw
    rn = re * (1.0 - _E2) / w
    if math.isnan(g):  # the square as a product: numba's `** 2` is one, CPython's a pow()
        d = 1.0 + h * sw / (re * _SQ1E2)
        g = _G0 * (1.0 + _G1 * s2 - _G2 * 4.0 * s2 * cl * cl) / (d * d)
    wen_n, wen_e = ve / (re + h), -vn / (rn + h)
    wen_d = -wen_n * sl / cl
    wx, wy, wz = _OM * cl + wen_n, wen_e, -_OM * sl + wen_d
    # eq. 17c without the specific force: g - (2 w_ie + w_en) x v
    cx, cz = wx + _OM * cl, wz - _OM * sl
    ax_, ay_, az_ = wy * vd - cz * ve, cz * vn - cx * vd, g - (cx * ve - wy * vn)
    ax_ = -ax_
    ay_ = -ay_
    if x[16] == 0.0:
        zx, zy, zz = wx * dt, wy * dt, wz * dt
        mx, my, mz = ax_ * dt, ay_ * dt, az_ * dt
    else:  # linear extrapolation to the middle of the interval
        k = 0.5 * dt / x[17]
        k1 = 1.0 + k
        zx, zy, zz = (k1 * wx - k * x[10]) * dt, (k1 * wy - k * x[11]) * dt, (k1 * wz - k * x[12]) * dt
        mx, my, mz = (k1 * ax_ - k * x[13]) * dt, (k1 * ay_ - k * x[14]) * dt, (k1 * az_ - k * x[15]) * dt
    x[10], x[11], x[12], x[13], x[14], x[15], x[16] = wx, wy, wz, ax_, ay_, az_, 1.0
    x[18], x[19], x[20] = wx, wy, wz
    x[17] = dt
    # body velocity increment: rotation and sculling compensation
    ux = bx + 0.5 * (ay * bz - az * by) + s0
    uy = by + 0.5 * (az * bx - ax * bz) + s1
    uz = bz + 0.5 * (ax * by - ay * bx) + s2_
    # C_nb from q (eq. 14, scalar first) applied to u
    fx = (q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3) * ux + 2.0 * ((q1 * q2 - q0 * q3) * uy + (q1 * q3 + q0 * q2) * uz)
    fy = (q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3) * uy + 2.0 * ((q1 * q2 + q0 * q3) * ux + (q2 * q3 - q0 * q1) * uz)
    fz = (q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3) * uz + 2.0 * ((q1 * q3 - q0 * q2) * ux + (q2 * q3 + q0 * q1) * uy)
    # navigation-frame rotation over the interval: (I - [zeta x] / 2)
    fx, fy, fz = (fx - 0.5 * (zy * fz - zz * fy), fy - 0.5 * (zz * fx - zx * fz),
                  fz - 0.5 * (zx * fy - zy * fx))
    x[21] += fx
    x[22] += fy
    x[23] += fz
    vn1, ve1, vd1 = vn + fx + mx, ve + fy + my, vd + fz + mz
    # attitude: q <- q(-zeta) * q * q(phi)   (eq. 13 as rotation vectors)
    px, py, pz = ax + c0, ay + c1, az + c2
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
    x[6], x[7], x[8], x[9] = n0 * nrm, n1 * nrm, n2 * nrm, n3 * nrm
    # position: eq. 18 with the mean velocity of the interval; the radii and cosine at the
    # middle latitude from first-order expansions (the latitude step is < 1e-5 rad)
    h1 = h - 0.5 * (vd + vd1) * dt
    hm = 0.5 * (h + h1)
    dlat = 0.5 * (vn + vn1) * dt / (rn + hm)
    half = 0.5 * dlat
    cm = cl - sl * half
    rem = re * (1.0 + _E2 * sl * cl * half / w)
    x[1] += 0.5 * (ve + ve1) * dt / ((rem + hm) * cm)
    x[0], x[2] = lat + dlat, h1
    x[3], x[4], x[5] = vn1, ve1, vd1


@compiled(fastmath=frozenset())
def mech_steps(x: np.ndarray, h: np.ndarray, dth: np.ndarray, dv: np.ndarray, con: np.ndarray,
               scu: np.ndarray, rows: np.ndarray) -> None:
    """Every interval of a record with eq. 16's gravity (:func:`mech_step`), the state after
    interval ``k`` written to ``rows[k + 1]`` (``lat, lon, h, v, q``)."""
    for k in range(h.size):
        mech_step(x, h[k], dth[k, 0], dth[k, 1], dth[k, 2], dv[k, 0], dv[k, 1], dv[k, 2],
                  con[k, 0], con[k, 1], con[k, 2], scu[k, 0], scu[k, 1], scu[k, 2], math.nan)
        rows[k + 1] = x[:10]


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
    arr = np.empty((t.size, 10))
    arr[0] = mech.x[:10]
    if gravity is None:
        mech_steps(mech.x, h, dth, dv, con, scu, arr)
    else:
        for k, (hk, a_, b_, c_, s_) in enumerate(zip(h.tolist(), dth.tolist(), dv.tolist(),
                                                    con.tolist(), scu.tolist())):
            mech.step(hk, a_, b_, c_, s_)
            arr[k + 1] = mech.x[:10]
    return StrapdownResult(t, np.degrees(arr[:, 0]), np.degrees(arr[:, 1]), arr[:, 2],
                           arr[:, 3:6], frames.quat_to_rph(arr[:, 6:10]))
