"""Power spectrum of a long zero-padded real series by a four-step (Bailey) transform, for eq. 17.

The complex transform of ``H = n1 n2`` points (the sample pairs of a real series of ``2 H``
samples, :mod:`stochmod.empirical.spectrum_jit`) is computed as in Bailey's four-step FFT
("FFTs in external or hierarchical memory", J. Supercomputing 4, 1990): with the series as an
``(n1, n2)`` array ``A[m1, m2] = z[n2 m1 + m2]``,

1. ``n2`` transforms of length ``n1`` along axis 0 (in blocks of :data:`BLOCK` columns),
2. each block multiplied, while in cache, by the twiddles ``exp(-2 pi i k1 m2 / H)``,
3. ``n1`` transforms of length ``n2`` along axis 1,

after which ``A[k1, k2] = Z[k1 + n1 k2]``. The final transpose of the classical algorithm is
not done: the eq. 17 Gram matrix sums over all frequencies, so their order does not matter as
long as every level uses the same, and the real-from-complex split reads each frequency's
partner through the index map of this layout. Every short transform works on data in the
cache, where one transform of ``H`` points makes several passes over an array larger than the
L2 cache.

:func:`transform_shape` chooses ``H >= n`` and its split from ``n`` alone (no timing at run
time): for short series (under :data:`FOUR_STEP_MIN` points) one transform of scipy's next
fast length; otherwise the smallest ``H = n1 n2 >= n`` with ``n1 <= n2 <= 2 n1`` and both
factors 7-smooth (pocketfft's radix-2, 3, 4, 5 and 7 kernels). The four-step's time per point
does not depend on the factors, whereas a single transform's does: so the rule only needs the
least padding.
"""

from __future__ import annotations

import bisect
import concurrent.futures
import functools
import math
from typing import NamedTuple

import numpy as np
from scipy import fft

from stochmod.empirical import spectrum_jit

__all__ = ["BLOCK", "FOUR_STEP_MIN", "Plan", "plan", "power_spectrum", "transform", "transform_shape"]

#: Columns per block of the first pass: ``n1 x BLOCK`` complex64 (512 kB at n1 = 1024) stay in
#: the L2 cache between the block's transforms and its twiddle multiply.
BLOCK = 64
#: Complex points from which the four-step pays against one transform.
FOUR_STEP_MIN = 1 << 15
_PRIMES = (2, 3, 5, 7)


def _smooth_numbers(limit: int) -> list[int]:
    """The 7-smooth numbers ``<= limit`` (products of 2, 3, 5 and 7), ascending."""
    values = [1]
    for p in _PRIMES:
        values = [v * p**e for v in values for e in range(int(math.log(limit, p)) + 2)
                  if v * p**e <= limit]
    return sorted(values)


@functools.lru_cache(maxsize=64)
def transform_shape(n: int) -> tuple[int, int]:
    """The four-step layout ``(n1, n2)`` of the complex transform for a series of `n` samples
    (``H = n1 n2 >= n`` complex points, the pairs of ``2 H`` padded real samples).

    ``(1, scipy.fft.next_fast_len(n))`` below :data:`FOUR_STEP_MIN`; otherwise the smallest
    ``H = n1 n2 >= n`` with ``n1 <= n2 <= 2 n1``, both 7-smooth (ties: the larger ``n1``).
    """
    if n < FOUR_STEP_MIN:
        return 1, fft.next_fast_len(n)
    smooth = _smooth_numbers(2 * math.isqrt(2 * n) + 4)
    best = (1, 2 * n)
    for n1 in smooth:
        if n1 * n1 > best[0] * best[1]:  # n2 >= n1: no smaller product left
            break
        if 2 * n1 * n1 < n:  # n2 would exceed 2 n1
            continue
        n2 = smooth[bisect.bisect_left(smooth, max(n1, -(-n // n1)))]
        if n2 <= 2 * n1 and n1 * n2 <= best[0] * best[1]:
            best = (n1, n2)
    return best


class Plan(NamedTuple):
    """A four-step transform's tables for one layout ``(n1, n2)`` (:func:`plan`)."""

    n1: int
    n2: int
    low: np.ndarray  # (n1, BLOCK) complex64: exp(-2 pi i k1 j / H), j < BLOCK
    high: np.ndarray  # (n1, ceil(n2 / BLOCK)) complex64: exp(-2 pi i k1 b BLOCK / H)
    rows: np.ndarray  # (n1, 2) float64: (cos, sin) of pi k1 / H
    cols: np.ndarray  # (n2, 2) float64: (cos, sin) of pi n1 k2 / H


def _turns(numerators: np.ndarray, h: int) -> np.ndarray:
    """``exp(-2 pi i r / h)`` for the integer array `r`, reduced modulo `h` first (exact)."""
    return np.exp((-2j * np.pi / h) * (numerators % h))


def _cos_sin(angle: np.ndarray) -> np.ndarray:
    return np.stack([np.cos(angle), np.sin(angle)], axis=1)


@functools.lru_cache(maxsize=2)
def plan(n1: int, n2: int) -> Plan:
    """The tables of the ``(n1, n2)`` layout, cached (every level of a signal shares them):
    about ``8 n1 (BLOCK + n2 / BLOCK) + 16 (n1 + n2)`` bytes, 0.6 MB at 2^20 points."""
    h = n1 * n2
    k1 = np.arange(n1, dtype=np.int64)[:, None]
    low = _turns(k1 * np.arange(BLOCK), h).astype(np.complex64)
    high = _turns(k1 * (BLOCK * np.arange(-(-n2 // BLOCK))), h).astype(np.complex64)
    return Plan(n1, n2, low, high, _cos_sin(np.pi * np.arange(n1) / h),
                _cos_sin(np.pi * n1 * np.arange(n2) / h))


def _in_place(transformed: np.ndarray, target: np.ndarray) -> None:
    """Keep a transform's result in `target` (scipy writes in place with ``overwrite_x``)."""
    if not np.may_share_memory(transformed, target):  # pragma: no cover - scipy's choice
        target[...] = transformed


def power_spectrum(buf: np.ndarray, tables: Plan, out: np.ndarray) -> None:
    """``out = |X|^2``, the power spectrum of the real float32 series `buf` (``2 n1 n2``
    samples, overwritten) at its ``n1 n2 + 1`` frequencies from 0 to Nyquist, in the order of
    :func:`~stochmod.empirical.spectrum_jit.split_power` (the natural order if ``n1 = 1``)."""
    spectrum_jit.split_power(transform(buf, tables), tables.rows, tables.cols, out)


def transform(buf: np.ndarray, tables: Plan,
              pool: concurrent.futures.Executor | None = None, workers: int = 1) -> np.ndarray:
    """The four-step transform of the sample pairs of the real float32 series `buf`, in place:
    the complex ``(n1, n2)`` view of `buf` in the layout ``C[k1, k2] = Z[k1 + n1 k2]``.

    With `pool` (an executor of at least `workers` threads), the first pass's blocks are
    split into `workers` runs of consecutive blocks on it, and the second pass's rows among
    `workers` threads of scipy: the same result, bit for bit, as one thread.
    """
    n1, n2 = tables.n1, tables.n2
    a = buf.view(np.complex64).reshape(n1, n2)
    if n1 > 1:
        blocks = range(0, -(-n2 // BLOCK))
        if pool is None or workers < 2:
            _first_pass(a, tables, blocks)
        else:
            step = -(-len(blocks) // workers)
            runs = [pool.submit(_first_pass, a, tables, blocks[i : i + step])
                    for i in range(0, len(blocks), step)]
            for run in runs:
                run.result()
    _in_place(fft.fft(a, axis=1, overwrite_x=True, workers=workers if pool is not None else 1), a)
    return a


def _first_pass(a: np.ndarray, tables: Plan, blocks: range) -> None:
    """The first pass of :func:`transform` on the column blocks `blocks` of `a`: each block's
    transforms along axis 0 and its twiddle multiply, while it is in cache."""
    for b in blocks:
        block = a[:, b * BLOCK : (b + 1) * BLOCK]
        _in_place(fft.fft(block, axis=0, overwrite_x=True), block)
        spectrum_jit.twiddle_block(block, b, tables.low, tables.high)
