"""Composite models: sums of independent processes.

``GM() + GM() + WN()`` or ``2 * GM() + WN()`` builds a :class:`Model`; ``model.bind(freq)``
fixes the sampling frequency. The composer sums wavelet variances, PSDs and
autocovariances, stacks parameter vectors and their transforms, and builds the EKF
augmentation on demand (:meth:`Model.augment`).

Specs (:mod:`stochmod.plugin.spec`): a string such as ``"2*GM+WN+RW"``, ``"AR(2)+WN"`` or ``"GM(beta=0.1)+WN"`` (values
free unless given), or a dict ``{"processes": [{"family": "GM", "params": {"beta": 0.02,
"sigma2": 1e-6}}, ...]}``; :meth:`Model.to_spec` gives the JSON-safe dict back.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Mapping
from typing import Any

import attrs
import numpy as np
from numpy.typing import ArrayLike
from scipy.linalg import block_diag

from stochmod.core.checks import check_freq, check_positive_int
from stochmod.core.errors import InputError, SpecError
from stochmod.core.process import Process, as_generator, psd_of
from stochmod.core.tables import format_table
from stochmod.core.statespace import StateSpaceBlock, stack_blocks

__all__ = ["Model", "AxesAugmentation", "as_model", "augment_axes"]


def _as_processes(value: Iterable[Process]) -> tuple[Process, ...]:
    procs = tuple(value)
    for p in procs:
        if not isinstance(p, Process):
            raise SpecError(f"a model is a sum of Process instances, got {p!r}")
    if not procs:
        raise SpecError("a model needs at least one process")
    return procs


def _optional_freq(value: float | None) -> float | None:
    return None if value is None else check_freq(value)


@attrs.frozen
class Model:
    """A composite model: the sum of independent processes, optionally bound to `freq`.

    Attributes
    ----------
    processes : tuple of Process
        The components, in order.
    freq : float or None
        Sampling frequency in Hz (needed by every theoretical quantity).
    """

    processes: tuple[Process, ...] = attrs.field(converter=_as_processes)
    freq: float | None = attrs.field(default=None, converter=_optional_freq)

    # ------------------------------------------------------------------ algebra
    def __add__(self, other: object) -> Model:
        if isinstance(other, Process):
            return attrs.evolve(self, processes=self.processes + (other,))
        if isinstance(other, Model):
            if None not in (self.freq, other.freq) and self.freq != other.freq:
                raise SpecError(f"cannot add models bound to {self.freq} Hz and {other.freq} Hz")
            return Model(self.processes + other.processes, self.freq or other.freq)
        return NotImplemented

    def __radd__(self, other: object) -> Model:
        if isinstance(other, Process):
            return attrs.evolve(self, processes=(other,) + self.processes)
        return NotImplemented

    def __mul__(self, count: object) -> Model:
        if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 1:
            return NotImplemented
        return attrs.evolve(self, processes=self.processes * int(count))

    __rmul__ = __mul__

    def bind(self, freq: float) -> Model:
        """Return the model bound to sampling frequency `freq` (Hz)."""
        return attrs.evolve(self, freq=freq)

    def _freq(self) -> float:
        if self.freq is None:
            raise SpecError("the model is not bound to a sampling frequency: use model.bind(freq)")
        return self.freq

    # ------------------------------------------------------------------ naming
    @property
    def labels(self) -> tuple[str, ...]:
        """One label per process: the family name, numbered when it repeats (``GM1``, ``GM2``)."""
        counts = Counter(p.family for p in self.processes)
        seen: Counter[str] = Counter()
        out = []
        for p in self.processes:
            seen[p.family] += 1
            out.append(p.family if counts[p.family] == 1 else f"{p.family}{seen[p.family]}")
        return tuple(out)

    @property
    def name(self) -> str:
        """Compact name, e.g. ``"2*GM+WN"``."""
        counts = Counter(_term_name(p) for p in self.processes)
        return "+".join(f"{c}*{n}" if c > 1 else n for n, c in counts.items())

    def __str__(self) -> str:
        return self.name

    @property
    def param_names(self) -> tuple[str, ...]:
        """Scalar parameter names, ``label.param`` (``label.phi[i]`` for vector parameters)."""
        out = []
        for label, p in zip(self.labels, self.processes):
            for spec in p.parameters():
                if spec.size == 1 and not isinstance(getattr(p, spec.name), tuple):
                    out.append(f"{label}.{spec.name}")
                else:
                    out.extend(f"{label}.{spec.name}[{i}]" for i in range(spec.size))
        return tuple(out)

    # ------------------------------------------------------------------ parameters
    @property
    def n_params(self) -> int:
        """Number of scalar parameters."""
        return sum(p.n_params for p in self.processes)

    @property
    def is_free(self) -> bool:
        """True when any parameter is free."""
        return any(p.is_free for p in self.processes)

    def free_mask(self) -> np.ndarray:
        """Boolean mask over :meth:`vector` marking the free scalars (whole parameters)."""
        mask = []
        for p in self.processes:
            for spec in p.parameters():
                mask.extend([getattr(p, spec.name) is None] * spec.size)
        return np.asarray(mask, dtype=bool)

    def _split(self, vec: np.ndarray) -> list[np.ndarray]:
        sizes = np.cumsum([p.n_params for p in self.processes])[:-1]
        return np.split(np.asarray(vec, dtype=np.float64).reshape(-1), sizes)

    def _check_size(self, vec: np.ndarray) -> np.ndarray:
        vec = np.asarray(vec, dtype=np.float64).reshape(-1)
        if vec.size != self.n_params:
            raise SpecError(f"model {self.name} has {self.n_params} parameters, got {vec.size} values")
        return vec

    def vector(self) -> np.ndarray:
        """All parameter values stacked (no parameter may be free)."""
        return np.concatenate([p.vector() for p in self.processes])

    def with_vector(self, vector: ArrayLike) -> Model:
        """A copy whose parameters take the values of `vector` (the inverse of :meth:`vector`)."""
        parts = self._split(self._check_size(vector))
        return attrs.evolve(self, processes=tuple(p.from_vector(v) for p, v in zip(self.processes, parts)))

    def to_unconstrained(self) -> np.ndarray:
        """Stacked unconstrained parameters."""
        return np.concatenate([p.to_unconstrained() for p in self.processes])

    def from_unconstrained(self, theta: ArrayLike) -> Model:
        """A copy with parameters mapped back from the unconstrained `theta`."""
        parts = self._split(self._check_size(theta))
        return self.with_processes(tuple(p.from_unconstrained(t) for p, t in zip(self.processes, parts)))

    def with_processes(self, processes: tuple[Process, ...]) -> Model:
        """A copy (same `freq`) whose components are `processes`: one Process per component
        of this model, each the image of its counterpart (``from_unconstrained``,
        ``from_vector`` ...). Built directly, without the constructor's checks of a new
        composition (an optimizer builds thousands of these)."""
        if len(processes) != len(self.processes) or not all(isinstance(p, Process) for p in processes):
            raise SpecError(f"model {self.name} takes {len(self.processes)} Process instances, "
                            f"got {processes!r}")
        new = object.__new__(Model)
        object.__setattr__(new, "processes", tuple(processes))
        object.__setattr__(new, "freq", self.freq)
        return new

    def transform_jacobian(self, theta: ArrayLike) -> np.ndarray:
        """Block-diagonal ``d vector / d theta`` at `theta`."""
        parts = self._split(self._check_size(theta))
        return block_diag(*[p.transform_jacobian(t) for p, t in zip(self.processes, parts)])

    def freed(self) -> Model:
        """A copy with every parameter free (the structure of the model only)."""
        return attrs.evolve(self, processes=tuple(p.freed() for p in self.processes))

    def start(self, wv: ArrayLike, *, rng: np.random.Generator | None = None) -> Model:
        """Fill free parameters with the families' starting values from an empirical Haar WV."""
        freq = self._freq()
        wv = np.asarray(wv, dtype=np.float64)
        counts = Counter(p.family for p in self.processes)
        seen: Counter[str] = Counter()
        procs = []
        for p in self.processes:
            index = seen[p.family]
            seen[p.family] += 1
            if p.is_free:
                guess = p.start(wv, freq, index=index, count=counts[p.family], rng=rng)
                fixed = {k: v for k, v in p.values().items() if v is not None}
                p = guess.with_values(**fixed) if fixed else guess
            procs.append(p)
        return attrs.evolve(self, processes=tuple(procs))

    def start_alternatives(self, wv: ArrayLike, *, template: Model | None = None) -> list[Model]:
        """Variants of :meth:`start`: one per alternative guess a free family offers
        (:meth:`Process.start_alternatives`), the other components at their start
        (`template`: ``self.start(wv)`` when the caller already has it)."""
        freq = self._freq()
        wv = np.asarray(wv, dtype=np.float64)
        if template is None:
            template = self.start(wv)
        counts = Counter(p.family for p in self.processes)
        seen: Counter[str] = Counter()
        variants = []
        for i, p in enumerate(self.processes):
            index = seen[p.family]
            seen[p.family] += 1
            if not p.is_free:
                continue
            fixed = {k: v for k, v in p.values().items() if v is not None}
            for guess in p.start_alternatives(wv, freq, index=index, count=counts[p.family]):
                guess = guess.with_values(**fixed) if fixed else guess
                procs = list(template.processes)
                procs[i] = guess
                variants.append(attrs.evolve(template, processes=tuple(procs)))
        return variants

    # ------------------------------------------------------------------ theory
    def wv(self, levels: int, wavelet: str = "haar") -> np.ndarray:
        """Theoretical wavelet variance at levels 1..`levels` (sum over processes), unit^2."""
        freq = self._freq()
        levels = check_positive_int(levels, name="levels")
        return np.sum([p.wv(levels, freq, wavelet) for p in self.processes], axis=0)

    def wv_jacobian(self, levels: int) -> np.ndarray:
        """Jacobian of :meth:`wv` with respect to :meth:`vector`, shape (levels, n_params)."""
        freq = self._freq()
        return np.hstack([p.wv_jacobian(levels, freq) for p in self.processes])

    def psd(self, f: ArrayLike) -> np.ndarray:
        """Two-sided PSD of the sum, unit^2/Hz, at `f` Hz."""
        freq = self._freq()
        f = np.asarray(f, dtype=np.float64)
        return np.sum([psd_of(p, f, freq) for p in self.processes], axis=0)

    def autocovariance(self, lags: ArrayLike) -> np.ndarray:
        """Autocovariance of the sum at integer `lags` (all components must be stationary)."""
        freq = self._freq()
        lags = np.asarray(lags)
        return np.sum([p.autocovariance(lags, freq) for p in self.processes], axis=0)

    def simulate(self, n: int, rng: np.random.Generator | int) -> np.ndarray:
        """Simulate `n` samples: the sum of independent simulations of the components.

        Each component draws from its own child generator spawned from `rng`, so a
        component's path does not depend on the others in the model.
        """
        freq = self._freq()
        n = check_positive_int(n, name="n")
        children = as_generator(rng).spawn(len(self.processes))
        total = None  # summed in place, in component order: the digits of np.sum(..., axis=0)
        for p, g in zip(self.processes, children):
            part = np.asarray(p.simulate(n, freq, g), dtype=np.float64)
            if part.shape != (n,):
                raise SpecError(f"{p.family}.simulate returned shape {part.shape} for "
                                f"n = {n} samples (the contract: an array of shape (n,))")
            if total is None:
                total = part.copy()
            else:
                total += part
        return total

    # ------------------------------------------------------------------ Kalman filter
    def augment(self, dt: float | None = None) -> StateSpaceBlock:
        """EKF state augmentation at filter step `dt` seconds (default: one sample period).

        Returns a :class:`~stochmod.core.statespace.StateSpaceBlock` with block-diagonal ``Phi``,
        ``Q``, ``P0`` (and ``F``, ``G``, ``Qc`` where every component has a continuous form),
        the output row ``H`` summing all blocks into the sensor reading, the summed white
        feed-through ``white_var`` and state names ``label.state``.
        """
        freq = self._freq()
        dt = 1.0 / freq if dt is None else dt
        blocks = [p.block(dt, freq).renamed(label) for label, p in zip(self.labels, self.processes)]
        return stack_blocks(blocks, dt)

    # ------------------------------------------------------------------ specs & reports
    def to_spec(self) -> dict[str, Any]:
        """JSON-safe dict spec; :func:`model_from_spec` reads it back."""
        spec: dict[str, Any] = {"processes": [p.to_spec() for p in self.processes]}
        if self.freq is not None:
            spec["freq"] = self.freq
        return spec

    def summary(self) -> str:
        """Table of parameters (canonical and physical)."""
        rows = []
        for label, p in zip(self.labels, self.processes):
            phys = p.physical(self.freq) if (self.freq and not p.is_free) else {}
            for name, v in p.values().items():
                rows.append([label, name, "free" if v is None else
                             (np.array2string(v, precision=6) if isinstance(v, np.ndarray) else v),
                             _param_unit(p, name)])
            for name, pv in phys.items():
                rows.append([label, name, pv.value, pv.unit])
        title = f"Model {self.name}" + (f" at {self.freq:g} Hz" if self.freq else "")
        return format_table(["process", "parameter", "value", "unit"], rows, title=title)


def _param_unit(p: Process, name: str) -> str:
    return next(s.unit for s in p.parameters() if s.name == name)


def _term_name(p: Process) -> str:
    args = [str(v) for v in p.structure().values()]
    return f"{p.family}({','.join(args)})" if args else p.family


def as_model(value: Model | Process) -> Model:
    """A :class:`Model` from a Model or a single Process."""
    if isinstance(value, Model):
        return value
    if isinstance(value, Process):
        return Model((value,))
    raise SpecError(f"expected a Model or a Process, got {value!r}")




def augment_axes(models: Mapping[str, Model], dt: float) -> AxesAugmentation:
    """Assemble one model per sensor axis into a block-diagonal augmentation with named states.

    Parameters
    ----------
    models : mapping of str to Model
        E.g. ``{"gyro_x": m1, "gyro_y": m2, ..., "accel_z": m6}`` (insertion order is kept).
    dt : float
        Filter step, s.

    Returns
    -------
    StateSpaceBlock
        States named ``axis.label.state``; ``H`` is replaced by the (n_axes, n_states)
        output matrix (row i sums axis i's blocks) and ``white_var`` by the vector of the
        axes' white feed-through variances. Ready to append to the navigation error states.
    """
    if not models:
        raise InputError("augment_axes needs at least one axis model")
    blocks = []
    for axis, model in models.items():
        if not isinstance(model, Model):
            raise SpecError(f"model for axis {axis!r} must be a Model, got {model!r}")
        blocks.append(model.augment(dt).renamed(axis))
    stacked = stack_blocks(blocks, dt)
    H = np.zeros((len(blocks), stacked.n_states))
    start = 0
    for i, b in enumerate(blocks):
        H[i, start : start + b.n_states] = b.H
        start += b.n_states
    return AxesAugmentation(stacked, H, np.array([b.white_var for b in blocks]), tuple(models))


@attrs.frozen
class AxesAugmentation:
    """Block-diagonal augmentation of several sensor axes.

    Attributes
    ----------
    block : StateSpaceBlock
        The stacked block (``Phi``, ``Q``, ``P0``, continuous form, state names).
    H : ndarray (n_axes, n_states)
        Output matrix: row i adds axis i's error states to its reading.
    white_var : ndarray (n_axes,)
        White feed-through variance per axis, per sample.
    axes : tuple of str
        Axis names, in row order of `H`.
    """

    block: StateSpaceBlock
    H: np.ndarray
    white_var: np.ndarray
    axes: tuple[str, ...]

    @property
    def Phi(self) -> np.ndarray:  # noqa: N802
        """Transition over dt."""
        return self.block.Phi

    @property
    def Q(self) -> np.ndarray:  # noqa: N802
        """Process noise over dt."""
        return self.block.Q

    @property
    def P0(self) -> np.ndarray:  # noqa: N802
        """Initial covariance."""
        return self.block.P0

    @property
    def state_names(self) -> tuple[str, ...]:
        """Named states ``axis.label.state``."""
        return self.block.state_names

    @property
    def n_states(self) -> int:
        """Number of augmented states."""
        return self.block.n_states
