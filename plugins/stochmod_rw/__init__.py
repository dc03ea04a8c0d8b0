"""Random walk (RW): the stochmod plugin for the family ``RW(sigma2)``.

``X_t = X_{t-1} + W_t``, ``W_t ~ N(0, sigma2)`` i.i.d., ``X_0 = 0``; sigma2 is the variance of
the per-sample increment (u^2) at the model's sampling frequency ``freq`` (Stebler et al. 2014,
Table I). Not stationary: it has no autocovariance, but its increments are white, so its Haar
wavelet variance and its generalised PSD exist.

Closed forms (m = 2^(j-1) samples per half of the level-j Haar filter, tau = m / freq):

- Haar WV: the Haar coefficient of a random walk is ``sum_l c_l W_{t-l}`` with ``c`` the
  partial sums of the Haar filter, ``c = (1, 2, ..., m, m-1, ..., 1, 0) / (2m)``, hence
  ``wv_j = sigma2 sum c_l^2 = sigma2 (2 m^2 + 1) / (12 m)`` (``~ sigma2 m / 6``: the *Allan*
  variance, twice the WV, is ``~ sigma2 m / 3``).
- Allan variance ``2 wv_j = K^2 tau / 3 + sigma2 / (6 m)`` with ``K^2 = sigma2 freq``: the
  IEEE rate random walk ``K = sqrt(sigma2 freq)`` in u/sqrt(s) (the second term is the
  difference between averaging samples and averaging a continuous path; it vanishes for
  large m).
- Generalised two-sided PSD of the sampled process
  ``sigma2 / (freq |1 - e^{-i 2 pi f / freq}|^2) = sigma2 / (4 freq sin^2(pi f / freq))`` u^2/Hz.
- Continuous form ``dx = dW``: ``F = 0``, ``G = 1``, ``Qc = sigma2 freq = K^2`` (u^2/s), so the
  re-discretisation at step dt has ``Phi = 1``, ``Q = K^2 dt``; ``P0 = 0``. A turn-on bias
  (a random constant with a prior variance) is a separate process, not part of RW.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import attrs
import numpy as np
from numpy.typing import ArrayLike

from stochmod.sdk import (
    ContinuousBlock,
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
    rw_density,
    rw_variance,
)

__all__ = ["RW", "stochmod_processes"]


@attrs.frozen
class RW(ScaledFamily):
    """Gaussian random walk with per-sample increment variance `sigma2` (signal unit^2).

    Parameters
    ----------
    sigma2 : float, optional
        Variance of the increment ``X_t - X_{t-1}``, u^2 per sample at ``freq``; free when None.
    """

    sigma2: float | None = None

    family: ClassVar[str] = "RW"
    description: ClassVar[str] = "Gaussian random walk (rate / acceleration random walk)"
    parameter_specs: ClassVar[tuple[Parameter, ...]] = (
        Parameter("sigma2", "positive", "u^2", "variance of the per-sample increment",
                  role="variance"),
    )
    stationary: ClassVar[bool] = False
    lattice_copies: ClassVar[int] = 1
    lattice_rank: ClassVar[int] = 30
    ieee952: ClassVar[tuple[tuple[str, ...], ...]] = (("K",),)

    @classmethod
    def from_rrw(cls, K: float, freq: float) -> RW:
        """Random walk of IEEE coefficient `K` (u/sqrt(s); AV ``K^2 tau / 3``) at `freq` Hz.

        ``sigma2 = K^2 / freq`` (:func:`stochmod.core.units.rw_variance`).
        """
        return cls(sigma2=rw_variance(K, freq))

    @classmethod
    def from_ieee952(cls, coefficients: Mapping[str, Any], freq: float) -> RW:
        """Random walk of the IEEE coefficient ``K`` (u/sqrt(s)) at `freq` Hz (:meth:`from_rrw`)."""
        c = check_coefficients(coefficients, cls.ieee952_set(coefficients), "RW.from_ieee952")
        return cls.from_rrw(c["K"], check_freq(freq))

    def to_ieee952(self, freq: float, names: tuple[str, ...]) -> dict[str, float]:
        """``{"K": sqrt(sigma2 freq)}``."""
        self.require_values()
        return {"K": float(rw_density(self.sigma2, freq))}

    def ordering_key(self) -> float:
        """``sigma2`` (u^2): the larger first."""
        self.require_values()
        return float(self.sigma2)

    # ------------------------------------------------------------------ theory
    @classmethod
    def haar_factor(cls, levels: int, freq: float) -> np.ndarray:
        """``d wv_j / d sigma2 = (2 m^2 + 1) / (12 m) = m / 6 + 1 / (12 m)`` at
        m = 2^(j-1), j = 1..levels: the Haar WV is ``sigma2`` times it (u^2; other wavelets:
        PSD quadrature)."""
        m = 2.0 ** np.arange(int(levels))
        return m / 6.0 + 1.0 / (12.0 * m)

    def psd(self, f: ArrayLike, freq: float) -> np.ndarray:
        """Generalised two-sided PSD ``sigma2 / (4 freq sin^2(pi f / freq))``, u^2/Hz (inf at 0)."""
        self.require_values()
        freq = check_freq(freq)
        s = np.sin(np.pi * np.asarray(f, dtype=np.float64) / freq)
        with np.errstate(divide="ignore"):
            return self.sigma2 / (4.0 * freq * s * s)

    # ------------------------------------------------------------------ state space
    @property
    def state_names(self) -> tuple[str, ...]:
        """One state: the walk's current value (u)."""
        return ("value",)

    def continuous_block(self, freq: float) -> ContinuousBlock:
        """``F = 0``, ``G = 1``, ``Qc = sigma2 freq`` (= K^2, u^2/s)."""
        self.require_values()
        return ContinuousBlock(F=[[0.0]], G=[[1.0]], Qc=[[self.sigma2 * check_freq(freq)]])

    # ------------------------------------------------------------------ simulation
    def simulate(self, n: int, freq: float, rng: np.random.Generator | int) -> np.ndarray:
        """``X_0 = 0`` (as ``P0 = 0``), then cumulative sums of N(0, sigma2) increments."""
        self.require_values()
        n = check_positive_int(n, name="n")
        check_freq(freq)
        steps = as_generator(rng).standard_normal(n - 1)
        steps *= np.sqrt(self.sigma2)
        path = np.empty(n)
        path[0] = 0.0
        np.cumsum(steps, out=path[1:])  # in place: the digits of concatenate([0], cumsum)
        return path

    # ------------------------------------------------------------------ estimation support
    def start(self, wv: np.ndarray, freq: float, *, index: int = 0, count: int = 1,
              rng: np.random.Generator | None = None) -> RW:
        """Invert the Haar WV at the deepest level (the ``index``-th start of ``count`` uses the
        level ``index`` above it), split over `count`; perturbed log-normally by `rng`."""
        wv = as_signal(wv, name="wv", min_length=1)
        j = max(wv.size - int(index), 1)
        if not wv[j - 1] > 0:
            raise InputError(f"wv[{j - 1}] = {wv[j - 1]!r} must be positive to start RW.sigma2")
        guess = float(wv[j - 1] / self.haar_factor(j, freq)[-1]) / count
        if rng is not None:
            guess *= float(np.exp(rng.normal(0.0, 1.0)))
        return self.with_values(sigma2=guess)

    @classmethod
    def example(cls, freq: float) -> RW:
        """``sigma2 = 1e-4``: above WN(1) in Haar WV from level 9 (m = 256) on."""
        return cls(sigma2=1e-4)

    def physical(self, freq: float) -> dict[str, PhysicalValue]:
        """Rate random walk K = sqrt(sigma2 freq) in u/sqrt(s)."""
        self.require_values()
        return {"K": PhysicalValue(rw_density(self.sigma2, freq), "u/sqrt(s)",
                                   "random-walk coefficient (RRW/AccRW), AV K^2 tau / 3")}


@hookimpl
def stochmod_processes() -> list[type[Process]]:
    """Register RW."""
    return [RW]
