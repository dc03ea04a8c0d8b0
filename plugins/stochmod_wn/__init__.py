"""White noise (WN): the stochmod plugin for the family ``WN(sigma2)``.

``X_t = W_t``, ``W_t ~ N(0, sigma2)`` i.i.d., sigma2 the variance per sample at the
model's sampling frequency ``freq``. Physical view: the noise density
``N = sqrt(sigma2 / freq)`` (u*sqrt(s), i.e. u/sqrt(Hz): angle or velocity random walk).
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from typing import Any, ClassVar

import attrs
import numpy as np
from numpy.typing import ArrayLike

from stochmod.sdk import (
    JIT_AVAILABLE as _COMPILED,
)
from stochmod.sdk import (
    Parameter,
    PhysicalValue,
    Process,
    as_generator,
    check_coefficients,
    check_freq,
    compiled,
    hookimpl,
    wn_density,
)

__all__ = ["WN", "stochmod_processes"]


@compiled
def _wv_kernel(values: np.ndarray, m: np.ndarray, freq: float, wv: np.ndarray,
               jac: np.ndarray) -> bool:  # pragma: no cover - compiled
    """:attr:`WN.haar_wv_kernel`: ``sigma2 / 2^j`` added to `wv`, ``1 / 2^j`` into `jac`
    (``2^j = 2 m``, exact: the divisions of :meth:`WN.haar_wv_rows`)."""
    sigma2 = values[0]
    for j in range(m.size):
        scale = 2.0 * m[j]
        wv[j] += sigma2 / scale
        jac[j, 0] = 1.0 / scale
    return True


@functools.lru_cache(maxsize=8)
def _scales(levels: int) -> tuple[np.ndarray, np.ndarray]:
    """``2^j`` and ``1 / 2^j`` for j = 1..`levels` (read-only, as :meth:`WN.wv` and
    :meth:`WN.wv_jacobian` compute them)."""
    scale = 2.0 ** np.arange(1, levels + 1)
    inverse = 1.0 / scale
    scale.flags.writeable = inverse.flags.writeable = False
    return scale, inverse


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
        Parameter("sigma2", "positive", "u^2", "variance per sample", role="variance"),
    )
    lattice_copies: ClassVar[int] = 1
    lattice_rank: ClassVar[int] = 20
    ieee952: ClassVar[tuple[tuple[str, ...], ...]] = (("N",),)
    haar_wv_kernel: ClassVar[Any] = staticmethod(_wv_kernel) if _COMPILED else None

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

    def wv(self, levels: int, freq: float, wavelet: str = "haar") -> np.ndarray:
        """``sigma2 / 2^j`` for any wavelet (the level-j MODWT filter has energy 1/2^j)."""
        self.require_values()
        return self.sigma2 / 2.0 ** np.arange(1, int(levels) + 1)

    def wv_jacobian(self, levels: int, freq: float) -> np.ndarray:
        """d wv / d sigma2 = 1 / 2^j."""
        return (1.0 / 2.0 ** np.arange(1, int(levels) + 1))[:, None]

    def haar_wv_rows(self, values: ArrayLike, levels: int, freq: float) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`wv` and :meth:`wv_jacobian` at rows ``(sigma2,)`` of `values` (K, 1), bit for bit."""
        values = np.asarray(values, dtype=np.float64).reshape(-1, 1)
        scale, inverse = _scales(int(levels))
        return values / scale, np.repeat(inverse[None, :, None], values.shape[0], axis=0)

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
