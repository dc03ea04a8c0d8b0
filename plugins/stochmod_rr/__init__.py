"""Random ramp (RR): the stochmod plugin for the family ``RR(omega)``.

``X_t = s t`` (t = 0, 1, ... samples) with a random slope ``s ~ N(0, omega^2)`` drawn once:
omega is the rms slope in u per sample at the model's sampling frequency ``freq``. The slope
in u/s is ``s freq``; its rms is the IEEE rate-ramp coefficient ``R = omega freq`` (u/s).
Random-ramp state space of Stebler et al. (2014), Table I: states ``[ramp (u), slope (u/s)]``,
``x1' = x2``, ``x2' = 0``.

Closed forms (m = 2^(j-1), tau = m / freq):

- Wavelet variance: a level-j MODWT filter ``h_j`` (``sum h_j = 0``) maps the ramp to the
  constant ``W = -s sum_l l h_{j,l} = -s m mu``, where ``mu = sum_l l h_{1,l}`` is the first
  moment of the level-1 filter (``-1/2`` for Haar; 0 for filters with two or more vanishing
  moments, db2, sym4, coif1 ...). So ``wv_j = omega^2 m^2 mu^2``: ``omega^2 m^2 / 4`` for Haar,
  exactly 0 otherwise. Given the slope the identity ``W = s m / 2`` holds for every
  coefficient, so an empirical WV of one path is ``s^2 m^2 / 4`` with no sampling error; only
  the slope is random (``s^2 / omega^2`` is chi-square with 1 degree of freedom).
- Allan variance ``2 wv = omega^2 m^2 / 2 = R^2 tau^2 / 2`` (IEEE Std 952 rate ramp).

PSD: a ramp has no PSD in the ordinary sense (its power sits at f = 0). :meth:`RR.psd`
returns the nominal IEEE Std 952 rate-ramp form, one-sided ``R^2 / (2 pi f)^3`` halved to the
two-sided ``R^2 / (2 (2 pi |f|)^3)``, for plots only: integrals of it against the Haar or
Allan filter diverge logarithmically at f = 0, so it does not reproduce ``R^2 tau^2 / 2``;
the wavelet variance never uses it.
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
    VectorisedWV,
    as_generator,
    as_signal,
    check_coefficients,
    check_freq,
    check_positive_int,
    hookimpl,
    modwt_filters,
)

__all__ = ["RR", "stochmod_processes"]

#: First moments below this are round-off of an exact zero (filters with >= 2 vanishing moments).
_MOMENT_ZERO = 1e-10


def _half_widths(levels: int) -> np.ndarray:
    return 2.0 ** np.arange(int(levels))


def _first_moment(wavelet: str) -> float:
    """``mu = sum_l l h_{1,l}`` of the level-1 MODWT wavelet filter (-1/2 for Haar)."""
    if wavelet == "haar":
        return -0.5
    h, _ = modwt_filters(wavelet)
    mu = float(np.dot(np.arange(h.size), h))
    return 0.0 if abs(mu) < _MOMENT_ZERO else mu


@attrs.frozen
class RR(Process, VectorisedWV):
    """Random ramp ``X_t = s t`` with rms slope `omega` per sample (signal unit per sample).

    Parameters
    ----------
    omega : float, optional
        Standard deviation of the slope, u per sample at ``freq`` (``R = omega freq`` u/s);
        free when None.
    """

    omega: float | None = None

    family: ClassVar[str] = "RR"
    description: ClassVar[str] = "random ramp (rate ramp): a line of random slope"
    parameter_specs: ClassVar[tuple[Parameter, ...]] = (
        Parameter("omega", "positive", "u", "rms slope per sample (u per sample)",
                  role="amplitude"),
    )
    stationary: ClassVar[bool] = False
    lattice_copies: ClassVar[int] = 1
    lattice_rank: ClassVar[int] = 50
    ieee952: ClassVar[tuple[tuple[str, ...], ...]] = (("R",),)

    @classmethod
    def from_rate_ramp(cls, R: float, freq: float) -> RR:
        """Random ramp of IEEE coefficient `R` (u/s, rms slope; Allan variance ``R^2 tau^2 / 2``)
        at `freq` Hz: ``omega = R / freq``."""
        return cls(omega=float(R) / check_freq(freq))

    @classmethod
    def from_ieee952(cls, coefficients: Mapping[str, Any], freq: float) -> RR:
        """Random ramp of the IEEE coefficient ``R`` (u/s) at `freq` Hz (:meth:`from_rate_ramp`)."""
        c = check_coefficients(coefficients, cls.ieee952_set(coefficients), "RR.from_ieee952")
        return cls.from_rate_ramp(c["R"], freq)

    def to_ieee952(self, freq: float, names: tuple[str, ...]) -> dict[str, float]:
        """``{"R": omega freq}``."""
        self.require_values()
        return {"R": float(self.omega) * check_freq(freq)}

    def ordering_key(self) -> float:
        """``omega`` (u per sample): the steeper first."""
        self.require_values()
        return float(self.omega)

    # ------------------------------------------------------------------ theory
    def wv(self, levels: int, freq: float, wavelet: str = "haar") -> np.ndarray:
        """``omega^2 m^2 mu^2`` (u^2): ``omega^2 m^2 / 4`` for Haar, 0 for wavelets with two or
        more vanishing moments (see the module notes)."""
        self.require_values()
        check_freq(freq)
        m = _half_widths(check_positive_int(levels, name="levels"))
        return (self.omega * m * _first_moment(wavelet)) ** 2

    def wv_jacobian(self, levels: int, freq: float) -> np.ndarray:
        """d wv_j / d omega = omega m^2 / 2 (Haar), shape (levels, 1)."""
        self.require_values()
        check_freq(freq)
        m = _half_widths(check_positive_int(levels, name="levels"))
        return (0.5 * self.omega * m * m)[:, None]

    def haar_wv_rows(self, values: ArrayLike, levels: int, freq: float) -> tuple[np.ndarray, np.ndarray]:
        """Haar :meth:`wv` and :meth:`wv_jacobian` at rows ``(omega,)`` of `values` (K, 1), bit for bit."""
        omega = np.asarray(values, dtype=np.float64).reshape(-1, 1)
        check_freq(freq)
        m = _half_widths(check_positive_int(levels, name="levels"))
        return (omega * m * _first_moment("haar")) ** 2, (0.5 * omega * m * m)[:, :, None]

    def wv_sampling_covariance(self, n_coef: ArrayLike, freq: float,
                               wavelet: str = "haar") -> np.ndarray:
        """``2 wv wv^T`` (u^4): one slope s per record, so the ramp's empirical WV is
        ``s^2 m^2 mu^2`` at every level, ``wv * chi2(1)`` fully correlated across levels,
        however long the record (its PSD is nominal and says nothing of this)."""
        wv = self.wv(np.size(n_coef), freq, wavelet)
        return 2.0 * np.outer(wv, wv)

    def psd(self, f: ArrayLike, freq: float) -> np.ndarray:
        """Nominal two-sided rate-ramp PSD ``R^2 / (2 (2 pi |f|)^3)``, R = omega freq (u^2/Hz).

        For plots against IEEE Std 952 readings only (see the module notes); inf at f = 0.
        """
        self.require_values()
        freq = check_freq(freq)
        w = 2.0 * np.pi * np.abs(np.asarray(f, dtype=np.float64))
        rate = self.omega * freq
        with np.errstate(divide="ignore"):
            return rate * rate / (2.0 * w**3)

    # ------------------------------------------------------------------ state space
    @property
    def state_names(self) -> tuple[str, ...]:
        """The ramp value (u) and its slope (u/s)."""
        return ("ramp", "slope")

    def continuous_block(self, freq: float) -> ContinuousBlock:
        """``F = [[0, 1], [0, 0]]``, no driving noise (``G`` a zero column, ``Qc = [[0]]``)."""
        return ContinuousBlock(F=[[0.0, 1.0], [0.0, 0.0]], G=[[0.0], [0.0]], Qc=[[0.0]])

    def initial_covariance(self, freq: float) -> np.ndarray:
        """``diag(0, (omega freq)^2)``: the ramp starts at 0, the slope is a random constant
        with mean square ``R^2`` (u/s)^2."""
        self.require_values()
        rate = self.omega * check_freq(freq)
        return np.diag([0.0, rate * rate])

    # ------------------------------------------------------------------ simulation
    def simulate(self, n: int, freq: float, rng: np.random.Generator | int) -> np.ndarray:
        """``s t`` for t = 0..n-1 with one draw ``s ~ N(0, omega^2)`` (the ramp state starts at 0
        and the slope state is N(0, (omega freq)^2), as in :meth:`initial_covariance`)."""
        self.require_values()
        n = check_positive_int(n, name="n")
        check_freq(freq)
        slope = self.omega * as_generator(rng).standard_normal()
        return slope * np.arange(n, dtype=np.float64)

    # ------------------------------------------------------------------ estimation support
    def start(self, wv: np.ndarray, freq: float, *, index: int = 0, count: int = 1,
              rng: np.random.Generator | None = None) -> RR:
        """Invert the Haar WV at the deepest level (``index`` levels above it for the
        ``index``-th of `count`): ``omega = 2 sqrt(wv_J) / m_J``, split over `count` in
        variance; perturbed log-normally by `rng`."""
        wv = as_signal(wv, name="wv", min_length=1)
        j = max(wv.size - int(index), 1)
        if not wv[j - 1] > 0:
            raise InputError(f"wv[{j - 1}] = {wv[j - 1]!r} must be positive to start RR.omega")
        guess = 2.0 * float(np.sqrt(wv[j - 1] / count)) / 2.0 ** (j - 1)
        if rng is not None:
            guess *= float(np.exp(0.5 * rng.normal(0.0, 1.0)))
        return self.with_values(omega=guess)

    @classmethod
    def example(cls, freq: float) -> RR:
        """``omega = 1e-4`` per sample: above WN(1) in Haar WV from level 11 (m = 1024) on,
        for a slope of typical size."""
        return cls(omega=1e-4)

    def physical(self, freq: float) -> dict[str, PhysicalValue]:
        """Rate ramp R = omega freq in u/s (rms slope)."""
        self.require_values()
        return {"R": PhysicalValue(float(self.omega * check_freq(freq)), "u/s",
                                   "rate ramp (rms slope), AV R^2 tau^2 / 2")}


@hookimpl
def stochmod_processes() -> list[type[Process]]:
    """Register RR."""
    return [RR]
