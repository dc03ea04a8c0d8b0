"""The predicted drift over a GNSS outage (stochmod.nav.drift) against emulated drives whose
errors are drawn from the calibration's models, the band's parameter draws against the
calibration's intervals, and ``stochmod drift``."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.stats import chi2

from stochmod.cli import main
from stochmod.core.errors import InputError
from stochmod.core.model import Model
from stochmod.data.examples import xsens_mtig_models
from stochmod.fit.classical.build import family_for
from stochmod.io.calibration import AxisCalibration, Calibration
from stochmod.nav.drift import (
    check_drift,
    draw_models,
    horizontal_error_cdf,
    parameter_spreads,
    predicted_drift,
)
from stochmod.nav.emulate import Segment, cep_to_sigma, ideal_imu

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


def _white_calibration(n_gyro: float, n_accel: float, rate: float = 10.0) -> Calibration:
    """White noise alone on every axis: gyro density `n_gyro` (rad/s/sqrt(Hz)), accelerometer
    density `n_accel` (m/s^2/sqrt(Hz))."""
    white = family_for(("N",))
    axes = []
    for axis in ("gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"):
        kind = axis.split("_")[0]
        n = n_gyro if kind == "gyro" else n_accel
        model = Model((white.from_ieee952({"N": n}, rate),)).bind(rate)
        axes.append(AxisCalibration(axis, kind, "rad/s" if kind == "gyro" else "m/s^2", model,
                                    model))
    return Calibration(axes, rate, 1.0 / rate, int(3600 * rate), "test")


def _horizontal_channel(g: float, n_gyro: float, n_accel: float, init: tuple, sigma_h: float,
                        sigma_vel: float, fixes: list[bool]) -> float:
    """1-sigma position error (m) of one horizontal axis at rest, by a covariance propagation
    of its own: states (position, velocity, tilt), ``r' = v``, ``v' = g tilt + w_a``, ``tilt'
    = w_g`` (white densities `n_accel`, `n_gyro`), exactly discretised over 1 s (Van Loan),
    position and velocity fixes of sigmas `sigma_h` (m) and `sigma_vel` (m/s) at the seconds
    where `fixes` is true, from the diagonal initial covariance of 1-sigmas `init`."""
    f = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, g], [0.0, 0.0, 0.0]])
    w = np.diag([0.0, n_accel**2, n_gyro**2])
    big = np.zeros((6, 6))
    big[:3, :3], big[:3, 3:], big[3:, 3:] = -f, w, f.T
    e = expm(big)
    phi = e[3:, 3:].T
    q = phi @ e[:3, 3:]
    p = np.diag(np.square(init))
    h = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    r = np.diag([sigma_h**2, sigma_vel**2])
    for fix in fixes:
        p = phi @ p @ phi.T + q
        if fix:
            k = p @ h.T @ np.linalg.inv(h @ p @ h.T + r)
            p = (np.eye(3) - k @ h) @ p
    return float(np.sqrt(p[0, 0]))


def test_earlier_outages_are_left_out_of_the_prediction() -> None:
    """At rest with white-noise models only, each horizontal axis is the double integrator of
    the accelerometer noise and of gravity times the tilt, the gyro noise's integral (Earth
    rate, Schuler and Coriolis terms move a 30 s outage by less than 0.1 %). An independent
    covariance propagation of that channel with the study's schedule of fixes (1 Hz, none from
    60 to 90 s, the last at 92 s, 30 s outage) gives the prediction of outage 2 with outage 1
    left out; with its fixes kept the prediction is 14 % smaller, because the tilt the gap let
    grow is not yet re-estimated after two fixes."""
    n_g, n_a = 1e-4, 1e-2
    cal = _white_calibration(n_g, n_a)
    init = (1.0, 0.1, (0.5, 0.5, 0.01))  # a small heading sigma keeps gyrocompassing out
    kw = {"outage": 30.0, "motion": "static", "n_draws": 0, "settle": 92.0, "init_sd": init,
          "settle_check": False, "record": None}
    gap = predicted_drift(cal, earlier_outages=[(60.0, 30.0)], **kw)
    full = predicted_drift(cal, **kw)
    assert gap.conditions.outages[0] == (60.0, 30.0) and len(full.conditions.outages) == 1
    assert "none from 60 to 90 s" in gap.conditions.describe()
    g = float(np.linalg.norm(ideal_imu(gap.conditions.trajectory(10.0), "increment").accel[1])
              * 10.0)  # the specific force at rest, m/s^2
    seconds = np.arange(1, 123)
    sd0 = (1.0, 0.1, math.radians(0.5))
    for pred, fixes in ((gap, (seconds <= 92) & ~((seconds >= 60) & (seconds < 90))),
                        (full, seconds <= 92)):
        expected = _horizontal_channel(g, n_g, n_a, sd0, cep_to_sigma(2.0), 0.1, list(fixes))
        assert pred.time[-1] == pytest.approx(30.0)
        assert pred.sigma_ne[-1] == pytest.approx([expected, expected], rel=1e-3)
        assert pred.end_sigma == pytest.approx(math.sqrt(2.0) * expected, rel=1e-3)
    assert gap.end_sigma > 1.1 * full.end_sigma
    # a single outage: the same as an empty schedule of earlier ones
    assert predicted_drift(cal, earlier_outages=(), **kw).end_sigma == full.end_sigma
    with pytest.raises(InputError, match="earlier outage"):
        predicted_drift(cal, earlier_outages=[(80.0, 20.0)], **kw)


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


def test_calibrate_predicts_the_drift_into_its_console_file_and_report(tmp_path, capsys) -> None:
    """``calibrate --drift T --report``: the console, OUT/drift.json and the report give the
    prediction that :func:`predicted_drift` makes from the calibration file written."""
    import json

    out = tmp_path / "out"
    assert main(["calibrate", "--n", "16384", "--candidates", "WN", "WN+RW", "--no-plots",
                 "--report", "--drift", "20", "--drift-draws", "3", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    again = predicted_drift(out / "calibration.json", outage=20.0, n_draws=3, rng=0)
    saved = json.loads((out / "drift.json").read_text())
    assert saved["sigma"][-1] == pytest.approx(again.end_sigma, rel=1e-12)
    assert saved["n_draws"] == 3 and saved["conditions"]["outage"] == 20.0
    low, high = again.band()
    assert (f"1-sigma horizontal {again.end_sigma:.4g} m (5-95 % over 3 parameter draws: "
            f"{low:.4g}-{high:.4g} m)") in printed
    page = (out / "report.html").read_text()
    assert page.index('id="drift"') < page.index('id="gyro_x"')
    assert f"<b>{again.end_sigma:.4g} m</b>" in page


def test_calibrate_refuses_a_drift_it_cannot_predict_before_fitting(tmp_path, capsys) -> None:
    path = tmp_path / "gyros.csv"
    rng = np.random.default_rng(1)
    np.savetxt(path, rng.normal(0.0, 1e-3, (4096, 3)), delimiter=",",
               header="gyro_x [rad/s],gyro_y [rad/s],gyro_z [rad/s]", comments="")
    out = tmp_path / "out"
    assert main(["calibrate", str(path), "--freq", "100", "--no-plots", "--drift", "60",
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--drift needs one column each of gyro_x" in err and "accel_x" in err
    assert not (out / "calibration.json").exists()
    assert main(["calibrate", "--n", "16384", "--no-plots", "--drift", "-5", "--out", str(out)]) == 2
    assert "--drift takes the outage's length in seconds" in capsys.readouterr().err
