"""Covariance of the empirical wavelet variance and the GMWM weighting matrices built from it."""

from __future__ import annotations

import numpy as np

from stochmod.errors import EstimationError, InputError

__all__ = ["WEIGHTINGS", "chi2_variance", "weighting_from_covariance"]

#: Names accepted by ``stochmod.gmwm(weighting=...)``.
WEIGHTINGS = ("diagonal", "optimal", "bootstrap", "identity")


def chi2_variance(wv: np.ndarray, n_coef: np.ndarray, level: np.ndarray) -> np.ndarray:
    """Variance of each empirical WV from its equivalent degrees of freedom, unit^4.

    ``var(v_j) = 2 v_j^2 / eta_j`` with ``eta_j = max(M_j / 2^j, 1)`` (Percival & Walden,
    2000, eq. 313c): the same approximation that gives the chi-square intervals.
    """
    eta = np.maximum(np.asarray(n_coef, float) / 2.0 ** np.asarray(level, float), 1.0)
    return 2.0 * np.asarray(wv, float) ** 2 / eta


def weighting_from_covariance(V: np.ndarray) -> np.ndarray:
    """The weighting ``Omega = V^{-1}``, computed stably (symmetrised, checked positive definite)."""
    V = 0.5 * (np.asarray(V, float) + np.asarray(V, float).T)
    if V.ndim != 2 or V.shape[0] != V.shape[1]:
        raise InputError(f"covariance must be square, got shape {V.shape}")
    scale = np.sqrt(np.diag(V))
    if np.any(~np.isfinite(scale)) or np.any(scale <= 0):
        raise EstimationError("wavelet-variance covariance has non-positive or non-finite variances")
    R = V / np.outer(scale, scale)
    try:
        L = np.linalg.cholesky(R)
    except np.linalg.LinAlgError:
        raise EstimationError(
            "the wavelet-variance covariance is not positive definite (too few coefficients at "
            "deep levels?): use fewer levels or weighting='diagonal'"
        ) from None
    Rinv = np.linalg.solve(L.T, np.linalg.solve(L, np.eye(len(R))))
    return Rinv / np.outer(scale, scale)
