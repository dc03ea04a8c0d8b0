"""PX4 ULog reader round trips on logs written by the file-format specification
(tests/_ulog_writer.py, independent of pyulog, which only reads).

Truth: the float32 samples and integer microsecond stamps written; the rate they were written
at; the positions of the samples left out.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from _ulog_writer import Topic, write_ulog

from stochmod.core.errors import InputError
from stochmod.io.recording import read_recording
from stochmod.plugin.registry import readers
from stochmod.testing import check_reader

pytest.importorskip("pyulog")

RATE = 250.0
PERIOD_US = 4000
START_US = 7_000_000


def _stamps(n: int, drop: list[int] | None = None) -> np.ndarray:
    k = np.setdiff1d(np.arange(n), drop or [])
    return (START_US + PERIOD_US * k).astype(np.uint64)


def _combined(stamps: np.ndarray, rng: np.random.Generator) -> tuple[Topic, np.ndarray]:
    n = stamps.size
    gyro = rng.normal(0, 0.01, (n, 3)).astype(np.float32)
    accel = (rng.normal(0, 0.05, (n, 3)) + [0, 0, -9.81]).astype(np.float32)
    fields = [
        ("uint64_t", "timestamp", 1),
        ("float", "gyro_rad", 3),
        ("uint32_t", "gyro_integral_dt", 1),
        ("int32_t", "accelerometer_timestamp_relative", 1),
        ("float", "accelerometer_m_s2", 3),
        ("uint32_t", "accelerometer_integral_dt", 1),
        ("uint8_t", "accelerometer_clipping", 1),
    ]
    values = {
        "timestamp": stamps,
        "gyro_rad": gyro,
        "gyro_integral_dt": np.full(n, PERIOD_US, np.uint32),
        "accelerometer_timestamp_relative": np.zeros(n, np.int32),
        "accelerometer_m_s2": accel,
        "accelerometer_integral_dt": np.full(n, PERIOD_US, np.uint32),
        "accelerometer_clipping": np.zeros(n, np.uint8),
    }
    return Topic("sensor_combined", fields, values), np.hstack([gyro, accel]).astype(np.float64)


def _gyro(
    stamps: np.ndarray, rng: np.random.Generator, multi_id: int, delay_us: int = 300
) -> tuple[Topic, np.ndarray]:
    n = stamps.size
    xyz = rng.normal(0, 0.02, (n, 3)).astype(np.float32)
    fields = [
        ("uint64_t", "timestamp", 1),
        ("uint64_t", "timestamp_sample", 1),
        ("uint32_t", "device_id", 1),
        ("float", "x", 1),
        ("float", "y", 1),
        ("float", "z", 1),
        ("float", "temperature", 1),
    ]
    values = {
        "timestamp": stamps + delay_us,
        "timestamp_sample": stamps,
        "device_id": np.full(n, 2490378 + multi_id, np.uint32),
        "x": xyz[:, 0],
        "y": xyz[:, 1],
        "z": xyz[:, 2],
        "temperature": np.full(n, 41.5, np.float32),
    }
    return Topic("sensor_gyro", fields, values, multi_id=multi_id), xyz.astype(np.float64)


def test_sensor_combined_round_trip(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    stamps = _stamps(500)
    topic, truth = _combined(stamps, rng)
    path = write_ulog(tmp_path / "flight.ulg", [topic])
    rec = read_recording(path)
    assert rec.columns == ("gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z")
    assert rec.units == ("rad/s",) * 3 + ("m/s^2",) * 3
    np.testing.assert_array_equal(rec.data, truth)
    np.testing.assert_array_equal(rec.time, stamps * 1e-6)
    assert rec.freq == pytest.approx(RATE, rel=1e-12)
    assert not rec.timing.has_gaps and rec.timing.jitter_max < 1e-12
    assert check_reader(readers()["ulog"], path, expected=truth)["rate"] == pytest.approx(
        RATE, rel=1e-12
    )


def test_topic_and_instance_options(tmp_path: Path) -> None:
    rng = np.random.default_rng(2)
    stamps = _stamps(300)
    combined, _ = _combined(stamps, rng)
    gyro0, truth0 = _gyro(stamps, rng, 0)
    gyro1, truth1 = _gyro(stamps, rng, 1)
    path = write_ulog(tmp_path / "multi.ulg", [combined, gyro0, gyro1])
    rec1 = read_recording(path, topic="sensor_gyro", instance=1)
    np.testing.assert_array_equal(rec1.data, truth1)
    assert rec1.columns == ("gyro_x", "gyro_y", "gyro_z")
    # timestamp_sample (the sensor's), not the publication timestamp 300 us later
    np.testing.assert_array_equal(rec1.time, stamps * 1e-6)
    np.testing.assert_array_equal(read_recording(path, topic="sensor_gyro").data, truth0)
    assert read_recording(path).data.shape[1] == 6  # default: sensor_combined, the first present
    with pytest.raises(InputError, match=r"topic 'sensor_gyro' has no instance 2; instances: 0, 1"):
        read_recording(path, topic="sensor_gyro", instance=2)
    with pytest.raises(
        InputError,
        match=r"has no topic 'sensor_accel'; IMU topics in the log: "
        r"sensor_combined, sensor_gyro",
    ):
        read_recording(path, topic="sensor_accel")
    with pytest.raises(InputError, match="'vehicle_attitude' is not an IMU topic"):
        read_recording(path, topic="vehicle_attitude")


def test_vehicle_imu_increments_become_rates(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    n = 200
    stamps = _stamps(n)
    dt_us = rng.integers(3900, 4100, n).astype(np.uint16)  # the integration intervals vary
    rate = rng.normal(0, 0.05, (n, 3))
    acc = rng.normal(0, 0.2, (n, 3)) + [0, 0, -9.80665]
    fields = [
        ("uint64_t", "timestamp", 1),
        ("uint64_t", "timestamp_sample", 1),
        ("uint32_t", "accel_device_id", 1),
        ("uint32_t", "gyro_device_id", 1),
        ("float", "delta_angle", 3),
        ("float", "delta_velocity", 3),
        ("uint16_t", "delta_angle_dt", 1),
        ("uint16_t", "delta_velocity_dt", 1),
    ]
    values = {
        "timestamp": stamps + 50,
        "timestamp_sample": stamps,
        "accel_device_id": np.ones(n, np.uint32),
        "gyro_device_id": np.ones(n, np.uint32),
        "delta_angle": (rate * dt_us[:, None] * 1e-6).astype(np.float32),
        "delta_velocity": (acc * dt_us[:, None] * 1e-6).astype(np.float32),
        "delta_angle_dt": dt_us,
        "delta_velocity_dt": dt_us,
    }
    path = write_ulog(tmp_path / "vimu.ulg", [Topic("vehicle_imu", fields, values)])
    rec = read_recording(path)
    # float32 increments: the rates come back to float32 precision
    np.testing.assert_allclose(rec.data, np.hstack([rate, acc]), rtol=2e-7, atol=1e-9)
    assert rec.freq == pytest.approx(RATE, rel=1e-12)


def test_dropped_samples_are_refused_where_they_are_or_split(tmp_path: Path) -> None:
    rng = np.random.default_rng(4)
    stamps = _stamps(400, drop=[100, 250, 251, 252])
    topic, truth = _combined(stamps, rng)
    path = write_ulog(tmp_path / "gaps.ulg", [topic])
    t_gap = (START_US + 99 * PERIOD_US) * 1e-6
    with pytest.raises(
        InputError,
        match=rf"2 gap\(s\).*4 sample\(s\) missing.*after sample 99 "
        rf"\(t = {t_gap:g} s\)",
    ):
        read_recording(path)
    rec = read_recording(path, split_gaps=True)
    assert [(g.index, g.missing) for g in rec.timing.gaps] == [(99, 1), (248, 3)]
    assert rec.freq == pytest.approx(RATE, rel=1e-12)
    pieces = rec.segments()
    assert [p.data.shape[0] for p in pieces] == [100, 149, 147]
    np.testing.assert_array_equal(np.vstack([p.data for p in pieces]), truth)


def test_not_a_ulog_file(tmp_path: Path) -> None:
    path = tmp_path / "broken.ulg"
    path.write_bytes(b"not a log at all, just text")
    with pytest.raises(InputError, match="broken.ulg"):
        read_recording(path)


def test_log_without_imu_topics(tmp_path: Path) -> None:
    stamps = _stamps(20)
    fields = [("uint64_t", "timestamp", 1), ("float", "q", 4)]
    attitude = Topic(
        "vehicle_attitude",
        fields,
        {"timestamp": stamps, "q": np.tile(np.float32([1, 0, 0, 0]), (20, 1))},
    )
    path = write_ulog(tmp_path / "att.ulg", [attitude])
    with pytest.raises(
        InputError, match="holds none of the IMU topics sensor_combined, vehicle_imu"
    ):
        read_recording(path)
    renamed = tmp_path / "att.log"  # found by its magic bytes whatever the suffix
    renamed.write_bytes(path.read_bytes())
    with pytest.raises(InputError, match="holds none of the IMU topics"):
        read_recording(renamed)
