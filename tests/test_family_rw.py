"""Tests of the RW family (plugins/stochmod_rw).

Truth: the exact variance of Haar-filtered random-walk increments, ``sigma2 sum_l c_l^2`` with
``c`` the partial sums of the explicit Haar filter, in mpmath or exact integers; the same for
other wavelets from their explicit MODWT filters; the PSD as ``sigma2 / (freq |1 - e^{-iw}|^2)``
in mpmath; Van Loan blocks against the closed form ``Phi = 1, Q = sigma2 freq dt`` and against
composed steps; seeded simulations (Monte Carlo means within their standard error);
allantools's Allan variance of simulated walks (peer) for the relation ``K^2 = sigma2 freq``.
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
from stochmod.core.process import simulate_block
from stochmod.core.filters import modwt_filter
from stochmod.empirical.wavelet_variance import wvar
from stochmod.core.statespace import compose_steps
from stochmod.core.theory import wv_from_psd
from stochmod_rw import RW
from stochmod_wn import WN

FREQ = 100.0
positive = st.floats(-150, 150).map(lambda e: 10.0**e)


def _exact_haar_sum_c2(m: int) -> mp.mpf:
    """sum_l c_l^2, c the partial sums of the Haar filter (+1/(2m) x m, -1/(2m) x m), in mpmath."""
    h = [mp.mpf(1) / (2 * m)] * m + [-mp.mpf(1) / (2 * m)] * m
    c, acc = [], mp.mpf(0)
    for tap in h:
        acc += tap
        c.append(acc)
    return mp.fsum(x * x for x in c)


@settings(max_examples=40, deadline=None)
@given(sigma2=positive, levels=st.integers(1, 10))
def test_haar_wv_equals_exact_variance_of_filtered_increments(sigma2: float, levels: int) -> None:
    wv = RW(sigma2=sigma2).wv(levels, FREQ)
    with mp.workdps(40):
        exact = [mp.mpf(sigma2) * _exact_haar_sum_c2(2 ** (j - 1)) for j in range(1, levels + 1)]
        err = max(abs((mp.mpf(w) - e) / e) for w, e in zip(wv, exact))
    assert err < 1e-13


@pytest.mark.parametrize("j", [12, 16, 20, 30, 45, 60])
def test_haar_wv_deep_levels_against_exact_integer_sums(j: int) -> None:
    # 4 m^2 sum c_l^2 = sum_{k<=m} k^2 + sum_{k<m} k^2 (the partial sums rise 1..m, fall m-1..0):
    # brute force in integers up to m = 2^15, Faulhaber's identity n(n+1)(2n+1)/6 beyond
    m = 2 ** (j - 1)
    if m <= 2**15:
        s = sum(k * k for k in range(m + 1)) + sum(k * k for k in range(m))
    else:
        s = m * (m + 1) * (2 * m + 1) // 6 + (m - 1) * m * (2 * m - 1) // 6
    exact = Fraction(s, 4 * m * m) * Fraction(3)  # sigma2 = 3
    got = RW(sigma2=3.0).wv(j, FREQ)[-1]
    assert abs(Fraction(got) / exact - 1) < Fraction(1, 10**13)


def test_haar_wv_is_the_allan_variance_of_the_continuous_walk_at_large_m() -> None:
    # AV = 2 wv -> K^2 tau / 3 with K^2 = sigma2 freq (IEEE): the ratio tends to 1 like 1/(2 m^2)
    p = RW(sigma2=2.5e-3)
    K = p.physical(FREQ)["K"].value
    m = 2.0 ** np.arange(40)
    ratio = 2 * p.wv(40, FREQ) / (K**2 * (m / FREQ) / 3)
    assert ratio[0] == pytest.approx(1.5, rel=1e-14)  # m = 1: (2 + 1) / 2
    assert ratio[-1] == pytest.approx(1.0, abs=1e-15)
    assert np.all(np.diff(ratio[:25]) < 0) and np.all(np.diff(ratio) <= 0)


def test_allan_variance_of_simulated_walks_matches_K_via_allantools() -> None:
    # peer: allantools's overlapping AV of seeded walks vs K^2 tau / 3 (+ sigma2 / (6 m)),
    # K^2 = sigma2 freq
    K, n, reps = 0.02, 2**13, 60
    p = RW.from_rrw(K, FREQ)
    ms = np.array([16, 64, 256])
    avs = []
    for g in np.random.default_rng(11).spawn(reps):
        taus, adev, _, _ = allantools.oadev(p.simulate(n, FREQ, g), rate=FREQ, data_type="freq",
                                            taus=ms / FREQ)
        avs.append(adev**2)
    avs = np.array(avs)
    mean, se = avs.mean(0), avs.std(0, ddof=1) / math.sqrt(reps)
    expected = K**2 * taus / 3 + p.sigma2 / (6 * ms)
    assert np.all(np.abs(mean - expected) < 4 * se)


@settings(max_examples=40, deadline=None)
@given(sigma2=positive, freq=st.floats(1e-3, 1e4), x=st.floats(1e-9, 0.5))
def test_psd_is_sigma2_over_freq_times_squared_gain_of_the_integrator(sigma2: float, freq: float,
                                                                      x: float) -> None:
    got = RW(sigma2=sigma2).psd(np.array([x * freq, -x * freq]), freq)
    with mp.workdps(40):
        z = mp.exp(-2j * mp.pi * mp.mpf(x))
        exact = mp.mpf(sigma2) / (mp.mpf(freq) * abs(1 - z) ** 2)
    assert got[0] == pytest.approx(float(exact), rel=1e-10)
    assert got[1] == got[0]


def test_psd_quadrature_reproduces_the_haar_wv() -> None:
    # the generalised PSD is the one whose Haar-filter integral is the exact WV (|C| = |H|/|1 - z|)
    p = RW(sigma2=0.7)
    quad = wv_from_psd(lambda f: p.psd(f, FREQ), 14, FREQ)
    np.testing.assert_allclose(p.wv(14, FREQ), quad, rtol=1e-9)


def _exact_wv_any_wavelet(sigma2: float, j: int, wavelet: str) -> float:
    c = np.cumsum(modwt_filter(j, wavelet))
    return sigma2 * float(np.sum(c * c))


@pytest.mark.parametrize("wavelet", ["db1", "db2", "db4", "sym4", "coif2"])
def test_other_wavelets_fall_back_to_the_psd(wavelet: str) -> None:
    p = RW(sigma2=2.0)
    exact = [_exact_wv_any_wavelet(2.0, j, wavelet) for j in range(1, 8)]
    np.testing.assert_allclose(p.wv(7, FREQ, wavelet), exact, rtol=1e-9)


@settings(max_examples=30, deadline=None)
@given(levels=st.integers(1, 12))
def test_jacobian_is_the_exact_filter_energy(levels: int) -> None:
    jac = RW(sigma2=4.0).wv_jacobian(levels, FREQ)
    assert jac.shape == (levels, 1)
    with mp.workdps(30):
        exact = [float(_exact_haar_sum_c2(2 ** (j - 1))) for j in range(1, levels + 1)]
    np.testing.assert_allclose(jac[:, 0], exact, rtol=1e-14)


@settings(max_examples=30, deadline=None)
@given(sigma2=positive, freq=st.floats(1e-2, 1e4), dt=st.floats(1e-4, 1e3), k=st.integers(2, 50))
def test_blocks_are_exact_at_any_step(sigma2: float, freq: float, dt: float, k: int) -> None:
    p = RW(sigma2=sigma2)
    b = p.block(dt, freq)
    assert b.state_names == ("value",)
    np.testing.assert_allclose(b.Phi, [[1.0]], rtol=1e-14)
    np.testing.assert_allclose(b.Q, [[sigma2 * freq * dt]], rtol=1e-12)
    np.testing.assert_array_equal(b.P0, [[0.0]])
    np.testing.assert_array_equal(b.H, [1.0])
    assert b.white_var == 0.0
    np.testing.assert_allclose(p.discrete_block(freq).Q, [[sigma2]], rtol=1e-12)
    Phi, Q = compose_steps(b.Phi, b.Q, k)
    big = p.block(k * dt, freq)
    np.testing.assert_allclose(big.Phi, Phi, rtol=1e-12)
    np.testing.assert_allclose(big.Q, Q, rtol=1e-10)
    cont = p.continuous_block(freq)
    np.testing.assert_array_equal([cont.F[0, 0], cont.G[0, 0]], [0.0, 1.0])
    assert cont.Qc[0, 0] == pytest.approx(sigma2 * freq, rel=1e-15)


def _mean_wv(simulate, reps: int, n: int, levels: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    wvs = np.array([wvar(simulate(g), FREQ, levels=levels).wv
                    for g in np.random.default_rng(seed).spawn(reps)])
    return wvs.mean(0), wvs.std(0, ddof=1) / math.sqrt(reps)


def test_simulation_mean_wv_matches_theory() -> None:
    p = RW(sigma2=0.3)
    mean, se = _mean_wv(lambda g: p.simulate(4096, FREQ, g), 40, 4096, 8, 3)
    assert np.all(np.abs(mean - p.wv(8, FREQ)) < 4 * se)


def test_state_space_simulation_matches_direct_simulation_in_wv() -> None:
    p = RW(sigma2=0.3)
    block = p.discrete_block(FREQ)
    mean, se = _mean_wv(lambda g: simulate_block(block, 2048, g), 30, 2048, 7, 5)
    assert np.all(np.abs(mean - p.wv(7, FREQ)) < 4 * se)


def test_simulation_starts_at_zero_with_gaussian_increments_and_reproduces() -> None:
    p = RW(sigma2=0.25)
    x = p.simulate(20000, FREQ, 7)
    assert x[0] == 0.0 and x.shape == (20000,)
    d = np.diff(x)
    se = 0.25 * math.sqrt(2 / d.size)  # standard error of the sample variance of normals
    assert abs(np.mean(d * d) - 0.25) < 4 * se
    np.testing.assert_array_equal(x, p.simulate(20000, FREQ, np.random.default_rng(7)))
    np.testing.assert_array_equal(p.simulate(1, FREQ, 0), [0.0])


@settings(max_examples=40, deadline=None)
@given(K=positive, freq=st.floats(1e-3, 1e5))
def test_physical_round_trip(K: float, freq: float) -> None:
    p = RW.from_rrw(K, freq)
    assert p.sigma2 == pytest.approx(K * K / freq, rel=1e-14)
    assert p.physical(freq)["K"].value == pytest.approx(K, rel=1e-14)
    assert p.physical(freq)["K"].unit == "u/sqrt(s)"


def test_start_inverts_the_deepest_level() -> None:
    truth = WN(sigma2=1.0) + RW(sigma2=1e-4)
    wv = truth.bind(FREQ).wv(15)
    guess = RW().start(wv, FREQ)
    assert guess.sigma2 == pytest.approx(1e-4, rel=2e-4)  # WN leaves 1/(2m) at m = 2^14
    assert RW().start(RW(sigma2=0.5).wv(9, FREQ), FREQ).sigma2 == pytest.approx(0.5, rel=1e-14)
    second = RW().start(RW(sigma2=0.5).wv(9, FREQ), FREQ, index=1, count=2)
    assert second.sigma2 == pytest.approx(0.25, rel=1e-14)
    a = RW().start(wv, FREQ, rng=np.random.default_rng(1))
    b = RW().start(wv, FREQ, rng=np.random.default_rng(1))
    assert a == b and a.sigma2 != guess.sigma2 and a.sigma2 > 0


def test_example_is_visible_next_to_unit_white_noise_in_2_16_samples() -> None:
    ex, wn = RW.example(FREQ), WN(sigma2=1.0)
    rw_wv, wn_wv = ex.wv(15, FREQ), wn.wv(15, FREQ)
    assert rw_wv[0] < wn_wv[0]
    assert np.all(rw_wv[9:] > 5 * wn_wv[9:])  # levels 10..15 (m >= 512) fit in 2^16 samples


@pytest.mark.parametrize("bad", [-1.0, 0.0, math.nan, math.inf])
def test_bad_values_raise_domain_error(bad: float) -> None:
    with pytest.raises(DomainError, match="sigma2"):
        RW(sigma2=bad)


def test_bad_inputs_raise() -> None:
    p = RW(sigma2=1.0)
    with pytest.raises(InputError, match="stationary"):
        p.autocovariance([0, 1], FREQ)
    with pytest.raises(InputError, match="levels"):
        p.wv(0, FREQ)
    with pytest.raises(InputError, match="freq"):
        p.wv(3, -1.0)
    with pytest.raises(InputError, match="n"):
        p.simulate(0, FREQ, 0)
    with pytest.raises(InputError, match="rng"):
        p.simulate(10, FREQ, None)
    with pytest.raises(SpecError, match="free"):
        RW().wv(3, FREQ)
    with pytest.raises(InputError, match="K"):
        RW.from_rrw(-1.0, FREQ)
    with pytest.raises(DomainError, match="sigma2"):
        RW.from_rrw(0.0, FREQ)
    with pytest.raises(InputError, match="wv"):
        RW().start(np.array([1.0, 0.0]), FREQ)
    with pytest.raises(InputError, match="wv"):
        RW().start(np.array([]), FREQ)


def test_spec_round_trip_and_model_sum() -> None:
    model = model_from_spec("RW(sigma2=1e-4)+WN(sigma2=1.0)", FREQ)
    assert model.processes[0] == RW(sigma2=1e-4)
    again = model_from_spec(model.to_spec())
    assert again == model
    parts = RW(sigma2=1e-4).wv(8, FREQ) + WN(sigma2=1.0).wv(8, FREQ)
    np.testing.assert_allclose(model.wv(8), parts, rtol=1e-15)
    aug = model.augment(0.5)
    assert aug.state_names == ("RW.value",)
    assert aug.Q[0, 0] == pytest.approx(1e-4 * FREQ * 0.5, rel=1e-12)
    assert aug.white_var == 1.0
