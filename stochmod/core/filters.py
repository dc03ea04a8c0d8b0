"""Wavelet filters of the MODWT and their squared gains (Percival & Walden 2000, ch. 5;
Stebler et al. 2014, eqs. 3-6 and 18).

- The level-1 MODWT filters are PyWavelets' orthogonal filters in *convolution* order,
  rescaled by ``1/sqrt(2)``: ``h_1 = dec_hi[::-1] / sqrt(2)`` (wavelet) and
  ``g_1 = dec_lo[::-1] / sqrt(2)`` (scaling), so that ``sum h_1 = 0``, ``sum h_1^2 = 1/2``.
  For Haar, ``h_1 = (+1/2, -1/2)``, the sign of eq. 18.
- The level-j wavelet filter (eq. 5) has width ``L_j = (2^j - 1)(L_1 - 1) + 1``; for Haar
  ``L_j = 2^j`` and ``h_{j,l} = +1/2^j`` for ``l < 2^(j-1)``, ``-1/2^j`` after.

The theoretical wavelet variance (:mod:`stochmod.core.theory`) integrates a PSD against the
squared gains; the transform itself is :mod:`stochmod.empirical.modwt`.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pywt
from numpy.typing import ArrayLike

from stochmod.core.checks import check_positive_int
from stochmod.core.errors import InputError

__all__ = [
    "modwt_filters",
    "modwt_filter",
    "filter_width",
    "max_level",
    "default_levels",
    "squared_gain",
    "check_level",
]


@functools.lru_cache(maxsize=64)
def _filters(wavelet: str) -> tuple[np.ndarray, np.ndarray]:
    if not isinstance(wavelet, str):
        raise InputError(f"wavelet must be a PyWavelets wavelet name (str), got {wavelet!r}")
    try:
        w = pywt.Wavelet(wavelet)
    except ValueError:
        raise InputError(
            f"unknown wavelet {wavelet!r}; use an orthogonal discrete PyWavelets wavelet "
            "such as 'haar', 'db4', 'sym4' or 'coif2'"
        ) from None
    if not w.orthogonal:
        raise InputError(
            f"wavelet {wavelet!r} is not orthogonal; the MODWT needs an orthogonal filter"
        )
    h = np.asarray(w.dec_hi, dtype=np.float64)[::-1] / math.sqrt(2.0)
    g = np.asarray(w.dec_lo, dtype=np.float64)[::-1] / math.sqrt(2.0)
    h.setflags(write=False)
    g.setflags(write=False)
    return h, g


def modwt_filters(wavelet: str = "haar") -> tuple[np.ndarray, np.ndarray]:
    """Level-1 MODWT wavelet and scaling filters ``(h_1, g_1)`` in convolution order.

    Parameters
    ----------
    wavelet : str
        Name of an orthogonal discrete PyWavelets wavelet ("haar", "db4", "sym4", ...).

    Returns
    -------
    h, g : ndarray, shape (L_1,)
        ``h = dec_hi[::-1] / sqrt(2)`` and ``g = dec_lo[::-1] / sqrt(2)`` (read-only), so that
        ``sum(h) = 0``, ``sum(h**2) = 1/2``, ``sum(g) = 1``.

    Raises
    ------
    InputError
        Unknown, continuous or non-orthogonal wavelet.
    """
    return _filters(wavelet)


def filter_width(level: int, wavelet: str = "haar") -> int:
    """Width ``L_j = (2^j - 1)(L_1 - 1) + 1`` (samples) of the level-`level` MODWT filter."""
    level = check_positive_int(level, name="level")
    width1 = _filters(wavelet)[0].size
    return (2**level - 1) * (width1 - 1) + 1


def max_level(n: int, wavelet: str = "haar") -> int:
    """Deepest level whose filter fits in `n` samples (``L_j <= n``, so ``M_j >= 1``); 0 if none."""
    n = check_positive_int(n, name="n")
    width1 = _filters(wavelet)[0].size
    # L_j <= n  <=>  2^j <= (n - 1) / (L_1 - 1) + 1
    return int(math.floor(math.log2((n - 1) // (width1 - 1) + 1)))


def default_levels(n: int, wavelet: str = "haar") -> int:
    """Default number of levels ``J = floor(log2 n) - 1``, capped at :func:`max_level`, at least 1.

    Raises
    ------
    InputError
        If even the level-1 filter does not fit in `n` samples.
    """
    top = max_level(n, wavelet)
    if top < 1:
        raise InputError(
            f"x has {n} sample(s); the level-1 {wavelet!r} MODWT filter needs at least "
            f"{filter_width(1, wavelet)}"
        )
    return max(1, min(int(math.floor(math.log2(n))) - 1, top))


def check_level(n: int, level: int, wavelet: str, name: str = "level") -> int:
    """`level` checked as a positive number of levels that `n` samples support for `wavelet`
    (InputError naming `name` otherwise)."""
    level = check_positive_int(level, name=name)
    top = max_level(n, wavelet)
    if level > top:
        raise InputError(
            f"{name}={level} is more than the data allow: {n} samples support at most "
            f"{top} level(s) of the {wavelet!r} MODWT (the level-j filter, "
            f"(2^j - 1)(L_1 - 1) + 1 samples wide, must fit in the signal)"
        )
    return level


def modwt_filter(level: int, wavelet: str = "haar") -> np.ndarray:
    """Equivalent level-`level` MODWT wavelet filter ``h_{j,l}``, ``l = 0..L_j - 1`` (eq. 5).

    Built by the cascade ``h_j = g_1 * g_1^(2) * ... * g_1^(2^(j-2)) * h_1^(2^(j-1))`` where
    ``^(k)`` inserts ``k - 1`` zeros between taps. ``sum h_j^2 = 1/2^j``.

    Parameters
    ----------
    level : int
        Level j >= 1.
    wavelet : str
        Orthogonal PyWavelets wavelet name.

    Returns
    -------
    ndarray, shape (L_j,)
        Dimensionless filter taps in convolution order (``W_t = sum_l h_l x_{t-l}``).
    """
    level = check_positive_int(level, name="level")
    h, g = _filters(wavelet)
    out = np.ones(1)
    for k in range(level):
        base = h if k == level - 1 else g
        up = np.zeros((base.size - 1) * 2**k + 1)
        up[:: 2**k] = base
        out = np.convolve(out, up)
    return out


def _reduce(f: np.ndarray) -> np.ndarray:
    """``f`` minus its nearest integer (exact in floating point), in [-1/2, 1/2]."""
    return f - np.round(f)


def _cosine_series(taps: np.ndarray, f: np.ndarray) -> np.ndarray:
    """``|sum_l c_l exp(-i 2 pi f l)|^2`` via the taps' autocorrelation (a cosine series)."""
    r = np.correlate(taps, taps, mode="full")[taps.size - 1 :]
    k = np.arange(1, taps.size)
    return r[0] + 2.0 * np.cos(2.0 * np.pi * f[..., None] * k) @ r[1:]


def _split_zeros(taps: np.ndarray, sign: float) -> tuple[int, np.ndarray]:
    """Factor ``C(z) = (1 - sign z^-1)^K Q(z)``: return K and the taps of Q.

    Each division by ``1 - s z^-1`` is ``q_l = s^l cumsum(s^k c_k)_l`` and must leave a
    vanishing remainder; K stops where it does not, or where the factorisation would no
    longer reproduce the taps to 1e-12 (deflating a multiple root is ill-conditioned).
    """
    k, q = 0, taps
    scale = np.abs(taps).sum()
    while q.size > 1:
        alt = sign ** np.arange(q.size)
        full = alt * np.cumsum(alt * q)
        rebuilt = full[:-1]
        for _ in range(k + 1):
            rebuilt = np.convolve(rebuilt, [1.0, -sign])
        if abs(full[-1]) > 1e-8 * scale or np.max(np.abs(rebuilt - taps)) > 1e-12 * scale:
            break
        k, q = k + 1, full[:-1]
    return k, q


@functools.lru_cache(maxsize=64)
def _gain_model(wavelet: str) -> tuple[tuple[int, np.ndarray], tuple[int, np.ndarray], bool]:
    """Per half-band filter ``(K, taps of Q)``, and whether the db/sym closed form applies."""
    h, g = _filters(wavelet)
    if pywt.Wavelet(wavelet).short_family_name in ("db", "sym"):
        half = h.size // 2
        coef = np.array([math.comb(half - 1 + l, l) for l in range(half)], dtype=np.float64)
        return (half, coef), (half, coef), True
    return _split_zeros(h, 1.0), _split_zeros(g, -1.0), False


def _half_gain(wavelet: str, phi: np.ndarray, lowpass: bool) -> np.ndarray:
    """``|G_1(phi)|^2`` (lowpass) or ``|H_1(phi)|^2``, phi in [-1/2, 1/2], accurate at zeros.

    ``sin(pi phi)`` and ``cos(pi phi) = sin(pi (1/2 - |phi|))`` are taken with exact arguments.
    Daubechies and symlets (same squared gains) in closed form (Percival & Walden 2000,
    eq. 105b): ``|G_1|^2 = cos^L sum_{l<L/2} C(L/2-1+l, l) sin^(2l)``, H with sin and cos
    swapped; other wavelets as ``(2 sin)^(2K) |Q|^2`` (resp. cos), K zeros split off the taps.
    """
    s2 = np.sin(np.pi * phi) ** 2
    c2 = np.sin(np.pi * (0.5 - np.abs(phi))) ** 2
    zero, other = (c2, s2) if lowpass else (s2, c2)
    hi, lo, closed = _gain_model(wavelet)
    k, q = lo if lowpass else hi
    if closed:
        return zero**k * np.polynomial.polynomial.polyval(other, q)
    return (4.0 * zero) ** k * np.maximum(_cosine_series(q, phi), 0.0)


def squared_gain(f: ArrayLike, level: int, wavelet: str = "haar") -> np.ndarray:
    """Squared gain ``|H_j(f)|^2`` of the level-j MODWT wavelet filter.

    Parameters
    ----------
    f : array_like
        Frequency in cycles/sample (``f_Hz / freq``); any real value (the gain has period 1).
    level : int
        Level j >= 1.
    wavelet : str
        Orthogonal PyWavelets wavelet name.

    Returns
    -------
    ndarray
        Dimensionless squared gain (>= 0), same shape as `f`;
        ``int_{-1/2}^{1/2} |H_j|^2 df = 1/2^j``.

    Notes
    -----
    Haar in closed form, ``sin^4(pi m f) / (m^2 sin^2(pi f))`` with ``m = 2^(j-1)`` (0 at
    integer f, the limit), evaluated as ``sin^2(pi m f) * (sin(pi m f) / (m sin(pi f)))^2``
    after reducing ``f`` and ``m f`` exactly to [-1/2, 1/2], so that the relative accuracy
    is a few ulps everywhere, also next to the zeros. Other wavelets by the product
    formula ``|H_1(2^(j-1) f)|^2 prod_{l<j-1} |G_1(2^l f)|^2`` (eq. 5) with exactly reduced
    arguments and factors written so as to keep their zeros (Daubechies and symlets in closed
    form, others as ``(2 sin(pi f))^(2K) |Q(f)|^2``): relative accuracy is kept near f = 0,
    where a PSD integrand ``|H_j|^2 S`` with S ~ 1/f^2 or steeper would otherwise be swamped
    by round-off. The theoretical wavelet variance of a process with PSD S (unit^2 per
    cycle/sample) is ``int_{-1/2}^{1/2} |H_j(f)|^2 S(f) df`` (eq. 8).
    """
    level = check_positive_int(level, name="level")
    try:
        f = np.asarray(f, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"f must be real frequencies in cycles/sample: {exc}") from None
    if not np.all(np.isfinite(f)):
        raise InputError("f contains NaN or inf; frequencies must be finite (cycles/sample)")
    h, _ = _filters(wavelet)
    m = 2 ** (level - 1)
    f0 = _reduce(f)
    if h.size == 2:  # Haar
        smf = np.sin(np.pi * _reduce(m * f0))
        sf = np.sin(np.pi * f0)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(sf == 0, 1.0, smf / (m * sf))
        return smf * smf * ratio * ratio
    out = _half_gain(wavelet, _reduce(m * f0), lowpass=False)
    for k in range(level - 1):
        out = out * _half_gain(wavelet, _reduce(2**k * f0), lowpass=True)
    return out
