"""Study: the cap on the first (flattened, eq. 34) stage of the GMWM multi-start search.

Fits the same seeded wavelet variances with the capped first stage
(``stochmod.fit.engine.STAGE1_TOLERANCE``, tolerance 1e-8, at most 100 evaluations) and with
the refinement's own settings (1e-12, 2000 evaluations), and prints, per model, how often the
capped search ends at a worse objective (relative 1e-6) and the time of each variant.
The numbers quoted in docs/gmwm.md ("Starting values and multi-start") come from this script.

Run: ``python studies/search_stage1.py``.
"""

from __future__ import annotations

import time

import stochmod
import stochmod.fit.engine as engine

FREQ = 100.0
UNCAPPED = (1e-12, 2000)
CASES = {  # model to fit: (truth, samples)
    "2*GM+WN": ("GM(beta=5.0, sigma2=1e-6) + GM(beta=0.01, sigma2=4e-6) + WN(sigma2=1e-4)", 2**16),
    "GM+WN+RW": ("GM(beta=0.1, sigma2=1e-6) + WN(sigma2=1e-4) + RW(sigma2=1e-11)", 2**16),
    "QN+WN+RW+RR": ("QN(Q2=1e-7) + WN(sigma2=3e-6) + RW(sigma2=1e-12) + RR(omega=1e-8)", 2**16),
    "3*GM+WN": ("GM(beta=20.0, sigma2=1.0) + GM(beta=1.0, sigma2=0.3) + GM(beta=0.02, sigma2=0.1)"
                " + WN(sigma2=1.0)", 2**16),
    "AR(2)+WN": ({"processes": [{"family": "AR", "params": {"phi": [1.949, -0.94905], "sigma2": 1e-10}},
                                {"family": "WN", "params": {"sigma2": 3e-6}}]}, 2**17),
}


def main(seeds: int = 4) -> None:
    capped = engine.STAGE1_TOLERANCE
    print(f"{'model':<12} {'fits':>4} {'worse':>5} {'capped s':>9} {'uncapped s':>10}")
    try:
        for name, (truth, n) in CASES.items():
            model = stochmod.model_from_spec(truth, FREQ)
            worse, seconds = 0, {capped: 0.0, UNCAPPED: 0.0}
            for seed in range(seeds):
                wv = stochmod.wvar(model.simulate(n, rng=seed), FREQ)
                objective = {}
                for setting in (UNCAPPED, capped):
                    engine.STAGE1_TOLERANCE = setting
                    start = time.perf_counter()
                    objective[setting] = stochmod.gmwm(wv, name, FREQ, rng=seed).objective
                    seconds[setting] += time.perf_counter() - start
                worse += objective[capped] > objective[UNCAPPED] * (1 + 1e-6)
            print(f"{name:<12} {seeds:>4} {worse:>5} {seconds[capped]:>9.1f} {seconds[UNCAPPED]:>10.1f}")
    finally:
        engine.STAGE1_TOLERANCE = capped


if __name__ == "__main__":
    main()
