"""Parametric bootstrap of GMWM fits: intervals and J-test where the asymptotics fail.

The asymptotic intervals of a GMWM fit (eqs. 22-23 of Stebler et al., 2014: the sandwich
``B V B'`` and the delta method on the log scale) and its J-test (eq. 27, chi-square
reference) hold when the record is long against every time scale of the model and each
component dominates levels with many equivalent degrees of freedom. They fail where users
need them: a slow Gauss-Markov component (correlation time a sizeable fraction of the
record), a component seen at a few deep levels only, a nearly white GM. There the estimate
is skewed, its spread depends on where it lies, and the J statistic is not chi-square.

This module replaces them, where needed, by a parametric bootstrap (Stebler et al. 2014,
eq. 35, used there for the weighting matrix):

1. ``B`` records of the fit's length are simulated from the fitted model
   (``fit.model.simulate(n, rng)``), each from its own child of one
   :class:`numpy.random.SeedSequence`, so the draws do not depend on how they are spread
   over workers;
2. each record's empirical WV is computed with the fit's estimator (wavelet, levels, robust
   options: :func:`stochmod.empirical.wavelet_variance.estimator_options`);
3. eq. 20 is solved again by one local search of the engine
   (:func:`stochmod.fit.engine.refine`, Levenberg-Marquardt) from the fit's estimate, with
   the weighting the fit used: a weighting computed from the WV alone (``"diagonal"``,
   ``"identity"``, a plugin's without ``needs_signal`` or ``needs_fit``) is computed again
   from the replicate's WV, so that the bootstrap repeats the estimator, the correlation
   of a data-dependent ``Omega`` with the residuals included (it biases a deep-level
   component's estimate and inflates the J statistic); any other ``Omega`` (``"optimal"``,
   ``"bootstrap"``, a custom matrix) is held fixed at the fit's, as eq. 17 or a nested
   bootstrap per replicate would cost more than the refit. Replicates whose search fails
   are left out (counted in :attr:`BootstrapDraws.failed`);
4. the draws give intervals for every free parameter and physical value, and the J
   statistic of every replicate, computed as the fit's (:class:`stochmod.fit.results.JTestForm`
   built at the replicate's estimate, WV and Omega), gives the J-test's bootstrap p-value.

:func:`identification` is the diagnostic that decides, for ``intervals="auto"``, which
parameters need the bootstrap; :func:`bootstrap` attaches the bootstrap to a fit
(``fit.resampling``), after which ``fit.parameters()``, ``fit.physical()`` and
``fit.jtest`` use it; ``stochmod.gmwm(..., intervals="auto" | "bootstrap")`` does both.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from concurrent.futures import Executor
from typing import Any

import attrs
import numpy as np
from scipy import special

from stochmod.core.checks import check_positive_int
from stochmod.core.errors import DomainError, EstimationError, InputError
from stochmod.core.model import Model
from stochmod.core.parallel import single_threaded_blas
from stochmod.core.tables import format_table
from stochmod.empirical.wavelet_variance import estimator_options, wvar
from stochmod.fit.engine import Problem, canonical, full_rank, refine, weighted_svd
from stochmod.fit.results import GMWMResult, JTest, JTestForm
from stochmod.fit.weighting import check_weighting_matrix, model_covariance
from stochmod.fit.weighting_plugins import WeightingInput, get_weighting

__all__ = [
    "DEFAULT_METHOD",
    "INTERVALS",
    "INTERVAL_METHODS",
    "MAX_RELATIVE_SE",
    "MAX_TC_FRACTION",
    "MIN_SHRINK_FACTOR",
    "MIN_SINGULAR_RATIO",
    "MIN_TC_SAMPLES",
    "Bootstrap",
    "BootstrapDraws",
    "Identification",
    "bootstrap",
    "bootstrap_draws",
    "identification",
    "with_intervals",
]

#: The choices of ``stochmod.gmwm(..., intervals=)``.
INTERVALS = ("asymptotic", "auto", "bootstrap")
#: Bootstrap interval methods (:meth:`Bootstrap.interval`).
INTERVAL_METHODS = ("basic", "bc", "percentile")
#: The default interval method (:class:`Bootstrap`).
DEFAULT_METHOD = "basic"
#: A component whose correlation time exceeds this fraction of the record is not identified
#: by the record's WV (its WV still rises at the deepest levels).
MAX_TC_FRACTION = 0.1
#: A component whose correlation time is below this many sample intervals is nearly white
#: (it trades off against the white noise at level 1).
MIN_TC_SAMPLES = 2.0
#: An asymptotic relative standard error above this: the log-scale normal approximation of
#: the delta method is no longer accurate (the estimate's skewness is of this order).
MAX_RELATIVE_SE = 0.2
#: Smallest ratio s_min / s_max of the weighted, column-scaled Jacobian
#: (:func:`stochmod.fit.engine.weighted_svd`) for which the sandwich is trusted.
MIN_SINGULAR_RATIO = 1e-4
#: A component whose own WV sampling variance (:meth:`Process.wv_sampling_covariance`) falls
#: by less than this factor when the record is 4 times longer is realised once per record
#: (a random ramp's slope): no record length makes its asymptotic interval right.
MIN_SHRINK_FACTOR = 2.0
#: Replicates per task handed to an executor.
_CHUNK = 25
#: (tolerance, evaluation cap) of a replicate's refit: looser than the fit's own
#: (:data:`stochmod.fit.engine.REFINE_TOLERANCE`); moves the draws by ~1e-7 relative, far
#: below their spread.
_REFIT_TOLERANCE = (1e-10, 500)
#: Levels of the central interval whose half width is the bootstrap standard error.
_ONE_SIGMA = (special.ndtr(-1.0), special.ndtr(1.0))


# ------------------------------------------------------------------------- diagnostic
@attrs.frozen
class Identification:
    """Which free parameters of a fit have untrustworthy asymptotic intervals, and why.

    Attributes
    ----------
    names : tuple of str
        The free parameters (``fit.free_names``).
    reasons : tuple of str
        Per parameter, the rules it fails (``""``: asymptotic interval trusted).
    """

    names: tuple[str, ...]
    reasons: tuple[str, ...]

    @property
    def flagged(self) -> np.ndarray:
        """Boolean mask over the free parameters: True where the bootstrap is needed."""
        return np.array([bool(r) for r in self.reasons], dtype=bool)

    @property
    def trustworthy(self) -> bool:
        """Whether every asymptotic interval is trusted (no parameter flagged)."""
        return not self.flagged.any()

    def summary(self) -> str:
        """One row per parameter: its name and the rules it fails."""
        rows = [[n, r or "ok"] for n, r in zip(self.names, self.reasons)]
        return format_table(["parameter", "asymptotic interval"], rows)


def identification(fit: GMWMResult, *, max_tc_fraction: float = MAX_TC_FRACTION,
                   min_tc_samples: float = MIN_TC_SAMPLES,
                   max_relative_se: float = MAX_RELATIVE_SE,
                   min_singular_ratio: float = MIN_SINGULAR_RATIO,
                   min_shrink_factor: float = MIN_SHRINK_FACTOR) -> Identification:
    """The identification diagnostic: where a fit's asymptotic intervals are not trustworthy.

    A free parameter is flagged when one of these rules holds for it, and then so are the
    other free parameters of its component (they are estimated jointly: a GM whose beta runs
    towards the random-walk limit drags its sigma2 along):

    1. **slow component**: its component has a correlation time (the physical value ``Tc``:
       GM, AR's slowest root) ``Tc > max_tc_fraction * T``, ``T = N / freq`` the record
       length in s. The WV of such a component is still rising at the deepest levels, where
       ``M_j / 2^j`` is a few units: only ``2 beta sigma2 / freq`` is seen, beta and sigma2
       trade off along the random-walk limit;
    2. **nearly white component**: ``Tc < min_tc_samples / freq``: the component competes
       with the white noise at level 1;
    3. **imprecise**: the asymptotic relative standard error ``se / |value|`` (eqs. 22-23)
       exceeds `max_relative_se` (or is not finite): the log-scale normal approximation of
       the delta method is off by terms of the order of the relative error itself
       (skewness, bias of order ``se^2 / value``);
    4. **ill-conditioned**: the singular values of the weighted, column-scaled Jacobian
       ``L D`` (``Omega = L' L``) have ``s_min / s_max < min_singular_ratio``, or the
       sandwich fails: the linearisation of eq. 22 is not reliable; every parameter is
       flagged;
    5. **realised once per record**: the component declares its own WV sampling covariance
       (:meth:`~stochmod.core.process.Process.wv_sampling_covariance`) and its trace falls by
       less than `min_shrink_factor` when the record is 4 times longer (a random ramp: one
       slope per record, ``s^2 / omega^2 ~ chi2(1)``). The eq. 17 V of the record sees the
       ramp it holds, not the spread of the slope across records, so the asymptotic
       interval is the uncertainty given the slope, whatever the record length.

    Parameters
    ----------
    fit : GMWMResult
        The fit.
    max_tc_fraction, min_tc_samples, max_relative_se, min_singular_ratio, min_shrink_factor : float
        The rules' thresholds (dimensionless; defaults :data:`MAX_TC_FRACTION`,
        :data:`MIN_TC_SAMPLES`, :data:`MAX_RELATIVE_SE`, :data:`MIN_SINGULAR_RATIO`,
        :data:`MIN_SHRINK_FACTOR`).

    Returns
    -------
    Identification
    """
    freq = float(fit.model.freq)
    record = fit.empirical.n / freq
    owner = np.repeat(np.arange(len(fit.model.processes)),
                      [proc.n_params for proc in fit.model.processes])[fit.free_mask]
    reasons: list[list[str]] = [[] for _ in fit.free_names]
    for k, (label, proc) in enumerate(zip(fit.model.labels, fit.model.processes)):
        try:
            tc = proc.physical(freq).get("Tc")
        except (DomainError, ArithmeticError, ValueError, EstimationError):
            tc = None
        if tc is None:
            continue
        why = ""
        if not tc.value < max_tc_fraction * record:
            why = f"{label}.Tc = {tc.value:.3g} s > {max_tc_fraction:g} T (T = {record:.4g} s)"
        elif tc.value < min_tc_samples / freq:
            why = f"{label}.Tc = {tc.value:.3g} s < {min_tc_samples:g} samples"
        if why:
            for i in np.flatnonzero(owner == k):
                reasons[i].append(why)
    n_coef = np.asarray(fit.empirical.n_coef[: fit.levels], dtype=np.float64)
    for k, (label, proc) in enumerate(zip(fit.model.labels, fit.model.processes)):
        own = proc.wv_sampling_covariance(n_coef, freq, fit.empirical.wavelet)
        if own is None:
            continue
        longer = proc.wv_sampling_covariance(4 * n_coef, freq, fit.empirical.wavelet)
        if not np.trace(longer) * min_shrink_factor < np.trace(own):
            for i in np.flatnonzero(owner == k):
                reasons[i].append(f"{label}: one realisation per record (its WV's sampling "
                                  "variance does not fall with N)")
    _, _, s = weighted_svd(fit.jacobian, fit.omega)
    if not full_rank(s, len(fit.free_names), min_singular_ratio):
        ratio = s[-1] / s[0] if s.size else 0.0
        for r in reasons:
            r.append(f"weighted Jacobian s_min / s_max = {ratio:.2g} < {min_singular_ratio:g}")
    try:
        se = fit.std_errors
    except EstimationError as exc:
        for r in reasons:
            r.append(f"sandwich failed ({exc})")
    else:
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = se / np.abs(fit.model.vector()[fit.free_mask])
        for i, value in enumerate(rel):
            if not value <= max_relative_se:
                reasons[i].append(f"relative s.e. {value:.2g} > {max_relative_se:g}")
    for k, label in enumerate(fit.model.labels):  # a component's parameters together
        mine = np.flatnonzero(owner == k)
        named = [fit.free_names[i] for i in mine if reasons[i]]
        for i in mine:
            if not reasons[i] and named:
                reasons[i].append(f"with {', '.join(named)}")
    return Identification(tuple(fit.free_names), tuple("; ".join(r) for r in reasons))


# ------------------------------------------------------------------------- replicates
@attrs.frozen
class _Task:
    """What a worker needs to run replicates: plain picklable data, no signal."""

    model: Model
    n: int
    levels: int
    wavelet: str
    estimator: dict
    omega: np.ndarray
    mask: np.ndarray
    form: JTestForm | None
    weighting: str | None  # a registered weighting recomputed per replicate, or None: omega
    template: GMWMResult | None = None  # the fit without its signal: each replicate's own form


@attrs.frozen
class BootstrapDraws:
    """The bootstrap replicates of a fit.

    Attributes
    ----------
    estimates : ndarray (B, p)
        Free parameters of each replicate's fit, natural scale, canonical order (NaN rows:
        failed searches).
    physical : ndarray (B, q)
        Physical values of each replicate's fit, in the order of ``fit.physical()``.
    physical_names : tuple of str
        Their names (``"GM1.Tc"`` ...).
    statistics : ndarray (B,)
        J statistic of each replicate with its own quadratic form (NaN without a J-test).
    converged : ndarray of bool (B,)
        Whether each replicate's search met its tolerances.
    """

    estimates: np.ndarray
    physical: np.ndarray
    physical_names: tuple[str, ...]
    statistics: np.ndarray
    converged: np.ndarray

    @property
    def size(self) -> int:
        """Number of replicates B (failed ones included)."""
        return int(self.statistics.size)

    @property
    def failed(self) -> int:
        """Replicates whose search failed (no estimate)."""
        return int(np.sum(~np.all(np.isfinite(self.estimates), axis=1)))


def _physical_values(model: Model) -> list[float]:
    """The physical values of `model` in the order of ``GMWMResult.physical()`` (shorter when
    one is not defined: the replicate then has none)."""
    freq = float(model.freq)
    out: list[float] = []
    for proc in model.processes:
        try:
            out.extend(pv.value for pv in proc.physical(freq).values())
        except (DomainError, ArithmeticError, ValueError, EstimationError):
            return []
    return out


def _run(task: _Task, seeds: Sequence[np.random.SeedSequence], n_physical: int
         ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Replicates of `task`, one per seed: (estimates, physical, statistics, converged).

    BLAS runs on one thread: the replicates' matrices are of the size of the number of
    levels, and a multi-threaded OpenBLAS busy-waits beside other workers (it made the
    replicates' J-test forms cost 35 ms each instead of under 1 ms on the shared 2-core
    machine)."""
    with single_threaded_blas():
        return _run_replicates(task, seeds, n_physical)


def _run_replicates(task: _Task, seeds: Sequence[np.random.SeedSequence], n_physical: int
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    p = int(task.mask.sum())
    est = np.full((len(seeds), p), np.nan)
    phys = np.full((len(seeds), n_physical), np.nan)
    stats = np.full(len(seeds), np.nan)
    conv = np.zeros(len(seeds), dtype=bool)
    x0 = task.model.to_unconstrained()[task.mask]
    freq = float(task.model.freq)
    for b, seed in enumerate(seeds):
        x = task.model.simulate(task.n, np.random.default_rng(seed))
        emp = wvar(x, freq, wavelet=task.wavelet, levels=task.levels, **task.estimator)
        nu = np.asarray(emp.wv[: task.levels], dtype=np.float64)
        if not np.all(nu > 0):
            continue
        try:
            omega = task.omega
            if task.weighting is not None:
                made = get_weighting(task.weighting).matrix(WeightingInput(emp, task.levels))
                omega = check_weighting_matrix(made.omega, task.levels)
            problem = Problem(task.model, nu, omega, task.mask)
            res = refine(problem.residuals, problem.jacobian, x0, *_REFIT_TOLERANCE)
            if not np.isfinite(problem.safe_objective(res.x)):
                continue
            model = canonical(problem.model(res.x))
            values = model.vector()[task.mask]
            phys_b = _physical_values(model)
        except (ArithmeticError, ValueError, np.linalg.LinAlgError, EstimationError, DomainError):
            continue
        est[b] = values
        conv[b] = bool(res.success)
        if len(phys_b) == n_physical:
            phys[b] = phys_b
        if task.form is not None:
            try:
                form = _own_form(task, model, emp, omega)
            except (ArithmeticError, ValueError, np.linalg.LinAlgError, EstimationError):
                form = None
            stats[b] = (task.form if form is None else form).statistic(nu - model.wv(task.levels))
    return est, phys, stats, conv


def _own_form(task: _Task, model: Model, emp: Any, omega: np.ndarray) -> JTestForm | None:
    """The J-test's quadratic form of a replicate, built as the fit's own is built from the
    fit (:attr:`~stochmod.fit.results.GMWMResult.jtest_form`: V of the model, P of the
    estimate and Omega, the same level and boundary rules) but at the replicate's estimate,
    WV and Omega; the fit's form when V has no model-based form (a family without a PSD, or
    a V given to the fit)."""
    fit = task.template
    if fit is None or fit.null_covariance is not None:
        return task.form
    n_coef = emp.n_coef[: task.levels]
    try:
        V = model_covariance(model, n_coef, emp.wavelet,
                             variance_ratio=emp.variance_ratio[: task.levels])
    except (NotImplementedError, EstimationError):
        return task.form
    replicate = attrs.evolve(fit, model=model, empirical=emp, omega=omega, null_covariance=V)
    return replicate.jtest_form


def _seeds(rng: int | np.random.SeedSequence, n_boot: int) -> list[np.random.SeedSequence]:
    if isinstance(rng, np.random.SeedSequence):
        return rng.spawn(n_boot)
    if isinstance(rng, (int, np.integer)) and not isinstance(rng, bool):
        return np.random.SeedSequence(int(rng)).spawn(n_boot)
    raise InputError(f"rng must be an integer seed or a numpy SeedSequence, got {rng!r}")


def _recomputed(weighting: str) -> str | None:
    """`weighting` when a replicate can compute it from its WV alone, else None."""
    if weighting == "custom":
        return None
    scheme = get_weighting(weighting)
    if getattr(scheme, "needs_signal", False) or getattr(scheme, "needs_fit", False):
        return None
    return weighting


def _check_fit(fit: GMWMResult) -> None:
    if fit.binding is not None:
        raise InputError("the bootstrap needs the analytic binding; this fit simulates its "
                         "binding function (indirect inference)")
    if fit.pooled is not None:
        raise InputError("the bootstrap resimulates one record; this fit matched the pooled "
                         "WV of replicate recordings")


def _task(fit: GMWMResult) -> _Task:
    """What the replicates of `fit` need (no signal)."""
    return _Task(model=fit.model, n=int(fit.empirical.n), levels=int(fit.levels),
                 wavelet=fit.empirical.wavelet, estimator=estimator_options(fit.empirical),
                 omega=np.asarray(fit.omega, dtype=np.float64),
                 mask=np.asarray(fit.free_mask, dtype=bool), form=fit.jtest_form,
                 template=attrs.evolve(fit, signal=None, covariance=None, resampling=None),
                 weighting=_recomputed(fit.weighting))


def bootstrap_draws(fit: GMWMResult, n_boot: int = 200, *, rng: int | np.random.SeedSequence = 0,
                    executor: Executor | None = None, chunk: int = _CHUNK) -> BootstrapDraws:
    """Parametric bootstrap replicates of a fit (steps 1-3 of the module's description).

    Parameters
    ----------
    fit : GMWMResult
        An analytic GMWM fit of one record (not indirect inference, not pooled replicates).
    n_boot : int
        Number of replicates B.
    rng : int or SeedSequence
        Seed: replicate b uses ``SeedSequence(rng).spawn(n_boot)[b]``, whatever the executor.
    executor : concurrent.futures.Executor, optional
        Runs the replicates in tasks of `chunk` through ``executor.submit`` (thread or process
        pools, a dask client's ``get_executor()``); default: in this process, in order.
    chunk : int
        Replicates per task.

    Returns
    -------
    BootstrapDraws
    """
    _check_fit(fit)
    n_boot = check_positive_int(n_boot, name="n_boot", minimum=2)
    chunk = check_positive_int(chunk, name="chunk")
    seeds = _seeds(rng, n_boot)
    names = tuple(name for name, _ in _physical_list(fit))
    task = _task(fit)
    parts = [seeds[i : i + chunk] for i in range(0, n_boot, chunk)]
    if executor is None:
        done = [_run(task, part, len(names)) for part in parts]
    else:
        if not callable(getattr(executor, "submit", None)):
            raise InputError(f"executor must be a concurrent.futures.Executor, got {executor!r}")
        futures = [executor.submit(_run, task, part, len(names)) for part in parts]
        done = [f.result() for f in futures]
    est, phys, stats, conv = (np.concatenate([d[k] for d in done]) for k in range(4))
    return BootstrapDraws(estimates=est, physical=phys, physical_names=names, statistics=stats,
                          converged=conv)


def _physical_list(fit: GMWMResult) -> list[tuple[str, float]]:
    """The fit's physical values as (name, value), in the order of ``fit.physical()``."""
    freq = float(fit.model.freq)
    return [(f"{label}.{name}", float(pv.value))
            for label, proc in zip(fit.model.labels, fit.model.processes)
            for name, pv in proc.physical(freq).items()]


# ------------------------------------------------------------------------- intervals
def _interval(draws: np.ndarray, value: float, alpha: float, method: str
              ) -> tuple[float, float, float]:
    """``(std_error, low, high)`` of one quantity from its finite bootstrap draws."""
    d = np.sort(draws[np.isfinite(draws)])
    if d.size < 2 or not math.isfinite(value):
        return math.nan, math.nan, math.nan
    a = np.array([alpha / 2, 1 - alpha / 2])
    if np.all(np.quantile(d, a) == value):
        # the refits did not move it: an estimate at its boundary (a random ramp fitted to
        # no ramp, omega -> 0), where resampling at the estimate reproduces the estimate and
        # says nothing of the parameter's range; the record does not bound it here
        return math.inf, (0.0 if value > 0 else -math.inf), math.inf
    lo_q, hi_q = np.quantile(d, _ONE_SIGMA)
    se = float(0.5 * (hi_q - lo_q))
    if method == "bc":
        below = (np.searchsorted(d, value, "left") + np.searchsorted(d, value, "right")) / 2
        frac = np.clip(below / d.size, 0.5 / d.size, 1 - 0.5 / d.size)
        z0 = special.ndtri(frac)
        a = special.ndtr(2 * z0 + special.ndtri(a))
        lo, hi = np.quantile(d, a)
    elif method == "percentile":
        lo, hi = np.quantile(d, a)
    else:  # basic: reflected about the estimate, on the log scale for positive quantities
        qlo, qhi = np.quantile(d, a)
        if value > 0 and d[0] > 0:
            lo, hi = value * value / qhi, value * value / qlo
        else:
            lo, hi = 2 * value - qhi, 2 * value - qlo
    return se, float(lo), float(hi)


@attrs.define(slots=False)
class Bootstrap:
    """Bootstrap inference of a fit (:class:`stochmod.fit.results.Resampling`).

    Intervals are **basic (reverse percentile) intervals on the log scale** by default: for a
    positive quantity with estimate ``theta_hat`` and draws ``theta*_b``, with ``q_a`` the
    a-quantile of the draws,

        ``[theta_hat^2 / q_{1-alpha/2}, theta_hat^2 / q_{alpha/2}]``,

    i.e. ``log theta_hat - (log theta* - log theta_hat)`` reflected at both ends (on the
    natural scale, ``[2 theta_hat - q_{1-alpha/2}, 2 theta_hat - q_{alpha/2}]``, for a
    quantity that is not positive, e.g. an AR coefficient). It takes
    ``log theta* - log theta_hat`` as the distribution of ``log theta_hat - log theta``. Why
    this one:

    - a deep-level component's estimate (a slow GM's beta, an RW or ramp amplitude fitted
      with the data-dependent diagonal weighting) is biased, and the replicates reproduce
      the bias: reflecting the draws about the estimate removes it, where the percentile
      interval doubles it and Efron's bias-corrected (BC) interval only shifts the quantile
      levels by the median bias: of the three, only the basic interval covers such
      parameters near the nominal level in the Monte Carlo study of
      docs/gmwm_monte_carlo.md, which tabulates them side by side;
    - on the log scale it stays positive, and it is equivariant under the power maps to the
      physical values (Tc = 1/beta, sigma = sqrt(sigma2), N = sqrt(sigma2 / freq) ...), so
      a physical value's interval is the map of the canonical one's;
    - a studentised interval needs each replicate's standard error, i.e. the eq. 17
      covariance of every resimulated record: more than the refit itself, and unstable
      exactly where the asymptotic standard error is (near the random-walk limit);
    - BCa's acceleration needs a jackknife, which a dependent series does not have.

    ``"bc"`` and ``"percentile"`` are available for comparison. The bootstrap standard
    error is the half width of the central 68.27 % percentile interval (the standard
    deviation of the draws is driven by a few replicates that run off to the random-walk or
    white-noise limits).

    The J-test's p-value is ``(1 + #{J*_b >= J}) / (1 + B')`` (B' replicates with a
    statistic), ``J`` the fit's statistic and ``J*_b`` the replicates', each with its own
    quadratic form (:class:`~stochmod.fit.results.JTestForm`: V of the fitted model, the
    projection of its estimate), built as the fit's is: the bootstrap replaces the
    chi-square reference, which the finite-sample statistic does not follow. Applying the
    fit's form to every replicate instead makes the test conservative (in the Monte Carlo
    study its p-values average 0.58 under the true model, size 0.01-0.04). A replicate
    whose own form does not exist (its estimate is rank-deficient) uses the fit's.

    Attributes
    ----------
    draws : BootstrapDraws
        The replicates.
    estimate : ndarray (p,)
        The fit's free parameters (natural scale).
    physical_values : ndarray (q,)
        The fit's physical values.
    observed : JTest or None
        The fit's asymptotic J-test.
    use : ndarray of bool (p,)
        Free parameters whose interval the bootstrap replaces.
    use_physical : ndarray of bool (q,)
        Physical values whose interval the bootstrap replaces.
    alpha : float
        Significance level (intervals of level 1 - alpha).
    method : str
        ``"basic"`` (default), ``"bc"`` or ``"percentile"``.
    diagnostic : Identification or None
        The diagnostic that chose `use` (None when every parameter uses the bootstrap).
    """

    draws: BootstrapDraws
    estimate: np.ndarray
    physical_values: np.ndarray
    observed: JTest | None
    use: np.ndarray
    use_physical: np.ndarray
    alpha: float = 0.05
    method: str = DEFAULT_METHOD
    diagnostic: Identification | None = None

    def interval(self, index: int, *, method: str | None = None, alpha: float | None = None
                 ) -> tuple[float, float, float]:
        """``(std_error, low, high)`` of free parameter `index` from the draws, whether or not
        it is used (natural scale, the parameter's unit)."""
        return _interval(self.draws.estimates[:, index], float(self.estimate[index]),
                         self.alpha if alpha is None else alpha, method or self.method)

    def physical_interval(self, index: int, *, method: str | None = None,
                          alpha: float | None = None) -> tuple[float, float, float]:
        """``(std_error, low, high)`` of physical value `index` from the draws."""
        return _interval(self.draws.physical[:, index], float(self.physical_values[index]),
                         self.alpha if alpha is None else alpha, method or self.method)

    def parameter(self, index: int) -> tuple[float, float, float] | None:
        """The interval of free parameter `index` where the bootstrap is used, else None."""
        return self.interval(index) if self.use[index] else None

    def physical(self, name: str) -> tuple[float, float, float] | None:
        """The interval of physical value `name` where the bootstrap is used, else None."""
        names = self.draws.physical_names
        if name not in names:
            return None
        k = names.index(name)
        return self.physical_interval(k) if self.use_physical[k] else None

    def describe(self) -> str:
        """Which intervals come from the bootstrap, its method and size."""
        names = [n for n, u in zip(self.draws.physical_names, self.use_physical) if u]
        free = [str(n) for n, u in zip(self.diagnostic.names if self.diagnostic else (),
                                       self.use) if u]
        if self.diagnostic is None:
            which = "intervals of every parameter"
        elif free or names:
            which = (f"intervals of {', '.join(free + names)} (flagged by the identification "
                     "diagnostic)")
        else:
            which = "no interval (the identification diagnostic flags none)"
        return (f"bootstrap ({self.method}, B = {self.draws.size}, {self.draws.failed} failed "
                f"refits): {which}; J-test p-value from the bootstrap")

    def jtest(self) -> JTest | None:
        """The J-test with its bootstrap p-value (None without an asymptotic statistic)."""
        if self.observed is None:
            return None
        stats = self.draws.statistics[np.isfinite(self.draws.statistics)]
        if stats.size == 0:
            return None
        p = (1.0 + np.sum(stats >= self.observed.statistic)) / (1.0 + stats.size)
        return JTest(self.observed.statistic, self.observed.df, float(p))


def bootstrap(fit: GMWMResult, n_boot: int = 200, *, rng: int | np.random.SeedSequence = 0,
              executor: Executor | None = None, apply: str = "all",
              method: str = DEFAULT_METHOD,
              diagnostic: Identification | None = None,
              draws: BootstrapDraws | None = None) -> GMWMResult:
    """The fit with bootstrap inference attached (``fit.resampling``).

    ``parameters()``, ``physical()`` and ``jtest`` of the returned fit use the bootstrap
    (:class:`Bootstrap`) for the parameters `apply` selects; the estimates are the fit's.

    Parameters
    ----------
    fit : GMWMResult
        An analytic fit of one record.
    n_boot : int
        Replicates B (200 gives interval ends to a few percent of the interval's width).
    rng : int or SeedSequence
        Seed of the replicates (:func:`bootstrap_draws`).
    executor : concurrent.futures.Executor, optional
        Where the replicates run (default: this process).
    apply : {"all", "flagged"}
        ``"all"``: every parameter and physical value; ``"flagged"``: those the diagnostic
        flags (a physical value when any free parameter of its component is flagged).
    method : {"basic", "bc", "percentile"}
        Interval method (:class:`Bootstrap`; default basic on the log scale).
    diagnostic : Identification, optional
        The diagnostic for ``apply="flagged"`` (default: :func:`identification` of `fit`).
    draws : BootstrapDraws, optional
        Replicates already drawn for `fit` (:func:`bootstrap_draws`); `n_boot`, `rng` and
        `executor` are then not used.

    Returns
    -------
    GMWMResult
        A copy of `fit` carrying its data covariances and the bootstrap.
    """
    if apply not in ("all", "flagged"):
        raise InputError(f"apply must be 'all' or 'flagged', got {apply!r}")
    if method not in INTERVAL_METHODS:
        raise InputError(f"method must be one of {INTERVAL_METHODS}, got {method!r}")
    if draws is None:
        draws = bootstrap_draws(fit, n_boot, rng=rng, executor=executor)
    elif draws.estimates.shape[1] != len(fit.free_names):
        raise InputError(f"draws of {draws.estimates.shape[1]} parameters do not belong to a "
                         f"fit of {len(fit.free_names)} free parameters")
    p = len(fit.free_names)
    if apply == "all":
        use, diag = np.ones(p, dtype=bool), None
    else:
        diag = identification(fit) if diagnostic is None else diagnostic
        use = diag.flagged
    owner = np.repeat(fit.model.labels, [proc.n_params for proc in fit.model.processes])
    chosen = set(owner[fit.free_mask][use])
    use_physical = np.array([name.split(".")[0] in chosen for name in draws.physical_names],
                            dtype=bool)
    physical_values = np.array([v for _, v in _physical_list(fit)], dtype=np.float64)
    boot = Bootstrap(draws=draws, estimate=fit.model.vector()[fit.free_mask],
                     physical_values=physical_values, observed=fit.asymptotic_jtest, use=use,
                     use_physical=use_physical, alpha=fit.alpha, method=method, diagnostic=diag)
    return attrs.evolve(fit, resampling=boot, **_computed_covariances(fit))


def _computed_covariances(fit: GMWMResult) -> dict[str, Any]:
    """The covariances `fit` already computed, so that its copy does not compute them again."""
    out: dict[str, Any] = {}
    known = fit.__dict__
    if "wv_covariance" in known and fit.binding is None:
        out["covariance"] = known["wv_covariance"]
    if fit.null_covariance is None and "null_wv_covariance" in known and fit.binding is None:
        out["null_covariance"] = known["null_wv_covariance"]
    return out


def with_intervals(fit: GMWMResult, intervals: str, n_boot: int = 200, *,
                   rng: int | np.random.SeedSequence = 0,
                   executor: Executor | None = None,
                   draws: BootstrapDraws | None = None) -> GMWMResult:
    """The fit with the inference ``stochmod.gmwm(..., intervals=)`` asks for.

    ``"asymptotic"``: `fit` itself (eqs. 22-23, 27). ``"bootstrap"``: :func:`bootstrap` of
    every parameter and the J-test. ``"auto"``: the bootstrap for the parameters
    :func:`identification` flags (and their components' physical values), the asymptotic
    intervals for the others, and the bootstrap p-value of the J-test always: no diagnostic
    of the fit tells where the chi-square reference of eq. 27 holds (the Monte Carlo study of
    docs/gmwm_monte_carlo.md finds its size above the nominal level on models whose every
    parameter the diagnostic trusts), and the replicates the J-test needs are those of the
    intervals. `draws` (:func:`bootstrap_draws` of `fit`) replaces `n_boot`, `rng`
    and `executor`.
    """
    if intervals not in INTERVALS:
        raise InputError(f"intervals must be one of {INTERVALS}, got {intervals!r}")
    if intervals == "asymptotic":
        return fit
    if intervals == "bootstrap":
        return bootstrap(fit, n_boot, rng=rng, executor=executor, draws=draws)
    return bootstrap(fit, n_boot, rng=rng, executor=executor, apply="flagged",
                     diagnostic=identification(fit), draws=draws)
