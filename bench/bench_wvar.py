"""Benchmark: stochmod Haar wavelet variance vs allantools overlapping Allan deviation.

Run: ``python bench/bench_wvar.py [N]``. Both compute the same quantity at every octave
(Haar WV = AVAR / 2); times are the best of `repeat` runs each, in the same process: wall clock
(the ratio the goal states), then CPU time of this process (``time.process_time``, less
disturbed by other jobs on a shared machine; both are single-threaded). Also reports the
peak extra memory of ``wvar`` (tracemalloc) relative to the input array, and the db4 and
"normal"-interval timings for information. The Haar path runs compiled loops
(:mod:`stochmod.empirical.haar_jit`).
"""

from __future__ import annotations

import sys
import time

import allantools
import numpy as np
from _timing import best_of, peak_ratio

from stochmod.empirical.wavelet_variance import wvar


def main(n: int = 2_000_000, repeat: int = 5) -> None:
    freq = 100.0
    rng = np.random.default_rng(20240601)
    x = rng.standard_normal(n) + np.cumsum(1e-3 * rng.standard_normal(n))  # WN + RW

    res = wvar(x, freq)
    taus, adev, _, _ = allantools.oadev(x, rate=freq, data_type="freq", taus="octave")
    common = np.isin(np.round(res.tau * freq), np.round(taus * freq))
    ref = 0.5 * adev[np.isin(np.round(taus * freq), np.round(res.tau * freq))] ** 2
    agree = np.max(np.abs(res.wv[common] / ref - 1))

    t_sm = best_of(lambda: wvar(x, freq), repeat)
    t_at = best_of(lambda: allantools.oadev(x, rate=freq, data_type="freq", taus="octave"), repeat)
    c_sm = best_of(lambda: wvar(x, freq), repeat, clock=time.process_time)
    c_at = best_of(lambda: allantools.oadev(x, rate=freq, data_type="freq", taus="octave"), repeat,
                   clock=time.process_time)
    t_db4 = best_of(lambda: wvar(x, freq, wavelet="db4"))
    t_norm = best_of(lambda: wvar(x, freq, ci="normal"))
    mem = peak_ratio(lambda: wvar(x, freq), x.nbytes)
    mem_norm = peak_ratio(lambda: wvar(x, freq, ci="normal"), x.nbytes)

    print(f"N = {n:,} samples (WN + RW), Haar levels 1..{res.levels[-1]}; "
          f"{int(common.sum())} octaves shared with allantools, max rel. diff {agree:.1e}")
    print(f"stochmod wvar (haar, chi2 CI)      {t_sm * 1e3:9.1f} ms")
    print(f"allantools oadev(taus='octave')    {t_at * 1e3:9.1f} ms")
    print(f"speed-up stochmod / allantools     {t_at / t_sm:9.1f} x   (goal >= 9)")
    print(f"CPU: wvar {c_sm * 1e3:.1f} ms, oadev {c_at * 1e3:.1f} ms, speed-up {c_at / c_sm:.1f} x")
    print(f"peak extra memory of wvar          {mem:9.2f} x input   (goal <= 1.1)")
    print(f"for information: db4 wvar          {t_db4 * 1e3:9.1f} ms")
    print(f"for information: haar, normal CI   {t_norm * 1e3:9.1f} ms, "
          f"peak memory {mem_norm:.2f} x input")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 2_000_000)
