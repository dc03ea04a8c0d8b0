"""Benchmark: stochmod Burg / Yule-Walker AR fits vs statsmodels on the same data.

Run: ``python bench/bench_ar.py [N]`` (default N = 2,520,000: seven hours at 100 Hz, as in
Quinchia et al. 2013). Times are the best of 5 runs each, in the same process; the ratio is
statsmodels time / stochmod time (goal for Burg AR(3): >= 1). Also prints the largest
coefficient difference, to show both compute the same estimate.
"""

from __future__ import annotations

import sys
import warnings

import numpy as np
from scipy.signal import lfilter
from statsmodels.regression.linear_model import burg as sm_burg
from statsmodels.regression.linear_model import yule_walker as sm_yule_walker

from stochmod.empirical.ar_fit import burg, fit_ar, yule_walker
from _timing import best_of


def main(n: int = 2_520_000) -> None:
    rng = np.random.default_rng(20240602)
    # AR(3) of Quinchia Table 2 (Acc Y: alpha = -2.564, 2.136, -0.572) plus white noise
    x = lfilter([1.0], [1.0, -2.564, 2.136, -0.572], rng.standard_normal(n))
    x += rng.standard_normal(n) * 10.0

    diff = np.max(np.abs(burg(x, 3)[0] - sm_burg(x, 3)[0]))
    t_ours = best_of(lambda: burg(x, 3))
    t_sm = best_of(lambda: sm_burg(x, 3))
    print(f"N = {n:,} samples, AR(3); max |phi difference| burg vs statsmodels {diff:.1e}")
    print(f"stochmod burg(x, 3)                 {t_ours * 1e3:8.1f} ms")
    print(f"statsmodels burg(x, 3)              {t_sm * 1e3:8.1f} ms")
    print(f"ratio statsmodels / stochmod        {t_sm / t_ours:8.2f} x   (goal >= 1)")

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t_yw_sm = best_of(lambda: sm_yule_walker(x, 3, method="mle"))
    t_yw = best_of(lambda: yule_walker(x, 3, method="mle"))
    print(f"stochmod yule_walker(x, 3)          {t_yw * 1e3:8.1f} ms")
    print(f"statsmodels yule_walker(x, 3)       {t_yw_sm * 1e3:8.1f} ms")
    print(f"ratio statsmodels / stochmod        {t_yw_sm / t_yw:8.2f} x")

    t_sel = best_of(lambda: fit_ar(x, 100.0, max_order=10), repeat=3)
    print(f"stochmod fit_ar order 1..10 by BIC  {t_sel * 1e3:8.1f} ms (one Burg pass, all orders)")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 2_520_000)
