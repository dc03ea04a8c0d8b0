"""White noise (WN): the stochmod plugin for the family ``WN(sigma2)``.

``X_t = W_t``, ``W_t ~ N(0, sigma2)`` i.i.d., sigma2 the variance per sample at the
model's sampling frequency ``freq``. Physical view: the noise density
``N = sqrt(sigma2 / freq)`` (u*sqrt(s), i.e. u/sqrt(Hz): angle or velocity random walk).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import attrs
import numpy as np
from numpy.typing import ArrayLike

from stochmod.sdk import (
    Parameter,
    PhysicalValue,
    Process,
    ScaledFamily,
    as_generator,
    check_coefficients,
    check_freq,
    hookimpl,
    wn_density,
)

__all__ = ["WN", "stochmod_processes"]


@attrs.frozen
class WN(ScaledFamily):
    """Gaussian white noise with variance `sigma2` per sample (signal unit^2).

    Its WV is ``sigma2 / 2^j`` for every wavelet (:class:`~stochmod.sdk.ScaledFamily` gives
    ``wv``, ``wv_jacobian`` and the vectorised rows from :meth:`haar_factor`).

    Parameters
    ----------
    sigma2 : float, optional
        Variance per sample, u^2; free when None.
    """

    sigma2: float | None = None

    family: ClassVar[str] = "WN"
    description: ClassVar[str] = "Gaussian white noise (angle/velocity random walk)"
    parameter_specs: ClassVar[tuple[Parameter, ...]] = (
        Parameter("sigma2", "positive", "u^2", "variance per sample", role="variance"),
    )
    lattice_copies: ClassVar[int] = 1
    lattice_rank: ClassVar[int] = 20
    ieee952: ClassVar[tuple[tuple[str, ...], ...]] = (("N",),)
    factor_for_every_wavelet: ClassVar[bool] = True

    @classmethod
    def from_density(cls, N: float, freq: float) -> WN:
        """White noise of density `N` (u*sqrt(s) = u/sqrt(Hz), Allan variance N^2/tau) at `freq` Hz."""
        return cls(sigma2=float(N) ** 2 * float(freq))

    @classmethod
    def from_ieee952(cls, coefficients: Mapping[str, Any], freq: float) -> WN:
        """White noise of the IEEE coefficient ``N`` (u*sqrt(s)) at `freq` Hz: ``sigma2 = N^2 freq``."""
        c = check_coefficients(coefficients, cls.ieee952_set(coefficients), "WN.from_ieee952")
        return cls.from_density(c["N"], check_freq(freq))

    def to_ieee952(self, freq: float, names: tuple[str, ...]) -> dict[str, float]:
        """``{"N": sqrt(sigma2 / freq)}``."""
        self.require_values()
        return {"N": float(wn_density(self.sigma2, freq))}

    def ordering_key(self) -> float:
        """``sigma2`` (u^2): the larger first."""
        self.require_values()
        return float(self.sigma2)

    @classmethod
    def haar_factor(cls, levels: int, freq: float) -> np.ndarray:
        """``1 / 2^j``, j = 1..levels: the level-j MODWT filter has energy ``2^-j`` (any
        wavelet), so ``wv_j = sigma2 / 2^j`` (exact: a power of two)."""
        return 1.0 / 2.0 ** np.arange(1, int(levels) + 1)

    def psd(self, f: ArrayLike, freq: float) -> np.ndarray:
        """Flat two-sided PSD ``sigma2 / freq`` (u^2/Hz)."""
        self.require_values()
        return np.full(np.shape(f), self.sigma2 / freq)

    def autocovariance(self, lags: ArrayLike, freq: float) -> np.ndarray:
        """``sigma2`` at lag 0, zero elsewhere."""
        self.require_values()
        return np.where(np.asarray(lags) == 0, self.sigma2, 0.0)

    def white_variance(self, freq: float) -> float:
        """The whole process is feed-through: ``sigma2`` per sample."""
        return float(self.sigma2)

    def simulate(self, n: int, freq: float, rng: np.random.Generator | int) -> np.ndarray:
        """i.i.d. normal draws with variance sigma2."""
        self.require_values()
        return np.sqrt(self.sigma2) * as_generator(rng).standard_normal(int(n))

    def start(self, wv: np.ndarray, freq: float, *, index: int = 0, count: int = 1,
              rng: np.random.Generator | None = None) -> WN:
        """Attribute the finest level to white noise: ``sigma2 = 2 wv_1`` (split over `count`)."""
        guess = 2.0 * float(wv[0]) / count
        if rng is not None:
            guess *= float(np.exp(rng.normal(0.0, 1.0)))
        return self.with_values(sigma2=guess)

    @classmethod
    def example(cls, freq: float) -> WN:
        """Unit variance per sample."""
        return cls(sigma2=1.0)

    def physical(self, freq: float) -> dict[str, PhysicalValue]:
        """Noise density N = sqrt(sigma2/freq) in u*sqrt(s)."""
        return {"N": PhysicalValue(float(np.sqrt(self.sigma2 / freq)), "u*sqrt(s)",
                                   "white-noise density (ARW/VRW)")}


@hookimpl
def stochmod_processes() -> list[type[Process]]:
    """Register WN."""
    return [WN]
