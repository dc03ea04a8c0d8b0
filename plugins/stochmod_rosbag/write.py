"""Writing ``sensor_msgs/msg/Imu`` bags with rosbags' writers (simulated data for a navigation
stack, the reader's round-trip tests and its benchmark)."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from stochmod.sdk import InputError, StochmodError, import_optional

__all__ = ["write_imu_bag"]


def _checked(stamp_ns: ArrayLike, gyro: ArrayLike, accel: ArrayLike) -> tuple[np.ndarray, ...]:
    t = np.asarray(stamp_ns)
    if t.ndim != 1 or not np.issubdtype(t.dtype, np.integer):
        raise InputError(
            f"stamp_ns must be a 1-D integer array of nanoseconds, got {t.dtype} {t.shape}"
        )
    g, a = np.asarray(gyro, dtype=np.float64), np.asarray(accel, dtype=np.float64)
    if g.shape != (t.size, 3) or a.shape != (t.size, 3):
        raise InputError(
            f"gyro and accel must have shape ({t.size}, 3), got {g.shape} and {a.shape}"
        )
    return t.astype(np.int64), g, a


def write_imu_bag(
    path: str | Path,
    stamp_ns: ArrayLike,
    gyro: ArrayLike,
    accel: ArrayLike,
    *,
    topic: str = "/imu",
    ros: Literal[1, 2] = 2,
    storage: Literal["sqlite3", "mcap"] = "sqlite3",
    frame_id: str = "imu",
    receive_delay_ns: int = 0,
) -> Path:
    """Write one ``sensor_msgs/msg/Imu`` message per sample to a new bag.

    Parameters
    ----------
    path : str or Path
        The bag to create: a folder for ROS 2, a ``.bag`` file for ROS 1 (must not exist).
    stamp_ns : array_like of int, shape (n,)
        ``header.stamp`` of each message, ns.
    gyro, accel : array_like, shape (n, 3)
        ``angular_velocity`` (rad/s) and ``linear_acceleration`` (m/s^2).
    topic : str
        Topic name.
    ros : {1, 2}
        Bag format.
    storage : {"sqlite3", "mcap"}
        ROS 2 storage plugin.
    frame_id : str
        ``header.frame_id``.
    receive_delay_ns : int
        The bag's receive time minus the header stamp, ns.

    Returns
    -------
    Path
        `path`.
    """
    import_optional("rosbags", extra="rosbag", what="writing ROS bags")
    from rosbags.typesys import Stores, get_typestore

    t, g, a = _checked(stamp_ns, gyro, accel)
    path = Path(path)
    store = get_typestore(Stores.LATEST if ros == 2 else Stores.ROS1_NOETIC)
    types = store.types
    imu, header, time = (
        types["sensor_msgs/msg/Imu"],
        types["std_msgs/msg/Header"],
        types["builtin_interfaces/msg/Time"],
    )
    vec, quat = types["geometry_msgs/msg/Vector3"], types["geometry_msgs/msg/Quaternion"]
    zeros = np.zeros(9)
    if ros == 2:
        from rosbags.rosbag2 import StoragePlugin, Writer

        writer = Writer(
            path, version=Writer.VERSION_LATEST, storage_plugin=StoragePlugin[storage.upper()]
        )
        serialize = store.serialize_cdr
    else:
        from rosbags.rosbag1 import Writer  # type: ignore[assignment]

        writer = Writer(path)
        serialize = store.serialize_ros1
    # One message serialised by rosbags with marker values, then every sample written into a
    # copy of its bytes at the markers' offsets (serialising 10^6 messages one by one is slow).
    markers = {
        "seq": 0x5E0_1234,
        "sec": 0x5EC_5678,
        "nanosec": 0x0A5_9ABC,
        **{
            f"{v}{c}": (i * 3 + j + 1) * 1.0e-301
            for i, v in enumerate("wa")
            for j, c in enumerate("xyz")
        },
    }
    stamp = time(sec=markers["sec"], nanosec=markers["nanosec"])
    head = (
        header(seq=markers["seq"], stamp=stamp, frame_id=frame_id)
        if ros == 1
        else header(stamp=stamp, frame_id=frame_id)
    )
    template = np.frombuffer(
        bytes(
            serialize(
                imu(
                    header=head,
                    orientation=quat(x=0.0, y=0.0, z=0.0, w=1.0),
                    orientation_covariance=zeros,
                    angular_velocity=vec(x=markers["wx"], y=markers["wy"], z=markers["wz"]),
                    angular_velocity_covariance=zeros,
                    linear_acceleration=vec(x=markers["ax"], y=markers["ay"], z=markers["az"]),
                    linear_acceleration_covariance=zeros,
                ),
                imu.__msgtype__,
            )
        ),
        dtype=np.uint8,
    )
    sec, nsec = np.divmod(t, 10**9)
    values = {
        "seq": np.arange(t.size) % 2**32,
        "sec": sec,
        "nanosec": nsec,
        **{f"w{c}": g[:, j] for j, c in enumerate("xyz")},
        **{f"a{c}": a[:, j] for j, c in enumerate("xyz")},
    }
    rows = np.tile(template, (t.size, 1))
    for key, marker in markers.items():
        if key == "seq" and ros == 2:
            continue
        code = "<f8" if isinstance(marker, float) else "<u4"
        pattern = np.array(marker, dtype=code).tobytes()
        at = template.tobytes().find(pattern)
        if at < 0 or template.tobytes().find(pattern, at + 1) >= 0:  # a changed message definition
            raise StochmodError(f"cannot locate {key} in the serialised {imu.__msgtype__}")
        rows[:, at : at + len(pattern)] = (
            values[key].astype(code).view(np.uint8).reshape(t.size, -1)
        )
    with writer:
        conn = writer.add_connection(topic, imu.__msgtype__, typestore=store)
        for i in range(t.size):
            writer.write(conn, int(t[i]) + receive_delay_ns, rows[i].data)
    return path
