"""Optional compiled pass (numba) for the eq. 17 covariance: the power spectrum of a real series
from the complex transform of its sample pairs.

A real series ``x`` of even length ``N``, read as the ``N/2`` complex numbers
``z_m = x_{2m} + i x_{2m+1}``, has the discrete Fourier transform

    X_k = E_k + w^k O_k,    E_k = (Z_k + conj Z_{N/2-k}) / 2,    O_k = (Z_k - conj Z_{N/2-k}) / 2i,

with ``Z`` the transform of ``z`` (indices modulo ``N/2``) and ``w = exp(-2 pi i / N)``: ``E`` and
``O`` are the transforms of the even and odd samples (the classical split of a real FFT into a
complex one of half the length; Press et al., Numerical Recipes, 2nd ed., sec. 12.3). pocketfft's
complex transform of ``N/2`` points takes about 60 % of its real transform of ``N`` points, and
one compiled pass then forms ``|X_k|^2``, ``k = 0 .. N/2``, reading ``Z`` twice and writing the
powers once; numpy would need about eight passes for the same (so without numba,
:mod:`stochmod.signal.wv_covariance` keeps scipy's real transform).

Without numba (or with ``STOCHMOD_DISABLE_JIT=1``) :data:`stochmod.signal.haar_jit.AVAILABLE`
is False and nothing here is used.
"""

from __future__ import annotations

import functools

import numpy as np

from stochmod.signal.haar_jit import compiled

__all__ = ["half_spectrum_power", "twiddles"]


@functools.lru_cache(maxsize=2)
def twiddles(nfft: int) -> np.ndarray:
    """``(cos, sin)`` of ``2 pi k / nfft`` for ``k = 0 .. nfft/2``, shape ``(nfft/2 + 1, 2)``,
    float32 (the precision of the transforms they combine). Cached: every level of a signal
    shares them."""
    angle = (2.0 * np.pi / nfft) * np.arange(nfft // 2 + 1)
    return np.stack([np.cos(angle), np.sin(angle)], axis=1).astype(np.float32)


@compiled
def half_spectrum_power(z: np.ndarray, table: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover
    """``out[k] = |X_k|^2`` for ``k = 0 .. H`` from ``z``, the complex transform (length ``H``)
    of a real series' sample pairs, and ``table = twiddles(2 H)``; in double precision, stored
    in `out`'s precision."""
    h = z.size
    for k in range(h + 1):
        a = z[k] if k < h else z[0]
        b = z[h - k] if k > 0 else z[0]
        ar = np.float64(a.real)
        ai = np.float64(a.imag)
        br = np.float64(b.real)
        bi = -np.float64(b.imag)  # conj Z_{H-k}
        er = 0.5 * (ar + br)
        ei = 0.5 * (ai + bi)
        o_r = 0.5 * (ai - bi)
        o_i = -0.5 * (ar - br)
        c = np.float64(table[k, 0])
        s = np.float64(table[k, 1])
        xr = er + c * o_r + s * o_i
        xi = ei + c * o_i - s * o_r
        out[k] = xr * xr + xi * xi
