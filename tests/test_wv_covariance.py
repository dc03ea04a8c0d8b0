"""Asymptotic covariance of the empirical WV (eq. 17) by FFT, against a direct sum and Monte Carlo."""

import numpy as np
import pytest

from stochmod.core.errors import InputError
from stochmod.core.filters import filter_width
from stochmod.empirical.modwt import modwt_coefficients
from stochmod.empirical.wavelet_variance import wvar
from stochmod.empirical.wv_covariance import wv_covariance


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


# ----------------------------------------------------------------- covariance under a model
from stochmod import model_from_spec  # noqa: E402
from stochmod.fit.weighting import (  # noqa: E402
    chi2_variance,
    decoupled_covariance,
    equivalent_dof,
    model_covariance,
)
from stochmod.core.theory import wv_covariance_from_psd  # noqa: E402

EXACT_N, EXACT_J = 1024, 6


def _exact_gaussian_covariance(cov_x: np.ndarray, levels: int) -> np.ndarray:
    """Finite-sample covariance of the unbiased MODWT WVs of a Gaussian vector with covariance
    `cov_x`: each WV is ``x' H_j' H_j x / M_j``, so ``cov = 2 ||H_j S H_k'||_F^2 / (M_j M_k)``
    (independent of the frequency-domain formula)."""
    n = cov_x.shape[0]
    H = [np.array([modwt_coefficients(e, j) for e in np.eye(n)]).T for j in range(1, levels + 1)]
    return np.array([[2.0 * np.sum((a @ cov_x @ b.T) ** 2) / (a.shape[0] * b.shape[0]) for b in H]
                     for a in H])


@pytest.mark.parametrize("spec", ["GM(beta=20.0, sigma2=1.0) + WN(sigma2=0.5)",
                                  "WN(sigma2=1.0) + RW(sigma2=0.01)",
                                  "AR(phi=[1.5, -0.75], sigma2=1.0)"])
def test_model_covariance_matches_exact_quadratic_forms(spec):
    """The large-sample formula against the exact covariance of N = 1024 samples: off by the
    boundary terms, O(2^j / M_j), and the quadrature's 1e-3."""
    model = model_from_spec(spec, 100.0)
    t = np.arange(EXACT_N)
    if "RW" in spec:  # x_t = walk from 0 (increments 0.01) + white noise
        cov_x = 0.01 * np.minimum.outer(t + 1, t + 1) + np.eye(EXACT_N)
    else:
        cov_x = model.autocovariance(np.abs(np.subtract.outer(t, t)))
    exact = _exact_gaussian_covariance(cov_x, EXACT_J)
    n_coef = EXACT_N - 2 ** np.arange(1, EXACT_J + 1) + 1
    got = model_covariance(model, n_coef)
    deeper = np.maximum.outer(np.arange(1, EXACT_J + 1), np.arange(1, EXACT_J + 1))
    tol = 0.5 * 2.0**deeper / np.minimum.outer(n_coef, n_coef) + 5e-3
    assert np.all(np.abs(got / exact - 1) <= tol), got / exact - 1
    np.testing.assert_array_equal(got, got.T)


def test_haar_fast_path_agrees_with_the_lobe_by_lobe_quadrature():
    model = model_from_spec("GM(beta=2.0, sigma2=1e-6) + GM(beta=0.02, sigma2=1e-7) + WN(sigma2=3e-6)", 100.0)
    n_coef = 2**16 - 2 ** np.arange(1, 13) + 1
    fast = wv_covariance_from_psd(model.psd, n_coef, 100.0)
    slow = wv_covariance_from_psd(model.psd, n_coef, 100.0, wavelet="db1")  # = Haar, generic path
    np.testing.assert_allclose(fast, slow, rtol=5e-3)


def test_random_ramp_adds_its_chi2_slope_covariance():
    """One slope per record: the RR part of the covariance is 2 wv wv' whatever N; checked
    against the sample covariance of simulated records at the deep levels RR dominates."""
    model = model_from_spec("RR(omega=1e-3) + WN(sigma2=1.0)", 1.0)
    n, J = 4096, 10
    sims = np.array([wvar(model.simulate(n, np.random.default_rng([4, r])), 1.0, levels=J).wv
                     for r in range(3000)])
    got = model_covariance(model, n - 2 ** np.arange(1, J + 1) + 1)
    rr = model.processes[0].wv(J, 1.0)
    np.testing.assert_allclose(got[-3:, -3:], np.cov(sims, rowvar=False)[-3:, -3:], rtol=0.15)
    assert got[-1, -1] >= 2 * rr[-1] ** 2


def test_decoupled_covariance_keeps_the_well_estimated_block():
    rng = np.random.default_rng(0)
    J = 8
    A = rng.normal(size=(J, J))
    V = A @ A.T
    wv = np.linspace(1.0, 2.0, J)
    level = np.arange(1, J + 1)
    n_coef = 1000 - 2**level + 1  # EDF 500 ... 3.9: the last level has fewer than 4
    chi2 = chi2_variance(wv, n_coef, level)
    assert int(np.sum(equivalent_dof(n_coef, level) >= 4.0)) == 7
    out = decoupled_covariance(V, wv, n_coef, level)
    np.testing.assert_array_equal(out[:7, :7], V[:7, :7])
    assert out[7, 7] == chi2[7] and np.all(out[7, :7] == 0) and np.all(out[:7, 7] == 0)
    # a covariance that makes the coupled block indefinite: its deepest level goes too
    V[5, 6] = V[6, 5] = 10 * np.sqrt(V[5, 5] * V[6, 6])
    out = decoupled_covariance(V, wv, n_coef, level)
    np.testing.assert_array_equal(out[:6, :6], V[:6, :6])
    np.testing.assert_array_equal(np.diag(out)[6:], chi2[6:])
    assert np.all(out[6:, :6] == 0)
    assert np.all(np.linalg.eigvalsh(out) > 0)


@pytest.mark.parametrize("unit", [1e-30, 1e25])
def test_any_unit_scales_as_its_fourth_power(unit):
    """Covariance is unit^4: the single-precision transforms must not under/overflow."""
    x = np.random.default_rng(8).normal(size=1500).cumsum()
    V = wv_covariance(x, 6)
    assert V == pytest.approx(direct_eq17(x, 6), rel=2e-5)
    np.testing.assert_allclose(wv_covariance(unit * x, 6) / unit**4, V, rtol=1e-5)


def test_default_levels_and_more_than_the_data_allow():
    x = np.random.default_rng(9).normal(size=1000)
    assert wv_covariance(x).shape == (8, 8)  # floor(log2 1000) - 1
    with pytest.raises(InputError, match="levels=10"):
        wv_covariance(x, 10)


@pytest.mark.parametrize("workers", [2, 3])
def test_threads_give_the_serial_digits_and_the_direct_sum(workers):
    """The threaded pipeline (transforms on a pool, Gram in fixed parts) changes no digit, with
    more levels than buffers so that every buffer is reused, and clipping on."""
    x = np.random.default_rng(11).standard_t(3, size=1500)
    serial = wv_covariance(x, 7, workers=1)
    assert np.array_equal(wv_covariance(x, 7, workers=workers), serial)
    assert serial == pytest.approx(direct_eq17(x, 7), rel=2e-5)
    bounds = 2.0 * np.sqrt(wvar(x, 1.0, levels=7).wv)
    assert np.array_equal(wv_covariance(x, 7, clip=bounds, workers=workers),
                          wv_covariance(x, 7, clip=bounds, workers=1))


def test_threads_default_from_the_environment(monkeypatch):
    from stochmod.empirical.wv_covariance import THREADS_VARIABLE, default_workers

    monkeypatch.setenv(THREADS_VARIABLE, "1")
    assert default_workers() == 1
    monkeypatch.setenv(THREADS_VARIABLE, "3")
    assert default_workers() == 3
    for bad in ("0", "two", "-1"):
        monkeypatch.setenv(THREADS_VARIABLE, bad)
        with pytest.raises(InputError, match=THREADS_VARIABLE):
            wv_covariance(np.arange(64.0), 2)
    with pytest.raises(InputError, match="workers"):
        wv_covariance(np.arange(64.0), 2, workers=0)


def test_power_spectrum_path_gives_the_direct_sum():
    """The compiled split of the complex transform of sample pairs
    (:mod:`stochmod.empirical.spectrum_jit`) against the direct double-precision sum."""
    x = np.random.default_rng(5).normal(size=913)
    assert wv_covariance(x, 6) == pytest.approx(direct_eq17(x, 6), rel=2e-5)
