"""Automatic model selection: fit a lattice of nested composite models by the GMWM and rank them.

``select(x, freq)`` builds the candidates (given specs, or every combination of the families
up to their maximal counts, e.g. 0..3 GM with WN, RW, QN, RR in or out) and arranges them in a
:class:`networkx.DiGraph` whose edges add one process. All candidates of a signal share one
weighting matrix ``Omega`` and one WV covariance ``V`` (eq. 17), so objectives and criteria
compare. Candidates without a fitted parent get the GMWM's full multi-start search; a child
starts from its best parent's fit padded with a negligible copy of the added process (so its
objective is never worse than any parent's) and from its parents' fits padded with the added
process started on the residual WV at several time scales (screened by the objective).

Fits run through any :class:`concurrent.futures.Executor` using ``submit`` only, each as soon
as its parents are done (a ``dask.distributed`` client's ``get_executor()`` works unchanged);
work items are plain picklable data (specs, the empirical WV, ``Omega``, seeds). Every fit's
seed depends only on ``rng`` and the candidate, so results do not depend on the executor, on
the order fits complete, or on the other columns of a multi-axis signal.
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import itertools
from collections import Counter, defaultdict
from collections.abc import Iterator, Mapping, Sequence
from typing import Any

import attrs
import networkx as nx
import numpy as np
from numpy.typing import ArrayLike

from stochmod.core.checks import as_signals, check_freq, check_positive_int
from stochmod.core.errors import DomainError, EstimationError, InputError, SpecError
from stochmod.core.model import Model, as_model
from stochmod.core.parallel import process_pool, single_threaded_blas
from stochmod.core.process import Process
from stochmod.core.tables import format_table
from stochmod.empirical.robust_wv import check_efficiency
from stochmod.empirical.wavelet_variance import WaveletVariance, wvar
from stochmod.fit import criteria as _criteria
from stochmod.fit.engine import Problem, SearchResult, refine, search
from stochmod.fit.lattice import default_families, default_max_counts
from stochmod.fit.replicates import is_replicates, pooled_wv
from stochmod.fit.results import GMWMResult
from stochmod.fit.weighting import check_weighting_matrix, data_covariance
from stochmod.fit.weighting_plugins import WeightingInput, get_weighting, weighting_names
from stochmod.io.recording import Recording
from stochmod.plugin.spec import model_from_spec

__all__ = ["select", "refit", "SelectionResult", "RankingRow", "candidate_lattice", "nested_graph", "model_terms",  # noqa: RUF022
           "DEFAULT_FAMILIES", "SELECTION_WEIGHTINGS"]  # noqa: F822 (read through __getattr__)


def __getattr__(name: str) -> Any:
    """Registry-derived constants, read when asked, not at import.

    ``DEFAULT_FAMILIES``: the registered families that declare lattice membership
    (:func:`stochmod.fit.lattice.default_families`). ``SELECTION_WEIGHTINGS``: the registered
    weightings usable in a selection (a weighting that needs each model's own fit, such as the
    bootstrap, cannot be shared by all candidates; :func:`stochmod.fit.weighting_plugins.weighting_names`).
    """
    if name == "DEFAULT_FAMILIES":
        return default_families()
    if name == "SELECTION_WEIGHTINGS":
        return tuple(weighting_names(shared=True))
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


_AUTO_PROGRESS = 8  # progress bar by default above this many fits
#: Without an executor, up to this many fits run on a thread of this process (beside V's
#: thread): a handful of fits costs less CPU than starting worker processes and pickling
#: their tasks and results, and leaves the cores to eq. 17.
_POOL_FITS = 8
_NEGLIGIBLE = 1e-30  # relative size of a padded component's WV (objective unchanged in float64)
_ROOT_SEARCH = (6, 200)  # gmwm's (n_starts, n_random) for a candidate without fitted parent
_PARENT_STARTS = 2  # a child starts from its best parents' fits (smallest objectives first)
_SCALES = 6  # time scales at which an added process is tried
_CHILD_RANDOM = 2  # perturbed family guesses screened for a child
_CHILD_KEEP = 2  # screened starts refined by a local search
_CHILD_NFEV = 200  # evaluation budget of one local search of a child
_CHILD_TOL = 1e-10  # its tolerances (relative change of the objective / step)


# --------------------------------------------------------------------------- candidates
def _term_key(p: Process) -> tuple[str, tuple]:
    """A process's structural identity: family and structural arguments (not values)."""
    return p.family, tuple(sorted(p.structure().items()))


def model_terms(model: Model) -> Counter:
    """The structure of `model`: a multiset of its processes' structural identities (family and
    structural arguments, not values); two models with equal terms are the same candidate."""
    return Counter(_term_key(p) for p in model.processes)


def candidate_lattice(families: Sequence[str] | None = None,
                      max_counts: Mapping[str, int] | None = None) -> list[Model]:
    """Every non-empty combination of `families` with 0..max_counts[f] copies of each.

    Parameters
    ----------
    families : sequence of str
        Family names (``"GM"``) or one-process terms (``"AR(2)"``), in the order the model
        names list them (default: :func:`stochmod.fit.lattice.default_families`).
    max_counts : mapping of str to int, optional
        Largest count per family (default 1 for a family not listed; e.g. ``{"GM": 3}``).

    Returns
    -------
    list of Model
        Free models, fewest processes first.
    """
    families = list(default_families() if families is None else families)
    if not families:
        raise InputError("families is empty: name at least one process family")
    if len(set(families)) != len(families):
        raise InputError(f"families lists a family twice: {families}")
    max_counts = dict(max_counts or {})
    unknown = set(max_counts) - set(families)
    if unknown:
        raise InputError(f"max_counts names {sorted(unknown)}, which are not in families {families}")
    protos = []
    for fam in families:
        model = model_from_spec(fam)
        if len(model.processes) != 1:
            raise InputError(f"families entries are single processes, got {fam!r}")
        protos.append(model.processes[0].freed())
    counts = []
    for fam in families:
        c = max_counts.get(fam, 1)
        if isinstance(c, bool) or not isinstance(c, (int, np.integer)) or c < 0:
            raise InputError(f"max_counts[{fam!r}] must be a non-negative integer, got {c!r}")
        counts.append(range(int(c) + 1))
    out = []
    for combo in itertools.product(*counts):
        procs = tuple(p for p, c in zip(protos, combo) for _ in range(c))
        if procs:
            out.append(Model(procs))
    if not out:
        raise InputError("max_counts allows no process at all")
    return sorted(out, key=lambda m: len(m.processes))


def nested_graph(models: Sequence[Model]) -> nx.DiGraph:
    """The DAG of `models` (nodes named ``model.name``) with an edge parent -> child wherever
    the child is the parent plus exactly one process (same structure otherwise).

    Node attributes: ``model`` (Model), ``n_params``; edge attribute ``added`` (family).
    """
    graph = nx.DiGraph()
    keys = {}
    for m in models:
        if m.name in graph:
            raise InputError(f"candidate {m.name!r} is listed twice (candidates are told apart by "
                             "their structure, not by fixed values)")
        graph.add_node(m.name, model=m, n_params=m.n_params)
        keys[m.name] = model_terms(m)
    for child, ck in keys.items():
        for parent, pk in keys.items():
            diff = ck - pk
            if sum(diff.values()) == 1 and not (pk - ck):
                (added,) = diff
                graph.add_edge(parent, child, added=added[0])
    return graph


def _as_candidates(candidates: Sequence[Any] | None, families: Sequence[str],
                   max_counts: Mapping[str, int] | None) -> list[Model]:
    if candidates is None:
        return candidate_lattice(families, max_counts)
    if isinstance(candidates, (str, Mapping, Model, Process)):
        candidates = [candidates]
    out = []
    for c in candidates:
        out.append(model_from_spec(c) if isinstance(c, (str, Mapping)) else as_model(c))
    if not out:
        raise InputError("candidates is empty: give at least one model spec, or None for the lattice")
    return [attrs.evolve(m, freq=None) for m in out]


# --------------------------------------------------------------------------- work items
@attrs.frozen
class _Column:
    """What every fit of one signal shares: the empirical WV and Omega (and V when Omega
    needs it; otherwise V is computed in parallel with the fits and attached at the end)."""

    empirical: WaveletVariance
    omega: np.ndarray
    covariance: np.ndarray | None = None


@attrs.frozen
class _Task:
    """One GMWM fit; plain picklable data (a spec and the starts' unconstrained parameter
    vectors of the child's full model, not models or callables).

    A root (no fitted parent) gets gmwm's full multi-start search. A child gets local
    searches from the best ``_CHILD_KEEP`` of `screen` (padded parents, family guesses) by
    objective value, and from `starts` (the negligibly padded best parent) unless a screened
    start is already at least as good.
    """

    column: int
    name: str
    spec: dict
    freq: float
    shared: _Column
    weighting: str
    seed: int
    starts: tuple[np.ndarray, ...] = ()
    screen: tuple[np.ndarray, ...] = ()

    @property
    def root(self) -> bool:
        return not (self.starts or self.screen)


def _column(emp: WaveletVariance, x: np.ndarray | None, scheme: Any, seed: int,
            covariance: np.ndarray | None = None) -> _Column:
    """The shared part of one column's fits from its empirical WV (and signal `x`, or the WV's
    known `covariance`)."""
    J = emp.wv.size
    if np.any(emp.wv <= 0):
        raise InputError("the empirical wavelet variance has non-positive levels (constant stretches?)")
    made = scheme.matrix(WeightingInput(emp, J, x, seed=seed, covariance=covariance))
    omega = check_weighting_matrix(made.omega, J, source=f"weighting {scheme.name!r}'s matrix")
    return _Column(emp, omega, covariance if covariance is not None else made.covariance)


def _prepare(item: tuple[np.ndarray, float, int | None, Any, int, dict]) -> _Column:
    """Empirical WV and weighting matrix of one signal (with V when the weighting inverts it,
    e.g. eq. 17 for the optimal weighting). The weighting object travels with the item, so a
    weighting registered at run time works in worker processes too; the last item holds
    wvar's estimator options (``robust``, ``efficiency``)."""
    x, freq, levels, scheme, seed, options = item
    return _column(wvar(x, freq, levels=levels, **options), x, scheme, seed)


def _covariance(item: tuple[np.ndarray, WaveletVariance, int]) -> np.ndarray:
    """Covariance V of the empirical WV (eq. 17, deep levels decoupled) at levels 1..J."""
    x, emp, J = item
    return data_covariance(x, emp, J)


def _local_search(task: _Task, base: Model, nu_hat: np.ndarray, mask: np.ndarray) -> SearchResult:
    """A child's fit: local least-squares searches of eq. 20 from its screened starts."""
    problem = Problem(base.start(nu_hat), nu_hat, task.shared.omega, mask)

    gen = np.random.default_rng(task.seed)
    pool = [s[mask] for s in task.screen]
    pool.append(problem.theta_full[mask])
    pool.extend(base.start(nu_hat, rng=gen).to_unconstrained()[mask] for _ in range(_CHILD_RANDOM))
    values = problem.safe_objectives(np.array(pool))
    chosen = [pool[i] for i in np.argsort(values, kind="stable")[:_CHILD_KEEP]
              if np.isfinite(values[i])]
    best_screened = float(np.min(values)) if values.size else np.inf
    for s in task.starts:  # searched unless a screened start is already as good
        x = s[mask]
        if not problem.safe_objective(x) >= best_screened:
            chosen.insert(0, x)
    # a start met twice (a parent's fit that is also a screened start) searches the same
    # path again and cannot beat its first result: searched once
    chosen = [x for i, x in enumerate(chosen)
              if not any(np.array_equal(x, y) for y in chosen[:i])]
    best: dict[str, Any] | None = None
    nfev = 0
    for x0 in chosen:
        res = refine(problem.residuals, problem.jacobian, x0, _CHILD_TOL, _CHILD_NFEV)
        nfev += res.nfev
        value = problem.safe_objective(res.x)
        if best is None or value < best["objective"]:
            best = {"x": res.x, "objective": value, "converged": bool(res.success),
                    "message": str(res.message)}
    if best is None or not np.isfinite(best["objective"]):
        raise EstimationError(f"GMWM failed to find a finite objective for {base.name}")
    return SearchResult(model=problem.model(best["x"]), nfev=nfev + len(pool),
                        n_starts=len(chosen), **best)


def _fit_task(task: _Task) -> GMWMResult:
    """Fit one candidate with the column's shared Omega (module level: picklable)."""
    emp = task.shared.empirical
    J = emp.wv.size
    nu_hat = np.asarray(emp.wv, float)
    base = model_from_spec(task.spec, task.freq)
    mask = base.free_mask()
    if task.root:
        found = search(base, nu_hat, task.shared.omega, mask, *_ROOT_SEARCH, (), task.seed)
    else:
        found = _local_search(task, base, nu_hat, mask)
    result = GMWMResult.from_search(
        found, empirical=emp, omega=task.shared.omega, weighting=task.weighting, levels=J,
        mask=mask, covariance=task.shared.covariance, rng_seed=task.seed)
    # the J-test's V, the J-test itself and the ranking's SVD, in the worker: they travel
    # with the fit and outlive the data's V that joins it (GMWMResult.with_data_covariance)
    result = result.with_null_covariance()
    for cached in ("asymptotic_jtest", "analytic_weighted_svd", "negligible"):
        getattr(result, cached)
    return result


def _negligible(proc: Process, nu_hat: np.ndarray, freq: float) -> Process | None:
    """`proc` with its scale parameter shrunk until its WV is below ``_NEGLIGIBLE * nu_hat``.

    The contract's rule (docs/plugin_contract.md, "Roles"): the WV is proportional to
    ``value ** d`` of the parameter declared with a scale role (d = 1 for ``"variance"``, 2 for
    ``"amplitude"``), so multiplying it by ``(_NEGLIGIBLE min_j nu_hat_j / wv_j) ** (1/d)``
    puts the component's WV below ``_NEGLIGIBLE`` times the data's at every level. None when
    the family declares no scale role or its WV is nowhere positive.
    """
    scale = proc.scale_parameter()
    if scale is None:
        return None
    spec, power = scale
    base = proc.wv(nu_hat.size, freq)
    pos = base > 0
    if not np.all(np.isfinite(base)) or not pos.any():
        return None
    factor = (_NEGLIGIBLE * np.min(nu_hat[pos] / base[pos])) ** (1.0 / power)
    try:
        return proc.with_values(**{spec.name: getattr(proc, spec.name) * factor})
    except DomainError:
        return None


def _slots(child: Model, parent: Model) -> tuple[list[Process | None], int] | None:
    """The child's processes filled with the parent's fitted ones (same structure, in order,
    the child's fixed values kept); the one slot left (None) is the added process."""
    pool: dict[tuple, list[Process]] = defaultdict(list)
    for p in parent.processes:
        pool[_term_key(p)].append(p)
    procs: list[Process | None] = []
    new = None
    for i, p in enumerate(child.processes):
        if pool[_term_key(p)]:
            fitted = pool[_term_key(p)].pop(0)
            fixed = {k: v for k, v in p.values().items() if v is not None}
            procs.append(fitted.with_values(**fixed) if fixed else fitted)
        else:
            procs.append(None)
            new = i
    return (procs, new) if new is not None else None


def _guesses(proc: Process, wv: np.ndarray, freq: float) -> list[Process]:
    """Starting guesses of one added process from a residual WV, spread over time scales."""
    out = []
    for i in range(_SCALES):
        try:
            out.append(proc.start(wv, freq, index=i, count=_SCALES))
        except (DomainError, InputError, ArithmeticError, ValueError, NotImplementedError):
            continue
    return out


def _child_starts(child: Model, parents: list[GMWMResult], nu_hat: np.ndarray, freq: float
                  ) -> tuple[tuple[dict, ...], tuple[dict, ...]]:
    """Starts of a child from its fitted parents.

    Returns ``(starts, screen)``, unconstrained parameter vectors of the whole child model
    (:meth:`Model.to_unconstrained`): `starts` holds the best parent (smallest objective) padded
    with a negligible copy of the added process, so that the child does no worse than any
    parent; `screen` holds the best parents padded with the added process started on the
    positive part of the residual WV at several time scales.
    """
    child = child.bind(freq)
    ranked = sorted(parents, key=lambda f: (f.objective, f.model.name))
    starts: list[np.ndarray] = []
    screen: list[np.ndarray] = []
    for i, parent in enumerate(ranked[:_PARENT_STARTS]):
        slots = _slots(child, parent.model)
        if slots is None:
            continue
        procs, new = slots
        resid = nu_hat - parent.model.wv(nu_hat.size)
        resid = np.where(resid > 0, resid, 1e-3 * nu_hat)
        fresh = child.processes[new]
        for guess in _guesses(fresh, resid, freq):
            procs[new] = guess
            screen.append(Model(tuple(procs), freq).to_unconstrained())
            if i == 0 and not starts:
                small = _negligible(guess, nu_hat, freq)
                if small is not None:
                    procs[new] = small
                    starts.append(Model(tuple(procs), freq).to_unconstrained())
    return tuple(starts), tuple(screen)


# --------------------------------------------------------------------------- result
@attrs.frozen
class RankingRow:
    """One candidate in a ranking.

    Attributes
    ----------
    model : str
        Model name (``"2*GM+WN"``).
    n_params : int
        Number of estimated parameters.
    objective : float
        GMWM objective (eq. 20) with the shared Omega.
    optimism : float
        Penalty of the criterion (``criterion - objective``).
    criterion : float
        Criterion value (smaller is better).
    jtest_pvalue : float or None
        p-value of the J-test of eq. 27 (goodness of fit; None when not computable).
    identified : bool
        Whether the fit's parameters are locally identified (see
        :func:`stochmod.fit.criteria.identified`); unidentified fits (e.g. a GM whose correlation
        time ran to infinity, so that only ``sigma2 * beta`` matters) rank after all identified
        ones and are never selected while one is identified.
    """

    model: str
    n_params: int
    objective: float
    optimism: float
    criterion: float
    jtest_pvalue: float | None
    identified: bool


@attrs.frozen(eq=False)
class SelectionResult:
    """Result of :func:`select` for one signal.

    Attributes
    ----------
    column : str
        Name of the signal (column).
    best : GMWMResult
        The fit of the selected model (smallest criterion).
    ranking : tuple of RankingRow
        Every candidate, best first.
    fits : dict of str to GMWMResult
        Every fit by model name.
    graph : networkx.DiGraph
        Candidates (nodes, with ``model``, ``n_params``, ``objective``, ``criterion``) and
        nesting edges parent -> child (``added``: the family added).
    criterion : str
        Name of the criterion.
    weighting : str
        The weighting shared by all fits.
    empirical : WaveletVariance
        The empirical wavelet variance of the signal.
    wv_covariance : ndarray (J, J)
        The covariance V of the empirical WV (eq. 17) shared by all fits, unit^4.
    final_weighting : str or None
        The weighting :attr:`best` was fitted with again after the ranking (:func:`refit`), or
        None: :attr:`best` is the selected candidate's fit with :attr:`weighting`.
    """

    column: str
    best: GMWMResult
    ranking: tuple[RankingRow, ...]
    fits: dict[str, GMWMResult]
    graph: nx.DiGraph
    criterion: str
    weighting: str
    empirical: WaveletVariance
    wv_covariance: np.ndarray
    final_weighting: str | None = None

    @property
    def refit_note(self) -> str:
        """What :func:`refit` did, in words ("" when :attr:`best` is the ranked fit)."""
        if self.final_weighting is None:
            return ""
        return (f"fitted again after the ranking ({self.weighting} weighting) with the "
                f"{self.final_weighting} weighting")

    def summary(self) -> str:
        """The ranking table followed by the selected fit's report."""
        rows = [[i + 1, r.model, r.n_params, r.objective, r.optimism, r.criterion,
                 "n/a" if r.jtest_pvalue is None else r.jtest_pvalue,
                 "yes" if r.identified else "no"]
                for i, r in enumerate(self.ranking)]
        robust = (f", robust WV: {self.empirical.rho}, efficiency {self.empirical.efficiency:g}"
                  if self.empirical.robust else "")
        title = (f"Model selection for {self.column} ({self.criterion}, {self.weighting} weighting{robust}, "
                 f"{len(self.ranking)} candidates, N = {self.empirical.n}, "
                 f"freq = {self.empirical.freq:g} Hz): selected {self.best.model.name}"
                 + (f", fitted again with the {self.final_weighting} weighting"
                    if self.final_weighting else ""))
        table = format_table(["rank", "model", "params", "objective", "optimism", self.criterion,
                              "J-test p", "identified"], rows, title=title)
        try:
            report = self.best.summary()
        except EstimationError as exc:
            report = f"no candidate is identified by the wavelet variance: {exc}"
        return f"{table}\n\n{report}"

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe summary: selected fit, ranking, nesting edges."""
        try:
            best = self.best.to_dict()
        except EstimationError:  # no identified candidate: no intervals
            best = {"model": self.best.model.to_spec(), "name": self.best.model.name,
                    "objective": self.best.objective, "identified": False}
        return {
            "column": self.column,
            "criterion": self.criterion,
            "weighting": self.weighting,
            "final_weighting": self.final_weighting,
            "selected": self.best.model.name,
            "best": best,
            "ranking": [attrs.asdict(r) for r in self.ranking],
            "edges": [[a, b] for a, b in self.graph.edges],
        }


# --------------------------------------------------------------------------- driver
def _seed(rng: int, index: int) -> int:
    """Seed of candidate `index`: the same for every column and executor, so a column's
    selection does not depend on the other columns or on the order fits complete."""
    return int(np.random.SeedSequence([rng, index]).generate_state(1)[0])


def _base_seed(rng: Any) -> int:
    if isinstance(rng, np.random.Generator):
        return int(rng.integers(2**32))
    if isinstance(rng, (int, np.integer)) and not isinstance(rng, bool) and rng >= 0:
        return int(rng)
    raise InputError(f"rng must be a non-negative integer seed or a numpy Generator, got {rng!r}")


@contextlib.contextmanager
def _progress(total: int, progress: bool | None, desc: str) -> Iterator[Any]:
    show = total > _AUTO_PROGRESS if progress is None else bool(progress)
    bar = None
    if show:
        try:
            from tqdm.auto import tqdm
        except ImportError:
            if progress:
                raise ImportError('progress=True needs tqdm: pip install "stochmod[progress]"') from None
        else:
            # automatic mode stays quiet when stderr is not a terminal (logs, pipes, CI)
            bar = tqdm(total=total, desc=desc, unit="fit", leave=False,
                       disable=None if progress is None else False)
    try:
        yield bar
    finally:
        if bar is not None:
            bar.close()


@contextlib.contextmanager
def _executor(executor: Any, n_fits: int) -> Iterator[tuple[Any, bool]]:
    """The executor of the fits, and whether it runs in or beside this process (then the WV is
    taken here and V runs on a thread of this process, beside the fits). The default: a
    thread of this process for at most ``_POOL_FITS`` fits, else 2 worker processes."""
    if executor is None:
        if n_fits <= _POOL_FITS:
            with concurrent.futures.ThreadPoolExecutor(max_workers=1) as pool:
                yield pool, True
        else:
            with process_pool(2) as pool:
                yield pool, True
    else:
        if not callable(getattr(executor, "submit", None)):
            raise InputError(f"executor must be a concurrent.futures.Executor (with .submit), "
                             f"got {executor!r}")
        yield executor, isinstance(executor, concurrent.futures.ProcessPoolExecutor)


def _start_workers(pool: concurrent.futures.ProcessPoolExecutor) -> None:
    """Have `pool` start its worker processes now, before this process starts V's threads.

    A forked worker inherits the locks of this process as they are at the fork: if V's
    thread were compiling or loading a numba function then, the worker would inherit numba's
    compiler lock held by a thread that does not exist in it, and wait forever on its own
    first compiled call (the GM closed form's). With the fork start method a pool starts all
    its workers at its first task; later tasks reuse them, so this costs one round trip.
    """
    pool.submit(int).result()


def _signals(x: Any, freq: float | None, names: Sequence[str] | None
             ) -> tuple[np.ndarray, float, list[str], bool]:
    single = False
    if isinstance(x, Recording):
        data, cols = x.data, list(x.columns)
        freq = x.freq if freq is None else freq
    else:
        single = np.ndim(x) == 1
        data = as_signals(x, name="x", min_length=8)
        cols = [str(i) for i in range(data.shape[1])]
    if freq is None:
        raise InputError("freq (Hz) is required")
    freq = check_freq(freq)
    if names is not None:
        names = [str(n) for n in names]
        if len(names) != data.shape[1]:
            raise InputError(f"names has {len(names)} entries but x has {data.shape[1]} column(s)")
        cols = names
    for k, c in enumerate(cols):
        if np.ptp(data[:, k]) == 0:
            raise InputError(f"column {c!r} of x is constant: it has no noise to model")
    return data, freq, cols, single


def select(
    x: ArrayLike | Recording,
    freq: float | None = None,
    candidates: Sequence[str | Mapping | Model | Process] | None = None,
    families: Sequence[str] | None = None,
    max_counts: Mapping[str, int] | None = None,
    criterion: str = "wvic",
    weighting: str = "diagonal",
    executor: concurrent.futures.Executor | None = None,
    progress: bool | None = None,
    rng: int | np.random.Generator = 0,
    levels: int | None = None,
    *,
    names: Sequence[str] | None = None,
    robust: bool = False,
    efficiency: float = 0.6,
    final_weighting: str | None = None,
) -> SelectionResult | list[SelectionResult]:
    """Select a composite model by fitting every candidate with the GMWM and ranking them.

    Parameters
    ----------
    x : array_like, shape (N,) or (N, k), Recording, or list of array_like
        Static error signal(s), unit u (rad/s, m/s^2 ...); a 2-D array holds one axis per
        column (e.g. 6 IMU axes) and gives one selection per column; a list of 1-D signals
        holds replicates of one sensor model and gives one selection on their pooled WV
        (:mod:`stochmod.fit.replicates`).
    freq : float
        Sampling frequency, Hz (taken from a Recording when it records it).
    candidates : sequence of spec, optional
        Model specs (``"2*GM+WN"``, dicts, Models). None: the lattice of `families` with
        counts 0..`max_counts` (see :func:`candidate_lattice`).
    families : sequence of str, optional
        Families of the lattice (default: the registered families that declare
        ``lattice_copies > 0``, :func:`stochmod.fit.lattice.default_families`; with the
        first-party plugins GM, WN, RW, QN, RR).
    max_counts : mapping, optional
        Largest count per family (default: each family's declared ``lattice_copies`` where
        above 1, others 1; with the first-party plugins ``{"GM": 3}``).
    criterion : str
        Registered criterion (``"wvic"``, or a plugin's from the ``stochmod_criteria`` hook).
    weighting : str
        A registered weighting (``"diagonal"``, ``"optimal"``, ``"identity"`` or a plugin's)
        that does not need each model's own fit: Omega, the same for every candidate of a
        signal.
    executor : concurrent.futures.Executor, optional
        Runs the fits through ``executor.submit`` (thread or process pools, a dask client's
        ``get_executor()`` ...). Default: for more than 8 fits (candidates times columns) a
        ProcessPoolExecutor with 2 workers, for fewer a thread of this process, shut down on
        return.
    progress : bool, optional
        Show a tqdm progress bar (None: only when there are more than 8 fits and stderr is
        a terminal).
    rng : int or Generator
        Seed of every fit's multi-start (results reproduce, whatever the executor).
    levels : int, optional
        Number of wavelet levels J (default: all the signal allows).
    names : sequence of str, optional
        Column names for the results (default: the Recording's, else "0", "1", ...).
    robust : bool
        Fit every candidate to the robust wavelet variance (see :func:`stochmod.gmwm`): a few
        outliers no longer call for spurious components; its variances and covariance give
        Omega and V. The diagnostic is ``result.empirical.contamination``.
    efficiency : float
        Gaussian efficiency in (0, 1] of the robust estimator (default 0.6; robust only).
    final_weighting : str, optional
        A registered weighting the selected model is fitted with again after the ranking
        (:func:`refit`), e.g. ``"model"``, whose estimates of the deep-level components (a
        random walk, a slow Gauss-Markov term) are not biased by the diagonal weights'
        correlation with the levels' errors, and whose intervals take the fitted model's
        covariance of the WV; a weighting that needs the signal is refused. The ranking stays
        that of the shared weighting.

    Returns
    -------
    SelectionResult, or list of SelectionResult (one per column) for 2-D input

    Raises
    ------
    InputError, SpecError
        Bad signal, empty candidates, unknown family or criterion, too many parameters.
    """
    scheme = get_weighting(weighting)
    if scheme.needs_fit:
        raise InputError(f"weighting {weighting!r} depends on each model's own fit and cannot be "
                         f"shared by the candidates; choose one of {weighting_names(shared=True)}")
    if final_weighting is not None and get_weighting(final_weighting).needs_signal:
        raise InputError(f"final_weighting {final_weighting!r} needs the signal; the final fit "
                         "has the selection's wavelet variance: choose one of "
                         f"{[n for n in weighting_names() if not get_weighting(n).needs_signal]}")
    crit = _criteria.get_criterion(criterion)
    seed = _base_seed(rng)
    if levels is not None:
        levels = check_positive_int(levels, name="levels", minimum=1)
    options = {"robust": True, "efficiency": check_efficiency(efficiency)} if robust else {}
    prepared: list[_Column] | None = None
    pooled = None
    if is_replicates(x):  # replicates of one sensor model: one selection on their pooled WV
        if freq is None:
            raise InputError("freq (Hz) is required when x is a list of signals")
        freq = check_freq(freq)
        if robust:
            raise InputError("robust=True is not available for replicates (a list of signals): "
                             "the pooled wavelet variance is the classical one")
        pooled = pooled_wv(x, freq, levels)
        cols = ["pooled"] if names is None else [str(n) for n in names]
        if len(cols) != 1:
            raise InputError(f"names has {len(cols)} entries for one pooled column")
        data, single = None, True
        prepared = [_column(pooled.wv, None, scheme, seed, pooled.covariance)]
    else:
        data, freq, cols, single = _signals(x, freq, names)
    if candidates is None:
        families = default_families() if families is None else tuple(families)
        if max_counts is None:
            max_counts = default_max_counts(families)
    models = _as_candidates(candidates, families, max_counts)
    graph = nested_graph(models)
    n_fits = graph.number_of_nodes() * len(cols)

    for name, node in graph.nodes.items():
        if not node["model"].free_mask().any():
            raise SpecError(f"candidate {name} has no free parameter to estimate")

    with single_threaded_blas(), _executor(executor, n_fits) as (pool, local), \
            _progress(n_fits, progress, "select") as bar, \
            concurrent.futures.ThreadPoolExecutor(1) as here:
        if prepared is not None:
            shared = prepared
        elif scheme.needs_signal or not local:
            # Omega needs eq. 17 of each column (in parallel), or the executor is not a local
            # process pool (in-process executors time their calls: stochmod.workflows.fleet)
            shared = [f.result() for f in [
                pool.submit(_prepare, (data[:, k], freq, levels, scheme, seed, options))
                for k in range(len(cols))]]
        else:  # the WV here (tens of ms): no signal sent to a worker and back, and workers
            # forked afterwards inherit its compiled loops instead of loading them again
            shared = [_prepare((data[:, k], freq, levels, scheme, seed, options))
                      for k in range(len(cols))]
        J = shared[0].empirical.wv.size
        for name, node in graph.nodes.items():
            free = int(node["model"].free_mask().sum())
            if free > J:
                raise InputError(f"candidate {name} has {free} free parameters but the signal gives "
                                 f"only {J} wavelet levels")
        if isinstance(pool, concurrent.futures.ProcessPoolExecutor):
            _start_workers(pool)
        # V runs alongside the fits: beside a local process pool, on a thread of this process
        # (its transforms release the GIL; no signal sent to a worker), else on the executor
        covs = [(here if local else pool).submit(_covariance, (data[:, k], sh.empirical, J))
                if sh.covariance is None else None for k, sh in enumerate(shared)]
        try:
            fits = _run_fits(pool, graph, shared, freq, weighting, seed, bar)
        except BaseException:
            for future in covs:
                if future is not None:
                    future.cancel()
            raise
        for k, future in enumerate(covs):
            if future is not None:
                shared[k] = attrs.evolve(shared[k], covariance=future.result())
                fits[k] = {n: f.with_data_covariance(shared[k].covariance) for n, f in fits[k].items()}

    if pooled is not None:  # every fit of the replicates carries their pooling and its test
        fits = [{n: attrs.evolve(f, pooled=pooled) for n, f in fits[0].items()}]
    with single_threaded_blas():  # J x J algebra: one thread is fastest
        results = [_result(cols[k], fits[k], graph, crit, criterion, weighting, shared[k])
                   for k in range(len(cols))]
    if final_weighting is not None:
        results = [refit(r, final_weighting) for r in results]
    return results[0] if single else results


def refit(sel: SelectionResult, weighting: str, best: GMWMResult | None = None
          ) -> SelectionResult:
    """`sel` with its selected model fitted again with `weighting`, from its estimate.

    The fit (:func:`stochmod.gmwm` on the selection's empirical WV, its levels and seed) starts
    from the selected estimate, and a weighting with ``needs_fit`` takes the selected fit's
    model as its pilot; inference uses the selection's V (eq. 17), or the fitted model's for a
    weighting with ``inference = "model"``. The ranking and the candidates' fits are those of
    the shared weighting.

    Parameters
    ----------
    sel : SelectionResult
        A selection.
    weighting : str
        A registered weighting that does not need the signal (``"model"``, ``"bootstrap"``,
        ``"identity"`` ...).
    best : GMWMResult, optional
        The fit to start from, when not ``sel.best`` (a triad's common structure).

    Returns
    -------
    SelectionResult
        With :attr:`~SelectionResult.best` the new fit and
        :attr:`~SelectionResult.final_weighting` set.
    """
    from stochmod.fit.gmwm import gmwm

    start = sel.best if best is None else best
    name = start.model.name
    base = sel.graph.nodes[name]["model"] if name in sel.graph else start.model.freed()
    scheme = get_weighting(weighting)
    fit = gmwm(sel.empirical, base, weighting=weighting, levels=start.levels,
               starts=(start.model,), rng=start.rng_seed, binding="analytic",
               pilot=start if scheme.needs_fit else None)
    if getattr(scheme, "inference", "data") != "model":
        fit = fit.with_data_covariance(sel.wv_covariance).with_null_covariance()
    if start.pooled is not None:
        fit = attrs.evolve(fit, pooled=start.pooled)
    return attrs.evolve(sel, best=fit, final_weighting=weighting)


def _run_fits(pool: Any, graph: nx.DiGraph, shared: list[_Column], freq: float, weighting: str,
              seed: int, bar: Any) -> list[dict[str, GMWMResult]]:
    """Fit every (column, candidate) through ``pool.submit``, each as soon as all its parents
    are fitted (no barrier between generations); results do not depend on completion order."""
    order = {name: i for i, name in enumerate(graph.nodes)}
    fits: list[dict[str, GMWMResult]] = [{} for _ in shared]
    pending: dict[concurrent.futures.Future, tuple[int, str]] = {}

    def submit(k: int, name: str) -> None:
        model = graph.nodes[name]["model"]
        starts, screen = _child_starts(model, [fits[k][p] for p in graph.predecessors(name)],
                                       shared[k].empirical.wv, freq)
        task = _Task(k, name, model.to_spec(), freq, shared[k], weighting,
                     _seed(seed, order[name]), starts, screen)
        pending[pool.submit(_fit_task, task)] = (k, name)

    try:
        for k in range(len(shared)):
            for name in graph.nodes:
                if graph.in_degree(name) == 0:
                    submit(k, name)
        while pending:
            done, _ = concurrent.futures.wait(pending, return_when=concurrent.futures.FIRST_COMPLETED)
            for future in sorted(done, key=lambda f: (pending[f][0], order[pending[f][1]])):
                k, name = pending.pop(future)
                fits[k][name] = future.result()
                if bar is not None:
                    bar.update(1)
                for child in graph.successors(name):
                    if all(p in fits[k] for p in graph.predecessors(child)):
                        submit(k, child)
    except BaseException:
        for future in pending:
            future.cancel()
        raise
    return [{name: f[name] for name in graph.nodes} for f in fits]


def _result(column: str, fits: dict[str, GMWMResult], graph: nx.DiGraph, crit: Any,
            criterion: str, weighting: str, shared: _Column) -> SelectionResult:
    rows = []
    g = graph.copy()
    for name, fit in fits.items():
        value = float(crit(fit))
        jt = fit.jtest
        ok = _criteria.identified(fit)
        rows.append(RankingRow(name, int(fit.free_mask.sum()), float(fit.objective),
                               value - float(fit.objective), value,
                               None if jt is None else float(jt.pvalue), ok))
        g.nodes[name].update(objective=float(fit.objective), criterion=value, identified=ok)
    rows.sort(key=lambda r: (not r.identified, r.criterion, r.n_params, r.model))
    return SelectionResult(column=column, best=fits[rows[0].model], ranking=tuple(rows),
                           fits=dict(fits), graph=g, criterion=criterion, weighting=weighting,
                           empirical=shared.empirical, wv_covariance=shared.covariance)
