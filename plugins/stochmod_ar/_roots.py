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
- where large residues of opposite signs (or the nearly imaginary residues of a complex pair
  next to +-1, whose small real part is the answer) still leave a sum to rounding,
  :meth:`ARRoots.haar_sum_precise` evaluates and sums the residues in double-double.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from fractions import Fraction
from functools import lru_cache

import attrs
import numpy as np

from stochmod_ar._dd import CDD, DD, cdd_mul, dd_add, dd_mul, dd_neg, haar_wv_dd, two_sum

__all__ = ["ARRoots", "ar_roots", "CLUSTER_ETA"]

#: Linkage threshold relative to the distance to the unit circle (see module docstring).
CLUSTER_ETA = 0.05
_ANCHOR_RADIUS = 0.5

KernelFn = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]

def _poly_dd(coef: np.ndarray, z: tuple[DD, DD]) -> complex:
    """``sum coef_i z^(p-i)`` (highest first) in complex double-double, rounded to complex."""
    v: tuple[DD, DD] = ((float(coef[0]), 0.0), (0.0, 0.0))
    for c in coef[1:]:
        v = cdd_mul(v, z)
        v = (dd_add(v[0], (float(c), 0.0)), v[1])
    return complex(v[0][0] + v[0][1], v[1][0] + v[1][1])


def _refine(coef: np.ndarray, z0: complex, guard: float, real: bool) -> tuple[tuple[DD, DD], bool]:
    """Newton on P with double-double residuals from z0, kept real if `real`; returns z as
    (re, im) double-doubles and whether it converged (steps below 1e-22 |z|, i.e. at the
    double-double noise floor after quadratic convergence). Gives up, returning z0, if an
    iterate leaves the disc of radius `guard` about z0."""
    der_coef = np.polyder(coef)
    z: tuple[DD, DD] = ((z0.real, 0.0), (0.0 if real else z0.imag, 0.0))
    small = 0
    for _ in range(60):
        val = _poly_dd(coef, z)
        zc = complex(z[0][0] + z[0][1], z[1][0] + z[1][1])
        if val == 0:
            return z, True
        der = complex(np.polyval(der_coef, zc))
        if der == 0 or not np.isfinite(val):
            break
        step = val / der
        if real:
            step = complex(step.real, 0.0)
        z = (dd_add(z[0], (-step.real, 0.0)), dd_add(z[1], (-step.imag, 0.0)))
        znew = complex(z[0][0] + z[0][1], z[1][0] + z[1][1])
        if not np.isfinite(znew) or abs(znew - z0) > guard:
            break
        if abs(step) <= 1e-31 * max(abs(znew), 1e-300):
            return z, True
        small = small + 1 if abs(step) <= 1e-22 * max(abs(znew), 1e-300) else 0
        if small >= 3:
            return z, True
    return ((z0.real, 0.0), (z0.imag, 0.0)), False


def _abs2_minus_one(z: tuple[DD, DD]) -> float:
    """``|z|^2 - 1`` from a double-double z, accurate to a few ulps of the result."""
    acc = dd_add(dd_mul(z[0], z[0]), dd_mul(z[1], z[1]))
    acc = dd_add(acc, (-1.0, 0.0))
    return acc[0] + acc[1]


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
        from stochmod.sdk import log1p_complex

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

    def pair_factors(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """``z_k - z_l`` (1 at l = k) and ``1 - z_k z_l`` for every root l, from the anchored
        form; ``1 - z_k conj(z_k)`` is ``-(|z_k|^2 - 1)``, accurate next to the unit circle."""
        s, w = self.anchor[k], self.w[k]
        diffs = np.ones(self.p, dtype=np.complex128)
        ones = np.empty(self.p, dtype=np.complex128)
        for l in range(self.p):
            if l != k:
                diffs[l] = self._diff(s, w, l)
            ones[l] = -self.abs2m1[k] if l == self.partner[k] else self._one_minus_prod(s, w, l)
        return diffs, ones

    def residue(self, k: int, kernel: KernelFn, cols: np.ndarray) -> np.ndarray:
        """Residue of ``z^(p-1) K(z) / (P(z) P*(z))`` at root k, one value per kernel column."""
        diffs, ones = self.pair_factors(k)
        den = complex(1.0)
        for d, o in zip(diffs, ones):
            den *= complex(d)
            den *= complex(o)
        zk = self.anchor[k] + self.w[k]
        val = kernel(self.sign[[k]], self.u[[k]], cols)[0]
        return val * (zk ** (self.p - 1) / den)

    def haar_residue_dd(self, k: int, m: int) -> CDD:
        """Residue at root k of ``z^(p-1) W_m(z) / (P(z) P*(z))`` in double-double arithmetic."""
        zk = CDD(*self.zdd[k])
        den = CDD(1.0)
        for l in range(self.p):
            zl = CDD(*self.zdd[l])
            if l != k:
                den = den * (zk - zl)
            den = den * (CDD(1.0) - zk * zl)
        re, im = self.zdd[k]
        wk = CDD(dd_add(re, (-float(self.anchor[k]), 0.0)), im)
        num = haar_wv_dd(zk, wk, float(self.anchor[k]), m)
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
            acc = CDD(0.0)
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
        """A group's summed residues by contour integrals, radius and nodes chosen per column.

        The radius is the largest admissible (see :func:`_contour_geometry`) where the
        kernel's powers z^rate vary little over it, else ``max(4 spread, 1/rate)``; for a smooth
        kernel, also the largest where those powers are negligible near the unit circle. The
        nodes make the trapezoidal error ~1e-19: geometric in the ratios of the radius to the
        group's spread and to the other singularities, and enough (``e rate radius / reach``)
        to resolve the powers on the circle unless they are below 1e-25 there. Beyond 8192
        nodes, distinct roots fall back to plain residues.
        """
        group = self.groups[gi]
        every = np.arange(rates.size)
        try:
            centre, spread, rho_max, d_out = _contour_geometry(self.z, self.w[list(group)], group)
        except ValueError:  # not separable from the other singularities: plain residues (rare)
            return self._residues(group, kernel, every)
        s = float(self.anchor[group[0]])
        zc = abs(s + centre)
        members = self.w[list(group)]
        min_sep = min(abs(a - b) for i, a in enumerate(members) for b in members[i + 1 :])
        rho = np.where(rates * rho_max <= 1.0, rho_max,
                       np.minimum(rho_max, np.maximum(4.0 * spread, 1.0 / rates)))
        if smooth:
            rho = np.where(rates * (1.0 - zc) >= 400.0, rho_max, rho)
        reach = zc + rho
        q = np.maximum(spread / rho, rho / d_out)
        with np.errstate(divide="ignore"):
            n_geo = np.ceil(-43.0 / np.log(np.maximum(q, 1e-300)))
            negligible = rates * np.log(reach) < -58.0
        n_pow = np.where(negligible & smooth, 0.0, 2.72 * rates * rho / reach + 32.0)
        nodes = np.maximum(32, np.maximum(n_geo, n_pow))
        plain = (nodes > 8192) & (min_sep > 0)
        nodes = np.minimum(nodes, 8192).astype(int)
        nodes += (-nodes) % 4
        out = np.zeros(rates.size, dtype=np.complex128)
        if np.any(plain):
            out[plain] = self._residues(group, kernel, every[plain])
        for r, n in set(zip(rho[~plain], nodes[~plain])):
            cols = every[~plain & (rho == r) & (nodes == n)]
            offset = r * np.exp(2j * np.pi * np.arange(n) / n)
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


def _refined_roots(coef: np.ndarray, z0: np.ndarray) -> list[tuple[DD, DD]]:
    """Each root refined in double-double. A real root whose real Newton iteration does not
    converge belongs to a near-double pair that np.roots split along the real axis although
    it is complex (or vice versa): it is retried, with its nearest real neighbour, from the
    complex point between them."""
    p = z0.size
    out, ok = [], []
    for k in range(p):
        dist = [abs(z0[k] - z0[l]) for l in range(p) if l != k]
        zk, conv = _refine(coef, complex(z0[k]), 0.25 * min(dist + [2.0]) + 1e-300, z0[k].imag == 0)
        if not conv and z0[k].imag != 0:
            # a near-double complex pair: np.roots can misplace it by more than a quarter of
            # the pair's separation; Newton may roam the whole half plane on its side
            zk, conv = _refine(coef, complex(z0[k]), 0.99 * abs(z0[k].imag), False)
        out.append(zk)
        ok.append(conv)
    stuck = [k for k in range(p) if not ok[k] and z0[k].imag == 0]
    while stuck:
        k = stuck.pop()
        reals = [l for l in range(p) if l != k and z0[l].imag == 0 and (l in stuck or not ok[l])]
        if not reals:
            continue
        l = min(reals, key=lambda l: abs(z0[l] - z0[k]))
        sep = abs(z0[l] - z0[k])
        start = complex(0.5 * (z0[k].real + z0[l].real), max(0.5 * sep, 1e-12 * abs(z0[k])))
        zc, conv = _refine(coef, start, 10.0 * sep + 1e-15, False)
        if conv and zc[1][0] != 0:
            im = zc[1] if zc[1][0] > 0 else dd_neg(zc[1])
            out[k], out[l] = (zc[0], im), (zc[0], dd_neg(im))
            if l in stuck:
                stuck.remove(l)
    return out


def _as_complex(z: tuple[DD, DD]) -> complex:
    return complex(z[0][0] + z[0][1], z[1][0] + z[1][1])


@lru_cache(maxsize=512)
def ar_roots(phi: tuple[float, ...]) -> ARRoots:
    """Refined, anchored and grouped roots of ``z^p - phi_1 z^(p-1) - ... - phi_p``."""
    coef = np.concatenate([[1.0], -np.asarray(phi, dtype=np.float64)])
    z0 = np.roots(coef).astype(np.complex128)
    z0 = np.where(np.abs(z0.imag) <= 4 * np.finfo(float).eps * np.abs(z0), z0.real + 0j, z0)
    p = z0.size
    zdd = _refined_roots(coef, z0)
    z = np.array([_as_complex(zk) for zk in zdd])
    groups = _separated(z, _groups(z))
    anchor = np.zeros(p)
    for g in groups:
        anchor[g] = _anchor_of(complex(np.mean(z[g])))
    w = np.array([complex((re[0] - a) + re[1], im[0] + im[1]) for (re, im), a in zip(zdd, anchor)])
    # groups: the factor polynomial from the exact Taylor coefficients, the members its roots
    factors: list[np.ndarray | None] = []
    for g in groups:
        if len(g) == 1:
            factors.append(None)
            continue
        a = int(anchor[g[0]])
        others = [complex((anchor[l] - a) + w[l]) for l in range(p) if l not in g]
        if all(abs(o) > 2.0 * max(abs(w[l]) for l in g) for o in others):
            c = _group_factor(_taylor_coefficients(phi, a), others, len(g))
        else:  # another root as near the anchor as the group: the series about it diverges
            c = np.polynomial.polynomial.polyfromroots(w[list(g)]).astype(np.complex128)
        factors.append(c)
        members = list(np.roots(c[::-1]))
        for k in g:  # each member takes the nearest remaining root of its factor
            wk = members.pop(int(np.argmin(np.abs(np.asarray(members) - w[k]))))
            w[k] = wk
            zdd[k] = (two_sum(a, wk.real), (wk.imag, 0.0))
    # conjugate pairs: the root with positive imaginary part, and its mirror image
    partner = np.arange(p)
    for k in np.argsort(-w.imag):
        if w[k].imag > 0 and partner[k] == k:
            cands = [l for l in range(p) if l != k and w[l].imag < 0 and partner[l] == l]
            if cands:
                l = min(cands, key=lambda l: abs(w[l] - np.conj(w[k])))
                partner[k], partner[l] = l, k
                w[l] = np.conj(w[k])
                zdd[l] = (zdd[k][0], dd_neg(zdd[k][1]))
    abs2m1 = np.array([_abs2_minus_one(zk) for zk in zdd])
    sign, u = ARRoots.sign_log(anchor, w)
    nonzero = (w != 0) | (anchor != 0)
    # near the unit circle, Re u = -log|z| from the double-double |z|^2 - 1 (the log of a
    # double |z| would leave it ~eps absolute); elsewhere the log of z itself is accurate
    near = nonzero & (abs2m1 > -0.5)
    u = np.where(near, -0.5 * np.log1p(np.where(near, abs2m1, 0.0)) + 1j * u.imag, u)
    return ARRoots(tuple(float(c) for c in phi), anchor, w, sign, u, abs2m1, partner,
                   tuple(tuple(g) for g in groups), tuple(factors), tuple(zdd))
