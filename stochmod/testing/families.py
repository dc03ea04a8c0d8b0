"""Conformance kit: checks that a process family honours the plugin contract.

A third party writing a family runs the whole kit with::

    from stochmod.testing import check_family
    report = check_family(MyFamily, freq=100.0, rng=0)
    print(report.summary())
    report.raise_if_failed()          # AssertionError listing every failure

Each check is also a public function ``check_<name>(process, freq, *, rng, ...)`` taking a
family instance with values (or a family class, whose :meth:`~stochmod.core.process.Process.example`
is then used), the sampling frequency in Hz and a seed or :class:`numpy.random.Generator`.
A check returns a dict of the figures it measured, raises :class:`AssertionError` with a
precise message when the family is wrong, and :class:`NotApplicable` when it does not apply
(e.g. the PSD integral of a non-stationary family).

The checks (names as in :data:`CHECKS`):

``example``
    ``cls.example(freq)`` exists and returns a fully valued instance of the class.
``round_trips``
    vector <-> from_vector, to_unconstrained <-> from_unconstrained (rel 1e-10),
    transform_jacobian against finite differences, to_spec -> JSON -> model_from_spec.
``bad_values``
    each parameter set to a value outside its domain (-1, 0, nan, inf ...) raises
    :class:`~stochmod.core.errors.DomainError` naming the parameter.
``simulate``
    direct simulation: shape, finiteness, reproducibility under a seed.
``wv_domain``
    the Haar wavelet variance is finite and non-negative (positive unless a real-valued
    parameter is zero) over the whole parameter domain (hypothesis, :func:`strategy_for`).
``wv_monte_carlo``
    the theoretical WV equals the mean of empirical Haar WVs of seeded simulations within
    Monte Carlo error.
``psd_integral``
    the two-sided PSD integrates over (-freq/2, freq/2] to the variance (stationary families).
``wv_fallbacks``
    the family's WV equals the base class's generic fallbacks (exact Haar sum over the
    autocovariance; quadrature of the PSD) where they apply.
``state_space``
    simulations through the state-space block (:func:`stochmod.core.process.simulate_block`) have
    the WV of the direct simulations; feed-through-only blocks carry the variance.
``rediscretisation``
    ``block(k dt)`` equals ``k`` composed steps of ``block(dt)``, and ``block(1/freq)`` equals
    ``discrete_block``.
``wv_jacobian``
    ``wv_jacobian`` against Richardson-extrapolated central differences (rel 1e-5).
``declarations``
    every parameter declares a role (:data:`stochmod.core.params.ROLES`) and the scale role is
    true (doubling the scale parameter multiplies the WV by ``2^d`` at every level, the rule
    selection relies on); ``ordering_key`` is a finite float that depends on the values only;
    ``lattice_copies``/``lattice_rank`` are non-negative integers; ``ieee952`` names only
    coefficients of :data:`stochmod.core.coefficients.COEFFICIENTS`.
``ieee952``
    for each declared coefficient set, ``from_ieee952(to_ieee952(...))`` gives the instance
    back (rel 1e-12), and a single IEEE coefficient (Q, N, K, R) gives the Allan line of the
    reading (``2 wv`` against ``3 Q^2/tau^2``, ``N^2/tau``, ``K^2 tau/3``, ``R^2 tau^2/2`` at
    ``m >= 64``, rel 1e-3). Skipped for families built from no reading.
``wv_rows``
    for a family that declares :class:`~stochmod.core.vectorised_wv.VectorisedWV`: its
    ``haar_wv_rows`` are each row's ``wv`` and ``wv_jacobian`` bit for bit, and its
    ``haar_wv_kernel``, where in force, the rows' digits (WV added to a non-zero start).

Combiners (plugin point ``stochmod_combiners``) are checked by :func:`check_combiner`
(see :mod:`stochmod.testing.combiners`): weights sum to 1, equal inputs give the input back,
permutation invariance, scale equivariance, NaN/inf refused.

Defaults are cheap (the whole kit takes a few seconds on one family); raise ``n_mc``, ``n``
and ``max_examples`` for stronger runs. hypothesis is imported only by the checks that need it.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterable, Mapping
from typing import Any

import attrs
import numpy as np
from scipy import integrate

from stochmod.core.checks import check_freq, check_positive_int
from stochmod.core.coefficients import COEFFICIENTS
from stochmod.testing.combiners import check_combiner
from stochmod.core.errors import DomainError, InputError
from stochmod.core.params import ROLES, get_domain, pacf_to_ar
from stochmod.core.process import Process, as_generator, declares_psd, simulate_block
from stochmod.core.tables import format_number, format_table
from stochmod.core.statespace import StateSpaceBlock, compose_steps
from stochmod.core.theory import wv_from_autocovariance, wv_from_psd
from stochmod.core.vectorised_wv import VectorisedWV, declares_wv_rows, wv_kernel, wv_rows_domains

__all__ = [
    "CHECKS",
    "ConformanceReport",
    "NotApplicable",
    "check_family",
    "strategy_for",
    "check_example",
    "check_round_trips",
    "check_bad_values",
    "check_simulate",
    "check_wv_domain",
    "check_wv_monte_carlo",
    "check_psd_integral",
    "check_wv_fallbacks",
    "check_wv_rows",
    "check_state_space",
    "check_rediscretisation",
    "check_wv_jacobian",
    "check_weighting",
    "check_reader",
    "check_combiner",
    "check_declarations",
    "check_ieee952",
]


class NotApplicable(Exception):
    """Raised by a check that does not apply to a family (the reason is the message)."""


Figures = dict[str, Any]
RngLike = np.random.Generator | int


# ---------------------------------------------------------------------------- helpers
def _overrides(cls: type, name: str) -> bool:
    """Whether the family class `cls` declares its own `name` (overrides the base class's)."""
    return getattr(cls, name) is not getattr(Process, name)


def _family_class(process: Process | type[Process]) -> type[Process]:
    cls = process if isinstance(process, type) else type(process)
    if not issubclass(cls, Process):
        raise InputError(f"expected a Process subclass or instance, got {process!r}")
    return cls


def _instance(process: Process | type[Process], freq: float) -> Process:
    """The instance to check: `process` itself, or its class's example at `freq`."""
    if isinstance(process, type):
        process = _family_class(process).example(freq)
    elif not isinstance(process, Process):
        raise InputError(f"expected a Process subclass or instance, got {process!r}")
    if process.is_free:
        raise InputError(
            f"{process.family} has free parameter(s) {list(process.free_names)}: the kit checks "
            "an instance with values (or pass the class to use its example)"
        )
    return process


def _fmt(x: Any) -> str:
    return np.array2string(np.asarray(x, dtype=float), precision=10, max_line_width=200)


def _assert_close(actual: Any, expected: Any, *, rtol: float, atol: float = 0.0, what: str) -> float:
    """Assert ``|actual - expected| <= atol + rtol |expected|`` elementwise; return the worst
    relative error (relative to ``atol + |expected|``)."""
    a = np.asarray(actual, dtype=np.float64)
    e = np.asarray(expected, dtype=np.float64)
    if a.shape != e.shape:
        raise AssertionError(f"{what}: shape {a.shape} differs from the expected {e.shape}")
    if not np.all(np.isfinite(a)):
        raise AssertionError(f"{what}: non-finite values {_fmt(a)}")
    err = np.abs(a - e)
    bound = atol + rtol * np.abs(e)
    if np.any(err > bound):
        i = np.unravel_index(np.argmax(err - bound), err.shape) if err.ndim else ()
        raise AssertionError(
            f"{what}: {a[i]!r} differs from {e[i]!r} at index {tuple(int(k) for k in i)} "
            f"(|diff| = {err[i]:.3g} > tolerance {bound[i]:.3g}, rtol = {rtol:g}, atol = {atol:.3g})\n"
            f"  got      {_fmt(a)}\n  expected {_fmt(e)}"
        )
    scale = np.where(np.abs(e) > 0, np.abs(e), 1.0) + atol
    return float(np.max(err / scale)) if err.size else 0.0


def _children(rng: RngLike, k: int) -> list[np.random.Generator]:
    return as_generator(rng).spawn(k)


def _eligible_levels(n: int, min_eta: float) -> np.ndarray:
    """Haar levels j whose M_j = n - 2^j + 1 interior coefficients give M_j / 2^j >= min_eta."""
    js = np.arange(1, int(math.log2(n)) + 1)
    ok = (n - 2.0**js + 1) / 2.0**js >= min_eta
    if not ok.any():
        raise InputError(f"n = {n} samples leave no level with M_j / 2^j >= {min_eta}; raise n")
    return js[ok]


def _mc_wv(simulate: Callable[[np.random.Generator], np.ndarray], n_mc: int, levels: int,
           freq: float, rng: RngLike) -> np.ndarray:
    """Empirical Haar WVs (levels 1..`levels`) of `n_mc` seeded simulations, shape (n_mc, levels)."""
    from stochmod.empirical.wavelet_variance import wvar

    out = np.empty((n_mc, levels))
    for r, g in enumerate(_children(rng, n_mc)):
        x = simulate(g)
        if not np.all(np.isfinite(x)):
            raise AssertionError(f"simulation {r} contains non-finite values")
        out[r] = wvar(x, freq, levels=levels).wv
    return out


def _mean_se(samples: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return samples.mean(axis=0), samples.std(axis=0, ddof=1) / math.sqrt(samples.shape[0])



# ---------------------------------------------------------------------------- strategies
def strategy_for(process: Process | type[Process], *, freq: float = 100.0, decades: float = 8.0) -> Any:
    """A hypothesis strategy drawing instances of a family over its whole parameter domain.

    Parameters
    ----------
    process : Process or Process subclass
        The family; an instance fixes the structure (e.g. AR's order); a class uses ``cls()``
        or, when that needs arguments, ``cls.example(freq)``.
    freq : float
        Sampling frequency in Hz, used only to build the example of a structured class.
    decades : float
        Positive values are drawn log-uniformly in ``[10^-decades, 10^decades]`` (in the
        parameter's own unit); real values as 0 or ``+-`` that range.

    Returns
    -------
    hypothesis.strategies.SearchStrategy
        Instances with every parameter set. Domains: ``positive`` (log-uniform over many
        decades), ``correlation`` (-1, 1), ``unit_interval`` (0, 1), ``stationary_ar`` (via
        partial autocorrelations in (-1, 1)^p), ``real``; other registered domains via their
        inverse transform of reals in [-20, 20].
    """
    from hypothesis import strategies as st

    if isinstance(process, type):
        cls = _family_class(process)
        try:
            base = cls()
        except (TypeError, ValueError):
            base = cls.example(freq)
    else:
        base = process
    base = base.freed()

    def scalar(domain: str) -> Any:
        if domain == "positive":
            return st.floats(-decades, decades).map(lambda e: 10.0**e)
        if domain == "real":
            mag = st.floats(-decades, decades).map(lambda e: 10.0**e)
            return st.one_of(st.just(0.0), mag, mag.map(lambda v: -v))
        if domain == "correlation":
            return st.floats(-1.0, 1.0, exclude_min=True, exclude_max=True, allow_subnormal=False)
        if domain == "unit_interval":
            return st.floats(0.0, 1.0, exclude_min=True, exclude_max=True, allow_subnormal=False)
        dom = get_domain(domain)
        return st.floats(-20.0, 20.0).map(lambda t: float(np.atleast_1d(dom.from_unconstrained(t))[0]))

    def parameter(spec: Any) -> Any:
        dom = get_domain(spec.domain)
        if spec.domain == "stationary_ar":
            r = st.floats(-1.0, 1.0, exclude_min=True, exclude_max=True, allow_subnormal=False)
            strat = st.lists(r, min_size=spec.size, max_size=spec.size).map(pacf_to_ar)
        elif spec.domain in ("positive", "real", "correlation", "unit_interval"):
            s = scalar(spec.domain)
            strat = s if spec.size == 1 else st.lists(s, min_size=spec.size, max_size=spec.size)
        else:
            t = st.lists(st.floats(-20.0, 20.0), min_size=spec.size, max_size=spec.size)
            strat = t.map(lambda v: np.atleast_1d(dom.from_unconstrained(np.asarray(v))))
            if spec.size == 1:
                strat = strat.map(lambda v: float(v[0]))
        return strat.filter(lambda v: dom.contains(np.asarray(v, dtype=float)))

    names = {spec.name: parameter(spec) for spec in base.parameters()}
    return st.fixed_dictionaries(names).map(lambda values: base.with_values(**values))


# ---------------------------------------------------------------------------- checks
def check_example(process: Process | type[Process], freq: float = 100.0, *, rng: RngLike = 0) -> Figures:
    """``cls.example(freq)`` returns a fully valued instance of the family's class."""
    freq = check_freq(freq)
    cls = _family_class(process)
    try:
        ex = cls.example(freq)
    except NotImplementedError as exc:
        raise AssertionError(f"{cls.family or cls.__name__} has no example(freq) classmethod: {exc}") from None
    if not isinstance(ex, cls):
        raise AssertionError(f"{cls.__name__}.example({freq}) returned {ex!r}, not a {cls.__name__}")
    if ex.is_free:
        raise AssertionError(f"{cls.__name__}.example({freq}) leaves {list(ex.free_names)} free")
    if not cls.family:
        raise AssertionError(f"{cls.__name__} sets no `family` name")
    return {"example": repr(ex)}


def check_round_trips(process: Process | type[Process], freq: float = 100.0, *, rng: RngLike = 0) -> Figures:
    """vector/from_vector, to/from_unconstrained (rel 1e-10), transform_jacobian against
    central differences (rel 1e-6), and to_spec -> JSON -> :func:`stochmod.model_from_spec`."""
    from stochmod.plugin.spec import model_from_spec

    freq = check_freq(freq)
    p = _instance(process, freq)
    vec = p.vector()
    if vec.shape != (p.n_params,):
        raise AssertionError(f"{p!r}.vector() has shape {vec.shape}, expected ({p.n_params},)")
    back = p.from_vector(vec)
    _assert_close(back.vector(), vec, rtol=0.0, what=f"{p.family}: from_vector(vector())")
    if back != p:
        raise AssertionError(f"{p.family}: from_vector(vector()) = {back!r} is not equal to {p!r}")
    theta = p.to_unconstrained()
    if theta.shape != vec.shape or not np.all(np.isfinite(theta)):
        raise AssertionError(f"{p.family}: to_unconstrained() = {_fmt(theta)} for vector {_fmt(vec)}")
    unc = _assert_close(p.from_unconstrained(theta).vector(), vec, rtol=1e-10, atol=1e-300,
                        what=f"{p.family}: from_unconstrained(to_unconstrained())")
    J = p.transform_jacobian(theta)
    cols = []
    for i in range(theta.size):
        h = 1e-5 * max(1.0, abs(theta[i]))
        e = np.zeros_like(theta)
        e[i] = h
        cols.append((p.from_unconstrained(theta + e).vector() - p.from_unconstrained(theta - e).vector())
                    / (2 * h))
    fd = np.column_stack(cols) if cols else np.zeros((0, 0))
    jac = _assert_close(J, fd, rtol=1e-6, atol=1e-9 * max(np.max(np.abs(fd), initial=0.0), 1e-300),
                        what=f"{p.family}: transform_jacobian vs central differences")
    spec = p.to_spec()
    try:
        text = json.dumps({"processes": [spec]}, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise AssertionError(f"{p.family}: to_spec() = {spec!r} is not strict JSON: {exc}") from None
    model = model_from_spec(json.loads(text), freq)
    if len(model.processes) != 1:
        raise AssertionError(f"{p.family}: model_from_spec(to_spec()) gave {len(model.processes)} processes")
    q = model.processes[0]
    if type(q) is not type(p):
        raise AssertionError(f"{p.family}: model_from_spec(to_spec()) built a {type(q).__name__}")
    spec_err = _assert_close(q.vector(), vec, rtol=1e-15, what=f"{p.family}: model_from_spec(to_spec())")
    if q.structure() != p.structure():
        raise AssertionError(f"{p.family}: structure {q.structure()} after the spec round trip, "
                             f"expected {p.structure()}")
    return {"unconstrained_rel_error": unc, "jacobian_rel_error": jac, "spec_rel_error": spec_err,
            "spec": text}


_BAD_VALUES: dict[str, tuple[float, ...]] = {
    "positive": (-1.0, 0.0, math.nan, math.inf),
    "real": (math.nan, math.inf),
    "correlation": (1.0, -1.0, 1.5, math.nan),
    "unit_interval": (0.0, 1.0, -0.5, math.nan),
}


def _bad_values(domain: str, size: int, good: np.ndarray) -> list[Any]:
    if domain == "stationary_ar":
        unit_root = np.zeros(size)
        unit_root[0] = 1.0
        return [unit_root, np.full(size, math.nan)]
    out = []
    for bad in _BAD_VALUES.get(domain, (math.nan,)):
        if size == 1:
            out.append(bad)
        else:
            v = np.array(good, dtype=float)
            v[0] = bad
            out.append(v)
    return out


def check_bad_values(process: Process | type[Process], freq: float = 100.0, *, rng: RngLike = 0) -> Figures:
    """Each parameter set to a value outside its domain raises DomainError naming it.

    Bad values: positive -1, 0, nan, inf; correlation +-1, 1.5, nan; unit_interval 0, 1,
    -0.5, nan; real nan, inf; stationary_ar a unit root and nan (vector parameters get the
    bad value in their first element).
    """
    p = _instance(process, check_freq(freq))
    tried = 0
    for spec in p.parameters():
        good = np.atleast_1d(np.asarray(getattr(p, spec.name), dtype=float))
        for bad in _bad_values(spec.domain, spec.size, good):
            tried += 1
            try:
                made = p.with_values(**{spec.name: bad})
            except DomainError as exc:
                if spec.name not in str(exc):
                    raise AssertionError(
                        f"{p.family}: the DomainError for {spec.name} = {bad!r} does not name the "
                        f"parameter: {exc}"
                    ) from None
                continue
            except Exception as exc:  # noqa: BLE001 - any other type is the failure reported
                raise AssertionError(
                    f"{p.family}: {spec.name} = {bad!r} ({spec.domain}) raised {type(exc).__name__}: {exc}, "
                    "expected stochmod.core.errors.DomainError"
                ) from None
            raise AssertionError(
                f"{p.family}: {spec.name} = {bad!r} is outside the '{spec.domain}' domain but was "
                f"accepted ({made!r}); expected stochmod.core.errors.DomainError"
            )
    return {"bad_values_tried": tried}


def check_simulate(process: Process | type[Process], freq: float = 100.0, *, rng: RngLike = 0,
                   n: int = 1000) -> Figures:
    """``simulate(n, freq, rng)``: float64 shape (n,), finite, identical under the same seed
    (integer seed and Generator alike), and n = 1 works."""
    freq = check_freq(freq)
    p = _instance(process, freq)
    seed = int(as_generator(rng).integers(2**31))
    x = p.simulate(n, freq, seed)
    if not (isinstance(x, np.ndarray) and x.shape == (n,) and x.dtype == np.float64):
        raise AssertionError(f"{p.family}.simulate({n}, ...) returned {type(x).__name__} "
                             f"{getattr(x, 'shape', '')} {getattr(x, 'dtype', '')}, expected float64 ({n},)")
    if not np.all(np.isfinite(x)):
        raise AssertionError(f"{p.family}.simulate returned non-finite values")
    again = p.simulate(n, freq, np.random.default_rng(seed))
    if not np.array_equal(x, again):
        raise AssertionError(f"{p.family}.simulate is not reproducible: seed {seed} and "
                             f"default_rng({seed}) give different paths")
    one = p.simulate(1, freq, seed)
    if np.shape(one) != (1,):
        raise AssertionError(f"{p.family}.simulate(1, ...) has shape {np.shape(one)}")
    return {"n": n, "std": float(np.std(x))}


def check_wv_domain(process: Process | type[Process], freq: float = 100.0, *, rng: RngLike = 0,
                    max_examples: int = 25, levels: int = 16, decades: float = 8.0) -> Figures:
    """Haar WV at levels 1..`levels` is finite and >= 0 for values drawn over the whole domain
    (strictly > 0 unless a real-valued parameter is 0); `max_examples` hypothesis examples."""
    from hypothesis import HealthCheck, given, seed, settings

    freq = check_freq(freq)
    max_examples = check_positive_int(max_examples, name="max_examples")
    base = process if isinstance(process, Process) else _family_class(process)
    strategy = strategy_for(base, freq=freq, decades=decades)
    seen = {"examples": 0, "min_wv": math.inf, "max_wv": 0.0}

    @seed(int(as_generator(rng).integers(2**31)))
    @settings(max_examples=max_examples, deadline=None, database=None, derandomize=False,
              suppress_health_check=list(HealthCheck))
    @given(strategy)
    def run(p: Process) -> None:
        wv = np.asarray(p.wv(levels, freq), dtype=float)
        if wv.shape != (levels,):
            raise AssertionError(f"{p!r}.wv({levels}, {freq}) has shape {wv.shape}")
        if not np.all(np.isfinite(wv)):
            raise AssertionError(f"{p!r}.wv({levels}, {freq}) is not finite: {_fmt(wv)}")
        if np.any(wv < 0):
            raise AssertionError(f"{p!r}.wv({levels}, {freq}) is negative: {_fmt(wv)}")
        zero_real = any(s.domain == "real" and np.any(np.asarray(getattr(p, s.name)) == 0)
                        for s in p.parameters())
        if not zero_real and np.any(wv == 0):
            raise AssertionError(f"{p!r}.wv({levels}, {freq}) has zeros: {_fmt(wv)}")
        seen["examples"] += 1
        seen["min_wv"] = min(seen["min_wv"], float(wv.min()))
        seen["max_wv"] = max(seen["max_wv"], float(wv.max()))

    run()
    return {**seen, "levels": levels}


def check_wv_monte_carlo(process: Process | type[Process], freq: float = 100.0, *, rng: RngLike = 0,
                         n_mc: int = 20, n: int = 2**14, z: float = 4.5, rel: float = 1e-6,
                         min_eta: float = 8.0) -> Figures:
    """Theoretical Haar WV against the mean of `n_mc` empirical WVs of simulations of `n` samples.

    Compared level by level where ``M_j / 2^j >= min_eta`` (enough coefficients):
    ``|mean - wv| <= z SE + rel wv`` with SE the Monte Carlo standard error of the mean.
    The empirical WV is :func:`stochmod.empirical.wavelet_variance.wvar` (interior, unbiased).
    """
    freq = check_freq(freq)
    p = _instance(process, freq)
    n_mc = check_positive_int(n_mc, name="n_mc", minimum=2)
    n = check_positive_int(n, name="n", minimum=4)
    js = _eligible_levels(n, min_eta)
    theory = np.asarray(p.wv(int(js[-1]), freq), dtype=float)
    emp = _mc_wv(lambda g: p.simulate(n, freq, g), n_mc, int(js[-1]), freq, rng)
    mean, se = _mean_se(emp)
    bound = z * se + rel * np.abs(theory)
    zs = np.abs(mean - theory) / np.where(se > 0, se, np.inf)
    bad = np.abs(mean - theory) > bound
    if bad.any():
        lines = [f"  j={j}: theory {t:.6g}, MC mean {m:.6g} +- {s:.3g} (|z| = {zz:.2f})"
                 for j, t, m, s, zz, b in zip(js, theory, mean, se, zs, bad) if b]
        raise AssertionError(
            f"{p!r}: theoretical WV disagrees with the mean of {n_mc} simulations of {n} samples "
            f"at {int(bad.sum())} level(s) (tolerance {z} SE + {rel:g} rel):\n" + "\n".join(lines)
        )
    return {"levels": int(js[-1]), "n_mc": n_mc, "n": n, "max_abs_z": float(np.max(zs[np.isfinite(zs)],
                                                                                     initial=0.0))}


def _variance(p: Process, freq: float) -> float:
    if not p.stationary:
        raise NotApplicable(f"{p.family} is not stationary: its PSD does not integrate to a variance")
    if not _overrides(type(p), "autocovariance"):
        raise NotApplicable(f"{p.family} declares no autocovariance")
    return float(np.asarray(p.autocovariance(np.array([0]), freq), dtype=float).reshape(-1)[0])


def _psd_or_skip(p: Process, f: np.ndarray, freq: float) -> np.ndarray:
    if not declares_psd(p):
        raise NotApplicable(f"{p.family} declares no PSD (psd = None)")
    return np.asarray(p.psd(f, freq), dtype=float)


def check_psd_integral(process: Process | type[Process], freq: float = 100.0, *, rng: RngLike = 0,
                       rtol: float = 1e-6) -> Figures:
    """Two-sided PSD (u^2/Hz) integrated over (-freq/2, freq/2] equals ``autocovariance(0)``.

    Adaptive quadrature (scipy ``quad``) on panels split at the family's ``psd_breakpoints``
    and geometrically towards f = 0; the PSD must be even (checked on a grid).
    """
    freq = check_freq(freq)
    p = _instance(process, freq)
    var = _variance(p, freq)
    grid = np.linspace(0.0, freq / 2, 257)[1:]
    s = _psd_or_skip(p, grid, freq)
    if s.shape != grid.shape or not np.all(np.isfinite(s)) or np.any(s < 0):
        raise AssertionError(f"{p!r}.psd is not finite and >= 0 on (0, freq/2]: {_fmt(s[:8])} ...")
    _assert_close(_psd_or_skip(p, -grid[:-1], freq), s[:-1], rtol=1e-12, atol=1e-300,
                  what=f"{p.family}: PSD symmetry S(-f) = S(f)")
    half = freq / 2
    edges = {0.0, half} | {half * 2.0**-k for k in range(1, 60)}
    edges |= {float(b) for b in p.psd_breakpoints(freq) if 0 < abs(b) < half}
    edges_arr = np.array(sorted(abs(e) for e in edges))

    def one(f: float) -> float:
        return float(np.asarray(p.psd(np.array([f]), freq), dtype=float)[0])

    total = sum(integrate.quad(one, a, b, epsabs=0.0, epsrel=1e-12, limit=200)[0]
                for a, b in zip(edges_arr[:-1], edges_arr[1:]))
    total *= 2.0
    err = _assert_close(total, var, rtol=rtol, what=f"{p!r}: integral of the two-sided PSD over "
                        "(-freq/2, freq/2] vs autocovariance(0)")
    return {"integral": total, "variance": var, "rel_error": err}


def _psd_wv_converges(p: Process, freq: float) -> None:
    """Raise NotApplicable unless ``int |H_j(f)|^2 S(f) df`` converges at f = 0.

    Near 0 the Haar gain is ``~ (pi f m / freq)^2``, so the integrand behaves like ``f^2 S(f)``;
    the integral converges when ``f^3 S(f) -> 0`` (checked over ten octaves far below the
    sampling frequency). A nominal PSD such as the rate ramp's ``1/f^3`` fails this test.
    """
    f = freq * np.array([2.0**-30, 2.0**-40])
    s = _psd_or_skip(p, f, freq)
    v = f**3 * s
    if not (np.all(np.isfinite(v)) and v[1] <= 0.1 * v[0]):
        raise NotApplicable(f"the wavelet variance integral of {p.family}'s PSD diverges at f = 0 "
                            f"(f^3 S(f) does not vanish: {_fmt(v)})")


def check_wv_fallbacks(process: Process | type[Process], freq: float = 100.0, *, rng: RngLike = 0,
                       levels: int = 10, rtol: float = 1e-6) -> Figures:
    """``wv`` equals the generic fallbacks of the base class where they apply (rel `rtol`):
    :func:`stochmod.core.theory.wv_from_autocovariance` (stationary families with an
    autocovariance) and :func:`stochmod.core.theory.wv_from_psd` (families with a PSD)."""
    freq = check_freq(freq)
    p = _instance(process, freq)
    wv = np.asarray(p.wv(levels, freq), dtype=float)
    atol = 1e-12 * float(np.max(np.abs(wv), initial=0.0))
    figures: Figures = {"levels": levels}
    try:
        _variance(p, freq)
    except NotApplicable as exc:
        figures["autocovariance"] = f"skipped: {exc}"
    else:
        ref = wv_from_autocovariance(lambda lags: p.autocovariance(lags, freq), levels)
        figures["autocovariance_rel_error"] = _assert_close(
            wv, ref, rtol=rtol, atol=atol, what=f"{p!r}: wv vs the exact Haar sum over the autocovariance")
    try:
        _psd_wv_converges(p, freq)
    except NotApplicable as exc:
        figures["psd"] = f"skipped: {exc}"
    else:
        ref = wv_from_psd(lambda f: p.psd(f, freq), levels, freq, breakpoints=p.psd_breakpoints(freq))
        figures["psd_rel_error"] = _assert_close(
            wv, ref, rtol=rtol, atol=atol, what=f"{p!r}: wv vs the quadrature of |H_j|^2 S over the PSD")
    reasons = [v[len("skipped: "):] for v in figures.values() if isinstance(v, str)]
    if len(reasons) == 2:
        raise NotApplicable("; ".join(reasons))
    return figures


def check_state_space(process: Process | type[Process], freq: float = 100.0, *, rng: RngLike = 0,
                      n_mc: int = 20, n: int = 2**12, z: float = 4.5, rel: float = 1e-6,
                      min_eta: float = 8.0) -> Figures:
    """Simulations through ``block(1/freq)`` match the direct ``simulate`` within MC error.

    With states: the mean empirical Haar WVs of `n_mc` simulations by
    :func:`stochmod.core.process.simulate_block` and by ``simulate`` agree level by level within
    ``z`` combined standard errors + ``rel``. Feed-through only (no states): the white
    variance equals ``autocovariance(0)`` (rel 1e-10).
    """
    freq = check_freq(freq)
    p = _instance(process, freq)
    block = p.block(1.0 / freq, freq)
    if block.n_states == 0:
        var = _variance(p, freq)
        err = _assert_close(block.white_var, var, rtol=1e-10,
                            what=f"{p!r}: feed-through white variance vs autocovariance(0)")
        return {"n_states": 0, "white_var": block.white_var, "rel_error": err}
    n_mc = check_positive_int(n_mc, name="n_mc", minimum=2)
    n = check_positive_int(n, name="n", minimum=4)
    js = _eligible_levels(n, min_eta)
    g_ss, g_direct = _children(rng, 2)
    ss = _mc_wv(lambda g: simulate_block(block, n, g), n_mc, int(js[-1]), freq, g_ss)
    direct = _mc_wv(lambda g: p.simulate(n, freq, g), n_mc, int(js[-1]), freq, g_direct)
    (m1, s1), (m2, s2) = _mean_se(ss), _mean_se(direct)
    se = np.hypot(s1, s2)
    diff = np.abs(m1 - m2)
    bad = diff > z * se + rel * np.abs(m2)
    zs = diff / np.where(se > 0, se, np.inf)
    if bad.any():
        lines = [f"  j={j}: state space {a:.6g} +- {sa:.3g}, direct {b:.6g} +- {sb:.3g} (|z| = {zz:.2f})"
                 for j, a, sa, b, sb, zz, k in zip(js, m1, s1, m2, s2, zs, bad) if k]
        raise AssertionError(
            f"{p!r}: state-space simulations disagree with the direct simulation (mean Haar WV of "
            f"{n_mc} runs of {n} samples each, tolerance {z} SE):\n" + "\n".join(lines)
        )
    return {"n_states": block.n_states, "levels": int(js[-1]), "n_mc": n_mc, "n": n,
            "max_abs_z": float(np.max(zs[np.isfinite(zs)], initial=0.0))}


def _compare_blocks(a: StateSpaceBlock, b: StateSpaceBlock, what: str, rtol: float = 1e-9) -> float:
    if a.state_names != b.state_names:
        raise AssertionError(f"{what}: state names {a.state_names} vs {b.state_names}")
    worst = 0.0
    for name in ("Phi", "Q", "P0", "H"):
        x, y = getattr(a, name), getattr(b, name)
        atol = 1e-12 * max(float(np.max(np.abs(y), initial=0.0)), 1e-300)
        worst = max(worst, _assert_close(x, y, rtol=rtol, atol=atol, what=f"{what}: {name}"))
    _assert_close(a.white_var, b.white_var, rtol=rtol, what=f"{what}: white_var")
    return worst


def check_rediscretisation(process: Process | type[Process], freq: float = 100.0, *, rng: RngLike = 0,
                           steps: Iterable[int] = (2, 3, 7), rtol: float = 1e-9) -> Figures:
    """``block(k/freq)`` equals ``k`` composed steps of ``block(1/freq)`` (Phi and Q, rel 1e-9)
    for k in `steps`, and ``block(1/freq)`` equals ``discrete_block(freq)``."""
    freq = check_freq(freq)
    p = _instance(process, freq)
    dt = 1.0 / freq
    one = p.block(dt, freq)
    if one.n_states == 0:
        raise NotApplicable(f"{p.family} is feed-through only (no states to re-discretise)")
    worst = _compare_blocks(one, p.discrete_block(freq), f"{p!r}: block(1/freq) vs discrete_block")
    for k in steps:
        many = p.block(k * dt, freq)
        if not math.isclose(many.dt, k * dt, rel_tol=1e-12):
            raise AssertionError(f"{p!r}: block({k}/freq).dt = {many.dt}, expected {k * dt}")
        Phi, Q = compose_steps(one.Phi, one.Q, k)
        composed = attrs.evolve(one, Phi=Phi, Q=Q, dt=k * dt)
        worst = max(worst, _compare_blocks(many, composed, f"{p!r}: block({k}/freq) vs {k} composed steps",
                                           rtol))
    return {"n_states": one.n_states, "steps": list(steps), "max_rel_error": worst}


def _richardson_column(p: Process, vec: np.ndarray, i: int, levels: int, freq: float,
                       h: float) -> np.ndarray:
    def wv_at(delta: float) -> np.ndarray:
        v = vec.copy()
        v[i] += delta
        return np.asarray(p.from_vector(v).wv(levels, freq), dtype=float)

    try:
        d1 = (wv_at(h) - wv_at(-h)) / (2 * h)
        d2 = (wv_at(h / 2) - wv_at(-h / 2)) / h
        return (4 * d2 - d1) / 3
    except DomainError:  # at a domain edge: second-order one-sided differences
        s = 1.0 if vec[i] > 0 or _stays(p, vec, i, h) else -1.0
        f0, f1, f2 = wv_at(0.0), wv_at(s * h / 2), wv_at(s * h)
        return s * (-3 * f0 + 4 * f1 - f2) / h


def _stays(p: Process, vec: np.ndarray, i: int, h: float) -> bool:
    v = vec.copy()
    v[i] += h
    try:
        p.from_vector(v)
    except DomainError:
        return False
    return True


def check_wv_jacobian(process: Process | type[Process], freq: float = 100.0, *, rng: RngLike = 0,
                      levels: int = 12, rtol: float = 1e-5) -> Figures:
    """``wv_jacobian(levels, freq)`` (shape (levels, n_params)) against Richardson-extrapolated
    central differences with relative steps 1e-3; tolerance ``rtol (|D| + 1e-2 |wv_j| / |v_i|)``."""
    freq = check_freq(freq)
    p = _instance(process, freq)
    J = np.asarray(p.wv_jacobian(levels, freq), dtype=float)
    vec = p.vector()
    if J.shape != (levels, vec.size):
        raise AssertionError(f"{p!r}.wv_jacobian({levels}, ...) has shape {J.shape}, "
                             f"expected {(levels, vec.size)}")
    scale = np.maximum(np.abs(vec), 1e-3)
    fd = np.column_stack([_richardson_column(p, vec, i, levels, freq, 1e-3 * scale[i])
                          for i in range(vec.size)])
    wv = np.abs(np.asarray(p.wv(levels, freq), dtype=float))
    norm = np.maximum(np.abs(fd) + 1e-2 * wv[:, None] / scale[None, :], 1e-300)
    tol = rtol * norm
    err = np.abs(J - fd)
    if not np.all(np.isfinite(J)) or np.any(err > tol):
        j, i = np.unravel_index(np.argmax(np.where(np.isfinite(err), err - tol, np.inf)), err.shape)
        raise AssertionError(
            f"{p!r}: wv_jacobian[{j}, {i}] (level {j + 1}, d/d {i}-th parameter) = {J[j, i]!r}, "
            f"finite differences give {fd[j, i]!r} (|diff| {err[j, i]:.3g} > {tol[j, i]:.3g})"
        )
    return {"levels": levels, "analytic": _overrides(type(p), "wv_jacobian"),
            "max_rel_error": float(np.max(err / norm))}


def check_wv_rows(process: Process | type[Process], freq: float = 100.0, *, rng: RngLike = 0,
                  levels: int = 12, rows: int = 16) -> Figures:
    """A family that declares the vectorised-WV protocol
    (:class:`~stochmod.core.vectorised_wv.VectorisedWV`) gives by its ``haar_wv_rows``, row by
    row and bit for bit, the ``wv(levels, freq)`` and ``wv_jacobian(levels, freq)`` of the
    process each row builds, and by its ``haar_wv_kernel``, where it has one in force, the
    rows' digits again (the contract's rule: the GMWM binding uses them in place of Process
    objects). The rows are the example and `rows - 1` points drawn around it in the
    unconstrained space (sd 2). Not applicable when the family does not declare the protocol,
    or inherits rows that are not in force (a subclass that changes ``wv`` or
    ``wv_jacobian``: :func:`~stochmod.core.vectorised_wv.declares_wv_rows`)."""
    freq = check_freq(freq)
    p = _instance(process, freq)
    if not isinstance(p, VectorisedWV):
        raise NotApplicable("the family does not declare the vectorised-WV protocol "
                            "(VectorisedWV): it is evaluated through Process objects")
    if not declares_wv_rows(type(p)):
        raise NotApplicable("the family changes wv or wv_jacobian below the class that defines "
                            "its haar_wv_rows: those rows are not in force")
    gen = as_generator(rng)
    theta = p.to_unconstrained()
    points = [p] + [p.from_unconstrained(theta + 2.0 * gen.standard_normal(theta.size))
                    for _ in range(rows - 1)]
    values = np.array([q.vector() for q in points])
    wv, jac = p.haar_wv_rows(values, levels, freq)
    wv, jac = np.asarray(wv), np.asarray(jac)
    if wv.shape != (rows, levels) or jac.shape != (rows, levels, values.shape[1]):
        raise AssertionError(f"{p!r}.haar_wv_rows gave shapes {wv.shape} and {jac.shape}, "
                             f"expected {(rows, levels)} and {(rows, levels, values.shape[1])}")
    for k, q in enumerate(points):
        for got, want, what in ((wv[k], q.wv(levels, freq), "wv"),
                                (jac[k], q.wv_jacobian(levels, freq), "wv_jacobian")):
            if not np.array_equal(got, np.asarray(want, dtype=float)):
                raise AssertionError(f"{p!r}.haar_wv_rows row {k} ({q!r}) differs from its "
                                     f"{what}: max |diff| {np.max(np.abs(got - want)):.3g}")
    return {"levels": levels, "rows": rows, "binding": wv_rows_domains(type(p)) is not None,
            "kernel_rows": _check_wv_kernel(type(p), values, wv, jac, levels, freq)}


def _check_wv_kernel(cls: type[Process], values: np.ndarray, wv: np.ndarray, jac: np.ndarray,
                     levels: int, freq: float) -> int:
    """The family's :attr:`~stochmod.core.vectorised_wv.VectorisedWV.haar_wv_kernel`, where it applies (returns
    True), adds row k's WV to what `wv` holds and writes its Jacobian, bit for bit the rows'
    `wv[k]` and `jac[k]` (the contract: the GMWM optimizer sums the kernels in place of the
    rows). The WV is added to a non-zero start to check that it is added. Returns how many
    rows the kernel took (0 without a kernel)."""
    kernel = wv_kernel(cls)
    if kernel is None:
        return 0
    m = 2.0 ** np.arange(levels)
    m.flags.writeable = False
    start = np.linspace(1.0, 2.0, levels)
    taken = 0
    for k, row in enumerate(values):
        got_wv, got_jac = start.copy(), np.full((levels, row.size), np.nan)
        if not kernel(row.copy(), m, freq, got_wv, got_jac):
            continue
        taken += 1
        for got, want, what in ((got_wv, start + wv[k], "WV added to the start"),
                                (got_jac, jac[k], "Jacobian")):
            if not np.array_equal(got, want):
                raise AssertionError(f"{cls.__name__}.haar_wv_kernel at row {k} ({row!r}) "
                                     f"differs from haar_wv_rows in its {what}: max |diff| "
                                     f"{np.max(np.abs(got - want)):.3g}")
    return taken


def check_declarations(process: Process | type[Process], freq: float = 100.0, *,
                       rng: RngLike = 0) -> Figures:
    """Roles on every parameter and a true scale role; a finite, value-only ordering key;
    valid lattice declarations and coefficient names."""
    freq = check_freq(freq)
    p = _instance(process, freq)
    cls = type(p)
    missing = [s.name for s in p.parameters() if s.role not in ROLES]
    if missing:
        raise AssertionError(f"{p.family}: parameter(s) {missing} declare no role; give "
                             f"Parameter(..., role=...) one of {list(ROLES)}")
    figures: Figures = {}
    scale = p.scale_parameter()
    if scale is not None:
        spec, power = scale
        levels = 10
        base = np.asarray(p.wv(levels, freq), float)
        doubled = np.asarray(p.with_values(**{spec.name: 2.0 * getattr(p, spec.name)}).wv(levels, freq),
                             float)
        figures["scale_rel_error"] = _assert_close(
            doubled, 2.0**power * base, rtol=1e-9, atol=1e-300,
            what=(f"{p.family}: wv with {spec.name} doubled vs 2^{power} wv (role "
                  f"{spec.role!r} says the WV is proportional to {spec.name}^{power})"))
        figures["scale_power"] = power
    key = p.ordering_key()
    if not (isinstance(key, (float, int, np.floating)) and math.isfinite(key)):
        raise AssertionError(f"{p.family}: ordering_key() = {key!r} is not a finite number")
    again = p.from_vector(p.vector()).ordering_key()
    if again != key:
        raise AssertionError(f"{p.family}: ordering_key() changed from {key!r} to {again!r} on a "
                             "copy with the same values")
    figures["ordering_key"] = float(key)
    for name in ("lattice_copies", "lattice_rank"):
        value = getattr(cls, name)
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise AssertionError(f"{p.family}: {name} = {value!r} must be a non-negative int")
    figures["lattice_copies"] = cls.lattice_copies
    bad = [n for names in cls.ieee952 for n in names if n not in COEFFICIENTS]
    if bad:
        raise AssertionError(f"{p.family}: ieee952 names {bad}, not coefficients of "
                             f"stochmod.core.coefficients.COEFFICIENTS {list(COEFFICIENTS)}")
    return figures


#: The Allan-variance line of a single IEEE 952 coefficient c at tau (s) (the reading's table).
_ALLAN_LINES: dict[str, Callable[[float, np.ndarray], np.ndarray]] = {
    "Q": lambda c, tau: 3.0 * c**2 / tau**2,
    "N": lambda c, tau: c**2 / tau,
    "K": lambda c, tau: c**2 * tau / 3.0,
    "R": lambda c, tau: c**2 * tau**2 / 2.0,
}


def check_ieee952(process: Process | type[Process], freq: float = 100.0, *,
                  rng: RngLike = 0) -> Figures:
    """``from_ieee952(to_ieee952())`` round trips for every declared set; single IEEE
    coefficients give the reading's Allan line (``2 wv`` at m >= 64, rel 1e-3)."""
    freq = check_freq(freq)
    p = _instance(process, freq)
    cls = type(p)
    if not cls.ieee952:
        raise NotApplicable(f"{p.family} is built from no classical-reading coefficients")
    figures: Figures = {}
    for names in cls.ieee952:
        coefs = p.to_ieee952(freq, names)
        if set(coefs) != set(names):
            raise AssertionError(f"{p.family}: to_ieee952({names}) gave {sorted(coefs)}")
        back = cls.from_ieee952(coefs, freq)
        if type(back) is not cls:
            raise AssertionError(f"{p.family}: from_ieee952 built a {type(back).__name__}")
        label = "+".join(names)
        figures[f"{label}_rel_error"] = _assert_close(
            back.vector(), p.vector(), rtol=1e-12, atol=1e-300,
            what=f"{p.family}: from_ieee952(to_ieee952({names}))")
        if len(names) == 1 and names[0] in _ALLAN_LINES:
            levels = 14
            m = 2.0 ** np.arange(levels)
            deep = m >= 64
            tau = m[deep] / freq
            line = _ALLAN_LINES[names[0]](float(coefs[names[0]]), tau)
            av = 2.0 * np.asarray(p.wv(levels, freq), float)[deep]
            figures[f"{label}_line_rel_error"] = _assert_close(
                av, line, rtol=1e-3, atol=0.0,
                what=f"{p.family}: Allan variance (2 wv) vs the {names[0]} line of the reading")
    return figures


# ---------------------------------------------------------------------------- the kit
#: Check name -> (function, options it accepts from :func:`check_family`).
CHECKS: Mapping[str, tuple[Callable[..., Figures], tuple[str, ...]]] = {
    "example": (check_example, ()),
    "round_trips": (check_round_trips, ()),
    "bad_values": (check_bad_values, ()),
    "simulate": (check_simulate, ()),
    "wv_domain": (check_wv_domain, ("max_examples",)),
    "wv_monte_carlo": (check_wv_monte_carlo, ("n_mc", "n")),
    "psd_integral": (check_psd_integral, ()),
    "wv_fallbacks": (check_wv_fallbacks, ()),
    "state_space": (check_state_space, ("n_mc", "n_ss")),
    "rediscretisation": (check_rediscretisation, ()),
    "wv_jacobian": (check_wv_jacobian, ()),
    "declarations": (check_declarations, ()),
    "ieee952": (check_ieee952, ()),
    "wv_rows": (check_wv_rows, ()),
}


@attrs.frozen
class ConformanceReport:
    """Outcome of :func:`check_family`.

    Attributes
    ----------
    family : str
        The family's registry name.
    freq : float
        Sampling frequency of the run, Hz.
    instance : str
        ``repr`` of the instance checked.
    ran : tuple of str
        Checks attempted, in order.
    passed : tuple of str
        Checks that passed.
    failed : dict of str to str
        Failed checks and their messages.
    skipped : dict of str to str
        Checks that do not apply, with the reason.
    figures : dict of str to dict
        What each passed check measured (errors, z-scores, levels ...).
    """

    family: str
    freq: float
    instance: str
    ran: tuple[str, ...]
    passed: tuple[str, ...]
    failed: dict[str, str]
    skipped: dict[str, str]
    figures: dict[str, Figures]

    @property
    def ok(self) -> bool:
        """True when no check failed."""
        return not self.failed

    def summary(self) -> str:
        """One row per check: status and the figures measured or the message."""
        rows = []
        for name in self.ran:
            if name in self.failed:
                rows.append([name, "FAILED", self.failed[name].splitlines()[0]])
            elif name in self.skipped:
                rows.append([name, "skipped", self.skipped[name]])
            else:
                figs = ", ".join(f"{k}={format_number(v, 3)}" for k, v in self.figures[name].items()
                                 if isinstance(v, (int, float, np.floating)))
                rows.append([name, "passed", figs])
        title = (f"Conformance of {self.family} at {format_number(self.freq)} Hz ({self.instance}): "
                 f"{len(self.passed)} passed, {len(self.failed)} failed, {len(self.skipped)} skipped")
        return format_table(["check", "status", "details"], rows, title=title)

    def raise_if_failed(self) -> None:
        """Raise AssertionError with every failure's full message (for use in tests)."""
        if self.failed:
            raise AssertionError(
                f"{self.family} fails {len(self.failed)} conformance check(s):\n"
                + "\n".join(f"[{name}] {msg}" for name, msg in self.failed.items())
            )


def check_family(process_or_cls: Process | type[Process], freq: float = 100.0, *, rng: RngLike = 0,
                 n_mc: int = 20, n: int = 2**14, n_ss: int = 2**12, max_examples: int = 25,
                 checks: Iterable[str] | None = None) -> ConformanceReport:
    """Run the conformance checks on a family and collect the outcome.

    Parameters
    ----------
    process_or_cls : Process or Process subclass
        An instance with values, or the class (its ``example(freq)`` is used; the
        ``example`` check always concerns the class).
    freq : float
        Sampling frequency, Hz.
    rng : numpy.random.Generator or int
        Seed of every random draw; each check gets its own child generator, so a check's
        outcome does not depend on which other checks run.
    n_mc : int
        Monte Carlo replications of the simulation checks (stronger runs: 100-500).
    n : int
        Samples per simulation of the WV Monte Carlo check (stronger: 2^16).
    n_ss : int
        Samples per state-space simulation (a Python loop: keep it moderate).
    max_examples : int
        hypothesis examples of the domain check (stronger: 200-1000).
    checks : iterable of str, optional
        Names from :data:`CHECKS` to run (default: all).

    Returns
    -------
    ConformanceReport
        Checks ran, passed, failed (message) and skipped (reason), and their figures.
        A check that raises anything other than :class:`NotApplicable` fails; so does
        every check when the class has no ``example``.
    """
    freq = check_freq(freq)
    cls = _family_class(process_or_cls)
    names = tuple(CHECKS) if checks is None else tuple(checks)
    unknown = [c for c in names if c not in CHECKS]
    if unknown:
        raise InputError(f"unknown check(s) {unknown}; known: {list(CHECKS)}")
    options = {"n_mc": n_mc, "n": n, "n_ss": n_ss, "max_examples": max_examples}
    children = dict(zip(CHECKS, _children(rng, len(CHECKS))))
    passed, failed, skipped, figures = [], {}, {}, {}
    target: Process | type[Process] = process_or_cls
    try:
        target = _instance(process_or_cls, freq)
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - no example: every check but `example` fails
        failed.update({c: f"no instance to check: {type(exc).__name__}: {exc}" for c in names
                       if c != "example"})
    for name in names:
        if name in failed:
            continue
        func, accepted = CHECKS[name]
        kwargs = {("n" if k == "n_ss" else k): options[k] for k in accepted}
        subject = process_or_cls if name == "example" else target
        try:
            figures[name] = func(subject, freq, rng=children[name], **kwargs)
        except NotApplicable as exc:
            skipped[name] = str(exc)
        except Exception as exc:  # noqa: BLE001 - a crash is a failure, reported with its type
            notes = "\n".join(getattr(exc, "__notes__", []))
            prefix = "" if isinstance(exc, AssertionError) else f"{type(exc).__name__}: "
            failed[name] = prefix + str(exc) + (f"\n{notes}" if notes else "")
        else:
            passed.append(name)
    return ConformanceReport(
        family=cls.family or cls.__name__, freq=freq,
        instance=repr(target) if isinstance(target, Process) else cls.__name__,
        ran=names, passed=tuple(passed), failed=failed, skipped=skipped, figures=figures,
    )


# ---------------------------------------------------------------------------- weightings
def _weighting_matrix(weighting: Any, data: Any, what: str) -> Any:
    """``weighting.matrix(data)`` with its Omega (and V) checked; AssertionError naming `what`."""
    from stochmod.fit.weighting import check_weighting_matrix

    try:
        made = weighting.matrix(data)
    except Exception as exc:  # noqa: BLE001 - any failure of a plugin is a conformance failure
        raise AssertionError(f"weighting {weighting.name!r}: matrix() failed on {what}: {exc!r}") from exc
    J = data.levels
    try:
        check_weighting_matrix(getattr(made, "omega", None), J, source=f"{what}: Omega")
    except InputError as exc:
        raise AssertionError(f"weighting {weighting.name!r}: {exc}") from None
    V = getattr(made, "covariance", None)
    if V is not None:
        V = np.asarray(V, dtype=float)
        if V.shape != (J, J) or not np.all(np.isfinite(V)) or np.any(np.diag(V) <= 0):
            raise AssertionError(f"weighting {weighting.name!r}: {what}: the covariance V must be "
                                 f"finite, (J, J) = {(J, J)}, with positive variances")
        if not np.allclose(V, V.T, rtol=1e-10, atol=0.0):
            raise AssertionError(f"weighting {weighting.name!r}: {what}: the covariance V is not symmetric")
    return made


def check_weighting(weighting: Any, model: Any, freq: float = 100.0, *, rng: RngLike = 0,
                    n: int = 2**13, reps: int = 30, scale: float = 1e3) -> Figures:
    """Check a GMWM weighting (the ``stochmod_weightings`` plugin point) against the contract.

    The signal is `n` samples simulated from `model` (seeded); the pilot fit of a weighting
    with ``needs_fit`` is the diagonal GMWM fit of the model's structure. Checked:

    - ``name`` (non-empty str), ``description`` (str), ``needs_signal`` and ``needs_fit``
      (bool), ``inference`` (``"data"`` or ``"model"``, when given) and a callable
      ``matrix``;
    - ``matrix(data)`` gives Omega of shape (J, J), finite, symmetric, positive definite, and a
      covariance V (when it gives one) finite, symmetric, with positive variances;
    - the same input gives the same matrix (results reproduce);
    - without ``needs_signal``, the WV alone suffices (``data.signal`` None);
    - a change of the signal's unit (the signal times `scale`) changes Omega by a constant
      factor only (rel 1e-5), so that the GMWM estimate does not depend on the unit;
    - registered, ``stochmod.gmwm(..., weighting=name)`` resolves it and fits with that Omega.

    Parameters
    ----------
    weighting : object
        The weighting (an object of a ``stochmod_weightings`` hook).
    model : Model, Process, str or dict
        A model with every value given (``"GM(beta=2, sigma2=1) + WN(sigma2=1)"``), unit u.
    freq : float
        Sampling frequency, Hz.
    rng : int or Generator
        Seed of the simulation and of the weighting.
    n : int
        Signal length, samples.
    reps : int
        ``WeightingInput.reps`` (Monte Carlo replications a weighting may use).
    scale : float
        Factor of the unit change.

    Returns
    -------
    dict
        ``levels``, ``condition`` (of Omega), ``covariance`` (whether V is given),
        ``scale_rel_error``, ``registered``, ``objective`` (of the registered fit, or None).

    Raises
    ------
    AssertionError
        The weighting breaks the contract (the message says how).
    """
    from stochmod.plugin import registry
    from stochmod.fit.engine import resolve_model
    from stochmod.fit.gmwm import gmwm
    from stochmod.fit.weighting_plugins import WeightingInput
    from stochmod.empirical.wavelet_variance import wvar

    name = getattr(weighting, "name", None)
    if not isinstance(name, str) or not name:
        raise AssertionError(f"{weighting!r} has no name (a non-empty str)")
    if not isinstance(getattr(weighting, "description", None), str):
        raise AssertionError(f"weighting {name!r} has no description (a str)")
    for flag in ("needs_signal", "needs_fit"):
        if not isinstance(getattr(weighting, flag, None), bool):
            raise AssertionError(f"weighting {name!r}: {flag} must be a bool")
    if getattr(weighting, "inference", "data") not in ("data", "model"):
        raise AssertionError(f"weighting {name!r}: inference must be 'data' or 'model', got "
                             f"{weighting.inference!r}")
    if not callable(getattr(weighting, "matrix", None)):
        raise AssertionError(f"weighting {name!r} has no matrix(data) method")
    freq = check_freq(freq)
    n = check_positive_int(n, name="n", minimum=64)
    truth = resolve_model(model, freq)
    truth.vector()  # SpecError when a value is missing
    seed = int(_children(rng, 1)[0].integers(2**31))
    x = truth.simulate(n, seed)
    structure = truth.freed()

    def data(signal: np.ndarray, with_signal: bool = True) -> Any:
        emp = wvar(signal, freq)
        pilot = None
        if weighting.needs_fit:
            pilot = gmwm(signal, structure, freq, weighting="diagonal", levels=emp.wv.size, rng=seed)
        return WeightingInput(emp, emp.wv.size, signal if with_signal else None, pilot,
                              seed=seed, reps=reps)

    base = data(x)
    J = base.levels
    made = _weighting_matrix(weighting, base, "the simulated signal")
    omega = np.asarray(made.omega, dtype=float)
    again = _weighting_matrix(weighting, base, "the same input again")
    if not np.array_equal(np.asarray(again.omega, dtype=float), omega):
        raise AssertionError(f"weighting {name!r}: the same input gives another matrix "
                             "(draw randomness from data.seed)")
    if not weighting.needs_signal:
        _weighting_matrix(weighting, data(x, with_signal=False), "the wavelet variance alone")
    scaled = np.asarray(_weighting_matrix(weighting, data(scale * x), "the signal in other units").omega,
                        dtype=float)
    a, b = omega / np.linalg.norm(omega), scaled / np.linalg.norm(scaled)
    scale_error = float(np.max(np.abs(a - b)) / np.max(np.abs(a)))
    if not scale_error <= 1e-5:
        raise AssertionError(
            f"weighting {name!r}: with the signal times {scale:g}, Omega is not a multiple of "
            f"the original one (max relative difference {scale_error:.3g}): the GMWM estimate "
            "would depend on the signal's unit")
    registered = registry.weightings().get(name) is weighting
    objective = None
    if registered:
        fit = gmwm(x, structure, freq, weighting=name, levels=J, rng=seed, bootstrap_reps=reps)
        if fit.weighting != name or not np.array_equal(fit.omega, omega):
            raise AssertionError(f"stochmod.gmwm(weighting={name!r}) does not fit with the "
                                 "weighting's matrix")
        objective = float(fit.objective)
    return {"levels": J, "condition": float(np.linalg.cond(omega)),
            "covariance": made.covariance is not None, "scale_rel_error": scale_error,
            "registered": registered, "objective": objective}


# ---------------------------------------------------------------------------- readers
def check_reader(reader: Any, path: Any, *, expected: Any = None, **options: Any) -> Figures:
    """Check a log-format reader against the ``stochmod_readers`` contract on a sample file.

    Parameters
    ----------
    reader : object
        The reader (e.g. a :class:`stochmod.io.recording.Reader` instance), registered or not.
    path : str or Path
        A sample file or folder in the reader's format.
    expected : array_like, shape (n, k), optional
        The samples the file holds; the data read must equal them exactly.
    **options
        Reader options to pass (each must be declared in ``reader.options``).

    Returns
    -------
    dict
        ``n``, ``k``, ``has_time``, ``rate`` (Hz, from the time stamps, or None).

    Raises
    ------
    AssertionError
        A declaration is missing or malformed (name, suffixes, options, sniff, read), ``read``
        does not accept its declared options, the result is not a finite (n, k) Recording with
        matching names, units that parse and strictly increasing time stamps, the data differ
        from `expected`, or, when the reader is registered, ``read_recording`` does not
        dispatch to it, read the same data or refuse an undeclared option.
    """
    import inspect
    from pathlib import Path

    from stochmod.io.recording import Recording, read_recording
    from stochmod.plugin.registry import readers
    from stochmod.io.timing import analyse_timing
    from stochmod.core.units import parse_unit

    path = Path(path)
    name = getattr(reader, "name", None)
    assert isinstance(name, str) and name, f"reader {reader!r} has no name"
    suffixes, declared = getattr(reader, "suffixes", ()), getattr(reader, "options", ())
    assert isinstance(suffixes, tuple) and all(
        isinstance(s, str) and s == s.lower() and (s == "" or s.startswith(".")) for s in suffixes
    ), f"reader {name!r}: suffixes must be a tuple of lower-case '.ext' strings, got {suffixes!r}"
    assert isinstance(declared, tuple) and all(isinstance(o, str) for o in declared), (
        f"reader {name!r}: options must be a tuple of str, got {declared!r}")
    undeclared = sorted(set(options) - set(declared))
    assert not undeclared, f"reader {name!r}: options {undeclared} passed but not declared"
    params = inspect.signature(reader.read).parameters
    takes_any = any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values())
    missing = [o for o in declared if o not in params and not takes_any]
    assert not missing, f"reader {name!r}: read() does not accept its declared option(s) {missing}"
    for probe in (path, path.parent / f"{path.name}.not-a-log-{name}"):
        verdict = reader.sniff(probe)
        assert isinstance(verdict, bool), (
            f"reader {name!r}: sniff({probe}) returned {verdict!r}, not a bool")
    assert suffixes or reader.sniff(path), (
        f"reader {name!r} declares no suffix and its sniff does not recognise {path}")

    rec = reader.read(path, **options)
    assert isinstance(rec, Recording), (
        f"reader {name!r} returned {type(rec).__name__}, not a Recording")
    data = np.asarray(rec.data)
    assert data.ndim == 2 and data.shape[0] >= 2 and data.shape[1] == len(rec.columns), (
        f"reader {name!r}: data of shape {data.shape} for columns {rec.columns}")
    assert np.all(np.isfinite(data.astype(np.float64))), f"reader {name!r}: non-finite samples"
    assert len(set(rec.columns)) == len(rec.columns), (
        f"reader {name!r}: repeated column names {rec.columns}")
    for unit in rec.units or ():
        if unit is not None:
            parse_unit(unit)  # InputError (a failure) when a unit does not parse
    rate = None
    if rec.time is not None:
        rate = analyse_timing(rec.time, name=f"reader {name!r}: time stamps of {path}").rate
    if expected is not None:
        want = np.asarray(expected, dtype=np.float64).reshape(data.shape[0], -1)
        np.testing.assert_array_equal(data, want, err_msg=f"reader {name!r}: samples differ")

    if readers().get(name) is reader:
        via = read_recording(path, split_gaps=True, **options)
        np.testing.assert_array_equal(via.data, data,
                                      err_msg=f"read_recording({path}) differs from {name!r}")
        try:
            read_recording(path, reader=name, split_gaps=True, not_an_option_of_any_reader=1)
        except InputError as exc:
            assert "not_an_option_of_any_reader" in str(exc), f"unclear refusal: {exc}"
        else:
            raise AssertionError(f"read_recording passed an undeclared option to reader {name!r}")
    return {"n": int(data.shape[0]), "k": int(data.shape[1]), "has_time": rec.time is not None,
            "rate": rate}
