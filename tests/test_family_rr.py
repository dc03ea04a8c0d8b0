"""Tests of the RR family (plugins/stochmod_rr).

Truth: the Haar (and any MODWT) coefficient of the ramp ``s t`` computed term by term with the
explicit filter in mpmath (or exact integer sums at deep levels); the conditional identity
``W = s m / 2`` on simulated paths through stochmod's wavelet variance; the slope's chi-square
law over seeded replications; the closed-form ramp transition ``[[1, dt], [0, 1]]``;
allantools's Allan variance of a ramp of known slope (peer) for ``R^2 tau^2 / 2``.
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
from scipy import integrate

from stochmod import model_from_spec
from stochmod.core.errors import DomainError, InputError, SpecError
from stochmod.core.process import simulate_block
from stochmod.core.filters import modwt_filter
from stochmod.empirical.wavelet_variance import wvar
from stochmod.core.statespace import compose_steps
from stochmod.core.theory import squared_gain
from stochmod_rr import RR
from stochmod_wn import WN

FREQ = 100.0
positive = st.floats(-100, 100).map(lambda e: 10.0**e)


def _haar_ramp_coefficient(m: int, t: int = 0) -> mp.mpf:
    """W = sum_l h_l (t - l) for the explicit Haar filter (+1/(2m) x m, -1/(2m) x m), in mpmath."""
    return mp.fsum((mp.mpf(1) if l < m else -mp.mpf(1)) / (2 * m) * (t - l) for l in range(2 * m))


@settings(max_examples=40, deadline=None)
@given(omega=positive, levels=st.integers(1, 10), t0=st.integers(0, 10**6))
def test_haar_wv_is_the_squared_filtered_ramp(omega: float, levels: int, t0: int) -> None:
    # E[W^2] = omega^2 (sum_l h_l (t - l))^2 for the explicit Haar filter, at any time t >= 2m - 1
    wv = RR(omega=omega).wv(levels, FREQ)
    with mp.workdps(40):
        for j, w in enumerate(wv, start=1):
            m = 2 ** (j - 1)
            exact = mp.mpf(omega) ** 2 * _haar_ramp_coefficient(m, t0 + 2 * m - 1) ** 2
            assert abs(mp.mpf(w) / exact - 1) < 1e-13


@pytest.mark.parametrize("j", [12, 18, 30, 50])
def test_haar_wv_deep_levels_by_exact_integer_sums(j: int) -> None:
    m = 2 ** (j - 1)
    if m <= 2**17:
        moment = sum(range(m)) - sum(range(m, 2 * m))
    else:  # Gauss's sums
        moment = m * (m - 1) // 2 - (m * (3 * m - 1) // 2)
    exact = Fraction(moment, 2 * m) ** 2 * Fraction(9, 4)  # omega = 1.5
    assert abs(Fraction(RR(omega=1.5).wv(j, FREQ)[-1]) / exact - 1) < Fraction(1, 10**14)


@pytest.mark.parametrize("wavelet", ["db1", "db2", "db4", "sym4", "coif1"])
def test_other_wavelets_use_the_explicit_filter_moment(wavelet: str) -> None:
    # a filter with >= 2 vanishing moments annihilates the ramp; db1 is Haar
    exact = np.array([0.7**2 * np.dot(np.arange(h.size), h) ** 2
                      for h in (modwt_filter(j, wavelet) for j in range(1, 7))])
    got = RR(omega=0.7).wv(6, FREQ, wavelet)
    np.testing.assert_allclose(got, exact, rtol=1e-12, atol=1e-18)
    if wavelet != "db1":
        assert np.all(got == 0.0)


def test_conditional_identity_on_simulated_paths() -> None:
    # given the slope s, every Haar coefficient is s m / 2, so the empirical WV is s^2 m^2 / 4
    p = RR(omega=0.02)
    for seed in range(5):
        x = p.simulate(5000, FREQ, seed)
        s = x[1]
        np.testing.assert_allclose(x, s * np.arange(5000), rtol=1e-15)
        m = 2.0 ** np.arange(10)
        np.testing.assert_allclose(wvar(x, FREQ, levels=10).wv, s * s * m * m / 4, rtol=1e-9)


def test_mean_wv_over_replications_matches_theory() -> None:
    # s^2 / omega^2 is chi-square(1): mean 1, sd sqrt(2); 400 replications of 128 samples
    p, reps = RR(omega=3e-3), 400
    paths = [p.simulate(128, FREQ, g) for g in np.random.default_rng(8).spawn(reps)]
    s2 = np.array([x[1] ** 2 for x in paths])
    assert abs(s2.mean() - 9e-6) < 4 * 9e-6 * math.sqrt(2 / reps)
    wvs = np.array([wvar(x, FREQ, levels=6).wv for x in paths])
    se = wvs.std(0, ddof=1) / math.sqrt(reps)
    assert np.all(np.abs(wvs.mean(0) - p.wv(6, FREQ)) < 4 * se)


@settings(max_examples=30, deadline=None)
@given(omega=positive, freq=st.floats(1e-2, 1e4), dt=st.floats(1e-4, 1e3), k=st.integers(2, 50))
def test_blocks_are_exact_at_any_step(omega: float, freq: float, dt: float, k: int) -> None:
    p = RR(omega=omega)
    b = p.block(dt, freq)
    assert b.state_names == ("ramp", "slope")
    np.testing.assert_allclose(b.Phi, [[1.0, dt], [0.0, 1.0]], rtol=1e-13, atol=1e-15)
    np.testing.assert_array_equal(b.Q, np.zeros((2, 2)))
    np.testing.assert_allclose(b.P0, np.diag([0.0, (omega * freq) ** 2]), rtol=1e-14)
    np.testing.assert_array_equal(b.H, [1.0, 0.0])
    assert b.white_var == 0.0
    Phi, Q = compose_steps(b.Phi, b.Q, k)
    big = p.block(k * dt, freq)
    np.testing.assert_allclose(big.Phi, Phi, rtol=1e-12, atol=1e-12 * k * dt)
    np.testing.assert_array_equal(big.Q, Q)
    cont = p.continuous_block(freq)
    np.testing.assert_array_equal(cont.F, [[0.0, 1.0], [0.0, 0.0]])
    assert cont.G.shape == (2, 1) and not cont.G.any()
    assert cont.Qc.shape == (1, 1) and not cont.Qc.any()


def test_state_space_paths_are_ramps_with_the_slope_law() -> None:
    p, reps = RR(omega=0.01), 300
    block = p.discrete_block(FREQ)
    slopes = []
    for g in np.random.default_rng(2).spawn(reps):
        y = simulate_block(block, 64, g)
        assert y[0] == 0.0
        np.testing.assert_allclose(y, y[1] * np.arange(64), rtol=1e-12, atol=1e-18)
        slopes.append(y[1])
    s2 = np.square(slopes)
    assert abs(s2.mean() - 1e-4) < 4 * 1e-4 * math.sqrt(2 / reps)


def test_allan_variance_of_a_ramp_via_allantools() -> None:
    # peer: a deterministic ramp of slope R (u/s) has AV R^2 tau^2 / 2; RR.from_rate_ramp(R)
    # expects it
    R = 0.4
    x = R * np.arange(4096) / FREQ
    taus, adev, _, _ = allantools.oadev(x, rate=FREQ, data_type="freq",
                                        taus=np.array([1, 8, 64]) / FREQ)
    np.testing.assert_allclose(adev**2, R**2 * taus**2 / 2, rtol=1e-9)
    p = RR.from_rate_ramp(R, FREQ)
    m = 2.0 ** np.arange(8)
    np.testing.assert_allclose(2 * p.wv(8, FREQ), R**2 * (m / FREQ) ** 2 / 2, rtol=1e-14)


def test_nominal_psd_limits_the_haar_integral_diverges() -> None:
    # documented limit: |H_1|^2 ~ (pi f)^2 near 0 against S ~ f^-3 gives a log divergence, so the
    # integral over [eps, 1/2] grows by the same amount per halving of eps
    p = RR(omega=1.0)
    f = np.array([1.0, 2.0, 7.0])
    assert np.all(p.psd(f, FREQ) > 0) and np.array_equal(p.psd(-f, FREQ), p.psd(f, FREQ))

    def integral(eps: float) -> float:
        def g(x: float) -> float:
            gain = squared_gain(np.array([x]), 1)[0]
            return float(gain * p.psd(np.array([x * FREQ]), FREQ)[0] * FREQ)
        edges = [eps * 2.0**k for k in range(int(math.log2(0.5 / eps)) + 1)] + [0.5]
        return sum(integrate.quad(g, a, b, epsrel=1e-12)[0] for a, b in zip(edges[:-1], edges[1:]))

    steps = np.diff([integral(2.0**-k) for k in (20, 21, 22, 23)])
    assert np.all(steps > 0)
    np.testing.assert_allclose(steps, steps[0], rtol=1e-4)


@settings(max_examples=30, deadline=None)
@given(omega=positive)
def test_jacobian_is_the_derivative_of_the_exact_wv(omega: float) -> None:
    jac = RR(omega=omega).wv_jacobian(12, FREQ)[:, 0]
    # central differences (exact for a quadratic) of omega^2 W_j^2, W_j the filtered ramp
    with mp.workdps(60):
        w, h = mp.mpf(omega), mp.mpf(omega) * mp.mpf("1e-20")
        exact = [((w + h) ** 2 - (w - h) ** 2) / (2 * h) * _haar_ramp_coefficient(2 ** (j - 1)) ** 2
                 for j in range(1, 13)]
    np.testing.assert_allclose(jac, [float(e) for e in exact], rtol=1e-12)


@settings(max_examples=40, deadline=None)
@given(R=positive, freq=st.floats(1e-3, 1e5))
def test_physical_round_trip(R: float, freq: float) -> None:
    p = RR.from_rate_ramp(R, freq)
    assert p.physical(freq)["R"].value == pytest.approx(R, rel=1e-14)
    assert p.physical(freq)["R"].unit == "u/s"


def test_start_inverts_the_deepest_level() -> None:
    truth = (WN(sigma2=1.0) + RR(omega=1e-4)).bind(FREQ)
    assert RR().start(truth.wv(15), FREQ).omega == pytest.approx(1e-4, rel=5e-5)  # WN: 1/(2m)
    wv = RR(omega=0.2).wv(6, FREQ)
    assert RR().start(wv, FREQ).omega == pytest.approx(0.2, rel=1e-14)
    assert RR().start(wv, FREQ, index=2, count=4).omega == pytest.approx(0.1, rel=1e-14)
    a = RR().start(wv, FREQ, rng=np.random.default_rng(6))
    assert a == RR().start(wv, FREQ, rng=np.random.default_rng(6)) and a.omega != 0.2


def test_example_is_visible_next_to_unit_white_noise() -> None:
    rr, wn = RR.example(FREQ).wv(15, FREQ), WN(sigma2=1.0).wv(15, FREQ)
    assert np.all(rr[:9] < wn[:9]) and np.all(rr[10:] > 3 * wn[10:])


@pytest.mark.parametrize("bad", [-1.0, 0.0, math.nan, math.inf])
def test_bad_values_raise_domain_error(bad: float) -> None:
    with pytest.raises(DomainError, match="omega"):
        RR(omega=bad)
    with pytest.raises(DomainError, match="omega"):
        RR.from_rate_ramp(bad, FREQ)


def test_bad_inputs_raise() -> None:
    p = RR(omega=1.0)
    with pytest.raises(InputError, match="stationary"):
        p.autocovariance([0], FREQ)
    with pytest.raises(InputError, match="levels"):
        p.wv(1.5, FREQ)
    with pytest.raises(InputError, match="wavelet"):
        p.wv(3, FREQ, "bior2.2")
    with pytest.raises(InputError, match="freq"):
        RR.from_rate_ramp(1.0, 0.0)
    with pytest.raises(SpecError, match="free"):
        RR().simulate(5, FREQ, 0)
    with pytest.raises(InputError, match="wv"):
        RR().start(np.array([1.0, 0.0]), FREQ)


def test_spec_round_trip_and_augmentation() -> None:
    model = model_from_spec("RR(omega=1e-4)+WN(sigma2=1)", FREQ)
    assert model.processes[0] == RR(omega=1e-4)
    assert model_from_spec(model.to_spec()) == model
    aug = model.augment(0.1)
    assert aug.state_names == ("RR.ramp", "RR.slope")
    np.testing.assert_allclose(aug.Phi, [[1.0, 0.1], [0.0, 1.0]], rtol=1e-13)
    np.testing.assert_allclose(aug.P0, np.diag([0.0, (1e-4 * FREQ) ** 2]), rtol=1e-14)
