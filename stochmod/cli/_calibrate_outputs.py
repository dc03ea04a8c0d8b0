"""``stochmod calibrate``'s datasheet, triad, export, report and fleet options.

Kept apart from :mod:`stochmod.cli.calibrate` so that its pipeline reads as one call per
feature: :func:`column_units`, :func:`apply_triad`, :func:`datasheet_section`,
:func:`write_exports_for`, :func:`write_report_for`.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import attrs
import numpy as np

from stochmod.output.datasheet import Datasheet, datasheet
from stochmod.core.units import SENSORS, signal_unit
from stochmod.core.errors import InputError
from stochmod.output.exports import EXPORT_FORMATS, write_exports
from stochmod.fit.selection import SelectionResult
from stochmod.empirical.allan_reading import AllanReading

__all__ = ["add_output_arguments", "column_units", "apply_triad", "datasheet_section",
           "write_exports_for", "write_report_for", "fleet_requested"]


def add_output_arguments(p: argparse.ArgumentParser) -> None:
    """The options of the datasheet, triad, export, report and fleet features."""
    g = p.add_argument_group("datasheet units, triads, exports, report, fleets")
    g.add_argument("more_files", nargs="*", metavar="FILE ...",
                   help="more recordings: a fleet run, OUT/<file stem>/ each and OUT/fleet.csv")
    g.add_argument("--sensor", choices=sorted(SENSORS), default=None,
                   help="what every column measures, where its name (gyro_x, accel_y ...) does "
                        "not tell: gyro (rad/s) or accel (m/s^2)")
    g.add_argument("--triad", action="store_true",
                   help="one model structure per sensor (gyro x/y/z, accel x/y/z), chosen on the "
                        "criterion summed over its axes; parameters per axis")
    g.add_argument("--export", nargs="+", default=[], choices=sorted(EXPORT_FORMATS),
                   metavar="FORMAT",
                   help="write navigation-stack configs: kalibr (OUT/kalibr_imu.yaml), openvins "
                        "(OUT/kalibr_imu_chain.yaml), pyins (OUT/pyins_imu.json), stochmod-nav "
                        "(OUT/stochmod_nav.json)")
    g.add_argument("--export-horizon", type=float, default=None, metavar="SECONDS",
                   help="horizon H of the random walk that bounds a GM/AR component in the "
                        "exports (default one sample: the GM's driving noise)")
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


def column_units(columns: list[str], args: argparse.Namespace, *, required: bool
                 ) -> dict[str, str] | None:
    """SI unit per column (``--sensor`` or the column names); None when unknown and not
    `required` (then the datasheet section is left out)."""
    try:
        return {c: signal_unit(c, args.sensor) for c in columns}
    except InputError as exc:
        if required:
            raise InputError(f"{exc} (needed by --triad, --export and --report: pass --sensor)") from None
        return None


def apply_triad(results: list[SelectionResult], units: dict[str, str]
                ) -> tuple[list[SelectionResult], list[Any]]:
    """One structure per sensor (:func:`stochmod.fit.triad.triad_select`): the selections with
    their ``best`` replaced by each axis's fit of that structure, and the choices."""
    from stochmod.fit.triad import group_triads, triad_select

    by_col = {r.column: r for r in results}
    choices = []
    for cols in group_triads(list(by_col), units).values():
        choice = triad_select([by_col[c] for c in cols], units)
        choices.append(choice)
        for c in cols:
            by_col[c] = attrs.evolve(by_col[c], best=choice.fits[c])
    return [by_col[r.column] for r in results], choices


def datasheet_section(results: list[SelectionResult], data: np.ndarray,
                      units: dict[str, str], readings: Sequence[AllanReading] | None = None
                      ) -> dict[str, Datasheet]:
    """Datasheet of every column (model beside the Allan reading of its data; `readings`:
    those readings made already, in the columns' order)."""
    if readings is not None:
        return {sel.column: datasheet(sel.best, units[sel.column], column=sel.column, reading=r)
                for sel, r in zip(results, readings, strict=True)}
    return {sel.column: datasheet(sel.best, units[sel.column], column=sel.column, x=data[:, k])
            for k, sel in enumerate(results)}


def write_exports_for(args: argparse.Namespace, results: list[SelectionResult],
                      units: dict[str, str], out: Path) -> list[Path]:
    """The ``--export`` files."""
    if not args.export:
        return []
    return write_exports(args.export, {s.column: s.best for s in results}, units, out,
                         horizon=args.export_horizon, rostopic=args.rostopic)


def write_report_for(args: argparse.Namespace, results: list[SelectionResult], data: np.ndarray,
                     sheets: dict[str, Datasheet], exported: list[Path], triads: list[Any],
                     title: str, out: Path) -> list[Path]:
    """``OUT/report.html`` (with ``--report``)."""
    if not args.report:
        return []
    from stochmod.fit.validation import validate
    from stochmod.output.html_report import ReportAxis, write_report

    axes = []
    for k, sel in enumerate(results):
        bands = validate(sel.best, data[:, k], R=args.n_sim, rng=args.seed)
        axes.append(ReportAxis(sel.column, sel, sheets[sel.column], bands,
                               note="" if not triads else "model structure chosen per triad"))
    exports = {p.name: p.read_text() for p in exported}
    path = write_report(out / "report.html", axes, title=title, exports=exports,
                        extra=[t.summary() for t in triads])
    return [path]
