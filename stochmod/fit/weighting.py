"""Covariance of the empirical wavelet variance and the GMWM weighting matrices built from it.

The weightings themselves (``"diagonal"``, ``"optimal"`` ...) are plugins of the
``stochmod_weightings`` hook, found by name through the registry
(:mod:`stochmod.fit.weighting_plugins`); this module holds the numerics they share.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from stochmod.plugin import registry
from stochmod.core.checks import check_positive_int
from stochmod.core.errors import EstimationError, InputError, SpecError
from stochmod.core.model import Model
from stochmod.core.process import as_generator, psd_of
from stochmod.empirical.wavelet_variance import WaveletVariance, wvar
from stochmod.empirical.wv_covariance import wv_covariance
from stochmod.core.theory import wv_covariance_from_psd

__all__ = [
    "WEIGHTINGS",
    "COVARIANCE_MIN_EDF",
    "equivalent_dof",
    "chi2_variance",
    "level_variances",
    "decoupled_covariance",
    "data_covariance",
    "bootstrap_covariance",
    "model_covariance",
    "weighting_from_covariance",
    "check_weighting_matrix",
]


def __getattr__(name: str) -> Any:
    """``WEIGHTINGS``: the names of the registered weightings, at the time of the access
    (kept for compatibility; :func:`stochmod.fit.weighting_plugins.weighting_names`)."""
    if name == "WEIGHTINGS":
        return tuple(registry.weightings())
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

#: Smallest equivalent degrees of freedom ``M_j / 2^j`` of a level whose covariances with the
#: other levels are taken from the eq. 17 estimate (see :func:`decoupled_covariance`).
COVARIANCE_MIN_EDF = 4.0


def equivalent_dof(n_coef: np.ndarray, level: np.ndarray) -> np.ndarray:
    """Equivalent degrees of freedom ``eta_j = max(M_j / 2^j, 1)`` of each empirical WV
    (Percival & Walden, 2000, eq. 313c): the number of effectively independent squared
    wavelet coefficients at level j."""
    return np.maximum(np.asarray(n_coef, float) / 2.0 ** np.asarray(level, float), 1.0)


def chi2_variance(wv: np.ndarray, n_coef: np.ndarray, level: np.ndarray) -> np.ndarray:
    """Variance of each empirical WV from its equivalent degrees of freedom, unit^4.

    ``var(v_j) = 2 v_j^2 / eta_j`` with ``eta_j = max(M_j / 2^j, 1)`` (Percival & Walden,
    2000, eq. 313c): the same approximation that gives the chi-square intervals.
    """
    return 2.0 * np.asarray(wv, float) ** 2 / equivalent_dof(n_coef, level)


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


def decoupled_covariance(V: np.ndarray, wv: np.ndarray, n_coef: np.ndarray, level: np.ndarray,
                         *, min_edf: float = COVARIANCE_MIN_EDF) -> np.ndarray:
    """A positive definite covariance of the empirical WV from the eq. 17 estimate `V`.

    The eq. 17 estimator sums products of the few wavelet coefficients a deep level has: with
    fewer than about `min_edf` equivalent degrees of freedom its covariances are mostly noise
    and ``V`` is often indefinite there (negative variances of linear combinations). Such
    levels are decoupled: their row and column are replaced by zeros and their diagonal by the
    chi-square variance ``2 wv_j^2 / eta_j`` (:func:`chi2_variance`). If the block of the
    remaining levels is still not positive definite, the deepest of them is decoupled too,
    until it is.

    Parameters
    ----------
    V : ndarray (J, J)
        Estimated covariance of the empirical WV (eq. 17), unit^4.
    wv, n_coef, level : ndarray (J,)
        The empirical WV (unit^2), its number of coefficients and level numbers.
    min_edf : float
        Equivalent degrees of freedom below which a level is decoupled.

    Returns
    -------
    ndarray (J, J)
        Symmetric positive definite covariance, unit^4.
    """
    V = 0.5 * (np.asarray(V, float) + np.asarray(V, float).T)
    J = V.shape[0]
    if V.shape != (J, J) or np.shape(wv) != (J,):
        raise InputError(f"V must be (J, J) and wv (J,), got {V.shape} and {np.shape(wv)}")
    coupled = int(np.sum(np.cumprod(equivalent_dof(n_coef, level) >= min_edf)))
    while coupled > 0:
        block = V[:coupled, :coupled]
        d = np.sqrt(np.diag(block))
        if np.all(np.isfinite(d)) and np.all(d > 0):
            try:
                np.linalg.cholesky(block / np.outer(d, d))
                break
            except np.linalg.LinAlgError:
                pass
        coupled -= 1
    out = np.diag(chi2_variance(wv, n_coef, level))
    out[:coupled, :coupled] = V[:coupled, :coupled]
    return out


def level_variances(emp: WaveletVariance, levels: int) -> np.ndarray:
    """Variances of the empirical WV `emp` at levels 1..`levels` for the diagonal weighting,
    unit^4: :func:`chi2_variance` times the estimator's variance ratio ``kappa_j`` (1 for the
    classical estimator; for the robust one, its variance over the classical one's,
    :mod:`stochmod.empirical.robust_wv`)."""
    return (chi2_variance(emp.wv[:levels], emp.n_coef[:levels], emp.levels[:levels])
            * emp.variance_ratio[:levels])


def data_covariance(x: np.ndarray, emp: WaveletVariance, levels: int) -> np.ndarray:
    """Covariance of the empirical WV `emp` of the signal `x` at levels 1..`levels`: the
    asymptotic estimator of eq. 17 (:func:`stochmod.empirical.wv_covariance.wv_covariance`),
    with the deep levels decoupled (:func:`decoupled_covariance`), unit^4.

    For a robust `emp` (``emp.robust``), eq. 17 runs on the coefficients clipped at
    ``c sqrt(nu_j)`` (outliers do not dominate it) and is scaled by the robust estimator's
    variance ratios, ``V_jl sqrt(kappa_j kappa_l)`` (:mod:`stochmod.empirical.robust_wv`)."""
    clip = emp.tuning * np.sqrt(emp.wv[:levels]) if emp.robust and emp.efficiency < 1 else None
    V = wv_covariance(x, levels, wavelet=emp.wavelet, clip=clip)
    V = decoupled_covariance(V, emp.wv[:levels], emp.n_coef[:levels], emp.levels[:levels])
    ratio = np.sqrt(emp.variance_ratio[:levels])
    return V * np.outer(ratio, ratio)


def bootstrap_covariance(model: Model, n: int, levels: int, *, reps: int = 100,
                         rng: np.random.Generator | int = 0, wavelet: str = "haar",
                         **estimator: Any) -> np.ndarray:
    """Parametric bootstrap covariance of the empirical WV (eq. 35): `reps` simulations of
    `n` samples from `model` (all values given, bound to its frequency), seeded; J x J, unit^4.
    `estimator` holds wvar's estimator options (:func:`~stochmod.empirical.wavelet_variance.estimator_options`: the robust WV's)."""
    reps = check_positive_int(reps, name="reps", minimum=2)
    gen = as_generator(rng)
    sims = np.array([
        wvar(model.simulate(n, g), model.freq, wavelet=wavelet, levels=levels, **estimator).wv
        for g in gen.spawn(reps)
    ])
    return np.cov(sims, rowvar=False)


def check_weighting_matrix(omega: Any, levels: int, *, source: str = "the weighting matrix"
                           ) -> np.ndarray:
    """`omega` checked as a GMWM weighting matrix: shape (J, J), finite, symmetric (to 1e-6 on
    the correlation scale: an inverse computed by solves is symmetric only to rounding) and
    positive definite; returned as a float64 array, unchanged.

    Raises
    ------
    InputError
        Naming `source` and the failed property.
    """
    omega = np.asarray(omega, dtype=np.float64)
    J = int(levels)
    if omega.shape != (J, J):
        raise InputError(f"{source} must have shape {(J, J)} (levels used), got {omega.shape}")
    if not np.all(np.isfinite(omega)):
        raise InputError(f"{source} has non-finite entries")
    d = np.diag(omega)
    if np.any(d <= 0):
        raise InputError(f"{source} is not positive definite (non-positive diagonal)")
    scale = np.sqrt(np.outer(d, d))
    if np.any(np.abs(omega - omega.T) > 1e-6 * scale):
        raise InputError(f"{source} is not symmetric")
    try:
        np.linalg.cholesky(0.5 * (omega + omega.T) / scale)
    except np.linalg.LinAlgError:
        raise InputError(f"{source} is not positive definite") from None
    return omega


def model_covariance(model: Model, n_coef: np.ndarray, wavelet: str = "haar", *,
                     variance_ratio: np.ndarray | None = None) -> np.ndarray:
    """Large-sample covariance of the empirical WV under `model` (J x J, unit^4).

    The Gaussian components' summed PSD gives :func:`stochmod.core.theory.wv_covariance_from_psd`;
    a component with its own sampling covariance (:meth:`Process.wv_sampling_covariance`,
    e.g. the random ramp) adds it (cross terms between the two kinds are left out). Unlike
    the eq. 17 estimate it has no estimation noise at deep levels: it is the covariance a
    test of the model (the J-test) should use under the null hypothesis.

    Parameters
    ----------
    model : Model
        A composite model with values, bound to its sampling frequency.
    n_coef : ndarray (J,)
        Number of coefficients M_j of the empirical WV at levels 1..J.
    wavelet : str
        Wavelet filter of the empirical WV.
    variance_ratio : ndarray (J,), optional
        ``kappa_j`` of a robust estimator: the result is scaled to ``V_jl sqrt(kappa_j kappa_l)``.
    """
    if model.freq is None:
        raise SpecError("the model is not bound to a sampling frequency: use model.bind(freq)")
    freq = float(model.freq)
    spectral, total = [], np.zeros((len(n_coef), len(n_coef)))
    for proc in model.processes:
        own = proc.wv_sampling_covariance(n_coef, freq, wavelet)
        if own is None:
            spectral.append(proc)
        else:
            total += own
    if spectral:
        breakpoints = sorted({b for p in spectral for b in p.psd_breakpoints(freq)})
        total += wv_covariance_from_psd(
            lambda f: np.sum([psd_of(p, f, freq) for p in spectral], axis=0), n_coef, freq,
            wavelet=wavelet, breakpoints=breakpoints)
    if variance_ratio is not None:
        ratio = np.sqrt(np.asarray(variance_ratio, dtype=np.float64))
        total = total * np.outer(ratio, ratio)
    return total
