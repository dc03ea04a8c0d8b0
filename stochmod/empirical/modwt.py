"""Maximal overlap discrete wavelet transform (MODWT): filters, gains and interior coefficients.

Conventions (Percival & Walden 2000, ch. 5; Stebler et al. 2014, eqs. 3-6 and 18):

- The level-1 MODWT filters are PyWavelets' orthogonal filters in *convolution* order,
  rescaled by ``1/sqrt(2)``: ``h_1 = dec_hi[::-1] / sqrt(2)`` (wavelet) and
  ``g_1 = dec_lo[::-1] / sqrt(2)`` (scaling), so that ``sum h_1 = 0``, ``sum h_1^2 = 1/2``.
  For Haar, ``h_1 = (+1/2, -1/2)``, the sign of eq. 18.
- The level-j wavelet filter (eq. 5) has width ``L_j = (2^j - 1)(L_1 - 1) + 1``; for Haar
  ``L_j = 2^j`` and ``h_{j,l} = +1/2^j`` for ``l < 2^(j-1)``, ``-1/2^j`` after.
- Coefficients are ``W_{j,t} = sum_l h_{j,l} x_{t-l}``; only the *interior* ones, which need
  no boundary rule, are returned: ``t = L_j - 1, ..., N - 1`` (0-based), ``M_j = N - L_j + 1``
  of them (eq. 9).

The transform is computed with the MODWT pyramid algorithm restricted to the interior
(``L_1`` multiply-adds per sample and level, processed in cache-sized chunks, in place on one
work array), never with ``pywt.swt`` (whose cost explodes at deep levels and which needs a
power-of-two length). For Haar the pyramid is a moving-sum doubling: each level costs one
addition and one subtraction per sample; unlike differences of one cumulative sum, its
round-off does not grow with N or with the signal's mean. When only the sums of squares are
needed (the wavelet variance), the shallow Haar levels are computed several at a time, block
by block, in one pass over memory, and each deeper level follows the one above it a few blocks
behind, while its input is still in cache; the Haar levels run as compiled loops
(:mod:`stochmod.empirical.haar_jit`).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from numpy.lib.stride_tricks import as_strided
from numpy.typing import ArrayLike

from stochmod.core.checks import as_signal
from stochmod.core.filters import check_level, default_levels, modwt_filters
from stochmod.empirical import haar_jit

__all__ = [
    "iter_modwt",
    "modwt_coefficients",
    "pyramid",
]

_CHUNK = 1 << 16  # samples per block of the pyramid: the working set stays in cache
_HALO = 16  # a sweep of several Haar levels recomputes at most _CHUNK / _HALO samples per block
_DOT = 8192  # dot products in pieces below OpenBLAS's threading threshold (n > 10000): threaded
# BLAS calls on such short vectors stall for milliseconds when the other cores are busy


def _sumsq(w: np.ndarray) -> float:
    """Sum of squares of a contiguous vector, by single-threaded dot products of _DOT pieces."""
    whole = w.size - w.size % _DOT
    rows = w[:whole].reshape(-1, _DOT)
    rest = w[whole:]
    return float(np.vecdot(rows, rows).sum()) + float(np.dot(rest, rest))


def _haar_block(levels: int, chunk: int) -> int:
    """Number of shallow Haar levels, from level 1, that one sweep of `chunk`-sample blocks
    serves.

    A sweep of k levels recomputes a halo of ``2^k - 1`` samples per block, kept at most
    ``chunk / _HALO``.
    """
    k = 1
    while k < levels and 2 ** (k + 1) - 1 <= chunk // _HALO:
        k += 1
    return k


def pyramid(
    x: np.ndarray, levels: int, wavelet: str, w_out: np.ndarray | None = None,
    sumsq: bool = True,
) -> Iterator[tuple[int, float, int]]:
    """Run the interior MODWT pyramid; yield ``(j, sum of W_j^2, M_j)`` for j = 1..levels.

    When `w_out` (length >= M_1) is given, ``w_out[:M_j]`` holds the level-j coefficients at
    the time of the yield (overwritten at the next level). With ``sumsq=False`` (and `w_out`)
    the sums of squares are not accumulated (0.0 is yielded): callers that only need the
    coefficients. Extra memory: one copy of `x`
    and two blocks of ``_CHUNK + _CHUNK / _HALO`` samples. For Haar without `w_out`, every
    level is yielded after one pass of the compiled pyramid.
    """
    h, g = modwt_filters(wavelet)
    width1 = h.size
    haar = width1 == 2
    if haar and w_out is None:
        yield from _haar_pyramid(x, levels)
        return
    v = np.array(x, dtype=np.float64, copy=True)  # V_{j-1} interior (Haar: unscaled sums)
    n_valid = v.size
    item = v.strides[0]
    sign = 1.0 if h[0] > 0 else -1.0
    coef = np.vstack([h[::-1], g[::-1]])  # rows: taps at offsets 0, step, ..., (L1-1) step
    for j in range(1, levels + 1):
        step = 2 ** (j - 1)
        m = n_valid - step * (width1 - 1)
        update = j < levels  # the scaling coefficients are not needed after the last level
        rows = coef if update else coef[:1]
        total = 0.0
        if haar:  # W_j = (newer half-sum - older half-sum) / 2^j ; V_j (unscaled) = their sum
            total = haar_jit.haar_level_coefficients(v, n_valid, step, sign * 0.5**j, update,
                                                     w_out)
            total = total if sumsq else 0.0
        else:
            for s in range(0, m, _CHUNK):
                e = min(s + _CHUNK, m)
                view = as_strided(v[s:], shape=(width1, e - s), strides=(step * item, item))
                out = np.einsum("ij,jk->ik", rows, view)  # no BLAS threads (see _DOT)
                if sumsq:
                    total += _sumsq(out[0])
                if w_out is not None:
                    w_out[s:e] = out[0]
                if update:
                    v[s:e] = out[1]
        n_valid = m
        yield j, (total * 0.25**j if haar else total), m


def _haar_pyramid(x: np.ndarray, levels: int) -> Iterator[tuple[int, float, int]]:
    """:func:`pyramid` for Haar without coefficients, in one call of
    :func:`stochmod.empirical.haar_jit.haar_pyramid_sums`: the shallow levels, whose filters
    are short next to a block, are computed block by block through all of them at once; each
    deeper level follows the one above it through memory a few blocks behind. The first level
    reads `x` directly, so no copy of the signal is made beyond the one work array of the sums.
    """
    v = np.empty(x.size)
    size = min(_CHUNK + _CHUNK // _HALO, x.size)  # a block and its halo
    bufs = np.empty((2, size))  # the block buffers that a block's levels alternate between
    # the compiled loops keep reassociated partial sums whose order follows the memory layout:
    # a strided view (a column of a 2-D array) is made contiguous so that it gives the digits
    # of the same data stored contiguously
    src = np.ascontiguousarray(x)
    totals = np.empty(levels)
    # the digits follow the pieces of a sweep of `parted` levels; the deepest of them runs
    # behind the sweep as the levels below it do, which costs less than its halo in the sweep
    parted = _haar_block(levels, _CHUNK)
    haar_jit.haar_pyramid_sums(src, v, levels, max(parted - 1, 1), parted, bufs, _CHUNK, totals)
    n_valid = x.size
    for j in range(1, levels + 1):
        n_valid -= 2 ** (j - 1)
        yield j, float(totals[j - 1]) * 0.25**j, n_valid


def modwt_coefficients(x: ArrayLike, level: int, wavelet: str = "haar") -> np.ndarray:
    """Interior MODWT wavelet coefficients of `x` at one level.

    Parameters
    ----------
    x : array_like, shape (N,)
        Finite signal, any length N >= L_j, in its own unit.
    level : int
        Level j, 1 <= j <= :func:`max_level` (N, wavelet).
    wavelet : str
        Orthogonal PyWavelets wavelet name (default "haar").

    Returns
    -------
    ndarray, shape (M_j,)
        ``W_{j,t} = sum_l h_{j,l} x_{t-l}`` for ``t = L_j - 1 .. N - 1`` (the coefficients that
        need no boundary rule), in the unit of `x`; ``M_j = N - L_j + 1``. Equals
        ``numpy.convolve(x, modwt_filter(level, wavelet), mode="valid")``.

    Raises
    ------
    InputError
        Bad signal (empty, NaN/inf, not 1-D, non-numeric), bad level, unknown wavelet.
    """
    x = as_signal(x, name="x", min_length=1)
    modwt_filters(wavelet)
    level = check_level(x.size, level, wavelet)
    buf = np.empty(x.size)
    for j, _, m in pyramid(x, level, wavelet, buf):
        if j == level:
            return buf[:m].copy()
    raise AssertionError("unreachable")  # pragma: no cover


def iter_modwt(
    x: ArrayLike, levels: int | None = None, wavelet: str = "haar"
) -> Iterator[tuple[int, np.ndarray]]:
    """Yield ``(j, W_j)``, the interior MODWT coefficients of every level j = 1..`levels`.

    One pass of the pyramid serves all levels (cost O(N L_1) per level). Each yielded array
    is new (length ``M_j``), so callers may keep them, e.g. for cross-level covariances.

    Parameters
    ----------
    x : array_like, shape (N,)
        Finite signal.
    levels : int, optional
        Number of levels J (default :func:`default_levels`).
    wavelet : str
        Orthogonal PyWavelets wavelet name.
    """
    x = as_signal(x, name="x", min_length=1)
    modwt_filters(wavelet)
    levels = default_levels(x.size, wavelet) if levels is None else check_level(
        x.size, levels, wavelet, name="levels"
    )

    def gen() -> Iterator[tuple[int, np.ndarray]]:
        buf = np.empty(x.size)
        for j, _, m in pyramid(x, levels, wavelet, buf):
            yield j, buf[:m].copy()

    return gen()
