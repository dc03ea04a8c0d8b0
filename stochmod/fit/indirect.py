"""Indirect inference for the GMWM (Stebler et al. 2014, Section III-C, eq. 29).

When a family has no theoretical wavelet variance (it overrides neither ``wv``, ``psd`` nor
``autocovariance``), or when the user asks for it, the binding function of eq. 20 is
replaced by ``phi*(theta)``: the empirical Haar WV of a series ``{y*_k(theta)}`` of length
``R N`` simulated from the model at theta (eq. 29). :func:`stochmod.gmwm` does this with
``binding="simulated"`` (every component simulated) or, by default, ``binding="auto"``
(only the components without a theoretical WV are simulated; by eq. 28 the analytic WVs
of the others are added, which removes their Monte Carlo error).

Design choices:

- Common random numbers: every evaluation seeds fresh generators from the same seed
  (``numpy.random.default_rng([rng, 29])``, spawned per simulated component, in the
  canonical component order), so ``phi*`` is a smooth, deterministic function of theta and
  the ordinary least-squares machinery of :mod:`stochmod.fit.engine` (weightings, flattened
  eq. 34 starts, multi-start) applies unchanged: :class:`SimulatedProblem` replaces the
  engine's binding function, and the result carries the :class:`SimulatedBinding` as its
  :class:`~stochmod.fit.results.Binding`.
- Jacobian by finite differences on the unconstrained scale (forward during the search,
  central at the estimate); analytic columns for analytic components.
- Bounded cost: the simulated length is ``min(R N, max(max_sim, N))`` samples
  (``max_sim = 2^20`` by default): never shorter than the data, never longer than the cap
  unless the data are.
- Inference: the estimate's error is ``B (phi_hat - phi(theta)) - B (phi*(theta) - phi(theta))``,
  two independent terms, so the covariance of eqs. 22-23 uses ``V + V_sim`` where ``V_sim``
  is the eq. 17 covariance of the simulated series' WV (``~ V N / n_sim`` when every component
  is simulated: the classical ``1 + 1/R`` factor); the J-test uses the same sum.
"""

from __future__ import annotations

import functools
import warnings
from typing import Any

import attrs
import numpy as np

from stochmod.core.checks import check_positive_int
from stochmod.core.errors import InputError, SpecError
from stochmod.fit.engine import Problem, canonical, sandwich
from stochmod.fit.results import GMWMResult
from stochmod.fit.weighting import data_covariance
from stochmod.core.model import Model
from stochmod.core.process import has_theoretical_wv
from stochmod.empirical.wavelet_variance import wvar

__all__ = ["BINDINGS", "MAX_SIMULATED", "SimulatedBinding", "SimulatedProblem",
           "IndirectGMWMResult", "plan_binding"]

#: Names accepted by ``stochmod.gmwm(binding=...)``.
BINDINGS = ("auto", "analytic", "simulated")
#: Default cap on the simulated length (samples).
MAX_SIMULATED = 2**20
#: Second entropy word of the common-random-number stream (eq. 29).
_STREAM = 29
#: Finite-difference steps on the unconstrained scale (relative steps for positive parameters).
_STEP_FORWARD = 1e-6
_STEP_CENTRAL = 1e-4


def _slices(model: Model) -> list[slice]:
    out, start = [], 0
    for p in model.processes:
        out.append(slice(start, start + p.n_params))
        start += p.n_params
    return out


@attrs.frozen
class SimulatedBinding:
    """The binding function ``phi*(theta)`` of indirect inference (eq. 29).

    ``phi*(theta) = sum of the analytic WVs of the components not simulated + the empirical
    WV (levels 1..`levels`, `wavelet`) of the sum of the simulated components, each drawn
    from its own child of a generator seeded afresh from (`seed`, 29) at every call``.

    Attributes
    ----------
    simulated : tuple of bool
        Per component of the model: simulated (True) or analytic.
    levels : int
        Number of levels J.
    n_sim : int
        Simulated length, samples (``min(R n, max(max_sim, n))``).
    n : int
        Length N of the data, samples.
    seed : int
        Seed of the common random numbers.
    wavelet : str
        Wavelet of the empirical WV.
    """

    simulated: tuple[bool, ...]
    levels: int
    n_sim: int
    n: int
    seed: int
    wavelet: str = "haar"
    _paths: dict = attrs.field(factory=dict, eq=False, repr=False)

    @property
    def R_effective(self) -> float:  # noqa: N802
        """``n_sim / N``: the simulated length in multiples of the data's."""
        return self.n_sim / self.n

    def _path(self, slot: int, proc: Any, freq: float, child: np.random.Generator) -> np.ndarray:
        """Simulated path of one component (cached by slot and parameter values: finite
        differences move one component at a time)."""
        key = (slot, proc.family, proc.vector().tobytes())
        path = self._paths.get(key)
        if path is None:
            path = proc.simulate(self.n_sim, freq, child)
            if len(self._paths) >= 2 * max(1, sum(self.simulated)) + 2:
                self._paths.pop(next(iter(self._paths)))
            self._paths[key] = path
        return path

    def series(self, model: Model) -> np.ndarray | None:
        """The simulated series (sum of the simulated components, `n_sim` samples), or None."""
        procs = [p for p, s in zip(model.processes, self.simulated) if s]
        if not procs:
            return None
        sub = canonical(Model(tuple(procs), model.freq))  # label-invariant stream assignment
        children = np.random.default_rng([self.seed, _STREAM]).spawn(len(procs))
        paths = [self._path(i, p, sub.freq, g) for i, (p, g) in enumerate(zip(sub.processes, children))]
        return np.sum(paths, axis=0)

    def __call__(self, model: Model) -> np.ndarray:
        """``phi*(theta)`` at the model's values, unit^2, shape (levels,)."""
        out = np.zeros(self.levels)
        for p, s in zip(model.processes, self.simulated):
            if not s:
                out += p.wv(self.levels, model.freq, self.wavelet)
        y = self.series(model)
        if y is not None:
            out += wvar(y, model.freq, wavelet=self.wavelet, levels=self.levels).wv
        return out

    def jacobian(self, model: Model, mask: np.ndarray, *, central: bool = True,
                 at: np.ndarray | None = None) -> np.ndarray:
        """``d phi* / d theta`` over the free unconstrained parameters, shape (levels, n_free).

        Analytic components: their analytic Jacobians times the transform's; simulated
        ones: finite differences with common random numbers (central, or forward from `at`,
        the value of ``phi*`` at `model`).
        """
        theta = model.to_unconstrained()
        D = np.zeros((self.levels, theta.size))
        fd = []
        for p, s, sl in zip(model.processes, self.simulated, _slices(model)):
            if s:
                fd.extend(range(sl.start, sl.stop))
            else:
                D[:, sl] = p.wv_jacobian(self.levels, model.freq) @ p.transform_jacobian(theta[sl])
        base = None if central else (self(model) if at is None else at)
        step = _STEP_CENTRAL if central else _STEP_FORWARD
        for i in fd:
            if not mask[i]:
                continue
            up = theta.copy()
            up[i] += step
            if central:
                down = theta.copy()
                down[i] -= step
                D[:, i] = (self(model.from_unconstrained(up))
                           - self(model.from_unconstrained(down))) / (2 * step)
            else:
                D[:, i] = (self(model.from_unconstrained(up)) - base) / step
        return D[:, mask]

    def wv(self, model: Model) -> np.ndarray:
        """``phi*(theta)`` (the :class:`~stochmod.fit.results.Binding` protocol)."""
        return self(model)

    def natural_jacobian(self, model: Model, mask: np.ndarray) -> np.ndarray:
        """``D`` on the natural scale of the free parameters: central differences with common
        random numbers on the unconstrained scale, then the transform's inverse."""
        D_u = self.jacobian(model, mask, central=True)
        T = model.transform_jacobian(model.to_unconstrained())[np.ix_(mask, mask)]
        return np.linalg.solve(T.T, D_u.T).T

    def covariance(self, model: Model) -> np.ndarray:
        """Covariance of ``phi*(theta)``: eq. 17 on the simulated series at the model
        (J x J, unit^4; ``~ V N / n_sim`` when every component is simulated; zeros when none is)."""
        y = self.series(model)
        if y is None:
            return np.zeros((self.levels, self.levels))
        emp = wvar(y, model.freq, wavelet=self.wavelet, levels=self.levels)
        return data_covariance(y, emp, self.levels)

    def problem(self, template: Model, nu_hat: np.ndarray, omega: np.ndarray,
                mask: np.ndarray) -> SimulatedProblem:
        """The least-squares problem of eq. 20 with this binding (the engine's search)."""
        return SimulatedProblem(template, nu_hat, omega, mask, self)

    def finished(self) -> SimulatedBinding:
        """This binding with the search's cached paths dropped (so that a result holding it
        does not hold them)."""
        self._paths.clear()
        return self


class SimulatedProblem(Problem):
    """Eq. 20 with ``phi*`` of eq. 29 (values cached per point: the optimizer asks the
    residuals and the Jacobian at the same point)."""

    def __init__(self, template: Model, nu_hat: np.ndarray, omega: np.ndarray, mask: np.ndarray,
                 binding: SimulatedBinding):
        super().__init__(template, nu_hat, omega, mask)
        self.binding = binding
        self._last: tuple[bytes, np.ndarray] | None = None

    def phi(self, x: np.ndarray) -> np.ndarray:
        key = np.asarray(x, float).tobytes()
        if self._last is not None and self._last[0] == key:
            return self._last[1]
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore", RuntimeWarning)
            try:
                value = self.binding(self.model(x))
            except (ArithmeticError, ValueError):  # out of a family's reach: not finite
                value = np.full(self.levels, np.inf)
        self._last = (key, value)
        return value

    def dphi(self, x: np.ndarray) -> np.ndarray:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore", RuntimeWarning)
            return self.binding.jacobian(self.model(x), self.mask, central=False, at=self.phi(x))


@attrs.define(slots=False)
class IndirectGMWMResult(GMWMResult):
    """A GMWM fit whose binding function was (partly) simulated (eq. 29).

    Everything of :class:`~stochmod.fit.results.GMWMResult`; its ``binding`` is the
    :class:`SimulatedBinding` used, so the model WV, the Jacobian ``D`` and the covariance of
    eqs. 22-27 are the simulated binding's (V is the data's plus the simulation's).
    """

    @property
    def simulation(self) -> SimulatedBinding:
        """The binding function used (which components, simulated length, seed)."""
        return self.binding

    @property
    def simulation_covariance(self) -> np.ndarray:
        """Covariance of ``phi*(theta)`` at the estimate (:meth:`SimulatedBinding.covariance`)."""
        return self.binding_covariance

    @functools.cached_property
    def cov_params_simulation(self) -> np.ndarray:
        """The part of :attr:`cov_params` due to the simulated binding, ``B V_sim B^T``: the
        Monte Carlo covariance of the estimate given the data (how far another seed or an
        analytic binding would move it). Shrinks as ``1 / n_sim``."""
        return sandwich(self.jacobian, self.omega, self.simulation_covariance)

    def summary(self) -> str:
        """The GMWM summary plus how the binding function was simulated."""
        sim = self.simulation
        labels = [lab for lab, s in zip(self.model.labels, sim.simulated) if s]
        return (super().summary() + "\n" +
                f"indirect inference (eq. 29): simulated {', '.join(labels)}; n_sim = {sim.n_sim} "
                f"samples (R_eff = {sim.R_effective:.3g}), seed {sim.seed}; standard errors "
                "include the simulation's variance")

    def to_dict(self) -> dict[str, Any]:
        """The GMWM dict plus ``"indirect"``: simulated components, n_sim, seed."""
        sim = self.simulation
        out = super().to_dict()
        out["indirect"] = {
            "simulated": [lab for lab, s in zip(self.model.labels, sim.simulated) if s],
            "n_sim": sim.n_sim, "R_effective": sim.R_effective, "seed": sim.seed,
        }
        return out


def plan_binding(model: Model, binding: str, *, R: int, max_sim: int, n: int, levels: int,
                 seed: int, wavelet: str = "haar") -> SimulatedBinding | None:
    """Choose the binding function of a GMWM fit.

    Parameters
    ----------
    model : Model
        The model (bound to its sampling frequency).
    binding : {"auto", "analytic", "simulated"}
        See :func:`stochmod.gmwm`.
    R : int
        Simulated length in multiples of `n` (>= 1).
    max_sim : int
        Cap on the simulated length, samples.
    n : int
        Data length N, samples.
    levels : int
        Number of levels J.
    seed : int
        Seed of the common random numbers (a non-negative integer).
    wavelet : str
        Wavelet of the empirical WV.

    Returns
    -------
    SimulatedBinding or None
        None for the analytic binding.

    Raises
    ------
    InputError
        Unknown `binding`, bad `R`, `max_sim` or `seed`.
    SpecError
        ``binding="analytic"`` for a model with a family that has no theoretical WV.
    """
    if binding not in BINDINGS:
        raise InputError(f"unknown binding {binding!r}; choose one of {list(BINDINGS)}")
    R = check_positive_int(R, name="R")
    max_sim = check_positive_int(max_sim, name="max_sim")
    theory = [has_theoretical_wv(p) for p in model.processes]
    if binding == "analytic" or (binding == "auto" and all(theory)):
        missing = sorted({p.family for p, t in zip(model.processes, theory) if not t})
        if missing:
            raise SpecError(f"{', '.join(missing)} has no theoretical wavelet variance: "
                            "use binding='auto' or 'simulated' (indirect inference)")
        return None
    seed = check_positive_int(seed, name="rng", minimum=0)
    simulated = tuple(True for _ in theory) if binding == "simulated" else tuple(not t for t in theory)
    n_sim = min(R * n, max(max_sim, n))
    return SimulatedBinding(simulated, levels, n_sim, n, seed, wavelet)

