"""Wavelet variance and MODWT: peers (allantools, R gmwm, pywt), closed forms, simulation."""

from __future__ import annotations

import json
from pathlib import Path

import allantools
import mpmath
import numpy as np
import pytest
import pywt
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from stochmod.core.errors import InputError
from stochmod.core.filters import default_levels, filter_width, max_level, modwt_filter, modwt_filters, squared_gain
from stochmod.empirical.modwt import iter_modwt, modwt_coefficients
from stochmod.empirical.wavelet_variance import NORMAL_CI_FLOOR, WaveletVariance, wvar

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
WAVELETS = ["haar", "db2", "db4", "sym4"]


# --- Haar wavelet variance == half the overlapping Allan variance (allantools) -----------------


@pytest.mark.parametrize("n", [257, 1001, 4099, 12345])
def test_haar_wv_is_half_allantools_oavar(n):
    rng = np.random.default_rng(n)
    x = rng.standard_normal(n) + 0.05 * np.cumsum(rng.standard_normal(n)) + 3.0
    freq = 37.5
    res = wvar(x, freq, levels=max_level(n))
    taus, adev, _, _ = allantools.oadev(x, rate=freq, data_type="freq", taus="octave")
    common = [(k, np.flatnonzero(np.isclose(res.tau, t, rtol=1e-12))) for k, t in enumerate(taus)]
    common = [(k, idx[0]) for k, idx in common if idx.size]
    assert len(common) >= res.levels.size - 1  # allantools stops one octave short at most
    for k, i in common:
        assert res.wv[i] == pytest.approx(0.5 * adev[k] ** 2, rel=1e-10)


# --- the R gmwm package on the real recording ----------------------------------------------------


def test_matches_r_gmwm_reference_on_gyro_x():
    ref_path = DATA / "reference" / "adis_16405_imu1_gyroX_gmwm.json"
    npz = DATA / "imudata" / "adis_16405_imu1.npz"
    if not (ref_path.is_file() and npz.is_file()):
        pytest.skip(f"reference data folder {DATA} is absent")
    ref = json.loads(ref_path.read_text())["wvar"]
    with np.load(npz) as z:
        x = z["Gyro_X"]
        freq = float(z["freq"])
    res = wvar(x, freq, levels=len(ref["variance"]))
    # the reference's scales are the filter widths 2^j (2^j / freq s); ours tau_j = 2^(j-1) / freq
    np.testing.assert_allclose(2 * res.tau, ref["scales_s"], rtol=1e-12)
    np.testing.assert_array_equal(res.n_coef, x.size - np.asarray(ref["scales_samples"]) + 1)
    np.testing.assert_allclose(res.wv, ref["variance"], rtol=1e-10)
    np.testing.assert_allclose(res.ci_low, ref["ci_low"], rtol=1e-8)
    np.testing.assert_allclose(res.ci_high, ref["ci_high"], rtol=1e-8)


# --- MODWT coefficients against PyWavelets' SWT and direct convolution ----------------------------


@pytest.mark.parametrize("wavelet", WAVELETS)
def test_modwt_coefficients_match_pywt_swt(wavelet):
    # pywt.swt (norm=True is the MODWT scaling) is circular and correlates with the filter
    # (convolves with dec_hi), so the convolution W_t = sum_l h_l x_{t-l} of x is pywt's SWT of
    # x reversed, read backwards. Our interior coefficients must be one contiguous run of it,
    # in order, at some circular alignment.
    size, levels = 512, 4
    x = np.random.default_rng(7).standard_normal(size)
    swt = pywt.swt(x[::-1], wavelet, level=levels, norm=True, trim_approx=True)
    for j in range(1, levels + 1):
        ours = modwt_coefficients(x, j, wavelet)
        assert ours.size == size - filter_width(j, wavelet) + 1
        detail = swt[-j][::-1]
        errors = [np.max(np.abs(np.roll(detail, -k)[: ours.size] - ours)) for k in range(size)]
        assert min(errors) < 1e-12


@pytest.mark.parametrize("wavelet", WAVELETS)
def test_modwt_filter_is_pywt_swt_impulse_response(wavelet):
    # pywt correlates with the filter (convolves with dec_hi), so its impulse response is the
    # level-j filter read backwards, circularly shifted.
    size, levels = 256, 4
    impulse = np.zeros(size)
    impulse[0] = 1.0
    swt = pywt.swt(impulse, wavelet, level=levels, norm=True, trim_approx=True)
    for j in range(1, levels + 1):
        h = modwt_filter(j, wavelet)
        padded = np.zeros(size)
        padded[: h.size] = h[::-1]
        errors = [np.max(np.abs(np.roll(padded, k) - swt[-j])) for k in range(size)]
        assert min(errors) < 1e-12
        # brute-force direct convolution with the pywt-derived filter
        shift = int(np.argmin(errors))
        h_pywt = np.roll(swt[-j], -shift)[: h.size][::-1]
        x = np.random.default_rng(j).standard_normal(300 + 7 * j)
        if h.size <= x.size:
            brute = np.array(
                [np.dot(h_pywt, x[t - np.arange(h.size)]) for t in range(h.size - 1, x.size)]
            )
            np.testing.assert_allclose(modwt_coefficients(x, j, wavelet), brute, atol=1e-12)


@pytest.mark.parametrize("wavelet", WAVELETS)
def test_iter_modwt_and_wvar_agree_with_convolution(wavelet):
    x = np.random.default_rng(3).standard_normal(3001)
    res = wvar(x, 10.0, wavelet=wavelet)
    for j, w in iter_modwt(x, res.levels.size, wavelet):
        direct = np.convolve(x, modwt_filter(j, wavelet), mode="valid")
        np.testing.assert_allclose(w, direct, atol=1e-12)
        assert res.wv[j - 1] == pytest.approx(np.mean(direct**2), rel=1e-11)
        assert res.n_coef[j - 1] == direct.size


def test_haar_filter_convention():
    # h_{j,l} = +1/2^j for l < 2^(j-1), -1/2^j after (eq. 18 sign), width 2^j
    for j in range(1, 7):
        m = 2 ** (j - 1)
        expected = np.r_[np.full(m, 1.0), np.full(m, -1.0)] / 2**j
        np.testing.assert_allclose(modwt_filter(j, "haar"), expected, atol=1e-15)


def test_haar_coefficients_are_accurate_on_large_mean_and_trend():
    # the pyramid's round-off does not grow with N or the mean: compare with exact integers
    n = 1 << 16
    rng = np.random.default_rng(11)
    x = rng.integers(-1000, 1000, n).astype(float) + 1e6 + 3.0 * np.arange(n)
    j = 5
    m = 2 ** (j - 1)
    xi = x.astype(np.int64)
    c = np.concatenate([[0], np.cumsum(xi)])  # exact integer sums
    t = np.arange(2 * m - 1, n)
    exact = ((c[t + 1] - c[t + 1 - m]) - (c[t + 1 - m] - c[t + 1 - 2 * m])) / 2**j
    np.testing.assert_allclose(modwt_coefficients(x, j), exact, rtol=0, atol=1e-9)


# --- squared gain ------------------------------------------------------------------------------


def _mp_gain(taps, f):
    mpmath.mp.dps = 40
    z = mpmath.fsum(
        mpmath.mpf(float(c)) * mpmath.expjpi(-2 * mpmath.mpf(f) * k) for k, c in enumerate(taps)
    )
    return float(abs(z) ** 2)


@settings(max_examples=200, deadline=None)
@given(f=st.floats(-3.0, 3.0, allow_nan=False), level=st.integers(1, 10))
def test_haar_squared_gain_against_mpmath(f, level):
    m = 2 ** (level - 1)
    taps = [mpmath.mpf(1) / 2**level] * m + [-mpmath.mpf(1) / 2**level] * m  # explicit Haar
    exact = _mp_gain(taps, f)
    assert squared_gain(f, level, "haar") == pytest.approx(exact, rel=1e-11, abs=1e-300)


@settings(max_examples=100, deadline=None)
@given(
    f=st.floats(-1.0, 1.0, allow_nan=False),
    level=st.integers(1, 6),
    wavelet=st.sampled_from(["db2", "db4", "sym4", "coif1"]),
)
def test_daubechies_squared_gain_against_mpmath(f, level, wavelet):
    exact = _mp_gain(modwt_filter(level, wavelet), f)
    assert squared_gain(f, level, wavelet) == pytest.approx(exact, rel=1e-9, abs=1e-14)


def test_squared_gain_at_zero_and_near_zero():
    # f -> 0 limit is 0; for small f the gain is (pi m f)^2 (leading term of the closed form)
    for level in (1, 4, 12):
        m = 2 ** (level - 1)
        assert squared_gain(0.0, level) == 0.0
        assert squared_gain(1.0, level) == 0.0
        f = 1e-9
        assert squared_gain(f, level) == pytest.approx((np.pi * m * f) ** 2, rel=1e-6)


@pytest.mark.parametrize("wavelet", WAVELETS)
@pytest.mark.parametrize("level", [1, 2, 5])
def test_squared_gain_parseval_and_fft(wavelet, level):
    h = modwt_filter(level, wavelet)
    size = 4 * h.size + 16  # uniform grid: exact quadrature for a trig polynomial of this degree
    f = np.arange(size) / size
    gain = squared_gain(f, level, wavelet)
    # db/sym gains are the exact closed form; pywt's sym4 taps hold only ~12 digits
    atol = 1e-11 if wavelet == "sym4" else 1e-14
    np.testing.assert_allclose(gain, np.abs(np.fft.fft(h, size)) ** 2, atol=atol)
    assert gain.mean() == pytest.approx(0.5**level, rel=1e-9)  # = integral over one period


def _db2_taps_exact():
    # Daubechies' D(4) scaling filter in closed form, (1+r3, 3+r3, 3-r3, 1-r3) / (4 sqrt 2),
    # MODWT-scaled by 1/sqrt(2); wavelet filter h_l = (-1)^l g_{3-l} (quadrature mirror)
    mpmath.mp.dps = 50
    r3 = mpmath.sqrt(3)
    g = [c / 8 for c in (1 + r3, 3 + r3, 3 - r3, 1 - r3)]
    return [(-1) ** k * g[3 - k] for k in range(4)], g


def test_db2_taps_match_closed_form():
    h, g = _db2_taps_exact()
    np.testing.assert_allclose(modwt_filter(1, "db2"), [float(c) for c in h], atol=1e-16)
    np.testing.assert_allclose(modwt_filters("db2")[1], [float(c) for c in g], atol=1e-16)


@settings(max_examples=100, deadline=None)
@given(log_f=st.floats(-12.0, np.log10(0.5)), level=st.integers(1, 6))
def test_db2_squared_gain_relative_accuracy_near_zero(log_f, level):
    # relative accuracy down to f = 1e-12, where |H|^2 ~ f^4: exact D(4) taps, 50 digits,
    # level-j filter by the explicit cascade in mpmath
    h, g = _db2_taps_exact()
    f = 10.0**log_f
    taps = [mpmath.mpf(1)]
    for k in range(level):
        base = h if k == level - 1 else g
        up = [mpmath.mpf(0)] * ((len(base) - 1) * 2**k + 1)
        up[:: 2**k] = base
        taps = [mpmath.fsum(taps[i] * up[n - i] for i in range(len(taps)) if 0 <= n - i < len(up))
                for n in range(len(taps) + len(up) - 1)]
    exact = _mp_gain(taps, f)
    assert squared_gain(f, level, "db2") == pytest.approx(exact, rel=1e-9)


@pytest.mark.parametrize(("wavelet", "moments"), [("coif1", 2), ("coif3", 6), ("db4", 4)])
def test_squared_gain_order_of_zero_at_origin(wavelet, moments):
    # |H_1(f)|^2 ~ c f^(2K) as f -> 0 for K vanishing moments (pywt's count); positive
    f = np.array([1e-3, 1e-4, 1e-5])
    gain = squared_gain(f, 1, wavelet)
    assert np.all(gain > 0)
    assert gain[1] / gain[2] == pytest.approx(10.0 ** (2 * moments), rel=1e-5)
    assert pywt.Wavelet(wavelet).vanishing_moments_psi == moments


# --- statistical properties on seeded simulations ------------------------------------------------


def _explicit_rw_wn_truth(wavelet, level, sigma2_wn, gamma2_rw):
    # Var(W) for x = WN + RW: sigma2 sum h^2 + gamma2 sum (partial sums of h)^2 (exact, sum h = 0)
    h = modwt_filter(level, wavelet)
    return sigma2_wn * np.sum(h**2) + gamma2_rw * np.sum(np.cumsum(h)[:-1] ** 2)


@pytest.mark.parametrize("wavelet", ["haar", "db4"])
def test_unbiased_on_white_noise_plus_random_walk(wavelet):
    rng = np.random.default_rng(2024)
    n, reps, sigma2, gamma2 = 2048, 300, 2.0, 1e-3
    levels = 6
    est = np.empty((reps, levels))
    for r in range(reps):
        x = np.sqrt(sigma2) * rng.standard_normal(n) + np.cumsum(
            np.sqrt(gamma2) * rng.standard_normal(n)
        )
        est[r] = wvar(x, 1.0, wavelet=wavelet, levels=levels).wv
    truth = np.array(
        [_explicit_rw_wn_truth(wavelet, j, sigma2, gamma2) for j in range(1, levels + 1)]
    )
    se = est.std(axis=0, ddof=1) / np.sqrt(reps)
    assert np.all(np.abs(est.mean(axis=0) - truth) < 4 * se)


def test_unbiased_on_white_noise_haar_closed_form():
    rng = np.random.default_rng(99)
    n, reps, sigma2, levels = 1000, 400, 0.7, 7
    est = np.array([wvar(np.sqrt(sigma2) * rng.standard_normal(n), 5.0, levels=levels).wv
                    for _ in range(reps)])
    truth = sigma2 / 2.0 ** np.arange(1, levels + 1)  # closed form: sigma2 / 2^j
    se = est.std(axis=0, ddof=1) / np.sqrt(reps)
    assert np.all(np.abs(est.mean(axis=0) - truth) < 4 * se)


def _haar_white_edof(n, level):
    # exact equivalent degrees of freedom 2 v^2 / var(v_hat) for Gaussian white noise (P&W eta_1)
    h = modwt_filter(level, "haar")
    m_j = n - h.size + 1
    acf = np.correlate(h, h, mode="full")  # autocovariance of W for unit white noise
    lags = np.arange(-(h.size - 1), h.size)
    var_hat = 2.0 / m_j**2 * np.sum((m_j - np.abs(lags)) * acf**2)
    return 2.0 * np.sum(h**2) ** 2 / var_hat


def test_ci_coverage_on_white_noise():
    rng = np.random.default_rng(17)
    n, reps, levels, alpha = 4096, 800, 6, 0.05
    truth = 1.0 / 2.0 ** np.arange(1, levels + 1)
    hits = {"chi2": np.zeros(levels), "normal": np.zeros(levels)}
    for _ in range(reps):
        x = rng.standard_normal(n)
        for method in hits:
            res = wvar(x, 1.0, levels=levels, ci=method, alpha=alpha)
            hits[method] += (res.ci_low <= truth) & (truth <= res.ci_high)
    mc = 3 * np.sqrt(alpha * (1 - alpha) / reps)
    # normal (eq. 10-11): near nominal at every level (M_j / 2^j >= 64 here)
    assert np.all(np.abs(hits["normal"] / reps - (1 - alpha)) < mc + 0.01)
    # chi2 with eta_3 = max(M_j/2^j, 1): conservative on white noise, where the true EDOF is
    # larger; its coverage is the chi2(eta_1) probability of the eta_3 interval
    for j in range(1, levels + 1):
        m_j = n - 2**j + 1
        eta3 = max(m_j / 2**j, 1.0)
        eta1 = _haar_white_edof(n, j)
        lo, hi = stats.chi2.ppf([alpha / 2, 1 - alpha / 2], eta3) / eta3
        predicted = stats.chi2.cdf(eta1 * hi, eta1) - stats.chi2.cdf(eta1 * lo, eta1)
        assert predicted >= 1 - alpha
        assert hits["chi2"][j - 1] / reps == pytest.approx(predicted, abs=mc + 0.01)


def test_normal_ci_is_eq11_brute_force_and_floor():
    x = np.cumsum(np.random.default_rng(1).standard_normal(300))  # random walk: wide deep CIs
    res = wvar(x, 2.0, ci="normal", alpha=0.1, levels=8)
    z = stats.norm.ppf(0.95)
    for j in res.levels:
        w = np.convolve(x, modwt_filter(j, "haar"), mode="valid")
        m_j = w.size
        s = [np.dot(w[: m_j - k], w[k:]) / m_j for k in range(m_j)]
        s_hat = s[0] ** 2 + 2 * np.sum(np.square(s[1:]))  # sum over |tau| < M_j (eq. 11)
        half = z * np.sqrt(s_hat / m_j)
        v = res.wv[j - 1]
        assert res.ci_high[j - 1] == pytest.approx(v + half, rel=1e-10)
        assert res.ci_low[j - 1] == pytest.approx(max(v - half, NORMAL_CI_FLOOR * v), rel=1e-10)
    assert np.any(res.ci_low == NORMAL_CI_FLOOR * res.wv)  # deep levels hit the floor


def test_chi2_interval_formula():
    x = np.random.default_rng(8).standard_normal(777)
    res = wvar(x, 1.0, alpha=0.1)
    eta = np.maximum(res.n_coef / 2.0**res.levels, 1.0)
    np.testing.assert_allclose(res.ci_low, eta * res.wv / stats.chi2.ppf(0.95, eta), rtol=1e-12)
    np.testing.assert_allclose(res.ci_high, eta * res.wv / stats.chi2.ppf(0.05, eta), rtol=1e-12)


# --- result object, levels ---------------------------------------------------------------------


def test_result_fields_summary_and_dict():
    x = np.random.default_rng(1).standard_normal(1000)
    res = wvar(x, 100.0)
    assert isinstance(res, WaveletVariance)
    assert res.levels.tolist() == list(range(1, 9))  # floor(log2 1000) - 1 = 8
    np.testing.assert_allclose(res.tau, 2.0 ** np.arange(8) / 100.0)
    assert res.n == 1000 and res.freq == 100.0 and res.wavelet == "haar"
    assert res.ci_method == "chi2" and res.alpha == 0.05
    np.testing.assert_array_equal(res.n_coef, 1000 - 2 ** np.arange(1, 9) + 1)
    d = json.loads(json.dumps(res.to_dict(), allow_nan=False))
    assert d["wv"] == res.wv.tolist() and d["n_coef"] == res.n_coef.tolist()
    text = res.summary()
    assert "tau [s]" in text and "M_j" in text and len(text.splitlines()) == 8 + 3
    assert res == wvar(x, 100.0)
    with pytest.raises(ValueError):
        res.wv[0] = 1.0  # read-only arrays


@pytest.mark.parametrize(
    ("n", "wavelet", "top", "default"),
    [(2, "haar", 1, 1), (3, "haar", 1, 1), (1024, "haar", 10, 9), (1023, "haar", 9, 8),
     (1000, "db4", 7, 7), (8, "db4", 1, 1)],
)
def test_levels(n, wavelet, top, default):
    # L_j = (2^j - 1)(L_1 - 1) + 1 <= n
    assert max_level(n, wavelet) == top
    assert filter_width(top, wavelet) <= n < filter_width(top + 1, wavelet)
    assert default_levels(n, wavelet) == default
    x = np.random.default_rng(n).standard_normal(n)
    res = wvar(x, 1.0, wavelet=wavelet, levels=top)
    assert res.n_coef[-1] == n - filter_width(top, wavelet) + 1


# --- bad input -----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("x", "kwargs", "match"),
    [
        ([], {}, "empty"),
        ([1.0], {}, "at least 2"),
        ([1.0, np.nan, 2.0, 3.0], {}, "NaN"),
        ([1.0, np.inf, 2.0, 3.0], {}, "inf"),
        # the first and the last sample enter only one level-1 coefficient each
        ([np.nan] + [1.0, 2.0] * 50, {}, "NaN at flat index 0"),
        ([1.0, 2.0] * 50 + [-np.inf], {}, "inf at flat index 100"),
        ([1.0, 2.0] * 50 + [np.inf], {"wavelet": "db4"}, "inf at flat index 100"),
        ([np.nan] + [1.0, 2.0] * 50, {"ci": "normal"}, "NaN at flat index 0"),
        ([1e300, -1e300] * 50, {}, "overflows float64"),
        (np.ones((10, 3)), {}, "one-dimensional"),
        (["a", "b", "c"], {}, "numeric"),
        (np.ones(100), {}, "constant"),
        (np.arange(100.0), {"levels": 7}, r"levels=7 .* at most 6"),
        (np.arange(100.0), {"levels": 0}, "at least 1"),
        (np.arange(100.0), {"levels": 2.5}, "integer"),
        (np.arange(100.0), {"wavelet": "nope"}, "unknown wavelet"),
        (np.arange(100.0), {"wavelet": "bior2.2"}, "not orthogonal"),
        (np.arange(100.0), {"wavelet": "morl"}, "unknown wavelet"),
        (np.arange(100.0), {"ci": "boot"}, "ci must be"),
        (np.arange(100.0), {"alpha": 1.5}, "alpha"),
        (np.arange(100.0), {"freq": -1.0}, "freq"),
        (np.arange(5.0), {"wavelet": "db4"}, "at least 8"),
    ],
)
def test_bad_input(x, kwargs, match):
    freq = kwargs.pop("freq", 1.0)
    with pytest.raises(InputError, match=match):
        wvar(x, freq, **kwargs)


def test_bad_input_modwt_and_gain():
    with pytest.raises(InputError, match="at most 3"):
        modwt_coefficients(np.arange(10.0), 4)
    with pytest.raises(InputError, match="unknown wavelet"):
        modwt_coefficients(np.arange(10.0), 1, "xyz")
    with pytest.raises(InputError, match="finite"):
        squared_gain([0.1, np.nan], 2)
    with pytest.raises(InputError, match="level"):
        squared_gain(0.1, 0)
