"""The readers plugin point: registry, dispatch, headers with units and time, gaps, SI
conversion, the conformance kit's check_reader, missing optional dependencies, CLI options.

Truth: the arrays the tests write, the SI values of deg/s and g by hand (pi/180, 9.80665),
the positions of the samples the tests remove.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from typing import ClassVar

import numpy as np
import pytest

import stochmod
from stochmod import sdk
from stochmod.cli import main
from stochmod.core.errors import InputError, StochmodError
from stochmod.io.recording import Reader, Recording, read_recording
from stochmod.plugin.registry import reader_names, readers
from stochmod.empirical.wavelet_variance import wvar
from stochmod.testing import check_reader

RNG = np.random.default_rng(7)


def _csv(path: Path, header: list[str], table: np.ndarray) -> Path:
    rows = "\n".join(",".join(repr(float(v)) for v in row) for row in table)
    path.write_text(",".join(header) + "\n" + rows + "\n")
    return path


def test_first_party_readers_are_registered_through_entry_points() -> None:
    import importlib.metadata

    names = set(reader_names())
    assert {"csv", "npy", "npz", "ulog", "rosbag"} <= names
    modules = {ep.value for ep in importlib.metadata.entry_points(group="stochmod")}
    assert {"stochmod_io_text", "stochmod_ulog", "stochmod_rosbag"} <= modules
    assert readers()["ulog"].options == ("topic", "instance")


def test_unknown_suffix_reader_and_option_are_clear_errors(tmp_path: Path) -> None:
    path = _csv(tmp_path / "a.csv", ["x"], RNG.normal(size=(4, 1)))
    (tmp_path / "a.json").write_text("[1]")
    with pytest.raises(InputError, match=r"unknown file format '.json'.*csv \(.csv.*ulog \(.ulg\)"):
        read_recording(tmp_path / "a.json")
    with pytest.raises(InputError, match=r"unknown reader 'hdf5'; registered readers: csv"):
        read_recording(path, reader="hdf5")
    with pytest.raises(
        InputError, match=r"csv reader does not take option\(s\) 'topic'.*takes: time_column"
    ):
        read_recording(path, topic="/imu")
    # None-valued options (CLI defaults) are not passed
    assert read_recording(path, topic=None).columns == ("x",)


def test_reader_option_forces_the_format(tmp_path: Path) -> None:
    table = RNG.normal(size=(5, 2))
    path = _csv(tmp_path / "log.imu", ["a", "b"], table)
    with pytest.raises(InputError, match="unknown file format '.imu'"):
        read_recording(path)
    np.testing.assert_array_equal(read_recording(path, reader="csv").data, table)


class _Sniffed(Reader):
    """A third-party reader found by content: files starting with b'SNIF' then float64s."""

    name: ClassVar[str] = "sniffed"
    suffixes: ClassVar[tuple[str, ...]] = ()

    def sniff(self, path: Path) -> bool:
        return path.is_file() and path.read_bytes()[:4] == b"SNIF"

    def read(self, path: Path) -> Recording:
        values = np.frombuffer(path.read_bytes()[4:], dtype="<f8")
        return Recording(data=values[:, None], columns=("v",), path=str(path))


class _Plugin:
    def __init__(self, *found: object) -> None:
        self.found = list(found)

    @sdk.hookimpl
    def stochmod_readers(self) -> list[object]:
        return self.found


def test_runtime_reader_is_dispatched_by_sniffing_and_checked(tmp_path: Path) -> None:
    values = RNG.normal(size=9)
    path = tmp_path / "data.csv"  # a CSV suffix, but the sniffer recognises the content first
    path.write_bytes(b"SNIF" + values.astype("<f8").tobytes())
    plugin = _Plugin(_Sniffed())
    stochmod.register_plugin(plugin)
    try:
        rec = read_recording(path)
        np.testing.assert_array_equal(rec.data[:, 0], values)
        assert check_reader(readers()["sniffed"], path, expected=values) == {
            "n": 9,
            "k": 1,
            "has_time": False,
            "rate": None,
        }
    finally:
        stochmod.unregister_plugin(plugin)
    assert "sniffed" not in reader_names()


def test_duplicate_or_malformed_reader_is_refused() -> None:
    with pytest.raises(StochmodError, match="two plugins register a reader named 'csv'"):
        stochmod.register_plugin(_Plugin(type("Csv", (_Sniffed,), {"name": "csv"})()))
    with pytest.raises(StochmodError, match="without a name"):
        stochmod.register_plugin(_Plugin(object()))
    assert reader_names().count("csv") == 1


def test_csv_header_units_and_time_column(tmp_path: Path) -> None:
    n = 6
    t_ms = 1000.0 + 5.0 * np.arange(n)  # 200 Hz in milliseconds
    table = RNG.normal(size=(n, 2))
    path = _csv(
        tmp_path / "imu.csv",
        ["time [ms]", "gyro_x [deg/s]", "accel_z [g]"],
        np.column_stack([t_ms, table]),
    )
    rec = read_recording(path)
    assert rec.columns == ("gyro_x", "accel_z") and rec.units == ("deg/s", "g")
    np.testing.assert_array_equal(rec.data, table)
    np.testing.assert_allclose(rec.time, t_ms / 1000.0, rtol=1e-15)
    assert rec.freq == pytest.approx(200.0, rel=1e-9) and not rec.timing.has_gaps
    si = rec.to_si()
    np.testing.assert_allclose(si.data, table * [math.pi / 180.0, 9.80665], rtol=1e-15)
    assert si.units == ("rad/s", "m/s^2")
    override = rec.to_si("mg")  # one unit for every column, overriding the header
    np.testing.assert_allclose(override.data, table * 9.80665e-3, rtol=1e-15)
    assert rec.select(["accel_z"]).units == ("g",)


def test_time_column_by_option_and_nanoseconds(tmp_path: Path) -> None:
    stamps = 10**9 + 2_500_000 * np.arange(5)  # 400 Hz in ns
    table = RNG.normal(size=(5, 1))
    path = _csv(tmp_path / "ns.tsv", ["clock [ns]", "x"], np.column_stack([stamps, table]))
    assert read_recording(path).columns == ("clock", "x")  # 'clock' is not a time name
    rec = read_recording(path, time_column="clock")
    assert rec.columns == ("x",) and rec.freq == pytest.approx(400.0, rel=1e-9)
    with pytest.raises(InputError, match="no time column 'stamp_us'"):
        read_recording(path, time_column="stamp_us")
    bad = _csv(
        tmp_path / "bad.csv", ["t [deg]", "x"], np.column_stack([np.arange(3.0), np.ones(3)])
    )
    with pytest.raises(InputError, match="unit 'deg' is not a unit of time"):
        read_recording(bad)


def test_gap_is_refused_where_it_is_or_split(tmp_path: Path) -> None:
    n = 40
    keep = np.setdiff1d(np.arange(n), [10, 11, 25])  # 2 samples missing after 9, 1 after 22
    table = RNG.normal(size=(keep.size, 2))
    path = _csv(tmp_path / "gaps.csv", ["t", "a", "b"], np.column_stack([keep * 0.01, table]))
    with pytest.raises(
        InputError,
        match=r"2 gap\(s\).*3 sample\(s\) missing.*after sample 9 "
        r"\(t = 0.09 s\).*after sample 22 \(t = 0.24 s\).*split_gaps=True",
    ):
        read_recording(path)
    rec = read_recording(path, split_gaps=True)
    assert rec.freq == pytest.approx(100.0, rel=1e-9) and rec.timing.dropped == 3
    pieces = rec.segments()
    assert [p.data.shape[0] for p in pieces] == [10, 13, 14]
    np.testing.assert_array_equal(np.vstack([p.data for p in pieces]), table)
    assert all(not p.timing.has_gaps for p in pieces)
    np.testing.assert_allclose(pieces[1].time, keep[10:23] * 0.01)


def test_npz_time_units_and_freq(tmp_path: Path) -> None:
    t = np.arange(8) / 50.0
    gx, az = RNG.normal(size=8), RNG.normal(size=8)
    np.savez(tmp_path / "r.npz", time=t, gyro_x=gx, accel_z=az, units=np.array(["deg/s", "mg"]))
    rec = read_recording(tmp_path / "r.npz")
    assert rec.columns == ("gyro_x", "accel_z") and rec.units == ("deg/s", "mg")
    assert rec.freq == pytest.approx(50.0, rel=1e-12)
    np.testing.assert_array_equal(rec.time, t)


def _samples(tmp_path: Path) -> dict[str, tuple[Path, np.ndarray]]:
    table = RNG.normal(size=(12, 3))
    np.save(tmp_path / "s.npy", table)
    np.savez(tmp_path / "s.npz", a=table[:, 0], b=table[:, 1], c=table[:, 2])
    csv = _csv(
        tmp_path / "s.csv", ["t", "a", "b", "c"], np.column_stack([np.arange(12) * 0.1, table])
    )
    return {
        "npy": (tmp_path / "s.npy", table),
        "npz": (tmp_path / "s.npz", table),
        "csv": (csv, table),
    }


@pytest.mark.parametrize("name", ["csv", "npy", "npz"])
def test_conformance_kit_passes_first_party_text_readers(tmp_path: Path, name: str) -> None:
    path, table = _samples(tmp_path)[name]
    figures = check_reader(readers()[name], path, expected=table)
    assert figures["n"] == 12 and figures["has_time"] == (name == "csv")


def test_conformance_kit_catches_a_wrong_reader(tmp_path: Path) -> None:
    path, table = _samples(tmp_path)["csv"]

    class Backwards(Reader):
        name: ClassVar[str] = "backwards"
        suffixes: ClassVar[tuple[str, ...]] = (".csv",)
        options: ClassVar[tuple[str, ...]] = ("scale",)  # declared, but read() does not take it

        def read(self, path: Path) -> Recording:
            return Recording(data=table, columns=("a", "b", "c"), time=-np.arange(12.0))

    with pytest.raises(
        AssertionError, match=r"does not accept its declared option\(s\) \['scale'\]"
    ):
        check_reader(Backwards(), path)
    Backwards.options = ()
    with pytest.raises(InputError, match="time stamps must increase"):
        check_reader(Backwards(), path)
    with pytest.raises(AssertionError, match="samples differ"):
        check_reader(readers()["csv"], path, expected=table + 1.0)


@pytest.mark.parametrize(
    ("module", "suffix", "extra"), [("pyulog", ".ulg", "ulog"), ("rosbags", ".bag", "rosbag")]
)
def test_missing_optional_dependency_names_the_extra(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, module: str, suffix: str, extra: str
) -> None:
    monkeypatch.setitem(sys.modules, module, None)  # import now raises ImportError
    path = tmp_path / f"log{suffix}"
    path.write_bytes(b"\x00" * 16)
    with pytest.raises(ImportError) as info:
        read_recording(path)
    message = str(info.value)
    assert message.endswith(f'pip install "stochmod[{extra}]"') and "\n" not in message
    assert module in message


# ---------------------------------------------------------------------- command line
def test_cli_unit_converts_to_si_before_modelling(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    x = np.random.default_rng(3).normal(size=4096)
    path = _csv(tmp_path / "deg.csv", ["t", "gyro"], np.column_stack([np.arange(4096) / 100.0, x]))
    assert main(["wv", str(path), "--unit", "deg/s", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    want = wvar(x * (math.pi / 180.0), 100.0)
    assert out["freq"] == pytest.approx(100.0, rel=1e-9)
    got = np.array(out["columns"]["gyro"]["wv"], dtype=float)
    np.testing.assert_allclose(got, want.wv, rtol=1e-9)


def test_cli_header_units_are_used_without_option(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    x = np.random.default_rng(4).normal(size=2048)
    path = _csv(tmp_path / "mg.csv", ["accel [mg]"], x[:, None])
    assert main(["wv", str(path), "--freq", "50", "--json"]) == 0
    got = np.array(json.loads(capsys.readouterr().out)["columns"]["accel"]["wv"], dtype=float)
    np.testing.assert_allclose(got, wvar(x * 9.80665e-3, 50.0).wv, rtol=1e-9)


def test_cli_gap_is_an_error_that_says_where(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    keep = np.setdiff1d(np.arange(600), [300])
    x = np.random.default_rng(5).normal(size=keep.size)
    path = _csv(tmp_path / "gap.csv", ["time", "x"], np.column_stack([keep / 100.0, x]))
    assert main(["wv", str(path), "--json"]) == 2
    err = capsys.readouterr().err
    assert "after sample 299 (t = 2.99 s)" in err and "--split-gaps" in err
    # wv pools the two segments: the mean of all their squared coefficients at each level
    assert main(["wv", str(path), "--split-gaps", "--json"]) == 0
    captured = capsys.readouterr()
    assert "2 gap-free segments; pooling the wavelet variances of 2 (599 samples)" in captured.err
    column = json.loads(captured.out)["columns"]["x"]
    each = [wvar(x[:300], 100.0), wvar(x[300:], 100.0)]
    pooled = sum(w.wv * w.n_coef for w in each) / sum(w.n_coef for w in each)
    np.testing.assert_allclose(np.array(column["wv"], dtype=float), pooled, rtol=1e-12)
    assert column["segments"] == 2 and column["n"] == 599
    # a subcommand that does not pool (Allan) reads the longest segment and says so
    assert main(["allan", str(path), "--split-gaps", "--json"]) == 0
    assert "using the longest (300 of 599 samples" in capsys.readouterr().err


def test_cli_reader_options_refused_for_the_bundled_example(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["calibrate", "--topic", "/imu", "--unit", "deg/s"]) == 2
    assert "--topic, --unit apply to a FILE" in capsys.readouterr().err


def test_cli_readers_lists_and_inspects(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["readers", "--json"]) == 0
    listed = json.loads(capsys.readouterr().out)
    assert (
        listed["ulog"]["options"] == ["topic", "instance"]
        and ".bag" in listed["rosbag"]["suffixes"]
    )
    keep = np.setdiff1d(np.arange(50), [20, 21])
    path = _csv(
        tmp_path / "g.csv",
        ["t [ms]", "x [deg/s]"],
        np.column_stack([keep * 10.0, np.ones(keep.size)]),
    )
    assert main(["readers", str(path), "--json"]) == 0  # gaps are reported, not refused
    out = json.loads(capsys.readouterr().out)
    assert out["units"] == ["deg/s"] and out["freq"] == pytest.approx(100.0, rel=1e-9)
    assert out["timing"]["gaps"] == [[19, pytest.approx(0.19), pytest.approx(0.03), 2]]
    assert main(["readers", str(path)]) == 0
    assert "after sample" in capsys.readouterr().out


def test_unknown_header_unit_is_an_error_naming_the_column(tmp_path: Path) -> None:
    path = _csv(tmp_path / "lsb.csv", ["gyro [LSB]", "accel [mg]"], RNG.normal(size=(4, 2)))
    rec = read_recording(path)
    with pytest.raises(InputError, match=r"column 'gyro': .*header says 'LSB'.*--unit"):
        rec.to_si()
    assert rec.select(["accel"]).to_si().units == ("m/s^2",)  # only the columns kept matter
    np.testing.assert_allclose(rec.to_si("deg/s").data, rec.data * math.pi / 180.0, rtol=1e-15)
