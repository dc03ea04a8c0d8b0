"""Zero-mean GARCH(p, q) volatility by Gaussian maximum likelihood (Waegli et al. 2010, eqs. 7-9).

Model (eq. 7): ``x_t = sigma_t Z_t``, ``Z_t ~ N(0, 1)`` i.i.d., and

    sigma_t^2 = omega + sum_{i=1}^p alpha_i x_{t-i}^2 + sum_{j=1}^q beta_j sigma_{t-j}^2,

with ``omega > 0``, ``alpha_i, beta_j >= 0`` and ``sum alpha + sum beta < 1`` (covariance
stationary). Pre-sample values of ``x^2`` and ``sigma^2`` are the exponentially weighted
backcast ``sum_k w_k x_k^2``, ``w_k`` proportional to ``0.94^k`` over the first
``min(75, T)`` samples (the convention of the ``arch`` package, so that log-likelihoods compare).

The derivatives of ``sigma_t^2`` with respect to the parameters obey the same recursion, so
the log-likelihood, its analytic gradient, the expected (Fisher) information
``J = 1/2 sum_t (d sigma_t^2)(d sigma_t^2)^T / sigma_t^4`` (eq. 9) and the observed information
come from one compiled pass over the data (:func:`stochmod.fit.garch_jit.garch_pass`).
The maximum is found by Newton steps on the observed information (Fisher scoring where it is
not positive definite) with Levenberg damping in unconstrained coordinates (``log omega``;
``alpha, beta`` and the slack ``1 - sum alpha - sum beta`` as a softmax), from the best point of
a grid; a coefficient whose maximum is at 0 is held there (see :func:`_boundary`). The data
are scaled to unit mean square inside, so IMU-scale inputs (variances of 1e-8 u^2 and below)
are handled as given; results are reported in the input's unit.
"""

from __future__ import annotations

import math

import attrs
import numpy as np
from numpy.typing import ArrayLike

from stochmod.core.fields import array_field
from stochmod.core.checks import as_signal, check_alpha, check_positive_int
from stochmod.core.errors import EstimationError, InputError
from stochmod.fit import garch_jit
from stochmod.fit._estimates import EstimatesMixin
from stochmod.fit.arch_lm import ArchLMTest, arch_lm_test

__all__ = ["GarchFit", "fit_garch", "garch_loglikelihood", "garch_variance", "select_garch",
           "backcast"]

_LOG_MAX = math.log(np.finfo(np.float64).max)
_BACKCAST_DECAY = 0.94
_BACKCAST_SAMPLES = 75
_GRID_SAMPLES = 100_000
_PREFIX_SAMPLES = 200_000
_EXTRAPOLATE = 0.55  # gain / predicted gain of a step above which longer steps are tried
_EXTRAPOLATE_STEPS = 6
_SHARE_FLOOR = 1e-6  # smallest alpha_i or beta_j the whole record starts from after the prefix
_OMEGA_FLOOR = 1e-12  # smallest omega (of data scaled to unit mean square) a stage starts from
_DAMPING_FLOOR = 1e-9  # smallest Levenberg weight, relative to the largest curvature
_DROPPED = 1e-300  # a share held at 0 is below this (its logit is ~ log(tiny))


def backcast(x2: np.ndarray) -> float:
    """Pre-sample value of ``x^2`` and ``sigma^2``: ``sum_k w_k x2_k``, ``w_k ~ 0.94^k``, k < 75."""
    tau = min(_BACKCAST_SAMPLES, x2.size)
    w = _BACKCAST_DECAY ** np.arange(tau)
    return float(np.dot(w / w.sum(), x2[:tau]))


def _split(theta: np.ndarray, p: int) -> tuple[float, np.ndarray, np.ndarray]:
    return float(theta[0]), theta[1 : 1 + p], theta[1 + p :]


def _check_theta(omega: float, alpha: np.ndarray, beta: np.ndarray) -> None:
    if not (np.isfinite(omega) and omega > 0):
        raise InputError(f"GARCH omega must be positive and finite, got {omega}")
    if np.any(~np.isfinite(alpha)) or np.any(alpha < 0) or np.any(~np.isfinite(beta)) or np.any(beta < 0):
        raise InputError(f"GARCH alpha and beta must be finite and >= 0, got {alpha}, {beta}")


def _parameters(x: ArrayLike, omega: float, alpha: ArrayLike, beta: ArrayLike
                ) -> tuple[np.ndarray, np.ndarray]:
    """The validated data and ``theta = (omega, alpha..., beta...)`` of the public functions."""
    x = as_signal(x, name="x")
    a = np.atleast_1d(np.asarray(alpha, dtype=np.float64))
    b = np.atleast_1d(np.asarray(beta, dtype=np.float64))
    _check_theta(float(omega), a, b)
    return x, np.concatenate([[float(omega)], a, b])


def garch_variance(x: ArrayLike, omega: float, alpha: ArrayLike, beta: ArrayLike) -> np.ndarray:
    """Conditional variances ``sigma_t^2`` of eq. 7 for the data `x` (unit u, result u^2).

    Parameters
    ----------
    x : array_like, shape (T,)
        Zero-mean residuals.
    omega : float
        Constant, u^2 (> 0).
    alpha, beta : array_like
        ARCH coefficients on ``x_{t-i}^2`` (length p) and GARCH coefficients on
        ``sigma_{t-j}^2`` (length q), all >= 0.
    """
    x, theta = _parameters(x, omega, alpha, beta)
    return _Likelihood(x, np.size(alpha), theta.size - 1 - np.size(alpha)).variance(theta)[1]


def garch_loglikelihood(x: ArrayLike, omega: float, alpha: ArrayLike, beta: ArrayLike) -> float:
    """Gaussian log-likelihood (nats) of `x` under GARCH(p, q) with these parameters."""
    x, theta = _parameters(x, omega, alpha, beta)
    return _Likelihood(x, np.size(alpha), theta.size - 1 - np.size(alpha)).value(theta)


# ------------------------------------------------------------------ unconstrained coordinates
def _to_theta(z: np.ndarray) -> np.ndarray:
    """``(log omega, logits)`` -> ``(omega, alpha..., beta...)``; the slack has logit 0."""
    logits = np.concatenate([z[1:], [0.0]])
    e = np.exp(logits - logits.max())
    share = e / e.sum()
    # a step far out may overflow omega: inf, which the callers' finiteness check refuses
    omega = math.exp(z[0]) if z[0] < _LOG_MAX else math.inf
    return np.concatenate([[omega], share[:-1]])


def _from_theta(theta: np.ndarray) -> np.ndarray:
    """Inverse of :func:`_to_theta`; an omega or a share that underflowed to 0 maps to a very
    negative log or logit."""
    tiny = np.finfo(np.float64).tiny
    slack = max(1.0 - theta[1:].sum(), tiny)
    log_omega = math.log(max(theta[0], tiny))  # omega may underflow where the maximum has it -> 0
    return np.concatenate([[log_omega], np.log(np.maximum(theta[1:], tiny)) - math.log(slack)])


def _theta_jacobian(z: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """``d theta / d z``, shape (k, k)."""
    k = theta.size
    jac = np.zeros((k, k))
    jac[0, 0] = theta[0]
    share = theta[1:]
    jac[1:, 1:] = np.diag(share) - np.outer(share, share)
    return jac


class _Likelihood:
    """Log-likelihood, score, expected information and observed Hessian of scaled data,
    through the compiled pass :func:`stochmod.fit.garch_jit.garch_pass`."""

    def __init__(self, y: np.ndarray, p: int, q: int):
        self.x2 = np.ascontiguousarray(y * y)
        self.bc = backcast(self.x2)
        self.p, self.q = p, q

    def _compiled_pass(self, theta: np.ndarray, level: int, s2: np.ndarray | None = None
                       ) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
        k = theta.size
        score, info, observed = np.zeros(k), np.zeros((k, k)), np.zeros((k, k))
        ll = garch_jit.garch_pass(self.x2, self.bc, float(theta[0]), *self._coefficients(theta),
                                  level, np.empty(0) if s2 is None else s2, score, info, observed)
        return ll, score, info, observed

    def _coefficients(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return (np.ascontiguousarray(theta[1 : 1 + self.p]),
                np.ascontiguousarray(theta[1 + self.p :]))

    def variance(self, theta: np.ndarray) -> tuple[float, np.ndarray]:
        """Log-likelihood (-inf where a variance is not positive and finite) and sigma^2 (T,)."""
        s2 = np.empty_like(self.x2)
        ll = self._compiled_pass(theta, 0, s2)[0]
        if ll == -math.inf:  # the pass stopped at that variance: all of them, as they are
            garch_jit.variance_recursion(self.x2, self.bc, float(theta[0]),
                                         *self._coefficients(theta), s2)
        return ll, s2

    def value(self, theta: np.ndarray) -> float:
        """Log-likelihood (-inf where a variance is not positive and finite)."""
        return self._compiled_pass(theta, 0)[0]

    def full(self, theta: np.ndarray) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
        """Log-likelihood, score (k,), expected information (k, k) and sigma^2 (T,)."""
        return self.terms(theta)[:4]

    def terms(self, theta: np.ndarray, hessian: bool = False
              ) -> tuple[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """As :meth:`full`, plus the observed information ``-d^2 loglik / d theta^2`` (k, k)
        when `hessian` (else None).

        With ``u_t = (1 - r_t) / sigma_t^2``, ``r_t = x_t^2 / sigma_t^2`` and ``D_t`` the
        derivatives of ``sigma_t^2``: score ``-1/2 sum u_t D_t``; the observed information is
        ``1/2 sum [(2 r_t - 1) D_t D_t^T / sigma_t^4 + u_t d^2 sigma_t^2]``.
        """
        s2 = np.empty_like(self.x2)
        ll, score, info, observed = self._compiled_pass(theta, 2 if hessian else 1, s2)
        return ll, score, info, s2, observed if hessian else None


def _grid_start(lik: _Likelihood, p: int, q: int) -> np.ndarray:
    """The best of a grid of (total alpha, persistence) with variance targeting (mean y^2 = 1).

    The grid is screened on the first ``_GRID_SAMPLES`` samples (it only picks a start).
    """
    if lik.x2.size > _GRID_SAMPLES:
        lik = _Likelihood(np.sqrt(lik.x2[:_GRID_SAMPLES]), p, q)
    best, best_ll = None, -math.inf
    for a_tot in (0.02, 0.05, 0.1, 0.2):
        for rho in (0.5, 0.8, 0.95, 0.99, 0.998):
            if q == 0:
                rho = a_tot
            if a_tot > rho:
                continue
            b_tot = rho - a_tot
            if q > 0 and b_tot <= 0:
                continue
            theta = np.concatenate([[1.0 - rho], np.full(p, a_tot / p), np.full(q, b_tot / max(q, 1))])
            ll = lik.value(theta)
            if ll > best_ll:
                best, best_ll = theta, ll
    if best is None:
        raise EstimationError("no GARCH starting point has a finite likelihood")
    return best


def _curvature(theta: np.ndarray, score: np.ndarray) -> np.ndarray:
    """``sum_m score_m d^2 theta_m / dz dz^T`` (k, k): the part of the Hessian in z that the
    change of coordinates adds (zero at a stationary point)."""
    k = theta.size
    out = np.zeros((k, k))
    out[0, 0] = score[0] * theta[0]
    share, g = theta[1:], score[1:]
    mean = float(g @ share)
    out[1:, 1:] = (np.diag(share * (g - mean)) - np.outer(share, share) * (g[:, None] + g[None, :])
                   + 2.0 * mean * np.outer(share, share))
    return out


def _newton_matrix(z: np.ndarray, theta: np.ndarray, score: np.ndarray, info: np.ndarray,
                   observed: np.ndarray, free: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Gradient and curvature in the `free` coordinates of z (boolean mask): the observed
    information (Newton) where it is positive definite, else the expected information
    (Fisher scoring)."""
    jac = _theta_jacobian(z, theta)[:, free]
    g = jac.T @ score
    h = jac.T @ observed @ jac - _curvature(theta, score)[np.ix_(free, free)]
    try:
        np.linalg.cholesky(h)
    except np.linalg.LinAlgError:
        h = jac.T @ info @ jac
    return g, h


def _boundary(theta: np.ndarray, score: np.ndarray) -> tuple[np.ndarray | None, np.ndarray]:
    """The shares held on the boundary 0, and `theta` moved when the boundary changes.

    A share below ``_SHARE_FLOOR`` whose likelihood falls as it grows at the expense of the
    others in proportion (its score below their mass-weighted mean, the slack's score 0 included:
    the sign of its softmax gradient, the Kuhn-Tucker condition of a maximum at 0) is set to 0
    and held there; one that collapsed although its likelihood rises is raised to the floor.
    In logits such a share would otherwise creep towards 0 by a constant factor per step, or
    stay stuck near it (its gradient and curvature are proportional to it).

    Returns the moved parameters (None when unchanged) and the mask of the free coordinates
    ``(log omega, logits)``.
    """
    share = theta[1:]
    rising = score[1:] > float(share @ score[1:])  # the mass-weighted mean, the slack's 0 included
    low = share < _SHARE_FLOOR
    held = low & ~rising
    drop = held & (share > _DROPPED)
    lift = low & rising & (share < 0.5 * _SHARE_FLOOR)
    free = np.concatenate([[True], ~held])
    if not (drop.any() or lift.any()):
        return None, free
    # the mass moved goes to or comes from the largest share, not the slack: near persistence
    # 1 the slack sets the variance level, and a small change of it a large one of the likelihood
    moved = theta.copy()
    shares = np.where(drop, 0.0, np.where(lift, _SHARE_FLOOR, share))
    shares[np.argmax(share)] -= shares.sum() - share.sum()
    moved[1:] = shares
    return moved, free


def _extrapolate(lik: _Likelihood, z: np.ndarray, step: np.ndarray, z_new: np.ndarray,
                 theta_new: np.ndarray, ll_new: float) -> tuple[np.ndarray, np.ndarray, float]:
    """``z + 2^k step``, k = 1, 2, .. while the log-likelihood increases (from the accepted
    ``z + step``); returns the best point, its parameters and log-likelihood."""
    for k in range(1, _EXTRAPOLATE_STEPS + 1):
        z_try = z + 2.0**k * step
        theta_try = _to_theta(z_try)
        if not (theta_try[1:].sum() < 1.0 and np.all(np.isfinite(theta_try))):
            break
        ll_try = lik.value(theta_try)
        if not ll_try > ll_new:
            break
        z_new, theta_new, ll_new = z_try, theta_try, ll_try
    return z_new, theta_new, ll_new


def _raise_shares(theta: np.ndarray) -> np.ndarray:
    """`theta` with every alpha_i, beta_j at least ``_SHARE_FLOOR``, taken from the largest, and
    omega at least ``_OMEGA_FLOOR``.

    A share that collapsed to ~0 on the prefix has a z-gradient ~0 on the whole record too (it
    is proportional to the share), so the whole record could not move it even where its
    maximum has it well inside; raised to the floor it can go either way.
    """
    theta = theta.copy()
    theta[0] = max(theta[0], _OMEGA_FLOOR)  # the same for omega, which may underflow to 0
    share = theta[1:]
    raised = np.maximum(share, _SHARE_FLOOR)
    raised[np.argmax(share)] -= raised.sum() - share.sum()
    theta[1:] = raised
    return theta


def _maximise(lik: _Likelihood, theta0: np.ndarray, max_iter: int, tol: float
              ) -> tuple[np.ndarray, int, bool, tuple[float, np.ndarray, np.ndarray]]:
    """Newton (Fisher scoring where the observed information is not positive definite) with
    Levenberg damping in unconstrained coordinates.

    Returns the estimate, the iterations used, whether `tol` was met, and the log-likelihood,
    expected information and sigma^2 at the estimate.
    """
    z = _from_theta(theta0)
    theta = theta0
    ll, score, info, s2, observed = lik.terms(theta, hessian=True)
    lam = 1e-3
    for it in range(1, max_iter + 1):
        moved, free = _boundary(theta, score)
        if moved is not None:
            z = _from_theta(moved)
            theta = _to_theta(z)
            ll, score, info, s2, observed = lik.terms(theta, hessian=True)
            free = _boundary(theta, score)[1]
        g, h = _newton_matrix(z, theta, score, info, observed, free)
        diag = np.diag(h).copy()
        diag[diag <= 0] = 1.0
        # a share near 0 has a z-curvature near 0 as well: without a floor on its weight, the
        # damping could not shorten a step that the near-singular h sends off in its direction
        diag = np.maximum(diag, _DAMPING_FLOOR * diag.max())
        improved = False
        for _ in range(40):
            step = np.zeros_like(z)
            step[free] = np.linalg.solve(h + lam * np.diag(diag), g)
            z_new = z + step
            theta_new = _to_theta(z_new)
            if theta_new[1:].sum() < 1.0 and np.all(np.isfinite(theta_new)):
                ll_new = lik.value(theta_new)
                if ll_new >= ll:
                    improved = True
                    break
            lam *= 10.0
        if not improved:
            met = bool(g @ np.linalg.lstsq(h, g, rcond=None)[0] < tol)
            return theta, it, met, (ll, info, s2)
        predicted = float(g @ step[free])
        if ll_new - ll > _EXTRAPOLATE * predicted:
            # the likelihood keeps rising beyond the quadratic model's prediction (a maximum on
            # the boundary sum alpha + sum beta -> 1, where each Newton step only gains a
            # constant factor): longer steps along the same direction while they gain
            z_new, theta_new, ll_new = _extrapolate(lik, z, step, z_new, theta_new, ll_new)
        gain = ll_new - ll
        z, theta = z_new, theta_new
        ll, score, info, s2, observed = lik.terms(theta, hessian=True)
        lam = max(lam / 10.0, 1e-12)
        if predicted < tol and gain <= tol:
            return theta, it, True, (ll, info, s2)
    return theta, max_iter, False, (ll, info, s2)


@attrs.frozen
class GarchFit(EstimatesMixin):
    """A zero-mean GARCH(p, q) fitted by Gaussian maximum likelihood.

    Attributes
    ----------
    omega : float
        Constant ``alpha_0`` of eq. 7, u^2.
    alpha : ndarray, shape (p,)
        ARCH coefficients (on ``x_{t-i}^2``), dimensionless.
    beta : ndarray, shape (q,)
        GARCH coefficients (on ``sigma_{t-j}^2``), dimensionless.
    loglikelihood : float
        Maximised Gaussian log-likelihood, nats (in the data's unit).
    conditional_variance : ndarray, shape (T,)
        ``sigma_t^2``, u^2: the one-step-ahead variance given the past.
    cov_params : ndarray, shape (1 + p + q, 1 + p + q)
        Inverse expected information (eqs. 8-9), in the order (omega, alpha, beta).
    n : int
        Number of samples T.
    converged : bool
        Whether the scoring iterations met the tolerance.
    n_iter : int
        Scoring iterations used.
    scale : float
        Root mean square of the data (the internal scaling), u.
    lm_test : ArchLMTest
        Engle's LM test for ARCH effects left in ``x_t / sigma_t``.
    """

    omega: float
    alpha: np.ndarray = array_field()
    beta: np.ndarray = array_field()
    loglikelihood: float
    conditional_variance: np.ndarray = array_field(repr=False)
    cov_params: np.ndarray = array_field(repr=False)
    n: int
    converged: bool
    n_iter: int
    scale: float
    lm_test: ArchLMTest

    @property
    def order(self) -> tuple[int, int]:
        """``(p, q)``."""
        return self.alpha.size, self.beta.size

    @property
    def params(self) -> np.ndarray:
        """``(omega, alpha_1..p, beta_1..q)``."""
        return np.concatenate([[self.omega], self.alpha, self.beta])

    @property
    def param_names(self) -> tuple[str, ...]:
        """Names in the paper's notation (``alpha0`` is omega)."""
        p, q = self.order
        return ("alpha0", *(f"alpha{i}" for i in range(1, p + 1)), *(f"beta{j}" for j in range(1, q + 1)))

    @property
    def persistence(self) -> float:
        """``sum alpha + sum beta`` (< 1)."""
        return float(self.alpha.sum() + self.beta.sum())

    @property
    def unconditional_variance(self) -> float:
        """``omega / (1 - persistence)``, u^2."""
        return self.omega / (1.0 - self.persistence)

    @property
    def aic(self) -> float:
        """Akaike information criterion ``-2 loglik + 2 k``."""
        return -2.0 * self.loglikelihood + 2.0 * self.params.size

    def summary(self) -> str:
        """Table of estimates, standard errors, t- and p-values (as Tables 1-2), and the LM test."""
        p, q = self.order
        text = self.estimates_table(
            f"GARCH({p},{q}) by Gaussian ML, T = {self.n}: loglik {self.loglikelihood:.6f}, "
            f"persistence {self.persistence:.6g}, "
            f"{'converged' if self.converged else 'NOT converged'} in {self.n_iter} iterations")
        return text + "\n" + self.lm_test.summary()


def fit_garch(x: ArrayLike, p: int = 1, q: int = 1, *, lags: int = 10, max_iter: int = 200,
              tol: float = 1e-8, start: ArrayLike | None = None) -> GarchFit:
    """Fit a zero-mean GARCH(p, q) (eq. 7) by Gaussian maximum likelihood.

    Parameters
    ----------
    x : array_like, shape (T,)
        Zero-mean residuals (e.g. the innovations of an ARMA mean model), unit u; any scale
        (the data are scaled to unit mean square inside).
    p : int
        ARCH order (lags of ``x^2``), >= 1.
    q : int
        GARCH order (lags of ``sigma^2``), >= 0.
    lags : int
        Lags of Engle's LM test on the standardized residuals.
    max_iter : int
        Scoring iterations allowed.
    tol : float
        Stop when the predicted log-likelihood gain of a step is below `tol` nats.
    start : array_like, optional
        ``(omega, alpha..., beta...)`` to start from (u^2 for omega) instead of the grid.

    Returns
    -------
    GarchFit

    Raises
    ------
    InputError
        NaN/inf, too short (fewer than ``max(100, 10 (1 + p + q))`` samples), all zero, bad orders.
    EstimationError
        No finite likelihood at any start.
    """
    return _fit_garch(x, p, q, lags, max_iter, tol, start, None)


def _fit_garch(x: ArrayLike, p: int, q: int, lags: int, max_iter: int, tol: float,
               start: ArrayLike | None, nested: GarchFit | None) -> GarchFit:
    """:func:`fit_garch`; from the estimate of the `nested` smaller model when none of the
    coefficients it lacks would rise from 0 there (see :func:`_warm_start`)."""
    p = check_positive_int(p, name="p")
    q = check_positive_int(q, name="q", minimum=0)
    k = 1 + p + q
    x = as_signal(x, name="x", min_length=max(100, 10 * k))
    scale = float(np.sqrt(np.mean(x * x)))
    if not scale > 0:
        raise InputError("x is identically zero: it has no volatility to model")
    y = x / scale
    lik = _Likelihood(y, p, q)
    warm = None if nested is None else _warm_start(lik, nested, scale)
    if warm is not None:
        theta0 = warm
    elif start is None:
        theta0 = _grid_start(lik, p, q)
    else:
        theta0 = np.asarray(start, dtype=np.float64).copy()
        if theta0.shape != (k,):
            raise InputError(f"start must hold 1 + p + q = {k} values, got shape {theta0.shape}")
        _check_theta(theta0[0], theta0[1 : 1 + p], theta0[1 + p :])
        if not theta0[1:].sum() < 1 or np.any(theta0[1:] <= 0):
            raise InputError("start must have alpha, beta > 0 and sum(alpha) + sum(beta) < 1")
        theta0[0] /= scale**2
    max_iter = check_positive_int(max_iter, name="max_iter")
    if warm is None and start is None and y.size > 4 * _PREFIX_SAMPLES:
        # converge on a prefix first (its scoring steps are cheap); the whole record then
        # needs only a few steps from there
        prefix = _Likelihood(y[:_PREFIX_SAMPLES], p, q)
        theta0 = _maximise(prefix, theta0, max_iter, tol * _PREFIX_SAMPLES / y.size)[0]
        theta0 = _raise_shares(theta0)
    theta, n_iter, converged, (ll, info, s2) = _maximise(lik, theta0, max_iter, tol)
    try:
        cov = np.linalg.inv(info)
    except np.linalg.LinAlgError:
        cov = np.full((k, k), np.nan)
    units = np.ones(k)
    units[0] = scale**2
    omega, alpha, beta = _split(theta * units, p)
    z = y / np.sqrt(s2)
    return GarchFit(
        omega=float(omega), alpha=alpha.copy(), beta=beta.copy(),
        loglikelihood=ll - x.size * math.log(scale), conditional_variance=s2 * scale**2,
        cov_params=cov * np.outer(units, units), n=int(x.size), converged=converged,
        n_iter=n_iter, scale=scale, lm_test=arch_lm_test(z, lags),
    )


def _warm_start(lik: _Likelihood, fit: GarchFit, scale: float) -> np.ndarray | None:
    """The smaller model `fit`'s estimate as a start for ``(lik.p, lik.q)`` (the data scaled by
    `scale`), the coefficients it lacks at ``_SHARE_FLOOR``; None when it does not nest, or when
    one of those would rise from 0 there (then the maximum is elsewhere: the cold start's grid
    and prefix get there for less than steps on the whole record)."""
    p, q = lik.p, lik.q
    p0, q0 = fit.order
    if p0 > p or q0 > q:
        return None
    theta = _raise_shares(np.concatenate([[fit.omega / scale**2], fit.alpha, np.zeros(p - p0),
                                          fit.beta, np.zeros(q - q0)]))
    score = lik.terms(theta)[1]
    added = np.r_[1 + p0 : 1 + p, 1 + p + q0 : 1 + p + q]
    if np.any(score[added] > theta[1:] @ score[1:]):
        return None
    return theta


def select_garch(x: ArrayLike, *, max_p: int = 2, max_q: int = 2, lags: int = 10,
                 alpha: float = 0.05, max_iter: int = 200, tol: float = 1e-8) -> GarchFit:
    """Grow GARCH(p, q) from (1, 1) until Engle's LM test finds no ARCH effect left.

    Models of total order ``p + q = 2, 3, ...`` (p >= 1) are fitted in turn; at each total order
    the one of highest likelihood is kept, and the growth stops at the first whose standardized
    residuals ``x_t / sigma_t`` pass the LM test at level `alpha` (Section 5). When none passes
    up to ``(max_p, max_q)``, the fit of best AIC is returned (its ``lm_test`` says it failed).

    A candidate that nests the previous order's best fit starts from its estimate (the added
    coefficients near 0, where its likelihood is already that fit's) unless one of them would
    rise from there; `max_iter` and `tol` are :func:`fit_garch`'s.
    """
    alpha = check_alpha(alpha)
    max_p = check_positive_int(max_p, name="max_p")
    max_q = check_positive_int(max_q, name="max_q", minimum=0)
    tried: list[GarchFit] = []
    for total in range(2 if max_q > 0 else 1, max_p + max_q + 1):
        nested = tried[-1] if tried else None
        level = [_fit_garch(x, p, total - p, lags, max_iter, tol, None, nested)
                 for p in range(1, max_p + 1) if 0 <= total - p <= max_q]
        if not level:
            continue
        best = max(level, key=lambda f: f.loglikelihood)
        tried.append(best)
        if best.lm_test.pvalue > alpha:
            return best
    return min(tried, key=lambda f: f.aic)
