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
import warnings
from collections.abc import Sequence
from typing import Any

import attrs
import numpy as np
from numpy.typing import ArrayLike
from scipy import optimize, stats

from stochmod._validation import as_signal, check_freq, check_positive_int
from stochmod.errors import EstimationError, InputError, SpecError
from stochmod.fit.weighting import WEIGHTINGS, chi2_variance, weighting_from_covariance
from stochmod.model import Model, as_model, model_from_spec
from stochmod.process import Process, as_generator
from stochmod.reporting import format_table
from stochmod.signal.wavelet_variance import WaveletVariance, wvar

__all__ = ["gmwm", "GMWMResult", "JTest", "ParameterEstimate"]

#: Smallest equivalent degrees of freedom M_j / 2^j of a level used by the J-test.
JTEST_MIN_EDF = 8.0

_BOUND = 300.0  # |unconstrained| bound: keeps exp() finite while allowing any realistic scale


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


def _least_squares(fun, jac, x0: np.ndarray) -> optimize.OptimizeResult:
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)
        return optimize.least_squares(
            fun, np.clip(x0, -_BOUND, _BOUND), jac=jac, bounds=(-_BOUND, _BOUND),
            method="trf", x_scale="jac", xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=2000,
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
        eq. 17 on the signal, or a parametric bootstrap at the fit when only a WV was given.
        """
        if self._covariance is not None:
            return self._covariance
        if self._signal is not None:
            from stochmod.signal.wv_covariance import wv_covariance

            return wv_covariance(self._signal, self.levels, wavelet=self.empirical.wavelet)
        return bootstrap_covariance(self.model, self.empirical.n, self.levels,
                                    reps=100, rng=self._rng_seed, wavelet=self.empirical.wavelet)

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
        return np.sqrt(np.clip(np.diag(self.cov_params), 0, None))

    @functools.cached_property
    def jtest(self) -> JTest | None:
        """J-test of eq. 27 with V the WV covariance, on the levels whose equivalent degrees of
        freedom ``M_j / 2^j`` are at least :data:`JTEST_MIN_EDF` (deeper levels have too few
        independent coefficients for V to be estimated, which would inflate the statistic);
        None when no more levels than free parameters remain."""
        p = int(self.free_mask.sum())
        levels = self.empirical.levels[: self.levels]
        keep = np.flatnonzero(self.empirical.n_coef[: self.levels] / 2.0**levels >= JTEST_MIN_EDF)
        if keep.size <= p:
            return None
        resid = (self.empirical.wv[: self.levels] - self.model_wv())[keep]
        V = self.wv_covariance[np.ix_(keep, keep)]
        stat = float(resid @ np.linalg.solve(V, resid))
        df = int(keep.size - p)
        return JTest(stat, df, float(stats.chi2.sf(stat, df)))

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
            if v > 0:
                f = np.exp(min(z * se / v, 700.0))
                lo, hi = v / f, v * f
            else:
                lo, hi = v - z * se, v + z * se
            out.append(ParameterEstimate(name, float(v), float(se), float(lo), float(hi), unit))
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
                grad = np.zeros(k)
                for i in range(k):
                    h = 1e-6 * max(abs(vec[i]), 1e-300)
                    up, dn = vec.copy(), vec.copy()
                    up[i] += h
                    dn[i] -= h
                    try:
                        grad[i] = (proc.from_vector(up).physical(freq)[name].value
                                   - proc.from_vector(dn).physical(freq)[name].value) / (2 * h)
                    except Exception:  # domain edge: one-sided
                        grad[i] = (proc.from_vector(up).physical(freq)[name].value - pv.value) / h
                se = float(np.sqrt(max(grad @ Cp @ grad, 0.0)))
                if pv.value > 0:
                    f = np.exp(min(z * se / pv.value, 700.0))
                    lo, hi = pv.value / f, pv.value * f
                else:
                    lo, hi = pv.value - z * se, pv.value + z * se
                out.append(ParameterEstimate(f"{label}.{name}", pv.value, se, lo, hi, pv.unit))
        return out

    def model_wv(self) -> np.ndarray:
        """The fitted model's theoretical WV at the fitted levels."""
        return self.model.wv(self.levels)

    def summary(self) -> str:
        """Readable report: estimates with intervals (canonical and physical), objective, J-test."""
        pct = f"{100 * (1 - self.alpha):g}%"
        head = (f"GMWM fit of {self.model.name} ({self.weighting} weighting, J = {self.levels}, "
                f"N = {self.empirical.n}, freq = {self.model.freq:g} Hz)")
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
        }


def _sandwich(D: np.ndarray, W: np.ndarray, V: np.ndarray) -> np.ndarray:
    """``B V B^T`` with ``B = (D^T W D)^{-1} D^T W`` (eqs. 22-23), symmetrised."""
    A = D.T @ W @ D
    try:
        B = np.linalg.solve(A, D.T @ W)
    except np.linalg.LinAlgError:
        raise EstimationError(
            "D^T Omega D is singular: some parameters are not identified by the wavelet variance"
        ) from None
    C = B @ V @ B.T
    return 0.5 * (C + C.T)


def _units(model: Model) -> np.ndarray:
    out = []
    for p in model.processes:
        for spec in p.parameters():
            out.extend([spec.unit] * spec.size)
    return np.asarray(out, dtype=object)


def bootstrap_covariance(model: Model, n: int, levels: int, *, reps: int = 100,
                         rng: np.random.Generator | int = 0, wavelet: str = "haar") -> np.ndarray:
    """Parametric bootstrap covariance of the empirical WV (eq. 35): `reps` simulations of
    `n` samples from `model`, seeded."""
    reps = check_positive_int(reps, name="reps", minimum=2)
    gen = as_generator(rng)
    sims = np.array([
        wvar(model.simulate(n, g), model.freq, wavelet=wavelet, levels=levels).wv
        for g in gen.spawn(reps)
    ])
    return np.cov(sims, rowvar=False)


def gmwm(
    data: ArrayLike | WaveletVariance,
    model: Model | Process | str | dict,
    freq: float | None = None,
    *,
    weighting: str = "diagonal",
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
    weighting : {"diagonal", "optimal", "bootstrap", "identity"}
        ``"diagonal"``: inverse chi-square variances of the empirical WV (fast default);
        ``"optimal"``: inverse of the full asymptotic covariance of eq. 17 (needs the signal);
        ``"bootstrap"``: inverse of a parametric-bootstrap covariance (eq. 35) at a first
        diagonal fit, then refitted; ``"identity"``.
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

    Returns
    -------
    GMWMResult
        (an :class:`~stochmod.fit.indirect.IndirectGMWMResult` when a component is simulated)
    """
    if weighting not in WEIGHTINGS:
        raise InputError(f"unknown weighting {weighting!r}; choose one of {list(WEIGHTINGS)}")
    signal = None
    if isinstance(data, WaveletVariance):
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
        emp = wvar(signal, freq, wavelet=wavelet, levels=levels)
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
    if weighting == "diagonal":
        omega = np.diag(1.0 / chi2_variance(nu_hat, emp.n_coef[:J], emp.levels[:J]))
    elif weighting == "identity":
        omega = np.eye(J)
    elif weighting == "optimal":
        if signal is None:
            raise InputError("weighting='optimal' needs the signal, not only its wavelet variance")
        from stochmod.signal.wv_covariance import wv_covariance

        covariance = wv_covariance(signal, J, wavelet=wavelet)
        omega = weighting_from_covariance(covariance)
    else:  # bootstrap: a first diagonal fit, then the covariance at that fit
        first = gmwm(emp, base, freq, weighting="diagonal", levels=J, n_starts=n_starts,
                     n_random=n_random, starts=starts, rng=rng, binding=binding, R=R,
                     max_sim=max_sim)
        covariance = bootstrap_covariance(first.model, emp.n, J, reps=bootstrap_reps, rng=rng,
                                          wavelet=emp.wavelet)
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


def _search(base: Model, nu_hat: np.ndarray, omega: np.ndarray, mask: np.ndarray,
            n_starts: int, n_random: int, starts: Sequence[Model], seed: int,
            n_refine: int = 3, *, problem_factory: Any = _Problem) -> dict[str, Any]:
    """Multi-start minimisation of eq. 20.

    Candidates: the families' guesses, the given starts, `n_starts` seeded perturbations of
    the guesses, and the best of `n_random` random points screened by the objective. Each
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
            flat = _least_squares(problem.flat_residuals, problem.flat_jacobian, x0)
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
