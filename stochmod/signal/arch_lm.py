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

from stochmod._validation import as_signal, check_positive_int
from stochmod.errors import InputError

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
    y = z2[lags:]
    if np.ptp(y) == 0:
        raise InputError("z^2 is constant: the LM regression has no variance to explain")
    nobs = y.size
    # centred regressors (the constant drops out): the Gram matrix of the lags from dot products
    # of shifted views (no T x m copy), X'y with the centred y alone (its sum is zero);
    # explained sum of squares b' X'y solved by Cholesky: R^2 = ESS / SST
    lag = [z2[lags - i : z2.size - i] for i in range(1, lags + 1)]
    means = np.array([v.mean() for v in lag])
    gram = np.empty((lags, lags))
    for i in range(lags):
        for k in range(i, lags):
            gram[i, k] = gram[k, i] = lag[i] @ lag[k] - nobs * means[i] * means[k]
    yc = y - y.mean()
    xty = np.array([yc @ v for v in lag])
    coef = linalg.solve(gram, xty, assume_a="pos", check_finite=False)
    stat = nobs * float(coef @ xty) / float(yc @ yc)
    return ArchLMTest(statistic=stat, pvalue=float(stats.chi2.sf(stat, lags)), lags=lags, nobs=nobs)
