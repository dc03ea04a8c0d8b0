"""``calibrate --report`` (one self-contained HTML file) and fleet runs (dask LocalCluster)."""

from __future__ import annotations

import base64
import csv
import json
import math
from html.parser import HTMLParser

import numpy as np
import pytest

import stochmod
from stochmod.cli import main
from stochmod.output import exports
from stochmod.workflows.fleet import MIN_UNITS, OUTLIER_Z, robust_z

FS = 50.0


def _save(path, gyro_noise: float, seed: int, n: int = 2**12) -> None:
    model = stochmod.model_from_spec(
        {"processes": [{"family": "WN", "params": {"sigma2": gyro_noise**2 * FS}},
                       {"family": "RW", "params": {"sigma2": 1e-8 / FS}}]}, FS)
    np.savez(path, gyro_x=model.simulate(n, rng=seed), freq=FS)


class _Parsed(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.images, self.tables, self.links, self.pre = [], [], [], []
        self._in_pre = False

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "img":
            self.images.append(a.get("src", ""))
        elif tag == "table":
            self.tables.append(a.get("class", ""))
        elif tag in ("link", "script") or (tag == "a" and not a.get("href", "#").startswith("#")):
            self.links.append(a)
        self._in_pre = tag == "pre"

    def handle_data(self, data):
        if self._in_pre:
            self.pre.append(data)


def test_report_is_one_self_contained_file(tmp_path, capsys, monkeypatch):
    pytest.importorskip("matplotlib")
    path = tmp_path / "u.npz"
    x = np.column_stack([stochmod.model_from_spec("WN(sigma2=1e-4)+RW(sigma2=1e-10)", FS)
                         .simulate(2**13, rng=s) for s in (1, 2)])
    np.savez(path, gyro_x=x[:, 0], accel_x=x[:, 1], freq=FS)
    out = tmp_path / "out"
    bounds = []  # the export bound is solved once per axis: the files and the report share it
    monkeypatch.setattr(exports, "avar_bound",
                        lambda *a, _f=exports.avar_bound, **k: bounds.append(k["column"]) or _f(*a, **k))
    assert main(["calibrate", "--assume-si", str(path), "--candidates", "WN", "WN+RW", "--no-plots", "--n-sim",
                 "4", "--out", str(out), "--report", "--export", "kalibr"]) == 0
    capsys.readouterr()
    assert bounds == ["gyro_x", "accel_x"]
    parser = _Parsed()
    parser.feed((out / "report.html").read_text())
    assert len(parser.images) == 3  # the Allan deviations of both axes, one figure per axis
    for src in parser.images:
        assert src.startswith("data:image/png;base64,")
        assert base64.b64decode(src.split(",", 1)[1])[:8] == b"\x89PNG\r\n\x1a\n"
    assert parser.links == []  # nothing outside the file
    assert parser.tables[0] == "summary"  # the summary across axes opens the report
    assert parser.tables.count("selection") == 2 and parser.tables.count("datasheet") == 2
    assert any("gyroscope_noise_density" in p for p in parser.pre)  # the export, verbatim


def test_robust_z_by_hand():
    v = [1.0, 2.0, 4.0, 8.0, 1000.0]
    z, med, mad = robust_z(v)
    logs = np.log(v)
    assert med == pytest.approx(math.log(4.0))
    assert mad == pytest.approx(math.log(2.0))  # |logs - ln 4| = 2,1,0,1,~5.5 ln2 -> median ln 2
    assert z[-1] == pytest.approx((logs[-1] - math.log(4.0)) / (1.4826 * math.log(2.0)))
    assert abs(z[-1]) > OUTLIER_Z > max(abs(z[:-1]))


def test_fleet_on_a_local_cluster_equals_the_serial_run(tmp_path, capsys):
    pytest.importorskip("distributed")
    files = []
    for i in range(6):
        files.append(tmp_path / f"unit{i}.npz")
        _save(files[-1], 0.02 if i == 3 else 1e-3, seed=100 + i)  # unit3: 20x the noise
    common = ["--candidates", "WN", "WN+RW", "--no-plots"]
    assert main(["calibrate", "--assume-si", *map(str, files), *common, "--out", str(tmp_path / "serial")]) == 0
    assert main(["calibrate", "--assume-si", *map(str, files), *common, "--out", str(tmp_path / "dask"),
                 "--workers", "2"]) == 0
    capsys.readouterr()
    for f in files:
        a = json.loads((tmp_path / "serial" / f.stem / "calibration.json").read_text())
        b = json.loads((tmp_path / "dask" / f.stem / "calibration.json").read_text())
        assert a["columns"] == b["columns"] and a["datasheet"] == b["datasheet"]
    with open(tmp_path / "dask" / "fleet.csv") as fh:
        rows = list(csv.DictReader(fh))
    arw = [r for r in rows if r["unit"] == "deg/sqrt(h)"]
    assert len(arw) == 6 >= MIN_UNITS
    assert {r["unit_name"] for r in arw if r["outlier"] == "True"} == {"unit3"}
    serial = (tmp_path / "serial" / "fleet.csv").read_text()
    assert serial == (tmp_path / "dask" / "fleet.csv").read_text()


def test_one_file_on_two_workers_equals_the_single_file_command(tmp_path, capsys):
    """A fleet runs a unit's columns as tasks of their own (stochmod.workflows.fleet.UnitSteps): a
    one-file fleet on two workers gives the single-file command's results, whose selection
    takes every column at once (in a pool of two processes), and spreads the columns over both
    workers."""
    pytest.importorskip("distributed")
    from stochmod.data.examples import XSENS_COLUMNS, xsens_mtig

    rec = xsens_mtig(n=2**13, seed=5)
    path = tmp_path / "imu.npz"
    np.savez(path, freq=rec.freq, **{c: rec.column(c) for c in XSENS_COLUMNS})
    common = ["--candidates", "WN", "WN+RW", "GM+WN", "--triad", "--export", "kalibr", "--no-plots"]
    assert main(["calibrate", "--assume-si", str(path), *common, "--out", str(tmp_path / "single")]) == 0
    assert main(["calibrate", "--assume-si", str(path), *common, "--out", str(tmp_path / "fleet"),
                 "--workers", "2"]) == 0
    capsys.readouterr()
    a = json.loads((tmp_path / "single" / "calibration.json").read_text())
    b = json.loads((tmp_path / "fleet" / "imu" / "calibration.json").read_text())
    assert sorted(b["columns"]) == sorted(XSENS_COLUMNS)
    for key in ["columns", "datasheet", "triads", "imu_augmentation"]:
        assert a[key] == b[key], key
    assert ((tmp_path / "single" / "kalibr_imu.yaml").read_text()
            == (tmp_path / "fleet" / "imu" / "kalibr_imu.yaml").read_text())
    with open(tmp_path / "fleet" / "fleet_tasks.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["part"] for r in rows] == ["read", *(f"select {c}" for c in XSENS_COLUMNS), "finish"]
    assert len({r["pid"] for r in rows if r["part"].startswith("select")}) == 2


@pytest.mark.parametrize("workers", [[], ["--workers", "2"]])
def test_a_fleet_error_names_its_file(tmp_path, capsys, workers):
    if workers:
        pytest.importorskip("distributed")
    _save(tmp_path / "good.npz", 1e-3, seed=1)
    np.savez(tmp_path / "flat.npz", gyro_x=np.full(2**12, 1e-3), freq=FS)  # nothing to model
    code = main(["calibrate", "--assume-si", str(tmp_path / "good.npz"), str(tmp_path / "flat.npz"),
                 "--candidates", "WN", "--no-plots", "--out", str(tmp_path / "out"), *workers])
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert code == 2
    assert err == (f"stochmod calibrate: error: {tmp_path / 'flat.npz'}: column 'gyro_x' of x is "
                   "constant: it has no noise to model")


def test_dask_weighs_a_unit_by_its_samples(tmp_path):
    pytest.importorskip("distributed")
    from dask.sizeof import sizeof

    from stochmod.cli import _parser_for
    from stochmod.cli.calibrate import read_unit
    from stochmod.workflows.fleet import SerialExecutor

    _save(tmp_path / "u.npz", 1e-3, seed=3, n=2**14)
    argv = ["calibrate", "--assume-si", str(tmp_path / "u.npz")]
    unit = read_unit(_parser_for(argv).parse_args(argv), SerialExecutor())
    samples = 8 * 2**14 * (2 if unit.segments[0].time is not None else 1)
    assert samples <= sizeof(unit) < samples + 1000
