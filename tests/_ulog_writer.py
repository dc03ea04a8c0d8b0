"""A minimal ULog writer following the PX4 file-format specification, for the reader's tests.

Independent of pyulog (which only reads): header, flag bits, formats, one information
message, subscriptions and data messages, little-endian and packed as the format says.
https://docs.px4.io/main/en/dev_log/ulog_file_format.html
"""

from __future__ import annotations

import struct
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

__all__ = ["Topic", "write_ulog"]

_MAGIC = b"ULog\x01\x12\x35"
_CODES = {
    "uint64_t": "Q",
    "int64_t": "q",
    "uint32_t": "I",
    "int32_t": "i",
    "uint16_t": "H",
    "int16_t": "h",
    "uint8_t": "B",
    "int8_t": "b",
    "float": "f",
    "double": "d",
    "bool": "?",
}


class Topic:
    """A logged topic: name, fields ``[(type, name, size)]`` and rows of values per field."""

    def __init__(
        self,
        name: str,
        fields: Sequence[tuple[str, str, int]],
        values: Mapping[str, np.ndarray],
        multi_id: int = 0,
    ) -> None:
        self.name, self.fields, self.values, self.multi_id = name, list(fields), values, multi_id

    def format(self) -> bytes:
        parts = [f"{t}[{n}] {f}" if n > 1 else f"{t} {f}" for t, f, n in self.fields]
        return f"{self.name}:{';'.join(parts)};".encode()

    def rows(self) -> list[bytes]:
        code = "<" + "".join(f"{n}{_CODES[t]}" for t, _, n in self.fields)
        count = len(self.values[self.fields[0][1]])
        out = []
        for r in range(count):
            flat: list[object] = []
            for t, f, n in self.fields:
                v = self.values[f][r]
                flat.extend(
                    np.atleast_1d(v).tolist() if n > 1 else [v.item() if hasattr(v, "item") else v]
                )
            out.append(struct.pack(code, *flat))
        return out


def _message(kind: bytes, payload: bytes) -> bytes:
    return struct.pack("<Hc", len(payload), kind) + payload


def write_ulog(path: Path, topics: Sequence[Topic], start_us: int = 0) -> Path:
    """Write `topics` to a ULog file; data messages are interleaved by ``timestamp``."""
    out = [_MAGIC, struct.pack("<BQ", 1, start_us)]
    out.append(_message(b"B", bytes(16) + struct.pack("<3Q", 0, 0, 0)))
    for name in dict.fromkeys(t.name for t in topics):
        out.append(_message(b"F", next(t for t in topics if t.name == name).format()))
    key = b"char[7] sys_name"
    out.append(_message(b"I", struct.pack("<B", len(key)) + key + b"stochmd"))
    stream = []
    for msg_id, topic in enumerate(topics):
        out.append(_message(b"A", struct.pack("<BH", topic.multi_id, msg_id) + topic.name.encode()))
        stamps = topic.values["timestamp"]
        stream += [(int(s), msg_id, row) for s, row in zip(stamps, topic.rows())]
    for _, msg_id, row in sorted(stream, key=lambda x: (x[0], x[1])):
        out.append(_message(b"D", struct.pack("<H", msg_id) + row))
    path.write_bytes(b"".join(out))
    return path
