"""``stochmod calibrate``: the main job on the command line. It reads the recording, calls the
library's main job (:mod:`stochmod.workflows.calibrate`), writes ``calibration.json``
(:class:`stochmod.io.calibration.Calibration`), the figures, exports and report, and prints
one block per axis."""

from __future__ import annotations

import argparse
import concurrent.futures
import contextlib
import functools
import importlib
import multiprocessing
import re
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import attrs
import numpy as np

from stochmod.cli import FLEET_WARM_MODULE
from stochmod.cli import _calibrate_outputs as extras
from stochmod.cli._common import add_input_arguments, declared_recording, load_segments, print_json
from stochmod.cli.select import add_selection_arguments, selection_options
from stochmod.core.errors import EstimationError, InputError
from stochmod.core.parallel import process_pool, single_threaded_blas
from stochmod.core.tables import format_table
from stochmod.core.units import SENSORS
from stochmod.data.examples import DEFAULT_EXAMPLE_N, xsens_mtig
from stochmod.empirical.allan_reading import AllanReading
from stochmod.fit.results import GMWMResult
from stochmod.fit.selection import SelectionResult
from stochmod.io.recording import Recording, longest_segment
from stochmod.output.datasheet import datasheet_reading
from stochmod.workflows.calibrate import (
    CalibrationRun,
    assemble,
    column_unit,
    prepare,
    select_column,
    select_columns,
)
from stochmod.workflows.fleet import SerialExecutor, UnitSteps, run_fleet

if TYPE_CHECKING:
    from stochmod.output.html_report import ReportAxis

__all__ = [
    "SIMULATIONS_PER_TASK",
    "UNIT_STEPS",
    "ColumnResult",
    "UnitInput",
    "calibrate_file",
    "calibrate_unit",
    "finish_unit",
    "read_unit",
    "register",
    "run",
    "select_unit_column",
    "unit_columns",
]

#: Simulated series per task of the figures on a pool (``--n-sim 20``: two tasks a column).
SIMULATIONS_PER_TASK = 10
#: The matplotlib modules of the figures: imported by this process while it reads the file,
#: so that the pool's workers, forked afterwards, inherit them (one import instead of one in
#: each worker).
_MATPLOTLIB = ("matplotlib.figure", "matplotlib.backends.backend_agg")
#: What the pool's workers import as they start when they will draw figures.
_FIGURE_MODULES = (*_MATPLOTLIB, "stochmod.output.html_report", "stochmod.output.plots")


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``calibrate`` subcommand."""
    p = subparsers.add_parser(
        "calibrate",
        help="select and fit a noise model per column, export the EKF augmentation (main job)",
        description=(
            "Select a composite noise model for each column by the GMWM and the wavelet-variance "
            "information criterion, print the selected models with physical parameters, 95% "
            "intervals and J-tests, and write OUT/calibration.json (per column: selected spec, "
            "physical parameters, ranking, EKF augmentation Phi, Q, H, P0, white_var at --dt; and "
            "the whole IMU's augmentation) and, with matplotlib, OUT/<column>.png. Without FILE it "
            "runs on the bundled example: a simulated XSens MTi-G (Stebler et al. 2014, Table II), "
            "gyro_x/y/z in rad/s and accel_x/y/z in m/s^2 at 100 Hz."
        ),
    )
    add_input_arguments(p, file_required=False)
    add_selection_arguments(p)
    p.add_argument("--dt", type=float, default=None, metavar="DT",
                   help="Kalman filter step in s for the augmentation (default 1/freq)")
    p.add_argument("--out", default="stochmod-calibration", metavar="DIR",
                   help="output folder (default ./stochmod-calibration)")
    p.add_argument("--scale", type=float, default=1.0,
                   help="multiply the data by this factor first, e.g. 0.017453292519943295 for "
                        "deg/s -> rad/s (default 1)")
    p.add_argument("--n", type=int, default=DEFAULT_EXAMPLE_N,
                   help=f"samples per column of the bundled example (no FILE; default {DEFAULT_EXAMPLE_N})")
    p.add_argument("--n-sim", type=int, default=0,
                   help="series simulated from each fit, the data's length each, whose 95%% band "
                        "the figures draw beside the model's (default 0: the model's band only, "
                        "the band of the verdict)")
    p.add_argument("--no-plots", action="store_true", help="do not write figures")
    p.add_argument("--jobs", type=int, default=2, metavar="N",
                   help="worker processes for the selection's fits and the figures (default 2; "
                        "1: all in this process)")
    p.add_argument("--verbose", action="store_true",
                   help="print every parameter, the runner-up of each selection, the triad "
                        "criteria and the datasheets' parameter tables")
    p.add_argument("--keep-fitted", action="store_true",
                   help="use the models as fitted: do not replace a component that is a simpler "
                        "term on the record (a GM of Tc below the sampling interval by white "
                        "noise, beyond the record by a random walk)")
    extras.add_output_arguments(p)
    p.add_argument("--pooled", action="store_true",
                   help="FILE FILE ...: replicates of one sensor model; fit one model per column "
                        "from their pooled wavelet variance, and test whether they share it "
                        "(without it, several FILEs are a fleet: one calibration each)")
    p.set_defaults(func=run, require_units=True)


def _input(args: argparse.Namespace) -> tuple[list[Recording], float]:
    """The recording's gap-free segments (one without gaps, several with ``--split-gaps``)."""
    if args.file is None:
        # reader options (stochmod.cli._common) apply to files only
        given = [f"--{o.replace('_', '-')}" for o in ("reader", "topic", "instance", "unit",
                                                       "gyro_unit", "accel_unit")
                 if getattr(args, o) is not None] + (["--split-gaps"] if args.split_gaps else [])
        if given:
            verb = "applies" if len(given) == 1 else "apply"
            raise InputError(f"{', '.join(given)} {verb} to a FILE, not to the bundled example")
        rec = declared_recording(xsens_mtig(n=args.n).select(args.column), args, required=True)
        if args.freq is not None and args.freq != rec.freq:
            raise InputError(f"--freq {args.freq:g} does not apply to the bundled example ({rec.freq:g} Hz)")
        return [rec], float(rec.freq)
    if args.n != DEFAULT_EXAMPLE_N:
        raise InputError("--n applies to the bundled example only (no FILE)")
    return load_segments(args)


def _filename(column: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", column).strip("_") or "column"


def _simulations(fit: GMWMResult, n_sim: int, seed: int, start: int, stop: int) -> np.ndarray:
    """Series ``start:stop`` of the `n_sim` simulated WVs of a column's figure (module level:
    runs in a worker process)."""
    from stochmod.output.plots import simulated_wv

    return simulated_wv(fit, n_sim, seed, indices=slice(start, stop))


def _draw(run_: CalibrationRun, k: int, out: Path, n_sim: int, seed: int,
          simulated: np.ndarray | None) -> ReportAxis | None:
    """Column `k`'s figure, written to ``OUT/<column>.png``: for a sensor column the report's
    (:func:`stochmod.output.html_report.axis_figure`, returned with its PNG for the report),
    for another column the fit's validation figure (:func:`stochmod.output.plots.plot_fit`,
    None returned); with the band of its `simulated` WVs when there are some
    (:func:`stochmod.validate` of those series)."""
    from stochmod.fit.validation import validate
    from stochmod.output.html_report import axis_figure_png
    from stochmod.output.plots import save_fit_figure

    sel = run_.selections[k]
    fit, path = sel.best, out / f"{_filename(sel.column)}.png"
    if sel.column not in run_.datasheets:
        save_fit_figure(fit, path, n_sim=n_sim, rng=seed, title=f"{sel.column}: {fit.model.name}",
                        unit=run_.record.unit_map().get(sel.column) or "u", simulated=simulated)
        return None
    bands = None
    if simulated is not None:
        bands = validate(fit, fit.empirical, R=n_sim, rng=seed, psd=False, simulated=simulated)
    axis = extras.report_axis(run_, k, bands=bands)
    png = axis_figure_png(axis)
    path.write_bytes(png)
    return attrs.evolve(axis, figure=png)


def _beside(executor: Any) -> Any:
    """`executor` when its tasks run beside this process (worker processes), else None (none
    given, or the in-process :class:`~stochmod.workflows.fleet.SerialExecutor`)."""
    return None if executor is None or isinstance(executor, SerialExecutor) else executor


def _start_figures(run_: CalibrationRun, out: Path, n_sim: int, seed: int,
                   executor: Any = None, first: int = 2) -> Callable[[], list[ReportAxis | None]]:
    """Start drawing each column's figure (:func:`_draw`); the call returned waits for them
    and gives what :func:`_figures` gives.

    Without simulations and on a pool of worker processes, the first `first` figures (one a
    worker) go to the workers at once (the selection has left them idle), and this process
    solves the exports' bounds meanwhile; the report's Allan overview, which shows them
    (:func:`~stochmod.cli._calibrate_outputs.report_overview`), is submitted next, and the
    other figures when the returned call is made, so that the overview, the longest task,
    does not run last beside an idle worker. Otherwise the figures are drawn when the
    returned call is made (:func:`_figures`). The figures are the same either way.
    """
    import importlib.util

    if importlib.util.find_spec("matplotlib") is None:
        return list
    if n_sim > 0 or _beside(executor) is None:
        return functools.partial(_figures, run_, out, n_sim, seed, executor)
    from stochmod.output.html_report import axis_figure_png
    from stochmod.output.plots import save_fit_figure

    def submit(k: int) -> tuple[ReportAxis | None, Path, concurrent.futures.Future]:
        sel = run_.selections[k]
        fit, path = sel.best, out / f"{_filename(sel.column)}.png"
        if sel.column in run_.datasheets:
            axis = extras.report_axis(run_, k)
            return axis, path, executor.submit(axis_figure_png, axis.for_figures())
        unit = run_.record.unit_map().get(sel.column) or "u"  # the worker writes the file
        return None, path, executor.submit(save_fit_figure, fit, path, n_sim=0, rng=seed,
                                           title=f"{sel.column}: {fit.model.name}", unit=unit)

    tasks = [submit(k) for k in range(min(first, len(run_.selections)))]

    def drawn() -> list[ReportAxis | None]:
        tasks.extend(submit(k) for k in range(len(tasks), len(run_.selections)))
        axes: list[ReportAxis | None] = []
        for axis, path, future in tasks:
            png = future.result()
            if axis is None:
                axes.append(None)
            else:
                path.write_bytes(png)
                axes.append(attrs.evolve(axis, figure=png))
        return axes

    return drawn


def _figures(run_: CalibrationRun, out: Path, n_sim: int, seed: int,
             executor: Any = None) -> list[ReportAxis | None]:
    """Each column's figure (:func:`_draw`), the same PNG that the report shows; with
    `n_sim` series simulated from each fit (the data's length each), the band of the
    simulations besides the model's.

    On a pool, the simulations go to the workers in tasks of :data:`SIMULATIONS_PER_TASK`
    series, the columns with the most components first (the longest tasks first balance the
    two workers best), and this process, which would otherwise wait, draws each figure as
    soon as its simulations are in; the figures are the same as drawn in one piece (series i
    draws from the i-th child of `seed` however the series are split).
    """
    import importlib.util

    if importlib.util.find_spec("matplotlib") is None:
        return []
    results = list(run_.selections)
    if n_sim == 0:
        return [_draw(run_, k, out, n_sim, seed, None) for k in range(len(results))]
    if _beside(executor) is None:  # no overlap
        def call(fn: Any, *args: Any) -> Any:
            return fn(*args) if executor is None else executor.submit(fn, *args).result()

        return [_draw(run_, k, out, n_sim, seed, call(_simulations, sel.best, n_sim, seed, 0, n_sim))
                for k, sel in enumerate(results)]
    spans = [(a, min(a + SIMULATIONS_PER_TASK, n_sim)) for a in range(0, n_sim, SIMULATIONS_PER_TASK)]
    longest_first = sorted(range(len(results)), key=lambda k: -len(results[k].best.model.processes))
    futures = {executor.submit(_simulations, results[k].best, n_sim, seed, a, b): (k, i)
               for k in longest_first for i, (a, b) in enumerate(spans)}
    parts: list[dict[int, np.ndarray]] = [{} for _ in results]
    drawn: dict[int, ReportAxis] = {}
    try:
        for future in concurrent.futures.as_completed(futures):
            k, i = futures[future]
            parts[k][i] = future.result()
            if len(parts[k]) == len(spans):
                simulated = np.vstack([parts[k][i] for i in range(len(spans))])
                drawn[k] = _draw(run_, k, out, n_sim, seed, simulated)
    except BaseException:
        for future in futures:
            future.cancel()
        raise
    return [drawn[k] for k in range(len(results))]


@contextlib.contextmanager
def _importing(modules: tuple[str, ...]) -> Iterator[None]:
    """Import `modules` on a thread of this process while the block runs (the file is read
    meanwhile), and wait for them at the block's end, before any pool forks: workers forked
    afterwards inherit them instead of each importing them. A module that is not installed
    or fails to import is left to the task that needs it, which reports the cause."""
    if not modules:
        yield
        return

    def load() -> None:
        for name in modules:
            try:
                importlib.import_module(name)
            except Exception:  # noqa: BLE001 - a lost head start only, never a traceback here
                return

    thread = threading.Thread(target=load, name="stochmod-figure-imports", daemon=True)
    thread.start()
    try:
        yield
    finally:
        thread.join()


@contextlib.contextmanager
def _pool(executor: Any, jobs: int, warm: tuple[str, ...] = ()) -> Iterator[Any]:
    """`executor` when given; else one pool of `jobs` worker processes for the selection's fits
    and the figures, which import the modules `warm` as they start (1: everything in this
    process)."""
    if executor is not None:
        yield executor
    elif jobs == 1:
        yield SerialExecutor()
    else:
        with process_pool(jobs, warm) as pool:
            yield pool




def _replicates(args: argparse.Namespace) -> tuple[list[list[Recording]], float]:
    """The replicate recordings of ``--pooled`` (same columns, same frequency), each as its
    gap-free segments (one without ``--split-gaps``), the units converted to SI."""
    if args.file is None or not args.more_files:
        raise InputError("--pooled needs two or more FILEs (replicates of one sensor model)")
    read = [load_segments(args, path) for path in [args.file, *args.more_files]]
    first = read[0][0][0]
    for segs, _ in read[1:]:
        if segs[0].columns != first.columns:
            raise InputError(f"{segs[0].path} has columns {list(segs[0].columns)}, {first.path} "
                             f"has {list(first.columns)}: replicates must share them (--column)")
    freqs = {freq for _, freq in read}
    if len(freqs) != 1:
        raise InputError(f"the replicates have different sampling frequencies {sorted(freqs)}")
    return [segs for segs, _ in read], freqs.pop()


def _run_pooled(args: argparse.Namespace) -> int:
    """``--pooled``: one selection per column on the replicates' pooled wavelet variance."""
    files, freq = _replicates(args)
    segments = _scaled(args, prepare([s for segs in files for s in segs]))
    extras.check_drift_request(args, segments[0].columns)
    dt = _dt(args, freq)
    sizes = [sum(int(s.data.shape[0]) for s in segs) for segs in files]
    options = selection_options(args)
    results = [select_column(segments, freq, k, **options)
               for k in range(len(segments[0].columns))]
    tests = {}
    for sel in results:
        test = sel.best.pooled.test  # the selection's pooling of the replicates
        tests[sel.column] = None if test is None else attrs.asdict(test)
    extra = {"scale": args.scale,
             "replicates": {"files": [segs[0].path for segs in files], "n": sizes,
                            "segments": len(segments), "equality_test": tests}}
    run_ = assemble(segments, freq, results, dt=dt, replace=not args.keep_fitted, extra=extra)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    path = run_.calibration.write(out / "calibration.json")
    drift, drift_files = extras.predict_drift(args, run_.calibration, out)
    if args.json:
        print_json(run_.calibration.to_dict())
        return 0
    print(_console(run_, args, f"{sum(sizes)} samples in {len(files)} replicates"))
    if drift is not None:
        print("\n" + extras.drift_line(drift))
    print(format_table(["column", "equality Q", "dof", "p-value"],
                       [[c, t["statistic"], t["dof"], t["pvalue"]] if t else [c, "-", "-", "-"]
                        for c, t in tests.items()],
                       title=f"\nreplicates {', '.join(segs[0].path for segs in files)}: do they "
                             "share one model?"))
    print(f"\nwrote {', '.join(str(p) for p in [path, *drift_files])}")
    return 0


def run(args: argparse.Namespace) -> int:
    """Select, fit, report and write calibration.json (+ figures); several FILEs: a fleet, or
    with ``--pooled`` replicates of one sensor model."""
    if args.pooled:
        return _run_pooled(args)
    if extras.fleet_requested(args):
        return run_fleet(args, UNIT_STEPS)
    calibrate_file(args)
    return 0


@attrs.frozen
class UnitInput:
    """A fleet unit's input, as its read task hands it on: the recording's gap-free segments
    (prepared: units declared, in SI, scaled by ``--scale``), the sampling frequency (Hz) and
    the filter step ``dt`` (s)."""

    segments: list[Recording]
    freq: float
    dt: float

    def __sizeof__(self) -> int:
        """Bytes of the samples and time stamps: what dask weighs when it considers moving the
        unit to another worker (its ``sizeof`` of an object it does not know)."""
        return object.__sizeof__(self) + sum(
            r.data.nbytes + (0 if r.time is None else r.time.nbytes) for r in self.segments)


def _scaled(args: argparse.Namespace, segments: list[Recording]) -> list[Recording]:
    if not args.scale > 0:
        raise InputError(f"--scale must be positive, got {args.scale}")
    if args.scale == 1.0:  # x * 1.0 is x: no copy of the samples for the default
        return segments
    return [attrs.evolve(r, data=r.data * args.scale) for r in segments]


def _dt(args: argparse.Namespace, freq: float) -> float:
    dt = 1.0 / freq if args.dt is None else args.dt
    if not dt > 0:
        raise InputError(f"--dt must be a positive number of seconds, got {args.dt}")
    return dt


def _check_outputs(args: argparse.Namespace, segments: list[Recording]) -> None:
    """Refuse, before any selection, the outputs that need sensor columns when one is not."""
    rec = segments[0]
    others = [c for k, c in enumerate(rec.columns) if rec.declared[k].kind not in SENSORS]
    wanted = [o for o, on in (("--triad", args.triad), ("--export", args.export),
                              ("--report", args.report)) if on]
    if others and wanted:
        raise InputError(f"{', '.join(wanted)} need gyro and accelerometer columns; "
                         f"{', '.join(others)} is neither by its name or the file: name the "
                         "columns (gyro_x ... accel_z), pass --sensor, or leave them out "
                         "(--column)")
    extras.check_drift_request(args, rec.columns)


def read_unit(args: argparse.Namespace, executor: SerialExecutor) -> UnitInput:
    """A unit's input (a fleet's first step, and :func:`calibrate_file`'s): its file read and
    prepared (:func:`stochmod.workflows.calibrate.prepare`), the options checked before any
    selection."""
    with executor.stage("read"):
        segments, freq = _input(args)
        segments = _scaled(args, prepare(segments))
    _check_outputs(args, segments)
    selection_options(args)
    return UnitInput(segments, freq, _dt(args, freq))


def unit_columns(unit: UnitInput) -> list[str]:
    """The columns of a fleet unit, one selection task each."""
    return list(unit.segments[0].columns)


@attrs.frozen
class ColumnResult:
    """What a fleet unit's column task hands on: the column's selection and the Allan reading
    of its data for the datasheet (None when the column is not a gyro or accelerometer)."""

    selection: SelectionResult
    reading: AllanReading | None


def select_unit_column(args: argparse.Namespace, unit: UnitInput, k: int,
                       executor: SerialExecutor) -> ColumnResult:
    """A fleet unit's column `k` alone: its selection
    (:func:`stochmod.workflows.calibrate.select_column`) and the Allan reading of its
    datasheet."""
    result = select_column(unit.segments, unit.freq, k, executor=executor,
                           **selection_options(args))
    rec = longest_segment(unit.segments)
    if rec.declared[k].kind not in SENSORS:
        return ColumnResult(result, None)
    with executor.stage("allan"):
        reading = datasheet_reading(rec.data[:, k], unit.freq, column_unit(rec, k))
    return ColumnResult(result, reading)


def finish_unit(args: argparse.Namespace, unit: UnitInput, columns: list[ColumnResult],
                executor: SerialExecutor) -> dict[str, Any]:
    """A fleet unit's last step: its outputs from its columns' tasks; its calibration's JSON
    content."""
    return _outputs(args, unit, [c.selection for c in columns], executor, quiet=True,
                    readings=[c.reading for c in columns])


def calibrate_unit(args: argparse.Namespace, executor: SerialExecutor) -> dict[str, Any]:
    """A fleet unit in one task: the quiet single-file calibration with its work items run in
    the calling thread by `executor`; its calibration's JSON content."""
    return calibrate_file(args, executor=executor, quiet=True)


#: The single-file calibration as a fleet runs it (:func:`stochmod.workflows.fleet.run_fleet`).
UNIT_STEPS = UnitSteps(calibrate_unit, read_unit, unit_columns, select_unit_column, finish_unit,
                       warm_module=FLEET_WARM_MODULE)


def calibrate_file(args: argparse.Namespace, executor: Any = None, quiet: bool = False
                   ) -> dict[str, Any]:
    """The single-file calibration: writes OUT/calibration.json (and the asked outputs), prints
    one block per axis (or the JSON with ``--json``; nothing when `quiet`) and returns the
    calibration's JSON content. `executor` runs the selection's fits and the figures (default:
    a pool of ``args.jobs`` worker processes)."""
    jobs = getattr(args, "jobs", 2)
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise InputError(f"--jobs must be a positive number of worker processes, got {jobs!r}")
    # the workers draw the figures after the fits
    warm = () if args.no_plots and not args.report else _FIGURE_MODULES
    forking = executor is None and jobs > 1 and multiprocessing.get_start_method() == "fork"
    with _importing(_MATPLOTLIB if warm and forking else ()):
        unit = read_unit(args, executor if isinstance(executor, SerialExecutor)
                         else SerialExecutor())
    with single_threaded_blas(), _pool(executor, jobs, warm) as pool:
        results = select_columns(unit.segments, unit.freq, executor=pool,
                                 **selection_options(args))
        return _outputs(args, unit, results, pool, quiet)


def _outputs(args: argparse.Namespace, unit: UnitInput, results: list[SelectionResult],
             pool: Any, quiet: bool, readings: list[AllanReading | None] | None = None
             ) -> dict[str, Any]:
    """:func:`calibrate_file` once the columns are selected: the calibration
    (:func:`stochmod.workflows.calibrate.assemble`), its file, the figures, exports and report,
    and the console (`readings`: the columns' Allan readings for the datasheet, when made
    already)."""
    segments = unit.segments
    run_ = assemble(segments, unit.freq, results, dt=unit.dt, triad=args.triad,
                    replace=not args.keep_fitted, readings=readings,
                    extra={"scale": args.scale})
    cal = run_.calibration
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    path = cal.write(out / "calibration.json")
    report = cal.to_dict()
    sensors = {a.column: a.unit for a in cal.axes if a.kind in SENSORS}
    drawing = list if args.no_plots else _start_figures(run_, out, args.n_sim, args.seed, pool,
                                                        first=getattr(args, "jobs", 2))
    noise = extras.export_noise(args, cal)  # the files' terms, shown again by the report
    exported = extras.write_exports_for(args, cal, sensors, out, noise)
    overview = extras.report_overview(args, run_, noise, _beside(pool))
    # the drift runs on a thread of this process while the last figures are submitted and
    # drawn (its filter's loops release the GIL; the workers are not kept waiting for it)
    with concurrent.futures.ThreadPoolExecutor(1) as side:
        predicting = side.submit(extras.predict_drift, args, cal, out)
        drawn = drawing()
        drift, drift_files = predicting.result()
    rec = run_.record
    figures = [out / f"{_filename(s.column)}.png" for s in run_.selections[:len(drawn)]]
    samples = f"{cal.n} samples" + (f" in {len(segments)} gap-free segments"
                                    if len(segments) > 1 else "")
    title = (f"stochmod calibration of {rec.path or 'the bundled example'} "
             f"({samples} at {unit.freq:g} Hz)")
    figures += extras.write_report_for(args, run_, exported, title, out, drawn, noise, overview(),
                                       drift)
    if quiet:
        return report
    if args.json:
        print_json(report)
        return report
    print(_console(run_, args, samples))
    if drift is not None:
        print("\n" + extras.drift_line(drift))
    written = [str(path)] + [str(f) for f in exported + drift_files + figures]
    print(f"\nwrote {', '.join(written)}")
    return report


def _console(run_: CalibrationRun, args: argparse.Namespace, samples: str) -> str:
    """One block per axis: the final model, its verdict, what was replaced, the datasheet's
    summary; ``--verbose`` adds every parameter, the runner-up and the triad criteria."""
    cal = run_.calibration
    crit = run_.selections[0].criterion if run_.selections else "-"
    lines = [(f"stochmod calibrate: {cal.source or 'the bundled example'} ({samples} x "
             f"{len(cal.axes)} column(s) at {cal.freq:g} Hz); selected by {crit}")]
    for axis, sel, fin, judged in zip(cal.axes, run_.selections, run_.finals, run_.verdicts):
        declared = (cal.extra.get("units") or {}).get("declared") or {}
        source = (declared.get(axis.column) or {}).get("source")
        unit = f"{axis.unit or 'unit unknown'}" + (" (assumed)" if source == "assumed" else "")
        lines += ["", f"{axis.column} ({axis.kind}, {unit}): {axis.model.name}",
                  f"  verdict: {judged.summary()}"]
        if sel.refit_note:
            lines.append(f"  {sel.refit_note}")
        for r in fin.replacements:
            lines.append(f"  fitted {fin.fitted.model.name}: {r.summary()}")
        sheet = run_.datasheets.get(axis.column)
        if sheet is not None:
            table = format_table(*sheet.summary_table(), digits=4)
            lines += ["  " + line for line in table.splitlines()]
        if args.verbose:
            lines += ["", _parameters(sel.best, axis.unit), "",
                      _runner_up(sel)]
    if args.verbose:
        lines += ["\n" + t.summary() for t in run_.triads]
        lines += ["\n" + d.summary() for d in run_.datasheets.values()]
    elif run_.triads:
        chosen = "; ".join(f"{', '.join(t.columns)}: {t.structure}" for t in run_.triads)
        lines += ["", f"structures chosen per triad: {chosen} (--verbose: criteria)"]
    for sel in run_.selections:
        if sel.empirical.contamination is not None:
            lines += ["", f"{sel.column}: {sel.empirical.contamination.summary()}"]
    return "\n".join(lines)


def _parameters(fit: GMWMResult, unit: str | None) -> str:
    rows = []
    try:
        physical = fit.physical()
    except EstimationError:  # a fit that is not identified has no intervals
        physical = []
    for e in physical:
        shown = re.sub(r"\bu\b", f"({unit})", e.unit) if unit else e.unit
        rows.append([e.name, e.value, e.low, e.high, shown])
    return format_table(["parameter", "value", "95% low", "95% high", "unit"], rows)


def _runner_up(sel: SelectionResult) -> str:
    if len(sel.ranking) < 2:
        return f"{sel.column}: the only candidate"
    first, second = sel.ranking[0], sel.ranking[1]
    return (f"{sel.column}: selected {first.model}, runner-up {second.model} "
            f"(criterion gap {second.criterion - first.criterion:.4g})")
