"""Benchmark: automatic model selection vs allantools' octave Allan deviation, same data, same run.

Run: ``python bench/bench_select.py [N]`` (default N = 2,000,000 samples at 100 Hz). The
selection fits {GM+WN, 2*GM+WN, 3*GM+WN, GM+WN+RW, QN+WN+RW+RR} by the GMWM with one
weighting matrix (wavelet variance, its eq.-17 covariance and the WVIC included) on the default
executor (for 5 fits, a thread of this process beside eq. 17's); the peer computes only the
overlapping Allan deviation at octave averaging times (``allantools.oadev(taus="octave")``).
Times are the best of `repeat`.
"""

from __future__ import annotations

import sys

from _timing import best_of
from bench_gmwm import FREQ, simulated, time_oadev  # same signal and peer timing

from stochmod.fit.selection import select

CANDIDATES = ["GM+WN", "2*GM+WN", "3*GM+WN", "GM+WN+RW", "QN+WN+RW+RR"]


def main(n: int = 2_000_000, repeat: int = 2) -> None:
    x = simulated(n)
    res = select(x, FREQ, candidates=CANDIDATES, progress=False)
    t_sel = best_of(lambda: select(x, FREQ, candidates=CANDIDATES, progress=False), repeat)
    t_at = time_oadev(x, repeat)
    print(f"N = {n:,} samples at {FREQ:g} Hz, truth 2*GM+WN; {len(CANDIDATES)} candidates, "
          f"J = {res.best.levels} levels")
    for row in res.ranking:
        print(f"  {row.model:<12} objective {row.objective:10.4g}  wvic {row.criterion:10.4g}")
    print(f"selected: {res.best.model.name}")
    print(f"stochmod select (5 GMWM fits + WV + V)   {t_sel:8.2f} s")
    print(f"allantools oadev(taus='octave')          {t_at:8.2f} s")
    print(f"ratio select / oadev                     {t_sel / t_at:8.2f}")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:2]))
