"""Regenerate ``_OCTAVE_CORR`` of stochmod/empirical/allan_reading.py by seeded simulation.

The slope reading treats the ln Allan-variance estimates of a region as correlated, with
correlation ``floor + (1 - floor) r^d`` between averaging times d octaves apart
(``_ln_av_covariance``). This script measures that correlation for each noise of the IEEE 952
table: it simulates `reps` seeded records of `n` samples of the noise alone, computes the
overlapping Allan variance at the octave taus m = 1, 2, 4, ... (up to n / 64, where the
estimates are still close to normal in log), and averages the correlation of ln AV across the
records over the pairs of taus d octaves apart. r is the correlation one octave apart; the
floor (quantization only: its AV at every tau is driven by the same uniform draws) is the
mean correlation at d >= 2, and then ``r = max((c_1 - floor) / (1 - floor), 0)`` (for
quantization the adjacent octaves are *less* correlated than distant ones, 0.15 against 0.3:
r = 0, a constant correlation 0.3 at every distance). A rate ramp is
deterministic within a record (its AV has no sampling error of its own): the white noise
around it makes the error, so R takes N's value.

Run: ``python studies/octave_corr.py [--reps 400] [--n 65536] [--seed 2024]`` (about a minute).
Its output is the dictionary to paste, and the per-distance correlations behind it.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from stochmod.empirical.allan import avar

FS = 1.0


def _flicker(rng: np.random.Generator, n: int) -> np.ndarray:
    """Two-sided PSD 1 / (2 pi |f|) between 1/n and 1/2 (bias instability B = 1), by shaping."""
    spec = np.fft.rfft(rng.standard_normal(n))
    f = np.fft.rfftfreq(n, 1.0 / FS)
    gain = np.zeros_like(f)
    gain[1:] = 1.0 / np.sqrt(2.0 * np.pi * f[1:])
    return np.fft.irfft(spec * gain * math.sqrt(FS), n)


SIMULATORS = {
    "Q": lambda rng, n: math.sqrt(12.0) * np.diff(rng.random(n + 1)),
    "N": lambda rng, n: rng.standard_normal(n),
    "B": _flicker,
    "K": lambda rng, n: np.cumsum(rng.standard_normal(n)),
}


def octave_correlations(name: str, reps: int, n: int, seed: int) -> np.ndarray:
    """Mean correlation of ln AV at octave distance d = 1, 2, ... (index d - 1)."""
    rng = np.random.default_rng([seed, ord(name)])
    m = 2 ** np.arange(int(math.log2(n // 64)) + 1)
    logs = np.array([np.log(avar(SIMULATORS[name](rng, n), FS, taus=m / FS).avar)
                     for _ in range(reps)])
    corr = np.corrcoef(logs, rowvar=False)
    k = m.size
    return np.array([np.mean(np.diagonal(corr, offset=d)) for d in range(1, k)])


def fit(c: np.ndarray, with_floor: bool) -> tuple[float, float]:
    """(r, floor) of ``floor + (1 - floor) r^d`` from the correlations by distance: r is the
    correlation one octave apart above the floor (clipped at 0: a negative r would make the
    kernel indefinite), the floor the mean correlation at d >= 2."""
    floor = float(np.mean(c[1:])) if with_floor else 0.0
    return max((float(c[0]) - floor) / (1.0 - floor), 0.0), floor


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reps", type=int, default=400)
    parser.add_argument("--n", type=int, default=2**16)
    parser.add_argument("--seed", type=int, default=2024)
    args = parser.parse_args()
    table = {}
    for name in SIMULATORS:
        c = octave_correlations(name, args.reps, args.n, args.seed)
        r, floor = fit(c, with_floor=name == "Q")
        table[name] = (round(r, 2), round(floor, 2))
        print(f"{name}: correlation by octave distance d = 1.. : "
              + " ".join(f"{v:.3f}" for v in c) + f"  ->  r = {r:.3f}, floor = {floor:.3f}")
    table["R"] = table["N"]
    print("_OCTAVE_CORR =", {k: table[k] for k in ("Q", "N", "B", "K", "R")})


if __name__ == "__main__":
    main()
