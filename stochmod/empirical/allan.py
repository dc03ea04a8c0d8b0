"""Allan variance family of a rate signal: overlapping, non-overlapping, Hadamard, modified.

The signal ``y`` is a rate (angular rate in rad/s, specific force in m/s^2: allantools'
``data_type="freq"``) sampled at ``freq`` Hz, ``tau0 = 1 / freq``. With the phase
``x_k = tau0 * sum_{i<k} (y_i - mean y)`` (``k = 0..N``, N + 1 points) and the averaging
factor m (``tau = m tau0``), every variance here is a mean of squared d-th differences of the
phase at lag m (NIST SP 1065 eqs. 7, 11, 14, 18, 20; Riley & Howe 2008 for the modified
Hadamard variance):

=====================  ===  =======  ========  ===================================  ==========
kind                   d    stride   modified  n_terms (P = N + 1 phase points)     allantools
=====================  ===  =======  ========  ===================================  ==========
overlapping            2    1        no        P - 2m                               oadev
non-overlapping        2    m        no        floor(N / m) - 1                     adev
hadamard               3    1        no        P - 3m                               ohdev
non-overlapping-had.   3    m        no        floor(N / m) - 2                     hdev
modified               2    1        yes       P - 3m + 1                           mdev
modified-hadamard      3    1        yes       P - 4m + 1                           --
=====================  ===  =======  ========  ===================================  ==========

``var(m) = sum_i (Delta^d_m x_i)^2 / (c_d m^2 tau0^2 n_terms)`` with ``c_2 = 2``, ``c_3 = 6``;
the modified kinds first sum m consecutive differences and divide by a further ``m^2``.

Computation: the d-th phase difference equals ``tau0`` times the (d - 1)-th difference of the
moving sums ``S_m[i] = sum_{k=i}^{i+m-1} y_k``. When every m is a power of two and the kind is
overlapping and unmodified, the moving sums are built level by level in place,
``S_2m[i] = S_m[i] + S_m[i+m]``, in cache-sized chunks (no cumulative sum, no temporaries):
O(N) per tau and 3-4x faster than allantools.oadev (``bench/bench_allan.py``). Other grids
and kinds take ``S_m`` from one cumulative sum (O(N) per tau: for the overlapping Allan and
Hadamard variances one compiled loop per tau, :mod:`stochmod.empirical.allan_jit`).

Confidence intervals come from equivalent degrees of freedom (EDF) and the chi-square law
(NIST SP 1065 eq. 45): ``[edf var / chi2_{1-a/2}(edf), edf var / chi2_{a/2}(edf)]``. The
EDF depends on the power-law noise type ``alpha`` (PSD of the rate ~ f^alpha: 2 quantization /
white phase, 0 white rate noise (ARW), -1 flicker (bias instability), -2 rate random walk,
-3/-4 for Hadamard only). For white rate noise (alpha = 0) it is, at every m and for every
kind, the exact EDF ``2 (E var)^2 / Var var`` of the variance of i.i.d. rate samples
(:func:`white_rate_edf`); for the other noises it is Greenhall & Riley's (2004) algorithm
(:func:`greenhall_edf`). Greenhall's EDF for alpha = 0 models a phase averaged over ``tau0``
(Stable32, allantools): 782 against the exact 666 at m = 1 for N = 1000, and intervals on
i.i.d. rate samples that cover 92.8 % instead of 95 % there; ``white_edf="greenhall"``
reproduces it. The two agree to 0.25 % once Greenhall's algorithm takes F = inf
(``m (d + 1) > 100``).
"""

from __future__ import annotations

import functools
import itertools
import math
import numbers
from typing import Any

import attrs
import numpy as np
from numpy.typing import ArrayLike
from scipy.special import chdtri, ndtri

from stochmod.core.checks import as_signal, check_alpha, check_freq, check_positive_int
from stochmod.core.errors import InputError
from stochmod.core.fields import array_field
from stochmod.core.tables import format_number, format_table
from stochmod.empirical import allan_jit

__all__ = [
    "CI_METHODS",
    "KINDS",
    "NOISE_NAMES",
    "TAU_GRIDS",
    "WHITE_EDFS",
    "AllanVariance",
    "avar",
    "greenhall_edf",
    "local_slopes",
    "percent_error",
    "tau_grid",
    "white_rate_edf",
]

#: kind -> (d: order of the phase difference, overlapping, modified)
KINDS: dict[str, tuple[int, bool, bool]] = {
    "overlapping": (2, True, False),
    "non-overlapping": (2, False, False),
    "hadamard": (3, True, False),
    "non-overlapping-hadamard": (3, False, False),
    "modified": (2, True, True),
    "modified-hadamard": (3, True, True),
}
#: Names of the automatic averaging-time grids.
TAU_GRIDS = ("octave", "decade", "log", "all")
#: Interval methods: Greenhall EDF + chi-square, Quinchia eq. 15 normal, none.
CI_METHODS = ("edf", "simple", "none")
#: EDF of white rate noise (alpha = 0): exact for i.i.d. rate samples, or Greenhall's.
WHITE_EDFS = ("exact", "greenhall")
#: Noise names accepted for ``noise`` (value: the power-law exponent alpha of the rate PSD).
NOISE_NAMES: dict[str, int] = {"QN": 2, "WN": 0, "BI": -1, "RW": -2, "RR": -3}

_CHUNK = 1 << 17  # samples per block of the in-place pyramid (the block stays in cache)
_AUTO_WINDOW = 0.3  # decades each side for the automatic noise identification
_AUTO_MAX_SE = 0.25  # largest standard error of a slope used to identify the noise
_JMAX = 100  # Greenhall & Riley's bound on the number of terms of the basic sum


@attrs.frozen
class AllanVariance:
    """One member of the Allan variance family of a rate signal, with intervals.

    Attributes
    ----------
    tau : ndarray, shape (T,)
        Averaging times ``m / freq``, s.
    m : ndarray of int, shape (T,)
        Averaging factors (samples per cluster).
    avar : ndarray, shape (T,)
        The variance (Allan, Hadamard or modified, see `kind`), in unit^2 (unit of the signal).
    ci_low, ci_high : ndarray, shape (T,)
        Bounds of the ``100 (1 - alpha)`` % interval on the variance, unit^2 (NaN for ci="none").
    n_terms : ndarray of int, shape (T,)
        Number of squared differences averaged at each tau.
    edf : ndarray, shape (T,)
        Equivalent degrees of freedom for the noise type `noise`: exact for i.i.d. white rate
        noise (:func:`white_rate_edf`), Greenhall & Riley (2004) otherwise.
    noise : ndarray of int, shape (T,)
        Power-law exponent alpha (rate PSD ~ f^alpha) assumed for the EDF at each tau.
    kind : str
        One of :data:`KINDS`.
    freq : float
        Sampling frequency, Hz.
    n : int
        Number of samples N of the signal.
    ci : str
        Interval method (:data:`CI_METHODS`).
    alpha : float
        Significance level of the intervals.
    """

    tau: np.ndarray = array_field()
    m: np.ndarray = array_field()
    avar: np.ndarray = array_field()
    ci_low: np.ndarray = array_field()
    ci_high: np.ndarray = array_field()
    n_terms: np.ndarray = array_field()
    edf: np.ndarray = array_field()
    noise: np.ndarray = array_field()
    kind: str
    freq: float
    n: int
    ci: str
    alpha: float

    @property
    def adev(self) -> np.ndarray:
        """Deviation ``sqrt(avar)``, in the signal's unit."""
        return np.sqrt(self.avar)

    @property
    def percent_error(self) -> np.ndarray:
        """Quinchia et al. (2013) eq. 15: ``100 / sqrt(2 (N/m - 1))``, percent of the deviation."""
        return percent_error(self.n, self.m)

    def summary(self) -> str:
        """Table of tau [s], m, deviation, variance, interval on the variance, EDF, n_terms."""
        level = format_number(100 * (1 - self.alpha))
        title = (
            f"Allan variance ({self.kind}, N = {self.n}, freq = {format_number(self.freq)} Hz, "
            f"{level}% CI: {self.ci})"
        )
        rows = [
            (t, int(m), d, v, lo, hi, e, int(k))
            for t, m, d, v, lo, hi, e, k in zip(
                self.tau, self.m, self.adev, self.avar, self.ci_low, self.ci_high,
                self.edf, self.n_terms,
            )
        ]
        headers = ["tau [s]", "m", "dev", "var", "CI low", "CI high", "edf", "n_terms"]
        return format_table(headers, rows, title=title)

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dict of every field (arrays as lists), plus ``adev``."""
        return {
            "tau": self.tau.tolist(),
            "m": [int(v) for v in self.m],
            "avar": self.avar.tolist(),
            "adev": self.adev.tolist(),
            "ci_low": self.ci_low.tolist(),
            "ci_high": self.ci_high.tolist(),
            "n_terms": [int(v) for v in self.n_terms],
            "edf": self.edf.tolist(),
            "noise": [int(v) for v in self.noise],
            "kind": self.kind,
            "freq": float(self.freq),
            "n": int(self.n),
            "ci": self.ci,
            "alpha": float(self.alpha),
        }


# ----------------------------------------------------------------------------- tau grids


def _check_kind(kind: str) -> tuple[int, bool, bool]:
    if kind not in KINDS:
        raise InputError(f"kind must be one of {', '.join(map(repr, KINDS))}; got {kind!r}")
    return KINDS[kind]


def _n_terms(n: int, m: np.ndarray, kind: str) -> np.ndarray:
    """Number of squared differences of `kind` at averaging factors `m` (N samples)."""
    d, overlapping, modified = KINDS[kind]
    m = np.asarray(m, dtype=np.int64)
    if modified:
        return n + 1 - (d + 1) * m + 1
    if overlapping:
        return n + 1 - d * m
    return n // m - d + 1


def _max_m(n: int, kind: str) -> int:
    """Largest averaging factor with at least two terms (allantools keeps n_terms > 1)."""
    d, overlapping, modified = KINDS[kind]
    if modified or not overlapping:
        return n // (d + 1)
    return (n - 1) // d


def _log_subsample(m: np.ndarray, count: int) -> np.ndarray:
    """At most `count` values of the sorted integer array `m`, log-uniformly spread."""
    if m.size <= count:
        return m
    targets = np.geomspace(m[0], m[-1], count)
    idx = np.unique(np.clip(np.searchsorted(m, targets), 0, m.size - 1))
    return m[idx]


def tau_grid(
    n: int,
    freq: float,
    taus: str | ArrayLike = "octave",
    kind: str = "overlapping",
    *,
    points_per_decade: int = 10,
    tau_reduction: int | None = None,
) -> np.ndarray:
    """Averaging factors m for a signal of `n` samples.

    Parameters
    ----------
    n : int
        Number of samples.
    freq : float
        Sampling frequency, Hz.
    taus : {"octave", "decade", "log", "all"} or array_like
        "octave": m = 1, 2, 4, ...; "decade"/"log": ``round(10^(k / points_per_decade))``,
        deduplicated; "all": every m (quadratic cost: pass `tau_reduction`); or explicit
        averaging times in seconds, each a multiple of ``1 / freq``.
    kind : str
        Variance kind (sets the largest valid m: at least two terms).
    points_per_decade : int
        Density of the "decade"/"log" grid.
    tau_reduction : int, optional
        Keep at most this many m, spread log-uniformly (for any grid).

    Returns
    -------
    ndarray of int64
        Sorted unique averaging factors.

    Raises
    ------
    InputError
        Unknown grid name; explicit taus not positive, not multiples of ``1/freq`` or too
        long for the signal; bad `points_per_decade` or `tau_reduction`.
    """
    _check_kind(kind)
    m_max = _max_m(n, kind)
    if m_max < 1:
        raise InputError(f"x has {n} samples: too short for any tau of kind {kind!r}")
    if isinstance(taus, str):
        if taus == "octave":
            m = 2 ** np.arange(int(math.floor(math.log2(m_max))) + 1, dtype=np.int64)
        elif taus in ("decade", "log"):
            ppd = check_positive_int(points_per_decade, name="points_per_decade")
            k = np.arange(int(math.floor(ppd * math.log10(m_max) + 1e-9)) + 1)
            m = np.unique(np.round(10.0 ** (k / ppd)).astype(np.int64))
        elif taus == "all":
            m = np.arange(1, m_max + 1, dtype=np.int64)
        else:
            raise InputError(
                f"taus must be one of {', '.join(map(repr, TAU_GRIDS))} or an array of seconds; "
                f"got {taus!r}"
            )
        m = m[m <= m_max]
    else:
        m = _explicit_m(taus, freq, m_max, kind)
    if tau_reduction is not None:
        m = _log_subsample(m, check_positive_int(tau_reduction, name="tau_reduction", minimum=2))
    return m


def _explicit_m(taus: ArrayLike, freq: float, m_max: int, kind: str) -> np.ndarray:
    t = as_signal(np.atleast_1d(np.asarray(taus)), name="taus", min_length=1)
    if np.any(t <= 0):
        raise InputError(f"taus must be positive seconds; got {t[t <= 0][0]!r}")
    m_float = t * freq
    m = np.round(m_float)
    bad = np.abs(m_float - m) > 1e-6 * np.maximum(m, 1.0)
    if np.any(bad):
        raise InputError(
            f"taus must be multiples of the sample period 1/freq = {1.0 / freq:g} s; "
            f"{t[bad][0]:g} s is {m_float[bad][0]:g} periods"
        )
    if np.any(m < 1) or np.any(m > m_max):
        worst = t[(m < 1) | (m > m_max)][0]
        raise InputError(
            f"tau = {worst:g} s is outside the valid range [{1.0 / freq:g}, {m_max / freq:g}] s "
            f"for kind {kind!r} on this signal (at least two terms are needed)"
        )
    return np.unique(m.astype(np.int64))


# ----------------------------------------------------------------------------- variances


def _sumsq(t: np.ndarray) -> float:
    """Sum of squares by numpy's own SIMD loop (BLAS dot threads stall on a busy machine)."""
    return float(np.einsum("i,i->", t, t))


def _pyramid_sums(y: np.ndarray, m_wanted: np.ndarray, d: int) -> dict[int, float]:
    """Sum of squared (d-1)-th lag-m differences of S_m, for powers of two m (in place)."""
    n = y.size
    wanted = {int(v) for v in m_wanted}
    top = max(wanted)
    out: dict[int, float] = {}
    scratch = np.empty(_CHUNK)
    scratch2 = np.empty(_CHUNK)
    s = y  # S_1 = y, read only; S_2 onwards live in their own buffer
    m = 1
    while True:
        n_s = n - m + 1  # length of S_m
        n_t = n_s - (d - 1) * m  # number of differences
        n_next = n_s - m  # length of S_2m
        if m == 1 and m < top:
            buf = np.empty(n_next)
        total = 0.0
        for a in range(0, max(n_t, n_next if m < top else 0), _CHUNK):
            e = min(a + _CHUNK, max(n_t, n_next))
            f = np.subtract(s[a + m : e + m], s[a:e], out=scratch[: e - a])  # S[i+m] - S[i]
            b = min(e, n_t)
            if b > a:
                t = f[: b - a]
                if d == 3:  # (S[i+2m] - S[i+m]) - (S[i+m] - S[i])
                    u = np.subtract(s[a + 2 * m : b + 2 * m], s[a + m : b + m],
                                    out=scratch2[: b - a])
                    t = np.subtract(u, t, out=u)
                total += _sumsq(t)
            if m < top:  # S_2m[i] = S[i] + S[i+m] = 2 S[i] + f[i], in place without a copy
                e = min(e, n_next)
                if s is y:
                    np.add(y[a:e], y[a + m : e + m], out=buf[a:e])
                else:
                    np.add(buf[a:e], buf[a:e], out=buf[a:e])
                    np.add(buf[a:e], f[: e - a], out=buf[a:e])
        if m in wanted:
            out[m] = total
        if m >= top:
            return out
        s = buf
        m *= 2


def _phase_sums(y: np.ndarray, m_all: np.ndarray, d: int, overlapping: bool, modified: bool
                ) -> dict[int, float]:
    """Sum of squared terms for arbitrary m from one cumulative sum (O(N) per m)."""
    n = y.size
    c = np.empty(n + 1)
    c[0] = 0.0
    # c = phase / tau0, accumulated in place: no second array of the signal's size
    np.cumsum(np.subtract(y, y.mean(), out=c[1:]), out=c[1:])
    out: dict[int, float] = {}
    for m in (int(v) for v in m_all):
        if not overlapping:
            blocks = np.diff(c[::m])  # non-overlapping cluster sums S_m[k m]
            t = np.diff(blocks, n=d - 1)
        elif not modified:
            out[m] = allan_jit.difference_sumsq(c, m, d)
            continue
        else:
            s = c[m:] - c[:-m]  # S_m
            n_t = s.size - (d - 1) * m
            t = s[m : m + n_t] - s[:n_t]
            if d == 3:  # second difference: (S[i+2m] - S[i+m]) - (S[i+m] - S[i])
                t = np.subtract(s[2 * m : 2 * m + n_t] - s[m : m + n_t], t, out=t)
            ct = np.empty(n_t + 1)
            ct[0] = 0.0
            np.cumsum(t, out=ct[1:])
            t = ct[m:] - ct[:-m]  # sums of m consecutive differences
        out[m] = _sumsq(t)
    return out


def _is_power_of_two(m: np.ndarray) -> bool:
    return bool(np.all((m > 0) & ((m & (m - 1)) == 0)))


def _variances(y: np.ndarray, m: np.ndarray, kind: str) -> tuple[np.ndarray, np.ndarray]:
    d, overlapping, modified = KINDS[kind]
    if overlapping and not modified and _is_power_of_two(m):
        sums = _pyramid_sums(y, m, d)
    else:
        sums = _phase_sums(y, m, d, overlapping, modified)
    n_terms = _n_terms(y.size, m, kind)
    norm = math.comb(2 * (d - 1), d - 1) * m.astype(float) ** (4 if modified else 2)
    total = np.array([sums[int(v)] for v in m])
    return total / (norm * n_terms), n_terms


# ----------------------------------------------------------------------------- EDF


def _sw(t: np.ndarray, alpha: int) -> np.ndarray:
    """Greenhall & Riley (2004) eq. 7."""
    a = np.abs(t)
    if alpha % 2 == 0:
        return -a if alpha == 2 else a ** (3 - alpha)
    with np.errstate(divide="ignore", invalid="ignore"):
        val = t ** (3 - alpha) * np.log(a)
    return np.where(a == 0, 0.0, val)


def _sx(t: np.ndarray, f: float, alpha: int) -> np.ndarray:
    """Eq. 8; F = inf is the limit sw(t, alpha + 2); alpha = 2 in exact closed form."""
    if math.isinf(f):
        return _sw(t, alpha + 2)
    if alpha == 2:  # F^2 (|t - 1/F| + |t + 1/F| - 2|t|), exactly
        return 2.0 * f * np.maximum(0.0, 1.0 - f * np.abs(t))
    return f * f * (2.0 * _sw(t, alpha) - _sw(t - 1.0 / f, alpha) - _sw(t + 1.0 / f, alpha))


def _sz(t: np.ndarray, f: float, alpha: int, d: int) -> np.ndarray:
    """Eq. 9: the 2d-th central difference of sx."""
    t = np.asarray(t, dtype=float)
    total = math.comb(2 * d, d) * _sx(t, f, alpha)
    for k in range(1, d + 1):
        c = (-1) ** k * math.comb(2 * d, d + k)
        total = total + c * (_sx(t - k, f, alpha) + _sx(t + k, f, alpha))
    return total


def _basic_sum(j: int, mm: float, s: float, f: float, alpha: int, d: int) -> float:
    """Eq. 10."""
    first = float(_sz(np.array(0.0), f, alpha, d)) ** 2
    second = (1.0 - j / mm) * float(_sz(np.array(j / s), f, alpha, d)) ** 2
    k = np.arange(1, int(j), dtype=float)
    third = float(np.sum(2.0 * (1.0 - k / mm) * _sz(k / s, f, alpha, d) ** 2))
    return first + second + third


# Greenhall & Riley (2004) Tables 1-3: rows alpha = 2, 1, ..., -4; columns d = 1, 2, 3.
_TABLE1 = [
    [(2 / 3, 1 / 3), (7 / 9, 1 / 2), (22 / 25, 2 / 3)],
    [(0.840, 0.345), (0.997, 0.616), (1.141, 0.843)],
    [(1.079, 0.368), (1.033, 0.607), (1.184, 0.848)],
    [(None, None), (1.048, 0.534), (1.180, 0.816)],
    [(None, None), (1.302, 0.535), (1.175, 0.777)],
    [(None, None), (None, None), (1.194, 0.703)],
    [(None, None), (None, None), (1.489, 0.702)],
]
_TABLE2 = [
    [(3 / 2, 1 / 2), (35 / 18, 1.0), (231 / 100, 3 / 2)],
    [(78.6, 25.2), (790.0, 410.0), (9950.0, 6520.0)],
    [(2 / 3, 1 / 6), (2 / 3, 1 / 3), (7 / 9, 1 / 2)],
    [(None, None), (0.852, 0.375), (0.997, 0.617)],
    [(None, None), (1.079, 0.368), (1.033, 0.607)],
    [(None, None), (None, None), (1.053, 0.553)],
    [(None, None), (None, None), (1.302, 0.535)],
]
_TABLE3 = [(6.0, 4.0), (15.23, 12.0), (47.8, 40.0)]  # alpha = 1: (b0, b1) by d


@functools.lru_cache(maxsize=4096)  # a fleet's axes share N and the grid: the same EDFs again
def _edf_one(alpha: int, d: int, m: int, n_phase: int, overlapping: bool, modified: bool) -> float:
    f = 1.0 if modified else float(m)
    s = float(m) if overlapping else 1.0
    mm = 1.0 + math.floor(s * (n_phase - (m / f + m * d)) / m)
    j = min(mm, (d + 1) * s)
    r = mm / s
    row, col = 2 - alpha, d - 1

    def summed(jj: float, m_: float, s_: float, f_: float, scale: float | None = None) -> float:
        """EDF from the basic sum (eq. 13), numerator sz(0)^2 unless `scale` is given."""
        top = float(_sz(np.array(0.0), f_, alpha, d)) ** 2 if scale is None else scale
        return m_ * top / _basic_sum(jj, m_, s_, f_, alpha, d)

    if modified:  # case 1
        if j <= _JMAX:
            return summed(j, mm, s, 1.0)
        if r > d + 1:
            a0, a1 = _TABLE1[row][col]
            return r / (a0 - a1 / r)
        return summed(_JMAX, _JMAX, _JMAX / r, 1.0)
    if alpha <= 0:  # case 2
        if j <= _JMAX:
            return summed(j, mm, s, float(m) if m * (d + 1) <= _JMAX else math.inf)
        if r > d + 1:
            a0, a1 = _TABLE2[row][col]
            return r / (a0 - a1 / r)
        return summed(_JMAX, _JMAX, _JMAX / r, math.inf)
    if alpha == 1:  # case 3
        b0, b1 = _TABLE3[col]
        if j <= _JMAX:
            return summed(j, mm, s, float(m))
        if r > d + 1:
            a0, a1 = _TABLE2[row][col]
            return (b0 + b1 * math.log(m)) ** 2 * r / (a0 - a1 / r)
        return summed(_JMAX, _JMAX, _JMAX / r, _JMAX / r, scale=(b0 + b1 * math.log(m)) ** 2)
    # case 4, alpha = 2 unmodified
    if math.ceil(r) > d:
        a0 = math.comb(4 * d, 2 * d) / math.comb(2 * d, d) ** 2
        return mm / (a0 - (d / 2.0) / r)
    # K <= d: the exact sum (eq. 13), sx in closed form for alpha = 2
    return summed(j, mm, s, float(m))


def greenhall_edf(
    alpha: int, d: int, m: ArrayLike, n_phase: int, *, overlapping: bool = True,
    modified: bool = False,
) -> float | np.ndarray:
    """Equivalent degrees of freedom of a variance based on finite differences.

    Greenhall & Riley (2004), "Uncertainty of stability variances based on finite
    differences" (35th PTTI), with their ``J_max = 100`` approximations (Tables 1-3); the one
    case they leave open (alpha = 2, unmodified, ``ceil(M/S) <= d``) is summed exactly. For
    alpha = 0 it models a phase averaged over ``tau0``; i.i.d. rate samples: `white_rate_edf`.

    Parameters
    ----------
    alpha : int
        Noise exponent of the rate PSD ``S_y(f) ~ f^alpha``, ``alpha + 2 d > 1``.
    d : {1, 2, 3}
        Order of the phase difference (1 first difference, 2 Allan, 3 Hadamard).
    m : int or array_like of int
        Averaging factors.
    n_phase : int
        Number of phase points (N + 1 for N rate samples).
    overlapping : bool
        Stride 1 (True) or m (False).
    modified : bool
        Modified variance (mvar, modified Hadamard).

    Returns
    -------
    float or ndarray
        EDF at each m (a float for a scalar `m`, else an array of the shape of `m`).
    """
    alpha, d = int(alpha), int(d)
    if d not in (1, 2, 3):
        raise InputError(f"d must be 1, 2 or 3; got {d}")
    if not -4 <= alpha <= 2 or alpha + 2 * d <= 1:
        raise InputError(f"noise exponent alpha = {alpha} is outside [-4, 2] or alpha + 2 d <= 1")
    ms = np.atleast_1d(np.asarray(m, dtype=np.int64))
    out = np.array(
        [_edf_one(alpha, d, int(v), int(n_phase), overlapping, modified) for v in ms.ravel()]
    )
    return out.reshape(np.shape(m)) if np.ndim(m) else out[0]


def _box_count(x: int, m: int, r: int) -> int:
    """Ways to write x as a sum of r integers in [0, m - 1] (the r-fold convolution of a box):
    ``sum_{j m <= x} (-1)^j C(r, j) C(x - j m + r - 1, r - 1)``, 0 for x < 0 (exact)."""
    total = 0
    for j in range(r + 1):
        u = x - j * m
        if u < 0:
            break
        total += (-1) ** j * math.comb(r, j) * math.comb(u + r - 1, r - 1)
    return total


@functools.lru_cache(maxsize=4096)
def _white_rate_one(d: int, m: int, n: int, overlapping: bool, modified: bool) -> float:
    if modified:
        length, terms, stride = (d + 1) * m - 1, n - (d + 1) * m + 2, 1
    elif overlapping:
        length, terms, stride = d * m, n - d * m + 1, 1
    else:
        length, terms, stride = d * m, n // m - d + 1, m
    if terms < 1:
        raise InputError(f"{n} samples give no term at m = {m} (d = {d})")
    r = 4 if modified else 2
    shift = (r // 2) * (m - 1)
    coef = [((-1) ** abs(j) * math.comb(2 * d - 2, d - 1 + j), j * m + shift)
            for j in range(1 - d, d)]  # integers: the sums below are exact

    def cov(lag: int) -> int:  # autocorrelation of the filter h at `lag` samples
        return sum(c * _box_count(lag + off, m, r) for c, off in coef)

    def term(k: int) -> int:  # (M - k) R_{k s}^2
        return (terms - k) * cov(k * stride) ** 2

    last = min(terms - 1, (length - 1) // stride)  # R vanishes beyond the filter's length
    total = 0
    if stride > 1 or last <= 64:
        total = sum(term(k) for k in range(1, last + 1))
    else:  # R is one polynomial of degree r - 1 between lags = -shift mod m: sum each piece
        degree = 2 * r - 1  # of (M - k) R_k^2
        cuts = (q * m - shift for q in range(1, (last + shift) // m + 1))
        starts = [1] + [k for k in cuts if 1 < k <= last]
        for a, b in zip(starts, starts[1:] + [last + 1]):
            if b - a <= degree + 1:
                total += sum(term(k) for k in range(a, b))
                continue
            diffs = [term(k) for k in range(a, a + degree + 1)]  # Newton forward differences
            for i in range(degree + 1):
                total += diffs[0] * math.comb(b - a, i + 1)
                diffs = [v1 - v0 for v0, v1 in itertools.pairwise(diffs)]
    r0 = cov(0)
    return (terms * r0) ** 2 / (terms * r0**2 + 2 * total)


def white_rate_edf(
    d: int, m: ArrayLike, n: int, *, overlapping: bool = True, modified: bool = False,
) -> float | np.ndarray:
    """Exact equivalent degrees of freedom of a variance of i.i.d. Gaussian rate samples.

    Each term is ``t_i = sum_k h_k y_{i s + k}``, with h the (d - 1)-th lag-m difference of a
    box of m ones (convolved with one more box of m ones when modified; ``sum h = 0``, so the
    mean of y drops out) and s the stride (1, or m non-overlapping). For y ~ N(0, sigma^2 I)
    the variance ``v = sum_{i<M} t_i^2 / c`` (M terms) has ``E v = sigma^2 M R_0 / c`` and
    ``Var v = 2 sigma^4 tr(A^2) / c^2`` (``A = sum_i h_i h_i^T``, h_i the row of term i), so

    ``edf = 2 (E v)^2 / Var v = (M R_0)^2 / (M R_0^2 + 2 sum_{k=1}^{M-1} (M - k) R_{k s}^2)``

    where ``R_l = sum_k h_k h_{k+l}`` (samples^2 per sigma^2) is the filter's autocorrelation:
    a polynomial in l of degree 1 (3 modified) between consecutive lags ``= -shift mod m``,
    built from exact box counts, so that the sum is taken in integers piece by piece by
    Newton forward differences, O(1) per m. The overlapping Allan variance at m = 1
    (``R_0 = 2``, ``R_1 = -1``) gives ``M^2 / (1.5 M - 0.5)``: 666.2 for N = 1000; the
    non-overlapping one the same at every m.

    :func:`greenhall_edf` with alpha = 0 takes F = m, a phase averaged over ``tau0``, whose
    rate samples have neighbour correlation 1/4: 782.0 at m = 1 for N = 1000. The two agree
    to 0.25 % where ``m (d + 1) > 100`` (Greenhall's algorithm then takes F = inf).

    Parameters
    ----------
    d : {2, 3}
        Order of the phase difference (2 Allan, 3 Hadamard).
    m : int or array_like of int
        Averaging factors.
    n : int
        Number of rate samples N (``N + 1`` phase points).
    overlapping : bool
        Stride 1 (True) or m (False).
    modified : bool
        Modified variance (mvar, modified Hadamard; stride 1).

    Returns
    -------
    float or ndarray
        EDF at each m (a float for a scalar `m`, else an array of the shape of `m`).

    Raises
    ------
    InputError
        `d` not 2 or 3, or an m with no term.
    """
    d = int(d)
    if d not in (2, 3):
        raise InputError(f"d must be 2 or 3; got {d}")
    ms = np.atleast_1d(np.asarray(m, dtype=np.int64))
    if np.any(ms < 1):
        raise InputError(f"m must be positive; got {int(ms.min())}")
    out = np.array(
        [_white_rate_one(d, int(v), int(n), overlapping, modified) for v in ms.ravel()]
    )
    return out.reshape(np.shape(m)) if np.ndim(m) else out[0]


def percent_error(n: int, m: ArrayLike) -> np.ndarray:
    """Percentage error of the Allan deviation, Quinchia et al. (2013) eq. 15 (IEEE 952).

    ``100 / sqrt(2 (N / m - 1))`` for N samples and clusters of m samples (inf when
    ``N / m <= 1``). E.g. N = 360000, m = 60000: 31.6 % ("approximately 32%").
    """
    ratio = n / np.asarray(m, dtype=float) - 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(ratio > 0, 100.0 / np.sqrt(2.0 * np.maximum(ratio, 1e-300)), np.inf)


def _window(lt: np.ndarray, i: int, half_width: float) -> np.ndarray:
    """Points within `half_width` decades of point i, and at least its two neighbours."""
    sel = np.abs(lt - lt[i]) <= half_width + 1e-12
    sel[max(i - 1, 0) : i + 2] = True
    return sel


def local_slopes(
    tau: ArrayLike,
    var: ArrayLike,
    *,
    half_width: float = math.log10(2.01),
    edf: ArrayLike | None = None,
    target_se: float | None = None,
    max_half_width: float = 0.5,
    return_stderr: bool = False,
) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Local log-log slope of `var` against `tau` by weighted least squares in a window.

    At each tau the slope of ``log var`` on ``log tau`` is fitted over the points within
    `half_width` decades (at least the two neighbours).

    Parameters
    ----------
    tau, var : array_like
        Averaging times (s, increasing) and variances.
    half_width : float
        Half-width of the window, decades.
    edf : array_like, optional
        Equivalent degrees of freedom of each variance: the points are weighted by the inverse
        variance of ``log10 var``, ``edf ln(10)^2 / 2``, and standard errors become available.
    target_se : float, optional
        With `edf`: widen each window (in steps of 0.05 decade, up to `max_half_width`) until
        the slope's standard error is at most `target_se`, so that the noisy long-tau end is
        smoothed more than the well-determined short-tau end.
    max_half_width : float
        Largest half-width for `target_se`, decades.
    return_stderr : bool
        Also return the standard errors (independent-point approximation: neighbouring
        variances are correlated, so they are optimistic); inf without `edf`.

    Returns
    -------
    ndarray or (ndarray, ndarray)
        Slopes (NaN where fewer than two points have a positive variance) [, standard errors].
    """
    lt = np.log10(np.asarray(tau, dtype=float))
    v = np.asarray(var, dtype=float)
    w = np.ones_like(lt) if edf is None else np.asarray(edf, dtype=float) * math.log(10.0) ** 2 / 2
    lv = np.log10(np.where(v > 0, v, np.nan))
    slopes = np.full(lt.size, np.nan)
    stderr = np.full(lt.size, np.inf)
    widths = [half_width]
    if target_se is not None and edf is not None:
        widths += list(np.arange(half_width + 0.05, max_half_width + 1e-9, 0.05))
    for i in range(lt.size):
        for h in widths:
            sel = _window(lt, i, h) & np.isfinite(lv)
            if sel.sum() < 2:
                continue
            xs, ys, ws = lt[sel], lv[sel], w[sel]
            xm = np.sum(ws * xs) / np.sum(ws)
            sxx = np.sum(ws * (xs - xm) ** 2)
            if sxx <= 0:
                continue
            slopes[i] = np.sum(ws * (xs - xm) * ys) / sxx
            if edf is not None:
                stderr[i] = 1.0 / math.sqrt(sxx)
            if target_se is None or stderr[i] <= target_se:
                break
    return (slopes, stderr) if return_stderr else slopes


# ----------------------------------------------------------------------------- front end


def _auto_noise(tau: np.ndarray, var: np.ndarray, edf_wn: np.ndarray, d: int,
                modified: bool) -> np.ndarray:
    """Noise exponent per tau from the local slope where it is well determined.

    The slope mu of log var on log tau is fitted within 0.3 decade (at least the
    neighbours), weighted by the white-noise EDF; ``alpha = round(-mu - 1)`` is used where the
    slope's standard error (independent-point approximation) is at most 0.25, otherwise the
    last well-determined exponent carries on (white noise, 0, before the first one).
    """
    mu, se = local_slopes(tau, var, half_width=_AUTO_WINDOW, edf=edf_wn, return_stderr=True)
    out = np.zeros(tau.size, dtype=int)
    last = 0
    for i in range(tau.size):
        if np.isfinite(mu[i]) and se[i] <= _AUTO_MAX_SE:
            a = int(np.clip(np.round(-mu[i] - 1.0), 2 - 2 * d, 2))
            last = 2 if (a == 1 and not modified) else a  # unmodified: tau^-2 for alpha 1, 2
        out[i] = last
    return out


def _noise_exponents(noise: int | str, tau: np.ndarray, var: np.ndarray, edf_wn: np.ndarray,
                     d: int, modified: bool) -> np.ndarray:
    lowest = 2 - 2 * d  # alpha + 2 d > 1
    if isinstance(noise, str) and noise == "auto":
        return _auto_noise(tau, var, edf_wn, d, modified)
    if isinstance(noise, str):
        if noise.upper() not in NOISE_NAMES:
            raise InputError(
                f"noise must be 'auto', an integer exponent or one of {sorted(NOISE_NAMES)}; "
                f"got {noise!r}"
            )
        value = NOISE_NAMES[noise.upper()]
    elif isinstance(noise, numbers.Integral) and not isinstance(noise, bool):
        value = int(noise)
    else:
        raise InputError(f"noise must be 'auto', an integer exponent or a name; got {noise!r}")
    if not lowest <= value <= 2:
        raise InputError(
            f"noise exponent {value} is not valid for this kind (needs {lowest} <= alpha <= 2)"
        )
    return np.full(tau.size, value, dtype=int)


def avar(
    x: ArrayLike,
    freq: float,
    taus: str | ArrayLike = "octave",
    kind: str = "overlapping",
    ci: str = "edf",
    alpha: float = 0.05,
    tau_reduction: int | None = None,
    *,
    points_per_decade: int = 10,
    noise: int | str = "auto",
    white_edf: str = "exact",
) -> AllanVariance:
    """Allan variance (or a relative: Hadamard, modified) of a rate signal, with intervals.

    Parameters
    ----------
    x : array_like, shape (N,)
        Rate signal (rad/s, m/s^2 ... any unit u), finite, N >= d + 1.
    freq : float
        Sampling frequency, Hz.
    taus : {"octave", "decade", "log", "all"} or array_like
        Averaging times: "octave" (m = 1, 2, 4, ... up to the largest valid), "decade" or
        "log" (``points_per_decade`` log-spaced integer m), "all" (every m: quadratic, use
        `tau_reduction`), or explicit seconds (multiples of ``1/freq``).
    kind : str
        "overlapping" (default, allantools oadev), "non-overlapping" (adev), "hadamard"
        (overlapping, ohdev), "non-overlapping-hadamard" (hdev), "modified" (mdev),
        "modified-hadamard".
    ci : {"edf", "simple", "none"}
        "edf" (default): chi-square interval with the EDF of the noise type `noise` (see
        `white_edf`; Greenhall & Riley's for alpha != 0). "simple": Quinchia eq. 15 (IEEE 952), ``dev (1 -+ z delta)`` with
        ``delta = 1 / sqrt(2 (N/m - 1))``, squared (lower end clipped at 0). "none": NaN.
    alpha : float
        Significance level (0.05: 95 % intervals).
    tau_reduction : int, optional
        Keep at most this many averaging times, log-uniformly spread.
    points_per_decade : int
        Density of the "decade"/"log" grid (default 10).
    noise : "auto", int or {"QN", "WN", "BI", "RW", "RR"}
        Noise exponent alpha for the EDF. "auto" (default) rounds ``-mu - 1`` where mu is the
        local log-log slope of the estimated variance (within 0.3 decade) wherever that slope
        is well determined (standard error <= 0.25), and carries the last such exponent on
        into the noisy long-tau tail (white noise, alpha = 0, before the first one); on
        unmodified kinds a tau^-2 slope is taken as white phase (quantization, alpha = 2).
        A fixed exponent or name applies to every tau.
    white_edf : {"exact", "greenhall"}
        EDF wherever the noise exponent is 0 (white rate noise). "exact" (default): the EDF
        of the estimated variance for i.i.d. Gaussian rate samples, at every m
        (:func:`white_rate_edf`; the overlapping AV at m = 1: ``M^2 / (1.5 M - 0.5)``, M
        terms). "greenhall": Greenhall & Riley's with F = m, exact for a phase averaged over
        ``tau0`` (neighbouring rate samples correlated by 1/4), as Stable32 and allantools.

    Returns
    -------
    AllanVariance
        tau (s), m, variance (u^2), interval on the variance, n_terms, EDF, noise exponents.

    Raises
    ------
    InputError
        Bad signal (empty, too short, NaN/inf, not 1-D), bad freq, unknown kind / grid / ci /
        noise / white_edf, explicit taus not multiples of 1/freq or out of range, bad alpha.
    """
    d, overlapping, modified = _check_kind(kind)
    y = as_signal(x, name="x", min_length=d + 1)
    freq = check_freq(freq)
    alpha = check_alpha(alpha)
    if ci not in CI_METHODS:
        raise InputError(f"ci must be one of {', '.join(map(repr, CI_METHODS))}; got {ci!r}")
    if white_edf not in WHITE_EDFS:
        raise InputError(
            f"white_edf must be one of {', '.join(map(repr, WHITE_EDFS))}; got {white_edf!r}"
        )
    m = tau_grid(y.size, freq, taus, kind, points_per_decade=points_per_decade,
                 tau_reduction=tau_reduction)
    tau = m / freq
    var, n_terms = _variances(y, m, kind)
    ov, mod = overlapping, modified
    if white_edf == "exact":
        edf_wn = white_rate_edf(d, m, y.size, overlapping=ov, modified=mod)
    else:
        edf_wn = greenhall_edf(0, d, m, y.size + 1, overlapping=ov, modified=mod)
    expo = _noise_exponents(noise, tau, var, edf_wn, d, modified)
    edf = np.array([
        edf_wn[i] if a == 0 else greenhall_edf(a, d, int(m[i]), y.size + 1, overlapping=ov,
                                               modified=mod)
        for i, a in enumerate(expo)
    ], dtype=float)
    if ci == "edf":
        low = edf * var / chdtri(edf, alpha / 2.0)
        high = edf * var / chdtri(edf, 1.0 - alpha / 2.0)
    elif ci == "simple":
        z = float(ndtri(1.0 - alpha / 2.0))
        delta = percent_error(y.size, m) / 100.0
        dev = np.sqrt(var)
        low = (dev * np.maximum(1.0 - z * delta, 0.0)) ** 2
        high = (dev * (1.0 + z * delta)) ** 2
    else:
        low = high = np.full(m.size, np.nan)
    return AllanVariance(
        tau=tau, m=m, avar=var, ci_low=low, ci_high=high, n_terms=n_terms.astype(np.int64),
        edf=edf, noise=expo, kind=kind, freq=freq, n=int(y.size), ci=ci, alpha=alpha,
    )
