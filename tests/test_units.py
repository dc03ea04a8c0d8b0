"""Tests of stochmod.core.units: unit parsing and conversion, per-sample values, CEP.

Truth comes from first principles computed here with mpmath (1 deg = pi/180 rad, 1 h = 3600 s,
g0 = 9.80665 m/s^2 exactly), brute-force quadratic forms, statsmodels (AR(1) autocovariance),
and the seed papers (line numbers refer to /work/shared/seeds/*.txt):
G = gonzalez2015-unified-ins-gps-model.txt, Q = quinchia2013-mems-error-model-comparison.txt.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import mpmath as mp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from statsmodels.tsa.arima_process import arma_acovf

import stochmod as sm
from stochmod.core import units as U
from stochmod_gm import discrete as gm_discrete
from stochmod.core.errors import DomainError, InputError

mp.mp.dps = 40
DEG = mp.pi / 180  # rad per degree, from first principles
HOUR = mp.mpf(3600)  # s per hour
G0 = mp.mpf("9.80665")  # standard gravity, m/s^2 (exact by definition)

# unit -> (SI value of one unit, computed here with mpmath; kind)
EXACT = {
    # angle random walk, SI rad/s/sqrt(Hz) = rad/sqrt(s)
    "deg/sqrt(h)": (DEG / mp.sqrt(HOUR), "angle_random_walk"),  # G eq. 2 (line 59): N/60 * pi/180
    "deg/rt-hr": (DEG / mp.sqrt(HOUR), "angle_random_walk"),
    "deg/√h": (DEG / mp.sqrt(HOUR), "angle_random_walk"),
    "deg/hr^0.5": (DEG / mp.sqrt(HOUR), "angle_random_walk"),
    "°/√hr": (DEG / mp.sqrt(HOUR), "angle_random_walk"),
    "deg/h/sqrt(Hz)": (DEG / HOUR, "angle_random_walk"),
    "deg/s/sqrt(Hz)": (DEG, "angle_random_walk"),
    "dps/rtHz": (DEG, "angle_random_walk"),
    "rad/s/sqrt(Hz)": (mp.mpf(1), "angle_random_walk"),
    # velocity random walk, SI m/s^2/sqrt(Hz)
    "m/s/sqrt(h)": (1 / mp.sqrt(HOUR), "velocity_random_walk"),  # G eq. 4 (line 73): N/60
    "m/s/rt-hr": (1 / mp.sqrt(HOUR), "velocity_random_walk"),
    "m/s^2/sqrt(Hz)": (mp.mpf(1), "velocity_random_walk"),
    "ug/sqrt(Hz)": (G0 * mp.mpf("1e-6"), "velocity_random_walk"),
    "µg/√Hz": (G0 * mp.mpf("1e-6"), "velocity_random_walk"),
    "mg/sqrt(Hz)": (G0 * mp.mpf("1e-3"), "velocity_random_walk"),
    # bias instability / rate / acceleration
    "deg/h": (DEG / HOUR, "rate"),
    "dph": (DEG / HOUR, "rate"),
    "deg/s": (DEG, "rate"),
    "rad/s": (mp.mpf(1), "rate"),
    "m/s^2": (mp.mpf(1), "acceleration"),
    "m s^-2": (mp.mpf(1), "acceleration"),
    "m/s/h": (1 / HOUR, "acceleration"),
    "g": (G0, "acceleration"),
    "mg": (G0 / 1000, "acceleration"),
    "ug": (G0 / 10**6, "acceleration"),
    # rate random walk, SI rad/s/sqrt(s)
    "deg/h^1.5": (DEG / HOUR**1.5, "rate_random_walk"),
    "deg/h/sqrt(h)": (DEG / HOUR**1.5, "rate_random_walk"),
    "deg/h^(3/2)": (DEG / HOUR**1.5, "rate_random_walk"),
    "deg/h^3/2": (DEG / HOUR**1.5, "rate_random_walk"),  # Q Table 4 header "(deg/h3/2)"
    "deg/s/sqrt(s)": (DEG, "rate_random_walk"),
    # acceleration random walk, SI m/s^2/sqrt(s)
    "m/s/h^1.5": (1 / HOUR**1.5, "accel_random_walk"),
    "m/s^2/sqrt(s)": (mp.mpf(1), "accel_random_walk"),
    "ug/sqrt(s)": (G0 / 10**6, "accel_random_walk"),
    # quantization
    "rad": (mp.mpf(1), "angle"),
    "deg": (DEG, "angle"),
    "arcsec": (DEG / 3600, "angle"),
    "m/s": (mp.mpf(1), "velocity"),
    # rate ramp
    "deg/h^2": (DEG / HOUR**2, "rate_ramp"),
    "deg/h/h": (DEG / HOUR**2, "rate_ramp"),
    "m/s/h^2": (1 / HOUR**2, "accel_ramp"),
    # time, frequency
    "s": (mp.mpf(1), "time"),
    "ms": (mp.mpf("1e-3"), "time"),
    "min": (mp.mpf(60), "time"),
    "h": (HOUR, "time"),
    "Hz": (mp.mpf(1), "frequency"),
    "1/s": (mp.mpf(1), "frequency"),
    "kHz": (mp.mpf(1000), "frequency"),
    # something without a named kind: a rate PSD
    "(deg/s)^2/Hz": (DEG**2, "other"),
}
UNITS = sorted(EXACT)
POSITIVE = st.floats(min_value=1e-290, max_value=1e290, allow_nan=False, allow_infinity=False)


# ---------------------------------------------------------------- conversions


@pytest.mark.parametrize("unit", UNITS)
def test_one_unit_in_si_is_exact(unit: str) -> None:
    expected, kind = EXACT[unit]
    assert U.to_si(1.0, unit) == pytest.approx(float(expected), rel=4e-16)
    assert U.parse_unit(unit).kind == kind


def test_named_identities() -> None:
    # 1 deg/sqrt(h) = 60 deg/h/sqrt(Hz) (sqrt(3600) = 60); 1 ug/sqrt(Hz) = 9.80665e-6 m/s^2/sqrt(Hz)
    assert U.convert(1.0, "deg/sqrt(h)", "deg/h/sqrt(Hz)") == pytest.approx(60.0, rel=1e-15)
    assert U.to_si(1.0, "ug/sqrt(Hz)") == pytest.approx(9.80665e-6, rel=1e-15)
    assert U.to_si(1.0, "deg/sqrt(h)") == pytest.approx(math.pi / 180 / 60, rel=1e-15)
    assert U.STANDARD_GRAVITY == 9.80665
    assert U.DEG == pytest.approx(float(DEG), rel=1e-16)


@settings(max_examples=300, deadline=None)
@given(x=POSITIVE, unit=st.sampled_from(UNITS))
def test_round_trip_through_si(x: float, unit: str) -> None:
    assert U.from_si(U.to_si(x, unit), unit) == pytest.approx(x, rel=1e-12)
    # and the SI value itself against the exact product
    assert U.to_si(x, unit) == pytest.approx(float(mp.mpf(x) * EXACT[unit][0]), rel=1e-14)


@settings(max_examples=200, deadline=None)
@given(x=POSITIVE, a=st.sampled_from(UNITS), b=st.sampled_from(UNITS))
def test_convert_between_units_of_one_kind(x: float, a: str, b: str) -> None:
    if U.parse_unit(a).dims != U.parse_unit(b).dims:
        with pytest.raises(InputError, match="cannot convert"):
            U.convert(x, a, b)
        return
    expected = mp.mpf(x) * EXACT[a][0] / EXACT[b][0]
    assert U.convert(x, a, b) == pytest.approx(float(expected), rel=1e-14)
    assert U.convert(U.convert(x, a, b), b, a) == pytest.approx(x, rel=1e-12)


def test_arrays_keep_shape_and_scalars_give_floats() -> None:
    x = np.array([[1.0, 2.0], [3.0, 4.5]])
    out = U.to_si(x, "deg/h")
    assert isinstance(out, np.ndarray) and out.shape == (2, 2)
    np.testing.assert_allclose(out, x * float(DEG / HOUR), rtol=1e-15)
    assert type(U.to_si(2.0, "deg/h")) is float
    assert type(U.to_si(np.float64(2.0), "deg/h")) is float


@pytest.mark.parametrize(
    ("kind", "unit"),
    [("N", "deg/sqrt(h)"), ("N", "ug/sqrt(Hz)"), ("B", "deg/h"), ("B", "mg"),
     ("K", "deg/h^1.5"), ("K", "m/s/h^1.5"), ("Q", "deg"), ("Q", "m/s"), ("R", "deg/h^2"),
     ("Tc", "min"), ("fs", "kHz")],
)
def test_kind_accepts_its_units(kind: str, unit: str) -> None:
    assert U.to_si(2.0, unit, kind=kind) == pytest.approx(2.0 * float(EXACT[unit][0]), rel=1e-15)


@pytest.mark.parametrize(
    ("kind", "unit", "named"),
    [("N", "deg/h", "rate"), ("B", "deg/sqrt(h)", "angle_random_walk"),
     ("K", "deg/sqrt(h)", "angle_random_walk"), ("N", "deg/h^1.5", "rate_random_walk"),
     ("B", "deg/h/sqrt(Hz)", "angle_random_walk"),
     ("Tc", "Hz", "frequency"), ("Q", "deg/s", "rate")],
)
def test_kind_mismatch_is_refused_and_named(kind: str, unit: str, named: str) -> None:
    with pytest.raises(InputError, match=named) as err:
        U.to_si(1.0, unit, kind=kind)
    assert repr(unit) in str(err.value) and repr(kind) in str(err.value)
    with pytest.raises(InputError):
        U.from_si(1.0, unit, kind=kind)


@pytest.mark.parametrize(
    ("unit", "match"),
    [("deg/furlong", "furlong"), ("mG", "mG"), ("", "empty"), ("deg/", "ends too early"),
     ("2 deg", "bare number"), ("deg/(h", "expected"), ("deg/h)", "unexpected"),
     ("deg^x", "exponent"), ("deg/s$", "unexpected character")],
)
def test_bad_unit_strings(unit: str, match: str) -> None:
    with pytest.raises(InputError, match=match):
        U.to_si(1.0, unit)


def test_bad_values_and_kinds() -> None:
    with pytest.raises(InputError, match="string"):
        U.parse_unit(3.0)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="kind must be one of"):
        U.to_si(1.0, "deg/h", kind="bias")
    with pytest.raises(InputError, match="non-negative"):
        U.to_si(-1.0, "deg/sqrt(h)", kind="N")
    with pytest.raises(InputError, match="positive"):
        U.to_si(0.0, "s", kind="Tc")
    with pytest.raises(InputError, match="finite"):
        U.to_si(float("nan"), "deg/h")
    with pytest.raises(InputError, match="numeric"):
        U.to_si("1.0", "deg/h")
    # a signed quantity without a coefficient kind keeps its sign (G Table III b_f = -0.151 m/s^2)
    assert U.to_si(-0.151, "m/s^2") == -0.151


# ---------------------------------------------------------------- per-sample values


FS = st.floats(min_value=1e-3, max_value=1e6)
DENSITY = st.floats(min_value=1e-100, max_value=1e100)


@settings(max_examples=200, deadline=None)
@given(n=DENSITY, fs=FS)
def test_white_noise_round_trip(n: float, fs: float) -> None:
    assert U.wn_density(U.wn_variance(n, fs), fs) == pytest.approx(n, rel=1e-12)
    assert U.wn_variance(n, fs) == pytest.approx(float(mp.mpf(n) ** 2 * fs), rel=1e-14)


@settings(max_examples=200, deadline=None)
@given(k=DENSITY, fs=FS)
def test_random_walk_round_trip(k: float, fs: float) -> None:
    assert U.rw_density(U.rw_variance(k, fs), fs) == pytest.approx(k, rel=1e-12)


def _haar_allan(cov: np.ndarray, m: int) -> float:
    """Allan variance at m samples from a covariance matrix, brute force: E[(mean2-mean1)^2]/2."""
    w = np.concatenate([-np.ones(m), np.ones(m)]) / m
    return float(w @ cov[: 2 * m, : 2 * m] @ w) / 2.0


@settings(max_examples=60, deadline=None)
@given(n=st.floats(1e-6, 1e3), fs=st.floats(0.5, 2000.0), m=st.integers(1, 40))
def test_white_noise_variance_gives_the_allan_convention(n: float, fs: float, m: int) -> None:
    # DESIGN: AV of white noise of density N is N^2/tau; the samples are iid with var sigma2.
    sigma2 = U.wn_variance(n, fs)
    av = _haar_allan(sigma2 * np.eye(2 * m), m)
    tau = m / fs
    assert av == pytest.approx(n * n / tau, rel=1e-12)


@settings(max_examples=60, deadline=None)
@given(k=st.floats(1e-6, 1e3), fs=st.floats(0.5, 2000.0), m=st.integers(1, 40))
def test_random_walk_variance_gives_the_allan_convention(k: float, fs: float, m: int) -> None:
    # x_i = sum_{j<=i} w_j, cov = q min(i, j).  Its AV by brute force equals q (2 m^2 + 1) / (6 m)
    # (count of each w_i in mean2 - mean1), i.e. the continuous K^2 tau / 3 times (1 + 1/(2 m^2)).
    q = U.rw_variance(k, fs)
    idx = np.arange(1, 2 * m + 1)
    av = _haar_allan(q * np.minimum.outer(idx, idx), m)
    tau = m / fs
    assert av == pytest.approx(k * k * tau / 3.0 * (1.0 + 1.0 / (2.0 * m * m)), rel=1e-10)


def _sin4_integral(power: int) -> mp.mpf:
    """int_0^inf sin(x)^4 / x^power dx: quadrature over periods of pi, summed by extrapolation."""
    with mp.workdps(20):
        f = lambda x: mp.sin(x) ** 4 / x**power  # noqa: E731
        return mp.nsum(lambda k: mp.quad(f, [k * mp.pi, (k + 1) * mp.pi]), [0, mp.inf])


def test_one_and_two_sided_densities() -> None:
    # AV from the two-sided PSD S2 (Q eq. 14): 4 int_0^inf S2 sin^4(pi f T)/(pi f T)^2 df, and with
    # x = pi f T that is 4 S2 / (pi T) int_0^inf sin^4 x / x^2 dx; from the one-sided S1 = 2 S2 the
    # factor is 2.  White noise of (two-sided) density N must give N^2/T both ways.
    n, tau = 0.7, 2.5
    kern = _sin4_integral(2) / (mp.pi * tau)
    assert float(4 * n**2 * kern) == pytest.approx(n**2 / tau, rel=1e-12)
    d1 = U.one_sided_density(n)
    assert float(2 * d1**2 * kern) == pytest.approx(n**2 / tau, rel=1e-12)
    assert U.two_sided_density(d1) == pytest.approx(n, rel=1e-15)


def test_bias_instability_factor_from_the_flicker_psd() -> None:
    # IEEE 952: bias instability PSD S(f) = B^2 / (2 pi f) (two-sided, below the cut-off).  Its AV
    # by Q eq. 14 is (2 B^2 / pi) int_0^inf sin^4 x / x^3 dx = (2 ln 2 / pi) B^2: the flat floor.
    integral = _sin4_integral(3)
    assert float(integral) == pytest.approx(math.log(2.0), rel=1e-12)
    assert U.BI_FACTOR**2 == pytest.approx(float(2 / mp.pi * integral), rel=1e-12)
    assert abs(U.BI_FACTOR - U.BI_FACTOR_IEEE) < 5e-4  # the rounded 0.664 of IEEE and Q


@settings(max_examples=100, deadline=None)
@given(b=DENSITY, factor=st.floats(0.1, 10.0))
def test_bias_instability_floor_round_trip(b: float, factor: float) -> None:
    assert U.bi_from_floor(U.bi_floor(b, factor), factor) == pytest.approx(b, rel=1e-12)


# ---------------------------------------------------------------- Gauss-Markov


@settings(max_examples=40, deadline=None)
@given(sigma=st.floats(1e-8, 1e3), tc=st.floats(0.05, 1e3), fs=st.floats(1.0, 1000.0))
def test_exact_gm_has_the_continuous_autocovariance(sigma: float, tc: float, fs: float) -> None:
    gm = gm_discrete.gm_discretize(sigma, tc, fs)
    lags = np.arange(8)
    # peer: statsmodels' AR(1) autocovariance with the innovation variance q
    acov = arma_acovf(np.array([1.0, -gm.phi]), np.array([1.0]), nobs=lags.size, sigma2=gm.q)
    np.testing.assert_allclose(acov, sigma**2 * np.exp(-lags / (tc * fs)), rtol=1e-9)
    assert gm.stationary_variance == pytest.approx(sigma**2, rel=1e-9)
    assert gm.tc == pytest.approx(tc, rel=1e-15)


@settings(max_examples=15, deadline=None)
@given(sigma=st.floats(1e-3, 10.0), tc=st.floats(0.1, 100.0), fs=st.floats(1.0, 100.0))
def test_exact_gm_innovation_is_the_integrated_driving_psd(
    sigma: float, tc: float, fs: float
) -> None:
    # continuous GM dx = -x/Tc dt + w, PSD of w = qc: the variance of the step's new part is
    # int_0^dt qc e^{-2s/Tc} ds, and the stationary variance is the same integral to infinity.
    qc = gm_discrete.gm_driving_psd(sigma, tc)
    step = mp.quad(lambda s: qc * mp.exp(-2 * s / tc), [0, 1 / fs])
    total = mp.quad(lambda s: qc * mp.exp(-2 * s / tc), [0, mp.inf])
    assert gm_discrete.gm_discretize(sigma, tc, fs).q == pytest.approx(float(step), rel=1e-12)
    assert float(total) == pytest.approx(sigma**2, rel=1e-12)


@settings(max_examples=200, deadline=None)
@given(sigma=st.floats(1e-100, 1e100), x=st.floats(1e-9, 700.0), fs=FS)
def test_gm_round_trip(sigma: float, x: float, fs: float) -> None:
    tc = 1.0 / (x * fs)  # x = beta / fs
    gm = gm_discrete.gm_discretize(sigma, tc, fs)
    back = gm_discrete.gm_from_discrete(gm.phi, gm.q, fs)
    # phi = exp(-x) carries x only to about eps / x relatively: that is the condition of the inverse
    tol = 1e-12 + 4 * np.finfo(float).eps / min(x, 1.0)
    assert back.tc == pytest.approx(tc, rel=tol)
    assert back.sigma == pytest.approx(sigma, rel=tol)


def test_gm_first_order_forms_of_the_seeds() -> None:
    sigma, tc, fs = 0.01, 4.56, 100.0
    dt, beta = 1.0 / fs, 1.0 / tc
    euler = gm_discrete.gm_discretize(sigma, tc, fs, method="euler")
    # Q eq. 2 (x_k = (1 - beta dt) x_k-1) and eq. 4 (sigma_w^2 = 2 beta sigma^2) times dt
    assert euler.phi == pytest.approx(1.0 - beta * dt, rel=1e-15)
    assert euler.q == pytest.approx(2.0 * beta * sigma**2 * dt, rel=1e-15)
    mixed = gm_discrete.gm_discretize(sigma, tc, fs, method="quinchia2013")
    # Q eq. 3 / Appendix eq. 28: sigma_w^2 = sigma^2 (1 - exp(-2 dt / Tc)), with eq. 2's phi
    assert mixed.phi == euler.phi
    assert mixed.q == pytest.approx(sigma**2 * (1.0 - math.exp(-2.0 * dt / tc)), rel=1e-14)
    # their chains' stationary variances (peer: statsmodels) are off by O(beta dt)
    for gm, expected in ((euler, sigma**2 / (1 - beta * dt / 2)), (mixed, None)):
        acov0 = arma_acovf(np.array([1.0, -gm.phi]), np.array([1.0]), nobs=1, sigma2=gm.q)[0]
        assert gm.stationary_variance == pytest.approx(acov0, rel=1e-10)
        if expected is not None:
            assert acov0 == pytest.approx(expected, rel=1e-10)
        assert abs(acov0 / sigma**2 - 1.0) > 0.1 * beta * dt


def test_gonzalez_printed_gm_psd_is_not_the_driving_psd() -> None:
    # G eq. 22a (line 307): n^2 = sigma^2 * tau.  XBOW1 gyro X, G Table III (lines 449, 455):
    # dbg = 3.427e-3 deg/s, tau = 250.7 s.  The driving PSD giving var = sigma^2 is 2 sigma^2 / tau.
    sigma, tau = U.to_si(3.427e-3, "deg/s"), 250.7
    printed = gm_discrete.gm_driving_psd(sigma, tau, form="gonzalez2015")
    assert printed == pytest.approx((3.427e-3 * math.pi / 180) ** 2 * 250.7, rel=1e-14)
    def stationary(qc: float) -> float:
        return float(mp.quad(lambda s: qc * mp.exp(-2 * s / tau), [0, mp.inf]))

    assert stationary(gm_discrete.gm_driving_psd(sigma, tau)) == pytest.approx(sigma**2, rel=1e-12)
    assert stationary(printed) == pytest.approx(sigma**2 * tau**2 / 2, rel=1e-12)


def test_gm_summary_and_arrays() -> None:
    gm = gm_discrete.gm_discretize([0.1, 0.2], [10.0, 20.0], 100.0)
    assert isinstance(gm.phi, np.ndarray) and gm.phi.shape == (2,)
    np.testing.assert_allclose(gm.phi, np.exp(-np.array([1e-3, 5e-4])), rtol=1e-15)
    text = gm.summary()
    assert "Tc [s]" in text and len(text.splitlines()) == 5


def test_gm_bad_input() -> None:
    with pytest.raises(InputError, match="fs"):
        gm_discrete.gm_discretize(1.0, 1.0, 0.0)
    with pytest.raises(InputError, match="tc"):
        gm_discrete.gm_discretize(1.0, -1.0, 100.0)
    with pytest.raises(InputError, match="sigma"):
        gm_discrete.gm_discretize(-1.0, 1.0, 100.0)
    with pytest.raises(InputError, match="Tc \\* fs > 1"):
        gm_discrete.gm_discretize(1.0, 0.005, 100.0, method="euler")
    with pytest.raises(InputError, match="method"):
        gm_discrete.gm_discretize(1.0, 1.0, 100.0, method="tustin")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="form"):
        gm_discrete.gm_driving_psd(1.0, 1.0, form="groves")  # type: ignore[arg-type]
    for phi in (0.0, 1.0, 1.2, -0.5):
        with pytest.raises(DomainError, match="phi must lie in the open interval"):
            gm_discrete.gm_from_discrete(phi, 1e-6, 100.0)
        # one conversion: the GM plugin's constructor refuses the same input the same way
        with pytest.raises(DomainError, match="phi must lie in the open interval"):
            sm.get_process("GM").from_ar1(phi, 1e-6, 100.0)


# ---------------------------------------------------------------- Quinchia et al. (2013)

DT = 0.01  # Q line 1505: "the sampling time of the INS i.e., 0.01 s"
# Q Table 4 (lines 945-965): N (m/s/sqrt(h) | deg/sqrt(h)), B (m/s/h | deg/h), K (m/s/h^1.5);
# Q Table 5 (line 974): Tc (s)
ACC = {
    "X": (0.045, 5.1581, 166.30, 4.56),
    "Y": (0.045, 4.5507, 24.95, 7.26),
    "Z": (0.047, 1.8336, 13.53, 20.74),
}
GYRO = {"X": (2.420, 44.533, 490.89), "Y": (1.988, 38.810, 623.25), "Z": (2.164, 31.717, 735.17)}


@pytest.mark.parametrize("axis", sorted(ACC))
def test_quinchia_appendix_accelerometers(axis: str) -> None:
    n, b, k, tc = ACC[axis]
    fs = 1.0 / DT
    # eq. 27 (line 1648): q_n = N^2 / (3600 dt)
    q_n = U.wn_variance(U.to_si(n, "m/s/sqrt(h)", kind="N"), fs)
    assert q_n == pytest.approx(n**2 / (3600 * DT), rel=1e-13)
    # eq. 29 (line 1673): sigma_GM = B * 0.664 / 3600
    # eq. 28 (line 1664): q_bi = sigma_GM^2 (1 - e^{-2 dt/Tc})
    gm = gm_discrete.gm_from_bias_instability(U.to_si(b, "m/s/h", kind="B"), tc, fs, factor=U.BI_FACTOR_IEEE,
                                    method="quinchia2013")
    sigma_gm = b * 0.664 / 3600
    assert gm.sigma == pytest.approx(sigma_gm, rel=1e-13)
    assert gm.q == pytest.approx(sigma_gm**2 * (1 - math.exp(-2 * DT / tc)), rel=1e-12)
    assert gm.phi == pytest.approx(1 - DT / tc, rel=1e-15)  # eq. 21 (line 1503): I - diag(beta dt)
    # the exact form has the same q (eq. 28 is exact) and phi = exp(-dt/Tc)
    exact = gm_discrete.gm_from_bias_instability(U.to_si(b, "m/s/h"), tc, fs, factor=U.BI_FACTOR_IEEE)
    assert exact.q == pytest.approx(gm.q, rel=1e-14)
    # eq. 30 (line 1681): q_k = K^2 dt / 3600^3
    q_k = U.rw_variance(U.to_si(k, "m/s/h^1.5", kind="K"), fs)
    assert q_k == pytest.approx(k**2 * DT / 3600**3, rel=1e-13)


def test_quinchia_appendix_acc_x_numbers() -> None:
    # eqs. 27-30 for Acc X worked by hand: 0.045^2/36 = 5.625e-5; 5.1581*0.664/3600 = 9.513829e-4;
    # 166.30^2 * 0.01 / 3600^3 = 5.927574e-9; (9.513829e-4)^2 (1 - e^{-0.02/4.56}) = 3.961173e-9
    fs = 100.0
    assert U.wn_variance(U.to_si(0.045, "m/s/sqrt(h)"), fs) == pytest.approx(5.625e-5, rel=1e-13)
    gm = gm_discrete.gm_from_bias_instability(U.to_si(5.1581, "m/s/h"), 4.56, fs, factor=0.664)
    assert gm.sigma == pytest.approx(9.513829e-4, rel=1e-6)
    assert gm.q == pytest.approx(3.961173e-9, rel=1e-6)
    assert U.rw_variance(U.to_si(166.30, "m/s/h^1.5"), fs) == pytest.approx(5.927574e-9, rel=1e-6)


@pytest.mark.parametrize("axis", sorted(GYRO))
def test_quinchia_appendix_gyros(axis: str) -> None:
    # eqs. 27-29 written for the x accelerometer; for a gyro the same with deg -> rad (pi/180)
    n, b, tc = GYRO[axis]
    fs, d = 1.0 / DT, math.pi / 180
    q_n = U.wn_variance(U.to_si(n, "deg/sqrt(h)"), fs)
    assert q_n == pytest.approx((n * d) ** 2 / (3600 * DT), rel=1e-13)
    gm = gm_discrete.gm_from_bias_instability(U.to_si(b, "deg/h"), tc, fs, factor=0.664)
    sigma_gm = b * d * 0.664 / 3600
    assert gm.sigma == pytest.approx(sigma_gm, rel=1e-13)
    assert gm.q == pytest.approx(sigma_gm**2 * (1 - math.exp(-2 * DT / tc)), rel=1e-12)


def test_quinchia_bias_instability_from_the_floor() -> None:
    # Q lines 914-917 (eq. 18): flat line at 29.57 deg/h, divided by 0.664 -> B = 44.533 deg/h
    # (also Table 4, line 963)
    b = U.bi_from_floor(U.to_si(29.57, "deg/h"), factor=U.BI_FACTOR_IEEE)
    assert U.from_si(b, "deg/h", kind="B") == pytest.approx(44.533, abs=5e-4)


def test_quinchia_table2_ar1_as_gauss_markov() -> None:
    # Q Table 2 (lines 771-772): gyro X AR(1) alpha_1 = -0.999, beta_0^2 = 1.014e-10 (rad/s)^2,
    # 100 Hz, x(n) = -alpha_1 x(n-1) + beta_0 w(n).  Tc = -1/(fs ln 0.999) = 9.995 s and
    # sigma^2 = q / (1 - 0.999^2).
    gm = gm_discrete.gm_from_discrete(0.999, 1.014e-10, 100.0)
    assert gm.tc == pytest.approx(float(-1 / (100 * mp.log(mp.mpf("0.999")))), rel=1e-12)
    assert gm.tc == pytest.approx(9.995, abs=1e-3)
    acov0 = arma_acovf(np.array([1.0, -0.999]), np.array([1.0]), nobs=1, sigma2=1.014e-10)[0]
    assert gm.sigma2 == pytest.approx(acov0, rel=1e-10)
    # the accelerometers' alpha_1 = -1 (lines 753-754) is a random walk, not a Gauss-Markov process
    with pytest.raises(DomainError, match="phi"):
        gm_discrete.gm_from_discrete(1.0, 2.129e-10, 100.0)


# ---------------------------------------------------------------- Gonzalez et al. (2015)

# G Table III (lines 437-442): ARW n_g (deg/s/sqrt(Hz)) and VRW n_f (m/s^2/sqrt(Hz)),
# XBOW1 / XSENS1 / GLAD, X axis
TABLE3_ARW = (3.996e-2, 8.230e-2, 1.418e-1)
TABLE3_VRW = (1.353e-3, 1.493e-3, 4.094e-2)


@pytest.mark.parametrize("n_g", TABLE3_ARW)
def test_gonzalez_eq2_table3_arw(n_g: float) -> None:
    # eq. 2 (line 59): n_g = N/60 * pi/180 rad/s/sqrt(Hz) for N in deg/sqrt(h);
    # Table III gives n_g in deg/s/sqrt(Hz)
    n_si = U.to_si(n_g, "deg/s/sqrt(Hz)", kind="N")
    n_datasheet = U.from_si(n_si, "deg/sqrt(h)", kind="N")
    assert n_datasheet == pytest.approx(60 * n_g, rel=1e-14)  # e.g. 3.996e-2 -> 2.3976 deg/sqrt(h)
    assert n_si == pytest.approx(n_datasheet / 60 * math.pi / 180, rel=1e-14)


@pytest.mark.parametrize("n_f", TABLE3_VRW)
def test_gonzalez_eq4_table3_vrw(n_f: float) -> None:
    # eq. 4 (line 73): n_f = N/60 m/s^2/sqrt(Hz) for N in m/s/sqrt(h);
    # 1.353e-3 -> 0.08118 m/s/sqrt(h)
    n_datasheet = U.from_si(U.to_si(n_f, "m/s^2/sqrt(Hz)"), "m/s/sqrt(h)", kind="N")
    assert n_datasheet == pytest.approx(60 * n_f, rel=1e-14)
    assert U.from_si(n_f, "ug/sqrt(Hz)") == pytest.approx(n_f / 9.80665e-6, rel=1e-14)


def test_gonzalez_table3_dynamic_bias() -> None:
    # Table III line 449: XBOW1 dbg_x = 3.427e-3 deg/s = 12.3372 deg/h = 5.98124e-5 rad/s
    assert U.convert(3.427e-3, "deg/s", "deg/h", kind="B") == pytest.approx(12.3372, rel=1e-13)
    assert U.to_si(3.427e-3, "deg/s") == pytest.approx(5.981243e-5, rel=1e-6)


def test_gonzalez_eq7_cep() -> None:
    # eq. 7 (line 99): sigma = 0.8493 CEP (4 digits); line 425: the GPS has 1.5 m CEP -> 1.27395 m
    assert U.cep_to_sigma(1.5) == pytest.approx(0.8493 * 1.5, rel=5e-5)
    assert 1.0 / U.CEP_FACTOR == pytest.approx(0.8493, abs=5e-5)


@settings(max_examples=25, deadline=None)
@given(r=st.floats(1e-3, 1e4), p=st.floats(0.01, 0.99))
def test_circular_error_probability_by_quadrature(r: float, p: float) -> None:
    # independent: mass of a circular 2-D normal (sigma per axis) inside radius r, polar quadrature
    sigma = U.cep_to_sigma(r, p=p)
    mass = mp.quad(lambda rho: rho / sigma**2 * mp.exp(-(rho**2) / (2 * sigma**2)), [0, r])
    assert float(mass) == pytest.approx(p, rel=1e-12)
    assert U.sigma_to_cep(sigma, p=p) == pytest.approx(r, rel=1e-12)


# ---------------------------------------------------------------- bad input, per-sample functions


@pytest.mark.parametrize("fs", [0.0, -100.0, float("nan"), float("inf"), True, "100"])
@pytest.mark.parametrize("func", [U.wn_variance, U.wn_density, U.rw_variance, U.rw_density])
def test_per_sample_functions_refuse_bad_fs(func: Callable[..., object], fs: object) -> None:
    with pytest.raises(InputError, match="fs"):
        func(1.0, fs)


@pytest.mark.parametrize("func", [U.wn_variance, U.wn_density, U.rw_variance, U.rw_density])
def test_per_sample_functions_refuse_negative_densities(func: Callable[..., object]) -> None:
    with pytest.raises(InputError, match="non-negative"):
        func(-1e-3, 100.0)
    with pytest.raises(InputError, match="non-negative"):
        func(np.array([1e-3, -1e-3]), 100.0)


def test_other_bad_input() -> None:
    with pytest.raises(InputError, match="non-negative"):
        U.bi_floor(-1.0)
    with pytest.raises(InputError, match="factor"):
        U.bi_from_floor(1.0, factor=0.0)
    with pytest.raises(InputError, match="factor"):
        U.bi_floor(1.0, factor=[0.6, 0.7])  # type: ignore[arg-type]
    with pytest.raises(InputError, match="non-negative"):
        U.cep_to_sigma(-1.5)
    for p in (0.0, 1.0, 1.5):
        with pytest.raises(InputError, match="p"):
            U.cep_to_sigma(1.5, p=p)
    with pytest.raises(InputError, match="non-negative"):
        U.two_sided_density(-1.0)
