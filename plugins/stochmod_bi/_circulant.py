"""Exact simulation of a stationary Gaussian series from its autocovariance (circulant embedding).

Davies & Harte (1987); Dietrich & Newsam (1997). The autocovariance up to lag ``M/2`` is
wrapped into a circulant of size ``M >= 2 (n - 1)`` whose eigenvalues (one FFT) must be
non-negative; the series is then the real part of an FFT of scaled complex normals, exact in
distribution, in O(M log M).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy import fft

from stochmod.sdk import EstimationError

__all__ = ["circulant_embedding"]

#: Relative size of negative embedding eigenvalues put down to rounding and set to zero.
EIGEN_TOL = 1e-10


def circulant_embedding(acvf: Callable[[np.ndarray], np.ndarray], n: int,
                        rng: np.random.Generator) -> np.ndarray:
    """Draw `n` samples of the zero-mean stationary Gaussian series with autocovariance `acvf`.

    Parameters
    ----------
    acvf : callable
        ``acvf(lags) -> autocovariance`` at integer lags (samples), unit^2.
    n : int
        Number of samples (>= 1).
    rng : numpy.random.Generator
        Source of the normal draws.

    Returns
    -------
    ndarray (n,)

    Raises
    ------
    EstimationError
        If the embedding has a clearly negative eigenvalue (not the case for autocovariances
        that are non-negative, decreasing and convex, such as mixtures of exponentials:
        Craigmile 2003, Gneiting 2000).

    Notes
    -----
    ``M = 2 * next_fast_len(n - 1)`` so the FFTs stay fast for any `n`; embedding a longer
    series than needed is still exact.
    """
    if n == 1:
        return np.sqrt(float(acvf(np.zeros(1))[0])) * rng.standard_normal(1)
    half = fft.next_fast_len(n - 1)
    gamma = np.asarray(acvf(np.arange(half + 1)), dtype=np.float64)
    row = np.concatenate([gamma, gamma[-2:0:-1]])
    size = row.size  # 2 * half
    eig = fft.rfft(row).real
    top = float(np.max(eig))
    low = float(np.min(eig))
    if low < -EIGEN_TOL * top:
        raise EstimationError(
            f"circulant embedding of the autocovariance has a negative eigenvalue ({low:.3g}, "
            f"largest {top:.3g}): this process cannot be simulated exactly this way"
        )
    eig = np.clip(eig, 0.0, None)
    full = np.concatenate([eig, eig[-2:0:-1]])
    z = rng.standard_normal(size) + 1j * rng.standard_normal(size)
    return fft.fft(np.sqrt(full / size) * z)[:n].real.copy()
