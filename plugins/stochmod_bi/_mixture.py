"""The unit flicker mixture behind BI: GM rates log-uniform over a band, plus the corner GM.

In rates per sample ``d = beta / freq`` the mixture has stationary variance density 1 per unit
of ``ln d`` on ``[d_lo, d_hi]`` with ``d_lo = 2 pi nu_c`` (``nu_c = fc / freq``) and
``d_hi = pi`` (a corner at the Nyquist frequency), plus one GM of variance 1 at ``d_lo``. When
``d_lo >= d_hi`` the band is empty and only the corner GM remains. BI scales all of it by
``B^2 / pi``. Every quantity is an integral over ``s = ln d`` of an AR(1) quantity, done by
composite Gauss-Legendre quadrature (the integrands are analytic in a strip of half-width
about pi/2 around the real s axis, so 12-point panels of width 1/2 reach rounding level).
The AR(1) Haar WV per unit variance is :func:`stochmod.core.geometric.haar_wv_geometric` at
``log z = -d`` (free of cancellation for slow components).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike
from scipy.special import exp1

from stochmod.sdk import haar_wv_geometric, haar_wv_geometric_dlog

__all__ = ["D_HI", "band", "mixture_nodes", "ar1_wv", "ar1_spectrum", "unit_wv", "unit_wv_d_lo",
           "unit_spectrum", "unit_autocovariance"]

#: Upper rate of the band, radians per sample: a corner at the Nyquist frequency.
D_HI = math.pi

_GL_X, _GL_W = np.polynomial.legendre.leggauss(12)
_PANEL = 0.5


def ar1_wv(d: ArrayLike, m: ArrayLike) -> np.ndarray:
    """Haar WV of a unit-variance AR(1) ``X_t = e^{-d} X_{t-1} + e_t`` at half-width `m`."""
    return haar_wv_geometric(-np.asarray(d, dtype=np.float64), m)


def ar1_spectrum(d: ArrayLike, theta: ArrayLike) -> np.ndarray:
    """Two-sided spectrum per cycle/sample of a unit-variance AR(1) at ``theta = 2 pi f / freq``.

    ``(1 - q^2) / |1 - q e^{-i theta}|^2`` with ``q = e^{-d}``, written
    ``u (1 + q) / (u^2 + 4 q sin^2(theta/2))`` with ``u = 1 - q``: stable for small and large
    ``d`` (its integral over a cycle is 1).
    """
    d, theta = np.broadcast_arrays(np.asarray(d, dtype=np.float64),
                                   np.asarray(theta, dtype=np.float64))
    u, q = -np.expm1(-d), np.exp(-d)
    return u * (1 + q) / (u * u + 4 * q * np.sin(0.5 * theta) ** 2)


def band(nu_c: float) -> tuple[float, float]:
    """``(d_lo, width)``: the corner rate ``2 pi nu_c`` and ``max(ln(d_hi / d_lo), 0)``."""
    d_lo = 2.0 * math.pi * nu_c
    return d_lo, max(math.log(D_HI / d_lo), 0.0)


def mixture_nodes(nu_c: float) -> tuple[np.ndarray, np.ndarray]:
    """Quadrature rates ``d`` and weights of the continuous part (empty when the band is)."""
    d_lo, width = band(nu_c)
    if width == 0.0:
        return np.zeros(0), np.zeros(0)
    panels = max(1, math.ceil(width / _PANEL))
    edges = math.log(d_lo) + width * np.arange(panels + 1) / panels
    half = 0.5 * (edges[1:] - edges[:-1])
    s = (edges[:-1] + half)[:, None] + half[:, None] * _GL_X[None, :]
    return np.exp(s).ravel(), (half[:, None] * _GL_W[None, :]).ravel()


def unit_wv(nu_c: float, levels: int) -> np.ndarray:
    """Haar WV of the unit mixture at levels 1..`levels`."""
    m = 2.0 ** np.arange(levels)[:, None]
    d, w = mixture_nodes(nu_c)
    d_lo = band(nu_c)[0]
    return ar1_wv(d[None, :], m) @ w + ar1_wv(d_lo, m[:, 0])


def unit_wv_d_lo(nu_c: float, levels: int) -> np.ndarray:
    """Derivative of :func:`unit_wv` with respect to the corner rate ``d_lo``.

    The lower limit of the band moves (``-wv_AR1(d_lo) / d_lo`` while the band is not empty)
    and the corner GM's rate moves (``d wv_AR1 / d d`` at ``d_lo``).
    """
    m = 2.0 ** np.arange(levels)
    d_lo, width = band(nu_c)
    edge = ar1_wv(d_lo, m) / d_lo if width > 0 else 0.0
    return -haar_wv_geometric_dlog(-d_lo, m) - edge


def unit_spectrum(nu: ArrayLike, nu_c: float, *, chunk: int = 4096) -> np.ndarray:
    """Two-sided spectrum of the unit mixture per cycle/sample at ``nu = f / freq``."""
    nu = np.asarray(nu, dtype=np.float64)
    theta = 2.0 * math.pi * nu.reshape(-1)
    d, w = mixture_nodes(nu_c)
    d_lo = band(nu_c)[0]
    out = ar1_spectrum(d_lo, theta)
    for start in range(0, theta.size, chunk):
        part = theta[start : start + chunk, None]
        out[start : start + chunk] += ar1_spectrum(d[None, :], part) @ w
    return out.reshape(nu.shape)


def unit_autocovariance(lags: ArrayLike, nu_c: float) -> np.ndarray:
    """Autocovariance of the unit mixture at integer `lags` (samples).

    ``E1(d_lo t) - E1(d_hi t) + exp(-d_lo t)`` for ``t >= 1``, and ``ln(d_hi / d_lo) + 1`` at
    ``t = 0`` (E1 the exponential integral); ``exp(-d_lo t)`` alone when the band is empty.
    """
    lags = np.asarray(lags, dtype=np.float64)
    t = np.abs(lags.reshape(-1))
    d_lo, width = band(nu_c)
    out = np.exp(-d_lo * t)
    if width > 0:
        pos = t > 0
        out[~pos] += width
        out[pos] += exp1(d_lo * t[pos]) - exp1(D_HI * t[pos])
    return out.reshape(lags.shape)
