"""Haar wavelet variance of a geometric autocovariance, evaluated without cancellation.

A stationary process whose autocovariance is a sum of geometric terms
``gamma(t) = sum_k c_k z_k^|t|`` (|z_k| < 1, real or complex) has the Haar wavelet variance
``sum_k c_k W_m(z_k)`` at level j (m = 2^(j-1) samples per half filter), where

``W_m(z) = sum_{t=-(2m-1)}^{2m-1} a_m(|t|) z^|t|``

and ``a_m`` is the Haar kernel (:func:`stochmod.core.theory.haar_kernel`). Summing the geometric
series gives the textbook closed form

``W_m(z) = [m (1 - z^2) - z (1 - z^m) (3 - z^m)] / (2 m^2 (1 - z)^2)``,

whose numerator vanishes to third order as z -> 1: at ``z = exp(-1e-8)`` every term is
O(1e-8) and the result O(1e-24), so the textbook form (the R gmwm package's, among others)
loses all digits for slow processes. With ``z = sign * exp(-u)`` the same function is

- ``sign = +1``: ``W = [2m (sinh u - u) + g(m u)] / (8 m^2 sinh^2(u/2))`` with
  ``g(x) = 2x - 3 + 4 e^{-x} - e^{-2x}``;
- ``sign = -1``: ``W = [2m sinh u + (1 - e^{-mu})(3 - e^{-mu})] / (8 m^2 cosh^2(u/2))`` for even m
  (``(1 + e^{-mu})(3 + e^{-mu})`` for odd m), with ``1 - e^{-mu} = -expm1(-mu)``.

For real u > 0 every part is positive, so nothing cancels; ``sinh u - u`` and ``g`` are taken
from their Taylor series where their arguments are small (|.| < 1), where direct evaluation
would cancel. For |z| < 1e-3 the polynomial itself is summed (its terms decay like |z|^t).

:func:`haar_wv_geometric_parts` splits ``W_m = L_m + R_m`` into the part that does not decay
with the powers of z, ``L_m(z) = (1 + z) / (2m (1 - z))`` (summed over a process's geometric
terms it gives the long-run variance over 2m), and the rest
``R_m(z) = -z (1 - z^m)(3 - z^m) / (2 m^2 (1 - z)^2)``, both free of cancellation. For a sum of
geometric terms whose coefficients are large and nearly cancel (complex roots close to the
unit circle, at deep levels) ``LRV / (2m) + sum_k c_k R_m(z_k)`` keeps the digits that
``sum_k c_k W_m(z_k)`` loses.
Working from ``u = -log z`` rather than from z also keeps the input exact: a first-order
Gauss-Markov process gives ``u = beta / freq`` with no rounding of ``exp(-beta/freq)``.
"""

from __future__ import annotations

import functools
import math
from fractions import Fraction

import numpy as np
from numpy.typing import ArrayLike

from stochmod.core.errors import InputError
from stochmod.core.jit import AVAILABLE as _JIT
from stochmod.core.jit import compiled

__all__ = [
    "WV_PEAK_X",
    "AV_PEAK_VALUE",
    "haar_kernel_value",
    "haar_wv_geometric",
    "haar_wv_geometric_dlog",
    "haar_wv_geometric_parts",
    "haar_wv_positive",
    "haar_wv_positive_rows",
    "log1p_complex",
    "positive_rows_kernel",
    "POSITIVE_ROWS_KERNEL_MAX_U",
]

#: ``m u`` at which the Haar WV of a geometric autocovariance ``exp(-u |h|)`` peaks over the
#: half-width m (slow limit): the maximiser of ``g(x) / x^2``, ``g(x) = 2x - 3 + 4e^-x - e^-2x``
#: (the Allan-variance peak at tau = 1.89 Tc of a first-order Gauss-Markov process).
WV_PEAK_X = 1.8926178329250188
#: ``g(WV_PEAK_X) / WV_PEAK_X^2``: that Allan-variance peak over the stationary variance.
AV_PEAK_VALUE = 0.38113865810244997

# Taylor coefficients: sinh(u) - u = u^3 sum_k u^(2k) / (2k+3)!  and
# g(x) = 2x - 3 + 4 e^-x - e^-2x = x^3 sum_n (-1)^n (4 - 2^n) / n! x^(n-3), n >= 3.
_S_COEFS = np.array([1.0 / math.factorial(2 * k + 3) for k in range(12)])
_G_COEFS = np.array([float(Fraction((-1) ** n * (4 - 2**n), math.factorial(n))) for n in range(3, 34)])
_EXPONENTS = np.arange(max(_S_COEFS.size, _G_COEFS.size), dtype=np.float64)
_POLY_TERMS = 7  # |z| < 1e-3: terms up to z^6 leave < 1e-18 relative
_SMALL_Z_LOG = math.log(1e-3)
#: Up to this many rows, :func:`haar_wv_positive_rows` checks ``u`` as plain floats.
_FEW_ROWS = 16


def _power_series(coefs: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``sum_k coefs[k] x^k`` for |x| < 1 (a matrix of powers: one vectorised product,
    where a Python loop over the coefficients would dominate an optimiser's calls)."""
    return np.power.outer(x, _EXPONENTS[: coefs.size]) @ coefs


def _sinh_minus_id(u: np.ndarray) -> np.ndarray:
    """``sinh(u) - u`` without cancellation (series for |u| < 1)."""
    small = np.abs(u) < 1.0
    out = np.sinh(u) - u
    if np.any(small):
        us = u[small]
        out[small] = us**3 * _power_series(_S_COEFS, us * us)
    return out


def _g(x: np.ndarray) -> np.ndarray:
    """``g(x) = 2x - 3 + 4 exp(-x) - exp(-2x)`` without cancellation (series for |x| < 1)."""
    small = np.abs(x) < 1.0
    with np.errstate(over="ignore", invalid="ignore"):
        e = np.exp(-np.where(small, 1.0, x))
        out = 2.0 * x - 3.0 + 4.0 * e - e * e
    if np.any(small):
        xs = x[small]
        out[small] = xs**3 * _power_series(_G_COEFS, xs)
    return out


def _two_square(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``x^2`` as an unevaluated sum hi + lo, exactly (Dekker's splitting)."""
    c = 134217729.0 * x
    hi = c - (c - x)
    lo = x - hi
    sq = x * x
    return sq, ((hi * hi - sq) + 2.0 * hi * lo) + lo * lo


def log1p_complex(w: ArrayLike) -> np.ndarray:
    """``log(1 + w)`` for complex `w`, accurate for small |w| (numpy's complex log1p loses the
    real part when |1 + w| is close to 1).

    The real part is ``log1p(2a + a^2 + b^2) / 2`` (w = a + ib) with the squares formed exactly,
    so it keeps its relative accuracy even when ``|1 + w| = 1 - 1e-17``.
    """
    w = np.asarray(w, dtype=np.complex128)
    a, b = w.real, w.imag
    bh, bl = _two_square(b)
    ah, al = _two_square(a)
    t = (2.0 * a + bh) + (ah + (bl + al))
    return 0.5 * np.log1p(t) + 1j * np.arctan2(b, 1.0 + a)


def haar_kernel_value(t: ArrayLike, m: ArrayLike) -> np.ndarray:
    """Haar kernel ``a_m(t)`` (see :func:`stochmod.core.theory.haar_kernel`) at integer lags ``t >= 0``.

    ``(2m - 3t) / (4 m^2)`` for ``t <= m``, ``-(2m - t) / (4 m^2)`` for ``m <= t < 2m``, 0 beyond.
    """
    t = np.asarray(t, dtype=np.float64)
    m = np.asarray(m, dtype=np.float64)
    a = np.where(t <= m, 2 * m - 3 * t, -(2 * m - t)) / (4.0 * m * m)
    return np.where(t < 2 * m, a, 0.0)


def _check_m(m: ArrayLike) -> np.ndarray:
    arr = np.asarray(m)
    if not np.issubdtype(arr.dtype, np.integer) and not (
        np.issubdtype(arr.dtype, np.floating) and np.all(np.isfinite(arr)) and np.all(arr == np.round(arr))
    ):
        raise InputError(f"m must be a positive integer (samples per half Haar filter), got {m!r}")
    if np.any(arr < 1):
        raise InputError(f"m must be >= 1, got {m!r}")
    return arr.astype(np.float64)


def _prepare(log_z: ArrayLike, m: ArrayLike, sign: ArrayLike):
    lz = np.asarray(log_z)
    if not (np.issubdtype(lz.dtype, np.number)):
        raise InputError(f"log_z must be numeric, got dtype {lz.dtype}")
    complex_in = np.iscomplexobj(lz)
    lz = lz.astype(np.complex128)
    s = np.asarray(sign, dtype=np.float64)
    if not np.all(np.abs(s) == 1):
        raise InputError(f"sign must be +1 or -1, got {sign!r}")
    # a complex log of a negative real number (imaginary part exactly +-pi): use the exact sign path
    on_axis = np.abs(lz.imag) == np.pi
    s = np.where(on_axis, -s, s)
    lz = np.where(on_axis, lz.real + 0j, lz)
    if np.any(np.isnan(lz)) or np.any(lz.real > 0) or np.any((lz.real == 0) & (lz.imag == 0)):
        raise InputError("log_z must have a negative real part (|z| < 1) or be -inf (z = 0)")
    mm = _check_m(m)
    u, mm, s = np.broadcast_arrays(-lz, mm, s)
    complex_out = complex_in and np.any(u.imag != 0)
    return u.astype(np.complex128).copy(), mm.copy(), s.copy(), complex_out


def _poly(u: np.ndarray, m: np.ndarray, s: np.ndarray, derivative: bool) -> np.ndarray:
    """Sum of the polynomial for |z| small: W = a0 + 2 sum a_t z^t; dW/du = -2 sum t a_t z^t."""
    with np.errstate(over="ignore", invalid="ignore"):
        z = s * np.exp(-u)
    z = np.where(np.isinf(u.real), 0.0, z)
    out = np.zeros_like(u) if derivative else haar_kernel_value(0, m) + 0j
    zt = np.ones_like(u)
    for t in range(1, _POLY_TERMS):
        zt = zt * z
        term = 2.0 * haar_kernel_value(t, m) * zt
        out = out - t * term if derivative else out + term
    return out


def _poly_positive(u: np.ndarray, m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``W`` and ``dW/du`` (K, J) of :func:`_poly` for real ``u`` (K,), finite and above
    ``-log 1e-3``, at the half-widths `m` (J,): the same operations in real arithmetic. The
    complex path's imaginary parts are all zero there, so its real parts are these roundings
    (``exp`` of ``-u + 0j`` is libm's ``exp(-u)``, which ``math.exp`` is), at a fraction of
    the cost of :func:`haar_wv_geometric` and :func:`haar_wv_geometric_dlog`."""
    z = np.array([math.exp(-v) for v in u.tolist()])[:, None]
    mm = np.broadcast_to(m, (u.size, m.size))
    w = haar_kernel_value(0, mm) + 0.0
    dw = np.zeros_like(w)
    zt = np.ones_like(w)
    for t in range(1, _POLY_TERMS):
        zt = zt * z
        term = 2.0 * haar_kernel_value(t, mm) * zt
        w = w + term
        dw = dw - t * term
    return w, dw


def haar_wv_geometric(log_z: ArrayLike, m: ArrayLike, *, sign: ArrayLike = 1) -> np.ndarray:
    """Haar wavelet variance per unit ``c`` of the autocovariance ``gamma(t) = c z^|t|``.

    Parameters
    ----------
    log_z : float or complex, array_like
        ``log z`` with negative real part (|z| < 1); ``-inf`` for z = 0. A complex logarithm of
        a negative real z (imaginary part exactly +-pi) is recognised and handled exactly.
    m : int, array_like
        Samples per half Haar filter, ``m = 2^(j-1)`` at level j (dimensionless).
    sign : {+1, -1}, array_like
        ``z = sign * exp(log_z)``: pass ``log|z|`` and ``sign=-1`` for a negative real z.

    Returns
    -------
    ndarray
        ``W_m(z) = sum_{|t| < 2m} a_m(|t|) z^|t|`` (dimensionless; multiply by c in u^2),
        broadcast over `log_z` and `m`; real unless `log_z` is complex off the real axis.
        Relative error a few ulps wherever the result is not itself a near-zero of the
        polynomial W_m (which only happens for complex z).
    """
    u, m, s, complex_out = _prepare(log_z, m, sign)
    out = np.empty_like(u)
    tiny = u.real > -_SMALL_Z_LOG
    out[tiny] = _poly(u[tiny], m[tiny], s[tiny], derivative=False)
    pos = ~tiny & (s > 0)
    if np.any(pos):
        up, mp = u[pos], m[pos]
        num = 2.0 * mp * _sinh_minus_id(up) + _g(mp * up)
        out[pos] = num / (8.0 * mp * mp * np.sinh(0.5 * up) ** 2)
    neg = ~tiny & (s < 0)
    if np.any(neg):
        un, mn = u[neg], m[neg]
        x = mn * un
        even = (mn % 2) == 0
        a = -np.expm1(-x)
        e = np.exp(-x)
        tail = np.where(even, a * (2.0 + a), (1.0 + e) * (3.0 + e))
        out[neg] = (2.0 * mn * np.sinh(un) + tail) / (8.0 * mn * mn * np.cosh(0.5 * un) ** 2)
    return out if complex_out else out.real.copy()


def haar_wv_geometric_dlog(log_z: ArrayLike, m: ArrayLike, *, sign: ArrayLike = 1) -> np.ndarray:
    """Derivative ``d W_m / d log|z|`` of :func:`haar_wv_geometric` (same arguments).

    With ``u = -log|z|`` (so ``d/d log z = -d/du``), for ``sign = +1``
    ``dW/du = 1/(2m) + (1 - e^{-mu})^2 / (4 m sinh^2(u/2)) - W coth(u/2)``, which has no
    catastrophic cancellation (the parts are within a small factor of the result except near
    the maximum of W over u, where the derivative itself crosses zero); for ``sign = -1``
    the analogous ``top'/(8 m^2 cosh^2(u/2)) - W tanh(u/2)``. For a first-order Gauss-Markov
    process ``u = beta / freq`` and ``d wv / d beta = -sigma2 / freq * dW/dlog z``.
    """
    u, m, s, complex_out = _prepare(log_z, m, sign)
    out = np.empty_like(u)
    tiny = u.real > -_SMALL_Z_LOG
    out[tiny] = _poly(u[tiny], m[tiny], s[tiny], derivative=True)
    rest = ~tiny
    if np.any(rest):
        ur, mr, sr = u[rest], m[rest], s[rest]
        w = haar_wv_geometric(-ur, mr, sign=sr).astype(np.complex128)
        x = mr * ur
        e = np.exp(-x)
        a = -np.expm1(-x)
        half = 0.5 * ur
        with np.errstate(invalid="ignore", divide="ignore"):
            d_pos = 1.0 / (2.0 * mr) + a * a / (4.0 * mr * np.sinh(half) ** 2) - w / np.tanh(half)
            even = (mr % 2) == 0
            top_d = 2.0 * mr * np.cosh(ur) + np.where(even, 2.0 * mr * e * (2.0 - e), -mr * e * (4.0 + 2.0 * e))
            d_neg = top_d / (8.0 * mr * mr * np.cosh(half) ** 2) - w * np.tanh(half)
        out[rest] = np.where(sr > 0, d_pos, d_neg)
    out = -out  # dW/dlog z = -dW/du
    return out if complex_out else out.real.copy()


def haar_wv_geometric_parts(log_z: ArrayLike, m: ArrayLike, *, sign: ArrayLike = 1
                            ) -> tuple[np.ndarray, np.ndarray]:
    """The two parts ``(L_m, R_m)`` of ``W_m = L_m + R_m`` (same arguments as
    :func:`haar_wv_geometric`; dimensionless).

    ``L_m(z) = (1 + z) / (2m (1 - z))`` and ``R_m(z) = -z (1 - z^m)(3 - z^m) / (2 m^2 (1 - z)^2)``,
    with ``1 - z^k`` from ``expm1``: each part is accurate to a few ulps (their sum cancels
    when ``m |log z|`` is small, which is what :func:`haar_wv_geometric` avoids).
    """
    u, m, s, complex_out = _prepare(log_z, m, sign)
    with np.errstate(over="ignore", invalid="ignore"):
        e = np.where(np.isinf(u.real), 0.0, np.exp(-u))
        em = np.where(np.isinf(u.real), 0.0, np.exp(-m * u))
        pos = s > 0
        one_minus_z = np.where(pos, -np.expm1(-u), 1.0 + e)
        odd = (m % 2) == 1
        one_minus_zm = np.where(pos | ~odd, -np.expm1(-m * u), 1.0 + em)
        one_minus_zm = np.where(np.isinf(u.real), 1.0, one_minus_zm)
        one_minus_z = np.where(np.isinf(u.real), 1.0, one_minus_z)
        z = s * e
        one_plus_z = np.where(pos, 1.0 + e, -np.expm1(-u))
        one_plus_z = np.where(np.isinf(u.real), 1.0, one_plus_z)
        lead = one_plus_z / (2.0 * m * one_minus_z)
        rest = -z * one_minus_zm * (2.0 + one_minus_zm) / (2.0 * m * m * one_minus_z**2)
    if complex_out:
        return lead, rest
    return lead.real.copy(), rest.real.copy()


def haar_wv_positive(u: float, m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``W_m(e^{-u})`` and ``dW/du`` for one real ``u > 0`` over many m: the fast path of a
    first-order Gauss-Markov process inside an optimiser, :func:`haar_wv_positive_rows` with
    one row (the same digits as that row of any call).

    Parameters
    ----------
    u : float
        ``-log z > 0`` (``beta / freq`` for a GM process).
    m : ndarray of float
        Samples per half Haar filter (``2^(j-1)``).
    """
    if not u > 0 or not math.isfinite(u):
        raise InputError(f"u must be a positive finite number, got {u!r}")
    w, dw = haar_wv_positive_rows(np.array([u], dtype=np.float64), m)
    return w[0], dw[0]


def haar_wv_positive_rows(u: np.ndarray, m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``W_m(e^{-u})`` and ``dW/du`` for many real ``u > 0`` at once (an optimizer's model with
    several Gauss-Markov terms, or a screen of many candidate points, in one call), at the
    Haar half-widths ``m = 1, 2, 4, ...``.

    The formula of :func:`haar_wv_geometric` for a positive z,
    ``W = [2m (sinh u - u) + g(m u)] / (8 m^2 sinh^2(u/2))``, with ``g`` at the doubled
    arguments from the exact recursion ``g(2x) = 2 g(x) + (1 - e^{-x})^3 (3 + e^{-x})``:
    with ``x_j = m_j u``, ``g(x_j) / m_j = g(u) + sum_{i<j} (1 - e^{-x_i})^3 (3 + e^{-x_i}) / m_{i+1}``,
    a cumulative sum of positive terms (no cancellation at any level, a few ulps). ``g(u)``
    and ``sinh u - u`` come from their Taylor series where u < 1. ``dW/du`` is
    :func:`haar_wv_geometric_dlog`'s ``1/(2m) + (1 - e^{-mu})^2 / (4 m sinh^2(u/2)) - W coth(u/2)``.
    Every step is elementwise on the (K, J) grid or a sum along one row, so row k is, bit for
    bit, the same whatever the other rows. Rows with ``z = e^{-u} < 1e-3`` go through
    :func:`haar_wv_geometric` (the polynomial).

    Parameters
    ----------
    u : ndarray of float, shape (K,)
        ``-log z > 0`` per row (``beta / freq`` for Gauss-Markov processes).
    m : ndarray of float, shape (J,)
        Samples per half Haar filter, ``m_j = 2^(j-1)`` for j = 1..J (other powers of two are
        taken from that ladder; other integers from :func:`haar_wv_geometric`).

    Returns
    -------
    W, dW_du : ndarray, shape (K, J)
        ``W_m(e^{-u})`` and ``dW/du`` (dimensionless).

    Raises
    ------
    InputError
        A `u` that is not a positive finite number, or an `m` below 1.
    """
    u = np.asarray(u, dtype=np.float64).reshape(-1)
    m = np.asarray(m, dtype=np.float64).reshape(-1)
    if u.size <= _FEW_ROWS:  # an optimizer's few rows: plain floats, no reductions
        us = u.tolist()
        if not all(0.0 < v < math.inf for v in us):
            bad = [v for v in us if not 0.0 < v < math.inf]
            raise InputError(f"u must be positive finite numbers, got {bad[0]!r}")
        high = max(us, default=1.0)
    else:
        low, high = (float(u.min()), float(u.max())) if u.size else (1.0, 1.0)
        if not (low > 0 and high < math.inf):
            bad = u[~((u > 0) & (u < math.inf))]
            raise InputError(f"u must be positive finite numbers, got {bad[0]!r}")
    m_bytes = m.tobytes()
    if high <= -_SMALL_Z_LOG and _full_ladder(m_bytes):  # the common case, at once
        w = np.empty((u.size, m.size))
        dw = np.empty((u.size, m.size))
        _positive_rows_jit(u, m, w, dw)
        return w, dw
    ladder = _ladder(m_bytes)
    if ladder is None:  # not powers of two: the general closed form, elementwise
        return haar_wv_geometric(-u[:, None], m), -haar_wv_geometric_dlog(-u[:, None], m)
    if ladder.size != m.size or ladder[-1] != m.size - 1:  # some of 1, 2, 4, ...: from all
        w, dw = haar_wv_positive_rows(u, 2.0 ** np.arange(int(ladder.max()) + 1))
        return w[:, ladder], dw[:, ladder]
    if high > -_SMALL_Z_LOG:  # z < 1e-3: the polynomial, elementwise too
        far = u > -_SMALL_Z_LOG
        w = np.empty((u.size, m.size))
        dw = np.empty((u.size, m.size))
        w[far], dw[far] = _poly_positive(u[far], m)
        if not far.all():
            w[~far], dw[~far] = haar_wv_positive_rows(u[~far], m)
        return w, dw
    w = np.empty((u.size, m.size))
    dw = np.empty((u.size, m.size))
    _positive_rows_jit(u, m, w, dw)
    return w, dw


@compiled
def _positive_rows_jit(u: np.ndarray, m: np.ndarray, w: np.ndarray,
                       dw: np.ndarray) -> None:  # pragma: no cover - compiled
    """The recursion of :func:`haar_wv_positive_rows` (0 < u <= -log 1e-3, m = 1, 2, 4, ...),
    row by row in one compiled pass: ``w`` and ``dw`` (K, J) are filled. (Few arguments: each
    costs numba's dispatcher a type check per call; the series' coefficients are constants.)"""
    s_coefs = _S_COEFS
    g_coefs = _G_COEFS
    inv2m = 0.5 / m  # exact: powers of two
    inv4m = 0.25 / m
    inv8m = 0.125 / m
    for k in range(u.size):
        v = u[k]
        if v < 1.0:  # g(u) and sinh(u) - u from their series
            acc = 0.0
            for i in range(g_coefs.size - 1, -1, -1):
                acc = acc * v + g_coefs[i]
            g = v**3 * acc
            acc = 0.0
            vv = v * v
            for i in range(s_coefs.size - 1, -1, -1):
                acc = acc * vv + s_coefs[i]
            smi = v**3 * acc
        else:
            e = math.exp(-v)
            g = 2.0 * v - 3.0 + 4.0 * e - e * e
            smi = math.sinh(v) - v
        half = 0.5 * v
        sh = math.sinh(half)
        sh2 = sh * sh
        th = math.tanh(half)
        term = 0.0
        for j in range(m.size):
            minus_x = v * -m[j]
            e = math.exp(minus_x)
            a = -math.expm1(minus_x)
            if j > 0:
                g += term * inv2m[j - 1]  # g(x_j) / m_j
            wj = (2.0 * smi + g) * inv8m[j] / sh2
            w[k, j] = wj
            dw[k, j] = inv2m[j] + a * a * inv4m[j] / sh2 - wj / th
            term = a * a * a * (3.0 + e)


#: The compiled recursion of :func:`haar_wv_positive_rows` for a family's compiled WV kernel
#: (:attr:`stochmod.core.vectorised_wv.VectorisedWV.haar_wv_kernel`): ``positive_rows_kernel(u, m, w, dw)``
#: fills ``W`` and ``dW/du`` (K, J) with that function's digits where ``0 < u <=``
#: :data:`POSITIVE_ROWS_KERNEL_MAX_U` and ``m = 1, 2, 4, ...``; None when ``STOCHMOD_DISABLE_JIT``
#: is set.
positive_rows_kernel = _positive_rows_jit if _JIT else None
#: The largest u (``z = e^-u >= 1e-3``) that :data:`positive_rows_kernel` covers.
POSITIVE_ROWS_KERNEL_MAX_U = -_SMALL_Z_LOG


@functools.lru_cache(maxsize=16)
def _ladder(m_bytes: bytes) -> np.ndarray | None:
    """``log2 m`` when every half-width m is a power of two, else None."""
    m = np.frombuffer(m_bytes, dtype=np.float64)
    if not np.all(np.isfinite(m) & (m >= 1)):
        raise InputError(f"m must be positive integers (samples per half Haar filter), got {m!r}")
    mantissa, exponent = np.frexp(m)
    return (exponent - 1).astype(np.intp) if np.all(mantissa == 0.5) else None


@functools.lru_cache(maxsize=16)
def _full_ladder(m_bytes: bytes) -> bool:
    """Whether the half-widths are exactly ``1, 2, 4, ..., 2^(J-1)`` (J >= 1)."""
    m = np.frombuffer(m_bytes, dtype=np.float64)
    return bool(m.size) and bool(np.array_equal(m, 2.0 ** np.arange(m.size)))
