"""One wavelet variance from several recordings of the same sensor model (replicates).

Replicates ``k = 1..K`` of lengths ``N_k`` give empirical Haar WVs ``nu_k`` from ``M_{j,k}``
interior coefficients at level j. Their pooled WV weights each replicate by its number of
coefficients (its length), ``nu_j = sum_k M_{j,k} nu_{j,k} / sum_k M_{j,k}``: the mean of all the
squared wavelet coefficients, as one record of ``sum_k M_{j,k}`` coefficients would give. With
independent replicates its covariance is ``sum_k W_k V_k W_k``, ``W_k = diag(M_{j,k} / sum_k M_{j,k})``
and ``V_k`` each replicate's covariance (eq. 17 of Stebler et al. 2014): about ``1/K`` of one
replicate's, hence GMWM intervals about ``sqrt(K)`` narrower.

Whether the replicates share one WV is tested by the homogeneity statistic
``Q = sum_k (nu_k - nu*)^T V_k^{-1} (nu_k - nu*)``, ``nu*`` the inverse-covariance weighted
mean, asymptotically chi-square with ``(K - 1) J`` degrees of freedom under the null, on the
levels where every replicate has at least ``min_dof`` equivalent degrees of freedom (deep levels
with few coefficients have unreliable covariance estimates).

Replicates of different lengths may reach different depths: a replicate whose data support
only levels ``1..J_k`` contributes ``M_{j,k} = 0`` coefficients (weight 0) at the deeper levels,
so the pooled WV reaches the depth of the longest replicate. This is how the gap-free segments of
one recording are pooled (``stochmod calibrate --split-gaps``): a short segment adds its
coefficients to the levels it has and nothing to the others.
"""

from __future__ import annotations

from collections.abc import Sequence

import attrs
import numpy as np
from numpy.typing import ArrayLike
from scipy import special

from stochmod.core.fields import array_field
from stochmod.core.checks import as_signal, check_alpha, check_freq, check_positive_int
from stochmod.core.errors import InputError
from stochmod.core.tables import format_table
from stochmod.core.filters import default_levels
from stochmod.empirical.wavelet_variance import WaveletVariance, chi2_interval, wvar
from stochmod.empirical.wv_covariance import wv_covariance

__all__ = ["EqualityTest", "PooledWaveletVariance", "pool_wv", "pooled_wvar", "replicate_levels",
           "wv_equality_test"]


@attrs.frozen
class EqualityTest:
    """Homogeneity test of the replicates' wavelet variances.

    Attributes
    ----------
    statistic : float
        ``Q``, chi-square under the null of one common WV.
    dof : int
        ``(K - 1) J_test``.
    pvalue : float
        ``P(chi2_dof > Q)``.
    levels : ndarray of int
        Levels used (every replicate with at least ``min_dof`` equivalent degrees of freedom).
    """

    statistic: float
    dof: int
    pvalue: float
    levels: np.ndarray = array_field()

    def summary(self) -> str:
        """One line."""
        return (f"replicates share one wavelet variance? Q = {self.statistic:.4g}, chi2 with "
                f"{self.dof} dof (levels {int(self.levels[0])}..{int(self.levels[-1])}), "
                f"p-value {self.pvalue:.4g}")


@attrs.frozen
class PooledWaveletVariance:
    """The pooled WV of replicates, its covariance, the replicates' own WVs and the equality test.

    Attributes
    ----------
    wv : WaveletVariance
        The pooled WV (``n_coef`` summed over the replicates, ``n`` their total length, chi-square
        intervals from the summed degrees of freedom); usable wherever a WV is accepted.
    covariance : ndarray, shape (J, J)
        Covariance of the pooled WV, unit^4.
    replicates : tuple of WaveletVariance
        Each replicate's WV at the common levels.
    covariances : tuple of ndarray
        Each replicate's covariance, unit^4.
    test : EqualityTest or None
        The homogeneity test (None for a single replicate or no level with enough data).
    """

    wv: WaveletVariance
    covariance: np.ndarray = array_field(repr=False)
    replicates: tuple[WaveletVariance, ...] = attrs.field(repr=False)
    covariances: tuple[np.ndarray, ...] = attrs.field(repr=False, eq=False)
    test: EqualityTest | None

    def summary(self) -> str:
        """The pooled WV per level next to each replicate's, and the equality test."""
        rows = [[int(j), t, v, np.sqrt(self.covariance[i, i]),
                 *(r.wv[i] if i < r.wv.size else "-" for r in self.replicates)]
                for i, (j, t, v) in enumerate(zip(self.wv.levels, self.wv.tau, self.wv.wv))]
        headers = ["level", "tau [s]", "pooled WV", "std error", *(f"rep {k}" for k in range(len(self.replicates)))]
        text = format_table(headers, rows, title=f"Pooled wavelet variance of {len(self.replicates)} "
                                                 f"replicates ({self.wv.n} samples in all)")
        return text + ("" if self.test is None else "\n" + self.test.summary())


def replicate_levels(lengths: Sequence[int], levels: int | None = None,
                     wavelet: str = "haar") -> list[int]:
    """Levels each replicate contributes: ``min(J, default_levels(N_k))`` with ``J`` the given
    `levels` or, by default, the deepest a replicate allows.

    Raises
    ------
    InputError
        `levels` deeper than the longest replicate allows.
    """
    own = [default_levels(n, wavelet) for n in lengths]
    if levels is None:
        return own
    levels = check_positive_int(levels, name="levels")
    if levels > max(own):
        raise InputError(f"levels = {levels} but the longest replicate ({max(lengths)} samples) "
                         f"allows {max(own)}")
    return [min(levels, j) for j in own]


def wv_equality_test(wvs: Sequence[WaveletVariance], covariances: Sequence[np.ndarray], *,
                     min_dof: float = 20.0) -> EqualityTest | None:
    """Homogeneity test ``Q`` of replicate WVs with their covariances (see the module docstring)."""
    if len(wvs) < 2:
        return None
    J = max(r.wv.size for r in wvs)
    levels = np.arange(1, J + 1)
    dof = np.min([np.pad(r.n_coef, (0, J - r.wv.size)) / 2.0**levels for r in wvs], axis=0)
    use = np.flatnonzero(dof >= min_dof)
    if use.size == 0:
        return None
    nus = [r.wv[use] for r in wvs]
    precisions = [np.linalg.inv(c[np.ix_(use, use)]) for c in covariances]
    total = np.sum(precisions, axis=0)
    common = np.linalg.solve(total, np.sum([p @ v for p, v in zip(precisions, nus)], axis=0))
    q = float(sum((v - common) @ p @ (v - common) for p, v in zip(precisions, nus)))
    df = (len(wvs) - 1) * use.size
    return EqualityTest(statistic=q, dof=df, pvalue=float(special.chdtrc(df, q)), levels=use + 1)


def pool_wv(wvs: Sequence[WaveletVariance], covariances: Sequence[np.ndarray], *,
            min_dof: float = 20.0) -> PooledWaveletVariance:
    """Pool replicate WVs (same frequency and wavelet, levels ``1..J_k`` each) with their
    covariances (``J_k x J_k`` each); the pooled WV has the levels of the deepest replicate."""
    if not wvs:
        raise InputError("no replicate to pool")
    deepest = max(wvs, key=lambda r: r.wv.size)
    J = deepest.wv.size
    for r in wvs:
        if r.freq != deepest.freq or r.wavelet != deepest.wavelet:
            raise InputError("replicates must share the sampling frequency and wavelet; got "
                             f"{(deepest.freq, deepest.wavelet)} and {(r.freq, r.wavelet)}")
        if not np.array_equal(r.levels, deepest.levels[:r.wv.size]):
            raise InputError(f"each replicate's WV must hold the levels 1..J_k; one has "
                             f"{r.levels.tolist()}")
    if len(covariances) != len(wvs) or any(np.shape(c) != (r.wv.size,) * 2
                                           for r, c in zip(wvs, covariances)):
        raise InputError("one J_k x J_k covariance per replicate (its own levels) is needed")
    counts = np.zeros((len(wvs), J))
    values = np.zeros((len(wvs), J))
    padded = []
    for k, (r, c) in enumerate(zip(wvs, covariances)):
        m = r.wv.size
        counts[k, :m], values[k, :m] = r.n_coef, r.wv
        full = np.zeros((J, J))
        full[:m, :m] = c
        padded.append(full)
    weights = counts / counts.sum(axis=0)
    nu = np.sum(weights * values, axis=0)
    cov = sum(np.outer(w, w) * c for w, c in zip(weights, padded))
    n_coef = counts.sum(axis=0).astype(np.int64)
    low, high = chi2_interval(nu, n_coef, deepest.levels, deepest.alpha)
    arrays = [deepest.levels.copy(), deepest.tau.copy(), nu, low, high, n_coef]
    for a in arrays:
        a.setflags(write=False)
    pooled = WaveletVariance(*arrays, freq=deepest.freq, wavelet=deepest.wavelet,
                             n=int(sum(r.n for r in wvs)), ci_method="chi2", alpha=deepest.alpha)
    return PooledWaveletVariance(wv=pooled, covariance=cov, replicates=tuple(wvs),
                                 covariances=tuple(covariances),
                                 test=wv_equality_test(wvs, covariances, min_dof=min_dof))


def pooled_wvar(signals: Sequence[ArrayLike], freq: float, *, levels: int | None = None,
                wavelet: str = "haar", alpha: float = 0.05, min_dof: float = 20.0
                ) -> PooledWaveletVariance:
    """Pooled wavelet variance of replicate recordings (eq. 17 covariances, equality test).

    Parameters
    ----------
    signals : sequence of array_like
        Two or more recordings of the same sensor model, unit u, any lengths.
    freq : float
        Common sampling frequency, Hz.
    levels : int, optional
        Levels J (default: all the longest replicate allows; a shorter replicate contributes
        to the levels its data support).
    wavelet : str
        Orthogonal wavelet (Haar by default).
    alpha : float
        Significance level of the pooled intervals.
    min_dof : float
        Equivalent degrees of freedom ``M_j / 2^j`` every replicate needs at a level for the
        equality test to use it.

    Raises
    ------
    InputError
        Fewer than 2 replicates, NaN/inf, constant or too short replicates.
    """
    if isinstance(signals, np.ndarray) or len(signals) < 2:
        raise InputError("replicates are given as a list of at least two 1-D signals")
    freq = check_freq(freq)
    alpha = check_alpha(alpha)
    xs = [as_signal(s, name=f"replicate {k}", min_length=8) for k, s in enumerate(signals)]
    depths = replicate_levels([x.size for x in xs], levels, wavelet)
    wvs = [wvar(x, freq, wavelet=wavelet, levels=J, alpha=alpha) for x, J in zip(xs, depths)]
    covs = [wv_covariance(x, J, wavelet=wavelet) for x, J in zip(xs, depths)]
    return pool_wv(wvs, covs, min_dof=min_dof)
