"""Root decomposition of a stationary AR(p) polynomial, for exact sums over its autocovariance.

The autocovariance of ``X_t = sum_i phi_i X_{t-i} + e_t`` (innovation variance sigma2) is

``gamma(h) = (sigma2 / 2 pi i) oint z^(h+p-1) / (P(z) P*(z)) dz``,

with ``P(z) = z^p - phi_1 z^(p-1) - ... - phi_p = prod_l (z - z_l)`` (roots |z_l| < 1) and
``P*(z) = prod_l (1 - z z_l)``. Any linear functional ``sum_h k(h) gamma(|h|)`` -- the Haar
wavelet variance, the autocovariance itself -- is therefore the sum of the residues of
``z^(p-1) K(z) / (P(z) P*(z))`` at the roots (times sigma2), ``K(z) = sum_h k(h) z^|h|``.

Accuracy measures:

- isolated roots are refined by Newton's method with P evaluated in double-double
  arithmetic, so they are the roots of the polynomial with the *given* binary coefficients
  to ~1e-30; from them ``|z|^2 - 1`` (which sets ``1 - z z_bar``, the size of the residues) and
  ``u = -log z`` are formed with their relative accuracy intact even for |z| = 1 - 1e-12.
- each root is also stored as ``z = anchor + w`` with ``anchor`` in {+1, -1, 0} (the nearest of
  +-1 when within 0.5): differences ``z_k - z_l`` and products ``1 - z_k z_l`` are formed from w
  without cancelling against the anchor.
- near-repeated roots make the individual residues large and of opposite signs (and a double
  root is only known to sqrt(eps)). Roots are grouped by single linkage when
  ``|z_k - z_l| < CLUSTER_ETA * min(1 - |z_k|, 1 - |z_l|, 1)``; a group's summed residue is the
  contour integral over a circle around it, by the trapezoidal rule (error geometric in the
  number of nodes), with the group's factor polynomial taken from the exactly rounded Taylor
  coefficients of P about the anchor: it depends only on symmetric functions of the group,
  which are well conditioned where the roots are not. The radius is as large as the other
  singularities allow (cancellation grows as it shrinks) but no larger than the scale 1/rate
  on which the kernel's powers z^rate vary, unless those powers are negligible on the circle.
  Exactly repeated roots are a group like any other.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from fractions import Fraction
from functools import lru_cache

import attrs
import numpy as np

__all__ = ["ARRoots", "ar_roots", "CLUSTER_ETA"]

#: Linkage threshold relative to the distance to the unit circle (see module docstring).
CLUSTER_ETA = 0.05
_ANCHOR_RADIUS = 0.5

KernelFn = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]

# ----------------------------------------------------------------------------- double-double
_SPLITTER = 134217729.0  # 2^27 + 1


def _two_sum(a: float, b: float) -> tuple[float, float]:
    s = a + b
    bb = s - a
    return s, (a - (s - bb)) + (b - bb)


def _split(a: float) -> tuple[float, float]:
    c = _SPLITTER * a
    hi = c - (c - a)
    return hi, a - hi


def _two_prod(a: float, b: float) -> tuple[float, float]:
    p = a * b
    ah, al = _split(a)
    bh, bl = _split(b)
    return p, ((ah * bh - p) + ah * bl + al * bh) + al * bl


def _dd_add(x: tuple[float, float], y: tuple[float, float]) -> tuple[float, float]:
    s, e = _two_sum(x[0], y[0])
    e += x[1] + y[1]
    return _two_sum(s, e)


def _dd_mul(x: tuple[float, float], y: tuple[float, float]) -> tuple[float, float]:
    p, e = _two_prod(x[0], y[0])
    e += x[0] * y[1] + x[1] * y[0]
    return _two_sum(p, e)


def _dd_neg(x: tuple[float, float]) -> tuple[float, float]:
    return -x[0], -x[1]


DD = tuple[float, float]


def _cdd_mul(a: tuple[DD, DD], b: tuple[DD, DD]) -> tuple[DD, DD]:
    re = _dd_add(_dd_mul(a[0], b[0]), _dd_neg(_dd_mul(a[1], b[1])))
    im = _dd_add(_dd_mul(a[0], b[1]), _dd_mul(a[1], b[0]))
    return re, im


def _poly_dd(coef: np.ndarray, z: tuple[DD, DD]) -> complex:
    """``sum coef_i z^(p-i)`` (highest first) in complex double-double, rounded to complex."""
    v: tuple[DD, DD] = ((float(coef[0]), 0.0), (0.0, 0.0))
    for c in coef[1:]:
        v = _cdd_mul(v, z)
        v = (_dd_add(v[0], (float(c), 0.0)), v[1])
    return complex(v[0][0] + v[0][1], v[1][0] + v[1][1])


def _refine(coef: np.ndarray, z0: complex, guard: float) -> tuple[DD, DD]:
    """Newton on P with double-double residuals; returns z as (re, im) double-doubles. A real
    start stays real. Keeps z0 if an iterate leaves the disc of radius `guard` about it."""
    real = z0.imag == 0
    der_coef = np.polyder(coef)
    z: tuple[DD, DD] = ((z0.real, 0.0), (z0.imag, 0.0))
    for _ in range(12):
        val = _poly_dd(coef, z)
        zc = complex(z[0][0] + z[0][1], z[1][0] + z[1][1])
        der = complex(np.polyval(der_coef, zc))
        if der == 0 or not np.isfinite(val):
            break
        step = val / der
        if real:
            step = complex(step.real, 0.0)
        z = (_dd_add(z[0], (-step.real, 0.0)), _dd_add(z[1], (-step.imag, 0.0)))
        znew = complex(z[0][0] + z[0][1], z[1][0] + z[1][1])
        if not np.isfinite(znew) or abs(znew - z0) > guard:
            return (z0.real, 0.0), (z0.imag, 0.0)
        if abs(step) <= 1e-31 * max(abs(znew), 1e-300):
            break
    return z


def _abs2_minus_one(z: tuple[DD, DD]) -> float:
    """``|z|^2 - 1`` from a double-double z, accurate to a few ulps of the result."""
    acc = _dd_add(_dd_mul(z[0], z[0]), _dd_mul(z[1], z[1]))
    acc = _dd_add(acc, (-1.0, 0.0))
    return acc[0] + acc[1]


def _dd_div(x: DD, y: DD) -> DD:
    q1 = x[0] / y[0]
    r = _dd_add(x, _dd_neg(_dd_mul((q1, 0.0), y)))
    q2 = r[0] / y[0]
    r = _dd_add(r, _dd_neg(_dd_mul((q2, 0.0), y)))
    q3 = r[0] / y[0]
    return _dd_add(_two_sum(q1, q2), (q3, 0.0))


class _CDD:
    """Complex double-double number (about 32 significant digits), for the few residues whose
    double-precision evaluation cancels."""

    __slots__ = ("re", "im")

    def __init__(self, re: DD | float, im: DD | float = 0.0) -> None:
        self.re = re if isinstance(re, tuple) else (float(re), 0.0)
        self.im = im if isinstance(im, tuple) else (float(im), 0.0)

    def __add__(self, o: _CDD) -> _CDD:
        return _CDD(_dd_add(self.re, o.re), _dd_add(self.im, o.im))

    def __sub__(self, o: _CDD) -> _CDD:
        return _CDD(_dd_add(self.re, _dd_neg(o.re)), _dd_add(self.im, _dd_neg(o.im)))

    def __mul__(self, o: _CDD) -> _CDD:
        re, im = _cdd_mul((self.re, self.im), (o.re, o.im))
        return _CDD(re, im)

    def __truediv__(self, o: _CDD) -> _CDD:
        den = _dd_add(_dd_mul(o.re, o.re), _dd_mul(o.im, o.im))
        num = self * _CDD(o.re, _dd_neg(o.im))
        return _CDD(_dd_div(num.re, den), _dd_div(num.im, den))

    def scale(self, k: float) -> _CDD:
        """Multiply by a double k (exact for powers of two)."""
        return _CDD(_dd_mul(self.re, (k, 0.0)), _dd_mul(self.im, (k, 0.0)))

    def __complex__(self) -> complex:
        return complex(self.re[0] + self.re[1], self.im[0] + self.im[1])


def _dd_of(x: Fraction) -> DD:
    hi = float(x)
    return hi, float(x - Fraction(hi))


@lru_cache(maxsize=256)
def _haar_series_about_one(m: int, terms: int = 34) -> tuple[DD, ...]:
    """Coefficients c_k (k = 0..terms-1) of ``W_m(1 + w) = sum c_k w^(k+1)``, exact then rounded
    to double-double: ``N(z) = m (1 - z^2) - z (1 - z^m)(3 - z^m)`` has a triple zero at z = 1,
    which exact integer coefficients remove without cancellation."""
    def coef_n(k: int) -> int:  # coefficient of w^k in N(1 + w)
        e = lambda j: (3 if j == 0 else 0) - 4 * math.comb(m, j) + math.comb(2 * m, j)  # 3 - 4z^m + z^2m
        lin = -m * (2 if k == 1 else 1 if k == 2 else 0)
        return lin - (e(k) + (e(k - 1) if k >= 1 else 0))
    return tuple(_dd_of(Fraction(coef_n(k + 3), 2 * m * m)) for k in range(terms))


def _haar_wv_dd(z: _CDD, w: _CDD, anchor: float, m: int) -> _CDD:
    """``W_m(z)`` in double-double, ``z = anchor + w``. About z = 1 with ``m |w| < 0.5``: the
    exact series in w; else the textbook form ``[m (1 - z^2) - z (1 - z^m)(3 - z^m)] /
    (2 m^2 (1 - z)^2)`` (m a power of two), which then keeps at least ~25 of its 32 digits."""
    if anchor > 0 and m * abs(complex(w)) < 0.5:
        coefs = _haar_series_about_one(m)
        acc = _CDD(coefs[-1])
        for c in coefs[-2::-1]:
            acc = acc * w + _CDD(c)
        return acc * w
    one, three = _CDD(1.0), _CDD(3.0)
    zm = z
    k = 1
    while k < m:
        zm = zm * zm
        k *= 2
    a = one - zm
    omz = one - z
    num = (one - z * z).scale(float(m)) - z * a * (three - zm)
    return num / (omz * omz).scale(2.0 * m * m)


# ----------------------------------------------------------------------------- decomposition
@attrs.frozen
class ARRoots:
    """Roots of an AR polynomial in anchored form, grouped for residue sums.

    Attributes
    ----------
    phi : tuple of float
        The AR coefficients.
    anchor : ndarray of float
        Per root: +1, -1 or 0.
    w : ndarray of complex
        Per root: ``z - anchor``.
    sign, u : ndarray
        Per root: ``z = sign * exp(-u)`` (sign +-1 real; u complex with accurate real part).
    abs2m1 : ndarray of float
        Per root: ``|z|^2 - 1`` (negative), accurate to a few ulps for isolated roots.
    partner : ndarray of int
        Per root: index of its complex conjugate (itself for a real root).
    groups : tuple of tuple of int
        Indices of the roots in each group (singletons for isolated roots).
    factors : tuple
        Per group: None for a singleton, else the coefficients (lowest first, monic) of
        ``prod_{l in group} (w - w_l)`` in the group's shifted variable.
    """

    phi: tuple[float, ...]
    anchor: np.ndarray
    w: np.ndarray
    sign: np.ndarray
    u: np.ndarray
    abs2m1: np.ndarray
    partner: np.ndarray
    groups: tuple[tuple[int, ...], ...]
    factors: tuple[np.ndarray | None, ...]
    zdd: tuple = ()

    @property
    def z(self) -> np.ndarray:
        """The roots ``anchor + w``."""
        return self.anchor + self.w

    @property
    def p(self) -> int:
        """The order."""
        return len(self.phi)

    # ----------------------------------------------------------------- pieces of the integrand
    def _diff(self, anchor: np.ndarray | float, w: np.ndarray, l: int) -> np.ndarray:
        """``z - z_l`` for points ``z = anchor + w``."""
        return (anchor - self.anchor[l]) + (w - self.w[l])

    def _one_minus_prod(self, anchor: np.ndarray | float, w: np.ndarray, l: int) -> np.ndarray:
        """``1 - z z_l`` for points ``z = anchor + w``, without cancelling against the 1."""
        s, wl = self.anchor[l], self.w[l]
        return (1.0 - anchor * s) - anchor * wl - s * w - w * wl

    @staticmethod
    def sign_log(anchor: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(sign, u)`` with ``z = sign * exp(-u)`` for points ``z = anchor + w``."""
        from stochmod.geometric import log1p_complex

        anchor = np.asarray(anchor, dtype=np.float64)
        w = np.asarray(w, dtype=np.complex128)
        sign = np.ones(w.shape)
        u = np.empty(w.shape, dtype=np.complex128)
        pos, neg, mid = anchor > 0, anchor < 0, anchor == 0
        u[pos] = -log1p_complex(w[pos])
        u[neg] = -log1p_complex(-w[neg])
        sign[neg] = -1.0
        zm = w[mid]
        neg_real = (zm.imag == 0) & (zm.real < 0)
        with np.errstate(divide="ignore"):
            u[mid] = -np.log(np.where(neg_real, -zm, zm))
        sign[mid] = np.where(neg_real, -1.0, 1.0)
        return sign, u

    def _contour_values(self, gi: int, w: np.ndarray, kernel: KernelFn, cols: np.ndarray) -> np.ndarray:
        """``z^(p-1) K(z) / (P(z) P*(z))`` at points ``z = anchor + w`` on group gi's contour;
        the members' factors come from the group's factor polynomial C:
        ``prod (z - z_l) = C(w)`` and ``prod (1 - z z_l) = z^k C((1 - s z) / z)``."""
        members = self.groups[gi]
        s = float(self.anchor[members[0]])
        z = s + w
        den = np.ones(w.shape, dtype=np.complex128)
        for l in range(self.p):
            if l not in members:
                den = den * self._diff(s, w, l) * self._one_minus_prod(s, w, l)
        c = self.factors[gi]
        x = -s * w / z if s != 0 else 1.0 / z
        den = den * np.polynomial.polynomial.polyval(w, c) * z ** len(members) \
            * np.polynomial.polynomial.polyval(x, c)
        sign, u = self.sign_log(np.full(w.shape, s), w)
        return kernel(sign, u, cols) * (z ** (self.p - 1) / den)[:, None]

    def residue(self, k: int, kernel: KernelFn, cols: np.ndarray) -> np.ndarray:
        """Residue of ``z^(p-1) K(z) / (P(z) P*(z))`` at root k, one value per kernel column."""
        s, w = self.anchor[k], self.w[k]
        den = complex(1.0)
        for l in range(self.p):
            if l != k:
                den *= complex(self._diff(s, w, l))
            if l == self.partner[k]:
                den *= -self.abs2m1[k]  # 1 - z_k conj(z_k) = 1 - |z_k|^2
            else:
                den *= complex(self._one_minus_prod(s, w, l))
        zk = s + w
        val = kernel(self.sign[[k]], self.u[[k]], cols)[0]
        return val * (zk ** (self.p - 1) / den)

    def haar_residue_dd(self, k: int, m: int) -> _CDD:
        """Residue at root k of ``z^(p-1) W_m(z) / (P(z) P*(z))`` in double-double arithmetic."""
        zk = _CDD(*self.zdd[k])
        den = _CDD(1.0)
        for l in range(self.p):
            zl = _CDD(*self.zdd[l])
            if l != k:
                den = den * (zk - zl)
            den = den * (_CDD(1.0) - zk * zl)
        re, im = self.zdd[k]
        wk = _CDD(_dd_add(re, (-float(self.anchor[k]), 0.0)), im)
        num = _haar_wv_dd(zk, wk, float(self.anchor[k]), m)
        for _ in range(self.p - 1):
            num = num * zk
        return num / den

    def haar_sum_precise(self, kernel: KernelFn, m: np.ndarray) -> np.ndarray:
        """Haar WV per unit sigma2 at the levels with half-widths `m`, with the residues of the
        isolated roots in double-double: where large residues of opposite signs, or nearly
        imaginary residues of a complex pair, leave the result to rounding in double
        precision. Groups of near-repeated roots keep their contour integrals."""
        m = np.asarray(m, dtype=np.float64)
        total = np.zeros(m.size)
        singles = [g[0] for g in self.groups if len(g) == 1 and self.partner[g[0]] >= g[0]]
        for i, mi in enumerate(m):  # sum the residues in double-double, round once
            acc = _CDD(0.0)
            for k in singles:
                res = self.haar_residue_dd(k, int(mi))
                acc = acc + (res if self.partner[k] == k else res.scale(2.0))
            total[i] = complex(acc).real
        for gi, group in enumerate(self.groups):
            if len(group) > 1:
                total += self._group_sum(gi, kernel, 2.0 * m, True).real
        return total

    def _residues(self, group: tuple[int, ...], kernel: KernelFn, cols: np.ndarray) -> np.ndarray:
        return sum(self.residue(k, kernel, cols) for k in group)

    # ----------------------------------------------------------------- residue sums
    def residue_sum(self, kernel: KernelFn, rates: np.ndarray, *, smooth: bool = False
                    ) -> tuple[np.ndarray, np.ndarray]:
        """``sum_roots Res[z^(p-1) K(z) / (P(z) P*(z))]``, one value per kernel column.

        Parameters
        ----------
        kernel : callable
            ``kernel(sign, u, cols)`` evaluates the kernels ``K_c(z)`` of the columns `cols` at
            points ``z = sign exp(-u)`` (1-D arrays), shape ``(points, len(cols))``.
        rates : ndarray
            Per column, the largest power of z in the kernel (``2m`` for the level-j Haar
            kernel, ``h`` for ``z^h``): the kernel varies on the scale 1/rate.
        smooth : bool
            True when the kernel is dominated by a part without fast-decaying powers (the Haar
            kernel's ``(1 + z) / (2m (1 - z))``, whose pole z = 1 is kept off the contours);
            allows wide contours where its powers of z are negligible.

        Returns
        -------
        total, magnitude : ndarray
            The (real) sum, and the sum of the moduli of the groups' contributions (the scale
            of the rounding error: ``eps * magnitude``).
        """
        rates = np.maximum(np.asarray(rates, dtype=np.float64).reshape(-1), 1.0)
        total = np.zeros(rates.size, dtype=np.complex128)
        magnitude = np.zeros(rates.size)
        every = np.arange(rates.size)
        for gi, group in enumerate(self.groups):
            if len(group) == 1:
                part = self.residue(group[0], kernel, every)
            else:
                part = self._group_sum(gi, kernel, rates, smooth)
            total += part
            magnitude += np.abs(part)
        return total.real, magnitude

    def _group_sum(self, gi: int, kernel: KernelFn, rates: np.ndarray, smooth: bool) -> np.ndarray:
        """A group's summed residues: contour integrals (radius chosen per column), or plain
        residues where the kernel varies fast enough across the group that they do not cancel."""
        group = self.groups[gi]
        every = np.arange(rates.size)
        try:
            centre, spread, rho_max, d_out = _contour_geometry(self.z, self.w[list(group)], group)
        except ValueError:  # not separable from the other singularities: plain residues (rare)
            return self._residues(group, kernel, every)
        to_circle = 1.0 - abs(self.anchor[group[0]] + centre)
        wide = (rates * rho_max <= 1.0) | (smooth & (rates * to_circle >= 400.0))
        plain = ~wide & (rates * spread >= 0.25)
        rho = np.where(wide, rho_max, np.maximum(4.0 * spread, 1.0 / rates))
        out = np.zeros(rates.size, dtype=np.complex128)
        if np.any(plain):
            out[plain] = self._residues(group, kernel, every[plain])
        for r in np.unique(rho[~plain]):
            cols = every[~plain & (rho == r)]
            q = max(spread / r, r / d_out)
            nodes = int(min(4096, max(32, math.ceil(-43.0 / math.log(q)) if q > 0 else 32)))
            nodes += (-nodes) % 4
            offset = r * np.exp(2j * np.pi * np.arange(nodes) / nodes)
            vals = self._contour_values(gi, centre + offset, kernel, cols)
            out[cols] = (vals * offset[:, None]).mean(axis=0)
        return out


def _contour_geometry(z: np.ndarray, w_group: np.ndarray, group: tuple[int, ...] | list[int]
                      ) -> tuple[complex, float, float, float]:
    """Centre (in w), spread, largest admissible radius and distance to the nearest other
    singularity for a group's contour circle.

    The radius may reach 0.4 of the distance to the nearest other root, reflected root 1/z_l
    or z = 1 (pole of the non-decaying part of the Haar kernel) and 0.75 of the distance to
    the unit circle. Raises ValueError when the group is not separated from the rest (its
    spread exceeds 0.25 of that radius).
    """
    centre = complex(np.mean(w_group))
    spread = float(np.max(np.abs(w_group - centre)))
    zc = complex(np.mean(z[list(group)]))
    obstacles = [abs(z[l] - zc) for l in range(z.size) if l not in group]
    obstacles += [abs(1.0 / zl - zc) for zl in z if zl != 0]
    d_out = min(obstacles + [abs(1.0 - zc), 2.0])
    rho_max = min(0.4 * d_out, 0.75 * (1.0 - abs(zc)))
    if not spread <= 0.25 * rho_max:
        raise ValueError("root group not separated")
    return centre, spread, rho_max, d_out


def _groups(z: np.ndarray) -> list[list[int]]:
    p = z.size
    scale = np.minimum(1.0, np.maximum(1.0 - np.abs(z), 0.0))
    parent = list(range(p))

    def find(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for k in range(p):
        for l in range(k + 1, p):
            if abs(z[k] - z[l]) < CLUSTER_ETA * min(scale[k], scale[l]):
                parent[find(k)] = find(l)
    out: dict[int, list[int]] = {}
    for i in range(p):
        out.setdefault(find(i), []).append(i)
    return list(out.values())


def _separated(z: np.ndarray, groups: list[list[int]]) -> list[list[int]]:
    """Merge a multi-root group with its nearest root until its contour circle is valid."""
    changed = True
    while changed:
        changed = False
        for g in groups:
            if len(g) < 2 or len(g) == z.size:
                continue
            try:
                _contour_geometry(z, z[g], g)
            except ValueError:
                zc = np.mean(z[g])
                near = min((l for l in range(z.size) if l not in g), key=lambda l: abs(z[l] - zc))
                other = next(h for h in groups if near in h)
                groups = [h for h in groups if h is not g and h is not other] + [sorted(g + other)]
                changed = True
                break
    return groups


def _taylor_coefficients(phi: tuple[float, ...], anchor: int) -> np.ndarray:
    """Coefficients b_k (k = 0..p, lowest first) of ``P(anchor + w) = sum b_k w^k``, exactly
    rounded from the binary values of phi."""
    p = len(phi)
    coef = [Fraction(1)] + [-Fraction(c) for c in phi]  # P(z) = sum_i coef_i z^(p-i)
    out = []
    for k in range(p + 1):
        acc = Fraction(0)
        for i, c in enumerate(coef):
            n = p - i
            if n >= k and c:
                acc += c * math.comb(n, k) * Fraction(anchor) ** (n - k)
        out.append(float(acc))
    return np.asarray(out)


def _group_factor(b: np.ndarray, w_others: list[complex], k: int) -> np.ndarray:
    """Monic factor of degree k of ``Q(w) = sum b_k w^k`` whose roots are near w = 0, given the
    other roots `w_others` (same shifted variable): ``Q / prod (w - w_l)`` expanded as a power
    series about 0 (the others lie farther out, so this division is stable), truncated."""
    if not w_others:
        return b.astype(np.complex128)
    inv = np.zeros(k, dtype=np.complex128)
    inv[0] = 1.0
    for wl in w_others:  # 1 / (w - wl) = -(1/wl) sum (w/wl)^n
        inv = np.convolve(inv, (1.0 / wl) ** np.arange(k))[:k] * (-1.0 / wl)
    return np.append(np.convolve(b.astype(np.complex128), inv)[:k], 1.0)


def _anchor_of(z: complex) -> int:
    if abs(z - 1) < _ANCHOR_RADIUS:
        return 1
    if abs(z + 1) < _ANCHOR_RADIUS:
        return -1
    return 0


@lru_cache(maxsize=512)
def ar_roots(phi: tuple[float, ...]) -> ARRoots:
    """Refined, anchored and grouped roots of ``z^p - phi_1 z^(p-1) - ... - phi_p``."""
    coef = np.concatenate([[1.0], -np.asarray(phi, dtype=np.float64)])
    z0 = np.roots(coef).astype(np.complex128)
    z0 = np.where(np.abs(z0.imag) <= 4 * np.finfo(float).eps * np.abs(z0), z0.real + 0j, z0)
    p = z0.size
    groups = _separated(z0, _groups(z0))
    anchor = np.zeros(p)
    zdd: list[tuple[DD, DD]] = [((z.real, 0.0), (z.imag, 0.0)) for z in z0]
    for g in groups:
        a = _anchor_of(complex(np.mean(z0[g])))
        anchor[g] = a
        if len(g) == 1:
            k = g[0]
            dist = [abs(z0[k] - z0[l]) for l in range(p) if l != k]
            zdd[k] = _refine(coef, complex(z0[k]), 0.25 * min(dist + [2.0]))
    # conjugate pairs: mirror the refined root with positive imaginary part
    partner = np.arange(p)
    for k in range(p):
        if z0[k].imag > 0:
            l = min((l for l in range(p) if l != k and z0[l].imag < 0),
                    key=lambda l: abs(z0[l] - np.conj(z0[k])))
            partner[k], partner[l] = l, k
            re, im = zdd[k]
            zdd[l] = (re, _dd_neg(im))
    w = np.array([complex((re[0] - a) + re[1], im[0] + im[1]) for (re, im), a in zip(zdd, anchor)])
    abs2m1 = np.array([_abs2_minus_one(zk) for zk in zdd])
    sign, u = ARRoots.sign_log(anchor, w)
    nonzero = (w != 0) | (anchor != 0)
    with np.errstate(divide="ignore"):  # |z|^2 underflowing to 0 gives u = inf, i.e. z = 0
        u = np.where(nonzero, -0.5 * np.log1p(np.where(nonzero, abs2m1, 0.0)) + 1j * u.imag, u)
    taylor = {a: _taylor_coefficients(phi, a) for a in (-1, 0, 1)}
    factors = []
    for g in groups:
        if len(g) == 1:
            factors.append(None)
            continue
        a = int(anchor[g[0]])
        others = [complex((anchor[l] - a) + w[l]) for l in range(p) if l not in g]
        factors.append(_group_factor(taylor[a], others, len(g)))
    return ARRoots(tuple(float(c) for c in phi), anchor, w, sign, u, abs2m1, partner,
                   tuple(tuple(g) for g in groups), tuple(factors), tuple(zdd))
