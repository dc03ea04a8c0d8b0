"""A GMWM weighting written as a third party would: the relative (flattened) weighting.

``Omega = diag(1 / nu_hat_j^2)``: eq. 20 becomes ``sum_j (1 - nu_j(theta) / nu_hat_j)^2``, the
flattened criterion of eq. 34 of Stebler et al. (2014), which weighs every level's relative
misfit alike. It needs neither the signal nor a first fit. Registered by the package's
``stochmod_weightings`` hook; use it as ``stochmod.gmwm(x, "MA1+RW", freq, weighting="relative")``.
"""

from __future__ import annotations

from typing import Any, ClassVar

import attrs
import numpy as np

from stochmod import sdk
from stochmod.sdk import Weighting, WeightingInput, WeightingMatrix

__all__ = ["RelativeWeighting", "RELATIVE", "stochmod_weightings"]


@attrs.frozen
class RelativeWeighting(Weighting):
    """``Omega = diag(1 / nu_hat_j^2)`` (unit^-4): relative least squares on the WV; needs
    neither the signal nor a first fit (the base class's defaults)."""

    name: ClassVar[str] = "relative"
    description: ClassVar[str] = "inverse squared empirical WV: relative misfit per level (eq. 34)"

    def matrix(self, data: WeightingInput) -> WeightingMatrix:
        """The diagonal of inverse squared empirical WVs, levels 1..J."""
        nu = np.asarray(data.empirical.wv[: data.levels], dtype=float)
        if np.any(~(nu > 0)):
            raise sdk.InputError("the relative weighting needs a positive wavelet variance")
        return WeightingMatrix(np.diag(1.0 / nu**2))


#: The instance the hook registers.
RELATIVE = RelativeWeighting()


@sdk.hookimpl
def stochmod_weightings() -> list[Any]:
    """Register the relative weighting."""
    return [RELATIVE]
