"""``stochmod outages``: a GNSS-outage study on an emulated drive with the models of a
calibration file (the step after ``stochmod calibrate``), with errors drawn from that
calibration or taken from a real static recording (``--errors``) and one filter per
calibration."""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from pathlib import Path

from stochmod.core.errors import InputError
from stochmod.core.model import Model
from stochmod.core.tables import format_table
from stochmod.fit.classical.build import family_for
from stochmod.nav.emulate import Segment
from stochmod.nav.logs import calibration_record, read_calibration
from stochmod.nav.study import (
    DEFAULT_OUTAGES,
    DEFAULT_PROFILE,
    GNSS_RATE,
    MEAN_REMOVAL,
    OutageStudy,
    outage_study,
    static_errors,
)

__all__ = ["predicted_drifts", "register", "run", "white_part"]

#: --quick: a 3 min drive with two 30 s outages (for a first look; the default is 10 min).
QUICK_PROFILE = (Segment(20, speed=15), Segment(15, turn=90), Segment(30, speed=20),
                 Segment(20, turn=-120, speed=12), Segment(30), Segment(20, turn=60, speed=18),
                 Segment(30, speed=22), Segment(15, turn=-90))
QUICK_OUTAGES = ((60.0, 30.0), (130.0, 30.0))
#: The drive's start (lat deg, lon deg, height m), heading (deg) and initial speed (m/s): the
#: defaults of :func:`stochmod.nav.study.outage_study`, which the drift prediction follows.
STUDY_START, STUDY_HEADING, STUDY_SPEED = (46.5, 6.6, 400.0), 30.0, 5.0


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
            "errors alike, the random walk it is over the record. With --errors STATIC_FILE the "
            "errors are instead the real error signal of a static recording (one "
            "non-overlapping window per run, outside the --exclude spans the calibrations were "
            "made from; units declared as calibrate declares them) and each --calibration is "
            "one filter; the table adds, at the end of each outage, the mean NEES with its 95 % "
            "chi-square band and the RMS ratio of the horizontal error to the filter's own "
            "horizontal 1-sigma. A last table gives, per outage and calibration, the 1-sigma "
            "horizontal drift the calibration predicts at the outage's end (`stochmod drift` "
            "along the same drive, no fixes in the earlier outages) with its 5-95 % band "
            "from the calibration's parameter uncertainty, beside the actual errors."
        ),
    )
    p.add_argument("--calibration", required=True, action="append", metavar="FILE",
                   help="calibration.json written by `stochmod calibrate`; with --errors, "
                        "repeat it for one filter per calibration")
    real = p.add_argument_group(
        "errors from a real static recording (docs/outages_real_errors.md)")
    real.add_argument("--errors", default=None, metavar="STATIC_FILE",
                      help="static recording whose error signal (less its mean) is added to the "
                           "emulated IMU, one non-overlapping window per run; the filters are "
                           "the calibrations' models")
    real.add_argument("--names", nargs="+", default=None, metavar="NAME",
                      help="names of the filters, one per --calibration (default: each "
                           "file's folder name)")
    real.add_argument("--exclude", action="append", default=None, metavar="START:END",
                      help="span of the static file, s from its first sample, that no window "
                           "may touch: the part the calibrations were made from (repeatable)")
    real.add_argument("--mean", choices=MEAN_REMOVAL, default="record",
                      help="remove the mean of the whole usable record (default) or of each "
                           "window")
    real.add_argument("--column", action="append", default=None, metavar="C",
                      help="the static file's six columns (gyro x y z, accel x y z), "
                           "repeatable (default: by name or by sensor kind)")
    real.add_argument("--unit", action="append", default=None, metavar="[COLUMN=]UNIT",
                      help="unit of a column of the static file, as calibrate takes it")
    real.add_argument("--gyro-unit", default=None, metavar="UNIT",
                      help="unit of the static file's gyro columns (deg/s, rad/s ...)")
    real.add_argument("--accel-unit", default=None, metavar="UNIT",
                      help="unit of the static file's accelerometer columns (g, m/s^2 ...)")
    real.add_argument("--assume-si", action="store_true",
                      help="take rad/s and m/s^2 for static columns of unknown unit")
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
    p.add_argument("--drift-draws", type=int, default=20, metavar="N",
                   help="parameter draws for the band of the predicted drift (docs/drift.md; "
                        "default 20; 0: the nominal prediction only)")
    p.add_argument("--no-drift", action="store_true",
                   help="do not predict the drift (skips one covariance run per outage, "
                        "calibration and draw)")
    p.add_argument("--quick", action="store_true",
                   help="a 3 min drive with two 30 s outages instead of the 10 min drive")
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


def predicted_drifts(calibrations: dict[str, str], study: OutageStudy, *, profile: Sequence,
                     cep: float, dt_filter: float, gyro_bias_sd: float, accel_bias_sd: float,
                     draws: int, seed: int, workers: int = 1) -> tuple[str, list[list]]:
    """Per outage of `study` and per calibration (filter name -> calibration file), the
    predicted 1-sigma horizontal drift at the outage's end with its 5-95 % band
    (:func:`stochmod.nav.drift.predicted_drift`, docs/drift.md) beside the study's actual
    maximum horizontal error (mean and median over the runs, m).

    The prediction runs the filter of the calibration along the study's drive (`profile`,
    its start, heading and initial speed) with the study's GNSS (`cep` m, 3 m vertical,
    0.1 m/s), initial sigmas, covariance step `dt_filter` (s) and turn-on bias sigmas (rad/s,
    m/s^2), and the fixes the study's filters take at 1 Hz: none in the earlier outages
    (``earlier_outages``), none from the outage's start to its end, so the last one before it
    is the last fix before its start and the prediction coasts from there to its end. Returns
    a title and the table's rows ``[outage, filter, mean, median, sigma, 5 %, 95 %]``."""
    from stochmod.nav.drift import predicted_drift

    options = {"gyro_bias_sd": gyro_bias_sd, "accel_bias_sd": accel_bias_sd}
    rows = []
    for k, (start, dur) in enumerate(study.outages):
        last, earlier = _last_fix(start, study.outages[:k])
        for name, path in calibrations.items():
            pred = predicted_drift(path, outage=start + dur - last, motion=list(profile),
                                   settle=last, gnss_rate=GNSS_RATE,
                                   speed=STUDY_SPEED, heading=STUDY_HEADING, start=STUDY_START,
                                   cep=cep, dt_filter=dt_filter, n_draws=draws,
                                   rng=[seed, k], filter_options=options, workers=workers,
                                   settle_check=False, earlier_outages=earlier)
            lo, hi = pred.band() if draws else (math.nan, math.nan)
            mean, med, _ = study.statistics(name)[k]
            rows.append([f"{start:g}+{dur:g} s", name, mean, med, pred.end_sigma, lo, hi])
    title = ("Predicted 1-sigma horizontal drift sqrt(P_NN + P_EE) at each outage's end (m) "
             "from each calibration alone (stochmod drift along this drive with the study's "
             "fixes), "
             + (f"5-95 % band over {draws} parameter draw(s)" if draws else "no band (0 draws)")
             + ", beside the actual max horizontal error (m)")
    return title, rows


def _last_fix(start: float, earlier: Sequence[tuple[float, float]]
              ) -> tuple[float, list[tuple[float, float]]]:
    """The study's last fix (at :data:`~stochmod.nav.study.GNSS_RATE`) before an outage
    starting at `start` (s from the first epoch; the study withholds the fixes at
    ``s <= t < s + d`` of every outage) and the earlier outages that end by it."""
    step = 1.0 / GNSS_RATE
    last = (math.ceil(start / step - 1e-9) - 1.0) * step
    while any(s <= last < s + d for s, d in earlier):
        last -= step
    return last, [(s, d) for s, d in earlier if s + d <= last + 1e-9]


def _span(text: str) -> tuple[float, float]:
    start, sep, end = text.partition(":")
    try:
        if not sep:
            raise ValueError
        return float(start), float(end)
    except ValueError:
        raise InputError(f"--exclude takes START:END in s, got {text!r}") from None


def _names(args: argparse.Namespace) -> list[str]:
    files = args.calibration
    if args.names is None:
        names = [Path(f).resolve().parent.name or Path(f).stem for f in files]
        if len(set(names)) < len(names):
            names = [str(f) for f in files]
    else:
        names = list(args.names)
        if len(names) != len(files):
            raise InputError(f"--names gives {len(names)} name(s) for {len(files)} "
                             "--calibration file(s)")
    if len(set(names)) < len(names):
        raise InputError(f"the filters' names must differ, got {names}")
    return names


def _rate(models: dict[str, Model], path: str) -> float:
    freqs = {m.freq for m in models.values()}
    if len(freqs) != 1:
        raise InputError(f"{path}: the calibration's models have different rates "
                         f"{sorted(freqs)} Hz; the emulated IMU needs one")
    return freqs.pop()


def run(args: argparse.Namespace) -> int:
    """Run the study and print its table."""
    if args.runs < 1:
        raise InputError(f"--runs must be at least 1, got {args.runs}")
    if args.drift_draws < 0:
        raise InputError(f"--drift-draws must be at least 0, got {args.drift_draws}")
    if args.workers < 1:
        raise InputError(f"--workers must be at least 1, got {args.workers}")
    if not (math.isfinite(args.dt_filter) and args.dt_filter > 0):
        raise InputError(f"--dt-filter must be a positive number of s, got {args.dt_filter!r}")
    for name in ("gyro_bias_sd", "accel_bias_sd", "cep"):
        value = getattr(args, name)
        if not (math.isfinite(value) and value >= 0) or (name == "cep" and value == 0):
            raise InputError(f"--{name.replace('_', '-')} must be a positive number, got {value!r}")
    if args.errors is None:
        given = [o for o in ("names", "exclude", "column", "unit", "gyro_unit", "accel_unit")
                 if getattr(args, o)] + (["assume_si"] if args.assume_si else [])
        if given or len(args.calibration) > 1:
            what = [f"--{o.replace('_', '-')}" for o in given]
            if len(args.calibration) > 1:
                what.append("several --calibration")
            raise InputError(f"{', '.join(what)} need(s) --errors STATIC_FILE; without it the "
                             "one calibration is the truth")

    def progress(r: int, name: str) -> None:
        print(f"run {r + 1}/{args.runs}: {name}", file=sys.stderr, flush=True)

    common = {"runs": args.runs, "seed": args.seed,
              "profile": QUICK_PROFILE if args.quick else DEFAULT_PROFILE,
              "outages": QUICK_OUTAGES if args.quick else DEFAULT_OUTAGES,
              "gyro_bias_sd": args.gyro_bias_sd, "accel_bias_sd": args.accel_bias_sd,
              "cep": args.cep, "dt_filter": args.dt_filter, "progress": progress,
              "workers": args.workers}
    if args.errors is None:
        path = args.calibration[0]
        models = read_calibration(path)
        filters = {"calibrated": models,
                   "white noise": {a: white_part(m) for a, m in models.items()}}
        # the calibration is both the truth and a filter: a component beyond its record is the
        # random walk it is over the record for both (None: an older file without the length)
        record = calibration_record(path)
        study = outage_study(filters, models, rate=_rate(models, path), record=record,
                             truth_record=record, **common)
        calibrations = {"calibrated": path}
    else:
        names = _names(args)
        filters = {n: read_calibration(f) for n, f in zip(names, args.calibration)}
        rates = {n: _rate(m, f) for (n, m), f in zip(filters.items(), args.calibration)}
        if len(set(rates.values())) != 1:
            raise InputError(f"the calibrations are at different rates {rates} Hz; the "
                             "emulated IMU needs one")
        rate = next(iter(rates.values()))
        errors = static_errors(args.errors, columns=args.column, freq=rate, unit=args.unit,
                               gyro_unit=args.gyro_unit, accel_unit=args.accel_unit,
                               assume_si=args.assume_si,
                               exclude=[_span(t) for t in args.exclude or ()], mean=args.mean)
        records = {n: calibration_record(f) for n, f in zip(names, args.calibration)}
        study = outage_study(filters, errors=errors, rate=rate, record=records, **common)
        calibrations = dict(zip(names, args.calibration))
    print(study.summary())
    if not args.no_drift:
        title, rows = predicted_drifts(
            calibrations, study, profile=common["profile"], cep=args.cep,
            dt_filter=args.dt_filter, gyro_bias_sd=args.gyro_bias_sd,
            accel_bias_sd=args.accel_bias_sd, draws=args.drift_draws, seed=args.seed,
            workers=args.workers)
        print(format_table(["outage", "filter", "actual mean", "median", "predicted sigma",
                            "5%", "95%"], rows, digits=4, title=title))
    return 0
