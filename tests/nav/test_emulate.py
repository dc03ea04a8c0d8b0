"""Emulation: GNSS noise levels and CEP conversion (Gonzalez eq. 7), lever arm, sensor errors
from models and from static recordings, records validation."""

import math

import numpy as np
import pytest

import stochmod
from stochmod.core.errors import InputError
from stochmod.nav import (
    GnssData,
    ImuData,
    Segment,
    add_sensor_errors,
    earth,
    frames,
    gnss_measurements,
    ideal_imu,
    magnetometer_heading,
    trajectory_from_profile,
)
from stochmod.nav.emulate import cep_to_sigma


@pytest.fixture(scope="module")
def drive():
    return trajectory_from_profile([Segment(50, speed=15), Segment(100, turn=720, roll=5),
                                    Segment(50, roll=0)], rate=20.0, lat=40.0, lon=-3.0,
                                   height=650.0, heading=10.0)


def test_cep_conversion_holds_half_the_fixes(drive):
    assert cep_to_sigma(1.5) == pytest.approx(0.8493 * 1.5)
    # a CEP circle holds half of the horizontal errors (Rayleigh median = 1.1774 sigma)
    g = gnss_measurements(drive, 5.0, cep=2.0, sigma_v=4.0, sigma_vel=None, rng=7)
    tr = drive.at(g.time)
    d = earth.lla_to_ned(g.lat, g.lon, g.height, tr.lat[0], tr.lon[0], tr.height[0]) - \
        earth.lla_to_ned(tr.lat, tr.lon, tr.height, tr.lat[0], tr.lon[0], tr.height[0])
    n = g.n
    assert n == 1001
    inside = np.mean(np.hypot(d[:, 0], d[:, 1]) < 2.0)
    assert abs(inside - 0.5) < 3 * math.sqrt(0.25 / n) + 0.01  # 0.8493 is eq. 7's rounding
    assert np.std(d[:, 2]) == pytest.approx(4.0, rel=4 / math.sqrt(2 * n))
    np.testing.assert_allclose(g.sd, np.tile([0.8493 * 2, 0.8493 * 2, 4.0], (n, 1)))
    assert g.vel_ned is None


def test_lever_arm_and_outages(drive):
    arm = np.array([1.0, -0.5, -2.0])
    g = gnss_measurements(drive, 1.0, sigma_h=1e-6, sigma_v=1e-6, sigma_vel=1e-6,
                          lever_arm=arm, rng=0, outages=[(20.0, 10.0), (100.0, 5.0)])
    assert not np.any((g.time >= 20) & (g.time < 30)) and not np.any((g.time >= 100) & (g.time < 105))
    assert g.n == 201 - 15
    tr = drive.at(g.time)
    C = frames.rph_to_dcm(tr.rph)
    want = np.einsum("nij,j->ni", C, arm)
    for i in range(0, g.n, 17):
        d = earth.lla_to_ned(g.lat[i], g.lon[i], g.height[i], tr.lat[i], tr.lon[i], tr.height[i])
        np.testing.assert_allclose(d, want[i], atol=1e-4)
    # antenna velocity during the turn differs from the IMU's by C (w_nb x l)
    turning = (g.time > 60) & (g.time < 140)
    dv = np.linalg.norm(g.vel_ned - tr.vel_ned, axis=1)
    rate = math.radians(720 / 100)
    assert dv[turning].max() > 0.5 * rate * np.hypot(arm[0], arm[1])
    with pytest.raises(InputError, match="exactly one"):
        gnss_measurements(drive, 1.0, sigma_h=1.0, cep=1.0)


def test_sensor_errors_from_models_and_static_recordings(drive):
    fs = 20.0
    imu = ideal_imu(drive, "rate")
    wn = stochmod.Model((stochmod.WN.from_density(1e-3, fs),)).bind(fs)
    noisy = add_sensor_errors(imu, {"gyro_y": wn}, rng=3)
    err = noisy.gyro - imu.gyro
    assert np.all(err[:, [0, 2]] == 0) and np.all(noisy.accel == imu.accel)
    assert np.var(err[:, 1]) == pytest.approx(1e-6 * fs, rel=0.1)  # N^2 fs per sample
    rec = np.random.default_rng(1).normal(size=imu.n + 10)
    inc = ideal_imu(drive, "increment")
    out = add_sensor_errors(inc, {"accel_z": rec})
    np.testing.assert_allclose(out.accel[:, 2] - inc.accel[:, 2], rec[:imu.n] / fs, rtol=1e-9,
                               atol=1e-12)
    with pytest.raises(InputError, match="unknown sensor axes"):
        add_sensor_errors(imu, {"gyro_w": wn})
    with pytest.raises(InputError, match="needs"):
        add_sensor_errors(imu, {"gyro_x": rec[:10]})


def test_magnetometer_heading_noise(drive):
    t, h = magnetometer_heading(drive, 2.0, rate=2.0, rng=5)
    d = (h - drive.at(t).rph[:, 2] + 180) % 360 - 180
    assert np.std(d) == pytest.approx(2.0, rel=0.15)
    assert np.all((h > -180) & (h <= 180))


def test_records_validate_their_input():
    t = np.arange(5.0)
    with pytest.raises(InputError, match="increase strictly"):
        ImuData(t[::-1], np.zeros((5, 3)), np.zeros((5, 3)))
    with pytest.raises(InputError, match="kind"):
        ImuData(t, np.zeros((5, 3)), np.zeros((5, 3)), kind="delta")
    with pytest.raises(InputError, match="shape"):
        ImuData(t, np.zeros((5, 2)), np.zeros((5, 3)))
    with pytest.raises(InputError, match="degrees"):
        GnssData(t, np.full(5, 100.0), np.zeros(5), np.zeros(5))
    with pytest.raises(InputError, match="positive"):
        GnssData(t, np.zeros(5), np.zeros(5), np.zeros(5), sd=np.zeros((5, 3)))
    g = GnssData(t, np.zeros(5), np.zeros(5), np.zeros(5), vel_ned=np.ones((5, 3)))
    assert g.select(t > 2).n == 2 and g.select(t > 2).vel_ned.shape == (2, 3)
