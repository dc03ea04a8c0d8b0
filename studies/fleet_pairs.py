"""Does this machine run two processes as fast as one? The ceiling of a fleet's scaling.

Run: ``python studies/fleet_pairs.py [--repeats 5]``. Each probe runs in a fresh process pinned
to one core, alone (core 0) and as a pair at once (cores 0 and 1), the two kinds interleaved
`repeats` times; printed are the median CPU time of a probe alone and in a pair (each
process's, and the slower one's), and the ratio pair / alone: how much a second busy process
slows the first.

Probes, from compute-bound to memory-bound:

- ``python``: a pure-Python loop (registers and L1);
- ``numpy-l2``: element-wise numpy on two 0.8 MB arrays (each core's L2);
- ``numpy-l3``: the same on two 16 MB arrays (together, the two processes' 64 MB exceed the
  shared L3 cache of 32 MB on the machine this was written on);
- ``eq17``: stochmod's WV covariance (:func:`stochmod.empirical.wv_covariance.wv_covariance`,
  one thread) of 2^20 samples, more than half of a fleet task's CPU (its J float32 spectra
  are 80 MB);
- ``calibrate``: one fleet task of ``bench/bench_fleet.py`` (6 axes x 2^20 samples, three
  candidates, no figures), warm (:mod:`stochmod.cli.fleet_worker` imported first).

A fleet of identical files on two workers (dynamic assignment: a worker takes the next file
when it is free) can be at most ``2 / ratio`` times faster than one worker, before its
start-up and the last task's imbalance (``bench/bench_fleet.py``).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys

import numpy as np

PROBES = {
    "python": "s = 0\nfor i in range(6_000_000):\n    s += i",
    "numpy-l2": ("a = np.random.default_rng(0).random(100_000); b = np.empty_like(a)\n"
                 "for _ in range(3000):\n    np.multiply(a, 0.5, out=b); np.add(b, 0.25, out=a)"),
    "numpy-l3": ("a = np.random.default_rng(0).random(2_000_000); b = np.empty_like(a)\n"
                 "for _ in range(150):\n    np.multiply(a, 0.5, out=b); np.add(b, 0.25, out=a)"),
    "eq17": ("from stochmod.empirical.wv_covariance import wv_covariance\n"
             "x = np.random.default_rng(0).standard_normal(1 << 20)\nwv_covariance(x, workers=1)\n"
             "t = time.process_time()\nfor _ in range(3):\n    wv_covariance(x, workers=1)"),
    "calibrate": ("import tempfile\nfrom pathlib import Path\nimport stochmod.cli.fleet_worker\n"
                  "from stochmod.cli import _parser_for\nfrom stochmod.cli.calibrate import calibrate_unit\n"
                  "from stochmod.data.examples import XSENS_COLUMNS, xsens_mtig\n"
                  "from stochmod.workflows.fleet import SerialExecutor, single_threaded\n"
                  "tmp = Path(tempfile.mkdtemp())\nrec = xsens_mtig(n=1 << 20, seed=7)\n"
                  "np.savez(tmp / 'imu.npz', freq=rec.freq, **{c: rec.column(c) for c in XSENS_COLUMNS})\n"
                  "argv = ['calibrate', str(tmp / 'imu.npz'), '--candidates', 'GM+WN', '2*GM+WN', "
                  "'WN+RW', '--no-plots', '--out', str(tmp / 'out')]\n"
                  "args = _parser_for(argv).parse_args(argv)\n"
                  "t = time.process_time()\nwith single_threaded():\n"
                  "    calibrate_unit(args, SerialExecutor())"),
}
_TIMED = ("import os, time\nimport numpy as np\nos.sched_setaffinity(0, {{{core}}})\n"
          "{setup}\nt = time.process_time()\n{body}\nprint(time.process_time() - t)")


def _script(probe: str, core: int) -> str:
    code = PROBES[probe]
    setup, _, body = code.partition("t = time.process_time()\n") if "t = time" in code else ("", "", code)
    return _TIMED.format(core=core, setup=setup, body=body)


def _run(probe: str, cores: list[int]) -> list[float]:
    """CPU seconds of the probe in one process per core in `cores`, all started at once."""
    env = os.environ | {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
                        "MKL_NUM_THREADS": "1", "STOCHMOD_FFT_THREADS": "1"}
    procs = [subprocess.Popen([sys.executable, "-c", _script(probe, c)], env=env, text=True,
                              stdout=subprocess.PIPE) for c in cores]
    return [float(p.communicate()[0]) for p in procs]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--probes", nargs="+", choices=list(PROBES), default=list(PROBES))
    a = p.parse_args()
    if not hasattr(os, "sched_setaffinity") or len(os.sched_getaffinity(0)) < 2:
        raise SystemExit("needs Linux and at least two cores")
    print("medians of CPU time (s); in a pair, each process's, then the slower one's")
    print(f"{'probe':10s} {'alone':>7s} {'pair':>7s} {'slower':>7s} {'pair/alone':>10s} "
          f"{'fleet ceiling':>13s}")
    for probe in a.probes:
        alone, pair, slower = [], [], []
        for _ in range(a.repeats):
            alone += _run(probe, [0])
            both = _run(probe, [0, 1])
            pair += both
            slower.append(max(both))
        ratio = float(np.median(pair) / np.median(alone))
        print(f"{probe:10s} {np.median(alone):7.2f} {np.median(pair):7.2f} {np.median(slower):7.2f} "
              f"{ratio:10.2f} {2 / ratio:12.2f}x")


if __name__ == "__main__":
    main()
