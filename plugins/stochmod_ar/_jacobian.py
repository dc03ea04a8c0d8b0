"""Analytic derivative of the AR(p) Haar wavelet variance with respect to the coefficients.

Per unit innovation variance the Haar WV at half-width m is the residue sum
``F = sum_r Res_{z_r} [z^(p-1) W_m(z) / (P(z) A(z))]`` over the roots z_r of
``P(z) = z^p - phi_1 z^(p-1) - ... - phi_p``, with ``A(z) = 1 - sum_k phi_k z^k
= prod_s (1 - z z_s)`` (see :mod:`stochmod_ar._roots`). The contour stays fixed while phi moves
(the roots stay inside the unit circle), so ``d/dphi_k`` goes under the integral:
``d/dphi_k [1 / (P A)] = z^(p-k) / (P^2 A) + z^k / (P A^2)`` (``dP/dphi_k = -z^(p-k)``,
``dA/dphi_k = -z^k``). The second part has simple poles at the roots; the first has double
ones. With ``Q_r = prod_{s != r} (z_r - z_s)``, ``A_r = A(z_r)``, ``c_r = z_r^(p-1) / (Q_r A_r)``
(the autocovariance's residue), ``S_r = sum_{s != r} 1 / (z_r - z_s)`` and
``T_r = -A'(z_r) / A_r = sum_s z_s / (1 - z_r z_s)``:

``dF/dphi_k = sum_r z_r^(2p-k-2) / (A_r Q_r^2) [z_r W'(z_r) + W(z_r) (2p-k-1 + z_r (T_r - 2 S_r))]
+ c_r W(z_r) z_r^k / A_r``

where ``z W'(z) = dW/dlog z`` (:func:`stochmod.core.geometric.haar_wv_geometric_dlog`). The terms
grow like ``1 / (z_r - z_s)^2`` as roots approach each other, and their sum cancels; each entry
comes with an estimate of its rounding error (eps times the sum of the moduli of its terms,
inflated by the relative accuracy of the root differences), and the caller falls back to
differences where the estimate is not small (near-repeated roots, complex pairs by the unit
circle at deep levels, the AR(1) at phi = 0 or subnormal).
"""

from __future__ import annotations

import numpy as np

from stochmod.sdk import haar_wv_geometric, haar_wv_geometric_dlog
from stochmod_ar._roots import ARRoots

__all__ = ["haar_wv_phi_jacobian"]

_EPS = 2.0**-52
_TINY = np.finfo(np.float64).tiny  # the smallest normal double


def haar_wv_phi_jacobian(roots: ARRoots, m: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """``d F / d phi_k`` per unit sigma2 at half-widths `m`, with an estimate of its error.

    Parameters
    ----------
    roots : ARRoots
        The refined roots of the AR polynomial.
    m : ndarray of float
        Samples per half Haar filter, ``2^(j-1)`` at level j.

    Returns
    -------
    (jacobian, abs_err) or None
        Arrays of shape ``(len(m), p)``: the derivatives and the estimated bound on their
        rounding error (both dimensionless, per unit sigma2); None where
        the closed form does not apply: a group of near-repeated roots, or AR(1) with |phi|
        below the smallest normal double (zero included).
    """
    p = roots.p
    z = roots.z
    if any(len(g) > 1 for g in roots.groups) or (p == 1 and abs(z[0]) < _TINY):
        # AR(1) divides dW/dlog z by z (e = -1 below): not at zero nor at a subnormal root,
        # where 1/z overflows; a simple root at zero is fine for p >= 2 (e >= 0)
        return None
    factors = [roots.pair_factors(r) for r in range(p)]
    diff = np.array([d for d, _ in factors])  # z_r - z_s (1 on the diagonal)
    one_minus = np.array([o for _, o in factors])  # 1 - z_r z_s
    Q = np.prod(diff, axis=1)
    A = np.prod(one_minus, axis=1)
    off = ~np.eye(p, dtype=bool)
    S = np.sum(np.where(off, 1.0 / diff, 0.0), axis=1)
    T = np.sum(z[None, :] / one_minus, axis=1)
    # relative accuracy of the differences: the anchored offsets carry ~eps |w| absolute error
    spread = np.max(np.abs(roots.w)) if p > 1 else 0.0
    cond = 1.0 + (spread / np.min(np.abs(diff[off])) if p > 1 else 0.0)

    log_z = -roots.u[:, None]
    W = haar_wv_geometric(log_z, m[None, :], sign=roots.sign[:, None]).astype(np.complex128)
    dW = haar_wv_geometric_dlog(log_z, m[None, :], sign=roots.sign[:, None]).astype(np.complex128)
    c = z ** (p - 1) / (Q * A)
    # dW/dlog z is a sum of parts of size 1/(2m) and |W coth(log z / 2)| that cancel as much as
    # 1/|z| for fast roots: its rounding error scales with them, not with |dW|
    with np.errstate(divide="ignore", invalid="ignore"):
        dW_size = (np.abs(dW) + 0.5 / m[None, :]
                   + np.abs(W) * np.abs((1.0 + z) / (1.0 - z))[:, None])

    jac = np.zeros((m.size, p))
    err = np.zeros((m.size, p))
    for k in range(1, p + 1):
        e = 2 * p - k - 2  # >= -1; -1 only for p = 1, where z != 0 here
        lead = (z**e / (A * Q * Q))[:, None]
        inner = dW + W * (2 * p - k - 1 + z * (T - 2.0 * S))[:, None]
        simple = (c * z**k / A)[:, None] * W
        terms = lead * inner + simple
        size = (np.abs(lead) * (dW_size + np.abs(W) * (2 * p - k - 1 + np.abs(z * T)
                                                         + 2.0 * np.abs(z * S))[:, None])
                + np.abs(simple))
        jac[:, k - 1] = terms.sum(axis=0).real
        err[:, k - 1] = 32.0 * _EPS * cond * size.sum(axis=0)
    return jac, err
