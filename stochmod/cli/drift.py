"""``stochmod drift``: the predicted 1-sigma horizontal drift over a GNSS outage from a
calibration file, with its band from the parameters' uncertainty, and optionally its check on
emulated drives (:mod:`stochmod.nav.drift`)."""

from __future__ import annotations

import argparse
import json
import sys

from stochmod.core.errors import InputError
from stochmod.nav.drift import MOTIONS, check_drift, predicted_drift

__all__ = ["register", "run"]


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``drift`` subcommand."""
    p = subparsers.add_parser(
        "drift",
        help="predicted horizontal drift over a GNSS outage from a calibration",
        description=(
            "Propagate the covariance of the loosely-coupled filter with the calibration's "
            "models along a stated motion: GNSS fixes for --settle s from the outage study's "
            "initial covariance, then none for --outage s; print the predicted 1-sigma "
            "horizontal drift sqrt(P_NN + P_EE) over the outage and its band, the "
            "percentiles over --draws parameter sets drawn from the calibration's intervals "
            "(log-normal for positive parameters). --check R also emulates R drives with "
            "errors drawn from the calibration's models and compares their horizontal errors "
            "at the outage's end with the prediction."
        ),
    )
    p.add_argument("--calibration", required=True, metavar="FILE",
                   help="calibration.json written by `stochmod calibrate`")
    p.add_argument("--outage", type=float, default=60.0, metavar="S",
                   help="seconds without GNSS after the last fix (default 60)")
    p.add_argument("--motion", choices=MOTIONS, default="static",
                   help="static (default), straight (constant --speed), or drive (the outage "
                        "study's 10-minute car drive)")
    p.add_argument("--speed", type=float, default=None, metavar="M_S",
                   help="speed of the straight motion (default 15 m/s)")
    p.add_argument("--settle", type=float, default=300.0, metavar="S",
                   help="seconds of GNSS fixes before the outage (default 300)")
    p.add_argument("--draws", type=int, default=100, metavar="N",
                   help="parameter draws for the band (default 100; 0: none)")
    p.add_argument("--seed", type=int, default=0, help="seed of the draws and drives (default 0)")
    p.add_argument("--cep", type=float, default=2.0, metavar="M",
                   help="GNSS horizontal CEP, m (default 2)")
    p.add_argument("--dt-filter", type=float, default=1.0, metavar="S",
                   help="the filter's covariance step, s (default 1)")
    p.add_argument("--imu-rate", type=float, default=None, metavar="HZ",
                   help="rate of the reference IMU of the prediction (default the "
                        "calibration's)")
    p.add_argument("--workers", type=int, default=1, metavar="N",
                   help="processes the draws and drives are spread over (default 1)")
    p.add_argument("--check", type=int, default=0, metavar="R",
                   help="also emulate R drives and compare their errors with the prediction")
    p.add_argument("--json", action="store_true", help="print the prediction as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Predict, optionally check, and print."""
    if args.check < 0:
        raise InputError(f"--check must be a number of drives >= 0, got {args.check}")
    print(f"propagating the nominal models and {args.draws} draw(s) ...", file=sys.stderr,
          flush=True)
    pred = predicted_drift(args.calibration, args.outage, args.motion, n_draws=args.draws,
                           rng=args.seed, settle=args.settle, speed=args.speed, cep=args.cep,
                           dt_filter=args.dt_filter, imu_rate=args.imu_rate,
                           workers=args.workers)
    check = None
    if args.check:
        print(f"emulating {args.check} drive(s) ...", file=sys.stderr, flush=True)
        check = check_drift(args.calibration, pred, runs=args.check, seed=args.seed,
                            workers=args.workers)
    if args.json:
        out = pred.to_dict()
        if check is not None:
            out["check"] = {"errors": check.errors.tolist(), "rms": check.rms,
                            "ks_pvalue": check.ks_pvalue}
        print(json.dumps(out, indent=2))
        return 0
    print(pred.summary())
    if check is not None:
        print()
        print(check.summary())
    return 0
