"""Benchmark: ``stochmod calibrate`` end to end and by stage, against allantools' octave Allan
deviation of the six columns of the same recording, in the same run.

Run: ``python bench/bench_calibrate.py [--skip-adis] [--skip-long] [--hours H] [--split COLUMN]
[--profile N]``.

Part 1, the real file (``../shared/data/imudata/adis_16405_imu1.npz``, 6 columns x 1e6
samples at 100 Hz): ``stochmod calibrate FILE --triad --report --export kalibr`` as a user runs
it (fits and figures on 2 worker processes). The npz's ``units`` entry (gyros in deg/s,
accelerometers in g) is read and the columns are converted to SI before the selection. Printed:
the total wall time and its ratio to the peer, the parent's stages (timed by wrapping the
functions wherever stochmod's modules hold them: the WV, the eq. 17 covariance on its thread
beside the fits, the datasheet's Allan reading, the figures, the report), the CPU time of the
parent and the workers (the figure that a loaded machine disturbs least) and the peak resident
memory of the parent and of the largest worker.

Part 2, a long record: 8 h at 400 Hz x 6 axes (1.152e7 samples a column), GM + white noise +
random walk per axis, simulated here in SI with its units declared, calibrated by the library
(``stochmod.calibrate``, no figures) in a fresh process, so that its peak resident memory is
its own: printed as the peak over the resident memory before the call (the input already
resident), against the input array's size. Targets: under 30 s and under 1.5x the input.

Part 3, the stage split: the selection of one column (``--split``, default Gyro_X, in SI) run
serially in this process, WV / covariance / fits; ``--profile N`` profiles it (which slows it)
and prints the N entries with the most internal time.

The peer, allantools ``oadev(taus="octave")`` of the file's six columns, is the best of 2. One
run of each part (they are long): on a shared machine times are noisy, the ratios less so.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import cProfile
import functools
import io
import json
import pstats
import resource
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path

import allantools
import numpy as np
from _timing import best_of

import stochmod.cli.calibrate as cli_calibrate
from stochmod.cli import _calibrate_outputs as cli_outputs
from stochmod.cli import main as cli_main
from stochmod.empirical.wavelet_variance import wvar
from stochmod.empirical.wv_covariance import wv_covariance
from stochmod.output.datasheet import datasheet_reading

FILE = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "imudata" / "adis_16405_imu1.npz"
COLUMNS = ("Gyro_X", "Gyro_Y", "Gyro_Z", "Accel_X", "Accel_Y", "Accel_Z")
LONG_FREQ = 400.0
LONG_COLUMNS = ("gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z")


class StageClock:
    """Wall-clock seconds per stage; a stage entered inside another (on the same thread) counts
    for the outer one. Stages on other threads (the covariance beside the fits) overlap."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}
        self.local = threading.local()
        self.lock = threading.Lock()

    def wrap(self, fn: Callable, stage: str) -> Callable:
        @functools.wraps(fn)
        def timed(*args, **kwargs):
            if getattr(self.local, "active", None) is not None:
                return fn(*args, **kwargs)
            self.local.active = stage
            t0 = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                with self.lock:
                    self.seconds[stage] = self.seconds.get(stage, 0.0) + time.perf_counter() - t0
                self.local.active = None

        return timed


def _started(clock: StageClock, start):
    """`start` (:func:`stochmod.cli.calibrate._start_figures`) whose returned call, the wait
    for the figures the workers draw, counts as the "figures" stage."""
    @functools.wraps(start)
    def wrapped(*args, **kwargs):
        return clock.wrap(start(*args, **kwargs), "figures")

    return wrapped


def install(clock: StageClock) -> None:
    """Replace the timed functions by wrappers in every loaded stochmod module that holds them
    (robust to where the code imports them)."""
    # import every module the run will use, so that the wrappers reach them all
    import stochmod.fit.selection
    import stochmod.fit.validation
    import stochmod.fit.weighting
    import stochmod.workflows.calibrate  # noqa: F401

    targets = {id(wvar): clock.wrap(wvar, "WV"),
               id(wv_covariance): clock.wrap(wv_covariance, "covariance (eq. 17, own thread)"),
               id(datasheet_reading): clock.wrap(datasheet_reading, "datasheet Allan reading"),
               id(cli_calibrate._figures): clock.wrap(cli_calibrate._figures, "figures"),
               id(cli_calibrate._start_figures): _started(clock, cli_calibrate._start_figures),
               id(cli_outputs.write_exports_for): clock.wrap(cli_outputs.write_exports_for,
                                                             "exports"),
               id(cli_outputs.report_overview): clock.wrap(cli_outputs.report_overview,
                                                           "report"),
               id(cli_outputs.write_report_for): clock.wrap(cli_outputs.write_report_for,
                                                            "report")}
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
        except BaseException as exc:  # noqa: BLE001 - handed to the caller through the future
            future.set_exception(exc)
        return future


def cpu_seconds() -> float:
    """User + system CPU seconds of this process and of its finished child processes (the
    pool workers are joined, hence counted, when calibrate returns)."""
    return sum(r.ru_utime + r.ru_stime for r in (resource.getrusage(resource.RUSAGE_SELF),
                                                resource.getrusage(resource.RUSAGE_CHILDREN)))


def _status_mb(field: str) -> float:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def reset_peak() -> None:
    """Reset this process's peak resident memory (VmHWM) to its current resident memory."""
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")


def peer() -> float:
    """Seconds of allantools' octave oadev of the file's six columns (best of 2)."""
    with np.load(FILE) as z:
        cols = [np.asarray(z[c], dtype=np.float64) for c in COLUMNS]
        freq = float(z["freq"])
    return best_of(lambda: [allantools.oadev(c, rate=freq, data_type="freq", taus="octave")
                            for c in cols], 2)


def adis(clock: StageClock, t_at: float) -> None:
    """Part 1: the CLI on the real file, as a user runs it."""
    argv = ["calibrate", str(FILE), "--triad", "--report", "--export", "kalibr"]
    reset_peak()
    base = _status_mb("VmRSS")
    cpu0 = cpu_seconds()
    clock.seconds.clear()
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
    peak = _status_mb("VmHWM")
    worker = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0
    print(f"1. stochmod calibrate {FILE.name} --triad --report --export kalibr: 6 columns x 1e6 "
          "samples at 100 Hz (fits and figures on 2 worker processes)")
    print(f"   {'stage (parent)':34s} {'seconds':>9s} {'share':>7s} {'x peer':>8s}")
    s = clock.seconds
    rest = total - sum(v for k, v in s.items() if "own thread" not in k)
    for stage, sec in [*sorted(s.items()), ("selection and the rest", rest), ("total", total)]:
        print(f"   {stage:34s} {sec:9.2f} {sec / total:7.1%} {sec / t_at:8.2f}")
    print(f"   CPU time, parent and workers: {cpu:.1f} s ({cpu / t_at:.1f}x the peer's wall time)")
    print(f"   peak resident memory: parent {peak:.0f} MB ({peak - base:+.0f} MB over the {base:.0f} "
          f"MB before the run), largest worker {worker:.0f} MB")
    print(f"   RATIO total / peer: {total / t_at:.1f}x (target 10x)")


def long_record(hours: float, seed: int = 0) -> np.ndarray:
    """`hours` at 400 Hz x 6 axes in SI: GM (Tc 60 s) + white noise + random walk per axis,
    float64, C order (n, 6); built a column at a time so that no temporary the size of the
    array is resident."""
    from scipy.signal import lfilter

    n = round(hours * 3600 * LONG_FREQ)
    rng = np.random.default_rng(seed)
    data = np.empty((n, 6))
    dt = 1.0 / LONG_FREQ
    beta = np.exp(-dt / 60.0)
    for k in range(6):
        s = 1e-3 if k < 3 else 2e-3  # rad/s, m/s^2 per sample
        col = lfilter([np.sqrt(1 - beta**2) * 0.2 * s], [1.0, -beta], rng.standard_normal(n))
        col += np.cumsum(rng.standard_normal(n)) * (1e-3 * s)
        col += rng.standard_normal(n) * s
        data[:, k] = col
        del col
    return data


def long_child(hours: float, spectra_bytes: int | None) -> None:
    """Part 2 in this (fresh) process; prints one JSON line."""
    import stochmod
    import stochmod.empirical.wv_covariance as covariance
    from stochmod.io.recording import Recording

    if spectra_bytes is not None:
        covariance.SPECTRA_BYTES = spectra_bytes

    data = long_record(hours)
    rec = Recording(data, LONG_COLUMNS, LONG_FREQ, units=("rad/s",) * 3 + ("m/s^2",) * 3)
    clock = StageClock()
    install(clock)
    reset_peak()
    base = _status_mb("VmRSS")
    cpu0 = cpu_seconds()
    t0 = time.perf_counter()
    cal = stochmod.calibrate(rec)
    total = time.perf_counter() - t0
    print(json.dumps({"seconds": total, "cpu": cpu_seconds() - cpu0, "peak": _status_mb("VmHWM"),
                      "base": base, "nbytes": data.nbytes, "n": data.shape[0],
                      "worker": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0,
                      "stages": clock.seconds,
                      "models": {a.column: a.model.name for a in cal.axes}}))


def long_part(hours: float, t_at: float, spectra_bytes: int | None = None) -> None:
    """Part 2: the long record in a fresh process (`spectra_bytes`: the covariance's budget
    of level spectra, :data:`stochmod.empirical.wv_covariance.SPECTRA_BYTES`)."""
    extra = [] if spectra_bytes is None else ["--spectra-bytes", str(spectra_bytes)]
    proc = subprocess.run([sys.executable, __file__, "--long-child", str(hours), *extra],
                          check=False, capture_output=True, text=True, cwd=Path(__file__).parent)
    if proc.returncode != 0:
        sys.exit(f"the long-record run failed:\n{proc.stderr}")
    r = json.loads(proc.stdout.strip().splitlines()[-1])
    mb = r["nbytes"] / 2**20
    extra = r["peak"] - r["base"]
    print(f"\n2. stochmod.calibrate of {hours:g} h at {LONG_FREQ:g} Hz x 6 axes ({r['n']:,} samples "
          f"a column, {mb:.0f} MB of input, SI, no figures), in a fresh process"
          + ("" if spectra_bytes is None else f", covariance spectra budget {spectra_bytes:,} B"))
    for stage, sec in sorted(r["stages"].items()):
        print(f"   {stage:34s} {sec:9.2f} s")
    print(f"   total {r['seconds']:.1f} s ({r['seconds'] / t_at:.1f}x the peer; target 30 s), "
          f"CPU parent and workers {r['cpu']:.1f} s")
    print(f"   peak resident memory {r['peak']:.0f} MB, {extra:+.0f} MB over the {r['base']:.0f} MB "
          f"before the call: {extra / mb:.2f}x the input (target 1.5x); largest worker "
          f"{r['worker']:.0f} MB")
    print(f"   models: {r['models']}")


def split(args: argparse.Namespace, clock: StageClock, t_at: float) -> None:
    """Part 3: one column's selection, serial, by stage (and profiled with --profile)."""
    from stochmod.core.units import convert
    from stochmod.fit.selection import select

    with np.load(FILE) as z:
        x = np.asarray(z[args.split], dtype=np.float64)
    unit = "deg/s" if args.split.lower().startswith("gyro") else "g"
    x = np.asarray(convert(x, unit, "rad/s" if unit == "deg/s" else "m/s^2"), dtype=np.float64)
    clock.seconds.clear()
    prof = cProfile.Profile() if args.profile else None
    t0 = time.perf_counter()
    if prof is None:
        select(x[:, None], 100.0, names=[args.split], executor=InlineExecutor())
    else:
        prof.runcall(select, x[:, None], 100.0, names=[args.split], executor=InlineExecutor())
    total = time.perf_counter() - t0
    s = clock.seconds
    cov = s.get("covariance (eq. 17, own thread)", 0.0)
    print(f"\n3. stage split: select() on {args.split} alone, serial in one process"
          f"{' (profiled: slower)' if prof else ''}")
    print(f"   {'stage':34s} {'seconds':>9s} {'share':>7s} {'x peer':>8s}")
    for stage, sec in [("WV", s.get("WV", 0.0)), ("covariance (eq. 17)", cov),
                       ("fits / selection", total - s.get("WV", 0.0) - cov), ("total", total)]:
        print(f"   {stage:34s} {sec:9.2f} {sec / total:7.1%} {sec / t_at:8.2f}")
    if prof is not None:
        text = io.StringIO()
        pstats.Stats(prof, stream=text).sort_stats("tottime").print_stats(args.profile)
        print(f"\nprofile of that run, by internal time:\n{text.getvalue()}")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--skip-adis", action="store_true", help="no part 1")
    p.add_argument("--skip-long", action="store_true", help="no part 2")
    p.add_argument("--skip-split", action="store_true", help="no part 3")
    p.add_argument("--hours", type=float, default=8.0, help="length of part 2's record (default 8)")
    p.add_argument("--split", default="Gyro_X", metavar="COLUMN",
                   help="the column of the serial stage split (default Gyro_X)")
    p.add_argument("--profile", type=int, default=0, metavar="N")
    p.add_argument("--spectra-bytes", type=int, default=None, metavar="B",
                   help="part 2 with this budget of the covariance's level spectra (default "
                        "the library's; a large one holds all levels at once)")
    p.add_argument("--long-child", type=float, default=None, help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.long_child is not None:
        long_child(args.long_child, args.spectra_bytes)
        return
    if not FILE.is_file():
        sys.exit(f"the recording {FILE} is absent")
    t_at = peer()
    print(f"peer: allantools oadev(taus='octave') of the file's six columns, {t_at:.2f} s "
          "(the unit of 'x peer')\n")
    if not args.skip_long:  # first: a fresh process, before this one holds the file
        long_part(args.hours, t_at, args.spectra_bytes)
        print()
    clock = StageClock()
    install(clock)
    if not args.skip_adis:
        adis(clock, t_at)
    if not args.skip_split:
        split(args, clock, t_at)
    print("\none run each on a shared machine: times are noisy, the ratios less so")


if __name__ == "__main__":
    main()
