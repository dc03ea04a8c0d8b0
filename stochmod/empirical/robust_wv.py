"""Robust wavelet variance: an M-estimate of each level's wavelet-coefficient variance.

The classical estimator (eq. 9 of Stebler et al. 2014) averages the squared MODWT coefficients,
so a handful of spikes inflates it at every level. Following Guerrier, Molinari,
Victoria-Feser and Xu (2022, JASA 117, "Robust two-step wavelet-based inference for time
series models"; the ``robust = TRUE`` option of the R gmwm package), the level-j wavelet
variance ``nu_j`` is instead the M-estimate of scale of the interior coefficients
``W_{j,t}`` (of the signal screened for isolated outliers, below): the largest root of

    (1 / M_j) sum_t chi(W_{j,t}^2 / nu_j) = delta,    delta = E[chi(Z^2)],  Z ~ N(0, 1),

with ``chi(r^2) = psi_c(r)^2`` for Tukey's biweight ``psi_c(r) = r (1 - r^2/c^2)^2`` on
``|r| <= c`` (0 beyond: a coefficient more than ``c`` robust standard deviations away gets no
weight at all), or ``chi(r^2) = min(r^2, c^2)`` for Huber's proposal 2. ``delta`` makes the
estimate consistent at the Gaussian (``nu_j`` is the wavelet variance when the coefficients
are Gaussian); ``c`` is tuned so that the estimator's asymptotic efficiency relative to the
classical estimator, for independent Gaussian coefficients,

    eff(c) = B^2 / (2 Var[chi(Z^2)]),    B = E[chi'(Z) Z] = E[chi(Z^2) (Z^2 - 1)]   (Stein),

equals the requested value. All Gaussian expectations are closed forms in the truncated
moments ``E[Z^(2k); |Z| <= c]`` (regularised incomplete gamma functions).

Asymptotic variance. Linearising the estimating equation,
``nu_hat - nu = (2 nu / B) (1/M) sum_t (chi(Z_t^2) - delta) + o_p``, so
``var(nu_hat) = (4 nu^2 / B^2) LRV / M`` with ``LRV = sum_h cov(chi(Z_0^2), chi(Z_h^2))`` the
long-run variance of the bounded scores along the (autocorrelated) coefficient series. For a
Gaussian series with coefficient autocorrelation ``rho_h`` the Hermite expansion
``chi(z^2) = delta + sum_k b_2k h_2k(z)`` (normalised Hermite polynomials) gives
``cov(chi(Z_0^2), chi(Z_h^2)) = sum_k b_2k^2 rho_h^(2k)``, hence
``LRV = sum_k b_2k^2 R_k`` with ``R_k = sum_h rho_h^(2k)``. The first term (``b_2^2 = B^2 / 2``)
is exactly the classical estimator's variance ``2 nu^2 R_1 / M``; the others add
``(1/eff - 1)`` times it at most (``1 <= R_k <= R_1``), so the variance ratio
``kappa_j = var(robust) / var(classical)`` lies in ``[1 + (1/eff - 1)/R_1, 1/eff]``: the
efficiency loss is ``1/eff`` for independent coefficients and shrinks at deep levels, whose
coefficients are strongly correlated. Two estimates of ``kappa_j`` are offered:

- ``ci="chi2"`` (default): the bound ``kappa_j = 1/eff`` (what the R gmwm package does),
  conservative, free: the chi-square interval with ``eff * eta_j`` equivalent degrees of
  freedom (``eta_j = max(M_j / 2^j, 1)``);
- ``ci="normal"``: the sandwich itself, with ``rho_h`` estimated by FFT from the coefficients
  clipped at ``+-c sqrt(nu_hat)`` (so outliers do not distort it), the same spectral route
  as the classical normal interval (eq. 11): ``R_1`` is half the sum over all lags of the
  squared sample autocorrelations (the periodogram's ``E[I^2] = 2 S^2``), ``R_k, k >= 2``
  the plain sums.

Screening for isolated outliers. A spike of size A at one sample touches 2^j coefficients
of level j, each by about ``A / 2^(j/2)`` level-j standard deviations (white noise): the
M-scale rejects it at the first levels, but from the level where that falls below c it
passes, in a share ``2^j eps`` of the coefficients (eps the spikes' share of the samples)
that doubles with each level. The bias is then level-dependent (low where the spikes are
rejected, high just below, where they are dense and small): a model absorbs it as a
spurious colour (a GM's beta 40 % high for 0.05 % spikes of 25 sd), where the classical
estimator's white bias (``eps A^2 / 2^j``) would only inflate a WN. So the spikes are
removed before the decomposition, where they are largest and sparse: on the level-1 Haar
coefficients ``x_{t+1} - x_t`` (whatever the wavelet), a coefficient is rejected beyond
``c`` robust sd (c of the biweight at the requested efficiency, also for Huber), and two
consecutive rejected ones of opposite signs at most :data:`MAX_PATCH` samples apart bound
a patch (a jump away and back), replaced by the straight line between its neighbours
(:func:`isolated_patches`, :func:`replace_patches`). Every level is then the M-estimate of
the screened signal. Longer bursts, steps and lone rejections are left to the per-level
M-scale. For Gaussian data a pair of opposite rejections is rare (for white noise 9e-8 per
sample at efficiency 0.6, 1.4e-5 at 0.3), and a replaced sample changes a level by O(1/N).

Computation. Each level costs one pass over its coefficients in cache-sized chunks: a robust
start ``nu_0`` (median of ``W^2`` on a subsample / 0.4549), the power sums of the
coefficients with ``W^2 <= c^2 nu_0 / 2`` (certainly inside the biweight's support for any
root in ``[nu_0 / 2, 2 nu_0]``: ``chi`` is a polynomial there) and the indices of the few
others; the root is then found exactly (Brent) on this summary, and the bracket widened if the
root is outside it. For Haar with chi-square intervals the pass is the pyramid's own level
step (:func:`_haar_scales`: no coefficient array), one compiled loop
(:mod:`stochmod.empirical.haar_jit`); its level-1 pass also screens, and the pyramid starts
again from the screened signal only when some samples were replaced. The coefficients are scaled by a power of two so that the
powers up to ``u^5`` stay in float32's range whatever the signal's unit.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Iterator
from typing import Any

import attrs
import numpy as np
import scipy.fft
from numpy.typing import ArrayLike
from scipy import special

from stochmod.core.fields import array_field
from stochmod.core.checks import as_signal, check_alpha, check_freq
from stochmod.core.errors import EstimationError, InputError
from stochmod.empirical import haar_jit, modwt
from stochmod.core.filters import check_level, default_levels, filter_width, modwt_filters
from stochmod.empirical.modwt import pyramid
from stochmod.empirical.contamination import Contamination
from stochmod.empirical.wv_classical import CI_METHODS, NORMAL_CI_FLOOR, WaveletVariance, classical_wvar

__all__ = [
    "RHO_FUNCTIONS",
    "DEFAULT_EFFICIENCY",
    "ScaleRho",
    "scale_rho",
    "check_efficiency",
    "MScale",
    "m_scale",
    "Contamination",
    "NoRootError",
    "robust_wvar",
    "sandwich_ratio",
    "MAX_PATCH",
    "isolated_patches",
    "replace_patches",
]

#: Names of the supported chi functions.
RHO_FUNCTIONS = ("biweight", "huber")
#: Default Gaussian efficiency (as the R gmwm package).
DEFAULT_EFFICIENCY = 0.6
_CHUNK = 1 << 16
_MEDIAN_CHI2_1 = 0.45493642311957283  # median of chi^2 with one degree of freedom
_HERMITE_TERMS = 10  # Hermite orders 2, 4, ..., 2K in the sandwich (the rest bounded by R_K+1)
_N_WORST = 5
#: Longest run of samples the screening replaces as one isolated outlier (module notes).
MAX_PATCH = 4
#: From this many coefficients on, the power sums run in single precision (twice the SIMD
#: width; relative error ~1e-6, chunk sums accumulated in double): far below the estimate's
#: own sampling error, which is above 1e-3 for M_j <= 2^20 coefficients (as wv_covariance).
_SINGLE_MIN = 1 << 17


def check_efficiency(efficiency: float) -> float:
    """Return a Gaussian efficiency as a float in (0, 1], or raise :class:`InputError`."""
    if isinstance(efficiency, bool):
        raise InputError(f"efficiency must be a number in (0, 1], got {efficiency!r}")
    try:
        value = float(efficiency)
    except (TypeError, ValueError):
        raise InputError(f"efficiency must be a number in (0, 1], got {efficiency!r}") from None
    if not 0.0 < value <= 1.0:  # also refuses NaN
        raise InputError(
            f"efficiency must be in (0, 1] (the robust estimator's Gaussian efficiency relative "
            f"to the classical wavelet variance; 1 = classical), got {efficiency!r}"
        )
    return value


def _truncated_moments(c: float, kmax: int) -> np.ndarray:
    """``E[Z^(2k); |Z| <= c]`` for k = 0..kmax, Z standard normal (incomplete gamma form)."""
    k = np.arange(kmax + 1, dtype=np.float64)
    full = np.exp(k * math.log(2.0) + special.gammaln(k + 0.5) - 0.5 * math.log(math.pi))
    return full * special.gammainc(k + 0.5, 0.5 * c * c)


@attrs.frozen
class ScaleRho:
    """The chi function of a scale M-estimator, ``chi(u)`` with ``u = r^2``.

    ``chi(u) = sum_p coef[p] u^p`` for ``u <= c^2`` and ``outside`` beyond.

    Attributes
    ----------
    name : str
        ``"biweight"`` (``chi = psi_c^2``, redescending) or ``"huber"`` (``min(u, c^2)``).
    c : float
        Tuning constant (robust standard deviations).
    coef : tuple of float
        Polynomial coefficients in u on ``[0, c^2]``.
    outside : float
        Value of chi beyond c.
    """

    name: str
    c: float
    coef: tuple[float, ...]
    outside: float

    def chi(self, u: ArrayLike) -> np.ndarray:
        """``chi(u)`` for squared standardised residuals ``u >= 0``."""
        u = np.asarray(u, dtype=np.float64)
        inside = np.polynomial.polynomial.polyval(u, self.coef)
        return np.where(u <= self.c * self.c, inside, self.outside)

    @functools.cached_property
    def _moments(self) -> tuple[float, float, float]:
        a = np.asarray(self.coef)
        P = a.size - 1
        mu = _truncated_moments(self.c, 2 * P + 1)
        tail0, tail2 = 1.0 - mu[0], 1.0 - mu[1]
        m1 = float(a @ mu[: P + 1]) + self.outside * tail0
        m2 = float(a @ np.array([[mu[p + q] for q in range(P + 1)] for p in range(P + 1)]) @ a)
        m2 += self.outside**2 * tail0
        slope = float(a @ (mu[1 : P + 2] - mu[: P + 1])) + self.outside * (tail2 - tail0)
        return m1, slope, m2 - m1 * m1

    @property
    def consistency(self) -> float:
        """``delta = E[chi(Z^2)]``: the right-hand side that makes the estimate consistent."""
        return self._moments[0]

    @property
    def slope(self) -> float:
        """``B = E[chi'(Z) Z]`` (with chi as a function of r), ``-2 nu d/dnu E[chi(W^2/nu)]``."""
        return self._moments[1]

    @property
    def score_variance(self) -> float:
        """``Var[chi(Z^2)]``."""
        return self._moments[2]

    @property
    def efficiency(self) -> float:
        """Asymptotic efficiency vs the mean of squares for iid Gaussian data, ``B^2 / (2 Var chi)``."""
        return self.slope**2 / (2.0 * self.score_variance)

    @property
    def rejection_probability(self) -> float:
        """``P(|Z| > c)``: share of coefficients beyond c for Gaussian data."""
        return float(special.erfc(self.c / math.sqrt(2.0)))

    @functools.cached_property
    def hermite_squares(self) -> np.ndarray:
        """``b_2k^2``, k = 1..K: squared coefficients of chi on the normalised Hermite
        polynomials ``h_2k = He_2k / sqrt((2k)!)``; their total is ``Var chi``."""
        n_max = 2 * _HERMITE_TERMS
        nodes, weights = np.polynomial.legendre.leggauss(160)
        z = 0.5 * self.c * (nodes + 1.0)  # [0, c]: chi is even, so are the h_2k
        w = 0.5 * self.c * weights * np.exp(-0.5 * z * z) / math.sqrt(2.0 * math.pi)
        f = self.chi(z * z) * w
        h_prev, h = np.ones_like(z), z.copy()
        hc_prev, hc = 1.0, self.c  # h_n(c), for the tail integral of a constant outside
        out = []
        for n in range(2, n_max + 1):
            h_prev, h = h, (z * h - math.sqrt(n - 1) * h_prev) / math.sqrt(n)
            hc_prev_n = hc  # h_{n-1}(c)
            hc_prev, hc = hc, (self.c * hc - math.sqrt(n - 1) * hc_prev) / math.sqrt(n)
            if n % 2 == 0:
                # int_c^inf He_n phi = He_{n-1}(c) phi(c): on the h scale h_{n-1}(c) phi(c)/sqrt(n)
                tail = hc_prev_n * math.exp(-0.5 * self.c**2) / math.sqrt(2.0 * math.pi * n)
                out.append(2.0 * (float(f @ h) + self.outside * tail))
        return np.square(np.array(out))


def _biweight_coef(c: float) -> tuple[float, ...]:
    # psi_c(r)^2 = u (1 - u/c^2)^4
    binom = (1.0, -4.0, 6.0, -4.0, 1.0)
    return (0.0, *(b / c ** (2 * i) for i, b in enumerate(binom)))


def _brentq(f: Any, a: float, b: float, **tolerances: float) -> float:
    """:func:`scipy.optimize.brentq`, imported at the first call (scipy.optimize is half a
    second of import, and every command that loads the plugins imports this module)."""
    from scipy.optimize import brentq

    return brentq(f, a, b, **tolerances)

def _make(rho: str, c: float) -> ScaleRho:
    if rho == "biweight":
        return ScaleRho("biweight", c, _biweight_coef(c), 0.0)
    return ScaleRho("huber", c, (0.0, 1.0), c * c)


@functools.lru_cache(maxsize=64)
def scale_rho(efficiency: float = DEFAULT_EFFICIENCY, rho: str = "biweight") -> ScaleRho:
    """The chi function tuned to a Gaussian `efficiency`.

    Parameters
    ----------
    efficiency : float
        Asymptotic efficiency in (0, 1) relative to the classical estimator for iid
        Gaussian coefficients (the biweight's c is found on the branch where the estimating
        equation decreases in nu, ``B > 0``, i.e. c above about 2.45).
    rho : {"biweight", "huber"}
        Chi function.

    Returns
    -------
    ScaleRho
    """
    efficiency = check_efficiency(efficiency)
    if rho not in RHO_FUNCTIONS:
        raise InputError(f"rho must be one of {RHO_FUNCTIONS}, got {rho!r}")
    if efficiency >= 1.0:
        raise InputError("efficiency 1 is the classical estimator: it has no tuning constant")
    low = 1e-3
    if rho == "biweight":  # below the root of B the equation has no consistent branch
        low = _brentq(lambda c: _make(rho, c).slope, 1.5, 3.5, xtol=1e-14)
        low *= 1.0 + 1e-9
    c = _brentq(lambda c: _make(rho, c).efficiency - efficiency, low, 200.0, xtol=1e-13,
                        rtol=1e-14)
    return _make(rho, c)


@attrs.frozen
class MScale:
    """Robust scale of one coefficient series.

    Attributes
    ----------
    variance : float
        The M-estimate ``nu_hat`` (unit^2).
    n_rejected : int
        Coefficients beyond ``c sqrt(nu_hat)`` (weight 0 for the biweight, clipped for Huber).
    worst : ndarray of int
        Indices of the largest ``|W|`` beyond ``c sqrt(nu_hat / 2)`` (at most n_worst),
        largest first.
    worst_score : ndarray
        Their standardised size ``|W| / sqrt(nu_hat)``.
    """

    variance: float
    n_rejected: int
    worst: np.ndarray = array_field()
    worst_score: np.ndarray = array_field()


def _block_buffers(n: int, single: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Work buffers of :func:`_accumulate` for blocks of up to `n` coefficients: the squares
    (float64), the higher powers (float32 if `single`) and the flags."""
    n = min(_CHUNK, n)
    return (np.empty(n), np.empty((2, n), dtype=np.float32 if single else np.float64),
            np.empty(n, dtype=bool))


def _accumulate(w: np.ndarray, core: float, sums: np.ndarray,
                bufs: tuple[np.ndarray, np.ndarray, np.ndarray]) -> np.ndarray:
    """Add ``sum u^p`` (p = 1..5) of ``u = w^2`` over the block's ``u <= core`` to
    ``sums[1:]`` (in the precision of the power buffers, :func:`_block_buffers`); return the
    block indices of the others (einsum dot products: no BLAS threads, see
    :mod:`stochmod.empirical.modwt`)."""
    squares, powers, flags = bufs
    n = w.size
    u = np.square(w, out=squares[:n])
    if powers.dtype != u.dtype:  # u = fl32(w^2): astype's contiguous cast beats a casting ufunc
        u = u.astype(powers.dtype)
    u2, u3 = powers[:, :n]
    local = np.flatnonzero(np.greater(u, core, out=flags[: w.size]))
    if local.size:
        u[local] = 0.0
    np.multiply(u, u, out=u2)
    np.multiply(u2, u, out=u3)
    sums[1] += u.sum()
    sums[2] += u2.sum()
    sums[3] += u3.sum()
    sums[4] += np.einsum("i,i->", u2, u2)
    sums[5] += np.einsum("i,i->", u3, u2)
    return local


def _power_sums(w: np.ndarray, scale: float, core: float
                ) -> tuple[np.ndarray, np.ndarray]:
    """``sum u^p`` (p = 1..5) of ``u = w^2 / scale`` over the coefficients with
    ``w^2 <= core``, and the indices of the others; in chunks that stay in cache."""
    sums = np.zeros(6)
    big: list[np.ndarray] = []
    bufs = _block_buffers(w.size, w.size >= _SINGLE_MIN)
    for s in range(0, w.size, _CHUNK):
        local = _accumulate(w[s : s + _CHUNK], core, sums, bufs)
        if local.size:
            big.append(local + s)
    sums /= scale ** np.arange(6.0)
    idx = np.concatenate(big) if big else np.empty(0, dtype=np.intp)
    return sums, idx


def _sorted_score(ub: np.ndarray, sums: np.ndarray, coef: np.ndarray, outside: float,
                  c2: float, delta: float, M: int, v_max: float = np.inf
                  ) -> tuple[np.ndarray, Any]:
    """The estimating function ``F(v) = mean(chi(u / v)) - delta`` for ``v <= v_max`` from the
    power sums of the core and the sorted others (those inside the support for v form a
    prefix; only the prefix that some ``v <= v_max`` reaches is summed)."""
    powers = np.arange(6.0)
    ub_sorted = np.sort(ub)
    reach = int(np.searchsorted(ub_sorted, c2 * v_max, side="right"))
    table = np.empty((5, reach + 1))  # column k: power sums (p = 1..5) of the k smallest
    table[:, 0] = 0.0
    for p in range(5):
        table[p, 1:] = ub_sorted[:reach] if p == 0 else table[p - 1, 1:] * ub_sorted[:reach]
    cum = np.cumsum(table, axis=1)

    def score(v: float) -> float:
        if not v <= v_max:
            raise ValueError(f"the score was set up for v <= {v_max}, not {v}")
        k = int(np.searchsorted(ub_sorted, c2 * v, side="right"))
        poly = coef * v**-powers
        total = float((sums[1:] + cum[:, k]) @ poly[1:])
        return (total + outside * (ub_sorted.size - k)) / M - delta

    return ub_sorted, score


class NoRootError(EstimationError):
    """The scale equation has no root: ``mean(chi(w^2 / v)) < delta`` for every v (a series
    with very few effectively independent values, e.g. a deep level of a random walk)."""


def _scan_largest_root(score: Any, u_max: float, u_min: float, delta: float) -> float:
    """Largest root of `score`, scanning down from where every ``chi(u/v) <= delta / 10``."""
    v_hi = 10.0 * u_max / delta
    f_hi = score(v_hi)
    v = v_hi
    while v > 1e-6 * u_min:
        v_new = 0.9 * v
        f_new = score(v_new)
        if f_new > 0 > f_hi:
            return _brentq(score, v_new, v, xtol=1e-15 * v, rtol=1e-13)
        v, f_hi = v_new, f_new
    raise NoRootError("the robust scale equation has no root: mean(chi(w^2/v)) < delta for "
                      "every v (too few effectively independent coefficients)")


def _start(sub: np.ndarray) -> float:
    """Robust start ``nu_0 = median(w^2) / 0.4549`` from squared coefficients `sub` (a
    subsample), ignoring exact zeros if most are zero; EstimationError if most are zero."""
    v0 = float(np.median(sub)) / _MEDIAN_CHI2_1
    if not v0 > 0:
        nz = sub[sub > 0]
        if nz.size < 0.25 * sub.size:
            raise EstimationError(
                "most wavelet coefficients are exactly zero (constant stretches): "
                "no robust scale can be estimated")
        v0 = float(np.median(nz)) / _MEDIAN_CHI2_1
    return v0


def _normaliser(v0: float) -> float:
    """A power of two f (1 when ``1e-4 < v0 < 1e4``) such that the powers ``u^p <= u^5`` of
    ``u = (f w)^2`` stay in float32's normal range: ``f^2 v0`` in [1/2, 2]. Being a power of
    two, f changes no rounding: the estimate scales back exactly."""
    if 1e-4 < v0 < 1e4:
        return 1.0
    return 2.0 ** -round(0.5 * math.log2(v0))


def _subsample(m: int, size: int = 65536) -> int:
    """Stride of the subsample (about `size` values) of a level's M coefficients that gives
    the start nu_0."""
    return max(1, m // size)


def _solve(first: tuple[np.ndarray, np.ndarray, np.ndarray], full: Callable[[], np.ndarray],
           v0: float, rho: ScaleRho, M: int, n_worst: int) -> MScale:
    """The largest root from the first bracket's summary ``(sums, idx, w[idx])``
    (:func:`_power_sums` at ``core = c^2 v0 / 2``, sums in units of v0); `full` gives all the
    coefficients if the bracket must move (rare). The variance is in the unit of w^2."""
    c2 = rho.c * rho.c
    coef = np.zeros(6)
    coef[: len(rho.coef)] = rho.coef
    delta = rho.consistency
    lo, hi = 0.5, 2.0  # bracket of v / v0
    sums, idx, wb = first
    for _ in range(60):
        ub = np.square(wb) * (1.0 / v0)  # u / v0 of the coefficients outside the core
        ub_sorted, score = _sorted_score(ub, sums, coef, rho.outside, c2, delta, M, hi)
        f_lo, f_hi = score(lo), score(hi)
        if f_lo > 0 and f_hi < 0:
            v = _brentq(score, lo, hi, xtol=1e-15, rtol=1e-13)
            break
        wn = full()
        if f_lo <= 0:  # the largest root may lie anywhere below: scan all coefficients
            idx = np.arange(M)
            ub = np.square(wn) * (1.0 / v0)
            ub_sorted, score = _sorted_score(ub, np.zeros(6), coef, rho.outside, c2, delta, M)
            smallest = float(ub_sorted[ub_sorted > 0][0])
            v = _scan_largest_root(score, float(ub_sorted[-1]), smallest, delta)
            break
        lo, hi = hi, 4.0 * hi  # F(hi) >= 0: the root is above
        sums, idx = _power_sums(wn, v0, c2 * lo * v0)
        wb = wn[idx]
    else:  # pragma: no cover - F -> -delta as v -> inf, so the upward search ends
        raise EstimationError("the robust scale equation has no root in a wide bracket")
    u_sorted = ub_sorted / v  # in units of the estimate
    n_rejected = int(u_sorted.size - np.searchsorted(u_sorted, c2, side="right"))
    if ub.size > n_worst:
        top = np.argpartition(ub, ub.size - n_worst)[-n_worst:]
    else:
        top = np.arange(ub.size)
    top = top[np.argsort(-ub[top], kind="stable")]
    top = top[ub[top] / v > 0.5 * c2]
    return MScale(v * v0, n_rejected, idx[top].astype(np.int64), np.sqrt(ub[top] / v))


def m_scale(w: ArrayLike, rho: ScaleRho, n_worst: int = _N_WORST) -> MScale:
    """M-estimate of the variance of a zero-mean series: the largest root of
    ``mean(chi(w^2 / v)) = delta``.

    Parameters
    ----------
    w : array_like, shape (M,)
        Coefficients (unit u), finite, not all zero.
    rho : ScaleRho
        Tuned chi function (:func:`scale_rho`).
    n_worst : int
        How many of the largest coefficients to report.

    Returns
    -------
    MScale

    Raises
    ------
    EstimationError
        If most coefficients are exactly zero (no scale to estimate);
        :class:`NoRootError` if the equation has no root.
    """
    w = np.ascontiguousarray(w, dtype=np.float64)
    M = w.size
    v0 = _start(np.square(w[:: _subsample(M)]))
    f = _normaliser(v0)
    wn = w if f == 1.0 else w * f
    v0 *= f * f
    sums, idx = _power_sums(wn, v0, rho.c * rho.c * 0.5 * v0)
    est = _solve((sums, idx, wn[idx]), lambda: wn, v0, rho, M, n_worst)
    return attrs.evolve(est, variance=est.variance / (f * f))

@attrs.define
class _Screening:
    """Outcome of the screening for isolated outliers (module notes): the signal the levels
    are computed from, the replaced samples and the level-1 M-scale of the record as given
    (None when nothing was replaced); `c2` is the squared threshold, in robust sd, beyond which
    a level-1 coefficient is an outlier (the biweight's c at the estimator's efficiency,
    whichever chi function estimates the levels)."""

    x: np.ndarray
    c2: float
    replaced: np.ndarray = attrs.field(factory=lambda: np.empty(0, dtype=np.int64))
    first: MScale | None = None


def _rejected(idx: np.ndarray, wb: np.ndarray, variance: float, c2: float, core: float,
              full: Callable[[], np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Indices and values of the coefficients beyond ``c sqrt(variance)``, from those above
    `core` (``idx``, ``wb``: a superset when ``core <= c^2 variance``), else from all of them."""
    if core <= c2 * variance:
        keep = np.square(wb) > c2 * variance
        return idx[keep], wb[keep]
    w = full()
    far = np.flatnonzero(np.square(w) > c2 * variance)
    return far, w[far]


def isolated_patches(idx: ArrayLike, w: ArrayLike, max_patch: int = MAX_PATCH
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Isolated outliers from the rejected level-1 Haar coefficients.

    ``w[k]`` is (up to a positive factor) ``x[idx[k] + 1] - x[idx[k]]``, sorted by index. Two
    consecutive rejected coefficients of opposite signs at most `max_patch` apart bound a
    patch ``x[idx[k] + 1 : idx[k + 1] + 1]``: a jump away and back (a single-sample spike
    gives two adjacent ones). Pairs are taken left to right, each coefficient in one pair at
    most; a lone rejected coefficient (an edge of a longer burst, a step) bounds nothing.

    Returns
    -------
    first, length : ndarray of int64
        First sample and number of samples of each patch, increasing. Patches never touch:
        the samples just before and after each one are not in any.
    """
    idx = np.asarray(idx, dtype=np.int64)
    w = np.asarray(w, dtype=np.float64)
    if idx.size < 2:
        return np.empty(0, dtype=np.int64), np.empty(0, dtype=np.int64)
    gap = np.diff(idx)
    pairs = np.flatnonzero((gap <= max_patch) & (np.sign(w[1:]) * np.sign(w[:-1]) < 0))
    taken = []
    last = -2
    for k in pairs.tolist():  # a chain of rejected coefficients: disjoint pairs, greedy
        if k >= last + 2:
            taken.append(k)
            last = k
    taken = np.array(taken, dtype=np.int64)
    return idx[taken] + 1, gap[taken]


def replace_patches(x: np.ndarray, first: ArrayLike, length: ArrayLike
                    ) -> tuple[np.ndarray, np.ndarray]:
    """A copy of `x` with each patch (:func:`isolated_patches`) replaced by the straight line
    between the samples just before and just after it; and the replaced samples' indices."""
    first = np.asarray(first, dtype=np.int64)
    length = np.asarray(length, dtype=np.int64)
    lo = np.repeat(first - 1, length)
    hi = np.repeat(first + length, length)
    samples = lo + 1 + np.arange(lo.size) - np.repeat(np.cumsum(length) - length, length)
    out = x.copy()
    out[samples] = x[lo] + (samples - lo) / (hi - lo) * (x[hi] - x[lo])
    return out, samples


def _screen_with(screening: _Screening, est: MScale, idx: np.ndarray, wb: np.ndarray,
                 variance: float, core: float, full: Callable[[], np.ndarray]) -> bool:
    """Fill `screening` from the level-1 M-scale of its signal (`variance` in the unit of
    `wb`, `est` in the unit of the level-1 coefficients) and the coefficients above `core`;
    whether some samples were replaced."""
    far, wf = _rejected(idx, wb, variance, screening.c2, core, full)
    first, length = isolated_patches(far, wf)
    if first.size:
        screening.x, screening.replaced = replace_patches(screening.x, first, length)
        screening.first = est
    return bool(first.size)


def _screen(screening: _Screening, rho: ScaleRho) -> None:
    """Screen the signal for isolated outliers on its level-1 Haar coefficients (general
    path)."""
    w = 0.5 * np.diff(screening.x)
    est = m_scale(w, rho)
    _screen_with(screening, est, np.empty(0, dtype=np.int64), np.empty(0), est.variance,
                 np.inf, lambda: w)


def _haar_scales(x: np.ndarray, levels: int, rho: ScaleRho, n_worst: int = _N_WORST,
                 screening: _Screening | None = None
                 ) -> Iterator[tuple[int, int, MScale | None]]:
    """Yield ``(j, M_j, m_scale of W_j)`` for the Haar levels j = 1..levels (None where the
    equation has no root), each level in one pass over the pyramid's work array.

    The M-scale runs on the unscaled differences ``d = V_{j-1,t+s} - V_{j-1,t}``
    (``W_j = d / 2^j`` up to the sign) times the power of two ``2^-j norm``
    (:func:`_normaliser`): every value is ``norm`` times the one :func:`m_scale` sees, so the
    result is the same, divided back by ``norm^2`` exactly. The start nu_0 comes from a
    subsample of d taken before the pass (by the compiled loop of the previous level); one
    compiled loop (:func:`stochmod.empirical.haar_jit.haar_level_power_sums`) then computes d,
    its power sums and the next level's sums V_j. The coefficients are never stored: where
    the first bracket fails (rare), they are computed again.

    With `screening`, level 1 also screens x for isolated outliers (module notes): if some
    are found, `screening` receives the cleaned signal, the replaced samples and this level-1
    estimate, and every level, the first included, is computed again from the cleaned signal.
    """
    c2 = rho.c * rho.c
    n_valid = x.size
    # the start only sets the bracket and the core (the root is exact either way): a 4x
    # smaller subsample than m_scale's, whose median would otherwise dominate a level's time
    sub_size = 16384
    # level 1 reads x and writes V_1 to the work array; then in place; contiguous: the
    # compiled sums' order follows the memory layout (see modwt)
    v, work = np.ascontiguousarray(x), np.empty(n_valid - 1)
    # room for the coefficients outside the core: an outlier touches 2^j of them
    big_idx = np.empty(max(1024, n_valid // 8), dtype=np.int64)
    big_w = np.empty(big_idx.size)
    stride = _subsample(n_valid - 1, sub_size)
    sub = np.square(v[1 : n_valid : stride] - v[: n_valid - 1 : stride])
    for j in range(1, levels + 1):
        step = 2 ** (j - 1)
        m = n_valid - step
        scale_j = 2.0**-j  # W_j = d / 2^j: v0 of W_j, as m_scale computes it
        try:
            v0 = _start(sub) * scale_j**2
        except EstimationError as exc:
            raise InputError(f"level {j}: {exc}") from None
        norm = _normaliser(v0)  # wn = d f = +-norm W_j
        f = scale_j * norm
        v0 *= norm * norm
        core = c2 * 0.5 * v0
        sums = np.zeros(6)
        # the kernel also copies the next level's subsample
        m_next = max(m - 2 * step, 0) if j < levels else 0
        stride = _subsample(m_next, sub_size)
        left, right = np.empty((2, -(-m_next // stride)))
        nb = haar_jit.haar_level_power_sums(v, work, n_valid, step, f, core, sums,
                                             big_idx, big_w, stride, left, right)
        sub = np.square(right - left)
        complete = nb <= big_idx.size
        idx, wb = big_idx[:nb].copy(), big_w[:nb].copy()
        v = work
        sums /= v0 ** np.arange(6.0)

        def full(j: int = j, norm: float = norm) -> np.ndarray:
            return modwt.modwt_coefficients(x, j) * norm

        if not complete:  # more coefficients outside the core than recorded: start again
            wn = full()
            sums, idx = _power_sums(wn, v0, core)
            wb = wn[idx]
        est = _level_scale(lambda: _solve((sums, idx, wb), full, v0, rho, m, n_worst), j)
        if j == 1 and screening is not None and est is not None:
            first = attrs.evolve(est, variance=est.variance / norm**2)
            if _screen_with(screening, first, idx, wb, est.variance, core, full):
                del v, work, big_idx, big_w, idx, wb  # the pass below has its own
                yield from _haar_scales(screening.x, levels, rho, n_worst)
                return
        yield j, m, None if est is None else attrs.evolve(est, variance=est.variance / norm**2)
        n_valid = m


def _level_scale(estimate: Callable[[], MScale], j: int) -> MScale | None:
    """``estimate()``, None if the equation has no root; other failures as an InputError
    naming level j."""
    try:
        return estimate()
    except NoRootError:
        return None
    except EstimationError as exc:
        raise InputError(f"level {j}: {exc}") from None


def _autocorrelation_powers(buf: np.ndarray, m: int, kmax: int) -> np.ndarray:
    """``sum_{|h|<M} rho_h^(2k)``, k = 1..kmax, of the sample autocorrelation of ``buf[:m]``
    (zero-padded after m), by FFT."""
    p = scipy.fft.next_fast_len(2 * m - 1, real=True)
    spec = scipy.fft.rfft(buf[:p])
    acov = scipy.fft.irfft(spec.real**2 + spec.imag**2, n=p)[:m]
    rho2 = np.square(acov / acov[0])
    out = np.empty(kmax)
    out[0] = 2.0 * rho2.sum() - 1.0
    # higher powers: lags with rho^2 <= 1e-5 add at most M 1e-10 to R_2 (R_k >= 1): dropped
    power = rho2[rho2 > 1e-5]
    base = power.copy()
    for k in range(1, kmax):
        power *= base
        out[k] = 2.0 * power.sum() - 1.0
    return out


def sandwich_ratio(rho: ScaleRho, powers: np.ndarray) -> float:
    """``kappa = var(robust) / var(classical)`` from ``R_k = sum_h rho_h^(2k)`` (k = 1..K+1),
    given as sums over all lags of the squared sample autocorrelations (so ``R_1`` is twice
    the true one, see the module notes).

    Parameters
    ----------
    rho : ScaleRho
    powers : ndarray, shape (K + 1,)
        ``sum_h rho_h^(2k)`` for k = 1..K+1 (K = number of Hermite terms).
    """
    b2 = rho.hermite_squares
    K = b2.size
    r1 = 0.5 * powers[0]
    rest = rho.score_variance - b2.sum()
    lrv = b2[0] * r1 + float(b2[1:] @ powers[1:K]) + max(rest, 0.0) * powers[K]
    return float(lrv / (b2[0] * r1))


def robust_wvar(
    x: ArrayLike,
    freq: float,
    efficiency: float = DEFAULT_EFFICIENCY,
    wavelet: str = "haar",
    levels: int | None = None,
    ci: str = "chi2",
    alpha: float = 0.05,
    rho: str = "biweight",
    screen: bool = True,
) -> WaveletVariance:
    """Robust MODWT wavelet variance (M-estimate per level) with intervals and diagnostic.

    Parameters
    ----------
    x : array_like, shape (N,)
        Finite signal (unit u), N >= 2 * L_1.
    freq : float
        Sampling frequency, Hz.
    efficiency : float
        Gaussian efficiency in (0, 1] relative to the classical estimator for independent
        coefficients (default 0.6, as R gmwm); lower is more robust. 1 gives the classical
        estimator.
    wavelet, levels, alpha
        As :func:`stochmod.empirical.wavelet_variance.wvar`.
    ci : {"chi2", "normal"}
        ``"chi2"``: chi-square interval with ``eff * eta_j`` equivalent degrees of freedom
        (variance ratio bound ``1/eff``); ``"normal"``: the sandwich variance (module notes).
    rho : {"biweight", "huber"}
        Chi function.
    screen : bool
        Replace isolated outliers (patches of at most :data:`MAX_PATCH` samples bounded by two
        rejected level-1 coefficients of opposite signs) by the straight line between their
        neighbours before the decomposition (module notes); False: the M-estimates of the
        record as given.

    Returns
    -------
    WaveletVariance
        With ``robust=True``, ``efficiency``, ``rho``, ``tuning`` (c), ``variance_ratio``
        (kappa_j) and ``contamination`` set (its ``replaced_time``: the replaced samples).

    Raises
    ------
    InputError
        Bad signal (NaN/inf, too short, constant), efficiency outside (0, 1], unknown rho,
        ci, wavelet, levels.
    """
    efficiency = check_efficiency(efficiency)
    if rho not in RHO_FUNCTIONS:
        raise InputError(f"rho must be one of {RHO_FUNCTIONS}, got {rho!r}")
    x = as_signal(x, name="x", min_length=2)
    freq = check_freq(freq)
    modwt_filters(wavelet)
    if x.size < 2 * filter_width(1, wavelet):
        raise InputError(f"x has {x.size} samples; the robust wavelet variance needs at least "
                         f"{2 * filter_width(1, wavelet)} (two level-1 {wavelet!r} filters)")
    if efficiency == 1.0:
        return attrs.evolve(classical_wvar(x, freq, wavelet=wavelet, levels=levels, ci=ci, alpha=alpha),
                            robust=True, efficiency=1.0, rho=rho)
    n = x.size
    n_levels = (default_levels(n, wavelet) if levels is None
                else check_level(n, levels, wavelet, "levels"))
    if ci not in CI_METHODS:
        raise InputError(f"ci must be one of {CI_METHODS}, got {ci!r}")
    alpha = check_alpha(alpha)
    if x.max() == x.min():
        raise InputError("x is constant: its wavelet variance is zero at every level")
    chi = scale_rho(efficiency, rho)
    js = np.arange(1, n_levels + 1)
    wv = np.empty(n_levels)
    n_coef = np.empty(n_levels, dtype=np.int64)
    share = np.empty(n_levels)
    ratio = np.full(n_levels, 1.0 / chi.efficiency)
    worst_t, worst_s = [], []
    m1 = n - filter_width(1, wavelet) + 1
    previous = m1
    lows: list[float] = []
    classical: list[int] = []
    highs: list[float] = []
    haar_pass = ci == "chi2" and modwt_filters(wavelet)[0].size == 2
    screening = _Screening(x, scale_rho(efficiency, "biweight").c ** 2)
    if haar_pass:  # Haar: the coefficients are not kept; level 1 screens
        scales = _haar_scales(x, n_levels, chi, screening=screening if screen else None)
    else:  # the coefficients in buf (the normal interval's spectra need them)
        if screen:
            _level_scale(lambda: _screen(screening, chi), 1)
        buf = np.zeros(scipy.fft.next_fast_len(2 * m1 - 1, real=True) if ci == "normal" else m1)
        scales = ((j, m, _level_scale(lambda m=m: m_scale(buf[:m], chi), j))
                  for j, _, m in pyramid(screening.x, n_levels, wavelet, buf, sumsq=False))
    for j, m, est in scales:
        if est is None:  # no root: the classical mean of squares stands at this level
            w = modwt.modwt_coefficients(screening.x, j, wavelet) if haar_pass else buf[:m]
            est = MScale(float(np.dot(w, w)) / m, 0, np.empty(0, np.int64), np.empty(0))
            classical.append(j)
            ratio[j - 1] = 1.0
        wv[j - 1] = est.variance
        n_coef[j - 1] = m
        share[j - 1] = est.n_rejected / m
        centre = (est.worst + 0.5 * (filter_width(j, wavelet) - 1)) / freq
        worst_t.append(centre)
        worst_s.append(est.worst_score)
        if ci == "normal":
            buf[m:previous] = 0.0
            previous = m
            bound = chi.c * math.sqrt(est.variance)
            np.clip(buf[:m], -bound, bound, out=buf[:m])
            powers = _autocorrelation_powers(buf, m, _HERMITE_TERMS + 1)
            if j not in classical:
                ratio[j - 1] = sandwich_ratio(chi, powers)
            # classical Gaussian variance of the level (powers[0] nu^2 = S_j), times kappa
            half = special.ndtri(1.0 - alpha / 2.0) * est.variance * math.sqrt(
                ratio[j - 1] * powers[0] / m)
            lows.append(max(est.variance - half, NORMAL_CI_FLOOR * est.variance))
            highs.append(est.variance + half)
    if screening.first is not None:  # level 1 as recorded: where the isolated outliers show
        share[0] = screening.first.n_rejected / (n - 1)
        worst_t[0] = (screening.first.worst + 0.5) / freq
        worst_s[0] = screening.first.worst_score
    if ci == "chi2":
        eta = np.maximum(n_coef / 2.0**js, 1.0) / ratio
        low = eta * wv / special.chdtri(eta, alpha / 2.0)
        high = eta * wv / special.chdtri(eta, 1.0 - alpha / 2.0)
    else:
        low, high = np.array(lows), np.array(highs)
    tau = 2.0 ** (js - 1) / freq
    arrays = [js, tau, wv, low, high, n_coef]
    for a in (*arrays, ratio, share):
        a.setflags(write=False)
    replaced = screening.replaced / freq
    replaced.setflags(write=False)
    diag = Contamination(js, tau, share, chi.rejection_probability, tuple(worst_t),
                         tuple(worst_s), tuple(classical), replaced)
    return WaveletVariance(*arrays, freq=freq, wavelet=wavelet, n=n, ci_method=ci, alpha=alpha,
                           robust=True, efficiency=efficiency, rho=rho, tuning=chi.c,
                           variance_ratio=ratio, contamination=diag)
