"""Input checks shared by every estimator: one place that turns user input into
clean float64 arrays or raises an :class:`~stochmod.core.errors.InputError` naming the problem."""

from __future__ import annotations

import math
import numbers
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from stochmod.core.errors import InputError

__all__ = ["as_float_array", "as_signal", "as_signals", "check_alpha", "check_freq", "check_positive",
           "check_positive_int", "check_finite", "checked_values", "scalar_or_array"]


def as_float_array(x: ArrayLike, name: str) -> np.ndarray:
    try:
        arr = np.asarray(x)
    except Exception as exc:  # ragged lists and the like
        raise InputError(f"{name} could not be read as an array: {exc}") from exc
    if arr.dtype == object or not (
        np.issubdtype(arr.dtype, np.number) or np.issubdtype(arr.dtype, np.bool_)
    ):
        raise InputError(f"{name} must be numeric, got dtype {arr.dtype}")
    if np.iscomplexobj(arr):
        raise InputError(f"{name} must be real, got complex values")
    return arr.astype(np.float64, copy=False)


def checked_values(x: ArrayLike, name: str, *, sign: Literal["any", "nonneg", "pos"] = "any"
                   ) -> tuple[np.ndarray, bool]:
    """Finite float64 array and whether the input was a scalar; checks the sign asked for
    (:class:`InputError` naming `name` otherwise)."""
    arr = as_float_array(x, name)
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} must be finite, got {x!r}")
    if sign == "nonneg" and np.any(arr < 0):
        raise InputError(f"{name} must be non-negative, got {x!r}")
    if sign == "pos" and np.any(arr <= 0):
        raise InputError(f"{name} must be positive, got {x!r}")
    return arr, arr.ndim == 0


def scalar_or_array(arr: np.ndarray, scalar: bool) -> float | np.ndarray:
    """`arr` as a float when the input was a scalar (see :func:`checked_values`)."""
    return float(arr) if scalar else arr


def check_finite(arr: np.ndarray, name: str) -> None:
    # a float sum is finite only if every term is (NaN and inf propagate through it), and one
    # summing pass costs half of isfinite's mask; a sum that overflows is checked term by term
    with np.errstate(over="ignore", invalid="ignore"):
        total = float(np.add.reduce(arr, axis=None))
    if math.isfinite(total) or np.all(np.isfinite(arr)):
        return
    bad = np.flatnonzero(~np.isfinite(arr.reshape(-1)))
    kind = "NaN" if np.isnan(arr.reshape(-1)[bad[0]]) else "inf"
    raise InputError(
        f"{name} contains {bad.size} non-finite value(s) ({kind} at flat index {bad[0]}); "
        "stochmod never drops gaps silently: split the record into segments or fill them explicitly"
    )


def as_signal(x: ArrayLike, *, name: str = "x", min_length: int = 2,
              finite: bool = True) -> np.ndarray:
    """Return `x` as a finite, 1-D float64 array, or raise :class:`InputError`.

    Parameters
    ----------
    x : array_like
        The signal, shape ``(n,)`` (a ``(n, 1)`` column is accepted and flattened).
    name : str
        The argument's name, used in error messages.
    min_length : int
        The smallest acceptable number of samples.
    finite : bool
        Check that every value is finite (:func:`check_finite`). False leaves the check to a
        caller whose own first pass over `x` proves it (a sum over every sample is finite only
        if every sample is), and which then calls :func:`check_finite` when that sum is not.
    """
    arr = as_float_array(x, name)
    if arr.ndim == 2 and 1 in arr.shape:
        arr = arr.reshape(-1)
    if arr.ndim != 1:
        raise InputError(f"{name} must be one-dimensional, got shape {arr.shape}")
    if arr.size == 0:
        raise InputError(f"{name} is empty")
    if arr.size < min_length:
        raise InputError(f"{name} has {arr.size} sample(s); at least {min_length} are needed")
    if finite:
        check_finite(arr, name)
    return arr


def as_signals(x: ArrayLike, *, name: str = "x", min_length: int = 2) -> np.ndarray:
    """Return `x` as a finite float64 array of shape ``(n, k)`` (one column per axis).

    A 1-D input becomes a single column.
    """
    arr = as_float_array(x, name)
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2:
        raise InputError(f"{name} must be 1-D or 2-D (samples x axes), got shape {arr.shape}")
    if arr.shape[0] == 0 or arr.shape[1] == 0:
        raise InputError(f"{name} is empty (shape {arr.shape})")
    if arr.shape[0] < min_length:
        raise InputError(f"{name} has {arr.shape[0]} sample(s); at least {min_length} are needed")
    check_finite(arr, name)
    return arr


def check_freq(freq: float, *, name: str = "freq") -> float:
    """Return a sampling frequency in Hz as a positive finite float, or raise."""
    if freq.__class__ is float and 0.0 < freq < math.inf:  # the common case, no conversion
        return freq
    if isinstance(freq, bool) or not isinstance(freq, numbers.Real):
        raise InputError(f"{name} must be a positive number of Hz, got {freq!r}")
    value = float(freq)
    if not np.isfinite(value) or value <= 0:
        raise InputError(f"{name} must be a positive, finite number of Hz, got {freq!r}")
    return value


def check_positive_int(value: int, *, name: str, minimum: int = 1) -> int:
    """Return `value` as an int >= `minimum`, or raise :class:`InputError`."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise InputError(f"{name} must be an integer, got {value!r}")
    if value < minimum:
        raise InputError(f"{name} must be at least {minimum}, got {value}")
    return int(value)


def check_positive(value: float, *, name: str) -> float:
    """Return `value` as a positive finite float, or raise :class:`InputError` naming it."""
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a positive number, got {value!r}") from None
    if isinstance(value, bool) or not (np.isfinite(out) and out > 0):
        raise InputError(f"{name} must be a positive number, got {value!r}")
    return out


def check_alpha(alpha: float) -> float:
    """Return a significance level as a float in (0, 1), or raise :class:`InputError`."""
    try:
        value = float(alpha)
    except (TypeError, ValueError):
        raise InputError(f"alpha must be a number in (0, 1), got {alpha!r}") from None
    if isinstance(alpha, bool) or not 0.0 < value < 1.0:
        raise InputError(f"alpha must be a number in (0, 1), got {alpha!r}")
    return value
