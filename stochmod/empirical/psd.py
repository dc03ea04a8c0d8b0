"""One-sided Welch power spectral density, log-frequency averaging and the slope reading.

Convention (IEEE Std 952/1293 plots): the spectrum is **one-sided**, ``G(f) = 2 S(f)`` for
``0 < f < freq/2``, where ``S`` is the two-sided PSD whose integral over ``(-freq/2, freq/2]``
is the variance. White noise of per-sample variance ``s2`` thus has ``G = 2 s2 / freq``.

The noise coefficients are those of the Allan-variance reading (IEEE 952 Annex C, whose
power laws are two-sided ``S``), so both readings give the same numbers:

======================  =======================  ===================  ===================
term                    two-sided S(f)           one-sided G(f)       Allan variance
======================  =======================  ===================  ===================
white noise N           ``N^2``                  ``2 N^2``            ``N^2 / tau``
bias instability B      ``B^2 / (2 pi f)``       ``B^2 / (pi f)``     ``(2 ln 2 / pi) B^2``
random walk K           ``K^2 / (2 pi f)^2``     ``K^2/(2 pi^2 f^2)`` ``K^2 tau / 3``
======================  =======================  ===================  ===================

``N`` is in u*sqrt(s) (= u/sqrt(Hz)), ``B`` in u, ``K`` in u/sqrt(s). In per-sample terms at
sampling frequency ``freq``: white variance ``N^2 * freq``, random-walk increment variance
``K^2 / freq``.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from typing import Any

import attrs
import numpy as np
from numpy.typing import ArrayLike

from stochmod.core.checks import as_signal, check_freq, check_positive_int
from stochmod.core.errors import InputError
from stochmod.empirical.allan import local_slopes
from stochmod.core.tables import format_table

__all__ = [
    "PowerSpectrum",
    "psd",
    "log_bin",
    "PSDTerm",
    "PSDReading",
    "psd_reading",
    "TERMS",
]

#: name -> (log-log slope of the one-sided PSD, unit, description)
TERMS: dict[str, tuple[int, str, str]] = {
    "N": (0, "u/sqrt(Hz)", "white noise (angle/velocity random walk)"),
    "B": (-1, "u", "bias instability"),
    "K": (-2, "u/sqrt(s)", "random walk (rate/acceleration random walk)"),
}
# G(f) = C f^slope  ->  coefficient = sqrt(C * _SCALE[name])
_SCALE = {"N": 0.5, "B": math.pi, "K": 2.0 * math.pi**2}


def _chi2_interval(
    values: np.ndarray, dof: np.ndarray, level: float
) -> tuple[np.ndarray, np.ndarray]:
    from scipy import stats  # here: scipy.stats and scipy.signal are a second of import

    alpha = 1.0 - level
    u, inv = np.unique(dof, return_inverse=True)  # quantiles once per distinct dof
    lo = (u / stats.chi2.ppf(1.0 - alpha / 2.0, u))[inv]
    hi = (u / stats.chi2.ppf(alpha / 2.0, u))[inv]
    return values * lo, values * hi


@attrs.frozen
class PowerSpectrum:
    """A one-sided power spectral density estimate.

    Attributes
    ----------
    f : ndarray
        Frequencies in Hz (for a binned spectrum: the geometric mean of each bin's frequencies).
    psd : ndarray
        One-sided PSD in u^2/Hz.
    freq : float
        Sampling frequency in Hz.
    nperseg : int
        Welch segment length in samples (frequency resolution ``freq / nperseg``).
    n_segments : int
        Number of Welch segments averaged.
    counts : ndarray of int
        Number of Fourier frequencies averaged into each value (1 before binning).
    dof : ndarray
        Approximate chi-square degrees of freedom of each value: ``2 * n_segments`` per Fourier
        frequency; a bin of ``c`` adjacent frequencies has ``2 * n_segments * c_eff`` where
        ``c_eff <= c`` discounts the correlation of neighbouring frequencies that the window
        causes (Hann: 0.444 between neighbours, so ``c_eff ~ c / 1.94`` for wide bins).
    ci_low, ci_high : ndarray
        Approximate confidence interval in u^2/Hz from ``chi2(dof)`` (the small correlation
        that 50 % segment overlap adds is ignored).
    window : str
        The Welch window.
    level : float
        Confidence level of the interval.
    """

    f: np.ndarray
    psd: np.ndarray
    freq: float
    nperseg: int
    n_segments: int
    counts: np.ndarray = attrs.field(repr=False)
    dof: np.ndarray = attrs.field(repr=False)
    ci_low: np.ndarray = attrs.field(repr=False)
    ci_high: np.ndarray = attrs.field(repr=False)
    window: str = "hann"
    level: float = 0.95

    def summary(self, max_rows: int = 60) -> str:
        """The spectrum as a table (at most `max_rows` rows, evenly thinned)."""
        idx = np.arange(self.f.size)
        if idx.size > max_rows:
            idx = np.unique(np.linspace(0, idx.size - 1, max_rows).round().astype(int))
        rows = [
            [self.f[i], self.psd[i], self.ci_low[i], self.ci_high[i], int(self.counts[i])]
            for i in idx
        ]
        return format_table(
            ["f (Hz)", "PSD (u^2/Hz)", f"{self.level:.0%} low", f"{self.level:.0%} high", "count"],
            rows,
            title=(
                f"one-sided Welch PSD (freq = {self.freq:g} Hz, nperseg = {self.nperseg}, "
                f"{self.n_segments} segment(s), {self.f.size} point(s))"
            ),
        )

    def to_dict(self) -> dict[str, Any]:
        """Arrays and settings as a JSON-ready dict."""
        return {
            "f": self.f.tolist(), "psd": self.psd.tolist(), "ci_low": self.ci_low.tolist(),
            "ci_high": self.ci_high.tolist(), "counts": self.counts.tolist(),
            "dof": self.dof.tolist(), "freq": self.freq, "nperseg": self.nperseg,
            "n_segments": self.n_segments, "window": self.window, "level": self.level,
        }


def _spectrum(f, p, freq, nperseg, n_segments, counts, dof, window, level) -> PowerSpectrum:
    lo, hi = _chi2_interval(p, dof, level)
    return PowerSpectrum(f=f, psd=p, freq=freq, nperseg=nperseg, n_segments=n_segments,
                         counts=counts, dof=dof, ci_low=lo, ci_high=hi, window=window, level=level)


@functools.lru_cache(maxsize=16)
def _bin_correlation(window: str, nperseg: int, max_shift: int = 8) -> np.ndarray:
    """Correlation of periodogram values ``k`` Fourier frequencies apart, ``k = 0..max_shift``.

    ``rho_k = |sum w_t^2 exp(-2 pi i k t / M)|^2 / (sum w_t^2)^2`` for a Gaussian process with a
    locally flat spectrum (Hann: 1, 4/9, 1/36, 0, ...).
    """
    from scipy import signal as sp_signal

    w2 = sp_signal.get_window(window, nperseg) ** 2
    spec = np.abs(np.fft.rfft(w2)[: max_shift + 1]) ** 2
    rho = spec / spec[0]
    rho.flags.writeable = False  # cached
    return rho


def _effective_counts(counts: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """``c^2 / sum_{i,j} rho_|i-j|``: independent-equivalent number of averaged frequencies."""
    c = counts.astype(float)
    denom = np.ones_like(c)
    for k in range(1, rho.size):
        denom += 2.0 * rho[k] * np.clip(1.0 - k / c, 0.0, None)
    return c / denom


def _default_nperseg(n: int) -> int:
    """Largest power of two <= n/2 (at least 3 half-overlapping segments), or n when short."""
    if n < 16:
        return n
    return 1 << int(math.floor(math.log2(n / 2)))


def psd(
    x: ArrayLike,
    freq: float,
    nperseg: int | None = None,
    window: str = "hann",
    average: str = "mean",
    *,
    level: float = 0.95,
) -> PowerSpectrum:
    """One-sided Welch PSD in u^2/Hz (50 % overlap, mean removed per segment).

    Parameters
    ----------
    x : array_like, shape (n,)
        Signal in units u.
    freq : float
        Sampling frequency in Hz.
    nperseg : int, optional
        Segment length in samples; default the largest power of two <= n/2.
    window : str
        Any :func:`scipy.signal.get_window` name.
    average : {"mean", "median"}
        How segment periodograms are combined (scipy's bias-corrected median).
    level : float
        Confidence level of the chi-square interval.

    Returns
    -------
    PowerSpectrum
        Without the zero frequency. White noise of variance ``s2`` has level ``2 s2 / freq``.
    """
    x = as_signal(x, name="x", min_length=4)
    freq = check_freq(freq)
    if average not in ("mean", "median"):
        raise InputError(f"average must be 'mean' or 'median', got {average!r}")
    if not 0.0 < level < 1.0:
        raise InputError(f"level must lie in (0, 1), got {level!r}")
    n = x.size
    if nperseg is None:
        nperseg = _default_nperseg(n)
    else:
        nperseg = check_positive_int(nperseg, name="nperseg", minimum=4)
    if nperseg > n:
        raise InputError(f"nperseg = {nperseg} exceeds the signal length {n}")
    noverlap = nperseg // 2
    from scipy import signal as sp_signal

    f, p = sp_signal.welch(x, fs=freq, window=window, nperseg=nperseg, noverlap=noverlap,
                           detrend="constant", return_onesided=True, scaling="density",
                           average=average)
    n_segments = 1 + (n - nperseg) // (nperseg - noverlap)
    keep = f > 0
    m = int(keep.sum())
    return _spectrum(f[keep], p[keep], freq, nperseg, n_segments, np.ones(m, dtype=np.int64),
                     np.full(m, 2.0 * n_segments), window, level)


def _subset(spec: PowerSpectrum, mask: np.ndarray) -> PowerSpectrum:
    """The spectrum restricted to the frequencies where `mask` is True."""
    return attrs.evolve(spec, **{k: getattr(spec, k)[mask] for k in
                                 ("f", "psd", "counts", "dof", "ci_low", "ci_high")})


def _bin_index(f: np.ndarray, bins_per_decade: int) -> np.ndarray:
    """Log bin of each frequency: ``floor(bins_per_decade * log10 f)``."""
    return np.floor(np.log10(f) * bins_per_decade + 1e-9).astype(np.int64)


def log_bin(spec: PowerSpectrum, bins_per_decade: int = 10) -> PowerSpectrum:
    """Frequency averaging into logarithmically spaced bins.

    Parameters
    ----------
    spec : PowerSpectrum
        A spectrum (typically from :func:`psd`).
    bins_per_decade : int
        Number of bins per decade of frequency; bin edges are ``10**(k / bins_per_decade)`` Hz.

    Returns
    -------
    PowerSpectrum
        One value per non-empty bin: the count-weighted mean of the bin's PSD values, at the
        geometric mean of its frequencies, with the number of Fourier frequencies averaged in
        ``counts`` (empty bins are dropped).
    """
    bpd = check_positive_int(bins_per_decade, name="bins_per_decade")
    pos = spec.f > 0
    f, p, c = spec.f[pos], spec.psd[pos], spec.counts[pos]
    if f.size == 0:
        raise InputError("the spectrum has no positive frequencies to bin")
    uniq, inv = np.unique(_bin_index(f, bpd), return_inverse=True)
    counts = np.bincount(inv, weights=c).astype(np.int64)
    mean_p = np.bincount(inv, weights=p * c) / counts
    mean_f = np.exp(np.bincount(inv, weights=np.log(f) * c) / counts)
    c_eff = _effective_counts(counts, _bin_correlation(spec.window, spec.nperseg))
    return _spectrum(mean_f, mean_p, spec.freq, spec.nperseg, spec.n_segments, counts,
                     2.0 * spec.n_segments * c_eff, spec.window, spec.level)


@attrs.frozen
class PSDTerm:
    """One noise coefficient read from a straight line of fixed slope on the log-log PSD.

    Attributes
    ----------
    name : str
        ``"N"``, ``"B"`` or ``"K"``.
    slope : int
        Log-log slope of the one-sided PSD (0, -1, -2).
    value : float
        The coefficient (N in u/sqrt(Hz), B in u, K in u/sqrt(s)).
    ci_low, ci_high : float
        Confidence interval of the coefficient.
    se_log : float
        Standard error of ``ln(value)``: chi-square theory, inflated by the reduced chi-square of
        the line's residuals when they scatter more than the theory says.
    f_low, f_high : float
        Frequency range of the fitted bins in Hz.
    n_bins : int
        Number of binned PSD values in the fit.
    auto : bool
        Whether the range was found automatically (else given by the user).
    """

    name: str
    slope: int
    value: float
    ci_low: float
    ci_high: float
    se_log: float
    f_low: float
    f_high: float
    n_bins: int
    auto: bool = True

    @property
    def unit(self) -> str:
        """Unit of the coefficient, with u the signal's unit."""
        return TERMS[self.name][1]

    def level_at(self, f: ArrayLike, freq: float | None = None) -> np.ndarray:
        """The fitted one-sided PSD ``G(f)`` in u^2/Hz (K: the sampled random walk's at `freq`)."""
        f = np.asarray(f, dtype=float)
        if freq is not None:
            f = _shape_frequency(self.name, f, freq)
        return self.value**2 / _SCALE[self.name] * f**self.slope

    def to_dict(self) -> dict[str, Any]:
        """Fields as a JSON-ready dict."""
        return attrs.asdict(self) | {"unit": self.unit}


@attrs.frozen
class PSDReading:
    """The slope reading of a PSD: white noise N, bias instability B, random walk K.

    Attributes
    ----------
    N, B, K : PSDTerm or None
        The coefficients found (None where the slope is absent).
    spectrum : PowerSpectrum
        The log-binned spectrum the lines were fitted on.
    freq : float
        Sampling frequency in Hz.
    """

    N: PSDTerm | None
    B: PSDTerm | None
    K: PSDTerm | None
    spectrum: PowerSpectrum = attrs.field(repr=False)
    freq: float = 0.0

    @property
    def terms(self) -> dict[str, PSDTerm]:
        """The terms that were found, by name."""
        return {k: t for k in TERMS if (t := getattr(self, k)) is not None}

    def model_psd(self, f: ArrayLike) -> np.ndarray:
        """Sum of the fitted power laws (one-sided, u^2/Hz) at frequencies `f` (Hz)."""
        f = np.asarray(f, dtype=float)
        total = np.zeros_like(f)
        for term in self.terms.values():
            total = total + term.level_at(f, self.freq)
        return total

    def summary(self) -> str:
        """The coefficients with their intervals and frequency ranges."""
        rows = []
        for name, (slope, unit, what) in TERMS.items():
            t = getattr(self, name)
            if t is None:
                rows.append([name, what, slope, "absent", "", "", "", "", ""])
            else:
                rows.append([name, what, slope, t.value, t.ci_low, t.ci_high, unit,
                             f"{t.f_low:.3g}-{t.f_high:.3g}", "auto" if t.auto else "given"])
        return format_table(
            ["term", "process", "slope", "value", "95% low", "95% high", "unit", "f range (Hz)",
             "range"],
            rows, title=f"PSD slope reading (freq = {self.freq:g} Hz, u = signal unit)",
        )

    def to_dict(self) -> dict[str, Any]:
        """Terms (None where absent) as a JSON-ready dict."""
        found = self.terms
        out = {k: (found[k].to_dict() if k in found else None) for k in TERMS}
        return out | {"freq": self.freq}

    def coefficient_values(self) -> dict[str, float]:
        """The coefficients found, ``{"N": ..., "B": ..., "K": ...}`` in SI (names of
        :data:`stochmod.core.coefficients.COEFFICIENTS`); :func:`stochmod.fit.classical.psd_reading_model`
        turns them into a model."""
        return {name: float(t.value) for name, t in self.terms.items()}



def _shape_frequency(name: str, f: np.ndarray, freq: float) -> np.ndarray:
    """Frequency in the power law: ``f`` itself, or for K the sampled random walk's
    ``(freq/pi) sin(pi f/freq)`` (its exact spectrum ``K^2 / (2 freq^2 sin^2(pi f/freq))``)."""
    if name == "K":
        return freq / math.pi * np.sin(np.pi * f / freq)
    return f


def _fit_term(name: str, raw: PowerSpectrum, sel: np.ndarray, groups: np.ndarray, level: float,
              auto: bool, others: list[PSDTerm] = ()) -> PSDTerm:
    """Fit ``G(f) = C h(f)`` on the raw Welch values `sel` and convert C to the coefficient.

    The lines of the `others` terms are subtracted first (joint reading of overlapping terms).

    ``C`` is the mean of ``G_k / h(f_k)`` (the maximum-likelihood scale of chi-square values
    with a common number of degrees of freedom, unbiased; fitting the ratio avoids the
    Jensen bias of evaluating a steep power law at a bin's mean frequency). Its relative
    standard error is ``sqrt(2 / (dof c_eff))``, inflated by the reduced chi-square of the
    ratios averaged per log bin (`groups`) when the line does not fit.
    """
    slope = TERMS[name][0]
    f = raw.f[sel]
    g = raw.psd[sel]
    for other in others:
        g = g - other.level_at(f, raw.freq)
    ratio = g * _shape_frequency(name, f, raw.freq) ** (-slope)
    c_hat = float(ratio.mean())
    rho = _bin_correlation(raw.window, raw.nperseg)
    nu = float(raw.dof[sel].mean())
    rel_se = math.sqrt(2.0 / nu / float(_effective_counts(np.array([ratio.size]), rho)[0]))
    uniq, inv = np.unique(groups[sel], return_inverse=True)
    if not c_hat > 0:
        # the other terms explain everything here: a zero coefficient, unbounded above
        c_hat, rel_se = float(np.finfo(float).tiny), math.inf
    elif uniq.size > 1:
        counts = np.bincount(inv)
        rel_means = np.bincount(inv, weights=ratio) / counts / c_hat
        rel_var = 2.0 / nu / _effective_counts(counts, rho)
        red_chi2 = float(np.sum((rel_means - 1.0) ** 2 / rel_var)) / (uniq.size - 1)
        rel_se *= math.sqrt(max(1.0, red_chi2))
    from scipy import stats

    z = float(stats.norm.ppf(0.5 + level / 2.0))
    value = math.sqrt(c_hat * _SCALE[name])
    se_log = rel_se / 2.0
    return PSDTerm(
        name=name, slope=slope, value=value, ci_low=value * math.exp(-z * se_log),
        ci_high=value * math.exp(z * se_log), se_log=se_log, f_low=float(f.min()),
        f_high=float(f.max()), n_bins=int(uniq.size), auto=auto,
    )


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Start/stop index pairs of the True runs of a boolean array."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return list(zip(edges[::2], edges[1::2]))


def psd_reading(
    x: ArrayLike,
    freq: float,
    *,
    nperseg: int | None = None,
    window: str = "hann",
    average: str = "mean",
    bins_per_decade: int = 10,
    ranges: Mapping[str, tuple[float, float]] | None = None,
    slope_tol: float = 0.3,
    min_decades: float = 0.5,
    skip_low: int = 4,
    joint: bool = True,
    level: float = 0.95,
) -> PSDReading:
    """Read N, B and K from straight lines of slope 0, -1, -2 on the log-binned one-sided PSD.

    Parameters
    ----------
    x : array_like, shape (n,)
        Static sensor error signal in units u.
    freq : float
        Sampling frequency in Hz.
    nperseg, window, average
        Passed to :func:`psd`.
    bins_per_decade : int
        Frequency averaging (:func:`log_bin`).
    ranges : mapping, optional
        User frequency ranges ``{"N": (f_lo, f_hi), ...}`` in Hz; terms not named are found
        automatically.
    slope_tol : float
        A bin belongs to a slope when its local slope is within this of 0, -1 or -2. The local
        slope is a weighted least-squares fit over +-1/4 decade, widened up to +-1 decade until
        its standard error is at most ``slope_tol / 3``; bins too noisy even then are unused.
    min_decades : float
        Shortest automatic region, in decades of frequency.
    skip_low : int
        Fourier frequencies ``k * freq / nperseg`` with ``k < skip_low`` are not used: there the
        window's main lobe leaks the power of lower frequencies and biases steep (random-walk)
        spectra upward (Hann, 1/f^2: +41 % at k = 2, +14 % at k = 3, +7 % at k = 4).
    joint : bool
        Fit the lines jointly: each term's level is read after subtracting the other found
        lines from its region (iterated to convergence), which removes the bias of overlapping
        terms near the region edges; False reads each line on its own, as by hand.
    level : float
        Confidence level of the intervals.

    Returns
    -------
    PSDReading
        Terms (None where absent). Automatic regions: N the highest-frequency flat run, K the
        lowest-frequency slope -2 run, B the longest slope -1 run.

    Notes
    -----
    The coefficients follow the IEEE 952 definitions (see the module docstring), so
    ``N`` equals the Allan reading's ``sqrt(AV(tau) tau)`` on white noise, ``K`` its
    ``sqrt(3 AV(tau) / tau)`` on a random walk and ``B`` its flat ``sigma / 0.664``.
    """
    raw = psd(x, freq, nperseg=nperseg, window=window, average=average, level=level)
    skip = check_positive_int(skip_low, name="skip_low", minimum=1)
    keep = raw.f * raw.nperseg / raw.freq >= skip - 0.5
    if keep.sum() < 3:
        raise InputError(
            f"only {int(keep.sum())} Fourier frequencies remain above the {skip} lowest: "
            "the signal is too short for a PSD reading (or lower skip_low / raise nperseg)"
        )
    raw = _subset(raw, keep)
    bpd = check_positive_int(bins_per_decade, name="bins_per_decade")
    spec = log_bin(raw, bpd)
    groups = _bin_index(raw.f, bpd)
    ranges = dict(ranges or {})
    unknown = set(ranges) - set(TERMS)
    if unknown:
        raise InputError(f"ranges has unknown term(s) {sorted(unknown)}; use N, B, K")
    if not slope_tol > 0:
        raise InputError(f"slope_tol must be positive, got {slope_tol!r}")
    regions: dict[str, tuple[np.ndarray, bool]] = {}
    for name, rng in ranges.items():
        try:
            lo, hi = (float(v) for v in rng)
        except (TypeError, ValueError):
            raise InputError(
                f"ranges[{name!r}] must be a pair (f_low, f_high) in Hz, got {rng!r}") from None
        if not 0 < lo < hi:
            raise InputError(
                f"ranges[{name!r}] must satisfy 0 < f_low < f_high (Hz), got {(lo, hi)}")
        sel = (raw.f >= lo) & (raw.f <= hi)
        if sel.sum() < 2:
            raise InputError(
                f"ranges[{name!r}] = {(lo, hi)} Hz holds {int(sel.sum())} usable Fourier "
                f"frequencies (resolution {raw.freq / raw.nperseg:.3g} Hz); need at least 2")
        regions[name] = (sel, False)

    target = slope_tol / 3.0
    local, se = local_slopes(spec.f, spec.psd, half_width=0.25, edf=spec.dof, target_se=target,
                             max_half_width=1.0, return_stderr=True)
    local[~(se <= target)] = np.nan  # too noisy even over +-1 decade: unused
    lf = np.log10(spec.f)
    bin_ids = _bin_index(spec.f, bpd)
    for name, (slope, _, _) in TERMS.items():
        if name in regions:
            continue
        runs = [(a, b) for a, b in _runs(np.abs(local - slope) <= slope_tol)
                if b - a >= 2 and lf[b - 1] - lf[a] >= min_decades]
        if not runs:
            continue
        if name == "N":
            a, b = max(runs, key=lambda r: r[1])
        elif name == "K":
            a, b = min(runs, key=lambda r: r[0])
        else:
            a, b = max(runs, key=lambda r: lf[r[1] - 1] - lf[r[0]])
        regions[name] = (np.isin(groups, bin_ids[a:b]), True)
    found = _backfit(raw, regions, groups, level, joint)
    return PSDReading(N=found.get("N"), B=found.get("B"), K=found.get("K"), spectrum=spec,
                      freq=spec.freq)


def _backfit(raw: PowerSpectrum, regions: dict[str, tuple[np.ndarray, bool]], groups: np.ndarray,
             level: float, joint: bool, max_iter: int = 200) -> dict[str, PSDTerm]:
    """Fit each term on its region; with `joint`, subtract the other lines and iterate
    (Gauss-Seidel backfitting) until the coefficients change by less than 1e-10 relative."""
    found = {name: _fit_term(name, raw, sel, groups, level, auto)
             for name, (sel, auto) in regions.items()}
    if not joint or len(found) < 2:
        return found
    for _ in range(max_iter):
        change = 0.0
        for name, (sel, auto) in regions.items():
            others = [t for k, t in found.items() if k != name]
            new = _fit_term(name, raw, sel, groups, level, auto, others)
            change = max(change, abs(new.value - found[name].value) / found[name].value)
            found[name] = new
        if change < 1e-10:
            break
    return found
