"""GNSS-outage studies: seeded emulations through filters that differ only in their error model.

The method of Stebler et al. (2014) Section VI and Quinchia et al. (2013) Section 7: a reference
trajectory from a motion profile and its exact IMU (:mod:`stochmod.nav.emulate`); per run, sensor
errors drawn from the TRUE per-axis models (plus a turn-on bias per axis), GNSS fixes with the
noise of Gonzalez Section II-D, and scheduled outages; each candidate filter (same settings,
its own error model) navigates the same data; per outage, the maximum horizontal error is kept.
The report gives, per filter and outage, the mean, median and 95th percentile of that maximum
over the runs (the statistics of Stebler Table III and Quinchia Tables 9-10) and the filter's
average NEES (9 navigation states: 9 for an honest covariance).
"""

from __future__ import annotations

import concurrent.futures
import math
from collections.abc import Callable, Mapping, Sequence

import attrs
import numpy as np
from numpy.typing import ArrayLike

from stochmod.core.checks import check_positive_int
from stochmod.core.errors import InputError, SpecError
from stochmod.fit.classical.build import family_for
from stochmod.core.units import signal_unit
from stochmod.fit.equivalence import beyond_record
from stochmod.core.model import Model
from stochmod.nav import earth
from stochmod.nav.emulate import (
    AXES,
    Segment,
    Trajectory,
    add_sensor_errors,
    gnss_measurements,
    ideal_imu,
    trajectory_from_profile,
)
from stochmod.nav.alignment import InitialState
from stochmod.nav.filter import LooselyCoupledFilter
from stochmod.nav.records import ImuData
from stochmod.core.tables import format_table

__all__ = [
    "DEFAULT_PROFILE",
    "DEFAULT_OUTAGES",
    "OutageStudy",
    "horizontal_error",
    "max_outage_errors",
    "outage_study",
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
    """

    filters: tuple[str, ...]
    outages: tuple[tuple[float, float], ...]
    max_error: dict[str, np.ndarray] = attrs.field(eq=False)
    nees: dict[str, np.ndarray] = attrs.field(eq=False)
    runs: int
    seed: int
    n_states: dict[str, int] = attrs.field(factory=dict)

    def statistics(self, name: str) -> np.ndarray:
        """(n_outages, 3): mean, median and 95th percentile of the max horizontal error, m."""
        if name not in self.max_error:
            raise InputError(f"no filter {name!r} in this study; filters are {list(self.filters)}")
        e = self.max_error[name]
        return np.stack([e.mean(0), np.median(e, 0), np.percentile(e, 95, axis=0)], -1)

    def summary(self) -> str:
        """Per outage and filter: mean, median, 95th percentile of the max horizontal error (m);
        then the filters' average NEES."""
        rows = []
        for k, (start, dur) in enumerate(self.outages):
            for name in self.filters:
                mean, med, p95 = self.statistics(name)[k]
                rows.append([f"{start:g}+{dur:g} s", name, mean, med, p95])
        lines = [format_table(["outage", "filter", "mean", "median", "95%"], rows, digits=4,
                              title=f"Max horizontal error in each GNSS outage (m), "
                                    f"{self.runs} run(s), seed {self.seed}")]
        nees_rows = [[n, self.n_states.get(n, ""), float(np.mean(self.nees[n])),
                      float(np.median(self.nees[n]))] for n in self.filters]
        lines.append(format_table(["filter", "states", "mean NEES", "median NEES"], nees_rows,
                                  digits=4, title="Average NEES of the 9 navigation states "
                                                  "(9 = honest covariance)"))
        return "\n".join(lines)

    def plot(self, ax=None):  # noqa: ANN001, ANN201 (matplotlib is optional)
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
    truth: Mapping[str, Model],
    *,
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
    record: float | None = None,
    truth_record: float | None = None,
) -> OutageStudy:
    """Run an outage study.

    Parameters
    ----------
    filters : mapping of str to mapping
        Filter name -> per-axis error models ``{"gyro_x": Model, ..., "accel_z": Model}``
        (bound to `rate`); the filters differ only in these.
    truth : mapping
        The per-axis models the sensor errors are drawn from (bound to `rate`).
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
    record : float, optional
        Length (s) of the record the filters' models were fitted on: correlated components
        beyond it enter every filter as the random walks they are over it
        (:class:`~stochmod.nav.LooselyCoupledFilter`, ``record``). None: models as given.
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
    _xyz(truth, "gyro"), _xyz(truth, "accel")  # every axis needs a true model
    specs = {name: (_xyz(m, "gyro"), _xyz(m, "accel")) for name, m in filters.items()}
    g_sd, a_sd = _bias_sd(gyro_bias_sd, "gyro_bias_sd"), _bias_sd(accel_bias_sd, "accel_bias_sd")
    traj = trajectory_from_profile(list(profile), rate=rate, lat=start[0], lon=start[1],
                                   height=start[2], heading=heading, speed=speed)
    t0 = float(traj.time[0])
    if any(s < 0 or d <= 0 or t0 + s + d > traj.time[-1] for s, d in outages):
        raise InputError(f"outages {list(outages)} must lie inside the "
                         f"{traj.time[-1] - t0:g} s trajectory")
    windows = [(t0 + s, t0 + s + d) for s, d in outages]
    workers = check_positive_int(workers, name="workers")
    true_models, start_sd = {a: truth[a] for a in AXES}, np.zeros(len(AXES))
    if truth_record is not None:
        if not (math.isfinite(truth_record) and truth_record > 0):
            raise InputError(f"truth_record must be a positive number of seconds, got "
                             f"{truth_record!r}")
        true_models, start_sd = truth_over_record(true_models, truth_record)
    setup = _Setup(traj, ideal_imu(traj, "increment"), specs, true_models,
                   g_sd, a_sd, tuple(outages), windows, seed, cep, sigma_v, sigma_vel, dt_filter,
                   record, start_sd)
    errors = {n: np.empty((runs, len(outages))) for n in specs}
    nees = {n: np.empty(runs) for n in specs}
    n_states: dict[str, int] = {}

    def keep(r: int, result: list[tuple[str, np.ndarray, float, int]]) -> None:
        for name, err, avg_nees, n in result:
            errors[name][r], nees[name][r], n_states[name] = err, avg_nees, n

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
    return OutageStudy(tuple(specs), tuple((float(s), float(d)) for s, d in outages), errors,
                       nees, runs, seed, n_states)


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
    record: float | None = None
    start_sd: np.ndarray = attrs.field(factory=lambda: np.zeros(len(AXES)))

    def run(self, r: int, progress: Callable[[int, str], None] | None = None
            ) -> list[tuple[str, np.ndarray, float, int]]:
        """Run `r`: (filter name, max error per outage, average NEES, number of states)."""
        traj, clean = self.traj, self.clean
        h = np.diff(clean.time)
        h = np.concatenate([h[:1], h])[:, None]
        rng = np.random.default_rng([self.seed, r])
        noisy = add_sensor_errors(clean, self.truth, rng)
        bias = np.concatenate([rng.normal(0.0, self.g_sd), rng.normal(0.0, self.a_sd)])
        if self.start_sd.any():  # the random walks' start over the truth's record
            bias = bias + rng.normal(0.0, self.start_sd)
        imu = ImuData(noisy.time, noisy.gyro + bias[:3] * h, noisy.accel + bias[3:] * h,
                      "increment")
        gnss = gnss_measurements(traj, 1.0, cep=self.cep, sigma_v=self.sigma_v,
                                 sigma_vel=self.sigma_vel, rng=rng)
        init = _initial_state(traj, rng)
        out = []
        for name, (gyro, accel) in self.specs.items():
            if progress is not None:
                progress(r, name)
            flt = LooselyCoupledFilter(gyro, accel, dt_filter=self.dt_filter,
                                       gyro_bias_sd=float(np.max(self.g_sd)),
                                       accel_bias_sd=float(np.max(self.a_sd)),
                                       record=self.record)
            res = flt.run(imu.time, imu.gyro, imu.accel, kind="increment", gnss=gnss, init=init,
                          outages=self.outages, truth=traj)
            out.append((name, max_outage_errors(traj, res.time, res.lat, res.lon, self.windows),
                        float(res.mean_nees), len(res.state_names)))
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


def _run_installed(r: int) -> list[tuple[str, np.ndarray, float, int]]:
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
