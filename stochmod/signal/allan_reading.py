"""The IEEE Std 952 slope reading of an Allan variance curve (Quinchia et al. 2013, Sec. 4.4, 5.5).

On a log-log plot the Allan variance (AV) of a sum of independent power-law noises is a sum
of straight lines. For a rate signal of unit u (rad/s, m/s^2 ...):

====  ==========================  ==========  ===========  ====================  ==============
name  noise                       AV slope    ADEV slope   AV                    SI unit
====  ==========================  ==========  ===========  ====================  ==============
Q     quantization                -2          -1           3 Q^2 / tau^2         u*s
N     white noise (ARW / VRW)     -1          -1/2         N^2 / tau             u*sqrt(s)
B     bias instability (flicker)  0           0            (2 ln2 / pi) B^2      u
K     rate / accel. random walk   +1          +1/2         K^2 tau / 3           u/sqrt(s)
R     rate ramp                   +2          +1           R^2 tau^2 / 2         u/s
====  ==========================  ==========  ===========  ====================  ==============

:func:`allan_reading` computes the overlapping AV on a dense log grid, finds the maximal
contiguous tau ranges where the local log-log slope stays within a tolerance of one of the
slopes above (joined across short noisy excursions; the widest range per slope), and fits a
line of that fixed slope in each range by weighted least squares in log space (weights: the
Greenhall EDF for that noise type), after subtracting the other identified lines (a few
back-fitting sweeps). A term is kept only if the share of the curve its line explains over
its range is significantly (one-sided, level alpha) above ``min_share``, and B only if a flat
line fits its range significantly better than a valley between a white-noise and a
random-walk line (whose bottom is flat but holds no bias instability). A coefficient is
reported only where the curve shows it, never invented. The method, its checks and its
Monte Carlo spread: docs/allan.md.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import attrs
import numpy as np
from numpy.typing import ArrayLike
from scipy.linalg import solve_triangular
from scipy.optimize import least_squares
from scipy.special import chdtri, ndtri

from stochmod._fields import array_field
from stochmod._validation import as_signal, check_freq, check_positive_int
from stochmod.errors import EstimationError, InputError
from stochmod.geometric import AV_PEAK_VALUE, WV_PEAK_X
from stochmod.reporting import format_number, format_table
from stochmod.signal.allan import AllanVariance, avar, greenhall_edf, local_slopes
from stochmod.units import BI_FACTOR, convert, parse_unit

__all__ = [
    "Coefficient",
    "AllanReading",
    "allan_reading",
    "TERMS",
    "DATASHEET_UNITS",
    "GM_CONVENTIONS",
    "GM_PEAK_X",
    "GM_PEAK_AV",
]

#: name -> (AV slope, noise, SI unit template in the signal unit u)
TERMS: dict[str, tuple[int, str, str]] = {
    "Q": (-2, "quantization", "u*s"),
    "N": (-1, "white noise (angle / velocity random walk)", "u*sqrt(s)"),
    "B": (0, "bias instability", "u"),
    "K": (1, "rate / acceleration random walk", "u/sqrt(s)"),
    "R": (2, "rate ramp", "u/s"),
}
#: coefficient^2 = factor * C where the line is AV = C tau^slope (B: the flat deviation floor
#: is BI_FACTOR * B)
_FACTOR = {"Q": 1.0 / 3.0, "N": 1.0, "B": 1.0 / BI_FACTOR**2, "K": 3.0, "R": 2.0}
#: Noise exponent (rate PSD ~ f^alpha) of each term for its EDF. A ramp is deterministic in a
#: record (its AV, R^2 tau^2 / 2, has no sampling error of its own): the white-noise EDF.
_NOISE = {"Q": 2, "N": 0, "B": -1, "K": -2, "R": 0}
#: Correlation of ln AV estimates one octave apart, by term, and its floor (simulated:
#: white noise 0.53, flicker 0.68, random walk 0.88, decaying about geometrically with the
#: octave distance; quantization about 0.3 at every distance: all scales share the U_t).
_OCTAVE_CORR = {"Q": (0.5, 0.3), "N": (0.55, 0.0), "B": (0.7, 0.0), "K": (0.88, 0.0),
                "R": (0.55, 0.0)}
#: Averaging time (s) at which the deviation line equals the coefficient (IEEE 952 read-off).
_READ_TAU = {"Q": math.sqrt(3.0), "N": 1.0, "K": 3.0, "R": math.sqrt(2.0)}
#: tau / Tc at the maximum of a first-order Gauss-Markov AV, and that maximum / sigma^2:
#: where a correlated bump sits on the curve (a flat region may be one).
#: AV = (2 s^2 Tc / tau) [1 - (Tc / 2 tau)(3 - 4 exp(-tau/Tc) + exp(-2 tau/Tc))]
#: (IEEE 952 Annex C); the values are checked against a numerical maximisation in the tests.
GM_PEAK_X = WV_PEAK_X
GM_PEAK_AV = AV_PEAK_VALUE
#: Conventions of the ``gm`` option (how a model is built from B and Tc,
#: :func:`stochmod.classical.allan_model`): "quinchia" (default) or "matched".
GM_CONVENTIONS = ("quinchia", "matched")
#: Datasheet unit of each term, by the physical kind of the signal unit ("rate", "acceleration").
DATASHEET_UNITS: dict[str, dict[str, str]] = {
    "rate": {"Q": "arcsec", "N": "deg/sqrt(h)", "B": "deg/h", "K": "deg/h^1.5", "R": "deg/h^2"},
    "acceleration": {"Q": "m/s", "N": "m/s/sqrt(h)", "B": "ug", "K": "m/s/h^1.5", "R": "m/s/h^2"},
}


@attrs.frozen
class Coefficient:
    """One noise coefficient read off the Allan variance.

    Attributes
    ----------
    value : float
        The coefficient in SI for the signal unit u (see :data:`TERMS`).
    low, high : float
        Bounds of its ``100 (1 - alpha)`` % interval.
    tau_range : tuple of float
        The averaging times (s) of the region the line was fitted on (first, last point).
    slope : int
        Log-log slope of the Allan *variance* line (-2 .. 2; the deviation's is half).
    unit_hint : str
        Unit of `value`, e.g. ``"u*sqrt(s)"`` or ``"(rad/s)*sqrt(s)"`` when the unit is known.
    n_points : int
        Number of AV points in the region.
    region : str
        "auto" (identified from the slopes) or "user" (given in ``regions``).
    """

    value: float
    low: float
    high: float
    tau_range: tuple[float, float]
    slope: int
    unit_hint: str
    n_points: int = 0
    region: str = "auto"

    @property
    def line(self) -> float:
        """C of the fitted line ``AV = C tau^slope`` (unit^2 s^-slope)."""
        return self.value**2 / _FACTOR[_name_of_slope(self.slope)]

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dict of the fields."""
        return {
            "value": float(self.value), "low": float(self.low), "high": float(self.high),
            "tau_range": [float(t) for t in self.tau_range], "slope": int(self.slope),
            "unit_hint": self.unit_hint, "n_points": int(self.n_points), "region": self.region,
        }


def _name_of_slope(slope: int) -> str:
    return next(k for k, v in TERMS.items() if v[0] == slope)


@attrs.frozen
class AllanReading:
    """Coefficients read off an Allan variance curve by its slopes (IEEE Std 952).

    Attributes
    ----------
    Q, N, B, K, R : Coefficient or None
        Quantization (u*s), white noise (u*sqrt(s)), bias instability (u), random walk
        (u/sqrt(s)), rate ramp (u/s); None where the curve shows no such region.
    Tc : float or None
        Averaging time (s) of the minimum of the AV curve within the flat (B) region. Quinchia
        et al. (2013, Sec. 5.5 and Table 5) read the correlation time of the first-order
        Gauss-Markov model of the bias instability off the flat segment of the curve and use
        it as is (beta = 1 / Tc, their eq. 1). None without a B region.
    avar : AllanVariance
        The overlapping Allan variance the reading used (dense log grid).
    slopes : ndarray
        Local log-log slope of the AV at each of its taus.
    freq : float
        Sampling frequency, Hz.
    unit : str or None
        Unit of the signal when given (e.g. "rad/s"); enables the datasheet column.
    gm : str
        Convention for a model built from B and Tc (:data:`GM_CONVENTIONS`,
        :func:`stochmod.classical.allan_model`).
    method : str
        "fit" (fixed-slope weighted least squares over each region) or "ieee" (single-point
        read-off: N at tau = 1 s, K at 3 s, Q at sqrt 3 s, R at sqrt 2 s on the region's
        line through its nearest point; B from the minimum of the region / 0.664).
    alpha : float
        Significance level of the intervals.
    """

    Q: Coefficient | None
    N: Coefficient | None
    B: Coefficient | None
    K: Coefficient | None
    R: Coefficient | None
    Tc: float | None
    avar: AllanVariance
    slopes: np.ndarray = array_field()
    freq: float = 1.0
    unit: str | None = None
    gm: str = "quinchia"
    method: str = "fit"
    alpha: float = 0.05

    @property
    def coefficients(self) -> dict[str, Coefficient | None]:
        """The five coefficients by name, in slope order (Q, N, B, K, R)."""
        return {name: getattr(self, name) for name in TERMS}

    def coefficient_values(self) -> dict[str, float]:
        """The identified coefficients in SI, ``{"N": ..., "B": ..., "Tc": ..., "K": ...}``
        (names of :data:`stochmod.coefficients.COEFFICIENTS`; Tc with B);
        :func:`stochmod.classical.allan_model` turns them into a model."""
        out = {name: float(c.value) for name, c in self.coefficients.items() if c is not None}
        if "B" in out and self.Tc is not None:
            out["Tc"] = float(self.Tc)
        return out

    def line(self, tau: ArrayLike) -> np.ndarray:
        """Sum of the identified lines (the AV the reading explains) at `tau` (s), unit^2."""
        t = np.asarray(tau, dtype=float)
        total = np.zeros_like(t)
        for c in self.coefficients.values():
            if c is not None:
                total = total + c.line * t**c.slope
        return total

    def summary(self) -> str:
        """Table of the coefficients with intervals (and datasheet units when possible)."""
        level = format_number(100 * (1 - self.alpha))
        kind = _datasheet_kind(self.unit)
        headers = ["coef", "slope", "value", "CI low", "CI high", "unit", "tau range [s]"]
        if kind is not None:
            headers += ["datasheet", "ds unit"]
        rows = []
        for name, c in self.coefficients.items():
            if c is None:
                row = [name, "", "not identified", "", "", "", ""]
                if kind is not None:
                    row += ["", ""]
            else:
                rng = f"{format_number(c.tau_range[0], 3)}-{format_number(c.tau_range[1], 3)}"
                row = [name, _slope_text(c.slope), c.value, c.low, c.high, c.unit_hint, rng]
                if kind is not None:
                    ds_unit = DATASHEET_UNITS[kind][name]
                    row += [_to_datasheet(c.value, self.unit, name, ds_unit), ds_unit]
            rows.append(row)
        title = (
            f"Allan variance slope reading ({self.method}, {level}% CI, N = {self.avar.n}, "
            f"freq = {format_number(self.freq)} Hz"
            + (f", unit {self.unit})" if self.unit else ")")
        )
        tc = "not identified" if self.Tc is None else f"{format_number(self.Tc)} s"
        return format_table(headers, rows, title=title) + f"\nTc (flat region): {tc}"

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dict: coefficients (None when absent), Tc, settings, the AV and slopes."""
        return {
            "coefficients": {k: (None if c is None else c.to_dict())
                             for k, c in self.coefficients.items()},
            "Tc": self.Tc,
            "freq": float(self.freq),
            "unit": self.unit,
            "gm": self.gm,
            "method": self.method,
            "alpha": float(self.alpha),
            "slopes": [None if not np.isfinite(v) else float(v) for v in self.slopes],
            "avar": self.avar.to_dict(),
        }

def _slope_text(slope: int) -> str:
    half = {-2: "-1", -1: "-1/2", 0: "0", 1: "+1/2", 2: "+1"}[slope]
    return f"{slope:+d} (dev {half})" if slope else "0 (dev 0)"


def _datasheet_kind(unit: str | None) -> str | None:
    """The kind ("rate", "acceleration") of `unit` when it has datasheet units, else None."""
    if unit is None:
        return None
    try:
        kind = parse_unit(unit).kind
    except InputError:  # an unparsable unit only loses the datasheet column
        return None
    return kind if kind in DATASHEET_UNITS else None


def _to_datasheet(value: float, unit: str | None, name: str, ds_unit: str) -> float:
    template = TERMS[name][2]
    si_unit = template.replace("u", f"({unit})", 1)
    return float(convert(value, si_unit, ds_unit, kind=name))


# ----------------------------------------------------------------------------- identification


_NONE = 99  # label of a point matching no slope
_MAX_GAP = 0.5  # decades of a short excursion that does not split a region


def _runs(labels: np.ndarray) -> list[tuple[int, int, int]]:
    """Maximal runs (label, first index, last index) of equal, non-null labels."""
    runs = []
    start = 0
    for i in range(1, labels.size + 1):
        if i == labels.size or labels[i] != labels[start]:
            if labels[start] != _NONE:
                runs.append((int(labels[start]), start, i - 1))
            start = i
    return runs


def _merged_runs(
    labels: np.ndarray, slopes: np.ndarray, lt: np.ndarray, tol: float
) -> list[tuple[int, int, int]]:
    """Runs of one slope joined across gaps of at most 0.5 decade whose slopes stay within
    twice the tolerance (a noisy excursion, not another noise)."""
    merged: list[tuple[int, int, int]] = []
    for s, i0, i1 in _runs(labels):
        if merged:
            ps, p0, p1 = merged[-1]
            gap = slopes[p1 + 1 : i0]
            short = lt[i0 - 1] - lt[p1 + 1] <= _MAX_GAP + 1e-9
            if ps == s and short and np.all(np.abs(gap - s) <= 2 * tol):
                merged[-1] = (s, p0, i1)
                continue
        merged.append((s, i0, i1))
    return merged


def _auto_regions(
    lt: np.ndarray, slopes: np.ndarray, edf: np.ndarray, tol: float, min_points: int,
    min_span: float,
) -> dict[str, np.ndarray]:
    """The widest run of each slope (ties: more degrees of freedom), as index arrays."""
    labels = np.full(lt.size, _NONE)
    for s, _, _ in TERMS.values():
        labels[np.isfinite(slopes) & (np.abs(slopes - s) <= tol)] = s
    best: dict[str, tuple[tuple[float, float], np.ndarray]] = {}
    for s, i0, i1 in _merged_runs(labels, slopes, lt, tol):
        if i1 - i0 + 1 < min_points or lt[i1] - lt[i0] < min_span - 1e-9:
            continue
        name = _name_of_slope(s)
        rank = (round(lt[i1] - lt[i0], 6), float(np.sum(edf[i0 : i1 + 1])))
        if name not in best or rank > best[name][0]:
            best[name] = (rank, np.arange(i0, i1 + 1))
    return {k: v[1] for k, v in best.items()}


def _user_regions(regions: Mapping[str, Any], tau: np.ndarray) -> dict[str, np.ndarray | None]:
    out: dict[str, np.ndarray | None] = {}
    for name, rng in regions.items():
        if name not in TERMS:
            raise InputError(f"regions keys must be among {list(TERMS)}; got {name!r}")
        if rng is None:
            out[name] = None
            continue
        try:
            t0, t1 = (float(v) for v in rng)
        except (TypeError, ValueError):
            raise InputError(
                f"regions[{name!r}] must be a (tau_min, tau_max) pair in seconds or None; "
                f"got {rng!r}"
            ) from None
        if not (0 < t0 <= t1) or not math.isfinite(t1):
            raise InputError(f"regions[{name!r}] = {rng!r} is not a range 0 < tau_min <= tau_max")
        idx = np.flatnonzero((tau >= t0 * (1 - 1e-9)) & (tau <= t1 * (1 + 1e-9)))
        if idx.size == 0:
            raise InputError(
                f"regions[{name!r}] = ({t0:g}, {t1:g}) s holds no averaging time of the curve "
                f"(which spans {tau[0]:g} to {tau[-1]:g} s)"
            )
        out[name] = idx
    return out


# ----------------------------------------------------------------------------- fitting


def _others(lines: dict[str, float], name: str, t: np.ndarray) -> np.ndarray:
    """Sum of the lines other than `name` at the averaging times `t`.

    The flat line (B) is left out of the sums for N, K, Q and R: a bias instability floor
    has no known extent and a Gauss-Markov bump read as B vanishes on both sides of its
    range. B's own fit has all the other lines subtracted.
    """
    total = np.zeros_like(t)
    for other, c in lines.items():
        if other != name and (name == "B" or other != "B"):
            total = total + c * t ** TERMS[other][0]
    return total


def _fit_lines(
    tau: np.ndarray, av: np.ndarray, weights: dict[str, np.ndarray],
    regions: dict[str, np.ndarray], sweeps: int = 4,
) -> dict[str, tuple[float, float]]:
    """Back-fitted fixed-slope lines: name -> (ln C, variance of ln C).

    Each line is fitted on its region to the AV minus the other lines (points where the
    others explain more than 80 % are left out), by weighted least squares on ln AV with the
    weights ``edf / 2`` scaled by (residual / AV)^2; `sweeps` passes over the lines. The
    variance is that of the weighted mean of correlated values (:func:`_mean_variance`)
    plus, to first order, what the subtracted lines' own variances pass on.
    """
    lines: dict[str, float] = {}
    own: dict[str, tuple[float, float]] = {}
    leverage: dict[str, dict[str, float]] = {}  # d ln C_name / d ln C_other
    for _ in range(sweeps):
        for name, idx in regions.items():
            t, v = tau[idx], av[idx]
            resid = v - _others(lines, name, t)
            keep = resid > 0.2 * v
            if not np.any(keep):
                lines.pop(name, None)
                own.pop(name, None)
                continue
            w = weights[name][keep] * (resid[keep] / v[keep]) ** 2  # 1 / var(ln resid)
            z = np.log(resid[keep]) - TERMS[name][0] * np.log(t[keep])
            ln_c = float(np.sum(w * z) / np.sum(w))
            lines[name] = math.exp(ln_c)
            own[name] = (ln_c, _mean_variance(w, t[keep], _OCTAVE_CORR[name]))
            leverage[name] = {
                o: float(np.sum(w * _others({o: c}, name, t[keep]) / resid[keep]) / np.sum(w))
                for o, c in lines.items() if o != name
            }
    return {
        name: (ln_c, var + sum(g**2 * own[o][1] for o, g in leverage[name].items() if o in own))
        for name, (ln_c, var) in own.items()
    }


def _ln_av_covariance(w: np.ndarray, t: np.ndarray, corr: tuple[float, float]) -> np.ndarray:
    """Covariance of ln AV values of variances ``1 / w`` at averaging times `t`.

    Correlation ``floor + (1 - floor) r^|log2(t_i / t_j)|`` for ``corr = (r, floor)``: the
    correlation of overlapping AV estimates falls about geometrically with their distance in
    octaves, to a floor (a constant plus an exponential kernel: positive definite).
    """
    r, floor = corr
    octaves = np.log2(t)
    sd = 1.0 / np.sqrt(w)
    rho = floor + (1.0 - floor) * r ** np.abs(octaves[:, None] - octaves[None, :])
    return rho * np.outer(sd, sd)


def _mean_variance(w: np.ndarray, t: np.ndarray, r: tuple[float, float]) -> float:
    """Variance of the weighted mean ``sum w_i z_i / sum w`` of correlated ln AV values z_i."""
    return float(w @ _ln_av_covariance(w, t, r) @ w) / float(np.sum(w)) ** 2


def _share_bound(
    name: str, fits: dict[str, tuple[float, float]], tau: np.ndarray, av: np.ndarray,
    weights: np.ndarray, idx: np.ndarray, z: float,
) -> float:
    """Lower confidence bound of the share of the AV the line explains over its region.

    The share is the weighted mean over the region of ``1 - others / AV`` (the fraction the
    other lines leave); each value has relative standard deviation ``sqrt(2 / edf)`` and
    neighbouring values are correlated as in :func:`_mean_variance`.
    """
    lines = {k: math.exp(v[0]) for k, v in fits.items()}
    t, v = tau[idx], av[idx]
    frac = 1.0 - _others(lines, name, t) / v
    share = float(np.sum(weights * frac) / np.sum(weights))
    return share - z * math.sqrt(_mean_variance(weights, t, _OCTAVE_CORR[name]))


def _flat_needed(
    fits: dict[str, tuple[float, float]], tau: np.ndarray, av: np.ndarray, weights: np.ndarray,
    idx: np.ndarray, alpha: float,
) -> bool:
    """Is the flat line significantly better than a valley on B's range? (likelihood ratio)

    On the points of B's range, ln AV is fitted by generalised least squares (variances
    ``2 / edf``, correlations as in :func:`_mean_variance`) by the other
    lines plus either a free random-walk line ``c tau`` (the valley between a white-noise and
    a random-walk line, which is flat near its minimum) or a free flat level and a free
    random-walk line; B is kept when the drop of the weighted sum of squares exceeds the
    ``1 - alpha`` quantile of chi-square(1).
    """
    lines = {k: math.exp(v[0]) for k, v in fits.items() if k not in ("B", "K")}
    t, v = tau[idx], av[idx]
    base = _others(lines, "B", t)
    chol = np.linalg.cholesky(_ln_av_covariance(weights, t, _OCTAVE_CORR["B"]))
    ln_v = np.log(v)
    floor = 1e-12 * float(np.median(v))

    def resid(p: np.ndarray) -> np.ndarray:  # whitened residuals
        return solve_triangular(chol, ln_v - np.log(base + p[0] + p[1] * t), lower=True)

    level = float(np.median(v))
    start_k = max(float(np.median(v / t)), floor)
    valley = least_squares(lambda q: resid(np.array([floor, q[0]])), [start_k],
                           bounds=([floor], [np.inf]), x_scale=[start_k])
    flat = least_squares(resid, [level, floor * 10], bounds=([floor, floor], [np.inf, np.inf]),
                         x_scale=[level, start_k])
    drop = 2.0 * (valley.cost - flat.cost)  # least_squares' cost is half the sum of squares
    return drop >= float(chdtri(1, alpha))


def _accept(
    av: AllanVariance, weights: dict[str, np.ndarray], chosen: dict[str, np.ndarray],
    user: set[str], share: float, alpha: float,
) -> dict[str, tuple[float, float]]:
    """Fit the lines; drop automatic terms that are not significant, weakest first; refit.

    A term goes when the lower one-sided ``1 - alpha`` bound of its share is below `share`,
    when nothing is left of its region once the other lines are subtracted, or (B) when a
    valley fits its range as well as a flat line does. `chosen` loses the dropped names.
    """
    z_one = float(ndtri(1.0 - alpha))
    fits = _fit_lines(av.tau, av.avar, weights, chosen)
    while True:
        bounds = {
            name: _share_bound(name, fits, av.tau, av.avar, weights[name], chosen[name], z_one)
            for name in fits if name not in user
        }
        weak = [(b, name) for name, b in bounds.items() if b < share]
        if "B" in bounds and bounds["B"] >= share and not _flat_needed(
            fits, av.tau, av.avar, weights["B"], chosen["B"], alpha
        ):
            weak.append((-1.0, "B"))  # a valley, not a floor
        weak += [(-math.inf, name) for name in chosen if name not in fits]  # nothing to fit
        if not weak:
            return fits
        chosen.pop(min(weak)[1])  # the weakest first: the others' fits change without it
        fits = _fit_lines(av.tau, av.avar, weights, chosen)


def _point_reading(
    name: str, idx: np.ndarray, av: AllanVariance
) -> tuple[float, float, float]:
    """IEEE single-point read-off: (C, C_low, C_high) of the line through one AV point."""
    s = TERMS[name][0]
    t = av.tau[idx]
    if name == "B":
        p = idx[int(np.argmin(av.avar[idx]))]
    else:
        p = idx[int(np.argmin(np.abs(np.log(t / _READ_TAU[name]))))]
    scale = av.tau[p] ** (-s)
    return av.avar[p] * scale, av.ci_low[p] * scale, av.ci_high[p] * scale


def _check_names(value: Sequence[str], what: str) -> tuple[str, ...]:
    if isinstance(value, str):
        value = (value,)
    names = tuple(value)
    bad = [v for v in names if v not in TERMS]
    if bad:
        raise InputError(f"{what} must name coefficients among {list(TERMS)}; got {bad[0]!r}")
    return names


def _positive_float(value: float, name: str) -> float:
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a positive number, got {value!r}") from None
    if not math.isfinite(out) or out <= 0:
        raise InputError(f"{name} must be a positive number, got {value!r}")
    return out


def allan_reading(
    x: ArrayLike,
    freq: float,
    regions: Mapping[str, tuple[float, float] | None] | None = None,
    *,
    kind: str = "overlapping",
    points_per_decade: int = 10,
    slope_tol: float = 0.25,
    slope_window: float = 0.2,
    min_points: int = 3,
    min_span: float = 0.2,
    min_share: float = 0.3,
    method: str = "fit",
    require: Sequence[str] = (),
    terms: Sequence[str] = ("Q", "N", "B", "K", "R"),
    alpha: float = 0.05,
    gm: str = "quinchia",
    unit: str | None = None,
) -> AllanReading:
    """Read the noise coefficients Q, N, B, K, R (and Tc) off the Allan variance by its slopes.

    Parameters
    ----------
    x : array_like, shape (N,)
        Static rate signal (unit u: rad/s, m/s^2 ...), finite, not constant.
    freq : float
        Sampling frequency, Hz.
    regions : dict, optional
        Tau ranges (s) per coefficient, ``{"N": (0.01, 1.0), "K": (100, 1000)}``; they override
        the automatic identification for those names (every AV point inside is used, no slope
        check, no share test); ``None`` for a name suppresses it.
    kind : {"overlapping", "non-overlapping"}
        Allan variance estimator.
    points_per_decade : int
        Density of the log tau grid (default 10).
    slope_tol : float
        A point belongs to a slope's region when its local slope is within `slope_tol` of it
        and the local slope's standard error is at most `slope_tol` (default 0.25).
    slope_window : float
        Half-width, in decades, of the window of the local slopes (default 0.2).
    min_points, min_span : int, float
        Smallest automatic region: points, and width in decades (defaults 3 and 0.2).
    min_share : float
        Smallest share of the summed lines a term must explain at its region's centre
        (default 0.3); weaker terms are dropped as not identified.
    method : {"fit", "ieee"}
        "fit" (default): fixed-slope weighted least squares in log space over each region,
        weights ``edf / 2`` (the inverse variance of ln AV), after subtracting the other lines.
        "ieee": single-point read-offs (N at 1 s, K at 3 s, Q at sqrt 3 s, R at sqrt 2 s on
        the line through the region's nearest point; B = sqrt(min AV of the region) / 0.664).
    require : sequence of str
        Coefficients that must be identified (EstimationError otherwise).
    terms : sequence of str
        Coefficients to look for (default all five).
    alpha : float
        Significance level of the intervals (0.05: 95 %).
    gm : {"quinchia", "matched"}
        How :func:`stochmod.classical.allan_model` builds a model from B and Tc.
    unit : str, optional
        Unit of the signal ("rad/s", "deg/s", "m/s^2", "g" ...): labels the SI units and adds
        datasheet values (deg/sqrt(h), deg/h ... or m/s/sqrt(h), ug ...) to the summary.

    Returns
    -------
    AllanReading
        Coefficients (None where not identified) with intervals, Tc, the AV and its slopes.

    Raises
    ------
    InputError
        Bad signal (too short, NaN/inf, constant), bad options or regions.
    EstimationError
        A coefficient named in `require` was not identified.

    Notes
    -----
    Interval of a fitted line: ``ln C -+ z sd``, mapped to the coefficient, where ``sd^2`` is
    the variance of the weighted mean of the region's ln AV values, each of variance
    ``2 / edf``, correlated as ``r^(octaves apart)`` with r = 0.55 (N), 0.7 (B), 0.88 (K),
    0.55 (R: a ramp is deterministic, the white noise around it makes the error) and
    ``0.3 + 0.7 * 0.5^(octaves apart)`` (Q) (simulated correlations of overlapping AV
    estimates).
    It covers the sampling error, not the bias from noises the lines do not describe (a
    Gauss-Markov bump read as B, a flat floor under the N region).
    """
    y = as_signal(x, name="x", min_length=8)
    freq = check_freq(freq)
    if np.ptp(y) == 0:
        raise InputError("x is constant: its Allan variance is zero at every tau")
    if kind not in ("overlapping", "non-overlapping"):
        raise InputError(
            f"kind must be 'overlapping' or 'non-overlapping' for the slope reading; got {kind!r}"
        )
    if method not in ("fit", "ieee"):
        raise InputError(f"method must be 'fit' or 'ieee'; got {method!r}")
    if gm not in GM_CONVENTIONS:
        raise InputError(f"gm must be one of {GM_CONVENTIONS}; got {gm!r}")
    ppd = check_positive_int(points_per_decade, name="points_per_decade", minimum=2)
    min_points = check_positive_int(min_points, name="min_points", minimum=2)
    tol = _positive_float(slope_tol, "slope_tol")
    window = _positive_float(slope_window, "slope_window")
    span = _positive_float(min_span, "min_span") if min_span else 0.0
    share = float(min_share)
    if not 0.0 <= share < 1.0:
        raise InputError(f"min_share must be in [0, 1); got {min_share!r}")
    required = _check_names(require, "require")
    wanted = _check_names(terms, "terms")
    if unit is not None and not isinstance(unit, str):
        raise InputError(f"unit must be a string such as 'rad/s'; got {unit!r}")

    av = avar(y, freq, taus="decade", kind=kind, alpha=alpha, points_per_decade=ppd)
    lt = np.log10(av.tau)
    slopes = local_slopes(av.tau, av.avar, half_width=window, edf=av.edf, target_se=tol)
    auto = _auto_regions(lt, slopes, av.edf, tol, min_points, span)
    user = _user_regions(regions or {}, av.tau)
    chosen = {k: v for k, v in auto.items() if k in wanted and k not in user}
    chosen.update({k: v for k, v in user.items() if v is not None})

    weights = {
        name: np.asarray(greenhall_edf(_NOISE[name], 2, av.m[idx], y.size + 1,
                                       overlapping=kind == "overlapping"), dtype=float) / 2.0
        for name, idx in chosen.items()
    }

    fits = _accept(av, weights, chosen, set(user), share, alpha)
    z = float(ndtri(1.0 - alpha / 2.0))
    coefs: dict[str, Coefficient | None] = dict.fromkeys(TERMS)
    for name, (ln_c, var_c) in fits.items():
        idx = chosen[name]
        if method == "ieee":
            c, c_lo, c_hi = _point_reading(name, idx, av)
        else:
            half = z * math.sqrt(var_c)
            c, c_lo, c_hi = math.exp(ln_c), math.exp(ln_c - half), math.exp(ln_c + half)
        f = _FACTOR[name]
        hint = TERMS[name][2] if unit is None else TERMS[name][2].replace("u", f"({unit})", 1)
        coefs[name] = Coefficient(
            value=math.sqrt(f * c), low=math.sqrt(f * c_lo), high=math.sqrt(f * c_hi),
            tau_range=(float(av.tau[idx[0]]), float(av.tau[idx[-1]])), slope=TERMS[name][0],
            unit_hint=hint, n_points=int(idx.size), region="user" if name in user else "auto",
        )
    tc_value = None
    if coefs["B"] is not None:
        idx = chosen["B"]
        tc_value = float(av.tau[idx[int(np.argmin(av.avar[idx]))]])
    missing = [k for k in required if coefs[k] is None]
    if missing:
        name = missing[0]
        raise EstimationError(
            f"{name} ({TERMS[name][1]}, Allan variance slope {TERMS[name][0]:+d}) was not "
            "identified: no region of the curve has that slope; pass regions={"
            f"{name!r}: (tau_min, tau_max)}} to read it on a range of your choice"
        )
    return AllanReading(
        Q=coefs["Q"], N=coefs["N"], B=coefs["B"], K=coefs["K"], R=coefs["R"], Tc=tc_value,
        avar=av, slopes=slopes, freq=freq, unit=unit, gm=gm, method=method, alpha=float(alpha),
    )
