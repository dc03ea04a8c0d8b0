"""Validation of a fitted model (Stebler et al. 2014, Section V-D, Fig. 5) and the octave-band
PSD read off a wavelet variance (Section III-D, eqs. 31-33).

:func:`validate` simulates ``R`` series of the data's length from the model (Fig. 5 uses 20)
and compares their Haar WVs and Welch PSDs with the data's: a fitted model is credible when
the data's WV lies inside the simulations' band at (about) every level.

:func:`octave_psd` turns a WV into a piecewise-constant PSD: by eq. 30 the level-j WV holds
the power of the octave ``[1/(2^{j+1} dt), 1/(2^j dt)]`` (both signs of f), so the
two-sided PSD level of that octave is ``C_j = 2^j v_j dt`` (eq. 33, with ``dt = 1/freq``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import attrs
import numpy as np
from numpy.typing import ArrayLike

from stochmod.core.fields import array_field
from stochmod.core.checks import as_signal, check_freq, check_positive_int
from stochmod.core.errors import InputError
from stochmod.core.plotting import log_grid
from stochmod.fit.engine import resolve_model
from stochmod.fit.results import GMWMResult
from stochmod.core.model import Model
from stochmod.core.process import Process, as_generator, has_theoretical_wv
from stochmod.core.tables import format_table
from stochmod.empirical.psd import psd as welch_psd
from stochmod.empirical.wavelet_variance import WaveletVariance, same_estimator, wvar

__all__ = ["ValidationBands", "validate", "OctavePSD", "octave_psd"]

#: Central probability of the percentile band of the simulations.
BAND_LEVEL = 0.95


def _figure_class() -> Any:
    try:
        from matplotlib.figure import Figure
    except ImportError:
        raise ImportError('plots need matplotlib: pip install "stochmod[plots]"') from None
    return Figure


# --------------------------------------------------------------------------- octave PSD
@attrs.frozen
class OctavePSD:
    """Piecewise-constant PSD over octave bands from a wavelet variance (eqs. 31-33).

    Attributes
    ----------
    levels : ndarray of int (J,)
        Levels j = 1..J.
    f_low, f_high : ndarray (J,)
        Band edges ``freq / 2^(j+1)`` and ``freq / 2^j``, Hz (level 1 ends at Nyquist).
    level : ndarray (J,)
        Two-sided PSD level ``C_j = 2^j v_j / freq``, u^2/Hz (integral over both signs of f
        of the piecewise-constant PSD over the band = ``v_j``, eq. 30).
    ci_low, ci_high : ndarray (J,) or None
        The WV's confidence interval mapped the same way (None for a bare array).
    freq : float
        Sampling frequency, Hz.
    """

    levels: np.ndarray = array_field(repr=False)
    f_low: np.ndarray = array_field(repr=False)
    f_high: np.ndarray = array_field(repr=False)
    level: np.ndarray = array_field(repr=False)
    freq: float
    ci_low: np.ndarray | None = array_field(default=None, repr=False)
    ci_high: np.ndarray | None = array_field(default=None, repr=False)

    @property
    def one_sided(self) -> np.ndarray:
        """One-sided level ``2 C_j`` (IEEE plots, :func:`stochmod.psd`), u^2/Hz."""
        return 2.0 * self.level

    def steps(self, one_sided: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Edges (J + 1, Hz, increasing) and levels (J, u^2/Hz, low to high frequency) for
        ``matplotlib.axes.Axes.stairs``."""
        values = (self.one_sided if one_sided else self.level)[::-1]
        return np.append(self.f_low[::-1], self.f_high[0]), values

    def summary(self) -> str:
        """Table of the octave bands and their two- and one-sided levels."""
        rows = [[int(j), lo, hi, c, 2 * c] for j, lo, hi, c in
                zip(self.levels, self.f_low, self.f_high, self.level)]
        return format_table(["level", "f low [Hz]", "f high [Hz]", "S two-sided [u^2/Hz]",
                             "G one-sided [u^2/Hz]"], rows,
                            title=f"Octave-band PSD from the wavelet variance (eq. 33, freq = {self.freq:g} Hz)")


def octave_psd(wv: WaveletVariance | ArrayLike, freq: float | None = None) -> OctavePSD:
    """Octave-band PSD levels ``C_j = 2^j v_j dt`` from a wavelet variance (eqs. 31-33).

    Parameters
    ----------
    wv : WaveletVariance or array_like
        Empirical WV (its interval is mapped too), or WVs at levels 1..J in u^2 (e.g. a
        model's ``model.wv(J)``).
    freq : float, optional
        Sampling frequency ``1/dt``, Hz (required for an array; checked against a
        WaveletVariance's).

    Returns
    -------
    OctavePSD
        Band edges (Hz) and two-sided levels (u^2/Hz). For white noise of variance s2 per
        sample the level is exactly ``s2 / freq`` at every j; for other spectra it is the band
        average times the Haar leakage factor (1 for a flat spectrum, ``pi^2/6`` for ``1/f^2``
        far from the ends; see docs/gmwm.md).
    """
    ci = None
    if isinstance(wv, WaveletVariance):
        if freq is not None and check_freq(freq) != wv.freq:
            raise InputError(f"freq = {freq} Hz but the wavelet variance was taken at {wv.freq} Hz")
        freq, v, j = wv.freq, np.asarray(wv.wv, float), np.asarray(wv.levels, int)
        ci = (wv.ci_low, wv.ci_high)
    else:
        if freq is None:
            raise InputError("freq (Hz) is required when wv is an array")
        freq = check_freq(freq)
        v = as_signal(wv, name="wv", min_length=1)
        j = np.arange(1, v.size + 1)
    if np.any(v <= 0):
        raise InputError("wv must be positive at every level")
    scale = 2.0 ** j / freq
    return OctavePSD(levels=j, f_low=freq / 2.0 ** (j + 1), f_high=freq / 2.0**j, level=scale * v,
                     freq=freq, ci_low=None if ci is None else scale * ci[0],
                     ci_high=None if ci is None else scale * ci[1])


# --------------------------------------------------------------------------- validation
@attrs.frozen
class ValidationBands:
    """The data's WV and PSD against those of `R` series simulated from the model (Fig. 5).

    Attributes
    ----------
    model : Model
        The validated model (all values given, bound to `freq`).
    freq : float
        Sampling frequency, Hz.
    n : int
        Data length N (and length of every simulation), samples.
    R : int
        Number of simulations.
    tau : ndarray (J,)
        Averaging times ``2^(j-1)/freq``, s.
    wv, ci_low, ci_high : ndarray (J,)
        The data's WV and its confidence interval, u^2.
    model_wv : ndarray (J,)
        The model's theoretical WV (when a family has none: the mean of the simulations), u^2.
    sim_wv : ndarray (R, J)
        WVs of the simulations, u^2.
    band_min, band_max : ndarray (J,)
        Their minimum and maximum per level.
    band_low, band_high : ndarray (J,)
        Their 2.5 % and 97.5 % percentiles per level.
    coverage : float
        Fraction of levels whose data WV lies in ``[band_low, band_high]``.
    f : ndarray (F,) or None
        Welch frequencies, Hz (None when only a WV was given).
    psd : ndarray (F,) or None
        The data's one-sided Welch PSD (:func:`stochmod.psd`), u^2/Hz.
    model_psd : ndarray (F,) or None
        The model's one-sided PSD ``2 S(f)`` where every family declares one.
    sim_psd : ndarray (R, F) or None
        One-sided Welch PSDs of the simulations (same segments and window).
    psd_low, psd_high : ndarray (F,) or None
        Their 2.5 % and 97.5 % percentiles.
    psd_coverage : float or None
        Fraction of frequencies whose data PSD lies in ``[psd_low, psd_high]``.
    wavelet : str
        Wavelet of the WVs.
    alpha : float
        Significance level of the data's WV interval.
    """

    model: Model
    freq: float
    n: int
    R: int
    tau: np.ndarray = array_field(repr=False)
    wv: np.ndarray = array_field(repr=False)
    ci_low: np.ndarray = array_field(repr=False)
    ci_high: np.ndarray = array_field(repr=False)
    model_wv: np.ndarray = array_field(repr=False)
    sim_wv: np.ndarray = array_field(repr=False)
    band_min: np.ndarray = array_field(repr=False)
    band_max: np.ndarray = array_field(repr=False)
    band_low: np.ndarray = array_field(repr=False)
    band_high: np.ndarray = array_field(repr=False)
    coverage: float
    wavelet: str = "haar"
    alpha: float = 0.05
    f: np.ndarray | None = array_field(default=None, repr=False)
    psd: np.ndarray | None = array_field(default=None, repr=False)
    model_psd: np.ndarray | None = array_field(default=None, repr=False)
    sim_psd: np.ndarray | None = array_field(default=None, repr=False)
    psd_low: np.ndarray | None = array_field(default=None, repr=False)
    psd_high: np.ndarray | None = array_field(default=None, repr=False)
    psd_coverage: float | None = None

    @property
    def inside(self) -> np.ndarray:
        """Per level: whether the data's WV lies in the 95 % band of the simulations."""
        return (self.wv >= self.band_low) & (self.wv <= self.band_high)

    def summary(self) -> str:
        """Table per level (data WV and CI, model WV, simulation band) and the coverages."""
        rows = [[j + 1, t, v, lo, hi, m, bl, bh, "yes" if ok else "NO"] for j, (t, v, lo, hi, m, bl, bh, ok)
                in enumerate(zip(self.tau, self.wv, self.ci_low, self.ci_high, self.model_wv,
                                 self.band_low, self.band_high, self.inside))]
        pct = f"{100 * (1 - self.alpha):g}%"
        table = format_table(
            ["level", "tau [s]", "data WV", f"{pct} low", f"{pct} high", "model WV",
             "sim 2.5%", "sim 97.5%", "inside"], rows,
            title=(f"Validation of {self.model.name} by {self.R} simulations of N = {self.n} "
                   f"(freq = {self.freq:g} Hz, {self.wavelet} WV)"))
        lines = [table, f"WV coverage: {self.coverage:.0%} of levels inside the simulations' 95% band"]
        if self.psd_coverage is not None:
            lines.append(f"PSD coverage: {self.psd_coverage:.0%} of Welch frequencies inside the band")
        return "\n".join(lines)

    def plot(self, ax: Any = None, *, unit: str = "u") -> Any:
        """Fig. 5 of Stebler et al. (2014): WV panel (data and CI, model, simulations) and,
        when the signal was given, PSD panel (data, simulations' band, model, octave levels).

        Parameters
        ----------
        ax : matplotlib Axes or pair of Axes, optional
            One Axes: the WV panel only; two: WV and PSD. Default: a new Figure with both.
        unit : str
            Signal unit for the axis labels.

        Returns
        -------
        matplotlib.figure.Figure
        """
        if ax is None:
            rows = 1 if self.f is None else 2
            fig = _figure_class()(figsize=(6.4, 4.0 * rows))
            axes = [fig.add_subplot(rows, 1, k + 1) for k in range(rows)]
        else:
            axes = list(ax) if isinstance(ax, Sequence) or isinstance(ax, np.ndarray) else [ax]
            fig = axes[0].figure
        self._plot_wv(axes[0], unit)
        if len(axes) > 1 and self.f is not None:
            self._plot_psd(axes[1], unit)
        return fig

    def _plot_wv(self, ax: Any, unit: str) -> None:
        for i, sim in enumerate(self.sim_wv):
            ax.loglog(self.tau, sim, color="0.75", lw=0.8,
                      label=f"{self.R} simulations of the model" if i == 0 else None)
        err = np.vstack([self.wv - self.ci_low, self.ci_high - self.wv])
        ax.errorbar(self.tau, self.wv, yerr=err, fmt="o", color="k", ms=4, capsize=2,
                    label=f"data WV, {100 * (1 - self.alpha):g}% CI")
        ax.loglog(self.tau, self.model_wv, "^-", color="0.35", ms=5, lw=1.0, label=f"model {self.model.name}")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("averaging time tau [s]")
        ax.set_ylabel(f"wavelet variance [{unit}^2]")
        ax.set_title(f"WV coverage {self.coverage:.0%}")
        log_grid(ax)
        ax.legend(fontsize="small")

    def _plot_psd(self, ax: Any, unit: str) -> None:
        ax.fill_between(self.f, self.psd_low, self.psd_high, color="0.8",
                        label=f"{self.R} simulations, 95% band")
        ax.loglog(self.f, self.psd, color="k", lw=0.8, label="data (Welch)")
        if self.model_psd is not None:
            ax.loglog(self.f, self.model_psd, color="0.35", lw=1.2, ls="--", label="model")
        edges, values = octave_psd(self.wv, self.freq).steps()
        ax.stairs(values, edges, baseline=None, color="C3", lw=1.2, label="octave levels of the data WV (eq. 33)")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("frequency [Hz]")
        ax.set_ylabel(f"one-sided PSD [{unit}^2/Hz]")
        log_grid(ax)
        ax.legend(fontsize="small")


def _model_psd(model: Model, f: np.ndarray) -> np.ndarray | None:
    """One-sided model PSD on Welch's frequencies (``2 S``; ``S`` at Nyquist, as Welch does)."""
    try:
        with np.errstate(all="ignore"):
            S = model.psd(f)
    except (NotImplementedError, ValueError):
        return None
    out = np.where(np.isclose(f, model.freq / 2.0, rtol=1e-12), 1.0, 2.0) * S
    return out if np.all(np.isfinite(out)) else None


def _band(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    tail = 50.0 * (1.0 - BAND_LEVEL)
    return np.percentile(values, tail, axis=0), np.percentile(values, 100.0 - tail, axis=0)


def validate(
    fit_or_model: GMWMResult | Model | Process | str | dict,
    x_or_wv: ArrayLike | WaveletVariance | None = None,
    freq: float | None = None,
    R: int = 20,
    rng: np.random.Generator | int = 0,
    levels: int | None = None,
    *,
    psd: bool = True,
    simulated: ArrayLike | None = None,
) -> ValidationBands:
    """Compare the data with `R` simulations of the model (Fig. 5 of Stebler et al. 2014).

    Parameters
    ----------
    fit_or_model : GMWMResult, Model, Process, str or dict
        A fit (its model is used), or a model with every value given.
    x_or_wv : array_like or WaveletVariance, optional
        The signal (u), or only its WV (then no PSD panel). Default: the fit's own data. A
        signal's WV, and every simulation's, is taken by the estimator of the fit's WV (robust
        for a robust fit, with its chi function and efficiency); with a WV, by that WV's.
    freq : float, optional
        Sampling frequency, Hz (default: the model's or the WV's).
    R : int
        Number of simulated series (>= 2), each of the data's length N.
    rng : Generator or int
        Seed of the simulations (each series from its own child generator).
    levels : int, optional
        Number of WV levels (default: the fit's, else all the data allow).
    psd : bool
        Compare the Welch PSDs too when the signal is given (default); False: the WVs only,
        without the PSD of every simulated series.
    simulated : array_like (R, J), optional
        The WVs of the `R` simulations when already computed, e.g. for the figure of the same
        fit (:func:`stochmod.output.plots.simulated_wv` with the same `R` and seed); no series
        is then simulated again unless the PSDs are compared.

    Returns
    -------
    ValidationBands
        WVs and PSDs of data, model and simulations, bands, coverages, ``summary()``,
        ``plot()``.
    """
    fit = fit_or_model if isinstance(fit_or_model, GMWMResult) else None
    if fit is not None:
        model = fit.model
        if x_or_wv is None:
            x_or_wv = fit.signal if fit.signal is not None else fit.empirical
        if levels is None:
            levels = fit.levels
    else:
        if x_or_wv is None:
            raise InputError("x_or_wv (the signal or its wavelet variance) is required with a model")
        model = fit_or_model
    if isinstance(x_or_wv, WaveletVariance):
        emp, signal = x_or_wv, None
        data_freq = emp.freq
    else:
        signal, emp = as_signal(x_or_wv, name="x_or_wv", min_length=8), None
        data_freq = None
    model_freq = model.freq if isinstance(model, Model) else None
    known = [f for f in (data_freq, model_freq) if f is not None]
    if freq is None:
        if not known:
            raise InputError("freq (Hz) is required: neither the model nor the data carry one")
        freq = known[0]
    freq = check_freq(freq)
    if any(f != freq for f in known):
        raise InputError(f"freq = {freq} Hz disagrees with the model's or the data's ({known} Hz)")
    model = resolve_model(model, freq)
    model.vector()  # SpecError when a parameter is free: fit the model first
    R = check_positive_int(R, name="R", minimum=2)
    wavelet = emp.wavelet if emp is not None else (fit.empirical.wavelet if fit is not None else "haar")
    if emp is None:  # the data's WV by the estimator the fit used (robust for a robust fit)
        emp = (wvar(signal, freq, wavelet=wavelet, levels=levels) if fit is None
               else same_estimator(signal, fit.empirical, levels))
    J = emp.wv.size if levels is None else check_positive_int(levels, name="levels")
    if J > emp.wv.size:
        raise InputError(f"levels = {J} but the wavelet variance has {emp.wv.size} levels")
    n = emp.n
    spec = None if signal is None or not psd else welch_psd(signal, freq)
    if simulated is not None:
        simulated = np.asarray(simulated, dtype=np.float64)
        if simulated.shape != (R, J):
            raise InputError(f"simulated must hold R = {R} rows of {J} wavelet variances, got "
                             f"shape {simulated.shape}")

    sim_wv, sim_psd = [], []
    if simulated is None or spec is not None:
        for g in as_generator(rng).spawn(R):
            y = model.simulate(n, g)
            if simulated is None:
                sim_wv.append(same_estimator(y, emp, J).wv)
            if spec is not None:
                sim_psd.append(welch_psd(y, freq, nperseg=spec.nperseg, window=spec.window).psd)
    sim_wv = np.array(sim_wv) if simulated is None else simulated
    if all(has_theoretical_wv(p) for p in model.processes):
        model_wv = model.wv(J, wavelet)
    else:
        model_wv = sim_wv.mean(axis=0)
    low, high = _band(sim_wv)
    data = np.asarray(emp.wv[:J], float)
    extra: dict[str, Any] = {}
    if spec is not None:
        sims = np.array(sim_psd)
        plo, phi = _band(sims)
        extra = dict(f=spec.f, psd=spec.psd, model_psd=_model_psd(model, spec.f), sim_psd=sims,
                     psd_low=plo, psd_high=phi,
                     psd_coverage=float(np.mean((spec.psd >= plo) & (spec.psd <= phi))))
    return ValidationBands(
        model=model, freq=freq, n=n, R=R, tau=np.asarray(emp.tau[:J], float), wv=data,
        ci_low=np.asarray(emp.ci_low[:J], float), ci_high=np.asarray(emp.ci_high[:J], float),
        model_wv=model_wv, sim_wv=sim_wv, band_min=sim_wv.min(axis=0), band_max=sim_wv.max(axis=0),
        band_low=low, band_high=high, coverage=float(np.mean((data >= low) & (data <= high))),
        wavelet=wavelet, alpha=emp.alpha, **extra,
    )
