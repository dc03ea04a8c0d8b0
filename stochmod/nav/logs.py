"""Readers for the inputs of ``stochmod navigate``: an IMU CSV and a GNSS CSV.

Both files have a header line; names are matched case-insensitively and surrounding spaces
are ignored. Every problem (missing or unknown column, NaN, time not strictly increasing,
latitude out of range, non-positive standard deviation) raises
:class:`~stochmod.core.errors.InputError` naming the file, the column and the row.

IMU file, one of two layouts (body x forward / y right / z down, with respect to inertial
space)::

    time, gyro_x, gyro_y, gyro_z, accel_x, accel_y, accel_z       # rates: rad/s, m/s^2
    time, dtheta_x, dtheta_y, dtheta_z, dv_x, dv_y, dv_z          # increments: rad, m/s

Increments are over the interval that ENDS at ``time``. GNSS file::

    time, lat, lon, height[, vn, ve, vd][, sd_n, sd_e, sd_d]      # s, deg, deg, m, m/s, m

with ellipsoidal height; velocity (NED) and the position standard deviations (NED) are used
when present, and come as complete triples. A header cell may give a column's unit
(``gyro_x [deg/s]``, ``accel_z [g]``, ``lat [rad]``, ``height [mm]``): it is converted to the
unit above, and one of another dimension is refused. The magnitudes are checked as a vehicle
shows them: a median specific force near g and a median rate below 1 rad/s (accelerometers in
g or gyros in deg/s read as SI are named), heights below 100 km, and fixes that move as far as
the GNSS velocity says when it is given (latitudes and longitudes in radians are named). The
readers return the records the filter takes (:class:`stochmod.nav.records.ImuData`,
:class:`~stochmod.nav.records.GnssData`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from stochmod.core.errors import InputError
from stochmod.core.model import Model
from stochmod.core.units import SENSORS, STANDARD_GRAVITY, parse_unit
from stochmod.io.calibration import Calibration
from stochmod.io.recording import read_with
from stochmod.nav.emulate import AXES
from stochmod.nav.records import GnssData, ImuData

__all__ = [
    "GNSS_COLUMNS",
    "IMU_COLUMNS",
    "calibration_record",
    "read_calibration",
    "read_gnss_csv",
    "read_imu_csv",
]

IMU_COLUMNS: dict[str, tuple[str, ...]] = {
    "rate": ("time", "gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"),
    "increment": ("time", "dtheta_x", "dtheta_y", "dtheta_z", "dv_x", "dv_y", "dv_z"),
}
"""The two IMU layouts, by ``kind``."""

GNSS_COLUMNS: dict[str, tuple[str, ...]] = {
    "position": ("time", "lat", "lon", "height"),
    "velocity": ("vn", "ve", "vd"),
    "sd": ("sd_n", "sd_e", "sd_d"),
}
"""GNSS columns: the required position block and the optional velocity and sd triples."""


def _read_table(path: str | Path) -> tuple[Path, dict[str, np.ndarray]]:
    """Read a headed CSV into ``{lower-case name: column}`` (NaN checked per column later),
    through the registered ``csv`` reader (the time column is the one it finds by name)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"no such file: {path}")
    rec = read_with(path, "csv")  # its samples and time are checked below, per column
    if all(name.isdigit() for name in rec.columns):
        raise InputError(f"{path} has no header line; the first line must name the columns")
    keys = [name.strip().lower() for name in rec.columns]
    repeated = sorted({k for k in keys if keys.count(k) > 1 or k == "time"})
    if repeated:
        raise InputError(f"{path}: column(s) {repeated} appear more than once "
                         "(names are case-insensitive)")
    units = rec.units or (None,) * len(keys)
    table = {k: _in_file_unit(path, k, rec.data[:, i], u)
             for i, (k, u) in enumerate(zip(keys, units))}
    if rec.time is not None:
        table = {"time": rec.time + rec.time_origin, **table}
    return path, table


#: Dimension and unit each column is read in: a header unit (``gyro_x [deg/s]``) of that
#: dimension is converted to it, one of another dimension is refused.
_COLUMN_UNITS: dict[str, tuple[str, str]] = {
    **{f"gyro_{a}": ("rate", "rad/s") for a in "xyz"},
    **{f"accel_{a}": ("acceleration", "m/s^2") for a in "xyz"},
    **{f"dtheta_{a}": ("angle", "rad") for a in "xyz"},
    **{f"dv_{a}": ("velocity", "m/s") for a in "xyz"},
    "lat": ("angle", "deg"), "lon": ("angle", "deg"), "height": ("length", "m"),
    **{f"v{a}": ("velocity", "m/s") for a in "ned"},
    **{f"sd_{a}": ("length", "m") for a in "ned"},
}


def _in_file_unit(path: Path, key: str, values: np.ndarray, unit: str | None) -> np.ndarray:
    """`values` of column `key` in the unit the filter reads it in, from its header `unit`."""
    if unit is None or key not in _COLUMN_UNITS:
        return values
    dimension, target = _COLUMN_UNITS[key]
    parsed = parse_unit(unit)
    if parsed.kind != dimension:
        raise InputError(f"{path}: column {key!r} is read as {dimension} ({target}), but its "
                         f"header gives the unit {unit!r}")
    return values * (parsed.scale / parse_unit(target).scale)


def _check_columns(path: Path, table: dict[str, np.ndarray], allowed: tuple[str, ...]) -> None:
    unknown = [k for k in table if k not in allowed]
    if unknown:
        raise InputError(
            f"{path}: unknown column(s) {unknown}; the accepted columns are {list(allowed)}"
        )


def _column(path: Path, table: dict[str, np.ndarray], name: str) -> np.ndarray:
    values = table[name]
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        raise InputError(
            f"{path}: column {name!r} has {bad.size} non-finite value(s), the first in data row "
            f"{bad[0] + 1} ({float(values[bad[0]])}); fill or cut the gap explicitly"
        )
    return values


def _time(path: Path, table: dict[str, np.ndarray]) -> np.ndarray:
    time = _column(path, table, "time")
    if time.size < 2:
        raise InputError(f"{path} has {time.size} data row(s); at least 2 are needed")
    step = np.diff(time)
    bad = np.flatnonzero(step <= 0)
    if bad.size:
        i = bad[0]
        raise InputError(
            f"{path}: time is not strictly increasing: data row {i + 2} has time "
            f"{float(time[i + 1])} "
            f"after {float(time[i])} in row {i + 1} ({bad.size} such step(s))"
        )
    return time


def _triple(path: Path, table: dict[str, np.ndarray], names: tuple[str, ...], *,
            required: bool) -> np.ndarray | None:
    present = [n for n in names if n in table]
    if not present and not required:
        return None
    missing = [n for n in names if n not in table]
    if missing:
        raise InputError(
            f"{path}: missing column(s) {missing}; {list(names)} come together "
            f"(found {present})"
        )
    return np.column_stack([_column(path, table, n) for n in names])


def read_imu_csv(path: str | Path) -> ImuData:
    """Read an IMU CSV (rates or increments, told apart by the header).

    Parameters
    ----------
    path : str or Path
        CSV with header ``time, gyro_x, gyro_y, gyro_z, accel_x, accel_y, accel_z`` (rad/s,
        m/s^2) or ``time, dtheta_x, dtheta_y, dtheta_z, dv_x, dv_y, dv_z`` (rad, m/s over the
        interval ending at ``time``); case-insensitive, any column order.

    Returns
    -------
    ImuData

    Raises
    ------
    InputError
        No header, a mix of the two layouts, missing or unknown columns, NaN/inf, time not
        strictly increasing, fewer than two rows.
    """
    path, table = _read_table(path)
    kinds = [k for k, cols in IMU_COLUMNS.items() if any(c in table for c in cols[1:])]
    if len(kinds) != 1:
        raise InputError(
            f"{path}: the header must name either {list(IMU_COLUMNS['rate'])} (rates) or "
            f"{list(IMU_COLUMNS['increment'])} (increments); found {list(table)}"
        )
    kind = kinds[0]
    cols = IMU_COLUMNS[kind]
    _check_columns(path, table, cols)
    if "time" not in table:
        raise InputError(f"{path}: missing column 'time'")
    time = _time(path, table)
    gyro = _triple(path, table, cols[1:4], required=True)
    accel = _triple(path, table, cols[4:7], required=True)
    if kind == "increment":  # the magnitudes of the rates they integrate
        step = np.diff(time, prepend=2 * time[0] - time[1])[:, None]
        _check_imu_magnitudes(path, gyro / step, accel / step, "increments")
    else:
        _check_imu_magnitudes(path, gyro, accel, "rates")
    return ImuData(time=time, gyro=gyro, accel=accel, kind=kind)  # type: ignore[arg-type]


#: A vehicle's median angular rate stays below this, rad/s (57 deg/s).
NAV_RATE_LIMIT = 1.0


def _check_imu_magnitudes(path: Path, rate: np.ndarray, force: np.ndarray, layout: str) -> None:
    """Refuse an IMU log whose magnitudes betray a unit other than rad/s and m/s^2: the median
    specific force of a vehicle is near g (it rests or moves at fractions of g), its median
    rate far below 1 rad/s."""
    g = STANDARD_GRAVITY
    f = float(np.median(np.linalg.norm(force, axis=1)))
    if not 0.5 * g <= f <= 1.5 * g:
        likely = "g" if 0.5 <= f <= 1.5 else "mg" if 500 <= f <= 1500 else None
        hint = (f"the accelerometers look like {likely}: give the unit in the header "
                f"(accel_x [{likely}])" if likely else "check the accelerometers' unit")
        raise InputError(f"{path}: the median specific force of the {layout} is {f:.4g} m/s^2, "
                         f"not near g = {g} m/s^2: {hint}")
    w = float(np.median(np.linalg.norm(rate, axis=1)))
    if w > NAV_RATE_LIMIT:
        raise InputError(f"{path}: the median angular rate of the {layout} is {w:.3g} rad/s, "
                         f"above {NAV_RATE_LIMIT} rad/s: the gyros look like deg/s; give the "
                         "unit in the header (gyro_x [deg/s])")


def read_gnss_csv(path: str | Path) -> GnssData:
    """Read a GNSS CSV of position fixes with optional velocity and standard deviations.

    Parameters
    ----------
    path : str or Path
        CSV with header ``time, lat, lon, height`` (s, deg, deg, m ellipsoidal), optionally
        ``vn, ve, vd`` (m/s) and ``sd_n, sd_e, sd_d`` (m); case-insensitive, any order.

    Returns
    -------
    GnssData

    Raises
    ------
    InputError
        No header, missing or unknown columns, an incomplete triple, NaN/inf, time not strictly
        increasing, latitude outside [-90, 90] deg, a standard deviation that is not positive.
    """
    path, table = _read_table(path)
    allowed = GNSS_COLUMNS["position"] + GNSS_COLUMNS["velocity"] + GNSS_COLUMNS["sd"]
    _check_columns(path, table, allowed)
    missing = [c for c in GNSS_COLUMNS["position"] if c not in table]
    if missing:
        raise InputError(f"{path}: missing column(s) {missing}; found {list(table)}")
    time = _time(path, table)
    lat = _column(path, table, "lat")
    outside = np.flatnonzero(np.abs(lat) > 90.0)
    if outside.size:
        raise InputError(
            f"{path}: lat must be in [-90, 90] deg; data row {outside[0] + 1} has "
            f"{float(lat[outside[0]])}"
        )
    lon = _column(path, table, "lon")
    if np.any(np.abs(lon) > 360.0):
        row = int(np.flatnonzero(np.abs(lon) > 360.0)[0])
        raise InputError(f"{path}: lon must be in [-180, 360] deg; data row {row + 1} has "
                         f"{float(lon[row])}")
    height = _column(path, table, "height")
    if np.any(np.abs(height) > HEIGHT_LIMIT):
        row = int(np.flatnonzero(np.abs(height) > HEIGHT_LIMIT)[0])
        raise InputError(f"{path}: height {float(height[row])} m in data row {row + 1} is beyond "
                         f"{HEIGHT_LIMIT:g} m: is it in mm? give the unit in the header "
                         "(height [mm])")
    vel = _triple(path, table, GNSS_COLUMNS["velocity"], required=False)
    if vel is not None:
        _check_positions_against_velocity(path, time, lat, lon, vel)
    sd = _triple(path, table, GNSS_COLUMNS["sd"], required=False)
    if sd is not None and np.any(sd <= 0):
        row, col = np.argwhere(sd <= 0)[0]
        raise InputError(
            f"{path}: {GNSS_COLUMNS['sd'][col]} must be positive (m); data row {row + 1} has "
            f"{float(sd[row, col])}"
        )
    return GnssData(time=time, lat=lat, lon=lon, height=height, vel_ned=vel, sd=sd)


#: Largest ellipsoidal height of a GNSS fix taken as metres.
HEIGHT_LIMIT = 1e5


def _check_positions_against_velocity(path: Path, time: np.ndarray, lat: np.ndarray,
                                      lon: np.ndarray, vel: np.ndarray) -> None:
    """Refuse latitudes and longitudes in radians: the distance between fixes, read in degrees,
    must match the GNSS velocity over the same interval (where the vehicle moves)."""
    radius = 6.371e6
    dlat = np.radians(np.diff(lat))
    dlon = np.radians(np.diff(lon)) * np.cos(np.radians(lat[1:]))
    moved = radius * np.hypot(dlat, dlon)
    speed = np.hypot(vel[1:, 0] + vel[:-1, 0], vel[1:, 1] + vel[:-1, 1]) / 2.0
    step = np.diff(time)
    moving = speed * step > 1.0  # at least a metre between fixes by the velocity
    if np.count_nonzero(moving) < 5:
        return
    ratio = float(np.median(moved[moving] / (speed[moving] * step[moving])))
    if ratio < 0.1:
        raise InputError(f"{path}: the fixes move {ratio:.3g} times as far as the GNSS velocity "
                         "says (lat/lon read in degrees): lat and lon look like radians; give "
                         "them in degrees or with their unit in the header (lat [rad])")


def read_calibration(path: str | Path) -> dict[str, Model]:
    """Per-axis final error models of a calibration file
    (:class:`stochmod.io.calibration.Calibration`, written by ``stochmod calibrate``).

    Parameters
    ----------
    path : str or Path
        The JSON file; its columns named ``gyro_x ... accel_z`` (case-insensitive) give each
        axis's final model (rad/s and m/s^2 units), bound to the file's ``freq``.

    Returns
    -------
    dict of str to Model
        Keys ``gyro_x ... accel_z``.

    Raises
    ------
    InputError
        Missing or unreadable file, a schema this stochmod does not read, missing axes, an
        axis given twice, a model that cannot be built (the message names the axis), a gyro
        or accelerometer axis whose unit is not SI.
    """
    path = Path(path)
    calibration = Calibration.read(path)
    by_axis: dict[str, Model] = {}
    for axis in calibration.axes:
        key = axis.column.strip().lower()
        if key in by_axis:
            raise InputError(f"{path}: axis {key!r} appears more than once (case-insensitive)")
        wanted = SENSORS.get(axis.kind)
        if wanted is not None and axis.unit not in (None, wanted):
            raise InputError(f"{path}: the model of {axis.column!r} is in {axis.unit}, not "
                             f"{wanted}: the navigation filter needs SI models")
        by_axis[key] = axis.model
    missing = [a for a in AXES if a not in by_axis]
    if missing:
        raise InputError(f"{path}: calibration has no column(s) {missing}; the navigation "
                         f"filter needs a model for each of {list(AXES)}")
    return {axis: by_axis[axis] for axis in AXES}


def calibration_record(path: str | Path) -> float | None:
    """Length (s) of the longest single record a calibration file was fitted on
    (:attr:`stochmod.io.calibration.Calibration.record_seconds`: segments of ``--split-gaps``
    and replicates of ``--pooled`` count one by one, each resolving correlation times only up
    to its own length). None when the file does not say (no sample count)."""
    calibration = Calibration.read(path)
    return calibration.record_seconds if calibration.n > 0 else None
