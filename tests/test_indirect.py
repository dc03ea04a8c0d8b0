"""Indirect inference for the GMWM (eq. 29): simulated binding with common random numbers.

Tolerance of "analytic vs simulated" comparisons: both fits use the same data and the same
Omega (the diagonal weighting depends on the data only), so the data's sampling error
cancels and, to first order, theta_sim - theta_an = -B (phi*(theta) - phi(theta)): the
Monte Carlo error of the simulated binding, with covariance B V_sim B^T
(``IndirectGMWMResult.cov_params_simulation``, V_sim the eq. 17 covariance of the
simulated series' WV). Each parameter must agree within 4 of those standard deviations.
"""

import attrs
import numpy as np
import pytest

import stochmod
from stochmod.core.errors import InputError, SpecError
from stochmod.fit.gmwm import GMWMResult
from stochmod.fit.indirect import IndirectGMWMResult, SimulatedBinding, plan_binding
from stochmod.core.process import Process, has_theoretical_wv

FREQ = 100.0
GM, WN, BI = (stochmod.get_process(n) for n in ("GM", "WN", "BI"))


@attrs.frozen
class SimWN(WN):
    """White noise that only knows how to simulate itself (no wv, psd nor autocovariance)."""

    family = "SimWN"
    wv = Process.wv
    wv_jacobian = Process.wv_jacobian
    psd = None  # declares no PSD: its theory comes from simulation
    autocovariance = Process.autocovariance


@attrs.frozen
class AcvfOnlyNonStationary(WN):
    """Declares an autocovariance but is not stationary: the base fallback cannot use it."""

    family = "AcvfOnly"
    stationary = False
    wv = Process.wv
    psd = None  # declares no PSD: its theory comes from simulation


def _within_mc_error(sim, an):
    """|theta_sim - theta_an| <= 4 sd of the simulation's Monte Carlo error, per parameter."""
    mc = np.sqrt(np.diag(sim.cov_params_simulation))
    diff = sim.model.vector()[sim.free_mask] - an.model.vector()[an.free_mask]
    assert np.all(np.abs(diff) <= 4 * mc), (diff / mc)
    return mc


def test_has_theoretical_wv_follows_the_base_fallbacks():
    for cls in (GM, WN, BI, stochmod.get_process("RW"), stochmod.get_process("AR")):
        assert has_theoretical_wv(cls)
    assert not has_theoretical_wv(SimWN(sigma2=1.0))
    assert not has_theoretical_wv(AcvfOnlyNonStationary)
    with pytest.raises(NotImplementedError):  # indeed: the base has nothing to work with
        SimWN(sigma2=1.0).wv(3, FREQ)


def test_common_random_numbers_make_the_binding_deterministic_and_smooth():
    binding = SimulatedBinding((True,), levels=10, n_sim=2**14, n=2**12, seed=7)
    one = binding(stochmod.Model((WN(sigma2=1.0),), FREQ))
    three = binding(stochmod.Model((WN(sigma2=3.0),), FREQ))
    again = SimulatedBinding((True,), 10, 2**14, 2**12, 7)(stochmod.Model((WN(sigma2=1.0),), FREQ))
    np.testing.assert_array_equal(one, again)  # fresh generator from the same seed each time
    # WN's path is sqrt(sigma2) z with the same z: phi* is exactly linear in sigma2 ...
    np.testing.assert_allclose(three, 3.0 * one, rtol=1e-12)
    # ... so d phi* / d log sigma2 = phi* (closed form), matched by the finite differences
    model = stochmod.Model((WN(sigma2=2.0),), FREQ)
    D = binding.jacobian(model, np.array([True]))
    np.testing.assert_allclose(D[:, 0], 2.0 * one, rtol=1e-7)
    Df = binding.jacobian(model, np.array([True]), central=False)
    np.testing.assert_allclose(Df[:, 0], 2.0 * one, rtol=1e-5)
    # and phi* is the WV of white noise, sigma2 / 2^j, within its sampling error
    j = np.arange(1, 11)
    eta = np.maximum((2**14 - 2**j + 1) / 2.0**j, 1.0)
    assert np.all(np.abs(one - 2.0**-j) <= 4 * 2.0**-j * np.sqrt(2 / eta))


def test_binding_is_invariant_to_the_order_of_repeated_components():
    a, b = GM(beta=5.0, sigma2=1.0), GM(beta=0.1, sigma2=2.0)
    binding = SimulatedBinding((True, True, True), 9, 2**13, 2**13, 0)
    one = binding(stochmod.Model((a, b, WN(sigma2=1.0)), FREQ))
    two = binding(stochmod.Model((b, a, WN(sigma2=1.0)), FREQ))
    np.testing.assert_array_equal(one, two)


def test_simulated_length_is_bounded():
    model = stochmod.model_from_spec("GM+WN", FREQ)
    plan = plan_binding(model, "simulated", R=10, max_sim=1000, n=500, levels=5, seed=0)
    assert plan.n_sim == 1000 and plan.R_effective == 2.0  # capped
    plan = plan_binding(model, "simulated", R=10, max_sim=1000, n=5000, levels=5, seed=0)
    assert plan.n_sim == 5000  # never shorter than the data
    plan = plan_binding(model, "simulated", R=3, max_sim=10**6, n=500, levels=5, seed=0)
    assert plan.n_sim == 1500 and plan.simulated == (True, True)
    assert plan_binding(model, "auto", R=3, max_sim=10, n=500, levels=5, seed=0) is None
    mixed = stochmod.Model((GM(), SimWN()), FREQ)
    assert plan_binding(mixed, "auto", R=3, max_sim=10**6, n=500, levels=5, seed=0).simulated == (False, True)


@pytest.fixture(scope="module")
def gm_wn_data():
    truth = stochmod.model_from_spec("GM(beta=2.0, sigma2=1e-4)+WN(sigma2=1e-4)", FREQ)
    return truth, truth.simulate(2**13, rng=3)


def test_gm_plus_wn_simulated_agrees_with_analytic_within_monte_carlo_error(gm_wn_data):
    truth, x = gm_wn_data
    an = stochmod.gmwm(x, "GM+WN", FREQ)
    sim = stochmod.gmwm(x, "GM+WN", FREQ, binding="simulated", R=8, n_random=16, n_starts=2)
    assert type(an) is GMWMResult and isinstance(sim, IndirectGMWMResult)
    assert sim.simulation.n_sim == 8 * x.size
    mc = _within_mc_error(sim, an)
    # every component simulated: V_sim ~ V N / n_sim, so the Monte Carlo sd is about
    # sd_analytic / sqrt(R) = 0.35 sd (eq. 17 estimates of V at deep levels are noisy: +-35 %)
    ratio = mc / an.std_errors
    assert np.all((ratio > 0.35 / 1.35) & (ratio < 0.35 * 1.35)), ratio
    # standard errors include the simulation: (1 + 1/R) V -> larger by ~ sqrt(1.125)
    assert np.all(sim.std_errors > an.std_errors)
    # truth recovered within 4 standard errors
    vec = truth.vector()
    assert np.all(np.abs(sim.model.vector() - vec) <= 4 * sim.std_errors)
    # reported objective is eq. 20 at the reported model with phi* (label-canonical binding)
    r = sim.empirical.wv[: sim.levels] - sim.model_wv()
    assert sim.objective == pytest.approx(r @ sim.omega @ r, rel=1e-9)
    assert sim.jtest is not None and sim.jtest.pvalue > 1e-3  # the model is true
    assert "indirect inference (eq. 29)" in sim.summary()
    assert sim.to_dict()["indirect"]["n_sim"] == 8 * x.size


def test_bi_plus_wn_simulated_agrees_with_analytic_within_monte_carlo_error():
    truth = stochmod.model_from_spec("BI(B=5e-3, fc=0.2)+WN(sigma2=1e-4)", FREQ)
    x = truth.simulate(2**14, rng=3)
    kw = {"n_random": 8, "n_starts": 1}
    an = stochmod.gmwm(x, "BI+WN", FREQ, **kw)
    sim = stochmod.gmwm(x, "BI+WN", FREQ, binding="simulated", R=2, **kw)
    _within_mc_error(sim, an)
    assert np.all(np.abs(sim.model.vector() - truth.vector()) <= 4 * sim.std_errors)


def test_family_without_theoretical_wv_is_fitted_by_indirect_inference(gm_wn_data):
    truth, x = gm_wn_data
    with pytest.raises(SpecError, match="SimWN has no theoretical wavelet variance"):
        stochmod.gmwm(x, GM() + SimWN(), FREQ, binding="analytic")
    hybrid = stochmod.gmwm(x, GM() + SimWN(), FREQ, R=8)  # auto: only SimWN is simulated
    assert hybrid.simulation.simulated == (False, True)
    an = stochmod.gmwm(x, "GM+WN", FREQ)
    _within_mc_error(hybrid, an)
    assert np.all(np.abs(hybrid.model.vector() - truth.vector()) <= 4 * hybrid.std_errors)
    # the GM part of D is analytic: identical to the analytic fit's at the same point
    D = hybrid.simulation.jacobian(hybrid.model, hybrid.free_mask)
    exact = hybrid.model.processes[0].wv_jacobian(hybrid.levels, FREQ) * hybrid.model.vector()[:2]
    np.testing.assert_allclose(D[:, :2], exact, rtol=1e-9)
    # ... and the SimWN column is d phi*/d log sigma2 = its simulated WV (linear in sigma2)
    wn_part = hybrid.model_wv() - hybrid.model.processes[0].wv(hybrid.levels, FREQ)
    np.testing.assert_allclose(D[:, 2], wn_part, rtol=1e-6)


def test_optimal_weighting_with_a_simulated_component(gm_wn_data):
    _, x = gm_wn_data
    # same Omega (eq. 17 on the data) on both sides: only the Monte Carlo error differs
    fit = stochmod.gmwm(x, GM() + SimWN(), FREQ, weighting="optimal", R=8)
    an = stochmod.gmwm(x, "GM+WN", FREQ, weighting="optimal")
    assert isinstance(fit, IndirectGMWMResult)
    np.testing.assert_array_equal(fit.omega, an.omega)
    _within_mc_error(fit, an)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"binding": "monte-carlo"}, "binding"),
        ({"binding": "simulated", "R": 0}, "R"),
        ({"binding": "simulated", "max_sim": 0}, "max_sim"),
        ({"binding": "simulated", "rng": -1}, "rng"),
        ({"R": 1.5}, "R"),
    ],
)
def test_bad_arguments_raise(kwargs, match):
    x = np.random.default_rng(0).normal(size=1024)
    with pytest.raises(InputError, match=match):
        stochmod.gmwm(x, "WN", FREQ, **kwargs)
