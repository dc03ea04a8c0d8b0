"""Robust wavelet variance (issue 13): tuning, consistency, variance, intervals, diagnostic."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import integrate, stats

import stochmod
from stochmod.core.errors import InputError
from stochmod.empirical.robust_wv import (
    MAX_PATCH,
    isolated_patches,
    m_scale,
    replace_patches,
    robust_wvar,
    sandwich_ratio,
    scale_rho,
)
from stochmod.empirical.wavelet_variance import wvar

PHI = stats.norm.pdf
# quad reports round-off near its 1e-12 target on the kinked integrands; accuracy is asserted
pytestmark = pytest.mark.filterwarnings("ignore::scipy.integrate.IntegrationWarning")


# --- independent definitions of the two chi functions (as functions of r, not u = r^2) ---
def _psi_biweight(r, c):
    return np.where(np.abs(r) <= c, r * (1.0 - (r / c) ** 2) ** 2, 0.0)


def _chi_of_r(r, rho):
    if rho.name == "biweight":
        return _psi_biweight(r, rho.c) ** 2
    return np.minimum(r * r, rho.c**2)


def _quad(f, rho):
    """Integral of f(z) phi(z) over the line, split at +-c (kinks)."""
    c = rho.c
    parts = [(-np.inf, -c), (-c, c), (c, np.inf)]
    return sum(integrate.quad(lambda z: f(z) * PHI(z), a, b, epsabs=1e-13, epsrel=1e-12,
                              limit=200)[0] for a, b in parts)


def _quad_efficiency(rho):
    h = 1e-6
    chi = lambda z: float(_chi_of_r(z, rho))  # noqa: E731
    dchi_z = lambda z: (chi(z + h) - chi(z - h)) / (2 * h) * z  # noqa: E731  chi'(z) z
    m1 = _quad(chi, rho)
    m2 = _quad(lambda z: chi(z) ** 2, rho)
    slope = _quad(dchi_z, rho)
    return m1, slope, m2 - m1**2


@settings(max_examples=12, deadline=None)
@given(eff=st.floats(0.05, 0.97), rho=st.sampled_from(["biweight", "huber"]))
def test_tuning_constant_reproduces_requested_efficiency(eff, rho):
    """c is tuned so that B^2 / (2 Var chi) = eff, checked by numerical integrals of the
    chi function written out from its definition (derivative by differences, not Stein)."""
    r = scale_rho(eff, rho)
    m1, slope, var = _quad_efficiency(r)
    assert slope**2 / (2 * var) == pytest.approx(eff, rel=1e-6)
    assert r.consistency == pytest.approx(m1, rel=1e-9)
    assert r.slope == pytest.approx(slope, rel=1e-6)
    assert r.score_variance == pytest.approx(var, rel=1e-9)


@pytest.mark.parametrize("rho", ["biweight", "huber"])
@pytest.mark.parametrize("nu", [1e-6, 0.3, 42.0])
def test_consistent_at_the_gaussian_by_quadrature(rho, nu):
    """E[chi(W^2 / v)] = delta at v = nu for W ~ N(0, nu), and the equation decreases
    through the root (it is the largest root, the one m_scale returns)."""
    r = scale_rho(0.6, rho)
    sd = math.sqrt(nu)

    def expected(v):
        return _quad(lambda z: float(_chi_of_r(z * sd / math.sqrt(v), r)), r)

    assert expected(nu) == pytest.approx(r.consistency, rel=1e-10)
    assert expected(1.05 * nu) < r.consistency < expected(0.95 * nu)
    if rho == "biweight":  # redescending: chi -> 0 for v -> 0 too, but the root is the upper one
        assert expected(1e-3 * nu) < r.consistency


def test_hermite_expansion_matches_bivariate_quadrature():
    """cov(chi(Z0^2), chi(Z1^2)) for corr(Z0, Z1) = rho equals sum_k b_2k^2 rho^2k; the
    bivariate expectation by a Gauss-Hermite product rule (independent of the expansion)."""
    chi = scale_rho(0.6)
    assert chi.hermite_squares.sum() == pytest.approx(chi.score_variance, rel=1e-5)
    assert chi.hermite_squares[0] == pytest.approx(chi.slope**2 / 2, rel=1e-10)
    nodes, weights = np.polynomial.hermite_e.hermegauss(200)
    weights = weights / weights.sum()
    for corr in (-0.5, 0.3, 0.8):
        z0 = nodes[:, None]
        z1 = corr * z0 + math.sqrt(1 - corr**2) * nodes[None, :]
        joint = np.outer(weights, weights)
        cov = float(np.sum(joint * chi.chi(z0**2) * chi.chi(z1**2))) - chi.consistency**2
        series = float(np.sum(chi.hermite_squares * corr ** (2 * np.arange(1, 11))))
        assert series == pytest.approx(cov, rel=2e-3)


def test_m_scale_solves_its_equation_and_is_equivariant():
    rng = np.random.default_rng(5)
    w = rng.standard_normal(50_000) * 0.2
    w[::997] *= 40.0  # outliers beyond the first bracket's core
    for name in ("biweight", "huber"):
        chi = scale_rho(0.6, name)
        est = m_scale(w, chi)
        assert np.mean(chi.chi(w**2 / est.variance)) == pytest.approx(chi.consistency, rel=1e-10)
        assert m_scale(3e-20 * w, chi).variance == pytest.approx(9e-40 * est.variance, rel=1e-9)
        assert est.variance == pytest.approx(0.04, rel=0.03)
    chi = scale_rho(0.6)
    est = m_scale(w, chi)
    assert est.n_rejected == np.count_nonzero(w**2 > chi.c**2 * est.variance)
    assert np.all(np.isin(est.worst, np.arange(0, w.size, 997)))
    assert np.all(np.diff(est.worst_score) <= 0)


def test_m_scale_variance_ratio_is_one_over_efficiency_for_iid_gaussian():
    """Monte Carlo: var(M-estimate) / var(mean of squares) -> 1/eff for iid coefficients."""
    rng = np.random.default_rng(11)
    reps, m, eff = 800, 1000, 0.6
    chi = scale_rho(eff)
    w = rng.standard_normal((reps, m))
    robust = np.array([m_scale(row, chi).variance for row in w])
    classical = np.mean(w**2, axis=1)
    ratio = robust.var() / classical.var()
    # sampling error of a ratio of two variances of correlated estimates: ~ 5 % here
    assert ratio == pytest.approx(1 / eff, rel=0.15)
    assert np.mean(robust) == pytest.approx(1.0, abs=4 * robust.std() / math.sqrt(reps))


def _exact_ratio_wn_level1(chi):
    """kappa at Haar level 1 of white noise: W_t = (x_t - x_{t-1}) / 2, rho_1 = -1/2, no other
    lag. LRV = Var chi + 2 cov(rho = -1/2) with the covariance by a Gauss-Hermite product rule."""
    nodes, weights = np.polynomial.hermite_e.hermegauss(200)
    weights = weights / weights.sum()
    z0 = nodes[:, None]
    z1 = -0.5 * z0 + math.sqrt(0.75) * nodes[None, :]
    cov = float(np.sum(np.outer(weights, weights) * chi.chi(z0**2) * chi.chi(z1**2)))
    cov -= chi.consistency**2
    lrv = chi.score_variance + 2 * cov
    classical_lrv = chi.slope**2 / 2 * (1 + 2 * 0.25)  # b_2^2 R_1
    return lrv / classical_lrv


def test_sandwich_ratio_exact_for_white_noise_level_one():
    chi = scale_rho(0.6)
    k = np.arange(1, 12)
    powers = 1 + 2 * 0.25**k
    powers[0] *= 2  # sandwich_ratio takes R_1 as the all-lag sum of sample values (2 R_1)
    exact = _exact_ratio_wn_level1(chi)
    assert sandwich_ratio(chi, powers) == pytest.approx(exact, rel=1e-6)
    assert 1.0 < exact < 1 / 0.6


def test_normal_interval_estimates_the_sandwich_ratio():
    x = np.random.default_rng(3).standard_normal(2**15)
    res = wvar(x, 10.0, robust=True, ci="normal", levels=6)
    assert res.variance_ratio[0] == pytest.approx(_exact_ratio_wn_level1(scale_rho(0.6)), rel=0.05)
    assert np.all(res.variance_ratio > 1.0) and np.all(res.variance_ratio < 1 / 0.6 + 0.05)
    assert np.all((res.ci_low < res.wv) & (res.wv < res.ci_high))


@pytest.mark.slow
def test_clean_gaussian_monte_carlo_efficiency_and_coverage():
    """Clean WN + RW (150 records): the robust WV is unbiased, its variance over the classical one's is
    the sandwich's kappa_j (between 1 and 1/eff), and its intervals cover (chi2: at least
    nominal, the 1/eff bound; normal: near nominal)."""
    rng = np.random.default_rng(2024)
    reps, n, levels, eff = 150, 2**13, 6, 0.6
    sigma2, gamma2 = 1.0, 1e-4
    truth = stochmod.model_from_spec(f"WN(sigma2={sigma2}) + RW(sigma2={gamma2})", 1.0).wv(levels)
    rob, cla, kappa = [], [], []
    hit_chi2 = np.zeros(levels)
    hit_norm = np.zeros(levels)
    for _ in range(reps):
        x = math.sqrt(sigma2) * rng.standard_normal(n) + np.cumsum(
            math.sqrt(gamma2) * rng.standard_normal(n))
        r = wvar(x, 1.0, levels=levels, robust=True, efficiency=eff)
        rn = wvar(x, 1.0, levels=levels, robust=True, efficiency=eff, ci="normal")
        rob.append(r.wv)
        cla.append(wvar(x, 1.0, levels=levels).wv)
        kappa.append(rn.variance_ratio)
        hit_chi2 += (r.ci_low <= truth) & (truth <= r.ci_high)
        hit_norm += (rn.ci_low <= truth) & (truth <= rn.ci_high)
    rob, cla = np.array(rob), np.array(cla)
    se = rob.std(axis=0) / math.sqrt(reps)
    assert np.all(np.abs(rob.mean(axis=0) - truth) < 4 * se)
    ratio = rob.var(axis=0) / cla.var(axis=0)
    assert np.all(ratio < 1 / eff * 1.2) and np.all(ratio > 0.9)
    assert np.allclose(ratio, np.mean(kappa, axis=0), rtol=0.2)
    mc = 3 * math.sqrt(0.05 * 0.95 / reps)
    assert np.all(hit_chi2 / reps > 0.95 - mc)
    assert np.all(np.abs(hit_norm / reps - 0.95) < mc + 0.02)


def _contaminated(rng, n=2**15, share=0.002):
    clean = rng.standard_normal(n) + np.cumsum(0.01 * rng.standard_normal(n))
    x = clean.copy()
    spikes = rng.choice(np.arange(100, n - 100), size=int(share * n), replace=False)
    x[spikes] += rng.choice([-1, 1], spikes.size) * 25.0
    x[20000:20008] += 15.0  # a short burst
    return clean, x, spikes


@pytest.mark.parametrize("rho", ["biweight", "huber"])
def test_outliers_leave_robust_near_truth_and_inflate_classical(rho):
    rng = np.random.default_rng(8)
    clean, x, _ = _contaminated(rng)
    truth = stochmod.model_from_spec("WN(sigma2=1) + RW(sigma2=1e-4)", 1.0).wv(8)
    rob = wvar(x, 1.0, levels=8, robust=True, rho=rho)
    cla = wvar(x, 1.0, levels=8)
    # levels whose filter (2^j samples) meets few spikes (2^j eps <= 5 %): near the truth
    sparse = 2.0 ** np.arange(1, 9) * 0.002 <= 0.05
    assert np.all(np.abs(rob.wv / truth - 1)[sparse] < 0.1)
    assert np.all(cla.wv[:5] / truth[:5] > 1.5)  # spikes of 25 sd at 0.2 %: inflated
    # against the classical WV of the clean record (same sampling error): where a level's
    # filter (2^j samples) meets few spikes (share 2^j eps <= 5 %) the robust one is within
    # 10 %; deeper, each spike touches 2^j coefficients by a few sd only, too dense to reject
    # (docs/robust.md), yet the robust WV stays closer to the clean one than the classical
    clean_cla = wvar(clean, 1.0, levels=8)
    assert np.all(np.abs(rob.wv / clean_cla.wv - 1)[sparse] < 0.1)
    assert np.all(np.abs(rob.wv - clean_cla.wv) < 0.6 * np.abs(cla.wv - clean_cla.wv))


def test_contamination_diagnostic_locates_the_spikes():
    rng = np.random.default_rng(9)
    clean, x, spikes = _contaminated(rng)
    freq = 50.0
    res = wvar(x, freq, levels=8, robust=True)
    diag = res.contamination
    assert diag.expected_share == pytest.approx(2 * stats.norm.sf(res.tuning))
    # level 1: each spike gives two coefficients at ~ 25 / sqrt(2) sd; times in s
    assert diag.share[0] == pytest.approx(2 * spikes.size / (x.size - 1), rel=0.1)
    spike_times = spikes / freq
    assert np.all(np.min(np.abs(diag.worst_time[0][:, None] - spike_times), axis=1) <= 0.5 / freq)
    assert np.all(diag.worst_score[0] > res.tuning)
    assert wvar(clean, freq, levels=8, robust=True).contamination.share.max() < 1e-3
    text = res.summary()
    assert "Robust wavelet variance (biweight, efficiency 0.6" in text and "Contamination" in text
    assert json.loads(json.dumps(res.to_dict()))["contamination"]["share"][0] == diag.share[0]


def test_isolated_patches_are_jumps_away_and_back():
    x = np.zeros(60)
    x[5] += 9.0  # a spike
    x[12:14] -= 9.0  # a two-sample patch
    x[20:] += 9.0  # a step: one jump, nothing to pair
    x[30 : 31 + MAX_PATCH] += 9.0  # a burst longer than MAX_PATCH: left to the levels
    x[45:] += 9.0
    x[47:] += 9.0  # two jumps of the same sign (a staircase): no patch
    w = np.diff(x)
    far = np.flatnonzero(np.abs(w) > 1.0)
    first, length = isolated_patches(far, w[far])
    assert first.tolist() == [5, 12] and length.tolist() == [1, 2]
    y, samples = replace_patches(x, first, length)
    assert samples.tolist() == [5, 12, 13]
    assert np.all(y[:20] == 0.0) and np.array_equal(y[14:], x[14:])
    # a chain up, down, up: one pair, the first two; the straight line between neighbours
    first, length = isolated_patches([3, 4, 5], [1.0, -1.0, 1.0])
    assert first.tolist() == [4] and length.tolist() == [1]
    y, _ = replace_patches(np.array([0.0, 1.0, 2.0, 3.0, 4.0, 50.0, 6.0, 7.0]), [5], [1])
    assert y[5] == 5.0


def test_clean_gaussian_monte_carlo_unbiased_and_nothing_screened():
    """Clean GM + WN (40 records of 2^15 samples at 100 Hz): the screening replaces nothing
    and the robust WV is unbiased against the closed form at the levels with at least 64
    equivalent degrees of freedom (levels 1-8), as the classical one."""
    freq, reps, n, levels = 100.0, 40, 2**15, 8
    truth = stochmod.model_from_spec("GM(beta=0.2, sigma2=2e-5) + WN(sigma2=1e-3)", freq)
    rob, cla = [], []
    for r in range(reps):
        x = truth.simulate(n, rng=np.random.default_rng([33, r]))
        res = robust_wvar(x, freq, levels=levels)
        assert res.contamination.replaced_time.size == 0
        # the same estimate (to rounding: the compiled sums' order follows memory alignment)
        np.testing.assert_allclose(res.wv, robust_wvar(x, freq, levels=levels, screen=False).wv,
                                   rtol=1e-12)
        rob.append(res.wv)
        cla.append(wvar(x, freq, levels=levels).wv)
    rob, cla = np.array(rob) / truth.wv(levels) - 1, np.array(cla) / truth.wv(levels) - 1
    for est in (rob, cla):
        se = est.std(axis=0) / math.sqrt(reps)
        assert np.all(np.abs(est.mean(axis=0)) < 4 * se)


def test_efficiency_one_is_the_classical_estimator():
    x = np.random.default_rng(1).standard_normal(3000)
    a, b = wvar(x, 2.0), wvar(x, 2.0, robust=True, efficiency=1.0)
    assert np.array_equal(a.wv, b.wv) and b.robust and b.efficiency == 1.0
    assert json.loads(json.dumps(b.to_dict(), allow_nan=False))["tuning"] is None


@pytest.mark.parametrize("eff", [0.0, -0.2, 1.5, float("nan"), "high", True, None])
def test_bad_efficiency(eff):
    with pytest.raises(InputError, match="efficiency"):
        wvar(np.random.default_rng(0).standard_normal(100), 1.0, robust=True, efficiency=eff)


def test_bad_input():
    x = np.random.default_rng(0).standard_normal(100)
    with pytest.raises(InputError, match="NaN"):
        wvar(np.r_[x, np.nan], 1.0, robust=True)
    with pytest.raises(InputError, match="at least 4"):
        wvar(x[:3], 1.0, robust=True)
    with pytest.raises(InputError, match="constant"):
        wvar(np.ones(100), 1.0, robust=True)
    with pytest.raises(InputError, match="rho"):
        wvar(x, 1.0, robust=True, rho="cauchy")
    with pytest.raises(InputError, match="ci"):
        wvar(x, 1.0, robust=True, ci="boot")
    steps = np.repeat(np.arange(10.0), 10)  # level-1 coefficients mostly exactly zero
    with pytest.raises(InputError, match="zero"):
        wvar(steps, 1.0, robust=True)


def test_no_root_falls_back_to_the_classical_level():
    """A third of the coefficients zero, the rest equal: mean chi <= chi_max / 3 < delta for
    every v, so the M-estimate does not exist; at a deep random-walk level (few effectively
    independent coefficients) the same happens and the level keeps the classical estimate."""
    from stochmod.empirical.robust_wv import NoRootError

    chi = scale_rho(0.6)
    u = np.linspace(1e-4, chi.c**2, 20001)
    assert chi.chi(u).max() / 3 < chi.consistency
    with pytest.raises(NoRootError):
        m_scale(np.tile([0.0, 0.0, 2.0], 1000), chi)
    x = np.cumsum(np.random.default_rng(18).standard_normal(2**12))
    rob, cla = wvar(x, 1.0, robust=True), wvar(x, 1.0)
    levels = rob.contamination.classical_levels
    assert levels == (10, 11)
    for j in levels:
        assert rob.wv[j - 1] == pytest.approx(cla.wv[j - 1], rel=1e-12)
        assert rob.variance_ratio[j - 1] == 1.0
    assert "no root: classical estimate" in rob.summary()


RECORDING = (Path(__file__).resolve().parents[1].parent / "shared" / "data" / "imudata"
             / "adis_16405_imu1.npz")


@pytest.mark.skipif(not RECORDING.exists(),
                    reason=f"real IMU data not found at {RECORDING} (shared/data is not beside "
                           "the repository)")
def test_real_gyro_without_outliers_agrees_with_classical():
    """ADIS16405 Gyro_X (10^6 samples at 100 Hz), a clean static record: the robust WV
    equals the classical one within 1 % at the first six levels and within its interval at
    levels 7-10, and rejects no more coefficients than a Gaussian record would (x 5)."""
    with np.load(RECORDING) as data:
        x = np.asarray(data["Gyro_X"], dtype=float)
        freq = float(data["freq"])
    rob = wvar(x, freq, robust=True, levels=10)
    cla = wvar(x, freq, levels=10)
    assert np.all(np.abs(rob.wv[:6] / cla.wv[:6] - 1) < 0.01)
    # deeper, where the intervals are wider than the two estimators' 1 % gap (Gyro_X is a
    # little heavier-tailed than Gaussian, kurtosis 0.03 at level 1), within the interval
    assert np.all(((rob.ci_low < cla.wv) & (cla.wv < rob.ci_high))[6:])
    # (clustered: one disturbance rejects ~2^j neighbouring coefficients, hence the margin)
    assert np.all(rob.contamination.share < 5 * rob.contamination.expected_share)


def test_single_precision_power_sums_agree_with_double(monkeypatch):
    """Long levels sum powers in float32 (speed): the estimate moves by < 1e-6 relative,
    far below its sampling error (> 1e-3 here)."""
    from stochmod.empirical import robust_wv

    rng = np.random.default_rng(12)
    w = rng.standard_normal(1 << 18) * 1e-3
    w[::500] *= 40.0
    chi = scale_rho(0.6)
    single = m_scale(w, chi)
    monkeypatch.setattr(robust_wv, "_SINGLE_MIN", 1 << 40)
    double = m_scale(w, chi)
    assert single.variance == pytest.approx(double.variance, rel=1e-6)
    assert single.n_rejected == double.n_rejected
    assert np.array_equal(single.worst, double.worst)
