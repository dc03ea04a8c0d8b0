"""The ``navigate`` CLI's input readers on files written here: layouts, case-insensitive headers,
optional GNSS triples, and a clear InputError for every malformed file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from stochmod.core.errors import InputError
from stochmod.nav.logs import read_gnss_csv, read_imu_csv

RNG = np.random.default_rng(7)
TIME = 100.0 + 0.01 * np.arange(50)
GYRO = RNG.normal(0.0, 0.1, (50, 3))
ACCEL = RNG.normal(0.0, 1.0, (50, 3)) + [0.0, 0.0, -9.8]


def _write(path: Path, header: list[str], columns: list[np.ndarray]) -> Path:
    data = np.column_stack(columns)
    rows = [",".join(header)] + [",".join(repr(float(v)) for v in row) for row in data]
    path.write_text("\n".join(rows) + "\n")
    return path


@pytest.mark.parametrize(
    ("names", "kind"),
    [
        (["time", "gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"], "rate"),
        (["Time", "DTHETA_X", "dtheta_y", "dTheta_z", "dv_x", "DV_Y", " dv_z "], "increment"),
    ],
)
def test_imu_layouts_round_trip(tmp_path: Path, names: list[str], kind: str) -> None:
    step = 0.01 if kind == "increment" else 1.0  # increments over the 10 ms sample interval
    path = _write(tmp_path / "imu.csv", names, [TIME, *(step * GYRO.T), *(step * ACCEL.T)])
    imu = read_imu_csv(path)
    assert imu.kind == kind
    np.testing.assert_array_equal(imu.time, TIME)
    np.testing.assert_array_equal(imu.gyro, step * GYRO)
    np.testing.assert_array_equal(imu.accel, step * ACCEL)


def test_imu_columns_in_any_order(tmp_path: Path) -> None:
    names = ["accel_z", "gyro_y", "time", "accel_x", "gyro_z", "gyro_x", "accel_y"]
    cols = {"time": TIME, "gyro_x": GYRO[:, 0], "gyro_y": GYRO[:, 1], "gyro_z": GYRO[:, 2],
            "accel_x": ACCEL[:, 0], "accel_y": ACCEL[:, 1], "accel_z": ACCEL[:, 2]}
    imu = read_imu_csv(_write(tmp_path / "imu.csv", names, [cols[n] for n in names]))
    np.testing.assert_array_equal(imu.gyro, GYRO)
    np.testing.assert_array_equal(imu.accel, ACCEL)


def test_gnss_optional_triples(tmp_path: Path) -> None:
    t = np.arange(5.0)
    lat, lon, h = 45.0 + 1e-5 * t, 7.0 - 1e-5 * t, 300.0 + t
    vel = RNG.normal(size=(5, 3))
    sd = 0.5 + RNG.uniform(size=(5, 3))
    base = read_gnss_csv(_write(tmp_path / "a.csv", ["time", "lat", "lon", "height"],
                                [t, lat, lon, h]))
    assert base.vel_ned is None and base.sd is None
    np.testing.assert_array_equal(base.lat, lat)
    np.testing.assert_array_equal(base.height, h)
    full = read_gnss_csv(_write(
        tmp_path / "b.csv",
        ["TIME", "Lat", "lon", "height", "sd_n", "sd_e", "sd_d", "VN", "ve", "vd"],
        [t, lat, lon, h, *sd.T, *vel.T],
    ))
    np.testing.assert_array_equal(full.vel_ned, vel)
    np.testing.assert_array_equal(full.sd, sd)


GNSS_SD = ["time", "lat", "lon", "height", "sd_n", "sd_e", "sd_d"]
IMU_RATE = ["time", "gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"]


@pytest.mark.parametrize(
    ("header", "edit", "message"),
    [
        (IMU_RATE[:-1] + ["dv_z"], None, "either"),
        (IMU_RATE[:-1] + ["extra"], None, "unknown column"),
        (IMU_RATE[1:] + ["gyro_x"], None, "more than once"),
        (["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z", "temp"], None, "unknown"),
        (IMU_RATE, (5, 2, np.nan), "'gyro_y' has 1 non-finite value(s), the first in data row 6"),
        (IMU_RATE, (7, 0, TIME[3]), "not strictly increasing: data row 8"),
    ],
)
def test_imu_bad_files(tmp_path: Path, header: list[str], edit, message: str) -> None:
    _assert_rejected(read_imu_csv, tmp_path / "imu.csv", header,
                     [TIME.copy(), *GYRO.T.copy(), *ACCEL.T.copy()], edit, message)


def _assert_rejected(reader, path: Path, header: list[str], cols: list[np.ndarray], edit,
                     message: str) -> None:
    """Write the columns (one cell changed by `edit` = (row, column, value)) and check that
    `reader` raises an InputError naming the file and containing `message`."""
    if edit is not None:
        row, col, value = edit
        cols[col][row] = value
    _write(path, header, cols)
    with pytest.raises(InputError) as info:
        reader(path)
    assert message in str(info.value)
    assert str(path) in str(info.value)


def test_imu_missing_column_and_time(tmp_path: Path) -> None:
    path = _write(tmp_path / "imu.csv", IMU_RATE[:-1], [TIME, *GYRO.T, *ACCEL.T[:2]])
    with pytest.raises(InputError, match=r"missing column\(s\) \['accel_z'\]"):
        read_imu_csv(path)
    path = _write(tmp_path / "imu2.csv", IMU_RATE[1:], [*GYRO.T, *ACCEL.T])
    with pytest.raises(InputError, match="missing column 'time'"):
        read_imu_csv(path)


def test_no_header_and_no_file(tmp_path: Path) -> None:
    path = tmp_path / "raw.csv"
    path.write_text("0,1,2,3\n1,1,2,3\n")
    with pytest.raises(InputError, match="no header"):
        read_gnss_csv(path)
    with pytest.raises(InputError, match="no such file"):
        read_imu_csv(tmp_path / "absent.csv")


@pytest.mark.parametrize(
    ("header", "edit", "message"),
    [
        (["time", "lat", "lon"], None, r"missing column(s) ['height']"),
        (["time", "lat", "lon", "height", "vn", "ve"], None, "missing column(s) ['vd']"),
        (["time", "lat", "lon", "height", "v_n", "ve", "vd"], None, "unknown column(s) ['v_n']"),
        (GNSS_SD, (2, 5, 0.0), "sd_e must be positive"),
        (GNSS_SD, (1, 1, 91.0), "lat must be in [-90, 90]"),
        (GNSS_SD, (3, 3, np.inf), "'height' has 1 non-finite"),
        (GNSS_SD, (4, 0, 3.0), "data row 5 has time 3.0"),
    ],
)
def test_gnss_bad_files(tmp_path: Path, header: list[str], edit, message: str) -> None:
    cols = [np.arange(6.0), np.full(6, 45.0), np.full(6, 7.0), np.full(6, 300.0),
            np.ones(6), np.ones(6), np.ones(6)][: len(header)]
    _assert_rejected(read_gnss_csv, tmp_path / "gnss.csv", header, cols, edit, message)


def test_header_units_are_converted_and_wrong_dimensions_refused(tmp_path: Path) -> None:
    header = ["time", "gyro_x [deg/s]", "gyro_y [deg/s]", "gyro_z [deg/s]", "accel_x [g]",
              "accel_y [g]", "accel_z [g]"]
    deg = 180.0 / np.pi
    imu = read_imu_csv(_write(tmp_path / "imu.csv", header,
                              [TIME, *(deg * GYRO.T), *(ACCEL.T / 9.80665)]))
    np.testing.assert_allclose(imu.gyro, GYRO, rtol=1e-12)
    np.testing.assert_allclose(imu.accel, ACCEL, rtol=1e-12)
    bad = ["time", "gyro_x [mg]", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"]
    with pytest.raises(InputError, match=r"'gyro_x' is read as rate \(rad/s\).*'mg'"):
        read_imu_csv(_write(tmp_path / "bad.csv", bad, [TIME, *GYRO.T, *ACCEL.T]))


@pytest.mark.parametrize(("gyro", "accel", "match"), [
    (1.0, 1 / 9.80665, r"look like g: .*accel_x \[g\]"),
    (1.0, 1000 / 9.80665, "look like mg"),
    (180 / np.pi * 20, 1.0, "gyros look like deg/s"),
])
def test_imu_magnitudes_name_the_likely_unit(tmp_path: Path, gyro, accel, match) -> None:
    names = ["time", "gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"]
    path = _write(tmp_path / "imu.csv", names, [TIME, *(gyro * GYRO.T), *(accel * ACCEL.T)])
    with pytest.raises(InputError, match=match):
        read_imu_csv(path)


def test_gnss_in_radians_or_millimetres_is_refused(tmp_path: Path) -> None:
    t = np.arange(30.0)
    lat = 47.0 + t * 10.0 / 111_195.0  # 10 m/s north
    lon = np.full_like(t, 8.0)
    vel = [np.full_like(t, 10.0), np.zeros_like(t), np.zeros_like(t)]
    names = ["time", "lat", "lon", "height", "vn", "ve", "vd"]
    ok = read_gnss_csv(_write(tmp_path / "g.csv", names, [t, lat, lon, np.full_like(t, 400.0), *vel]))
    np.testing.assert_allclose(ok.lat, lat)
    with pytest.raises(InputError, match="look like radians"):
        read_gnss_csv(_write(tmp_path / "r.csv", names,
                             [t, np.radians(lat), np.radians(lon), np.full_like(t, 400.0), *vel]))
    with pytest.raises(InputError, match=r"is it in mm\?"):
        read_gnss_csv(_write(tmp_path / "h.csv", names, [t, lat, lon, np.full_like(t, 4e5), *vel]))
    rad = read_gnss_csv(_write(tmp_path / "u.csv", ["time", "lat [rad]", "lon [rad]", "height"],
                               [t, np.radians(lat), np.radians(lon), np.full_like(t, 400.0)]))
    np.testing.assert_allclose(rad.lat, lat, rtol=1e-12)  # the header's unit converts them
