"""First-order Gauss-Markov (GM): the stochmod plugin for the family ``GM(beta, sigma2)``.

``dx/dt = -beta x + w(t)``, stationary variance ``sigma2`` (u^2), ``beta = 1/Tc`` in 1/s.
Sampled at ``freq`` Hz it is the AR(1) ``x_t = phi x_{t-1} + e_t`` with ``phi = exp(-beta/freq)``
and innovation variance ``sigma2 (1 - phi^2)``; autocovariance ``sigma2 phi^|h|``.

Closed forms (m = 2^(j-1), ``u = beta / freq``):

- Haar WV ``sigma2 W_m(e^-u)`` with :func:`stochmod.core.geometric.haar_wv_geometric`, evaluated
  from u itself, without cancellation: relative error ~1e-15 down to ``u = 1e-8`` and below
  (correlation times of days at 1 kHz) where the textbook AR(1) formula loses every digit;
  analytic Jacobian from :func:`stochmod.core.geometric.haar_wv_geometric_dlog`.
- Two-sided PSD of the sampled process
  ``sigma2 (1 - phi^2) / (freq |1 - phi e^{-i 2 pi f/freq}|^2)`` (u^2/Hz), with
  ``|1 - phi e^{-iw}|^2 = (1 - phi)^2 + 4 phi sin^2(w/2)`` and ``1 - phi = -expm1(-u)``.
- Continuous form ``F = -beta``, ``G = 1``, ``Qc = 2 beta sigma2`` (u^2/s), ``P0 = sigma2``; the
  base class re-discretises it exactly (Van Loan) at any filter step.

Physical views: correlation time ``Tc = 1/beta`` (s) and stationary ``sigma = sqrt(sigma2)`` (u);
:meth:`GM.from_bias_instability` builds the GM that Quinchia et al. (2013, eqs. 29-30) use for
a bias instability B.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from typing import Any, ClassVar

import attrs
import numpy as np
from numpy.typing import ArrayLike

from stochmod.sdk import (
    AV_PEAK_VALUE,
    BI_FACTOR,
    POSITIVE_ROWS_KERNEL_MAX_U,
    WV_PEAK_X,
    ContinuousBlock,
    DomainError,
    InputError,
    Parameter,
    PhysicalValue,
    Process,
    VectorisedWV,
    as_generator,
    as_signal,
    bi_floor,
    bi_from_floor,
    check_coefficients,
    check_freq,
    check_positive_int,
    haar_wv_positive,
    haar_wv_positive_rows,
    hookimpl,
    positive_rows_kernel,
)
from stochmod_gm.discrete import (
    GMDiscrete,
    ar1_to_gm,
    gm_discretize,
    gm_driving_psd,
    gm_from_bias_instability,
    gm_from_discrete,
)

__all__ = ["GM", "PEAK_X", "PEAK_AV", "CONVENTIONS", "stochmod_processes", "GMDiscrete",
           "ar1_to_gm", "gm_discretize", "gm_driving_psd", "gm_from_bias_instability",
           "gm_from_discrete"]

#: ``m beta / freq`` at which a GM's Haar WV peaks over the levels (slow limit); the Allan
#: variance peaks at ``tau = PEAK_X Tc``.
PEAK_X = WV_PEAK_X
#: That Allan-variance maximum over sigma2.
PEAK_AV = AV_PEAK_VALUE
#: How :meth:`GM.from_ieee952` turns (B, Tc) into a GM.
CONVENTIONS = ("quinchia", "matched")


def _positive(value: object, what: str) -> float:
    try:
        v = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise DomainError(f"{what} must be a positive number, got {value!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise DomainError(f"{what} must be positive and finite, got {value!r}")
    return v


@functools.lru_cache(maxsize=8)
def _levels_m(levels: int) -> np.ndarray:
    """``m = 2^(j-1)`` for j = 1..`levels` (read-only: shared by every call)."""
    m = 2.0 ** np.arange(check_positive_int(levels, name="levels"))
    m.flags.writeable = False
    return m


def _wv_kernel(values: np.ndarray, m: np.ndarray, freq: float, wv: np.ndarray,
               jac: np.ndarray) -> bool:
    """:attr:`GM.haar_wv_kernel`: ``sigma2 W_m(e^-u)`` added to `wv` and its derivatives
    written into `jac` by the compiled recursion, with :meth:`GM.haar_wv_rows`'s operations
    on one row (the recursion is called as compiled on its own: inlined into another
    compiled function its reassociated sums round differently); False where that method
    takes another path (``e^-u < 1e-3``)."""
    beta, sigma2 = values.tolist()  # plain floats: the same roundings as the rows' arrays
    u = beta / freq
    if not 0.0 < u <= POSITIVE_ROWS_KERNEL_MAX_U:
        return False
    w = np.empty((1, m.size))
    dw = np.empty((1, m.size))
    positive_rows_kernel(np.array([u]), m, w, dw)
    w = w[0]
    wv += sigma2 * w
    np.multiply(sigma2 / freq, dw[0], out=jac[:, 0])
    jac[:, 1] = w
    return True


@functools.lru_cache(maxsize=64)
def _peak_wv(m: float) -> float:
    """``W_m(e^-u)`` at ``u = PEAK_X / m`` (where a GM's WV peaks at half-width m): the
    starting values' divisor, the same for every call at that level."""
    return float(haar_wv_positive(PEAK_X / m, np.array([m]))[0][0])


@functools.lru_cache(maxsize=16)
def _haar_wv(u: float, levels: int) -> tuple[np.ndarray, np.ndarray]:
    """``W_m(e^-u)`` and ``dW/du`` at m = 2^(j-1), j = 1..`levels` (read-only arrays): an
    optimizer asks for a model's WV and then its Jacobian at the same point."""
    w, dw = haar_wv_positive(u, _levels_m(levels))
    w.flags.writeable = dw.flags.writeable = False
    return w, dw


@attrs.frozen
class GM(Process, VectorisedWV):
    """First-order Gauss-Markov process.

    Parameters
    ----------
    beta : float, optional
        Inverse correlation time 1/Tc, 1/s (> 0); free when None.
    sigma2 : float, optional
        Stationary variance, u^2 (> 0); free when None.
    """

    beta: float | None = None
    sigma2: float | None = None

    family: ClassVar[str] = "GM"
    description: ClassVar[str] = "first-order Gauss-Markov process (exponentially correlated bias)"
    parameter_specs: ClassVar[tuple[Parameter, ...]] = (
        Parameter("beta", "positive", "1/s", "inverse correlation time 1/Tc", role="rate"),
        Parameter("sigma2", "positive", "u^2", "stationary variance", role="variance"),
    )
    lattice_copies: ClassVar[int] = 3
    lattice_rank: ClassVar[int] = 10
    ieee952: ClassVar[tuple[tuple[str, ...], ...]] = (("B", "Tc"), ("rate", "variance"))
    haar_wv_kernel: ClassVar[Any] = (None if positive_rows_kernel is None
                                     else staticmethod(_wv_kernel))

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_correlation_time(cls, Tc: float, sigma: float) -> GM:
        """GM of correlation time `Tc` (s, > 0) and stationary standard deviation `sigma` (u, > 0)."""
        Tc = _positive(Tc, "GM.from_correlation_time: Tc (correlation time, s)")
        sigma = _positive(sigma, "GM.from_correlation_time: sigma (stationary std, u)")
        return cls(beta=1.0 / Tc, sigma2=sigma * sigma)

    @classmethod
    def from_ar1(cls, phi: float, innovation_var: float, freq: float) -> GM:
        """GM whose samples at `freq` Hz are the AR(1) ``x_t = phi x_{t-1} + e_t``.

        Parameters
        ----------
        phi : float
            AR(1) coefficient in (0, 1) (dimensionless).
        innovation_var : float
            Variance of e_t, u^2 (> 0).
        freq : float
            Sampling frequency, Hz.

        Notes
        -----
        ``beta = -log(phi) freq``, ``sigma2 = innovation_var / ((1 - phi)(1 + phi))``
        (:func:`stochmod_gm.discrete.ar1_to_gm`, the conversion
        :func:`stochmod_gm.discrete.gm_from_discrete` also uses: same errors); a phi within a few ulps of 1 carries few digits of beta.
        """
        _, _, beta, sigma2, scalar = ar1_to_gm(phi, innovation_var, freq)
        if not scalar:
            raise InputError(f"GM.from_ar1 takes one phi and one innovation_var, got {phi!r}, "
                             f"{innovation_var!r}")
        return cls(beta=float(beta), sigma2=float(sigma2))

    @classmethod
    def from_bias_instability(cls, B: float, Tc: float, *, factor: float = BI_FACTOR) -> GM:
        """The GM that models a bias instability `B` (u) with correlation time `Tc` (s).

        Follows Quinchia et al. (2013, Sect. 5.5 and eqs. 29-30): the GM's stationary sigma is
        the flat Allan-deviation floor ``factor * B`` (:func:`stochmod.core.units.bi_floor`) and its
        correlation time the one read on the Allan curve. ``factor`` defaults to the exact
        ``sqrt(2 ln 2 / pi)`` (:data:`stochmod.core.units.BI_FACTOR`); pass
        :data:`stochmod.core.units.BI_FACTOR_IEEE` (0.664) to reproduce the paper's numbers.
        """
        B = _positive(B, "GM.from_bias_instability: B (bias instability, u)")
        return cls.from_correlation_time(Tc, float(bi_floor(B, factor)))

    @classmethod
    def from_ieee952(cls, coefficients: Mapping[str, Any], freq: float, *,
                     convention: str = "quinchia") -> GM:
        """GM from a classical reading: a bias instability ``B`` (u) with the correlation time
        ``Tc`` (s) read on the Allan curve, or an autocorrelation's decay ``rate`` (1/s) and
        ``variance`` (u^2). `freq` (Hz) is checked; GM's parameters do not depend on it.

        `convention` for (B, Tc): ``"quinchia"`` (Quinchia et al. 2013 eqs. 19-20, 27-30):
        ``beta = 1 / Tc`` and the stationary sigma the flat Allan-deviation level
        ``BI_FACTOR * B`` (eq. 29); ``"matched"``: the GM whose Allan-variance peak (at
        ``tau = PEAK_X / beta``, value ``PEAK_AV sigma2``) sits on that level at Tc.
        """
        check_freq(freq)
        names = cls.ieee952_set(coefficients)
        c = check_coefficients(coefficients, names, "GM.from_ieee952")
        if names == ("rate", "variance"):
            return cls(beta=c["rate"], sigma2=c["variance"])
        if convention not in CONVENTIONS:
            raise InputError(f"GM.from_ieee952: convention must be one of {CONVENTIONS}; "
                             f"got {convention!r}")
        level = float(bi_floor(c["B"])) ** 2  # flat Allan-variance level, u^2
        if convention == "quinchia":
            return cls(beta=1.0 / c["Tc"], sigma2=level)
        return cls(beta=PEAK_X / c["Tc"], sigma2=level / PEAK_AV)

    def to_ieee952(self, freq: float, names: tuple[str, ...]) -> dict[str, float]:
        """``{"B", "Tc"}`` (the "quinchia" convention) or ``{"rate", "variance"}``."""
        self.require_values()
        check_freq(freq)
        if tuple(names) == ("rate", "variance"):
            return {"rate": float(self.beta), "variance": float(self.sigma2)}
        if tuple(names) == ("B", "Tc"):
            return {"B": float(bi_from_floor(math.sqrt(self.sigma2))), "Tc": 1.0 / self.beta}
        raise InputError(f"GM is built from {list(self.ieee952)}, not {names!r}")

    def ordering_key(self) -> float:
        """``beta`` (1/s): repeated GMs are ordered fastest first."""
        self.require_values()
        return float(self.beta)

    def to_ar1(self, freq: float) -> tuple[float, float]:
        """``(phi, innovation_var)`` of the samples at `freq` Hz: ``exp(-beta/freq)`` and
        ``sigma2 (1 - phi^2)`` in u^2 (computed as ``-sigma2 expm1(-2 beta/freq)``)."""
        self.require_values()
        u = self.beta / check_freq(freq)
        return math.exp(-u), -self.sigma2 * math.expm1(-2.0 * u)

    # ------------------------------------------------------------------ theory
    def wv(self, levels: int, freq: float, wavelet: str = "haar") -> np.ndarray:
        """Haar: ``sigma2 W_m(exp(-beta/freq))``, m = 2^(j-1) (u^2); other wavelets: PSD quadrature."""
        if wavelet != "haar":
            return super().wv(levels, freq, wavelet)
        self.require_values()
        return self.sigma2 * _haar_wv(self.beta / check_freq(freq), levels)[0]

    def wv_jacobian(self, levels: int, freq: float) -> np.ndarray:
        """Columns ``d wv / d beta`` (u^2 s) and ``d wv / d sigma2`` (dimensionless), shape (levels, 2)."""
        self.require_values()
        freq = check_freq(freq)
        w, dw_du = _haar_wv(self.beta / freq, levels)
        return np.column_stack([self.sigma2 / freq * dw_du, w])

    def haar_wv_rows(self, values: ArrayLike, levels: int, freq: float) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`wv` and :meth:`wv_jacobian` at rows ``(beta, sigma2)`` of `values` (K, 2),
        bit for bit, in one call (:func:`stochmod.core.geometric.haar_wv_positive_rows`):
        shapes (K, J) in u^2 and (K, J, 2)."""
        values = np.asarray(values, dtype=np.float64).reshape(-1, 2)
        freq = check_freq(freq)
        w, dw_du = haar_wv_positive_rows(values[:, 0] / freq, _levels_m(levels))
        sigma2 = values[:, 1:2]
        jac = np.empty(w.shape + (2,))
        np.multiply(sigma2 / freq, dw_du, out=jac[..., 0])
        jac[..., 1] = w
        return sigma2 * w, jac

    def psd(self, f: ArrayLike, freq: float) -> np.ndarray:
        """Two-sided PSD of the sampled process, u^2/Hz, at `f` Hz in (-freq/2, freq/2]."""
        self.require_values()
        freq = check_freq(freq)
        u = self.beta / freq
        phi = math.exp(-u)
        s = np.sin(np.pi * np.asarray(f, dtype=np.float64) / freq)
        den = math.expm1(-u) ** 2 + 4.0 * phi * s * s
        return -self.sigma2 * math.expm1(-2.0 * u) / (freq * den)

    def autocovariance(self, lags: ArrayLike, freq: float) -> np.ndarray:
        """``sigma2 exp(-beta |h| / freq)`` at integer lags h (samples), u^2."""
        self.require_values()
        h = np.abs(np.asarray(lags, dtype=np.float64))
        return self.sigma2 * np.exp(-h * (self.beta / check_freq(freq)))

    # ------------------------------------------------------------------ state space
    @property
    def state_names(self) -> tuple[str, ...]:
        """One state: the process value (u)."""
        return ("value",)

    def continuous_block(self, freq: float) -> ContinuousBlock:
        """``F = -beta``, ``G = 1``, ``Qc = 2 beta sigma2`` (u^2/s)."""
        self.require_values()
        return ContinuousBlock(F=[[-self.beta]], G=[[1.0]], Qc=[[2.0 * self.beta * self.sigma2]])

    def initial_covariance(self, freq: float) -> np.ndarray:
        """Stationary: ``[[sigma2]]`` (u^2)."""
        self.require_values()
        return np.array([[float(self.sigma2)]])

    # ------------------------------------------------------------------ simulation
    def simulate(self, n: int, freq: float, rng: np.random.Generator | int) -> np.ndarray:
        """Stationary AR(1) recursion (scipy.signal.lfilter), started from N(0, sigma2)."""
        import scipy.signal  # here: it is slow to import, and only simulations use it

        self.require_values()
        n = check_positive_int(n, name="n")
        phi, q = self.to_ar1(freq)
        g = as_generator(rng)
        x_prev = math.sqrt(self.sigma2) * g.standard_normal()
        e = g.standard_normal(n)
        e *= math.sqrt(q)  # in place: the digits of sqrt(q) * e without a second array
        return scipy.signal.lfilter([1.0], [1.0, -phi], e, zi=[phi * x_prev])[0]

    # ------------------------------------------------------------------ estimation support
    def start(self, wv: np.ndarray, freq: float, *, index: int = 0, count: int = 1,
              rng: np.random.Generator | None = None) -> GM:
        """Starting values from an empirical Haar WV (levels 1..J, u^2).

        The `index`-th of `count` GMs is placed at level ``j = 1 + round((J-1)(index+1)/(count+1))``
        (the fastest at the finest levels, the others log-spaced in tau = 2^(j-1)/freq), with
        the correlation time that puts its WV peak there (``m beta / freq = PEAK_X``) and the
        sigma2 that makes its WV equal the empirical one at that level. `rng` perturbs both
        log-normally (sd 0.5) for multi-start searches.
        """
        wv = as_signal(wv, name="wv", min_length=1)
        freq = check_freq(freq)
        count = check_positive_int(count, name="count")
        index = check_positive_int(index, name="index", minimum=0)
        if index >= count:
            raise InputError(f"index must be < count = {count}, got {index}")
        j = 1 + round((wv.size - 1) * (index + 1) / (count + 1))
        if not wv[j - 1] > 0:
            positive = wv[wv > 0]
            if not positive.size:
                raise InputError("wv has no positive value: cannot start GM.sigma2")
            level_wv = float(np.median(positive))
        else:
            level_wv = float(wv[j - 1])
        m = 2.0 ** (j - 1)
        u = PEAK_X / m
        beta = u * freq
        sigma2 = level_wv / _peak_wv(m)
        if rng is not None:
            beta *= float(np.exp(rng.normal(0.0, 0.5)))
            sigma2 *= float(np.exp(rng.normal(0.0, 0.5)))
        return self.with_values(beta=beta, sigma2=sigma2)

    @classmethod
    def example(cls, freq: float) -> GM:
        """Correlation time 50 samples (``beta = freq / 50``), unit stationary variance."""
        return cls(beta=check_freq(freq) / 50.0, sigma2=1.0)

    def physical(self, freq: float) -> dict[str, PhysicalValue]:
        """Correlation time Tc = 1/beta (s) and stationary sigma = sqrt(sigma2) (u)."""
        self.require_values()
        return {
            "Tc": PhysicalValue(1.0 / self.beta, "s", "correlation time"),
            "sigma": PhysicalValue(math.sqrt(self.sigma2), "u", "stationary standard deviation"),
        }


@hookimpl
def stochmod_processes() -> list[type[Process]]:
    """Register GM."""
    return [GM]
