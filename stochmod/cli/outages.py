"""``stochmod outages``: a GNSS-outage study on an emulated drive with the models of a
calibration file (the step after ``stochmod calibrate``)."""

from __future__ import annotations

import argparse
import math
import sys

from stochmod.fit.classical.build import family_for
from stochmod.core.errors import InputError
from stochmod.core.model import Model
from stochmod.nav.emulate import Segment
from stochmod.nav.logs import calibration_record, read_calibration
from stochmod.nav.study import DEFAULT_OUTAGES, DEFAULT_PROFILE, outage_study

__all__ = ["register", "run", "white_part"]

#: --quick: a 3.5 min drive with two 30 s outages (for a first look; the default is 10 min).
QUICK_PROFILE = (Segment(20, speed=15), Segment(15, turn=90), Segment(30, speed=20),
                 Segment(20, turn=-120, speed=12), Segment(30), Segment(20, turn=60, speed=18),
                 Segment(30, speed=22), Segment(15, turn=-90))
QUICK_OUTAGES = ((60.0, 30.0), (130.0, 30.0))


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``outages`` subcommand."""
    p = subparsers.add_parser(
        "outages",
        help="GNSS-outage study on an emulated drive with a calibration's models",
        description=(
            "Emulate --runs seeded 10-minute car drives whose IMU errors are drawn from the "
            "models of a calibration file (columns gyro_x ... accel_z of `stochmod calibrate`'s "
            "JSON), with 1 Hz GNSS and three 60 s outages, and navigate each with two filters "
            "that differ only in their error model: the calibrated model, and white noise alone "
            "(each axis's white part, or the white noise of equal level-1 wavelet variance when "
            "the model has none). Prints per outage the mean, median and 95th percentile of the "
            "maximum horizontal error, and each filter's average NEES. A component of the "
            "calibration correlated beyond its record is, for the filters and for the emulated "
            "errors alike, the random walk it is over the record."
        ),
    )
    p.add_argument("--calibration", required=True, metavar="FILE",
                   help="calibration.json written by `stochmod calibrate`")
    p.add_argument("--runs", type=int, default=10, metavar="R",
                   help="number of emulated drives (default 10)")
    p.add_argument("--seed", type=int, default=0, help="seed of the emulations (default 0)")
    p.add_argument("--gyro-bias-sd", type=float, default=0.0, metavar="RAD_S",
                   help="turn-on gyro bias 1-sigma drawn per run, rad/s (default 0)")
    p.add_argument("--accel-bias-sd", type=float, default=0.0, metavar="M_S2",
                   help="turn-on accelerometer bias 1-sigma drawn per run, m/s^2 (default 0)")
    p.add_argument("--cep", type=float, default=2.0, metavar="M",
                   help="GNSS horizontal CEP, m (default 2)")
    p.add_argument("--workers", type=int, default=1, metavar="N",
                   help="processes the runs are spread over (default 1; the table does not "
                        "depend on it)")
    p.add_argument("--dt-filter", type=float, default=0.1, metavar="S",
                   help="covariance step of the filters, s (default 0.1; 1.0 propagates once "
                        "per GNSS interval, about twice as fast)")
    p.add_argument("--quick", action="store_true",
                   help="a 3.5 min drive with two 30 s outages instead of the 10 min drive")
    p.set_defaults(func=run)


def white_part(model: Model) -> Model:
    """The white-noise-only model of an axis, bound to ``model.freq``: white noise of the
    model's white feed-through variance (its state-space form's ``white_var``: the components
    without states), or, when it has none, of equal level-1 Haar wavelet variance
    (``sigma2 = 2 nu_1``). The white-noise family is the registered one built from the IEEE-952
    noise density N (``N^2 = sigma2 / freq``), so no family is named here."""
    freq = float(model.freq)
    var = float(model.augment(1.0 / freq).white_var)
    if not var > 0:
        var = 2.0 * float(model.wv(1)[0])
    white = family_for(("N",))
    return Model((white.from_ieee952({"N": math.sqrt(var / freq)}, freq),)).bind(freq)


def run(args: argparse.Namespace) -> int:
    """Run the study and print its table."""
    models = read_calibration(args.calibration)
    if args.runs < 1:
        raise InputError(f"--runs must be at least 1, got {args.runs}")
    if args.workers < 1:
        raise InputError(f"--workers must be at least 1, got {args.workers}")
    if not (math.isfinite(args.dt_filter) and args.dt_filter > 0):
        raise InputError(f"--dt-filter must be a positive number of s, got {args.dt_filter!r}")
    for name in ("gyro_bias_sd", "accel_bias_sd", "cep"):
        value = getattr(args, name)
        if not (math.isfinite(value) and value >= 0) or (name == "cep" and value == 0):
            raise InputError(f"--{name.replace('_', '-')} must be a positive number, got {value!r}")
    freqs = {m.freq for m in models.values()}
    if len(freqs) != 1:
        raise InputError(f"the calibration's models have different rates {sorted(freqs)} Hz; "
                         "the emulated IMU needs one")
    rate = freqs.pop()
    filters = {"calibrated": models, "white noise": {a: white_part(m) for a, m in models.items()}}

    def progress(r: int, name: str) -> None:
        print(f"run {r + 1}/{args.runs}: {name}", file=sys.stderr, flush=True)

    # the calibration is both the truth and a filter: a component beyond its record is the
    # random walk it is over the record for both (None: an older file without the length)
    record = calibration_record(args.calibration)
    study = outage_study(filters, models, runs=args.runs, seed=args.seed,
                         profile=QUICK_PROFILE if args.quick else DEFAULT_PROFILE,
                         outages=QUICK_OUTAGES if args.quick else DEFAULT_OUTAGES, rate=rate,
                         gyro_bias_sd=args.gyro_bias_sd, accel_bias_sd=args.accel_bias_sd,
                         cep=args.cep, dt_filter=args.dt_filter, progress=progress,
                         workers=args.workers, record=record, truth_record=record)
    print(study.summary())
    return 0
