"""GNSS-outage studies: seeded emulations through filters that differ only in their error model.

The method of Stebler et al. (2014) Section VI and Quinchia et al. (2013) Section 7: a reference
trajectory from a motion profile and its exact IMU (:mod:`stochmod.nav.emulate`); per run, sensor
errors drawn from the TRUE per-axis models, or taken from a window of a real static recording
(:class:`StaticErrors`: each run its own window, none overlapping another or the span the
filters' models were calibrated on), plus a turn-on bias per axis, GNSS fixes with the noise of
Gonzalez Section II-D, and scheduled outages; each candidate filter (same settings, its own
error model) navigates the same data; per outage, the maximum horizontal error is kept, and at
the outage's last filter epoch the NEES and the ratio of the horizontal error to the filter's
own horizontal 1-sigma. The report gives, per filter and outage, the mean, median and 95th
percentile of that maximum over the runs (the statistics of Stebler Table III and Quinchia
Tables 9-10), the mean end-of-outage NEES with its 95 % chi-square band, the RMS ratio, and the
filter's average NEES over the run (9 navigation states: 9 for an honest covariance).
"""

from __future__ import annotations

import concurrent.futures
import math
from collections.abc import Callable, Mapping, Sequence

import attrs
import numpy as np
from numpy.typing import ArrayLike
from scipy.stats import chi2

from stochmod.core.checks import check_freq, check_positive_int
from stochmod.core.errors import InputError, SpecError
from stochmod.core.model import Model
from stochmod.core.tables import format_table
from stochmod.core.units import signal_unit
from stochmod.fit.classical.build import family_for
from stochmod.fit.equivalence import beyond_record
from stochmod.io.recording import Recording, read_recording
from stochmod.io.sensors import check_static_magnitudes, declare_units
from stochmod.nav import earth
from stochmod.nav.alignment import InitialState
from stochmod.nav.emulate import (
    AXES,
    Segment,
    Trajectory,
    add_sensor_errors,
    gnss_measurements,
    ideal_imu,
    trajectory_from_profile,
)
from stochmod.nav.filter import LooselyCoupledFilter, NavResult
from stochmod.nav.records import ImuData

__all__ = [
    "DEFAULT_OUTAGES",
    "DEFAULT_PROFILE",
    "GNSS_RATE",
    "MEAN_REMOVAL",
    "OutageStudy",
    "StaticErrors",
    "horizontal_error",
    "max_outage_errors",
    "nees_band",
    "outage_study",
    "static_errors",
    "truth_over_record",
]

#: A 10-minute car drive: accelerations, turns both ways, a climb, stops of the turning kind.
DEFAULT_PROFILE: tuple[Segment, ...] = (
    Segment(30, speed=15), Segment(20, turn=90), Segment(40, speed=20),
    Segment(25, turn=-120, speed=12), Segment(45, pitch=3), Segment(30, pitch=0, speed=25),
    Segment(30, turn=60), Segment(50), Segment(25, turn=-150, speed=10), Segment(40, speed=22),
    Segment(30, turn=90), Segment(45, speed=15, pitch=-2), Segment(30, pitch=0, turn=-45),
    Segment(50, speed=20), Segment(30, turn=120), Segment(45, speed=18), Segment(35, turn=-60),
)
#: Rate of the study's GNSS fixes, Hz (the first at the drive's first epoch).
GNSS_RATE = 1.0
#: Three 60 s outages while the car moves: (start s after the first epoch, duration s).
DEFAULT_OUTAGES: tuple[tuple[float, float], ...] = ((120.0, 60.0), (300.0, 60.0), (480.0, 60.0))

# initial state errors are drawn from this 1-sigma (stated to the filter): m, m/s, deg
_INIT_SD = {"position": 1.0, "velocity": 0.1, "attitude": (0.5, 0.5, 2.0)}


def horizontal_error(reference: Trajectory, time: ArrayLike, lat: ArrayLike,
                     lon: ArrayLike) -> np.ndarray:
    """Horizontal distance (m) between positions (deg) and the reference at the same times.

    North and east differences through the meridian and prime-vertical radii at the reference
    (Gonzalez eq. 11), exact to ~1e-6 relative at the metre to kilometre scale.
    """
    time = np.asarray(time, dtype=float)
    ref = reference.at(time)
    lat_r = np.radians(ref.lat)
    r_n, r_e = earth.principal_radii(lat_r)
    north = np.radians(np.asarray(lat, dtype=float) - ref.lat) * (r_n + ref.height)
    east = (np.radians(np.asarray(lon, dtype=float) - ref.lon) * (r_e + ref.height)
            * np.cos(lat_r))
    return np.hypot(north, east)


def max_outage_errors(reference: Trajectory, time: ArrayLike, lat: ArrayLike, lon: ArrayLike,
                      windows: Sequence[tuple[float, float]]) -> np.ndarray:
    """Maximum horizontal error (m) inside each ``(start, end)`` window (absolute times, s)."""
    time, lat, lon = (np.asarray(a, dtype=float) for a in (time, lat, lon))
    out = np.empty(len(windows))
    for i, (start, end) in enumerate(windows):
        k = (time >= start) & (time <= end)
        if not k.any():
            raise InputError(f"no solution epochs inside the outage [{start}, {end}] s")
        out[i] = horizontal_error(reference, time[k], lat[k], lon[k]).max()
    return out


#: How the error signal of a static recording is centred (:class:`StaticErrors`).
MEAN_REMOVAL = ("record", "window")


def nees_band(runs: int, dof: int = 9, level: float = 0.95) -> tuple[float, float]:
    """Two-sided `level` band of the mean over `runs` independent runs of a NEES of `dof`
    states at one epoch: ``chi2(dof * runs) / runs`` (Bar-Shalom's test of consistency)."""
    runs = check_positive_int(runs, name="runs")
    lo, hi = chi2.ppf([(1 - level) / 2, (1 + level) / 2], dof * runs) / runs
    return float(lo), float(hi)


@attrs.frozen
class StaticErrors:
    """The error signal of a real static recording, to be cut into one window per run.

    The seeds' method (Stebler et al. 2014, Section VI, step 2): the real error signals of a
    sensor at rest are added to the exact IMU of an emulated trajectory. Run ``r`` takes the
    ``r``-th window of :meth:`windows`: consecutive, non-overlapping, each inside one stretch of
    samples outside the `excluded` spans (the part of the recording the filters' models were
    calibrated on), so no run sees another's errors or the calibration data.

    Attributes
    ----------
    data : ndarray (n, 6)
        The recording's samples in the channel order ``gyro_x ... accel_z``, rad/s and m/s^2
        (raw: gravity and turn-on biases in it are removed by the centring).
    freq : float
        Sampling frequency, Hz.
    excluded : tuple of (start, stop)
        Sample index spans ``[start, stop)`` no window may touch.
    mean : {"record", "window"}
        Centring of the error signal. ``"record"`` (default): each channel less its mean over
        every sample outside `excluded` (one constant per channel; the wander of the bias from
        window to window is kept, as the sensor shows it in a drive). ``"window"``: each window
        less its own mean (each run starts without the sensor's local bias).
    source : str
        Where the samples come from (a path), for the reports.
    """

    data: np.ndarray = attrs.field(eq=False, repr=False)
    freq: float
    excluded: tuple[tuple[int, int], ...] = ()
    mean: str = "record"
    source: str = ""

    def __attrs_post_init__(self) -> None:
        data = np.asarray(self.data, dtype=float)
        if data.ndim != 2 or data.shape[1] != len(AXES):
            raise InputError(f"a static error record needs {len(AXES)} channels {list(AXES)}, "
                             f"got an array of shape {data.shape}")
        if not np.all(np.isfinite(data)):
            raise InputError("the static error record has non-finite samples")
        object.__setattr__(self, "data", data)
        object.__setattr__(self, "freq", check_freq(self.freq))
        if self.mean not in MEAN_REMOVAL:
            raise InputError(f"mean must be one of {MEAN_REMOVAL}, got {self.mean!r}")
        spans = []
        for span in self.excluded:
            start, stop = (int(v) for v in span)
            if not 0 <= start < stop:
                raise InputError(f"an excluded span is [start, stop) with 0 <= start < stop "
                                 f"samples, got {span!r}")
            spans.append((start, min(stop, data.shape[0])))
        object.__setattr__(self, "excluded", tuple(sorted(spans)))
        if not self.usable.any():
            raise InputError("the excluded spans cover the whole static record")

    @property
    def n(self) -> int:
        """Number of samples of the record."""
        return int(self.data.shape[0])

    @property
    def usable(self) -> np.ndarray:
        """Boolean mask of the samples outside the excluded spans."""
        keep = np.ones(self.n, bool)
        for start, stop in self.excluded:
            keep[start:stop] = False
        return keep

    def windows(self, length: int, count: int | None = None) -> list[tuple[int, int]]:
        """Consecutive non-overlapping windows ``[start, stop)`` of `length` samples outside
        the excluded spans, from the start of the record (the first `count`; all when None).

        Raises
        ------
        InputError
            Fewer than `count` windows fit; the message says how many do.
        """
        length = check_positive_int(length, name="length")
        out: list[tuple[int, int]] = []
        for start, stop in self._stretches():
            out += [(a, a + length) for a in range(start, stop - length + 1, length)]
        if count is not None:
            count = check_positive_int(count, name="count")
            if len(out) < count:
                raise InputError(
                    f"the static record {self.source or ''} holds {len(out)} window(s) of "
                    f"{length} samples ({length / self.freq:g} s) outside the excluded spans "
                    f"{list(self.excluded)}; {count} run(s) need {count}")
            out = out[:count]
        return out

    def _stretches(self) -> list[tuple[int, int]]:
        """The maximal runs ``[start, stop)`` of samples outside the excluded spans."""
        out, start = [], 0
        for a, b in self.excluded:  # sorted by start
            if a > start:
                out.append((start, a))
            start = max(start, b)
        if start < self.n:
            out.append((start, self.n))
        return out

    def errors(self, window: tuple[int, int]) -> np.ndarray:
        """The centred error signal of one window, (stop - start, 6), rad/s and m/s^2."""
        start, stop = window
        if not (0 <= start < stop <= self.n) or not self.usable[start:stop].all():
            raise InputError(f"window {window!r} is not inside the usable part of the record")
        x = self.data[start:stop]
        if self.mean == "window":
            return x - x.mean(axis=0)
        return x - self._record_mean

    @property
    def _record_mean(self) -> np.ndarray:
        return self.data[self.usable].mean(axis=0)


def _axis_columns(rec: Recording, kinds: Sequence[str]) -> list[int]:
    """Indices of the recording's columns in the order ``gyro_x ... accel_z``: by name when
    the columns are named so (case-insensitive), else the three gyro columns then the three
    accelerometer columns, each in file order."""
    names = [c.strip().lower() for c in rec.columns]
    if all(a in names for a in AXES):
        return [names.index(a) for a in AXES]
    gyro = [k for k, kind in enumerate(kinds) if kind == "gyro"]
    accel = [k for k, kind in enumerate(kinds) if kind == "accel"]
    if len(gyro) != 3 or len(accel) != 3:
        raise InputError(
            f"{rec.path}: a static error record needs three gyro and three accelerometer "
            f"columns (x, y, z in file order, or named {list(AXES)}); found gyro {len(gyro)}, "
            f"accel {len(accel)} among {list(rec.columns)} (name them with columns=)")
    return gyro + accel


def static_errors(path: str, *, columns: Sequence[str | int] | None = None,
                  freq: float | None = None, unit: Sequence[str] | str | None = None,
                  gyro_unit: str | None = None, accel_unit: str | None = None,
                  assume_si: bool = False, exclude: Sequence[tuple[float, float]] = (),
                  mean: str = "record", reader: str | None = None) -> StaticErrors:
    """Read a static recording as the error signal of an outage study.

    Units are declared and checked as ``stochmod calibrate`` does
    (:func:`stochmod.io.sensors.declare_units`: from the file, e.g. an npz ``units`` entry
    ``"gyro: deg/s, accel: g"``, or the options; a gyro or accelerometer column of unknown unit
    is refused unless `assume_si`), converted to rad/s and m/s^2, and the magnitudes checked
    (:func:`~stochmod.io.sensors.check_static_magnitudes`: g read as m/s^2 or deg/s read as
    rad/s is refused). A raw record (gravity, turn-on biases) is fine: :class:`StaticErrors`
    removes its mean.

    Parameters
    ----------
    path : str
        The recording (any format :func:`stochmod.io.recording.read_recording` reads).
    columns : sequence of str or int, optional
        The six columns to use (default all). They are taken as ``gyro_x ... accel_z`` by name
        (case-insensitive), else as the three gyro then the three accelerometer columns by
        sensor kind, each in file order.
    freq : float, optional
        Sampling frequency, Hz: needed when the file does not record it, refused when it
        differs from the file's by more than 1 %.
    unit, gyro_unit, accel_unit, assume_si
        As ``stochmod calibrate``'s ``--unit``, ``--gyro-unit``, ``--accel-unit``,
        ``--assume-si``.
    exclude : sequence of (start, end)
        Spans in s from the record's first sample (``[start, end)``) that no window may touch:
        the part the calibrations were made from.
    mean : {"record", "window"}
        Centring of the error signal (:class:`StaticErrors`).
    reader : str, optional
        Reader name (default: by content, then suffix).
    """
    rec = read_recording(path, columns=None if columns is None else list(columns),
                         reader=reader)
    declared = declare_units(rec.columns, rec.units, rec.kinds, unit=unit, gyro_unit=gyro_unit,
                             accel_unit=accel_unit, assume_si=assume_si, required=True)
    rec = attrs.evolve(rec, units=tuple(c.unit for c in declared), declared=declared).to_si()
    order = _axis_columns(rec, [c.kind for c in declared])
    check_static_magnitudes(rec.data[:, order], [declared[k] for k in order])
    if freq is not None and rec.freq is not None and abs(freq - rec.freq) > 0.01 * rec.freq:
        raise InputError(f"{path} is sampled at {rec.freq:.6g} Hz, not at the {freq:g} Hz "
                         "asked for (the calibrations' rate)")
    fs = freq if freq is not None else rec.freq
    if fs is None:
        raise InputError(f"{path} does not record its sampling frequency: give freq")
    fs = check_freq(fs)
    spans = []
    for span in exclude:
        t0, t1 = (float(v) for v in span)
        if not (math.isfinite(t0) and math.isfinite(t1) and 0 <= t0 < t1):
            raise InputError(f"an excluded span is (start, end) s with 0 <= start < end, "
                             f"got {span!r}")
        spans.append((math.floor(t0 * fs + 1e-9), math.ceil(t1 * fs - 1e-9)))
    return StaticErrors(rec.data[:, order], fs, tuple(spans), mean, str(path))


@attrs.frozen
class OutageStudy:
    """Result of :func:`outage_study`.

    Attributes
    ----------
    filters : tuple of str
        Names of the filters, in the order given.
    outages : tuple of (start, duration)
        s after the first epoch.
    max_error : dict of str to ndarray (runs, n_outages)
        Maximum horizontal error in each outage, m, per filter and run.
    nees : dict of str to ndarray (runs,)
        Average NEES of the 9 navigation states per filter and run (9 when honest).
    runs, seed : int
        Number of emulations and the seed they were drawn from.
    n_states : dict of str to int
        Number of filter states per filter.
    end_nees : dict of str to ndarray (runs, n_outages)
        NEES of the 9 navigation states at the last filter epoch of each outage (before GNSS
        returns), per filter and run.
    end_ratio : dict of str to ndarray (runs, n_outages)
        At the same epoch, the horizontal error over the filter's own horizontal 1-sigma
        ``sqrt(sd_n^2 + sd_e^2)``; its RMS over the runs is 1 for an honest filter.
    windows : tuple of (start, stop)
        With errors from a static recording: the sample span of the record each run took.
    errors_source : str
        Where the errors came from: ``"models"`` or the static recording's path.
    rejected : dict of str to ndarray (runs,)
        GNSS updates (position and velocity) the filter's innovation gate rejected per run: an
        overconfident filter may refuse the fixes that end an outage and coast on.
    """

    filters: tuple[str, ...]
    outages: tuple[tuple[float, float], ...]
    max_error: dict[str, np.ndarray] = attrs.field(eq=False)
    nees: dict[str, np.ndarray] = attrs.field(eq=False)
    runs: int
    seed: int
    n_states: dict[str, int] = attrs.field(factory=dict)
    end_nees: dict[str, np.ndarray] = attrs.field(factory=dict, eq=False)
    end_ratio: dict[str, np.ndarray] = attrs.field(factory=dict, eq=False)
    windows: tuple[tuple[int, int], ...] = ()
    errors_source: str = "models"
    rejected: dict[str, np.ndarray] = attrs.field(factory=dict, eq=False)

    def statistics(self, name: str) -> np.ndarray:
        """(n_outages, 3): mean, median and 95th percentile of the max horizontal error, m."""
        if name not in self.max_error:
            raise InputError(f"no filter {name!r} in this study; filters are {list(self.filters)}")
        e = self.max_error[name]
        return np.stack([e.mean(0), np.median(e, 0), np.percentile(e, 95, axis=0)], -1)

    def consistency(self, name: str) -> np.ndarray:
        """(n_outages, 3): at the end of each outage, the mean NEES over the runs (the band is
        :meth:`nees_band`), the RMS and the median of the ratio of the horizontal error to the
        filter's own horizontal 1-sigma."""
        if name not in self.end_nees:
            raise InputError(f"no end-of-outage values for filter {name!r}; filters are "
                             f"{list(self.end_nees)}")
        e, r = self.end_nees[name], self.end_ratio[name]
        return np.stack([e.mean(0), np.sqrt(np.mean(r * r, 0)), np.median(r, 0)], -1)

    def nees_band(self) -> tuple[float, float]:
        """95 % band of the mean end-of-outage NEES over this study's runs (:func:`nees_band`)."""
        return nees_band(self.runs)

    def summary(self) -> str:
        """Per outage and filter: mean, median, 95th percentile of the max horizontal error (m);
        the end-of-outage NEES and error-to-sigma ratio; then the filters' average NEES."""
        rows = []
        for k, (start, dur) in enumerate(self.outages):
            for name in self.filters:
                mean, med, p95 = self.statistics(name)[k]
                rows.append([f"{start:g}+{dur:g} s", name, mean, med, p95])
        source = ("errors drawn from the models" if self.errors_source == "models" else
                  f"errors from {len(self.windows)} window(s) of {self.errors_source}")
        lines = [format_table(["outage", "filter", "mean", "median", "95%"], rows, digits=4,
                              title=f"Max horizontal error in each GNSS outage (m), "
                                    f"{self.runs} run(s), seed {self.seed}, {source}")]
        if self.end_nees:
            lo, hi = self.nees_band()
            rows = []
            for k, (start, dur) in enumerate(self.outages):
                for name in self.filters:
                    nees, rms, med = self.consistency(name)[k]
                    flag = "in" if lo <= nees <= hi else ("above" if nees > hi else "below")
                    rows.append([f"{start:g}+{dur:g} s", name, nees, flag, rms, med])
            lines.append(format_table(
                ["outage", "filter", "mean NEES", "band", "RMS error/sigma", "median"], rows,
                digits=4, title=f"At the end of each outage: NEES of the 9 navigation states "
                                f"(95 % band for {self.runs} run(s) [{lo:.3g}, {hi:.3g}]) and "
                                "horizontal error over the filter's horizontal 1-sigma "
                                "(RMS 1 = honest)"))
        nees_rows = [[n, self.n_states.get(n, ""), float(np.mean(self.nees[n])),
                      float(np.median(self.nees[n]))] for n in self.filters]
        head = ["filter", "states", "mean NEES", "median NEES"]
        if self.rejected:
            head.append("GNSS rejected")
            for row, n in zip(nees_rows, self.filters):
                row.append(int(np.sum(self.rejected[n])))
        lines.append(format_table(head, nees_rows, digits=4,
                                  title="Average NEES of the 9 navigation states over the run "
                                        "(9 = honest covariance)"))
        return "\n".join(lines)

    def plot(self, ax=None):
        """Box plot of the max horizontal error per outage and filter (needs matplotlib)."""
        try:
            import matplotlib.pyplot as plt
        except ImportError as exc:  # pragma: no cover - depends on the environment
            raise ImportError("plots need matplotlib: pip install 'stochmod[plots]'") from exc
        if ax is None:
            _, ax = plt.subplots(figsize=(8, 4))
        n_f = len(self.filters)
        for j, name in enumerate(self.filters):
            pos = np.arange(len(self.outages)) * (n_f + 1) + j
            ax.boxplot(self.max_error[name], positions=pos, widths=0.8, patch_artist=True,
                       boxprops={"facecolor": f"C{j}"}, label=name)
        ax.set_xticks(np.arange(len(self.outages)) * (n_f + 1) + (n_f - 1) / 2,
                      [f"{s:g} s" for s, _ in self.outages])
        ax.set_xlabel("outage start")
        ax.set_ylabel("max horizontal error (m)")
        ax.legend()
        return ax


def _xyz(models: Mapping[str, Model], prefix: str) -> dict[str, Model]:
    try:
        return {a: models[f"{prefix}_{a}"] for a in "xyz"}
    except KeyError as exc:
        raise SpecError(f"error models need the axes {list(AXES)}: missing {exc}") from None


def _bias_sd(value: float | Sequence[float], name: str) -> np.ndarray:
    sd = np.broadcast_to(np.asarray(value, dtype=float), (3,))
    if not np.all(np.isfinite(sd)) or np.any(sd < 0):
        raise InputError(f"{name} must be >= 0, got {value!r}")
    return sd


def outage_study(
    filters: Mapping[str, Mapping[str, Model]],
    truth: Mapping[str, Model] | None = None,
    *,
    errors: StaticErrors | None = None,
    runs: int = 10,
    seed: int = 0,
    profile: Sequence[Segment] = DEFAULT_PROFILE,
    outages: Sequence[tuple[float, float]] = DEFAULT_OUTAGES,
    rate: float = 100.0,
    start: tuple[float, float, float] = (46.5, 6.6, 400.0),
    heading: float = 30.0,
    speed: float = 5.0,
    gyro_bias_sd: float = 0.0,
    accel_bias_sd: float = 0.0,
    cep: float = 2.0,
    sigma_v: float = 3.0,
    sigma_vel: float | None = 0.1,
    dt_filter: float = 0.1,
    progress: Callable[[int, str], None] | None = None,
    workers: int = 1,
    record: float | Mapping[str, float | None] | None = None,
    truth_record: float | None = None,
) -> OutageStudy:
    """Run an outage study.

    Parameters
    ----------
    filters : mapping of str to mapping
        Filter name -> per-axis error models ``{"gyro_x": Model, ..., "accel_z": Model}``
        (bound to `rate`); the filters differ only in these.
    truth : mapping, optional
        The per-axis models the sensor errors are drawn from (bound to `rate`). Give it or
        `errors`.
    errors : StaticErrors, optional
        A real static recording (:func:`static_errors`) at `rate`: run ``r`` adds the centred
        error signal of the record's ``r``-th window (:meth:`StaticErrors.windows`, of the
        trajectory's length) instead of errors drawn from `truth`; the seed still draws the
        GNSS noise, the initial state and the turn-on biases.
    runs : int
        Number of seeded emulations R.
    seed : int
        Seed of the emulations (run r uses the stream ``(seed, r)``).
    profile : sequence of Segment
        Motion profile (:func:`stochmod.nav.trajectory_from_profile`); the default is a 10 min
        car drive.
    outages : sequence of (start, duration)
        GNSS outages, s after the first epoch.
    rate : float
        IMU rate, Hz.
    start : (lat, lon, height)
        Start position (deg, deg, m).
    heading, speed : float
        Initial heading (deg) and speed (m/s).
    gyro_bias_sd, accel_bias_sd : float
        1-sigma of the turn-on bias drawn per run and axis (rad/s, m/s^2); every filter is
        told the same value.
    cep, sigma_v, sigma_vel : float
        GNSS horizontal CEP (m, Gonzalez eq. 7), vertical 1-sigma (m), velocity 1-sigma (m/s;
        None: position only).
    dt_filter : float
        Covariance step of the filters, s (1.0 with 1 Hz GNSS: once per GNSS interval, about
        twice as fast; see docs/outages.md for its effect on the errors).
    progress : callable, optional
        Called as ``progress(run, filter_name)`` before each filter run (with ``workers > 1``:
        in the calling process, for every filter of a run once the run is done).
    workers : int
        Number of processes the runs are spread over (1: all in this process). Each run draws
        from its own stream ``(seed, r)``, so the result is the same for any number of workers.
    record : float or mapping of str to float, optional
        Length (s) of the record the filters' models were fitted on (one for every filter, or
        per filter name): correlated components beyond it enter the filter as the random walks
        they are over it (:class:`~stochmod.nav.LooselyCoupledFilter`, ``record``). None:
        models as given.
    truth_record : float, optional
        Length (s) of the record the *truth* models were fitted on, when they are fits
        themselves (``stochmod outages`` emulates with a calibration's models): a one-state
        component whose correlation time exceeds it is drawn as the random walk it is over the
        record (:func:`truth_over_record`) instead of from its unidentified stationary sigma.
        None (default): the truth is drawn as given.

    Returns
    -------
    OutageStudy
    """
    runs = check_positive_int(runs, name="runs")
    if not filters:
        raise InputError("an outage study needs at least one filter")
    if (truth is None) == (errors is None):
        raise InputError("give the sensor errors either as models (truth) or as a static "
                         "recording (errors), not both")
    if truth is not None:
        _xyz(truth, "gyro"), _xyz(truth, "accel")  # every axis needs a true model
    elif not isinstance(errors, StaticErrors):
        raise InputError(f"errors must be a StaticErrors (static_errors), got "
                         f"{type(errors).__name__}")
    elif not math.isclose(errors.freq, rate, rel_tol=1e-9):
        raise InputError(f"the static record is sampled at {errors.freq:g} Hz, the emulated "
                         f"IMU at {rate:g} Hz: they must agree")
    specs = {name: (_xyz(m, "gyro"), _xyz(m, "accel")) for name, m in filters.items()}
    records = _records(record, specs)
    g_sd, a_sd = _bias_sd(gyro_bias_sd, "gyro_bias_sd"), _bias_sd(accel_bias_sd, "accel_bias_sd")
    traj = trajectory_from_profile(list(profile), rate=rate, lat=start[0], lon=start[1],
                                   height=start[2], heading=heading, speed=speed)
    t0 = float(traj.time[0])
    if any(s < 0 or d <= 0 or t0 + s + d > traj.time[-1] for s, d in outages):
        raise InputError(f"outages {list(outages)} must lie inside the "
                         f"{traj.time[-1] - t0:g} s trajectory")
    windows = [(t0 + s, t0 + s + d) for s, d in outages]
    workers = check_positive_int(workers, name="workers")
    true_models, start_sd, spans = {}, np.zeros(len(AXES)), ()
    if errors is not None:
        spans = tuple(errors.windows(traj.time.size, runs))
    else:
        true_models = {a: truth[a] for a in AXES}
    if truth_record is not None and truth is not None:
        if not (math.isfinite(truth_record) and truth_record > 0):
            raise InputError(f"truth_record must be a positive number of seconds, got "
                             f"{truth_record!r}")
        true_models, start_sd = truth_over_record(true_models, truth_record)
    setup = _Setup(traj, ideal_imu(traj, "increment"), specs, true_models,
                   g_sd, a_sd, tuple(outages), windows, seed, cep, sigma_v, sigma_vel, dt_filter,
                   records, start_sd, errors, spans)
    max_error = {n: np.empty((runs, len(outages))) for n in specs}
    end_nees = {n: np.empty((runs, len(outages))) for n in specs}
    end_ratio = {n: np.empty((runs, len(outages))) for n in specs}
    nees = {n: np.empty(runs) for n in specs}
    rejected = {n: np.zeros(runs, int) for n in specs}
    n_states: dict[str, int] = {}

    def keep(r: int, result: list[_RunResult]) -> None:
        for out in result:
            name = out.name
            max_error[name][r], nees[name][r], n_states[name] = out.max_error, out.nees, out.n
            end_nees[name][r], end_ratio[name][r] = out.end_nees, out.end_ratio
            rejected[name][r] = out.rejected

    if workers == 1 or runs == 1:
        for r in range(runs):
            keep(r, setup.run(r, progress))
    else:
        with concurrent.futures.ProcessPoolExecutor(
                max_workers=min(workers, runs), initializer=_install, initargs=(setup,)) as pool:
            futures = {pool.submit(_run_installed, r): r for r in range(runs)}
            for fut in concurrent.futures.as_completed(futures):
                r = futures[fut]
                if progress is not None:
                    for name in specs:
                        progress(r, name)
                keep(r, fut.result())
    return OutageStudy(tuple(specs), tuple((float(s), float(d)) for s, d in outages), max_error,
                       nees, runs, seed, n_states, end_nees, end_ratio, spans,
                       "models" if errors is None else errors.source or "a static recording",
                       rejected)


def _records(record: float | Mapping[str, float | None] | None, specs: Mapping[str, object]
             ) -> dict[str, float | None]:
    """The record length (s) of each filter's models, from one value or a per-name mapping."""
    if record is None or not isinstance(record, Mapping):
        out = dict.fromkeys(specs, record)
    else:
        unknown = set(record) - set(specs)
        if unknown:
            raise InputError(f"record names unknown filter(s) {sorted(unknown)}; filters are "
                             f"{list(specs)}")
        out = {name: record.get(name) for name in specs}
    for name, value in out.items():
        if value is not None and not (math.isfinite(value) and value > 0):
            raise InputError(f"record of {name!r} must be a positive number of s, got {value!r}")
    return {name: None if v is None else float(v) for name, v in out.items()}


@attrs.frozen
class _RunResult:
    """One filter on one run."""

    name: str
    max_error: np.ndarray
    nees: float
    n: int
    end_nees: np.ndarray
    end_ratio: np.ndarray
    rejected: int = 0


def _outage_ends(traj: Trajectory, res: NavResult, windows: Sequence[tuple[float, float]]
                 ) -> tuple[np.ndarray, np.ndarray]:
    """NEES and horizontal error / horizontal 1-sigma at the last filter epoch of each outage
    window ``(start, end)`` (the epoch before the fix at `end` returns)."""
    nees, ratio = np.empty(len(windows)), np.empty(len(windows))
    for i, (start, end) in enumerate(windows):
        k = np.flatnonzero((res.epoch_time >= start) & (res.epoch_time < end - 1e-9))
        if not k.size:
            raise InputError(f"no filter epoch inside the outage [{start}, {end}] s")
        k = int(k[-1])
        t = float(res.epoch_time[k])
        j = min(int(np.searchsorted(res.time, t - 1e-9)), res.time.size - 1)
        err = horizontal_error(traj, res.time[j:j + 1], res.lat[j:j + 1], res.lon[j:j + 1])[0]
        nees[i] = float(res.nees[k])
        ratio[i] = err / math.hypot(float(res.epoch_sd[k, 0]), float(res.epoch_sd[k, 1]))
    return nees, ratio


@attrs.frozen
class _Setup:
    """Everything a run needs (sent once to each worker process)."""

    traj: Trajectory
    clean: ImuData
    specs: dict
    truth: dict
    g_sd: np.ndarray
    a_sd: np.ndarray
    outages: tuple
    windows: list
    seed: int
    cep: float
    sigma_v: float
    sigma_vel: float | None
    dt_filter: float
    records: dict = attrs.field(factory=dict)
    start_sd: np.ndarray = attrs.field(factory=lambda: np.zeros(len(AXES)))
    static: StaticErrors | None = None
    spans: tuple = ()

    def run(self, r: int, progress: Callable[[int, str], None] | None = None
            ) -> list[_RunResult]:
        """Run `r`: per filter, its max error per outage, average NEES, number of states and
        end-of-outage NEES and ratio."""
        traj, clean = self.traj, self.clean
        h = np.diff(clean.time)
        h = np.concatenate([h[:1], h])[:, None]
        rng = np.random.default_rng([self.seed, r])
        if self.static is not None:
            e = self.static.errors(self.spans[r])
            noisy = add_sensor_errors(clean, {a: e[:, j] for j, a in enumerate(AXES)})
        else:
            noisy = add_sensor_errors(clean, self.truth, rng)
        bias = np.concatenate([rng.normal(0.0, self.g_sd), rng.normal(0.0, self.a_sd)])
        if self.start_sd.any():  # the random walks' start over the truth's record
            bias = bias + rng.normal(0.0, self.start_sd)
        imu = ImuData(noisy.time, noisy.gyro + bias[:3] * h, noisy.accel + bias[3:] * h,
                      "increment")
        gnss = gnss_measurements(traj, GNSS_RATE, cep=self.cep, sigma_v=self.sigma_v,
                                 sigma_vel=self.sigma_vel, rng=rng)
        init = _initial_state(traj, rng)
        out = []
        for name, (gyro, accel) in self.specs.items():
            if progress is not None:
                progress(r, name)
            flt = LooselyCoupledFilter(gyro, accel, dt_filter=self.dt_filter,
                                       gyro_bias_sd=float(np.max(self.g_sd)),
                                       accel_bias_sd=float(np.max(self.a_sd)),
                                       record=self.records.get(name))
            res = flt.run(imu.time, imu.gyro, imu.accel, kind="increment", gnss=gnss, init=init,
                          outages=self.outages, truth=traj)
            end_nees, end_ratio = _outage_ends(traj, res, self.windows)
            out.append(_RunResult(
                name, max_outage_errors(traj, res.time, res.lat, res.lon, self.windows),
                float(res.mean_nees), len(res.state_names), end_nees, end_ratio,
                sum(res.rejected.get(k, 0) for k in ("gnss_position", "gnss_velocity"))))
        return out


def truth_over_record(truth: Mapping[str, Model], record: float
                      ) -> tuple[dict[str, Model], np.ndarray]:
    """Per-axis truth models as they are over a record of `record` s.

    A one-state correlated component whose correlation time exceeds the record
    (:func:`stochmod.fit.equivalence.equivalent_term`) is, over it, the random walk of the same
    driving intensity ``q`` (``2 sigma^2 / Tc`` for a Gauss-Markov process) started at a draw of
    variance ``q * record``, the filter's ``record`` rule (docs/navigation.md, "Correlated
    components beyond the record"): its fitted stationary sigma is not identified by the record.

    Returns
    -------
    models : dict of str to Model
        The axes' models with each such component replaced by a random walk of intensity ``q``
        (the registered family built from the IEEE-952 coefficient K, ``K^2 = q``) starting
        at zero; other axes unchanged.
    start_sd : ndarray (6,)
        Per axis (``gyro_x ... accel_z``), the 1-sigma of the walks' summed start,
        ``sqrt(sum q * record)`` (signal units); 0 where nothing was replaced.
    """
    walk = family_for(("K",))
    out, start_sd = {}, np.zeros(len(AXES))
    for j, axis in enumerate(AXES):
        model = truth[axis]
        freq = float(model.freq)
        walks = {k for k, _ in beyond_record(model, signal_unit(axis), record)}
        procs, var = [], 0.0
        for k, proc in enumerate(model.processes):
            block = proc.block(1.0 / freq, freq) if k in walks else None
            if block is None or block.n_states != 1 or block.continuous is None:
                procs.append(proc)
                continue
            c = block.continuous
            q = float((c.G @ c.Qc @ c.G.T)[0, 0])
            procs.append(walk.from_ieee952({"K": math.sqrt(q)}, freq))
            var += q * record
        out[axis] = Model(tuple(procs)).bind(freq) if var else model
        start_sd[j] = math.sqrt(var)
    return out, start_sd


_INSTALLED: list[_Setup] = []


def _install(setup: _Setup) -> None:
    """Worker initializer: keep the study's set-up for the runs this process gets."""
    _INSTALLED[:] = [setup]


def _run_installed(r: int) -> list[_RunResult]:
    return _INSTALLED[0].run(r)


def _initial_state(traj: Trajectory, rng: np.random.Generator) -> InitialState:
    """The true start perturbed by a draw from the covariance stated to the filters."""
    first = traj.at(traj.time[:1])
    lat_r = math.radians(float(first.lat[0]))
    r_n, r_e = earth.principal_radii(lat_r)
    h0 = float(first.height[0])
    dpos = rng.normal(0.0, _INIT_SD["position"], 3)
    dvel = rng.normal(0.0, _INIT_SD["velocity"], 3)
    datt = rng.normal(0.0, 1.0, 3) * np.asarray(_INIT_SD["attitude"])
    return InitialState(
        float(first.lat[0]) + math.degrees(dpos[0] / (float(r_n) + h0)),
        float(first.lon[0]) + math.degrees(dpos[1] / ((float(r_e) + h0) * math.cos(lat_r))),
        h0 - dpos[2], first.vel_ned[0] + dvel, first.rph[0] + datt, time=float(traj.time[0]),
        sd_position=_INIT_SD["position"], sd_velocity=_INIT_SD["velocity"],
        sd_attitude=_INIT_SD["attitude"])
