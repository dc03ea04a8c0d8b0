"""The Generalized Method of Wavelet Moments (GMWM) estimator (Stebler et al., 2014, eqs. 19-27).

``gmwm(x, "2*GM+WN", freq)`` matches the model's theoretical Haar wavelet variance to the
empirical one by weighted least squares (eq. 20) over the families' unconstrained
transforms, with analytic Jacobians from the composer. Starting values come from the
families' guesses refined on the flattened criterion of eq. 34, plus a deterministic,
seeded multi-start (random draws screened by the objective, best ones refined), so that
the global optimum is found reliably. The search, the canonical order and the sandwich
covariance are the engine's (:mod:`stochmod.fit.engine`), the result is a
:class:`~stochmod.fit.results.GMWMResult`, the weighting matrix comes from a registered
weighting (:mod:`stochmod.fit.weighting_plugins`).
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import Executor

import attrs
import numpy as np
from numpy.typing import ArrayLike

from stochmod.core.checks import as_signal, check_freq, check_positive_int
from stochmod.core.errors import InputError, SpecError
from stochmod.core.model import Model
from stochmod.core.process import Process
from stochmod.empirical.wavelet_variance import WaveletVariance, wvar
from stochmod.empirical.wv_classical import classical_wvar
from stochmod.fit.bootstrap import INTERVALS, with_intervals
from stochmod.fit.engine import Problem, resolve_model, search
from stochmod.fit.indirect import IndirectGMWMResult, plan_binding
from stochmod.fit.replicates import is_replicates, pooled_wv
from stochmod.fit.results import GMWMResult, JTest, ParameterEstimate
from stochmod.fit.weighting import check_weighting_matrix
from stochmod.fit.weighting_plugins import WeightingInput, get_weighting

__all__ = ["GMWMResult", "JTest", "ParameterEstimate", "gmwm"]


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
    intervals: str = "asymptotic",
    n_boot: int = 200,
    executor: Executor | None = None,
    pilot: GMWMResult | None = None,
) -> GMWMResult:
    """Fit a composite model by the GMWM (eq. 20).

    Parameters
    ----------
    data : array_like, WaveletVariance or list of array_like
        The static error signal (unit u, mean removed or not: the Haar WV ignores the mean),
        or a precomputed empirical wavelet variance, or a list of replicate signals of one
        sensor model (:mod:`stochmod.fit.replicates`: their pooled WV is matched, the weighting
        and the inference use its covariance, and ``result.pooled`` holds the pooling and the
        equality test).
    model : Model, Process, str or dict
        The composite model (``"2*GM+WN"``, ``GM() + WN()`` ...); parameters with values are
        held fixed, free ones are estimated.
    freq : float
        Sampling frequency, Hz (taken from `data` when it is a WaveletVariance).
    weighting : str or array_like (J, J)
        A registered weighting (:mod:`stochmod.fit.weighting_plugins`; a plugin may add others).
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
        Match the robust wavelet variance (:mod:`stochmod.empirical.robust_wv`, Tukey biweight
        M-estimate of each level's coefficient variance) instead of the classical one: a few
        outliers in the record no longer drive the fit. Its variances (inflated by
        ``kappa_j``) enter the diagonal weighting, its covariance (eq. 17 on clipped
        coefficients, scaled by ``kappa``) the optimal weighting and the inference, the
        robust WV of the simulations the bootstrap. Implied when `data` is a robust
        WaveletVariance.
    efficiency : float
        Gaussian efficiency in (0, 1] of the robust estimator (default 0.6; robust only).
    intervals : {"asymptotic", "auto", "bootstrap"}
        Inference of ``parameters()``, ``physical()`` and ``jtest``. ``"asymptotic"``
        (default): the sandwich of eqs. 22-23 with log-scale delta-method intervals and the
        chi-square J-test of eq. 27. ``"bootstrap"``: a parametric bootstrap of `n_boot`
        replicates for every parameter and the J-test (:mod:`stochmod.fit.bootstrap`).
        ``"auto"``: the bootstrap for the parameters the identification diagnostic
        (:func:`stochmod.fit.bootstrap.identification`: a correlation time above T/10 or
        below 2 samples, an asymptotic relative standard error above 0.2, an ill-conditioned
        weighted Jacobian, a component realised once per record such as a random ramp; a
        component's parameters together) flags, the asymptotic intervals for the others, and
        the bootstrap p-value of the J-test always. The estimates are the same in all three.
        Analytic fits of one record only.
    n_boot : int
        Bootstrap replicates (intervals "auto" and "bootstrap"), seeded by `rng`.
    executor : concurrent.futures.Executor, optional
        Runs the bootstrap replicates (default: in this process); the results do not depend
        on it.
    pilot : GMWMResult, optional
        The first fit of a weighting with ``needs_fit`` (``"model"``, ``"bootstrap"``): a fit
        of the same model, whose estimate fixes Omega and starts the final search. Default:
        the diagonal fit of the model to `data` with the same options.

    Returns
    -------
    GMWMResult
        (an :class:`~stochmod.fit.indirect.IndirectGMWMResult` when a component is simulated)
    """
    if intervals not in INTERVALS:
        raise InputError(f"intervals must be one of {INTERVALS}, got {intervals!r}")
    custom, scheme = None, None
    if not isinstance(weighting, str):
        custom, weighting = np.array(weighting, dtype=np.float64), "custom"
    else:
        scheme = get_weighting(weighting)
    signal, pooled = None, None
    if is_replicates(data):  # replicates: one model from their pooled wavelet variance
        if freq is None:
            raise InputError("freq (Hz) is required when data is a list of signals")
        if robust:
            raise InputError("robust=True is not available for replicates (a list of signals): "
                             "the pooled wavelet variance is the classical one")
        pooled = pooled_wv(data, check_freq(freq), levels, wavelet)
        data = pooled.wv
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
        signal = as_signal(data, name="data", min_length=8, finite=False)  # checked by the WV
        if robust:
            emp = wvar(signal, freq, wavelet=wavelet, levels=levels, robust=True,
                       efficiency=efficiency)
        else:
            emp = classical_wvar(signal, freq, wavelet=wavelet, levels=levels, name="data")
    J = emp.wv.size if levels is None else levels
    nu_hat = np.asarray(emp.wv[:J], float)
    if np.any(nu_hat <= 0):
        raise InputError("the empirical wavelet variance has non-positive levels (constant stretches?)")
    base = resolve_model(model, freq)
    mask = base.free_mask()
    if not mask.any():
        raise SpecError(f"model {base.name} has no free parameter to estimate")
    if mask.sum() > J:
        raise InputError(f"model {base.name} has {int(mask.sum())} free parameters but only {J} levels")
    # indirect inference (stochmod.fit.indirect): None = the analytic binding
    plan = plan_binding(base, binding, R=R, max_sim=max_sim, n=emp.n, levels=J, seed=rng,
                        wavelet=emp.wavelet)
    if plan is None and emp.wavelet != "haar":
        raise InputError(
            f"the analytic GMWM matches Haar wavelet variances; the data's WV uses {emp.wavelet!r}: "
            "use wavelet='haar' or binding='simulated' (indirect inference with the same wavelet)"
        )

    if pilot is not None:
        _check_pilot(pilot, base, scheme)
    covariance = None
    if custom is not None:
        omega = check_weighting_matrix(custom, J)
        omega = 0.5 * (omega + omega.T)
    else:
        known = None if pooled is None else pooled.covariance
        if scheme.needs_signal and signal is None and known is None:
            raise InputError(f"weighting={weighting!r} needs the signal, not only its wavelet variance")
        if scheme.needs_fit and pilot is None:  # its model also starts the final search
            pilot = gmwm(emp, base, freq, weighting="diagonal", levels=J, n_starts=n_starts,
                         n_random=n_random, starts=starts, rng=rng, binding=binding, R=R,
                         max_sim=max_sim)
        if pilot is not None:
            starts = (*starts, pilot.model)
        made = scheme.matrix(WeightingInput(emp, J, signal, pilot, seed=rng, reps=bootstrap_reps,
                                            covariance=known))
        omega = check_weighting_matrix(made.omega, J, source=f"weighting {weighting!r}'s matrix")
        covariance = made.covariance

    if pooled is not None and covariance is None:
        covariance = pooled.covariance[:J, :J]
    found = search(base, nu_hat, omega, mask, n_starts, n_random, starts, rng,
                   problem_factory=Problem if plan is None else plan.problem)
    if plan is None:
        result = GMWMResult.from_search(
            found, empirical=emp, omega=omega, weighting=weighting, levels=J, mask=mask,
            alpha=alpha, signal=signal, covariance=covariance, rng_seed=rng)
        if getattr(scheme, "inference", "data") == "model":
            result = result.with_model_covariance()
    else:
        result = IndirectGMWMResult.from_search(
            found, empirical=emp, omega=omega, weighting=weighting, levels=J, mask=mask,
            alpha=alpha, signal=signal, covariance=covariance, rng_seed=rng, binding=plan.finished())
    if pooled is not None:
        result = attrs.evolve(result, pooled=pooled)
    return with_intervals(result, intervals, n_boot, rng=rng, executor=executor)


def _check_pilot(pilot: GMWMResult, base: Model, scheme: object) -> None:
    """A SpecError or InputError unless `pilot` is a fit of `base` for a weighting with
    ``needs_fit``."""
    if scheme is None or not scheme.needs_fit:
        name = "a custom matrix" if scheme is None else f"weighting {scheme.name!r}"
        raise InputError(f"pilot is the first fit of a weighting with needs_fit; {name} "
                         "does not take one")
    if not isinstance(pilot, GMWMResult):
        raise InputError(f"pilot must be a GMWMResult, got {type(pilot).__name__}")
    if pilot.model.name != base.name or pilot.model.n_params != base.n_params:
        raise SpecError(f"pilot fit of {pilot.model.name} does not match model {base.name}")
