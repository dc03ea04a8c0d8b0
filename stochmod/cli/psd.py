"""``stochmod psd``: log-binned one-sided Welch PSD of each column and its slope reading."""

from __future__ import annotations

import argparse

from stochmod.cli._common import add_input_arguments, load_input, print_json
from stochmod.core.plotting import log_grid
from stochmod.empirical.psd import PSDReading, psd_reading

__all__ = ["register", "run"]


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``psd`` subcommand."""
    p = subparsers.add_parser(
        "psd",
        help="one-sided Welch PSD, frequency-averaged, with the N/B/K slope reading",
        description=(
            "One-sided Welch PSD (u^2/Hz) of each column, averaged into log-spaced frequency "
            "bins, and the reading of white noise N (slope 0, u/sqrt(Hz)), bias instability B "
            "(slope -1, u) and random walk K (slope -2, u/sqrt(s)) in the IEEE 952 convention "
            "shared with the Allan variance."
        ),
    )
    add_input_arguments(p)
    p.add_argument("--nperseg", type=int, default=None, metavar="N",
                   help="Welch segment length (default: largest power of two <= n/2)")
    p.add_argument("--bins-per-decade", type=int, default=10, metavar="B",
                   help="log-frequency bins per decade (default 10)")
    p.add_argument("--plot", default=None, metavar="OUT.png",
                   help="save a log-log plot of the binned PSD and the fitted lines")
    p.set_defaults(func=run)


def _plot(readings: dict[str, PSDReading], path: str) -> None:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as exc:  # optional dependency
        raise ImportError(
            f'--plot needs matplotlib: pip install "stochmod[plots]" ({exc})') from exc
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for name, reading in readings.items():
        spec = reading.spectrum
        line = ax.loglog(spec.f, spec.psd, ".-", lw=1, label=f"{name}")[0]
        ax.fill_between(spec.f, spec.ci_low, spec.ci_high, color=line.get_color(), alpha=0.2)
        for term in reading.terms.values():
            f = spec.f[(spec.f >= term.f_low) & (spec.f <= term.f_high)]
            ax.loglog(f, term.level_at(f, reading.freq), "--", color=line.get_color(), lw=1.5)
            mid = f[len(f) // 2]
            ax.annotate(f"{name}: {term.name}={term.value:.3g}",
                        (mid, term.level_at(mid, reading.freq)), fontsize=8,
                        color=line.get_color())
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("one-sided PSD (u$^2$/Hz)")
    log_grid(ax)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def run(args: argparse.Namespace) -> int:
    """Compute, print (and plot) the PSD reading of every selected column."""
    rec, freq = load_input(args)
    readings = {
        name: psd_reading(rec.data[:, k], freq, nperseg=args.nperseg,
                          bins_per_decade=args.bins_per_decade)
        for k, name in enumerate(rec.columns)
    }
    if args.plot:
        _plot(readings, args.plot)
    if args.json:
        print_json({
            "columns": {n: {"spectrum": r.spectrum.to_dict(), "reading": r.to_dict()}
                        for n, r in readings.items()},
            "freq": freq,
        })
        return 0
    blocks = [f"column {n}\n{r.spectrum.summary()}\n\n{r.summary()}" for n, r in readings.items()]
    print("\n\n".join(blocks))
    return 0
