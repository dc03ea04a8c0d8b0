"""The library main job (stochmod.calibrate) and its file (stochmod.Calibration): final models
that replace the components a record cannot tell from simpler terms, units declared and
checked, and a versioned JSON that round-trips."""

from __future__ import annotations

import json
import math
from pathlib import Path

import attrs
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import stochmod
from stochmod.core.errors import InputError
from stochmod.fit.equivalence import RANDOM_WALK, WHITE_NOISE, replace_equivalents
from stochmod.io.calibration import SCHEMA, Calibration
from stochmod.io.recording import Recording

FREQ = 100.0
DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "imudata"


@pytest.fixture(scope="module")
def base_fit():
    """A GM+WN fit whose model the tests below replace by chosen values (n = 2^14)."""
    x = stochmod.model_from_spec("GM(beta=2, sigma2=1e-6) + WN(sigma2=1e-4)", FREQ).simulate(
        2**14, rng=3)
    return stochmod.gmwm(x, "GM+WN", FREQ)


def _forced(fit, gm_beta: float, gm_sigma2: float, wn: float):
    model = stochmod.model_from_spec(f"GM(beta={gm_beta!r}, sigma2={gm_sigma2!r}) + "
                                     f"WN(sigma2={wn!r})", FREQ)
    return attrs.evolve(fit, model=model)


@settings(max_examples=30, deadline=None)
@given(tc_samples=st.floats(0.02, 0.999), gm_sigma2=st.floats(1e-8, 1e-2), wn=st.floats(1e-8, 1e-2))
def test_gm_faster_than_a_sample_becomes_white_noise_of_its_low_frequency_density(
        base_fit, tc_samples, gm_sigma2, wn) -> None:
    beta = FREQ / tc_samples  # Tc below the sampling interval
    final = replace_equivalents(_forced(base_fit, beta, gm_sigma2, wn), "rad/s")
    (rep,) = final.replacements
    assert rep.term == WHITE_NOISE and math.isclose(rep.tc, 1.0 / beta, rel_tol=1e-12)
    # the sum of the AR(1) autocovariance over all lags, summed term by term
    phi = math.exp(-beta / FREQ)
    lags = np.arange(1, 20_000)
    density = gm_sigma2 * (1.0 + 2.0 * math.fsum(phi ** lags))
    (wn_final,) = final.final.model.processes
    assert wn_final.family == "WN"
    assert wn_final.sigma2 == pytest.approx(wn + density, rel=1e-9)
    assert final.fitted.model.name == "GM+WN" and final.final.model.name == "WN"
    # the WV the filter integrates is the same at long averaging times
    J = 14
    long_fitted, long_final = final.fitted.model.wv(J)[-1], final.final.model.wv(J)[-1]
    assert long_final == pytest.approx(long_fitted, rel=2e-3)


@settings(max_examples=30, deadline=None)
@given(record_fraction=st.floats(0.01, 0.9), gm_sigma2=st.floats(1e-8, 1e-2))
def test_gm_slower_than_the_record_becomes_the_random_walk_of_its_increments(
        base_fit, record_fraction, gm_sigma2) -> None:
    record = base_fit.empirical.n / FREQ
    beta = record_fraction / record  # Tc beyond the record
    final = replace_equivalents(_forced(base_fit, beta, gm_sigma2, 1e-4), "rad/s")
    (rep,) = final.replacements
    assert rep.term == RANDOM_WALK
    phi = math.exp(-beta / FREQ)
    cov = gm_sigma2 * np.array([[1.0, phi], [phi, 1.0]])  # (x_t, x_t+1)
    d = np.array([1.0, -1.0])
    rw = next(p for p in final.final.model.processes if p.family == "RW")
    assert rw.sigma2 == pytest.approx(float(d @ cov @ d), rel=1e-9)
    # q = 2 sigma^2 / Tc per second, to first order in 1 / (Tc freq)
    assert rw.sigma2 * FREQ == pytest.approx(2.0 * gm_sigma2 * beta, rel=beta / FREQ + 1e-12)
    assert final.final.model.name == "WN+RW"


def test_a_resolved_gm_and_an_unknown_unit_are_kept(base_fit) -> None:
    kept = replace_equivalents(_forced(base_fit, 2.0, 1e-6, 1e-4), "rad/s")
    assert kept.replacements == () and kept.final is kept.fitted
    unknown = replace_equivalents(_forced(base_fit, 500.0, 1e-6, 1e-4), None)
    assert unknown.replacements == () and unknown.final.model.name == "GM+WN"


def _recording(units: tuple[str | None, ...], scale: float = 1.0) -> Recording:
    truth = stochmod.model_from_spec("GM(beta=300, sigma2=1e-5) + WN(sigma2=1e-5)", FREQ)
    gyro = np.column_stack([truth.simulate(2**13, rng=k) for k in range(2)]) * scale
    return Recording(gyro, ("gyro_x", "gyro_y"), FREQ, "sim.npz", units=units)


@pytest.fixture(scope="module")
def calibration() -> Calibration:
    return stochmod.calibrate(_recording(("rad/s", "rad/s")), candidates=["WN", "GM+WN"])


def test_calibrate_exports_the_final_model_and_keeps_the_fitted_one(calibration) -> None:
    for axis in calibration.axes:
        assert axis.kind == "gyro" and axis.unit == "rad/s"
        if axis.fitted.name == "GM+WN":  # Tc = 3.3 ms < 10 ms
            assert axis.model.name == "WN" and axis.replacements[0]["term"] == WHITE_NOISE
        sheet = {r["quantity"]: r for r in axis.details["datasheet"]["summary"]}
        assert sheet["white noise density (ARW)"]["model"] > 0  # never "-"
    models = calibration.models
    assert set(models) == {"gyro_x", "gyro_y"}
    aug = calibration.augmentation()
    assert aug.axes == ("gyro_x", "gyro_y")


def test_datasheet_readings_on_threads_equal_the_serial_ones(monkeypatch) -> None:
    from stochmod.empirical.wv_covariance import THREADS_VARIABLE
    from stochmod.output.datasheet import datasheet_reading

    rec = _recording(("rad/s", "rad/s"))
    accel = 9.8 + 1e-3 * np.random.default_rng(7).standard_normal(rec.data.shape[0])
    rec = Recording(np.column_stack([rec.data, accel]), ("gyro_x", "gyro_y", "accel_z"), FREQ,
                    "sim.npz", units=("rad/s", "rad/s", "m/s^2"))
    content = {}
    for threads in ("1", "3"):
        monkeypatch.setenv(THREADS_VARIABLE, threads)
        cal = stochmod.calibrate(rec, candidates=["WN"])
        content[threads] = cal.to_json()
    assert content["1"] == content["3"]
    sheets = json.loads(content["3"])["datasheet"]
    assert set(sheets) == set(rec.columns)
    # each column's own reading (ARW in deg/sqrt(h), VRW in m/s/sqrt(h)), not a neighbour's
    per_sqrt_hour = {"rad/s": math.degrees(1.0) * 60.0, "m/s^2": 60.0}
    for k, column in enumerate(rec.columns):
        reading = datasheet_reading(rec.data[:, k], FREQ, rec.units[k])
        assert sheets[column]["summary"][0]["reading"] == pytest.approx(
            reading.N.value * per_sqrt_hour[rec.units[k]], rel=1e-12)


def test_calibration_round_trips_through_json(calibration, tmp_path) -> None:
    path = calibration.write(tmp_path / "calibration.json")
    content = json.loads(path.read_text())
    assert content["schema"] == SCHEMA == Calibration.SCHEMA
    for column, entry in content["columns"].items():
        assert entry["fitted"]["name"] == calibration.axis(column).fitted.name
        assert entry["model"] == calibration.axis(column).model.to_spec()
    again = Calibration.read(path)
    assert again == calibration and again.models == calibration.models
    assert again.columns == calibration.columns  # the recording's order, not the file's sorted keys


def test_a_schema_one_file_is_read_and_a_newer_one_refused(calibration, tmp_path) -> None:
    old = calibration.to_dict()
    for key in ("schema", "record_sizes", "column_order"):
        old.pop(key)
    for entry in old["columns"].values():
        for key in ("fitted", "replacements", "kind", "unit"):
            entry.pop(key)
    path = tmp_path / "old.json"
    path.write_text(json.dumps(old))
    read = Calibration.read(path)
    assert read.models == {c: calibration.axis(c).model for c in sorted(calibration.columns)}
    assert read.fitted_models == read.models  # version 1 replaced nothing
    assert {a.kind for a in read.axes} == {"gyro"}
    path.write_text(json.dumps({**old, "schema": SCHEMA + 1}))
    with pytest.raises(InputError, match=f"schema {SCHEMA + 1}, written by a newer stochmod"):
        Calibration.read(path)


def test_units_are_declared_never_assumed() -> None:
    with pytest.raises(InputError, match="unit of column 'gyro_x' .* is not known"):
        stochmod.calibrate(_recording((None, None)), candidates=["WN"])
    assumed = stochmod.calibrate(_recording((None, None)), candidates=["WN"], assume_si=True)
    assert assumed.extra["units"]["declared"]["gyro_x"]["source"] == "assumed"
    # the same signal in deg/s gives the same model in rad/s
    deg = stochmod.calibrate(_recording(("deg/s", "deg/s"), scale=180 / math.pi),
                             candidates=["WN"])
    rad = stochmod.calibrate(_recording(("rad/s", "rad/s")), candidates=["WN"])
    for a, b in zip(deg.axes, rad.axes):
        assert a.unit == "rad/s"
        assert a.model.processes[0].sigma2 == pytest.approx(b.model.processes[0].sigma2, rel=1e-9)
    with pytest.raises(InputError, match="is not a rate"):
        stochmod.calibrate(_recording(("m/s^2", "m/s^2")), candidates=["WN"])


@pytest.mark.skipif(not DATA.is_dir(), reason=f"real IMU data not found under {DATA} "
                    "(shared/data is not beside the repository)")
def test_adis_gyros_get_a_white_noise_density_from_their_file_units() -> None:
    """The ADIS16405 file says deg/s; its gyros' fitted GMs of Tc below the 10 ms sample
    interval become white noise, so the datasheet gives an ARW on every axis, in the range
    of the sensor's datasheet (ADIS16405: 2.0 deg/sqrt(h))."""
    rec = stochmod.io.read_recording(DATA / "adis_16405_imu1.npz").select(
        ["Gyro_X", "Gyro_Y", "Gyro_Z"])
    rec = attrs.evolve(rec, data=rec.data[:100_000])
    cal = stochmod.calibrate(rec)
    for axis in cal.axes:
        assert axis.unit == "rad/s"
        assert all(float(p.physical(cal.freq)["Tc"].value) >= 1.0 / cal.freq
                   for p in axis.model.processes if p.family == "GM")
        arw = {r["quantity"]: r for r in axis.details["datasheet"]["summary"]}[
            "white noise density (ARW)"]
        assert 1.0 < arw["model"] < 5.0, arw  # deg/sqrt(h)


def test_calibrate_command_converts_a_files_units_once(tmp_path) -> None:
    """An npz in deg/s and g (its ``units`` entry): the CLI reads, declares and converts the
    units, and the library's own preparation leaves the SI data as they are (a second
    conversion would put the accelerometers' mean at 9.8 g and refuse the file)."""
    from stochmod.cli import main

    rng = np.random.default_rng(0)
    n, sd_deg = 20_000, 0.1
    gyro = rng.normal(0.0, sd_deg, (n, 3)) + [0.01, -0.02, 0.005]  # deg/s
    accel = rng.normal(0.0, 0.002, (n, 3)) + [0.0, 0.0, -1.0]  # g
    path = tmp_path / "imu.npz"
    np.savez(path, freq=FREQ, units="gyro: deg/s, accel: g",
             **{f"Gyro_{a}": gyro[:, k] for k, a in enumerate("XYZ")},
             **{f"Accel_{a}": accel[:, k] for k, a in enumerate("XYZ")})
    out = tmp_path / "out"
    assert main(["calibrate", str(path), "--no-plots", "--out", str(out), "--candidates", "WN",
                 "WN+RW"]) == 0
    cal = Calibration.read(out / "calibration.json")
    gx = cal.axis("Gyro_X")
    assert gx.unit == "rad/s" and gx.model.name == "WN"
    # white noise of sd 0.1 deg/s per sample at 100 Hz: ARW 0.1 deg/s * sqrt(0.01 s) = 0.6 deg/sqrt(h)
    arw = {r["quantity"]: r for r in gx.details["datasheet"]["summary"]}["white noise density (ARW)"]
    assert arw["model"] == pytest.approx(sd_deg * math.sqrt(1.0 / FREQ) * 60.0, rel=0.03)


@pytest.mark.parametrize("pooled", [False, True])
def test_calibrate_command_checks_magnitudes_once_on_every_path(tmp_path, capsys, pooled) -> None:
    """deg/s data declared rad/s are refused by the library's prepare(), for one file and for
    --pooled replicates alike (the command itself no longer checks)."""
    from stochmod.cli import main

    rng = np.random.default_rng(0)
    path = tmp_path / "gyro.npz"
    np.savez(path, freq=FREQ, **{f"gyro_{a}": rng.normal(0.0, 5.0, 20_000) for a in "xyz"})
    files = [str(path), str(path), "--pooled"] if pooled else [str(path)]
    assert main(["calibrate", *files, "--gyro-unit", "rad/s", "--no-plots",
                 "--out", str(tmp_path / "out")]) == 2
    assert "the data look like deg/s" in capsys.readouterr().err
