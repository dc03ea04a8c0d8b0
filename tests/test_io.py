"""Tests of stochmod.io.recording.read_recording: every value read is compared with the array written
to the file by the test (numpy's own writers and plain text), and every bad file raises
InputError naming the problem."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from stochmod.core.errors import InputError
from stochmod.io.recording import Recording, read_recording

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
RNG = np.random.default_rng(12)
TABLE = RNG.normal(size=(7, 3))


def _write_text(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _rows(data: np.ndarray, sep: str) -> str:
    # repr() of a float64 round-trips exactly
    return "\n".join(sep.join(repr(float(v)) for v in row) for row in data) + "\n"


@pytest.mark.parametrize(("sep", "name"), [(",", "x.csv"), (";", "x.csv"), ("\t", "x.tsv"),
                                           (" ", "x.txt"), (", ", "x.dat")])
def test_csv_without_header_any_separator(tmp_path: Path, sep: str, name: str) -> None:
    rec = read_recording(_write_text(tmp_path, name, _rows(TABLE, sep)))
    np.testing.assert_array_equal(rec.data, TABLE)
    assert rec.columns == ("0", "1", "2")
    assert rec.freq is None and rec.data.dtype == np.float64


@pytest.mark.parametrize("sep", [",", ";", "\t"])
def test_csv_with_header_and_comments(tmp_path: Path, sep: str) -> None:
    text = ("# recorded on a bench\n" + sep.join(["gyro_x", "gyro_y", "gyro_z"]) + "\n"
            + _rows(TABLE[:3], sep) + "# a pause\n\n" + _rows(TABLE[3:], sep))
    rec = read_recording(_write_text(tmp_path, "h.csv", text))
    np.testing.assert_array_equal(rec.data, TABLE)
    assert rec.columns == ("gyro_x", "gyro_y", "gyro_z")


def test_csv_single_column_and_exponents(tmp_path: Path) -> None:
    rec = read_recording(_write_text(tmp_path, "one.csv", "1e-3\n-2.5E+2\n3\n"))
    np.testing.assert_array_equal(rec.data[:, 0], [1e-3, -250.0, 3.0])


def test_column_selection_by_name_and_index(tmp_path: Path) -> None:
    text = "a,b,c\n" + _rows(TABLE, ",")
    path = _write_text(tmp_path, "sel.csv", text)
    rec = read_recording(path, columns=["c", 0])
    np.testing.assert_array_equal(rec.data, TABLE[:, [2, 0]])
    assert rec.columns == ("c", "a")
    assert read_recording(path, columns=["1"]).columns == ("b",)  # digit strings are indices
    np.testing.assert_array_equal(read_recording(path).column(-1), TABLE[:, 2])
    with pytest.raises(InputError, match=r"no column 'd'.*\['a', 'b', 'c'\]"):
        read_recording(path, columns=["d"])
    with pytest.raises(InputError, match="column index 3 out of range"):
        read_recording(path, columns=[3])


@pytest.mark.parametrize("shape", [(9,), (9, 1), (9, 4)])
def test_npy_one_and_two_dimensional(tmp_path: Path, shape: tuple[int, ...]) -> None:
    arr = RNG.normal(size=shape)
    np.save(tmp_path / "a.npy", arr)
    rec = read_recording(tmp_path / "a.npy")
    np.testing.assert_array_equal(rec.data, arr.reshape(shape[0], -1))
    assert rec.columns == tuple(str(i) for i in range(rec.data.shape[1]))


def test_npy_integers_become_float64(tmp_path: Path) -> None:
    np.save(tmp_path / "i.npy", np.arange(6, dtype=np.int16))
    rec = read_recording(tmp_path / "i.npy")
    assert rec.data.dtype == np.float64
    np.testing.assert_array_equal(rec.data[:, 0], np.arange(6.0))


def test_npz_with_freq_and_text_entries(tmp_path: Path) -> None:
    x, y, m = RNG.normal(size=8), RNG.normal(size=8), RNG.normal(size=(8, 2))
    np.savez(tmp_path / "r.npz", x=x, freq=np.array(200.0), units=np.array(["deg/s", "g"]), y=y, m=m)
    rec = read_recording(tmp_path / "r.npz")
    assert rec.freq == 200.0
    assert rec.columns == ("x", "y", "m[0]", "m[1]")
    np.testing.assert_array_equal(rec.data, np.column_stack([x, y, m]))
    sel = read_recording(tmp_path / "r.npz", columns=["m[1]", "x"])
    np.testing.assert_array_equal(sel.data, np.column_stack([m[:, 1], x]))


def test_npz_without_freq(tmp_path: Path) -> None:
    np.savez(tmp_path / "r.npz", a=np.arange(4.0))
    rec = read_recording(tmp_path / "r.npz")
    assert rec.freq is None and isinstance(rec, Recording)


@pytest.mark.data
def test_shared_adis_recording() -> None:
    path = DATA / "imudata" / "adis_16405_imu1.npz"
    if not path.is_file():
        pytest.skip(f"shared data folder absent: {path}")
    rec = read_recording(path, columns=["Gyro_X"])
    with np.load(path) as z:
        np.testing.assert_array_equal(rec.data[:, 0], z["Gyro_X"])
        assert rec.freq == float(z["freq"])


# ------------------------------------------------------------------ errors
@pytest.mark.parametrize(
    ("name", "text", "message"),
    [
        ("cell.csv", "a,b\n1,2\n3,abc\n", r"non-numeric value 'abc' in data row 3"),
        ("ragged.csv", "1,2\n3\n", r"data row 2 has 1 fields, expected 2"),
        ("nan.csv", "1,2\n3,nan\n", r"NaN"),
        ("inf.csv", "1,2\n3,inf\n", r"inf"),
        ("empty.csv", "", r"no data rows"),
        ("comments.csv", "# only\n# comments\n", r"no data rows"),
        ("header_only.csv", "a,b\n", r"header but no data rows"),
        ("short.csv", "1,2\n", r"1 sample\(s\); at least 2"),
        ("widths.csv", "a,b,c\n1,2\n3,4\n", r"header has 3 names but rows have 2"),
        ("data.json", "[1, 2]", r"unknown file format '.json'"),
    ],
)
def test_bad_text_files(tmp_path: Path, name: str, text: str, message: str) -> None:
    with pytest.raises(InputError, match=message):
        read_recording(_write_text(tmp_path, name, text))


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="no such file"):
        read_recording(tmp_path / "nope.csv")
    with pytest.raises(InputError, match="no such file"):
        read_recording(tmp_path)  # a directory is not a recording


def test_bad_binary_files(tmp_path: Path) -> None:
    (tmp_path / "junk.npy").write_text("not numpy")
    (tmp_path / "junk.npz").write_bytes(b"PK\x03\x04 not a zip")
    (tmp_path / "latin.csv").write_bytes(b"\xff\xfe1,2\n")
    np.save(tmp_path / "obj.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    np.save(tmp_path / "cube.npy", np.zeros((2, 2, 2)))
    np.save(tmp_path / "empty.npy", np.zeros(0))
    np.savez(tmp_path / "text.npz", s=np.array(["a", "b"]))
    np.savez(tmp_path / "ragged.npz", a=np.ones(4), b=np.ones(5))
    np.savez(tmp_path / "nan.npz", a=np.array([1.0, np.nan, 2.0]))
    cases = {
        "junk.npy": "cannot read", "junk.npz": "cannot read", "latin.csv": "cannot read",
        "obj.npy": "cannot read", "cube.npy": "1-D or 2-D", "empty.npy": "empty",
        "text.npz": "no numeric arrays", "ragged.npz": r"different lengths \[4, 5\]",
        "nan.npz": "NaN",
    }
    for name, message in cases.items():
        with pytest.raises(InputError, match=message):
            read_recording(tmp_path / name)


def test_first_row_with_a_typo_is_an_error_not_a_header(tmp_path):
    path = tmp_path / "typo.csv"
    path.write_text("1.0,2x\n3.0,4.0\n")
    with pytest.raises(InputError, match="2x"):
        read_recording(path)
