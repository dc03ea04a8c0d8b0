"""A simulated redundant gyro array with known truth (Waegli et al. 2010, Section 6 and Table 4).

Four gyros around one known angular rate: sensor 1 three times noisier than the others,
sensor 2 biased, every sensor's noise level modulated in time, and sensor 0 perturbed as in
eq. 13, ``+ sin(6 pi t / t_max) W`` with ``W ~ a N(0, var[noise_0])``. Used by the tests and the
worked example of docs/redundant_imu.md to report each combiner's error against the truth.
"""

from __future__ import annotations

import numpy as np

from stochmod.core.checks import check_positive_int

__all__ = ["redundant_gyros"]


def redundant_gyros(a: float, length: int = 20_000, seed: int = 13, freq: float = 100.0
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Four gyros (rad/s) and the true rate.

    Parameters
    ----------
    a : float
        Perturbation constant of eq. 13 (the seed uses 0, 5 and 10).
    length : int
        Samples per sensor.
    seed : int
        Seed of the noise.
    freq : float
        Sampling frequency, Hz.

    Returns
    -------
    x : ndarray, shape (4, length)
        The sensors' readings, rad/s.
    truth : ndarray, shape (length,)
        The true rate ``0.5 sin(2 pi 0.05 t)``, rad/s.
    """
    length = check_positive_int(length, name="length", minimum=2)
    rng = np.random.default_rng(seed)
    t = np.arange(length) / freq
    truth = 0.5 * np.sin(2 * np.pi * 0.05 * t)
    modulation = 1.0 + 0.5 * np.sin(2 * np.pi * t / t[-1] * 2.0)
    sigma = np.array([0.01, 0.03, 0.01, 0.01])
    bias = np.array([0.0, 0.0, 0.02, 0.0])
    noise = sigma[:, None] * modulation * rng.standard_normal((4, length))
    x = truth + bias[:, None] + noise
    x[0] += np.sin(6 * np.pi * t / t[-1]) * a * np.std(noise[0]) * rng.standard_normal(length)
    return x, truth
