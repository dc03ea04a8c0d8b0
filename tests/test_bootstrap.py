"""The parametric bootstrap of GMWM fits (stochmod.fit.bootstrap): reproducibility, a closed
form, the identification diagnostic, the J-test's bootstrap p-value and the gmwm option."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import attrs
import numpy as np
import pytest
from scipy import special, stats

import stochmod
from stochmod.core.errors import InputError
from stochmod.fit.bootstrap import (
    Bootstrap,
    BootstrapDraws,
    _own_form,
    _task,
    bootstrap,
    bootstrap_draws,
    identification,
    with_intervals,
)
from stochmod.fit.gmwm import gmwm

FREQ = 100.0


def _record(spec: str, n: int, seed: int) -> np.ndarray:
    return stochmod.model_from_spec(spec, FREQ).simulate(n, np.random.default_rng(seed))


@pytest.fixture(scope="module")
def gm_wn_fit():
    x = _record("GM(beta=1.0, sigma2=1e-6) + WN(sigma2=3e-6)", 2**12, 11)
    return gmwm(x, "GM+WN", FREQ)


def test_draws_are_seeded_and_independent_of_the_executor(gm_wn_fit):
    serial = bootstrap_draws(gm_wn_fit, 12, rng=5)
    with ThreadPoolExecutor(3) as pool:
        pooled = bootstrap_draws(gm_wn_fit, 12, rng=5, executor=pool, chunk=5)
    single = bootstrap_draws(gm_wn_fit, 12, rng=5, chunk=1)
    for other in (pooled, single):
        np.testing.assert_array_equal(serial.estimates, other.estimates)
        np.testing.assert_array_equal(serial.physical, other.physical)
        np.testing.assert_array_equal(serial.statistics, other.statistics)
    assert serial.failed == 0 and serial.estimates.shape == (12, 3)
    assert np.all(np.isfinite(serial.statistics))
    again = bootstrap_draws(gm_wn_fit, 12, rng=np.random.SeedSequence(5))
    np.testing.assert_array_equal(serial.estimates, again.estimates)
    assert not np.array_equal(serial.estimates, bootstrap_draws(gm_wn_fit, 12, rng=6).estimates)


def test_white_noise_standard_error_and_width_match_the_closed_form():
    # WN fitted on level 1 only: sigma2_hat = 2 nu_1_hat = mean(d_t^2) / 2 with d_t = x_t - x_t-1
    # over M = N - 1 differences; var(d^2) = 8 sigma^4, cov(d_t^2, d_t+1^2) = 2 sigma^4, so
    # sd(sigma2_hat) = sigma2 sqrt(3M - 1) / M exactly
    n, sigma2 = 2**14, 2.0
    fit = gmwm(_record(f"WN(sigma2={sigma2})", n, 3), "WN", FREQ, levels=1)
    est = fit.model.vector()[0]
    M = fit.empirical.n_coef[0]
    assert M == n - 1
    np.testing.assert_allclose(est, 2 * fit.empirical.wv[0], rtol=1e-9)
    exact_sd = est * np.sqrt(3 * M - 1) / M  # at the fitted value, the bootstrap's truth
    boot = bootstrap(fit, 400, rng=1)
    (p,) = boot.parameters()
    assert p.value == est
    assert abs(p.std_error / exact_sd - 1) < 0.12
    width = 2 * special.ndtri(0.975) * exact_sd
    assert abs((p.high - p.low) / width - 1) < 0.12
    assert p.low < est < p.high
    (phys,) = boot.physical()  # the WN density's interval: the map of sigma2's (monotone)
    assert phys.name == "WN.N"
    np.testing.assert_allclose([phys.low, phys.high], np.sqrt([p.low, p.high] / np.float64(FREQ)),
                               rtol=0.03)


def test_diagnostic_flags_a_slow_gm_and_not_a_fast_one():
    # Tc = 20 s in a record of 41 s: the GM's parameters are flagged, the WN's are not
    slow = gmwm(_record("GM(beta=0.05, sigma2=1e-6) + WN(sigma2=3e-6)", 2**12, 2), "GM+WN", FREQ)
    diag = identification(slow)
    assert list(diag.flagged) == [True, True, False]
    assert all("Tc" in r for r in diag.reasons[:2])
    assert not diag.trustworthy
    # Tc = 0.2 s in a record of 655 s, both well above the noise: nothing flagged
    fast = gmwm(_record("GM(beta=5.0, sigma2=1e-5) + WN(sigma2=3e-6)", 2**16, 2), "GM+WN", FREQ)
    assert identification(fast).trustworthy
    assert "ok" in identification(fast).summary()
    # auto keeps every asymptotic interval and takes the J-test's p-value from the bootstrap
    auto = with_intervals(fast, "auto", 19, rng=4)
    assert [(a.low, a.high) for a in auto.parameters()] == [(a.low, a.high)
                                                           for a in fast.parameters()]
    assert auto.physical() == fast.physical()
    assert auto.jtest.statistic == fast.jtest.statistic
    assert auto.jtest.pvalue != fast.jtest.pvalue
    assert round(auto.jtest.pvalue * 20, 9) % 1 == 0  # (1 + k) / (1 + B)
    assert "no interval" in auto.resampling.describe()


def test_auto_replaces_only_the_flagged_intervals():
    x = _record("GM(beta=0.05, sigma2=1e-6) + WN(sigma2=3e-6)", 2**12, 2)
    plain = gmwm(x, "GM+WN", FREQ)
    auto = gmwm(x, "GM+WN", FREQ, intervals="auto", n_boot=40)
    np.testing.assert_array_equal(plain.model.vector(), auto.model.vector())
    a, b = plain.parameters(), auto.parameters()
    assert (a[2].low, a[2].high) == (b[2].low, b[2].high)  # WN: asymptotic, unchanged
    assert (a[0].low, a[0].high) != (b[0].low, b[0].high)  # GM.beta: bootstrap
    pa, pb = plain.physical(), auto.physical()
    assert pa[2] == pb[2] and pa[0] != pb[0]  # WN.N kept, GM.Tc from the draws
    assert auto.jtest.statistic == plain.jtest.statistic
    assert auto.jtest.pvalue != plain.jtest.pvalue  # bootstrap p-value, a multiple of 1/41
    assert round(auto.jtest.pvalue * 41, 9) % 1 == 0
    assert "GMWM fit of GM+WN" in auto.summary()


def test_diagnostic_flags_a_whole_component():
    # Tc = 3.3 s in a record of 164 s (no Tc rule): the GM's beta has a relative s.e. above
    # 0.2, its sigma2 below; both are flagged, the WN is not
    fit = gmwm(_record("GM(beta=0.3, sigma2=1e-7) + WN(sigma2=3e-6)", 2**14, 2), "GM+WN", FREQ)
    rel = fit.std_errors / np.abs(fit.model.vector()[fit.free_mask])
    assert rel[0] > 0.2 > rel[1] and rel[2] < 0.2
    diag = identification(fit)
    assert list(diag.flagged) == [True, True, False]
    assert diag.reasons[0].startswith("relative s.e.") and diag.reasons[1] == "with GM.beta"


def test_random_ramp_interval_is_the_exact_pivot_of_its_one_slope():
    # WN + a ramp of slope s that dominates the deep levels: omega_hat = |s| (to 2 %), and
    # s / omega ~ N(0, 1), so the exact 95 % interval of omega from one record is
    # [|s| / q_0.975, |s| / q_0.025] with q the quantiles of |N(0, 1)| (2.2414, 0.031338).
    # The log-scale basic interval reproduces it; the asymptotic one (eq. 17 V sees the ramp
    # the record holds, not the spread of slopes) is 10 times too narrow, whence rule 5.
    n, s = 2**12, 1.3e-5
    x = np.random.default_rng(4).normal(0.0, 1e-2, n) + s * np.arange(n)
    fit = gmwm(x, "WN+RR", FREQ)
    omega = fit.model.vector()[1]
    assert abs(omega / s - 1) < 0.02
    diag = identification(fit)
    assert list(diag.flagged) == [False, True]
    assert "one realisation per record" in diag.reasons[1]
    q_lo, q_hi = stats.halfnorm.ppf([0.025, 0.975])
    asym = fit.parameters()[1]
    assert asym.high / asym.low < 0.1 * q_hi / q_lo
    p = with_intervals(fit, "auto", 400, rng=3).parameters()[1]
    assert abs(p.low / (omega / q_hi) - 1) < 0.15  # B = 400: ~5 % sampling error here
    assert 0.5 < p.high / (omega / q_lo) < 2.0  # ~30 % here: 10 draws below q_0.025


def test_an_estimate_the_refits_do_not_move_gets_an_unbounded_interval():
    # every replicate returns the estimate (a ramp fitted at omega -> 0): the draws carry no
    # information, the interval of a positive value is [0, inf), of a signed one (-inf, inf)
    est = np.array([1e-25, -0.3])
    draws = BootstrapDraws(estimates=np.tile(est, (50, 1)), physical=np.zeros((50, 0)),
                           physical_names=(), statistics=np.full(50, np.nan),
                           converged=np.ones(50, dtype=bool))
    boot = Bootstrap(draws=draws, estimate=est, physical_values=np.zeros(0), observed=None,
                     use=np.ones(2, dtype=bool), use_physical=np.zeros(0, dtype=bool))
    for method in ("basic", "bc", "percentile"):
        assert boot.interval(0, method=method) == (np.inf, 0.0, np.inf)
        assert boot.interval(1, method=method) == (np.inf, -np.inf, np.inf)
    moved = attrs.evolve(draws, estimates=draws.estimates * np.linspace(0.5, 2.0, 50)[:, None])
    se, low, high = attrs.evolve(boot, draws=moved).interval(0)
    assert 0 < se < np.inf
    assert 0 < low < est[0] < high < np.inf


def test_a_replicate_builds_its_jtest_form_as_the_fit_does(gm_wn_fit):
    # at the fit's own estimate, WV and Omega the replicate's form is the fit's, to round-off;
    # at another estimate it differs (V of that model, projection of that estimate)
    fit = gm_wn_fit
    task = _task(fit)
    same = _own_form(task, fit.model, fit.empirical, fit.omega)
    ref = fit.jtest_form
    np.testing.assert_array_equal(same.keep, ref.keep)
    np.testing.assert_allclose(same.variances, ref.variances, rtol=1e-9)
    np.testing.assert_allclose(same.scale, ref.scale, rtol=1e-9)
    r = fit.empirical.wv[: fit.levels] - fit.fitted_wv
    np.testing.assert_allclose(same.statistic(r), fit.asymptotic_jtest.statistic, rtol=1e-9)
    other = fit.model.with_vector(fit.model.vector() * np.array([1.5, 1.0, 1.0]))
    moved = _own_form(task, other, fit.empirical, fit.omega)
    assert np.max(np.abs(moved.scale / ref.scale - 1)) > 0.1  # V of the other model


def test_jtest_bootstrap_pvalue_is_uniform_under_the_true_model_and_small_under_a_wrong_one():
    truth = "GM(beta=1.0, sigma2=1e-6) + WN(sigma2=3e-6)"
    pvalues = []
    for k in range(24):
        fit = gmwm(_record(truth, 2**11, 100 + k), "GM+WN", FREQ, n_starts=1, n_random=8)
        pvalues.append(bootstrap(fit, 39, rng=k).jtest.pvalue)
    pvalues = np.array(pvalues)
    # 24 p-values of a true model: Kolmogorov-Smirnov against U(0, 1), and no excess of
    # small ones (a chi-square reference that over-rejects shows up as both)
    assert stats.kstest(pvalues, "uniform").pvalue > 0.05
    assert np.mean(pvalues <= 0.1) <= 0.25
    wrong = gmwm(_record(truth, 2**14, 7), "WN", FREQ)
    assert bootstrap(wrong, 39, rng=0).jtest.pvalue == 1 / 40


def test_bad_options_are_refused(gm_wn_fit):
    x = _record("WN(sigma2=1.0)", 2**10, 0)
    with pytest.raises(InputError, match="intervals"):
        gmwm(x, "WN", FREQ, intervals="exact")
    with pytest.raises(InputError, match="pooled"):
        gmwm([x, x[::-1].copy()], "WN", FREQ, intervals="bootstrap", n_boot=5)
    with pytest.raises(InputError, match="apply"):
        bootstrap(gm_wn_fit, 5, apply="some")
    with pytest.raises(InputError, match="method"):
        bootstrap(gm_wn_fit, 5, method="bca")
    with pytest.raises(InputError, match="rng"):
        bootstrap_draws(gm_wn_fit, 5, rng=1.5)
