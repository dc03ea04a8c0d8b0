"""Quantization noise (QN): the stochmod plugin for the family ``QN(Q2)``.

``X_t = sqrt(12 Q2) (U_t - U_{t-1})`` with ``U_t`` i.i.d. uniform on (0, 1) (Stebler et al.
2014, Table I): the difference of a uniform rounding error, so an MA(1) with a unit root.
Stationary, with autocovariance ``gamma(0) = 2 Q2``, ``gamma(1) = -Q2``, zero beyond (u^2).

Closed forms (m = 2^(j-1), tau = m / freq):

- Haar WV ``3 Q2 / (2 m^2)``: the Haar filter applied to the differences of U is the
  difference of the Haar filter, with taps ``1/(2m), -1/m, 1/(2m)`` at lags ``0, m, 2m``, so
  ``wv = 12 Q2 var(U) (1/4 + 1 + 1/4) / m^2``.
- Two-sided PSD ``4 Q2 sin^2(pi f / freq) / freq`` (u^2/Hz), integral ``2 Q2``.
- Allan variance ``2 wv = 3 Q^2 / tau^2`` with the IEEE quantization coefficient
  ``Q = sqrt(Q2) / freq`` in u*s.

State space: no state; the white feed-through variance is ``2 Q2``. This is an approximation:
it keeps the variance but drops the lag-1 correlation ``-Q2`` that makes the sum of QN samples
bounded. A filter that integrates the reading (attitude from a gyro) therefore sees a random
walk of increment variance ``2 Q2`` per sample where the true QN contributes a bounded error;
the approximation is conservative. An exact representation needs a state (the previous U),
and the unit root makes the MA(1) non-invertible, so it is not offered.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import attrs
import numpy as np
from numpy.typing import ArrayLike

from stochmod.sdk import (
    DomainError,
    InputError,
    Parameter,
    PhysicalValue,
    Process,
    ScaledFamily,
    as_generator,
    as_signal,
    check_coefficients,
    check_freq,
    check_positive_int,
    hookimpl,
)

__all__ = ["QN", "stochmod_processes"]


@attrs.frozen
class QN(ScaledFamily):
    """Quantization noise of parameter `Q2` (signal unit^2), ``X_t = sqrt(12 Q2)(U_t - U_{t-1})``.

    Parameters
    ----------
    Q2 : float, optional
        u^2; the variance of each sample is ``2 Q2``; free when None.
    """

    Q2: float | None = None

    family: ClassVar[str] = "QN"
    description: ClassVar[str] = "quantization noise (differenced uniform rounding error)"
    parameter_specs: ClassVar[tuple[Parameter, ...]] = (
        Parameter("Q2", "positive", "u^2",
                  "quantization parameter: variance 2 Q2, lag-1 covariance -Q2", role="variance"),
    )
    lattice_copies: ClassVar[int] = 1
    lattice_rank: ClassVar[int] = 40
    ieee952: ClassVar[tuple[tuple[str, ...], ...]] = (("Q",),)

    @classmethod
    def from_quantization(cls, Q: float, freq: float) -> QN:
        """QN of IEEE coefficient `Q` (u*s; Allan variance ``3 Q^2 / tau^2``) at `freq` Hz:
        ``Q2 = (Q freq)^2``."""
        freq = check_freq(freq)
        Q = float(Q)
        if not (np.isfinite(Q) and Q > 0):
            raise DomainError(f"QN.from_quantization: Q = {Q!r} must be a positive, finite "
                              "number of u*s")
        q = Q * freq  # u; squares beyond the float range give inf, refused as out of domain
        return cls(Q2=q * q)

    @classmethod
    def from_ieee952(cls, coefficients: Mapping[str, Any], freq: float) -> QN:
        """QN of the IEEE coefficient ``Q`` (u*s) at `freq` Hz (:meth:`from_quantization`)."""
        c = check_coefficients(coefficients, cls.ieee952_set(coefficients), "QN.from_ieee952")
        return cls.from_quantization(c["Q"], freq)

    def to_ieee952(self, freq: float, names: tuple[str, ...]) -> dict[str, float]:
        """``{"Q": sqrt(Q2) / freq}``."""
        self.require_values()
        return {"Q": math.sqrt(self.Q2) / check_freq(freq)}

    def ordering_key(self) -> float:
        """``Q2`` (u^2): the larger first."""
        self.require_values()
        return float(self.Q2)

    # ------------------------------------------------------------------ theory
    @classmethod
    def haar_factor(cls, levels: int, freq: float) -> np.ndarray:
        """``d wv_j / d Q2 = 3 / (2 m^2)`` at m = 2^(j-1), j = 1..levels: the Haar WV is
        ``Q2`` times it (u^2; other wavelets: PSD quadrature)."""
        return 1.5 * 4.0 ** -np.arange(int(levels), dtype=np.float64)

    def psd(self, f: ArrayLike, freq: float) -> np.ndarray:
        """Two-sided PSD ``4 Q2 sin^2(pi f / freq) / freq`` (u^2/Hz)."""
        self.require_values()
        freq = check_freq(freq)
        s = np.sin(np.pi * np.asarray(f, dtype=np.float64) / freq)
        return 4.0 * self.Q2 * s * s / freq

    def autocovariance(self, lags: ArrayLike, freq: float) -> np.ndarray:
        """``2 Q2`` at lag 0, ``-Q2`` at lags +-1, zero elsewhere (u^2)."""
        self.require_values()
        lags = np.abs(np.asarray(lags))
        return np.where(lags == 0, 2.0 * self.Q2, np.where(lags == 1, -self.Q2, 0.0))

    # ------------------------------------------------------------------ state space
    def white_variance(self, freq: float) -> float:
        """Feed-through variance ``2 Q2`` per sample (white approximation: see the module notes)."""
        return 2.0 * float(self.Q2)

    # ------------------------------------------------------------------ simulation
    def simulate(self, n: int, freq: float, rng: np.random.Generator | int) -> np.ndarray:
        """``sqrt(12 Q2) (U_t - U_{t-1})`` from n + 1 uniform draws on [0, 1)."""
        self.require_values()
        n = check_positive_int(n, name="n")
        check_freq(freq)
        u = as_generator(rng).random(n + 1)
        return np.sqrt(12.0 * self.Q2) * np.diff(u)

    # ------------------------------------------------------------------ estimation support
    def start(self, wv: np.ndarray, freq: float, *, index: int = 0, count: int = 1,
              rng: np.random.Generator | None = None) -> QN:
        """Invert the Haar WV at the finest level (level ``1 + index`` for the ``index``-th of
        `count`), ``Q2 = 2 m^2 wv_j / 3``, split over `count`; perturbed log-normally by `rng`."""
        wv = as_signal(wv, name="wv", min_length=1)
        j = min(1 + int(index), wv.size)
        if not wv[j - 1] > 0:
            raise InputError(f"wv[{j - 1}] = {wv[j - 1]!r} must be positive to start QN.Q2")
        guess = float(wv[j - 1] / self.haar_factor(j, freq)[-1]) / count
        if rng is not None:
            guess *= float(np.exp(rng.normal(0.0, 1.0)))
        return self.with_values(Q2=guess)

    @classmethod
    def example(cls, freq: float) -> QN:
        """``Q2 = 2``: above WN(1) in Haar WV at levels 1 to 3."""
        return cls(Q2=2.0)

    def physical(self, freq: float) -> dict[str, PhysicalValue]:
        """Quantization coefficient Q = sqrt(Q2) / freq in u*s."""
        self.require_values()
        return {"Q": PhysicalValue(float(np.sqrt(self.Q2) / check_freq(freq)), "u*s",
                                   "quantization coefficient, AV 3 Q^2 / tau^2")}


@hookimpl
def stochmod_processes() -> list[type[Process]]:
    """Register QN."""
    return [QN]
