"""The GARCH-weighted synthetic IMU (Waegli et al. 2010, Section 5, eqs. 7-12).

For each sensor i (and axis j), on the least-squares residuals ``r_i(t) = x_i(t) - mean_k x_k(t)``:

1. an ARMA(p, q) mean model (eq. 10), orders chosen by AIC (Table 1), gives the predictable
   part ``E[r_i(t) | past]`` and the innovations ``e_i(t)``;
2. a zero-mean GARCH(p, q) (eq. 7) fitted to ``e_i`` by Gaussian maximum likelihood, orders
   grown from (1, 1) until Engle's LM test finds no ARCH effect left, gives the conditional
   variance ``sigma_i^2(t)``;
3. the weighted synthetic signal (eq. 12) ``sum_i w_i(t) (x_i(t) - E[r_i(t) | past])`` with
   ``w_i(t) = sigma_i^-2(t) / sum_k sigma_k^-2(t)``, whose error variance is estimated as
   ``1 / sum_i sigma_i^-2(t)``.

The estimators are the core's :func:`stochmod.fit.arma.select_arma` and
:func:`stochmod.fit_garch` (they scale the data inside: IMU-scale inputs work as given).
"""

from __future__ import annotations

import concurrent.futures
from typing import TYPE_CHECKING, Any, ClassVar

import attrs
import numpy as np

from stochmod.sdk import (
    CombinationResult,
    InputError,
    as_sensor_array,
    check_positive_int,
    hookimpl,
    prepare_garch,
    residuals_from_mean,
)

if TYPE_CHECKING:  # the estimators are imported where they run (they import scipy.signal)
    from stochmod.sdk import ArmaFit, GarchFit

__all__ = ["GarchCombiner", "SensorVolatility", "stochmod_combiners"]


@attrs.frozen
class SensorVolatility:
    """The mean and volatility models of one sensor's residuals on one axis."""

    sensor: int
    axis: int | None
    arma: ArmaFit
    garch: GarchFit

    def summary(self) -> str:
        """The ARMA table (Table 1) then the GARCH table (Table 2) of this sensor."""
        where = f"sensor {self.sensor}" + ("" if self.axis is None else f", axis {self.axis}")
        return f"--- {where}\n{self.arma.summary()}\n{self.garch.summary()}"


def _orders(value: Any, name: str) -> tuple[int, int] | None:
    """``(p, q)`` from a pair, or None for automatic selection (``"aic"`` / ``"lm"``)."""
    if isinstance(value, str):
        return None
    try:
        p, q = (int(v) for v in value)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a pair (p, q) or the automatic choice, got {value!r}") from None
    return p, q


def _fit_axis(r: np.ndarray, sensor: int, axis: int | None, arma: Any, garch: Any,
              max_order: int, lags: int, select_samples: int
              ) -> tuple[np.ndarray, np.ndarray, SensorVolatility]:
    """Conditional mean (T,), conditional variance (T,) and the fits of one residual series."""
    from stochmod.sdk import fit_arma, fit_garch, select_arma, select_garch

    arma_order = _orders(arma, "arma")
    if arma_order is None:
        arma_order = select_arma(r[:select_samples], max_p=max_order, max_q=max_order).order
    mean_fit = fit_arma(r, *arma_order)
    e = mean_fit.innovations(r)
    p = mean_fit.order[0]
    garch_order = _orders(garch, "garch")
    vol = (select_garch(e[p:], max_p=max_order, max_q=max_order, lags=lags) if garch_order is None
           else fit_garch(e[p:], *garch_order, lags=lags))
    s2 = np.empty_like(r)
    s2[p:] = vol.conditional_variance
    s2[:p] = vol.conditional_variance[0]
    return r - e, s2, SensorVolatility(sensor, axis, mean_fit, vol)


@attrs.frozen
class GarchCombiner:
    """Weights ``1 / sigma_i^2(t)`` from per-sensor ARMA + GARCH fits (eq. 12)."""

    name: ClassVar[str] = "garch"
    description: ClassVar[str] = ("weighted synthetic IMU: per-sensor ARMA mean + GARCH volatility, "
                                  "weights 1/sigma_i^2(t) (eqs. 7-12)")
    assumes: ClassVar[str] = ("independent sensors; each sensor's residual is ARMA with GARCH(p,q) "
                              "Gaussian innovations (volatility may differ by sensor and vary in "
                              "time); residuals from the mean stand in for errors")

    def combine(self, x: Any, *, arma: Any = "aic", garch: Any = "lm", max_order: int = 2,
                lags: int = 10, select_samples: int = 2**15, workers: int | None = None
                ) -> CombinationResult:
        """Fit each sensor and axis, then weight by the inverse conditional variances.

        Parameters
        ----------
        x : array_like, shape (n, T) or (n, T, 3)
            Time-aligned sensors, unit u (any scale).
        arma : "aic" or (p, q)
            ARMA orders of the mean model: chosen by AIC up to ``(max_order, max_order)`` on the
            first `select_samples` samples (then fitted on all), or fixed.
        garch : "lm" or (p, q)
            GARCH orders: grown until the LM test passes, or fixed.
        max_order : int
            Largest order tried by the automatic choices.
        lags : int
            Lags of Engle's LM test.
        select_samples : int
            Samples of the AIC order choice (the first ones; default 2^15).
        workers : int, optional
            Processes fitting the sensors (and axes) in parallel; None or 1: one after another
            in this process. The fits are independent, so the result is the serial one.
        """
        select_samples = check_positive_int(select_samples, name="select_samples", minimum=100)
        workers = 1 if workers is None else check_positive_int(workers, name="workers")
        x = as_sensor_array(x, min_length=100)
        n = x.shape[0]
        r = residuals_from_mean(x)
        triad = x.ndim == 3
        if not np.any(r):  # the sensors agree exactly: nothing to weight, no error seen
            return CombinationResult(
                signal=x[0].copy(), weights=np.full(x.shape, 1.0 / n),
                variance=np.zeros(x.shape[1:]), method=self.name, assumes=self.assumes,
                sensor_variance=np.zeros(x.shape), info={"note": "identical sensors"})
        cols = [(i, j) for i in range(n) for j in (range(x.shape[2]) if triad else [None])]
        index = [(i, slice(None), j) if triad else (i,) for i, j in cols]
        series = [np.ascontiguousarray(r[idx]) for idx in index]
        common = (arma, garch, max_order, lags, select_samples)
        args = [(s, i, j, *common) for s, (i, j) in zip(series, cols)]
        if workers > 1 and len(cols) > 1:
            # the worker processes inherit this one's libraries and their settings (BLAS
            # threads included), so their sums round as here: the serial result exactly;
            # and the compiled GARCH pass, loaded once here
            prepare_garch()
            with concurrent.futures.ProcessPoolExecutor(max_workers=min(workers, len(cols))) as pool:
                outs = list(pool.map(_fit_axis, *zip(*args)))
        else:
            outs = [_fit_axis(*a) for a in args]
        mean = np.empty_like(x)
        s2 = np.empty_like(x)
        fits = []
        for idx, (m, v, fit) in zip(index, outs):
            mean[idx], s2[idx] = m, v
            fits.append(fit)
        inv = 1.0 / s2
        total = inv.sum(axis=0)
        weights = inv / total
        return CombinationResult(
            signal=np.sum(weights * (x - mean), axis=0), weights=weights, variance=1.0 / total,
            method=self.name, assumes=self.assumes, sensor_variance=s2, sensors=tuple(fits),
            info={"arma": arma if isinstance(arma, str) else tuple(arma),
                  "garch": garch if isinstance(garch, str) else tuple(garch), "lags": lags,
                  "orders": ", ".join(f"{f.sensor}{'' if f.axis is None else '.' + str(f.axis)}: "
                                      f"ARMA{f.arma.order} GARCH{f.garch.order}" for f in fits)},
        )


@hookimpl
def stochmod_combiners() -> list[Any]:
    return [GarchCombiner()]
