"""Benchmark: the GARCH-weighted synthetic IMU of 4 sensors x 3 axes x 1,000,000 samples.

Run: ``python bench/bench_combine.py [T [WORKERS]]`` (defaults 1,000,000 per axis, 2). Data: 4 gyro triads
(rad/s) around a known rate: one sensor three times noisier, one biased, every noise level
modulated in time, sensor 0 perturbed on x as eq. 13 with a = 5 (Waegli et al. 2010). The
timed call is ``stochmod.combine(x, "garch", workers=2)`` with its defaults (ARMA orders by AIC
on a prefix, GARCH grown until Engle's LM test passes: 12 ARMA + GARCH fits in 2 processes),
compared in the same run with the serial call (the same result: the largest relative
difference is printed) and the plain mean; goal under 30 s on the 2-core machine. Also prints each method's
error standard deviation against the simulated truth. The machine is shared: times are noisy, so
the CPU seconds of the serial run and of the workers are printed too (a loaded machine stretches
the wall time, not the work).
"""

from __future__ import annotations

import os
import resource
import sys
import time

import numpy as np

import stochmod


def simulate(length: int, seed: int = 4) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(length) / 100.0
    truth = np.stack([0.5 * np.sin(2 * np.pi * 0.05 * t + k) for k in range(3)], axis=-1)
    sigma = np.array([0.01, 0.03, 0.01, 0.01])
    bias = np.array([0.0, 0.0, 0.02, 0.0])
    modulation = (1.0 + 0.5 * np.sin(2 * np.pi * t / t[-1] * 2.0))[:, None]
    x = np.empty((4, length, 3))
    for i in range(4):
        x[i] = truth + bias[i] + sigma[i] * modulation * rng.standard_normal((length, 3))
    x[0, :, 0] += np.sin(6 * np.pi * t / t[-1]) * 5 * sigma[0] * rng.standard_normal(length)
    return x, truth


def _children_cpu() -> float:
    """CPU seconds (user + system) of the finished child processes (the pool's workers)."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def main(length: int = 1_000_000, workers: int = 2) -> None:
    x, truth = simulate(length)
    t0 = time.perf_counter()
    mean = stochmod.combine(x, "mean")
    t_mean = time.perf_counter() - t0
    t0, c0 = time.perf_counter(), _children_cpu()
    garch = stochmod.combine(x, "garch", workers=workers)
    t_par, c_par = time.perf_counter() - t0, _children_cpu() - c0
    t0, c0 = time.perf_counter(), time.process_time()
    serial = stochmod.combine(x, "garch")
    t_ser, c_ser = time.perf_counter() - t0, time.process_time() - c0
    diff = max(float(np.max(np.abs(getattr(garch, f) - getattr(serial, f)) / np.abs(getattr(serial, f))))
               for f in ("signal", "weights", "variance"))
    print(f"4 sensors x 3 axes x {length:,} samples (12 ARMA + GARCH fits); load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print(f"stochmod.combine(x, 'garch', workers={workers})  {t_par:7.2f} s wall, {c_par:7.2f} s CPU "
          "in the workers   (goal < 30 s wall)")
    print(f"stochmod.combine(x, 'garch')             {t_ser:7.2f} s wall, {c_ser:7.2f} s CPU   "
          f"(serial / {workers} workers: {t_ser / t_par:.2f} x; largest relative difference {diff:.1e})")
    print(f"stochmod.combine(x, 'mean')              {t_mean:7.2f} s")
    print(f"orders: {garch.info['orders']}")
    for name, res in (("mean", mean), ("garch", garch)):
        err = np.std(res.signal - truth, axis=0)
        print(f"{name:6s} error std per axis [rad/s]: {np.array2string(err, precision=5)}")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]))
