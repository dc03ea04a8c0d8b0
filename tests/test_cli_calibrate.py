"""The main job ``stochmod calibrate`` on a small simulated recording and on the bundled example."""

import json

import numpy as np

import stochmod
from stochmod.cli import main


def test_calibrate_file_writes_models_and_augmentation(tmp_path, capsys):
    truth = stochmod.model_from_spec("GM(beta=1.0, sigma2=1e-2)+WN(sigma2=1e-2)", 50.0)
    path = tmp_path / "rec.npy"
    np.save(path, truth.simulate(2**14, rng=9)[:, None])
    code = main(["calibrate", str(path), "--freq", "50", "--out", str(tmp_path / "out"),
                 "--candidates", "WN", "GM+WN", "--no-plots", "--dt", "0.04"])
    assert code == 0
    report = json.loads((tmp_path / "out" / "calibration.json").read_text())
    col = report["columns"]["0"]
    assert col["name"] == "GM+WN"
    aug = col["augmentation"]
    assert len(aug["state_names"]) == 1 and aug["state_names"][0].startswith("GM.")
    beta = col["model"]["processes"][0]["params"]["beta"]
    assert abs(np.asarray(aug["Phi"])[0, 0] - np.exp(-beta * 0.04)) < 1e-12
    assert "GM+WN" in capsys.readouterr().out


def test_calibrate_bundled_example_runs(tmp_path):
    code = main(["calibrate", "--n", "4096", "--column", "gyro_x", "--candidates", "WN", "GM+WN",
                 "--out", str(tmp_path), "--json", "--no-plots"])
    assert code == 0
    assert "gyro_x" in json.loads((tmp_path / "calibration.json").read_text())["columns"]


def test_calibrate_missing_file_is_a_one_line_error(tmp_path, capsys):
    assert main(["calibrate", str(tmp_path / "nope.csv"), "--freq", "10"]) == 2
    assert "no such file" in capsys.readouterr().err
