"""Asymptotic covariance of the empirical wavelet variance (Stebler et al. 2014, eq. 17), by FFT.

For levels m and l, eq. 17 sums the squared sample cross-covariances of the two wavelet
coefficient series over all lags. With every level's interior coefficients placed at their
time indices in a zero-padded buffer of length >= 2N, the cross-correlation sequence is a
product of discrete Fourier transforms, and by Parseval its sum of squares is
``sum_f |X_m(f)|^2 |X_l(f)|^2 / nfft``: one FFT per level and one dot product per pair,
O(J N log N) in all, where the paper found the direct sum infeasible for long signals.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from scipy import fft

from stochmod._validation import as_signal
from stochmod.signal.modwt import filter_width, iter_modwt

__all__ = ["wv_covariance"]


def wv_covariance(x: ArrayLike, levels: int | None = None, wavelet: str = "haar", *,
                  clip: ArrayLike | None = None) -> np.ndarray:
    """Covariance matrix of the empirical wavelet variances at levels 1..J, unit^4.

    ``Cov(v_m, v_l) = (1 / M_ml) sum_tau c_ml(tau)^2`` with ``c_ml(tau) = (1/M_ml) sum_k
    W_{m,k} W_{l,k+tau}`` over the common interior indices (``M_ml = min(M_m, M_l)``), the
    Gaussian asymptotic form of eqs. 10-11 and 17.

    Parameters
    ----------
    x : array_like, shape (N,)
        The signal.
    levels : int, optional
        Number of levels J (default: all the signal allows).
    wavelet : str
        Orthogonal pywt wavelet (Haar by default).
    clip : array_like, shape (J,), optional
        Per-level bounds (unit u): level j's coefficients are clipped to ``+-clip[j-1]``
        first, so that a few outliers do not dominate the sums (the robust wavelet variance
        uses ``c sqrt(nu_j)``).

    Returns
    -------
    ndarray, shape (J, J)
        Symmetric covariance of the estimator ``v_hat``, already divided by the sample sizes.
    """
    x = as_signal(x, name="x", min_length=2)
    n = x.size
    nfft = fft.next_fast_len(2 * n, real=True)
    weights = np.full(nfft // 2 + 1, 2.0)
    weights[0] = 1.0
    if nfft % 2 == 0:
        weights[-1] = 1.0
    powers: list[np.ndarray] = []
    sizes: list[int] = []
    # single-precision transforms (relative error ~1e-6, far below the estimator's own
    # sampling error of order 1/sqrt(M_j)) halve the time and memory; sums are in float64
    buf = np.zeros(nfft, dtype=np.float32)
    bounds = None if clip is None else np.asarray(clip, dtype=np.float64)
    for j, coef in iter_modwt(x, levels, wavelet):
        if bounds is not None:
            np.clip(coef, -bounds[j - 1], bounds[j - 1], out=coef)
        start = filter_width(j, wavelet) - 1
        buf[:] = 0.0
        buf[start : start + coef.size] = coef
        spec = fft.rfft(buf)
        powers.append(spec.real**2 + spec.imag**2)
        sizes.append(coef.size)
    J = len(powers)
    V = np.empty((J, J))
    weights = weights.astype(np.float32)
    for a in range(J):
        wa = weights * powers[a]
        for b in range(a, J):
            M = min(sizes[a], sizes[b])
            s = float(np.einsum("i,i->", wa, powers[b], dtype=np.float64)) / nfft / M**2
            V[a, b] = V[b, a] = s / M
    return V
