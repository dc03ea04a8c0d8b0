"""``stochmod allan``: Allan variance and its IEEE 952 slope reading for each column."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from stochmod.cli._common import add_input_arguments, load_input, print_json
from stochmod.core.errors import InputError
from stochmod.core.plotting import log_grid
from stochmod.empirical.allan import KINDS, AllanVariance, avar
from stochmod.empirical.allan_reading import AllanReading, allan_reading

__all__ = ["register", "run", "plot_reading"]


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``allan`` subcommand."""
    p = subparsers.add_parser(
        "allan",
        help="Allan variance with intervals and its slope reading (N, B, K, Q, R)",
        description=(
            "Allan variance (or Hadamard / modified variance) of each column at the chosen "
            "averaging times, with equivalent-degrees-of-freedom intervals, followed by the "
            "IEEE Std 952 slope reading of the overlapping Allan variance on a dense log grid: "
            "Q (u*s), N (u*sqrt(s)), B (u), K (u/sqrt(s)), R (u/s) with intervals, and Tc. "
            "u is the column's unit; give it with --unit for datasheet values."
        ),
    )
    add_input_arguments(p)
    p.add_argument("--kind", choices=tuple(KINDS), default="overlapping",
                   help="variance of the table (default overlapping; the reading always uses "
                        "the overlapping Allan variance unless this is non-overlapping)")
    p.add_argument("--taus", choices=("octave", "decade", "all"), default="octave",
                   help="averaging times of the table (default octave)")
    p.add_argument("--alpha", type=float, default=0.05,
                   help="significance level of the intervals (default 0.05)")
    p.add_argument("--plot", default=None, metavar="OUT.png",
                   help="save a log-log Allan deviation plot with intervals and fitted lines "
                        "(needs matplotlib)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Compute, print (table or JSON) and optionally plot every selected column."""
    if args.plot:
        _check_plot_path(args.plot)
    rec, freq = load_input(args, to_si=False)  # the reading reports in --unit (or the file's)
    units = rec.units or (None,) * len(rec.columns)
    reading_kind = "non-overlapping" if args.kind == "non-overlapping" else "overlapping"
    results: dict[str, tuple[AllanVariance, AllanReading]] = {}
    for k, name in enumerate(rec.columns):
        x = rec.data[:, k]
        table = avar(x, freq, taus=args.taus, kind=args.kind, alpha=args.alpha)
        reading = allan_reading(x, freq, kind=reading_kind, alpha=args.alpha,
                                unit=units[k])
        results[name] = (table, reading)
    if args.plot:
        plot_reading({n: r for n, (_, r) in results.items()}, args.plot,
                     tables={n: t for n, (t, _) in results.items()})
    if args.json:
        print_json({
            "columns": {n: {"avar": t.to_dict(), "reading": r.to_dict()}
                        for n, (t, r) in results.items()},
            "freq": freq,
        })
        return 0
    blocks = [f"column {n}\n{t.summary()}\n\n{r.summary()}" for n, (t, r) in results.items()]
    print("\n\n".join(blocks))
    return 0


def plot_reading(
    readings: dict[str, AllanReading], path: str | Path,
    tables: dict[str, AllanVariance] | None = None,
) -> Path:
    """Save a log-log Allan deviation plot: curves with interval bars and the fitted lines.

    Like Figs. 15-16 of Quinchia et al. (2013): one curve per column (the `tables` when given,
    else each reading's own AV), vertical bars for the intervals, dashed lines of the
    identified slopes over (a little beyond) their tau ranges, labelled with their values,
    and their sum (dotted), the curve the reading explains.

    Raises
    ------
    ImportError
        matplotlib is not installed (``pip install "stochmod[plots]"``).
    """
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError(
            'the --plot option needs matplotlib: pip install "stochmod[plots]"'
        ) from exc
    path = _check_plot_path(path)
    fig = Figure(figsize=(7.5, 5.5))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    colors = [f"C{i}" for i in range(10)]
    for i, (name, reading) in enumerate(readings.items()):
        av = tables[name] if tables and name in tables else reading.avar
        color = colors[i % len(colors)]
        dev = av.adev
        err = _bars(av)
        ax.errorbar(av.tau, dev, yerr=err, fmt="o-", ms=3, lw=1, color=color, capsize=2,
                    label=f"{name} ({av.kind})")
        if any(c is not None for c in reading.coefficients.values()):
            t = np.geomspace(av.tau[0], av.tau[-1], 100)
            ax.plot(t, np.sqrt(reading.line(t)), ":", color=color, lw=1.0,
                    label=f"{name}: sum of the lines")
        for coef_name, c in reading.coefficients.items():
            if c is None:
                continue
            t = np.geomspace(c.tau_range[0] / 2.0, c.tau_range[1] * 2.0, 20)
            ax.plot(t, np.sqrt(c.line * t**c.slope), "--", color=color, lw=1.2)
            ax.annotate(f"{coef_name} = {c.value:.3g}", (t[10], np.sqrt(c.line * t[10]**c.slope)),
                        fontsize=8, color=color, textcoords="offset points", xytext=(4, 6))
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("averaging time tau [s]")
    units = {r.unit for r in readings.values()}
    unit = units.pop() if len(units) == 1 else None
    ax.set_ylabel(f"Allan deviation [{unit or 'signal unit'}]")
    log_grid(ax)
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=120)
    return path


def _check_plot_path(path: str | Path) -> Path:
    path = Path(path)
    if path.suffix.lower() not in (".png", ".pdf", ".svg"):
        raise InputError(f"--plot needs a .png, .pdf or .svg file name; got {str(path)!r}")
    return path


def _bars(av: AllanVariance) -> Any:
    """Asymmetric error bars of the deviation from the interval on the variance (or None)."""
    if not np.all(np.isfinite(av.ci_low)):
        return None
    dev = av.adev
    return np.vstack([dev - np.sqrt(av.ci_low), np.sqrt(av.ci_high) - dev])
