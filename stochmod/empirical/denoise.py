"""Wavelet de-noising (MATLAB ``wden`` conventions) and the Quinchia et al. (2013) pipelines.

The signal is decomposed with :func:`pywt.wavedec` to `level` levels, the detail coefficients
of each level are thresholded and the signal is rebuilt with :func:`pywt.waverec`. Thresholds
follow MATLAB's ``thselect``/``wden``:

* ``"rigrsure"``: Stein's unbiased risk estimate minimised over the candidate thresholds
  ``|d_i|`` (sorting, O(n log n)) on each level's coefficients divided by the noise scale;
* ``"sqtwolog"``: the universal threshold ``sqrt(2 ln n)``, n the total number of wavelet
  coefficients (approximation included: wden applies ``thselect`` to the whole vector ``c``);
* ``"heursure"``: ``sqtwolog`` when the level's energy is close to that of pure noise
  (``(|d|^2 - n)/n < (log2 n)^1.5 / sqrt(n)``), else the smaller of SURE and universal;
* ``"minimaxi"``: ``0.3936 + 0.1829 log2 n`` (0 for ``n <= 32``), n as for sqtwolog;
* a number: a fixed threshold in units of the noise scale (0 reconstructs perfectly).

Every threshold is multiplied by the level's noise scale: ``"level"`` (wden ``'mln'``,
``median(|d_j|)/0.6745`` of each level), ``"one"`` (``'sln'``, that of the finest level for
every level) or ``"none"`` (``'one'``, unit noise). A level whose noise scale is below
``sqrt(eps) * max|d_j|`` is left untouched (wden's guard).

Level and band: after ``k`` levels the approximation keeps frequencies below
``freq / 2^(k+1)`` Hz (ideal filters), i.e. Allan cluster times above ``2^(k+1) / freq`` s
(Quinchia Section 5.6: 3 levels at 100 Hz keep 0-6.25 Hz and tau > 0.16 s, 8 levels
0-0.1953 Hz and tau > 5.12 s; Table 7: 6 levels -> 0.78 Hz, 7 levels -> 0.39 Hz).
"""

from __future__ import annotations

import math
from typing import Any

import attrs
import numpy as np
import pywt
from numpy.typing import ArrayLike

from stochmod.core.checks import as_signal, check_freq, check_positive_int
from stochmod.core.errors import InputError
from stochmod.core.tables import format_table

__all__ = [
    "RULES",
    "select_threshold",
    "sure_threshold",
    "soft_threshold",
    "hard_threshold",
    "band_limit",
    "level_for_frequency",
    "WaveletDenoising",
    "wavelet_denoise",
    "denoise",
    "denoise_then_ar",
    "DenoisedAllan",
    "denoised_allan",
]

RULES = ("rigrsure", "sqtwolog", "heursure", "minimaxi")
_NOISE = ("level", "one", "none")
_MODES = ("soft", "hard")
_MAD_FACTOR = 0.6745  # MATLAB wnoisest: median(|d|) / 0.6745


def _sure_sorted(sx2: np.ndarray) -> float:
    """SURE threshold from the ascending squared unit-noise coefficients (MATLAB's formula)."""
    n = sx2.size
    if n == 0:
        return 0.0
    k = np.arange(1.0, n + 1.0)
    risks = np.cumsum(sx2)
    risks += (n - k) * sx2
    k *= -2.0
    k += n
    risks += k
    return float(math.sqrt(sx2[int(np.argmin(risks))]))


def _heursure_sorted(sx2: np.ndarray) -> float:
    m = sx2.size
    if m == 0:
        return 0.0
    hthr = _universal(m)
    eta = (float(sx2.sum()) - m) / m
    crit = math.log2(m) ** 1.5 / math.sqrt(m)
    return hthr if eta < crit else min(_sure_sorted(sx2), hthr)


def sure_threshold(d: ArrayLike) -> float:
    """SURE threshold of unit-noise coefficients (MATLAB ``thselect(d, 'rigrsure')``).

    Minimises ``SURE(t) = n - 2 #{|d_i| <= t} + sum min(d_i^2, t^2)`` over ``t`` in ``{|d_i|}``
    by sorting: at the k-th smallest ``|d|`` the risk is
    ``n - 2k + sum_{i<=k} d_(i)^2 + (n - k) d_(k)^2``.
    """
    return _sure_sorted(np.sort(np.abs(np.asarray(d, dtype=float).ravel())) ** 2)


def _universal(n: int) -> float:
    return math.sqrt(2.0 * math.log(n)) if n > 1 else 0.0


def _minimax(n: int) -> float:
    return 0.0 if n <= 32 else 0.3936 + 0.1829 * math.log2(n)


def select_threshold(d: ArrayLike, rule: str, *, n_total: int | None = None) -> float:
    """Threshold for unit-noise coefficients `d` by a MATLAB ``thselect`` rule.

    Parameters
    ----------
    d : array_like
        Coefficients already divided by the noise scale.
    rule : {"rigrsure", "sqtwolog", "heursure", "minimaxi"}
        The rule (see the module docstring).
    n_total : int, optional
        The n of ``sqtwolog`` and ``minimaxi`` (default ``d.size``; :func:`wavelet_denoise` passes
        the total number of coefficients, as ``wden`` does).
    """
    d = np.asarray(d, dtype=float).ravel()
    n = d.size if n_total is None else int(n_total)
    if rule == "rigrsure":
        return sure_threshold(d)
    if rule == "sqtwolog":
        return _universal(n)
    if rule == "minimaxi":
        return _minimax(n)
    if rule == "heursure":
        return _heursure_sorted(np.sort(np.abs(d)) ** 2)
    raise InputError(f"rule must be one of {RULES} or a non-negative number, got {rule!r}")


def soft_threshold(d: np.ndarray, t: float) -> np.ndarray:
    """Soft thresholding ``sign(d) max(|d| - t, 0)``."""
    return d - np.clip(d, -t, t)


def hard_threshold(d: np.ndarray, t: float) -> np.ndarray:
    """Hard thresholding ``d 1{|d| > t}`` (MATLAB ``wthresh``)."""
    return np.where(np.abs(d) > t, d, 0.0)


def band_limit(freq: float, level: int) -> float:
    """Upper frequency in Hz of the approximation after `level` levels: ``freq / 2^(level+1)``."""
    return check_freq(freq) / 2.0 ** (check_positive_int(level, name="level", minimum=0) + 1)


def level_for_frequency(freq: float, f_limit: float) -> int:
    """Smallest level k >= 1 whose approximation band ``freq / 2^(k+1)`` is at most `f_limit` Hz."""
    freq = check_freq(freq)
    f_limit = check_freq(f_limit, name="f_limit")
    if f_limit >= freq / 4.0:
        return 1
    return max(1, int(math.ceil(math.log2(freq / f_limit) - 1.0 - 1e-12)))


def _wavelet(wavelet: str | pywt.Wavelet) -> pywt.Wavelet:
    try:
        w = wavelet if isinstance(wavelet, pywt.Wavelet) else pywt.Wavelet(wavelet)
    except (ValueError, TypeError) as exc:
        raise InputError(f"unknown wavelet {wavelet!r}: {exc}") from None
    if not w.orthogonal:
        raise InputError(f"wavelet {w.name!r} is not orthogonal; use e.g. 'db4', 'sym8', 'haar'")
    return w


@attrs.frozen
class WaveletDenoising:
    """A de-noised signal with the thresholds that made it.

    Attributes
    ----------
    signal : ndarray, shape (n,)
        The de-noised signal, same length and unit as the input.
    level : int
        Number of decomposition levels.
    wavelet : str
        The pywt wavelet name.
    rule, mode, noise : str
        Threshold rule, ``"soft"``/``"hard"``, noise-scale option.
    thresholds : ndarray, shape (level,)
        Threshold applied at levels 1..level (finest first), in signal units.
    noise_sigma : ndarray, shape (level,)
        Noise scale of levels 1..level (1 for ``noise="none"``).
    freq : float or None
        Sampling frequency in Hz when given.
    """

    signal: np.ndarray = attrs.field(repr=False)
    level: int
    wavelet: str
    rule: str
    mode: str
    noise: str
    thresholds: np.ndarray
    noise_sigma: np.ndarray
    freq: float | None = None

    @property
    def band_limit(self) -> float | None:
        """Upper frequency of the kept approximation band, Hz (None without freq)."""
        return None if self.freq is None else band_limit(self.freq, self.level)

    def summary(self) -> str:
        """Thresholds per level."""
        rows = []
        for j, (t, s) in enumerate(zip(self.thresholds, self.noise_sigma), start=1):
            band = ("" if self.freq is None
                    else f"{self.freq / 2 ** (j + 1):.4g}-{self.freq / 2 ** j:.4g}")
            rows.append([j, band, s, t])
        title = (f"wavelet de-noising: {self.wavelet}, {self.level} level(s), {self.rule}, "
                 f"{self.mode}, noise={self.noise}")
        if self.freq is not None:
            title += f"; approximation keeps 0-{self.band_limit:.4g} Hz"
        headers = ["level", "detail band (Hz)", "noise sigma", "threshold"]
        return format_table(headers, rows, title=title)


def wavelet_denoise(
    x: ArrayLike,
    wavelet: str | pywt.Wavelet = "db4",
    level: int | None = None,
    rule: str | float = "rigrsure",
    mode: str = "soft",
    noise: str = "level",
    freq: float | None = None,
    f_limit: float | None = None,
    *,
    extension: str = "symmetric",
) -> WaveletDenoising:
    """De-noise a signal by thresholding its wavelet details; returns the thresholds too.

    Parameters are those of :func:`denoise`.
    """
    x = as_signal(x, name="x", min_length=2)
    w = _wavelet(wavelet)
    if mode not in _MODES:
        raise InputError(f"mode must be 'soft' or 'hard', got {mode!r}")
    if noise not in _NOISE:
        raise InputError(f"noise must be one of {_NOISE}, got {noise!r}")
    if isinstance(rule, str):
        if rule not in RULES:
            raise InputError(f"rule must be one of {RULES} or a non-negative number, got {rule!r}")
        fixed = None
    else:
        if isinstance(rule, bool) or not isinstance(rule, (int, float, np.floating, np.integer)):
            raise InputError(f"rule must be one of {RULES} or a non-negative number, got {rule!r}")
        fixed = float(rule)
        if not (math.isfinite(fixed) and fixed >= 0):
            raise InputError(f"a fixed threshold must be finite and >= 0, got {rule!r}")
    if extension not in pywt.Modes.modes:
        raise InputError(f"extension must be one of {pywt.Modes.modes}, got {extension!r}")
    if freq is not None:
        freq = check_freq(freq)
    top = pywt.dwt_max_level(x.size, w.dec_len)
    if level is not None and f_limit is not None:
        raise InputError("give either level or f_limit, not both")
    if f_limit is not None:
        if freq is None:
            raise InputError("f_limit (Hz) needs the sampling frequency freq")
        level = level_for_frequency(freq, f_limit)
    elif level is None:
        level = max(top, 1)
    level = check_positive_int(level, name="level")
    if level > top:
        raise InputError(
            f"level {level} is too deep for {x.size} samples with {w.name} (filter length "
            f"{w.dec_len}): at most {top}; use a longer record or fewer levels"
        )

    coeffs = pywt.wavedec(x, w, mode=extension, level=level)
    n_total = sum(c.size for c in coeffs)
    details = coeffs[:0:-1]  # finest (level 1) first
    sure_like = fixed is None and rule in ("rigrsure", "heursure")
    # |d| sorted once per level serves both the MAD noise scale and the SURE risk
    sorted_abs = [np.sort(np.abs(d)) for d in details] if sure_like else None

    def mad(j: int) -> float:
        if sorted_abs is None:
            return float(np.median(np.abs(details[j]))) / _MAD_FACTOR
        a = sorted_abs[j]
        m = a.size // 2
        return float(a[m] if a.size % 2 else (a[m - 1] + a[m]) / 2.0) / _MAD_FACTOR

    if noise == "level":
        sigma = np.array([mad(j) for j in range(level)])
    elif noise == "one":
        sigma = np.full(level, mad(0))
    else:
        sigma = np.ones(level)
    eps = math.sqrt(np.finfo(float).eps)
    thresholds = np.empty(level)
    shrink = soft_threshold if mode == "soft" else hard_threshold
    for j, d in enumerate(details):
        s = sigma[j]
        if fixed is not None:
            unit = fixed
        elif rule in ("sqtwolog", "minimaxi"):
            unit = select_threshold(d, rule, n_total=n_total)
        elif s == 0.0 or s < eps * float(sorted_abs[j][-1]):
            unit = 0.0  # wden's guard: no noise to speak of at this level
        else:
            sx2 = (sorted_abs[j] / s) ** 2  # = sort(|d / s|)^2 exactly
            unit = _sure_sorted(sx2) if rule == "rigrsure" else _heursure_sorted(sx2)
        thresholds[j] = unit * s
        coeffs[level - j] = shrink(d, thresholds[j])
    y = pywt.waverec(coeffs, w, mode=extension)[: x.size]
    return WaveletDenoising(
        signal=y, level=level, wavelet=w.name, rule=rule if fixed is None else f"fixed {fixed:g}",
        mode=mode, noise=noise, thresholds=thresholds, noise_sigma=sigma, freq=freq,
    )


def denoise(
    x: ArrayLike,
    wavelet: str | pywt.Wavelet = "db4",
    level: int | None = None,
    rule: str | float = "rigrsure",
    mode: str = "soft",
    noise: str = "level",
    freq: float | None = None,
    f_limit: float | None = None,
    *,
    extension: str = "symmetric",
) -> np.ndarray:
    """Wavelet de-noising of a 1-D signal (MATLAB ``wden`` conventions).

    Parameters
    ----------
    x : array_like, shape (n,)
        The signal in units u (any length).
    wavelet : str or pywt.Wavelet
        Any orthogonal pywt wavelet (Quinchia: ``"db4"``).
    level : int, optional
        Number of levels (LOD). Default: from `f_limit`, else the deepest level pywt allows
        (``pywt.dwt_max_level``, as MATLAB ``wdenoise``).
    rule : str or float
        ``"rigrsure"`` (SURE, Quinchia's choice), ``"sqtwolog"``, ``"heursure"``,
        ``"minimaxi"``, or a fixed threshold in noise units.
    mode : {"soft", "hard"}
        Thresholding.
    noise : {"level", "one", "none"}
        Noise scale per level (MAD/0.6745), once from the finest level, or none (unit).
    freq : float, optional
        Sampling frequency in Hz (needed with `f_limit`).
    f_limit : float, optional
        Keep the approximation band up to this frequency: the smallest level k with
        ``freq / 2^(k+1) <= f_limit`` (Quinchia Section 5.6, Table 7).
    extension : str
        pywt signal-extension mode (MATLAB's default ``"symmetric"``).

    Returns
    -------
    ndarray, shape (n,)
        The de-noised signal.
    """
    return wavelet_denoise(x, wavelet, level, rule, mode, noise, freq, f_limit,
                           extension=extension).signal


def denoise_then_ar(
    x: ArrayLike,
    freq: float,
    order: int | None = None,
    *,
    wavelet: str = "db4",
    level: int | None = 6,
    f_limit: float | None = None,
    rule: str | float = "rigrsure",
    mode: str = "soft",
    noise: str = "level",
    method: str = "burg",
    max_order: int = 10,
    criterion: str = "bic",
) -> Any:
    """De-noise, then fit an AR(p) on the de-noised signal (Quinchia Section 5.3, Table 2).

    Parameters
    ----------
    x : array_like, shape (n,)
        Static sensor error signal in units u.
    freq : float
        Sampling frequency in Hz.
    order : int, optional
        AR order (Quinchia: 1 and 3); None selects it by `criterion`.
    wavelet, level, f_limit, rule, mode, noise
        De-noising settings (default: db4, 6 levels, soft SURE, as in Quinchia Table 2).
    method, max_order, criterion
        Passed to :func:`stochmod.empirical.ar_fit.fit_ar`.

    Returns
    -------
    ARFit
        :func:`stochmod.fit.classical.ar_model` gives the AR(p) model.
    """
    from stochmod.empirical.ar_fit import fit_ar

    freq = check_freq(freq)
    if f_limit is not None:
        level = None
    y = denoise(x, wavelet, level, rule, mode, noise, freq, f_limit)
    return fit_ar(y, freq, order, max_order=max_order, method=method, criterion=criterion)


@attrs.frozen
class DenoisedAllan:
    """Allan variance of a signal before and after de-noising (Quinchia Fig. 17).

    Attributes
    ----------
    level : int
        Decomposition levels.
    band_limit : float
        Upper frequency of the kept band, Hz (``freq / 2^(level+1)``).
    tau_limit : float
        Cluster time ``2^(level+1) / freq`` s above which the de-noised Allan variance is
        expected to follow the raw one (Fig. 17's vertical lines: 0.16 s for 3 levels, 5.12 s for
        8 levels at 100 Hz).
    raw : object
        :func:`stochmod.empirical.allan.avar` of the input.
    denoised : object
        The same for the de-noised signal.
    denoising : WaveletDenoising
        Thresholds used.
    """

    level: int
    band_limit: float
    tau_limit: float
    raw: Any = attrs.field(repr=False)
    denoised: Any = attrs.field(repr=False)
    denoising: WaveletDenoising = attrs.field(repr=False)


def denoised_allan(
    x: ArrayLike,
    freq: float,
    *,
    wavelet: str = "db4",
    level: int | None = None,
    f_limit: float | None = None,
    rule: str | float = "rigrsure",
    mode: str = "soft",
    noise: str = "level",
    **avar_kwargs: Any,
) -> DenoisedAllan:
    """Allan variance of the de-noised signal next to that of the raw one (Quinchia Fig. 17).

    Parameters
    ----------
    x : array_like, shape (n,)
        Static sensor error signal in units u.
    freq : float
        Sampling frequency in Hz.
    wavelet, level, f_limit, rule, mode, noise
        De-noising settings (:func:`denoise`).
    **avar_kwargs
        Passed to :func:`stochmod.empirical.allan.avar`.
    """
    try:
        from stochmod.empirical.allan import avar
    except ImportError as exc:  # written by another part of the project
        raise ImportError(
            f"denoised_allan needs stochmod.empirical.allan.avar, which is not available: {exc}"
        ) from exc
    freq = check_freq(freq)
    x = as_signal(x, name="x")
    den = wavelet_denoise(x, wavelet, level, rule, mode, noise, freq, f_limit)
    return DenoisedAllan(
        level=den.level, band_limit=band_limit(freq, den.level),
        tau_limit=2.0 ** (den.level + 1) / freq, raw=avar(x, freq, **avar_kwargs),
        denoised=avar(den.signal, freq, **avar_kwargs), denoising=den,
    )
