"""``stochmod combine`` and ``stochmod combiners``: files in, synthetic .npz out.

Truth: the synthetic columns equal the library's combination of the same arrays (itself
tested against simulated truth in tests/test_combiners.py), the written file reads back
through stochmod.io.recording, and the printed noise reduction of the mean of 4 equal sensors is the
closed form 50 %.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import stochmod
from stochmod.cli import main
from stochmod.io.recording import read_recording

FREQ = 100.0


@pytest.fixture
def sensors(tmp_path: Path) -> tuple[list[str], np.ndarray]:
    rng = np.random.default_rng(42)
    truth = np.sin(np.arange(4000) / 200.0)
    sig = np.array([1.0, 3.0, 1.0, 1.0]) * 1e-2
    x = truth + sig[:, None] * rng.standard_normal((4, 2, truth.size))[:, 0]
    y = -truth + sig[:, None] * rng.standard_normal((4, truth.size))
    files = []
    for i in range(4):
        path = tmp_path / f"imu{i}.npz"
        np.savez(path, gyro_x=x[i], gyro_y=y[i], freq=FREQ)
        files.append(str(path))
    return files, np.stack([x, y], axis=-1)


def test_combine_mean_writes_the_synthetic_columns(sensors, tmp_path: Path, capsys) -> None:
    files, data = sensors
    out = tmp_path / "syn.npz"
    assert main(["combine", *files, "--method", "mean", "--out", str(out), "--no-plots"]) == 0
    text = capsys.readouterr().out
    assert "50.0%" in text and "imu3.npz" in text
    rec = read_recording(out, columns=["gyro_x", "gyro_y"])
    np.testing.assert_allclose(rec.data, data.mean(axis=0), rtol=1e-14)
    assert rec.freq == FREQ
    with np.load(out) as z:
        assert z["gyro_x_weights"].shape == (4000, 4)
        np.testing.assert_allclose(z["gyro_y_variance"],
                                   stochmod.combine(data[..., 1], "mean").variance, rtol=1e-14)


def test_combine_garch_prints_volatility_parameters(sensors, tmp_path: Path, capsys) -> None:
    files, data = sensors
    out = tmp_path / "g.npz"
    assert main(["combine", *files, "--method", "garch", "--arma", "0", "0", "--garch", "1", "1",
                 "--column", "gyro_x", "--out", str(out), "--json", "--workers", "2"]) == 0
    report = json.loads(capsys.readouterr().out)
    ref = stochmod.combine(data[..., 0], "garch", arma=(0, 0), garch=(1, 1))
    np.testing.assert_allclose(report["columns"]["gyro_x"]["mean_weights"], ref.weights.mean(axis=1),
                               rtol=1e-12)
    # the noisier sensor (index 1) gets the smallest weight
    assert int(np.argmin(report["columns"]["gyro_x"]["mean_weights"])) == 1
    assert report["weights_of_the_mean"] == []
    with np.load(out) as z:
        np.testing.assert_allclose(z["gyro_x"], ref.signal, rtol=1e-12)
    assert out.with_suffix(".png").exists() or __import__("importlib").util.find_spec("matplotlib") is None


def test_combine_inverse_variance_from_calibrations(sensors, tmp_path: Path) -> None:
    files, data = sensors
    cals = []
    for i, s2 in enumerate((1e-4, 9e-4, 1e-4, 1e-4)):
        model = stochmod.model_from_spec(f"WN(sigma2={s2})", FREQ)
        path = tmp_path / f"cal{i}.json"
        path.write_text(json.dumps({"columns": {"gyro_x": {"model": model.to_spec()}}}))
        cals += ["--calibration", str(path)]
    out = tmp_path / "iv.npz"
    assert main(["combine", *files, "--method", "inverse-variance", "--column", "gyro_x", *cals,
                 "--out", str(out), "--no-plots"]) == 0
    with np.load(out) as z:
        np.testing.assert_allclose(z["gyro_x_weights"][0], np.array([9, 1, 9, 9]) / 28, rtol=1e-12)


def test_combiners_lists_the_plugins(capsys) -> None:
    assert main(["combiners", "--json"]) == 0
    table = {c["name"]: c for c in json.loads(capsys.readouterr().out)["combiners"]}
    assert {"mean", "averaged-volatility", "garch", "inverse-variance"} <= set(table)
    assert "half_window" in table["averaged-volatility"]["options"]
    assert table["garch"]["plugin"] == "stochmod_garch"


def test_bad_input(sensors, tmp_path: Path, capsys) -> None:
    files, _ = sensors
    short = tmp_path / "short.npz"
    np.savez(short, gyro_x=np.zeros(10), gyro_y=np.zeros(10), freq=FREQ)
    fast = tmp_path / "fast.npz"
    data = np.load(files[0])
    np.savez(fast, gyro_x=data["gyro_x"], gyro_y=data["gyro_y"], freq=2 * FREQ)
    cases = [
        ([files[0]], "at least two"),
        ([*files, str(short)], "different lengths"),
        ([*files, "--column", "accel_z"], "no column"),
        ([*files, "--method", "nope"], "unknown --method"),
        ([*files, "--method", "inverse-variance", "--calibration", "x.json"], "1 --calibration"),
        ([*files, "--method", "mean", "--workers", "2"], "--workers applies to --method garch"),
        ([files[0], str(fast)], "different sampling rates"),
    ]
    for argv, match in cases:
        assert main(["combine", *argv, "--out", str(tmp_path / "o.npz"), "--no-plots"]) == 2
        assert match in capsys.readouterr().err
    for out in ("o.csv", "o"):  # the suffix given is kept or refused, never replaced
        assert main(["combine", *files, "--out", str(tmp_path / out), "--no-plots"]) == 2
        assert "ends in .npz" in capsys.readouterr().err
        assert not list(tmp_path.glob("o.*"))


def test_a_method_that_cannot_differ_from_the_mean_says_so(sensors, tmp_path: Path,
                                                           capsys) -> None:
    files, x = sensors
    out = tmp_path / "two.npz"
    assert main(["combine", *files[:2], "--method", "garch", "--arma", "0", "0", "--garch", "1",
                 "1", "--column", "gyro_x", "--out", str(out), "--no-plots"]) == 0
    printed = capsys.readouterr().out
    assert "are those of the mean (1/2, to 1e-06)" in printed and "equal and opposite" in printed
    with np.load(out) as two:
        np.testing.assert_allclose(two["gyro_x_weights"], 0.5, atol=1e-6)
