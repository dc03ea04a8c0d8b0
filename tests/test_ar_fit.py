"""Burg and Yule-Walker against statsmodels; AR recovery within Monte Carlo error on seeded
simulations; order selection; stationarity checks against roots built by hand."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.signal import lfilter
from statsmodels.regression.linear_model import burg as sm_burg
from statsmodels.regression.linear_model import yule_walker as sm_yule_walker
from statsmodels.tsa.stattools import pacf_burg

from stochmod.fit.classical import ar_model
from stochmod.core.errors import EstimationError, InputError
from stochmod.empirical.ar_fit import (
    ar_roots_modulus,
    burg,
    check_stationary,
    fit_ar,
    yule_walker,
)


def _ar(rng: np.random.Generator, phi: list[float], n: int, sigma2: float = 1.0, burn: int = 2000):
    e = rng.standard_normal(n + burn) * math.sqrt(sigma2)
    return lfilter([1.0], np.concatenate([[1.0], -np.asarray(phi)]), e)[burn:]


def _sm_yw(x, order, method):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rho, sigma = sm_yule_walker(x, order, method=method)[:2]
    return rho, sigma


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(12, 600), order=st.integers(1, 8),
       demean=st.booleans())
def test_burg_equals_statsmodels(seed, n, order, demean):
    rng = np.random.default_rng(seed)
    x = _ar(rng, [0.6, -0.3], n, burn=50) + rng.uniform(-3, 3)
    phi, s2 = burg(x, order, demean=demean)
    ref_phi, ref_s2 = sm_burg(x, order, demean=demean)
    np.testing.assert_allclose(phi, ref_phi, rtol=0, atol=1e-8)
    assert s2 == pytest.approx(ref_s2, rel=1e-8)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(12, 600), order=st.integers(1, 8),
       method=st.sampled_from(["mle", "adjusted"]), demean=st.booleans())
def test_yule_walker_equals_statsmodels(seed, n, order, method, demean):
    rng = np.random.default_rng(seed)
    x = _ar(rng, [0.5, 0.2], n, burn=50) + rng.uniform(-3, 3)
    phi, s2 = yule_walker(x, order, method=method, demean=demean)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref_phi, ref_sigma = sm_yule_walker(x, order, method=method, demean=demean)[:2]
    np.testing.assert_allclose(phi, ref_phi, rtol=0, atol=1e-8)
    if np.isfinite(ref_sigma):
        assert s2 == pytest.approx(ref_sigma**2, rel=1e-8)


def test_burg_path_variances_equal_statsmodels_pacf_burg():
    x = _ar(np.random.default_rng(1), [0.5, -0.2, 0.1], 3000)
    fit = fit_ar(x, 100.0, 6)
    ref = pacf_burg(x, 6, demean=True)
    np.testing.assert_allclose(fit.sigma2_path, ref.sigma2[1:], rtol=1e-10)


def test_information_criteria_from_independent_fits():
    # each order's criterion from a separate burg() call: n log sigma2 + 2m (AIC), + m log n (BIC)
    x = _ar(np.random.default_rng(2), [0.4, 0.3], 2000)
    fit = fit_ar(x, 10.0, max_order=5)
    n = x.size
    for m in range(1, 6):
        s2 = burg(x, m)[1]
        assert fit.aic[m - 1] == pytest.approx(n * math.log(s2) + 2 * m, rel=1e-12)
        assert fit.bic[m - 1] == pytest.approx(n * math.log(s2) + m * math.log(n), rel=1e-12)


def test_ar1_recovery_and_asymptotic_standard_error():
    # asymptotic SE of phi_hat for AR(1): sqrt((1 - phi^2) / N)
    phi, n = 0.9, 40_000
    x = _ar(np.random.default_rng(3), [phi], n)
    fit = fit_ar(x, 100.0, 1)
    se = math.sqrt((1 - phi**2) / n)
    assert abs(fit.phi[0] - phi) < 4 * se
    assert fit.phi_se[0] == pytest.approx(se, rel=0.05)
    assert fit.alpha[0] == -fit.phi[0]  # Quinchia eq. 9 sign convention


@pytest.mark.parametrize("method", ["burg", "yw", "yw-adjusted"])
@pytest.mark.parametrize("phi", [[1.2, -0.5], [0.5, -0.3, 0.4]])
def test_recovers_ar2_ar3_within_monte_carlo_error(method, phi):
    n = 30_000
    x = _ar(np.random.default_rng(4), phi, n, sigma2=2.0)
    fit = fit_ar(x, 50.0, len(phi), method=method)
    assert np.all(np.abs(fit.phi - phi) < 4 * fit.phi_se)
    # sigma2_hat - sigma2 ~ N(0, 2 sigma2^2 / n)
    assert abs(fit.sigma2 - 2.0) < 4 * 2.0 * math.sqrt(2 / n)


def test_order_selection_picks_three_on_a_clear_ar3():
    x = _ar(np.random.default_rng(5), [0.5, -0.3, 0.4], 20_000)
    for criterion in ("bic", "aic"):
        fit = fit_ar(x, 100.0, max_order=8, criterion=criterion)
        assert fit.order == 3 and fit.phi.size == 3
    assert fit_ar(x, 100.0, max_order=8).orders.tolist() == list(range(1, 9))


@settings(max_examples=60, deadline=None)
@given(roots=st.lists(st.tuples(st.floats(0.05, 3.0), st.floats(0.0, math.pi)),
                     min_size=1, max_size=3))
def test_root_modulus_against_roots_built_by_hand(roots):
    # characteristic roots lambda (real, or conjugate pairs away from the real axis) -> phi
    lam = []
    for r, theta in roots:
        if theta < 0.3 or theta > math.pi - 0.3:
            lam.append(r if theta < 0.3 else -r)
        else:
            lam.extend([r * np.exp(1j * theta), r * np.exp(-1j * theta)])
    # well-separated roots keep np.roots accurate (repeated roots lose digits: eps^(1/mult))
    assume(all(abs(a - b) > 0.1 for i, a in enumerate(lam) for b in lam[i + 1 :]))
    coeffs = np.real(np.poly(lam))
    phi = -coeffs[1:]
    expected = max(abs(v) for v in lam)
    assert ar_roots_modulus(phi) == pytest.approx(expected, rel=1e-6)
    if expected < 0.999:
        assert check_stationary(phi) == pytest.approx(expected, rel=1e-6)
    elif expected > 1.001:
        with pytest.raises(EstimationError, match="not stationary"):
            check_stationary(phi)


def test_unstable_yule_walker_adjusted_raises_naming_the_modulus():
    # short data where the n-k denominators make the Yule-Walker AR(1) explosive
    x = [0.4, -2.1, 1.7, -1.9, 0.4]
    phi, _ = yule_walker(x, 1, method="adjusted")
    assert abs(phi[0]) > 1
    with pytest.raises(EstimationError, match=f"modulus {abs(phi[0]):.6g}"):
        fit_ar(x, 1.0, 1, method="yw-adjusted")
    # Burg on the same data is stationary
    assert fit_ar(x, 1.0, 1).max_root_modulus < 1


def test_summary_dict_and_spec():
    x = _ar(np.random.default_rng(6), [0.7], 5000)
    fit = fit_ar(x, 100.0, 1)
    assert "AR(1) by burg" in fit.summary()
    d = fit.to_dict()
    assert d["order"] == 1 and d["phi"] == fit.phi.tolist()
    assert fit.coefficient_values() == {"ar": (fit.phi[0],), "innovation": fit.sigma2}
    model = ar_model(fit)
    ar = {"family": "AR", "params": {"phi": [fit.phi[0]], "sigma2": fit.sigma2}, "order": 1}
    assert model.freq == 100.0 and model.to_spec()["processes"] == [ar]
    # the model's lag-1 autocorrelation is the fitted phi (AR(1)), near the simulated 0.7
    p = model.processes[0]
    assert p.autocovariance(1, 100.0) / p.autocovariance(0, 100.0) == pytest.approx(fit.phi[0], rel=1e-12)
    assert fit.phi[0] == pytest.approx(0.7, abs=0.03)


@pytest.mark.parametrize(
    "args, kwargs, exc, match",
    [
        ((np.arange(10.0), 1.0, 0), {}, InputError, "order"),
        ((np.arange(5.0), 1.0, 4), {}, InputError, "at least 6"),
        ((np.arange(50.0), 1.0, 2), {"method": "ols"}, InputError, "method"),
        ((np.arange(50.0), 1.0, 2), {"criterion": "hqic"}, InputError, "criterion"),
        ((np.ones(50), 1.0, 2), {}, InputError, "constant"),
        ((np.r_[np.arange(5.0), np.inf], 1.0, 1), {}, InputError, "non-finite"),
        ((np.arange(50.0), 0.0, 1), {}, InputError, "freq"),
    ],
)
def test_bad_input(args, kwargs, exc, match):
    with pytest.raises(exc, match=match):
        fit_ar(*args, **kwargs)


def test_bad_input_of_the_plain_estimators():
    with pytest.raises(InputError, match="method"):
        yule_walker(np.arange(10.0), 1, method="unbiased")
    with pytest.raises(InputError, match="order"):
        burg(np.arange(10.0), 1.5)
