"""Engle's (1982) Lagrange-multiplier test for ARCH effects.

Regress ``z_t^2`` on a constant and ``z_{t-1}^2 .. z_{t-m}^2`` over the ``T - m`` samples that
have every lag; under the null of i.i.d. (Gaussian) ``z`` the statistic ``(T - m) R^2`` is
asymptotically chi-square with ``m`` degrees of freedom (the convention of
``statsmodels.stats.diagnostic.het_arch``). Waegli et al. (2010, Section 5) grow the GARCH
orders until the standardized residuals pass it.
"""

from __future__ import annotations

import attrs
import numpy as np
from numpy.typing import ArrayLike
from scipy import linalg, stats

from stochmod.core.checks import as_signal, check_positive_int
from stochmod.core.errors import InputError

__all__ = ["ArchLMTest", "arch_lm_test"]


@attrs.frozen
class ArchLMTest:
    """Result of Engle's LM test.

    Attributes
    ----------
    statistic : float
        ``(T - m) R^2``.
    pvalue : float
        ``P(chi2_m > statistic)``.
    lags : int
        ``m``.
    nobs : int
        ``T - m``, the regression's sample size.
    """

    statistic: float
    pvalue: float
    lags: int
    nobs: int

    def summary(self) -> str:
        """One line: statistic, degrees of freedom, p-value."""
        return (f"Engle LM test for remaining ARCH effects: T R^2 = {self.statistic:.4g} "
                f"(chi2 with {self.lags} dof, {self.nobs} obs), p-value {self.pvalue:.4g}")


def arch_lm_test(z: ArrayLike, lags: int = 10) -> ArchLMTest:
    """Engle's LM test of `z` (e.g. standardized GARCH residuals) with `lags` lags of ``z^2``.

    Parameters
    ----------
    z : array_like, shape (T,)
        The series tested (any scale).
    lags : int
        Number of lags ``m`` of ``z^2`` in the auxiliary regression.

    Returns
    -------
    ArchLMTest

    Raises
    ------
    InputError
        NaN/inf, fewer than ``3 m + 10`` samples, or ``z^2`` constant.
    """
    lags = check_positive_int(lags, name="lags")
    z = as_signal(z, name="z", min_length=3 * lags + 10)
    z2 = z * z
    z2 = z2 / z2.mean()
    if np.ptp(z2[lags:]) == 0:
        raise InputError("z^2 is constant: the LM regression has no variance to explain")
    nobs = z2.size - lags
    # y and the lags are the windows v_i = z2[m - i : T - i], i = 0 (y) .. m. Their dot
    # products v_i . v_k are the autocovariance sums R(i - k) over the whole record less the
    # few products outside the windows, so the Gram matrix of all of them takes m + 1 passes
    # over the data (einsum: one thread, no BLAS call) instead of (m + 1)(m + 2) / 2; centring
    # drops the constant; R^2 = ESS / SST from the normal equations (Cholesky).
    n = z2.size
    auto = np.array([np.einsum("i,i->", z2[: n - d], z2[d:]) for d in range(lags + 1)])
    gram = np.empty((lags + 1, lags + 1))
    for i in range(lags + 1):
        for k in range(i + 1):
            d = i - k
            head = z2[: lags - i] @ z2[d : lags - i + d]  # s < m - i
            tail = z2[n - i : n - d] @ z2[n - i + d : n]  # s > T - 1 - i
            gram[i, k] = gram[k, i] = auto[d] - head - tail
    total = z2.sum()
    sums = np.array([total - z2[: lags - i].sum() - z2[n - i :].sum() for i in range(lags + 1)])
    gram -= np.outer(sums, sums) / nobs
    xty = gram[1:, 0]
    coef = linalg.solve(gram[1:, 1:], xty, assume_a="pos", check_finite=False)
    stat = nobs * float(coef @ xty) / float(gram[0, 0])
    return ArchLMTest(statistic=stat, pvalue=float(stats.chi2.sf(stat, lags)), lags=lags, nobs=nobs)
