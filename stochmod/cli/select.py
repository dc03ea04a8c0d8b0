"""``stochmod select``: automatic model selection per column (GMWM + information criterion)."""

from __future__ import annotations

import argparse
from typing import Any

from stochmod.cli._common import add_input_arguments, load_segments, print_json
from stochmod.core.errors import InputError
from stochmod.fit.lattice import default_families, default_max_counts
from stochmod.workflows.calibrate import select_columns

__all__ = ["add_selection_arguments", "register", "run", "selection_options"]


def add_selection_arguments(p: argparse.ArgumentParser) -> None:
    """Candidate, criterion and weighting options shared by ``select`` and ``calibrate``."""
    p.add_argument("--candidates", nargs="+", default=None, metavar="SPEC",
                   help='candidate models, e.g. "GM+WN" "2*GM+WN" (default: every combination '
                        "of --families, up to --max-count copies of each)")
    try:
        families = default_families()
    except InputError:  # no registered family declares lattice membership: --families needed
        families = ()
    p.add_argument("--families", nargs="+", default=list(families), metavar="F",
                   help=f"families of the candidate lattice (default: {' '.join(families)}, the "
                        "registered families that declare lattice membership)")
    counts = " ".join(f"{f}={k}" for f, k in default_max_counts(families).items())
    p.add_argument("--max-count", nargs="+", default=[], metavar="F=K",
                   help="largest number of processes of a family in the lattice (default: the "
                        f"family's declared lattice_copies{', ' + counts if counts else ''}; "
                        "others 1)")
    p.add_argument("--criterion", default="wvic",
                   help="selection criterion registered by a plugin (default wvic)")
    p.add_argument("--weighting", default="diagonal", metavar="NAME",
                   help="registered GMWM weighting shared by all candidates: diagonal (default), "
                        "optimal, identity, or a plugin's")
    p.add_argument("--final-weighting", default=None, metavar="NAME",
                   help="fit the selected model again with this registered weighting after "
                        "the ranking, e.g. model: deep-level terms (random walk, slow "
                        "Gauss-Markov) without the diagonal weighting's bias (docs/gmwm.md)")
    p.add_argument("--levels", type=int, default=None, metavar="J",
                   help="number of wavelet levels (default: all the signal allows)")
    p.add_argument("--seed", type=int, default=0, help="seed of the multi-start searches (default 0)")
    p.add_argument("--robust", action="store_true",
                   help="fit the robust wavelet variance (biweight M-estimate): outliers such as "
                        "knocks and logger glitches no longer drive the model; the report shows "
                        "where the record was disturbed")
    p.add_argument("--efficiency", type=float, default=0.6, metavar="EFF",
                   help="Gaussian efficiency in (0, 1] of the robust estimator (default 0.6; "
                        "lower is more robust; with --robust)")


def selection_options(args: argparse.Namespace) -> dict[str, Any]:
    """Keyword arguments of :func:`stochmod.select` from the shared options."""
    families = tuple(args.families)
    return {
        "candidates": args.candidates,
        "families": families,
        "max_counts": default_max_counts(families) | _max_counts(args.max_count),
        "criterion": args.criterion,
        "weighting": args.weighting,
        "final_weighting": args.final_weighting,
        "levels": args.levels,
        "rng": args.seed,
        "robust": args.robust,
        "efficiency": args.efficiency,
    }


def _max_counts(items: list[str]) -> dict[str, int]:
    """``["GM=2", "WN=1"]`` -> ``{"GM": 2, "WN": 1}``."""
    out = {}
    for item in items:
        name, sep, count = item.partition("=")
        if not (sep and name and count.strip().isdigit()):
            raise InputError(f"--max-count takes FAMILY=K with K a non-negative integer, got {item!r}")
        out[name.strip()] = int(count)
    return out


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``select`` subcommand."""
    p = subparsers.add_parser(
        "select",
        help="select a composite model per column (GMWM fits ranked by an information criterion)",
        description=(
            "Fit every candidate model by the GMWM with a common weighting matrix and rank them "
            "by the wavelet-variance information criterion (objective + optimism), with the "
            "J-test p-value as goodness of fit. Candidates: --candidates, or every combination "
            "of --families with up to --max-count copies of each. Units: those of the file."
        ),
    )
    add_input_arguments(p)
    add_selection_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the selection on every selected column and print the rankings."""
    segments, freq = load_segments(args)
    results = select_columns(segments, freq, **selection_options(args))
    if args.json:
        print_json({"columns": {r.column: r.to_dict() for r in results}, "freq": freq})
        return 0
    print("\n\n".join(r.summary() for r in results))
    return 0
