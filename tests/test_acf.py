"""Sample ACF against statsmodels and the direct sum; the GM fit of Quinchia Section 4.1 on
seeded Gauss-Markov simulations, with its Monte Carlo spread and its caveats."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.signal import lfilter
from statsmodels.tsa.stattools import acf as sm_acf

from stochmod.fit.classical import acf_model
from stochmod.core.errors import EstimationError, InputError
from stochmod.empirical.acf import acf, acovf, fit_gm_acf


def _gm(rng: np.random.Generator, n: int, beta: float, sigma2: float, freq: float) -> np.ndarray:
    """Exact discretised first-order GM: AR(1), phi = exp(-beta/freq), stationary start."""
    phi = math.exp(-beta / freq)
    e = rng.standard_normal(n) * math.sqrt(sigma2 * (1 - phi**2))
    e[0] = rng.standard_normal() * math.sqrt(sigma2)
    return lfilter([1.0], [1.0, -phi], e)


@settings(max_examples=60, deadline=None)
@given(n=st.integers(3, 400), seed=st.integers(0, 2**32 - 1), frac=st.floats(0.0, 1.0))
def test_acf_equals_statsmodels_and_direct_sum(n, seed, frac):
    rng = np.random.default_rng(seed)
    x = rng.standard_normal(n) * rng.uniform(0.1, 10) + rng.uniform(-5, 5)
    max_lag = int(round(frac * (n - 1)))
    ours = acf(x, max_lag)
    np.testing.assert_allclose(ours, sm_acf(x, nlags=max_lag, fft=True), rtol=0, atol=1e-12)
    xc = x - x.mean()
    direct = np.array([np.dot(xc[: n - k], xc[k:]) / n for k in range(max_lag + 1)])
    np.testing.assert_allclose(acovf(x, max_lag), direct, rtol=1e-12, atol=1e-12 * direct[0])


def test_acf_defaults_to_all_lags():
    x = np.random.default_rng(0).standard_normal(50)
    assert acf(x).shape == (50,)
    np.testing.assert_allclose(acf(x), sm_acf(x, nlags=49, fft=True), atol=1e-12)


def test_gm_fit_recovers_tc_with_the_predicted_spread():
    # 100 records of 2000 correlation times: the 1/e reading's Monte Carlo mean is within 4 SE of
    # the true Tc, and its Monte Carlo spread matches the Bartlett-based tc_se.
    freq, beta, sigma2 = 100.0, 10.0, 3.0  # Tc = 0.1 s = 10 samples
    rng = np.random.default_rng(7)
    fits = [fit_gm_acf(_gm(rng, 20_000, beta, sigma2, freq), freq, max_lag=200) for _ in range(100)]
    tc = np.array([f.tc for f in fits])
    se = np.mean([f.tc_se for f in fits])
    assert abs(tc.mean() - 0.1) < 4 * tc.std(ddof=1) / math.sqrt(tc.size)
    assert 0.75 < tc.std(ddof=1) / se < 1.33
    beta_ls = np.array([f.beta_ls for f in fits])
    se_mean = beta_ls.std(ddof=1) / math.sqrt(beta_ls.size)
    assert abs(beta_ls.mean() - beta) < 4 * se_mean + 0.01 * beta
    s2 = np.array([f.sigma2 for f in fits])
    assert abs(s2.mean() - sigma2) < 4 * s2.std(ddof=1) / math.sqrt(s2.size)
    assert 0.75 < s2.std(ddof=1) / np.mean([f.sigma2_se for f in fits]) < 1.33
    assert all(f.caveats == () for f in fits)


def test_zero_lag_sigma2_and_ls_amplitude_without_white_noise():
    freq = 50.0
    rng = np.random.default_rng(3)
    gm = _gm(rng, 100_000, 2.0, 1.0, freq)
    wn = rng.standard_normal(gm.size) * 0.7
    fit = fit_gm_acf(gm + wn, freq)
    # sigma2 is the zero-lag value (variance of the record); the LS amplitude excludes the WN
    assert fit.sigma2 == pytest.approx(np.var(gm + wn), rel=1e-12)
    assert fit.sigma2_ls == pytest.approx(1.0, rel=0.15)
    assert fit.beta_ls == pytest.approx(2.0, rel=0.15)


def test_caveat_on_short_record():
    freq = 10.0
    fit = fit_gm_acf(_gm(np.random.default_rng(1), 300, 0.2, 1.0, freq), freq)  # 6 Tc
    assert any("Tc long" in c for c in fit.caveats)


def test_caveat_on_record_shorter_than_200_tc():
    freq = 10.0
    fit = fit_gm_acf(_gm(np.random.default_rng(2), 5000, 0.2, 1.0, freq), freq)  # 100 Tc
    assert any("biased low" in c for c in fit.caveats)


def test_caveats_on_random_walk():
    rw = np.cumsum(np.random.default_rng(4).standard_normal(20_000))
    fit = fit_gm_acf(rw, 100.0)
    assert fit.caveats
    assert any("Tc long" in c or "never drops" in c for c in fit.caveats)


def test_caveat_when_white_noise_dominates():
    fit = fit_gm_acf(np.random.default_rng(5).standard_normal(10_000), 100.0)
    assert any("within one lag" in c for c in fit.caveats)


def test_never_reaching_one_over_e_gives_nan_and_refuses_a_model():
    rw = np.cumsum(np.random.default_rng(6).standard_normal(5000))
    fit = fit_gm_acf(rw, 1.0, max_lag=10)
    assert math.isnan(fit.tc) and math.isnan(fit.beta)
    assert any("never drops below 1/e" in c for c in fit.caveats)
    with pytest.raises(EstimationError, match="no usable exponential decay"):
        fit.coefficient_values()
    with pytest.raises(EstimationError, match="never drops below 1/e"):
        acf_model(fit)


def test_spec_and_model():
    freq = 100.0
    fit = fit_gm_acf(_gm(np.random.default_rng(8), 50_000, 5.0, 2.0, freq), freq)
    assert fit.coefficient_values() == {"rate": fit.beta, "variance": fit.sigma2}
    model = acf_model(fit)
    gm = {"family": "GM", "params": {"beta": fit.beta, "sigma2": fit.sigma2}}
    assert model.freq == freq and model.to_spec()["processes"] == [gm]
    assert acf_model(fit, use_ls=True).processes[0].beta == fit.beta_ls
    # the model's autocorrelation falls to 1/e at the fitted Tc, and the fit is near the truth
    rho = model.processes[0].autocovariance(fit.tc * freq, freq) / fit.sigma2
    assert rho == pytest.approx(math.exp(-1.0), rel=1e-12)
    assert fit.beta == pytest.approx(5.0, rel=0.1) and fit.sigma2 == pytest.approx(2.0, rel=0.1)
    assert "Tc (1/e crossing)" in fit.summary()


@pytest.mark.parametrize(
    "x, kwargs, match",
    [
        ([1.0, np.nan, 2.0, 3.0], {}, "non-finite"),
        (np.ones(100), {}, "constant"),
        (np.arange(10.0), {"max_lag": 10}, "max_lag"),
        (np.zeros((3, 3)), {}, "one-dimensional"),
    ],
)
def test_bad_input(x, kwargs, match):
    with pytest.raises(InputError, match=match):
        fit_gm_acf(x, 1.0, **kwargs)


def test_bad_freq_and_acf_input():
    with pytest.raises(InputError, match="freq"):
        fit_gm_acf(np.arange(10.0), -1.0)
    with pytest.raises(InputError, match="constant"):
        acf(np.full(5, 2.0))
    with pytest.raises(InputError, match="empty"):
        acf([])
