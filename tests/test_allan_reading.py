"""Tests of stochmod.empirical.allan_reading: the IEEE 952 slope reading of the Allan variance.

Truth: seeded simulations with known coefficients (white noise N, random walk K, first-order
Gauss-Markov, flicker noise of two-sided PSD B^2 / (2 pi f) made by spectral shaping as in
Stebler et al. (2014) Table I, quantization X_t = sqrt(12 Q2)(U_t - U_{t-1})); exact discrete
Allan variances of the per-sample models of ``stochmod.fit.classical.allan_model`` computed from their autocovariances;
the maximum of the Gauss-Markov AV found numerically with mpmath; the R gmwm package's
wavelet variance of the real ADIS16405 gyro (``../shared/data/reference``).

Tolerances come from the Monte Carlo of docs/allan.md (200 seeded replications of each case at
N = 1e6, 100 Hz; relative spread of the readings): tolerance = max(4 sd, |bias| + 3 sd).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import mpmath as mp
import numpy as np
import pytest
from scipy.signal import lfilter

from stochmod.fit.classical import allan_model
from stochmod.core.errors import EstimationError, InputError
from stochmod.empirical.allan import avar
from stochmod.empirical.allan_reading import (
    GM_PEAK_AV,
    GM_PEAK_X,
    AllanReading,
    Coefficient,
    allan_reading,
)

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
FS = 100.0
N_SAMPLES = 1_000_000
BI = math.sqrt(2 * math.log(2) / math.pi)


# ----------------------------------------------------------------------------- simulators


def white(rng, n, n_coef):
    """White noise of coefficient N (u sqrt(s)): per-sample variance N^2 fs."""
    return rng.standard_normal(n) * n_coef * math.sqrt(FS)


def random_walk(rng, n, k_coef):
    """Random walk of coefficient K (u / sqrt(s)): per-sample increment variance K^2 / fs."""
    return np.cumsum(rng.standard_normal(n)) * k_coef / math.sqrt(FS)


def gauss_markov(rng, n, sigma, tc):
    """Stationary first-order Gauss-Markov process, correlation time tc (s)."""
    phi = math.exp(-1.0 / (FS * tc))
    e = rng.standard_normal(n) * sigma * math.sqrt(1 - phi**2)
    x0 = sigma * rng.standard_normal()
    return lfilter([1.0], [1.0, -phi], e) + x0 * phi ** np.arange(1, n + 1)


def quantization(rng, n, q_coef):
    """X_t = sqrt(12 Q2)(U_t - U_{t-1}), U uniform on (0, 1), Q2 = Q^2 fs^2."""
    q2 = q_coef**2 * FS**2
    return math.sqrt(12 * q2) * np.diff(rng.random(n + 1))


def flicker(rng, n, b_coef):
    """Two-sided PSD B^2 / (2 pi |f|) between 1/T and fs/2 (Stebler Table I), by shaping."""
    spec = np.fft.rfft(rng.standard_normal(n))
    f = np.fft.rfftfreq(n, 1.0 / FS)
    psd = np.zeros_like(f)
    psd[1:] = b_coef**2 / (2 * np.pi * f[1:])
    return np.fft.irfft(spec * np.sqrt(psd * FS), n)


def _rel(c: Coefficient | None, truth: float) -> float:
    assert c is not None
    return c.value / truth - 1.0


# ----------------------------------------------------------------------------- simulations


def test_white_noise_plus_random_walk():
    rng = np.random.default_rng(1000)
    x = white(rng, N_SAMPLES, 1e-3) + random_walk(rng, N_SAMPLES, 1e-3)
    r = allan_reading(x, FS)
    assert isinstance(r, AllanReading)
    assert abs(_rel(r.N, 1e-3)) < 0.005  # MC: bias 0.00 %, sd 0.08 %
    assert abs(_rel(r.K, 1e-3)) < 0.10  # MC: bias -0.14 %, sd 2.5 %
    assert r.N.low <= 1e-3 <= r.N.high and r.K.low <= 1e-3 <= r.K.high
    assert r.Q is None and r.B is None and r.R is None and r.Tc is None
    assert r.N.slope == -1 and r.K.slope == 1 and r.N.unit_hint == "u*sqrt(s)"
    assert r.N.tau_range[0] == pytest.approx(0.01) and r.K.tau_range[0] > r.N.tau_range[1]


def test_white_noise_gauss_markov_random_walk():
    rng = np.random.default_rng(1001)
    sigma, tc = 1e-3, 1.0
    x = (white(rng, N_SAMPLES, 3e-4) + gauss_markov(rng, N_SAMPLES, sigma, tc)
         + random_walk(rng, N_SAMPLES, 3e-4))
    r = allan_reading(x, FS, gm="matched")
    assert abs(_rel(r.N, 3e-4)) < 0.015  # MC: bias +0.8 % (the GM rise under N), sd 0.08 %
    assert abs(_rel(r.K, 3e-4)) < 0.30  # MC: bias +1.2 %, sd 7.1 %
    # the GM bump is read as the flat region: it holds the GM's peak (1.8926 Tc), and the
    # flat level (fitted after subtracting the N and K lines) lies within the range of the
    # GM's own AV (closed form, IEEE 952 Annex C) over it
    assert r.B is not None and r.Tc is not None
    assert r.B.tau_range[0] <= GM_PEAK_X * tc <= r.B.tau_range[1]
    u = np.geomspace(*r.B.tau_range, 200) / tc
    gm_av = sigma**2 * (2 / u) * (1 - (3 - 4 * np.exp(-u) + np.exp(-2 * u)) / (2 * u))
    assert gm_av.min() < r.B.line < gm_av.max()


def test_white_noise_plus_bias_instability():
    rng = np.random.default_rng(1002)
    x = white(rng, N_SAMPLES, 1e-3) + flicker(rng, N_SAMPLES, 1e-3)
    r = allan_reading(x, FS)
    assert abs(_rel(r.B, 1e-3)) < 0.12  # MC: bias -0.6 %, sd 2.8 %
    assert abs(_rel(r.N, 1e-3)) < 0.02  # MC: bias +1.5 % (the floor under N), sd 0.09 %
    assert r.K is None and r.Q is None
    assert r.B.tau_range[0] <= r.Tc <= r.B.tau_range[1]


def test_quantization_plus_white_noise():
    rng = np.random.default_rng(1003)
    x = quantization(rng, N_SAMPLES, 1e-4) + white(rng, N_SAMPLES, 1e-4)
    r = allan_reading(x, FS)
    assert abs(_rel(r.Q, 1e-4)) < 0.01  # MC: bias +0.02 %, sd 0.23 %
    assert abs(_rel(r.N, 1e-4)) < 0.15  # MC: bias -0.5 %, sd 3.6 %
    assert r.Q.slope == -2 and r.Q.unit_hint == "u*s"


def test_pure_white_noise_reports_only_n():
    rng = np.random.default_rng(1004)
    r = allan_reading(white(rng, 200_000, 2e-3), FS)
    assert abs(_rel(r.N, 2e-3)) < 0.01  # MC at N = 1e6: sd 0.08 %; here N = 2e5
    assert r.K is None and r.B is None and r.Q is None and r.R is None
    text = r.summary()
    assert text.count("not identified") == 5  # Q, B, K, R and Tc
    with pytest.raises(EstimationError, match="K .*random walk.*not identified"):
        allan_reading(white(rng, 200_000, 2e-3), FS, require=("K",))


def test_rate_ramp_is_read():
    rng = np.random.default_rng(1005)
    n = 200_000
    ramp = 1e-5 * np.arange(n) / FS  # R = 1e-5 u/s
    r = allan_reading(white(rng, n, 1e-3) + ramp, FS)
    assert abs(_rel(r.R, 1e-5)) < 0.05
    assert r.K is None


# ----------------------------------------------------------------------------- options


def test_user_regions_override_and_suppress():
    rng = np.random.default_rng(1006)
    x = white(rng, 200_000, 1e-3) + random_walk(rng, 200_000, 1e-3)
    r = allan_reading(x, FS, regions={"N": (0.02, 0.2), "K": None})
    assert r.N.region == "user" and r.N.tau_range == (pytest.approx(0.02), pytest.approx(0.2))
    assert r.K is None
    # the fixed-slope fit on those points is the weighted mean of AV * tau (no other line)
    av = r.avar
    sel = (av.tau >= 0.02 - 1e-12) & (av.tau <= 0.2 + 1e-12)
    assert r.N.n_points == int(sel.sum())
    assert r.N.value**2 == pytest.approx(float(np.mean(av.avar[sel] * av.tau[sel])), rel=0.01)


def test_ieee_single_point_readings():
    rng = np.random.default_rng(1007)
    x = white(rng, 200_000, 1e-3) + flicker(rng, 200_000, 1e-3)
    r = allan_reading(x, FS, method="ieee")
    av = r.avar
    lo, hi = r.N.tau_range
    inside = np.flatnonzero((av.tau >= lo) & (av.tau <= hi))
    p = inside[np.argmin(np.abs(np.log(av.tau[inside])))]  # the point nearest tau = 1 s
    assert r.N.value == pytest.approx(math.sqrt(av.avar[p] * av.tau[p]), rel=1e-12)
    lo, hi = r.B.tau_range
    inside = (av.tau >= lo) & (av.tau <= hi)
    assert r.B.value == pytest.approx(math.sqrt(av.avar[inside].min()) / BI, rel=1e-12)


def test_gm_peak_constants_by_numerical_maximisation():
    mp.mp.dps = 30

    def av_gm(x):  # AV / sigma^2 of a GM at tau = x Tc (IEEE 952 Annex C)
        return (2 / x) * (1 - (3 - 4 * mp.exp(-x) + mp.exp(-2 * x)) / (2 * x))

    x_star = mp.findroot(lambda x: mp.diff(av_gm, x), 1.9)
    assert float(x_star) == pytest.approx(GM_PEAK_X, rel=1e-12)
    assert float(av_gm(x_star)) == pytest.approx(GM_PEAK_AV, rel=1e-12)


def _exact_discrete_av(acov, m: int) -> float:
    """AV at m of a stationary sequence with autocovariance acov(lag), by brute force."""
    w = np.concatenate([-np.ones(m), np.ones(m)]) / m  # ybar_2 - ybar_1
    lags = np.abs(np.subtract.outer(np.arange(2 * m), np.arange(2 * m)))
    return 0.5 * float(w @ acov(lags) @ w)


def _spec(reading, freq=None):
    return {p["family"]: p["params"] for p in allan_model(reading, freq).to_spec()["processes"]}


def test_model_per_sample_parameters_give_the_ieee_lines():
    rng = np.random.default_rng(1008)
    x = (quantization(rng, 400_000, 1e-4) + white(rng, 400_000, 1e-4)
         + 2e-6 * np.arange(400_000) / FS)
    r = allan_reading(x, FS, regions={"Q": (0.01, 0.3), "N": (5.0, 20.0), "R": (300.0, 1000.0)})
    spec = _spec(r)
    q2, s2, omega = spec["QN"]["Q2"], spec["WN"]["sigma2"], spec["RR"]["omega"]
    for m in (1, 3, 10):
        tau = m / FS
        # QN: gamma(0) = 2 Q2, gamma(1) = -Q2  ->  AV = 3 Q^2 / tau^2 exactly
        qn = _exact_discrete_av(lambda k: np.where(k == 0, 2 * q2, np.where(k == 1, -q2, 0.0)), m)
        assert qn == pytest.approx(3 * r.Q.value**2 / tau**2, rel=1e-12)
        wn = _exact_discrete_av(lambda k: np.where(k == 0, s2, 0.0), m)
        assert wn == pytest.approx(r.N.value**2 / tau, rel=1e-12)
        # RR: the sample means of a ramp of slope omega per sample differ by omega m
        assert 0.5 * (omega * m) ** 2 == pytest.approx(r.R.value**2 * tau**2 / 2, rel=1e-12)


def test_model_random_walk_and_gm_conventions():
    rng = np.random.default_rng(1009)
    x = white(rng, 300_000, 1e-3) + flicker(rng, 300_000, 2e-3) + random_walk(rng, 300_000, 3e-4)
    r = allan_reading(x, FS, regions={"K": (300.0, 1000.0)})
    assert r.B is not None and r.Tc is not None
    assert r.coefficient_values() == {"N": r.N.value, "B": r.B.value, "Tc": r.Tc, "K": r.K.value}
    spec = _spec(r, 50.0)
    assert spec["RW"]["sigma2"] == pytest.approx(r.K.value**2 / 50.0, rel=1e-12)
    assert spec["WN"]["sigma2"] == pytest.approx(r.N.value**2 * 50.0, rel=1e-12)
    # Quinchia eqs. 29 and Table 5: sigma_GM = 0.664 B (the flat deviation), beta = 1 / Tc
    assert math.sqrt(spec["GM"]["sigma2"]) == pytest.approx(BI * r.B.value, rel=1e-12)
    assert spec["GM"]["beta"] == pytest.approx(1.0 / r.Tc, rel=1e-12)
    matched = _spec(allan_reading(x, FS, regions={"K": (300.0, 1000.0)}, gm="matched"), 50.0)
    # the matched GM's AV peak, 0.3811 sigma^2 at 1.8926 / beta, is the flat level at Tc
    assert GM_PEAK_AV * matched["GM"]["sigma2"] == pytest.approx(BI**2 * r.B.value**2, rel=1e-12)
    assert GM_PEAK_X / matched["GM"]["beta"] == pytest.approx(r.Tc, rel=1e-12)


def test_model_reproduces_the_lines():
    rng = np.random.default_rng(1010)
    x = white(rng, 400_000, 1e-3) + random_walk(rng, 400_000, 1e-3)
    r = allan_reading(x, FS)
    model = allan_model(r)
    wv = np.asarray(model.wv(16))
    assert [p.family for p in model.processes] == ["WN", "RW"] and model.freq == FS
    # the Haar wavelet variance is half the Allan variance; the discrete random walk adds
    # K^2 tau / 3 * 1/(2 m^2) to the line, negligible from m = 16 on
    m = 2.0 ** np.arange(16)
    sel = m >= 16
    np.testing.assert_allclose(2 * wv[sel], r.line(m[sel] / FS), rtol=3e-3)


def test_summary_datasheet_column_and_dict():
    rng = np.random.default_rng(1011)
    r = allan_reading(white(rng, 100_000, 1e-3) * 180 / math.pi, FS, unit="deg/s")
    text = r.summary()
    # N in deg/sqrt(h) is 60 x N in deg/sqrt(s) (Gonzalez et al. 2015, eq. 2)
    assert f"{60.0 * r.N.value:.6g}" in text and "deg/sqrt(h)" in text
    assert r.N.value == pytest.approx(1e-3 * 180 / math.pi, rel=0.01)
    d = r.to_dict()
    assert d["coefficients"]["K"] is None
    assert d["coefficients"]["N"]["value"] == r.N.value
    assert json.loads(json.dumps(d, allow_nan=False))["unit"] == "deg/s"


# ----------------------------------------------------------------------------- real data


def _gyro_x() -> np.ndarray:
    path = DATA / "imudata" / "adis_16405_imu1.npz"
    if not path.is_file():
        pytest.skip(f"real data not available: {path} is absent")
    with np.load(path) as z:
        return z["Gyro_X"].astype(float)


@pytest.mark.data
def test_real_gyro_avar_equals_gmwm_wavelet_variance():
    x = _gyro_x()
    ref_path = DATA / "reference" / "adis_16405_imu1_gyroX_gmwm.json"
    if not ref_path.is_file():
        pytest.skip(f"reference not available: {ref_path} is absent")
    ref = json.loads(ref_path.read_text())["wvar"]
    m = np.array(ref["scales_samples"]) // 2
    res = avar(x, FS, taus=m / FS)
    # the Haar wavelet variance is half the overlapping Allan variance (Stebler et al. 2014)
    np.testing.assert_allclose(res.avar / 2, ref["variance"], rtol=1e-10)


@pytest.mark.data
def test_real_gyro_reading_returns_n_and_b():
    x = np.deg2rad(_gyro_x())  # deg/s -> rad/s
    r = allan_reading(x, FS, unit="rad/s")
    assert r.N is not None and r.B is not None
    n_dsh = r.N.value * 180 / math.pi * 60  # deg/sqrt(h)
    b_dsh = r.B.value * 180 / math.pi * 3600  # deg/h
    # ADIS16405 datasheet: angle random walk 2.0 deg/sqrt(h), in-run bias stability 0.007
    # deg/s = 25.2 deg/h (typical values; this unit reads within a factor of two of them)
    assert 1.0 < n_dsh < 4.0 and 12.0 < b_dsh < 50.0
    assert r.B.tau_range[0] <= r.Tc <= r.B.tau_range[1]


# ----------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    ("x", "kwargs", "match"),
    [
        (np.ones(5), {}, "at least 8"),
        (np.r_[np.ones(50), np.nan], {}, "NaN"),
        (np.ones(100), {}, "constant"),
        (None, {"kind": "hadamard"}, "kind"),
        (None, {"method": "eyeball"}, "method"),
        (None, {"gm": "first-order"}, "gm"),
        (None, {"regions": {"X": (1, 2)}}, "regions keys"),
        (None, {"regions": {"N": (5, 1)}}, "not a range"),
        (None, {"regions": {"N": (1e5, 1e6)}}, "holds no averaging time"),
        (None, {"require": ("Z",)}, "require"),
        (None, {"slope_tol": -0.1}, "slope_tol"),
        (None, {"min_share": 1.5}, "min_share"),
        (None, {"alpha": 0.0}, "alpha"),
    ],
)
def test_bad_input_raises(x, kwargs, match):
    if x is None:
        x = np.random.default_rng(0).standard_normal(2000)
    with pytest.raises(InputError, match=match):
        allan_reading(x, FS, **kwargs)
