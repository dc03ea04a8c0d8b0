"""Tests of the QN family (plugins/stochmod_qn).

Truth: the autocovariance of ``sqrt(12 Q2)(U_t - U_{t-1})`` from its definition (var U = 1/12,
computed in mpmath), the exact Haar sum ``sum_t a_m(t) gamma(t)`` with the kernel taken from
the explicit Haar filter in mpmath (and by exact counting at deep levels); the PSD as the
Fourier series of that autocovariance; explicit MODWT filters for other wavelets; seeded
simulations; allantools's Allan variance of simulated QN (peer) for ``3 Q^2 / tau^2``.
"""

from __future__ import annotations

import math
from fractions import Fraction

import allantools
import mpmath as mp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stochmod import model_from_spec
from stochmod.core.errors import DomainError, InputError, SpecError
from stochmod.core.filters import modwt_filter
from stochmod.empirical.wavelet_variance import wvar
from stochmod.core.theory import wv_from_psd
from stochmod_qn import QN
from stochmod_wn import WN

FREQ = 100.0
positive = st.floats(-150, 150).map(lambda e: 10.0**e)


def _gamma(Q2: mp.mpf) -> tuple[mp.mpf, mp.mpf]:
    """gamma(0), gamma(1) of sqrt(12 Q2)(U_t - U_{t-1}) with var U = int_0^1 (u - 1/2)^2 du."""
    var_u = mp.quad(lambda u: (u - mp.mpf(1) / 2) ** 2, [0, 1])
    return 12 * Q2 * 2 * var_u, -12 * Q2 * var_u


def _haar_kernel_mp(m: int) -> list[mp.mpf]:
    """a(t) = sum_l h_l h_{l+t} of the explicit Haar filter, t = 0..2m-1, in mpmath."""
    h = [mp.mpf(1) / (2 * m)] * m + [-mp.mpf(1) / (2 * m)] * m
    return [mp.fsum(h[l] * h[l + t] for l in range(2 * m - t)) for t in range(2 * m)]


@settings(max_examples=30, deadline=None)
@given(Q2=positive, levels=st.integers(1, 7))
def test_haar_wv_equals_exact_kernel_sum(Q2: float, levels: int) -> None:
    wv = QN(Q2=Q2).wv(levels, FREQ)
    with mp.workdps(40):
        g0, g1 = _gamma(mp.mpf(Q2))
        gamma = lambda t: g0 if t == 0 else (g1 if t == 1 else mp.mpf(0))  # noqa: E731
        for j, w in enumerate(wv, start=1):
            a = _haar_kernel_mp(2 ** (j - 1))
            exact = a[0] * gamma(0) + 2 * mp.fsum(a[t] * gamma(t) for t in range(1, len(a)))
            assert abs(mp.mpf(w) / exact - 1) < 1e-13


@pytest.mark.parametrize("j", [1, 2, 10, 20, 40, 60])
def test_haar_wv_deep_levels_by_exact_counting(j: int) -> None:
    # a(0) = 2m taps of 1/(2m)^2; a(1): 2m - 2 same-sign neighbours, 1 sign change
    m = 2 ** (j - 1)
    a0 = Fraction(2 * m, 4 * m * m)
    a1 = Fraction((2 * m - 2) - 1, 4 * m * m) if m > 1 else Fraction(-1, 4)
    exact = Fraction(7) * (a0 * 2 - 2 * a1)  # Q2 = 7: gamma(0) = 14, gamma(1) = -7
    got = QN(Q2=7.0).wv(j, FREQ)[-1]
    assert abs(Fraction(got) / exact - 1) < Fraction(1, 10**14)


@settings(max_examples=40, deadline=None)
@given(Q2=positive, freq=st.floats(1e-3, 1e4), x=st.floats(0.0, 0.5))
def test_psd_is_the_fourier_series_of_the_autocovariance(Q2: float, freq: float, x: float) -> None:
    got = QN(Q2=Q2).psd(np.array([x * freq, -x * freq]), freq)
    with mp.workdps(40):
        g0, g1 = _gamma(mp.mpf(Q2))
        exact = (g0 + 2 * g1 * mp.cos(2 * mp.pi * mp.mpf(x))) / mp.mpf(freq)
    assert got[0] == pytest.approx(float(exact), rel=1e-9, abs=1e-15 * Q2 / freq)
    assert got[1] == got[0]


@pytest.mark.parametrize("freq", [0.5, 100.0, 4000.0])
def test_psd_integrates_to_the_variance(freq: float) -> None:
    p = QN(Q2=0.3)
    with mp.workdps(30):
        total = mp.quad(lambda f: float(p.psd(np.array([float(f)]), freq)[0]),
                        [-freq / 2, 0, freq / 2])
    assert float(total) == pytest.approx(p.autocovariance([0], freq)[0], rel=1e-12)
    np.testing.assert_allclose(p.autocovariance([-2, -1, 0, 1, 2, 5], freq),
                               [0, -0.3, 0.6, -0.3, 0, 0])


def test_psd_quadrature_reproduces_the_haar_wv() -> None:
    p = QN(Q2=0.3)
    quad = wv_from_psd(lambda f: p.psd(f, FREQ), 14, FREQ)
    np.testing.assert_allclose(p.wv(14, FREQ), quad, rtol=1e-9)


@pytest.mark.parametrize("wavelet", ["db2", "db4", "sym4", "coif1"])
def test_other_wavelets_fall_back_to_the_psd(wavelet: str) -> None:
    # exact: the filter of the differenced uniform is the first difference of h_j (var U = 1/12)
    diffs = (np.diff(np.concatenate([[0.0], modwt_filter(j, wavelet), [0.0]])) for j in range(1, 7))
    exact = [2.0 * float(np.sum(d * d)) for d in diffs]
    np.testing.assert_allclose(QN(Q2=2.0).wv(6, FREQ, wavelet), exact, rtol=1e-9)


@settings(max_examples=20, deadline=None)
@given(levels=st.integers(1, 7))
def test_jacobian_is_the_exact_kernel_sum_per_unit_q2(levels: int) -> None:
    jac = QN(Q2=5.0).wv_jacobian(levels, FREQ)
    assert jac.shape == (levels, 1)
    with mp.workdps(30):
        exact = []
        for j in range(1, levels + 1):
            a = _haar_kernel_mp(2 ** (j - 1))
            exact.append(float(2 * a[0] - 2 * a[1]))  # d/dQ2 of a0 (2 Q2) + 2 a1 (-Q2)
    np.testing.assert_allclose(jac[:, 0], exact, rtol=1e-14)


def test_state_space_is_white_feed_through_with_the_variance() -> None:
    p = QN(Q2=0.4)
    for dt in (0.01, 0.5, 3.0):
        b = p.block(dt, FREQ)
        assert b.n_states == 0 and b.Phi.shape == (0, 0)
        assert b.white_var == pytest.approx(0.8, rel=1e-15)
    assert p.discrete_block(FREQ).white_var == pytest.approx(0.8, rel=1e-15)
    assert p.continuous_block(FREQ) is None


def test_simulation_is_a_difference_of_uniforms() -> None:
    # partial sums telescope: cumsum(x) / sqrt(12 Q2) = U_t - U_0 lies in (-1, 1), and as U_t is
    # uniform its range spans nearly the whole interval
    p = QN(Q2=0.25)
    x = p.simulate(50000, FREQ, 3)
    s = np.cumsum(x) / math.sqrt(12 * 0.25)
    assert np.all(np.abs(s) < 1) and np.ptp(s) > 0.999
    assert np.all(np.abs(x) < math.sqrt(12 * 0.25))
    np.testing.assert_array_equal(x, p.simulate(50000, FREQ, np.random.default_rng(3)))
    assert p.simulate(1, FREQ, 0).shape == (1,)


def test_simulated_autocovariance_matches() -> None:
    p, n = QN(Q2=0.5), 200000
    x = p.simulate(n, FREQ, 9)
    lags = np.array([np.mean(x * x), np.mean(x[1:] * x[:-1]), np.mean(x[2:] * x[:-2])])
    # var of x_t x_{t+k} products: bounded by E x^4 <= (12 Q2)^2; MC error ~ 12 Q2 sqrt(3 / n)
    se = 12 * 0.5 * math.sqrt(3 / n)
    np.testing.assert_allclose(lags, [1.0, -0.5, 0.0], atol=4 * se)


def test_simulation_mean_wv_matches_theory() -> None:
    p, reps = QN(Q2=0.5), 20
    wvs = np.array([wvar(p.simulate(4096, FREQ, g), FREQ, levels=8).wv
                    for g in np.random.default_rng(21).spawn(reps)])
    se = wvs.std(0, ddof=1) / math.sqrt(reps)
    assert np.all(np.abs(wvs.mean(0) - p.wv(8, FREQ)) < 4 * se)


def test_allan_variance_of_simulations_is_3_Q2_over_tau2_via_allantools() -> None:
    Q, reps = 0.003, 20
    p = QN.from_quantization(Q, FREQ)
    ms = np.array([1, 4, 16])
    avs = []
    for g in np.random.default_rng(5).spawn(reps):
        taus, adev, _, _ = allantools.oadev(p.simulate(8192, FREQ, g), rate=FREQ, data_type="freq",
                                            taus=ms / FREQ)
        avs.append(adev**2)
    avs = np.array(avs)
    se = avs.std(0, ddof=1) / math.sqrt(reps)
    assert np.all(np.abs(avs.mean(0) - 3 * Q**2 / taus**2) < 4 * se)


@settings(max_examples=40, deadline=None)
@given(Q=st.floats(-100, 100).map(lambda e: 10.0**e), freq=st.floats(1e-3, 1e5))
def test_physical_round_trip(Q: float, freq: float) -> None:
    p = QN.from_quantization(Q, freq)
    assert p.physical(freq)["Q"].value == pytest.approx(Q, rel=1e-14)
    assert p.physical(freq)["Q"].unit == "u*s"


def test_start_inverts_the_finest_level() -> None:
    wv = QN(Q2=0.6).wv(8, FREQ)
    assert QN().start(wv, FREQ).Q2 == pytest.approx(0.6, rel=1e-14)
    assert QN().start(wv, FREQ, index=1, count=2).Q2 == pytest.approx(0.3, rel=1e-14)
    a = QN().start(wv, FREQ, rng=np.random.default_rng(4))
    assert a == QN().start(wv, FREQ, rng=np.random.default_rng(4)) and a.Q2 != 0.6


def test_example_is_visible_next_to_unit_white_noise() -> None:
    qn, wn = QN.example(FREQ).wv(10, FREQ), WN(sigma2=1.0).wv(10, FREQ)
    assert np.all(qn[:3] > wn[:3]) and np.all(qn[4:] < wn[4:])


@pytest.mark.parametrize("bad", [-1.0, 0.0, math.nan, math.inf])
def test_bad_values_raise_domain_error(bad: float) -> None:
    with pytest.raises(DomainError, match="Q2"):
        QN(Q2=bad)
    with pytest.raises(DomainError, match="Q"):
        QN.from_quantization(bad, FREQ)


def test_bad_inputs_raise() -> None:
    p = QN(Q2=1.0)
    with pytest.raises(InputError, match="levels"):
        p.wv(0, FREQ)
    with pytest.raises(InputError, match="freq"):
        p.psd([1.0], 0.0)
    with pytest.raises(InputError, match="n"):
        p.simulate(-3, FREQ, 0)
    with pytest.raises(InputError, match="freq"):
        QN.from_quantization(1.0, math.nan)
    with pytest.raises(SpecError, match="free"):
        QN().autocovariance([0], FREQ)
    with pytest.raises(InputError, match="wv"):
        QN().start(np.array([-1.0, 2.0]), FREQ)
    with pytest.raises(InputError, match="wv"):
        QN().start(np.array([1.0, math.nan]), FREQ)


def test_spec_round_trip_and_model_sum() -> None:
    model = model_from_spec({"processes": [{"family": "QN", "params": {"Q2": 2.0}},
                                           {"family": "WN", "params": {"sigma2": 1.0}}]}, FREQ)
    assert model.processes[0] == QN(Q2=2.0)
    assert model_from_spec(model.to_spec()) == model
    assert model_from_spec("QN(Q2=2.0)+WN(sigma2=1)", FREQ) == model
    np.testing.assert_allclose(model.autocovariance([0, 1, 2]), [5.0, -2.0, 0.0])
    assert model.augment().white_var == pytest.approx(5.0)
