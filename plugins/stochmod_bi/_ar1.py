"""Numerically stable Haar wavelet variance and spectrum of a unit-variance AR(1) (sampled GM).

The bias-instability family is a superposition of Gauss-Markov processes; sampled at ``freq``
each one is an AR(1) ``X_t = q X_{t-1} + e_t`` with ``q = exp(-d)``, ``d = beta / freq`` (the
rate in radians per sample) and stationary variance 1. These helpers give its Haar WV at
half-width ``m`` (level ``j = log2(m) + 1``), the derivative in ``d``, and its spectrum, to
about 1e-12 relative accuracy for every ``d > 0`` and ``m >= 1``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["ar1_haar_wv", "ar1_haar_wv_dd", "ar1_spectrum"]

#: Below this value of ``x = m d`` the closed form cancels; the Taylor series in d is used.
_SWITCH = 0.05

# Taylor coefficients of the Haar WV in d: wv = sum_k d^k sum_p c[k][p] m^p (p = -1 means 1/m).
# Derived from 4 W(m) - W(2m), W(n) = 2 sum_{t<n} (n - t)(q^t - 1), with Faulhaber sums
# (sympy); the truncation error at x = 0.05 is below 1e-12 relative (tests/test_family_bi.py
# checks the whole function against an exact brute-force sum in mpmath).
_SERIES: tuple[dict[int, float], ...] = (
    {1: 1 / 3, -1: 1 / 6},
    {2: -1 / 4},
    {3: 7 / 60, 1: -1 / 36, -1: -1 / 180},
    {4: -1 / 24, 2: 1 / 48},
    {5: 31 / 2520, 3: -7 / 720, 1: 1 / 720, -1: 1 / 5040},
    {6: -1 / 320, 4: 1 / 288, 2: -1 / 960},
    {7: 127 / 181440, 5: -31 / 30240, 3: 7 / 14400, 1: -1 / 18144, -1: -1 / 151200},
)


def _series_coefficients(m: np.ndarray) -> list[np.ndarray]:
    return [sum(c * m**p for p, c in coefs.items()) for coefs in _SERIES]


def _closed_parts(d: np.ndarray, m: np.ndarray) -> tuple[np.ndarray, ...]:
    """``u = 1 - q``, ``q``, ``v = 1 - q^m``, ``q^m`` (each computed directly, no cancellation)
    and the numerator of the closed form."""
    u, q = -np.expm1(-d), np.exp(-d)
    v, qm = -np.expm1(-m * d), np.exp(-m * d)
    numerator = 2 * m * u * (1 + q) - 2 * q * v * (2 + v)
    return u, q, v, qm, numerator


def _split(d: ArrayLike, m: ArrayLike, closed: Callable[..., np.ndarray],
           series: Callable[[np.ndarray, list[np.ndarray]], np.ndarray]) -> np.ndarray:
    """Broadcast `d` and `m`; the closed form where ``m d >= 0.05``, the series below."""
    d, m = np.broadcast_arrays(np.asarray(d, dtype=np.float64), np.asarray(m, dtype=np.float64))
    small = m * d < _SWITCH
    out = np.empty(d.shape)
    if np.any(~small):
        out[~small] = closed(*_closed_parts(d[~small], m[~small]), m[~small])
    if np.any(small):
        out[small] = series(d[small], _series_coefficients(m[small]))
    return out


def ar1_haar_wv(d: ArrayLike, m: ArrayLike) -> np.ndarray:
    """Haar WV of a unit-variance AR(1) with ``q = exp(-d)`` at half-width `m` (broadcast).

    Closed form ``(4 V(m) - V(2m)) / (4 m^2)`` with ``V(n)`` the variance of a sum of n
    samples, written in ``u = 1 - q``, ``v = 1 - q^m``::

        wv = [2 m u (1 + q) - 2 q v (2 + v)] / (4 m^2 u^2)

    and its Taylor series in ``d`` where ``m d < 0.05`` (the closed form cancels there).
    """
    return _split(d, m, lambda u, q, v, qm, num, m: num / (4 * m * m * u * u),
                  lambda d, coefs: sum(c * d ** (k + 1) for k, c in enumerate(coefs)))


def ar1_haar_wv_dd(d: ArrayLike, m: ArrayLike) -> np.ndarray:
    """Derivative of :func:`ar1_haar_wv` with respect to ``d`` (same stable split)."""

    def closed(u: np.ndarray, q: np.ndarray, v: np.ndarray, qm: np.ndarray, num: np.ndarray,
               m: np.ndarray) -> np.ndarray:
        dnum = 4 * m * q * q + 2 * q * v * (2 + v) - 4 * m * q * qm * (1 + v)
        return (dnum * u - 2 * num * q) / (4 * m * m * u**3)

    return _split(d, m, closed,
                  lambda d, coefs: sum((k + 1) * c * d**k for k, c in enumerate(coefs)))


def ar1_spectrum(d: ArrayLike, theta: ArrayLike) -> np.ndarray:
    """Two-sided spectrum per cycle/sample of a unit-variance AR(1) at ``theta = 2 pi f / freq``.

    ``(1 - q^2) / |1 - q e^{-i theta}|^2``, written ``u (1 + q) / (u^2 + 4 q sin^2(theta/2))``
    with ``u = 1 - q``: stable for small and large ``d`` (its integral over a cycle is 1).
    """
    d, theta = np.broadcast_arrays(np.asarray(d, dtype=np.float64),
                                   np.asarray(theta, dtype=np.float64))
    u, q = -np.expm1(-d), np.exp(-d)
    return u * (1 + q) / (u * u + 4 * q * np.sin(0.5 * theta) ** 2)
