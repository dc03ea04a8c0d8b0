"""Compiled passes of the eq. 17 covariance: the power spectrum of a real series
from the complex transform of its sample pairs, in natural or four-step order.

A real series ``x`` of even length ``N``, read as the ``H = N/2`` complex numbers
``z_m = x_{2m} + i x_{2m+1}``, has the discrete Fourier transform

    X_k = E_k + w^k O_k,    E_k = (Z_k + conj Z_{H-k}) / 2,    O_k = (Z_k - conj Z_{H-k}) / 2i,

with ``Z`` the transform of ``z`` (indices modulo ``H``) and ``w = exp(-2 pi i / N)``: ``E`` and
``O`` are the transforms of the even and odd samples (the classical split of a real FFT into a
complex one of half the length; Press et al., Numerical Recipes, 2nd ed., sec. 12.3). Since
``E_{H-k} = conj E_k``, ``O_{H-k} = conj O_k`` and ``w^{H-k} = -conj w^k``, one pair
``(Z_k, Z_{H-k})`` gives both powers, ``|X_k|^2 = |E_k + w^k O_k|^2`` and
``|X_{H-k}|^2 = |E_k - w^k O_k|^2``; ``k = 0`` pairs with the Nyquist frequency ``k = H``.

:func:`split_power` takes ``Z`` in the layout of a four-step transform
(:mod:`stochmod.empirical.four_step`): an ``(n1, n2)`` array ``C`` with ``C[k1, k2] = Z[k1 + n1 k2]``
(``H = n1 n2``), where the partner of ``(k1, k2)`` is ``(-k1 mod n1, n2 - 1 - k2)``, or
``(0, -k2 mod n2)`` in row 0, and writes the powers in that same order, which the Gram matrix
of eq. 17 does not see (it sums over all frequencies); with ``n1 = 1`` it is the natural order.
:func:`twiddle_block` is the four-step's multiply between its two passes of short transforms;
:func:`power_gram` the Gram matrix of the levels' float32 powers, :func:`bfloat16_gram` that of
powers stored as bfloat16 (:func:`to_bfloat16`) when float32 rows would not fit in memory;
:func:`scale_to_float32` turns a level's float64 coefficients into the float32 series of its
transform in the same buffer. One pass of :func:`split_power` reads each pair once and writes
both powers. The loops are compiled by :func:`stochmod.core.jit.compiled`; with
``STOCHMOD_DISABLE_JIT=1`` the same functions run as plain Python.
"""

from __future__ import annotations

import numpy as np

from stochmod.core.jit import compiled

__all__ = ["bfloat16_gram", "power_gram", "scale_to_float32", "split_power", "to_bfloat16",
           "twiddle_block"]


@compiled
def _pair(a: complex, b: complex, cr: float, ci: float) -> tuple[float, float]:  # pragma: no cover
    """``(|X_k|^2, |X_{H-k}|^2)`` from ``a = Z_k``, ``b = Z_{H-k}`` and ``(cr, ci)``, the
    (cos, sin) of ``2 pi k / N``; in double precision."""
    ar = np.float64(a.real)
    ai = np.float64(a.imag)
    br = np.float64(b.real)
    bi = np.float64(b.imag)
    er = ar + br  # 2 E_k
    ei = ai - bi
    o_r = ai + bi  # 2 O_k
    o_i = br - ar
    wr = cr * o_r + ci * o_i  # 2 w^k O_k, w^k = cr - i ci
    wi = cr * o_i - ci * o_r
    return (0.25 * ((er + wr) * (er + wr) + (ei + wi) * (ei + wi)),
            0.25 * ((er - wr) * (er - wr) + (ei - wi) * (ei - wi)))


@compiled
def split_power(c: np.ndarray, rows: np.ndarray, cols: np.ndarray, out: np.ndarray,
                first: int = 0, last: int = -1) -> None:  # pragma: no cover
    """Powers ``|X_k|^2`` of a real series of ``N = 2 H`` samples from ``c``, the transform of
    its sample pairs in four-step layout ``c[k1, k2] = Z[k1 + n1 k2]`` (shape ``(n1, n2)``,
    ``H = n1 n2``); ``out[k1 n2 + k2] = |X_{k1 + n1 k2}|^2`` and ``out[H]`` the Nyquist
    frequency's. `rows` and `cols` hold the (cos, sin) of ``pi k1 / H`` (``k1 < n1``) and of
    ``pi n1 k2 / H`` (``k2 < n2``), whose product is the twiddle ``w^k``. Double precision,
    stored in `out`'s precision. With `first` and `last`, only the row pairs
    ``(k1, n1 - k1)`` with ``first <= k1 < last`` are done (row 0 and the ends for
    ``k1 = 0``; ``last = -1``: up to ``n1 // 2``), so that disjoint ranges can run at once."""
    n1, n2 = c.shape
    stop1 = n1 // 2 + 1 if last < 0 else last
    flat = out[: n1 * n2].reshape(n1, n2)
    if first == 0:
        out[0], out[n1 * n2] = _pair(c[0, 0], c[0, 0], 1.0, 0.0)  # k = 0 and k = H
        for k2 in range(1, n2 // 2 + 1):  # row 0: k2 <-> n2 - k2
            flat[0, k2], flat[0, n2 - k2] = _pair(c[0, k2], c[0, n2 - k2],
                                                  np.float64(cols[k2, 0]),
                                                  np.float64(cols[k2, 1]))
    for k1 in range(max(first, 1), stop1):  # row k1 <-> row n1 - k1, reversed
        q1 = n1 - k1
        rc = np.float64(rows[k1, 0])
        rs = np.float64(rows[k1, 1])
        row, mirror = c[k1], c[q1]
        dst, dst_mirror = flat[k1], flat[q1]
        stop = n2 if k1 < q1 else (n2 + 1) // 2  # the middle row pairs with itself
        for k2 in range(stop):
            cc = np.float64(cols[k2, 0])
            cs = np.float64(cols[k2, 1])
            dst[k2], dst_mirror[n2 - 1 - k2] = _pair(row[k2], mirror[n2 - 1 - k2],
                                                     rc * cc - rs * cs, rc * cs + rs * cc)


@compiled
def twiddle_block(block: np.ndarray, b: int, low: np.ndarray,
                  high: np.ndarray) -> None:  # pragma: no cover
    """Multiply ``block[k1, j]``, columns ``m2 = b c + j`` of the four-step array after its
    first pass (``c = low.shape[1]``, ``j < c``), by ``exp(-2 pi i k1 m2 / H)``
    ``= low[k1, j] high[k1, b]`` (tables of ``exp(-2 pi i k1 j / H)`` and
    ``exp(-2 pi i k1 b c / H)``); the product in double precision."""
    n1, width = block.shape
    for k1 in range(n1):
        h = high[k1, b]
        hr = np.float64(h.real)
        hi = np.float64(h.imag)
        row = block[k1]
        lows = low[k1]
        for j in range(width):
            lr = np.float64(lows[j].real)
            li = np.float64(lows[j].imag)
            tr = lr * hr - li * hi
            ti = lr * hi + li * hr
            xr = np.float64(row[j].real)
            xi = np.float64(row[j].imag)
            row[j] = complex(xr * tr - xi * ti, xr * ti + xi * tr)


@compiled
def _block_products(block: np.ndarray, w: int, first: int,
                    gram: np.ndarray) -> None:  # pragma: no cover
    """``gram[a, b] += sum_f block[a, f] block[b, f]`` over the first `w` columns of the
    float64 `block`, for rows ``a >= first`` and ``b <= a``: each row is multiplied with four
    others at a time, so that one load of ``block[a, f]`` serves four products."""
    for a in range(first, block.shape[0]):
        ra = block[a]
        b = 0
        while b + 4 <= a + 1:
            r0, r1, r2, r3 = block[b], block[b + 1], block[b + 2], block[b + 3]
            c0 = c1 = c2 = c3 = 0.0
            for f in range(w):
                c0 += ra[f] * r0[f]
                c1 += ra[f] * r1[f]
                c2 += ra[f] * r2[f]
                c3 += ra[f] * r3[f]
            gram[a, b] += c0
            gram[a, b + 1] += c1
            gram[a, b + 2] += c2
            gram[a, b + 3] += c3
            b += 4
        for rest in range(b, a + 1):
            rb = block[rest]
            c0 = 0.0
            for f in range(w):
                c0 += ra[f] * rb[f]
            gram[a, rest] += c0


@compiled
def power_gram(powers: np.ndarray, width: int) -> np.ndarray:  # pragma: no cover
    """``G_ab = sum_f P_a(f) P_b(f)`` over the columns of the float32 rows `powers` (J, K),
    in double precision: blocks of `width` columns are promoted once to a float64 buffer
    (in L1 at J = 19, width = 128) and multiplied by :func:`_block_products`. Symmetric."""
    J, K = powers.shape
    gram = np.zeros((J, J))
    block = np.empty((J, width))
    for s in range(0, K, width):
        w = min(width, K - s)
        for a in range(J):
            for f in range(w):
                block[a, f] = powers[a, s + f]
        _block_products(block, w, 0, gram)
    for a in range(J):
        for b in range(a):
            gram[b, a] = gram[a, b]
    return gram


@compiled
def bfloat16_gram(rows: np.ndarray, first: int, start: int, stop: int,
                  width: int) -> np.ndarray:  # pragma: no cover
    """``G_ab = sum_f P_a(f) P_b(f)`` over columns ``start <= f < stop`` of the bfloat16 rows
    `rows` (J, K) (uint16: the upper half of each float32, :func:`to_bfloat16`), for rows
    ``a >= first`` and ``b <= a`` (the lower triangle of those rows, other entries zero): blocks
    of `width` columns are decoded to float64 and multiplied by :func:`_block_products`, the
    sums in double precision."""
    J = rows.shape[0]
    gram = np.zeros((J, J))
    block = np.empty((J, width))
    bits = np.empty(width, dtype=np.uint32)
    values = bits.view(np.float32)
    for s in range(start, stop, width):
        w = min(width, stop - s)
        for a in range(J):
            for f in range(w):
                bits[f] = np.uint32(rows[a, s + f]) << np.uint32(16)
            for f in range(w):
                block[a, f] = values[f]
        _block_products(block, w, first, gram)
    return gram


@compiled
def to_bfloat16(values: np.ndarray) -> None:  # pragma: no cover
    """Round the float32 array `values` to bfloat16 (8 significant bits, to nearest, ties to
    even) in place: the results, uint16 upper halves, fill the first half of its bytes
    (``values.view(np.uint16)[:values.size]``). Forward order, so that each write lands on
    bytes already read. Finite values only (a value within half a unit of the float32
    maximum rounds to infinity)."""
    bits = values.view(np.uint32)
    out = values.view(np.uint16)
    half = np.uint32(0x7FFF)
    one = np.uint32(1)
    shift = np.uint32(16)
    for i in range(bits.size):
        u = bits[i]
        out[i] = np.uint16((u + half + ((u >> shift) & one)) >> shift)


@compiled
def scale_to_float32(buf: np.ndarray, m: int, factor: float) -> None:  # pragma: no cover
    """``buf[:m] = float32(c[:m] * factor)`` with ``c = buf.view(np.float64)`` (the first
    ``8 m`` bytes hold m float64 values), in place, then ``buf[m:] = 0``: each product is in
    double precision and rounded once, as ``np.multiply(c, factor, out=buf)`` would give with a
    separate `c`. Forward order: each write lands on bytes already read."""
    c = buf.view(np.float64)
    for i in range(m):
        buf[i] = c[i] * factor
    for i in range(m, buf.size):
        buf[i] = 0.0
