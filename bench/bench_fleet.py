"""Benchmark: a fleet calibration on a dask LocalCluster against the serial run, same files.

Run: ``python bench/bench_fleet.py [--files 12] [--n 1048576] [--workers 2]`` (defaults: 12
files x 6 axes x 2^20 samples at 100 Hz, the XSens MTi-G models of the bundled example, each
file its own seed). Both runs calibrate every file with ``stochmod calibrate FILE ...
--candidates GM+WN 2*GM+WN WN+RW --no-plots`` (three candidates per axis, to keep the run
practical): serially (no ``--workers``: one file after the other in one process, each file's
fits in its own thread) and with ``--workers N`` (one dask task per file). The printed ratio
is serial / parallel wall time; the runs' results are checked to be identical. The runs are
made in the order parallel, serial, serial, parallel (so that a drift of the machine's load
hits both alike) and the best of each kind is kept; on a shared machine they stay noisy.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from stochmod.cli import main as cli
from stochmod.examples import XSENS_COLUMNS, xsens_mtig

CANDIDATES = ["GM+WN", "2*GM+WN", "WN+RW"]


def _files(folder: Path, n_files: int, n: int) -> list[Path]:
    paths = []
    for i in range(n_files):
        rec = xsens_mtig(n=n, seed=1000 + i)
        path = folder / f"imu{i:02d}.npz"
        np.savez(path, freq=rec.freq, **{c: rec.column(c) for c in XSENS_COLUMNS})
        paths.append(path)
    return paths


def _run(files: list[Path], out: Path, extra: list[str]) -> float:
    t0 = time.perf_counter()
    code = cli(["calibrate", *map(str, files), "--candidates", *CANDIDATES, "--no-plots",
                "--out", str(out), *extra])
    if code != 0:
        raise SystemExit(f"calibrate failed with code {code}")
    return time.perf_counter() - t0


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--files", type=int, default=12)
    p.add_argument("--n", type=int, default=2**20, help="samples per axis (default 2^20)")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--rounds", type=int, choices=(1, 2), default=2,
                   help="1: parallel then serial; 2: parallel, serial, serial, parallel")
    a = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        files = _files(folder, a.files, a.n)
        t_par, t_ser = [], []
        for k, kind in enumerate(("parallel", "serial", "serial", "parallel")[: 2 * a.rounds]):
            extra = ["--workers", str(a.workers)] if kind == "parallel" else []
            (t_par if kind == "parallel" else t_ser).append(_run(files, folder / f"{kind}{k}", extra))
        outs = [d for d in folder.iterdir() if d.is_dir()]
        same = all(
            json.loads((d / f.stem / "calibration.json").read_text())["columns"]
            == json.loads((outs[0] / f.stem / "calibration.json").read_text())["columns"]
            for f in files for d in outs)
        runs = f"parallel runs {[round(t, 1) for t in t_par]} s, serial runs {[round(t, 1) for t in t_ser]} s"
        t_par, t_ser = min(t_par), min(t_ser)
    print(f"{a.files} files x {len(XSENS_COLUMNS)} axes x {a.n:,} samples, candidates {CANDIDATES}")
    print(runs)
    print(f"serial run (best)                  {t_ser:9.1f} s")
    print(f"dask LocalCluster, {a.workers} workers (best) {t_par:9.1f} s")
    print(f"speed-up serial / parallel         {t_ser / t_par:9.2f}")
    print(f"identical results                  {same}")


if __name__ == "__main__":
    main()
