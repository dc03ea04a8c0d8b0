"""ROS 1 and ROS 2 bag reader round trips on bags written with rosbags' writers.

Truth: the samples and integer nanosecond header stamps written; the rate they were written
at; the positions of the samples left out.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from stochmod.core.errors import InputError
from stochmod.io.recording import read_recording
from stochmod.plugin.registry import readers
from stochmod.testing import check_reader

pytest.importorskip("rosbags")
from stochmod_rosbag.write import write_imu_bag

RATE = 200.0
PERIOD_NS = 5_000_000
EPOCH_NS = 1_733_100_000_123_456_789  # a Unix time: seconds lose ~0.2 us in float64


def _imu(
    n: int, seed: int, drop: list[int] | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    k = np.setdiff1d(np.arange(n), drop or [])
    rng = np.random.default_rng(seed)
    gyro = rng.normal(0, 0.01, (k.size, 3))
    accel = rng.normal(0, 0.05, (k.size, 3)) + [0.0, 0.0, 9.80665]
    return EPOCH_NS + PERIOD_NS * k, gyro, accel


@pytest.mark.parametrize(
    ("ros", "storage", "name"),
    [(2, "sqlite3", "bag2"), (2, "mcap", "bag2m"), (1, "sqlite3", "bag1.bag")],
)
def test_round_trip_samples_rate_and_stamps(
    tmp_path: Path, ros: int, storage: str, name: str
) -> None:
    stamps, gyro, accel = _imu(400, seed=ros)
    path = write_imu_bag(
        tmp_path / name, stamps, gyro, accel, ros=ros, storage=storage, topic="/imu0"
    )
    rec = read_recording(path, topic="/imu0")
    truth = np.hstack([gyro, accel])
    np.testing.assert_array_equal(rec.data, truth)
    assert rec.columns == ("gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z")
    assert rec.units == ("rad/s",) * 3 + ("m/s^2",) * 3
    assert rec.time_origin == EPOCH_NS * 1e-9
    np.testing.assert_allclose(rec.time, (stamps - EPOCH_NS) * 1e-9, rtol=0, atol=1e-15)
    assert rec.freq == pytest.approx(RATE, rel=1e-12)
    assert rec.timing.jitter_max < 1e-12 and not rec.timing.has_gaps
    check_reader(readers()["rosbag"], path, expected=truth, topic="/imu0")


def test_ros2_bag_is_its_folder_or_its_storage_file(tmp_path: Path) -> None:
    stamps, gyro, accel = _imu(50, seed=3)
    folder = write_imu_bag(tmp_path / "run", stamps, gyro, accel)
    by_folder = read_recording(folder)  # one Imu topic: no --topic needed
    (db3,) = folder.glob("*.db3")
    np.testing.assert_array_equal(read_recording(db3).data, by_folder.data)
    assert readers()["rosbag"].sniff(folder) and not readers()["rosbag"].sniff(tmp_path)


def test_bag_receive_stamps(tmp_path: Path) -> None:
    stamps, gyro, accel = _imu(60, seed=4)
    path = write_imu_bag(tmp_path / "late", stamps, gyro, accel, receive_delay_ns=2_000_000)
    rec = read_recording(path, stamp="bag")
    assert rec.time_origin == (EPOCH_NS + 2_000_000) * 1e-9
    np.testing.assert_allclose(rec.time, (stamps - EPOCH_NS) * 1e-9, atol=1e-15)
    with pytest.raises(InputError, match="stamp must be 'header' or 'bag'"):
        read_recording(path, stamp="receive")


def test_gaps_in_header_stamps(tmp_path: Path) -> None:
    stamps, gyro, accel = _imu(300, seed=5, drop=[40, 41, 200])
    path = write_imu_bag(tmp_path / "gaps", stamps, gyro, accel)
    with pytest.raises(
        InputError,
        match=r"2 gap\(s\).*3 sample\(s\) missing at 200 Hz.*after sample 39 "
        r"\(t = 0.195 s\).*after sample 197 \(t = 0.995 s\)",
    ):
        read_recording(path)
    rec = read_recording(path, split_gaps=True)
    assert [(g.index, g.missing) for g in rec.timing.gaps] == [(39, 2), (197, 1)]
    assert [p.data.shape[0] for p in rec.segments()] == [40, 158, 99]
    assert rec.freq == pytest.approx(RATE, rel=1e-12)


def test_topic_errors(tmp_path: Path) -> None:
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.LATEST)
    string = store.types["std_msgs/msg/String"]
    path = tmp_path / "chatter"
    with Writer(path, version=Writer.VERSION_LATEST) as writer:
        conn = writer.add_connection("/chatter", string.__msgtype__, typestore=store)
        writer.write(conn, 1, store.serialize_cdr(string(data="hi"), string.__msgtype__))
    with pytest.raises(
        InputError, match=r"holds 0 sensor_msgs/msg/Imu topics \(none\): choose one"
    ):
        read_recording(path)
    with pytest.raises(
        InputError, match="topic '/chatter' carries std_msgs/msg/String, not sensor_msgs/msg/Imu"
    ):
        read_recording(path, topic="/chatter")
    with pytest.raises(InputError, match="has no topic '/imu'"):
        read_recording(path, topic="/imu")


def test_cli_reads_a_bag_by_topic(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import json

    from stochmod.cli import main
    from stochmod.empirical.wavelet_variance import wvar

    stamps, gyro, accel = _imu(4096, seed=6)
    path = write_imu_bag(tmp_path / "cli", stamps, gyro, accel, topic="/imu/data")
    assert main(["wv", str(path), "--topic", "/imu/data", "--column", "gyro_y", "--json"]) == 0
    captured = capsys.readouterr()
    out = json.loads(captured.out)
    assert out["freq"] == pytest.approx(RATE, rel=1e-12)
    np.testing.assert_allclose(
        out["columns"]["gyro_y"]["wv"], wvar(gyro[:, 1], RATE).wv, rtol=1e-12
    )
    assert "4096 samples at 200 Hz from the time stamps, 0 gap(s)" in captured.err
    assert (
        main(
            [
                "calibrate",
                str(path),
                "--topic",
                "/imu/data",
                "--column",
                "accel_z",
                "--no-plots",
                "--candidates",
                "WN",
                "RW+WN",
                "--out",
                str(tmp_path / "out"),
                "--json",
            ]
        )
        == 0
    )
    report = json.loads(capsys.readouterr().out)
    assert report["freq"] == pytest.approx(RATE, rel=1e-12) and report["n"] == 4096
    assert list(report["columns"]) == ["accel_z"]


@pytest.mark.parametrize("ros", [1, 2])
def test_vectorised_decoding_equals_rosbags_deserialiser(tmp_path: Path, ros: int) -> None:
    """Every frame_id length 0..9 (all CDR alignments), against rosbags message by message."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore
    from stochmod_rosbag._imu_layout import decode

    for length in range(10):
        stamps, gyro, accel = _imu(20, seed=length)
        name = f"f{length}.bag" if ros == 1 else f"f{length}"
        path = write_imu_bag(tmp_path / name, stamps, gyro, accel, ros=ros, frame_id="x" * length)
        with AnyReader([path], default_typestore=get_typestore(Stores.LATEST)) as bag:
            messages = list(bag.messages())
            msgs = [bag.deserialize(raw, c.msgtype) for c, _, raw in messages]
            data, ns = decode([raw for _, _, raw in messages], ros2=(ros == 2))
        want = np.array(
            [
                [
                    m.angular_velocity.x,
                    m.angular_velocity.y,
                    m.angular_velocity.z,
                    m.linear_acceleration.x,
                    m.linear_acceleration.y,
                    m.linear_acceleration.z,
                ]
                for m in msgs
            ]
        )
        np.testing.assert_array_equal(data, want)
        np.testing.assert_array_equal(
            ns, [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in msgs]
        )
        np.testing.assert_array_equal(ns, stamps)


def test_mixed_frame_ids_fall_back_to_rosbags(tmp_path: Path) -> None:
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.LATEST)
    ty = store.types
    stamps, gyro, accel = _imu(30, seed=8)
    path = tmp_path / "mixed"
    with Writer(path, version=Writer.VERSION_LATEST) as writer:
        conn = writer.add_connection("/imu", "sensor_msgs/msg/Imu", typestore=store)
        for i, t in enumerate(stamps):
            sec, nsec = divmod(int(t), 10**9)
            head = ty["std_msgs/msg/Header"](
                stamp=ty["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec),
                frame_id="imu" if i % 2 else "imu_link",
            )
            vec = ty["geometry_msgs/msg/Vector3"]
            msg = ty["sensor_msgs/msg/Imu"](
                header=head,
                orientation=ty["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                orientation_covariance=np.zeros(9),
                angular_velocity=vec(*gyro[i]),
                angular_velocity_covariance=np.zeros(9),
                linear_acceleration=vec(*accel[i]),
                linear_acceleration_covariance=np.zeros(9),
            )
            writer.write(conn, int(t), store.serialize_cdr(msg, "sensor_msgs/msg/Imu"))
    rec = read_recording(path)
    np.testing.assert_array_equal(rec.data, np.hstack([gyro, accel]))
    np.testing.assert_allclose(rec.time, (stamps - EPOCH_NS) * 1e-9, atol=1e-15)


def test_batches_join_exactly(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import stochmod_rosbag

    stamps, gyro, accel = _imu(50, seed=9, drop=[23])
    path = write_imu_bag(tmp_path / "chunks", stamps, gyro, accel, receive_delay_ns=7)
    monkeypatch.setattr(stochmod_rosbag, "CHUNK", 7)  # 8 batches, the last one short
    rec = read_recording(path, split_gaps=True)
    np.testing.assert_array_equal(rec.data, np.hstack([gyro, accel]))
    np.testing.assert_allclose(rec.time, (stamps - EPOCH_NS) * 1e-9, atol=1e-15)
    assert [(g.index, g.missing) for g in rec.timing.gaps] == [(22, 1)]
    bag = read_recording(path, split_gaps=True, stamp="bag")
    assert bag.time_origin == (EPOCH_NS + 7) * 1e-9
