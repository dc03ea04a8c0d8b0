"""Asymptotic covariance of the empirical wavelet variance (Stebler et al. 2014, eq. 17), by FFT.

For levels m and l, eq. 17 sums the squared sample cross-covariances of the two wavelet
coefficient series over all lags. With each level's interior coefficients zero-padded to a
length ``nfft >= 2N``, the cross-correlation sequence is a product of discrete Fourier
transforms, and by Parseval its sum of squares is ``sum_f |X_m(f)|^2 |X_l(f)|^2 / nfft``:
one real FFT per level and, for all pairs at once, one Gram matrix of the level power
spectra, O(J N log N + J^2 N) in all, where the paper found the direct sum infeasible for
long signals. The sum over all lags does not depend on where each series sits in the
buffer, so every level starts at index 0.
"""

from __future__ import annotations

import collections
import concurrent.futures
import contextlib
import os
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike

from stochmod.core.checks import as_signal, check_positive_int
from stochmod.core.errors import InputError
from stochmod.core.filters import check_level, default_levels, modwt_filters
from stochmod.empirical import four_step, spectrum_jit
from stochmod.empirical.modwt import pyramid

__all__ = ["SPECTRA_BYTES", "THREADS_VARIABLE", "default_workers", "wv_covariance"]

#: Environment variable that sets the default number of threads of :func:`wv_covariance`.
THREADS_VARIABLE = "STOCHMOD_FFT_THREADS"
_GRAM_BLOCK = 128  # frequencies per block of the compiled Gram (J x 128 float64 in L1)
#: Bytes of float32 level spectra held at once (384 MiB). Above it (long records: 22 levels
#: of 46 MB at 1.15e7 samples, 8 h at 400 Hz) the levels are taken in groups that fit
#: (:func:`_grouped_gram`): less memory for more transforms. Below about 4e6 samples all
#: levels fit.
SPECTRA_BYTES = 384 << 20


def default_workers() -> int:
    """Threads :func:`wv_covariance` uses when not told: ``$STOCHMOD_FFT_THREADS`` if set (a
    positive integer; set it to 1 in each process of a pool that already keeps every core
    busy), otherwise two, or one on a single-core machine."""
    value = os.environ.get(THREADS_VARIABLE, "")
    if value == "":
        return min(2, os.cpu_count() or 1)
    try:
        workers = int(value)
    except ValueError:
        workers = 0
    if workers < 1:
        raise InputError(f"${THREADS_VARIABLE} must be a positive integer, got {value!r}")
    return workers


def _level_power(shape: tuple[int, int]) -> Callable[[np.ndarray, np.ndarray], None]:
    """The function ``power(buf, out)`` that sets `out` to the float32 power spectrum
    ``|rfft(buf)|^2`` at the ``n1 n2 + 1`` frequencies of one zero-padded series of
    ``2 n1 n2`` samples, ``shape = (n1, n2)``; `buf` is overwritten. The four-step transform
    of the sample pairs, in place, and the split of its layout
    (:func:`stochmod.empirical.four_step.power_spectrum`; the frequencies in that layout's
    order, which the Gram matrix does not see)."""
    tables = four_step.plan(*shape)

    def power(buf: np.ndarray, out: np.ndarray) -> None:
        four_step.power_spectrum(buf, tables, out)

    return power


def _power_spectra(
    x: np.ndarray, levels: int, wavelet: str, shape: tuple[int, int],
    clip: np.ndarray | None = None, workers: int = 1,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Scaled half-spectrum powers ``|X_j(f)|^2 / scale_j`` of every level's interior W_j.

    Each series is zero-padded to ``nfft = 2 n1 n2`` samples, ``shape = (n1, n2)``
    (:func:`stochmod.empirical.four_step.transform_shape`). Returns ``(powers, scale, sizes)``:
    float32 rows of ``nfft // 2 + 1`` frequencies (every row in the same order), the
    float64 factors ``scale_j = mean(W_j^2)`` (unit^2) that undo the normalisation, and M_j.
    Each series is divided by its RMS before the single-precision FFT, so that neither
    ``|X|^2`` nor its products leave float32's range whatever the signal's unit. With
    ``workers > 1``, each level's transform runs on a pool of `workers` threads while this
    thread computes the next levels (one one-dimensional transform per task: pocketfft's
    batched transforms of such long rows are slower than the rows one by one). With `clip`,
    level j's coefficients are first clipped to ``+-clip[j-1]``.
    """
    n = x.size
    nfft = 2 * shape[0] * shape[1]
    powers = np.empty((levels, nfft // 2 + 1), dtype=np.float32)
    scale = np.zeros(levels)
    sizes = np.empty(levels, dtype=np.int64)
    coef = np.empty(n)
    bufs = [np.empty(nfft, dtype=np.float32) for _ in range(workers + 1 if workers > 1 else 1)]
    power = _level_power(shape)
    pending: collections.deque[concurrent.futures.Future[None]] = collections.deque()
    with (concurrent.futures.ThreadPoolExecutor(workers) if workers > 1
          else contextlib.nullcontext()) as pool:
        for j, sumsq, m in pyramid(x, levels, wavelet, coef):
            if clip is not None:
                w = np.clip(coef[:m], -clip[j - 1], clip[j - 1], out=coef[:m])
                sumsq = float(np.dot(w, w))
            ms = sumsq / m
            k = (j - 1) % len(bufs)
            if len(pending) == len(bufs):
                pending.popleft().result()  # the task that read bufs[k]
            buf = bufs[k]
            np.multiply(coef[:m], 1.0 / np.sqrt(ms) if ms > 0 else 0.0, out=buf[:m])
            buf[m:] = 0.0  # the padding (the last transform may have overwritten it)
            scale[j - 1], sizes[j - 1] = ms, m
            if pool is None:
                power(buf, powers[j - 1])
            else:
                pending.append(pool.submit(power, buf, powers[j - 1]))
        for task in pending:
            task.result()
    return powers, scale, sizes


def _grouped_gram(
    x: np.ndarray, levels: int, wavelet: str, shape: tuple[int, int], group: int,
    clip: np.ndarray | None = None, workers: int = 1,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_half_spectrum_gram` of :func:`_power_spectra`, holding at most `group` level
    spectra at once: returns ``(gram, scale, sizes)``.

    The levels are taken in groups of `group`, in order. For each group, one run of the
    pyramid transforms its levels and keeps their spectra, which give the group's block of
    the Gram matrix, and then transforms each deeper level and multiplies its powers with the
    kept ones straight from its transform (its entries against the group,
    :func:`~stochmod.empirical.spectrum_jit.split_power_cross`, no spectrum stored); the next
    group runs the pyramid again from level 1 without transforming the levels before it. For
    J levels this is ``J + (J - g) + (J - 2 g) + ...`` transforms instead of J (33 instead of
    22 for two groups of 11), in about ``group / J`` of the spectra's memory. The sums are the
    same as :func:`_half_spectrum_gram`'s, those against the deeper levels in another order
    (the same to float rounding).
    """
    n = x.size
    H = shape[0] * shape[1]
    gram = np.zeros((levels, levels))
    ends = np.zeros((levels, 2))
    scale = np.zeros(levels)
    sizes = np.empty(levels, dtype=np.int64)
    coef = np.empty(n)
    slots = max(1, workers)
    bufs = [np.empty(2 * H, dtype=np.float32) for _ in range(slots)]
    power = _level_power(shape)
    tables = four_step.plan(*shape)
    with (concurrent.futures.ThreadPoolExecutor(workers) if workers > 1
          else contextlib.nullcontext()) as pool:
        for start in range(0, levels, group):
            stop = min(start + group, levels)
            kept = np.empty((stop - start, H + 1), dtype=np.float32)
            pending: collections.deque[concurrent.futures.Future[None]] = collections.deque()
            free = collections.deque(range(slots))

            def streamed(k: int, j: int, kept: np.ndarray = kept, start: int = start,
                         stop: int = stop) -> int:
                cross = np.zeros(stop - start)
                ends[j - 1] = spectrum_jit.split_power_cross(
                    four_step.transform(bufs[k], tables), tables.rows, tables.cols, kept, cross)
                gram[j - 1, start:stop] = cross
                gram[start:stop, j - 1] = cross
                return k

            def stored(k: int, j: int, kept: np.ndarray = kept, start: int = start) -> int:
                power(bufs[k], kept[j - 1 - start])
                return k

            for j, sumsq, m in pyramid(x, levels, wavelet, coef):
                if j <= start:
                    continue
                if clip is not None:
                    w = np.clip(coef[:m], -clip[j - 1], clip[j - 1], out=coef[:m])
                    sumsq = float(np.dot(w, w))
                ms = sumsq / m
                scale[j - 1], sizes[j - 1] = ms, m
                if j == stop + 1:  # the group is complete: its block, then the deeper levels
                    while pending:
                        free.append(pending.popleft().result())
                    block = spectrum_jit.power_gram(kept, _GRAM_BLOCK)
                    gram[start:stop, start:stop] = block
                    ends[start:stop] = kept[:, [0, -1]]
                if not free:
                    free.append(pending.popleft().result())
                k = free.popleft()
                buf = bufs[k]
                np.multiply(coef[:m], 1.0 / np.sqrt(ms) if ms > 0 else 0.0, out=buf[:m])
                buf[m:] = 0.0
                task = stored if j <= stop else streamed
                if pool is None:
                    free.append(task(k, j))
                else:
                    pending.append(pool.submit(task, k, j))
            while pending:
                free.append(pending.popleft().result())
            if stop == levels:  # the last group streams nothing
                gram[start:stop, start:stop] = spectrum_jit.power_gram(kept, _GRAM_BLOCK)
                ends[start:stop] = kept[:, [0, -1]]
            del kept, stored, streamed  # the group's spectra (the tasks held them)
    gram *= 2.0  # the conjugate half
    gram -= ends @ ends.T  # f = 0 and nfft / 2 appear once in the full spectrum
    return gram, scale, sizes


def _half_spectrum_gram(powers: np.ndarray, nfft: int) -> np.ndarray:
    """``G_ab = sum_f P_a(f) P_b(f)`` over all ``nfft`` frequencies, from the half spectrum.

    The float32 rows are promoted to float64 block by block, so the products and their sums
    are in double precision (:func:`~stochmod.empirical.spectrum_jit.power_gram`).
    """
    gram = spectrum_jit.power_gram(powers, _GRAM_BLOCK)
    gram *= 2.0  # the conjugate half
    ends = powers[:, [0, -1]].astype(np.float64) if nfft % 2 == 0 else powers[:, :1].astype(
        np.float64
    )
    gram -= ends @ ends.T  # f = 0 (and nfft / 2) appear once in the full spectrum
    return gram


def wv_covariance(x: ArrayLike, levels: int | None = None, wavelet: str = "haar", *,
                  clip: ArrayLike | None = None, workers: int | None = None) -> np.ndarray:
    """Covariance matrix of the empirical wavelet variances at levels 1..J, unit^4.

    ``Cov(v_m, v_l) = (1 / M_ml) sum_tau c_ml(tau)^2`` with ``c_ml(tau) = (1/M_ml) sum_k
    W_{m,k} W_{l,k+tau}`` over the common interior indices (``M_ml = min(M_m, M_l)``), the
    Gaussian asymptotic form of eqs. 10-11 and 17.

    Parameters
    ----------
    x : array_like, shape (N,)
        The signal.
    levels : int, optional
        Number of levels J (default: :func:`stochmod.empirical.modwt.default_levels`).
    wavelet : str
        Orthogonal pywt wavelet (Haar by default).
    clip : array_like, shape (J,), optional
        Per-level bounds (unit u): level j's coefficients are clipped to ``+-clip[j-1]``
        first, so that a few outliers do not dominate the sums (the robust wavelet variance
        uses ``c sqrt(nu_j)``).
    workers : int, optional
        Threads for the levels' transforms (default :func:`default_workers`). The result is
        the same, bit for bit, for every number of threads.

    Returns
    -------
    ndarray, shape (J, J)
        Symmetric covariance of the estimator ``v_hat``, already divided by the sample sizes.

    Raises
    ------
    InputError
        Bad signal, bad `levels` (more than the data allow), unknown wavelet, `workers` not a
        positive integer.

    Notes
    -----
    The transforms are in single precision (relative error ~1e-6, far below the estimator's
    own sampling error of order 1/sqrt(M_j)) on RMS-normalised series, which halves their
    time and memory; the products and sums are in double precision. Each level's transform
    is a four-step one of short transforms in cache (:mod:`stochmod.empirical.four_step`),
    whose frequencies come out in another order: the Gram matrix does not depend on it.
    Memory: the J float32 half spectra, about 4 J N bytes, plus ``workers + 1`` float32 FFT
    buffers of 8 N bytes, two float64 copies of `x` and the four-step's tables (0.6 MB at
    N = 2^20). When the spectra would exceed :data:`SPECTRA_BYTES`, the levels are taken in
    groups of spectra that fit it, each group's pass transforming the deeper levels again
    (three groups at 8 h of 400 Hz data: 42 transforms instead of 22, 1.6x the CPU time, in
    0.6x the memory); ``workers`` FFT buffers then. The result is the same to float
    rounding either way.
    """
    x = as_signal(x, name="x", min_length=2)
    modwt_filters(wavelet)
    n = x.size
    J = default_levels(n, wavelet) if levels is None else check_level(n, levels, wavelet, "levels")
    shape = four_step.transform_shape(n)
    nfft = 2 * shape[0] * shape[1]  # >= 2 n: the sums over lags do not wrap around
    bounds = None
    if clip is not None:
        bounds = np.asarray(clip, dtype=np.float64)
        if bounds.shape != (J,) or not np.all(bounds > 0):
            raise InputError(f"clip must hold {J} positive bounds (one per level), got {bounds!r}")
    workers = default_workers() if workers is None else check_positive_int(workers, name="workers")
    row_bytes = 4 * (nfft // 2 + 1)
    if J * row_bytes <= SPECTRA_BYTES:
        powers, scale, sizes = _power_spectra(x, J, wavelet, shape, bounds, workers)
        gram = _half_spectrum_gram(powers, nfft)
        del powers
    else:
        group = max(1, SPECTRA_BYTES // row_bytes)
        group = -(-J // -(-J // group))  # the same number of groups, as even as they can be
        gram, scale, sizes = _grouped_gram(x, J, wavelet, shape, group, bounds, workers)
    M = np.minimum.outer(sizes, sizes).astype(np.float64)
    V = gram * np.outer(scale, scale) / (nfft * M**3)
    upper = np.triu_indices(J, 1)
    V.T[upper] = V[upper]  # exactly symmetric
    return V
