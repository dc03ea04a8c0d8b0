"""The antenna lever arm as filter states (the cause of the n380 outage errors, issue 10): on an
emulated drive whose GNSS antenna sits off the IMU, a filter that ignores the offset reads it as
attitude error at every turn (NEES far above its band, worse outages), while the filter that
estimates it converges to the true lever arm and stays honest."""

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
