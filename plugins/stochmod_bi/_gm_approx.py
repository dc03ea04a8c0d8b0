"""A finite sum of Gauss-Markov processes that approximates BI's wavelet variance.

The flicker mixture is a continuum of GMs; a Kalman filter needs finitely many. K rates and
variances are fitted to the mixture's Haar WV over the levels that matter (relative errors,
least squares, then a minimax linear programme for the variances at the fitted rates). The
fit depends only on ``nu_c = fc / freq``, K and the levels (B scales out), so it is cached.
"""

from __future__ import annotations

import math
from functools import lru_cache

import attrs
import numpy as np

from stochmod.sdk import EstimationError, format_table

from ._mixture import D_HI, ar1_wv, band, unit_wv

__all__ = ["GMApproximation", "default_levels", "fit_unit_gms"]

#: The approximation covers levels up to where ``m nu_c`` reaches this (well past the bend).
_DEPTH = 64.0


def default_levels(nu_c: float) -> int:
    """Levels 1..J with ``2^(J-1) nu_c >= 64``: Nyquist end, flat floor, bend and tail."""
    return max(2, math.ceil(math.log2(_DEPTH / nu_c)) + 1)


def _minimax_weights(G: np.ndarray) -> tuple[np.ndarray, float] | None:
    """Non-negative w minimising ``max_j |(G w)_j - 1|`` (a linear programme), or None."""
    from scipy.optimize import linprog  # here: the registry loads every plugin at start-up

    J, K = G.shape
    ones = np.ones((J, 1))
    res = linprog(np.r_[np.zeros(K), 1.0],
                  A_ub=np.block([[G, -ones], [-G, -ones]]), b_ub=np.r_[np.ones(J), -np.ones(J)],
                  bounds=[(0, None)] * (K + 1), method="highs")
    return (res.x[:K], float(res.x[K])) if res.status == 0 else None


@lru_cache(maxsize=256)
def fit_unit_gms(nu_c: float, n_gm: int, levels: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rates ``d_k`` (per sample), variances ``w_k`` (unit mixture) and per-level relative errors.

    Starts from rates spread evenly in ``ln d`` over the band (the corner GM first) with
    trapezoid-like variances, minimises the relative WV errors in least squares over
    ``(ln d_k, ln w_k)``, then re-solves the variances for the smallest maximum error.
    """
    m = 2.0 ** np.arange(levels)
    target = unit_wv(nu_c, levels)
    d_lo, width = band(nu_c)
    if width == 0.0:  # empty band: the process is exactly its corner GM
        d = d_lo * 2.0 ** np.arange(n_gm)
        w = np.r_[1.0, np.zeros(n_gm - 1)]
        return d, w, ar1_wv(d_lo, m) / target - 1.0

    def design(log_d: np.ndarray) -> np.ndarray:
        return ar1_wv(np.exp(log_d)[None, :], m[:, None]) / target[:, None]

    a = math.log(d_lo)
    s0 = a + width * np.linspace(0.02, 0.92, n_gm) if n_gm > 1 else np.array([a])
    w0 = np.full(n_gm, width / n_gm)
    w0[0] += 1.0

    def residuals(p: np.ndarray) -> np.ndarray:
        return design(p[:n_gm]) @ np.exp(p[n_gm:]) - 1.0

    lo = np.r_[np.full(n_gm, a - 5.0), np.full(n_gm, -60.0)]
    hi = np.r_[np.full(n_gm, math.log(D_HI) + 5.0), np.full(n_gm, 20.0)]
    from scipy.optimize import least_squares

    fit = least_squares(residuals, np.r_[s0, np.log(w0)], bounds=(lo, hi), x_scale=1.0)
    if not np.all(np.isfinite(fit.x)):
        raise EstimationError(f"GM approximation of BI at fc/freq = {nu_c:g} failed: {fit.message}")
    log_d = fit.x[:n_gm]
    w = np.exp(fit.x[n_gm:])
    polished = _minimax_weights(design(log_d))
    if polished is not None and polished[1] < np.max(np.abs(fit.fun)):
        w = polished[0]
    order = np.argsort(log_d)
    d, w = np.exp(log_d[order]), w[order]
    return d, w, (ar1_wv(d[None, :], m[:, None]) @ w) / target - 1.0


@attrs.frozen
class GMApproximation:
    """K Gauss-Markov processes whose summed Haar WV approximates a BI process's.

    Attributes
    ----------
    beta : ndarray (K,)
        Inverse correlation times, 1/s, increasing.
    sigma2 : ndarray (K,)
        Stationary variances, u^2.
    freq : float
        Sampling frequency of the fit, Hz.
    rel_error : ndarray (J,)
        Relative error of the summed GM WV against BI's at levels 1..J.
    """

    beta: np.ndarray = attrs.field(eq=attrs.cmp_using(eq=np.array_equal))
    sigma2: np.ndarray = attrs.field(eq=attrs.cmp_using(eq=np.array_equal))
    freq: float
    rel_error: np.ndarray = attrs.field(eq=attrs.cmp_using(eq=np.array_equal))

    @property
    def levels(self) -> int:
        """Number of levels the error was measured on."""
        return int(self.rel_error.size)

    @property
    def max_rel_error(self) -> float:
        """Largest absolute relative WV error over the levels."""
        return float(np.max(np.abs(self.rel_error)))

    def gms(self) -> list:
        """The approximation as registered ``GM(beta, sigma2)`` processes (needs the GM plugin)."""
        from stochmod.sdk import get_process

        gm = get_process("GM")
        return [gm(beta=float(b), sigma2=float(s)) for b, s in zip(self.beta, self.sigma2)]

    def summary(self) -> str:
        """Table of the GMs (rate, correlation time, variance, sigma) and the WV error."""
        rows = [[k + 1, b, 1.0 / b, s, math.sqrt(s)]
                for k, (b, s) in enumerate(zip(self.beta, self.sigma2))]
        title = (f"{self.beta.size} GMs approximating BI at {self.freq:g} Hz: "
                 f"max relative WV error {self.max_rel_error:.3g} over levels 1..{self.levels}")
        return format_table(["k", "beta [1/s]", "Tc [s]", "sigma2 [u^2]", "sigma [u]"], rows,
                            title=title)
