"""A fitted model in datasheet units, beside the Allan-variance reading of the data.

Every physical parameter a family declares (``GMWMResult.physical()``: WN's N, RW's K, GM's
correlation time and sigma, QN's Q ...) carries a unit template in the signal unit ``u``
(``"u*sqrt(s)"``, ``"u/sqrt(s)"``, ``"u"``, ``"s"`` ...).  With the sensor known (a gyroscope
measures rad/s, an accelerometer m/s^2) the template becomes an SI unit whose *dimension* says
what the number is -- an angle random walk, a rate, a rate random walk -- and hence which
datasheet unit it is quoted in (:data:`DATASHEET_UNITS`).  Nothing here names a process family:
the mapping goes through the declared units only.

The per-axis datasheet summary (:class:`Datasheet`) gives, from the fitted model:

- the white-noise density (ARW in deg/sqrt(h); VRW in m/s/sqrt(h) and ug/sqrt(Hz)): the root
  of the summed squares of every component whose physical unit is ``u*sqrt(s)``;
- the bias instability B (deg/h, ug) and the averaging time of the model's Allan minimum:
  ``B = min_tau sigma_A(tau) / sqrt(2 ln 2 / pi)`` on the model's Allan deviation (IEEE 952),
  whatever components make the minimum;
- the rate / acceleration random walk K (deg/h/sqrt(h), m/s/h^1.5): summed over components of
  unit ``u/sqrt(s)``;
- each correlated component's correlation time and sigma,

and beside them the coefficients that :func:`stochmod.allan_reading` reads off the data's Allan
variance by its slopes, in the same units.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import attrs
import numpy as np
from numpy.typing import ArrayLike

from stochmod.core.errors import EstimationError, InputError
from stochmod.fit.gmwm import GMWMResult, ParameterEstimate
from stochmod.core.tables import format_table
from stochmod.empirical.allan_reading import AllanReading, allan_reading
from stochmod.core.units import BI_FACTOR, SENSORS, convert, parse_unit, sensor_unit, si_unit_of

__all__ = [
    "DATASHEET_UNITS",
    "DatasheetParameter",
    "DatasheetRow",
    "Datasheet",
    "datasheet",
    "datasheet_reading",
    "model_allan_minimum",
]

#: Datasheet unit(s) of a quantity by its physical kind (see :attr:`stochmod.core.units.Unit.kind`).
DATASHEET_UNITS: dict[str, tuple[str, ...]] = {
    "angle_random_walk": ("deg/sqrt(h)",),
    "velocity_random_walk": ("m/s/sqrt(h)", "ug/sqrt(Hz)"),
    "rate": ("deg/h",),
    "acceleration": ("ug",),
    "rate_random_walk": ("deg/h/sqrt(h)",),
    "accel_random_walk": ("m/s/h^1.5",),
    "angle": ("arcsec",),
    "velocity": ("m/s",),
    "rate_ramp": ("deg/h^2",),
    "accel_ramp": ("m/s/h^2",),
    "time": ("s",),
    "dimensionless": ("1",),
}

@attrs.frozen
class DatasheetParameter:
    """One physical parameter in SI and in datasheet units.

    Attributes
    ----------
    name : str
        ``label.param`` (``"GM2.Tc"``, ``"WN.N"``).
    kind : str
        Physical kind of the value (``"angle_random_walk"``, ``"rate"``, ``"time"`` ...).
    si, si_low, si_high : float
        Value and 95 % interval in :attr:`si_unit`.
    si_unit : str
        SI unit (``"rad/s*sqrt(s)"``).
    values : dict of str to tuple of float
        Datasheet unit -> (value, low, high).
    """

    name: str
    kind: str
    si: float
    si_low: float
    si_high: float
    si_unit: str
    values: dict[str, tuple[float, float, float]]


@attrs.frozen
class DatasheetRow:
    """One line of the per-axis datasheet summary: the model's value and the data's reading.

    Attributes
    ----------
    quantity : str
        ``"white noise density"``, ``"bias instability"``, ``"random walk"`` ...
    unit : str
        Datasheet unit of both values.
    model : float or None
        From the fitted model (None when the model has no such term).
    low, high : float or None
        Interval of the model value, where one component alone makes it.
    reading : float or None
        From :func:`stochmod.allan_reading` on the data (None when it identified no such term).
    tau : float or None
        Averaging time (s) of the model's Allan minimum (bias instability row only).
    note : str
        E.g. that the minimum lies at the edge of the fitted range.
    """

    quantity: str
    unit: str
    model: float | None
    low: float | None = None
    high: float | None = None
    reading: float | None = None
    tau: float | None = None
    note: str = ""


@attrs.frozen(eq=False)
class Datasheet:
    """A fitted axis in datasheet units (see :func:`datasheet`).

    Attributes
    ----------
    column : str
        Axis name.
    unit : str
        SI signal unit (rad/s or m/s^2).
    freq : float
        Sampling frequency, Hz.
    model : str
        Name of the fitted model.
    parameters : tuple of DatasheetParameter
        Every physical parameter of the fit.
    rows : tuple of DatasheetRow
        The per-axis summary (model beside Allan reading).
    reading : AllanReading or None
        The Allan reading of the data, when the data were given.
    """

    column: str
    unit: str
    freq: float
    model: str
    parameters: tuple[DatasheetParameter, ...]
    rows: tuple[DatasheetRow, ...]
    reading: AllanReading | None = None

    @property
    def sensor(self) -> str:
        """``"gyro"`` or ``"accel"``."""
        return next(k for k, v in SENSORS.items() if v == self.unit)

    def row(self, quantity: str, unit: str | None = None) -> DatasheetRow:
        """The summary row of `quantity` (in `unit` when it has several)."""
        for r in self.rows:
            if r.quantity == quantity and (unit is None or r.unit == unit):
                return r
        raise KeyError(f"no datasheet row {quantity!r}" + (f" in {unit}" if unit else ""))

    def summary_table(self) -> tuple[list[str], list[list[Any]]]:
        """Headers and cells of the summary (``-`` where a value is absent)."""
        rows = [[r.quantity, "-" if r.model is None else r.model, "" if r.low is None else r.low,
                 "" if r.high is None else r.high, "-" if r.reading is None else r.reading,
                 r.unit, "" if r.tau is None else r.tau, r.note] for r in self.rows]
        return (["quantity", "model", "95% low", "95% high", "Allan reading", "unit", "tau [s]",
                 "note"], rows)

    def summary(self) -> str:
        """Two tables: the summary (model beside Allan reading) and every parameter."""
        head = (f"Datasheet of {self.column} ({self.sensor}, {self.model}, "
                f"freq = {self.freq:g} Hz, SI unit {self.unit})")
        summary = format_table(*self.summary_table(), title=head, digits=4)
        prow = []
        for p in self.parameters:
            for unit, (v, lo, hi) in p.values.items():
                prow.append([p.name, p.si, p.si_unit, v, lo, hi, unit])
        params = format_table(["parameter", "SI", "SI unit", "datasheet", "95% low", "95% high",
                               "unit"], prow, digits=5)
        return f"{summary}\n\n{params}"

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe content (non-finite numbers stay floats; use ``to_jsonable``)."""
        return {
            "column": self.column,
            "sensor": self.sensor,
            "unit": self.unit,
            "freq": self.freq,
            "model": self.model,
            "summary": [attrs.asdict(r) for r in self.rows],
            "parameters": [
                {"name": p.name, "kind": p.kind, "si": p.si, "si_low": p.si_low,
                 "si_high": p.si_high, "si_unit": p.si_unit,
                 "datasheet": [{"unit": u, "value": v, "low": lo, "high": hi}
                               for u, (v, lo, hi) in p.values.items()]}
                for p in self.parameters
            ],
        }


def _parameter(est: ParameterEstimate, unit: str) -> DatasheetParameter:
    si_unit = si_unit_of(est.unit, unit)
    kind = parse_unit(si_unit).kind
    values = {}
    for ds in DATASHEET_UNITS.get(kind, ()):
        conv = [float(convert(v, si_unit, ds)) if math.isfinite(v) else v
                for v in (est.value, est.low, est.high)]
        values[ds] = (conv[0], conv[1], conv[2])
    return DatasheetParameter(est.name, kind, float(est.value), float(est.low), float(est.high),
                              si_unit, values)


def _physical(fit: GMWMResult) -> list[ParameterEstimate]:
    """The fit's physical parameters with intervals, or without (NaN) where the fit is not
    identified (a component the wavelet variance does not resolve)."""
    try:
        return fit.physical()
    except EstimationError:
        freq = float(fit.model.freq)
        return [ParameterEstimate(f"{label}.{name}", pv.value, math.nan, math.nan, math.nan, pv.unit)
                for label, proc in zip(fit.model.labels, fit.model.processes)
                for name, pv in proc.physical(freq).items()]


#: Octaves of the model's theoretical AV beyond the fitted range that the spline also runs over.
_SPLINE_EXTRA_OCTAVES = 2


def model_allan_minimum(fit: GMWMResult, points_per_octave: int = 16
                        ) -> tuple[float, float, bool]:
    """Minimum of the fitted model's Allan deviation over the fitted averaging times.

    The model's Allan variance at the dyadic averaging times ``tau_j = 2^(j-1) / freq`` is twice
    its Haar wavelet variance (exact, levels 1..J of the fit); between them it is interpolated
    by a cubic spline of log AV in log tau (a sum of power laws is smooth there). The spline
    runs over two more octaves of the model's theoretical AV than the fitted range, so that its
    end conditions do not bend the curve where a minimum near the last fitted tau is read.

    Returns
    -------
    tau : float
        Averaging time of the minimum, s.
    adev : float
        Allan deviation at the minimum, signal unit.
    edge : bool
        True when the minimum lies at the first or last fitted tau (the curve has no interior
        minimum in the range: the value bounds the bias instability, it does not measure it).
    """
    J = int(fit.levels)
    freq = float(fit.model.freq)
    tau = 2.0 ** np.arange(J) / freq
    av = 2.0 * fit.model.wv(J)
    if not np.all(np.isfinite(av) & (av > 0)):
        raise EstimationError("the fitted model's Allan variance is not positive at every level")
    if J < 3:
        k = int(np.argmin(av))
        return float(tau[k]), float(np.sqrt(av[k])), k in (0, J - 1)
    extra = _SPLINE_EXTRA_OCTAVES
    tau_ext = 2.0 ** np.arange(J + extra) / freq
    av_ext = 2.0 * fit.model.wv(J + extra)
    if not np.all(np.isfinite(av_ext) & (av_ext > 0)):
        tau_ext, av_ext = tau, av  # the theory beyond the fitted range is unusable: fitted range only
    from scipy.interpolate import CubicSpline  # on first use: not on every command's start

    spline = CubicSpline(np.log(tau_ext), np.log(av_ext))
    grid = np.linspace(np.log(tau[0]), np.log(tau[-1]), (J - 1) * points_per_octave + 1)
    values = spline(grid)
    k = int(np.argmin(values))
    return float(np.exp(grid[k])), float(np.exp(0.5 * values[k])), k in (0, grid.size - 1)


def _combined(params: Sequence[DatasheetParameter], kind: str, unit: str
              ) -> tuple[float | None, float | None, float | None]:
    """Root sum of squares of the parameters of `kind` in `unit`, with the interval of a
    single contributing parameter (None for several: their errors are correlated)."""
    vals = [p.values[unit] for p in params if p.kind == kind and unit in p.values]
    if not vals:
        return None, None, None
    if len(vals) == 1:
        return vals[0]
    return math.sqrt(sum(v[0] ** 2 for v in vals)), None, None


def _reading_value(reading: AllanReading | None, name: str, unit: str, sensor_si: str
                   ) -> float | None:
    if reading is None:
        return None
    coef = reading.coefficients.get(name)
    if coef is None:
        return None
    from stochmod.empirical.allan_reading import TERMS

    return float(convert(coef.value, si_unit_of(TERMS[name][2], sensor_si), unit))


def _rows(fit: GMWMResult, params: tuple[DatasheetParameter, ...], unit: str,
          reading: AllanReading | None) -> list[DatasheetRow]:
    gyro = unit == SENSORS["gyro"]
    white = "angle_random_walk" if gyro else "velocity_random_walk"
    walk = "rate_random_walk" if gyro else "accel_random_walk"
    level = "rate" if gyro else "acceleration"
    rows = []
    for ds in DATASHEET_UNITS[white]:
        v, lo, hi = _combined(params, white, ds)
        rows.append(DatasheetRow("white noise density (ARW)" if gyro else
                                 "white noise density (VRW)", ds, v, lo, hi,
                                 _reading_value(reading, "N", ds, unit)))
    tau, adev, edge = model_allan_minimum(fit)
    ds = DATASHEET_UNITS[level][0]
    b = float(convert(adev / BI_FACTOR, unit, ds))
    note = "minimum at the edge of the fitted taus: a bound" if edge else ""
    rows.append(DatasheetRow("bias instability", ds, b, reading=_reading_value(reading, "B", ds, unit),
                             tau=tau, note=note))
    ds = DATASHEET_UNITS[walk][0]
    v, lo, hi = _combined(params, walk, ds)
    rows.append(DatasheetRow("rate random walk" if gyro else "acceleration random walk", ds,
                             v, lo, hi, _reading_value(reading, "K", ds, unit)))
    by_label: dict[str, dict[str, DatasheetParameter]] = {}
    for p in params:
        label, _, pname = p.name.rpartition(".")
        by_label.setdefault(label, {})[p.kind] = p
    for label, kinds in by_label.items():
        if "time" in kinds and level in kinds:  # a correlated component: Tc and sigma
            tc, sig = kinds["time"], kinds[level]
            rows.append(DatasheetRow(f"{label} correlation time", "s", tc.si, tc.si_low, tc.si_high))
            rows.append(DatasheetRow(f"{label} sigma", DATASHEET_UNITS[level][0],
                                     *sig.values[DATASHEET_UNITS[level][0]]))
    return rows


def datasheet_reading(x: ArrayLike, freq: float, sensor: str) -> AllanReading:
    """The Allan reading of an axis's data that :func:`datasheet` sets beside the model (the
    data's part of a datasheet, which a fleet computes in the axis's own task).

    Parameters
    ----------
    x : array_like, shape (N,)
        The axis's data, in SI (rad/s or m/s^2).
    freq : float
        Sampling frequency, Hz.
    sensor : {"gyro", "accel"} or unit
        What the axis measures.
    """
    return allan_reading(x, freq, unit=sensor_unit(sensor))


def datasheet(fit: GMWMResult, sensor: str, *, column: str = "", x: ArrayLike | None = None,
              reading: AllanReading | None = None) -> Datasheet:
    """A fitted axis in SI and datasheet units, beside the Allan reading of its data.

    Parameters
    ----------
    fit : GMWMResult
        The fit of one axis (e.g. ``select(...).best``), signal in SI (rad/s or m/s^2).
    sensor : {"gyro", "accel"} or unit
        What the axis measures (``"rad/s"`` and ``"m/s^2"`` are accepted too).
    column : str
        Axis name for the report.
    x : array_like, optional
        The axis's data (same unit as the fit); :func:`stochmod.allan_reading` reads it.
    reading : AllanReading, optional
        An Allan reading already made (instead of `x`).

    Returns
    -------
    Datasheet
        Intervals are NaN where the fit is not identified.

    Raises
    ------
    InputError
        Unknown sensor kind, or both `x` and `reading` given.
    """
    unit = sensor_unit(sensor)
    if x is not None and reading is not None:
        raise InputError("give the data x or an Allan reading, not both")
    if x is not None:
        reading = datasheet_reading(x, float(fit.model.freq), unit)
    params = tuple(_parameter(e, unit) for e in _physical(fit))
    rows = _rows(fit, params, unit, reading)
    return Datasheet(column=column, unit=unit, freq=float(fit.model.freq), model=fit.model.name,
                     parameters=params, rows=tuple(rows), reading=reading)
