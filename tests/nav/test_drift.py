"""The predicted drift over a GNSS outage (stochmod.nav.drift) against emulated drives whose
errors are drawn from the calibration's models, the band's parameter draws against the
calibration's intervals, and ``stochmod drift``."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import chi2

from stochmod.cli import main
from stochmod.core.errors import InputError
from stochmod.data.examples import xsens_mtig_models
from stochmod.io.calibration import AxisCalibration, Calibration
from stochmod.nav.drift import (
    check_drift,
    draw_models,
    horizontal_error_cdf,
    parameter_spreads,
    predicted_drift,
)
from stochmod.nav.emulate import Segment

RATE = 20.0  # Hz: the emulated drives run at the models' rate; low keeps the test fast


def _calibration(log_sd: float = 0.3, rate: float = RATE) -> Calibration:
    """The simulated MTi-G's true models (Stebler Table II) as a calibration whose every
    parameter has the log-scale standard error `log_sd` (interval ``v exp(-+ 1.96 log_sd)``)."""
    axes = []
    for axis, model in xsens_mtig_models(rate).items():
        z = 1.959963984540054
        params = [{"name": n, "value": float(v), "std_error": float(v) * log_sd,
                   "low": float(v) * math.exp(-z * log_sd), "high": float(v) * math.exp(z * log_sd),
                   "unit": ""} for n, v in zip(model.param_names, model.vector())]
        kind = axis.split("_")[0]
        axes.append(AxisCalibration(axis, kind, "rad/s" if kind == "gyro" else "m/s^2", model,
                                    model, details={"parameters": params}))
    return Calibration(axes, rate, 1.0 / rate, int(3600 * rate), "test")


@pytest.fixture(scope="module")
def cal() -> Calibration:
    return _calibration()


@pytest.fixture(scope="module")
def prediction(cal: Calibration):
    return predicted_drift(cal, 30.0, "static", n_draws=30, rng=7, settle=60.0)


def test_emulated_errors_fall_inside_the_predicted_band(cal, prediction) -> None:
    check = check_drift(cal, prediction, runs=100, seed=3)
    lo, hi = prediction.band()
    s = prediction.end_sigma
    assert lo < s < hi
    # the RMS of the actual errors: inside the band, and within the sampling spread of the
    # nominal prediction (squared errors sigma^2 chi2(2)/2 per run, 99.9 % two-sided)
    assert check.inside_band, (check.rms, lo, hi)
    k = 2 * check.runs
    a, b = chi2.ppf([0.0005, 0.9995], k)
    assert s * math.sqrt(a / k) < check.rms < s * math.sqrt(b / k), (check.rms, s)
    # the per-run errors are distributed as the predicted 2-D Gaussian's radius (Rayleigh)
    assert check.ks_pvalue > 0.01
    # the filter of the emulated drives reports the predicted sigma (the same propagation)
    assert np.allclose(check.filter_sigma, s, rtol=0.02)
    assert "KS p-value" in check.summary()


def test_prediction_grows_and_reports(prediction) -> None:
    sig = prediction.sigma
    assert prediction.time[0] == 0.0 and prediction.time[-1] == pytest.approx(30.0)
    assert np.all(np.diff(sig) > 0)  # the drift only grows while coasting
    assert prediction.start_sigma < 2.0 < prediction.end_sigma
    p5, p50, p95 = prediction.percentile([5, 50, 95])[:, -1]
    assert p5 < p50 < p95
    assert prediction.settle_change is not None and abs(prediction.settle_change) < 0.05
    text = prediction.summary()
    assert "Predicted 1-sigma horizontal drift" in text and "settle check" in text
    d = prediction.to_dict()
    assert len(d["band"]["p95"]) == sig.size and d["n_draws"] == 30


def test_draws_reproduce_the_intervals() -> None:
    cal = _calibration(log_sd=0.4)
    sets = draw_models(cal, 3000, rng=1)
    spreads = {(s.axis, s.name): s for s in parameter_spreads(cal)}
    for axis in ("gyro_x", "accel_z"):
        model = cal.axis(axis).model
        vec = np.array([d[axis].vector() for d in sets])
        for i, name in enumerate(model.param_names):
            s = spreads[(axis, name)]
            assert s.scale_sd == pytest.approx(0.4) and not s.held
            lo, hi = np.percentile(vec[:, i], [2.5, 97.5])
            assert lo == pytest.approx(s.low, rel=0.06) and hi == pytest.approx(s.high, rel=0.06)


def test_no_uncertainty_gives_a_band_of_zero_width() -> None:
    cal = _calibration(log_sd=0.0)
    spreads = parameter_spreads(cal)
    assert all(s.scale_sd == 0 and "standard error" in s.held for s in spreads)
    p = predicted_drift(cal, 10.0, "straight", n_draws=2, rng=0, settle=20.0,
                        settle_check=False)
    assert np.allclose(p.draws, p.sigma, rtol=1e-12)
    assert "held at their values" in p.summary()


def test_horizontal_error_cdf() -> None:
    r = np.array([0.5, 1.0, 2.0, 3.0])
    assert np.allclose(horizontal_error_cdf(r, (1.0, 1.0)), 1 - np.exp(-r**2 / 2), atol=1e-12)
    e = np.random.default_rng(0).standard_normal((200_000, 2)) * [1.0, 3.0]
    mc = (np.hypot(e[:, 0], e[:, 1])[:, None] <= r).mean(axis=0)
    assert np.allclose(horizontal_error_cdf(r, (1.0, 3.0)), mc, atol=4e-3)


def test_bad_input(cal) -> None:
    with pytest.raises(InputError, match="motion"):
        predicted_drift(cal, 10.0, "flying", n_draws=0)
    with pytest.raises(InputError, match="outage"):
        predicted_drift(cal, -1.0, n_draws=0)
    with pytest.raises(InputError, match="shorter"):
        predicted_drift(cal, 30.0, [Segment(20.0, speed=5.0)], n_draws=0, settle=10.0)
    few = Calibration([a for a in cal.axes if a.column != "gyro_z"], RATE, 1 / RATE, 100)
    with pytest.raises(InputError, match="gyro_z"):
        predicted_drift(few, 10.0, n_draws=0)


def test_cli_drift(tmp_path, capsys) -> None:
    path = _calibration().write(tmp_path / "calibration.json")
    assert main(["drift", "--calibration", str(path), "--outage", "10", "--settle", "20",
                 "--draws", "3", "--seed", "1"]) == 0
    out = capsys.readouterr().out
    assert "Predicted 1-sigma horizontal drift" in out and "10 s GNSS outage" in out
    assert main(["drift", "--calibration", str(path), "--outage", "10", "--settle", "20",
                 "--draws", "0", "--check", "3", "--motion", "straight"]) == 0
    assert "emulated drive" in capsys.readouterr().out
    assert main(["drift", "--calibration", str(tmp_path / "none.json")]) == 2
    assert main(["drift", "--calibration", str(path), "--outage", "5", "--settle", "10",
                 "--draws", "2", "--json"]) == 0
    assert '"band"' in capsys.readouterr().out
