"""Compiled loops of the Haar MODWT pyramid (:mod:`stochmod.empirical.modwt`) and of the robust
wavelet variance (:mod:`stochmod.empirical.robust_wv`).

Each level reads the unscaled sums ``V_{j-1}`` once: the coefficient
``V_{j-1,t+s} - V_{j-1,t}`` (``2^j W_{j,t}`` up to the sign, ``s = 2^(j-1)``), its square
summed, and the next level's sums ``V_{j-1,t} + V_{j-1,t+s}``, per sample, with two loads and
one store. The loops are compiled by :func:`stochmod.core.jit.compiled`; with
``STOCHMOD_DISABLE_JIT=1`` the same functions run as plain Python. The sums of squares are
accumulated in several partial sums (``reassoc``), in an order set by the memory layout: the
callers pass contiguous arrays.
"""

from __future__ import annotations

import numpy as np

from stochmod.core.jit import compiled

__all__ = ["haar_level_coefficients", "haar_level_power_sums", "haar_pyramid_sums"]

_BLOCK = 4096  # samples per inner block of the robust pass (three float64 arrays in L1/L2)
_GROUP = 64  # coefficients per group of the robust pass's scan for those outside the core



@compiled
def _level(cur: np.ndarray, out: np.ndarray, own: int, size: int,
           step: int) -> float:  # pragma: no cover
    """``out[t] = cur[t] + cur[t + step]`` for t < size; return the sum of
    ``(cur[t + step] - cur[t])^2`` over t < own (<= size). `out` must not overlap `cur`."""
    a_ = cur[:size]
    b_ = cur[step : step + size]
    o = out[:size]
    acc = 0.0
    for t in range(own):
        a = a_[t]
        b = b_[t]
        acc += (b - a) * (b - a)
        o[t] = a + b
    for t in range(own, size):
        o[t] = a_[t] + b_[t]
    return acc


@compiled
def _sum_sq_diff(cur: np.ndarray, own: int, step: int) -> float:  # pragma: no cover
    """Sum of ``(cur[t + step] - cur[t])^2`` over t < own."""
    a_ = cur[:own]
    b_ = cur[step : step + own]
    acc = 0.0
    for t in range(own):
        d = b_[t] - a_[t]
        acc += d * d
    return acc


@compiled
def _last_level(cur: np.ndarray, out: np.ndarray, own: int, step: int,
                write: bool) -> float:  # pragma: no cover
    """Sum of ``(cur[t + step] - cur[t])^2`` over t < own and, if `write`,
    ``out[t] = cur[t] + cur[t + step]`` (`out` must not overlap `cur`)."""
    acc = _sum_sq_diff(cur, own, step)
    if write:
        a_ = cur[:own]
        b_ = cur[step : step + own]
        o = out[:own]
        for t in range(own):
            o[t] = a_[t] + b_[t]
    return acc


@compiled
def _level_in_place(v: np.ndarray, own: int, step: int, write: bool) -> float:  # pragma: no cover
    """Sum of ``(v[t + step] - v[t])^2`` over t < own and, if `write`, ``v[t] += v[t + step]``
    in place, in pieces of at most `step` samples: within a piece the written and the read
    samples do not overlap, so the loop runs on vectors."""
    acc = _sum_sq_diff(v, own, step)
    if write:
        for s in range(0, own, step):
            n = min(step, own - s)
            a_ = v[s : s + n]
            b_ = v[s + step : s + step + n]
            for t in range(n):
                a_[t] += b_[t]
    return acc


@compiled
def _sweep_block(src: np.ndarray, v: np.ndarray, n_valid: int, k: int, fused_last: bool,
                 last: bool, bufs: np.ndarray, s: int, e: int, tail: bool,
                 totals: np.ndarray) -> None:  # pragma: no cover
    """Haar levels ``1 .. k`` of the output samples ``[s, e)`` of a sweep (see
    :func:`haar_pyramid_sums`); the sums of squares are added to ``totals[:k]``. The `tail`
    block also owns the tails of the shallower levels. With `fused_last` (a sweep one level
    shorter than the one whose pieces fix the digits), level k's sum is taken by the loop of
    the sweep's inner levels, whose partial sums round as in that longer sweep, and its V is
    copied to `v` after it."""
    size = (n_valid if tail else e + 2**k - 1) - s  # samples of V_0 = the signal read
    for i in range(k):
        step = 2**i
        size -= step
        own = size if tail else e - s
        if i == k - 1 and not fused_last:  # own == e - s: the block's V_k goes to `v`
            if i == 0:
                totals[i] += _last_level(src[s:], v[s:], own, step, not last)
            else:
                totals[i] += _last_level(bufs[(i - 1) % 2], v[s:], own, step, not last)
        elif i == 0:
            totals[i] += _level(src[s:], bufs[0], own, size, step)
        else:
            totals[i] += _level(bufs[(i - 1) % 2], bufs[i % 2], own, size, step)
    if fused_last:
        v[s:e] = bufs[(k - 1) % 2, : e - s]


@compiled
def haar_pyramid_sums(src: np.ndarray, v: np.ndarray, levels: int, k: int, parted: int,
                      bufs: np.ndarray, chunk: int, totals: np.ndarray) -> None:  # pragma: no cover
    """Sums of the unscaled squared Haar coefficients ``(2^j W_j)^2`` of `src` (the signal) at
    levels ``j = 1 .. levels``, into ``totals[:levels]``.

    Each level's sum is the sum, in order, of the sums of its pieces: blocks of `chunk`
    coefficients from the start, the last piece running to the level's end ``M_j``. For the
    levels ``1 .. parted`` (those of the sweep that fixes the digits, ``k <= parted <= k + 1``)
    the last piece starts at ``T``, the last multiple of `chunk` below ``M_parted``; for the
    deeper ones at the last multiple of `chunk` below their own ``M_j``. Each piece's sum is
    taken by the loop a sweep of `parted` levels takes it with (the loop that also forms V
    below level `parted`, a plain sum from it on), so the digits do not depend on `k`.

    Levels ``1 .. k`` run as one sweep: each block of output samples (`chunk` of them, the
    last block from ``T`` on) is read once with its halo of ``2^k - 1`` samples, its k levels
    alternate between the two rows of `bufs` (each at least ``chunk + 2^parted - 1`` samples,
    or the signal's length), and its unscaled sums ``V_k`` go to `v` (length of `src`). Each
    deeper level j updates `v` in place, piece after piece, from ``V_{j-1}`` to ``V_j``; a
    piece runs as soon as the level above has written the samples it reads (``2^(j-1)`` past
    its end), so that the levels follow each other through memory a few blocks apart and `v`
    is read from cache. Every W and V value is the same floating-point operation as in a
    level-by-level pyramid.
    """
    n = src.size
    for i in range(levels):
        totals[i] = 0.0
    tail = (n - 2**parted) // chunk * chunk  # T: M_parted - 1 = n - 2^parted, rounded down
    deep = levels - k
    size = np.empty(deep + 1, dtype=np.int64)  # size[i]: samples of V_{k+i} (M_{k+i})
    last = np.empty(deep + 1, dtype=np.int64)  # last[i]: start of the last piece of level k+i
    done = np.zeros(deep + 1, dtype=np.int64)  # done[i]: samples of V_{k+i} written so far
    size[0] = n - (2**k - 1)
    for i in range(1, deep + 1):
        size[i] = size[i - 1] - 2 ** (k + i - 1)
        last[i] = tail if k + i <= parted else (size[i] - 1) // chunk * chunk
    for s in range(0, tail + 1, chunk):
        e = size[0] if s == tail else s + chunk
        _sweep_block(src, v, n, k, k < parted, deep == 0, bufs, s, e, s == tail, totals)
        done[0] = e
        for i in range(1, deep + 1):  # level k + i, step 2^(k+i-1)
            step = 2 ** (k + i - 1)
            while done[i] < size[i]:
                start = done[i]
                stop = size[i] if start == last[i] else start + chunk
                if stop + step > done[i - 1]:
                    break
                totals[k + i - 1] += _level_in_place(v[start:], stop - start, step, i < deep)
                done[i] = stop


@compiled
def haar_level_coefficients(v: np.ndarray, n_valid: int, step: int, factor: float,
                            update: bool, w_out: np.ndarray) -> float:  # pragma: no cover
    """One Haar level with its coefficients, in one pass over the unscaled sums
    ``V = v[:n_valid]``: ``w_out[t] = (V[t + step] - V[t]) * factor`` for the
    ``M = n_valid - step`` interior positions; returns the sum of ``(V[t + step] - V[t])^2``;
    if `update`, ``v[t]`` becomes ``V[t] + V[t + step]`` (t < M, the next level's sums),
    block by block through a buffer, so that the in-place update reads only old values."""
    m = n_valid - step
    acc = 0.0
    buf = np.empty(_BLOCK)
    for s in range(0, m, _BLOCK):
        e = min(s + _BLOCK, m)
        n = e - s
        a_ = v[s:e]  # slices indexed from 0: no wrap-around checks, so LLVM vectorises
        b_ = v[s + step : e + step]
        w_ = w_out[s:e]
        d_ = buf[:n]
        for t in range(n):
            a = a_[t]
            b = b_[t]
            d = b - a
            acc += d * d
            w_[t] = d * factor
            d_[t] = a + b
        if update:
            for t in range(n):
                a_[t] = d_[t]
    return acc


# without reassoc: with it LLVM vectorised the sums behind run-time checks on the buffers'
# addresses, so their last bits, and the robust WV's, followed the heap (about 1 call in
# 100); the sums in order are reproducible, and on this loop no slower
@compiled(fastmath=frozenset())
def haar_level_power_sums(src: np.ndarray, dst: np.ndarray, n_valid: int, step: int,
                          factor: float, core: float, sums: np.ndarray, big_idx: np.ndarray,
                          big_w: np.ndarray, sub_stride: int, left: np.ndarray,
                          right: np.ndarray) -> int:  # pragma: no cover
    """One Haar level of the robust estimator in one pass over ``src[:n_valid]`` (the
    unscaled sums ``V_{j-1}``).

    With ``w_t = (src[t + step] - src[t]) * factor`` and ``u = w^2``, accumulates
    ``sum u^p`` (p = 1..5) over ``u <= core`` into ``sums[1:6]`` (float64), records the index
    and value of the others in `big_idx` / `big_w` (as many as fit) and writes the next
    level's sums ``dst[t] = src[t] + src[t + step]``, block by block through a buffer, so
    that `dst` may be `src` itself (in place: a block is written back after it was read, and
    its lines are still in cache). Returns the number of coefficients above `core` (more than
    ``big_idx.size`` means some were not recorded).

    Also copies the next level's subsample for its start (``robust_wv._start``) while the
    block is in cache: ``left[k] = dst[k sub_stride]`` and
    ``right[k] = dst[k sub_stride + 2 step]`` for k < ``left.size``.
    """
    m = n_valid - step
    cap = big_idx.size
    nb = 0
    s1 = 0.0
    s2 = 0.0
    s3 = 0.0
    s4 = 0.0
    s5 = 0.0
    buf = np.empty(_BLOCK)
    sums_buf = np.empty(_BLOCK)
    for s in range(0, m, _BLOCK):
        e = min(s + _BLOCK, m)
        n = e - s
        a_ = src[s:e]  # slices indexed from 0: no wrap-around checks, so LLVM vectorises
        b_ = src[s + step : e + step]
        d_ = sums_buf[:n]
        w_ = buf[:n]
        for g in range(0, n, _GROUP):  # groups: only those with a coefficient outside are scanned
            h = min(g + _GROUP, n)
            outside = 0
            for t in range(g, h):
                a = a_[t]
                b = b_[t]
                d_[t] = a + b
                w = (b - a) * factor
                w_[t] = w
                u = w * w
                outside += u > core
                u = u if u <= core else 0.0
                u2 = u * u
                s1 += u
                s2 += u2
                s3 += u2 * u
                s4 += u2 * u2
                s5 += u2 * u2 * u
            if outside:
                for t in range(g, h):
                    w = w_[t]
                    if w * w > core:
                        if nb < cap:
                            big_idx[nb] = s + t
                            big_w[nb] = w
                        nb += 1
        out_ = dst[s:e]
        for t in range(n):
            out_[t] = d_[t]
        for pos, out in ((0, left), (2 * step, right)):  # subsample positions in [s, e)
            k = max(0, (s - pos + sub_stride - 1) // sub_stride)
            while k < out.size and k * sub_stride + pos < e:
                out[k] = d_[k * sub_stride + pos - s]
                k += 1
    sums[1] += s1
    sums[2] += s2
    sums[3] += s3
    sums[4] += s4
    sums[5] += s5
    return nb
