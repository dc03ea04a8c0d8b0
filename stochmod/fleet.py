"""Calibrate a fleet of IMUs in one run, on a dask.distributed cluster or serially.

``stochmod calibrate A.npz B.npz ... --workers N`` (a local cluster of N single-threaded
worker processes) or ``--scheduler tcp://host:8786`` (an existing cluster, any number of
machines) runs the single-file calibration of every file as one task, writing ``OUT/<file
stem>/`` each, then the fleet table ``OUT/fleet.csv``.  Without ``--workers`` or
``--scheduler`` the files are calibrated one after the other.  Each file's selection runs its
fits in the task's own thread (the task is the unit of parallelism), and every fit is seeded
from ``--seed`` and the candidate only, so a fleet run gives exactly the results of a serial
run, whatever the cluster.

The fleet table compares the units on what every model has, whatever its structure: the
datasheet summary of each axis (white-noise density, bias instability, random walk; see
:mod:`stochmod.datasheet`).  A unit is flagged as an outlier on a quantity when its robust
z-score on the log scale,

    z = (ln v - median(ln v)) / (1.4826 MAD(ln v)),

exceeds :data:`OUTLIER_Z` = 3.5 in absolute value (Iglewicz and Hoaglin's modified z-score;
the log because noise coefficients are positive and spread multiplicatively; 1.4826 MAD
estimates the standard deviation of a normal sample).  With fewer than :data:`MIN_UNITS`
units, or a MAD of zero, nobody is flagged.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import contextlib
import copy
import csv
import math
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import attrs
import numpy as np

from stochmod.errors import InputError
from stochmod.reporting import format_table

__all__ = ["OUTLIER_Z", "MIN_UNITS", "FleetRow", "fleet_rows", "robust_z", "write_fleet_csv",
           "run_fleet", "calibrate_files", "unit_folders", "SerialExecutor", "CalibrateOne"]

#: |robust z| above which a unit is an outlier on a quantity.
OUTLIER_Z = 3.5
#: Fewest units for which outliers are flagged.
MIN_UNITS = 4
_MAD_TO_SD = 1.4826


@attrs.frozen
class FleetRow:
    """One unit's value of one datasheet quantity of one axis, within the fleet."""

    unit_name: str
    column: str
    quantity: str
    unit: str
    value: float
    median: float
    mad: float
    z: float
    outlier: bool


def robust_z(values: Sequence[float]) -> tuple[np.ndarray, float, float]:
    """Robust z-scores of positive `values` on the log scale, with the median and MAD (of the
    logs); z is NaN where a value is not positive and finite, 0 with a MAD of zero."""
    v = np.asarray(values, dtype=float)
    ok = np.isfinite(v) & (v > 0)
    logs = np.log(np.where(ok, v, np.nan))
    med = float(np.nanmedian(logs)) if ok.any() else math.nan
    mad = float(np.nanmedian(np.abs(logs - med))) if ok.any() else math.nan
    with np.errstate(invalid="ignore", divide="ignore"):
        z = np.where(ok, (logs - med) / (_MAD_TO_SD * mad) if mad > 0 else 0.0, np.nan)
    return z, med, mad


def fleet_rows(reports: dict[str, dict[str, Any]]) -> list[FleetRow]:
    """Fleet table from each unit's ``calibration.json`` content (with its ``datasheet``)."""
    values: dict[tuple[str, str, str], dict[str, float]] = {}
    for name, report in reports.items():
        for col, ds in (report.get("datasheet") or {}).items():
            for row in ds["summary"]:
                if row["model"] is not None:
                    values.setdefault((col, row["quantity"], row["unit"]), {})[name] = row["model"]
    rows = []
    for (col, quantity, unit), by_unit in values.items():
        names = list(by_unit)
        z, med, mad = robust_z([by_unit[n] for n in names])
        flag = len(names) >= MIN_UNITS
        for n, zi in zip(names, z):
            rows.append(FleetRow(n, col, quantity, unit, by_unit[n], math.exp(med), mad, float(zi),
                                 bool(flag and np.isfinite(zi) and abs(zi) > OUTLIER_Z)))
    return rows


def write_fleet_csv(path: Path, rows: Sequence[FleetRow]) -> Path:
    """Write the fleet table (one line per unit, axis and quantity)."""
    fields = [f.name for f in attrs.fields(FleetRow)]
    with open(path, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(fields)
        for r in rows:
            writer.writerow([getattr(r, f) for f in fields])
    return path


def unit_folders(files: Sequence[str], out: Path) -> dict[str, Path]:
    """``OUT/<file stem>`` per file; two files with one stem are refused (they would collide)."""
    folders: dict[str, Path] = {}
    for f in files:
        stem = Path(f).name.split(".")[0] if Path(f).is_file() else Path(f).name
        if stem in folders:
            raise InputError(f"two files have the stem {stem!r}: their result folders would collide")
        folders[stem] = out / stem
    return folders


#: The single-file calibration of one unit: its argument namespace in, its report dict out.
CalibrateOne = Callable[[argparse.Namespace], dict[str, Any]]


class SerialExecutor(concurrent.futures.Executor):
    """Runs each submitted call at once in the caller's thread (the task is the parallel unit)."""

    def submit(self, fn: Any, /, *args: Any, **kwargs: Any) -> concurrent.futures.Future:
        future: concurrent.futures.Future = concurrent.futures.Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except BaseException as exc:  # handed to the caller through the future
            future.set_exception(exc)
        return future


@contextlib.contextmanager
def _client(workers: int | None, scheduler: str | None) -> Iterator[Any]:
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise ImportError('fleet runs need dask.distributed: pip install "stochmod[fleet]"') from None
    if scheduler:
        with Client(scheduler) as client:
            yield client
    else:
        with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                          dashboard_address=None) as cluster, Client(cluster) as client:
            yield client


def calibrate_files(tasks: Sequence[argparse.Namespace], calibrate_one: CalibrateOne,
                    workers: int | None = None, scheduler: str | None = None
                    ) -> list[dict[str, Any]]:
    """Run `calibrate_one` (the single-file calibration, a module-level function so that dask
    can ship it) on each task: serially, or one dask task per file."""
    if workers is None and scheduler is None:
        return [calibrate_one(t) for t in tasks]
    with _client(workers, scheduler) as client:
        futures = client.map(calibrate_one, list(tasks), pure=False)
        return client.gather(futures)


def run_fleet(args: argparse.Namespace, calibrate_one: CalibrateOne) -> int:
    """``stochmod calibrate FILE FILE ...``: every file through `calibrate_one` (the CLI's
    quiet single-file calibration, returning its report dict), then ``OUT/fleet.csv``."""
    files = [args.file, *args.more_files]
    if args.file is None:
        raise InputError("a fleet run needs FILE arguments (the bundled example is one unit)")
    if args.workers is not None and args.workers < 1:
        raise InputError(f"--workers must be a positive integer, got {args.workers}")
    if args.workers is not None and args.scheduler:
        raise InputError("give --workers (a local cluster) or --scheduler (an existing one), not both")
    out = Path(args.out)
    folders = unit_folders(files, out)
    tasks = []
    for f, (stem, folder) in zip(files, folders.items()):
        task = copy.copy(args)
        task.file, task.more_files, task.out = f, [], str(folder)
        tasks.append(task)
    reports = calibrate_files(tasks, calibrate_one, args.workers, args.scheduler)
    out.mkdir(parents=True, exist_ok=True)
    rows = fleet_rows(dict(zip(folders, reports)))
    path = write_fleet_csv(out / "fleet.csv", rows)
    print(_fleet_summary(rows, len(files)))
    print(f"\nwrote {', '.join(str(p) for p in folders.values())} and {path}")
    return 0


def _fleet_summary(rows: Sequence[FleetRow], n_units: int) -> str:
    groups: dict[tuple[str, str, str], list[FleetRow]] = {}
    for r in rows:
        groups.setdefault((r.column, r.quantity, r.unit), []).append(r)
    table = []
    for (col, quantity, unit), rs in groups.items():
        vals = [r.value for r in rs]
        flagged = ", ".join(r.unit_name for r in rs if r.outlier) or "-"
        table.append([col, quantity, unit, rs[0].median, min(vals), max(vals), flagged])
    return format_table(["column", "quantity", "unit", "median", "min", "max", "outliers"], table,
                        title=f"Fleet of {n_units} units (outliers: |robust z| > {OUTLIER_Z:g} "
                              "on the log scale)", digits=4)
