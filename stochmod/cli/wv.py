"""``stochmod wv``: empirical wavelet variance of each column of a recording."""

from __future__ import annotations

import argparse

from stochmod.cli._common import add_input_arguments, column_replicates, load_segments, print_json
from stochmod.core.errors import InputError
from stochmod.io.recording import Recording
from stochmod.empirical.pooled import pooled_wvar
from stochmod.empirical.wavelet_variance import CI_METHODS, wvar

__all__ = ["register", "run"]


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``wv`` subcommand."""
    p = subparsers.add_parser(
        "wv",
        help="empirical wavelet variance (MODWT) with confidence intervals",
        description=(
            "Empirical MODWT wavelet variance of each column at levels j = 1..J, averaging time "
            "tau_j = 2^(j-1)/freq s (Haar: half the overlapping Allan variance), with "
            "confidence intervals. Units: the column's unit squared."
        ),
    )
    add_input_arguments(p)
    p.add_argument("--wavelet", default="haar",
                   help="orthogonal PyWavelets wavelet: haar (default), db2, db4, sym4, ...")
    p.add_argument("--levels", type=int, default=None, metavar="J",
                   help="number of levels (default floor(log2 N) - 1, capped by the filter width)")
    p.add_argument("--ci", choices=CI_METHODS, default="chi2",
                   help="interval method: chi2 (default, equivalent degrees of freedom) or normal")
    p.add_argument("--alpha", type=float, default=0.05,
                   help="significance level of the intervals (default 0.05)")
    p.add_argument("--robust", action="store_true",
                   help="robust wavelet variance (biweight M-estimate) with the contamination "
                        "diagnostic: share of coefficients rejected per level, worst times")
    p.add_argument("--efficiency", type=float, default=0.6, metavar="EFF",
                   help="Gaussian efficiency in (0, 1] of the robust estimator (default 0.6)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Compute and print the wavelet variance of every selected column (with ``--split-gaps``,
    the pooled WV of the gap-free segments)."""
    segments, freq = load_segments(args)
    if len(segments) > 1:
        return _run_pooled(args, segments, freq)
    rec = segments[0]
    results = {
        name: wvar(rec.data[:, k], freq, wavelet=args.wavelet, levels=args.levels,
                   ci=args.ci, alpha=args.alpha,
                   **({"robust": True, "efficiency": args.efficiency} if args.robust else {}))
        for k, name in enumerate(rec.columns)
    }
    if args.json:
        print_json({"columns": {n: r.to_dict() for n, r in results.items()}, "freq": freq})
        return 0
    blocks = [f"column {name}\n{res.summary()}" for name, res in results.items()]
    print("\n\n".join(blocks))
    return 0


def _run_pooled(args: argparse.Namespace, segments: list[Recording], freq: float) -> int:
    """The pooled WV of the gap-free segments (chi-square intervals, the equality test)."""
    if args.robust:
        raise InputError("--robust is not available with gaps split into segments: the pooled "
                         "wavelet variance is the classical one")
    if args.ci != "chi2":
        raise InputError("--ci normal is not available with gaps split into segments: the "
                         "pooled wavelet variance has chi-square intervals")
    results = {name: pooled_wvar(column_replicates(segments, k), freq, levels=args.levels,
                                 wavelet=args.wavelet, alpha=args.alpha)
               for k, name in enumerate(segments[0].columns)}
    if args.json:
        print_json({"columns": {n: {**r.wv.to_dict(), "segments": len(r.replicates),
                                    "equality_test": None if r.test is None else {
                                        "statistic": r.test.statistic, "dof": r.test.dof,
                                        "pvalue": r.test.pvalue}}
                                for n, r in results.items()}, "freq": freq})
        return 0
    print("\n\n".join(f"column {name}\n{res.summary()}" for name, res in results.items()))
    return 0
