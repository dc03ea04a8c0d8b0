"""Benchmark: a 200-replicate parametric bootstrap of a GM+WN fit at 2^20 samples vs
allantools' octave Allan deviation of the same signal, in the same run.

Run: ``python bench/bench_bootstrap.py [N] [B]`` (default N = 2^20 samples at 100 Hz, B =
200). stochmod resimulates B records from the fit, takes their Haar wavelet variance at every
level and refits the model (:func:`stochmod.fit.bootstrap.bootstrap`), once in this process
and once on a 2-worker process pool (pool start included); the peer computes
``allantools.oadev(taus="octave")`` once. Times are wall clock, then CPU time (this process
plus the pool's workers, which ``resource.getrusage(RUSAGE_CHILDREN)`` counts once the pool is
shut down): on a shared machine the CPU time is the steadier figure.
"""

from __future__ import annotations

import resource
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import allantools
import numpy as np
from _timing import best_of

import stochmod
from stochmod.fit.bootstrap import bootstrap
from stochmod.fit.gmwm import gmwm

FREQ = 100.0
TRUTH = "GM(beta=0.5, sigma2=1e-6) + WN(sigma2=3e-6)"


def _cpu() -> float:
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def timed(fn) -> tuple[float, float, object]:
    """Wall and CPU time (this process and its reaped children) of one call, and its value."""
    t0, c0 = time.perf_counter(), _cpu()
    out = fn()
    return time.perf_counter() - t0, _cpu() - c0, out


def main(n: int = 2**20, n_boot: int = 200) -> None:
    x = stochmod.model_from_spec(TRUTH, FREQ).simulate(n, rng=20240601)
    fit = gmwm(x, "GM+WN", FREQ)
    _ = fit.jtest  # the asymptotic inference the bootstrap starts from, outside the timing

    def pooled():
        with ProcessPoolExecutor(2) as pool:
            return bootstrap(fit, n_boot, rng=1, executor=pool)

    w_serial, c_serial, boot = timed(lambda: bootstrap(fit, n_boot, rng=1))
    w_pool, c_pool, boot2 = timed(pooled)
    same = np.array_equal(boot.resampling.draws.estimates, boot2.resampling.draws.estimates)
    w_at, c_at, _ = timed(lambda: allantools.oadev(x, rate=FREQ, data_type="freq", taus="octave"))
    w_at = min(w_at, best_of(lambda: allantools.oadev(x, rate=FREQ, data_type="freq",
                                                      taus="octave"), 2))
    beta = boot.parameters()[0]
    print(f"N = {n:,} samples at {FREQ:g} Hz; truth {TRUTH}; B = {n_boot}")
    print(f"GM.beta = {beta.value:.4g} 1/s, bootstrap 95 % [{beta.low:.4g}, {beta.high:.4g}]; "
          f"J-test bootstrap p = {boot.jtest.pvalue:.3g}; failed refits "
          f"{boot.resampling.draws.failed}; pool draws identical: {same}")
    print(f"bootstrap, this process                {w_serial:8.2f} s wall {c_serial:8.2f} s CPU")
    print(f"bootstrap, 2 worker processes          {w_pool:8.2f} s wall {c_pool:8.2f} s CPU")
    print(f"allantools oadev(taus='octave')        {w_at:8.3f} s wall {c_at:8.3f} s CPU")
    print(f"ratio bootstrap (2 workers) / oadev    {w_pool / w_at:8.1f} wall "
          f"{c_pool / c_at:8.1f} CPU")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]))
