"""White noise (WN): the stochmod plugin for the family ``WN(sigma2)``.

``X_t = W_t``, ``W_t ~ N(0, sigma2)`` i.i.d., sigma2 the variance per sample at the
model's sampling frequency ``freq``. Physical view: the noise density
``N = sqrt(sigma2 / freq)`` (u*sqrt(s), i.e. u/sqrt(Hz): angle or velocity random walk).
"""

from __future__ import annotations

from typing import ClassVar

import attrs
import numpy as np
from numpy.typing import ArrayLike

from stochmod.hookspecs import hookimpl
from stochmod.params import Parameter
from stochmod.process import PhysicalValue, Process, as_generator

__all__ = ["WN", "stochmod_processes"]


@attrs.frozen
class WN(Process):
    """Gaussian white noise with variance `sigma2` per sample (signal unit^2).

    Parameters
    ----------
    sigma2 : float, optional
        Variance per sample, u^2; free when None.
    """

    sigma2: float | None = None

    family: ClassVar[str] = "WN"
    description: ClassVar[str] = "Gaussian white noise (angle/velocity random walk)"
    parameter_specs: ClassVar[tuple[Parameter, ...]] = (
        Parameter("sigma2", "positive", "u^2", "variance per sample"),
    )

    @classmethod
    def from_density(cls, N: float, freq: float) -> WN:
        """White noise of density `N` (u*sqrt(s) = u/sqrt(Hz), Allan variance N^2/tau) at `freq` Hz."""
        return cls(sigma2=float(N) ** 2 * float(freq))

    def wv(self, levels: int, freq: float, wavelet: str = "haar") -> np.ndarray:
        """``sigma2 / 2^j`` for any wavelet (the level-j MODWT filter has energy 1/2^j)."""
        self._require_values()
        return self.sigma2 / 2.0 ** np.arange(1, int(levels) + 1)

    def wv_jacobian(self, levels: int, freq: float) -> np.ndarray:
        """d wv / d sigma2 = 1 / 2^j."""
        return (1.0 / 2.0 ** np.arange(1, int(levels) + 1))[:, None]

    def psd(self, f: ArrayLike, freq: float) -> np.ndarray:
        """Flat two-sided PSD ``sigma2 / freq`` (u^2/Hz)."""
        self._require_values()
        return np.full(np.shape(f), self.sigma2 / freq)

    def autocovariance(self, lags: ArrayLike, freq: float) -> np.ndarray:
        """``sigma2`` at lag 0, zero elsewhere."""
        self._require_values()
        return np.where(np.asarray(lags) == 0, self.sigma2, 0.0)

    def white_variance(self, freq: float) -> float:
        """The whole process is feed-through: ``sigma2`` per sample."""
        return float(self.sigma2)

    def simulate(self, n: int, freq: float, rng: np.random.Generator | int) -> np.ndarray:
        """i.i.d. normal draws with variance sigma2."""
        self._require_values()
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
