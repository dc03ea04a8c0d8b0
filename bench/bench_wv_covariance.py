"""Benchmark: the full asymptotic covariance of the wavelet variance (Stebler et al. 2014, eq. 17)
at every level, vs allantools' octave Allan deviation on the same data, in the same run.

Run: ``python bench/bench_wv_covariance.py [N] [--contention]`` (default N = 2,000,000 samples
at 100 Hz). The paper calls eq. 17 infeasible for long signals (a direct evaluation sums J^2
cross-correlations over all lags, O(J^2 N^2)); stochmod evaluates it by FFT in O(J N log N).
Also timed: the same covariance under a model (`model_covariance`, the J-test's V, O(J^2) PSD
evaluations). Times are the best of `repeat` runs, wall clock and CPU (``time.process_time``,
less sensitive to other jobs on a shared machine), the covariance with its default threads
and on one thread.

``--contention``: what two processes at once cost each other, the figure that limits a fleet of
single-threaded workers (``stochmod calibrate --workers 2``). Each of the one-thread
covariance and the peer runs in fresh processes, first one alone, then two at once; printed
is the CPU time per call (best and median of `repeat`) and the ratio together / alone (1.0: no
contention; memory-bandwidth-bound work is above).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from _timing import best_of
from bench_gmwm import FREQ, simulated, time_oadev

import stochmod
from stochmod.fit.weighting import model_covariance
from stochmod.empirical.wv_covariance import wv_covariance


def _task(what: str, x: np.ndarray):
    """The timed call: ``eq17`` (wv_covariance on one thread) or ``oadev`` (the peer)."""
    if what == "eq17":
        return lambda: wv_covariance(x, workers=1)
    import allantools

    return lambda: allantools.oadev(x, rate=FREQ, data_type="freq", taus="octave")


def _child(what: str, n: int, repeat: int) -> None:
    fn = _task(what, simulated(n))
    fn()  # warm-up: imports, compiled code, caches
    times = []
    for _ in range(repeat):
        t0 = time.process_time()
        fn()
        times.append(time.process_time() - t0)
    print(min(times), float(np.median(times)))


def _processes(what: str, n: int, repeat: int, count: int) -> np.ndarray:
    """CPU seconds per call (best, median) of `count` fresh processes running `what` at the
    same time, one row per process."""
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", what, str(n),
           "--repeat", str(repeat)]
    runs = [subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True) for _ in range(count)]
    return np.array([[float(v) for v in p.communicate()[0].split()] for p in runs])


def contention(n: int, repeat: int, rounds: int = 2) -> None:
    print(f"two processes at once, CPU per call, best (median) of {repeat} per process, "
          f"best of {rounds} rounds (N = {n:,})")
    for what, label in (("eq17", "stochmod wv_covariance, 1 thread"),
                        ("oadev", "allantools oadev(taus='octave')")):
        alone = np.min([_processes(what, n, repeat, 1)[0] for _ in range(rounds)], axis=0)
        together = np.min([_processes(what, n, repeat, 2).mean(axis=0) for _ in range(rounds)],
                          axis=0)
        print(f"{label:<34} alone {alone[0]:6.3f} ({alone[1]:.3f}) s  two at once "
              f"{together[0]:6.3f} ({together[1]:.3f}) s  ratio {together[0] / alone[0]:5.2f} "
              f"({together[1] / alone[1]:.2f})")


def main(n: int = 2_000_000, repeat: int = 3) -> None:
    x = simulated(n)
    emp = stochmod.wvar(x, FREQ)
    J = emp.wv.size
    V = wv_covariance(x, J)
    t_v = best_of(lambda: wv_covariance(x, J), repeat)
    c_v = best_of(lambda: wv_covariance(x, J), repeat, clock=time.process_time)
    c_v1 = best_of(lambda: wv_covariance(x, J, workers=1), repeat, clock=time.process_time)
    model = stochmod.gmwm(emp, "2*GM+WN").model
    Vm = model_covariance(model, emp.n_coef)
    t_m = best_of(lambda: model_covariance(model, emp.n_coef), repeat)
    t_at = time_oadev(x, repeat)
    c_at = best_of(_task("oadev", x), repeat, clock=time.process_time)
    keep = emp.n_coef / 2.0**emp.levels >= 16
    ratio = np.diag(V)[keep] / np.diag(Vm)[keep]
    print(f"N = {n:,} samples at {FREQ:g} Hz, J = {J} levels (all)")
    print(f"eq. 17 / model variances on the {keep.sum()} levels with M_j/2^j >= 16: "
          f"{ratio.min():.3f} .. {ratio.max():.3f}")
    print(f"stochmod wv_covariance (eq. 17, J x J)        {t_v:8.3f} s   CPU {c_v:7.3f} s")
    print(f"  the same on one thread                      {'':8s}     CPU {c_v1:7.3f} s")
    print(f"stochmod model_covariance (fitted 2*GM+WN)    {t_m:8.3f} s")
    print(f"allantools oadev(taus='octave')               {t_at:8.3f} s   CPU {c_at:7.3f} s")
    print(f"ratio wv_covariance / oadev                   {t_v / t_at:8.2f}     CPU "
          f"{c_v / c_at:7.2f} (one thread {c_v1 / c_at:.2f})")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("n", nargs="?", type=int, default=2_000_000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--contention", action="store_true")
    parser.add_argument("--child", nargs=2, metavar=("WHAT", "N"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        _child(args.child[0], int(args.child[1]), args.repeat)
    elif args.contention:
        contention(args.n, args.repeat)
    else:
        main(args.n, args.repeat)
