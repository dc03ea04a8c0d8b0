"""Benchmark: stochmod GARCH(1,1) maximum likelihood vs the arch package on the same data.

Run: ``python bench/bench_garch.py [N]`` (default N = 1,000,000). Data: a zero-mean GARCH(1,1)
at the seed's Table 2 scale (alpha0 1.3e-7 rad^2/s^2, alpha1 0.0175, beta1 0.98; Waegli et al.
2010), simulated from eq. 7. Both fit the data as given (arch with ``rescale=False``) and, for
arch, also rescaled to unit variance by hand. Times are the best of 2 runs in the same process
(the machine is shared: ratios, not absolute times, are the figure); the log-likelihoods are in
nats on the data's scale (arch's rescaled fit is mapped back by ``- N log(scale)``). Goal:
stochmod faster, with a log-likelihood at least as high.
"""

from __future__ import annotations

import math
import sys
import warnings

import numpy as np

from stochmod.fit.garch import fit_garch, garch_loglikelihood
from _timing import best_of

TRUTH = (1.3e-7, 0.0175, 0.98)


def simulate(n: int, seed: int = 2010, burn: int = 5000) -> np.ndarray:
    """Eq. 7 by a plain loop (Table 2 parameters)."""
    omega, alpha, beta = TRUTH
    z = np.random.default_rng(seed).standard_normal(n + burn)
    out = np.empty(n + burn)
    s2 = omega / (1 - alpha - beta)
    for t in range(n + burn):
        out[t] = math.sqrt(s2) * z[t]
        s2 = omega + alpha * out[t] * out[t] + beta * s2
    return out[burn:]


def main(n: int = 1_000_000) -> None:
    from arch import arch_model

    x = simulate(n)
    scale = float(np.std(x))
    ll_truth = garch_loglikelihood(x, *TRUTH[:1], [TRUTH[1]], [TRUTH[2]])
    fits: dict[str, object] = {}

    def ours() -> None:
        fits["ours"] = fit_garch(x)

    def arch_raw() -> None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            fits["raw"] = arch_model(x, mean="Zero", vol="GARCH", p=1, q=1, rescale=False).fit(disp="off")

    def arch_scaled() -> None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            fits["scaled"] = arch_model(x / scale, mean="Zero", vol="GARCH", p=1, q=1,
                                        rescale=False).fit(disp="off")

    t_ours = best_of(ours, repeat=2)
    t_raw = best_of(arch_raw, repeat=2)
    t_scaled = best_of(arch_scaled, repeat=2)
    g, raw, sc = fits["ours"], fits["raw"], fits["scaled"]
    ll_scaled = sc.loglikelihood - n * math.log(scale)
    print(f"N = {n:,}, GARCH(1,1) truth alpha0 {TRUTH[0]:.2g}, alpha1 {TRUTH[1]}, beta1 {TRUTH[2]}; "
          f"loglik at the truth {ll_truth:.3f}")
    print(f"{'fit':28s} {'time [s]':>9s} {'alpha1':>8s} {'beta1':>8s} {'loglik - truth [nats]':>22s}")
    print(f"{'stochmod fit_garch':28s} {t_ours:9.2f} {g.alpha[0]:8.4f} {g.beta[0]:8.4f} "
          f"{g.loglikelihood - ll_truth:22.3f}")
    print(f"{'arch, data as given':28s} {t_raw:9.2f} {raw.params['alpha[1]']:8.4f} "
          f"{raw.params['beta[1]']:8.4f} {raw.loglikelihood - ll_truth:22.3f}")
    print(f"{'arch, rescaled by hand':28s} {t_scaled:9.2f} {sc.params['alpha[1]']:8.4f} "
          f"{sc.params['beta[1]']:8.4f} {ll_scaled - ll_truth:22.3f}")
    print(f"ratio arch (rescaled) / stochmod time   {t_scaled / t_ours:6.2f} x   (goal > 1)")
    print(f"ratio arch (as given) / stochmod time   {t_raw / t_ours:6.2f} x")
    print(f"stochmod loglik - best arch loglik      {g.loglikelihood - max(raw.loglikelihood, ll_scaled):.3f} "
          "nats (goal >= 0)")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 1_000_000)
