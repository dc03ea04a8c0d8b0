"""ARMA(p, q) mean models by conditional Gaussian maximum likelihood (Waegli et al. 2010, eqs. 10-11).

Model (eq. 10): ``x_t = nu + sum_{i=1}^p a_i x_{t-i} + sum_{j=1}^q b_j e_{t-j} + e_t``,
``e_t ~ N(0, sigma2)``. Conditioning on the first ``p`` observations and on pre-sample
innovations equal to zero, the innovations are the output of the IIR filter
``e = (1 + b(B))^{-1} (x - nu - a(B) x)`` (one :func:`scipy.signal.lfilter` call), so the
conditional likelihood is a sum of squares; it is minimised by Gauss-Newton with step halving
from Hannan-Rissanen starting values (long AR, then a regression on lagged values and
residuals), the Jacobian being filtered the same way. Standard errors come from the
information matrix ``sigma2 (J^T J)^{-1}`` (eq. 11); orders are chosen by AIC (Table 1).
For long records (IMU rates) the conditional and exact likelihoods agree to O(1/T).
"""

from __future__ import annotations

import math

import attrs
import numpy as np
from numpy.typing import ArrayLike
from scipy.signal import lfilter

from stochmod.core.fields import array_field
from stochmod.core.checks import as_signal, check_positive_int
from stochmod.core.errors import EstimationError, InputError
from stochmod.fit._estimates import EstimatesMixin

__all__ = ["ArmaFit", "fit_arma", "select_arma", "arma_innovations"]

_LOG_2PI = math.log(2.0 * math.pi)
_START_SAMPLES = 2**17


def _lag_rows(x: np.ndarray, lags: int, start: int) -> list[np.ndarray]:
    """Rows ``x[t - 1], .., x[t - lags]`` for ``t = start .. T - 1``."""
    return [x[start - i : x.size - i] for i in range(1, lags + 1)]


def _innovations(x: np.ndarray, nu: float, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``e_t`` for ``t = p .. T - 1`` (conditional on pre-sample innovations of zero)."""
    p = a.size
    w = x[p:] - nu
    for i, ai in enumerate(a, start=1):
        w = w - ai * x[p - i : x.size - i]
    return lfilter([1.0], np.concatenate([[1.0], b]), w) if b.size else w


def _jacobian(x: np.ndarray, e: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``d e / d (nu, a, b)`` as rows, shape (1 + p + q, T - p)."""
    p, q = a.size, b.size
    drive = np.empty((1 + p + q, e.size))
    drive[0] = -1.0
    for i in range(1, p + 1):
        drive[i] = -x[p - i : x.size - i]
    for j in range(1, q + 1):
        drive[p + j, :j] = 0.0
        drive[p + j, j:] = -e[:-j]
    if q:
        drive = lfilter([1.0], np.concatenate([[1.0], b]), drive, axis=1)
    return drive


def _lstsq(rows: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Least squares ``min |rows^T c - y|`` by the normal equations (few regressors as rows of
    a C-contiguous array, many samples), refined once."""
    gram = rows @ rows.T
    coef = np.linalg.solve(gram, rows @ y)
    return coef + np.linalg.solve(gram, rows @ (y - rows.T @ coef))


def _max_root_modulus(poly_tail: np.ndarray, sign: float) -> float:
    """Largest modulus of the roots of ``z^k + sign * c_1 z^(k-1) + ..`` (0 without terms)."""
    if poly_tail.size == 0:
        return 0.0
    return float(np.max(np.abs(np.roots(np.concatenate([[1.0], sign * poly_tail])))))


def _hannan_rissanen(x: np.ndarray, p: int, q: int) -> np.ndarray:
    """Starting values ``(nu, a, b)``: long-AR residuals, then least squares on lags of x and e
    (over the first ``_START_SAMPLES`` samples: it is only a start)."""
    x = x[:_START_SAMPLES]
    if q == 0:
        m = 0
        e = np.zeros_like(x)
    else:
        m = min(max(2 * (p + q), 10), x.size // 10)
        X = np.array([np.ones(x.size - m), *_lag_rows(x, m, m)])
        coef = _lstsq(X, x[m:])
        e = np.zeros_like(x)
        e[m:] = x[m:] - coef @ X
    start = m + max(p, q)
    X = np.array([np.ones(x.size - start), *_lag_rows(x, p, start), *_lag_rows(e, q, start)])
    theta = _lstsq(X, x[start:])
    b = theta[1 + p :]
    if _max_root_modulus(b, 1.0) >= 0.99:  # keep the start invertible
        theta[1 + p :] *= 0.9 / _max_root_modulus(b, 1.0)
    return theta


@attrs.frozen
class ArmaFit(EstimatesMixin):
    """An ARMA(p, q) fitted by conditional Gaussian maximum likelihood.

    Attributes
    ----------
    nu : float
        Constant, u.
    ar : ndarray, shape (p,)
        ``a_i`` of eq. 10 (on ``x_{t-i}``).
    ma : ndarray, shape (q,)
        ``b_j`` of eq. 10 (on ``e_{t-j}``).
    sigma2 : float
        Innovation variance, u^2.
    loglikelihood : float
        Conditional log-likelihood at the estimate, nats.
    cov_params : ndarray
        ``sigma2 (J^T J)^{-1}`` in the order (nu, ar, ma).
    n : int
        Number of innovations ``T - p`` in the likelihood.
    converged : bool
        Whether Gauss-Newton met its tolerance.
    """

    nu: float
    ar: np.ndarray = array_field()
    ma: np.ndarray = array_field()
    sigma2: float
    loglikelihood: float
    cov_params: np.ndarray = array_field(repr=False)
    n: int
    converged: bool

    @property
    def order(self) -> tuple[int, int]:
        """``(p, q)``."""
        return self.ar.size, self.ma.size

    @property
    def params(self) -> np.ndarray:
        """``(nu, a_1..a_p, b_1..b_q)``."""
        return np.concatenate([[self.nu], self.ar, self.ma])

    @property
    def param_names(self) -> tuple[str, ...]:
        p, q = self.order
        return ("nu", *(f"ar{i}" for i in range(1, p + 1)), *(f"ma{j}" for j in range(1, q + 1)))

    @property
    def aic(self) -> float:
        """``-2 loglik + 2 (p + q + 2)`` (nu and sigma2 included)."""
        return -2.0 * self.loglikelihood + 2.0 * (self.params.size + 1)

    def innovations(self, x: ArrayLike) -> np.ndarray:
        """Innovations ``e_t`` of `x` under this model, shape (T,), zero for ``t < p``."""
        x = as_signal(x, name="x", min_length=self.ar.size + 1)
        out = np.zeros_like(x)
        out[self.ar.size :] = _innovations(x, self.nu, self.ar, self.ma)
        return out

    def conditional_mean(self, x: ArrayLike) -> np.ndarray:
        """One-step predictions ``E[x_t | past] = x_t - e_t`` (u), shape (T,)."""
        x = as_signal(x, name="x", min_length=self.ar.size + 1)
        return x - self.innovations(x)

    def summary(self) -> str:
        """Estimates, standard errors, t- and p-values (Table 1)."""
        p, q = self.order
        return self.estimates_table(
            f"ARMA({p},{q}) by conditional Gaussian ML, {self.n} innovations: sigma2 "
            f"{self.sigma2:.6g}, loglik {self.loglikelihood:.6f}, AIC {self.aic:.6f}")


def arma_innovations(x: ArrayLike, nu: float, ar: ArrayLike, ma: ArrayLike) -> np.ndarray:
    """Innovations ``e_t``, ``t = p .. T - 1``, of eq. 10 for given coefficients."""
    x = as_signal(x, name="x")
    return _innovations(x, float(nu), np.atleast_1d(np.asarray(ar, float)),
                        np.atleast_1d(np.asarray(ma, float)))


def _gauss_newton(y: np.ndarray, p: int, theta: np.ndarray, max_iter: int, tol: float
                  ) -> tuple[np.ndarray, np.ndarray, float, bool, np.ndarray]:
    """Minimise the conditional sum of squares from `theta`; step halving keeps the MA invertible.

    Returns the estimate, its innovations and sum of squares, whether the tolerance was met,
    and the Jacobian at the last point where one was computed (the estimate, or the point
    one converged step before it, which differs from it by far less than a standard error).
    """
    e = _innovations(y, theta[0], theta[1 : 1 + p], theta[1 + p :])
    ssr = float(np.einsum("i,i->", e, e))
    jac = _jacobian(y, e, theta[1 : 1 + p], theta[1 + p :])
    if theta.size == 1:  # the constant alone is solved exactly by least squares
        return theta, e, ssr, True, jac
    for it in range(max_iter):
        if it:
            jac = _jacobian(y, e, theta[1 : 1 + p], theta[1 + p :])
        step = _lstsq(jac, -e)
        t = 1.0
        while t > 1e-6:
            cand = theta + t * step
            if _max_root_modulus(cand[1 + p :], 1.0) < 1.0:
                e_new = _innovations(y, cand[0], cand[1 : 1 + p], cand[1 + p :])
                ssr_new = float(np.einsum("i,i->", e_new, e_new))
                if np.isfinite(ssr_new) and ssr_new <= ssr:
                    break
            t /= 2.0
        else:
            return theta, e, ssr, True, jac  # no descent left along the Gauss-Newton direction
        done = ssr - ssr_new <= tol * ssr
        theta, e, ssr = cand, e_new, ssr_new
        if done:
            return theta, e, ssr, True, jac
    return theta, e, ssr, False, jac


def fit_arma(x: ArrayLike, p: int = 1, q: int = 1, *, max_iter: int = 50, tol: float = 1e-9
             ) -> ArmaFit:
    """Fit ARMA(p, q) with a constant (eq. 10) by conditional Gaussian maximum likelihood.

    Parameters
    ----------
    x : array_like, shape (T,)
        The series, unit u (any scale: the fit is scale-equivariant).
    p, q : int
        AR and MA orders (>= 0).
    max_iter : int
        Gauss-Newton iterations allowed.
    tol : float
        Relative decrease of the sum of squares below which the iterations stop.

    Raises
    ------
    InputError
        NaN/inf, constant, fewer than ``20 (p + q + 1)`` samples.
    EstimationError
        The fitted AR part is not stationary or the MA part not invertible.
    """
    p = check_positive_int(p, name="p", minimum=0)
    q = check_positive_int(q, name="q", minimum=0)
    x = as_signal(x, name="x", min_length=max(20 * (p + q + 1), 30))
    scale = float(np.std(x))
    if not scale > 0:
        raise InputError("x is constant: no ARMA model can be fitted")
    y = x / scale
    theta = _hannan_rissanen(y, p, q)
    if y.size > 4 * _START_SAMPLES:  # converge on a prefix first: the full record then needs few steps
        theta = _gauss_newton(y[:_START_SAMPLES], p, theta, max_iter, tol)[0]
    theta, e, ssr, converged, jac = _gauss_newton(y, p, theta, max_iter, tol)
    a, b = theta[1 : 1 + p], theta[1 + p :]
    if _max_root_modulus(a, -1.0) >= 1.0:
        raise EstimationError(f"the fitted ARMA({p},{q}) has a non-stationary AR part (a = {a})")
    if _max_root_modulus(b, 1.0) >= 1.0:
        raise EstimationError(f"the fitted ARMA({p},{q}) has a non-invertible MA part (b = {b})")
    n = e.size
    sigma2 = ssr / n
    try:
        cov = sigma2 * np.linalg.inv(jac @ jac.T)
    except np.linalg.LinAlgError:
        cov = np.full((theta.size, theta.size), np.nan)
    units = np.ones(theta.size)
    units[0] = scale
    return ArmaFit(
        nu=float(theta[0] * scale), ar=a.copy(), ma=b.copy(), sigma2=sigma2 * scale**2,
        loglikelihood=-0.5 * n * (_LOG_2PI + math.log(sigma2 * scale**2) + 1.0),
        cov_params=cov * np.outer(units, units), n=n, converged=converged,
    )


def select_arma(x: ArrayLike, *, max_p: int = 2, max_q: int = 2, **options: float) -> ArmaFit:
    """The ARMA(p, q), ``0 <= p <= max_p``, ``0 <= q <= max_q``, of lowest AIC (Table 1).

    Orders whose fit is not stationary/invertible are skipped. The likelihoods are made
    comparable by dropping the first ``max_p`` samples for every order.
    """
    max_p = check_positive_int(max_p, name="max_p", minimum=0)
    max_q = check_positive_int(max_q, name="max_q", minimum=0)
    x = as_signal(x, name="x")
    best: ArmaFit | None = None
    failures = []
    for p in range(max_p + 1):
        for q in range(max_q + 1):
            try:
                fit = fit_arma(x[max_p - p :], p, q, **options)
            except EstimationError as exc:
                failures.append(str(exc))
                continue
            if best is None or fit.aic < best.aic:
                best = fit
    if best is None:
        raise EstimationError("no ARMA order up to "
                              f"({max_p},{max_q}) could be fitted: {'; '.join(failures)}")
    return best
