"""Double-double arithmetic (about 32 significant digits) for the AR root refinement and the
few residues whose double-precision evaluation cancels (Dekker 1971; Hida, Li & Bailey 2001).

Plain Python floats: the callers handle a handful of numbers (p roots, 30 levels).
"""

from __future__ import annotations

import math
from fractions import Fraction
from functools import lru_cache

__all__ = ["DD", "CDD", "dd_add", "dd_mul", "dd_neg", "cdd_mul", "haar_wv_dd"]

_SPLITTER = 134217729.0  # 2^27 + 1

#: A double-double number: the unevaluated sum hi + lo with |lo| <= ulp(hi) / 2.
DD = tuple[float, float]


def two_sum(a: float, b: float) -> DD:
    """``a + b`` exactly, as (rounded sum, error) (Knuth)."""
    s = a + b
    bb = s - a
    return s, (a - (s - bb)) + (b - bb)


def split(a: float) -> DD:
    """``a = hi + lo`` with hi, lo of 26 significant bits each (Dekker)."""
    c = _SPLITTER * a
    hi = c - (c - a)
    return hi, a - hi


def two_prod(a: float, b: float) -> DD:
    """``a * b`` exactly, as (rounded product, error) (Dekker)."""
    p = a * b
    ah, al = split(a)
    bh, bl = split(b)
    return p, ((ah * bh - p) + ah * bl + al * bh) + al * bl


def dd_add(x: DD, y: DD) -> DD:
    """Double-double sum."""
    s, e = two_sum(x[0], y[0])
    e += x[1] + y[1]
    return two_sum(s, e)


def dd_mul(x: DD, y: DD) -> DD:
    """Double-double product."""
    p, e = two_prod(x[0], y[0])
    e += x[0] * y[1] + x[1] * y[0]
    return two_sum(p, e)


def dd_neg(x: DD) -> DD:
    """Negation."""
    return -x[0], -x[1]



def cdd_mul(a: tuple[DD, DD], b: tuple[DD, DD]) -> tuple[DD, DD]:
    """Product of complex double-doubles given as (re, im) pairs."""
    re = dd_add(dd_mul(a[0], b[0]), dd_neg(dd_mul(a[1], b[1])))
    im = dd_add(dd_mul(a[0], b[1]), dd_mul(a[1], b[0]))
    return re, im


def dd_div(x: DD, y: DD) -> DD:
    """Double-double quotient (three correction steps)."""
    q1 = x[0] / y[0]
    r = dd_add(x, dd_neg(dd_mul((q1, 0.0), y)))
    q2 = r[0] / y[0]
    r = dd_add(r, dd_neg(dd_mul((q2, 0.0), y)))
    q3 = r[0] / y[0]
    return dd_add(two_sum(q1, q2), (q3, 0.0))


class CDD:
    """Complex double-double number (about 32 significant digits), for the few residues whose
    double-precision evaluation cancels."""

    __slots__ = ("re", "im")

    def __init__(self, re: DD | float, im: DD | float = 0.0) -> None:
        self.re = re if isinstance(re, tuple) else (float(re), 0.0)
        self.im = im if isinstance(im, tuple) else (float(im), 0.0)

    def __add__(self, o: CDD) -> CDD:
        return CDD(dd_add(self.re, o.re), dd_add(self.im, o.im))

    def __sub__(self, o: CDD) -> CDD:
        return CDD(dd_add(self.re, dd_neg(o.re)), dd_add(self.im, dd_neg(o.im)))

    def __mul__(self, o: CDD) -> CDD:
        re, im = cdd_mul((self.re, self.im), (o.re, o.im))
        return CDD(re, im)

    def __truediv__(self, o: CDD) -> CDD:
        den = dd_add(dd_mul(o.re, o.re), dd_mul(o.im, o.im))
        num = self * CDD(o.re, dd_neg(o.im))
        return CDD(dd_div(num.re, den), dd_div(num.im, den))

    def scale(self, k: float) -> CDD:
        """Multiply by a double k (exact for powers of two)."""
        return CDD(dd_mul(self.re, (k, 0.0)), dd_mul(self.im, (k, 0.0)))

    def __complex__(self) -> complex:
        return complex(self.re[0] + self.re[1], self.im[0] + self.im[1])


def dd_of(x: Fraction) -> DD:
    """A rational rounded to double-double."""
    hi = float(x)
    return hi, float(x - Fraction(hi))


@lru_cache(maxsize=256)
def haar_series_about_one(m: int, terms: int = 34) -> tuple[DD, ...]:
    """Coefficients c_k (k = 0..terms-1) of ``W_m(1 + w) = sum c_k w^(k+1)``, exact then rounded
    to double-double: ``N(z) = m (1 - z^2) - z (1 - z^m)(3 - z^m)`` has a triple zero at z = 1,
    which exact integer coefficients remove without cancellation."""
    def coef_n(k: int) -> int:  # coefficient of w^k in N(1 + w)
        e = lambda j: (3 if j == 0 else 0) - 4 * math.comb(m, j) + math.comb(2 * m, j)  # 3 - 4z^m + z^2m
        lin = -m * (2 if k == 1 else 1 if k == 2 else 0)
        return lin - (e(k) + (e(k - 1) if k >= 1 else 0))
    return tuple(dd_of(Fraction(coef_n(k + 3), 2 * m * m)) for k in range(terms))


def haar_wv_dd(z: CDD, w: CDD, anchor: float, m: int) -> CDD:
    """``W_m(z)`` in double-double, ``z = anchor + w``. About z = 1 with ``m |w| < 0.5``: the
    exact series in w; else the textbook form ``[m (1 - z^2) - z (1 - z^m)(3 - z^m)] /
    (2 m^2 (1 - z)^2)`` (m a power of two), which then keeps at least ~25 of its 32 digits."""
    if anchor > 0 and m * abs(complex(w)) < 0.5:
        coefs = haar_series_about_one(m)
        acc = CDD(coefs[-1])
        for c in coefs[-2::-1]:
            acc = acc * w + CDD(c)
        return acc * w
    one, three = CDD(1.0), CDD(3.0)
    zm = z
    k = 1
    while k < m:
        zm = zm * zm
        k *= 2
    a = one - zm
    omz = one - z
    num = (one - z * z).scale(float(m)) - z * a * (three - zm)
    return num / (omz * omz).scale(2.0 * m * m)


