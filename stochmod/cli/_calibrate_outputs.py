"""``stochmod calibrate``'s datasheet, triad, export, report and fleet options.

Kept apart from :mod:`stochmod.cli.calibrate` so that its pipeline reads as one call per
feature: :func:`write_exports_for`, :func:`write_report_for`.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from stochmod.core.units import SENSORS
from stochmod.fit.selection import SelectionResult
from stochmod.io.calibration import Calibration
from stochmod.output.exports import (
    DEFAULT_HORIZON_CAP,
    EXPORT_FORMATS,
    exports_from_calibration,
    write_exports,
)

if TYPE_CHECKING:
    from stochmod.workflows.calibrate import CalibrationRun

__all__ = ["EXPORT_HORIZON_HELP", "add_output_arguments", "fleet_requested", "write_exports_for",
           "write_report_for"]

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
    g.add_argument("--workers", type=int, default=None, metavar="N",
                   help="calibrate the FILEs on a local dask cluster of N worker processes")
    g.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="calibrate the FILEs on an existing dask.distributed cluster "
                        "(e.g. tcp://10.0.0.5:8786)")


def fleet_requested(args: argparse.Namespace) -> bool:
    """Whether the command line asks for a fleet run."""
    return bool(args.more_files) or args.workers is not None or bool(args.scheduler)


def write_exports_for(args: argparse.Namespace, source: Calibration | list[SelectionResult],
                      units: dict[str, str], out: Path) -> list[Path]:
    """The ``--export`` files: from the calibration's final models
    (:func:`stochmod.output.exports.exports_from_calibration`, the same files as ``stochmod
    export OUT/calibration.json``), or from selections' best fits (the columns of `units`)."""
    if not args.export:
        return []
    if isinstance(source, Calibration):
        return exports_from_calibration(source, args.export, out, horizon=args.export_horizon,
                                        rostopic=args.rostopic)
    return write_exports(args.export, {s.column: s.best for s in source if s.column in units},
                         units, out, horizon=args.export_horizon, rostopic=args.rostopic)


def write_report_for(args: argparse.Namespace, run_: CalibrationRun, exported: list[Path],
                     title: str, out: Path) -> list[Path]:
    """``OUT/report.html`` (with ``--report``) of the calibration `run_`: the summary across
    axes first, with each axis's exported N and K when `exported` holds files. Each axis's
    bands compare WVs only, on the simulations its figure drew when there is one
    (:func:`stochmod.fit.validation.keep_simulated`)."""
    if not args.report:
        return []
    from stochmod.fit.validation import validate
    from stochmod.output.exports import noise_terms
    from stochmod.output.html_report import ReportAxis, write_report

    data = run_.record.data
    axes = []
    for k, (sel, fin, judged) in enumerate(zip(run_.selections, run_.finals, run_.verdicts)):
        sheet = run_.datasheets[sel.column]
        # the WV bands (the report shows no PSD), from the figure's simulations when drawn
        bands = validate(sel.best, data[:, k], R=args.n_sim, rng=args.seed, psd=False)
        noise = (noise_terms(sel.best, sheet.unit, column=sel.column, horizon=args.export_horizon,
                             record_seconds=run_.calibration.record_seconds)
                 if exported else None)
        axes.append(ReportAxis(sel.column, sel, sheet, bands,
                               note="" if not run_.triads else "model structure chosen per triad",
                               final=fin, noise=noise, verdict=judged))
    exports = {p.name: p.read_text() for p in exported}
    path = write_report(out / "report.html", axes, title=title, exports=exports,
                        triads=run_.triads)
    return [path]
