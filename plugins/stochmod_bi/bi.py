"""Bias instability (BI): band-limited flicker noise as a log-uniform mixture of GM processes."""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from typing import Any, ClassVar

import attrs
import numpy as np
from numpy.typing import ArrayLike

from stochmod.sdk import (
    BI_FACTOR,
    ContinuousBlock,
    DomainError,
    InputError,
    Parameter,
    PhysicalValue,
    Process,
    SpecError,
    as_generator,
    bi_from_floor,
    check_coefficients,
    check_freq,
    check_positive_int,
    to_si,
)

from ._circulant import circulant_embedding
from ._gm_approx import GMApproximation, default_levels, fit_unit_gms
from ._mixture import unit_autocovariance, unit_spectrum, unit_wv, unit_wv_d_lo

__all__ = ["BI", "DEFAULT_N_GM", "HALF_FLOOR_TAU_FC"]

#: Number of GM states of the state-space approximation unless ``n_gm`` is given.
DEFAULT_N_GM = 6
#: ``tau * fc`` at which the Haar WV of BI has fallen to half its flat floor (from the
#: theoretical curve for fc/freq -> 0: 0.70; used by :meth:`BI.start` to read fc off a WV).
HALF_FLOOR_TAU_FC = 0.70


def _check_n_gm(value: object) -> int | None:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 1:
        raise SpecError(f"BI.n_gm (number of GM states) must be a positive integer, got {value!r}")
    return int(value)


@attrs.frozen
class BI(Process):
    """Bias instability: flicker (1/f) noise between a corner frequency `fc` and Nyquist.

    The process is a superposition of first-order Gauss-Markov processes whose rates beta are
    log-uniformly distributed (the classical model of 1/f noise as a superposition of
    relaxation processes, van der Ziel 1950): stationary variance ``B^2 / pi`` per unit of
    ``ln beta`` for ``2 pi fc <= beta <= pi freq``, plus one GM of rate ``2 pi fc`` and variance
    ``B^2 / pi`` (it cancels the ``1/f^2`` term left by cutting the mixture at fc, so the 1/f
    law holds to third order above fc). Sampled at ``freq`` every GM is an exact AR(1), so
    the PSD, autocovariance, wavelet variance, simulation and state space all describe the
    same sampled process.

    - Two-sided PSD ``S(f) ~ B^2 / (2 pi |f|)`` (u^2/Hz) for ``fc << |f| << freq/2`` (IEEE
      Std 952: one-sided ``B^2 / (pi f)``), flat ``~ 2 B^2 / (pi^2 fc)`` below fc: finite
      variance ``(B^2 / pi) (ln(freq / (2 fc)) + 1)``, stationary.
    - Allan variance: the flat floor ``(2 ln 2 / pi) B^2 = (0.664 B)^2`` for
      ``1/freq << tau << 0.01/fc`` (within 0.3 %); Haar WV half of it. Beyond the bend
      (half the floor at ``tau ~ 0.7 / fc``) the WV falls as ``1/tau``.
    - Autocovariance ``(B^2/pi) [E1(d t) - E1(pi t) + exp(-d t)]`` at lag t >= 1 samples,
      ``d = 2 pi fc / freq`` (E1 the exponential integral); exact simulation by circulant
      embedding (the autocovariance is completely monotone, so the embedding is valid).
    - Haar WV: quadrature over ``ln beta`` of the closed-form AR(1) WV (relative error
      < 1e-11, any level); analytic Jacobian.
    - State space: ``n_gm`` GMs (default 6) fitted to the WV; see :meth:`gm_approximation`.
      With 6 GMs the maximum relative WV error is 3e-7 for a band of 2 decades
      (``freq / (2 fc) = 100``), 1.2e-4 for 3, 3e-3 for 4, 1.1e-2 for 5, 3e-2 for 6; use
      ``n_gm = 8`` below 5e-3 at 6 decades (``tests/test_family_bi.py`` checks these bounds).
    - When ``fc >= freq/2`` the band is empty and BI is its corner GM alone (continuous in fc).

    Parameters
    ----------
    B : float, optional
        Bias instability, u (signal unit: rad/s, m/s^2); free when None.
    fc : float, optional
        Lower corner frequency of the 1/f band, Hz; correlation time of the slowest
        component ``1 / (2 pi fc)`` s. Free when None.
    n_gm : int, optional
        Number of GM states of the state-space approximation (structure, not a parameter;
        default :data:`DEFAULT_N_GM`). Written ``"BI(4)"`` in spec strings.
    """

    B: float | None = None
    fc: float | None = None
    n_gm: int | None = attrs.field(default=None, converter=_check_n_gm, kw_only=True)

    family: ClassVar[str] = "BI"
    description: ClassVar[str] = "bias instability: flicker (1/f) noise above a corner frequency"
    parameter_specs: ClassVar[tuple[Parameter, ...]] = (
        Parameter("B", "positive", "u", "bias instability (Allan deviation floor / 0.664)",
                  role="amplitude"),
        Parameter("fc", "positive", "Hz", "corner frequency below which the PSD is flat",
                  role="rate"),
    )
    ieee952: ClassVar[tuple[tuple[str, ...], ...]] = (("B", "fc"),)
    structural_fields: ClassVar[tuple[str, ...]] = ("n_gm",)

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_correlation_time(cls, B: float, Tc: float) -> BI:
        """BI of bias instability `B` (u) whose slowest component has correlation time `Tc` (s)."""
        return cls(B=B, fc=1.0 / (2.0 * math.pi * _positive(Tc, "Tc")))

    @classmethod
    def from_allan_floor(cls, floor: float, fc: float) -> BI:
        """BI whose flat Allan-deviation floor is `floor` (u): ``B = floor / 0.66428``."""
        return cls(B=float(bi_from_floor(_positive(floor, "floor"))), fc=fc)

    @classmethod
    def from_datasheet(cls, B: float, unit: str, Tc: float, Tc_unit: str = "s") -> BI:
        """BI from datasheet values, e.g. ``BI.from_datasheet(10, "deg/h", 100)``.

        `B` in `unit` (any unit :func:`stochmod.core.units.to_si` reads as a rate or acceleration),
        `Tc` in `Tc_unit`; stored in SI (rad/s or m/s^2, and Hz).
        """
        return cls.from_correlation_time(to_si(B, unit, kind="B"), to_si(Tc, Tc_unit, kind="Tc"))

    @classmethod
    def from_ieee952(cls, coefficients: Mapping[str, Any], freq: float) -> BI:
        """BI of a reading's bias instability ``B`` (u) above the corner ``fc`` (Hz)."""
        check_freq(freq)
        c = check_coefficients(coefficients, cls.ieee952_set(coefficients), "BI.from_ieee952")
        return cls(B=c["B"], fc=c["fc"])

    def to_ieee952(self, freq: float, names: tuple[str, ...]) -> dict[str, float]:
        """``{"B": B, "fc": fc}``."""
        self.require_values()
        return {"B": float(self.B), "fc": float(self.fc)}

    def ordering_key(self) -> float:
        """``B`` (u): the larger first."""
        self.require_values()
        return float(self.B)

    @classmethod
    def example(cls, freq: float) -> BI:
        """``B = 1`` u, ``fc = freq / 5000``: floor from ~8 to ~50 samples, bend near 3500."""
        return cls(B=1.0, fc=check_freq(freq) / 5000.0)

    # ------------------------------------------------------------------ helpers
    @property
    def gm_count(self) -> int:
        """Number of GM states of the state-space approximation."""
        return DEFAULT_N_GM if self.n_gm is None else self.n_gm

    def structure(self) -> dict[str, Any]:
        """``{"n_gm": K}`` when K was given, else empty (so the spec reads plain ``"BI"``)."""
        return {} if self.n_gm is None else {"n_gm": self.n_gm}

    def _scale_nu(self, freq: float) -> tuple[float, float, float]:
        self.require_values()
        freq = check_freq(freq)
        return float(self.B) ** 2 / math.pi, float(self.fc) / freq, freq

    # ------------------------------------------------------------------ theory
    def wv(self, levels: int, freq: float, wavelet: str = "haar") -> np.ndarray:
        """Haar WV at levels 1..`levels`, u^2 (other wavelets: PSD quadrature)."""
        if wavelet != "haar":
            return super().wv(levels, freq, wavelet)
        levels = check_positive_int(levels, name="levels")
        c, nu_c, _ = self._scale_nu(freq)
        return c * unit_wv(nu_c, levels)

    def wv_jacobian(self, levels: int, freq: float) -> np.ndarray:
        """Columns ``d wv / d B = 2 wv / B`` and ``d wv / d fc`` (u^2 / Hz), shape (levels, 2).

        At the shallow levels ``d wv / d fc`` is the difference of two terms near 1/2 whose
        sum is of order ``d = 2 pi fc / freq`` (:func:`unit_wv_d_lo`): its relative accuracy
        is about ``1e-16 / d`` times a small factor, 5e-8 at ``fc = 1e-8 freq`` (a corner
        period of 10^8 samples), 1e-14 at ``fc = 1e-3 freq``."""
        levels = check_positive_int(levels, name="levels")
        c, nu_c, freq = self._scale_nu(freq)
        d_b = 2.0 * c * unit_wv(nu_c, levels) / float(self.B)
        d_fc = c * unit_wv_d_lo(nu_c, levels) * 2.0 * math.pi / freq
        return np.column_stack([d_b, d_fc])

    def psd(self, f: ArrayLike, freq: float) -> np.ndarray:
        """Two-sided PSD of the sampled process, u^2/Hz, at `f` Hz in (-freq/2, freq/2]."""
        c, nu_c, freq = self._scale_nu(freq)
        return c * unit_spectrum(np.asarray(f, dtype=np.float64) / freq, nu_c) / freq

    def autocovariance(self, lags: ArrayLike, freq: float) -> np.ndarray:
        """Autocovariance at integer `lags` (samples), u^2 (exact, exponential integrals)."""
        c, nu_c, _ = self._scale_nu(freq)
        return c * unit_autocovariance(lags, nu_c)

    # ------------------------------------------------------------------ state space
    def gm_approximation(self, freq: float, levels: int | None = None,
                         n_gm: int | None = None) -> GMApproximation:
        """The GMs of the state-space block, fitted to this process's Haar WV.

        Parameters
        ----------
        freq : float
            Sampling frequency, Hz.
        levels : int, optional
            Levels 1..J the fit and its error cover (default: until ``tau fc >= 64``, well
            into the ``1/tau`` tail).
        n_gm : int, optional
            Number of GMs (default: the instance's, 6 unless set).

        Returns
        -------
        GMApproximation
            Rates (1/s), variances (u^2), the relative WV error per level and its maximum.
        """
        c, nu_c, freq = self._scale_nu(freq)
        if levels is None:
            levels = default_levels(nu_c)
        levels = check_positive_int(levels, name="levels")
        k = self.gm_count if n_gm is None else _check_n_gm(n_gm)
        d, w, err = fit_unit_gms(nu_c, k, levels)
        return GMApproximation(beta=d * freq, sigma2=c * w, freq=freq, rel_error=err.copy())

    @property
    def state_names(self) -> tuple[str, ...]:
        """``("gm1", ..., "gmK")``, slowest first."""
        return tuple(f"gm{k + 1}" for k in range(self.gm_count))

    def continuous_block(self, freq: float) -> ContinuousBlock:
        """Block-diagonal GMs ``dx_k = -beta_k x_k dt + dW_k``, ``Qc_k = 2 beta_k sigma2_k``."""
        approx = self.gm_approximation(freq)
        return ContinuousBlock(np.diag(-approx.beta), np.eye(approx.beta.size),
                               np.diag(2.0 * approx.beta * approx.sigma2))

    def initial_covariance(self, freq: float) -> np.ndarray:
        """Stationary covariance ``diag(sigma2_k)``."""
        return np.diag(self.gm_approximation(freq).sigma2)

    def output_row(self, freq: float) -> np.ndarray:
        """The GMs add up: ``H = (1, ..., 1)``."""
        return np.ones(self.gm_count)

    # ------------------------------------------------------------------ simulation
    def simulate(self, n: int, freq: float, rng: np.random.Generator | int) -> np.ndarray:
        """Exact Gaussian simulation of `n` samples (circulant embedding of the autocovariance)."""
        self.require_values()
        n = check_positive_int(n, name="n")
        freq = check_freq(freq)
        return circulant_embedding(lambda lags: self.autocovariance(lags, freq), n,
                                   as_generator(rng))

    # ------------------------------------------------------------------ estimation support
    def start(self, wv: np.ndarray, freq: float, *, index: int = 0, count: int = 1,
              rng: np.random.Generator | None = None) -> BI:
        """Starting values from an empirical Haar WV (levels 1..J).

        ``B`` from the flattest level (``wv = (ln 2 / pi) B^2`` there), ``fc`` from the first
        later level where the WV has fallen below half of it (``fc = 0.70 / tau``), or, if none,
        a bend just past the last level. With ``count`` BIs their ``B^2`` share the floor and
        their corners are spread by factors of 8; `rng` perturbs both (multi-start).
        """
        freq = check_freq(freq)
        wv = np.asarray(wv, dtype=np.float64).reshape(-1)
        if wv.size == 0 or not np.all(np.isfinite(wv)) or np.any(wv <= 0):
            raise InputError(
                f"BI.start needs a non-empty, positive, finite wavelet variance, got {wv!r}")
        tau = 2.0 ** np.arange(wv.size) / freq
        if wv.size >= 3:
            slope = np.abs(np.gradient(np.log(wv), np.log(tau)))
            flat = int(np.argmin(slope[1:-1])) + 1
        else:
            flat = wv.size - 1
        floor = float(wv[flat])
        below = np.flatnonzero(wv[flat:] < 0.5 * floor)
        if below.size:
            j = flat + int(below[0])
            # log-log interpolation of the half-floor crossing between levels j-1 and j
            frac = math.log(wv[j - 1] / (0.5 * floor)) / math.log(wv[j - 1] / wv[j])
            tau_half = tau[j - 1] * 2.0**frac
        else:
            tau_half = 2.0 * tau[-1]
        B = math.sqrt(math.pi * floor / math.log(2.0) / count)
        fc = HALF_FLOOR_TAU_FC / tau_half * 8.0 ** (index - (count - 1) / 2)
        if rng is not None:
            B *= math.exp(rng.normal(0.0, 0.3))
            fc *= math.exp(rng.normal(0.0, 0.5))
        return self.with_values(B=B, fc=min(fc, 0.25 * freq))

    def physical(self, freq: float) -> dict[str, PhysicalValue]:
        """The slowest correlation time Tc (s) and the Allan-deviation floor (u).

        (B and fc, already physical, are the parameters themselves.)
        """
        self.require_values()
        B, fc = float(self.B), float(self.fc)
        return {
            "Tc": PhysicalValue(1.0 / (2.0 * math.pi * fc), "s",
                                "correlation time of the slowest component"),
            "floor": PhysicalValue(BI_FACTOR * B, "u",
                                   "flat Allan-deviation floor sqrt(2 ln 2 / pi) B"),
        }


def _positive(value: float, name: str) -> float:
    v = float(value)
    if not (math.isfinite(v) and v > 0):
        raise DomainError(f"BI: {name} must be positive and finite, got {value!r}")
    return v
