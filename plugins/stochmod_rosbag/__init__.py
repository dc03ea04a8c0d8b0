"""ROS 1 and ROS 2 bag reader: the stochmod plugin for ``sensor_msgs/msg/Imu`` topics
(optional extra ``rosbag``: rosbags, pure Python).

A ROS 2 bag is its folder (``metadata.yaml`` with ``.db3`` or ``.mcap`` storage); its storage
file is accepted too and read through the folder. A ROS 1 bag is a ``.bag`` file. The columns
are gyro_x/y/z from ``angular_velocity`` (rad/s) and accel_x/y/z from ``linear_acceleration``
(m/s^2), in the order the bag stores the messages.

Options: ``topic`` (required when the bag holds several Imu topics) and ``stamp``:
``"header"`` (default, the sensor's ``header.stamp``) or ``"bag"`` (the time the recorder
received the message).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from stochmod.sdk import InputError, Reader, Recording, hookimpl, import_optional
from stochmod_rosbag._imu_layout import decode

__all__ = ["RosbagReader", "IMU_TYPE", "stochmod_readers"]

#: The message type read (ROS 1 ``sensor_msgs/Imu`` is normalised to this name by rosbags).
IMU_TYPE = "sensor_msgs/msg/Imu"
_COLUMNS = ("gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z")
_UNITS = ("rad/s",) * 3 + ("m/s^2",) * 3


def _bag_root(path: Path) -> Path:
    """The folder of a ROS 2 bag given its folder or one of its storage files; else `path`."""
    if (
        path.is_file()
        and path.suffix.lower() in {".db3", ".mcap"}
        and (path.parent / "metadata.yaml").is_file()
    ):
        return path.parent
    return path


def _choose_topic(path: Path, connections: list[Any], topic: str | None) -> str:
    imu_topics = sorted({c.topic for c in connections if c.msgtype == IMU_TYPE})
    if topic is None:
        if len(imu_topics) != 1:
            raise InputError(
                f"{path} holds {len(imu_topics)} {IMU_TYPE} topics "
                f"({', '.join(imu_topics) or 'none'}): choose one with topic= (--topic)"
            )
        return imu_topics[0]
    types = {c.msgtype for c in connections if c.topic == topic}
    if not types:
        raise InputError(
            f"{path} has no topic {topic!r}; {IMU_TYPE} topics: {', '.join(imu_topics) or 'none'}"
        )
    if IMU_TYPE not in types:
        raise InputError(
            f"{path}: topic {topic!r} carries {', '.join(sorted(types))}, not {IMU_TYPE}"
        )
    return topic


def _deserialise(bag: Any, messages: list[tuple[Any, int, Any]]) -> tuple[np.ndarray, np.ndarray]:
    """Samples and header stamps (ns) of each message through rosbags' deserialiser."""
    rows, stamps = [], []
    for conn, _, raw in messages:
        msg = bag.deserialize(raw, conn.msgtype)
        w, a, st = msg.angular_velocity, msg.linear_acceleration, msg.header.stamp
        rows.append((w.x, w.y, w.z, a.x, a.y, a.z))
        stamps.append(st.sec * 10**9 + st.nanosec)
    return np.asarray(rows, dtype=np.float64), np.asarray(stamps, dtype=np.int64)


#: Messages decoded per batch: bounds the memory held in serialised form.
CHUNK = 65536


def _read_messages(bag: Any, chosen: list[Any]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Samples (n, 6), header stamps and receive times (ns) of the chosen connections.

    Batches of :data:`CHUNK` messages are decoded at once (:func:`decode`), or one by one by
    rosbags where a batch mixes layouts.
    """
    parts: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    batch: list[tuple[Any, int, Any]] = []

    def flush() -> None:
        decoded = decode([raw for _, _, raw in batch], ros2=bag.is2)
        data, header_ns = _deserialise(bag, batch) if decoded is None else decoded
        parts.append((data, header_ns, np.array([t for _, t, _ in batch], dtype=np.int64)))
        batch.clear()

    for item in bag.messages(connections=chosen):
        batch.append(item)
        if len(batch) == CHUNK:
            flush()
    if batch:
        flush()
    if not parts:
        return np.empty((0, 6)), np.empty(0, np.int64), np.empty(0, np.int64)
    data, header_ns, received = zip(*parts)
    return np.vstack(data), np.concatenate(header_ns), np.concatenate(received)


class RosbagReader(Reader):
    """ROS 1 ``.bag`` files and ROS 2 bag folders, ``sensor_msgs/msg/Imu`` through rosbags."""

    name: ClassVar[str] = "rosbag"
    suffixes: ClassVar[tuple[str, ...]] = (".bag", ".db3", ".mcap")
    options: ClassVar[tuple[str, ...]] = ("topic", "stamp")
    description: ClassVar[str] = "ROS 1 .bag and ROS 2 bag folders: sensor_msgs/msg/Imu"

    def sniff(self, path: Path) -> bool:
        """A folder holding a ROS 2 ``metadata.yaml``."""
        return path.is_dir() and (path / "metadata.yaml").is_file()

    def read(self, path: Path, topic: str | None = None, stamp: str = "header") -> Recording:
        if stamp not in ("header", "bag"):
            raise InputError(f"stamp must be 'header' or 'bag', got {stamp!r}")
        import_optional("rosbags", extra="rosbag", what="reading ROS bags")
        from rosbags.highlevel import AnyReader, AnyReaderError
        from rosbags.typesys import Stores, get_typestore

        root = _bag_root(path)
        try:
            with AnyReader([root], default_typestore=get_typestore(Stores.LATEST)) as bag:
                name = _choose_topic(path, bag.connections, topic)
                chosen = [c for c in bag.connections if c.topic == name and c.msgtype == IMU_TYPE]
                data, header_ns, received = _read_messages(bag, chosen)
        except AnyReaderError as exc:
            raise InputError(f"cannot read {path} as a ROS bag: {exc}") from None
        if data.shape[0] == 0:
            raise InputError(f"{path}: topic {name!r} holds no messages")
        ns = header_ns if stamp == "header" else received
        # seconds after the first stamp: exact in float64, where Unix seconds would lose ~0.2 us
        return Recording(
            data=data,
            columns=_COLUMNS,
            path=str(path),
            time=(ns - ns[0]) * 1e-9,
            time_origin=ns[0] * 1e-9,
            units=_UNITS,
        )


@hookimpl
def stochmod_readers() -> list[Reader]:
    """Register the ROS bag reader."""
    return [RosbagReader()]
