"""Benchmark: robust (biweight M-estimate) vs classical Haar wavelet variance, same run.

Run: ``python bench/bench_robust_wv.py [N]``. Both at every level the signal allows, chi2
intervals; times are the best of 3 runs each, in the same process (the machine may be shared:
read the ratio, not the absolute times). Also the peak extra memory (tracemalloc) relative to
the input, and the sandwich ("normal") interval's time for information. Both estimators run
compiled Haar loops (:mod:`stochmod.empirical.haar_jit`).
"""

from __future__ import annotations

import sys
import time

import numpy as np

from stochmod.empirical.wavelet_variance import wvar
from _timing import best_of, peak_ratio


def main(n: int = 2_000_000) -> None:
    freq = 100.0
    rng = np.random.default_rng(20240601)
    x = rng.standard_normal(n) + np.cumsum(1e-3 * rng.standard_normal(n))  # WN + RW
    spikes = rng.choice(n, size=n // 1000, replace=False)
    x[spikes] += 30.0  # 0.1 % isolated outliers

    classical = wvar(x, freq)
    robust = wvar(x, freq, robust=True, efficiency=0.6)
    t_cl = best_of(lambda: wvar(x, freq))
    t_rb = best_of(lambda: wvar(x, freq, robust=True, efficiency=0.6))
    cpu_cl = best_of(lambda: wvar(x, freq), clock=time.process_time)
    cpu_rb = best_of(lambda: wvar(x, freq, robust=True, efficiency=0.6), clock=time.process_time)
    t_nm = best_of(lambda: wvar(x, freq, robust=True, ci="normal"), repeat=1)
    mem = peak_ratio(lambda: wvar(x, freq, robust=True), x.nbytes)

    print(f"N = {n:,} samples (WN + RW, 0.1% spikes), Haar levels 1..{robust.levels[-1]}")
    print(f"level-1 WV: classical {classical.wv[0]:.4g}, robust {robust.wv[0]:.4g} (truth 0.5)")
    print(f"classical wvar (chi2 CI)           {t_cl * 1e3:9.1f} ms")
    print(f"robust wvar (biweight, eff 0.6)    {t_rb * 1e3:9.1f} ms")
    print(f"ratio robust / classical           {t_rb / t_cl:9.2f} x   (goal <= 5)")
    print(f"same, CPU time (process_time)      {cpu_rb / cpu_cl:9.2f} x   (less sensitive to load)")
    print(f"peak extra memory of robust wvar   {mem:9.2f} x input")
    print(f"for information: robust, normal CI {t_nm * 1e3:9.1f} ms")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 2_000_000)
