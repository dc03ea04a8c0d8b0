"""Fitted noise models exported to navigation stacks: Kalibr, OpenVINS, pyins, stochmod's own.

Kalibr, OpenVINS and pyins model each IMU axis as white noise plus a random-walk bias:

========================  ==========================  =====================================
term                      Kalibr / OpenVINS key        pyins keyword (inertial sensor model)
========================  ==========================  =====================================
white noise density N     ``*_noise_density``          ``noise``      (u/sqrt(Hz))
bias random walk K        ``*_random_walk``            ``bias_walk``  (u/s/sqrt(Hz))
bias spread               --                           ``bias_sd``    (u)
========================  ==========================  =====================================

(u = rad/s for gyroscopes, m/s^2 for accelerometers).  :func:`noise_terms` maps every
component of a fitted composite model onto these two terms, by the unit its family declares
for its physical parameters (the core names no family):

- a component with a white-noise density (unit ``u*sqrt(s)``) adds ``N^2``;
- a component with a random-walk coefficient (unit ``u/sqrt(s)``) adds ``K^2``;
- a quantization-like component (unit ``u*s``, Allan variance ``3 Q^2 / tau^2``) is bounded by
  white noise at every averaging time ``tau >= 1/fs``: ``3 Q^2 / tau^2 <= (3 Q^2 fs) / tau``,
  so it adds ``3 Q^2 fs`` to ``N^2``;
- a stationary, correlated component (GM, AR(p), ...: one with an autocovariance ``g(k)``)
  has no word in these formats.  Its drift over a time T, ``D(T) = E[x(t+T) - x(t)]^2 =
  2 (g(0) - g(T))``, is bounded by a random walk of coefficient K, whose drift is ``K^2 T``,
  at every ``T >= H`` (the stated horizon) if and only if ::

      K^2 >= sup_{T >= H} 2 (g(0) - g(T)) / T.

  That supremum is the exported ``K_eq^2``.  For a first-order GM (``g(T) = sigma^2
  exp(-T/Tc)``) ``D(T)/T`` decreases in T, so ``K_eq^2 = 2 sigma^2 (1 - exp(-H/Tc)) / H``;
  with the default horizon of one sample (``H = 1/fs``) this is ``2 sigma^2/Tc`` to first
  order -- the GM's own driving noise, a bound at every horizon (a GM is that random walk
  pulled back towards zero).  A longer horizon (the longest time the filter must coast on
  the bias without observing it) gives a smaller, still bounding, K.  A component whose
  correlation is lost within one sample (lag-one correlation below 1/e) is white noise for
  the filter: it adds its low-frequency density ``(g(0) + 2 sum_k g(k)) / fs`` to ``N^2``.
  Its stationary variance ``g(0)`` goes into pyins's ``bias_sd``.
- anything else (a rate ramp grows faster than any random walk) raises an
  :class:`~stochmod.core.errors.InputError` naming the component.

Kalibr and OpenVINS take one value per sensor for its three axes: the largest over the axes
(conservative).  pyins takes three: one per axis (x, y, z in column order).  stochmod's own
navigation filter reads the per-axis model specs (:func:`stochmod_nav_config`), which lose
nothing.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import attrs
import numpy as np

from stochmod.core.units import SENSORS, sensor_unit, si_unit_of
from stochmod.core.errors import EstimationError, InputError
from stochmod.fit.gmwm import GMWMResult
from stochmod.core.model import Model
from stochmod.core.process import Process
from stochmod.core.units import parse_unit

__all__ = ["EXPORT_FORMATS", "AxisNoise", "noise_terms", "random_walk_bound", "kalibr_yaml",
           "openvins_yaml", "pyins_parameters", "stochmod_nav_config", "write_exports"]

#: Export formats and the file each writes in the output folder.
EXPORT_FORMATS: dict[str, str] = {
    "kalibr": "kalibr_imu.yaml",
    "openvins": "kalibr_imu_chain.yaml",
    "pyins": "pyins_imu.json",
    "stochmod-nav": "stochmod_nav.json",
}
_KALIBR_NAMES = {"gyro": "gyroscope", "accel": "accelerometer"}
_WHITE_CORRELATION = math.exp(-1.0)  # lag-one correlation below which a component is white
_MAX_LAGS = 2**22  # largest lag searched by the random-walk bound


@attrs.frozen
class AxisNoise:
    """One axis as white noise plus a random-walk bias (Kalibr's model).

    Attributes
    ----------
    column : str
        Axis name.
    sensor : str
        ``"gyro"`` or ``"accel"``.
    noise_density : float
        White noise density N, u/sqrt(Hz) (u = rad/s or m/s^2).
    random_walk : float
        Bias random walk K, u/s/sqrt(Hz) (= u/sqrt(s)).
    bias_sd : float
        Stationary spread of the correlated components, plus the random walk's over the
        record, u (pyins's ``bias_sd``).
    freq : float
        Sampling frequency, Hz.
    horizon : float
        Horizon H (s) of the random-walk bound of correlated components.
    rules : tuple of (str, str)
        Component label -> how it entered (``"white"``, ``"random walk"``,
        ``"random walk bound at H"``, ``"white equivalent"``, ``"white bound"``).
    noise_interval, walk_interval : tuple of float or None
        95 % interval of N (of K) when one white (random-walk) component alone makes it.
    """

    column: str
    sensor: str
    noise_density: float
    random_walk: float
    bias_sd: float
    freq: float
    horizon: float
    rules: tuple[tuple[str, str], ...]
    noise_interval: tuple[float, float] | None = None
    walk_interval: tuple[float, float] | None = None


def random_walk_bound(process: Process, freq: float, horizon: float) -> float:
    """Smallest K (u/sqrt(s)) whose random walk bounds a stationary component's drift at every
    time ``T >= horizon``: ``K^2 = sup_{T >= H} 2 (g(0) - g(T)) / T`` over whole lags.

    Parameters
    ----------
    process : Process
        A stationary family with an autocovariance (u^2 at integer lags).
    freq : float
        Sampling frequency, Hz.
    horizon : float
        H, s; rounded up to a whole number of samples (at least one).
    """
    k0 = max(1, math.ceil(horizon * freq - 1e-9))
    g0 = float(process.autocovariance(np.array([0]), freq)[0])
    best = 2.0 * (g0 - float(process.autocovariance(np.array([k0]), freq)[0])) * freq / k0
    # beyond lag 4 g0 fs / best no T can beat `best` (D(T) <= 4 g(0)); search a log grid up to
    # there, dense enough (64 per octave) for an oscillating autocovariance's peaks
    kmax = min(_MAX_LAGS, math.ceil(4.0 * g0 * freq / best)) if best > 0 else k0
    if kmax > k0:
        lags = np.unique(np.round(np.geomspace(k0, kmax, 64 * max(1, math.ceil(math.log2(kmax / k0))))))
        d = 2.0 * (g0 - process.autocovariance(lags.astype(int), freq)) * freq / lags
        best = max(best, float(np.max(d)))
    return math.sqrt(max(best, 0.0))


def _single_interval(fit: GMWMResult, label: str, name: str) -> tuple[float, float] | None:
    try:
        est = next(e for e in fit.physical() if e.name == f"{label}.{name}")
    except (StopIteration, EstimationError):  # not identified: no interval
        return None
    return (est.low, est.high)


def noise_terms(fit: GMWMResult, sensor: str, *, column: str = "", horizon: float | None = None,
                record_seconds: float | None = None) -> AxisNoise:
    """White density and random-walk bias of one fitted axis (the rules in the module doc).

    Parameters
    ----------
    fit : GMWMResult
        The axis's fit (signal in SI).
    sensor : {"gyro", "accel"} or unit
        What the axis measures.
    column : str
        Axis name.
    horizon : float, optional
        H in s for the random-walk bound of correlated components (default one sample).
    record_seconds : float, optional
        Record length for pyins's ``bias_sd`` (default the fit's N / freq).
    """
    unit = sensor_unit(sensor)
    kind = next(k for k, v in SENSORS.items() if v == unit)
    model: Model = fit.model
    freq = float(model.freq)
    H = 1.0 / freq if horizon is None else float(horizon)
    if not (math.isfinite(H) and H > 0):
        raise InputError(f"the export horizon must be a positive number of seconds, got {horizon!r}")
    T = fit.empirical.n / freq if record_seconds is None else float(record_seconds)
    n2 = k2 = var = 0.0
    rules, white, walks = [], [], []
    for label, proc in zip(model.labels, model.processes):
        phys = proc.physical(freq)
        kinds = {name: parse_unit(si_unit_of(pv.unit, unit)).kind for name, pv in phys.items()}
        if len(phys) == 1 and next(iter(kinds.values())).endswith("_random_walk"):
            (name, pv), = phys.items()
            if kinds[name] in ("angle_random_walk", "velocity_random_walk"):
                n2 += pv.value ** 2
                white.append((label, name))
                rules.append((label, "white"))
            else:
                k2 += pv.value ** 2
                walks.append((label, name))
                rules.append((label, "random walk"))
        elif len(phys) == 1 and next(iter(kinds.values())) in ("angle", "velocity"):
            (pv,) = phys.values()
            n2 += 3.0 * pv.value ** 2 * freq
            rules.append((label, "white bound"))
        elif proc.stationary and _has_autocovariance(proc, freq):
            g = proc.autocovariance(np.array([0, 1]), freq)
            if g[1] < _WHITE_CORRELATION * g[0]:
                lags = np.arange(0, 4096)
                acv = proc.autocovariance(lags, freq)
                n2 += max(float(acv[0] + 2.0 * np.sum(acv[1:])), 0.0) / freq
                rules.append((label, "white equivalent"))
            else:
                k2 += random_walk_bound(proc, freq, H) ** 2
                rules.append((label, f"random walk bound at H = {H:g} s"))
            var += float(g[0])
        else:
            raise InputError(
                f"{column or 'the axis'}: component {label} ({proc.family}) has no white-noise, "
                "random-walk or stationary form, so no white noise plus random walk bounds it "
                "(a rate ramp grows faster than any random walk); select without it "
                "(e.g. --families GM WN RW QN)")
    to_n = [lab for lab, how in rules if how.startswith("white")]
    to_k = [lab for lab, how in rules if how.startswith("random walk")]
    n_int = _single_interval(fit, *white[0]) if len(white) == 1 and len(to_n) == 1 else None
    k_int = _single_interval(fit, *walks[0]) if len(walks) == 1 and len(to_k) == 1 else None
    return AxisNoise(column=column, sensor=kind, noise_density=math.sqrt(n2),
                     random_walk=math.sqrt(k2), bias_sd=math.sqrt(var + k2 * T), freq=freq,
                     horizon=H, rules=tuple(rules), noise_interval=n_int, walk_interval=k_int)


def _has_autocovariance(proc: Process, freq: float) -> bool:
    try:
        proc.autocovariance(np.array([0]), freq)
    except (InputError, NotImplementedError):
        return False
    return True


def _by_sensor(axes: Sequence[AxisNoise], need: Sequence[str]) -> dict[str, list[AxisNoise]]:
    out: dict[str, list[AxisNoise]] = {s: [] for s in SENSORS}
    for a in axes:
        out[a.sensor].append(a)
    missing = [s for s in need if not out[s]]
    if missing:
        raise InputError(f"this export needs gyroscope and accelerometer axes; none for "
                         f"{', '.join(missing)} (columns: {', '.join(a.column for a in axes)})")
    freqs = {a.freq for a in axes}
    if len(freqs) != 1:
        raise InputError(f"the axes have different sampling frequencies {sorted(freqs)}")
    return out


def _kalibr_values(axes: Sequence[AxisNoise]) -> dict[str, float]:
    groups = _by_sensor(axes, list(SENSORS))
    values: dict[str, float] = {}
    for sensor, name in _KALIBR_NAMES.items():
        values[f"{name}_noise_density"] = max(a.noise_density for a in groups[sensor])
        values[f"{name}_random_walk"] = max(a.random_walk for a in groups[sensor])
    values["update_rate"] = axes[0].freq
    return values


def _header(axes: Sequence[AxisNoise]) -> list[str]:
    rules = "; ".join(f"{a.column}: " + ", ".join(f"{lab} {how}" for lab, how in a.rules) for a in axes)
    return ["# written by stochmod calibrate --export (docs/datasheet_exports.md)",
            "# per sensor: the largest value over its axes; " + rules]


def kalibr_yaml(axes: Sequence[AxisNoise], rostopic: str = "/imu0") -> str:
    """Kalibr's ``imu.yaml`` (IMU noise model: continuous-time densities, SI units)."""
    v = _kalibr_values(axes)
    lines = _header(axes) + [
        f"rostopic: {rostopic}",
        f"update_rate: {v['update_rate']!r}  # Hz",
        f"accelerometer_noise_density: {v['accelerometer_noise_density']!r}  # m/s^2/sqrt(Hz)",
        f"accelerometer_random_walk: {v['accelerometer_random_walk']!r}  # m/s^3/sqrt(Hz)",
        f"gyroscope_noise_density: {v['gyroscope_noise_density']!r}  # rad/s/sqrt(Hz)",
        f"gyroscope_random_walk: {v['gyroscope_random_walk']!r}  # rad/s^2/sqrt(Hz)",
    ]
    return "\n".join(lines) + "\n"


def openvins_yaml(axes: Sequence[AxisNoise], rostopic: str = "/imu0") -> str:
    """OpenVINS's ``kalibr_imu_chain.yaml`` (its Kalibr-like IMU chain; intrinsics identity)."""
    v = _kalibr_values(axes)
    eye3 = ["    - [1.0, 0.0, 0.0]", "    - [0.0, 1.0, 0.0]", "    - [0.0, 0.0, 1.0]"]
    zero3 = ["    - [0.0, 0.0, 0.0]"] * 3
    eye4 = ["    - [1.0, 0.0, 0.0, 0.0]", "    - [0.0, 1.0, 0.0, 0.0]",
            "    - [0.0, 0.0, 1.0, 0.0]", "    - [0.0, 0.0, 0.0, 1.0]"]
    lines = ["%YAML:1.0", *_header(axes), "", "imu0:", "  T_i_b:", *eye4,
             f"  accelerometer_noise_density: {v['accelerometer_noise_density']!r}  # m/s^2/sqrt(Hz)",
             f"  accelerometer_random_walk: {v['accelerometer_random_walk']!r}  # m/s^3/sqrt(Hz)",
             f"  gyroscope_noise_density: {v['gyroscope_noise_density']!r}  # rad/s/sqrt(Hz)",
             f"  gyroscope_random_walk: {v['gyroscope_random_walk']!r}  # rad/s^2/sqrt(Hz)",
             f"  rostopic: {rostopic}", "  time_offset: 0.0",
             f"  update_rate: {v['update_rate']!r}  # Hz", '  model: "kalibr"',
             "  Tw:", *eye3, "  R_IMUtoGYRO:", *eye3, "  Ta:", *eye3, "  R_IMUtoACC:", *eye3,
             "  Tg:", *zero3]
    return "\n".join(lines) + "\n"


def pyins_parameters(axes: Sequence[AxisNoise]) -> dict[str, Any]:
    """Keyword arguments of pyins's inertial sensor model, one dict per sensor.

    ``{"gyro": {"bias_sd": [...], "noise": [...], "bias_walk": [...], "axes": [...]},
    "accel": {...}}``, SI: the first three are the keywords of pyins 1.0.1's
    ``pyins.inertial_sensor.EstimationModel`` (its filters' sensor model; checked against the
    installed package in the tests, whose simulator ``inertial_sensor.Parameters`` reproduces
    the fitted model from the same ``noise`` and ``bias_walk``)::

        gyro = EstimationModel(**{k: params["gyro"][k] for k in ("bias_sd", "noise", "bias_walk")})

    Three values per sensor (its axes in column order) when it has three axes, else one (the
    largest) for all three.
    """
    groups = _by_sensor(axes, [s for s in SENSORS if any(a.sensor == s for a in axes)] or ["gyro"])
    out: dict[str, Any] = {}
    for sensor, group in groups.items():
        if not group:
            continue
        fields = {"bias_sd": [a.bias_sd for a in group], "noise": [a.noise_density for a in group],
                  "bias_walk": [a.random_walk for a in group]}
        out[sensor] = {k: (v if len(v) == 3 else max(v)) for k, v in fields.items()}
        out[sensor]["axes"] = [a.column for a in group]
    out["units"] = {"gyro": {"bias_sd": "rad/s", "noise": "rad/s/sqrt(Hz)",
                             "bias_walk": "rad/s^2/sqrt(Hz)"},
                    "accel": {"bias_sd": "m/s^2", "noise": "m/s^2/sqrt(Hz)",
                              "bias_walk": "m/s^3/sqrt(Hz)"}}
    out["update_rate"] = axes[0].freq
    return out


def stochmod_nav_config(fits: Mapping[str, GMWMResult], units: Mapping[str, str]) -> dict[str, Any]:
    """Per-axis model specs for stochmod's navigation filter, with their units.

    ``{"axes": {column: {"unit": "rad/s", "model": spec, "name": ...}}, "freq": ..., "units": ...}``;
    ``stochmod.model_from_spec(spec, freq)`` rebuilds each fitted model exactly.
    """
    freqs = {float(f.model.freq) for f in fits.values()}
    if len(freqs) != 1:
        raise InputError(f"the axes have different sampling frequencies {sorted(freqs)}")
    axes = {}
    for col, fit in fits.items():
        axes[col] = {"unit": units[col], "name": fit.model.name, "model": fit.model.to_spec(),
                     "parameter_units": _parameter_units(fit.model, units[col])}
    return {"format": "stochmod-nav", "freq": freqs.pop(), "axes": axes,
            "units": "model parameters are per sample at freq in the axis unit u "
                     "(variances u^2, GM beta 1/s); see parameter_units"}


def _parameter_units(model: Model, unit: str) -> dict[str, str]:
    out = {}
    for label, proc in zip(model.labels, model.processes):
        for spec in proc.parameters():
            out[f"{label}.{spec.name}"] = si_unit_of(spec.unit, unit) if spec.unit else "1"
    return out


def write_exports(formats: Sequence[str], fits: Mapping[str, GMWMResult], units: Mapping[str, str],
                  out: Path, *, horizon: float | None = None,
                  rostopic: str = "/imu0") -> list[Path]:
    """Write the asked `formats` (keys of :data:`EXPORT_FORMATS`) into `out`; the paths."""
    unknown = sorted(set(formats) - set(EXPORT_FORMATS))
    if unknown:
        raise InputError(f"unknown export format(s) {unknown}; choose from {sorted(EXPORT_FORMATS)}")
    axes = [noise_terms(fit, units[col], column=col, horizon=horizon) for col, fit in fits.items()]
    written = []
    for fmt in dict.fromkeys(formats):
        path = Path(out) / EXPORT_FORMATS[fmt]
        if fmt == "kalibr":
            path.write_text(kalibr_yaml(axes, rostopic))
        elif fmt == "openvins":
            path.write_text(openvins_yaml(axes, rostopic))
        else:
            content = pyins_parameters(axes) if fmt == "pyins" else stochmod_nav_config(fits, units)
            path.write_text(json.dumps(content, indent=1, sort_keys=True, allow_nan=False))
        written.append(path)
    return written
