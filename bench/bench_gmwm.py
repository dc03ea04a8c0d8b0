"""Benchmark: one GMWM fit (2*GM+WN, wavelet variance included) vs allantools' octave Allan
deviation on the same data, in the same run.

Run: ``python bench/bench_gmwm.py [N]`` (default N = 2,000,000 samples at 100 Hz). stochmod
computes the Haar wavelet variance at every level and fits the model (multi-start); the peer
only computes ``allantools.oadev(taus="octave")``. Times are the best of `repeat` runs: wall
clock (the ratio the issue states), then CPU time of this process (``time.process_time``,
less disturbed by other jobs on a shared machine).
"""

from __future__ import annotations

import sys
import time

import allantools
import numpy as np
from _timing import best_of

import stochmod
from stochmod.fit.gmwm import gmwm

FREQ = 100.0


def simulated(n: int) -> np.ndarray:
    """The benchmark signal: N samples of GM(5/s, 1e-6) + GM(0.01/s, 4e-6) + WN(1e-4), seeded."""
    truth = stochmod.model_from_spec(
        "GM(beta=5.0, sigma2=1e-6) + GM(beta=0.01, sigma2=4e-6) + WN(sigma2=1e-4)", FREQ)
    return truth.simulate(n, rng=20240601)


def time_oadev(x: np.ndarray, repeat: int) -> float:
    """Best time of the peer, allantools' overlapping Allan deviation at octave taus."""
    return best_of(lambda: allantools.oadev(x, rate=FREQ, data_type="freq", taus="octave"), repeat)


def main(n: int = 2_000_000, repeat: int = 5) -> None:
    x = simulated(n)
    fit = gmwm(x, "2*GM+WN", FREQ)
    t_fit = best_of(lambda: gmwm(x, "2*GM+WN", FREQ), repeat)
    t_at = time_oadev(x, repeat)
    c_fit = best_of(lambda: gmwm(x, "2*GM+WN", FREQ), repeat, clock=time.process_time)
    c_at = best_of(lambda: allantools.oadev(x, rate=FREQ, data_type="freq", taus="octave"), repeat,
                   clock=time.process_time)
    gm1, gm2, wn = fit.model.processes
    print(f"N = {n:,} samples at {FREQ:g} Hz; truth GM(5/s, 1e-6) + GM(0.01/s, 4e-6) + WN(1e-4)")
    print(f"fit: GM({gm1.beta:.3g}/s, {gm1.sigma2:.3g}) + GM({gm2.beta:.3g}/s, {gm2.sigma2:.3g}) "
          f"+ WN({wn.sigma2:.3g}); J = {fit.levels}, {fit.n_starts} local searches")
    print(f"stochmod gmwm 2*GM+WN (WV included)   {t_fit:8.3f} s")
    print(f"allantools oadev(taus='octave')        {t_at:8.3f} s")
    print(f"ratio gmwm / oadev                     {t_fit / t_at:8.2f}")
    print(f"CPU: gmwm {c_fit:.3f} s, oadev {c_at:.3f} s, ratio {c_fit / c_at:.2f}")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:2]))
