"""Units declared, checked, never assumed: what each column measures and in which unit.

Truth: the units a file or the user states, the dimension of each unit, and the magnitudes a
static IMU shows in SI (gravity g on an accelerometer triad; a gyro's mean rate and noise far
below 1 rad/s), on seeded simulations and on the ADIS16405 recordings (gyro deg/s, accel g).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stochmod.cli import main
from stochmod.core.errors import InputError
from stochmod.core.units import STANDARD_GRAVITY as G
from stochmod.io.recording import read_recording
from stochmod.io import sensors
from stochmod.io.sensors import check_static_magnitudes, declare_units, sensor_kind

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "imudata"
ADIS = DATA / "adis_16405_imu1.npz"
COLUMNS = ("gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z")


def _static_imu(n: int = 20_000, seed: int = 5) -> np.ndarray:
    """A static IMU in SI: gyro bias 0.01 rad/s + noise 2e-3 rad/s; accel -g on z + noise."""
    rng = np.random.default_rng(seed)
    gyro = 0.01 + 2e-3 * rng.standard_normal((n, 3))
    accel = np.array([0.05, -0.1, -G]) + 0.02 * rng.standard_normal((n, 3))
    return np.hstack([gyro, accel])


def test_kinds_come_from_the_file_then_the_unit_then_the_name() -> None:
    assert sensor_kind("Gyro_X", None, "Accelerometer") == "accel"  # the file's word first
    assert sensor_kind("x", "deg/s") == "gyro" and sensor_kind("x", "mg") == "accel"
    assert sensor_kind("acc_z") == "accel" and sensor_kind("omega_y") == "gyro"
    assert sensor_kind("temperature") == "other"


def test_options_override_the_file_per_column_over_kind_over_every_column() -> None:
    cols = ("gyro_x", "gyro_y", "accel_x")
    out = declare_units(cols, ("rad/s", "rad/s", "m/s^2"), gyro_unit="deg/s",
                        unit=["gyro_y=deg/h"])
    assert [(c.unit, c.source) for c in out] == [("deg/s", "option"), ("deg/h", "option"),
                                                 ("m/s^2", "file")]
    one = declare_units(("gyro_x", "gyro_y"), unit="deg/s")  # a one-sensor file
    assert [c.unit for c in one] == ["deg/s", "deg/s"]


@pytest.mark.parametrize("kwargs, match", [
    ({"unit": "deg/s"}, "gyro and accelerometer columns alike"),
    ({"unit": ["gyro_z=mg"], "accel_unit": "g", "gyro_unit": "deg/s"},
     r"'gyro_z' is a gyro .* its unit 'mg' is not a rate"),
    ({"gyro_unit": "deg/s"}, r"unit of column 'accel_x' \(accel\) is not known.*--accel-unit"),
    ({"unit": ["nope=g"]}, "no column 'nope'"),
    ({"gyro_unit": "furlong", "accel_unit": "g"}, "not a unit stochmod knows"),
])
def test_bad_declarations_are_refused(kwargs, match) -> None:
    with pytest.raises(InputError, match=match):
        declare_units(COLUMNS, **kwargs)


def test_unknown_units_are_assumed_si_only_when_asked_and_then_say_so() -> None:
    with pytest.raises(InputError, match="--assume-si"):
        declare_units(COLUMNS)
    out = declare_units(COLUMNS, assume_si=True)
    assert {(c.kind, c.unit, c.source) for c in out} == {("gyro", "rad/s", "assumed"),
                                                         ("accel", "m/s^2", "assumed")}
    other = declare_units(("temperature",))  # not a sensor of the model: no unit needed
    assert other[0].kind == "other" and other[0].unit is None


def test_a_static_imu_in_si_passes_and_wrong_units_are_named() -> None:
    x = _static_imu()
    si = declare_units(COLUMNS, assume_si=True)
    check_static_magnitudes(x, si)
    # accel in g (or mg) read as m/s^2: |mean f| is 1 (1000), not g
    for factor, likely in ((1 / G, "g"), (1000 / G, "mg")):
        y = x.copy()
        y[:, 3:] *= factor
        with pytest.raises(InputError, match=f"look like {likely}: --accel-unit {likely}"):
            check_static_magnitudes(y, si)
    # gyro in deg/s read as rad/s
    y = x.copy()
    y[:, :3] *= 180 / np.pi
    with pytest.raises(InputError, match="look like deg/s: --gyro-unit deg/s"):
        check_static_magnitudes(y, si)


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 50), k=st.integers(1, 6), offset=st.floats(-1e4, 1e4),
       scale=st.floats(1e-6, 1e3), seed=st.integers(0, 2**16))
def test_column_moments_over_blocks_are_numpys_mean_and_std(n, k, offset, scale, seed) -> None:
    x = offset + scale * np.random.default_rng(seed).standard_normal((n, k + 1))
    cols = list(range(1, k + 1))[::-1]
    old, sensors._MOMENT_ROWS = sensors._MOMENT_ROWS, 7  # several blocks, a partial last one
    try:
        mean, rms = sensors._column_moments(x, cols)
    finally:
        sensors._MOMENT_ROWS = old
    np.testing.assert_allclose(mean, x[:, cols].mean(axis=0), rtol=1e-12, atol=1e-12 * abs(offset))
    np.testing.assert_allclose(rms, x[:, cols].std(axis=0), rtol=1e-7, atol=1e-9 * scale)


def test_an_error_signal_whose_mean_was_removed_is_not_refused_for_it() -> None:
    x = _static_imu()
    x -= x.mean(axis=0)
    check_static_magnitudes(x, declare_units(COLUMNS, assume_si=True))
    y = x.copy()
    y[:, 3:] *= 1000.0  # noise of 20 m/s^2 rms at rest is no accelerometer in m/s^2
    with pytest.raises(InputError, match="above g"):
        check_static_magnitudes(y, declare_units(COLUMNS, assume_si=True))


def test_npz_units_as_a_key_string_and_sensor_entry(tmp_path: Path) -> None:
    x = _static_imu(2000)
    path = tmp_path / "imu.npz"
    np.savez(path, Gyro_X=x[:, 0], Gyro_Y=x[:, 1], Accel_Z=x[:, 5] / G, freq=100.0,
             units="gyro: rad/s (from the datasheet), accel: g; a note",
             sensor=np.array(["Gyroscope", "Gyroscope", "Accelerometer"]))
    rec = read_recording(path)
    assert rec.units == ("rad/s", "rad/s", "g")
    assert rec.kinds == ("Gyroscope", "Gyroscope", "Accelerometer")


def test_calibrate_refuses_unknown_units_and_records_assumed_ones(tmp_path: Path,
                                                                 capsys) -> None:
    rng = np.random.default_rng(2)
    path = tmp_path / "g.npz"
    np.savez(path, gyro_x=1e-3 * rng.standard_normal(2**13), freq=100.0)
    out = tmp_path / "out"
    argv = ["calibrate", str(path), "--candidates", "WN", "--no-plots", "--out", str(out)]
    assert main(argv) == 2
    assert "--gyro-unit UNIT or --unit gyro_x=UNIT" in capsys.readouterr().err
    assert main([*argv, "--assume-si"]) == 0
    declared = json.loads((out / "calibration.json").read_text())["units"]["declared"]
    assert declared == {"gyro_x": {"kind": "gyro", "unit": "rad/s", "source": "assumed"}}
    assert main([*argv, "--gyro-unit", "deg/s"]) == 0
    report = json.loads((out / "calibration.json").read_text())
    assert report["units"]["declared"]["gyro_x"] == {"kind": "gyro", "unit": "deg/s",
                                                     "source": "option"}


@pytest.mark.skipif(not ADIS.is_file(), reason="../shared/data/imudata is absent")
def test_adis_units_are_read_and_a_wrong_one_is_caught(tmp_path: Path, capsys) -> None:
    assert main(["readers", str(ADIS), "--json"]) == 0
    shown = json.loads(capsys.readouterr().out)
    assert shown["units"] == ["deg/s"] * 3 + ["g"] * 3
    argv = ["calibrate", str(ADIS), "--no-plots", "--out", str(tmp_path)]
    assert main([*argv, "--gyro-unit", "rad/s"]) == 2
    assert "look like deg/s" in capsys.readouterr().err
    assert main([*argv, "--accel-unit", "m/s^2"]) == 2
    assert "look like g: --accel-unit g" in capsys.readouterr().err
