"""A third party's combiner: the sample median of redundant sensors (robust to one faulty sensor).

At each sample the median of ``n`` readings is a weighted mean whose weights select the middle
order statistic (odd ``n``: weight 1 on it; even ``n``: 1/2 on each of the two middle ones), so
the weights sum to 1 and the combiner contract applies unchanged. Its error variance is
estimated for independent Gaussian sensors of one common level ``s^2`` as the median's
asymptotic ``pi s^2 / (2 n)``, ``s`` from the median absolute deviation of the readings about
the median (``1.4826 MAD``, pooled over time).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from stochmod import sdk
from stochmod.sdk import as_sensor_array

__all__ = ["MedianCombiner"]


class MedianCombiner:
    """Sample median of the sensors at every sample."""

    name: ClassVar[str] = "median"
    description: ClassVar[str] = "sample median of the sensors (robust to a faulty one)"
    assumes: ClassVar[str] = ("independent sensors with one common Gaussian error level; a minority "
                              "may be faulty (outliers are ignored, not weighted)")

    def combine(self, x: Any, **options: Any) -> sdk.CombinationResult:
        """Median over the sensors of `x` (n, T) or (n, T, 3); takes no options."""
        if options:
            raise sdk.InputError(f"the 'median' combiner takes no options, got {sorted(options)}")
        x = as_sensor_array(x, min_sensors=3)
        n = x.shape[0]
        order = np.argsort(x, axis=0, kind="stable")
        weights = np.zeros_like(x)
        middle = [n // 2] if n % 2 else [n // 2 - 1, n // 2]
        for k in middle:
            np.put_along_axis(weights, order[k : k + 1], 1.0 / len(middle), axis=0)
        signal = np.sum(weights * x, axis=0)
        mad = np.median(np.abs(x - signal), axis=0).mean(axis=0)  # per axis
        s2 = (1.4826 * mad) ** 2
        return sdk.CombinationResult(
            signal=signal, weights=weights, variance=np.broadcast_to(np.pi * s2 / (2 * n), signal.shape).copy(),
            method=self.name, assumes=self.assumes,
            sensor_variance=np.broadcast_to(s2, (n, *np.shape(s2))).copy(),
        )
