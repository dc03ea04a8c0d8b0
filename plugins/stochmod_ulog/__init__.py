"""PX4 ULog reader: the stochmod plugin for ``.ulg`` flight logs (optional extra ``ulog``: pyulog).

The IMU topics PX4 logs are read as gyro and accelerometer columns in SI with their time
stamps (``timestamp_sample`` where the topic has it, else ``timestamp``; microseconds in the
file, seconds in the :class:`~stochmod.io.recording.Recording`):

=================  =====================================================================
topic              columns
=================  =====================================================================
sensor_combined    gyro_x/y/z from ``gyro_rad[i]`` (rad/s), accel_x/y/z from
                   ``accelerometer_m_s2[i]`` (m/s^2)
vehicle_imu        gyro_x/y/z = ``delta_angle[i] / delta_angle_dt``, accel_x/y/z =
                   ``delta_velocity[i] / delta_velocity_dt`` (the mean over each interval)
sensor_gyro        gyro_x/y/z from ``x, y, z`` (rad/s)
sensor_accel       accel_x/y/z from ``x, y, z`` (m/s^2)
=================  =====================================================================

Options: ``topic`` (default: the first of the table present in the log) and ``instance``
(the topic's multi-instance index, default 0).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from stochmod.sdk import InputError, Reader, Recording, hookimpl, import_optional

__all__ = ["ULogReader", "IMU_TOPICS", "stochmod_readers"]

_GYRO, _ACCEL = ("gyro_x", "gyro_y", "gyro_z"), ("accel_x", "accel_y", "accel_z")
_RAD_S, _M_S2 = "rad/s", "m/s^2"


def _vector(d: dict[str, np.ndarray], name: str) -> list[np.ndarray]:
    return [d[f"{name}[{i}]"].astype(np.float64) for i in range(3)]


def _xyz(d: dict[str, np.ndarray]) -> list[np.ndarray]:
    return [d[a].astype(np.float64) for a in "xyz"]


def _per_second(d: dict[str, np.ndarray], name: str, dt_name: str) -> list[np.ndarray]:
    dt = d[dt_name].astype(np.float64) * 1e-6
    if np.any(dt <= 0):
        raise InputError(f"{dt_name} is not positive at message {int(np.flatnonzero(dt <= 0)[0])}")
    return [v / dt for v in _vector(d, name)]


#: Supported topics: name -> (columns, units, function of the field dict giving the columns).
IMU_TOPICS: dict[str, tuple[tuple[str, ...], tuple[str, ...], Any]] = {
    "sensor_combined": (
        _GYRO + _ACCEL,
        (_RAD_S,) * 3 + (_M_S2,) * 3,
        lambda d: _vector(d, "gyro_rad") + _vector(d, "accelerometer_m_s2"),
    ),
    "vehicle_imu": (
        _GYRO + _ACCEL,
        (_RAD_S,) * 3 + (_M_S2,) * 3,
        lambda d: (
            _per_second(d, "delta_angle", "delta_angle_dt")
            + _per_second(d, "delta_velocity", "delta_velocity_dt")
        ),
    ),
    "sensor_gyro": (_GYRO, (_RAD_S,) * 3, _xyz),
    "sensor_accel": (_ACCEL, (_M_S2,) * 3, _xyz),
}


class ULogReader(Reader):
    """PX4 ULog files (``.ulg``), IMU topics through pyulog."""

    name: ClassVar[str] = "ulog"
    suffixes: ClassVar[tuple[str, ...]] = (".ulg",)
    options: ClassVar[tuple[str, ...]] = ("topic", "instance")
    description: ClassVar[str] = "PX4 ULog: sensor_combined, vehicle_imu, sensor_gyro, sensor_accel"

    def sniff(self, path: Path) -> bool:
        """A file starting with the ULog magic bytes ``ULog\\x01\\x12\\x35``."""
        if not path.is_file():
            return False
        with path.open("rb") as f:
            return f.read(7) == b"ULog\x01\x12\x35"

    def read(self, path: Path, topic: str | None = None, instance: int = 0) -> Recording:
        pyulog = import_optional("pyulog", extra="ulog", what="reading PX4 ULog files")
        wanted = list(IMU_TOPICS) if topic is None else [topic]
        if topic is not None and topic not in IMU_TOPICS:
            raise InputError(
                f"{path}: topic {topic!r} is not an IMU topic the ulog reader knows; "
                f"choose one of {', '.join(IMU_TOPICS)}"
            )
        try:
            log = pyulog.ULog(str(path), message_name_filter_list=wanted)
        except getattr(
            pyulog, "ULogException", ValueError
        ) as exc:  # not a ValueError in pyulog 1.x
            raise InputError(f"cannot read {path} as ULog: {exc}") from None
        found = {(d.name, d.multi_id): d for d in log.data_list}
        present = sorted({name for name, _ in found})
        if topic is None:
            if not present:
                raise InputError(f"{path} holds none of the IMU topics {', '.join(IMU_TOPICS)}")
            topic = next(t for t in IMU_TOPICS if t in present)
        instances = sorted(i for name, i in found if name == topic)
        if not instances:
            logged = pyulog.ULog(str(path), message_name_filter_list=list(IMU_TOPICS)).data_list
            raise InputError(
                f"{path} has no topic {topic!r}; IMU topics in the log: "
                f"{', '.join(sorted({d.name for d in logged})) or 'none'}"
            )
        if int(instance) not in instances:
            raise InputError(
                f"{path}: topic {topic!r} has no instance {instance}; "
                f"instances: {', '.join(map(str, instances))}"
            )
        fields = found[(topic, int(instance))].data
        columns, units, extract = IMU_TOPICS[topic]
        try:
            data = np.column_stack(extract(fields))
        except KeyError as exc:
            raise InputError(f"{path}: topic {topic!r} lacks the field {exc.args[0]!r}") from None
        stamp = "timestamp_sample" if "timestamp_sample" in fields else "timestamp"
        time = fields[stamp].astype(np.float64) * 1e-6
        return Recording(data=data, columns=columns, path=str(path), time=time, units=units)


@hookimpl
def stochmod_readers() -> list[Reader]:
    """Register the ULog reader."""
    return [ULogReader()]
