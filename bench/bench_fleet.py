"""Benchmark: a fleet calibration on a dask LocalCluster against the serial run, same files.

Run: ``python bench/bench_fleet.py [--files 12] [--n 1048576] [--workers 2]`` (defaults: 12
files x 6 axes x 2^20 samples at 100 Hz, the XSens MTi-G models of the bundled example, each
file its own seed). Every run is the command a user types, in a fresh process (its imports
and the cluster's start-up included): ``stochmod calibrate FILE ... --candidates GM+WN
2*GM+WN WN+RW --no-plots`` (three candidates per axis, to keep the run practical), serially
(no ``--workers``: one file after the other in one process, each file's fits in its own
thread), with ``--workers N`` and with ``--workers 1`` (the same
fleet machinery on one worker; a unit's read, each column's selection and its outputs are
tasks of their own, :class:`stochmod.workflows.fleet.UnitSteps`). The runs are made in the order parallel, serial, one-worker
(and back again, and so on, with ``--rounds N``, so that a drift of the machine's load hits
all alike); the best of each kind is kept, each round's own ratios are printed beside the
ratios of the bests, and the runs' results are checked to be identical.

Printed: every run's wall time and the CPU time of its whole process tree; the ratios
serial / parallel and one-worker / parallel; and, from ``OUT/fleet_tasks.csv`` (each task's
stages timed inside its worker, :class:`stochmod.workflows.fleet.TaskTiming`), where the parallel
run's time went: per stage, per worker (start-up, busy, idle gaps, tail) and the CPU-time
scaling (the tasks' CPU over the run's wall: how many cores the fleet kept busy), which
says more than the wall ratio on a shared machine; and, per round, the tasks' CPU in the
parallel run over the one-worker run's (the same tasks: how much slower a core ran while two
workers ran at once, the pair penalty that bounds the wall ratio at ``2 / penalty``).
"""

from __future__ import annotations

import argparse
import csv
import json
import resource
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

from stochmod.data.examples import XSENS_COLUMNS, xsens_mtig
from stochmod.workflows.fleet import STAGES

CANDIDATES = ["GM+WN", "2*GM+WN", "WN+RW"]
STAGE_NAMES = [*dict.fromkeys(STAGES.values()), "other"]


def _files(folder: Path, n_files: int, n: int) -> list[Path]:
    paths = []
    for i in range(n_files):
        rec = xsens_mtig(n=n, seed=1000 + i)
        path = folder / f"imu{i:02d}.npz"
        np.savez(path, freq=rec.freq, **{c: rec.column(c) for c in XSENS_COLUMNS})
        paths.append(path)
    return paths


def _command(given: str | None = None) -> list[str]:
    """The ``stochmod`` command: `given` (a command line, e.g. another checkout's launcher),
    else the console script of this environment (or the same entry point)."""
    if given:
        return shlex.split(given)
    script = Path(sys.executable).with_name("stochmod")
    if script.exists():
        return [str(script)]
    found = shutil.which("stochmod")
    return [found] if found else [sys.executable, "-c",
                                  "import sys; from stochmod.cli import main; sys.exit(main())"]


def _children_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _run(files: list[Path], out: Path, extra: list[str], command: str | None = None) -> dict:
    """One calibrate command in a fresh process: wall, CPU of the process tree, task rows."""
    cmd = [*_command(command), "calibrate", *map(str, files), "--candidates", *CANDIDATES,
           "--no-plots", "--out", str(out), *extra]
    cpu, t0, epoch = _children_cpu(), time.perf_counter(), time.time()
    done = subprocess.run(cmd, capture_output=True, text=True)
    wall, cpu = time.perf_counter() - t0, _children_cpu() - cpu
    if done.returncode != 0:
        raise SystemExit(f"calibrate failed with code {done.returncode}:\n{done.stderr}")
    with open(out / "fleet_tasks.csv") as fh:
        tasks = [{k: v if k in ("unit_name", "part", "host") else float(v) for k, v in r.items()}
                 for r in csv.DictReader(fh)]
    for t in tasks:  # s from the command's start
        t["start"], t["end"] = t["start"] - epoch, t["end"] - epoch
        t["process_start"] = t.get("process_start", float("nan")) - epoch  # older checkouts: NaN
    return {"wall": wall, "cpu": cpu, "tasks": tasks, "out": out}


def _stage_table(tasks: list[dict]) -> list[str]:
    wall = sum(t["wall"] for t in tasks)
    lines = [f"  {'stage':8s} {'wall s':>8s} {'CPU s':>8s} {'CPU/wall':>8s} {'share':>6s}"]
    for name in STAGE_NAMES:
        w = sum(t[f"{name}_wall"] for t in tasks)
        c = sum(t[f"{name}_cpu"] for t in tasks)
        if w > 0:
            lines.append(f"  {name:8s} {w:8.1f} {c:8.1f} {c / w:8.2f} {w / wall:6.1%}")
    cpu = sum(t["cpu"] for t in tasks)
    lines.append(f"  {'all':8s} {wall:8.1f} {cpu:8.1f} {cpu / wall:8.2f}")
    return lines


def _worker_table(run: dict) -> list[str]:
    """Per worker process: when the process started (for a local worker: its fork or spawn,
    the end of the command's own start), start-up (the command's start to its first task:
    imports, the cluster's start, the worker's own start), tasks (a unit's read, its columns'
    selections and its outputs are tasks of their own; older checkouts: one per unit), busy
    time, idle gaps between its tasks, the tail (its last task's end to the run's end), its
    first task's wall time (what the first task still loads) and minor page faults per task."""
    by_pid: dict[float, list[dict]] = defaultdict(list)
    for t in run["tasks"]:
        by_pid[t["pid"]].append(t)
    lines = [f"  {'worker':>8s} {'tasks':>5s} {'process':>7s} {'start-up':>8s} {'busy':>7s} {'gaps':>6s} "
             f"{'tail':>6s} {'CPU':>7s} {'first':>6s} {'faults/task':>11s}"]
    for pid, ts in sorted(by_pid.items()):
        ts.sort(key=lambda t: t["start"])
        gaps = sum(b["start"] - a["end"] for a, b in zip(ts, ts[1:]))
        busy = sum(t["wall"] for t in ts)
        lines.append(f"  {int(pid):8d} {len(ts):5d} {ts[0]['process_start']:7.2f} {ts[0]['start']:8.1f} "
                     f"{busy:7.1f} {gaps:6.2f} "
                     f"{run['wall'] - ts[-1]['end']:6.1f} {sum(t['cpu'] for t in ts):7.1f} "
                     f"{ts[0]['wall']:6.2f} {np.mean([t['page_faults'] for t in ts]):11.0f}")
    return lines


def _same_results(files: list[Path], outs: list[Path]) -> bool:
    def columns(d: Path, f: Path) -> dict:
        return json.loads((d / f.stem / "calibration.json").read_text())["columns"]
    return all(columns(d, f) == columns(outs[0], f) for f in files for d in outs) and all(
        (d / "fleet.csv").read_text() == (outs[0] / "fleet.csv").read_text() for d in outs)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--files", type=int, default=12)
    p.add_argument("--n", type=int, default=2**20, help="samples per axis (default 2^20)")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--rounds", type=int, default=1,
                   help="rounds of every kind of run: parallel, serial, one-worker, then back "
                        "again and so on, so that a drift of the machine hits all alike (default 1)")
    p.add_argument("--pause", type=float, default=0.0, metavar="S",
                   help="seconds of rest before each run after the first, so that every run "
                        "starts from an idle machine as a user's single run does (default 0; "
                        "e.g. 60 on a virtual machine, whose host may slow sustained load)")
    p.add_argument("--no-one-worker", action="store_true", help="skip the one-worker fleet runs")
    p.add_argument("--command", default=None, metavar="CMD",
                   help="the stochmod command to time (default: this environment's console "
                        "script), e.g. 'python /tmp/old/run_stochmod.py' for another checkout")
    a = p.parse_args()
    kinds = ["parallel", "serial"] + ([] if a.no_one_worker else ["one-worker"])
    if a.rounds < 1:
        p.error(f"--rounds must be a positive integer, got {a.rounds}")
    if a.files < 2:  # one FILE is a single-file calibration, not a fleet: no fleet_tasks.csv
        p.error(f"--files must be at least 2 (one file is not a fleet), got {a.files}")
    if a.pause < 0:
        p.error(f"--pause must be zero or positive, got {a.pause}")
    order = [kind for r in range(a.rounds) for kind in (kinds if r % 2 == 0 else kinds[::-1])]
    extra = {"parallel": ["--workers", str(a.workers)], "serial": [], "one-worker": ["--workers", "1"]}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        files = _files(folder, a.files, a.n)
        runs: dict[str, list[dict]] = defaultdict(list)
        for k, kind in enumerate(order):
            if k and a.pause:
                time.sleep(a.pause)
            runs[kind].append(_run(files, folder / f"{kind}{k}", extra[kind], a.command))
        same = _same_results(files, [r["out"] for rs in runs.values() for r in rs])
    best = {kind: min(rs, key=lambda r: r["wall"]) for kind, rs in runs.items()}
    par, ser = best["parallel"], best["serial"]
    load = Path("/proc/loadavg").read_text().split()[:3] if Path("/proc/loadavg").exists() else "?"
    print(f"{a.files} files x {len(XSENS_COLUMNS)} axes x {a.n:,} samples, candidates {CANDIDATES}; "
          f"load average at the end {' '.join(load)}"
          + (f"; {a.pause:g} s of rest before each run" if a.pause else ""))
    print("every run (wall s / CPU s of its process tree):")
    for kind, rs in runs.items():
        print(f"  {kind:10s} " + ", ".join(f"{r['wall']:.1f} / {r['cpu']:.1f}" for r in rs))
    print(f"serial run (best)                    {ser['wall']:8.1f} s")
    if "one-worker" in best:
        print(f"dask LocalCluster, 1 worker (best)   {best['one-worker']['wall']:8.1f} s")
    print(f"dask LocalCluster, {a.workers} workers (best)  {par['wall']:8.1f} s")
    print(f"speed-up serial / parallel           {ser['wall'] / par['wall']:8.2f}")
    if "one-worker" in best:
        print(f"speed-up one-worker / parallel       {best['one-worker']['wall'] / par['wall']:8.2f}")
    if a.rounds > 1:  # the same ratios within each round (its runs minutes apart, not the bests)
        for other in [k for k in kinds if k != "parallel"]:
            ratios = [run["wall"] / par_run["wall"]
                      for run, par_run in zip(runs[other], runs["parallel"])]
            print(f"  {other} / parallel in each round: "
                  + ", ".join(f"{r:.2f}" for r in ratios) + f" (median {np.median(ratios):.2f})")
    if "one-worker" in runs:  # the same work on two busy cores against one: what the host gave
        penalties = [sum(t["cpu"] for t in par_run["tasks"]) / sum(t["cpu"] for t in run["tasks"])
                     for run, par_run in zip(runs["one-worker"], runs["parallel"])]
        print("  tasks' CPU, parallel / one-worker, in each round: "
              + ", ".join(f"{r:.2f}" for r in penalties)
              + " (the same tasks took this much more CPU while two workers ran at once: the "
                "machine's pair penalty in that round; bench/fleet_pairs.py measures it alone)")
    print(f"identical results                    {same}")
    ser_cpu = sum(t["cpu"] for t in ser["tasks"])

    def cores(tasks: list[dict], stages: list[str]) -> float:
        return (sum(t[f"{s}_cpu"] for t in tasks for s in stages)
                / max(sum(t[f"{s}_wall"] for t in tasks for s in stages), 1e-9))

    rest = [s for s in STAGE_NAMES if s != "eq17"]
    helper = ser_cpu - sum(t["thread_cpu"] for t in ser["tasks"])
    print(f"\nserial run, in its one process: tasks' CPU {ser_cpu:.1f} s over {ser['wall']:.1f} s wall; "
          f"CPU/wall {cores(ser['tasks'], ['eq17']):.2f} in the eq. 17 stage against "
          f"{cores(ser['tasks'], rest):.2f} in the others; {helper:.1f} s of the CPU ran outside "
          f"the tasks' thread (eq. 17's FFT helper threads): the serial path "
          + ("uses the second core for part of each file" if helper > 0.02 * ser_cpu
             else "runs on one core"))
    par_cpu = sum(t["cpu"] for t in par["tasks"])
    busiest = max(sum(t["cpu"] for t in par["tasks"] if t["pid"] == pid)
                  for pid in {t["pid"] for t in par["tasks"]})
    print(f"parallel run: tasks' CPU {par_cpu:.1f} s over {par['wall']:.1f} s wall = "
          f"{par_cpu / par['wall']:.2f} cores busy (of {a.workers}); CPU per file "
          f"{par_cpu / a.files:.2f} s in a worker against {ser_cpu / a.files:.2f} s serially")
    print(f"CPU-time scaling: serial tasks' CPU / the busiest worker's tasks' CPU = "
          f"{ser_cpu / busiest:.2f} (the wall speed-up if every process had a core of its own, "
          "start-up excluded)")
    if helper > 0.02 * ser_cpu:
        print(f"  the serial run's helper threads took {helper:.1f} s: on an idle machine it takes at "
              f"least {ser_cpu - helper:.1f} s, the same estimate against that is "
              f"{(ser_cpu - helper) / busiest:.2f}")
    reports = [t for t in par["tasks"] if t.get("part", "finish") == "finish"]
    handed = sum(t["result_bytes"] for t in par["tasks"]) - sum(t["result_bytes"] for t in reports)
    print(f"reports shipped back to the client: {sum(t['result_bytes'] for t in reports) / 1e3:.0f} kB "
          f"in all (handed from task to task, moved between workers only when a task runs "
          f"elsewhere: {handed / 1e6:.0f} MB); threads per worker process "
          f"{sorted({int(t['threads']) for t in par['tasks']})}")
    for kind in best:
        print(f"\n{kind} run (best): stages summed over its tasks, timed inside the workers")
        print("\n".join(_stage_table(best[kind]["tasks"])))
        print(f"{kind} run: per worker process (s from the command's start)")
        print("\n".join(_worker_table(best[kind])))


if __name__ == "__main__":
    main()
