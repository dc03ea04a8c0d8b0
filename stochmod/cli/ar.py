"""``stochmod ar``: AR(p) fit (Burg or Yule-Walker) of each column, order given or by BIC."""

from __future__ import annotations

import argparse

from stochmod.cli._common import add_input_arguments, load_input, print_json
from stochmod.core.errors import InputError
from stochmod.empirical.ar_fit import fit_ar

__all__ = ["register", "run"]

_METHODS = {"burg": "burg", "yw": "yw", "yw-adjusted": "yw-adjusted"}


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``ar`` subcommand."""
    p = subparsers.add_parser(
        "ar",
        help="autoregressive AR(p) fit (Burg or Yule-Walker) with AIC/BIC table",
        description=(
            "Fit X_t = sum phi_i X_{t-i} + e_t to each column (Quinchia et al. 2013 write "
            "alpha_k = -phi_k, beta0^2 = sigma2). sigma2 is the innovation variance per sample "
            "in the column's unit squared."
        ),
    )
    add_input_arguments(p)
    p.add_argument("--order", required=True, metavar="P",
                   help="AR order, or 'auto' to choose 1..--max-order by --criterion")
    p.add_argument("--method", choices=sorted(_METHODS), default="burg",
                   help="burg (default), yw (Yule-Walker, n denominators) or yw-adjusted")
    p.add_argument("--max-order", type=int, default=10, metavar="P",
                   help="largest order considered with --order auto (default 10)")
    p.add_argument("--criterion", choices=["bic", "aic"], default="bic",
                   help="order-selection criterion (default bic)")
    p.set_defaults(func=run)


def _order(text: str) -> int | None:
    if text.strip().lower() == "auto":
        return None
    try:
        return int(text)
    except ValueError:
        raise InputError(f"--order must be a positive integer or 'auto', got {text!r}") from None


def run(args: argparse.Namespace) -> int:
    """Fit and print the AR model of every selected column."""
    order = _order(args.order)
    rec, freq = load_input(args)
    fits = {
        name: fit_ar(rec.data[:, k], freq, order, max_order=args.max_order,
                     method=_METHODS[args.method], criterion=args.criterion)
        for k, name in enumerate(rec.columns)
    }
    if args.json:
        print_json({"columns": {n: f.to_dict() for n, f in fits.items()}, "freq": freq})
        return 0
    print("\n\n".join(f"column {n}\n{f.summary()}" for n, f in fits.items()))
    return 0
