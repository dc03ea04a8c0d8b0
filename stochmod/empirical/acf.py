"""Sample autocorrelation and the first-order Gauss-Markov fit from its decay.

The classical reading of Quinchia et al. (2013), Section 4.1: a first-order GM process has the
autocorrelation ``R(tau) = sigma2 * exp(-beta |tau|)`` (eq. 11), so its correlation time
``Tc = 1/beta`` is the lag where the normalised autocorrelation falls to ``1/e`` and ``sigma2`` is
the zero-lag value. The paper also warns that the estimate is poor on short records, that real
MEMS data rarely look like a first-order GM, and that white noise hides the decay; the fit reports
these situations as ``caveats`` instead of returning silently wrong numbers.
"""

from __future__ import annotations

import math
from typing import Any

import attrs
import numpy as np
from numpy.typing import ArrayLike
from scipy import fft as sp_fft

from stochmod.core.checks import as_signal, check_freq, check_positive_int
from stochmod.core.errors import EstimationError, InputError
from stochmod.core.tables import format_table

__all__ = ["acovf", "acf", "GMAcfFit", "fit_gm_acf"]

_INV_E = math.exp(-1.0)
# Bartlett's variance of the AR(1) sample ACF at the 1/e lag, in units of k/N (k = Tc * freq):
# (1 + phi^2)(1 - phi^2k)/(1 - phi^2) - 2k phi^2k  ->  k (1 - 3 e^-2) as phi -> 1.
_MIN_RECORD_TC = 10.0  # below this many correlation times the reading is meaningless
_UNBIASED_RECORD_TC = 200.0  # below this the sample ACF is noticeably biased and noisy
_MIN_R2 = 0.95


def acovf(x: ArrayLike, max_lag: int | None = None, *, demean: bool = True) -> np.ndarray:
    """Biased sample autocovariance via FFT.

    ``c[k] = (1/n) * sum_{t=0}^{n-1-k} (x[t] - m)(x[t+k] - m)`` for ``k = 0..max_lag``.

    Parameters
    ----------
    x : array_like, shape (n,)
        The signal, in units u.
    max_lag : int, optional
        Largest lag in samples (default ``n - 1``).
    demean : bool
        Subtract the sample mean first.

    Returns
    -------
    ndarray, shape (max_lag + 1,)
        Autocovariance in u^2.
    """
    x = as_signal(x, name="x")
    n = x.size
    max_lag = n - 1 if max_lag is None else check_positive_int(max_lag, name="max_lag", minimum=0)
    if max_lag > n - 1:
        raise InputError(f"max_lag must be at most n - 1 = {n - 1}, got {max_lag}")
    if demean:
        x = x - x.mean()
    nfft = sp_fft.next_fast_len(n + max_lag, real=True)
    spec = sp_fft.rfft(x, nfft)
    cov = sp_fft.irfft(spec.real**2 + spec.imag**2, nfft)[: max_lag + 1]
    return cov / n


def acf(x: ArrayLike, max_lag: int | None = None) -> np.ndarray:
    """Sample autocorrelation (biased estimator, normalised by lag 0) via FFT.

    Equal to ``statsmodels.tsa.stattools.acf(x, nlags=max_lag, fft=True)``.

    Parameters
    ----------
    x : array_like, shape (n,)
        The signal (any unit; the result is dimensionless).
    max_lag : int, optional
        Largest lag in samples (default ``n - 1``).

    Returns
    -------
    ndarray, shape (max_lag + 1,)
        ``rho[0] = 1``, ``rho[k] = c[k] / c[0]``.

    Raises
    ------
    InputError
        Empty, non-finite or constant signal, or ``max_lag`` out of range.
    """
    cov = acovf(x, max_lag)
    if not cov[0] > 0:
        raise InputError("x is constant: its autocorrelation is undefined")
    return cov / cov[0]


@attrs.frozen
class GMAcfFit:
    """First-order Gauss-Markov parameters read from the sample autocorrelation.

    Attributes
    ----------
    beta : float
        Inverse correlation time in 1/s, ``1/Tc`` (NaN when the ACF never reaches 1/e).
    tc : float
        Correlation time in s: the lag where the normalised ACF first falls to 1/e
        (log-linear interpolation between the two bracketing lags).
    sigma2 : float
        Zero-lag autocovariance in u^2 (Quinchia eq. 11's sigma^2; includes any white noise).
    beta_se, tc_se, sigma2_se : float
        Asymptotic standard errors (Bartlett's formula for an AR(1) sample ACF at the 1/e lag,
        propagated to ``Tc`` through the slope of the exponential; ``sigma2`` from the variance of
        the sample variance of an AR(1)).
    beta_ls : float
        Inverse correlation time in 1/s of a least-squares fit of ``a exp(-beta tau)`` to the ACF
        over lags 1 .. ``fit_lags`` (log-linear regression on the decaying part).
    sigma2_ls : float
        The fitted amplitude ``a`` in u^2: the GM variance without the white noise at lag 0.
    r2 : float
        Coefficient of determination of that exponential on the normalised ACF (lags 1 ..
        three times the 1/e lag).
    fit_lags : int
        Number of lags used in the least-squares fit.
    freq : float
        Sampling frequency in Hz.
    n : int
        Record length in samples.
    lags : ndarray
        Lags in s of the stored ACF.
    rho : ndarray
        Normalised sample ACF at those lags.
    caveats : tuple of str
        Why the reading may be poor (Quinchia Section 4.1); empty when none applies.
    """

    beta: float
    tc: float
    sigma2: float
    beta_se: float
    tc_se: float
    sigma2_se: float
    beta_ls: float
    sigma2_ls: float
    r2: float
    fit_lags: int
    freq: float
    n: int
    lags: np.ndarray = attrs.field(repr=False)
    rho: np.ndarray = attrs.field(repr=False)
    caveats: tuple[str, ...] = ()

    @property
    def warnings(self) -> tuple[str, ...]:
        """Alias of :attr:`caveats`."""
        return self.caveats

    @property
    def record_tc(self) -> float:
        """Record length in correlation times, ``n / (freq * Tc)``."""
        return self.n / (self.freq * self.tc) if self.tc > 0 else math.nan

    def summary(self) -> str:
        """A readable table of the fit and its caveats."""
        rows = [
            ["Tc (1/e crossing)", "s", self.tc, self.tc_se],
            ["beta", "1/s", self.beta, self.beta_se],
            ["sigma2 (lag 0)", "u^2", self.sigma2, self.sigma2_se],
            ["beta (LS fit)", "1/s", self.beta_ls, math.nan],
            ["sigma2 (LS amplitude)", "u^2", self.sigma2_ls, math.nan],
            ["R^2 of exponential", "", self.r2, math.nan],
            ["record / Tc", "", self.record_tc, math.nan],
        ]
        text = format_table(
            ["quantity", "unit", "value", "std. error"], rows,
            title=(f"First-order GM from the autocorrelation (n = {self.n}, "
                   f"freq = {self.freq:g} Hz)"),
        )
        if self.caveats:
            text += "\ncaveats:\n" + "\n".join(f"  - {c}" for c in self.caveats)
        return text

    def to_dict(self) -> dict[str, Any]:
        """Scalar fields and caveats as a JSON-ready dict."""
        return {
            "beta": self.beta, "tc": self.tc, "sigma2": self.sigma2, "beta_se": self.beta_se,
            "tc_se": self.tc_se, "sigma2_se": self.sigma2_se, "beta_ls": self.beta_ls,
            "sigma2_ls": self.sigma2_ls, "r2": self.r2, "fit_lags": self.fit_lags,
            "freq": self.freq, "n": self.n, "caveats": list(self.caveats),
        }

    def coefficient_values(self, *, use_ls: bool = False) -> dict[str, float]:
        """``{"rate": beta (1/s), "variance": sigma2 (u^2)}`` of the exponential (``use_ls``:
        the least-squares pair); :func:`stochmod.fit.classical.acf_model` builds the model.

        Raises
        ------
        EstimationError
            The fit gave no usable pair (the message lists the caveats).
        """
        beta, sigma2 = (self.beta_ls, self.sigma2_ls) if use_ls else (self.beta, self.sigma2)
        if not (np.isfinite(beta) and beta > 0 and np.isfinite(sigma2) and sigma2 > 0):
            raise EstimationError(
                f"no usable exponential decay (rate={beta!r} 1/s, variance={sigma2!r}); caveats: "
                + ("; ".join(self.caveats) or "none")
            )
        return {"rate": float(beta), "variance": float(sigma2)}


def _crossing(rho: np.ndarray, level: float) -> float:
    """First fractional lag (samples) where rho falls to `level`; NaN if it never does."""
    below = np.flatnonzero(rho <= level)
    if below.size == 0:
        return math.nan
    k = int(below[0])
    a, b = rho[k - 1], rho[k]
    if b > 0:  # exact for an exponential
        return k - 1 + (math.log(a) - math.log(level)) / (math.log(a) - math.log(b))
    return k - 1 + (a - level) / (a - b)


def _ls_exponential(rho: np.ndarray, k_end: int) -> tuple[float, float, int]:
    """Regress log rho[1..k_end] on the lag: returns (slope per sample, intercept, lags used)."""
    k = np.arange(1, k_end + 1)
    r = rho[1 : k_end + 1]
    keep = r > 0
    k, r = k[keep], r[keep]
    if k.size < 2:
        return math.nan, math.nan, int(k.size)
    slope, intercept = np.polyfit(k.astype(float), np.log(r), 1)
    return float(slope), float(intercept), int(k.size)


def fit_gm_acf(x: ArrayLike, freq: float, *, max_lag: int | None = None) -> GMAcfFit:
    """Fit a first-order Gauss-Markov process to the decay of the sample autocorrelation.

    Parameters
    ----------
    x : array_like, shape (n,)
        Static sensor error signal in units u (turn-on bias is removed by demeaning).
    freq : float
        Sampling frequency in Hz.
    max_lag : int, optional
        Largest lag computed, in samples (default ``n - 1``: the whole record).

    Returns
    -------
    GMAcfFit
        ``Tc`` at the 1/e crossing, ``sigma2`` at lag 0 (Quinchia eq. 11), a least-squares
        exponential on the decaying part, standard errors and caveats.

    Notes
    -----
    Caveats are reported when the ACF never reaches 1/e, when it does so within one lag (white
    noise dominates the zero-lag value), when the record is shorter than 10 Tc (meaningless) or
    200 Tc (noticeably biased towards short Tc and noisy), and when the exponential fits poorly
    (R^2 < 0.95: not first-order GM; consider AR(p) after de-noising, Quinchia Section 4.2).
    """
    x = as_signal(x, name="x", min_length=3)
    freq = check_freq(freq)
    cov = acovf(x, max_lag)
    if not cov[0] > 0:
        raise InputError("x is constant: its autocorrelation is undefined")
    rho = cov / cov[0]
    n = x.size
    sigma2 = float(cov[0])
    caveats: list[str] = []

    k_e = _crossing(rho, _INV_E)
    if math.isnan(k_e):
        caveats.append(
            f"the autocorrelation never drops below 1/e within {rho.size - 1} lags "
            f"({(rho.size - 1) / freq:g} s): Tc is not identifiable from this record"
        )
        tc = beta = tc_se = beta_se = math.nan
        k_end = rho.size - 1
    else:
        tc = k_e / freq
        beta = 1.0 / tc
        # Bartlett: var(rho_k) ~ (k/N)(1 - 3 e^-2) for an AR(1) near the unit circle at rho = 1/e,
        # and d rho / d tau = -rho / Tc, so se(Tc)/Tc = e * se(rho).
        phi = math.exp(-1.0 / max(k_e, 1e-12))
        kk = max(k_e, 1.0)
        var_rho = ((1 + phi**2) * (1 - _INV_E**2) / (1 - phi**2) - 2 * kk * _INV_E**2) / n
        tc_se = tc * math.e * math.sqrt(max(var_rho, 0.0))
        beta_se = beta * tc_se / tc
        k_end = min(rho.size - 1, max(2, int(math.ceil(3 * k_e))))
        if rho[1] <= _INV_E:
            caveats.append(
                f"the autocorrelation falls to 1/e within one lag (rho[1] = {rho[1]:.3g}): white "
                "noise dominates the zero-lag value and Tc is not resolved; de-noise first "
                "(Quinchia Section 5.2) or model white noise plus GM"
            )
        record_tc = n / k_e
        if record_tc < _MIN_RECORD_TC:
            caveats.append(
                f"the record is only {record_tc:.3g} Tc long (< {_MIN_RECORD_TC:g} Tc): the sample "
                "autocorrelation cannot resolve the decay (random walk or a drift look like this)"
            )
        elif record_tc < _UNBIASED_RECORD_TC:
            caveats.append(
                f"the record is {record_tc:.3g} Tc long (< {_UNBIASED_RECORD_TC:g} Tc): the sample "
                "autocorrelation is biased low, so Tc is underestimated, and it is noisy "
                f"(relative std. error {tc_se / tc:.2g})"
            )

    phi = math.exp(-1.0 / k_e) if k_e > 0 and not math.isnan(k_e) else 0.0
    sigma2_se = sigma2 * math.sqrt(2 * (1 + phi**2) / max(1 - phi**2, 1e-300) / n)

    k_ls = k_end if math.isnan(k_e) else min(rho.size - 1, max(2, int(math.ceil(k_e))) * 2)
    slope, intercept, used = _ls_exponential(rho, k_ls)
    if math.isnan(slope) or slope >= 0:
        beta_ls = sigma2_ls = r2 = math.nan
    else:
        beta_ls = -slope * freq
        sigma2_ls = sigma2 * math.exp(intercept)
        lags = np.arange(1, k_end + 1)
        fitted = np.exp(intercept + slope * lags)
        resid = rho[1 : k_end + 1] - fitted
        total = rho[1 : k_end + 1] - rho[1 : k_end + 1].mean()
        denom = float(total @ total)
        r2 = 1.0 - float(resid @ resid) / denom if denom > 0 else math.nan
    if not math.isnan(k_e) and not (r2 >= _MIN_R2):
        caveats.append(
            f"the autocorrelation does not look exponential (R^2 = {r2:.3g} < {_MIN_R2}): a "
            "first-order GM is a poor model; consider AR(p) after de-noising (Quinchia Section 4.2)"
        )
    keep = min(rho.size, max(k_end + 1, 2))
    return GMAcfFit(
        beta=beta, tc=tc, sigma2=sigma2, beta_se=beta_se, tc_se=tc_se, sigma2_se=sigma2_se,
        beta_ls=beta_ls, sigma2_ls=sigma2_ls, r2=r2, fit_lags=used, freq=freq, n=n,
        lags=np.arange(keep) / freq, rho=rho[:keep].copy(), caveats=tuple(caveats),
    )
