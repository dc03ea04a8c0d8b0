"""GMWM weightings as plugins: the ``stochmod_weightings`` hook and the first-party weightings.

A weighting builds the matrix ``Omega`` of eq. 20 for one empirical wavelet variance. It is an
object with

- ``name`` (str): the name ``stochmod.gmwm(weighting=...)``, ``stochmod.select`` and the CLI's
  ``--weighting`` resolve through the registry;
- ``description`` (str): one line for listings;
- ``needs_signal`` (bool): it needs the signal, not only its WV (``"optimal"``);
- ``needs_fit`` (bool): it depends on a first fit of the model (``"bootstrap"``): the caller
  passes that pilot fit, and a selection, whose candidates share one ``Omega``, refuses it;
- ``matrix(data: WeightingInput) -> WeightingMatrix``: ``Omega`` (J x J, symmetric positive
  definite, unit^-4) and, when it inverts one, the covariance ``V`` of the empirical WV
  (unit^4), which the result then reuses for inference;
- ``inference`` (str, optional, default ``"data"``): the covariance of the empirical WV that
  the fit's intervals use: ``"data"``, the one the matrix gave or eq. 17 on the signal;
  ``"model"``, the fitted model's at the estimate
  (:meth:`~stochmod.fit.results.GMWMResult.model_based_covariance`), as the ``"model"``
  weighting declares.

A plugin returns such objects from ``stochmod_weightings()``; the first-party ones below are
registered by this module exactly that way (it is in the registry's built-in list, as the WVIC
criterion is). :func:`stochmod.testing.check_weighting` checks a weighting against the contract.
"""

from __future__ import annotations

import abc
from typing import TYPE_CHECKING, Any, ClassVar

import attrs
import numpy as np

from stochmod.plugin import registry
from stochmod.core.errors import InputError
from stochmod.fit.weighting import (
    bootstrap_covariance,
    data_covariance,
    level_variances,
    model_covariance,
    weighting_from_covariance,
)
from stochmod.plugin.hookspecs import hookimpl
from stochmod.empirical.wavelet_variance import WaveletVariance, estimator_options

if TYPE_CHECKING:
    from stochmod.fit.results import GMWMResult

__all__ = [
    "WeightingInput",
    "WeightingMatrix",
    "Weighting",
    "InverseCovarianceWeighting",
    "DiagonalWeighting",
    "IdentityWeighting",
    "OptimalWeighting",
    "BootstrapWeighting",
    "ModelWeighting",
    "DIAGONAL",
    "IDENTITY",
    "OPTIMAL",
    "BOOTSTRAP",
    "MODEL",
    "get_weighting",
    "weighting_names",
    "stochmod_weightings",
]


@attrs.frozen
class WeightingInput:
    """What a weighting may use to build ``Omega``.

    Attributes
    ----------
    empirical : WaveletVariance
        The empirical wavelet variance (levels 1..J at least).
    levels : int
        Number of levels J of the fit.
    signal : ndarray or None
        The signal (unit u), None when only its WV was given.
    pilot : GMWMResult or None
        A first fit of the model with the diagonal weighting, given to a weighting with
        ``needs_fit``.
    seed : int
        Seed of any random choice (results reproduce).
    reps : int
        Monte Carlo replications a simulation-based weighting may use.
    covariance : ndarray or None
        The covariance V of the empirical WV (J x J, unit^4) when it is known without the
        signal, e.g. propagated from replicates (:mod:`stochmod.fit.replicates`); a weighting that
        inverts V uses it instead of estimating V from the signal.
    """

    empirical: WaveletVariance
    levels: int
    signal: np.ndarray | None = attrs.field(default=None, repr=False)
    pilot: GMWMResult | None = attrs.field(default=None, repr=False)
    seed: int = 0
    reps: int = 100
    covariance: np.ndarray | None = attrs.field(default=None, repr=False)

    @property
    def wv(self) -> np.ndarray:
        """The empirical WV at levels 1..J, unit^2."""
        return np.asarray(self.empirical.wv[: self.levels], float)

    def require(self, field: str, weighting: str) -> Any:
        """``signal`` or ``pilot``, or an InputError saying that `weighting` needs it."""
        value = getattr(self, field)
        if value is None:
            need = {"signal": "the signal, not only its wavelet variance",
                    "pilot": "a first fit of the model (pilot)"}[field]
            raise InputError(f"weighting={weighting!r} needs {need}")
        return value


@attrs.frozen
class WeightingMatrix:
    """A weighting's output: ``omega`` (J x J, unit^-4) and the WV covariance ``covariance``
    (J x J, unit^4) it inverts, or None."""

    omega: np.ndarray = attrs.field(repr=False)
    covariance: np.ndarray | None = attrs.field(default=None, repr=False)


class Weighting(abc.ABC):
    """Base class of a weighting (optional: the registry asks only for the attributes).

    A subclass sets ``name`` and ``description``, sets ``needs_signal`` or ``needs_fit`` when
    true (both default to False), ``inference`` to ``"model"`` when its fits' intervals take
    the fitted model's covariance of the WV (default ``"data"``), and implements
    :meth:`matrix`.
    """

    name: ClassVar[str]
    description: ClassVar[str]
    needs_signal: ClassVar[bool] = False
    needs_fit: ClassVar[bool] = False
    inference: ClassVar[str] = "data"

    @abc.abstractmethod
    def matrix(self, data: WeightingInput) -> WeightingMatrix:
        """``Omega`` (J x J) for `data`, and the covariance V it inverts, if any."""


@attrs.frozen
class DiagonalWeighting(Weighting):
    """``Omega = diag(1 / var(v_j))`` with the chi-square variances ``2 v_j^2 / eta_j``
    (:func:`~stochmod.fit.weighting.chi2_variance`, times the robust estimator's variance
    ratios for a robust WV: :func:`~stochmod.fit.weighting.level_variances`): fast, from the WV
    alone (the default)."""

    name: ClassVar[str] = "diagonal"
    description: ClassVar[str] = "inverse chi-square variances of the empirical WV (default)"

    def matrix(self, data: WeightingInput) -> WeightingMatrix:
        """The diagonal matrix."""
        return WeightingMatrix(np.diag(1.0 / level_variances(data.empirical, data.levels)))


@attrs.frozen
class IdentityWeighting(Weighting):
    """``Omega = I`` (ordinary least squares on the WV)."""

    name: ClassVar[str] = "identity"
    description: ClassVar[str] = "identity matrix (ordinary least squares)"

    def matrix(self, data: WeightingInput) -> WeightingMatrix:
        """The identity."""
        return WeightingMatrix(np.eye(data.levels))


class InverseCovarianceWeighting(Weighting):
    """Base class of the weightings ``Omega = V^{-1}``: a subclass implements
    :meth:`covariance`; the inverse is computed stably
    (:func:`~stochmod.fit.weighting.weighting_from_covariance`) and V is returned with it, so
    that inference reuses it."""

    @abc.abstractmethod
    def covariance(self, data: WeightingInput) -> np.ndarray:
        """The covariance V of the empirical WV at levels 1..J (J x J, unit^4)."""

    def matrix(self, data: WeightingInput) -> WeightingMatrix:
        """``V^{-1}`` and V."""
        V = self.covariance(data)
        return WeightingMatrix(weighting_from_covariance(V), V)


@attrs.frozen
class OptimalWeighting(InverseCovarianceWeighting):
    """``Omega = V^{-1}`` with V the asymptotic covariance of eq. 17 on the signal, deep
    levels decoupled (:func:`~stochmod.fit.weighting.data_covariance`)."""

    name: ClassVar[str] = "optimal"
    description: ClassVar[str] = "inverse of the eq. 17 covariance of the empirical WV (needs the signal)"
    needs_signal: ClassVar[bool] = True

    def covariance(self, data: WeightingInput) -> np.ndarray:
        """The known covariance of the WV when given (replicates), else eq. 17 on the signal."""
        if data.covariance is not None:
            return np.asarray(data.covariance, float)[: data.levels, : data.levels]
        return data_covariance(data.require("signal", self.name), data.empirical, data.levels)


@attrs.frozen
class BootstrapWeighting(InverseCovarianceWeighting):
    """``Omega = V^{-1}`` with V a parametric bootstrap (eq. 35) at a first diagonal fit: `reps`
    seeded simulations of the data's length."""

    name: ClassVar[str] = "bootstrap"
    description: ClassVar[str] = "inverse of a parametric-bootstrap covariance at a first diagonal fit"
    needs_fit: ClassVar[bool] = True

    def covariance(self, data: WeightingInput) -> np.ndarray:
        """The bootstrap covariance at the pilot fit."""
        pilot, emp = data.require("pilot", self.name), data.empirical
        return bootstrap_covariance(pilot.model, emp.n, data.levels, reps=data.reps,
                                    rng=data.seed, wavelet=emp.wavelet, **estimator_options(emp))


@attrs.frozen
class ModelWeighting(Weighting):
    """``Omega = diag(1 / V_jj)`` with V the model-based covariance of the empirical WV at a
    first diagonal fit (:func:`~stochmod.fit.weighting.model_covariance`: the Gaussian form of
    eq. 17 from the pilot model's PSD, times the robust estimator's variance ratios).

    The diagonal weighting divides each level by its own squared empirical WV, so at deep
    levels, with few equivalent degrees of freedom, a level that came out low by chance
    weighs more: the estimates of a random walk or a slow Gauss-Markov term are biased low and
    spread more than eqs. 22-23 say. Weights from the pilot model do not depend on the level's
    own error; the estimate then has the large-sample spread of the sandwich with
    ``Omega = diag(1 / V_jj)`` (:func:`stochmod.fit.plan.interval_half_widths`). Its intervals
    take V from the fitted model too, at the estimate (``inference = "model"``): the eq. 17
    estimate on the signal rests on a few coefficients at those levels and, in the sandwich,
    makes the intervals of a random walk too short.
    """

    name: ClassVar[str] = "model"
    description: ClassVar[str] = ("inverse model-based variances of the empirical WV at a first "
                                  "diagonal fit; intervals from the fitted model's covariance")
    needs_fit: ClassVar[bool] = True
    inference: ClassVar[str] = "model"

    def matrix(self, data: WeightingInput) -> WeightingMatrix:
        """The diagonal matrix at the pilot fit."""
        pilot, emp, J = data.require("pilot", self.name), data.empirical, data.levels
        V = model_covariance(pilot.model, emp.n_coef[:J], emp.wavelet,
                             variance_ratio=emp.variance_ratio[:J])
        return WeightingMatrix(np.diag(1.0 / np.diag(V)))


#: The first-party weightings (registered by :func:`stochmod_weightings`).
DIAGONAL = DiagonalWeighting()
IDENTITY = IdentityWeighting()
OPTIMAL = OptimalWeighting()
BOOTSTRAP = BootstrapWeighting()
MODEL = ModelWeighting()


@hookimpl
def stochmod_weightings() -> list[Any]:
    """Register the first-party weightings."""
    return [DIAGONAL, OPTIMAL, BOOTSTRAP, MODEL, IDENTITY]


def weighting_names(*, shared: bool = False) -> list[str]:
    """Names of the registered weightings, sorted; ``shared=True``: only those a selection's
    candidates can share (no ``needs_fit``)."""
    return [n for n, w in registry.weightings().items() if not (shared and w.needs_fit)]


def get_weighting(name: str) -> Any:
    """The registered weighting called `name` (``"diagonal"`` or a plugin's).

    Raises
    ------
    InputError
        Unknown name; the message lists the registered ones.
    """
    table = registry.weightings()
    try:
        return table[name]
    except (KeyError, TypeError):
        raise InputError(f"unknown weighting {name!r}; registered weightings: "
                         f"{', '.join(table) or 'none'} (or pass a (J, J) matrix to gmwm)") from None
