"""Monte Carlo: the size of the J-test on a GMWM fit of pooled replicates.

Run: ``python studies/mc_pooled_jtest.py [PAIRS [N [CASE]]]`` (defaults 100 pairs of 2^15
samples, both cases). Each pair is two replicates simulated from one GM + WN model at 100 Hz
(case "fast": the model of tests/test_pooled.py; case "slow": a slow GM whose WV still rises at
the deep levels, where the pooled WV has twice the coefficients of each replicate) and fitted
by ``stochmod.gmwm([x1, x2], "GM+WN", 100)``: the true structure, so the J-test's p-value is
uniform under its null and the share of p < alpha must match alpha within the binomial Monte
Carlo error ``sqrt(alpha (1 - alpha) / PAIRS)``. The same is printed for one replicate alone
(``stochmod.gmwm(x1, ...)``) as the reference. Seeded: the same numbers on every run.
"""

from __future__ import annotations

import math
import sys

import numpy as np

import stochmod

FREQ = 100.0
CASES = {"fast": "GM(beta=0.5, sigma2=1e-6) + WN(sigma2=1e-4)",
         "slow": "GM(beta=0.02, sigma2=4e-8) + WN(sigma2=1e-4)"}


def pvalues(true: str, pairs: int, n: int, seed: int = 2024
            ) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """J-test p-values of the pooled fits and of the first replicate's fits, and the dfs."""
    model = stochmod.model_from_spec(true, FREQ)
    pooled, single, dfs = [], [], []
    for k in range(pairs):
        xs = [model.simulate(n, rng=seed + 2 * k + i) for i in range(2)]
        fit = stochmod.gmwm(xs, "GM+WN", FREQ)
        one = stochmod.gmwm(xs[0], "GM+WN", FREQ)
        pooled.append(np.nan if fit.jtest is None else fit.jtest.pvalue)
        single.append(np.nan if one.jtest is None else one.jtest.pvalue)
        dfs.append(-1 if fit.jtest is None else fit.jtest.df)
    return np.array(pooled), np.array(single), dfs


def main(pairs: int = 100, n: int = 2**15, case: str | None = None) -> None:
    for name in CASES if case is None else [case]:
        true = CASES[name]
        pooled, single, dfs = pvalues(true, pairs, n)
        print(f"{pairs} replicate pairs of {n} samples from {true} at {FREQ:g} Hz, fitted GM+WN")
        print(f"J-test df of the pooled fits: {sorted(set(dfs))}")
        for alpha in (0.05, 0.01):
            mc = math.sqrt(alpha * (1 - alpha) / pairs)
            for label, p in (("pooled (2 replicates)", pooled), ("one replicate", single)):
                ok = p[np.isfinite(p)]
                print(f"{label:22s} share p < {alpha:<4g}: {np.mean(ok < alpha):.3f} "
                      f"(nominal {alpha}, Monte Carlo s.e. {mc:.3f}; {ok.size} tests)")
        print("smallest pooled p-values:", np.array2string(np.sort(pooled)[:5], precision=4))


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]), *sys.argv[3:4])
