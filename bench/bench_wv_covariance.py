"""Benchmark: the full asymptotic covariance of the wavelet variance (Stebler et al. 2014, eq. 17)
at every level, vs allantools' octave Allan deviation on the same data, in the same run.

Run: ``python bench/bench_wv_covariance.py [N]`` (default N = 2,000,000 samples at 100 Hz).
The paper calls eq. 17 infeasible for long signals (a direct evaluation sums J^2 cross-
correlations over all lags, O(J^2 N^2)); stochmod evaluates it by FFT in O(J N log N). Also
timed: the same covariance under a model (`model_covariance`, the J-test's V, O(J^2) PSD
evaluations). Times are the best of `repeat` runs.
"""

from __future__ import annotations

import sys

import numpy as np
from _timing import best_of
from bench_gmwm import FREQ, simulated, time_oadev

import stochmod
from stochmod.fit.weighting import model_covariance
from stochmod.signal.wv_covariance import wv_covariance


def main(n: int = 2_000_000, repeat: int = 3) -> None:
    x = simulated(n)
    emp = stochmod.wvar(x, FREQ)
    J = emp.wv.size
    V = wv_covariance(x, J)
    t_v = best_of(lambda: wv_covariance(x, J), repeat)
    model = stochmod.gmwm(emp, "2*GM+WN").model
    Vm = model_covariance(model, emp.n_coef)
    t_m = best_of(lambda: model_covariance(model, emp.n_coef), repeat)
    t_at = time_oadev(x, repeat)
    keep = emp.n_coef / 2.0**emp.levels >= 16
    ratio = np.diag(V)[keep] / np.diag(Vm)[keep]
    print(f"N = {n:,} samples at {FREQ:g} Hz, J = {J} levels (all)")
    print(f"eq. 17 / model variances on the {keep.sum()} levels with M_j/2^j >= 16: "
          f"{ratio.min():.3f} .. {ratio.max():.3f}")
    print(f"stochmod wv_covariance (eq. 17, J x J)        {t_v:8.3f} s")
    print(f"stochmod model_covariance (fitted 2*GM+WN)    {t_m:8.3f} s")
    print(f"allantools oadev(taus='octave')               {t_at:8.3f} s")
    print(f"ratio wv_covariance / oadev                   {t_v / t_at:8.2f}")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:2]))
