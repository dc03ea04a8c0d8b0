"""Calibrate a fleet of IMUs in one run, on a dask.distributed cluster or serially.

``stochmod calibrate A.npz B.npz ... --workers N`` (a local cluster of N single-threaded
worker processes) or ``--scheduler tcp://host:8786`` (an existing cluster, any number of
machines) runs the single-file calibration of every file, writing ``OUT/<file stem>/`` each,
then the fleet table ``OUT/fleet.csv``.  On a cluster a unit is one task, except the last
units, as many as the cluster has threads, each of which runs as several (:class:`UnitSteps`):
its read, one selection per column, which any worker may take, and its outputs, so that the
end of the run (and a fleet of fewer files than workers) keeps every worker busy; two units
per worker thread are in flight.  Without ``--workers`` or ``--scheduler`` the files are
calibrated one after the other.  A task
runs its fits in its own thread (the task is the unit of parallelism: no process pool inside
a task, whatever ``--jobs`` says), and every fit is seeded from ``--seed`` and the candidate
only, so a fleet run gives exactly the results of a serial run, whatever the cluster.

A task in a worker runs on one core: the local cluster's workers have one thread each, BLAS
pinned to one thread (dask's default worker environment), the eq. 17 FFTs on one thread
(:func:`single_threaded`, through ``$STOCHMOD_FFT_THREADS``, the default of
:mod:`stochmod.empirical.wv_covariance`), dask's sampling profiler off, its periodic checks
at intervals of a second or so, and
glibc's default ``malloc`` (dask's ``MALLOC_TRIM_THRESHOLD_`` makes every large array a fresh
``mmap``: 3-4 times the page faults of a file; see docs/fleet.md).  The local cluster's workers
are forks of a process server that imported the task's modules and loaded its compiled loops
once (:func:`start_process_server`), so that no worker imports or loads them again.  Every task
records where its time went
(:class:`TaskTiming`: wall and CPU time per stage, measured inside the worker), written to
``OUT/fleet_tasks.csv``.

The fleet table compares the units on what every model has, whatever its structure: the
datasheet summary of each axis (white-noise density, bias instability, random walk; see
:mod:`stochmod.output.datasheet`).  A unit is flagged as an outlier on a quantity when its robust
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
import multiprocessing
import os
import pickle
import socket
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import attrs
import numpy as np

from stochmod.core.errors import InputError, StochmodError
from stochmod.core.tables import format_table

__all__ = ["OUTLIER_Z", "MIN_UNITS", "FleetRow", "fleet_rows", "robust_z", "write_fleet_csv",
           "run_fleet", "calibrate_files", "unit_folders", "SerialExecutor", "UnitSteps",
           "TaskTiming", "STAGES", "single_threaded", "write_task_csv", "start_process_server"]

#: |robust z| above which a unit is an outlier on a quantity.
OUTLIER_Z = 3.5
#: Fewest units for which outliers are flagged.
MIN_UNITS = 4
_MAD_TO_SD = 1.4826
#: Stages of a unit's calibration timed inside its tasks: the function that
#: :class:`SerialExecutor` runs (stochmod.fit.selection's work items, calibrate's figures),
#: or a stage opened with :meth:`SerialExecutor.stage` (the file's read, a column's Allan
#: reading for the datasheet); the rest of a task is ``other`` (the ranking; the report:
#: datasheet, JSON, exports).
STAGES = {"read": "read", "_prepare": "wv", "_covariance": "eq17", "_fit_task": "fits",
          "allan": "allan", "_figure": "figures"}
#: dask configuration of the local cluster: no sampling profiler in the workers (a thread
#: that walks the task's stack every 10 ms, holding the GIL), glibc's default malloc (see the
#: module docstring), and the periodic checks of every server (the scheduler, the nannies and
#: the workers) at human intervals instead of dask's: the event loop's health tick every
#: second (20 ms), the system monitor's psutil samples (dashboard only; there is none) every
#: 2 s (500 ms), the memory limits checked every 0.5 s (100 ms). At dask's intervals these
#: checks take CPU in the command's process and as much again in the workers, on the cores
#: the tasks run on; at these intervals, a third of it (docs/fleet.md).
_MALLOC_TRIM = "MALLOC_TRIM_THRESHOLD_"
_LOCAL_CLUSTER_CONFIG = {"distributed.worker.profile.enabled": False,
                         f"distributed.nanny.pre-spawn-environ.{_MALLOC_TRIM}": None,
                         "distributed.admin.tick.interval": "1s",
                         "distributed.admin.system-monitor.interval": "2s",
                         "distributed.worker.memory.monitor-interval": "500ms"}
#: What the local cluster's process server imports before it forks the workers, around the
#: caller's warm-up module (the last one makes its exit skip the interpreter's teardown:
#: :mod:`stochmod.workflows.fleet_server`).
_SERVER_PRELOAD = ("distributed", "stochmod.workflows.fleet_server")
_HAS_SERVER = "forkserver" in multiprocessing.get_all_start_methods()  # not on Windows
#: The workers' environment when dask's configuration is not loaded yet (its defaults).
_WORKER_ENV = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}


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


@attrs.frozen
class UnitSteps:
    """A unit's calibration, whole or in the steps that a fleet runs as tasks of their own.

    ``whole(args, executor)`` calibrates the unit in one call and returns its report.
    The steps: ``read(args, executor)`` reads the unit's file into its input (which stays in
    the worker that read it: the selections take it from there); ``columns(unit)`` names its
    columns; ``select(args, unit, k, executor)`` selects the model of column `k` alone (the
    columns of a unit are independent: the same result as in a selection of all of them);
    ``finish(args, unit, results, executor)`` writes the unit's outputs from the columns'
    results, in their order, and returns its report. Every function is a module-level one
    (dask ships it by reference) whose `executor` runs its work items in the calling thread
    (:class:`SerialExecutor`, timing them).
    """

    whole: Callable[[argparse.Namespace, concurrent.futures.Executor], dict[str, Any]]
    read: Callable[[argparse.Namespace, concurrent.futures.Executor], Any]
    columns: Callable[[Any], list[str]]
    select: Callable[[argparse.Namespace, Any, int, concurrent.futures.Executor], Any]
    finish: Callable[[argparse.Namespace, Any, list[Any], concurrent.futures.Executor],
                     dict[str, Any]]
    #: Module the process server of a local cluster imports before it forks the workers: what
    #: a task needs, and a warm-up that loads the plugins and compiled loops once.
    warm_module: str | None = None


class SerialExecutor(concurrent.futures.Executor):
    """Runs each submitted call at once in the caller's thread (the task is the parallel unit).

    Parameters
    ----------
    stages : dict, optional
        When given, the wall and CPU time (s) of every call are added to
        ``stages[name] = [wall, cpu]``, `name` from :data:`STAGES` (else the function's own
        name). CPU is the process's (``time.process_time``: the call's helper threads count).
    """

    def __init__(self, stages: dict[str, list[float]] | None = None) -> None:
        self.stages = stages

    @contextlib.contextmanager
    def stage(self, name: str) -> Iterator[None]:
        """Time the enclosed code as stage `name` (nothing when not timing)."""
        if self.stages is None:
            yield
            return
        wall, cpu = time.perf_counter(), time.process_time()
        try:
            yield
        finally:
            total = self.stages.setdefault(STAGES.get(name, name), [0.0, 0.0])
            total[0] += time.perf_counter() - wall
            total[1] += time.process_time() - cpu

    def submit(self, fn: Any, /, *args: Any, **kwargs: Any) -> concurrent.futures.Future:
        future: concurrent.futures.Future = concurrent.futures.Future()
        try:
            with self.stage(getattr(fn, "__name__", "call")):
                future.set_result(fn(*args, **kwargs))
        except BaseException as exc:  # handed to the caller through the future
            future.set_exception(exc)
        return future


@attrs.frozen
class TaskTiming:
    """Where one task of a unit's calibration spent its time, measured inside the process that
    ran it.

    `part` names the task (:class:`UnitSteps`): ``unit`` (the whole unit), or a step:
    ``read``, ``select <column>`` or ``finish``.
    Times in s; `start` and `end` are wall-clock times (s since the epoch) of that machine.
    `cpu` is the process's CPU time during the task (every thread: the FFT helpers, and in a
    dask worker its own threads), `thread_cpu` the task thread's alone. `stages` maps a
    stage of :data:`STAGES` (and ``other``, the rest) to its (wall, cpu). `page_faults`
    counts the process's minor faults during the task (fresh memory pages), `threads` its
    OS threads at the end, `result_bytes` the pickled size of what the task hands on (to the
    next step, or the report to the client), `process_start` the wall-clock time at which
    that process started (a worker forked by the local cluster's process server: its fork;
    NaN without psutil).
    """

    unit_name: str
    part: str
    host: str
    pid: int
    start: float
    end: float
    wall: float
    cpu: float
    thread_cpu: float
    page_faults: int
    threads: int
    result_bytes: int
    process_start: float
    stages: dict[str, tuple[float, float]]

    def row(self) -> dict[str, Any]:
        """Flat CSV row: the fields, then each stage's ``<stage>_wall`` and ``<stage>_cpu``."""
        row = attrs.asdict(self, filter=lambda a, _: a.name != "stages")
        for name in [*dict.fromkeys(STAGES.values()), "other"]:
            wall, cpu = self.stages.get(name, (0.0, 0.0))
            row[f"{name}_wall"], row[f"{name}_cpu"] = wall, cpu
        return row


def _minor_faults() -> int:
    try:
        import resource
    except ImportError:  # pragma: no cover - not on Windows
        return 0
    return int(resource.getrusage(resource.RUSAGE_SELF).ru_minflt)


def _process_start() -> float:
    try:
        import psutil  # a dependency of dask.distributed
    except ImportError:
        return math.nan
    return float(psutil.Process().create_time())


def _os_threads() -> int:
    try:
        return len(os.listdir("/proc/self/task"))
    except OSError:  # pragma: no cover - not Linux
        return threading.active_count()


@contextlib.contextmanager
def single_threaded() -> Iterator[None]:
    """Run the enclosed task's numerical work on one thread (the fleet's workers are the
    parallel unit): the eq. 17 covariance's default thread count (``$STOCHMOD_FFT_THREADS``,
    :func:`stochmod.empirical.wv_covariance.default_workers`) and scipy.fft's calls that do not
    name theirs are set to 1, and restored afterwards. BLAS cannot be pinned at run time
    without threadpoolctl: dask's worker environment does it (``OPENBLAS_NUM_THREADS=1``
    ...) before the worker process starts.
    """
    from scipy import fft

    from stochmod.empirical.wv_covariance import THREADS_VARIABLE

    with _environ(THREADS_VARIABLE, "1"), fft.set_workers(1):
        yield


def _pickled_bytes(value: Any) -> int:
    """Size of `value` pickled (protocol 5: its arrays' buffers counted, not copied)."""
    buffers: list[pickle.PickleBuffer] = []
    head = pickle.dumps(value, protocol=5, buffer_callback=buffers.append)
    return len(head) + sum(b.raw().nbytes for b in buffers)


def _run_step(step: Callable[..., Any], unit_name: str, part: str, in_worker: bool,
              *args: Any) -> tuple[Any, TaskTiming]:
    """One step of a unit's calibration, ``step(*args, executor)`` (``args[0]``: the unit's
    options), with its stages timed (module level: dask ships it by reference); in a worker on
    one thread (:func:`single_threaded`). Returns the step's value and the task's timing; a
    stochmod error gets the unit's file name in front of its message."""
    stages: dict[str, list[float]] = {}
    pool = SerialExecutor(stages)
    start, wall, cpu = time.time(), time.perf_counter(), time.process_time()
    thread_cpu, faults = time.thread_time(), _minor_faults()
    try:
        with single_threaded() if in_worker else contextlib.nullcontext():
            value = step(*args, pool)
    except StochmodError as exc:  # a fleet's error names its file
        raise type(exc)(f"{args[0].file}: {exc}") from exc
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    stages["other"] = [wall - sum(w for w, _ in stages.values()),
                       cpu - sum(c for _, c in stages.values())]
    timing = TaskTiming(unit_name, part, socket.gethostname(), os.getpid(), start, time.time(),
                        wall, cpu, time.thread_time() - thread_cpu, _minor_faults() - faults,
                        _os_threads(), _pickled_bytes(value), _process_start(),
                        {k: (float(w), float(c)) for k, (w, c) in stages.items()})
    return value, timing


def _select_step(steps: UnitSteps, unit_name: str, column: str, in_worker: bool,
                 args: argparse.Namespace, read: tuple[Any, TaskTiming], k: int
                 ) -> tuple[Any, TaskTiming]:
    """The selection of column `k` (named `column`) of the unit that `read` holds."""
    return _run_step(steps.select, unit_name, f"select {column}", in_worker, args, read[0], k)


def _finish_step(steps: UnitSteps, unit_name: str, in_worker: bool, args: argparse.Namespace,
                 read: tuple[Any, TaskTiming], *selected: tuple[Any, TaskTiming]
                 ) -> tuple[dict[str, Any], list[TaskTiming]]:
    """The unit's outputs from its columns' selections; its report and every task's timing."""
    report, timing = _run_step(steps.finish, unit_name, "finish", in_worker, args, read[0],
                               [result for result, _ in selected])
    return report, [read[1], *(t for _, t in selected), timing]


def _column_names(steps: UnitSteps, read: tuple[Any, TaskTiming]) -> list[str]:
    return list(steps.columns(read[0]))


def _whole_step(steps: UnitSteps, unit_name: str, in_worker: bool, args: argparse.Namespace
                ) -> tuple[dict[str, Any], list[TaskTiming]]:
    """The unit calibrated in one task; its report and the task's timing."""
    report, timing = _run_step(steps.whole, unit_name, "unit", in_worker, args)
    return report, [timing]


#: dask priorities of a unit's tasks (higher first): a worker runs a unit's outputs before
#: selections, and selections before the next file's read (or whole unit), so that the units
#: in flight finish and free their memory before more are read.
_PRIORITY = {"read": 0, "columns": 1, "select": 2, "finish": 3}
#: Units in flight per worker thread on a cluster (submitted and not yet finished, whole or
#: in steps): enough that a worker always finds a task while the client submits the next
#: unit's selections.
_UNITS_PER_THREAD = 2


def _calibrate_on(client: Any, tasks: Sequence[argparse.Namespace], steps: UnitSteps
                  ) -> list[tuple[dict[str, Any], list[TaskTiming]]]:
    """Every unit on a dask cluster: one task per unit, except the last units, as many as
    the cluster has threads, which run as one task per step: their read, a selection task per
    column (which any worker may take, so that the end of the run, or a fleet of fewer files
    than workers, keeps every worker busy), then their outputs. A unit in one task costs
    less: its columns' work shares one heap (column tasks fault 4-5 times the memory pages
    in a worker; docs/fleet.md). At most :data:`_UNITS_PER_THREAD` units per worker
    thread are in flight."""
    from distributed import as_completed

    threads = max(1, sum(client.nthreads().values()))
    first_split = max(0, len(tasks) - threads)
    names = [Path(t.out).name for t in tasks]
    results: dict[int, tuple[dict[str, Any], list[TaskTiming]]] = {}
    waiting = as_completed()
    role: dict[Any, tuple[str, int, Any]] = {}
    pending = iter(range(len(tasks)))

    def start_next() -> None:
        i = next(pending, None)
        if i is None:
            return
        if i < first_split:
            unit = client.submit(_whole_step, steps, names[i], True, tasks[i], pure=False,
                                 priority=_PRIORITY["read"])
            role[unit] = ("unit", i, None)
            waiting.add(unit)
            return
        read = client.submit(_run_step, steps.read, names[i], "read", True, tasks[i],
                             pure=False, priority=_PRIORITY["read"])
        columns = client.submit(_column_names, steps, read, pure=False,
                                priority=_PRIORITY["columns"])
        role[columns] = ("columns", i, read)
        waiting.add(columns)

    for _ in range(threads * _UNITS_PER_THREAD):
        start_next()
    for future in waiting:
        kind, i, read = role.pop(future)
        if kind == "columns":
            selected = [client.submit(_select_step, steps, names[i], column, True, tasks[i], read, k,
                                      pure=False, priority=_PRIORITY["select"])
                        for k, column in enumerate(future.result())]
            finish = client.submit(_finish_step, steps, names[i], True, tasks[i], read, *selected,
                                   pure=False, priority=_PRIORITY["finish"])
            role[finish] = ("finish", i, None)
            waiting.add(finish)
        else:
            results[i] = future.result()
            start_next()
        future.release()
    return [results[i] for i in range(len(tasks))]


def write_task_csv(path: Path, timings: Sequence[TaskTiming]) -> Path:
    """Write the tasks' timings (one line per task; see :meth:`TaskTiming.row`)."""
    rows = [t.row() for t in timings]
    with open(path, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]) if rows else ["unit_name"])
        writer.writeheader()
        writer.writerows(rows)
    return path


@contextlib.contextmanager
def _client(workers: int | None, scheduler: str | None, warm_module: str | None = None
            ) -> Iterator[Any]:
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise ImportError('fleet runs need dask.distributed: pip install "stochmod[fleet]"') from None
    if scheduler:
        with Client(scheduler) as client:
            yield client
    else:
        import dask

        config = dict(_LOCAL_CLUSTER_CONFIG)
        if _HAS_SERVER:  # else dask's default: spawned workers
            start_process_server(warm_module)
            config["distributed.worker.multiprocessing-method"] = "forkserver"
        with _stopping_process_server(), dask.config.set(config), _environ(_MALLOC_TRIM, None), \
                LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                             dashboard_address=None) as cluster, Client(cluster) as client:
            yield client


def start_process_server(warm_module: str | None = None) -> None:
    """Start the process server that forks the local cluster's workers, warm.

    The server imports what a task needs, loads the plugins and the compiled loops of a first
    task (the module `warm_module`, imported before the workers fork) once, while this process goes on (``stochmod
    calibrate ... --workers N`` calls this before its own imports); each worker then starts
    as a fork of the server, in milliseconds and warm, instead of as a fresh interpreter that
    imports everything again and loads the loops in its first task. Returns at once, also
    when the server runs already. The server has one thread, so a fork inherits no lock held
    by another thread (numba's compiler lock: docs/fleet.md). It starts with the workers'
    environment, which its forks cannot change any more: dask's ``pre-spawn-environ``
    (BLAS and OpenMP on one thread) without ``MALLOC_TRIM_THRESHOLD_``.
    """
    import dask
    from multiprocessing import forkserver

    env = _WORKER_ENV | {k: str(v) for k, v in
                         dask.config.get("distributed.nanny.pre-spawn-environ", default={}).items()}
    env.pop(_MALLOC_TRIM, None)
    multiprocessing.get_context("forkserver").set_forkserver_preload(
        [_SERVER_PRELOAD[0], *([warm_module] if warm_module else []), _SERVER_PRELOAD[-1]])
    with contextlib.ExitStack() as stack:
        stack.enter_context(_environ(_MALLOC_TRIM, None))
        for name, value in env.items():
            stack.enter_context(_environ(name, value))
        forkserver.ensure_running()


@contextlib.contextmanager
def _stopping_process_server() -> Iterator[None]:
    """Stop the process server after the enclosed cluster closed, and wait for it: the next
    cluster starts with the environment of its time, and the workers' CPU time is counted
    in this process's children (``RUSAGE_CHILDREN``) as with spawned workers."""
    try:
        yield
    finally:
        if _HAS_SERVER:
            from multiprocessing import forkserver

            stop = getattr(forkserver._forkserver, "_stop", None)  # CPython's tests use it
            if stop is not None:
                stop()


@contextlib.contextmanager
def _environ(name: str, value: str | None) -> Iterator[None]:
    """This process's environment variable `name` set to `value` (removed when None) for the
    enclosed code, restored after. Worker processes inherit the environment: a local
    cluster's workers must not inherit the ``MALLOC_TRIM_THRESHOLD_`` that a LocalCluster
    started earlier with dask's defaults leaves in it."""
    before = os.environ.pop(name, None)
    if value is not None:
        os.environ[name] = value
    try:
        yield
    finally:
        os.environ.pop(name, None)
        if before is not None:
            os.environ[name] = before


def calibrate_files(tasks: Sequence[argparse.Namespace], steps: UnitSteps,
                    workers: int | None = None, scheduler: str | None = None
                    ) -> tuple[list[dict[str, Any]], list[TaskTiming]]:
    """Calibrate each task's unit through `steps`: serially in this process (each unit
    whole), or on a dask cluster (a local one of `workers` processes, or the one at
    `scheduler`; see :func:`_calibrate_on`); the reports (in the tasks' order) and every
    task's timing."""
    if workers is None and scheduler is None:
        done = [_whole_step(steps, Path(t.out).name, False, t) for t in tasks]
    else:
        with _client(workers, scheduler, steps.warm_module) as client:
            done = _calibrate_on(client, tasks, steps)
    return [report for report, _ in done], [t for _, timings in done for t in timings]


def run_fleet(args: argparse.Namespace, steps: UnitSteps) -> int:
    """``stochmod calibrate FILE FILE ...``: every file through `steps` (the CLI's quiet
    single-file calibration, in steps), then ``OUT/fleet.csv``."""
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
    reports, timings = calibrate_files(tasks, steps, args.workers, args.scheduler)
    out.mkdir(parents=True, exist_ok=True)
    rows = fleet_rows(dict(zip(folders, reports)))
    path = write_fleet_csv(out / "fleet.csv", rows)
    times = write_task_csv(out / "fleet_tasks.csv", timings)
    print(_fleet_summary(rows, len(files)))
    print(f"\nwrote {', '.join(str(p) for p in folders.values())}, {path} and {times}")
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
