"""Averaged volatilities (Waegli et al. 2010, eqs. 2-3): a moving-window variance shared by all sensors.

With ``r_{j,i}(t) = x_{j,i}(t) - mean_k x_{j,k}(t)`` the least-squares residuals of sensor i on
axis j, the error variance at time t is estimated over the window ``t - T .. t + T`` as

    sigma_t^2(T) = 1 / ((m_t - 1) n k) sum_i sum_k sum_j (r_{j,i}(k) - rbar_j(t))^2,

``rbar_j(t)`` the mean of the residuals of axis j over the window and the sensors (eq. 3),
``m_t = 2T + 1`` samples inside the record (fewer at its ends), ``k`` the number of axes pooled
(3 for triads: eq. 2's ``6 T n``). The synthetic signal is the plain mean (eq. 1) and its
variance ``sigma_t^2 / n``.

Caveat (eq. 4): residuals from the mean are not errors. For independent sensors of equal
variance ``s^2``, ``E[r^2] = s^2 (n - 1) / n``: the estimate is low by the factor
``(n - 1) / n`` (25 % for n = 4), because the mean is the value that minimises the sum of
squares. ``correct_residuals=True`` divides by that factor; the paper does not.
"""

from __future__ import annotations

from typing import Any, ClassVar

import attrs
import numpy as np

from stochmod.sdk import (
    CombinationResult,
    as_sensor_array,
    check_positive_int,
    hookimpl,
    residuals_from_mean,
)

__all__ = ["AveragedVolatility", "moving_sum", "stochmod_combiners"]


def moving_sum(a: np.ndarray, half_window: int) -> np.ndarray:
    """Sum of ``a[t - T .. t + T]`` along axis 0, truncated at the ends (cumulative sums)."""
    c = np.concatenate([np.zeros((1, *a.shape[1:])), np.cumsum(a, axis=0)])
    t = np.arange(a.shape[0])
    hi = np.minimum(t + half_window + 1, a.shape[0])
    lo = np.maximum(t - half_window, 0)
    return c[hi] - c[lo]


@attrs.frozen
class AveragedVolatility:
    """Moving-window variance of the residuals, pooled over sensors and axes (eqs. 2-3)."""

    name: ClassVar[str] = "averaged-volatility"
    description: ClassVar[str] = ("synthetic IMU with a moving-window variance of the least-squares "
                                  "residuals pooled over sensors and axes (eqs. 2-3)")
    assumes: ClassVar[str] = ("independent sensors sharing one error variance, constant within "
                              "each window of 2T+1 samples; residuals stand in for errors (eq. 4: "
                              "biased low by (n-1)/n unless corrected)")

    def combine(self, x: Any, *, half_window: int = 100, correct_residuals: bool = False
                ) -> CombinationResult:
        """Equal weights; variance from eq. 2 with window ``2 half_window + 1`` samples.

        Parameters
        ----------
        x : array_like, shape (n, T) or (n, T, 3)
            Time-aligned sensors, unit u; triads pool their three axes (eq. 2).
        half_window : int
            ``T`` of eq. 2 (samples), >= 1.
        correct_residuals : bool
            Multiply by ``n / (n - 1)`` (unbiased for equal independent sensors; see eq. 4).
        """
        half_window = check_positive_int(half_window, name="half_window")
        x = as_sensor_array(x)
        n = x.shape[0]
        r = residuals_from_mean(x)
        axes = 1 if r.ndim == 2 else r.shape[2]
        per_t = r.sum(axis=0)  # (T,) or (T, 3)
        sq_t = (r * r).sum(axis=0)
        s1 = moving_sum(per_t, half_window)
        s2 = moving_sum(sq_t, half_window)
        m = moving_sum(np.ones(r.shape[1]), half_window)
        mm = m if r.ndim == 2 else m[:, None]
        ss = s2 - s1 * s1 / (mm * n)  # sum_i sum_k (r - rbar_j(t))^2, per axis
        if r.ndim == 3:
            ss = ss.sum(axis=1)
        sigma2 = np.maximum(ss, 0.0) / ((m - 1) * n * axes)
        if correct_residuals:
            sigma2 = sigma2 * n / (n - 1)
        if r.ndim == 3:
            sigma2 = np.repeat(sigma2[:, None], 3, axis=1)
        return CombinationResult(
            signal=x.mean(axis=0), weights=np.full(x.shape, 1.0 / n), variance=sigma2 / n,
            method=self.name, assumes=self.assumes,
            sensor_variance=np.broadcast_to(sigma2, x.shape).copy(),
            info={"half_window": half_window, "window_samples": 2 * half_window + 1,
                  "correct_residuals": bool(correct_residuals)},
        )


@hookimpl
def stochmod_combiners() -> list[Any]:
    return [AveragedVolatility()]
