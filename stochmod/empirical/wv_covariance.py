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
#: Bytes of level spectra held at once (512 MiB). Below it every level keeps its float32
#: spectrum (up to about 6e6 samples); above it (22 levels of 46 MB at 1.15e7 samples, 8 h at
#: 400 Hz) the spectra are kept as bfloat16, as many at a time as fit (:func:`_bfloat16_gram`).
SPECTRA_BYTES = 512 << 20


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


def _bfloat16_gram(
    x: np.ndarray, levels: int, wavelet: str, shape: tuple[int, int], group: int,
    clip: np.ndarray | None = None, workers: int = 1,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_half_spectrum_gram` of the level spectra stored as bfloat16, at most `group`
    at once: returns ``(gram, scale, sizes)``, the Gram matrix already doubled and corrected
    for the frequencies counted once.

    One FFT buffer serves every level: the pyramid writes W_j into it as float64, which
    :func:`~stochmod.empirical.spectrum_jit.scale_to_float32` turns in place into the float32
    series of the transform; the float32 powers land in two free rows of bfloat16 and are
    rounded in place into the first (:func:`~stochmod.empirical.spectrum_jit.to_bfloat16`).
    The levels are taken in groups of `group`, in order: one run of the pyramid stores its
    group's spectra, then gives each deeper level's row against them (its spectrum in the row
    after the group's) and, for the last level, its own entry; the next group runs the pyramid
    again from level 1, without transforming the levels before it. Transforms: J when
    ``group >= J - 1``. The transforms use `workers` threads each
    (:func:`~stochmod.empirical.four_step.transform`), the Gram two halves of the
    frequencies, on the same threads; the result does not depend on `workers`.
    """
    H = shape[0] * shape[1]
    width = H + 1
    row = width + width % 2  # even: two rows hold one float32 row
    gram = np.zeros((levels, levels))
    ends = np.zeros((levels, 2))
    scale = np.zeros(levels)
    sizes = np.empty(levels, dtype=np.int64)
    buf = np.empty(2 * H, dtype=np.float32)
    coef = buf.view(np.float64)  # H >= n >= M_1 values
    slots = np.empty((min(group, levels) + 2, row), dtype=np.uint16)
    tables = four_step.plan(*shape)
    halves = (0, width // 2, width)

    def level_gram(rows: np.ndarray, first: int) -> np.ndarray:
        parts = [(pool.submit if pool is not None else _now)(
            spectrum_jit.bfloat16_gram, rows, first, lo, hi, _GRAM_BLOCK)
            for lo, hi in zip(halves[:-1], halves[1:])]
        return parts[0].result() + parts[1].result()

    with (concurrent.futures.ThreadPoolExecutor(workers) if workers > 1
          else contextlib.nullcontext()) as pool:
        start = 0
        while start < levels:
            stop = min(start + group, levels)
            for j, sumsq, m in pyramid(x, levels, wavelet, coef):
                if j <= start:
                    continue
                if clip is not None:
                    w = np.clip(coef[:m], -clip[j - 1], clip[j - 1], out=coef[:m])
                    sumsq = float(np.dot(w, w))
                ms = sumsq / m
                scale[j - 1], sizes[j - 1] = ms, m
                spectrum_jit.scale_to_float32(buf, m, 1.0 / np.sqrt(ms) if ms > 0 else 0.0)
                slot = min(j, stop + 1) - 1 - start  # a group's own row, or the one after it
                landing = slots[slot : slot + 2].reshape(-1).view(np.float32)[:width]
                _split(four_step.transform(buf, tables, pool, workers), tables, landing, pool,
                       workers)
                spectrum_jit.to_bfloat16(landing)
                ends[j - 1] = [_decode(slots[slot, 0]), _decode(slots[slot, H])]
                if j == stop:
                    block = level_gram(slots[: stop - start], 0)
                    gram[start:stop, start:stop] = block + np.tril(block, -1).T
                elif j > stop:
                    g = stop - start
                    cross = level_gram(slots[: g + 1], g)[g]
                    gram[j - 1, start:stop] = gram[start:stop, j - 1] = cross[:g]
                    if j == levels == stop + 1:  # the last level alone: its own entry too
                        gram[j - 1, j - 1] = cross[g]
            start = stop if stop < levels - 1 else levels
    gram *= 2.0  # the conjugate half
    gram -= ends @ ends.T  # f = 0 and nfft / 2 appear once in the full spectrum
    return gram, scale, sizes


def _split(c: np.ndarray, tables: four_step.Plan, out: np.ndarray,
           pool: concurrent.futures.Executor | None, workers: int) -> None:
    """:func:`~stochmod.empirical.spectrum_jit.split_power` of the transform `c` into `out`,
    its row pairs in `workers` ranges on `pool` (the same powers as one call)."""
    pairs = tables.n1 // 2 + 1
    if pool is None or workers < 2 or pairs < 2 * workers:
        spectrum_jit.split_power(c, tables.rows, tables.cols, out)
        return
    edges = np.linspace(0, pairs, workers + 1).astype(int)
    runs = [pool.submit(spectrum_jit.split_power, c, tables.rows, tables.cols, out, int(lo), int(hi))
            for lo, hi in zip(edges[:-1], edges[1:])]
    for run in runs:
        run.result()


def _now(fn: Callable[..., np.ndarray], *args: object) -> concurrent.futures.Future[np.ndarray]:
    """`fn(*args)` run here, as a completed future."""
    future: concurrent.futures.Future[np.ndarray] = concurrent.futures.Future()
    future.set_result(fn(*args))
    return future


def _decode(half: np.uint16) -> float:
    """The float value of one bfloat16 (the upper half of a float32)."""
    return float(np.array([np.uint32(half) << np.uint32(16)], dtype=np.uint32).view(np.float32)[0])


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
    N = 2^20). When the spectra would exceed :data:`SPECTRA_BYTES`, each is rounded to
    bfloat16 (the upper half of its float32, to nearest even: relative error at most 2^-8)
    and as many are kept as fit the budget, the deeper levels transformed again for each
    further group (one group, J transforms, up to about 1.4e7 samples); one FFT buffer serves
    every level. Every product in the Gram sums is non-negative, so each entry of the result
    is within ``2^-7`` (0.8 %) of the float32 computation (measured: 0.4 % at most, 2e-4 in
    the median); the largest differences are at the deep levels, where the spectra are
    concentrated in few frequencies and the wavelet variance's own relative error, about
    ``sqrt(2^j / M_j)``, is one to two orders larger. Interval widths move by half of it.
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
        slot_bytes = 2 * (nfft // 2 + 1 + (nfft // 2 + 1) % 2)
        group = max(1, SPECTRA_BYTES // slot_bytes - 2)
        gram, scale, sizes = _bfloat16_gram(x, J, wavelet, shape, group, bounds, workers)
    M = np.minimum.outer(sizes, sizes).astype(np.float64)
    V = gram * np.outer(scale, scale) / (nfft * M**3)
    upper = np.triu_indices(J, 1)
    V.T[upper] = V[upper]  # exactly symmetric
    return V
