"""The :class:`Process` base class: what a process family declares, and generic fallbacks.

A family is a frozen attrs subclass with one field per parameter (``None`` while free),
registered by a plugin's ``stochmod_processes`` hook. The core never names a family: it asks
the class for everything it needs. Parameters are per sample at the model's sampling
frequency ``freq`` unless their unit says otherwise (GM's ``beta`` is in 1/s).

Generic fallbacks, used where a family does not override them:

- :meth:`Process.wv` from the autocovariance (exact Haar sum) for stationary families that
  declare one, else from the PSD (quadrature of ``|H_j(f)|^2 S(f)``, any Daubechies filter);
- :meth:`Process.wv_jacobian` by central differences;
- :meth:`Process.block` by exact Van Loan re-discretisation of :meth:`continuous_block`,
  or by composing integer numbers of native steps of :meth:`discrete_block`;
- :meth:`Process.simulate` from the state-space block (families override with direct forms).

Optional protocols a family may declare on top: vectorised Haar WV rows for the GMWM
optimizer (:class:`stochmod.core.vectorised_wv.VectorisedWV`), and the base of families whose
Haar WV is a scale times a fixed factor (:class:`stochmod.core.scaled_family.ScaledFamily`).
"""

from __future__ import annotations

import abc
import functools
import math
from collections.abc import Callable, Mapping
from typing import Any, ClassVar

import attrs
import numpy as np
from numpy.typing import ArrayLike

from stochmod.core.checks import check_freq, check_positive_int
from stochmod.core.errors import DomainError, InputError, SpecError
from stochmod.core.params import SCALE_POWERS, Domain, Parameter, get_domain, scalar_contains
from stochmod.core.statespace import ContinuousBlock, StateSpaceBlock, compose_steps, van_loan
from stochmod.core.theory import wv_from_autocovariance, wv_from_psd

__all__ = [
    "PhysicalValue",
    "Process",
    "as_generator",
    "declares_block",
    "declares_psd",
    "has_theoretical_wv",
    "psd_of",
    "scalar_domains",
]


def as_generator(rng: np.random.Generator | int | None) -> np.random.Generator:
    """Return a numpy Generator from a Generator or an integer seed (None is refused:
    results must reproduce, so randomness is always explicit)."""
    if isinstance(rng, np.random.Generator):
        return rng
    if isinstance(rng, (int, np.integer)) and not isinstance(rng, bool):
        return np.random.default_rng(int(rng))
    raise InputError(f"rng must be a numpy Generator or an integer seed, got {rng!r}")


@attrs.frozen
class PhysicalValue:
    """A parameter in physical terms (e.g. GM correlation time), for reports."""

    value: float
    unit: str
    description: str = ""


@attrs.frozen
class Process(abc.ABC):
    """Base class of process families.

    Subclasses set the class variables below, declare one attrs field per parameter
    (default ``None``: free) and must implement the abstract :meth:`start` and
    :meth:`example`, and declare a state-space block: :meth:`continuous_block` or
    :meth:`discrete_block` (with :attr:`state_names`), or, for a feed-through family without
    states, :meth:`white_variance` (:func:`declares_block`; an instance of a family that
    declares none is refused). They implement :meth:`psd` (families without one are fitted by
    indirect inference, see :func:`has_theoretical_wv`), :meth:`physical`, and stationary
    families :meth:`autocovariance`. Everything else has a generic fallback.

    Class variables
    ---------------
    family : str
        Unique name in the registry and in specs (``"GM"``).
    description : str
        One line for listings.
    parameter_specs : tuple of Parameter
        The parameters, in order (families whose parameter sizes depend on the instance,
        like AR(p), override :meth:`parameters`).
    structural_fields : tuple of str
        Constructor arguments that fix the structure rather than a value (AR's ``order``);
        they appear in specs (``"AR(2)"`` or ``{"family": "AR", "order": 2}``).
    stationary : bool
        Whether the process has a stationary autocovariance.
    lattice_copies : int
        Copies of the family in the default selection lattice (0: not in it; the GM plugin
        declares 3). :func:`stochmod.fit.lattice.default_families` reads it from the registry.
    lattice_rank : int
        Where the family's processes sit in the default lattice's model names (ascending;
        ties by family name): GM 10, WN 20, RW 30, QN 40, RR 50 give ``"GM+WN+RW"``.
    ieee952 : tuple of tuple of str
        The sets of coefficients (names of :data:`stochmod.core.coefficients.COEFFICIENTS`) that
        :meth:`from_ieee952` builds the family from, e.g. ``(("N",),)`` for white noise or
        ``(("B", "Tc"), ("rate", "variance"))``; empty: no classical reading yields it.
    """

    family: ClassVar[str] = ""
    description: ClassVar[str] = ""
    parameter_specs: ClassVar[tuple[Parameter, ...]] = ()
    structural_fields: ClassVar[tuple[str, ...]] = ()
    stationary: ClassVar[bool] = True
    lattice_copies: ClassVar[int] = 0
    lattice_rank: ClassVar[int] = 0
    ieee952: ClassVar[tuple[tuple[str, ...], ...]] = ()

    def __attrs_post_init__(self) -> None:
        if not declares_block(type(self)):
            raise TypeError(
                f"Can't instantiate family {type(self).__name__}: it declares no state-space "
                "block (override continuous_block or discrete_block, with state_names; or "
                "white_variance for a feed-through family without states)")
        for spec in self.parameters():
            value = getattr(self, spec.name)
            if value is not None:
                checked = spec.check(value, self.family)
                if spec.size > 1 or get_domain(spec.domain).vector:
                    checked = tuple(float(c) for c in np.atleast_1d(checked))
                object.__setattr__(self, spec.name, checked)

    # ------------------------------------------------------------------ algebra
    def __add__(self, other: object) -> Any:
        from stochmod.core.model import Model

        if isinstance(other, (Process, Model)):
            return Model((self,)) + other
        return NotImplemented

    def __mul__(self, count: object) -> Any:
        from stochmod.core.model import Model

        return Model((self,)).__mul__(count)

    __rmul__ = __mul__

    # ------------------------------------------------------------------ parameters
    def parameters(self) -> tuple[Parameter, ...]:
        """The parameter declarations of this instance, in order."""
        return self.parameter_specs

    def values(self) -> dict[str, Any]:
        """Parameter values by name (``None`` for free ones; vectors as float arrays)."""
        out = {}
        for spec in self.parameters():
            v = getattr(self, spec.name)
            out[spec.name] = None if v is None else (np.asarray(v, float) if spec.size > 1
                                                     or isinstance(v, tuple) else float(v))
        return out

    def value(self, name: str) -> Any:
        """One parameter's value; raises :class:`SpecError` if it is free."""
        v = self.values()[name]
        if v is None:
            raise SpecError(f"{self.family}.{name} is free (no value): fit the model or give it")
        return v

    @property
    def free_names(self) -> tuple[str, ...]:
        """Names of the parameters without a value."""
        return tuple(n for n, v in self.values().items() if v is None)

    @property
    def is_free(self) -> bool:
        """True when at least one parameter has no value."""
        return any(getattr(self, spec.name) is None for spec in self.parameters())

    @property
    def n_params(self) -> int:
        """Number of scalar parameters."""
        return sum(p.size for p in self.parameters())

    def require_values(self) -> None:
        """Raise :class:`SpecError` naming the free parameters, if any (call it before
        evaluating a formula)."""
        if self.is_free:
            raise SpecError(
                f"{self.family} has free parameter(s) {list(self.free_names)}: "
                "give values or fit the model first"
            )

    #: The name plugins written against earlier docs call; use :meth:`require_values`.
    _require_values = require_values

    def scale_parameter(self) -> tuple[Parameter, int] | None:
        """The scalar parameter declared with a scale role and its power d (the wavelet
        variance is proportional to ``value ** d``: 1 for ``"variance"``, 2 for
        ``"amplitude"``); None when the family declares none."""
        for spec in self.parameters():
            if spec.role in SCALE_POWERS and spec.size == 1:
                return spec, SCALE_POWERS[spec.role]
        return None

    def ordering_key(self) -> float:
        """Key that orders repeated components of this family in a fitted model, larger first
        (GM: fastest first), so fits compare across runs without label switching.

        Default: the first parameter declared with role ``"rate"``, else the scale parameter
        (:meth:`scale_parameter`). Families whose order is another quantity override it.
        """
        self.require_values()
        for spec in self.parameters():
            if spec.role == "rate" and spec.size == 1:
                return float(getattr(self, spec.name))
        scale = self.scale_parameter()
        if scale is None:
            raise SpecError(f"{self.family} declares no rate or scale parameter role: declare "
                            "roles on its Parameters or override Process.ordering_key")
        return float(getattr(self, scale[0].name))

    @classmethod
    def from_ieee952(cls, coefficients: Mapping[str, Any], freq: float, **options: Any) -> Process:
        """The process built from classical-reading coefficients (:attr:`ieee952` names which
        sets), per-sample parameters at `freq` Hz. `options` are family conventions (GM's
        ``convention``). Families without :attr:`ieee952` do not override it."""
        raise SpecError(f"{cls.family} is built from no classical-reading coefficients "
                        "(it declares no ieee952 sets)")

    @classmethod
    def ieee952_set(cls, coefficients: Mapping[str, Any]) -> tuple[str, ...]:
        """The first of :attr:`ieee952` whose coefficients are all in `coefficients`.

        Raises
        ------
        SpecError
            None is (the message lists what the family is built from).
        """
        for names in cls.ieee952:
            if all(n in coefficients for n in names):
                return names
        raise SpecError(f"{cls.family} is built from the coefficients {list(cls.ieee952)}; "
                        f"got {sorted(coefficients)}")

    def to_ieee952(self, freq: float, names: tuple[str, ...]) -> dict[str, Any]:
        """The coefficients `names` (one of :attr:`ieee952`) of this process at `freq` Hz: the
        inverse of :meth:`from_ieee952` (with its default options)."""
        raise SpecError(f"{self.family} declares no ieee952 sets")

    def with_values(self, **values: Any) -> Process:
        """Return a copy with the given parameters set (validated against their domains)."""
        names = {p.name for p in self.parameters()}
        unknown = set(values) - names
        if unknown:
            raise SpecError(f"{self.family} has no parameter(s) {sorted(unknown)}; it has {sorted(names)}")
        return attrs.evolve(self, **values)

    def freed(self) -> Process:
        """Return a copy with every parameter free (structure kept)."""
        return attrs.evolve(self, **{p.name: None for p in self.parameters()})

    def vector(self) -> np.ndarray:
        """All parameters as one float vector in declaration order (no parameter may be free)."""
        self.require_values()
        return np.concatenate([np.atleast_1d(np.asarray(getattr(self, p.name), float))
                               for p in self.parameters()])

    def from_vector(self, vector: ArrayLike) -> Process:
        """Inverse of :meth:`vector`: a copy whose parameters take the values in `vector`."""
        vec = np.asarray(vector, dtype=np.float64).reshape(-1)
        if vec.size != self.n_params:
            raise SpecError(f"{self.family} takes {self.n_params} value(s), got {vec.size}")
        values, i = {}, 0
        for p in self.parameters():
            chunk = vec[i : i + p.size]
            values[p.name] = float(chunk[0]) if p.size == 1 else chunk.copy()
            i += p.size
        return attrs.evolve(self, **values)

    def to_unconstrained(self) -> np.ndarray:
        """Parameters mapped to the unconstrained space of their domains."""
        self.require_values()
        return np.concatenate([
            np.atleast_1d(get_domain(p.domain).to_unconstrained(np.asarray(getattr(self, p.name), float)))
            for p in self.parameters()
        ])

    def from_unconstrained(self, theta: ArrayLike) -> Process:
        """A copy whose parameters are the image of `theta` under the domains' inverse maps.

        Families whose parameters are all scalars of built-in domains, and which keep the
        base class's construction (:meth:`parameters`, :meth:`from_vector`,
        ``__attrs_post_init__``), take a validated fast path: the same values and the same
        domain verdicts, with plain-float checks instead of a rebuild through ``attrs.evolve``
        (an optimizer builds thousands of models). Values outside their domain (overflow at
        extreme `theta`) go through the general path, which raises.
        """
        theta = np.asarray(theta, dtype=np.float64).reshape(-1)
        layout = _scalar_layout(type(self))
        if layout is not None and theta.size == len(layout):
            fast = self._from_scalar_theta(theta, layout)
            if fast is not None:
                return fast
        out, i = [], 0
        for p in self.parameters():
            out.append(np.atleast_1d(get_domain(p.domain).from_unconstrained(theta[i : i + p.size])))
            i += p.size
        return self.from_vector(np.concatenate(out) if out else np.zeros(0))

    def _from_scalar_theta(self, theta: np.ndarray, layout: _ScalarLayout) -> Process | None:
        """:meth:`from_unconstrained` for the families of :func:`_scalar_layout`: a copy whose
        fields are set directly, or None when a value falls outside its domain."""
        values = []
        for i, (_, domain, contains) in enumerate(layout):
            v = float(domain.from_unconstrained(theta[i : i + 1])[0])
            if not contains(v):
                return None
            values.append(v)
        new = object.__new__(type(self))
        for name in _field_names(type(self)):
            object.__setattr__(new, name, getattr(self, name))
        for (name, _, _), v in zip(layout, values):
            object.__setattr__(new, name, v)
        return new

    def transform_jacobian(self, theta: ArrayLike) -> np.ndarray:
        """Block-diagonal Jacobian ``d vector / d theta`` of :meth:`from_unconstrained`."""
        theta = np.asarray(theta, dtype=np.float64).reshape(-1)
        J = np.zeros((theta.size, theta.size))
        i = 0
        for p in self.parameters():
            J[i : i + p.size, i : i + p.size] = get_domain(p.domain).jacobian(theta[i : i + p.size])
            i += p.size
        return J

    def structure(self) -> dict[str, Any]:
        """Structural constructor arguments (see :attr:`structural_fields`)."""
        return {name: getattr(self, name) for name in self.structural_fields}

    def to_spec(self) -> dict[str, Any]:
        """JSON-safe spec: ``{"family": ..., "params": {...given values...}, **structure}``."""
        params = {}
        for name, v in self.values().items():
            if v is not None:
                params[name] = v.tolist() if isinstance(v, np.ndarray) else float(v)
        return {"family": self.family, "params": params, **self.structure()}

    # ------------------------------------------------------------------ theory
    def wv(self, levels: int, freq: float, wavelet: str = "haar") -> np.ndarray:
        """Theoretical wavelet variance at levels 1..`levels`, signal unit^2.

        Generic fallback: exact Haar sum over :meth:`autocovariance` for stationary families
        that declare one, else quadrature of the PSD (:func:`stochmod.core.theory.wv_from_psd`).
        """
        self.require_values()
        levels = check_positive_int(levels, name="levels")
        freq = check_freq(freq)
        if wavelet == "haar" and self.stationary and _overrides(type(self), "autocovariance"):
            return wv_from_autocovariance(lambda lags: self.autocovariance(lags, freq), levels)
        return wv_from_psd(lambda f: psd_of(self, f, freq), levels, freq, wavelet=wavelet,
                           breakpoints=self.psd_breakpoints(freq))

    def wv_sampling_covariance(self, n_coef: ArrayLike, freq: float,
                               wavelet: str = "haar") -> np.ndarray | None:
        """Covariance (J x J, u^4) of this component's empirical WV that :meth:`psd` does not
        describe, or None (default).

        None means the family is a Gaussian process whose spectral density :meth:`psd` is: a
        composite's WV covariance then comes from its summed PSD
        (:func:`stochmod.core.theory.wv_covariance_from_psd`). A family whose WV varies from
        record to record in another way (a random ramp: one slope per record) returns its own.
        `n_coef` are the numbers of coefficients M_j at levels 1..J.
        """
        return None

    def wv_jacobian(self, levels: int, freq: float) -> np.ndarray:
        """Jacobian of :meth:`wv` with respect to :meth:`vector`, shape (levels, n_params).

        Generic fallback: central differences with relative steps (families with a closed
        form override this).
        """
        vec = self.vector()
        cols = []
        for i in range(vec.size):
            h = 1e-6 * max(abs(vec[i]), 1e-300)
            hi, lo = vec.copy(), vec.copy()
            hi[i] += h
            lo[i] -= h
            try:
                up, down = self.from_vector(hi), self.from_vector(lo)
                cols.append((up.wv(levels, freq) - down.wv(levels, freq)) / (2 * h))
            except DomainError:  # at a domain edge: one-sided difference
                up = self.from_vector(hi)
                cols.append((up.wv(levels, freq) - self.wv(levels, freq)) / h)
        return np.column_stack(cols) if cols else np.zeros((levels, 0))

    @abc.abstractmethod
    def psd(self, f: ArrayLike, freq: float) -> np.ndarray:
        """Two-sided PSD of the sampled process, signal unit^2/Hz, at `f` Hz in (-freq/2, freq/2].

        Every family declares it. A family whose spectrum cannot be stated (fitted by
        simulation only, ``stochmod.gmwm(..., binding="simulated")``) declares ``psd = None``
        in its class body; :func:`declares_psd` tells which, and :func:`psd_of` evaluates it.
        """

    def psd_breakpoints(self, freq: float) -> tuple[float, ...]:
        """Frequencies (Hz) where the PSD has a kink or jump (quadrature splits there)."""
        return ()

    def autocovariance(self, lags: ArrayLike, freq: float) -> np.ndarray:
        """Autocovariance at integer `lags` (samples), signal unit^2; stationary families only."""
        raise InputError(f"{self.family} is not stationary: it has no autocovariance")

    # ------------------------------------------------------------------ state space
    @property
    def state_names(self) -> tuple[str, ...]:
        """Names of the states this family adds to a filter (empty for feed-through only)."""
        return ()

    def continuous_block(self, freq: float) -> ContinuousBlock | None:
        """Continuous-time form, or None where the family is discrete only (AR(p))."""
        return None

    def discrete_block(self, freq: float) -> StateSpaceBlock:
        """State-space block at the native step ``1/freq``."""
        if not self.state_names:
            return self._feedthrough_block(1.0 / freq, freq)
        cont = self.continuous_block(freq)
        if cont is None:
            raise NotImplementedError(f"{self.family} declares neither a discrete nor a continuous block")
        return self._block_from_continuous(cont, 1.0 / freq, freq)

    def initial_covariance(self, freq: float) -> np.ndarray:
        """Covariance of the states at the start (stationary where it exists)."""
        return np.zeros((len(self.state_names),) * 2)

    def white_variance(self, freq: float) -> float:
        """White feed-through variance per sample at `freq` (signal unit^2)."""
        return 0.0

    def output_row(self, freq: float) -> np.ndarray:
        """Output row H: how the states add to the sensor reading (default: first state)."""
        k = len(self.state_names)
        return np.eye(k)[0] if k else np.zeros(0)

    def _feedthrough_block(self, dt: float, freq: float) -> StateSpaceBlock:
        empty = np.zeros((0, 0))
        return StateSpaceBlock((), empty, empty, np.zeros(0), empty, self.white_variance(freq), dt)

    def _block_from_continuous(self, cont: ContinuousBlock, dt: float, freq: float) -> StateSpaceBlock:
        Phi, Q = van_loan(cont, dt) if cont.F.size else (np.zeros((0, 0)), np.zeros((0, 0)))
        names = self.state_names
        return StateSpaceBlock(names, Phi, Q, self.output_row(freq), self.initial_covariance(freq),
                               self.white_variance(freq), dt, cont)

    def block(self, dt: float, freq: float) -> StateSpaceBlock:
        """State-space block at filter step `dt` seconds, exact.

        With a continuous form: exact Van Loan discretisation at any `dt`. Discrete-only
        families: `dt` must be a whole number of sample periods, and the block composes that
        many native steps exactly.
        """
        self.require_values()
        freq = check_freq(freq)
        dt = float(dt)
        if not (np.isfinite(dt) and dt > 0):
            raise InputError(f"dt must be a positive number of seconds, got {dt!r}")
        if not self.state_names:  # feed-through only (WN, QN): no dynamics, any dt
            return self._feedthrough_block(dt, freq)
        cont = self.continuous_block(freq)
        if cont is not None:
            return self._block_from_continuous(cont, dt, freq)
        native = self.discrete_block(freq)
        steps = dt * freq
        k = round(steps)
        if k < 1 or not math.isclose(steps, k, rel_tol=1e-9):
            raise InputError(
                f"{self.family} is discrete-time: dt = {dt} s must be a whole multiple of the sample "
                f"period 1/{freq} s"
            )
        Phi, Q = compose_steps(native.Phi, native.Q, k) if native.n_states else (native.Phi, native.Q)
        return attrs.evolve(native, Phi=Phi, Q=Q, dt=dt)

    # ------------------------------------------------------------------ simulation
    def simulate(self, n: int, freq: float, rng: np.random.Generator | int) -> np.ndarray:
        """Simulate `n` samples at `freq` Hz from a seeded generator (generic: via the state space)."""
        self.require_values()
        return simulate_block(self.discrete_block(check_freq(freq)),
                              check_positive_int(n, name="n"), as_generator(rng))

    # ------------------------------------------------------------------ estimation support
    @abc.abstractmethod
    def start(self, wv: np.ndarray, freq: float, *, index: int = 0, count: int = 1,
              rng: np.random.Generator | None = None) -> Process:
        """Starting values for the free parameters from an empirical Haar WV (levels 1..J).

        `index` of `count` tells which of several processes of this family is meant (the
        composer asks GM 1 of 2, GM 2 of 2 ...), so starts spread over time scales; `rng`,
        when given, perturbs the guess for multi-start searches.
        """
        raise NotImplementedError(f"{self.family} provides no starting values")

    def start_alternatives(self, wv: np.ndarray, freq: float, *, index: int = 0,
                           count: int = 1) -> tuple[Process, ...]:
        """Other deterministic starting guesses worth a local search (default: none).

        A family whose :meth:`start` reads the WV in one way that another component of a
        composite can mislead (e.g. AR's ratio of the two finest levels under white noise)
        offers guesses read in other ways; the GMWM search tries each, the rest of the model
        at its :meth:`start`. Same arguments as :meth:`start`, without `rng`.
        """
        return ()

    def physical(self, freq: float) -> dict[str, PhysicalValue]:
        """The parameters in physical terms (correlation time, noise density ...)."""
        return {}

    @classmethod
    @abc.abstractmethod
    def example(cls, freq: float) -> Process:
        """A typical instance at `freq` Hz (for documentation and the conformance kit):
        its time scales must be resolvable by simulations of ~2^16 samples."""
        raise NotImplementedError(f"{cls.family} provides no example instance")


def _overrides(cls: type, name: str) -> bool:
    return getattr(cls, name) is not getattr(Process, name)


def scalar_domains(cls: type[Process]) -> tuple[Domain, ...] | None:
    """The domains of `cls`'s parameters, in order, when its instances are nothing more than
    their scalar values checked against those domains (the fast path of
    :meth:`Process.from_unconstrained`: every parameter a scalar of a built-in scalar domain,
    the base class's construction kept); None otherwise."""
    layout = _scalar_layout(cls)
    return None if layout is None else tuple(domain for _, domain, _ in layout)


def declares_psd(process: Process | type[Process]) -> bool:
    """Whether the family states its PSD (it did not declare ``psd = None``)."""
    cls = process if isinstance(process, type) else type(process)
    return cls.psd is not None


def psd_of(process: Process, f: ArrayLike, freq: float) -> np.ndarray:
    """``process.psd(f, freq)``, signal unit^2/Hz.

    Raises
    ------
    NotImplementedError
        The family declares no PSD (``psd = None``: it is fitted by simulation only).
    """
    if not declares_psd(process):
        raise NotImplementedError(f"{process.family} declares no PSD (psd = None: its theory "
                                  "comes from simulation, binding='simulated')")
    return process.psd(f, freq)


_ScalarLayout = tuple[tuple[str, Domain, Callable[[float], bool]], ...]


@functools.cache
def _scalar_layout(cls: type[Process]) -> _ScalarLayout | None:
    """(name, domain, scalar membership test) per parameter of `cls`, when
    :meth:`Process.from_unconstrained` may build its instances directly: every parameter a
    scalar of a built-in scalar domain (:func:`stochmod.core.params.scalar_contains`), and the
    class keeps the base class's :meth:`~Process.parameters`, :meth:`~Process.from_vector`
    and ``__attrs_post_init__``, and gives its parameter fields no attrs validator or
    converter (a family that checks more, like AR, is rebuilt in full)."""
    if any(_overrides(cls, name) for name in ("parameters", "from_vector", "__attrs_post_init__")):
        return None
    fields = {f.name: f for f in attrs.fields(cls)}
    if any(fields[spec.name].validator is not None or fields[spec.name].converter is not None
           for spec in cls.parameter_specs):
        return None
    layout = []
    for spec in cls.parameter_specs:
        contains = scalar_contains(spec.domain)
        if spec.size != 1 or contains is None:
            return None
        layout.append((spec.name, get_domain(spec.domain), contains))
    return tuple(layout)


@functools.cache
def _field_names(cls: type[Process]) -> tuple[str, ...]:
    return tuple(f.name for f in attrs.fields(cls))


@functools.cache
def declares_block(cls: type[Process]) -> bool:
    """Whether the family declares its state-space block: it overrides
    :meth:`Process.continuous_block` or :meth:`Process.discrete_block`, or
    :meth:`Process.white_variance` (a feed-through family without states)."""
    return any(_overrides(cls, name) for name in ("continuous_block", "discrete_block",
                                                  "white_variance"))


def has_theoretical_wv(process: Process | type[Process]) -> bool:
    """Whether the family has a theoretical wavelet variance: it overrides :meth:`Process.wv`,
    or declares its PSD (:func:`declares_psd`), or (stationary) overrides
    :meth:`Process.autocovariance`. Families without one are fitted by indirect inference
    (``stochmod.gmwm(..., binding="simulated")``)."""
    cls = process if isinstance(process, type) else type(process)
    return (_overrides(cls, "wv") or declares_psd(cls)
            or (bool(cls.stationary) and _overrides(cls, "autocovariance")))


def simulate_block(block: StateSpaceBlock, n: int, rng: np.random.Generator) -> np.ndarray:
    """Simulate ``y_t = H x_t + v_t`` with ``x_{t+1} = Phi x_t + w_t``, x_0 ~ N(0, P0),
    ``v_t ~ N(0, white_var)``; the reading at t uses the state at t."""
    k = block.n_states
    y = np.zeros(n)
    if k:
        L0 = _psd_sqrt(block.P0)
        Lq = _psd_sqrt(block.Q)
        x = L0 @ rng.standard_normal(k)
        w = rng.standard_normal((n, k)) @ Lq.T
        for t in range(n):
            y[t] = block.H @ x
            x = block.Phi @ x + w[t]
    if block.white_var > 0:
        y += math.sqrt(block.white_var) * rng.standard_normal(n)
    return y


def _psd_sqrt(S: np.ndarray) -> np.ndarray:
    w, V = np.linalg.eigh(0.5 * (S + S.T))
    return V * np.sqrt(np.clip(w, 0, None))
