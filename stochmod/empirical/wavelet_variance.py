"""Empirical wavelet variance (MODWT estimator, eq. 9 of Stebler et al. 2014) and its intervals.

Levels j = 1..J; averaging time ``tau_j = 2^(j-1) / freq`` seconds (the Haar filter of level
j averages ``2^(j-1)`` samples per half), so that the Haar wavelet variance is half the
overlapping Allan variance at ``tau_j``. Only the ``M_j = N - L_j + 1`` interior wavelet
coefficients enter the estimate (no boundary rule, unbiased).

:func:`wvar` is the entry point: the classical estimator (mean of the squared coefficients,
:mod:`stochmod.empirical.wv_classical`) or, with ``robust=True``, the robust M-estimate
(:mod:`stochmod.empirical.robust_wv`); both return a :class:`WaveletVariance`.
"""

from __future__ import annotations

from typing import Any

from numpy.typing import ArrayLike

from stochmod.empirical.modwt import modwt_coefficients
from stochmod.empirical.robust_wv import robust_wvar
from stochmod.empirical.wv_classical import (
    CI_METHODS,
    NORMAL_CI_FLOOR,
    WaveletVariance,
    chi2_interval,
    classical_wvar,
)

__all__ = ["WaveletVariance", "wvar", "modwt_coefficients", "chi2_interval", "CI_METHODS",
           "NORMAL_CI_FLOOR", "estimator_options", "same_estimator"]


def wvar(
    x: ArrayLike,
    freq: float,
    wavelet: str = "haar",
    levels: int | None = None,
    ci: str = "chi2",
    alpha: float = 0.05,
    *,
    robust: bool = False,
    efficiency: float = 0.6,
    rho: str = "biweight",
) -> WaveletVariance:
    """Empirical MODWT wavelet variance at levels 1..J with confidence intervals.

    Parameters
    ----------
    x : array_like, shape (N,)
        Finite, non-constant signal in its own unit (e.g. rad/s); any length N >= L_1.
    freq : float
        Sampling frequency, Hz.
    wavelet : str
        Orthogonal PyWavelets wavelet (default "haar"; Daubechies "db2", "db4", ... or
        "sym4" ... for processes whose differences of order L_1/2 are stationary).
    levels : int, optional
        Number of levels J; default ``floor(log2 N) - 1``, capped so that the level-J
        filter fits in the signal. Asking for more than the data allow raises.
    ci : {"chi2", "normal"}
        Interval method. "chi2" (default): ``eta v / chi2_{1-alpha/2}(eta)`` to
        ``eta v / chi2_{alpha/2}(eta)`` with equivalent degrees of freedom
        ``eta = max(M_j / 2^j, 1)`` (Percival & Walden 2000, eta_3), as the R gmwm package;
        always positive, skewed like the estimator's distribution, and free.
        "normal": ``v -+ z sqrt(S_j / M_j)`` where ``S_j = sum_{|tau|<M_j} s_tau^2`` is the
        estimate (eq. 11) of the asymptotic variance (eq. 10) from the wavelet coefficients'
        autocovariances, by FFT in O(M_j log M_j) per level; its lower end is clipped at
        ``NORMAL_CI_FLOOR * v`` (1e-3 v) when ``v - z sqrt(S_j / M_j)`` is not larger.
        (The robust estimator's intervals: :func:`stochmod.empirical.robust_wv.robust_wvar`.)
    alpha : float
        Significance level; the intervals have nominal coverage ``1 - alpha``.
    robust : bool
        If True, the robust M-estimate of each level's coefficient variance
        (:func:`stochmod.empirical.robust_wv.robust_wvar`: biweight or Huber, consistent at the
        Gaussian, with its own intervals and the ``contamination`` diagnostic).
    efficiency : float
        Gaussian efficiency in (0, 1] of the robust estimator (default 0.6; robust only).
    rho : {"biweight", "huber"}
        Chi function of the robust estimator (robust only).

    Returns
    -------
    WaveletVariance
        Levels, averaging times (s), wavelet variance (unit^2), intervals, ``M_j``.

    Raises
    ------
    InputError
        Empty, too short, NaN/inf, 2-D, non-numeric or constant `x`; bad `freq`, `levels`,
        `ci`, `alpha`, `efficiency`, `rho`; unknown or non-orthogonal wavelet.

    Notes
    -----
    Extra memory of the classical estimator: one copy of `x` for "chi2" (the pyramid runs in
    place, in chunks); for "normal" also the coefficients and their zero-padded FFT (about
    5 N more).
    """
    if robust:
        return robust_wvar(x, freq, efficiency, wavelet=wavelet, levels=levels, ci=ci,
                           alpha=alpha, rho=rho)
    return classical_wvar(x, freq, wavelet=wavelet, levels=levels, ci=ci, alpha=alpha)


def estimator_options(emp: WaveletVariance) -> dict[str, Any]:
    """The :func:`wvar` options that reproduce `emp`'s estimator (empty for the classical one;
    ``robust``, ``efficiency``, ``rho`` for a robust one)."""
    if not emp.robust:
        return {}
    return {"robust": True, "efficiency": emp.efficiency, "rho": emp.rho}


def same_estimator(x: ArrayLike, like: WaveletVariance, levels: int | None = None
                   ) -> WaveletVariance:
    """:func:`wvar` of `x` by the estimator that gave `like`: its sampling frequency, wavelet
    and, for a robust WV, its chi function and efficiency (default chi-square intervals); at
    `levels` levels (default as many as `like`). What a simulated series is compared to data
    with: a robust fit's band comes from robust WVs of its simulations."""
    return wvar(x, like.freq, wavelet=like.wavelet, levels=like.wv.size if levels is None else levels,
                **estimator_options(like))
