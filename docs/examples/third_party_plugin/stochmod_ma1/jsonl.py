"""A log-format reader written as a third party would: JSON Lines (``.jsonl``).

One JSON object per line, e.g. ``{"t": 0.005, "gyro_x": 0.01, "gyro_y": -0.02}``; every key
but the time key is a column, in the order of the first line; each line must have the same
keys. A first line ``{"units": {"gyro_x": "deg/s", ...}}`` gives the columns' units.
Only public stochmod names are used.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import ClassVar

import numpy as np

from stochmod.sdk import InputError, Reader, Recording

__all__ = ["JsonLinesReader"]


class JsonLinesReader(Reader):
    """JSON Lines: one object per sample, an optional time key (option ``time_key``, "t")."""

    name: ClassVar[str] = "jsonl"
    suffixes: ClassVar[tuple[str, ...]] = (".jsonl",)
    options: ClassVar[tuple[str, ...]] = ("time_key",)
    description: ClassVar[str] = "JSON Lines, one object per sample (example third-party reader)"

    def read(self, path: Path, time_key: str = "t") -> Recording:
        lines = [ln for ln in path.read_text().splitlines() if ln.strip()]
        objects = [json.loads(ln) for ln in lines]
        units: dict[str, str] = {}
        if objects and set(objects[0]) == {"units"}:
            units = objects.pop(0)["units"]
        if not objects:
            raise InputError(f"{path} holds no samples")
        keys = [k for k in objects[0] if k != time_key]
        for lineno, obj in enumerate(objects, start=len(lines) - len(objects) + 1):
            if set(obj) != set(objects[0]):
                raise InputError(
                    f"{path}: line {lineno} has keys {sorted(obj)}, expected {sorted(objects[0])}"
                )
        data = np.array([[obj[k] for k in keys] for obj in objects], dtype=np.float64)
        time = (
            np.array([obj[time_key] for obj in objects], dtype=np.float64)
            if time_key in objects[0]
            else None
        )
        return Recording(
            data=data,
            columns=tuple(keys),
            path=str(path),
            time=time,
            units=tuple(units.get(k) for k in keys) if units else None,
        )
