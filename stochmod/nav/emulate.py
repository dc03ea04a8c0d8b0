"""Emulation: reference trajectories from motion profiles, their exact IMU, sensor errors,
GNSS and magnetometer measurements with scheduled outages.

This follows the seeds' emulation method (Stebler et al. 2014, Section VI; Quinchia et al. 2013,
Section 7): a reference trajectory, its error-free IMU signal, sensor errors added per axis
(drawn from a stochastic model, or taken from a real static recording), GNSS with the noise of
Gonzalez et al. (2015) Section II-D (eq. 6-8, CEP to sigma by eq. 7) and GNSS outages.

A profile trajectory is analytic: speed, heading, pitch and roll blend between segment values
with the quintic ``s(u) = 10u^3 - 15u^4 + 6u^5`` (zero first and second derivatives at the
segment ends, so the motion is twice continuously differentiable); the body x axis points
along the velocity. The geodetic position integrates eq. 18's differential form with an
8th-order Runge-Kutta (``DOP853``, relative tolerance 1e-12). The ideal IMU is the exact inverse
of the mechanisation's differential equations: ``w_ib^b = w_nb^b + C_bn (w_ie + w_en)`` and
``f^b = C_bn (dv/dt - g + (2 w_ie + w_en) x v)`` (eq. 13a, 17c solved for the sensors); the
increments integrate them over each interval with 5-point Gauss-Legendre quadrature.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import attrs
import numpy as np
from numpy.typing import ArrayLike

from stochmod.core.errors import InputError
from stochmod.core.model import Model
from stochmod.nav import earth, frames
from stochmod.nav.records import IMU_KINDS, GnssData, ImuData, TrajectoryArrays

__all__ = [
    "Segment",
    "Trajectory",
    "trajectory_from_profile",
    "ideal_imu",
    "add_sensor_errors",
    "gnss_measurements",
    "magnetometer_heading",
    "cep_to_sigma",
    "AXES",
]

#: Per-axis sensor names, in the order of the 6 IMU channels.
AXES = ("gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z")

#: Gonzalez eq. 7: sigma_lat = sigma_lon = 0.8493 CEP.
_CEP_FACTOR = 0.8493


def cep_to_sigma(cep: float) -> float:
    """Horizontal 1-sigma per axis (m) from a circular error probable (m), Gonzalez eq. 7."""
    if not cep > 0:
        raise InputError(f"CEP must be positive, got {cep!r}")
    return _CEP_FACTOR * float(cep)


@attrs.frozen
class Segment:
    """One segment of a motion profile.

    Attributes
    ----------
    duration : float
        s (> 0).
    speed : float or None
        Speed at the end of the segment, m/s (None: unchanged).
    turn : float
        Heading change over the segment, deg (positive: to the right, clockwise seen from above).
    pitch : float or None
        Pitch (= climb angle of the path) at the end of the segment, deg (None: unchanged).
    roll : float or None
        Roll at the end of the segment, deg (None: unchanged).
    """

    duration: float
    speed: float | None = None
    turn: float = 0.0
    pitch: float | None = None
    roll: float | None = None

    def __attrs_post_init__(self) -> None:
        if not (math.isfinite(self.duration) and self.duration > 0):
            raise InputError(f"segment duration must be positive, got {self.duration!r}")
        if self.speed is not None and not (math.isfinite(self.speed) and self.speed >= 0):
            raise InputError(f"segment speed must be >= 0 m/s, got {self.speed!r}")
        for name in ("pitch", "roll"):
            v = getattr(self, name)
            if v is not None and not abs(v) < 80.0:
                raise InputError(f"segment {name} must be within (-80, 80) deg, got {v!r}")
        if not math.isfinite(self.turn):
            raise InputError(f"segment turn must be finite, got {self.turn!r}")


class _ProfileMotion:
    """Analytic motion of a profile: speed, heading, pitch, roll as C2 functions of time."""

    def __init__(self, t0: float, knots: np.ndarray, values: np.ndarray,
                 lat: float, lon: float, height: float) -> None:
        self.t0 = t0
        self.knots = knots            # (m+1,) segment boundaries, s
        self.values = values          # (m+1, 4): speed, heading, pitch, roll (rad) at the knots
        from scipy.integrate import solve_ivp  # here: half the import time of stochmod.nav

        t_end = knots[-1]
        sol = solve_ivp(self._rhs, (t0, t_end), [lat, lon, height], method="DOP853",
                        rtol=1e-12, atol=[1e-14, 1e-14, 1e-7], dense_output=True,
                        max_step=max(1.0, (t_end - t0) / 2000))
        if not sol.success:  # pragma: no cover - DOP853 on a smooth bounded ODE
            raise InputError(f"position integration failed: {sol.message}")
        self._pos = sol.sol

    def kinematics(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Values, first and second time derivatives of (speed, heading, pitch, roll), (n, 4)."""
        t = np.clip(np.asarray(t, dtype=float), self.knots[0], self.knots[-1])
        i = np.clip(np.searchsorted(self.knots, t, side="right") - 1, 0, len(self.knots) - 2)
        d = (self.knots[i + 1] - self.knots[i])[:, None]
        u = ((t - self.knots[i])[:, None]) / d
        x0, dx = self.values[i], self.values[i + 1] - self.values[i]
        s = u**3 * (10.0 - 15.0 * u + 6.0 * u * u)
        s1 = 30.0 * u * u * (1.0 - u) ** 2 / d
        s2 = 60.0 * u * (1.0 - u) * (1.0 - 2.0 * u) / (d * d)
        return x0 + dx * s, dx * s1, dx * s2

    def velocity(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """NED velocity and its time derivative, (n, 3) each."""
        x, x1, _ = self.kinematics(t)
        v, psi, th = x[:, 0], x[:, 1], x[:, 2]
        dv, dpsi, dth = x1[:, 0], x1[:, 1], x1[:, 2]
        cp, sp, ct, st = np.cos(psi), np.sin(psi), np.cos(th), np.sin(th)
        u = np.stack([ct * cp, ct * sp, -st], -1)
        du = np.stack([-st * dth * cp - ct * sp * dpsi, -st * dth * sp + ct * cp * dpsi,
                       -ct * dth], -1)
        return v[:, None] * u, dv[:, None] * u + v[:, None] * du

    def _rhs(self, t: float, y: np.ndarray) -> list[float]:
        lat, _, h = y
        v, _ = self.velocity(np.array([t]))
        rn, re = earth.principal_radii(lat)
        return [v[0, 0] / (rn + h), v[0, 1] / ((re + h) * math.cos(lat)), -v[0, 2]]

    def position(self, t: np.ndarray) -> np.ndarray:
        """(lat rad, lon rad, height m), (n, 3)."""
        t = np.clip(np.asarray(t, dtype=float), self.knots[0], self.knots[-1])
        return self._pos(t).T

    def sensors(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """True angular rate w.r.t. inertial space (rad/s) and specific force (m/s^2), body."""
        x, x1, _ = self.kinematics(t)
        psi, th, ph = x[:, 1], x[:, 2], x[:, 3]
        dpsi, dth, dph = x1[:, 1], x1[:, 2], x1[:, 3]
        sph, cph, sth, cth = np.sin(ph), np.cos(ph), np.sin(th), np.cos(th)
        # Euler-angle rates to body rates (ZYX)
        w_nb = np.stack([dph - dpsi * sth, dth * cph + dpsi * sph * cth,
                         -dth * sph + dpsi * cph * cth], -1)
        pos = self.position(t)
        vel, acc = self.velocity(t)
        w_ie = earth.earth_rate_ned(pos[:, 0])
        w_en = earth.transport_rate_ned(pos[:, 0], pos[:, 2], vel)
        C_nb = frames.rph_to_dcm(np.degrees(np.stack([ph, th, psi], -1)))
        g = earth.gravity_ned(pos[:, 0], pos[:, 2])
        f_n = acc - g + np.cross(2.0 * w_ie + w_en, vel)
        w_ib = w_nb + np.einsum("nji,nj->ni", C_nb, w_ie + w_en)
        return w_ib, np.einsum("nji,nj->ni", C_nb, f_n)


@attrs.frozen
class Trajectory(TrajectoryArrays):
    """A reference trajectory: the arrays of :class:`~stochmod.nav.records.TrajectoryArrays`
    (time s, lat/lon deg, height m, vel_ned m/s, rph deg) and, for a profile trajectory, the
    analytic `motion` behind them (used by :func:`ideal_imu` and :meth:`at`)."""

    motion: _ProfileMotion | None = attrs.field(default=None, eq=False, repr=False)

    def at(self, t: ArrayLike) -> Trajectory:
        """The trajectory at other times (exact for a profile trajectory; linear interpolation
        of position/velocity and of the unwrapped angles otherwise)."""
        t = np.asarray(t, dtype=float).reshape(-1)
        if self.motion is not None:
            return _sample(self.motion, t)
        if t.size and (t.min() < self.time[0] or t.max() > self.time[-1]):
            raise InputError("requested times fall outside the trajectory")
        interp = lambda y: np.interp(t, self.time, y)  # noqa: E731
        rph = np.degrees(np.unwrap(np.radians(self.rph), axis=0))
        rph = np.stack([interp(rph[:, i]) for i in range(3)], -1)
        rph[:, 2] = (rph[:, 2] + 180.0) % 360.0 - 180.0
        return Trajectory(t, interp(self.lat), interp(self.lon), interp(self.height),
                          np.stack([interp(self.vel_ned[:, i]) for i in range(3)], -1), rph)


def _sample(motion: _ProfileMotion, t: np.ndarray) -> Trajectory:
    pos = motion.position(t)
    vel, _ = motion.velocity(t)
    x, _, _ = motion.kinematics(t)
    rph = np.degrees(x[:, [3, 2, 1]])
    rph[:, 2] = (rph[:, 2] + 180.0) % 360.0 - 180.0
    return Trajectory(t, np.degrees(pos[:, 0]), np.degrees(pos[:, 1]), pos[:, 2], vel, rph,
                      motion=motion)


def trajectory_from_profile(segments: Sequence[Segment], *, rate: float, lat: float, lon: float,
                            height: float = 0.0, heading: float = 0.0, speed: float = 0.0,
                            pitch: float = 0.0, roll: float = 0.0, t0: float = 0.0
                            ) -> Trajectory:
    """A smooth reference trajectory from a motion profile.

    Parameters
    ----------
    segments : sequence of Segment
        The profile, in order.
    rate : float
        Sampling rate of the returned trajectory, Hz.
    lat, lon : float
        Start position, deg.
    height : float
        Start ellipsoidal height, m.
    heading, speed, pitch, roll : float
        Initial heading (deg), speed (m/s), pitch and roll (deg).
    t0 : float
        Start time, s.
    """
    if not segments:
        raise InputError("a profile needs at least one segment")
    if not (rate > 0 and math.isfinite(rate)):
        raise InputError(f"rate must be a positive number of Hz, got {rate!r}")
    if not abs(lat) < 89.0:
        raise InputError(f"start latitude must be within (-89, 89) deg, got {lat!r}")
    cur = [float(speed), math.radians(heading), math.radians(pitch), math.radians(roll)]
    knots, values = [float(t0)], [list(cur)]
    for seg in segments:
        if not isinstance(seg, Segment):
            raise InputError(f"segments must be Segment objects, got {seg!r}")
        cur = [cur[0] if seg.speed is None else float(seg.speed),
               cur[1] + math.radians(seg.turn),
               cur[2] if seg.pitch is None else math.radians(seg.pitch),
               cur[3] if seg.roll is None else math.radians(seg.roll)]
        knots.append(knots[-1] + seg.duration)
        values.append(list(cur))
    motion = _ProfileMotion(float(t0), np.array(knots), np.array(values), math.radians(lat),
                            math.radians(lon), float(height))
    n = int(math.floor((knots[-1] - t0) * rate + 1e-9)) + 1
    return _sample(motion, t0 + np.arange(n) / rate)


_GL_X, _GL_W = np.polynomial.legendre.leggauss(5)


def ideal_imu(trajectory: Trajectory, kind: str = "rate") -> ImuData:
    """The error-free IMU of a profile trajectory at its time stamps.

    ``kind="rate"``: angular rate and specific force at each stamp. ``kind="increment"``: their
    integrals over the interval ending at each stamp (the first interval has the length of the
    second and lies before the start, where the motion is held at its initial values).
    """
    if kind not in IMU_KINDS:
        raise InputError(f"kind must be one of {IMU_KINDS}, got {kind!r}")
    motion = trajectory.motion
    if motion is None:
        raise InputError("ideal_imu needs an analytic trajectory: build it with "
                         "trajectory_from_profile")
    t = trajectory.time
    if kind == "rate":
        w, f = motion.sensors(t)
        return ImuData(t, w, f, kind)
    h = np.diff(t)
    h = np.concatenate([h[:1], h])
    a = t - h
    nodes = (a[:, None] + 0.5 * h[:, None] * (_GL_X[None, :] + 1.0)).reshape(-1)
    w, f = motion.sensors(nodes)
    wts = (0.5 * h[:, None] * _GL_W[None, :])[:, :, None]
    dth = (w.reshape(t.size, -1, 3) * wts).sum(axis=1)
    dv = (f.reshape(t.size, -1, 3) * wts).sum(axis=1)
    return ImuData(t, dth, dv, kind)


def add_sensor_errors(imu: ImuData, errors: Mapping[str, Model] | Mapping[str, ArrayLike],
                      rng: np.random.Generator | int | None = None) -> ImuData:
    """Add per-axis sensor errors to an IMU record.

    Parameters
    ----------
    imu : ImuData
        Error-free (or any) IMU samples.
    errors : mapping
        Keys among ``gyro_x ... accel_z`` (missing axes get no error). Values are either
        stochmod models bound to the IMU rate (drawn with ``model.simulate``, rad/s and m/s^2),
        or arrays of at least ``imu.n`` samples of a real static recording with its mean
        removed (the seeds' method; rates in rad/s and m/s^2).
    rng : Generator or int
        Random source for the models (each axis gets its own child generator).

    Notes
    -----
    The errors are rates; for increment data they are multiplied by each interval's length
    (an error constant over the interval).
    """
    unknown = set(errors) - set(AXES)
    if unknown:
        raise InputError(f"unknown sensor axes {sorted(unknown)}; expected names from {AXES}")
    gen = np.random.default_rng(rng)
    children = dict(zip(AXES, gen.spawn(len(AXES))))
    n = imu.n
    err = np.zeros((n, 6))
    for axis, src in errors.items():
        j = AXES.index(axis)
        if isinstance(src, Model):
            err[:, j] = src.simulate(n, children[axis])
        else:
            rec = np.asarray(src, dtype=float).reshape(-1)
            if rec.size < n or not np.all(np.isfinite(rec[:n])):
                raise InputError(f"static recording for {axis} needs {n} finite samples, "
                                 f"got {rec.size}")
            err[:, j] = rec[:n]
    if imu.kind == "increment":
        h = np.diff(imu.time)
        err *= np.concatenate([h[:1], h])[:, None]
    return ImuData(imu.time, imu.gyro + err[:, :3], imu.accel + err[:, 3:], imu.kind)


def gnss_measurements(trajectory: Trajectory, rate: float = 1.0, *, sigma_h: float | None = None,
                      cep: float | None = None, sigma_v: float = 3.0,
                      sigma_vel: float | None = 0.1, lever_arm: ArrayLike = (0.0, 0.0, 0.0),
                      rng: np.random.Generator | int | None = None,
                      outages: Sequence[tuple[float, float]] = ()) -> GnssData:
    """Noisy GNSS fixes of the antenna along a trajectory (Gonzalez eq. 6 and 8).

    Parameters
    ----------
    trajectory : Trajectory
    rate : float
        Fix rate, Hz (fixes at ``time[0] + k / rate``).
    sigma_h, cep : float
        Horizontal noise: 1-sigma per axis (m), or a CEP (m) converted by eq. 7. One of them.
    sigma_v : float
        Vertical 1-sigma, m.
    sigma_vel : float or None
        Velocity 1-sigma per axis, m/s (None: no velocity).
    lever_arm : array_like (3,)
        IMU to antenna in the body frame, m.
    rng : Generator or int
    outages : sequence of (start, duration)
        Seconds after ``time[0]`` during which no fix is produced.
    """
    if (sigma_h is None) == (cep is None):
        raise InputError("give exactly one of sigma_h and cep")
    sh = cep_to_sigma(cep) if cep is not None else float(sigma_h)
    if not (sh > 0 and sigma_v > 0 and (sigma_vel is None or sigma_vel > 0) and rate > 0):
        raise InputError("GNSS noise levels and rate must be positive")
    gen = np.random.default_rng(rng)
    t0 = trajectory.time[0]
    t = t0 + np.arange(int(math.floor((trajectory.time[-1] - t0) * rate + 1e-9)) + 1) / rate
    keep = np.ones(t.size, bool)
    for start, dur in outages:
        keep &= ~((t >= t0 + start) & (t < t0 + start + dur))
    t = t[keep]
    tr = trajectory.at(t)
    arm = np.asarray(lever_arm, dtype=float)
    C = frames.rph_to_dcm(tr.rph)
    ned_arm = C @ arm
    noise = gen.standard_normal((t.size, 3)) * np.array([sh, sh, sigma_v])
    lat_r = np.radians(tr.lat)
    scale = earth.ned_scale(lat_r, tr.height)
    d = (ned_arm + noise) / scale  # rad, rad, -m
    sd = np.tile([sh, sh, sigma_v], (t.size, 1))
    vel = sd_vel = None
    if sigma_vel is not None:
        # antenna velocity: v + C (w_nb^b x l), w_nb from the motion when available
        vel = tr.vel_ned.copy()
        if np.any(arm) and trajectory.motion is not None:
            w_ib, _ = trajectory.motion.sensors(t)
            w_in = earth.earth_rate_ned(lat_r) + earth.transport_rate_ned(lat_r, tr.height,
                                                                          tr.vel_ned)
            w_nb = w_ib - np.einsum("nji,nj->ni", C, w_in)
            vel += np.einsum("nij,nj->ni", C, np.cross(w_nb, arm))
        vel += gen.standard_normal((t.size, 3)) * sigma_vel
        sd_vel = np.full((t.size, 3), float(sigma_vel))
    return GnssData(t, tr.lat + np.degrees(d[:, 0]), tr.lon + np.degrees(d[:, 1]),
                    tr.height + d[:, 2], vel, sd, sd_vel)


def magnetometer_heading(trajectory: Trajectory, sigma: float, *, rate: float = 1.0,
                         rng: np.random.Generator | int | None = None
                         ) -> tuple[np.ndarray, np.ndarray]:
    """Magnetic heading measurements (deg, declination removed) with 1-sigma `sigma` deg.

    Returns ``(time, heading)``. Gonzalez eq. 19 computes it from the magnetometers; here it is
    the true heading plus white noise of the manufacturer's accuracy ``sigma_psi_m``.
    """
    if not sigma > 0 or not rate > 0:
        raise InputError("sigma and rate must be positive")
    gen = np.random.default_rng(rng)
    t0 = trajectory.time[0]
    t = t0 + np.arange(int(math.floor((trajectory.time[-1] - t0) * rate + 1e-9)) + 1) / rate
    hdg = trajectory.at(t).rph[:, 2] + gen.standard_normal(t.size) * sigma
    return t, (hdg + 180.0) % 360.0 - 180.0
