"""stochmod.output.exports: Kalibr / OpenVINS / pyins / stochmod-nav configurations from fitted models.

Every exported number is recomputed here from the fitted model's canonical per-sample values
(``model.to_spec()``) by hand: N = sqrt(sigma2_WN / fs), K = sqrt(sigma2_RW fs); the GM and
AR(2) random-walk bounds by brute force over lags (AR(2) autocovariance from statsmodels).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml
from statsmodels.tsa.arima_process import arma_acovf

import stochmod
from stochmod.cli import main
from stochmod.core.errors import InputError
from stochmod.output.exports import (kalibr_yaml, noise_terms, openvins_yaml, pyins_parameters,
                              random_walk_bound, stochmod_nav_config)
from stochmod.fit.gmwm import gmwm

FS = 100.0
N = 2**15


def _wn_rw(n_density: float, k: float) -> stochmod.Model:
    return stochmod.model_from_spec(
        {"processes": [{"family": "WN", "params": {"sigma2": n_density**2 * FS}},
                       {"family": "RW", "params": {"sigma2": k**2 / FS}}]}, FS)


TRUTH = {"gyro_x": (3e-3, 4e-5), "accel_x": (2e-3, 5e-4)}  # (N, K) in SI


@pytest.fixture(scope="module")
def fits():
    return {col: gmwm(_wn_rw(*nk).simulate(N, rng=11 + i), "WN+RW", FS)
            for i, (col, nk) in enumerate(TRUTH.items())}


def _params(model, family):
    return next(p["params"] for p in model.to_spec()["processes"] if p["family"] == family)


def test_kalibr_densities_from_the_model_and_within_the_fit_interval_of_the_truth(fits):
    axes = [noise_terms(fit, "gyro" if c.startswith("gyro") else "accel", column=c)
            for c, fit in fits.items()]
    doc = yaml.safe_load(kalibr_yaml(axes, rostopic="/imu"))
    assert doc["rostopic"] == "/imu" and doc["update_rate"] == FS
    for col, prefix in (("gyro_x", "gyroscope"), ("accel_x", "accelerometer")):
        model = fits[col].model
        n = math.sqrt(_params(model, "WN")["sigma2"] / FS)  # per-sample variance -> density
        k = math.sqrt(_params(model, "RW")["sigma2"] * FS)  # increment variance -> K
        assert doc[f"{prefix}_noise_density"] == pytest.approx(n, rel=1e-12)
        assert doc[f"{prefix}_random_walk"] == pytest.approx(k, rel=1e-12)
        axis = next(a for a in axes if a.column == col)
        n_true, k_true = TRUTH[col]
        assert axis.noise_interval[0] < n_true < axis.noise_interval[1]
        assert axis.walk_interval[0] < k_true < axis.walk_interval[1]


def test_openvins_has_kalibr_values_under_imu0(fits):
    axes = [noise_terms(fit, c.split("_")[0], column=c) for c, fit in fits.items()]
    text = openvins_yaml(axes)
    assert text.startswith("%YAML:1.0")
    doc = yaml.safe_load(text.split("\n", 1)[1])["imu0"]
    kal = yaml.safe_load(kalibr_yaml(axes))
    for key in ("gyroscope_noise_density", "gyroscope_random_walk", "accelerometer_noise_density",
                "accelerometer_random_walk", "update_rate"):
        assert doc[key] == kal[key]
    assert np.array_equal(doc["T_i_b"], np.eye(4)) and doc["model"] == "kalibr"


def test_gm_random_walk_bound_closed_form_and_brute_force():
    """GM: K^2 = 2 sigma^2 (1 - exp(-H/Tc)) / H (D(T)/T decreasing); checked by brute force."""
    sigma2, beta = 4e-6, 0.05
    gm = stochmod.model_from_spec({"processes": [{"family": "GM", "params":
                                                  {"beta": beta, "sigma2": sigma2}}]}, FS).processes[0]
    for H in (1 / FS, 0.5, 10.0, 1000.0):
        closed = math.sqrt(2 * sigma2 * -math.expm1(-H * beta) / H)
        assert random_walk_bound(gm, FS, H) == pytest.approx(closed, rel=1e-9)
        lags = np.arange(max(1, round(H * FS)), 200_000)
        brute = np.max(2 * sigma2 * -np.expm1(-beta * lags / FS) * FS / lags)
        assert random_walk_bound(gm, FS, H) == pytest.approx(math.sqrt(brute), rel=1e-9)
    # a horizon of one sample: the GM's driving noise 2 sigma^2 / Tc to first order
    assert random_walk_bound(gm, FS, 1 / FS) == pytest.approx(math.sqrt(2 * sigma2 * beta), rel=1e-3)


def test_ar2_random_walk_bound_against_statsmodels_brute_force():
    phi = (1.2, -0.6)  # complex roots: an oscillating autocovariance
    ar = stochmod.model_from_spec({"processes": [{"family": "AR", "order": 2,
                                                  "params": {"phi": list(phi), "sigma2": 1e-4}}]},
                                  FS).processes[0]
    acv = arma_acovf(np.r_[1, -np.array(phi)], np.array([1.0]), nobs=5000, sigma2=1e-4)
    for H in (1 / FS, 0.05, 1.0):
        k0 = max(1, round(H * FS))
        lags = np.arange(k0, 5000)
        brute = np.max(2 * (acv[0] - acv[lags]) * FS / lags)
        assert random_walk_bound(ar, FS, H) ** 2 == pytest.approx(brute, rel=1e-6)


def test_fast_gm_is_white_and_slow_gm_a_walk_in_the_exports():
    fast = {"family": "GM", "params": {"beta": 500.0, "sigma2": 1e-4}}  # Tc = 2 ms < 10 ms
    slow = {"family": "GM", "params": {"beta": 0.01, "sigma2": 1e-6}}
    wn = {"family": "WN", "params": {"sigma2": 1e-4}}
    truth = stochmod.model_from_spec({"processes": [fast, slow, wn]}, FS)
    # the GMs held at their values, WN fitted
    fit = gmwm(truth.simulate(2**12, rng=1), {"processes": [fast, slow, {"family": "WN"}]}, FS)
    axis = noise_terms(fit, "gyro", horizon=2.0)
    phi = math.exp(-500.0 / FS)
    wn_fit = fit.model.to_spec()["processes"][2]["params"]["sigma2"]
    n2 = wn_fit / FS + 1e-4 * (1 + phi) / (1 - phi) / FS  # WN + the fast GM's low-frequency density
    assert axis.noise_density == pytest.approx(math.sqrt(n2), rel=1e-6)
    assert axis.random_walk == pytest.approx(math.sqrt(2e-6 * -math.expm1(-0.02) / 2.0), rel=1e-9)
    assert [how for _, how in axis.rules] == ["white equivalent", "random walk bound at H = 2 s", "white"]
    assert axis.bias_sd == pytest.approx(math.sqrt(1e-4 + 1e-6 + axis.random_walk**2 * 2**12 / FS))


def test_ramp_is_refused_with_a_clear_error():
    model = stochmod.model_from_spec("WN(sigma2=1e-4) + RR(omega=1e-7)", FS)
    fit = gmwm(model.simulate(2**12, rng=1), "WN + RR(omega=1e-7)", FS)
    with pytest.raises(InputError, match="rate ramp"):
        noise_terms(fit, "gyro")
    with pytest.raises(InputError, match="horizon"):
        noise_terms(fit, "gyro", horizon=-1.0)


def test_pyins_and_stochmod_nav(fits):
    axes = [noise_terms(fit, c.split("_")[0], column=c) for c, fit in fits.items()]
    p = pyins_parameters(axes)
    model = fits["gyro_x"].model
    k = math.sqrt(_params(model, "RW")["sigma2"] * FS)
    T = N / FS
    assert p["gyro"]["noise"] == pytest.approx(math.sqrt(_params(model, "WN")["sigma2"] / FS))
    assert p["gyro"]["bias_walk"] == pytest.approx(k)
    assert p["gyro"]["bias_sd"] == pytest.approx(k * math.sqrt(T))  # the walk over the record
    assert p["units"]["accel"]["bias_walk"] == "m/s^3/sqrt(Hz)"
    units = {"gyro_x": "rad/s", "accel_x": "m/s^2"}
    nav = stochmod_nav_config(fits, units)
    for col, fit in fits.items():
        rebuilt = stochmod.model_from_spec(nav["axes"][col]["model"], nav["freq"])
        assert np.array_equal(rebuilt.wv(10), fit.model.wv(10))
        assert nav["axes"][col]["unit"] == units[col]
    assert nav["axes"]["gyro_x"]["parameter_units"]["WN.sigma2"] == "(rad/s)^2"


def test_pyins_reads_the_exported_parameters_as_the_fitted_model(fits):
    """The peer's own model and simulator take the export's keywords (pyins 1.0.1,
    ``inertial_sensor.EstimationModel`` and ``Parameters``); errors pyins simulates from them
    have the fitted model's wavelet variance: a refit recovers the exported model."""
    pyins_sensor = pytest.importorskip("pyins.inertial_sensor")
    pd = pytest.importorskip("pandas")
    axes = [noise_terms(fit, c.split("_")[0], column=c) for c, fit in fits.items()]
    p = pyins_parameters(axes)
    keywords = {k: p["gyro"][k] for k in ("bias_sd", "noise", "bias_walk")}
    est = pyins_sensor.EstimationModel(**keywords)  # refuses a misnamed or misshaped keyword
    assert est.n_states == 3 and np.allclose(np.diag(est.P), keywords["bias_sd"] ** 2)
    assert np.allclose(est.q, keywords["bias_walk"]) and np.allclose(est.v, keywords["noise"])
    n = 2**17
    imu = pd.DataFrame(0.0, index=pd.Index(np.arange(n) / FS, name="time"),
                       columns=["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"])
    simulated = pyins_sensor.apply_imu_parameters(
        imu, "rate", pyins_sensor.Parameters(noise=keywords["noise"],
                                             bias_walk=keywords["bias_walk"], rng=3),
        pyins_sensor.Parameters(rng=4))
    refit = gmwm(simulated["gyro_x"].to_numpy(), "WN+RW", FS)
    z = (refit.model.vector() - fits["gyro_x"].model.vector()) / refit.std_errors
    assert np.all(np.abs(z) < 4), z


def test_calibrate_export_writes_the_files(tmp_path, capsys):
    x = np.column_stack([_wn_rw(*TRUTH[c]).simulate(N, rng=20 + i) for i, c in enumerate(TRUTH)])
    path = tmp_path / "imu.npz"
    np.savez(path, gyro_x=x[:, 0], accel_x=x[:, 1], freq=FS)
    out = tmp_path / "out"
    assert main(["calibrate", "--assume-si", str(path), "--candidates", "WN", "WN+RW", "--no-plots",
                 "--out", str(out), "--export", "kalibr", "openvins", "pyins", "stochmod-nav"]) == 0
    text = capsys.readouterr().out
    assert "kalibr_imu.yaml" in text and "deg/sqrt(h)" in text
    doc = yaml.safe_load((out / "kalibr_imu.yaml").read_text())
    report = json.loads((out / "calibration.json").read_text())
    spec = report["columns"]["gyro_x"]["model"]
    wn = next(p for p in spec["processes"] if p["family"] == "WN")
    assert doc["gyroscope_noise_density"] == pytest.approx(math.sqrt(wn["params"]["sigma2"] / FS))
    assert report["units"]["signal"] == {"gyro_x": "rad/s", "accel_x": "m/s^2"}
    assert report["datasheet"]["gyro_x"]["summary"][0]["unit"] == "deg/sqrt(h)"
    assert (out / "kalibr_imu_chain.yaml").exists() and (out / "pyins_imu.json").exists()
    assert json.loads((out / "stochmod_nav.json").read_text())["format"] == "stochmod-nav"
    # one sensor only: Kalibr needs both
    np.savez(path, gyro_x=x[:, 0], freq=FS)
    assert main(["calibrate", "--assume-si", str(path), "--candidates", "WN+RW", "--no-plots", "--out",
                 str(out), "--export", "kalibr"]) == 2
    assert "accel" in capsys.readouterr().err
