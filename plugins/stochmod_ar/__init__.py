"""Autoregressive process AR(p): the stochmod plugin for the family ``AR(phi, sigma2)``.

``X_t = sum_{i=1}^p phi_i X_{t-i} + e_t``, ``e_t ~ N(0, sigma2)`` i.i.d., at the model's
sampling frequency ``freq``; discrete time only. The order p is structural: ``"AR(2)"``,
``{"family": "AR", "order": 2}`` or ``AR(phi=[0.5, 0.2], sigma2=1.0)`` (order inferred).

Everything exact goes through the roots z_l of ``z^p - phi_1 z^(p-1) - ... - phi_p``
(:mod:`stochmod_ar._roots`): the autocovariance and the Haar WV are residue sums of
``sigma2 z^(p-1) K(z) / (P(z) P*(z))``, i.e. sums of geometric terms ``c_l z_l^|h|`` whose Haar
WV comes from :func:`stochmod.core.geometric.haar_wv_geometric` (stable as |z_l| -> 1, phi near +-1);
groups of near-repeated roots are summed by a contour integral around the group instead of
by their individually large residues, and levels whose estimated rounding error exceeds
1e-12 are summed again with double-double residues. Accuracy against the exact value for
the given binary phi (mpmath at 150 digits): relative error below ~2e-12 in every test,
typically 1e-15, including roots within 1e-8 of +-1 or of the unit circle, near-double roots
and all levels up to 30 -- also where the problem itself is ill-conditioned (one ulp of phi
changing the WV by 1e-2 at deep levels). Coefficients whose polynomial has a root within
1e-28 of the unit circle are refused as not stationary.

State space: companion form with states ``(x_t, x_{t-1}, ..., x_{t-p+1})``, ``Q = sigma2 e1 e1'``,
``P0`` the stationary covariance (Toeplitz of the exact autocovariance); the base class
composes whole numbers of steps for filter steps that are multiples of ``1/freq``.
"""

from __future__ import annotations

import functools
import math
import numbers
import warnings
from collections.abc import Mapping
from fractions import Fraction
from typing import Any, ClassVar

import attrs
import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike

from stochmod.sdk import (
    WV_PEAK_X,
    AccuracyWarning,
    DomainError,
    InputError,
    Parameter,
    PhysicalValue,
    Process,
    SpecError,
    StateSpaceBlock,
    as_generator,
    as_signal,
    check_coefficients,
    check_freq,
    check_positive_int,
    get_domain,
    haar_wv_geometric,
    haar_wv_geometric_parts,
    hookimpl,
)
from stochmod_ar._jacobian import haar_wv_phi_jacobian
from stochmod_ar._roots import ARRoots, ar_roots

__all__ = ["AR", "stochmod_processes"]

_PHI = Parameter("phi", "stationary_ar", "1", "AR coefficients phi_1..phi_p (size = order)",
                 role="shape")
_SIGMA2 = Parameter("sigma2", "positive", "u^2", "innovation variance per sample", role="variance")
_CHUNK = 1 << 15
_EPS = 2.0 ** -52
_PRECISE_ABOVE = 1e-12  # estimated relative rounding error above which residues go double-double
_SPLIT_ABOVE = 8.0 * _EPS  # direct residue sums within this (estimated, relative) need no split form
_JACOBIAN_RTOL = 1e-10  # estimated relative error at which the Jacobian step ladder stops
_ANALYTIC_RTOL = 1e-6  # estimated relative error up to which the analytic Jacobian is used
_UNRESOLVED = 0.1  # estimated relative error of a Jacobian entry beyond which it is reported


def _check_order(order: object) -> int:
    if isinstance(order, bool) or not isinstance(order, (numbers.Integral, float)) or (
        isinstance(order, float) and not order.is_integer()
    ):
        raise SpecError(f"AR order must be a whole number >= 1, got {order!r}")
    if order < 1:
        raise SpecError(f"AR order must be >= 1, got {order!r}")
    return int(order)


def _phi_array(phi: object) -> np.ndarray:
    try:
        arr = np.atleast_1d(np.asarray(phi, dtype=np.float64))
    except (TypeError, ValueError):
        raise DomainError(f"AR.phi must be a list of numbers, got {phi!r}") from None
    if arr.ndim != 1:
        raise DomainError(f"AR.phi must be one-dimensional, got shape {arr.shape}")
    return arr


@attrs.frozen
class AR(Process):
    """Autoregressive process of order `order`.

    Parameters
    ----------
    order : int, optional
        p >= 1 (structural). Inferred from `phi` when omitted; 1 when both are omitted.
    phi : sequence of float, optional
        Coefficients phi_1..phi_p of a stationary AR(p) (dimensionless); free when None.
    sigma2 : float, optional
        Innovation variance per sample, u^2 (> 0); free when None.
    """

    order: int | None = None
    phi: tuple[float, ...] | None = None
    sigma2: float | None = None

    family: ClassVar[str] = "AR"
    description: ClassVar[str] = "autoregressive process AR(p) (discrete time)"
    parameter_specs: ClassVar[tuple[Parameter, ...]] = (_PHI, _SIGMA2)
    structural_fields: ClassVar[tuple[str, ...]] = ("order",)
    ieee952: ClassVar[tuple[tuple[str, ...], ...]] = (("ar", "innovation"),)

    def __attrs_post_init__(self) -> None:
        arr = None if self.phi is None else _phi_array(self.phi)
        order = self.order
        if order is None:
            order = arr.size if arr is not None else 1
        order = _check_order(order)
        if arr is not None and arr.size != order:
            raise SpecError(f"AR order {order} does not match the {arr.size} coefficient(s) in phi={arr.tolist()}")
        object.__setattr__(self, "order", order)
        if arr is not None:
            if not np.all(np.isfinite(arr)):
                raise DomainError(f"AR.phi = {arr.tolist()} must be finite")
            if not get_domain(_PHI.domain).contains(arr):  # partial autocorrelations in (-1, 1)
                radius = float(np.max(np.abs(np.roots(np.concatenate([[1.0], -arr])))))
                raise DomainError(
                    f"AR.phi = {arr.tolist()} is not stationary: the roots of z^p - phi_1 z^(p-1) "
                    f"- ... - phi_p must lie inside the unit circle; the largest has modulus {radius:.9g}"
                )
            object.__setattr__(self, "phi", tuple(float(c) for c in arr))
            _stationary_roots(self.phi)  # the PACF test rounds; the refined roots decide
        if self.sigma2 is not None:
            object.__setattr__(self, "sigma2", _SIGMA2.check(self.sigma2, self.family))

    def parameters(self) -> tuple[Parameter, ...]:
        """``phi`` (size = order) and ``sigma2``."""
        return (attrs.evolve(_PHI, size=self.order), _SIGMA2)

    # ------------------------------------------------------------------ helpers
    def _roots(self) -> ARRoots:
        self.require_values()
        return _stationary_roots(self.phi)

    def _companion(self) -> np.ndarray:
        p = self.order
        A = np.zeros((p, p))
        A[0] = self.phi
        A[1:, :-1] = np.eye(p - 1)
        return A

    # ------------------------------------------------------------------ theory
    def wv(self, levels: int, freq: float, wavelet: str = "haar") -> np.ndarray:
        """Haar: exact residue sum over the roots (u^2); other wavelets: PSD quadrature.

        Per level, the better conditioned of two exact forms: ``sum_l c_l W_m(z_l)``, or
        ``LRV / (2m) + sum_l c_l R_m(z_l)`` with the long-run variance
        ``LRV = sigma2 / (1 - sum phi)^2`` (exactly rounded) and the decaying part R_m of the
        Haar kernel (:func:`stochmod.core.geometric.haar_wv_geometric_parts`); the second keeps its
        digits at deep levels when roots close to the unit circle make the residues large.
        """
        if wavelet != "haar":
            return super().wv(levels, freq, wavelet)
        check_freq(freq)
        m = 2.0 ** np.arange(check_positive_int(levels, name="levels"))
        roots = self._roots()

        def haar(mm: np.ndarray):  # kernel W_m for the half-widths mm
            def kernel(sign: np.ndarray, u: np.ndarray, cols: np.ndarray) -> np.ndarray:
                w = haar_wv_geometric(-u[:, None], mm[None, cols], sign=sign[:, None])
                return w.astype(np.complex128)
            return kernel

        whole = haar(m)

        def decaying(sign: np.ndarray, u: np.ndarray, cols: np.ndarray) -> np.ndarray:
            rest = haar_wv_geometric_parts(-u[:, None], m[None, cols], sign=sign[:, None])[1]
            return rest.astype(np.complex128)

        direct, err_direct = roots.residue_sum(whole, 2.0 * m, smooth=True)
        if np.all(err_direct <= _SPLIT_ABOVE * np.abs(direct)):  # a few ulps already
            use_split = np.zeros(m.size, dtype=bool)
            lead = err_rest = np.zeros(m.size)
            out = direct
        else:
            rest, err_rest = roots.residue_sum(decaying, 2.0 * m, smooth=True)
            phi1 = float(1 - sum(Fraction(c) for c in self.phi))  # 1 - sum phi, exactly rounded
            lead = 1.0 / (phi1 * phi1 * 2.0 * m)
            use_split = lead + err_rest < err_direct
            out = np.where(use_split, lead + rest, direct)
        # estimated relative rounding error; redo the worst levels with double-double residues
        est = _EPS * np.where(use_split, lead + err_rest, err_direct) / np.abs(out)
        bad = est > _PRECISE_ABOVE
        # complex roots near the unit circle: z^m carries a phase m arg(z) that double
        # precision only knows to m * eps; the double-double residues use the refined roots
        cplx = roots.partner != np.arange(roots.p)
        for uk in roots.u[cplx]:
            with np.errstate(under="ignore"):
                bad |= np.exp(-m * uk.real) * m * abs(uk.imag) > 1e3
        if np.any(bad):
            out[bad] = roots.haar_sum_precise(haar(m[bad]), m[bad])
        return self.sigma2 * out

    def wv_jacobian(self, levels: int, freq: float) -> np.ndarray:
        """Jacobian of the Haar WV w.r.t. ``(phi_1..phi_p, sigma2)``, shape (levels, p + 1).

        ``d wv / d sigma2 = wv / sigma2`` exactly. The phi columns from the residue form of the
        derivative (:mod:`stochmod_ar._jacobian`) wherever its estimated relative error is at
        most 1e-6 (the actual error is typically 10-100 times smaller); where it is larger
        (near-repeated roots, roots within ~1e-7 of +-1 or complex pairs by the unit circle at
        deep levels), Richardson differences (:meth:`_wv_jacobian_by_differences`) replace the
        entries whose own error estimate is smaller. Relative accuracy ~1e-12 typically, 1e-4
        or better next to near-repeated roots, degrading like ``1e-10 / (1 - max |z|)`` as roots
        approach the unit circle (5e-6 for roots 5e-9 from +1 and -1); next to near-repeated
        roots that are also close to the circle, the differences' rounding at their largest step
        sets a floor of about ``1e-12 / (0.3 d)``, ``d`` the distance in phi-space to
        non-stationarity (:meth:`_wv_jacobian_by_differences`; 1.2e-4 measured for real roots
        7e-5 and 3e-4 from +1, where ``d = 1e-8``). Where neither form
        resolves an entry to 10% (several roots within ~1e-8 of the circle, where one ulp of
        phi moves the WV by more than the step differences need), an
        :class:`~stochmod.core.errors.AccuracyWarning` names the entries.
        """
        freq = check_freq(freq)
        base = self.wv(levels, freq)
        analytic = haar_wv_phi_jacobian(self._roots(), 2.0 ** np.arange(levels))
        if analytic is None:  # near-repeated roots: differences throughout
            analytic = (np.zeros((levels, self.order)), np.full((levels, self.order), np.inf))
        jac, abs_err = analytic
        cols = []
        for i in range(self.order):
            col = self.sigma2 * jac[:, i]
            err = self.sigma2 * abs_err[:, i]
            bad = ~(err <= _ANALYTIC_RTOL * np.abs(col))
            if np.any(bad):  # differences where their own error estimate is smaller
                diff, diff_err = self._wv_jacobian_by_differences(i, levels, freq, base)
                better = bad & ~(diff_err >= err)
                col[better] = diff[better]
                err[better] = diff_err[better]
                # relative to the entry, or to 1e-3 wv where the derivative itself vanishes
                lost = bad & ~(err <= _UNRESOLVED * np.maximum(np.abs(col), 1e-3 * base))
                if np.any(lost):
                    warnings.warn(
                        f"AR.wv_jacobian at phi = {list(self.phi)}: d wv / d phi_{i + 1} is not "
                        f"resolved in double precision at level(s) {(np.flatnonzero(lost) + 1).tolist()} "
                        "(roots within ~1e-8 of the unit circle); estimated error above 10%",
                        AccuracyWarning, stacklevel=2)
            cols.append(col)
        cols.append(base / self.sigma2)
        return np.column_stack(cols)

    def _wv_jacobian_by_differences(self, i: int, levels: int, freq: float,
                                    base: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Column ``d wv / d phi_i`` by Richardson-extrapolated central differences, with the
        estimated absolute error of each entry.

        Steps as represented in binary, per level from the step of a ladder
        ``(0.3, 1e-2, 1e-4) * margin`` with the smallest estimated error (truncation: the
        Richardson correction; rounding: ``1e-12 wv / step``, the WV's worst relative accuracy).
        The margin ``min(1, min_k |P(z_k / |z_k|)| / p)`` is the distance in phi-space to
        non-stationarity (``(1 - |z|) |P'(z)|`` for a simple root, the square of the distance for
        a double one), the scale on which the WV varies with phi; a step is divided by 8 until
        the perturbed coefficients stay stationary. The ladder stops at the first step whose
        estimated error is below 1e-10 relative at every level. Relative accuracy ~1e-9
        typically, ~1e-6 next to a double root close to the unit circle.
        """
        z = self._roots().z
        # distance in phi-space to non-stationarity: |P| at the roots' projections on the circle
        on_circle = np.where(z != 0, np.exp(1j * np.angle(z)), 1.0)  # z / |z|, also subnormal z
        scale = min(1.0, float(np.min(np.abs(np.prod(on_circle[:, None] - z[None, :], axis=1)))) / z.size)
        phi = np.asarray(self.phi)

        def central(step: float) -> np.ndarray:
            hi, lo = phi.copy(), phi.copy()
            hi[i] += step
            lo[i] -= step
            if hi[i] == lo[i]:  # step below the coefficient's ulp: not a difference
                return np.full(levels, np.nan)
            up = AR(phi=hi, sigma2=self.sigma2).wv(levels, freq)
            down = AR(phi=lo, sigma2=self.sigma2).wv(levels, freq)
            return (up - down) / (hi[i] - lo[i])

        best = np.full(levels, np.inf)
        col = np.zeros(levels)
        for rel in (1e-2, 0.3, 1e-4):  # the middle step first: usually enough
            h = rel * scale
            while True:
                try:
                    coarse, fine = central(h), central(h / 2)
                    break
                except DomainError:
                    h /= 8.0
            err = np.abs(fine - coarse) / 3.0 + 1e-12 * np.abs(base) / h
            better = err < best  # False where a step was unresolvable (NaN)
            col = np.where(better, (4.0 * fine - coarse) / 3.0, col)
            best = np.fmin(err, best)  # a NaN (unresolvable step) never replaces an estimate
            if np.all(best <= _JACOBIAN_RTOL * np.abs(col)):
                break
        return col, best

    def autocovariance(self, lags: ArrayLike, freq: float) -> np.ndarray:
        """Exact autocovariance at integer `lags` (samples), u^2: residues at the roots."""
        check_freq(freq)
        roots = self._roots()
        lags = np.asarray(lags)
        h = np.abs(lags.astype(np.float64)).reshape(-1)
        out = np.empty(h.size)
        for start in range(0, h.size, _CHUNK):
            hh = h[start : start + _CHUNK]

            def kernel(sign: np.ndarray, u: np.ndarray, cols: np.ndarray, hh: np.ndarray = hh) -> np.ndarray:
                k = hh[None, cols]
                with np.errstate(invalid="ignore", over="ignore"):
                    zh = sign[:, None] ** k * np.exp(-u[:, None] * k)
                return np.where(k == 0, 1.0 + 0j, zh)

            out[start : start + hh.size] = roots.residue_sum(kernel, hh)[0]
        return self.sigma2 * out.reshape(lags.shape)

    def psd(self, f: ArrayLike, freq: float) -> np.ndarray:
        """Two-sided PSD ``sigma2 / (freq prod_l |e^{iw} - z_l|^2)``, w = 2 pi f / freq (u^2/Hz).

        Each factor is formed about the root's anchor (+1, -1 or 0) so that it keeps its digits
        near f = 0 (root near +1) and f = freq/2 (root near -1).
        """
        freq = check_freq(freq)
        roots = self._roots()
        fa = np.abs(np.asarray(f, dtype=np.float64))
        w = 2.0 * np.pi * fa / freq
        # e^{iw} - 1 and e^{iw} + 1 without cancellation
        near_p = -2.0 * np.sin(0.5 * w) ** 2 + 1j * np.sin(w)
        v = 2.0 * np.pi * (fa - 0.5 * freq) / freq  # w - pi
        near_m = 2.0 * np.sin(0.5 * v) ** 2 - 1j * np.sin(v)
        e = np.exp(1j * w)
        den = np.ones(fa.shape)
        for a, wl in zip(roots.anchor, roots.w):
            base = near_p if a > 0 else (near_m if a < 0 else e)
            den = den * np.abs(base - wl) ** 2
        return self.sigma2 / (freq * den)

    # ------------------------------------------------------------------ state space
    @property
    def state_names(self) -> tuple[str, ...]:
        """``value`` (x_t) then ``lag1`` ... ``lag{p-1}`` (x_{t-1} ...), u."""
        return ("value",) + tuple(f"lag{i}" for i in range(1, self.order))

    def discrete_block(self, freq: float) -> StateSpaceBlock:
        """Companion form at the native step 1/freq: ``Phi`` companion, ``Q = sigma2 e1 e1'``."""
        self.require_values()
        freq = check_freq(freq)
        Q = np.zeros((self.order, self.order))
        Q[0, 0] = self.sigma2
        return StateSpaceBlock(self.state_names, self._companion(), Q, self.output_row(freq),
                               self.initial_covariance(freq), 0.0, 1.0 / freq, None)

    def initial_covariance(self, freq: float) -> np.ndarray:
        """Stationary covariance of the state: ``Toeplitz(gamma(0..p-1))`` (u^2), the solution of
        ``P = Phi P Phi' + Q`` (scipy.linalg.solve_discrete_lyapunov), from the exact gamma."""
        return scipy.linalg.toeplitz(self.autocovariance(np.arange(self.order), freq))

    # ------------------------------------------------------------------ simulation
    def simulate(self, n: int, freq: float, rng: np.random.Generator | int) -> np.ndarray:
        """The recursion (scipy.signal.lfilter) started from the stationary law of the p past values."""
        import scipy.signal  # here: it is slow to import, and only simulations use it

        self.require_values()
        n = check_positive_int(n, name="n")
        g = as_generator(rng)
        P0 = self.initial_covariance(check_freq(freq))
        evals, evecs = np.linalg.eigh(P0)
        past = (evecs * np.sqrt(np.clip(evals, 0.0, None))) @ g.standard_normal(self.order)
        a = np.concatenate([[1.0], -np.asarray(self.phi)])
        zi = scipy.signal.lfiltic([1.0], a, past)  # past = (x_{-1}, x_{-2}, ...)
        e = math.sqrt(self.sigma2) * g.standard_normal(n)
        return scipy.signal.lfilter([1.0], a, e, zi=zi)[0]

    # ------------------------------------------------------------------ estimation support
    def start(self, wv: np.ndarray, freq: float, *, index: int = 0, count: int = 1,
              rng: np.random.Generator | None = None) -> AR:
        """A stable AR(1)-shaped guess ``phi = (r, 0, ..., 0)`` from an empirical Haar WV (u^2).

        The first AR of a model matches r and sigma2 to the WV at levels 1 and 2 (an AR(1)
        has ``wv_2 / wv_1 = W_2(r) / W_1(r)``, monotone in r); further ones (`index` >= 1 of
        `count`) are placed at deeper levels like GM starts (``r = exp(-1.89 / m)``).
        `rng` perturbs atanh(r) (sd 0.3) and sigma2 (log-normal, sd 0.5).
        """
        wv = as_signal(wv, name="wv", min_length=1)
        check_freq(freq)
        count = check_positive_int(count, name="count")
        index = check_positive_int(index, name="index", minimum=0)
        if index >= count:
            raise InputError(f"index must be < count = {count}, got {index}")
        if not np.all(wv > 0):
            raise InputError("wv must be positive at every level to start AR")
        if rng is not None and rng.random() < 0.5:  # half the perturbed starts: the ladder
            levels = _ladder_levels(wv.size, self.order, index, count)
            levels = np.clip(levels + rng.normal(0.0, 1.0, levels.size), 1.0, wv.size)
            return self._real_roots_start(wv, levels)
        if index == 0 and wv.size >= 2:
            r = _ar1_from_ratio(float(wv[1] / wv[0]))
            j = 1
        else:
            j = 1 + round((wv.size - 1) * (index + 1) / (count + 1))
            r = math.exp(-WV_PEAK_X / 2.0 ** (j - 1))
        if rng is not None:
            r = math.tanh(math.atanh(r) + rng.normal(0.0, 0.3))
        log_r = math.log(abs(r)) if r != 0 else -math.inf
        gamma0_per_level = float(haar_wv_geometric(log_r, 2 ** (j - 1), sign=1 if r >= 0 else -1))
        sigma2 = float(wv[j - 1]) / gamma0_per_level * (1.0 - r) * (1.0 + r)
        if rng is not None:
            sigma2 *= float(np.exp(rng.normal(0.0, 0.5)))
        phi = [r] + [0.0] * (self.order - 1)
        return self.with_values(phi=phi, sigma2=sigma2)

    def start_alternatives(self, wv: np.ndarray, freq: float, *, index: int = 0,
                           count: int = 1) -> tuple[AR, ...]:
        """The ladder guess: p real roots placed like GM starts over the levels.

        The ratio start of :meth:`start` reads the two finest levels, where white noise (or a
        faster component) usually dominates in a composite model. Here the k-th root of the
        `index`-th AR of `count` is ``z_k = exp(-PEAK_X / m_k)``, whose WV peaks at level
        ``j_k = 1 + (J-1)(index p + k + 1) / (count p + 1)`` (``m_k = 2^(j_k - 1)``), and sigma2
        makes the AR's WV equal the empirical one at the deepest of these levels.
        """
        wv = as_signal(wv, name="wv", min_length=1)
        check_freq(freq)
        if not np.all(wv > 0):
            raise InputError("wv must be positive at every level to start AR")
        return (self._real_roots_start(wv, _ladder_levels(wv.size, self.order, index, count)),)

    def _real_roots_start(self, wv: np.ndarray, levels: np.ndarray) -> AR:
        """AR with real roots peaking at the (fractional) `levels`, matched at the deepest."""
        roots = np.exp(-WV_PEAK_X / 2.0 ** (np.asarray(levels, float) - 1.0))
        while True:  # rounding of the coefficients may leave a root on the circle: shrink
            try:
                unit = AR(phi=-np.poly(roots)[1:], sigma2=1.0)
                break
            except DomainError:
                roots = roots * roots
        phi = unit.phi
        j = int(round(float(np.max(levels))))
        sigma2 = float(wv[j - 1]) / float(unit.wv(j, 1.0)[j - 1])
        return self.with_values(phi=phi, sigma2=sigma2)

    @classmethod
    def from_ieee952(cls, coefficients: Mapping[str, Any], freq: float) -> AR:
        """AR(p) of an AR fit's coefficients ``ar`` (phi_1..phi_p) and ``innovation`` (u^2)."""
        check_freq(freq)
        c = check_coefficients(coefficients, cls.ieee952_set(coefficients), "AR.from_ieee952")
        return cls(phi=c["ar"], sigma2=c["innovation"])

    def to_ieee952(self, freq: float, names: tuple[str, ...]) -> dict[str, Any]:
        """``{"ar": phi, "innovation": sigma2}``."""
        self.require_values()
        return {"ar": tuple(self.phi), "innovation": float(self.sigma2)}

    def ordering_key(self) -> float:
        """``phi_1``: the larger first."""
        self.require_values()
        return float(self.phi[0])

    @classmethod
    def example(cls, freq: float) -> AR:
        """AR(2) ``phi = (1.5, -0.75)``: complex roots of modulus 0.866 at +-30 degrees (a damped
        oscillation of period 12 samples), ``sigma2 = 1``."""
        return cls(phi=(1.5, -0.75), sigma2=1.0)

    def physical(self, freq: float) -> dict[str, PhysicalValue]:
        """Stationary sigma (u) and the e-folding time of the slowest root (s)."""
        freq = check_freq(freq)
        roots = self._roots()
        slowest = float(np.min(roots.u.real))
        return {
            "sigma": PhysicalValue(math.sqrt(float(self.autocovariance(0, freq))), "u",
                                   "stationary standard deviation"),
            "Tc": PhysicalValue(1.0 / (slowest * freq) if slowest > 0 else math.inf, "s",
                                "e-folding time of the slowest root, -1/(freq log|z|)"),
        }


@functools.lru_cache(maxsize=512)
def _stationary_roots(phi: tuple[float, ...]) -> ARRoots:
    """The refined roots, after checks that decide stationarity for the binary coefficients:
    ``P(1) = 1 - sum phi > 0`` and ``(-1)^p P(-1) > 0`` exactly (fractions), and every refined
    root at least 1e-28 inside the unit circle (closer is beyond the double-double
    refinement; the partial-autocorrelation test of the domain rounds at ~1e-16)."""
    exact = [Fraction(c) for c in phi]
    at_one = 1 - sum(exact)
    at_minus_one = 1 - sum(c * (-1) ** i for i, c in enumerate(exact, start=1))
    roots = ar_roots(phi)
    if not (at_one > 0 and at_minus_one > 0 and np.all(roots.abs2m1 < -1e-28)):
        worst = float(np.max(roots.abs2m1))
        raise DomainError(
            f"AR.phi = {list(phi)} is not stationary: the polynomial with these (binary) "
            f"coefficients has a root on or outside the unit circle (|z|^2 - 1 = {worst:.3g}, "
            f"P(1) = {float(at_one):.3g}, (-1)^p P(-1) = {float(at_minus_one):.3g})"
        )
    return roots


def _ladder_levels(n_levels: int, order: int, index: int, count: int) -> np.ndarray:
    """Fractional levels of the `order` roots of the `index`-th AR of `count`, spread evenly
    over levels 1..`n_levels` (like GM starts: the first ones finest)."""
    k = np.arange(order) + index * order + 1
    return 1.0 + (n_levels - 1) * k / (count * order + 1)


def _ar1_from_ratio(ratio: float) -> float:
    """The r in (-0.99, 0.99) whose AR(1) has ``wv_2 / wv_1 = ratio`` (clipped at the ends)."""

    def f(r: float) -> float:
        lr = math.log(abs(r)) if r else -math.inf
        s = 1 if r >= 0 else -1
        return float(haar_wv_geometric(lr, 2, sign=s) / haar_wv_geometric(lr, 1, sign=s)) - ratio

    lo, hi = -0.99, 0.99
    if f(lo) >= 0:
        return lo
    if f(hi) <= 0:
        return hi
    import scipy.optimize  # here: the registry loads every plugin, and only AR starts use it

    return float(scipy.optimize.brentq(f, lo, hi, xtol=1e-12))


@hookimpl
def stochmod_processes() -> list[type[Process]]:
    """Register AR."""
    return [AR]
