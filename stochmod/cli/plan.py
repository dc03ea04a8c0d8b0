"""``stochmod plan``: how long to record so that each parameter's interval is within +-X %."""

from __future__ import annotations

import argparse

from stochmod.cli._common import print_json
from stochmod.core.errors import InputError
from stochmod.fit.plan import record_length
from stochmod.io.calibration import Calibration
from stochmod.plugin.spec import model_from_spec

__all__ = ["register", "run"]


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``plan`` subcommand."""
    p = subparsers.add_parser(
        "plan",
        help="how long to record for a given precision of every parameter",
        description=(
            "For each axis of a calibration (or a declared model), the shortest static record "
            "whose asymptotic GMWM 95%% interval is within +-PRECISION %% for each parameter, and "
            "the half-widths at the calibration's own record length (stochmod.fit.plan)."
        ),
    )
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--calibration", metavar="FILE", help="calibration.json of stochmod calibrate")
    src.add_argument("--model", metavar="SPEC",
                     help='a model with values, e.g. "WN(sigma2=1e-6) + RW(sigma2=1e-12)"')
    p.add_argument("--freq", type=float, default=None, metavar="HZ",
                   help="sampling frequency of --model, Hz")
    p.add_argument("--column", nargs="+", default=None, metavar="NAME",
                   help="axes of the calibration to plan for (default all)")
    p.add_argument("--precision", type=float, default=10.0, metavar="PERCENT",
                   help="wanted half-width of each interval, %% of the value (default 10)")
    p.add_argument("--level", type=float, default=0.95, help="confidence level (default 0.95)")
    p.add_argument("--json", action="store_true", help="print JSON instead of tables")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Print the plan of each axis."""
    if args.calibration is not None:
        if args.freq is not None:
            raise InputError("--freq applies to --model; a calibration states its own")
        cal = Calibration.read(args.calibration)
        columns = args.column or list(cal.columns)
        models = {c: cal.axis(c).model for c in columns}
        current = max(cal.record_sizes or (cal.n,))
        details = {c: cal.axis(c).details for c in columns}
        fitted = {c: d.get("final_weighting") or d.get("weighting") for c, d in details.items()}
    else:
        if args.freq is None:
            raise InputError("--model needs --freq HZ")
        if args.column is not None:
            raise InputError("--column applies to --calibration")
        models = {"model": model_from_spec(args.model, args.freq)}
        current = None
        fitted = {}
    plans = {c: record_length(m, precision=args.precision / 100.0, level=args.level,
                              current=current) for c, m in models.items()}
    if args.json:
        print_json({c: {"parameters": list(p.names), "values": p.values, "samples": p.samples,
                        "hours": p.hours, "current": p.current, "current_widths": p.current_widths}
                    for c, p in plans.items()})
        return 0
    for column, plan in plans.items():
        print(f"{column}: {models[column].name}")
        print(plan.summary())
        if fitted.get(column) not in (None, "model"):
            print(f"(this axis was fitted with the {fitted[column]} weighting: its random walk "
                  "and slow Gauss-Markov terms spread up to twice the widths above, "
                  "docs/record_length.md; calibrate with --final-weighting model for the "
                  "planned ones)")
        print()
    return 0
