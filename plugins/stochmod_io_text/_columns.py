"""Header cells ``name [unit]`` and the choice of the time column, shared by the readers."""

from __future__ import annotations

import re

from stochmod.sdk import InputError, parse_unit

__all__ = ["TIME_NAMES", "split_header", "find_time_column", "time_scale"]

#: Column names taken as time stamps when no ``time_column`` option is given (case-insensitive).
TIME_NAMES = ("time", "t", "timestamp", "timestamps", "stamp", "time_s")

_CELL = re.compile(r"^(?P<name>.*?)\s*\[(?P<unit>[^\[\]]*)\]\s*$")


def split_header(cells: list[str]) -> tuple[tuple[str, ...], tuple[str | None, ...]]:
    """Split header cells ``"gyro_x [deg/s]"`` into names and units (None where absent)."""
    names, units = [], []
    for cell in cells:
        m = _CELL.match(cell.strip())
        if m and m["name"]:
            names.append(m["name"])
            units.append(m["unit"].strip() or None)
        else:
            names.append(cell.strip())
            units.append(None)
    return tuple(names), tuple(units)


def find_time_column(names: tuple[str, ...], option: str | int | None, path: object) -> int | None:
    """Index of the time column: the one named by `option`, else the first in :data:`TIME_NAMES`."""
    if option is None:
        for i, name in enumerate(names):
            if name.strip().lower() in TIME_NAMES:
                return i
        return None
    if isinstance(option, str) and option in names:
        return names.index(option)
    try:
        index = int(option)
    except (TypeError, ValueError):
        raise InputError(f"{path}: no time column {option!r}; columns are {list(names)}") from None
    if not 0 <= index < len(names):
        raise InputError(f"{path}: time column index {index} out of range ({len(names)} columns)")
    return index


def time_scale(unit: str | None, path: object) -> float:
    """Seconds per unit of a time column (1 when the header gives no unit)."""
    if unit is None:
        return 1.0
    parsed = parse_unit(unit)
    if parsed.kind != "time":
        raise InputError(f"{path}: the time column's unit {unit!r} is not a unit of time")
    return parsed.scale
