"""Bad files in every format reach every command as one line on stderr and exit code 2.

Each format the first-party readers take (CSV/TSV, NPY, NPZ, PX4 ULog, ROS 1 bag) is given as
random bytes, as the first bytes of a valid file (truncated) and as an empty file, to
``calibrate``, ``navigate``, ``combine`` and ``readers``: none may end in a traceback or a
silent result.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from stochmod.cli import main

SUFFIXES = (".csv", ".tsv", ".npy", ".npz", ".ulg", ".bag")


def _valid(path: Path) -> None:
    """A small valid file of the suffix of `path` (the source of the truncated one)."""
    if path.suffix == ".npy":
        np.save(path, np.zeros((50, 2)))
    elif path.suffix == ".npz":
        np.savez(path, gyro_x=np.zeros(50), freq=100.0)
    else:
        sep = "\t" if path.suffix == ".tsv" else ","
        rows = [sep.join(("time", "gyro_x"))] + [sep.join((f"{k / 100:.2f}", "0.0"))
                                                 for k in range(50)]
        path.write_text("\n".join(rows) + "\n")


def _bad(tmp_path: Path, suffix: str, kind: str) -> Path:
    path = tmp_path / f"{kind}{suffix}"
    if kind == "garbage":
        path.write_bytes(np.random.default_rng(7).bytes(3000))
    elif kind == "empty":
        path.write_bytes(b"")
    else:
        source = tmp_path / f"valid{suffix}"
        _valid(source)
        data = source.read_bytes()
        path.write_bytes(data[: max(1, len(data) // 3)] if suffix in (".npy", ".npz")
                         else data[:12])
    return path


def _commands(path: Path, out: Path) -> dict[str, list[str]]:
    f = str(path)
    return {"calibrate": ["calibrate", f, "--out", str(out), "--no-plots"],
            "navigate": ["navigate", f, f, "--out", str(out)],
            "combine": ["combine", f, f, "--out", str(out / "s.npz"), "--no-plots"],
            "readers": ["readers", f]}


@pytest.mark.parametrize("suffix", SUFFIXES)
@pytest.mark.parametrize("kind", ["garbage", "truncated", "empty"])
@pytest.mark.parametrize("command", ["calibrate", "navigate", "combine", "readers"])
def test_a_bad_file_is_one_line_and_exit_2(tmp_path: Path, capsys, suffix: str, kind: str,
                                           command: str) -> None:
    path = _bad(tmp_path, suffix, kind)
    argv = _commands(path, tmp_path / "out")[command]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"stochmod {command}: error: "), err

