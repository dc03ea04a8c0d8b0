"""What each column of a recording measures and in which unit: declared, checked, never assumed.

A column's **sensor kind** (``"gyro"``, ``"accel"`` or ``"other"``) comes from the file (an
npz ``sensor`` array, a bag or ULog message type), else from its name (``gyro_x``, ``acc_z``),
else from the dimension of its unit (a rate is a gyro, an acceleration an accelerometer). Its
**unit** comes from the file (a CSV header ``name [unit]``, an npz ``units`` entry) or from the
user: one unit for every column of a one-sensor file, one per sensor kind, or one per column
(:func:`declare_units`). A unit whose dimension contradicts the kind is refused; a column
without a unit is refused unless SI is assumed explicitly, and then the assumption is recorded.

:func:`check_static_magnitudes` catches the common slips on a static recording once it is in
SI: an accelerometer triad in g read as m/s^2 (its mean specific force is g), a gyro in deg/s
read as rad/s (a static gyro's mean rate and noise are far below 1 rad/s).
"""

from __future__ import annotations

from collections.abc import Sequence

import attrs
import numpy as np

from stochmod.core.errors import InputError
from stochmod.core.units import SENSORS, STANDARD_GRAVITY, kind_from_name, parse_unit

__all__ = ["KINDS", "UNIT_SOURCES", "ColumnUnit", "sensor_kind", "declare_units",
           "check_static_magnitudes", "GYRO_RATE_LIMIT",
           "RAW_MEAN_RATIO"]

#: Sensor kinds of a column.
KINDS = ("gyro", "accel", "other")
#: Where a column's unit comes from.
UNIT_SOURCES = ("file", "option", "assumed")
#: A static gyro's mean rate and its noise (rms) stay below this, rad/s (11.5 deg/s): far above
#: Earth's rate and any MEMS turn-on bias, far below the same signal read in deg/s as rad/s.
GYRO_RATE_LIMIT = 0.2
#: |mean specific force| over the largest rms of the triad's columns above which a record is
#: raw (gravity in it) rather than an error signal whose mean was removed.
RAW_MEAN_RATIO = 20.0
#: Unit dimension (:attr:`stochmod.core.units.Unit.kind`) of each sensor kind.
_DIMENSION = {"gyro": "rate", "accel": "acceleration"}
_FILE_KINDS = {"gyroscope": "gyro", "gyro": "gyro", "accelerometer": "accel", "accel": "accel"}


@attrs.frozen
class ColumnUnit:
    """The declared unit of one column.

    Attributes
    ----------
    column : str
    kind : {"gyro", "accel", "other"}
    unit : str or None
        The unit the samples are in (``"deg/s"``); None for an ``"other"`` column of unknown
        unit.
    source : {"file", "option", "assumed"}
        Where the unit comes from; ``"assumed"`` is SI taken on the user's word
        (``--assume-si``).
    """

    column: str
    kind: str
    unit: str | None
    source: str

    def to_dict(self) -> dict[str, str | None]:
        return {"kind": self.kind, "unit": self.unit, "source": self.source}


def sensor_kind(column: str, unit: str | None = None, hint: str | None = None) -> str:
    """The sensor kind of a column: from the file's `hint` (``"Gyroscope"``), else the
    column's name, else the dimension of `unit`, else ``"other"``."""
    if hint is not None and hint.strip().lower() in _FILE_KINDS:
        return _FILE_KINDS[hint.strip().lower()]
    named = kind_from_name(column)
    if named is not None:
        return named
    if unit is not None:
        try:
            dimension = parse_unit(unit).kind
        except InputError:
            dimension = ""
        for kind, dim in _DIMENSION.items():
            if dimension == dim:
                return kind
    return "other"


def _parse_column_units(entries: Sequence[str], columns: Sequence[str]
                        ) -> tuple[str | None, dict[str, str]]:
    """``--unit`` entries: one bare ``UNIT`` (every column) and/or ``COLUMN=UNIT`` pairs."""
    every, per_column = None, {}
    for entry in entries:
        name, sep, unit = entry.partition("=")
        if not sep:
            if every is not None:
                raise InputError(f"--unit {every} and --unit {entry}: a unit for every column is "
                                 "given once; name the columns (--unit COLUMN=UNIT)")
            every = entry.strip()
            continue
        name, unit = name.strip(), unit.strip()
        if name not in columns:
            raise InputError(f"--unit {entry}: no column {name!r}; the columns are "
                             f"{list(columns)}")
        per_column[name] = unit
    return every, per_column


def declare_units(columns: Sequence[str], file_units: Sequence[str | None] | None = None,
                  file_kinds: Sequence[str | None] | None = None, *,
                  unit: Sequence[str] | str | None = None, gyro_unit: str | None = None,
                  accel_unit: str | None = None, assume_si: bool = False,
                  required: bool = True) -> tuple[ColumnUnit, ...]:
    """Each column's sensor kind and unit, from the file and the user's options.

    Parameters
    ----------
    columns : sequence of str
        Column names.
    file_units, file_kinds : sequence of (str or None), optional
        What the file says, per column (units; sensor kinds such as ``"Gyroscope"``).
    unit : str or sequence of str, optional
        ``--unit`` entries: ``"UNIT"`` for every column (a one-sensor file only) and/or
        ``"COLUMN=UNIT"``.
    gyro_unit, accel_unit : str, optional
        The unit of every gyro (accelerometer) column.
    assume_si : bool
        Take the SI unit of its kind for a gyro or accelerometer column whose unit nobody gave.
    required : bool
        Whether a gyro or accelerometer column without a unit is an error (else its unit is
        None).

    Returns
    -------
    tuple of ColumnUnit
        Per column; the options override the file (per column over per kind over every
        column).

    Raises
    ------
    InputError
        A unit that does not parse, whose dimension contradicts the column's kind, a bare
        ``--unit`` on a file with gyro and accelerometer columns, or (when `required`) a gyro
        or accelerometer column without a unit and without `assume_si`.
    """
    n = len(columns)
    file_units = list(file_units) if file_units is not None else [None] * n
    file_kinds = list(file_kinds) if file_kinds is not None else [None] * n
    entries = [unit] if isinstance(unit, str) else list(unit or ())
    every, per_column = _parse_column_units(entries, columns)
    if every is not None:
        kinds = {sensor_kind(c, per_column.get(c) or u, k)
                 for c, u, k in zip(columns, file_units, file_kinds)} & set(SENSORS)
        if len(kinds) > 1:
            raise InputError(f"--unit {every} would apply to gyro and accelerometer columns "
                             "alike: give --gyro-unit and --accel-unit, or --unit COLUMN=UNIT")
    out = []
    for column, f_unit, f_kind in zip(columns, file_units, file_kinds):
        given = per_column.get(column)
        kind = sensor_kind(column, given or f_unit, f_kind)
        by_kind = {"gyro": gyro_unit, "accel": accel_unit}.get(kind)
        for value, source in ((given, "option"), (by_kind, "option"), (every, "option"),
                              (f_unit, "file")):
            if value:
                chosen, origin = value, source
                break
        else:
            chosen, origin = None, None
        if chosen is not None:
            _check_dimension(column, kind, chosen, origin)
        elif kind in SENSORS and assume_si:
            chosen, origin = SENSORS[kind], "assumed"
        elif kind in SENSORS and required:
            raise InputError(
                f"the unit of column {column!r} ({kind}) is not known: give it with "
                f"--{kind}-unit UNIT or --unit {column}=UNIT (e.g. deg/s, rad/s, g, m/s^2), "
                "or --assume-si to take SI on your word")
        out.append(ColumnUnit(column, kind, chosen, origin or "file"))
    return tuple(out)


def _check_dimension(column: str, kind: str, unit: str, source: str) -> None:
    try:
        dimension = parse_unit(unit).kind
    except InputError as exc:
        where = "the option" if source == "option" else "the file"
        raise InputError(f"column {column!r}: {where} gives the unit {unit!r}, which is not a "
                         f"unit stochmod knows ({exc})") from None
    wanted = _DIMENSION.get(kind)
    if wanted is not None and dimension != wanted:
        what = "a rate" if kind == "gyro" else "an acceleration"
        raise InputError(f"column {column!r} is {'a gyro' if kind == 'gyro' else 'an accel'} "
                         f"(from its name or the file), but its unit {unit!r} is not {what}: "
                         f"give the right unit (--unit {column}=UNIT)")


def check_static_magnitudes(data: np.ndarray, declared: Sequence[ColumnUnit]) -> None:
    """Refuse a static recording, in SI, whose magnitudes betray a wrong unit.

    An accelerometer triad (three accel columns) at rest measures ``|mean f| = g``: a norm
    near 1 is g read as m/s^2, near 1000 mg read as m/s^2. The check applies where the mean
    stands above :data:`RAW_MEAN_RATIO` times the noise (rms), as gravity does in a raw record;
    an error signal (its mean removed beforehand) is not refused for it, and its noise (rms)
    must still stay below g. A gyro's mean rate and its noise (rms) stay below
    :data:`GYRO_RATE_LIMIT`; above it, the data are most likely deg/s read as rad/s.

    Parameters
    ----------
    data : ndarray, shape (n, k)
        The samples in SI (rad/s, m/s^2).
    declared : sequence of ColumnUnit
        The columns' kinds and units (:func:`declare_units`), in the order of `data`'s columns.

    Raises
    ------
    InputError
        Naming the column(s), what was found and the likely unit.
    """
    g = STANDARD_GRAVITY
    accel = [k for k, c in enumerate(declared) if c.kind == "accel"]
    sensors = [k for k, c in enumerate(declared) if c.kind in ("gyro", "accel")]
    if not sensors:
        return
    means, rms = np.zeros(len(declared)), np.zeros(len(declared))
    means[sensors], rms[sensors] = _column_moments(np.asarray(data), sensors)
    for k, c in enumerate(declared):
        if c.kind == "gyro" and max(abs(means[k]), rms[k]) > GYRO_RATE_LIMIT:
            raise InputError(
                f"gyro column {c.column!r} (unit {c.unit}, {c.source}) has a mean rate of "
                f"{abs(means[k]):.3g} rad/s and noise of {rms[k]:.3g} rad/s rms: a static gyro "
                f"stays far below {GYRO_RATE_LIMIT} rad/s; the data look like deg/s: "
                f"--gyro-unit deg/s (or --unit {c.column}=deg/s)")
    if len(accel) == 3:
        norm = float(np.linalg.norm(means[accel]))
        spread = float(np.max(rms[accel]))
        names = ", ".join(declared[k].column for k in accel)
        # gravity stands far above the noise in a raw record; an error signal's mean does not
        if norm > RAW_MEAN_RATIO * spread and not 0.5 * g <= norm <= 1.5 * g:
            likely = ("g" if 0.5 <= norm <= 1.5 else "mg" if 500 <= norm <= 1500
                      else "a unit that is not the one given")
            raise InputError(
                f"the accelerometer triad ({names}) measures a mean specific force of "
                f"{norm:.4g} m/s^2 at rest, not g = {g} m/s^2: the data look like {likely}: "
                f"--accel-unit {likely if likely in ('g', 'mg') else 'UNIT'} (or, for an error "
                f"signal whose bias stands {norm / spread:.3g} times above its noise, remove its "
                "mean first)")
    for k in accel:
        if rms[k] > g:
            raise InputError(
                f"accelerometer column {declared[k].column!r} has noise of {rms[k]:.3g} m/s^2 "
                "rms at rest, above g: its unit is not the one given (--accel-unit UNIT)")


#: Rows per block of :func:`_column_moments` (a block of six float64 columns stays in cache).
_MOMENT_ROWS = 1 << 15


def _column_moments(data: np.ndarray, columns: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard deviation (ddof 0) of the `columns` of `data` (shape (n, k)), in two
    passes over blocks of rows: no temporary of the columns' size, which for a long record
    would be hundreds of MB beside it."""
    n, cols = data.shape[0], list(columns)
    total = np.zeros(len(cols))
    for i in range(0, n, _MOMENT_ROWS):
        total += data[i : i + _MOMENT_ROWS, cols].sum(axis=0)
    mean = total / n
    squares = np.zeros(len(cols))
    for i in range(0, n, _MOMENT_ROWS):
        d = data[i : i + _MOMENT_ROWS, cols] - mean
        squares += np.einsum("ij,ij->j", d, d)
    return mean, np.sqrt(squares / n)

