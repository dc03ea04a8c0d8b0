"""``stochmod calibrate``'s datasheet, triad, export, report and fleet options.

Kept apart from :mod:`stochmod.cli.calibrate` so that its pipeline reads as one call per
feature: :func:`export_noise`, :func:`write_exports_for`, :func:`write_report_for`.
"""

from __future__ import annotations

import argparse
import functools
import json
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import attrs

from stochmod.core.errors import InputError
from stochmod.core.units import SENSORS
from stochmod.fit.selection import SelectionResult
from stochmod.io.calibration import Calibration
from stochmod.output.exports import (
    DEFAULT_HORIZON_CAP,
    EXPORT_FORMATS,
    calibration_noise,
    exports_from_calibration,
    write_exports,
)

if TYPE_CHECKING:
    from stochmod.fit.validation import ValidationBands
    from stochmod.nav.drift import DriftPrediction
    from stochmod.output.exports import AxisNoise
    from stochmod.output.html_report import ReportAxis
    from stochmod.workflows.calibrate import CalibrationRun

__all__ = ["EXPORT_HORIZON_HELP", "add_output_arguments", "check_drift_request", "drift_line",
           "export_noise", "fleet_requested", "predict_drift", "report_axis", "report_overview",
           "write_exports_for", "write_report_for"]

#: Help of ``--export-horizon`` (``calibrate`` and ``export``).
EXPORT_HORIZON_HELP = (
    "H, s: the exported white density N and random walk K are the tightest pair whose Allan "
    "variance (N^2/tau + K^2 tau/3, as sampled at fs) over-bounds the final model's at every "
    "tau in [1/fs, H], "
    "never below the model's own N and K "
    f"(default min({DEFAULT_HORIZON_CAP:g} s, record/10): the longest coast on the bias model "
    "a filter is expected to bridge, within what the record's Allan variance checks); the "
    "files' headers state the range and the inflation over the model's own N and K")


def add_output_arguments(p: argparse.ArgumentParser) -> None:
    """The options of the datasheet, triad, export, report and fleet features."""
    g = p.add_argument_group("datasheet units, triads, exports, report, fleets")
    g.add_argument("more_files", nargs="*", metavar="FILE ...",
                   help="more recordings: a fleet run, OUT/<file stem>/ each and OUT/fleet.csv")
    g.add_argument("--sensor", choices=sorted(SENSORS), default=None,
                   help="what every column measures, where its name (gyro_x, accel_y ...) and "
                        "the file do not tell: gyro or accel (its unit still comes from the file, "
                        "--gyro-unit/--accel-unit, --unit or --assume-si)")
    g.add_argument("--triad", action="store_true",
                   help="one model structure per sensor (gyro x/y/z, accel x/y/z), chosen on the "
                        "criterion summed over its axes; parameters per axis")
    g.add_argument("--export", nargs="+", default=[], choices=sorted(EXPORT_FORMATS),
                   metavar="FORMAT",
                   help="write navigation-stack configs: kalibr (OUT/kalibr_imu.yaml), openvins "
                        "(OUT/kalibr_imu_chain.yaml), pyins (OUT/pyins_imu.json), stochmod-nav "
                        "(OUT/stochmod_nav.json)")
    g.add_argument("--export-horizon", type=float, default=None, metavar="SECONDS",
                   help=EXPORT_HORIZON_HELP)
    g.add_argument("--rostopic", default="/imu0", help="IMU topic in the Kalibr/OpenVINS files")
    g.add_argument("--report", action="store_true",
                   help="write OUT/report.html: figures, selection, datasheet, exports in one file")
    g.add_argument("--drift", type=float, default=None, metavar="SECONDS",
                   help="predict the 1-sigma horizontal drift of a loosely-coupled INS/GNSS "
                        "filter with the final models over a GNSS outage of SECONDS at rest, "
                        "after 300 s of fixes, with its 5-95 %% band over --drift-draws "
                        "parameter draws (docs/drift.md): printed, written to OUT/drift.json "
                        "and shown in the report; needs columns gyro_x ... accel_z")
    g.add_argument("--drift-draws", type=int, default=20, metavar="N",
                   help="parameter draws for the band of --drift (default 20; 0: the nominal "
                        "prediction only)")
    g.add_argument("--workers", type=int, default=None, metavar="N",
                   help="calibrate the FILEs on a local dask cluster of N worker processes")
    g.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="calibrate the FILEs on an existing dask.distributed cluster "
                        "(e.g. tcp://10.0.0.5:8786)")


def fleet_requested(args: argparse.Namespace) -> bool:
    """Whether the command line asks for a fleet run."""
    return bool(args.more_files) or args.workers is not None or bool(args.scheduler)


def check_drift_request(args: argparse.Namespace, columns: Sequence[str]) -> None:
    """Refuse, before any selection, a ``--drift`` that is not a duration or that the
    recording's `columns` cannot serve (one each of the navigation filter's axes,
    :data:`stochmod.nav.emulate.AXES`, case-insensitive, as
    :func:`stochmod.nav.drift.calibration_axes` will ask of the calibration)."""
    if args.drift is None:
        return
    from stochmod.nav.emulate import AXES

    if not (math.isfinite(args.drift) and args.drift > 0):
        raise InputError(f"--drift takes the outage's length in seconds (> 0), got {args.drift:g}")
    if args.drift_draws < 0:
        raise InputError(f"--drift-draws must be at least 0, got {args.drift_draws}")
    keys = [c.strip().lower() for c in columns]
    missing = [a for a in AXES if keys.count(a) != 1]
    if missing:
        raise InputError(f"--drift needs one column each of {', '.join(AXES)} "
                         f"(case-insensitive) for the navigation filter; {', '.join(missing)} "
                         f"missing or repeated among {list(columns)}")


def predict_drift(args: argparse.Namespace, calibration: Calibration, out: Path
                  ) -> tuple[DriftPrediction | None, list[Path]]:
    """With ``--drift``: the predicted drift with `calibration`'s final models
    (:func:`stochmod.nav.drift.predicted_drift`, at rest, ``--drift-draws`` draws seeded by
    ``--seed``) and ``OUT/drift.json``; else None and no file."""
    if args.drift is None:
        return None, []
    from stochmod.nav.drift import predicted_drift

    pred = predicted_drift(calibration, outage=args.drift, n_draws=args.drift_draws,
                           rng=args.seed)
    path = out / "drift.json"
    path.write_text(json.dumps(pred.to_dict(), indent=1), encoding="utf-8")
    return pred, [path]


def drift_line(pred: DriftPrediction) -> str:
    """One console line: the predicted drift at the outage's end and its band."""
    c = pred.conditions
    band = ""
    if pred.draws.shape[0] > pred.n_failed:
        low, high = pred.band()
        band = (f" (5-95 % over {pred.draws.shape[0] - pred.n_failed} parameter draws: "
                f"{low:.4g}-{high:.4g} m)")
    return (f"predicted drift over a {c.outage:g} s GNSS outage at rest after {c.settle:g} s "
            f"of fixes: 1-sigma horizontal {pred.end_sigma:.4g} m{band}; docs/drift.md")


def write_exports_for(args: argparse.Namespace, source: Calibration | list[SelectionResult],
                      units: dict[str, str], out: Path,
                      noise: Sequence[AxisNoise] | None = None) -> list[Path]:
    """The ``--export`` files: from the calibration's final models
    (:func:`stochmod.output.exports.exports_from_calibration`, the same files as ``stochmod
    export OUT/calibration.json``; its exported terms `noise` when computed already,
    :func:`export_noise`), or from selections' best fits (the columns of `units`)."""
    if not args.export:
        return []
    if isinstance(source, Calibration):
        return exports_from_calibration(source, args.export, out, horizon=args.export_horizon,
                                        rostopic=args.rostopic, noise=noise)
    return write_exports(args.export, {s.column: s.best for s in source if s.column in units},
                         units, out, horizon=args.export_horizon, rostopic=args.rostopic)


def export_noise(args: argparse.Namespace, calibration: Calibration) -> list[AxisNoise] | None:
    """The exported white density and random walk of each gyro and accelerometer axis of
    `calibration` (its final models, ``--export-horizon``) when ``--export`` asks for files,
    else None: what the export files hold and the report shows."""
    if not args.export:
        return None
    return calibration_noise(calibration, horizon=args.export_horizon)


def report_axis(run_: CalibrationRun, k: int, *, bands: ValidationBands | None = None,
                noise: AxisNoise | None = None) -> ReportAxis:
    """What the report and the column's figure show of column `k` of the calibration `run_`:
    its selection, datasheet, final fit and verdict, with the `bands` of simulations and the
    exported `noise` terms when there are some."""
    from stochmod.output.html_report import ReportAxis

    sel = run_.selections[k]
    notes = ["model structure chosen per triad" if run_.triads else "", sel.refit_note]
    return ReportAxis(sel.column, sel, run_.datasheets[sel.column], bands,
                      note="; ".join(n for n in notes if n),
                      final=run_.finals[k], noise=noise, verdict=run_.verdicts[k])


def _report_axes(run_: CalibrationRun, drawn: Sequence[ReportAxis | None] = (),
                 noise: Sequence[AxisNoise] | None = None) -> list[ReportAxis]:
    """The report's axes: :func:`report_axis` of each column, or its figure drawn already
    (`drawn`), with its exported terms when there are some."""
    drawn = list(drawn) or [None] * len(run_.selections)
    axes = [report_axis(run_, k) if a is None else a for k, a in enumerate(drawn)]
    by_column = {a.column: a for a in noise or ()}
    return [attrs.evolve(a, noise=by_column[a.column]) if a.column in by_column else a
            for a in axes]


def report_overview(args: argparse.Namespace, run_: CalibrationRun,
                    noise: Sequence[AxisNoise] | None = None, executor: Any = None
                    ) -> Callable[[], bytes | None]:
    """Start the report's Allan overview, with the exported terms `noise`
    (:func:`export_noise`), for :func:`write_report_for`; the call returned gives its PNG
    (None without ``--report`` or matplotlib). On `executor` (a pool of worker processes,
    which draw the columns' figures too) it is drawn there, else when the call is made."""
    import importlib.util

    if not args.report or not run_.selections or importlib.util.find_spec("matplotlib") is None:
        return lambda: None
    from stochmod.output.html_report import allan_overview_png

    axes = _report_axes(run_, noise=noise)
    if executor is None:
        return functools.partial(allan_overview_png, axes)
    return executor.submit(allan_overview_png, [a.for_figures() for a in axes]).result


def write_report_for(args: argparse.Namespace, run_: CalibrationRun, exported: list[Path],
                     title: str, out: Path, drawn: Sequence[ReportAxis | None] = (),
                     noise: Sequence[AxisNoise] | None = None,
                     overview: bytes | None = None,
                     drift: DriftPrediction | None = None) -> list[Path]:
    """``OUT/report.html`` (with ``--report``) of the calibration `run_`: the summary across
    axes first, with each axis's exported N and K when `exported` holds files (`noise`, the
    exported terms, :func:`export_noise`; computed from the final models when not given).
    `drawn`: per column, its figure drawn already (:func:`report_axis` with its PNG) or None;
    the report draws the others, and its Allan overview unless given (:func:`report_overview`
    of the same `noise`); `drift`: the ``--drift`` prediction (:func:`predict_drift`)."""
    if not args.report:
        return []
    from stochmod.output.html_report import write_report

    if exported and noise is None:
        noise = calibration_noise(run_.calibration, horizon=args.export_horizon)
    axes = _report_axes(run_, drawn, noise if exported else None)
    exports = {p.name: p.read_text() for p in exported}
    path = write_report(out / "report.html", axes, title=title, exports=exports,
                        triads=run_.triads, overview=overview, drift=drift)
    return [path]
