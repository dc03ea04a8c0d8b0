"""Figures of fitted models (matplotlib, optional: ``pip install "stochmod[plots]"``).

:func:`plot_fit` draws the validation figure of Stebler et al. (2014, Fig. 5, upper panels):
the empirical Haar wavelet variance with its confidence interval, the fitted model's
theoretical WV, and the WVs of synthetic series simulated from the fit. Figures are built
with matplotlib's object API (no pyplot state, no display needed).

:func:`plot_allan` draws an Allan deviation in datasheet units (deg/h for a gyroscope, ug or
mg for a coarse accelerometer, :func:`allan_unit`): the data with their interval, a model's curve,
the white-plus-random-walk bound ``N^2/tau + K^2 tau/3`` of an export; :func:`allan_figure`
puts one such panel per axis on a grid.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import attrs
import numpy as np

from stochmod.core.checks import check_positive_int
from stochmod.core.errors import InputError
from stochmod.core.plotting import log_grid
from stochmod.core.process import as_generator
from stochmod.core.units import convert, parse_unit
from stochmod.empirical.wavelet_variance import same_estimator

if TYPE_CHECKING:
    from stochmod.fit.results import GMWMResult

__all__ = ["AllanCurves", "allan_figure", "allan_unit", "plot_allan", "plot_fit",
           "save_fit_figure", "simulated_wv"]

FIGSIZE = (6.4, 4.8)  # inches
#: Fixed margins of a new figure, as fractions of :data:`FIGSIZE`, wide enough for the
#: log-axis tick labels, a unit in the y label and a one-line title. (``tight_layout``
#: measures every text first: a second layout pass, about as long as drawing the figure.)
MARGINS = {"left": 0.12, "right": 0.97, "bottom": 0.1, "top": 0.93}


def _figure_class() -> Any:
    try:
        from matplotlib.figure import Figure
    except ImportError:
        raise ImportError('figures need matplotlib: pip install "stochmod[plots]"') from None
    return Figure


def _axes(ax: Any) -> Any:
    """`ax`, or the axes of a new Figure of :data:`FIGSIZE` with :data:`MARGINS`."""
    if ax is not None:
        return ax
    fig = _figure_class()(figsize=FIGSIZE)
    fig.subplots_adjust(**MARGINS)
    return fig.add_subplot()


def simulated_wv(fit: GMWMResult, n_sim: int = 20, rng: np.random.Generator | int = 0,
                 n: int | None = None, *, indices: slice | None = None) -> np.ndarray:
    """Empirical WVs of `n_sim` series simulated from the fitted model, by the estimator of
    the fit's own WV (:func:`~stochmod.empirical.wavelet_variance.same_estimator`: robust for
    a robust fit).

    Parameters
    ----------
    fit : GMWMResult
        The fit.
    n_sim : int
        Number of synthetic series.
    rng : Generator or int
        Seed (each series draws from its own child generator).
    n : int, optional
        Length of each series (default: the length of the fitted signal).
    indices : slice, optional
        Only these of the `n_sim` series (default: all). Series i always draws from the i-th
        of the `n_sim` child generators spawned from `rng`, so with an integer seed, calls over
        disjoint slices (e.g. in parallel) stack to the full set.

    Returns
    -------
    ndarray (n_sim, J), or (number of `indices`, J)
        Wavelet variances at the fitted levels, unit^2.
    """
    n_sim = check_positive_int(n_sim, name="n_sim")
    n = fit.empirical.n if n is None else check_positive_int(n, name="n")
    children = as_generator(rng).spawn(n_sim)
    if indices is not None:
        children = children[indices]
    return np.array([same_estimator(fit.model.simulate(n, g), fit.empirical, fit.levels).wv
                     for g in children]).reshape(-1, fit.levels)


def plot_fit(fit: GMWMResult, *, n_sim: int = 20, rng: np.random.Generator | int = 0,
             title: str | None = None, unit: str = "u", ax: Any = None,
             simulated: np.ndarray | None = None) -> Any:
    """Validation figure of a GMWM fit: empirical WV (95% CI), model WV, simulated WVs.

    Parameters
    ----------
    fit : GMWMResult
        The fit to show.
    n_sim : int
        Number of series simulated from the fit (0: none).
    rng : Generator or int
        Seed of the simulations.
    title : str, optional
        Axes title (default: the model name).
    unit : str
        Signal unit for the axis label.
    ax : matplotlib Axes, optional
        Draw into these axes; by default a new Figure is created.
    simulated : ndarray (k, J), optional
        The simulated WVs to draw, already computed (:func:`simulated_wv`, e.g. in parallel);
        `n_sim` and `rng` are then not used.

    Returns
    -------
    matplotlib.figure.Figure
    """
    ax = _axes(ax)
    fig = ax.figure
    emp, J = fit.empirical, fit.levels
    tau = emp.tau[:J]
    if simulated is None:
        simulated = simulated_wv(fit, n_sim, rng) if n_sim else np.empty((0, J))
    elif np.shape(simulated)[1:] != (J,):
        raise InputError(f"simulated must hold rows of {J} wavelet variances (the fit's levels), "
                         f"got shape {np.shape(simulated)}")
    for i, wv in enumerate(simulated):
        ax.loglog(tau, wv, color="0.75", lw=0.8,
                  label=f"{len(simulated)} simulations from fit" if i == 0 else None)
    ax.fill_between(tau, emp.ci_low[:J], emp.ci_high[:J], color="C0", alpha=0.25,
                    label=f"{100 * (1 - emp.alpha):g}% CI")
    ax.loglog(tau, emp.wv[:J], "o", color="C0", ms=4, label="empirical WV")
    ax.loglog(tau, fit.model_wv(), "^-", color="C3", ms=4, lw=1.2, label=f"model {fit.model.name}")
    ax.set_xlabel("averaging time tau [s]")
    squared = f"({unit})^2" if "/" in unit or "*" in unit else f"{unit}^2"
    ax.set_ylabel(f"Haar wavelet variance [{squared}]")
    # an explicit y: no search for overlapping tick labels at every draw
    ax.set_title(title or f"GMWM fit: {fit.model.name}", y=1.0)
    log_grid(ax)
    ax.legend(fontsize="small")
    return fig


def save_fit_figure(fit: GMWMResult, path: str | Path, **kwargs: Any) -> Path:
    """Draw :func:`plot_fit` and save it to `path` (format from the suffix, PNG by default)."""
    path = Path(path)
    fig = plot_fit(fit, **kwargs)
    fig.savefig(path, dpi=110)
    return path


#: Datasheet unit of an Allan deviation by the physical kind of the signal; an accelerometer's
#: switches from ug to mg where its whole curve lies above :data:`_MG_FROM` ug.
ALLAN_UNITS = {"rate": "deg/h", "acceleration": "ug"}
_MG_FROM = 1000.0


def allan_unit(unit: str, adev: Any = ()) -> str:
    """The unit an Allan deviation of a signal in `unit` is drawn in: deg/h for a rate,
    ug for an acceleration (the unit of its bias instability; mg when even the minimum of
    `adev`, in `unit`, reaches 1000 ug), `unit` itself for anything else (an unknown unit
    too)."""
    try:
        kind = parse_unit(unit).kind
    except InputError:
        return unit
    shown = ALLAN_UNITS.get(kind)
    if shown is None:
        return unit
    values = np.asarray(adev, dtype=float)
    values = values[np.isfinite(values) & (values > 0)]
    if kind == "acceleration" and values.size and (
            float(convert(np.min(values), unit, "ug")) >= _MG_FROM):
        return "mg"
    return shown


@attrs.frozen(eq=False)
class AllanCurves:
    """What one Allan-deviation panel shows, every value in the signal unit `unit` (SI).

    Attributes
    ----------
    column : str
        Axis name (the panel's title, with `model_name`).
    unit : str
        Signal unit (``"rad/s"``, ``"m/s^2"``).
    tau, adev, low, high : ndarray or None
        The data's Allan deviation and its interval at averaging times `tau` (s).
    model_tau, model_adev : ndarray or None
        The model's Allan deviation.
    model_name : str
    noise_density, random_walk : float or None
        N (u/sqrt(Hz)) and K (u/sqrt(s)) of an export: drawn as the deviation of
        ``N^2/tau + K^2 tau/3``.
    horizon : float or None
        The export's horizon H, s (a vertical line: the range it bounds the model over).
    minimum : tuple of float or None
        ``(tau, adev)`` of the model's Allan minimum (the bias instability's point).
    band_tau, band_low, band_high : ndarray or None
        A band of simulated Allan deviations.
    band_label : str
    """

    column: str
    unit: str
    tau: np.ndarray | None = None
    adev: np.ndarray | None = None
    low: np.ndarray | None = None
    high: np.ndarray | None = None
    model_tau: np.ndarray | None = None
    model_adev: np.ndarray | None = None
    model_name: str = ""
    noise_density: float | None = None
    random_walk: float | None = None
    horizon: float | None = None
    minimum: tuple[float, float] | None = None
    band_tau: np.ndarray | None = None
    band_low: np.ndarray | None = None
    band_high: np.ndarray | None = None
    band_label: str = "simulations (95%)"

    def taus(self) -> np.ndarray:
        """Every averaging time the panel draws at."""
        parts = [np.asarray(t, dtype=float) for t in (self.tau, self.model_tau, self.band_tau)
                 if t is not None]
        return np.concatenate(parts) if parts else np.empty(0)


def _shown(values: Any, unit: str, shown: str) -> np.ndarray:
    if shown == unit:
        return np.asarray(values, dtype=float)
    return np.asarray(convert(np.asarray(values, dtype=float), unit, shown), dtype=float)


def plot_allan(curves: AllanCurves, ax: Any = None, *, legend: bool = True,
               unit: str | None = None) -> Any:
    """An Allan deviation in datasheet units: data (95 % interval), model, export bound.

    Parameters
    ----------
    curves : AllanCurves
        What to draw (SI).
    ax : matplotlib Axes, optional
        Draw into these axes; by default a new Figure is created.
    legend : bool
        Draw the legend.
    unit : str, optional
        Unit of the y axis (default :func:`allan_unit` of the curves).

    Returns
    -------
    matplotlib.figure.Figure
    """
    ax = _axes(ax)
    c, u = curves, curves.unit
    ref = c.adev if c.adev is not None else c.model_adev
    shown = unit or allan_unit(u, () if ref is None else ref)
    if c.band_tau is not None and c.band_low is not None and c.band_high is not None:
        ax.fill_between(c.band_tau, _shown(c.band_low, u, shown), _shown(c.band_high, u, shown),
                        color="0.8", label=c.band_label)
    if c.tau is not None and c.adev is not None:
        if c.low is not None and c.high is not None:
            ax.fill_between(c.tau, _shown(c.low, u, shown), _shown(c.high, u, shown), color="C0",
                            alpha=0.3, label="data 95% CI")
        ax.loglog(c.tau, _shown(c.adev, u, shown), ".", color="C0", ms=3, label="data ADEV")
    if c.model_tau is not None and c.model_adev is not None:
        ax.loglog(c.model_tau, _shown(c.model_adev, u, shown), "-", color="C3",
                  label=f"model {c.model_name}".strip())
    if c.minimum is not None:
        ax.loglog([c.minimum[0]], _shown([c.minimum[1]], u, shown), "v", color="C3", ms=6,
                  label="model minimum (bias instability)")
    taus = c.taus()
    if c.noise_density is not None and c.random_walk is not None and taus.size:
        t = np.geomspace(float(np.min(taus)), float(np.max(taus)), 200)
        bound = np.sqrt(c.noise_density ** 2 / t + c.random_walk ** 2 * t / 3.0)
        ax.loglog(t, _shown(bound, u, shown), "--", color="k", lw=1.0,
                  label="exported N\u00b2/\u03c4 + K\u00b2\u03c4/3")
        if c.horizon is not None:
            ax.axvline(c.horizon, color="0.4", ls=":", lw=1.0, label="export horizon H")
    ax.set_xlabel("averaging time tau [s]")
    ax.set_ylabel(f"Allan deviation [{shown}]")
    ax.set_title(f"{c.column}: {c.model_name}" if c.model_name else c.column, fontsize="medium",
                 y=1.0)
    log_grid(ax)
    if legend:
        ax.legend(fontsize="x-small")
    return ax.figure


def allan_figure(panels: Sequence[AllanCurves], ncols: int = 3, *,
                 panel_size: tuple[float, float] = (3.7, 3.0)) -> Any:
    """One Allan-deviation panel per axis (:func:`plot_allan`) on a grid of `ncols` columns,
    one legend under the grid.

    Returns
    -------
    matplotlib.figure.Figure
    """
    if not panels:
        raise InputError("allan_figure needs at least one panel")
    ncols = max(1, min(check_positive_int(ncols, name="ncols"), len(panels)))
    nrows = math.ceil(len(panels) / ncols)
    legend_height = 0.35  # inches
    height = panel_size[1] * nrows + legend_height
    fig = _figure_class()(figsize=(panel_size[0] * ncols, height))
    grid = fig.subplots(nrows, ncols, squeeze=False)
    labels: dict[str, Any] = {}
    for k, ax in enumerate(grid.flat):
        if k < len(panels):
            plot_allan(panels[k], ax, legend=False)
            for handle, label in zip(*ax.get_legend_handles_labels()):
                if not label.startswith("model ") or label.startswith("model minimum"):
                    labels.setdefault(label, handle)
                else:
                    labels.setdefault("final model", handle)
        else:
            ax.set_axis_off()
    fig.legend(list(labels.values()), list(labels), loc="lower center", ncol=len(labels),
               fontsize="small", frameon=False)
    # fixed margins in inches (tight_layout measures every text first: a second layout pass)
    width = panel_size[0] * ncols
    fig.subplots_adjust(left=0.75 / width, right=1.0 - 0.15 / width,
                        bottom=(legend_height + 0.5) / height, top=1.0 - 0.3 / height,
                        wspace=0.32, hspace=1.35 / panel_size[1])
    return fig
