"""Model-selection criteria for GMWM fits: the wavelet-variance information criterion (WVIC).

The WVIC of Guerrier et al. ("An algorithm for automatic inertial sensors calibration",
ION GNSS 2013) estimates the *out-of-sample* GMWM objective: the in-sample objective of
eq. 20 plus an optimism penalty. Let ``nu`` be the true wavelet variance, ``nu_hat`` its
estimate with covariance ``V``, ``Omega`` the (common) weighting matrix, ``D = d nu / d theta``
at the estimate (free parameters) and ``B = (D' Omega D)^{-1} D' Omega`` the GMWM's influence,
so that ``nu(theta_hat) - nu ~ D B (nu_hat - nu) = P e`` to first order. For an independent
replicate ``nu_tilde`` of the empirical WV,

    E[(nu_tilde - nu(theta_hat))' Omega (nu_tilde - nu(theta_hat))]
        - E[(nu_hat - nu(theta_hat))' Omega (nu_hat - nu(theta_hat))]  =  2 tr(Omega D B V),

hence ``WVIC = objective + 2 tr(Omega D B V)``. It is computed stably as
``2 tr(Pi L V L')`` with ``Omega = L' L`` and ``Pi`` the orthogonal projector onto the column
space of ``L D`` (rank-revealing SVD, so nearly unidentified parameters do not break it).
With ``Omega = V^{-1}`` the optimism is ``2 p`` (p = rank of D): the criterion then reduces
to an AIC on the J-statistic. The R package gmwm reports the same quantity as
"ObjFun + Optimism, Optimism = 2 tr(A dTheta Omega V)".

Criteria are plugins: objects with a ``name`` and ``__call__(fit) -> float`` (smaller is
better), returned by the ``stochmod_criteria`` hook. This module registers the first-party
:data:`WVIC` with the plugin manager when it is imported (it needs no entry point).
"""

from __future__ import annotations

from typing import Any, ClassVar

import attrs
import numpy as np

from stochmod.core.errors import InputError
from stochmod.fit.engine import IDENTIFIED_RTOL, full_rank
from stochmod.fit.results import GMWMResult, negligible_components
from stochmod.plugin.hookspecs import hookimpl
from stochmod.plugin.registry import criteria

__all__ = ["WaveletVarianceIC", "WVIC", "optimism", "identified", "negligible_components",
           "get_criterion",
           "criterion_names", "stochmod_criteria"]

_RANK_TOL = 1e-10  # singular values below this fraction of the largest count as zero


def optimism(fit: GMWMResult, covariance: np.ndarray | None = None) -> float:
    """Optimism ``2 tr(Omega D B V)`` of a GMWM fit's in-sample objective (dimensionless,
    on the scale of the objective of eq. 20).

    Parameters
    ----------
    fit : GMWMResult
        A GMWM fit; its ``omega``, ``levels``, ``free_mask`` and fitted model are used.
    covariance : ndarray (J, J), optional
        ``V``, the covariance of the empirical WV at the fitted levels, unit^4 (default:
        ``fit.wv_covariance``).

    Returns
    -------
    float
        Non-negative optimism (``2 tr(Pi L V L')``, see the module docstring).
    """
    J = fit.levels
    V = fit.wv_covariance if covariance is None else np.asarray(covariance, float)
    if V.shape != (J, J):
        raise InputError(f"covariance must have shape {(J, J)}, got {V.shape}")
    L, U, s = fit.analytic_weighted_svd
    U = U[:, : int(np.sum(s > s[0] * _RANK_TOL))] if s.size else U
    return float(max(2.0 * np.trace(U.T @ (L @ V @ L.T) @ U), 0.0))


def identified(fit: GMWMResult, tol: float = IDENTIFIED_RTOL) -> bool:
    """Whether the free parameters of `fit` are locally identified by the wavelet variance.

    True when the singular values of ``L D`` (``Omega = L' L``, columns scaled to unit norm)
    satisfy ``s_min / s_max > tol``; False for degenerate fits such as a GM whose correlation
    time ran to infinity (only ``sigma2 beta`` is then determined) or a component of
    negligible amplitude, whose parameters and intervals mean nothing.
    """
    _, _, s = fit.analytic_weighted_svd
    n_free = int(fit.free_mask.sum())
    return n_free > 0 and full_rank(s, n_free, tol) and not fit.negligible


@attrs.frozen
class WaveletVarianceIC:
    """The WVIC: ``objective + 2 tr(Omega D B V)`` (smaller is better).

    ``__call__(fit)`` returns the criterion; :meth:`optimism` the penalty alone. Objectives of
    different candidates compare only when they share the same weighting matrix ``Omega``
    and WV covariance ``V`` (:func:`stochmod.select` guarantees both).
    """

    name: ClassVar[str] = "wvic"
    description: ClassVar[str] = ("wavelet-variance information criterion: GMWM objective + "
                                  "2 tr(Omega D B V) (Guerrier et al., ION GNSS 2013)")

    def optimism(self, fit: GMWMResult) -> float:
        """The optimism penalty ``2 tr(Omega D B V)`` of `fit`."""
        return optimism(fit)

    def __call__(self, fit: GMWMResult) -> float:
        return float(fit.objective) + self.optimism(fit)


#: The first-party criterion instance (registered as ``"wvic"``).
WVIC = WaveletVarianceIC()


@hookimpl
def stochmod_criteria() -> list[Any]:
    """Register the WVIC."""
    return [WVIC]


def criterion_names() -> list[str]:
    """Names of the registered selection criteria, sorted."""
    return sorted(criteria())


def get_criterion(name: str) -> Any:
    """The registered criterion called `name` (``"wvic"`` or a plugin's)."""
    table = criteria()
    try:
        return table[name]
    except KeyError:
        raise InputError(
            f"unknown selection criterion {name!r}; registered criteria: {', '.join(sorted(table))}"
        ) from None

