"""What the process server of a fleet's local cluster imports before it forks the workers
(:func:`stochmod.workflows.fleet.start_process_server`): the modules a calibration task needs, the
registered plugins, and the compiled loops of its first task.

A fresh worker would pay all of it in its first task: the imports, and numba's cache loads
of the WV sweep, the eq. 17 spectra, the GM's closed form and the Allan sums (six loops). Importing this module pays them once, in the server, while the
command's own process is still importing; every worker forked from the server starts with
them. The warm-up is a one-column selection of :data:`WARM_N` samples of white noise and
the Allan reading of its datasheet (the results are discarded), large enough to take the
four-step path of eq. 17 like a real recording. It runs on this
thread only (:func:`stochmod.workflows.fleet.single_threaded`, :class:`stochmod.workflows.fleet.SerialExecutor`),
so that no other thread exists when the server forks.
"""

from __future__ import annotations

import numpy as np

import stochmod.cli.calibrate  # noqa: F401 - the task's function and everything it imports
from stochmod.output.datasheet import datasheet_reading
from stochmod.fit.selection import select
from stochmod.workflows.fleet import SerialExecutor, single_threaded
from stochmod.plugin.registry import processes, readers

__all__ = ["WARM_N", "warm_up"]

#: Samples of the warm-up signal (2^16: eq. 17 takes its four-step path, as at 2^20).
WARM_N = 1 << 16


def warm_up() -> None:
    """Load the plugins and the compiled loops of a calibration task into this process."""
    processes()
    readers()
    x = np.random.default_rng(0).standard_normal(WARM_N)
    with single_threaded():
        select(x, 100.0, candidates=["GM+WN"], executor=SerialExecutor(), progress=False)
        datasheet_reading(x, 100.0, "gyro")


try:
    warm_up()
except Exception:  # noqa: BLE001 - a lost head start only: each task meets and reports the cause
    pass
