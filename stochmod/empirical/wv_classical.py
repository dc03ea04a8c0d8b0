"""The wavelet-variance result and the classical MODWT estimator (eq. 9 of Stebler et al.
2014) with its intervals; :func:`stochmod.empirical.wavelet_variance.wvar` chooses between it and
the robust estimator (:mod:`stochmod.empirical.robust_wv`).

Levels j = 1..J; averaging time ``tau_j = 2^(j-1) / freq`` seconds (the Haar filter of level
j averages ``2^(j-1)`` samples per half), so that the Haar wavelet variance is half the
overlapping Allan variance at ``tau_j``. Only the ``M_j = N - L_j + 1`` interior wavelet
coefficients enter the estimate (no boundary rule, unbiased).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import attrs
import numpy as np
import scipy.fft
from numpy.typing import ArrayLike
from scipy.special import chdtri, ndtri

from stochmod.core.fields import array_field
from stochmod.core.checks import as_signal, check_alpha, check_finite, check_freq
from stochmod.core.errors import InputError
from stochmod.core.tables import format_number, format_table
from stochmod.core.filters import check_level, default_levels, filter_width, modwt_filters
from stochmod.empirical.modwt import pyramid

if TYPE_CHECKING:
    from stochmod.empirical.contamination import Contamination

__all__ = ["WaveletVariance", "classical_wvar", "chi2_interval", "CI_METHODS", "NORMAL_CI_FLOOR"]

CI_METHODS = ("chi2", "normal")

#: The "normal" interval's lower end is clipped at ``NORMAL_CI_FLOOR * wv`` (relative floor).
NORMAL_CI_FLOOR = 1e-3


@attrs.frozen
class WaveletVariance:
    """Empirical wavelet variance of one signal, with confidence intervals.

    Attributes
    ----------
    levels : ndarray of int, shape (J,)
        Levels ``1..J``.
    tau : ndarray, shape (J,)
        Averaging time ``2^(j-1) / freq`` in seconds.
    wv : ndarray, shape (J,)
        Wavelet variance, unit^2 (the signal's unit squared).
    ci_low, ci_high : ndarray, shape (J,)
        Bounds of the ``100 (1 - alpha)`` % confidence interval, unit^2.
    n_coef : ndarray of int, shape (J,)
        ``M_j``, the number of interior wavelet coefficients averaged at each level.
    freq : float
        Sampling frequency, Hz.
    wavelet : str
        PyWavelets name of the wavelet filter.
    n : int
        Signal length N (samples).
    ci_method : str
        ``"chi2"`` or ``"normal"``.
    alpha : float
        Significance level of the intervals.
    robust : bool
        Whether ``wv`` is the robust M-estimate (:mod:`stochmod.empirical.robust_wv`).
    efficiency : float
        Gaussian efficiency the robust estimator was tuned to (1 for the classical one).
    rho : str or None
        Chi function of the robust estimator ("biweight", "huber").
    tuning : float
        Its tuning constant c (inf for the classical estimator).
    variance_ratio : ndarray, shape (J,)
        ``kappa_j``: variance of this estimator over that of the classical one at each level,
        as used by its intervals and by the GMWM weighting (ones for the classical).
    contamination : Contamination or None
        The robust estimator's outlier diagnostic.
    """

    levels: np.ndarray = array_field()
    tau: np.ndarray = array_field()
    wv: np.ndarray = array_field()
    ci_low: np.ndarray = array_field()
    ci_high: np.ndarray = array_field()
    n_coef: np.ndarray = array_field()
    freq: float
    wavelet: str
    n: int
    ci_method: str
    alpha: float
    robust: bool = False
    efficiency: float = 1.0
    rho: str | None = None
    tuning: float = float("inf")
    variance_ratio: np.ndarray = array_field(
        default=attrs.Factory(lambda self: np.ones(self.wv.size), takes_self=True))
    contamination: Contamination | None = None

    def summary(self) -> str:
        """Table of level, tau [s], wavelet variance, interval bounds and M_j."""
        kind = "Wavelet variance"
        if self.robust:
            kind = (f"Robust wavelet variance ({self.rho}, efficiency "
                    f"{format_number(self.efficiency)}, c = {format_number(self.tuning, 4)})")
        title = (
            f"{kind} ({self.wavelet}, N = {self.n}, "
            f"freq = {format_number(self.freq)} Hz, "
            f"{format_number(100 * (1 - self.alpha))}% CI: {self.ci_method})"
        )
        rows = [
            (int(j), t, v, lo, hi, int(m))
            for j, t, v, lo, hi, m in zip(
                self.levels, self.tau, self.wv, self.ci_low, self.ci_high, self.n_coef
            )
        ]
        headers = ["level", "tau [s]", "WV", "CI low", "CI high", "M_j"]
        table = format_table(headers, rows, title=title)
        if self.contamination is None:
            return table
        return table + "\n\n" + self.contamination.summary()

    def robust_info(self) -> dict[str, Any] | None:
        """JSON-safe robust settings (rho, efficiency, tuning, variance_ratio) and the
        contamination diagnostic; None for the classical estimator."""
        if not self.robust:
            return None
        full = self.to_dict()
        return {key: full[key] for key in ("rho", "efficiency", "tuning", "variance_ratio",
                                           "contamination")}

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dict of every field (arrays as lists of Python numbers)."""
        return {
            "levels": [int(j) for j in self.levels],
            "tau": [float(t) for t in self.tau],
            "wv": [float(v) for v in self.wv],
            "ci_low": [float(v) for v in self.ci_low],
            "ci_high": [float(v) for v in self.ci_high],
            "n_coef": [int(m) for m in self.n_coef],
            "freq": float(self.freq),
            "wavelet": self.wavelet,
            "n": int(self.n),
            "ci_method": self.ci_method,
            "alpha": float(self.alpha),
            "robust": bool(self.robust),
            "efficiency": float(self.efficiency),
            "rho": self.rho,
            "tuning": None if np.isinf(self.tuning) else float(self.tuning),  # classical: None
            "variance_ratio": [float(r) for r in self.variance_ratio],
            "contamination": None if self.contamination is None else self.contamination.to_dict(),
        }


def chi2_interval(
    wv: np.ndarray, n_coef: np.ndarray, levels: np.ndarray, alpha: float
) -> tuple[np.ndarray, np.ndarray]:
    """Equivalent-degrees-of-freedom interval, eta_3 = max(M_j / 2^j, 1) (P&W 2000, 8.4)."""
    eta = np.maximum(n_coef / 2.0**levels, 1.0)
    upper_q = chdtri(eta, alpha / 2.0)  # chi2_{1 - alpha/2}(eta)
    lower_q = chdtri(eta, 1.0 - alpha / 2.0)  # chi2_{alpha/2}(eta)
    return eta * wv / upper_q, eta * wv / lower_q


def _sum_squared_acov(buf: np.ndarray, m: int) -> float:
    """``sum_{|tau| < M} s_tau^2`` with ``s_tau = (1/M) sum_k W_k W_{k+|tau|}`` (eq. 11).

    ``buf[:m]`` holds W; ``buf[m:]`` is zero padding (at least m - 1 long). By Parseval,
    the sum of the squared linear autocorrelation equals ``sum_k |X_k|^4 / P`` over the
    length-P DFT of the zero-padded sequence: one real FFT, O(M log M).
    """
    p = scipy.fft.next_fast_len(2 * m - 1, real=True)
    spec = scipy.fft.rfft(buf[:p]).view(np.float64)  # interleaved (re, im)
    np.square(spec, out=spec)
    power = np.add(spec[0::2], spec[1::2], out=spec[0::2])  # |X_k|^2, in place
    total = 2.0 * float(np.dot(power, power)) - power[0] ** 2
    if p % 2 == 0:
        total -= power[-1] ** 2
    return total / p / (m * m)


def classical_wvar(
    x: ArrayLike,
    freq: float,
    wavelet: str = "haar",
    levels: int | None = None,
    ci: str = "chi2",
    alpha: float = 0.05,
    *,
    name: str = "x",
) -> WaveletVariance:
    """Classical (mean of squares) MODWT wavelet variance at levels 1..J with intervals; the
    estimator behind :func:`stochmod.empirical.wavelet_variance.wvar` (``robust=False``), whose
    docstring gives the parameters, the interval methods, the result and the errors; `name` is
    the signal's name in error messages.

    Extra memory: one copy of `x` for "chi2" (the pyramid runs in place, in chunks); for
    "normal" also the coefficients and their zero-padded FFT (about 5 N more).
    """
    x = as_signal(x, name=name, min_length=2, finite=False)  # level 1's sum proves it below
    freq = check_freq(freq)
    modwt_filters(wavelet)
    n = x.size
    n_levels = (
        default_levels(n, wavelet) if levels is None else check_level(n, levels, wavelet, "levels")
    )
    if ci not in CI_METHODS:
        raise InputError(f"ci must be one of {CI_METHODS}, got {ci!r}")
    alpha = check_alpha(alpha)

    js = np.arange(1, n_levels + 1)
    wv = np.empty(n_levels)
    n_coef = np.empty(n_levels, dtype=np.int64)
    buf = None
    if ci == "normal":
        m1 = n - filter_width(1, wavelet) + 1
        buf = np.zeros(scipy.fft.next_fast_len(2 * m1 - 1, real=True))
        s_hat = np.empty(n_levels)
    previous = n
    for j, sumsq, m in pyramid(x, n_levels, wavelet, buf):
        wv[j - 1] = sumsq / m
        n_coef[j - 1] = m
        if buf is not None:
            buf[m:previous] = 0.0  # the previous level's coefficients: now zero padding
            previous = m
            s_hat[j - 1] = _sum_squared_acov(buf, m)
    if not np.isfinite(wv).all():  # every sample enters level 1: a NaN or inf, or an overflow
        check_finite(x, name)
        raise InputError(f"the wavelet variance of {name} overflows float64 (|{name}| up to "
                         f"{np.abs(x).max():.3g}): rescale the signal, e.g. to another unit")
    # a constant signal has W_1 = x_t - x_{t-1} = 0 exactly, so only then is the min/max pass
    # needed (a level-1 WV can also underflow to 0 on a non-constant signal of tiny values)
    if wv[0] == 0.0 and x.max() == x.min():
        raise InputError("x is constant: its wavelet variance is zero at every level")
    if ci == "chi2":
        low, high = chi2_interval(wv, n_coef, js, alpha)
    else:
        half = ndtri(1.0 - alpha / 2.0) * np.sqrt(s_hat / n_coef)
        low = np.maximum(wv - half, NORMAL_CI_FLOOR * wv)
        high = wv + half
    arrays = [js, 2.0 ** (js - 1) / freq, wv, low, high, n_coef]
    for a in arrays:
        a.setflags(write=False)
    return WaveletVariance(
        *arrays, freq=freq, wavelet=wavelet, n=n, ci_method=ci, alpha=alpha
    )
