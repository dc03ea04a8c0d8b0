"""Autoregressive AR(p) fits: Burg and Yule-Walker estimators, order selection, stability.

Model (the composer's AR family): ``X_t = sum_{i=1}^p phi_i X_{t-i} + e_t`` with innovation
variance ``sigma2``. Quinchia et al. (2013, eq. 9) write the same model as
``x(n) = -sum alpha_k x(n-k) + beta0 w(n)``, so ``alpha_k = -phi_k`` and ``beta0^2 = sigma2``.

:func:`burg` reproduces ``statsmodels.regression.linear_model.burg`` (same demeaning, same
innovation variance ``(1 - k_p^2) d_p / (2 (n - p))``: the mean of the squared order-p forward and
backward prediction errors) in O(n p) with in-place BLAS updates; :func:`yule_walker` reproduces
``statsmodels.regression.linear_model.yule_walker`` (``"mle"``: autocovariances over ``n``;
``"adjusted"``: over ``n - k``) but returns the variance, not the standard deviation.
"""

from __future__ import annotations

import math
from typing import Any

import attrs
import numpy as np
from numpy.typing import ArrayLike
from scipy.linalg import blas, solve_toeplitz

from stochmod.core.checks import as_signal, check_freq, check_positive_int
from stochmod.core.errors import EstimationError, InputError
from stochmod.core.tables import format_table

__all__ = [
    "burg",
    "yule_walker",
    "ar_roots_modulus",
    "check_stationary",
    "ARFit",
    "fit_ar",
]

_METHODS = ("burg", "yw", "yw-adjusted")
_CRITERIA = ("aic", "bic")


def _prepare(x: ArrayLike, order: int, demean: bool) -> tuple[np.ndarray, int]:
    order = check_positive_int(order, name="order")
    x = as_signal(x, name="x", min_length=order + 2)
    xd = (x - x.mean()) if demean else x.copy()
    if not np.any(xd):
        raise InputError("x is constant (zero after demeaning): no AR model can be fitted")
    return xd, order


def _levinson_from_reflection(ks: np.ndarray) -> np.ndarray:
    """AR coefficients (``phi``) of every order from reflection coefficients: row m-1 is AR(m)."""
    p = ks.size
    table = np.zeros((p, p))
    phi = np.zeros(0)
    for m, k in enumerate(ks):
        phi = np.concatenate([phi - k * phi[::-1], [k]])
        table[m, : m + 1] = phi
    return table


def _burg_path(x: np.ndarray, order: int) -> tuple[np.ndarray, np.ndarray]:
    """Burg's reflection coefficients k_1..k_p and innovation variances sigma2_1..sigma2_p.

    `x` (already demeaned if wanted) is overwritten. Forward errors live in `f` at their own time
    index; backward errors in `b` shifted left by the current order, so each stage is one
    ``drotm`` (in-place 2x2 update) plus one dot product over the shrinking overlap.
    """
    n = x.size
    f = x
    b = x.copy()
    ks = np.empty(order)
    sig = np.empty(order)
    d = 2.0 * float(f @ f) - f[0] ** 2 - f[-1] ** 2
    param = np.array([0.0, 1.0, 0.0, 0.0, 1.0])  # flag 0: x' = x + h12 y, y' = h21 x + y
    for m in range(order):
        if not d > 0:
            raise EstimationError(
                f"Burg recursion broke down at order {m + 1}: the prediction errors vanished "
                "(the signal is constant or exactly predictable)"
            )
        num = float(np.dot(f[m + 1 :], b[: n - m - 1]))
        k = 2.0 * num / d
        ks[m] = k
        sig[m] = (1.0 - k * k) * d / (2.0 * (n - m - 1))
        if m + 1 < order:
            param[2] = param[3] = -k
            f, b = blas.drotm(f, b, param, n=n - m - 1, offx=m + 1, offy=0,
                              overwrite_x=1, overwrite_y=1)
            d = (1.0 - k * k) * d - f[m + 1] ** 2 - b[n - m - 2] ** 2
    return ks, sig


def burg(x: ArrayLike, order: int, demean: bool = True) -> tuple[np.ndarray, float]:
    """Burg's AR(p) estimator.

    Parameters
    ----------
    x : array_like, shape (n,)
        The signal in units u.
    order : int
        AR order p >= 1 (n must exceed p + 1).
    demean : bool
        Subtract the sample mean first.

    Returns
    -------
    phi : ndarray, shape (p,)
        AR coefficients, ``X_t = sum phi_i X_{t-i} + e_t``.
    sigma2 : float
        Innovation variance in u^2: the mean of the squared order-p forward and backward
        prediction errors, ``(1 - k_p^2) d_p / (2 (n - p))`` (statsmodels' definition).

    Notes
    -----
    Equal to ``statsmodels.regression.linear_model.burg(x, order, demean)``; Burg's fit is
    always stationary (|reflection coefficients| <= 1).
    """
    xd, order = _prepare(x, order, demean)
    ks, sig = _burg_path(xd, order)
    return _levinson_from_reflection(ks)[-1].copy(), float(sig[-1])


def _autocov_direct(x: np.ndarray, order: int, adjusted: bool) -> np.ndarray:
    n = x.size
    r = np.empty(order + 1)
    r[0] = float(x @ x) / n
    for k in range(1, order + 1):
        r[k] = float(x[:-k] @ x[k:]) / (n - k if adjusted else n)
    return r


def yule_walker(
    x: ArrayLike, order: int, method: str = "mle", demean: bool = True
) -> tuple[np.ndarray, float]:
    """Yule-Walker AR(p) estimator.

    Parameters
    ----------
    x : array_like, shape (n,)
        The signal in units u.
    order : int
        AR order p >= 1.
    method : {"mle", "adjusted"}
        Autocovariance denominators ``n`` ("mle", always stationary) or ``n - k`` ("adjusted").
    demean : bool
        Subtract the sample mean first.

    Returns
    -------
    phi : ndarray, shape (p,)
        AR coefficients.
    sigma2 : float
        Innovation variance ``r_0 - sum phi_k r_k`` in u^2 (statsmodels returns its square root).
    """
    if method not in ("mle", "adjusted"):
        raise InputError(f"method must be 'mle' or 'adjusted', got {method!r}")
    xd, order = _prepare(x, order, demean)
    r = _autocov_direct(xd, order, method == "adjusted")
    phi = solve_toeplitz(r[:-1], r[1:])
    return phi, float(r[0] - r[1:] @ phi)


def _yw_path(x: np.ndarray, order: int, adjusted: bool) -> tuple[np.ndarray, np.ndarray]:
    """Yule-Walker fits of orders 1..p (Levinson-Durbin on the same autocovariances)."""
    r = _autocov_direct(x, order, adjusted)
    table = np.zeros((order, order))
    sig = np.empty(order)
    phi = np.zeros(0)
    v = r[0]
    for m in range(1, order + 1):
        k = (r[m] - phi @ r[m - 1 : 0 : -1]) / v if m > 1 else r[1] / r[0]
        phi = np.concatenate([phi - k * phi[::-1], [k]])
        v = v * (1.0 - k * k)
        table[m - 1, :m] = phi
        sig[m - 1] = r[0] - r[1 : m + 1] @ phi
    return table, sig


def ar_roots_modulus(phi: ArrayLike) -> float:
    """Largest modulus of the characteristic roots ``z^p - phi_1 z^(p-1) - ... - phi_p``.

    The AR model is stationary iff this is < 1 (equivalently, the AR polynomial
    ``1 - phi_1 z - ... - phi_p z^p`` has all its roots outside the unit circle).
    """
    phi = np.atleast_1d(np.asarray(phi, dtype=float))
    if phi.size == 0 or not np.any(phi):
        return 0.0
    return float(np.max(np.abs(np.roots(np.concatenate([[1.0], -phi])))))


def check_stationary(phi: ArrayLike, *, what: str = "AR model") -> float:
    """Return the largest characteristic-root modulus, raising if the model is not stationary.

    Raises
    ------
    EstimationError
        When a characteristic root has modulus >= 1 (a root of the AR polynomial on or inside
        the unit circle); the message names that modulus.
    """
    rmax = ar_roots_modulus(phi)
    if not rmax < 1.0:
        raise EstimationError(
            f"{what} is not stationary: the largest characteristic root has modulus {rmax:.6g} "
            f">= 1 (the AR polynomial has a root of modulus {1 / rmax:.6g} on or inside the unit "
            "circle); use method='burg', a lower order or a longer record"
        )
    return rmax


@attrs.frozen
class ARFit:
    """An AR(p) fit with its order-selection table.

    Attributes
    ----------
    phi : ndarray, shape (p,)
        AR coefficients, ``X_t = sum phi_i X_{t-i} + e_t`` (Quinchia's ``alpha_k = -phi_k``).
    sigma2 : float
        Innovation variance per sample in u^2 (Quinchia's ``beta0^2``).
    order : int
        The order p (chosen by `criterion` when not given).
    method : str
        ``"burg"``, ``"yw"`` (Yule-Walker, mle) or ``"yw-adjusted"``.
    criterion : str
        ``"aic"`` or ``"bic"``.
    orders : ndarray of int
        Orders 1..max_order that were fitted.
    sigma2_path : ndarray
        Innovation variance of each of those orders, u^2.
    aic, bic : ndarray
        ``n log(sigma2_m) + 2 m`` and ``n log(sigma2_m) + m log n`` for each order m (Gaussian
        log-likelihood up to a constant, with the innovation variance standing for the
        likelihood).
    phi_se : ndarray, shape (p,)
        Asymptotic standard errors, ``sqrt(diag(sigma2 Gamma_p^{-1}) / n)`` with ``Gamma_p`` the
        Toeplitz matrix of sample autocovariances (AR(1): ``sqrt((1 - phi^2) / n)``).
    max_root_modulus : float
        Largest characteristic-root modulus (< 1: stationary).
    freq : float
        Sampling frequency in Hz.
    n : int
        Number of samples.
    """

    phi: np.ndarray
    sigma2: float
    order: int
    method: str
    criterion: str
    orders: np.ndarray = attrs.field(repr=False)
    sigma2_path: np.ndarray = attrs.field(repr=False)
    aic: np.ndarray = attrs.field(repr=False)
    bic: np.ndarray = attrs.field(repr=False)
    phi_se: np.ndarray
    max_root_modulus: float
    freq: float
    n: int

    @property
    def alpha(self) -> np.ndarray:
        """Quinchia's (eq. 9) coefficients ``alpha_k = -phi_k``."""
        return -self.phi

    def summary(self) -> str:
        """Coefficients and the information-criteria table."""
        coef = format_table(
            ["coefficient", "value", "std. error"],
            [[f"phi_{i + 1}", v, s] for i, (v, s) in enumerate(zip(self.phi, self.phi_se))]
            + [["sigma2 (u^2)", self.sigma2, math.nan]],
            title=(
                f"AR({self.order}) by {self.method} (n = {self.n}, freq = {self.freq:g} Hz, "
                f"max |root| = {self.max_root_modulus:.6g})"
            ),
        )
        crit = format_table(
            ["order", "sigma2", "AIC", "BIC", "chosen"],
            [
                [int(m), s, a, b, "*" if m == self.order else ""]
                for m, s, a, b in zip(self.orders, self.sigma2_path, self.aic, self.bic)
            ],
            title=f"information criteria (selection by {self.criterion.upper()})",
        )
        return coef + "\n\n" + crit

    def to_dict(self) -> dict[str, Any]:
        """Fields as a JSON-ready dict."""
        return {
            "phi": self.phi.tolist(), "phi_se": self.phi_se.tolist(), "sigma2": self.sigma2,
            "order": self.order, "method": self.method, "criterion": self.criterion,
            "orders": self.orders.tolist(), "sigma2_path": self.sigma2_path.tolist(),
            "aic": self.aic.tolist(), "bic": self.bic.tolist(),
            "max_root_modulus": self.max_root_modulus, "freq": self.freq, "n": self.n,
        }

    def coefficient_values(self) -> dict[str, Any]:
        """``{"ar": (phi_1, ..., phi_p), "innovation": sigma2 (u^2)}``;
        :func:`stochmod.fit.classical.ar_model` builds the model."""
        return {"ar": tuple(float(v) for v in self.phi), "innovation": float(self.sigma2)}


def fit_ar(
    x: ArrayLike,
    freq: float,
    order: int | None = None,
    *,
    max_order: int = 10,
    method: str = "burg",
    criterion: str = "bic",
    demean: bool = True,
) -> ARFit:
    """Fit an AR(p) model, choosing p by an information criterion when not given.

    Parameters
    ----------
    x : array_like, shape (n,)
        Static sensor error signal in units u (e.g. after :func:`~stochmod.empirical.denoise.denoise`,
        Quinchia Section 5.3).
    freq : float
        Sampling frequency in Hz (kept for the model; AR coefficients are per sample).
    order : int, optional
        The order; None selects it among 1..`max_order` by `criterion`.
    max_order : int
        Largest order considered when `order` is None (with a given order, the criteria table
        covers orders 1..`order`).
    method : {"burg", "yw", "yw-adjusted"}
        Burg (always stationary; Quinchia's choice), Yule-Walker with ``n`` or ``n - k``
        denominators.
    criterion : {"bic", "aic"}
        ``n log sigma2_m + m log n`` or ``n log sigma2_m + 2 m``.
    demean : bool
        Subtract the sample mean first.

    Returns
    -------
    ARFit

    Raises
    ------
    EstimationError
        If the fitted model is not stationary (possible with ``"yw-adjusted"`` on short data);
        the message names the largest characteristic-root modulus.
    InputError
        Bad signal, order, method or criterion.
    """
    freq = check_freq(freq)
    if method not in _METHODS:
        raise InputError(f"method must be one of {_METHODS}, got {method!r}")
    if criterion not in _CRITERIA:
        raise InputError(f"criterion must be one of {_CRITERIA}, got {criterion!r}")
    if order is None:
        top = check_positive_int(max_order, name="max_order")
    else:
        top = check_positive_int(order, name="order")
    xd, top = _prepare(x, top, demean)
    n = xd.size
    r = _autocov_direct(xd, top, False)  # for the standard errors (before xd is overwritten)
    if method == "burg":
        ks, sig = _burg_path(xd, top)
        table = _levinson_from_reflection(ks)
    else:
        table, sig = _yw_path(xd, top, method == "yw-adjusted")
    orders = np.arange(1, top + 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        n_log_s2 = np.where(sig > 0, n * np.log(np.where(sig > 0, sig, 1.0)), np.inf)
    aic = n_log_s2 + 2 * orders
    bic = n_log_s2 + orders * math.log(n)
    p = top if order is not None else int(orders[np.argmin(bic if criterion == "bic" else aic)])
    phi = table[p - 1, :p].copy()
    rmax = check_stationary(phi, what=f"AR({p}) fitted by {method}")
    if not sig[p - 1] > 0:
        raise EstimationError(
            f"non-positive innovation variance {sig[p - 1]:.3g} for AR({p}) ({method}): the "
            "signal is (numerically) perfectly predictable"
        )
    gamma = solve_toeplitz(r[:p], np.eye(p))
    phi_se = np.sqrt(np.clip(np.diag(gamma), 0.0, None) * sig[p - 1] / n)
    return ARFit(
        phi=phi, sigma2=float(sig[p - 1]), order=p, method=method, criterion=criterion,
        orders=orders, sigma2_path=sig.copy(), aic=aic, bic=bic, phi_se=phi_se,
        max_root_modulus=rmax, freq=freq, n=n,
    )
