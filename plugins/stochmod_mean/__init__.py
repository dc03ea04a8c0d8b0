"""The synthetic IMU (Waegli et al. 2010, eq. 1): the plain mean of ``n`` redundant sensors.

Every sensor gets the weight ``1/n``. Under the method's assumption (independent sensors with
one common, constant error variance ``s^2``) the synthetic signal's error variance is ``s^2 / n``,
a noise reduction of ``1 - 1/sqrt(n)`` (50 % for four sensors; the paper measured 48.6 %).
``s^2`` is estimated from the least-squares residuals ``r_i(t) = x_i(t) - mean_k x_k(t)``:
``s^2 = mean_t sum_i r_i(t)^2 / (n - 1)`` per axis, unbiased under the assumption.
"""

from __future__ import annotations

from typing import Any, ClassVar

import attrs
import numpy as np

from stochmod.sdk import (
    CombinationResult,
    InputError,
    as_sensor_array,
    hookimpl,
    residuals_from_mean,
)

__all__ = ["MeanCombiner", "stochmod_combiners"]


@attrs.frozen
class MeanCombiner:
    """Equal weights ``1/n`` (eq. 1); one constant error variance per axis, estimated."""

    name: ClassVar[str] = "mean"
    description: ClassVar[str] = "synthetic IMU: the plain mean of the sensors (eq. 1)"
    assumes: ClassVar[str] = ("independent sensors with one common error variance, constant in "
                              "time; no bias between sensors")

    def combine(self, x: Any, **options: Any) -> CombinationResult:
        """Mean of `x` (n, T) or (n, T, 3) over the sensors; takes no options."""
        if options:
            raise InputError(f"the 'mean' combiner takes no options, got {sorted(options)}")
        x = as_sensor_array(x)
        n = x.shape[0]
        r = residuals_from_mean(x)
        s2 = np.sum(r * r, axis=0).mean(axis=0) / (n - 1)  # per axis: scalar or (3,)
        signal = x.mean(axis=0)
        return CombinationResult(
            signal=signal, weights=np.full(x.shape, 1.0 / n),
            variance=np.broadcast_to(s2 / n, signal.shape).copy(), method=self.name,
            assumes=self.assumes, sensor_variance=np.broadcast_to(s2, (n, *np.shape(s2))).copy(),
        )


@hookimpl
def stochmod_combiners() -> list[Any]:
    return [MeanCombiner()]
