"""Benchmark: reading sensor_msgs/Imu from a ROS 2 bag, stochmod vs rosbags' own loop.

Run: ``python bench/bench_rosbag.py [MINUTES]`` (default 60: a 1-hour 200 Hz bag, 720,000
messages, written first to a temporary folder with rosbags' writer). Times, in the same
process, best of 2 each:

- stochmod: ``read_recording(bag, topic="/imu")``: messages deserialised, columns in SI, time
  stamps checked (rate, gaps, jitter);
- rosbags: the bare loop ``for conn, t, raw in reader.messages(...): reader.deserialize(raw, ...)``
  that every rosbags user writes, keeping nothing.

The target is a ratio within 2x. Timings on a shared machine are noisy.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _timing import best_of
from stochmod_rosbag.write import write_imu_bag

from stochmod.io.recording import read_recording

RATE = 200.0
TOPIC = "/imu"


def raw_loop(bag: Path) -> int:
    """rosbags' own deserialisation loop over the Imu topic (the peer)."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    count = 0
    with AnyReader([bag], default_typestore=get_typestore(Stores.LATEST)) as reader:
        conns = [c for c in reader.connections if c.topic == TOPIC]
        for conn, _, raw in reader.messages(connections=conns):
            reader.deserialize(raw, conn.msgtype)
            count += 1
    return count


def main(minutes: float = 60.0) -> None:
    n = int(minutes * 60 * RATE)
    rng = np.random.default_rng(20241202)
    stamps = 1_733_100_000 * 10**9 + np.arange(n, dtype=np.int64) * int(1e9 / RATE)
    gyro = rng.normal(0.0, 1e-3, (n, 3))
    accel = rng.normal(0.0, 1e-2, (n, 3)) + [0.0, 0.0, 9.80665]
    with tempfile.TemporaryDirectory() as tmp:
        bag = Path(tmp) / "imu_bag"
        t0 = time.perf_counter()
        write_imu_bag(bag, stamps, gyro, accel, topic=TOPIC)
        t_write = time.perf_counter() - t0
        rec = read_recording(bag, topic=TOPIC)  # also warms imports and the page cache
        assert np.array_equal(rec.data, np.hstack([gyro, accel])) and raw_loop(bag) == n
        t_sm = best_of(lambda: read_recording(bag, topic=TOPIC), repeat=2)
        t_raw = best_of(lambda: raw_loop(bag), repeat=2)
    print(
        f"ROS 2 bag (sqlite3), {n:,} sensor_msgs/Imu messages = {minutes:g} min at {RATE:g} Hz "
        f"(written in {t_write:.1f} s)"
    )
    print(f"stochmod read_recording              {t_sm:8.2f} s  ({t_sm / n * 1e6:5.1f} us/message)")
    print(
        f"rosbags raw deserialisation loop     {t_raw:8.2f} s  ({t_raw / n * 1e6:5.1f} us/message)"
    )
    print(
        f"ratio stochmod / rosbags = {t_sm / t_raw:.2f} (target <= 2); rate read "
        f"{rec.freq:.6f} Hz, {len(rec.timing.gaps)} gaps"
    )


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else 60.0)
