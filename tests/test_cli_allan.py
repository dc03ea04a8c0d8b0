"""``stochmod allan``: table and JSON equal to the library (avar, allan_reading), the plot,
and one-line errors with exit code 2."""

from __future__ import annotations

import json

import numpy as np
import pytest

from stochmod.cli import main
from stochmod.empirical.allan import avar
from stochmod.empirical.allan_reading import allan_reading

FREQ = 100.0


@pytest.fixture
def data():
    # column 0: white noise, N = 0.01 u sqrt(s); column 1: white noise + random walk
    rng = np.random.default_rng(7)
    n = 20_000
    wn = rng.standard_normal(n) * 0.01 * np.sqrt(FREQ)
    rw = np.cumsum(rng.standard_normal(n)) * 0.003 / np.sqrt(FREQ)
    return np.column_stack([wn, 0.5 * wn[::-1] + rw])


def _run_json(capsys, argv):
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_json_equals_library(tmp_path, capsys, data):
    path = tmp_path / "rec.csv"
    np.savetxt(path, data, delimiter=",", header="gx,gy", comments="", fmt="%.17g")
    out = _run_json(capsys, ["allan", str(path), "--freq", str(FREQ), "--json"])
    assert out["freq"] == FREQ and sorted(out["columns"]) == ["gx", "gy"]
    for k, name in enumerate(["gx", "gy"]):
        entry = out["columns"][name]
        table = avar(data[:, k], FREQ)
        np.testing.assert_allclose(entry["avar"]["avar"], table.avar, rtol=1e-12)
        np.testing.assert_allclose(entry["avar"]["ci_high"], table.ci_high, rtol=1e-12)
        assert entry["avar"]["m"] == table.m.tolist()
        reading = allan_reading(data[:, k], FREQ)
        for coef, c in reading.coefficients.items():
            got = entry["reading"]["coefficients"][coef]
            if c is None:
                assert got is None
            else:
                assert got["value"] == pytest.approx(c.value, rel=1e-12)
                assert got["low"] == pytest.approx(c.low, rel=1e-12)
    # the white-noise column: N = 0.01 (seeded simulation), no random walk
    gx = out["columns"]["gx"]["reading"]["coefficients"]
    assert gx["N"]["value"] == pytest.approx(0.01, rel=0.03)
    assert gx["K"] is None


def test_table_options_and_unit(tmp_path, capsys, data):
    path = tmp_path / "rec.npy"
    np.save(path, data)
    argv = ["allan", str(path), "--freq", str(FREQ), "--column", "0", "--kind", "hadamard",
            "--taus", "decade", "--unit", "deg/s"]
    assert main(argv) == 0
    text = capsys.readouterr().out
    table = avar(data[:, 0], FREQ, taus="decade", kind="hadamard")
    assert "column 0" in text and "hadamard" in text and "column 1" not in text
    assert f"{table.adev[5]:.6g}" in text
    reading = allan_reading(data[:, 0], FREQ, unit="deg/s")
    # datasheet column: N in deg/sqrt(h) = 60 x N in deg/sqrt(s)
    assert f"{60.0 * reading.N.value:.6g}" in text and "deg/sqrt(h)" in text
    assert "not identified" in text


def test_plot_is_written(tmp_path, capsys, data):
    pytest.importorskip("matplotlib")
    path = tmp_path / "rec.csv"
    np.savetxt(path, data, delimiter=",", fmt="%.17g")
    png = tmp_path / "adev.png"
    assert main(["allan", str(path), "--freq", str(FREQ), "--plot", str(png)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000


@pytest.mark.parametrize(
    ("extra", "content", "match"),
    [
        ([], "1,2\n3,nan\n", "NaN"),
        ([], "1\n3\n2\n4\n6\n5\n", "at least 8"),
        (["--plot", "out.txt"], None, ".png"),
    ],
)
def test_errors_are_one_line_exit_2(tmp_path, capsys, data, extra, content, match):
    path = tmp_path / "rec.csv"
    if content is None:
        np.savetxt(path, data, delimiter=",", fmt="%.17g")
    else:
        path.write_text(content)
    if "--plot" in extra:
        extra = ["--plot", str(tmp_path / extra[1])]
    assert main(["allan", str(path), "--freq", "10", *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("stochmod allan: error:") and match in err and "\n" not in err


def test_missing_frequency_is_an_error(tmp_path, capsys, data):
    path = tmp_path / "rec.csv"
    np.savetxt(path, data, delimiter=",", fmt="%.17g")
    assert main(["allan", str(path)]) == 2
    assert "--freq" in capsys.readouterr().err
