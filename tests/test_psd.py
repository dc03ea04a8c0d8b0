"""One-sided Welch PSD levels and intervals, log binning against a brute-force loop, and the
N/B/K slope reading against the simulated truth and against the Allan reading (allantools)."""

from __future__ import annotations

import math
from pathlib import Path

import allantools
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stochmod.fit.classical import psd_reading_model
from stochmod.core.errors import EstimationError, InputError
from stochmod.empirical.psd import (
    _bin_correlation,
    log_bin,
    psd,
    psd_reading,
)
from stochmod.core.units import BI_FACTOR

FREQ = 100.0
DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


def _flicker(rng: np.random.Generator, n: int, b: float, freq: float = FREQ) -> np.ndarray:
    """Noise with the IEEE bias-instability spectrum, two-sided S(f) = B^2 / (2 pi |f|), built in
    the frequency domain: E|X_k|^2 = G(f_k) n freq / 2 with G = 2 S the one-sided PSD."""
    f = np.fft.rfftfreq(n, 1.0 / freq)
    g = np.zeros_like(f)
    g[1:] = b**2 / (math.pi * f[1:])
    coef = rng.standard_normal(f.size) + 1j * rng.standard_normal(f.size)
    coef *= np.sqrt(g * n * freq / 4)
    return np.fft.irfft(coef, n)


def _allan_dev(x: np.ndarray, tau: float) -> float:
    (_, ), (adev, ), *_ = allantools.oadev(x, rate=FREQ, data_type="freq", taus=[tau])
    return float(adev)


def test_white_noise_level_is_two_s2_over_freq():
    s2 = 0.25
    x = np.random.default_rng(0).standard_normal(2**16) * math.sqrt(s2)
    spec = psd(x, FREQ, nperseg=1024)
    assert spec.psd.mean() == pytest.approx(2 * s2 / FREQ, rel=0.01)
    assert spec.f[0] == pytest.approx(FREQ / 1024) and spec.f[-1] == pytest.approx(FREQ / 2)
    # segments with 50 % overlap, counted independently
    assert spec.n_segments == len(range(0, x.size - 1024 + 1, 512))
    # per-frequency interval from chi2(2K): about 95 % of the frequencies cover the truth
    cover = np.mean((spec.ci_low <= 2 * s2 / FREQ) & (2 * s2 / FREQ <= spec.ci_high))
    assert 0.92 < cover < 0.98


def test_hann_bin_correlation_closed_form():
    # |FT of w^2|^2 normalised: Hann gives 1, (2/3)^2, (1/6)^2, then 0
    rho = _bin_correlation("hann", 1024)
    np.testing.assert_allclose(rho[:4], [1.0, 4 / 9, 1 / 36, 0.0], atol=1e-12)


def test_binned_interval_covers_the_truth_about_95_percent():
    # effective degrees of freedom discount the Hann correlation of neighbouring frequencies;
    # without it the binned intervals are too narrow (coverage ~ 80 %)
    hits = total = 0
    for seed in range(20):
        x = np.random.default_rng(seed).standard_normal(2**15)
        b = log_bin(psd(x, FREQ, nperseg=2048), 10)
        wide = b.counts >= 8
        hits += np.sum((b.ci_low[wide] <= 2 / FREQ) & (2 / FREQ <= b.ci_high[wide]))
        total += wide.sum()
    assert 0.9 < hits / total < 0.99


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), nper=st.sampled_from([64, 256, 1000]),
       bpd=st.integers(1, 20))
def test_log_bin_against_brute_force_loop(seed, nper, bpd):
    x = np.random.default_rng(seed).standard_normal(4 * nper)
    spec = psd(x, 7.0, nperseg=nper)
    binned = log_bin(spec, bpd)
    rows = []
    k = math.floor(math.log10(spec.f.min()) * bpd) - 1
    while 10 ** (k / bpd) <= spec.f.max():
        lo, hi = 10 ** (k / bpd), 10 ** ((k + 1) / bpd)
        inside = [(f, p) for f, p in zip(spec.f, spec.psd)
                  if lo * (1 - 1e-12) <= f < hi * (1 - 1e-12)]
        if inside:
            fs, ps = zip(*inside)
            geo = math.exp(sum(math.log(f) for f in fs) / len(fs))
            rows.append((geo, sum(ps) / len(ps), len(ps)))
        k += 1
    assert binned.f.size == len(rows)
    np.testing.assert_allclose(binned.f, [r[0] for r in rows], rtol=1e-12)
    np.testing.assert_allclose(binned.psd, [r[1] for r in rows], rtol=1e-12)
    assert binned.counts.tolist() == [r[2] for r in rows]
    assert binned.counts.sum() == spec.f.size


def test_reading_white_noise_equals_truth_and_allan():
    s2 = 0.01
    x = np.random.default_rng(1).standard_normal(200_000) * math.sqrt(s2)
    r = psd_reading(x, FREQ)
    n_true = math.sqrt(s2 / FREQ)  # AV(tau) = N^2 / tau and AV = s2 / m at tau = m / freq
    assert r.N.ci_low < n_true < r.N.ci_high
    assert r.N.value == pytest.approx(n_true, rel=0.01)
    # the Allan reading on the same data: N = sigma(tau) sqrt(tau)
    assert r.N.value == pytest.approx(_allan_dev(x, 1.0) * 1.0, rel=0.04)
    assert r.B is None and r.K is None
    wn = {"family": "WN", "params": {"sigma2": pytest.approx(s2, rel=0.02)}}
    assert r.coefficient_values() == {"N": r.N.value}
    assert psd_reading_model(r).to_spec()["processes"] == [wn]


def test_reading_random_walk_equals_truth_and_allan():
    q = 1e-6  # per-sample increment variance
    x = np.cumsum(np.random.default_rng(2).standard_normal(400_000)) * math.sqrt(q)
    r = psd_reading(x, FREQ)
    k_true = math.sqrt(q * FREQ)  # AV(tau) ~ K^2 tau / 3
    assert r.K.ci_low < k_true < r.K.ci_high
    assert r.K.value == pytest.approx(k_true, rel=0.01)
    tau = 20.0  # 200 clusters in 4000 s: Allan deviation error ~ 1/sqrt(2 * 200 / 1.5) ~ 6 %
    assert r.K.value == pytest.approx(_allan_dev(x, tau) * math.sqrt(3 / tau), rel=0.15)
    assert r.N is None and r.B is None
    rw = {"family": "RW", "params": {"sigma2": pytest.approx(q, rel=0.02)}}
    assert psd_reading_model(r).to_spec()["processes"] == [rw]


def test_reading_bias_instability_equals_truth_and_allan_flat():
    b = 0.02
    x = _flicker(np.random.default_rng(3), 200_000, b)
    r = psd_reading(x, FREQ)
    assert r.B.ci_low < b < r.B.ci_high
    # IEEE 952: the Allan deviation of bias instability is flat at sqrt(2 ln 2 / pi) B = 0.664 B
    assert BI_FACTOR == pytest.approx(0.664, abs=5e-4)
    assert r.B.value == pytest.approx(_allan_dev(x, 1.0) / BI_FACTOR, rel=0.03)
    assert r.N is None and r.K is None


def test_joint_reading_of_white_noise_bias_instability_and_random_walk():
    # corner frequencies N/B at 2 Hz and B/K at 0.05 Hz: each term dominates about a decade
    rng = np.random.default_rng(4)
    n = 1_000_000
    truth = {"N": 0.01, "B": 0.0354, "K": 0.0199}
    x = (rng.standard_normal(n) * truth["N"] * math.sqrt(FREQ) + _flicker(rng, n, truth["B"])
         + np.cumsum(rng.standard_normal(n)) * truth["K"] / math.sqrt(FREQ))
    r = psd_reading(x, FREQ)
    assert sorted(r.terms) == ["B", "K", "N"]
    for name, value in truth.items():
        term = r.terms[name]
        assert term.ci_low < value < term.ci_high, name
    assert r.N.value == pytest.approx(truth["N"], rel=0.02)
    assert r.B.value == pytest.approx(truth["B"], rel=0.05)
    assert r.N.f_low > r.B.f_high and r.B.f_low > r.K.f_high  # N above B above K
    # each line read alone (as by hand) is biased by its neighbours; the joint reading is not
    alone = psd_reading(x, FREQ, joint=False)
    assert alone.B.value > 1.1 * truth["B"]
    def spec(**kw):
        return psd_reading_model(r, **kw).to_spec()

    assert r.coefficient_values() == {"N": r.N.value, "B": r.B.value, "K": r.K.value}
    spec = spec(bias_tc=30.0)
    assert [p["family"] for p in spec["processes"]] == ["WN", "GM", "RW"]
    gm = {"beta": 1 / 30.0, "sigma2": (BI_FACTOR * r.B.value) ** 2}
    assert spec["processes"][1]["params"] == gm
    assert spec["processes"][0]["params"]["sigma2"] == pytest.approx(r.N.value**2 * FREQ)
    assert spec["processes"][2]["params"]["sigma2"] == pytest.approx(r.K.value**2 / FREQ)
    with pytest.raises(InputError, match="bias_tc"):
        psd_reading_model(r)
    with pytest.raises(InputError, match="bias_tc"):
        psd_reading_model(r, bias_tc=-1.0)
    assert [p.family for p in psd_reading_model(r, bias=None).processes] == ["WN", "RW"]
    # the BI family carries the same flicker law: B as read, corner at the region's low end
    bi = psd_reading_model(r, bias="bi").processes[1]
    assert bi.to_spec() == {"family": "BI", "params": {"B": r.B.value, "fc": r.B.f_low}}
    assert psd_reading_model(r, bias="bi", bias_tc=10.0).processes[1].fc == pytest.approx(1 / (20 * math.pi))
    assert psd_reading_model(r, bias="bi", bias_fc=0.01).processes[1].fc == 0.01
    with pytest.raises(InputError, match="bias must be"):
        psd_reading_model(r, bias="flicker")
    model = r.model_psd(r.spectrum.f)
    assert np.median(np.abs(np.log(model / r.spectrum.psd))) < 0.1
    text = r.summary()
    assert "bias instability" in text and "white noise" in text
    # the models' PSDs are the fitted laws where each term was read (one-sided = 2 x two-sided)
    for bias in ("gm", "bi"):
        built = psd_reading_model(r, bias=bias, bias_tc=30.0 if bias == "gm" else None)
        assert built.freq == FREQ
        for term in (r.N, r.K):
            f = np.geomspace(term.f_low, term.f_high, 5)
            np.testing.assert_allclose(2 * built.processes[[0, 2][term is r.K]].psd(f, FREQ),
                                       term.level_at(f, FREQ), rtol=1e-9)


def test_user_ranges():
    s2 = 1.0
    x = np.random.default_rng(5).standard_normal(100_000) * math.sqrt(s2)
    r = psd_reading(x, FREQ, ranges={"N": (1.0, 10.0), "K": (0.1, 0.5)})
    assert not r.N.auto and 1.0 <= r.N.f_low and r.N.f_high <= 10.0
    assert r.N.value == pytest.approx(math.sqrt(s2 / FREQ), rel=0.03)
    assert r.K is not None and not r.K.auto  # forced, however poor
    assert r.to_dict()["N"]["auto"] is False


@pytest.mark.data
def test_adis_gyro_white_noise_agrees_with_allan():
    path = DATA / "imudata" / "adis_16405_imu1.npz"
    if not path.is_file():
        pytest.skip(f"real data not found at {path}")
    with np.load(path) as z:
        x = z["Gyro_X"] - z["Gyro_X"].mean()
    r = psd_reading(x, FREQ)
    # the Allan reading's white-noise level at tau = 0.1 s (where white noise dominates)
    assert r.N.value == pytest.approx(_allan_dev(x, 0.1) * math.sqrt(0.1), rel=0.03)


def test_no_term_on_a_rising_spectrum():
    # differenced white noise: G(f) = (8 / freq) sin^2(pi f / freq), slope +2 -> no N, B or K
    x = np.diff(np.random.default_rng(8).standard_normal(100_001))
    r = psd_reading(x, FREQ)
    assert r.terms == {}
    assert r.coefficient_values() == {}
    with pytest.raises(EstimationError, match="no term"):
        psd_reading_model(r)


def test_model_from_reading():
    x = np.random.default_rng(6).standard_normal(50_000)
    r = psd_reading(x, FREQ)
    model = psd_reading_model(r)
    assert [p.family for p in model.processes] == ["WN"] and model.freq == FREQ
    # WN of unit variance per sample: its density N^2 is 1 / FREQ, read within the interval
    assert model.processes[0].sigma2 == pytest.approx(r.N.value**2 * FREQ, rel=1e-12)
    assert r.N.ci_low**2 * FREQ < 1.0 < r.N.ci_high**2 * FREQ


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda x: psd(x, FREQ, nperseg=10_000), "exceeds"),
        (lambda x: psd(x, FREQ, average="max"), "average"),
        (lambda x: psd(x, FREQ, level=1.5), "level"),
        (lambda x: psd(np.r_[x, np.nan], FREQ), "non-finite"),
        (lambda x: psd(x, 0.0), "freq"),
        (lambda x: psd_reading(x, FREQ, ranges={"Q": (1, 2)}), "unknown term"),
        (lambda x: psd_reading(x, FREQ, ranges={"N": (2, 1)}), "f_low < f_high"),
        (lambda x: psd_reading(x, FREQ, ranges={"N": (10.0, 10.01)}), "need at least 2"),
        (lambda x: psd_reading(x[:8], FREQ), "too short"),
        (lambda x: log_bin(psd(x, FREQ), 0), "bins_per_decade"),
    ],
)
def test_bad_input(call, match):
    x = np.random.default_rng(7).standard_normal(2000)
    with pytest.raises(InputError, match=match):
        call(x)
