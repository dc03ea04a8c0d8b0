"""Combining redundant sensors: the result every combiner returns, and :func:`combine`.

A *combiner* (plugin point ``stochmod_combiners``, see :mod:`stochmod.plugin.hookspecs`) fuses ``n``
time-aligned recordings of one quantity, an ``(n, T)`` array (one axis of ``n`` sensors) or an
``(n, T, 3)`` array (triads), into a synthetic signal ``sum_i w_i(t) x_i(t)`` with weights that
sum to one at every sample, and estimates the per-sample variance of the synthetic signal's
error (Waegli et al. 2010, eqs. 1 and 12). The core names no combiner: they are plugins,
listed by :func:`stochmod.combiner_names`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol, runtime_checkable

import attrs
import numpy as np
from numpy.typing import ArrayLike

from stochmod.core.fields import array_field
from stochmod.core.checks import as_float_array, check_finite
from stochmod.core.errors import EstimationError, InputError
from stochmod.plugin.registry import get_combiner
from stochmod.core.tables import format_table

__all__ = [
    "Combiner",
    "CombinationResult",
    "as_sensor_array",
    "combine",
    "residuals_from_mean",
    "check_combination",
    "synthetic_wv",
    "WEIGHT_TOLERANCE",
]

#: Largest accepted ``|sum_i w_i(t) - 1|``.
WEIGHT_TOLERANCE = 1e-9


@runtime_checkable
class Combiner(Protocol):
    """What a combiner plugin provides (see :meth:`StochmodSpec.stochmod_combiners`)."""

    name: str
    description: str
    assumes: str

    def combine(self, x: np.ndarray, **options: Any) -> CombinationResult:
        """Fuse `x` of shape (n, T) or (n, T, 3) into a :class:`CombinationResult`."""


def as_sensor_array(x: ArrayLike, *, name: str = "x", min_sensors: int = 2,
                    min_length: int = 2) -> np.ndarray:
    """Return `x` as a finite float64 array of shape ``(n, T)`` or ``(n, T, 3)``, or raise.

    Parameters
    ----------
    x : array_like
        ``n`` time-aligned recordings of one axis, shape (n, T), or of triads, shape (n, T, 3);
        a list of equal-length 1-D arrays is accepted.
    name : str
        The argument's name in error messages.
    min_sensors : int
        Fewest sensors the caller needs.
    min_length : int
        Fewest samples per sensor.

    Raises
    ------
    InputError
        Wrong shape, too few sensors or samples, non-numeric, NaN or inf.
    """
    arr = as_float_array(x, name)
    if arr.ndim not in (2, 3) or (arr.ndim == 3 and arr.shape[2] != 3):
        raise InputError(
            f"{name} must have shape (n_sensors, T) or (n_sensors, T, 3), got {arr.shape}"
        )
    if arr.shape[0] < min_sensors:
        raise InputError(f"{name} holds {arr.shape[0]} sensor(s); this method needs at least {min_sensors}")
    if arr.shape[1] < min_length:
        raise InputError(f"{name} has {arr.shape[1]} sample(s) per sensor; at least {min_length} are needed")
    check_finite(arr, name)
    return arr


def residuals_from_mean(x: np.ndarray) -> np.ndarray:
    """Least-squares residuals ``x_i(t) - mean_k x_k(t)`` of each sensor (the residuals of eq. 2).

    Their sum over the sensors is zero at every sample; for independent sensors of variances
    ``s_i^2`` their variance is ``s_i^2 (1 - 2/n) + sum_k s_k^2 / n^2``, smaller than the
    error's on average (eq. 4).
    """
    return x - x.mean(axis=0, keepdims=True)


def _noise_reduction(variance: np.ndarray, sensor_variance: np.ndarray | None) -> float | None:
    """``1 - sqrt(mean variance of the synthetic / mean variance of the sensors)``."""
    if sensor_variance is None:
        return None
    mean_sensor = float(np.mean(sensor_variance))
    if not mean_sensor > 0:
        return None
    return 1.0 - float(np.sqrt(np.mean(variance) / mean_sensor))


@attrs.frozen
class CombinationResult:
    """A synthetic signal from ``n`` redundant sensors.

    Attributes
    ----------
    signal : ndarray, shape (T,) or (T, 3)
        The synthetic signal, in the sensors' unit u.
    weights : ndarray, shape (n, T) or (n, T, 3)
        Weight of each sensor at each sample; they sum to 1 over the sensors.
    variance : ndarray, shape (T,) or (T, 3)
        Estimated variance of the synthetic signal's error at each sample, u^2.
    method : str
        Name of the combiner.
    assumes : str
        What the combiner assumes of the sensors' errors.
    sensor_variance : ndarray or None
        Estimated error variance of each sensor, shape (n,), (n, 3), (n, T) or (n, T, 3), u^2,
        where the method estimates it (``None`` otherwise).
    sensors : tuple
        Per-sensor fits (objects with ``summary()``), where the method fits one per sensor and
        axis (GARCH), in sensor-major order.
    info : dict
        Other figures of the method (window, chosen orders, ...), JSON-safe scalars.
    """

    signal: np.ndarray = array_field()
    weights: np.ndarray = array_field()
    variance: np.ndarray = array_field()
    method: str
    assumes: str
    sensor_variance: np.ndarray | None = attrs.field(default=None, eq=False)
    sensors: tuple[Any, ...] = attrs.field(default=(), eq=False)
    info: dict[str, Any] = attrs.field(factory=dict, eq=False)

    @property
    def n_sensors(self) -> int:
        """Number of sensors combined."""
        return int(self.weights.shape[0])

    @property
    def noise_reduction(self) -> float | None:
        """``1 - sqrt(mean variance / mean sensor variance)``: 0.5 for the mean of 4 equal sensors.

        ``None`` when the method does not estimate the sensors' variances.
        """
        return _noise_reduction(self.variance, self.sensor_variance)

    def summary(self) -> str:
        """Per-sensor mean weight (and variance where estimated), then each sensor's own fit."""
        n = self.n_sensors
        mean_w = self.weights.reshape(n, -1).mean(axis=1)
        sv = None
        if self.sensor_variance is not None:
            sv = np.asarray(self.sensor_variance).reshape(n, -1).mean(axis=1)
        rows = [[i, mean_w[i], "-" if sv is None else sv[i],
                 self.weights[i].min(), self.weights[i].max()] for i in range(n)]
        shape = "x".join(str(s) for s in self.signal.shape)
        nr = self.noise_reduction
        title = (f"Combination {self.method!r} of {n} sensors ({shape} samples); assumes: "
                 f"{self.assumes}\nmean variance of the synthetic signal "
                 f"{float(np.mean(self.variance)):.6g} u^2"
                 + ("" if nr is None else f"; noise reduction {100 * nr:.1f}%"))
        text = format_table(["sensor", "mean weight", "mean variance [u^2]", "min weight",
                             "max weight"], rows, title=title)
        if self.info:
            text += "\n" + ", ".join(f"{k} = {v}" for k, v in self.info.items())
        for fit in self.sensors:
            text += "\n\n" + fit.summary()
        return text


def synthetic_wv(models: Sequence[Any], weights: ArrayLike, levels: int) -> np.ndarray:
    """Predicted Haar wavelet variance of a synthetic signal from its members' models, u^2.

    For independent sensors with static weights ``w_i`` (summing to 1), the synthetic error
    ``sum_i w_i e_i`` has ``nu(tau_j) = sum_i w_i^2 nu_i(tau_j)`` at levels ``j = 1..levels``.

    Parameters
    ----------
    models : sequence of Model
        Each member's fitted model, bound to the common sampling frequency.
    weights : array_like, shape (n,)
        The static weights.
    levels : int
        Number of levels J.
    """
    w = np.asarray(weights, dtype=np.float64)
    if w.shape != (len(models),):
        raise InputError(f"weights must have shape ({len(models)},), got {w.shape}")
    if not abs(w.sum() - 1.0) <= WEIGHT_TOLERANCE or np.any(~np.isfinite(w)):
        raise InputError(f"weights must be finite and sum to 1, got {w}")
    return np.sum([wi * wi * m.wv(levels) for wi, m in zip(w, models)], axis=0)


def check_combination(result: Any, x: np.ndarray, method: str) -> CombinationResult:
    """Verify what a combiner returned: its type, shapes, finiteness and weight sums."""
    if not isinstance(result, CombinationResult):
        raise EstimationError(f"combiner {method!r} returned {type(result).__name__}, "
                              "not a CombinationResult")
    out_shape = x.shape[1:]
    for field, shape in (("signal", out_shape), ("weights", x.shape), ("variance", out_shape)):
        arr = getattr(result, field)
        if not isinstance(arr, np.ndarray) or arr.shape != shape:
            got = getattr(arr, "shape", type(arr).__name__)
            raise EstimationError(f"combiner {method!r} returned {field} of shape {got}; expected {shape}")
        if not np.all(np.isfinite(arr)):
            raise EstimationError(f"combiner {method!r} returned non-finite {field}")
    if np.any(result.variance < 0):
        raise EstimationError(f"combiner {method!r} returned a negative variance")
    err = float(np.max(np.abs(result.weights.sum(axis=0) - 1.0)))
    if err > WEIGHT_TOLERANCE:
        raise EstimationError(f"combiner {method!r} returned weights whose sums differ from 1 by {err:.3g}")
    return result


def combine(x: ArrayLike | Sequence[ArrayLike], method: str = "mean", **options: Any) -> CombinationResult:
    """Fuse redundant sensors into one synthetic signal with the combiner `method`.

    Parameters
    ----------
    x : array_like, shape (n, T) or (n, T, 3)
        One axis of ``n`` time-aligned sensors (or their triads), in the signal unit u.
    method : str
        A registered combiner (:func:`stochmod.combiner_names`): first-party ``"mean"``
        (eq. 1), ``"averaged-volatility"`` (eqs. 2-3), ``"garch"`` (eqs. 7-12),
        ``"inverse-variance"`` (static weights from each sensor's model).
    **options
        Passed to the combiner (see its docstring, or ``stochmod combiners``).

    Returns
    -------
    CombinationResult
        ``.signal``, ``.weights`` (n, ...), ``.variance`` and ``summary()``.

    Raises
    ------
    InputError
        Unknown method, wrong shape, NaN/inf, fewer than 2 sensors.
    EstimationError
        The combiner returned an inconsistent result.
    """
    comb = get_combiner(method)
    arr = as_sensor_array(x)
    return check_combination(comb.combine(arr, **options), arr, method)
