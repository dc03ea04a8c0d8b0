"""Tests of the BI family (plugins/stochmod_bi).

Truth: the definition of BI as a mixture of Gauss-Markov processes (variance B^2/pi per unit of
ln(rate) between 2 pi fc and pi freq, plus the corner GM of variance B^2/pi), evaluated
independently in mpmath at 40-50 digits: the AR(1) Haar WV by the brute-force block-sum
identity (4 V(m) - V(2m)) / (4 m^2); the autocovariance and PSD by quadrature of the
mixture's defining integral; the WV by the exact finite Haar sum over that autocovariance and,
at deep levels, by quadrature of the AR(1) WV over ln(rate). IEEE Std 952's flat Allan floor
(2 ln 2 / pi) B^2 and the 0.664 factor; allantools (peer) on seeded simulations; closed-form
Gauss-Markov blocks and composed steps; seeded Monte Carlo means within their standard error.
"""

from __future__ import annotations

import json
import math

import allantools
import mpmath as mp
import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from scipy import integrate

from stochmod import model_from_spec
from stochmod.core.errors import DomainError, EstimationError, InputError, SpecError
from stochmod.empirical.wavelet_variance import wvar
from stochmod.core.statespace import compose_steps
from stochmod.core.theory import wv_from_autocovariance
from stochmod.core.units import BI_FACTOR, BI_FACTOR_IEEE
from stochmod_bi import BI, DEFAULT_N_GM, HALF_FLOOR_TAU_FC, circulant_embedding
from stochmod_wn import WN

FREQ = 100.0
# fc / freq from deep 1/f bands to past Nyquist (empty band: the corner GM alone)
nu_cs = st.floats(-12, 1).map(lambda e: 10.0**e).filter(lambda v: abs(v - 0.5) > 1e-9)
b_values = st.floats(-6, 6).map(lambda e: 10.0**e)


# ---------------------------------------------------------------------------- mpmath references
def _mp_block_wv(gamma, m: int) -> mp.mpf:
    """Haar WV from an autocovariance by (4 V(m) - V(2m)) / (4 m^2), V(n) = var of an n-sum."""
    def V(n: int) -> mp.mpf:
        return n * gamma(0) + 2 * mp.fsum((n - t) * gamma(t) for t in range(1, n))

    return (4 * V(m) - V(2 * m)) / (4 * m * m)


def _mp_ar1_wv_closed(d: mp.mpf, m: int) -> mp.mpf:
    q = mp.e ** (-d)
    u, v = 1 - q, 1 - q**m
    return (2 * m * u * (2 - u) - 2 * q * v * (2 + v)) / (4 * m * m * u * u)


def _mp_band(nu_c: float) -> tuple[mp.mpf, mp.mpf, list]:
    d_lo = 2 * mp.pi * mp.mpf(nu_c)
    a, b = mp.log(d_lo), mp.log(mp.pi)
    pts = [a + k for k in range(int(mp.floor(b - a)) + 1)] + [b] if b > a else []
    return d_lo, mp.mpf(1) / mp.pi, pts


def _mp_gamma(nu_c: float, B: float):
    """Autocovariance from the mixture's E1 form (its own test checks it against the integral)."""
    d_lo, c, pts = _mp_band(nu_c)
    c = c * mp.mpf(B) ** 2
    band = bool(pts)

    def gamma(t: int) -> mp.mpf:
        atom = mp.e ** (-d_lo * t)
        if not band:
            return c * atom
        if t == 0:
            return c * (mp.log(mp.pi / d_lo) + 1)
        return c * (mp.e1(d_lo * t) - mp.e1(mp.pi * t) + atom)

    return gamma


def _mp_wv_quadrature(nu_c: float, m: int, B: float = 1.0) -> mp.mpf:
    d_lo, c, pts = _mp_band(nu_c)
    total = _mp_ar1_wv_closed(d_lo, m)
    if pts:
        total += mp.quad(lambda s: _mp_ar1_wv_closed(mp.e**s, m), pts)
    return c * mp.mpf(B) ** 2 * total


# ---------------------------------------------------------------------------- the reference itself
@settings(max_examples=20, deadline=None)
@given(d=st.floats(-11, 1.5).map(lambda e: 10.0**e), j=st.integers(1, 9))
@example(d=1e-11, j=2)
def test_mpmath_ar1_closed_form_equals_brute_force_block_sums(d: float, j: int) -> None:
    # the deep-level reference below integrates this closed form; check it first. Both sides
    # cancel: the block sums like (m d)^-2, the closed form like (m d)^-3 (1e-33 at d = 1e-11,
    # m = 1), so they are compared at 80 digits
    m = 2 ** (j - 1)
    with mp.workdps(80):
        q = mp.e ** (-mp.mpf(d))
        assert abs(_mp_ar1_wv_closed(mp.mpf(d), m) / _mp_block_wv(lambda t: q**t, m) - 1) < 1e-20


# ---------------------------------------------------------------------------- autocovariance, PSD
@settings(max_examples=25, deadline=None)
@given(nu_c=nu_cs, B=b_values, lag=st.integers(0, 10**6))
def test_autocovariance_equals_the_mixture_integral(nu_c: float, B: float, lag: int) -> None:
    got = BI(B=B, fc=nu_c * FREQ).autocovariance(np.array([lag, -lag]), FREQ)
    with mp.workdps(40):
        d_lo, c, pts = _mp_band(nu_c)
        exact = mp.e ** (-d_lo * lag)
        if pts:  # int over ln d of exp(-d t): the definition, not the E1 closed form
            exact += mp.quad(lambda s: mp.e ** (-mp.e**s * lag), pts)
        exact *= c * mp.mpf(B) ** 2
        assert got[0] == got[1]
        # absolute error relative to the variance: far lags are tiny differences of E1 values
        scale = c * mp.mpf(B) ** 2 * (mp.log(mp.pi / d_lo) + 1 if pts else 1)
        assert abs(mp.mpf(float(got[0])) - exact) <= 1e-13 * scale


@settings(max_examples=20, deadline=None)
@given(nu_c=nu_cs, B=b_values, frac=st.floats(0.0, 1.0))
def test_psd_equals_the_mixture_of_ar1_spectra(nu_c: float, B: float, frac: float) -> None:
    f = frac * FREQ / 2
    got = BI(B=B, fc=nu_c * FREQ).psd(np.array([f, -f]), FREQ)
    with mp.workdps(40):
        d_lo, c, pts = _mp_band(nu_c)
        th = 2 * mp.pi * mp.mpf(f) / FREQ

        def spec(d: mp.mpf) -> mp.mpf:
            q = mp.e ** (-d)
            return (1 - q * q) / (1 - 2 * q * mp.cos(th) + q * q)

        exact = spec(d_lo)
        if pts:
            peak = [mp.log(th)] if th > 0 and pts[0] < mp.log(th) < pts[-1] else []
            split = sorted(set(pts + peak))
            exact += mp.quad(lambda s: spec(mp.e**s), split)
        exact *= c * mp.mpf(B) ** 2 / FREQ
        assert got[0] == got[1]
        assert abs(mp.mpf(float(got[0])) / exact - 1) < 1e-10


@pytest.mark.parametrize("nu_c", [1e-7, 1e-3, 0.2, 3.0])
def test_psd_integrates_to_the_variance(nu_c: float) -> None:
    p = BI(B=2.0, fc=nu_c * FREQ)
    edges = np.r_[0.0, FREQ / 2 * 2.0 ** -np.arange(40, -1, -1)]
    total = 2 * sum(integrate.quad(lambda f: p.psd(np.array([f]), FREQ)[0], a, b, epsrel=1e-12,
                                   epsabs=0.0, limit=200)[0] for a, b in zip(edges[:-1], edges[1:]))
    assert total == pytest.approx(p.autocovariance(np.array([0]), FREQ)[0], rel=1e-9)


def test_psd_follows_the_ieee_flicker_law_between_the_corners() -> None:
    # IEEE Std 952: two-sided S(f) = B^2 / (2 pi |f|) (one-sided B^2 / (pi f)) in the 1/f band;
    # the corner GM cancels the 1/f^2 term, so the law holds to O((fc/f)^3) above fc, and to
    # O(f / freq) below the Nyquist corner
    B, fc = 3.0, 1e-5
    f = np.logspace(-3, -1, 9)  # 100 fc .. freq/1000
    ratio = BI(B=B, fc=fc).psd(f, FREQ) * 2 * math.pi * f / B**2
    assert np.max(np.abs(ratio - 1)) < 5e-4


# ---------------------------------------------------------------------------- wavelet variance
@settings(max_examples=25, deadline=None)
@given(nu_c=nu_cs, B=b_values, j=st.integers(1, 9))
def test_wv_equals_the_exact_haar_sum_over_the_autocovariance(nu_c: float, B: float,
                                                              j: int) -> None:
    got = BI(B=B, fc=nu_c * FREQ).wv(j, FREQ)[-1]
    with mp.workdps(30):
        exact = _mp_block_wv(_mp_gamma(nu_c, B), 2 ** (j - 1))
        assert abs(mp.mpf(float(got)) / exact - 1) < 1e-9


@settings(max_examples=15, deadline=None)
@given(nu_c=nu_cs, j=st.integers(1, 50))
def test_wv_at_any_level_against_mpmath_quadrature(nu_c: float, j: int) -> None:
    got = BI(B=1.0, fc=nu_c * FREQ).wv(j, FREQ)[-1]
    with mp.workdps(50):
        assert abs(mp.mpf(float(got)) / _mp_wv_quadrature(nu_c, 2 ** (j - 1)) - 1) < 1e-9


@settings(max_examples=5, deadline=None)
@given(nu_c=st.floats(-9, 0.5).map(lambda e: 10.0**e).filter(lambda v: abs(v - 0.5) > 1e-3),
       j=st.integers(1, 30))
def test_wv_jacobian_against_mpmath_derivatives(nu_c: float, j: int) -> None:
    B, fc = 1.7, nu_c * FREQ
    jac = BI(B=B, fc=fc).wv_jacobian(j, FREQ)[-1]
    with mp.workdps(40):
        m = 2 ** (j - 1)
        d_fc = mp.diff(lambda x: _mp_wv_quadrature(x / FREQ, m, B), mp.mpf(fc))
        d_b = mp.diff(lambda x: _mp_wv_quadrature(nu_c, m, x), mp.mpf(B))
        # d wv / d fc is a difference of two terms near 1/2 whose sum is O(nu_c): rounding
        # grows as 1/nu_c at tiny corners (5e-8 measured at nu_c = 1e-8, 1e-14 at 1e-3)
        assert abs(mp.mpf(float(jac[1])) / d_fc - 1) < 1e-8 + 2e-15 / nu_c
        assert abs(mp.mpf(float(jac[0])) / d_b - 1) < 1e-10


def test_wv_is_continuous_where_the_band_closes() -> None:
    below = BI(B=1.0, fc=FREQ / 2 * (1 - 1e-12)).wv(12, FREQ)
    above = BI(B=1.0, fc=FREQ / 2 * (1 + 1e-12)).wv(12, FREQ)
    np.testing.assert_allclose(below, above, rtol=1e-10)


def test_allan_floor_is_the_ieee_bias_instability_floor() -> None:
    # IEEE Std 952 / Quinchia eq. 18: Allan deviation floor = 0.664 B; Haar WV = AVAR / 2
    B = 2.5e-5
    nu_c = 1e-9
    p = BI(B=B, fc=nu_c * FREQ)
    avar = 2 * p.wv(30, FREQ)
    m = 2.0 ** np.arange(30)
    flat = (m >= 8) & (m * nu_c <= 1e-2)  # 1/freq << tau << 0.01/fc
    assert flat.sum() >= 15
    np.testing.assert_allclose(avar[flat], BI_FACTOR**2 * B**2, rtol=3e-3)
    np.testing.assert_allclose(np.sqrt(avar[flat]), BI_FACTOR_IEEE * B, rtol=3e-3)


def test_half_floor_time_constant_used_by_start() -> None:
    m = 2**20
    p = BI(B=1.0, fc=HALF_FLOOR_TAU_FC * FREQ / m)  # tau_21 * fc = 0.70 exactly
    ratio = p.wv(21, FREQ)[-1] / (math.log(2) / math.pi)
    assert ratio == pytest.approx(0.5, abs=0.01)


# ---------------------------------------------------------------------------- simulation
def test_simulation_mean_wv_matches_theory_within_monte_carlo_error() -> None:
    p = BI(B=1.0, fc=FREQ / 2000)
    n, reps, levels = 2**13, 40, 8
    rng = np.random.default_rng(11)
    est = np.array([wvar(p.simulate(n, FREQ, g), FREQ, levels=levels).wv for g in rng.spawn(reps)])
    mean, se = est.mean(axis=0), est.std(axis=0, ddof=1) / math.sqrt(reps)
    theory = p.wv(levels, FREQ)
    assert np.all(np.abs(mean - theory) < 4.5 * se)
    # sample variance about the sample mean: E = gamma(0) - var(mean), var(mean) = V(n) / n^2
    n = 4096
    g = p.autocovariance(np.arange(n), FREQ)
    expected = g[0] - (n * g[0] + 2 * np.dot(n - np.arange(1, n), g[1:])) / n**2
    var = np.array([np.var(p.simulate(n, FREQ, r)) for r in rng.spawn(reps)])
    assert abs(var.mean() - expected) < 4.5 * var.std(ddof=1) / math.sqrt(reps)


def test_simulation_reproduces_the_allan_floor_with_allantools() -> None:
    # peer: allantools's overlapping Allan deviation of seeded BI paths
    B, fc = 4e-4, FREQ * 1e-6
    p = BI(B=B, fc=fc)
    taus = np.array([0.16, 0.64, 2.56])
    rng = np.random.default_rng(5)
    adev = np.array([allantools.oadev(p.simulate(2**15, FREQ, g), rate=FREQ, data_type="freq",
                                      taus=taus)[1] for g in rng.spawn(12)])
    assert adev.shape == (12, 3)
    mean = adev.mean(axis=0)
    theory = np.sqrt(2 * p.wv(9, FREQ))[[4, 6, 8]]  # tau = 16, 64, 256 samples
    se = adev.std(axis=0, ddof=1) / math.sqrt(12)
    assert np.all(np.abs(mean - theory) < 4.5 * se + 0.02 * theory)
    np.testing.assert_allclose(theory, BI_FACTOR_IEEE * B, rtol=5e-3)


def test_simulation_is_reproducible_and_any_length() -> None:
    p = BI.example(FREQ)
    np.testing.assert_array_equal(p.simulate(777, FREQ, 3),
                                  p.simulate(777, FREQ, np.random.default_rng(3)))
    assert p.simulate(1, FREQ, 0).shape == (1,)
    assert p.simulate(2, FREQ, 0).shape == (2,)


def test_circulant_embedding_refuses_an_invalid_autocovariance() -> None:
    with pytest.raises(EstimationError, match="negative eigenvalue"):
        # gamma = 1, 0.99, -0.9, -0.9, ...: not a valid autocovariance
        circulant_embedding(lambda t: np.select([t == 0, t == 1], [1.0, 0.99], -0.9),
                            16, np.random.default_rng(0))


# ---------------------------------------------------------------------------- state space
def test_block_is_the_closed_form_of_the_fitted_gms() -> None:
    p = BI.example(FREQ)
    approx = p.gm_approximation(FREQ)
    for dt in (1 / FREQ, 0.37, 5.0):
        block = p.block(dt, FREQ)
        phi = np.exp(-approx.beta * dt)
        np.testing.assert_allclose(block.Phi, np.diag(phi), rtol=1e-12, atol=1e-300)
        np.testing.assert_allclose(block.Q, np.diag(approx.sigma2 * (1 - phi**2)), rtol=1e-10,
                                   atol=1e-300)
        np.testing.assert_allclose(block.P0, np.diag(approx.sigma2), rtol=1e-15)
        np.testing.assert_array_equal(block.H, np.ones(DEFAULT_N_GM))
    one, seven = p.block(1 / FREQ, FREQ), p.block(7 / FREQ, FREQ)
    Phi, Q = compose_steps(one.Phi, one.Q, 7)
    np.testing.assert_allclose(seven.Phi, Phi, rtol=1e-12)
    np.testing.assert_allclose(seven.Q, Q, rtol=1e-10, atol=1e-15)


def test_gm_approximation_error_is_what_the_state_space_model_has() -> None:
    # the WV of the stacked GM blocks, by the exact Haar sum over their autocovariance
    p = BI(B=3.0, fc=FREQ * 2e-5)
    approx = p.gm_approximation(FREQ)
    block = p.block(1 / FREQ, FREQ)
    phis = np.diag(block.Phi)
    levels = approx.levels
    p0 = np.diag(block.P0)
    ss = wv_from_autocovariance(lambda t: (p0 * phis ** np.abs(t)[:, None]).sum(1), 16)
    rel = ss / p.wv(16, FREQ) - 1
    np.testing.assert_allclose(rel, approx.rel_error[:16], atol=1e-9)
    assert levels >= 20 and approx.max_rel_error == np.max(np.abs(approx.rel_error))


@pytest.mark.parametrize(("decades", "n_gm", "bound"), [
    (2, 6, 1e-5), (3, 6, 5e-4), (4, 6, 5e-3), (5, 6, 1.5e-2), (6, 8, 7e-3),
])
def test_gm_approximation_bounds_stated_in_the_docs(decades: int, n_gm: int, bound: float) -> None:
    p = BI(B=1.0, fc=FREQ / 2 / 10**decades, n_gm=n_gm)
    approx = p.gm_approximation(FREQ)
    assert approx.beta.shape == approx.sigma2.shape == (n_gm,)
    assert np.all(approx.sigma2 >= 0) and np.all(np.diff(approx.beta) > 0)
    assert approx.max_rel_error < bound
    assert "max relative WV error" in approx.summary()


def test_augment_names_the_gm_states() -> None:
    model = model_from_spec("BI(3)+WN", FREQ).with_vector([1e-3, 0.01, 1e-4])
    aug = model.augment(0.5)
    assert aug.state_names == ("BI.gm1", "BI.gm2", "BI.gm3")
    assert aug.white_var == pytest.approx(1e-4)
    assert aug.Phi.shape == (3, 3)


# ---------------------------------------------------------------------------- physical, start
def test_physical_constructors_round_trip() -> None:
    p = BI.from_correlation_time(2e-5, 300.0)
    phys = p.physical(FREQ)
    assert phys["Tc"].value == pytest.approx(300.0, rel=1e-14)
    assert phys["floor"].value == pytest.approx(0.6642824702 * 2e-5, rel=1e-9)  # sqrt(2 ln2/pi)
    q = BI.from_allan_floor(phys["floor"].value, p.fc)
    assert q.B == pytest.approx(p.B, rel=1e-14)
    r = BI.from_datasheet(10.0, "deg/h", 5.0, "min")
    assert r.B == pytest.approx(10 * math.pi / 180 / 3600, rel=1e-14)
    assert r.physical(FREQ)["Tc"].value == pytest.approx(300.0, rel=1e-14)


@pytest.mark.parametrize("nu_c", [1e-6, 3e-5])
def test_start_recovers_b_and_fc_from_a_theoretical_wv(nu_c: float) -> None:
    B, fc = 2e-3, nu_c * FREQ
    wv = BI(B=B, fc=fc).wv(24, FREQ) + WN(sigma2=1e-6).wv(24, FREQ)
    guess = BI().start(wv, FREQ)
    assert guess.B == pytest.approx(B, rel=0.03)
    assert guess.fc == pytest.approx(fc, rel=0.15)
    spread = [BI().start(wv, FREQ, index=i, count=2) for i in range(2)]
    assert spread[0].fc < spread[1].fc
    assert BI().start(wv, FREQ, rng=np.random.default_rng(0)).fc != guess.fc


# ---------------------------------------------------------------------------- specs and bad input
def test_spec_round_trips() -> None:
    model = model_from_spec("BI+WN", FREQ)
    assert model.name == "BI+WN" and model.processes[0].n_gm is None
    four = model_from_spec("BI(4)+WN", FREQ)
    assert four.processes[0].n_gm == 4 and four.name == "BI(4)+WN"
    valued = model_from_spec("BI(B=1e-4, fc=0.01, n_gm=3)", FREQ)
    spec = json.loads(json.dumps(valued.to_spec()))
    assert spec["processes"][0] == {"family": "BI", "params": {"B": 1e-4, "fc": 0.01}, "n_gm": 3}
    assert model_from_spec(spec) == valued
    assert model_from_spec(json.loads(json.dumps(model.to_spec()))) == model


@pytest.mark.parametrize("kwargs", [{"B": -1.0}, {"B": 0.0}, {"fc": 0.0}, {"fc": math.nan},
                                    {"B": math.inf}])
def test_out_of_domain_values_raise(kwargs: dict) -> None:
    with pytest.raises(DomainError, match="BI"):
        BI(**kwargs)


def test_bad_input_raises() -> None:
    with pytest.raises(SpecError, match="n_gm"):
        BI(n_gm=0)
    with pytest.raises(SpecError, match="n_gm"):
        BI(n_gm=2.5)
    with pytest.raises(SpecError, match="free"):
        BI(B=1.0).wv(3, FREQ)
    with pytest.raises(DomainError, match="Tc"):
        BI.from_correlation_time(1.0, -2.0)
    with pytest.raises(InputError):
        BI.from_datasheet(1.0, "deg/h", 10.0, "m")  # a length is not a time
    with pytest.raises(InputError, match="levels"):
        BI.example(FREQ).wv(0, FREQ)
    with pytest.raises(InputError, match="freq"):
        BI.example(FREQ).psd([1.0], -1.0)
    with pytest.raises(InputError, match="rng"):
        BI.example(FREQ).simulate(10, FREQ, None)
    for bad in ([], [1.0, -1.0, 2.0], [1.0, math.nan]):
        with pytest.raises(InputError, match="BI.start"):
            BI().start(np.array(bad), FREQ)
