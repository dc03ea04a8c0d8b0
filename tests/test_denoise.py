"""Wavelet de-noising: thresholds against their closed forms and a brute-force SURE, shrinkage
against pywt, a whole wden-style pipeline written independently, level selection against
Quinchia et al. (2013) Section 5.6 / Table 7, reconstruction and MSE reduction."""

from __future__ import annotations

import math

import numpy as np
import pytest
import pywt
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.signal import lfilter

from stochmod.core.errors import InputError
from stochmod.empirical.denoise import (
    band_limit,
    denoise,
    denoise_then_ar,
    hard_threshold,
    level_for_frequency,
    select_threshold,
    soft_threshold,
    sure_threshold,
    wavelet_denoise,
)


def _brute_sure(d: np.ndarray) -> float:
    """O(n^2): evaluate SURE(t) = n - 2 #{|d| <= t} + sum min(d^2, t^2) at every t = |d_i|."""
    n = d.size
    best_t, best_risk = None, math.inf
    for t in np.abs(d):
        risk = n - 2 * sum(1 for v in d if abs(v) <= t) + sum(min(v * v, t * t) for v in d)
        tol = 1e-12 * max(1.0, abs(risk))
        tie = best_t is not None and abs(risk - best_risk) <= tol and t < best_t
        if best_t is None or risk < best_risk - tol or tie:
            best_t, best_risk = t, risk
    return float(best_t)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 120), scale=st.floats(0.1, 5.0))
def test_sure_threshold_equals_brute_force_minimisation(seed, n, scale):
    rng = np.random.default_rng(seed)
    d = rng.standard_normal(n) * scale
    d[: n // 4] += rng.uniform(-8, 8, n // 4)  # some signal
    assert sure_threshold(d) == pytest.approx(_brute_sure(d), rel=1e-12)
    assert select_threshold(d, "rigrsure") == sure_threshold(d)


@pytest.mark.parametrize("n", [2, 10, 32, 33, 100, 4097, 10**6])
def test_fixed_form_thresholds(n):
    d = np.zeros(n)
    assert select_threshold(d, "sqtwolog") == math.sqrt(2 * math.log(n))
    expected = 0.0 if n <= 32 else 0.3936 + 0.1829 * math.log(n) / math.log(2)
    assert select_threshold(d, "minimaxi") == pytest.approx(expected, rel=1e-14, abs=0)


def test_heursure_branches():
    rng = np.random.default_rng(0)
    noise = rng.standard_normal(1000)  # energy ~ n: the universal threshold
    assert select_threshold(noise, "heursure") == math.sqrt(2 * math.log(1000))
    strong = noise.copy()
    strong[:200] += 10.0  # (|d|^2 - n)/n >> (log2 n)^1.5 / sqrt(n): min(SURE, universal)
    expected = min(_brute_sure(strong), math.sqrt(2 * math.log(1000)))
    assert select_threshold(strong, "heursure") == expected


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 200), t=st.floats(0.0, 4.0))
def test_soft_and_hard_against_pywt(seed, n, t):
    d = np.random.default_rng(seed).standard_normal(n) * 2
    np.testing.assert_allclose(soft_threshold(d, t), pywt.threshold(d, t, mode="soft"), atol=1e-15)
    np.testing.assert_array_equal(hard_threshold(d, t), pywt.threshold(d, t, mode="hard"))


def _independent_wden(x, wavelet, level, rule, mode, noise):
    """A straight transcription of MATLAB wden with pywt and brute-force thresholds."""
    c = pywt.wavedec(x, wavelet, mode="symmetric", level=level)
    total = sum(a.size for a in c)
    finest = np.median(np.abs(c[-1])) / 0.6745
    out = [c[0]]
    for j in range(1, level + 1):  # c[j] is level level+1-j
        d = c[j]
        s = {"level": np.median(np.abs(d)) / 0.6745, "one": finest, "none": 1.0}[noise]
        if rule == "sqtwolog":
            thr = math.sqrt(2 * math.log(total))
        elif rule == "minimaxi":
            thr = 0.3936 + 0.1829 * math.log2(total) if total > 32 else 0.0
        else:
            thr = _brute_sure(d / s)
        if mode == "soft":
            out.append(pywt.threshold(d, thr * s, mode="soft"))
        else:  # MATLAB wthresh 'h' zeroes |d| == t; pywt keeps it (SURE's t is one of the |d_i|)
            out.append(np.where(np.abs(d) > thr * s, d, 0.0))
    return pywt.waverec(out, wavelet, mode="symmetric")[: x.size]


@pytest.mark.parametrize("rule", ["rigrsure", "sqtwolog", "minimaxi"])
@pytest.mark.parametrize("noise", ["level", "one", "none"])
@pytest.mark.parametrize("mode", ["soft", "hard"])
def test_pipeline_equals_an_independent_wden(rule, noise, mode):
    rng = np.random.default_rng(11)
    t = np.arange(301)
    x = np.sin(2 * np.pi * t / 80) * 3 + rng.standard_normal(t.size)
    ours = denoise(x, "db4", 3, rule=rule, mode=mode, noise=noise)
    ref = _independent_wden(x, "db4", 3, rule, mode, noise)
    np.testing.assert_allclose(ours, ref, atol=1e-12)


def test_sqtwolog_threshold_is_sigma_sqrt_2_ln_n():
    x = np.random.default_rng(2).standard_normal(5000)
    res = wavelet_denoise(x, "db4", 5, rule="sqtwolog", noise="level")
    coeffs = pywt.wavedec(x, "db4", level=5)
    n_total = sum(c.size for c in coeffs)
    for j in range(1, 6):
        sigma = np.median(np.abs(coeffs[-j])) / 0.6745
        assert res.noise_sigma[j - 1] == sigma
        assert res.thresholds[j - 1] == sigma * math.sqrt(2 * math.log(n_total))


@pytest.mark.parametrize("wavelet", ["db4", "haar", "sym8", "coif2"])
@pytest.mark.parametrize("n", [257, 1000, 1001])
def test_zero_threshold_reconstructs_perfectly(wavelet, n):
    x = np.random.default_rng(n).standard_normal(n).cumsum()
    y = denoise(x, wavelet, 3, rule=0.0)
    assert y.shape == x.shape
    np.testing.assert_allclose(y, x, atol=1e-9 * np.abs(x).max())


def test_denoising_reduces_mse_on_smooth_signal_plus_white_noise():
    rng = np.random.default_rng(3)
    t = np.linspace(0, 1, 4097)
    clean = np.sin(2 * np.pi * 3 * t) + 0.5 * np.sign(np.sin(2 * np.pi * 1.3 * t))
    noisy = clean + 0.3 * rng.standard_normal(t.size)
    mse0 = np.mean((noisy - clean) ** 2)
    for rule in ("rigrsure", "sqtwolog", "heursure", "minimaxi"):
        y = denoise(noisy, "db4", 6, rule=rule)
        assert y.shape == noisy.shape
        assert np.mean((y - clean) ** 2) < 0.5 * mse0, rule


def test_levels_of_quinchia_section_5_6_and_table_7():
    # Section 5.6: 3 LOD at 100 Hz keep 0-6.25 Hz, 8 LOD keep 0-0.1953 Hz; Fig. 17's cluster
    # times 0.16 s and 5.12 s are 1 / band limit. Table 7: LOD 6 -> 0.78 Hz, LOD 7 -> 0.39 Hz
    # (rounded to two decimals in the table).
    assert band_limit(100, 3) == 6.25
    assert round(band_limit(100, 8), 4) == 0.1953
    assert 1 / band_limit(100, 3) == pytest.approx(0.16)
    assert 1 / band_limit(100, 8) == pytest.approx(5.12)
    assert round(band_limit(100, 6), 2) == 0.78
    assert round(band_limit(100, 7), 2) == 0.39
    assert level_for_frequency(100, 6.25) == 3
    assert level_for_frequency(100, 5.0) == 4  # "the one that nearly reaches 5 Hz" is 3 (6.25 Hz)
    assert level_for_frequency(100, 0.78125) == 6
    assert level_for_frequency(100, 0.4) == 7
    assert level_for_frequency(100, 0.390625) == 7
    assert level_for_frequency(100, 0.39) == 8  # strictly below the table's rounded 0.3906
    res = wavelet_denoise(np.random.default_rng(0).standard_normal(3000), freq=100.0, f_limit=0.78)
    assert res.level == 7 and res.band_limit == 100 / 2**8


@settings(max_examples=100, deadline=None)
@given(freq=st.floats(1.0, 1e4), ratio=st.floats(1e-4, 2.0))
def test_level_for_frequency_is_the_smallest_such_level(freq, ratio):
    f_limit = freq * ratio
    k = level_for_frequency(freq, f_limit)
    brute = next(j for j in range(1, 64) if freq / 2 ** (j + 1) <= f_limit * (1 + 1e-12))
    assert k == brute


def test_denoise_then_ar_removes_the_white_noise_bias():
    # AR(1) drift buried in white noise: Burg on the raw data is biased towards 0; after
    # de-noising (Quinchia Section 5.3) the coefficient moves towards the true one
    rng = np.random.default_rng(5)
    phi = 0.995
    drift = lfilter([1.0], [1.0, -phi], rng.standard_normal(50_000) * 0.1)
    x = drift + rng.standard_normal(drift.size)
    from stochmod.empirical.ar_fit import fit_ar

    raw = fit_ar(x, 100.0, 1)
    den = denoise_then_ar(x, 100.0, 1, level=6)
    assert abs(den.phi[0] - phi) < 0.5 * abs(raw.phi[0] - phi)
    assert den.order == 1


def test_denoised_allan_reproduces_figure_17_behaviour():
    # Quinchia Fig. 17: de-noising removes the short-term (white) noise while the long-term
    # noise keeps its Allan variance above the cut-off cluster time 2^(L+1) / freq
    pytest.importorskip("stochmod.empirical.allan", reason="the Allan module is not available")
    from stochmod.empirical.denoise import denoised_allan

    rng = np.random.default_rng(6)
    n = 200_000
    x = rng.standard_normal(n) + np.cumsum(rng.standard_normal(n)) * 0.02
    for level, tau_limit in ((3, 0.16), (8, 5.12)):
        res = denoised_allan(x, 100.0, level=level)
        assert res.tau_limit == pytest.approx(tau_limit)
        assert res.band_limit == 100 / 2 ** (level + 1)
        ratio = res.denoised.avar / res.raw.avar
        np.testing.assert_array_equal(res.raw.tau, res.denoised.tau)
        assert ratio[0] < 0.01  # tau = 0.01 s: the white noise is gone
        assert np.all(ratio[res.raw.tau >= 4 * tau_limit] > 0.95)


def test_summary_lists_levels():
    res = wavelet_denoise(np.random.default_rng(1).standard_normal(1000), "db4", 4, freq=100.0)
    text = res.summary()
    assert "25-50" in text and "3.125-6.25" in text


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"wavelet": "bior2.2"}, "not orthogonal"),
        ({"wavelet": "nope"}, "unknown wavelet"),
        ({"rule": "visu"}, "rule"),
        ({"rule": -1.0}, "fixed threshold"),
        ({"mode": "garrote"}, "mode"),
        ({"noise": "mad"}, "noise"),
        ({"level": 20}, "too deep"),
        ({"level": 0}, "level"),
        ({"level": 2, "f_limit": 1.0, "freq": 100.0}, "either level or f_limit"),
        ({"f_limit": 1.0}, "needs the sampling frequency"),
        ({"extension": "mirror"}, "extension"),
    ],
)
def test_bad_input(kwargs, match):
    with pytest.raises(InputError, match=match):
        denoise(np.random.default_rng(0).standard_normal(500), **kwargs)


def test_bad_signal():
    with pytest.raises(InputError, match="non-finite"):
        denoise([1.0, np.nan, 3.0, 4.0], "haar", 1)
