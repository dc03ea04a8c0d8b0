"""Figures of fitted models (matplotlib, optional: ``pip install "stochmod[plots]"``).

:func:`plot_fit` draws the validation figure of Stebler et al. (2014, Fig. 5, upper panels):
the empirical Haar wavelet variance with its confidence interval, the fitted model's
theoretical WV, and the WVs of synthetic series simulated from the fit. Figures are built
with matplotlib's object API (no pyplot state, no display needed).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from stochmod.core.checks import check_positive_int
from stochmod.core.errors import InputError
from stochmod.core.process import as_generator
from stochmod.empirical.wavelet_variance import wvar

if TYPE_CHECKING:
    from stochmod.fit.results import GMWMResult

__all__ = ["plot_fit", "save_fit_figure", "simulated_wv"]

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


def simulated_wv(fit: GMWMResult, n_sim: int = 20, rng: np.random.Generator | int = 0,
                 n: int | None = None, *, indices: slice | None = None) -> np.ndarray:
    """Empirical Haar WVs of `n_sim` series simulated from the fitted model.

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
    freq, J = fit.model.freq, fit.levels
    return np.array([wvar(fit.model.simulate(n, g), freq, levels=J,
                          wavelet=fit.empirical.wavelet).wv for g in children]).reshape(-1, J)


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
    if ax is None:
        fig = _figure_class()(figsize=FIGSIZE)
        fig.subplots_adjust(**MARGINS)
        ax = fig.add_subplot()
    else:
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
    ax.set_title(title or f"GMWM fit: {fit.model.name}")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small")
    return fig


def save_fit_figure(fit: GMWMResult, path: str | Path, **kwargs: Any) -> Path:
    """Draw :func:`plot_fit` and save it to `path` (format from the suffix, PNG by default)."""
    path = Path(path)
    fig = plot_fit(fit, **kwargs)
    fig.savefig(path, dpi=110)
    return path
