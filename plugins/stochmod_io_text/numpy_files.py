"""numpy's binary formats: ``.npy`` (one 1-D or 2-D array) and ``.npz`` (one array per column)."""

from __future__ import annotations

import re
from pathlib import Path
from typing import ClassVar

import numpy as np

from stochmod.sdk import InputError, Reader, Recording, sensor_kind
from stochmod_io_text._columns import find_time_column

__all__ = ["NpyReader", "NpzReader"]


class NpyReader(Reader):
    """A ``.npy`` array of shape (n,) or (n, k); columns are named ``"0"``, ``"1"`` ..."""

    name: ClassVar[str] = "npy"
    suffixes: ClassVar[tuple[str, ...]] = (".npy",)
    description: ClassVar[str] = "numpy array, (n,) or (n, k)"

    def read(self, path: Path) -> Recording:
        arr = np.load(path, allow_pickle=False)
        if arr.ndim not in (1, 2):
            raise InputError(f"{path} must be 1-D or 2-D (samples x axes), got shape {arr.shape}")
        width = 1 if arr.ndim == 1 else arr.shape[1]
        return Recording(
            data=arr.reshape(arr.shape[0], width) if arr.size else arr.reshape(0, width),
            columns=tuple(str(i) for i in range(width)),
            path=str(path),
        )


def _columns(path: Path, arrays: dict[str, np.ndarray]) -> tuple[np.ndarray, tuple[str, ...]]:
    lengths = {a.shape[0] for a in arrays.values()}
    if len(lengths) != 1:
        raise InputError(f"{path}: numeric arrays have different lengths {sorted(lengths)}")
    names: list[str] = []
    blocks = []
    for name, arr in arrays.items():
        if arr.ndim == 1:
            names.append(name)
            blocks.append(arr[:, None])
        elif arr.ndim == 2:
            names.extend(f"{name}[{i}]" for i in range(arr.shape[1]))
            blocks.append(arr)
        else:
            raise InputError(f"{path}: array {name!r} has {arr.ndim} dimensions; expected 1 or 2")
    return np.hstack(blocks).astype(np.float64, copy=False), tuple(names)


class NpzReader(Reader):
    """A ``.npz`` archive: each numeric array of length n is a column (2-D arrays ``name[i]``).

    A scalar ``freq`` entry is the sampling frequency in Hz; ``units`` gives the units, as a
    1-D string array with one entry per column or as one ``"key: unit, key: unit"`` string
    whose keys are columns or sensor kinds (``gyro``, ``accel``); a 1-D string array
    ``sensor`` with one entry per column gives what each measures (``"Gyroscope"``); a time
    array (named by the ``time_column`` option, else ``time``, ``t``, ``timestamp`` ...) gives
    the time stamps in s.
    """

    name: ClassVar[str] = "npz"
    suffixes: ClassVar[tuple[str, ...]] = (".npz",)
    options: ClassVar[tuple[str, ...]] = ("time_column",)
    description: ClassVar[str] = "numpy archive, one array per column, optional freq, units, time"

    def read(self, path: Path, time_column: str | None = None) -> Recording:
        with np.load(path, allow_pickle=False) as z:
            members = {k: z[k] for k in z.files}  # each z[k] reads (and checks) the member again
        freq_array = members.get("freq")
        freq = float(freq_array) if freq_array is not None and freq_array.size == 1 else None
        units = members.get("units")
        arrays = {
            k: a
            for k, a in members.items()
            if a.ndim >= 1 and np.issubdtype(a.dtype, np.number) and k != "freq"
        }
        names = tuple(arrays)
        it = find_time_column(names, time_column, path)
        time = None
        if it is not None:
            time = arrays.pop(names[it])
            if time.ndim != 1:
                raise InputError(
                    f"{path}: the time array {names[it]!r} must be 1-D, got shape {time.shape}"
                )
        if not arrays:
            raise InputError(
                f"{path} holds no numeric arrays"
                + (" besides the time" if time is not None else "")
            )
        data, columns = _columns(path, arrays)
        if time is not None and time.shape[0] != data.shape[0]:
            raise InputError(f"{path}: {time.shape[0]} time stamps for {data.shape[0]} samples")
        kinds = _per_column(members.get("sensor"), columns)
        unit_list = _per_column(units, columns)
        if units is not None and units.ndim == 0 and units.dtype.kind == "U":
            unit_list = _units_by_key(str(units), columns, kinds)
        return Recording(data=data, columns=columns, freq=freq, path=str(path), time=time,
                         units=unit_list, kinds=kinds)


def _per_column(entry: np.ndarray | None, columns: tuple[str, ...]) -> tuple[str | None, ...] | None:
    """A 1-D string array with one entry per column, else None."""
    if entry is None or entry.ndim != 1 or entry.dtype.kind != "U" or len(entry) != len(columns):
        return None
    return tuple(str(u) or None for u in entry)


def _units_by_key(text: str, columns: tuple[str, ...], kinds: tuple[str | None, ...] | None
                  ) -> tuple[str | None, ...] | None:
    """Units from a ``"key: unit"`` string (``"gyro: deg/s (from the LSB), accel: g"``): a key
    is a column or a sensor kind (``gyro``/``accel``, matched against the ``sensor`` entry or
    the column's name); the unit is the first word after the colon."""
    by_key = {}
    for part in _PAIRS.split(text):
        key, sep, rest = part.partition(":")
        words = rest.split()
        if sep and words:
            by_key[key.strip().lower()] = words[0]
    if not by_key:
        return None
    out = []
    for k, column in enumerate(columns):
        hint = (kinds[k] if kinds is not None else None) or column
        kind = sensor_kind(column, None, hint)
        out.append(by_key.get(column.lower(), by_key.get(kind)))
    return tuple(out) if any(out) else None


_PAIRS = re.compile(r"[,;]")
