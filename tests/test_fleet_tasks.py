"""Fleet tasks: each unit's stages timed inside its worker (``OUT/fleet_tasks.csv``), and the
local cluster's workers set up to run one task on one core."""

from __future__ import annotations

import csv
import os
import subprocess
import sys
import time

import numpy as np
import pytest

import stochmod
from stochmod.cli import main
from stochmod.cli.calibrate import UNIT_STEPS
from stochmod.workflows import fleet
from stochmod.workflows.fleet import STAGES, SerialExecutor, _client, single_threaded

FS = 50.0


def _sleep(seconds: float) -> float:
    time.sleep(seconds)
    return seconds


def _covariance(_: None) -> None:  # named like selection's eq. 17 work item
    raise ValueError("bad item")


def test_serial_executor_times_each_stage_and_keeps_results_and_errors():
    stages: dict[str, list[float]] = {}
    pool = SerialExecutor(stages)
    assert pool.submit(_sleep, 0.05).result() == 0.05
    assert pool.submit(_sleep, 0.05).result() == 0.05
    with pytest.raises(ValueError, match="bad item"):
        pool.submit(_covariance, None).result()
    with pool.stage("read"):
        time.sleep(0.02)
    assert stages.keys() == {"_sleep", "eq17", "read"}  # STAGES names the known work items
    wall, cpu = stages["_sleep"]
    assert 0.1 <= wall < 5.0  # two sleeps of 0.05 s
    assert stages["read"][0] >= 0.02
    # without a stage dict nothing is recorded, the results are the same
    assert SerialExecutor().submit(_sleep, 0.0).result() == 0.0
    # the CPU column is CPU time, not wall time: a sleep uses none. It is the process's CPU
    # (helper threads count), so this is checked in a fresh interpreter with BLAS on one
    # thread, as in a fleet worker: OpenBLAS's helper threads spin for a while after numpy's
    # import or a BLAS call (0.02-0.06 s of CPU during a 0.2-s sleep here), and in this
    # process an earlier test's can still be spinning
    probe = ("import time\nfrom stochmod.workflows.fleet import SerialExecutor\nstages = {}\n"
             "SerialExecutor(stages).submit(time.sleep, 0.2)\nprint(*stages['sleep'])")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                          check=True, env=os.environ | {"OPENBLAS_NUM_THREADS": "1",
                                                        "OMP_NUM_THREADS": "1",
                                                        "MKL_NUM_THREADS": "1"})
    wall, cpu = map(float, done.stdout.split())
    assert wall >= 0.2 and 0.0 <= cpu < 0.05


def test_single_threaded_sets_the_fft_default_to_one(monkeypatch):
    from scipy import fft

    from stochmod.empirical.wv_covariance import THREADS_VARIABLE, default_workers

    monkeypatch.setenv(THREADS_VARIABLE, "2")
    with single_threaded():
        assert fft.get_workers() == 1
        assert default_workers() == 1
    assert default_workers() == 2  # restored
    monkeypatch.delenv(THREADS_VARIABLE)
    with single_threaded():
        assert default_workers() == 1
    assert THREADS_VARIABLE not in os.environ


def _worker_setup() -> dict:
    import dask

    return {"pid": os.getpid(), "malloc": os.environ.get("MALLOC_TRIM_THRESHOLD_"),
            "blas": os.environ.get("OPENBLAS_NUM_THREADS"),
            "profile": dask.config.get("distributed.worker.profile.enabled"),
            "tick": dask.config.get("distributed.admin.tick.interval"),
            "memory check": dask.config.get("distributed.worker.memory.monitor-interval")}


def test_local_cluster_workers_run_one_thread_without_profiler_malloc_trim_or_fast_ticks(monkeypatch):
    pytest.importorskip("distributed")
    # as a LocalCluster started earlier with dask's defaults leaves it in this process
    monkeypatch.setenv("MALLOC_TRIM_THRESHOLD_", "65536")
    with _client(1, None) as client:
        nthreads = client.nthreads()
        (setup,) = client.run(_worker_setup).values()
    assert list(nthreads.values()) == [1]
    assert setup == {"pid": setup["pid"], "malloc": None, "blas": "1", "profile": False,
                     "tick": "1s", "memory check": "500ms"}
    assert setup["pid"] != os.getpid()
    assert os.environ["MALLOC_TRIM_THRESHOLD_"] == "65536"  # this process's own, restored


def _worker_warmth() -> dict:
    import sys

    from stochmod.empirical import allan_jit, haar_jit, spectrum_jit

    return {"parent": os.getppid(), "warm_module": "stochmod.cli._fleet_worker" in sys.modules,
            "loops": [len(haar_jit.haar_pyramid_sums.signatures), len(spectrum_jit.power_gram.signatures),
                      len(allan_jit.difference_sumsq.signatures)],
            "blas": os.environ.get("OPENBLAS_NUM_THREADS"),
            "malloc": os.environ.get("MALLOC_TRIM_THRESHOLD_")}


@pytest.mark.skipif(not fleet._HAS_SERVER, reason="no forkserver start method on this platform")
def test_local_workers_are_forks_of_a_warm_process_server(monkeypatch):
    pytest.importorskip("distributed")
    from multiprocessing import forkserver

    monkeypatch.setenv("MALLOC_TRIM_THRESHOLD_", "65536")
    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    with _client(2, None, UNIT_STEPS.warm_module) as client:
        server = forkserver._forkserver._forkserver_pid
        setups = list(client.run(_worker_warmth).values())
    assert len(setups) == 2
    for setup in setups:
        # forked by the server (not this process), which had imported the task's modules and
        # loaded the WV sweep's, eq. 17's and the Allan sums' compiled loops before any task ran
        assert setup["parent"] == server != os.getpid()
        assert setup["warm_module"] and min(setup["loops"]) >= 1
        assert setup["blas"] == "1" and setup["malloc"] is None  # the server's environment
    assert forkserver._forkserver._forkserver_pid is None  # stopped with its cluster


def test_the_process_server_exits_without_the_interpreter_teardown():
    """The server imports stochmod.workflows.fleet_server last; a process that imports it leaves with
    exit code 0 and without tearing its modules down (a finaliser that would print at teardown
    does not run), so the command does not wait ~0.8 s for the server's teardown."""
    assert fleet._SERVER_PRELOAD[-1] == "stochmod.workflows.fleet_server"  # after the warm-up
    code = ("import stochmod.workflows.fleet_server, sys\n"
            "class Teardown:\n"
            "    def __del__(self):\n"
            "        sys.stdout.write('torn down')\n"
            "keep = Teardown()\n"
            "sys.stdout.write('ran '); sys.stdout.flush()\n")
    without = subprocess.run([sys.executable, "-c", code.replace("stochmod.workflows.fleet_server", "os")],
                             capture_output=True, text=True, check=True)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert without.stdout == "ran torn down"  # the finaliser runs at a normal teardown
    assert (done.returncode, done.stdout) == (0, "ran ")


def test_only_a_local_fleet_command_starts_the_process_server_early():
    pytest.importorskip("distributed")
    from stochmod.cli import _local_fleet

    assert _local_fleet(["calibrate", "--assume-si", "a.npz", "b.npz", "--workers", "2"])
    assert _local_fleet(["calibrate", "--assume-si", "a.npz", "b.npz", "--workers=2"])
    assert not _local_fleet(["calibrate", "--assume-si", "a.npz", "b.npz"])  # serial
    assert not _local_fleet(["calibrate", "--assume-si", "a.npz", "--scheduler", "tcp://host:8786"])
    assert not _local_fleet(["combine", "a.npz", "--workers", "2"])
    assert not _local_fleet(["calibrate", "--assume-si", "--workers", "2", "--help"])
    assert not _local_fleet([])


@pytest.mark.parametrize("workers", [[], ["--workers", "2"]])
def test_fleet_tasks_csv_accounts_for_each_task(tmp_path, capsys, workers):
    if workers:
        pytest.importorskip("distributed")
    model = stochmod.model_from_spec("WN(sigma2=1e-4)+RW(sigma2=1e-10)", FS)
    files = []
    for i in range(3):
        files.append(tmp_path / f"u{i}.npz")
        np.savez(files[-1], gyro_x=model.simulate(2**12, rng=i), freq=FS)
    out = tmp_path / "out"
    before = time.time()
    assert main(["calibrate", "--assume-si", *map(str, files), "--candidates", "WN", "WN+RW", "--no-plots",
                 "--out", str(out), *workers]) == 0
    capsys.readouterr()
    with open(out / "fleet_tasks.csv") as fh:
        rows = list(csv.DictReader(fh))
    # serially a task per unit; on 2 workers the first unit is one task, the last two (as
    # many as the cluster's threads) a task per step: read, the column's selection, outputs
    steps = ["read", "select gyro_x", "finish"]
    parts = [("u0", "unit")] + [(u, p) for u in ["u1", "u2"] for p in (steps if workers else ["unit"])]
    assert [(r["unit_name"], r["part"]) for r in rows] == parts
    stages = [*dict.fromkeys(STAGES.values()), "other"]
    for r in rows:
        wall = float(r["wall"])
        # the stages partition the task's wall time
        assert sum(float(r[f"{s}_wall"]) for s in stages) == pytest.approx(wall, rel=1e-9)
        busy = {s for s in stages if float(r[f"{s}_wall"]) > 0}
        # read: the file (and the checks); select: WV, eq. 17, fits, the Allan reading of the
        # datasheet (and the rest, other); finish: the report and its outputs (--no-plots)
        assert busy == {"read": {"read", "other"}, "finish": {"other"},
                        "select gyro_x": {"wv", "eq17", "fits", "allan", "other"},
                        "unit": {"read", "wv", "eq17", "fits", "other"}}[r["part"]]
        assert float(r["start"]) <= float(r["end"]) and float(r["end"]) - float(r["start"]) >= wall * 0.99
        assert int(r["threads"]) >= 1
        # the process that ran it started before the task; a worker during this command
        assert float(r["process_start"]) <= float(r["start"])
        assert (float(r["process_start"]) > before - 1.0) is bool(workers)
    by_part = {(r["unit_name"], r["part"]): r for r in rows}
    assert int(by_part["u0", "unit"]["result_bytes"]) > 1000  # the report
    for u in ["u1", "u2"] if workers else []:
        # the steps in order; what a step hands on: the 2^12 samples (8 bytes each), a
        # selection, the report
        read, sel, fin = (by_part[u, p] for p in steps)
        assert float(read["end"]) <= float(sel["start"]) and float(sel["end"]) <= float(fin["start"])
        assert int(read["result_bytes"]) > 8 * 2**12 and int(fin["result_bytes"]) > 1000
    pids = {int(r["pid"]) for r in rows}
    assert (os.getpid() in pids) is (not workers)  # serially in this process, else in workers
