"""Strapdown mechanisation on the exact IMU of analytic profile trajectories: centimetres over
ten minutes at 100 Hz, second-order convergence, rates and increments agree."""

import numpy as np
import pytest

from stochmod.core.errors import InputError
from stochmod.nav import Segment, earth, frames, ideal_imu, strapdown, trajectory_from_profile
from stochmod.nav.emulate import _ProfileMotion

CAR = [Segment(10, speed=10), Segment(10, turn=90, roll=10), Segment(10, speed=20, pitch=5, roll=0),
       Segment(10, turn=-120, pitch=0)]


def _run(tr, kind):
    imu = ideal_imu(tr, kind)
    return strapdown(imu.time, imu.gyro, imu.accel, lat=tr.lat[0], lon=tr.lon[0],
                     height=tr.height[0], vel_ned=tr.vel_ned[0], rph=tr.rph[0], kind=kind)


def _pos_err(res, tr):
    o = (tr.lat[0], tr.lon[0], tr.height[0])
    d = earth.lla_to_ned(res.lat, res.lon, res.height, *o) - earth.lla_to_ned(
        tr.lat, tr.lon, tr.height, *o)
    return np.linalg.norm(d, axis=1)


def _att_err(res, tr):
    E = frames.rph_to_dcm(res.rph) @ np.swapaxes(frames.rph_to_dcm(tr.rph), -1, -2)
    return np.linalg.norm(frames.dcm_to_rotvec(E), axis=-1)


@pytest.mark.slow
def test_ten_minutes_at_100hz_within_centimetres():
    segs = [Segment(20, speed=15), Segment(40, turn=90), Segment(60, speed=25, pitch=3),
            Segment(30, pitch=0), Segment(60, turn=-270, roll=8), Segment(30, roll=0),
            Segment(100), Segment(40, speed=5, turn=60), Segment(20, speed=0),
            Segment(100), Segment(50, speed=20, turn=-30), Segment(50, speed=30)]
    tr = trajectory_from_profile(segs, rate=100.0, lat=46.5, lon=6.6, height=400.0, heading=-20)
    assert tr.time[-1] == pytest.approx(600.0)
    for kind in ("increment", "rate"):
        res = _run(tr, kind)
        assert _pos_err(res, tr).max() < 0.015, kind
        assert np.abs(res.vel_ned - tr.vel_ned).max() < 1e-3, kind
        assert _att_err(res, tr).max() < 1e-6, kind


@pytest.mark.parametrize("kind", ["increment", "rate"])
def test_error_shrinks_at_second_order(kind):
    errs = []
    for rate in (10.0, 20.0, 40.0):
        tr = trajectory_from_profile(CAR, rate=rate, lat=45.0, lon=7.0, height=300.0, heading=30)
        errs.append(_pos_err(_run(tr, kind), tr).max())
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all((orders > 1.8) & (orders < 2.3)), orders
    assert errs[-1] < 5e-3


def test_rates_and_increments_agree_and_irregular_stamps_work():
    tr = trajectory_from_profile(CAR, rate=100.0, lat=-33.0, lon=151.0, height=50.0, heading=120)
    a, b = _run(tr, "rate"), _run(tr, "increment")
    o = (tr.lat[0], tr.lon[0], tr.height[0])
    d = earth.lla_to_ned(a.lat, a.lon, a.height, *o) - earth.lla_to_ned(b.lat, b.lon, b.height, *o)
    assert np.linalg.norm(d, axis=1).max() < 2e-3
    # irregular stamps: jittered times, the exact IMU at them, same accuracy
    rng = np.random.default_rng(3)
    t = np.cumsum(np.r_[0.0, 0.01 * (1 + 0.4 * rng.uniform(-1, 1, 3999))])
    t = t[t <= tr.time[-1]]
    trj = tr.at(t)
    for kind in ("rate", "increment"):
        res = _run(trj, kind)
        assert _pos_err(res, trj).max() < 3e-3, kind


def test_ideal_imu_at_rest_is_gravity_and_earth_rate():
    tr = trajectory_from_profile([Segment(5.0)], rate=10.0, lat=30.0, lon=0.0, height=100.0,
                                 heading=0.0)
    imu = ideal_imu(tr, "rate")
    g = earth.gravity_ned(np.radians(30.0), 100.0)[2]
    np.testing.assert_allclose(imu.accel, np.tile([0, 0, -g], (tr.n, 1)), atol=1e-12)
    np.testing.assert_allclose(imu.gyro, np.tile(earth.earth_rate_ned(np.radians(30.0)),
                                                 (tr.n, 1)), atol=1e-18)
    res = _run(tr, "rate")
    assert _pos_err(res, tr).max() < 1e-9


def test_profile_kinematics_are_derivatives_of_the_samples():
    tr = trajectory_from_profile(CAR, rate=100.0, lat=10.0, lon=20.0, heading=0.0)
    m = tr.motion
    assert isinstance(m, _ProfileMotion)
    t = np.linspace(1.0, 39.0, 50)
    x, x1, x2 = m.kinematics(t)
    eps = 1e-4
    xp, x1p, _ = m.kinematics(t + eps)
    xm, x1m, _ = m.kinematics(t - eps)
    np.testing.assert_allclose(x1, (xp - xm) / (2 * eps), atol=1e-7)
    np.testing.assert_allclose(x2, (x1p - x1m) / (2 * eps), atol=1e-6)
    # velocity is the derivative of the integrated position (a wider difference: the dense
    # output carries ~1e-13 rad of interpolation noise)
    eps = 1e-2
    p, pp, pm = m.position(t), m.position(t + eps), m.position(t - eps)
    rn, re = earth.principal_radii(p[:, 0])
    v, _ = m.velocity(t)
    np.testing.assert_allclose((pp[:, 0] - pm[:, 0]) / (2 * eps) * (rn + p[:, 2]), v[:, 0],
                               atol=2e-4)
    np.testing.assert_allclose((pp[:, 1] - pm[:, 1]) / (2 * eps) * (re + p[:, 2])
                               * np.cos(p[:, 0]), v[:, 1], atol=2e-4)


def test_bad_input_is_refused():
    tr = trajectory_from_profile([Segment(1.0)], rate=10.0, lat=0.0, lon=0.0)
    imu = ideal_imu(tr)
    kw = dict(lat=0.0, lon=0.0, height=0.0, vel_ned=[0, 0, 0], rph=[0, 0, 0])
    with pytest.raises(InputError, match="increase strictly"):
        strapdown(imu.time[::-1], imu.gyro, imu.accel, **kw)
    with pytest.raises(InputError, match="shape"):
        strapdown(imu.time, imu.gyro[:, :2], imu.accel, **kw)
    bad = imu.accel.copy()
    bad[3, 1] = np.nan
    with pytest.raises(InputError, match="non-finite"):
        strapdown(imu.time, imu.gyro, bad, **kw)
    with pytest.raises(InputError, match="kind"):
        strapdown(imu.time, imu.gyro, imu.accel, kind="rates", **kw)
    with pytest.raises(InputError, match="latitude"):
        strapdown(imu.time, imu.gyro, imu.accel, **{**kw, "lat": 90.0})
    with pytest.raises(InputError, match="duration"):
        Segment(0.0)
