"""Benchmark: ``stochmod calibrate`` of the real 6-axis ADIS16405 recording, end to end and by
stage, against one allantools octave Allan deviation of one axis in the same run.

Run: ``python bench/bench_calibrate.py [--columns Gyro_X ...] [--no-plots] [--split COLUMN]
[--profile N]``.
The file (``../shared/data/imudata/adis_16405_imu1.npz``, 1e6 samples per axis at 100 Hz)
holds gyros in deg/s and accelerometers in g with their turn-on biases; the calibration runs
on them as they are (the default lattice, ``--scale 1``): a constant bias cancels in every
wavelet coefficient, so it changes neither the wavelet variance nor the fits, and each column
is fitted in its own unit.

Part 1, end to end: the CLI as a user runs it (its selection's fits and then its figures on
one pool of 2 worker processes, ``--jobs 2``), total wall time, the figure step (timed in the
parent), the CPU time of the parent and the workers (the figure that a loaded machine
disturbs least) and the peak resident memory of the parent and of the largest worker. Part 2, the stage split: the selection of one
column (``--split``, default Gyro_X) run serially in this process, with ``wvar`` ("WV"),
``wv_covariance`` ("covariance", eq. 17) and the rest ("fits / selection") timed by wrapping
the functions wherever stochmod's modules hold them; ``--profile N`` profiles that same serial
run (which slows it) and prints the N entries with the most internal time. One run each (they
are long); the oadev reference is the best of 3.
"""

from __future__ import annotations

import argparse
import cProfile
import functools
import io
import pstats
import resource
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import concurrent.futures

import allantools
import numpy as np
from _timing import best_of

import stochmod.cli.calibrate as cli_calibrate
from stochmod.cli import main as cli_main
from stochmod.empirical.wavelet_variance import wvar
from stochmod.empirical.wv_covariance import wv_covariance

FILE = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "imudata" / "adis_16405_imu1.npz"


class StageClock:
    """Wall-clock seconds per stage; a stage entered inside another counts for the outer one."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}
        self.active: str | None = None

    def wrap(self, fn: Callable, stage: str) -> Callable:
        @functools.wraps(fn)
        def timed(*args, **kwargs):
            if self.active is not None:
                return fn(*args, **kwargs)
            self.active = stage
            t0 = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                self.seconds[stage] = self.seconds.get(stage, 0.0) + time.perf_counter() - t0
                self.active = None

        return timed


def install(clock: StageClock) -> None:
    """Replace wvar, wv_covariance and the CLI's figure step by timed wrappers in every
    loaded stochmod module that holds them (robust to where the fit code imports them)."""
    targets = {id(wvar): clock.wrap(wvar, "WV"),
               id(wv_covariance): clock.wrap(wv_covariance, "covariance"),
               id(cli_calibrate._figures): clock.wrap(cli_calibrate._figures, "figures")}
    for name, module in list(sys.modules.items()):
        if not name.startswith("stochmod") or module is None:
            continue
        for attr, value in list(vars(module).items()):
            if id(value) in targets and callable(value):
                setattr(module, attr, targets[id(value)])


class InlineExecutor(concurrent.futures.Executor):
    """Runs each submitted call at once in this process (a serial selection)."""

    def submit(self, fn, /, *args, **kwargs):
        future = concurrent.futures.Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except BaseException as exc:  # handed to the caller through the future
            future.set_exception(exc)
        return future


def cpu_seconds() -> float:
    """User + system CPU seconds of this process and of its finished child processes (the
    selection's pool workers are joined, hence counted, when calibrate returns)."""
    return sum(r.ru_utime + r.ru_stime for r in (resource.getrusage(resource.RUSAGE_SELF),
                                                resource.getrusage(resource.RUSAGE_CHILDREN)))


def rss_mb() -> float:
    """Current resident set size, MB (Linux /proc)."""
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * resource.getpagesize() / 2**20


def end_to_end(args: argparse.Namespace, clock: StageClock, t_at: float, n: int, nbytes: int) -> None:
    """Part 1: the CLI on every requested column, as a user runs it."""
    argv = ["calibrate", str(FILE)]
    for c in args.columns or []:
        argv += ["--column", c]
    if args.no_plots:
        argv.append("--no-plots")
    base = rss_mb()
    cpu0 = cpu_seconds()
    with tempfile.TemporaryDirectory() as out:
        sink = io.StringIO()
        t0 = time.perf_counter()
        stdout, sys.stdout = sys.stdout, sink
        try:
            status = cli_main(argv + ["--out", out])
        finally:
            sys.stdout = stdout
        total = time.perf_counter() - t0
    cpu = cpu_seconds() - cpu0
    if status != 0:
        sys.exit(f"stochmod calibrate exited with status {status}")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    worker = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0
    figures = clock.seconds.pop("figures", 0.0)
    k = len(args.columns or []) or 6
    print(f"stochmod calibrate {FILE.name}: {k} column(s) x {n:,} samples at 100 Hz, default "
          f"lattice{', no figures' if args.no_plots else ''} (fits and figures on 2 worker processes)")
    print(f"{'stage':24s} {'seconds':>9s} {'share':>7s} {'x oadev':>9s}")
    for stage, sec in [("select + report", total - figures), ("figures", figures),
                       ("total", total)]:
        print(f"{stage:24s} {sec:9.2f} {sec / total:7.1%} {sec / t_at:9.1f}")
    print(f"CPU time, parent and workers: {cpu:.1f} s (x oadev {cpu / t_at:.1f}); on a machine "
          f"nobody else uses, 2 cores need at least {cpu / 2:.1f} s of wall time for it")
    print(f"peak resident memory: parent {peak:.0f} MB ({peak - base:+.0f} MB over the "
          f"{base:.0f} MB before the run), largest worker {worker:.0f} MB; the data: "
          f"{k} x {nbytes / 2**20:.0f} MB")


def split(args: argparse.Namespace, clock: StageClock, t_at: float) -> None:
    """Part 2: one column's selection, serial, by stage (and profiled with --profile)."""
    from stochmod.fit.selection import select

    with np.load(FILE) as z:
        x = np.asarray(z[args.split], dtype=np.float64)
    clock.seconds.clear()
    prof = cProfile.Profile() if args.profile else None
    t0 = time.perf_counter()
    if prof is None:
        select(x[:, None], 100.0, names=[args.split], executor=InlineExecutor())
    else:
        prof.runcall(select, x[:, None], 100.0, names=[args.split], executor=InlineExecutor())
    total = time.perf_counter() - t0
    s = clock.seconds
    print(f"\nstage split: select() on {args.split} alone, serial in one process"
          f"{' (profiled: slower)' if prof else ''}")
    print(f"{'stage':24s} {'seconds':>9s} {'share':>7s} {'x oadev':>9s}")
    for stage, sec in [("WV", s.get("WV", 0.0)), ("covariance (eq. 17)", s.get("covariance", 0.0)),
                       ("fits / selection", total - sum(s.values())), ("total", total)]:
        print(f"{stage:24s} {sec:9.2f} {sec / total:7.1%} {sec / t_at:9.1f}")
    if prof is not None:
        text = io.StringIO()
        pstats.Stats(prof, stream=text).sort_stats("tottime").print_stats(args.profile)
        print(f"\nprofile of that run, by internal time:\n{text.getvalue()}")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--columns", nargs="*", default=None, help="columns (default: all six)")
    p.add_argument("--no-plots", action="store_true")
    p.add_argument("--split", default="Gyro_X", metavar="COLUMN",
                   help="the column of the serial stage split (default Gyro_X)")
    p.add_argument("--skip-end-to-end", action="store_true", help="part 2 only")
    p.add_argument("--profile", type=int, default=0, metavar="N")
    args = p.parse_args()
    if not FILE.is_file():
        sys.exit(f"the recording {FILE} is absent")
    with np.load(FILE) as z:
        gyro_x = np.asarray(z["Gyro_X"], dtype=np.float64)
        freq = float(z["freq"])
    t_at = best_of(lambda: allantools.oadev(gyro_x, rate=freq, data_type="freq", taus="octave"), 3)

    # import every module the run will use, so that the wrappers reach them all
    import stochmod.fit.selection  # noqa: F401
    import stochmod.fit.weighting  # noqa: F401

    clock = StageClock()
    install(clock)
    if not args.skip_end_to_end:
        end_to_end(args, clock, t_at, gyro_x.size, gyro_x.nbytes)
    split(args, clock, t_at)
    print(f"\nallantools oadev(taus='octave') of Gyro_X: {t_at:.3f} s (the unit of 'x oadev'); "
          "one run on a shared machine: times are noisy, the ratios less so")


if __name__ == "__main__":
    main()
