"""``stochmod wv``: tables and JSON equal to the library's wvar, and one-line errors (exit 2)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from stochmod.cli import main
from stochmod.empirical.wavelet_variance import wvar

FREQ = 50.0


@pytest.fixture
def data():
    rng = np.random.default_rng(42)
    return np.column_stack([rng.standard_normal(600), np.cumsum(rng.standard_normal(600))])


def _json(capsys, argv):
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def _assert_same(entry, expected):
    np.testing.assert_allclose(entry["wv"], expected.wv, rtol=1e-12)
    np.testing.assert_allclose(entry["ci_low"], expected.ci_low, rtol=1e-12)
    np.testing.assert_allclose(entry["ci_high"], expected.ci_high, rtol=1e-12)
    np.testing.assert_allclose(entry["tau"], expected.tau, rtol=1e-12)
    assert entry["n_coef"] == expected.n_coef.tolist()
    assert entry["levels"] == expected.levels.tolist()


def test_csv_with_header_json(tmp_path, capsys, data):
    path = tmp_path / "rec.csv"
    np.savetxt(path, data, delimiter=",", header="gx,gy", comments="", fmt="%.17g")
    out = _json(capsys, ["wv", str(path), "--freq", str(FREQ), "--json"])
    assert out["freq"] == FREQ
    assert sorted(out["columns"]) == ["gx", "gy"]
    for k, name in enumerate(["gx", "gy"]):
        _assert_same(out["columns"][name], wvar(data[:, k], FREQ))


def test_headerless_csv_column_and_options(tmp_path, capsys, data):
    path = tmp_path / "rec.csv"
    np.savetxt(path, data, delimiter=",", fmt="%.17g")
    argv = ["wv", str(path), "--freq", "10", "--column", "1", "--json",
            "--wavelet", "db2", "--levels", "4", "--ci", "normal"]
    out = _json(capsys, argv)
    assert list(out["columns"]) == ["1"]
    entry = out["columns"]["1"]
    assert entry["wavelet"] == "db2" and entry["ci_method"] == "normal"
    _assert_same(entry, wvar(data[:, 1], 10.0, wavelet="db2", levels=4, ci="normal"))


def test_npy_table(tmp_path, capsys, data):
    path = tmp_path / "rec.npy"
    np.save(path, data)
    assert main(["wv", str(path), "--freq", str(FREQ), "--levels", "3"]) == 0
    text = capsys.readouterr().out
    assert "column 0" in text and "column 1" in text and "tau [s]" in text
    expected = wvar(data[:, 1], FREQ, levels=3)
    block = text.split("column 1")[1].splitlines()
    rows = [line.split() for line in block if line.strip() and line.split()[0].isdigit()]
    assert [int(r[0]) for r in rows] == [1, 2, 3]
    np.testing.assert_allclose([float(r[2]) for r in rows], expected.wv, rtol=1e-5)  # 6 digits
    assert [int(r[5]) for r in rows] == expected.n_coef.tolist()


def test_npz_reads_freq(tmp_path, capsys, data):
    path = tmp_path / "rec.npz"
    np.savez(path, Gyro_X=data[:, 0], freq=np.array(25.0))
    out = _json(capsys, ["wv", str(path), "--json"])
    assert out["freq"] == 25.0
    _assert_same(out["columns"]["Gyro_X"], wvar(data[:, 0], 25.0))


def _error(capsys, argv):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("stochmod wv: error:") and err.count("\n") == 1
    return err


def test_errors(tmp_path, capsys, data):
    assert "no such file" in _error(capsys, ["wv", str(tmp_path / "missing.csv"), "--freq", "1"])
    bad = tmp_path / "nan.csv"
    bad.write_text("a,b\n1,2\nnan,3\n4,5\n")
    assert "NaN" in _error(capsys, ["wv", str(bad), "--freq", "1"])
    good = tmp_path / "rec.npy"
    np.save(good, data)
    assert "column" in _error(capsys, ["wv", str(good), "--freq", "1", "--column", "zz"])
    assert "levels=30" in _error(capsys, ["wv", str(good), "--freq", "1", "--levels", "30"])
    assert "wavelet" in _error(capsys, ["wv", str(good), "--freq", "1", "--wavelet", "bogus"])
    assert "--freq" in _error(capsys, ["wv", str(good)])  # .npy holds no frequency
