"""Predicted horizontal drift over a GNSS outage, from a calibration, with its band from the
parameters' uncertainty.

The seeds judge an error model by the navigation error in coasting mode *and* by the accuracy
the EKF predicts for it there (Stebler et al. 2014, Section VI, step 4, and Fig. 9: the 3-sigma
bounds from the diagonal of ``P_k``). This module gives that prediction before any drive, from a
calibration alone:

1. **Propagation** (:func:`predicted_drift`). A reference trajectory for the stated motion
   (``"static"``; ``"straight"``: constant velocity on a straight line; ``"drive"``: the outage
   study's 10-minute car drive; or any profile of :class:`~stochmod.nav.emulate.Segment`), its
   exact IMU (:func:`~stochmod.nav.emulate.ideal_imu`) and error-free GNSS fixes that state the
   receiver's sigmas (horizontal from a CEP by Gonzalez et al. 2015, eq. 7). The
   :class:`~stochmod.nav.filter.LooselyCoupledFilter` with the calibration's models runs over
   it from a stated initial covariance at the truth, takes the fixes for ``settle`` seconds
   (none in the stated earlier outages, ``earlier_outages``: the schedule of fixes an outage
   study's filter sees before its later outages) and none for the ``outage`` seconds after the
   last one. Its covariance is the only output used:
   ``P <- Phi P Phi' + Q`` between fixes and the update at each (Gonzalez Alg. 1, lines 4-8, in
   Joseph form), with the sensor-error states that :func:`stochmod.augment_axes` builds from the models
   (Quinchia et al. 2013, Section 7) -- the filter's own code, not a copy. With exact fixes
   every innovation is zero, so the filter stays on the reference trajectory and ``F`` is taken
   along it. The predicted 1-sigma horizontal drift at time ``t`` of the outage is
   ``sqrt(P_NN(t) + P_EE(t))`` (m), the root of the expected squared horizontal error.
2. **Start of the outage.** The covariance at the outage's start is the filter's after
   ``settle`` s of fixes, less those of the earlier outages, from the stated initial
   covariance (default: the outage study's, 1 m, 0.1 m/s, 0.5/0.5/2 deg), i.e. the covariance
   a filter of these models actually has when GNSS is lost. It is not an algebraic steady
   state: with static or straight motion, heading, the vertical gyro's bias and the split
   between tilt and accelerometer bias are not observable and their variances keep changing
   with the settle time. What the drift needs
   converges fast; :attr:`DriftPrediction.settle_change` reports the change of the end sigma
   when the settle time is doubled (static and straight motion).
3. **Band** (:func:`draw_models`). Each axis's parameters are drawn from the calibration's
   intervals (``details["parameters"]``): a parameter of value ``v`` and standard error ``se``
   is drawn on its domain's unconstrained scale ``t = g(v)`` as ``t + z se / g'^-1(t)``, ``z ~
   N(0, 1)``; for a positive parameter ``g = log`` and the draw is the log-normal ``v exp(z se
   / v)``, whose ``1 - alpha`` interval is the calibration's ``v exp(-+ z_alpha se / v)`` (the
   delta method on the log scale applied to the GMWM's asymptotic normality, Stebler eq. 21-22).
   Every draw is propagated as in 1, and the band is the percentiles of the drawn sigma. The
   calibration keeps marginal intervals only, so parameters are drawn independently; where the
   fit's estimates are correlated (a Gauss-Markov process's correlation time and variance) the
   band is wider than the joint uncertainty would make it.
4. **Check** (:func:`check_drift`). Emulated drives along the same trajectory at the models'
   rate, with sensor errors drawn from the calibration's models
   (:func:`~stochmod.nav.emulate.add_sensor_errors`), noisy fixes of the stated sigmas
   (Gonzalez eq. 6, 8) and an initial state drawn from the stated covariance, through the same
   filter: the horizontal errors at the outage's end. Their RMS should be the nominal sigma,
   inside the band, and for a zero-mean Gaussian N/E error of variances ``(s_N^2, s_E^2)`` the
   error's distribution is :func:`horizontal_error_cdf` (the Rayleigh distribution when ``s_N =
   s_E``, whose median, the CEP, is ``1.1774 s``: the relation behind Gonzalez eq. 7).
"""

from __future__ import annotations

import concurrent.futures
import math
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path

import attrs
import numpy as np
from numpy.typing import ArrayLike
from scipy.stats import chi2, kstest

from stochmod.core.checks import check_positive_int
from stochmod.core.errors import EstimationError, InputError, SpecError, StochmodError
from stochmod.core.jsonable import to_jsonable
from stochmod.core.model import Model
from stochmod.core.params import get_domain
from stochmod.core.tables import format_table
from stochmod.core.units import SENSORS
from stochmod.io.calibration import AxisCalibration, Calibration
from stochmod.nav import earth
from stochmod.nav.alignment import InitialState
from stochmod.nav.emulate import (
    AXES,
    Segment,
    Trajectory,
    add_sensor_errors,
    cep_to_sigma,
    gnss_measurements,
    ideal_imu,
    trajectory_from_profile,
)
from stochmod.nav.filter import LooselyCoupledFilter
from stochmod.nav.records import GnssData, ImuData
from stochmod.nav.study import DEFAULT_PROFILE, horizontal_error, truth_over_record

__all__ = [
    "MOTIONS",
    "DriftCheck",
    "DriftConditions",
    "DriftPrediction",
    "ParameterSpread",
    "calibration_axes",
    "check_drift",
    "draw_models",
    "horizontal_error_cdf",
    "parameter_spreads",
    "predicted_drift",
]

#: Named motions of :func:`predicted_drift` (a sequence of Segment is a motion too).
MOTIONS = ("static", "straight", "drive")

#: Initial 1-sigma stated to the filter (position m, velocity m/s, roll/pitch/heading deg):
#: the outage study's.
INIT_SD = (1.0, 0.1, (0.5, 0.5, 2.0))


@attrs.frozen
class ParameterSpread:
    """How one parameter of one axis is drawn for the band (module notes, step 3).

    Attributes
    ----------
    axis : str
        ``gyro_x ... accel_z``.
    name : str
        Parameter (``label.param``, as ``Model.param_names``).
    value : float
        The calibration's value.
    std_error : float
        Its standard error (nan when the calibration gives none).
    low, high : float
        The calibration's interval.
    scale_sd : float
        1-sigma of the draw on the domain's unconstrained scale (for a positive parameter the
        log-scale sigma ``se / value``); 0 when the parameter is held at its value.
    held : str
        Why the parameter is held at its value ("" when it is drawn).
    """

    axis: str
    name: str
    value: float
    std_error: float
    low: float
    high: float
    scale_sd: float
    held: str = ""

    @property
    def factor(self) -> float:
        """``exp(scale_sd)``: the 1-sigma multiplicative spread of a positive parameter."""
        return math.exp(self.scale_sd)


def calibration_axes(calibration: Calibration | str | Path) -> Calibration:
    """The calibration (read from a path when one is given), checked to hold an SI model for
    each of ``gyro_x ... accel_z`` (column names case-insensitive)."""
    if not isinstance(calibration, Calibration):
        calibration = Calibration.read(calibration)
    keys = [a.column.strip().lower() for a in calibration.axes]
    for axis in AXES:
        if keys.count(axis) != 1:
            raise InputError(f"{calibration.source or 'calibration'}: needs exactly one column "
                             f"{axis!r} (case-insensitive) for the navigation filter; its columns "
                             f"are {list(calibration.columns)}")
        unit = calibration.axes[keys.index(axis)].unit
        if unit not in (None, SENSORS[axis.split("_")[0]]):
            raise InputError(f"the model of {axis} is in {unit}: the filter needs SI models")
    return calibration


def _axis(calibration: Calibration, axis: str) -> AxisCalibration:
    keys = [a.column.strip().lower() for a in calibration.axes]
    return calibration.axes[keys.index(axis)]


def _models(calibration: Calibration) -> dict[str, Model]:
    return {a: _axis(calibration, a).model for a in AXES}


def parameter_spreads(calibration: Calibration | str | Path) -> tuple[ParameterSpread, ...]:
    """Per axis and parameter of the final models, how the band draws it.

    A parameter is drawn when the calibration gives it a finite positive standard error, its
    value matches the model's and its domain maps elementwise to an unconstrained scale; it is
    held at its value otherwise (not identified, a vector domain such as AR coefficients).
    """
    cal = calibration_axes(calibration)
    out = []
    for axis in AXES:
        ax = _axis(cal, axis)
        model = ax.model
        names = model.param_names
        vec = model.vector()
        domains = [spec.domain for p in model.processes for spec in p.parameters()
                   for _ in range(spec.size)]
        given = {e.get("name"): e for e in ax.details.get("parameters") or ()
                 if isinstance(e, Mapping)}
        for i, name in enumerate(names):
            e = given.get(name, {})
            se = _number(e.get("std_error"))
            low, high = _number(e.get("low")), _number(e.get("high"))
            dom = get_domain(domains[i])
            held, sd = "", 0.0
            if not e:
                held = "no interval in the calibration"
            elif not math.isclose(_number(e.get("value")), float(vec[i]), rel_tol=1e-9):
                held = "the interval belongs to another model"
            elif not (math.isfinite(se) and se > 0):
                held = "no finite standard error (not identified)"
            elif dom.vector or dom.elementwise_derivative is None:
                held = f"vector domain {dom.name!r}"
            else:
                t = np.atleast_1d(dom.to_unconstrained(np.array([vec[i]])))
                deriv = float(np.atleast_1d(dom.elementwise_derivative(t))[0])
                sd = se / abs(deriv) if deriv else math.inf
                if not math.isfinite(sd):
                    held, sd = "the unconstrained scale is degenerate at the value", 0.0
            out.append(ParameterSpread(axis, name, float(vec[i]), se, low, high, sd, held))
    return tuple(out)


def _number(v: object) -> float:
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else math.nan


def draw_models(calibration: Calibration | str | Path, n: int,
                rng: np.random.Generator | int | None = None) -> list[dict[str, Model]]:
    """`n` sets of per-axis models with parameters drawn from the calibration's intervals.

    Each drawn parameter (:func:`parameter_spreads`) independently, on its domain's
    unconstrained scale with the delta-method sigma (log-normal for a positive parameter: the
    distribution whose interval is the calibration's, module notes step 3); the others held.

    Returns
    -------
    list of dict of str to Model
        Keys ``gyro_x ... accel_z``, models bound to the calibration's rate.
    """
    cal = calibration_axes(calibration)
    n = check_positive_int(n, name="n")
    gen = np.random.default_rng(rng)
    spreads = parameter_spreads(cal)
    base = _models(cal)
    out = []
    for _ in range(n):
        draw = {}
        for axis in AXES:
            model = base[axis]
            vec = model.vector().copy()
            domains = [spec.domain for p in model.processes for spec in p.parameters()
                       for _ in range(spec.size)]
            for i, s in enumerate(x for x in spreads if x.axis == axis):
                if s.scale_sd > 0:
                    dom = get_domain(domains[i])
                    t = np.atleast_1d(dom.to_unconstrained(np.array([s.value])))
                    vec[i] = float(np.atleast_1d(dom.from_unconstrained(
                        t + s.scale_sd * gen.standard_normal()))[0])
            draw[axis] = model.with_vector(vec)
        out.append(draw)
    return out


@attrs.frozen
class DriftConditions:
    """What a prediction is made for (the same conditions serve :func:`check_drift`).

    Attributes
    ----------
    motion : str
        ``"static"``, ``"straight"``, ``"drive"`` or ``"profile"``.
    profile : tuple of Segment
        The motion profile (:func:`~stochmod.nav.emulate.trajectory_from_profile`).
    outage : float
        Seconds without fixes after the last fix (the coasting time), s.
    settle : float
        Seconds of fixes from the start to the last fix before the outage, s.
    start : (lat deg, lon deg, height m)
    heading, speed : float
        Initial heading (deg) and speed (m/s).
    gnss_rate : float
        Fix rate, Hz.
    sigma_h, sigma_v : float
        Horizontal 1-sigma per axis and vertical 1-sigma of the fixes, m.
    sigma_vel : float or None
        Velocity 1-sigma per axis, m/s (None: position fixes only).
    init_sd : (position m, velocity m/s, (roll, pitch, heading) deg)
        Initial 1-sigma stated to the filter at the start.
    dt_filter : float
        The filter's covariance step, s.
    record : float or None
        The calibration's record length, s, for the filter's rule on components correlated
        beyond it (None: models taken as they are).
    filter_options : dict
        Further keywords of :class:`~stochmod.nav.filter.LooselyCoupledFilter`.
    earlier_outages : tuple of (start, duration)
        Gaps in the fixes before the last one, s from the start of the trajectory: the fixes
        at ``start <= t < start + duration`` are withheld (the filter's ``outages``).
    """

    motion: str
    profile: tuple
    outage: float
    settle: float
    start: tuple
    heading: float
    speed: float
    gnss_rate: float
    sigma_h: float
    sigma_v: float
    sigma_vel: float | None
    init_sd: tuple
    dt_filter: float
    record: float | None
    filter_options: dict = attrs.field(factory=dict, converter=dict)
    earlier_outages: tuple = attrs.field(
        default=(), converter=lambda v: tuple((float(a), float(b)) for a, b in v))

    @property
    def end(self) -> float:
        """End of the outage, s from the start of the trajectory."""
        return self.settle + self.outage

    def trajectory(self, rate: float) -> Trajectory:
        """The reference trajectory sampled at `rate` Hz."""
        return trajectory_from_profile(list(self.profile), rate=rate, lat=self.start[0],
                                       lon=self.start[1], height=self.start[2],
                                       heading=self.heading, speed=self.speed)

    def initial_state(self, traj: Trajectory, rng: np.random.Generator | None = None
                      ) -> InitialState:
        """The start of `traj`, perturbed by a draw from :attr:`init_sd` when `rng` is given."""
        first = traj.at(traj.time[:1])
        pos_sd, vel_sd, att_sd = self.init_sd
        lat_r = math.radians(float(first.lat[0]))
        r_n, r_e = earth.principal_radii(lat_r)
        h0 = float(first.height[0])
        d = np.zeros(9) if rng is None else rng.standard_normal(9)
        dpos, dvel = d[:3] * pos_sd, d[3:6] * vel_sd
        datt = d[6:] * np.asarray(att_sd, dtype=float)
        return InitialState(
            float(first.lat[0]) + math.degrees(dpos[0] / (float(r_n) + h0)),
            float(first.lon[0]) + math.degrees(dpos[1] / ((float(r_e) + h0) * math.cos(lat_r))),
            h0 - dpos[2], first.vel_ned[0] + dvel, first.rph[0] + datt,
            time=float(traj.time[0]), sd_position=pos_sd, sd_velocity=vel_sd,
            sd_attitude=tuple(np.broadcast_to(np.asarray(att_sd, float), (3,)).tolist()))

    def exact_fixes(self, traj: Trajectory) -> GnssData:
        """Error-free fixes at :attr:`gnss_rate` up to the outage's end, with the stated
        sigmas."""
        t0 = float(traj.time[0])
        t = t0 + np.arange(math.floor(self.end * self.gnss_rate + 1e-9) + 1) / self.gnss_rate
        tr = traj.at(t)
        sd = np.tile([self.sigma_h, self.sigma_h, self.sigma_v], (t.size, 1))
        vel = sd_vel = None
        if self.sigma_vel is not None:
            vel, sd_vel = tr.vel_ned, np.full((t.size, 3), float(self.sigma_vel))
        return GnssData(t, tr.lat, tr.lon, tr.height, vel, sd, sd_vel)

    def noisy_fixes(self, traj: Trajectory, rng: np.random.Generator) -> GnssData:
        """Fixes with noise of the stated sigmas (Gonzalez eq. 6, 8)."""
        return gnss_measurements(traj, self.gnss_rate, sigma_h=self.sigma_h,
                                 sigma_v=self.sigma_v, sigma_vel=self.sigma_vel, rng=rng)

    @property
    def outages(self) -> list[tuple[float, float]]:
        """The filter's outage windows (start, duration), s: the earlier outages and no fix
        after the one at :attr:`settle`."""
        return [*self.earlier_outages,
                (self.settle + 0.5 / self.gnss_rate, self.outage + 1.0 / self.gnss_rate)]

    def make_filter(self, models: Mapping[str, Model]) -> LooselyCoupledFilter:
        """The filter of `models` (``gyro_x ... accel_z``) with these settings."""
        return LooselyCoupledFilter({a[-1]: models[a] for a in AXES[:3]},
                                    {a[-1]: models[a] for a in AXES[3:]},
                                    dt_filter=self.dt_filter, record=self.record,
                                    **self.filter_options)

    def describe(self) -> str:
        """One paragraph for reports."""
        what = {"static": "at rest", "straight": f"straight at {self.speed:g} m/s",
                "drive": "the outage study's car drive",
                "profile": "a given motion profile"}[self.motion]
        pos, vel, att = self.init_sd
        gnss = (f"{self.gnss_rate:g} Hz fixes of 1-sigma {self.sigma_h:.3g} m horizontal, "
                f"{self.sigma_v:.3g} m vertical"
                + ("" if self.sigma_vel is None else f", {self.sigma_vel:.3g} m/s velocity"))
        gaps = "".join(f", none from {s:g} to {s + d:g} s" for s, d in self.earlier_outages)
        return (f"motion: {what}; {gnss} for {self.settle:g} s from an initial 1-sigma of "
                f"{pos:g} m, {vel:g} m/s, {tuple(np.broadcast_to(att, (3,)).tolist())} deg"
                f"{gaps}, then {self.outage:g} s without; filter step {self.dt_filter:g} s"
                + ("" if self.record is None else f"; record {self.record:g} s"))


def _conditions(calibration: Calibration, outage: float, motion: str | Sequence[Segment],
                settle: float, speed: float | None, heading: float, start: Sequence[float],
                cep: float, sigma_v: float, sigma_vel: float | None, gnss_rate: float,
                init_sd: Sequence, dt_filter: float, record: float | str | None,
                filter_options: Mapping | None, earlier_outages: Sequence = ()
                ) -> DriftConditions:
    for name, v in (("outage", outage), ("settle", settle), ("dt_filter", dt_filter),
                    ("gnss_rate", gnss_rate), ("cep", cep), ("sigma_v", sigma_v)):
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise InputError(f"{name} must be a positive number, got {v!r}")
    if sigma_vel is not None and not (math.isfinite(sigma_vel) and sigma_vel > 0):
        raise InputError(f"sigma_vel must be positive or None, got {sigma_vel!r}")
    total = settle + outage
    if isinstance(motion, str):
        if motion not in MOTIONS:
            raise InputError(f"motion must be one of {MOTIONS} or a sequence of Segment, got "
                             f"{motion!r}")
        if motion == "static":
            profile, v0 = (Segment(total, speed=0.0),), 0.0
        elif motion == "straight":
            v0 = 15.0 if speed is None else float(speed)
            if not (math.isfinite(v0) and v0 > 0):
                raise InputError(f"a straight motion needs a positive speed, got {speed!r}")
            profile = (Segment(total),)
        else:
            profile, v0 = tuple(DEFAULT_PROFILE), 5.0 if speed is None else float(speed)
        name = motion
    else:
        profile = tuple(motion)
        if not profile or not all(isinstance(s, Segment) for s in profile):
            raise InputError("a motion profile is a non-empty sequence of Segment")
        v0, name = (0.0 if speed is None else float(speed)), "profile"
    length = sum(s.duration for s in profile)
    if length < total - 1e-9:
        raise InputError(f"the motion lasts {length:g} s, shorter than settle + outage = "
                         f"{total:g} s")
    if record == "calibration":
        record = calibration.record_seconds if calibration.n > 0 else None
    elif record is not None and not (math.isfinite(record) and record > 0):
        raise InputError(f"record must be a positive number of s, 'calibration' or None, got "
                         f"{record!r}")
    pos, vel, att = init_sd
    att = tuple(np.broadcast_to(np.asarray(att, dtype=float), (3,)).tolist())
    if not all(math.isfinite(x) and x > 0 for x in (pos, vel, *att)):
        raise InputError(f"init_sd must be positive (position, velocity, attitude), got "
                         f"{init_sd!r}")
    gaps = []
    for o in earlier_outages:
        try:
            s, d = (float(x) for x in o)
        except (TypeError, ValueError):
            raise InputError(f"an earlier outage is (start, duration) in s, got {o!r}") from None
        if not (math.isfinite(s) and math.isfinite(d) and s >= 0 and d > 0
                and s + d <= settle + 1e-9):
            raise InputError(f"earlier outage {o!r} must be (start >= 0, duration > 0) s and "
                             f"end by the last fix at settle = {settle:g} s")
        gaps.append((s, d))
    lat, lon, hgt = (float(x) for x in start)
    return DriftConditions(name, profile, float(outage), float(settle), (lat, lon, hgt),
                           float(heading), v0, float(gnss_rate), cep_to_sigma(cep),
                           float(sigma_v), None if sigma_vel is None else float(sigma_vel),
                           (float(pos), float(vel), att), float(dt_filter),
                           None if record is None else float(record), dict(filter_options or {}),
                           tuple(gaps))


def _cut(imu: ImuData, t_end: float) -> ImuData:
    k = imu.time <= t_end + 1e-9
    return ImuData(imu.time[k], imu.gyro[k], imu.accel[k], imu.kind)


@attrs.frozen
class _Propagation:
    """One covariance-only run of the filter along the reference (picklable for workers)."""

    cond: DriftConditions
    imu: ImuData
    gnss: GnssData
    init: InitialState

    def __call__(self, models: Mapping[str, Model]) -> tuple[np.ndarray, np.ndarray, tuple]:
        """Times since the outage start (s), horizontal sigma (m) and N/E sigmas at those
        times, and the filter's random-walk substitutions; NaN sigmas when the filter fails."""
        flt = self.cond.make_filter(models)
        t0 = float(self.imu.time[0])
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)
                res = flt.run(self.imu.time, self.imu.gyro, self.imu.accel, kind=self.imu.kind,
                              gnss=self.gnss, init=self.init, outages=self.cond.outages)
        except (EstimationError, SpecError, InputError):
            return np.array([np.nan]), np.full((1, 2), np.nan), ()
        k = res.epoch_time >= t0 + self.cond.settle - 1e-9
        ne = res.epoch_sd[k, :2]
        return res.epoch_time[k] - t0 - self.cond.settle, ne, res.random_walks


def _map(fn: object, items: Sequence, workers: int) -> list:
    if workers == 1 or len(items) < 2:
        return [fn(x) for x in items]
    with concurrent.futures.ProcessPoolExecutor(max_workers=min(workers, len(items))) as pool:
        return list(pool.map(fn, items))


def horizontal_error_cdf(r: ArrayLike, sigma_ne: ArrayLike) -> np.ndarray:
    """``P(|e| <= r)`` for a horizontal error ``e ~ N(0, diag(s_N^2, s_E^2))``.

    In polar coordinates the probability is ``1/(2 pi s_N s_E) int_0^{2 pi} (1 - exp(-r^2
    q(th) / 2)) / q(th) d th`` with ``q = cos^2 th / s_N^2 + sin^2 th / s_E^2``, integrated by
    the trapezoid rule on 256 angles (spectrally accurate for the periodic integrand). With
    ``s_N = s_E = s`` it is the Rayleigh ``1 - exp(-r^2 / (2 s^2))``.

    Parameters
    ----------
    r : array_like
        Radii, m.
    sigma_ne : array_like (2,)
        North and east 1-sigma, m.
    """
    s_n, s_e = (float(x) for x in np.asarray(sigma_ne, dtype=float).reshape(2))
    if not (s_n > 0 and s_e > 0):
        raise InputError(f"sigma_ne must be two positive sigmas, got {sigma_ne!r}")
    r = np.asarray(r, dtype=float)
    th = np.linspace(0.0, 2.0 * np.pi, 256, endpoint=False)
    q = np.cos(th) ** 2 / s_n**2 + np.sin(th) ** 2 / s_e**2
    x = np.clip(r, 0.0, None)[..., None] ** 2
    return (-np.expm1(-0.5 * x * q) / q).mean(axis=-1) / (s_n * s_e)


@attrs.frozen
class DriftPrediction:
    """Result of :func:`predicted_drift`.

    Attributes
    ----------
    conditions : DriftConditions
    time : ndarray (k,)
        Filter epochs from the last fix (0) to the outage's end, s.
    sigma : ndarray (k,)
        Nominal predicted 1-sigma horizontal drift ``sqrt(P_NN + P_EE)`` (m), the
        calibration's models.
    sigma_ne : ndarray (k, 2)
        Its north and east 1-sigma, m.
    draws : ndarray (n_draws, k)
        The same for each parameter draw (NaN rows: the filter failed on that draw).
    spreads : tuple of ParameterSpread
        How each parameter was drawn.
    settle_change : float or None
        Relative change of the end sigma with the settle time doubled (static and straight
        motion; None otherwise).
    random_walks : tuple of str
        The nominal filter's substitutions of components correlated beyond the record.
    seed : object
        The seed the draws came from (for the report).
    """

    conditions: DriftConditions
    time: np.ndarray = attrs.field(eq=False)
    sigma: np.ndarray = attrs.field(eq=False)
    sigma_ne: np.ndarray = attrs.field(eq=False)
    draws: np.ndarray = attrs.field(eq=False)
    spreads: tuple = ()
    settle_change: float | None = None
    random_walks: tuple = ()
    seed: object = None

    @property
    def end_sigma(self) -> float:
        """Nominal predicted 1-sigma horizontal drift at the outage's end, m."""
        return float(self.sigma[-1])

    @property
    def start_sigma(self) -> float:
        """Nominal horizontal 1-sigma at the last fix before the outage, m."""
        return float(self.sigma[0])

    @property
    def n_failed(self) -> int:
        """Draws on which the filter failed (left out of the percentiles)."""
        return int(np.sum(~np.isfinite(self.draws[:, -1]))) if self.draws.size else 0

    def percentile(self, q: float | Sequence[float]) -> np.ndarray:
        """Percentile(s) `q` (0-100) of the drawn sigma at every epoch, m: shape (k,) or
        (len(q), k)."""
        ok = np.isfinite(self.draws[:, -1])
        if not ok.any():
            raise EstimationError("no parameter draw gave a prediction")
        return np.percentile(self.draws[ok], q, axis=0)

    def band(self, low: float = 5.0, high: float = 95.0) -> tuple[float, float]:
        """The `low`-`high` percentile band of the drawn sigma at the outage's end, m."""
        lo, hi = self.percentile([low, high])[:, -1]
        return float(lo), float(hi)

    def cdf(self, r: ArrayLike) -> np.ndarray:
        """Distribution of the horizontal error at the outage's end under the nominal model
        (:func:`horizontal_error_cdf`)."""
        return horizontal_error_cdf(r, self.sigma_ne[-1])

    def at(self, t: float) -> tuple[float, float, float, float]:
        """``(nominal, 5th, 50th, 95th percentile)`` sigma (m) at `t` s into the outage
        (the epoch at or just before `t`)."""
        i = int(np.searchsorted(self.time, t + 1e-9) - 1)
        if i < 0:
            raise InputError(f"t = {t!r} s is before the outage")
        if self.n_failed == self.draws.shape[0]:  # no band
            return float(self.sigma[i]), math.nan, math.nan, math.nan
        p = self.percentile([5, 50, 95])[:, i]
        return float(self.sigma[i]), float(p[0]), float(p[1]), float(p[2])

    def summary(self, times: Sequence[float] | None = None) -> str:
        """Table of the nominal sigma and the band over the outage, the conditions, the
        drawn parameters and the settle check."""
        c = self.conditions
        if times is None:
            times = sorted({0.0, *(c.outage * f for f in (0.25, 0.5, 0.75)), c.outage})
        rows = [[f"{t:g}", *self.at(t)] for t in times]
        n = self.draws.shape[0]
        lines = [format_table(
            ["t in outage [s]", "nominal sigma [m]", "5%", "median", "95%"], rows, digits=4,
            title=f"Predicted 1-sigma horizontal drift sqrt(P_NN + P_EE) over a {c.outage:g} s "
                  f"GNSS outage; band: {n - self.n_failed} parameter draw(s)"
                  + (f" ({self.n_failed} failed)" if self.n_failed else "")
                  + (f", seed {self.seed}" if self.seed is not None else ""))]
        lines.append(c.describe())
        s_n, s_e = self.sigma_ne[-1]
        lines.append(f"at the end: north {s_n:.4g} m, east {s_e:.4g} m; a CEP of "
                     f"{_cep(self.sigma_ne[-1]):.4g} m")
        if self.settle_change is not None:
            lines.append(f"settle check: the end sigma changes by {self.settle_change:+.2%} with "
                         f"{2 * c.settle:g} s of fixes instead of {c.settle:g} s")
        lines += list(self.random_walks)
        drawn = [s for s in self.spreads if s.scale_sd > 0]
        rows = [[s.axis, s.name, s.value, s.low, s.high, s.scale_sd] for s in drawn]
        if rows:
            lines.append(format_table(["axis", "parameter", "value", "low", "high",
                                       "sd (log scale)"], rows, digits=4,
                                      title="Parameters drawn, independently (the "
                                            "calibration's marginal intervals)"))
        held = [f"{s.axis} {s.name}: {s.held}" for s in self.spreads if s.held]
        if held:
            lines.append("held at their values: " + "; ".join(held))
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """JSON-ready form (strict JSON: non-finite values converted)."""
        ok = np.isfinite(self.draws[:, -1]) if self.draws.size else np.zeros(0, bool)
        band = {} if not ok.any() else {
            f"p{q}": self.percentile(q).tolist() for q in (5, 50, 95)}
        return to_jsonable({"conditions": {**attrs.asdict(self.conditions),
                               "profile": [attrs.asdict(s) for s in self.conditions.profile]},
                "time": self.time.tolist(), "sigma": self.sigma.tolist(),
                "sigma_ne": self.sigma_ne.tolist(), "band": band,
                "n_draws": int(self.draws.shape[0]), "n_failed": self.n_failed,
                "settle_change": self.settle_change, "random_walks": list(self.random_walks),
                "spreads": [attrs.asdict(s) for s in self.spreads]})

    def plot(self, ax: object = None) -> object:
        """Nominal sigma and the 5-95 % band against the time in the outage (matplotlib)."""
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots(figsize=(6, 4))
        lo, med, hi = self.percentile([5, 50, 95])
        ax.fill_between(self.time, lo, hi, alpha=0.3, label="5-95 % of the draws")
        ax.plot(self.time, med, "--", label="median of the draws")
        ax.plot(self.time, self.sigma, "k", label="calibrated model")
        ax.set_xlabel("time since the last fix [s]")
        ax.set_ylabel("predicted 1-sigma horizontal error [m]")
        ax.legend()
        return ax


def _cep(sigma_ne: np.ndarray) -> float:
    """Median of the horizontal error (bisection on :func:`horizontal_error_cdf`)."""
    lo, hi = 0.0, 4.0 * float(np.hypot(*sigma_ne))
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if horizontal_error_cdf(mid, sigma_ne) < 0.5 else (lo, mid)
    return 0.5 * (lo + hi)


def predicted_drift(calibration: Calibration | str | Path, outage: float = 60.0,
                    motion: str | Sequence[Segment] = "static", *, n_draws: int = 100,
                    rng: np.random.Generator | int | None = None, settle: float = 300.0,
                    speed: float | None = None, heading: float = 30.0,
                    start: Sequence[float] = (46.5, 6.6, 400.0), cep: float = 2.0,
                    sigma_v: float = 3.0, sigma_vel: float | None = 0.1,
                    gnss_rate: float = 1.0, init_sd: Sequence = INIT_SD,
                    dt_filter: float = 1.0, record: float | str | None = "calibration",
                    imu_rate: float | None = None, filter_options: Mapping | None = None,
                    workers: int = 1, settle_check: bool = True,
                    earlier_outages: Sequence[tuple[float, float]] = ()) -> DriftPrediction:
    """Predicted 1-sigma horizontal drift over a GNSS outage, with its band from the
    calibration's parameter uncertainty (module notes).

    Parameters
    ----------
    calibration : Calibration or path
        With models for ``gyro_x ... accel_z`` (SI).
    outage : float
        Coasting time after the last fix, s.
    motion : {"static", "straight", "drive"} or sequence of Segment
        ``"straight"``: constant `speed` (default 15 m/s) on a straight line; ``"drive"``: the
        outage study's 10-minute car drive (``stochmod.nav.study.DEFAULT_PROFILE``; with the
        default settle its outage is the study's second); a profile: its first ``settle +
        outage`` seconds.
    n_draws : int
        Parameter draws for the band (0: none).
    rng : Generator or int, optional
        Source of the draws.
    settle : float
        Seconds of fixes before the outage (from the stated initial covariance), s.
    speed, heading : float
        Initial speed (m/s; the motion's default when None) and heading (deg).
    start : (lat deg, lon deg, height m)
    cep, sigma_v, sigma_vel : float
        GNSS horizontal CEP (m, Gonzalez eq. 7), vertical 1-sigma (m), velocity 1-sigma (m/s;
        None: position only), as the outage study states them.
    gnss_rate : float
        Fix rate, Hz.
    init_sd : (position m, velocity m/s, attitude deg or (roll, pitch, heading) deg)
        Initial 1-sigma stated to the filter at the start (default the outage study's).
    dt_filter : float
        The filter's covariance step, s (1.0: once per fix interval).
    record : float, "calibration" or None
        Record length (s) for the filter's rule on components correlated beyond it; default the
        calibration's, as ``stochmod outages`` does.
    imu_rate : float, optional
        Rate of the reference IMU, Hz (default the calibration's rate, the filter exactly as it
        runs on the sensor; a lower rate is faster and gives the same covariance for models
        with a continuous form whose sub-sample components stay so).
    filter_options : mapping, optional
        Further keywords of :class:`~stochmod.nav.filter.LooselyCoupledFilter` (e.g.
        ``gyro_bias_sd``, ``error_model``).
    workers : int
        Processes the draws are spread over (the result does not depend on it).
    settle_check : bool
        Also propagate the nominal models with the settle time doubled (static and straight
        motion) and report the change of the end sigma.
    earlier_outages : sequence of (start, duration)
        Gaps in the fixes before the outage, s from the start of the motion: the fixes at
        ``start <= t < start + duration`` are withheld, as the filter's ``outages`` withhold
        them (for outage ``k`` of an outage study, its outages ``0 .. k-1``); each ends by
        `settle`. Default none: fixes all through the `settle` seconds.

    Returns
    -------
    DriftPrediction
    """
    cal = calibration_axes(calibration)
    cond = _conditions(cal, outage, motion, settle, speed, heading, start, cep, sigma_v,
                       sigma_vel, gnss_rate, init_sd, dt_filter, record, filter_options,
                       earlier_outages)
    if not (isinstance(n_draws, (int, np.integer)) and n_draws >= 0):
        raise InputError(f"n_draws must be a whole number >= 0, got {n_draws!r}")
    workers = check_positive_int(workers, name="workers")
    rate = float(cal.freq) if imu_rate is None else float(imu_rate)
    if not (math.isfinite(rate) and rate > 0):
        raise InputError(f"imu_rate must be a positive number of Hz, got {imu_rate!r}")
    nominal = _models(cal)
    prop = _propagation(cond, rate)
    t, ne, walks = prop(nominal)
    if not np.all(np.isfinite(ne)):
        raise EstimationError("the filter failed on the calibration's own models along this "
                              "motion")
    change = None
    if settle_check and cond.motion in ("static", "straight"):
        longer = attrs.evolve(cond, settle=2 * cond.settle,
                              profile=(attrs.evolve(cond.profile[0],
                                                    duration=2 * cond.settle + cond.outage),))
        _, ne2, _ = _propagation(longer, rate)(nominal)
        change = float(np.hypot(*ne2[-1]) / np.hypot(*ne[-1]) - 1.0)
    draws = np.zeros((0, t.size))
    gen = np.random.default_rng(rng)
    if n_draws:
        sets = draw_models(cal, n_draws, gen)
        rows = []
        for tt, nn, _ in _map(prop, sets, workers):
            rows.append(np.hypot(nn[:, 0], nn[:, 1]) if tt.shape == t.shape
                        else np.full(t.size, np.nan))
        draws = np.array(rows)
    seed = rng if isinstance(rng, (int, np.integer)) else None
    return DriftPrediction(cond, t, np.hypot(ne[:, 0], ne[:, 1]), ne, draws,
                           parameter_spreads(cal), change, tuple(w.describe() for w in walks),
                           seed)


def _propagation(cond: DriftConditions, rate: float) -> _Propagation:
    traj = cond.trajectory(rate)
    imu = _cut(ideal_imu(traj, "increment"), float(traj.time[0]) + cond.end)
    return _Propagation(cond, imu, cond.exact_fixes(traj), cond.initial_state(traj))


@attrs.frozen
class DriftCheck:
    """Result of :func:`check_drift`: actual horizontal errors at the outage's end on emulated
    drives against the prediction.

    Attributes
    ----------
    prediction : DriftPrediction
    errors : ndarray (runs,)
        Horizontal error at the outage's end per run, m.
    filter_sigma : ndarray (runs,)
        The filter's own horizontal 1-sigma there per run, m.
    seed : int
    """

    prediction: DriftPrediction = attrs.field(eq=False)
    errors: np.ndarray = attrs.field(eq=False)
    filter_sigma: np.ndarray = attrs.field(eq=False)
    seed: int = 0

    @property
    def runs(self) -> int:
        """Number of emulated drives."""
        return int(self.errors.size)

    @property
    def rms(self) -> float:
        """RMS of the horizontal errors, m (the predicted sigma estimates it)."""
        return float(np.sqrt(np.mean(self.errors**2)))

    def rms_interval(self, level: float = 0.95) -> tuple[float, float]:
        """Two-sided `level` interval of the RMS of `runs` errors if the nominal prediction is
        right, m: ``sigma sqrt(chi2(2R) / 2R)`` (the Rayleigh case, squared error ``sigma^2
        chi2(2) / 2``)."""
        k = 2 * self.runs
        lo, hi = chi2.ppf([(1 - level) / 2, (1 + level) / 2], k)
        s = self.prediction.end_sigma
        return float(s * math.sqrt(lo / k)), float(s * math.sqrt(hi / k))

    @property
    def ks_pvalue(self) -> float:
        """Kolmogorov-Smirnov p-value of the errors against the predicted distribution
        (:meth:`DriftPrediction.cdf`)."""
        return float(kstest(self.errors, self.prediction.cdf).pvalue)

    @property
    def inside_band(self) -> bool:
        """Whether the RMS error lies in the 5-95 % band of the drawn sigma."""
        lo, hi = self.prediction.band()
        return lo <= self.rms <= hi

    def summary(self) -> str:
        """The comparison, in one table."""
        p = self.prediction
        lo, hi = p.band() if p.n_failed < p.draws.shape[0] else (math.nan, math.nan)
        a, b = self.rms_interval()
        rows = [["predicted sigma (calibrated model)", p.end_sigma],
                ["predicted band 5 %", lo], ["predicted band 95 %", hi],
                ["RMS actual error", self.rms],
                ["95 % interval of the RMS under the prediction", f"[{a:.4g}, {b:.4g}]"],
                ["median actual error", float(np.median(self.errors))],
                ["predicted median (CEP)", _cep(p.sigma_ne[-1])],
                ["mean filter sigma in the runs", float(np.mean(self.filter_sigma))],
                ["KS p-value vs the predicted distribution", self.ks_pvalue]]
        return format_table(["quantity", "value"], rows, digits=4,
                            title=f"Horizontal error at the end of a {p.conditions.outage:g} s "
                                  f"outage, {self.runs} emulated drive(s), seed {self.seed}")


@attrs.frozen
class _Drive:
    """One emulated drive (picklable for workers)."""

    cond: DriftConditions
    traj: Trajectory
    clean: ImuData
    truth: dict
    start_sd: np.ndarray
    models: dict
    seed: int

    def __call__(self, r: int) -> tuple[float, float]:
        rng = np.random.default_rng([self.seed, r])
        noisy = add_sensor_errors(self.clean, self.truth, rng)
        if self.start_sd.any():  # the walks' start over the record (truth_over_record)
            h = np.diff(self.clean.time)
            h = np.concatenate([h[:1], h])[:, None]
            b = rng.normal(0.0, self.start_sd)
            noisy = ImuData(noisy.time, noisy.gyro + b[:3] * h, noisy.accel + b[3:] * h,
                            noisy.kind)
        gnss = self.cond.noisy_fixes(self.traj, rng)
        init = self.cond.initial_state(self.traj, rng)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            res = self.cond.make_filter(self.models).run(
                noisy.time, noisy.gyro, noisy.accel, kind=noisy.kind, gnss=gnss, init=init,
                outages=self.cond.outages)
        err = horizontal_error(self.traj, res.time[-1:], res.lat[-1:], res.lon[-1:])[0]
        return float(err), float(np.hypot(*res.epoch_sd[-1, :2]))


def check_drift(calibration: Calibration | str | Path, prediction: DriftPrediction, *,
                runs: int = 100, seed: int = 0, workers: int = 1) -> DriftCheck:
    """Emulated drives under the prediction's conditions, with sensor errors drawn from the
    calibration's models (module notes, step 4).

    Each run ``r`` (stream ``(seed, r)``): the reference at the models' rate, its exact IMU
    plus errors from the calibration's models (a component correlated beyond the record drawn
    as the random walk it is over it, :func:`~stochmod.nav.study.truth_over_record`, as
    ``stochmod outages`` does), noisy fixes of the stated sigmas, an initial state drawn from
    the stated covariance, and the filter of the calibration's models; the horizontal error at
    the outage's end and the filter's own sigma there are kept.
    """
    cal = calibration_axes(calibration)
    runs = check_positive_int(runs, name="runs")
    workers = check_positive_int(workers, name="workers")
    cond = prediction.conditions
    models = _models(cal)
    traj = cond.trajectory(float(cal.freq))
    clean = _cut(ideal_imu(traj, "increment"), float(traj.time[0]) + cond.end)
    truth, start_sd = dict(models), np.zeros(len(AXES))
    if cond.record is not None:
        truth, start_sd = truth_over_record(models, cond.record)
    drive = _Drive(cond, traj, clean, truth, start_sd, models, int(seed))
    try:
        out = np.array(_map(drive, list(range(runs)), workers))
    except StochmodError as exc:
        raise EstimationError(f"an emulated drive failed: {exc}") from None
    return DriftCheck(prediction, out[:, 0], out[:, 1], int(seed))
