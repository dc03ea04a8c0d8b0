"""Results of GMWM fits: estimates, their covariance (eqs. 22-23), intervals and the J-test
(eq. 27) of Stebler et al. (2014).

:class:`GMWMResult` holds what a search found (:class:`stochmod.fit.engine.SearchResult`) and
the data it matched, and derives inference lazily. The binding function is a component, not a
subclass hook: an analytic fit has ``binding=None`` (the model's theoretical WV); indirect
inference passes a :class:`~stochmod.fit.results.Binding` (e.g.
:class:`stochmod.fit.indirect.SimulatedBinding`) whose WV, Jacobian and own covariance replace
the analytic ones in eqs. 22-27. The covariances a caller computed elsewhere (a selection
computes V once per signal and the model-based covariance in its workers) are carried by the
fields ``covariance`` and ``null_covariance`` (:meth:`GMWMResult.with_data_covariance`,
:meth:`GMWMResult.with_null_covariance`).
"""

from __future__ import annotations

import functools
import math
from typing import Any, Protocol

import attrs
import numpy as np
from scipy import special
from scipy.linalg import solve_triangular

from stochmod.core.errors import DomainError, EstimationError
from stochmod.fit.engine import SearchResult, canonical, full_rank, sandwich, weighted_svd
from stochmod.fit.weighting import (
    bootstrap_covariance,
    chi2_variance,
    data_covariance,
    model_covariance,
)
from stochmod.core.model import Model
from stochmod.core.process import Process
from stochmod.core.tables import format_table
from stochmod.empirical.pooled import PooledWaveletVariance
from stochmod.empirical.wavelet_variance import WaveletVariance, estimator_options

__all__ = ["GMWMResult", "JTest", "JTestForm", "ParameterEstimate", "Binding", "Resampling",
           "negligible_components", "JTEST_MIN_EDF"]

#: Smallest equivalent degrees of freedom M_j / 2^j of a level used by the J-test.
JTEST_MIN_EDF = 16.0
#: Eigenvalues of the residual correlation below this fraction of the largest count as fitted.
_JTEST_RANK_RTOL = 1e-3


class Binding(Protocol):
    """A binding function other than the model's theoretical WV (indirect inference).

    Attributes
    ----------
    levels : int
        Number of levels J.
    """

    levels: int

    def wv(self, model: Model) -> np.ndarray:
        """``phi(theta)`` at the model's values, levels 1..J, unit^2."""

    def natural_jacobian(self, model: Model, mask: np.ndarray) -> np.ndarray:
        """``d phi / d theta`` over the free parameters on their natural scale, (J, n_free)."""

    def covariance(self, model: Model) -> np.ndarray:
        """Covariance of the binding's own error at the model (J x J, unit^4): added to the
        data's in eqs. 22-27."""


class Resampling(Protocol):
    """Inference by resampling that replaces the asymptotic one where it applies (the
    parametric bootstrap of :mod:`stochmod.fit.bootstrap`).

    Each method returns None where the asymptotic result (eqs. 22-23, 27) is kept.
    """

    def parameter(self, index: int) -> tuple[float, float, float] | None:
        """``(std_error, low, high)`` of free parameter `index` (natural scale)."""

    def physical(self, name: str) -> tuple[float, float, float] | None:
        """``(std_error, low, high)`` of physical parameter `name` (``"GM1.Tc"`` ...)."""

    def jtest(self) -> JTest | None:
        """The J-test (its p-value from the resampled statistic)."""

    def describe(self) -> str:
        """One line for :meth:`GMWMResult.summary`: which results are resampled, and how."""


#: Cached properties of :class:`GMWMResult` that do not read the data's WV covariance V once
#: :attr:`GMWMResult.null_covariance` is given (:meth:`GMWMResult.with_data_covariance`).
_WITHOUT_DATA_COVARIANCE = ("binding_covariance", "null_wv_covariance", "jacobian",
                            "analytic_jacobian", "analytic_weighted_svd", "negligible",
                            "fitted_wv", "jtest_form", "asymptotic_jtest")


@attrs.frozen
class JTest:
    """Goodness-of-fit J-test of eq. 27: statistic ~ chi2(df) under the model."""

    statistic: float
    df: int
    pvalue: float


@attrs.frozen
class JTestForm:
    """The quadratic form of the J-test (eq. 27) at a fit: ``J(r) = sum_k (e_k' r_s)^2 / l_k``
    with ``r_s = r[keep] / scale`` the residual on the correlation scale and ``(l_k, e_k)``
    the `df` largest eigenpairs of the correlation form of ``P V P'`` on the kept levels
    (:attr:`GMWMResult.jtest_form`).

    Attributes
    ----------
    keep : ndarray of int
        Levels (0-based) the statistic uses.
    scale : ndarray
        ``sqrt(V_jj)`` on those levels, unit^2.
    variances : ndarray (df,)
        Eigenvalues ``l_k`` (dimensionless).
    directions : ndarray (len(keep), df)
        Eigenvectors ``e_k``.
    """

    keep: np.ndarray
    scale: np.ndarray
    variances: np.ndarray
    directions: np.ndarray

    @property
    def df(self) -> int:
        """Degrees of freedom of the chi-square reference."""
        return int(self.variances.size)

    def statistic(self, residual: np.ndarray) -> float:
        """``J(r)`` of a residual ``r = nu_hat - nu(theta_hat)`` at levels 1..J, unit^2."""
        z = self.directions.T @ (residual[self.keep] / self.scale)
        return float(np.sum(z * z / self.variances))


@attrs.frozen
class ParameterEstimate:
    """One estimated quantity with its standard error and confidence interval."""

    name: str
    value: float
    std_error: float
    low: float
    high: float
    unit: str


def negligible_components(fit: GMWMResult, fraction: float = 0.01) -> list[str]:
    """Labels of fitted components whose wavelet variance stays below `fraction` of the
    empirical WV's standard error at every level: they do not change the fit (their amplitude
    ran to zero), so the candidate is the nested model without them in disguise."""
    emp = fit.empirical
    J = fit.levels
    se = np.sqrt(chi2_variance(emp.wv[:J], emp.n_coef[:J], emp.levels[:J]))
    return [
        label
        for label, proc in zip(fit.model.labels, fit.model.processes)
        if np.all(proc.wv(J, fit.model.freq) < fraction * se)
    ]


@attrs.define(slots=False)
class GMWMResult:
    """Result of :func:`stochmod.gmwm`.

    Attributes
    ----------
    model : Model
        The fitted composite model (``model.to_spec()`` gives canonical values).
    empirical : WaveletVariance
        The empirical wavelet variance that was matched.
    objective : float
        Value of eq. 20 at the estimate.
    weighting : str
        The weighting used (a registered name, or ``"custom"``).
    omega : ndarray (J, J)
        The weighting matrix.
    levels : int
        Number of levels J used.
    converged : bool
        Whether the best local search met its convergence tolerances.
    message : str
        The optimizer's message for the best start.
    n_starts : int
        Number of local searches run.
    n_evaluations : int
        Function evaluations over all starts.
    free_names : tuple of str
        Names of the estimated parameters (``label.param``).
    free_mask : ndarray of bool
        The estimated parameters among ``model.vector()``.
    alpha : float
        Significance level of the intervals.
    signal : ndarray or None
        The signal fitted (None when only its WV was given).
    covariance : ndarray (J, J) or None
        The data's WV covariance V when known beforehand (optimal or bootstrap weighting,
        or supplied by a selection); None: computed on first use (:attr:`wv_covariance`).
    null_covariance : ndarray (J, J) or None
        The model-based covariance of the WV at the estimate when computed beforehand
        (:meth:`with_null_covariance`); None: computed on first use
        (:attr:`null_wv_covariance`).
    rng_seed : int
        Seed of the parametric bootstrap of V when only a WV was given.
    binding : Binding or None
        The binding function when it is not the model's theoretical WV (indirect inference).
    pooled : PooledWaveletVariance or None
        The pooling of replicate recordings when the fit matched their pooled WV (its
        ``test`` says whether they share one WV).
    resampling : Resampling or None
        Bootstrap inference (:func:`stochmod.fit.bootstrap.bootstrap`) that replaces the
        asymptotic intervals and J-test p-value where it applies; None: asymptotic only.
    """

    model: Model
    empirical: WaveletVariance
    objective: float
    weighting: str
    omega: np.ndarray
    levels: int
    converged: bool
    message: str
    n_starts: int
    n_evaluations: int
    free_names: tuple[str, ...]
    free_mask: np.ndarray
    alpha: float = 0.05
    signal: np.ndarray | None = attrs.field(default=None, repr=False)
    covariance: np.ndarray | None = attrs.field(default=None, repr=False)
    null_covariance: np.ndarray | None = attrs.field(default=None, repr=False)
    rng_seed: int = 0
    binding: Binding | None = attrs.field(default=None, repr=False)
    pooled: PooledWaveletVariance | None = attrs.field(default=None, repr=False)
    resampling: Resampling | None = attrs.field(default=None, repr=False)

    @classmethod
    def from_search(cls, found: SearchResult, *, empirical: WaveletVariance, omega: np.ndarray,
                    weighting: str, levels: int, mask: np.ndarray, **fields: Any) -> GMWMResult:
        """The result of a search (:func:`stochmod.fit.engine.search` or a local one): the
        model in canonical order (:func:`~stochmod.fit.engine.canonical`), with the data it
        matched; `fields` sets the optional attributes (``signal``, ``covariance``, ...)."""
        fitted = canonical(found.model)
        return cls(model=fitted, empirical=empirical, objective=found.objective,
                   weighting=weighting, omega=omega, levels=levels, converged=found.converged,
                   message=found.message, n_starts=found.n_starts, n_evaluations=found.nfev,
                   free_names=tuple(np.asarray(fitted.param_names)[mask]), free_mask=mask,
                   **fields)

    # ---------------------------------------------------------------- inference
    @functools.cached_property
    def binding_covariance(self) -> np.ndarray | None:
        """Covariance of the binding function's own error at the estimate (J x J, unit^4;
        :meth:`Binding.covariance`), None for the analytic binding."""
        return None if self.binding is None else self.binding.covariance(self.model)

    @functools.cached_property
    def wv_covariance(self) -> np.ndarray:
        """Covariance ``V`` of the empirical WV used for inference (J x J), unit^4.

        The optimal or bootstrap weighting's own V (or :attr:`covariance` when supplied);
        otherwise the asymptotic estimator of eq. 17 on the signal with the deep levels
        decoupled (:func:`stochmod.fit.weighting.decoupled_covariance`), or a parametric
        bootstrap at the fit when only a WV was given. With a simulated binding, the
        binding's covariance (:attr:`binding_covariance`) is added: V is then the covariance
        of ``phi_hat - phi*(theta)``.
        """
        if self.covariance is not None:
            V = self.covariance
        elif self.signal is not None:
            V = data_covariance(self.signal, self.empirical, self.levels)
        else:
            V = bootstrap_covariance(self.model, self.empirical.n, self.levels, reps=100,
                                     rng=self.rng_seed, wavelet=self.empirical.wavelet,
                                     **estimator_options(self.empirical))
        extra = self.binding_covariance
        return V if extra is None else V + extra

    def model_based_covariance(self) -> np.ndarray | None:
        """:func:`~stochmod.fit.weighting.model_covariance` at the estimate: the covariance of
        the empirical WV if the fitted model were true (None for a family without a PSD).
        Depends on the fitted model only, not on the data's V; :attr:`null_covariance` when
        it was computed beforehand."""
        if self.null_covariance is not None:
            return self.null_covariance
        try:
            return model_covariance(self.model, self.empirical.n_coef[: self.levels],
                                    self.empirical.wavelet,
                                    variance_ratio=self.empirical.variance_ratio[: self.levels])
        except (NotImplementedError, EstimationError):
            return None

    @functools.cached_property
    def null_wv_covariance(self) -> np.ndarray:
        """Covariance of the empirical WV if the fitted model were true (J x J, unit^4):
        :meth:`model_based_covariance`, free of the estimation noise of eq. 17 at deep levels
        (plus the binding's covariance); the J-test's V. Falls back to :attr:`wv_covariance`
        for a family without a PSD."""
        cov = self.model_based_covariance()
        if cov is None:
            return self.wv_covariance
        extra = self.binding_covariance
        return cov if extra is None else cov + extra

    def with_data_covariance(self, covariance: np.ndarray) -> GMWMResult:
        """This fit with the data's WV covariance V supplied (a selection computes V once per
        signal, alongside the fits); :attr:`null_covariance` is kept, and with it what this
        fit has computed already that does not read V (:data:`_WITHOUT_DATA_COVARIANCE`: the
        Jacobians, the weighted SVD, the J-test under the model)."""
        fit = attrs.evolve(self, covariance=covariance)
        if self.null_covariance is not None:  # then the J-test's V is not the data's
            known = vars(self)
            vars(fit).update({k: known[k] for k in _WITHOUT_DATA_COVARIANCE if k in known})
        return fit

    def with_model_covariance(self) -> GMWMResult:
        """This fit with the fitted model's covariance of the WV at the estimate
        (:meth:`model_based_covariance`) as the V of its intervals too, as a weighting with
        ``inference = "model"`` declares (:mod:`stochmod.fit.weighting_plugins`); unchanged
        where the model has none (a family without a PSD)."""
        fit = self if self.null_covariance is not None else self.with_null_covariance()
        return fit if fit.null_covariance is None else fit.with_data_covariance(fit.null_covariance)

    def with_null_covariance(self) -> GMWMResult:
        """This fit carrying its model-based covariance, computed now
        (:meth:`model_based_covariance`): a selection calls it in the worker that fitted the
        model, so that the cost is paid in parallel and the result travels with it."""
        return attrs.evolve(self, null_covariance=self.model_based_covariance())

    @functools.cached_property
    def jacobian(self) -> np.ndarray:
        """``D = d phi / d theta`` at the estimate over the free parameters, natural scale,
        shape (J, n_free): the model's analytic WV Jacobian, or the binding's."""
        if self.binding is not None:
            return self.binding.natural_jacobian(self.model, self.free_mask)
        return self.analytic_jacobian

    @functools.cached_property
    def analytic_jacobian(self) -> np.ndarray:
        """The model's analytic WV Jacobian at the estimate over the free parameters, shape
        (J, n_free) (:attr:`jacobian` without a binding)."""
        return self.model.wv_jacobian(self.levels)[:, self.free_mask]

    @functools.cached_property
    def analytic_weighted_svd(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(L, U, s)`` of :func:`~stochmod.fit.engine.weighted_svd` for
        :attr:`analytic_jacobian` and ``Omega``: what the criteria's identification and
        optimism read (:mod:`stochmod.fit.criteria`)."""
        return weighted_svd(self.analytic_jacobian, self.omega)

    @functools.cached_property
    def negligible(self) -> tuple[str, ...]:
        """Labels of :func:`negligible_components` at its default fraction."""
        return tuple(negligible_components(self))

    @functools.cached_property
    def fitted_wv(self) -> np.ndarray:
        """The binding function at the estimate (levels 1..J), unit^2: the fitted model's
        theoretical WV, or ``phi*(theta_hat)`` for a simulated binding."""
        if self.binding is not None:
            return self.binding.wv(self.model)
        return self.model.wv(self.levels)

    @functools.cached_property
    def cov_params(self) -> np.ndarray:
        """Covariance of the free parameters on their natural scale (eqs. 22-23)."""
        return sandwich(self.jacobian, self.omega, self.wv_covariance)

    @functools.cached_property
    def std_errors(self) -> np.ndarray:
        """Standard errors of the free parameters (natural scale)."""
        var = np.diag(self.cov_params)
        if np.any(var < -1e-10 * np.max(np.abs(var))):
            raise EstimationError(
                f"negative variances {var.tolist()} for {list(self.free_names)}: the "
                "wavelet-variance covariance is not positive semi-definite"
            )
        return np.sqrt(np.clip(var, 0.0, None))  # clip round-off only

    @functools.cached_property
    def jtest(self) -> JTest | None:
        """The J-test: :attr:`asymptotic_jtest`, with the bootstrap p-value of
        :attr:`resampling` when there is one."""
        if self.resampling is not None:
            found = self.resampling.jtest()
            if found is not None:
                return found
        return self.asymptotic_jtest

    @functools.cached_property
    def asymptotic_jtest(self) -> JTest | None:
        """J-test of eq. 27 with its chi-square p-value, valid for any weighting.

        At the estimate the residual is ``r = nu_hat - nu(theta_hat) ~ P e`` with
        ``P = I - D (D' Omega D)^{-1} D' Omega`` and ``e`` the WV's error of covariance V, so
        ``r' (P V P')^+ r ~ chi2`` with as many degrees of freedom as the rank (Hansen's
        statistic ``r' V^{-1} r`` is the special case of the optimal weighting; evaluated at
        another weighting's estimate it over-rejects). The statistic uses the levels whose
        equivalent degrees of freedom ``M_j / 2^j`` are at least :data:`JTEST_MIN_EDF` (their
        WV is close to normal); df is the rank of ``P V P'`` on those levels (eigenvalues of
        its correlation form above 1e-3 of the largest); the parameters of a component of
        negligible amplitude (on the boundary, :func:`negligible_components`)
        do not count as fitted. V is :attr:`null_wv_covariance`, the
        covariance under the fitted model: with the eq. 17 estimate, whose error the inverse
        amplifies, the test rejects a true model about twice as often as its level says.
        None when df < 1, or when the fitted parameters are not identified (the WV does not
        depend on one of them at the estimate, or the singular values of the weighted Jacobian
        fall below :data:`~stochmod.fit.engine.IDENTIFIED_RTOL` of the largest:
        :func:`~stochmod.fit.engine.weighted_svd`, whose orthogonal factors give ``P``).
        """
        form = self.jtest_form
        if form is None:
            return None
        stat = form.statistic(self.empirical.wv[: self.levels] - self.model_wv())
        return JTest(stat, form.df, float(special.chdtrc(form.df, stat)))

    @functools.cached_property
    def jtest_form(self) -> JTestForm | None:
        """The quadratic form of :attr:`asymptotic_jtest` (levels, V, the fit's projection),
        None where that test is None."""
        # a component whose amplitude ran to zero sits on the boundary: its directions are
        # not fitted (the estimate could not go below zero), so they stay in the residual
        dropped = set(self.negligible)
        owner = np.repeat(self.model.labels, [proc.n_params for proc in self.model.processes])
        fitted = ~np.isin(owner[self.free_mask], list(dropped))
        p = int(fitted.sum())
        J = self.levels
        levels = self.empirical.levels[:J]
        keep = np.flatnonzero(self.empirical.n_coef[:J] / 2.0**levels >= JTEST_MIN_EDF)
        df = min(keep.size, J - p)
        if df < 1:
            return None
        V = self.null_wv_covariance
        L, U, s = weighted_svd(self.jacobian[:, fitted], self.omega)
        if not full_rank(s, p):
            return None  # parameters not identified: no residual covariance to test against
        P = np.eye(J) - solve_triangular(L, U @ (U.T @ L))  # I - L^-1 U U' L
        C = (P @ V @ P.T)[np.ix_(keep, keep)]
        scale = np.sqrt(np.diag(V)[keep])  # units: work on the correlation scale
        evals, evecs = np.linalg.eigh(C / np.outer(scale, scale))
        # directions the fit nearly absorbs carry almost no residual variance, estimated
        # with V's error: they count as fitted (rank at a relative tolerance)
        df = min(df, int(np.sum(evals > _JTEST_RANK_RTOL * evals[-1])))
        if df < 1:
            return None
        return JTestForm(keep, scale, evals[-df:], evecs[:, -df:])

    def parameters(self) -> list[ParameterEstimate]:
        """Canonical parameters with standard errors and intervals.

        Positive parameters get intervals on the log scale (delta method), so they stay
        positive; others are symmetric. Where :attr:`resampling` gives one, its standard error
        and interval replace the asymptotic ones (:mod:`stochmod.fit.bootstrap`).
        """
        z = special.ndtri(1 - self.alpha / 2)
        vec = self.model.vector()[self.free_mask]
        units = _units(self.model)[self.free_mask]
        boot = self.resampling
        out = []
        for i, (name, v, unit) in enumerate(zip(self.free_names, vec, units)):
            found = None if boot is None else boot.parameter(i)
            if found is None:
                se = self.std_errors[i]
                lo, hi = _interval(v, se, z)
            else:
                se, lo, hi = found
            out.append(ParameterEstimate(name, float(v), float(se), lo, hi, unit))
        return out

    def physical(self) -> list[ParameterEstimate]:
        """Physical parameters (GM correlation time and sigma, WN density, RW K ...) with
        intervals from the delta method on the log scale, or from :attr:`resampling` where
        it gives one."""
        z = special.ndtri(1 - self.alpha / 2)
        boot = self.resampling
        freq = self.model.freq
        C = None  # the asymptotic covariance, when some value needs it
        out, start = [], 0
        for label, proc in zip(self.model.labels, self.model.processes):
            k = proc.n_params
            vec = proc.vector()
            block = slice(start, start + k)
            start += k
            base = proc.physical(freq)
            for name, pv in base.items():
                found = None if boot is None else boot.physical(f"{label}.{name}")
                if found is not None:
                    se, lo, hi = found
                    out.append(ParameterEstimate(f"{label}.{name}", pv.value, se, lo, hi, pv.unit))
                    continue
                if C is None:
                    C = np.zeros((self.model.n_params,) * 2)
                    C[np.ix_(self.free_mask, self.free_mask)] = self.cov_params
                Cp = C[block, block]
                grad = np.array([_physical_derivative(proc, vec, i, name, pv.value, freq)
                                 for i in range(k)])
                se = float(np.sqrt(max(grad @ Cp @ grad, 0.0)))  # NaN when grad is unknown
                lo, hi = _interval(pv.value, se, z)
                out.append(ParameterEstimate(f"{label}.{name}", pv.value, se, lo, hi, pv.unit))
        return out

    def model_wv(self) -> np.ndarray:
        """The binding function at the estimate, levels 1..J, unit^2 (:attr:`fitted_wv`)."""
        return self.fitted_wv

    def summary(self) -> str:
        """Readable report: estimates with intervals (canonical and physical), objective, J-test."""
        pct = f"{100 * (1 - self.alpha):g}%"
        emp = self.empirical
        robust = (f", robust WV: {emp.rho}, efficiency {emp.efficiency:g}" if emp.robust else "")
        head = (f"GMWM fit of {self.model.name} ({self.weighting} weighting{robust}, "
                f"J = {self.levels}, N = {emp.n}, freq = {self.model.freq:g} Hz)")
        rows = [[e.name, e.value, e.std_error, e.low, e.high, e.unit] for e in self.parameters()]
        table = format_table(["parameter", "estimate", "std.err", f"{pct} low", f"{pct} high", "unit"],
                             rows, title=head)
        prow = [[e.name, e.value, e.low, e.high, e.unit] for e in self.physical()]
        ptable = format_table(["physical", "value", f"{pct} low", f"{pct} high", "unit"], prow)
        lines = [table, "", ptable, "", f"objective (eq. 20): {self.objective:.6g}"]
        jt = self.jtest
        if jt is not None:
            lines.append(f"J-test (eq. 27): statistic {jt.statistic:.4g}, df {jt.df}, p-value {jt.pvalue:.3g}")
        if self.resampling is not None:
            lines.append(self.resampling.describe())
        lines.append(f"converged: {self.converged} ({self.n_starts} local searches, "
                     f"{self.n_evaluations} evaluations): {self.message}")
        if emp.contamination is not None:
            lines.extend(["", emp.contamination.summary()])
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe summary: model spec, objective, estimates (no lazily expensive fields
        beyond those the summary shows)."""
        jt = self.jtest
        return {
            "model": self.model.to_spec(),
            "name": self.model.name,
            "objective": self.objective,
            "weighting": self.weighting,
            "levels": self.levels,
            "converged": self.converged,
            "parameters": [attrs.asdict(e) for e in self.parameters()],
            "physical": [attrs.asdict(e) for e in self.physical()],
            "jtest": None if jt is None else attrs.asdict(jt),
            "robust": self.empirical.robust_info(),
        }


def _physical_derivative(proc: Process, vec: np.ndarray, i: int, name: str, value: float,
                         freq: float) -> float:
    """d physical[name] / d vec[i] by differences with a relative step 1e-6: central, or
    one-sided next to the domain's edge (a unit-root AR, a GM corner at Nyquist); NaN when
    the physical value is not defined on either side."""
    h = 1e-6 * max(abs(vec[i]), 1e-300)

    def at(step: float) -> float:
        moved = vec.copy()
        moved[i] += step
        return proc.from_vector(moved).physical(freq)[name].value

    for lo, hi in ((-h, h), (-h, 0.0), (0.0, h)):
        try:
            a = value if lo == 0.0 else at(lo)
            b = value if hi == 0.0 else at(hi)
        except (DomainError, ArithmeticError, ValueError, EstimationError):
            continue
        d = (b - a) / (hi - lo)
        if np.isfinite(d):
            return float(d)
    return math.nan


def _interval(value: float, se: float, z: float) -> tuple[float, float]:
    """Interval ``value */ exp(z se / value)`` (delta method on the log scale) for a positive
    value, so that it stays positive; ``value -+ z se`` otherwise. An upper end beyond the
    float range is inf."""
    value, se = float(value), float(se)
    if not value > 0:
        return value - z * se, value + z * se
    r = z * se / value
    log_hi = math.log(value) + r
    hi = math.exp(log_hi) if log_hi < 709.0 else math.inf
    return math.exp(math.log(value) - r), hi




def _units(model: Model) -> np.ndarray:
    """The unit of every entry of ``model.vector()``."""
    out = []
    for p in model.processes:
        for spec in p.parameters():
            out.extend([spec.unit] * spec.size)
    return np.asarray(out, dtype=object)
