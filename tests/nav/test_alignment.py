"""Alignment: levelling and magnetic heading against known attitudes, in-motion alignment from
GNSS velocity on an emulated drive, and the filter started without an initial state."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import stochmod
from stochmod.core.errors import InputError
from stochmod.nav import (
    LooselyCoupledFilter,
    Segment,
    align_from_gnss,
    earth,
    frames,
    gnss_measurements,
    ideal_imu,
    level,
    static_alignment,
    trajectory_from_profile,
)


@settings(max_examples=40, deadline=None)
@given(st.floats(-60, 60), st.floats(-60, 60), st.floats(-179, 179))
def test_levelling_and_magnetic_heading_recover_the_attitude(roll, pitch, heading):
    C = frames.rph_to_dcm([roll, pitch, heading])
    g = earth.gravity_ned(math.radians(45.0), 0.0)
    f_b = C.T @ -g
    r, p = level(f_b)
    assert r == pytest.approx(roll, abs=1e-9) and p == pytest.approx(pitch, abs=1e-9)
    # Earth's field with declination 3 deg and inclination 60 deg, seen in the body frame
    decl = 3.0
    dec, inc = math.radians(decl), math.radians(60.0)
    m_n = np.array([math.cos(inc) * math.cos(dec), math.cos(inc) * math.sin(dec), math.sin(inc)])
    n = 50
    t = np.arange(n) * 0.01
    init = static_alignment(t, np.zeros((n, 3)), np.tile(f_b, (n, 1)), lat=45.0, lon=0.0,
                            height=0.0, mag=C.T @ m_n, declination=decl)
    # eq. 19b: magnetic heading plus the (east-positive) declination is the true heading
    assert (init.rph[2] - heading + 180) % 360 - 180 == pytest.approx(0.0, abs=1e-7)


def test_static_alignment_heading_matches_true_heading_with_declination():
    C = frames.rph_to_dcm([2.0, -3.0, 70.0])
    dec, inc = math.radians(5.0), math.radians(60.0)
    m_n = np.array([math.cos(inc) * math.cos(dec), math.cos(inc) * math.sin(dec), math.sin(inc)])
    f_b = C.T @ -earth.gravity_ned(0.5, 0.0)
    t = np.arange(10) * 0.01
    init = static_alignment(t, np.zeros((10, 3)), np.tile(f_b, (10, 1)), lat=30.0, lon=0.0,
                            height=0.0, mag=C.T @ m_n, declination=5.0)
    # magnetic heading = true heading - declination; eq. 19b adds D back
    np.testing.assert_allclose(init.rph, [2.0, -3.0, 70.0], atol=1e-9)
    with pytest.raises(InputError, match="heading or magnetometer"):
        static_alignment(t, np.zeros((10, 3)), np.tile(f_b, (10, 1)), lat=30.0, lon=0.0,
                         height=0.0)
    with pytest.raises(InputError, match="far from gravity"):
        level([0.1, 0.0, 0.0])


def test_in_motion_alignment_and_filter_without_init():
    fs = 100.0
    tr = trajectory_from_profile([Segment(5.0), Segment(10.0, speed=10.0), Segment(20.0, turn=60),
                                  Segment(25.0)], rate=fs, lat=-20.0, lon=30.0, height=100.0,
                                 heading=110.0)
    imu = ideal_imu(tr, "rate")
    gnss = gnss_measurements(tr, 1.0, sigma_h=0.5, sigma_v=1.0, sigma_vel=0.02, rng=0)
    init = align_from_gnss(imu.time, imu.gyro, imu.accel, gnss, kind="rate", min_speed=3.0)
    truth = tr.at([init.time])
    assert init.time > 5.0 and init.time < 15.0
    assert abs((init.rph[2] - truth.rph[0, 2] + 180) % 360 - 180) < 0.5
    assert abs(init.rph[0] - truth.rph[0, 0]) < 0.5
    g = stochmod.Model((stochmod.WN.from_density(1e-5, fs),)).bind(fs)
    a = stochmod.Model((stochmod.WN.from_density(1e-4, fs),)).bind(fs)
    res = LooselyCoupledFilter(g, a, dt_filter=0.1).run(imu.time, imu.gyro, imu.accel,
                                                        kind="rate", gnss=gnss, truth=tr)
    assert res.time[0] == pytest.approx(init.time)
    assert np.isfinite(res.nees).all()
    err = earth.lla_to_ned(res.lat[-1], res.lon[-1], res.height[-1], tr.lat[-1], tr.lon[-1],
                           tr.height[-1])
    assert np.linalg.norm(err[:2]) < 1.0
    with pytest.raises(InputError, match="speed"):
        align_from_gnss(imu.time, imu.gyro, imu.accel, gnss, min_speed=50.0)
