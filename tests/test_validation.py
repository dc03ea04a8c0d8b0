"""Validation bands (Fig. 5) and the octave-band PSD from the wavelet variance (eqs. 31-33).

Convention under test: eq. 30 integrates the two-sided PSD over the positive octave and
doubles it (both signs of f), so ``C_j = 2^j v_j dt`` (eq. 33) is the TWO-SIDED PSD level,
u^2/Hz; the one-sided level (IEEE plots, ``stochmod.psd``) is ``2 C_j``.
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import signal as sp_signal

import stochmod
from stochmod.core.errors import InputError, SpecError
from stochmod.fit.validation import octave_psd, validate

FREQ = 100.0
GM = stochmod.get_process("GM")
RW = stochmod.get_process("RW")


def _gm_band_average(beta: float, freq: float, j: np.ndarray) -> np.ndarray:
    """Exact average of the sampled GM's two-sided PSD (unit variance) over the octave of level j,
    from the closed-form integral of the AR(1) spectrum (independent of the plugin):
    int S df over [a, b] = (1/pi) [arctan(k tan(pi f / freq))]_a^b, k = (1 + phi) / (1 - phi)."""
    phi = math.exp(-beta / freq)
    k = (1.0 + phi) / -math.expm1(-beta / freq)
    integral = (np.arctan(k * np.tan(np.pi / 2.0**j)) - np.arctan(k * np.tan(np.pi / 2.0 ** (j + 1)))) / np.pi
    return integral / (freq / 2.0 ** (j + 1))


def _rw_leakage(j: np.ndarray) -> np.ndarray:
    """C_j / band average for a random walk, exact: the published Haar WV of RW,
    sigma2 (2^(2j) + 2) / (12 2^j), over twice the band integral of its PSD
    sigma2 / (4 freq sin^2(pi f / freq)), i.e. sigma2 / (4 pi) [cot(pi/2^(j+1)) - cot(pi/2^j)]."""
    wv = (2.0 ** (2 * j) + 2.0) / (12.0 * 2.0**j)
    band = (1.0 / np.tan(np.pi / 2.0 ** (j + 1)) - 1.0 / np.tan(np.pi / 2.0**j)) / (4.0 * np.pi)
    return wv / (2.0 * band)


# ----------------------------------------------------------------------------- octave PSD
@settings(max_examples=60, deadline=None)
@given(sigma2=st.floats(1e-12, 1e6), freq=st.floats(0.01, 1e5), J=st.integers(1, 40))
def test_octave_level_of_white_noise_is_its_two_sided_psd_exactly(sigma2, freq, J):
    wn = stochmod.WN(sigma2=sigma2)
    oct_ = octave_psd(wn.wv(J, freq), freq)
    # closed form: the two-sided PSD of white noise is sigma2 / freq at every frequency
    np.testing.assert_allclose(oct_.level, sigma2 / freq, rtol=1e-13)
    np.testing.assert_allclose(oct_.one_sided, 2.0 * sigma2 / freq, rtol=1e-13)
    j = np.arange(1, J + 1)
    np.testing.assert_allclose(oct_.f_high, freq / 2.0**j, rtol=1e-15)
    np.testing.assert_allclose(oct_.f_low, freq / 2.0 ** (j + 1), rtol=1e-15)
    assert oct_.f_high[0] == pytest.approx(freq / 2.0)  # level 1 ends at Nyquist
    np.testing.assert_array_equal(oct_.f_high[1:], oct_.f_low[:-1])  # contiguous octaves


def test_octave_level_of_random_walk_tends_to_pi2_over_6_times_the_band_average():
    j = np.arange(1, 21)
    sigma2 = 2.5e-7
    wv = sigma2 * (2.0 ** (2 * j) + 2.0) / (12.0 * 2.0**j)  # published Haar WV of RW
    oct_ = octave_psd(wv, FREQ)
    band = sigma2 * (1 / np.tan(np.pi / 2.0 ** (j + 1)) - 1 / np.tan(np.pi / 2.0**j)) / (4 * np.pi)
    average = band / (FREQ / 2.0 ** (j + 1))
    ratio = oct_.level / average
    assert ratio[0] == pytest.approx(math.pi / 2, rel=1e-12)  # j = 1: (1/4) / (1/(2 pi))
    # continuum limit of the Haar kernel 4 sin^4(pi u/2) / (pi u)^2 against u^-2 over [1/2, 1]:
    # (4/pi^2) int_0^inf sin^4(pi u/2) u^-4 du = pi^2/6
    assert ratio[-1] == pytest.approx(math.pi**2 / 6, rel=1e-10)
    np.testing.assert_allclose(ratio, _rw_leakage(j), rtol=1e-12)


@settings(max_examples=60, deadline=None)
@given(beta_rel=st.floats(-7.0, 2.0), freq=st.sampled_from([0.5, 100.0, 4000.0]))
def test_octave_level_of_gm_against_its_band_average_within_the_known_leakage(beta_rel, freq):
    """Eq. 33 replaces the Haar kernel by the octave's indicator. For a GM (corner
    fc = beta / 2 pi) the first-order leakage, derived from the kernel's small-u (pi^2 u^2/4)
    and large-u (3 / (2 pi^2 u^2) on average) forms, is
      plateau (f_high << fc):  1 - C/avg  in [0, (3 / 2 pi) f_high / fc]
      tail    (f_low >> fc):   1 - C/(avg rho_RW)  in [0, (3 pi / 8) fc / f_low]
    and in between C/avg stays in [0.85, 5/3] (RW's largest, level 2, is 1.66608)."""
    beta = 10.0**beta_rel * freq
    J = 30
    j = np.arange(1, J + 1)
    oct_ = octave_psd(GM(beta=beta, sigma2=1.0).wv(J, freq), freq)
    ratio = oct_.level / _gm_band_average(beta, freq, j)
    assert np.all((ratio > 0.85) & (ratio < 5.0 / 3.0))
    fc = beta / (2 * math.pi)
    x, y = oct_.f_high / fc, fc / oct_.f_low
    plateau, tail = x <= 0.05, y <= 0.05
    dev_p = 1.0 - ratio[plateau]
    assert np.all((dev_p >= -1e-12) & (dev_p <= 3 / (2 * math.pi) * x[plateau] + 1e-12))
    dev_t = 1.0 - ratio[tail] / _rw_leakage(j[tail])
    assert np.all((dev_t >= -1e-12) & (dev_t <= 1.001 * 3 * math.pi / 8 * y[tail] + 1e-12))


def test_gm_leakage_constants_are_reached_asymptotically():
    j = np.arange(1, 31)
    # tail: slow GM, levels far above the corner (and away from Nyquist's discreteness)
    beta = 1e-5
    ratio = octave_psd(GM(beta=beta, sigma2=1.0).wv(30, FREQ), FREQ).level / _gm_band_average(beta, FREQ, j)
    fc, flo = beta / (2 * math.pi), FREQ / 2.0 ** (j + 1)
    sel = (j >= 6) & (fc / flo <= 1e-3)
    coef = (1 - ratio[sel] / _rw_leakage(j[sel])) / (fc / flo[sel])
    np.testing.assert_allclose(coef, 3 * math.pi / 8, rtol=5e-3)
    # plateau: fast GM (corner well below Nyquist), deep levels far below the corner
    beta = 0.1
    ratio = octave_psd(GM(beta=beta, sigma2=1.0).wv(30, FREQ), FREQ).level / _gm_band_average(beta, FREQ, j)
    fhi = FREQ / 2.0**j
    sel = fhi / (beta / (2 * math.pi)) <= 1e-3
    coef = (1 - ratio[sel]) / (fhi[sel] / (beta / (2 * math.pi)))
    np.testing.assert_allclose(coef, 3 / (2 * math.pi), rtol=5e-3)


def test_octave_psd_of_empirical_white_noise_against_truth_and_welch():
    sigma2 = 4e-6
    x = np.random.default_rng(7).normal(0.0, math.sqrt(sigma2), 2**16)
    oct_ = octave_psd(stochmod.wvar(x, FREQ))
    truth = sigma2 / FREQ
    inside = (oct_.ci_low <= truth) & (truth <= oct_.ci_high)
    assert inside.mean() >= 0.8  # 95 % intervals, 14 levels
    # peer: scipy's Welch one-sided PSD averaged over the three top octaves (many bins each)
    f, p = sp_signal.welch(x, fs=FREQ, nperseg=1024)
    for k in range(3):
        band = (f > oct_.f_low[k]) & (f < oct_.f_high[k])
        assert oct_.one_sided[k] == pytest.approx(p[band].mean(), rel=0.05)


def test_octave_psd_bad_input():
    with pytest.raises(InputError, match="freq"):
        octave_psd([1.0, 0.5])
    with pytest.raises(InputError, match="positive"):
        octave_psd([1.0, 0.0], FREQ)
    wv = stochmod.wvar(np.random.default_rng(0).normal(size=256), FREQ)
    with pytest.raises(InputError, match="freq"):
        octave_psd(wv, 50.0)


# ----------------------------------------------------------------------------- validate
@pytest.fixture(scope="module")
def gm_wn():
    truth = stochmod.model_from_spec("GM(beta=2.0, sigma2=1e-4)+WN(sigma2=1e-4)", FREQ)
    return truth, truth.simulate(2**14, rng=3)


def test_bands_of_the_true_model_contain_its_theoretical_wv_and_the_data(gm_wn):
    truth, x = gm_wn
    val = validate(truth, x, R=20, rng=1)
    J = val.tau.size
    np.testing.assert_allclose(val.model_wv, truth.wv(J), rtol=1e-14)
    np.testing.assert_allclose(val.tau, 2.0 ** np.arange(J) / FREQ)
    assert val.sim_wv.shape == (20, J)
    # the theoretical WV is the mean of the simulations: within 4 Monte Carlo errors
    se = val.sim_wv.std(axis=0, ddof=1) / math.sqrt(20)
    assert np.all(np.abs(val.sim_wv.mean(axis=0) - val.model_wv) <= 4 * se)
    assert np.all((val.band_low <= val.model_wv) & (val.model_wv <= val.band_high))
    assert np.all(val.band_min <= val.band_low) and np.all(val.band_high <= val.band_max)
    assert val.coverage == pytest.approx(np.mean(val.inside))
    assert val.coverage >= 0.75  # the data come from this model
    # PSD: same frequencies as the data's Welch PSD, model PSD one-sided 2 S(f)
    spec = stochmod.psd(x, FREQ)
    np.testing.assert_array_equal(val.f, spec.f)
    np.testing.assert_array_equal(val.psd, spec.psd)
    inner = val.f < FREQ / 2
    np.testing.assert_allclose(val.model_psd[inner], 2 * truth.psd(val.f[inner]), rtol=1e-14)
    assert val.psd_coverage >= 0.8


def test_simulated_psd_of_white_noise_is_unbiased():
    sigma2 = 1e-4
    model = stochmod.model_from_spec(f"WN(sigma2={sigma2})", FREQ)
    x = model.simulate(2**13, rng=4)
    val = validate(model, x, R=10, rng=2)
    inner = val.f < FREQ / 2  # Welch does not double the Nyquist bin
    # each value: chi2 with 2 K dof (K segments, overlap ignored) -> relative sd 1/sqrt(K)
    k = stochmod.psd(x, FREQ).n_segments
    sims = val.sim_psd[:, inner]
    rel_se = 1.0 / math.sqrt(k * sims.size)
    assert sims.mean() / (2 * sigma2 / FREQ) == pytest.approx(1.0, abs=4 * rel_se * 2)


def test_a_wrong_model_is_caught(gm_wn):
    _, x = gm_wn
    wrong = stochmod.model_from_spec("WN(sigma2=1e-4)", FREQ)
    val = validate(wrong, x, R=20, rng=1)
    assert val.coverage <= 0.3  # the GM bump (levels 4-12) is far outside a white-noise band


def test_validate_a_fit_uses_its_data_levels_and_is_reproducible(gm_wn):
    _, x = gm_wn
    fit = stochmod.gmwm(x, "GM+WN", FREQ)
    a, b = validate(fit), validate(fit, x, rng=0)
    assert a.tau.size == fit.levels
    np.testing.assert_array_equal(a.sim_wv, b.sim_wv)  # same seed, same bands
    np.testing.assert_allclose(a.model_wv, fit.model_wv(), rtol=1e-14)
    c = validate(fit, rng=5)
    assert not np.array_equal(a.sim_wv, c.sim_wv)
    assert a.coverage >= 0.75
    text = a.summary()
    assert "coverage" in text and "GM+WN" in text


def test_validate_from_a_wavelet_variance_has_no_psd(gm_wn):
    truth, x = gm_wn
    wv = stochmod.wvar(x, FREQ, levels=8)
    val = validate(stochmod.Model(truth.processes), wv, R=5)  # unbound: freq from the WV
    assert val.f is None and val.psd_coverage is None and val.n == x.size
    np.testing.assert_array_equal(val.wv, wv.wv)
    assert val.tau.size == 8


def test_model_without_theoretical_wv_uses_the_mean_of_simulations(gm_wn):
    _, x = gm_wn

    class SimOnlyWN(stochmod.WN):  # only simulate(): no wv, psd nor autocovariance
        family = "SimWN"
        wv = stochmod.Process.wv
        wv_jacobian = stochmod.Process.wv_jacobian
        psd = None  # declares no PSD
        autocovariance = stochmod.Process.autocovariance

    model = stochmod.Model((SimOnlyWN(sigma2=2e-4),), FREQ)
    val = validate(model, x, R=8, rng=3)
    np.testing.assert_allclose(val.model_wv, val.sim_wv.mean(axis=0))
    # and that mean is the white-noise WV sigma2 / 2^j within 4 Monte Carlo errors
    truth = 2e-4 / 2.0 ** np.arange(1, val.tau.size + 1)
    se = val.sim_wv.std(axis=0, ddof=1) / math.sqrt(8)
    assert np.all(np.abs(val.model_wv - truth) <= 4 * se)
    assert val.model_psd is None


def test_plot_draws_both_panels(gm_wn):
    pytest.importorskip("matplotlib")
    truth, x = gm_wn
    val = validate(truth, x, R=3)
    fig = val.plot()
    wv_ax, psd_ax = fig.axes
    assert wv_ax.get_xscale() == "log" and psd_ax.get_yscale() == "log"
    line = wv_ax.get_lines()[0]  # first simulation
    np.testing.assert_allclose(line.get_xdata(), val.tau)
    np.testing.assert_allclose(line.get_ydata(), val.sim_wv[0])
    only = validate(truth, stochmod.wvar(x, FREQ), R=3).plot()
    assert len(only.axes) == 1


@pytest.mark.parametrize(
    "kwargs, error, match",
    [
        ({"R": 1}, InputError, "R"),
        ({"levels": 40}, InputError, "levels"),
        ({"freq": 50.0}, InputError, "freq"),
        ({"model": "GM+WN", "freq": FREQ}, SpecError, "free"),
        ({"model": "GM(beta=1.0, sigma2=1.0)"}, InputError, "freq"),
        ({"x_or_wv": np.ones(100)}, InputError, "constant"),
    ],
)
def test_validate_bad_input(gm_wn, kwargs, error, match):
    truth, x = gm_wn
    args = {"model": truth, "x_or_wv": x[:2048]} | kwargs
    model = args.pop("model")
    data = args.pop("x_or_wv")
    with pytest.raises(error, match=match):
        validate(model, data, **args)


def test_validate_needs_data_with_a_model():
    with pytest.raises(InputError, match="x_or_wv"):
        validate(stochmod.model_from_spec("WN(sigma2=1.0)", FREQ))


def test_a_robust_fit_is_validated_with_robust_wavelet_variances():
    """Data and simulations go through the estimator the fit used: for a robust fit on data
    with spikes, the data's WV is the robust one it was fitted to (the classical WV of the
    spiky data is far above it at level 1), and each simulation's WV is the robust WV of
    that series with the fit's efficiency."""
    from stochmod.core.process import as_generator
    from stochmod.output.plots import simulated_wv

    truth = stochmod.model_from_spec("GM(beta=0.5, sigma2=1e-4) + WN(sigma2=1e-4)", FREQ)
    x = truth.simulate(2**14, rng=3)
    x[::500] += 0.5  # 33 spikes of 50 white-noise sigmas
    fit = stochmod.gmwm(x, "GM+WN", FREQ, robust=True, efficiency=0.8)
    bands = validate(fit, x, R=3, rng=4, psd=False)
    J = fit.levels
    np.testing.assert_allclose(bands.wv, fit.empirical.wv[:J], rtol=1e-12)
    classical = stochmod.wvar(x, FREQ, levels=J).wv
    assert classical[0] > 5 * bands.wv[0]
    first = as_generator(4).spawn(3)[0]
    y = fit.model.simulate(x.size, first)
    own = stochmod.wvar(y, FREQ, levels=J, robust=True, efficiency=0.8).wv
    np.testing.assert_allclose(bands.sim_wv[0], own, rtol=1e-12)
    np.testing.assert_allclose(simulated_wv(fit, 3, rng=4)[0], own, rtol=1e-12)
    assert np.max(np.abs(stochmod.wvar(y, FREQ, levels=J).wv / own - 1)) > 1e-3  # not classical
