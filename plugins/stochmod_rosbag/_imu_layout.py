"""Vectorised decoding of serialised ``sensor_msgs/msg/Imu`` messages.

Deserialising message by message in rosbags (pure Python) costs a Python-level decode per
message, and an IMU bag holds millions. When every message has the same layout (one ``frame_id``, the usual case), the
fields sit at fixed byte offsets and numpy reads them for all messages at once. The layouts
(ROS 2: CDR, little-endian, 8-byte alignment counted after the 4-byte encapsulation header;
ROS 1: packed, little-endian, header with ``seq``):

====================  =========================  =========================
field                 ROS 2 offset               ROS 1 offset
====================  =========================  =========================
stamp sec / nanosec   4 (int32) / 8 (uint32)     4 / 8 (uint32)
frame_id length L     12 (uint32, with the NUL)  12 (uint32, no NUL)
orientation (q)       4 + align8(12 + L)         16 + L
angular_velocity      q + 104                    q + 104
linear_acceleration   q + 200                    q + 200
message length        q + 296                    q + 296
====================  =========================  =========================

:func:`decode` returns None when the messages do not share one such layout; the caller then
deserialises them one by one.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["decode"]


def _column(buf: np.ndarray, offset: int, dtype: str) -> np.ndarray:
    size = np.dtype(dtype).itemsize
    return np.ascontiguousarray(buf[:, offset : offset + size]).view(dtype)[:, 0]


def decode(raws: Sequence[bytes | memoryview], ros2: bool) -> tuple[np.ndarray, np.ndarray] | None:
    """Decode serialised Imu messages of one layout.

    Parameters
    ----------
    raws : sequence of bytes
        The serialised messages, in order.
    ros2 : bool
        CDR (ROS 2) or ROS 1 serialisation.

    Returns
    -------
    (data, stamp_ns) or None
        ``data`` (n, 6): angular_velocity x, y, z and linear_acceleration x, y, z (float64);
        ``stamp_ns`` (n,) int64: ``header.stamp`` in ns. None when the layouts differ, the
        encoding is not little-endian CDR, or a length does not match the layout.
    """
    n = len(raws)
    if n == 0:
        return None
    size = len(raws[0])
    if size < 16 or any(len(r) != size for r in raws):
        return None
    buf = np.frombuffer(b"".join(raws), dtype=np.uint8).reshape(n, size)
    if ros2 and not (np.all(buf[:, 0] == 0) and np.all(buf[:, 1] == 1)):  # CDR_LE encapsulation
        return None
    length = _column(buf, 12, "<u4")
    if np.any(length != length[0]):
        return None
    start = 16 + int(length[0])
    q = 4 + -(-(start - 4) // 8) * 8 if ros2 else start
    if size != q + 296:
        return None
    gyro = [_column(buf, q + 104 + 8 * i, "<f8") for i in range(3)]
    accel = [_column(buf, q + 200 + 8 * i, "<f8") for i in range(3)]
    sec = _column(buf, 4, "<i4" if ros2 else "<u4").astype(np.int64)
    nsec = _column(buf, 8, "<u4").astype(np.int64)
    return np.column_stack(gyro + accel), sec * 10**9 + nsec
