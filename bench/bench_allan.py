"""Benchmark: overlapping Allan variance, stochmod vs allantools.oadev.

N = 2,000,000 samples of white noise at 100 Hz; both libraries compute the same averaging
times: the 20 octave taus (m = 1, 2, 4, ..., 2^19: stochmod's in-place pyramid), then the
decade grid that a datasheet reading uses (any m: one cumulative sum and, with numba, one
compiled loop per tau); best of 3 wall-clock runs each, in the same process. The stochmod call
includes its interval computation (Greenhall EDF); allantools' does not.

    python bench/bench_allan.py
"""

from __future__ import annotations


import allantools
import numpy as np

from stochmod.empirical.allan import avar
from _timing import best_of



def main() -> None:
    n, freq = 2_000_000, 100.0
    x = np.random.default_rng(12345).standard_normal(n)
    ours = avar(x, freq, taus="octave")
    taus, dev, _, _ = allantools.oadev(x, rate=freq, data_type="freq", taus="octave")
    assert np.array_equal(taus, ours.tau), "the two tau grids differ"
    rel = float(np.max(np.abs(dev**2 / ours.avar - 1.0)))
    t_ours = best_of(lambda: avar(x, freq, taus="octave"))
    t_peer = best_of(lambda: allantools.oadev(x, rate=freq, data_type="freq", taus="octave"))
    print(f"N = {n}, {ours.tau.size} octave taus, largest relative difference of the variances "
          f"{rel:.1e}")
    print(f"stochmod avar (overlapping, with EDF intervals): {t_ours * 1e3:8.1f} ms")
    print(f"allantools.oadev:                               {t_peer * 1e3:8.1f} ms")
    print(f"ratio allantools / stochmod: {t_peer / t_ours:.2f}x (goal >= 3x)")

    ours = avar(x, freq, taus="decade")
    taus, dev, _, _ = allantools.oadev(x, rate=freq, data_type="freq", taus=ours.tau)
    assert np.allclose(taus, ours.tau, rtol=1e-12, atol=0), "the two tau grids differ"
    rel = float(np.max(np.abs(dev**2 / ours.avar - 1.0)))
    t_ours = best_of(lambda: avar(x, freq, taus="decade"))
    t_peer = best_of(lambda: allantools.oadev(x, rate=freq, data_type="freq", taus=ours.tau))
    print(f"\n{ours.tau.size} decade-grid taus, largest relative difference of the variances "
          f"{rel:.1e}")
    print(f"stochmod avar (overlapping, with EDF intervals): {t_ours * 1e3:8.1f} ms")
    print(f"allantools.oadev:                               {t_peer * 1e3:8.1f} ms")
    print(f"ratio allantools / stochmod: {t_peer / t_ours:.2f}x")


if __name__ == "__main__":
    main()
