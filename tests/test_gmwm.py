"""GMWM estimator: recovery of known parameters from seeded simulations, inference, bad input."""

import numpy as np
import pytest

import stochmod
from stochmod import gmwm
from stochmod.core.errors import EstimationError, InputError, SpecError

FREQ = 100.0


def test_white_noise_variance_recovered_within_its_standard_error():
    x = np.random.default_rng(11).normal(0.0, 2.0, 50_000)
    fit = stochmod.gmwm(x, "WN", FREQ)
    (est,) = fit.parameters()
    assert abs(est.value - 4.0) < 4 * est.std_error
    assert est.low < 4.0 < est.high


def test_gm_plus_wn_recovered_from_seeded_simulation():
    truth = stochmod.model_from_spec(
        {"processes": [{"family": "GM", "params": {"beta": 2.0, "sigma2": 1e-4}},
                       {"family": "WN", "params": {"sigma2": 1e-4}}]}, FREQ)
    x = truth.simulate(2**17, rng=3)
    fit = stochmod.gmwm(x, "GM+WN", FREQ)
    gm, wn = fit.model.processes
    # Monte Carlo spread at N = 2^17 (20 seeds, run once): beta ~ 10 %, sigma2 ~ 5 %, WN ~ 1 %
    assert gm.beta == pytest.approx(2.0, rel=0.35)
    assert gm.sigma2 == pytest.approx(1e-4, rel=0.2)
    assert wn.sigma2 == pytest.approx(1e-4, rel=0.05)
    # the estimate fits at least as well as the truth (eq. 20 with the same Omega)
    resid = fit.empirical.wv[: fit.levels] - truth.wv(fit.levels)
    assert fit.objective <= resid @ fit.omega @ resid + 1e-9


def test_fixed_parameters_are_held():
    truth = stochmod.model_from_spec("GM(beta=1.0, sigma2=1e-3)+WN(sigma2=1e-3)", FREQ)
    x = truth.simulate(2**15, rng=5)
    fit = stochmod.gmwm(x, "GM(beta=1.0)+WN", FREQ)
    assert fit.model.processes[0].beta == 1.0
    assert fit.free_names == ("GM.sigma2", "WN.sigma2")


def test_precomputed_wavelet_variance_gives_the_same_fit():
    x = np.random.default_rng(2).normal(size=2**14)
    a = stochmod.gmwm(x, "WN", FREQ)
    b = stochmod.gmwm(stochmod.wvar(x, FREQ), "WN")
    assert a.model.vector() == pytest.approx(b.model.vector(), rel=1e-10)


@pytest.mark.parametrize(
    "kwargs, error",
    [
        ({"weighting": "best"}, InputError),
        ({"model": "FOO"}, SpecError),
        ({"model": "WN(sigma2=1.0)"}, SpecError),
    ],
)
def test_bad_arguments_raise(kwargs, error):
    x = np.random.default_rng(0).normal(size=1024)
    args = {"model": "WN"} | kwargs
    with pytest.raises(error):
        stochmod.gmwm(x, args.pop("model"), FREQ, **args)


def test_bad_signals_raise():
    with pytest.raises(InputError, match="constant"):
        stochmod.gmwm(np.ones(1024), "WN", FREQ)
    y = np.random.default_rng(0).normal(size=1024)
    y[10] = np.nan
    with pytest.raises(InputError, match="data contains 1 non-finite value.*NaN at flat index 10"):
        stochmod.gmwm(y, "WN", FREQ)
    with pytest.raises(InputError, match="freq"):
        stochmod.gmwm(y[:5], "WN")


def test_non_haar_wavelet_needs_the_simulated_binding():
    x = np.random.default_rng(0).normal(size=2048)
    with pytest.raises(InputError, match="haar"):
        stochmod.gmwm(x, "WN", FREQ, wavelet="db4", binding="analytic")


def test_optimal_weighting_works_at_the_default_levels():
    """Eq. 17's V is indefinite at the deepest levels of 2^16 samples; with those levels
    decoupled the optimal fit uses all of them and reaches the truth's objective."""
    truth = stochmod.model_from_spec("GM(beta=2.0, sigma2=1e-6) + GM(beta=0.02, sigma2=1e-7) + WN(sigma2=3e-6)", 100.0)
    x = truth.simulate(2**16, rng=3)
    from stochmod.fit.weighting import weighting_from_covariance
    from stochmod.empirical.wv_covariance import wv_covariance

    with pytest.raises(EstimationError, match="not positive definite"):
        weighting_from_covariance(wv_covariance(x, stochmod.wvar(x, 100.0).wv.size))
    fit = gmwm(x, "2*GM+WN", 100.0, weighting="optimal")
    assert fit.levels == stochmod.wvar(x, 100.0).wv.size
    r = fit.empirical.wv - truth.wv(fit.levels)
    assert fit.objective <= float(r @ fit.omega @ r)
    assert np.all(fit.std_errors > 0)
    for est, true in zip(fit.parameters(), truth.vector()):
        assert est.low <= true <= est.high or abs(est.value - true) <= 4 * est.std_error


def test_indefinite_covariance_is_refused_not_clipped():
    truth = stochmod.model_from_spec("GM(beta=2.0, sigma2=1e-6) + WN(sigma2=3e-6)", 100.0)
    fit = gmwm(truth.simulate(2**12, rng=0), "GM+WN", 100.0)
    fit.__dict__["wv_covariance"] = -np.eye(fit.levels) * 1e-12  # a broken V
    with pytest.raises(EstimationError, match="negative variances"):
        fit.std_errors


def test_ar_ladder_start_spreads_real_roots_over_the_levels():
    from stochmod.core.geometric import WV_PEAK_X

    wv = 1.0 / 2.0 ** np.arange(17) + 1e-3  # white noise over a flat floor
    (alt,) = stochmod.AR(order=2).start_alternatives(wv, 100.0)
    levels = 1 + 16 * np.array([1, 2]) / 3
    roots = np.sort(np.real(np.roots(np.concatenate([[1.0], -np.asarray(alt.phi)]))))
    np.testing.assert_allclose(roots, np.exp(-WV_PEAK_X / 2.0 ** (levels - 1)), rtol=1e-12)
    j = round(levels[-1])
    assert alt.wv(j, 100.0)[j - 1] == pytest.approx(wv[j - 1], rel=1e-12)


def test_a_custom_weighting_matrix_is_used_as_given():
    truth = stochmod.model_from_spec("GM(beta=2.0, sigma2=1e-6) + WN(sigma2=3e-6)", FREQ)
    x = truth.simulate(2**13, rng=5)
    diag = gmwm(x, "GM+WN", FREQ)
    custom = gmwm(x, "GM+WN", FREQ, weighting=diag.omega)
    assert custom.weighting == "custom"
    np.testing.assert_array_equal(custom.omega, diag.omega)
    np.testing.assert_allclose(custom.model.vector(), diag.model.vector(), rtol=1e-8)
    J = diag.levels
    for bad, match in [(np.eye(J + 1), "shape"), (-np.eye(J), "positive definite"),
                       (np.triu(np.ones((J, J))), "symmetric"), (np.full((J, J), np.nan), "non-finite")]:
        with pytest.raises(InputError, match=match):
            gmwm(x, "GM+WN", FREQ, weighting=bad)
