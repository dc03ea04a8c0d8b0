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
:func:`power_gram` the Gram matrix of the levels' powers, :func:`split_power_cross` one level's
row of it against stored levels straight from its transform, without storing its powers. One
pass reads each pair once and writes both powers. The loops are compiled by :func:`stochmod.core.jit.compiled`; with
``STOCHMOD_DISABLE_JIT=1`` the same functions run as plain Python.
"""

from __future__ import annotations

import numpy as np

from stochmod.core.jit import compiled

__all__ = ["power_gram", "split_power", "split_power_cross", "twiddle_block"]


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
def split_power(c: np.ndarray, rows: np.ndarray, cols: np.ndarray,
                out: np.ndarray) -> None:  # pragma: no cover
    """Powers ``|X_k|^2`` of a real series of ``N = 2 H`` samples from ``c``, the transform of
    its sample pairs in four-step layout ``c[k1, k2] = Z[k1 + n1 k2]`` (shape ``(n1, n2)``,
    ``H = n1 n2``); ``out[k1 n2 + k2] = |X_{k1 + n1 k2}|^2`` and ``out[H]`` the Nyquist
    frequency's. `rows` and `cols` hold the (cos, sin) of ``pi k1 / H`` (``k1 < n1``) and of
    ``pi n1 k2 / H`` (``k2 < n2``), whose product is the twiddle ``w^k``. Double precision,
    stored in `out`'s precision."""
    n1, n2 = c.shape
    flat = out[: n1 * n2].reshape(n1, n2)
    out[0], out[n1 * n2] = _pair(c[0, 0], c[0, 0], 1.0, 0.0)  # k = 0 and k = H
    for k2 in range(1, n2 // 2 + 1):  # row 0: k2 <-> n2 - k2
        flat[0, k2], flat[0, n2 - k2] = _pair(c[0, k2], c[0, n2 - k2], np.float64(cols[k2, 0]),
                                              np.float64(cols[k2, 1]))
    for k1 in range(1, n1 // 2 + 1):  # row k1 <-> row n1 - k1, reversed
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
def power_gram(powers: np.ndarray, width: int) -> np.ndarray:  # pragma: no cover
    """``G_ab = sum_f P_a(f) P_b(f)`` over the columns of the float32 rows `powers` (J, K),
    in double precision: blocks of `width` columns are promoted once to a float64 buffer
    (in L1 at J = 19, width = 128), and each row is multiplied with four others at a time,
    so that one load of ``P_a(f)`` serves four products. Symmetric."""
    J, K = powers.shape
    gram = np.zeros((J, J))
    block = np.empty((J, width))
    for s in range(0, K, width):
        w = min(width, K - s)
        for a in range(J):
            for f in range(w):
                block[a, f] = powers[a, s + f]
        for a in range(J):
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
    for a in range(J):
        for b in range(a):
            gram[b, a] = gram[a, b]
    return gram



@compiled
def _weigh(p: float, stored: np.ndarray, i: int, acc: np.ndarray) -> None:  # pragma: no cover
    """``acc[a] += p stored[a, i]`` for every row a, `p` first rounded to float32 (the value a
    float32 spectrum holds)."""
    q = np.float64(np.float32(p))
    for a in range(stored.shape[0]):
        acc[a] += q * np.float64(stored[a, i])


@compiled
def split_power_cross(c: np.ndarray, rows: np.ndarray, cols: np.ndarray, stored: np.ndarray,
                      acc: np.ndarray) -> tuple[float, float]:  # pragma: no cover
    """:func:`split_power` of `c` multiplied with the float32 spectra `stored` (B, H + 1) in
    the same layout without being stored: ``acc[a] += sum_i P(i) stored[a, i]``, each power
    rounded to float32 first, in double precision. Returns the powers at ``k = 0`` and at the
    Nyquist frequency (the ends of the half spectrum)."""
    n1, n2 = c.shape
    h = n1 * n2
    first, last = _pair(c[0, 0], c[0, 0], 1.0, 0.0)
    _weigh(first, stored, 0, acc)
    _weigh(last, stored, h, acc)
    for k2 in range(1, n2 // 2 + 1):
        p, q = _pair(c[0, k2], c[0, n2 - k2], np.float64(cols[k2, 0]), np.float64(cols[k2, 1]))
        if k2 != n2 - k2:
            _weigh(p, stored, k2, acc)
        _weigh(q, stored, n2 - k2, acc)
    for k1 in range(1, n1 // 2 + 1):
        q1 = n1 - k1
        rc = np.float64(rows[k1, 0])
        rs = np.float64(rows[k1, 1])
        row, mirror = c[k1], c[q1]
        stop = n2 if k1 < q1 else (n2 + 1) // 2
        for k2 in range(stop):
            cc = np.float64(cols[k2, 0])
            cs = np.float64(cols[k2, 1])
            p, q = _pair(row[k2], mirror[n2 - 1 - k2], rc * cc - rs * cs, rc * cs + rs * cc)
            i, i_mirror = k1 * n2 + k2, q1 * n2 + n2 - 1 - k2
            if i != i_mirror:
                _weigh(p, stored, i, acc)
            _weigh(q, stored, i_mirror, acc)
    return np.float64(np.float32(first)), np.float64(np.float32(last))

