"""Outage studies on the error signal of a static recording (Stebler et al. 2014, Section VI):
the windows are non-overlapping and outside the calibration span, the signal is centred and in
SI whatever the file's units, and a filter built from the calibration of the record's true model
is consistent (NEES in its chi-square band) on a short synthetic record; the ADIS16405 file
reads with its units."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import stochmod
from stochmod.cli import main
from stochmod.core.errors import InputError
from stochmod.nav.emulate import AXES, Segment
from stochmod.nav.logs import calibration_record, read_calibration
from stochmod.nav.study import StaticErrors, nees_band, outage_study, static_errors

FS = 50.0
WN, GM = stochmod.WN, stochmod.GM
GYRO = (WN.from_density(3e-4, FS) + GM.from_correlation_time(60.0, 3e-4)).bind(FS)
ACCEL = (WN.from_density(2e-3, FS) + GM.from_correlation_time(60.0, 5e-3)).bind(FS)
TRUTH = {a: GYRO if a.startswith("gyro") else ACCEL for a in AXES}
PROFILE = [Segment(20, speed=15), Segment(15, turn=90), Segment(30, speed=20),
           Segment(20, turn=-120, speed=12), Segment(30), Segment(20, turn=60, speed=18),
           Segment(30, speed=22), Segment(15, turn=-90)]
OUTAGES = [(60.0, 30.0), (130.0, 30.0)]
WINDOW = int(sum(s.duration for s in PROFILE) * FS) + 1  # samples of the emulated drive
CALIBRATION_SPAN = 200.0  # s at the start of the synthetic record the "calibration" used
DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "imudata"
TURN_ON = np.array([0.5, -0.3, 0.2, 0.01, -0.02, -1.01])  # deg/s and g: raw offsets, gravity


@pytest.fixture(scope="module")
def static_file(tmp_path_factory):
    """A raw static record in deg/s and g (gravity and turn-on biases in it) whose error
    signal is simulated from TRUTH, and the calibration.json of that true model."""
    folder = tmp_path_factory.mktemp("static")
    n = int(CALIBRATION_SPAN * FS) + 9 * WINDOW
    rng = np.random.default_rng(2014)
    si = np.column_stack([TRUTH[a].simulate(n, rng) for a in AXES])
    scale = np.array([np.pi / 180] * 3 + [9.80665] * 3)
    raw = si / scale + TURN_ON
    names = ["Gyro_X", "Gyro_Y", "Gyro_Z", "Accel_X", "Accel_Y", "Accel_Z"]
    np.savez(folder / "static.npz", **{c: raw[:, k] for k, c in enumerate(names)}, freq=FS,
             units="gyro: deg/s, accel: g",
             sensor=np.array(["Gyroscope"] * 3 + ["Accelerometer"] * 3))
    calibration = {"freq": FS, "n": int(CALIBRATION_SPAN * FS),
                   "columns": {a: {"model": m.to_spec()} for a, m in TRUTH.items()}}
    (folder / "true.json").write_text(json.dumps(calibration))
    white = {a: stochmod.Model((m.processes[0],)).bind(FS) for a, m in TRUTH.items()}
    calibration["columns"] = {a: {"model": m.to_spec()} for a, m in white.items()}
    (folder / "white.json").write_text(json.dumps(calibration))
    return folder, si


def test_windows_are_disjoint_and_avoid_the_excluded_spans() -> None:
    data = np.random.default_rng(0).normal(size=(1000, 6))
    rec = StaticErrors(data, 10.0, excluded=((100, 250), (600, 610)))
    windows = rec.windows(90)
    # free stretches [0, 100), [250, 600), [610, 1000) hold 1 + 3 + 4 windows of 90 samples
    assert windows == [(0, 90), (250, 340), (340, 430), (430, 520), (610, 700), (700, 790),
                       (790, 880), (880, 970)]
    used = np.zeros(1000, int)
    for start, stop in windows:
        used[start:stop] += 1
    assert used.max() == 1  # no sample in two windows
    assert not used[100:250].any() and not used[600:610].any()
    assert rec.windows(90, 3) == windows[:3]
    with pytest.raises(InputError, match="holds 8 window"):
        rec.windows(90, 9)
    with pytest.raises(InputError, match="not inside the usable part"):
        rec.errors((90, 180))
    with pytest.raises(InputError, match="whole static record"):
        StaticErrors(data, 10.0, excluded=((0, 1000),))
    with pytest.raises(InputError, match="6 channels"):
        StaticErrors(data[:, :3], 10.0)
    with pytest.raises(InputError, match="mean must be"):
        StaticErrors(data, 10.0, mean="median")


def test_error_signal_is_the_record_less_its_mean() -> None:
    rng = np.random.default_rng(1)
    data = rng.normal(size=(800, 6)) + np.arange(6.0)
    data[:200] += 50.0  # the excluded (calibration) span does not enter the mean
    rec = StaticErrors(data, 10.0, excluded=((0, 200),))
    mean = data[200:].mean(axis=0)
    windows = rec.windows(100)
    for w in windows:
        np.testing.assert_allclose(rec.errors(w), data[w[0]:w[1]] - mean, atol=1e-12)
    pooled = np.concatenate([rec.errors(w) for w in windows])
    np.testing.assert_allclose(pooled.mean(axis=0), 0.0, atol=1e-12)
    per_window = StaticErrors(data, 10.0, excluded=((0, 200),), mean="window")
    for w in windows:
        e = per_window.errors(w)
        np.testing.assert_allclose(e.mean(axis=0), 0.0, atol=1e-12)
        np.testing.assert_allclose(e, data[w[0]:w[1]] - data[w[0]:w[1]].mean(0), atol=1e-12)


def test_units_are_converted_and_the_calibration_span_excluded(static_file) -> None:
    folder, si = static_file
    rec = static_errors(str(folder / "static.npz"), exclude=[(0.0, CALIBRATION_SPAN)])
    assert rec.freq == FS and rec.excluded == ((0, int(CALIBRATION_SPAN * FS)),)
    # deg/s and g in the file: rad/s and m/s^2 out, the raw offsets and gravity removed
    keep = rec.usable
    np.testing.assert_allclose(rec.data, si + TURN_ON * ([np.pi / 180] * 3 + [9.80665] * 3),
                               rtol=1e-12, atol=1e-15)
    w = rec.windows(WINDOW, 1)[0]
    assert w[0] >= CALIBRATION_SPAN * FS
    np.testing.assert_allclose(rec.errors(w), si[w[0]:w[1]] - si[keep].mean(0), atol=1e-12)
    # the same file with its units stripped: refused, unless the user names them
    with np.load(folder / "static.npz") as d:
        bare = {k: d[k] for k in d.files if k != "units"}
    np.savez(folder / "bare.npz", **bare)
    with pytest.raises(InputError, match="unit"):
        static_errors(str(folder / "bare.npz"))
    again = static_errors(str(folder / "bare.npz"), gyro_unit="deg/s", accel_unit="g")
    np.testing.assert_allclose(again.data, rec.data, rtol=1e-12)
    # a rate other than the file's (calibrations at another rate) is refused
    with pytest.raises(InputError, match="sampled at 50 Hz"):
        static_errors(str(folder / "static.npz"), freq=100.0)
    # deg/s read as rad/s betrays itself by its magnitude, as in calibrate
    with pytest.raises(InputError, match="rad/s"):
        static_errors(str(folder / "bare.npz"), gyro_unit="rad/s", accel_unit="g")


def test_true_model_calibration_is_consistent_on_the_record(static_file) -> None:
    folder, _ = static_file
    path = folder / "true.json"
    errors = static_errors(str(folder / "static.npz"), exclude=[(0.0, CALIBRATION_SPAN)])
    runs = 6
    study = outage_study({"true": read_calibration(path)}, errors=errors, runs=runs, seed=3,
                         profile=PROFILE, outages=OUTAGES, rate=FS, gyro_bias_sd=1e-3,
                         accel_bias_sd=0.02, dt_filter=1.0, record=calibration_record(path))
    # each run its own window, none overlapping another or the calibration span
    starts = [s for s, _ in study.windows]
    assert len(study.windows) == runs and starts[0] >= CALIBRATION_SPAN * FS
    assert all(b[0] >= a[1] for a, b in zip(study.windows, study.windows[1:]))
    assert study.end_nees["true"].shape == (runs, len(OUTAGES))
    # end-of-outage NEES pooled over runs and outages inside its 95 % chi-square band
    lo, hi = nees_band(runs * len(OUTAGES))
    assert lo < study.end_nees["true"].mean() < hi
    rms = study.consistency("true")[:, 1]
    assert np.all((rms > 0.6) & (rms < 1.6)), rms
    assert 6.0 < study.nees["true"].mean() < 13.0
    assert study.nees_band() == nees_band(runs)
    assert "static.npz" in study.errors_source and "band" in study.summary()


def test_outages_cli_with_errors_and_several_calibrations(static_file, capsys) -> None:
    folder, _ = static_file
    code = main(["outages", "--errors", str(folder / "static.npz"),
                 "--calibration", str(folder / "true.json"),
                 "--calibration", str(folder / "white.json"), "--names", "true", "white",
                 "--exclude", f"0:{CALIBRATION_SPAN:g}", "--runs", "2", "--quick",
                 "--dt-filter", "1"])
    assert code == 0
    out = capsys.readouterr().out
    assert "2 window(s) of" in out and "static.npz" in out
    assert "true" in out and "white" in out and "RMS error/sigma" in out
    for bad in (["--names", "one"],  # one name for two calibrations
                ["--exclude", "0-200"]):
        assert main(["outages", "--errors", str(folder / "static.npz"),
                     "--calibration", str(folder / "true.json"),
                     "--calibration", str(folder / "white.json"), "--runs", "1", "--quick",
                     *bad]) == 2
    # several calibrations without --errors: which one would be the truth?
    assert main(["outages", "--calibration", str(folder / "true.json"),
                 "--calibration", str(folder / "white.json"), "--runs", "1"]) == 2
    # more runs than the record holds windows: the message says how many fit
    assert main(["outages", "--errors", str(folder / "static.npz"),
                 "--calibration", str(folder / "true.json"), "--runs", "50", "--quick"]) == 2
    assert "window(s)" in capsys.readouterr().err


def test_study_takes_models_or_a_record_not_both(static_file) -> None:
    folder, _ = static_file
    errors = static_errors(str(folder / "static.npz"))
    with pytest.raises(InputError, match="not both"):
        outage_study({"x": TRUTH}, TRUTH, errors=errors, runs=1)
    with pytest.raises(InputError, match="not both"):
        outage_study({"x": TRUTH}, runs=1)
    with pytest.raises(InputError, match="Hz"):
        outage_study({"x": TRUTH}, errors=errors, runs=1, rate=100.0)
    with pytest.raises(InputError, match="unknown filter"):
        outage_study({"x": TRUTH}, errors=errors, runs=1, rate=FS, record={"y": 10.0})


@pytest.mark.skipif(not DATA.is_dir(),
                    reason=f"real IMU data not found under {DATA} (shared/data is not beside "
                           "the repository)")
def test_adis_recording_reads_in_si_with_disjoint_windows() -> None:
    rec = static_errors(str(DATA / "adis_16405_imu1.npz"), exclude=[(0.0, 5000.0)])
    assert rec.freq == 100.0 and rec.excluded == ((0, 500000),)
    windows = rec.windows(60001)
    assert len(windows) == 8 and windows[0][0] == 500000 and windows[-1][1] <= 1000000
    e = rec.errors(windows[0])
    # gyro noise of a few mrad/s (not deg/s), accelerometers a few cm/s^2 around zero (no g)
    assert np.all(np.std(e[:, :3], axis=0) < 0.02)
    assert np.all(np.abs(np.mean(e[:, 3:], axis=0)) < 0.05)


def test_outages_cli_prints_each_calibrations_predicted_drift(static_file, capsys) -> None:
    """Beside the actual errors, the 1-sigma horizontal drift each calibration predicts at the
    end of each outage: the filter's own covariance along the study's drive
    (stochmod.nav.drift.predicted_drift with the study's settings and its schedule of fixes:
    none in the earlier outages, the last 1 s before the outage's start).
    The calibration of the record's true model predicts what its filter then meets: the
    end-of-outage errors over the predicted sigma have an RMS near 1; the white-noise-only
    calibration, which knows no bias, predicts a far smaller drift."""
    from stochmod.cli.outages import (
        QUICK_OUTAGES,
        QUICK_PROFILE,
        STUDY_SPEED,
        STUDY_START,
        _last_fix,
    )
    from stochmod.nav.drift import predicted_drift

    folder, _ = static_file
    code = main(["outages", "--errors", str(folder / "static.npz"),
                 "--calibration", str(folder / "true.json"),
                 "--calibration", str(folder / "white.json"), "--names", "true", "white",
                 "--exclude", f"0:{CALIBRATION_SPAN:g}", "--runs", "2", "--quick",
                 "--dt-filter", "1", "--drift-draws", "2"])
    assert code == 0
    out = capsys.readouterr().out
    assert "Predicted 1-sigma horizontal drift" in out and "2 parameter draw(s)" in out
    rows = {}
    for line in out.splitlines():
        cells = line.split()
        if len(cells) == 8 and cells[0].endswith("+30") and cells[2] in ("true", "white"):
            rows[(cells[0], cells[2])] = [float(c) for c in cells[3:]]
    assert len(rows) == 4, out
    sigma = {}
    for k, (start, _) in enumerate(QUICK_OUTAGES):
        # the study's filters take no fix from an outage's start: the last is 1 s before it
        pred = predicted_drift(str(folder / "true.json"), outage=31.0,
                               motion=list(QUICK_PROFILE), settle=start - 1, speed=STUDY_SPEED,
                               start=STUDY_START, dt_filter=1.0, n_draws=0, settle_check=False,
                               earlier_outages=QUICK_OUTAGES[:k])
        sigma[start] = pred.end_sigma
        true, white = rows[(f"{start:g}+30", "true")], rows[(f"{start:g}+30", "white")]
        assert true[2] == pytest.approx(pred.end_sigma, rel=1e-3)  # 4 digits printed
        assert white[2] < 0.5 * true[2]
        assert true[3] <= true[2] <= true[4]  # the band holds the nominal (no spreads here)
    # the true model's predicted sigma is about the true filter's error: max errors of 2 runs
    # within a factor 3 of the sigma at the end
    for start, s in sigma.items():
        assert s / 3 < rows[(f"{start:g}+30", "true")][0] < 3 * s
    # an outage right after another: the last fix is the one before both
    assert _last_fix(90.0, [(60.0, 30.0)]) == (59.0, [])
    assert _last_fix(130.5, [(60.0, 30.0)]) == (130.0, [(60.0, 30.0)])
    assert main(["outages", "--calibration", str(folder / "true.json"), "--runs", "1",
                 "--drift-draws", "-1"]) == 2
