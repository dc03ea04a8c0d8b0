"""The calibration file: a sensor's final noise model per axis, and how it was made.

:class:`Calibration` is what :func:`stochmod.calibrate` returns and the one format that
``stochmod calibrate`` writes (``calibration.json``) and ``navigate``, ``outages`` and the
exports read. Its JSON carries a ``"schema"`` version (:data:`SCHEMA`); files without one are
version 1 (their ``model`` is read both as the final and the fitted model), a newer version
is refused with a message that names it.

Per axis the file holds the **final** model (``model``: what the tables, datasheet,
augmentation, exports and the navigation filter use, :func:`stochmod.fit.equivalence.
replace_equivalents`) and the model as **fitted** (``fitted``), the replacements that lead
from one to the other, and the selection's details (parameters with intervals, J-test,
verdict, ranking, datasheet).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar

import attrs

from stochmod.core.errors import InputError, StochmodError
from stochmod.core.jsonable import to_jsonable
from stochmod.core.model import AxesAugmentation, Model, augment_axes
from stochmod.core.tables import format_table
from stochmod.io.sensors import KINDS, sensor_kind
from stochmod.plugin.spec import model_from_spec

__all__ = ["SCHEMA", "AxisCalibration", "Calibration"]

#: Version of the calibration file this stochmod writes, and the newest it reads.
SCHEMA = 2


def _frozen_dict(value: Mapping[str, Any] | None) -> dict[str, Any]:
    return dict(value or {})


def _replacements(value: Any) -> tuple[dict[str, Any], ...]:
    """The replacements in their JSON form (so that a calibration read back compares equal)."""
    return tuple(to_jsonable(dict(r)) for r in value)


@attrs.frozen
class AxisCalibration:
    """One axis of a calibration.

    Attributes
    ----------
    column : str
        The column's name in the recording.
    kind : {"gyro", "accel", "other"}
        What it measures.
    unit : str or None
        The SI unit of the models' signal (``"rad/s"``, ``"m/s^2"``); None when unknown.
    model : Model
        The final model, bound to the sampling frequency (per-sample parameters in `unit`).
    fitted : Model
        The model as fitted (the final model with equivalent components not yet replaced).
    replacements : tuple of dict
        Each replaced component: ``component``, ``tc`` (s), ``term``, ``sigma2`` (u^2),
        ``wv_change`` (relative, levels 1-3).
    details : dict
        JSON-safe results of the selection (``parameters``, ``physical``, ``jtest``,
        ``verdict``, ``ranking``, ``criterion``, ``weighting``, ``datasheet`` ...).
    """

    column: str
    kind: str = attrs.field(validator=attrs.validators.in_(KINDS))
    unit: str | None
    model: Model
    fitted: Model
    replacements: tuple[dict[str, Any], ...] = attrs.field(default=(), converter=_replacements)
    details: dict[str, Any] = attrs.field(factory=dict, converter=_frozen_dict, eq=False,
                                          repr=False)

    def __attrs_post_init__(self) -> None:
        if self.model.freq is None or self.fitted.freq is None:
            raise InputError(f"calibration of {self.column!r}: its models must be bound to the "
                             "sampling frequency (Model.bind(freq))")

    def to_dict(self, dt: float) -> dict[str, Any]:
        """The axis's JSON entry, with its augmentation at the filter step `dt` (s)."""
        block = self.model.augment(dt)
        return {**self.details, "kind": self.kind, "unit": self.unit,
                "name": self.model.name, "model": self.model.to_spec(),
                "fitted": {"name": self.fitted.name, "model": self.fitted.to_spec()},
                "replacements": list(self.replacements),
                "augmentation": {"state_names": list(block.state_names), "Phi": block.Phi,
                                 "Q": block.Q, "H": block.H, "P0": block.P0,
                                 "white_var": block.white_var, "dt": block.dt}}


@attrs.frozen
class Calibration:
    """The calibration of a recording: the final noise model of each axis.

    Attributes
    ----------
    axes : tuple of AxisCalibration
        In the recording's column order.
    freq : float
        Sampling frequency of the recording, Hz.
    dt : float
        Filter step of the exported augmentation, s.
    n : int
        Samples per column that were fitted (all segments or replicates).
    source : str
        Where the recording was read from.
    record_sizes : tuple of int
        Samples of each gap-free segment or replicate (one entry for a single record): each
        resolves correlation times only up to its own length.
    extra : dict
        Further JSON-safe content (``units``, ``triads``, ``segments``, ``replicates``, ...).
    """

    SCHEMA: ClassVar[int] = SCHEMA

    axes: tuple[AxisCalibration, ...] = attrs.field(converter=tuple)
    freq: float
    dt: float
    n: int
    source: str = ""
    record_sizes: tuple[int, ...] = attrs.field(default=(), converter=tuple)
    extra: dict[str, Any] = attrs.field(factory=dict, converter=_frozen_dict, eq=False,
                                        repr=False)

    def __attrs_post_init__(self) -> None:
        names = [a.column for a in self.axes]
        if len(set(names)) != len(names):
            raise InputError(f"calibration: columns {names} repeat a name")
        if not (self.freq > 0 and self.dt > 0):
            raise InputError(f"calibration: freq {self.freq!r} Hz and dt {self.dt!r} s must be "
                             "positive")

    # ------------------------------------------------------------------ access
    @property
    def columns(self) -> tuple[str, ...]:
        """The axes' column names."""
        return tuple(a.column for a in self.axes)

    @property
    def models(self) -> dict[str, Model]:
        """Column -> final model (SI signal unit, bound to :attr:`freq`)."""
        return {a.column: a.model for a in self.axes}

    @property
    def fitted_models(self) -> dict[str, Model]:
        """Column -> model as fitted, before equivalent components were replaced."""
        return {a.column: a.fitted for a in self.axes}

    def axis(self, column: str) -> AxisCalibration:
        """The axis of `column`."""
        for a in self.axes:
            if a.column == column:
                return a
        raise InputError(f"calibration has no column {column!r}; its columns are "
                         f"{list(self.columns)}")

    @property
    def record_seconds(self) -> float:
        """Length of the longest single record fitted, s (segments and replicates count one
        by one)."""
        return max(self.record_sizes or (self.n,)) / self.freq

    def augmentation(self, dt: float | None = None) -> AxesAugmentation:
        """The whole sensor's EKF augmentation at the filter step `dt` (default :attr:`dt`)."""
        return augment_axes(self.models, self.dt if dt is None else dt)

    def summary(self) -> str:
        """One row per axis: the final model, what was replaced, the verdict."""
        rows = []
        for a in self.axes:
            verdict = a.details.get("verdict") or {}
            status = {True: "accepted", False: "rejected"}.get(verdict.get("accepted"), "-")
            replaced = "; ".join(f"{r['component']} -> {r['term']}" for r in a.replacements)
            rows.append([a.column, a.kind, a.unit or "?", a.model.name,
                         a.fitted.name if a.replacements else "-", replaced or "-",
                         status])
        return format_table(["column", "kind", "unit", "model", "fitted", "replaced", "verdict"],
                            rows, title=f"calibration of {self.source or 'a recording'} "
                                        f"({self.n} samples at {self.freq:g} Hz)")

    # ------------------------------------------------------------------ JSON
    def to_dict(self) -> dict[str, Any]:
        """The JSON content (strict-JSON safe: numpy and non-finite values converted)."""
        imu = self.augmentation()
        content = {
            **self.extra, "schema": SCHEMA, "source": self.source, "freq": self.freq,
            "dt": self.dt, "n": self.n, "record_sizes": list(self.record_sizes),
            "column_order": list(self.columns),
            "columns": {a.column: a.to_dict(self.dt) for a in self.axes},
            "imu_augmentation": {"axes": list(imu.axes), "state_names": list(imu.state_names),
                                 "Phi": imu.Phi, "Q": imu.Q, "H": imu.H, "P0": imu.P0,
                                 "white_var": imu.white_var, "dt": self.dt},
        }
        return to_jsonable(content)

    def to_json(self) -> str:
        """``calibration.json``: indented, key-sorted strict JSON."""
        return json.dumps(self.to_dict(), indent=1, sort_keys=True, allow_nan=False)

    def write(self, path: str | Path) -> Path:
        """Write :meth:`to_json` to `path`; the path."""
        path = Path(path)
        path.write_text(self.to_json())
        return path

    @classmethod
    def from_json(cls, text: str, source: str = "calibration") -> Calibration:
        """Read a calibration written by :meth:`to_json` (schema 1 or 2).

        Raises
        ------
        InputError
            Not JSON, a schema this stochmod does not read (the message says which), or
            content that does not build (the message names the column).
        """
        try:
            data = json.loads(text)
        except ValueError as exc:
            raise InputError(f"{source} is not a JSON file: {exc}") from None
        return cls.from_dict(data, source)

    @classmethod
    def read(cls, path: str | Path) -> Calibration:
        """:meth:`from_json` of a file."""
        path = Path(path)
        if not path.is_file():
            raise InputError(f"no such calibration file: {path}")
        try:
            text = path.read_text()
        except UnicodeDecodeError:
            raise InputError(f"{path} is not a JSON file (not text)") from None
        return cls.from_json(text, str(path))

    @classmethod
    def from_dict(cls, data: Any, source: str = "calibration") -> Calibration:
        """:meth:`from_json` of parsed content."""
        if not isinstance(data, dict) or not isinstance(data.get("columns"), dict):
            raise InputError(f"{source} has no 'columns' object: write it with "
                             "`stochmod calibrate`")
        schema = data.get("schema", 1)
        if isinstance(schema, bool) or not isinstance(schema, int) or schema < 1:
            raise InputError(f"{source}: 'schema' must be a positive integer, got {schema!r}")
        if schema > SCHEMA:
            raise InputError(f"{source} is a calibration of schema {schema}, written by a newer "
                             f"stochmod; this one reads schemas 1 to {SCHEMA}: upgrade stochmod")
        freq = data.get("freq")
        if isinstance(freq, bool) or not isinstance(freq, (int, float)) or not freq > 0:
            raise InputError(f"{source}: 'freq' must be a positive number of Hz, got {freq!r}")
        units = data.get("units") if isinstance(data.get("units"), dict) else {}
        entries = data["columns"]
        order = data.get("column_order")
        if not (isinstance(order, list) and sorted(map(str, order)) == sorted(entries)):
            order = list(entries)  # the file's order (a schema-1 file keeps its columns sorted)
        axes = [_axis(source, str(column), entries[column], float(freq), schema, units)
                for column in order]
        n = data.get("n")
        sizes = data.get("record_sizes") or _legacy_sizes(data)
        known = {"schema", "source", "freq", "dt", "n", "record_sizes", "column_order",
                 "columns", "imu_augmentation"}
        return cls(axes, float(freq), float(data.get("dt") or 1.0 / freq),
                   int(n) if isinstance(n, (int, float)) else 0, str(data.get("source") or ""),
                   tuple(int(s) for s in sizes), {k: v for k, v in data.items() if k not in known})


def _legacy_sizes(data: dict[str, Any]) -> list[int]:
    """Record sizes of a schema-1 file: its segments' or replicates' sizes."""
    if isinstance(data.get("segments"), list):
        return [s["n"] for s in data["segments"] if isinstance(s, dict) and "n" in s]
    if isinstance(data.get("replicates"), dict) and isinstance(data["replicates"].get("n"), list):
        return list(data["replicates"]["n"])
    return []


def _model(source: str, column: str, spec: Any, freq: float, what: str) -> Model:
    if spec is None:
        raise InputError(f"{source}: column {column!r} has no '{what}'")
    bound = spec.get("freq", freq) if isinstance(spec, dict) else freq
    try:
        return model_from_spec(spec, bound)
    except StochmodError as exc:
        raise InputError(f"{source}: the {what} of {column!r} cannot be built: {exc}") from None


def _axis(source: str, column: str, entry: Any, freq: float, schema: int,
          units: dict[str, Any]) -> AxisCalibration:
    if not isinstance(entry, dict):
        raise InputError(f"{source}: column {column!r} is not an object")
    model = _model(source, column, entry.get("model"), freq, "model")
    if schema >= 2:
        fitted_entry = entry.get("fitted")
        fitted = _model(source, column, fitted_entry.get("model") if isinstance(
            fitted_entry, dict) else None, freq, "fitted model")
        kind, unit = entry.get("kind"), entry.get("unit")
    else:  # schema 1 replaced nothing; its units block says the kinds where it has one
        fitted = model
        declared = (units.get("declared") or {}).get(column) or {}
        unit = (units.get("signal") or {}).get(column)
        kind = declared.get("kind") or sensor_kind(column, unit)
    if kind not in KINDS:
        raise InputError(f"{source}: column {column!r} has kind {kind!r}, not one of {KINDS}")
    skip = {"kind", "unit", "name", "model", "fitted", "replacements", "augmentation"}
    return AxisCalibration(column, kind, unit, model, fitted,
                           tuple(entry.get("replacements") or ()),
                           {k: v for k, v in entry.items() if k not in skip})
