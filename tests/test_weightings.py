"""GMWM weightings are a plugin point that is called: the first-party weightings are found
through the registry like a third party's, gmwm / select / the CLI resolve names there, and a
weighting registered at run time is used.

Truth: closed forms of the white-noise GMWM estimate (the WV of WN(s2) is s2 / 2^j, so eq. 20
is quadratic in s2 and its minimiser is explicit for a diagonal Omega); the matrices gmwm used
before weightings were plugins (inverse chi-square variances, the identity).
"""

from __future__ import annotations

import concurrent.futures
from typing import Any, ClassVar

import attrs
import numpy as np
import pytest

import stochmod
from stochmod import sdk
import stochmod.fit.selection  # used as stochmod.fit.selection below
from stochmod.cli import main
from stochmod.core.errors import InputError, SpecError, StochmodError
from stochmod.fit.weighting import WEIGHTINGS
from stochmod.fit.weighting_plugins import (
    Weighting,
    WeightingInput,
    WeightingMatrix,
    get_weighting,
    weighting_names,
)
from stochmod.plugin.registry import plugin_manager, weightings

FREQ = 100.0
FIRST_PARTY = ["bootstrap", "diagonal", "identity", "model", "optimal"]


def white(seed: int = 3, n: int = 2**13) -> np.ndarray:
    return np.random.default_rng(seed).normal(0.0, 2.0, n)


def wn_estimate(nu: np.ndarray, weights: np.ndarray) -> float:
    """argmin_s2 sum_j w_j (nu_j - s2 / 2^j)^2 = sum w_j nu_j 2^-j / sum w_j 4^-j."""
    g = 2.0 ** -np.arange(1, nu.size + 1)
    return float(np.sum(weights * nu * g) / np.sum(weights * g * g))


@attrs.frozen
class Inverse4th(Weighting):
    """A test-only weighting: Omega = diag(1 / nu^4), counting its calls."""

    name: ClassVar[str] = "inverse4"
    description: ClassVar[str] = "test weighting"
    calls: list = attrs.field(factory=list, eq=False)

    def matrix(self, data: WeightingInput) -> WeightingMatrix:
        self.calls.append(data.levels)
        return WeightingMatrix(np.diag(1.0 / data.wv**4))


def _plugin(*objects: Any) -> object:
    class Plugin:
        @sdk.hookimpl
        def stochmod_weightings(self) -> list[Any]:
            return list(objects)

    return Plugin()


@pytest.fixture
def inverse4():
    w = Inverse4th()
    plugin = _plugin(w)
    stochmod.register_plugin(plugin)
    try:
        yield w
    finally:
        stochmod.unregister_plugin(plugin)


def test_first_party_weightings_are_registered_through_the_hook() -> None:
    table = weightings()
    assert set(FIRST_PARTY) <= set(table) and list(table) == sorted(table)
    loaded = {name for name, _ in plugin_manager().list_name_plugin()}
    assert "stochmod.fit.weighting_plugins" in loaded
    for name in FIRST_PARTY:
        assert get_weighting(name) is table[name] and table[name].name == name
    assert set(FIRST_PARTY) <= set(WEIGHTINGS)  # the compatibility tuple follows the registry
    assert "bootstrap" not in weighting_names(shared=True) and "model" not in weighting_names(shared=True)
    assert set(weighting_names(shared=True)) == set(stochmod.fit.selection.SELECTION_WEIGHTINGS)


def test_diagonal_and_identity_give_the_closed_form_white_noise_estimate() -> None:
    x = white()
    emp = stochmod.wvar(x, FREQ)
    J = emp.wv.size
    diag = stochmod.gmwm(x, "WN", FREQ)
    eta = np.maximum(emp.n_coef / 2.0**emp.levels, 1.0)  # equivalent degrees of freedom
    np.testing.assert_allclose(diag.omega, np.diag(eta / (2 * emp.wv**2)), rtol=1e-14)
    assert diag.model.vector()[0] == pytest.approx(wn_estimate(emp.wv, np.diag(diag.omega)), rel=1e-8)
    ident = stochmod.gmwm(x, "WN", FREQ, weighting="identity")
    np.testing.assert_array_equal(ident.omega, np.eye(J))
    assert ident.model.vector()[0] == pytest.approx(wn_estimate(emp.wv, np.ones(J)), rel=1e-8)
    assert ident.model.vector()[0] != pytest.approx(diag.model.vector()[0], rel=1e-6)


def _haar_coefficient_acov(j: int, s2: float) -> np.ndarray:
    """Autocovariances (lags 0..2^j - 1) of the level-j Haar MODWT coefficients of WN(s2),
    from the filter itself: 2^(j-1) taps of 2^-j, then 2^(j-1) of -2^-j."""
    half = 2 ** (j - 1)
    h = np.concatenate([np.full(half, 2.0**-j), np.full(half, -(2.0**-j))])
    return s2 * np.correlate(h, h, mode="full")[h.size - 1:]


def test_the_model_weighting_is_the_inverse_model_variance_at_the_pilot_fit() -> None:
    """For a white-noise pilot WN(s2), V_jj of eq. 17 is the time-domain sum
    (2 / M_j) sum_tau gamma_j(tau)^2 of the Haar coefficients' autocovariances, and the fit is
    the closed-form WN estimate with those weights."""
    x = white()
    emp = stochmod.wvar(x, FREQ)
    fit = stochmod.gmwm(x, "WN", FREQ, weighting="model")
    pilot = stochmod.gmwm(x, "WN", FREQ).model.vector()[0]
    var = []
    for j, m in zip(emp.levels, emp.n_coef):
        g = _haar_coefficient_acov(int(j), pilot)
        var.append(2.0 / m * (g[0] ** 2 + 2.0 * np.sum(g[1:] ** 2)))
    assert fit.weighting == "model"
    np.testing.assert_allclose(np.diag(fit.omega), 1.0 / np.array(var), rtol=1e-8)
    assert np.count_nonzero(fit.omega - np.diag(np.diag(fit.omega))) == 0
    assert fit.model.vector()[0] == pytest.approx(wn_estimate(emp.wv, 1.0 / np.array(var)), rel=1e-8)


def test_a_given_pilot_fixes_the_model_weighting() -> None:
    """``pilot=``: Omega is the inverse model variance at the pilot's model (here WN(9), away
    from the data's WN(4)), not at a diagonal fit; a pilot of another model, or for a
    weighting without ``needs_fit``, is refused."""
    x = white()
    emp = stochmod.wvar(x, FREQ)
    diagonal = stochmod.gmwm(x, "WN", FREQ)
    pilot = attrs.evolve(diagonal, model=stochmod.model_from_spec("WN(sigma2=9.0)", FREQ))
    fit = stochmod.gmwm(x, "WN", FREQ, weighting="model", pilot=pilot)
    var = [2.0 / m * (g[0] ** 2 + 2.0 * np.sum(g[1:] ** 2))
           for g, m in ((_haar_coefficient_acov(int(j), 9.0), m)
                        for j, m in zip(emp.levels, emp.n_coef))]
    np.testing.assert_allclose(np.diag(fit.omega), 1.0 / np.array(var), rtol=1e-8)
    other = stochmod.gmwm(x, "GM+WN", FREQ)
    with pytest.raises(SpecError, match="pilot fit of GM\\+WN does not match model WN"):
        stochmod.gmwm(x, "WN", FREQ, weighting="model", pilot=other)
    with pytest.raises(InputError, match="weighting 'diagonal' does not take one"):
        stochmod.gmwm(x, "WN", FREQ, pilot=diagonal)
    with pytest.raises(InputError, match="pilot must be a GMWMResult, got Model"):
        stochmod.gmwm(x, "WN", FREQ, weighting="model", pilot=pilot.model)


def test_the_model_weighting_removes_the_random_walks_bias_of_the_diagonal_weighting() -> None:
    """WN(1e-4) + RW(1e-9) at 100 Hz, 2^16 samples, 100 seeded records. The WV is linear in
    both variances, so with weights that do not depend on the data the estimate is unbiased.
    The diagonal weights eta_j / (2 v_j^2) of the deep levels, where eta_j is a few, rise and
    fall with the level's own error: the RW estimate is 12 % low on average (4 standard
    errors); with weights from the pilot model it is within its standard error (2.3 %)."""
    truth = stochmod.model_from_spec("WN(sigma2=1e-4) + RW(sigma2=1e-9)", FREQ)
    ratios = {"diagonal": [], "model": []}
    for r in range(100):
        x = truth.simulate(2**16, rng=5000 + r)
        for name, values in ratios.items():
            values.append(stochmod.gmwm(x, "WN+RW", FREQ, weighting=name).model.vector()
                          / truth.vector())
    mean = {name: np.mean(v, axis=0) for name, v in ratios.items()}
    assert mean["diagonal"][1] < 0.92  # the reason for the model weighting
    assert abs(mean["model"][1] - 1.0) < 0.05 and abs(mean["model"][0] - 1.0) < 0.003
    spread = {name: np.std(np.log(v), axis=0, ddof=1)[1] for name, v in ratios.items()}
    assert spread["model"] < 0.7 * spread["diagonal"]


def test_the_model_weightings_intervals_cover_a_random_walk() -> None:
    """WN(1e-4) + RW(1e-9) at 100 Hz, 2^15 samples, 300 seeded records: the 95 % intervals of
    the model weighting, with V from the fitted model at the estimate, cover the true RW in
    93-97 % of the records (s.e. 1.3 %); the diagonal weighting's, with V from eq. 17 on the
    signal, in under 85 %."""
    truth = stochmod.model_from_spec("WN(sigma2=1e-4) + RW(sigma2=1e-9)", FREQ)
    covered = {"diagonal": 0, "model": 0}
    for r in range(300):
        x = truth.simulate(2**15, rng=7000 + r)
        for name in covered:
            rw = stochmod.gmwm(x, "WN+RW", FREQ, weighting=name).parameters()[1]
            covered[name] += rw.low <= 1e-9 <= rw.high
    assert 0.93 <= covered["model"] / 300 <= 0.97
    assert covered["diagonal"] / 300 < 0.85


def test_a_runtime_weighting_is_called_by_gmwm_and_select(inverse4: Inverse4th) -> None:
    x = white()
    emp = stochmod.wvar(x, FREQ)
    fit = stochmod.gmwm(x, "WN", FREQ, weighting="inverse4", levels=8)
    assert inverse4.calls == [8] and fit.weighting == "inverse4"
    np.testing.assert_array_equal(fit.omega, np.diag(1.0 / emp.wv[:8] ** 4))
    assert fit.model.vector()[0] == pytest.approx(wn_estimate(emp.wv[:8], emp.wv[:8] ** -4.0), rel=1e-8)
    assert "inverse4" in weighting_names(shared=True)
    with concurrent.futures.ThreadPoolExecutor(1) as pool:
        sel = stochmod.select(x, FREQ, candidates=["WN", "WN+RW"], weighting="inverse4", executor=pool,
                              progress=False)
    assert sel.weighting == "inverse4" and len(inverse4.calls) == 2
    np.testing.assert_array_equal(sel.fits["WN"].omega, np.diag(1.0 / emp.wv**4))
    assert sel.fits["WN"].model.vector()[0] == pytest.approx(wn_estimate(emp.wv, emp.wv**-4.0), rel=1e-8)


def test_unknown_and_unshareable_weightings_are_refused_with_the_registered_names() -> None:
    x = white()
    with pytest.raises(InputError, match="unknown weighting 'nope'; registered weightings: bootstrap, diagonal"):
        stochmod.gmwm(x, "WN", FREQ, weighting="nope")
    with pytest.raises(InputError, match="unknown weighting 'nope'"):
        stochmod.select(x, FREQ, candidates=["WN"], weighting="nope")
    with pytest.raises(InputError, match="'bootstrap' depends on each model's own fit.*'diagonal'"):
        stochmod.select(x, FREQ, candidates=["WN"], weighting="bootstrap")
    with pytest.raises(InputError, match="'optimal' needs the signal"):
        stochmod.gmwm(stochmod.wvar(x, FREQ), "WN", weighting="optimal")
    data = WeightingInput(stochmod.wvar(x, FREQ), 8)  # no signal, no pilot
    with pytest.raises(InputError, match="'optimal' needs the signal"):
        get_weighting("optimal").matrix(data)
    with pytest.raises(InputError, match="'bootstrap' needs a first fit"):
        get_weighting("bootstrap").matrix(data)


def test_the_cli_resolves_weightings_through_the_registry(tmp_path, capsys, inverse4) -> None:
    path = tmp_path / "x.csv"
    np.savetxt(path, white()[:4096])
    assert main(["fit", str(path), "--freq", "100", "--model", "WN", "--weighting", "inverse4"]) == 0
    assert "inverse4 weighting" in capsys.readouterr().out
    assert main(["fit", str(path), "--freq", "100", "--model", "WN", "--weighting", "nope"]) == 2
    err = capsys.readouterr().err
    assert "unknown weighting 'nope'" in err and "inverse4" in err and "optimal" in err
    assert main(["select", str(path), "--freq", "100", "--candidates", "WN", "--weighting",
                 "bootstrap"]) == 2
    assert "cannot be shared" in capsys.readouterr().err


def test_bad_weighting_plugins_are_refused_at_registration() -> None:
    @attrs.frozen
    class Nameless:
        def matrix(self, data):
            return WeightingMatrix(np.eye(data.levels))

    @attrs.frozen
    class FakeDiagonal(Inverse4th):
        name: ClassVar[str] = "diagonal"

    for bad, match in [(Nameless(), "not a weighting"), (FakeDiagonal(), "two plugins register a weighting named 'diagonal'")]:
        plugin = _plugin(bad)
        with pytest.raises(StochmodError, match=match):
            stochmod.register_plugin(plugin)
        assert plugin not in plugin_manager().get_plugins()
    assert type(get_weighting("diagonal")).__name__ == "DiagonalWeighting"


def test_a_weighting_whose_matrix_is_not_a_weighting_matrix_is_refused(inverse4) -> None:
    @attrs.frozen
    class Skewed(Inverse4th):
        name: ClassVar[str] = "skewed"

        def matrix(self, data):
            return WeightingMatrix(np.eye(data.levels) + np.triu(np.ones((data.levels,) * 2), 1))

    plugin = _plugin(Skewed())
    stochmod.register_plugin(plugin)
    try:
        with pytest.raises(InputError, match="weighting 'skewed'.s matrix is not symmetric"):
            stochmod.gmwm(white(), "WN", FREQ, weighting="skewed")
    finally:
        stochmod.unregister_plugin(plugin)
