"""GARCH(p, q) by Gaussian maximum likelihood and Engle's LM test (Waegli et al. 2010, eqs. 7-9).

Truth: seeded simulations from known parameters (written here as a plain loop over eq. 7,
independent of the lfilter recursion), the MLE property ``loglik(estimate) >= loglik(truth)``,
the Table 2 scale of the seed, a Monte Carlo of the standard errors, the arch package's fit on
the same data (peer), and the LM statistic recomputed with numpy's lstsq and statsmodels.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import stochmod
from stochmod.core.errors import InputError
from stochmod.fit.arch_lm import arch_lm_test
from stochmod.fit.garch import backcast, fit_garch, garch_loglikelihood, garch_variance, select_garch


def simulate_garch(n: int, omega: float, alpha: list[float], beta: list[float], seed: int,
                   burn: int = 5000) -> np.ndarray:
    """Eq. 7 by a plain loop, started at the unconditional variance."""
    rng = np.random.default_rng(seed)
    z = rng.standard_normal(n + burn)
    p, q = len(alpha), len(beta)
    s2u = omega / (1 - sum(alpha) - sum(beta))
    x2 = [s2u] * p
    s2 = [s2u] * q
    out = np.empty(n + burn)
    for t in range(n + burn):
        v = omega + sum(a * x2[-i] for i, a in enumerate(alpha, 1)) + sum(b * s2[-j] for j, b in enumerate(beta, 1))
        out[t] = math.sqrt(v) * z[t]
        x2.append(out[t] ** 2)
        s2.append(v)
        x2, s2 = x2[-max(p, 1):], s2[-max(q, 1):]
    return out[burn:]


def loop_variance(x: np.ndarray, omega: float, alpha: list[float], beta: list[float]) -> np.ndarray:
    """sigma_t^2 of eq. 7 with the arch-style backcast, by a plain loop (the reference)."""
    tau = min(75, x.size)
    w = 0.94 ** np.arange(tau)
    bc = float(np.sum(w / w.sum() * x[:tau] ** 2))
    s2 = np.empty(x.size)
    for t in range(x.size):
        v = omega
        for i, a in enumerate(alpha, 1):
            v += a * (x[t - i] ** 2 if t - i >= 0 else bc)
        for j, b in enumerate(beta, 1):
            v += b * (s2[t - j] if t - j >= 0 else bc)
        s2[t] = v
    return s2


@settings(max_examples=30, deadline=None)
@given(p=st.integers(1, 3), q=st.integers(0, 3), seed=st.integers(0, 2**16),
       scale=st.floats(-6, 2).map(lambda e: 10.0**e))
def test_variance_recursion_matches_a_plain_loop(p: int, q: int, seed: int, scale: float) -> None:
    rng = np.random.default_rng(seed)
    shares = rng.dirichlet(np.ones(p + q + 1)) * 0.999
    alpha, beta = list(shares[:p]), list(shares[p : p + q])
    x = scale * rng.standard_normal(300)
    omega = 0.1 * scale**2
    np.testing.assert_allclose(garch_variance(x, omega, alpha, beta),
                               loop_variance(x, omega, alpha, beta), rtol=1e-12)


def test_score_and_information_against_finite_differences() -> None:
    from stochmod.fit.garch import _Likelihood

    x = simulate_garch(3000, 0.05, [0.1, 0.05], [0.7], seed=4)
    y = x / np.sqrt(np.mean(x * x))
    lik = _Likelihood(y, 2, 1)
    theta = np.array([0.08, 0.12, 0.04, 0.72])
    _, score, info, _ = lik.full(theta)
    h = 1e-6
    numeric = np.array([(lik.value(theta + h * e) - lik.value(theta - h * e)) / (2 * h)
                        for e in np.eye(4)])
    np.testing.assert_allclose(score, numeric, rtol=1e-6, atol=1e-6)
    # expected information: the mean of the outer products of per-sample scores agrees with it
    # only in expectation; here check symmetry and positive definiteness, and the identity
    # info = 1/2 sum (ds2/s2)(ds2/s2)^T against the outer product of numerical ds2
    assert np.allclose(info, info.T) and np.all(np.linalg.eigvalsh(info) > 0)

    def s2(th: np.ndarray) -> np.ndarray:
        return lik.variance(th)[1]

    ds2 = np.array([(s2(theta + h * e) - s2(theta - h * e)) / (2 * h) for e in np.eye(4)])
    scaled = ds2 / s2(theta)
    np.testing.assert_allclose(info, 0.5 * scaled @ scaled.T, rtol=1e-6)



@pytest.mark.parametrize("p, q, theta", [(2, 1, [0.08, 0.12, 0.04, 0.72]), (1, 2, [0.08, 0.12, 0.4, 0.3]),
                                         (2, 0, [0.5, 0.2, 0.1])])
def test_observed_information_and_its_z_form_against_finite_differences(p, q, theta) -> None:
    """The Newton matrix: -d(score)/d(theta) by central differences, and its form in the
    unconstrained coordinates z against differences of the z-gradient."""
    from stochmod.fit.garch import _curvature, _from_theta, _Likelihood, _theta_jacobian, _to_theta

    x = simulate_garch(3000, 0.05, [0.1, 0.05], [0.7], seed=4)
    lik = _Likelihood(x / np.sqrt(np.mean(x * x)), p, q)
    theta = np.array(theta)
    _, score, _, _, observed = lik.terms(theta, hessian=True)
    h = 1e-6
    numeric = np.array([(lik.full(theta + h * e)[1] - lik.full(theta - h * e)[1]) / (2 * h)
                        for e in np.eye(theta.size)])
    np.testing.assert_allclose(observed, -numeric, rtol=1e-6, atol=1e-6 * np.abs(observed).max())
    z = _from_theta(theta)
    in_z = _theta_jacobian(z, theta).T @ observed @ _theta_jacobian(z, theta) - _curvature(theta, score)

    def grad_z(zz: np.ndarray) -> np.ndarray:
        th = _to_theta(zz)
        return _theta_jacobian(zz, th).T @ lik.full(th)[1]

    numeric_z = np.array([(grad_z(z + h * e) - grad_z(z - h * e)) / (2 * h) for e in np.eye(z.size)])
    np.testing.assert_allclose(in_z, -numeric_z, rtol=1e-5, atol=1e-6 * np.abs(in_z).max())


def test_table2_scale_persistent_garch_is_recovered() -> None:
    """Seed Table 2: alpha0 1.3e-7, alpha1 0.0175, beta1 0.98 at N = 300,000, data as given."""
    truth = (1.3e-7, 0.0175, 0.98)
    x = simulate_garch(300_000, truth[0], [truth[1]], [truth[2]], seed=2010)
    fit = stochmod.fit_garch(x, 1, 1)
    assert fit.converged
    assert type(fit.omega) is float and fit.omega == fit.params[0]  # a scalar is a float
    est = fit.params
    z = (est - np.array(truth)) / fit.std_errors
    assert np.all(np.abs(z) < 4), (est, fit.std_errors)
    # the MLE is at least as likely as the truth (the truth is a feasible point)
    ll_truth = garch_loglikelihood(x, truth[0], [truth[1]], [truth[2]])
    assert fit.loglikelihood >= ll_truth - 1e-6
    # conditional variances are the recursion's at the estimate, in the data's unit
    np.testing.assert_allclose(fit.conditional_variance,
                               garch_variance(x, fit.omega, fit.alpha, fit.beta), rtol=1e-10)
    assert fit.lm_test.pvalue > 0.01  # no ARCH effect left in the standardized residuals
    assert "alpha0" in fit.summary() and "Engle LM" in fit.summary()


def test_scaling_inside_makes_imu_scale_irrelevant() -> None:
    x = simulate_garch(20_000, 0.05, [0.08], [0.9], seed=7)
    a = fit_garch(x)
    b = fit_garch(x * 1e-5)  # variances ~1e-10: like a gyro in rad/s
    np.testing.assert_allclose(b.alpha, a.alpha, rtol=1e-8)
    np.testing.assert_allclose(b.beta, a.beta, rtol=1e-8)
    np.testing.assert_allclose(b.omega, a.omega * 1e-10, rtol=1e-8)
    assert b.loglikelihood == pytest.approx(a.loglikelihood - x.size * math.log(1e-5), rel=1e-12)
    np.testing.assert_allclose(b.std_errors[1:], a.std_errors[1:], rtol=1e-6)


@pytest.mark.slow
def test_standard_errors_match_the_monte_carlo_spread() -> None:
    truth = np.array([0.1, 0.1, 0.8])
    fits = [fit_garch(simulate_garch(4000, 0.1, [0.1], [0.8], seed=100 + r)) for r in range(40)]
    est = np.array([f.params for f in fits])
    se = np.array([f.std_errors for f in fits])
    mc_sd = est.std(axis=0, ddof=1)
    # the mean estimate is within 4 Monte Carlo standard errors of the truth (small bias at N = 4000)
    assert np.all(np.abs(est.mean(axis=0) - truth) < 4 * mc_sd / math.sqrt(len(fits)) + 0.02 * truth)
    # the information-matrix standard errors describe the spread (median within 35 %)
    ratio = np.median(se, axis=0) / mc_sd
    assert np.all((ratio > 0.65) & (ratio < 1.35)), ratio


@pytest.mark.filterwarnings("ignore")  # arch warns that its own optimiser stopped early
def test_loglik_at_least_arch_s() -> None:
    arch_model = pytest.importorskip("arch", reason="arch (test extra) is the peer").arch_model
    x = simulate_garch(50_000, 1.3e-7, [0.0175], [0.98], seed=11)
    ours = fit_garch(x)
    res = arch_model(x, mean="Zero", vol="GARCH", p=1, q=1, rescale=False).fit(disp="off")
    assert ours.loglikelihood >= res.loglikelihood - 1e-6
    # arch's log-likelihood at its own parameters is our likelihood function's (same backcast)
    params = res.params
    ll = garch_loglikelihood(x, params["omega"], [params["alpha[1]"]], [params["beta[1]"]])
    assert ll == pytest.approx(res.loglikelihood, abs=1e-6 * abs(ll))


@pytest.mark.filterwarnings("ignore::FutureWarning")
def test_lm_statistic_equals_t_r2_by_lstsq() -> None:
    rng = np.random.default_rng(5)
    for z in (rng.standard_normal(2000), simulate_garch(2000, 0.1, [0.3], [0.5], seed=3)):
        m = 6
        z2 = z**2
        y = z2[m:]
        X = np.column_stack([np.ones(y.size)] + [z2[m - i : z2.size - i] for i in range(1, m + 1)])
        coef, *_ = np.linalg.lstsq(X, y, rcond=None)
        r2 = 1 - np.sum((y - X @ coef) ** 2) / np.sum((y - y.mean()) ** 2)
        res = arch_lm_test(z, m)
        assert res.statistic == pytest.approx(y.size * r2, rel=1e-9)
        assert res.nobs == y.size and res.lags == m
    diagnostic = pytest.importorskip("statsmodels.stats.diagnostic")
    lm, pval, _, _ = diagnostic.het_arch(z, nlags=m)
    assert res.statistic == pytest.approx(lm, rel=1e-9)
    assert res.pvalue == pytest.approx(pval, rel=1e-6)


def test_lm_growth_stops_at_the_true_order() -> None:
    x = simulate_garch(20_000, 0.05, [0.1], [0.85], seed=9)
    fit = select_garch(x)
    assert fit.order == (1, 1)
    assert fit.lm_test.pvalue > 0.05
    # raw GARCH data fail the test (ARCH effects); the fitted model's residuals pass it
    assert arch_lm_test(x).pvalue < 1e-6


def test_backcast_is_the_exponentially_weighted_mean() -> None:
    x2 = np.arange(1.0, 101.0)
    w = 0.94 ** np.arange(75)
    assert backcast(x2) == pytest.approx(np.sum(w * x2[:75]) / w.sum(), rel=1e-14)


def test_bad_input() -> None:
    x = np.random.default_rng(0).standard_normal(1000)
    bad = x.copy()
    bad[10] = np.nan
    with pytest.raises(InputError, match="NaN"):
        fit_garch(bad)
    with pytest.raises(InputError, match="inf"):
        fit_garch(np.where(np.arange(1000) == 5, np.inf, x))
    with pytest.raises(InputError, match="identically zero"):
        fit_garch(np.zeros(1000))
    with pytest.raises(InputError, match="at least"):
        fit_garch(x[:50])
    with pytest.raises(InputError, match="p must be"):
        fit_garch(x, p=0)
    with pytest.raises(InputError, match="start"):
        fit_garch(x, start=[1.0, 0.6, 0.6])
    with pytest.raises(InputError, match="omega"):
        garch_variance(x, -1.0, [0.1], [0.8])
