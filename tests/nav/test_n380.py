"""The onavdata HGuide n380 drive as tests/nav/_n380.py converts it: the frame, the time convention
of the increments and the GNSS fixes are checked against the unit's own INS solution, and the
drive survives the round trip through the ``navigate`` CSV formats."""

from __future__ import annotations

import contextlib
import json
from pathlib import Path

import numpy as np
import pytest

from stochmod.nav import earth, frames
from stochmod.nav.logs import read_gnss_csv, read_imu_csv

from ._n380 import (ENSEMBLE_JSON, ENSEMBLE_VELOCITY_JSON, ENSEMBLE_VELOCITY_LEVER_ARM_JSON,
                    LEVER_ARM, PEER_JSON, load_n380, max_outage_errors, onavdata_missing_reason,
                    pyins_velocity_jacobian, run_stochmod, stochmod_runs, summary, verdict,
                    write_navigate_csvs)

pytestmark = pytest.mark.skipif(onavdata_missing_reason() is not None,
                                reason=str(onavdata_missing_reason()))


@pytest.fixture(scope="module")
def drive():
    return load_n380()


def test_span_and_rates(drive) -> None:
    imu, gnss, ref = drive.imu, drive.gnss, drive.reference
    assert imu.kind == "increment"
    # onavdata's description: 669 s in navigation mode, 100 Hz IMU, 1 Hz GNSS
    assert imu.time[-1] - imu.time[0] == pytest.approx(669.4, abs=0.1)
    assert np.median(np.diff(imu.time)) == pytest.approx(0.01, rel=1e-3)
    assert np.median(np.diff(gnss.time)) == pytest.approx(1.0, rel=1e-3)
    assert gnss.time[0] >= imu.time[0] and gnss.time[-1] <= imu.time[-1]
    np.testing.assert_array_equal(ref.time, imu.time)


def test_body_frame_at_rest_matches_reference_attitude(drive) -> None:
    """Stationary first 100 s: the mean specific force equals C_bn (-g) of the reference attitude
    (the rotation Rsensor2body gives x fwd / y right / z down) to a few mg of bias."""
    imu, ref = drive.imu, drive.reference
    speed = np.linalg.norm(ref.vel_ned, axis=1)
    still = slice(1, int(np.flatnonzero(speed > 0.5)[0]) - 100)
    assert imu.time[still.stop] - imu.time[0] > 100.0
    f = imu.accel[still].sum(0) / (imu.time[still.stop - 1] - imu.time[still.start - 1])
    C_nb = frames.rph_to_dcm(ref.rph[still].mean(0))
    g = earth.gravity_ned(np.radians(ref.lat[0]), ref.height[0])
    np.testing.assert_allclose(f, C_nb.T @ -g, atol=0.03)  # 3 mg; gravity alone is 9.8 m/s^2
    assert f[2] < -9.7


def test_increments_end_at_their_stamp(drive) -> None:
    """The body z angle increment over (t[k-1], t[k]] tracks the reference heading change over
    the same interval better than over the interval one sample earlier or later."""
    imu, ref = drive.imu, drive.reference
    wz = imu.gyro[1:, 2]
    dh = np.diff(np.unwrap(np.radians(ref.rph[:, 2])))
    moving = slice(15000, -200)

    def misfit(lag: int) -> float:
        a = wz[moving.start + lag: moving.stop + lag] - dh[moving]
        return float(np.std(a))

    assert misfit(0) < 0.6 * min(misfit(-1), misfit(1))


def test_gnss_fixes_near_reference(drive) -> None:
    gnss, ref = drive.gnss, drive.reference
    at = ref.at(gnss.time)
    ned = earth.lla_to_ned(gnss.lat, gnss.lon, gnss.height, at.lat[0], at.lon[0], at.height[0])
    ned_ref = earth.lla_to_ned(at.lat, at.lon, at.height, at.lat[0], at.lon[0], at.height[0])
    horizontal = np.hypot(*(ned - ned_ref)[:, :2].T)
    assert np.median(horizontal) < 3.0  # m: antenna on the roof, fix noise ~0.5 m
    np.testing.assert_allclose(np.median(np.abs(gnss.vel_ned - at.vel_ned), axis=0), 0, atol=0.1)


def test_navigate_csv_round_trip(drive, tmp_path: Path) -> None:
    imu_path, gnss_path = write_navigate_csvs(drive, tmp_path)
    imu, gnss = read_imu_csv(imu_path), read_gnss_csv(gnss_path)
    assert imu.kind == "increment"
    for got, want in [(imu.time, drive.imu.time), (imu.gyro, drive.imu.gyro),
                      (imu.accel, drive.imu.accel), (gnss.lat, drive.gnss.lat),
                      (gnss.vel_ned, drive.gnss.vel_ned), (gnss.sd, drive.gnss.sd)]:
        np.testing.assert_array_equal(got, want)  # %.17g round-trips doubles exactly


# A single drive: the max error in an outage is one realisation, and the two filters differ
# in their error formulation, discretisation and update timing, so "no worse" is decided over
# seeded starts (test_real_drive_over_seeded_starts_beside_pyins). This single start holds the
# measured figures with a margin: the sum over the three outages at most SUM_SLACK above pyins'
# and no outage more than RELATIVE_SLACK worse. Measured: sums 0.906 (position) and 1.011
# (position + velocity) of pyins', the worst outage 1.061 of pyins' (position, outage 3).
SUM_SLACK = 0.02
RELATIVE_SLACK = 0.10


@pytest.mark.slow
@pytest.mark.parametrize("mode", ["position", "position_velocity"])
def test_real_drive_beside_pyins(drive, mode) -> None:
    """stochmod's 21-state filter with pyins' example settings on the same increments, GNSS and
    start as pyins' run in tests/nav/reference/nav_pyins_n380.json (studies/nav_pyins_n380.py)."""
    peer = json.loads(PEER_JSON.read_text())
    theirs = np.array(peer["runs"][f"raw/{mode}"]["max_horizontal_error_m"])
    result = run_stochmod(drive, velocity=mode == "position_velocity",
                          initial_error=peer["initial_error"])
    assert len(result.state_names) == 21
    ours = np.array(max_outage_errors(result.time, result.lat, result.lon, drive.reference,
                                      drive.t0))
    assert np.all(ours > 1.0)  # 60 s of dead reckoning: metres, not a copy of the reference
    assert ours.sum() <= (1 + SUM_SLACK) * theirs.sum()
    np.testing.assert_array_less(ours, (1 + RELATIVE_SLACK) * theirs)


# The lever arm fitted from the data (docs/navigation.md, "Real drive"): with it both filters
# reproduce the pattern of the pyins figures the comparison set out to match (85, 6.6 and ~18 m
# with position updates). One drive is one realisation, and the start alone moves the outage-2
# maximum by metres, so the comparison is over an ensemble of the SAME seeded random starts
# (studies/nav_n380_ensemble.py; pyins' runs, ~10 min each here, are cached in
# tests/nav/reference/nav_pyins_n380_ensemble.json by that script).
# Outages 2 and 3: stochmod is worse than pyins beyond the ensemble's standard error by about a
# metre (docs/navigation_real_drive.md, "Over seeded starts"), so "no worse" is not asserted
# there (measured: +0.21 and +0.80 m; the states before every outage of every
# seed at most 0.35 of pyins' sigma from pyins', under the 0.5 asserted); the gap is held below
# GAP_BOUND (m) so that it cannot grow unnoticed. Its cause is the
# reset ("The cause"): with pyins' one the gap goes (test_real_drive_with_pyins_reset_...).
GAP_BOUND = 2.0


@pytest.mark.slow
def test_real_drive_over_seeded_starts_beside_pyins(drive) -> None:
    """Both filters from the same seeded starts, position updates, the fitted lever arm fixed:
    per outage the paired difference of the maximum horizontal error (stochmod - pyins) over
    the seeds, and before every outage of every seed the two filters' attitude error, gyro and
    accelerometer biases within half of pyins' own 1-sigma."""
    cache = json.loads(ENSEMBLE_JSON.read_text())
    assert cache["lever_arm_m"] == list(LEVER_ARM) and cache["mode"] == "position"
    assert len(cache["runs"]) >= 8
    runs = stochmod_runs(drive, cache)
    s = summary({seed: r[0] for seed, r in runs.items()}, cache)
    assert all((r[0] > 1.0).all() for r in runs.values())  # dead reckoning: metres, not a copy
    # outage 1: better with margin; over the three outages: better with margin
    assert verdict(s)[0] == "better"
    sums = np.array([runs[k][0].sum() - sum(cache["runs"][k]["max_horizontal_error_m"])
                     for k in runs])
    assert sums.mean() + 2 * sums.std(ddof=1) / np.sqrt(sums.size) < 0
    np.testing.assert_array_less(s["difference_mean"][1:], GAP_BOUND)
    for seed, (_, ours) in runs.items():
        theirs = cache["runs"][seed]["states_at_outages"]
        for name, sd in (("rph_error_deg", "rph_sd_deg"), ("gyro_bias_deg_h", "gyro_bias_sd_deg_h"),
                         ("accel_bias_m_s2", "accel_bias_sd_m_s2")):
            np.testing.assert_array_less(np.abs(np.subtract(ours[name], theirs[name])),
                                         0.5 * np.array(theirs[sd]), err_msg=f"{seed} {name}")


# With pyins' reset and feedback (error_model="modified-phi", docs/navigation_real_drive.md,
# "The cause" and "The residual of modified-phi") stochmod reproduces pyins' runs: per seed and
# outage within MODIFIED_SLACK of pyins' maximum (plus MODIFIED_ABS), and before every outage
# the attitude error and both biases within MODIFIED_STATE_SD of pyins' own 1-sigma. Measured:
# at most 0.129 m, 0.25 of this error allowance, and 0.008 sigma (margins of 3.9 and 3); the psi
# model misses both on these seeds (errors up to 11.5 m apart, states up to 0.35 sigma from
# pyins'). Over all the cached seeds this is also "no worse than pyins per outage": no
# outage where stochmod is worse beyond 2 standard errors of the paired difference (measured,
# 10 seeds: -0.03 +- 0.02, -0.01 +- 0.01 and -0.04 +- 0.01 m: not resolved, not resolved,
# better).
MODIFIED_SLACK = 0.005
MODIFIED_ABS = 0.25  # m
MODIFIED_STATE_SD = 0.025


@pytest.mark.slow
def test_real_drive_with_pyins_reset_reproduces_pyins(drive) -> None:
    cache = json.loads(ENSEMBLE_JSON.read_text())
    assert len(cache["runs"]) >= 8
    runs = stochmod_runs(drive, cache, error_model="modified-phi")
    s = summary({seed: r[0] for seed, r in runs.items()}, cache)
    assert "worse" not in verdict(s), (verdict(s), s["difference_mean"], s["difference_se"])
    for seed, (errors, ours) in runs.items():
        peer = cache["runs"][seed]
        theirs = np.array(peer["max_horizontal_error_m"])
        np.testing.assert_array_less(np.abs(errors - theirs),
                                     MODIFIED_SLACK * theirs + MODIFIED_ABS,
                                     err_msg=f"seed {seed}")
        for name, sd in (("rph_error_deg", "rph_sd_deg"), ("gyro_bias_deg_h", "gyro_bias_sd_deg_h"),
                         ("accel_bias_m_s2", "accel_bias_sd_m_s2")):
            np.testing.assert_array_less(np.abs(np.subtract(ours[name], peer["states_at_outages"][
                name])), MODIFIED_STATE_SD * np.array(peer["states_at_outages"][sd]),
                err_msg=f"{seed} {name}")


# Position + velocity updates, no lever arm (the settings of test_real_drive_beside_pyins)
# over the seeded starts of tests/nav/reference/nav_pyins_n380_ensemble_velocity.json
# (studies/nav_n380_ensemble.py --velocity; docs/navigation_real_drive.md, "With velocity
# updates"). The psi filter is worse than pyins in outage 2 in every seed, by a systematic
# 1.29 +- 0.06 m (3.7 %; the sum by 1.96 +- 0.87 m): the tilt / accelerometer-bias split of
# its reset (before outage 2 its states differ from pyins' with the signs of the position
# case), not realisation noise. It is held to the per-outage figure of the comparison (mean
# within VELOCITY_RELATIVE of pyins'), to its states (within half of pyins' sigma; measured at
# most 0.18) and below VELOCITY_GAP_BOUND so that it cannot grow unnoticed. With pyins' reset
# (modified-phi) no outage and not the sum is worse than pyins at 2 standard errors (measured:
# -0.07 +- 0.02, -0.13 +- 0.06, -0.03 +- 0.01 m, sum -0.23 +- 0.07 m: better), every seed's
# outages within VELOCITY_MODIFIED_SLACK of pyins' plus MODIFIED_ABS (measured at most 0.43 m,
# half of the allowance) and its states within VELOCITY_MODIFIED_STATE_SD of pyins' sigma
# (measured at most 0.038).
VELOCITY_RELATIVE = 0.10
VELOCITY_GAP_BOUND = 2.0  # m
VELOCITY_MODIFIED_SLACK = 0.02
VELOCITY_MODIFIED_STATE_SD = 0.1


@pytest.mark.slow
@pytest.mark.parametrize("error_model", ["psi", "modified-phi"])
def test_real_drive_with_velocity_over_seeded_starts_beside_pyins(drive, error_model) -> None:
    cache = json.loads(ENSEMBLE_VELOCITY_JSON.read_text())
    assert cache["lever_arm_m"] == [0.0, 0.0, 0.0] and cache["mode"] == "position_velocity"
    assert len(cache["runs"]) >= 8
    runs = stochmod_runs(drive, cache, error_model=error_model)
    s = summary({seed: r[0] for seed, r in runs.items()}, cache)
    assert all((r[0] > 1.0).all() for r in runs.values())  # dead reckoning: metres, not a copy
    sums = np.array([runs[k][0].sum() - sum(cache["runs"][k]["max_horizontal_error_m"])
                     for k in runs])
    sum_lower = sums.mean() - 2 * sums.std(ddof=1) / np.sqrt(sums.size)
    np.testing.assert_array_less(s["stochmod_mean"], (1 + VELOCITY_RELATIVE) * s["pyins_mean"])
    for seed, (_, ours) in runs.items():
        theirs = cache["runs"][seed]["states_at_outages"]
        for name, sd in (("rph_error_deg", "rph_sd_deg"), ("gyro_bias_deg_h", "gyro_bias_sd_deg_h"),
                         ("accel_bias_m_s2", "accel_bias_sd_m_s2")):
            limit = 0.5 if error_model == "psi" else VELOCITY_MODIFIED_STATE_SD
            np.testing.assert_array_less(np.abs(np.subtract(ours[name], theirs[name])),
                                         limit * np.array(theirs[sd]), err_msg=f"{seed} {name}")
    if error_model == "psi":
        assert verdict(s)[1] == "worse"  # the known, systematic gap (see above)
        np.testing.assert_array_less(s["difference_mean"], VELOCITY_GAP_BOUND)
        return
    assert "worse" not in verdict(s), (verdict(s), s["difference_mean"], s["difference_se"])
    assert sum_lower <= 0  # the sum: at or below pyins' (not worse at 2 standard errors)
    for seed, (errors, _) in runs.items():
        theirs = np.array(cache["runs"][seed]["max_horizontal_error_m"])
        np.testing.assert_array_less(np.abs(errors - theirs),
                                     VELOCITY_MODIFIED_SLACK * theirs + MODIFIED_ABS,
                                     err_msg=f"seed {seed}")


# Position + velocity updates with the fitted lever arm fixed in both filters, over the seeded
# starts of tests/nav/reference/nav_pyins_n380_ensemble_velocity_lever_arm.json
# (studies/nav_n380_ensemble.py --velocity --lever-arm; docs/navigation_real_drive.md, "With
# velocity updates and the lever arm"). pyins 1.0.1 predicts the antenna velocity
# v + C (w x l) but differentiates only v: its Jacobian lacks [(C (w x l)) x] on the attitude
# error and the gyro-bias column, which stochmod's has (the derivative of the prediction,
# tests/nav/test_lever_arm.py). With pyins' Jacobian (pyins_velocity_jacobian) the
# modified-phi filter reproduces pyins: every seed and outage within MODIFIED_SLACK of pyins'
# plus MODIFIED_ABS (measured at most 0.105 m, 0.36 of the allowance), the states within
# MODIFIED_STATE_SD of pyins' sigma (measured at most 0.011) and no outage nor the sum worse at
# 2 standard errors (measured -0.02 +- 0.01, -0.04 +- 0.01, -0.03 +- 0.01, sum -0.08 +- 0.02 m).
# With its own Jacobian each model is held to the comparison's per-outage figure, its mean
# within LEVER_VELOCITY_RELATIVE of pyins' (measured: modified-phi +2.4, +0.2, +0.4 %; psi
# -0.2, +3.5, +1.9 %), its states within LEVER_VELOCITY_STATE_SD of pyins' sigma (measured
# 0.080 and 0.129), and the sum's excess over pyins' below LEVER_VELOCITY_SUM_BOUND (measured
# +0.92 +- 0.17 m modified-phi, +0.44 +- 0.19 m psi: the complete Jacobian costs this recording
# about a metre in outage 1, where on emulated drives with known truth it is no worse,
# studies/nav_reset_emulation.py --velocity-sd).
LEVER_VELOCITY_RELATIVE = 0.10
LEVER_VELOCITY_STATE_SD = {"psi": 0.5, "modified-phi": 0.2}
LEVER_VELOCITY_SUM_BOUND = 2.0  # m


@pytest.mark.slow
@pytest.mark.parametrize("error_model, jacobian", [("modified-phi", "pyins"),
                                                   ("modified-phi", "stochmod"),
                                                   ("psi", "stochmod")])
def test_real_drive_with_velocity_and_lever_arm_over_seeded_starts_beside_pyins(
        drive, error_model, jacobian) -> None:
    cache = json.loads(ENSEMBLE_VELOCITY_LEVER_ARM_JSON.read_text())
    assert cache["lever_arm_m"] == list(LEVER_ARM) and cache["mode"] == "position_velocity"
    assert len(cache["runs"]) >= 8
    with pyins_velocity_jacobian() if jacobian == "pyins" else contextlib.nullcontext():
        runs = stochmod_runs(drive, cache, error_model=error_model)
    s = summary({seed: r[0] for seed, r in runs.items()}, cache)
    assert all((r[0] > 1.0).all() for r in runs.values())  # dead reckoning: metres, not a copy
    sums = np.array([runs[k][0].sum() - sum(cache["runs"][k]["max_horizontal_error_m"])
                     for k in runs])
    se = sums.std(ddof=1) / np.sqrt(sums.size)
    limit = MODIFIED_STATE_SD if jacobian == "pyins" else LEVER_VELOCITY_STATE_SD[error_model]
    for seed, (_, ours) in runs.items():
        theirs = cache["runs"][seed]["states_at_outages"]
        for name, sd in (("rph_error_deg", "rph_sd_deg"), ("gyro_bias_deg_h", "gyro_bias_sd_deg_h"),
                         ("accel_bias_m_s2", "accel_bias_sd_m_s2")):
            np.testing.assert_array_less(np.abs(np.subtract(ours[name], theirs[name])),
                                         limit * np.array(theirs[sd]), err_msg=f"{seed} {name}")
    if jacobian == "pyins":  # pyins' filter, reproduced
        assert "worse" not in verdict(s), (verdict(s), s["difference_mean"], s["difference_se"])
        assert sums.mean() - 2 * se <= 0
        for seed, (errors, _) in runs.items():
            theirs = np.array(cache["runs"][seed]["max_horizontal_error_m"])
            np.testing.assert_array_less(np.abs(errors - theirs),
                                         MODIFIED_SLACK * theirs + MODIFIED_ABS,
                                         err_msg=f"seed {seed}")
        return
    np.testing.assert_array_less(s["stochmod_mean"],
                                 (1 + LEVER_VELOCITY_RELATIVE) * s["pyins_mean"])
    assert sums.mean() < LEVER_VELOCITY_SUM_BOUND
