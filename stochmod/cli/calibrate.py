"""``stochmod calibrate``: the main job. Select and fit a model per column, report, and export
the Kalman-filter augmentation (``calibration.json``) and validation figures."""

from __future__ import annotations

import argparse
import concurrent.futures
import contextlib
import json
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import attrs
import numpy as np

from stochmod.cli import FLEET_WARM_MODULE
from stochmod.cli import _calibrate_outputs as extras
from stochmod.cli._common import (add_input_arguments, column_replicates, declared_recording,
                                  load_segments, longest_segment, print_json, to_jsonable)
from stochmod.cli.select import add_selection_arguments, select_columns, selection_options
from stochmod.output.datasheet import datasheet_reading
from stochmod.core.errors import EstimationError, InputError
from stochmod.workflows.fleet import SerialExecutor, UnitSteps, run_fleet
from stochmod.data.examples import DEFAULT_EXAMPLE_N, XSENS_UNITS, xsens_mtig
from stochmod.fit.results import GMWMResult
from stochmod.fit.selection import SelectionResult, select
from stochmod.fit.verdict import verdict
from stochmod.io.recording import Recording
from stochmod.core.model import augment_axes
from stochmod.core.tables import format_table
from stochmod.empirical.allan_reading import AllanReading
from stochmod.core.statespace import StateSpaceBlock
from stochmod.core.units import SENSORS

__all__ = ["register", "run", "calibrate_file", "calibration_report", "SIMULATIONS_PER_TASK",
           "UnitInput", "ColumnResult", "UNIT_STEPS", "calibrate_unit", "read_unit",
           "unit_columns", "select_unit_column", "finish_unit"]

#: Simulated series per task of the figures on a pool (the default 20 a column: two tasks).
SIMULATIONS_PER_TASK = 10


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
    p.add_argument("--n-sim", type=int, default=20,
                   help="series simulated from each fit for the figures (default 20)")
    p.add_argument("--no-plots", action="store_true", help="do not write figures")
    p.add_argument("--jobs", type=int, default=2, metavar="N",
                   help="worker processes for the selection's fits and the figures (default 2; "
                        "1: all in this process)")
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


def _block_dict(block: StateSpaceBlock) -> dict[str, Any]:
    return {"state_names": list(block.state_names), "Phi": block.Phi, "Q": block.Q,
            "H": block.H, "P0": block.P0, "white_var": block.white_var, "dt": block.dt}


def _safe(fn: Any) -> Any:
    """Value of an inference accessor, or None where the fit is not identified."""
    try:
        return fn()
    except EstimationError:
        return None


def calibration_report(results: list[SelectionResult], rec: Recording, freq: float, dt: float,
                       scale: float = 1.0) -> dict[str, Any]:
    """The content of ``calibration.json`` (JSON-safe after ``to_jsonable``)."""
    columns: dict[str, Any] = {}
    for sel in results:
        best = sel.best
        phys = _safe(best.physical)
        params = _safe(best.parameters)
        jt = best.jtest
        columns[sel.column] = {
            "name": best.model.name,
            "model": best.model.to_spec(),
            "objective": best.objective,
            "parameters": None if params is None else [attrs.asdict(e) for e in params],
            "physical": None if phys is None else [attrs.asdict(e) for e in phys],
            "jtest": None if jt is None else attrs.asdict(jt),
            "criterion": sel.criterion,
            "weighting": sel.weighting,
            "ranking": [attrs.asdict(r) for r in sel.ranking],
            "augmentation": _block_dict(best.model.augment(dt)),
            "robust": sel.empirical.robust_info(),
            "verdict": verdict(best, candidates=sel.ranking).to_dict(),
        }
    imu = augment_axes({sel.column: sel.best.model for sel in results}, dt)
    return {
        "source": rec.path,
        "freq": freq,
        "dt": dt,
        "n": int(rec.data.shape[0]),
        "scale": scale,
        "columns": columns,
        "imu_augmentation": {
            "axes": list(imu.axes), "state_names": list(imu.state_names), "Phi": imu.Phi,
            "Q": imu.Q, "H": imu.H, "P0": imu.P0, "white_var": imu.white_var, "dt": dt,
        },
    }


def _filename(column: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", column).strip("_") or "column"


def _figure(fit: GMWMResult, path: Path, n_sim: int, seed: int, title: str, unit: str,
            simulated: np.ndarray | None = None) -> Path:
    """One column's validation figure (module level: runs in a worker process), with its
    `simulated` WVs when they are already computed."""
    from stochmod.output.plots import save_fit_figure

    return save_fit_figure(fit, path, n_sim=n_sim, rng=seed, title=title, unit=unit,
                           simulated=simulated)


def _simulations(fit: GMWMResult, n_sim: int, seed: int, start: int, stop: int) -> np.ndarray:
    """Series ``start:stop`` of the `n_sim` simulated WVs of a column's figure (module level:
    runs in a worker process)."""
    from stochmod.output.plots import simulated_wv

    return simulated_wv(fit, n_sim, seed, indices=slice(start, stop))


def _figures(results: list[SelectionResult], out: Path, n_sim: int, seed: int,
             units: dict[str, str], executor: Any = None) -> list[Path]:
    """The columns' figures, calibrate's second largest stage after the fits: each simulates
    `n_sim` series of the data's length.

    On a pool, the simulations go to the workers in tasks of :data:`SIMULATIONS_PER_TASK`
    series, the columns with the most components first (the longest tasks first balance the
    two workers best), and this process, which would otherwise wait, draws each figure as
    soon as its simulations are in; the figures are the same as drawn in one piece (series i
    draws from the i-th child of `seed` however the series are split).
    """
    import importlib.util

    if importlib.util.find_spec("matplotlib") is None:
        return []
    jobs = [(sel.best, out / f"{_filename(sel.column)}.png", n_sim, seed,
             f"{sel.column}: {sel.best.model.name}", units.get(sel.column, "u"))
            for sel in results]
    if executor is None:
        return [_figure(*job) for job in jobs]
    if isinstance(executor, SerialExecutor) or n_sim == 0:  # nothing to overlap
        return [f.result() for f in [executor.submit(_figure, *job) for job in jobs]]
    spans = [(a, min(a + SIMULATIONS_PER_TASK, n_sim)) for a in range(0, n_sim, SIMULATIONS_PER_TASK)]
    longest_first = sorted(range(len(jobs)), key=lambda k: -len(results[k].best.model.processes))
    futures = {executor.submit(_simulations, results[k].best, n_sim, seed, a, b): (k, i)
               for k in longest_first for i, (a, b) in enumerate(spans)}
    parts: list[dict[int, np.ndarray]] = [{} for _ in jobs]
    paths: list[Path] = [job[1] for job in jobs]
    try:
        for future in concurrent.futures.as_completed(futures):
            k, i = futures[future]
            parts[k][i] = future.result()
            if len(parts[k]) == len(spans):
                _figure(*jobs[k], simulated=np.vstack([parts[k][i] for i in range(len(spans))]))
    except BaseException:
        for future in futures:
            future.cancel()
        raise
    return paths


@contextlib.contextmanager
def _pool(executor: Any, jobs: int) -> Iterator[Any]:
    """`executor` when given; else one pool of `jobs` worker processes for the selection's fits
    and the figures (1: everything in this process)."""
    if executor is not None:
        yield executor
    elif jobs == 1:
        yield SerialExecutor()
    else:
        with concurrent.futures.ProcessPoolExecutor(max_workers=jobs) as pool:
            yield pool


def _table(results: list[SelectionResult], rec: Recording, freq: float,
           units: dict[str, str], samples: str | None = None) -> str:
    rows = []
    for sel in results:
        best = sel.best
        jt = best.jtest
        pval = "n/a" if jt is None else f"{jt.pvalue:.3g}"
        signal_unit = units.get(sel.column)
        for e in _safe(best.physical) or []:
            unit = re.sub(r"\bu\b", f"({signal_unit})", e.unit) if signal_unit else e.unit
            rows.append([sel.column, best.model.name, e.name, e.value, e.low, e.high, unit, pval])
    samples = samples or f"{rec.data.shape[0]} samples"
    title = (f"stochmod calibrate: {rec.path} ({samples} x {len(results)} "
             f"column(s) at {freq:g} Hz); selected by {results[0].criterion}")
    return format_table(["column", "model", "parameter", "value", "95% low", "95% high", "unit",
                         "J-test p"], rows, title=title)


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
    segments = [s for segs in files for s in segs]
    sizes = [sum(int(s.data.shape[0]) for s in segs) for segs in files]
    if not args.scale > 0:
        raise InputError(f"--scale must be positive, got {args.scale}")
    dt = 1.0 / freq if args.dt is None else args.dt
    options = selection_options(args)
    results, tests = [], {}
    for k, column in enumerate(segments[0].columns):
        xs = [seg.data[:, k] * args.scale for seg in segments]
        results.append(select(xs, freq, names=[column], **options))
        test = results[-1].best.pooled.test  # the selection's pooling of the replicates
        tests[column] = None if test is None else attrs.asdict(test)
    report = calibration_report(results, segments[0], freq, dt, args.scale)
    report["n"] = sum(sizes)
    report["replicates"] = {"files": [segs[0].path for segs in files], "n": sizes,
                            "segments": len(segments), "equality_test": tests}
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "calibration.json"
    path.write_text(json.dumps(to_jsonable(report), indent=1, sort_keys=True, allow_nan=False))
    if args.json:
        print_json(report)
        return 0
    print(_table(results, segments[0], freq, {}, f"{sum(sizes)} samples in {len(files)} replicates"))
    print(format_table(["column", "equality Q", "dof", "p-value"],
                       [[c, t["statistic"], t["dof"], t["pvalue"]] if t else [c, "-", "-", "-"]
                        for c, t in tests.items()],
                       title=f"\nreplicates {', '.join(segs[0].path for segs in files)}: do they share one "
                             "model?"))
    print(f"\nwrote {path}")
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
    (scaled by ``--scale``), the sampling frequency (Hz) and the filter step ``dt`` (s)."""

    segments: list[Recording]
    freq: float
    dt: float

    def __sizeof__(self) -> int:
        """Bytes of the samples and time stamps: what dask weighs when it considers moving the
        unit to another worker (its ``sizeof`` of an object it does not know)."""
        return object.__sizeof__(self) + sum(
            r.data.nbytes + (0 if r.time is None else r.time.nbytes) for r in self.segments)


def read_unit(args: argparse.Namespace, executor: SerialExecutor) -> UnitInput:
    """A unit's input (a fleet's first step, and :func:`calibrate_file`'s): its file read and
    the options checked (before any selection), the data scaled."""
    with executor.stage("read"):
        segments, freq, dt = _checked_input(args)
    _sensor_units(args, segments)  # bad options fail here, not in every column's task
    selection_options(args)
    if args.scale != 1.0:  # x * 1.0 is x: no copy of the samples for the default
        segments = [attrs.evolve(r, data=r.data * args.scale) for r in segments]
    return UnitInput(segments, freq, dt)


def unit_columns(unit: UnitInput) -> list[str]:
    """The columns of a fleet unit, one selection task each."""
    return list(unit.segments[0].columns)


@attrs.frozen
class ColumnResult:
    """What a fleet unit's column task hands on: the column's selection and the Allan reading
    of its data for the datasheet (None when the column's sensor is unknown)."""

    selection: SelectionResult
    reading: AllanReading | None


def select_unit_column(args: argparse.Namespace, unit: UnitInput, k: int,
                       executor: SerialExecutor) -> ColumnResult:
    """A fleet unit's column `k` alone: its selection (equal to that column's in a selection
    of every column: each column's fits are seeded by ``--seed`` and the candidate only) and
    the Allan reading of its datasheet."""
    column = unit_columns(unit)[k]
    result = select(column_replicates(unit.segments, k), unit.freq, names=[column],
                    executor=executor, **selection_options(args))
    units = _sensor_units(args, unit.segments)
    if units is None:
        return ColumnResult(result, None)
    with executor.stage("allan"):
        reading = datasheet_reading(longest_segment(unit.segments).data[:, k], unit.freq,
                                    units[column])
    return ColumnResult(result, reading)


def finish_unit(args: argparse.Namespace, unit: UnitInput, columns: list[ColumnResult],
                executor: SerialExecutor) -> dict[str, Any]:
    """A fleet unit's last step: its outputs from its columns' tasks; its report."""
    return _outputs(args, unit.segments, unit.freq, unit.dt, [c.selection for c in columns],
                    executor, quiet=True, readings=[c.reading for c in columns])


def calibrate_unit(args: argparse.Namespace, executor: SerialExecutor) -> dict[str, Any]:
    """A fleet unit in one task: the quiet single-file calibration with its work items run in
    the calling thread by `executor`; its report."""
    return calibrate_file(args, executor=executor, quiet=True)


#: The single-file calibration as a fleet runs it (:func:`stochmod.workflows.fleet.run_fleet`).
UNIT_STEPS = UnitSteps(calibrate_unit, read_unit, unit_columns, select_unit_column, finish_unit,
                       warm_module=FLEET_WARM_MODULE)


def _checked_input(args: argparse.Namespace) -> tuple[list[Recording], float, float]:
    """The recording's gap-free segments, its frequency and the filter step, with the
    options checked."""
    segments, freq = _input(args)
    if not args.scale > 0:
        raise InputError(f"--scale must be positive, got {args.scale}")
    dt = 1.0 / freq if args.dt is None else args.dt
    if not dt > 0:
        raise InputError(f"--dt must be a positive number of seconds, got {args.dt}")
    return segments, freq, dt


def calibrate_file(args: argparse.Namespace, executor: Any = None, quiet: bool = False
                   ) -> dict[str, Any]:
    """The single-file calibration: writes OUT/calibration.json (and the asked outputs), prints
    the tables (or the JSON with ``--json``; nothing when `quiet`) and returns the report.
    `executor` runs the selection's fits and the figures (default: a pool of ``args.jobs``
    worker processes)."""
    unit = read_unit(args, executor if isinstance(executor, SerialExecutor) else SerialExecutor())
    jobs = getattr(args, "jobs", 2)
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise InputError(f"--jobs must be a positive number of worker processes, got {jobs!r}")
    with _pool(executor, jobs) as pool:
        results = select_columns(unit.segments, unit.freq, selection_options(args), pool)
        return _outputs(args, unit.segments, unit.freq, unit.dt, results, pool, quiet)


def _sensor_units(args: argparse.Namespace, segments: list[Recording]) -> dict[str, str] | None:
    """The columns' SI signal units: from their declared sensor kinds, else ``--sensor`` or the
    column names (None when unknown and not needed; an error when ``--triad``, ``--export`` or
    ``--report`` needs them)."""
    declared = segments[0].declared
    if declared and args.sensor is None and all(c.kind in SENSORS for c in declared):
        return {c.column: SENSORS[c.kind] for c in declared}
    return extras.column_units(list(segments[0].columns), args,
                               required=bool(args.triad or args.export or args.report))


def _outputs(args: argparse.Namespace, segments: list[Recording], freq: float, dt: float,
             results: list[SelectionResult], pool: Any, quiet: bool,
             readings: list[AllanReading | None] | None = None) -> dict[str, Any]:
    """:func:`calibrate_file` once the (scaled) recording's gap-free `segments` are selected:
    the report, the outputs and the printed tables, with `pool` running the figures
    (`readings`: the columns' Allan readings for the datasheet, when made already)."""
    # with --split-gaps the fits pool all segments; the Allan reading and the validation bands
    # of the datasheet and report use the longest one
    rec = longest_segment(segments)
    data = rec.data
    sensor_units = _sensor_units(args, segments)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    # datasheet units, triads, exports, report (stochmod.cli._calibrate_outputs)
    triads: list[Any] = []
    if args.triad:
        results, triads = extras.apply_triad(results, sensor_units)
    sheets = {} if sensor_units is None else extras.datasheet_section(results, data, sensor_units,
                                                                      readings)
    report = calibration_report(results, rec, freq, dt, args.scale)
    if len(segments) > 1:
        report["n"] = sum(int(r.data.shape[0]) for r in segments)
        report["segments"] = [{"start": float(r.time[0]), "n": int(r.data.shape[0])}
                              for r in segments]
    report["units"] = {"signal": sensor_units, "note": "parameters: canonical per-sample values "
                       "in the signal unit u (see physical for SI, datasheet for datasheet units)",
                       "declared": None if rec.declared is None else
                       {c.column: c.to_dict() for c in rec.declared}}
    report["datasheet"] = {c: d.to_dict() for c, d in sheets.items()}
    report["triads"] = [t.to_dict() for t in triads]
    path = out / "calibration.json"
    path.write_text(json.dumps(to_jsonable(report), indent=1, sort_keys=True, allow_nan=False))
    samples = f"{report['n']} samples" + (f" in {len(segments)} gap-free segments"
                                          if len(segments) > 1 else "")
    exported = extras.write_exports_for(args, results, sensor_units, out)
    units = XSENS_UNITS if args.file is None else rec.unit_map()
    figures = [] if args.no_plots else _figures(results, out, args.n_sim, args.seed, units, pool)
    title = (f"stochmod calibration of {rec.path or 'the bundled example'} "
             f"({samples} at {freq:g} Hz)")
    figures += extras.write_report_for(args, results, data, sheets, exported, triads, title, out)
    if quiet:
        return report
    if args.json:
        print_json(report)
        return report
    print(_table(results, rec, freq, units, samples))
    print()
    print(format_table(["column", "selected", "2nd", "criterion gap"],
                       [[s.column, s.ranking[0].model, s.ranking[1].model if len(s.ranking) > 1 else "-",
                         s.ranking[1].criterion - s.ranking[0].criterion if len(s.ranking) > 1 else "-"]
                        for s in results]))
    print()
    print(format_table(["column", "verdict"],
                       [[sel.column, verdict(sel.best, candidates=sel.ranking).summary()]
                        for sel in results], title="verdict per axis (docs/calibrate.md)"))
    for sel in results:
        if sel.empirical.contamination is not None:
            print(f"\n{sel.column}: {sel.empirical.contamination.summary()}")
    for text in [t.summary() for t in triads] + [d.summary() for d in sheets.values()]:
        print(f"\n{text}")
    written = [str(path)] + [str(f) for f in exported + figures]
    print(f"\nwrote {', '.join(written)}")
    return report
