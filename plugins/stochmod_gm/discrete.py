"""The first-order Gauss-Markov process in discrete time: datasheet values <-> (phi, q).

Quinchia et al. (2013, eqs. 2-4 and 27-30) and Gonzalez et al. (2015): the exact discrete form
of ``dx/dt = -beta x + w(t)`` at a sampling frequency, the first-order forms the papers use,
the AR(1) read back as a GM, and the GM of a bias instability. :func:`ar1_to_gm` is the one
AR(1) conversion, shared with :meth:`stochmod_gm.GM.from_ar1`. The units and per-sample
values of the other families are in :mod:`stochmod.core.units`.
"""

from __future__ import annotations

import math
from typing import Literal

import attrs
import numpy as np
from numpy.typing import ArrayLike

from stochmod.sdk import (
    BI_FACTOR,
    DomainError,
    InputError,
    bi_floor,
    check_freq,
    checked_values,
    format_table,
    scalar_or_array,
)

__all__ = [
    "GMMethod",
    "GMDiscrete",
    "ar1_to_gm",
    "gm_discretize",
    "gm_from_discrete",
    "gm_from_bias_instability",
    "gm_driving_psd",
]


GMMethod = Literal["exact", "euler", "quinchia2013"]


@attrs.frozen
class GMDiscrete:
    """A first-order Gauss-Markov process and its discrete form at a sampling frequency.

    ``x[k] = phi * x[k-1] + w[k]``, ``var w[k] = q``; the continuous process is
    ``dx/dt = -beta x + w(t)`` with stationary variance ``sigma2``.

    Attributes
    ----------
    sigma2 : float or ndarray
        Stationary variance of the continuous process, u^2.
    beta : float or ndarray
        Inverse correlation time 1/Tc, 1/s.
    fs : float
        Sampling frequency, Hz.
    phi : float or ndarray
        Transition coefficient (exact: ``exp(-beta/fs)``).
    q : float or ndarray
        Innovation (driving noise) variance per sample, u^2 (exact: ``sigma2 (1 - phi^2)``).
    method : str
        ``"exact"``, ``"euler"`` or ``"quinchia2013"`` (see :func:`gm_discretize`).
    """

    sigma2: float | np.ndarray
    beta: float | np.ndarray
    fs: float
    phi: float | np.ndarray
    q: float | np.ndarray
    method: str = "exact"

    @property
    def sigma(self) -> float | np.ndarray:
        """Stationary standard deviation, u."""
        if isinstance(self.sigma2, np.ndarray):
            return np.sqrt(self.sigma2)
        return math.sqrt(self.sigma2)

    @property
    def tc(self) -> float | np.ndarray:
        """Correlation time Tc = 1/beta, s."""
        return 1.0 / self.beta

    @property
    def stationary_variance(self) -> float | np.ndarray:
        """Stationary variance of the discrete chain, ``q / (1 - phi^2)``, u^2.

        Equals :attr:`sigma2` for the exact method only; the first-order forms give
        ``sigma2 / (1 - beta/(2 fs))`` (euler) and about ``sigma2 (1 - beta/(2 fs))``
        (quinchia2013).
        """
        return self.q / ((1.0 - self.phi) * (1.0 + self.phi))

    def summary(self) -> str:
        """Table of Tc, sigma, beta, phi and q (one row per element for array fields)."""
        cols = np.broadcast_arrays(*(np.atleast_1d(np.asarray(v, dtype=float)) for v in (
            self.tc, self.sigma, self.beta, self.phi, self.q)))
        rows = [list(r) for r in zip(*(c.ravel() for c in cols))]
        return format_table(
            ["Tc [s]", "sigma [u]", "beta [1/s]", "phi", "q [u^2]"], rows,
            title=f"Gauss-Markov at fs = {self.fs:g} Hz ({self.method})",
            digits=9,
        )


def _gm_result(sigma2: np.ndarray, beta: np.ndarray, phi: np.ndarray, q: np.ndarray,
               fs: float, method: str, scalar: bool) -> GMDiscrete:
    """A GMDiscrete with all fields broadcast to one shape (floats for scalar input)."""
    fields = np.broadcast_arrays(sigma2, beta, phi, q)
    out = [scalar_or_array(np.array(v, dtype=float), scalar) for v in fields]
    return GMDiscrete(sigma2=out[0], beta=out[1], fs=fs, phi=out[2], q=out[3], method=method)


def _gm_inputs(sigma: ArrayLike, tc: ArrayLike, fs: float
               ) -> tuple[np.ndarray, np.ndarray, float, bool]:
    fs = check_freq(fs, name="fs")
    s, s_scalar = checked_values(sigma, "sigma", sign="nonneg")
    t, t_scalar = checked_values(tc, "tc", sign="pos")
    return s, t, fs, s_scalar and t_scalar


def gm_discretize(sigma: ArrayLike, tc: ArrayLike, fs: float, method: GMMethod = "exact"
                  ) -> GMDiscrete:
    """Discrete form of a first-order Gauss-Markov process at sampling frequency `fs`.

    Parameters
    ----------
    sigma : float or array_like
        Stationary standard deviation, u (rad/s or m/s^2), >= 0.
    tc : float or array_like
        Correlation time Tc, s, > 0.
    fs : float
        Sampling frequency, Hz, > 0.
    method : {"exact", "euler", "quinchia2013"}
        ``"exact"``: ``phi = exp(-beta/fs)``, ``q = sigma^2 (1 - phi^2)`` -- the sampled process
        has exactly the continuous autocovariance ``sigma^2 exp(-beta |tau|)``.
        ``"euler"``: ``phi = 1 - beta/fs``, ``q = 2 beta sigma^2 / fs`` (Quinchia eqs. 2 and 4 times
        dt; Gonzalez Alg. 1 lines 2-3 ``Phi = I + F dt``, ``Q_k = Q dt``), first order in beta/fs.
        ``"quinchia2013"``: ``phi = 1 - beta/fs`` with the exact ``q`` (Quinchia eqs. 2-3, and
        Appendix eqs. 21 and 28).  Both first-order forms need ``Tc * fs > 1``.

    Returns
    -------
    GMDiscrete
    """
    s, t, fs, scalar = _gm_inputs(sigma, tc, fs)
    x = 1.0 / (t * fs)  # beta * dt
    sigma2 = s * s
    if method == "exact":
        phi, q = np.exp(-x), -sigma2 * np.expm1(-2.0 * x)
    elif method in ("euler", "quinchia2013"):
        if np.any(x >= 1.0):
            raise InputError(
                f"method={method!r} needs Tc * fs > 1 (its phi = 1 - 1/(Tc fs) must be positive); "
                f"got Tc * fs = {np.min(t) * fs:g}; use method='exact'"
            )
        phi = 1.0 - x
        q = 2.0 * x * sigma2 if method == "euler" else -sigma2 * np.expm1(-2.0 * x)
    else:
        raise InputError(f"method must be 'exact', 'euler' or 'quinchia2013', got {method!r}")
    return _gm_result(sigma2, 1.0 / t, phi, q, fs, method, scalar)


def ar1_to_gm(phi: ArrayLike, q: ArrayLike, fs: float
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, bool]:
    """The one AR(1) -> Gauss-Markov conversion (used by :func:`gm_from_discrete` and
    :meth:`stochmod_gm.GM.from_ar1`): ``(phi, q, beta, sigma2, scalar)`` as arrays.

    ``beta = -ln(phi) fs`` (1/s), ``sigma2 = q / ((1 - phi)(1 + phi))`` (u^2).

    Raises
    ------
    DomainError
        A phi outside the open interval (0, 1).
    InputError
        A non-finite phi or q, a negative q, a bad `fs`.
    """
    fs = check_freq(fs, name="fs")
    p, p_scalar = checked_values(phi, "phi")
    qq, q_scalar = checked_values(q, "q", sign="nonneg")
    if np.any((p <= 0) | (p >= 1)):
        raise DomainError(
            f"phi must lie in the open interval (0, 1) for a Gauss-Markov process, got {phi!r}"
        )
    return p, qq, -np.log(p) * fs, qq / ((1.0 - p) * (1.0 + p)), p_scalar and q_scalar


def gm_from_discrete(phi: ArrayLike, q: ArrayLike, fs: float) -> GMDiscrete:
    """Recover a Gauss-Markov process from its exact discrete form (an AR(1) with 0 < phi < 1).

    Parameters
    ----------
    phi : float or array_like
        AR(1) coefficient, in (0, 1).  Quinchia's Table 2 prints ``alpha_1 = -phi``.
    q : float or array_like
        Innovation variance per sample, u^2, >= 0.
    fs : float
        Sampling frequency, Hz, > 0.

    Returns
    -------
    GMDiscrete
        ``beta = -ln(phi) fs``, ``sigma2 = q / (1 - phi^2)``.  The relative error of beta is
        about ``eps / (beta/fs)``: a phi very close to 1 carries few digits of beta.
    """
    p, qq, beta, sigma2, scalar = ar1_to_gm(phi, q, fs)
    return _gm_result(sigma2, beta, p, qq, fs, "exact", scalar)


def gm_from_bias_instability(b: ArrayLike, tc: ArrayLike, fs: float, *,
                             factor: float = BI_FACTOR, method: GMMethod = "exact") -> GMDiscrete:
    """The Gauss-Markov model of a bias instability B as Quinchia et al. (2013) build it.

    ``sigma_GM = factor * B`` (eq. 29, with ``factor = 0.664`` there: the GM's stationary sigma
    is set to the flat Allan-deviation floor), then :func:`gm_discretize`.

    Parameters
    ----------
    b : float or array_like
        Bias instability B in u (rad/s or m/s^2), >= 0.
    tc : float or array_like
        Correlation time read from the Allan variance, s, > 0.
    fs : float
        Sampling frequency, Hz, > 0.
    factor : float
        Floor / B ratio; :data:`stochmod.core.units.BI_FACTOR` (exact) or :data:`stochmod.core.units.BI_FACTOR_IEEE` (0.664, the paper's).
    method : {"exact", "euler", "quinchia2013"}
        See :func:`gm_discretize`.  Quinchia's Appendix uses ``"quinchia2013"``.
    """
    return gm_discretize(bi_floor(b, factor), tc, fs, method=method)


def gm_driving_psd(sigma: ArrayLike, tc: ArrayLike,
                   form: Literal["exact", "gonzalez2015"] = "exact") -> float | np.ndarray:
    """PSD of the white noise driving ``dx/dt = -x/Tc + w`` for a GM of stationary sigma.

    Parameters
    ----------
    sigma : float or array_like
        Stationary standard deviation, u, >= 0.
    tc : float or array_like
        Correlation time, s, > 0.
    form : {"exact", "gonzalez2015"}
        ``"exact"``: ``2 sigma^2 / Tc`` in u^2/s (Quinchia eq. 4, ``2 beta sigma^2``): the only
        value for which the stationary variance ``q Tc / 2`` equals ``sigma^2``.
        ``"gonzalez2015"``: ``sigma^2 Tc`` (u^2 s) as printed in Gonzalez et al. (2015) eq. 22;
        it is not dimensionally a driving PSD and gives the variance ``sigma^2 Tc^2 / 2``.
        Kept only to reproduce that paper.

    Returns
    -------
    float or ndarray
    """
    s, s_scalar = checked_values(sigma, "sigma", sign="nonneg")
    t, t_scalar = checked_values(tc, "tc", sign="pos")
    if form == "exact":
        psd = 2.0 * s * s / t
    elif form == "gonzalez2015":
        psd = s * s * t
    else:
        raise InputError(f"form must be 'exact' or 'gonzalez2015', got {form!r}")
    return scalar_or_array(np.asarray(psd, dtype=float), s_scalar and t_scalar)
