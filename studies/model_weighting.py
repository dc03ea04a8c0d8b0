"""How the weighting and the V of the intervals decide the GMWM's random walk.

WN(1e-4) + RW(1e-9) at 100 Hz, R seeded records (child r of 7000 + r) at 2^15, 2^16 and
2^17 samples, fitted with the diagonal and the model weighting. For each: the mean of the
RW estimate over the truth, the spread of its log against the plan's
(:func:`stochmod.fit.plan.interval_half_widths`), and the coverage of the 95 % intervals
with V from eq. 17 on the signal and with V from the fitted model at the estimate
(docs/gmwm_monte_carlo.md, "The weighting and the V of a random walk").

Run: ``python studies/model_weighting.py [--records R]`` (R = 300: about 40 s).
"""

from __future__ import annotations

import argparse

import numpy as np

import stochmod
from stochmod.fit.plan import interval_half_widths
from stochmod.fit.weighting import data_covariance

TRUTH = "WN(sigma2=1e-4) + RW(sigma2=1e-9)"
FREQ = 100.0
Z = 1.959963984540054


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--records", type=int, default=300)
    args = parser.parse_args()
    truth = stochmod.model_from_spec(TRUTH, FREQ)
    rw = truth.vector()[1]
    print("| N | weighting | mean RW / truth | spread / plan | cover, V eq. 17 | cover, V model |")
    print("|---|---|---|---|---|---|")
    for n in (2**15, 2**16, 2**17):
        planned = np.log1p(interval_half_widths(truth, n))[1] / Z
        for name in ("diagonal", "model"):
            est, data_v, model_v = [], 0, 0
            for r in range(args.records):
                fit = stochmod.gmwm(truth.simulate(n, rng=7000 + r), "WN+RW", FREQ,
                                    weighting=name)
                est.append(fit.model.vector()[1])
                eq17 = data_covariance(fit.signal, fit.empirical, fit.levels)
                on_data = fit.with_data_covariance(eq17).parameters()[1]
                on_model = fit.with_model_covariance().parameters()[1]
                data_v += on_data.low <= rw <= on_data.high
                model_v += on_model.low <= rw <= on_model.high
            est = np.asarray(est)
            print(f"| 2^{int(np.log2(n))} | {name} | {np.mean(est) / rw:.3f} | "
                  f"{np.std(np.log(est), ddof=1) / planned:.2f} | {data_v / args.records:.3f} | "
                  f"{model_v / args.records:.3f} |", flush=True)


if __name__ == "__main__":
    main()
