"""The GMWM fitting engine: the least-squares problem of eq. 20, its multi-start search, the
canonical order of repeated components and the sandwich covariance of eqs. 22-23.

This is the documented internal API that :func:`stochmod.gmwm`, indirect inference
(:mod:`stochmod.fit.indirect`) and model selection (:mod:`stochmod.fit.selection`) share; a new
estimator built on the GMWM criterion uses it the same way (see docs/architecture.md):

1. :func:`resolve_model` turns a spec into a :class:`~stochmod.core.model.Model` bound to the
   sampling frequency;
2. :class:`Problem` is eq. 20, ``|| L (nu_hat - phi(theta)) ||^2`` with ``Omega = L' L``, over
   the free parameters on the unconstrained scale (``phi`` is the model's theoretical WV; a
   subclass may replace the binding function ``phi`` and its Jacobian, as indirect inference
   does);
3. :func:`search` runs the seeded multi-start (flattened criterion of eq. 34, then eq. 20)
   and :func:`refine` one bounded local search; both return a :class:`SearchResult`;
4. :func:`canonical` orders repeated components so that fits compare across runs;
5. :func:`sandwich` gives ``B V B'`` (eqs. 22-23) from the Jacobian ``D``, ``Omega`` and ``V``.

:class:`stochmod.fit.results.GMWMResult` turns a :class:`SearchResult` into a result with
inference.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import attrs
import numpy as np

from stochmod.core.errors import EstimationError, SpecError
from stochmod.fit.lsq import levenberg_marquardt
from stochmod.fit.vector_binding import VectorBinding
from stochmod.core.model import Model, as_model
from stochmod.plugin.spec import model_from_spec
from stochmod.core.process import Process

if TYPE_CHECKING:
    from scipy import optimize

__all__ = [
    "BOUND",
    "STAGE1_TOLERANCE",
    "REFINE_TOLERANCE",
    "Problem",
    "SearchResult",
    "resolve_model",
    "refine",
    "search",
    "canonical",
    "IDENTIFIED_RTOL",
    "weighted_svd",
    "full_rank",
    "sandwich",
]

#: The free parameters of a fit are identified when the singular values of the weighted,
#: column-scaled Jacobian (:func:`weighted_svd`) satisfy ``s_min > IDENTIFIED_RTOL s_max``.
IDENTIFIED_RTOL = 1e-7
#: Bound on every unconstrained parameter, ``|theta_u| <= BOUND``: keeps exp() finite while
#: allowing any realistic scale.
BOUND = 300.0
#: Stage 1 of :func:`search` (the flattened criterion of eq. 34) only ranks starting points
#: for the refinement on eq. 20 itself: (tolerance, evaluation cap), looser than
#: :data:`REFINE_TOLERANCE`, which would crawl along flat valleys of weakly identified models.
#: Read at each call (studies/search_stage1.py varies it).
STAGE1_TOLERANCE = (1e-8, 100)
#: (tolerance, evaluation cap) of the refinement on eq. 20.
REFINE_TOLERANCE = (1e-12, 2000)


#: Points whose model and binding value a :class:`Problem` remembers: more than a search's
#: stage 1 evaluates, so that the objectives and WVs it asks for afterwards (raw starts,
#: stage-1 results) are the solver's own values, not computed again.
_REMEMBERED = 256

#: Two stage-1 points whose models' WVs agree to this (relative, every level) count as one:
#: they differ only along directions the WV does not see (a component shrunk to nothing,
#: two components swapped), and refining both would find one optimum twice.
_SAME_WV = 1e-3

_FAILURES = (ArithmeticError, ValueError, np.linalg.LinAlgError, EstimationError)
#: The methods of :class:`Problem` that define its binding: a subclass that overrides one
#: (indirect inference) is evaluated through them, never through the vector binding.
_BINDING_METHODS = ("phi", "dphi", "residuals", "objective", "safe_objective")


def _same_wv(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two finite WVs agree to :data:`_SAME_WV` (relative to `b`) at every level:
    ``np.allclose(a, b, rtol=_SAME_WV, atol=0)`` without its generic checks."""
    return bool(np.all(np.abs(a - b) <= _SAME_WV * np.abs(b)))


def _overrides(cls: type, name: str) -> bool:
    return getattr(cls, name) is not getattr(Problem, name)


def resolve_model(model: Model | Process | str | dict, freq: float) -> Model:
    """The composite model of a spec (``"2*GM+WN"``, dict), a Process or a Model, bound to
    `freq` (Hz)."""
    if isinstance(model, (str, dict)):
        return model_from_spec(model, freq)
    return as_model(model).bind(freq)


class Problem:
    """The least-squares form of eq. 20 over the free, unconstrained parameters.

    Parameters
    ----------
    template : Model
        A model with every value given (the start); its fixed values are kept.
    nu_hat : ndarray (J,)
        Empirical wavelet variance at levels 1..J, unit^2.
    omega : ndarray (J, J)
        Symmetric positive definite weighting matrix, unit^-4.
    mask : ndarray of bool
        The free parameters among ``template.vector()``.

    Notes
    -----
    The binding function ``phi(x)`` (the model's WV at the free unconstrained values `x`) and
    its Jacobian ``dphi(x)`` are the two methods a subclass overrides to change the binding
    (indirect inference: :class:`stochmod.fit.indirect.SimulatedProblem`); residuals,
    Jacobians and the flattened criterion of eq. 34 follow from them.
    """

    def __init__(self, template: Model, nu_hat: np.ndarray, omega: np.ndarray, mask: np.ndarray):
        self.template = template
        self.nu_hat = nu_hat
        self.levels = nu_hat.size
        self.mask = mask
        self.theta_full = template.to_unconstrained()
        self._all_free = bool(np.all(mask))
        self._nu_column = nu_hat[:, None]
        # Omega = L^T L: L is the transposed Cholesky factor of Omega
        self.L = np.linalg.cholesky(omega).T
        self.omega = omega
        # each process's slice of the parameter vector
        ends = np.cumsum([p.n_params for p in template.processes])
        self._slices = [slice(int(e) - p.n_params, int(e)) for e, p in zip(ends, template.processes)]
        # the last few points evaluated: the optimizer asks for phi, then dphi, at one point,
        # and the search re-evaluates the points its local searches returned
        self._models: dict[bytes, Model] = {}
        self._phis: dict[bytes, np.ndarray] = {}
        self._jacobians: dict[bytes, np.ndarray] = {}
        # the built-in families' WVs straight from parameter vectors (same digits); a subclass
        # that changes the binding, or a family without a vector form, keeps Process objects
        self._vector = None
        if not any(_overrides(type(self), name) for name in _BINDING_METHODS):
            self._vector = VectorBinding.of(template, self.levels)

    def _theta(self, x: np.ndarray) -> np.ndarray:
        if self._all_free:  # read only by callers: x itself is the full vector
            return np.asarray(x, dtype=np.float64)
        theta = self.theta_full.copy()
        theta[self.mask] = x
        return theta

    @staticmethod
    def _remember(cache: dict, key: bytes, value: Any) -> Any:
        if len(cache) >= _REMEMBERED:
            del cache[next(iter(cache))]
        cache[key] = value
        return value

    def model(self, x: np.ndarray) -> Model:
        """The model at free unconstrained values `x`."""
        key = np.asarray(x, dtype=np.float64).tobytes()
        found = self._models.get(key)
        if found is not None:
            return found
        theta = self._theta(x)
        procs = tuple(p.from_unconstrained(theta[s])
                      for p, s in zip(self.template.processes, self._slices))
        return self._remember(self._models, key, self.template.with_processes(procs))

    def phi(self, x: np.ndarray) -> np.ndarray:
        """Binding function: the model's Haar WV at `x`, levels 1..J, unit^2."""
        key = np.asarray(x, dtype=np.float64).tobytes()
        found = self._phis.get(key)
        if found is None:
            found = self._vector_point(x, key)
            if found is None:
                found = self.model(x).wv(self.levels)
            found = self._remember(self._phis, key, found)
            found.flags.writeable = False
        return found

    def _vector_point(self, x: np.ndarray, key: bytes) -> np.ndarray | None:
        """The WV at `x` by the vector binding, its Jacobian remembered; None without one or
        outside the domains (the Process path then raises as it always did)."""
        if self._vector is None:
            return None
        found = self._vector.point(self._theta(x))
        if found is None:
            return None
        self._remember(self._jacobians, key, found[1])
        return found[0]

    def dphi(self, x: np.ndarray) -> np.ndarray:
        """Jacobian of :meth:`phi` on the free unconstrained scale, shape (J, n_free)."""
        theta = self._theta(x)
        if self._vector is not None:
            key = np.asarray(x, dtype=np.float64).tobytes()
            found = self._jacobians.get(key)
            if found is None and self._vector_point(x, key) is not None:
                found = self._jacobians[key]
            if found is not None:  # the vector binding's d wv / d vector, then the domains' maps
                # (diagonal: column by column, the digits of the Process path's block products)
                return (found * self._vector.derivatives(theta))[:, self.mask]
        m = self.model(x)
        D = m.wv_jacobian(self.levels)
        for p, s in zip(m.processes, self._slices):  # times the block-diagonal d vector / d theta
            D[:, s] = D[:, s] @ p.transform_jacobian(theta[s])
        return D[:, self.mask]

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """``L (nu_hat - phi(x))``: eq. 20 is their sum of squares."""
        return self.L @ (self.nu_hat - self.phi(x))

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        """Jacobian of :meth:`residuals`."""
        return -self.L @ self.dphi(x)

    def flat_residuals(self, x: np.ndarray) -> np.ndarray:
        """``1 - phi(x) / nu_hat``: the flattened criterion of eq. 34 (dimensionless)."""
        return 1.0 - self.phi(x) / self.nu_hat

    def flat_jacobian(self, x: np.ndarray) -> np.ndarray:
        """Jacobian of :meth:`flat_residuals`."""
        return -self.dphi(x) / self._nu_column

    def objective(self, x: np.ndarray) -> float:
        """Eq. 20 at `x` (dimensionless)."""
        r = self.residuals(x)
        return float(r @ r)

    def safe_objective(self, x: np.ndarray) -> float:
        """Eq. 20 at `x`, inf where the model cannot be evaluated."""
        try:
            value = self.objective(x)
        except (ArithmeticError, ValueError):
            return np.inf
        return value if np.isfinite(value) else np.inf

    def safe_objectives(self, points: np.ndarray) -> np.ndarray:
        """:meth:`safe_objective` at each row of `points` (P, n_free): with the vector
        binding, every point's WV comes from one call per family (the same digits)."""
        points = np.asarray(points, dtype=np.float64)
        if self._vector is None:
            return np.array([self.safe_objective(x) for x in points])
        theta = np.repeat(self.theta_full[None, :], points.shape[0], axis=0)
        theta[:, self.mask] = points
        values, valid = self._vector.values(theta)
        try:
            wv, _ = self._vector.evaluate(values[valid])
        except (ArithmeticError, ValueError):
            return np.array([self.safe_objective(x) for x in points])
        out = np.empty(points.shape[0])
        rows = iter(wv)
        for i, x in enumerate(points):
            if not valid[i]:
                out[i] = self.safe_objective(x)
                continue
            r = self.L @ (self.nu_hat - next(rows))
            value = float(r @ r)
            out[i] = value if np.isfinite(value) else np.inf
        return out


@attrs.frozen
class SearchResult:
    """The best point of a search of eq. 20.

    Attributes
    ----------
    model : Model
        The model at the best point (not yet in canonical order, see :func:`canonical`).
    x : ndarray
        Free unconstrained values at the best point.
    objective : float
        Eq. 20 there.
    converged : bool
        Whether the best local search met its tolerances.
    message : str
        The optimizer's message for the best local search.
    n_starts : int
        Number of starting points (or local searches) considered.
    nfev : int
        Function evaluations over all local searches.
    """

    model: Model
    x: np.ndarray = attrs.field(eq=False, repr=False)
    objective: float
    converged: bool
    message: str
    n_starts: int
    nfev: int


def refine(fun: Callable[[np.ndarray], np.ndarray], jac: Callable[[np.ndarray], np.ndarray],
           x0: np.ndarray, tol: float = REFINE_TOLERANCE[0], max_nfev: int = REFINE_TOLERANCE[1]
           ) -> optimize.OptimizeResult:
    """One bounded local least-squares search from `x0` clipped to ``[-BOUND, BOUND]``, with
    `tol` as xtol, ftol and gtol: the Levenberg-Marquardt of :mod:`stochmod.fit.lsq` (the
    stopping rules and result fields of ``scipy.optimize.least_squares``, a fraction of its
    overhead per iteration on these small problems). Floating point warnings of the model's
    evaluations are silenced (a trial step may leave a family's reach; the search then backs
    off).
    """
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)
        return levenberg_marquardt(fun, jac, x0, (-BOUND, BOUND), ftol=tol, xtol=tol, gtol=tol,
                                   max_nfev=max_nfev)


def canonical(model: Model) -> Model:
    """Order repeated components of one family by their declared ``ordering_key()``, largest
    first (GM: fastest first), so that fitted models compare across runs (no label switching)."""
    procs = list(model.processes)
    for family in {p.family for p in procs}:
        slots = [i for i, p in enumerate(procs) if p.family == family]
        ordered = sorted((procs[i] for i in slots), key=lambda p: -p.ordering_key())
        for i, p in zip(slots, ordered):
            procs[i] = p
    return attrs.evolve(model, processes=tuple(procs))


def search(base: Model, nu_hat: np.ndarray, omega: np.ndarray, mask: np.ndarray,
           n_starts: int, n_random: int, starts: Sequence[Model | str | dict], seed: int,
           n_refine: int = 3, *,
           problem_factory: Callable[..., Problem] = Problem) -> SearchResult:
    """Seeded multi-start minimisation of eq. 20.

    Candidates: the families' guesses and their alternatives, the given `starts`, `n_starts`
    seeded perturbations of the guesses, and the best of `n_random` random points screened by
    the objective. Each candidate first descends the flattened criterion of eq. 34 (cheap,
    well scaled; :data:`STAGE1_TOLERANCE`). The candidates and their stage-1 results are
    ranked by eq. 20; the `n_refine` best whose models' WVs differ (by more than
    ``_SAME_WV``, relative, at some level), and every given start as it is, are then refined
    on eq. 20 itself (:data:`REFINE_TOLERANCE`). The best refined point wins. Both stages run
    :func:`refine` with the lean trust-region Levenberg-Marquardt of :mod:`stochmod.fit.lsq`.

    Parameters
    ----------
    base : Model
        The model to fit, bound to its sampling frequency; parameters with values are fixed.
    nu_hat : ndarray (J,)
        Empirical WV, unit^2.
    omega : ndarray (J, J)
        Weighting matrix.
    mask : ndarray of bool
        ``base.free_mask()``.
    n_starts, n_random : int
        Seeded perturbed starts, and random points screened by the objective.
    starts : sequence of Model or spec
        Extra starting models with every value given.
    seed : int
        Seed of every random choice.
    n_refine : int
        Stage-1 results refined on eq. 20.
    problem_factory : callable
        ``(template, nu_hat, omega, mask) -> Problem`` (a subclass changes the binding).

    Raises
    ------
    SpecError
        A start that does not match `base`.
    EstimationError
        No start gives a finite objective.
    """
    gen = np.random.default_rng(seed)
    template = base.start(nu_hat)
    problem = problem_factory(template, nu_hat, omega, mask)
    candidates = [template.to_unconstrained()[mask]]
    given = []
    for s in starts:
        s = resolve_model(s, base.freq)
        if s.n_params != base.n_params or s.is_free:
            raise SpecError(f"start {s.name} does not match model {base.name} with all values given")
        given.append(s.to_unconstrained()[mask])
    candidates.extend(given)
    candidates.extend(alt.to_unconstrained()[mask]
                      for alt in base.start_alternatives(nu_hat, template=template))
    for _ in range(n_starts):
        candidates.append(base.start(nu_hat, rng=gen).to_unconstrained()[mask])
    if n_random:
        centre = candidates[0]
        cloud = centre + gen.normal(0.0, 3.0, size=(n_random, centre.size))
        values = problem.safe_objectives(cloud)
        best_cloud = np.argsort(values)[: max(2, n_starts // 2)]
        candidates.extend(cloud[i] for i in best_cloud if np.isfinite(values[i]))

    nfev = 0
    stage1: list[tuple[float, np.ndarray]] = [(problem.safe_objective(x), x) for x in given]
    for x0 in candidates:
        try:
            flat = refine(problem.flat_residuals, problem.flat_jacobian, x0, *STAGE1_TOLERANCE)
        except _FAILURES:
            continue
        nfev += flat.nfev
        stage1.append((problem.safe_objective(flat.x), flat.x))
        stage1.append((problem.safe_objective(x0), x0))
    stage1 = [(v, x) for v, x in stage1 if np.isfinite(v)]
    stage1.sort(key=lambda item: item[0])
    chosen: list[np.ndarray] = []
    seen: list[np.ndarray] = []  # their models' WVs
    for _, x in stage1:
        wv = problem.phi(x)
        if not any(_same_wv(wv, c) for c in seen):
            chosen.append(x)
            seen.append(wv)
        if len(chosen) >= n_refine:
            break
    chosen.extend(g for g in given if not any(g is c for c in chosen))

    best: dict[str, Any] | None = None
    for x1 in chosen:
        try:
            res = refine(problem.residuals, problem.jacobian, x1)
        except _FAILURES:
            continue
        nfev += res.nfev
        value = problem.safe_objective(res.x)
        if best is None or value < best["objective"]:
            best = {"x": res.x, "objective": value, "converged": bool(res.success),
                    "message": str(res.message)}
    if best is None or not np.isfinite(best["objective"]):
        raise EstimationError(f"GMWM failed to find a finite objective for {base.name} from any start")
    return SearchResult(model=problem.model(best["x"]), nfev=nfev, n_starts=len(candidates), **best)


def weighted_svd(D: np.ndarray, W: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The fit's geometry in the metric of the weighting: ``(L, U, s)`` with ``L`` upper
    triangular, ``W = L^T L``, and ``U diag(s)`` the thin SVD's left factor and singular values
    of ``L D`` with its columns scaled to unit norm (column scaling leaves the column space,
    hence the projection, unchanged; columns of norm zero or not finite, parameters the WV does
    not depend on, are left out, so that ``s`` can be shorter than D has columns).

    The fit's projection ``D (D^T W D)^{-1} D^T W`` (eqs. 22-23) is ``L^{-1} U U^T L`` when
    ``s`` is well away from zero, computed from orthogonal factors without the normal
    equations (whose condition is the square of ``L D``'s). Singular values below
    :data:`IDENTIFIED_RTOL` times the largest mean that some parameters are not identified.
    """
    L = np.linalg.cholesky(0.5 * (W + W.T)).T
    A = L @ D
    norms = np.linalg.norm(A, axis=0)
    ok = np.isfinite(norms) & (norms > 0)
    if not ok.any():
        return L, np.zeros((A.shape[0], 0)), np.zeros(0)
    U, s, _ = np.linalg.svd(A[:, ok] / norms[ok], full_matrices=False)
    return L, U, s


def full_rank(s: np.ndarray, n_params: int, tol: float = IDENTIFIED_RTOL) -> bool:
    """Whether the singular values `s` of :func:`weighted_svd` resolve all `n_params`
    parameters: none was left out and ``s_min > tol s_max`` (True for no parameter)."""
    return bool(s.size == n_params and (n_params == 0 or s[-1] > tol * s[0]))


def sandwich(D: np.ndarray, W: np.ndarray, V: np.ndarray) -> np.ndarray:
    """``B V B^T`` with ``B = (D^T W D)^{-1} D^T W`` (eqs. 22-23), symmetrised.

    Parameters
    ----------
    D : ndarray (J, p)
        Jacobian of the binding function at the estimate (natural scale), unit^2 per
        parameter unit.
    W : ndarray (J, J)
        Weighting matrix Omega.
    V : ndarray (J, J)
        Covariance of the empirical WV, unit^4.

    Returns
    -------
    ndarray (p, p)
        Covariance of the estimate, in the parameters' units squared. Computed with D's
        columns scaled to unit norm (a parameter the WV barely sees has a tiny column and a
        huge row of B), then scaled back: a variance beyond the float range is inf.

    Raises
    ------
    EstimationError
        A parameter the WV does not depend on, or ``D^T W D`` singular.
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
