"""Haar wavelet variance of a geometric autocovariance, evaluated without cancellation.

A stationary process whose autocovariance is a sum of geometric terms
``gamma(t) = sum_k c_k z_k^|t|`` (|z_k| < 1, real or complex) has the Haar wavelet variance
``sum_k c_k W_m(z_k)`` at level j (m = 2^(j-1) samples per half filter), where

``W_m(z) = sum_{t=-(2m-1)}^{2m-1} a_m(|t|) z^|t|``

and ``a_m`` is the Haar kernel (:func:`stochmod.theory.haar_kernel`). Summing the geometric
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

from stochmod.errors import InputError

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


def _power_series(coefs: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``sum_k coefs[k] x^k`` for |x| < 1 (a matrix of powers: one vectorised product
    instead of a Python loop over the coefficients, which dominated an optimiser's calls)."""
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
    """Haar kernel ``a_m(t)`` (see :func:`stochmod.theory.haar_kernel`) at integer lags ``t >= 0``.

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
    first-order Gauss-Markov process inside an optimiser (same formulas as
    :func:`haar_wv_geometric` and :func:`haar_wv_geometric_dlog`, without the complex and
    sign machinery). Falls back to them when ``z = e^{-u} < 1e-3``.

    Parameters
    ----------
    u : float
        ``-log z > 0`` (``beta / freq`` for a GM process).
    m : ndarray of float
        Samples per half Haar filter (``2^(j-1)``).
    """
    if not u > 0 or not math.isfinite(u):
        raise InputError(f"u must be a positive finite number, got {u!r}")
    if u > -_SMALL_Z_LOG:
        return haar_wv_geometric(-u, m), -haar_wv_geometric_dlog(-u, m)
    m = np.asarray(m, dtype=np.float64)
    x = m * u
    sh = math.sinh(0.5 * u)
    smi = float(_sinh_minus_id(np.array([u]))[0])
    w = (2.0 * m * smi + _g(x)) / (8.0 * m * m * sh * sh)
    a = -np.expm1(-x)
    dw = 1.0 / (2.0 * m) + a * a / (4.0 * m * sh * sh) - w / math.tanh(0.5 * u)
    return w, dw


def haar_wv_positive_rows(u: np.ndarray, m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`haar_wv_positive` for many ``u`` at once: row k of each result is, bit for bit,
    ``haar_wv_positive(u[k], m)`` (an optimizer's model with several Gauss-Markov terms, or a
    screen of many candidate points, in one call).

    The elementwise steps run on the whole (K, J) grid; the two power series, whose matrix
    products round differently with the number of rows, are summed row by row with the same
    shapes as the one-``u`` function, so the digits do not depend on K.

    Parameters
    ----------
    u : ndarray of float, shape (K,)
        ``-log z > 0`` per row (``beta / freq`` for Gauss-Markov processes).
    m : ndarray of float, shape (J,)
        Samples per half Haar filter (``2^(j-1)``).

    Returns
    -------
    W, dW_du : ndarray, shape (K, J)
        ``W_m(e^{-u})`` and ``dW/du`` (dimensionless).
    """
    u = np.asarray(u, dtype=np.float64).reshape(-1)
    m = np.asarray(m, dtype=np.float64).reshape(-1)
    us = u.tolist()
    for v in us:
        if not (v > 0 and math.isfinite(v)):
            raise InputError(f"u must be positive finite numbers, got {v!r}")
    if any(v > -_SMALL_Z_LOG for v in us):  # z < 1e-3: the polynomial path, row by row
        w = np.empty((u.size, m.size))
        dw = np.empty((u.size, m.size))
        far = [k for k, v in enumerate(us) if v > -_SMALL_Z_LOG]
        for k in far:
            w[k], dw[k] = haar_wv_positive(us[k], m)
        near = [k for k, v in enumerate(us) if not v > -_SMALL_Z_LOG]
        if near:
            w[near], dw[near] = haar_wv_positive_rows(u[near], m)
        return w, dw
    m2, m8, inv2m, m4 = _m_constants(m.tobytes())
    x = u[:, None] * m
    # sinh(u) - u: the series where u < 1, as _sinh_minus_id does for one value (the cube
    # and the product are elementwise: taken for every row at once)
    smi = np.sinh(u) - u
    uu, u3 = u * u, u**3
    for i, v in enumerate(us):
        if v < 1.0:
            smi[i] = float(u3[i]) * float(_power_series(_S_COEFS, uu[i : i + 1])[0])
    # g(x): the direct form, then the series where x < 1 (row by row, as _g does for one u)
    e = np.exp(-x)
    g = 2.0 * x - 3.0 + 4.0 * e - e * e
    small = x < 1.0
    xs = x[small]  # row after row
    if xs.size:
        ends = np.cumsum(small.sum(axis=1)).tolist()
        series = [_power_series(_G_COEFS, xs[a:b]) for a, b in zip([0, *ends[:-1]], ends) if b > a]
        g[small] = xs**3 * np.concatenate(series)
    sh = np.array([math.sinh(0.5 * v) for v in us])[:, None]
    th = np.array([math.tanh(0.5 * v) for v in us])[:, None]
    w = (m2 * smi[:, None] + g) / (m8 * sh * sh)
    a = -np.expm1(-x)
    dw = inv2m + a * a / (m4 * sh * sh) - w / th
    return w, dw


@functools.lru_cache(maxsize=8)
def _m_constants(m_bytes: bytes) -> tuple[np.ndarray, ...]:
    """``2m``, ``8 m m``, ``1 / (2m)`` and ``4m``, computed as :func:`haar_wv_positive`
    computes them (the same operations, so the same digits), once per set of half-widths."""
    m = np.frombuffer(m_bytes, dtype=np.float64)
    out = (2.0 * m, 8.0 * m * m, 1.0 / (2.0 * m), 4.0 * m)
    for a in out:  # shared by every call
        a.flags.writeable = False
    return out
    un = u[near]
    x = un[:, None] * m
    # sinh(u) - u: the series where u < 1, as _sinh_minus_id does for one value
    smi = np.sinh(un) - un
    for i in np.flatnonzero(un < 1.0):
        us = un[i : i + 1]
        smi[i] = (us**3 * _power_series(_S_COEFS, us * us))[0]
    # g(x): the direct form, then the series where x < 1, row by row as _g does
    e = np.exp(-x)
    g = 2.0 * x - 3.0 + 4.0 * e - e * e
    small = x < 1.0
    for i in np.flatnonzero(small.any(axis=1)):
        xs = x[i][small[i]]
        g[i, small[i]] = xs**3 * _power_series(_G_COEFS, xs)
    half = [0.5 * float(v) for v in un]
    sh = np.array([math.sinh(h) for h in half])[:, None]
    th = np.array([math.tanh(h) for h in half])[:, None]
    wn = (2.0 * m * smi[:, None] + g) / (8.0 * m * m * sh * sh)
    a = -np.expm1(-x)
    w[near] = wn
    dw[near] = 1.0 / (2.0 * m) + a * a / (4.0 * m * sh * sh) - wn / th
    return w, dw
