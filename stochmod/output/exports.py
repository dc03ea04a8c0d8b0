"""Final noise models exported to navigation stacks: Kalibr, OpenVINS, pyins, stochmod's own.

Kalibr, OpenVINS and pyins model each IMU axis as white noise plus a random-walk bias:

========================  ==========================  =====================================
term                      Kalibr / OpenVINS key        pyins keyword (inertial sensor model)
========================  ==========================  =====================================
white noise density N     ``*_noise_density``          ``noise``      (u/sqrt(Hz))
bias random walk K        ``*_random_walk``            ``bias_walk``  (u/s/sqrt(Hz))
bias spread               --                           ``bias_sd``    (u)
========================  ==========================  =====================================

(u = rad/s for gyroscopes, m/s^2 for accelerometers).  A final model (WN, RW, GM, QN, AR ...)
has more in it than these two terms; :func:`avar_bound` chooses the pair by one rule.

The rule: an Allan-variance over-bound over a stated range
----------------------------------------------------------
Kalibr's discrete model of an axis sampled at ``fs`` is white noise of variance ``N^2 fs``
per sample plus a bias whose steps have variance ``K^2 / fs``.  Its Allan variance at the
averaging time ``tau = m / fs`` (m samples) is ::

    E_{N,K}(tau) = N^2 / tau + K^2 tau / 3 + K^2 / (6 fs^2 tau)

(the last term is the sampling of the walk; relative to the white term it is
``K^2 / (6 fs^2 N^2)``, 2e-3 for the bundled example's accelerometers, 1e-9 for its
gyroscopes).  The exported pair is the one with

1. ``E_{N,K}(tau) >= AVAR_model(tau)`` at every ``tau`` of the range ``[1/fs, H]``;
2. ``N >= N_model`` and ``K >= K_model`` (the model's own white noise and random walk: the
   root sum of squares of its components with a white-noise and a random-walk unit);
3. the smallest ``max_tau E_{N,K}(tau) / AVAR_model(tau)`` over the range (the tightest
   uniform over-bound), and among the pairs that reach it the smallest additions to
   ``N_model^2`` and ``K_model^2``.

It is a linear program in ``(N^2, K^2)``; with two unknowns it reduces to convex problems in
``N^2`` alone, minimised by golden sections (:func:`_minimax`). It is solved on every
averaging factor ``m <= 128`` and 128 per octave above, up to ``m = round(H fs)``; the pair is
then scaled up by the largest remaining shortfall at **every** m of the range, if any (a
shortfall of ~1e-9 between grid points, or rounding), so that (1) holds at every
averaging time ``m / fs`` a sampled record has (on the grid only beyond ``2^21`` samples).
A model of white noise and random walk only exports its own N and K (the ratio is 1
everywhere); every other component adds to them only as much as its Allan variance needs
over the range.  At least one tau of the range is tight (``E = AVAR``): otherwise a smaller
pair would do.

``AVAR_model`` is exact: twice the Haar wavelet variance at half-width m (the identity
``AVAR(m) = 2 nu^2_m``), i.e. for each stationary component of autocovariance ``g(k)`` ::

    AVAR(m) = (4 V(m) - V(2m)) / (2 m^2),   V(n) = n g(0) + 2 sum_{k=1}^{n-1} (n - k) g(k)

(V(n): variance of a sum of n consecutive samples), and for a random-walk component of step
variance ``s^2`` the discrete ``s^2 (2 m^2 + 1) / (6 m)``.  A component with neither form (a
rate ramp grows faster than any random walk) raises an
:class:`~stochmod.core.errors.InputError` naming it.

The horizon H: the longest averaging time the filter must trust its bias model for.  The
default (:func:`default_horizon`) is ``min(600 s, T / 10)`` for a record of T seconds: a
filter relies on the bias model alone while the bias is unobserved -- a GNSS outage (tens of
seconds to a few minutes; ``stochmod outages`` emulates 60 s ones) or a visual-inertial
filter's feature-poor stretch -- and ten minutes covers these with margin; beyond ``T / 10``
the record's own Allan variance has fewer than ~18 degrees of freedom (IEEE Std 952's
``1 / sqrt(2 (T/tau - 1))`` is 24 % there), so the model's Allan variance at longer tau is an
extrapolation the data did not check.  Never one sample: a bound over ``[1/fs, 1/fs]`` is
free to ignore every correlated component.

Kalibr and OpenVINS take one value per sensor for its three axes: the largest over the axes
(conservative).  pyins takes three: one per axis (x, y, z in column order).  stochmod's own
navigation filter reads the per-axis model specs (:func:`stochmod_nav_config`), which lose
nothing.  :func:`exports_from_calibration` writes the files from a
:class:`~stochmod.io.calibration.Calibration` (``calibration.json``) without refitting.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import attrs
import numpy as np

from stochmod.core.errors import EstimationError, InputError
from stochmod.core.model import Model
from stochmod.core.process import Process
from stochmod.core.units import SENSORS, parse_unit, sensor_unit, si_unit_of
from stochmod.fit.gmwm import GMWMResult

if TYPE_CHECKING:
    from stochmod.io.calibration import Calibration

__all__ = [
    "DEFAULT_HORIZON_CAP",
    "EXPORT_FORMATS",
    "AxisNoise",
    "avar_bound",
    "avar_grid",
    "axis_noise",
    "calibration_noise",
    "component_avar",
    "default_horizon",
    "envelope_avar",
    "exports_from_calibration",
    "header_lines",
    "kalibr_yaml",
    "noise_terms",
    "openvins_yaml",
    "pyins_parameters",
    "stochmod_nav_config",
    "write_exports",
]

#: Export formats and the file each writes in the output folder.
EXPORT_FORMATS: dict[str, str] = {
    "kalibr": "kalibr_imu.yaml",
    "openvins": "kalibr_imu_chain.yaml",
    "pyins": "pyins_imu.json",
    "stochmod-nav": "stochmod_nav.json",
}
#: Cap of the default horizon, s (the longest coast on the bias model a filter is expected
#: to bridge, with margin).
DEFAULT_HORIZON_CAP = 600.0
_RECORD_FRACTION = 10.0  # default horizon at most the record / this
_KALIBR_NAMES = {"gyro": "gyroscope", "accel": "accelerometer"}
_DENSE = 128  # every averaging factor up to this, then this many per octave
_CHUNK = 2**20  # lags of an autocovariance evaluated at once
_TIE = 1e-6  # relative slack on the optimal ratio when the additions are minimised
_EVERY_M = 2**21  # up to this many samples in the range the bound is checked at every m


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
        Exported white noise density N, u/sqrt(Hz) (u = rad/s or m/s^2).
    random_walk : float
        Exported bias random walk K, u/s/sqrt(Hz) (= u/sqrt(s)).
    bias_sd : float
        Stationary spread of the correlated components, plus the exported random walk's over
        the record, u (pyins's ``bias_sd``): ``sqrt(sum g(0) + K^2 T)``.
    freq : float
        Sampling frequency fs, Hz.
    horizon : float
        H, s: the bound holds over ``tau`` in ``[1/fs, H]``.
    rules : tuple of (str, str)
        Component label -> how it entered (``"white"``, ``"random walk"``, ``"bounded"``).
    model_noise_density, model_random_walk : float
        The model's own N and K (root sum of squares of its white-noise and random-walk
        components; 0 without one), same units.
    max_ratio : float
        ``max E_{N,K}(tau) / AVAR_model(tau)`` over the range (1: the model itself).
    tight_tau : float
        An averaging time (s) of the range where ``E = AVAR_model``.
    horizon_source : str
        Where H comes from (``"given"``, or the default's rule and the record length).
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
    model_noise_density: float = 0.0
    model_random_walk: float = 0.0
    max_ratio: float = 1.0
    tight_tau: float = float("nan")
    horizon_source: str = "given"
    noise_interval: tuple[float, float] | None = None
    walk_interval: tuple[float, float] | None = None

    @property
    def noise_inflation(self) -> float:
        """``N / N_model`` (inf when the model has no white noise and N > 0)."""
        return _ratio(self.noise_density, self.model_noise_density)

    @property
    def walk_inflation(self) -> float:
        """``K / K_model`` (inf when the model has no random walk and K > 0)."""
        return _ratio(self.random_walk, self.model_random_walk)


def _ratio(value: float, model: float) -> float:
    if model > 0:
        return value / model
    return 1.0 if value == 0 else math.inf


def default_horizon(record_seconds: float, freq: float) -> float:
    """Default horizon H of the bound, s: ``min(600 s, T / 10)``, at least two samples.

    Parameters
    ----------
    record_seconds : float
        Length T of the longest single record fitted, s.
    freq : float
        Sampling frequency fs, Hz.

    Notes
    -----
    600 s covers, with margin, the time a navigation filter coasts on its bias model (GNSS
    outages of tens of seconds to minutes); ``T / 10`` is the longest averaging time at which
    the record's Allan variance has ~18 degrees of freedom (beyond it the model's Allan
    variance is an extrapolation).  See the module documentation.
    """
    return max(2.0 / freq, min(DEFAULT_HORIZON_CAP, float(record_seconds) / _RECORD_FRACTION))


def avar_grid(freq: float, horizon: float) -> np.ndarray:
    """Averaging factors m (samples, int64) of the bound over ``tau = m / fs`` in ``[1/fs, H]``:
    every m up to 128, then 128 per octave, and ``round(H fs)``."""
    top = max(1, round(horizon * freq))
    m = np.arange(1, min(top, _DENSE) + 1, dtype=np.float64)
    if top > _DENSE:
        count = math.ceil(_DENSE * math.log2(top / _DENSE)) + 1
        m = np.r_[m, np.round(np.geomspace(_DENSE, top, count)), top]
    return np.unique(m).astype(np.int64)


def _block_variances(process: Process, freq: float, n: np.ndarray) -> np.ndarray:
    """``V(n) = Var(x_1 + ... + x_n) = n g(0) + 2 sum_{k<n} (n - k) g(k)`` at the sorted
    integers `n`, u^2, from the autocovariance g in chunks of lags (bounded memory)."""
    g0 = float(process.autocovariance(np.array([0]), freq)[0])
    k_needed = n - 1  # V(n) needs C0(n-1) = sum_{k=1}^{n-1} g(k) and C1(n-1) = sum k g(k)
    c0 = np.zeros(n.size)
    c1 = np.zeros(n.size)
    kmax = int(k_needed.max())
    carry0 = carry1 = 0.0
    for start in range(1, kmax + 1, _CHUNK):
        lags = np.arange(start, min(start + _CHUNK, kmax + 1), dtype=np.int64)
        g = np.asarray(process.autocovariance(lags, freq), dtype=np.float64)
        s0 = carry0 + np.cumsum(g)
        s1 = carry1 + np.cumsum(lags * g)
        here = (k_needed >= start) & (k_needed <= lags[-1])
        c0[here] = s0[k_needed[here] - start]
        c1[here] = s1[k_needed[here] - start]
        carry0, carry1 = float(s0[-1]), float(s1[-1])
    return n * g0 + 2.0 * (n * c0 - c1)


def _with_doubles(m: np.ndarray) -> np.ndarray:
    """The sorted union of the averaging factors `m` and ``2 m``, without repeats; for every m
    from 1 to M (the bound's grid below ``_EVERY_M``) it is 1..M and the even numbers up to 2M,
    built directly (a sort of 2M values is most of the time otherwise)."""
    top = int(m[-1]) if m.size else 0
    if m.size == top and m[0] == 1 and np.all(np.diff(m) == 1):
        return np.r_[m, np.arange(top + 1 + (top + 1) % 2, 2 * top + 1, 2, dtype=np.int64)]
    both = np.sort(np.r_[m, 2 * m])  # np.unique is slower here
    return both[np.r_[True, both[1:] != both[:-1]]]


def component_avar(process: Process, freq: float, m: np.ndarray, unit: str = "rad/s"
                   ) -> np.ndarray:
    """Exact Allan variance of one component at the averaging factors `m`, u^2.

    ``AVAR(m) = 2 nu^2_m`` (twice the Haar wavelet variance at half-width m, any integer m):

    - stationary, autocovariance g: ``(4 V(m) - V(2m)) / (2 m^2)`` with
      ``V(n) = n g(0) + 2 sum_{k=1}^{n-1} (n - k) g(k)``;
    - random walk (one parameter in ``u/sqrt(s)``) of step variance ``s^2 = K^2 / fs``:
      ``s^2 (2 m^2 + 1) / (6 m)``, checked against the family's own wavelet variance.

    Parameters
    ----------
    process : Process
        The component, with values.
    freq : float
        Sampling frequency fs, Hz.
    m : array_like of int
        Averaging factors (``tau = m / fs``), at least 1.
    unit : str
        The signal's SI unit (to read the component's physical unit).

    Raises
    ------
    InputError
        A component with no autocovariance that is not a random walk (a rate ramp).
    """
    m = np.asarray(m, dtype=np.int64)
    if process.stationary and _has_autocovariance(process, freq):
        both = _with_doubles(m)
        v = _block_variances(process, freq, both)
        vm, v2m = v[np.searchsorted(both, m)], v[np.searchsorted(both, 2 * m)]
        return (4.0 * vm - v2m) / (2.0 * m.astype(np.float64) ** 2)
    kind, value = _single_kind(process, freq, unit)
    if kind is not None and kind.endswith("_random_walk") and kind not in _WHITE_KINDS:
        s2 = value * value / freq
        mf = m.astype(np.float64)
        avar = s2 * (2.0 * mf * mf + 1.0) / (6.0 * mf)
        levels = int(m.max()).bit_length()
        dyadic = 2.0 ** np.arange(levels)
        own = 2.0 * process.wv(levels, freq)
        if np.allclose(own, s2 * (2.0 * dyadic**2 + 1.0) / (6.0 * dyadic), rtol=1e-9, atol=0):
            return avar
    raise InputError(
        f"{process.family} has no white-noise, random-walk or stationary form, so no "
        "white noise plus random walk bounds it (a rate ramp grows faster than any random "
        "walk); select without it (e.g. --families GM WN RW QN)")


def envelope_avar(noise_density: float, random_walk: float, freq: float, m: np.ndarray
                  ) -> np.ndarray:
    """Allan variance of Kalibr's discrete white noise N plus random walk K at ``tau = m/fs``,
    u^2: ``N^2 / tau + K^2 tau / 3 + K^2 / (6 fs^2 tau)``."""
    w, r = _envelope_basis(freq, np.asarray(m))
    return noise_density**2 * w + random_walk**2 * r


def _envelope_basis(freq: float, m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``E = N^2 w + K^2 r``: ``w = fs / m`` (= 1/tau), ``r = (2 m^2 + 1) / (6 m fs)``."""
    mf = m.astype(np.float64)
    return freq / mf, (2.0 * mf * mf + 1.0) / (6.0 * mf * freq)


_WHITE_KINDS = ("angle_random_walk", "velocity_random_walk")


def _single_kind(process: Process, freq: float, unit: str) -> tuple[str | None, float]:
    """The physical kind and value of a one-parameter family (``(None, nan)`` otherwise)."""
    phys = process.physical(freq)
    if len(phys) != 1:
        return None, math.nan
    (pv,) = phys.values()
    return parse_unit(si_unit_of(pv.unit, unit)).kind, float(pv.value)


def _has_autocovariance(proc: Process, freq: float) -> bool:
    try:
        proc.autocovariance(np.array([0]), freq)
    except (InputError, NotImplementedError):
        return False
    return True


def _minimax(w: np.ndarray, r: np.ndarray, n2: float, k2: float, rest: np.ndarray
             ) -> tuple[float, float]:
    """Additions ``(a, b) >= 0`` to ``(N^2, K^2)`` that minimise ``max E / A`` subject to
    ``E >= A`` (``E = (n2 + a) w + (k2 + b) r``, ``A = n2 w + k2 r + rest``), then the
    normalised sum ``a / sa + b / sb`` among the pairs within ``1 + _TIE`` of that minimum.

    The linear program has two unknowns, so it is solved as two convex problems in the white
    addition alone: for a given ``a`` the best ``b`` is the smallest that keeps ``E >= A``
    (a larger one raises every ratio), which leaves the ratio's maximum, and the normalised
    sum, convex piecewise-linear functions of ``a`` (minimised by golden sections)."""
    total = n2 * w + k2 * r + rest
    if not np.all(np.isfinite(total)) or not np.all(total > 0):
        raise EstimationError("the export bound needs a positive, finite Allan variance of the "
                              "model at every averaging time of the range")
    sa, sb = float(total[0] / w[0]), float(total[-1] / r[-1])  # a = sa: white covers A at 1/fs
    wn, rn = sa * w / total, sb * r / total
    base = (n2 * w + k2 * r) / total
    gap = 1.0 - base  # what the additions must cover, in ratio units

    def walk(a: float) -> float:  # the smallest normalised b with E >= A, given a
        return max(0.0, float(np.max((gap - a * wn) / rn)))

    def peak(a: float) -> float:  # the largest ratio E / A at (a, walk(a))
        return float(np.max(base + a * wn + walk(a) * rn))

    top = float(np.min((peak(0.0) - base) / wn))  # peak(a) > peak(0) beyond it
    a = _golden(peak, 0.0, max(top, 0.0))
    t = peak(a) * (1.0 + _TIE)
    low = _crossing(peak, t, 0.0, a)
    high = _crossing(peak, t, float(np.min((t - base) / wn)), a)
    a = _golden(lambda x: x + walk(x), low, high)
    return max(a, 0.0) * sa, walk(a) * sb


def _golden(f: Callable[[float], float], lo: float, hi: float) -> float:
    """The minimiser of the convex function `f` on ``[lo, hi]``, to a relative 1e-15."""
    inv = (math.sqrt(5.0) - 1.0) / 2.0
    x1, x2 = hi - inv * (hi - lo), lo + inv * (hi - lo)
    f1, f2 = f(x1), f(x2)
    while hi - lo > 1e-15 * max(1.0, abs(hi)):
        if f1 <= f2:
            hi, x2, f2 = x2, x1, f1
            x1 = hi - inv * (hi - lo)
            f1 = f(x1)
        else:
            lo, x1, f1 = x1, x2, f2
            x2 = lo + inv * (hi - lo)
            f2 = f(x2)
    return lo if f(lo) <= f(hi) else hi


def _crossing(f: Callable[[float], float], level: float, outside: float, inside: float
              ) -> float:
    """The end of the sublevel set ``{f <= level}`` of a convex `f` between a point `inside`
    it and one `outside` (either side), by bisection; a point where ``f <= level``."""
    if f(outside) <= level:
        return outside
    while abs(outside - inside) > 1e-15 * max(1.0, abs(inside)):
        mid = 0.5 * (outside + inside)
        if f(mid) <= level:
            inside = mid
        else:
            outside = mid
    return inside


def avar_bound(model: Model, sensor: str, *, column: str = "", horizon: float | None = None,
               record_seconds: float | None = None,
               intervals: Mapping[str, tuple[float, float]] | None = None) -> AxisNoise:
    """White density N and random walk K of one axis: the tightest Allan-variance over-bound
    of its model over ``[1/fs, H]`` (the rule in the module documentation).

    Finds ``(N, K)`` with ``N >= N_model``, ``K >= K_model`` and
    ``N^2 / tau + K^2 tau / 3 + K^2 / (6 fs^2 tau) >= AVAR_model(tau)`` at every
    ``tau = m / fs``, m = 1 .. round(H fs), minimising the largest ratio of the two sides
    (solved on :func:`avar_grid`).

    Parameters
    ----------
    model : Model
        The axis's final model, bound to its sampling frequency (signal in SI).
    sensor : {"gyro", "accel"} or unit
        What the axis measures.
    column : str
        Axis name.
    horizon : float, optional
        H in s (default :func:`default_horizon` of `record_seconds`).
    record_seconds : float, optional
        Record length T, s: the default horizon and pyins's ``bias_sd`` (default 10 H, or
        6000 s when neither is given).
    intervals : mapping, optional
        ``"label.name" -> (low, high)`` 95 % intervals of the physical parameters, SI.

    Returns
    -------
    AxisNoise
    """
    unit = sensor_unit(sensor)
    kind = next(k for k, v in SENSORS.items() if v == unit)
    if model.freq is None:
        raise InputError(f"{column or 'the axis'}: the model must be bound to its sampling "
                         "frequency (Model.bind(freq))")
    freq = float(model.freq)
    if record_seconds is None:
        record_seconds = _RECORD_FRACTION * (DEFAULT_HORIZON_CAP if horizon is None
                                             else float(horizon))
    T = float(record_seconds)
    H = default_horizon(T, freq) if horizon is None else float(horizon)
    source = (f"default min({DEFAULT_HORIZON_CAP:g} s, record/{_RECORD_FRACTION:g}), record "
              f"{T:g} s" if horizon is None else "given")
    if not (math.isfinite(H) and H * freq >= 1.0 - 1e-9):
        raise InputError(f"the export horizon must be a number of seconds of at least one "
                         f"sample ({1.0 / freq:g} s), got {horizon!r}")
    grid = avar_grid(freq, H)
    top = int(grid[-1])
    m = np.arange(1, top + 1, dtype=np.int64) if top <= _EVERY_M else grid
    on_grid = grid - 1 if top <= _EVERY_M else np.arange(grid.size)
    w, r = _envelope_basis(freq, m)
    n2 = k2 = var = 0.0
    rest = np.zeros(m.size)
    rules, white, walks = [], [], []
    for label, proc in zip(model.labels, model.processes):
        pkind, value = _single_kind(proc, freq, unit)
        if pkind in _WHITE_KINDS:
            n2 += value * value
            white.append(f"{label}.{next(iter(proc.physical(freq)))}")
            rules.append((label, "white"))
            continue
        try:
            avar = component_avar(proc, freq, m, unit)
        except InputError as exc:
            raise InputError(f"{column or 'the axis'}: component {label}: {exc}") from None
        if pkind is not None and pkind.endswith("_random_walk") and not proc.stationary:
            k2 += value * value
            walks.append(f"{label}.{next(iter(proc.physical(freq)))}")
            rules.append((label, "random walk"))
            continue
        rest += avar
        rules.append((label, "bounded"))
        if pkind not in ("angle", "velocity"):  # a quantization is no bias
            var += float(proc.autocovariance(np.array([0]), freq)[0])
    a = b = 0.0
    if np.any(rest > 0):
        a, b = _minimax(w[on_grid], r[on_grid], n2, k2, rest[on_grid])
    total = n2 * w + k2 * r + rest
    N2, K2 = n2 + a, k2 + b
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(total > 0, (N2 * w + K2 * r) / total, 1.0)
    short = float(np.min(ratio))
    if short < 1.0:  # rounding, or between grid points: scale up to hold at every m
        N2, K2 = N2 / short, K2 / short
        ratio = ratio / short
    lookup = dict(intervals or {})
    n_int = lookup.get(white[0]) if len(white) == 1 and a == 0 else None
    k_int = lookup.get(walks[0]) if len(walks) == 1 and b == 0 else None
    return AxisNoise(column=column, sensor=kind, noise_density=math.sqrt(N2),
                     random_walk=math.sqrt(K2), bias_sd=math.sqrt(var + K2 * T), freq=freq,
                     horizon=H, rules=tuple(rules), model_noise_density=math.sqrt(n2),
                     model_random_walk=math.sqrt(k2), max_ratio=float(np.max(ratio)),
                     tight_tau=float(m[int(np.argmin(ratio))] / freq), horizon_source=source,
                     noise_interval=None if n_int is None else tuple(n_int),
                     walk_interval=None if k_int is None else tuple(k_int))


def _fit_intervals(fit: GMWMResult) -> dict[str, tuple[float, float]]:
    try:
        return {e.name: (e.low, e.high) for e in fit.physical()}
    except EstimationError:  # not identified: no intervals
        return {}


def _intervals_of(physical: Any, model: Model) -> dict[str, tuple[float, float]]:
    """Intervals of a calibration's ``details["physical"]`` entries that describe `model`'s
    values (an entry whose value differs belongs to another model: left out)."""
    if not isinstance(physical, list):
        return {}
    values = {f"{lab}.{name}": pv.value for lab, proc in zip(model.labels, model.processes)
              for name, pv in proc.physical(float(model.freq)).items()}
    out = {}
    for e in physical:
        if not isinstance(e, dict) or e.get("name") not in values:
            continue
        low, high, value = e.get("low"), e.get("high"), e.get("value")
        if (isinstance(low, (int, float)) and isinstance(high, (int, float))
                and isinstance(value, (int, float))
                and math.isclose(value, values[e["name"]], rel_tol=1e-9)):
            out[e["name"]] = (float(low), float(high))
    return out


def noise_terms(fit: GMWMResult, sensor: str, *, column: str = "", horizon: float | None = None,
                record_seconds: float | None = None) -> AxisNoise:
    """:func:`avar_bound` of a fit's model, with the fit's intervals.

    Parameters
    ----------
    fit : GMWMResult
        The axis's fit (signal in SI).
    sensor : {"gyro", "accel"} or unit
        What the axis measures.
    column : str
        Axis name.
    horizon : float, optional
        H in s (default :func:`default_horizon`).
    record_seconds : float, optional
        Record length, s (default the fit's N / freq).
    """
    T = fit.empirical.n / float(fit.model.freq) if record_seconds is None else record_seconds
    return avar_bound(fit.model, sensor, column=column, horizon=horizon, record_seconds=T,
                      intervals=_fit_intervals(fit))


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


def _inflation(value: float, model: float, what: str) -> str:
    if model > 0:
        return f"{value:.6g} = x{value / model:.4g} the model's {model:.6g}"
    return f"{value:.6g} (the model has no {what})"


def header_lines(axes: Sequence[AxisNoise], per_sensor: bool = True) -> list[str]:
    """The exports' header: the rule, its range ``[1/fs, H]`` and, per axis (and per sensor
    with `per_sensor`), the inflation ``N / N_model``, ``K / K_model``."""
    freq = axes[0].freq
    horizons = sorted({(a.horizon, a.horizon_source) for a in axes})
    H = "; ".join(f"{h:g} s ({src})" for h, src in horizons)
    lines = ["written by stochmod from the final noise models (docs/datasheet_exports.md)",
             "rule: per axis the (N, K) whose Allan variance N^2/tau + K^2 tau/3 + K^2/(6 fs^2 tau)",
             f"  over-bounds the model's at every tau in [1/fs, H] = [{1.0 / freq:g} s, H], H = {H},",
             "  with the smallest largest ratio of the two; N, K never below the model's own"]
    for a in axes:
        if a.max_ratio == 1.0:
            fit = "envelope = model AVAR at every tau"
        else:
            fit = f"envelope/AVAR in [1, {a.max_ratio:.4g}], 1 at tau = {a.tight_tau:.4g} s"
        lines.append(f"{a.column}: N {_inflation(a.noise_density, a.model_noise_density, 'white noise')}"
                     f", K {_inflation(a.random_walk, a.model_random_walk, 'random walk')}; "
                     f"{fit}; " + ", ".join(f"{lab} {how}" for lab, how in a.rules))
    if per_sensor:
        for sensor, name in _KALIBR_NAMES.items():
            group = [a for a in axes if a.sensor == sensor]
            if not group:
                continue
            n = max(a.noise_density for a in group)
            k = max(a.random_walk for a in group)
            lines.append(
                f"{name}: the largest over its axes, N "
                f"{_inflation(n, max(a.model_noise_density for a in group), 'white noise')}, K "
                f"{_inflation(k, max(a.model_random_walk for a in group), 'random walk')} "
                "(the model's: the largest over the axes)")
    return lines


def _header(axes: Sequence[AxisNoise]) -> list[str]:
    return ["# " + line for line in header_lines(axes)]


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
    "accel": {...}, "header": [...]}``, SI: the first three are the keywords of pyins
    1.0.1's ``pyins.inertial_sensor.EstimationModel`` (its filters' sensor model; checked
    against the installed package in the tests, whose simulator
    ``inertial_sensor.Parameters`` reproduces the fitted model from the same ``noise`` and
    ``bias_walk``)::

        gyro = EstimationModel(**{k: params["gyro"][k] for k in ("bias_sd", "noise", "bias_walk")})

    Three values per sensor (its axes in column order) when it has three axes, else one (the
    largest) for all three.  ``header`` states the rule, its range and the inflation.
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
    out["header"] = header_lines(axes, per_sensor=False)
    return out


def _as_model(item: Model | GMWMResult) -> Model:
    return item.model if isinstance(item, GMWMResult) else item


def stochmod_nav_config(models: Mapping[str, Model | GMWMResult], units: Mapping[str, str]
                        ) -> dict[str, Any]:
    """Per-axis model specs for stochmod's navigation filter, with their units.

    ``{"axes": {column: {"unit": "rad/s", "model": spec, "name": ...}}, "freq": ..., "units": ...}``;
    ``stochmod.model_from_spec(spec, freq)`` rebuilds each model exactly (no bound: nothing
    is lost).
    """
    models = {col: _as_model(item) for col, item in models.items()}
    freqs = {float(m.freq) for m in models.values()}
    if len(freqs) != 1:
        raise InputError(f"the axes have different sampling frequencies {sorted(freqs)}")
    axes = {}
    for col, model in models.items():
        axes[col] = {"unit": units[col], "name": model.name, "model": model.to_spec(),
                     "parameter_units": _parameter_units(model, units[col])}
    return {"format": "stochmod-nav", "freq": freqs.pop(), "axes": axes,
            "units": "model parameters are per sample at freq in the axis unit u "
                     "(variances u^2, GM beta 1/s); see parameter_units"}


def _parameter_units(model: Model, unit: str) -> dict[str, str]:
    out = {}
    for label, proc in zip(model.labels, model.processes):
        for spec in proc.parameters():
            out[f"{label}.{spec.name}"] = si_unit_of(spec.unit, unit) if spec.unit else "1"
    return out


def axis_noise(models: Mapping[str, Model | GMWMResult], units: Mapping[str, str], *,
               horizon: float | None = None, record_seconds: float | None = None,
               intervals: Mapping[str, Mapping[str, tuple[float, float]]] | None = None
               ) -> list[AxisNoise]:
    """The exported white density and random walk of each axis (:func:`avar_bound` of a
    model, :func:`noise_terms` of a fit), in the order of `models`; the arguments as for
    :func:`write_exports`."""
    axes = []
    for col, item in models.items():
        if isinstance(item, GMWMResult):
            axes.append(noise_terms(item, units[col], column=col, horizon=horizon,
                                    record_seconds=record_seconds))
        else:
            axes.append(avar_bound(item, units[col], column=col, horizon=horizon,
                                   record_seconds=record_seconds,
                                   intervals=(intervals or {}).get(col)))
    return axes


def write_exports(formats: Sequence[str], models: Mapping[str, Model | GMWMResult],
                  units: Mapping[str, str], out: Path, *, horizon: float | None = None,
                  record_seconds: float | None = None,
                  intervals: Mapping[str, Mapping[str, tuple[float, float]]] | None = None,
                  rostopic: str = "/imu0", noise: Sequence[AxisNoise] | None = None
                  ) -> list[Path]:
    """Write the asked `formats` (keys of :data:`EXPORT_FORMATS`) into `out`; the paths.

    Parameters
    ----------
    formats : sequence of str
        Export formats.
    models : mapping
        Column -> final model (or a fit: its model and intervals), signal in SI.
    units : mapping
        Column -> SI unit (``"rad/s"``, ``"m/s^2"``).
    out : Path
        Output folder.
    horizon : float, optional
        H, s (default :func:`default_horizon` of the record).
    record_seconds : float, optional
        Record length T, s (default a fit's N / freq; for bare models 10 H).
    intervals : mapping, optional
        Column -> ``{"label.name": (low, high)}`` of the physical parameters.
    rostopic : str
        IMU topic of the Kalibr and OpenVINS files.
    noise : sequence of AxisNoise, optional
        The axes' exported terms, one per model in order, when computed already
        (:func:`axis_noise` of the same arguments); then `horizon`, `record_seconds` and
        `intervals` are not read.
    """
    unknown = sorted(set(formats) - set(EXPORT_FORMATS))
    if unknown:
        raise InputError(f"unknown export format(s) {unknown}; choose from {sorted(EXPORT_FORMATS)}")
    if noise is None:
        axes = axis_noise(models, units, horizon=horizon, record_seconds=record_seconds,
                          intervals=intervals)
    else:
        axes = list(noise)
        if [a.column for a in axes] != list(models):
            raise InputError(f"noise holds the axes {[a.column for a in axes]}, the models "
                             f"{list(models)}")
    written = []
    for fmt in dict.fromkeys(formats):
        path = Path(out) / EXPORT_FORMATS[fmt]
        if fmt == "kalibr":
            path.write_text(kalibr_yaml(axes, rostopic))
        elif fmt == "openvins":
            path.write_text(openvins_yaml(axes, rostopic))
        else:
            content = pyins_parameters(axes) if fmt == "pyins" else stochmod_nav_config(models, units)
            path.write_text(json.dumps(content, indent=1, sort_keys=True, allow_nan=False))
        written.append(path)
    return written


def exports_from_calibration(calibration: Calibration, formats: Sequence[str], out: str | Path,
                             *, horizon: float | None = None, rostopic: str = "/imu0",
                             noise: Sequence[AxisNoise] | None = None) -> list[Path]:
    """Write the exports of a calibration's final models (no refit); the paths.

    Parameters
    ----------
    calibration : Calibration
        E.g. ``Calibration.read("calibration.json")``: its gyro and accelerometer axes
        (``kind``, SI ``unit``, final ``model``, intervals in ``details["physical"]``), its
        record length (:attr:`~stochmod.io.calibration.Calibration.record_seconds`, for the
        default horizon and pyins's ``bias_sd``).
    formats : sequence of str
        Keys of :data:`EXPORT_FORMATS`.
    out : str or Path
        Output folder (created if missing).
    horizon : float, optional
        H, s (default :func:`default_horizon`).
    rostopic : str
        IMU topic of the Kalibr and OpenVINS files.
    noise : sequence of AxisNoise, optional
        :func:`calibration_noise` of the same calibration and horizon, when computed already.
    """
    models, units, intervals = _calibration_axes(calibration)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    return write_exports(formats, models, units, out, horizon=horizon,
                         record_seconds=calibration.record_seconds, intervals=intervals,
                         rostopic=rostopic, noise=noise)


def calibration_noise(calibration: Calibration, *, horizon: float | None = None
                      ) -> list[AxisNoise]:
    """The exported terms of a calibration's gyro and accelerometer axes, from their final
    models: what :func:`exports_from_calibration` writes with the same `horizon`."""
    models, units, intervals = _calibration_axes(calibration)
    return axis_noise(models, units, horizon=horizon, record_seconds=calibration.record_seconds,
                      intervals=intervals)


def _calibration_axes(calibration: Calibration) -> tuple[dict[str, Model], dict[str, str], dict]:
    """Final model, SI unit and physical intervals of each gyro and accelerometer axis."""
    sensors = [a for a in calibration.axes if a.kind in SENSORS]
    if not sensors:
        raise InputError(f"{calibration.source or 'the calibration'} has no gyro or "
                         "accelerometer axis to export")
    units = {a.column: a.unit or SENSORS[a.kind] for a in sensors}
    models = {a.column: a.model for a in sensors}
    intervals = {a.column: _intervals_of(a.details.get("physical"), a.model) for a in sensors}
    return models, units, intervals
