"""``stochmod psd``, ``stochmod ar`` and ``stochmod denoise``: output equal to the library's on the
same data, written files readable back, one-line errors with exit code 2."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.signal import lfilter

from stochmod.cli import main
from stochmod.io.recording import read_recording
from stochmod.empirical.ar_fit import fit_ar
from stochmod.empirical.denoise import denoise
from stochmod.empirical.psd import psd_reading

FREQ = 100.0


@pytest.fixture
def data():
    rng = np.random.default_rng(9)
    ar = lfilter([1.0], [1.0, -0.6, 0.2], rng.standard_normal(4000))
    wn_rw = rng.standard_normal(4000) + np.cumsum(rng.standard_normal(4000)) * 0.05
    return np.column_stack([ar, wn_rw])


@pytest.fixture
def csv_path(tmp_path, data):
    path = tmp_path / "rec.csv"
    np.savetxt(path, data, delimiter=",", header="gx,ax", comments="", fmt="%.17g")
    return path


def _json(capsys, argv):
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_psd_json_equals_library(csv_path, data, capsys):
    out = _json(capsys, ["psd", str(csv_path), "--freq", str(FREQ), "--json", "--nperseg", "512"])
    assert sorted(out["columns"]) == ["ax", "gx"] and out["freq"] == FREQ
    for k, name in enumerate(["gx", "ax"]):
        ref = psd_reading(data[:, k], FREQ, nperseg=512)
        entry = out["columns"][name]
        np.testing.assert_allclose(entry["spectrum"]["psd"], ref.spectrum.psd, rtol=1e-12)
        np.testing.assert_allclose(entry["spectrum"]["f"], ref.spectrum.f, rtol=1e-12)
        for term in ("N", "B", "K"):
            t = getattr(ref, term)
            if t is None:
                assert entry["reading"][term] is None
            else:
                assert entry["reading"][term]["value"] == pytest.approx(t.value, rel=1e-12)


def test_psd_table_and_plot(csv_path, tmp_path, capsys):
    png = tmp_path / "psd.png"
    argv = ["psd", str(csv_path), "--freq", str(FREQ), "--column", "ax", "--plot", str(png)]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "column ax" in text and "PSD slope reading" in text and "column gx" not in text
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_ar_json_equals_library(csv_path, data, capsys):
    out = _json(capsys, ["ar", str(csv_path), "--freq", str(FREQ), "--order", "2", "--json"])
    for k, name in enumerate(["gx", "ax"]):
        ref = fit_ar(data[:, k], FREQ, 2)
        np.testing.assert_allclose(out["columns"][name]["phi"], ref.phi, rtol=1e-12)
        assert out["columns"][name]["sigma2"] == pytest.approx(ref.sigma2, rel=1e-12)


def test_ar_auto_order_and_yule_walker(csv_path, data, capsys):
    out = _json(capsys, ["ar", str(csv_path), "--freq", str(FREQ), "--order", "auto",
                         "--method", "yw", "--column", "gx", "--json"])
    ref = fit_ar(data[:, 0], FREQ, None, method="yw")
    entry = out["columns"]["gx"]
    assert entry["order"] == ref.order == 2  # the simulated AR(2)
    np.testing.assert_allclose(entry["phi"], ref.phi, rtol=1e-12)
    assert main(["ar", str(csv_path), "--freq", str(FREQ), "--order", "1"]) == 0
    assert "AR(1) by burg" in capsys.readouterr().out


@pytest.mark.parametrize("suffix", [".npy", ".csv", ".npz"])
def test_denoise_writes_all_columns(csv_path, data, tmp_path, capsys, suffix):
    out_path = tmp_path / f"clean{suffix}"
    argv = ["denoise", str(csv_path), "--freq", str(FREQ), "--level", "4", "-o", str(out_path)]
    assert main(argv) == 0
    assert "wrote 4000 x 2" in capsys.readouterr().out
    back = read_recording(out_path)
    expected = np.column_stack([denoise(data[:, k], "db4", 4) for k in range(2)])
    np.testing.assert_allclose(back.data, expected, rtol=1e-14, atol=1e-14)
    if suffix != ".npy":
        assert back.columns == ("gx", "ax")
    if suffix == ".npz":
        assert back.freq == FREQ


def test_denoise_options_and_json(csv_path, data, tmp_path, capsys):
    out_path = tmp_path / "clean.npy"
    out = _json(capsys, ["denoise", str(csv_path), "--freq", str(FREQ), "--f-limit", "0.8",
                         "--wavelet", "sym4", "--rule", "sqtwolog", "--mode", "hard",
                         "--noise", "one", "--column", "ax", "-o", str(out_path), "--json"])
    entry = out["columns"]["ax"]
    assert entry["level"] == 6 and entry["band_limit_hz"] == FREQ / 2**7  # Table 7: 0.78 Hz
    expected = denoise(data[:, 1], "sym4", None, "sqtwolog", "hard", "one", FREQ, 0.8)
    np.testing.assert_allclose(np.load(out_path)[:, 0], expected, rtol=1e-14, atol=1e-14)
    assert main(["denoise", str(csv_path), "--freq", str(FREQ), "--level", "2", "--rule", "0",
                 "-o", str(out_path)]) == 0
    np.testing.assert_allclose(np.load(out_path), data, atol=1e-9)


@pytest.mark.parametrize(
    "argv, match",
    [
        (["ar", "{csv}", "--freq", "100", "--order", "three"], "--order"),
        (["ar", "{csv}", "--freq", "100", "--order", "0"], "order"),
        (["denoise", "{csv}", "--freq", "100", "--level", "2", "-o", "{tmp}/x.txt"],
         "output format"),
        (["denoise", "{csv}", "--freq", "100", "--level", "2", "--rule", "bogus",
          "-o", "{tmp}/x.npy"], "--rule"),
        (["denoise", "{csv}", "--freq", "100", "--level", "40", "-o", "{tmp}/x.npy"], "too deep"),
        (["psd", "{csv}", "--freq", "100", "--nperseg", "100000"], "exceeds"),
        (["psd", "{tmp}/missing.csv", "--freq", "100"], "no such file"),
    ],
)
def test_errors_are_one_line_exit_2(argv, match, csv_path, tmp_path, capsys):
    argv = [a.format(csv=csv_path, tmp=tmp_path) for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and match in err and err.startswith(f"stochmod {argv[0]}: error:")
