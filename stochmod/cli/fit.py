"""``stochmod fit``: GMWM fit of one composite model to each column."""

from __future__ import annotations

import argparse

from stochmod.cli._common import add_input_arguments, column_replicates, load_segments, print_json
from stochmod.fit.gmwm import gmwm

__all__ = ["register", "run"]


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``fit`` subcommand."""
    p = subparsers.add_parser(
        "fit",
        help="fit a composite noise model by the GMWM",
        description=(
            "Fit a composite model (e.g. \"2*GM+WN\", \"QN+WN+RW\", \"AR(2)+WN\") to each column "
            "by the Generalized Method of Wavelet Moments; prints estimates with standard errors "
            "and 95% intervals (canonical and physical), the objective and the J-test. Units: "
            "those of the file (parameters per sample at --freq; GM beta in 1/s)."
        ),
    )
    add_input_arguments(p)
    p.add_argument("--model", required=True, metavar="SPEC", help='model spec, e.g. "2*GM+WN"')
    p.add_argument("--weighting", default="diagonal", metavar="NAME",
                   help="registered weighting matrix: diagonal (default), optimal, model, "
                        "bootstrap, identity, or a plugin's")
    p.add_argument("--levels", type=int, default=None, metavar="J",
                   help="number of wavelet levels (default: all the signal allows)")
    p.add_argument("--seed", type=int, default=0, help="seed of the multi-start search (default 0)")
    p.add_argument("--robust", action="store_true",
                   help="fit the robust wavelet variance (biweight M-estimate; docs/robust.md)")
    p.add_argument("--efficiency", type=float, default=0.6, metavar="EFF",
                   help="Gaussian efficiency in (0, 1] of the robust estimator (default 0.6)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Fit the model to every selected column and print the reports."""
    segments, freq = load_segments(args)
    fits = {name: gmwm(column_replicates(segments, k), args.model, freq, weighting=args.weighting,
                       levels=args.levels, rng=args.seed, robust=args.robust,
                       efficiency=args.efficiency)
            for k, name in enumerate(segments[0].columns)}
    if args.json:
        print_json({"columns": {n: f.to_dict() for n, f in fits.items()}, "freq": freq})
        return 0
    print("\n\n".join(f"column {n}\n{f.summary()}" for n, f in fits.items()))
    return 0
