"""ARMA(p, q) mean models by conditional Gaussian ML with AIC orders (Waegli et al. 2010, eqs. 10-11).

Truth: seeded simulations (scipy's lfilter of Gaussian innovations) from the seed's Table 1
ARMA(2,2) coefficients; statsmodels' exact-likelihood ARIMA on the same data (peer); the
innovations recomputed by a plain loop over eq. 10.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import lfilter

import stochmod
from stochmod.core.errors import EstimationError, InputError
from stochmod.fit.arma import arma_innovations, fit_arma, select_arma

TABLE1_AR = (1.666, -0.671)
TABLE1_MA = (-1.086, 0.160)


def simulate_arma(n: int, nu: float, ar: tuple, ma: tuple, sigma: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    e = sigma * rng.standard_normal(n + 3000)
    mean = nu / (1 - sum(ar))
    return mean + lfilter(np.r_[1.0, ma], np.r_[1.0, -np.asarray(ar)], e)[3000:]


def test_table1_arma22_recovered_within_standard_errors() -> None:
    truth = np.array([0.0, *TABLE1_AR, *TABLE1_MA])
    x = simulate_arma(200_000, 0.0, TABLE1_AR, TABLE1_MA, 2e-3, seed=1)
    fit = fit_arma(x, 2, 2)
    assert fit.converged
    z = (fit.params - truth) / fit.std_errors
    assert np.all(np.abs(z) < 4), (fit.params, fit.std_errors)
    assert fit.sigma2 == pytest.approx(4e-6, rel=0.01)
    assert "ar1" in fit.summary() and "t-value" in fit.summary()


@pytest.mark.slow
def test_standard_errors_match_the_monte_carlo_spread() -> None:
    fits = [fit_arma(simulate_arma(4000, 0.5, (0.6,), (0.3,), 1.0, seed=50 + r), 1, 1) for r in range(40)]
    est = np.array([f.params for f in fits])
    se = np.median([f.std_errors for f in fits], axis=0)
    truth = np.array([0.5, 0.6, 0.3])
    sd = est.std(axis=0, ddof=1)
    assert np.all(np.abs(est.mean(axis=0) - truth) < 4 * sd / np.sqrt(len(fits)) + 0.01)
    assert np.all((se / sd > 0.7) & (se / sd < 1.4)), se / sd


@pytest.mark.slow
def test_agrees_with_statsmodels_exact_likelihood() -> None:
    arima = pytest.importorskip("statsmodels.tsa.arima.model", reason="statsmodels is the peer")
    x = simulate_arma(3_000, 0.2, (0.7, -0.2), (0.4,), 1.0, seed=3)
    ours = fit_arma(x, 2, 1)
    peer = arima.ARIMA(x, order=(2, 0, 1), trend="c").fit()
    # statsmodels reports the mean, not the constant nu: nu = mean (1 - sum ar)
    peer_ar, peer_ma = peer.arparams, peer.maparams
    peer_nu = peer.params[0] * (1 - peer_ar.sum())
    peer_params = np.r_[peer_nu, peer_ar, peer_ma]
    # conditional and exact likelihoods differ by O(1/N): far less than a standard error
    assert np.all(np.abs(ours.params - peer_params) < 0.15 * ours.std_errors)
    np.testing.assert_allclose(ours.std_errors[1:], peer.bse[1:4], rtol=0.05)


def test_aic_chooses_the_true_order() -> None:
    x = simulate_arma(20_000, 0.0, (0.8,), (0.5,), 1.0, seed=21)
    best = select_arma(x, max_p=2, max_q=2)
    assert best.order == (1, 1)
    # it is the minimum of the AICs of every order fitted on the same samples
    aics = {(p, q): fit_arma(x[2 - p :], p, q).aic for p in range(3) for q in range(3)}
    assert min(aics, key=aics.get) == (1, 1)
    assert best.aic == pytest.approx(aics[(1, 1)], rel=1e-12)


def test_innovations_match_a_plain_loop() -> None:
    x = simulate_arma(500, 0.1, (0.5, 0.2), (0.3, -0.2), 1.0, seed=8)
    nu, ar, ma = 0.1, [0.5, 0.2], [0.3, -0.2]
    e = np.zeros(x.size)
    for t in range(2, x.size):
        e[t] = x[t] - nu - ar[0] * x[t - 1] - ar[1] * x[t - 2] - ma[0] * e[t - 1] - ma[1] * e[t - 2]
    np.testing.assert_allclose(arma_innovations(x, nu, ar, ma), e[2:], rtol=1e-12, atol=1e-12)


def test_bad_input() -> None:
    x = np.random.default_rng(0).standard_normal(1000)
    with pytest.raises(InputError, match="NaN"):
        fit_arma(np.where(np.arange(1000) == 3, np.nan, x))
    with pytest.raises(InputError, match="constant"):
        fit_arma(np.ones(1000))
    with pytest.raises(InputError, match="at least"):
        fit_arma(x[:40], 2, 2)
    with pytest.raises(EstimationError, match="non-stationary"):
        fit_arma(np.cumsum(np.cumsum(x)), 1, 0)
