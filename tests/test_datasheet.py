"""stochmod.output.datasheet: fitted parameters in datasheet units, beside the Allan reading.

Truth is set in datasheet units (deg/s, ug) and converted to SI here by hand (1 deg = pi/180
rad, 1 h = 3600 s, 1 ug = 9.80665e-6 m/s^2), independently of stochmod.core.units.
"""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import stochmod
from stochmod.output.datasheet import datasheet, model_allan_minimum
from stochmod.core.units import sensor_unit, signal_unit
from stochmod.core.errors import InputError
from stochmod.fit.gmwm import gmwm

D2R = math.pi / 180.0
UG = 9.80665e-6
FS = 100.0
N_SAMPLES = 2**16


@pytest.fixture(scope="module")
def gyro_fit():
    """WN + RW gyro with truth in deg: N = 0.005 deg/s/sqrt(Hz), K = 5e-4 deg/s/sqrt(s)."""
    n_deg, k_deg = 0.005, 5e-4
    truth = stochmod.model_from_spec(
        {"processes": [{"family": "WN", "params": {"sigma2": (n_deg * D2R) ** 2 * FS}},
                       {"family": "RW", "params": {"sigma2": (k_deg * D2R) ** 2 / FS}}]}, FS)
    x = truth.simulate(N_SAMPLES, rng=3)
    return gmwm(x, "WN+RW", FS), x, n_deg, k_deg


@pytest.fixture(scope="module")
def accel_fit():
    """GM + WN accelerometer with truth in ug: N = 100 ug/sqrt(Hz), GM Tc = 5 s, sigma = 300 ug."""
    n_ug, tc, s_ug = 100.0, 5.0, 300.0
    truth = stochmod.model_from_spec(
        {"processes": [{"family": "GM", "params": {"beta": 1 / tc, "sigma2": (s_ug * UG) ** 2}},
                       {"family": "WN", "params": {"sigma2": (n_ug * UG) ** 2 * FS}}]}, FS)
    x = truth.simulate(N_SAMPLES, rng=5)
    return gmwm(x, "GM+WN", FS), x, n_ug, tc, s_ug


def _phys(fit, name):
    return next(e for e in fit.physical() if e.name == name)


def test_gyro_arw_and_rrw_equal_the_truth_converted_by_hand(gyro_fit):
    fit, x, n_deg, k_deg = gyro_fit
    ds = datasheet(fit, "gyro", column="gyro_x", x=x)
    arw = ds.row("white noise density (ARW)", "deg/sqrt(h)")
    n_fit = _phys(fit, "WN.N")
    # rad*sqrt(s)/s -> deg/sqrt(h): * 180/pi * sqrt(3600)
    assert arw.model == pytest.approx(n_fit.value / D2R * 60.0, rel=1e-12)
    assert arw.low == pytest.approx(n_fit.low / D2R * 60.0, rel=1e-12)
    assert arw.low < n_deg * 60.0 < arw.high  # truth: 0.005 deg/s/sqrt(Hz) = 0.3 deg/sqrt(h)
    rrw = ds.row("rate random walk", "deg/h/sqrt(h)")
    k_fit = _phys(fit, "RW.K")
    # rad/s/sqrt(s) -> deg/h/sqrt(h): * 180/pi * 3600 * sqrt(3600)
    assert rrw.model == pytest.approx(k_fit.value / D2R * 3600.0 * 60.0, rel=1e-12)
    assert rrw.low < k_deg * 3600.0 * 60.0 < rrw.high
    # the Allan reading of the same data is in the same units and close to the model
    assert arw.reading == pytest.approx(n_deg * 60.0, rel=0.1)


def test_bias_instability_is_the_model_allan_minimum(gyro_fit):
    """WN + RW: AV = N^2/tau + K^2 tau/3 has its minimum 2 N K / sqrt(3) at tau = sqrt(3) N / K;
    B = sqrt(min AV) / sqrt(2 ln 2 / pi) (IEEE 952)."""
    fit, _, _, _ = gyro_fit
    n, k = _phys(fit, "WN.N").value, _phys(fit, "RW.K").value
    tau_star = math.sqrt(3.0) * n / k
    b_si = math.sqrt(2.0 * n * k / math.sqrt(3.0)) / math.sqrt(2.0 * math.log(2.0) / math.pi)
    row = datasheet(fit, "gyro").row("bias instability")
    assert row.unit == "deg/h" and row.note == ""
    assert row.tau == pytest.approx(tau_star, rel=0.05)
    assert row.model == pytest.approx(b_si / D2R * 3600.0, rel=0.01)


def test_accel_vrw_and_gm_in_ug(accel_fit):
    fit, x, n_ug, tc, s_ug = accel_fit
    ds = datasheet(fit, "accel", column="accel_x")
    n_fit = _phys(fit, "WN.N")
    vrw = ds.row("white noise density (VRW)", "ug/sqrt(Hz)")
    assert vrw.model == pytest.approx(n_fit.value / UG, rel=1e-12)
    assert vrw.low < n_ug < vrw.high
    vrw_h = ds.row("white noise density (VRW)", "m/s/sqrt(h)")
    assert vrw_h.model == pytest.approx(n_fit.value * 60.0, rel=1e-12)  # m/s^2*sqrt(s) -> m/s/sqrt(h)
    sig = ds.row("GM sigma")
    assert sig.unit == "ug" and sig.model == pytest.approx(_phys(fit, "GM.sigma").value / UG, rel=1e-12)
    assert sig.low < s_ug < sig.high
    tcr = ds.row("GM correlation time")
    assert tcr.low < tc < tcr.high
    # GM + WN: the Allan deviation keeps falling past the GM, so the minimum is at the edge
    assert "edge" in ds.row("bias instability").note
    text = ds.summary()
    assert "ug/sqrt(Hz)" in text and "accel_x" in text
    d = ds.to_dict()
    assert d["sensor"] == "accel" and {p["name"] for p in d["parameters"]} == {"GM.Tc", "GM.sigma", "WN.N"}


@settings(max_examples=25, deadline=None)
@given(n=st.floats(1e-4, 1e-1), k=st.floats(1e-6, 1e-3))
def test_allan_minimum_matches_the_closed_form_over_the_domain(n, k):
    """The spline minimum of the exact dyadic AV against the closed-form minimum of
    N^2/tau + K^2 tau/3 (+ the RW's discrete term K^2/(6 fs^2 tau)), where it is interior."""
    fs = 100.0
    model = stochmod.model_from_spec(
        {"processes": [{"family": "WN", "params": {"sigma2": n * n * fs}},
                       {"family": "RW", "params": {"sigma2": k * k / fs}}]}, fs)

    class _Fit:  # the two attributes model_allan_minimum reads
        levels = 22
    _Fit.model = model
    tau_star = math.sqrt(3.0 * (n * n + k * k / (6 * fs * fs))) / k
    tau, adev, edge = model_allan_minimum(_Fit)
    if 0.05 < tau_star < 2.0**21 / fs / 2:
        assert not edge
        exact = math.sqrt((n * n + k * k / (6 * fs * fs)) / tau_star + k * k * tau_star / 3)
        assert adev == pytest.approx(exact, rel=2e-3)
        assert tau == pytest.approx(tau_star, rel=0.05)


def test_sensor_kinds_and_bad_input(gyro_fit):
    assert sensor_unit("gyro") == "rad/s" and sensor_unit("deg/s") == "rad/s"
    assert sensor_unit("m/s^2") == "m/s^2" and sensor_unit("mg") == "m/s^2"
    assert signal_unit("gyro_x") == "rad/s" and signal_unit("AccZ") == "m/s^2"
    assert signal_unit("col", "accel") == "m/s^2"
    with pytest.raises(InputError, match="gyroscope or an accelerometer"):
        signal_unit("temperature")
    with pytest.raises(InputError, match="sensor must be"):
        sensor_unit("deg")
    fit, x, _, _ = gyro_fit
    with pytest.raises(InputError, match="not both"):
        datasheet(fit, "gyro", x=x, reading=stochmod.allan_reading(x, FS))
