"""Conformance checks of redundant-sensor combiners (re-exported by :mod:`stochmod.testing`).

:func:`check_combiner` calls a combiner's own ``combine`` (not through :func:`stochmod.combine`,
so that a plugin used directly is held to the contract too) on seeded simulated sensors and
verifies the properties every weighted mean ``sum_i w_i(t) x_i(t)`` with ``sum_i w_i(t) = 1``
has, whatever the weights:

``result``
    a :class:`~stochmod.redundant.combination.CombinationResult` with the shapes of the contract, finite,
    variance >= 0, weights summing to 1 (within 1e-9) at every sample, for ``(n, T)`` and
    ``(n, T, 3)`` inputs;
``equal_inputs``
    ``n`` copies of one signal give that signal back (any weights summing to 1 do);
``permutation``
    permuting the sensors permutes the weights and leaves the signal and variance unchanged;
``scale``
    multiplying every sensor by ``c`` (``2^-20``, IMU scale, and ``-2^7``; powers of two are
    exact in floating point) multiplies the signal by ``c``, the variance by ``c^2`` and leaves
    the weights unchanged;
``nan_refused``
    a NaN or an inf in one sensor raises a :class:`~stochmod.core.errors.StochmodError`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from stochmod.redundant.combination import check_combination
from stochmod.core.errors import StochmodError
from stochmod.plugin.registry import get_combiner

__all__ = ["check_combiner", "simulate_sensors", "COMBINER_CHECKS"]

#: Relative tolerance of the invariance checks (the combiners re-estimate on changed input).
RTOL = 1e-6


def simulate_sensors(n: int, length: int, rng: np.random.Generator, *, triads: bool = False) -> np.ndarray:
    """Seeded test input: one smooth common signal plus independent noise of unequal, time-varying
    levels per sensor (shape (n, length) or (n, length, 3))."""
    t = np.arange(length) / length
    shape = (n, length, 3) if triads else (n, length)
    common = np.sin(2 * np.pi * 3 * t) + 0.3 * t
    level = (0.5 + np.arange(n)) / n
    modulation = 1.0 + 0.5 * np.sin(2 * np.pi * (2 * t[None, :] + np.arange(n)[:, None] / n))
    if triads:
        common, modulation = common[:, None], modulation[:, :, None]
    return common + level.reshape((n,) + (1,) * (len(shape) - 1)) * modulation * rng.standard_normal(shape)


def _close(a: np.ndarray, b: np.ndarray, what: str, ref: float) -> float:
    err = float(np.max(np.abs(a - b))) / ref if ref > 0 else float(np.max(np.abs(a - b)))
    if not err <= RTOL:
        raise AssertionError(f"{what}: relative difference {err:.3g} > {RTOL:g}")
    return err


def _run(comb: Any, x: np.ndarray, options: Mapping[str, Any]) -> Any:
    return check_combination(comb.combine(x.copy(), **options), x, comb.name)


def _check_result(comb: Any, x: np.ndarray, x3: np.ndarray, options: Mapping[str, Any]) -> dict[str, Any]:
    res = _run(comb, x, options)
    res3 = _run(comb, x3, options)
    return {"weight_sum_error": float(np.max(np.abs(res.weights.sum(axis=0) - 1))),
            "triad_weight_sum_error": float(np.max(np.abs(res3.weights.sum(axis=0) - 1))),
            "mean_variance": float(np.mean(res.variance))}


def _check_equal(comb: Any, x: np.ndarray, options: Mapping[str, Any]) -> dict[str, Any]:
    same = np.broadcast_to(x[0], x.shape).copy()
    res = _run(comb, same, options)
    return {"rel_error": _close(res.signal, x[0], "n equal inputs do not give the input back",
                                float(np.max(np.abs(x[0]))))}


def _check_permutation(comb: Any, x: np.ndarray, base: Any, options: Mapping[str, Any],
                       rng: np.random.Generator) -> dict[str, Any]:
    perm = rng.permutation(x.shape[0])
    while x.shape[0] > 1 and np.all(perm == np.arange(x.shape[0])):
        perm = rng.permutation(x.shape[0])
    res = _run(comb, x[perm], options)
    ref = float(np.max(np.abs(base.signal)))
    return {
        "signal_rel_error": _close(res.signal, base.signal, "permuted sensors change the signal", ref),
        "weights_error": _close(res.weights, base.weights[perm], "weights do not follow the permutation", 1.0),
        "variance_rel_error": _close(res.variance, base.variance, "permuted sensors change the variance",
                                     float(np.max(base.variance))),
    }


def _check_scale(comb: Any, x: np.ndarray, base: Any, options: Mapping[str, Any]) -> dict[str, Any]:
    figures = {}
    for c in (2.0**-20, -(2.0**7)):
        res = _run(comb, c * x, options)
        ref = float(np.max(np.abs(base.signal)))
        figures[f"signal_rel_error({c:g})"] = _close(res.signal / c, base.signal,
                                                     f"scaling by {c:g} is not equivariant (signal)", ref)
        figures[f"weights_error({c:g})"] = _close(res.weights, base.weights,
                                                  f"scaling by {c:g} changes the weights", 1.0)
        figures[f"variance_rel_error({c:g})"] = _close(
            res.variance / c**2, base.variance, f"scaling by {c:g} is not equivariant (variance)",
            float(np.max(base.variance)))
    return figures


def _check_nan(comb: Any, x: np.ndarray, options: Mapping[str, Any]) -> dict[str, Any]:
    for bad in (np.nan, np.inf):
        y = x.copy()
        y[x.shape[0] // 2, x.shape[1] // 3] = bad
        try:
            comb.combine(y, **options)
        except StochmodError:
            continue
        raise AssertionError(f"a {bad} in one sensor was not refused with a StochmodError")
    return {"refused": 2}


COMBINER_CHECKS: tuple[str, ...] = ("result", "equal_inputs", "permutation", "scale", "nan_refused")


def check_combiner(combiner: Any, *, n: int = 4, length: int = 1024, rng: int | np.random.Generator = 0,
                   options: Mapping[str, Any] | None = None) -> dict[str, dict[str, Any]]:
    """Run every combiner check; return what each measured or raise listing every failure.

    Parameters
    ----------
    combiner : str or combiner object
        A registered name or the object a plugin returns from ``stochmod_combiners``.
    n : int
        Number of simulated sensors (>= 3 so that every first-party method applies).
    length : int
        Samples per sensor.
    rng : int or numpy.random.Generator
        Seed of the simulated input.
    options : mapping, optional
        Options passed to every ``combine`` call (e.g. fixed GARCH orders for speed).

    Returns
    -------
    dict
        Check name -> figures (relative errors, weight-sum errors).

    Raises
    ------
    AssertionError
        One or more checks failed; the message lists each with its reason.
    """
    comb = get_combiner(combiner) if isinstance(combiner, str) else combiner
    gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    options = dict(options or {})
    x = simulate_sensors(n, length, gen)
    x3 = simulate_sensors(n, length, gen, triads=True)
    figures: dict[str, dict[str, Any]] = {}
    failures: list[str] = []

    def attempt(name: str, fn: Callable[[], dict[str, Any]]) -> None:
        try:
            figures[name] = fn()
        except AssertionError as exc:
            failures.append(f"[{name}] {exc}")
        except Exception as exc:  # noqa: BLE001 - a crash is a failure, reported with its type
            failures.append(f"[{name}] {type(exc).__name__}: {exc}")

    attempt("result", lambda: _check_result(comb, x, x3, options))
    attempt("equal_inputs", lambda: _check_equal(comb, x, options))
    try:
        base = _run(comb, x, options)
    except Exception as exc:  # noqa: BLE001
        failures.append(f"[permutation, scale] no base result: {type(exc).__name__}: {exc}")
    else:
        attempt("permutation", lambda: _check_permutation(comb, x, base, options, gen))
        attempt("scale", lambda: _check_scale(comb, x, base, options))
    attempt("nan_refused", lambda: _check_nan(comb, x, options))
    if failures:
        raise AssertionError(f"combiner {getattr(comb, 'name', comb)!r} fails {len(failures)} "
                             "check(s):\n" + "\n".join(failures))
    return figures
