"""Writing ``sensor_msgs/msg/Imu`` bags with rosbags' writers (simulated data for a navigation
stack, the reader's round-trip tests and its benchmark)."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from stochmod.errors import InputError
from stochmod.io import import_optional

__all__ = ["write_imu_bag"]


def _checked(stamp_ns: ArrayLike, gyro: ArrayLike, accel: ArrayLike) -> tuple[np.ndarray, ...]:
    t = np.asarray(stamp_ns)
    if t.ndim != 1 or not np.issubdtype(t.dtype, np.integer):
        raise InputError(f"stamp_ns must be a 1-D integer array of nanoseconds, got {t.dtype} {t.shape}")
    g, a = np.asarray(gyro, dtype=np.float64), np.asarray(accel, dtype=np.float64)
    if g.shape != (t.size, 3) or a.shape != (t.size, 3):
        raise InputError(f"gyro and accel must have shape ({t.size}, 3), got {g.shape} and {a.shape}")
    return t.astype(np.int64), g, a


def write_imu_bag(path: str | Path, stamp_ns: ArrayLike, gyro: ArrayLike, accel: ArrayLike, *,
                  topic: str = "/imu", ros: Literal[1, 2] = 2, storage: Literal["sqlite3", "mcap"] = "sqlite3",
                  frame_id: str = "imu", receive_delay_ns: int = 0) -> Path:
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
    imu, header, time = types["sensor_msgs/msg/Imu"], types["std_msgs/msg/Header"], types["builtin_interfaces/msg/Time"]
    vec, quat = types["geometry_msgs/msg/Vector3"], types["geometry_msgs/msg/Quaternion"]
    zeros = np.zeros(9)
    if ros == 2:
        from rosbags.rosbag2 import StoragePlugin, Writer

        writer = Writer(path, version=Writer.VERSION_LATEST, storage_plugin=StoragePlugin[storage.upper()])
        serialize = store.serialize_cdr
    else:
        from rosbags.rosbag1 import Writer  # type: ignore[assignment]

        writer = Writer(path)
        serialize = store.serialize_ros1
    extra = {"seq": 0} if ros == 1 else {}
    with writer:
        conn = writer.add_connection(topic, imu.__msgtype__, typestore=store)
        for i in range(t.size):
            sec, nsec = divmod(int(t[i]), 10**9)
            msg = imu(header=header(**extra, stamp=time(sec=sec, nanosec=nsec), frame_id=frame_id),
                      orientation=quat(x=0.0, y=0.0, z=0.0, w=1.0), orientation_covariance=zeros,
                      angular_velocity=vec(x=g[i, 0], y=g[i, 1], z=g[i, 2]), angular_velocity_covariance=zeros,
                      linear_acceleration=vec(x=a[i, 0], y=a[i, 1], z=a[i, 2]),
                      linear_acceleration_covariance=zeros)
            writer.write(conn, int(t[i]) + receive_delay_ns, serialize(msg, imu.__msgtype__))
    return path
