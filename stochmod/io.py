"""Reading sensor recordings from files: CSV (with or without header), ``.npy`` and ``.npz``.

A recording is a table of samples x columns; every reader returns a :class:`Recording`
with float64 data, column names and, where the file says so, the sampling frequency.
"""

from __future__ import annotations

import csv
import io as _io
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import attrs
import numpy as np

from stochmod._validation import as_signals
from stochmod.errors import InputError

__all__ = ["Recording", "read_recording"]

_T = TypeVar("_T")


@attrs.frozen
class Recording:
    """A multi-column static recording.

    Attributes
    ----------
    data : ndarray, shape (n, k)
        Samples (float64), one column per axis, in the file's units.
    columns : tuple of str
        Column names (``"0"``, ``"1"`` ... where the file has none).
    freq : float or None
        Sampling frequency in Hz when the file records it (``freq`` in an ``.npz``).
    path : str
        Where the recording was read from.
    """

    data: np.ndarray
    columns: tuple[str, ...]
    freq: float | None = None
    path: str = ""

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
                f"no column {key!r} in {self.path or 'the recording'}; columns are {list(self.columns)}"
            ) from None
        if not -len(self.columns) <= index < len(self.columns):
            raise InputError(
                f"column index {index} out of range: {self.path or 'the recording'} has "
                f"{len(self.columns)} column(s)"
            )
        return index % len(self.columns)

    def select(self, keys: list[str | int] | None) -> "Recording":
        """Return the recording restricted to `keys` (all columns when None)."""
        if not keys:
            return self
        idx = [self.column_index(k) for k in keys]
        return attrs.evolve(
            self, data=self.data[:, idx], columns=tuple(self.columns[i] for i in idx)
        )


def _read_csv(path: Path) -> tuple[np.ndarray, tuple[str, ...]]:
    text = path.read_text()
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise InputError(f"{path} holds no data rows")
    try:
        dialect = csv.Sniffer().sniff(lines[0], delimiters=",;\t ")
        delimiter = dialect.delimiter
    except csv.Error:
        delimiter = ","
    rows = list(csv.reader(_io.StringIO("\n".join(lines)), delimiter=delimiter, skipinitialspace=True))
    rows = [[c for c in row if c != ""] if delimiter == " " else row for row in rows]

    header: tuple[str, ...] | None = None
    # a header is a first row with no numeric cell: a typo in the first data row stays an error
    if not any(_is_float(c) for c in rows[0]):
        header = tuple(c.strip() for c in rows[0])
        rows = rows[1:]
    if not rows:
        raise InputError(f"{path} has a header but no data rows")
    width = len(rows[0])
    values = []
    for lineno, row in enumerate(rows, start=2 if header else 1):
        if len(row) != width:
            raise InputError(f"{path}: data row {lineno} has {len(row)} fields, expected {width}")
        try:
            values.append([float(c) for c in row])
        except ValueError:
            bad = next(c for c in row if not _is_float(c))
            raise InputError(f"{path}: non-numeric value {bad!r} in data row {lineno}") from None
    data = np.asarray(values, dtype=np.float64)
    if header is not None and len(header) != width:
        raise InputError(f"{path}: header has {len(header)} names but rows have {width} fields")
    return data, header or tuple(str(i) for i in range(width))


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _read_npz(path: Path) -> tuple[np.ndarray, tuple[str, ...], float | None]:
    with np.load(path, allow_pickle=False) as z:
        freq = float(z["freq"]) if "freq" in z.files and z["freq"].size == 1 else None
        arrays = {
            k: z[k]
            for k in z.files
            if z[k].ndim >= 1 and np.issubdtype(z[k].dtype, np.number) and k != "freq"
        }
    if not arrays:
        raise InputError(f"{path} holds no numeric arrays")
    lengths = {a.shape[0] for a in arrays.values()}
    if len(lengths) != 1:
        raise InputError(f"{path}: numeric arrays have different lengths {sorted(lengths)}")
    columns: list[str] = []
    blocks = []
    for name, arr in arrays.items():
        if arr.ndim == 1:
            columns.append(name)
            blocks.append(arr[:, None])
        elif arr.ndim == 2:
            columns.extend(f"{name}[{i}]" for i in range(arr.shape[1]))
            blocks.append(arr)
        else:
            raise InputError(f"{path}: array {name!r} has {arr.ndim} dimensions; expected 1 or 2")
    return np.hstack(blocks).astype(np.float64), tuple(columns), freq


def _unreadable_as_input_error(reader: Callable[..., _T], path: Path, **kwargs: Any) -> _T:
    """Call ``reader(path, **kwargs)``; numpy's errors on corrupt or pickled files become InputError."""
    try:
        return reader(path, **kwargs)
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as exc:
        if isinstance(exc, InputError):
            raise
        raise InputError(f"cannot read {path} as {path.suffix}: {exc}") from None


def read_recording(path: str | Path, *, columns: list[str | int] | None = None) -> Recording:
    """Read a recording from a CSV, ``.npy`` or ``.npz`` file.

    Parameters
    ----------
    path : str or Path
        ``.csv``/``.txt``/``.dat`` (comma, semicolon, tab or space separated, optional header
        line, ``#`` comments), ``.npy`` (1-D or 2-D array) or ``.npz`` (one numeric array per
        column; a scalar ``freq`` entry is read as the sampling frequency in Hz).
    columns : list of str or int, optional
        Keep only these columns (names or 0-based indices).

    Returns
    -------
    Recording
        Finite float64 data of shape (n, k).

    Raises
    ------
    InputError
        Missing file, unknown format, non-numeric cells, ragged rows, NaN/inf, empty data.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"no such file: {path}")
    suffix = path.suffix.lower()
    freq = None
    if suffix == ".npy":
        arr = _unreadable_as_input_error(np.load, path, allow_pickle=False)
        data = as_signals(arr, name=str(path))
        names = tuple(str(i) for i in range(data.shape[1]))
    elif suffix == ".npz":
        data, names, freq = _unreadable_as_input_error(_read_npz, path)
    elif suffix in {".csv", ".txt", ".dat", ".tsv", ""}:
        data, names = _unreadable_as_input_error(_read_csv, path)
    else:
        raise InputError(f"unknown file format {suffix!r} for {path}; use .csv, .npy or .npz")
    data = as_signals(data, name=str(path))
    return Recording(data=data, columns=names, freq=freq, path=str(path)).select(columns)
