"""Loosely-coupled filter on emulated data with known error models: NEES inside its chi-square
band over seeded runs, sensor-error states converge to the simulated biases, gating counts an
injected outlier, lever arm, heading and zero-velocity updates, AR (discrete) sensor blocks."""

import math

import numpy as np
import pytest
from scipy.stats import chi2

import stochmod
from stochmod.core.errors import InputError, SpecError
from stochmod.nav import (
    GnssData,
    InitialState,
    LooselyCoupledFilter,
    Segment,
    add_sensor_errors,
    frames,
    gnss_measurements,
    ideal_imu,
    magnetometer_heading,
    trajectory_from_profile,
)
from stochmod.nav.emulate import AXES
from stochmod.core.statespace import discretise
from stochmod.nav.filter import _axis_models, _Sensors
from stochmod.nav.measurements import heading_jacobian
from stochmod.core.statespace import ContinuousBlock, van_loan

from ._emulated import imu_with_biases

FS = 100.0
WN, GM = stochmod.WN, stochmod.GM
GYRO = (WN.from_density(6e-5, FS) + GM.from_correlation_time(100.0, 1e-4)).bind(FS)
ACCEL = (WN.from_density(8e-4, FS) + GM.from_correlation_time(200.0, 1e-3)).bind(FS)
BIAS_SD = (5e-4, 0.02)
ARM = np.array([0.8, 0.3, -1.2])
PROFILE = [Segment(15, speed=10), Segment(15, turn=90), Segment(20, speed=20),
           Segment(15, turn=-90), Segment(25, turn=180, pitch=2), Segment(20, speed=12, pitch=0),
           Segment(15, turn=-90), Segment(15, turn=45, speed=18)]


@pytest.fixture(scope="module")
def truth():
    return trajectory_from_profile(PROFILE, rate=FS, lat=47.0, lon=8.0, height=500.0,
                                   heading=-40.0, speed=5.0)


@pytest.fixture(scope="module")
def clean_imu(truth):
    return ideal_imu(truth, "increment")


def _emulate(truth, clean, seed):
    rng = np.random.default_rng(seed)
    imu, bias = imu_with_biases(clean, GYRO, ACCEL, BIAS_SD, rng)
    gnss = gnss_measurements(truth, 1.0, cep=1.5, sigma_v=3.0, sigma_vel=0.05, lever_arm=ARM,
                             rng=rng)
    init0 = truth.at(truth.time[:1])
    sd = np.array([1.0, 1.0, 1.0, 0.1, 0.1, 0.1, 0.5, 0.5, 2.0])
    e = rng.standard_normal(9) * sd  # a start drawn from the stated initial covariance
    init = InitialState(init0.lat[0] + math.degrees(e[0] / 6.37e6),
                        init0.lon[0] + math.degrees(e[1] / 6.37e6 / math.cos(math.radians(47))),
                        init0.height[0] - e[2], init0.vel_ned[0] + e[3:6],
                        init0.rph[0] + e[6:9], sd_position=1.0, sd_velocity=0.1,
                        sd_attitude=(0.5, 0.5, 2.0))
    return imu, gnss, init, bias


def _filter(**kw):
    return LooselyCoupledFilter(GYRO, ACCEL, dt_filter=0.1, lever_arm=ARM,
                                gyro_bias_sd=BIAS_SD[0], accel_bias_sd=BIAS_SD[1], **kw)


@pytest.mark.slow
def test_nees_in_band_and_biases_converge(truth, clean_imu):
    runs = 3
    flt = _filter()
    nees, hits = [], 0
    for seed in range(runs):
        imu, gnss, init, bias = _emulate(truth, clean_imu, seed)
        res = flt.run(imu.time, imu.gyro, imu.accel, kind="increment", gnss=gnss, init=init,
                      truth=truth)
        assert len(res.state_names) == 21
        nees.append(res.nees[res.epoch_time > 10.0])
        # turn-on bias states: within 3 sigma of the truth, sigma well below the prior for the
        # axes the manoeuvres make observable
        names = list(res.state_names)
        for i, axis in enumerate(AXES):
            j = names.index(f"{axis}.bias")
            est = res.sensor_states[-1, j - 9]
            sd = res.epoch_sd[-1, j]
            prior = BIAS_SD[i // 3]
            assert abs(est - bias[i]) < 3.5 * sd + 0.2 * prior, (axis, est, bias[i], sd)
            if axis in ("gyro_x", "gyro_y", "accel_x", "accel_y", "accel_z"):
                assert sd < 0.35 * prior, (axis, sd)
                hits += abs(est - bias[i]) < 0.3 * prior
    # average NEES of the 9 navigation states over runs and epochs inside the 95% band of the
    # mean of `runs` independent chi-square(9) variables (epochs of one run are correlated, so
    # the band counts one sample per run)
    mean = np.mean([x.mean() for x in nees])
    lo, hi = chi2.ppf([0.025, 0.975], 9 * runs) / runs
    print(f"mean NEES {mean:.3f} band [{lo:.3f}, {hi:.3f}], close bias estimates {hits}")
    assert lo < mean < hi, (mean, lo, hi)
    assert hits >= 0.8 * 5 * runs


def test_gate_rejects_an_injected_outlier_and_counts_it(truth, clean_imu):
    imu, gnss, init, _ = _emulate(truth, clean_imu, 11)
    lat = gnss.lat.copy()
    k = 60
    lat[k] += math.degrees(80.0 / 6.37e6)  # an 80 m jump north
    bad = GnssData(gnss.time, lat, gnss.lon, gnss.height, gnss.vel_ned, gnss.sd, gnss.sd_vel)
    sel = truth.time <= 100.0
    res = _filter(gate=0.9999).run(imu.time[sel], imu.gyro[sel], imu.accel[sel],
                                   kind="increment", gnss=bad, init=init, truth=truth)
    assert res.rejected == {"gnss_position": 1}
    nis = res.nis["gnss_position"]
    assert nis[nis[:, 3] == 0, 0] == pytest.approx([gnss.time[k]])
    assert nis[nis[:, 3] == 0, 1][0] > 100.0
    # without the gate the outlier pulls the position
    res2 = _filter(gate=None).run(imu.time[sel], imu.gyro[sel], imu.accel[sel],
                                  kind="increment", gnss=bad, init=init, truth=truth)
    assert res2.rejected == {}
    assert res2.nees.max() > 5 * res.nees.max()
    assert "rejected" in res.summary()


def test_outage_grows_sigma_and_heading_zupt_updates(truth, clean_imu):
    imu, gnss, init, _ = _emulate(truth, clean_imu, 5)
    sel = truth.time <= 120.0
    mag_t, mag_h = magnetometer_heading(truth, 1.0, rate=1.0, rng=1)
    res = _filter().run(imu.time[sel], imu.gyro[sel], imu.accel[sel], kind="increment",
                        gnss=gnss, init=init, outages=[(60.0, 30.0)], truth=truth,
                        heading=(mag_t, mag_h, 1.0))
    inside = (res.time > 60.0) & (res.time < 90.0)
    before = (res.time > 50.0) & (res.time < 60.0)
    assert res.sd_position[inside, 0].max() > 3 * res.sd_position[before, 0].max()
    gt = res.nis["gnss_position"][:, 0]
    assert not np.any((gt >= 60.0) & (gt < 90.0))
    assert res.nis["heading"].shape[0] == 120
    assert 0.3 < res.nis["heading"][:, 1].mean() < 2.5  # chi-square(1) mean 1
    assert res.mean_nees < chi2.ppf(0.999, 9)


def test_zero_velocity_update_at_rest():
    tr = trajectory_from_profile([Segment(30.0)], rate=FS, lat=10.0, lon=20.0, height=0.0)
    imu = add_sensor_errors(ideal_imu(tr, "rate"), {"accel_x": ACCEL, "gyro_z": GYRO}, 3)
    init = InitialState(tr.lat[0], tr.lon[0], 0.0, [0.0, 0.0, 0.0], tr.rph[0], sd_velocity=0.5)
    flt = LooselyCoupledFilter(GYRO, ACCEL, dt_filter=0.1)
    res = flt.run(imu.time, imu.gyro, imu.accel, kind="rate", init=init,
                  zero_velocity=(np.arange(1.0, 30.0, 1.0), 0.01), truth=tr)
    assert res.nis["zero_velocity"].shape[0] == 29
    assert np.abs(res.vel_ned[-1]).max() < 0.05
    assert res.sd_velocity[-1].max() < 0.02


def test_ar_models_give_a_discrete_sensor_block(truth, clean_imu):
    ar = stochmod.model_from_spec({"processes": [
        {"family": "AR", "params": {"phi": [0.5, 0.3, 0.1], "sigma2": 1e-9}},
        {"family": "WN", "params": {"sigma2": 6e-5**2 * FS}}], "freq": FS})
    imu, gnss, init, _ = _emulate(truth, clean_imu, 2)
    flt = LooselyCoupledFilter(ar, ACCEL, dt_filter=0.1, lever_arm=ARM,
                               accel_bias_sd=BIAS_SD[1], gyro_bias_sd=BIAS_SD[0])
    sel = truth.time <= 60.0
    res = flt.run(imu.time[sel], imu.gyro[sel], imu.accel[sel], kind="increment", gnss=gnss,
                  init=init, truth=truth)
    assert len(res.state_names) == 9 + 3 * 3 + 3 + 6  # 27 states
    assert "gyro_x.AR.lag2" in res.state_names
    assert np.isfinite(res.nees).all() and res.mean_nees < 3 * 9
    # a real IMU clock (30 ppm fast) is not a whole multiple of the AR sample period
    t = imu.time[sel] * (1 - 3e-5)
    res2 = flt.run(t, imu.gyro[sel], imu.accel[sel], kind="increment", gnss=gnss, init=init)
    assert np.isfinite(res2.epoch_sd).all()


def test_series_discretisation_matches_van_loan():
    rng = np.random.default_rng(0)
    for scale in (0.01, 1.0, 30.0):
        F = rng.normal(size=(12, 12)) * scale
        G = rng.normal(size=(12, 12))
        W = G @ G.T
        Phi, Q = discretise(F, W, 0.1)
        Phi2, Q2 = van_loan(ContinuousBlock(F, np.eye(12), W), 0.1)
        np.testing.assert_allclose(Phi, Phi2, rtol=1e-9, atol=1e-12 * np.abs(Phi2).max())
        np.testing.assert_allclose(Q, Q2, rtol=1e-8, atol=1e-11 * np.abs(Q2).max())


def _stiff_error_model(dt):
    """Navigation-like F and W coupled to the blocks of a GMWM-like ``3*GM + WN`` whose GM
    correlation times are far below (1e-4 s, 1e-20 s) and far above (1e4 s) the step."""
    taus, sigmas = (1e-4, 1e4, 1e-20), (2e-3, 1e-3, 1e-2)
    model = WN.from_density(1e-4, FS)
    for tau, sig in zip(taus, sigmas):
        model = model + GM.from_correlation_time(tau, sig)
    cont = model.bind(FS).augment(dt).continuous
    rng = np.random.default_rng(3)
    F = np.zeros((9 + 3, 9 + 3))
    F[:9, :9] = rng.normal(size=(9, 9)) * 1e-3
    F[0:3, 3:6] = np.eye(3)
    F[3:9, 9:] = rng.normal(size=(6, 3))
    F[9:, 9:] = cont.F
    W = np.zeros_like(F)
    W[3:9, 3:9] = np.eye(6) * 1e-6
    W[9:, 9:] = cont.G @ cont.Qc @ cont.G.T
    return F, W, np.array(taus), np.array(sigmas)


def test_discretisation_is_exact_on_poles_far_from_the_step():
    # a Gauss-Markov pole 1e20/s overflowed the unscaled power series (NaN covariance)
    dt = 1.0
    F, W, taus, sigmas = _stiff_error_model(dt)
    Phi, Q = discretise(F, W, dt)
    assert np.isfinite(Phi).all() and np.isfinite(Q).all()
    phi = np.exp(-dt / taus)  # closed-form Gauss-Markov discretisation
    np.testing.assert_allclose(Phi[9:, 9:], np.diag(phi), rtol=1e-13, atol=1e-300)
    np.testing.assert_allclose(Q[9:, 9:], np.diag(sigmas**2 * (1 - phi**2)), rtol=1e-12,
                               atol=1e-300)
    assert np.linalg.eigvalsh(Q)[0] > -1e-12 * np.abs(Q).max()
    # without the 1e20/s pole Van Loan (scipy's expm, its own scaling) is an independent check
    keep = np.r_[0:11]
    F2, W2 = F[np.ix_(keep, keep)], W[np.ix_(keep, keep)]
    Phi2, Q2 = discretise(F2, W2, dt)
    Phi3, Q3 = van_loan(ContinuousBlock(F2, np.eye(11), W2), dt)
    np.testing.assert_allclose(Phi2, Phi3, rtol=1e-9, atol=1e-12 * np.abs(Phi3).max())
    np.testing.assert_allclose(Q2, Q3, rtol=1e-8, atol=1e-11 * np.abs(Q3).max())
    # the pole at 1e20/s acts on the navigation states as white noise of PSD 2 sigma^2 tau:
    # dropping it changes the navigation block of Q by that white noise only (< 1e-20 here)
    np.testing.assert_allclose(Phi[:11, :11], Phi2, rtol=1e-12, atol=1e-12)
    bad = F.copy()
    bad[11, 11] = -np.inf
    with pytest.raises(InputError, match="non-finite"):
        discretise(bad, W, dt)


def test_a_sub_sample_gauss_markov_process_is_the_white_noise_it_is_at_the_imu_rate(
        truth, clean_imu):
    # correlation times of 1e-4 s and 1e-20 s (a GMWM fit can return either) at 100 Hz: each
    # sample is independent, variance sigma^2; the filter must treat them as that white noise
    # (integrated in continuous time they would give 2 sigma^2 Tc, far too little), and the
    # 1e-20 s pole once overflowed the discretisation
    imu, gnss, init, _ = _emulate(truth, clean_imu, 0)
    sig = (2e-4, 1e-4)
    fast = (GYRO + GM.from_correlation_time(1e-4, sig[0])
            + GM.from_correlation_time(1e-20, sig[1])).bind(FS)
    wn_var = GYRO.augment(1.0 / FS).white_var + sig[0] ** 2 + sig[1] ** 2
    white = (WN(sigma2=wn_var) + GYRO.processes[1]).bind(FS)
    sel = truth.time <= 5.0
    runs = [LooselyCoupledFilter(m, ACCEL, dt_filter=0.1, lever_arm=ARM).run(
        imu.time[sel], imu.gyro[sel], imu.accel[sel], kind="increment", gnss=gnss, init=init)
        for m in (fast, white)]
    assert len(runs[0].state_names) == len(runs[1].state_names)  # the two fast states are gone
    np.testing.assert_allclose(runs[0].epoch_sd, runs[1].epoch_sd, rtol=1e-12)
    np.testing.assert_allclose(runs[0].lat, runs[1].lat, rtol=0, atol=1e-12)
    # a process correlated over several samples keeps its state
    slow = (GYRO + GM.from_correlation_time(0.05, sig[0])).bind(FS)
    assert len(LooselyCoupledFilter(slow, ACCEL).state_names(1.0 / FS)) == \
        len(LooselyCoupledFilter(GYRO, ACCEL).state_names(1.0 / FS)) + 3


def test_a_gauss_markov_far_beyond_the_record_is_the_random_walk_it_equals_over_it(
        truth, clean_imu):
    # closed form: at fixed driving noise q = 2 sigma^2 / Tc the GM's exact step, Phi =
    # exp(-dt/Tc) and Q = sigma^2 (1 - exp(-2 dt/Tc)), tends to the random walk's (1, q dt)
    # at the rate dt/Tc as Tc -> infinity
    dt, q = 0.01, 2 * 32.0**2 / 7e13  # gyro y of the degenerate full-structure fit (outages.md)
    rw = stochmod.Model((stochmod.RW.from_rrw(math.sqrt(q), FS),), FS).augment(dt)
    assert rw.Phi[0, 0] == 1.0 and rw.Q[0, 0] == pytest.approx(q * dt, rel=1e-12)
    for tc in (1e4, 1e7, 1e10, 7e13):
        gm = stochmod.Model((GM.from_correlation_time(tc, math.sqrt(q * tc / 2)),), FS).augment(dt)
        assert abs(gm.Phi[0, 0] - rw.Phi[0, 0]) == pytest.approx(dt / tc, rel=1e-3)
        assert gm.Q[0, 0] / rw.Q[0, 0] - 1 == pytest.approx(-dt / tc, rel=1e-3, abs=1e-14)
        assert gm.P0[0, 0] == pytest.approx(q * tc / 2)  # stationary: grows without bound
    # the filter, told the 5243 s record of the fit, augments it as that random walk started
    # with the spread it reaches over the record, q T, instead of the stationary 32 rad/s
    record = 2**19 / FS
    degenerate = (GYRO + GM.from_correlation_time(7e13, 32.0)).bind(FS)
    with pytest.warns(UserWarning, match=r"gyro_x.GM2.*beyond the 5242.88 s record"):
        sens = _Sensors(_axis_models(degenerate, ACCEL), dt, 0.0, 0.0, record=record)
    names = list(sens.names)
    walks = {r.state: r for r in sens.random_walks}
    assert sorted(walks) == [f"gyro_{a}.GM2.value" for a in "xyz"]
    for state, r in walks.items():
        i = names.index(state)
        assert r.q == pytest.approx(q, rel=1e-12) and r.tc == pytest.approx(7e13)
        assert r.stationary_sd == pytest.approx(32.0, rel=1e-12)
        assert sens.F[i, i] == 0.0 and sens.Phi1[i, i] == 1.0
        assert sens.Q1[i, i] == pytest.approx(rw.Q[0, 0], rel=1e-12)
        assert sens.P0[i, i] == pytest.approx(q * record, rel=1e-12)
    # GMs the record resolves (100 s and 200 s) are untouched: the same block as without it
    plain = _Sensors(_axis_models(GYRO, ACCEL), dt, 0.0, 0.0)
    same = _Sensors(_axis_models(GYRO, ACCEL), dt, 0.0, 0.0, record=record)
    assert same.random_walks == ()
    for a, b in ((plain.Phi1, same.Phi1), (plain.Q1, same.Q1), (plain.P0, same.P0)):
        np.testing.assert_array_equal(a, b)
    # a run reports the substitution; a record shorter than every Tc refuses nothing else
    imu, gnss, init, _ = _emulate(truth, clean_imu, 0)
    sel = truth.time <= 5.0
    with pytest.warns(UserWarning, match="random walk"):
        res = LooselyCoupledFilter(degenerate, ACCEL, dt_filter=0.1, lever_arm=ARM,
                                   record=record).run(imu.time[sel], imu.gyro[sel],
                                                      imu.accel[sel], kind="increment",
                                                      gnss=gnss, init=init)
    assert len(res.random_walks) == 3 and "gyro_y.GM2.value" in res.summary()
    j = list(res.state_names).index("gyro_y.GM2.value")
    assert res.epoch_sd[0, j] <= math.sqrt(q * record) * (1 + 1e-9)
    with pytest.raises(InputError, match="record"):
        LooselyCoupledFilter(GYRO, ACCEL, record=-1.0)


def test_heading_jacobian_by_finite_differences():
    rng = np.random.default_rng(4)
    for _ in range(20):
        rph = rng.uniform([-40, -60, -180], [40, 60, 180])
        C = frames.rph_to_dcm(rph)
        J = np.zeros(3)
        for i in range(3):
            d = np.zeros(3)
            d[i] = 1e-7
            hp = frames.dcm_to_rph((np.eye(3) - frames.skew(d)) @ C)[2]
            hm = frames.dcm_to_rph((np.eye(3) + frames.skew(d)) @ C)[2]
            J[i] = math.radians((hp - hm + 180) % 360 - 180) / 2e-7
        np.testing.assert_allclose(heading_jacobian(C), J, atol=1e-6)
        p, h = math.radians(rph[1]), math.radians(rph[2])
        np.testing.assert_allclose(heading_jacobian(C),
                                   [-math.cos(h) * math.tan(p), -math.sin(h) * math.tan(p), -1],
                                   atol=1e-9)


def test_bad_configuration_is_refused(truth, clean_imu):
    with pytest.raises(SpecError, match="bound"):
        LooselyCoupledFilter(stochmod.model_from_spec("GM+WN"), ACCEL)
    with pytest.raises(SpecError, match="x', 'y', 'z"):
        LooselyCoupledFilter({"x": GYRO}, ACCEL)
    with pytest.raises(InputError, match="dt_filter"):
        LooselyCoupledFilter(GYRO, ACCEL, dt_filter=0.0)
    with pytest.raises(InputError, match="gate"):
        LooselyCoupledFilter(GYRO, ACCEL, gate=1.5)
    flt = LooselyCoupledFilter(GYRO, ACCEL)
    imu = clean_imu
    with pytest.raises(InputError, match="give gnss"):
        flt.run(imu.time, imu.gyro, imu.accel, kind="increment")
    init = InitialState(47.0, 8.0, 500.0, [0, 0, 0], [0, 0, 0], time=1e6)
    with pytest.raises(InputError, match="fewer than two"):
        flt.run(imu.time, imu.gyro, imu.accel, kind="increment", init=init)
    with pytest.raises(InputError, match="positive"):
        InitialState(47.0, 8.0, 500.0, [0, 0, 0], [0, 0, 0], sd_position=0.0).covariance()


def test_a_broken_covariance_is_reported_not_hidden(truth, clean_imu, monkeypatch):
    import stochmod.nav.filter as nf

    real = nf.discretise

    def broken(F, W, dt):  # a process noise with a negative eigenvalue
        Phi, Q = real(F, W, dt)
        return Phi, Q - np.eye(Q.shape[0]) * 10.0

    monkeypatch.setattr(nf, "discretise", broken)
    imu, gnss, init, _ = _emulate(truth, clean_imu, 0)
    sel = truth.time <= 5.0
    with pytest.raises(nf.EstimationError, match="positive semi-definiteness"):
        _filter().run(imu.time[sel], imu.gyro[sel], imu.accel[sel], kind="increment", gnss=gnss,
                      init=init)


def test_gnss_between_imu_samples_and_a_late_start(truth, clean_imu):
    # fixes stamped 3.7 ms after IMU epochs (asynchronous) and a start 2 s into the record
    imu, _, _, _ = _emulate(truth, clean_imu, 8)
    shifted = truth.at(truth.time[truth.time <= 80.0] + 0.0037)
    gnss = gnss_measurements(shifted, 1.0, cep=1.5, sigma_v=3.0, sigma_vel=0.05, lever_arm=ARM,
                             rng=9)
    assert np.allclose(gnss.time % 1.0, 0.0037)
    s = truth.at([2.0])
    init = InitialState(s.lat[0], s.lon[0], s.height[0], s.vel_ned[0], s.rph[0], time=2.0,
                        sd_position=1.0, sd_velocity=0.1, sd_attitude=(0.5, 0.5, 2.0))
    sel = truth.time <= 80.0
    res = _filter().run(imu.time[sel], imu.gyro[sel], imu.accel[sel], kind="increment",
                        gnss=gnss, init=init, truth=truth)
    assert res.time[0] == pytest.approx(2.0)
    assert res.nis["gnss_position"][0, 0] == pytest.approx(2.0037)  # first fix after the start
    for kind in ("gnss_position", "gnss_velocity"):
        assert 1.8 < res.nis[kind][:, 1].mean() < 4.5, kind  # chi-square(3) mean 3
    assert res.mean_nees < chi2.ppf(0.99, 9)
