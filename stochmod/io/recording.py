"""Reading sensor recordings through the readers plugin point.

A recording is a table of samples x columns, optionally with a time stamp per sample and a
unit per column. :func:`read_recording` picks a reader registered by a plugin (hook
``stochmod_readers``): by name, else the first whose ``sniff`` recognises the path (folders
such as a ROS 2 bag), else by the file's suffix. First-party readers (CSV/TSV, NPY/NPZ, PX4
ULog, ROS 1/2 bags) are plugins registered exactly as a third party's; see docs/readers.md.

Time stamps are checked here, whatever the reader: the rate is estimated
(:func:`stochmod.io.timing.analyse_timing`), and a recording with dropped samples or gaps is
refused with an error saying where, unless ``split_gaps=True`` asks for its gap-free
:meth:`Recording.segments`.
"""

from __future__ import annotations

import abc
import importlib
import zipfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import ModuleType
from typing import Any, ClassVar

import attrs
import numpy as np

from stochmod.core.checks import as_signals
from stochmod.core.errors import InputError, StochmodError
from stochmod.core.tables import format_table
from stochmod.core.units import parse_unit
from stochmod.io.sensors import ColumnUnit
from stochmod.io.timing import DEFAULT_GAP_FACTOR, TimingReport, analyse_timing
from stochmod.plugin.registry import readers

__all__ = [
    "Reader",
    "Recording",
    "column_replicates",
    "format_names",
    "import_optional",
    "read_recording",
    "read_with",
]


def _tuple_or_none(value: Any) -> tuple[str | None, ...] | None:
    return None if value is None else tuple(value)


def _array_or_none(value: Any) -> np.ndarray | None:
    return None if value is None else np.asarray(value, dtype=np.float64)


@attrs.frozen
class Recording:
    """A multi-column static recording.

    Attributes
    ----------
    data : ndarray, shape (n, k)
        Samples (float64), one column per axis, in the units of :attr:`units`.
    columns : tuple of str
        Column names (``"0"``, ``"1"`` ... where the file has none).
    freq : float or None
        Sampling frequency in Hz: recorded by the file (``freq`` in an ``.npz``) or estimated
        from the time stamps.
    path : str
        Where the recording was read from.
    time : ndarray, shape (n,), or None
        Time stamp of each sample, s after :attr:`time_origin`, where the file has them.
    units : tuple of (str or None), or None
        Unit of each column (e.g. ``"deg/s"``; None where unknown), where the file says.
    kinds : tuple of (str or None), or None
        What each column measures, where the file says (``"Gyroscope"``, ``"gyro"``,
        ``"accel"``; :func:`stochmod.io.sensors.sensor_kind` reads it).
    declared : tuple of ColumnUnit, or None
        Each column's kind, unit and where the unit comes from, once declared
        (:func:`stochmod.io.sensors.declare_units`); :meth:`to_si` keeps the declaration.
    timing : TimingReport or None
        Rate, gaps and jitter found in :attr:`time` (set by :func:`read_recording`).
    time_origin : float
        Absolute time of ``time == 0``, s (e.g. the Unix time of a ROS bag's first stamp,
        kept apart so that :attr:`time` keeps its resolution in float64).
    """

    data: np.ndarray
    columns: tuple[str, ...]
    freq: float | None = None
    path: str = ""
    time: np.ndarray | None = attrs.field(default=None, converter=_array_or_none)
    units: tuple[str | None, ...] | None = attrs.field(default=None, converter=_tuple_or_none)
    timing: TimingReport | None = None
    time_origin: float = 0.0
    kinds: tuple[str | None, ...] | None = attrs.field(default=None, converter=_tuple_or_none)
    declared: tuple[ColumnUnit, ...] | None = None

    def __attrs_post_init__(self) -> None:
        n, k = np.shape(self.data)[0], len(self.columns)
        if self.time is not None and self.time.shape != (n,):
            raise InputError(
                f"{self.path or 'recording'}: {self.time.size} time stamps for {n} samples"
            )
        if self.units is not None and len(self.units) != k:
            raise InputError(f"{self.path or 'recording'}: {len(self.units)} units for {k} columns")
        if self.kinds is not None and len(self.kinds) != k:
            raise InputError(f"{self.path or 'recording'}: {len(self.kinds)} sensor kinds for "
                             f"{k} columns")

    def column(self, key: str | int) -> np.ndarray:
        """Return one column by name or by 0-based index."""
        return self.data[:, self.column_index(key)]

    def column_index(self, key: str | int) -> int:
        """Resolve a column name or 0-based index (given as int or digit string)."""
        if isinstance(key, str) and key in self.columns:
            return self.columns.index(key)
        try:
            index = int(key)
        except (TypeError, ValueError):
            raise InputError(
                f"no column {key!r} in {self.path or 'the recording'}; "
                f"columns are {list(self.columns)}"
            ) from None
        if not -len(self.columns) <= index < len(self.columns):
            raise InputError(
                f"column index {index} out of range: {self.path or 'the recording'} has "
                f"{len(self.columns)} column(s)"
            )
        return index % len(self.columns)

    def select(self, keys: list[str | int] | None) -> Recording:
        """Return the recording restricted to `keys` (all columns when None)."""
        if not keys:
            return self
        idx = [self.column_index(k) for k in keys]
        units = None if self.units is None else tuple(self.units[i] for i in idx)
        kinds = None if self.kinds is None else tuple(self.kinds[i] for i in idx)
        declared = None if self.declared is None else tuple(self.declared[i] for i in idx)
        return attrs.evolve(self, data=self.data[:, idx],
                            columns=tuple(self.columns[i] for i in idx), units=units, kinds=kinds,
                            declared=declared)

    def summary(self) -> str:
        """Columns with units and ranges, the sampling rate, and the time-stamp report."""
        rows = [
            [c, u or "?", float(np.min(x)), float(np.mean(x)), float(np.max(x))]
            for c, u, x in zip(self.columns, self.units or (None,) * len(self.columns), self.data.T)
        ]
        rate = "unknown rate" if self.freq is None else f"{self.freq:.6g} Hz"
        text = format_table(
            ["column", "unit", "min", "mean", "max"],
            rows,
            title=f"{self.path or 'recording'}: {self.data.shape[0]} samples, {rate}",
        )
        return text + ("" if self.timing is None else "\n\n" + self.timing.summary())

    def unit_map(self) -> dict[str, str]:
        """Column name -> unit, for the columns whose unit is known."""
        return {c: u for c, u in zip(self.columns, self.units or ()) if u}

    def to_si(self, unit: str | Mapping[str, str] | None = None) -> Recording:
        """Return the recording with every column of known unit converted to SI.

        Parameters
        ----------
        unit : str or mapping of str to str, optional
            The unit of every column (e.g. ``"deg/s"``, ``"mg"``), or column -> unit,
            overriding the file's. Without it the units read from the file are used; columns
            of unknown unit are left as they are.

        Returns
        -------
        Recording
            Data multiplied by each unit's SI value (:func:`stochmod.core.units.parse_unit`),
            :attr:`units` set to the SI units (``rad/s``, ``m/s^2`` ...).

        Raises
        ------
        InputError
            A unit that does not parse.
        """
        given = list(self.units or [None] * len(self.columns))
        if isinstance(unit, str):
            given = [unit] * len(self.columns)
        elif unit is not None:
            given = [unit.get(c, u) for c, u in zip(self.columns, given)]
        parsed = []
        for column, u in zip(self.columns, given):
            try:
                parsed.append(None if u is None else parse_unit(u))
            except InputError as exc:
                source = (
                    "the unit given"
                    if unit is not None
                    else f"{self.path or 'the recording'}'s header"
                )
                raise InputError(
                    f"column {column!r}: {source} says {u!r}, which is not a unit stochmod "
                    f"knows ({exc}); give the data's unit explicitly (--unit)"
                ) from None
        if all(p is None for p in parsed):
            return self
        scale = np.array([1.0 if p is None else p.scale for p in parsed])
        units = tuple(None if p is None else p.si for p in parsed)
        return attrs.evolve(self, data=self.data * scale, units=units)

    def segments(self) -> list[Recording]:
        """The gap-free pieces of the recording, in time order (itself when it has no gaps).

        Each piece keeps the columns, units, rate and the time stamps of its samples; its
        :attr:`timing` covers the piece only.
        """
        if self.timing is None or not self.timing.has_gaps:
            return [self]
        pieces = []
        for a, b in self.timing.segment_bounds():
            time = self.time[a:b]
            timing = None
            if b - a >= 2:
                timing = analyse_timing(time, gap_factor=self.timing.gap_factor, name=self.path)
            pieces.append(attrs.evolve(self, data=self.data[a:b], time=time, timing=timing))
        return pieces


class Reader(abc.ABC):
    """Base class of a log-format reader (the ``stochmod_readers`` hook returns instances).

    Subclassing is optional: any object with these attributes and methods is a reader.

    Attributes
    ----------
    name : str
        Unique format name, used by ``read_recording(..., reader=name)`` (e.g. ``"ulog"``).
    suffixes : tuple of str
        Lower-case file suffixes with the dot (``".ulg"``) that select this reader; ``""``
        matches a file without suffix.
    options : tuple of str
        Names of the keyword options :meth:`read` takes (e.g. ``("topic", "instance")``).
    description : str
        One line for listings (``stochmod readers``, error messages).
    """

    name: ClassVar[str]
    suffixes: ClassVar[tuple[str, ...]] = ()
    options: ClassVar[tuple[str, ...]] = ()
    description: ClassVar[str] = ""

    def sniff(self, path: Path) -> bool:
        """Whether `path` (a file or a folder) is in this format regardless of its suffix."""
        return False

    @abc.abstractmethod
    def read(self, path: Path, **options: Any) -> Recording:
        """Read `path` and return a :class:`Recording` (time stamps in s where the format has
        them)."""


def import_optional(module: str, *, extra: str, what: str) -> ModuleType:
    """Import an optional dependency, or raise a one-line ImportError naming the extra.

    Parameters
    ----------
    module : str
        Module to import, e.g. ``"pyulog"``.
    extra : str
        The stochmod extra that installs it, e.g. ``"ulog"``.
    what : str
        What needs it, e.g. ``"reading PX4 ULog files"``.
    """
    try:
        return importlib.import_module(module)
    except ImportError:
        raise ImportError(f'{what} needs {module}: pip install "stochmod[{extra}]"') from None


def format_names() -> str:
    """Registered readers with their suffixes, e.g. ``"csv (.csv, .tsv), ulog (.ulg)"``."""
    parts = []
    for name, r in readers().items():
        sfx = ", ".join(s or "no suffix" for s in r.suffixes)
        parts.append(f"{name} ({sfx})" if sfx else f"{name} (by content)")
    return ", ".join(parts) or "none"


def _choose(path: Path, reader: str | None) -> Any:
    table = readers()
    if reader is not None:
        try:
            return table[reader]
        except KeyError:
            raise InputError(
                f"unknown reader {reader!r}; registered readers: {format_names()}"
            ) from None
    for r in table.values():
        if r.sniff(path):
            return r
    if path.is_dir():
        raise InputError(
            f"no such file: {path} is a folder that no reader recognises "
            f"(registered readers: {format_names()})"
        )
    suffix = path.suffix.lower()
    for r in table.values():
        if suffix in r.suffixes:
            return r
    raise InputError(
        f"unknown file format {suffix!r} for {path}; registered readers: {format_names()}"
    )


def _call(r: Any, path: Path, options: dict[str, Any]) -> Recording:
    unknown = sorted(set(options) - set(r.options))
    if unknown:
        takes = ", ".join(r.options) or "no options"
        raise InputError(
            f"the {r.name} reader does not take option(s) {', '.join(map(repr, unknown))} "
            f"for {path}; it takes: {takes}"
        )
    try:
        rec = r.read(path, **options)
    except StochmodError:
        raise
    except (ValueError, OSError, EOFError, KeyError, IndexError, zipfile.BadZipFile) as exc:
        raise InputError(f"cannot read {path} as {r.name}: {exc}") from None
    if not isinstance(rec, Recording):
        raise InputError(f"the {r.name} reader returned {type(rec).__name__}, not a Recording")
    return rec


def read_with(path: str | Path, reader: str, **options: Any) -> Recording:
    """The recording as the reader named `reader` returns it, without the checks of
    :func:`read_recording` (samples, time stamps): for a caller that checks them its own way.

    Raises
    ------
    InputError
        Unknown reader, an option it does not take, or a file it cannot read (the reader's
        error, in one line).
    """
    found = readers()
    if reader not in found:
        raise InputError(f"unknown reader {reader!r}; registered: {', '.join(sorted(found))}")
    return _call(found[reader], Path(path), options)


def read_recording(
    path: str | Path,
    *,
    columns: list[str | int] | None = None,
    reader: str | None = None,
    split_gaps: bool = False,
    gap_factor: float = DEFAULT_GAP_FACTOR,
    **options: Any,
) -> Recording:
    """Read a recording with the reader registered for its format.

    Parameters
    ----------
    path : str or Path
        A file, or a folder some reader recognises (a ROS 2 bag). First-party formats:
        CSV/TSV/TXT/DAT (optional header ``name [unit]``, optional time column), ``.npy``,
        ``.npz`` (a scalar ``freq`` entry is the sampling frequency in Hz), PX4 ``.ulg``,
        ROS 1 ``.bag`` and ROS 2 bag folders (or their ``.db3``/``.mcap`` files).
    columns : list of str or int, optional
        Keep only these columns (names or 0-based indices).
    reader : str, optional
        The reader's name (see :func:`stochmod.plugin.registry.reader_names`); default: chosen by
        sniffing, then by suffix.
    split_gaps : bool
        Accept a recording whose time stamps have gaps; :meth:`Recording.segments` then
        returns its gap-free pieces. Without it a gap is an :class:`InputError` saying where.
    gap_factor : float
        An interval between stamps longer than this many periods is a gap.
    **options
        Reader options, e.g. ``topic="/imu"``, ``instance=1``; None values are ignored.

    Returns
    -------
    Recording
        Finite float64 data of shape (n, k); ``freq`` estimated from the time stamps when the
        file does not record it, ``timing`` their report.

    Raises
    ------
    InputError
        Missing file, unknown format or reader, an option the reader does not take, non-numeric
        cells, NaN/inf, empty data, time stamps that do not increase, gaps (unless
        `split_gaps`).
    ImportError
        The reader's optional dependency is missing (the message names the extra).
    """
    path = Path(path)
    if not path.exists():
        raise InputError(f"no such file: {path}")
    r = _choose(path, reader)
    rec = _call(r, path, {k: v for k, v in options.items() if v is not None})
    data = as_signals(rec.data, name=str(path))
    rec = attrs.evolve(rec, data=data, path=rec.path or str(path))
    if rec.time is not None:
        timing = analyse_timing(rec.time, gap_factor=gap_factor, name=str(path))
        if timing.has_gaps and not split_gaps:
            raise InputError(
                f"{path}: {len(timing.gaps)} gap(s) in the time stamps ({timing.dropped} sample(s) "
                f"missing at {timing.rate:.6g} Hz): {timing.describe_gaps()}; pass split_gaps=True "
                "(--split-gaps) to use the gap-free segments"
            )
        freq = rec.freq if rec.freq is not None else timing.rate
        rec = attrs.evolve(rec, timing=timing, freq=freq)
    return rec.select(columns)


def column_replicates(segments: Sequence[Recording], k: int) -> np.ndarray | list[np.ndarray]:
    """Column `k` of a recording's gap-free segments: one signal, or the list of the segments'
    signals (replicates for :func:`stochmod.gmwm` and :func:`stochmod.select`)."""
    xs = [s.data[:, k] for s in segments]
    return xs[0] if len(xs) == 1 else xs


def longest_segment(pieces: Sequence[Recording]) -> Recording:
    """The longest of a recording's gap-free `pieces` (:meth:`Recording.segments`): the data
    of what does not pool segments (the Allan, PSD, AR and de-noising commands, calibrate's
    Allan reading and validation bands)."""
    return max(pieces, key=lambda r: r.data.shape[0])
