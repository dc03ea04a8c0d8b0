"""GMWM estimator: recovery of known parameters from seeded simulations, inference, bad input."""

import numpy as np
import pytest

import stochmod
from stochmod.errors import InputError, SpecError

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
    with pytest.raises(InputError, match="NaN"):
        stochmod.gmwm(y, "WN", FREQ)
    with pytest.raises(InputError, match="freq"):
        stochmod.gmwm(y[:5], "WN")


def test_non_haar_wavelet_needs_the_simulated_binding():
    x = np.random.default_rng(0).normal(size=2048)
    with pytest.raises(InputError, match="haar"):
        stochmod.gmwm(x, "WN", FREQ, wavelet="db4", binding="analytic")
