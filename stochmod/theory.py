"""Generic theoretical wavelet variances: from an autocovariance, from a PSD, or by simulation.

These are the fallbacks of :class:`stochmod.process.Process` for families that do not declare
an analytic wavelet variance. Levels follow the project convention: at level ``j`` the Haar
filter has width ``2^j`` and averages ``m = 2^(j-1)`` samples per half.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from stochmod.signal.modwt import filter_width, squared_gain

__all__ = [
    "haar_kernel",
    "wv_from_autocovariance",
    "wv_from_psd",
]


def haar_kernel(m: int) -> np.ndarray:
    """Autocorrelation ``a(t) = sum_l h_l h_{l+t}`` of the Haar MODWT filter of half-width `m`, t = 0..2m-1.

    ``a(t) = (2m - 3t) / (4 m^2)`` for ``0 <= t <= m`` and ``-(2m - t) / (4 m^2)`` for
    ``m <= t < 2m``; the wavelet variance is ``a(0) g(0) + 2 sum_{t>0} a(t) g(t)``.
    """
    t = np.arange(2 * m, dtype=np.float64)
    a = np.where(t <= m, 2 * m - 3 * t, -(2 * m - t))
    return a / (4.0 * m * m)


def wv_from_autocovariance(acvf: Callable[[np.ndarray], np.ndarray], levels: int) -> np.ndarray:
    """Haar wavelet variance at levels 1..`levels` by the exact finite sum over the autocovariance.

    Parameters
    ----------
    acvf : callable
        ``acvf(lags) -> autocovariance`` at integer lags (in samples), unit^2.
    levels : int
        Number of levels J.

    Notes
    -----
    Exact, but the sum cancels when the autocovariance decays slowly compared with ``2^j``
    (the kernel sums to zero); families with slow dynamics should provide a closed form.
    """
    out = np.empty(levels)
    for j in range(1, levels + 1):
        m = 2 ** (j - 1)
        a = haar_kernel(m)
        g = np.asarray(acvf(np.arange(2 * m)), dtype=np.float64)
        out[j - 1] = a[0] * g[0] + 2.0 * np.dot(a[1:], g[1:])
    return out


_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(12)


def wv_from_psd(
    psd: Callable[[np.ndarray], np.ndarray],
    levels: int,
    freq: float,
    *,
    wavelet: str = "haar",
    breakpoints: Sequence[float] = (),
) -> np.ndarray:
    """Wavelet variance ``int |H_j(f)|^2 S(f) df`` (eq. 8 of Stebler et al.) by quadrature.

    Parameters
    ----------
    psd : callable
        Two-sided PSD of the sampled process, ``psd(f_hz) -> unit^2/Hz`` for f in (0, freq/2].
    levels : int
        Number of levels J.
    freq : float
        Sampling frequency, Hz.
    wavelet : str
        ``"haar"`` or any orthogonal pywt wavelet name.
    breakpoints : sequence of float
        Frequencies (Hz) where the PSD is not smooth (band edges); panels split there.

    Notes
    -----
    Composite 12-point Gauss-Legendre panels between the zeros ``k / 2^(j-1)`` of the filter
    gain, refined geometrically towards f = 0 so that PSDs singular at the origin
    (``1/f``, ``1/f^2``) are integrated accurately. Panels on which the PSD is not resolved
    (its Legendre coefficients at the 12 nodes have not decayed, e.g. the sharp peak of an
    AR(2) near the unit circle) are bisected until they are; relative accuracy about 1e-10.
    The cost is O(2^j) per level.
    """
    out = np.empty(levels)
    extra = np.asarray([b / freq for b in breakpoints if 0 < b / freq < 0.5])
    for j in range(1, levels + 1):
        m = 2 ** (j - 1)
        # panels no wider than one lobe of the gain: 1/m for Haar, 1/(m L1/2) for longer filters
        per = m * max(1, filter_width(1, wavelet) // 2)
        edges = np.arange(0, per // 2 + 1) / per if per > 1 else np.array([0.0])
        near_zero = (1.0 / (2 * m)) * 2.0 ** -np.arange(0, 60)
        edges = np.unique(np.concatenate([edges, near_zero, extra, [0.5]]))
        out[j - 1] = 2.0 * _integrate_panels(psd, j, wavelet, freq, edges[:-1], edges[1:])
    return out


# PSD values at the 12 nodes -> coefficients of its Legendre series on the panel
_TO_LEGENDRE = np.linalg.inv(np.polynomial.legendre.legvander(_GL_NODES, _GL_NODES.size - 1))
_MAX_BISECTIONS = 40


def _integrate_panels(psd: Callable[[np.ndarray], np.ndarray], level: int, wavelet: str,
                      freq: float, a: np.ndarray, b: np.ndarray) -> float:
    """``int |H_j(f)|^2 S(f) freq df`` over the panels [a, b] (f in cycles/sample), bisecting
    the panels whose PSD is not resolved by the 12-point rule."""
    total = 0.0
    for _ in range(_MAX_BISECTIONS):
        half = 0.5 * (b - a)
        x = (a + half)[:, None] + half[:, None] * _GL_NODES[None, :]
        gain = squared_gain(x, level, wavelet)
        s = np.asarray(psd(x * freq), dtype=np.float64).reshape(x.shape)
        parts = half * ((gain * s * freq) @ _GL_WEIGHTS)
        # error bound of a panel: the size of the PSD's last Legendre terms times its weight
        tail = np.abs(s @ _TO_LEGENDRE[-2:].T).sum(axis=1)
        err = tail * 2.0 * half * freq * gain.max(axis=1)
        bad = (err > 1e-12 * abs(total + parts.sum())) & (b - a > 1e-12)
        total += float(parts[~bad].sum())
        if not bad.any():
            return total
        mid = a[bad] + half[bad]
        a, b = np.concatenate([a[bad], mid]), np.concatenate([mid, b[bad]])
    return total + float(parts[bad].sum())
