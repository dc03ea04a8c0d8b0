"""Asymptotic covariance of the empirical WV (eq. 17) by FFT, against a direct sum and Monte Carlo."""

import numpy as np
import pytest

from stochmod.errors import InputError
from stochmod.signal.modwt import filter_width, modwt_coefficients
from stochmod.signal.wavelet_variance import wvar
from stochmod.signal.wv_covariance import wv_covariance


def direct_eq17(x, levels):
    """Eq. 17 by its definition: sums over all lags of squared cross-covariances on the common
    interior indices, divided by M (independent O(N^2) code)."""
    n = x.size
    series = {}
    for j in range(1, levels + 1):
        w = np.zeros(n)
        start = filter_width(j) - 1
        w[start:] = modwt_coefficients(x, j)
        series[j] = (w, n - start)
    V = np.zeros((levels, levels))
    for a in range(1, levels + 1):
        for b in range(1, levels + 1):
            wa, ma = series[a]
            wb, mb = series[b]
            M = min(ma, mb)
            c = np.correlate(wb, wa, mode="full") / M  # all lags, both directions
            V[a - 1, b - 1] = np.sum(c * c) / M
    return V


def test_fft_equals_the_direct_sum():
    x = np.random.default_rng(3).normal(size=777)
    V = wv_covariance(x, 5)
    assert V == pytest.approx(direct_eq17(x, 5), rel=2e-5)  # single-precision FFTs
    assert np.allclose(V, V.T)


def test_white_noise_variance_matches_monte_carlo_and_closed_form():
    rng = np.random.default_rng(0)
    n, J = 4096, 4
    V = np.mean([wv_covariance(rng.normal(size=n), J) for _ in range(50)], axis=0)
    sims = np.array([wvar(rng.normal(size=n), 1.0, levels=J).wv for _ in range(1500)])
    C = np.cov(sims, rowvar=False)
    # closed form at level 1: W = (x_t - x_{t-1})/2, Var(mean W^2) ~ 3 sigma^4 / (4 M)
    assert np.diag(V)[0] == pytest.approx(3 / (4 * (n - 1)), rel=0.1)
    assert np.diag(V) == pytest.approx(np.diag(C), rel=0.2)
    assert V[0, 1] == pytest.approx(C[0, 1], rel=0.3)


def test_bad_input():
    with pytest.raises(InputError):
        wv_covariance(np.array([1.0, np.nan, 2.0]))
    with pytest.raises(InputError):
        wv_covariance(np.zeros(16), 10)
