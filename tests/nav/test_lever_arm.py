"""The antenna lever arm as filter states (the cause of the n380 outage errors, issue 10): on an
emulated drive whose GNSS antenna sits off the IMU, a filter that ignores the offset reads it as
attitude error at every turn (NEES far above its band, worse outages), while the filter that
estimates it converges to the true lever arm and stays honest. The lever-arm terms of the
measurements are checked on constructed cases with an exactly known antenna track: the
predicted antenna velocity and its Jacobian, the attitude taken at the fix's own time, and the
gyro-bias column of the velocity Jacobian."""

import math

import numpy as np
import pytest
from scipy.stats import chi2

import stochmod
from stochmod.core.errors import InputError
from stochmod.nav import (
    InitialState,
    LooselyCoupledFilter,
    Segment,
    frames,
    gnss_measurements,
    ideal_imu,
    trajectory_from_profile,
)
from stochmod.nav.measurements import GnssPosition, GnssVelocity, Snapshot

from ._emulated import imu_with_biases

FS = 100.0
GYRO = (stochmod.WN.from_density(6e-5, FS) + stochmod.RW.from_rrw(1e-6, FS)).bind(FS)
ACCEL = (stochmod.WN.from_density(8e-4, FS) + stochmod.RW.from_rrw(5e-5, FS)).bind(FS)
BIAS_SD = (5e-4, 0.02)
ARM = np.array([-1.4, 0.5, -0.8])  # antenna behind, right of and above the IMU, m
PROFILE = [Segment(10, speed=8), Segment(10, turn=90), Segment(15, speed=15),
           Segment(10, turn=-90), Segment(15, turn=180), Segment(10, turn=-90, speed=10),
           Segment(10, turn=90, speed=14), Segment(30)]
OUTAGE = (80.0, 30.0)


@pytest.fixture(scope="module")
def drive():
    truth = trajectory_from_profile(PROFILE, rate=FS, lat=45.0, lon=-93.0, height=250.0,
                                    heading=30.0, speed=5.0)
    return truth, ideal_imu(truth, "increment")


def _emulate(truth, clean, seed):
    rng = np.random.default_rng(seed)
    imu, _ = imu_with_biases(clean, GYRO, ACCEL, BIAS_SD, rng)
    gnss = gnss_measurements(truth, 1.0, sigma_h=0.5, sigma_v=1.0, sigma_vel=0.05,
                             lever_arm=ARM, rng=rng)
    t0 = truth.at(truth.time[:1])
    init = InitialState(t0.lat[0], t0.lon[0], t0.height[0], t0.vel_ned[0], t0.rph[0],
                        sd_position=1.0, sd_velocity=0.1, sd_attitude=(0.2, 0.2, 1.0))
    return imu, gnss, init


def _run(truth, imu, gnss, init, **kw):
    flt = LooselyCoupledFilter(GYRO, ACCEL, dt_filter=0.1, gyro_bias_sd=BIAS_SD[0],
                               accel_bias_sd=BIAS_SD[1], gate=None, gnss_sd=(0.5, 0.5, 1.0),
                               gnss_vel_sd=0.05, **kw)
    return flt.run(imu.time, imu.gyro, imu.accel, kind="increment", gnss=gnss, init=init,
                   outages=[OUTAGE], truth=truth)


def _outage_error(res, truth):
    start, dur = OUTAGE
    m = (res.time >= start) & (res.time < start + dur)
    tr = truth.at(res.time[m])
    dn = np.radians(res.lat[m] - tr.lat) * 6.37e6
    de = np.radians(res.lon[m] - tr.lon) * 6.37e6 * math.cos(math.radians(45.0))
    return float(np.hypot(dn, de).max())


@pytest.mark.slow
def test_estimated_lever_arm_converges_and_keeps_the_filter_honest(drive):
    truth, clean = drive
    runs = 3
    est_nees, ign_nees, est_err, ign_err = [], [], [], []
    for seed in range(runs):
        imu, gnss, init = _emulate(truth, clean, seed)
        est = _run(truth, imu, gnss, init, lever_arm=(0.0, 0.0, 0.0), lever_arm_sd=2.0)
        ign = _run(truth, imu, gnss, init)  # lever arm taken as zero and exact
        arm, sd = est.lever_arm[-1], est.epoch_sd[-1, -3:]
        # x and y are observable through the turns (heading changes rotate C l); z only
        # through the small attitude changes
        assert np.all(np.abs(arm - ARM) < 3.5 * sd + 1e-3), (arm, ARM, sd)
        assert np.all(np.abs(arm[:2] - ARM[:2]) < 0.15), arm
        assert np.all(sd[:2] < 0.1) and sd[2] < 2.0, sd
        assert est.state_names[-3:] == ("lever_arm.x", "lever_arm.y", "lever_arm.z")
        est_nees.append(est.mean_nees)
        ign_nees.append(ign.mean_nees)
        est_err.append(_outage_error(est, truth))
        ign_err.append(_outage_error(ign, truth))
    lo, hi = chi2.ppf([0.005, 0.995], 9 * runs) / runs
    print(f"NEES estimated {np.round(est_nees, 2)} ignored {np.round(ign_nees, 2)}; outage error "
          f"estimated {np.round(est_err, 2)} ignored {np.round(ign_err, 2)} m")
    assert lo < np.mean(est_nees) < hi
    assert np.mean(ign_nees) > 3 * hi  # the ignored offset makes the covariance dishonest
    assert np.mean(est_err) < np.mean(ign_err)


def test_lever_arm_jacobians_by_finite_differences():
    rng = np.random.default_rng(7)
    for _ in range(10):
        C = frames.rph_to_dcm(rng.uniform([-30, -30, -180], [30, 30, 180]))
        w = rng.normal(0, 0.3, 3)
        arm = rng.normal(0, 1.5, 3)
        snap = Snapshot(0.8, -1.6, 200.0, rng.normal(0, 10, 3), C, w, np.zeros(3), arm)
        for meas in (GnssPosition(45.8, -91.7, 210.0, 1.0), GnssVelocity(np.zeros(3), 0.1)):
            J = np.zeros((3, 3))
            for i in range(3):
                d = np.zeros(3)
                d[i] = 1e-4
                yp = meas.evaluate(snap._replace(lever_arm=arm + d))[0]
                ym = meas.evaluate(snap._replace(lever_arm=arm - d))[0]
                J[:, i] = (yp - ym) / 2e-4
            np.testing.assert_allclose(meas.lever_arm_jacobian(snap), J, atol=1e-7)
        # without an estimate the measurement's own lever arm is used
        own = GnssPosition(45.8, -91.7, 210.0, 1.0, lever_arm=arm)
        np.testing.assert_allclose(own.evaluate(snap._replace(lever_arm=None))[0],
                                   own.evaluate(snap)[0])


def test_lever_arm_sd_is_validated():
    with pytest.raises(InputError, match="lever_arm_sd"):
        LooselyCoupledFilter(GYRO, ACCEL, lever_arm_sd=-1.0)
    with pytest.raises(InputError, match="lever_arm_sd"):
        LooselyCoupledFilter(GYRO, ACCEL, lever_arm_sd=(1.0, 2.0))
    flt = LooselyCoupledFilter(GYRO, ACCEL, lever_arm_sd=0.0)
    assert "lever_arm.x" not in flt.state_names(0.01)


def _turning_drive():
    """A car accelerating through a right turn with a roll change: body rate on all axes."""
    profile = [Segment(3, speed=12), Segment(4, turn=60, roll=8), Segment(3, turn=-30, roll=-4)]
    return trajectory_from_profile(profile, rate=FS, lat=45.0, lon=-93.0, height=250.0,
                                   heading=30.0, speed=10.0)


def test_antenna_velocity_and_its_jacobian_against_the_antenna_track():
    """On a turning, rolling car the predicted antenna velocity ``v + C (w_nb x l)`` at the
    true state is the time derivative of the antenna's own track (``p + C l``, central
    differences), and the Jacobian is the exact derivative of the prediction: attitude
    ``[(C (w x l)) x]`` and body rate ``-C [l x]`` (Groves 2013, Chapter 14)."""
    from stochmod.nav import earth

    truth = _turning_drive()
    for t in (4.0, 5.5, 8.2):
        dt = 1e-3
        tr = truth.at(np.array([t - dt, t, t + dt]))
        C = frames.rph_to_dcm(tr.rph)
        lat, h = np.radians(tr.lat), tr.height
        rn, re = earth.principal_radii(lat[1])
        ned = np.stack([np.radians(tr.lat - tr.lat[1]) * (rn + h[1]),
                        np.radians(tr.lon - tr.lon[1]) * (re + h[1]) * np.cos(lat[1]),
                        -(h - h[1])], -1) + C @ ARM
        v_antenna = (ned[2] - ned[0]) / (2 * dt)
        w_ib, _ = truth.motion.sensors(np.array([t]))
        w_in = earth.earth_rate_ned(lat[1]) + earth.transport_rate_ned(lat[1], h[1],
                                                                       tr.vel_ned[1])
        w_nb = w_ib[0] - C[1].T @ w_in
        snap = Snapshot(lat[1], np.radians(tr.lon[1]), h[1], tr.vel_ned[1], C[1], w_nb, w_in)
        meas = GnssVelocity(v_antenna, 0.1, lever_arm=ARM)
        y, H, _ = meas.evaluate(snap)
        assert np.linalg.norm(np.cross(w_nb, ARM)) > 0.2  # the lever-arm term matters
        np.testing.assert_allclose(y, 0.0, atol=2e-5)  # central differences, O(dt^2)
        # the attitude columns: C_hat = (I - [psi x]) C
        for i in range(3):
            d = np.zeros(3)
            d[i] = 1e-6
            yp = meas.evaluate(snap._replace(C_nb=(np.eye(3) - frames.skew(d)) @ C[1]))[0]
            ym = meas.evaluate(snap._replace(C_nb=(np.eye(3) + frames.skew(d)) @ C[1]))[0]
            np.testing.assert_allclose(H[:, 6 + i], (yp - ym) / 2e-6, atol=1e-6)
            yp = meas.evaluate(snap._replace(w_nb_b=w_nb + d))[0]
            ym = meas.evaluate(snap._replace(w_nb_b=w_nb - d))[0]
            np.testing.assert_allclose(meas.rate_jacobian(snap)[:, i], (yp - ym) / 2e-6,
                                       atol=1e-6)
        np.testing.assert_allclose(H[:, 3:6], np.eye(3))
    assert GnssVelocity(np.zeros(3), 0.1).rate_jacobian(snap) is None  # no lever arm


def _spin_on_the_spot(arm, gyro_bias_z=0.0, seconds=2.0):
    """A car turning on the spot (72 deg in `seconds`, yaw rate up to 1.2 rad/s), its exact
    IMU plus a z-gyro bias (rad/s), the antenna at `arm` (body, m) and exact antenna fixes 5 ms
    after the IMU epochs at 10 Hz (position sd 1 km: only the velocity informs)."""
    from stochmod.nav import GnssData, earth

    truth = trajectory_from_profile([Segment(seconds, turn=72)], rate=FS, lat=45.0, lon=-93.0,
                                    height=250.0, heading=30.0)
    clean = ideal_imu(truth, "increment")
    h = np.diff(clean.time)
    gyro = clean.gyro.copy()
    gyro[:, 2] += gyro_bias_z * np.r_[h[:1], h]
    tm = truth.time[0] + 0.005 + np.arange(1, int(seconds * 10)) * 0.1
    tr = truth.at(tm)
    C = frames.rph_to_dcm(tr.rph)
    w_ib, _ = truth.motion.sensors(tm)  # at rest the NED frame turns at the earth rate only
    w_nb = w_ib - np.einsum("nji,nj->ni", C, earth.earth_rate_ned(np.radians(tr.lat)))
    v_antenna = tr.vel_ned + np.einsum("nij,nj->ni", C, np.cross(w_nb, arm))
    rn, re = earth.principal_radii(np.radians(tr.lat))
    ned = C @ arm
    gnss = GnssData(tm, tr.lat + np.degrees(ned[:, 0] / (rn + tr.height)),
                    tr.lon + np.degrees(ned[:, 1] / ((re + tr.height) * np.cos(np.radians(tr.lat)))),
                    tr.height - ned[:, 2], vel_ned=v_antenna, sd=np.full((tm.size, 3), 1e3),
                    sd_vel=np.full((tm.size, 3), 1e-3))
    t0 = truth.at(truth.time[:1])
    init = InitialState(t0.lat[0], t0.lon[0], t0.height[0], t0.vel_ned[0], t0.rph[0],
                        sd_position=1e-3, sd_velocity=1e-4, sd_attitude=(1e-3, 1e-3, 1e-3))
    return clean.time, gyro, clean.accel, gnss, init


def test_a_fix_between_imu_epochs_takes_the_attitude_at_its_own_time():
    """Exact IMU, start and antenna fixes 5 ms before the end of their IMU interval on a car
    turning on the spot at up to 1.2 rad/s: the predicted antenna position and velocity are the
    truth, so every innovation is zero to the interpolation's second order (measured at most
    2e-5 m and 3e-5 m/s). Taken at the end of the interval the attitude is 5 ms late (6e-3 rad
    at 1.2 rad/s), which moves ``C l`` by 6.2 mm and ``C (w x l)`` by 3.9 mm/s."""
    arm = np.array([1.3, 0.0, 0.0])
    t, gyro, accel, gnss, init = _spin_on_the_spot(arm)
    flt = LooselyCoupledFilter(GYRO, ACCEL, dt_filter=0.1, gyro_bias_sd=BIAS_SD[0],
                               accel_bias_sd=BIAS_SD[1], gate=None, lever_arm=arm)
    res = flt.run(t, gyro, accel, kind="increment", gnss=gnss, init=init)
    for kind in ("gnss_position", "gnss_velocity"):
        assert np.abs(res.innovations[kind][:, 1:]).max() < 1e-4, kind


def test_velocity_fixes_reveal_the_gyro_bias_through_the_lever_arm():
    """The same car turning on the spot with its antenna 1.3 m ahead of the IMU and a 0.2
    deg/s z-gyro bias the filter does not know (prior 1-sigma 1 deg/s): the antenna velocity
    it predicts is off by ``C (b x l)``, 4.5 mm/s sideways, besides the heading error the bias
    builds up. The velocity Jacobian carries the gyro-error states (``-C [l x]`` on the rate
    error; the rate is the gyro output less the estimated error), and exact velocity fixes at
    10 Hz for 2 s give the bias to 1 % (measured 0.12 %); without that column the filter reads
    the same innovations as velocity and attitude errors, and its bias estimate runs away (-91
    times the bias)."""
    arm = np.array([1.3, 0.0, 0.0])
    bias = math.radians(0.2)
    t, gyro, accel, gnss, init = _spin_on_the_spot(arm, bias)
    flt = LooselyCoupledFilter(GYRO, ACCEL, dt_filter=0.1, gyro_bias_sd=math.radians(1.0),
                               accel_bias_sd=1e-4, gate=None, lever_arm=arm)
    res = flt.run(t, gyro, accel, kind="increment", gnss=gnss, init=init)
    est = res.sensor_errors[-1, 2]
    assert abs(est - bias) < 0.01 * bias, (est, bias)
