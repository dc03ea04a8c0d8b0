"""MA(1): an example of a stochmod process family written as a third party would, with a GMWM
weighting (:mod:`stochmod_ma1.weighting`, ``"relative"``) registered by the same package.

``X_t = e_t + theta e_{t-1}``, ``e_t ~ N(0, sigma2)`` i.i.d., ``|theta| < 1`` (invertible).
Only public stochmod names are used. The family deliberately declares no wavelet variance:
stochmod's generic fallback computes it exactly from :meth:`MA1.autocovariance`.

Install with ``pip install .`` from this folder (the entry point in ``pyproject.toml``
registers it), or register it at run time with ``stochmod.register_plugin(stochmod_ma1)``.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import attrs
import numpy as np
from numpy.typing import ArrayLike

from stochmod import sdk

from stochmod_ma1.jsonl import JsonLinesReader
from stochmod_ma1.weighting import RELATIVE, RelativeWeighting, stochmod_weightings

__all__ = ["MA1", "stochmod_processes", "RelativeWeighting", "RELATIVE", "stochmod_weightings",
           "JsonLinesReader", "stochmod_readers", "stochmod_combiners"]

__version__ = "0.1.0"


def _generator(rng: np.random.Generator | int) -> np.random.Generator:
    """A Generator from a Generator or an integer seed (None refused: results must reproduce)."""
    if isinstance(rng, np.random.Generator):
        return rng
    if isinstance(rng, (int, np.integer)) and not isinstance(rng, bool):
        return np.random.default_rng(int(rng))
    raise sdk.InputError(f"rng must be a numpy Generator or an integer seed, got {rng!r}")


@attrs.frozen
class MA1(sdk.Process):
    """First-order moving average ``X_t = e_t + theta e_{t-1}`` (a discrete-time family).

    Parameters
    ----------
    theta : float, optional
        MA coefficient, dimensionless, in (-1, 1); free when None.
    sigma2 : float, optional
        Innovation variance per sample, u^2; free when None.

    Notes
    -----
    Autocovariance ``sigma2 (1 + theta^2)`` at lag 0, ``sigma2 theta`` at lag +-1, zero beyond.
    Two-sided PSD ``sigma2 |1 + theta e^{-i 2 pi f / freq}|^2 / freq`` (u^2/Hz). State space:
    ``x_t = (e_t, e_{t-1})``, ``Phi = [[0, 0], [1, 0]]``, ``Q = diag(sigma2, 0)``,
    ``H = (1, theta)``; it re-samples at whole multiples of the sample period.
    """

    theta: float | None = None
    sigma2: float | None = None

    family: ClassVar[str] = "MA1"
    description: ClassVar[str] = "first-order moving average X_t = e_t + theta e_{t-1}"
    parameter_specs: ClassVar[tuple[sdk.Parameter, ...]] = (
        sdk.Parameter("theta", "correlation", "1", "MA coefficient (|theta| < 1)",
                           role="shape"),
        sdk.Parameter("sigma2", "positive", "u^2", "innovation variance per sample",
                           role="variance"),
    )

    def _values(self) -> tuple[float, float]:
        theta, sigma2 = self.vector()  # raises SpecError while a parameter is free
        return float(theta), float(sigma2)

    # ---------------------------------------------------------------- theory
    def autocovariance(self, lags: ArrayLike, freq: float) -> np.ndarray:
        """Autocovariance at integer `lags` (samples), u^2."""
        theta, sigma2 = self._values()
        k = np.abs(np.asarray(lags))
        return np.where(k == 0, sigma2 * (1 + theta**2), np.where(k == 1, sigma2 * theta, 0.0))

    def psd(self, f: ArrayLike, freq: float) -> np.ndarray:
        """Two-sided PSD of the sampled process, u^2/Hz, at `f` Hz in (-freq/2, freq/2]."""
        theta, sigma2 = self._values()
        w = 2 * np.pi * np.asarray(f, dtype=np.float64) / freq
        return sigma2 * (1 + theta**2 + 2 * theta * np.cos(w)) / freq

    # ---------------------------------------------------------------- state space
    @property
    def state_names(self) -> tuple[str, ...]:
        """The current and the previous innovation."""
        return ("e", "e_prev")

    def discrete_block(self, freq: float) -> sdk.StateSpaceBlock:
        """The block at the native step 1/freq."""
        theta, sigma2 = self._values()
        return sdk.StateSpaceBlock(
            state_names=self.state_names,
            Phi=np.array([[0.0, 0.0], [1.0, 0.0]]),
            Q=np.diag([sigma2, 0.0]),
            H=np.array([1.0, theta]),
            P0=np.diag([sigma2, sigma2]),
            white_var=0.0,
            dt=1.0 / freq,
        )

    def initial_covariance(self, freq: float) -> np.ndarray:
        """Two independent innovations."""
        return np.eye(2) * self._values()[1]

    def output_row(self, freq: float) -> np.ndarray:
        """``X_t = e_t + theta e_{t-1}``."""
        return np.array([1.0, self._values()[0]])

    # ---------------------------------------------------------------- simulation
    def simulate(self, n: int, freq: float, rng: np.random.Generator | int) -> np.ndarray:
        """`n` samples from a seeded generator (vectorised)."""
        theta, sigma2 = self._values()
        e = math.sqrt(sigma2) * _generator(rng).standard_normal(int(n) + 1)
        return e[1:] + theta * e[:-1]

    # ---------------------------------------------------------------- estimation support
    def start(self, wv: np.ndarray, freq: float, *, index: int = 0, count: int = 1,
              rng: np.random.Generator | None = None) -> MA1:
        """Moment starts from the Haar WV at levels 1 and 2.

        ``wv_1 = sigma2 (1 - theta + theta^2) / 2``,
        ``wv_2 = sigma2 (2 + 2 theta^2 + theta) / 8``; their ratio ``r = wv_2 / wv_1`` gives
        ``theta + 1/theta = (4 r + 1) / (4 r - 2)`` (the root in (-1, 1)). With `count` MA1s
        the innovation variance is shared; `rng` perturbs theta (multi-start).
        """
        wv = np.asarray(wv, dtype=np.float64).reshape(-1)
        if wv.size < 2 or not np.all(np.isfinite(wv[:2])) or np.any(wv[:2] <= 0):
            raise sdk.InputError(
                f"MA1.start needs positive wavelet variances at levels 1 and 2, got {wv!r}")
        r = wv[1] / wv[0]
        theta = 0.0
        if abs(4 * r - 2) > 1e-12:
            k = (4 * r + 1) / (4 * r - 2)
            if abs(k) > 2:  # the root of theta^2 - k theta + 1 = 0 inside (-1, 1)
                theta = (k - math.copysign(math.sqrt(k * k - 4), k)) / 2
            else:  # no MA(1) has this ratio: start near the edge it points to
                theta = math.copysign(0.95, k)
        if rng is not None:
            theta = math.tanh(math.atanh(theta) + rng.normal(0.0, 0.3))
        sigma2 = 2 * wv[0] / (1 - theta + theta**2) / count
        return self.with_values(theta=float(theta), sigma2=float(sigma2))

    def physical(self, freq: float) -> dict[str, sdk.PhysicalValue]:
        """Innovation sigma (u); white-noise density at long averaging times (u*sqrt(s))."""
        theta, sigma2 = self._values()
        return {
            "sigma": sdk.PhysicalValue(math.sqrt(sigma2), "u",
                                            "innovation standard deviation"),
            "N": sdk.PhysicalValue(abs(1 + theta) * math.sqrt(sigma2 / freq), "u*sqrt(s)",
                                        "white-noise density seen at long averaging times"),
        }

    def ordering_key(self) -> float:
        """Repeated MA(1) components are ordered by innovation variance, the larger first."""
        return self._values()[1]

    @classmethod
    def example(cls, freq: float) -> MA1:
        """``theta = 0.5``, unit innovation variance."""
        return cls(theta=0.5, sigma2=1.0)


@sdk.hookimpl
def stochmod_processes() -> list[type[sdk.Process]]:
    """Register MA1."""
    return [MA1]


@sdk.hookimpl
def stochmod_readers() -> list[JsonLinesReader]:
    """Register the JSON Lines reader (a log format, see jsonl.py)."""
    return [JsonLinesReader()]


@sdk.hookimpl
def stochmod_combiners() -> list[Any]:
    """Register the median combiner (a second plugin point served by the same package)."""
    from stochmod_ma1.median import MedianCombiner

    return [MedianCombiner()]
