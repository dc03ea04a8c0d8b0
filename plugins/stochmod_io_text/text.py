"""Delimited text: CSV, TSV, TXT, DAT with an optional header ``name [unit]`` and time column."""

from __future__ import annotations

import csv
import io
import re
from pathlib import Path
from typing import ClassVar

import numpy as np

from stochmod.sdk import InputError, Reader, Recording
from stochmod_io_text._columns import find_time_column, split_header, time_scale

__all__ = ["TextReader"]

_HEADER_CELL = re.compile(r"[^\s\[]+(?:\s*\[[^\]]*\])?")


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _rows(path: Path) -> list[list[str]]:
    """Non-empty, non-comment rows split on the sniffed delimiter (``, ; tab space``)."""
    lines = [
        ln for ln in path.read_text().splitlines() if ln.strip() and not ln.lstrip().startswith("#")
    ]
    if not lines:
        raise InputError(f"{path} holds no data rows")
    try:  # sniffed on the second line: a header such as "gyro_x [deg/s]" holds spaces
        delimiter = csv.Sniffer().sniff(lines[min(1, len(lines) - 1)], delimiters=",;\t ").delimiter
    except csv.Error:
        delimiter = ","
    rows = list(
        csv.reader(io.StringIO("\n".join(lines)), delimiter=delimiter, skipinitialspace=True)
    )
    if delimiter != " ":
        return rows
    rows = [[c for c in row if c != ""] for row in rows]
    rows[0] = _HEADER_CELL.findall(lines[0])  # "t [s] gyro_x [deg/s]": a unit joins its name
    return rows


def _table(path: Path, rows: list[list[str]], first_line: int) -> np.ndarray:
    width = len(rows[0])
    values = []
    for lineno, row in enumerate(rows, start=first_line):
        if len(row) != width:
            raise InputError(f"{path}: data row {lineno} has {len(row)} fields, expected {width}")
        try:
            values.append([float(c) for c in row])
        except ValueError:
            bad = next(c for c in row if not _is_float(c))
            raise InputError(f"{path}: non-numeric value {bad!r} in data row {lineno}") from None
    return np.asarray(values, dtype=np.float64)


class TextReader(Reader):
    """Comma, semicolon, tab or space separated text with an optional header line.

    A header is a first row with no numeric cell (so a typo in the first data row stays an
    error); a cell ``gyro_x [deg/s]`` names the column ``gyro_x`` with unit ``deg/s``. Lines
    starting with ``#`` are comments. The time column is the one named by the ``time_column``
    option (name or 0-based index), else the first named ``time``, ``t``, ``timestamp``,
    ``timestamps``, ``stamp`` or ``time_s``; its unit (``[ms]``, ``[us]``, ``[ns]``) defaults to s.
    """

    name: ClassVar[str] = "csv"
    suffixes: ClassVar[tuple[str, ...]] = (".csv", ".tsv", ".txt", ".dat", "")
    options: ClassVar[tuple[str, ...]] = ("time_column",)
    description: ClassVar[str] = "delimited text, optional header 'name [unit]' and time column"

    def read(self, path: Path, time_column: str | int | None = None) -> Recording:
        rows = _rows(path)
        names: tuple[str, ...] | None = None
        units: tuple[str | None, ...] | None = None
        if not any(_is_float(c) for c in rows[0]):
            names, units = split_header(rows[0])
            rows = rows[1:]
            if not rows:
                raise InputError(f"{path} has a header but no data rows")
        data = _table(path, rows, 2 if names else 1)
        width = data.shape[1]
        if names is not None and len(names) != width:
            raise InputError(f"{path}: header has {len(names)} names but rows have {width} fields")
        names = names or tuple(str(i) for i in range(width))
        units = units if units is not None and any(units) else None
        it = find_time_column(names, time_column, path)
        if it is None:
            return Recording(data=data, columns=names, path=str(path), units=units)
        if width < 2:
            raise InputError(f"{path}: the time column {names[it]!r} is the only column")
        keep = [i for i in range(width) if i != it]
        scale = time_scale(units[it] if units else None, path)
        return Recording(
            data=data[:, keep],
            columns=tuple(names[i] for i in keep),
            path=str(path),
            time=data[:, it] * scale,
            units=None if units is None else tuple(units[i] for i in keep),
        )
