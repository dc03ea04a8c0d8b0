"""GM(beta, sigma2): closed forms against mpmath, state space, simulation, constructors, specs."""

from __future__ import annotations

import math
import sys

import mpmath as mp
import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from scipy import integrate

from stochmod import model_from_spec
from stochmod.core.errors import DomainError, InputError, SpecError
from stochmod.core.statespace import compose_steps
from stochmod.core.theory import wv_from_autocovariance, wv_from_psd
from stochmod.core.units import BI_FACTOR, BI_FACTOR_IEEE, DEG, HOUR
from stochmod_gm import GM, PEAK_X

LEVELS = (1, 2, 3, 6, 11, 12, 13, 17, 24, 30)


def mp_wv(beta: float, sigma2: float, freq: float, m: int):
    """sigma2 sum_{|t| < 2m} a_m(|t|) exp(-beta |t| / freq): exact finite sum at 50 digits up to
    m = 2^12, the textbook closed form in phi at 80 digits beyond (validated in test_geometric)."""
    with mp.workdps(80 if m > 2**12 else 50):
        phi = mp.exp(-mp.mpf(beta) / mp.mpf(freq))
        if m > 2**12:
            pm = phi**m
            w = (m * (1 - phi**2) - phi * (1 - pm) * (3 - pm)) / (2 * m * m * (1 - phi) ** 2)
        else:
            w, pt = mp.mpf(1) / (2 * m), mp.mpf(1)
            for t in range(1, 2 * m):
                pt *= phi
                w += 2 * mp.mpf(2 * m - 3 * t if t <= m else -(2 * m - t)) / (4 * m * m) * pt
        return mp.mpf(sigma2) * w


def empirical_haar_wv(x: np.ndarray, levels: int) -> np.ndarray:
    """Non-boundary Haar MODWT wavelet variance: mean of ((sum of next m) - (sum of last m))^2 / (2m)^2."""
    c = np.concatenate([[0.0], np.cumsum(x - x.mean())])
    out = []
    for j in range(1, levels + 1):
        m = 2 ** (j - 1)
        first = c[m : c.size - m] - c[: c.size - 2 * m]
        second = c[2 * m :] - c[m : c.size - m]
        out.append(np.mean(((second - first) / (2 * m)) ** 2))
    return np.asarray(out)


# ----------------------------------------------------------------- wavelet variance
@settings(max_examples=25, deadline=None)
@given(log_u=st.floats(-8.0, 1.7), log_s2=st.floats(-12.0, 6.0), freq=st.sampled_from([1.0, 100.0, 1000.0]))
@example(log_u=-8.0, log_s2=0.0, freq=1000.0)  # Tc = 1e5 s (28 h) at 1 kHz
@example(log_u=math.log10(-math.log(0.99927)), log_s2=0.0, freq=100.0)  # R gmwm: 7e-7 off
@example(log_u=math.log10(-math.log(0.9999972)), log_s2=-6.0, freq=100.0)  # R gmwm: 10x off
@example(log_u=1.7, log_s2=0.0, freq=100.0)  # Tc = 1/50 sample: nearly white
def test_haar_wv_matches_mpmath(log_u, log_s2, freq):
    beta = 10.0**log_u * freq
    sigma2 = 10.0**log_s2
    wv = GM(beta=beta, sigma2=sigma2).wv(30, freq)
    for j in LEVELS:
        ref = mp_wv(beta, sigma2, freq, 2 ** (j - 1))
        assert float(abs(wv[j - 1] - ref) / ref) <= 1e-12, j


def test_haar_wv_equals_generic_fallbacks_where_they_are_accurate():
    # peers inside stochmod: exact sum over the autocovariance, quadrature of the PSD
    gm = GM(beta=2.0, sigma2=3.0)
    wv = gm.wv(10, 100.0)
    np.testing.assert_allclose(wv, wv_from_autocovariance(lambda h: gm.autocovariance(h, 100.0), 10),
                               rtol=1e-12)
    np.testing.assert_allclose(wv, wv_from_psd(lambda f: gm.psd(f, 100.0), 10, 100.0), rtol=1e-9)


def test_other_wavelets_use_psd_quadrature():
    gm = GM(beta=5.0, sigma2=1.0)
    np.testing.assert_allclose(gm.wv(8, 100.0, "db4"),
                               wv_from_psd(lambda f: gm.psd(f, 100.0), 8, 100.0, wavelet="db4"), rtol=1e-12)


@settings(max_examples=15, deadline=None)
@given(log_u=st.floats(-8.0, 1.5), freq=st.sampled_from([1.0, 100.0]))
@example(log_u=-8.0, freq=100.0)
def test_wv_jacobian_matches_mpmath_derivative(log_u, freq):
    beta, sigma2 = 10.0**log_u * freq, 2.5
    J = GM(beta=beta, sigma2=sigma2).wv_jacobian(30, freq)
    assert J.shape == (30, 2)
    for j in (1, 2, 5, 13, 20, 30):
        m = 2 ** (j - 1)
        with mp.workdps(80):
            def wv_of_beta(b, m=m):
                phi = mp.exp(-b / freq)
                pm = phi**m
                return sigma2 * (m * (1 - phi**2) - phi * (1 - pm) * (3 - pm)) / (2 * m * m * (1 - phi) ** 2)

            d_beta = mp.diff(wv_of_beta, mp.mpf(beta))
            # d wv / d beta crosses zero at the WV peak: compare on the scale wv / beta
            scale = abs(wv_of_beta(mp.mpf(beta))) / beta
            assert float(abs(J[j - 1, 0] - d_beta) / max(abs(d_beta), 1e-3 * scale)) <= 1e-9, j
            assert float(abs(J[j - 1, 1] - wv_of_beta(mp.mpf(beta)) / sigma2)) <= 1e-13 * float(
                wv_of_beta(mp.mpf(beta)) / sigma2)


# ----------------------------------------------------------------- PSD, autocovariance
@pytest.mark.parametrize("u", [1e-6, 1e-3, 0.1, 3.0])
def test_psd_integrates_to_the_variance(u):
    freq, sigma2 = 100.0, 2.0
    gm = GM(beta=u * freq, sigma2=sigma2)
    # the peak at f = 0 has width ~ u freq / (2 pi): split the range geometrically there
    edges = np.unique(np.concatenate([[0.0], u * freq * np.logspace(-4, 4, 17), [freq / 2]]))
    edges = edges[edges <= freq / 2]
    total = sum(integrate.quad(lambda f: gm.psd(f, freq), a, b, epsabs=0, epsrel=1e-13, limit=200)[0]
                for a, b in zip(edges[:-1], edges[1:]))
    assert abs(2 * total - sigma2) <= 1e-10 * sigma2


def test_psd_is_the_fourier_series_of_the_autocovariance():
    freq, gm = 50.0, GM(beta=10.0, sigma2=1.5)  # phi = e^-0.2: 500 lags reach 1e-43
    f = np.linspace(-25.0, 25.0, 41)
    h = np.arange(1, 500)
    gamma = 1.5 * np.exp(-0.2 * h)
    series = (1.5 + 2 * np.cos(2 * np.pi * np.outer(f, h) / freq) @ gamma) / freq
    np.testing.assert_allclose(gm.psd(f, freq), series, rtol=1e-12)


def test_autocovariance():
    gm = GM(beta=3.0, sigma2=2.0)
    lags = np.array([0, 1, -1, 7, 1000])
    np.testing.assert_allclose(gm.autocovariance(lags, 10.0), 2.0 * np.exp(-0.3 * np.abs(lags)), rtol=1e-15)


# ----------------------------------------------------------------- state space
@pytest.mark.parametrize("beta, dt", [(1e-5, 0.37), (2.0, 0.01), (2.0, 0.37), (40.0, 1.3)])
def test_block_at_any_dt_is_the_closed_form(beta, dt):
    gm = GM(beta=beta, sigma2=2.0)
    block = gm.block(dt, 100.0)
    assert block.state_names == ("value",)
    np.testing.assert_allclose(block.Phi, [[math.exp(-beta * dt)]], rtol=1e-14)
    np.testing.assert_allclose(block.Q, [[-2.0 * math.expm1(-2 * beta * dt)]], rtol=1e-13)
    np.testing.assert_allclose(block.P0, [[2.0]])
    np.testing.assert_allclose([block.F[0, 0], block.G[0, 0], block.Qc[0, 0]], [-beta, 1.0, 4.0 * beta])
    # k steps of dt compose to one step of k dt
    Phi, Q = block.Phi, block.Q
    for _ in range(6):
        Phi, Q = block.Phi @ Phi, block.Phi @ Q @ block.Phi.T + block.Q
    big = gm.block(7 * dt, 100.0)
    np.testing.assert_allclose(big.Phi, Phi, rtol=1e-12)
    np.testing.assert_allclose(big.Q, Q, rtol=1e-12)
    np.testing.assert_allclose(compose_steps(block.Phi, block.Q, 7)[1], Q, rtol=1e-12)


def test_discrete_block_is_the_ar1():
    gm = GM(beta=4.0, sigma2=0.5)
    phi, q = gm.to_ar1(100.0)
    block = gm.discrete_block(100.0)
    np.testing.assert_allclose([block.Phi[0, 0], block.Q[0, 0]], [phi, q], rtol=1e-14)


# ----------------------------------------------------------------- simulation
def test_simulation_has_the_theoretical_wv():
    freq, levels, reps, n = 100.0, 8, 40, 2**14
    gm = GM(beta=freq / 30.0, sigma2=2.0)
    rng = np.random.default_rng(7)
    est = np.array([empirical_haar_wv(gm.simulate(n, freq, rng), levels) for _ in range(reps)])
    mean, se = est.mean(axis=0), est.std(axis=0, ddof=1) / math.sqrt(reps)
    assert np.all(np.abs(mean - gm.wv(levels, freq)) < 4.5 * se)


def test_simulation_is_stationary_and_reproducible():
    gm = GM(beta=1.0, sigma2=4.0)
    x = np.array([gm.simulate(3, 10.0, s)[[0, 2]] for s in range(4000)])
    # var of x_0 and x_2 is sigma2; their correlation exp(-2 beta / freq)
    cov = np.cov(x.T)
    se_var = 4.0 * math.sqrt(2.0 / 4000)
    assert abs(cov[0, 0] - 4.0) < 4.5 * se_var and abs(cov[1, 1] - 4.0) < 4.5 * se_var
    assert abs(cov[0, 1] / 4.0 - math.exp(-0.2)) < 4.5 / math.sqrt(4000)
    np.testing.assert_array_equal(gm.simulate(100, 10.0, 3), gm.simulate(100, 10.0, 3))


# ----------------------------------------------------------------- physical views
@settings(max_examples=30, deadline=None)
@given(log_tc=st.floats(-3.0, 6.0), log_sigma=st.floats(-6.0, 3.0), freq=st.sampled_from([1.0, 100.0, 1000.0]))
@example(log_tc=-3.0, log_sigma=0.0, freq=1.0)  # u = 1000: phi underflows
@example(log_tc=-2.859375, log_sigma=0.0, freq=1.0)  # u = 723: phi = 3.6e-314 is subnormal
def test_physical_constructors_round_trip(log_tc, log_sigma, freq):
    tc, sigma = 10.0**log_tc, 10.0**log_sigma
    gm = GM.from_correlation_time(tc, sigma)
    phys = gm.physical(freq)
    assert phys["Tc"].unit == "s" and phys["sigma"].unit == "u"
    assert abs(phys["Tc"].value - tc) <= 1e-15 * tc and abs(phys["sigma"].value - sigma) <= 1e-15 * sigma
    u = gm.beta / freq
    phi, q = gm.to_ar1(freq)
    if phi == 0.0:  # exp(-u) underflows (u > 745): no AR(1) view to come back from
        with pytest.raises(DomainError):
            GM.from_ar1(phi, q, freq)
        return
    back = GM.from_ar1(phi, q, freq)
    # beta comes back from log(phi): relative error ~ eps / u, plus, for a subnormal phi
    # (u > 708), the subnormal spacing 2^-1074 relative to phi, over u
    spacing = math.ulp(0.0) / phi if phi < sys.float_info.min else 0.0
    assert abs(back.beta - gm.beta) <= (4e-16 * max(1.0, 1.0 / u) + spacing / u) * gm.beta
    assert abs(back.sigma2 - gm.sigma2) <= 4e-16 * gm.sigma2 * max(1.0, 1.0 / u)


def test_to_ar1_is_exact_for_slow_processes():
    gm = GM(beta=1e-5, sigma2=1.0)  # u = 1e-8 at 1 kHz
    phi, q = gm.to_ar1(1000.0)
    with mp.workdps(40):
        assert abs(q - float(1 - mp.exp(-mp.mpf(2e-8)))) <= 1e-15 * q
    assert phi == math.exp(-1e-8)


def test_from_bias_instability_reproduces_quinchia():
    # Quinchia et al. 2013, Sect. 5.5: a flat Allan-deviation floor of 29.57 deg/h divided by
    # 0.664 gives B = 44.533 deg/h; eqs. 29-30 take sigma_GM = 0.664 B.
    B = 44.533 * DEG / HOUR
    gm = GM.from_bias_instability(B, 300.0, factor=BI_FACTOR_IEEE)
    assert abs(math.sqrt(gm.sigma2) / (DEG / HOUR) - 29.57) < 5e-4
    assert gm.beta == 1.0 / 300.0
    exact = GM.from_bias_instability(B, 300.0)
    assert math.sqrt(exact.sigma2) == pytest.approx(BI_FACTOR * B, rel=1e-15)


def test_example_has_a_50_sample_correlation_time():
    gm = GM.example(200.0)
    assert gm.physical(200.0)["Tc"].value * 200.0 == pytest.approx(50.0, rel=1e-15)


# ----------------------------------------------------------------- starting values
def test_start_spreads_over_time_scales_and_matches_the_wv():
    freq = 100.0
    wv = GM(beta=0.5, sigma2=1.0).wv(16, freq) + GM(beta=50.0, sigma2=0.1).wv(16, freq)
    starts = [GM().start(wv, freq, index=i, count=3) for i in range(3)]
    tcs = [1 / s.beta for s in starts]
    assert tcs[0] < tcs[1] < tcs[2]
    for i, s in enumerate(starts):
        j = 1 + round(15 * (i + 1) / 4)
        assert s.wv(16, freq)[j - 1] == pytest.approx(wv[j - 1], rel=1e-12)
        assert s.beta * 2 ** (j - 1) / freq == pytest.approx(PEAK_X, rel=1e-12)
    a = GM().start(wv, freq, rng=np.random.default_rng(5))
    b = GM().start(wv, freq, rng=np.random.default_rng(5))
    assert a == b and a != GM().start(wv, freq)


def test_peak_x_is_the_argmax_of_the_slow_limit():
    # g(x) / x^2 with g(x) = 2x - 3 + 4e^-x - e^-2x, maximised by mpmath
    with mp.workdps(30):
        g = lambda x: (2 * x - 3 + 4 * mp.exp(-x) - mp.exp(-2 * x)) / x**2  # noqa: E731
        assert abs(float(mp.findroot(lambda x: mp.diff(g, x), 1.9)) - PEAK_X) < 1e-15


# ----------------------------------------------------------------- bad input and specs
@pytest.mark.parametrize("kwargs", [dict(beta=0.0), dict(beta=-1.0), dict(beta=float("nan")),
                                    dict(beta=float("inf")), dict(sigma2=0.0), dict(sigma2=-2.0),
                                    dict(sigma2=float("nan"))])
def test_bad_values_raise_domain_error(kwargs):
    name = next(iter(kwargs))
    with pytest.raises(DomainError, match=f"GM.{name}"):
        GM(**kwargs)


@pytest.mark.parametrize("call", [
    lambda: GM.from_correlation_time(0.0, 1.0),
    lambda: GM.from_correlation_time(1.0, -1.0),
    lambda: GM.from_correlation_time(float("inf"), 1.0),
    lambda: GM.from_ar1(1.0, 1.0, 100.0),
    lambda: GM.from_ar1(-0.5, 1.0, 100.0),
    lambda: GM.from_ar1(0.5, 0.0, 100.0),
    lambda: GM.from_bias_instability(-1.0, 10.0),
])
def test_bad_physical_values_raise_domain_error(call):
    with pytest.raises(DomainError):
        call()


def test_free_parameters_raise_spec_error():
    for call in (lambda g: g.wv(4, 1.0), lambda g: g.psd([0.1], 1.0), lambda g: g.block(1.0, 1.0),
                 lambda g: g.simulate(10, 1.0, 0), lambda g: g.wv_jacobian(3, 1.0)):
        with pytest.raises(SpecError, match="free"):
            call(GM(beta=1.0))


def test_bad_start_input_raises():
    with pytest.raises(InputError):
        GM().start([], 100.0)
    with pytest.raises(InputError):
        GM().start([0.0, 0.0], 100.0)
    with pytest.raises(InputError):
        GM().start([1.0, 0.5], 100.0, index=2, count=2)


def test_spec_round_trip():
    model = model_from_spec("GM(beta=0.1, sigma2=2.0)+2*GM+WN", 100.0)
    assert [p.family for p in model.processes] == ["GM", "GM", "GM", "WN"]
    assert model.processes[0] == GM(beta=0.1, sigma2=2.0) and model.processes[1].is_free
    spec = {"processes": [{"family": "GM", "params": {"beta": 0.02, "sigma2": 1e-6}}], "freq": 50.0}
    m2 = model_from_spec(spec)
    assert m2.to_spec() == spec
    np.testing.assert_allclose(m2.wv(12), GM(beta=0.02, sigma2=1e-6).wv(12, 50.0), rtol=0)


def test_conformance_kit():
    testing = pytest.importorskip("stochmod.testing")
    report = testing.check_family(GM, freq=100.0, rng=0)
    report.raise_if_failed()
