"""The Generalized Method of Wavelet Moments (GMWM) estimator (Stebler et al., 2014, eqs. 19-27).

``gmwm(x, "2*GM+WN", freq)`` matches the model's theoretical Haar wavelet variance to the
empirical one by weighted least squares (eq. 20) over the families' unconstrained
transforms, with analytic Jacobians from the composer. Starting values come from the
families' guesses refined on the flattened criterion of eq. 34, plus a deterministic,
seeded multi-start (random draws screened by the objective, best ones refined), so that
the global optimum is found reliably.
"""

from __future__ import annotations

import functools
import math
import warnings
from collections.abc import Sequence
from typing import Any

import attrs
import numpy as np
from numpy.typing import ArrayLike
from scipy import optimize, stats

from stochmod._validation import as_signal, check_freq, check_positive_int
from stochmod.errors import DomainError, EstimationError, InputError, SpecError
from stochmod.fit.weighting import (
    WEIGHTINGS,
    data_covariance,
    level_variances,
    model_covariance,
    weighting_from_covariance,
)
from stochmod.model import Model, as_model, model_from_spec
from stochmod.process import Process, as_generator
from stochmod.reporting import format_table
from stochmod.signal.wavelet_variance import WaveletVariance, wvar

__all__ = ["gmwm", "GMWMResult", "JTest", "ParameterEstimate"]

#: Smallest equivalent degrees of freedom M_j / 2^j of a level used by the J-test.
JTEST_MIN_EDF = 16.0
#: Eigenvalues of the residual correlation below this fraction of the largest count as fitted.
_JTEST_RANK_RTOL = 1e-3

_BOUND = 300.0  # |unconstrained| bound: keeps exp() finite while allowing any realistic scale
#: Stage 1 of the search (the flattened criterion of eq. 34) only ranks starting points for the
#: refinement on eq. 20 itself: (tolerance, evaluation cap) looser than the refinement's
#: (1e-12, 2000), which crawled along flat valleys of weakly identified models.
_STAGE1_TOLERANCE = (1e-8, 100)


@attrs.frozen
class JTest:
    """Goodness-of-fit J-test of eq. 27: statistic ~ chi2(df) under the model."""

    statistic: float
    df: int
    pvalue: float


@attrs.frozen
class ParameterEstimate:
    """One estimated quantity with its standard error and confidence interval."""

    name: str
    value: float
    std_error: float
    low: float
    high: float
    unit: str


def _resolve_model(model: Model | Process | str | dict, freq: float) -> Model:
    if isinstance(model, (str, dict)):
        return model_from_spec(model, freq)
    return as_model(model).bind(freq)


class _Problem:
    """The least-squares form of eq. 20 over the free, unconstrained parameters."""

    def __init__(self, template: Model, nu_hat: np.ndarray, omega: np.ndarray, mask: np.ndarray):
        self.template = template
        self.nu_hat = nu_hat
        self.levels = nu_hat.size
        self.mask = mask
        self.theta_full = template.to_unconstrained()
        # Omega = L^T L with L upper-triangular-free: use the Cholesky factor of Omega.
        self.L = np.linalg.cholesky(omega).T
        self.omega = omega

    def model(self, x: np.ndarray) -> Model:
        theta = self.theta_full.copy()
        theta[self.mask] = x
        return self.template.from_unconstrained(theta)

    def _jac_u(self, x: np.ndarray) -> tuple[np.ndarray, Model]:
        theta = self.theta_full.copy()
        theta[self.mask] = x
        m = self.template.from_unconstrained(theta)
        D = m.wv_jacobian(self.levels) @ m.transform_jacobian(theta)
        return D[:, self.mask], m

    # binding function phi(theta) and its Jacobian on the free unconstrained scale
    # (indirect inference, stochmod.fit.indirect, overrides these two)
    def phi(self, x: np.ndarray) -> np.ndarray:
        return self.model(x).wv(self.levels)

    def dphi(self, x: np.ndarray) -> np.ndarray:
        return self._jac_u(x)[0]

    def residuals(self, x: np.ndarray) -> np.ndarray:
        return self.L @ (self.nu_hat - self.phi(x))

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        return -self.L @ self.dphi(x)

    def flat_residuals(self, x: np.ndarray) -> np.ndarray:
        return 1.0 - self.phi(x) / self.nu_hat

    def flat_jacobian(self, x: np.ndarray) -> np.ndarray:
        return -self.dphi(x) / self.nu_hat[:, None]

    def objective(self, x: np.ndarray) -> float:
        r = self.residuals(x)
        return float(r @ r)

    def safe_objective(self, x: np.ndarray) -> float:
        try:
            value = self.objective(x)
        except (ArithmeticError, ValueError):
            return np.inf
        return value if np.isfinite(value) else np.inf


def _least_squares(fun, jac, x0: np.ndarray, tol: float = 1e-12,
                   max_nfev: int = 2000) -> optimize.OptimizeResult:
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)
        return optimize.least_squares(
            fun, np.clip(x0, -_BOUND, _BOUND), jac=jac, bounds=(-_BOUND, _BOUND),
            method="trf", x_scale="jac", xtol=tol, ftol=tol, gtol=tol, max_nfev=max_nfev,
        )


def _canonical(model: Model) -> Model:
    """Order repeated components of one family by their first parameter, largest first
    (GM: fastest first), so that fitted models compare across runs (no label switching)."""
    procs = list(model.processes)
    for family in {p.family for p in procs}:
        slots = [i for i, p in enumerate(procs) if p.family == family]
        ordered = sorted((procs[i] for i in slots), key=lambda p: -float(p.vector()[0]))
        for i, p in zip(slots, ordered):
            procs[i] = p
    return attrs.evolve(model, processes=tuple(procs))


@attrs.define(slots=False)
class GMWMResult:
    """Result of :func:`gmwm`.

    Attributes
    ----------
    model : Model
        The fitted composite model (``model.to_spec()`` gives canonical values).
    empirical : WaveletVariance
        The empirical wavelet variance that was matched.
    objective : float
        Value of eq. 20 at the estimate.
    weighting : str
        The weighting used.
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
    _signal: np.ndarray | None = attrs.field(default=None, repr=False)
    _covariance: np.ndarray | None = attrs.field(default=None, repr=False)
    _rng_seed: int = 0

    # ---------------------------------------------------------------- inference
    @functools.cached_property
    def wv_covariance(self) -> np.ndarray:
        """Covariance ``V`` of the empirical WV used for inference (J x J), unit^4.

        The optimal or bootstrap weighting's own V; otherwise the asymptotic estimator of
        eq. 17 on the signal with the deep levels decoupled
        (:func:`stochmod.fit.weighting.decoupled_covariance`), or a parametric bootstrap at
        the fit when only a WV was given.
        """
        if self._covariance is not None:
            return self._covariance
        if self._signal is not None:
            return data_covariance(self._signal, self.empirical, self.levels)
        return bootstrap_covariance(self.model, self.empirical.n, self.levels,
                                    reps=100, rng=self._rng_seed, wavelet=self.empirical.wavelet,
                                    **_estimator_options(self.empirical))

    @functools.cached_property
    def null_wv_covariance(self) -> np.ndarray:
        """Covariance of the empirical WV if the fitted model were true (J x J, unit^4):
        :func:`stochmod.fit.weighting.model_covariance` at the estimate, free of the
        estimation noise of eq. 17 at deep levels; the J-test's V. Falls back to
        :attr:`wv_covariance` for a family without a PSD."""
        cov = self._model_null_covariance
        return self.wv_covariance if cov is None else cov

    @functools.cached_property
    def _model_null_covariance(self) -> np.ndarray | None:
        """:func:`~stochmod.fit.weighting.model_covariance` at the estimate (None for a family
        without a PSD); depends on the fitted model only, not on the data's V."""
        try:
            return model_covariance(self.model, self.empirical.n_coef[: self.levels],
                                    self.empirical.wavelet,
                                    variance_ratio=self.empirical.variance_ratio[: self.levels])
        except (NotImplementedError, EstimationError):
            return None

    def with_data_covariance(self, covariance: np.ndarray) -> GMWMResult:
        """This fit with the data's WV covariance V supplied (model selection computes V
        alongside the fits); cached results that do not depend on V are kept."""
        new = attrs.evolve(self, covariance=covariance)
        if "_model_null_covariance" in self.__dict__:
            new.__dict__["_model_null_covariance"] = self.__dict__["_model_null_covariance"]
        return new

    @functools.cached_property
    def _jacobian(self) -> np.ndarray:
        D = self.model.wv_jacobian(self.levels)
        return D[:, self.free_mask]

    @functools.cached_property
    def cov_params(self) -> np.ndarray:
        """Covariance of the free parameters on their natural scale (eqs. 22-23)."""
        return _sandwich(self._jacobian, self.omega, self.wv_covariance)

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
        """J-test of eq. 27, valid for any weighting.

        At the estimate the residual is ``r = nu_hat - nu(theta_hat) ~ P e`` with
        ``P = I - D (D' Omega D)^{-1} D' Omega`` and ``e`` the WV's error of covariance V, so
        ``r' (P V P')^+ r ~ chi2`` with as many degrees of freedom as the rank (Hansen's
        statistic ``r' V^{-1} r`` is the special case of the optimal weighting; evaluated at
        another weighting's estimate it over-rejects). The statistic uses the levels whose
        equivalent degrees of freedom ``M_j / 2^j`` are at least :data:`JTEST_MIN_EDF` (their
        WV is close to normal); df is the rank of ``P V P'`` on those levels (eigenvalues of
        its correlation form above 1e-3 of the largest); the parameters of a component of
        negligible amplitude (on the boundary, :func:`~stochmod.fit.criteria.negligible_components`)
        do not count as fitted. V is :attr:`null_wv_covariance`, the
        covariance under the fitted model: with the eq. 17 estimate, whose error the inverse
        amplifies, the test rejects a true model about twice as often as its level says.
        None when df < 1.
        """
        from stochmod.fit.criteria import negligible_components

        # a component whose amplitude ran to zero sits on the boundary: its directions are
        # not fitted (the estimate could not go below zero), so they stay in the residual
        dropped = set(negligible_components(self))
        owner = np.repeat(self.model.labels, [proc.n_params for proc in self.model.processes])
        fitted = ~np.isin(owner[self.free_mask], list(dropped))
        p = int(fitted.sum())
        J = self.levels
        levels = self.empirical.levels[:J]
        keep = np.flatnonzero(self.empirical.n_coef[:J] / 2.0**levels >= JTEST_MIN_EDF)
        df = min(keep.size, J - p)
        if df < 1:
            return None
        D, W, V = self._jacobian[:, fitted], self.omega, self.null_wv_covariance
        try:
            P = np.eye(J) - D @ np.linalg.solve(D.T @ W @ D, D.T @ W)
        except np.linalg.LinAlgError:
            return None  # parameters not identified: no residual covariance to test against
        C = (P @ V @ P.T)[np.ix_(keep, keep)]
        r = (self.empirical.wv[:J] - self.model_wv())[keep]
        scale = np.sqrt(np.diag(V)[keep])  # units: work on the correlation scale
        evals, evecs = np.linalg.eigh(C / np.outer(scale, scale))
        # directions the fit nearly absorbs carry almost no residual variance, estimated
        # with V's error: they count as fitted (rank at a relative tolerance)
        df = min(df, int(np.sum(evals > _JTEST_RANK_RTOL * evals[-1])))
        if df < 1:
            return None
        evals, evecs = evals[-df:], evecs[:, -df:]
        z = evecs.T @ (r / scale)
        stat = float(np.sum(z * z / evals))
        return JTest(stat, int(df), float(stats.chi2.sf(stat, df)))

    def parameters(self) -> list[ParameterEstimate]:
        """Canonical parameters with standard errors and intervals.

        Positive parameters get intervals on the log scale (delta method), so they stay
        positive; others are symmetric.
        """
        z = stats.norm.ppf(1 - self.alpha / 2)
        vec = self.model.vector()[self.free_mask]
        units = _units(self.model)[self.free_mask]
        out = []
        for name, v, se, unit in zip(self.free_names, vec, self.std_errors, units):
            lo, hi = _interval(v, se, z)
            out.append(ParameterEstimate(name, float(v), float(se), lo, hi, unit))
        return out

    def physical(self) -> list[ParameterEstimate]:
        """Physical parameters (GM correlation time and sigma, WN density, RW K ...) with
        intervals from the delta method on the log scale."""
        z = stats.norm.ppf(1 - self.alpha / 2)
        freq = self.model.freq
        C = np.zeros((self.model.n_params,) * 2)
        C[np.ix_(self.free_mask, self.free_mask)] = self.cov_params
        out, start = [], 0
        for label, proc in zip(self.model.labels, self.model.processes):
            k = proc.n_params
            vec = proc.vector()
            Cp = C[start : start + k, start : start + k]
            start += k
            base = proc.physical(freq)
            for name, pv in base.items():
                grad = np.array([_physical_derivative(proc, vec, i, name, pv.value, freq)
                                 for i in range(k)])
                se = float(np.sqrt(max(grad @ Cp @ grad, 0.0)))  # NaN when grad is unknown
                lo, hi = _interval(pv.value, se, z)
                out.append(ParameterEstimate(f"{label}.{name}", pv.value, se, lo, hi, pv.unit))
        return out

    def model_wv(self) -> np.ndarray:
        """The fitted model's theoretical WV at the fitted levels."""
        return self.model.wv(self.levels)

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


def _sandwich(D: np.ndarray, W: np.ndarray, V: np.ndarray) -> np.ndarray:
    """``B V B^T`` with ``B = (D^T W D)^{-1} D^T W`` (eqs. 22-23), symmetrised.

    Computed with D's columns scaled to unit norm (a parameter the WV barely sees has a tiny
    column and a huge row of B), then scaled back: a variance beyond the float range is inf.
    """
    norms = np.linalg.norm(D, axis=0)
    if not np.all(np.isfinite(norms) & (norms > 0)):
        raise EstimationError("the wavelet variance does not depend on some parameter at the estimate")
    Ds = D / norms
    try:
        Bs = np.linalg.solve(Ds.T @ W @ Ds, Ds.T @ W)
    except np.linalg.LinAlgError:
        raise EstimationError(
            "D^T Omega D is singular: some parameters are not identified by the wavelet variance"
        ) from None
    Cs = Bs @ V @ Bs.T
    Cs = 0.5 * (Cs + Cs.T)
    with np.errstate(over="ignore"):
        return Cs / np.outer(norms, norms)


def _units(model: Model) -> np.ndarray:
    out = []
    for p in model.processes:
        for spec in p.parameters():
            out.extend([spec.unit] * spec.size)
    return np.asarray(out, dtype=object)


def _estimator_options(emp: WaveletVariance) -> dict[str, Any]:
    """The wvar options that reproduce `emp`'s estimator (robust or classical)."""
    if not emp.robust:
        return {}
    return {"robust": True, "efficiency": emp.efficiency, "rho": emp.rho}


def bootstrap_covariance(model: Model, n: int, levels: int, *, reps: int = 100,
                         rng: np.random.Generator | int = 0, wavelet: str = "haar",
                         robust: bool = False, efficiency: float = 0.6,
                         rho: str = "biweight") -> np.ndarray:
    """Parametric bootstrap covariance of the empirical WV (eq. 35): `reps` simulations of
    `n` samples from `model`, seeded; with `robust`, of the robust WV (same options as
    :func:`~stochmod.signal.wavelet_variance.wvar`)."""
    reps = check_positive_int(reps, name="reps", minimum=2)
    gen = as_generator(rng)
    options = {"robust": True, "efficiency": efficiency, "rho": rho} if robust else {}
    sims = np.array([
        wvar(model.simulate(n, g), model.freq, wavelet=wavelet, levels=levels, **options).wv
        for g in gen.spawn(reps)
    ])
    return np.cov(sims, rowvar=False)


def gmwm(
    data: ArrayLike | WaveletVariance,
    model: Model | Process | str | dict,
    freq: float | None = None,
    *,
    weighting: str | ArrayLike = "diagonal",
    levels: int | None = None,
    wavelet: str = "haar",
    n_starts: int = 4,
    n_random: int = 64,
    starts: Sequence[Model] = (),
    bootstrap_reps: int = 100,
    rng: int = 0,
    alpha: float = 0.05,
    binding: str = "auto",
    R: int = 10,
    max_sim: int = 2**20,
    robust: bool = False,
    efficiency: float = 0.6,
) -> GMWMResult:
    """Fit a composite model by the GMWM (eq. 20).

    Parameters
    ----------
    data : array_like or WaveletVariance
        The static error signal (unit u, mean removed or not: the Haar WV ignores the mean),
        or a precomputed empirical wavelet variance.
    model : Model, Process, str or dict
        The composite model (``"2*GM+WN"``, ``GM() + WN()`` ...); parameters with values are
        held fixed, free ones are estimated.
    freq : float
        Sampling frequency, Hz (taken from `data` when it is a WaveletVariance).
    weighting : {"diagonal", "optimal", "bootstrap", "identity"} or array_like (J, J)
        ``"diagonal"``: inverse chi-square variances of the empirical WV (fast default);
        ``"optimal"``: inverse of the full asymptotic covariance of eq. 17 (needs the signal);
        ``"bootstrap"``: inverse of a parametric-bootstrap covariance (eq. 35) at a first
        diagonal fit, then refitted; ``"identity"``; or a symmetric positive definite
        (J, J) matrix, used as Omega as given (``result.weighting == "custom"``).
    levels : int, optional
        Number of levels J (default: all the signal allows).
    wavelet : str
        Wavelet filter of the empirical WV (Haar by default).
    n_starts : int
        Number of extra local searches from seeded perturbed starts.
    n_random : int
        Random candidate points screened by the objective; the best seed extra searches.
    starts : sequence of Model
        Extra starting models (e.g. a nested model's fit padded with a new component).
    bootstrap_reps : int
        Replications of the bootstrap weighting.
    rng : int
        Seed of every random choice (results reproduce).
    alpha : float
        Significance level of the intervals.
    binding : {"auto", "analytic", "simulated"}
        The binding function phi(theta). ``"analytic"``: the families' theoretical WVs;
        ``"simulated"``: indirect inference (eq. 29), the empirical WV of a series of
        ``min(R N, max(max_sim, N))`` samples simulated from the model at theta with common
        random numbers (seed `rng`); ``"auto"`` (default): analytic when every family has a
        theoretical WV, else only the components without one are simulated (eq. 28 adds
        the analytic WVs of the others). See :mod:`stochmod.fit.indirect`.
    R : int
        Length of the simulated series in multiples of N (indirect inference only).
    max_sim : int
        Cap on the simulated length, samples (never below N).
    robust : bool
        Match the robust wavelet variance (:mod:`stochmod.signal.robust_wv`, Tukey biweight
        M-estimate of each level's coefficient variance) instead of the classical one: a few
        outliers in the record no longer drive the fit. Its variances (inflated by
        ``kappa_j``) enter the diagonal weighting, its covariance (eq. 17 on clipped
        coefficients, scaled by ``kappa``) the optimal weighting and the inference, the
        robust WV of the simulations the bootstrap. Implied when `data` is a robust
        WaveletVariance.
    efficiency : float
        Gaussian efficiency in (0, 1] of the robust estimator (default 0.6; robust only).

    Returns
    -------
    GMWMResult
        (an :class:`~stochmod.fit.indirect.IndirectGMWMResult` when a component is simulated)
    """
    custom = None
    if not isinstance(weighting, str):
        custom, weighting = np.array(weighting, dtype=np.float64), "custom"
    elif weighting not in WEIGHTINGS:
        raise InputError(f"unknown weighting {weighting!r}; choose one of {list(WEIGHTINGS)} "
                         "or pass a (J, J) matrix")
    signal = None
    if isinstance(data, WaveletVariance):
        if robust and not data.robust:
            raise InputError("robust=True needs the signal or a robust WaveletVariance "
                             "(wvar(x, freq, robust=True)); this one is classical")
        emp = data
        freq = emp.freq if freq is None else check_freq(freq)
        if levels is not None:
            levels = check_positive_int(levels, name="levels")
            if levels > emp.wv.size:
                raise InputError(f"levels = {levels} but the wavelet variance has {emp.wv.size} levels")
    else:
        if freq is None:
            raise InputError("freq (Hz) is required when data is a signal")
        freq = check_freq(freq)
        signal = as_signal(data, name="data", min_length=8)
        if np.ptp(signal) == 0:
            raise InputError("data is constant: it has no noise to model")
        emp = wvar(signal, freq, wavelet=wavelet, levels=levels,
                   **({"robust": True, "efficiency": efficiency} if robust else {}))
    J = emp.wv.size if levels is None else levels
    nu_hat = np.asarray(emp.wv[:J], float)
    if np.any(nu_hat <= 0):
        raise InputError("the empirical wavelet variance has non-positive levels (constant stretches?)")
    base = _resolve_model(model, freq)
    mask = base.free_mask()
    if not mask.any():
        raise SpecError(f"model {base.name} has no free parameter to estimate")
    if mask.sum() > J:
        raise InputError(f"model {base.name} has {int(mask.sum())} free parameters but only {J} levels")
    # --- indirect inference hook (stochmod.fit.indirect): None = analytic binding
    from stochmod.fit.indirect import plan_binding

    plan = plan_binding(base, binding, R=R, max_sim=max_sim, n=emp.n, levels=J, seed=rng,
                        wavelet=emp.wavelet)
    if plan is None and emp.wavelet != "haar":
        raise InputError(
            f"the analytic GMWM matches Haar wavelet variances; the data's WV uses {emp.wavelet!r}: "
            "use wavelet='haar' or binding='simulated' (indirect inference with the same wavelet)"
        )

    covariance = None
    if custom is not None:
        omega = _checked_omega(custom, J)
    elif weighting == "diagonal":
        omega = np.diag(1.0 / level_variances(emp, J))
    elif weighting == "identity":
        omega = np.eye(J)
    elif weighting == "optimal":
        if signal is None:
            raise InputError("weighting='optimal' needs the signal, not only its wavelet variance")
        covariance = data_covariance(signal, emp, J)
        omega = weighting_from_covariance(covariance)
    else:  # bootstrap: a first diagonal fit, then the covariance at that fit
        first = gmwm(emp, base, freq, weighting="diagonal", levels=J, n_starts=n_starts,
                     n_random=n_random, starts=starts, rng=rng, binding=binding, R=R,
                     max_sim=max_sim)
        covariance = bootstrap_covariance(first.model, emp.n, J, reps=bootstrap_reps, rng=rng,
                                          wavelet=emp.wavelet, **_estimator_options(emp))
        omega = weighting_from_covariance(covariance)
        starts = (*starts, first.model)

    fit = _search(base, nu_hat, omega, mask, n_starts, n_random, starts, rng,
                  problem_factory=_Problem if plan is None else plan.problem)
    fitted = _canonical(fit["model"])
    result_cls, extra = (GMWMResult, {}) if plan is None else plan.result_type()
    return result_cls(
        model=fitted, empirical=emp, objective=fit["objective"], weighting=weighting, omega=omega,
        levels=J, converged=fit["converged"], message=fit["message"], n_starts=fit["n_starts"],
        n_evaluations=fit["nfev"], free_names=tuple(np.asarray(fitted.param_names)[mask]),
        free_mask=mask, alpha=alpha, signal=signal, covariance=covariance, rng_seed=rng, **extra,
    )


def _checked_omega(omega: np.ndarray, J: int) -> np.ndarray:
    """A user's weighting matrix, checked: (J, J), finite, symmetric, positive definite."""
    if omega.shape != (J, J):
        raise InputError(f"the weighting matrix must have shape {(J, J)} (levels used), got {omega.shape}")
    if not np.all(np.isfinite(omega)):
        raise InputError("the weighting matrix has non-finite entries")
    if not np.allclose(omega, omega.T, rtol=1e-10, atol=0.0):
        raise InputError("the weighting matrix is not symmetric")
    try:
        np.linalg.cholesky(omega)
    except np.linalg.LinAlgError:
        raise InputError("the weighting matrix is not positive definite") from None
    return 0.5 * (omega + omega.T)


def _search(base: Model, nu_hat: np.ndarray, omega: np.ndarray, mask: np.ndarray,
            n_starts: int, n_random: int, starts: Sequence[Model], seed: int,
            n_refine: int = 3, *, problem_factory: Any = _Problem) -> dict[str, Any]:
    """Multi-start minimisation of eq. 20.

    Candidates: the families' guesses and their alternatives, the given starts, `n_starts`
    seeded perturbations of the guesses, and the best of `n_random` random points screened by the objective. Each
    candidate first descends the flattened criterion of eq. 34 (cheap, well scaled); the
    `n_refine` best distinct results (by eq. 20), and every given start as it is, are then
    refined on eq. 20 itself. The best refined point wins. `problem_factory` builds the
    least-squares problem (``_Problem``, or the simulated binding of indirect inference).
    """
    gen = np.random.default_rng(seed)
    template = base.start(nu_hat)
    problem = problem_factory(template, nu_hat, omega, mask)
    candidates = [template.to_unconstrained()[mask]]
    given = []
    for s in starts:
        s = _resolve_model(s, base.freq)
        if s.n_params != base.n_params or s.is_free:
            raise SpecError(f"start {s.name} does not match model {base.name} with all values given")
        given.append(s.to_unconstrained()[mask])
    candidates.extend(given)
    candidates.extend(alt.to_unconstrained()[mask] for alt in base.start_alternatives(nu_hat))
    for _ in range(n_starts):
        candidates.append(base.start(nu_hat, rng=gen).to_unconstrained()[mask])
    if n_random:
        centre = candidates[0]
        cloud = centre + gen.normal(0.0, 3.0, size=(n_random, centre.size))
        values = np.array([problem.safe_objective(x) for x in cloud])
        best_cloud = np.argsort(values)[: max(2, n_starts // 2)]
        candidates.extend(cloud[i] for i in best_cloud if np.isfinite(values[i]))

    nfev = 0
    stage1: list[tuple[float, np.ndarray]] = [(problem.safe_objective(x), x) for x in given]
    for x0 in candidates:
        try:
            flat = _least_squares(problem.flat_residuals, problem.flat_jacobian, x0,
                                  *_STAGE1_TOLERANCE)
        except (ArithmeticError, ValueError, np.linalg.LinAlgError, EstimationError):
            continue
        nfev += flat.nfev
        stage1.append((problem.safe_objective(flat.x), flat.x))
        stage1.append((problem.safe_objective(x0), x0))
    stage1 = [(v, x) for v, x in stage1 if np.isfinite(v)]
    stage1.sort(key=lambda item: item[0])
    chosen: list[np.ndarray] = []
    for _, x in stage1:
        if not any(np.allclose(x, c, rtol=1e-3, atol=1e-3) for c in chosen):
            chosen.append(x)
        if len(chosen) >= n_refine:
            break
    chosen.extend(g for g in given if not any(g is c for c in chosen))

    best: dict[str, Any] | None = None
    for x1 in chosen:
        try:
            res = _least_squares(problem.residuals, problem.jacobian, x1)
        except (ArithmeticError, ValueError, np.linalg.LinAlgError, EstimationError):
            continue
        nfev += res.nfev
        value = problem.safe_objective(res.x)
        if best is None or value < best["objective"]:
            best = {"x": res.x, "objective": value, "converged": bool(res.success),
                    "message": str(res.message)}
    if best is None or not np.isfinite(best["objective"]):
        raise EstimationError(f"GMWM failed to find a finite objective for {base.name} from any start")
    best["model"] = problem.model(best["x"])
    best["nfev"] = nfev
    best["n_starts"] = len(candidates)
    return best
